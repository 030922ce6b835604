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
//! c = ∓ e_fwd or ∓ e_yaw picks the limit. The pattern is fixed by the envelope model (M's
//! branch pattern, J's rows on the coordinates that move their frames, the held-direction row
//! with both base entries), so one solver serves the
//! four limits and every state: `update_A`, `update_b` and `update_q` overwrite its data
//! (presolve and zero-dropping off keep the pattern).

use super::model::EnvelopeModel;
use crate::error::{Error, Result};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSettingsBuilder, DefaultSolver, IPSolver, NonnegativeConeT,
    SecondOrderConeT, SolverStatus, SupportedConeT, ZeroConeT,
};
use nalgebra::{DMatrix, DVector};

/// Where a stored entry of A comes from.
#[derive(Clone, Copy, Debug)]
enum Src {
    /// M[i, c].
    Mass(usize, usize),
    /// −J[r, i] (dynamics row i, λ column r).
    JacobianT(usize, usize),
    /// J[r, c] (constraint row r, a column c).
    Jacobian(usize, usize),
    /// A constant.
    Const(f64),
    /// The held-direction row's entry on the forward coordinate: 1 when the yaw limits are
    /// sought (forward held), else 0.
    HoldForward,
    /// Its entry on the yaw coordinate: 1 when the forward limits are sought (yaw held).
    HoldYaw,
}

/// Which base direction a limit maximises (the other one is held at zero acceleration).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Direction {
    /// Forward acceleration free, yaw acceleration held.
    Forward,
    /// Yaw acceleration free, forward acceleration held.
    Yaw,
}

/// Clarabel's settings for the dynamics' cone programs (the envelope and the dynamic
/// projection): the pattern stays fixed for updates; tolerances tighter than Clarabel's defaults
/// (the limits are compared with closed forms to 1e-6).
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
    n: usize,
    m: usize,
    /// A's column pattern and where each entry comes from.
    colptr: Vec<usize>,
    rowval: Vec<usize>,
    src: Vec<Src>,
    a_val: Vec<f64>,
    b: Vec<f64>,
    c: Vec<f64>,
    cones: Vec<SupportedConeT<f64>>,
    solver: Option<DefaultSolver<f64>>,
    /// Direction whose held row is in the solver's A.
    direction: Direction,
}

impl Socp {
    /// The pattern for `em` (allocates; once per envelope model). The solver is built at the
    /// first [`Socp::load`].
    pub fn new(em: &EnvelopeModel) -> Self {
        let (nv, na, nc) = (em.nv, em.na(), em.nc);
        let n = nv + na + nc;
        let mut cols: Vec<Vec<(usize, Src)>> = vec![vec![]; n];
        let mut row = 0;
        // Dynamics rows.
        for i in 0..nv {
            for c in (0..nv).filter(|&c| em.mass_pattern[i * nv + c]) {
                cols[c].push((row, Src::Mass(i, c)));
            }
            for (k, act) in em.actuators.iter().enumerate() {
                if act.coordinate == i {
                    cols[nv + k].push((row, Src::Const(-1.0)));
                }
            }
            for r in (0..nc).filter(|&r| em.jacobian_pattern[r * nv + i]) {
                cols[nv + na + r].push((row, Src::JacobianT(r, i)));
            }
            row += 1;
        }
        for r in 0..nc {
            for c in (0..nv).filter(|&c| em.jacobian_pattern[r * nv + c]) {
                cols[c].push((row, Src::Jacobian(r, c)));
            }
            row += 1;
        }
        for &h in &em.held {
            cols[h].push((row, Src::Const(1.0)));
            row += 1;
        }
        cols[em.forward].push((row, Src::HoldForward));
        cols[em.yaw].push((row, Src::HoldYaw));
        row += 1;
        let n_eq = row;
        let effort_row0 = row;
        for (k, act) in em.actuators.iter().enumerate() {
            if act.effort.is_finite() {
                cols[nv + k].push((row, Src::Const(1.0)));
                cols[nv + k].push((row + 1, Src::Const(-1.0)));
                row += 2;
            }
        }
        for ct in em.contacts.iter().filter(|ct| !ct.has_cone()) {
            if let Some(nr) = ct.normal {
                cols[nv + na + nr].push((row, Src::Const(-1.0)));
                row += 1;
            }
        }
        let n_nonneg = row - n_eq;
        let mut cones: Vec<SupportedConeT<f64>> = vec![ZeroConeT(n_eq)];
        if n_nonneg > 0 {
            cones.push(NonnegativeConeT(n_nonneg));
        }
        for ct in em.contacts.iter().filter(|ct| ct.has_cone()) {
            let (nr, mu) = (ct.normal.expect("a cone"), ct.friction.expect("a cone"));
            cols[nv + na + nr].push((row, Src::Const(-mu)));
            for (t, &tr) in ct.tangential.iter().enumerate() {
                cols[nv + na + tr].push((row + 1 + t, Src::Const(-1.0)));
            }
            cones.push(SecondOrderConeT(1 + ct.tangential.len()));
            row += 1 + ct.tangential.len();
        }
        let m = row;
        let mut colptr = vec![0];
        let (mut rowval, mut src) = (vec![], vec![]);
        for col in &mut cols {
            col.sort_by_key(|e| e.0);
            for &(r, s) in col.iter() {
                rowval.push(r);
                src.push(s);
            }
            colptr.push(rowval.len());
        }
        let mut b = vec![0.0; m];
        let mut r = effort_row0;
        for act in em.actuators.iter().filter(|a| a.effort.is_finite()) {
            b[r] = act.effort;
            b[r + 1] = act.effort;
            r += 2;
        }
        Self {
            n,
            m,
            a_val: vec![0.0; src.len()],
            colptr,
            rowval,
            src,
            b,
            c: vec![0.0; n],
            cones,
            solver: None,
            direction: Direction::Forward,
        }
    }

    fn fill_a(&mut self, m: &DMatrix<f64>, j: &DMatrix<f64>) {
        let hold_forward = self.direction == Direction::Yaw;
        for (val, s) in self.a_val.iter_mut().zip(&self.src) {
            *val = match *s {
                Src::Mass(i, c) => m[(i, c)],
                Src::JacobianT(r, i) => -j[(r, i)],
                Src::Jacobian(r, c) => j[(r, c)],
                Src::Const(x) => x,
                Src::HoldForward => f64::from(u8::from(hold_forward)),
                Src::HoldYaw => f64::from(u8::from(!hold_forward)),
            };
        }
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
                let p = CscMatrix::new(self.n, self.n, vec![0; self.n + 1], vec![], vec![]);
                let a = CscMatrix::new(
                    self.m,
                    self.n,
                    self.colptr.clone(),
                    self.rowval.clone(),
                    self.a_val.clone(),
                );
                let s =
                    DefaultSolver::new(&p, &self.c, &a, &self.b, &self.cones, solver_settings())
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
