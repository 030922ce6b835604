//! Logging: the `log` crate to stderr and, for node messages, to `/rosout`.
//!
//! Domain code (the engine, the workers) logs through [`NodeLog`], which tags each record
//! with the node's name; the glue registers each node's rosout handle with [`register`], and
//! the process logger forwards tagged records to it. Records of other crates (ros2-client,
//! RustDDS) go to stderr only, at `warn` and above unless `--log-level` asks for more.

use std::collections::HashMap;
use std::sync::{Mutex, OnceLock};

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
    if log::set_logger(l).is_ok() {
        log::set_max_level(LevelFilter::Trace);
    }
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
