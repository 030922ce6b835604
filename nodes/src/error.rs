//! The node crate's errors. A request or message a node refuses gets one of these as its
//! reason (in the response's `message`, or on `/rosout`); nothing here panics on input.

use crate::params::ParamsError;
use crate::ros::args::RosArgsError;
use crate::ros::context::RosContextError;

/// Why a node could not start, or could not serve a request or use a message.
#[derive(Debug, thiserror::Error)]
pub enum NodeError {
    /// The scene file could not be loaded or built.
    #[error("scene {path}: {source}")]
    Scene {
        /// The scene file.
        path: String,
        /// What the core said.
        source: constraint_dynamics::Error,
    },
    /// A computation of the core library failed (what it was doing, and why).
    #[error("{what}: {source}")]
    Core {
        /// What the node asked the core for.
        what: &'static str,
        /// What the core said.
        source: constraint_dynamics::Error,
    },
    /// A service request the node cannot serve: the field at fault and why.
    #[error("{field}: {reason}")]
    BadRequest {
        /// Request field (or `request` as a whole).
        field: String,
        /// What is wrong with it.
        reason: String,
    },
    /// Two request fields that must have the same length do not.
    #[error(
        "{names} has {n_names} entries but {values} has {n_values}: they must be the same length"
    )]
    LengthMismatch {
        /// The names field.
        names: String,
        /// Its length.
        n_names: usize,
        /// The values field.
        values: String,
        /// Its length.
        n_values: usize,
    },
    /// An input message the node drops: which message and why.
    #[error("{message}: {reason}")]
    BadMessage {
        /// The message type and field (`JointState: position`).
        message: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A URDF on `/robot_description` that is empty.
    #[error("the URDF is empty")]
    EmptyUrdf,
    /// Bad parameters.
    #[error(transparent)]
    Params(#[from] ParamsError),
    /// Bad command line or parameter file.
    #[error(transparent)]
    Args(#[from] RosArgsError),
    /// DDS context, node, topic or service creation.
    #[error(transparent)]
    Ros(#[from] RosContextError),
    /// A thread could not be started.
    #[error("cannot start the worker thread: {0}")]
    Thread(#[from] std::io::Error),
    /// A lifecycle transition that cannot run.
    #[error("lifecycle: {0}")]
    Lifecycle(#[from] crate::lifecycle::LifecycleError),
    /// A lock held by a thread that panicked.
    #[error("internal error: a lock was poisoned by a panic")]
    Poisoned,
    /// Which node an error belongs to.
    #[error("{node}: {source}")]
    InNode {
        /// The node's name.
        node: String,
        /// The error.
        source: Box<NodeError>,
    },
    /// The suite's configuration as a whole (no node enabled, nodes that disagree, the
    /// network rule).
    #[error("{0}")]
    Suite(String),
}

impl NodeError {
    /// A refused request field.
    pub fn request(field: impl Into<String>, reason: impl Into<String>) -> Self {
        NodeError::BadRequest {
            field: field.into(),
            reason: reason.into(),
        }
    }

    /// A refused message.
    pub fn message(message: impl Into<String>, reason: impl Into<String>) -> Self {
        NodeError::BadMessage {
            message: message.into(),
            reason: reason.into(),
        }
    }

    /// A core error with what the node was doing.
    pub fn core(what: &'static str) -> impl FnOnce(constraint_dynamics::Error) -> NodeError {
        move |source| NodeError::Core { what, source }
    }

    /// This error, attributed to `node`.
    pub fn in_node(self, node: &str) -> NodeError {
        NodeError::InNode {
            node: node.to_string(),
            source: Box::new(self),
        }
    }
}
