//! Which command type the predictor follows (`command.type`, `command.stamped`, the graph).

use super::{CommandMsg, CommandParams};

const TWIST: &str = "geometry_msgs::msg::dds_::Twist_";
const STAMPED: &str = "geometry_msgs::msg::dds_::TwistStamped_";

fn names(types: &[&str]) -> Vec<String> {
    types.iter().map(|s| s.to_string()).collect()
}

#[test]
fn auto_follows_the_published_type_and_defaults_to_stamped() {
    use CommandMsg::*;
    let follow = |p: &[&str], cur| CommandMsg::follow(None, &names(p), cur);
    assert_eq!(follow(&[], None), TwistStamped, "nothing published yet");
    assert_eq!(follow(&[TWIST], None), Twist);
    assert_eq!(follow(&[TWIST, TWIST], Some(TwistStamped)), Twist);
    assert_eq!(follow(&[STAMPED], Some(Twist)), TwistStamped);
    // The publisher left: keep what was followed rather than flip back.
    assert_eq!(follow(&[], Some(Twist)), Twist);
    // Both types on one topic (a misconfigured graph): no flapping either.
    assert_eq!(follow(&[TWIST, STAMPED], Some(Twist)), Twist);
    assert_eq!(follow(&[TWIST, STAMPED], None), TwistStamped);
    // Other types on the topic do not count.
    assert_eq!(
        follow(&["std_msgs::msg::dds_::String_"], None),
        TwistStamped
    );
}

#[test]
fn a_forced_type_ignores_the_graph() {
    use CommandMsg::*;
    assert_eq!(
        CommandMsg::follow(Some(Twist), &names(&[STAMPED]), None),
        Twist
    );
    assert_eq!(
        CommandMsg::follow(Some(TwistStamped), &names(&[TWIST]), Some(Twist)),
        TwistStamped
    );
}

#[test]
fn type_and_the_older_stamped_flag() {
    // Through the node's parameter parsing: an unknown `type` is refused there, naming it.
    let parse = |t: &str, stamped: bool| {
        let yaml = format!(
            "cd_predictor:\n  ros__parameters:\n    model: {{ scene_file: s.yaml }}\n    \
             command: {{ type: {t}, stamped: {stamped} }}\n"
        );
        let p = crate::ros::args::parse_params_yaml(&yaml, "/cd_predictor").unwrap();
        crate::params::NodeParams::<crate::predictor::PredictorParams>::from_parameters(&p)
            .map(|n| n.node.command)
    };
    let p = |t: &str, stamped| CommandParams {
        msg_type: serde_yaml::from_str(t).unwrap(),
        stamped,
        ..Default::default()
    };
    assert_eq!(CommandParams::default().forced_type().unwrap(), None);
    assert_eq!(
        p("twist", false).forced_type().unwrap(),
        Some(CommandMsg::Twist)
    );
    assert_eq!(
        p("twist_stamped", false).forced_type().unwrap(),
        Some(CommandMsg::TwistStamped)
    );
    assert_eq!(
        p("auto", true).forced_type().unwrap(),
        Some(CommandMsg::TwistStamped)
    );
    let e = p("twist", true).validate().unwrap_err().to_string();
    assert!(e.contains("contradicts"), "{e}");
    let e = parse("Twist", false).unwrap_err().to_string();
    assert!(
        e.contains("command.type") && e.contains("twist_stamped"),
        "{e}"
    );
}
