//! Constraint forces in physical terms: each constraint's multipliers as a force or wrench at a
//! named frame in named axes (the force exerted by the constraint ON the robot).

use super::{Constraint, ConstraintData, ConstraintKind, ConstraintSet};
use crate::algorithm::{Data, frame_placement, point_position};
use crate::model::Model;
use crate::spatial::{Force, SE3};
use nalgebra::{DVector, Matrix3, Vector3};
use serde::Serialize;

/// One constraint's force, as reported by `eval`, the nodes and the predictor.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ConstraintForce {
    /// The constraint's name in the scene.
    pub name: String,
    /// The constraint's kind.
    pub kind: ConstraintKind,
    /// Frame the force acts on (its point of application is `point_world`); for a coupling,
    /// the two coordinates' names joined by `+`.
    pub frame: String,
    /// Origin of `frame`, world [m]; `None` for a coupling (no frame).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frame_origin_world: Option<[f64; 3]>,
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
    /// Rolling contacts: normal force [N]; absent when the base type holds the height and no
    /// normal row exists (nothing non-finite is ever reported).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub normal_force: Option<f64>,
    /// Rolling contacts: magnitude of the tangential (t₁, t₂) force [N].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tangential_force: Option<f64>,
    /// `velocity` constraints: the generalized force (∂f/∂v)ᵀλ on each velocity coordinate f
    /// depends on, with its unit (N on a linear coordinate, N·m on an angular one). λ itself
    /// is in [that unit × the coordinate's velocity unit / f's unit]: N·s/m per (m/s of f)
    /// when f is a linear velocity, for instance.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub generalized_force: Option<Vec<GeneralizedForce>>,
}

/// One entry of a `velocity` constraint's generalized force (∂f/∂v)ᵀλ.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GeneralizedForce {
    /// Velocity coordinate name (`v_names`).
    pub coordinate: String,
    /// The force on it.
    pub value: f64,
    /// `N` or `N·m`.
    pub unit: &'static str,
}

/// Unit of the generalized force dual to velocity coordinate `i`: N for a translation
/// (prismatic, a base's linear velocity), N·m for a rotation.
pub fn generalized_force_unit(model: &Model, i: usize) -> &'static str {
    use crate::model::JointKind;
    for b in model.bodies.iter().skip(1) {
        let j = &b.joint;
        if (j.idx_v..j.idx_v + j.kind.nv()).contains(&i) {
            let k = i - j.idx_v;
            let linear = match j.kind {
                JointKind::Prismatic { .. } => true,
                JointKind::FreeFlyer => k < 3,
                JointKind::Planar => k < 2,
                _ => false,
            };
            return if linear { "N" } else { "N·m" };
        }
    }
    "N·m"
}

impl ConstraintForce {
    /// The wrench on the robot about the origin of `frame` (world axes, or `axes`):
    /// τ_o = τ_p + (p − o) × f. About the point of application where there is no frame.
    pub fn wrench_at_frame_origin(&self) -> Force {
        let at_point = Force {
            lin: Vector3::from(self.force),
            ang: Vector3::from(self.torque),
        };
        match self.frame_origin_world {
            Some(o) => {
                let offset = Vector3::from(self.point_world) - Vector3::from(o);
                SE3::new(Matrix3::identity(), offset).act_force(&at_point)
            }
            None => at_point,
        }
    }
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
            .map(|&i| ["t1", "t2", "n", "rolling"][i].to_string())
            .collect(),
        Constraint::NoSideSlip(_) => vec!["lateral".into()],
        Constraint::Velocity(_) => vec!["f".into()],
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
        let mut generalized = None;
        let frame_id = match c {
            Constraint::Point(p) => Some(p.frame_a),
            Constraint::Weld(w) => Some(w.frame_a),
            Constraint::Distance(d) => Some(d.frame_a),
            Constraint::Coupling(_) => None,
            Constraint::Rolling(rc) => Some(rc.wheel),
            Constraint::NoSideSlip(ns) => Some(ns.frame),
            Constraint::Velocity(_) => None,
        };
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
                let (mut along, mut across) = (Vector3::zeros(), 0.0);
                for (i, &row) in rc.rows.iter().enumerate() {
                    if row == 2 {
                        across = lam[i];
                    } else {
                        along += rc.row_direction(row, &contact.axis) * lam[i];
                    }
                }
                force = along + rc.normal() * across;
                // The tangential rows are orthonormal: their force's norm is the hypot of their
                // λ, finite wherever they are (|t| ~ 1e308 squared overflows).
                tangential = Some(
                    (rc.rows.iter().zip(&lam))
                        .filter(|(row, _)| **row != 2)
                        .fold(0.0, |m: f64, (_, l)| m.hypot(*l)),
                );
                // No normal row (a planar base holds the height): no normal force to report.
                normal = rc.rows.contains(&2).then_some(across);
                (fname(rc.wheel), "world".into(), contact.point)
            }
            Constraint::NoSideSlip(ns) => {
                let o_m_f = frame_placement(model, data, ns.frame);
                force = o_m_f.rotation * ns.axis * lam[0];
                (fname(ns.frame), "world".into(), o_m_f.translation)
            }
            Constraint::Velocity(vc) => {
                let mut idx: Vec<usize> = vc.velocity_indices().collect();
                idx.sort();
                idx.dedup();
                let names: Vec<String> = idx.iter().map(|&i| model.v_names[i].clone()).collect();
                generalized = Some(
                    idx.iter()
                        .map(|&i| GeneralizedForce {
                            coordinate: model.v_names[i].clone(),
                            value: cd.j[(r.start, i)] * lam[0],
                            unit: generalized_force_unit(model, i),
                        })
                        .collect(),
                );
                (names.join("+"), "generalized".into(), Vector3::zeros())
            }
        };
        out.push(ConstraintForce {
            name: set.names[k].clone(),
            kind: c.kind(),
            frame_origin_world: frame_id.map(|f| arr(frame_placement(model, data, f).translation)),
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
            generalized_force: generalized,
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrench_moves_to_the_frame_origin() {
        // Contact 0.05 m below the wheel centre: τ_o = (p − o) × f = (0, 0, −0.05) × (2, 0, 10)
        // = (0, −0.1, 0).
        let f = ConstraintForce {
            name: "c".into(),
            kind: ConstraintKind::Rolling,
            frame: "wheel".into(),
            frame_origin_world: Some([0.0, 0.0, 0.05]),
            axes: "world".into(),
            rows: vec![],
            lambda: vec![],
            force: [2.0, 0.0, 10.0],
            torque: [0.0, 0.0, 0.0],
            point_world: [0.0, 0.0, 0.0],
            position_residual: vec![],
            velocity_residual: vec![],
            normal_force: Some(10.0),
            tangential_force: Some(2.0),
            generalized_force: None,
        };
        let w = f.wrench_at_frame_origin();
        assert_eq!([w.ang.x, w.ang.y, w.ang.z], [0.0, -0.1, 0.0]);
        assert_eq!([w.lin.x, w.lin.y, w.lin.z], [2.0, 0.0, 10.0]);
    }
}
