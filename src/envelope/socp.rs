//! The envelope's second-order cone program in Clarabel, built once and updated in place.
//!
//! Variables x = [a (nv); τ (na); λ (nc)]. Clarabel's form: minimise cᵀx subject to
//! A x + s = b, s ∈ K, with the rows grouped by cone:
//!
//! ```text
//! {0}^nv      M a − Sᵀ τ − Jᵀ λ = Q − h        dynamics
//! {0}^nc      J a = −γ                          constraints at acceleration level
//! {0}^nh      a_i = 0                           held coordinates (an arm)
//! {0}^1       a_yaw = 0  or  a_fwd = 0          the other base direction held
//! ℝ₊^(2ne)    τ_k ≤ e_k,  −τ_k ≤ e_k           actuators with a finite effort
//! ℝ₊^nn       λ_n ≥ 0                           normal rows without a cone
//! SOC(1+nt)   (μ λ_n, λ_t) ∈ 𝒬                  each friction cone
//! ```
//!
//! c = ∓ e_fwd or ∓ e_yaw picks the limit. The dynamics, constraint and limit rows are the
//! shared layout of `robot_limits/program.rs`; the envelope adds the held rows (in the zero
//! cone) and its objective. The pattern is fixed by the envelope model (M's branch pattern, J's
//! rows on the coordinates that move their frames, the held-direction row with both base
//! entries), so one solver serves the four limits and every state: `update_A`, `update_b` and
//! `update_q` overwrite its data (presolve and zero-dropping off keep the pattern).

use super::model::EnvelopeModel;
use crate::error::{Error, Result};
use crate::robot_limits::program::{Entry, Program, ProgramBuilder, solver_settings};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSolver, IPSolver, SolverStatus};
use nalgebra::{DMatrix, DVector};

/// The envelope's own entries of A: the held-direction row's.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Hold {
    /// The entry on the forward coordinate: 1 when the yaw limits are sought (forward held),
    /// else 0.
    Forward,
    /// The entry on the yaw coordinate: 1 when the forward limits are sought (yaw held).
    Yaw,
}

/// The envelope's own rows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum HeldRow {
    /// a_c = 0 for a coordinate that does not drive the base.
    Coordinate(usize),
    /// The other base direction held.
    Direction,
}

/// Which base direction a limit maximises (the other one is held at zero acceleration).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Direction {
    /// Forward acceleration free, yaw acceleration held.
    Forward,
    /// Yaw acceleration free, forward acceleration held.
    Yaw,
}

/// The outcome of one solve.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Outcome {
    /// An optimum; x in [`Socp::x`].
    Optimal,
    /// The objective is unbounded (a dual infeasibility certificate).
    Unbounded,
    /// No (a, τ, λ) satisfies the limits with the other direction held.
    Infeasible,
}

/// The cone program of one envelope model, with its Clarabel solver.
pub(super) struct Socp {
    program: Program<Hold, HeldRow>,
    a_val: Vec<f64>,
    b: Vec<f64>,
    c: Vec<f64>,
    solver: Option<DefaultSolver<f64>>,
    /// Direction whose held row is in the solver's A.
    direction: Direction,
}

impl Socp {
    /// The pattern for `em` (allocates; once per envelope model). The solver is built at the
    /// first [`Socp::load`].
    pub fn new(em: &EnvelopeModel) -> Self {
        let mut builder = ProgramBuilder::new(em.structure());
        for &h in &em.held {
            builder.push_row(HeldRow::Coordinate(h), [(h, Entry::Const(1.0))]);
        }
        let hold = [
            (em.forward, Entry::Own(Hold::Forward)),
            (em.yaw, Entry::Own(Hold::Yaw)),
        ];
        builder.push_row(HeldRow::Direction, hold);
        let program = builder.build();
        let mut b = vec![0.0; program.m()];
        program.fill_effort_b(&mut b);
        Self {
            a_val: vec![0.0; program.entries.len()],
            b,
            c: vec![0.0; program.n],
            program,
            solver: None,
            direction: Direction::Forward,
        }
    }

    fn fill_a(&mut self, m: &DMatrix<f64>, j: &DMatrix<f64>) {
        let hold_forward = self.direction == Direction::Yaw;
        let hold = |h| match h {
            Hold::Forward => f64::from(u8::from(hold_forward)),
            Hold::Yaw => f64::from(u8::from(!hold_forward)),
        };
        // The actuators' torques enter the dynamics with gain 1: forces, not impulses.
        self.program.fill_a(m, j, 1.0, hold, &mut self.a_val);
    }

    /// Load one state's data: M, J, the dynamics right side Q − h (nv) and −γ (nc). Builds
    /// the solver at the first call. Debug builds check that M and J are zero off the pattern.
    pub fn load(
        &mut self,
        em: &EnvelopeModel,
        m: &DMatrix<f64>,
        j: &DMatrix<f64>,
        rhs: &DVector<f64>,
        gamma: &DVector<f64>,
    ) -> Result<()> {
        let (nv, nc) = (m.nrows(), j.nrows());
        debug_assert!((0..nv * nv).all(|k| em.mass_pattern[k] || m[(k / nv, k % nv)] == 0.0));
        debug_assert!((0..nc * nv).all(|k| em.jacobian_pattern[k] || j[(k / nv, k % nv)] == 0.0));
        self.b[..nv].copy_from_slice(rhs.as_slice());
        for r in 0..nc {
            self.b[nv + r] = -gamma[r];
        }
        self.fill_a(m, j);
        match &mut self.solver {
            Some(s) => {
                let ok = s.update_A(&self.a_val).is_ok() && s.update_b(&self.b).is_ok();
                if !ok {
                    return Err(numerical("the solver refused the updated data"));
                }
            }
            None => {
                let n = self.program.n;
                let p = CscMatrix::new(n, n, vec![0; n + 1], vec![], vec![]);
                let a = self.program.a_matrix(&self.a_val);
                let cones = &self.program.cones;
                let s = DefaultSolver::new(&p, &self.c, &a, &self.b, cones, solver_settings())
                    .map_err(|e| numerical(&format!("Clarabel refused the problem: {e:?}")))?;
                self.solver = Some(s);
            }
        }
        Ok(())
    }

    /// Maximise `sign ·` the acceleration of `coordinate` with the other base direction held
    /// (`direction`), on the loaded data.
    pub fn solve(
        &mut self,
        m: &DMatrix<f64>,
        j: &DMatrix<f64>,
        direction: Direction,
        coordinate: usize,
        sign: f64,
    ) -> Result<Outcome> {
        if direction != self.direction {
            self.direction = direction;
            self.fill_a(m, j);
            let s = self.solver.as_mut().expect("load() ran");
            s.update_A(&self.a_val)
                .map_err(|_| numerical("the solver refused the held-direction row"))?;
        }
        self.c.fill(0.0);
        self.c[coordinate] = -sign;
        let s = self.solver.as_mut().expect("load() ran");
        s.update_q(&self.c)
            .map_err(|_| numerical("the solver refused the objective"))?;
        s.solve();
        Ok(match s.solution.status {
            SolverStatus::Solved | SolverStatus::AlmostSolved => Outcome::Optimal,
            SolverStatus::DualInfeasible | SolverStatus::AlmostDualInfeasible => Outcome::Unbounded,
            SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => {
                Outcome::Infeasible
            }
            other => return Err(numerical(&format!("Clarabel stopped with {other:?}"))),
        })
    }

    /// Interior-point iterations of the last solve.
    pub fn iterations(&self) -> u32 {
        self.solver.as_ref().map_or(0, |s| s.solution.iterations)
    }

    /// The last solution x = [a; τ; λ].
    pub fn x(&self) -> &[f64] {
        &self.solver.as_ref().expect("solve() ran").solution.x
    }
}

fn numerical(why: &str) -> Error {
    Error::Unsupported {
        what: "this acceleration envelope".into(),
        why: format!("{why} (a numerical failure of the cone program)"),
    }
}
