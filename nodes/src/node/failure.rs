//! A node whose configuration or activation failed says why on `/diagnostics` (ERROR, the
//! node's fully qualified name, the error) until a transition succeeds, so a monitor sees a
//! node that is down, and not only one that is silent. While active a node publishes its
//! health instead ([`super::health`]).

use std::time::{Duration, Instant};

use ros2_client::Publisher;

use crate::error::NodeError;
use crate::msg::builtin_interfaces::Time;
use crate::msg::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus};
use crate::msg::std_msgs::Header;
use crate::node::health::kv;
use crate::ros::context::{RosNode, qos};
use crate::ros::logging::NodeLog;

/// The last failed transition, published every `period` until a transition succeeds.
pub struct Failure {
    status: DiagnosticStatus,
    publisher: Publisher<DiagnosticArray>,
    period: Duration,
    next: Instant,
}

impl Failure {
    /// The status of node `fqn`, now in lifecycle state `state`, after `what` (`configure`)
    /// failed with `error`; published at once and then every `period`.
    pub fn new(
        ros: &mut RosNode,
        fqn: &str,
        what: &str,
        state: &str,
        error: &NodeError,
        period: Duration,
    ) -> Result<Failure, NodeError> {
        let publisher = ros.publisher::<DiagnosticArray>("/diagnostics", &qos::reliable(10))?;
        let status = DiagnosticStatus {
            level: DiagnosticStatus::ERROR,
            name: fqn.to_string(),
            message: format!("{what} failed: {error}"),
            hardware_id: String::new(),
            values: vec![kv("lifecycle state", state)],
        };
        Ok(Failure {
            status,
            publisher,
            period,
            next: Instant::now(),
        })
    }

    /// Publishes the status when it is due.
    pub fn report(&mut self, log: &NodeLog) {
        if Instant::now() < self.next {
            return;
        }
        self.next = Instant::now() + self.period;
        let msg = DiagnosticArray {
            header: Header {
                stamp: Time::now(),
                frame_id: String::new(),
            },
            status: vec![self.status.clone()],
        };
        if let Err(e) = self.publisher.publish(msg) {
            log.warn(&format!("publish diagnostics: {e:?}"));
        }
    }
}
