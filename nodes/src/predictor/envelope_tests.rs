//! The acceleration envelope each tick publishes at its start state, from the node's logic
//! without DDS: closed forms on the diff drive, the slip coefficient standing in for undeclared
//! friction, a floating variant of the robot checked on request, a bad envelope scene refused.

use super::tests::{node, tick};
use super::*;
use crate::msg::constraint_dynamics_msgs::AccelerationLimit;
use crate::params::CommonParams;

/// Every tick carries the acceleration envelope at its start state: the diff drive at rest has
/// docs/projection.md's closed forms, a = 2 τ_max / (r (M + 2 I_w/r²)) = 20.61856 m/s² both
/// ways and α = 2 τ_max d / (r (I_O + 2 I_w d²/r²)) = 144.5169 rad/s² both ways, the wheels'
/// effort binding each; the planar base leaves lift-off and friction unchecked.
#[test]
fn each_tick_publishes_the_envelope_of_its_start_state() {
    let mut n = node("stop");
    let t0 = Time::from_nanos(1_000_000_000);
    let o = tick(&mut n, t0);
    let m = o.limits.expect("acceleration limits");
    assert_eq!(m.header.stamp, t0);
    assert_eq!(m.header.frame_id, n.robot.base_frame());
    let closed = [20.61855670, 20.61855670, 144.5168603, 144.5168603];
    let limits = [
        &m.forward_acceleration,
        &m.forward_deceleration,
        &m.yaw_acceleration_left,
        &m.yaw_acceleration_right,
    ];
    for (l, want) in limits.into_iter().zip(closed) {
        assert_eq!(l.status, AccelerationLimit::BOUNDED);
        // The closed forms are written to 10 digits (±5e-10 relative); the core meets the exact
        // values to 4e-11 (tests/it/envelope.rs).
        assert!((l.max - want).abs() <= 1e-9 * want, "{} vs {want}", l.max);
        assert_eq!(l.binding_kinds, ["effort", "effort"]);
        assert_eq!(l.binding_names, ["left_wheel_joint", "right_wheel_joint"]);
    }
    for kind in ["lift_off", "friction"] {
        assert_eq!(m.unchecked_kinds.iter().filter(|k| *k == kind).count(), 2);
    }
    assert_eq!(o.forward_speed, 0.0);
    let diagnostics = n.diagnostics();
    let shown = diagnostics
        .iter()
        .find(|kv| kv.key == "forward deceleration limit [m/s²]")
        .expect("the braking limit on /diagnostics");
    assert!(
        shown.value.starts_with("20.6186 (effort: left_wheel_joint"),
        "{}",
        shown.value
    );
    assert!(n.warnings().is_empty(), "{:?}", n.warnings());
}

/// The floating suite's wheels declare no μ: the envelope checks their friction with
/// `slip.friction_coefficient` (nothing is left unchecked: the caster is a frictionless
/// unilateral point), a lower μ lowers the forward limit until friction binds it, and a change
/// of the parameter at run time takes effect at the next tick.
#[test]
fn contacts_without_friction_take_the_slip_coefficient_in_the_envelope() {
    let mut common = CommonParams::default();
    common.model.scene_file = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../params/suite_mobile_manipulator_floating.yaml"
    )
    .into();
    let mut params = NodeParams::<PredictorParams> {
        common,
        node: PredictorParams::default(),
    };
    params.node.covariance.propagate = false;
    let robot = Robot::load(&params.common).unwrap();
    let mut n = PredictorNode::new(robot, params.clone(), NodeLog::new("test")).unwrap();
    let forward = |n: &mut PredictorNode| {
        let m = tick(n, Time::from_nanos(1_000_000_000))
            .limits
            .expect("limits");
        assert!(m.unchecked_kinds.is_empty(), "{:?}", m.unchecked_names);
        let f = m.forward_acceleration;
        assert_eq!(f.status, AccelerationLimit::BOUNDED);
        (f.max, f.binding_kinds)
    };
    let (a_high, _) = forward(&mut n);
    params.common.slip.friction_coefficient = 0.05;
    n.set_params(params);
    let (a_low, kinds) = forward(&mut n);
    assert!(a_low < a_high, "{a_low} vs {a_high}");
    assert!(kinds.iter().all(|k| k == "friction"), "{kinds:?}");
}

/// `envelope.scene_file`: the planar suite's predictor checks its limits on the floating variant
/// of the same robot, at the predictor's state (base pose and twist, joints by name), so the
/// caster's lift-off is checked: the core's envelope of that scene at that state, to rounding.
#[test]
fn the_envelope_may_check_a_floating_variant_of_the_robot() {
    use constraint_dynamics::envelope::{
        EnvelopeData, EnvelopeModel, Reach, acceleration_envelope,
    };
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../params/");
    let mut common = CommonParams::default();
    common.model.scene_file = format!("{root}suite_mobile_manipulator.yaml");
    let mut params = NodeParams::<PredictorParams> {
        common,
        node: PredictorParams::default(),
    };
    params.node.covariance.propagate = false;
    let floating = format!("{root}suite_mobile_manipulator_floating.yaml");
    params.node.envelope.scene_file = floating.clone();
    let robot = Robot::load(&params.common).unwrap();
    let mut n = PredictorNode::new(robot, params, NodeLog::new("test")).unwrap();
    let m = tick(&mut n, Time::from_nanos(1_000_000_000))
        .limits
        .expect("limits");
    assert!(m.unchecked_kinds.is_empty(), "{:?}", m.unchecked_names);
    assert_eq!(m.forward_deceleration.binding_kinds, ["lift_off"]);
    assert_eq!(m.forward_deceleration.binding_names, ["caster_contact"]);
    // The core on the floating scene, its coordinates set by name from the planar start state
    // (the base upright at the origin, its forward speed and the joints; the planar yaw rate is
    // zero at the start).
    let scene = Scene::load(&floating).unwrap();
    let (mut q, mut v) = (scene.q0.clone(), scene.v0.clone());
    let planar = Robot::load(&{
        let mut c = CommonParams::default();
        c.model.scene_file = format!("{root}suite_mobile_manipulator.yaml");
        c
    })
    .unwrap();
    let pm = planar.model();
    for (x, names, from, planar_names) in [
        (
            &mut q,
            &scene.model.q_names,
            &planar.scene().q0,
            &pm.q_names,
        ),
        (
            &mut v,
            &scene.model.v_names,
            &planar.scene().v0,
            &pm.v_names,
        ),
    ] {
        for (i, name) in names.iter().enumerate() {
            if let Some(j) = planar_names.iter().position(|p| p == name) {
                x[i] = from[j];
            }
        }
    }
    assert_eq!(q[0..3], [0.0, 0.0, 0.0]);
    let mut sys = System::from_scene(&scene).unwrap();
    let mut elements = ForceElements::new(sys.model(), &scene.file.forces).unwrap();
    let em = EnvelopeModel::from_scene(&scene, &sys)
        .unwrap()
        .assume_friction(0.8);
    let mut ed = EnvelopeData::new(&em);
    let zero = vec![0.0; sys.model().nv];
    let mut applied = zero.clone();
    constraint_dynamics::applied::applied_generalized_force(
        &mut sys,
        &mut elements,
        (0.0, &q, &v),
        &zero,
        &mut applied,
    );
    let e = acceleration_envelope(&mut sys, &em, &mut ed, &q, &v, &applied).unwrap();
    let pairs = [
        (&m.forward_acceleration, &e.forward_acceleration),
        (&m.forward_deceleration, &e.forward_deceleration),
        (&m.yaw_acceleration_left, &e.yaw_acceleration_left),
        (&m.yaw_acceleration_right, &e.yaw_acceleration_right),
    ];
    for (got, want) in pairs {
        match want.reach {
            Reach::Bounded => {
                assert_eq!(got.status, AccelerationLimit::BOUNDED);
                let tol = 1e-12 * want.max.abs();
                assert!(
                    (got.max - want.max).abs() <= tol,
                    "{} vs {}",
                    got.max,
                    want.max
                );
            }
            Reach::Infeasible => assert_eq!(got.status, AccelerationLimit::INFEASIBLE),
            Reach::Unbounded => assert_eq!(got.status, AccelerationLimit::UNBOUNDED),
        }
    }
    // The suite's start pose holds the arm out ahead of the axle: braking is out of reach (the
    // caster behind would lift), which the planar model alone cannot say.
    assert!(
        m.forward_deceleration.max < 0.0,
        "{}",
        m.forward_deceleration.max
    );
}

/// An `envelope.scene_file` that cannot be loaded, or whose coordinates the predictor's robot
/// does not have, is refused at start, naming the file or the parameter.
#[test]
fn a_bad_envelope_scene_is_refused_by_name() {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../params/");
    for (file, expect) in [
        ("no_such_scene.yaml", "no_such_scene.yaml"),
        ("fourbar.yaml", "envelope.scene_file"),
    ] {
        let mut common = CommonParams::default();
        common.model.scene_file = format!("{root}suite_mobile_manipulator.yaml");
        let mut params = NodeParams::<PredictorParams> {
            common,
            node: PredictorParams::default(),
        };
        params.node.envelope.scene_file = format!("{root}{file}");
        let robot = Robot::load(&params.common).unwrap();
        let e = PredictorNode::new(robot, params, NodeLog::new("test"))
            .err()
            .expect("refused");
        assert!(e.to_string().contains(expect), "{file}: {e}");
    }
}
