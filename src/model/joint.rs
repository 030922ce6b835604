//! Joint kinds: their configuration space (nq), tangent space (nv), transform, motion subspace and
//! integration on their Lie group.
//!
//! Every joint's motion subspace S is constant in the joint's child frame, so the joint velocity
//! twist is `S q̇` and its bias acceleration `c_J` is zero (free-flyer and planar velocities are
//! expressed in the child frame, as a ROS odometry twist is in `child_frame_id`).

use crate::spatial::{Motion, SE3};
use nalgebra::{Matrix3, Quaternion, UnitQuaternion, Vector3};

/// Sine and cosine of a joint angle [rad]: the `libm` crate's `sincos` (musl's), within 1 ulp
/// of the standard library's (glibc's) and faster — 13.3 against 17.7 ns a call on this
/// machine; every kinematics pass calls it once per revolute joint and the planar base.
#[inline(always)]
pub(crate) fn sin_cos(angle: f64) -> (f64, f64) {
    libm::sincos(angle)
}

/// (sin w / w, (1 − cos w) / w), the SE(2) exponential's coefficients for a turn of w [rad].
/// Below |w| = 0.1 (every step of a rolling base) by their series to w⁸ and w⁹, whose first
/// terms left out are under 3e-18 relative there: the same numbers to rounding, without the
/// trigonometric call and the divisions.
#[inline(always)]
fn se2_coefficients(w: f64) -> (f64, f64) {
    if w.abs() < 0.1 {
        let x = w * w;
        let a = 1.0 + x * (-1.0 / 6.0 + x * (1.0 / 120.0 + x * (-1.0 / 5040.0 + x / 362_880.0)));
        let b = w
            * (0.5
                + x * (-1.0 / 24.0 + x * (1.0 / 720.0 + x * (-1.0 / 40_320.0 + x / 3_628_800.0))));
        (a, b)
    } else {
        let (sw, cw) = sin_cos(w);
        (sw / w, (1.0 - cw) / w)
    }
}

/// Kind of a movable joint.
#[derive(Clone, Debug, PartialEq)]
pub enum JointKind {
    /// Rotation about a unit axis of the joint frame; q [rad], v [rad/s]. `skew` = [a]× and
    /// `skew2` = [a]×² are kept so the rotation `1 + sin q [a]× + (1 − cos q) [a]×²` costs no
    /// matrix product; `aligned` marks an axis along ±x, ±y or ±z (sparse rotation).
    Revolute {
        /// Unit rotation axis a, joint frame.
        axis: Vector3<f64>,
        /// [a]×, the cross-product matrix of `axis`.
        skew: Matrix3<f64>,
        /// [a]×², the square of `skew`.
        skew2: Matrix3<f64>,
        /// `Some((i, ±1))` when `axis` is ±e_i (x, y or z), else `None`.
        aligned: Option<(usize, f64)>,
    },
    /// Translation along a unit axis of the joint frame; q [m], v [m/s].
    Prismatic {
        /// Unit translation axis, joint frame.
        axis: Vector3<f64>,
    },
    /// Free-flyer: q = [x, y, z, qx, qy, qz, qw] (child pose in the parent frame, unit quaternion),
    /// v = [v_lin; ω] of the child, both in the child frame.
    FreeFlyer,
    /// Planar in the joint frame's x-y plane: q = [x, y, yaw], v = [vx, vy, ωz] in the child frame.
    Planar,
}

impl JointKind {
    /// A revolute joint about the unit `axis`.
    pub fn revolute(axis: Vector3<f64>) -> Self {
        let skew = crate::spatial::skew(&axis);
        let aligned = (0..3)
            .find(|&i| (axis[i].abs() - 1.0).abs() < 1e-15)
            .map(|i| (i, axis[i].signum()));
        JointKind::Revolute {
            axis,
            skew,
            skew2: skew * skew,
            aligned,
        }
    }

    /// Number of configuration coordinates.
    pub fn nq(&self) -> usize {
        match self {
            JointKind::Revolute { .. } | JointKind::Prismatic { .. } => 1,
            JointKind::FreeFlyer => 7,
            JointKind::Planar => 3,
        }
    }

    /// Number of velocity coordinates.
    pub fn nv(&self) -> usize {
        match self {
            JointKind::Revolute { .. } | JointKind::Prismatic { .. } => 1,
            JointKind::FreeFlyer => 6,
            JointKind::Planar => 3,
        }
    }

    /// Columns of the motion subspace S (in the child frame), `nv` of them.
    pub fn motion_subspace(&self) -> [Motion; 6] {
        let z = Vector3::zeros();
        let e = |i: usize| Vector3::ith(i, 1.0);
        let mut s = [Motion::zero(); 6];
        match self {
            JointKind::Revolute { axis, .. } => s[0] = Motion::new(z, *axis),
            JointKind::Prismatic { axis } => s[0] = Motion::new(*axis, z),
            JointKind::FreeFlyer => {
                for i in 0..3 {
                    s[i] = Motion::new(e(i), z);
                    s[i + 3] = Motion::new(z, e(i));
                }
            }
            JointKind::Planar => {
                s[0] = Motion::new(e(0), z);
                s[1] = Motion::new(e(1), z);
                s[2] = Motion::new(z, e(2));
            }
        }
        s
    }

    /// Transform `joint_frame_m_child` at configuration `q` (slice of length nq).
    #[inline]
    pub fn transform(&self, q: &[f64]) -> SE3 {
        match self {
            JointKind::Revolute {
                skew,
                skew2,
                aligned,
                ..
            } => {
                let (sn, cs) = sin_cos(q[0]);
                let r = match aligned {
                    Some((i, sign)) => axis_rotation(*i, sign * sn, cs),
                    None => Matrix3::identity() + skew * sn + skew2 * (1.0 - cs),
                };
                SE3::new(r, Vector3::zeros())
            }
            JointKind::Prismatic { axis } => SE3::new(Matrix3::identity(), axis * q[0]),
            JointKind::FreeFlyer => free_flyer_transform(q),
            JointKind::Planar => planar_transform(q),
        }
    }

    /// `placement ∘ transform(q)`: the body's pose in its parent's frame at q. For a revolute
    /// joint about a frame axis this mixes two columns of the placement's rotation (12 products)
    /// instead of a 3×3 product (27) and a translation update; every kinematics pass does it
    /// once per body. Always inlined: as a hint, thin LTO keeps it out of line in some binaries
    /// and not others (the dynamics bench calls it, an example inlines it), and panda's CRBA,
    /// whose joints all take this path, takes 440 ns out of line against 350 ns inlined.
    #[inline(always)]
    pub fn placed(&self, placement: &SE3, q: &[f64]) -> SE3 {
        if let JointKind::Revolute {
            aligned: Some((i, sign)),
            ..
        } = self
        {
            let (sn, cs) = sin_cos(q[0]);
            let r = turned(&placement.rotation, *i, sign * sn, cs);
            return SE3::new(r, placement.translation);
        }
        placement.compose(&self.transform(q))
    }

    /// Neutral configuration (zero, identity quaternion).
    pub fn neutral(&self, q: &mut [f64]) {
        q.iter_mut().for_each(|x| *x = 0.0);
        if let JointKind::FreeFlyer = self {
            q[6] = 1.0;
        }
    }

    /// `q_out = q ⊕ v·dt` on the joint's Lie group (SE(3) exponential for a free-flyer, SE(2)
    /// for planar); the quaternion is renormalised.
    pub fn integrate(&self, q: &[f64], v: &[f64], dt: f64, q_out: &mut [f64]) {
        match self {
            JointKind::Revolute { .. } | JointKind::Prismatic { .. } => q_out[0] = q[0] + v[0] * dt,
            JointKind::FreeFlyer => {
                let m0 = self.transform(q);
                let nu = Motion::new(
                    Vector3::new(v[0], v[1], v[2]) * dt,
                    Vector3::new(v[3], v[4], v[5]) * dt,
                );
                let m1 = m0.compose(&SE3::exp(&nu));
                write_free_flyer(&m1, q_out);
            }
            JointKind::Planar => {
                let (vx, vy, w) = (v[0] * dt, v[1] * dt, v[2] * dt);
                // SE(2) exponential of (vx, vy, w) in the body frame.
                let (a, b) = se2_coefficients(w);
                let dx = a * vx - b * vy;
                let dy = b * vx + a * vy;
                let (s, c) = sin_cos(q[2]);
                q_out[0] = q[0] + c * dx - s * dy;
                q_out[1] = q[1] + s * dx + c * dy;
                q_out[2] = q[2] + w;
            }
        }
    }

    /// `v_out = (q1 ⊖ q0)`: the constant velocity that takes q0 to q1 in unit time.
    pub fn difference(&self, q0: &[f64], q1: &[f64], v_out: &mut [f64]) {
        match self {
            JointKind::Revolute { .. } | JointKind::Prismatic { .. } => v_out[0] = q1[0] - q0[0],
            JointKind::FreeFlyer => {
                let d = self
                    .transform(q0)
                    .inverse()
                    .compose(&self.transform(q1))
                    .log();
                v_out[..3].copy_from_slice(d.lin.as_slice());
                v_out[3..6].copy_from_slice(d.ang.as_slice());
            }
            JointKind::Planar => {
                let w = q1[2] - q0[2];
                let (s, c) = sin_cos(q0[2]);
                let (gx, gy) = (q1[0] - q0[0], q1[1] - q0[1]);
                let (dx, dy) = (c * gx + s * gy, -s * gx + c * gy);
                let (a, b) = se2_coefficients(w);
                let det = a * a + b * b;
                v_out[0] = (a * dx + b * dy) / det;
                v_out[1] = (-b * dx + a * dy) / det;
                v_out[2] = w;
            }
        }
    }

    /// Renormalise the quaternion of a free-flyer (no-op otherwise).
    pub fn normalize(&self, q: &mut [f64]) {
        if let JointKind::FreeFlyer = self {
            let n = (q[3] * q[3] + q[4] * q[4] + q[5] * q[5] + q[6] * q[6]).sqrt();
            if n > 0.0 {
                q[3..7].iter_mut().for_each(|x| *x /= n);
            }
        }
    }

    /// `q̇ = G(q) v`: the time derivative of this joint's coordinates for velocity `v`.
    pub fn qdot(&self, q: &[f64], v: &[f64], qdot: &mut [f64]) {
        match self {
            JointKind::Revolute { .. } | JointKind::Prismatic { .. } => qdot[0] = v[0],
            JointKind::FreeFlyer => {
                let m = self.transform(q);
                let pdot = m.rotation * Vector3::new(v[0], v[1], v[2]);
                qdot[..3].copy_from_slice(pdot.as_slice());
                // q̇uat = ½ quat ⊗ (ω, 0)
                let quat = Quaternion::new(q[6], q[3], q[4], q[5]);
                let w = Quaternion::new(0.0, v[3], v[4], v[5]);
                let d = quat * w * 0.5;
                qdot[3] = d.i;
                qdot[4] = d.j;
                qdot[5] = d.k;
                qdot[6] = d.w;
            }
            JointKind::Planar => {
                let (s, c) = sin_cos(q[2]);
                qdot[0] = c * v[0] - s * v[1];
                qdot[1] = s * v[0] + c * v[1];
                qdot[2] = v[2];
            }
        }
    }
}

fn write_free_flyer(m: &SE3, q: &mut [f64]) {
    let r = nalgebra::Rotation3::from_matrix_unchecked(m.rotation);
    // Renormalise: rounding in R would otherwise compound from step to step.
    let quat =
        UnitQuaternion::new_normalize(*UnitQuaternion::from_rotation_matrix(&r).quaternion());
    q[0] = m.translation.x;
    q[1] = m.translation.y;
    q[2] = m.translation.z;
    q[3] = quat.i;
    q[4] = quat.j;
    q[5] = quat.k;
    q[6] = quat.w;
}

/// The rotation by θ about frame axis e_i, from (sin θ, cos θ).
#[inline(always)]
pub(crate) fn axis_rotation(i: usize, sn: f64, cs: f64) -> Matrix3<f64> {
    match i {
        0 => axis_rotation_jk::<1, 2>(sn, cs),
        1 => axis_rotation_jk::<2, 0>(sn, cs),
        _ => axis_rotation_jk::<0, 1>(sn, cs),
    }
}

/// [`axis_rotation`] about the axis whose two successors in cyclic order (x → y → z → x) are
/// J and K: constants, so that the entries it sets are fixed offsets (an index looked up per
/// joint and checked against 3 is measurable in every kinematics pass).
#[inline(always)]
fn axis_rotation_jk<const J: usize, const K: usize>(sn: f64, cs: f64) -> Matrix3<f64> {
    let mut r = Matrix3::identity();
    r[(J, J)] = cs;
    r[(K, K)] = cs;
    r[(K, J)] = sn;
    r[(J, K)] = -sn;
    r
}

/// `r · axis_rotation(i, sn, cs)`: the two columns other than i mixed (12 products instead of a
/// 3×3 product's 27; the product's other terms are exact zeros, so the numbers are the same).
#[inline(always)]
pub(crate) fn turned(r: &Matrix3<f64>, i: usize, sn: f64, cs: f64) -> Matrix3<f64> {
    match i {
        0 => turned_jk::<1, 2>(r, sn, cs),
        1 => turned_jk::<2, 0>(r, sn, cs),
        _ => turned_jk::<0, 1>(r, sn, cs),
    }
}

/// [`turned`] with the two mixed columns J and K as constants (see [`axis_rotation_jk`]).
#[inline(always)]
fn turned_jk<const J: usize, const K: usize>(r: &Matrix3<f64>, sn: f64, cs: f64) -> Matrix3<f64> {
    let (pj, pk) = (r.column(J), r.column(K));
    let mut out = *r;
    out.set_column(J, &(pj * cs + pk * sn));
    out.set_column(K, &(pk * cs - pj * sn));
    out
}

// The base joints' transforms, kept out of line: they run once per model and forward pass,
// while the small revolute and prismatic arms of `transform` are inlined into every pass.
#[inline(never)]
fn free_flyer_transform(q: &[f64]) -> SE3 {
    let quat = Quaternion::new(q[6], q[3], q[4], q[5]);
    let r = UnitQuaternion::new_unchecked(quat).to_rotation_matrix();
    SE3::new(*r.matrix(), Vector3::new(q[0], q[1], q[2]))
}

#[inline(never)]
fn planar_transform(q: &[f64]) -> SE3 {
    let (s, c) = sin_cos(q[2]);
    let r = Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0);
    SE3::new(r, Vector3::new(q[0], q[1], 0.0))
}
