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
//! (`PROPTEST_CASES`, `PROPTEST_RNG_SEED` override; tools/fuzz_long.sh runs more). Each target
//! counts its answered and refused cases and needs both (`Tally`); `FUZZ_WHY=1` prints every
//! refusal's message, to see what the strategies hit.

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
use std::sync::atomic::{AtomicUsize, Ordering};
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

/// An array of the given base coordinates followed by the scene's joints.
macro_rules! with_joints {
    ($($base:literal),*) => {
        [$($base,)* "left_wheel_joint", "right_wheel_joint", "arm_shoulder_yaw",
         "arm_shoulder_pitch", "arm_elbow", "arm_wrist"]
    };
}
/// The scene's coordinates (nq = nv = 9, planar base).
const Q_NAMES: [&str; 9] = with_joints!("root_joint:x", "root_joint:y", "root_joint:yaw");
/// Its velocity coordinates (the planar base's are in the base frame).
const V_NAMES: [&str; 9] = with_joints!(
    "root_joint:vx_local",
    "root_joint:vy_local",
    "root_joint:wz"
);
const JOINTS: [&str; 6] = with_joints!();

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

/// n floats: all plausible, or one or two of them hostile, or all drawn from [`hostile`]. (Each
/// entry drawn from `hostile` alone made 9 plausible floats a 1-in-2 000 event: 0 of 512
/// `project_velocity` cases and 4 % of the `predict` cases reached the computation.)
fn fixed(n: usize) -> impl Strategy<Value = Vec<f64>> {
    let plausible = prop::collection::vec(-3.0..3.0f64, n);
    prop_oneof![
        6 => plausible.clone(),
        2 => (plausible, prop::collection::vec((0..n, hostile()), 1..3)).prop_map(|(mut v, bad)| {
            for (i, x) in bad {
                v[i] = x;
            }
            v
        }),
        1 => prop::collection::vec(hostile(), n),
    ]
}

/// `v` made a valid array of n: entries that are not plausible become 0.1.
fn sanitized(v: &[f64], n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| {
            v.get(i)
                .copied()
                .filter(|x| x.is_finite() && x.abs() < 3.0)
                .unwrap_or(0.1)
        })
        .collect()
}

/// A velocity the wheels' rolling rows allow: the base and wheels at rest (a random one makes
/// the redundant lateral rows disagree: refused as inconsistent), the arm's drawn.
fn rolling_velocity(v: &[f64]) -> Vec<f64> {
    let mut v = sanitized(v, 9);
    v[..5].fill(0.0);
    v
}

/// The twist a differential drive follows: `t`'s linear.x and angular.z (sanitized), the rest 0.
fn planar(t: &Twist) -> Twist {
    let s = sanitized(&[t.linear.x, t.angular.z], 2);
    let mut out = Twist::default();
    (out.linear.x, out.angular.z) = (s[0], s[1]);
    out
}

/// Floats for an array of n: [`fixed`] mostly, else of a wrong length ([`length`]).
fn floats(n: usize) -> impl Strategy<Value = Vec<f64>> {
    prop_oneof![
        3 => fixed(n),
        1 => length(n).prop_flat_map(|len| prop::collection::vec(hostile(), len)),
    ]
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

/// A twist: mostly one a differential drive follows (linear.x, angular.z), else [`fixed`].
fn twist() -> impl Strategy<Value = Twist> {
    prop_oneof![
        2 => (-1.0..1.0f64, -2.0..2.0f64).prop_map(|(vx, wz)| {
            let mut t = Twist::default();
            (t.linear.x, t.angular.z) = (vx, wz);
            t
        }),
        1 => any_twist(),
    ]
}

fn any_twist() -> impl Strategy<Value = Twist> {
    fixed(6).prop_map(|a| Twist {
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

/// Refused and answered cases of one target, printed when its last case is judged: a target
/// whose cases were all refused would test no computation, one with none refused no check.
struct Tally {
    target: &'static str,
    refused: AtomicUsize,
    answered: AtomicUsize,
}

impl Tally {
    const fn new(target: &'static str) -> Self {
        Self {
            target,
            refused: AtomicUsize::new(0),
            answered: AtomicUsize::new(0),
        }
    }

    /// Count one case; after the run's last case, print the counts and require both outcomes
    /// at least [`MIN_SHARE`] of the cases (shrinking after a failure counts more: no check).
    fn count(&self, success: bool) {
        let c = if success {
            &self.answered
        } else {
            &self.refused
        };
        c.fetch_add(1, Ordering::Relaxed);
        let (a, r) = (
            self.answered.load(Ordering::Relaxed),
            self.refused.load(Ordering::Relaxed),
        );
        let cases = config().cases as usize;
        if a + r == cases {
            println!(
                "{}: {a} answered, {r} refused of {cases} cases",
                self.target
            );
            assert!(
                a as f64 >= MIN_SHARE * cases as f64 && r as f64 >= MIN_SHARE * cases as f64,
                "{}: {a} answered and {r} refused of {cases}: the strategies no longer reach \
                 both outcomes",
                self.target
            );
        }
    }
}

/// The least share of a target's cases that must be answered, and refused.
const MIN_SHARE: f64 = 0.05;

/// The share of cases whose drawn request is made valid before the call (`sanitized`): the
/// computation behind the checks is fuzzed too, with plausible but random states and commands.
const CLEAN: f64 = 0.3;

static GET_CONSTRAINT_FORCES: Tally = Tally::new("get_constraint_forces");
static PROJECT_VELOCITY: Tally = Tally::new("project_velocity");
static FILTER_COMMAND: Tally = Tally::new("filter_command (a case: its first command answered)");
static PREDICT: Tally = Tally::new("predict");
static ROLLOUTS: Tally = Tally::new("rollouts");
static PREDICTOR_TICK: Tally = Tally::new("predictor tick (answered: odometry published)");
static ROBOT_DESCRIPTION: Tally = Tally::new("robot_description (answered: robot replaced)");

/// Refused with a reason, or every float finite.
fn judge(what: &str, success: bool, message: &str, resp: &impl Serialize) -> Result<(), String> {
    if !success {
        if std::env::var_os("FUZZ_WHY").is_some() {
            eprintln!("WHY {what}: {message}");
        }
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
    (stamp(), fixed(7), twist(), fixed(6)).prop_map(|(stamp, p, t, c)| {
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
        // Variances: a plausible draw made non-negative (a negative one half the time made
        // the message's every field valid once in 64); the hostile draws kept as they are.
        for (i, x) in c.iter().enumerate() {
            let x = if x.abs() < 3.0 { x.abs() } else { *x };
            od.pose.covariance[7 * i] = x;
            od.twist.covariance[7 * i] = x;
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
        GET_CONSTRAINT_FORCES.count(r.success);
    }

    #[test]
    fn project_velocity_hostile(
        use_latest_state in any::<bool>(),
        q in floats(9),
        v_names in names(&V_NAMES),
        v_des in floats(9),
        use_twist in any::<bool>(),
        base_twist in twist(),
        joint_names in names(&JOINTS),
        joint_velocities in floats(6),
        bound_names in names(&V_NAMES),
        lower in floats(9),
        upper in floats(9),
        accel_limit_dt in hostile(),
        od in prop::collection::vec(odometry(), 0..2),
        clean in prop::bool::weighted(CLEAN),
    ) {
        let mut n: ProjectionNode = node(ProjectionParams::default());
        feed(n.robot_mut(), &[], &od);
        // A clean case: the drawn values made valid (mismatched lengths were most refusals).
        let (use_latest_state, q, v_names, v_des, base_twist, bound_names, lower, upper) = if clean {
            let bounds = |x: &[f64], s: f64| sanitized(x, 9).iter().map(|b| s * (b.abs() + 0.5)).collect();
            (false, sanitized(&q, 9), vec![], sanitized(&v_des, 9), planar(&base_twist),
             V_NAMES.iter().map(|s| s.to_string()).collect(), bounds(&lower, -1.0), bounds(&upper, 1.0))
        } else {
            (use_latest_state, q, v_names, v_des, base_twist, bound_names, lower, upper)
        };
        let (joint_names, joint_velocities, accel_limit_dt) = if clean {
            (JOINTS.iter().map(|s| s.to_string()).collect(), sanitized(&joint_velocities, 6),
             sanitized(&[accel_limit_dt], 1)[0].abs())
        } else {
            (joint_names, joint_velocities, accel_limit_dt)
        };
        let req = ProjectVelocityRequest {
            use_latest_state, q, v_names, v_des, use_twist, base_twist, joint_names,
            joint_velocities, bound_names, lower, upper, accel_limit_dt,
        };
        let r = timed("project_velocity", || n.project_velocity(&req));
        judge("project_velocity", r.success, &r.message, &r).map_err(TestCaseError::fail)?;
        PROJECT_VELOCITY.count(r.success);
    }

    #[test]
    fn filter_command_hostile(
        cmds in prop::collection::vec(twist(), 1..8),
        js in prop::collection::vec(joint_state(), 0..2),
        od in prop::collection::vec(odometry(), 0..2),
    ) {
        let mut n: ProjectionNode = node(ProjectionParams::default());
        feed(n.robot_mut(), &js, &od);
        let mut first_answered = None;
        for c in &cmds {
            match timed("filter_command", || n.filter_command(c)) {
                Ok((t, resp)) => {
                    judge("filter_command", resp.success, &resp.message, &resp)
                        .map_err(TestCaseError::fail)?;
                    prop_assert!(all_finite(&t), "filtered twist not finite: {t:?}");
                    first_answered.get_or_insert(resp.success);
                }
                Err(e) => {
                    prop_assert!(!e.to_string().is_empty());
                    first_answered.get_or_insert(false);
                }
            }
        }
        FILTER_COMMAND.count(first_answered == Some(true));
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
        clean in prop::bool::weighted(CLEAN),
    ) {
        let mut n: PredictionNode = node(PredictionParams::default());
        feed(n.robot_mut(), &js, &od);
        let (use_latest_state, q, v, commands, command_period, horizon, start_covariance) = if clean {
            let horizon = if horizon > 0.0 && horizon <= 0.6 { horizon } else { 0.3 };
            (false, sanitized(&q, 9), rolling_velocity(&v), commands.iter().take(6).map(planar).collect(),
             0.1, horizon, vec![])
        } else {
            (use_latest_state, q, v, commands, command_period, horizon, start_covariance)
        };
        let req = PredictRequest {
            use_latest_state, q, v, commands, command_period, horizon, with_forces,
            with_covariance, start_covariance,
        };
        let r = timed("predict", || n.predict(&req, now));
        judge("predict", r.success, &r.message, &r).map_err(TestCaseError::fail)?;
        PREDICT.count(r.success);
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
        clean in prop::bool::weighted(CLEAN),
    ) {
        // A clean case: 1–8 sequences of 1–5 plausible commands, each held ≤ 0.1 s.
        let (use_latest_state, q, v, commands, sequence_length, step) = if clean {
            let len = if (1..=5).contains(&sequence_length) { sequence_length } else { 2 };
            let n = (commands.len() / len as usize).clamp(1, 8) * len as usize;
            let commands = (0..n)
                .map(|i| commands.get(i).map(planar).unwrap_or_default())
                .collect();
            let step = if step > 0.01 && step <= 0.1 { step } else { 0.05 };
            (false, sanitized(&q, 9), rolling_velocity(&v), commands, len, step)
        } else {
            (use_latest_state, q, v, commands, sequence_length, step)
        };
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
        ROLLOUTS.count(r.success);
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
        let published = out.is_some();
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
        PREDICTOR_TICK.count(published);
    }

    /// `/robot_description`: truncated or byte-mutated bundled URDF, or random text. The new
    /// robot is refused with a typed error, or is used for one prediction.
    #[test]
    fn robot_description_hostile(
        kind in 0..6u8,
        mass in hostile(),
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
            3 => String::from_utf8_lossy(&junk).into_owned(),
            // The bundled URDF whole, its base's mass a drawn number (a plausible one loads).
            _ => URDF.replacen(r#"<mass value="8.0"/>"#, &format!(r#"<mass value="{mass}"/>"#), 1),
        };
        let p = PredictorParams { horizon: 0.3, ..Default::default() };
        let n: PredictorNode = node(p);
        let common = n.params().common.clone();
        let loaded = timed("with_urdf", || n.robot().with_urdf(&urdf, &common));
        ROBOT_DESCRIPTION.count(loaded.is_ok());
        match loaded {
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
