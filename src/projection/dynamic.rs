//! The projection that respects the dynamics: the velocity closest to the request (the
//! kinetic-energy metric) that the robot can reach within one control period Δt under the
//! limits of the acceleration envelope.
//!
//! ```text
//! v⁺ = argmin ½ (v⁺ − v_des)ᵀ M(q) (v⁺ − v_des)    over v⁺ (nv), τ (na), Λ (nc)
//!      subject to  M (v⁺ − v) = Δt (Q + Sᵀ τ − h) + Jᵀ Λ    impulse form of the dynamics
//!                  J(q) v⁺ = 0                             the constraints at v⁺
//!                  |τ_k| ≤ e_k                             URDF <limit effort>
//!                  Λ_n ≥ 0,  ‖Λ_t‖ ≤ μ Λ_n                 contacts push, inside their cones
//!                  lo ≤ v⁺ ≤ hi,  A v⁺ ≤ b                 the kinematic projection's bounds
//!                                                          (URDF velocity limits, request,
//!                                                          v ± a_max Δt_accel) and rows
//! ```
//!
//! v is the current velocity, h = h(q, v) the bias force, Q the force elements' generalized
//! force, S the actuated coordinates' selection, Λ the constraint impulses over the period
//! [N·s per row, the rows' convention]. Everything holds over the period with M, J, h frozen at
//! the current state (one explicit step): from rest with every contact steady, the reachable
//! set is exactly Δt times the envelope's acceleration set, which is what the tests check.
//!
//! Δt = 0 is the kinematic projection, unchanged: the same code path ([`VelocityProjector`]).
//! The per-axis acceleration limits of the request still apply as bounds, so the tighter of
//! them and the dynamics wins. The answer names what binds (the envelope's kinds: `effort`,
//! `friction`, `lift_off`, and `bound` for a velocity bound) and, when nothing is reachable, the
//! limits that cannot hold together (the support of Clarabel's infeasibility certificate).
//!
//! The cone program (`dynamic_socp.rs`) is built at the first call and updated in place; it is
//! rebuilt only when the set of finite bounds or the number of rows of A changes. Nothing else
//! allocates after the first call on an optimal answer (an infeasible one names its conflicts).

use super::activity::velocity_scale;
use super::diagnose::Conflict;
use super::dynamic_diagnose::{DynamicConflict, diagnose};
use super::dynamic_socp::{DynSocp, SocpData, SocpOutcome};
use super::problem::{ProjectionProblem, Side};
use super::projector::{Outcome, SolvePath, Status, VelocityProjector};
use super::qp::{IneqRow, inequality_rows};
use super::report::{ActiveBound, ActiveInequality, DynamicReport, NamedConflict, Projection};
use super::request::{Mode, ProjectionRequest};
use crate::constraints::ConstraintSet;
use crate::envelope::{EnvelopeModel, unchecked_limits};
use crate::error::{Error, Result, check_finite, check_len};
use crate::model::Model;
use crate::robot_limits::{
    ACTIVE_TOLERANCE, Binding, LimitKind, NamedLimit, active_limits, max_active_limits,
};
use crate::system::System;
use nalgebra::DVector;

/// Workspace and results of the dynamic projection for one model and constraint set.
pub struct DynamicProjector {
    /// The kinematic projection (Δt = 0), and the effective bounds of a dynamic call.
    pub kinematic: VelocityProjector,
    socp: Option<DynSocp>,
    builds: usize,
    ineq: Vec<IneqRow>,
    rhs: DVector<f64>,
    /// v⁺ (nv) [m/s, rad/s]; NaN when infeasible.
    pub v: DVector<f64>,
    /// Actuator torques over the period (na, [`EnvelopeModel::actuators`]) [N·m or N].
    pub tau: DVector<f64>,
    /// Constraint impulses over the period Λ (nc) [N·s or N·m·s], the rows' convention.
    pub lambda: DVector<f64>,
    /// Dual of the dynamics rows (nv) [m/s]: `M (v⁺ − v_des) = −M y − Jᵀ w + ν − Aᵀ η`;
    /// `Δt (S y)_k` is actuator k's effort multiplier, `−J y` lies in the contacts' dual cones.
    pub y: DVector<f64>,
    /// Dual of the constraint rows J v⁺ = 0 (nc).
    pub w: DVector<f64>,
    /// Bound multipliers ν (nv): ≥ 0 on an active lower bound, ≤ 0 on an upper one.
    pub nu: DVector<f64>,
    /// Multipliers η ≥ 0 of the rows of A.
    pub eta: Vec<f64>,
    /// What binds the answer: efforts, cones, lift-off, and velocity bounds (index = coordinate).
    pub binding: Vec<Binding>,
    /// Active velocity bounds (coordinate, side).
    pub active_bounds: Vec<(usize, Side)>,
    /// Active rows of A.
    pub active_rows: Vec<usize>,
    /// When infeasible: the limits that cannot hold together.
    pub conflicts: Vec<DynamicConflict>,
    /// Summary of the last call.
    pub outcome: Outcome,
}

impl DynamicProjector {
    /// Size the workspaces for the model and constraint set.
    pub fn new(model: &Model, set: &ConstraintSet) -> Self {
        let (nv, nc) = (model.nv, set.nrows);
        let kinematic = VelocityProjector::new(model, set);
        let outcome = kinematic.outcome;
        Self {
            kinematic,
            socp: None,
            builds: 0,
            ineq: Vec::with_capacity(2 * nv),
            rhs: DVector::zeros(nv),
            v: DVector::zeros(nv),
            tau: DVector::zeros(0),
            lambda: DVector::zeros(nc),
            y: DVector::zeros(nv),
            w: DVector::zeros(nc),
            nu: DVector::zeros(nv),
            eta: vec![],
            binding: vec![],
            active_bounds: Vec::with_capacity(2 * nv),
            active_rows: vec![],
            conflicts: vec![],
            outcome,
        }
    }

    /// How many times the cone program was built (once per structure: the finite bounds and
    /// the number of rows of A); other calls update it in place.
    pub fn builds(&self) -> usize {
        self.builds
    }

    /// Project `problem` at (q, v) over the period Δt = `period` [s] with the force elements'
    /// generalized force `applied` (nv). Δt = 0 is [`VelocityProjector::project`] itself (no
    /// limits needed: `em` may be `None`); Δt > 0 needs the robot's limits `em`. Results in
    /// `v`, `tau`, `lambda`, the duals and `binding` (or `conflicts`); for Δt = 0 in
    /// `kinematic`.
    #[allow(clippy::too_many_arguments)]
    pub fn project(
        &mut self,
        sys: &mut System,
        em: Option<&EnvelopeModel>,
        q: &[f64],
        v: &[f64],
        applied: &[f64],
        problem: &ProjectionProblem,
        period: f64,
    ) -> Result<Outcome> {
        if period == 0.0 {
            let p = sys.parts();
            return (self.kinematic).project(p.model, p.data, p.constraints, p.rows, q, problem);
        }
        let em = check_period(period, em)?;
        let (nv, nc) = (sys.model().nv, sys.constraints().nrows);
        sys.model().check_state(q, v)?;
        check_len("applied", applied, nv)?;
        check_finite("applied", applied)?;
        problem.validate(nv)?;
        if em.nv != nv || em.nc != nc {
            return Err(Error::Invalid(format!(
                "the limits are sized for nv = {}, nc = {}; the system has nv = {nv}, nc = {nc}",
                em.nv, em.nc
            )));
        }
        // A projection is of the present: time-dependent rows at the rows' own last time.
        sys.evaluate_rows_and_dynamics(sys.rows().t, q, v)?;
        let (m, h) = (&sys.data().mass_matrix, &sys.data().tau);
        // rhs = M v + Δt (Q − h)
        for i in 0..nv {
            let mv: f64 = (0..nv).map(|c| m[(i, c)] * v[c]).sum();
            self.rhs[i] = mv + period * (applied[i] - h[i]);
        }
        self.solve_evaluated(sys.model(), em, problem, period, sys)
    }

    fn solve_evaluated(
        &mut self,
        model: &Model,
        em: &EnvelopeModel,
        p: &ProjectionProblem,
        period: f64,
        sys: &System,
    ) -> Result<Outcome> {
        let (nv, na) = (model.nv, em.na());
        if self.tau.len() != na {
            self.tau = DVector::zeros(na);
        }
        let most = max_active_limits(&em.actuators, &em.contacts) + 2 * nv;
        if self.binding.capacity() < most {
            self.binding = Vec::with_capacity(most);
        }
        if self.eta.len() != p.b.len() {
            self.eta = vec![0.0; p.b.len()];
        }
        let kin = &mut self.kinematic;
        kin.bounds.fill(model, p);
        let vscale = velocity_scale(p, &kin.bounds);
        self.conflicts.clear();
        self.binding.clear();
        self.active_bounds.clear();
        self.active_rows.clear();
        self.outcome = Outcome {
            status: Status::Optimal,
            method: SolvePath::Dynamic,
            rank_deficiency: 0,
            multipliers_unique: false,
            multipliers_exact: false,
            qp_iterations: 0,
        };
        if let Some(i) = (0..nv).find(|&i| kin.bounds.lo[i] > kin.bounds.hi[i]) {
            for side in [Side::Lower, Side::Upper] {
                let c = Conflict::Bound { index: i, side };
                self.conflicts.push(DynamicConflict::Kinematic(c));
            }
            return Ok(self.finish_infeasible(SolvePath::BoundCheck));
        }
        inequality_rows(&kin.bounds, p.a.nrows(), &mut self.ineq);
        let data = SocpData {
            m: &sys.data().mass_matrix,
            j: &sys.rows().j,
            rhs: &self.rhs,
            v_des: &p.v_des,
            bounds: &kin.bounds,
            a: &p.a,
            b: &p.b,
            period,
        };
        if !self.socp.as_ref().is_some_and(|s| s.matches(&self.ineq)) {
            self.socp = Some(DynSocp::new(em, &self.ineq, &data)?);
            self.builds += 1;
        }
        let socp = self.socp.as_mut().expect("built above");
        let status = socp.solve(em, &data)?;
        self.outcome.qp_iterations = socp.iterations();
        let z = socp.z();
        if status == SocpOutcome::Infeasible {
            diagnose(em, socp, &data, &mut self.conflicts)?;
            return Ok(self.finish_infeasible(SolvePath::DynamicCertificate));
        }
        let x = socp.x();
        let nc = em.nc;
        self.v.as_mut_slice().copy_from_slice(&x[..nv]);
        self.tau.as_mut_slice().copy_from_slice(&x[nv..nv + na]);
        self.lambda
            .as_mut_slice()
            .copy_from_slice(&x[nv + na..nv + na + nc]);
        self.y.as_mut_slice().copy_from_slice(&z[..nv]);
        self.w.as_mut_slice().copy_from_slice(&z[nv..nv + nc]);
        self.nu.fill(0.0);
        self.eta.fill(0.0);
        // Impulses over the period: the force scale times Δt.
        let (tau, lambda) = (&x[nv..nv + na], &x[nv + na..]);
        let scale = em.force_scale * period;
        active_limits(
            &em.actuators,
            &em.contacts,
            tau,
            lambda,
            scale,
            &mut self.binding,
        );
        for (t, &row) in self.ineq.iter().enumerate() {
            let zt = z[socp.ineq_row0 + t];
            let slack = row.violation(&x[..nv], &kin.bounds, &p.a, &p.b).abs();
            let active = slack <= ACTIVE_TOLERANCE * (row.value(&kin.bounds, &p.b).abs() + vscale);
            match row {
                IneqRow::Bound(i, side) => {
                    self.nu[i] += if side == Side::Lower { zt } else { -zt };
                    if active {
                        self.active_bounds.push((i, side));
                        let b = Binding {
                            kind: LimitKind::Bound,
                            index: i,
                        };
                        // lo = hi: one coordinate held, named once.
                        if self.binding.last() != Some(&b) {
                            self.binding.push(b);
                        }
                    }
                }
                IneqRow::User(k) => {
                    self.eta[k] = zt;
                    if active {
                        self.active_rows.push(k);
                    }
                }
            }
        }
        Ok(self.outcome)
    }

    fn finish_infeasible(&mut self, method: SolvePath) -> Outcome {
        for x in [
            &mut self.v,
            &mut self.tau,
            &mut self.lambda,
            &mut self.y,
            &mut self.w,
            &mut self.nu,
        ] {
            x.fill(f64::NAN);
        }
        self.eta.fill(f64::NAN);
        self.outcome.status = Status::Infeasible;
        self.outcome.method = method;
        self.outcome
    }

    /// Evaluate at (q, v), resolve the named request, project over its `period` and name the
    /// result. `period: 0` is [`VelocityProjector::project_request`] itself. With a period the
    /// request is solved in the mass metric (`mode: twist`'s uniform scaling is kinematic).
    #[allow(clippy::too_many_arguments)]
    pub fn project_request(
        &mut self,
        sys: &mut System,
        em: Option<&EnvelopeModel>,
        q: &[f64],
        v: &[f64],
        applied: &[f64],
        request: &ProjectionRequest,
    ) -> Result<Projection> {
        let period = request.period;
        if period == 0.0 {
            return super::project_system(&mut self.kinematic, sys, q, v, request);
        }
        let em = check_period(period, em)?;
        if request.mode == Mode::Twist {
            return Err(Error::Invalid(
                "projection request: mode twist scales the request uniformly, a kinematic \
                 answer; with a period the request is solved in the mass metric (mode mass or \
                 auto)"
                    .into(),
            ));
        }
        sys.model().check_state(q, v)?;
        sys.evaluate_rows(sys.rows().t, q, v);
        let problem = request.resolve(sys.model(), &sys.rows().j, v)?;
        // The kinematics stay at (q, v) for the impulses' frames.
        self.project(sys, Some(em), q, v, applied, &problem, period)?;
        Ok(self.report(sys, em, &problem, period))
    }

    /// Name the results of the last dynamic solve (kinematics in `sys` at the same q).
    pub fn report(
        &self,
        sys: &System,
        em: &EnvelopeModel,
        problem: &ProjectionProblem,
        period: f64,
    ) -> Projection {
        let model = sys.model();
        let o = self.outcome;
        let ok = o.status == Status::Optimal;
        let row_names = sys.constraints().row_names();
        let named = |b: &Binding| NamedLimit {
            kind: b.kind.name(),
            name: em.binding_name(model, b).to_string(),
        };
        let mut binding: Vec<NamedLimit> = self.binding.iter().map(named).collect();
        let mut conflicts = vec![];
        for c in &self.conflicts {
            let (kind, index) = match *c {
                DynamicConflict::Kinematic(k) => {
                    conflicts.push(self.kinematic.name_conflict(
                        model,
                        sys.constraints(),
                        &row_names,
                        k,
                    ));
                    if let Conflict::Bound { index, .. } = k {
                        binding.push(named(&Binding {
                            kind: LimitKind::Bound,
                            index,
                        }));
                    }
                    continue;
                }
                DynamicConflict::Effort(k) => (LimitKind::Effort, k),
                DynamicConflict::Friction(k) => (LimitKind::Friction, k),
                DynamicConflict::LiftOff(k) => (LimitKind::LiftOff, k),
            };
            let b = named(&Binding { kind, index });
            let label = match kind {
                LimitKind::Effort => format!("|tau| <= effort of {} (effort)", b.name),
                LimitKind::Friction => format!("{} inside its friction cone (friction)", b.name),
                _ => format!("{} pushes, never pulls (lift_off)", b.name),
            };
            conflicts.push(NamedConflict {
                kind: b.kind,
                name: b.name.clone(),
                detail: String::new(),
                label,
            });
            binding.push(b);
        }
        let v: Vec<f64> = self.v.iter().copied().collect();
        let nb = super::base_dofs(model);
        let message = if ok {
            format!("optimal ({:?}, period {period} s)", o.method)
        } else {
            format!(
                "infeasible: no velocity reachable within {period} s meets every limit; these \
                 cannot hold together: {}",
                conflicts
                    .iter()
                    .map(|c| c.label.as_str())
                    .collect::<Vec<_>>()
                    .join("; ")
            )
        };
        let mut out = Projection {
            status: o.status,
            method: o.method,
            message,
            v_names: model.v_names.clone(),
            v_des: problem.v_des.clone(),
            v: ok.then(|| v.clone()),
            base_twist: (ok && nb > 0).then(|| v[..nb].to_vec()),
            joint_names: model.v_names[nb..].to_vec(),
            joint_velocities: ok.then(|| v[nb..].to_vec()),
            constraint_rows: row_names,
            impulses: ok.then(|| self.lambda.iter().copied().collect()),
            constraints: if ok {
                super::report::impulses(
                    model,
                    sys.data(),
                    sys.constraints(),
                    sys.rows(),
                    &self.lambda,
                )
            } else {
                vec![]
            },
            rank_deficiency: 0,
            multipliers_unique: false,
            multipliers_exact: false,
            active_bounds: self
                .active_bounds
                .iter()
                .map(|&(i, side)| {
                    let (value, source) = self.kinematic.bound(i, side);
                    ActiveBound {
                        coordinate: model.v_names[i].clone(),
                        index: i,
                        side,
                        source,
                        value,
                        multiplier: self.nu[i],
                    }
                })
                .collect(),
            active_inequalities: self
                .active_rows
                .iter()
                .map(|&k| ActiveInequality {
                    index: k,
                    multiplier: self.eta[k],
                })
                .collect(),
            conflicts,
            qp_iterations: o.qp_iterations,
            dynamics: None,
        };
        out.dynamics = Some(DynamicReport {
            period,
            binding,
            actuators: em.actuators.iter().map(|a| a.joint.clone()).collect(),
            tau: ok.then(|| self.tau.iter().copied().collect()),
            unchecked: unchecked_limits(em),
        });
        out
    }
}

/// A period is ≥ 0 and finite; a positive one needs the robot's limits.
fn check_period(period: f64, em: Option<&EnvelopeModel>) -> Result<&EnvelopeModel> {
    if !(period.is_finite() && period > 0.0) {
        return Err(Error::Invalid(format!(
            "period = {period} s must be zero (the kinematic projection) or positive and finite"
        )));
    }
    em.ok_or_else(|| Error::Unsupported {
        what: "a projection over a period".into(),
        why: "it needs the robot's limits (an envelope model: a planar or floating base)".into(),
    })
}
