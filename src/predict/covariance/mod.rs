//! Covariance of a prediction: the start state's uncertainty carried through the integrator's
//! own step sensitivity, with process noise, kept on the constraints.
//!
//! State x = (q, v) in the tangent space (δq a right perturbation q ⊕ δq, then δv), P 2nv × 2nv.
//! Per linearized step of size h, `P ← A P Aᵀ + Q_h`, and where P is read (covariance/chunks.rs)
//!
//! `P ← T P Tᵀ`
//!
//! - A = ∂x⁺/∂x of one step of the prediction's method ([`linearize_step`](crate::predict::covariance::linearize::linearize_step), under the
//!   generalized force held over it, with the joint spring-dampers and the controllers'
//!   feedback moving with the state — `Actuators::feedback`; without it P missed the suite's
//!   closed-loop sensitivity by 10³, tests/it/covariance_sensitivity.rs — and so do the
//!   elements acting at frames: tyres, turning resistances, frame forces, point springs,
//!   linearize/frame_forces.rs) that may span several
//!   of the prediction's steps: the
//!   sensitivity of the flow, not of the step size, is what the covariance needs, and one
//!   linearization per 2–32 steps is what makes the covariance cheap (covariance/chunks.rs,
//!   with the check that keeps it honest);
//! - Q_h: white acceleration noise of density σ_i per velocity coordinate (`uncertainty:` in the
//!   scene, [(m/s²)/√Hz] or [(rad/s²)/√Hz], as robot_localization's continuous process noise)
//!   integrated exactly over the step as for a double integrator:
//!   `σ_i² [h³/3, h²/2; h²/2, h]` on (δq_i, δv_i); white effort noise of density σ_τ,i, a
//!   generalized force on the coordinate (`uncertainty.effort_noise`, [(N·m)/√Hz] or [N/√Hz]);
//!   and slip noise of density σ_s,i on the coordinate's position (`uncertainty.slip_noise`,
//!   [m/√s] or [rad/√s]), a random walk `σ_s,i² h` on δq_i outside the dynamics, carried by the
//!   same integral. Each enters on the constraints (covariance/noise.rs);
//! - T keeps P on the tangent space of the constraint manifold {φ_h(q) = 0, J(q) v = 0}:
//!   `T = [[T_q, 0], [−G N T_q, 1 − G J]]` with `G = M⁻¹Jᵀ (J M⁻¹ Jᵀ)⁻¹` (all rows: the
//!   mass-weighted projection that constraint impulses would make), T_q the same projection
//!   with the holonomic rows only (J_h δq = 0), and `N = ∂(J(q) v)/∂δq` at the nominal state:
//!   a pose perturbation changes which velocities are admissible (a tilted rolling disk), so the
//!   admissible δv is the one with `J δv + N δq = 0`, not `J δv = 0`. N by forward differences
//!   of J(q ⊕ εe_k) v (ε = 1e-7: error ~1e-7 of N, far below any covariance's own; nv + 2
//!   constraint evaluations, against 2nv + 1 for central ones); it vanishes
//!   where J does not depend on q in the body frame (the diff drive). Dependent rows are dropped
//!   first.

mod chunks;
mod constants;
pub(in crate::predict) mod linearize;
mod noise;
mod reading;
mod substeps;
pub(in crate::predict) mod worker;

use crate::actuators::Feedback;
use crate::dynamics::Baumgarte;
use crate::error::{Error, Result, check_finite};
use crate::forces::ForceElements;
use crate::linalg::{
    cholesky_in_place, cholesky_solve, gemm_into, semidefinite_cholesky, semidefinite_solve,
};
use crate::predict::covariance::chunks::{ChunkControl, StepRecord};
use crate::predict::covariance::constants::ConstantInputs;
use crate::predict::covariance::linearize::Linearization;
use crate::predict::covariance::noise::NoiseTerms;
use crate::predict::covariance::reading::Reading;
use crate::predict::covariance::substeps::Substeps;
use crate::system::System;
use nalgebra::DMatrix;
pub use noise::UncertaintySpec;
pub(crate) use noise::noise_variances;

/// Propagates a covariance along a prediction (buffers sized once; a step allocates nothing).
#[derive(Clone, Debug)]
pub struct CovariancePropagator {
    /// The current covariance, 2nv × 2nv, order [δq; δv] in the velocity order.
    pub p: DMatrix<f64>,
    /// The process noise's terms and where they enter (covariance/noise.rs).
    noise: NoiseTerms,
    pub(in crate::predict) lin: Linearization,
    /// The prediction's steps not yet in `p`, and how they are cut into chunks
    /// (covariance/chunks.rs).
    pub(in crate::predict) record: StepRecord,
    pub(in crate::predict) chunks: ChunkControl,
    /// The buffers of Radau5's substeps (covariance/substeps.rs).
    substeps: Substeps,
    /// Linearized steps so far, tried ones included, and the wall time of the flushes [s].
    pub(in crate::predict) linearizations: usize,
    pub(in crate::predict) time_s: f64,
    tmp: DMatrix<f64>,
    proj: DMatrix<f64>,
    minv: DMatrix<f64>,
    chol: DMatrix<f64>,
    col: Vec<f64>,
    /// N = ∂(J v)/∂δq (nc × nv), then N T_q; J(q ⊕ εe_k) v; q ⊕ εe_k.
    n_jv: DMatrix<f64>,
    n_tq: DMatrix<f64>,
    jv_at_q: Vec<f64>,
    q_pert: Vec<f64>,
    e_k: Vec<f64>,
    /// Holonomic rows (for T_q) and all rows (for T_v), built at the first projection (the
    /// rows' kinds are known once the constraints were evaluated).
    blocks: Option<[RowProjector; 2]>,
    /// The velocity controllers' start offsets, where P0 gives them a variance
    /// (covariance_integral.rs), and the saturated controllers' grip biases.
    constants: Option<ConstantInputs>,
    /// What a sample reads, and how long since P was projected (covariance/reading.rs).
    pub(in crate::predict) reading: Reading,
}

/// P exactly symmetric (rounding).
fn symmetrize(p: &mut DMatrix<f64>) {
    for i in 0..p.nrows() {
        for j in 0..i {
            let m = 0.5 * (p[(i, j)] + p[(j, i)]);
            p[(i, j)] = m;
            p[(j, i)] = m;
        }
    }
}

/// `P ← A P Aᵀ` for a symmetric P, as `A (A P)ᵀ`: two column-major products and an in-place
/// transpose, no allocation.
fn congruence(p: &mut DMatrix<f64>, a: &DMatrix<f64>, tmp: &mut DMatrix<f64>) {
    gemm_into(tmp, 1.0, a, p, 0.0);
    tmp.transpose_mut();
    gemm_into(p, 1.0, a, tmp, 0.0);
}

/// `1 − M⁻¹J_Rᵀ (J_R M⁻¹ J_Rᵀ)⁻¹ J_R` for a fixed set R of rows, with its buffers.
#[derive(Clone, Debug)]
struct RowProjector {
    rows: Vec<usize>,
    minv_jt: DMatrix<f64>,
    k: DMatrix<f64>,
    dropped: Vec<bool>,
    y: Vec<f64>,
}

impl RowProjector {
    fn new(rows: Vec<usize>, nv: usize) -> Self {
        let nr = rows.len();
        Self {
            rows,
            minv_jt: DMatrix::zeros(nv, nr),
            k: DMatrix::zeros(nr, nr),
            dropped: vec![false; nr],
            y: vec![0.0; nr],
        }
    }

    /// `proj[off.., off..] −= M⁻¹J_Rᵀ K⁺ J_R` (dependent rows dropped).
    fn apply(
        &mut self,
        j: &DMatrix<f64>,
        minv: &DMatrix<f64>,
        proj: &mut DMatrix<f64>,
        off: usize,
    ) {
        let nv = j.ncols();
        let nr = self.rows.len();
        if nr == 0 {
            return;
        }
        for (c, &r) in self.rows.iter().enumerate() {
            for i in 0..nv {
                self.minv_jt[(i, c)] = (0..nv).map(|k| minv[(i, k)] * j[(r, k)]).sum();
            }
        }
        for (a, &ra) in self.rows.iter().enumerate() {
            for b in 0..nr {
                self.k[(a, b)] = (0..nv).map(|i| j[(ra, i)] * self.minv_jt[(i, b)]).sum();
            }
        }
        semidefinite_cholesky(&mut self.k, 1e-9, &mut self.dropped);
        for c in 0..nv {
            for (b, &r) in self.rows.iter().enumerate() {
                self.y[b] = j[(r, c)];
            }
            semidefinite_solve(&self.k, &self.dropped, &mut self.y);
            for i in 0..nv {
                let s: f64 = (0..nr).map(|b| self.minv_jt[(i, b)] * self.y[b]).sum();
                proj[(off + i, off + c)] -= s;
            }
        }
    }

    /// `proj[off.., ..nv] −= M⁻¹J_Rᵀ K⁺ (N T_q)_R`: the velocity correction a pose perturbation
    /// needs (module doc), with the factor of the last [`Self::apply`].
    fn apply_coupling(&mut self, n_tq: &DMatrix<f64>, proj: &mut DMatrix<f64>, off: usize) {
        let nr = self.rows.len();
        if nr == 0 {
            return;
        }
        let nv = n_tq.ncols();
        for c in 0..nv {
            for (b, &r) in self.rows.iter().enumerate() {
                self.y[b] = n_tq[(r, c)];
            }
            semidefinite_solve(&self.k, &self.dropped, &mut self.y);
            for i in 0..nv {
                let s: f64 = (0..nr).map(|b| self.minv_jt[(i, b)] * self.y[b]).sum();
                proj[(off + i, c)] -= s;
            }
        }
    }
}

impl CovariancePropagator {
    /// Sized for `sys`, with the process noise of `spec` (names checked against the model),
    /// linearizing the force elements of `forces` (joint spring-dampers in closed form, the
    /// elements acting at frames by differences: linearize/frame_forces.rs).
    pub fn new(sys: &System, forces: &ForceElements, spec: &UncertaintySpec) -> Result<Self> {
        let (model, nv) = (sys.model(), sys.model().nv);
        Ok(Self {
            p: DMatrix::zeros(2 * nv, 2 * nv),
            noise: NoiseTerms::new(model, spec)?,
            lin: {
                let mut lin = Linearization::new(sys)
                    .with_joint_springs(forces.joint_spring_dampers())
                    .with_frame_forces(sys, forces);
                lin.inputs = false;
                lin
            },
            record: StepRecord::new(sys),
            chunks: ChunkControl::new(sys),
            substeps: Substeps::new(sys),
            linearizations: 0,
            time_s: 0.0,
            tmp: DMatrix::zeros(2 * nv, 2 * nv),
            proj: DMatrix::identity(2 * nv, 2 * nv),
            minv: DMatrix::zeros(nv, nv),
            chol: DMatrix::zeros(nv, nv),
            col: vec![0.0; nv],
            n_jv: DMatrix::zeros(sys.constraints().nrows, nv),
            n_tq: DMatrix::zeros(sys.constraints().nrows, nv),
            jv_at_q: vec![0.0; sys.constraints().nrows],
            q_pert: vec![0.0; sys.model().nq],
            e_k: vec![0.0; nv],
            blocks: None,
            constants: None,
            reading: Reading::new(sys),
        })
    }

    /// A propagator for a prediction from (t, q, v): sized for `sys`, started at `p0` kept on
    /// the constraints, with the controllers of `feedback` (`Actuators::feedback`).
    #[allow(clippy::too_many_arguments)]
    pub fn start(
        sys: &mut System,
        gains: Baumgarte,
        forces: &ForceElements,
        feedback: &[Feedback],
        spec: &UncertaintySpec,
        p0: &DMatrix<f64>,
        (t, q, v): (f64, &[f64], &[f64]),
    ) -> Result<Self> {
        let mut c = Self::new(sys, forces, spec)?;
        c.record.reserve_feedback(feedback.len());
        c.reset(p0)?;
        c.project(sys, t, q, v)?;
        c.start_reading((t, q, v));
        c.constants = ConstantInputs::start(
            &c.p,
            feedback,
            &c.noise.saturation_bias,
            &c.noise.saturation_slip,
        );
        c.lin.inputs = c
            .constants
            .as_ref()
            .is_some_and(ConstantInputs::need_inputs);
        c.lin.gains = gains;
        Ok(c)
    }

    /// Set the start covariance (2nv × 2nv, symmetric, finite, non-negative diagonal).
    pub fn reset(&mut self, p0: &DMatrix<f64>) -> Result<()> {
        let n = self.p.nrows();
        if p0.shape() != (n, n) {
            return Err(Error::Dimension {
                what: "start covariance (2nv × 2nv)".into(),
                expected: n,
                got: p0.nrows(),
            });
        }
        check_finite("start covariance", p0.as_slice())?;
        for i in 0..n {
            if p0[(i, i)] < 0.0 {
                return Err(Error::Invalid(format!(
                    "start covariance: diagonal entry {i} is negative ({})",
                    p0[(i, i)]
                )));
            }
            for j in 0..i {
                if (p0[(i, j)] - p0[(j, i)]).abs() > 1e-12 * (p0[(i, i)] + p0[(j, j)]).max(1e-300) {
                    return Err(Error::Invalid(format!(
                        "start covariance is not symmetric at ({i}, {j})"
                    )));
                }
            }
        }
        self.p.copy_from(p0);
        Ok(())
    }

    /// `P ← A P Aᵀ + Q_h` with A = `self.lin.a` of a step of size h [s] under the controllers'
    /// `feedback` (and the constant inputs: covariance/constants.rs).
    ///
    /// Q_h = ∫₀ʰ Φ(u) Q_c Φ(u)ᵀ du for white acceleration noise Q_c = σ² e eᵀ on velocity
    /// coordinate i (e = T e_{nv+i}, the entry on the constraints; T [0; M⁻¹ e_i] for effort
    /// noise), with the transition over the time u left taken linear in u,
    /// Φ(u) ≈ I + (u/h)(A − I): Q_h = h σ² (w wᵀ + d dᵀ/12), d = (A − I) e, w = e + d/2. Exact
    /// for a free double integrator (σ² [h³/3, h²/2; h²/2, h]); on a joint a controller holds
    /// at rate a, within a relative (ah)²/6 of the exact variance (the free integrator's Q_h
    /// added undamped would be off by ah, and a density would mean more on longer chunks).
    /// Slip noise is the same integral with e = e_i, the coordinate's position: exact wherever
    /// a position perturbation moves the state linearly in time (a yaw slip on a straight
    /// drive, tests/it/covariance_noise.rs).
    pub(in crate::predict) fn apply_linearization(&mut self, h: f64, feedback: &[Feedback]) {
        if let Some(o) = self.constants.as_mut() {
            o.step(
                &self.lin.a,
                &self.lin.b,
                &self.noise.entry_proj,
                h,
                feedback,
            );
        }
        congruence(&mut self.p, &self.lin.a, &mut self.tmp);
        if let Some(o) = self.constants.as_mut() {
            o.add_cross_terms(&mut self.p);
        }
        self.noise.add_white(&mut self.p, &self.lin.a, h);
    }

    /// Keep P on the constraints at (t, q, v): `P ← T P Tᵀ` (module doc).
    pub fn project(&mut self, sys: &mut System, t: f64, q: &[f64], v: &[f64]) -> Result<()> {
        let constrained = self.projector(sys, t, q, v)?;
        if constrained {
            congruence(&mut self.p, &self.proj, &mut self.tmp);
            if let Some(o) = self.constants.as_mut() {
                o.project(&self.proj);
            }
            symmetrize(&mut self.p);
        }
        if self.noise.effort_enters() && !constrained {
            sys.evaluate_rows(t, q, v);
            self.inverse_mass(sys)?;
        }
        self.noise.enter_at(constrained, &self.proj, &self.minv);
        Ok(())
    }

    /// M⁻¹ at the configuration of the last `evaluate_rows` into `minv`.
    fn inverse_mass(&mut self, sys: &mut System) -> Result<()> {
        let nv = self.minv.nrows();
        let m = sys.mass_matrix_after_rows();
        self.chol.view_mut((0, 0), (nv, nv)).copy_from(m);
        cholesky_in_place(&mut self.chol, nv, 1e-14).map_err(|i| Error::SingularMass {
            message: format!(
                "coordinate '{}': the covariance's constraint projection needs M⁻¹",
                sys.model().v_names[i]
            ),
        })?;
        for c in 0..nv {
            self.col.iter_mut().for_each(|x| *x = 0.0);
            self.col[c] = 1.0;
            cholesky_solve(&self.chol, nv, &mut self.col[..nv]);
            for r in 0..nv {
                self.minv[(r, c)] = self.col[r];
            }
        }
        Ok(())
    }

    /// T at (t, q, v) into `proj` (module doc); false without constraints (T = I).
    fn projector(&mut self, sys: &mut System, t: f64, q: &[f64], v: &[f64]) -> Result<bool> {
        let nv = v.len();
        if sys.constraints().is_empty() {
            return Ok(false);
        }
        self.velocity_row_variation(sys, t, q, v);
        self.inverse_mass(sys)?;
        self.proj.as_mut_slice().fill(0.0);
        for i in 0..2 * nv {
            self.proj[(i, i)] = 1.0;
        }
        let blocks = self.blocks.get_or_insert_with(|| {
            let cd = sys.rows();
            let holonomic = (0..cd.j.nrows()).filter(|&r| cd.holonomic[r]).collect();
            [
                RowProjector::new(holonomic, nv),
                RowProjector::new((0..cd.j.nrows()).collect(), nv),
            ]
        });
        let j = &sys.rows().j;
        blocks[0].apply(j, &self.minv, &mut self.proj, 0);
        blocks[1].apply(j, &self.minv, &mut self.proj, nv);
        // N T_q, then the lower-left block −G N T_q.
        let nc = self.n_jv.nrows();
        for r in 0..nc {
            for c in 0..nv {
                self.n_tq[(r, c)] = (0..nv).map(|k| self.n_jv[(r, k)] * self.proj[(k, c)]).sum();
            }
        }
        blocks[1].apply_coupling(&self.n_tq, &mut self.proj, nv);
        Ok(true)
    }

    /// N = ∂(J(q) v)/∂δq by forward differences (module doc), into `n_jv`; leaves the
    /// constraints and the kinematics evaluated at (t, q, v).
    fn velocity_row_variation(&mut self, sys: &mut System, t: f64, q: &[f64], v: &[f64]) {
        const EPS: f64 = 1e-7;
        let jv = &sys.evaluate_rows(t, q, v).jv;
        self.jv_at_q.copy_from_slice(jv.as_slice());
        for k in 0..v.len() {
            self.e_k.iter_mut().for_each(|x| *x = 0.0);
            self.e_k[k] = EPS;
            sys.model().integrate(q, &self.e_k, 1.0, &mut self.q_pert);
            let jv = &sys.evaluate_rows(t, &self.q_pert, v).jv;
            for r in 0..self.jv_at_q.len() {
                self.n_jv[(r, k)] = (jv[r] - self.jv_at_q[r]) / EPS;
            }
        }
        sys.evaluate_rows(t, q, v);
    }
}
