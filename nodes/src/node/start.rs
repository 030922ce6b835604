//! Starting one node of any kind: its ROS node with declared parameters, each set request
//! validated as a whole and handed to the worker when there is one, and its lifecycle
//! ([`super::managed`]), configured and activated at once unless `autostart` is false.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use ros2_client::{Context, NodeOptions};

use super::managed::{Managed, Supervisor, WorkerLink};
use super::state_readers::StateReaders;
use super::wiring::RosWiring;
use crate::error::NodeError;
use crate::node::worker::{Event, NodeLogic};
use crate::params::{NodeParams, WorkBudget};
use crate::ros::args::{Parameters, RosArgs};
use crate::ros::context::RosNode;
use crate::ros::logging::{self, NodeLog};

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

/// Starts node `name` of kind `N` in the arguments' namespace (`__ns`, else `/`) with its
/// parameters: its ROS node, its
/// lifecycle services and, with `autostart` (the default), configured and active at once. Its
/// joint states and odometry come through the process's shared `readers`. A
/// failed configuration or activation leaves the node unconfigured (or inactive) with an
/// ERROR on `/rosout` and `/diagnostics`, so the other nodes of the process run on; with
/// `exit_on_failure` it is returned instead (the process exits).
pub fn start_node<N: RosWiring>(
    context: &Context,
    args: &RosArgs,
    name: &str,
    ros_params: Parameters,
    params: NodeParams<N::Params>,
    readers: &StateReaders,
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
    let namespace = args.namespace_or("/");
    let ros = RosNode::new(context, namespace, name, options)?;
    logging::register(name, ros.node.logging_handle());
    ready.store(true, Ordering::SeqCst);
    let fqn = format!("{}/{name}", namespace.trim_end_matches('/'));
    let autostart = params.common.autostart;
    let mut managed = Managed::<N>::new(
        context.clone(),
        args.clone(),
        ros,
        readers.clone(),
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
