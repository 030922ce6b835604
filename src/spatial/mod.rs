//! Spatial algebra (Featherstone, in Pinocchio's conventions) on small fixed-size types.
//!
//! Conventions, stated once:
//! - A spatial motion (twist) is `[linear; angular]`, a spatial force (wrench) `[force; torque]`,
//!   both expressed in some frame and taken about that frame's origin.
//! - `SE3` named `a_m_b` maps coordinates in frame b to frame a: `p_a = R p_b + t`.
//! - `act` moves a quantity from b to a; `act_inv` from a to b.

mod inertia;
mod motion;
mod se3;

pub use inertia::{Inertia, OriginInertia};
pub use motion::{Force, Motion};
pub use se3::{SE3, skew};

use nalgebra::{Matrix3, Vector3};

/// Rotation about unit `axis` by `angle` (Rodrigues).
pub fn rotation_about_axis(axis: &Vector3<f64>, angle: f64) -> Matrix3<f64> {
    let (s, c) = angle.sin_cos();
    let k = skew(axis);
    Matrix3::identity() + k * s + k * k * (1.0 - c)
}

/// Rotation from URDF roll-pitch-yaw: `R = Rz(yaw) Ry(pitch) Rx(roll)`.
pub fn rotation_from_rpy(rpy: &[f64; 3]) -> Matrix3<f64> {
    *nalgebra::Rotation3::from_euler_angles(rpy[0], rpy[1], rpy[2]).matrix()
}
