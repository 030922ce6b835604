//! The suite as a child process of a test: its binary, started with its log in a file,
//! interrupted (SIGINT) and reaped on drop with its threads' stacks and log printed when the
//! test failed, and its memory.

use std::fs::File;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use super::repo_root;

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
