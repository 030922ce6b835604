//! Predictions of large trees, which step on the linear-time path (ABA, and without M with
//! constraint rows) and hold no n × n matrix unless a method or a covariance asks for one:
//!
//! - RK4 predictions of the 200-link chain, free and held at both ends, against RK4 written
//!   out here on the dense path's q̈ (CRBA, the LTL factor of M and its Schur complement): q and
//!   v agree to 1e-12 relative at every sample (achieved 9.3e-15).
//! - The work bound counts the path the stages take: a 5 000-link chain's RK4 prediction is
//!   accepted and runs with the default `max_work`; 100 s of it, and ROS2 (whose F and its
//!   factor are dense), are refused before running, naming the work, the bodies and the path.
//! - The implicit methods' F, W and the dynamics' derivatives, sized by their first step above
//!   256 coordinates: ROS2 and SDIRK2 of the 300-link chain held at both ends (20 ms at 1 ms)
//!   are off RK4's q (whose own estimate, 5.8e-11, is 5e-5 of theirs) by their error estimate,
//!   within 1 % (achieved 0.02 % and 0.06 %).
//! - The explicit methods' step-size check takes the mobilities (M⁻¹)_ii of a 300-link chain's
//!   joint spring-dampers from ABA's factors: the rate it reports is the one the dense inverse
//!   of M, formed here, gives (to the four digits printed).

use crate::chain;
use crate::common::*;
use constraint_dynamics::algorithm::Data;
use constraint_dynamics::constraints::{ConstraintData, ConstraintSet};
use constraint_dynamics::dynamics::{
    KktOptions, KktWorkspace, constrained_forward_dynamics, takes_linear_path,
};
use constraint_dynamics::predict::{
    DriftControl, IntegrationOverrides, Method, PredictionRequest, Predictor,
};
use constraint_dynamics::{Error, Model, Scene, System};

/// The integration both sides of the comparison take: RK4 at 1 ms, no drift control (the
/// held chain's rows are met by the dynamics alone), no error estimate.
const DT: f64 = 1e-3;

/// RK4 on (q, v) ∈ R^n × R^n (revolute joints: q ⊕ Θ = q + Θ) with q̈ from the dense
/// multiplier form (`set` may be empty), every `per_sample` steps recorded.
fn dense_rk4(
    m: &Model,
    set: &ConstraintSet,
    (q0, v0): (&[f64], &[f64]),
    steps: usize,
    per_sample: usize,
) -> Vec<(Vec<f64>, Vec<f64>)> {
    let n = m.nv;
    let (mut data, mut cd) = (Data::new(m), ConstraintData::new(m, set));
    let mut kkt = KktWorkspace::new(m, set);
    let tau = vec![0.0; n];
    let mut accel = |q: &[f64], v: &[f64]| -> Vec<f64> {
        let opts = KktOptions::default();
        constrained_forward_dynamics(m, &mut data, set, &mut cd, &mut kkt, q, v, &tau, opts)
            .expect("the dense path accepts the chain");
        kkt.qdd.as_slice().to_vec()
    };
    let axpy = |x: &[f64], a: f64, y: &[f64]| -> Vec<f64> {
        x.iter().zip(y).map(|(x, y)| x + a * y).collect()
    };
    let (mut q, mut v) = (q0.to_vec(), v0.to_vec());
    let mut out = vec![(q.clone(), v.clone())];
    for k in 1..=steps {
        let (k1q, k1v) = (v.clone(), accel(&q, &v));
        let (q2, v2) = (axpy(&q, DT / 2.0, &k1q), axpy(&v, DT / 2.0, &k1v));
        let (k2q, k2v) = (v2.clone(), accel(&q2, &v2));
        let (q3, v3) = (axpy(&q, DT / 2.0, &k2q), axpy(&v, DT / 2.0, &k2v));
        let (k3q, k3v) = (v3.clone(), accel(&q3, &v3));
        let (q4, v4) = (axpy(&q, DT, &k3q), axpy(&v, DT, &k3v));
        let (k4q, k4v) = (v4.clone(), accel(&q4, &v4));
        for i in 0..n {
            q[i] += DT / 6.0 * (k1q[i] + 2.0 * k2q[i] + 2.0 * k3q[i] + k4q[i]);
            v[i] += DT / 6.0 * (k1v[i] + 2.0 * k2v[i] + 2.0 * k3v[i] + k4v[i]);
        }
        if k % per_sample == 0 {
            out.push((q.clone(), v.clone()));
        }
    }
    out
}

#[test]
fn predictions_of_the_200_link_chain_agree_with_rk4_on_the_dense_path() {
    let n = 200;
    let (steps, per_sample) = (20, 5);
    for held in [false, true] {
        let scene = chain::load_chain_scene(n, held);
        assert!(takes_linear_path(&scene.model));
        let sys = System::from_scene(&scene).unwrap();
        let set = sys.constraints().clone();
        assert_eq!(set.nrows, if held { 3 } else { 0 });
        let mut p = Predictor::from_scene(&scene).unwrap();
        let overrides = IntegrationOverrides {
            method: Some(Method::Rk4),
            dt: Some(DT),
            drift: Some(DriftControl::None),
            sample_period: Some(per_sample as f64 * DT),
            error_estimate: Some(false),
            ..Default::default()
        };
        let req = PredictionRequest::new(&scene.q0, &scene.v0)
            .horizon(steps as f64 * DT)
            .integration(overrides);
        let traj = p.predict(&req).unwrap();
        let reference = dense_rk4(
            &scene.model,
            &set,
            (&scene.q0, &scene.v0),
            steps,
            per_sample,
        );
        assert_eq!(traj.samples.len(), reference.len());
        for (s, (q, v)) in traj.samples.iter().zip(&reference) {
            let what = format!("chain (held {held}) at t = {} s", s.t);
            assert_close(&format!("{what}: q"), &s.q, q, 1e-12);
            assert_close(&format!("{what}: v"), &s.v, v, 1e-12);
        }
        // The chain moved: the comparison is not of two starts.
        let (q_end, _) = reference.last().unwrap();
        let moved = (q_end.iter().zip(&scene.q0)).fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
        assert!(moved > 1e-4, "the chain moved only {moved:e} rad");
    }
}

#[test]
fn the_work_bound_counts_the_linear_path_on_a_5000_link_chain() {
    let n = 5000;
    let scene = chain::load_chain_scene(n, false);
    let mut p = Predictor::from_scene(&scene).unwrap();
    let rk4 = IntegrationOverrides {
        method: Some(Method::Rk4),
        dt: Some(DT),
        sample_period: Some(5e-3),
        ..Default::default()
    };
    let req = |horizon: f64, integration: IntegrationOverrides| {
        PredictionRequest::new(&scene.q0, &scene.v0)
            .horizon(horizon)
            .integration(integration)
    };
    // Accepted under the default max_work, error estimate on, and run.
    let traj = p.predict(&req(0.01, rk4)).unwrap();
    assert_eq!(traj.steps, 10);
    let last = traj.samples.last().unwrap();
    assert!((last.q.iter().chain(&last.v)).all(|x| x.is_finite()));
    assert!(last.error_estimate.unwrap() < 1e-6);
    // 100 s (1e5 steps, about 45 minutes): refused before running.
    let t = std::time::Instant::now();
    let e = p.predict(&req(100.0, rk4)).unwrap_err();
    assert!(matches!(e, Error::WorkLimit { .. }), "{e}");
    assert_has(
        &e.to_string(),
        &[
            "work units",
            "5000-body",
            "linear-time path",
            "integration.max_work",
        ],
    );
    // ROS2 forms and factors a dense F: refused at the dense path's cost for 10 ms.
    let ros2 = IntegrationOverrides {
        method: Some(Method::Ros2),
        ..rk4
    };
    let e = p.predict(&req(0.01, ros2)).unwrap_err().to_string();
    assert_has(&e, &["work units", "5000-body", "dense path"]);
    assert!(t.elapsed().as_secs_f64() < 0.5, "{:?}", t.elapsed());
}

#[test]
fn the_step_size_check_of_a_large_tree_takes_its_mobilities_from_aba() {
    let n = 300;
    let dir = std::env::temp_dir().join(format!("cd_linear_prediction_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let urdf = dir.join("chain.urdf");
    std::fs::write(&urdf, chain::chain_urdf(n)).unwrap();
    let springs = [(40, 2.0e3, 0.0), (150, 5.0e2, 3.0), (299, 1.0e2, 2.0)];
    let mut yaml = chain::chain_scene_yaml(n, &urdf.display().to_string());
    yaml.push_str("forces:\n  joint_springs:\n");
    for (j, k, d) in springs {
        yaml.push_str(&format!(
            "    - {{joint: joint{j}, stiffness: {k}, damping: {d}}}\n"
        ));
    }
    let scene: Scene = scene_from_yaml(&yaml).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    assert!(takes_linear_path(&scene.model));
    // The dense inverse of M, formed here.
    let mut sys = System::from_scene(&scene).unwrap();
    let minv = sys.mass_matrix_at(&scene.q0).clone().try_inverse().unwrap();
    let rate = springs
        .iter()
        .map(|&(j, k, d)| {
            let w = minv[(j - 1, j - 1)];
            (k * w).sqrt().max(d * w)
        })
        .fold(0.0f64, f64::max);
    let mut p = Predictor::from_scene(&scene).unwrap();
    let overrides = IntegrationOverrides {
        method: Some(Method::Rk4),
        dt: Some(1e-3),
        ..Default::default()
    };
    let req = PredictionRequest::new(&scene.q0, &scene.v0)
        .horizon(0.01)
        .integration(overrides);
    let e = p.predict(&req).unwrap_err();
    assert!(matches!(e, Error::StepTooLarge { .. }), "{e}");
    let e = e.to_string();
    let reported: f64 = e
        .split("(rate ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .and_then(|r| r.parse().ok())
        .unwrap_or_else(|| panic!("no rate in: {e}"));
    eprintln!("achieved: rate {reported:e} 1/s reported, {rate:e} 1/s from the dense M⁻¹");
    // Four digits printed.
    assert!(
        (reported - rate).abs() <= 6e-4 * rate,
        "{reported} against {rate}"
    );
}

#[test]
fn implicit_methods_size_their_dense_workspaces_on_a_large_tree() {
    let scene = chain::load_chain_scene(300, true);
    let mut p = Predictor::from_scene(&scene).unwrap();
    let mut run = |method: Method| {
        let overrides = IntegrationOverrides {
            method: Some(method),
            dt: Some(DT),
            sample_period: Some(0.02),
            ..Default::default()
        };
        let req = PredictionRequest::new(&scene.q0, &scene.v0)
            .horizon(0.02)
            .integration(overrides);
        p.predict(&req).unwrap()
    };
    let reference = run(Method::Rk4);
    let q_ref = &reference.samples.last().unwrap().q;
    for method in [Method::Ros2, Method::Sdirk2] {
        let traj = run(method);
        assert!(traj.jacobians >= 1, "{method:?} formed no F");
        let last = traj.samples.last().unwrap();
        let off = (last.q.iter().zip(q_ref)).fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
        let estimate = last.error_estimate.unwrap();
        eprintln!("achieved: {method:?} off RK4 by {off:.4e} rad, its estimate {estimate:.4e}");
        assert!(
            (off - estimate).abs() <= 0.01 * estimate,
            "{method:?}: {off:e} off RK4, estimate {estimate:e}"
        );
    }
}
