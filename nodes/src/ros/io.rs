//! The executor side of subscriptions and service servers: loops that take messages and
//! requests and hand them on, never blocking on the worker.

use std::time::Duration;

use crate::msg::RosService;
use crate::ros::logging::NodeLog;

/// Where a request's response goes.
pub type Reply<T> = smol::channel::Sender<T>;

/// Takes messages from `sub` and hands each to `f`, until the node stops.
pub async fn subscribe<M: serde::de::DeserializeOwned + 'static>(
    sub: ros2_client::Subscription<M>,
    log: NodeLog,
    mut f: impl FnMut(M),
) {
    let mut errors = 0u64;
    loop {
        match sub.async_take().await {
            Ok((m, _)) => f(m),
            Err(e) => {
                errors += 1;
                if errors == 1 || errors.is_power_of_two() {
                    log.warn(&format!(
                        "dropped an undecodable message ({errors} so far): {e:?}"
                    ));
                }
                smol::Timer::after(Duration::from_millis(1)).await;
            }
        }
    }
}

/// Serves `S`: every request goes to the worker through `send`, whose reply is sent back;
/// `error` makes the response when the worker cannot answer. Requests are taken as they come
/// while earlier ones are computed, so a burst reaches the worker's queue and what does not
/// fit is answered "busy" at once, instead of waiting in the DDS reader's history (where the
/// oldest are dropped without a trace once it is full).
pub async fn serve<S, F>(
    server: ros2_client::Server<S::Request, S::Response>,
    log: NodeLog,
    send: F,
    error: fn(String) -> S::Response,
) where
    S: RosService,
    F: Fn(S::Request, Reply<S::Response>) -> bool,
{
    use futures::stream::FuturesUnordered;
    use futures::{FutureExt, StreamExt};
    // The requests the worker has, each waiting for its reply.
    let mut pending = FuturesUnordered::new();
    loop {
        let (id, resp) = futures::select_biased! {
            (id, reply) = pending.select_next_some() => {
                let reply: Result<S::Response, smol::channel::RecvError> = reply;
                let resp = reply.unwrap_or_else(|_| error(
                    "internal error while serving this request (see the node's log); \
                     the node rebuilt its model and keeps serving"
                        .into(),
                ));
                (id, resp)
            }
            // Cancel-safe: a request is taken only when the poll returns it.
            r = server.async_receive_request().fuse() => match r {
                Ok((id, req)) => {
                    let (reply_tx, reply_rx) = smol::channel::bounded(1);
                    if send(req, reply_tx) {
                        pending.push(async move { (id, reply_rx.recv().await) });
                        continue;
                    }
                    (id, error("busy: the node's request queue is full, try again".into()))
                }
                Err(e) => {
                    log.warn(&format!(
                        "{}: dropped an undecodable request: {e:?}",
                        S::NAME
                    ));
                    smol::Timer::after(Duration::from_millis(1)).await;
                    continue;
                }
            },
        };
        if let Err(e) = server.async_send_response(id, resp).await {
            log.warn(&format!("{}: sending the response failed: {e:?}", S::NAME));
        }
    }
}
