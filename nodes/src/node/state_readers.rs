//! The state inputs (`joint_states`, `odom`) of the nodes in one process: one DDS reader per
//! topic, shared by every node that subscribes to the same resolved name (the QoS is sensor
//! data for all), which decodes each message once and puts it in each node's [`Inbox`].
//!
//! A worker takes what its inbox holds whenever it runs (a request, a tick, a status, any
//! event) and applies it in arrival order, so a node that only answers requests is not woken
//! by each message. It is woken for its inbox only when the inbox holds [`BATCH`] messages
//! (the queue stays bounded while nothing else wakes it), when an input arrives after a
//! silence longer than `diagnostics.input_timeout` (its status turns fresh at once), and for
//! every message under `use_sim_time`: the arrival is then stamped with the node's ROS clock,
//! which only its worker knows.
//!
//! The reader is created on the ROS node that joins first and runs on its executor; it stays
//! while any node is joined (the node that created it may be cleaned up before the others: its
//! ROS node and executor live until the process stops its nodes) and is removed when the last
//! one leaves.

use std::collections::{HashMap, VecDeque};
use std::sync::{Arc, Mutex, MutexGuard, Weak};
use std::time::{Duration, Instant};

use ros2_client::gid::Gid;

use crate::error::NodeError;
use crate::msg::builtin_interfaces::Time;
use crate::msg::nav_msgs::Odometry;
use crate::msg::sensor_msgs::JointState;

/// An inbox holding this many messages wakes its worker (at 2 × 20 Hz about every 1.6 s).
pub const BATCH: usize = 64;

/// Messages an inbox holds at most; more arriving while the worker is busy are dropped until it
/// takes them (the state it then applies is only as fresh as the last one kept). 1024 holds
/// 25 s of joint states and odometry at 20 Hz each, 5 s at 100 Hz.
pub const CAPACITY: usize = 1024;

/// One state message, decoded once and shared by the nodes that read it.
#[derive(Clone)]
pub enum StateMsg {
    /// `joint_states`.
    JointState(Arc<JointState>),
    /// `odom`.
    Odometry(Arc<Odometry>),
}

impl StateMsg {
    fn input(&self) -> usize {
        match self {
            StateMsg::JointState(_) => 0,
            StateMsg::Odometry(_) => 1,
        }
    }
}

/// The state messages that reached one node since its worker last took them, each with its
/// arrival time (wall clock).
pub struct Inbox {
    pending: Mutex<Pending>,
    batch: usize,
    silence: Duration,
}

#[derive(Default)]
struct Pending {
    messages: VecDeque<(Time, StateMsg)>,
    /// Last arrival per input (joint states, odometry).
    last: [Option<Instant>; 2],
    /// How often the worker was woken for its inbox, and how many messages arrived.
    wakes: u64,
    arrived: u64,
}

impl Inbox {
    /// An inbox that wakes its worker every `batch` messages or after `silence` without an
    /// input.
    pub fn new(batch: usize, silence: Duration) -> Arc<Inbox> {
        Arc::new(Inbox {
            pending: Mutex::new(Pending::default()),
            batch: batch.max(1),
            silence,
        })
    }

    fn lock(&self) -> MutexGuard<'_, Pending> {
        self.pending.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Holds a message that arrived at `arrived` (`now` on the monotonic clock); true when its
    /// worker should be woken.
    fn push(&self, message: StateMsg, arrived: Time, now: Instant) -> bool {
        let mut p = self.lock();
        let input = message.input();
        let after_silence = p.last[input].is_none_or(|t| now - t > self.silence);
        p.last[input] = Some(now);
        p.arrived += 1;
        if p.messages.len() >= CAPACITY {
            return false;
        }
        p.messages.push_back((arrived, message));
        let wake = after_silence || p.messages.len() == self.batch;
        p.wakes += u64::from(wake);
        wake
    }

    /// Moves the held messages, oldest first, to the end of `into`.
    pub fn take(&self, into: &mut VecDeque<(Time, StateMsg)>) {
        into.extend(self.lock().messages.drain(..));
    }

    /// (messages arrived, times the worker was woken for them).
    pub fn counts(&self) -> (u64, u64) {
        let p = self.lock();
        (p.arrived, p.wakes)
    }
}

/// A node joined to a topic: its inbox and how to wake its worker.
struct Member {
    id: u64,
    inbox: Arc<Inbox>,
    wake: Box<dyn Fn() + Send + Sync>,
}

/// Hands each message of one reader to the nodes joined to its topic.
#[derive(Clone)]
pub struct Fanout(Arc<Mutex<Vec<Member>>>);

impl Fanout {
    /// Puts `message` in every joined node's inbox, waking the workers that should run.
    pub fn send(&self, message: StateMsg) {
        let (arrived, now) = (Time::now(), Instant::now());
        let members = self.0.lock().unwrap_or_else(|p| p.into_inner());
        for m in members.iter() {
            if m.inbox.push(message.clone(), arrived, now) {
                (m.wake)();
            }
        }
    }
}

/// One shared reader: the task that owns it, its GUID and the nodes it feeds.
struct Reader {
    fanout: Fanout,
    gid: Gid,
    _task: smol::Task<()>,
}

type Readers = HashMap<String, Reader>;

/// The process's shared state readers, by resolved topic name. Cloning shares them.
#[derive(Clone, Default)]
pub struct StateReaders {
    readers: Arc<Mutex<Readers>>,
    next_id: Arc<std::sync::atomic::AtomicU64>,
}

impl StateReaders {
    fn lock(&self) -> MutexGuard<'_, Readers> {
        self.readers.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Joins `inbox` to `topic` (resolved name): its worker is woken by `wake`. The first node
    /// to join creates the reader with `create`, which spawns a task reading the topic into
    /// the [`Fanout`] it is given and returns it with the reader's GUID. Dropping the returned
    /// [`Joined`] leaves the topic.
    pub fn join(
        &self,
        topic: &str,
        inbox: Arc<Inbox>,
        wake: Box<dyn Fn() + Send + Sync>,
        create: impl FnOnce(Fanout) -> Result<(smol::Task<()>, Gid), NodeError>,
    ) -> Result<Joined, NodeError> {
        let id = (self.next_id).fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let member = Member { id, inbox, wake };
        let mut readers = self.lock();
        let gid = match readers.get(topic) {
            Some(r) => {
                (r.fanout.0.lock().unwrap_or_else(|p| p.into_inner())).push(member);
                r.gid
            }
            None => {
                let fanout = Fanout(Arc::new(Mutex::new(vec![member])));
                let (task, gid) = create(fanout.clone())?;
                readers.insert(
                    topic.to_string(),
                    Reader {
                        fanout,
                        gid,
                        _task: task,
                    },
                );
                gid
            }
        };
        Ok(Joined {
            readers: Arc::downgrade(&self.readers),
            topic: topic.to_string(),
            id,
            gid,
        })
    }

    /// The topics read, and how many nodes each feeds.
    pub fn topics(&self) -> Vec<(String, usize)> {
        let mut t: Vec<(String, usize)> = (self.lock().iter())
            .map(|(name, r)| (name.clone(), r.fanout.0.lock().map_or(0, |m| m.len())))
            .collect();
        t.sort();
        t
    }
}

/// A node's membership of one shared reader; dropping it leaves, and the last to leave
/// removes the reader.
pub struct Joined {
    readers: Weak<Mutex<Readers>>,
    topic: String,
    id: u64,
    gid: Gid,
}

impl Joined {
    /// The shared reader's GUID, for the joining node to list as its own reader in the ROS
    /// graph (`ros2 node info` shows every node's state subscriptions, whichever created it).
    pub fn reader_gid(&self) -> Gid {
        self.gid
    }
}

impl Drop for Joined {
    fn drop(&mut self) {
        let Some(readers) = self.readers.upgrade() else {
            return;
        };
        let mut readers = readers.lock().unwrap_or_else(|p| p.into_inner());
        let Some(r) = readers.get(&self.topic) else {
            return;
        };
        let empty = {
            let mut members = r.fanout.0.lock().unwrap_or_else(|p| p.into_inner());
            members.retain(|m| m.id != self.id);
            members.is_empty()
        };
        if empty {
            // Dropping the task drops the reader with it.
            let removed = readers.remove(&self.topic);
            drop(readers);
            drop(removed);
        }
    }
}

#[cfg(test)]
#[path = "state_readers_tests.rs"]
mod tests;
