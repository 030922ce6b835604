//! `lifecycle_msgs/msg/*` and `/srv/*`: the managed-node interface (rcl_lifecycle, Nav2's
//! lifecycle_manager). The state and transition ids are the `.msg` constants; the state
//! machine itself is [`crate::lifecycle`].

use serde::{Deserialize, Serialize};

use super::RosService;

/// `lifecycle_msgs/msg/State`: a primary or transition state.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct State {
    /// `PRIMARY_STATE_*` (0–4) or `TRANSITION_STATE_*` (10–15).
    pub id: u8,
    /// `unconfigured`, `inactive`, … as rcl_lifecycle names them.
    pub label: String,
}

/// `lifecycle_msgs/msg/Transition`.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Transition {
    /// `TRANSITION_*`: 1 configure, 2 cleanup, 3 activate, 4 deactivate, 5–7 shutdown, and the
    /// callback results (10 = on_configure success, …).
    pub id: u8,
    /// `configure`, `cleanup`, … (a request may name the transition by label with id 0).
    pub label: String,
}

/// `lifecycle_msgs/msg/TransitionDescription`: a transition available from a state.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct TransitionDescription {
    pub transition: Transition,
    pub start_state: State,
    /// The transition state it enters (as rcl_lifecycle reports it), e.g. `configuring`.
    pub goal_state: State,
}

/// `lifecycle_msgs/msg/TransitionEvent`: published on `~/transition_event` at every step.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct TransitionEvent {
    /// When it happened [ns since the epoch, or of the ROS clock].
    pub timestamp: u64,
    pub transition: Transition,
    pub start_state: State,
    pub goal_state: State,
}

super::ros_messages!("lifecycle_msgs": State, Transition, TransitionDescription, TransitionEvent);

/// Request of `lifecycle_msgs/srv/ChangeState`.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ChangeStateRequest {
    pub transition: Transition,
}

/// Response of `lifecycle_msgs/srv/ChangeState`.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ChangeStateResponse {
    /// The transition ran and its callback succeeded.
    pub success: bool,
}

/// An empty request: rosidl adds this one-byte member, and it is on the wire.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct EmptyRequest {
    /// Always 0.
    pub structure_needs_at_least_one_member: u8,
}

/// Response of `lifecycle_msgs/srv/GetState`.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct GetStateResponse {
    pub current_state: State,
}

/// Response of `lifecycle_msgs/srv/GetAvailableStates`.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct GetAvailableStatesResponse {
    pub available_states: Vec<State>,
}

/// Response of `lifecycle_msgs/srv/GetAvailableTransitions`.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct GetAvailableTransitionsResponse {
    pub available_transitions: Vec<TransitionDescription>,
}

impl ros2_client::Message for ChangeStateRequest {}
impl ros2_client::Message for ChangeStateResponse {}
impl ros2_client::Message for EmptyRequest {}
impl ros2_client::Message for GetStateResponse {}
impl ros2_client::Message for GetAvailableStatesResponse {}
impl ros2_client::Message for GetAvailableTransitionsResponse {}

macro_rules! lifecycle_service {
    ($srv:ident, $req:ty, $resp:ty) => {
        #[doc = concat!("Marker for `lifecycle_msgs/srv/", stringify!($srv), "`.")]
        #[derive(Clone, Copy, Debug)]
        pub struct $srv;
        impl RosService for $srv {
            type Request = $req;
            type Response = $resp;
            const PACKAGE: &'static str = "lifecycle_msgs";
            const NAME: &'static str = stringify!($srv);
        }
    };
}

lifecycle_service!(ChangeState, ChangeStateRequest, ChangeStateResponse);
lifecycle_service!(GetState, EmptyRequest, GetStateResponse);
lifecycle_service!(GetAvailableStates, EmptyRequest, GetAvailableStatesResponse);
lifecycle_service!(
    GetAvailableTransitions,
    EmptyRequest,
    GetAvailableTransitionsResponse
);
