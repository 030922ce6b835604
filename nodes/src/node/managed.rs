//! A node's lifecycle on ROS: the `lifecycle_msgs` services (`~/change_state`, `~/get_state`,
//! `~/get_available_states`, `~/get_available_transitions`), `~/transition_event`, and what each
//! transition does to the node (the state machine itself is [`crate::lifecycle`]):
//!
//! | state | what exists besides the lifecycle and parameter services |
//! |---|---|
//! | unconfigured, finalized | nothing |
//! | inactive | the worker with the scene loaded, following `joint_states`, `odom`, `robot_description`, `/clock` (so activation starts from a fresh state); no ticks |
//! | active | also the kind's publishers, servers, command input, `/diagnostics`; ticking |
//!
//! One supervisor thread per node owns the ROS node and all of this; the lifecycle servers'
//! tasks hand it their requests, and it looks at the graph every [`GRAPH_PERIOD`] for the
//! endpoints that follow it ([`RosWiring::follow_graph`]). Owning the ROS node on its own
//! thread lets it create and remove endpoints while the node's executor runs.

use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, SyncSender, channel};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use ros2_client::{Context, Publisher};

use super::failure::Failure;
use super::lifecycle_servers::{Request, lifecycle_servers};
use super::state_readers::{Joined, StateReaders};
use super::wiring::{
    Followed, GRAPH_PERIOD, RosWiring, Wiring, wire_diagnostics, wire_set_payload,
    wire_state_inputs,
};
use super::worker::{Event, NodeLogic, WorkerHandle};
use crate::error::NodeError;
use crate::lifecycle::{Callback, Lifecycle, LifecycleError, Transition};
use crate::msg::builtin_interfaces::Time;
use crate::msg::diagnostic_msgs::DiagnosticStatus;
use crate::msg::lifecycle_msgs::{
    ChangeStateResponse, GetAvailableTransitionsResponse, GetStateResponse, TransitionEvent,
};
use crate::params::{KindParams, NodeParams, WorkBudget};
use crate::robot::Robot;
use crate::ros::args::{Parameters, RosArgs};
use crate::ros::context::{RosNode, qos};
use crate::ros::logging::NodeLog;
use constraint_dynamics::model::Model;

/// The parameters as the ROS node holds them, and the slot through which run-time changes
/// reach the worker (empty while there is none).
pub type ParamsLink<N> = (Arc<Mutex<Parameters>>, Arc<Mutex<Option<WorkerLink<N>>>>);

/// What a run-time parameter set reaches while the node is configured.
pub struct WorkerLink<N: NodeLogic> {
    /// The worker's events.
    pub tx: SyncSender<Event<N>>,
    /// The scene's work limits, which the values that size work must respect.
    pub budget: WorkBudget,
    /// The model, which the parameters naming its parts must fit (`payload.frame`,
    /// [`crate::params::KindParams::check_model`]).
    pub model: Arc<Model>,
}

/// What exists while configured.
struct Configured<N: NodeLogic> {
    params: NodeParams<N::Params>,
    /// The scene's constraint names (per-constraint topics).
    constraints: Vec<String>,
    worker: WorkerHandle<N>,
    outputs: smol::channel::Receiver<N::Output>,
    statuses: smol::channel::Receiver<(Time, DiagnosticStatus)>,
    /// The URDF and clock subscriptions.
    tasks: Vec<smol::Task<()>>,
    /// The node's places at the process's shared joint-state and odometry readers.
    inputs: Vec<Joined>,
}

/// What exists while active.
struct Active {
    /// Own the kind's endpoints: dropping them removes the endpoints from the graph.
    _endpoints: Vec<smol::Task<()>>,
    followed: Option<Followed>,
}

/// A node's lifecycle: see the module documentation.
pub struct Managed<N: RosWiring> {
    context: Context,
    args: RosArgs,
    ros: RosNode,
    readers: StateReaders,
    fqn: String,
    params: ParamsLink<N>,
    log: NodeLog,
    machine: Lifecycle,
    events: Publisher<TransitionEvent>,
    configured: Option<Configured<N>>,
    active: Option<Active>,
    /// The last failed configuration or activation, on `/diagnostics` until a transition
    /// succeeds.
    failure: Option<Failure>,
    requests: (Sender<Request>, Receiver<Request>),
    /// The lifecycle servers.
    servers: Vec<smol::Task<()>>,
}

/// The supervisor thread of a node.
pub struct Supervisor {
    tx: Sender<Request>,
    thread: Option<JoinHandle<()>>,
}

impl Supervisor {
    /// Stops the node: deactivates and cleans up, then drops the ROS node.
    pub fn stop(&mut self) {
        let _ = self.tx.send(Request::Stop);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for Supervisor {
    fn drop(&mut self) {
        self.stop();
    }
}

impl<N: RosWiring> Managed<N> {
    /// The lifecycle of node `ros` (unconfigured), with its services and event topic; its
    /// state inputs will join `readers`.
    pub fn new(
        context: Context,
        args: RosArgs,
        mut ros: RosNode,
        readers: StateReaders,
        fqn: &str,
        params: ParamsLink<N>,
        log: NodeLog,
    ) -> Result<Self, NodeError> {
        let (ns, name) = (ros.namespace().to_string(), ros.name().to_string());
        let topic = |t: &str| args.resolve_topic(&ns, &name, t);
        let events =
            ros.publisher::<TransitionEvent>(&topic("~/transition_event"), &qos::reliable(10))?;
        let requests = channel::<Request>();
        let servers = lifecycle_servers(&mut ros, &topic, &log, &requests.0)?;
        Ok(Managed {
            context,
            args,
            ros,
            readers,
            fqn: fqn.to_string(),
            params,
            log,
            machine: Lifecycle::default(),
            events,
            configured: None,
            active: None,
            failure: None,
            requests,
            servers,
        })
    }

    /// Configure, then activate (`autostart`); the configuration's error if it fails.
    pub fn autostart(&mut self) -> Result<(), NodeError> {
        self.change(Transition::Configure)?;
        self.change(Transition::Activate)
    }

    /// Runs the supervisor on its own thread.
    pub fn spawn(self) -> Result<Supervisor, NodeError> {
        let tx = self.requests.0.clone();
        let thread = std::thread::Builder::new()
            .name(format!("lc-{}", self.ros.name()))
            .spawn(move || self.run())?;
        Ok(Supervisor {
            tx,
            thread: Some(thread),
        })
    }

    fn run(mut self) {
        loop {
            match self.requests.1.recv_timeout(GRAPH_PERIOD) {
                Ok(Request::Stop) | Err(RecvTimeoutError::Disconnected) => break,
                Ok(Request::Change(t, reply)) => {
                    let success = match self.machine.resolve(&t) {
                        Ok(t) => self.change(t).is_ok(),
                        Err(e) => {
                            self.log.warn(&format!("change_state refused: {e}"));
                            false
                        }
                    };
                    let _ = reply.try_send(ChangeStateResponse { success });
                }
                Ok(Request::State(reply)) => {
                    let current_state = self.machine.state().msg();
                    let _ = reply.try_send(GetStateResponse { current_state });
                }
                Ok(Request::Transitions(reply)) => {
                    let available_transitions = self.machine.available_msgs();
                    let _ = reply.try_send(GetAvailableTransitionsResponse {
                        available_transitions,
                    });
                }
                Err(RecvTimeoutError::Timeout) => {}
            }
            if let Err(e) = self.follow_graph() {
                self.log.warn(&format!("following the graph: {e}"));
            }
            if let Some(f) = self.failure.as_mut() {
                f.report(&self.log);
            }
        }
        // Stop in order: the kind's endpoints, the worker and inputs, the lifecycle servers,
        // then the ROS node (dropped with `self`).
        self.active = None;
        self.cleanup();
        self.servers.clear();
    }

    /// Runs transition `t`, publishing both events; the callback's error if it failed.
    fn change(&mut self, t: Transition) -> Result<(), NodeError> {
        let (pending, event) = self.machine.begin(t, stamp())?;
        self.publish(event);
        let result = match t.callback() {
            Callback::Configure => self.configure(),
            Callback::Activate => self.activate(),
            Callback::Deactivate => {
                self.deactivate();
                Ok(())
            }
            Callback::Cleanup => {
                self.cleanup();
                Ok(())
            }
            Callback::Shutdown => {
                self.active = None;
                self.cleanup();
                Ok(())
            }
        };
        if let Err(e) = &result {
            self.log.error(&format!("{} failed: {e}", t.label()));
            // A failed activation leaves the node inactive, a failed configuration unconfigured.
            self.deactivate();
            if t == Transition::Configure {
                self.cleanup();
            }
        }
        let event = self.machine.finish(pending, result.is_ok(), stamp());
        self.log.info(&format!(
            "lifecycle: {} → {}",
            t.label(),
            self.machine.state().label()
        ));
        self.publish(event);
        self.failure = match &result {
            Err(e) if matches!(t, Transition::Configure | Transition::Activate) => {
                // At the node's diagnostics.period (the parameters were checked at start).
                let period = self.params.0.lock().ok().and_then(|c| {
                    NodeParams::<N::Params>::from_parameters(&c)
                        .ok()
                        .map(|p| p.common.diagnostics.period)
                });
                let state = self.machine.state().label();
                let what = (t.label(), state, e);
                Failure::start(&mut self.ros, &self.fqn, what, period, &self.log)
            }
            _ => None,
        };
        result
    }

    fn publish(&self, event: TransitionEvent) {
        if let Err(e) = self.events.publish(event) {
            self.log.warn(&format!("publish transition_event: {e:?}"));
        }
    }

    /// Loads the scene (parameters as they are now), starts the worker and the state inputs.
    fn configure(&mut self) -> Result<(), NodeError> {
        let current = self.params.0.lock().map_err(|_| poisoned())?.clone();
        let params = NodeParams::<N::Params>::from_parameters(&current)?;
        let robot = Robot::load(&params.common)?;
        let budget = WorkBudget::of(robot.scene());
        params.node.check_work(&budget)?;
        params.check_model(robot.model())?;
        let logic = N::new(robot, params.clone(), self.log.clone())?;
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
        let constraints = logic.robot().constraint_names().to_vec();
        let model = Arc::new(logic.robot().model().clone());
        let (out_tx, outputs) = smol::channel::bounded::<N::Output>(16);
        let (diag_tx, statuses) = smol::channel::bounded::<(Time, DiagnosticStatus)>(4);
        let worker = WorkerHandle::spawn(logic, self.ros.name(), &self.fqn, out_tx, diag_tx)?;
        {
            // A set that arrived while the scene loaded changed `current` but had no worker to
            // reach: hand the worker the parameters as they are now, under the lock the set
            // action takes, so no acknowledged set is lost between the two.
            let now = self.params.0.lock().map_err(|_| poisoned())?;
            let sender = worker.sender();
            if now.values != current.values {
                let latest = NodeParams::<N::Params>::from_parameters(&now)?;
                let _ = sender.send(Event::Params(Box::new(latest)));
            }
            *self.params.1.lock().map_err(|_| poisoned())? = Some(WorkerLink {
                tx: sender,
                budget,
                model,
            });
        }
        let mut c = Configured {
            params,
            constraints,
            worker,
            outputs,
            statuses,
            tasks: Vec::new(),
            inputs: Vec::new(),
        };
        let (mut tasks, mut inputs) = (Vec::new(), Vec::new());
        let inbox = c.worker.inbox();
        with_wiring(
            &self.context,
            &self.args,
            &mut self.ros,
            &self.log,
            &mut c,
            &mut tasks,
            |w| {
                inputs = wire_state_inputs(w, &self.readers, &inbox)?;
                Ok(())
            },
        )?;
        (c.tasks, c.inputs) = (tasks, inputs);
        self.configured = Some(c);
        self.log
            .info(&format!("{} configured: {summary}", self.ros.name()));
        Ok(())
    }

    /// Creates the kind's endpoints and `/diagnostics`, starts ticking.
    fn activate(&mut self) -> Result<(), NodeError> {
        let Some(c) = self.configured.as_mut() else {
            return Err(LifecycleError::NotConfigured.into());
        };
        // Outputs and statuses from before a deactivation are stale now.
        while c.outputs.try_recv().is_ok() {}
        while c.statuses.try_recv().is_ok() {}
        let statuses = c.statuses.clone();
        let mut tasks = Vec::new();
        let mut followed = None;
        with_wiring(
            &self.context,
            &self.args,
            &mut self.ros,
            &self.log,
            c,
            &mut tasks,
            |w| {
                wire_diagnostics(w, statuses)?;
                wire_set_payload(w)?;
                N::wire(w)?;
                N::follow_graph(w, &mut followed)
            },
        )?;
        let _ = c.worker.sender().send(Event::Active(true));
        self.active = Some(Active {
            _endpoints: tasks,
            followed,
        });
        Ok(())
    }

    /// Removes the kind's endpoints, stops ticking.
    fn deactivate(&mut self) {
        self.active = None;
        if let Some(c) = &self.configured {
            let _ = c.worker.sender().send(Event::Active(false));
        }
    }

    /// Stops the worker and the state inputs.
    fn cleanup(&mut self) {
        if let Ok(mut slot) = self.params.1.lock() {
            *slot = None;
        }
        if let Some(mut c) = self.configured.take() {
            c.tasks.clear();
            c.inputs.clear();
            c.worker.stop();
        }
    }

    /// Lets the active kind adapt to the discovered graph.
    fn follow_graph(&mut self) -> Result<(), NodeError> {
        let (Some(active), Some(c)) = (self.active.as_mut(), self.configured.as_mut()) else {
            return Ok(());
        };
        let mut unused = Vec::new();
        with_wiring(
            &self.context,
            &self.args,
            &mut self.ros,
            &self.log,
            c,
            &mut unused,
            |w| N::follow_graph(w, &mut active.followed),
        )
    }
}

/// Runs `f` with a [`Wiring`] of the configured node; the tasks it creates go to `tasks`.
fn with_wiring<N: RosWiring>(
    context: &Context,
    args: &RosArgs,
    ros: &mut RosNode,
    log: &NodeLog,
    c: &mut Configured<N>,
    tasks: &mut Vec<smol::Task<()>>,
    f: impl FnOnce(&mut Wiring<N>) -> Result<(), NodeError>,
) -> Result<(), NodeError> {
    let (ns, name) = (ros.namespace().to_string(), ros.name().to_string());
    let topic = |t: &str| args.resolve_topic(&ns, &name, t);
    let mut w = Wiring::<N> {
        context,
        ros,
        params: &c.params,
        constraints: &c.constraints,
        topic: &topic,
        tx: c.worker.sender(),
        outputs: Some(c.outputs.clone()),
        log: log.clone(),
        tasks: Vec::new(),
    };
    let result = f(&mut w);
    tasks.append(&mut w.tasks);
    result
}

/// A transition event's timestamp [ns since the epoch] (wall time, as rcl_lifecycle's).
fn stamp() -> u64 {
    Time::now().to_nanos().max(0) as u64
}

fn poisoned() -> NodeError {
    NodeError::Poisoned
}
