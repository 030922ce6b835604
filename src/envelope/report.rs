//! The envelope by name, as the CLI prints it (JSON; no nulls: an unbounded or infeasible
//! limit has no `max`).

use super::{Envelope, EnvelopeModel, Limit, Reach};
use crate::model::Model;
use crate::robot_limits::NamedLimit;
use serde::Serialize;

/// One limit: `{"max": a, "binding": [...]}`, or `{"unbounded": true, ...}`, or
/// `{"infeasible": true, ...}`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LimitReport {
    /// The signed maximum [m/s² or rad/s²] (absent unless bounded).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max: Option<f64>,
    /// True when nothing bounds this direction.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub unbounded: bool,
    /// True when no accelerations meet every limit with the other direction held.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub infeasible: bool,
    /// What binds the maximum.
    pub binding: Vec<NamedLimit>,
}

/// The four limits and what the envelope could not check.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct EnvelopeReport {
    /// Largest forward acceleration, yaw acceleration held at 0 [m/s²].
    pub forward_acceleration: LimitReport,
    /// Largest forward deceleration, yaw acceleration held at 0 [m/s²] (negative: the robot
    /// cannot hold still with every contact holding).
    pub forward_deceleration: LimitReport,
    /// Largest yaw acceleration to the left (+z), forward acceleration held at 0 [rad/s²].
    pub yaw_acceleration_left: LimitReport,
    /// Largest yaw acceleration to the right, forward acceleration held at 0 [rad/s²].
    pub yaw_acceleration_right: LimitReport,
    /// Limits not checked: friction of contacts without μ (or without a normal row), lift-off
    /// of wheels without a normal row (planar base), effort of joints without one.
    pub unchecked: Vec<NamedLimit>,
}

impl EnvelopeReport {
    /// Name every limit of `envelope` (allocates; for output).
    pub fn new(model: &Model, em: &EnvelopeModel, envelope: &Envelope) -> Self {
        let limit = |l: &Limit| LimitReport {
            max: (l.reach == Reach::Bounded).then_some(l.max),
            unbounded: l.reach == Reach::Unbounded,
            infeasible: l.reach == Reach::Infeasible,
            binding: l
                .binding
                .iter()
                .map(|b| NamedLimit {
                    kind: b.kind.name(),
                    name: em.binding_name(model, b).to_string(),
                })
                .collect(),
        };
        Self {
            forward_acceleration: limit(&envelope.forward_acceleration),
            forward_deceleration: limit(&envelope.forward_deceleration),
            yaw_acceleration_left: limit(&envelope.yaw_acceleration_left),
            yaw_acceleration_right: limit(&envelope.yaw_acceleration_right),
            unchecked: unchecked_limits(em),
        }
    }
}

/// The limits the model cannot check (`EnvelopeModel::unchecked`), named as the report names
/// them.
pub(crate) fn unchecked_limits(em: &EnvelopeModel) -> Vec<NamedLimit> {
    em.unchecked
        .iter()
        .map(|(k, n)| NamedLimit {
            kind: k.name(),
            name: n.clone(),
        })
        .collect()
}
