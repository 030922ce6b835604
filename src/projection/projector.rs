//! `VelocityProjector`: the workspace built once per model and constraint set, and the solve.
//!
//! 1. Kinematics at q, J (nc × nv) and M (CRBA) from one pass.
//! 2. Effective bounds (URDF limit, request, acceleration limit; tightest per side). A coordinate
//!    whose lower bound exceeds its upper bound is infeasible at once, both bounds named.
//! 3. Equality-only KKT solve (`kkt.rs`). Without finite bounds or rows of A this is the answer
//!    (`SolvePath::Kkt`); if it already satisfies every inequality it is also the bounded optimum
//!    (`SolvePath::KktBoundsInactive`: the problem is convex, so the KKT point of the equality
//!    problem that is feasible is optimal).
//! 4. Otherwise Clarabel (`qp.rs`) finds the active set; a KKT re-solve with the active rows held
//!    as equalities polishes v, λ, ν to machine precision (`SolvePath::ClarabelPolished`), after a
//!    few primal–dual active-set corrections if Clarabel's set was not exactly right.
//! 5. A primal-infeasible QP is diagnosed (`diagnose.rs`): the infeasibility certificate's
//!    support, reduced by a deletion filter to a minimal conflicting set, named.

use super::activity::{mark_active, row_tol, velocity_scale};
use super::diagnose::Conflict;
use super::kkt::{EqualityWorkspace, RowRef};
use super::problem::{Bounds, ProjectionProblem, Side};
use super::qp::{IneqRow, QpCache, inequality_rows};
use crate::algorithm::{Data, crba_full_after_kinematics};
use crate::constraints::{ConstraintData, ConstraintSet};
use crate::error::{Error, Result, check_finite, check_len};
use crate::model::Model;
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

/// Optimal, or no velocity satisfies every constraint, bound and inequality.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// v* found: the optimum of the projection problem.
    Optimal,
    /// No velocity satisfies every constraint, bound and inequality.
    Infeasible,
}

/// How the result was obtained.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SolvePath {
    /// Equality constraints only: one KKT solve.
    Kkt,
    /// Bounds or inequalities present, none binding at the equality-only solution.
    KktBoundsInactive,
    /// Clarabel found the active set; KKT re-solve with the active rows held.
    ClarabelPolished,
    /// Clarabel's own solution (the polish did not verify; accuracy ~1e-8).
    Clarabel,
    /// Infeasible before any solve (a lower bound above an upper bound).
    BoundCheck,
    /// Infeasibility certificate from Clarabel.
    ClarabelCertificate,
    /// Planner semantics: nearest in the requested components, uniformly scaled to the bounds.
    TwistScaled,
    /// Over a control period: the cone program of the dynamic projection (`dynamic.rs`),
    /// Clarabel's solution (tolerance 1e-10).
    Dynamic,
    /// Over a control period: infeasibility certificate of the cone program.
    DynamicCertificate,
}

/// Summary of the last `project` call (Copy: returned without allocating).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Outcome {
    /// Optimal or infeasible.
    pub status: Status,
    /// How the result was obtained.
    pub method: SolvePath,
    /// Constraint rows dependent on the others (nc − rank J M⁻¹ Jᵀ).
    pub rank_deficiency: usize,
    /// λ and ν are unique ([Jᵀ, active rows] has full column rank).
    pub multipliers_unique: bool,
    /// λ, ν, η satisfy the KKT conditions to machine precision (from a KKT solve); false when
    /// they are Clarabel's duals (about 1e-8), which happens only when they are not unique and
    /// no independent subset of the active rows has sign-consistent multipliers.
    pub multipliers_exact: bool,
    /// Clarabel interior-point iterations (0 when not called).
    pub qp_iterations: u32,
}

/// Workspace and results of the velocity projection for one model and constraint set.
pub struct VelocityProjector {
    pub(super) nv: usize,
    pub(super) nc: usize,
    pub(super) eq: EqualityWorkspace,
    pub(super) bounds: Bounds,
    pub(super) rows: Vec<RowRef>,
    pub(super) d: Vec<f64>,
    pub(super) ineq: Vec<IneqRow>,
    pub(super) working: Vec<usize>,
    pub(super) qp: Option<QpCache>,
    pub(super) qp_builds: usize,
    /// Velocity scale of the current problem (tolerances are relative to it).
    pub(super) vscale: f64,
    pub(super) zero_v: Vec<f64>,
    pub(super) v_qp: Vec<f64>,
    /// v* (nv) [m/s, rad/s]; meaningless when infeasible.
    pub v: DVector<f64>,
    /// Impulse per constraint row λ (nc) [N·s or N·m·s]: M (v* − v_des) = Jᵀλ + ν − Aᵀη.
    pub lambda: DVector<f64>,
    /// Bound multipliers ν per coordinate (nv): ≥ 0 on an active lower bound, ≤ 0 on an upper.
    pub nu: DVector<f64>,
    /// Multipliers η ≥ 0 of the rows of A.
    pub eta: Vec<f64>,
    /// Active inequality rows (indices into `ineq`).
    pub(super) active: Vec<usize>,
    /// A minimal conflicting set when infeasible (named by [`super::Projection`]).
    pub conflicts: Vec<Conflict>,
    /// Summary of the last solve.
    pub outcome: Outcome,
}

impl VelocityProjector {
    /// Size every workspace for the model and constraint set.
    pub fn new(model: &Model, set: &ConstraintSet) -> Self {
        let (nv, nc) = (model.nv, set.nrows);
        Self {
            nv,
            nc,
            eq: EqualityWorkspace::new(nv, nc + nv),
            bounds: Bounds::new(nv),
            rows: (0..nc).map(RowRef::Jacobian).collect(),
            d: vec![0.0; nc],
            ineq: Vec::with_capacity(2 * nv),
            working: Vec::with_capacity(2 * nv),
            qp: None,
            qp_builds: 0,
            vscale: 1.0,
            zero_v: vec![0.0; nv],
            v_qp: vec![0.0; nv],
            v: DVector::zeros(nv),
            lambda: DVector::zeros(nc),
            nu: DVector::zeros(nv),
            eta: vec![],
            active: Vec::with_capacity(2 * nv),
            conflicts: vec![],
            outcome: Outcome {
                status: Status::Optimal,
                method: SolvePath::Kkt,
                rank_deficiency: 0,
                multipliers_unique: true,
                multipliers_exact: true,
                qp_iterations: 0,
            },
        }
    }

    /// Project at configuration q: kinematics, J, M, then [`Self::solve_evaluated`].
    /// Results in `v`, `lambda`, `nu`, `eta`, `conflicts`; J in `cd.j`, M in `data.mass_matrix`.
    #[allow(clippy::too_many_arguments)]
    pub fn project(
        &mut self,
        model: &Model,
        data: &mut Data,
        set: &ConstraintSet,
        cd: &mut ConstraintData,
        q: &[f64],
        problem: &ProjectionProblem,
    ) -> Result<Outcome> {
        check_len("q", q, model.nq)?;
        check_finite("q", q)?;
        problem.validate(model.nv)?; // before using v_current
        let v_eval = match &problem.accel_limit {
            Some(al) => al.v_current.as_slice(),
            None => self.zero_v.as_slice(),
        };
        // A projection is of the present: time-dependent rows at the rows' own last time.
        let t = cd.t;
        set.evaluate(model, data, cd, t, q, v_eval);
        crba_full_after_kinematics(model, data);
        self.solve_evaluated(model, &data.mass_matrix, &cd.j, problem)
    }

    /// The projection for given M (nv × nv) and J (nc × nv).
    pub fn solve_evaluated(
        &mut self,
        model: &Model,
        m: &DMatrix<f64>,
        j: &DMatrix<f64>,
        p: &ProjectionProblem,
    ) -> Result<Outcome> {
        let (nv, nc) = (self.nv, self.nc);
        if m.shape() != (nv, nv) || j.shape() != (nc, nv) || model.nv != nv {
            return Err(Error::Invalid(format!(
                "projector sized for nv = {nv}, nc = {nc}; got M {:?}, J {:?}",
                m.shape(),
                j.shape()
            )));
        }
        p.validate(nv)?;
        self.bounds.fill(model, p);
        self.vscale = velocity_scale(p, &self.bounds);
        self.conflicts.clear();
        self.active.clear();
        self.working.clear();
        self.nu.as_mut_slice().fill(0.0);
        if self.eta.len() != p.b.len() {
            self.eta = vec![0.0; p.b.len()];
        }
        self.eta.fill(0.0);
        self.outcome.qp_iterations = 0;
        if let Some(i) = (0..nv).find(|&i| self.bounds.lo[i] > self.bounds.hi[i]) {
            self.conflicts.push(Conflict::Bound {
                index: i,
                side: Side::Lower,
            });
            self.conflicts.push(Conflict::Bound {
                index: i,
                side: Side::Upper,
            });
            return Ok(self.finish_infeasible(SolvePath::BoundCheck));
        }
        // Equality-only KKT.
        self.eq.factor_mass(model, m, j)?;
        self.eq
            .solve(model, j, &p.a, &self.rows[..nc], &self.d[..nc], &p.v_des)?;
        self.v.copy_from(&self.eq.v);
        self.lambda.copy_from_slice(&self.eq.mu[..nc]);
        self.outcome.status = Status::Optimal;
        self.outcome.rank_deficiency = self.eq.dependent_constraint_rows;
        self.outcome.multipliers_unique = self.eq.dependent_constraint_rows == 0;
        self.outcome.multipliers_exact = true;
        if !self.bounds.any() && p.a.nrows() == 0 {
            self.outcome.method = SolvePath::Kkt;
            return Ok(self.outcome);
        }
        inequality_rows(&self.bounds, p.a.nrows(), &mut self.ineq);
        let feasible = self.ineq.iter().all(|&r| {
            r.violation(self.v.as_slice(), &self.bounds, &p.a, &p.b)
                <= row_tol(r, &self.bounds, &p.a, &p.b, self.v.as_slice(), self.vscale)
        });
        if feasible {
            let v = self.v.as_slice();
            mark_active(
                &self.ineq,
                &self.working,
                &self.bounds,
                p,
                v,
                self.vscale,
                &mut self.active,
            );
            self.outcome.method = SolvePath::KktBoundsInactive;
            return Ok(self.outcome);
        }
        self.solve_qp(model, m, j, p)
    }

    /// `mode: twist` (see `twist.rs`); `Ok(None)` when no uniform scale exists (zero velocity
    /// violates a bound) and the caller should solve in the mass metric.
    pub(super) fn solve_twist(
        &mut self,
        model: &Model,
        m: &DMatrix<f64>,
        j: &DMatrix<f64>,
        p: &ProjectionProblem,
        given: &[bool],
    ) -> Result<Option<Outcome>> {
        p.validate(self.nv)?;
        self.bounds.fill(model, p);
        self.vscale = velocity_scale(p, &self.bounds);
        let Some(v_eq) = super::twist::nearest_in_task(m, j, given, &p.v_des) else {
            return Ok(None);
        };
        let Some(s) =
            super::twist::largest_feasible_scale(v_eq.as_slice(), &self.bounds, &p.a, &p.b)
        else {
            return Ok(None);
        };
        self.v.copy_from(&(v_eq * s));
        self.conflicts.clear();
        self.active.clear();
        self.working.clear();
        self.lambda.as_mut_slice().fill(0.0);
        self.nu.as_mut_slice().fill(0.0);
        self.eta = vec![0.0; p.b.len()];
        inequality_rows(&self.bounds, p.a.nrows(), &mut self.ineq);
        let v = self.v.as_slice();
        mark_active(
            &self.ineq,
            &self.working,
            &self.bounds,
            p,
            v,
            self.vscale,
            &mut self.active,
        );
        self.outcome = Outcome {
            status: Status::Optimal,
            method: SolvePath::TwistScaled,
            rank_deficiency: 0,
            multipliers_unique: false,
            multipliers_exact: false,
            qp_iterations: 0,
        };
        Ok(Some(self.outcome))
    }

    pub(super) fn finish_infeasible(&mut self, method: SolvePath) -> Outcome {
        self.v.fill(f64::NAN);
        self.lambda.fill(f64::NAN);
        self.nu.fill(f64::NAN);
        self.eta.fill(f64::NAN);
        self.outcome.status = Status::Infeasible;
        self.outcome.method = method;
        self.outcome.multipliers_unique = false;
        self.outcome.multipliers_exact = false;
        self.outcome
    }

    /// How many times the Clarabel problem was built (once per structure: which coordinates
    /// carry finite bounds, and the number of rows of A); other calls update it in place.
    pub fn qp_builds(&self) -> usize {
        self.qp_builds
    }

    /// Active inequality rows of the last solve: `(coordinate, side)` for bounds.
    pub fn active_bounds(&self) -> impl Iterator<Item = (usize, Side)> + '_ {
        self.active.iter().filter_map(|&t| match self.ineq[t] {
            IneqRow::Bound(i, s) => Some((i, s)),
            IneqRow::User(_) => None,
        })
    }

    /// Active rows of A of the last solve.
    pub fn active_inequalities(&self) -> impl Iterator<Item = usize> + '_ {
        self.active.iter().filter_map(|&t| match self.ineq[t] {
            IneqRow::User(k) => Some(k),
            IneqRow::Bound(..) => None,
        })
    }

    /// Effective bound of coordinate i on a side, with its source.
    pub fn bound(&self, i: usize, side: Side) -> (f64, super::BoundSource) {
        match side {
            Side::Lower => (self.bounds.lo[i], self.bounds.lo_src[i]),
            Side::Upper => (self.bounds.hi[i], self.bounds.hi_src[i]),
        }
    }
}
