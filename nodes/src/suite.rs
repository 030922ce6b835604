//! The ROS glue: starts the nodes the parameters enable (all in one process, one DDS
//! participant), each with its worker thread, and is the only place that owns ROS handles.
//!
//! Per node: subscriptions turn messages into [`Event`]s for the worker; service servers turn
//! requests into events with a reply channel and send back what the worker answers; the
//! worker's [`Output`]s are published. Everything here runs on the node's executor thread and
//! never blocks on the worker (`try_send`; a full queue answers "busy").

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::SyncSender;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use ros2_client::{Context, NodeOptions, ParameterValue};

use crate::engine::Engine;
use crate::logging::{self, NodeLog};
use crate::msg::RosService;
use crate::msg::constraint_dynamics_msgs::ConstraintForces;
use crate::msg::constraint_dynamics_msgs::srv::{
    GetConstraintForces, GetConstraintForcesResponse, Predict, PredictResponse, ProjectVelocity,
    ProjectVelocityResponse,
};
use crate::msg::geometry_msgs::{Twist, TwistStamped};
use crate::msg::nav_msgs::{Odometry, Path};
use crate::msg::rosgraph_msgs::Clock;
use crate::msg::sensor_msgs::JointState;
use crate::msg::std_msgs::StringMsg;
use crate::params::{NetworkParams, NodeKind, NodeParams, resolve_path};
use crate::ros_args::{Parameters, RosArgs};
use crate::ros_context::{NetworkConfig, RosNode, in_loopback_only_namespace, qos};
use crate::worker::{Event, Output, Reply, WorkerHandle};

/// Environment variable that allows DDS on non-loopback interfaces (like
/// `network.allow_external`).
pub const ALLOW_EXTERNAL_ENV: &str = "CD_ALLOW_EXTERNAL_NETWORK";

/// A running node: its worker, executor tasks and ROS node (dropped in that order).
struct RunningNode {
    name: String,
    worker: WorkerHandle,
    tasks: Vec<smol::Task<()>>,
    ros: Option<RosNode>,
}

impl RunningNode {
    fn stop(&mut self) {
        self.worker.stop();
        self.tasks.clear();
        logging::unregister(&self.name);
        self.ros = None;
    }
}

/// The running suite. Drop (or [`Suite::shutdown`]) stops every node.
pub struct Suite {
    nodes: Vec<RunningNode>,
    _context: Context,
}

impl Suite {
    /// Fully qualified names of the running nodes.
    pub fn node_names(&self) -> Vec<String> {
        self.nodes
            .iter()
            .filter_map(|n| n.ros.as_ref())
            .map(|r| fqn(r.namespace(), r.name()))
            .collect()
    }

    /// Stops every node.
    pub fn shutdown(mut self) {
        self.stop_all();
    }

    fn stop_all(&mut self) {
        for n in &mut self.nodes {
            n.stop();
        }
        self.nodes.clear();
    }
}

impl Drop for Suite {
    fn drop(&mut self) {
        self.stop_all();
    }
}

fn fqn(namespace: &str, name: &str) -> String {
    format!("{}/{name}", namespace.trim_end_matches('/'))
}

/// One node to start: kind, name, parameters.
struct Plan {
    kind: NodeKind,
    name: String,
    ros_params: Parameters,
    params: NodeParams,
}

/// Reads and checks the parameters of the nodes to start: `only` one kind, or every kind whose
/// `enabled` is true.
fn plan(args: &RosArgs, only: Option<NodeKind>) -> Result<Vec<Plan>, String> {
    if only.is_none() && args.node_name.is_some() {
        return Err(
            "-r __node:=NAME names a single node: use it with --node predictor|forces|projection|prediction \
             (the suite's nodes keep their names cd_predictor, cd_forces, cd_projection, cd_prediction; \
             move them with -r __ns:=/NS)"
                .into(),
        );
    }
    let namespace = args.namespace_or("/");
    let kinds: Vec<NodeKind> = match only {
        Some(k) => vec![k],
        None => NodeKind::ALL.to_vec(),
    };
    let mut plans = Vec::new();
    for kind in kinds {
        let name = match only {
            Some(_) => args.node_name_or(kind.default_node_name()).to_string(),
            None => kind.default_node_name().to_string(),
        };
        let mut ros_params = args
            .parameters(&fqn(namespace, &name))
            .map_err(|e| format!("{name}: {e}"))?;
        let mut params =
            NodeParams::from_parameters(kind, &ros_params).map_err(|e| format!("{name}: {e}"))?;
        if only.is_none() && !params.common().enabled {
            continue;
        }
        let scene = resolve_path(&params.common().model.scene_file, &args.params_files);
        let scene = scene.display().to_string();
        ros_params.values.insert(
            "model.scene_file".into(),
            ParameterValue::String(scene.clone()),
        );
        *params.scene_file_mut() = scene;
        plans.push(Plan {
            kind,
            name,
            ros_params,
            params,
        });
    }
    if plans.is_empty() {
        return Err("no node is enabled (set enabled: true for at least one node)".into());
    }
    Ok(plans)
}

/// The participant's network settings, refusing all interfaces outside a loopback-only
/// namespace unless allowed.
fn network(plans: &[Plan]) -> Result<NetworkConfig, String> {
    let first: &NetworkParams = plans[0].params.common().network;
    for p in &plans[1..] {
        if p.params.common().network != first {
            return Err(format!(
                "network.* differs between {} and {}: one process has one DDS participant; \
                 set network.* in the /** section",
                plans[0].name, p.name
            ));
        }
    }
    let net = NetworkConfig::from_env()
        .and_then(|n| n.with_interfaces_param(&first.interfaces))
        .map_err(|e| e.to_string())?;
    let env_allows = std::env::var(ALLOW_EXTERNAL_ENV).is_ok_and(|v| v.trim() == "1");
    network_guard(
        &net,
        first.allow_external || env_allows,
        in_loopback_only_namespace(),
    )?;
    Ok(net)
}

/// The network rule of this project as a check: a participant on all (or non-loopback)
/// interfaces is refused unless it is `allowed` (`network.allow_external`,
/// `CD_ALLOW_EXTERNAL_NETWORK=1`) or the process is `in_namespace` (a loopback-only network
/// namespace, where no other interface exists).
pub fn network_guard(net: &NetworkConfig, allowed: bool, in_namespace: bool) -> Result<(), String> {
    let loopback = net
        .interfaces
        .as_ref()
        .is_some_and(|ifs| !ifs.is_empty() && ifs.iter().all(|a| a.is_loopback()));
    if loopback || allowed || in_namespace {
        return Ok(());
    }
    Err(format!(
        "refusing to open DDS on {}: this machine has interfaces other than loopback. \
         Run inside a loopback-only namespace (tools/ros2/netns_run.sh), restrict with \
         -p network.interfaces:=localhost (or CD_ROS_INTERFACES=127.0.0.1), or, on a robot \
         network, allow it with -p network.allow_external:=true (or {ALLOW_EXTERNAL_ENV}=1)",
        match &net.interfaces {
            None => "all interfaces".to_string(),
            Some(ifs) => format!("{ifs:?}"),
        }
    ))
}

/// Starts the nodes (see [`plan`]) on one participant.
pub fn start(args: &RosArgs, only: Option<NodeKind>) -> Result<Suite, String> {
    let plans = plan(args, only)?;
    let net = network(&plans)?;
    let context = net.create_context().map_err(|e| e.to_string())?;
    let namespace = args.namespace_or("/").to_string();
    let mut suite = Suite {
        nodes: Vec::new(),
        _context: context.clone(),
    };
    for plan in plans {
        let node = start_node(&context, args, &namespace, plan)?;
        suite.nodes.push(node);
    }
    Ok(suite)
}

/// Sends a state event; a full queue drops it (the next message replaces it anyway).
fn forward(tx: &SyncSender<Event>, ev: Event) {
    let _ = tx.try_send(ev);
}

fn start_node(
    context: &Context,
    args: &RosArgs,
    namespace: &str,
    plan: Plan,
) -> Result<RunningNode, String> {
    let Plan {
        kind,
        name,
        ros_params,
        params,
    } = plan;
    let log = NodeLog::new(&name);
    let engine = Engine::load(params.clone(), log.clone()).map_err(|e| format!("{name}: {e}"))?;
    let base_frame = engine.base_frame().to_string();
    let model_summary = {
        let m = &engine.scene().model;
        format!(
            "scene {}, model '{}' ({:?} base, nq = {}, nv = {}, {} constraints)",
            engine.scene().path.display(),
            m.name,
            m.base,
            m.nq,
            m.nv,
            engine.scene().file.constraints.len()
        )
    };

    // Parameters: declared with their values, validated on set; dynamic ones reach the worker.
    let ready = Arc::new(AtomicBool::new(false));
    let current = Arc::new(Mutex::new(ros_params));
    let (event_tx_slot, event_tx_get) = {
        let slot: Arc<Mutex<Option<SyncSender<Event>>>> = Arc::new(Mutex::new(None));
        (slot.clone(), slot)
    };
    let mut options = NodeOptions::new().enable_rosout(true);
    for (pname, value) in params.to_ros() {
        options = options.declare_parameter(&pname, value);
    }
    {
        let (ready, current) = (ready.clone(), current.clone());
        options = options.parameter_validator(Box::new(move |pname, value| {
            if !ready.load(Ordering::SeqCst) {
                return Ok(());
            }
            updated(kind, &current, pname, value).map(|_| ())
        }));
    }
    {
        let (ready, current) = (ready.clone(), current.clone());
        options = options.parameter_set_action(Box::new(move |pname, value| {
            if !ready.load(Ordering::SeqCst) {
                return Ok(());
            }
            let next = updated(kind, &current, pname, value)?;
            if let Ok(mut c) = current.lock() {
                c.values.insert(pname.to_string(), value.clone());
            }
            if let Some(tx) = event_tx_get.lock().ok().and_then(|t| t.clone()) {
                let _ = tx.try_send(Event::Params(Box::new(next)));
            }
            Ok(())
        }));
    }
    let mut ros = RosNode::new(context, namespace, &name, options).map_err(|e| e.to_string())?;
    logging::register(&name, ros.node.logging_handle());

    let (out_tx, out_rx) = smol::channel::bounded::<Output>(16);
    let tick = match &params {
        NodeParams::Predictor(p) => Some(Duration::from_secs_f64(1.0 / p.rate)),
        _ => None,
    };
    let worker = WorkerHandle::spawn(engine, &name, tick, out_tx).map_err(|e| e.to_string())?;
    *event_tx_slot.lock().map_err(|e| e.to_string())? = Some(worker.sender());
    ready.store(true, Ordering::SeqCst);

    let topic = |t: &str| args.resolve_topic(namespace, &name, t);
    let err = |e: crate::ros_context::RosContextError| format!("{name}: {e}");
    let mut tasks = Vec::new();
    let c = params.common();

    // State subscriptions.
    if !c.state.joint_states_topic.is_empty() {
        let sub = ros
            .subscription::<JointState>(&topic(&c.state.joint_states_topic), &qos::sensor_data())
            .map_err(err)?;
        let tx = worker.sender();
        tasks.push(ros.spawn(subscribe(sub, log.clone(), move |m| {
            forward(&tx, Event::JointState(m))
        })));
    }
    if !c.state.odom_topic.is_empty() {
        let sub = ros
            .subscription::<Odometry>(&topic(&c.state.odom_topic), &qos::sensor_data())
            .map_err(err)?;
        let tx = worker.sender();
        tasks.push(ros.spawn(subscribe(sub, log.clone(), move |m| {
            forward(&tx, Event::Odometry(Box::new(m)))
        })));
    }
    if c.model.use_robot_description {
        let sub = ros
            .subscription::<StringMsg>(
                &topic(&c.model.robot_description_topic),
                &qos::transient_local(),
            )
            .map_err(err)?;
        let tx = worker.sender();
        let log2 = log.clone();
        tasks.push(ros.spawn(subscribe(sub, log.clone(), move |m: StringMsg| {
            // The model rebuild must not be lost: block-free retry is not needed, the queue
            // is large; report if it is full.
            if tx.try_send(Event::RobotDescription(m.data)).is_err() {
                log2.error("robot_description: the worker queue is full; message dropped");
            }
        })));
    }
    if use_sim_time(&params) {
        let sub = ros
            .subscription::<Clock>("/clock", &qos::sensor_data())
            .map_err(err)?;
        let tx = worker.sender();
        tasks.push(ros.spawn(subscribe(sub, log.clone(), move |m: Clock| {
            forward(&tx, Event::Clock(m.clock))
        })));
    }

    match &params {
        NodeParams::Predictor(p) => {
            let cmd_topic = topic(&p.command.topic);
            let tx = worker.sender();
            if p.command.stamped {
                let sub = ros
                    .subscription::<TwistStamped>(&cmd_topic, &qos::sensor_data())
                    .map_err(err)?;
                tasks.push(
                    ros.spawn(subscribe(sub, log.clone(), move |m: TwistStamped| {
                        forward(&tx, Event::Command(m.twist))
                    })),
                );
            } else {
                let sub = ros
                    .subscription::<Twist>(&cmd_topic, &qos::sensor_data())
                    .map_err(err)?;
                tasks.push(ros.spawn(subscribe(sub, log.clone(), move |m: Twist| {
                    forward(&tx, Event::Command(m))
                })));
            }
            let odom_pub = ros
                .publisher::<Odometry>(&topic("~/predicted_odom"), &qos::reliable(10))
                .map_err(err)?;
            let path_pub = if p.publish_path {
                Some(
                    ros.publisher::<Path>(&topic("~/predicted_path"), &qos::reliable(10))
                        .map_err(err)?,
                )
            } else {
                None
            };
            let forces_pub = if p.publish_forces {
                Some(
                    ros.publisher::<ConstraintForces>(
                        &topic("~/constraint_forces"),
                        &qos::reliable(10),
                    )
                    .map_err(err)?,
                )
            } else {
                None
            };
            let log2 = log.clone();
            tasks.push(ros.spawn(async move {
                while let Ok(out) = out_rx.recv().await {
                    let Output::Periodic(out) = out else { continue };
                    let out = *out;
                    if let Err(e) = odom_pub.async_publish(out.odom).await {
                        log2.warn(&format!("publish predicted_odom: {e:?}"));
                    }
                    if let Some(p) = &path_pub
                        && let Err(e) = p.async_publish(out.path).await
                    {
                        log2.warn(&format!("publish predicted_path: {e:?}"));
                    }
                    if let Some(p) = &forces_pub
                        && let Err(e) = p.async_publish(out.forces).await
                    {
                        log2.warn(&format!("publish constraint_forces: {e:?}"));
                    }
                }
            }));
        }
        NodeParams::Forces(_) => {
            let server = ros
                .server::<GetConstraintForces>(&topic("~/get_constraint_forces"))
                .map_err(err)?;
            let tx = worker.sender();
            tasks.push(ros.spawn(serve::<GetConstraintForces, _>(
                server,
                log.clone(),
                move |req, reply| tx.try_send(Event::GetConstraintForces(req, reply)).is_ok(),
                |message| GetConstraintForcesResponse {
                    success: false,
                    message,
                    ..Default::default()
                },
            )));
        }
        NodeParams::Projection(p) => {
            if p.service {
                let server = ros
                    .server::<ProjectVelocity>(&topic("~/project_velocity"))
                    .map_err(err)?;
                let tx = worker.sender();
                tasks.push(ros.spawn(serve::<ProjectVelocity, _>(
                    server,
                    log.clone(),
                    move |req, reply| tx.try_send(Event::ProjectVelocity(req, reply)).is_ok(),
                    |message| ProjectVelocityResponse {
                        success: false,
                        status: "error".into(),
                        message,
                        ..Default::default()
                    },
                )));
            }
            if p.filter.enabled {
                let tx = worker.sender();
                let (input, output) = (topic(&p.filter.input_topic), topic(&p.filter.output_topic));
                let log2 = log.clone();
                if p.filter.stamped {
                    let sub = ros
                        .subscription::<TwistStamped>(&input, &qos::sensor_data())
                        .map_err(err)?;
                    tasks.push(
                        ros.spawn(subscribe(sub, log.clone(), move |m: TwistStamped| {
                            forward(&tx, Event::FilterCommand(m.twist, Some(m.header)))
                        })),
                    );
                    let publisher = ros
                        .publisher::<TwistStamped>(&output, &qos::reliable(10))
                        .map_err(err)?;
                    tasks.push(ros.spawn(async move {
                        while let Ok(Output::Filtered(twist, header)) = out_rx.recv().await {
                            let msg = TwistStamped {
                                header: header.unwrap_or_default(),
                                twist,
                            };
                            if let Err(e) = publisher.async_publish(msg).await {
                                log2.warn(&format!("publish filtered command: {e:?}"));
                            }
                        }
                    }));
                } else {
                    let sub = ros
                        .subscription::<Twist>(&input, &qos::sensor_data())
                        .map_err(err)?;
                    tasks.push(ros.spawn(subscribe(sub, log.clone(), move |m: Twist| {
                        forward(&tx, Event::FilterCommand(m, None))
                    })));
                    let publisher = ros
                        .publisher::<Twist>(&output, &qos::reliable(10))
                        .map_err(err)?;
                    tasks.push(ros.spawn(async move {
                        while let Ok(Output::Filtered(twist, _)) = out_rx.recv().await {
                            if let Err(e) = publisher.async_publish(twist).await {
                                log2.warn(&format!("publish filtered command: {e:?}"));
                            }
                        }
                    }));
                }
            }
        }
        NodeParams::Prediction(_) => {
            let server = ros.server::<Predict>(&topic("~/predict")).map_err(err)?;
            let tx = worker.sender();
            tasks.push(ros.spawn(serve::<Predict, _>(
                server,
                log.clone(),
                move |req, reply| tx.try_send(Event::Predict(req, reply)).is_ok(),
                |message| PredictResponse {
                    success: false,
                    message,
                    ..Default::default()
                },
            )));
        }
    }
    log.info(&format!(
        "{} ready: {model_summary}, base frame '{base_frame}'",
        kind.key()
    ));
    Ok(RunningNode {
        name,
        worker,
        tasks,
        ros: Some(ros),
    })
}

fn use_sim_time(p: &NodeParams) -> bool {
    match p {
        NodeParams::Predictor(p) => p.use_sim_time,
        NodeParams::Forces(p) => p.use_sim_time,
        NodeParams::Projection(p) => p.use_sim_time,
        NodeParams::Prediction(p) => p.use_sim_time,
    }
}

/// The node's parameters with `name` set to `value`, if that is allowed and valid.
fn updated(
    kind: NodeKind,
    current: &Mutex<Parameters>,
    name: &str,
    value: &ParameterValue,
) -> Result<NodeParams, String> {
    if name == "use_sim_time" {
        return Err("use_sim_time cannot change while the node runs: restart it".into());
    }
    if !kind
        .dynamic_parameters()
        .iter()
        .any(|d| name == *d || (d.ends_with('.') && name.starts_with(d)))
    {
        return Err(format!(
            "parameter '{name}' cannot change while the node runs (run-time changes: {}); \
             restart the node with the new value",
            kind.dynamic_parameters().join(", ")
        ));
    }
    let mut params = current.lock().map_err(|e| e.to_string())?.clone();
    params.values.insert(name.to_string(), value.clone());
    NodeParams::from_parameters(kind, &params)
}

/// Takes messages from `sub` and hands each to `f`, until the node stops.
async fn subscribe<M: serde::de::DeserializeOwned + 'static>(
    sub: ros2_client::Subscription<M>,
    log: NodeLog,
    mut f: impl FnMut(M),
) {
    let mut errors = 0u64;
    loop {
        match sub.async_take().await {
            Ok((m, _)) => f(m),
            Err(e) => {
                errors += 1;
                if errors == 1 || errors.is_power_of_two() {
                    log.warn(&format!(
                        "dropped an undecodable message ({errors} so far): {e:?}"
                    ));
                }
                smol::Timer::after(Duration::from_millis(1)).await;
            }
        }
    }
}

/// Serves `S`: every request goes to the worker through `send`, whose reply is sent back;
/// `error` makes the response when the worker cannot answer.
async fn serve<S, F>(
    server: ros2_client::Server<S::Request, S::Response>,
    log: NodeLog,
    send: F,
    error: fn(String) -> S::Response,
) where
    S: RosService,
    F: Fn(S::Request, Reply<S::Response>) -> bool,
{
    loop {
        let (id, req) = match server.async_receive_request().await {
            Ok(r) => r,
            Err(e) => {
                log.warn(&format!(
                    "{}: dropped an undecodable request: {e:?}",
                    S::NAME
                ));
                smol::Timer::after(Duration::from_millis(1)).await;
                continue;
            }
        };
        let (reply_tx, reply_rx) = smol::channel::bounded(1);
        let resp = if send(req, reply_tx) {
            match reply_rx.recv().await {
                Ok(resp) => resp,
                Err(_) => error(
                    "internal error while serving this request (see the node's log); \
                     the node rebuilt its model and keeps serving"
                        .into(),
                ),
            }
        } else {
            error("busy: the node's request queue is full, try again".into())
        };
        if let Err(e) = server.async_send_response(id, resp).await {
            log.warn(&format!("{}: sending the response failed: {e:?}", S::NAME));
        }
    }
}

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
    let suite = match start(&args, only) {
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
    while !STOP.load(Ordering::SeqCst) {
        std::thread::sleep(Duration::from_millis(50));
    }
    log::info!(target: "constraint_dynamics_nodes", "shutting down");
    suite.shutdown();
    ExitCode::SUCCESS
}

/// The command-line help.
pub fn usage() -> String {
    "usage: constraint_dynamics_suite [--node predictor|forces|projection|prediction] \
     --ros-args --params-file FILE [-p NAME:=VALUE] [-r __ns:=/NS] [-r __node:=NAME (with --node)] \
     [-r FROM:=TO] [--log-level LEVEL]\n\
     \n\
     Starts the constraint_dynamics ROS 2 nodes (docs/nodes.md): cd_predictor (predicted odometry, \
     path, constraint forces), cd_forces (~/get_constraint_forces), cd_projection \
     (~/project_velocity, command filter), cd_prediction (~/predict). Without --node every node \
     whose `enabled` parameter is true runs in this process.\n\
     ROS_DOMAIN_ID selects the domain; network.interfaces / CD_ROS_INTERFACES the interfaces."
        .to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn network_guard_allows_loopback_namespaces_and_explicit_consent_only() {
        let all = NetworkConfig::default();
        let lo = NetworkConfig::loopback(0);
        let lan = NetworkConfig::default()
            .with_interfaces_param("192.168.1.20")
            .unwrap();
        assert!(network_guard(&all, false, false).is_err());
        assert!(network_guard(&lan, false, false).is_err());
        assert!(network_guard(&lo, false, false).is_ok());
        assert!(network_guard(&all, true, false).is_ok());
        assert!(network_guard(&all, false, true).is_ok());
        let e = network_guard(&all, false, false).unwrap_err();
        assert!(
            e.contains("netns_run.sh") && e.contains("allow_external"),
            "{e}"
        );
    }
}
