//! Markers against hand-computed geometry: arrow tips p + s·f, rotations of 90° about z,
//! footprint corners R(yaw)·c + o, wrench torques (p − o) × f.

use super::*;
use constraint_dynamics::constraints::{ConstraintKind, Contact, ContactLimits};

use crate::msg::geometry_msgs::{Pose, PoseStamped, Quaternion};

const TOL: f64 = 1e-15;

/// 90° about z: x → y, y → −x.
const RZ90: Rotation = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]];

fn style() -> MarkerStyle {
    MarkerStyle {
        force_scale: 0.01,
        arrow_width: 0.02,
        lifetime: 0.3,
        line_width: 0.01,
    }
}

fn force(name: &str, kind: ConstraintKind, frame: &str, axes: &str) -> ConstraintForce {
    ConstraintForce {
        name: name.into(),
        kind,
        frame: frame.into(),
        frame_origin_world: Some([0.0, 0.2, 0.05]),
        axes: axes.into(),
        rows: vec![],
        lambda: vec![],
        force: [0.0; 3],
        torque: [0.0; 3],
        point_world: [0.0, 0.2, 0.0],
        position_residual: vec![],
        velocity_residual: vec![],
        normal_force: None,
        tangential_force: None,
        generalized_force: None,
    }
}

fn rolling(name: &str, force_world: [f64; 3], normal: f64) -> ConstraintForce {
    let mut f = force(name, ConstraintKind::Rolling, "left_wheel", "world");
    f.force = force_world;
    f.normal_force = Some(normal);
    f.tangential_force = Some(force_world[0].hypot(force_world[1]));
    f
}

/// A wheel's contact judged at λ = (t₁, t₂, n) under μ = 0.5 (declared by none).
fn judged(lambda: [f64; 3]) -> Option<ContactState> {
    let wheel = Contact {
        name: "w".into(),
        normal: Some(2),
        tangential: vec![0, 1],
        friction: None,
        sideways_tyre: None,
    };
    let limits = ContactLimits {
        friction: Some(0.5),
        normal_force: None,
    };
    Some(wheel.judge(&lambda, 0.0, &limits, 1e-6))
}

fn rotations(frame: &str) -> Option<Rotation> {
    match frame {
        "gripper" | "left_wheel" => Some(RZ90),
        _ => None,
    }
}

fn xyz(p: &Point) -> [f64; 3] {
    [p.x, p.y, p.z]
}

fn assert_near(what: &str, a: [f64; 3], b: [f64; 3], tol: f64) {
    for i in 0..3 {
        assert!((a[i] - b[i]).abs() <= tol, "{what}: {a:?} vs {b:?}");
    }
}

#[test]
fn arrows_start_at_the_point_of_application_and_are_coloured_by_the_contacts() {
    // μ = 0.5 on N = 50 N grips up to μ N = 25 N: the first contact needs ‖(3, 4)‖ = 5 N (grips),
    // the second 30 N (slips); the third would have to pull with 10 N (lifts off).
    let mut weld = force("hold", ConstraintKind::Weld, "gripper", "gripper");
    weld.force = [2.0, 0.0, 0.0];
    weld.point_world = [1.0, 1.0, 1.0];
    let mut coupling = force("gears", ConstraintKind::Coupling, "a+b", "a+b");
    coupling.frame_origin_world = None;
    let nan = rolling("broken", [f64::NAN, 0.0, 1.0], 1.0);
    let forces = [
        rolling("grip", [3.0, 4.0, 50.0], 50.0),
        rolling("slip", [30.0, 0.0, 50.0], 50.0),
        rolling("lift", [0.0, 0.0, -10.0], -10.0),
        weld,
        coupling,
        nan,
    ];
    let contacts = [
        judged([3.0, 4.0, 50.0]),
        judged([30.0, 0.0, 50.0]),
        judged([0.0, 0.0, -10.0]),
        None,
        None,
        judged([f64::NAN, 0.0, 1.0]),
    ];
    let header = Header {
        stamp: Time::from_nanos(5),
        frame_id: "odom".into(),
    };
    let m = force_markers(&forces, &contacts, &rotations, &header, &style());
    assert_eq!(m.len(), 4, "the coupling and the NaN force are left out");
    assert_eq!(m.iter().map(|m| m.id).collect::<Vec<_>>(), [0, 1, 2, 3]);
    for a in &m {
        assert_eq!(
            (a.type_, a.action, a.ns.as_str()),
            (Marker::ARROW, 0, FORCES_NS)
        );
        assert_eq!(a.header, header);
        assert_eq!(a.points.len(), 2);
        assert_eq!((a.lifetime.sec, a.lifetime.nanosec), (0, 300_000_000));
        assert_eq!((a.scale.x, a.scale.y, a.scale.z), (0.02, 0.04, 0.06));
    }
    // tip = p + 0.01 m/N × f.
    assert_near("grip start", xyz(&m[0].points[0]), [0.0, 0.2, 0.0], 0.0);
    assert_near("grip tip", xyz(&m[0].points[1]), [0.03, 0.24, 0.5], TOL);
    assert_eq!([m[0].color, m[1].color, m[2].color], [GRIP, SLIP, SLIP]);
    // Local axes rotated 90° about z: (2, 0, 0) in the gripper is (0, 2, 0) in the world.
    assert_near("weld tip", xyz(&m[3].points[1]), [1.0, 1.02, 1.0], TOL);
    assert_eq!(m[3].color, OTHER);
    assert_eq!(m[3].text, "hold");
}

#[test]
fn a_force_in_axes_of_an_unknown_frame_is_left_out() {
    let mut f = force("x", ConstraintKind::Point, "elsewhere", "elsewhere");
    f.force = [1.0, 0.0, 0.0];
    let m = force_markers(&[f], &[None], &rotations, &Header::default(), &style());
    assert!(m.is_empty());
}

fn path(poses: &[(f64, [f64; 3], f64)]) -> Path {
    Path {
        header: Header {
            stamp: Time::default(),
            frame_id: "odom".into(),
        },
        poses: poses
            .iter()
            .map(|&(t, p, yaw)| PoseStamped {
                header: Header {
                    stamp: Time::from_nanos((t * 1e9) as i64),
                    frame_id: "odom".into(),
                },
                pose: Pose {
                    position: Point {
                        x: p[0],
                        y: p[1],
                        z: p[2],
                    },
                    orientation: Quaternion {
                        x: 0.0,
                        y: 0.0,
                        z: (0.5 * yaw).sin(),
                        w: (0.5 * yaw).cos(),
                    },
                },
            })
            .collect(),
    }
}

#[test]
fn footprint_outlines_follow_the_path_poses() {
    use std::f64::consts::FRAC_PI_2;
    let rect = [[0.2, 0.1], [-0.2, 0.1], [-0.2, -0.1], [0.2, -0.1]];
    let p = path(&[
        (0.0, [0.0, 0.0, 0.0], 0.0),
        (0.1, [0.5, 0.0, 0.0], 0.3),
        (0.2, [1.0, 2.0, 0.0], FRAC_PI_2),
        (0.3, [1.0, 2.5, 0.0], 1.0),
        (0.4, [1.0, 3.0, 0.0], -FRAC_PI_2),
    ]);
    let m = footprint_marker(&p, &rect, 0.2, Time::from_nanos(7), &style());
    assert_eq!(
        (m.type_, m.header.frame_id.as_str()),
        (Marker::LINE_LIST, "odom")
    );
    assert_eq!(m.scale.x, 0.01);
    // Poses at 0, 0.2 and 0.4 s: three closed outlines of four edges, two points each.
    assert_eq!(m.points.len(), 3 * 4 * 2);
    // The first corner at each pose: R(yaw)·(0.2, 0.1) + o.
    assert_near("t=0", xyz(&m.points[0]), [0.2, 0.1, 0.0], TOL);
    assert_near(
        "t=0.2",
        xyz(&m.points[8]),
        [1.0 - 0.1, 2.0 + 0.2, 0.0],
        1e-15,
    );
    assert_near(
        "t=0.4",
        xyz(&m.points[16]),
        [1.0 + 0.1, 3.0 - 0.2, 0.0],
        1e-15,
    );
    // Each edge ends where the next begins; the last closes the polygon.
    assert_eq!(m.points[1], m.points[2]);
    assert_eq!(m.points[7], m.points[0]);
    // 0.25 s apart: 0 and 0.3 s, and the last pose always.
    let m = footprint_marker(&p, &rect, 0.25, Time::default(), &style());
    assert_eq!(m.points.len(), 3 * 8);
    assert_near(
        "t=0.3",
        xyz(&m.points[8]),
        {
            let (s, c) = 1f64.sin_cos();
            [1.0 + 0.2 * c - 0.1 * s, 2.5 + 0.2 * s + 0.1 * c, 0.0]
        },
        1e-15,
    );
}

#[test]
fn rotation_of_a_yaw_quaternion() {
    for yaw in [0.0, 0.4, -2.5] {
        let (s, c) = f64::sin_cos(yaw);
        let r = rotation_of([0.0, 0.0, (0.5 * yaw).sin(), (0.5 * yaw).cos()]);
        let want = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]];
        for i in 0..3 {
            assert_near("row", r[i], want[i], 1e-15);
        }
    }
    // Not normalised: the same rotation.
    let r = rotation_of([0.0, 0.0, 2.0, 0.0]);
    assert_near("180° about z", r[0], [-1.0, 0.0, 0.0], 1e-15);
}

#[test]
fn wrenches_are_about_the_frame_origin_in_the_frame_axes() {
    // Contact point p = (0, 0.2, 0) under the wheel origin o = (0, 0.2, 0.05), force
    // (3, 0, 50) N in world axes, no torque about p: about o, τ = (p − o) × f = (0, −0.15, 0).
    // The wheel frame is turned 90° about z, so in its axes f = (0, −3, 50), τ = (−0.15, 0, 0).
    let mut f = rolling("left", [3.0, 0.0, 50.0], 50.0);
    f.frame = "left_wheel".into();
    let mut on_world = force("pin", ConstraintKind::Point, "world", "world");
    on_world.force = [1.0, 2.0, 3.0];
    on_world.point_world = [0.0, 0.2, 0.05];
    let mut coupling = force("gears", ConstraintKind::Coupling, "a+b", "a+b");
    coupling.frame_origin_world = None;
    let mut unknown = force("u", ConstraintKind::Point, "nowhere", "world");
    unknown.force = [1.0, 0.0, 0.0];
    let w = constraint_wrenches(
        &[f, on_world, coupling, unknown],
        &rotations,
        "odom",
        Time::from_nanos(9),
    );
    assert_eq!(w.len(), 2);
    let (name, m) = &w[0];
    assert_eq!(
        (name.as_str(), m.header.frame_id.as_str()),
        ("left", "left_wheel")
    );
    assert_eq!(m.header.stamp, Time::from_nanos(9));
    let f = &m.wrench.force;
    let t = &m.wrench.torque;
    assert_near("force", [f.x, f.y, f.z], [0.0, -3.0, 50.0], 1e-14);
    assert_near("torque", [t.x, t.y, t.z], [-0.15, 0.0, 0.0], 1e-15);
    let (name, m) = &w[1];
    assert_eq!((name.as_str(), m.header.frame_id.as_str()), ("pin", "odom"));
    assert_eq!(m.wrench.force.z, 3.0);
}

#[test]
fn constraint_names_become_topic_tokens() {
    assert_eq!(topic_token("left_wheel_contact"), "left_wheel_contact");
    assert_eq!(topic_token("arm/hold-1"), "arm_hold_1");
    assert_eq!(topic_token("2nd"), "_2nd");
    assert_eq!(topic_token(""), "_");
}
