//! The cone program of the dynamics under a robot's limits, in Clarabel's form: minimise
//! ½ xᵀPx + qᵀx subject to A x + s = b, s ∈ K. The acceleration envelope and the dynamic
//! projection pose the same rows with their own objective and rows of their own; this file
//! lays out A's pattern once, with where each entry and each row comes from.
//!
//! Variables x = [motion (nv); τ (na); λ (nc)]: accelerations and forces (the envelope), or the
//! velocity after a period and the impulses over it (the dynamic projection). Rows, grouped by
//! cone, in this order:
//!
//! ```text
//! {0}^nv      M motion − g Sᵀ τ − Jᵀ λ = …       dynamics; g the actuation's gain (1, or Δt)
//! {0}^nc      J motion = …                         the constraints
//! {0}^…       the caller's equalities
//! ℝ₊^…        the caller's inequalities
//! ℝ₊^(2ne)    τ_k ≤ e_k,  −τ_k ≤ e_k              actuators with a finite effort
//! ℝ₊^nn       λ_n ≥ 0                              normal rows without a cone
//! SOC(1+nt)   (μ λ_n, λ_t) ∈ 𝒬                     each friction cone
//! ```
//!
//! The pattern is fixed by the structure (M's branch pattern, J's rows on the coordinates that
//! move their frames, the caller's rows), so a solver built once serves every state: the values
//! are refilled in the pattern's order and handed to Clarabel's `update_*` (presolve and
//! zero-dropping off keep the pattern).

use super::Actuator;
use crate::constraints::Contact;
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSettingsBuilder, NonnegativeConeT, SecondOrderConeT, SupportedConeT,
    ZeroConeT,
};
use nalgebra::DMatrix;

/// Clarabel's settings for the dynamics' cone programs: the pattern stays fixed for updates;
/// tolerances tighter than Clarabel's defaults (the limits are compared with closed forms to
/// 1e-6).
pub(crate) fn solver_settings() -> DefaultSettings<f64> {
    DefaultSettingsBuilder::default()
        .verbose(false)
        .presolve_enable(false)
        .input_sparse_dropzeros(false)
        .max_threads(1)
        .tol_gap_abs(1e-10)
        .tol_gap_rel(1e-10)
        .tol_feas(1e-10)
        .tol_ktratio(1e-8)
        .build()
        .expect("valid Clarabel settings")
}

/// What the program is posed on: sizes, limits and the structural patterns of M and J.
#[derive(Clone, Copy)]
pub(crate) struct Structure<'a> {
    /// Velocity coordinates (nv).
    pub nv: usize,
    /// Constraint rows (nc).
    pub nc: usize,
    /// The actuators, one τ column each.
    pub actuators: &'a [Actuator],
    /// The contacts whose forces are limited (rows index λ).
    pub contacts: &'a [Contact],
    /// M's pattern, nv × nv row-major.
    pub mass_pattern: &'a [bool],
    /// J's pattern, nc × nv row-major.
    pub jacobian_pattern: &'a [bool],
}

/// Where a stored entry of A comes from; `E` names the caller's own entries.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Entry<E> {
    /// M[i, c] (dynamics row i, motion column c).
    Mass(usize, usize),
    /// −J[r, i] (dynamics row i, λ column r).
    JacobianT(usize, usize),
    /// J[r, c] (constraint row r, motion column c).
    Jacobian(usize, usize),
    /// −g, the actuation's gain (dynamics row of an actuated coordinate, τ column).
    Actuation,
    /// A constant.
    Const(f64),
    /// One of the caller's.
    Own(E),
}

/// What a row of the program is; `R` names the caller's own rows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Row<R> {
    /// Dynamics row of coordinate i.
    Dynamics(usize),
    /// Constraint row r.
    Constraint(usize),
    /// One of the caller's.
    Own(R),
    /// Actuator k's effort (two rows: upper side, then lower).
    Effort(usize),
    /// Contact k's normal row (no cone).
    Normal(usize),
    /// Contact k's friction cone (its first row, on the normal).
    Cone(usize),
    /// A tangential row of a cone.
    ConeTail,
}

/// A program being laid out: the dynamics and constraint rows, then the caller's rows, then
/// (at [`ProgramBuilder::build`]) the limits' rows.
pub(crate) struct ProgramBuilder<'a, E, R> {
    st: Structure<'a>,
    /// Each column's entries (row, source), in any row order.
    cols: Vec<Vec<(usize, Entry<E>)>>,
    rows: Vec<Row<R>>,
    /// Rows in the zero cone, once the caller's inequalities began.
    n_eq: Option<usize>,
}

impl<'a, E: Copy, R: Copy> ProgramBuilder<'a, E, R> {
    /// The dynamics and constraint rows of `st` (allocates; once per structure).
    pub fn new(st: Structure<'a>) -> Self {
        let (nv, na, nc) = (st.nv, st.actuators.len(), st.nc);
        let mut b = Self {
            st,
            cols: vec![vec![]; nv + na + nc],
            rows: vec![],
            n_eq: None,
        };
        for i in 0..nv {
            let row = b.rows.len();
            for c in (0..nv).filter(|&c| st.mass_pattern[i * nv + c]) {
                b.cols[c].push((row, Entry::Mass(i, c)));
            }
            for (k, act) in st.actuators.iter().enumerate() {
                if act.coordinate == i {
                    b.cols[nv + k].push((row, Entry::Actuation));
                }
            }
            for r in (0..nc).filter(|&r| st.jacobian_pattern[r * nv + i]) {
                b.cols[nv + na + r].push((row, Entry::JacobianT(r, i)));
            }
            b.rows.push(Row::Dynamics(i));
        }
        for r in 0..nc {
            let row = b.rows.len();
            for c in (0..nv).filter(|&c| st.jacobian_pattern[r * nv + c]) {
                b.cols[c].push((row, Entry::Jacobian(r, c)));
            }
            b.rows.push(Row::Constraint(r));
        }
        b
    }

    /// The index the next row will have.
    pub fn next_row(&self) -> usize {
        self.rows.len()
    }

    /// Append the caller's row `what` with its entries (column, source).
    pub fn push_row(&mut self, what: R, entries: impl IntoIterator<Item = (usize, Entry<E>)>) {
        let row = self.rows.len();
        for (c, e) in entries {
            self.cols[c].push((row, e));
        }
        self.rows.push(Row::Own(what));
    }

    /// The rows pushed from now on are inequalities (ℝ₊); the ones before, equalities.
    pub fn begin_inequalities(&mut self) {
        debug_assert!(self.n_eq.is_none());
        self.n_eq = Some(self.rows.len());
    }

    /// Append the limits' rows (effort box, normal rows, friction cones) and lay out A.
    pub fn build(mut self) -> Program<E, R> {
        let st = self.st;
        let (nv, na) = (st.nv, st.actuators.len());
        let n_eq = self.n_eq.unwrap_or(self.rows.len());
        let effort_row0 = self.rows.len();
        let mut efforts = vec![];
        for (k, act) in st.actuators.iter().enumerate() {
            if act.effort.is_finite() {
                let row = self.rows.len();
                self.cols[nv + k].push((row, Entry::Const(1.0)));
                self.cols[nv + k].push((row + 1, Entry::Const(-1.0)));
                self.rows.extend([Row::Effort(k), Row::Effort(k)]);
                efforts.push(act.effort);
            }
        }
        for (k, ct) in st.contacts.iter().enumerate() {
            if let (false, Some(nr)) = (ct.has_cone(), ct.normal) {
                self.cols[nv + na + nr].push((self.rows.len(), Entry::Const(-1.0)));
                self.rows.push(Row::Normal(k));
            }
        }
        let n_nonneg = self.rows.len() - n_eq;
        let mut cones: Vec<SupportedConeT<f64>> = vec![ZeroConeT(n_eq)];
        if n_nonneg > 0 {
            cones.push(NonnegativeConeT(n_nonneg));
        }
        for (k, ct) in st.contacts.iter().enumerate().filter(|(_, c)| c.has_cone()) {
            let (nr, mu) = (ct.normal.expect("a cone"), ct.friction.expect("a cone"));
            let row = self.rows.len();
            self.cols[nv + na + nr].push((row, Entry::Const(-mu)));
            self.rows.push(Row::Cone(k));
            for (t, &tr) in ct.tangential.iter().enumerate() {
                self.cols[nv + na + tr].push((row + 1 + t, Entry::Const(-1.0)));
                self.rows.push(Row::ConeTail);
            }
            cones.push(SecondOrderConeT(1 + ct.tangential.len()));
        }
        let mut colptr = vec![0];
        let (mut rowval, mut entries) = (vec![], vec![]);
        for col in &mut self.cols {
            col.sort_by_key(|e| e.0);
            for &(r, e) in col.iter() {
                rowval.push(r);
                entries.push(e);
            }
            colptr.push(rowval.len());
        }
        Program {
            n: self.cols.len(),
            colptr,
            rowval,
            entries,
            rows: self.rows,
            cones,
            effort_row0,
            efforts,
        }
    }
}

/// A laid-out program: A's compressed-column pattern with the source of each stored entry, what
/// each row is, and the cones.
pub(crate) struct Program<E, R> {
    /// Variables (nv + na + nc).
    pub n: usize,
    /// A's column pointers (n + 1).
    pub colptr: Vec<usize>,
    /// Row of each stored entry of A.
    pub rowval: Vec<usize>,
    /// Source of each stored entry of A.
    pub entries: Vec<Entry<E>>,
    /// What each row is.
    pub rows: Vec<Row<R>>,
    /// The cones, in the rows' order.
    pub cones: Vec<SupportedConeT<f64>>,
    /// First row of the effort box.
    effort_row0: usize,
    /// The finite efforts, in the box's order.
    efforts: Vec<f64>,
}

impl<E: Copy, R> Program<E, R> {
    /// Rows (m).
    pub fn m(&self) -> usize {
        self.rows.len()
    }

    /// A's values in the pattern's order from M, J, the actuation's gain and the caller's own
    /// entries (`own`). Allocates nothing.
    pub fn fill_a(
        &self,
        m: &DMatrix<f64>,
        j: &DMatrix<f64>,
        gain: f64,
        own: impl Fn(E) -> f64,
        a: &mut [f64],
    ) {
        for (val, e) in a.iter_mut().zip(&self.entries) {
            *val = match *e {
                Entry::Mass(i, c) => m[(i, c)],
                Entry::JacobianT(r, i) => -j[(r, i)],
                Entry::Jacobian(r, c) => j[(r, c)],
                Entry::Actuation => -gain,
                Entry::Const(x) => x,
                Entry::Own(x) => own(x),
            };
        }
    }

    /// The effort box's right side in `b` (m): e_k on both rows of each finite effort. The
    /// normal and cone rows' right side is zero.
    pub fn fill_effort_b(&self, b: &mut [f64]) {
        for (t, &e) in self.efforts.iter().enumerate() {
            b[self.effort_row0 + 2 * t] = e;
            b[self.effort_row0 + 2 * t + 1] = e;
        }
    }

    /// A with the values `a` (allocates; to build a solver).
    pub fn a_matrix(&self, a: &[f64]) -> CscMatrix<f64> {
        CscMatrix::new(
            self.m(),
            self.n,
            self.colptr.clone(),
            self.rowval.clone(),
            a.to_vec(),
        )
    }
}
