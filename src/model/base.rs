//! The base of a state for any base type: its pose in the world (REP-105's odom frame) and its
//! twist in the base frame, the way odometry states them, and back.
//!
//! Coordinates (stated once for the crate, README "Conventions"): a planar base has
//! q = (x, y, yaw), v = (vx, vy, ωz) in the base frame; a floating base has
//! q = (x, y, z, qx, qy, qz, qw), v = (v_lin; ω) in the base frame; a fixed base has none.

use super::{BaseType, Model};
use crate::error::{Error, Result};
use nalgebra::{Quaternion, UnitQuaternion};

/// Variance [m² or rad²] from which an odometry's entry counts as not measured: a planar
/// odometry states z, roll and pitch so (REP-105 practice: 1e3 and more; diff_drive_controller
/// gives 1e6).
pub const UNMEASURED_VARIANCE: f64 = 1e3;

/// Whether a REP-103 6×6 covariance (pose or twist) leaves z, roll and pitch (or their rates)
/// unmeasured: their variances at least [`UNMEASURED_VARIANCE`], as a planar odometry states them.
pub(crate) fn measures_planar_motion_only(covariance: &[f64; 36]) -> bool {
    [14, 21, 28]
        .iter()
        .all(|&i| covariance[i] >= UNMEASURED_VARIANCE)
}

/// Pose of the base in the world frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BasePose {
    /// Position [m], world axes.
    pub position: [f64; 3],
    /// Orientation base → world as a unit quaternion (x, y, z, w).
    pub orientation_xyzw: [f64; 4],
}

/// Twist of the base in the base frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BaseTwist {
    /// Linear velocity [m/s], base axes.
    pub linear: [f64; 3],
    /// Angular velocity [rad/s], base axes.
    pub angular: [f64; 3],
}

/// Components of a twist below this are taken as zero when a base cannot follow them
/// [m/s or rad/s].
pub const TWIST_TOLERANCE: f64 = 1e-9;

impl BaseType {
    /// Number of base configuration coordinates (0, 3 or 7), which come first in q.
    pub const fn nq(self) -> usize {
        match self {
            BaseType::Fixed => 0,
            BaseType::Planar => 3,
            BaseType::Floating => 7,
        }
    }

    /// Number of base velocity coordinates (0, 3 or 6), which come first in v.
    pub const fn nv(self) -> usize {
        match self {
            BaseType::Fixed => 0,
            BaseType::Planar => 3,
            BaseType::Floating => 6,
        }
    }
}

impl Model {
    /// The base pose at configuration `q` (identity for a fixed base).
    pub fn base_pose(&self, q: &[f64]) -> BasePose {
        match self.base {
            BaseType::Planar => BasePose {
                position: [q[0], q[1], 0.0],
                orientation_xyzw: [0.0, 0.0, (0.5 * q[2]).sin(), (0.5 * q[2]).cos()],
            },
            BaseType::Floating => BasePose {
                position: [q[0], q[1], q[2]],
                orientation_xyzw: [q[3], q[4], q[5], q[6]],
            },
            BaseType::Fixed => BasePose {
                position: [0.0; 3],
                orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
            },
        }
    }

    /// The base twist at velocity `v` (zero for a fixed base).
    pub fn base_twist(&self, v: &[f64]) -> BaseTwist {
        match self.base {
            BaseType::Planar => BaseTwist {
                linear: [v[0], v[1], 0.0],
                angular: [0.0, 0.0, v[2]],
            },
            BaseType::Floating => BaseTwist {
                linear: [v[0], v[1], v[2]],
                angular: [v[3], v[4], v[5]],
            },
            BaseType::Fixed => BaseTwist::default(),
        }
    }

    /// On a floating base under a planar odometry (its z, roll and pitch variances at least
    /// [`UNMEASURED_VARIANCE`]), the height, roll and pitch the odometry does not measure are
    /// `rest`'s (the scene's initial state: a robot at rest on its supports), under the heading
    /// `q` has; otherwise `q` stays as it is. REP-103 covariance over (x, y, z, roll, pitch, yaw).
    pub fn keep_unmeasured_tilt(&self, pose_covariance: &[f64; 36], rest: &[f64], q: &mut [f64]) {
        if self.base != BaseType::Floating || !measures_planar_motion_only(pose_covariance) {
            return;
        }
        let quat =
            |x: &[f64]| UnitQuaternion::from_quaternion(Quaternion::new(x[6], x[3], x[4], x[5]));
        let (roll, pitch, _) = quat(rest).euler_angles();
        let (_, _, yaw) = quat(q).euler_angles();
        let r = UnitQuaternion::from_euler_angles(roll, pitch, yaw);
        q[2] = rest[2];
        q[3..7].copy_from_slice(&[r.i, r.j, r.k, r.w]);
    }

    /// Writes a base pose and twist into `q` and `v` (the inverse of [`Model::base_pose`] and
    /// [`Model::base_twist`]): a planar base takes x, y, the heading (yaw) of the orientation and
    /// vx, vy, ωz; a floating base all of them; a fixed base nothing. The quaternion must be
    /// unit (callers normalise it).
    pub fn set_base(&self, pose: &BasePose, twist: &BaseTwist, q: &mut [f64], v: &mut [f64]) {
        let (p, t) = (pose.position, twist);
        match self.base {
            BaseType::Fixed => {}
            BaseType::Planar => {
                let [x, y, z, w] = pose.orientation_xyzw;
                let yaw = (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z));
                q[..3].copy_from_slice(&[p[0], p[1], yaw]);
                v[..3].copy_from_slice(&[t.linear[0], t.linear[1], t.angular[2]]);
            }
            BaseType::Floating => {
                q[..3].copy_from_slice(&p);
                q[3..7].copy_from_slice(&pose.orientation_xyzw);
                v[..3].copy_from_slice(&t.linear);
                v[3..6].copy_from_slice(&t.angular);
            }
        }
    }

    /// The base's velocity coordinates (the first `base.nv()` entries of v) for a twist, refusing
    /// components the base cannot follow (a planar base: linear z, roll and pitch rates).
    pub fn base_velocity(&self, t: &BaseTwist) -> Result<Vec<f64>> {
        let all = [t.linear, t.angular].concat();
        if let Some(x) = all.iter().find(|x| !x.is_finite()) {
            return Err(Error::Invalid(format!(
                "base twist value is not finite ({x})"
            )));
        }
        match self.base {
            BaseType::Planar => {
                let off = [t.linear[2], t.angular[0], t.angular[1]];
                if off.iter().any(|x| x.abs() > TWIST_TOLERANCE) {
                    return Err(Error::Invalid(format!(
                        "a planar base cannot move along z or roll/pitch \
                         (linear.z, angular.x, angular.y = {}, {}, {})",
                        off[0], off[1], off[2]
                    )));
                }
                Ok(vec![t.linear[0], t.linear[1], t.angular[2]])
            }
            BaseType::Floating => Ok(all),
            BaseType::Fixed => Err(Error::Invalid(
                "the model has a fixed base: it cannot follow a base twist".into(),
            )),
        }
    }
}

impl BaseTwist {
    /// The (v, ω) a differential drive follows — linear.x [m/s] and angular.z [rad/s] — refusing
    /// a twist with other components (lateral, vertical, roll, pitch) above the tolerance.
    pub fn unicycle(&self) -> Result<[f64; 2]> {
        let all = [self.linear, self.angular].concat();
        if let Some(x) = all.iter().find(|x| !x.is_finite()) {
            return Err(Error::Invalid(format!(
                "twist has a non-finite value ({x})"
            )));
        }
        let lateral = [
            self.linear[1],
            self.linear[2],
            self.angular[0],
            self.angular[1],
        ];
        if lateral.iter().any(|x| x.abs() > TWIST_TOLERANCE) {
            return Err(Error::Invalid(format!(
                "a differential drive follows linear.x and angular.z only \
                 (linear.y, linear.z, angular.x, angular.y = {lateral:?})"
            )));
        }
        Ok([self.linear[0], self.angular[2]])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ModelOptions;

    fn model(base: BaseType) -> Model {
        let urdf = r#"<robot name="r"><link name="b"><inertial><mass value="2"/>
            <inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link></robot>"#;
        let opts = ModelOptions {
            base,
            ..Default::default()
        };
        Model::from_urdf_str(urdf, "test.urdf", &opts).unwrap()
    }

    #[test]
    fn planar_pose_is_a_yaw_quaternion_and_twist_round_trips() {
        let m = model(BaseType::Planar);
        let p = m.base_pose(&[1.0, 2.0, std::f64::consts::FRAC_PI_2]);
        let h = std::f64::consts::FRAC_1_SQRT_2;
        assert_eq!(p.position, [1.0, 2.0, 0.0]);
        for (a, b) in p.orientation_xyzw.iter().zip([0.0, 0.0, h, h]) {
            // sin(π/4) and 1/√2 agree to one ulp (1.1e-16).
            assert!((a - b).abs() <= 1.2e-16, "{a} vs {b}");
        }
        let t = m.base_twist(&[0.5, -0.1, 0.3]);
        assert_eq!(m.base_velocity(&t).unwrap(), vec![0.5, -0.1, 0.3]);
        let (mut q, mut v) = ([0.0; 3], [0.0; 3]);
        m.set_base(&p, &t, &mut q, &mut v);
        assert!((q[2] - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
        assert_eq!(v, [0.5, -0.1, 0.3]);
        let mut up = t;
        up.linear[2] = 0.1;
        assert!(
            m.base_velocity(&up)
                .unwrap_err()
                .to_string()
                .contains("linear.z")
        );
    }

    /// A floating base resting pitched 6.3 mrad, 0.96 mm low; a planar odometry at yaw 1.2 rad:
    /// the state keeps the height and the tilt and turns to the odometry's heading (read back
    /// from the rotation matrix: R₂₀ = −sin pitch, atan2(R₁₀, R₀₀) = yaw). A full odometry, or a
    /// planar base, is left alone.
    #[test]
    fn a_planar_odometry_keeps_a_floating_base_height_roll_and_pitch() {
        let m = model(BaseType::Floating);
        let rest = UnitQuaternion::from_euler_angles(0.0, 0.0063, 0.0);
        let q0 = [0.0, 0.0, -0.00096, rest.i, rest.j, rest.k, rest.w];
        let heading = UnitQuaternion::from_euler_angles(0.0, 0.0, 1.2);
        let odom = [2.0, 3.0, 0.0, heading.i, heading.j, heading.k, heading.w];
        let mut cov = [0.0; 36];
        let mut q = odom;
        m.keep_unmeasured_tilt(&cov, &q0, &mut q);
        assert_eq!(q, odom, "a full odometry measures the tilt");
        for i in [14, 21, 28] {
            cov[i] = 1e6;
        }
        m.keep_unmeasured_tilt(&cov, &q0, &mut q);
        let r = UnitQuaternion::from_quaternion(Quaternion::new(q[6], q[3], q[4], q[5]))
            .to_rotation_matrix();
        let r = r.matrix();
        assert_eq!(&q[..3], &[2.0, 3.0, -0.00096]);
        assert!((-r[(2, 0)] - 0.0063_f64.sin()).abs() < 1e-15);
        assert!((r[(1, 0)].atan2(r[(0, 0)]) - 1.2).abs() < 1e-15);
        assert!(r[(2, 1)].abs() < 1e-15, "no roll");
        let planar = model(BaseType::Planar);
        let mut p = [2.0, 3.0, 1.2];
        planar.keep_unmeasured_tilt(&cov, &[0.0; 3], &mut p);
        assert_eq!(p, [2.0, 3.0, 1.2]);
    }

    #[test]
    fn floating_and_fixed_bases() {
        let m = model(BaseType::Floating);
        let q = [1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0];
        assert_eq!(m.base_pose(&q).position, [1.0, 2.0, 3.0]);
        let v = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
        assert_eq!(m.base_velocity(&m.base_twist(&v)).unwrap(), v.to_vec());
        let f = model(BaseType::Fixed);
        assert_eq!(f.base_twist(&[]), BaseTwist::default());
        assert!(f.base_velocity(&BaseTwist::default()).is_err());
    }

    #[test]
    fn unicycle_refuses_what_a_diff_drive_cannot_do() {
        let t = BaseTwist {
            linear: [0.5, 0.0, 0.0],
            angular: [0.0, 0.0, 0.2],
        };
        assert_eq!(t.unicycle().unwrap(), [0.5, 0.2]);
        let side = BaseTwist {
            linear: [0.5, 0.1, 0.0],
            ..t
        };
        assert!(
            side.unicycle()
                .unwrap_err()
                .to_string()
                .contains("linear.x and angular.z")
        );
        let nan = BaseTwist {
            linear: [f64::NAN, 0.0, 0.0],
            ..t
        };
        assert!(
            nan.unicycle()
                .unwrap_err()
                .to_string()
                .contains("non-finite")
        );
    }
}
