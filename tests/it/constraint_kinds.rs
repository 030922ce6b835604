//! Weld and distance constraints against closed forms, and frame Jacobians against forward
//! kinematics in every reference frame.

use crate::common;
use common::*;
use constraint_dynamics::algorithm::*;
use constraint_dynamics::constraints::{Axes, ConstraintSet, ConstraintSpec, Row};
use constraint_dynamics::dynamics::{Baumgarte, Formulation};
use constraint_dynamics::{BaseType, Model, ModelOptions, System};
use nalgebra::{DMatrix, DVector, UnitQuaternion, Vector3};

fn weld(rpy: [f64; 3], xyz: [f64; 3]) -> ConstraintSpec {
    ConstraintSpec::Weld {
        name: "w".into(),
        frame_a: "disk".into(),
        frame_b: "world".into(),
        axes: Axes::World,
        rows: vec![Row::X, Row::Y, Row::Z, Row::Rx, Row::Ry, Row::Rz],
        relative_xyz: xyz,
        relative_rpy: rpy,
    }
}

#[test]
fn welded_body_carries_its_weight_and_baumgarte_pulls_it_back() {
    let model = reference_disk(BaseType::Floating);
    let (rpy, xyz) = ([0.3, -0.2, 1.1], [0.5, -0.4, 1.2]);
    let target = UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]);
    let q = q_at(xyz, &target);
    let set = ConstraintSet::new(&model, &[weld(rpy, xyz)], &q).unwrap();
    let mut sys = System::new(model, set, Baumgarte::default(), Formulation::Multipliers);
    let qdd = sys
        .forward_dynamics(&q, &[0.0; 6], &[0.0; 6], true)
        .unwrap()
        .clone();
    // Closed form: held at its target pose, the body does not move and φ = 0.
    assert_close("welded: q̈", qdd.as_slice(), &[0.0; 6], 1e-13); // achieved 1.8e-15
    assert_close("welded: φ", sys.rows().phi.as_slice(), &[0.0; 6], 5e-15); // achieved 9.7e-17
    // Weight m g = 9.81 N upward, no torque about the COM (the frame origin).
    let f = &sys.constraint_forces()[0];
    assert_close("weld force", &f.force, &[0.0, 0.0, 9.81], 1e-14); // achieved 1.8e-16 (closed form m g)
    assert_close("weld torque", &f.torque, &[0.0, 0.0, 0.0], 1e-15); // achieved 0; floor 1e-15

    // Off target by δ (world) and by a rotation ε about world z, at rest: with K_p only,
    // the world accelerations are −K_p δ and −K_p ε ẑ (a critically simple closed form).
    let (kp, delta, eps) = (50.0, Vector3::new(0.01, -0.02, 0.005), 0.03);
    sys = sys.with_baumgarte(Baumgarte { kp, kd: 0.0 });
    let rot = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), eps) * target;
    let q1 = q_at([xyz[0] + delta.x, xyz[1] + delta.y, xyz[2] + delta.z], &rot);
    let qdd = sys
        .forward_dynamics(&q1, &[0.0; 6], &[0.0; 6], true)
        .unwrap()
        .clone();
    let r = rot.to_rotation_matrix();
    let a_world = r * Vector3::new(qdd[0], qdd[1], qdd[2]); // ω = 0: world accel = R a_lin
    let alpha_world = r * Vector3::new(qdd[3], qdd[4], qdd[5]);
    assert_close(
        "pull-back linear",
        a_world.as_slice(),
        (-kp * delta).as_slice(),
        2e-13, // achieved 6.4e-15 (closed form −K_p δ)
    );
    assert_close(
        "pull-back angular",
        alpha_world.as_slice(),
        &[0.0, 0.0, -kp * eps],
        2e-13, // achieved 7.3e-15 (closed form −K_p ε)
    );
}

/// Statics of the weld: the disk held at a rotated pose against a generalized force τ =
/// (f, m) in its own axes (the free-flyer's) stays at rest, and the weld supplies the opposite
/// wrench in world axes, −R f + m g ẑ and −R m (about the COM, the frame origin): every
/// torque row lands on its own axis.
#[test]
fn welded_body_holds_an_applied_wrench() {
    let model = reference_disk(BaseType::Floating);
    let (rpy, xyz) = ([0.3, -0.2, 1.1], [0.5, -0.4, 1.2]);
    let target = UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]);
    let q = q_at(xyz, &target);
    let set = ConstraintSet::new(&model, &[weld(rpy, xyz)], &q).unwrap();
    let mut sys = System::new(model, set, Baumgarte::default(), Formulation::Multipliers);
    let tau = [0.4, -0.7, 0.2, 0.3, -0.5, 0.8];
    let qdd = sys
        .forward_dynamics(&q, &[0.0; 6], &tau, true)
        .unwrap()
        .clone();
    assert_close("q̈", qdd.as_slice(), &[0.0; 6], 1e-13); // achieved 1.4e-14 (at rest)
    let r = target.to_rotation_matrix();
    let force = -(r * Vector3::new(tau[0], tau[1], tau[2])) + Vector3::new(0.0, 0.0, 9.81);
    let torque = -(r * Vector3::new(tau[3], tau[4], tau[5]));
    let f = &sys.constraint_forces()[0];
    assert_close("weld force", &f.force, force.as_slice(), 1e-14); // achieved 3.7e-16 (statics)
    assert_close("weld torque", &f.torque, torque.as_slice(), 1e-14); // achieved 3.3e-16
}

/// Axes and normals are directions: declared with any length they act as their unit vectors.
/// The knife edge on the planar disk (axis [0, 2.5, 0], moving at u, turning at ω) carries
/// λ = m u ω, the lateral force along the unit axis; the disk resting upright on the ground
/// (wheel axis [0, 4, 0], plane normal [0, 0, 3]) carries its weight m g on the normal row.
#[test]
fn axes_and_normals_of_any_length_act_as_unit_vectors() {
    let planar = Model::from_urdf_file(
        reference_dir().join("urdf/disk.urdf"),
        &ModelOptions {
            base: BaseType::Planar,
            ..Default::default()
        },
    )
    .unwrap();
    let edge = ConstraintSpec::NoSideSlip {
        name: "edge".into(),
        frame: "disk".into(),
        axis: [0.0, 2.5, 0.0],
    };
    let q = [0.4, 0.1, 0.6];
    let set = ConstraintSet::new(&planar, &[edge], &q).unwrap();
    let mut sys = System::new(planar, set, Baumgarte::default(), Formulation::Multipliers);
    let (u, w) = (1.5, -0.8);
    sys.forward_dynamics(&q, &[u, 0.0, w], &[0.0; 3], true)
        .unwrap();
    assert_close(
        "knife edge λ",
        sys.multipliers().lambda.as_slice(),
        &[u * w],
        1e-15,
    ); // achieved 0 (m u ω)

    let contact = ConstraintSpec::Rolling {
        name: "contact".into(),
        wheel: "disk".into(),
        axis: [0.0, 4.0, 0.0],
        radius: 0.1,
        axle_offset: 0.0,
        axle_offset_turn_gain: 0.0,
        lateral: Default::default(),
        plane_normal: [0.0, 0.0, 3.0],
        plane_height: 0.0,
        friction: None,
    };
    let q = q_at([0.0, 0.0, 0.1], &UnitQuaternion::identity());
    let model = reference_disk(BaseType::Floating);
    let set = ConstraintSet::new(&model, &[contact], &q).unwrap();
    let mut sys = System::new(model, set, Baumgarte::default(), Formulation::Multipliers);
    let qdd = sys
        .forward_dynamics(&q, &[0.0; 6], &[0.0; 6], true)
        .unwrap()
        .clone();
    assert_close("resting disk q̈", qdd.as_slice(), &[0.0; 6], 1e-15); // achieved 0
    let f = &sys.constraint_forces()[0];
    assert_close("normal force", &[f.normal_force.unwrap()], &[9.81], 1e-15); // achieved 0 (m g)
    assert_close("φ", &f.position_residual, &[0.0; 3], 1e-15); // achieved 0 (on the plane)
}

#[test]
fn distance_pendulum_tension_is_m_g_plus_m_u2_over_l() {
    // Disk origin (its COM) on a massless rod of length L = 1 m from the world point (0, 0, 1):
    // hanging at the bottom with horizontal speed u, the rod pulls with m (g + u²/L) and the
    // centre accelerates upward by u²/L. λ is the force along n = (p_a − p_b)/|p_a − p_b| = −z,
    // so λ = −m (g + u²/L).
    let model = reference_disk(BaseType::Floating);
    let spec = ConstraintSpec::Distance {
        name: "rod".into(),
        frame_a: "disk".into(),
        point_a: [0.0; 3],
        frame_b: "world".into(),
        point_b: [0.0, 0.0, 1.0],
        distance: 1.0,
    };
    let q = q_at([0.0, 0.0, 0.0], &UnitQuaternion::identity());
    let set = ConstraintSet::new(&model, &[spec], &q).unwrap();
    let mut sys = System::new(model, set, Baumgarte::default(), Formulation::Multipliers);
    for u in [0.0, 0.7, 3.0] {
        let v = [u, 0.0, 0.0, 0.0, 0.0, 0.0];
        let qdd = sys
            .forward_dynamics(&q, &v, &[0.0; 6], true)
            .unwrap()
            .clone();
        assert_close(
            &format!("u = {u}: q̈"),
            qdd.as_slice(),
            &[0.0, 0.0, u * u, 0.0, 0.0, 0.0],
            1e-14, // achieved 2.8e-16 (closed form u²/L)
        );
        assert_close(
            &format!("u = {u}: λ"),
            sys.multipliers().lambda.as_slice(),
            &[-(9.81 + u * u)],
            1e-15, // achieved 0 (closed form −m(g + u²/L))
        );
        let f = &sys.constraint_forces()[0];
        assert_close(
            "force on the body",
            &f.force,
            &[0.0, 0.0, 9.81 + u * u],
            1e-15, // achieved 0
        );
    }
    // Off the velocity constraint: also a radial speed w (the rod lengthening), without
    // Baumgarte. The constraint then holds |d|¨ = 0: n·d̈ + (|ḋ|² − (n·ḋ)²)/|d| = 0 with
    // |ḋ|² − (n·ḋ)² = u², so the centre still accelerates upward by u²/L whatever w is.
    sys = sys.with_baumgarte(Baumgarte { kp: 0.0, kd: 0.0 });
    for (u, w) in [(0.7, 0.4), (3.0, -1.5)] {
        let v = [u, 0.0, w, 0.0, 0.0, 0.0];
        let qdd = sys
            .forward_dynamics(&q, &v, &[0.0; 6], true)
            .unwrap()
            .clone();
        assert_close(
            &format!("u = {u}, w = {w}: q̈"),
            qdd.as_slice(),
            &[0.0, 0.0, u * u, 0.0, 0.0, 0.0],
            1e-14, // achieved ≤ 2.8e-16 (closed form u²/L)
        );
    }
}

#[test]
fn frame_jacobians_agree_with_forward_kinematics_in_every_reference_frame() {
    let case = load_case("solo12_four_feet");
    let model = case_model(&case);
    let st = &case["states"][2];
    let (q, v) = (vecf(&st["q"]), vecf(&st["qd"]));
    let mut data = Data::new(&model);
    forward_kinematics(&model, &mut data, &q, &v, &vec![0.0; model.nv]);
    let mut j = DMatrix::zeros(6, model.nv);
    let vv = DVector::from_vec(v.clone());
    for name in ["FL_FOOT", "HR_LOWER_LEG", "base_link"] {
        let f = model.frame_id(name).unwrap();
        let local = frame_velocity(&model, &data, f).to_vector();
        let o_m_f = frame_placement(&model, &data, f);
        frame_jacobian(&model, &data, f, ReferenceFrame::Local, &mut j);
        assert_close(
            &format!("{name} local"),
            (&j * &vv).as_slice(),
            local.as_slice(),
            2e-14, // achieved ≤ 4.0e-16 (J v against the kinematics pass)
        );
        frame_jacobian(&model, &data, f, ReferenceFrame::LocalWorldAligned, &mut j);
        let r = o_m_f.rotation;
        let (l, a) = (r * local.fixed_rows::<3>(0), r * local.fixed_rows::<3>(3));
        let lwa = [l.as_slice(), a.as_slice()].concat();
        assert_close(
            &format!("{name} local world aligned"),
            (&j * &vv).as_slice(),
            &lwa,
            2e-14, // achieved ≤ 1.4e-16
        );
        frame_jacobian(&model, &data, f, ReferenceFrame::World, &mut j);
        let world = o_m_f
            .act_motion(&constraint_dynamics::spatial::Motion::from_vector(&local))
            .to_vector();
        assert_close(
            &format!("{name} world"),
            (&j * &vv).as_slice(),
            world.as_slice(),
            2e-14, // achieved ≤ 1.4e-16
        );
    }
}

#[test]
fn weld_in_local_axes_gives_the_same_motion_and_rotated_wrench() {
    // Solo12's FL foot welded to its moving base: world-axis and base-axis rows describe the same
    // constraint, so at a consistent moving state q̈ agrees and λ_local = R_baseᵀ λ_world.
    let case = load_case("solo12_four_feet");
    let model = case_model(&case);
    let st = &case["states"][3];
    let q = vecf(&st["q"]);
    let mut data = Data::new(&model);
    forward_kinematics_pos(&model, &mut data, &q);
    let (foot, base) = (
        model.frame_id("FL_FOOT").unwrap(),
        model.frame_id("base_link").unwrap(),
    );
    let rel = frame_placement(&model, &data, base)
        .inverse()
        .compose(&frame_placement(&model, &data, foot));
    let rpy = nalgebra::Rotation3::from_matrix(&rel.rotation).euler_angles();
    let spec = |axes| ConstraintSpec::Weld {
        name: "w".into(),
        frame_a: "FL_FOOT".into(),
        frame_b: "base_link".into(),
        axes,
        rows: vec![Row::X, Row::Y, Row::Z, Row::Rx, Row::Ry, Row::Rz],
        relative_xyz: rel.translation.into(),
        relative_rpy: [rpy.0, rpy.1, rpy.2],
    };
    let mut world = System::new(
        model.clone(),
        ConstraintSet::new(&model, &[spec(Axes::World)], &q).unwrap(),
        Baumgarte::default(),
        Formulation::Multipliers,
    );
    let mut local = System::new(
        model.clone(),
        ConstraintSet::new(&model, &[spec(Axes::Local)], &q).unwrap(),
        Baumgarte::default(),
        Formulation::Multipliers,
    );
    // A velocity in the null space of the weld Jacobian (the leg moves rigidly with the base).
    world
        .forward_dynamics(&q, &[0.0; 18], &[0.0; 18], true)
        .unwrap();
    let jw = world.rows().j.clone();
    let svd = jw.clone().svd(true, true);
    let vt = svd.v_t.unwrap();
    let raw = DVector::from_fn(18, |i, _| ((i + 1) as f64 * 0.37).sin());
    let mut v = raw.clone();
    for k in 0..6 {
        let row = vt.row(k).transpose();
        v -= &row * row.dot(&raw);
    }
    assert_close(
        "J v in the null space",
        (&jw * &v).as_slice(),
        &[0.0; 6],
        2e-14,
    ); // achieved 3.3e-16
    let tau: Vec<f64> = (0..18)
        .map(|i| if i < 6 { 0.0 } else { (i as f64).cos() })
        .collect();
    let a = world
        .forward_dynamics(&q, v.as_slice(), &tau, true)
        .unwrap()
        .clone();
    let lw = world.lambda().clone();
    let b = local
        .forward_dynamics(&q, v.as_slice(), &tau, true)
        .unwrap()
        .clone();
    assert_close("q̈ world vs local rows", b.as_slice(), a.as_slice(), 2e-12); // achieved 6.1e-14 (same constraint in two row bases)
    let r = frame_placement(&model, local.data(), base).rotation;
    let (f, m) = (
        r.transpose() * lw.fixed_rows::<3>(0),
        r.transpose() * lw.fixed_rows::<3>(3),
    );
    assert_close(
        "λ local = Rᵀ λ world",
        local.lambda().as_slice(),
        &[f.as_slice(), m.as_slice()].concat(),
        5e-12, // achieved 9.9e-14 (λ_local = Rᵀ λ_world)
    );
}

/// Redundant constraint rows in the embedded form, whose dropped rows are checked for consistency.
/// - The fourbar's loop closure declared twice (4 rows, rank 2): the same q̈ as one
///   declaration, also at 1000× the scene's speed.
/// - The differential drive, whose two wheels' lateral rows are the same row computed through
///   different frames (rank deficiency 1): at 1, 1e3 and 1e5 × a turning velocity, γ grows as
///   v² and the round-off in the dropped row with it; the check is relative to the right-hand
///   side, so a consistent set is accepted at any scale, with the multiplier form's q̈.
/// - A copy anchored 1 mm away, with K_p = 100/s²: the duplicated rows ask for different
///   accelerations (K_p·1 mm = 0.1 m/s² apart, against a right-hand side of size ~10 m/s²), which
///   no q̈ meets: `Error::InconsistentConstraints` from both forms, never a q̈ that silently
///   drops one copy.
#[test]
fn redundant_rows_are_accepted_when_consistent_and_refused_when_not() {
    use constraint_dynamics::Scene;
    use constraint_dynamics::error::Error;
    let single = Scene::load(repo_dir().join("params/fourbar.yaml")).unwrap();
    let with_copy = |shift: f64| {
        let mut sc = single.clone();
        let mut dup = sc.file.constraints[0].clone();
        if let ConstraintSpec::Point { name, point_b, .. } = &mut dup {
            *name = "loop_closure_again".into();
            point_b[0] += shift;
        }
        sc.file.constraints.push(dup);
        sc
    };
    let tau = [0.0; 3];
    for speed in [1.0, 1e3] {
        let v: Vec<f64> = single.v0.iter().map(|x| speed * x).collect();
        let mut one = System::from_scene(&single).unwrap();
        one = one.with_formulation(Formulation::Embedded);
        let a = one
            .forward_dynamics(&single.q0, &v, &tau, false)
            .unwrap()
            .clone();
        let mut two = System::from_scene(&with_copy(0.0)).unwrap();
        two = two.with_formulation(Formulation::Embedded);
        let b = two
            .forward_dynamics(&single.q0, &v, &tau, false)
            .unwrap_or_else(|e| panic!("speed ×{speed}: consistent copies refused: {e}"))
            .clone();
        // Achieved 0 (the dropped rows do not enter q̈); floor 1e-15.
        assert_close(
            &format!("speed ×{speed}: one vs two declarations"),
            b.as_slice(),
            a.as_slice(),
            1e-15,
        );
    }
    let dd = Scene::load(repo_dir().join("params/diff_drive.yaml")).unwrap();
    let mut sys = System::from_scene(&dd).unwrap();
    let (r, c) = (0.05, 0.17);
    for speed in [1.0, 1e3, 1e5] {
        let (vx, wz) = (speed * 0.8, speed * 0.6);
        let v = [vx, 0.0, wz, (vx - c * wz) / r, (vx + c * wz) / r];
        let tau = [0.0, 0.0, 0.0, 0.3, -0.2];
        sys = sys.with_formulation(Formulation::Multipliers);
        let a = sys
            .forward_dynamics(&dd.q0, &v, &tau, true)
            .unwrap()
            .clone();
        assert_eq!(sys.multipliers().rank_deficiency, 1);
        sys = sys.with_formulation(Formulation::Embedded);
        let b = sys
            .forward_dynamics(&dd.q0, &v, &tau, false)
            .unwrap_or_else(|e| panic!("diff drive ×{speed}: consistent rows refused: {e}"))
            .clone();
        // Achieved ≤ 4.1e-15 relative to max(1, |q̈|) (×1); tol 2e-13.
        assert_close(
            &format!("diff drive ×{speed}: embedded vs multipliers"),
            b.as_slice(),
            a.as_slice(),
            2e-13,
        );
    }

    let mut bad = System::from_scene(&with_copy(1e-3)).unwrap();
    bad = bad.with_formulation(Formulation::Embedded);
    bad = bad.with_baumgarte(Baumgarte { kp: 100.0, kd: 0.0 });
    match bad.forward_dynamics(&single.q0, &single.v0, &tau, false) {
        Err(Error::InconsistentConstraints { message }) => {
            eprintln!("inconsistent copies (embedded): {message}")
        }
        other => panic!(
            "inconsistent copies (embedded): expected InconsistentConstraints, got {other:?}"
        ),
    }
    // The multiplier form refuses them too (its least-squares λ would hide the conflict).
    bad = bad.with_formulation(Formulation::Multipliers);
    match bad.forward_dynamics(&single.q0, &single.v0, &tau, true) {
        Err(Error::InconsistentConstraints { message }) => {
            eprintln!("inconsistent copies (multipliers): {message}")
        }
        other => panic!(
            "inconsistent copies (multipliers): expected InconsistentConstraints, got {other:?}"
        ),
    }
}
