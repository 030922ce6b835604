//! Recorded ROS 2 logs: rosbag2 bags in MCAP storage with CDR messages, as Jazzy and later
//! record them — a single `.mcap` file, or a bag directory whose `metadata.yaml` lists its
//! files — read into the core's [`Recording`] (docs/logs.md).
//!
//! The MCAP container is the `mcap` crate's (zstd and lz4 chunks), the CDR decoding
//! `cdr-encoding`'s into the message structs of [`crate::msg`]. Samples are timed by their
//! header stamps; an unstamped `geometry_msgs/Twist` by the bag's log time, which must then be
//! on the stamps' clock ([`BagError::Clock`]).

mod decode;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use constraint_dynamics::replay::{Recording, Series, show_stamp};
use mcap::sans_io::{LinearReaderOptions, MessageReadEvent, MessageReader};
use serde::Deserialize;

use decode::{Decoded, decode};
pub use decode::{Kind, cdr, odometry_sample};

/// The topics a recording is read from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BagTopics {
    /// `nav_msgs/Odometry`: the start states' base.
    pub odom: String,
    /// `sensor_msgs/JointState`: the start states' joints.
    pub joint_states: String,
    /// `geometry_msgs/Twist` or `TwistStamped`: the base commands.
    pub cmd_vel: String,
    /// `nav_msgs/Odometry` the predictions are scored against; None: `odom` itself.
    pub reference: Option<String>,
}

impl Default for BagTopics {
    fn default() -> Self {
        BagTopics {
            odom: "/odom".into(),
            joint_states: "/joint_states".into(),
            cmd_vel: "/cmd_vel".into(),
            reference: None,
        }
    }
}

/// Why a bag cannot be read. Each names the file, and the topic and time where there is one.
#[derive(Debug, thiserror::Error)]
pub enum BagError {
    /// A file cannot be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The reason.
        source: std::io::Error,
    },
    /// A bag directory's `metadata.yaml` is missing or unusable.
    #[error("{path}: {message}")]
    Metadata {
        /// The metadata file (or the directory).
        path: String,
        /// What is wrong.
        message: String,
    },
    /// The MCAP container is truncated or corrupt.
    #[error("{path}: truncated or corrupt after {messages} messages{last}: {message}")]
    Corrupt {
        /// The file.
        path: String,
        /// Messages read before the fault.
        messages: usize,
        /// ", the last logged at …" when there was one.
        last: String,
        /// The MCAP reader's reason.
        message: String,
    },
    /// A topic the replay needs is not in the bag.
    #[error("{path}: no {what} topic '{topic}' (the bag has: {available})")]
    MissingTopic {
        /// The bag.
        path: String,
        /// What it is for, e.g. "odometry".
        what: String,
        /// The topic asked for.
        topic: String,
        /// The bag's topics and types.
        available: String,
    },
    /// A topic has a type the reader does not take for it.
    #[error("{path}: topic '{topic}' is {found}; expected {expected}")]
    WrongType {
        /// The bag.
        path: String,
        /// The topic.
        topic: String,
        /// Its schema name (and encoding).
        found: String,
        /// What the reader takes.
        expected: String,
    },
    /// A message cannot be decoded.
    #[error("{path}: topic '{topic}', message logged at {stamp}: {message}")]
    Decode {
        /// The file.
        path: String,
        /// The topic.
        topic: String,
        /// Its log time (`sec.nanosec`).
        stamp: String,
        /// The decoder's reason.
        message: String,
    },
    /// Unstamped commands timed by log times on another clock than the stamps.
    #[error(
        "{path}: '{commands}' is geometry_msgs/msg/Twist (no stamp) and is timed by the bag's \
         log time, but '{odom}' has stamps {offset_s:.3} s from its log times (another clock, \
         e.g. simulated time): record geometry_msgs/msg/TwistStamped commands"
    )]
    Clock {
        /// The bag.
        path: String,
        /// The command topic.
        commands: String,
        /// The odometry topic.
        odom: String,
        /// Its stamp − log time at its first message [s].
        offset_s: f64,
    },
}

#[derive(Deserialize)]
struct MetadataFile {
    rosbag2_bagfile_information: BagInfo,
}

#[derive(Deserialize)]
struct BagInfo {
    storage_identifier: String,
    relative_file_paths: Vec<String>,
    #[serde(default)]
    compression_format: String,
}

/// The MCAP files of a bag: `path` itself, or the files a bag directory's metadata.yaml lists.
pub fn bag_files(path: &Path) -> Result<Vec<PathBuf>, BagError> {
    if !path.is_dir() {
        return Ok(vec![path.to_path_buf()]);
    }
    let meta = path.join("metadata.yaml");
    let shown = meta.display().to_string();
    let text = std::fs::read_to_string(&meta).map_err(|source| BagError::Io {
        path: shown.clone(),
        source,
    })?;
    let err = |message: String| BagError::Metadata {
        path: shown.clone(),
        message,
    };
    let file: MetadataFile = serde_yaml::from_str(&text).map_err(|e| err(e.to_string()))?;
    let info = file.rosbag2_bagfile_information;
    if info.storage_identifier != "mcap" {
        return Err(err(format!(
            "storage '{}': only mcap bags are read (convert with `ros2 bag convert`)",
            info.storage_identifier
        )));
    }
    if !info.compression_format.is_empty() {
        return Err(err(format!(
            "file compression '{}': only uncompressed files are read (MCAP's own chunk \
             compression is)",
            info.compression_format
        )));
    }
    if info.relative_file_paths.is_empty() {
        return Err(err("relative_file_paths lists no file".into()));
    }
    Ok((info.relative_file_paths.iter())
        .map(|f| path.join(f))
        .collect())
}

/// What one topic becomes.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Role {
    Odometry,
    JointStates,
    Commands,
    Reference,
}

/// Reads the recording of `topics` from the bag at `path` (an `.mcap` file or a bag directory).
pub fn read_recording(path: &Path, topics: &BagTopics) -> Result<Recording, BagError> {
    let shown = path.display().to_string();
    let reference = topics.reference.as_deref().unwrap_or(&topics.odom);
    let wanted = [
        (Role::Odometry, topics.odom.as_str(), "odometry"),
        (
            Role::JointStates,
            topics.joint_states.as_str(),
            "joint-state",
        ),
        (Role::Commands, topics.cmd_vel.as_str(), "command"),
        (Role::Reference, reference, "reference odometry"),
    ];
    let mut rec = Recording {
        odometry: Series::new(&topics.odom),
        joint_states: Series::new(&topics.joint_states),
        commands: Series::new(&topics.cmd_vel),
        reference: Series::new(reference),
    };
    // Every topic seen: name → type, for the errors.
    let mut seen: BTreeMap<String, String> = BTreeMap::new();
    let mut unstamped_commands = false;
    let mut odom_clock_offset: Option<i64> = None;
    for file in bag_files(path)? {
        let fshown = file.display().to_string();
        let bytes = std::fs::read(&file).map_err(|source| BagError::Io {
            path: fshown.clone(),
            source,
        })?;
        let corrupt = |messages: usize, last: Option<u64>, e: mcap::McapError| BagError::Corrupt {
            path: fshown.clone(),
            messages,
            last: last.map_or(String::new(), |t| {
                format!(", the last logged at {}", show_stamp(t as i64))
            }),
            message: e.to_string(),
        };
        let (mut count, mut last) = (0usize, None);
        for m in messages(&bytes) {
            let m = m.map_err(|e| corrupt(count, last, e))?;
            count += 1;
            last = Some(m.log_time);
            let topic = &m.channel.topic;
            let schema = m.channel.schema.as_ref().map_or("", |s| s.name.as_str());
            seen.entry(topic.clone())
                .or_insert_with(|| schema.to_string());
            for (role, name, _) in wanted {
                if topic != name {
                    continue;
                }
                let kind = kind_of(role, schema, &m.channel.message_encoding).ok_or_else(|| {
                    BagError::WrongType {
                        path: shown.clone(),
                        topic: topic.clone(),
                        found: format!("{schema} ({})", m.channel.message_encoding),
                        expected: expected(role),
                    }
                })?;
                let log_time = m.log_time.min(i64::MAX as u64) as i64;
                let decoded =
                    decode(kind, &m.data, log_time).map_err(|message| BagError::Decode {
                        path: fshown.clone(),
                        topic: topic.clone(),
                        stamp: show_stamp(log_time),
                        message,
                    })?;
                match (role, decoded) {
                    (Role::Odometry, Decoded::Odometry(t, o)) => {
                        odom_clock_offset.get_or_insert(t - log_time);
                        rec.odometry.samples.push((t, *o));
                    }
                    (Role::Reference, Decoded::Odometry(t, o)) => {
                        rec.reference.samples.push((t, *o))
                    }
                    (Role::JointStates, Decoded::JointStates(t, j)) => {
                        rec.joint_states.samples.push((t, j))
                    }
                    (Role::Commands, Decoded::Command(t, c)) => {
                        unstamped_commands |= kind == Kind::Twist;
                        rec.commands.samples.push((t, c));
                    }
                    _ => unreachable!("kind_of gives each role its kinds"),
                }
            }
        }
    }
    for (role, name, what) in wanted {
        let empty = match role {
            Role::Odometry => rec.odometry.samples.is_empty(),
            Role::JointStates => rec.joint_states.samples.is_empty(),
            Role::Commands => rec.commands.samples.is_empty(),
            Role::Reference => rec.reference.samples.is_empty(),
        };
        if empty {
            let available: Vec<String> = seen.iter().map(|(t, s)| format!("{t} [{s}]")).collect();
            return Err(BagError::MissingTopic {
                path: shown,
                what: what.into(),
                topic: name.into(),
                available: available.join(", "),
            });
        }
    }
    // Half a second is the node's command timeout: a larger offset misplaces every command.
    if let Some(offset) = odom_clock_offset.filter(|o| unstamped_commands && o.abs() > 500_000_000)
    {
        return Err(BagError::Clock {
            path: shown,
            commands: topics.cmd_vel.clone(),
            odom: topics.odom.clone(),
            offset_s: offset as f64 * 1e-9,
        });
    }
    Ok(rec)
}

/// The longest record or chunk a file of `len` bytes may hold: 64 × its length (a chunk's
/// compression rarely reaches 10×), at most 1 GiB, so that a damaged length field is an error
/// and not an allocation of petabytes.
fn record_limit(len: usize) -> usize {
    len.saturating_mul(64).saturating_add(1 << 20).min(1 << 30)
}

/// The messages of one MCAP file in file order, chunk CRCs checked, every record and chunk
/// bounded by [`record_limit`]. (`mcap::MessageStream` decompresses chunks without a bound: a
/// flipped length byte aborted the process on an allocation of 3·10¹⁶ bytes.)
fn messages(bytes: &[u8]) -> impl Iterator<Item = mcap::McapResult<mcap::Message<'static>>> + '_ {
    let options = LinearReaderOptions::default()
        .with_record_length_limit(record_limit(bytes.len()))
        .with_validate_chunk_crcs(true);
    let mut reader = MessageReader::new_with_options(options);
    let mut rest = bytes;
    std::iter::from_fn(move || {
        loop {
            match reader.next_event()? {
                Ok(MessageReadEvent::ReadRequest(need)) => {
                    let n = need.min(rest.len());
                    reader.insert(n).copy_from_slice(&rest[..n]);
                    reader.notify_read(n);
                    rest = &rest[n..];
                }
                Ok(MessageReadEvent::Message(m)) => return Some(Ok(m)),
                Err(e) => return Some(Err(e)),
            }
        }
    })
}

/// The message kind a topic of `role` with this schema and encoding is read as.
fn kind_of(role: Role, schema: &str, encoding: &str) -> Option<Kind> {
    let kinds: &[Kind] = match role {
        Role::Odometry | Role::Reference => &[Kind::Odometry],
        Role::JointStates => &[Kind::JointState],
        Role::Commands => &[Kind::Twist, Kind::TwistStamped],
    };
    (encoding == "cdr")
        .then(|| kinds.iter().copied().find(|k| k.schema() == schema))
        .flatten()
}

fn expected(role: Role) -> String {
    let kinds = match role {
        Role::Odometry | Role::Reference => "nav_msgs/msg/Odometry",
        Role::JointStates => "sensor_msgs/msg/JointState",
        Role::Commands => "geometry_msgs/msg/Twist or geometry_msgs/msg/TwistStamped",
    };
    format!("{kinds} (cdr)")
}
