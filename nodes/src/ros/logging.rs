//! Logging: the `log` crate to stderr and, for node messages, to `/rosout`.
//!
//! Domain code (the engine, the workers) logs through [`NodeLog`], which tags each record
//! with the node's name; the glue registers each node's rosout handle with [`register`], and
//! the process logger forwards tagged records to it. Records of other crates (ros2-client,
//! RustDDS) go to stderr only, at `warn` and above unless `--log-level` asks for more.

use std::collections::HashMap;
use std::sync::{Mutex, OnceLock};
use std::time::{Duration, Instant};

use log::{Level, LevelFilter, Metadata, Record};
use ros2_client::log::LogLevel;
use ros2_client::rosout::{NodeLoggingHandle, RosoutRaw};

const NODE_TARGET_PREFIX: &str = "cd_node:";

struct Logger {
    /// Level of the nodes' own records.
    level: Mutex<LevelFilter>,
    /// Level of other crates' records.
    external: Mutex<LevelFilter>,
    sinks: Mutex<HashMap<String, NodeLoggingHandle>>,
}

static LOGGER: OnceLock<Logger> = OnceLock::new();

fn logger() -> &'static Logger {
    LOGGER.get_or_init(|| Logger {
        level: Mutex::new(LevelFilter::Info),
        external: Mutex::new(LevelFilter::Warn),
        sinks: Mutex::new(HashMap::new()),
    })
}

/// Installs the process logger (once; later calls only change the levels). `levels` are
/// `--log-level` values: `debug`, `info`, ... (the nodes' level) or `LOGGER:=LEVEL`
/// (`rustdds:=debug`, `ros2_client:=info` raise the external level).
pub fn init(levels: &[String]) {
    let l = logger();
    for spec in levels {
        let (who, level) = match spec.split_once(":=") {
            Some((w, lv)) => (Some(w), lv),
            None => (None, spec.as_str()),
        };
        let Ok(level) = level.trim().parse::<LevelFilter>() else {
            eprintln!("--log-level {spec}: unknown level (debug, info, warn, error)");
            continue;
        };
        match who {
            None => *l.level.lock().unwrap_or_else(|e| e.into_inner()) = level,
            Some(_) => *l.external.lock().unwrap_or_else(|e| e.into_inner()) = level,
        }
    }
    // The `log` macros compare with the max level before they call the logger: at the levels
    // asked for, RustDDS's per-datagram debug! and trace! lines cost a comparison, not a call
    // (with its lock) that then drops them.
    let _ = log::set_logger(l);
    log::set_max_level(l.max_level());
}

/// Sends the records of node `name` to its `/rosout` handle too.
pub fn register(name: &str, handle: NodeLoggingHandle) {
    logger()
        .sinks
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .insert(name.to_string(), handle);
}

/// Stops sending records of node `name` to `/rosout` (before its node is dropped).
pub fn unregister(name: &str) {
    logger()
        .sinks
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .remove(name);
}

impl Logger {
    /// The most verbose level any record is logged at.
    fn max_level(&self) -> LevelFilter {
        let level = *self.level.lock().unwrap_or_else(|e| e.into_inner());
        let external = *self.external.lock().unwrap_or_else(|e| e.into_inner());
        level.max(external)
    }
}

impl log::Log for Logger {
    fn enabled(&self, m: &Metadata) -> bool {
        // RustDDS warns about every datagram above a size threshold (paths, forces), and
        // ros2-client about every request from a client that sends no related sample identity
        // (ros2-client's own clients): noise, not faults.
        if (m.target().starts_with("rustdds::network::udp_sender")
            || m.target().starts_with("ros2_client::service::wrappers"))
            && m.level() > Level::Error
        {
            return false;
        }
        let limit = if m.target().starts_with(NODE_TARGET_PREFIX)
            || m.target().starts_with("constraint_dynamics")
        {
            *self.level.lock().unwrap_or_else(|e| e.into_inner())
        } else {
            *self.external.lock().unwrap_or_else(|e| e.into_inner())
        };
        m.level() <= limit
    }

    fn log(&self, r: &Record) {
        if !self.enabled(r.metadata()) {
            return;
        }
        let node = r.target().strip_prefix(NODE_TARGET_PREFIX);
        let now = crate::msg::builtin_interfaces::Time::now();
        eprintln!(
            "[{}] [{}.{:09}] [{}]: {}",
            r.level(),
            now.sec,
            now.nanosec,
            node.unwrap_or(r.target()),
            r.args()
        );
        if let Some(name) = node {
            let sinks = self.sinks.lock().unwrap_or_else(|e| e.into_inner());
            if let Some(handle) = sinks.get(name) {
                let level = match r.level() {
                    Level::Error => LogLevel::Error,
                    Level::Warn => LogLevel::Warn,
                    Level::Info => LogLevel::Info,
                    Level::Debug | Level::Trace => LogLevel::Debug,
                };
                handle.rosout_raw(
                    ros2_client::builtin_interfaces::Time::now(),
                    level,
                    name,
                    &r.args().to_string(),
                    r.file().unwrap_or(""),
                    r.module_path().unwrap_or(""),
                    r.line().unwrap_or(0),
                );
            }
        }
    }

    fn flush(&self) {}
}

/// A node's logger: records go to stderr and to the node's `/rosout`.
#[derive(Clone, Debug)]
pub struct NodeLog {
    target: String,
}

impl NodeLog {
    /// For the node with this name (as registered with [`register`]).
    pub fn new(node_name: &str) -> Self {
        NodeLog {
            target: format!("{NODE_TARGET_PREFIX}{node_name}"),
        }
    }

    /// Logs `msg` at `level`.
    pub fn log(&self, level: Level, msg: &str) {
        log::log!(target: &self.target, level, "{msg}");
    }
    /// Logs an error.
    pub fn error(&self, msg: &str) {
        self.log(Level::Error, msg)
    }
    /// Logs a warning.
    pub fn warn(&self, msg: &str) {
        self.log(Level::Warn, msg)
    }
    /// Logs information.
    pub fn info(&self, msg: &str) {
        self.log(Level::Info, msg)
    }
    /// Logs a debugging detail.
    pub fn debug(&self, msg: &str) {
        self.log(Level::Debug, msg)
    }
}

/// Rate limit of the lines about dropped messages, per (message kind, reason): the first drop
/// of a kind for a reason is logged at WARN, the same reason again within `window` at DEBUG
/// only; a different reason gets its WARN at once. The reason is the error text with its
/// numbers masked ([`reason_key`]), so a changing value (a variance of −0.1, then −0.2) is the
/// same reason and a stream of bad messages logs one WARN per window.
#[derive(Debug)]
pub struct DropLog {
    window: Duration,
    /// When each (kind, reason) last had its WARN.
    last: HashMap<(&'static str, String), Instant>,
}

impl DropLog {
    /// Window of the lines about dropped input messages.
    pub const WINDOW: Duration = Duration::from_secs(10);

    /// One WARN per (kind, reason) per `window`.
    pub fn new(window: Duration) -> Self {
        DropLog {
            window,
            last: HashMap::new(),
        }
    }

    /// The level of the line about a `kind` message dropped at `now` because of `reason`: WARN
    /// when this (kind, reason) had no WARN within the window (it counts as logged at `now`),
    /// DEBUG otherwise.
    pub fn level(&mut self, kind: &'static str, reason: &str, now: Instant) -> Level {
        let window = self.window;
        self.last
            .retain(|_, at| now.saturating_duration_since(*at) < window);
        match self.last.entry((kind, reason_key(reason))) {
            std::collections::hash_map::Entry::Occupied(_) => Level::Debug,
            std::collections::hash_map::Entry::Vacant(v) => {
                v.insert(now);
                Level::Warn
            }
        }
    }
}

impl Default for DropLog {
    fn default() -> Self {
        DropLog::new(DropLog::WINDOW)
    }
}

/// `reason` with every number (a run of digits, with its decimal point) replaced by `#`:
/// `pose.covariance[35]: is -0.001` → `pose.covariance[#]: is -#`. Words stay, so `NaN`,
/// `inf` and a sign still tell reasons apart.
pub fn reason_key(reason: &str) -> String {
    let mut key = String::with_capacity(reason.len());
    let mut in_number = false;
    for c in reason.chars() {
        if c.is_ascii_digit() || (in_number && c == '.') {
            if !in_number {
                key.push('#');
                in_number = true;
            }
        } else {
            in_number = false;
            key.push(c);
        }
    }
    key
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::nav_msgs::Odometry;
    use crate::robot::state::StateEstimate;
    use constraint_dynamics::Scene;

    /// Why `od` is refused by a diff-drive robot's state.
    fn refusal(od: &Odometry) -> String {
        let path = format!("{}/../params/diff_drive.yaml", env!("CARGO_MANIFEST_DIR"));
        let model = Scene::load(&path).unwrap().model;
        let mut st = StateEstimate::new(&model, &vec![0.0; model.nq], &vec![0.0; model.nv]);
        st.apply_odometry(&model, od).unwrap_err().to_string()
    }

    fn odometry() -> Odometry {
        let mut od = Odometry::default();
        od.pose.pose.orientation.w = 1.0;
        od
    }

    /// A NaN odometry then one with a negative variance, within the window: both are WARN
    /// lines. The same reason again (another negative value) within the window is DEBUG only,
    /// and WARN again once the window has passed; a joint state is a kind of its own.
    #[test]
    fn a_new_reason_is_logged_within_the_window() {
        let mut nan = odometry();
        nan.pose.pose.position.x = f64::NAN;
        let nan = refusal(&nan);
        let negative = |v: f64| {
            let mut od = odometry();
            od.pose.covariance[35] = v;
            refusal(&od)
        };
        let (neg1, neg2) = (negative(-1e-3), negative(-0.25));
        assert_ne!(neg1, neg2, "the values differ in the text");

        let mut log = DropLog::new(Duration::from_secs(3));
        let t0 = Instant::now();
        let at = |s: f64| t0 + Duration::from_secs_f64(s);
        assert_eq!(log.level("odometry", &nan, at(0.0)), Level::Warn, "{nan}");
        assert_eq!(log.level("odometry", &neg1, at(0.5)), Level::Warn, "{neg1}");
        assert_eq!(
            log.level("odometry", &neg2, at(1.0)),
            Level::Debug,
            "{neg2}"
        );
        assert_eq!(log.level("odometry", &nan, at(1.5)), Level::Debug, "{nan}");
        assert_eq!(log.level("joint_state", &nan, at(1.6)), Level::Warn);
        assert_eq!(log.level("odometry", &neg1, at(2.9)), Level::Debug);
        assert_eq!(
            log.level("odometry", &nan, at(3.1)),
            Level::Warn,
            "window over"
        );
        assert_eq!(
            log.level("odometry", &neg1, at(3.6)),
            Level::Warn,
            "window over"
        );
        assert_eq!(log.level("odometry", &neg2, at(3.7)), Level::Debug);
    }

    #[test]
    fn reason_key_masks_numbers_only() {
        assert_eq!(
            reason_key("Odometry: pose.covariance[35]: is -0.001 (must be ≥ 0)"),
            "Odometry: pose.covariance[#]: is -# (must be ≥ #)"
        );
        assert_eq!(reason_key("is NaN"), "is NaN");
        assert_eq!(
            reason_key("3 entries for 12 names."),
            "# entries for # names."
        );
    }
}
