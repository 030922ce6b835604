//! The bounded projection as a Clarabel QP, built once per problem structure and updated in place.
//!
//! Scaled variables `x = D v` with `D = diag(√M_ii)` give a unit-diagonal Hessian; every row is
//! normalised (constraint and inequality rows to unit norm in x, bound rows to ±1), so a robot
//! with 10 kg bases and 1 g fingers, or bounds of 0.01 and 1000, yields the same well-scaled QP:
//!
//!   minimise ½ xᵀ P̃ x + q̃ᵀ x,  P̃ = D⁻¹ M D⁻¹,  q̃ = −D⁻¹ M v_des
//!   subject to  Ã x + s = b̃,  s ∈ {0}^nc × ℝ₊^ni
//!
//! and finally x = σ x′ with σ = max(|q̃|, |b̃|), so q̃/σ and b̃/σ are of order one whether the
//! request is in mm/s or km/s (Clarabel's tolerances have absolute floors).
//!
//! where the first nc rows are `s_r J_r D⁻¹ x = 0` (ZeroCone) and the next ni rows the bounds and
//! `A v ≤ b` (NonnegativeCone). The pattern of P̃ is M's branch pattern (coordinate i couples to
//! j only if one is an ancestor of the other), J is stored dense, so the pattern depends only on
//! which coordinates carry finite bounds and on the number of rows of A: the `DefaultSolver` is
//! rebuilt only when that changes, otherwise `update_P`, `update_q`, `update_A`, `update_b`
//! overwrite its data (presolve and zero-dropping are off, which keeps the pattern fixed; static
//! regularisation stays on, it is what lets Clarabel accept the redundant rows of, e.g., a
//! differential drive's two identical no-side-slip rows).
//!
//! Physical multipliers from Clarabel's duals z (row scale s_k): a row `c v ≤ d` (or `= d`)
//! contributes `M (v − v_des) = −Σ s_k z_k c_kᵀ`.

use super::kkt::RowRef;
use super::problem::{Bounds, Side};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSettingsBuilder, DefaultSolver, IPSolver, NonnegativeConeT,
    SolverStatus, SupportedConeT, ZeroConeT,
};
use nalgebra::DMatrix;

/// An inequality row of the QP.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum IneqRow {
    /// `v_i ≤ hi_i` or `v_i ≥ lo_i`.
    Bound(usize, Side),
    /// Row k of `A v ≤ b`.
    User(usize),
}

impl IneqRow {
    pub fn as_row_ref(self) -> RowRef {
        match self {
            IneqRow::Bound(i, _) => RowRef::Unit(i),
            IneqRow::User(k) => RowRef::User(k),
        }
    }

    /// Right side of the row as an equality when active.
    pub fn value(self, bounds: &Bounds, b: &[f64]) -> f64 {
        match self {
            IneqRow::Bound(i, Side::Lower) => bounds.lo[i],
            IneqRow::Bound(i, Side::Upper) => bounds.hi[i],
            IneqRow::User(k) => b[k],
        }
    }

    /// Violation `c v − d` of the row in its "≤" orientation (positive = violated).
    pub fn violation(self, v: &[f64], bounds: &Bounds, a: &DMatrix<f64>, b: &[f64]) -> f64 {
        match self {
            IneqRow::Bound(i, Side::Lower) => bounds.lo[i] - v[i],
            IneqRow::Bound(i, Side::Upper) => v[i] - bounds.hi[i],
            IneqRow::User(k) => (0..v.len()).map(|c| a[(k, c)] * v[c]).sum::<f64>() - b[k],
        }
    }
}

/// The canonical inequality rows of a problem: per coordinate lower then upper where finite,
/// then the rows of A. Refills `out` (no allocation once it has grown).
pub(super) fn inequality_rows(bounds: &Bounds, m_user: usize, out: &mut Vec<IneqRow>) {
    out.clear();
    for i in 0..bounds.lo.len() {
        if bounds.lo[i].is_finite() {
            out.push(IneqRow::Bound(i, Side::Lower));
        }
        if bounds.hi[i].is_finite() {
            out.push(IneqRow::Bound(i, Side::Upper));
        }
    }
    out.extend((0..m_user).map(IneqRow::User));
}

#[derive(Clone, Copy, Debug)]
enum Entry {
    Jacobian(usize, usize),
    Unit(f64),
    /// Row u of A, column c, at QP row k.
    User(usize, usize, usize),
}

/// Settings that keep the sparsity pattern fixed for updates.
pub(super) fn settings() -> DefaultSettings<f64> {
    DefaultSettingsBuilder::default()
        .verbose(false)
        .presolve_enable(false)
        .input_sparse_dropzeros(false)
        .max_threads(1)
        .build()
        .expect("valid Clarabel settings")
}

/// A Clarabel solver for one problem structure, with its scaling.
pub(super) struct QpCache {
    nc: usize,
    /// The structure: inequality rows in order.
    pub ineq: Vec<IneqRow>,
    solver: Option<DefaultSolver<f64>>,
    p_idx: Vec<(usize, usize)>,
    a_src: Vec<Entry>,
    p_val: Vec<f64>,
    a_val: Vec<f64>,
    q: Vec<f64>,
    b: Vec<f64>,
    /// D = √diag M.
    pub d: Vec<f64>,
    /// Row scales s_k (nc constraint rows, then the inequality rows).
    pub row_scale: Vec<f64>,
    /// Overall scale σ of the scaled variables (x = σ x′).
    pub sigma: f64,
    /// Data already in the solver (just built).
    fresh: bool,
}

/// The data one call fills in.
pub(super) struct QpData<'a> {
    pub m: &'a DMatrix<f64>,
    pub j: &'a DMatrix<f64>,
    pub a: &'a DMatrix<f64>,
    pub b: &'a [f64],
    pub bounds: &'a Bounds,
    pub v_des: &'a [f64],
}

impl QpCache {
    /// Build the pattern and the solver for `ineq` (allocates; once per structure).
    pub fn new(v_parent: &[usize], nc: usize, ineq: &[IneqRow], data: &QpData) -> Self {
        let nv = data.m.nrows();
        let mut p_colptr = vec![0];
        let mut p_row = vec![];
        let mut p_idx = vec![];
        for c in 0..nv {
            let mut rows = vec![c];
            let mut i = v_parent[c];
            while i != usize::MAX {
                rows.push(i);
                i = v_parent[i];
            }
            rows.sort_unstable();
            for r in rows {
                p_row.push(r);
                p_idx.push((r, c));
            }
            p_colptr.push(p_row.len());
        }
        let mut a_colptr = vec![0];
        let mut a_row = vec![];
        let mut a_src = vec![];
        for c in 0..nv {
            for r in 0..nc {
                a_row.push(r);
                a_src.push(Entry::Jacobian(r, c));
            }
            for (t, row) in ineq.iter().enumerate() {
                match *row {
                    IneqRow::Bound(i, side) if i == c => {
                        a_row.push(nc + t);
                        a_src.push(Entry::Unit(if side == Side::Upper { 1.0 } else { -1.0 }));
                    }
                    IneqRow::User(u) => {
                        a_row.push(nc + t);
                        a_src.push(Entry::User(u, c, nc + t));
                    }
                    _ => {}
                }
            }
            a_colptr.push(a_row.len());
        }
        let m_rows = nc + ineq.len();
        let mut me = Self {
            nc,
            ineq: ineq.to_vec(),
            solver: None,
            p_val: vec![0.0; p_idx.len()],
            p_idx,
            a_val: vec![0.0; a_src.len()],
            a_src,
            q: vec![0.0; nv],
            b: vec![0.0; m_rows],
            d: vec![1.0; nv],
            row_scale: vec![1.0; m_rows],
            sigma: 1.0,
            fresh: false,
        };
        me.fill(data);
        let p = CscMatrix::new(nv, nv, p_colptr, p_row, me.p_val.clone());
        let a = CscMatrix::new(m_rows, nv, a_colptr, a_row, me.a_val.clone());
        let mut cones: Vec<SupportedConeT<f64>> = vec![];
        if nc > 0 {
            cones.push(ZeroConeT(nc));
        }
        if !ineq.is_empty() {
            cones.push(NonnegativeConeT(ineq.len()));
        }
        me.solver = DefaultSolver::new(&p, &me.q, &a, &me.b, &cones, settings()).ok();
        me.fresh = true;
        me
    }

    /// Whether this cache was built for the structure (nc, ineq).
    pub fn matches(&self, nc: usize, ineq: &[IneqRow]) -> bool {
        self.nc == nc && self.ineq == ineq
    }

    /// Scaled values of P̃, q̃, Ã, b̃ from the physical data.
    fn fill(&mut self, data: &QpData) {
        let nv = data.m.nrows();
        for i in 0..nv {
            let mii = data.m[(i, i)];
            self.d[i] = if mii > 0.0 { mii.sqrt() } else { 1.0 };
        }
        let d = &self.d;
        for (val, &(r, c)) in self.p_val.iter_mut().zip(&self.p_idx) {
            *val = data.m[(r, c)] / (d[r] * d[c]);
        }
        for i in 0..nv {
            self.q[i] = -(0..nv).map(|c| data.m[(i, c)] * data.v_des[c]).sum::<f64>() / d[i];
        }
        for r in 0..self.nc {
            let n2: f64 = (0..nv).map(|c| (data.j[(r, c)] / d[c]).powi(2)).sum();
            self.row_scale[r] = if n2 > 0.0 { 1.0 / n2.sqrt() } else { 1.0 };
            self.b[r] = 0.0;
        }
        for (t, row) in self.ineq.iter().enumerate() {
            let k = self.nc + t;
            match *row {
                IneqRow::Bound(i, Side::Upper) => {
                    self.row_scale[k] = d[i];
                    self.b[k] = d[i] * data.bounds.hi[i];
                }
                IneqRow::Bound(i, Side::Lower) => {
                    self.row_scale[k] = d[i];
                    self.b[k] = -d[i] * data.bounds.lo[i];
                }
                IneqRow::User(u) => {
                    let n2: f64 = (0..nv).map(|c| (data.a[(u, c)] / d[c]).powi(2)).sum();
                    self.row_scale[k] = if n2 > 0.0 { 1.0 / n2.sqrt() } else { 1.0 };
                    self.b[k] = self.row_scale[k] * data.b[u];
                }
            }
        }
        // Overall scale σ: x = σ x′ makes q̃ and b̃ of order one whatever the units of the request
        // (Clarabel's tolerances have absolute floors); duals scale by σ too.
        let sigma = self
            .q
            .iter()
            .chain(&self.b)
            .fold(0.0f64, |m, x| m.max(x.abs()));
        self.sigma = if sigma > 0.0 && sigma.is_finite() {
            sigma
        } else {
            1.0
        };
        for x in self.q.iter_mut().chain(self.b.iter_mut()) {
            *x /= self.sigma;
        }
        for (val, e) in self.a_val.iter_mut().zip(&self.a_src) {
            *val = match *e {
                Entry::Jacobian(r, c) => data.j[(r, c)] / d[c] * self.row_scale[r],
                Entry::Unit(sign) => sign,
                Entry::User(u, c, k) => data.a[(u, c)] / d[c] * self.row_scale[k],
            };
        }
    }

    /// Refill the data (same structure) and solve.
    pub fn solve(&mut self, data: &QpData) -> SolverStatus {
        if self.solver.is_none() {
            return SolverStatus::NumericalError;
        }
        if !std::mem::take(&mut self.fresh) {
            self.fill(data);
            let solver = self.solver.as_mut().expect("checked above");
            let ok = solver.update_P(&self.p_val).is_ok()
                && solver.update_q(&self.q).is_ok()
                && solver.update_A(&self.a_val).is_ok()
                && solver.update_b(&self.b).is_ok();
            if !ok {
                return SolverStatus::NumericalError;
            }
        }
        let solver = self.solver.as_mut().expect("checked above");
        solver.solve();
        solver.solution.status
    }

    fn sol(&self) -> &clarabel::solver::DefaultSolution<f64> {
        &self.solver.as_ref().expect("solve() ran").solution
    }

    /// v = σ D⁻¹ x′ into `v`.
    pub fn primal(&self, v: &mut [f64]) {
        for (i, vi) in v.iter_mut().enumerate() {
            *vi = self.sigma * self.sol().x[i] / self.d[i];
        }
    }

    /// Dual z_k and slack s_k of QP row k (constraint rows first), in the normalised units.
    pub fn dual_slack(&self, k: usize) -> (f64, f64) {
        (self.sol().z[k], self.sol().s[k])
    }

    /// Physical multiplier of QP row k: λ_r = −s_r z_r on constraint rows, ν = ∓ s z on
    /// upper/lower bounds, η = s z ≥ 0 on rows of A.
    pub fn multiplier(&self, k: usize) -> f64 {
        let sz = self.sigma * self.row_scale[k] * self.sol().z[k];
        if k < self.nc {
            return -sz;
        }
        match self.ineq[k - self.nc] {
            IneqRow::Bound(_, Side::Upper) => -sz,
            IneqRow::Bound(_, Side::Lower) => sz,
            IneqRow::User(_) => sz,
        }
    }

    pub fn iterations(&self) -> u32 {
        self.sol().iterations
    }

    /// Rows of the certificate z with |z_k| > `rel · max |z|` (after a primal-infeasible exit).
    pub fn certificate_support(&self, rel: f64) -> Vec<usize> {
        let z = &self.sol().z;
        let zmax = z.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        (0..z.len()).filter(|&k| z[k].abs() > rel * zmax).collect()
    }

    /// Scaled dense row k of Ã and b̃_k (for the diagnosis of infeasible problems).
    pub fn scaled_row(&self, k: usize, nv: usize, data: &QpData) -> (Vec<f64>, f64) {
        let d = &self.d;
        let s = self.row_scale[k];
        let row: Vec<f64> = if k < self.nc {
            (0..nv).map(|c| data.j[(k, c)] / d[c] * s).collect()
        } else {
            match self.ineq[k - self.nc] {
                IneqRow::Bound(i, side) => {
                    let mut r = vec![0.0; nv];
                    r[i] = if side == Side::Upper { 1.0 } else { -1.0 };
                    r
                }
                IneqRow::User(u) => (0..nv).map(|c| data.a[(u, c)] / d[c] * s).collect(),
            }
        };
        (row, self.b[k])
    }

    pub fn nc(&self) -> usize {
        self.nc
    }
}

/// Feasibility of `Ã_eq x = b̃_eq, Ã_in x ≤ b̃_in` (scaled rows): min ½‖x‖² under those rows.
/// `None` when Clarabel cannot decide.
pub(super) fn feasible(
    nv: usize,
    eq: &[(Vec<f64>, f64)],
    ineq: &[(Vec<f64>, f64)],
) -> Option<bool> {
    let rows: Vec<&(Vec<f64>, f64)> = eq.iter().chain(ineq.iter()).collect();
    let (mut ii, mut jj, mut vv) = (vec![], vec![], vec![]);
    for (r, (row, _)) in rows.iter().enumerate() {
        for (c, &x) in row.iter().enumerate() {
            if x != 0.0 {
                ii.push(r);
                jj.push(c);
                vv.push(x);
            }
        }
    }
    let a = CscMatrix::new_from_triplets(rows.len(), nv, ii, jj, vv);
    let b: Vec<f64> = rows.iter().map(|r| r.1).collect();
    let mut cones: Vec<SupportedConeT<f64>> = vec![];
    if !eq.is_empty() {
        cones.push(ZeroConeT(eq.len()));
    }
    if !ineq.is_empty() {
        cones.push(NonnegativeConeT(ineq.len()));
    }
    let p = CscMatrix::identity(nv);
    let mut s = DefaultSolver::new(&p, &vec![0.0; nv], &a, &b, &cones, settings()).ok()?;
    s.solve();
    match s.solution.status {
        SolverStatus::Solved | SolverStatus::AlmostSolved => Some(true),
        SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => Some(false),
        _ => None,
    }
}
