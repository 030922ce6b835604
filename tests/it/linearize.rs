//! `linearize_step`: the discrete-time A = ∂x⁺/∂x and B = ∂x⁺/∂τ of one integrator step
//! against finite differences of the step, on every bundled scene (planar, floating and fixed
//! bases; point and rolling constraints), for semi-implicit Euler, RK4 and DOPRI5; and the
//! step it linearizes is the predictor's own step (same q⁺, v⁺).
//!
//! Differences: central, Richardson-extrapolated (h and h/2), δq on the group (q ⊕ δ).
//! Error: max |X − X_fd| / max(1, max |X_fd|).

use crate::common;
use common::*;
use constraint_dynamics::actuators::Actuators;
use constraint_dynamics::algorithm::{Data, crba};
use constraint_dynamics::constraints::ConstraintKind;
use constraint_dynamics::forces::ForceElements;
use constraint_dynamics::predict::{
    DriftControl, Linearization, Method, PredictionRequest, Predictor, linearize_step,
};
use constraint_dynamics::{Scene, System};
use nalgebra::{DMatrix, DVector};

/// Achieved ≤ 1.4e-10 (the differences' own error), 7e-10 for B on Andrews' gram-scale bodies;
/// the required bar is 1e-7.
const TOL: f64 = 1e-8;
/// Step [s], or ten of the scene's own steps where that is shorter (Andrews' spring: a 1e-5 s
/// scene step; at 0.01 s one explicit step is far outside its stable range).
const DT: f64 = 0.01;

fn step_for(scene: &Scene) -> f64 {
    DT.min(10.0 * Predictor::from_scene(scene).unwrap().config().settings().dt)
}

/// x⁺ of the step as a tangent vector at the unperturbed x⁺: (q⁺ ⊖ q⁺_ref, v⁺).
fn step_out(
    sys: &mut System,
    lin: &mut Linearization,
    method: Method,
    q: &[f64],
    v: &[f64],
    (tau, dt): (&[f64], f64),
    q_ref: &[f64],
) -> DVector<f64> {
    linearize_step(sys, lin, method, 0.0, q, v, tau, dt).unwrap();
    let nv = v.len();
    let mut d = vec![0.0; nv];
    sys.model().difference(q_ref, &lin.q_next, &mut d);
    let mut out = DVector::zeros(2 * nv);
    out.rows_mut(0, nv).copy_from_slice(&d);
    out.rows_mut(nv, nv).copy_from_slice(&lin.v_next);
    out
}

#[test]
fn step_linearization_matches_finite_differences_on_every_bundled_scene() {
    let mut worst = 0.0f64;
    // And the report's floating-base rolling disk.
    let disk = repo_dir().join("params/report/rolling_disk.yaml");
    for p in bundled_scenes().into_iter().chain([disk]) {
        let scene = Scene::load(&p).unwrap();
        let name = p.file_name().unwrap().to_string_lossy().to_string();
        let mut sys = System::from_scene(&scene).unwrap();
        let dt = step_for(&scene);
        // Expression constraints have no analytic derivatives (Unsupported).
        if sys
            .constraints()
            .items
            .iter()
            .any(|c| c.kind() == ConstraintKind::Velocity)
        {
            continue;
        }
        let model = sys.model().clone();
        let nv = model.nv;
        let mut lin = Linearization::new(&sys);
        let mut other = Linearization::new(&sys);
        let (q, v) = (scene.q0.clone(), scene.v0.clone());
        let tau: Vec<f64> = (0..nv).map(|i| 0.3 * ((i + 1) as f64).sin()).collect();
        for method in [Method::SemiImplicitEuler, Method::Rk4, Method::Dopri5] {
            let tag = format!("{name} {method:?}");
            if let Err(e) = linearize_step(&mut sys, &mut lin, method, 0.0, &q, &v, &tau, dt) {
                panic!("{tag}: {e}");
            }
            let q_ref = lin.q_next.clone();
            let (a, b) = (lin.a.clone(), lin.b.clone());
            // Velocity directions: all of them when J has full row rank; with dependent rows
            // (two wheels on one axle) only the admissible ones (J δv = 0), where the step is
            // differentiable — elsewhere it depends on how inconsistent rows are reconciled.
            let j = sys.evaluate_rows(0.0, &q, &v).j.clone();
            let tol = 1e-9 * j.amax().max(1.0);
            let full_rank = j.nrows() == 0 || j.clone().svd(false, false).rank(tol) == j.nrows();
            let dirs_v = if full_rank {
                DMatrix::identity(nv, nv)
            } else {
                // Eigenvectors of JᵀJ (nv × nv) with a zero eigenvalue span null(J).
                let eig = (j.transpose() * &j).symmetric_eigen();
                let top = eig.eigenvalues.amax();
                let n: Vec<_> = (0..nv)
                    .filter(|&k| eig.eigenvalues[k] <= 1e-14 * top)
                    .map(|k| eig.eigenvectors.column(k).into_owned())
                    .collect();
                DMatrix::from_columns(&n)
            };
            let nd = dirs_v.ncols();
            // τ steps scaled by M's diagonal, so that each perturbs its acceleration by ~1e-3
            // whatever the scene's masses (Andrews' bodies weigh grams: a 1e-3 N·m step there
            // is a 100 rad/s² kick, far outside the linear range).
            let m_diag = crba(&model, &mut Data::new(&model), &q).diagonal();
            assert!(
                full_rank || nd == nv - j.clone().svd(false, false).rank(tol),
                "{tag}: null(J)"
            );
            let mut fd_a = DMatrix::zeros(2 * nv, nv + nd);
            let mut fd_b = DMatrix::zeros(2 * nv, nv);
            for c in 0..2 * nv + nd {
                // c < nv: δq = e_c; nv ≤ c < nv + nd: δv = dirs_v[:, c − nv]; then δτ = e.
                let (kind, k) = if c < nv {
                    (0, c)
                } else if c < nv + nd {
                    (1, c - nv)
                } else {
                    (2, c - nv - nd)
                };
                let h = match kind {
                    0 => 1e-4,
                    1 => 1e-3,
                    _ => 1e-3 * m_diag[k].min(1.0).sqrt(),
                };
                let mut at = |t: f64| {
                    let (mut qq, mut vv, mut tt) = (q.clone(), v.clone(), tau.clone());
                    match kind {
                        0 => {
                            let mut e = vec![0.0; nv];
                            e[k] = t;
                            qq = perturbed(&model, &q, &e, 1.0);
                        }
                        1 => vv
                            .iter_mut()
                            .enumerate()
                            .for_each(|(i, x)| *x += t * dirs_v[(i, k)]),
                        _ => tt[k] += t,
                    }
                    step_out(&mut sys, &mut other, method, &qq, &vv, (&tt, dt), &q_ref)
                };
                let d1 = (at(h) - at(-h)) / (2.0 * h);
                let d2 = (at(h / 2.0) - at(-h / 2.0)) / h;
                let col = (d2 * 4.0 - d1) / 3.0;
                match kind {
                    2 => fd_b.set_column(k, &col),
                    _ => fd_a.set_column(c, &col),
                }
            }
            // Ours in the same directions: [A_q | A_v N].
            let mut a_dirs = DMatrix::zeros(2 * nv, nv + nd);
            a_dirs.columns_mut(0, nv).copy_from(&a.columns(0, nv));
            a_dirs
                .columns_mut(nv, nd)
                .copy_from(&(a.columns(nv, nv) * &dirs_v));
            let a = a_dirs;
            for (what, ours, fd) in [("A", &a, &fd_a), ("B", &b, &fd_b)] {
                let e = (ours - fd).amax() / fd.amax().max(1.0);
                eprintln!("achieved {tag} {what}: {e:.2e} (tol {TOL:.0e})");
                assert!(e <= TOL, "{tag} {what}: {e:.3e}\n diff {:.2e}", ours - fd);
                worst = worst.max(e);
            }
        }
    }
    eprintln!("worst: {worst:.2e}");
}

#[test]
fn linearized_step_is_the_predictors_step() {
    for p in bundled_scenes() {
        let scene = Scene::load(&p).unwrap();
        let name = p.file_name().unwrap().to_string_lossy().to_string();
        let forces = ForceElements::new(&scene.model, &scene.file.forces).unwrap();
        let actuators = Actuators::new(&scene.model, &scene.file.actuators).unwrap();
        if !forces.is_empty() || !actuators.is_empty() {
            continue; // the predictor adds force elements and actuator torques to τ
        }
        let mut sys = System::from_scene(&scene).unwrap();
        // Expression constraints have no analytic derivatives (Unsupported).
        if sys
            .constraints()
            .items
            .iter()
            .any(|c| c.kind() == ConstraintKind::Velocity)
        {
            continue;
        }
        let mut lin = Linearization::new(&sys);
        let nv = sys.model().nv;
        for method in [Method::SemiImplicitEuler, Method::Rk4, Method::Dopri5] {
            let mut pred = Predictor::from_scene(&scene)
                .unwrap()
                .with_settings(|s| {
                    s.method = method;
                    s.dt = DT;
                    s.sample_period = DT;
                    s.drift = DriftControl::None;
                    s.rtol = 1e30; // DOPRI5 takes the first step as given
                    // One step compared with its linearization, whatever its accuracy (SIE's
                    // error estimate over this step is 3.7e-3 on the mobile manipulator).
                    s.max_error = f64::INFINITY;
                })
                .unwrap();
            let traj = pred
                .predict(&PredictionRequest::new(&scene.q0, &scene.v0).horizon(DT))
                .unwrap();
            let last = traj.samples.last().unwrap();
            linearize_step(
                &mut sys,
                &mut lin,
                method,
                0.0,
                &scene.q0,
                &scene.v0,
                &vec![0.0; nv],
                DT,
            )
            .unwrap();
            let tag = format!("{name} {method:?}");
            assert_close(&format!("{tag} q+"), &lin.q_next, &last.q, 1e-15);
            assert_close(&format!("{tag} v+"), &lin.v_next, &last.v, 1e-15);
        }
    }
}
