//! The multiplier-free (embedded, Voronets) and the multiplier propagations of every bundled scene
//! stay together over the horizon: RK4, dt = 1 ms, projection, 1 s (2 s for the report scenes;
//! shorter where the scene passes a singular position or balances on an unstable equilibrium).
//! Stated tolerance: the final q (Lie-group difference) and v agree to 1e-8 [m, rad, m/s, rad/s].

use constraint_dynamics::Scene;
use constraint_dynamics::dynamics::Formulation;
use constraint_dynamics::predict::{DriftControl, Method, Predictor, Trajectory};
use std::path::PathBuf;

const TOL: f64 = 1e-8;

fn propagate(
    sc: &Scene,
    formulation: Formulation,
    horizon: f64,
    dt: f64,
) -> (Predictor, Trajectory) {
    let mut p = Predictor::from_scene(sc).unwrap();
    p.sys.formulation = formulation;
    p.settings.method = Method::Rk4;
    p.settings.dt = dt;
    p.settings.drift = DriftControl::Projection;
    p.settings.sample_period = 0.1;
    let t = p.predict(&sc.q0, &sc.v0, &[], horizon).unwrap();
    (p, t)
}

#[test]
fn embedded_and_multiplier_propagations_agree_on_every_bundled_scene() {
    let scenes = [
        ("params/pendulum_a01.yaml", 1.0),
        ("params/rod_body.yaml", 1.0),
        ("params/vertical_disk.yaml", 1.0),
        ("params/fourbar.yaml", 1.0),
        ("params/slider_crank.yaml", 1.0),
        ("params/double_fourbar.yaml", 1.0),
        ("params/diff_drive.yaml", 1.0),
        ("params/mobile_manipulator.yaml", 1.0),
        // An unstable equilibrium (the arm upright): round-off grows by e^{λt}, ~1e-8 at 1 s.
        ("params/mobile_manipulator_floating.yaml", 0.5),
        ("params/spring_chain.yaml", 1.0),
        ("params/report/rolling_disk.yaml", 2.0),
        ("params/report/diff_drive_coasting.yaml", 2.0),
        ("params/report/spring_chain_stiff.yaml", 0.05),
    ];
    for (rel, horizon) in scenes {
        // The stiff chain's fastest mode is ~4.5e3 rad/s: RK4 needs dt ≤ 6e-4 s (1e-5 s here).
        let dt = if rel.contains("stiff") { 1e-5 } else { 1e-3 };
        let sc = Scene::load(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(rel)).unwrap();
        let (p, emb) = propagate(&sc, Formulation::Embedded, horizon, dt);
        let (_, mul) = propagate(&sc, Formulation::Multipliers, horizon, dt);
        let mut worst: f64 = 0.0;
        for (a, b) in emb.samples.iter().zip(&mul.samples) {
            let mut d = vec![0.0; p.sys.model.nv];
            p.sys.model.difference(&a.q, &b.q, &mut d);
            let dv = a.v.iter().zip(&b.v).map(|(x, y)| (x - y).abs());
            worst = d.iter().map(|x| x.abs()).chain(dv).fold(worst, f64::max);
        }
        assert_eq!(emb.samples.len(), mul.samples.len());
        println!("{rel}: embedded vs multipliers over {horizon} s: max |Δq|, |Δv| = {worst:.3e}");
        assert!(worst <= TOL, "{rel}: formulations differ by {worst:e}");
    }
}
