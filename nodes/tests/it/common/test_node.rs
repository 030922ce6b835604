//! The test's own ROS node (loopback only, in the namespace): service clients and calls,
//! subscriptions read with time limits, the robot's state published as a robot would, and
//! parameters set through a node's `set_parameters` service.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use constraint_dynamics_nodes::msg::RosService;
use constraint_dynamics_nodes::msg::builtin_interfaces::Time;
use constraint_dynamics_nodes::msg::geometry_msgs::Twist;
use constraint_dynamics_nodes::msg::nav_msgs::Odometry;
use constraint_dynamics_nodes::msg::sensor_msgs::JointState;
use constraint_dynamics_nodes::msg::std_msgs::StringMsg;
use constraint_dynamics_nodes::ros::context::{NetworkConfig, RosNode, call_with_retry, qos};
use ros2_client::{Client, NodeOptions, Publisher, Subscription};

use super::WAIT;

/// Runs `fut` on this thread with a time limit.
pub fn block_on_timeout<T>(limit: Duration, fut: impl Future<Output = T>) -> Option<T> {
    smol::block_on(smol::future::or(async { Some(fut.await) }, async {
        smol::Timer::after(limit).await;
        None
    }))
}

/// The test's own ROS node (loopback only, in the namespace).
pub struct TestNode {
    pub node: RosNode,
    pub ctx: ros2_client::Context,
}

impl TestNode {
    pub fn new(name: &str) -> TestNode {
        let net = NetworkConfig::from_env().expect("network config");
        let ctx = net.create_context().expect("context");
        let node =
            RosNode::new(&ctx, "/", name, NodeOptions::new().read_rosout(true)).expect("test node");
        TestNode { node, ctx }
    }

    /// A client of `S` at `name`, once the service is discovered.
    /// On a loaded machine a client's wait can miss the server's discovery for good; a fresh
    /// client (new readers and writers) is discovered again, so it retries every 5 s.
    pub fn client<S: RosService>(&mut self, name: &str) -> Client<S::Request, S::Response> {
        let deadline = Instant::now() + WAIT;
        loop {
            let c = self.node.client::<S>(name).expect("client");
            let per_try =
                Duration::from_secs(5).min(deadline.saturating_duration_since(Instant::now()));
            if block_on_timeout(per_try, c.wait_for_service(&self.node.node)).is_some() {
                return c;
            }
            assert!(
                Instant::now() < deadline,
                "service {name} not discovered within {WAIT:?}"
            );
        }
    }

    /// Subscribes `topic` (reliable).
    pub fn subscribe<M: constraint_dynamics_nodes::msg::RosMessage + 'static>(
        &mut self,
        topic: &str,
    ) -> Subscription<M> {
        self.node
            .subscription::<M>(topic, &qos::reliable(10))
            .expect("subscription")
    }

    /// The rosout reader.
    pub fn rosout(&self) -> &Subscription<ros2_client::Log> {
        self.node
            .node
            .rosout_subscription()
            .expect("rosout reading enabled")
    }
}

/// Calls a service (retrying while discovery settles).
pub fn call<Req, Resp>(client: &Client<Req, Resp>, req: Req) -> Resp
where
    Req: ros2_client::Message + Clone + 'static,
    Resp: ros2_client::Message + 'static,
{
    smol::block_on(call_with_retry(
        client,
        req,
        Duration::from_millis(1500),
        10,
    ))
    .map(|(r, _)| r)
    .unwrap_or_else(|e| panic!("service call: {e}"))
}

/// The first message on `sub` for which `accept` returns true, within `limit`; the last
/// rejected reason on failure.
pub fn take_until<M, F>(sub: &Subscription<M>, limit: Duration, mut accept: F) -> Result<M, String>
where
    M: serde::de::DeserializeOwned + 'static,
    F: FnMut(&M) -> Result<(), String>,
{
    let deadline = Instant::now() + limit;
    let mut last = "no message".to_string();
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(last);
        }
        match block_on_timeout(left, sub.async_take()) {
            None => return Err(format!("timeout; last: {last}")),
            Some(Err(e)) => last = format!("read error {e:?}"),
            Some(Ok((m, _))) => match accept(&m) {
                Ok(()) => return Ok(m),
                Err(why) => last = why,
            },
        }
    }
}

/// What the test publishes as the robot's measured state and command.
#[derive(Clone, Debug, Default)]
pub struct RobotFeed {
    pub joint_state: Option<JointState>,
    pub odom: Option<Odometry>,
    pub cmd_vel: Option<Twist>,
}

/// Publishes the feed at 50 Hz (the latest content of the shared slot) until dropped.
pub struct FeedPublisher {
    pub feed: Arc<Mutex<RobotFeed>>,
    _task: smol::Task<()>,
}

impl FeedPublisher {
    pub fn start(node: &mut TestNode) -> FeedPublisher {
        let js: Publisher<JointState> = node
            .node
            .publisher("/joint_states", &qos::reliable(10))
            .expect("pub");
        let od: Publisher<Odometry> = node
            .node
            .publisher("/odom", &qos::reliable(10))
            .expect("pub");
        let cmd: Publisher<Twist> = node
            .node
            .publisher("/cmd_vel", &qos::reliable(10))
            .expect("pub");
        let feed = Arc::new(Mutex::new(RobotFeed::default()));
        let f = feed.clone();
        let task = node.node.spawn(async move {
            loop {
                let now = Time::now();
                let snapshot = f.lock().unwrap().clone();
                if let Some(mut m) = snapshot.joint_state {
                    m.header.stamp = now;
                    let _ = js.async_publish(m).await;
                }
                if let Some(mut m) = snapshot.odom {
                    m.header.stamp = now;
                    let _ = od.async_publish(m).await;
                }
                if let Some(m) = snapshot.cmd_vel {
                    let _ = cmd.async_publish(m).await;
                }
                smol::Timer::after(Duration::from_millis(20)).await;
            }
        });
        FeedPublisher { feed, _task: task }
    }

    pub fn set(&self, feed: RobotFeed) {
        *self.feed.lock().unwrap() = feed;
    }
}

/// A publisher of `/robot_description` (transient local, as robot_state_publisher).
pub fn description_publisher(node: &mut TestNode) -> Publisher<StringMsg> {
    node.node
        .publisher("/robot_description", &qos::transient_local())
        .expect("robot_description publisher")
}

/// Sets parameter `name` of node `fqn` (`/cd_predictor`) through its `set_parameters`
/// service: (accepted, reason).
pub fn set_param(
    client: &Client<
        ros2_client::rcl_interfaces::SetParametersRequest,
        ros2_client::rcl_interfaces::SetParametersResponse,
    >,
    name: &str,
    value: ros2_client::ParameterValue,
) -> (bool, String) {
    let r = call(
        client,
        ros2_client::rcl_interfaces::SetParametersRequest {
            parameter: vec![ros2_client::parameters::raw::Parameter {
                name: name.into(),
                value: value.into(),
            }],
        },
    );
    let r = r.results.first().expect("one result per parameter");
    (r.successful, r.reason.clone())
}
