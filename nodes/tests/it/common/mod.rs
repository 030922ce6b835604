//! Shared by the suite tests and the bench: re-executing inside a loopback-only network
//! namespace, running the suite binary as a child process in it, and a ros2-client test node
//! (publishers of the robot's state, service clients, subscriptions with time limits).
#![allow(dead_code)]

use std::fs::File;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::time::{Duration, Instant};

use constraint_dynamics_nodes::msg::RosService;
use constraint_dynamics_nodes::msg::builtin_interfaces::Time;
use constraint_dynamics_nodes::msg::geometry_msgs::{Quaternion, Twist, Vector3};
use constraint_dynamics_nodes::msg::nav_msgs::Odometry;
use constraint_dynamics_nodes::msg::sensor_msgs::JointState;
use constraint_dynamics_nodes::msg::std_msgs::StringMsg;
use constraint_dynamics_nodes::ros::context::{
    NetworkConfig, RosNode, call_with_retry, in_loopback_only_namespace, qos,
};
use ros2_client::{Client, NodeOptions, Publisher, Subscription};
use serde_json::Value;

pub const WAIT: Duration = Duration::from_secs(20);

/// Which module's tests are running, and how many of them.
struct Running {
    module: Option<&'static str>,
    tests: usize,
}

static RUNNING: Mutex<Running> = Mutex::new(Running {
    module: None,
    tests: 0,
});
static MODULE_DONE: Condvar = Condvar::new();

/// Held by a test for its whole run: tests of one module run side by side, tests of two
/// modules never at once. The suites these tests start measure rates, latencies and memory, and
/// each module expects to have the machine to itself, as it had when it was a binary of its own.
pub struct ModuleGroup(&'static str);

/// Waits until no other module's test runs, then joins `module`'s group
/// (`exclusive_group(module_path!())`, first thing in every test of this target).
pub fn exclusive_group(module: &'static str) -> ModuleGroup {
    let mut running = RUNNING.lock().unwrap_or_else(PoisonError::into_inner);
    loop {
        match running.module {
            None => running.module = Some(module),
            Some(m) if m == module => {}
            Some(_) => {
                running = MODULE_DONE
                    .wait(running)
                    .unwrap_or_else(PoisonError::into_inner);
                continue;
            }
        }
        running.tests += 1;
        return ModuleGroup(module);
    }
}

impl Drop for ModuleGroup {
    fn drop(&mut self) {
        let mut running = RUNNING.lock().unwrap_or_else(PoisonError::into_inner);
        debug_assert_eq!(running.module, Some(self.0));
        running.tests -= 1;
        if running.tests == 0 {
            running.module = None;
            MODULE_DONE.notify_all();
        }
    }
}

pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .canonicalize()
        .expect("repo root")
}

/// The DDS tests are `#[ignore]`d in a plain `cargo test` (they need root for a loopback-only
/// network namespace, some the peer venv too); `tools/test.sh` runs them with
/// `--include-ignored`.
///
/// True when the caller should run its body here (we are in a loopback-only namespace).
/// Otherwise re-runs `test_name` of this test binary inside a fresh namespace, asserts it
/// passed and returns false. A missing prerequisite is a failure, never a skip: these tests are
/// `#[ignore]`d, so whoever runs them asked for them.
pub fn in_namespace_or_reexec(test_name: &str) -> bool {
    if in_loopback_only_namespace() {
        return true;
    }
    if std::env::var("CD_NETNS").as_deref() == Ok("1") {
        panic!("CD_NETNS=1 but interfaces other than lo are visible: refusing to open DDS");
    }
    let can_unshare = Command::new("unshare")
        .args(["-n", "true"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    assert!(
        can_unshare,
        "{test_name}: cannot create a network namespace (`unshare -n` needs root); no DDS \
         participant was opened. Run it as root, e.g. through tools/test.sh."
    );
    let exe = std::env::current_exe().expect("test binary path");
    // libtest names a test's thread by the test's path in the target (`module::function`); the
    // inner run selects exactly that test.
    let full_name = std::thread::current()
        .name()
        .filter(|n| n.ends_with(test_name))
        .map(str::to_owned);
    let mut inner = Command::new(repo_root().join("tools/ros2/netns_run.sh"));
    inner.arg(exe);
    match &full_name {
        Some(name) => inner.args([name.as_str(), "--exact"]),
        None => inner.arg(test_name),
    };
    let status = inner
        // The test is #[ignore]d: the inner run must include it.
        .args(["--include-ignored", "--nocapture", "--test-threads=1"])
        .status()
        .expect("run tools/ros2/netns_run.sh");
    assert!(
        status.success(),
        "{test_name} inside the network namespace failed: {status}"
    );
    false
}

/// The rclpy peer's python (`CD_ROS2_VENV`, default `<repo>/.venv-ros2`, made by
/// `tools/ros2/setup_peer_venv.sh`); panics naming the fix when it is missing.
pub fn peer_python(test_name: &str) -> PathBuf {
    let venv = std::env::var_os("CD_ROS2_VENV")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo_root().join(".venv-ros2"));
    let python = venv.join("bin/python");
    assert!(
        python.exists(),
        "{test_name}: no peer venv at {} (make it with tools/ros2/setup_peer_venv.sh, or run \
         tools/test.sh, which does)",
        venv.display()
    );
    python
}

/// The suite binary (built by cargo for this test or bench).
pub fn suite_binary(name: &str) -> PathBuf {
    let dir = std::env::current_exe()
        .expect("exe")
        .parent()
        .expect("deps dir")
        .parent()
        .expect("profile dir")
        .to_path_buf();
    dir.join(name)
}

/// A suite process; interrupted (SIGINT) and reaped on drop. Its stderr goes to a log file
/// that [`SuiteProcess::log`] returns.
pub struct SuiteProcess {
    pub child: Child,
    pub log_path: PathBuf,
    pub started: Instant,
}

impl SuiteProcess {
    /// Starts `binary` (a path, or a name next to this test's binary) with `args`, working
    /// directory the repository root.
    pub fn spawn(binary: &str, args: &[&str], tag: &str) -> SuiteProcess {
        let exe = if Path::new(binary).is_absolute() {
            PathBuf::from(binary)
        } else {
            suite_binary(binary)
        };
        assert!(
            exe.exists(),
            "{} not built (cargo builds the package's binaries for its tests)",
            exe.display()
        );
        let log_path =
            std::env::temp_dir().join(format!("cd_suite_{tag}_{}.log", std::process::id()));
        let log = File::create(&log_path).expect("log file");
        let started = Instant::now();
        let child = Command::new(&exe)
            .args(args)
            .current_dir(repo_root())
            .stdout(log.try_clone().expect("log"))
            .stderr(log)
            .spawn()
            .unwrap_or_else(|e| panic!("start {}: {e}", exe.display()));
        SuiteProcess {
            child,
            log_path,
            started,
        }
    }

    /// What the process wrote so far.
    pub fn log(&self) -> String {
        std::fs::read_to_string(&self.log_path).unwrap_or_default()
    }

    /// Still running?
    pub fn alive(&mut self) -> bool {
        matches!(self.child.try_wait(), Ok(None))
    }

    /// SIGINT, then wait (kill after 5 s); returns the exit status success.
    pub fn stop(&mut self) -> bool {
        self.stop_within(Duration::from_secs(5))
    }

    /// SIGINT, then wait up to `limit` (then kill); returns the exit status success. A worker
    /// finishes the request it is computing before the process exits.
    pub fn stop_within(&mut self, limit: Duration) -> bool {
        if !self.alive() {
            return self.child.wait().map(|s| s.success()).unwrap_or(false);
        }
        unsafe {
            libc::kill(self.child.id() as libc::pid_t, libc::SIGINT);
        }
        let deadline = Instant::now() + limit;
        while Instant::now() < deadline {
            if let Ok(Some(s)) = self.child.try_wait() {
                return s.success();
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
        false
    }

    /// Every thread's stack of the running suite (gdb, bounded to 30 s), for a test that failed
    /// while the suite may be stuck: a hang seen once in CI (patches/README.md, "discovery DB
    /// guard held across a blocking send") left only a log that stopped.
    fn thread_stacks(&mut self) -> String {
        if !self.alive() {
            return "(the suite had exited)".into();
        }
        let pid = self.child.id().to_string();
        match Command::new("timeout")
            .args([
                "30",
                "gdb",
                "-p",
                &pid,
                "-batch",
                "-ex",
                "thread apply all bt",
            ])
            .stdin(Stdio::null())
            .output()
        {
            Ok(o) => String::from_utf8_lossy(&o.stdout)
                .lines()
                .filter(|l| l.starts_with('#') || l.starts_with("Thread "))
                .collect::<Vec<_>>()
                .join("\n"),
            Err(e) => format!("(no stacks: gdb could not run: {e})"),
        }
    }
}

impl Drop for SuiteProcess {
    fn drop(&mut self) {
        if std::thread::panicking() {
            eprintln!(
                "---- suite threads at the failure ----\n{}",
                self.thread_stacks()
            );
        }
        self.stop();
        if std::thread::panicking() {
            eprintln!(
                "---- suite log ({}) ----\n{}",
                self.log_path.display(),
                self.log()
            );
        }
    }
}

/// Runs `fut` on this thread with a time limit.
pub fn block_on_timeout<T>(limit: Duration, fut: impl Future<Output = T>) -> Option<T> {
    smol::block_on(smol::future::or(async { Some(fut.await) }, async {
        smol::Timer::after(limit).await;
        None
    }))
}

/// The test's own ROS node (loopback only, in the namespace).
pub struct TestNode {
    pub node: RosNode,
    pub ctx: ros2_client::Context,
}

impl TestNode {
    pub fn new(name: &str) -> TestNode {
        let net = NetworkConfig::from_env().expect("network config");
        let ctx = net.create_context().expect("context");
        let node =
            RosNode::new(&ctx, "/", name, NodeOptions::new().read_rosout(true)).expect("test node");
        TestNode { node, ctx }
    }

    /// A client of `S` at `name`, once the service is discovered.
    /// On a loaded machine a client's wait can miss the server's discovery for good; a fresh
    /// client (new readers and writers) is discovered again, so it retries every 5 s.
    pub fn client<S: RosService>(&mut self, name: &str) -> Client<S::Request, S::Response> {
        let deadline = Instant::now() + WAIT;
        loop {
            let c = self.node.client::<S>(name).expect("client");
            let per_try =
                Duration::from_secs(5).min(deadline.saturating_duration_since(Instant::now()));
            if block_on_timeout(per_try, c.wait_for_service(&self.node.node)).is_some() {
                return c;
            }
            assert!(
                Instant::now() < deadline,
                "service {name} not discovered within {WAIT:?}"
            );
        }
    }

    /// Subscribes `topic` (reliable).
    pub fn subscribe<M: constraint_dynamics_nodes::msg::RosMessage + 'static>(
        &mut self,
        topic: &str,
    ) -> Subscription<M> {
        self.node
            .subscription::<M>(topic, &qos::reliable(10))
            .expect("subscription")
    }

    /// The rosout reader.
    pub fn rosout(&self) -> &Subscription<ros2_client::Log> {
        self.node
            .node
            .rosout_subscription()
            .expect("rosout reading enabled")
    }
}

/// Calls a service (retrying while discovery settles).
pub fn call<Req, Resp>(client: &Client<Req, Resp>, req: Req) -> Resp
where
    Req: ros2_client::Message + Clone + 'static,
    Resp: ros2_client::Message + 'static,
{
    smol::block_on(call_with_retry(
        client,
        req,
        Duration::from_millis(1500),
        10,
    ))
    .map(|(r, _)| r)
    .unwrap_or_else(|e| panic!("service call: {e}"))
}

/// The first message on `sub` for which `accept` returns true, within `limit`; the last
/// rejected reason on failure.
pub fn take_until<M, F>(sub: &Subscription<M>, limit: Duration, mut accept: F) -> Result<M, String>
where
    M: serde::de::DeserializeOwned + 'static,
    F: FnMut(&M) -> Result<(), String>,
{
    let deadline = Instant::now() + limit;
    let mut last = "no message".to_string();
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(last);
        }
        match block_on_timeout(left, sub.async_take()) {
            None => return Err(format!("timeout; last: {last}")),
            Some(Err(e)) => last = format!("read error {e:?}"),
            Some(Ok((m, _))) => match accept(&m) {
                Ok(()) => return Ok(m),
                Err(why) => last = why,
            },
        }
    }
}

/// What the test publishes as the robot's measured state and command.
#[derive(Clone, Debug, Default)]
pub struct RobotFeed {
    pub joint_state: Option<JointState>,
    pub odom: Option<Odometry>,
    pub cmd_vel: Option<Twist>,
}

/// Publishes the feed at 50 Hz (the latest content of the shared slot) until dropped.
pub struct FeedPublisher {
    pub feed: Arc<Mutex<RobotFeed>>,
    _task: smol::Task<()>,
}

impl FeedPublisher {
    pub fn start(node: &mut TestNode) -> FeedPublisher {
        let js: Publisher<JointState> = node
            .node
            .publisher("/joint_states", &qos::reliable(10))
            .expect("pub");
        let od: Publisher<Odometry> = node
            .node
            .publisher("/odom", &qos::reliable(10))
            .expect("pub");
        let cmd: Publisher<Twist> = node
            .node
            .publisher("/cmd_vel", &qos::reliable(10))
            .expect("pub");
        let feed = Arc::new(Mutex::new(RobotFeed::default()));
        let f = feed.clone();
        let task = node.node.spawn(async move {
            loop {
                let now = Time::now();
                let snapshot = f.lock().unwrap().clone();
                if let Some(mut m) = snapshot.joint_state {
                    m.header.stamp = now;
                    let _ = js.async_publish(m).await;
                }
                if let Some(mut m) = snapshot.odom {
                    m.header.stamp = now;
                    let _ = od.async_publish(m).await;
                }
                if let Some(m) = snapshot.cmd_vel {
                    let _ = cmd.async_publish(m).await;
                }
                smol::Timer::after(Duration::from_millis(20)).await;
            }
        });
        FeedPublisher { feed, _task: task }
    }

    pub fn set(&self, feed: RobotFeed) {
        *self.feed.lock().unwrap() = feed;
    }
}

/// A publisher of `/robot_description` (transient local, as robot_state_publisher).
pub fn description_publisher(node: &mut TestNode) -> Publisher<StringMsg> {
    node.node
        .publisher("/robot_description", &qos::transient_local())
        .expect("robot_description publisher")
}

/// The yaw [rad] of an orientation: its rotation about z, in [−π, π].
pub fn yaw(q: &Quaternion) -> f64 {
    (2.0 * (q.w * q.z + q.x * q.y)).atan2(1.0 - 2.0 * (q.y * q.y + q.z * q.z))
}

pub fn twist(v: f64, w: f64) -> Twist {
    Twist {
        linear: Vector3 {
            x: v,
            y: 0.0,
            z: 0.0,
        },
        angular: Vector3 {
            x: 0.0,
            y: 0.0,
            z: w,
        },
    }
}

/// |a − b| ≤ tol·(1 + |b|) entrywise, naming the first difference.
pub fn close(what: &str, a: &[f64], b: &[f64], tol: f64) -> Result<(), String> {
    if a.len() != b.len() {
        return Err(format!("{what}: length {} vs {}", a.len(), b.len()));
    }
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        let ok = (x - y).abs() <= tol * (1.0 + y.abs());
        if !ok {
            return Err(format!("{what}[{i}]: {x} vs {y} (diff {:e})", x - y));
        }
    }
    Ok(())
}

pub fn assert_close(what: &str, a: &[f64], b: &[f64], tol: f64) {
    if let Err(e) = close(what, a, b, tol) {
        panic!("{e}");
    }
}

/// The resident set of process `pid` [kB] (`VmRSS` of /proc/PID/status).
pub fn rss_kb(pid: u32) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status"))
        .unwrap_or_else(|e| panic!("read /proc/{pid}/status: {e}"));
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .unwrap_or_else(|| panic!("no VmRSS in /proc/{pid}/status"))
}

/// Sets parameter `name` of node `fqn` (`/cd_predictor`) through its `set_parameters`
/// service: (accepted, reason).
pub fn set_param(
    client: &Client<
        ros2_client::rcl_interfaces::SetParametersRequest,
        ros2_client::rcl_interfaces::SetParametersResponse,
    >,
    name: &str,
    value: ros2_client::ParameterValue,
) -> (bool, String) {
    let r = call(
        client,
        ros2_client::rcl_interfaces::SetParametersRequest {
            parameter: vec![ros2_client::parameters::raw::Parameter {
                name: name.into(),
                value: value.into(),
            }],
        },
    );
    let r = r.results.first().expect("one result per parameter");
    (r.successful, r.reason.clone())
}

impl SuiteProcess {
    /// SIGINT, then the time until the process exited (None: still running after `limit`,
    /// then killed) and whether it exited successfully.
    pub fn interrupt_timed(&mut self, limit: Duration) -> (Option<Duration>, bool) {
        assert!(
            self.alive(),
            "the suite exited before SIGINT:\n{}",
            self.log()
        );
        let sent = Instant::now();
        unsafe {
            libc::kill(self.child.id() as libc::pid_t, libc::SIGINT);
        }
        while sent.elapsed() < limit {
            if let Ok(Some(s)) = self.child.try_wait() {
                return (Some(sent.elapsed()), s.success());
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
        (None, false)
    }
}

/// Run the rclpy peer `nodes/tests/peers/<script>` with `args` under `python`, killed if it has
/// not finished within `limit`, and return its report: the JSON on the last line of its stdout.
/// The stdout is read while the peer runs (a report can exceed a pipe buffer).
pub fn peer_report(python: &Path, script: &str, args: &[String], limit: Duration) -> Value {
    let child = Command::new(python)
        .arg(repo_root().join("nodes/tests/peers").join(script))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap_or_else(|e| panic!("start {script}: {e}"));
    let pid = child.id();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(child.wait_with_output());
    });
    let out = match rx.recv_timeout(limit) {
        Ok(out) => out.unwrap_or_else(|e| panic!("{script} output: {e}")),
        Err(_) => {
            unsafe {
                libc::kill(pid as libc::pid_t, libc::SIGKILL);
            }
            panic!("{script} did not finish within {} s", limit.as_secs_f64());
        }
    };
    let stdout = String::from_utf8_lossy(&out.stdout);
    serde_json::from_str(stdout.lines().last().unwrap_or("")).unwrap_or_else(|e| {
        panic!(
            "{script} ({}): last line is not JSON ({e}): {stdout}",
            out.status
        )
    })
}
