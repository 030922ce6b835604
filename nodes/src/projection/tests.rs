//! The projection node with a control period: the service and the command filter answer with
//! a velocity reachable within the period, as the acceleration envelope says, and name what
//! binds it.

use super::*;
use crate::params::CommonParams;
use constraint_dynamics::envelope::{EnvelopeData, EnvelopeReport, acceleration_envelope};

/// The floating cart of tests/data: two driven wheels (effort 2 N·m each, μ 0.8) and a caster
/// that pushes but never pulls, at rest.
fn node(control_period: f64) -> ProjectionNode {
    let mut common = CommonParams::default();
    common.model.scene_file = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../tests/data/cart_tall_mass.yaml"
    )
    .into();
    let mut node = ProjectionParams::default();
    node.filter.control_period = control_period;
    let params = NodeParams { common, node };
    let robot = Robot::load(&params.common).unwrap();
    ProjectionNode::new(robot, params, NodeLog::new("test")).unwrap()
}

/// The envelope at the scene's start state, by the core's acceleration problem (not the
/// projection's impulse problem).
fn envelope(n: &mut ProjectionNode) -> EnvelopeReport {
    let scene = n.robot.scene().clone();
    let mut sys = System::from_scene(&scene).unwrap();
    let em = EnvelopeModel::from_scene(&scene, &sys).unwrap();
    let mut ed = EnvelopeData::new(&em);
    let zero = vec![0.0; sys.model().nv];
    acceleration_envelope(&mut sys, &em, &mut ed, &scene.q0, &scene.v0, &zero).unwrap();
    EnvelopeReport::new(sys.model(), &em, &ed.envelope)
}

fn request(vx: f64, period: f64, q: &[f64], v_current: Vec<f64>) -> ProjectVelocityRequest {
    let mut base_twist = Twist::default();
    base_twist.linear.x = vx;
    ProjectVelocityRequest {
        use_latest_state: false,
        q: q.to_vec(),
        use_twist: true,
        base_twist,
        period,
        v_current,
        ..Default::default()
    }
}

fn pairs(kinds: &[String], names: &[String]) -> Vec<(String, String)> {
    let mut p: Vec<(String, String)> = kinds.iter().cloned().zip(names.iter().cloned()).collect();
    p.sort();
    p.dedup();
    p
}

/// From rest, a request far ahead gains Δt × the envelope's forward acceleration (effort-bound)
/// and far behind Δt × its braking limit (the caster lifting off), each naming the envelope's
/// binding limits; the cone program is solved to 1e-10, so 1e-6 relative.
#[test]
fn the_service_answers_what_the_envelope_allows_within_the_period() {
    let mut n = node(0.0);
    let env = envelope(&mut n);
    let q0 = n.robot.scene().q0.clone();
    let nv = n.robot.model().nv;
    for (vx, limit) in [
        (50.0, &env.forward_acceleration),
        (-50.0, &env.forward_deceleration),
    ] {
        let a = limit.max.unwrap();
        let want_kinds: Vec<String> = limit.binding.iter().map(|b| b.kind.to_string()).collect();
        let want_names: Vec<String> = limit.binding.iter().map(|b| b.name.clone()).collect();
        for period in [0.005, 0.02] {
            let r = n.project_velocity(&request(vx, period, &q0, vec![0.0; nv]));
            assert!(r.success, "{}", r.message);
            let want = vx.signum() * period * a;
            let rel = (r.base_twist.linear.x - want).abs() / want.abs();
            eprintln!(
                "vx {vx}, Δt {period}: Δv {:.12e} vs {want:.12e} (rel {rel:.1e}), binding {:?}",
                r.base_twist.linear.x, r.binding_names
            );
            assert!(rel < 1e-6, "{} vs {want}", r.base_twist.linear.x);
            assert_eq!(
                pairs(&r.binding_kinds, &r.binding_names),
                pairs(&want_kinds, &want_names)
            );
        }
    }
    // The start velocity is the request's: rolling at 0.1 m/s (wheels of radius 0.1 m at
    // 1 rad/s) the gain is the same.
    let mut v = vec![0.0; nv];
    v[0] = 0.1;
    v[nv - 2] = 1.0;
    v[nv - 1] = 1.0;
    let r = n.project_velocity(&request(50.0, 0.01, &q0, v));
    let want = 0.1 + 0.01 * env.forward_acceleration.max.unwrap();
    assert!((r.base_twist.linear.x - want).abs() < 1e-6 * want, "{r:?}");
    // Period 0 is the kinematic projection: nothing dynamic binds, nothing is unchecked.
    let r = n.project_velocity(&request(0.5, 0.0, &q0, vec![]));
    assert!(r.success && r.binding_kinds.is_empty() && r.unchecked_kinds.is_empty());
    assert!((r.base_twist.linear.x - 0.5).abs() < 1e-9, "{r:?}");
}

/// The filter with a control period sends what the robot can reach in one period from its
/// latest state (at rest: Δt × the envelope's forward acceleration).
#[test]
fn the_filter_sends_what_one_control_period_reaches() {
    let period = 0.02;
    let mut n = node(period);
    let env = envelope(&mut n);
    let mut cmd = Twist::default();
    cmd.linear.x = 2.0;
    let (out, resp) = n.filter_command(&cmd).unwrap();
    let want = period * env.forward_acceleration.max.unwrap();
    assert!(resp.success, "{}", resp.message);
    assert!(
        (out.linear.x - want).abs() < 1e-6 * want,
        "{} vs {want}",
        out.linear.x
    );
}

/// Bad periods and start velocities are refused, naming the field.
#[test]
fn bad_periods_and_start_velocities_name_their_field() {
    let mut n = node(0.0);
    let q0 = n.robot.scene().q0.clone();
    let nv = n.robot.model().nv;
    for period in [f64::NAN, -0.01, f64::INFINITY] {
        let r = n.project_velocity(&request(1.0, period, &q0, vec![]));
        assert!(!r.success && r.message.contains("period"), "{}", r.message);
    }
    let r = n.project_velocity(&request(1.0, 0.01, &q0, vec![0.0; nv - 1]));
    assert!(
        !r.success && r.message.contains("v_current"),
        "{}",
        r.message
    );
    let mut v = vec![0.0; nv];
    v[2] = f64::NAN;
    let r = n.project_velocity(&request(1.0, 0.01, &q0, v));
    assert!(
        !r.success && r.message.contains("v_current"),
        "{}",
        r.message
    );
}

/// A diff drive whose wheels a tyre holds sideways (`lateral: tyre`): the service answers on
/// the robot's rigid-sideways system, so a request to slide sideways gets none of it, while
/// the robot's own system (the predictor's start state) leaves the sideways creep free.
#[test]
fn a_sideways_tyre_is_held_rigid_by_the_projection() {
    let mut common = CommonParams::default();
    common.model.scene_file = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../tests/data/diff_drive_sideways_tyres.yaml"
    )
    .into();
    let params = NodeParams {
        common,
        node: ProjectionParams::default(),
    };
    let robot = Robot::load(&params.common).unwrap();
    let mut n = ProjectionNode::new(robot, params, NodeLog::new("test")).unwrap();
    assert_eq!(n.robot.system().constraints().nrows, 2);
    assert_eq!(n.robot.kinematic_system().constraints().nrows, 4);
    let q0 = n.robot.scene().q0.clone();
    let mut req = request(0.5, 0.0, &q0, vec![]);
    req.base_twist.linear.y = 0.3;
    req.base_twist.angular.z = 0.4;
    let r = n.project_velocity(&req);
    assert!(r.success, "{}", r.message);
    let t = &r.base_twist;
    assert!(t.linear.y.abs() < 1e-12, "{t:?}");
    assert!(
        (t.linear.x - 0.5).abs() < 1e-9 && (t.angular.z - 0.4).abs() < 1e-9,
        "{t:?}"
    );
}
