//! Parameter parsing: shared sections, nesting, unknown keys and named bad values.

use super::*;
use crate::forces::ForcesParams;
use crate::predictor::PredictorParams;
use crate::projection::ProjectionParams;
use crate::ros::args::parse_params_yaml;

/// A set request of one parameter.
pub(crate) fn one(name: &str, value: ParameterValue) -> [Parameter; 1] {
    [Parameter {
        name: name.into(),
        value,
    }]
}

#[test]
fn defaults_validate_once_a_scene_is_given() {
    let mut p = NodeParams::<ProjectionParams>::default();
    let e = p.validate().unwrap_err().to_string();
    assert!(e.contains("model.scene_file"), "{e}");
    p.common.model.scene_file = "x.yaml".into();
    p.validate().unwrap();
    let mut p = NodeParams::<PredictorParams>::default();
    p.common.model.scene_file = "x.yaml".into();
    p.validate().unwrap();
    for kind in NodeKind::ALL {
        assert_eq!(NodeKind::from_key(kind.key()), Some(kind));
    }
}

#[test]
fn nested_keys_shared_section_and_unknown_keys() {
    let yaml = r#"
/**:
  ros__parameters:
    model: { scene_file: s.yaml }
    slip: { friction_coefficient: 0.5 }
cd_predictor:
  ros__parameters:
    rate: 20.0
    command: { stamped: true, fallback: hold }
cd_forces:
  ros__parameters:
    rate: 20.0
"#;
    let p = parse_params_yaml(yaml, "/cd_predictor").unwrap();
    let pp = NodeParams::<PredictorParams>::from_parameters(&p).unwrap();
    assert_eq!(pp.node.rate, 20.0);
    assert_eq!(pp.common.slip.friction_coefficient, 0.5);
    assert!(pp.node.command.stamped);
    assert_eq!(pp.node.command.fallback, Fallback::Hold);
    assert_eq!(pp.common.model.scene_file, "s.yaml");
    assert_eq!(pp.common.state.joint_states_topic, "joint_states");
    // `rate` is not a parameter of the forces node.
    let p = parse_params_yaml(yaml, "/cd_forces").unwrap();
    let e = NodeParams::<ForcesParams>::from_parameters(&p)
        .unwrap_err()
        .to_string();
    assert!(e.contains("unknown field `rate`"), "{e}");
}

#[test]
fn bad_values_are_named() {
    let cases = [
        ("rate: 0.0", "rate"),
        (
            "covariance: { position_floor: 0.0 }",
            "covariance.position_floor",
        ),
        ("command: { fallback: brake }", "command.fallback"),
        (
            "slip: { friction_coefficient: -1.0 }",
            "slip.friction_coefficient",
        ),
        ("network: { interfaces: eth0 }", "network.interfaces"),
        ("state: { timeout: 0.0 }", "state.timeout"),
        (
            "state: { stale_behaviour: ignore }",
            "state.stale_behaviour",
        ),
        (
            "state: { joint_noise: { position: -0.1 } }",
            "state.joint_noise.position",
        ),
        (
            "state: { joint_noise: { joints: { arm_elbow: [0.1] } } }",
            "state.joint_noise.joints.arm_elbow",
        ),
        ("envelope: { dead_band: 1.0 }", "envelope.dead_band"),
        ("envelope: { min_interval: 0.0 }", "envelope.min_interval"),
        ("envelope: { linear_floor: -0.1 }", "envelope.linear_floor"),
        (
            "envelope: { angular_floor: .nan }",
            "envelope.angular_floor",
        ),
        (
            "envelope: { velocity_smoother: 'smoother node' }",
            "envelope.velocity_smoother",
        ),
        (
            "envelope: { enabled: false, velocity_smoother: velocity_smoother }",
            "envelope.velocity_smoother",
        ),
    ];
    for (body, name) in cases {
        let yaml = format!(
            "cd_predictor:\n  ros__parameters:\n    model: {{ scene_file: s.yaml }}\n    {body}\n"
        );
        let p = parse_params_yaml(&yaml, "/cd_predictor").unwrap();
        let e = NodeParams::<PredictorParams>::from_parameters(&p)
            .unwrap_err()
            .to_string();
        assert!(e.contains(name), "{body}: {e}");
    }
}

#[test]
fn ros_parameters_round_trip() {
    let mut p = NodeParams::<ProjectionParams>::default();
    p.common.model.scene_file = "s.yaml".into();
    let ros = p.to_ros();
    let get = |n: &str| ros.iter().find(|(k, _)| k == n).map(|(_, v)| v.clone());
    assert_eq!(
        get("model.scene_file"),
        Some(ParameterValue::String("s.yaml".into()))
    );
    assert_eq!(
        get("acceleration_limits.values"),
        Some(ParameterValue::DoubleArray(vec![1.0, 2.0]))
    );
    assert_eq!(get("filter.enabled"), Some(ParameterValue::Boolean(false)));
    let mut params = Parameters::default();
    params.values.extend(ros);
    let back = NodeParams::<ProjectionParams>::from_parameters(&params).unwrap();
    assert_eq!(back, p);
}

#[test]
fn run_time_changes_only_of_dynamic_parameters() {
    let mut p = NodeParams::<PredictorParams>::default();
    p.common.model.scene_file = "s.yaml".into();
    let mut current = Parameters::default();
    current.values.extend(p.to_ros());
    let next = NodeParams::<PredictorParams>::updated(
        &current,
        &one("horizon", ParameterValue::Double(2.0)),
        None,
    )
    .unwrap();
    assert_eq!(next.node.horizon, 2.0);
    let e = NodeParams::<PredictorParams>::updated(
        &current,
        &one("rate", ParameterValue::Double(5.0)),
        None,
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("'rate' cannot change while the node runs"),
        "{e}"
    );
    let e = NodeParams::<PredictorParams>::updated(
        &current,
        &one("use_sim_time", ParameterValue::Boolean(true)),
        None,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("use_sim_time"), "{e}");
    // Dynamic, but out of range: refused with the name.
    let e = NodeParams::<PredictorParams>::updated(
        &current,
        &one("covariance.twist_floor", ParameterValue::Double(-1.0)),
        None,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("covariance.twist_floor"), "{e}");
}

#[test]
fn namespaced_example_follows_rcl_key_rules() {
    // params/namespaced.yaml: `/robot1/cd_predictor` and `/**` apply in /robot1; the bare
    // `cd_predictor:` key means /cd_predictor and must not.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../params/namespaced.yaml");
    let text = std::fs::read_to_string(&path).unwrap();
    let ns = parse_params_yaml(&text, "/robot1/cd_predictor").unwrap();
    let p = NodeParams::<PredictorParams>::from_parameters(&ns).unwrap();
    assert_eq!(p.node.rate, 10.0);
    assert_eq!(p.node.command.msg_type, CommandType::Auto);
    assert_eq!(p.node.command.forced_type().unwrap(), None);
    assert_eq!(p.common.state.odom_topic, "odom");
    assert_eq!(p.common.frames.odom_frame, "robot1/odom");
    let root = parse_params_yaml(&text, "/cd_predictor").unwrap();
    let p = NodeParams::<PredictorParams>::from_parameters(&root).unwrap();
    assert_eq!(p.node.rate, 1.0);
    // Every kind accepts the shared section in the namespace.
    let forces = parse_params_yaml(&text, "/robot1/cd_forces").unwrap();
    NodeParams::<ForcesParams>::from_parameters(&forces).unwrap();
}

#[test]
fn relative_default_topics_resolve_in_the_namespace() {
    use crate::ros::args::RosArgs;
    let p = NodeParams::<PredictorParams>::default();
    let args = RosArgs::parse(["x", "--ros-args", "-r", "__ns:=/robot1"]).unwrap();
    let ns = args.namespace_or("/");
    let topic = |t: &str| args.resolve_topic(ns, "cd_predictor", t);
    assert_eq!(topic(&p.common.state.odom_topic), "/robot1/odom");
    assert_eq!(
        topic(&p.common.state.joint_states_topic),
        "/robot1/joint_states"
    );
    assert_eq!(topic(&p.node.command.topic), "/robot1/cmd_vel");
    assert_eq!(
        topic(&p.common.model.robot_description_topic),
        "/robot1/robot_description"
    );
    assert_eq!(
        topic("~/predicted_odom"),
        "/robot1/cd_predictor/predicted_odom"
    );
    // An absolute name is used as given.
    assert_eq!(topic("/odom"), "/odom");
}

/// Per-joint noise from a parameter file: dotted names of a map, typed; the others take the
/// group's default.
#[test]
fn joint_noise_by_name() {
    let yaml = "cd_predictor:\n  ros__parameters:\n    model: { scene_file: s.yaml }\n    \
                state: { timeout: 0.25, stale_behaviour: warn, joint_noise: { position: 0.001, \
                joints: { arm_elbow: [0.002, 0.03] } } }\n";
    let p = parse_params_yaml(yaml, "/cd_predictor").unwrap();
    let pp = NodeParams::<PredictorParams>::from_parameters(&p).unwrap();
    let st = &pp.common.state;
    assert_eq!(st.timeout, 0.25);
    assert_eq!(st.stale_behaviour, crate::params::StaleBehaviour::Warn);
    assert_eq!(st.joint_noise.of("arm_elbow"), (0.002, 0.03));
    assert_eq!(st.joint_noise.of("arm_wrist"), (0.001, 0.0));
    let names: Vec<String> = pp.to_ros().into_iter().map(|(n, _)| n).collect();
    assert!(
        names.contains(&"state.joint_noise.joints.arm_elbow".to_string()),
        "{names:?}"
    );
}

#[test]
fn payload_group_is_typed_named_and_changeable_on_every_kind() {
    let cases = [
        ("payload: { mass: 2.0 }", "payload.frame"),
        ("payload: { frame: tool0, mass: -2.0 }", "payload.mass"),
        (
            "payload: { frame: tool0, mass: 2.0, com: [0.1, 0.2] }",
            "payload.com",
        ),
        (
            "payload: { frame: tool0, mass: 2.0, inertia: [0.3, 0.0, 0.0, 0.1, 0.0, 0.1] }",
            "payload.inertia",
        ),
        (
            "payload: { frame: tool0, masss: 2.0 }",
            "unknown field `masss`",
        ),
    ];
    for (body, name) in cases {
        let yaml = format!(
            "cd_forces:\n  ros__parameters:\n    model: {{ scene_file: s.yaml }}\n    {body}\n"
        );
        let p = parse_params_yaml(&yaml, "/cd_forces").unwrap();
        let e = NodeParams::<ForcesParams>::from_parameters(&p)
            .unwrap_err()
            .to_string();
        assert!(e.contains(name), "{body}: {e}");
    }
    // Default: the scene's payload; a frame with mass 0 is "none".
    let mut p = NodeParams::<ProjectionParams>::default();
    p.common.model.scene_file = "s.yaml".into();
    assert_eq!(p.common.payload.payload().unwrap(), None);
    let mut current = Parameters::default();
    current.values.extend(p.to_ros());
    let next = NodeParams::<ProjectionParams>::updated(
        &current,
        &one("payload.frame", ParameterValue::String("tool0".into())),
        None,
    )
    .unwrap();
    let none = next.common.payload.payload().unwrap().unwrap();
    assert!(none.is_none() && none.frame == "tool0");
    current.values.insert(
        "payload.frame".into(),
        ParameterValue::String("tool0".into()),
    );
    let next = NodeParams::<ProjectionParams>::updated(
        &current,
        &one("payload.mass", ParameterValue::Double(2.0)),
        None,
    )
    .unwrap();
    let p = next.common.payload.payload().unwrap().unwrap();
    assert_eq!((p.frame.as_str(), p.mass), ("tool0", 2.0));
    assert_eq!(p.describe(), "2.0 kg on tool0");
}
