//! Replaying a recorded drive: predictions from its recorded states under its recorded
//! commands, scored against what it recorded next (docs/logs.md).
//!
//! - `series.rs`: the recording as plain time series (no message format);
//! - `start.rs`: a start state at t0, assembled and projected as the predictor node does;
//! - `evaluate.rs`: predictions every `every` seconds over each horizon, their errors against
//!   the reference poses and the covariance's coverage, the starts spread over threads;
//! - `replayer.rs`: one thread's share of the starts, with its own predictor;
//! - `record.rs`: the replay's settings, and one prediction scored against the reference;
//! - `stats.rs`: the order statistics, χ²(3) regions and NEES.
//!
//! Nothing here reads a file: a log reader (the nodes crate's rosbag2 reader) fills a
//! [`Recording`].

mod evaluate;
mod record;
mod replayer;
mod series;
mod start;
pub mod stats;

pub use evaluate::{Evaluation, HorizonSummary, evaluate};
pub use record::{CovarianceFloors, EvaluationSettings, PredictionRecord};
pub use series::{JointStates, JointTracks, Nanos, Odometry, Recording, Series, show_stamp};
pub use start::{StartAssembler, StartState};

/// Why a recording cannot be replayed. Every variant names the series (topic) and the time:
/// seconds from the recording's start, and the stamp itself (`sec.nanosec`).
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// A series the replay needs has no sample.
    #[error("{series}: no messages")]
    Empty {
        /// The series (topic).
        series: String,
    },
    /// Time goes back within a series.
    #[error("{series}: time goes back by {back_s:.3} s at {at_s:.3} s (stamp {stamp})")]
    TimeJump {
        /// The series (topic).
        series: String,
        /// When [s from the recording's start].
        at_s: f64,
        /// The stamp of the sample that goes back.
        stamp: String,
        /// By how much [s].
        back_s: f64,
    },
    /// A state input or the reference stops for longer than allowed.
    #[error(
        "{series}: no message for {gap_s:.3} s after {after_s:.3} s (stamp {stamp}); at most \
         {max_gap_s} s is allowed"
    )]
    Gap {
        /// The series (topic).
        series: String,
        /// Where the gap starts [s from the recording's start].
        after_s: f64,
        /// The stamp before the gap.
        stamp: String,
        /// Its length [s].
        gap_s: f64,
        /// The longest gap allowed [s].
        max_gap_s: f64,
    },
    /// A sample cannot be used.
    #[error("{series}: message at {at_s:.3} s (stamp {stamp}): {what}")]
    BadSample {
        /// The series (topic).
        series: String,
        /// When [s from the recording's start].
        at_s: f64,
        /// Its stamp.
        stamp: String,
        /// What is wrong with it.
        what: String,
    },
    /// No sample of a state input at or before a start time.
    #[error("{series}: no message at or before the start at {at_s:.3} s (stamp {stamp})")]
    NoStart {
        /// The series (topic).
        series: String,
        /// The start [s from the recording's start].
        at_s: f64,
        /// Its stamp.
        stamp: String,
    },
    /// The start state cannot be projected onto the constraints.
    #[error("start state at {at_s:.3} s (stamp {stamp}): {source}")]
    Start {
        /// The start [s from the recording's start].
        at_s: f64,
        /// Its stamp.
        stamp: String,
        /// The core's reason.
        source: Box<crate::Error>,
    },
    /// A prediction failed (other than by its error bound, which is rerun without it).
    #[error("prediction from {at_s:.3} s (stamp {stamp}) over {horizon_s} s: {source}")]
    Prediction {
        /// The start [s from the recording's start].
        at_s: f64,
        /// Its stamp.
        stamp: String,
        /// The horizon [s].
        horizon_s: f64,
        /// The core's reason.
        source: Box<crate::Error>,
    },
    /// The evaluation's settings cannot be used.
    #[error("{0}")]
    Settings(String),
    /// The scene cannot be replayed.
    #[error(transparent)]
    Scene(#[from] crate::Error),
}
