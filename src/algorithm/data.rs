//! The reusable workspace of the algorithms.

use crate::model::Model;
use crate::spatial::{Force, Motion, OriginInertia, SE3};
use nalgebra::{DMatrix, DVector, Matrix6, Vector6};

/// Up to this many velocity coordinates the workspaces hold their nv × nv matrices from the
/// start (no allocation on the first evaluation); above it they are sized when first needed.
pub const DENSE_EAGER_NV: usize = 256;

/// Every result and intermediate of the algorithms, sized once for a model.
#[derive(Clone, Debug)]
pub struct Data {
    /// `parent_m_body` at the current q.
    pub li_m_i: Vec<SE3>,
    /// `world_m_body` at the current q.
    pub o_m_i: Vec<SE3>,
    /// Body twists in body frames.
    pub v: Vec<Motion>,
    /// Body spatial accelerations in body frames (without the gravity offset).
    pub a: Vec<Motion>,
    /// Body accelerations with the gravity offset (RNEA, ABA).
    pub a_gf: Vec<Motion>,
    /// Body wrenches in body frames (RNEA).
    pub f: Vec<Force>,
    /// World-axes subspace column ᵒS_c of each velocity coordinate c (CRBA), nv.
    pub o_s: Vec<Motion>,
    /// Composite inertias (CRBA), world axes.
    pub ycrb: Vec<OriginInertia>,
    /// Per velocity coordinate c, ᵒY_i ᵒS_c with i its body (CRBA), world axes, nv (a
    /// free-flyer robot's, but for the base's own six, in the base frame after CRBA).
    pub f_crb: Vec<Force>,
    /// Joint-space inertia matrix M(q), nv × nv, symmetric: [`crate::algorithm::crba`] writes
    /// its lower triangle only, `crba_full` and RNEA's derivatives both. Sized by `Data::new`
    /// up to [`DENSE_EAGER_NV`] coordinates; a larger model's is sized by the first call that
    /// computes it (CRBA, RNEA's derivatives), so that its O(n) paths never hold n² entries.
    pub mass_matrix: DMatrix<f64>,
    /// RNEA output τ (or bias h = C v + g when called with q̈ = 0), nv.
    pub tau: DVector<f64>,
    /// ABA output q̈, nv.
    pub qdd: DVector<f64>,
    /// A frame Jacobian, 6 × nv, rows [lin; ang].
    pub jacobian: DMatrix<f64>,
    // ABA workspace.
    pub(crate) ia: Vec<Matrix6<f64>>,
    pub(crate) pa: Vec<Vector6<f64>>,
    pub(crate) u_mat: Vec<Matrix6<f64>>,
    pub(crate) d_inv: Vec<Matrix6<f64>>,
    pub(crate) u_vec: Vec<Vector6<f64>>,
    pub(crate) c: Vec<Motion>,
}

impl Data {
    /// Size every buffer for the model (zero state).
    pub fn new(model: &Model) -> Self {
        let nb = model.nbodies();
        let nv = model.nv;
        Self {
            li_m_i: vec![SE3::identity(); nb],
            o_m_i: vec![SE3::identity(); nb],
            v: vec![Motion::zero(); nb],
            a: vec![Motion::zero(); nb],
            a_gf: vec![Motion::zero(); nb],
            f: vec![Force::zero(); nb],
            o_s: vec![Motion::zero(); nv],
            ycrb: vec![OriginInertia::default(); nb],
            f_crb: vec![Force::zero(); nv],
            mass_matrix: if nv <= DENSE_EAGER_NV {
                DMatrix::zeros(nv, nv)
            } else {
                DMatrix::zeros(0, 0)
            },
            tau: DVector::zeros(nv),
            qdd: DVector::zeros(nv),
            jacobian: DMatrix::zeros(6, nv),
            ia: vec![Matrix6::zeros(); nb],
            pa: vec![Vector6::zeros(); nb],
            u_mat: vec![Matrix6::zeros(); nb],
            d_inv: vec![Matrix6::zeros(); nb],
            u_vec: vec![Vector6::zeros(); nb],
            c: vec![Motion::zero(); nb],
        }
    }
}

impl Data {
    /// Size `mass_matrix` to nv × nv when it is not (a large model's first CRBA).
    pub(crate) fn size_mass_matrix(&mut self, nv: usize) {
        if self.mass_matrix.shape() != (nv, nv) {
            self.mass_matrix = DMatrix::zeros(nv, nv);
        }
    }
}
