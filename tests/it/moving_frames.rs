//! Constraints between two moving bodies (a floating base and a body on a floating joint):
//! γ = J̇ v against differences of J v, and a weld that makes the pair one rigid body, against
//! the composite body's closed form.

use crate::common;
use common::*;
use constraint_dynamics::constraints::{Axes, ConstraintSet, ConstraintSpec, Row};
use constraint_dynamics::dynamics::{Baumgarte, Formulation};
use constraint_dynamics::{BaseType, Model, ModelOptions, System};
use nalgebra::{DVector, UnitQuaternion};

/// Two free bodies: a on a floating base (m = 1 kg, I = diag(0.1, 0.2, 0.15)), b on a floating
/// joint 0.5 m out along x (m = 2 kg, I = diag(0.3, 0.2, 0.25)), COMs at the link origins.
fn pair() -> Model {
    let urdf = r#"<robot name="pair">
  <link name="a"><inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.2" iyz="0" izz="0.15"/></inertial></link>
  <link name="b"><inertial><mass value="2"/><inertia ixx="0.3" ixy="0" ixz="0" iyy="0.2" iyz="0" izz="0.25"/></inertial></link>
  <joint name="free" type="floating"><parent link="a"/><child link="b"/><origin xyz="0.5 0 0"/></joint>
</robot>"#;
    Model::from_urdf_str(
        urdf,
        "pair.urdf",
        &ModelOptions {
            base: BaseType::Floating,
            ..Default::default()
        },
    )
    .unwrap()
}

/// γ is J̇ v, the rate of the constraint velocity J(q) v along q̇ = G(q) v at constant v
/// (q̈ = 0), checked against a Richardson central difference of J v for welds to a moving,
/// turned frame in world and in local axes, a point and a distance between the two bodies,
/// at a state off the constraints (J v ≠ 0: a relative velocity, which the local axes' term
/// −ω_B × (R_Bᵀ J v) acts on).
#[test]
fn gamma_is_the_rate_of_the_constraint_velocity() {
    let model = pair();
    let weld = |axes, a: &str, b: &str| ConstraintSpec::Weld {
        name: format!("w_{axes:?}_{a}{b}"),
        frame_a: a.into(),
        frame_b: b.into(),
        axes,
        rows: vec![Row::X, Row::Y, Row::Z, Row::Rx, Row::Ry, Row::Rz],
        relative_xyz: [0.4, 0.1, -0.2],
        relative_rpy: [0.2, -0.3, 0.5],
    };
    let specs = [
        weld(Axes::World, "b", "a"),
        weld(Axes::Local, "b", "a"),
        // B = b, the body on the joint: its angular acceleration at q̈ = 0 (ω_a × ω_rel) is not
        // zero, as the root's is.
        weld(Axes::World, "a", "b"),
        weld(Axes::Local, "a", "b"),
        ConstraintSpec::Point {
            name: "p".into(),
            frame_a: "b".into(),
            point_a: [0.1, 0.0, 0.05],
            frame_b: "a".into(),
            point_b: [0.6, 0.0, 0.0],
            rows: vec![Row::X, Row::Y, Row::Z],
            unilateral: false,
            friction: None,
        },
        ConstraintSpec::Distance {
            name: "d".into(),
            frame_a: "b".into(),
            point_a: [0.0, 0.1, 0.0],
            frame_b: "a".into(),
            point_b: [0.0, 0.0, 0.2],
            distance: 0.5,
        },
    ];
    let base = UnitQuaternion::from_euler_angles(0.4, -0.6, 1.1);
    let joint = UnitQuaternion::from_euler_angles(-0.3, 0.2, 0.7);
    let mut q = q_at([0.1, -0.2, 1.0], &base);
    q.extend(q_at([0.05, 0.1, -0.1], &joint));
    let v = [
        0.3, -0.5, 0.2, 0.9, -0.4, 0.6, -0.2, 0.4, 0.1, -0.7, 0.5, 0.8,
    ];
    let set = ConstraintSet::new(&model, &specs, &q).unwrap();
    let mut sys = System::new(model, set, Baumgarte::default(), Formulation::Multipliers);
    let mut jv_at = |h: f64| {
        let mut qh = vec![0.0; q.len()];
        sys.model().integrate(&q, &v, h, &mut qh);
        sys.evaluate_rows(sys.rows().t, &qh, &v);
        sys.rows().jv.clone()
    };
    let d = |h: f64, jv_at: &mut dyn FnMut(f64) -> DVector<f64>| (jv_at(h) - jv_at(-h)) / (2.0 * h);
    let h = 1e-3;
    let rate = (d(h / 2.0, &mut jv_at) * 4.0 - d(h, &mut jv_at)) / 3.0;
    let jv0 = jv_at(0.0);
    assert!(
        jv0.amax() > 0.1,
        "off the constraints: |J v| = {}",
        jv0.amax()
    );
    assert_close(
        "γ vs d/dt (J v)",
        sys.rows().gamma.as_slice(),
        rate.as_slice(),
        5e-11,
    ); // achieved 9.2e-13 (Richardson, h = 1e-3)
}

/// A body welded to a moving base (both free: a floating base a, and b on a floating joint
/// 0.5 m out along x) turns with it as one rigid body. A couple τ on the base at rest: the
/// COM c = (1/3, 0, 0) falls at g, and α = I_c⁻¹ τ with the composite inertia about c,
/// I_c = I_a + I_b + diag(0, s, s), s = m_a (1/3)² + m_b (1/6)² = 1/6 (Steiner); the base
/// origin accelerates at g + α × (−1/3, 0, 0) and the joint does not move (q̈ = 0).
#[test]
fn body_welded_to_a_moving_base_turns_with_it() {
    let model = pair();
    let spec = ConstraintSpec::Weld {
        name: "w".into(),
        frame_a: "b".into(),
        frame_b: "a".into(),
        axes: Axes::World,
        rows: vec![Row::X, Row::Y, Row::Z, Row::Rx, Row::Ry, Row::Rz],
        relative_xyz: [0.5, 0.0, 0.0],
        relative_rpy: [0.0; 3],
    };
    let mut q = vec![0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    q.extend([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
    let set = ConstraintSet::new(&model, &[spec], &q).unwrap();
    let mut sys = System::new(model, set, Baumgarte::default(), Formulation::Multipliers);
    let couple = [0.3, -0.5, 0.8];
    let mut tau = [0.0; 12];
    tau[3..6].copy_from_slice(&couple);
    let qdd = sys
        .forward_dynamics(&q, &[0.0; 12], &tau, true)
        .unwrap()
        .clone();
    let s = 1.0 / 6.0;
    let alpha = [
        couple[0] / 0.4,
        couple[1] / (0.4 + s),
        couple[2] / (0.4 + s),
    ];
    let mut expected = [0.0; 12];
    expected[..6].copy_from_slice(&[
        0.0,
        -alpha[2] / 3.0,
        -9.81 + alpha[1] / 3.0,
        alpha[0],
        alpha[1],
        alpha[2],
    ]);
    assert_close("q̈", qdd.as_slice(), &expected, 1e-14); // achieved 1.8e-16 (rigid pair)
}
