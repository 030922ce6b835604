//! The equality-constrained projection: `min ½ (v − v_des)ᵀ M (v − v_des)` s.t. `C v = d`, where C
//! stacks the constraint Jacobian J (d = 0) and, when polishing a bounded solution, the rows of
//! the active bounds and inequalities (d = their values). No QP solver: one factorization.
//!
//! With M = W Wᵀ (W = Lᵀ of the branch-sparse LTL factor), Y = W⁻¹ Cᵀ and S = Yᵀ Y = C M⁻¹ Cᵀ,
//! the KKT system `[M Cᵀ; C 0] [v; −μ] = [M v_des; d]` reduces to
//!   `S μ = d − C v_des`,  `v = v_des + W⁻ᵀ (Y μ)`,  so `M (v − v_des) = Cᵀ μ`.
//! Redundant rows (S singular) are handled by a pivoted Cholesky of S that keeps a maximal
//! independent set I (constraint rows first) and the minimum-norm μ:
//!   `μ_I⁰ = S_II⁻¹ r_I`, `B = S_II⁻¹ S_ID = L₁₁⁻ᵀ L₂₁ᵀ`, null(S) = span [−B; I],
//!   `c = (I + BᵀB)⁻¹ (−Bᵀ μ_I⁰)`, `μ_I = μ_I⁰ + B c`, `μ_D = −c`.
//! When M is only semi-definite (a massless link that the constraints fix) M + ρ JᵀJ replaces M;
//! on `J v = 0` the objective changes by a constant, and `λ = λ̃ + ρ J v_des` restores the
//! multipliers of the original problem.
//!
//! Everything is sized at construction (rows up to `capacity`); `solve` does not allocate unless
//! more rows than the capacity are passed (the polish of a bounded problem may grow it once).

use crate::error::{Error, Result};
use crate::linalg::{
    cholesky_in_place as cholesky, ltl_factor, ltl_solve_l, ltl_solve_lt, rank_revealing_cholesky,
    solve_lower, solve_lower_transpose,
};
use crate::model::Model;
use nalgebra::{DMatrix, DVector};

/// A row of C.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum RowRef {
    /// Row r of the constraint Jacobian J.
    Jacobian(usize),
    /// The unit row e_i (a bound on velocity coordinate i).
    Unit(usize),
    /// Row k of the user's inequality matrix A.
    User(usize),
}

/// Relative pivot threshold of the pivoted Cholesky of S (squared sine of the angle between a row
/// and the span of the rows already taken, in the M⁻¹ metric).
const RANK_TOL: f64 = 1e-11;

/// Dot product with four accumulators (lets the compiler vectorise).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a4, b4) = (a[..n].chunks_exact(4), b[..n].chunks_exact(4));
    let tail: f64 = a4
        .remainder()
        .iter()
        .zip(b4.remainder())
        .map(|(x, y)| x * y)
        .sum();
    let mut acc = [0.0; 4];
    for (x, y) in a4.zip(b4) {
        for k in 0..4 {
            acc[k] += x[k] * y[k];
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// Factor of M (or of M + ρ JᵀJ), with the two half solves.
#[derive(Clone, Debug)]
struct MassFactor {
    l: DMatrix<f64>,
    /// Reciprocals of the LTL factor's diagonal.
    inv_diag: Vec<f64>,
    augmented: bool,
    rho: f64,
}

impl MassFactor {
    /// `x ← W⁻¹ x`.
    fn half(&self, parent: &[usize], x: &mut [f64]) {
        if self.augmented {
            solve_lower(&self.l, x.len(), x)
        } else {
            ltl_solve_lt(&self.l, &self.inv_diag, parent, x)
        }
    }
    /// `x ← W⁻ᵀ x`.
    fn half_t(&self, parent: &[usize], x: &mut [f64]) {
        if self.augmented {
            solve_lower_transpose(&self.l, x.len(), x)
        } else {
            ltl_solve_l(&self.l, &self.inv_diag, parent, x)
        }
    }
}

/// Workspace and results of the equality-constrained projection.
#[derive(Clone, Debug)]
pub(super) struct EqualityWorkspace {
    nv: usize,
    cap: usize,
    factor: MassFactor,
    y: DMatrix<f64>,
    s: DMatrix<f64>,
    bmat: DMatrix<f64>,
    g: DMatrix<f64>,
    perm: Vec<usize>,
    diag0: Vec<f64>,
    rhs: Vec<f64>,
    work: Vec<f64>,
    coef: Vec<f64>,
    tmp: Vec<f64>,
    /// Solution v* (nv).
    pub v: DVector<f64>,
    /// Multipliers μ in the order of the rows passed to `solve`.
    pub mu: Vec<f64>,
    /// Rank of C M⁻¹ Cᵀ.
    pub rank: usize,
    /// Rows found dependent: constraint rows, other rows.
    pub dependent_constraint_rows: usize,
    pub dependent_other_rows: usize,
    /// max |C v − d| after the solve, in the rows' units.
    pub residual: f64,
    n_rows: usize,
}

impl EqualityWorkspace {
    pub fn new(nv: usize, capacity: usize) -> Self {
        let cap = capacity.max(1);
        Self {
            nv,
            cap,
            factor: MassFactor {
                l: DMatrix::zeros(nv, nv),
                inv_diag: vec![0.0; nv],
                augmented: false,
                rho: 0.0,
            },
            y: DMatrix::zeros(nv, cap),
            s: DMatrix::zeros(cap, cap),
            bmat: DMatrix::zeros(cap, cap),
            g: DMatrix::zeros(cap, cap),
            perm: vec![0; cap],
            diag0: vec![0.0; cap],
            rhs: vec![0.0; cap],
            work: vec![0.0; cap],
            coef: vec![0.0; cap],
            tmp: vec![0.0; nv],
            v: DVector::zeros(nv),
            mu: vec![0.0; cap],
            rank: 0,
            dependent_constraint_rows: 0,
            dependent_other_rows: 0,
            residual: 0.0,
            n_rows: 0,
        }
    }

    /// Rows (indices into the rows of the last `solve`) found dependent on the others.
    pub fn dependent_rows(&self) -> &[usize] {
        &self.perm[self.rank..self.n_rows]
    }

    fn ensure_capacity(&mut self, n: usize) {
        if n > self.cap {
            *self = Self {
                factor: self.factor.clone(),
                ..Self::new(self.nv, n.max(2 * self.cap))
            };
        }
    }

    /// Factor M (from CRBA), or M + ρ JᵀJ when M is only positive semi-definite.
    pub fn factor_mass(&mut self, model: &Model, m: &DMatrix<f64>, j: &DMatrix<f64>) -> Result<()> {
        let f = &mut self.factor;
        f.l.copy_from(m);
        f.augmented = false;
        f.rho = 0.0;
        if ltl_factor(
            &mut f.l,
            &model.v_parent,
            &model.v_subtree_end,
            1e-14,
            &mut f.inv_diag,
        )
        .is_ok()
        {
            return Ok(());
        }
        let rho = (0..model.nv)
            .map(|i| m[(i, i)])
            .fold(0.0, f64::max)
            .max(1.0);
        f.l.copy_from(m);
        for a in 0..model.nv {
            for c in 0..model.nv {
                f.l[(a, c)] += rho * (0..j.nrows()).map(|k| j[(k, a)] * j[(k, c)]).sum::<f64>();
            }
        }
        f.augmented = true;
        f.rho = rho;
        cholesky(&mut f.l, model.nv, 1e-14).map_err(|i| Error::SingularMass {
            message: format!(
                "velocity coordinate '{}' has no inertia and no constraint fixes it",
                model.v_names[i]
            ),
        })
    }

    /// Dense row c of C into `out` (nv).
    fn row(rr: RowRef, j: &DMatrix<f64>, a: &DMatrix<f64>, out: &mut [f64]) {
        match rr {
            RowRef::Jacobian(r) => out.iter_mut().enumerate().for_each(|(c, o)| *o = j[(r, c)]),
            RowRef::User(k) => out.iter_mut().enumerate().for_each(|(c, o)| *o = a[(k, c)]),
            RowRef::Unit(i) => {
                out.fill(0.0);
                out[i] = 1.0;
            }
        }
    }

    /// `c · x` for a row of C.
    pub fn row_dot(rr: RowRef, j: &DMatrix<f64>, a: &DMatrix<f64>, x: &[f64]) -> f64 {
        let strided = |m: &DMatrix<f64>, r: usize| -> f64 {
            let rows = m.nrows();
            let ms = m.as_slice();
            x.iter()
                .enumerate()
                .map(|(c, xc)| ms[c * rows + r] * xc)
                .sum()
        };
        match rr {
            RowRef::Jacobian(r) => strided(j, r),
            RowRef::User(k) => strided(a, k),
            RowRef::Unit(i) => x[i],
        }
    }

    /// Solve with rows `rows` of C (constraint rows first) and right side `d`, after
    /// `factor_mass` at the same q. Results in `v`, `mu[..rows.len()]`, `rank`.
    pub fn solve(
        &mut self,
        model: &Model,
        j: &DMatrix<f64>,
        a: &DMatrix<f64>,
        rows: &[RowRef],
        d: &[f64],
        v_des: &[f64],
    ) -> Result<()> {
        let n = rows.len();
        self.ensure_capacity(n);
        self.n_rows = n;
        let parent = &model.v_parent;
        let nv = self.nv;
        let n_first = rows
            .iter()
            .take_while(|r| matches!(r, RowRef::Jacobian(_)))
            .count();
        // Y = W⁻¹ Cᵀ, column by column (contiguous, column-major); r = d − C v_des.
        for (k, &rr) in rows.iter().enumerate() {
            let col = &mut self.y.as_mut_slice()[k * nv..(k + 1) * nv];
            Self::row(rr, j, a, col);
            self.rhs[k] = d[k] - dot(col, v_des);
            self.factor.half(parent, col);
        }
        // S = Yᵀ Y (leading n × n).
        let cap = self.cap;
        let ys = self.y.as_slice();
        let ss = self.s.as_mut_slice();
        for p in 0..n {
            let yp = &ys[p * nv..(p + 1) * nv];
            for q in 0..=p {
                let v = dot(yp, &ys[q * nv..(q + 1) * nv]);
                ss[q * cap + p] = v;
                ss[p * cap + q] = v;
            }
            self.perm[p] = p;
            self.diag0[p] = ss[p * cap + p];
        }
        let k = rank_revealing_cholesky(
            self.s.as_mut_slice(),
            cap,
            n,
            &mut self.perm,
            &mut self.diag0,
            RANK_TOL,
        );
        self.rank = k;
        self.dependent_constraint_rows = self.perm[k..n].iter().filter(|&&p| p < n_first).count();
        self.dependent_other_rows = n - k - self.dependent_constraint_rows;
        // μ_I⁰ = S_II⁻¹ r_I in pivoted order.
        for i in 0..n {
            self.work[i] = self.rhs[self.perm[i]];
        }
        solve_lower(&self.s, k, &mut self.work);
        solve_lower_transpose(&self.s, k, &mut self.work);
        let m = n - k;
        if m > 0 {
            // B[:, t] = L₁₁⁻ᵀ L₂₁[t, :]ᵀ
            for t in 0..m {
                for i in 0..k {
                    self.tmp_b_set(i, t, k);
                }
                let mut col = self.bmat.column_mut(t);
                solve_lower_transpose(&self.s, k, &mut col.as_mut_slice()[..k]);
            }
            // G = I + BᵀB, c = G⁻¹ (−Bᵀ μ_I⁰)
            for p in 0..m {
                for q in 0..=p {
                    let v: f64 = (0..k)
                        .map(|i| self.bmat[(i, p)] * self.bmat[(i, q)])
                        .sum::<f64>()
                        + if p == q { 1.0 } else { 0.0 };
                    self.g[(p, q)] = v;
                    self.g[(q, p)] = v;
                }
                self.coef[p] = -(0..k)
                    .map(|i| self.bmat[(i, p)] * self.work[i])
                    .sum::<f64>();
            }
            cholesky(&mut self.g, m, 0.0).map_err(|_| Error::InconsistentConstraints {
                message: "null-space Gram matrix of the multipliers is singular".into(),
            })?;
            solve_lower(&self.g, m, &mut self.coef);
            solve_lower_transpose(&self.g, m, &mut self.coef);
            for i in 0..k {
                self.work[i] += (0..m)
                    .map(|t| self.bmat[(i, t)] * self.coef[t])
                    .sum::<f64>();
            }
            for t in 0..m {
                self.work[k + t] = -self.coef[t];
            }
        }
        for i in 0..n {
            self.mu[self.perm[i]] = self.work[i];
        }
        // v = v_des + W⁻ᵀ (Y μ)
        self.tmp.fill(0.0);
        let ys = self.y.as_slice();
        for p in 0..n {
            let mu = self.mu[p];
            for (t, y) in self.tmp.iter_mut().zip(&ys[p * nv..(p + 1) * nv]) {
                *t += y * mu;
            }
        }
        self.factor.half_t(parent, &mut self.tmp);
        for c in 0..nv {
            self.v[c] = v_des[c] + self.tmp[c];
        }
        if self.factor.augmented {
            // λ = λ̃ + ρ J v_des on constraint rows.
            for (p, &rr) in rows.iter().enumerate() {
                if let RowRef::Jacobian(_) = rr {
                    self.mu[p] += self.factor.rho * Self::row_dot(rr, j, a, v_des);
                }
            }
        }
        self.residual = rows
            .iter()
            .zip(d)
            .map(|(&rr, &dk)| (Self::row_dot(rr, j, a, self.v.as_slice()) - dk).abs())
            .fold(0.0, f64::max);
        Ok(())
    }

    /// `bmat[i, t] = L₂₁[t, i]` (row k + t of the factored S).
    fn tmp_b_set(&mut self, i: usize, t: usize, k: usize) {
        self.bmat[(i, t)] = self.s[(k + t, i)];
    }
}
