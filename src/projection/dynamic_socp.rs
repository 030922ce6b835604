//! The dynamic projection's second-order cone program in Clarabel, built once per structure
//! and updated in place.
//!
//! Variables x = [v⁺ (nv); τ (na); Λ (nc)]. Clarabel's form: minimise ½ xᵀPx + qᵀx subject to
//! A x + s = b, s ∈ K, with P = blockdiag(M, 0, 0), q = [−M v_des; 0; 0] and the rows grouped
//! by cone:
//!
//! ```text
//! {0}^nv      M v⁺ − Δt Sᵀ τ − Jᵀ Λ = M v + Δt (Q − h)   impulse form of the dynamics
//! {0}^nc      J v⁺ = 0                                   constraints at velocity level
//! ℝ₊^nb       v⁺_i ≤ hi_i,  −v⁺_i ≤ −lo_i                finite velocity bounds
//! ℝ₊^m        A v⁺ ≤ b                                   the request's inequalities
//! ℝ₊^(2ne)    τ_k ≤ e_k,  −τ_k ≤ e_k                     actuators with a finite effort
//! ℝ₊^nn       Λ_n ≥ 0                                    normal rows without a cone
//! SOC(1+nt)   (μ Λ_n, Λ_t) ∈ 𝒬                           each friction cone
//! ```
//!
//! The pattern depends on the envelope model (fixed per robot) and on which coordinates carry
//! finite bounds and how many rows A has (as the kinematic QP's, `qp.rs`): the solver is
//! rebuilt only when those change; otherwise `update_P`, `update_q`, `update_A` and `update_b`
//! overwrite its data (presolve and zero-dropping off keep the pattern).
//!
//! Duals z (Clarabel's sign: P x + q + Aᵀz = 0): y = z of the dynamics rows (nv, m/s),
//! w = z of the constraint rows (nc), so that at the optimum
//! `M (v⁺ − v_des) = −M y − Jᵀ w + ν − Aᵀ η`, `Δt (S y)_k` is the effort multiplier of
//! actuator k, and `u = −J y` lies in each contact's dual cone (u_n ≥ 0, ‖u_t‖ ≤ u_n / μ) with
//! `Λᵀu = 0` per contact.

use super::problem::{Bounds, Side};
use super::qp::IneqRow;
use crate::envelope::{EnvelopeModel, solver_settings};
use crate::error::{Error, Result};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSolver, IPSolver, NonnegativeConeT, SecondOrderConeT, SolverStatus, SupportedConeT,
    ZeroConeT,
};
use nalgebra::{DMatrix, DVector};

/// Where a stored entry of A comes from.
#[derive(Clone, Copy, Debug)]
enum Src {
    /// M[i, c].
    Mass(usize, usize),
    /// −J[r, i] (dynamics row i, Λ column r).
    JacobianT(usize, usize),
    /// J[r, c] (constraint row r, v⁺ column c).
    Jacobian(usize, usize),
    /// −Δt (dynamics row of an actuated coordinate, τ column).
    MinusPeriod,
    /// Row u of A, column c.
    User(usize, usize),
    /// A constant.
    Const(f64),
}

/// What a row of the program is, for naming a certificate's support.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum RowKind {
    /// Dynamics row of coordinate i.
    Dynamics(usize),
    /// Constraint row r.
    Constraint(usize),
    /// An inequality of the kinematic problem (bound or row of A).
    Ineq(IneqRow),
    /// Actuator k's effort, upper (true) or lower side.
    Effort(usize),
    /// Contact k's normal row (no cone).
    Normal(usize),
    /// Contact k's friction cone (its first row).
    Cone(usize),
    /// A tangential row of a cone (its normal is the cone's first row).
    ConeTail,
}

/// The outcome of one solve.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum SocpOutcome {
    /// An optimum in [`DynSocp::x`].
    Optimal,
    /// No (v⁺, τ, Λ) meets every limit; the certificate is in [`DynSocp::z`].
    Infeasible,
}

/// The data of one call.
pub(super) struct SocpData<'a> {
    pub m: &'a DMatrix<f64>,
    pub j: &'a DMatrix<f64>,
    /// M v + Δt (Q − h) (nv).
    pub rhs: &'a DVector<f64>,
    pub v_des: &'a [f64],
    pub bounds: &'a Bounds,
    pub a: &'a DMatrix<f64>,
    pub b: &'a [f64],
    pub period: f64,
}

/// The cone program for one envelope model and one inequality structure.
pub(super) struct DynSocp {
    n: usize,
    /// The structure: the kinematic inequality rows in order.
    pub ineq: Vec<IneqRow>,
    /// What each row is.
    pub rows: Vec<RowKind>,
    p_idx: Vec<(usize, usize)>,
    p_val: Vec<f64>,
    a_src: Vec<Src>,
    /// Row of each stored entry of A.
    a_row: Vec<usize>,
    a_val: Vec<f64>,
    /// Rows lifted out of the problem (the diagnosis of an infeasible request): their entries
    /// are zero and their slack is a point inside the cone.
    pub relaxed: Vec<bool>,
    q: Vec<f64>,
    b: Vec<f64>,
    /// First row of the inequality block.
    pub ineq_row0: usize,
    /// First row of the effort block.
    effort_row0: usize,
    solver: DefaultSolver<f64>,
}

impl DynSocp {
    /// Build the pattern and the solver (allocates; once per structure).
    pub fn new(em: &EnvelopeModel, ineq: &[IneqRow], data: &SocpData) -> Result<Self> {
        let (nv, na, nc) = (em.nv, em.na(), em.nc);
        let n = nv + na + nc;
        let mut cols: Vec<Vec<(usize, Src)>> = vec![vec![]; n];
        let mut rows = vec![];
        for i in 0..nv {
            let row = rows.len();
            for c in (0..nv).filter(|&c| em.mass_pattern[i * nv + c]) {
                cols[c].push((row, Src::Mass(i, c)));
            }
            for (k, act) in em.actuators.iter().enumerate() {
                if act.coordinate == i {
                    cols[nv + k].push((row, Src::MinusPeriod));
                }
            }
            for r in (0..nc).filter(|&r| em.jacobian_pattern[r * nv + i]) {
                cols[nv + na + r].push((row, Src::JacobianT(r, i)));
            }
            rows.push(RowKind::Dynamics(i));
        }
        for r in 0..nc {
            let row = rows.len();
            for c in (0..nv).filter(|&c| em.jacobian_pattern[r * nv + c]) {
                cols[c].push((row, Src::Jacobian(r, c)));
            }
            rows.push(RowKind::Constraint(r));
        }
        let n_eq = rows.len();
        let ineq_row0 = rows.len();
        for &ir in ineq {
            let row = rows.len();
            match ir {
                IneqRow::Bound(i, Side::Upper) => cols[i].push((row, Src::Const(1.0))),
                IneqRow::Bound(i, Side::Lower) => cols[i].push((row, Src::Const(-1.0))),
                IneqRow::User(u) => {
                    for (c, col) in cols.iter_mut().enumerate().take(nv) {
                        col.push((row, Src::User(u, c)));
                    }
                }
            }
            rows.push(RowKind::Ineq(ir));
        }
        let effort_row0 = rows.len();
        for (k, act) in em.actuators.iter().enumerate() {
            if act.effort.is_finite() {
                let row = rows.len();
                cols[nv + k].push((row, Src::Const(1.0)));
                cols[nv + k].push((row + 1, Src::Const(-1.0)));
                rows.push(RowKind::Effort(k));
                rows.push(RowKind::Effort(k));
            }
        }
        for (k, ct) in em.contacts.iter().enumerate() {
            if let (false, Some(nr)) = (ct.has_cone(), ct.normal) {
                cols[nv + na + nr].push((rows.len(), Src::Const(-1.0)));
                rows.push(RowKind::Normal(k));
            }
        }
        let n_nonneg = rows.len() - n_eq;
        let mut cones: Vec<SupportedConeT<f64>> = vec![ZeroConeT(n_eq)];
        if n_nonneg > 0 {
            cones.push(NonnegativeConeT(n_nonneg));
        }
        for (k, ct) in em
            .contacts
            .iter()
            .enumerate()
            .filter(|(_, ct)| ct.has_cone())
        {
            let (nr, mu) = (ct.normal.expect("a cone"), ct.friction.expect("a cone"));
            let row = rows.len();
            cols[nv + na + nr].push((row, Src::Const(-mu)));
            rows.push(RowKind::Cone(k));
            for (t, &tr) in ct.tangential.iter().enumerate() {
                cols[nv + na + tr].push((row + 1 + t, Src::Const(-1.0)));
                rows.push(RowKind::ConeTail);
            }
            cones.push(SecondOrderConeT(1 + ct.tangential.len()));
        }
        let m = rows.len();
        let mut colptr = vec![0];
        let (mut rowval, mut a_src) = (vec![], vec![]);
        for col in &mut cols {
            col.sort_by_key(|e| e.0);
            for &(r, s) in col.iter() {
                rowval.push(r);
                a_src.push(s);
            }
            colptr.push(rowval.len());
        }
        // P: M's pattern, upper triangle, in the v⁺ block.
        let mut p_colptr = vec![0];
        let (mut p_row, mut p_idx) = (vec![], vec![]);
        for c in 0..n {
            if c < nv {
                for r in (0..=c).filter(|&r| em.mass_pattern[r * nv + c]) {
                    p_row.push(r);
                    p_idx.push((r, c));
                }
            }
            p_colptr.push(p_row.len());
        }
        let mut a_val = vec![0.0; a_src.len()];
        let mut p_val = vec![0.0; p_idx.len()];
        let mut q = vec![0.0; n];
        let mut b = vec![0.0; m];
        fill(
            em,
            data,
            ineq,
            (&a_src, &mut a_val),
            (&p_idx, &mut p_val),
            &mut q,
            &mut b,
            (ineq_row0, effort_row0),
        );
        let p = CscMatrix::new(n, n, p_colptr, p_row, p_val.clone());
        let a = CscMatrix::new(m, n, colptr, rowval.clone(), a_val.clone());
        let solver = DefaultSolver::new(&p, &q, &a, &b, &cones, solver_settings())
            .map_err(|e| numerical(&format!("Clarabel refused the problem: {e:?}")))?;
        let relaxed = vec![false; m];
        Ok(Self {
            n,
            ineq: ineq.to_vec(),
            rows,
            p_idx,
            p_val,
            a_src,
            a_row: rowval,
            a_val,
            relaxed,
            q,
            b,
            ineq_row0,
            effort_row0,
            solver,
        })
    }

    /// Whether this program was built for the inequality structure `ineq`.
    pub fn matches(&self, ineq: &[IneqRow]) -> bool {
        self.ineq == ineq
    }

    /// Refill every value from `data` (same structure; allocates nothing) and solve.
    pub fn solve(&mut self, em: &EnvelopeModel, data: &SocpData) -> Result<SocpOutcome> {
        fill(
            em,
            data,
            &self.ineq,
            (&self.a_src, &mut self.a_val),
            (&self.p_idx, &mut self.p_val),
            &mut self.q,
            &mut self.b,
            (self.ineq_row0, self.effort_row0),
        );
        for (val, &r) in self.a_val.iter_mut().zip(&self.a_row) {
            if self.relaxed[r] {
                *val = 0.0;
            }
        }
        for (r, kind) in self.rows.iter().enumerate() {
            if self.relaxed[r] {
                self.b[r] = if *kind == RowKind::ConeTail { 0.0 } else { 1.0 };
            }
        }
        let s = &mut self.solver;
        let ok = s.update_P(&self.p_val).is_ok()
            && s.update_q(&self.q).is_ok()
            && s.update_A(&self.a_val).is_ok()
            && s.update_b(&self.b).is_ok();
        if !ok {
            return Err(numerical("the solver refused the updated data"));
        }
        s.solve();
        Ok(match s.solution.status {
            SolverStatus::Solved | SolverStatus::AlmostSolved => SocpOutcome::Optimal,
            SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => {
                SocpOutcome::Infeasible
            }
            other => return Err(numerical(&format!("Clarabel stopped with {other:?}"))),
        })
    }

    /// Interior-point iterations of the last solve.
    pub fn iterations(&self) -> u32 {
        self.solver.solution.iterations
    }

    /// The last solution x = [v⁺; τ; Λ] (n).
    pub fn x(&self) -> &[f64] {
        &self.solver.solution.x[..self.n]
    }

    /// The last duals z (one per row), or the infeasibility certificate.
    pub fn z(&self) -> &[f64] {
        &self.solver.solution.z
    }
}

/// The values of P, q, A, b for `data` (the pattern's order).
#[allow(clippy::too_many_arguments)]
fn fill(
    em: &EnvelopeModel,
    data: &SocpData,
    ineq: &[IneqRow],
    (a_src, a_val): (&[Src], &mut [f64]),
    (p_idx, p_val): (&[(usize, usize)], &mut [f64]),
    q: &mut [f64],
    b: &mut [f64],
    (ineq_row0, effort_row0): (usize, usize),
) {
    let (m, j) = (data.m, data.j);
    let nv = m.nrows();
    debug_assert!((0..nv * nv).all(|k| em.mass_pattern[k] || m[(k / nv, k % nv)] == 0.0));
    debug_assert!(
        (0..j.nrows() * nv).all(|k| em.jacobian_pattern[k] || j[(k / nv, k % nv)] == 0.0)
    );
    for (val, &(r, c)) in p_val.iter_mut().zip(p_idx) {
        *val = m[(r, c)];
    }
    for (val, s) in a_val.iter_mut().zip(a_src) {
        *val = match *s {
            Src::Mass(i, c) => m[(i, c)],
            Src::JacobianT(r, i) => -j[(r, i)],
            Src::Jacobian(r, c) => j[(r, c)],
            Src::MinusPeriod => -data.period,
            Src::User(u, c) => data.a[(u, c)],
            Src::Const(x) => x,
        };
    }
    q.fill(0.0);
    for i in 0..nv {
        q[i] = -(0..nv).map(|c| m[(i, c)] * data.v_des[c]).sum::<f64>();
    }
    b.fill(0.0);
    b[..nv].copy_from_slice(data.rhs.as_slice());
    for (t, &ir) in ineq.iter().enumerate() {
        b[ineq_row0 + t] = match ir {
            IneqRow::Bound(i, Side::Upper) => data.bounds.hi[i],
            IneqRow::Bound(i, Side::Lower) => -data.bounds.lo[i],
            IneqRow::User(u) => data.b[u],
        };
    }
    let mut r = effort_row0;
    for act in em.actuators.iter().filter(|a| a.effort.is_finite()) {
        b[r] = act.effort;
        b[r + 1] = act.effort;
        r += 2;
    }
}

fn numerical(why: &str) -> Error {
    Error::Unsupported {
        what: "this dynamic projection".into(),
        why: format!("{why} (a numerical failure of the cone program)"),
    }
}
