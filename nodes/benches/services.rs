//! Service round trips and startup of the suite, measured from a ros2-client client in the
//! same loopback-only network namespace (the bench re-executes itself in one):
//!
//! ```sh
//! CARGO_TARGET_DIR=target-nodes cargo bench -p constraint_dynamics_nodes --bench services
//! ```
//!
//! Starts `constraint_dynamics_suite --ros-args --params-file params/default.yaml` (bundled
//! mobile manipulator, its default state), then reports
//! - startup: process start → first `~/predicted_odom` received,
//! - round trip p50 / p99 / max of `~/get_constraint_forces` (latest state) and
//!   `~/project_velocity` (base twist at the latest state), `CD_BENCH_CALLS` calls each
//!   (default 2000) after 50 warm-up calls, and of `~/predict` (1 s horizon, 20 calls),
//! - the same computations in-process (engine only, no ROS) for the overhead.

#[path = "../tests/it/common/mod.rs"]
mod common;

use std::process::{Command, ExitCode};
use std::time::{Duration, Instant};

use common::*;
use constraint_dynamics_nodes::forces::ForcesNode;
use constraint_dynamics_nodes::msg::builtin_interfaces::Time;
use constraint_dynamics_nodes::msg::constraint_dynamics_msgs::srv::{
    GetConstraintForces, GetConstraintForcesRequest, Predict, PredictRequest, ProjectVelocity,
    ProjectVelocityRequest,
};
use constraint_dynamics_nodes::msg::nav_msgs::Odometry;
use constraint_dynamics_nodes::node::worker::NodeLogic;
use constraint_dynamics_nodes::params::{CommonParams, NodeParams};
use constraint_dynamics_nodes::projection::ProjectionNode;
use constraint_dynamics_nodes::robot::Robot;
use constraint_dynamics_nodes::ros::context::in_loopback_only_namespace;
use constraint_dynamics_nodes::ros::logging::NodeLog;

struct Stats {
    p50: f64,
    p99: f64,
    max: f64,
    n: usize,
}

fn stats(mut xs: Vec<f64>) -> Stats {
    xs.sort_by(f64::total_cmp);
    let q = |p: f64| xs[((xs.len() as f64 - 1.0) * p).round() as usize];
    Stats {
        p50: q(0.5),
        p99: q(0.99),
        max: *xs.last().unwrap(),
        n: xs.len(),
    }
}

fn time_calls<Req, Resp>(
    client: &ros2_client::Client<Req, Resp>,
    req: &Req,
    n: usize,
    ok: impl Fn(&Resp) -> bool,
) -> Stats
where
    Req: ros2_client::Message + Clone + 'static,
    Resp: ros2_client::Message + 'static,
{
    for _ in 0..50 {
        assert!(ok(&call(client, req.clone())), "warm-up call failed");
    }
    let mut xs = Vec::with_capacity(n);
    for _ in 0..n {
        let t0 = Instant::now();
        let r = smol::block_on(client.async_call_service(req.clone())).expect("call");
        xs.push(t0.elapsed().as_secs_f64() * 1e3);
        assert!(ok(&r));
    }
    stats(xs)
}

fn time_local(n: usize, mut f: impl FnMut()) -> Stats {
    for _ in 0..50 {
        f();
    }
    let mut xs = Vec::with_capacity(n);
    for _ in 0..n {
        let t0 = Instant::now();
        f();
        xs.push(t0.elapsed().as_secs_f64() * 1e3);
    }
    stats(xs)
}

fn main() -> ExitCode {
    if !in_loopback_only_namespace() {
        let can_unshare = Command::new("unshare")
            .args(["-n", "true"])
            .status()
            .is_ok_and(|s| s.success());
        if !can_unshare {
            eprintln!("SKIPPED services bench: cannot create a network namespace (needs root)");
            return ExitCode::SUCCESS;
        }
        let exe = std::env::current_exe().expect("exe");
        let status = Command::new(repo_root().join("tools/ros2/netns_run.sh"))
            .arg(exe)
            .status()
            .expect("netns_run.sh");
        return if status.success() {
            ExitCode::SUCCESS
        } else {
            ExitCode::FAILURE
        };
    }
    let n: usize = std::env::var("CD_BENCH_CALLS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(2000);

    let mut t = TestNode::new("cd_bench");
    let odom = t.subscribe::<Odometry>("/cd_predictor/predicted_odom");
    let suite = SuiteProcess::spawn(
        env!("CARGO_BIN_EXE_constraint_dynamics_suite"),
        &["--ros-args", "--params-file", "params/default.yaml"],
        "bench",
    );
    take_until(&odom, WAIT, |_| Ok(())).expect("no predicted odometry");
    let startup = suite.started.elapsed().as_secs_f64();

    let forces = t.client::<GetConstraintForces>("/cd_forces/get_constraint_forces");
    let project = t.client::<ProjectVelocity>("/cd_projection/project_velocity");
    let predict = t.client::<Predict>("/cd_prediction/predict");
    let forces_req = GetConstraintForcesRequest {
        use_latest_state: true,
        ..Default::default()
    };
    let project_req = ProjectVelocityRequest {
        use_latest_state: true,
        use_twist: true,
        base_twist: twist(0.3, 0.2),
        ..Default::default()
    };
    let predict_req = PredictRequest {
        use_latest_state: true,
        commands: vec![twist(0.3, 0.2)],
        horizon: 1.0,
        ..Default::default()
    };
    let f = time_calls(&forces, &forces_req, n, |r| r.success);
    let p = time_calls(&project, &project_req, n, |r| r.success);
    let pr = time_calls(&predict, &predict_req, 20, |r| r.success);
    drop(suite);

    // The same work without ROS (the logic a node's worker owns).
    let mut common = CommonParams::default();
    common.model.scene_file = repo_root()
        .join("params/suite_mobile_manipulator.yaml")
        .display()
        .to_string();
    let robot = Robot::load(&common).expect("robot");
    let log = NodeLog::new("bench");
    let forces_params = NodeParams {
        common: common.clone(),
        node: Default::default(),
    };
    let mut forces_node =
        ForcesNode::new(robot.clone(), forces_params, log.clone()).expect("forces");
    let projection_params = NodeParams {
        common,
        node: Default::default(),
    };
    let mut projection_node =
        ProjectionNode::new(robot, projection_params, log).expect("projection");
    let lf = time_local(n, || {
        assert!(
            forces_node
                .get_constraint_forces(&forces_req, Time::now())
                .success
        )
    });
    let lp = time_local(n, || {
        assert!(projection_node.project_velocity(&project_req).success)
    });

    let row = |name: &str, s: &Stats| {
        format!(
            "| {name} | {} | {:.3} | {:.3} | {:.3} |",
            s.n, s.p50, s.p99, s.max
        )
    };
    println!("\nconstraint_dynamics_suite services (ms), client in the same loopback namespace:\n");
    println!("| call | n | p50 [ms] | p99 [ms] | max [ms] |");
    println!("|---|---|---|---|---|");
    println!("{}", row("get_constraint_forces (ROS round trip)", &f));
    println!("{}", row("project_velocity (ROS round trip)", &p));
    println!("{}", row("predict, 1 s horizon (ROS round trip)", &pr));
    println!("{}", row("get_constraint_forces (engine only)", &lf));
    println!("{}", row("project_velocity (engine only)", &lp));
    println!(
        "\nstartup: process start → first predicted_odom: {:.3} s",
        startup
    );
    std::thread::sleep(Duration::from_millis(10));
    ExitCode::SUCCESS
}
