//! The real-time side of a node: one thread that owns the node's [`Engine`] and handles
//! domain [`Event`]s in order, off the ROS executor.
//!
//! The glue translates every message and request into an [`Event`] and sends it with
//! `try_send` (never blocking the executor); requests carry a reply channel the glue awaits.
//! The predictor's worker also ticks at the prediction rate and hands its results to the glue
//! as [`Output`]s. A panic inside the engine is caught: the request gets an error, the engine
//! is rebuilt from its scene, and the worker keeps serving.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, sync_channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::engine::{Engine, PeriodicOutput};
use crate::logging::NodeLog;
use crate::msg::builtin_interfaces::Time;
use crate::msg::constraint_dynamics_msgs::srv::{
    GetConstraintForcesRequest, GetConstraintForcesResponse, PredictRequest, PredictResponse,
    ProjectVelocityRequest, ProjectVelocityResponse,
};
use crate::msg::geometry_msgs::Twist;
use crate::msg::nav_msgs::Odometry;
use crate::msg::sensor_msgs::JointState;
use crate::msg::std_msgs::Header;
use crate::params::NodeParams;

/// Where a request's response goes.
pub type Reply<T> = smol::channel::Sender<T>;

/// Everything a worker reacts to.
pub enum Event {
    /// `/joint_states`.
    JointState(JointState),
    /// `/odom`.
    Odometry(Box<Odometry>),
    /// A velocity command (predictor: the command to predict under).
    Command(Twist),
    /// A command to filter (projection node), with the header of a stamped input.
    FilterCommand(Twist, Option<Header>),
    /// A new URDF on `/robot_description`.
    RobotDescription(String),
    /// `/clock` (with `use_sim_time`).
    Clock(Time),
    /// New parameter values (run-time change).
    Params(Box<NodeParams>),
    GetConstraintForces(
        GetConstraintForcesRequest,
        Reply<GetConstraintForcesResponse>,
    ),
    ProjectVelocity(ProjectVelocityRequest, Reply<ProjectVelocityResponse>),
    Predict(PredictRequest, Reply<PredictResponse>),
    /// Stop the thread.
    Shutdown,
}

/// What a worker hands to the glue to publish.
pub enum Output {
    Periodic(Box<PeriodicOutput>),
    /// A filtered command (with the input's header when stamped).
    Filtered(Twist, Option<Header>),
}

/// Capacity of a worker's event queue. State messages that find it full are dropped;
/// requests get a "busy" error.
pub const QUEUE: usize = 1024;

/// The glue's side of a worker.
pub struct WorkerHandle {
    tx: SyncSender<Event>,
    thread: Option<JoinHandle<()>>,
}

impl WorkerHandle {
    /// Starts a worker owning `engine`. `tick` is the prediction period (predictor only).
    pub fn spawn(
        engine: Engine,
        name: &str,
        tick: Option<Duration>,
        outputs: smol::channel::Sender<Output>,
    ) -> std::io::Result<WorkerHandle> {
        let (tx, rx) = sync_channel(QUEUE);
        let log = NodeLog::new(name);
        let mut worker = Worker {
            engine,
            log,
            outputs,
            tick,
            sim_time: None,
            last_command: None,
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
    pub fn sender(&self) -> SyncSender<Event> {
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

impl Drop for WorkerHandle {
    fn drop(&mut self) {
        self.stop();
    }
}

/// Which "warn once" messages were logged.
#[derive(Default)]
struct Warned {
    joint_state: bool,
    odometry: bool,
    command: bool,
    unknown_joints: bool,
}

struct Worker {
    engine: Engine,
    log: NodeLog,
    outputs: smol::channel::Sender<Output>,
    tick: Option<Duration>,
    sim_time: Option<Time>,
    /// Latest (v, ω) command and when it arrived.
    last_command: Option<([f64; 2], Instant)>,
    warned: Warned,
}

impl Worker {
    fn run(&mut self, rx: Receiver<Event>) {
        let mut next_tick = Instant::now();
        loop {
            let timeout = match self.tick {
                Some(_) => next_tick.saturating_duration_since(Instant::now()),
                None => Duration::from_secs(3600),
            };
            match rx.recv_timeout(timeout) {
                Ok(Event::Shutdown) | Err(RecvTimeoutError::Disconnected) => break,
                Ok(Event::RobotDescription(urdf)) => {
                    if self.guarded("robot_description", |w| w.robot_description(&urdf)) {
                        // A new model re-plans at once.
                        next_tick = Instant::now();
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
            if let Some(period) = self.tick {
                let now = Instant::now();
                if now >= next_tick {
                    self.guarded("prediction", |w| {
                        w.periodic();
                        false
                    });
                    next_tick += period;
                    if next_tick < Instant::now() {
                        // Behind (a prediction took longer than the period): do not catch up.
                        next_tick = Instant::now() + period;
                    }
                }
            }
        }
    }

    /// Runs `f`, catching a panic: logs it and rebuilds the engine.
    fn guarded(&mut self, what: &str, f: impl FnOnce(&mut Worker) -> bool) -> bool {
        match catch_unwind(AssertUnwindSafe(|| f(self))) {
            Ok(r) => r,
            Err(p) => {
                let msg = panic_message(&p);
                self.log.error(&format!(
                    "internal error while handling {what}: {msg}; rebuilding the model"
                ));
                match self.engine.rebuilt() {
                    Ok(e) => self.engine = e,
                    Err(e) => self.log.error(&format!("rebuild failed: {e}")),
                }
                false
            }
        }
    }

    fn now(&self) -> Time {
        self.sim_time.unwrap_or_else(Time::now)
    }

    fn handle(&mut self, ev: Event) {
        match ev {
            Event::JointState(js) => match self.engine.apply_joint_state(&js) {
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
            },
            Event::Odometry(od) => {
                if let Err(e) = self.engine.apply_odometry(&od) {
                    let first = !std::mem::replace(&mut self.warned.odometry, true);
                    self.log
                        .log(level(first), &format!("dropped an odometry message: {e}"));
                }
            }
            Event::Command(t) => {
                let cmd = if t.linear.x.is_finite() && t.angular.z.is_finite() {
                    Some([t.linear.x, t.angular.z])
                } else {
                    None
                };
                if let Err(e) = self.engine.twist_command(&t, "cmd_vel") {
                    let first = !std::mem::replace(&mut self.warned.command, true);
                    self.log.log(
                        level(first),
                        &format!("{e}; using linear.x and angular.z if finite"),
                    );
                }
                match cmd {
                    Some(c) => self.last_command = Some((c, Instant::now())),
                    None => self.last_command = None,
                }
            }
            Event::FilterCommand(t, header) => {
                let out = match self.engine.filter_command(&t) {
                    Ok((out, resp)) => {
                        if !resp.success {
                            self.log.warn(&format!(
                                "filter: command ({}, {}, {}) is infeasible, sending zero: {}",
                                t.linear.x, t.linear.y, t.angular.z, resp.message
                            ));
                        }
                        out
                    }
                    Err(e) => {
                        self.log
                            .warn(&format!("filter: command refused, sending zero: {e}"));
                        Twist::default()
                    }
                };
                let _ = self.outputs.try_send(Output::Filtered(out, header));
            }
            Event::RobotDescription(urdf) => {
                self.robot_description(&urdf);
            }
            Event::Clock(t) => self.sim_time = Some(t),
            Event::Params(p) => {
                self.log.info("parameters changed");
                self.engine.set_params(*p);
            }
            Event::GetConstraintForces(req, reply) => {
                let now = self.now();
                let resp = self.engine.get_constraint_forces(&req, now);
                let _ = reply.try_send(resp);
            }
            Event::ProjectVelocity(req, reply) => {
                let resp = self.engine.project_velocity(&req);
                let _ = reply.try_send(resp);
            }
            Event::Predict(req, reply) => {
                let now = self.now();
                let resp = self.engine.predict(&req, now);
                let _ = reply.try_send(resp);
            }
            Event::Shutdown => {}
        }
    }

    /// Rebuilds the model from a URDF; true if it changed.
    fn robot_description(&mut self, urdf: &str) -> bool {
        match self.engine.with_urdf(urdf) {
            Ok(next) => {
                let m = &next.scene().model;
                self.log.info(&format!(
                    "model rebuilt from robot_description: '{}', nq = {}, nv = {}",
                    m.name, m.nq, m.nv
                ));
                self.engine = next;
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

    fn periodic(&mut self) {
        let timeout = self.engine.params().command().timeout;
        let command = self
            .last_command
            .filter(|(_, at)| at.elapsed().as_secs_f64() <= timeout)
            .map(|(c, _)| c);
        let now = self.now();
        match self.engine.periodic(now, command) {
            Ok(out) => {
                self.log
                    .debug(&format!("prediction took {:.3} ms", out.compute_s * 1e3));
                let _ = self.outputs.try_send(Output::Periodic(Box::new(out)));
            }
            Err(e) => self.log.error(&format!("periodic prediction failed: {e}")),
        }
    }
}

/// Warn the first time, debug afterwards (a stream of bad messages should not flood /rosout).
fn level(first: bool) -> log::Level {
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
