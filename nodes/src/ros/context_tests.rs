//! Tests of `context.rs`: the network configuration from the environment, topic names.

use super::*;

fn vars<'a>(pairs: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
    move |k| {
        pairs
            .iter()
            .find(|(n, _)| *n == k)
            .map(|(_, v)| v.to_string())
    }
}

#[test]
fn network_config_from_environment() {
    assert_eq!(
        NetworkConfig::from_vars(vars(&[])).unwrap(),
        NetworkConfig {
            domain_id: 0,
            interfaces: None
        }
    );
    let c = NetworkConfig::from_vars(vars(&[
        ("ROS_DOMAIN_ID", " 42 "),
        ("CD_ROS_INTERFACES", "127.0.0.1, ::1"),
    ]))
    .unwrap();
    assert_eq!(c.domain_id, 42);
    assert_eq!(
        c.interfaces,
        Some(vec![IpAddr::from([127, 0, 0, 1]), "::1".parse().unwrap()])
    );
    let c =
        NetworkConfig::from_vars(vars(&[("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")])).unwrap();
    assert_eq!(c, NetworkConfig::loopback(0));
    // The explicit list wins over the discovery range.
    let c = NetworkConfig::from_vars(vars(&[
        ("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST"),
        ("CD_ROS_INTERFACES", "10.0.0.5"),
    ]))
    .unwrap();
    assert_eq!(c.interfaces, Some(vec![IpAddr::from([10, 0, 0, 5])]));
    assert!(matches!(
        NetworkConfig::from_vars(vars(&[("ROS_DOMAIN_ID", "300")])),
        Err(RosContextError::BadDomainId(_))
    ));
    assert!(matches!(
        NetworkConfig::from_vars(vars(&[("ROS_DOMAIN_ID", "x")])),
        Err(RosContextError::BadDomainId(_))
    ));
    assert!(matches!(
        NetworkConfig::from_vars(vars(&[("CD_ROS_INTERFACES", "eth0")])),
        Err(RosContextError::BadInterface(_))
    ));
    let c = NetworkConfig::default()
        .with_interfaces_param("localhost")
        .unwrap();
    assert_eq!(c, NetworkConfig::loopback(0));
    assert_eq!(
        NetworkConfig::default()
            .with_interfaces_param("")
            .unwrap()
            .interfaces,
        None
    );
}

#[test]
fn topic_names() {
    for (ns, n, dds) in [
        ("/", "/odom", "rt/odom"),
        ("/", "odom", "rt/odom"),
        ("/", "/a/b/c", "rt/a/b/c"),
        ("/", "a/b", "rt/a/b"),
        ("/robot", "odom", "rt/robot/odom"),
        ("/robot", "~/forces", "rt/robot/cd/forces"),
        ("/robot", "/odom", "rt/odom"),
    ] {
        let name = topic_name(ns, "cd", n).unwrap();
        let node = NodeName::new(ns, "cd").unwrap();
        assert_eq!(name.to_dds_name("rt", &node, ""), dds, "{ns} {n}");
    }
    assert!(topic_name("/", "cd", "/bad name").is_err());
    assert!(topic_name("/", "cd", "a//b").is_err());
}
