//! Where constraint forces and declarations meet their conventions: the generalized-force unit
//! of every velocity coordinate (N for a translation, N·m for a rotation, also after the first
//! coordinate of a multi-DOF joint), the stacking and naming of rows, and the scene format's
//! documented defaults (`constraints/spec.rs`).

use crate::common;
use common::*;
use constraint_dynamics::constraints::generalized_force_unit;
use constraint_dynamics::constraints::{ConstraintSet, ConstraintSpec, Row};
use constraint_dynamics::{BaseType, Model, ModelOptions};

/// The free-flyer's linear velocities are dual to forces, its angular ones to torques, and
/// an index past the last coordinate reads as a torque.
#[test]
fn free_flyer_units_are_n_then_n_m() {
    let model = reference_disk(BaseType::Floating);
    let units: Vec<&str> = (0..7).map(|i| generalized_force_unit(&model, i)).collect();
    assert_eq!(units, ["N", "N", "N", "N·m", "N·m", "N·m", "N·m"]);
}

/// A set of two declarations stacks their rows in order: the pin's 2 rows, then the contact's 3
/// (a free-flyer can move the contact along n, so the normal row is kept); names find them.
#[test]
fn constraint_set_stacks_rows_in_declaration_order() {
    let model = reference_disk(BaseType::Floating);
    let specs = [
        ConstraintSpec::Point {
            name: "pin".into(),
            frame_a: "disk".into(),
            point_a: [0.0, 0.0, 0.1],
            frame_b: "world".into(),
            point_b: [0.0, 0.0, 0.2],
            rows: vec![Row::X, Row::Z],
            unilateral: false,
            friction: None,
        },
        disk_on_the_ground(),
    ];
    let q = [0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0];
    let set = ConstraintSet::new(&model, &specs, &q).unwrap();
    assert_eq!(set.nrows, 5);
    assert_eq!(set.ranges, [0..2, 2..5]);
    assert_eq!(
        (set.index("pin"), set.index("contact"), set.index("x")),
        (Some(0), Some(1), None)
    );
    assert_eq!(
        set.row_names(),
        ["pin/x", "pin/z", "contact/t1", "contact/t2", "contact/n"]
    );
    assert!(!set.is_empty());
}

/// The reference disk (radius 0.1 m, spin axis y) rolling on the plane z = 0.
fn disk_on_the_ground() -> ConstraintSpec {
    ConstraintSpec::Rolling {
        name: "contact".into(),
        wheel: "disk".into(),
        axis: [0.0, 1.0, 0.0],
        radius: 0.1,
        axle_offset: 0.0,
        axle_offset_turn_gain: 0.0,
        lateral: Default::default(),
        plane_normal: [0.0, 0.0, 1.0],
        plane_height: 0.0,
        friction: None,
    }
}

/// Units of joints that do not start at velocity index 0: a revolute arm (N·m) carrying a body
/// on a floating joint (3 forces, 3 torques) or a puck on a planar joint (2 forces, 1 torque).
#[test]
fn units_of_multi_dof_joints_after_the_first_coordinate() {
    let robot = |joint: &str| {
        let urdf = format!(
            r#"<robot name="arm"><link name="base"/>
  <link name="arm"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <link name="body"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <joint name="spin" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="carry" type="{joint}"><parent link="arm"/><child link="body"/><axis xyz="0 0 1"/></joint>
</robot>"#
        );
        Model::from_urdf_str(&urdf, "arm.urdf", &ModelOptions::default()).unwrap()
    };
    let units =
        |m: &Model| -> Vec<&str> { (0..m.nv).map(|i| generalized_force_unit(m, i)).collect() };
    assert_eq!(
        units(&robot("floating")),
        ["N·m", "N", "N", "N", "N·m", "N·m", "N·m"]
    );
    assert_eq!(units(&robot("planar")), ["N·m", "N", "N", "N·m"]);
}

/// The scene format's documented defaults (`constraints/spec.rs`): a point constraint holds all
/// three world axes against the world's origin, a weld all six rows in world axes, a rolling
/// contact runs on the plane z = 0.
#[test]
fn omitted_fields_take_the_documented_defaults() {
    use constraint_dynamics::constraints::Axes;
    let spec = |yaml: &str| serde_yaml::from_str::<ConstraintSpec>(yaml).unwrap();
    assert_eq!(
        spec("{name: p, kind: point, frame_a: disk}"),
        ConstraintSpec::Point {
            name: "p".into(),
            frame_a: "disk".into(),
            point_a: [0.0; 3],
            frame_b: "world".into(),
            point_b: [0.0; 3],
            rows: vec![Row::X, Row::Y, Row::Z],
            unilateral: false,
            friction: None,
        }
    );
    assert_eq!(
        spec("{name: w, kind: weld, frame_a: disk}"),
        ConstraintSpec::Weld {
            name: "w".into(),
            frame_a: "disk".into(),
            frame_b: "world".into(),
            axes: Axes::World,
            rows: vec![Row::X, Row::Y, Row::Z, Row::Rx, Row::Ry, Row::Rz],
            relative_xyz: [0.0; 3],
            relative_rpy: [0.0; 3],
        }
    );
    assert_eq!(
        spec("{name: c, kind: rolling, wheel: disk, axis: [0, 1, 0], radius: 0.1}"),
        ConstraintSpec::Rolling {
            name: "c".into(),
            wheel: "disk".into(),
            axis: [0.0, 1.0, 0.0],
            radius: 0.1,
            axle_offset: 0.0,
            axle_offset_turn_gain: 0.0,
            lateral: Default::default(),
            plane_normal: [0.0, 0.0, 1.0],
            plane_height: 0.0,
            friction: None,
        }
    );
}

/// The residuals a sample reports, by their definitions: a disk of radius 0.1 m upright (axis
/// y) with its centre 0.13 m above the plane z = 0 is 0.03 m off its normal row, its contact's
/// material point moves at v_c + ω × (−r ẑ) = (vx − r ω_y, vy + r ω_x, vz), and a knife edge
/// along the disk's y sees vy: here (0.1, −0.16, 0.05) m/s and −0.2 m/s, the largest 0.2.
#[test]
fn sample_residuals_are_the_contact_gap_and_the_slip_speed() {
    let model = reference_disk(BaseType::Floating);
    let specs = [
        disk_on_the_ground(),
        ConstraintSpec::NoSideSlip {
            name: "edge".into(),
            frame: "disk".into(),
            axis: [0.0, 1.0, 0.0],
        },
    ];
    let q = [0.2, -0.1, 0.13, 0.0, 0.0, 0.0, 1.0];
    let v = [0.3, -0.2, 0.05, 0.4, 2.0, -0.7];
    let mut sys = multiplier_system(model, &specs, &q);
    let (position, velocity) = sys.residuals(0.0, &q, &v);
    let rows = [0.1, -0.16, 0.05, -0.2];
    for (k, (got, want)) in sys.rows().jv.iter().zip(rows).enumerate() {
        assert!(
            (got - want).abs() < 1e-15,
            "row {k}: J v = {got}, not {want}"
        );
    }
    assert_eq!(sys.rows().holonomic, [false, false, true, false]);
    assert!((position - 0.03).abs() < 1e-15, "{position}");
    assert!((velocity - 0.2).abs() < 1e-15, "{velocity}");
}

/// `dynamics.baumgarte_time_constant: T` means a critically damped residual decaying as
/// e^{−t/T}: φ̈ + K_d φ̇ + K_p φ = 0 with s² + K_d s + K_p = (s + 1/T)², a double root at −1/T.
#[test]
fn a_baumgarte_time_constant_gives_a_double_root_at_minus_one_over_t() {
    use constraint_dynamics::dynamics::Baumgarte;
    for t in [0.003, 0.05, 0.1, 2.5] {
        let b = Baumgarte::from_time_constant(t);
        let (kp, kd) = (b.kp, b.kd);
        // The roots (−K_d ± √(K_d² − 4 K_p)) / 2: the discriminant vanishes to rounding.
        assert!(
            (kd * kd - 4.0 * kp).abs() <= 1e-15 * kd * kd,
            "T = {t}: K_d² − 4 K_p = {}",
            kd * kd - 4.0 * kp
        );
        let root = -kd / 2.0;
        assert!(
            (root + 1.0 / t).abs() <= 1e-15 / t,
            "T = {t}: root {root} against {}",
            -1.0 / t
        );
    }
}
