//! The node kinds of the suite, their `--node` keys and default names.

/// The four node kinds of the suite.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum NodeKind {
    /// Periodic prediction from the latest state and command: `~/predicted_odom`,
    /// `~/predicted_path`, `~/constraint_forces`.
    Predictor,
    /// `~/get_constraint_forces` service.
    Forces,
    /// `~/project_velocity` service and the command filter.
    Projection,
    /// `~/predict` service.
    Prediction,
}

impl NodeKind {
    /// All kinds, in the order the suite starts them.
    pub const ALL: [NodeKind; 4] = [
        NodeKind::Predictor,
        NodeKind::Forces,
        NodeKind::Projection,
        NodeKind::Prediction,
    ];

    /// The `--node` switch value.
    pub fn key(self) -> &'static str {
        match self {
            NodeKind::Predictor => "predictor",
            NodeKind::Forces => "forces",
            NodeKind::Projection => "projection",
            NodeKind::Prediction => "prediction",
        }
    }

    /// The default ROS node name.
    pub fn default_node_name(self) -> &'static str {
        match self {
            NodeKind::Predictor => "cd_predictor",
            NodeKind::Forces => "cd_forces",
            NodeKind::Projection => "cd_projection",
            NodeKind::Prediction => "cd_prediction",
        }
    }

    /// From a `--node` value (`predictor`, `forces`, `projection`, `prediction`).
    pub fn from_key(key: &str) -> Option<NodeKind> {
        NodeKind::ALL.into_iter().find(|k| k.key() == key)
    }
}
