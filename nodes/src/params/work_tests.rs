//! The bounds on work-sizing parameters: static ranges, the scene's limits, run-time sets.

use constraint_dynamics::Scene;
use constraint_dynamics::predict::{IntegrationSettings, Method};
use ros2_client::ParameterValue;

use super::*;
use crate::params::NodeParams;
use crate::params::tests::one;
use crate::prediction::PredictionParams;
use crate::predictor::PredictorParams;
use crate::ros::args::Parameters;
use crate::ros::args::parse_params_yaml;

/// The budget of a bundled scene (`params/<name>`).
fn budget_of(name: &str) -> WorkBudget {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let scene = Scene::load(root.join("params").join(name)).expect("scene");
    WorkBudget::of(&scene)
}

/// The suite's diff drive: its controllers held for the 1 ms control period, RK4 at that period.
fn scene_budget() -> WorkBudget {
    budget_of("suite_diff_drive.yaml")
}

fn current<K: crate::params::KindParams>(p: &NodeParams<K>) -> Parameters {
    let mut c = Parameters::default();
    c.values.extend(p.to_ros());
    c
}

#[test]
fn absurd_values_are_refused_with_their_range() {
    // (yaml of the node's section, the parameter named, the range in the message)
    let predictor = [
        ("horizon: 1.0e9", "horizon", "[0, 3600] s"),
        ("horizon: 1.0e308", "horizon", "[0, 3600] s"),
        ("horizon: -1.0", "horizon", "[0, 3600] s"),
        ("rate: 1.0e9", "rate", "[0.01, 1000] Hz"),
        ("rate: 1.0e-300", "rate", "[0.01, 1000] Hz"),
        (
            "diagnostics: { period: 1.0e-300 }",
            "diagnostics.period",
            "[0.01, 3600] s",
        ),
        (
            "diagnostics: { period: 1.0e300 }",
            "diagnostics.period",
            "[0.01, 3600] s",
        ),
    ];
    for (body, name, range) in predictor {
        let yaml = format!(
            "cd_predictor:\n  ros__parameters:\n    model: {{ scene_file: s.yaml }}\n    {body}\n"
        );
        let p = parse_params_yaml(&yaml, "/cd_predictor").unwrap();
        let e = NodeParams::<PredictorParams>::from_parameters(&p)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with(name) && e.contains(range), "{body}: {e}");
    }
    let prediction = [
        ("max_horizon: 1.0e9", "max_horizon", "[0.001, 3600] s"),
        ("max_horizon: 0.0", "max_horizon", "[0.001, 3600] s"),
        ("max_commands: 4000000000", "max_commands", "[1, 1000000]"),
        ("max_rollouts: 0", "max_rollouts", "[1, 100000]"),
        ("max_rollouts: 1000000", "max_rollouts", "[1, 100000]"),
        (
            "max_rollout_samples: 4000000000",
            "max_rollout_samples",
            "[1, 10000000]",
        ),
        ("rollout_threads: 5000", "rollout_threads", "[0, 1024]"),
    ];
    for (body, name, range) in prediction {
        let yaml = format!(
            "cd_prediction:\n  ros__parameters:\n    model: {{ scene_file: s.yaml }}\n    {body}\n"
        );
        let p = parse_params_yaml(&yaml, "/cd_prediction").unwrap();
        let e = NodeParams::<PredictionParams>::from_parameters(&p)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with(name) && e.contains(range), "{body}: {e}");
    }
    let mut p = NodeParams::<PredictorParams>::default();
    p.common.model.scene_file = "s.yaml".into();
    p.node.markers.footprint = vec![0.1; 2 * 257];
    let e = p.validate().unwrap_err().to_string();
    assert!(
        e.contains("markers.footprint has 257 vertices, more than its limit of 256"),
        "{e}"
    );
}

#[test]
fn the_scene_limits_the_horizon() {
    // The suite's mobile manipulator: ROS2 at dt = 20 ms, samples every 20 ms, default limits
    // (1e6 steps, 1e5 samples): one prediction may cover 1e5 samples × 20 ms = 2000 s (its
    // 1e6 steps would allow 20 000 s); at 10 Hz, 10 × horizon / 20 ms ≤ 1e6 gives 2000 s too.
    let b = budget_of("suite_mobile_manipulator.yaml");
    assert_eq!(b.max_horizon(None), 2000.0);
    assert_eq!(b.max_horizon(Some(10.0)), 2000.0);
    b.check_horizon("horizon", 2000.0, Some(10.0)).unwrap();
    let e = b
        .check_horizon("horizon", 2001.0, Some(10.0))
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("horizon = 2001 s is beyond its limit of 2000 s on this scene")
            && e.contains("integration.max_steps = 1e6 steps (horizon / integration.dt 0.02 s)")
            && e.contains("integration.max_samples = 100000 samples"),
        "{e}"
    );
    // The suite's diff drive: rk4 at dt = control period = 1 ms, samples every 20 ms: one
    // prediction may cover 1e6 × 1 ms = 1000 s; at 10 Hz, 10 × horizon / 1 ms ≤ 1e6 steps per
    // second gives 100 s.
    let b = scene_budget();
    assert_eq!(b.max_horizon(None), 1000.0);
    assert_eq!(b.max_horizon(Some(10.0)), 100.0);
    b.check_horizon("horizon", 100.0, Some(10.0)).unwrap();
    b.check_horizon("max_horizon", 1000.0, None).unwrap();
    let e = b
        .check_horizon("horizon", 100.5, Some(10.0))
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("horizon = 100.5 s is beyond its limit of 100 s on this scene")
            && e.contains(
                "integration.max_steps = 1e6 steps (horizon / integration.dt 0.001 s, \
                 actuators.control_period 0.001 s)"
            )
            && e.contains("at rate 10 Hz"),
        "{e}"
    );
    let e = b
        .check_horizon("max_horizon", 1001.0, None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("max_horizon = 1001 s is beyond its limit of 1000 s"),
        "{e}"
    );
    // Fixed-step methods: horizon / dt counts; samples too.
    let mut s = IntegrationSettings {
        method: Method::Rk4,
        dt: 1e-4,
        ..Default::default()
    };
    let b = WorkBudget::new(s.clone(), None);
    assert_eq!(b.max_horizon(None), 100.0); // 1e6 × 1e-4 s
    s.dt = 1.0;
    s.sample_period = 1e-3;
    let b = WorkBudget::new(s, None);
    assert_eq!(b.max_horizon(None), 100.0); // 1e5 samples × 1e-3 s
    let e = b
        .check_horizon("max_horizon", 200.0, None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("integration.max_samples = 100000"), "{e}");
    // Whatever the scene allows, a horizon the core would refuse is refused here too.
    for h in [1e9, 1e308, f64::INFINITY, f64::NAN] {
        assert!(b.check_horizon("horizon", h, Some(10.0)).is_err(), "{h}");
    }
}

#[test]
fn run_time_sets_respect_the_scene() {
    let b = scene_budget();
    let mut p = NodeParams::<PredictorParams>::default();
    p.common.model.scene_file = "s.yaml".into();
    let c = current(&p);
    let set = |name: &str, x: f64| {
        NodeParams::<PredictorParams>::updated(&c, &one(name, ParameterValue::Double(x)), Some(&b))
    };
    assert_eq!(set("horizon", 50.0).unwrap().node.horizon, 50.0);
    for (h, needle) in [
        (1e9, "horizon = 1e9 s is outside its range [0, 3600] s"),
        (1e308, "horizon = 1e308 s is outside its range [0, 3600] s"),
        (
            500.0,
            "horizon = 500 s is beyond its limit of 100 s on this scene",
        ),
    ] {
        let e = set("horizon", h).unwrap_err().to_string();
        assert!(e.contains(needle), "{h}: {e}");
    }
    // Without a scene (not configured yet) only the static range applies; configure checks
    // the rest.
    let unconfigured = NodeParams::<PredictorParams>::updated(
        &c,
        &one("horizon", ParameterValue::Double(500.0)),
        None,
    );
    assert_eq!(unconfigured.unwrap().node.horizon, 500.0);
    // 0 = the scene's horizon (1 s), within the limits.
    assert!(set("horizon", 0.0).is_ok());

    let mut p = NodeParams::<PredictionParams>::default();
    p.common.model.scene_file = "s.yaml".into();
    let c = current(&p);
    let set = |x: f64| {
        NodeParams::<PredictionParams>::updated(
            &c,
            &one("max_horizon", ParameterValue::Double(x)),
            Some(&b),
        )
    };
    assert_eq!(set(30.0).unwrap().node.max_horizon, 30.0);
    let e = set(1e9).unwrap_err().to_string();
    assert!(
        e.contains("max_horizon = 1e9 s is outside its range [0.001, 3600] s"),
        "{e}"
    );
    let e = set(2000.0).unwrap_err().to_string();
    assert!(
        e.contains("max_horizon = 2000 s is beyond its limit of 1000 s"),
        "{e}"
    );
}
