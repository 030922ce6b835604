//! Linearization of one integrator step for planners and covariance propagation:
//! `x⁺ = step(x, u)` with x = (q, v) in the tangent space (δq a right perturbation, q ⊕ δq) and
//! u = τ (the generalized force, held over the step), gives the discrete-time
//! `A = ∂x⁺/∂x` (2nv × 2nv) and `B = ∂x⁺/∂u` (2nv × nv).
//!
//! The step's own sensitivity, not the continuous Jacobian times dt: the variations are carried
//! through every stage of the Munthe-Kaas Runge–Kutta step (integrators/mod.rs) — the stage
//! configuration `q ⊕ Θ_i` (a perturbation δq moves to `Ad(Exp(−Θ_i)) δq + J_r(Θ_i) δΘ_i`), the
//! stage accelerations by the analytic derivatives of the constrained dynamics
//! ([`crate::derivatives`]), and the increments `dexp⁻¹_{−Θ}(v)` by the derivative of the same
//! series. Semi-implicit Euler likewise. The result equals finite differences of the step
//! (tests).

mod frame_forces;
pub(in crate::predict) mod ros2;
mod stages;
use frame_forces::FrameForces;
pub(in crate::predict) use ros2::{linearize_variational_step, ros2_with_step_jacobian};
use stages::{dynamics, stage_acceleration};
pub(in crate::predict) use stages::{dynamics_derivatives, stage_options};

use crate::actuators::Feedback;
use crate::derivatives::DerivativeData;
use crate::dynamics::Baumgarte;
use crate::error::{Error, Result};
use crate::forces::ForceElements;
use crate::linalg::{gemm_columns, mat_vec_add};
use crate::predict::integrators::lie::{StageMaps, dexp_inv, right_jacobian, transport};
use crate::predict::integrators::{Method, Tableau};
use crate::system::System;
use nalgebra::DMatrix;

/// Workspace and result of [`linearize_step`], sized once for a system.
#[derive(Clone, Debug)]
pub struct Linearization {
    /// A = ∂(q⁺, v⁺)/∂(q, v), tangent space, 2nv × 2nv.
    pub a: DMatrix<f64>,
    /// B = ∂(q⁺, v⁺)/∂τ, 2nv × nv.
    pub b: DMatrix<f64>,
    /// Compute B (default true); false leaves `b` untouched and saves a third of the work
    /// (covariance propagation needs A only).
    pub inputs: bool,
    /// Baumgarte gains of the step linearized: the system's own unless the prediction runs
    /// with others (`drift: baumgarte` without the scene's gains).
    pub gains: Baumgarte,
    /// Time [s] at the start of the step being linearized (`linearize_step`'s argument).
    t: f64,
    /// Joint spring-dampers (q index, v index, k, d, rest) recomputed at every stage instead of
    /// held in τ, so that A carries their stiffness and damping
    /// ([`Linearization::with_joint_springs`]), then the controllers' feedback of the step
    /// ([`Linearization::set_feedback`]).
    joint_springs: Vec<(usize, usize, f64, f64, f64)>,
    /// How many of `joint_springs` are the force elements' (the rest is feedback).
    fixed_springs: usize,
    /// The force elements acting at frames, moved to and differentiated at every stage
    /// ([`Linearization::with_frame_forces`]).
    frame_forces: Option<FrameForces>,
    /// τ of the current stage.
    tau_stage: Vec<f64>,
    /// q⁺ (nq) and v⁺ (nv) of the step.
    pub q_next: Vec<f64>,
    /// v⁺ (nv).
    pub v_next: Vec<f64>,
    dd: DerivativeData,
    /// Per stage: Θ_i, V_i, q_i, k_i = (kΘ, kv) and the variations of Θ_i, V_i, kΘ_i, kv_i for
    /// the 3nv seed columns [δq | δv | δτ].
    theta: Vec<Vec<f64>>,
    vel: Vec<Vec<f64>>,
    kth: Vec<Vec<f64>>,
    kv: Vec<Vec<f64>>,
    d_theta: DMatrix<f64>,
    d_vel: DMatrix<f64>,
    d_kth: Vec<DMatrix<f64>>,
    d_kv: Vec<DMatrix<f64>>,
    /// Final increment Θ of the step.
    theta_end: Vec<f64>,
    /// The current stage's Lie maps and δq_i over the seed columns (nv × 3nv).
    maps: StageMaps,
    moved_cols: DMatrix<f64>,
    qs: Vec<f64>,
    x: Vec<f64>,
    y: Vec<f64>,
    dq: Vec<f64>,
    moved: Vec<f64>,
    jr: Vec<f64>,
    /// Power-iteration vectors of [`Self::stiffness`] (2nv each).
    power: [Vec<f64>; 2],
    /// The linearized ROS2 step's matrices.
    ros2: ros2::Ros2Buffers,
}

impl Linearization {
    /// How this step's stages are evaluated: at its start time (plus each stage's offset) with
    /// the run's gains.
    pub(super) fn stage_options(&self) -> crate::dynamics::KktOptions {
        stages::stage_options(self.t, self.gains)
    }

    /// The seed columns carried through the step: [δq | δv] and, with `inputs`, [δτ].
    fn columns(&self) -> usize {
        let nv = self.v_next.len();
        if self.inputs { 3 * nv } else { 2 * nv }
    }

    /// The stiffness of the step's last stage [1/s]: the spectral radius of the continuous
    /// Jacobian `F = [[0, 1], [∂q̈/∂q, ∂q̈/∂v]]` there, estimated by power iteration (the mean
    /// growth per product over iterations 8–24 from a fixed start: within a few % of |λ|max,
    /// also for a complex pair, where a norm bound would be 10× too large for an arm's Coriolis
    /// terms). Steps much longer than its inverse leave an explicit method's stability region.
    pub fn stiffness(&mut self) -> f64 {
        const WARM: usize = 8;
        const COUNT: usize = 16;
        let nv = self.v_next.len();
        let [x, y] = &mut self.power;
        for (i, xi) in x.iter_mut().enumerate() {
            // Fixed, irregular: no special structure to be orthogonal to a mode by accident.
            *xi = 1.0 + ((i * 7919) % 13) as f64 / 13.0;
        }
        let mut log_growth = 0.0;
        for it in 0..WARM + COUNT {
            let norm_x = x.iter().map(|a| a * a).sum::<f64>().sqrt();
            let (xq, xv) = x.split_at(nv);
            let (yq, yv) = y.split_at_mut(nv);
            yq.copy_from_slice(xv);
            mat_vec_add(&self.dd.dqdd_dq, xq, 0.0, yv);
            mat_vec_add(&self.dd.dqdd_dv, xv, 1.0, yv);
            let norm_y = y.iter().map(|a| a * a).sum::<f64>().sqrt();
            if !(norm_y > 0.0 && norm_y.is_finite()) {
                return if norm_y == 0.0 { 0.0 } else { f64::INFINITY };
            }
            if it >= WARM {
                log_growth += (norm_y / norm_x).ln();
            }
            for (xi, yi) in x.iter_mut().zip(y.iter()) {
                *xi = yi / norm_y;
            }
        }
        (log_growth / COUNT as f64).exp()
    }

    /// Joint spring-dampers `τ_i = −k (q_j − rest) − d v_i` (q index j, v index i) to
    /// linearize: the τ given to [`linearize_step`] includes them at the step's start, and each
    /// stage replaces that share by its own.
    pub fn with_joint_springs(mut self, springs: &[(usize, usize, f64, f64, f64)]) -> Self {
        // (iq, iv, k, d, rest) → (iq, iv, k, d, rate): a spring's torque has no rate of its own.
        self.joint_springs = springs
            .iter()
            .map(|&(iq, iv, k, d, _rest)| (iq, iv, k, d, 0.0))
            .collect();
        self.fixed_springs = springs.len();
        self
    }

    /// The force elements of `forces` that act at frames (tyres, turning resistances, frame
    /// forces), linearized at every stage instead of held in τ (linearize/frame_forces.rs): the
    /// τ given to [`linearize_step`] includes their generalized force at the step's start.
    pub fn with_frame_forces(mut self, sys: &System, forces: &ForceElements) -> Self {
        self.frame_forces = FrameForces::new(sys, forces);
        self
    }

    /// The controllers' feedback over the next step (`Actuators::feedback`), linearized as
    /// joint spring-dampers beside the force elements' (replacing the previous step's;
    /// allocates only when the list grows).
    pub fn set_feedback(&mut self, feedback: &[Feedback]) {
        self.joint_springs.truncate(self.fixed_springs);
        let active = feedback
            .iter()
            .filter(|f| f.k != 0.0 || f.d != 0.0 || f.rate != 0.0);
        self.joint_springs
            .extend(active.map(|f| (f.iq, f.iv, f.k, f.d, f.rate)));
    }

    /// Size for a system (its model and constraint rows).
    pub fn new(sys: &System) -> Self {
        let (nq, nv) = (sys.model().nq, sys.model().nv);
        let cols = 3 * nv;
        let stages = crate::predict::integrators::MAX_STAGES;
        Self {
            a: DMatrix::zeros(2 * nv, 2 * nv),
            b: DMatrix::zeros(2 * nv, nv),
            inputs: true,
            gains: sys.baumgarte(),
            t: 0.0,
            joint_springs: vec![],
            fixed_springs: 0,
            frame_forces: None,
            tau_stage: vec![0.0; nv],
            q_next: vec![0.0; nq],
            v_next: vec![0.0; nv],
            dd: DerivativeData::new(sys.model(), sys.constraints().nrows),
            theta: vec![vec![0.0; nv]; stages],
            vel: vec![vec![0.0; nv]; stages],
            kth: vec![vec![0.0; nv]; stages],
            kv: vec![vec![0.0; nv]; stages],
            d_theta: DMatrix::zeros(nv, cols),
            d_vel: DMatrix::zeros(nv, cols),
            d_kth: vec![DMatrix::zeros(nv, cols); stages],
            d_kv: vec![DMatrix::zeros(nv, cols); stages],
            theta_end: vec![0.0; nv],
            maps: StageMaps::new(nv),
            moved_cols: DMatrix::zeros(nv, cols),
            qs: vec![0.0; nq],
            x: vec![0.0; nv],
            y: vec![0.0; nv],
            dq: vec![0.0; nv],
            moved: vec![0.0; nv],
            jr: vec![0.0; nv],
            power: [vec![0.0; 2 * nv], vec![0.0; 2 * nv]],
            ros2: ros2::Ros2Buffers::new(nv),
        }
    }
}

/// One step of `method` from (q, v) at time `t` [s] under the held generalized force τ with
/// step `dt` [s],
/// and its linearization, into `lin`. The methods of [`Method::linearizable`] (the embedded
/// pairs as fixed steps); the others (the implicit SDIRK2 and Radau5) are refused. Drift
/// projection and force elements are not part of this step.
#[allow(clippy::too_many_arguments)]
pub fn linearize_step(
    sys: &mut System,
    lin: &mut Linearization,
    method: Method,
    t: f64,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    dt: f64,
) -> Result<()> {
    prepare_step(sys, lin, t, q, v, dt)?;
    // The method's own linearized step (integrators/, `Step::linearize`): one of the functions
    // below, or a refusal.
    method.linearize(sys, lin, (q, v), tau, dt)
}

/// What every linearized step starts with: the state and step checked, the time, whether
/// ∂q̈/∂τ is needed, the elements acting at frames taken at the start.
pub(super) fn prepare_step(
    sys: &mut System,
    lin: &mut Linearization,
    t: f64,
    q: &[f64],
    v: &[f64],
    dt: f64,
) -> Result<()> {
    sys.model().check_state(q, v)?;
    lin.t = t;
    if !(dt.is_finite() && dt > 0.0) {
        return Err(Error::Invalid(format!(
            "linearize: dt = {dt} s must be finite and > 0"
        )));
    }
    // ∂q̈/∂τ enters only B and the stiffness and damping of the joint springs and the elements
    // acting at frames.
    lin.dd.with_tau = lin.inputs || !lin.joint_springs.is_empty() || lin.frame_forces.is_some();
    if let Some(f) = lin.frame_forces.as_mut() {
        f.start_step(sys, q, v);
    }
    Ok(())
}

/// Seed of column c of [δq | δv | δτ]: (δq, δv, δτ) unit vectors.
fn seed(nv: usize, c: usize, which: usize, i: usize) -> f64 {
    if c / nv == which && c % nv == i {
        1.0
    } else {
        0.0
    }
}

/// The linearized semi-implicit Euler step.
pub(in crate::predict) fn semi_implicit_euler(
    sys: &mut System,
    lin: &mut Linearization,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    dt: f64,
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
    for i in 0..nv {
        lin.v_next[i] = v[i] + dt * lin.dd.qdd[i];
        lin.theta_end[i] = dt * lin.v_next[i];
    }
    sys.model().integrate(q, &lin.v_next, dt, &mut lin.q_next);
    let model = sys.model();
    for c in 0..lin.columns() {
        // δv⁺ = δv + dt (F_q δq + F_v δv + F_τ δτ)
        for i in 0..nv {
            let f = &lin.dd;
            let dqdd = if c < nv {
                f.dqdd_dq[(i, c)]
            } else if c < 2 * nv {
                f.dqdd_dv[(i, c - nv)]
            } else {
                f.dqdd_dtau[(i, c - 2 * nv)]
            };
            lin.y[i] = seed(nv, c, 1, i) + dt * dqdd;
            lin.x[i] = dt * lin.y[i];
            lin.dq[i] = seed(nv, c, 0, i);
        }
        finish_column(model, lin, c);
    }
    Ok(())
}

/// Writes column c of A or B from δq (`lin.dq`), δΘ (`lin.x`) and δv⁺ (`lin.y`) at the final
/// increment Θ (`lin.theta_end`): δq⁺ = Ad(Exp(−Θ)) δq + J_r(Θ) δΘ.
fn finish_column(model: &crate::model::Model, lin: &mut Linearization, c: usize) {
    let nv = model.nv;
    let Linearization {
        a,
        b,
        theta_end,
        x,
        y,
        dq,
        moved,
        jr,
        ..
    } = lin;
    transport(model, theta_end, dq, moved);
    right_jacobian(model, theta_end, x, jr);
    let (out, col) = if c < 2 * nv { (a, c) } else { (b, c - 2 * nv) };
    for i in 0..nv {
        out[(i, col)] = moved[i] + jr[i];
        out[(nv + i, col)] = y[i];
    }
}

/// An explicit Munthe-Kaas RK step (integrators/mod.rs) with its variations, all seed columns at
/// once as matrix products (the stage's Lie maps built once, [`StageMaps`]).
pub(in crate::predict) fn explicit(
    sys: &mut System,
    lin: &mut Linearization,
    tab: &Tableau,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    dt: f64,
) -> Result<()> {
    let nv = v.len();
    let cols = lin.columns();
    // Trailing stages of weight zero (DOPRI5's seventh, there for its error estimate) do not
    // enter the step.
    let stages = tab.b.iter().rposition(|&b| b != 0.0).map_or(0, |i| i + 1);
    let b = &tab.b[..stages];
    for st in 0..stages {
        // Θ_i, V_i and their variations from the earlier stages.
        for i in 0..nv {
            let (mut th, mut ve) = (0.0, v[i]);
            for (j, &a) in tab.a[st].iter().enumerate() {
                th += dt * a * lin.kth[j][i];
                ve += dt * a * lin.kv[j][i];
            }
            lin.theta[st][i] = th;
            lin.vel[st][i] = ve;
        }
        combine_variations(lin, tab.a[st], dt);
        sys.model().integrate(q, &lin.theta[st], 1.0, &mut lin.qs);
        let springs = &lin.joint_springs;
        // The stage's time offset c_i dt (c_i = Σ_j a_ij).
        let ds = dt * tab.a[st].iter().sum::<f64>();
        let stage = (&lin.qs[..], &lin.vel[st][..], ds);
        dynamics(
            sys,
            lin.stage_options(),
            &mut lin.dd,
            springs,
            lin.frame_forces.as_mut(),
            &mut lin.tau_stage,
            (q, v),
            stage,
            tau,
        )?;
        lin.kv[st].copy_from_slice(lin.dd.qdd.as_slice());
        dexp_inv(sys.model(), &lin.theta[st], &lin.vel[st], &mut lin.kth[st]);
        lin.maps
            .build(sys.model(), &lin.theta[st], Some(&lin.vel[st]));
        // δq_i = Ad(Exp(−Θ_i)) δq + J_r(Θ_i) δΘ_i (tangent at q_i); δΘ_i = 0 at a first stage.
        let first = tab.a[st].is_empty();
        stage_variation(lin, st, cols, first);
    }
    // Final combination.
    for i in 0..nv {
        let (mut th, mut ve) = (0.0, v[i]);
        for (j, &bj) in b.iter().enumerate() {
            th += dt * bj * lin.kth[j][i];
            ve += dt * bj * lin.kv[j][i];
        }
        lin.theta_end[i] = th;
        lin.v_next[i] = ve;
    }
    sys.model()
        .integrate(q, &lin.theta_end, 1.0, &mut lin.q_next);
    combine_variations(lin, b, dt);
    lin.maps.build(sys.model(), &lin.theta_end, None);
    tangent_variation(lin, cols, false);
    for c in 0..cols {
        let (out, col) = if c < 2 * nv {
            (&mut lin.a, c)
        } else {
            (&mut lin.b, c - 2 * nv)
        };
        for i in 0..nv {
            out[(i, col)] = lin.moved_cols[(i, c)];
            out[(nv + i, col)] = lin.d_vel[(i, c)];
        }
    }
    Ok(())
}

/// Stage `st`'s right-hand-side variation over the seed columns, from the stage's derivatives
/// (`lin.dd`), its Lie maps (`lin.maps`, built at the stage) and its δΘ_i, δV_i (`d_theta`,
/// `d_vel`): δq_i = Ad(Exp(−Θ_i)) δq + J_r(Θ_i) δΘ_i (tangent at q_i; δΘ_i = 0 at a `first`
/// stage), δkv_i = ∂q̈/∂q δq_i + ∂q̈/∂v δV_i + ∂q̈/∂τ δτ into `d_kv[st]`, and
/// δkΘ_i = ∂dexp⁻¹/∂Θ [δΘ_i] + dexp⁻¹(δV_i) into `d_kth[st]`.
pub(super) fn stage_variation(lin: &mut Linearization, st: usize, cols: usize, first: bool) {
    let nv = lin.v_next.len();
    tangent_variation(lin, cols, first);
    let (f, d_kv) = (&lin.dd, &mut lin.d_kv[st]);
    gemm_columns(d_kv, 1.0, &f.dqdd_dq, &lin.moved_cols, 0.0, cols);
    gemm_columns(d_kv, 1.0, &f.dqdd_dv, &lin.d_vel, 1.0, cols);
    for c in 2 * nv..cols {
        for i in 0..nv {
            d_kv[(i, c)] += f.dqdd_dtau[(i, c - 2 * nv)];
        }
    }
    let d_kth = &mut lin.d_kth[st];
    gemm_columns(d_kth, 1.0, &lin.maps.dexp_inv, &lin.d_vel, 0.0, cols);
    if !first {
        let dexp_inv_dtheta = &lin.maps.dexp_inv_dtheta;
        gemm_columns(d_kth, 1.0, dexp_inv_dtheta, &lin.d_theta, 1.0, cols);
    }
}

/// `d_theta = Σ_j dt w_j δkΘ_j` and `d_vel = δv + Σ_j dt w_j δkv_j` over the seed columns, for
/// a stage's row of A (w = a_i) or the final weights (w = b).
fn combine_variations(lin: &mut Linearization, weights: &[f64], dt: f64) {
    let nv = lin.v_next.len();
    let len = nv * lin.columns();
    let (d_theta, d_vel) = (
        &mut lin.d_theta.as_mut_slice()[..len],
        &mut lin.d_vel.as_mut_slice()[..len],
    );
    d_theta.fill(0.0);
    d_vel.fill(0.0);
    for (j, &w) in weights.iter().enumerate() {
        let kth = &lin.d_kth[j].as_slice()[..len];
        let kv = &lin.d_kv[j].as_slice()[..len];
        for ((t, v), (a, b)) in d_theta
            .iter_mut()
            .zip(d_vel.iter_mut())
            .zip(kth.iter().zip(kv))
        {
            *t += dt * w * a;
            *v += dt * w * b;
        }
    }
    // The seed δv: column nv + i is e_i.
    for i in 0..nv {
        lin.d_vel[(i, nv + i)] += 1.0;
    }
}

/// `moved_cols = Ad(Exp(−Θ)) δq + J_r(Θ) d_theta` over the seed columns, with the maps of
/// the last [`StageMaps::build`] (column i < nv of δq is e_i, the rest zero); `d_theta_zero`:
/// d_theta is known to be zero (a first stage), so only the transport is written.
fn tangent_variation(lin: &mut Linearization, cols: usize, d_theta_zero: bool) {
    let nv = lin.v_next.len();
    if d_theta_zero {
        lin.moved_cols.as_mut_slice()[..nv * cols].fill(0.0);
    } else {
        gemm_columns(
            &mut lin.moved_cols,
            1.0,
            &lin.maps.right_jacobian,
            &lin.d_theta,
            0.0,
            cols,
        );
    }
    for c in 0..nv {
        for i in 0..nv {
            lin.moved_cols[(i, c)] += lin.maps.transport[(i, c)];
        }
    }
}
