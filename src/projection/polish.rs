//! The bounded path: Clarabel finds the active set, a KKT re-solve with the active rows held as
//! equalities polishes v*, λ, ν, η to machine precision.
//!
//! Working set W = rows whose Clarabel dual exceeds their slack. Then a primal–dual active-set
//! loop on the equality-constrained problem `[J; C_W] v = [0; d_W]` (`kkt.rs`): add the most
//! violated row outside W; else, when the multipliers are unique, drop the row whose multiplier
//! has the wrong sign; else accept. A bound with lo = hi is one equality (free-signed). When the
//! rows of W are dependent (more active rows than the constraints leave free, as for Solo12 with
//! many joints at their limits), v* is still unique: it is checked against Clarabel's, and the
//! dependent rows are dropped to obtain one exact, sign-consistent set of multipliers (or
//! Clarabel's duals are reported, flagged `multipliers_exact = false`).

use super::activity::{mark_active, row_tol};
use super::diagnose::diagnose;
use super::problem::{Bounds, ProjectionProblem, Side};
use super::projector::{Outcome, SolvePath, VelocityProjector};
use super::qp::{IneqRow, QpCache, QpData};
use crate::error::{Error, Result};
use crate::model::Model;
use clarabel::solver::SolverStatus;
use nalgebra::DMatrix;

/// Row t is the upper row of a bound lo = hi whose lower row is already in the working set.
fn implied(ineq: &[IneqRow], working: &[usize], bounds: &Bounds, t: usize) -> bool {
    match ineq[t] {
        IneqRow::Bound(i, side) if bounds.lo[i] == bounds.hi[i] => working
            .iter()
            .any(|&w| matches!(ineq[w], IneqRow::Bound(k, s) if k == i && s != side)),
        _ => false,
    }
}

impl VelocityProjector {
    pub(super) fn solve_qp(
        &mut self,
        model: &Model,
        m: &DMatrix<f64>,
        j: &DMatrix<f64>,
        p: &ProjectionProblem,
    ) -> Result<Outcome> {
        let nc = self.nc;
        let data = QpData {
            m,
            j,
            a: &p.a,
            b: &p.b,
            bounds: &self.bounds,
            v_des: &p.v_des,
        };
        if !self.qp.as_ref().is_some_and(|c| c.matches(nc, &self.ineq)) {
            self.qp = Some(QpCache::new(&model.v_parent, nc, &self.ineq, &data));
            self.qp_builds += 1;
        }
        let qp = self.qp.as_mut().expect("built above");
        let status = qp.solve(&data);
        self.outcome.qp_iterations = qp.iterations();
        match status {
            SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => {
                self.conflicts = diagnose(&data, qp, &self.ineq);
                return Ok(self.finish_infeasible(SolvePath::ClarabelCertificate));
            }
            SolverStatus::Solved
            | SolverStatus::AlmostSolved
            | SolverStatus::MaxIterations
            | SolverStatus::MaxTime
            | SolverStatus::InsufficientProgress => {}
            other => {
                return Err(Error::Invalid(format!(
                    "velocity projection: the QP solver stopped with status {other:?}"
                )));
            }
        }
        qp.primal(&mut self.v_qp);
        let solved = matches!(status, SolverStatus::Solved | SolverStatus::AlmostSolved);
        // Working set: rows whose dual exceeds their slack.
        // (A bound with lo = hi is one equality: only its lower row joins the working set.)
        self.working.clear();
        for t in 0..self.ineq.len() {
            let (z, s) = qp.dual_slack(nc + t);
            if z > s && !implied(&self.ineq, &self.working, &self.bounds, t) {
                self.working.push(t);
            }
        }
        // Scaled multipliers μ/s_k are in the units of x = D v, whose scale is σ.
        let xscale = qp.sigma;
        let dual_tol = 1e-9 * xscale;
        let max_iter = 2 * self.ineq.len() + 10;
        let mut accepted = false;
        for _ in 0..max_iter {
            self.rows.truncate(nc);
            self.d.truncate(nc);
            for &t in &self.working {
                self.rows.push(self.ineq[t].as_row_ref());
                self.d.push(self.ineq[t].value(&self.bounds, &p.b));
            }
            self.eq
                .solve(model, j, &p.a, &self.rows, &self.d, &p.v_des)?;
            let v = self.eq.v.as_slice();
            // Most violated row outside the working set (in the QP's scaled units).
            let mut worst: Option<(usize, f64)> = None;
            for (t, &r) in self.ineq.iter().enumerate() {
                if self.working.contains(&t) {
                    continue;
                }
                let viol = r.violation(v, &self.bounds, &p.a, &p.b);
                if viol > row_tol(r, &self.bounds, &p.a, &p.b, v, self.vscale) {
                    let sv = viol * qp.row_scale[nc + t];
                    if worst.is_none_or(|(_, w)| sv > w) {
                        worst = Some((t, sv));
                    }
                }
            }
            if let Some((t, _)) = worst
                && !implied(&self.ineq, &self.working, &self.bounds, t)
            {
                self.working.push(t);
                continue;
            }
            // Wrong-signed multiplier (only meaningful when the multipliers are unique).
            if self.eq.dependent_other_rows == 0 {
                let mut wrong: Option<(usize, f64)> = None;
                for (w, &t) in self.working.iter().enumerate() {
                    let mu = self.eq.mu[nc + w];
                    // Outward-pointing sign: ν ≥ 0 at a lower bound; ν ≤ 0 upper; η = −μ ≥ 0;
                    // free on an equality lo = hi.
                    let bad = match self.ineq[t] {
                        IneqRow::Bound(i, _) if self.bounds.lo[i] == self.bounds.hi[i] => 0.0,
                        IneqRow::Bound(_, Side::Lower) => -mu,
                        _ => mu,
                    } / qp.row_scale[nc + t];
                    if bad > dual_tol && wrong.is_none_or(|(_, b)| bad > b) {
                        wrong = Some((w, bad));
                    }
                }
                if let Some((w, _)) = wrong {
                    self.working.remove(w);
                    continue;
                }
            }
            accepted = true;
            break;
        }
        let unique = accepted && self.eq.dependent_other_rows == 0;
        let mut exact = unique;
        if accepted && !unique {
            // v is unique even when the multipliers are not. The dependent rows are implied by
            // the others: without them the multipliers are unique, and if their signs are right
            // they are exact multipliers of the full problem too (zero on the rows dropped) —
            // a KKT certificate. Otherwise v is accepted only if Clarabel converged to it.
            let dep: Vec<usize> = self
                .eq
                .dependent_rows()
                .iter()
                .filter(|&&r| r >= nc)
                .map(|&r| r - nc)
                .collect();
            let kept: Vec<usize> = (0..self.working.len())
                .filter(|w| !dep.contains(w))
                .map(|w| self.working[w])
                .collect();
            self.rows.truncate(nc);
            self.d.truncate(nc);
            for &t in &kept {
                self.rows.push(self.ineq[t].as_row_ref());
                self.d.push(self.ineq[t].value(&self.bounds, &p.b));
            }
            let v_keep = self.eq.v.clone();
            self.eq
                .solve(model, j, &p.a, &self.rows, &self.d, &p.v_des)?;
            let vs = self.vscale;
            let same = (0..self.nv)
                .all(|i| (self.eq.v[i] - v_keep[i]).abs() <= 1e-9 * (v_keep[i].abs() + vs));
            let signs = kept.iter().enumerate().all(|(w, &t)| {
                let mu = self.eq.mu[nc + w];
                let bad = match self.ineq[t] {
                    IneqRow::Bound(i, _) if self.bounds.lo[i] == self.bounds.hi[i] => 0.0,
                    IneqRow::Bound(_, Side::Lower) => -mu,
                    _ => mu,
                } / qp.row_scale[nc + t];
                bad <= dual_tol
            });
            if same && signs && self.eq.dependent_other_rows == 0 {
                self.working = kept;
                exact = true;
            } else {
                self.eq.v.copy_from(&v_keep);
                let dist = (0..self.nv)
                    .map(|i| (qp.d[i] * (self.eq.v[i] - self.v_qp[i])).abs())
                    .fold(0.0, f64::max);
                accepted = solved && dist <= 1e-5 * xscale;
            }
        }
        if accepted {
            self.v.copy_from(&self.eq.v);
            self.outcome.method = SolvePath::ClarabelPolished;
        } else if solved {
            self.v.copy_from_slice(&self.v_qp);
            self.outcome.method = SolvePath::Clarabel;
        } else {
            return Err(Error::Invalid(format!(
                "velocity projection: the QP solver stopped with status {status:?} and the \
                 active-set polish did not converge"
            )));
        }
        self.outcome.rank_deficiency = self.eq.dependent_constraint_rows;
        self.outcome.multipliers_unique = unique && self.eq.dependent_constraint_rows == 0;
        self.outcome.multipliers_exact = exact;
        if !accepted {
            self.working.clear();
        }
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
        if exact {
            self.lambda.copy_from_slice(&self.eq.mu[..nc]);
            for (w, &t) in self.working.iter().enumerate() {
                let mu = self.eq.mu[nc + w];
                match self.ineq[t] {
                    IneqRow::Bound(i, _) => self.nu[i] += mu,
                    IneqRow::User(k) => self.eta[k] = -mu,
                }
            }
        } else {
            // Non-unique multipliers: Clarabel's duals (sign-consistent, ~1e-8), zero on
            // inactive rows.
            for r in 0..nc {
                self.lambda[r] = qp.multiplier(r);
            }
            for &t in &self.active {
                let mu = qp.multiplier(nc + t);
                match self.ineq[t] {
                    IneqRow::Bound(i, _) => self.nu[i] += mu,
                    IneqRow::User(k) => self.eta[k] = mu,
                }
            }
        }
        self.rows.truncate(nc);
        self.d.truncate(nc);
        Ok(self.outcome)
    }
}
