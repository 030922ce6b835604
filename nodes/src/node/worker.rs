//! The real-time side of a node: one thread that owns the node's logic and handles its events
//! in order, off the ROS executor.
//!
//! The glue translates every message and request into an [`Event`] and sends it with
//! `try_send` (never blocking the executor); requests carry a reply channel the glue awaits.
//! A node kind with a tick (the predictor) is ticked at its period on the ROS clock (wall time,
//! or `/clock` under `use_sim_time`) and hands
//! its results to the glue as outputs. A panic inside the logic is caught: the request gets an
//! error, the logic is rebuilt from its scene, and the worker keeps serving.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, sync_channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::error::NodeError;
use crate::msg::builtin_interfaces::Time;
use crate::msg::nav_msgs::Odometry;
use crate::msg::sensor_msgs::JointState;
use crate::params::{KindParams, NodeParams};
use crate::robot::Robot;
use crate::ros::logging::NodeLog;

pub use crate::ros::io::Reply;

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
    /// One periodic step at ROS time `now`.
    fn tick(&mut self, _now: Time, _out: &mut dyn FnMut(Self::Output)) {}
}

/// Everything a worker reacts to.
pub enum Event<N: NodeLogic> {
    /// `joint_states`.
    JointState(JointState),
    /// `odom`.
    Odometry(Box<Odometry>),
    /// A new URDF on `robot_description`.
    RobotDescription(String),
    /// `/clock` (with `use_sim_time`).
    Clock(Time),
    /// New parameter values (run-time change), already validated.
    Params(Box<NodeParams<N::Params>>),
    /// The kind's own input.
    Node(N::Input),
    /// Stop the thread.
    Shutdown,
}

/// Capacity of a worker's event queue. State messages that find it full are dropped;
/// requests get a "busy" error.
pub const QUEUE: usize = 1024;

/// The glue's side of a worker.
pub struct WorkerHandle<N: NodeLogic> {
    tx: SyncSender<Event<N>>,
    thread: Option<JoinHandle<()>>,
}

impl<N: NodeLogic> WorkerHandle<N> {
    /// Starts a worker owning `logic`; its outputs go to `outputs`.
    pub fn spawn(
        logic: N,
        name: &str,
        outputs: smol::channel::Sender<N::Output>,
    ) -> Result<WorkerHandle<N>, NodeError> {
        let (tx, rx) = sync_channel(QUEUE);
        let mut worker = Worker {
            logic,
            log: NodeLog::new(name),
            outputs,
            sim_time: None,
            warned: Default::default(),
        };
        let thread = std::thread::Builder::new()
            .name(format!("cd-{name}"))
            .spawn(move || worker.run(rx))?;
        Ok(WorkerHandle {
            tx,
            thread: Some(thread),
        })
    }

    /// A sender for tasks of the glue.
    pub fn sender(&self) -> SyncSender<Event<N>> {
        self.tx.clone()
    }

    /// Stops the thread and waits for it.
    pub fn stop(&mut self) {
        let _ = self.tx.send(Event::Shutdown);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
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
    joint_state: bool,
    odometry: bool,
    unknown_joints: bool,
}

struct Worker<N: NodeLogic> {
    logic: N,
    log: NodeLog,
    outputs: smol::channel::Sender<N::Output>,
    sim_time: Option<Time>,
    warned: Warned,
}

impl<N: NodeLogic> Worker<N> {
    fn run(&mut self, rx: Receiver<Event<N>>) {
        // The tick runs on the ROS clock: wall time, or /clock under `use_sim_time` (then the
        // ticks follow the simulation's time, faster or slower than real time, and stop with it).
        let sim = self.logic.params().common.use_sim_time;
        let mut next_wall = Instant::now();
        let mut next_sim: Option<Time> = None;
        loop {
            let timeout = match self.logic.tick_period() {
                Some(_) if !sim => next_wall.saturating_duration_since(Instant::now()),
                _ => Duration::from_secs(3600),
            };
            match rx.recv_timeout(timeout) {
                Ok(Event::Shutdown) | Err(RecvTimeoutError::Disconnected) => break,
                Ok(Event::RobotDescription(urdf)) => {
                    if self.guarded("robot_description", |w| w.robot_description(&urdf)) {
                        // A new model re-plans at once.
                        next_wall = Instant::now();
                        next_sim = None;
                    }
                }
                Ok(ev) => {
                    self.guarded("event", |w| {
                        w.handle(ev);
                        false
                    });
                }
                Err(RecvTimeoutError::Timeout) => {}
            }
            let Some(period) = self.logic.tick_period() else {
                continue;
            };
            let due = if sim {
                match self.sim_time {
                    Some(now) if next_sim.is_none_or(|n| now.to_nanos() >= n.to_nanos()) => {
                        // Behind (a jump of /clock): the next tick is one period from now.
                        next_sim = Some(crate::convert::time_plus(now, period.as_secs_f64()));
                        true
                    }
                    _ => false,
                }
            } else if Instant::now() >= next_wall {
                next_wall += period;
                if next_wall < Instant::now() {
                    // Behind (a tick took longer than the period): do not catch up.
                    next_wall = Instant::now() + period;
                }
                true
            } else {
                false
            };
            if due {
                self.guarded("prediction", |w| {
                    let t = w.now();
                    let outputs = &w.outputs;
                    w.logic.tick(t, &mut |o| {
                        let _ = outputs.try_send(o);
                    });
                    false
                });
            }
        }
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
            Event::JointState(js) => {
                match self.logic.robot_mut().state_mut().apply_joint_state(&js) {
                    Ok(report) => {
                        if !report.unknown.is_empty() && !self.warned.unknown_joints {
                            self.warned.unknown_joints = true;
                            self.log.info(&format!(
                                "joint_states: ignoring joints the model does not have: {}",
                                report.unknown.join(", ")
                            ));
                        }
                    }
                    Err(e) => {
                        let first = !std::mem::replace(&mut self.warned.joint_state, true);
                        self.log
                            .log(level(first), &format!("dropped a joint state message: {e}"));
                    }
                }
            }
            Event::Odometry(od) => {
                let robot = self.logic.robot_mut();
                let model = robot.model().clone();
                if let Err(e) = robot.state_mut().apply_odometry(&model, &od) {
                    let first = !std::mem::replace(&mut self.warned.odometry, true);
                    self.log
                        .log(level(first), &format!("dropped an odometry message: {e}"));
                }
            }
            Event::RobotDescription(urdf) => {
                self.robot_description(&urdf);
            }
            Event::Clock(t) => self.sim_time = Some(t),
            Event::Params(p) => {
                self.log.info("parameters changed");
                self.logic.set_params(*p);
            }
            Event::Node(input) => {
                let now = self.now();
                let outputs = &self.outputs;
                self.logic.handle(input, now, &mut |o| {
                    let _ = outputs.try_send(o);
                });
            }
            Event::Shutdown => {}
        }
    }

    /// Rebuilds the model from a URDF; true if it changed.
    fn robot_description(&mut self, urdf: &str) -> bool {
        let params = self.logic.params().clone();
        let next = self
            .logic
            .robot()
            .with_urdf(urdf, &params.common)
            .and_then(|robot| N::new(robot, params, self.log.clone()));
        match next {
            Ok(next) => {
                let m = next.robot().model();
                self.log.info(&format!(
                    "model rebuilt from robot_description: '{}', nq = {}, nv = {}",
                    m.name, m.nq, m.nv
                ));
                self.logic = next;
                true
            }
            Err(e) => {
                self.log.error(&format!(
                    "robot_description refused, keeping the current model: {e}"
                ));
                false
            }
        }
    }
}

/// Warn the first time, debug afterwards (a stream of bad messages should not flood /rosout).
pub(crate) fn level(first: bool) -> log::Level {
    if first {
        log::Level::Warn
    } else {
        log::Level::Debug
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
