//! The named result of a projection (what the CLI prints and a node returns), built on demand from
//! the projector's numeric results (allocates; the numeric path does not).

use super::diagnose::Conflict;
use super::problem::{BoundSource, ProjectionProblem, Side};
use super::projector::{SolvePath, Status, VelocityProjector};
use super::request::{ProjectionRequest, base_dofs};
use crate::algorithm::{Data, crba_full_after_kinematics};
use crate::constraints::{ConstraintData, ConstraintSet, constraint_forces};
use crate::error::{Error, Result};
use crate::model::Model;
use crate::robot_limits::NamedLimit;
use serde::Serialize;

/// One constraint's impulse at its frame: Jᵀλ expressed as a linear impulse at a point and an
/// angular impulse about it (the constraint's force convention, see `constraints::forces`).
#[derive(Clone, Debug, Serialize)]
pub struct ConstraintImpulse {
    /// The constraint's name in the scene.
    pub name: String,
    /// The constraint's kind.
    pub kind: crate::constraints::ConstraintKind,
    /// Frame the impulse acts on; for a coupling, the two coordinates' names joined by `+`.
    pub frame: String,
    /// Axes of `impulse` / `angular_impulse` ("world", a frame name, or "joint").
    pub axes: String,
    /// Row names (e.g. x, z; t1, t2, n).
    pub rows: Vec<String>,
    /// λ of the rows [N·s or N·m·s].
    pub lambda: Vec<f64>,
    /// Linear impulse on the robot [N·s].
    pub impulse: [f64; 3],
    /// Angular impulse on the robot about the point [N·m·s].
    pub angular_impulse: [f64; 3],
    /// Point of application, world [m].
    pub point_world: [f64; 3],
}

/// A bound that holds with equality at v*.
#[derive(Clone, Debug, Serialize)]
pub struct ActiveBound {
    /// Name of the velocity coordinate (as in `v_names`).
    pub coordinate: String,
    /// Index of the velocity coordinate (0..nv).
    pub index: usize,
    /// Lower or upper bound.
    pub side: Side,
    /// Where the (tightest) bound comes from.
    pub source: BoundSource,
    /// Bound value [m/s or rad/s].
    pub value: f64,
    /// ν_i [N·s or N·m·s]: ≥ 0 on a lower bound, ≤ 0 on an upper bound.
    pub multiplier: f64,
}

/// A row of A v ≤ b that holds with equality at v*.
#[derive(Clone, Debug, Serialize)]
pub struct ActiveInequality {
    /// Row k of A v ≤ b.
    pub index: usize,
    /// η ≥ 0.
    pub multiplier: f64,
}

/// A member of a conflicting set, named.
#[derive(Clone, Debug, Serialize)]
pub struct NamedConflict {
    /// "constraint", "bound" or "inequality".
    pub kind: &'static str,
    /// Constraint name, coordinate name or `A[k]`.
    pub name: String,
    /// Constraint row label, or the bound's side.
    pub detail: String,
    /// e.g. `left_wheel_joint >= 1 (request)`, `left_wheel_contact/t1 = 0`.
    pub label: String,
}

/// What the dynamics add to a named projection (absent when Δt = 0).
#[derive(Clone, Debug, Serialize)]
pub struct DynamicReport {
    /// The control period Δt [s].
    pub period: f64,
    /// The limits that bind the answer (or, when infeasible, that cannot hold together).
    pub binding: Vec<NamedLimit>,
    /// The actuated joints, in order.
    pub actuators: Vec<String>,
    /// Their torques (forces) over the period [N·m or N]; absent when infeasible.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tau: Option<Vec<f64>>,
    /// Limits the dynamics cannot check (as the envelope lists them).
    pub unchecked: Vec<NamedLimit>,
}

/// The result by name.
#[derive(Clone, Debug, Serialize)]
pub struct Projection {
    /// Optimal or infeasible.
    pub status: Status,
    /// How the result was obtained.
    pub method: SolvePath,
    /// `optimal (method)`, or `infeasible: ...` listing the conflicting set.
    pub message: String,
    /// Names of the nv velocity coordinates, in order.
    pub v_names: Vec<String>,
    /// Resolved desired velocity (nv) [m/s, rad/s].
    pub v_des: Vec<f64>,
    /// v* [m/s, rad/s]; absent when infeasible (the CLI prints no null).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub v: Option<Vec<f64>>,
    /// v* split: base twist in the base frame (planar [vx, vy, wz], floating 6), then joints.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub base_twist: Option<Vec<f64>>,
    /// Names of the joint velocity coordinates (after the base's).
    pub joint_names: Vec<String>,
    /// v* of the joints [rad/s or m/s]; absent when infeasible (the CLI prints no null).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub joint_velocities: Option<Vec<f64>>,
    /// Constraint row names `constraint/row`, in stacked order.
    pub constraint_rows: Vec<String>,
    /// λ per constraint row [N·s or N·m·s]; absent when infeasible (the CLI prints no null).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub impulses: Option<Vec<f64>>,
    /// Impulse of each constraint at its frame; empty when infeasible.
    pub constraints: Vec<ConstraintImpulse>,
    /// Constraint rows dependent on the others (nc − rank J M⁻¹ Jᵀ).
    pub rank_deficiency: usize,
    /// λ and ν are unique ([Jᵀ, active rows] has full column rank).
    pub multipliers_unique: bool,
    /// False when the multipliers are the QP solver's duals (~1e-8), see [`super::Outcome`].
    pub multipliers_exact: bool,
    /// Bounds holding with equality at v*.
    pub active_bounds: Vec<ActiveBound>,
    /// Rows of A v ≤ b holding with equality at v*.
    pub active_inequalities: Vec<ActiveInequality>,
    /// A minimal conflicting set, named; empty unless infeasible.
    pub conflicts: Vec<NamedConflict>,
    /// Clarabel interior-point iterations (0 when not called).
    pub qp_iterations: u32,
    /// With a control period: the period, what binds and the torques (absent when Δt = 0).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dynamics: Option<DynamicReport>,
}

/// Each constraint's impulse `lambda` (nc) at its frame (kinematics in `data`).
pub(super) fn impulses(
    model: &Model,
    data: &Data,
    set: &ConstraintSet,
    cd: &ConstraintData,
    lambda: &nalgebra::DVector<f64>,
) -> Vec<ConstraintImpulse> {
    constraint_forces(model, data, set, cd, lambda)
        .into_iter()
        .map(|f| ConstraintImpulse {
            name: f.name,
            kind: f.kind,
            frame: f.frame,
            axes: f.axes,
            rows: f.rows,
            lambda: f.lambda,
            impulse: f.force,
            angular_impulse: f.torque,
            point_world: f.point_world,
        })
        .collect()
}

fn relation(side: Side) -> &'static str {
    match side {
        Side::Lower => ">=",
        Side::Upper => "<=",
    }
}

impl VelocityProjector {
    /// Evaluate at (q, v_current), resolve the named request, solve, and name the result.
    #[allow(clippy::too_many_arguments)]
    pub fn project_request(
        &mut self,
        model: &Model,
        data: &mut Data,
        set: &ConstraintSet,
        cd: &mut ConstraintData,
        q: &[f64],
        v_current: &[f64],
        request: &ProjectionRequest,
    ) -> Result<Projection> {
        model.check_state(q, v_current)?;
        if request.period != 0.0 {
            return Err(Error::Invalid(format!(
                "projection request: period = {} s needs the robot's limits; project it with \
                 DynamicProjector (the CLI's --period)",
                request.period
            )));
        }
        // A projection is of the present: time-dependent rows at the rows' own last time.
        let t = cd.t;
        set.evaluate(model, data, cd, t, q, v_current);
        crba_full_after_kinematics(model, data);
        let problem = request.resolve(model, &cd.j, v_current)?;
        let twist_done = request.effective_mode() == super::Mode::Twist
            && self
                .solve_twist(
                    model,
                    &data.mass_matrix,
                    &cd.j,
                    &problem,
                    &request.given(model)?,
                )?
                .is_some();
        if !twist_done {
            self.solve_evaluated(model, &data.mass_matrix, &cd.j, &problem)?;
        }
        Ok(self.report(model, data, set, cd, &problem))
    }

    /// Name the results of the last solve (kinematics in `data` at the same q).
    pub fn report(
        &self,
        model: &Model,
        data: &Data,
        set: &ConstraintSet,
        cd: &ConstraintData,
        problem: &ProjectionProblem,
    ) -> Projection {
        let o = self.outcome;
        let ok = o.status == Status::Optimal;
        let nb = base_dofs(model);
        let row_names = set.row_names();
        let v: Vec<f64> = self.v.iter().copied().collect();
        let constraints = if ok {
            impulses(model, data, set, cd, &self.lambda)
        } else {
            vec![]
        };
        let active_bounds = self
            .active_bounds()
            .map(|(i, side)| {
                let (value, source) = self.bound(i, side);
                ActiveBound {
                    coordinate: model.v_names[i].clone(),
                    index: i,
                    side,
                    source,
                    value,
                    multiplier: self.nu[i],
                }
            })
            .collect();
        let active_inequalities = self
            .active_inequalities()
            .map(|k| ActiveInequality {
                index: k,
                multiplier: self.eta[k],
            })
            .collect();
        let conflicts: Vec<NamedConflict> = self
            .conflicts
            .iter()
            .map(|c| self.name_conflict(model, set, &row_names, *c))
            .collect();
        let message = if ok {
            format!("optimal ({:?})", o.method)
        } else {
            format!(
                "infeasible: these cannot hold together: {}",
                conflicts
                    .iter()
                    .map(|c| c.label.as_str())
                    .collect::<Vec<_>>()
                    .join("; ")
            )
        };
        Projection {
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
            constraints,
            rank_deficiency: o.rank_deficiency,
            multipliers_unique: o.multipliers_unique,
            multipliers_exact: o.multipliers_exact,
            active_bounds,
            active_inequalities,
            conflicts,
            qp_iterations: o.qp_iterations,
            dynamics: None,
        }
    }

    pub(super) fn name_conflict(
        &self,
        model: &Model,
        set: &ConstraintSet,
        rows: &[String],
        c: Conflict,
    ) -> NamedConflict {
        match c {
            Conflict::ConstraintRow(r) => {
                let k = set
                    .ranges
                    .iter()
                    .position(|rg| rg.contains(&r))
                    .unwrap_or(0);
                let name = set.names.get(k).cloned().unwrap_or_default();
                let row = rows[r].rsplit('/').next().unwrap_or("").to_string();
                NamedConflict {
                    kind: "constraint",
                    label: format!("{} = 0 (constraint {})", rows[r], set.items[k].kind()),
                    name,
                    detail: row,
                }
            }
            Conflict::Bound { index, side } => {
                let (value, source) = self.bound(index, side);
                let name = model.v_names[index].clone();
                NamedConflict {
                    kind: "bound",
                    label: format!("{name} {} {value} ({})", relation(side), source.label()),
                    name,
                    detail: format!("{side:?}").to_lowercase(),
                }
            }
            Conflict::Inequality(k) => NamedConflict {
                kind: "inequality",
                name: format!("A[{k}]"),
                detail: String::new(),
                label: format!("A[{k}] v <= b[{k}]"),
            },
        }
    }
}
