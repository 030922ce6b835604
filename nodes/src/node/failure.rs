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
    /// The status of node `fqn` after transition `what.0` (`configure`) failed with `what.2`,
    /// leaving it in lifecycle state `what.1`; published at once and then every `period` [s]
    /// (1 s if unknown). `None` (with a warning) if the publisher cannot be made.
    pub fn start(
        ros: &mut RosNode,
        fqn: &str,
        what: (&str, &str, &NodeError),
        period: Option<f64>,
        log: &NodeLog,
    ) -> Option<Failure> {
        let (transition, state, error) = what;
        let publisher = match ros.publisher::<DiagnosticArray>("/diagnostics", &qos::reliable(10)) {
            Ok(p) => p,
            Err(e) => {
                log.warn(&format!("/diagnostics for the failed {transition}: {e}"));
                return None;
            }
        };
        let status = DiagnosticStatus {
            level: DiagnosticStatus::ERROR,
            name: fqn.to_string(),
            message: format!("{transition} failed: {error}"),
            hardware_id: String::new(),
            values: vec![kv("lifecycle state", state)],
        };
        let mut f = Failure {
            status,
            publisher,
            period: Duration::from_secs_f64(period.unwrap_or(1.0)),
            next: Instant::now(),
        };
        f.report(log);
        Some(f)
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
