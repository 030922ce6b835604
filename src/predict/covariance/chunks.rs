//! Covariance steps that span several of the prediction's steps.
//!
//! The covariance needs the flow's sensitivity Φ(t₁, t₀), not one per integrator step: the
//! prediction's step is set by the accuracy and stability of its nominal trajectory, while Φ of
//! a smooth flow is represented as well by one step of the same method over several of them.
//! So the prediction records its steps (start state, held generalized force, size) and, at every
//! sample (where P is read) or when the record is full, [`CovariancePropagator::flush`] covers
//! them with linearized steps of m recorded steps each. A chunk may span control ticks: it holds
//! the torque of its first step, and the check below refuses it where the controllers' torque
//! changed enough to matter.
//!
//! The check that keeps it honest: the linearized step from a chunk's start state also
//! computes that step's end state; the chunk is accepted only if that reproduces the recorded
//! end state to [`CHUNK_RTOL`] of the chunk's motion (tangent-space max norm, q and v apart).
//! Where it does not (a force element that varies within the chunk, a fast transient), the
//! chunk is shortened as a step-size controller would (×0.9·ratio^(−1/(p+1)), at most
//! doubling), down to the single recorded step, which is the exact per-step linearization,
//! by the step's own method (chunks of several DOPRI5 or DOP853 steps are linearized by RK4,
//! `chunk_method`: within RK4's local error).
//! That check cannot see a stiff mode the nominal does not excite (a stiff spring at rest: the
//! long step reproduces the state, but its Φ amplifies perturbations along that mode), so a
//! chunk must also stay inside the method's stability region: H · ρ ≤ [`CHUNK_STABILITY`],
//! ρ = [`Linearization::stiffness`] (the continuous Jacobian's spectral radius at the chunk's
//! last stage), and the next chunk stays within that bound.
//!
//! The steps up to a sample are cut into equal chunks of at most the current length (10 steps
//! with a length of 6 are two of 5, not 6 + 4), and an accepted chunk never shortens the
//! next one: a piece cut short by the sample says nothing against the longer length.
//!
//! A length that was refused by the check is not tried again at once: after a refusal the
//! length may grow only after `wait` accepted chunks, and `wait` doubles with every refusal
//! (up to [`MAX_PATIENCE`]) until a chunk that long is accepted. Controllers that change
//! their torque at every step (PI wheel controllers at a 1 ms control period) refuse every
//! chunk of two steps; without the backoff, growing back to two after each accepted step
//! would cost one refused linearization per step.
//!
//! The acceptance tolerance [`CHUNK_RTOL`] trades P's accuracy against linearizations: at
//! 3e-3 of the motion P stays within 8.2e-4 of finite differences of the whole prediction
//! (tests/it/covariance_sensitivity.rs, mobile manipulator) — a covariance is an uncertainty, and
//! 0.1 % of it is far below what a Monte Carlo check resolves (√(2/N) = 3 % at N = 2000).
//!
//! A ROS2 step hands over the F it stepped with, q̈ at its start and ∂q̈/∂t
//! (`StepRecord::push`): such steps are linearized one by one with them (linearize/ros2.rs, no
//! derivatives of their own; steps with the same F and size share one sensitivity), which costs
//! less than one refused chunk, and a chunk of them would not pass the check where the step
//! damps stiff modes rather than resolving them.
//!
//! Radau5 has no linearized step of its own: its steps are covered one by one by ROS2 substeps
//! under a control of Φ itself (substeps.rs), since a chunk's check sees only the nominal.
//!
//! P is brought onto the constraints (`project`) where the flush ends — a sample, where P is
//! read, or a full record — not after every chunk: the linearized flow keeps it on them to
//! the chunk's accuracy, and the projection costs about a linearization's stage.

use super::CovariancePropagator;
use crate::actuators::Feedback;
use crate::error::Result;
use crate::model::Model;
use crate::predict::covariance::linearize::{
    Linearization, linearize_step, ros2_with_step_jacobian,
};
use crate::predict::integrators::Method;
use crate::system::System;
use nalgebra::DMatrix;

/// Most recorded steps per flush (and per linearized step).
pub(crate) const CHUNK_CAPACITY: usize = 32;
/// A linearized chunk must reproduce the recorded end state to this fraction of the chunk's
/// motion (|Δq|∞ for q, |Δv|∞ for v)...
pub(crate) const CHUNK_RTOL: f64 = 3e-3;
/// ...plus this [m, rad; m/s, rad/s per unit of |v|∞ + 1]: the drift projection's and
/// rounding's share, far below any covariance a prediction reports.
pub(crate) const CHUNK_ATOL: f64 = 1e-10;
/// Most accepted chunks to wait before a refused length is tried again.
pub(crate) const MAX_PATIENCE: usize = 64;
/// Largest H · ρ of a chunk of several steps (RK4's and DOPRI5's stability regions reach
/// |hλ| ≈ 2.8 and 3.3 on the real axis; at 0.5 RK4's Φ is within 3e-4 of exp(Hλ) on the stiffest
/// mode, and far closer on the others).
pub(crate) const CHUNK_STABILITY: f64 = 0.5;

/// The prediction's steps since P was last updated (buffers sized once): what
/// [`CovariancePropagator::flush_record`] covers with linearized chunks.
#[derive(Clone, Debug, Default)]
pub(crate) struct StepRecord {
    /// States at the recorded steps' starts and the last one's end (CHUNK_CAPACITY + 1).
    pub(super) q: Vec<Vec<f64>>,
    pub(super) v: Vec<Vec<f64>>,
    /// Generalized force held over each recorded step [N, N·m] (CHUNK_CAPACITY).
    pub(super) tau: Vec<Vec<f64>>,
    /// The controllers' feedback over each recorded step (`Actuators::feedback`).
    pub(super) feedback: Vec<Vec<Feedback>>,
    /// Time of each recorded state since the first [s] (differences of these are the steps).
    pub(super) t: Vec<f64>,
    /// The prediction's time at the first recorded state [s].
    start: f64,
    /// Each step's own W-method matrix F (2nv × 2nv) and increment (Θ, Δv) before the drift
    /// projection, where the step gave them (ROS2): its linearization then needs no
    /// derivatives and no evaluation.
    jac: Vec<DMatrix<f64>>,
    dx: Vec<Vec<f64>>,
    has_jac: Vec<bool>,
    /// Recorded steps.
    len: usize,
}

impl StepRecord {
    pub(crate) fn new(sys: &System) -> Self {
        let (nq, nv) = (sys.model().nq, sys.model().nv);
        Self {
            q: vec![vec![0.0; nq]; CHUNK_CAPACITY + 1],
            v: vec![vec![0.0; nv]; CHUNK_CAPACITY + 1],
            tau: vec![vec![0.0; nv]; CHUNK_CAPACITY],
            feedback: vec![vec![]; CHUNK_CAPACITY],
            t: vec![0.0; CHUNK_CAPACITY + 1],
            start: 0.0,
            jac: vec![DMatrix::zeros(2 * nv, 2 * nv); CHUNK_CAPACITY],
            dx: vec![vec![0.0; 2 * nv]; CHUNK_CAPACITY],
            has_jac: vec![false; CHUNK_CAPACITY],
            len: 0,
        }
    }

    /// Room for `controllers` feedback controllers (`Actuators::feedback`) in every step, so
    /// that recording one allocates nothing.
    pub(crate) fn reserve_feedback(&mut self, controllers: usize) {
        for f in &mut self.feedback {
            f.reserve(controllers);
        }
    }

    /// Recorded steps.
    pub(super) fn len(&self) -> usize {
        self.len
    }

    /// The prediction's time at recorded state k [s]: where a time-dependent constraint is
    /// evaluated.
    pub(super) fn time(&self, k: usize) -> f64 {
        self.start + self.t[k]
    }

    /// Forget the recorded steps.
    pub(crate) fn clear(&mut self) {
        self.len = 0;
    }

    /// An empty record of the same size, feedback room included.
    pub(crate) fn like(&self, sys: &System) -> Self {
        let mut r = Self::new(sys);
        r.reserve_feedback(self.feedback.first().map_or(0, Vec::capacity));
        r
    }

    /// Append one step of the prediction: from (q0, v0) under the held generalized force τ
    /// [N, N·m] and the controllers' `feedback` for h [s] to (q1, v1) at time t1 [s], with the step's own F
    /// and increment when it has them (`step`). Returns true when the record is full (P
    /// must catch up before the next step).
    pub(crate) fn push(
        &mut self,
        (q0, v0): (&[f64], &[f64]),
        tau: &[f64],
        feedback: impl Iterator<Item = Feedback>,
        step: Option<(&DMatrix<f64>, &[f64])>,
        h: f64,
        (t1, q1, v1): (f64, &[f64], &[f64]),
    ) -> bool {
        let k = self.len;
        if k == 0 {
            self.q[0].copy_from_slice(q0);
            self.v[0].copy_from_slice(v0);
            self.t[0] = 0.0;
            self.start = t1 - h;
        }
        self.tau[k].copy_from_slice(tau);
        self.feedback[k].clear();
        self.feedback[k].extend(feedback);
        self.has_jac[k] = step.is_some();
        if let Some((jac, dx)) = step {
            self.jac[k].copy_from(jac);
            self.dx[k].copy_from_slice(dx);
        }
        self.t[k + 1] = self.t[k] + h;
        self.q[k + 1].copy_from_slice(q1);
        self.v[k + 1].copy_from_slice(v1);
        self.len += 1;
        self.len == CHUNK_CAPACITY
    }
}

/// How the chunks' length is chosen (module doc), carried from one flush to the next.
#[derive(Clone, Debug, Default)]
pub(crate) struct ChunkControl {
    /// Recorded steps per linearized step to try next.
    chunk: usize,
    /// Longest span [s] the last linearization's stiffness allows a chunk
    /// ([`CHUNK_STABILITY`] / ρ): a longer chunk is cut before it is linearized, not refused
    /// after.
    stable_span: f64,
    /// The last length the check refused (0: none since one that long was accepted), the
    /// accepted chunks to wait before growing, and the wait after the next refusal.
    refused: usize,
    wait: usize,
    patience: usize,
    diff: Vec<f64>,
}

impl ChunkControl {
    pub(crate) fn new(sys: &System) -> Self {
        Self {
            chunk: CHUNK_CAPACITY,
            stable_span: f64::INFINITY,
            refused: 0,
            wait: 0,
            patience: 0,
            diff: vec![0.0; sys.model().nv],
        }
    }

    /// How far the linearized step `lin` from state `lo` misses the recorded state `hi`, as a
    /// fraction of what is accepted (≤ 1: reproduced).
    fn mismatch(
        &mut self,
        model: &Model,
        rec: &StepRecord,
        lin: &Linearization,
        (lo, hi): (usize, usize),
    ) -> f64 {
        let max_abs = |x: &[f64]| x.iter().fold(0.0f64, |m, y| m.max(y.abs()));
        model.difference(&rec.q[hi], &lin.q_next, &mut self.diff);
        let err_q = max_abs(&self.diff);
        model.difference(&rec.q[lo], &rec.q[hi], &mut self.diff);
        let motion_q = max_abs(&self.diff);
        let (mut err_v, mut motion_v) = (0.0f64, 0.0f64);
        for i in 0..self.diff.len() {
            err_v = err_v.max((lin.v_next[i] - rec.v[hi][i]).abs());
            motion_v = motion_v.max((rec.v[hi][i] - rec.v[lo][i]).abs());
        }
        let speed = max_abs(&rec.v[hi]);
        (err_q / (CHUNK_RTOL * motion_q + CHUNK_ATOL))
            .max(err_v / (CHUNK_RTOL * motion_v + CHUNK_ATOL * (1.0 + speed)))
    }
}

/// The method of the linearized steps (`Integrator::linearized_as`: the prediction's own, RK4
/// for the embedded pairs); an implicit method's own, which `linearize_step` then refuses.
fn chunk_method(method: Method) -> Method {
    method.integrator().linearized_as().unwrap_or(method)
}

/// Steps of the next chunk after one of `m` steps missed by `ratio` (mismatch): the local
/// error of a p-th order step grows as H^(p+1), so H scales by ratio^(−1/(p+1)), with the
/// usual safety factor 0.9 and at most doubling.
fn next_chunk(m: usize, ratio: f64, order: f64) -> usize {
    let factor = (0.9 * ratio.max(1e-12).powf(-1.0 / (order + 1.0))).min(2.0);
    ((m as f64 * factor).floor() as usize).max(1)
}

impl CovariancePropagator {
    /// Bring P up to the last recorded state (module doc); with `read`, what a sample there
    /// reads (covariance/reading.rs).
    pub fn flush(&mut self, sys: &mut System, method: Method, read: bool) -> Result<()> {
        // The record leaves `self` while P is updated from it (disjoint borrows; no allocation).
        let mut rec = std::mem::take(&mut self.record);
        let result = self.flush_record(sys, method, &mut rec, read);
        self.record = rec;
        result
    }

    /// [`Self::flush`] from a record kept elsewhere (a worker thread's, covariance/worker.rs),
    /// emptied after.
    pub(crate) fn flush_record(
        &mut self,
        sys: &mut System,
        method: Method,
        rec: &mut StepRecord,
        read: bool,
    ) -> Result<()> {
        let start = std::time::Instant::now();
        let mut ctl = std::mem::take(&mut self.chunks);
        let result = (self.flush_chunks(sys, method, rec, &mut ctl))
            .and_then(|()| self.after_flush(sys, rec, read));
        self.chunks = ctl;
        rec.clear();
        self.time_s += start.elapsed().as_secs_f64();
        result
    }

    fn flush_chunks(
        &mut self,
        sys: &mut System,
        method: Method,
        rec: &StepRecord,
        hst: &mut ChunkControl,
    ) -> Result<()> {
        let n = rec.len;
        let mut lo = 0;
        // Steps that bring their own F are linearized one by one with it: no derivatives,
        // cheaper than any chunk (stiff modes the step only damps keep a longer chunk from
        // reproducing it anyway).
        while lo < n && rec.has_jac[lo] && !self.lin.inputs {
            let h = rec.t[lo + 1] - rec.t[lo];
            self.lin.set_feedback(&rec.feedback[lo]);
            let start = (&rec.q[lo][..], &rec.v[lo][..]);
            let step = (&rec.jac[lo], &rec.dx[lo][..]);
            ros2_with_step_jacobian(sys, &mut self.lin, start, h, step)?;
            self.linearizations += 1;
            self.apply_linearization(h, &rec.feedback[lo]);
            lo += 1;
            self.applied(sys, rec, lo, 1)?;
        }
        // Steps without a linearization of their own (Radau5's) are covered one by one, under
        // a control of Φ itself (`variational_substeps`): a chunk's check sees only the nominal.
        if method.integrator().covariance_by_substeps() {
            while lo < n {
                self.lin.set_feedback(&rec.feedback[lo]);
                self.variational_substeps(sys, rec, lo)?;
                lo += 1;
                self.applied(sys, rec, lo, 1)?;
            }
            return Ok(());
        }
        while lo < n {
            // The rest in equal pieces of at most `chunk` steps: no short leftover chunk.
            let rest = n - lo;
            let pieces = rest.div_ceil(hst.chunk);
            let mut m = rest.div_ceil(pieces);
            while m > 1 && rec.t[lo + m] - rec.t[lo] > hst.stable_span {
                m -= 1;
            }
            let hi = lo + m;
            let h = rec.t[hi] - rec.t[lo];
            self.lin.set_feedback(&rec.feedback[lo]);
            // One recorded step is linearized by its own method: an embedded pair's adaptive
            // step on a stiff problem rides its own stability limit (DOPRI5's 3.3 on the real
            // axis), where RK4's Φ (2.8) would grow without bound.
            let lin_method = if m == 1 { method } else { chunk_method(method) };
            linearize_step(
                sys,
                &mut self.lin,
                lin_method,
                rec.time(lo),
                &rec.q[lo],
                &rec.v[lo],
                &rec.tau[lo],
                h,
            )?;
            self.linearizations += 1;
            // Steps of the chunk the stability bound allows (at least one).
            let per_step = h / m as f64;
            // An L-stable method (ROS2) damps the stiff modes at any chunk length.
            hst.stable_span = match chunk_method(method).integrator().stability_limit() {
                Some(_) => CHUNK_STABILITY / self.lin.stiffness(),
                None => f64::INFINITY,
            };
            let stable = (hst.stable_span / per_step).floor();
            let stable = if stable.is_finite() {
                (stable as usize).clamp(1, CHUNK_CAPACITY)
            } else {
                CHUNK_CAPACITY
            };
            let order = f64::from(chunk_method(method).order());
            let ratio = if m > 1 {
                hst.mismatch(sys.model(), rec, &self.lin, (lo, hi))
            } else {
                0.0
            };
            if m > 1 && (m > stable || ratio > 1.0) {
                if ratio > 1.0 {
                    hst.patience = (2 * hst.patience).clamp(1, MAX_PATIENCE);
                    hst.wait = hst.patience;
                    hst.refused = m;
                }
                hst.chunk = next_chunk(m, ratio, order).min(m - 1).min(stable);
                continue;
            }
            self.apply_linearization(h, &rec.feedback[lo]);
            // Between projections the linearized flow keeps P on the constraints to the
            // chunks' accuracy (covariance/reading.rs).
            self.applied(sys, rec, hi, m)?;
            // An accepted chunk never shrinks the next: a piece shorter than `chunk` (the
            // rest before a sample) says nothing against the longer one.
            let grown = if m > 1 {
                next_chunk(m, ratio, order)
            } else {
                2
            };
            if hst.refused > 0 && m >= hst.refused {
                // A chunk as long as the refused one passed: the backoff is over.
                (hst.refused, hst.wait, hst.patience) = (0, 0, 0);
            }
            let grown = if hst.wait > 0 {
                hst.wait -= 1;
                hst.chunk
            } else {
                grown
            };
            hst.chunk = grown.max(hst.chunk).min(stable);
            lo = hi;
        }
        Ok(())
    }
}
