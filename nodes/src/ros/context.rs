//! A ros2-client [`Context`] configured the way a ROS user expects, and nodes whose spinner
//! runs on a background thread.
//!
//! - Domain: `ROS_DOMAIN_ID` (0 if unset), as rcl does; ros2-client's `Context::new()` ignores it.
//! - Network interfaces: all (as ROS does) unless restricted by the `ros_interfaces` parameter or
//!   the `CD_ROS_INTERFACES` environment variable: a comma/space-separated list of IP addresses
//!   (`127.0.0.1`, `::1`, `192.168.1.20`) or `localhost`. `ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`
//!   (the kilted way to keep ROS on one machine) restricts to 127.0.0.1 too. The restriction is
//!   `DomainParticipantBuilder::with_only_networks`.
//! - Services use [`ServiceMapping::Enhanced`], the mapping that interoperates with
//!   `rmw_fastrtps_cpp` (rclpy/rclcpp default).
//!
//! Tests and demos still run inside a loopback-only network namespace (`tools/ros2/netns_run.sh`):
//! the namespace is the hard guarantee that no DDS traffic leaves the machine.

use std::net::IpAddr;
use std::sync::Arc;
use std::thread::JoinHandle;

use ros2_client::dds::rustdds::DomainParticipantBuilder;
use ros2_client::qos::{Durability, History, Reliability, WhenFull};
use ros2_client::{
    Client, Context, Name, Node, NodeName, NodeOptions, Publisher, QosProfile, Server,
    ServiceMapping, Subscription,
};

use crate::msg::{RosMessage, RosService};

/// Errors of context and node creation.
#[derive(Debug, thiserror::Error)]
pub enum RosContextError {
    /// `ROS_DOMAIN_ID` is not a number in 0..=232.
    #[error("ROS_DOMAIN_ID={0:?} is not a domain id (0..=232)")]
    BadDomainId(String),
    /// An entry of the interface list is not an IP address.
    #[error("network interface {0:?} is not an IP address (e.g. 127.0.0.1) or 'localhost'")]
    BadInterface(String),
    /// A node, topic or service name that ROS refuses.
    #[error("invalid ROS name {0:?}: {1}")]
    BadName(String, String),
    /// No response to a service call in time.
    #[error("no response from service after {tries} tries of {per_try:?}")]
    Timeout {
        /// Tries made.
        tries: u32,
        /// Time allowed per try.
        per_try: std::time::Duration,
    },
    /// A service call failed.
    #[error("service call: {0}")]
    Call(String),
    /// ros2-client / RustDDS could not create something.
    #[error("ros2-client: {0}")]
    Create(String),
}

/// Where the participant may talk: the DDS domain and the network interfaces.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct NetworkConfig {
    /// DDS domain (`ROS_DOMAIN_ID`).
    pub domain_id: u16,
    /// `None`: all interfaces (ROS's default). `Some(list)`: only these addresses.
    pub interfaces: Option<Vec<IpAddr>>,
}

impl NetworkConfig {
    /// From the environment: `ROS_DOMAIN_ID`, `CD_ROS_INTERFACES`, and
    /// `ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`.
    pub fn from_env() -> Result<Self, RosContextError> {
        Self::from_vars(|k| std::env::var(k).ok())
    }

    /// Like [`Self::from_env`] with a given variable lookup (for tests).
    pub fn from_vars(var: impl Fn(&str) -> Option<String>) -> Result<Self, RosContextError> {
        let domain_id = match var("ROS_DOMAIN_ID").map(|s| s.trim().to_string()) {
            None => 0,
            Some(s) if s.is_empty() => 0,
            Some(s) => match s.parse::<u16>() {
                Ok(d) if d <= 232 => d,
                _ => return Err(RosContextError::BadDomainId(s)),
            },
        };
        let interfaces = match var("CD_ROS_INTERFACES") {
            Some(list) if !list.trim().is_empty() => Some(parse_interfaces(&list)?),
            _ => match var("ROS_AUTOMATIC_DISCOVERY_RANGE") {
                Some(r) if r.trim().eq_ignore_ascii_case("LOCALHOST") => {
                    Some(vec![IpAddr::from([127, 0, 0, 1])])
                }
                _ => None,
            },
        };
        Ok(NetworkConfig {
            domain_id,
            interfaces,
        })
    }

    /// Only loopback (127.0.0.1) on `domain_id`.
    pub fn loopback(domain_id: u16) -> Self {
        NetworkConfig {
            domain_id,
            interfaces: Some(vec![IpAddr::from([127, 0, 0, 1])]),
        }
    }

    /// Overrides the interfaces with a parameter value (same syntax as
    /// `CD_ROS_INTERFACES`; an empty string keeps the current setting).
    pub fn with_interfaces_param(mut self, list: &str) -> Result<Self, RosContextError> {
        if !list.trim().is_empty() {
            self.interfaces = Some(parse_interfaces(list)?);
        }
        Ok(self)
    }

    /// Creates the context (one DDS participant).
    pub fn create_context(&self) -> Result<Context, RosContextError> {
        let mut builder = DomainParticipantBuilder::new(self.domain_id);
        if let Some(ifs) = &self.interfaces {
            builder = builder.with_only_networks(ifs.iter().copied());
        }
        let participant = builder
            .build()
            .map_err(|e| RosContextError::Create(format!("{e:?}")))?;
        Context::from_domain_participant(participant)
            .map_err(|e| RosContextError::Create(format!("{e:?}")))
    }
}

/// Parses `"127.0.0.1, ::1"` / `"localhost"` into addresses.
pub fn parse_interfaces(list: &str) -> Result<Vec<IpAddr>, RosContextError> {
    list.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .map(|s| {
            if s.eq_ignore_ascii_case("localhost") {
                Ok(IpAddr::from([127, 0, 0, 1]))
            } else {
                s.parse::<IpAddr>()
                    .map_err(|_| RosContextError::BadInterface(s.to_string()))
            }
        })
        .collect()
}

/// Whether this process is in a network namespace whose only interface is
/// loopback (read from `/proc/net/dev`, which shows the current namespace).
/// Tests use it to refuse to open a participant anywhere else.
pub fn in_loopback_only_namespace() -> bool {
    match std::fs::read_to_string("/proc/net/dev") {
        Ok(text) => {
            let ifs: Vec<&str> = text
                .lines()
                .skip(2)
                .filter_map(|l| l.split(':').next())
                .map(str::trim)
                .collect();
            ifs == ["lo"]
        }
        Err(_) => false,
    }
}

/// A node plus the background thread that runs its spinner (and any other
/// tasks given to [`RosNode::spawn`]) on a smol executor.
///
/// Dropping it stops the executor and joins the thread; the node is dropped
/// after that.
pub struct RosNode {
    /// The ros2-client node: create publishers, subscriptions, servers on it.
    pub node: Node,
    namespace: String,
    name: String,
    executor: Arc<smol::Executor<'static>>,
    stop: Option<smol::channel::Sender<()>>,
    thread: Option<JoinHandle<()>>,
}

impl RosNode {
    /// Creates node `name` in namespace `namespace` (e.g. `"/"`), starts its
    /// spinner on a new background thread.
    pub fn new(
        context: &Context,
        namespace: &str,
        name: &str,
        options: NodeOptions,
    ) -> Result<Self, RosContextError> {
        let node_name = NodeName::new(namespace, name).map_err(|e| {
            RosContextError::BadName(format!("{namespace}/{name}"), format!("{e:?}"))
        })?;
        let mut node = context
            .new_node(node_name, options)
            .map_err(|e| RosContextError::Create(format!("{e:?}")))?;
        let spinner = node
            .spinner()
            .map_err(|e| RosContextError::Create(format!("{e:?}")))?;
        let executor = Arc::new(smol::Executor::new());
        executor
            .spawn(async move {
                if let Err(e) = spinner.spin().await {
                    log::error!("ROS spinner stopped: {e:?}");
                }
            })
            .detach();
        let (stop, stopped) = smol::channel::bounded::<()>(1);
        let ex = executor.clone();
        let thread = std::thread::Builder::new()
            .name(format!("ros-{name}"))
            .spawn(move || {
                smol::block_on(ex.run(async move {
                    let _ = stopped.recv().await;
                }))
            })
            .map_err(|e| RosContextError::Create(e.to_string()))?;
        Ok(RosNode {
            node,
            namespace: namespace.to_string(),
            name: name.to_string(),
            executor,
            stop: Some(stop),
            thread: Some(thread),
        })
    }

    /// The node's namespace (`/` or `/a/b`).
    pub fn namespace(&self) -> &str {
        &self.namespace
    }

    /// The node's name (without namespace).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// `name` as an absolute ros2-client [`Name`] for this node (see [`topic_name`]).
    pub fn topic_name(&self, name: &str) -> Result<Name, RosContextError> {
        topic_name(&self.namespace, &self.name, name)
    }

    /// Runs a future on the node's background executor (e.g. a service loop).
    /// Dropping the returned task cancels it; `.detach()` it to let it run
    /// until the node is dropped.
    pub fn spawn<F>(&self, future: F) -> smol::Task<F::Output>
    where
        F: std::future::Future + Send + 'static,
        F::Output: Send + 'static,
    {
        self.executor.spawn(future)
    }

    /// A publisher of `M` on `topic` (relative names are in the node's namespace).
    pub fn publisher<M: RosMessage>(
        &mut self,
        topic: &str,
        qos: &QosProfile,
    ) -> Result<Publisher<M>, RosContextError> {
        let t = self
            .node
            .create_topic(&self.topic_name(topic)?, M::type_name(), qos)
            .map_err(|e| RosContextError::Create(format!("{e:?}")))?;
        self.node
            .create_publisher::<M>(&t, None)
            .map_err(|e| RosContextError::Create(format!("{e:?}")))
    }

    /// A subscription to `M` on `topic`.
    pub fn subscription<M: RosMessage + 'static>(
        &mut self,
        topic: &str,
        qos: &QosProfile,
    ) -> Result<Subscription<M>, RosContextError> {
        let t = self
            .node
            .create_topic(&self.topic_name(topic)?, M::type_name(), qos)
            .map_err(|e| RosContextError::Create(format!("{e:?}")))?;
        self.node
            .create_subscription::<M>(&t, None)
            .map_err(|e| RosContextError::Create(format!("{e:?}")))
    }

    /// A server of service `S` named `name`, with the Enhanced mapping and ROS's default
    /// service QoS, but [`qos::service_depth`] waiting requests (ROS's 10 lost some).
    pub fn server<S: RosService>(
        &mut self,
        name: &str,
    ) -> Result<Server<S::Request, S::Response>, RosContextError> {
        self.node
            .create_server::<S::Request, S::Response>(
                ServiceMapping::Enhanced,
                &self.topic_name(name)?,
                &S::type_name(),
                qos::reliable(qos::service_depth(S::NAME)),
                qos::services(),
            )
            .map_err(|e| RosContextError::Create(format!("{e:?}")))
    }

    /// A client of service `S` named `name`, with the Enhanced mapping and ROS's default service
    /// QoS, but [`qos::service_depth`] waiting responses (its reader gets every client's).
    pub fn client<S: RosService>(
        &mut self,
        name: &str,
    ) -> Result<Client<S::Request, S::Response>, RosContextError> {
        self.node
            .create_client::<S::Request, S::Response>(
                ServiceMapping::Enhanced,
                &self.topic_name(name)?,
                &S::type_name(),
                qos::services(),
                qos::reliable(qos::service_depth(S::NAME)),
            )
            .map_err(|e| RosContextError::Create(format!("{e:?}")))
    }
}

impl Drop for RosNode {
    fn drop(&mut self) {
        if let Some(stop) = self.stop.take() {
            let _ = stop.try_send(());
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// A ros2-client [`Name`] for topic/service `name` of node `node_name` in
/// `namespace`: relative (`odom`), private (`~/odom`) and absolute (`/odom`)
/// names are expanded to an absolute name first, as rcl does.
///
/// (ros2-client itself turns a relative name of a node in the root namespace
/// into the DDS topic `rt//odom`, which no ROS peer matches; always handing it
/// absolute names avoids that.) Apply remappings before calling this, with
/// [`RosArgs::resolve_topic`](crate::ros::args::RosArgs::resolve_topic).
pub fn topic_name(namespace: &str, node_name: &str, name: &str) -> Result<Name, RosContextError> {
    let full = crate::ros::args::expand_name(namespace, node_name, name);
    Name::parse(&full).map_err(|e| RosContextError::BadName(full.clone(), format!("{e:?}")))
}

/// Calls a service, sending the request again if no response came within
/// `per_try`, up to `tries` times. Returns the response and the number of
/// tries used.
///
/// Why: `Client::wait_for_service` sees the match from the client's side only.
/// A request sent right after it can race the server's discovery of the client
/// (the server's response writer not yet matched to the client's response
/// reader, so the response is lost). Only for requests that are safe to repeat.
pub async fn call_with_retry<Req, Resp>(
    client: &Client<Req, Resp>,
    request: Req,
    per_try: std::time::Duration,
    tries: u32,
) -> Result<(Resp, u32), RosContextError>
where
    Req: ros2_client::Message + Clone + 'static,
    Resp: ros2_client::Message + 'static,
{
    for attempt in 1..=tries {
        let call = async { Some(client.async_call_service(request.clone()).await) };
        let timeout = async {
            smol::Timer::after(per_try).await;
            None
        };
        match smol::future::or(call, timeout).await {
            Some(Ok(resp)) => return Ok((resp, attempt)),
            Some(Err(e)) => return Err(RosContextError::Call(format!("{e:?}"))),
            None => {
                log::debug!("service call: no response in {per_try:?} (try {attempt} of {tries})")
            }
        }
    }
    Err(RosContextError::Timeout { tries, per_try })
}

/// QoS profiles matching rclcpp/rclpy's named profiles.
pub mod qos {
    use super::*;

    /// rclcpp `SystemDefaultsQoS`/`QoS(depth)`: reliable, volatile, keep last `depth`.
    /// Matches rclpy's default subscriber (odometry, paths, forces).
    pub fn reliable(depth: usize) -> QosProfile {
        QosProfile::publisher_default()
            .reliability_reliable(WhenFull::DEFAULT)
            .durability(Durability::Volatile)
            .history(History::KeepLast { depth })
    }

    /// `rmw_qos_profile_sensor_data`: best effort, volatile, keep last 5.
    pub fn sensor_data() -> QosProfile {
        QosProfile::publisher_default()
            .reliability(Reliability::BestEffort)
            .durability(Durability::Volatile)
            .history(History::KeepLast { depth: 5 })
    }

    /// Latched (e.g. `/robot_description`): reliable, transient local, keep last 1.
    pub fn transient_local() -> QosProfile {
        reliable(1).durability(Durability::TransientLocal)
    }

    /// Requests a server's reader (responses a client's) keep until taken, as deep as a worker's
    /// queue. The cache also keeps that many taken: `Predict` (0.5 MB messages) keeps ROS's 10.
    pub const SERVER_REQUEST_DEPTH: usize = 1024;
    /// The history depth of service `name`'s request (server) and response (client) readers.
    pub fn service_depth(name: &str) -> usize {
        match name {
            "Predict" | "Rollouts" => 10, // MB replies, never pipelined faster than taken
            _ => SERVER_REQUEST_DEPTH,
        }
    }

    /// `rmw_qos_profile_services_default`: reliable, volatile, keep last 10.
    pub fn services() -> QosProfile {
        reliable(10)
    }
}

#[cfg(test)]
#[path = "context_tests.rs"]
mod tests;
