//! A diff drive's command lag (`actuators.diff_drive.command_lag: τ`, actuators/lag.rs) against
//! its definition. A first-order lag started at x₀ under a command u held from t = 0 gives the
//! drive x(t) = u + (x₀ − u) e^(−t/τ) (computed here, not by the library), so a prediction under
//! the lagged command equals one without a lag under a staircase of x, a command every 1 ms.
//! Held controllers at a 1 ms control period read the lag at each tick and hold it: the
//! staircase of x at each step's start, exactly. Continuous ones follow x itself, which the
//! staircase of x's mean over each step approaches to second order in the step (the point
//! values' staircase lags it by half a step: 0.39 mrad of yaw here).
use crate::common;
use constraint_dynamics::Scene;
use constraint_dynamics::actuators::{Command, Hold};
use constraint_dynamics::predict::{IntegrationOverrides, Method, PredictionRequest, Predictor};

const TAU_S: f64 = 0.15;
const FROM: [f64; 2] = [0.2, 0.0];
const TO: [f64; 2] = [0.5, 0.8];
const HORIZON_S: f64 = 0.6;
const STAIR_S: f64 = 0.001;

/// The suite's mobile manipulator under `hold`, its arm held where it starts.
fn scene_and_arm(hold: Hold) -> (Scene, Command) {
    let mut scene = common::scene("params/suite_mobile_manipulator.yaml");
    scene.file.actuators.hold = hold;
    scene.file.actuators.control_period = Some(STAIR_S);
    let mut arm = Command::default();
    for c in &scene.file.actuators.position {
        let b = scene.model.joint_body(&c.joint).unwrap();
        let iq = scene.model.bodies[b].joint.idx_q;
        arm.joint_position.insert(c.joint.clone(), scene.q0[iq]);
    }
    (scene, arm)
}

/// The base pose (x, y, yaw) at the horizon, from the scene's start under `commands`, with
/// `lagged` the lag's start; RK4 at the staircase's step, so that both runs step alike.
fn pose_at_horizon(
    scene: &Scene,
    commands: &[(f64, Command)],
    lagged: Option<[f64; 2]>,
) -> [f64; 3] {
    let mut p = Predictor::from_scene(scene).unwrap();
    let req = PredictionRequest {
        commands,
        lagged_command: lagged,
        integration: IntegrationOverrides {
            method: Some(Method::Rk4),
            dt: Some(STAIR_S),
            error_estimate: Some(false),
            ..Default::default()
        },
        ..PredictionRequest::new(&scene.q0, &scene.v0).horizon(HORIZON_S)
    };
    let traj = p.predict(&req).unwrap();
    let q = &traj.samples.last().unwrap().q;
    [q[0], q[1], q[2]]
}

/// The lag's step response at `t` [s] (module doc), or with `mean` its mean over the step
/// from `t`.
fn lagged(t: f64, mean: bool) -> [f64; 2] {
    let decay = match mean {
        false => (-t / TAU_S).exp(),
        true => TAU_S / STAIR_S * ((-t / TAU_S).exp() - (-(t + STAIR_S) / TAU_S).exp()),
    };
    [0, 1].map(|i| TO[i] + (FROM[i] - TO[i]) * decay)
}

/// The difference of the lagged run and the staircase run [m or rad, largest of x, y, yaw],
/// and how far the drive went (so that the lag visibly matters).
fn lag_against_staircase(hold: Hold) -> (f64, f64) {
    let (mut scene, arm) = scene_and_arm(hold);
    let with_twist = |twist: [f64; 2]| Command {
        base_twist: Some(twist),
        ..arm.clone()
    };
    let n = (HORIZON_S / STAIR_S).round() as usize;
    let stairs: Vec<(f64, Command)> = (0..n)
        .map(|k| {
            let t = k as f64 * STAIR_S;
            (t, with_twist(lagged(t, hold == Hold::Continuous)))
        })
        .collect();
    let staircase = pose_at_horizon(&scene, &stairs, None);
    let unlagged = pose_at_horizon(&scene, &[(0.0, with_twist(TO))], None);
    if let Some(d) = scene.file.actuators.diff_drive.as_mut() {
        d.command_lag = Some(TAU_S);
    }
    let lagged_run = pose_at_horizon(&scene, &[(0.0, with_twist(TO))], Some(FROM));
    let diff = (0..3)
        .map(|i| (lagged_run[i] - staircase[i]).abs())
        .fold(0.0, f64::max);
    let lag_matters = (0..3)
        .map(|i| (lagged_run[i] - unlagged[i]).abs())
        .fold(0.0, f64::max);
    (diff, lag_matters)
}

#[test]
fn held_controllers_follow_the_staircase_of_the_lag() {
    let (diff, matters) = lag_against_staircase(Hold::ZeroOrder);
    // The lag moves the pose by 0.11 (yaw, rad); the two runs agree to 1.7e-16.
    assert!(matters > 0.05, "the lag moves the pose by {matters}");
    assert!(diff < 1e-14, "held: {diff} from the staircase");
}

#[test]
fn continuous_controllers_follow_the_lag_itself() {
    let (diff, matters) = lag_against_staircase(Hold::Continuous);
    // Achieved 1.4e-8 (the point values' staircase: 3.9e-4).
    assert!(matters > 0.05, "the lag moves the pose by {matters}");
    assert!(diff < 5e-8, "continuous: {diff} from the 1 ms staircase");
}

/// A lag of 0, or below a microsecond, is no lag (its rate (u − x)/τ would overflow); a
/// negative or non-finite one is refused, naming the key.
#[test]
fn a_lag_must_be_finite_and_not_negative() {
    let (scene, arm) = scene_and_arm(Hold::Continuous);
    let commands = [(
        0.0,
        Command {
            base_twist: Some(TO),
            ..arm
        },
    )];
    let unlagged = pose_at_horizon(&scene, &commands, None);
    for none in [0.0, 1e-300] {
        let mut tiny = scene.clone();
        tiny.file.actuators.diff_drive.as_mut().unwrap().command_lag = Some(none);
        assert_eq!(pose_at_horizon(&tiny, &commands, Some(FROM)), unlagged);
    }
    for bad in [-0.1, f64::NAN] {
        let mut bad_scene = scene.clone();
        bad_scene
            .file
            .actuators
            .diff_drive
            .as_mut()
            .unwrap()
            .command_lag = Some(bad);
        let e = Predictor::from_scene(&bad_scene).err().unwrap().to_string();
        assert!(e.contains("command_lag"), "{e}");
    }
}
