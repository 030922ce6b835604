//! `src/algorithm/` on what the reference robots do not have: multi-DOF joints (planar, floating)
//! below a moving body, against closed forms written here from Newton–Euler (no code of the
//! crate computes an expected number).
//!
//! A planar or floating joint transmits no force along its free directions, so the body it
//! carries moves as if free along them, whatever the arm above does, and the arm feels nothing of
//! it about its own axis:
//! - the arm (revolute about the vertical z, fixed base) has q̈ = τ / I_zz, I_zz its own
//!   inertia about the joint axis (izz + m d², Steiner);
//! - a puck on a horizontal planar joint keeps its world velocity in the plane: its centre of mass
//!   has zero world acceleration (gravity is along the plane normal and the arm carries it);
//! - a body on a floating joint falls freely: its centre of mass accelerates at g and its
//!   angular acceleration is Euler's ω̇ = −I_w⁻¹ (ω × I_w ω), I_w = R I Rᵀ (world axes).
//!
//! Both are checked at states with every velocity non-zero, on ABA's q̈ (the articulated inertia
//! and bias of a multi-DOF joint carried to a moving parent), and on the RNEA and CRBA of the same
//! robots: RNEA(q, v, q̈) = τ and M q̈ + h = τ.

use crate::common;
use common::*;
use constraint_dynamics::algorithm::*;
use constraint_dynamics::{BaseType, Model, ModelOptions};
use nalgebra::{DVector, Matrix3, Vector3};

/// The arm: 2 kg, COM 0.25 m out along x, izz 0.05 kg m² about its COM, spinning about world z at
/// the origin. `child` is the joint that carries the second body 0.5 m out along the arm.
fn arm_with(child_joint: &str, rpy: &str, body_inertia: &str) -> Model {
    let urdf = format!(
        r#"<robot name="arm_with_free_body">
  <link name="base"/>
  <link name="arm">
    <inertial><origin xyz="0.25 0 0"/><mass value="2.0"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.06" iyz="0" izz="0.05"/></inertial>
  </link>
  <link name="body">
    <inertial><origin xyz="0 0 0"/><mass value="0.7"/>{body_inertia}</inertial>
  </link>
  <joint name="spin" type="revolute"><parent link="base"/><child link="arm"/>
    <axis xyz="0 0 1"/><limit lower="-10" upper="10" effort="1" velocity="1"/></joint>
  <joint name="carry" type="{child_joint}"><parent link="arm"/><child link="body"/>
    <origin xyz="0.5 0 0" rpy="{rpy}"/><axis xyz="0 0 1"/></joint>
</robot>"#
    );
    Model::from_urdf_str(
        &urdf,
        "arm_with_free_body.urdf",
        &ModelOptions {
            base: BaseType::Fixed,
            ..Default::default()
        },
    )
    .unwrap()
}

/// The arm's inertia about the spin axis: izz + m d² = 0.05 + 2 · 0.25² (Steiner).
const ARM_IZZ: f64 = 0.05 + 2.0 * 0.25 * 0.25;

/// RNEA(q, v, q̈) = τ and M q̈ + h = τ for ABA's q̈ (two other algorithms, each checked against
/// Pinocchio in reference_terms.rs).
fn check_inverse_dynamics(what: &str, model: &Model, q: &[f64], v: &[f64], tau: &[f64]) {
    let mut data = Data::new(model);
    let qdd = aba(model, &mut data, q, v, tau).clone();
    let back = rnea(model, &mut data, q, v, qdd.as_slice()).clone();
    assert_close(
        &format!("{what}: RNEA(ABA(τ))"),
        back.as_slice(),
        tau,
        5e-14,
    ); // achieved ≤ 6.7e-16
    let m = crba_full(model, &mut data, q).clone();
    let h = nonlinear_effects(model, &mut data, q, v).clone();
    let lhs = m * &qdd + h;
    assert_close(&format!("{what}: M q̈ + h"), lhs.as_slice(), tau, 1e-13); // achieved ≤ 2.7e-15
}

#[test]
fn puck_on_a_planar_joint_below_a_spinning_arm_moves_freely_in_its_plane() {
    let model = arm_with(
        "planar",
        "0 0 0",
        r#"<inertia ixx="0.02" ixy="0" ixz="0" iyy="0.03" iyz="0" izz="0.01"/>"#,
    );
    assert_eq!((model.nq, model.nv), (4, 4));
    let body = model.frame_id("body").unwrap();
    // q = (spin, x, y, θ of the planar joint), every velocity non-zero.
    let q = [0.7, 0.2, -0.1, 0.4];
    let v = [1.3, -0.6, 0.9, 2.1];
    // τ on the spin joint only: the planar joint is passive, so the puck is free in its plane.
    let tau = [0.37, 0.0, 0.0, 0.0];
    let mut data = Data::new(&model);
    let qdd = aba(&model, &mut data, &q, &v, &tau).clone();
    // The arm alone: q̈ = τ / I_zz.
    assert_close("arm q̈", &[qdd[0]], &[tau[0] / ARM_IZZ], 1e-14); // achieved 0; floor 1e-14
    // The puck's COM (its frame origin) has zero world acceleration, and its spin ω_arm + θ̇ is
    // constant: world angular acceleration zero.
    forward_kinematics(&model, &mut data, &q, &v, qdd.as_slice());
    let a_com = point_classical_acceleration(&model, &data, body, &Vector3::zeros());
    assert_close("puck COM acceleration", a_com.as_slice(), &[0.0; 3], 1e-14); // achieved 9.9e-17
    let b = model.frames[body].body;
    let alpha = data.o_m_i[b].rotation * data.a[b].ang;
    assert_close(
        "puck angular acceleration",
        alpha.as_slice(),
        &[0.0; 3],
        1e-14,
    ); // achieved 0; floor 1e-14
    check_inverse_dynamics("planar", &model, &q, &v, &tau);
}

#[test]
fn body_on_a_floating_joint_below_a_spinning_arm_falls_freely() {
    let model = arm_with(
        "floating",
        "0 0 0",
        r#"<inertia ixx="0.03" ixy="0.003" ixz="-0.002" iyy="0.05" iyz="0.001" izz="0.04"/>"#,
    );
    assert_eq!((model.nq, model.nv), (8, 7));
    let body = model.frames[model.frame_id("body").unwrap()].body;
    // q = (spin, position, unit quaternion (x, y, z, w)) of the floating joint.
    let quat = nalgebra::UnitQuaternion::from_euler_angles(0.3, -0.5, 0.8);
    let q = [-0.4, 0.1, 0.2, -0.3, quat.i, quat.j, quat.k, quat.w];
    let v = [0.8, 0.5, -0.7, 0.3, 1.1, -1.7, 0.6];
    let tau = [-0.25, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    let mut data = Data::new(&model);
    let qdd = aba(&model, &mut data, &q, &v, &tau).clone();
    assert_close("arm q̈", &[qdd[0]], &[tau[0] / ARM_IZZ], 1e-14); // achieved 0; floor 1e-14

    forward_kinematics(&model, &mut data, &q, &v, qdd.as_slice());
    let a_com = point_classical_acceleration(
        &model,
        &data,
        model.frame_id("body").unwrap(),
        &Vector3::zeros(),
    );
    // Free fall: g = (0, 0, −9.81) (the model's default gravity).
    assert_close(
        "body COM acceleration",
        a_com.as_slice(),
        &[0.0, 0.0, -9.81],
        1e-14,
    ); // achieved 1.8e-16 (closed form g)
    // Euler: I_w ω̇ + ω × I_w ω = 0 in world axes.
    let r = data.o_m_i[body].rotation;
    let i_body = Matrix3::new(0.03, 0.003, -0.002, 0.003, 0.05, 0.001, -0.002, 0.001, 0.04);
    let i_w = r * i_body * r.transpose();
    let omega = r * data.v[body].ang;
    let expected = -i_w.try_inverse().unwrap() * omega.cross(&(i_w * omega));
    let alpha = r * data.a[body].ang;
    assert_close(
        "body angular acceleration (Euler)",
        alpha.as_slice(),
        expected.as_slice(),
        5e-14,
    ); // achieved 6.5e-16
    check_inverse_dynamics("floating", &model, &q, &v, &tau);

    // Kinetic energy of the free body and the arm from their own inertias:
    // ½ m |v_c|² + ½ ωᵀ I_w ω + ½ I_zz ω_arm² (the arm's COM speed is in I_zz by Steiner).
    forward_kinematics(&model, &mut data, &q, &v, &[0.0; 7]);
    let v_c = point_velocity(
        &model,
        &data,
        model.frame_id("body").unwrap(),
        &Vector3::zeros(),
    );
    let ke = 0.5 * 0.7 * v_c.norm_squared()
        + 0.5 * omega.dot(&(i_w * omega))
        + 0.5 * ARM_IZZ * v[0] * v[0];
    assert_close(
        "kinetic energy",
        &[kinetic_energy(&model, &data)],
        &[ke],
        1e-14,
    ); // achieved 1.7e-16
    let m = crba_full(&model, &mut data, &q).clone();
    let vv = DVector::from_column_slice(&v);
    assert_close("½ vᵀ M v", &[0.5 * vv.dot(&(m * &vv))], &[ke], 1e-14); // achieved 5.6e-17
}

/// The planar joint turned so that its plane is vertical (normal along the arm): the arm's spin
/// now lies in the puck's plane, so the velocity product v × v_J leaves the joint's subspace
/// (which the horizontal case never does). Free in its plane, the puck's COM acceleration
/// projected on the plane is gravity's projection, and no torque acts about the plane normal n:
/// n · (I_w ω̇ + ω × I_w ω) = 0.
#[test]
fn puck_on_a_vertical_planar_joint_is_free_in_its_plane() {
    let model = arm_with(
        "planar",
        "0 1.5707963267948966 0",
        r#"<inertia ixx="0.02" ixy="0.004" ixz="0" iyy="0.03" iyz="-0.002" izz="0.04"/>"#,
    );
    let frame = model.frame_id("body").unwrap();
    let body = model.frames[frame].body;
    let q = [0.7, 0.2, -0.1, 0.4];
    let v = [1.3, -0.6, 0.9, 2.1];
    let tau = [0.37, 0.0, 0.0, 0.0];
    check_inverse_dynamics("vertical planar", &model, &q, &v, &tau);
    let mut data = Data::new(&model);
    let qdd = aba(&model, &mut data, &q, &v, &tau).clone();
    forward_kinematics(&model, &mut data, &q, &v, qdd.as_slice());
    let r = data.o_m_i[body].rotation;
    let n = r * Vector3::z();
    let g = Vector3::new(0.0, 0.0, -9.81);
    let a_com = point_classical_acceleration(&model, &data, frame, &Vector3::zeros());
    let in_plane = |x: Vector3<f64>| x - n * n.dot(&x);
    assert_close(
        "COM acceleration in the plane",
        in_plane(a_com).as_slice(),
        in_plane(g).as_slice(),
        2e-15,
    ); // achieved 4.4e-17 (closed form: gravity's projection)
    let i_body = Matrix3::new(0.02, 0.004, 0.0, 0.004, 0.03, -0.002, 0.0, -0.002, 0.04);
    let i_w = r * i_body * r.transpose();
    let omega = r * data.v[body].ang;
    let alpha = r * data.a[body].ang;
    let torque_n = n.dot(&(i_w * alpha + omega.cross(&(i_w * omega))));
    assert_close("torque about the normal", &[torque_n], &[0.0], 1e-15); // achieved 4.5e-17; floor 1e-15
}
