//! The dynamic projection's answers certified: random requests, bounds, current velocities and
//! periods on three robots, and every optimal answer checked against the optimality conditions
//! of the cone program (primal limits, dual cones, complementarity, stationarity), evaluated
//! here from the problem's data, independent of how it was solved.
//!
//! Conventions: `M (v⁺ − v) = Δt (Q + Sᵀτ − h) + JᵀΛ`, Λ = impulse ON the robot over Δt.

use crate::common;
use crate::projection_dynamic::{cart_scene, robot};
use common::*;
use constraint_dynamics::envelope::EnvelopeModel;
use constraint_dynamics::projection::*;
use constraint_dynamics::{Scene, System};
use nalgebra::DVector;

/// Residuals of an answer in the optimality conditions of the cone program, from the problem's
/// data evaluated here (CRBA, RNEA's bias, the constraints) and the returned primal and dual
/// values. Every entry is relative (see each).
#[derive(Debug, Default, Clone, Copy)]
struct Certificate {
    /// |M (v⁺ − v) − Δt (Sᵀτ − h) − JᵀΛ|∞ / (|M v|∞ + Δt |h|∞ + 1).
    dynamics: f64,
    /// |J v⁺|∞ / (|v⁺|∞ + 1).
    jv: f64,
    /// Largest violation of a velocity bound, relative to 1 + |bound|.
    bounds: f64,
    /// Largest (|τ| − e) / e.
    effort: f64,
    /// Largest max(‖Λ_t‖ − μ Λ_n, −Λ_n) / (Δt m g).
    cones: f64,
    /// |M (v⁺ − v_des) + M y + Jᵀ w − ν|∞ / max(1, |M v_des|∞).
    stationarity: f64,
    /// Dual cones: effort multipliers of the wrong sign, u = −J y outside a contact's dual cone
    /// or nonzero on a row no limit bounds, bound multipliers of the wrong sign; relative to
    /// 1 + |y|∞ (u) or 1 + the multipliers' scale.
    dual: f64,
    /// Complementarity: ξ_k (e ∓ τ_k), Λᵀu per contact, ν_i (v_i − bound), relative.
    complementarity: f64,
}

impl Certificate {
    fn max(self, o: Self) -> Self {
        Self {
            dynamics: self.dynamics.max(o.dynamics),
            jv: self.jv.max(o.jv),
            bounds: self.bounds.max(o.bounds),
            effort: self.effort.max(o.effort),
            cones: self.cones.max(o.cones),
            stationarity: self.stationarity.max(o.stationarity),
            dual: self.dual.max(o.dual),
            complementarity: self.complementarity.max(o.complementarity),
        }
    }
    fn within(&self, t: &Self) -> bool {
        self.dynamics <= t.dynamics
            && self.jv <= t.jv
            && self.bounds <= t.bounds
            && self.effort <= t.effort
            && self.cones <= t.cones
            && self.stationarity <= t.stationarity
            && self.dual <= t.dual
            && self.complementarity <= t.complementarity
    }
}

#[allow(clippy::too_many_arguments)]
fn certificate(
    sys: &System,
    em: &EnvelopeModel,
    proj: &DynamicProjector,
    q: &[f64],
    v: &[f64],
    p: &ProjectionProblem,
    period: f64,
) -> Certificate {
    use constraint_dynamics::algorithm::{Data, crba_full, nonlinear_effects};
    use constraint_dynamics::constraints::ConstraintData;
    let model = sys.model();
    let nv = model.nv;
    let mut d = Data::new(model);
    let m = crba_full(model, &mut d, q).clone();
    let h = nonlinear_effects(model, &mut d, q, v).clone();
    let mut cd = ConstraintData::new(model, sys.constraints());
    sys.constraints()
        .evaluate(model, &mut d, &mut cd, 0.0, q, v);
    let j = cd.j.clone();
    let vv = DVector::from_column_slice(v);
    let (vp, tau, lam, y) = (&proj.v, &proj.tau, &proj.lambda, &proj.y);
    let mut stau = DVector::zeros(nv);
    for (k, a) in em.actuators.iter().enumerate() {
        stau[a.coordinate] += tau[k];
    }
    let dyn_res = &m * (vp - &vv) - period * (&stau - &h) - j.transpose() * lam;
    let mut c = Certificate {
        dynamics: dyn_res.amax() / ((&m * &vv).amax() + period * h.amax() + 1.0),
        jv: (&j * vp).amax() / (vp.amax() + 1.0),
        ..Default::default()
    };
    let vdes = DVector::from_column_slice(&p.v_des);
    let stat = &m * (vp - &vdes) + &m * y + j.transpose() * &proj.w - &proj.nu;
    c.stationarity = stat.amax() / (&m * &vdes).amax().max(1.0);
    let yscale = 1.0 + y.amax();
    // Efforts: ξ = Δt y_c ≥ 0 only at +e, ≤ 0 only at −e.
    for (k, a) in em.actuators.iter().enumerate() {
        let xi = period * y[a.coordinate];
        if a.effort.is_finite() {
            c.effort = c.effort.max((tau[k].abs() - a.effort) / a.effort);
            let compl = xi.max(0.0) * (a.effort - tau[k]) + (-xi).max(0.0) * (a.effort + tau[k]);
            c.complementarity = c.complementarity.max(compl / (a.effort * period * yscale));
        } else {
            c.dual = c.dual.max(xi.abs() / (period * yscale));
        }
    }
    // Contacts: u = −J y.
    let u = -(&j * y);
    let weight = period * 9.81 * 40.0;
    let mut limited = vec![false; em.nc];
    for ct in &em.contacts {
        let Some(n) = ct.normal else {
            for &t in &ct.tangential {
                c.dual = c.dual.max(u[t].abs() / yscale);
                limited[t] = true;
            }
            continue;
        };
        limited[n] = true;
        let lt = ct
            .tangential
            .iter()
            .map(|&t| lam[t] * lam[t])
            .sum::<f64>()
            .sqrt();
        let ut = ct
            .tangential
            .iter()
            .map(|&t| u[t] * u[t])
            .sum::<f64>()
            .sqrt();
        for &t in &ct.tangential {
            limited[t] = true;
        }
        match (ct.has_cone(), ct.friction) {
            (true, Some(mu)) => {
                c.cones = c.cones.max((lt - mu * lam[n]) / weight);
                c.dual = c.dual.max((ut - u[n] / mu) / yscale);
            }
            _ => {
                // Tangential rows unbounded: their dual vanishes.
                c.dual = c.dual.max(ut / yscale);
            }
        }
        c.cones = c.cones.max(-lam[n] / weight);
        c.dual = c.dual.max(-u[n] / yscale);
        let rows: Vec<usize> = std::iter::once(n)
            .chain(ct.tangential.iter().copied())
            .collect();
        let compl: f64 = rows.iter().map(|&r| lam[r] * u[r]).sum();
        c.complementarity = c.complementarity.max(compl.abs() / (weight * yscale));
    }
    for r in 0..em.nc {
        if !limited[r] {
            c.dual = c.dual.max(u[r].abs() / yscale);
        }
    }
    // Bounds: ν ≥ 0 only at a lower bound, ≤ 0 only at an upper one.
    let nuscale = 1.0 + (&m * (vp - &vdes)).amax();
    for i in 0..nv {
        let (lo, _) = proj.kinematic.bound(i, Side::Lower);
        let (hi, _) = proj.kinematic.bound(i, Side::Upper);
        c.bounds = c
            .bounds
            .max((lo - vp[i]) / (1.0 + lo.abs()))
            .max((vp[i] - hi) / (1.0 + hi.abs()));
        let nu = proj.nu[i];
        let compl = if nu > 0.0 {
            nu * (vp[i] - lo)
        } else {
            -nu * (hi - vp[i])
        };
        c.complementarity = c.complementarity.max(compl / (nuscale * (1.0 + vp.amax())));
    }
    c
}

/// Tolerances on [`Certificate`] (the cone program is solved to 1e-10), about 50× the worst
/// case over the 180 random problems below (printed by the test): dynamics 3.3e-15, |J v⁺|
/// 2.7e-16, stationarity 5.4e-12, dual cones 1.4e-12, complementarity 5.5e-10; the primal
/// limits (bounds, efforts, cones) are met exactly (an interior point), tolerance 1e-12.
const CERT_TOL: Certificate = Certificate {
    dynamics: 2e-13,
    jv: 2e-14,
    bounds: 1e-12,
    effort: 1e-12,
    cones: 1e-12,
    stationarity: 3e-10,
    dual: 1e-10,
    complementarity: 3e-8,
};

/// Random requests, bounds, current velocities and periods on the cart (friction cones and a
/// unilateral caster), the floating mobile manipulator (unilateral wheels and caster, arm
/// efforts) and the planar diff drive (efforts only): every optimal answer satisfies the
/// primal limits and carries dual multipliers in the dual cones with complementarity — a
/// certificate of optimality of the convex program, independent of how it was solved.
#[test]
fn random_dynamic_projections_carry_kkt_and_cone_certificates() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let mut worst = Certificate::default();
    let mut counts = std::collections::BTreeMap::<String, usize>::new();
    let scenes = [
        ("cart", cart_scene(0.5)),
        (
            "mobile_manipulator_floating",
            Scene::load(repo_dir().join("params/mobile_manipulator_floating.yaml")).unwrap(),
        ),
        (
            "diff_drive",
            Scene::load(repo_dir().join("params/diff_drive.yaml")).unwrap(),
        ),
    ];
    for (name, scene) in scenes {
        let mut r = robot(scene);
        let nv = r.sys.model().nv;
        let q = r.scene.q0.clone();
        let zero = vec![0.0; nv];
        let mut kin = VelocityProjector::new(r.sys.model(), r.sys.constraints());
        for trial in 0..60 {
            // A current velocity the constraints allow: a random one, projected.
            let mut pk = ProjectionProblem::new(r.sys.model());
            pk.v_des = (0..nv).map(|_| 1.0 * (rng.next() - 0.5)).collect();
            kin.project(
                r.sys.model(),
                &mut constraint_dynamics::algorithm::Data::new(r.sys.model()),
                r.sys.constraints(),
                &mut constraint_dynamics::constraints::ConstraintData::new(
                    r.sys.model(),
                    r.sys.constraints(),
                ),
                &q,
                &pk,
            )
            .unwrap();
            let v: Vec<f64> = kin.v.iter().copied().collect();
            let mut p = ProjectionProblem::new(r.sys.model());
            p.v_des = (0..nv).map(|_| 6.0 * (rng.next() - 0.5)).collect();
            for (i, &vi) in v.iter().enumerate() {
                let u = rng.next();
                if u < 0.2 {
                    p.upper[i] = vi + 0.05 + rng.next();
                } else if u < 0.4 {
                    p.lower[i] = vi - 0.05 - rng.next();
                }
            }
            let period = [0.005, 0.02, 0.1][trial % 3];
            let o = r
                .proj
                .project(&mut r.sys, Some(&r.em), &q, &v, &zero, &p, period)
                .unwrap();
            *counts.entry(format!("{name}: {:?}", o.status)).or_default() += 1;
            if o.status != Status::Optimal {
                continue;
            }
            for b in &r.proj.binding {
                *counts
                    .entry(format!("{name}: binds {}", b.kind.name()))
                    .or_default() += 1;
            }
            let c = certificate(&r.sys, &r.em, &r.proj, &q, &v, &p, period);
            worst = worst.max(c);
            assert!(c.within(&CERT_TOL), "{name}[{trial}]: {c:?}");
        }
        // One structure per set of finite bounds; never more builds than calls.
        eprintln!("{name}: {} builds of the cone program", r.proj.builds());
    }
    eprintln!("{counts:#?}");
    eprintln!("worst certificate residuals: {worst:?}");
    // Every kind of limit was met by some answer: the certificates cover each cone.
    for key in [
        "cart: binds effort",
        "cart: binds friction",
        "cart: binds lift_off",
        "cart: binds bound",
        "mobile_manipulator_floating: binds effort",
        "mobile_manipulator_floating: binds lift_off",
        "diff_drive: binds effort",
    ] {
        assert!(counts.contains_key(key), "no answer where {key}");
    }
}
