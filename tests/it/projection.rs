//! Velocity projection: every `velocity_projection` entry of the four reference cases (Pinocchio
//! M and J, DAQP/ProxQP for the bounded ones; tolerances below), scaled requests giving scaled
//! answers, and the equality-only path allocation-free. The differential drive's closed forms,
//! infeasible and bad requests are in `projection_diff_drive.rs`; the KKT certificates (a mixed
//! problem, random bounded ones) in `projection_kkt.rs`.
//!
//! Conventions are the reference's: `M (v* − v_des) = Jᵀλ + ν`, λ = impulse ON the robot.

use crate::common;
use common::*;
use constraint_dynamics::algorithm::Data;
use constraint_dynamics::constraints::{ConstraintData, ConstraintSet};
use constraint_dynamics::projection::*;
use constraint_dynamics::{Error, Model};
use serde_json::Value;

use crate::counting_alloc;
use counting_alloc::allocations;

// ---------------------------------------------------------------------------------------------
// Reference cases.

struct Fixture {
    model: Model,
    data: Data,
    set: ConstraintSet,
    cd: ConstraintData,
    proj: VelocityProjector,
}

fn fixture(model: &Model, set: ConstraintSet) -> Fixture {
    Fixture {
        data: Data::new(model),
        cd: ConstraintData::new(model, &set),
        proj: VelocityProjector::new(model, &set),
        model: model.clone(),
        set,
    }
}

impl Fixture {
    fn project(&mut self, q: &[f64], p: &ProjectionProblem) -> Result<Outcome, Error> {
        self.proj
            .project(&self.model, &mut self.data, &self.set, &mut self.cd, q, p)
    }
}

/// The reference's bound array: null = none.
fn bound_array(v: &Value, none: f64) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap_or(none))
        .collect()
}

// Reference projections (`../shared/reference/cases/*.json`, `velocity_projection`), achieved
// relative errors over all 18 states (printed per state): equality-only v 5.0e-15 and λ
// 1.3e-15; bounded v 3.5e-13 (Solo12: DAQP and ProxQP themselves differ by up to 6.8e-13),
// λ 5.6e-14, ν 1.5e-14. Tolerances ≈ 40–80× those.
const EQ_V_TOL: f64 = 2e-13;
const EQ_LAMBDA_TOL: f64 = 1e-13;
const BOUNDED_V_TOL: f64 = 2e-11;
const BOUNDED_LAMBDA_TOL: f64 = 2e-12;
const BOUNDED_NU_TOL: f64 = 1e-12;

fn check_reference(name: &str) -> (usize, usize) {
    let case = load_case(name);
    let model = case_model(&case);
    let (mut n_eq, mut n_bounded) = (0, 0);
    for (k, st) in case["states"].as_array().unwrap().iter().enumerate() {
        let q = vecf(&st["q"]);
        let set = ConstraintSet::new(&model, &specs_for(&case, st), &q).unwrap();
        let mut fx = fixture(&model, set);
        let vp = &st["expected"]["velocity_projection"];
        let tag = format!("{name}[{k}]");

        // Equality only: the reference problem has no bounds (URDF limits off).
        let mut p = ProjectionProblem::new(&model);
        p.velocity_limits = false;
        p.v_des = vecf(&vp["v_des"]);
        let o = fx.project(&q, &p).unwrap();
        assert_eq!(o.method, SolvePath::Kkt, "{tag}");
        assert_eq!(o.rank_deficiency, 0, "{tag}");
        let eq = &vp["equality_only"];
        eprintln!(
            "{tag}: equality-only rel. error v {:.1e}, lambda {:.1e}",
            rel_err(fx.proj.v.as_slice(), &vecf(&eq["v"])),
            rel_err(fx.proj.lambda.as_slice(), &vecf(&eq["lambda"]))
        );
        assert_close(
            &format!("{tag} equality-only v"),
            fx.proj.v.as_slice(),
            &vecf(&eq["v"]),
            EQ_V_TOL,
        );
        assert_close(
            &format!("{tag} equality-only lambda"),
            fx.proj.lambda.as_slice(),
            &vecf(&eq["lambda"]),
            EQ_LAMBDA_TOL,
        );
        n_eq += 1;

        let Some(b) = vp.get("bounded") else {
            continue;
        };
        p.lower = bound_array(&b["lb"], f64::NEG_INFINITY);
        p.upper = bound_array(&b["ub"], f64::INFINITY);
        let o = fx.project(&q, &p).unwrap();
        assert_eq!(o.status, Status::Optimal, "{tag}");
        let active_ref: Vec<usize> = b["active_bounds"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_u64().unwrap() as usize)
            .collect();
        if active_ref.is_empty() {
            assert_eq!(o.method, SolvePath::KktBoundsInactive, "{tag}");
        } else {
            assert_eq!(o.method, SolvePath::ClarabelPolished, "{tag}");
        }
        assert_close(
            &format!("{tag} bounded v"),
            fx.proj.v.as_slice(),
            &vecf(&b["v"]),
            BOUNDED_V_TOL,
        );
        eprintln!(
            "{tag}: bounded ({:?}, {} QP iterations) rel. error v {:.1e}{}",
            o.method,
            o.qp_iterations,
            rel_err(fx.proj.v.as_slice(), &vecf(&b["v"])),
            if b["multipliers_unique"].as_bool().unwrap() {
                format!(
                    ", lambda {:.1e}, nu {:.1e}",
                    rel_err(fx.proj.lambda.as_slice(), &vecf(&b["lambda"])),
                    rel_err(fx.proj.nu.as_slice(), &vecf(&b["nu_bounds"]))
                )
            } else {
                " (multipliers not unique)".into()
            }
        );
        let mut active: Vec<usize> = fx.proj.active_bounds().map(|(i, _)| i).collect();
        active.sort();
        assert_eq!(active, active_ref, "{tag}: active set");
        for (i, side) in fx.proj.active_bounds() {
            let want = if fx.proj.v[i] > 0.0 {
                Side::Upper
            } else {
                Side::Lower
            };
            assert_eq!(side, want, "{tag}: side of the bound on coordinate {i}");
        }
        let unique = b["multipliers_unique"].as_bool().unwrap();
        assert_eq!(
            o.multipliers_unique, unique,
            "{tag}: uniqueness of the multipliers"
        );
        if unique {
            assert_close(
                &format!("{tag} bounded lambda"),
                fx.proj.lambda.as_slice(),
                &vecf(&b["lambda"]),
                BOUNDED_LAMBDA_TOL,
            );
            assert_close(
                &format!("{tag} bounded nu"),
                fx.proj.nu.as_slice(),
                &vecf(&b["nu_bounds"]),
                BOUNDED_NU_TOL,
            );
        }
        n_bounded += 1;
    }
    (n_eq, n_bounded)
}

#[test]
fn fourbar_projections_match_reference() {
    assert_eq!(check_reference("fourbar"), (5, 5));
}

#[test]
fn ur5_projections_match_reference() {
    assert_eq!(check_reference("ur5_ee_point"), (4, 4));
}

#[test]
fn solo12_projections_match_reference() {
    assert_eq!(check_reference("solo12_four_feet"), (5, 5));
}

#[test]
fn rolling_disk_projections_match_reference() {
    assert_eq!(check_reference("rolling_disk"), (4, 0));
}

// ---------------------------------------------------------------------------------------------
// Allocation.

#[test]
fn equality_only_projection_does_not_allocate() {
    let mut cases: Vec<(String, Fixture, Vec<f64>, ProjectionProblem)> = vec![];
    for name in ["ur5_ee_point", "solo12_four_feet", "rolling_disk"] {
        let case = load_case(name);
        let model = case_model(&case);
        let st = &case["states"][1];
        let q = vecf(&st["q"]);
        let set = ConstraintSet::new(&model, &specs_for(&case, st), &q).unwrap();
        let mut p = ProjectionProblem::new(&model);
        p.velocity_limits = false;
        p.v_des = vecf(&st["expected"]["velocity_projection"]["v_des"]);
        cases.push((name.into(), fixture(&model, set), q, p));
    }
    // The diff drive: redundant rows (min-norm path), URDF limits present but not binding.
    let (scene, sys) = scene_system("diff_drive.yaml");
    let mut p = ProjectionProblem::new(sys.model());
    p.v_des = vec![0.3, 0.2, 0.5, 1.0, 2.0];
    cases.push((
        "diff_drive".into(),
        fixture(sys.model(), sys.constraints().clone()),
        scene.q0.clone(),
        p,
    ));
    let probe = allocations(|| {
        std::hint::black_box(vec![1u8; 10]);
    });
    assert_eq!(probe, 1, "the counter counts");
    for (name, fx, q, p) in &mut cases {
        let first = fx.project(q, p).unwrap();
        let n = allocations(|| {
            fx.project(q, p).unwrap();
        });
        assert_eq!(n, 0, "{name}: the projection allocates ({first:?})");
    }
}

/// Badly scaled requests: the problem is positively homogeneous, v*(α v_des, α bounds) = α v*, so
/// the reference bounded problems scaled by α = 1e-8 … 1e8 must give α times the reference v*
/// (Clarabel sees the scaled data; the polish restores full precision).
#[test]
fn scaled_requests_give_scaled_answers() {
    for name in ["ur5_ee_point", "solo12_four_feet"] {
        let case = load_case(name);
        let model = case_model(&case);
        let st = &case["states"][3];
        let q = vecf(&st["q"]);
        let set = ConstraintSet::new(&model, &specs_for(&case, st), &q).unwrap();
        let mut fx = fixture(&model, set);
        let b = &st["expected"]["velocity_projection"]["bounded"];
        let v_ref = vecf(&b["v"]);
        for alpha in [1e-8, 1e-5, 1e-2, 1e2, 1e5, 1e8] {
            let mut p = ProjectionProblem::new(&model);
            p.velocity_limits = false;
            p.v_des = vecf(&st["expected"]["velocity_projection"]["v_des"])
                .iter()
                .map(|x| alpha * x)
                .collect();
            p.lower = bound_array(&b["lb"], f64::NEG_INFINITY)
                .iter()
                .map(|x| alpha * x)
                .collect();
            p.upper = bound_array(&b["ub"], f64::INFINITY)
                .iter()
                .map(|x| alpha * x)
                .collect();
            let o = fx.project(&q, &p).unwrap();
            assert_eq!(o.method, SolvePath::ClarabelPolished, "{name} α = {alpha}");
            let v: Vec<f64> = fx.proj.v.iter().map(|x| x / alpha).collect();
            // Achieved ≤ 1.9e-13 (Solo12), as the unscaled bounded problems.
            assert_close(&format!("{name} α = {alpha}"), &v, &v_ref, BOUNDED_V_TOL);
        }
    }
}
