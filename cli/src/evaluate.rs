//! `evaluate`: how well a scene predicts a recorded drive (docs/logs.md). Reads the bag
//! (`constraint_dynamics_nodes::bag`), replays it (`constraint_dynamics::replay`) and prints the
//! errors per horizon with the covariance's coverage.

use constraint_dynamics::model::base_covariance::JointSigma;
use constraint_dynamics::replay::{CovarianceFloors, EvaluationSettings, Recording, evaluate};
use constraint_dynamics::{Error, Result};
use constraint_dynamics_nodes::bag::{BagTopics, read_recording};
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct EvaluateArgs {
    /// Scene file (YAML).
    #[arg(long)]
    scene: PathBuf,
    /// The recorded drive: a rosbag2 `.mcap` file, or a bag directory with metadata.yaml.
    #[arg(long)]
    bag: PathBuf,
    /// Horizons [s], comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "0.25,0.5,1,2")]
    horizons: Vec<f64>,
    #[command(flatten)]
    replay: ReplayArgs,
    /// Write plots into this directory: the errors against the horizon
    /// (errors_vs_horizon.png) and, per horizon, the predicted 95 % position ellipses over the
    /// reference path (ellipses_<h>s.png).
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Also print every prediction (`records`: start, horizon, predicted and reference pose with
    /// their covariances, errors, NEES).
    #[arg(long)]
    records: bool,
}

/// How a recorded drive is read and replayed (shared by `evaluate` and `calibrate`).
#[derive(clap::Args)]
pub struct ReplayArgs {
    /// Period of the start times [s].
    #[arg(long, default_value_t = 0.5)]
    pub every: f64,
    /// Odometry topic (nav_msgs/Odometry): the start states' base.
    #[arg(long, default_value = "/odom")]
    pub odom_topic: String,
    /// Joint-state topic (sensor_msgs/JointState): the start states' joints.
    #[arg(long, default_value = "/joint_states")]
    pub joint_states_topic: String,
    /// Command topic (geometry_msgs/Twist or TwistStamped).
    #[arg(long, default_value = "/cmd_vel")]
    pub cmd_vel_topic: String,
    /// Score against this nav_msgs/Odometry topic (e.g. a simulator's ground truth) instead of
    /// the odometry topic.
    #[arg(long)]
    pub truth_topic: Option<String>,
    /// σ added to the predicted x and y in quadrature [m] (the predictor node's
    /// covariance.position_floor).
    #[arg(long, default_value_t = 1e-3)]
    pub position_floor: f64,
    /// σ added to the predicted yaw in quadrature [rad] (covariance.orientation_floor).
    #[arg(long, default_value_t = 1e-3)]
    pub orientation_floor: f64,
    /// Every joint's state noise "σ_position,σ_velocity" [rad or m, rad/s or m/s] (the node's
    /// state.joint_noise; default 0).
    #[arg(long, value_delimiter = ',', num_args = 2)]
    pub joint_noise: Option<Vec<f64>>,
    /// The longest gap allowed in the odometry, joint states and reference [s].
    #[arg(long, default_value_t = 0.5)]
    pub max_gap: f64,
    /// Start the velocity controllers' integrals where the joint states' recorded efforts put
    /// them, under the command then in force, instead of at zero (the node's
    /// state.controller_integrals_from_effort).
    #[arg(long)]
    pub controllers_from_efforts: bool,
    /// Threads the predictions run on (default: every core; the figures do not depend on it).
    #[arg(long)]
    pub threads: Option<usize>,
}

impl ReplayArgs {
    /// The topics to read.
    pub fn topics(&self) -> BagTopics {
        BagTopics {
            odom: self.odom_topic.clone(),
            joint_states: self.joint_states_topic.clone(),
            cmd_vel: self.cmd_vel_topic.clone(),
            reference: self.truth_topic.clone(),
        }
    }

    /// The replay's settings over `horizons_s`.
    pub fn settings(&self, horizons_s: Vec<f64>) -> EvaluationSettings {
        let joint_noise = match self.joint_noise.as_deref() {
            Some([position, velocity]) => JointSigma {
                position: *position,
                velocity: *velocity,
            },
            _ => JointSigma::default(),
        };
        EvaluationSettings {
            horizons_s,
            every_s: self.every,
            floors: CovarianceFloors {
                position_m: self.position_floor,
                orientation_rad: self.orientation_floor,
            },
            joint_noise,
            max_gap_s: self.max_gap,
            integrals_from_efforts: self.controllers_from_efforts,
            threads: self
                .threads
                .unwrap_or(EvaluationSettings::default().threads),
            ..EvaluationSettings::default()
        }
    }

    /// The recording of `bag` (a stderr warning if its odometry carries no covariance).
    pub fn read(&self, bag: &Path) -> Result<Recording> {
        let recording =
            read_recording(bag, &self.topics()).map_err(|e| Error::Invalid(e.to_string()))?;
        warn_without_covariance(&recording);
        Ok(recording)
    }
}

/// A stderr line for what the evaluation assumes of an odometry without covariance.
fn warn_without_covariance(rec: &Recording) {
    let planar_zero = |c: &[f64; 36]| [0, 7, 35].iter().all(|&i| c[i] == 0.0);
    if (rec.odometry.samples.iter()).all(|(_, o)| planar_zero(&o.pose_covariance)) {
        eprintln!(
            "warning: {} carries no pose covariance (all zero): its poses are taken as exact, \
             and the coverage is that of the floors and the propagated twist covariance",
            rec.odometry.name
        );
    }
}

pub fn run(a: EvaluateArgs) -> Result<Value> {
    let scene = super::state::load_scene(&a.scene)?;
    let recording = a.replay.read(&a.bag)?;
    let settings = a.replay.settings(a.horizons);
    let ev = evaluate(&scene, &recording, &settings)
        .map_err(|e| Error::Invalid(format!("{}: {e}", a.bag.display())))?;
    let mut out = serde_json::to_value(&ev).map_err(|e| Error::Invalid(e.to_string()))?;
    out["scene"] = json!(a.scene.display().to_string());
    out["bag"] = json!(a.bag.display().to_string());
    out["reference_topic"] = json!(recording.reference.name);
    if let Some(dir) = &a.plot {
        let written = super::evaluate_plot::write(dir, &ev, &recording).map_err(Error::Invalid)?;
        out["plots"] = json!(written);
    }
    if a.records {
        out["records"] =
            serde_json::to_value(&ev.records).map_err(|e| Error::Invalid(e.to_string()))?;
    }
    Ok(out)
}
