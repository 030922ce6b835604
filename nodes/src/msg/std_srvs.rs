//! `std_srvs/srv/*`.

use serde::{Deserialize, Serialize};

use super::RosService;

/// Request of `std_srvs/srv/Trigger`: empty in the `.srv`; rosidl adds this
/// one-byte member to every empty structure, and it is on the wire.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct TriggerRequest {
    /// Always 0.
    pub structure_needs_at_least_one_member: u8,
}

/// Response of `std_srvs/srv/Trigger`.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct TriggerResponse {
    /// Whether the action succeeded.
    pub success: bool,
    /// Informational, e.g. an error message.
    pub message: String,
}

/// Marker for the `std_srvs/srv/Trigger` service.
#[derive(Clone, Copy, Debug)]
pub struct Trigger;

impl RosService for Trigger {
    type Request = TriggerRequest;
    type Response = TriggerResponse;
    const PACKAGE: &'static str = "std_srvs";
    const NAME: &'static str = "Trigger";
}

impl ros2_client::Message for TriggerRequest {}
impl ros2_client::Message for TriggerResponse {}
