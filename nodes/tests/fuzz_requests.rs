//! Fuzzing every ROS request type without DDS (issue 15): the pure handlers the ROS plumbing
//! calls — `get_constraint_forces`, `project_velocity`, `filter_command`, `predict`, `rollouts` —
//! and the predictor's inputs (joint states, odometry, twist commands, `/robot_description`
//! text), fed hostile floats (NaN, ±∞, ±1e308, 1e-300, −0), wrong-length arrays (0, n−1, n+1, 10 000),
//! unknown / duplicated / empty / unicode joint names, big command lists and odd timestamps.
//!
//! Property per call: no panic; the response is `success = false` with a non-empty message, or
//! every float in it is finite (a message serialised to JSON turns NaN and ±∞ into `null`, so
//! "no `null` anywhere" is "every float finite"); and each call takes less than [`BOUND`] of
//! its thread's CPU time (`rollouts`: [`ROLLOUTS_BOUND`] of the process's).
//!
//! No DDS participant is opened: the nodes are built as `nodes/src/predictor/tests.rs` builds
//! one (`Robot::load` + `NodeLogic::new`). 512 cases per target by default with a fixed seed
//! (`PROPTEST_CASES`, `PROPTEST_RNG_SEED` override; tools/fuzz_long.sh runs more).

use constraint_dynamics_nodes::forces::{ForcesNode, ForcesParams};
use constraint_dynamics_nodes::msg::builtin_interfaces::Time;
use constraint_dynamics_nodes::msg::constraint_dynamics_msgs::srv::{
    GetConstraintForcesRequest, PredictRequest, ProjectVelocityRequest, RolloutsRequest,
};
use constraint_dynamics_nodes::msg::geometry_msgs::{Twist, Vector3};
use constraint_dynamics_nodes::msg::nav_msgs::Odometry;
use constraint_dynamics_nodes::msg::sensor_msgs::JointState;
use constraint_dynamics_nodes::msg::std_msgs::Header;
use constraint_dynamics_nodes::node::worker::NodeLogic;
use constraint_dynamics_nodes::params::{CommonParams, KindParams, NodeParams};
use constraint_dynamics_nodes::prediction::{PredictionNode, PredictionParams};
use constraint_dynamics_nodes::predictor::{PredictorInput, PredictorNode, PredictorParams};
use constraint_dynamics_nodes::projection::{ProjectionNode, ProjectionParams};
use constraint_dynamics_nodes::robot::Robot;
use constraint_dynamics_nodes::ros::logging::NodeLog;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};
use serde::Serialize;
use std::time::{Duration, Instant};

/// The most CPU time one handler call may take (release build). CPU time of the calling
/// thread, not wall time: the bound is on a request's work, which a starved process (a fuzz
/// run at nice 19 beside a CI build took 2.17 s of wall time for a 0.5 s predictor tick) or the
/// test's own parallel targets would otherwise stretch.
const BOUND: Duration = Duration::from_secs(2);

/// The bound on one `~/rollouts` call, whose work runs on its own worker threads: CPU time of
/// the whole process, which also counts the other targets running beside it (an over-count).
const ROLLOUTS_BOUND: Duration = Duration::from_secs(8);

/// CPU time used so far by the calling thread (`CLOCK_THREAD_CPUTIME_ID`) or the process.
fn cpu_time(clock: libc::clockid_t) -> Duration {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec; the clock ids need nothing else.
    let rc = unsafe { libc::clock_gettime(clock, &mut ts) };
    assert_eq!(rc, 0, "clock_gettime({clock}) failed");
    Duration::new(ts.tv_sec as u64, ts.tv_nsec as u32)
}

const SCENE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../params/suite_mobile_manipulator.yaml"
);
const URDF: &str = include_str!("../../urdf/mobile_manipulator.urdf");

/// The scene's coordinates (nq = nv = 9, planar base).
const Q_NAMES: [&str; 9] = [
    "root_joint:x",
    "root_joint:y",
    "root_joint:yaw",
    "left_wheel_joint",
    "right_wheel_joint",
    "arm_shoulder_yaw",
    "arm_shoulder_pitch",
    "arm_elbow",
    "arm_wrist",
];
const JOINTS: [&str; 6] = [
    "left_wheel_joint",
    "right_wheel_joint",
    "arm_shoulder_yaw",
    "arm_shoulder_pitch",
    "arm_elbow",
    "arm_wrist",
];

fn config() -> Config {
    let mut c = Config::default();
    if std::env::var_os("PROPTEST_CASES").is_none() {
        c.cases = 512;
    }
    if std::env::var_os("PROPTEST_RNG_SEED").is_none() {
        c.rng_seed = RngSeed::Fixed(0x15_15);
    }
    c.failure_persistence = None;
    c
}

fn node<N: NodeLogic>(kind: N::Params) -> N
where
    N::Params: KindParams,
{
    let mut common = CommonParams::default();
    common.model.scene_file = SCENE.into();
    let params = NodeParams { common, node: kind };
    let robot = Robot::load(&params.common).unwrap();
    N::new(robot, params, NodeLog::new("fuzz")).unwrap()
}

/// A float a hostile peer might send: mostly plausible, often absurd.
fn hostile() -> impl Strategy<Value = f64> {
    prop_oneof![
        6 => -3.0..3.0f64,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(f64::NEG_INFINITY),
        1 => Just(1e308),
        1 => Just(-1e308),
        1 => Just(1e-300),
        1 => Just(-0.0),
        1 => any::<f64>(),
    ]
}

/// A length around n: 0, n − 1, n, n + 1 (mostly), or 10 000.
fn length(n: usize) -> impl Strategy<Value = usize> {
    prop_oneof![
        1 => Just(0usize),
        2 => Just(n - 1),
        6 => Just(n),
        2 => Just(n + 1),
        1 => Just(10_000usize),
    ]
}

fn floats(n: usize) -> impl Strategy<Value = Vec<f64>> {
    length(n).prop_flat_map(|len| prop::collection::vec(hostile(), len))
}

/// A joint name: a real one mostly, else unknown, empty or random unicode.
fn name(real: &'static [&'static str]) -> impl Strategy<Value = String> {
    prop_oneof![
        8 => prop::sample::select(real).prop_map(String::from),
        1 => Just(String::new()),
        1 => Just("no_such_joint".to_string()),
        1 => any::<String>(),
    ]
}

/// Names in order (possibly permuted / duplicated / wrong), or none (= the node's order).
fn names(real: &'static [&'static str]) -> impl Strategy<Value = Vec<String>> {
    prop_oneof![
        3 => Just(Vec::new()),
        3 => Just(real.iter().map(|s| s.to_string()).collect::<Vec<_>>()),
        2 => Just(real.to_vec()).prop_shuffle().prop_map(|v| v.iter().map(|s| s.to_string()).collect()),
        3 => length(real.len()).prop_flat_map(move |n| prop::collection::vec(name(real), n.min(200))),
    ]
}

fn twist() -> impl Strategy<Value = Twist> {
    prop::array::uniform6(hostile()).prop_map(|a| Twist {
        linear: Vector3 {
            x: a[0],
            y: a[1],
            z: a[2],
        },
        angular: Vector3 {
            x: a[3],
            y: a[4],
            z: a[5],
        },
    })
}

fn stamp() -> impl Strategy<Value = Time> {
    prop_oneof![
        4 => (0i64..4_000_000_000_000).prop_map(Time::from_nanos),
        1 => Just(Time::from_nanos(0)),
        1 => Just(Time::from_nanos(-1)),
        1 => Just(Time::from_nanos(i64::MAX)),
        1 => Just(Time::from_nanos(i64::MIN)),
    ]
}

/// The response's every float finite: NaN and ±∞ serialise to JSON `null`.
fn all_finite(v: &impl Serialize) -> bool {
    fn walk(v: &serde_json::Value) -> bool {
        match v {
            serde_json::Value::Null => false,
            serde_json::Value::Array(a) => a.iter().all(walk),
            serde_json::Value::Object(o) => o.values().all(walk),
            _ => true,
        }
    }
    walk(&serde_json::to_value(v).unwrap())
}

/// Refused with a reason, or every float finite.
fn judge(what: &str, success: bool, message: &str, resp: &impl Serialize) -> Result<(), String> {
    if !success {
        if message.is_empty() {
            return Err(format!("{what}: refused without a message"));
        }
        return Ok(());
    }
    if !all_finite(resp) {
        return Err(format!(
            "{what}: success with a non-finite value: {}",
            serde_json::to_string(resp).unwrap()
        ));
    }
    Ok(())
}

fn timed<T>(what: &str, f: impl FnOnce() -> T) -> T {
    timed_on(libc::CLOCK_THREAD_CPUTIME_ID, BOUND, what, f)
}

fn timed_on<T>(clock: libc::clockid_t, bound: Duration, what: &str, f: impl FnOnce() -> T) -> T {
    let (cpu0, wall0) = (cpu_time(clock), Instant::now());
    let out = f();
    let cpu = cpu_time(clock) - cpu0;
    assert!(
        cpu < bound,
        "{what} took {cpu:?} of CPU ({:?} of wall time; bound {bound:?})",
        wall0.elapsed()
    );
    out
}

/// A hostile `/joint_states` message.
fn joint_state() -> impl Strategy<Value = JointState> {
    (
        stamp(),
        names(&JOINTS),
        floats(JOINTS.len()),
        floats(JOINTS.len()),
        floats(JOINTS.len()),
    )
        .prop_map(|(stamp, name, position, velocity, effort)| JointState {
            header: Header {
                stamp,
                frame_id: String::new(),
            },
            name,
            position,
            velocity,
            effort,
        })
}

/// A hostile `/odom` message.
fn odometry() -> impl Strategy<Value = Odometry> {
    (
        stamp(),
        prop::array::uniform7(hostile()),
        twist(),
        prop::array::uniform6(hostile()),
    )
        .prop_map(|(stamp, p, t, c)| {
            let mut od = Odometry::default();
            od.header.stamp = stamp;
            od.pose.pose.position.x = p[0];
            od.pose.pose.position.y = p[1];
            od.pose.pose.position.z = p[2];
            od.pose.pose.orientation.x = p[3];
            od.pose.pose.orientation.y = p[4];
            od.pose.pose.orientation.z = p[5];
            od.pose.pose.orientation.w = p[6];
            od.twist.twist = t;
            for (i, x) in c.iter().enumerate() {
                od.pose.covariance[7 * i] = *x;
                od.twist.covariance[7 * i] = *x;
            }
            od
        })
}

/// Feeds the robot's state estimate (joint states, odometry): each either applied or refused.
fn feed(robot: &mut Robot, js: &[JointState], od: &[Odometry]) {
    for j in js {
        let _ = timed("joint state", || robot.state_mut().apply_joint_state(j));
    }
    for o in od {
        let model = robot.model().clone();
        let _ = timed("odometry", || robot.state_mut().apply_odometry(&model, o));
    }
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn get_constraint_forces_hostile(
        use_latest_state in any::<bool>(),
        q_names in names(&Q_NAMES),
        q in floats(9),
        v_names in names(&Q_NAMES),
        v in floats(9),
        tau in floats(9),
        js in prop::collection::vec(joint_state(), 0..3),
        now in stamp(),
    ) {
        let mut n: ForcesNode = node(ForcesParams::default());
        feed(n.robot_mut(), &js, &[]);
        let req = GetConstraintForcesRequest { use_latest_state, q_names, q, v_names, v, tau };
        let r = timed("get_constraint_forces", || n.get_constraint_forces(&req, now));
        judge("get_constraint_forces", r.success, &r.message, &r).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn project_velocity_hostile(
        use_latest_state in any::<bool>(),
        q in floats(9),
        v_names in names(&Q_NAMES),
        v_des in floats(9),
        use_twist in any::<bool>(),
        base_twist in twist(),
        joint_names in names(&JOINTS),
        joint_velocities in floats(6),
        bound_names in names(&Q_NAMES),
        lower in floats(9),
        upper in floats(9),
        accel_limit_dt in hostile(),
        od in prop::collection::vec(odometry(), 0..2),
    ) {
        let mut n: ProjectionNode = node(ProjectionParams::default());
        feed(n.robot_mut(), &[], &od);
        let req = ProjectVelocityRequest {
            use_latest_state, q, v_names, v_des, use_twist, base_twist, joint_names,
            joint_velocities, bound_names, lower, upper, accel_limit_dt,
        };
        let r = timed("project_velocity", || n.project_velocity(&req));
        judge("project_velocity", r.success, &r.message, &r).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn filter_command_hostile(
        cmds in prop::collection::vec(twist(), 1..8),
        js in prop::collection::vec(joint_state(), 0..2),
        od in prop::collection::vec(odometry(), 0..2),
    ) {
        let mut n: ProjectionNode = node(ProjectionParams::default());
        feed(n.robot_mut(), &js, &od);
        for c in &cmds {
            match timed("filter_command", || n.filter_command(c)) {
                Ok((t, resp)) => {
                    judge("filter_command", resp.success, &resp.message, &resp)
                        .map_err(TestCaseError::fail)?;
                    prop_assert!(all_finite(&t), "filtered twist not finite: {t:?}");
                }
                Err(e) => prop_assert!(!e.to_string().is_empty()),
            }
        }
    }

    #[test]
    fn predict_hostile(
        use_latest_state in any::<bool>(),
        q in floats(9),
        v in floats(9),
        commands in prop_oneof![
            8 => prop::collection::vec(twist(), 0..6),
            1 => prop::collection::vec(twist(), 10_000),
        ],
        command_period in prop_oneof![4 => 0.01..0.5f64, 1 => hostile(), 1 => Just(1e-300), 1 => Just(-1.0)],
        horizon in prop_oneof![4 => 0.0..0.6f64, 1 => hostile(), 1 => Just(1e9), 1 => Just(-5.0)],
        with_forces in any::<bool>(),
        with_covariance in any::<bool>(),
        start_covariance in prop_oneof![
            3 => Just(Vec::new()),
            1 => floats(324),
        ],
        js in prop::collection::vec(joint_state(), 0..2),
        od in prop::collection::vec(odometry(), 0..2),
        now in stamp(),
    ) {
        let mut n: PredictionNode = node(PredictionParams::default());
        feed(n.robot_mut(), &js, &od);
        let req = PredictRequest {
            use_latest_state, q, v, commands, command_period, horizon, with_forces,
            with_covariance, start_covariance,
        };
        let r = timed("predict", || n.predict(&req, now));
        judge("predict", r.success, &r.message, &r).map_err(TestCaseError::fail)?;
    }

    /// `~/rollouts` under limits that keep a case small (8 sequences of at most 0.5 s).
    #[test]
    fn rollouts_hostile(
        use_latest_state in any::<bool>(),
        q in floats(9),
        v in floats(9),
        commands in prop_oneof![
            8 => prop::collection::vec(twist(), 0..24),
            1 => prop::collection::vec(twist(), 10_000),
        ],
        sequence_length in prop_oneof![4 => 1..6u32, 1 => Just(0u32), 1 => any::<u32>()],
        step in prop_oneof![4 => 0.01..0.2f64, 1 => hostile(), 1 => Just(1e-300), 1 => Just(-1.0)],
        with_forces in any::<bool>(),
        js in prop::collection::vec(joint_state(), 0..2),
        od in prop::collection::vec(odometry(), 0..2),
        now in stamp(),
    ) {
        let params = PredictionParams {
            max_rollouts: 8,
            max_horizon: 0.5,
            rollout_threads: 2,
            ..Default::default()
        };
        let mut n: PredictionNode = node(params);
        feed(n.robot_mut(), &js, &od);
        let req = RolloutsRequest {
            use_latest_state, q, v, commands, sequence_length, step, with_forces,
        };
        let clock = libc::CLOCK_PROCESS_CPUTIME_ID;
        let r = timed_on(clock, ROLLOUTS_BOUND, "rollouts", || n.rollouts(&req, now));
        judge("rollouts", r.success, &r.message, &r).map_err(TestCaseError::fail)?;
        if r.success {
            let len = req.sequence_length as usize;
            prop_assert_eq!(r.poses.len(), req.commands.len());
            prop_assert_eq!(r.twists.len(), req.commands.len());
            prop_assert!(len > 0 && req.commands.len().is_multiple_of(len));
        }
    }

    /// The predictor: commands (plain twists) and state messages in, a tick out.
    #[test]
    fn predictor_inputs_hostile(
        cmds in prop::collection::vec((twist(), stamp()), 0..4),
        js in prop::collection::vec(joint_state(), 0..3),
        od in prop::collection::vec(odometry(), 0..3),
        now in stamp(),
    ) {
        let p = PredictorParams { horizon: 0.5, ..Default::default() };
        let mut n: PredictorNode = node(p);
        feed(n.robot_mut(), &js, &od);
        for (c, at) in cmds {
            timed("command", || n.handle(PredictorInput::Command(c), at, &mut |_| {}));
        }
        let mut out = None;
        let r = timed("tick", || n.tick(now, &mut |o| out = Some(o)));
        match r {
            Err(e) => prop_assert!(!e.to_string().is_empty()),
            Ok(()) => {
                if let Some(o) = out {
                    prop_assert!(all_finite(&o.odom), "odom: {:?}", o.odom);
                    prop_assert!(all_finite(&o.path), "path not finite");
                    prop_assert!(all_finite(&o.forces), "forces: {:?}", o.forces);
                }
            }
        }
    }

    /// `/robot_description`: truncated or byte-mutated bundled URDF, or random text. The new
    /// robot is refused with a typed error, or is used for one prediction.
    #[test]
    fn robot_description_hostile(
        kind in 0..4u8,
        cut in 0.0..1.0f64,
        junk in prop::collection::vec(any::<u8>(), 0..64),
        text in any::<String>(),
    ) {
        let urdf = match kind {
            0 => URDF[..URDF.floor_char_boundary((cut * URDF.len() as f64) as usize)].to_string(),
            1 => {
                let mut b = URDF.as_bytes().to_vec();
                let at = (cut * b.len() as f64) as usize;
                for (i, x) in junk.iter().enumerate() {
                    if at + i < b.len() {
                        b[at + i] = *x;
                    }
                }
                String::from_utf8_lossy(&b).into_owned()
            }
            2 => text,
            _ => String::from_utf8_lossy(&junk).into_owned(),
        };
        let p = PredictorParams { horizon: 0.3, ..Default::default() };
        let n: PredictorNode = node(p);
        let common = n.params().common.clone();
        match timed("with_urdf", || n.robot().with_urdf(&urdf, &common)) {
            Err(e) => prop_assert!(!e.to_string().is_empty()),
            Ok(robot) => {
                let params = n.params().clone();
                if let Ok(mut m) = PredictorNode::new(robot, params, NodeLog::new("fuzz")) {
                    let mut out = None;
                    if timed("tick", || m.tick(Time::from_nanos(1), &mut |o| out = Some(o))).is_ok()
                        && let Some(o) = out
                    {
                        prop_assert!(all_finite(&o.odom), "odom: {:?}", o.odom);
                    }
                }
            }
        }
    }
}
