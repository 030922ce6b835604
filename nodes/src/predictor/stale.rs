//! The predictor's stale inputs: the message naming them and what it does, logged on the
//! transitions between fresh and stale.

use super::PredictorNode;
use crate::params::StaleBehaviour;

impl PredictorNode {
    /// "odom stale (odom 0.62 s > state.timeout 0.5 s): predictions stopped".
    pub(super) fn stale_message(&self, stale: &[String]) -> String {
        let state = &self.params.common.state;
        let what = match state.stale_behaviour {
            StaleBehaviour::Warn => "predicting from the last state, covariance grown",
            StaleBehaviour::Stop => "predictions stopped",
        };
        let names: Vec<&str> = stale.iter().filter_map(|s| s.split(' ').next()).collect();
        format!(
            "{} stale ({} > state.timeout {} s): {what}",
            names.join(", "),
            stale.join(", "),
            state.timeout
        )
    }

    /// Logs the transitions between fresh and stale inputs (a WARN when they go stale, an INFO
    /// when they return), not every tick.
    pub(super) fn log_stale(&mut self, stale: Vec<String>) {
        match (self.stale.is_empty(), stale.is_empty()) {
            (true, false) => self.log.warn(&self.stale_message(&stale)),
            (false, true) => self
                .log
                .info("state inputs fresh again: predicting from them"),
            _ => {}
        }
        self.stale = stale;
    }
}
