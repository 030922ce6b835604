//! `evaluate`: how well a scene predicts a recorded drive (docs/logs.md). Reads the bag
//! (`constraint_dynamics_nodes::bag`), replays it (`constraint_dynamics::replay`) and prints the
//! errors per horizon with the covariance's coverage.

use constraint_dynamics::model::base_covariance::JointSigma;
use constraint_dynamics::replay::{CovarianceFloors, EvaluationSettings, Recording, evaluate};
use constraint_dynamics::{Error, Result};
use constraint_dynamics_nodes::bag::{BagTopics, read_recording};
use serde_json::{Value, json};
use std::path::PathBuf;

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
    /// Period of the start times [s].
    #[arg(long, default_value_t = 0.5)]
    every: f64,
    /// Odometry topic (nav_msgs/Odometry): the start states' base.
    #[arg(long, default_value = "/odom")]
    odom_topic: String,
    /// Joint-state topic (sensor_msgs/JointState): the start states' joints.
    #[arg(long, default_value = "/joint_states")]
    joint_states_topic: String,
    /// Command topic (geometry_msgs/Twist or TwistStamped).
    #[arg(long, default_value = "/cmd_vel")]
    cmd_vel_topic: String,
    /// Score against this nav_msgs/Odometry topic (e.g. a simulator's ground truth) instead of
    /// the odometry topic.
    #[arg(long)]
    truth_topic: Option<String>,
    /// σ added to the predicted x and y in quadrature [m] (the predictor node's
    /// covariance.position_floor).
    #[arg(long, default_value_t = 1e-3)]
    position_floor: f64,
    /// σ added to the predicted yaw in quadrature [rad] (covariance.orientation_floor).
    #[arg(long, default_value_t = 1e-3)]
    orientation_floor: f64,
    /// Every joint's state noise "σ_position,σ_velocity" [rad or m, rad/s or m/s] (the node's
    /// state.joint_noise; default 0).
    #[arg(long, value_delimiter = ',', num_args = 2)]
    joint_noise: Option<Vec<f64>>,
    /// The longest gap allowed in the odometry, joint states and reference [s].
    #[arg(long, default_value_t = 0.5)]
    max_gap: f64,
    /// Also print every prediction (`records`: start, horizon, predicted and reference pose with
    /// their covariances, errors, NEES).
    #[arg(long)]
    records: bool,
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
    let topics = BagTopics {
        odom: a.odom_topic,
        joint_states: a.joint_states_topic,
        cmd_vel: a.cmd_vel_topic,
        reference: a.truth_topic,
    };
    let recording = read_recording(&a.bag, &topics).map_err(|e| Error::Invalid(e.to_string()))?;
    warn_without_covariance(&recording);
    let joint_noise = match a.joint_noise.as_deref() {
        Some([position, velocity]) => JointSigma {
            position: *position,
            velocity: *velocity,
        },
        _ => JointSigma::default(),
    };
    let settings = EvaluationSettings {
        horizons_s: a.horizons,
        every_s: a.every,
        floors: CovarianceFloors {
            position_m: a.position_floor,
            orientation_rad: a.orientation_floor,
        },
        joint_noise,
        max_gap_s: a.max_gap,
        ..EvaluationSettings::default()
    };
    let ev = evaluate(&scene, &recording, &settings)
        .map_err(|e| Error::Invalid(format!("{}: {e}", a.bag.display())))?;
    let mut out = serde_json::to_value(&ev).map_err(|e| Error::Invalid(e.to_string()))?;
    out["scene"] = json!(a.scene.display().to_string());
    out["bag"] = json!(a.bag.display().to_string());
    out["reference_topic"] = json!(recording.reference.name);
    if a.records {
        out["records"] =
            serde_json::to_value(&ev.records).map_err(|e| Error::Invalid(e.to_string()))?;
    }
    Ok(out)
}
