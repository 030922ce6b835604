//! The query tool's ROS side: one client node, calls with retry, topic echo.

use std::time::Duration;

use constraint_dynamics_nodes::msg::RosService;
use constraint_dynamics_nodes::ros::context::{RosNode, call_with_retry, qos};
use serde::Serialize;

use crate::QueryError;

/// Prints `v` as pretty JSON on stdout.
pub fn print<T: Serialize>(v: &T) {
    println!(
        "{}",
        serde_json::to_string_pretty(v).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
    );
}

/// A client node and the tool's timing options.
pub struct Query {
    pub node: RosNode,
    /// The suite's namespace (`--ns`).
    pub ns: String,
    /// How long a call or an echo may take in all (`--timeout`).
    pub timeout: Duration,
    /// How long a call waits before sending its request again (`--try`).
    pub per_try: Duration,
}

impl Query {
    pub fn name(&self, node: &str, leaf: &str) -> String {
        let node = node.trim_start_matches('/');
        format!("{}/{node}/{leaf}", self.ns.trim_end_matches('/'))
    }

    pub fn call<S: RosService>(
        &mut self,
        name: &str,
        req: S::Request,
    ) -> Result<S::Response, QueryError> {
        let mut out = None;
        self.call_n::<S>(name, req, 1, |_, r| out = Some(r))?;
        out.ok_or_else(|| "no response".into())
    }

    /// Calls `name` `n` times with one client, handing each response to `each`. The first
    /// call is retried while discovery settles; the later ones are sent once and may take up
    /// to `--timeout` each.
    pub fn call_n<S: RosService>(
        &mut self,
        name: &str,
        req: S::Request,
        n: u32,
        mut each: impl FnMut(u32, S::Response),
    ) -> Result<(), QueryError> {
        let client = self.node.client::<S>(name).map_err(|e| e.to_string())?;
        let found = smol::block_on(smol::future::or(
            async {
                client.wait_for_service(&self.node.node).await;
                true
            },
            async {
                smol::Timer::after(self.timeout).await;
                false
            },
        ));
        if !found {
            return Err(format!("service {name} not found within {:?}", self.timeout).into());
        }
        let tries = (self.timeout.as_secs_f64() / self.per_try.as_secs_f64())
            .ceil()
            .max(1.0) as u32;
        let (first, _) = smol::block_on(call_with_retry(&client, req.clone(), self.per_try, tries))
            .map_err(|e| QueryError::Usage(e.to_string()))?;
        each(0, first);
        for i in 1..n {
            let r = smol::block_on(smol::future::or(
                async { Some(client.async_call_service(req.clone()).await) },
                async {
                    smol::Timer::after(self.timeout).await;
                    None
                },
            ))
            .ok_or_else(|| {
                format!(
                    "call {} of {n}: no response within {:?}",
                    i + 1,
                    self.timeout
                )
            })?
            .map_err(|e| format!("call {} of {n}: {e:?}", i + 1))?;
            each(i, r);
        }
        Ok(())
    }

    pub fn echo<M>(&mut self, topic: &str, count: usize) -> Result<(), QueryError>
    where
        M: constraint_dynamics_nodes::msg::RosMessage + Serialize + 'static,
    {
        let sub = self
            .node
            .subscription::<M>(topic, &qos::reliable(10))
            .map_err(|e| e.to_string())?;
        for _ in 0..count {
            let m = smol::block_on(smol::future::or(
                async { Some(sub.async_take().await) },
                async {
                    smol::Timer::after(self.timeout).await;
                    None
                },
            ))
            .ok_or_else(|| format!("no message on {topic} within {:?}", self.timeout))?
            .map_err(|e| format!("{e:?}"))?;
            print(&m.0);
        }
        Ok(())
    }
}
