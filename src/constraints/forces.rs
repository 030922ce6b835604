//! Constraint forces in physical terms: each constraint's multipliers as a force or wrench at a
//! named frame in named axes (the force exerted by the constraint ON the robot).

use super::{Constraint, ConstraintData, ConstraintSet};
use crate::algorithm::{Data, frame_placement, point_position};
use crate::model::Model;
use nalgebra::{DVector, Vector3};
use serde::Serialize;

/// One constraint's force, as reported by `eval`, the nodes and the predictor.
#[derive(Clone, Debug, Serialize)]
pub struct ConstraintForce {
    pub name: String,
    pub kind: &'static str,
    /// Frame the force acts on (its point of application is `point_world`).
    pub frame: String,
    /// Axes `force` and `torque` are expressed in ("world" or a frame name).
    pub axes: String,
    /// Row names (e.g. x, z; t1, t2, n).
    pub rows: Vec<String>,
    /// Raw multipliers λ of the rows.
    pub lambda: Vec<f64>,
    /// Force [N] on the robot.
    pub force: [f64; 3],
    /// Torque [N·m] on the robot about the point of application.
    pub torque: [f64; 3],
    /// Point of application, world [m].
    pub point_world: [f64; 3],
    /// Position residual φ of the rows [m or rad] (0 on nonholonomic rows).
    pub position_residual: Vec<f64>,
    /// Velocity residual J v of the rows [m/s or rad/s].
    pub velocity_residual: Vec<f64>,
    /// Rolling contacts: normal force [N] (NaN when the base type holds the height and no normal
    /// row exists) and tangential force magnitude [N].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub normal_force: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tangential_force: Option<f64>,
}

pub(crate) fn row_labels(c: &Constraint) -> Vec<String> {
    const AX: [&str; 6] = ["x", "y", "z", "rx", "ry", "rz"];
    match c {
        Constraint::Point(p) => p.axes.iter().map(|&i| AX[i].to_string()).collect(),
        Constraint::Weld(w) => w.rows.iter().map(|&i| AX[i].to_string()).collect(),
        Constraint::Distance(_) => vec!["distance".into()],
        Constraint::Coupling(_) => vec!["coupling".into()],
        Constraint::Rolling(r) => r
            .rows
            .iter()
            .map(|&i| ["t1", "t2", "n"][i].to_string())
            .collect(),
        Constraint::NoSideSlip(_) => vec!["lateral".into()],
    }
}

fn arr(v: Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

/// Forces of every constraint for multipliers `lambda` (after `evaluate` at the same state).
pub fn constraint_forces(
    model: &Model,
    data: &Data,
    set: &ConstraintSet,
    cd: &ConstraintData,
    lambda: &DVector<f64>,
) -> Vec<ConstraintForce> {
    let mut out = vec![];
    for (k, c) in set.items.iter().enumerate() {
        let r = set.ranges[k].clone();
        let lam: Vec<f64> = lambda.rows(r.start, r.len()).iter().copied().collect();
        let fname = |f: usize| model.frames[f].name.clone();
        let mut force = Vector3::zeros();
        let mut torque = Vector3::zeros();
        let (mut normal, mut tangential) = (None, None);
        let (frame, axes, point) = match c {
            Constraint::Point(p) => {
                for (i, &ax) in p.axes.iter().enumerate() {
                    force[ax] = lam[i];
                }
                (
                    fname(p.frame_a),
                    "world".into(),
                    point_position(model, data, p.frame_a, &p.point_a),
                )
            }
            Constraint::Weld(w) => {
                for (i, &row) in w.rows.iter().enumerate() {
                    if row < 3 {
                        force[row] = lam[i]
                    } else {
                        torque[row - 3] = lam[i]
                    }
                }
                let axes = if w.local {
                    fname(w.frame_b)
                } else {
                    "world".into()
                };
                (
                    fname(w.frame_a),
                    axes,
                    frame_placement(model, data, w.frame_a).translation,
                )
            }
            Constraint::Distance(d) => {
                let pa = point_position(model, data, d.frame_a, &d.point_a);
                let pb = point_position(model, data, d.frame_b, &d.point_b);
                force = (pa - pb).normalize() * lam[0];
                (fname(d.frame_a), "world".into(), pa)
            }
            Constraint::Coupling(cp) => {
                let jn = |vi: usize| model.v_names[vi].clone();
                (
                    format!("{}+{}", jn(cp.vi), jn(cp.vj)),
                    "joint".into(),
                    Vector3::zeros(),
                )
            }
            Constraint::Rolling(rc) => {
                let contact = rc.contact(model, data);
                let mut local = Vector3::zeros();
                for (i, &row) in rc.rows.iter().enumerate() {
                    local[row] = lam[i];
                }
                force = rc.basis * local;
                tangential = Some(local.xy().norm());
                normal = Some(if rc.rows.contains(&2) {
                    local.z
                } else {
                    f64::NAN
                });
                (fname(rc.wheel), "world".into(), contact.point)
            }
            Constraint::NoSideSlip(ns) => {
                let o_m_f = frame_placement(model, data, ns.frame);
                force = o_m_f.rotation * ns.axis * lam[0];
                (fname(ns.frame), "world".into(), o_m_f.translation)
            }
        };
        out.push(ConstraintForce {
            name: set.names[k].clone(),
            kind: c.kind(),
            frame,
            axes,
            rows: row_labels(c),
            lambda: lam,
            force: arr(force),
            torque: arr(torque),
            point_world: arr(point),
            position_residual: cd.phi.rows(r.start, r.len()).iter().copied().collect(),
            velocity_residual: cd.jv.rows(r.start, r.len()).iter().copied().collect(),
            normal_force: normal,
            tangential_force: tangential,
        });
    }
    out
}
