//! `constraint_dynamics_query`: query a running suite without a ROS installation (the ros2 CLI
//! equivalent for this project's services, topics and parameters). Prints JSON.
//!
//! ```text
//! constraint_dynamics_query [--ns /NS] [--timeout S] [--try S] COMMAND
//!   forces [--q a,b,..] [--v a,b,..] [--tau a,b,..]       ~/get_constraint_forces (latest state
//!                                                         unless --q is given)
//!   project --twist vx,vy,wz [--joint NAME=V]... [--lower NAME=V]... [--upper NAME=V]...
//!           [--accel-dt S]                                ~/project_velocity at the latest state
//!   predict [--twist v,w]... [--period S] [--horizon S] [--forces] [--repeat N]
//!                                                         ~/predict from the latest state
//!                                                         (--repeat: N calls by one client,
//!                                                         one summary line per reply)
//!   echo odom|path|forces [--count N]                     the predictor's topics
//!   param list NODE | param get NODE NAME | param set NODE NAME VALUE
//! ```
//!
//! A call sends its request again when no response came within `--try` seconds (default 0.5;
//! raise it for requests that take longer to compute), until `--timeout`.
//!
//! Node names are those of the suite (cd_predictor, cd_forces, cd_projection, cd_prediction)
//! under `--ns`. Like the suite it opens DDS only in a loopback-only namespace, on
//! `CD_ROS_INTERFACES=127.0.0.1`, or with `CD_ALLOW_EXTERNAL_NETWORK=1`; run it in the same
//! `tools/ros2/netns_run.sh` call as the suite.

use std::process::ExitCode;
use std::time::Duration;

use constraint_dynamics_nodes::msg::constraint_dynamics_msgs::ConstraintForces;
use constraint_dynamics_nodes::msg::constraint_dynamics_msgs::srv::{
    GetConstraintForces, GetConstraintForcesRequest, Predict, PredictRequest, PredictResponse,
    ProjectVelocity, ProjectVelocityRequest,
};
use constraint_dynamics_nodes::msg::geometry_msgs::{Twist, Vector3};
use constraint_dynamics_nodes::msg::nav_msgs::{Odometry, Path};
use constraint_dynamics_nodes::msg::rcl_interfaces::{
    GetParameters, ListParameters, SetParameters,
};
use constraint_dynamics_nodes::ros::args::yaml_to_param;
use constraint_dynamics_nodes::ros::context::{NetworkConfig, RosNode, in_loopback_only_namespace};
use constraint_dynamics_nodes::ros::network_guard::{ALLOW_EXTERNAL_ENV, network_guard};
use query::{Query, print};
use ros2_client::dds::rustdds::no_key::SerializerAdapter;
use ros2_client::dds::rustdds::serialization::CDRSerializerAdapter;
use ros2_client::rcl_interfaces::{
    GetParametersRequest, ListParametersRequest, SetParametersRequest,
};
use ros2_client::{NodeOptions, ParameterValue};

mod query;

const USAGE: &str = "usage: constraint_dynamics_query [--ns /NS] [--timeout S] [--try S] COMMAND
  forces [--q a,b,..] [--v a,b,..] [--tau a,b,..]
  project --twist vx,vy,wz [--joint NAME=V]... [--lower NAME=V]... [--upper NAME=V]... [--accel-dt S]
  predict [--twist v,w]... [--period S] [--horizon S] [--forces] [--repeat N]
  echo odom|path|forces [--count N]
  param list NODE | param get NODE NAME | param set NODE NAME VALUE";

struct Opts {
    ns: String,
    timeout: Duration,
    per_try: Duration,
    rest: Vec<String>,
}

/// Why a query failed: a usage error (the message says what to type), or ROS.
#[derive(Debug, thiserror::Error)]
enum QueryError {
    /// Bad command line, or a failed call with its reason.
    #[error("{0}")]
    Usage(String),
    /// The network rule refused the participant.
    #[error(transparent)]
    Network(#[from] constraint_dynamics_nodes::ros::network_guard::NetworkRefused),
}

impl From<String> for QueryError {
    fn from(s: String) -> Self {
        QueryError::Usage(s)
    }
}

impl From<&str> for QueryError {
    fn from(s: &str) -> Self {
        QueryError::Usage(s.to_string())
    }
}

fn numbers(s: &str) -> Result<Vec<f64>, QueryError> {
    s.split(',')
        .filter(|x| !x.trim().is_empty())
        .map(|x| {
            x.trim()
                .parse::<f64>()
                .map_err(|_| QueryError::Usage(format!("{x:?} is not a number")))
        })
        .collect()
}

fn named(s: &str) -> Result<(String, f64), QueryError> {
    let (n, v) = s
        .split_once('=')
        .ok_or_else(|| format!("{s:?}: expected NAME=VALUE"))?;
    let v = v
        .trim()
        .parse::<f64>()
        .map_err(|_| format!("{s:?}: {v:?} is not a number"))?;
    Ok((n.trim().to_string(), v))
}

/// A duration option's value: positive, finite seconds, at most a day.
fn seconds(option: &str, value: Option<String>) -> Result<Duration, QueryError> {
    let v = value.ok_or_else(|| format!("{option} needs a value in seconds"))?;
    match v.trim().parse::<f64>() {
        Ok(s) if s > 0.0 && s <= 86_400.0 => Ok(Duration::from_secs_f64(s)),
        _ => Err(format!("{option} {v:?}: expected seconds in (0, 86400]").into()),
    }
}

fn twist3(v: &[f64]) -> Result<Twist, QueryError> {
    let (x, y, w) = match v {
        [x, w] => (*x, 0.0, *w),
        [x, y, w] => (*x, *y, *w),
        _ => return Err("--twist takes v,w or vx,vy,wz".into()),
    };
    Ok(Twist {
        linear: Vector3 { x, y, z: 0.0 },
        angular: Vector3 {
            x: 0.0,
            y: 0.0,
            z: w,
        },
    })
}

fn run(opts: Opts) -> Result<(), QueryError> {
    let net = NetworkConfig::from_env().map_err(|e| e.to_string())?;
    let allowed = std::env::var(ALLOW_EXTERNAL_ENV).is_ok_and(|v| v.trim() == "1");
    network_guard(&net, allowed, in_loopback_only_namespace())?;
    let ctx = net.create_context().map_err(|e| e.to_string())?;
    let node = RosNode::new(
        &ctx,
        "/",
        &format!("cd_query_{}", std::process::id()),
        NodeOptions::new().start_parameter_services(false),
    )
    .map_err(|e| e.to_string())?;
    let mut q = Query {
        node,
        ns: opts.ns,
        timeout: opts.timeout,
        per_try: opts.per_try,
    };
    let mut args = opts.rest.into_iter();
    let cmd = args.next().ok_or(USAGE)?;
    let mut rest: Vec<String> = args.collect();
    let mut take = |flag: &str| -> Vec<String> {
        let mut out = Vec::new();
        let mut i = 0;
        while i < rest.len() {
            if rest[i] == flag && i + 1 < rest.len() {
                out.push(rest.remove(i + 1));
                rest.remove(i);
            } else {
                i += 1;
            }
        }
        out
    };
    match cmd.as_str() {
        "forces" => {
            let mut req = GetConstraintForcesRequest {
                use_latest_state: true,
                ..Default::default()
            };
            if let Some(s) = take("--q").pop() {
                req.use_latest_state = false;
                req.q = numbers(&s)?;
            }
            if let Some(s) = take("--v").pop() {
                req.v = numbers(&s)?;
            }
            if let Some(s) = take("--tau").pop() {
                req.tau = numbers(&s)?;
            }
            let name = q.name("cd_forces", "get_constraint_forces");
            print(&q.call::<GetConstraintForces>(&name, req)?);
        }
        "project" => {
            let mut req = ProjectVelocityRequest {
                use_latest_state: true,
                use_twist: true,
                ..Default::default()
            };
            let tw = take("--twist").pop().ok_or("project needs --twist")?;
            req.base_twist = twist3(&numbers(&tw)?)?;
            for j in take("--joint") {
                let (n, v) = named(&j)?;
                req.joint_names.push(n);
                req.joint_velocities.push(v);
            }
            let lower = take("--lower");
            let upper = take("--upper");
            for (s, is_lower) in lower
                .iter()
                .map(|s| (s, true))
                .chain(upper.iter().map(|s| (s, false)))
            {
                let (n, v) = named(s)?;
                let k = match req.bound_names.iter().position(|b| *b == n) {
                    Some(k) => k,
                    None => {
                        req.bound_names.push(n);
                        req.lower.push(f64::NEG_INFINITY);
                        req.upper.push(f64::INFINITY);
                        req.bound_names.len() - 1
                    }
                };
                if is_lower {
                    req.lower[k] = v;
                } else {
                    req.upper[k] = v;
                }
            }
            if let Some(s) = take("--accel-dt").pop() {
                req.accel_limit_dt = s.parse().map_err(|_| "--accel-dt: not a number")?;
            }
            let name = q.name("cd_projection", "project_velocity");
            print(&q.call::<ProjectVelocity>(&name, req)?);
        }
        "predict" => {
            let mut req = PredictRequest {
                use_latest_state: true,
                horizon: 1.0,
                command_period: 1.0,
                ..Default::default()
            };
            for t in take("--twist") {
                req.commands.push(twist3(&numbers(&t)?)?);
            }
            if let Some(s) = take("--period").pop() {
                req.command_period = s.parse().map_err(|_| "--period: not a number")?;
            }
            if let Some(s) = take("--horizon").pop() {
                req.horizon = s.parse().map_err(|_| "--horizon: not a number")?;
            }
            let repeat = take("--repeat")
                .pop()
                .map(|s| s.parse::<u32>().map_err(|_| "--repeat: not a number"))
                .transpose()?;
            if let Some(k) = rest.iter().position(|a| a == "--forces") {
                rest.remove(k);
                req.with_forces = true;
            }
            let name = q.name("cd_prediction", "predict");
            match repeat {
                None => print(&q.call::<Predict>(&name, req)?),
                Some(n) => {
                    let started = std::time::Instant::now();
                    q.call_n::<Predict>(&name, req, n.max(1), |i, r| {
                        // Size of the reply's serialized payload: encapsulation + CDR body.
                        let bytes = CDRSerializerAdapter::<PredictResponse>::to_bytes(&r)
                            .map_or(0, |b| b.len() + 4);
                        println!(
                            "{}",
                            serde_json::json!({
                                "reply": i + 1,
                                "success": r.success,
                                // Why, when success is false (a refusal is a reply too).
                                "message": r.message,
                                "samples": r.path.poses.len(),
                                "forces": r.forces.len(),
                                "payload_bytes": bytes,
                                "seconds": started.elapsed().as_secs_f64(),
                            })
                        );
                    })?;
                }
            }
        }
        "echo" => {
            let count = take("--count")
                .pop()
                .map(|s| s.parse::<usize>().map_err(|_| "--count: not a number"))
                .transpose()?
                .unwrap_or(1);
            let what = rest
                .first()
                .cloned()
                .ok_or("echo needs odom, path or forces")?;
            rest.clear();
            match what.as_str() {
                "odom" => {
                    let t = q.name("cd_predictor", "predicted_odom");
                    q.echo::<Odometry>(&t, count)?
                }
                "path" => {
                    let t = q.name("cd_predictor", "predicted_path");
                    q.echo::<Path>(&t, count)?
                }
                "forces" => {
                    let t = q.name("cd_predictor", "constraint_forces");
                    q.echo::<ConstraintForces>(&t, count)?
                }
                other => return Err(format!("echo {other}: expected odom, path or forces").into()),
            }
        }
        "param" => {
            let sub = rest.first().cloned().ok_or(USAGE)?;
            let node = rest.get(1).cloned().ok_or("param needs a NODE")?;
            match (sub.as_str(), rest.len()) {
                ("list", 2) => {
                    let r = q.call::<ListParameters>(
                        &q.name(&node, "list_parameters"),
                        ListParametersRequest {
                            prefixes: vec![],
                            depth: 0,
                        },
                    )?;
                    print(&r.result.names);
                }
                ("get", 3) => {
                    let r = q.call::<GetParameters>(
                        &q.name(&node, "get_parameters"),
                        GetParametersRequest {
                            names: vec![rest[2].clone()],
                        },
                    )?;
                    let v: Vec<String> = r
                        .values
                        .into_iter()
                        .map(|v| format!("{:?}", ParameterValue::from(v)))
                        .collect();
                    print(&v);
                }
                ("set", 4) => {
                    let yaml: serde_yaml::Value = serde_yaml::from_str(&rest[3])
                        .unwrap_or_else(|_| serde_yaml::Value::String(rest[3].clone()));
                    let value = yaml_to_param(&rest[2], &yaml).map_err(|e| e.to_string())?;
                    let r = q.call::<SetParameters>(
                        &q.name(&node, "set_parameters"),
                        SetParametersRequest {
                            parameter: vec![ros2_client::parameters::raw::Parameter {
                                name: rest[2].clone(),
                                value: value.into(),
                            }],
                        },
                    )?;
                    let out: Vec<(bool, String)> = r
                        .results
                        .into_iter()
                        .map(|x| (x.successful, x.reason))
                        .collect();
                    print(&out);
                }
                _ => return Err(USAGE.into()),
            }
            rest.clear();
        }
        "-h" | "--help" => {
            println!("{USAGE}");
            return Ok(());
        }
        other => return Err(format!("unknown command {other:?}\n{USAGE}").into()),
    }
    if !rest.is_empty() {
        eprintln!("warning: ignored arguments {rest:?}");
    }
    Ok(())
}

fn main() -> ExitCode {
    let mut opts = Opts {
        ns: "/".into(),
        timeout: Duration::from_secs(5),
        per_try: Duration::from_millis(500),
        rest: Vec::new(),
    };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--ns" => opts.ns = args.next().unwrap_or_else(|| "/".into()),
            "--timeout" | "--try" => match seconds(&a, args.next()) {
                Ok(d) if a == "--timeout" => opts.timeout = d,
                Ok(d) => opts.per_try = d,
                Err(e) => {
                    eprintln!("error: {e}\n\n{USAGE}");
                    return ExitCode::from(2);
                }
            },
            _ => {
                opts.rest.push(a);
                opts.rest.extend(args.by_ref());
            }
        }
    }
    if opts.rest.is_empty() {
        eprintln!("{USAGE}");
        return ExitCode::from(2);
    }
    match run(opts) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
