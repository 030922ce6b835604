//! The velocity controllers' integrals in the covariance.
//!
//! A PI velocity controller's integral is its joint's travel since the prediction started,
//! `∫(target − q̇) dt = target·t − (q − q(0))`, so the linearized steps carry it as a spring on
//! the joint's position (`Actuators::feedback`): its torque moves by `−ki δq(t)`. That holds
//! for a perturbation that leaves the start position alone; a perturbation of the start
//! position itself (an encoder's uncertainty, `state.joint_noise`) does not reach the
//! controller, which integrates velocity errors, and its share `−ki δq(0)` is given back as a
//! constant torque: the start offsets `c_j = δq_j(0)` join the state as constants,
//!
//! ```text
//! [δx⁺; c] = [[A, B̃], [0, 1]] [δx; c],   B̃ = Σ_j B[:, j] k_j e_jᵀ
//! ```
//!
//! with B = ∂x⁺/∂τ of the linearized step and k_j the controller's ki in it (0 when saturated
//! or without a target). So, with P_xc = cov(δx, c) and P_cc = cov(c):
//! `P ← A P Aᵀ + Y B̃ᵀ + B̃ Yᵀ + Z B̃ᵀ`, `P_xc ← Y + Z`, with `Y = A P_xc`, `Z = B̃ P_cc`.
//! Carried only when the start covariance gives such a position a variance (B costs half as
//! much again per linearization); the constraint projection acts on P_xc's rows as on P's.

use crate::actuators::Feedback;
use nalgebra::DMatrix;

/// cov(δx, c) and cov(c) of the start offsets of the velocity-controlled joints (module doc).
#[derive(Clone, Debug)]
pub(in crate::predict) struct IntegralOffsets {
    /// Per offset: its joint's v index and its index in the feedback list.
    joints: Vec<(usize, usize)>,
    p_xc: DMatrix<f64>,
    p_cc: DMatrix<f64>,
    b_tilde: DMatrix<f64>,
    y: DMatrix<f64>,
    tmp: DMatrix<f64>,
}

impl IntegralOffsets {
    /// The offsets of the velocity controllers in `feedback` whose start position has a
    /// variance in `p` (2nv × 2nv, already on the constraints); None when none has.
    pub(in crate::predict) fn start(p: &DMatrix<f64>, feedback: &[Feedback]) -> Option<Self> {
        let joints: Vec<(usize, usize)> = feedback
            .iter()
            .enumerate()
            .filter(|(_, f)| f.integral && p[(f.iv, f.iv)] > 0.0)
            .map(|(i, f)| (f.iv, i))
            .collect();
        if joints.is_empty() {
            return None;
        }
        let (n, m) = (p.nrows(), joints.len());
        let p_xc = DMatrix::from_fn(n, m, |r, c| p[(r, joints[c].0)]);
        let p_cc = DMatrix::from_fn(m, m, |r, c| p[(joints[r].0, joints[c].0)]);
        Some(Self {
            joints,
            p_xc,
            p_cc,
            b_tilde: DMatrix::zeros(n, m),
            y: DMatrix::zeros(n, m),
            tmp: DMatrix::zeros(n, m),
        })
    }

    /// One linearized step (A, B) under `feedback`: P and P_xc forward (module doc). Before
    /// `p ← A p Aᵀ`, since Y needs A only.
    pub(in crate::predict) fn step(
        &mut self,
        a: &DMatrix<f64>,
        b: &DMatrix<f64>,
        feedback: &[Feedback],
    ) {
        for (c, &(iv, i)) in self.joints.iter().enumerate() {
            let k = feedback.get(i).map_or(0.0, |f| f.k);
            for r in 0..a.nrows() {
                self.b_tilde[(r, c)] = b[(r, iv)] * k;
            }
        }
        self.y.gemm(1.0, a, &self.p_xc, 0.0);
        // P_xc ← Y + B̃ P_cc (held in p_xc; Z = p_xc − y).
        self.p_xc.copy_from(&self.y);
        self.p_xc.gemm(1.0, &self.b_tilde, &self.p_cc, 1.0);
    }

    /// Adds `Y B̃ᵀ + B̃ Yᵀ + Z B̃ᵀ` to P (after `p ← A p Aᵀ`), with Z = P_xc − Y.
    pub(in crate::predict) fn add_cross_terms(&mut self, p: &mut DMatrix<f64>) {
        // Y B̃ᵀ + B̃ Yᵀ + (P_xc − Y) B̃ᵀ = P_xc B̃ᵀ + B̃ Yᵀ.
        let (n, m) = self.p_xc.shape();
        for s in 0..n {
            for r in 0..n {
                p[(r, s)] += (0..m)
                    .map(|c| {
                        self.p_xc[(r, c)] * self.b_tilde[(s, c)]
                            + self.b_tilde[(r, c)] * self.y[(s, c)]
                    })
                    .sum::<f64>();
            }
        }
    }

    /// `P_xc ← T P_xc` (the constraint projection of P).
    pub(in crate::predict) fn project(&mut self, t: &DMatrix<f64>) {
        self.tmp.gemm(1.0, t, &self.p_xc, 0.0);
        std::mem::swap(&mut self.tmp, &mut self.p_xc);
    }
}
