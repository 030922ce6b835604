//! Spatial motion (twist) and force (wrench) vectors with the two cross products.

use nalgebra::{Vector3, Vector6};
use std::ops::{Add, AddAssign, Mul, Neg, Sub, SubAssign};

/// A spatial motion `[v; ω]`: linear velocity of the frame origin [m/s] and angular velocity [rad/s]
/// (or the corresponding accelerations).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Motion {
    /// Linear part v [m/s] (or [m/s²]) of the frame origin.
    pub lin: Vector3<f64>,
    /// Angular part ω [rad/s] (or [rad/s²]).
    pub ang: Vector3<f64>,
}

/// A spatial force `[f; τ]`: force [N] and torque about the frame origin [N·m].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Force {
    /// Force f [N].
    pub lin: Vector3<f64>,
    /// Torque τ about the frame origin [N·m].
    pub ang: Vector3<f64>,
}

impl Motion {
    /// The zero motion.
    pub const fn zero() -> Self {
        Self {
            lin: Vector3::new(0.0, 0.0, 0.0),
            ang: Vector3::new(0.0, 0.0, 0.0),
        }
    }
    /// A motion from its linear and angular parts.
    pub fn new(lin: Vector3<f64>, ang: Vector3<f64>) -> Self {
        Self { lin, ang }
    }
    /// From a 6-vector `[lin; ang]`.
    pub fn from_vector(v: &Vector6<f64>) -> Self {
        Self {
            lin: v.fixed_rows::<3>(0).into(),
            ang: v.fixed_rows::<3>(3).into(),
        }
    }
    /// As a 6-vector `[lin; ang]`.
    pub fn to_vector(&self) -> Vector6<f64> {
        Vector6::new(
            self.lin.x, self.lin.y, self.lin.z, self.ang.x, self.ang.y, self.ang.z,
        )
    }
    /// Motion cross product `self × m` (the derivative of `m` in a frame moving with `self`).
    #[inline]
    pub fn cross_motion(&self, m: &Motion) -> Motion {
        Motion {
            lin: self.ang.cross(&m.lin) + self.lin.cross(&m.ang),
            ang: self.ang.cross(&m.ang),
        }
    }
    /// Force cross product `self ×* f`.
    #[inline]
    pub fn cross_force(&self, f: &Force) -> Force {
        Force {
            lin: self.ang.cross(&f.lin),
            ang: self.ang.cross(&f.ang) + self.lin.cross(&f.lin),
        }
    }
    /// Power `f · m` [W].
    #[inline]
    pub fn dot(&self, f: &Force) -> f64 {
        self.lin.dot(&f.lin) + self.ang.dot(&f.ang)
    }
}

impl Force {
    /// The zero force.
    pub const fn zero() -> Self {
        Self {
            lin: Vector3::new(0.0, 0.0, 0.0),
            ang: Vector3::new(0.0, 0.0, 0.0),
        }
    }
    /// A force from its linear (force) and angular (torque) parts.
    pub fn new(lin: Vector3<f64>, ang: Vector3<f64>) -> Self {
        Self { lin, ang }
    }
    /// From a 6-vector `[f; τ]`.
    pub fn from_vector(v: &Vector6<f64>) -> Self {
        Self {
            lin: v.fixed_rows::<3>(0).into(),
            ang: v.fixed_rows::<3>(3).into(),
        }
    }
    /// As a 6-vector `[f; τ]`.
    pub fn to_vector(&self) -> Vector6<f64> {
        Vector6::new(
            self.lin.x, self.lin.y, self.lin.z, self.ang.x, self.ang.y, self.ang.z,
        )
    }
}

macro_rules! vector_ops {
    ($t:ident) => {
        impl Add for $t {
            type Output = $t;
            #[inline]
            fn add(self, o: $t) -> $t {
                $t {
                    lin: self.lin + o.lin,
                    ang: self.ang + o.ang,
                }
            }
        }
        impl Sub for $t {
            type Output = $t;
            #[inline]
            fn sub(self, o: $t) -> $t {
                $t {
                    lin: self.lin - o.lin,
                    ang: self.ang - o.ang,
                }
            }
        }
        impl AddAssign for $t {
            #[inline]
            fn add_assign(&mut self, o: $t) {
                self.lin += o.lin;
                self.ang += o.ang;
            }
        }
        impl SubAssign for $t {
            #[inline]
            fn sub_assign(&mut self, o: $t) {
                self.lin -= o.lin;
                self.ang -= o.ang;
            }
        }
        impl Mul<f64> for $t {
            type Output = $t;
            #[inline]
            fn mul(self, s: f64) -> $t {
                $t {
                    lin: self.lin * s,
                    ang: self.ang * s,
                }
            }
        }
        impl Neg for $t {
            type Output = $t;
            #[inline]
            fn neg(self) -> $t {
                $t {
                    lin: -self.lin,
                    ang: -self.ang,
                }
            }
        }
    };
}
vector_ops!(Motion);
vector_ops!(Force);
