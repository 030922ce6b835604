//! Criterion benchmarks of prediction and of the two formulations.
//!
//! - `horizon/mobile_manipulator/<formulation>`: a 2 s horizon, RK4 with projection
//!   (params/mobile_manipulator.yaml: two rolling wheels, rank-deficient rows; samples every
//!   10 ms), in the multiplier and in the embedded form, at 0.5 ms: the step whose true error
//!   meets the scene's `max_error` (1e-3; at 1 ms the falling wrist is 3.4e-3 rad off),
//!   checked once before timing against the same run at a quarter of the step.
//! - `horizon/mobile_manipulator/unconstrained`: 2 s at 1 ms with the scene's constraints
//!   removed (so no projection either): a floor under the two above, and the figure to set
//!   beside compiled Pinocchio's same horizon (`tools/peers/horizon_floor.sh`, the same
//!   computation: end |v| equal to 1e-9).
//! - `horizon/mobile_manipulator/covariance`: the multiplier form's horizon with a propagated
//!   covariance (σ = 1 mm, 1 mrad, 1 mm/s, 1 mrad/s on every coordinate): its cost is read as
//!   the ratio to `horizon/mobile_manipulator/multipliers` of the same run (the bar: ≤ 2×).
//! - `evaluation/<scene>/<formulation>`: one constrained forward-dynamics evaluation at the
//!   scene's initial state (params/ and params/report/), multipliers vs embedded: the figures
//!   behind the predictor's choice of formulation (docs/bench.md).

use constraint_dynamics::dynamics::Formulation;
use constraint_dynamics::predict::{DriftControl, Method, PredictionRequest, Predictor};
use constraint_dynamics::system::DynamicsOptions;
use constraint_dynamics::{Scene, System};
use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::DMatrix;
use std::hint::black_box;
use std::path::PathBuf;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

const FORMS: [(&str, Formulation); 2] = [
    ("multipliers", Formulation::Multipliers),
    ("embedded", Formulation::Embedded),
];

/// The scene's predictor at the horizons' settings: RK4 at `dt` [s], a sample every 10 ms, the
/// prediction alone (the error estimate's companion doubles the work; estimate.rs).
fn rk4_predictor(scene: &Scene, dt: f64) -> Predictor {
    Predictor::from_scene(scene)
        .expect("predictor")
        .with_settings(|s| {
            s.method = Method::Rk4;
            s.dt = dt;
            s.error_estimate = false;
            s.sample_period = 0.01;
        })
        .expect("settings")
}

/// [`rk4_predictor`] with projection.
fn rk4_projected(scene: &Scene, dt: f64) -> Predictor {
    rk4_predictor(scene, dt)
        .with_settings(|s| s.drift = DriftControl::Projection)
        .expect("settings")
}

/// The constrained horizons' step [s]: RK4's error at 1 ms (3.4e-3 rad) over 2⁴.
const DT: f64 = 5e-4;

/// The largest tangent-space difference of q [m or rad] over the common samples of a 2 s run of
/// `p` and the same run at a quarter of its step: RK4's true error to within 1/256.
fn true_error(p: &Predictor, scene: &Scene) -> f64 {
    let req = PredictionRequest::new(&scene.q0, &scene.v0).horizon(2.0);
    let dt = p.config().settings().dt;
    let mut fine = p
        .clone()
        .with_settings(|s| s.dt = dt / 4.0)
        .expect("settings");
    let (a, b) = (
        p.clone().predict(&req).expect("predict"),
        fine.predict(&req).expect("predict"),
    );
    let model = p.model();
    let mut diff = vec![0.0; model.nv];
    let mut worst = 0.0f64;
    for (x, y) in a.samples.iter().zip(&b.samples) {
        model.difference(&y.q, &x.q, &mut diff);
        worst = diff.iter().fold(worst, |m, d| m.max(d.abs()));
    }
    worst
}

/// `horizon/mobile_manipulator/<label>`: 2 s from the scene's initial state (`steps` steps, four
/// evaluations each, checked once before timing), from the start covariance `p0` if any.
fn bench_horizon(
    c: &mut Criterion,
    label: &str,
    p: &mut Predictor,
    scene: &Scene,
    (p0, steps): (Option<&DMatrix<f64>>, usize),
) {
    let request = |q0, v0| PredictionRequest {
        start_covariance: p0,
        ..PredictionRequest::new(q0, v0).horizon(2.0)
    };
    let t = p.predict(&request(&scene.q0, &scene.v0)).expect("predict");
    assert_eq!((t.steps, t.evaluations), (steps, 4 * steps));
    c.bench_function(&format!("horizon/mobile_manipulator/{label}"), |b| {
        b.iter(|| {
            p.predict(&request(black_box(&scene.q0), black_box(&scene.v0)))
                .unwrap()
        })
    });
}

fn horizon(c: &mut Criterion) {
    let scene = Scene::load(root().join("params/mobile_manipulator.yaml")).expect("scene");
    let steps = (2.0 / DT).round() as usize;
    for (label, form) in FORMS {
        let mut formed = scene.clone();
        formed.file.dynamics.formulation = form;
        let mut p = rk4_projected(&formed, DT);
        let (error, bound) = (true_error(&p, &formed), p.config().settings().max_error);
        assert!(
            error <= bound,
            "{label}: true error {error:e} > max_error {bound:e}"
        );
        eprintln!(
            "horizon/mobile_manipulator/{label}: true error {error:.2e} (max_error {bound:e})"
        );
        bench_horizon(c, label, &mut p, &scene, (None, steps));
    }
    let mut free = scene.clone();
    free.file.constraints.clear();
    let mut p = rk4_predictor(&free, 1e-3);
    assert!(
        System::from_scene(&free)
            .expect("system")
            .constraints()
            .is_empty()
    );
    bench_horizon(c, "unconstrained", &mut p, &scene, (None, 2000));
    let mut p = rk4_projected(&scene, DT);
    let n = 2 * p.model().nv;
    let p0 = DMatrix::identity(n, n) * 1e-6;
    let req = PredictionRequest::new(&scene.q0, &scene.v0).horizon(2.0);
    let t = p.predict(&req.covariance(&p0)).expect("predict");
    assert!(t.samples.last().unwrap().covariance.is_some());
    bench_horizon(c, "covariance", &mut p, &scene, (Some(&p0), steps));
}

fn evaluation(c: &mut Criterion) {
    let mut scenes: Vec<PathBuf> = ["params", "params/report"]
        .iter()
        .flat_map(|d| std::fs::read_dir(root().join(d)).expect("params"))
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension().is_some_and(|x| x == "yaml")
                && std::fs::read_to_string(p).is_ok_and(|t| t.contains("urdf:"))
        })
        .collect();
    scenes.sort();
    for path in scenes {
        let name = path.file_stem().unwrap().to_string_lossy().to_string();
        let scene = Scene::load(&path).expect("scene");
        let mut sys = System::from_scene(&scene).expect("system");
        if sys.constraints().is_empty() {
            continue; // unconstrained: both forms are M⁻¹(τ − h), nothing to compare
        }
        let nv = sys.model().nv;
        let tau: Vec<f64> = (0..nv).map(|i| ((i + 1) as f64 * 0.9).sin()).collect();
        for (label, formulation) in FORMS {
            let opts = DynamicsOptions {
                formulation,
                allow_inconsistent: true,
                ..Default::default()
            };
            sys.forward_dynamics_with(&scene.q0, &scene.v0, &tau, opts)
                .expect("dynamics");
            c.bench_function(&format!("evaluation/{name}/{label}"), |b| {
                b.iter(|| {
                    sys.forward_dynamics_with(
                        black_box(&scene.q0),
                        black_box(&scene.v0),
                        black_box(&tau),
                        opts,
                    )
                    .unwrap()
                    .len()
                })
            });
        }
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(20)
        .warm_up_time(std::time::Duration::from_millis(500))
        .measurement_time(std::time::Duration::from_secs(2));
    targets = horizon, evaluation
}
criterion_main!(benches);
