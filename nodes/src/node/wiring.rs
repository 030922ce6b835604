//! Starting one node of any kind: its ROS node with declared, validated parameters, the
//! inputs every node has (`joint_states`, `odom`, `robot_description`, `/clock`), its worker,
//! and the kind's own topics and services ([`RosWiring`]).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::SyncSender;
use std::sync::{Arc, Mutex};

use ros2_client::{Context, NodeOptions};

use crate::error::NodeError;
use crate::msg::RosService;
use crate::msg::builtin_interfaces::Time;
use crate::msg::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus};
use crate::msg::nav_msgs::Odometry;
use crate::msg::rosgraph_msgs::Clock;
use crate::msg::sensor_msgs::JointState;
use crate::msg::std_msgs::Header;
use crate::msg::std_msgs::StringMsg;
use crate::node::worker::{Event, NodeLogic, WorkerHandle};
use crate::params::NodeParams;
use crate::robot::Robot;
use crate::ros::args::{Parameters, RosArgs};
use crate::ros::context::{RosNode, qos};
use crate::ros::io::{Reply, serve, subscribe};
use crate::ros::logging::{self, NodeLog};

/// What a kind's wiring works with.
pub struct Wiring<'a, N: NodeLogic> {
    /// The ROS node.
    pub ros: &'a mut RosNode,
    /// The node's parameters.
    pub params: &'a NodeParams<N::Params>,
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

/// A node kind's topics and services: translate messages and requests into its events and
/// publish its outputs.
pub trait RosWiring: NodeLogic {
    /// Creates the kind's subscriptions, servers and publishers.
    fn wire(w: &mut Wiring<Self>) -> Result<(), NodeError>;
}

/// A running node: its worker, executor tasks and ROS node (stopped in that order).
pub trait RunningNode: Send {
    /// The node's name.
    fn name(&self) -> &str;
    /// The ROS node (for its fully qualified name).
    fn ros(&self) -> Option<&RosNode>;
    /// Stops the worker, the tasks, then the ROS node.
    fn stop(&mut self);
}

struct Running<N: NodeLogic> {
    name: String,
    worker: WorkerHandle<N>,
    tasks: Vec<smol::Task<()>>,
    ros: Option<RosNode>,
}

impl<N: NodeLogic> RunningNode for Running<N> {
    fn name(&self) -> &str {
        &self.name
    }
    fn ros(&self) -> Option<&RosNode> {
        self.ros.as_ref()
    }
    fn stop(&mut self) {
        self.worker.stop();
        self.tasks.clear();
        logging::unregister(&self.name);
        self.ros = None;
    }
}

/// Sends a state event; a full queue drops it (the next message replaces it anyway).
pub fn forward<N: NodeLogic>(tx: &SyncSender<Event<N>>, ev: Event<N>) {
    let _ = tx.try_send(ev);
}

/// Starts node `name` of kind `N` in `namespace` with its parameters.
pub fn start_node<N: RosWiring>(
    context: &Context,
    args: &RosArgs,
    namespace: &str,
    name: &str,
    ros_params: Parameters,
    params: NodeParams<N::Params>,
) -> Result<Box<dyn RunningNode>, NodeError> {
    let log = NodeLog::new(name);
    let robot = Robot::load(&params.common)?;
    let logic = N::new(robot, params.clone(), log.clone())?;
    let summary = {
        let (r, m) = (logic.robot(), logic.robot().model());
        format!(
            "scene {}, model '{}' ({:?} base, nq = {}, nv = {}, {} constraints), base frame '{}'",
            r.scene().path.display(),
            m.name,
            m.base,
            m.nq,
            m.nv,
            r.scene().file.constraints.len(),
            r.base_frame()
        )
    };

    // Parameters: declared with their values, validated on set; dynamic ones reach the worker.
    let ready = Arc::new(AtomicBool::new(false));
    let current = Arc::new(Mutex::new(ros_params));
    let event_tx: Arc<Mutex<Option<SyncSender<Event<N>>>>> = Arc::new(Mutex::new(None));
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
            let c = current.lock().map_err(|e| e.to_string())?;
            NodeParams::<N::Params>::updated(&c, pname, value)
                .map(|_| ())
                .map_err(|e| e.to_string())
        }));
    }
    {
        let (ready, current, event_tx) = (ready.clone(), current.clone(), event_tx.clone());
        options = options.parameter_set_action(Box::new(move |pname, value| {
            if !ready.load(Ordering::SeqCst) {
                return Ok(());
            }
            let mut c = current.lock().map_err(|e| e.to_string())?;
            let next =
                NodeParams::<N::Params>::updated(&c, pname, value).map_err(|e| e.to_string())?;
            c.values.insert(pname.to_string(), value.clone());
            if let Some(tx) = event_tx.lock().ok().and_then(|t| t.clone()) {
                let _ = tx.try_send(Event::Params(Box::new(next)));
            }
            Ok(())
        }));
    }
    let mut ros = RosNode::new(context, namespace, name, options)?;
    logging::register(name, ros.node.logging_handle());

    let (out_tx, out_rx) = smol::channel::bounded::<N::Output>(16);
    let (diag_tx, diag_rx) = smol::channel::bounded::<(Time, DiagnosticStatus)>(4);
    let fqn = format!("{}/{name}", namespace.trim_end_matches('/'));
    let worker = WorkerHandle::spawn(logic, name, &fqn, out_tx, diag_tx)?;
    if let Ok(mut slot) = event_tx.lock() {
        *slot = Some(worker.sender());
    }
    ready.store(true, Ordering::SeqCst);

    let topic = |t: &str| args.resolve_topic(namespace, name, t);
    let mut w = Wiring::<N> {
        ros: &mut ros,
        params: &params,
        topic: &topic,
        tx: worker.sender(),
        outputs: Some(out_rx),
        log: log.clone(),
        tasks: Vec::new(),
    };
    wire_state_inputs(&mut w)?;
    wire_diagnostics(&mut w, diag_rx)?;
    N::wire(&mut w)?;
    let tasks = std::mem::take(&mut w.tasks);
    log.info(&format!("{} ready: {summary}", name));
    Ok(Box::new(Running::<N> {
        name: name.to_string(),
        worker,
        tasks,
        ros: Some(ros),
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

/// The node's status on `/diagnostics` (global, as diagnostic_updater publishes it; the status
/// name is the node's fully qualified name).
fn wire_diagnostics<N: NodeLogic>(
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
fn wire_state_inputs<N: NodeLogic>(w: &mut Wiring<N>) -> Result<(), NodeError> {
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
