//! Random constants that drive the state: the velocity controllers' start offsets, the
//! saturated controllers' grip biases and the skid's slide, carried beside P.
//!
//! **Start offsets.** A PI velocity controller's integral is its joint's travel since the
//! prediction started, `∫(target − q̇) dt = target·t − (q − q(0))`, so the linearized steps
//! carry it as a spring on the joint's position (`Actuators::feedback`): its torque moves by
//! `−ki δq(t)`. That holds for a perturbation that leaves the start position alone; a
//! perturbation of the start position itself (an encoder's uncertainty, `state.joint_noise`)
//! does not reach the controller, which integrates velocity errors, and its share `−ki δq(0)` is
//! given back as a constant torque: the offset `c_j = δq_j(0)`, entering a step through
//! `B[:, j] k_j` (B = ∂x⁺/∂τ of the linearized step, k_j the controller's ki in it: 0 when
//! saturated or without a target). Carried only when the start covariance gives such a position
//! a variance (B costs half as much again per linearization).
//!
//! **Grip biases** (`uncertainty.saturation_bias`). While a controller is saturated its joint
//! accelerates as fast as the grip allows, and how much that is the model knows only roughly
//! (the floor, the load on the wheel as the robot pitches): an acceleration offset `c_j` of
//! variance σ_b², the same through the prediction, acts on the joint's velocity coordinate
//! whenever its controller is saturated. Over a chunk of length h it enters through
//! `h w`, w = u + (A − I) u / 2 with u = T e (e = e_{nv+j} brought onto the constraints by T of
//! the running P's last projection; the transition over the chunk taken linear in time, as for
//! the white noise, mod.rs). A constant, unlike white noise, moves the velocity in
//! proportion to the time spent saturated, not to its square root: a long skid moves it more
//! than a short one in the ratio of their lengths.
//!
//! **Skid slides** (`uncertainty.saturation_slip`). While any velocity controller is
//! saturated the wheels skid, and the base slides at a rate the model knows only roughly: a
//! wheel hops and grips again, the load moves between the wheels and the caster as the robot
//! pitches. A rate offset `c_i` of variance σ_k², the same through the prediction, acts on
//! coordinate i's position while the drive skids, through `h w` with e = e_i: the grip bias's
//! entry moved from the velocity to the position, as the slip noise's is from the acceleration
//! noise's (mod.rs). On the base's two horizontal coordinates it lets the covariance grow
//! across the path as well as along it, where a skid's error goes and a wheel's offset,
//! through the rolling constraints, cannot send it.
//!
//! Either way, with x⁺ = A x + B̃ c:
//!
//! ```text
//! [δx⁺; c] = [[A, B̃], [0, 1]] [δx; c]
//! ```
//!
//! so with P_xc = cov(δx, c) and P_cc = cov(c):
//! `P ← A P Aᵀ + Y B̃ᵀ + B̃ Yᵀ + Z B̃ᵀ`, `P_xc ← Y + Z`, with `Y = A P_xc`, `Z = B̃ P_cc`.
//! The constraint projection acts on P_xc's rows as on P's.

use crate::actuators::Feedback;
use nalgebra::DMatrix;

/// What a constant is, with its joint's v index and its index in the feedback list.
#[derive(Clone, Copy, Debug)]
enum Constant {
    StartOffset { iv: usize, feedback: usize },
    GripBias { iv: usize, feedback: usize },
    SkidSlide { iv: usize },
}

/// cov(δx, c) and cov(c) of the constants (module doc).
#[derive(Clone, Debug)]
pub(in crate::predict) struct ConstantInputs {
    constants: Vec<Constant>,
    p_xc: DMatrix<f64>,
    p_cc: DMatrix<f64>,
    b_tilde: DMatrix<f64>,
    y: DMatrix<f64>,
    tmp: DMatrix<f64>,
}

impl ConstantInputs {
    /// The start offsets of the velocity controllers in `feedback` whose start position has a
    /// variance in `p` (2nv × 2nv, already on the constraints), the grip biases of the
    /// controllers whose joint has a variance in `bias` (σ_b² per v index), and the skid
    /// slides of the coordinates with a variance in `slide` (σ_k² per v index) when a velocity
    /// controller can saturate; None when there is none of them.
    pub(in crate::predict) fn start(
        p: &DMatrix<f64>,
        feedback: &[Feedback],
        bias: &[f64],
        slide: &[f64],
    ) -> Option<Self> {
        let offsets = feedback
            .iter()
            .enumerate()
            .filter(|(_, f)| f.integral && p[(f.iv, f.iv)] > 0.0)
            .map(|(i, f)| Constant::StartOffset {
                iv: f.iv,
                feedback: i,
            });
        let biases = feedback
            .iter()
            .enumerate()
            .filter(|(_, f)| bias.get(f.iv).is_some_and(|&b| b > 0.0))
            .map(|(i, f)| Constant::GripBias {
                iv: f.iv,
                feedback: i,
            });
        let skids = feedback.iter().any(|f| f.integral);
        let slides = (slide.iter().enumerate())
            .filter(move |&(_, &s)| skids && s > 0.0)
            .map(|(iv, _)| Constant::SkidSlide { iv });
        let constants: Vec<Constant> = offsets.chain(biases).chain(slides).collect();
        if constants.is_empty() {
            return None;
        }
        let (n, m) = (p.nrows(), constants.len());
        let mut p_xc = DMatrix::zeros(n, m);
        let mut p_cc = DMatrix::zeros(m, m);
        for (c, a) in constants.iter().enumerate() {
            match *a {
                Constant::StartOffset { iv, .. } => {
                    for r in 0..n {
                        p_xc[(r, c)] = p[(r, iv)];
                    }
                    for (d, b) in constants.iter().enumerate() {
                        if let Constant::StartOffset { iv: jv, .. } = *b {
                            p_cc[(c, d)] = p[(iv, jv)];
                        }
                    }
                }
                Constant::GripBias { iv, .. } => p_cc[(c, c)] = bias[iv],
                Constant::SkidSlide { iv } => p_cc[(c, c)] = slide[iv],
            }
        }
        Some(Self {
            constants,
            p_xc,
            p_cc,
            b_tilde: DMatrix::zeros(n, m),
            y: DMatrix::zeros(n, m),
            tmp: DMatrix::zeros(n, m),
        })
    }

    /// Whether a step needs B = ∂x⁺/∂τ (a start offset enters through it).
    pub(in crate::predict) fn need_inputs(&self) -> bool {
        (self.constants.iter()).any(|c| matches!(c, Constant::StartOffset { .. }))
    }

    /// One linearized step (A, B) of length h [s] under `feedback`: P and P_xc forward (module
    /// doc). Before `p ← A p Aᵀ`, since Y needs A only.
    pub(in crate::predict) fn step(
        &mut self,
        a: &DMatrix<f64>,
        b: &DMatrix<f64>,
        t: &DMatrix<f64>,
        h: f64,
        feedback: &[Feedback],
    ) {
        let nv = a.nrows() / 2;
        let skidding = feedback.iter().any(|f| f.saturated);
        for (c, constant) in self.constants.iter().enumerate() {
            match *constant {
                Constant::StartOffset { iv, feedback: i } => {
                    let k = feedback.get(i).map_or(0.0, |f| f.k);
                    for r in 0..a.nrows() {
                        self.b_tilde[(r, c)] = b[(r, iv)] * k;
                    }
                }
                Constant::GripBias { iv, feedback: i } => {
                    let on = feedback.get(i).is_some_and(|f| f.saturated);
                    set_entry(&mut self.b_tilde, c, (a, t), nv + iv, h, on);
                }
                Constant::SkidSlide { iv } => {
                    set_entry(&mut self.b_tilde, c, (a, t), iv, h, skidding)
                }
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

/// B̃'s column `c` for a constant entering at state index `e` over a chunk of length h, when it
/// acts (`on`): h w = h (A u + u) / 2 with u = T e, the entry on the constraints (T at the
/// running P's last projection); else 0.
fn set_entry(
    b_tilde: &mut DMatrix<f64>,
    c: usize,
    (a, t): (&DMatrix<f64>, &DMatrix<f64>),
    e: usize,
    h: f64,
    on: bool,
) {
    let mut column = b_tilde.column_mut(c);
    if on {
        let u = t.column(e);
        column.gemv(0.5 * h, a, &u, 0.0);
        column.axpy(0.5 * h, &u, 1.0);
    } else {
        column.fill(0.0);
    }
}
