//! A node kind's ROS side: what its wiring works with ([`Wiring`]), what it implements
//! ([`RosWiring`]), and the endpoints every node has: the state inputs (`joint_states`, `odom`,
//! `robot_description`, `/clock`) while configured, `/diagnostics` and `~/set_payload` while
//! active. The lifecycle ([`super::managed`]) decides when each is created and removed.

use std::sync::Arc;
use std::sync::mpsc::SyncSender;

use ros2_client::Context;

use crate::error::NodeError;
use crate::msg::builtin_interfaces::Time;
use crate::msg::constraint_dynamics_msgs::srv::{SetPayload, SetPayloadResponse};
use crate::msg::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus};
use crate::msg::nav_msgs::Odometry;
use crate::msg::rosgraph_msgs::Clock;
use crate::msg::sensor_msgs::JointState;
use crate::msg::std_msgs::Header;
use crate::msg::std_msgs::StringMsg;
use crate::msg::{RosMessage, RosService};
use crate::node::state_readers::{Inbox, Joined, StateMsg, StateReaders};
use crate::node::worker::{Event, NodeLogic};
use crate::params::NodeParams;
use crate::ros::args::expand_name;
use crate::ros::context::{RosNode, qos};
use crate::ros::io::{Reply, serve, subscribe};
use crate::ros::logging::NodeLog;

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

/// Sends a state event; a full queue drops it (the next message replaces it anyway).
pub fn forward<N: NodeLogic>(tx: &SyncSender<Event<N>>, ev: Event<N>) {
    let _ = tx.try_send(ev);
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

/// The inputs every node has: joint states and odometry through the process's shared
/// readers into the worker's `inbox` (the returned memberships keep them), the URDF and
/// `/clock` on the node's own subscriptions (a transient-local URDF must reach every node that
/// joins, and the clock paces the worker).
pub(crate) fn wire_state_inputs<N: NodeLogic>(
    w: &mut Wiring<N>,
    readers: &StateReaders,
    inbox: &Arc<Inbox>,
) -> Result<Vec<Joined>, NodeError> {
    let c = &w.params.common;
    let mut joined = Vec::new();
    if !c.state.joint_states_topic.is_empty() {
        let topic = (w.topic)(&c.state.joint_states_topic);
        joined.push(join::<N, JointState>(w, readers, inbox, &topic, |m| {
            StateMsg::JointState(Arc::new(m))
        })?);
    }
    let c = &w.params.common;
    if !c.state.odom_topic.is_empty() {
        let topic = (w.topic)(&c.state.odom_topic);
        joined.push(join::<N, Odometry>(w, readers, inbox, &topic, |m| {
            StateMsg::Odometry(Arc::new(m))
        })?);
    }
    let c = &w.params.common;
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
    Ok(joined)
}

/// Joins the worker's inbox to the shared reader of `topic` (remapped), creating the reader on
/// this node when it is the first. Readers are shared by the absolute name, so a private or
/// relative name is one reader per node only when it expands differently.
fn join<N: NodeLogic, M: RosMessage + serde::de::DeserializeOwned + Send + Sync + 'static>(
    w: &mut Wiring<N>,
    readers: &StateReaders,
    inbox: &Arc<Inbox>,
    topic: &str,
    wrap: fn(M) -> StateMsg,
) -> Result<Joined, NodeError> {
    let absolute = expand_name(w.ros.namespace(), w.ros.name(), topic);
    let tx = w.tx.clone();
    let wake = Box::new(move || forward(&tx, Event::StateWaiting));
    let joined = readers.join(&absolute, inbox.clone(), wake, |fanout| {
        let sub = w.ros.subscription::<M>(&absolute, &qos::sensor_data())?;
        let gid = sub.guid().into();
        let task = (w.ros).spawn(subscribe(sub, w.log.clone(), move |m| fanout.send(wrap(m))));
        Ok((task, gid))
    })?;
    w.ros.node.register_reader(joined.reader_gid());
    Ok(joined)
}
