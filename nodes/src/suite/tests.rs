//! Planning the suite's nodes: parameters set for every node reach the nodes that have them,
//! the others ignore them, and one no node has is named.

use super::*;

/// The bundled parameter file, with `extra` ROS arguments after it.
fn args(extra: &str) -> RosArgs {
    let file = concat!(env!("CARGO_MANIFEST_DIR"), "/../params/default.yaml");
    let mut a = vec![
        "--ros-args".to_string(),
        "--params-file".into(),
        file.into(),
    ];
    a.extend(extra.split_whitespace().map(str::to_string));
    RosArgs::parse(a).unwrap()
}

fn param<'a>(plans: &'a [Plan], node: &str, name: &str) -> Option<&'a ParameterValue> {
    let p = plans.iter().find(|p| p.name == node).expect("planned");
    p.ros_params.get(name)
}

#[test]
fn a_parameter_for_every_node_reaches_the_nodes_that_have_it() {
    let (plans, unused) = plan(
        &args("-p envelope.velocity_smoother:=velocity_smoother -p no_such.parameter:=1"),
        None,
    )
    .unwrap();
    assert_eq!(plans.len(), 4);
    assert_eq!(
        param(&plans, "cd_predictor", "envelope.velocity_smoother"),
        Some(&ParameterValue::String("velocity_smoother".into()))
    );
    for node in ["cd_forces", "cd_projection", "cd_prediction"] {
        assert_eq!(param(&plans, node, "envelope.velocity_smoother"), None);
        assert_eq!(param(&plans, node, "no_such.parameter"), None);
    }
    // Only the name no node has is reported.
    assert_eq!(unused, vec!["no_such.parameter".to_string()]);
    // A shared parameter every kind has still reaches all.
    let (plans, unused) = plan(&args("-p slip.friction_coefficient:=0.5"), None).unwrap();
    assert!(unused.is_empty(), "{unused:?}");
    for p in &plans {
        assert_eq!(
            p.ros_params.get("slip.friction_coefficient"),
            Some(&ParameterValue::Double(0.5)),
            "{}",
            p.name
        );
    }
}

#[test]
fn alone_a_node_reports_what_it_does_not_have() {
    let (plans, unused) = plan(
        &args("-p envelope.velocity_smoother:=velocity_smoother"),
        Some(NodeKind::Forces),
    )
    .unwrap();
    assert_eq!(plans.len(), 1);
    assert_eq!(unused, vec!["envelope.velocity_smoother".to_string()]);
}

#[test]
fn a_parameter_for_one_node_that_it_does_not_have_is_an_error() {
    for rule in [
        "cd_forces:envelope.velocity_smoother:=velocity_smoother",
        "/cd_forces:envelope.velocity_smoother:=velocity_smoother",
    ] {
        let e = plan(&args(&format!("-p {rule}")), None)
            .err()
            .expect("refused")
            .to_string();
        assert!(
            e.contains("cd_forces") && e.contains("unknown field `envelope`"),
            "{rule}: {e}"
        );
    }
}
