//! The network rule of this project as a check: DDS discovery multicasts on every interface,
//! so a participant may open on non-loopback interfaces only with explicit consent.

use crate::ros::context::NetworkConfig;

/// Environment variable that allows DDS on non-loopback interfaces (like
/// `network.allow_external`).
pub const ALLOW_EXTERNAL_ENV: &str = "CD_ALLOW_EXTERNAL_NETWORK";

/// The network rule of this project as a check: a participant on all (or non-loopback)
/// interfaces is refused unless it is `allowed` (`network.allow_external`,
/// `CD_ALLOW_EXTERNAL_NETWORK=1`) or the process is `in_namespace` (a loopback-only network
/// namespace, where no other interface exists).
pub fn network_guard(
    net: &NetworkConfig,
    allowed: bool,
    in_namespace: bool,
) -> Result<(), NetworkRefused> {
    let loopback = net
        .interfaces
        .as_ref()
        .is_some_and(|ifs| !ifs.is_empty() && ifs.iter().all(|a| a.is_loopback()));
    if loopback || allowed || in_namespace {
        return Ok(());
    }
    Err(NetworkRefused(format!(
        "refusing to open DDS on {}: this machine has interfaces other than loopback. \
         Run inside a loopback-only namespace (tools/ros2/netns_run.sh), restrict with \
         -p network.interfaces:=localhost (or CD_ROS_INTERFACES=127.0.0.1), or, on a robot \
         network, allow it with -p network.allow_external:=true (or {ALLOW_EXTERNAL_ENV}=1)",
        match &net.interfaces {
            None => "all interfaces".to_string(),
            Some(ifs) => format!("{ifs:?}"),
        }
    )))
}

/// Why the network rule refused a participant (the message says how to proceed).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct NetworkRefused(pub String);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn network_guard_allows_loopback_namespaces_and_explicit_consent_only() {
        let all = NetworkConfig::default();
        let lo = NetworkConfig::loopback(0);
        let lan = NetworkConfig::default()
            .with_interfaces_param("192.168.1.20")
            .unwrap();
        assert!(network_guard(&all, false, false).is_err());
        assert!(network_guard(&lan, false, false).is_err());
        assert!(network_guard(&lo, false, false).is_ok());
        assert!(network_guard(&all, true, false).is_ok());
        assert!(network_guard(&all, false, true).is_ok());
        let e = network_guard(&all, false, false).unwrap_err().to_string();
        assert!(
            e.contains("netns_run.sh") && e.contains("allow_external"),
            "{e}"
        );
    }
}
