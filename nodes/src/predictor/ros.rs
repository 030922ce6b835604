//! `cd_predictor` on ROS: the command subscription (following the type published on its
//! topic), the predicted odometry, path, forces, rviz2 markers and per-constraint wrenches.

use std::collections::HashMap;

use ros2_client::Gid;
use ros2_client::dds::rustdds::{DomainParticipant, GUID, RTPSEntity};

use super::markers::topic_token;
use super::{PredictorInput, PredictorNode};
use crate::error::NodeError;
use crate::msg::constraint_dynamics_msgs::{AccelerationLimits, ConstraintForces};
use crate::msg::diagnostic_msgs::DiagnosticArray;
use crate::msg::geometry_msgs::{Twist, TwistStamped, WrenchStamped};
use crate::msg::nav_msgs::{Odometry, Path};
use crate::msg::visualization_msgs::MarkerArray;
use crate::node::wiring::{Followed, RosWiring, Wiring, forward};
use crate::node::worker::Event;
use crate::params::CommandMsg;
use crate::ros::context::qos;
use crate::ros::logging::NodeLog;

/// Takes commands from the writers that announce type `want` only, handing each to `f`.
///
/// Why: RustDDS matches a reader with every writer on its topic whatever its type (Fast DDS and
/// Cyclone compare type names), so a `Twist` reader would decode the bytes of a RustDDS
/// `TwistStamped` publisher as a wrong but finite `Twist`. Each writer's announced type is
/// looked up once in discovery; messages of other types are dropped with one warning per writer.
/// Writers of this process (the suite's command filter) are not in discovery: they are trusted
/// to publish the type their node is configured with.
async fn typed_commands<M: serde::de::DeserializeOwned + 'static>(
    sub: ros2_client::Subscription<M>,
    participant: DomainParticipant,
    want: CommandMsg,
    log: NodeLog,
    mut f: impl FnMut(M),
) {
    let mut verdicts: HashMap<Gid, bool> = HashMap::new();
    let own_prefix = participant.guid().prefix;
    let mut errors = 0u64;
    loop {
        let (m, info) = match sub.async_take().await {
            Ok(x) => x,
            Err(e) => {
                errors += 1;
                if errors == 1 || errors.is_power_of_two() {
                    log.warn(&format!(
                        "dropped an undecodable command ({errors} so far): {e:?}"
                    ));
                }
                smol::Timer::after(std::time::Duration::from_millis(1)).await;
                continue;
            }
        };
        let gid = info.publisher_gid();
        let ok = match verdicts.get(&gid) {
            Some(&ok) => ok,
            None => {
                let announced = participant
                    .discovered_writers()
                    .into_iter()
                    .map(|d| d.publication_topic_data)
                    .find(|t| Gid::from(t.key) == gid)
                    .map(|t| t.type_name);
                let Some(announced) = announced else {
                    // Discovery lists other participants' writers only. One of this process
                    // (a command filter of the suite) publishes the type it is configured
                    // with: trusted. Another not discovered yet: drop, ask on the next.
                    if GUID::from(gid).prefix == own_prefix {
                        verdicts.insert(gid, true);
                        f(m);
                    }
                    continue;
                };
                let ok = announced == want.dds_type();
                if !ok {
                    log.warn(&format!(
                        "command input: ignoring a publisher of {announced} while following {}",
                        want.ros_type()
                    ));
                }
                verdicts.insert(gid, ok);
                ok
            }
        };
        if ok {
            f(m);
        }
    }
}

/// One of the predictor's per-tick outputs: its publisher and its topic's DDS name.
struct Output<M: serde::Serialize> {
    publisher: ros2_client::Publisher<M>,
    dds_topic: String,
}

impl<M: crate::msg::RosMessage + std::fmt::Debug> Output<M> {
    fn new(w: &mut Wiring<PredictorNode>, topic: &str) -> Result<Self, NodeError> {
        let topic = (w.topic)(topic);
        Ok(Output {
            publisher: w.ros.publisher::<M>(&topic, &qos::reliable(10))?,
            dds_topic: format!("rt{topic}"),
        })
    }

    /// Publishes `msg` if the topic has a subscriber: serializing and handing to DDS a
    /// message nobody reads is the larger part of publishing it.
    async fn publish(&self, readers: &Readers, msg: M, log: &NodeLog) {
        if !readers.topics.contains(&self.dds_topic) {
            return;
        }
        if let Err(e) = self.publisher.async_publish(msg).await {
            log.warn(&format!("publish {}: {e:?}", &self.dds_topic[2..]));
        }
    }
}

/// How often [`Readers`] looks at discovery: a copy of every discovered reader costs about
/// 0.14 M instructions with one rclpy peer (and grows with the graph), half the instructions
/// the publishing task spends on a tick's outputs.
const READERS_PERIOD: std::time::Duration = std::time::Duration::from_secs(1);

/// The topics other participants subscribe to (DDS names), looked up in discovery at most
/// every [`READERS_PERIOD`]: a new subscriber misses at most that on top of what it misses
/// before its reader is matched (the topics are volatile).
struct Readers {
    participant: DomainParticipant,
    checked: Option<std::time::Instant>,
    topics: std::collections::HashSet<String>,
}

impl Readers {
    fn refresh(&mut self) {
        let now = std::time::Instant::now();
        if self
            .checked
            .is_some_and(|t| now.duration_since(t) < READERS_PERIOD)
        {
            return;
        }
        self.checked = Some(now);
        self.topics = (self.participant.discovered_readers().into_iter())
            .map(|r| r.subscription_topic_data.topic_name)
            .collect();
    }
}

impl RosWiring for PredictorNode {
    fn wire(w: &mut Wiring<Self>) -> Result<(), NodeError> {
        let p = w.params.node.clone();
        let odom_pub = Output::<Odometry>::new(w, "~/predicted_odom")?;
        let path_pub = match p.publish_path {
            true => Some(Output::<Path>::new(w, "~/predicted_path")?),
            false => None,
        };
        let forces_pub = match p.publish_forces {
            true => Some(Output::<ConstraintForces>::new(w, "~/constraint_forces")?),
            false => None,
        };
        let markers_pub = match p.markers.enabled {
            true => Some(Output::<MarkerArray>::new(w, "~/markers")?),
            false => None,
        };
        let mut wrench_pubs = HashMap::new();
        if p.markers.wrenches {
            let constraints = w.constraints;
            for name in constraints {
                let topic = format!("~/wrench/{}", topic_token(name));
                wrench_pubs.insert(name.clone(), Output::<WrenchStamped>::new(w, &topic)?);
            }
        }
        let limits_pub = match p.envelope.enabled {
            true => Some(Output::<AccelerationLimits>::new(
                w,
                "~/acceleration_limits",
            )?),
            false => None,
        };
        let residuals_pub = match p.monitor.enabled {
            true => Some(Output::<DiagnosticArray>::new(w, "~/prediction_residuals")?),
            false => None,
        };
        let bridge = match p.envelope.velocity_smoother.is_empty() {
            true => None,
            false => {
                let (tx, task) =
                    super::smoother_ros::start(w.ros, w.topic, &p.envelope, w.log.clone())?;
                w.tasks.push(task);
                Some(tx)
            }
        };
        let log = w.log.clone();
        let mut readers = Readers {
            participant: w.context.domain_participant(),
            checked: None,
            topics: Default::default(),
        };
        // The envelope is wanted at every tick by the bridge or a subscriber of the limits;
        // the predictor starts out computing it.
        let tx = w.tx.clone();
        let mut limits_wanted = true;
        let Some(out_rx) = w.outputs.take() else {
            return Ok(());
        };
        w.tasks.push(w.ros.spawn(async move {
            while let Ok(out) = out_rx.recv().await {
                let out = *out;
                readers.refresh();
                if let Some(l) = &limits_pub {
                    let wanted = bridge.is_some() || readers.topics.contains(&l.dds_topic);
                    let told = || Event::Node(PredictorInput::LimitsWanted(wanted));
                    if wanted != limits_wanted && tx.try_send(told()).is_ok() {
                        limits_wanted = wanted;
                    }
                }
                odom_pub.publish(&readers, out.odom, &log).await;
                if let Some(p) = &path_pub {
                    p.publish(&readers, out.path, &log).await;
                }
                if let Some(p) = &forces_pub {
                    p.publish(&readers, out.forces, &log).await;
                }
                if let (Some(p), Some(m)) = (&markers_pub, out.markers) {
                    p.publish(&readers, m, &log).await;
                }
                if let (Some(tx), Some(m)) = (&bridge, &out.limits) {
                    super::smoother_ros::offer(tx, (m.clone(), out.forward_speed));
                }
                if let (Some(p), Some(m)) = (&limits_pub, out.limits) {
                    p.publish(&readers, m, &log).await;
                }
                if let (Some(p), Some(m)) = (&residuals_pub, out.residuals) {
                    p.publish(&readers, m, &log).await;
                }
                for (name, msg) in out.wrenches {
                    if let Some(p) = wrench_pubs.get(&name) {
                        p.publish(&readers, msg, &log).await;
                    }
                }
            }
        }));
        Ok(())
    }

    /// The command input: a subscription of the type `command.type` forces, or of the type the
    /// topic's publishers use (their DDS type names, from discovery), replaced when that
    /// changes.
    fn follow_graph(w: &mut Wiring<Self>, slot: &mut Option<Followed>) -> Result<(), NodeError> {
        let p = &w.params.node.command;
        let topic = (w.topic)(&p.topic);
        let forced = p.forced_type()?;
        let published: Vec<String> = match forced {
            Some(_) => Vec::new(),
            None => {
                let dds_topic = format!("rt{topic}");
                w.context
                    .domain_participant()
                    .discovered_writers()
                    .into_iter()
                    .map(|d| d.publication_topic_data)
                    .filter(|t| t.topic_name == dds_topic)
                    .map(|t| t.type_name)
                    .collect()
            }
        };
        let current = slot.as_ref().map(|f| match f.key.as_str() {
            k if k == CommandMsg::Twist.ros_type() => CommandMsg::Twist,
            _ => CommandMsg::TwistStamped,
        });
        let want = CommandMsg::follow(forced, &published, current);
        if current == Some(want) {
            return Ok(());
        }
        // The old subscription goes first, so the topic never has two types of ours.
        *slot = None;
        let tx = w.tx.clone();
        let log = w.log.clone();
        let participant = w.context.domain_participant();
        let task = match want {
            CommandMsg::TwistStamped => {
                let sub = w
                    .ros
                    .subscription::<TwistStamped>(&topic, &qos::sensor_data())?;
                w.ros
                    .spawn(typed_commands(sub, participant, want, log, move |m| {
                        forward(&tx, Event::Node(PredictorInput::Command(m.twist)))
                    }))
            }
            CommandMsg::Twist => {
                let sub = w.ros.subscription::<Twist>(&topic, &qos::sensor_data())?;
                w.ros
                    .spawn(typed_commands(sub, participant, want, log, move |m| {
                        forward(&tx, Event::Node(PredictorInput::Command(m)))
                    }))
            }
        };
        let why = match (forced, published.is_empty()) {
            (Some(_), _) => "command.type".to_string(),
            (None, true) => "nobody publishes it yet".to_string(),
            (None, false) => format!("published as {}", published.join(", ")),
        };
        w.log.info(&format!(
            "command input {topic}: {} ({why})",
            want.ros_type()
        ));
        *slot = Some(Followed {
            key: want.ros_type().to_string(),
            task,
        });
        Ok(())
    }
}
