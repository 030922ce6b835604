//! Conversions between the core library's values and ROS messages (pure functions).
//!
//! Conventions (REP-103/105): poses in the odom frame, twists in the base frame, SI units; the
//! base coordinates are the core's (`constraint_dynamics::model::base`).

use constraint_dynamics::Model;
use constraint_dynamics::constraints::{ConstraintForce as CoreForce, Contact, ContactState};
use constraint_dynamics::model::{BasePose, BaseTwist};
use constraint_dynamics::predict::{ContactJudge, Sample, Trajectory};
use constraint_dynamics::spatial::Force;

use crate::error::NodeError;
use crate::msg::builtin_interfaces::Time;
use crate::msg::constraint_dynamics_msgs::{ConstraintForce, ConstraintForces};
use crate::msg::geometry_msgs::{Point, Pose, PoseStamped, Quaternion, Twist, Vector3, Wrench};
use crate::msg::nav_msgs::Path;
use crate::msg::std_msgs::Header;

/// Yaw [rad] of a quaternion (rotation about z of the heading), after normalising it.
/// Errors on a non-finite or zero quaternion.
pub fn yaw_of(q: &Quaternion) -> Result<f64, NodeError> {
    let [x, y, z, w] = unit_quaternion(q)?;
    Ok((2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z)))
}

/// The quaternion normalised, as (x, y, z, w). Errors on non-finite or zero length.
pub fn unit_quaternion(q: &Quaternion) -> Result<[f64; 4], NodeError> {
    let a = [q.x, q.y, q.z, q.w];
    if a.iter().any(|x| !x.is_finite()) {
        return Err(NodeError::message(
            "orientation",
            format!("{a:?} is not finite"),
        ));
    }
    let n = a.iter().map(|x| x * x).sum::<f64>().sqrt();
    if n < 1e-9 {
        return Err(NodeError::message("orientation", "is a zero quaternion"));
    }
    Ok(a.map(|x| x / n))
}

/// The quaternion of a rotation by `yaw` about z.
pub fn quaternion_from_yaw(yaw: f64) -> Quaternion {
    Quaternion {
        x: 0.0,
        y: 0.0,
        z: (0.5 * yaw).sin(),
        w: (0.5 * yaw).cos(),
    }
}

fn v3(a: [f64; 3]) -> Vector3 {
    Vector3 {
        x: a[0],
        y: a[1],
        z: a[2],
    }
}

/// A core base pose as a `geometry_msgs/Pose`.
pub fn pose_msg(p: &BasePose) -> Pose {
    let [x, y, z, w] = p.orientation_xyzw;
    Pose {
        position: Point {
            x: p.position[0],
            y: p.position[1],
            z: p.position[2],
        },
        orientation: Quaternion { x, y, z, w },
    }
}

/// A core base twist as a `geometry_msgs/Twist`.
pub fn twist_msg(t: &BaseTwist) -> Twist {
    Twist {
        linear: v3(t.linear),
        angular: v3(t.angular),
    }
}

/// A `geometry_msgs/Twist` as a core base twist.
pub fn base_twist_of(t: &Twist) -> BaseTwist {
    BaseTwist {
        linear: [t.linear.x, t.linear.y, t.linear.z],
        angular: [t.angular.x, t.angular.y, t.angular.z],
    }
}

/// A spatial force as a `geometry_msgs/Wrench`.
pub fn wrench_msg(f: &Force) -> Wrench {
    Wrench {
        force: v3([f.lin.x, f.lin.y, f.lin.z]),
        torque: v3([f.ang.x, f.ang.y, f.ang.z]),
    }
}

/// A time `dt` seconds after `t`.
pub fn time_plus(t: Time, dt: f64) -> Time {
    Time::from_nanos(t.to_nanos().saturating_add((dt * 1e9).round() as i64))
}

/// The predicted base poses as a `nav_msgs/Path` in `frame_id`, each stamped `start + t`.
pub fn path_msg(model: &Model, traj: &Trajectory, start: Time, frame_id: &str) -> Path {
    Path {
        header: Header {
            stamp: start,
            frame_id: frame_id.to_string(),
        },
        poses: traj
            .samples
            .iter()
            .map(|s| PoseStamped {
                header: Header {
                    stamp: time_plus(start, s.t),
                    frame_id: frame_id.to_string(),
                },
                pose: pose_msg(&model.base_pose(&s.q)),
            })
            .collect(),
    }
}

/// The constraint forces at one state, as the core gives them (`constraint_forces_at`, or a
/// prediction's sample).
#[derive(Clone, Copy, Debug, Default)]
pub struct ForcesAt<'a> {
    /// Each constraint's force, in the scene's order.
    pub forces: &'a [CoreForce],
    /// The stacked multipliers λ (nc).
    pub lambda: &'a [f64],
    /// Jᵀλ (nv) [N or N·m].
    pub generalized_force: &'a [f64],
    /// nc − rank(J M⁻¹ Jᵀ).
    pub rank_deficiency: usize,
    /// Each contact judged at λ, in the order of [`ContactJudge::contacts`]; `None` without
    /// contacts.
    pub contacts: Option<&'a [ContactState]>,
}

impl<'a> ForcesAt<'a> {
    /// The forces a prediction's sample carries (`None` when it was predicted without).
    pub fn of_sample(s: &'a Sample) -> Option<Self> {
        Some(ForcesAt {
            forces: s.forces.as_deref()?,
            lambda: s.lambda.as_deref()?,
            generalized_force: s.generalized_force.as_deref().unwrap_or_default(),
            rank_deficiency: s.rank_deficiency.unwrap_or(0),
            contacts: s.contacts.as_deref(),
        })
    }

    /// Each constraint's contact and its state (`judge`'s contacts are those the states were
    /// judged with); `None` for a constraint that limits no force.
    pub fn judged(&self, judge: &'a ContactJudge) -> Vec<Option<(&'a Contact, ContactState)>> {
        let mut out = vec![None; self.forces.len()];
        for ((k, c), s) in judge
            .contacts()
            .iter()
            .zip(self.contacts.unwrap_or_default())
        {
            if let Some(slot) = out.get_mut(*k) {
                *slot = Some((c, *s));
            }
        }
        out
    }
}

/// Everything a `ConstraintForces` message needs besides the forces.
pub struct ForcesContext<'a> {
    /// Header stamp.
    pub stamp: Time,
    /// The fixed frame that replaces the core's "world".
    pub world_frame: &'a str,
    /// Names of the velocity coordinates (the order of `generalized_force`).
    pub v_names: &'a [String],
    /// The contacts the forces' states were judged with.
    pub contacts: &'a ContactJudge,
}

/// A `ConstraintForces` message from core forces: each wrench about its frame's origin; each
/// contact's normal force N (λ_n, or the assumed one of a wheel without a normal row), its
/// tangential force ‖λ_t‖, and `slipping` where it breaks — slip (‖λ_t‖ > μ N) or lift-off
/// (λ_n < 0, N then the pull it would need).
pub fn constraint_forces_msg(at: &ForcesAt, ctx: &ForcesContext) -> ConstraintForces {
    let world = |s: &str| {
        if s == "world" {
            ctx.world_frame.to_string()
        } else {
            s.to_string()
        }
    };
    let constraints = (at.forces.iter())
        .zip(at.judged(ctx.contacts))
        .map(|(f, judged)| ConstraintForce {
            name: f.name.clone(),
            kind: f.kind.name().to_string(),
            frame_id: world(&f.frame),
            axes_frame_id: world(&f.axes),
            wrench: wrench_msg(&f.wrench_at_frame_origin()),
            multipliers: f.lambda.clone(),
            row_names: f.rows.clone(),
            position_residual: f.position_residual.clone(),
            velocity_residual: f.velocity_residual.clone(),
            normal_force: judged.and_then(|(_, s)| s.normal_force).unwrap_or(0.0),
            tangential_force: judged.map_or(0.0, |(_, s)| s.tangential_force),
            slipping: judged.is_some_and(|(_, s)| s.breaks.is_some()),
        })
        .collect();
    ConstraintForces {
        header: Header {
            stamp: ctx.stamp,
            frame_id: ctx.world_frame.to_string(),
        },
        constraints,
        v_names: ctx.v_names.to_vec(),
        generalized_force: at.generalized_force.to_vec(),
        rank_deficiency: at.rank_deficiency as u32,
    }
}

/// Diagonal 6×6 covariance (row-major) with the given standard deviations.
pub fn diagonal_covariance(stddev: [f64; 6]) -> [f64; 36] {
    let mut c = [0.0; 36];
    for (i, s) in stddev.iter().enumerate() {
        c[i * 7] = s * s;
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yaw_round_trip_and_bad_quaternions() {
        for yaw in [0.0, 0.3, -2.0, 3.1] {
            let q = quaternion_from_yaw(yaw);
            assert!((yaw_of(&q).unwrap() - yaw).abs() < 1e-12);
            let scaled = Quaternion {
                x: 0.0,
                y: 0.0,
                z: 2.0 * q.z,
                w: 2.0 * q.w,
            };
            assert!((yaw_of(&scaled).unwrap() - yaw).abs() < 1e-12);
        }
        let zero = Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 0.0,
        };
        assert!(yaw_of(&zero).unwrap_err().to_string().contains("zero"));
        let nan = Quaternion {
            x: f64::NAN,
            ..Quaternion::default()
        };
        assert!(yaw_of(&nan).unwrap_err().to_string().contains("finite"));
    }

    #[test]
    fn covariance_is_diagonal() {
        let c = diagonal_covariance([1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        assert_eq!(c[0], 1.0);
        assert_eq!(c[7], 4.0);
        assert_eq!(c[35], 36.0);
        assert_eq!(c.iter().filter(|x| **x != 0.0).count(), 6);
        assert_eq!(
            time_plus(Time::from_nanos(1_500_000_000), 0.75).to_nanos(),
            2_250_000_000
        );
    }
}
