//! Criterion benchmarks of the velocity projection (one full call: kinematics, J, M, solve) beside
//! one constrained forward-dynamics evaluation on the same robot and constraints, for the ratio:
//! UR5 with its end effector held (reference case, 3 rows), Solo12 on four point feet (12 rows),
//! and the planar mobile manipulator (params/mobile_manipulator.yaml: two rolling wheels, 4 rows
//! of which one is redundant, URDF limits wheels 20 rad/s, arm 2 rad/s).
//!
//! Problems: `equality_only` (no bounds), `bounds_inactive` (bounds that the equality-only
//! solution meets: no QP), `bounded` (bounds that bind: Clarabel + polish). UR5 and Solo12 use
//! the reference case's state 2 with its `bounded` lb/ub (3 and 5 active bounds).

#[path = "../tests/it/common/mod.rs"]
mod common;

use constraint_dynamics::algorithm::Data;
use constraint_dynamics::constraints::{ConstraintData, ConstraintSet};
use constraint_dynamics::dynamics::{Baumgarte, KktWorkspace, constrained_forward_dynamics};
use constraint_dynamics::projection::{ProjectionProblem, SolvePath, VelocityProjector};
use constraint_dynamics::{BaseType, Model, ModelOptions, Scene};
use criterion::{Criterion, criterion_group, criterion_main};
use serde_json::Value;
use std::hint::black_box;
use std::path::PathBuf;

struct Case {
    name: &'static str,
    model: Model,
    set: ConstraintSet,
    q: Vec<f64>,
    v: Vec<f64>,
    tau: Vec<f64>,
    equality_only: ProjectionProblem,
    bounds_inactive: ProjectionProblem,
    bounded: ProjectionProblem,
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn f(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap_or(f64::NAN))
        .collect()
}

fn reference(name: &'static str, urdf: &str, base: BaseType, case: &str) -> Case {
    let dir = root().join("../shared/reference");
    let opts = ModelOptions {
        base,
        ..Default::default()
    };
    let model = Model::from_urdf_file(dir.join("urdf").join(urdf), &opts).expect("model");
    let text = std::fs::read_to_string(dir.join("cases").join(case)).expect("case file");
    let json: Value = serde_json::from_str(&text).expect("json");
    let st = &json["states"][2];
    let specs = common::specs_for(&json, st);
    let q = f(&st["q"]);
    let set = ConstraintSet::new(&model, &specs, &q).expect("constraints");
    let vp = &st["expected"]["velocity_projection"];
    let mut eq = ProjectionProblem::new(&model);
    eq.velocity_limits = false;
    eq.v_des = f(&vp["v_des"]);
    let mut bounded = eq.clone();
    let none = |x: f64, inf: f64| if x.is_nan() { inf } else { x };
    bounded.lower = f(&vp["bounded"]["lb"])
        .into_iter()
        .map(|x| none(x, f64::NEG_INFINITY))
        .collect();
    bounded.upper = f(&vp["bounded"]["ub"])
        .into_iter()
        .map(|x| none(x, f64::INFINITY))
        .collect();
    let mut inactive = bounded.clone();
    for x in inactive.lower.iter_mut().chain(inactive.upper.iter_mut()) {
        *x *= 100.0;
    }
    Case {
        name,
        q,
        v: f(&st["qd"]),
        tau: f(&st["tau"]),
        set,
        equality_only: eq,
        bounds_inactive: inactive,
        bounded,
        model,
    }
}

fn mobile_manipulator() -> Case {
    let scene = Scene::load(root().join("params/mobile_manipulator.yaml")).expect("scene");
    let model = scene.model.clone();
    let set = ConstraintSet::new(&model, &scene.file.constraints, &scene.q0).expect("set");
    let nv = model.nv;
    let mut eq = ProjectionProblem::new(&model);
    eq.velocity_limits = false;
    // A planner's request: drive and turn, move the arm (wheels 18 / 22 rad/s, arm up to 3 rad/s).
    eq.v_des = vec![1.0, 0.1, 0.5, 18.3, 21.7, 0.8, -3.0, 2.5, 1.0];
    let mut bounded = eq.clone();
    bounded.velocity_limits = true; // URDF: wheels 20 rad/s, arm 2 rad/s
    let mut inactive = eq.clone();
    inactive.v_des = vec![0.2, 0.0, 0.1, 3.66, 4.34, 0.3, -0.5, 0.4, 0.2];
    inactive.velocity_limits = true;
    Case {
        name: "mobile_manipulator",
        q: scene.q0.clone(),
        v: scene.v0.clone(),
        tau: vec![0.0; nv],
        set,
        equality_only: eq,
        bounds_inactive: inactive,
        bounded,
        model: (*model).clone(),
    }
}

fn bench(c: &mut Criterion) {
    let cases = [
        reference(
            "ur5",
            "ur5_robot.urdf",
            BaseType::Fixed,
            "ur5_ee_point.json",
        ),
        reference(
            "solo12",
            "solo12.urdf",
            BaseType::Floating,
            "solo12_four_feet.json",
        ),
        mobile_manipulator(),
    ];
    for k in &cases {
        let m = &k.model;
        let mut d = Data::new(m);
        let mut cd = ConstraintData::new(m, &k.set);
        let mut proj = VelocityProjector::new(m, &k.set);
        for (label, p, want) in [
            ("equality_only", &k.equality_only, SolvePath::Kkt),
            (
                "bounds_inactive",
                &k.bounds_inactive,
                SolvePath::KktBoundsInactive,
            ),
            ("bounded", &k.bounded, SolvePath::ClarabelPolished),
        ] {
            let o = proj.project(m, &mut d, &k.set, &mut cd, &k.q, p).unwrap();
            assert_eq!(o.method, want, "{}/{label}", k.name);
            c.bench_function(&format!("projection/{}/{label}", k.name), |b| {
                b.iter(|| {
                    proj.project(m, &mut d, &k.set, &mut cd, black_box(&k.q), black_box(p))
                        .unwrap();
                })
            });
        }
        let mut ws = KktWorkspace::new(m, &k.set);
        c.bench_function(
            &format!("projection/{}/constrained_dynamics", k.name),
            |b| {
                b.iter(|| {
                    constrained_forward_dynamics(
                        m,
                        &mut d,
                        &k.set,
                        &mut cd,
                        &mut ws,
                        black_box(&k.q),
                        black_box(&k.v),
                        black_box(&k.tau),
                        Baumgarte::default(),
                    )
                    .unwrap();
                })
            },
        );
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .warm_up_time(std::time::Duration::from_millis(500))
        .measurement_time(std::time::Duration::from_secs(2));
    targets = bench
}
criterion_main!(benches);
