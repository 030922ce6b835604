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
//! The dynamics, constraint and limit rows are the shared layout of `robot_limits/program.rs`;
//! the projection adds the inequalities (bounds and rows of A) and its objective. The pattern
//! depends on the envelope model (fixed per robot) and on which coordinates carry
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
use crate::envelope::EnvelopeModel;
use crate::error::{Error, Result};
use crate::robot_limits::program::{Entry, Program, ProgramBuilder, Row, solver_settings};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSolver, IPSolver, SolverStatus};
use nalgebra::{DMatrix, DVector};

/// The projection's own entries of A: A[u, c], row u of the request's inequalities on
/// coordinate c.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct RequestEntry {
    row: usize,
    coordinate: usize,
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
    /// The structure: the kinematic inequality rows in order.
    pub ineq: Vec<IneqRow>,
    /// A's layout and what each row is (the projection's own rows: the inequalities, for
    /// naming a certificate's support).
    pub program: Program<RequestEntry, IneqRow>,
    p_idx: Vec<(usize, usize)>,
    p_val: Vec<f64>,
    a_val: Vec<f64>,
    /// Rows lifted out of the problem (the diagnosis of an infeasible request): their entries
    /// are zero and their slack is a point inside the cone.
    pub relaxed: Vec<bool>,
    q: Vec<f64>,
    b: Vec<f64>,
    /// First row of the inequality block.
    pub ineq_row0: usize,
    solver: DefaultSolver<f64>,
}

impl DynSocp {
    /// Build the pattern and the solver (allocates; once per structure).
    pub fn new(em: &EnvelopeModel, ineq: &[IneqRow], data: &SocpData) -> Result<Self> {
        let nv = em.nv;
        let mut builder = ProgramBuilder::new(em.structure());
        builder.begin_inequalities();
        let ineq_row0 = builder.next_row();
        for &ir in ineq {
            match ir {
                IneqRow::Bound(i, Side::Upper) => builder.push_row(ir, [(i, Entry::Const(1.0))]),
                IneqRow::Bound(i, Side::Lower) => builder.push_row(ir, [(i, Entry::Const(-1.0))]),
                IneqRow::User(u) => builder.push_row(
                    ir,
                    (0..nv).map(|c| {
                        let e = RequestEntry {
                            row: u,
                            coordinate: c,
                        };
                        (c, Entry::Own(e))
                    }),
                ),
            }
        }
        let program = builder.build();
        let (n, m) = (program.n, program.m());
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
        let mut a_val = vec![0.0; program.entries.len()];
        let mut p_val = vec![0.0; p_idx.len()];
        let mut q = vec![0.0; n];
        let mut b = vec![0.0; m];
        fill(
            em,
            data,
            ineq,
            (&program, &mut a_val),
            (&p_idx, &mut p_val),
            &mut q,
            &mut b,
            ineq_row0,
        );
        let p = CscMatrix::new(n, n, p_colptr, p_row, p_val.clone());
        let a = program.a_matrix(&a_val);
        let solver = DefaultSolver::new(&p, &q, &a, &b, &program.cones, solver_settings())
            .map_err(|e| numerical(&format!("Clarabel refused the problem: {e:?}")))?;
        Ok(Self {
            ineq: ineq.to_vec(),
            program,
            p_idx,
            p_val,
            a_val,
            relaxed: vec![false; m],
            q,
            b,
            ineq_row0,
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
            (&self.program, &mut self.a_val),
            (&self.p_idx, &mut self.p_val),
            &mut self.q,
            &mut self.b,
            self.ineq_row0,
        );
        for (val, &r) in self.a_val.iter_mut().zip(&self.program.rowval) {
            if self.relaxed[r] {
                *val = 0.0;
            }
        }
        for (r, kind) in self.program.rows.iter().enumerate() {
            if self.relaxed[r] {
                self.b[r] = if *kind == Row::ConeTail { 0.0 } else { 1.0 };
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
        &self.solver.solution.x[..self.program.n]
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
    (program, a_val): (&Program<RequestEntry, IneqRow>, &mut [f64]),
    (p_idx, p_val): (&[(usize, usize)], &mut [f64]),
    q: &mut [f64],
    b: &mut [f64],
    ineq_row0: usize,
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
    // The torques act over the period: their impulses enter the dynamics with gain Δt.
    let request = |e: RequestEntry| data.a[(e.row, e.coordinate)];
    program.fill_a(m, j, data.period, request, a_val);
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
    program.fill_effort_b(b);
}

fn numerical(why: &str) -> Error {
    Error::Unsupported {
        what: "this dynamic projection".into(),
        why: format!("{why} (a numerical failure of the cone program)"),
    }
}
