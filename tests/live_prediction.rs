//! The suite's live prediction (continuous controllers, ROS2) against the held reference.
mod common;
use constraint_dynamics::Scene;
use constraint_dynamics::actuators::{Command, Hold};
use constraint_dynamics::predict::{Method, PredictionRequest, Predictor};
use std::time::Instant;

fn commands(scene: &Scene, p: &Predictor) -> Vec<(f64, Command)> {
    let held = [
        "arm_shoulder_yaw",
        "arm_shoulder_pitch",
        "arm_elbow",
        "arm_wrist",
    ];
    let mk = |tw: [f64; 2]| {
        let mut c = Command {
            base_twist: Some(tw),
            ..Default::default()
        };
        for n in held {
            let i = p.model().q_names.iter().position(|x| x == n).unwrap();
            c.joint_position.insert(n.to_string(), scene.q0[i]);
        }
        c
    };
    let a: Vec<f64> = std::env::var("CMD")
        .unwrap_or("0.4,0.8,0.3,-0.6".into())
        .split(',')
        .map(|x| x.parse().unwrap())
        .collect();
    vec![(0.0, mk([a[0], a[1]])), (0.5, mk([a[2], a[3]]))]
}

#[test]
#[ignore]
fn explore() {
    let scene =
        Scene::load(common::repo_dir().join("params/suite_mobile_manipulator.yaml")).unwrap();
    let mut reference = Predictor::from_scene(&scene)
        .unwrap()
        .with_settings(|s| {
            s.method = Method::Rk4;
            s.dt = 1e-4;
            s.error_estimate = false;
            s.max_steps = 1e7;
            s.max_work = 1e12;
        })
        .unwrap();
    let cmds = commands(&scene, &reference);
    let horizon: f64 = std::env::var("H")
        .ok()
        .and_then(|x| x.parse().ok())
        .unwrap_or(1.0);
    let r = reference
        .predict(
            &PredictionRequest::new(&scene.q0, &scene.v0)
                .commands(&cmds)
                .horizon(horizon),
        )
        .unwrap();
    let mut cont = scene.clone();
    cont.file.actuators.hold = Hold::Continuous;
    let mut exact = Predictor::from_scene(&cont)
        .unwrap()
        .with_settings(|s| {
            s.method = Method::Rk4;
            s.dt = 1e-4;
            s.error_estimate = false;
            s.max_steps = 1e7;
            s.max_work = 1e12;
        })
        .unwrap();
    let e = exact
        .predict(
            &PredictionRequest::new(&scene.q0, &scene.v0)
                .commands(&cmds)
                .horizon(horizon),
        )
        .unwrap();
    let pose = |a: &[f64], b: &[f64]| ((a[0] - b[0]).hypot(a[1] - b[1]), (a[2] - b[2]).abs());
    let worst = |x: &constraint_dynamics::predict::Trajectory,
                 y: &constraint_dynamics::predict::Trajectory| {
        let mut w = (0.0f64, 0.0f64);
        for (a, b) in x.samples.iter().zip(&y.samples) {
            assert!((a.t - b.t).abs() < 1e-9);
            let (p, o) = pose(&a.q, &b.q);
            w = (w.0.max(p), w.1.max(o));
        }
        w
    };
    println!(
        "model (continuous vs held), both RK4 0.1 ms: {:?}",
        worst(&e, &r)
    );
    for dt in [0.005, 0.01, 0.02, 0.04] {
        for method in [Method::Ros2] {
            let mut p = Predictor::from_scene(&cont)
                .unwrap()
                .with_settings(|s| {
                    s.method = method;
                    s.dt = dt;
                    s.error_estimate = true;
                    s.max_error = f64::INFINITY;
                })
                .unwrap();
            let t0 = Instant::now();
            let mut tr = None;
            for _ in 0..20 {
                tr = Some(
                    p.predict(
                        &PredictionRequest::new(&scene.q0, &scene.v0)
                            .commands(&cmds)
                            .horizon(horizon),
                    )
                    .unwrap(),
                );
            }
            let el = t0.elapsed().as_secs_f64() / 20.0;
            let tr = tr.unwrap();
            let est = tr
                .samples
                .iter()
                .map(|s| s.error_estimate.unwrap_or(0.0))
                .fold(0.0, f64::max);
            let mut true_err = 0.0f64;
            let mut diff = vec![0.0; p.model().nv];
            for (a, b) in tr.samples.iter().zip(&e.samples) {
                p.model().difference(&a.q, &b.q, &mut diff);
                true_err = true_err.max(diff.iter().fold(0.0f64, |m, x| m.max(x.abs())));
            }
            println!(
                "{method:?} dt {dt}: vs held {:?}, vs continuous exact {:?}, true err(q inf) {true_err:.3e} est {est:.3e}, {:.3} ms, evals {} est_evals {} jac {}",
                worst(&tr, &r),
                worst(&tr, &e),
                el * 1e3,
                tr.evaluations,
                tr.estimate_evaluations,
                tr.jacobians
            );
        }
    }
}

#[test]
#[ignore]
fn tick() {
    let scene =
        Scene::load(common::repo_dir().join("params/suite_mobile_manipulator.yaml")).unwrap();
    let dt: f64 = std::env::var("DT")
        .ok()
        .and_then(|x| x.parse().ok())
        .unwrap_or(0.01);
    let mut cont = scene.clone();
    cont.file.actuators.hold = Hold::Continuous;
    let mut p = Predictor::from_scene(&cont)
        .unwrap()
        .with_settings(|s| {
            s.method = Method::Ros2;
            s.dt = dt;
            s.error_estimate = true;
            s.max_error = f64::INFINITY;
        })
        .unwrap();
    let cmds = commands(&scene, &p);
    let nv = p.model().nv;
    let mut p0 = nalgebra::DMatrix::zeros(2 * nv, 2 * nv);
    for i in [0, 1, 2, nv, nv + 1, nv + 2] {
        p0[(i, i)] = 1e-4;
    }
    let covs: Vec<bool> = match std::env::var("COV").as_deref() {
        Ok("0") => vec![false],
        Ok("1") => vec![true],
        _ => vec![false, true],
    };
    for cov in covs {
        let t0 = Instant::now();
        let mut tr = None;
        for _ in 0..20 {
            let mut req = PredictionRequest::new(&scene.q0, &scene.v0).commands(&cmds);
            if cov {
                req = req.covariance(&p0);
            }
            tr = Some(p.predict(&req).unwrap());
        }
        let tr = tr.unwrap();
        println!(
            "dt {dt} cov {cov}: {:.3} ms, evals {} est {} jac {} lin {} cov_time {:.3} ms worker {}",
            t0.elapsed().as_secs_f64() / 20.0 * 1e3,
            tr.evaluations,
            tr.estimate_evaluations,
            tr.jacobians,
            tr.covariance_linearizations,
            tr.covariance_time_s * 1e3,
            tr.covariance_on_worker
        );
    }
}
