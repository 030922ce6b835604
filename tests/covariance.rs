//! Propagated covariance of a prediction against Monte Carlo: start states drawn from the
//! (constraint-projected) start covariance, each propagated through the nonlinear dynamics with
//! the same method and step, their spread at the horizon compared with the propagated
//! covariance (relative Frobenius). And the constraints: the diff drive's lateral body velocity
//! has no variance.
//!
//! The diff drive coasts on an arc (no actuators, no force elements): v = 0.5 m/s,
//! ω = 0.5 rad/s, wheels rolling (r = 0.05 m, track 0.34 m; params/diff_drive.yaml).

mod common;
use common::*;
use constraint_dynamics::predict::Predictor;
use constraint_dynamics::{Model, Scene};
use nalgebra::{DMatrix, DVector};

/// Monte Carlo samples; the sample covariance's own relative error is ~sqrt(2/N) ≈ 2 %.
const N: usize = 4000;
/// Relative Frobenius difference allowed (the bar). Achieved 0.039 (N = 4000; 0.034 and
/// 0.072 with N = 2000 and other seeds: the sampling error dominates).
const TOL: f64 = 0.10;

struct Rng(u64);
impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    /// Standard normal (Box–Muller).
    fn normal(&mut self) -> f64 {
        let (a, b) = (self.uniform(), self.uniform());
        (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos()
    }
}

fn rows_to_matrix(rows: &[Vec<f64>]) -> DMatrix<f64> {
    DMatrix::from_fn(rows.len(), rows.len(), |i, j| rows[i][j])
}

/// (δq, δv) of a state relative to a reference, in the tangent space.
fn tangent(model: &Model, q_ref: &[f64], v_ref: &[f64], q: &[f64], v: &[f64]) -> DVector<f64> {
    let nv = model.nv;
    let mut d = vec![0.0; nv];
    model.difference(q_ref, q, &mut d);
    let mut x = DVector::zeros(2 * nv);
    x.rows_mut(0, nv).copy_from_slice(&d);
    for i in 0..nv {
        x[nv + i] = v[i] - v_ref[i];
    }
    x
}

#[test]
fn diff_drive_covariance_matches_monte_carlo_and_has_no_lateral_velocity_variance() {
    let scene = Scene::load(repo_dir().join("params/diff_drive.yaml")).unwrap();
    let mut pred = Predictor::from_scene(&scene).unwrap();
    // The covariance is under test, not the error estimate: 4000 runs without its companion.
    pred.settings.error_estimate = false;
    let model = pred.sys.model.clone();
    let nv = model.nv;
    let (v_lin, w, r, b) = (0.5, 0.5, 0.05, 0.34);
    let q0 = scene.q0.clone();
    let mut v0 = vec![0.0; nv];
    v0[model.v_index("root_joint:vx_local").unwrap()] = v_lin;
    v0[model.v_index("root_joint:wz").unwrap()] = w;
    v0[model.v_index("left_wheel_joint").unwrap()] = (v_lin - w * b / 2.0) / r;
    v0[model.v_index("right_wheel_joint").unwrap()] = (v_lin + w * b / 2.0) / r;
    let horizon = 1.0;
    // σ = 1 mm / 1 mrad on q, 1 mm/s / 1 mrad/s on v: small, so the spread stays linear.
    let sigma = 1e-3;
    let p0 = DMatrix::identity(2 * nv, 2 * nv) * (sigma * sigma);
    pred.start_covariance = Some(p0);
    let traj = pred.predict(&q0, &v0, &[], horizon).unwrap();
    let first = rows_to_matrix(traj.samples[0].covariance.as_ref().unwrap());
    let last_sample = traj.samples.last().unwrap();
    let p_t = rows_to_matrix(last_sample.covariance.as_ref().unwrap());
    let (q_ref, v_ref) = (last_sample.q.clone(), last_sample.v.clone());

    // The lateral body velocity (vy_local) has no variance: the wheels forbid it.
    let (ix, iy) = (
        nv + model.v_index("root_joint:vx_local").unwrap(),
        nv + model.v_index("root_joint:vy_local").unwrap(),
    );
    eprintln!(
        "achieved var(vy_local)/var(vx_local) = {:.2e}",
        p_t[(iy, iy)] / p_t[(ix, ix)]
    );
    assert!(
        p_t[(iy, iy)] <= 1e-12 * p_t[(ix, ix)],
        "lateral velocity variance {}",
        p_t[(iy, iy)]
    );

    // Monte Carlo from the projected start covariance (its symmetric square root).
    let eig = first.clone().symmetric_eigen();
    let root =
        &eig.eigenvectors * DMatrix::from_diagonal(&eig.eigenvalues.map(|l| l.max(0.0).sqrt()));
    pred.start_covariance = None;
    // Two threads (this machine's cores), each with its own generator and predictor.
    let run = |seed: u64, n: usize| {
        let mut pred = pred.clone();
        let mut rng = Rng(seed);
        (0..n)
            .map(|_| {
                let z = DVector::from_fn(2 * nv, |_, _| rng.normal());
                let dx = &root * z;
                let mut q = vec![0.0; model.nq];
                model.integrate(&q0, dx.rows(0, nv).as_slice(), 1.0, &mut q);
                let v: Vec<f64> = (0..nv).map(|i| v0[i] + dx[nv + i]).collect();
                let t = pred.predict(&q, &v, &[], horizon).unwrap();
                let s = t.samples.last().unwrap();
                tangent(&model, &q_ref, &v_ref, &s.q, &s.v)
            })
            .collect::<Vec<_>>()
    };
    let xs: Vec<DVector<f64>> = std::thread::scope(|sc| {
        let a = sc.spawn(|| run(0x5eed_cafe_f00d_1234, N / 2));
        let b = sc.spawn(|| run(0x00dd_ba11_c0ff_ee99, N - N / 2));
        let mut xs = a.join().unwrap();
        xs.extend(b.join().unwrap());
        xs
    });
    let mut mean = DVector::<f64>::zeros(2 * nv);
    for x in &xs {
        mean += x;
    }
    let mut sum = DMatrix::<f64>::zeros(2 * nv, 2 * nv);
    mean /= N as f64;
    for x in &xs {
        let d = x - &mean;
        sum += &d * d.transpose();
    }
    let mc = sum / (N as f64 - 1.0);
    let rel = (&mc - &p_t).norm() / p_t.norm();
    eprintln!("achieved relative Frobenius |P_mc − P| / |P| = {rel:.3} (N = {N}, tol {TOL})");
    eprintln!("propagated diag: {:.3e}", p_t.diagonal().transpose());
    eprintln!("monte carlo diag: {:.3e}", mc.diagonal().transpose());
    assert!(
        rel <= TOL,
        "covariance differs from Monte Carlo by {rel:.3}"
    );
}
