//! Covariances of the base between the world-frame convention of odometry and the core's
//! tangent space (pure functions).
//!
//! The core propagates P over x = [δq; δv] (2nv × 2nv, velocity order), δq a **right**
//! perturbation q ⊕ δq: for the base, δq is expressed in the **base** frame
//! (`predict/covariance/`, `predict/integrators/lie.rs`). Odometry (REP-103, REP-105,
//! `nav_msgs/Odometry`) states it differently:
//! - the pose covariance is over (x, y, z, rotation about X, Y, Z) of the **world (odom)** frame,
//!   a row-major 6×6 — a small displacement of the position and a small rotation about the
//!   fixed world axes;
//! - the twist covariance is over (vx, vy, vz, ωx, ωy, ωz) in the **base** frame.
//!
//! To first order a right perturbation (ρ, φ) of the base pose (p, R) moves it to
//! (p + R ρ, R Exp(φ)) = (p + R ρ, Exp(R φ) R): the world-frame displacement is R ρ and the
//! world-frame rotation R φ. So with G = diag(Rᵀ, Rᵀ) (planar: diag(R₂ᵀ, 1) over x, y, yaw),
//! `P_qq(base) = G Σ_pose Gᵀ` on the way in and `Σ_pose = Gᵀ P_qq(base) G` on the way out.
//! The twist is in the base frame on both sides and the core's v is too: copied as is.
//! A planar base uses the x, y, yaw and vx, vy, ωz entries; a floating base all six.

use super::base::measures_planar_motion_only;
use super::{BaseType, Model};
use crate::error::Result;
use crate::predict::UncertaintySpec;
use crate::predict::noise_variances;
use nalgebra::{DMatrix, Matrix3, Quaternion, UnitQuaternion};

/// Indices of the planar base's (x, y, yaw) in a REP-103 6×6 covariance.
pub const PLANAR: [usize; 3] = [0, 1, 5];

/// The odom-frame → base-frame rotation block G of the base's configuration coordinates at q
/// (nb × nb, nb = 3 planar / 6 floating / 0 fixed): a world displacement d is the right
/// perturbation G d.
pub fn world_to_body(model: &Model, q: &[f64]) -> DMatrix<f64> {
    match model.base {
        BaseType::Fixed => DMatrix::zeros(0, 0),
        BaseType::Planar => {
            let (s, c) = q[2].sin_cos();
            DMatrix::from_row_slice(3, 3, &[c, s, 0.0, -s, c, 0.0, 0.0, 0.0, 1.0])
        }
        BaseType::Floating => {
            let quat = UnitQuaternion::from_quaternion(Quaternion::new(q[6], q[3], q[4], q[5]));
            let rt: Matrix3<f64> = quat.to_rotation_matrix().into_inner().transpose();
            let mut g = DMatrix::zeros(6, 6);
            g.view_mut((0, 0), (3, 3)).copy_from(&rt);
            g.view_mut((3, 3), (3, 3)).copy_from(&rt);
            g
        }
    }
}

/// The REP-103 indices (of x, y, z, rx, ry, rz) the base's coordinates use.
pub fn rep103_indices(base: BaseType) -> &'static [usize] {
    match base {
        BaseType::Fixed => &[],
        BaseType::Planar => &PLANAR,
        BaseType::Floating => &[0, 1, 2, 3, 4, 5],
    }
}

/// The block of a row-major 6×6 covariance over `idx`, symmetrised (ROS publishers round
/// differently above and below the diagonal) and with negative eigenvalues clipped to 0 (a
/// covariance that is not positive semidefinite would grow negative variances).
pub fn covariance_block(c: &[f64; 36], idx: &[usize]) -> DMatrix<f64> {
    let n = idx.len();
    let m = DMatrix::from_fn(n, n, |i, j| {
        0.5 * (c[6 * idx[i] + idx[j]] + c[6 * idx[j] + idx[i]])
    });
    if n == 0 {
        return m;
    }
    let eig = m.clone().symmetric_eigen();
    if eig.eigenvalues.iter().all(|&l| l >= 0.0) {
        return m;
    }
    let d = DMatrix::from_diagonal(&eig.eigenvalues.map(|l| l.max(0.0)));
    &eig.eigenvectors * d * eig.eigenvectors.transpose()
}

/// Joint-state noise of one 1-DOF joint: standard deviations of its position [rad or m] and
/// velocity [rad/s or m/s].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct JointSigma {
    /// σ of the position [rad or m].
    pub position: f64,
    /// σ of the velocity [rad/s or m/s].
    pub velocity: f64,
}

/// The start covariance in the core's tangent space (2nv × 2nv, [δq; δv]) at configuration q:
/// the odometry's pose covariance (odom frame) turned into the base's right perturbation, its
/// twist covariance (base frame) as is, and `joints` (v index, σ) on the diagonal. Pose and
/// twist are independent (`nav_msgs/Odometry` has no cross term).
pub fn start_covariance(
    model: &Model,
    q: &[f64],
    pose: &[f64; 36],
    twist: &[f64; 36],
    joints: &[(usize, JointSigma)],
) -> DMatrix<f64> {
    let nv = model.nv;
    let mut p = DMatrix::zeros(2 * nv, 2 * nv);
    let idx = rep103_indices(model.base);
    let nb = idx.len();
    if nb > 0 {
        let (pose, twist) = (
            &without_unmeasured(model, pose),
            &without_unmeasured(model, twist),
        );
        let g = world_to_body(model, q);
        let body = &g * covariance_block(pose, idx) * g.transpose();
        // Exactly symmetric (rounding differs above and below the diagonal; the core checks).
        let body = (&body + body.transpose()) * 0.5;
        p.view_mut((0, 0), (nb, nb)).copy_from(&body);
        p.view_mut((nv, nv), (nb, nb))
            .copy_from(&covariance_block(twist, idx));
    }
    for &(iv, s) in joints {
        p[(iv, iv)] = s.position * s.position;
        p[(nv + iv, nv + iv)] = s.velocity * s.velocity;
    }
    p
}

/// A floating base's covariance from a planar odometry (its z, roll and pitch variances at least
/// [`super::base::UNMEASURED_VARIANCE`]; in the twist, vz and the roll and pitch rates) without those rows and
/// columns: the state takes them from the robot at rest ([`Model::keep_unmeasured_tilt`]), not
/// from the odometry's placeholder.
fn without_unmeasured(model: &Model, c: &[f64; 36]) -> [f64; 36] {
    let mut out = *c;
    if model.base == BaseType::Floating && measures_planar_motion_only(c) {
        for k in 2..5 {
            for j in 0..6 {
                out[6 * k + j] = 0.0;
                out[6 * j + k] = 0.0;
            }
        }
    }
    out
}

/// The scene's process noise as a measured state's age needs it (`uncertainty:`): what the
/// state may have drifted by since it was measured, the motion over the age aside. The effort
/// noise is left out: a wheel's torque noise reaches the pose through the whole robot's inertia,
/// and over an age of tens of milliseconds moves it by tens of micrometres, below any odometry's
/// noise.
#[derive(Clone, Debug, Default)]
pub struct AgeNoise {
    /// σᵢ² of the white acceleration noise per velocity coordinate.
    acceleration: Vec<f64>,
    /// σ_s,i² of the slip noise on each coordinate's position.
    slip: Vec<f64>,
}

impl AgeNoise {
    /// From the scene's `uncertainty:`; a name the model does not have, or a bad σ, is an
    /// error naming it.
    pub fn new(model: &Model, spec: &UncertaintySpec) -> Result<Self> {
        Ok(Self {
            acceleration: noise_variances(model, "acceleration_noise", &spec.acceleration_noise)?,
            slip: noise_variances(model, "slip_noise", &spec.slip_noise)?,
        })
    }

    /// No process noise at all: a zero start then stays zero.
    pub fn is_zero(&self) -> bool {
        self.acceleration
            .iter()
            .chain(&self.slip)
            .all(|s| *s == 0.0)
    }

    /// Adds the noise of `age` [s] to P, integrated as the core does over a step: the
    /// acceleration noise as a double integrator's `σᵢ² [a³/3, a²/2; a²/2, a]` on (δqᵢ, δvᵢ),
    /// the slip noise as a random walk `σ_s,i² a` on δqᵢ.
    pub fn add_to(&self, p: &mut DMatrix<f64>, age: f64) {
        let nv = self.acceleration.len();
        let a = age.max(0.0);
        for (i, (&s2, &slip2)) in self.acceleration.iter().zip(&self.slip).enumerate() {
            p[(i, i)] += s2 * a * a * a / 3.0 + slip2 * a;
            p[(i, nv + i)] += s2 * a * a / 2.0;
            p[(nv + i, i)] += s2 * a * a / 2.0;
            p[(nv + i, nv + i)] += s2 * a;
        }
    }
}

/// The odometry covariances (pose in the odom frame, twist in the base frame, REP-103 6×6
/// row-major) of a tangent-space covariance P (2nv × 2nv) at configuration q. Axes the base
/// does not have (a planar base's z, roll, pitch) are left 0 here; the caller adds its floors.
pub fn odometry_covariance(model: &Model, q: &[f64], p: &[Vec<f64>]) -> ([f64; 36], [f64; 36]) {
    let nv = model.nv;
    let idx = rep103_indices(model.base);
    let nb = idx.len();
    let (mut pose, mut twist) = ([0.0; 36], [0.0; 36]);
    if nb == 0 {
        return (pose, twist);
    }
    let g = world_to_body(model, q);
    let body = DMatrix::from_fn(nb, nb, |i, j| p[i][j]);
    let world = g.transpose() * body * &g;
    for (a, &i) in idx.iter().enumerate() {
        for (b, &j) in idx.iter().enumerate() {
            pose[6 * i + j] = 0.5 * (world[(a, b)] + world[(b, a)]);
            twist[6 * i + j] = 0.5 * (p[nv + a][nv + b] + p[nv + b][nv + a]);
        }
    }
    (pose, twist)
}
