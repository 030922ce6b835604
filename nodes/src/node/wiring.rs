//! Starting one node of any kind: its ROS node with declared, validated parameters and its
//! lifecycle ([`super::managed`]), which brings up the inputs every node has (`joint_states`,
//! `odom`, `robot_description`, `/clock`) and its worker when configured, and when active
//! `/diagnostics`, `~/set_payload` and the kind's own topics and services ([`RosWiring`]).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::SyncSender;
use std::sync::{Arc, Mutex};

use ros2_client::{Context, NodeOptions};

use super::managed::{Managed, Supervisor, WorkerLink};

use crate::error::NodeError;
use crate::msg::RosService;
use crate::msg::builtin_interfaces::Time;
use crate::msg::constraint_dynamics_msgs::srv::{SetPayload, SetPayloadResponse};
use crate::msg::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus};
use crate::msg::nav_msgs::Odometry;
use crate::msg::rosgraph_msgs::Clock;
use crate::msg::sensor_msgs::JointState;
use crate::msg::std_msgs::Header;
use crate::msg::std_msgs::StringMsg;
use crate::node::worker::{Event, NodeLogic};
use crate::params::{NodeParams, WorkBudget};
use crate::ros::args::{Parameters, RosArgs};
use crate::ros::context::{RosNode, qos};
use crate::ros::io::{Reply, serve, subscribe};
use crate::ros::logging::{self, NodeLog};

/// What a kind's wiring works with.
pub struct Wiring<'a, N: NodeLogic> {
    /// The DDS participant's context (for the discovered graph).
    pub context: &'a Context,
    /// The ROS node.
    pub ros: &'a mut RosNode,
    /// The node's parameters.
    pub params: &'a NodeParams<N::Params>,
    /// The names of the scene's constraints.
    pub constraints: &'a [String],
    /// Resolves a topic or service name (namespace, `~`, remappings).
    pub topic: &'a dyn Fn(&str) -> String,
    /// Events to the worker.
    pub tx: SyncSender<Event<N>>,
    /// The worker's outputs (taken by the task that publishes them).
    pub outputs: Option<smol::channel::Receiver<N::Output>>,
    /// The node's log.
    pub log: NodeLog,
    /// The executor tasks of the node.
    pub tasks: Vec<smol::Task<()>>,
}

/// Endpoints a kind keeps while they fit the ROS graph (see [`RosWiring::follow_graph`]):
/// what they were made for (`key`) and the task that owns them.
pub struct Followed {
    /// What the endpoints were made for (e.g. the message type of a subscription).
    pub key: String,
    /// Owns the endpoints: dropping it removes them from the graph.
    pub task: smol::Task<()>,
}

/// A node kind's topics and services: translate messages and requests into its events and
/// publish its outputs. Created when the node is activated, removed when it is deactivated.
pub trait RosWiring: NodeLogic {
    /// Creates the kind's subscriptions, servers and publishers.
    fn wire(w: &mut Wiring<Self>) -> Result<(), NodeError>;

    /// Called on activation and then every [`GRAPH_PERIOD`] while active: endpoints that
    /// depend on the discovered graph live in `slot` and may be replaced (the predictor's
    /// command input follows the type published on its topic). Default: none.
    fn follow_graph(_w: &mut Wiring<Self>, _slot: &mut Option<Followed>) -> Result<(), NodeError> {
        Ok(())
    }
}

/// How often an active node looks at the discovered graph [`RosWiring::follow_graph`].
pub const GRAPH_PERIOD: std::time::Duration = std::time::Duration::from_millis(250);

/// A running node: its lifecycle supervisor, which owns the worker, the tasks and the ROS
/// node.
pub trait RunningNode: Send {
    /// The node's name.
    fn name(&self) -> &str;
    /// The node's fully qualified name.
    fn fqn(&self) -> &str;
    /// Stops the worker, the tasks, then the ROS node.
    fn stop(&mut self);
}

struct Running {
    name: String,
    fqn: String,
    supervisor: Option<Supervisor>,
}

impl RunningNode for Running {
    fn name(&self) -> &str {
        &self.name
    }
    fn fqn(&self) -> &str {
        &self.fqn
    }
    fn stop(&mut self) {
        if let Some(mut s) = self.supervisor.take() {
            s.stop();
        }
        logging::unregister(&self.name);
    }
}

/// The scene's work limits while the node is configured (none before: `configure` checks the
/// parameters against them then).
fn budget_of<N: NodeLogic>(link: &Mutex<Option<WorkerLink<N>>>) -> Option<WorkBudget> {
    link.lock()
        .ok()
        .and_then(|l| l.as_ref().map(|l| l.budget.clone()))
}

/// Sends a state event; a full queue drops it (the next message replaces it anyway).
pub fn forward<N: NodeLogic>(tx: &SyncSender<Event<N>>, ev: Event<N>) {
    let _ = tx.try_send(ev);
}

/// Starts node `name` of kind `N` in `namespace` with its parameters: its ROS node, its
/// lifecycle services and, with `autostart` (the default), configured and active at once. A
/// failed configuration or activation leaves the node unconfigured (or inactive) with an
/// ERROR on `/rosout` and `/diagnostics`, so the other nodes of the process run on; with
/// `exit_on_failure` it is returned instead (the process exits).
pub fn start_node<N: RosWiring>(
    context: &Context,
    args: &RosArgs,
    namespace: &str,
    name: &str,
    ros_params: Parameters,
    params: NodeParams<N::Params>,
    exit_on_failure: bool,
) -> Result<Box<dyn RunningNode>, NodeError> {
    let log = NodeLog::new(name);
    // Parameters: declared with their values; each set request is validated as a whole (the
    // combination it would make), and reaches the worker when there is one (configured).
    let ready = Arc::new(AtomicBool::new(false));
    let current = Arc::new(Mutex::new(ros_params));
    let link: Arc<Mutex<Option<WorkerLink<N>>>> = Arc::new(Mutex::new(None));
    let mut options = NodeOptions::new().enable_rosout(true);
    for (pname, value) in params.to_ros() {
        options = options.declare_parameter(&pname, value);
    }
    {
        let (ready, current, link) = (ready.clone(), current.clone(), link.clone());
        options = options.parameters_validator(Box::new(move |changes| {
            if !ready.load(Ordering::SeqCst) {
                return Ok(());
            }
            let c = current.lock().map_err(|e| e.to_string())?;
            let budget = budget_of(&link);
            let next = NodeParams::<N::Params>::updated(&c, changes, budget.as_ref())
                .map_err(|e| e.to_string())?;
            check_model(&next, &link)
        }));
    }
    {
        let (ready, current, link) = (ready.clone(), current.clone(), link.clone());
        options = options.parameters_set_action(Box::new(move |changes| {
            if !ready.load(Ordering::SeqCst) {
                return Ok(());
            }
            let mut c = current.lock().map_err(|e| e.to_string())?;
            let budget = budget_of(&link);
            let next = NodeParams::<N::Params>::updated(&c, changes, budget.as_ref())
                .map_err(|e| e.to_string())?;
            check_model(&next, &link)?;
            // A set is acknowledged only once the worker has it: with its queue full the set is
            // refused (the caller can retry), never dropped after a success reply.
            let tx = link
                .lock()
                .ok()
                .and_then(|l| l.as_ref().map(|l| l.tx.clone()));
            if let Some(tx) = tx {
                tx.try_send(Event::Params(Box::new(next))).map_err(|_| {
                    "the node is busy (request queue full); nothing set, try again".to_string()
                })?;
            }
            for p in changes {
                c.values.insert(p.name.clone(), p.value.clone());
            }
            Ok(())
        }));
    }
    let ros = RosNode::new(context, namespace, name, options)?;
    logging::register(name, ros.node.logging_handle());
    ready.store(true, Ordering::SeqCst);
    let fqn = format!("{}/{name}", namespace.trim_end_matches('/'));
    let autostart = params.common.autostart;
    let mut managed = Managed::<N>::new(
        context.clone(),
        args.clone(),
        ros,
        &fqn,
        (current, link),
        log.clone(),
    )?;
    if autostart {
        if let Err(e) = managed.autostart() {
            if exit_on_failure {
                return Err(e);
            }
            log.error(&format!(
                "{name} is not running ({e}); the process's other nodes run on (a lifecycle \
                 manager may configure it again; --exit-on-failure exits instead)"
            ));
        }
    } else {
        log.info(&format!(
            "{name} unconfigured (autostart: false): waiting for ~/change_state"
        ));
    }
    Ok(Box::new(Running {
        name: name.to_string(),
        fqn,
        supervisor: Some(managed.spawn()?),
    }))
}

/// Serves `S` at `name`: each request becomes the kind's input `input(request, reply)`; `error`
/// makes the response when the worker cannot answer (busy, internal error).
pub fn serve_service<N, S>(
    w: &mut Wiring<N>,
    name: &str,
    input: fn(S::Request, Reply<S::Response>) -> N::Input,
    error: fn(String) -> S::Response,
) -> Result<(), NodeError>
where
    N: NodeLogic,
    S: RosService + 'static,
    S::Request: Send + Sync,
    S::Response: Send + Sync,
{
    let server = w.ros.server::<S>(&(w.topic)(name))?;
    let tx = w.tx.clone();
    w.tasks.push(w.ros.spawn(serve::<S, _>(
        server,
        w.log.clone(),
        move |req, reply| tx.try_send(Event::Node(input(req, reply))).is_ok(),
        error,
    )));
    Ok(())
}

/// `~/set_payload` (every kind): each request goes to the worker, which rebuilds the model.
pub(crate) fn wire_set_payload<N: NodeLogic>(w: &mut Wiring<N>) -> Result<(), NodeError> {
    let server = w.ros.server::<SetPayload>(&(w.topic)("~/set_payload"))?;
    let tx = w.tx.clone();
    w.tasks.push(w.ros.spawn(serve::<SetPayload, _>(
        server,
        w.log.clone(),
        move |req, reply| tx.try_send(Event::SetPayload(req, reply)).is_ok(),
        |message| SetPayloadResponse {
            success: false,
            message,
        },
    )));
    Ok(())
}

/// The parameters that name parts of the model checked against it (none before the node is
/// configured, when `configure` checks them).
fn check_model<N: NodeLogic>(
    params: &NodeParams<N::Params>,
    link: &Mutex<Option<WorkerLink<N>>>,
) -> Result<(), String> {
    let model = link
        .lock()
        .ok()
        .and_then(|l| l.as_ref().map(|l| l.model.clone()));
    match model {
        Some(m) => params.check_model(&m).map_err(|e| e.to_string()),
        None => Ok(()),
    }
}

/// The node's status on `/diagnostics` (global, as diagnostic_updater publishes it; the status
/// name is the node's fully qualified name).
pub(crate) fn wire_diagnostics<N: NodeLogic>(
    w: &mut Wiring<N>,
    statuses: smol::channel::Receiver<(Time, DiagnosticStatus)>,
) -> Result<(), NodeError> {
    let publisher = w
        .ros
        .publisher::<DiagnosticArray>("/diagnostics", &qos::reliable(10))?;
    let log = w.log.clone();
    w.tasks.push(w.ros.spawn(async move {
        while let Ok((stamp, status)) = statuses.recv().await {
            let msg = DiagnosticArray {
                header: Header {
                    stamp,
                    frame_id: String::new(),
                },
                status: vec![status],
            };
            if let Err(e) = publisher.async_publish(msg).await {
                log.warn(&format!("publish diagnostics: {e:?}"));
            }
        }
    }));
    Ok(())
}

/// The inputs every node has: joint states, odometry, the URDF, and `/clock`.
pub(crate) fn wire_state_inputs<N: NodeLogic>(w: &mut Wiring<N>) -> Result<(), NodeError> {
    let c = &w.params.common;
    if !c.state.joint_states_topic.is_empty() {
        let sub = w.ros.subscription::<JointState>(
            &(w.topic)(&c.state.joint_states_topic),
            &qos::sensor_data(),
        )?;
        let tx = w.tx.clone();
        w.tasks
            .push(w.ros.spawn(subscribe(sub, w.log.clone(), move |m| {
                forward(&tx, Event::JointState(m))
            })));
    }
    if !c.state.odom_topic.is_empty() {
        let sub = w
            .ros
            .subscription::<Odometry>(&(w.topic)(&c.state.odom_topic), &qos::sensor_data())?;
        let tx = w.tx.clone();
        w.tasks
            .push(w.ros.spawn(subscribe(sub, w.log.clone(), move |m| {
                forward(&tx, Event::Odometry(Box::new(m)))
            })));
    }
    if c.model.use_robot_description {
        let sub = w.ros.subscription::<StringMsg>(
            &(w.topic)(&c.model.robot_description_topic),
            &qos::transient_local(),
        )?;
        let tx = w.tx.clone();
        let log = w.log.clone();
        w.tasks.push(
            w.ros
                .spawn(subscribe(sub, w.log.clone(), move |m: StringMsg| {
                    // A model rebuild must not be lost silently: report if the queue is full.
                    if tx.try_send(Event::RobotDescription(m.data)).is_err() {
                        log.error("robot_description: the worker queue is full; message dropped");
                    }
                })),
        );
    }
    if c.use_sim_time {
        let sub = w.ros.subscription::<Clock>("/clock", &qos::sensor_data())?;
        let tx = w.tx.clone();
        w.tasks
            .push(w.ros.spawn(subscribe(sub, w.log.clone(), move |m: Clock| {
                forward(&tx, Event::Clock(m.clock))
            })));
    }
    Ok(())
}
