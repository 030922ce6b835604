//! What one periodic prediction cost, for `/diagnostics`: so that a rate below the requested
//! one comes with its reason — a prediction whose work exceeds the period (and which part of
//! it: the covariance's linearized steps, or the prediction itself) — instead of a bare rate.

use constraint_dynamics::predict::Trajectory;

use crate::msg::diagnostic_msgs::KeyValue;
use crate::node::health::kv;

/// The work of the last periodic prediction.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PredictionWork {
    /// The whole tick: prediction, forces, messages [s].
    pub tick_s: f64,
    /// Of which the covariance's propagation [s] (beside the prediction, not part of it, when
    /// `covariance_parallel`).
    pub covariance_s: f64,
    pub covariance_parallel: bool,
    /// Accepted steps, and right-hand-side evaluations (the error estimate's included).
    pub steps: usize,
    pub evaluations: usize,
    /// The covariance's linearized steps (tried ones included).
    pub covariance_linearizations: usize,
}

impl PredictionWork {
    /// The work of `traj`, in a tick that took `tick_s` [s].
    pub fn of(traj: &Trajectory, tick_s: f64) -> Self {
        PredictionWork {
            tick_s,
            covariance_s: traj.covariance_time_s,
            covariance_parallel: traj.covariance_on_worker,
            steps: traj.steps,
            evaluations: traj.evaluations + traj.estimate_evaluations,
            covariance_linearizations: traj.covariance_linearizations,
        }
    }

    /// `/diagnostics` values.
    pub fn key_values(&self) -> Vec<KeyValue> {
        vec![
            kv(
                "last tick [ms] (covariance)",
                &format!("{:.1} ({:.1})", self.tick_s * 1e3, self.covariance_s * 1e3),
            ),
            kv(
                "last prediction work",
                &format!(
                    "{} steps, {} evaluations, {} covariance linearizations",
                    self.steps, self.evaluations, self.covariance_linearizations
                ),
            ),
        ]
    }

    /// The reason for a WARN when the tick takes at least the period `period_s` [s] (the timer
    /// cannot keep the rate), naming the part that dominates and what would lower it; None
    /// when the tick fits.
    pub fn overrun(&self, period_s: f64) -> Option<String> {
        if self.tick_s.is_nan() || self.tick_s < period_s {
            return None;
        }
        let cov = self.covariance_s;
        // On its own thread the covariance overlaps the prediction: the tick waits for the
        // longer of the two.
        let (beside, prediction_s) = match self.covariance_parallel {
            true => (" on its own thread", self.tick_s),
            false => ("", self.tick_s - cov),
        };
        let remedy = if cov >= 0.5 * self.tick_s {
            format!(
                "the covariance takes {:.0} ms{beside} ({} linearized steps for {} steps of the \
                 prediction); lower `rate` or `horizon`, or set `covariance.propagate` false",
                cov * 1e3,
                self.covariance_linearizations,
                self.steps
            )
        } else {
            format!(
                "the prediction takes {:.0} ms ({} steps, {} evaluations); lower `rate` or \
                 `horizon`",
                prediction_s * 1e3,
                self.steps,
                self.evaluations
            )
        };
        Some(format!(
            "a tick takes {:.0} ms ≥ the {:.0} ms period: {remedy}",
            self.tick_s * 1e3,
            period_s * 1e3
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn work(tick_s: f64, covariance_s: f64) -> PredictionWork {
        PredictionWork {
            tick_s,
            covariance_s,
            covariance_parallel: false,
            steps: 1000,
            evaluations: 8000,
            covariance_linearizations: 1001,
        }
    }

    #[test]
    fn a_tick_within_the_period_gives_no_reason() {
        assert_eq!(work(0.099, 0.06).overrun(0.1), None);
        assert_eq!(work(f64::NAN, 0.0).overrun(0.1), None);
    }

    #[test]
    fn an_overrun_names_the_covariance_when_it_dominates() {
        let w = work(0.117, 0.07).overrun(0.1).expect("overrun");
        assert!(
            w.starts_with("a tick takes 117 ms ≥ the 100 ms period"),
            "{w}"
        );
        assert!(
            w.contains("covariance takes 70 ms (1001 linearized steps"),
            "{w}"
        );
        assert!(w.contains("`covariance.propagate` false"), "{w}");
        // On its own thread: the 90 ms it took are beside the prediction's.
        let w = PredictionWork {
            covariance_parallel: true,
            ..work(0.105, 0.09)
        };
        let w = w.overrun(0.1).expect("overrun");
        assert!(
            w.contains("covariance takes 90 ms on its own thread"),
            "{w}"
        );
    }

    #[test]
    fn an_overrun_names_the_prediction_when_it_dominates() {
        let w = work(0.25, 0.05).overrun(0.2).expect("overrun");
        assert!(
            w.contains("the prediction takes 200 ms (1000 steps, 8000 evaluations)"),
            "{w}"
        );
        assert!(!w.contains("covariance.propagate"), "{w}");
        // With the covariance beside it, the prediction is the whole tick.
        let w = PredictionWork {
            covariance_parallel: true,
            ..work(0.25, 0.05)
        };
        let w = w.overrun(0.2).expect("overrun");
        assert!(w.contains("the prediction takes 250 ms"), "{w}");
        let kvs = work(0.25, 0.05).key_values();
        assert_eq!(kvs[0].value, "250.0 (50.0)");
        assert_eq!(
            kvs[1].value,
            "1000 steps, 8000 evaluations, 1001 covariance linearizations"
        );
    }
}
