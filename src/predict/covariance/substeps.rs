//! Radau5's steps under the covariance: Radau IIA has no linearized step of its own, so each
//! recorded step is covered by ROS2 steps of the variational equation, in as many substeps as
//! settle Φ (`variational_substeps`).

use super::CovariancePropagator;
use super::chunks::StepRecord;
use super::linearize::linearize_variational_step;
use crate::error::Result;
use crate::linalg::{gemm_columns, gemm_into};
use crate::system::System;
use nalgebra::DMatrix;

/// Most substeps per recorded step.
pub(crate) const MAX_SUBSTEPS: usize = 32;
/// The substeps' composed A is accepted when halving them changes it by this fraction.
pub(crate) const SUBSTEP_RTOL: f64 = 3e-2;

/// A substep's start and held τ, the composed A and B, the last composition's A, and the
/// products' scratch (sized once).
#[derive(Clone, Debug, Default)]
pub(crate) struct Substeps {
    q: Vec<f64>,
    v: Vec<f64>,
    tau: Vec<f64>,
    a_acc: DMatrix<f64>,
    b_acc: DMatrix<f64>,
    a_prev: DMatrix<f64>,
    scratch: DMatrix<f64>,
    scratch_b: DMatrix<f64>,
}

impl Substeps {
    pub(crate) fn new(sys: &System) -> Self {
        let (nq, nv) = (sys.model().nq, sys.model().nv);
        Self {
            q: vec![0.0; nq],
            v: vec![0.0; nv],
            tau: vec![0.0; nv],
            a_acc: DMatrix::zeros(2 * nv, 2 * nv),
            b_acc: DMatrix::zeros(2 * nv, nv),
            a_prev: DMatrix::zeros(2 * nv, 2 * nv),
            scratch: DMatrix::zeros(2 * nv, 2 * nv),
            scratch_b: DMatrix::zeros(2 * nv, nv),
        }
    }
}

impl CovariancePropagator {
    /// Apply recorded step `lo` of a method without a linearization of its own (Radau5:
    /// `Integrator::covariance_by_substeps`), covered by ROS2 steps stepping the variational
    /// equation (linearize/ros2.rs, `variational`: L-stable as Radau IIA is, second order in
    /// Φ). Radau's step is set by its nominal's error and can be long against a mode the
    /// nominal hardly excites (an arm held still by its PD, at h|λ| near 1), where one such step
    /// leaves Φ off while the state is reproduced. So Φ itself is controlled, as an
    /// extrapolation would: the step is covered by 1, 2, 4, … equal substeps, each linearized
    /// from the last one's end state under the recorded τ moved there and composed, until two
    /// successive compositions agree to [`SUBSTEP_RTOL`] (‖ΔA‖ / ‖A‖, Frobenius, over A's
    /// configuration rows: the tyres' slip modes at 10⁴ /s are damped to nothing at any
    /// substep, while their velocity entries would refine it to their time scale), at most
    /// [`MAX_SUBSTEPS`]; the finer of the two is applied.
    pub(super) fn variational_substeps(
        &mut self,
        sys: &mut System,
        rec: &StepRecord,
        lo: usize,
    ) -> Result<()> {
        // The buffers leave `self` while `self.lin` and P are updated (disjoint borrows; a
        // default Substeps holds no allocation).
        let mut sub = std::mem::take(&mut self.substeps);
        let result = self.substeps_with(sys, rec, lo, &mut sub);
        self.substeps = sub;
        result
    }

    fn substeps_with(
        &mut self,
        sys: &mut System,
        rec: &StepRecord,
        lo: usize,
        sub: &mut Substeps,
    ) -> Result<()> {
        let h = rec.t[lo + 1] - rec.t[lo];
        let cols_b = if self.lin.inputs {
            self.lin.b.ncols()
        } else {
            0
        };
        let (q, v) = (&rec.q[lo][..], &rec.v[lo][..]);
        linearize_variational_step(sys, &mut self.lin, rec.time(lo), q, v, &rec.tau[lo], h)?;
        self.linearizations += 1;
        sub.a_prev.copy_from(&self.lin.a);
        let mut k = 2;
        loop {
            let dt = h / k as f64;
            sub.q.copy_from_slice(&rec.q[lo]);
            sub.v.copy_from_slice(&rec.v[lo]);
            for i in 0..k {
                let t = rec.time(lo) + i as f64 * dt;
                let (q, v) = (&sub.q[..], &sub.v[..]);
                // The recorded τ is held from the step's start: a substep holds it as moved
                // to its own start.
                let start = (&rec.q[lo][..], &rec.v[lo][..]);
                let ds = i as f64 * dt;
                (self.lin).torque_at(sys, start, &rec.tau[lo], (q, v, ds), &mut sub.tau);
                linearize_variational_step(sys, &mut self.lin, t, q, v, &sub.tau, dt)?;
                self.linearizations += 1;
                if i == 0 {
                    sub.a_acc.copy_from(&self.lin.a);
                    sub.b_acc
                        .columns_mut(0, cols_b)
                        .copy_from(&self.lin.b.columns(0, cols_b));
                } else {
                    // A ← A_i A, B ← A_i B + B_i
                    gemm_into(&mut sub.scratch, 1.0, &self.lin.a, &sub.a_acc, 0.0);
                    sub.a_acc.copy_from(&sub.scratch);
                    if cols_b > 0 {
                        let s = &mut sub.scratch_b;
                        gemm_columns(s, 1.0, &self.lin.a, &sub.b_acc, 0.0, cols_b);
                        for c in 0..cols_b {
                            for r in 0..s.nrows() {
                                sub.b_acc[(r, c)] = s[(r, c)] + self.lin.b[(r, c)];
                            }
                        }
                    }
                }
                sub.q.copy_from_slice(&self.lin.q_next);
                sub.v.copy_from_slice(&self.lin.v_next);
            }
            let nv = rec.v[lo].len();
            let (mut diff2, mut norm2) = (0.0, 0.0);
            for c in 0..2 * nv {
                for r in 0..nv {
                    let (x, y) = (sub.a_acc[(r, c)], sub.a_prev[(r, c)]);
                    diff2 += (x - y) * (x - y);
                    norm2 += x * x;
                }
            }
            let change = (diff2 / norm2.max(f64::MIN_POSITIVE)).sqrt();
            if change <= SUBSTEP_RTOL || 2 * k > MAX_SUBSTEPS {
                break;
            }
            sub.a_prev.copy_from(&sub.a_acc);
            k *= 2;
        }
        self.lin.a.copy_from(&sub.a_acc);
        if cols_b > 0 {
            self.lin
                .b
                .columns_mut(0, cols_b)
                .copy_from(&sub.b_acc.columns(0, cols_b));
        }
        self.apply_linearization(h, &rec.feedback[lo]);
        Ok(())
    }
}
