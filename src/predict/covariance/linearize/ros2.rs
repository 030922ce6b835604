//! The linearized ROS2 step (integrators/ros2.rs). Its sensitivity is taken with the step's own
//! matrix F = [[0, 1], [∂q̈/∂q, ∂q̈/∂v]] at the start held through both stages, as the W-method
//! itself holds it: with seeds E (the [δq | δv] unit columns and, for B, [0; ∂q̈/∂τ]),
//!
//! `δk₁ = W⁻¹ F E`, `δk₂ = W⁻¹ (F E + dt F δk₁ − 2 δk₁)`, `δ(increment) = dt (3/2 δk₁ + 1/2 δk₂)`,
//!
//! which is the step's exact sensitivity for a linear flow and within O(dt · ∂F) of it
//! otherwise; the increment then moves to q⁺ as in the explicit steps (the Lie maps of
//! linearize.rs). L-stable, so a chunk of many steps keeps the stiff modes damped. W is
//! factored as the step factors it (integrators/shifted.rs); a step the prediction recorded
//! brings its own increment, so only its sensitivity is computed here.

use super::{Linearization, dynamics, stage_acceleration, stage_variation, tangent_variation};
use crate::error::{Error, Result};
use crate::linalg::gemm_columns;
use crate::predict::integrators::ShiftedFactor;
use crate::predict::integrators::lie::dexp_inv;
use crate::predict::integrators::tableaus::ROS2_GAMMA as GAMMA;
use crate::system::System;
use nalgebra::DMatrix;

/// Buffers of the linearized ROS2 step (2nv = n).
#[derive(Clone, Debug)]
pub(super) struct Ros2Buffers {
    /// F, and W = I − γ dt F factored.
    f: DMatrix<f64>,
    w: ShiftedFactor,
    /// F E, then δk₁, δk₂ over the seed columns (n × 3nv).
    fe: DMatrix<f64>,
    dk1: DMatrix<f64>,
    dk2: DMatrix<f64>,
    k1: Vec<f64>,
    k2: Vec<f64>,
    /// ∂q̈/∂t at the start (nv).
    ft: Vec<f64>,
    /// The increment's variation (`d_theta`, `d_vel`) that `f` gave at this dt [s], when it
    /// came from a recorded step: the next recorded step with the same F (one F serves
    /// `jacobian_spans` steps) and dt takes it without a factorization. "The same dt" is to
    /// [`SAME_DT`]: the recorded sizes of equal steps differ by the rounding of their times.
    sensitivity_dt: Option<f64>,
    d_theta: DMatrix<f64>,
    d_vel: DMatrix<f64>,
}

impl Ros2Buffers {
    pub(super) fn new(nv: usize) -> Self {
        let n = 2 * nv;
        Self {
            f: DMatrix::zeros(n, n),
            w: ShiftedFactor::new(nv),
            fe: DMatrix::zeros(n, 3 * nv),
            dk1: DMatrix::zeros(n, 3 * nv),
            dk2: DMatrix::zeros(n, 3 * nv),
            k1: vec![0.0; n],
            k2: vec![0.0; n],
            ft: vec![0.0; nv],
            sensitivity_dt: None,
            d_theta: DMatrix::zeros(nv, 3 * nv),
            d_vel: DMatrix::zeros(nv, 3 * nv),
        }
    }
}

/// Step sizes within this fraction of each other share a sensitivity (one F per
/// `jacobian_spans` steps of a fixed dt, whose recorded sizes differ by a few ulps of the times).
const SAME_DT: f64 = 1e-12;

/// Solve W x = b for columns 0..cols of `m` in place.
fn solve_columns(w: &ShiftedFactor, m: &mut DMatrix<f64>, cols: usize) {
    let n = m.nrows();
    for col in m.as_mut_slice().chunks_exact_mut(n).take(cols) {
        w.solve(col);
    }
}

/// The linearized ROS2 step from (q, v) under the held τ.
pub(in crate::predict) fn ros2(
    sys: &mut System,
    lin: &mut Linearization,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    dt: f64,
) -> Result<()> {
    at_start(sys, lin, q, v, tau)?;
    sensitivity(lin, dt)?;
    nominal(sys, lin, (q, v), tau, dt, false)?;
    finish(sys, lin, q);
    Ok(())
}

/// A ROS2 step from (q, v) at `t` [s] under τ over `dt` [s] with the variations stepped as the
/// variational equation ([`variational`]), into `lin`: the flow's sensitivity to second order,
/// where `linearize_step` gives the step's own. The covariance's cover for a method without a
/// linearization of its own (Radau5, covariance/substeps.rs).
pub(in crate::predict) fn linearize_variational_step(
    sys: &mut System,
    lin: &mut Linearization,
    t: f64,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    dt: f64,
) -> Result<()> {
    super::prepare_step(sys, lin, t, q, v, dt)?;
    variational(sys, lin, q, v, tau, dt)
}

/// A ROS2 step from (q, v) under the held τ, with the variations stepped as the variational
/// equation δẋ = F(x(t)) δx by the same W-method, not as the step's own sensitivity:
/// W = I − γ dt F₀ for both stages, and the second stage's right-hand side from its own
/// derivatives at the stage (q ⊕ Θ₁, V₁), the perturbation moved there as an explicit stage
/// moves it. A W-method keeps its order with any W, so Φ is second order in dt, where holding
/// F₀ in both stages (as [`ros2`] does, the step's own sensitivity) is first order in dt · Ḟ:
/// a tyre's grip whose slope changes within the step. What covers Radau5's steps under the
/// covariance (covariance/substeps.rs, tests/it/covariance_sensitivity.rs).
pub(in crate::predict) fn variational(
    sys: &mut System,
    lin: &mut Linearization,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    dt: f64,
) -> Result<()> {
    let nv = v.len();
    let cols = lin.columns();
    at_start(sys, lin, q, v, tau)?;
    first_stage_variation(lin, dt)?;
    nominal(sys, lin, (q, v), tau, dt, true)?;
    // The second stage's variation: δΘ₁ = dt δk₁θ, δV₁ = δv + dt δk₁v, the perturbation moved
    // to the stage's tangent space, and its right-hand side's variation there.
    for c in 0..cols {
        for i in 0..nv {
            lin.d_theta[(i, c)] = dt * lin.ros2.dk1[(i, c)];
            lin.d_vel[(i, c)] = dt * lin.ros2.dk1[(nv + i, c)] + f64::from(u8::from(c == nv + i));
        }
    }
    lin.maps
        .build(sys.model(), &lin.theta[0], Some(&lin.vel[0]));
    stage_variation(lin, 0, cols, false);
    let r = &mut lin.ros2;
    for c in 0..cols {
        for i in 0..nv {
            r.dk2[(i, c)] = lin.d_kth[0][(i, c)] - 2.0 * r.dk1[(i, c)];
            r.dk2[(nv + i, c)] = lin.d_kv[0][(i, c)] - 2.0 * r.dk1[(nv + i, c)];
        }
    }
    solve_columns(&r.w, &mut r.dk2, cols);
    increment_variation(lin, dt);
    finish(sys, lin, q);
    Ok(())
}

/// F, q̈ and ∂q̈/∂t at the step's start (q, v) under τ, into `lin.ros2` (and the start's
/// derivatives in `lin.dd`).
fn at_start(
    sys: &mut System,
    lin: &mut Linearization,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
) -> Result<()> {
    let nv = v.len();
    let springs = &lin.joint_springs;
    dynamics(
        sys,
        lin.stage_options(),
        &mut lin.dd,
        springs,
        lin.frame_forces.as_mut(),
        &mut lin.tau_stage,
        (q, v),
        (q, v, 0.0),
        tau,
    )?;
    let r = &mut lin.ros2;
    r.sensitivity_dt = None;
    r.f.fill(0.0);
    for i in 0..nv {
        r.f[(i, nv + i)] = 1.0;
        for j in 0..nv {
            r.f[(nv + i, j)] = lin.dd.dqdd_dq[(i, j)];
            r.f[(nv + i, nv + j)] = lin.dd.dqdd_dv[(i, j)];
        }
    }
    r.k1[nv..].copy_from_slice(lin.dd.qdd.as_slice());
    // ∂q̈/∂t: the controllers' own torque rates through ∂q̈/∂τ (as the step takes it).
    r.ft.iter_mut().for_each(|x| *x = 0.0);
    if lin.dd.with_tau {
        for &(_, iv, _, _, rate) in &lin.joint_springs {
            for i in 0..nv {
                r.ft[i] += lin.dd.dqdd_dtau[(i, iv)] * rate;
            }
        }
    }
    Ok(())
}

/// The linearized ROS2 step the prediction took: under its F (`jac`, its W-method matrix, the
/// controllers' feedback and the joint springs included) and with its increment
/// `dx = (Θ, Δv)`: no derivatives and no evaluation are computed. Only without input
/// columns (B).
pub(in crate::predict) fn ros2_with_step_jacobian(
    sys: &mut System,
    lin: &mut Linearization,
    (q, v): (&[f64], &[f64]),
    dt: f64,
    (jac, dx): (&DMatrix<f64>, &[f64]),
) -> Result<()> {
    let nv = v.len();
    debug_assert!(!lin.inputs);
    let r = &mut lin.ros2;
    let same_f =
        (r.f.as_slice().iter().zip(jac.as_slice())).all(|(a, b)| a.to_bits() == b.to_bits());
    let same_dt = r
        .sensitivity_dt
        .is_some_and(|h| (h - dt).abs() <= SAME_DT * dt);
    if same_dt && same_f {
        lin.d_theta.copy_from(&r.d_theta);
        lin.d_vel.copy_from(&r.d_vel);
    } else {
        r.sensitivity_dt = None;
        r.f.copy_from(jac);
        sensitivity(lin, dt)?;
        let r = &mut lin.ros2;
        r.d_theta.copy_from(&lin.d_theta);
        r.d_vel.copy_from(&lin.d_vel);
        r.sensitivity_dt = Some(dt);
    }
    lin.theta_end.copy_from_slice(&dx[..nv]);
    for i in 0..nv {
        lin.v_next[i] = v[i] + dx[nv + i];
    }
    finish(sys, lin, q);
    Ok(())
}

/// The step's sensitivity with F (`lin.ros2.f`) held through both stages: δk₁, then
/// δk₂ = W⁻¹ (F E + dt F δk₁ − 2 δk₁), and the increment's variation (`d_theta`, `d_vel`).
fn sensitivity(lin: &mut Linearization, dt: f64) -> Result<()> {
    let cols = lin.columns();
    first_stage_variation(lin, dt)?;
    let r = &mut lin.ros2;
    r.dk2.columns_mut(0, cols).copy_from(&r.fe.columns(0, cols));
    gemm_columns(&mut r.dk2, dt, &r.f, &r.dk1, 1.0, cols);
    let n = r.f.nrows();
    for c in 0..cols {
        for i in 0..n {
            r.dk2[(i, c)] -= 2.0 * r.dk1[(i, c)];
        }
    }
    solve_columns(&r.w, &mut r.dk2, cols);
    increment_variation(lin, dt);
    Ok(())
}

/// W = I − γ dt F factored (`lin.ros2.f`, the start's F), F E over the seed columns (F's
/// columns for [δq | δv], then [0; ∂q̈/∂τ] for δτ, from `lin.dd` at the start) and
/// δk₁ = W⁻¹ F E.
fn first_stage_variation(lin: &mut Linearization, dt: f64) -> Result<()> {
    let nv = lin.v_next.len();
    let n = 2 * nv;
    let cols = lin.columns();
    let r = &mut lin.ros2;
    if !r.w.factor(&r.f, dt * GAMMA) {
        return Err(Error::StepTooLarge {
            message: format!("linearize: the ROS2 matrix I − γ dt F is singular at dt = {dt} s"),
        });
    }
    for c in 0..cols {
        for i in 0..n {
            r.fe[(i, c)] = if c < n {
                r.f[(i, c)]
            } else if i >= nv {
                lin.dd.dqdd_dtau[(i - nv, c - n)]
            } else {
                0.0
            };
        }
    }
    r.dk1.columns_mut(0, cols).copy_from(&r.fe.columns(0, cols));
    solve_columns(&r.w, &mut r.dk1, cols);
    Ok(())
}

/// The increment's variation dt (3/2 δk₁ + 1/2 δk₂) into `d_theta` and `d_vel` (δv's seed
/// added).
fn increment_variation(lin: &mut Linearization, dt: f64) {
    let nv = lin.v_next.len();
    let r = &lin.ros2;
    for c in 0..lin.columns() {
        for i in 0..nv {
            let d = |m: &DMatrix<f64>, row| dt * (1.5 * m[(row, c)] + 0.5 * r.dk2[(row, c)]);
            lin.d_theta[(i, c)] = d(&r.dk1, i);
            lin.d_vel[(i, c)] = d(&r.dk1, nv + i) + f64::from(u8::from(c == nv + i));
        }
    }
}

/// The nominal step (`theta_end`, `v_next`) as integrators/ros2.rs takes it, from q̈ at the
/// start (`lin.ros2.k1[nv..]`, set by the caller) and ∂q̈/∂t (`lin.ros2.ft`) with W factored.
/// The second stage's q̈ by a plain evaluation, or with `stage_derivatives` with its
/// derivatives, left in `lin.dd` (and the stage in `lin.theta[0]`, `lin.vel[0]`).
fn nominal(
    sys: &mut System,
    lin: &mut Linearization,
    (q, v): (&[f64], &[f64]),
    tau: &[f64],
    dt: f64,
    stage_derivatives: bool,
) -> Result<()> {
    let nv = v.len();
    let n = 2 * nv;
    let at = lin.stage_options();
    let springs = &lin.joint_springs;
    let r = &mut lin.ros2;
    let gdt = GAMMA * dt;
    r.k1[..nv].copy_from_slice(v);
    for i in 0..nv {
        r.k1[nv + i] += gdt * r.ft[i];
    }
    r.w.solve(&mut r.k1);
    for i in 0..nv {
        lin.theta[0][i] = dt * r.k1[i];
        lin.vel[0][i] = v[i] + dt * r.k1[nv + i];
    }
    sys.model().integrate(q, &lin.theta[0], 1.0, &mut lin.qs);
    let stage = (&lin.qs[..], &lin.vel[0][..], dt);
    let frame = lin.frame_forces.as_mut();
    if stage_derivatives {
        dynamics(
            sys,
            at,
            &mut lin.dd,
            springs,
            frame,
            &mut lin.tau_stage,
            (q, v),
            stage,
            tau,
        )?;
        r.k2[nv..].copy_from_slice(lin.dd.qdd.as_slice());
    } else {
        let qdd = &mut r.k2[nv..];
        stage_acceleration(
            sys,
            at,
            springs,
            frame,
            &mut lin.tau_stage,
            (q, v),
            stage,
            tau,
            qdd,
        )?;
    }
    dexp_inv(sys.model(), &lin.theta[0], &lin.vel[0], &mut r.k2[..nv]);
    for i in 0..n {
        r.k2[i] -= 2.0 * r.k1[i];
    }
    for i in 0..nv {
        r.k2[nv + i] -= gdt * r.ft[i];
    }
    r.w.solve(&mut r.k2);
    for i in 0..nv {
        lin.theta_end[i] = dt * (1.5 * r.k1[i] + 0.5 * r.k2[i]);
        lin.v_next[i] = v[i] + dt * (1.5 * r.k1[nv + i] + 0.5 * r.k2[nv + i]);
    }
    Ok(())
}

/// q⁺ from the increment, and the step's A (and B) with the increment's variation moved there.
fn finish(sys: &mut System, lin: &mut Linearization, q: &[f64]) {
    let nv = lin.v_next.len();
    let n = 2 * nv;
    let cols = lin.columns();
    sys.model()
        .integrate(q, &lin.theta_end, 1.0, &mut lin.q_next);
    lin.maps.build(sys.model(), &lin.theta_end, None);
    tangent_variation(lin, cols, false);
    for c in 0..cols {
        let (out, col) = if c < n {
            (&mut lin.a, c)
        } else {
            (&mut lin.b, c - n)
        };
        for i in 0..nv {
            out[(i, col)] = lin.moved_cols[(i, c)];
            out[(nv + i, col)] = lin.d_vel[(i, c)];
        }
    }
}
