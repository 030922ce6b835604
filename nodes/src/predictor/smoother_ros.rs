//! The velocity smoother bridge on ROS: a task of the node's executor that reads the smoother's
//! `max_accel` and `max_decel` once (`<name>/get_parameters`: its own setting caps what is
//! sent, and gives y), then keeps them at the envelope through `<name>/set_parameters`, as
//! [`super::smoother`] decides.
//!
//! It never blocks the tick: the publishing task hands it the latest envelope through a
//! one-slot channel (a newer one replaces one not yet taken), and every call is bounded
//! ([`CALL_WAIT`] per try, [`CALL_TRIES`] tries). A smoother that does not answer, or refuses,
//! gets a WARN (one per reason per [`DropLog::WINDOW`]) and is asked again after [`RETRY`].

use std::time::{Duration, Instant};

use ros2_client::parameters::{ParameterValue, raw};
use ros2_client::rcl_interfaces::{GetParametersRequest, SetParametersRequest};

use super::params::EnvelopeParams;
use super::smoother::{DeadBand, SmootherLimits, smoother_limits};
use crate::error::NodeError;
use crate::msg::constraint_dynamics_msgs::AccelerationLimits;
use crate::msg::rcl_interfaces::{GetParameters, SetParameters};
use crate::ros::context::{RosNode, call_with_retry};
use crate::ros::logging::{DropLog, NodeLog};

/// How long one try of a call waits for the response.
pub const CALL_WAIT: Duration = Duration::from_millis(500);
/// Tries of one call (a request can race the server's discovery of the client).
pub const CALL_TRIES: u32 = 2;
/// Pause after a failed call before the next one.
pub const RETRY: Duration = Duration::from_secs(2);

/// One envelope for the bridge: the limits and the base's forward speed at their state [m/s].
pub type BridgeInput = (AccelerationLimits, f64);

/// Starts the bridge to the smoother `p.velocity_smoother` (resolved by `resolve`): the sender
/// the publishing task feeds, and the task (dropping it stops the bridge).
pub fn start(
    ros: &mut RosNode,
    resolve: &dyn Fn(&str) -> String,
    p: &EnvelopeParams,
    log: NodeLog,
) -> Result<(smol::channel::Sender<BridgeInput>, smol::Task<()>), NodeError> {
    let name = p.velocity_smoother.trim_end_matches('/');
    let get = ros.client::<GetParameters>(&resolve(&format!("{name}/get_parameters")))?;
    let set = ros.client::<SetParameters>(&resolve(&format!("{name}/set_parameters")))?;
    let (tx, rx) = smol::channel::bounded::<BridgeInput>(1);
    let p = p.clone();
    let who = format!("velocity smoother '{name}'");
    log.info(&format!(
        "{who}: keeping max_accel and max_decel at the acceleration envelope"
    ));
    let task = ros.spawn(async move {
        let mut warnings = DropLog::new(DropLog::WINDOW);
        let mut warn = |reason: &str| {
            let level = warnings.level("smoother", reason, Instant::now());
            log.log(level, &format!("{who}: {reason}"));
        };
        let mut setting: Option<SmootherLimits> = None;
        let mut dead_band = DeadBand::default();
        let mut next_try = Instant::now();
        let min_interval = Duration::from_secs_f64(p.min_interval);
        while let Ok((limits, v_x)) = rx.recv().await {
            let now = Instant::now();
            if now < next_try {
                continue;
            }
            let Some(own) = setting else {
                match read_setting(&get).await {
                    Ok(s) => {
                        log.info(&format!(
                            "{who}: its own max_accel {:?}, max_decel {:?} cap what is sent",
                            s.max_accel, s.max_decel
                        ));
                        setting = Some(s);
                    }
                    Err(e) => {
                        warn(&format!("{e}; asking again in {} s", RETRY.as_secs()));
                        next_try = Instant::now() + RETRY;
                    }
                }
                continue;
            };
            let (next, floored) = smoother_limits(&limits, v_x, &own, &p);
            if !dead_band.due(&next, now, p.dead_band, min_interval) {
                continue;
            }
            if !floored.is_empty() {
                warn(&format!(
                    "{} (limits at or below the floor: the robot cannot keep every contact)",
                    floored.join(", ")
                ));
            }
            match write_limits(&set, &next).await {
                Ok(()) => {
                    log.info(&format!(
                        "{who}: max_accel {:?}, max_decel {:?}",
                        next.max_accel, next.max_decel
                    ));
                    dead_band.sent(next, Instant::now());
                }
                Err(e) => {
                    warn(&format!("{e}; trying again in {} s", RETRY.as_secs()));
                    next_try = Instant::now() + RETRY;
                }
            }
        }
    });
    Ok((tx, task))
}

/// Hands `input` to the bridge, replacing an envelope it has not taken yet.
pub fn offer(tx: &smol::channel::Sender<BridgeInput>, input: BridgeInput) {
    let _ = tx.force_send(input);
}

/// The smoother's `max_accel` and `max_decel`.
async fn read_setting(
    get: &ros2_client::Client<
        GetParametersRequest,
        ros2_client::rcl_interfaces::GetParametersResponse,
    >,
) -> Result<SmootherLimits, String> {
    let req = GetParametersRequest {
        names: vec!["max_accel".into(), "max_decel".into()],
    };
    let (resp, _) = call_with_retry(get, req, CALL_WAIT, CALL_TRIES)
        .await
        .map_err(|e| format!("get_parameters: no answer ({e}): is the node running?"))?;
    let doubles = |i: usize, name: &str| match resp.values.get(i).cloned().map(ParameterValue::from)
    {
        Some(ParameterValue::DoubleArray(x)) => Ok(x),
        other => Err(format!(
            "{name} is {other:?}, not a double array [x, y, θ] (a Nav2 velocity smoother declares it)"
        )),
    };
    SmootherLimits::from_setting(&doubles(0, "max_accel")?, &doubles(1, "max_decel")?)
}

/// Sets `max_accel` and `max_decel` in one call.
async fn write_limits(
    set: &ros2_client::Client<
        SetParametersRequest,
        ros2_client::rcl_interfaces::SetParametersResponse,
    >,
    l: &SmootherLimits,
) -> Result<(), String> {
    let param = |name: &str, x: [f64; 3]| raw::Parameter {
        name: name.to_string(),
        value: ParameterValue::DoubleArray(x.to_vec()).into(),
    };
    let req = SetParametersRequest {
        parameter: vec![
            param("max_accel", l.max_accel),
            param("max_decel", l.max_decel),
        ],
    };
    let (resp, _) = call_with_retry(set, req, CALL_WAIT, CALL_TRIES)
        .await
        .map_err(|e| format!("set_parameters: no answer ({e})"))?;
    let refused: Vec<String> = resp
        .results
        .iter()
        .zip(["max_accel", "max_decel"])
        .filter(|(r, _)| !r.successful)
        .map(|(r, n)| format!("{n}: {}", r.reason))
        .collect();
    match (resp.results.len(), refused.is_empty()) {
        (2, true) => Ok(()),
        (2, false) => Err(format!("set_parameters refused {}", refused.join("; "))),
        (n, _) => Err(format!(
            "set_parameters answered {n} results for 2 parameters"
        )),
    }
}
