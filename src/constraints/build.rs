//! One declared constraint (`ConstraintSpec`) checked against the model and built: its frames
//! and joints found, its numbers finite and in range, its rows chosen.

use super::{
    Constraint, ConstraintSpec, CouplingConstraint, DistanceConstraint, LateralGrip,
    NoSideSlipConstraint, PointConstraint, ROLLING_ROW, RollingConstraint, VelocityConstraint,
    WeldConstraint,
};
use crate::algorithm::Data;
use crate::error::{Error, Result};
use crate::model::{JointKind, Model};
use crate::spatial::{SE3, rotation_from_rpy};
use nalgebra::{DMatrix, Vector3};

pub(super) fn coupling(model: &Model, bi: usize, bj: usize, a: f64, b: f64, c: f64) -> Constraint {
    let (ji, jj) = (&model.bodies[bi].joint, &model.bodies[bj].joint);
    Constraint::Coupling(CouplingConstraint {
        qi: ji.idx_q,
        vi: ji.idx_v,
        qj: jj.idx_q,
        vj: jj.idx_v,
        a,
        b,
        c,
    })
}

/// A `friction:` coefficient: finite and positive (at most `limits::MAX_COEFFICIENT`).
fn friction_of(name: &str, mu: Option<f64>) -> Result<Option<f64>> {
    match mu {
        Some(m) if !(m > 0.0 && m <= crate::limits::MAX_COEFFICIENT) => Err(Error::Constraint {
            name: name.into(),
            message: format!(
                "friction {} must be positive and at most {:e}",
                crate::limits::show(m),
                crate::limits::MAX_COEFFICIENT
            ),
        }),
        _ => Ok(mu),
    }
}

pub(super) fn build_one(model: &Model, data: &Data, spec: &ConstraintSpec) -> Result<Constraint> {
    let name = spec.name();
    let cerr = |message: String| Error::Constraint {
        name: name.into(),
        message,
    };
    let frame = |f: &str| model.frame_id(f).map_err(|e| cerr(e.to_string()));
    let rows_of = |rows: &[super::Row], max: usize| -> Result<Vec<usize>> {
        let idx: Vec<usize> = rows.iter().map(|r| r.index()).collect();
        if idx.is_empty() {
            return Err(cerr("no rows selected".into()));
        }
        if let Some(&bad) = idx.iter().find(|&&i| i >= max) {
            return Err(cerr(format!(
                "row '{}' is not valid for this kind",
                rows[idx.iter().position(|&i| i == bad).unwrap()].name()
            )));
        }
        let mut s = idx.clone();
        s.sort();
        s.dedup();
        if s.len() != idx.len() {
            return Err(cerr("a row is selected twice".into()));
        }
        Ok(idx)
    };
    Ok(match spec {
        ConstraintSpec::Point {
            frame_a,
            point_a,
            frame_b,
            point_b,
            rows,
            unilateral,
            friction,
            ..
        } => {
            let axes = rows_of(rows, 3)?;
            let friction = friction_of(name, *friction)?;
            let frame_b = frame(frame_b)?;
            if *unilateral && axes.len() != 1 {
                return Err(cerr(format!(
                    "unilateral: true needs exactly one row (it lists {})",
                    axes.len()
                )));
            }
            if friction.is_some() {
                let on_ground = model.frames[frame_b].body == 0;
                let tangential = axes.iter().any(|&a| a != 2);
                if !(on_ground && axes.contains(&2) && tangential) {
                    return Err(cerr(
                        "friction needs a ground contact: frame_b fixed in the world, the \
                         normal row z and a tangential row x or y"
                            .into(),
                    ));
                }
            }
            Constraint::Point(PointConstraint {
                frame_a: frame(frame_a)?,
                point_a: finite3(name, "point_a", *point_a)?,
                frame_b,
                point_b: finite3(name, "point_b", *point_b)?,
                axes,
                unilateral: *unilateral,
                friction,
            })
        }
        ConstraintSpec::Weld {
            frame_a,
            frame_b,
            axes,
            rows,
            relative_xyz,
            relative_rpy,
            ..
        } => Constraint::Weld(WeldConstraint {
            frame_a: frame(frame_a)?,
            frame_b: frame(frame_b)?,
            target: SE3::new(
                rotation_from_rpy(&finite3(name, "relative_rpy", *relative_rpy)?.into()),
                finite3(name, "relative_xyz", *relative_xyz)?,
            ),
            local: *axes == super::Axes::Local,
            rows: rows_of(rows, 6)?,
        }),
        ConstraintSpec::Distance {
            frame_a,
            point_a,
            frame_b,
            point_b,
            distance,
            ..
        } => {
            if !(*distance > 0.0 && *distance <= crate::limits::MAX_LENGTH) {
                return Err(cerr(format!(
                    "distance {} m must be positive and at most {:e} m",
                    crate::limits::show(*distance),
                    crate::limits::MAX_LENGTH
                )));
            }
            Constraint::Distance(DistanceConstraint {
                frame_a: frame(frame_a)?,
                point_a: finite3(name, "point_a", *point_a)?,
                frame_b: frame(frame_b)?,
                point_b: finite3(name, "point_b", *point_b)?,
                distance: *distance,
            })
        }
        ConstraintSpec::Coupling {
            joint_i,
            joint_j,
            a,
            b,
            c,
            ..
        } => {
            let bi = model.joint_body(joint_i).map_err(|e| cerr(e.to_string()))?;
            let bj = model.joint_body(joint_j).map_err(|e| cerr(e.to_string()))?;
            for (b_, n) in [(bi, joint_i), (bj, joint_j)] {
                if !matches!(
                    model.bodies[b_].joint.kind,
                    JointKind::Revolute { .. } | JointKind::Prismatic { .. }
                ) {
                    return Err(cerr(format!("joint '{n}' is not a 1-DOF joint")));
                }
            }
            if ![*a, *b, *c]
                .iter()
                .all(|x| x.abs() <= crate::limits::MAX_COEFFICIENT)
                || (*a == 0.0 && *b == 0.0)
            {
                return Err(cerr(format!(
                    "coefficients a = {a}, b = {b}, c = {c} must be at most {:e} in magnitude \
                     (finite), a and b not both zero",
                    crate::limits::MAX_COEFFICIENT
                )));
            }
            coupling(model, bi, bj, *a, *b, *c)
        }
        ConstraintSpec::Rolling {
            wheel,
            axis,
            radius,
            axle_offset,
            axle_offset_turn_gain,
            lateral,
            plane_normal,
            plane_height,
            friction,
            ..
        } => {
            let friction = friction_of(name, *friction)?;
            if !(*radius > 0.0 && *radius <= crate::limits::MAX_LENGTH) {
                return Err(cerr(format!(
                    "wheel radius {} m must be positive and at most {:e} m",
                    crate::limits::show(*radius),
                    crate::limits::MAX_LENGTH
                )));
            }
            if !axle_offset.is_finite() || axle_offset.abs() > crate::limits::MAX_LENGTH {
                return Err(cerr(format!(
                    "axle_offset {axle_offset} m must be finite and at most {:e} m",
                    crate::limits::MAX_LENGTH
                )));
            }
            if !axle_offset_turn_gain.is_finite()
                || axle_offset_turn_gain.abs() > crate::limits::MAX_LENGTH
            {
                return Err(cerr(format!(
                    "axle_offset_turn_gain {axle_offset_turn_gain} m/(rad/s)² must be finite and \
                     at most {:e}",
                    crate::limits::MAX_LENGTH
                )));
            }
            if !plane_height.is_finite() || plane_height.abs() > crate::limits::MAX_LENGTH {
                return Err(cerr(format!(
                    "plane_height {plane_height} m must be finite and at most {:e} m",
                    crate::limits::MAX_LENGTH
                )));
            }
            let axis = unit(name, "wheel axis", *axis)?;
            let n = unit(name, "plane normal", *plane_normal)?;
            let wheel = frame(wheel)?;
            let mut c = RollingConstraint {
                wheel,
                axis,
                radius: *radius,
                axle_offset: *axle_offset,
                axle_offset_turn_gain: *axle_offset_turn_gain,
                basis: RollingConstraint::basis_for(&n),
                height: *plane_height,
                rows: match lateral {
                    LateralGrip::Rigid => vec![0, 1, 2],
                    LateralGrip::Tyre => vec![ROLLING_ROW, 2],
                },
                friction,
            };
            let a_world = crate::algorithm::frame_placement(model, data, wheel).rotation * axis;
            if a_world.dot(&n).abs() > 1.0 - 1e-9 {
                return Err(cerr(
                    "wheel axis is parallel to the plane normal: the contact point is undefined"
                        .into(),
                ));
            }
            // Keep the normal row only if the contact can move along n.
            let pc = c.contact(model, data).point;
            let o_m_w = crate::algorithm::frame_placement(model, data, wheel);
            let mut j3 = DMatrix::zeros(3, model.nv);
            crate::algorithm::point_jacobian(
                model,
                data,
                wheel,
                &o_m_w.act_inv_point(&pc),
                &mut j3,
                0,
            );
            let jn = n.transpose() * j3;
            if jn.amax() < 1e-12 {
                c.rows.retain(|&r| r != 2);
            }
            Constraint::Rolling(c)
        }
        ConstraintSpec::NoSideSlip { frame: f, axis, .. } => {
            Constraint::NoSideSlip(NoSideSlipConstraint {
                frame: frame(f)?,
                axis: unit(name, "axis", *axis)?,
            })
        }
        ConstraintSpec::Velocity {
            expression,
            variables,
            virtual_displacements,
            dependent,
            reference_velocity,
            ..
        } => Constraint::Velocity(VelocityConstraint::build(
            model,
            name,
            expression,
            variables,
            *virtual_displacements,
            dependent,
            reference_velocity,
        )?),
    })
}

fn unit(name: &str, what: &str, v: [f64; 3]) -> Result<Vector3<f64>> {
    let v = Vector3::from(v);
    let n = v.norm();
    if !(n.is_finite() && n > 1e-12) {
        return Err(Error::Constraint {
            name: name.into(),
            message: format!("{what} is zero or not finite"),
        });
    }
    Ok(v / n)
}

fn finite3(name: &str, what: &str, v: [f64; 3]) -> Result<Vector3<f64>> {
    let max = crate::limits::MAX_LENGTH;
    if v.iter().any(|x| !x.is_finite() || x.abs() > max) {
        return Err(Error::Constraint {
            name: name.into(),
            message: format!(
                "{what} [{}, {}, {}] is not finite or beyond {max:e} m",
                v[0], v[1], v[2]
            ),
        });
    }
    Ok(Vector3::from(v))
}
