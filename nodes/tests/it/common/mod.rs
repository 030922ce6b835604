//! Shared by the suite tests and the bench: one module's tests at a time, re-executing inside
//! a loopback-only network namespace, the rclpy peer, running the suite binary as a child
//! process in it ([`suite_process`]), a ros2-client test node (publishers of the robot's state,
//! service clients, subscriptions with time limits: [`test_node`]) and value comparisons.
#![allow(dead_code)]

mod suite_process;
mod test_node;

pub use suite_process::*;
pub use test_node::*;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::{Condvar, Mutex, PoisonError};
use std::time::Duration;

use constraint_dynamics_nodes::msg::geometry_msgs::{Quaternion, Twist, Vector3};
use constraint_dynamics_nodes::ros::context::in_loopback_only_namespace;
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
