//! Velocity projection's KKT certificates: a mixed equality/bounded problem on the mobile
//! manipulator (and the QP's reuse), and random bounded problems on three robots — every optimal
//! answer satisfies feasibility, stationarity with the returned λ, ν, η, signs and
//! complementarity. Conventions as in `projection.rs`.

use crate::common;
use common::*;
use constraint_dynamics::System;
use constraint_dynamics::algorithm::Data;
use constraint_dynamics::constraints::{ConstraintData, ConstraintSet};
use constraint_dynamics::projection::*;
use nalgebra::DMatrix;

// ---------------------------------------------------------------------------------------------
// Mixed problem: KKT conditions, structure reuse.

/// The residuals of v* in its KKT conditions with the returned multipliers (the optimality
/// certificate of a convex QP, independent of how the answer was found).
#[derive(Debug, Default, Clone, Copy)]
struct KktResiduals {
    /// |M (v − v_des) − Jᵀλ − ν + Aᵀη|∞ / max(1, |M v_des|∞).
    stationarity: f64,
    /// |J v|∞.
    jv: f64,
    /// Largest |v_i − bound| / (1 + |bound|) over the active bounds.
    active_gap: f64,
    /// Largest violation of a bound or inequality (relative), ≥ 0.
    infeasibility: f64,
    /// Largest multiplier of the wrong sign (ν_i on a one-sided active bound, η_k).
    wrong_sign: f64,
    /// Largest |ν_i| on an inactive bound plus largest |η_k| on a slack row (complementarity).
    complementarity: f64,
}

impl KktResiduals {
    fn max(self, o: KktResiduals) -> KktResiduals {
        KktResiduals {
            stationarity: self.stationarity.max(o.stationarity),
            jv: self.jv.max(o.jv),
            active_gap: self.active_gap.max(o.active_gap),
            infeasibility: self.infeasibility.max(o.infeasibility),
            wrong_sign: self.wrong_sign.max(o.wrong_sign),
            complementarity: self.complementarity.max(o.complementarity),
        }
    }
}

/// Residuals of the KKT conditions of the last answer of `proj` to `p`.
fn kkt_residuals(
    data: &Data,
    cd: &ConstraintData,
    proj: &VelocityProjector,
    p: &ProjectionProblem,
) -> KktResiduals {
    let m = &data.mass_matrix;
    let j = &cd.j;
    let v = &proj.v;
    let nv = v.len();
    let dv = nalgebra::DVector::from_iterator(nv, (0..nv).map(|i| v[i] - p.v_des[i]));
    let mut stat = m * dv - j.transpose() * &proj.lambda - &proj.nu;
    if p.a.nrows() > 0 {
        stat += p.a.transpose() * nalgebra::DVector::from_vec(proj.eta.clone());
    }
    let scale = (m * nalgebra::DVector::from_vec(p.v_des.clone()))
        .amax()
        .max(1.0);
    let mut r = KktResiduals {
        stationarity: stat.amax() / scale,
        jv: if j.nrows() > 0 { (j * v).amax() } else { 0.0 },
        ..Default::default()
    };
    let mut active = vec![false; nv];
    for (i, side) in proj.active_bounds() {
        active[i] = true;
        let (b, _) = proj.bound(i, side);
        r.active_gap = r.active_gap.max((v[i] - b).abs() / (1.0 + b.abs()));
        if proj.bound(i, Side::Lower).0 == proj.bound(i, Side::Upper).0 {
            continue; // an equality: ν of either sign
        }
        let wrong = match side {
            Side::Lower => -proj.nu[i],
            Side::Upper => proj.nu[i],
        };
        r.wrong_sign = r.wrong_sign.max(wrong.max(0.0));
    }
    for i in 0..nv {
        let (lo, _) = proj.bound(i, Side::Lower);
        let (hi, _) = proj.bound(i, Side::Upper);
        r.infeasibility = r
            .infeasibility
            .max((lo - v[i]) / (1.0 + lo.abs()))
            .max((v[i] - hi) / (1.0 + hi.abs()));
        if !active[i] {
            r.complementarity = r.complementarity.max(proj.nu[i].abs());
        }
    }
    for k in 0..p.a.nrows() {
        let av: f64 = (0..nv).map(|c| p.a[(k, c)] * v[c]).sum();
        r.infeasibility = r.infeasibility.max((av - p.b[k]) / (1.0 + p.b[k].abs()));
        r.wrong_sign = r.wrong_sign.max(-proj.eta[k]);
        if av < p.b[k] - 1e-7 * (1.0 + p.b[k].abs()) {
            r.complementarity = r.complementarity.max(proj.eta[k].abs());
        }
    }
    r
}

/// Tolerances on [`KktResiduals`], from the worst case over the 600 random problems of
/// `random_bounded_projections_satisfy_kkt` and the mixed problem (both print it): stationarity
/// 8.4e-16 relative (tol 2e-14), |J v| 1.5e-13 (tol 5e-12), an active bound met and every bound
/// kept to 4.8e-13 relative (tol 2e-11), wrong-sign multipliers and complementarity exactly 0
/// (tol 0: the polish sets ν and η of inactive rows to zero and keeps only correctly signed
/// active sets).
const KKT_TOL: KktResiduals = KktResiduals {
    stationarity: 2e-14,
    jv: 5e-12,
    active_gap: 2e-11,
    infeasibility: 2e-11,
    wrong_sign: 0.0,
    complementarity: 0.0,
};

fn assert_kkt(tag: &str, r: KktResiduals, tol: KktResiduals) {
    let ok = r.stationarity <= tol.stationarity
        && r.jv <= tol.jv
        && r.active_gap <= tol.active_gap
        && r.infeasibility <= tol.infeasibility
        && r.wrong_sign <= tol.wrong_sign
        && r.complementarity <= tol.complementarity;
    assert!(ok, "{tag}: KKT residuals {r:?} exceed {tol:?}");
}

/// The mobile manipulator with URDF limits (wheels 20 rad/s, arm 2 rad/s), an acceleration limit
/// from the current velocity, and a user inequality on the base; a sequence of requests through
/// one projector (the QP is built once and updated) equals fresh projectors.
#[test]
fn mobile_manipulator_mixed_bounds_satisfy_kkt_and_reuse_the_qp() {
    let (scene, sys) = scene_system("mobile_manipulator.yaml");
    let (mut data, mut cd, _) = workspaces(&sys);
    let (q, v0) = (scene.q0.clone(), scene.v0.clone());
    let nv = sys.model().nv;
    let mut proj = VelocityProjector::new(sys.model(), sys.constraints());
    let mut answers: Vec<Vec<f64>> = vec![];
    let mut worst = KktResiduals::default();
    for k in 0..4 {
        let s = k as f64;
        let mut p = ProjectionProblem::new(sys.model());
        p.v_des = (0..nv)
            .map(|i| 3.0 * ((i as f64 + 1.0) * (0.7 + s)).sin())
            .collect();
        p.v_des[3] = 30.0 - 5.0 * s; // over the wheel limit
        let mut a_max = vec![f64::INFINITY; nv];
        a_max[5..].fill(10.0);
        p.accel_limit = Some(AccelLimit {
            dt: 0.1,
            a_max,
            v_current: v0.clone(),
        });
        p.a = DMatrix::from_row_slice(1, nv, &{
            let mut r = vec![0.0; nv];
            r[0] = 1.0;
            r[2] = 0.3;
            r
        });
        p.b = vec![0.4];
        let o = proj
            .project(sys.model(), &mut data, sys.constraints(), &mut cd, &q, &p)
            .unwrap();
        assert_eq!(o.status, Status::Optimal);
        assert_eq!(o.method, SolvePath::ClarabelPolished, "request {k}");
        let r = kkt_residuals(&data, &cd, &proj, &p);
        worst = worst.max(r);
        assert_kkt(&format!("request {k}"), r, KKT_TOL);
        let mut fresh = VelocityProjector::new(sys.model(), sys.constraints());
        fresh
            .project(sys.model(), &mut data, sys.constraints(), &mut cd, &q, &p)
            .unwrap();
        // achieved 0 (same data, same solver path); floor 1e-15
        assert_close(
            "reused vs fresh",
            proj.v.as_slice(),
            fresh.v.as_slice(),
            1e-15,
        );
        // The same active set, not only the same vector.
        let sorted = |x: &VelocityProjector| {
            let mut b: Vec<(usize, bool)> = x
                .active_bounds()
                .map(|(i, s)| (i, s == Side::Upper))
                .collect();
            b.sort();
            (b, x.active_inequalities().collect::<Vec<_>>())
        };
        assert_eq!(sorted(&proj), sorted(&fresh), "request {k}: active sets");
        eprintln!(
            "request {k}: active {:?}, v {:?}",
            sorted(&proj),
            proj.v.as_slice()
        );
        answers.push(proj.v.iter().copied().collect());
    }
    eprintln!("mixed problem: worst KKT residuals {worst:?}");
    // Every request got its own answer: an in-place update that kept the previous data (or the
    // previous solution) would repeat a vector. The requests differ by O(1) in v_des.
    assert_eq!(answers.len(), 4);
    for (k, w) in answers.windows(2).enumerate() {
        let d = rel_err(&w[1], &w[0]);
        eprintln!("answers {k} → {}: relative change {d:.2e}", k + 1);
        // Smallest change achieved: 3.2e-2 (request 1 → 2).
        assert!(
            d > 3e-3,
            "answers {k} and {} are the same: {:?}",
            k + 1,
            w[1]
        );
    }
    assert_eq!(
        proj.qp_builds(),
        1,
        "one structure, one Clarabel problem, updated in place"
    );
}

// ---------------------------------------------------------------------------------------------
// Randomised: every answer carries a KKT certificate.

/// Random desired velocities and random bound subsets (some lo = hi) on three robots: every
/// optimal answer satisfies the KKT conditions (feasibility, stationarity with the returned
/// λ, ν, η, signs, complementarity), which certify optimality of a convex QP.
#[test]
fn random_bounded_projections_satisfy_kkt() {
    let mut systems: Vec<(String, System, Vec<f64>)> = vec![];
    for name in ["ur5_ee_point", "solo12_four_feet"] {
        let case = load_case(name);
        let model = case_model(&case);
        let st = &case["states"][2];
        let q = vecf(&st["q"]);
        let set = ConstraintSet::new(&model, &specs_for(&case, st), &q).unwrap();
        let sys = System::new(model, set, Default::default(), Default::default());
        systems.push((name.into(), sys, q));
    }
    let (scene, sys) = scene_system("mobile_manipulator.yaml");
    systems.push(("mobile_manipulator".into(), sys, scene.q0.clone()));
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let mut methods = std::collections::BTreeMap::<String, usize>::new();
    let mut worst = KktResiduals::default();
    for (name, sys, q) in &mut systems {
        let nv = sys.model().nv;
        let (mut data, mut cd, _) = workspaces(sys);
        let mut proj = VelocityProjector::new(sys.model(), sys.constraints());
        for trial in 0..150 {
            let mut p = ProjectionProblem::new(sys.model());
            p.v_des = (0..nv).map(|_| 6.0 * (rng.next() - 0.5)).collect();
            for i in 0..nv {
                let u = rng.next();
                if u < 0.3 {
                    p.upper[i] = 0.2 + 2.0 * rng.next();
                } else if u < 0.6 {
                    p.lower[i] = -0.2 - 2.0 * rng.next();
                } else if u < 0.8 {
                    p.upper[i] = 0.1 + rng.next();
                    p.lower[i] = -0.1 - rng.next();
                } else if u < 0.82 {
                    p.lower[i] = 0.0;
                    p.upper[i] = 0.0;
                }
            }
            let o = proj
                .project(sys.model(), &mut data, sys.constraints(), &mut cd, q, &p)
                .unwrap();
            *methods
                .entry(format!("{name}: {:?}", o.method))
                .or_default() += 1;
            if o.status == Status::Infeasible {
                continue;
            }
            assert_ne!(
                o.method,
                SolvePath::Clarabel,
                "{name}[{trial}]: polish not accepted {o:?}"
            );
            *methods
                .entry(format!("{name}: exact multipliers {}", o.multipliers_exact))
                .or_default() += 1;
            assert!(o.multipliers_exact, "{name}[{trial}]: {o:?}");
            let r = kkt_residuals(&data, &cd, &proj, &p);
            worst = worst.max(r);
            assert_kkt(&format!("{name}[{trial}]"), r, KKT_TOL);
        }
    }
    eprintln!("{methods:#?}");
    eprintln!("random bounded projections: worst KKT residuals {worst:?}");
}
