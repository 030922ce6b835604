//! Drift control after a step: mass-weighted projection of q onto φ(q) = 0 (Newton, holonomic
//! rows only) and of v onto J(q) v = 0 (Ascher, Chin, Petzold & Reich 1995):
//!   Δq = −M⁻¹ Jₕᵀ (Jₕ M⁻¹ Jₕᵀ)⁺ φₕ,  q ← q ⊕ Δq   (repeated while |φ| > tol),
//!   v ← v − M⁻¹ Jᵀ (J M⁻¹ Jᵀ)⁺ J v   (unless J v is zero to rounding: `VELOCITY_TOL`).
//! With M = L Lᵀ and Y = L⁻¹ Aᵀ the correction is `L⁻ᵀ Y μ`, `(YᵀY) μ = r`; redundant rows make
//! YᵀY singular, and a semi-definite Cholesky that drops them gives the same correction as the
//! pseudo-inverse (Y μ is unique). A massless link fixed only by the constraints (M semi-definite)
//! uses the metric M + ρ AᵀA instead: the projected point is the same on the constraint's range.
//! Everything lives in a [`DriftProjector`] sized once: a projection allocates nothing.

use crate::algorithm::DENSE_EAGER_NV;
use crate::dynamics::Baumgarte;
use crate::error::{Error, Result};
use crate::linalg::cholesky_in_place;
use crate::linalg::{semidefinite_cholesky, semidefinite_solve};
use crate::predict::InvariantDynamics;
use crate::system::System;
use nalgebra::DMatrix;
use serde::Serialize;

/// Position tolerance of the Newton projection [m or rad].
pub const POSITION_TOL: f64 = 1e-12;
/// A position residual still above this after the Newton iterations is an error [m or rad]:
/// the step moved the state too far from the constraints to come back.
pub const POSITION_FAIL: f64 = 1e-8;
/// Velocity tolerance of the projection, relative to max(1, max |v_i|): a state whose every
/// |J v| row is at most this is zero to rounding and is left as it is (the correction would
/// move v by rounding alone). After an RK4 step of 1 ms the mobile manipulator's rolling rows
/// are off by ≤ 3.3e-16 m/s, so the correction, and the metric it needs, are skipped on its
/// steps; a projection that does correct leaves |J v| near 1e-16.
pub const VELOCITY_TOL: f64 = 16.0 * f64::EPSILON;
/// Relative pivot threshold below which a constraint row counts as redundant.
const RANK_TOL: f64 = 1e-12;
const NEWTON_ITERATIONS: usize = 8;

/// Workspace of the projection (one per predictor).
#[derive(Clone, Debug, Default)]
pub struct DriftProjector {
    /// Holonomic rows of the constraint set.
    rows_h: Vec<usize>,
    /// Metric factor L (nv × nv).
    l: DMatrix<f64>,
    /// Y = L⁻¹ Aᵀ (nv × rows) and S = YᵀY (rows × rows), per row set (holonomic, all).
    y: [DMatrix<f64>; 2],
    s: [DMatrix<f64>; 2],
    dropped: [Vec<bool>; 2],
    mu: [Vec<f64>; 2],
    dq: Vec<f64>,
    q_tmp: Vec<f64>,
    rhs: Vec<f64>,
    /// Rank deficiency of the last velocity projection.
    pub rank_deficiency: usize,
    /// The last projection left (q, v) where it evaluated the rows: the kinematics and rows of
    /// the system are those of the projected state (`DynamicsOptions::rows_evaluated`).
    pub rows_current: bool,
}

impl DriftProjector {
    /// Size the workspace for the system's model and constraint set.
    pub fn new(sys: &System) -> Self {
        let (nv, nc, nq) = (sys.model().nv, sys.constraints().nrows, sys.model().nq);
        Self {
            rows_h: Vec::with_capacity(nc),
            // A large tree's is sized by its first dense metric (the tree path needs none).
            l: if nv <= DENSE_EAGER_NV {
                DMatrix::zeros(nv, nv)
            } else {
                DMatrix::zeros(0, 0)
            },
            y: [DMatrix::zeros(nv, 0), DMatrix::zeros(nv, nc)],
            s: [DMatrix::zeros(0, 0), DMatrix::zeros(nc, nc)],
            dropped: [vec![false; nc], vec![false; nc]],
            mu: [vec![0.0; nc], vec![0.0; nc]],
            dq: vec![0.0; nv],
            q_tmp: vec![0.0; nq],
            rhs: vec![0.0; nv],
            rank_deficiency: 0,
            rows_current: false,
        }
    }

    /// Project (q, v) at time `t` [s] onto the constraint manifold in place (positions first
    /// when asked).
    /// Returns the largest holonomic residual after the position projection.
    /// `form`: the scene's constant form, if it has one — no position rows, and v left as it is
    /// while it stays in the rows' null space (dynamics/invariant.rs), judged without the rows.
    pub fn project(
        &mut self,
        sys: &mut System,
        t: f64,
        q: &mut [f64],
        v: &mut [f64],
        positions: bool,
        form: Option<&InvariantDynamics>,
    ) -> Result<f64> {
        self.rows_current = false;
        if sys.constraints().is_empty() {
            return Ok(0.0);
        }
        let tol = VELOCITY_TOL * v.iter().fold(1.0f64, |m, x| m.max(x.abs()));
        if form.is_some_and(|f| f.on_constraints(v, tol)) {
            return Ok(0.0);
        }
        let mut residual = 0.0;
        if positions {
            // Leaves the rows (and the kinematics) evaluated at the corrected q.
            residual = self.project_positions(sys, t, q, v)?;
        } else {
            sys.evaluate_rows(t, q, v);
        }
        let nc = sys.constraints().nrows;
        if sys.rows().jv.iter().all(|x| x.abs() <= tol) {
            self.rows_current = true;
            return Ok(residual);
        }
        let rhs: &mut Vec<f64> = &mut self.mu[1];
        rhs[..nc].copy_from_slice(sys.rows().jv.as_slice());
        self.rank_deficiency = nc - self.correct(sys, q, 1)?;
        for (vi, d) in v.iter_mut().zip(&self.dq) {
            *vi -= d;
        }
        Ok(residual)
    }

    /// Newton on the holonomic rows. Every correction is followed by an evaluation, so on return
    /// the system's rows and kinematics are those of the final (q, v).
    fn project_positions(
        &mut self,
        sys: &mut System,
        t: f64,
        q: &mut [f64],
        v: &[f64],
    ) -> Result<f64> {
        let mut worst = 0.0;
        let nv = sys.model().nv;
        for it in 0..=NEWTON_ITERATIONS {
            let rows = sys.evaluate_rows(t, q, v);
            if it == 0 {
                self.rows_h.clear();
                let hol = &rows.holonomic;
                self.rows_h.extend((0..hol.len()).filter(|&k| hol[k]));
                let nh = self.rows_h.len();
                if self.s[0].nrows() != nh {
                    self.y[0] = DMatrix::zeros(nv, nh);
                    self.s[0] = DMatrix::zeros(nh, nh);
                }
            }
            worst = self
                .rows_h
                .iter()
                .fold(0.0f64, |m, &k| m.max(rows.phi[k].abs()));
            if self.rows_h.is_empty() || worst <= POSITION_TOL || it == NEWTON_ITERATIONS {
                break;
            }
            if !worst.is_finite() {
                break;
            }
            for (a, &k) in self.rows_h.iter().enumerate() {
                self.mu[0][a] = sys.rows().phi[k];
            }
            self.correct(sys, q, 0)?;
            self.dq.iter_mut().for_each(|x| *x = -*x);
            self.q_tmp.copy_from_slice(q);
            sys.model().integrate(&self.q_tmp, &self.dq, 1.0, q);
        }
        if worst.is_nan() || worst > POSITION_FAIL {
            return Err(Error::Diverged {
                t: f64::NAN,
                message: format!(
                    "the position projection left |φ| = {worst:.3e} after {NEWTON_ITERATIONS} \
                     Newton iterations; the step is too large for the constraints"
                ),
            });
        }
        Ok(worst)
    }

    /// `dq` = M⁻¹ Aᵀ μ with (A M⁻¹ Aᵀ) μ = `mu[set]` (the rows of `set`: 0 holonomic, 1 all) at
    /// the configuration q of the rows' last evaluation; returns the rank of A M⁻¹ Aᵀ. On a
    /// large tree by ABA's factors, without M ([`System::tree_metric`]); elsewhere through the
    /// dense metric.
    fn correct(&mut self, sys: &mut System, q: &[f64], set: usize) -> Result<usize> {
        if let Some(rank) = self.tree_correction(sys, q, set) {
            return Ok(rank);
        }
        self.metric(sys, set == 0)?;
        Ok(self.correction(sys, set))
    }

    /// [`Self::correct`] on ABA's factorization M⁻¹ = Ψᵀ D⁻¹ Ψ: Y's columns are the rows'
    /// innovations Ψ aᵀ, S = Yᵀ D⁻¹ Y (a Gram matrix, as the dense LᵀY's), dq = Ψᵀ D⁻¹ (Y μ).
    /// None where the system does not take the linear path or ABA's pivots fail there.
    fn tree_correction(&mut self, sys: &mut System, q: &[f64], set: usize) -> Option<usize> {
        if !sys.takes_linear_path() {
            return None;
        }
        let nv = sys.model().nv;
        let nr = self.s[set].nrows();
        // The rows of A first: the metric borrows the system.
        let j = &sys.rows().j;
        for a in 0..nr {
            let row = if set == 0 { self.rows_h[a] } else { a };
            for i in 0..nv {
                self.y[set][(i, a)] = j[(row, i)];
            }
        }
        let mut metric = sys.tree_metric(q)?;
        let y = self.y[set].as_mut_slice();
        for a in 0..nr {
            self.rhs.copy_from_slice(&y[a * nv..(a + 1) * nv]);
            metric.innovations(&self.rhs, &mut y[a * nv..(a + 1) * nv]);
        }
        let s = &mut self.s[set];
        for a in 0..nr {
            for b in 0..=a {
                let x = metric.product(&y[a * nv..(a + 1) * nv], &y[b * nv..(b + 1) * nv]);
                s[(a, b)] = x;
                s[(b, a)] = x;
            }
        }
        let rank = semidefinite_cholesky(s, RANK_TOL, &mut self.dropped[set]);
        semidefinite_solve(s, &self.dropped[set], &mut self.mu[set][..nr]);
        self.rhs.fill(0.0);
        for a in 0..nr {
            let m = self.mu[set][a];
            for (x, ya) in self.rhs.iter_mut().zip(&y[a * nv..(a + 1) * nv]) {
                *x += m * ya;
            }
        }
        metric.from_innovations(&self.rhs, &mut self.dq);
        Some(rank)
    }

    /// Factor the metric: M (at the rows' last evaluation), or M + ρ AᵀA when M is singular
    /// (A = holonomic rows when `holonomic`, else all rows). Returns ρ (0 for M itself).
    fn metric(&mut self, sys: &mut System, holonomic: bool) -> Result<f64> {
        let nv = sys.model().nv;
        if self.l.nrows() != nv {
            self.l = DMatrix::zeros(nv, nv);
        }
        self.l.copy_from(sys.mass_matrix_after_rows());
        if cholesky_in_place(&mut self.l, nv, 1e-14).is_ok() {
            return Ok(0.0);
        }
        let m = &sys.data().mass_matrix;
        let rho = (0..nv).map(|i| m[(i, i)]).fold(0.0, f64::max).max(1.0);
        self.l.copy_from(m);
        let rows = sys.rows();
        let j = &rows.j;
        let nc = j.nrows();
        for a in 0..nv {
            for c in 0..nv {
                let mut s = 0.0;
                for k in 0..nc {
                    if !holonomic || rows.holonomic[k] {
                        s += j[(k, a)] * j[(k, c)];
                    }
                }
                self.l[(a, c)] += rho * s;
            }
        }
        cholesky_in_place(&mut self.l, nv, 1e-14).map_err(|i| Error::SingularMass {
            message: format!(
                "projection: coordinate '{}' has no inertia and no constraint fixes it",
                sys.model().v_names[i]
            ),
        })?;
        Ok(rho)
    }

    /// Constrained accelerations in the least-squares sense, for states where the constraint
    /// accelerations cannot all be met (at or next to a singular configuration, where drift and
    /// stage errors make `J q̈ = b` slightly inconsistent): q̈ is the M-weighted projection of the
    /// free acceleration onto the rows of J that are independent, i.e.
    ///   q̈ = q̈_free − M⁻¹ Jᵀ S⁺ (J q̈_free − b),  S = J M⁻¹ Jᵀ,  b = −γ − K_d J v − K_p φ.
    /// Returns nc − rank(S).
    pub(crate) fn least_squares_accel(
        &mut self,
        sys: &mut System,
        gains: Baumgarte,
        (t, q, v): (f64, &[f64], &[f64]),
        tau: &[f64],
        qdd: &mut [f64],
    ) -> Result<usize> {
        let (nv, nc) = (sys.model().nv, sys.constraints().nrows);
        sys.evaluate_rows(t, q, v);
        let rho = self.metric(sys, false)?;
        sys.bias_after_rows();
        let (cd, h, stab) = (sys.rows(), &sys.data().tau, gains);
        let b = |k: usize| -cd.gamma[k] - stab.kd * cd.jv[k] - stab.kp * cd.phi[k];
        // q̈_free = M̃⁻¹ (τ − h + ρ Jᵀ b)
        for i in 0..nv {
            self.rhs[i] = tau[i] - h[i] + rho * (0..nc).map(|k| cd.j[(k, i)] * b(k)).sum::<f64>();
        }
        for i in 0..nv {
            let mut s = self.rhs[i];
            for k in 0..i {
                s -= self.l[(i, k)] * self.rhs[k];
            }
            self.rhs[i] = s / self.l[(i, i)];
        }
        for i in (0..nv).rev() {
            let mut s = self.rhs[i];
            for k in i + 1..nv {
                s -= self.l[(k, i)] * self.rhs[k];
            }
            self.rhs[i] = s / self.l[(i, i)];
        }
        for k in 0..nc {
            self.mu[1][k] = (0..nv).map(|i| cd.j[(k, i)] * self.rhs[i]).sum::<f64>() - b(k);
        }
        let rank = self.correction(sys, 1);
        for i in 0..nv {
            qdd[i] = self.rhs[i] - self.dq[i];
        }
        Ok(nc - rank)
    }

    /// `dq = L⁻ᵀ Y μ` with `(YᵀY) μ = r` (r in `mu[set]`), rows = holonomic (set 0) or all (set 1).
    /// Returns the rank of YᵀY.
    fn correction(&mut self, sys: &System, set: usize) -> usize {
        let nv = sys.model().nv;
        let j = &sys.rows().j;
        let nr = self.s[set].nrows();
        let y = &mut self.y[set];
        for a in 0..nr {
            let row = if set == 0 { self.rows_h[a] } else { a };
            for i in 0..nv {
                y[(i, a)] = j[(row, i)];
            }
            // y[:, a] ← L⁻¹ y[:, a]
            for i in 0..nv {
                let mut s = y[(i, a)];
                for k in 0..i {
                    s -= self.l[(i, k)] * y[(k, a)];
                }
                y[(i, a)] = s / self.l[(i, i)];
            }
        }
        let s = &mut self.s[set];
        for a in 0..nr {
            for b in 0..=a {
                let mut acc = 0.0;
                for i in 0..nv {
                    acc += y[(i, a)] * y[(i, b)];
                }
                s[(a, b)] = acc;
                s[(b, a)] = acc;
            }
        }
        let rank = semidefinite_cholesky(s, RANK_TOL, &mut self.dropped[set]);
        semidefinite_solve(s, &self.dropped[set], &mut self.mu[set][..nr]);
        // dq = L⁻ᵀ (Y μ)
        for i in 0..nv {
            self.dq[i] = (0..nr).map(|a| y[(i, a)] * self.mu[set][a]).sum();
        }
        for i in (0..nv).rev() {
            let mut s = self.dq[i];
            for k in i + 1..nv {
                s -= self.l[(k, i)] * self.dq[k];
            }
            self.dq[i] = s / self.l[(i, i)];
        }
        rank
    }
}

/// How far a measured state lay off the constraints, and how far its projection moved it
/// ([`DriftProjector::project_measured`]). Norms mix the rows' units (m and rad; m/s and rad/s).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct OffConstraints {
    /// ‖φₕ(q)‖₂ over the holonomic rows before the projection [m or rad].
    pub position_residual: f64,
    /// ‖J(q) v‖₂ before the projection [m/s or rad/s].
    pub velocity_residual: f64,
    /// ‖Δq‖₂ of the projection, tangent space [m or rad].
    pub position_correction: f64,
    /// ‖Δv‖₂ of the projection [m/s or rad/s].
    pub velocity_correction: f64,
}

impl DriftProjector {
    /// A measured (q, v) — odometry and joint states of slightly different instants, never
    /// exactly on the constraints — projected onto them in place, positions and velocities, as
    /// the drift control projects a step's end; returns how far off it was. Off the constraints
    /// redundant rows stop agreeing: two wheels on one axle hold one lateral row twice, and
    /// their γ agree only where J v = 0 (d/dt (Nᵀ J) = 0 gives Nᵀ γ = −Ṅᵀ J v for the
    /// rows' left null vector N).
    pub fn project_measured(
        &mut self,
        sys: &mut System,
        q: &mut [f64],
        v: &mut [f64],
    ) -> Result<OffConstraints> {
        if sys.constraints().is_empty() {
            return Ok(OffConstraints::default());
        }
        // A measured start is a prediction's: time-dependent rows at t = 0.
        let cd = sys.evaluate_rows(0.0, q, v);
        let norm = |x: &mut dyn Iterator<Item = f64>| x.fold(0.0, |s, y| s + y * y).sqrt();
        let position_residual = norm(
            &mut (0..cd.holonomic.len())
                .filter(|&k| cd.holonomic[k])
                .map(|k| cd.phi[k]),
        );
        let velocity_residual = norm(&mut cd.jv.iter().copied());
        let (q0, v0) = (q.to_vec(), v.to_vec());
        self.project(sys, 0.0, q, v, true, None)?;
        let mut dq = vec![0.0; sys.model().nv];
        sys.model().difference(&q0, q, &mut dq);
        Ok(OffConstraints {
            position_residual,
            velocity_residual,
            position_correction: norm(&mut dq.into_iter()),
            velocity_correction: norm(&mut v.iter().zip(&v0).map(|(a, b)| a - b)),
        })
    }
}

/// Project (q, v) onto the constraint manifold in place (convenience: a fresh workspace), as a
/// prediction's start: time-dependent rows at t = 0.
pub fn project(sys: &mut System, q: &mut [f64], v: &mut [f64], positions: bool) -> Result<()> {
    DriftProjector::new(sys)
        .project(sys, 0.0, q, v, positions, None)
        .map(|_| ())
}
