//! Constrained dynamics that depend on no coordinate: a planar base on flat ground rolling on
//! axisymmetric wheels (the diff drive), a cart on a level rail. In the base's body axes, M and
//! the rolling rows are then the same at every configuration, the velocity stays in J's null
//! space N, and q̈ is a quadratic form of the velocity plus a linear map of the force:
//!
//! `q̈ = a₀ + A τ + Σ_{j≤k} c_jk u_j u_k`, `u = Nᵀ v`,
//!
//! with A (nv × nv), the c_jk (nv each) and N (nv × nu, orthonormal) constant. Fitted from the
//! full multiplier evaluation at one configuration and accepted only where it reproduces that
//! evaluation at random configurations, velocities on N and forces ([`InvariantDynamics::fit`]);
//! one evaluation then costs ≈ nv (nv + nu²) flops instead of kinematics, CRBA, the rows and
//! their solve (docs/performance.md, "Rollouts for sampling planners").

use crate::constraints::Constraint;
use crate::linalg::by_size;
use crate::system::{DynamicsOptions, System};
use nalgebra::{DMatrix, SymmetricEigen};

/// The largest null space the form is built for (the stack holds u).
const MAX_U: usize = 8;
/// Random configurations the fit must reproduce.
const CHECKS: usize = 32;
/// Accepted disagreement with the full evaluation, relative to max(1, |q̈|∞): rounding of the
/// full evaluation's factorizations, far below any integration error.
const TOLERANCE: f64 = 1e-9;

/// q̈ as a constant quadratic form of the velocity and linear map of the force (module doc).
#[derive(Clone, Debug)]
pub struct InvariantDynamics {
    nv: usize,
    nu: usize,
    /// q̈ at v = 0, τ = 0 (nv).
    a0: Vec<f64>,
    /// ∂q̈/∂τ, column-major (nv × nv).
    a: Vec<f64>,
    /// J's null space, orthonormal columns, column-major (nv × nu).
    n: Vec<f64>,
    /// I − N Nᵀ, the projector off N, column-major (nv × nv).
    off: Vec<f64>,
    /// The coefficient of u_j u_k (j ≤ k, in that order), column-major (nv × nu(nu+1)/2).
    c: Vec<f64>,
}

impl InvariantDynamics {
    /// The form of `sys`'s constrained dynamics, fitted at `q0`, if it has one: only velocity
    /// constraints of rolling wheels and knife edges (no time, no position rows), no Baumgarte
    /// gains, and every one of [`CHECKS`] random states reproduced to [`TOLERANCE`]. Leaves
    /// `sys`'s workspaces at the last state it evaluated.
    pub fn fit(sys: &mut System, q0: &[f64]) -> Option<Self> {
        let eligible = !sys.constraints().is_empty()
            && (sys.constraints().items.iter()).all(|c| match c {
                // A turn gain makes the rows depend on the velocity; a contact whose sideways
                // grip is a tyre's has the tyre's force beside its row.
                Constraint::Rolling(rc) => rc.axle_offset_turn_gain == 0.0 && !rc.lateral_free(),
                Constraint::NoSideSlip(_) => true,
                _ => false,
            })
            && sys.baumgarte() == Default::default();
        if !eligible {
            return None;
        }
        let nv = sys.model().nv;
        let zero = vec![0.0; nv];
        let full = |sys: &mut System, q: &[f64], v: &[f64], tau: &[f64]| {
            (sys.forward_dynamics_with(q, v, tau, DynamicsOptions::default())
                .ok())
            .map(|qdd| qdd.as_slice().to_vec())
        };
        let a0 = full(sys, q0, &zero, &zero)?;
        if sys.rows().holonomic.iter().any(|&h| h) {
            // A wheel's normal row (a floating base): positions drift, and the projection that
            // corrects them needs the rows.
            return None;
        }
        let n = null_space(&sys.rows().j)?;
        let nu = n.ncols();
        if nu == 0 || nu > MAX_U {
            return None;
        }
        let mut a = Vec::with_capacity(nv * nv);
        let mut e = zero.clone();
        for j in 0..nv {
            e[j] = 1.0;
            let r = full(sys, q0, &zero, &e)?;
            a.extend(r.iter().zip(&a0).map(|(r, a0)| r - a0));
            e[j] = 0.0;
        }
        // The diagonal terms from u = e_j, the cross terms from u = e_j + e_k by polarization.
        let along = |u: &[f64]| -> Vec<f64> {
            (0..nv)
                .map(|i| (0..nu).map(|k| n[(i, k)] * u[k]).sum())
                .collect()
        };
        let mut unit = vec![vec![0.0; nv]; nu];
        for (j, f) in unit.iter_mut().enumerate() {
            let mut u = vec![0.0; nu];
            u[j] = 1.0;
            let r = full(sys, q0, &along(&u), &zero)?;
            *f = r.iter().zip(&a0).map(|(r, a0)| r - a0).collect();
        }
        let mut c = Vec::with_capacity(nv * nu * (nu + 1) / 2);
        for j in 0..nu {
            for k in j..nu {
                if j == k {
                    c.extend_from_slice(&unit[j]);
                    continue;
                }
                let mut u = vec![0.0; nu];
                (u[j], u[k]) = (1.0, 1.0);
                let r = full(sys, q0, &along(&u), &zero)?;
                c.extend((0..nv).map(|i| r[i] - a0[i] - unit[j][i] - unit[k][i]));
            }
        }
        let form = Self {
            nv,
            nu,
            a0,
            a,
            n: n.as_slice().to_vec(),
            off: (DMatrix::identity(nv, nv) - &n * n.transpose())
                .as_slice()
                .to_vec(),
            c,
        };
        // Reproduced at random states, or refused: a coordinate that M, h or the rows depend
        // on shows at the first of them.
        let mut rng = XorShift(0x9e37_79b9_7f4a_7c15);
        let (mut q, mut dq, mut tau) = (q0.to_vec(), vec![0.0; nv], vec![0.0; nv]);
        let mut fast = vec![0.0; nv];
        for _ in 0..CHECKS {
            dq.iter_mut().for_each(|x| *x = 3.0 * rng.uniform());
            sys.model().integrate(q0, &dq, 1.0, &mut q);
            let u: Vec<f64> = (0..nu).map(|_| 10.0 * rng.uniform()).collect();
            tau.iter_mut().for_each(|x| *x = 10.0 * rng.uniform());
            let v = along(&u);
            let reference = full(sys, &q, &v, &tau)?;
            form.accel(&v, &tau, &mut fast);
            let bound = TOLERANCE * reference.iter().fold(1.0f64, |m, x| m.max(x.abs()));
            // Written so that a NaN on either side refuses the form.
            let close = |(a, b): (&f64, &f64)| (a - b).abs() <= bound;
            if !bound.is_finite() || !fast.iter().zip(&reference).all(close) {
                return None;
            }
        }
        Some(form)
    }

    /// Whether `v` lies in J's null space to `tol` (max |v − N Nᵀ v|): J is constant in body
    /// axes and every q̈ of the form lies in N, so a step keeps v there to rounding, and the
    /// drift projection has nothing to do unless this says otherwise.
    pub fn on_constraints(&self, v: &[f64], tol: f64) -> bool {
        by_size!(
            self.nv,
            on_constraints_n(self, v, tol),
            on_constraints_body(self, self.nv, v, tol)
        )
    }

    /// q̈ (nv) at velocity `v` and generalized force `tau`: the form, with v taken by its part
    /// on the constraints (u = Nᵀ v; a stage off them by its step's error loses that part).
    pub fn accel(&self, v: &[f64], tau: &[f64], qdd: &mut [f64]) {
        by_size!(
            self.nv,
            accel_n(self, v, tau, qdd),
            accel_body(self, self.nv, v, tau, qdd)
        )
    }

    /// The form's derivatives at velocity `v` (all nv × nv): ∂q̈/∂q = 0 (no coordinate enters
    /// it), ∂q̈/∂τ = A, and ∂q̈/∂v = Σ_{j≤k} c_jk (u_k n_j + u_j n_k)ᵀ with n_j N's columns — the
    /// exact Jacobian of what the form integrates (zero along velocities off N, which it takes
    /// by their part on N).
    pub fn derivatives(
        &self,
        v: &[f64],
        dqdd_dq: &mut DMatrix<f64>,
        dqdd_dv: &mut DMatrix<f64>,
        dqdd_dtau: &mut DMatrix<f64>,
    ) {
        let (nv, nu) = (self.nv, self.nu);
        let u = coordinates(self, nv, v);
        dqdd_dq.fill(0.0);
        dqdd_dv.fill(0.0);
        dqdd_dtau.as_mut_slice().copy_from_slice(&self.a);
        let (n, dv) = (&self.n[..nv * nu], dqdd_dv.as_mut_slice());
        let mut cols = self.c.chunks_exact(nv);
        for j in 0..nu {
            for k in j..nu {
                let col = cols.next().unwrap_or_default();
                // ∂(u_j u_k)/∂v = u_k n_j + u_j n_k.
                for (c, dvc) in dv.chunks_exact_mut(nv).enumerate() {
                    let w = u[k] * n[j * nv + c] + u[j] * n[k * nv + c];
                    if w != 0.0 {
                        for (x, &ci) in dvc.iter_mut().zip(col) {
                            *x += ci * w;
                        }
                    }
                }
            }
        }
    }
}

// The kernels: one body each, built for each nv up to linalg::FIXED_MAX (linalg/sized.rs).

fn on_constraints_n<const NV: usize>(form: &InvariantDynamics, v: &[f64], tol: f64) -> bool {
    on_constraints_body(form, NV, v, tol)
}

/// max |(I − N Nᵀ) v| ≤ tol.
#[inline(always)]
fn on_constraints_body(form: &InvariantDynamics, nv: usize, v: &[f64], tol: f64) -> bool {
    let (v, off) = (&v[..nv], &form.off[..nv * nv]);
    (0..nv).all(|i| {
        let mut r = 0.0;
        for (c, &vc) in v.iter().enumerate() {
            r += off[c * nv + i] * vc;
        }
        r.abs() <= tol
    })
}

fn accel_n<const NV: usize>(form: &InvariantDynamics, v: &[f64], tau: &[f64], qdd: &mut [f64]) {
    accel_body(form, NV, v, tau, qdd)
}

/// The form (module doc).
#[inline(always)]
fn accel_body(form: &InvariantDynamics, nv: usize, v: &[f64], tau: &[f64], qdd: &mut [f64]) {
    let nu = form.nu;
    let np = nu * (nu + 1) / 2;
    let (v, tau, qdd) = (&v[..nv], &tau[..nv], &mut qdd[..nv]);
    let (a, c) = (&form.a[..nv * nv], &form.c[..nv * np]);
    let u = coordinates(form, nv, v);
    qdd.copy_from_slice(&form.a0[..nv]);
    for (col, &t) in a.chunks_exact(nv).zip(tau) {
        if t != 0.0 {
            for (x, &a) in qdd.iter_mut().zip(col) {
                *x += a * t;
            }
        }
    }
    // The columns of c in the order of the pairs j ≤ k.
    let mut cols = c.chunks_exact(nv);
    for j in 0..nu {
        for k in j..nu {
            let (w, col) = (u[j] * u[k], cols.next().unwrap_or_default());
            for (x, &c) in qdd.iter_mut().zip(col) {
                *x += c * w;
            }
        }
    }
}

/// u = Nᵀ v (the first nu entries).
#[inline(always)]
fn coordinates(form: &InvariantDynamics, nv: usize, v: &[f64]) -> [f64; MAX_U] {
    let mut u = [0.0; MAX_U];
    for (uk, col) in u.iter_mut().zip(form.n.chunks_exact(nv)) {
        let mut sum = 0.0;
        for (&n, &v) in col.iter().zip(&v[..nv]) {
            sum += n * v;
        }
        *uk = sum;
    }
    u
}

/// An orthonormal basis of J's null space (nv × nu): the eigenvectors of JᵀJ whose eigenvalue
/// is rounding against its largest. None if the eigen-solver fails.
fn null_space(j: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let nv = j.ncols();
    let eig = SymmetricEigen::try_new(j.transpose() * j, 1e-15, 1000)?;
    let top = eig.eigenvalues.amax().max(f64::MIN_POSITIVE);
    let keep: Vec<usize> = (0..nv)
        .filter(|&i| eig.eigenvalues[i].abs() <= 1e-12 * top)
        .collect();
    Some(DMatrix::from_fn(nv, keep.len(), |r, c| {
        eig.eigenvectors[(r, keep[c])]
    }))
}

/// Deterministic uniform numbers in [−1, 1) for the fit's checks.
struct XorShift(u64);

impl XorShift {
    fn uniform(&mut self) -> f64 {
        let s = &mut self.0;
        *s ^= *s << 13;
        *s ^= *s >> 7;
        *s ^= *s << 17;
        (*s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }
}
