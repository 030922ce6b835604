//! Radau IIA (order 5, `method: radau5`, src/predict/integrators/radau.rs) against independent answers:
//! - a damped stiff spring chain (springs 1e4–1e8 N/m, the stiff ones near critically damped:
//!   eigenvalues down to −1.27e5 1/s, slow modes at 138 and 362 rad/s): linear, so the exact
//!   state is e^{At} x₀ (nalgebra's Padé matrix exponential). Explicit methods must keep
//!   dt ≤ ~3/1.27e5 s there; the stiff solver's step follows the slow modes;
//! - Andrews' squeezing mechanism (a stiff loop mechanism with 6 loop rows): the IVP test set's
//!   reference at t = 0.03 s (accurate to ~1.4e-9 rad, tests/it/andrews.rs).

use constraint_dynamics::Scene;
use constraint_dynamics::forces::{ForcesSpec, JointSpringSpec};
use constraint_dynamics::predict::{
    DriftControl, Method, PredictionRequest, Predictor, Trajectory,
};
use nalgebra::{DMatrix, DVector};
use std::path::PathBuf;

const STIFFNESS: [f64; 5] = [1e4, 1e7, 1e8, 1e7, 1e4];
const DAMPING: [f64; 5] = [0.2, 2e3, 6e3, 2e3, 0.2];
const MASS: f64 = 0.1;
const HORIZON: f64 = 0.2;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The five 0.1 kg sliders of the report's chain with the springs and dampers above.
fn damped_chain(method: Method, tol: f64) -> (Predictor, Vec<f64>) {
    let mut sc = Scene::load(root().join("params/report/spring_chain_stiff.yaml")).unwrap();
    let mut spec = ForcesSpec::default();
    for i in 0..5 {
        spec.joint_springs.push(JointSpringSpec {
            joint: format!("slider{}", i + 1),
            stiffness: STIFFNESS[i],
            damping: DAMPING[i],
            rest: 0.0,
        });
    }
    // The scene's force elements are these springs and dampers.
    sc.file.forces = spec;
    let p = Predictor::from_scene(&sc)
        .unwrap()
        .with_settings(|s| {
            s.method = method;
            s.drift = DriftControl::None;
            s.rtol = tol;
            s.atol = tol;
            s.error_estimate = false;
            s.max_error = f64::INFINITY;
            s.sample_period = HORIZON;
        })
        .unwrap();
    (p, sc.q0.clone())
}

/// x(t) = e^{At} x₀ of M q̈ + D q̇ + K q = 0 on the relative coordinates (M_jk = m (5 − max(j, k))).
fn chain_exact(q0: &[f64], t: f64, squarings: i32) -> Vec<f64> {
    let n = 5;
    let m = DMatrix::from_fn(n, n, |j, k| MASS * (n - j.max(k)) as f64);
    let minv = m.try_inverse().unwrap();
    let k = DMatrix::from_diagonal(&DVector::from_column_slice(&STIFFNESS));
    let d = DMatrix::from_diagonal(&DVector::from_column_slice(&DAMPING));
    let mut a = DMatrix::zeros(2 * n, 2 * n);
    a.view_mut((0, n), (n, n))
        .copy_from(&DMatrix::identity(n, n));
    a.view_mut((n, 0), (n, n)).copy_from(&(-&minv * k));
    a.view_mut((n, n), (n, n)).copy_from(&(-&minv * d));
    // e^{At} = (e^{A t/2^s})^(2^s): the Padé approximant on a small norm, then squarings.
    let s = squarings;
    let mut e = (a * (t / f64::powi(2.0, s))).exp();
    for _ in 0..s {
        e = &e * &e;
    }
    let mut x0 = DVector::zeros(2 * n);
    x0.rows_mut(0, n).copy_from_slice(q0);
    (e * x0).rows(0, n).iter().copied().collect()
}

fn run(method: Method, tol: f64) -> (Trajectory, f64) {
    let (p, q0) = damped_chain(method, tol);
    let mut p = p.with_settings(|s| s.dt = 1e-6).unwrap();
    let t = p
        .predict(&PredictionRequest::new(&q0, &[0.0; 5]).horizon(HORIZON))
        .unwrap();
    let exact = chain_exact(&q0, HORIZON, 12);
    let last = t.samples.last().unwrap();
    let err = last
        .q
        .iter()
        .zip(&exact)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    (t, err)
}

/// The reference itself: two matrix-exponential evaluations (2^12 and 2^16 squarings) agree.
#[test]
fn chain_reference_is_converged() {
    let (_, q0) = damped_chain(Method::Radau5, 1e-6);
    let a = chain_exact(&q0, HORIZON, 12);
    let b = chain_exact(&q0, HORIZON, 16);
    let diff = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    println!("reference q(0.2 s) = {a:?}, 2^12 vs 2^16 squarings: {diff:.1e}");
    // Achieved 4.8e-15 m (q ~ 1e-3 m): far below the 4.5e-11 m of the tightest run below.
    assert!(diff < 1e-14 && a.iter().all(|x| x.is_finite()));
}

/// Every tolerance 1e-6 … 1e-10 is met (error ≤ rtol against e^{At} x₀; q ~ 1e-3 m; achieved
/// 0.06, 0.17 and 0.45 of rtol), in ≥ 10× fewer evaluations than the cheapest explicit run that
/// is as accurate: DOPRI5 at any tolerance takes ~7 700 steps here, its step held by stability
/// (dt·|λ|max ≤ 3.3 with λ = −1.27e5 1/s), not by accuracy. Measured (loaded machine): radau5
/// 2.3 / 3.7 / 13 ms against dopri5's 135–264 ms.
#[test]
fn radau5_meets_its_tolerance_on_the_damped_stiff_chain_far_cheaper_than_dopri5() {
    let (d, err_d) = run(Method::Dopri5, 1e-4);
    println!(
        "dopri5 rtol 1e-4: err {err_d:.2e}, {} steps, {} evaluations, {:.2} ms",
        d.steps,
        d.evaluations,
        d.run_time_s * 1e3
    );
    for tol in [1e-6, 1e-8, 1e-10] {
        let (r, err_r) = run(Method::Radau5, tol);
        println!(
            "rtol {tol:e}: radau5 err {err_r:.2e}, {} steps, {} evaluations, {} Jacobians, \
             {:.2} ms",
            r.steps,
            r.evaluations,
            r.jacobians,
            r.run_time_s * 1e3,
        );
        assert!(err_r <= tol, "radau5 at {tol:e}: {err_r:e}");
        assert!(err_d <= tol, "dopri5 is as accurate: {err_d:e}");
        assert!(
            d.evaluations >= 10 * r.evaluations,
            "{} vs {}",
            d.evaluations,
            r.evaluations
        );
        // A Jacobian is refreshed only when Newton converges slowly: 47–61 per ~238 steps at
        // 1e-6 (the count moves with rounding-level changes of the derivatives and of the
        // Newton solves, whose contraction rate sits near the 1e-3 that keeps a Jacobian),
        // 22–27 at 1e-8.
        assert!(
            10 * r.jacobians <= 3 * r.steps,
            "Jacobians kept across steps: {}",
            r.jacobians
        );
    }
}

/// The global error estimate (companion at rtol / 32) against the true error: within the required
/// [0.1, 100] bar.
#[test]
fn radau5_error_estimate_brackets_the_true_error() {
    for tol in [1e-6, 1e-8, 1e-10] {
        let (p, q0) = damped_chain(Method::Radau5, tol);
        let mut p = p.with_settings(|s| s.error_estimate = true).unwrap();
        let t = p
            .predict(&PredictionRequest::new(&q0, &[0.0; 5]).horizon(HORIZON))
            .unwrap();
        let exact = chain_exact(&q0, HORIZON, 12);
        let last = t.samples.last().unwrap();
        let truth = last
            .q
            .iter()
            .zip(&exact)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        let e = last.error_estimate.unwrap();
        println!(
            "| damped stiff chain, 0.2 s | Radau5 | rtol = {tol:e} | {truth:.2e} | {e:.2e} | {:.2} |",
            e / truth
        );
        // Achieved 0.96 at every tolerance; the bar is [0.1, 100].
        assert!((0.5..=2.0).contains(&(e / truth)), "{e:e} vs {truth:e}");
    }
}

/// Andrews' squeezer: radau5 at rtol 1e-10 lands on the test set's reference to its accuracy.
#[test]
fn radau5_reaches_the_andrews_reference() {
    let sc = Scene::load(root().join("params/andrews.yaml")).unwrap();
    for tol in [1e-6, 1e-8, 1e-10] {
        let mut p = Predictor::from_scene(&sc)
            .unwrap()
            .with_settings(|s| {
                s.method = Method::Radau5;
                s.rtol = tol;
                s.atol = tol;
                s.error_estimate = false;
            })
            .unwrap();
        let t = p
            .predict(&PredictionRequest::new(&sc.q0, &sc.v0).horizon(0.03))
            .unwrap();
        let q = &t.samples.last().unwrap().q;
        let i = |n: &str| t.q_names.iter().position(|s| s == n).unwrap();
        let err = (q[i("beta")] - 15.81077119629904)
            .abs()
            .max((q[i("theta")] + 15.75637105984298).abs());
        println!(
            "andrews radau5 rtol {tol:e}: err {err:.2e}, {} steps, {} evaluations, {} Jacobians",
            t.steps, t.evaluations, t.jacobians
        );
        // Achieved 1.2e-5, 4.3e-8 (|q| ≈ 16 rad) and 1.40e-9, the reference's own accuracy.
        let bound = if tol < 1e-9 { 2e-9 } else { 20.0 * tol };
        assert!(err <= bound, "rtol {tol:e}: {err:e}");
    }
}
