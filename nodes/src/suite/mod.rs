//! The suite: starts the nodes the parameters enable, all in one process on one DDS
//! participant, each with its worker thread. This is the only place that knows every node kind;
//! each kind's module holds its logic (`mod.rs`) and its ROS wiring (`ros.rs`).

pub mod cli;

use ros2_client::{Context, ParameterValue};

use crate::error::NodeError;
use crate::forces::ForcesNode;
use crate::node::start::{RunningNode, start_node};
use crate::node::state_readers::StateReaders;
use crate::node::wiring::RosWiring;
use crate::params::{NodeKind, NodeParams, resolve_path};
use crate::prediction::PredictionNode;
use crate::predictor::PredictorNode;
use crate::projection::ProjectionNode;
use crate::ros::args::{Parameters, RosArgs};
use crate::ros::context::{NetworkConfig, in_loopback_only_namespace};
use crate::ros::network_guard::{ALLOW_EXTERNAL_ENV, network_guard};

pub use cli::main;

/// The running suite. Drop (or [`Suite::shutdown`]) stops every node.
pub struct Suite {
    nodes: Vec<Box<dyn RunningNode>>,
    /// The joint-state and odometry readers the nodes share.
    readers: StateReaders,
    _context: Context,
}

impl Suite {
    /// Fully qualified names of the running nodes.
    pub fn node_names(&self) -> Vec<String> {
        self.nodes.iter().map(|n| n.fqn().to_string()).collect()
    }

    /// Stops every node.
    pub fn shutdown(mut self) {
        self.stop_all();
    }

    /// Stops the nodes side by side: each waits at most `worker::STOP_WAIT` for its worker,
    /// so a suite stops in about that time whatever its workers are computing.
    fn stop_all(&mut self) {
        std::thread::scope(|s| {
            for n in &mut self.nodes {
                s.spawn(move || n.stop());
            }
        });
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

/// Starts a planned node: (context, arguments, name, ROS parameters, shared state readers,
/// exit on failure) → the node.
type StartNode = Box<
    dyn FnOnce(
        &Context,
        &RosArgs,
        String,
        Parameters,
        &StateReaders,
        bool,
    ) -> Result<Box<dyn RunningNode>, NodeError>,
>;

/// One node to start: its name, ROS parameters, network settings, and how to start it (with
/// its typed parameters, which depend on its kind).
struct Plan {
    name: String,
    ros_params: Parameters,
    network: crate::params::NetworkParams,
    start: StartNode,
}

/// What planning one node found: the node to start (`None` when it is disabled), the shared
/// parameters it ignored (set for every node, not one of its own), and whether its kind has a
/// parameter.
struct Planned {
    plan: Option<Plan>,
    ignored: Vec<String>,
    has: fn(&str) -> bool,
}

/// The plan for one node of kind `N`, or `None` when it is disabled (and not asked for alone).
fn plan_kind<N: RosWiring>(args: &RosArgs, name: String, only: bool) -> Result<Planned, NodeError> {
    let namespace = args.namespace_or("/");
    let in_node = |e: NodeError| e.in_node(&name);
    let mut ros_params = args
        .parameters(&fqn(namespace, &name))
        .map_err(|e| in_node(e.into()))?;
    let has = NodeParams::<N::Params>::has;
    let ignored = ros_params.drop_shared(has);
    let log = crate::ros::logging::NodeLog::new(&name);
    for key in &ignored {
        log.debug(&format!(
            "ignoring parameter {key} (set for every node; not a parameter of {name})"
        ));
    }
    let mut params =
        NodeParams::<N::Params>::from_parameters(&ros_params).map_err(|e| in_node(e.into()))?;
    if !only && !params.common.enabled {
        return Ok(Planned {
            plan: None,
            ignored,
            has,
        });
    }
    let scene = resolve_path(&params.common.model.scene_file, &args.params_files);
    let scene = scene.display().to_string();
    ros_params.values.insert(
        "model.scene_file".into(),
        ParameterValue::String(scene.clone()),
    );
    params.common.model.scene_file = scene;
    let plan = Plan {
        name,
        network: params.common.network.clone(),
        ros_params,
        start: Box::new(move |context, args, name, ros_params, readers, exit| {
            start_node::<N>(context, args, &name, ros_params, params, readers, exit)
                .map_err(|e| e.in_node(&name))
        }),
    };
    Ok(Planned {
        plan: Some(plan),
        ignored,
        has,
    })
}

/// The shared parameters (set for every node) that no node to be started has: a WARN each
/// names them, as they change nothing.
fn unused_shared(planned: &[Planned]) -> Vec<String> {
    let started: Vec<&Planned> = planned.iter().filter(|p| p.plan.is_some()).collect();
    let mut unused: Vec<String> = planned
        .iter()
        .flat_map(|p| p.ignored.iter())
        .filter(|key| !started.iter().any(|p| (p.has)(key)))
        .cloned()
        .collect();
    unused.sort();
    unused.dedup();
    unused
}

/// Reads and checks the parameters of the nodes to start: `only` one kind, or every kind whose
/// `enabled` is true. Also returns the parameters set for every node that none of them has.
fn plan(args: &RosArgs, only: Option<NodeKind>) -> Result<(Vec<Plan>, Vec<String>), NodeError> {
    if only.is_none() && args.node_name.is_some() {
        return Err(NodeError::Suite(
            "-r __node:=NAME names a single node: use it with --node predictor|forces|projection|prediction \
             (the suite's nodes keep their names cd_predictor, cd_forces, cd_projection, cd_prediction; \
             move them with -r __ns:=/NS)"
                .into(),
        ));
    }
    let kinds: Vec<NodeKind> = match only {
        Some(k) => vec![k],
        None => NodeKind::ALL.to_vec(),
    };
    let mut planned = Vec::new();
    for kind in kinds {
        let name = match only {
            Some(_) => args.node_name_or(kind.default_node_name()).to_string(),
            None => kind.default_node_name().to_string(),
        };
        let alone = only.is_some();
        planned.push(match kind {
            NodeKind::Predictor => plan_kind::<PredictorNode>(args, name, alone)?,
            NodeKind::Forces => plan_kind::<ForcesNode>(args, name, alone)?,
            NodeKind::Projection => plan_kind::<ProjectionNode>(args, name, alone)?,
            NodeKind::Prediction => plan_kind::<PredictionNode>(args, name, alone)?,
        });
    }
    let unused = unused_shared(&planned);
    let plans: Vec<Plan> = planned.into_iter().filter_map(|p| p.plan).collect();
    if plans.is_empty() {
        return Err(NodeError::Suite(
            "no node is enabled (set enabled: true for at least one node)".into(),
        ));
    }
    Ok((plans, unused))
}

/// The participant's network settings, refusing all interfaces outside a loopback-only
/// namespace unless allowed.
fn network(plans: &[Plan]) -> Result<NetworkConfig, NodeError> {
    let first = &plans[0].network;
    for p in &plans[1..] {
        if &p.network != first {
            return Err(NodeError::Suite(format!(
                "network.* differs between {} and {}: one process has one DDS participant; \
                 set network.* in the /** section",
                plans[0].name, p.name
            )));
        }
    }
    let net = NetworkConfig::from_env().and_then(|n| n.with_interfaces_param(&first.interfaces))?;
    let env_allows = std::env::var(ALLOW_EXTERNAL_ENV).is_ok_and(|v| v.trim() == "1");
    network_guard(
        &net,
        first.allow_external || env_allows,
        in_loopback_only_namespace(),
    )
    .map_err(|e| NodeError::Suite(e.to_string()))?;
    Ok(net)
}

/// Starts the nodes (see [`plan`]) on one participant. A node whose automatic configuration
/// fails stays unconfigured while the others run, unless `exit_on_failure` (then its error is
/// returned).
pub fn start(
    args: &RosArgs,
    only: Option<NodeKind>,
    exit_on_failure: bool,
) -> Result<Suite, NodeError> {
    let (plans, unused) = plan(args, only)?;
    for key in unused {
        log::warn!(
            target: "constraint_dynamics_nodes",
            "parameter {key} (from a /** section or -p without a node name) is not a parameter \
             of any node in this process: ignored"
        );
    }
    let net = network(&plans)?;
    let context = net.create_context()?;
    // The nodes with the same joint-state or odometry topic share one reader of it.
    let mut suite = Suite {
        nodes: Vec::new(),
        readers: StateReaders::default(),
        _context: context.clone(),
    };
    for p in plans {
        let node = (p.start)(
            &context,
            args,
            p.name,
            p.ros_params,
            &suite.readers,
            exit_on_failure,
        )?;
        suite.nodes.push(node);
    }
    Ok(suite)
}

#[cfg(test)]
mod tests;
