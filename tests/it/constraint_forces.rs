//! Constraint forces in physical terms (`constraints/forces.rs`: `constraint_forces`, a velocity
//! constraint's generalized force; units, row stacking and the scene defaults are in
//! constraint_conventions.rs) against closed forms written here from Newton's laws on
//! the reference disk (`../shared/reference/urdf/disk.urdf`: m = 1 kg, COM at the origin,
//! I = diag(0.0025, 0.005, 0.0025) kg m²) and on two sliders written inline.

use crate::common;
use common::*;
use constraint_dynamics::constraints::generalized_force_unit;
use constraint_dynamics::constraints::{Constraint, ConstraintKind, ConstraintSpec, Row};
use constraint_dynamics::{BaseType, Model, ModelOptions};
use std::collections::BTreeMap;

const M: f64 = 1.0;
const IZZ: f64 = 0.0025;

/// The disk hangs from a world point 0.1 m above its centre, held on rows x and z only: at rest
/// the pin carries the weight, (0, 0, m g) on the disk at the pin, no torque.
#[test]
fn point_constraint_force_is_the_weight_at_the_pin() {
    let model = reference_disk(BaseType::Floating);
    let spec = ConstraintSpec::Point {
        name: "pin".into(),
        frame_a: "disk".into(),
        point_a: [0.0, 0.0, 0.1],
        frame_b: "world".into(),
        point_b: [0.3, -0.2, 1.1],
        rows: vec![Row::X, Row::Z],
        unilateral: false,
        friction: None,
    };
    let q = [0.3, -0.2, 1.0, 0.0, 0.0, 0.0, 1.0];
    let mut sys = multiplier_system(model, &[spec], &q);
    sys.forward_dynamics(&q, &[0.0; 6], &[0.0; 6], true)
        .unwrap();
    assert_eq!(sys.constraints().row_names(), ["pin/x", "pin/z"]);
    let f = &sys.constraint_forces()[0];
    assert_eq!(
        (f.kind, f.frame.as_str(), f.axes.as_str()),
        (ConstraintKind::Point, "disk", "world")
    );
    assert_eq!(f.rows, ["x", "z"]);
    assert_close("pin λ", &f.lambda, &[0.0, M * 9.81], 1e-15); // achieved 0 (closed form m g)
    assert_close("pin force", &f.force, &[0.0, 0.0, M * 9.81], 1e-15); // achieved 0
    assert_close("pin torque", &f.torque, &[0.0; 3], 1e-15); // floor
    assert_close("pin point", &f.point_world, &[0.3, -0.2, 1.1], 1e-15); // geometry: the pin
    assert_close(
        "disk origin",
        &f.frame_origin_world.unwrap(),
        &[0.3, -0.2, 1.0],
        1e-15,
    );
    assert_close("φ", &f.position_residual, &[0.0, 0.0], 1e-15);
}

/// Knife edge on the planar disk (blocked axis: its own y, through the COM), moving forward at u
/// while turning at ω: the edge supplies the centripetal force m u ω along the body's y, through
/// the COM, so q̈ = 0 (body-frame velocities stay constant) and the force in world axes is
/// m u ω (−sin θ, cos θ, 0).
#[test]
fn knife_edge_force_is_centripetal() {
    let model = reference_disk(BaseType::Planar);
    let spec = ConstraintSpec::NoSideSlip {
        name: "edge".into(),
        frame: "disk".into(),
        axis: [0.0, 1.0, 0.0],
    };
    let (theta, u, w) = (0.6_f64, 1.5, -0.8);
    let q = [0.4, 0.1, theta];
    let mut sys = multiplier_system(model, &[spec], &q);
    let qdd = sys
        .forward_dynamics(&q, &[u, 0.0, w], &[0.0; 3], true)
        .unwrap()
        .clone();
    assert_close("q̈", qdd.as_slice(), &[0.0; 3], 1e-15); // achieved 0
    let f = &sys.constraint_forces()[0];
    assert_eq!(f.rows, ["lateral"]);
    assert_close("λ", &f.lambda, &[M * u * w], 1e-15); // achieved 0 (closed form m u ω)
    let mag = M * u * w;
    assert_close(
        "force (world)",
        &f.force,
        &[-mag * theta.sin(), mag * theta.cos(), 0.0],
        1e-15, // achieved 0
    );
    assert_close("point", &f.point_world, &[0.4, 0.1, 0.0], 1e-15); // the frame origin
}

/// Two 1-DOF sliders along x (m₁ = 2 kg, m₂ = 3 kg, no gravity along x) coupled q₁ − q₂ = 0.1:
/// a force F on slider 1 accelerates both at F/(m₁ + m₂), and the coupling's generalized force
/// on slider 1 is λ = −m₂ F/(m₁ + m₂) (on slider 2: −λ).
#[test]
fn coupling_force_is_the_share_of_the_second_slider() {
    let urdf = r#"<robot name="sliders"><link name="base"/>
      <link name="a"><inertial><mass value="2"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
      <link name="b"><inertial><mass value="3"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
      <joint name="s1" type="prismatic"><parent link="base"/><child link="a"/><axis xyz="1 0 0"/>
        <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
      <joint name="s2" type="prismatic"><parent link="base"/><child link="b"/><axis xyz="1 0 0"/>
        <limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>"#;
    let model = Model::from_urdf_str(urdf, "sliders.urdf", &ModelOptions::default()).unwrap();
    assert_eq!(
        (0..2)
            .map(|i| generalized_force_unit(&model, i))
            .collect::<Vec<_>>(),
        ["N", "N"]
    );
    let spec = ConstraintSpec::Coupling {
        name: "gear".into(),
        joint_i: "s1".into(),
        joint_j: "s2".into(),
        a: 1.0,
        b: -1.0,
        c: 0.1,
    };
    let q = [0.3, 0.2];
    let mut sys = multiplier_system(model, &[spec], &q);
    let force = 5.0;
    let qdd = sys
        .forward_dynamics(&q, &[0.4, 0.4], &[force, 0.0], true)
        .unwrap()
        .clone();
    let a = force / 5.0;
    assert_close("q̈", qdd.as_slice(), &[a, a], 1e-15); // achieved 0 (closed form F/(m₁+m₂))
    let f = &sys.constraint_forces()[0];
    assert_eq!((f.frame.as_str(), f.axes.as_str()), ("s1+s2", "joint"));
    assert_eq!(f.frame_origin_world, None);
    assert_close("λ", &f.lambda, &[-3.0 * force / 5.0], 1e-15); // achieved 1.5e-16
    assert_close("φ", &f.position_residual, &[0.0], 1e-15); // q₁ − q₂ − 0.1 = 0
}

/// `velocity` constraints report (∂f/∂v)ᵀλ per coordinate with its unit. On the planar disk at
/// rest, f = vx − 0.5 wz and a force F along x: m v̇x = F + λ, I ẇ = −0.5 λ, v̇x = 0.5 ẇ, so
/// ẇ = F / (0.5 m + 2 I) and λ = −2 I ẇ; the forces are λ [N] on vx and −0.5 λ [N·m] on wz.
#[test]
fn velocity_constraint_generalized_force_has_units_per_coordinate() {
    let model = reference_disk(BaseType::Planar);
    assert_eq!(
        (0..3)
            .map(|i| generalized_force_unit(&model, i))
            .collect::<Vec<_>>(),
        ["N", "N", "N·m"]
    );
    let vars: BTreeMap<String, String> =
        [("vx", "v:root_joint:vx_local"), ("wz", "v:root_joint:wz")]
            .into_iter()
            .map(|(a, b)| (a.to_string(), b.to_string()))
            .collect();
    let spec = ConstraintSpec::Velocity {
        name: "servo".into(),
        expression: "vx - 0.5*wz".into(),
        variables: vars,
        virtual_displacements: Default::default(),
        dependent: vec![],
        reference_velocity: BTreeMap::new(),
    };
    let q = [0.0, 0.0, 0.2];
    let mut sys = multiplier_system(model, &[spec], &q);
    let force = 0.6;
    let qdd = sys
        .forward_dynamics(&q, &[0.0; 3], &[force, 0.0, 0.0], true)
        .unwrap()
        .clone();
    let wdot = force / (0.5 * M + 2.0 * IZZ);
    let lambda = -2.0 * IZZ * wdot;
    assert_close("q̈", qdd.as_slice(), &[0.5 * wdot, 0.0, wdot], 1e-14); // achieved 2.2e-16
    let f = &sys.constraint_forces()[0];
    assert_eq!(
        (f.frame.as_str(), f.axes.as_str()),
        ("root_joint:vx_local+root_joint:wz", "generalized")
    );
    assert_close("λ", &f.lambda, &[lambda], 1e-14); // achieved 0
    let g = f.generalized_force.as_ref().unwrap();
    let names: Vec<(&str, &str)> = g.iter().map(|x| (x.coordinate.as_str(), x.unit)).collect();
    assert_eq!(
        names,
        [("root_joint:vx_local", "N"), ("root_joint:wz", "N·m")]
    );
    // The parsed expression has the two symbols it was written with (never empty).
    match &sys.constraints().items[0] {
        Constraint::Velocity(vc) => {
            assert!(!vc.expression.is_empty());
            assert_eq!(vc.expression.len(), 2);
            // f = vx − 0.5 wz at v = (0.4, 0, 0.2): 0.3.
            assert_close(
                "f",
                &[vc.residual(&q, &[0.4, 0.0, 0.2], 0.0)],
                &[0.3],
                1e-15,
            ); // achieved 5.6e-17
        }
        other => panic!("expected a velocity constraint, got {other:?}"),
    }
    let values: Vec<f64> = g.iter().map(|x| x.value).collect();
    assert_close("(∂f/∂v)ᵀλ", &values, &[lambda, -0.5 * lambda], 1e-14); // achieved 0
}

/// The reference disk (r = 0.1 m, I_axis = ½ m r²) rolling straight down a plane of slope α
/// (normal n = (sin α, 0, cos α), height h = 0.2 m), its axis (body y) along the slope's level
/// line: the centre accelerates at a = g sin α / (1 + I/(m r²)) = ⅔ g sin α down the slope
/// d = (cos α, 0, −sin α), at any rolling speed; the contact carries the normal force m g cos α
/// and the friction m g sin α / 3 up the slope. α = 1.3 rad puts n.x > 0.9 (the other tangent
/// basis of `basis_for`). Off the plane by δ along n, the normal row's φ is δ.
#[test]
fn disk_rolls_down_an_incline_at_two_thirds_g_sin_alpha() {
    let (r, h, g) = (0.1, 0.2, 9.81);
    for alpha in [0.5_f64, 1.3] {
        let n = [alpha.sin(), 0.0, alpha.cos()];
        let d = [alpha.cos(), 0.0, -alpha.sin()];
        let spec = ConstraintSpec::Rolling {
            name: "contact".into(),
            wheel: "disk".into(),
            axis: [0.0, 1.0, 0.0],
            radius: r,
            axle_offset: 0.0,
            axle_offset_turn_gain: 0.0,
            lateral: Default::default(),
            plane_normal: n,
            plane_height: h,
            friction: None,
        };
        let c: Vec<f64> = n.iter().map(|x| (h + r) * x).collect();
        let q = [c[0], c[1], c[2], 0.0, 0.0, 0.0, 1.0];
        let mut sys = multiplier_system(reference_disk(BaseType::Floating), &[spec], &q);
        assert_eq!(
            sys.constraints().row_names(),
            ["contact/t1", "contact/t2", "contact/n"]
        );
        let a = 2.0 / 3.0 * g * alpha.sin();
        // Rolling down at u: v_c = u d, ω = (u/r) ŷ (body axes = world axes at this pose).
        for u in [0.0, 2.0] {
            let v = [u * d[0], 0.0, u * d[2], 0.0, u / r, 0.0];
            // q̈ is the derivative of the body-axes twist: the classical acceleration a d less
            // ω × v (ω = (0, w, 0) with w = u/r).
            let w = u / r;
            let qdd = sys
                .forward_dynamics(&q, &v, &[0.0; 6], true)
                .unwrap()
                .clone();
            let what = format!("α = {alpha}, u = {u}");
            assert_close(
                &format!("{what}: q̈"),
                qdd.as_slice(),
                &[
                    a * d[0] - w * u * d[2],
                    0.0,
                    a * d[2] + w * u * d[0],
                    0.0,
                    a / r,
                    0.0,
                ],
                1e-14, // achieved ≤ 1.2e-16 (closed form ⅔ g sin α)
            );
            let f = &sys.constraint_forces()[0];
            assert_close(
                &format!("{what}: normal, tangential force"),
                &[f.normal_force.unwrap(), f.tangential_force.unwrap()],
                &[g * alpha.cos(), g * alpha.sin() / 3.0],
                1e-14, // achieved ≤ 7.1e-16 (closed forms m g cos α, m g sin α / 3)
            );
            let fw: Vec<f64> = (0..3)
                .map(|k| g * alpha.cos() * n[k] - g * alpha.sin() / 3.0 * d[k])
                .collect();
            assert_close(&format!("{what}: force (world)"), &f.force, &fw, 1e-14); // achieved ≤ 4.8e-16
            let p: Vec<f64> = n.iter().map(|x| h * x).collect();
            assert_close(&format!("{what}: contact point"), &f.point_world, &p, 1e-15); // geometry
            assert_close(
                &format!("{what}: φ"),
                &f.position_residual,
                &[0.0; 3],
                1e-15,
            );
        }
        let delta = 0.003;
        let q_off = [
            c[0] + delta * n[0],
            c[1],
            c[2] + delta * n[2],
            0.0,
            0.0,
            0.0,
            1.0,
        ];
        sys.forward_dynamics(&q_off, &[0.0; 6], &[0.0; 6], true)
            .unwrap();
        let f = &sys.constraint_forces()[0];
        assert_close(
            &format!("α = {alpha}: φ off the plane"),
            &f.position_residual,
            &[0.0, 0.0, delta],
            1e-15, // achieved ≤ 5.9e-17 (δ by construction)
        );
    }
}

/// A distance constraint of L = 0.4 m (not 1: the unit vector d/|d| differs from d·|d| only
/// when |d| ≠ 1) between the disk's centre and the world point (0, 0, 1), at angle β from the
/// vertical, moving at speed u along the circle: the centre accelerates at −g sin β along the
/// tangent t = (cos β, 0, sin β) and −u²/L along n = (sin β, 0, −cos β) (towards the pivot), and
/// λ (the force along n) is −m (g cos β + u²/L).
#[test]
fn distance_pendulum_off_the_vertical() {
    let (l, g) = (0.4, 9.81);
    let model = reference_disk(BaseType::Floating);
    let spec = ConstraintSpec::Distance {
        name: "rod".into(),
        frame_a: "disk".into(),
        point_a: [0.0; 3],
        frame_b: "world".into(),
        point_b: [0.0, 0.0, 1.0],
        distance: l,
    };
    for (beta, u) in [(0.3_f64, 0.0), (-0.7, 1.2)] {
        let (n, t) = (
            [beta.sin(), 0.0, -beta.cos()],
            [beta.cos(), 0.0, beta.sin()],
        );
        let q = [l * n[0], 0.0, 1.0 + l * n[2], 0.0, 0.0, 0.0, 1.0];
        let mut sys = multiplier_system(model.clone(), std::slice::from_ref(&spec), &q);
        let v = [u * t[0], 0.0, u * t[2], 0.0, 0.0, 0.0];
        let qdd = sys
            .forward_dynamics(&q, &v, &[0.0; 6], true)
            .unwrap()
            .clone();
        let a: Vec<f64> = (0..3)
            .map(|k| -g * beta.sin() * t[k] - u * u / l * n[k])
            .collect();
        let what = format!("β = {beta}, u = {u}");
        assert_close(
            &format!("{what}: q̈"),
            qdd.as_slice(),
            &[a[0], a[1], a[2], 0.0, 0.0, 0.0],
            1e-14, // achieved ≤ 8.9e-16 (closed form of the pendulum)
        );
        assert_close(
            &format!("{what}: λ"),
            sys.multipliers().lambda.as_slice(),
            &[-M * (g * beta.cos() + u * u / l)],
            1e-14, // achieved ≤ 1.9e-16
        );
        // φ = |d| − L: 0 here, and δ with the centre moved δ further out along n.
        assert_close(
            &format!("{what}: φ"),
            sys.rows().phi.as_slice(),
            &[0.0],
            1e-15,
        ); // achieved 0; floor 1e-15
        let delta = 0.002;
        let q_out = [
            (l + delta) * n[0],
            0.0,
            1.0 + (l + delta) * n[2],
            0.0,
            0.0,
            0.0,
            1.0,
        ];
        sys.forward_dynamics(&q_out, &v, &[0.0; 6], true).unwrap();
        assert_close(
            &format!("{what}: φ at L + δ"),
            sys.rows().phi.as_slice(),
            &[delta],
            1e-15,
        ); // achieved 1.7e-18 (δ by construction)
    }
}

/// A body welded to a moving base (both free: a floating base and a floating joint 0.5 m out)
/// falls with it: at rest the pair is in free fall, q̈ = g on the base and 0 in the joint, and
/// the weld carries nothing (λ = 0).
#[test]
fn body_welded_to_a_falling_base_falls_with_it() {
    let urdf = r#"<robot name="pair">
  <link name="a"><inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.2" iyz="0" izz="0.15"/></inertial></link>
  <link name="b"><inertial><mass value="2"/><inertia ixx="0.3" ixy="0" ixz="0" iyy="0.2" iyz="0" izz="0.25"/></inertial></link>
  <joint name="free" type="floating"><parent link="a"/><child link="b"/><origin xyz="0.5 0 0"/></joint>
</robot>"#;
    let model = Model::from_urdf_str(
        urdf,
        "pair.urdf",
        &ModelOptions {
            base: BaseType::Floating,
            ..Default::default()
        },
    )
    .unwrap();
    let spec = ConstraintSpec::Weld {
        name: "w".into(),
        frame_a: "b".into(),
        frame_b: "a".into(),
        axes: constraint_dynamics::constraints::Axes::World,
        rows: vec![Row::X, Row::Y, Row::Z, Row::Rx, Row::Ry, Row::Rz],
        relative_xyz: [0.5, 0.0, 0.0],
        relative_rpy: [0.0; 3],
    };
    // Base at identity 1 m up, the joint at its zero pose (b where the weld wants it).
    let mut q = vec![0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    q.extend([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
    let mut sys = multiplier_system(model, &[spec], &q);
    let qdd = sys
        .forward_dynamics(&q, &[0.0; 12], &[0.0; 12], true)
        .unwrap()
        .clone();
    let mut expected = [0.0; 12];
    expected[2] = -9.81;
    assert_close("q̈", qdd.as_slice(), &expected, 1e-15); // achieved 1.8e-17 (free fall)
    assert_close("λ", sys.multipliers().lambda.as_slice(), &[0.0; 6], 5e-14); // achieved 9.5e-16
}
