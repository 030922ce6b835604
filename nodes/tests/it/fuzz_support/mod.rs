//! The fuzz harness of `fuzz_requests.rs`: the scene, the strategies of hostile floats,
//! arrays, names, twists, stamps and messages, the judgement of a response (refused with a
//! reason, or every float finite), the per-call CPU bound and the answered/refused tally.

use constraint_dynamics_nodes::msg::builtin_interfaces::Time;
use constraint_dynamics_nodes::msg::geometry_msgs::{Twist, Vector3};
use constraint_dynamics_nodes::msg::nav_msgs::Odometry;
use constraint_dynamics_nodes::msg::sensor_msgs::JointState;
use constraint_dynamics_nodes::msg::std_msgs::Header;
use constraint_dynamics_nodes::node::worker::NodeLogic;
use constraint_dynamics_nodes::params::{CommonParams, KindParams, NodeParams};
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
pub const BOUND: Duration = Duration::from_secs(2);

/// The bound on one `~/rollouts` call, whose work runs on its own worker threads: CPU time of
/// the whole process, which also counts the other targets running beside it (an over-count).
pub const ROLLOUTS_BOUND: Duration = Duration::from_secs(8);

/// CPU time used so far by the calling thread (`CLOCK_THREAD_CPUTIME_ID`) or the process.
pub fn cpu_time(clock: libc::clockid_t) -> Duration {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec; the clock ids need nothing else.
    let rc = unsafe { libc::clock_gettime(clock, &mut ts) };
    assert_eq!(rc, 0, "clock_gettime({clock}) failed");
    Duration::new(ts.tv_sec as u64, ts.tv_nsec as u32)
}

pub const SCENE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../params/suite_mobile_manipulator.yaml"
);
pub const URDF: &str = include_str!("../../../../urdf/mobile_manipulator.urdf");

/// An array of the given base coordinates followed by the scene's joints.
macro_rules! with_joints {
    ($($base:literal),*) => {
        [$($base,)* "left_wheel_joint", "right_wheel_joint", "arm_shoulder_yaw",
         "arm_shoulder_pitch", "arm_elbow", "arm_wrist"]
    };
}
/// The scene's coordinates (nq = nv = 9, planar base).
pub const Q_NAMES: [&str; 9] = with_joints!("root_joint:x", "root_joint:y", "root_joint:yaw");
/// Its velocity coordinates (the planar base's are in the base frame).
pub const V_NAMES: [&str; 9] = with_joints!(
    "root_joint:vx_local",
    "root_joint:vy_local",
    "root_joint:wz"
);
pub const JOINTS: [&str; 6] = with_joints!();

pub fn config() -> Config {
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

pub fn node<N: NodeLogic>(kind: N::Params) -> N
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
pub fn hostile() -> impl Strategy<Value = f64> {
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
pub fn length(n: usize) -> impl Strategy<Value = usize> {
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
pub fn fixed(n: usize) -> impl Strategy<Value = Vec<f64>> {
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
pub fn sanitized(v: &[f64], n: usize) -> Vec<f64> {
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
pub fn rolling_velocity(v: &[f64]) -> Vec<f64> {
    let mut v = sanitized(v, 9);
    v[..5].fill(0.0);
    v
}

/// The twist a differential drive follows: `t`'s linear.x and angular.z (sanitized), the rest 0.
pub fn planar(t: &Twist) -> Twist {
    let s = sanitized(&[t.linear.x, t.angular.z], 2);
    let mut out = Twist::default();
    (out.linear.x, out.angular.z) = (s[0], s[1]);
    out
}

/// Floats for an array of n: [`fixed`] mostly, else of a wrong length ([`length`]).
pub fn floats(n: usize) -> impl Strategy<Value = Vec<f64>> {
    prop_oneof![
        3 => fixed(n),
        1 => length(n).prop_flat_map(|len| prop::collection::vec(hostile(), len)),
    ]
}

/// A joint name: a real one mostly, else unknown, empty or random unicode.
pub fn name(real: &'static [&'static str]) -> impl Strategy<Value = String> {
    prop_oneof![
        8 => prop::sample::select(real).prop_map(String::from),
        1 => Just(String::new()),
        1 => Just("no_such_joint".to_string()),
        1 => any::<String>(),
    ]
}

/// Names in order (possibly permuted / duplicated / wrong), or none (= the node's order).
pub fn names(real: &'static [&'static str]) -> impl Strategy<Value = Vec<String>> {
    prop_oneof![
        3 => Just(Vec::new()),
        3 => Just(real.iter().map(|s| s.to_string()).collect::<Vec<_>>()),
        2 => Just(real.to_vec()).prop_shuffle().prop_map(|v| v.iter().map(|s| s.to_string()).collect()),
        3 => length(real.len()).prop_flat_map(move |n| prop::collection::vec(name(real), n.min(200))),
    ]
}

/// A twist: mostly one a differential drive follows (linear.x, angular.z), else [`fixed`].
pub fn twist() -> impl Strategy<Value = Twist> {
    prop_oneof![
        2 => (-1.0..1.0f64, -2.0..2.0f64).prop_map(|(vx, wz)| {
            let mut t = Twist::default();
            (t.linear.x, t.angular.z) = (vx, wz);
            t
        }),
        1 => any_twist(),
    ]
}

pub fn any_twist() -> impl Strategy<Value = Twist> {
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

pub fn stamp() -> impl Strategy<Value = Time> {
    prop_oneof![
        4 => (0i64..4_000_000_000_000).prop_map(Time::from_nanos),
        1 => Just(Time::from_nanos(0)),
        1 => Just(Time::from_nanos(-1)),
        1 => Just(Time::from_nanos(i64::MAX)),
        1 => Just(Time::from_nanos(i64::MIN)),
    ]
}

/// The response's every float finite: NaN and ±∞ serialise to JSON `null`.
pub fn all_finite(v: &impl Serialize) -> bool {
    pub fn walk(v: &serde_json::Value) -> bool {
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
pub struct Tally {
    target: &'static str,
    refused: AtomicUsize,
    answered: AtomicUsize,
}

impl Tally {
    pub const fn new(target: &'static str) -> Self {
        Self {
            target,
            refused: AtomicUsize::new(0),
            answered: AtomicUsize::new(0),
        }
    }

    /// Count one case; after the run's last case, print the counts and require both outcomes
    /// at least [`MIN_SHARE`] of the cases (shrinking after a failure counts more: no check).
    pub fn count(&self, success: bool) {
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

/// The least share of a target's cases that must be answered, and refused. The rarest outcome,
/// the predictor tick's refusals, comes at 8.0 % of 512 cases and 4.9 % of 4 096
/// (`tools/fuzz_long.sh 30`, seed 797349, where a 5 % bar failed with no other finding): 2 % is
/// three standard deviations below it at 512 cases and still catches strategies that stop
/// reaching an outcome.
pub const MIN_SHARE: f64 = 0.02;

/// The share of cases whose drawn request is made valid before the call (`sanitized`): the
/// computation behind the checks is fuzzed too, with plausible but random states and commands.
pub const CLEAN: f64 = 0.3;

/// Refused with a reason, or every float finite.
pub fn judge(
    what: &str,
    success: bool,
    message: &str,
    resp: &impl Serialize,
) -> Result<(), String> {
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

pub fn timed<T>(what: &str, f: impl FnOnce() -> T) -> T {
    timed_on(libc::CLOCK_THREAD_CPUTIME_ID, BOUND, what, f)
}

pub fn timed_on<T>(
    clock: libc::clockid_t,
    bound: Duration,
    what: &str,
    f: impl FnOnce() -> T,
) -> T {
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
pub fn joint_state() -> impl Strategy<Value = JointState> {
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
pub fn odometry() -> impl Strategy<Value = Odometry> {
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
pub fn feed(robot: &mut Robot, js: &[JointState], od: &[Odometry]) {
    for j in js {
        let _ = timed("joint state", || robot.state_mut().apply_joint_state(j));
    }
    for o in od {
        let model = robot.model().clone();
        let _ = timed("odometry", || robot.state_mut().apply_odometry(&model, o));
    }
}
