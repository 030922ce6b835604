//! What the binaries run: `[--node KIND] [--ros-args ...]`, until SIGINT or SIGTERM.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use crate::params::NodeKind;
use crate::ros::args::RosArgs;
use crate::ros::heap::HeapTrimmer;
use crate::ros::logging;

use super::start;

/// Set by SIGINT / SIGTERM.
static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: libc::c_int) {
    STOP.store(true, Ordering::SeqCst);
}

/// What the binaries run: `[--node KIND] [--ros-args ...]`. Returns the exit code.
pub fn main(only: Option<NodeKind>) -> std::process::ExitCode {
    use std::process::ExitCode;
    let args = match RosArgs::from_env() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    let mut only = only;
    let mut exit_on_failure = false;
    let mut user = args.user_args.iter();
    while let Some(a) = user.next() {
        match a.as_str() {
            "-h" | "--help" => {
                println!("{}", usage());
                return ExitCode::SUCCESS;
            }
            "--node" => match user.next().and_then(|k| NodeKind::from_key(k)) {
                Some(k) => only = Some(k),
                None => {
                    eprintln!(
                        "error: --node needs one of predictor, forces, projection, prediction\n\n{}",
                        usage()
                    );
                    return ExitCode::from(2);
                }
            },
            "--exit-on-failure" => exit_on_failure = true,
            other => {
                eprintln!("error: unknown argument {other:?}\n\n{}", usage());
                return ExitCode::from(2);
            }
        }
    }
    logging::init(&args.log_levels);
    // SAFETY: the handler only stores to an atomic, which is async-signal-safe.
    unsafe {
        libc::signal(libc::SIGINT, on_signal as *const () as libc::sighandler_t);
        libc::signal(libc::SIGTERM, on_signal as *const () as libc::sighandler_t);
    }
    let suite = match start(&args, only, exit_on_failure) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    };
    log::info!(
        target: "constraint_dynamics_nodes",
        "running {} (Ctrl-C to stop)",
        suite.node_names().join(", ")
    );
    let mut heap = HeapTrimmer::default();
    while !STOP.load(Ordering::SeqCst) {
        std::thread::sleep(Duration::from_millis(50));
        heap.tick();
    }
    log::info!(target: "constraint_dynamics_nodes", "shutting down");
    suite.shutdown();
    ExitCode::SUCCESS
}

/// The command-line help.
pub fn usage() -> String {
    "usage: constraint_dynamics_suite [--node predictor|forces|projection|prediction] \
     [--exit-on-failure] --ros-args --params-file FILE [-p NAME:=VALUE] [-r __ns:=/NS] [-r __node:=NAME (with --node)] \
     [-r FROM:=TO] [--log-level LEVEL]\n\
     \n\
     Starts the constraint_dynamics ROS 2 nodes (docs/nodes.md): cd_predictor (predicted odometry, \
     path, constraint forces), cd_forces (~/get_constraint_forces), cd_projection \
     (~/project_velocity, command filter), cd_prediction (~/predict). Without --node every node \
     whose `enabled` parameter is true runs in this process. A node that fails to configure \
     stays unconfigured (ERROR on /rosout and /diagnostics) while the others run; \
     --exit-on-failure exits instead.\n\
     ROS_DOMAIN_ID selects the domain; network.interfaces / CD_ROS_INTERFACES the interfaces."
        .to_string()
}
