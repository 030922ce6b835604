//! The ROS 2 command line (`--ros-args ...`) and ROS parameter files.
//!
//! ros2-client parses neither, so the nodes do it here, following rcl:
//!
//! ```text
//! node [USER ARGS] --ros-args [ROS ARGS] [-- [USER ARGS]] [--ros-args ...]
//!   -p | --param [NODE:]NAME:=VALUE     VALUE is YAML (1, 2.5, true, text, [1.0, 2.0])
//!   --params-file FILE                  ROS parameter YAML, see below
//!   -r | --remap [NODE:]FROM:=TO        topic/service remapping
//!   -r __node:=NAME | -r __name:=NAME   node name
//!   -r __ns:=/NS                        node namespace
//!   -e | --enclave E, --log-level L, --log-config-file F,
//!   --enable-/--disable-{rosout,stdout,external-lib}-logs   accepted, stored, not acted on
//! ```
//!
//! A parameter file maps node names to `ros__parameters`:
//!
//! ```yaml
//! /**:                       # wildcard: every node
//!   ros__parameters:
//!     use_sim_time: false
//! constraint_dynamics:       # = /constraint_dynamics (root namespace)
//!   ros__parameters:
//!     rate: 100.0            # [Hz]
//!     solver: { tolerance: 1.0e-9 }   # nested keys become "solver.tolerance"
//! ```
//!
//! Node keys are matched against the node's fully qualified name (a key
//! without a leading `/` gets one, as rclcpp does; `*` matches one name
//! token, `**` any number). Keys may also nest namespaces
//! (`robot: { node: { ros__parameters: .. } } = /robot/node`).
//!
//! Precedence, lowest to highest: parameter files in command-line order, and
//! within one file wildcard keys before node-specific keys (node-specific wins);
//! then `-p` values in command-line order.
//!
//! Wildcard sections and `-p` without a node name address every node: a node that does not
//! have such a parameter ignores it, as rclcpp ignores overrides a node does not declare
//! ([`Parameters::shared`]). A node's own section and `-p NODE:NAME` are its own: a name it
//! does not have there is an error.
//!
//! Scalars follow the YAML 1.2 core schema of `serde_yaml` (`true`/`false`
//! are booleans; `yes`/`on` stay strings). An empty sequence becomes an
//! empty `StringArray`. Integers mixed with doubles in a sequence become doubles.

use std::path::PathBuf;

mod params_file;

pub use params_file::{
    Parameters, load_params_file, node_key_matches, param_to_yaml, parse_params_yaml, yaml_to_param,
};

use ros2_client::ParameterValue;
use serde_yaml::Value;

/// Errors of command-line and parameter-file parsing.
#[derive(Debug, thiserror::Error)]
pub enum RosArgsError {
    /// A flag that needs a value was last.
    #[error("--ros-args: {0} needs a value")]
    MissingValue(String),
    /// A flag rcl does not know.
    #[error("--ros-args: unknown ROS argument {0:?}")]
    UnknownArgument(String),
    /// A `-p`/`-r` rule without `:=`, or with an empty side.
    #[error("--ros-args: malformed rule {0:?} (expected NAME:=VALUE)")]
    MalformedRule(String),
    /// A name that is not a valid ROS name.
    #[error("invalid ROS name {name:?}: {reason}")]
    InvalidName {
        /// The name.
        name: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A parameter value that is not a ROS parameter type.
    #[error("parameter {name:?}: {reason}")]
    BadValue {
        /// Parameter name.
        name: String,
        /// What is wrong.
        reason: String,
    },
    /// A parameter file that cannot be read.
    #[error("cannot read parameter file {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The error.
        source: std::io::Error,
    },
    /// A parameter file that is not ROS parameter YAML.
    #[error("parameter file {path}: {reason}")]
    ParamsFile {
        /// The file (or `<string>`).
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// The parameters do not fit the node's typed parameter struct: the parameter (its dotted
    /// path) and why.
    #[error("parameters: {}{source}", if path == "." { String::new() } else { format!("{path}: ") })]
    Deserialize {
        /// The parameter, e.g. `command.fallback` (`.` when the whole set is refused).
        path: String,
        /// serde's reason ("unknown variant `brake`, expected one of …").
        source: serde_yaml::Error,
    },
}

/// One `-r [NODE:]FROM:=TO` rule.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RemapRule {
    /// Only for this node name (the `NODE:` prefix), if given.
    pub node: Option<String>,
    /// Name to replace (relative names are relative to the node's namespace).
    pub from: String,
    /// Replacement.
    pub to: String,
}

/// One `-p [NODE:]NAME:=VALUE` override.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamOverride {
    /// Only for this node name (the `NODE:` prefix), if given.
    pub node: Option<String>,
    /// Parameter name (dotted for nested keys).
    pub name: String,
    /// The value.
    pub value: ParameterValue,
}

/// The parsed command line: ROS arguments and the user's own arguments.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RosArgs {
    /// Arguments outside `--ros-args` sections, in order (program name excluded).
    pub user_args: Vec<String>,
    /// `-r __node:=NAME` (last one wins).
    pub node_name: Option<String>,
    /// `-r __ns:=/NS` (last one wins), normalised to start with `/`.
    pub namespace: Option<String>,
    /// Topic/service remapping rules, in command-line order.
    pub remaps: Vec<RemapRule>,
    /// `--params-file` files, in command-line order.
    pub params_files: Vec<PathBuf>,
    /// `-p` overrides, in command-line order.
    pub params: Vec<ParamOverride>,
    /// `--log-level` values (`LEVEL` or `LOGGER:=LEVEL`).
    pub log_levels: Vec<String>,
    /// Other accepted flags that the nodes do not act on (`-e`, `--enable-rosout-logs`, ...).
    pub ignored: Vec<String>,
}

impl RosArgs {
    /// Parses `std::env::args()` (skipping the program name).
    pub fn from_env() -> Result<Self, RosArgsError> {
        Self::parse(std::env::args().skip(1))
    }

    /// Parses arguments (without the program name).
    pub fn parse<I, S>(args: I) -> Result<Self, RosArgsError>
    where
        I: IntoIterator<Item = S>,
        S: Into<String>,
    {
        let mut out = RosArgs::default();
        let mut it = args.into_iter().map(Into::into);
        let mut in_ros = false;
        while let Some(arg) = it.next() {
            if arg == "--ros-args" {
                in_ros = true;
                continue;
            }
            if !in_ros {
                out.user_args.push(arg);
                continue;
            }
            let mut value = |flag: &str| {
                it.next()
                    .ok_or_else(|| RosArgsError::MissingValue(flag.to_string()))
            };
            match arg.as_str() {
                "--" => in_ros = false,
                "-p" | "--param" => {
                    let rule = value(&arg)?;
                    out.params.push(parse_param_rule(&rule)?);
                }
                "--params-file" => out.params_files.push(PathBuf::from(value(&arg)?)),
                "-r" | "--remap" => {
                    let rule = value(&arg)?;
                    out.add_remap(&rule)?;
                }
                "--log-level" => out.log_levels.push(value(&arg)?),
                "-e" | "--enclave" | "--log-config-file" => {
                    let v = value(&arg)?;
                    out.ignored.push(format!("{arg} {v}"));
                }
                "--enable-rosout-logs"
                | "--disable-rosout-logs"
                | "--enable-stdout-logs"
                | "--disable-stdout-logs"
                | "--enable-external-lib-logs"
                | "--disable-external-lib-logs" => out.ignored.push(arg),
                _ => return Err(RosArgsError::UnknownArgument(arg)),
            }
        }
        Ok(out)
    }

    fn add_remap(&mut self, rule: &str) -> Result<(), RosArgsError> {
        let (lhs, to) = split_rule(rule)?;
        let (node, from) = split_node_prefix(lhs);
        match from {
            "__node" | "__name" => {
                if node.is_none() {
                    validate_node_name(to)?;
                    self.node_name = Some(to.to_string());
                }
            }
            "__ns" => {
                if node.is_none() {
                    let ns = if to.starts_with('/') {
                        to.to_string()
                    } else {
                        format!("/{to}")
                    };
                    validate_namespace(&ns)?;
                    self.namespace = Some(ns);
                }
            }
            _ => self.remaps.push(RemapRule {
                node: node.map(str::to_string),
                from: from.to_string(),
                to: to.to_string(),
            }),
        }
        Ok(())
    }

    /// The node name: `-r __node:=` if given, else `default`.
    pub fn node_name_or<'a>(&'a self, default: &'a str) -> &'a str {
        self.node_name.as_deref().unwrap_or(default)
    }

    /// The namespace: `-r __ns:=` if given, else `default` (e.g. `"/"`).
    pub fn namespace_or<'a>(&'a self, default: &'a str) -> &'a str {
        self.namespace.as_deref().unwrap_or(default)
    }

    /// Fully resolves a topic or service `name` of the node `node_name` in
    /// `namespace` (`~/x`, relative and absolute names), then applies the first
    /// matching remapping rule. Returns an absolute name.
    pub fn resolve_topic(&self, namespace: &str, node_name: &str, name: &str) -> String {
        let full = expand_name(namespace, node_name, name);
        for rule in &self.remaps {
            if rule.node.as_deref().is_some_and(|n| n != node_name) {
                continue;
            }
            if expand_name(namespace, node_name, &rule.from) == full {
                return expand_name(namespace, node_name, &rule.to);
            }
        }
        full
    }

    /// The parameters of the node with fully qualified name `node_fqn`
    /// (e.g. `/robot/constraint_dynamics`): files, then `-p` overrides.
    pub fn parameters(&self, node_fqn: &str) -> Result<Parameters, RosArgsError> {
        let mut params = Parameters::default();
        for file in &self.params_files {
            params.merge(load_params_file(file, node_fqn)?);
        }
        let node_name = node_fqn.rsplit('/').next().unwrap_or(node_fqn);
        for p in &self.params {
            match p.node.as_deref() {
                None => params.set(p.name.clone(), p.value.clone(), true),
                Some(n) if n == node_name || n == node_fqn => {
                    params.set(p.name.clone(), p.value.clone(), false)
                }
                Some(_) => {}
            }
        }
        Ok(params)
    }
}

fn split_rule(rule: &str) -> Result<(&str, &str), RosArgsError> {
    match rule.split_once(":=") {
        Some((l, r)) if !l.is_empty() => Ok((l, r)),
        _ => Err(RosArgsError::MalformedRule(rule.to_string())),
    }
}

/// `node:name` → (Some(node), name); a `:` inside `~/`... is not expected in ROS names.
fn split_node_prefix(lhs: &str) -> (Option<&str>, &str) {
    match lhs.split_once(':') {
        Some((node, name)) if !node.is_empty() => (Some(node), name),
        _ => (None, lhs),
    }
}

fn parse_param_rule(rule: &str) -> Result<ParamOverride, RosArgsError> {
    let (lhs, text) = split_rule(rule)?;
    let (node, name) = split_node_prefix(lhs);
    if text.is_empty() {
        return Err(RosArgsError::MalformedRule(rule.to_string()));
    }
    let yaml: Value =
        serde_yaml::from_str(text).unwrap_or_else(|_| Value::String(text.to_string()));
    let value = yaml_to_param(name, &yaml)?;
    Ok(ParamOverride {
        node: node.map(str::to_string),
        name: name.to_string(),
        value,
    })
}

fn validate_node_name(name: &str) -> Result<(), RosArgsError> {
    let bad = |reason: &str| {
        Err(RosArgsError::InvalidName {
            name: name.to_string(),
            reason: reason.to_string(),
        })
    };
    if name.is_empty() {
        return bad("empty");
    }
    if name.starts_with(|c: char| c.is_ascii_digit()) {
        return bad("starts with a digit");
    }
    if !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
        return bad("only letters, digits and _ are allowed");
    }
    Ok(())
}

fn validate_namespace(ns: &str) -> Result<(), RosArgsError> {
    if ns == "/" {
        return Ok(());
    }
    if ns.ends_with('/') {
        return Err(RosArgsError::InvalidName {
            name: ns.to_string(),
            reason: "ends with /".into(),
        });
    }
    for token in ns[1..].split('/') {
        validate_node_name(token).map_err(|_| RosArgsError::InvalidName {
            name: ns.to_string(),
            reason: format!("bad token {token:?}"),
        })?;
    }
    Ok(())
}

/// Expands a topic/service name to an absolute one: `/a` stays, `a` becomes
/// `NS/a`, `~` and `~/a` become `NS/NODE` and `NS/NODE/a`.
pub fn expand_name(namespace: &str, node_name: &str, name: &str) -> String {
    let ns = namespace.trim_end_matches('/');
    if name.starts_with('/') {
        name.to_string()
    } else if name == "~" {
        format!("{ns}/{node_name}")
    } else if let Some(rest) = name.strip_prefix("~/") {
        format!("{ns}/{node_name}/{rest}")
    } else {
        format!("{ns}/{name}")
    }
}

#[cfg(test)]
mod tests;
