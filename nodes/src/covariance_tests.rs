//! The frame conversions against closed forms, and against the core's own ⊕ (`Model::integrate`):
//! a right perturbation G d of the base must move it by the odom-frame displacement d.

use super::*;
use constraint_dynamics::Scene;
use nalgebra::{DMatrix, Matrix3, Quaternion, UnitQuaternion};
use std::sync::Arc;

fn model(scene: &str) -> Arc<Model> {
    let path = format!("{}/../params/{scene}", env!("CARGO_MANIFEST_DIR"));
    Scene::load(&path).unwrap().model
}

/// A row-major 6×6 with the given entries (symmetric) and zeros elsewhere.
fn cov6(entries: &[(usize, usize, f64)]) -> [f64; 36] {
    let mut c = [0.0; 36];
    for &(i, j, x) in entries {
        c[6 * i + j] = x;
        c[6 * j + i] = x;
    }
    c
}

/// Planar base at yaw θ: the odom-frame (x, y, yaw) covariance becomes the body-frame one,
/// P_b = G Σ Gᵀ with G = [[c, s, 0], [−s, c, 0], [0, 0, 1]], entry by entry in closed form.
#[test]
fn planar_pose_covariance_rotates_into_the_base_frame() {
    let m = model("diff_drive.yaml");
    let th: f64 = 0.7;
    let (s, c) = th.sin_cos();
    let mut q = vec![0.0; m.nq];
    q[..3].copy_from_slice(&[1.0, -2.0, th]);
    let (sx2, sy2, rho, st2, cxt, cyt) = (0.04, 0.01, 0.006, 0.0025, 0.003, -0.002);
    let pose = cov6(&[
        (0, 0, sx2),
        (1, 1, sy2),
        (0, 1, rho),
        (5, 5, st2),
        (0, 5, cxt),
        (1, 5, cyt),
        (2, 2, 1e6), // unused axes: ignored
        (3, 3, 1e6),
        (4, 4, 1e6),
    ]);
    let twist = cov6(&[(0, 0, 0.09), (5, 5, 0.16), (0, 5, 0.01), (1, 1, 4e-4)]);
    let joints = [(
        3,
        JointSigma {
            position: 0.1,
            velocity: 0.2,
        },
    )];
    let p = start_covariance(&m, &q, &pose, &twist, &joints);
    let nv = m.nv;
    let want = [
        (0, 0, c * c * sx2 + 2.0 * c * s * rho + s * s * sy2),
        (1, 1, s * s * sx2 - 2.0 * c * s * rho + c * c * sy2),
        (0, 1, -c * s * sx2 + (c * c - s * s) * rho + c * s * sy2),
        (0, 2, c * cxt + s * cyt),
        (1, 2, -s * cxt + c * cyt),
        (2, 2, st2),
        (nv, nv, 0.09),
        (nv + 2, nv + 2, 0.16),
        (nv, nv + 2, 0.01),
        (nv + 1, nv + 1, 4e-4),
        (3, 3, 0.01),
        (nv + 3, nv + 3, 0.04),
        (4, 4, 0.0),
        (0, nv, 0.0),
    ];
    for (i, j, x) in want {
        assert!(
            (p[(i, j)] - x).abs() < 1e-15,
            "P[{i},{j}] = {} ≠ {x}",
            p[(i, j)]
        );
        assert_eq!(p[(i, j)], p[(j, i)]);
    }
    // Back to the odom frame at the same q: the input, on the used axes.
    let rows: Vec<Vec<f64>> = (0..2 * nv)
        .map(|i| p.row(i).iter().copied().collect())
        .collect();
    let (pose_back, twist_back) = odometry_covariance(&m, &q, &rows);
    for i in [0, 1, 5] {
        for j in [0, 1, 5] {
            assert!((pose_back[6 * i + j] - pose[6 * i + j]).abs() < 1e-15);
            assert!((twist_back[6 * i + j] - twist[6 * i + j]).abs() < 1e-15);
        }
    }
    assert_eq!(pose_back[14], 0.0, "z is left to the caller's floor");
}

/// The convention, checked against the core's ⊕: moving the base by the right perturbation
/// ε G d (`Model::integrate`, SE(2)/SE(3) exponential) displaces it by ε d in the odom frame
/// (position) and rotates it by ε d about the odom axes (orientation), to first order.
#[test]
fn right_perturbation_of_g_d_is_the_odom_displacement_d() {
    let eps = 1e-7;
    // Planar at yaw 2.1.
    let m = model("diff_drive.yaml");
    let mut q = vec![0.0; m.nq];
    q[..3].copy_from_slice(&[0.3, 0.4, 2.1]);
    let g = world_to_body(&m, &q);
    for d in [
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.3, -0.5, 0.2],
    ] {
        let dv = nalgebra::DVector::from_column_slice(&d);
        let body = &g * dv;
        let mut v = vec![0.0; m.nv];
        v[..3].copy_from_slice(body.as_slice());
        let mut q1 = vec![0.0; m.nq];
        m.integrate(&q, &v, eps, &mut q1);
        for k in 0..3 {
            let moved = (q1[k] - q[k]) / eps;
            assert!((moved - d[k]).abs() < 1e-6, "planar {d:?}[{k}]: {moved}");
        }
    }
    // Floating base with a general attitude.
    let m = model("mobile_manipulator_floating.yaml");
    let mut q = vec![0.0; m.nq];
    let att = UnitQuaternion::from_euler_angles(0.4, -0.3, 1.2);
    q[..3].copy_from_slice(&[1.0, 2.0, 0.5]);
    q[3..7].copy_from_slice(&[att.i, att.j, att.k, att.w]);
    let g = world_to_body(&m, &q);
    for d in [
        [1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
        [0.2, -0.1, 0.3, 0.5, -0.4, 0.1],
    ] {
        let body = &g * nalgebra::DVector::from_column_slice(&d);
        let mut v = vec![0.0; m.nv];
        v[..6].copy_from_slice(body.as_slice());
        let mut q1 = vec![0.0; m.nq];
        m.integrate(&q, &v, eps, &mut q1);
        for k in 0..3 {
            let moved = (q1[k] - q[k]) / eps;
            assert!((moved - d[k]).abs() < 1e-6, "floating {d:?}[{k}]: {moved}");
        }
        // R₁ R₀ᵀ = Exp(ε φ) ≈ 1 + ε [φ]×: φ about the odom axes.
        let r = |q: &[f64]| {
            UnitQuaternion::from_quaternion(Quaternion::new(q[6], q[3], q[4], q[5]))
                .to_rotation_matrix()
                .into_inner()
        };
        let w = (r(&q1) * r(&q).transpose() - Matrix3::identity()) / eps;
        let phi = [w[(2, 1)], w[(0, 2)], w[(1, 0)]];
        for k in 0..3 {
            assert!(
                (phi[k] - d[3 + k]).abs() < 1e-6,
                "floating rotation {d:?}[{k}]: {phi:?}"
            );
        }
    }
}

/// Floating base at a general attitude: odom frame → base frame → odom frame gives the input
/// back (all six axes), and the twist is copied as is.
#[test]
fn floating_round_trip() {
    let m = model("mobile_manipulator_floating.yaml");
    let mut q = vec![0.0; m.nq];
    let att = UnitQuaternion::from_euler_angles(0.4, -0.3, 1.2);
    q[3..7].copy_from_slice(&[att.i, att.j, att.k, att.w]);
    // A positive definite 6×6: A Aᵀ + diag with A's entries distinct.
    let a = DMatrix::from_fn(6, 6, |i, j| 0.01 * ((i * 6 + j) as f64).sin());
    let s = &a * a.transpose() + DMatrix::from_diagonal_element(6, 6, 1e-3);
    let mut pose = [0.0; 36];
    pose.iter_mut()
        .enumerate()
        .for_each(|(k, x)| *x = s[(k / 6, k % 6)]);
    let twist = pose.map(|x| 2.0 * x);
    let p = start_covariance(&m, &q, &pose, &twist, &[]);
    let nv = m.nv;
    assert_eq!(
        p[(nv + 4, nv + 2)],
        twist[6 * 4 + 2],
        "twist copied in the base frame"
    );
    let rows: Vec<Vec<f64>> = (0..2 * nv)
        .map(|i| p.row(i).iter().copied().collect())
        .collect();
    let (pose_back, twist_back) = odometry_covariance(&m, &q, &rows);
    for k in 0..36 {
        assert!((pose_back[k] - pose[k]).abs() < 1e-15, "pose[{k}]");
        assert!((twist_back[k] - twist[k]).abs() < 1e-15, "twist[{k}]");
    }
    // And the base-frame block really is rotated (not the input).
    assert!((p[(0, 0)] - pose[0]).abs() > 1e-6);
}

/// A covariance that is not positive semidefinite is clipped to the nearest one that is (its
/// negative eigenvalue set to 0), symmetrised first: [[1, 2], [2, 1]] has eigenvalues 3, −1
/// along (1, 1)/√2 and (1, −1)/√2, so it becomes 1.5 [[1, 1], [1, 1]].
#[test]
fn not_positive_semidefinite_is_clipped() {
    let c = cov6(&[(0, 0, 1.0), (1, 1, 1.0), (0, 1, 2.0)]);
    let b = block(&c, &[0, 1]);
    for (i, j) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
        assert!((b[(i, j)] - 1.5).abs() < 1e-12, "{b}");
    }
}

/// Non-finite or negative-variance entries of the used axes are refused, naming the entry;
/// unused axes are not looked at.
#[test]
fn bad_odometry_covariance_is_refused() {
    let mut c = [0.0; 36];
    c[14] = f64::NAN; // z: unused by a planar base
    assert!(check_odometry_covariance(BaseType::Planar, "pose", &c).is_ok());
    c[35] = -1e-3;
    let e = check_odometry_covariance(BaseType::Planar, "pose", &c).unwrap_err();
    assert!(e.to_string().contains("pose.covariance[35]"), "{e}");
    assert!(check_odometry_covariance(BaseType::Floating, "twist", &[0.0; 36]).is_ok());
    let mut c = [0.0; 36];
    c[1] = f64::INFINITY;
    assert!(check_odometry_covariance(BaseType::Floating, "twist", &c).is_err());
}

/// The age's process noise: the acceleration noise is the double integrator's
/// σ² [a³/3, a²/2; a²/2, a], the slip noise a random walk σ_s² a on the position.
#[test]
fn age_noise_is_the_double_integrator_and_a_random_walk() {
    let m = model("diff_drive.yaml");
    let (nv, yaw) = (m.nv, m.v_index("root_joint:wz").unwrap());
    let wheel = m.v_index("left_wheel_joint").unwrap();
    let spec = constraint_dynamics::predict::UncertaintySpec {
        acceleration_noise: [("left_wheel_joint".to_string(), 0.5)].into(),
        slip_noise: [("root_joint:wz".to_string(), 0.3)].into(),
        ..Default::default()
    };
    let noise = AgeNoise::new(&m, &spec).unwrap();
    assert!(!noise.is_zero());
    let mut p = DMatrix::zeros(2 * nv, 2 * nv);
    noise.add_to(&mut p, 0.6);
    let (s2, slip2, a): (f64, f64, f64) = (0.25, 0.09, 0.6);
    assert!((p[(wheel, wheel)] - s2 * a.powi(3) / 3.0).abs() < 1e-16);
    assert!((p[(wheel, nv + wheel)] - s2 * a * a / 2.0).abs() < 1e-16);
    assert!((p[(nv + wheel, wheel)] - s2 * a * a / 2.0).abs() < 1e-16);
    assert!((p[(nv + wheel, nv + wheel)] - s2 * a).abs() < 1e-16);
    assert!((p[(yaw, yaw)] - slip2 * a).abs() < 1e-16);
    assert_eq!(p[(nv + yaw, nv + yaw)], 0.0);
    let others = (0..2 * nv).filter(|&i| ![wheel, nv + wheel, yaw].contains(&i));
    assert!(others.into_iter().all(|i| p[(i, i)] == 0.0));
    // An unknown name and a negative σ are refused, naming the field and the entry.
    for (name, sigma, says) in [
        (
            "root_joint:spin",
            0.3,
            "uncertainty.slip_noise: unknown velocity coordinate 'root_joint:spin'",
        ),
        (
            "root_joint:wz",
            -0.3,
            "uncertainty.slip_noise.root_joint:wz",
        ),
    ] {
        let bad = constraint_dynamics::predict::UncertaintySpec {
            slip_noise: [(name.to_string(), sigma)].into(),
            ..Default::default()
        };
        let e = AgeNoise::new(&m, &bad).unwrap_err();
        assert!(e.to_string().contains(says), "{e}");
    }
}
