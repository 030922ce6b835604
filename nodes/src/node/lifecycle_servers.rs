//! A node's `lifecycle_msgs` services: `~/change_state`, `~/get_state` and
//! `~/get_available_transitions` hand their requests to the node's supervisor
//! ([`super::managed`]), which owns the state machine; `~/get_available_states` never changes
//! and is answered on the executor.

use std::sync::mpsc::Sender;

use crate::error::NodeError;
use crate::lifecycle::State;
use crate::msg::lifecycle_msgs::{
    self as lm, ChangeState, ChangeStateResponse, GetAvailableStates, GetAvailableStatesResponse,
    GetAvailableTransitions, GetAvailableTransitionsResponse, GetState, GetStateResponse,
};
use crate::ros::context::RosNode;
use crate::ros::io::{Reply, serve};
use crate::ros::logging::NodeLog;

/// What the lifecycle servers ask the supervisor.
pub(super) enum Request {
    Change(lm::Transition, Reply<ChangeStateResponse>),
    State(Reply<GetStateResponse>),
    Transitions(Reply<GetAvailableTransitionsResponse>),
    Stop,
}

/// Serves the lifecycle services of `ros` (names resolved by `topic`); the requests the
/// supervisor answers go to `requests`. The returned tasks own the servers.
pub(super) fn lifecycle_servers(
    ros: &mut RosNode,
    topic: &dyn Fn(&str) -> String,
    log: &NodeLog,
    requests: &Sender<Request>,
) -> Result<Vec<smol::Task<()>>, NodeError> {
    let mut servers = Vec::new();
    let tx = requests.clone();
    let server = ros.server::<ChangeState>(&topic("~/change_state"))?;
    servers.push(ros.spawn(serve::<ChangeState, _>(
        server,
        log.clone(),
        move |req, reply| tx.send(Request::Change(req.transition, reply)).is_ok(),
        |_| ChangeStateResponse { success: false },
    )));
    let tx = requests.clone();
    let server = ros.server::<GetState>(&topic("~/get_state"))?;
    servers.push(ros.spawn(serve::<GetState, _>(
        server,
        log.clone(),
        move |_, reply| tx.send(Request::State(reply)).is_ok(),
        |_| GetStateResponse::default(),
    )));
    let tx = requests.clone();
    let server = ros.server::<GetAvailableTransitions>(&topic("~/get_available_transitions"))?;
    servers.push(ros.spawn(serve::<GetAvailableTransitions, _>(
        server,
        log.clone(),
        move |_, reply| tx.send(Request::Transitions(reply)).is_ok(),
        |_| GetAvailableTransitionsResponse::default(),
    )));
    let server = ros.server::<GetAvailableStates>(&topic("~/get_available_states"))?;
    servers.push(ros.spawn(serve::<GetAvailableStates, _>(
        server,
        log.clone(),
        |_, reply| {
            let available_states = State::ALL.iter().map(|s| s.msg()).collect();
            reply
                .try_send(GetAvailableStatesResponse { available_states })
                .is_ok()
        },
        |_| GetAvailableStatesResponse::default(),
    )));
    Ok(servers)
}
