//! The real-time side of a node: one thread that owns the node's logic and handles its events
//! in order, off the ROS executor.
//!
//! The glue translates every request and message into an [`Event`] and sends it with
//! `try_send` (never blocking the executor); requests carry a reply channel the glue awaits.
//! Joint states and odometry instead wait in the worker's inbox, filled by readers the
//! process's nodes share ([`super::state_readers`]), and are applied before the next event or
//! tick: a node that only answers requests is not woken by each of them.
//! A node kind with a tick (the predictor) is ticked at its period on the ROS clock (wall time,
//! or `/clock` under `use_sim_time`) and hands
//! its results to the glue as outputs. A panic inside the logic is caught: the request gets an
//! error, the logic is rebuilt from its scene, and the worker keeps serving.

use std::collections::VecDeque;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, sync_channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::error::NodeError;
use crate::msg::builtin_interfaces::Time;
use crate::msg::constraint_dynamics_msgs::srv::{SetPayloadRequest, SetPayloadResponse};
use crate::msg::diagnostic_msgs::{DiagnosticStatus, KeyValue};
use crate::msg::nav_msgs::Odometry;
use crate::msg::sensor_msgs::JointState;
use crate::node::health::{Health, Input, StatusContext};
use crate::node::state_readers::{BATCH, Inbox, StateMsg};
use crate::node::timer::RosTimer;
use crate::params::{KindParams, NodeParams};
use crate::robot::Robot;
use crate::ros::logging::{DropLog, NodeLog};

pub use crate::ros::io::Reply;

#[path = "worker_rebuild.rs"]
mod rebuild;
#[path = "worker_state.rs"]
mod state;

/// The domain logic of one node kind: plain data in, plain data out, no ROS handles.
pub trait NodeLogic: Sized + Send + 'static {
    /// The kind's own parameters.
    type Params: KindParams;
    /// What the kind reacts to besides the state inputs every node has.
    type Input: Send + 'static;
    /// What the kind hands to the glue to publish.
    type Output: Send + 'static;

    /// Builds the kind's logic around a robot.
    fn new(robot: Robot, params: NodeParams<Self::Params>, log: NodeLog)
    -> Result<Self, NodeError>;
    /// The robot it serves.
    fn robot(&self) -> &Robot;
    /// The robot, to apply state messages to.
    fn robot_mut(&mut self) -> &mut Robot;
    /// Its parameters.
    fn params(&self) -> &NodeParams<Self::Params>;
    /// Replaces the parameters (run-time changes of the dynamic ones).
    fn set_params(&mut self, params: NodeParams<Self::Params>);
    /// Handles one kind-specific input at ROS time `now`; `out` publishes.
    fn handle(&mut self, input: Self::Input, now: Time, out: &mut dyn FnMut(Self::Output));
    /// The tick period, for kinds that work periodically.
    fn tick_period(&self) -> Option<Duration> {
        None
    }
    /// One periodic step at ROS time `now`; an error means the node cannot do its work.
    fn tick(&mut self, _now: Time, _out: &mut dyn FnMut(Self::Output)) -> Result<(), NodeError> {
        Ok(())
    }
    /// A `joint_states` message, just applied to the robot's state.
    fn joint_state_applied(&mut self, _js: &JointState) {}
    /// An `odom` message, just applied to the robot's state.
    fn odometry_applied(&mut self, _od: &Odometry) {}
    /// Kind-specific values for the node's `/diagnostics` status.
    fn diagnostics(&self) -> Vec<KeyValue> {
        Vec::new()
    }
    /// Kind-specific reasons for a WARN status (stale inputs the kind will not use).
    fn warnings(&self) -> Vec<String> {
        Vec::new()
    }
    /// Why the tick rate may fall short of the requested one (the last tick's work against the
    /// period), added to the status' rate warning when the achieved rate is low.
    fn rate_shortfall(&self) -> Option<String> {
        None
    }
}

/// Everything a worker reacts to. Joint states and odometry wait in the worker's inbox
/// ([`super::state_readers`]) and are applied before each event.
pub enum Event<N: NodeLogic> {
    /// The inbox asks to be taken (a batch, an input after a silence, sim time).
    StateWaiting,
    /// A new URDF on `robot_description`.
    RobotDescription(String),
    /// `/clock` (with `use_sim_time`).
    Clock(Time),
    /// New parameter values (run-time change), already validated.
    Params(Box<NodeParams<N::Params>>),
    /// `~/set_payload`: rebuild the model with this payload.
    SetPayload(SetPayloadRequest, Reply<SetPayloadResponse>),
    /// The kind's own input.
    Node(N::Input),
    /// Lifecycle: active (tick and report) or not (follow inputs only).
    Active(bool),
    /// Stop the thread.
    Shutdown,
}

/// Capacity of a worker's event queue: requests that find it full get a "busy" error.
pub const QUEUE: usize = 1024;

/// How long [`WorkerHandle::stop`] waits for the worker to finish what it is computing. A
/// prediction cannot be interrupted (it may run for seconds, up to the scene's work limits);
/// after this the worker is left to finish on its own and then exit, so that stopping a node
/// — and SIGINT, which stops every node — never waits for a computation.
pub const STOP_WAIT: Duration = Duration::from_millis(200);

/// The glue's side of a worker.
pub struct WorkerHandle<N: NodeLogic> {
    tx: SyncSender<Event<N>>,
    thread: Option<JoinHandle<()>>,
    /// Set by [`WorkerHandle::stop`]: the worker exits before its next event.
    stopping: Arc<AtomicBool>,
    name: String,
    inbox: Arc<Inbox>,
}

impl<N: NodeLogic> WorkerHandle<N> {
    /// Starts a worker owning `logic`; its outputs go to `outputs`.
    pub fn spawn(
        logic: N,
        name: &str,
        fqn: &str,
        outputs: smol::channel::Sender<N::Output>,
        diagnostics: smol::channel::Sender<(Time, DiagnosticStatus)>,
    ) -> Result<WorkerHandle<N>, NodeError> {
        let (tx, rx) = sync_channel(QUEUE);
        let common = &logic.params().common;
        let mut subscribed = Vec::new();
        if !common.state.joint_states_topic.is_empty() {
            subscribed.push(Input::JointStates);
        }
        if !common.state.odom_topic.is_empty() {
            subscribed.push(Input::Odometry);
        }
        // Under sim time each message wakes the worker, which stamps it with its clock.
        let batch = if common.use_sim_time { 1 } else { BATCH };
        let silence = Duration::from_secs_f64(common.diagnostics.input_timeout);
        let inbox = Inbox::new(batch, silence);
        let stopping = Arc::new(AtomicBool::new(false));
        let mut worker = Worker {
            inbox: inbox.clone(),
            taken: VecDeque::new(),
            stopping: stopping.clone(),
            logic,
            log: NodeLog::new(name),
            fqn: fqn.to_string(),
            outputs,
            diagnostics,
            subscribed,
            health: Health::default(),
            last_level: None,
            sim_time: None,
            warned: Default::default(),
            drops: DropLog::default(),
            active: false,
        };
        let thread = std::thread::Builder::new()
            .name(format!("cd-{name}"))
            .spawn(move || worker.run(rx))?;
        Ok(WorkerHandle {
            tx,
            thread: Some(thread),
            stopping,
            name: name.to_string(),
            inbox,
        })
    }

    /// The inbox the node's state readers fill.
    pub fn inbox(&self) -> Arc<Inbox> {
        self.inbox.clone()
    }

    /// A sender for tasks of the glue.
    pub fn sender(&self) -> SyncSender<Event<N>> {
        self.tx.clone()
    }

    /// Stops the thread: it exits before its next event (queued requests are dropped, their
    /// callers get the "internal error" reply or none). Waits for it at most [`STOP_WAIT`]; a
    /// worker still computing then is left to finish and exit on its own.
    pub fn stop(&mut self) {
        self.stopping.store(true, Ordering::SeqCst);
        // Wakes an idle worker; a full queue means it is busy and will see the flag.
        let _ = self.tx.try_send(Event::Shutdown);
        let Some(t) = self.thread.take() else {
            return;
        };
        let deadline = Instant::now() + STOP_WAIT;
        while !t.is_finished() && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(2));
        }
        if t.is_finished() {
            let _ = t.join();
        } else {
            NodeLog::new(&self.name).info(&format!(
                "stopping while a computation runs: not waiting for it (more than {} ms)",
                STOP_WAIT.as_millis()
            ));
        }
    }
}

impl<N: NodeLogic> Drop for WorkerHandle<N> {
    fn drop(&mut self) {
        self.stop();
    }
}

/// Which "warn once" messages were logged.
#[derive(Default)]
struct Warned {
    unknown_joints: bool,
}

struct Worker<N: NodeLogic> {
    /// Set when the node stops: exit before the next event.
    stopping: Arc<AtomicBool>,
    logic: N,
    log: NodeLog,
    /// Fully qualified node name (the diagnostics status' name).
    fqn: String,
    outputs: smol::channel::Sender<N::Output>,
    diagnostics: smol::channel::Sender<(Time, DiagnosticStatus)>,
    subscribed: Vec<Input>,
    health: Health,
    /// Level of the last published status, and whether the kind warned (a change of either
    /// publishes at once: stale inputs are reported when they go stale, even under a WARN
    /// for another reason).
    last_level: Option<(u8, bool)>,
    sim_time: Option<Time>,
    warned: Warned,
    /// Rate limit of the lines about dropped joint states and odometry, per reason.
    drops: DropLog,
    /// Lifecycle state: only an active node ticks and publishes its status.
    active: bool,
    /// Joint states and odometry not yet applied.
    inbox: Arc<Inbox>,
    /// What was taken from the inbox and is being applied.
    taken: VecDeque<(Time, StateMsg)>,
}

/// The worker's two timers.
struct Timers {
    diag: RosTimer,
    tick: Option<RosTimer>,
}

impl<N: NodeLogic> Worker<N> {
    fn run(&mut self, rx: Receiver<Event<N>>) {
        if self.logic.tick_period().is_some() {
            crate::node::timer::lower_priority();
        }
        // Ticks and diagnostics run on the ROS clock (see `RosTimer`).
        let sim = self.logic.params().common.use_sim_time;
        let diag_period = Duration::from_secs_f64(self.logic.params().common.diagnostics.period);
        let mut timers = Timers {
            diag: RosTimer::new(diag_period),
            tick: self.logic.tick_period().map(RosTimer::new),
        };
        loop {
            // Inactive: only events wake the worker (its timers are not advanced, so waiting
            // for them would spin).
            let idle = Duration::from_secs(3600);
            let timeout = match self.active {
                true => timers
                    .tick
                    .as_ref()
                    .map_or(idle, |t| t.wait(sim))
                    .min(timers.diag.wait(sim)),
                false => idle,
            };
            let received = rx.recv_timeout(timeout);
            if self.stopping.load(Ordering::SeqCst) {
                return;
            }
            match received {
                Ok(ev) => {
                    if self.apply(ev, &mut timers) {
                        return;
                    }
                }
                Err(RecvTimeoutError::Disconnected) => return,
                Err(RecvTimeoutError::Timeout) => {}
            }
            // Apply every queued state message before a tick, so that a prediction never
            // starts from a state older than the queue (a slow tick would otherwise leave it
            // one message behind per period).
            while let Ok(ev) = rx.try_recv() {
                if self.stopping.load(Ordering::SeqCst) || self.apply(ev, &mut timers) {
                    return;
                }
            }
            if self.stopping.load(Ordering::SeqCst) {
                return;
            }
            self.take_state();
            // An inactive node (lifecycle) follows its inputs but neither predicts nor reports.
            if !self.active {
                continue;
            }
            let clock = sim.then_some(self.sim_time);
            if timers.tick.as_mut().is_some_and(|t| t.due(clock)) {
                self.guarded("prediction", |w| {
                    w.tick();
                    false
                });
            }
            let scheduled = timers.diag.due(clock);
            self.publish_status(scheduled);
        }
    }

    /// Handles one event; true to stop the thread.
    fn apply(&mut self, ev: Event<N>, timers: &mut Timers) -> bool {
        // What arrived before the event is applied before it.
        self.take_state();
        match ev {
            Event::Shutdown => return true,
            Event::RobotDescription(urdf) => {
                // A new model re-plans at once.
                if self.guarded("robot_description", |w| w.robot_description(&urdf))
                    && let Some(t) = timers.tick.as_mut()
                {
                    t.reset();
                }
            }
            Event::SetPayload(req, reply) => {
                // A new model re-plans at once, as a new URDF does.
                if self.serve_set_payload(&req, reply)
                    && let Some(t) = timers.tick.as_mut()
                {
                    t.reset();
                }
            }
            Event::Active(active) => {
                if active && !self.active {
                    // Predict and report at once on activation.
                    timers.diag.reset();
                    if let Some(t) = timers.tick.as_mut() {
                        t.reset();
                    }
                    self.last_level = None;
                }
                self.active = active;
            }
            ev => {
                self.guarded("event", |w| {
                    w.handle(ev);
                    false
                });
            }
        }
        false
    }

    /// One periodic step, timed and recorded.
    fn tick(&mut self) {
        let now = self.now();
        let started = Instant::now();
        let outputs = &self.outputs;
        let result = self.logic.tick(now, &mut |o| {
            let _ = outputs.try_send(o);
        });
        let error = result.err().map(|e| {
            self.log.error(&format!("periodic prediction failed: {e}"));
            e.to_string()
        });
        self.health
            .tick(now, started.elapsed().as_secs_f64(), error);
    }

    /// Sends the node's status when `scheduled` or when its level (or the kind's warning)
    /// changed. Called after every event: the status itself is built only when it is sent.
    fn publish_status(&mut self, scheduled: bool) {
        let now = self.now();
        let params = self.logic.params();
        let requested_rate = self.logic.tick_period().map(|p| 1.0 / p.as_secs_f64());
        let warnings = self.logic.warnings();
        let kind_warns = !warnings.is_empty();
        let diagnostics = &params.common.diagnostics;
        let level = (self.health).level(
            now,
            requested_rate,
            &self.subscribed,
            diagnostics,
            kind_warns,
        );
        let level = Some((level, kind_warns));
        if !scheduled && self.last_level == level {
            return;
        }
        let mut extra = vec![self.payload_status()];
        extra.extend(self.logic.diagnostics());
        let ctx = StatusContext {
            name: &self.fqn,
            model: &self.logic.robot().model().name,
            requested_rate,
            subscribed: &self.subscribed,
            params: diagnostics,
            extra,
            warnings,
            rate_shortfall: self.logic.rate_shortfall(),
        };
        let status = self.health.status(now, ctx);
        debug_assert_eq!(Some((status.level, kind_warns)), level);
        self.last_level = level;
        let _ = self.diagnostics.try_send((now, status));
    }

    /// Runs `f`, catching a panic: logs it and rebuilds the logic.
    fn guarded(&mut self, what: &str, f: impl FnOnce(&mut Self) -> bool) -> bool {
        match catch_unwind(AssertUnwindSafe(|| f(self))) {
            Ok(r) => r,
            Err(p) => {
                let msg = panic_message(&p);
                self.log.error(&format!(
                    "internal error while handling {what}: {msg}; rebuilding the model"
                ));
                let params = self.logic.params().clone();
                let next = self
                    .logic
                    .robot()
                    .rebuilt(&params.common)
                    .and_then(|robot| N::new(robot, params, self.log.clone()));
                match next {
                    Ok(l) => self.logic = l,
                    Err(e) => self.log.error(&format!("rebuild failed: {e}")),
                }
                false
            }
        }
    }

    fn now(&self) -> Time {
        self.sim_time.unwrap_or_else(Time::now)
    }

    fn handle(&mut self, ev: Event<N>) {
        match ev {
            Event::RobotDescription(urdf) => {
                self.robot_description(&urdf);
            }
            Event::Clock(t) => self.sim_time = Some(t),
            Event::Params(p) => self.params_changed(*p),
            Event::Node(input) => {
                let now = self.now();
                let started = Instant::now();
                let outputs = &self.outputs;
                self.logic.handle(input, now, &mut |o| {
                    let _ = outputs.try_send(o);
                });
                self.health.request(started.elapsed().as_secs_f64());
            }
            Event::SetPayload(req, reply) => {
                self.serve_set_payload(&req, reply);
            }
            Event::StateWaiting | Event::Shutdown | Event::Active(_) => {}
        }
    }
}

fn panic_message(p: &Box<dyn std::any::Any + Send>) -> String {
    if let Some(s) = p.downcast_ref::<&str>() {
        s.to_string()
    } else if let Some(s) = p.downcast_ref::<String>() {
        s.clone()
    } else {
        "panic".into()
    }
}
