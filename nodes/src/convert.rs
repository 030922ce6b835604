//! Conversions between the core library's values and ROS messages (pure functions).
//!
//! Conventions (REP-103/105): poses in the odom frame, twists in the base frame, SI units;
//! planar base `q = (x, y, yaw)`, `v = (vx, vy, wz)` (base frame); floating base
//! `q = (x, y, z, qx, qy, qz, qw)`, `v = (v_lin, ω)` (base frame), as the core orders them.

use constraint_dynamics::algorithm::{forward_kinematics_pos, frame_placement};
use constraint_dynamics::constraints::ConstraintForce as CoreForce;
use constraint_dynamics::{BaseType, Model, System};

use crate::msg::builtin_interfaces::Time;
use crate::msg::constraint_dynamics_msgs::{ConstraintForce, ConstraintForces};
use crate::msg::geometry_msgs::{Point, Pose, PoseStamped, Quaternion, Twist, Vector3, Wrench};
use crate::msg::std_msgs::Header;

/// Yaw [rad] of a quaternion (rotation about z of the heading), after normalising it.
/// Errors on a non-finite or zero quaternion.
pub fn yaw_of(q: &Quaternion) -> Result<f64, String> {
    let [x, y, z, w] = unit_quaternion(q)?;
    Ok((2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z)))
}

/// The quaternion normalised, as (x, y, z, w). Errors on non-finite or zero length.
pub fn unit_quaternion(q: &Quaternion) -> Result<[f64; 4], String> {
    let a = [q.x, q.y, q.z, q.w];
    if a.iter().any(|x| !x.is_finite()) {
        return Err(format!("orientation {a:?} is not finite"));
    }
    let n = a.iter().map(|x| x * x).sum::<f64>().sqrt();
    if n < 1e-9 {
        return Err("orientation is a zero quaternion".into());
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

/// The base pose in the world (odom) frame from a configuration.
pub fn base_pose(model: &Model, q: &[f64]) -> Pose {
    match model.base {
        BaseType::Planar => Pose {
            position: Point {
                x: q[0],
                y: q[1],
                z: 0.0,
            },
            orientation: quaternion_from_yaw(q[2]),
        },
        BaseType::Floating => Pose {
            position: Point {
                x: q[0],
                y: q[1],
                z: q[2],
            },
            orientation: Quaternion {
                x: q[3],
                y: q[4],
                z: q[5],
                w: q[6],
            },
        },
        BaseType::Fixed => Pose::default(),
    }
}

/// The base twist in the base frame from a velocity.
pub fn base_twist(model: &Model, v: &[f64]) -> Twist {
    match model.base {
        BaseType::Planar => Twist {
            linear: Vector3 {
                x: v[0],
                y: v[1],
                z: 0.0,
            },
            angular: Vector3 {
                x: 0.0,
                y: 0.0,
                z: v[2],
            },
        },
        BaseType::Floating => Twist {
            linear: Vector3 {
                x: v[0],
                y: v[1],
                z: v[2],
            },
            angular: Vector3 {
                x: v[3],
                y: v[4],
                z: v[5],
            },
        },
        BaseType::Fixed => Twist::default(),
    }
}

/// A time `dt` seconds after `t`.
pub fn time_plus(t: Time, dt: f64) -> Time {
    Time::from_nanos(t.to_nanos().saturating_add((dt * 1e9).round() as i64))
}

/// Poses of a trajectory for `nav_msgs/Path`: the base pose at each `(t, q)`, stamped
/// `start + t`, in `frame_id`.
pub fn path_poses<'a>(
    model: &Model,
    samples: impl Iterator<Item = (f64, &'a [f64])>,
    start: Time,
    frame_id: &str,
) -> Vec<PoseStamped> {
    samples
        .map(|(t, q)| PoseStamped {
            header: Header {
                stamp: time_plus(start, t),
                frame_id: frame_id.to_string(),
            },
            pose: base_pose(model, q),
        })
        .collect()
}

/// How slip is judged (see [`crate::params::SlipParams`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlipRule {
    /// μ [-].
    pub mu: f64,
    /// Normal force used when the model has none (planar base) [N].
    pub fallback_normal: f64,
}

impl SlipRule {
    /// From the parameters and the model: `planar_normal_force`, or m·|g| / n_rolling.
    pub fn new(params: &crate::params::SlipParams, model: &Model, n_rolling: usize) -> Self {
        let fallback_normal = if params.planar_normal_force > 0.0 {
            params.planar_normal_force
        } else {
            model.total_mass() * model.gravity.norm() / n_rolling.max(1) as f64
        };
        SlipRule {
            mu: params.friction_coefficient,
            fallback_normal,
        }
    }

    /// (normal force used, tangential force, slipping) of a rolling contact.
    pub fn judge(&self, f: &CoreForce) -> Option<(f64, f64, bool)> {
        if f.kind != "rolling" {
            return None;
        }
        let tangential = f.tangential_force.unwrap_or(0.0);
        let normal = match f.normal_force {
            Some(n) if n.is_finite() => n,
            _ => self.fallback_normal,
        };
        Some((normal, tangential, tangential > self.mu * normal))
    }
}

/// The wrench of a core constraint force moved from its point of application to the origin of
/// its frame: τ_o = τ_p + (p − o) × f. `origin` is the frame origin in world coordinates.
pub fn wrench_at(f: &CoreForce, origin: Option<[f64; 3]>) -> Wrench {
    let mut torque = f.torque;
    if let Some(o) = origin {
        let r = [
            f.point_world[0] - o[0],
            f.point_world[1] - o[1],
            f.point_world[2] - o[2],
        ];
        let c = cross(r, f.force);
        for k in 0..3 {
            torque[k] += c[k];
        }
    }
    Wrench {
        force: v3(f.force),
        torque: v3(torque),
    }
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn v3(a: [f64; 3]) -> Vector3 {
    Vector3 {
        x: a[0],
        y: a[1],
        z: a[2],
    }
}

/// World positions of the frame origins named by `forces` at configuration `q` (None for names
/// that are not frames, e.g. couplings). Runs a position kinematics pass on `sys.data`.
pub fn frame_origins(sys: &mut System, q: &[f64], forces: &[CoreForce]) -> Vec<Option<[f64; 3]>> {
    forward_kinematics_pos(&sys.model, &mut sys.data, q);
    forces
        .iter()
        .map(|f| {
            sys.model.frame_id(&f.frame).ok().map(|id| {
                let t = frame_placement(&sys.model, &sys.data, id).translation;
                [t.x, t.y, t.z]
            })
        })
        .collect()
}

/// Everything a `ConstraintForces` message needs besides the forces.
pub struct ForcesContext<'a> {
    pub stamp: Time,
    /// The fixed frame that replaces the core's "world".
    pub world_frame: &'a str,
    pub v_names: &'a [String],
    /// Jᵀλ (nv) [N or N·m].
    pub generalized_force: &'a [f64],
    pub rank_deficiency: usize,
    pub slip: SlipRule,
}

/// A `ConstraintForces` message from core forces and their frame origins
/// (see [`frame_origins`]).
pub fn constraint_forces_msg(
    forces: &[CoreForce],
    origins: &[Option<[f64; 3]>],
    ctx: &ForcesContext,
) -> ConstraintForces {
    let world = |s: &str| {
        if s == "world" {
            ctx.world_frame.to_string()
        } else {
            s.to_string()
        }
    };
    let constraints = forces
        .iter()
        .enumerate()
        .map(|(k, f)| {
            let (normal_force, tangential_force, slipping) = match ctx.slip.judge(f) {
                Some((n, t, s)) => (n, t, s),
                None => (0.0, 0.0, false),
            };
            ConstraintForce {
                name: f.name.clone(),
                kind: f.kind.to_string(),
                frame_id: world(&f.frame),
                axes_frame_id: world(&f.axes),
                wrench: wrench_at(f, origins.get(k).copied().flatten()),
                multipliers: f.lambda.clone(),
                row_names: f.rows.clone(),
                position_residual: f.position_residual.clone(),
                velocity_residual: f.velocity_residual.clone(),
                normal_force,
                tangential_force,
                slipping,
            }
        })
        .collect();
    ConstraintForces {
        header: Header {
            stamp: ctx.stamp,
            frame_id: ctx.world_frame.to_string(),
        },
        constraints,
        v_names: ctx.v_names.to_vec(),
        generalized_force: ctx.generalized_force.to_vec(),
        rank_deficiency: ctx.rank_deficiency as u32,
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
        assert!(yaw_of(&zero).unwrap_err().contains("zero"));
        let nan = Quaternion {
            x: f64::NAN,
            ..Quaternion::default()
        };
        assert!(yaw_of(&nan).unwrap_err().contains("finite"));
    }

    #[test]
    fn wrench_moves_to_the_frame_origin() {
        let f = CoreForce {
            name: "c".into(),
            kind: "rolling",
            frame: "wheel".into(),
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
        };
        // Contact 0.05 m below the wheel centre: τ = (0, 0, −0.05) × (2, 0, 10) = (0, −0.1, 0).
        let w = wrench_at(&f, Some([0.0, 0.0, 0.05]));
        assert_eq!(
            (w.torque.x, w.torque.y, w.torque.z),
            (0.0, -0.1, 0.0),
            "{w:?}"
        );
        let rule = SlipRule {
            mu: 0.1,
            fallback_normal: 1.0,
        };
        assert_eq!(rule.judge(&f), Some((10.0, 2.0, true)));
        let rule = SlipRule { mu: 0.5, ..rule };
        assert_eq!(rule.judge(&f), Some((10.0, 2.0, false)));
        let planar = CoreForce {
            normal_force: Some(f64::NAN),
            ..f
        };
        assert_eq!(rule.judge(&planar), Some((1.0, 2.0, true)));
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
