//! The reusable workspace of the derivative algorithms: world-axes kinematics, the per-column
//! variations and every output matrix, sized once for a model and a number of constraint rows.

use super::rnea::{AngularColumns, Column};
use crate::model::Model;
use crate::spatial::{Force, Motion, OriginInertia};
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

/// Results and intermediates of [`rnea_derivatives`](super::rnea_derivatives),
/// [`aba_derivatives`](super::aba_derivatives) and
/// [`constrained_dynamics_derivatives`](super::constrained_dynamics_derivatives). Nothing
/// allocates after `new`.
#[derive(Clone, Debug)]
pub struct DerivativeData {
    /// ∂τ/∂q of inverse dynamics (nv × nv, tangent columns), minus ∂(Jᵀλ)/∂q at fixed λ when
    /// the constrained derivatives computed it.
    pub dtau_dq: DMatrix<f64>,
    /// ∂τ/∂v of inverse dynamics (nv × nv).
    pub dtau_dv: DMatrix<f64>,
    /// M⁻¹ (nv × nv), which is ∂q̈/∂τ of the unconstrained dynamics.
    pub minv: DMatrix<f64>,
    /// ∂q̈/∂q (nv × nv): unconstrained after `aba_derivatives`, constrained after
    /// `constrained_dynamics_derivatives`.
    pub dqdd_dq: DMatrix<f64>,
    /// ∂q̈/∂v (nv × nv).
    pub dqdd_dv: DMatrix<f64>,
    /// ∂q̈/∂τ (nv × nv): M⁻¹ without constraints, the KKT inverse's upper-left block with them.
    pub dqdd_dtau: DMatrix<f64>,
    /// ∂λ/∂q (nc × nv), λ the force on the robot as in `constraint_forces`.
    pub dlambda_dq: DMatrix<f64>,
    /// ∂λ/∂v (nc × nv).
    pub dlambda_dv: DMatrix<f64>,
    /// ∂λ/∂τ (nc × nv).
    pub dlambda_dtau: DMatrix<f64>,
    /// True when J had full row rank, so λ and its derivatives are unique; otherwise λ (a
    /// minimum-norm choice) has no derivative, the λ derivatives are zero, and only the q̈
    /// derivatives (which are unique) are meaningful.
    pub lambda_unique: bool,
    /// Compute the τ derivatives (default true). False spares the constrained derivatives a
    /// third of the KKT solve and leaves `dqdd_dtau` and `dlambda_dtau` as they were; a
    /// covariance without joint springs needs only ∂q̈/∂(q, v).
    pub with_tau: bool,
    /// q̈ at which the derivatives were taken (nv).
    pub qdd: DVector<f64>,

    // World-axes kinematics of the last pass (index: body; 0 = world).
    pub(crate) o_v: Vec<Motion>,
    /// Spatial accelerations with the gravity offset (base at −g), world axes.
    pub(crate) o_a: Vec<Motion>,
    /// q̈'s share of o_a (the bias form of the passes).
    pub(crate) o_aq: Vec<Motion>,
    /// Each body's wrench of q̈'s share, its world inertia times o_aq, summed leaf to root in
    /// the backward pass (the bias form).
    pub(crate) f_q: Vec<Force>,
    /// Composite wrenches of inverse dynamics (minus the applied point forces), world axes.
    pub(crate) o_f: Vec<Force>,
    /// ᵒS of each velocity coordinate.
    pub(crate) o_s: Vec<Motion>,
    /// Body of each velocity coordinate.
    pub(crate) dof_body: Vec<usize>,
    /// Bodies `b .. subtree_end[b]` are b's subtree (bodies are numbered depth-first).
    pub(crate) subtree_end: Vec<usize>,
    /// Per-column variation of the composite wrenches.
    pub(crate) df: Vec<Force>,
    /// End of each body's subtree in velocity coordinates: `idx_v .. v_end[b]`.
    pub(crate) v_end: Vec<usize>,
    /// Composite world inertia Y, its variation Ẏ and the applied forces' G per body
    /// (rnea.rs), summed leaf to root during the backward pass.
    pub(crate) ycrb: Vec<OriginInertia>,
    pub(crate) dycrb: Vec<AngularColumns>,
    pub(crate) gext: Vec<AngularColumns>,
    /// Whether any point force or moment is applied (G is zero everywhere otherwise).
    pub(crate) has_applied: bool,
    /// The backward pass's 6-vectors per velocity coordinate.
    pub(crate) cols: Vec<Column>,
    /// Point forces applied per body (world axes): Σf, Σ p × f, Σ p fᵀ, Σ p·f.
    pub(crate) ext_f: Vec<Vector3<f64>>,
    pub(crate) ext_m: Vec<Vector3<f64>>,
    pub(crate) ext_pf: Vec<Matrix3<f64>>,
    pub(crate) ext_pdotf: Vec<f64>,
    // Dense scratch of the constrained solve.
    pub(crate) chol: DMatrix<f64>,
    /// M's LTL factor and its diagonal's reciprocals (for M⁻¹).
    pub(crate) ltl: DMatrix<f64>,
    pub(crate) ltl_inv_diag: Vec<f64>,
    /// τ − h of the unconstrained forward dynamics (nv).
    pub(crate) col_scratch: DVector<f64>,
    pub(crate) rows_dq: DMatrix<f64>,
    pub(crate) rows_dv: DMatrix<f64>,
    pub(crate) minv_jt: DMatrix<f64>,
    pub(crate) schur: DMatrix<f64>,
    /// K⁻¹ when J has full row rank.
    pub(crate) schur_inv: DMatrix<f64>,
    pub(crate) dropped: Vec<bool>,
    pub(crate) rhs_v: DMatrix<f64>,
    pub(crate) rhs_c: DMatrix<f64>,
    pub(crate) rhs_c_scratch: DMatrix<f64>,
    pub(crate) r1: DMatrix<f64>,
    /// Orthonormal basis of null(J M⁻¹ Jᵀ) (first columns) when rows are dependent.
    pub(crate) null_basis: DMatrix<f64>,
    pub(crate) n_null: usize,
    /// ρ of the augmented M + ρ JᵀJ used when M alone is singular (0: M itself).
    pub(crate) rho: f64,
}

impl DerivativeData {
    /// Size the workspace for `model` and `nc` constraint rows (0 without constraints).
    pub fn new(model: &Model, nc: usize) -> Self {
        let (nb, nv) = (model.nbodies(), model.nv);
        let mut subtree_end: Vec<usize> = (0..nb).map(|b| b + 1).collect();
        for b in (1..nb).rev() {
            let p = model.bodies[b].parent;
            subtree_end[p] = subtree_end[p].max(subtree_end[b]);
        }
        let mut dof_body = vec![0; nv];
        for b in 1..nb {
            let j = &model.bodies[b].joint;
            dof_body[j.idx_v..j.idx_v + j.kind.nv()].fill(b);
        }
        // Bodies are numbered depth-first and their coordinates in the same order, so each
        // subtree's coordinates are contiguous.
        let v_end: Vec<usize> = (0..nb)
            .map(|b| {
                let e = subtree_end[b];
                if e < nb {
                    model.bodies[e].joint.idx_v
                } else {
                    nv
                }
            })
            .collect();
        let z = |r, c| DMatrix::zeros(r, c);
        Self {
            dtau_dq: z(nv, nv),
            dtau_dv: z(nv, nv),
            minv: z(nv, nv),
            dqdd_dq: z(nv, nv),
            dqdd_dv: z(nv, nv),
            dqdd_dtau: z(nv, nv),
            dlambda_dq: z(nc, nv),
            dlambda_dv: z(nc, nv),
            dlambda_dtau: z(nc, nv),
            lambda_unique: true,
            with_tau: true,
            qdd: DVector::zeros(nv),
            o_v: vec![Motion::zero(); nb],
            o_a: vec![Motion::zero(); nb],
            o_aq: vec![Motion::zero(); nb],
            f_q: vec![Force::zero(); nb],
            o_f: vec![Force::zero(); nb],
            o_s: vec![Motion::zero(); nv],
            dof_body,
            subtree_end,
            df: vec![Force::zero(); nb],
            v_end,
            ycrb: vec![OriginInertia::default(); nb],
            dycrb: vec![AngularColumns::default(); nb],
            gext: vec![AngularColumns::default(); nb],
            has_applied: false,
            cols: vec![Column::default(); nv],
            ext_f: vec![Vector3::zeros(); nb],
            ext_m: vec![Vector3::zeros(); nb],
            ext_pf: vec![Matrix3::zeros(); nb],
            ext_pdotf: vec![0.0; nb],
            chol: z(nv.max(nc), nv.max(nc)),
            ltl: z(nv, nv),
            ltl_inv_diag: vec![0.0; nv],
            col_scratch: DVector::zeros(nv),
            rows_dq: z(nc, nv),
            rows_dv: z(nc, nv),
            minv_jt: z(nv, nc),
            schur: z(nc, nc),
            schur_inv: z(nc, nc),
            dropped: vec![false; nc],
            rhs_v: z(nv, nv),
            rhs_c: z(nc, nv),
            rhs_c_scratch: z(nc, nv),
            r1: z(nv, nv),
            null_basis: z(nc, nc),
            n_null: 0,
            rho: 0.0,
        }
    }

    /// Forget the applied point forces (before a new inverse-dynamics pass).
    pub(crate) fn clear_point_forces(&mut self) {
        self.ext_f.fill(Vector3::zeros());
        self.ext_m.fill(Vector3::zeros());
        self.ext_pf.fill(Matrix3::zeros());
        self.ext_pdotf.fill(0.0);
    }

    /// Apply the world-axes pure moment `m` [N·m] to `body` (fixed in world axes).
    pub(crate) fn add_moment(&mut self, body: usize, m: &Vector3<f64>) {
        self.ext_m[body] += m;
    }

    /// Apply the world-axes force `f` [N] at the world point `p` [m] of `body`; inverse dynamics
    /// then returns τ − (the generalized force of f), and its derivatives include f's lever arm
    /// moving with the body (f itself stays fixed in world axes).
    pub(crate) fn add_point_force(&mut self, body: usize, p: &Vector3<f64>, f: &Vector3<f64>) {
        self.ext_f[body] += f;
        self.ext_m[body] += p.cross(f);
        self.ext_pf[body] += p * f.transpose();
        self.ext_pdotf[body] += p.dot(f);
    }
}
