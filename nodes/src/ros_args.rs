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
//! Scalars follow the YAML 1.2 core schema of `serde_yaml` (`true`/`false`
//! are booleans; `yes`/`on` stay strings). An empty sequence becomes an
//! empty `StringArray`. Integers mixed with doubles in a sequence become doubles.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use ros2_client::ParameterValue;
use serde::de::DeserializeOwned;
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
    /// The parameters do not fit the node's typed parameter struct.
    #[error("parameters: {0}")]
    Deserialize(#[from] serde_yaml::Error),
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
            if p.node
                .as_deref()
                .is_none_or(|n| n == node_name || n == node_fqn)
            {
                params.values.insert(p.name.clone(), p.value.clone());
            }
        }
        Ok(params)
    }
}

/// Node parameters: dotted name → value, sorted by name.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Parameters {
    /// The values.
    pub values: BTreeMap<String, ParameterValue>,
}

impl Parameters {
    /// Overlays `other` on `self` (`other` wins).
    pub fn merge(&mut self, other: Parameters) {
        self.values.extend(other.values);
    }

    /// A value by dotted name.
    pub fn get(&self, name: &str) -> Option<&ParameterValue> {
        self.values.get(name)
    }

    /// The parameters as one YAML mapping, dotted names nested again
    /// (`solver.tolerance` → `{solver: {tolerance: ..}}`).
    pub fn to_yaml(&self) -> Value {
        let mut root = serde_yaml::Mapping::new();
        for (name, value) in &self.values {
            let mut map = &mut root;
            let mut parts = name.split('.').peekable();
            while let Some(part) = parts.next() {
                let key = Value::String(part.to_string());
                if parts.peek().is_none() {
                    map.insert(key, param_to_yaml(value));
                    break;
                }
                let entry = map
                    .entry(key)
                    .or_insert_with(|| Value::Mapping(serde_yaml::Mapping::new()));
                if !entry.is_mapping() {
                    // "a" and "a.b" both set: the nested one wins in the typed view.
                    *entry = Value::Mapping(serde_yaml::Mapping::new());
                }
                map = entry.as_mapping_mut().expect("just made a mapping");
            }
        }
        Value::Mapping(root)
    }

    /// Deserializes the parameters into a typed struct (use
    /// `#[serde(deny_unknown_fields)]` on it to refuse unknown keys, and
    /// `#[serde(default)]` for defaults).
    pub fn deserialize<T: DeserializeOwned>(&self) -> Result<T, RosArgsError> {
        Ok(serde_yaml::from_value(self.to_yaml())?)
    }
}

/// Reads a ROS parameter file and returns the parameters that apply to `node_fqn`.
pub fn load_params_file(path: &Path, node_fqn: &str) -> Result<Parameters, RosArgsError> {
    let text = std::fs::read_to_string(path).map_err(|source| RosArgsError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_params_yaml(&text, node_fqn).map_err(|e| match e {
        RosArgsError::ParamsFile { reason, .. } => RosArgsError::ParamsFile {
            path: path.to_path_buf(),
            reason,
        },
        other => other,
    })
}

/// Parses ROS parameter YAML text and returns the parameters that apply to `node_fqn`.
pub fn parse_params_yaml(text: &str, node_fqn: &str) -> Result<Parameters, RosArgsError> {
    let file_err = |reason: String| RosArgsError::ParamsFile {
        path: PathBuf::from("<string>"),
        reason,
    };
    let doc: Value = serde_yaml::from_str(text).map_err(|e| file_err(e.to_string()))?;
    let mut sections = Vec::new(); // (node key, its ros__parameters)
    match &doc {
        Value::Null => {}
        Value::Mapping(m) => collect_sections(m, "", &mut sections).map_err(file_err)?,
        _ => return Err(file_err("top level must be a mapping of node names".into())),
    }
    // Wildcard sections first, node-specific ones after, so node-specific wins;
    // file order is kept within each group.
    let mut params = Parameters::default();
    for wildcard in [true, false] {
        for (key, body) in &sections {
            if key.contains('*') == wildcard && node_key_matches(key, node_fqn) {
                flatten_params(body, "", &mut params.values)?;
            }
        }
    }
    Ok(params)
}

fn collect_sections<'a>(
    map: &'a serde_yaml::Mapping,
    prefix: &str,
    out: &mut Vec<(String, &'a Value)>,
) -> Result<(), String> {
    for (k, v) in map {
        let key = k
            .as_str()
            .ok_or_else(|| format!("node key {k:?} is not a string"))?;
        if key == "ros__parameters" {
            if prefix.is_empty() {
                return Err("ros__parameters at top level: it must be under a node name".into());
            }
            let body = match v {
                Value::Mapping(_) | Value::Null => v,
                _ => return Err(format!("{prefix}: ros__parameters must be a mapping")),
            };
            out.push((prefix.to_string(), body));
            continue;
        }
        let name = if prefix.is_empty() {
            if key.starts_with('/') {
                key.to_string()
            } else {
                format!("/{key}")
            }
        } else {
            format!(
                "{}/{}",
                prefix.trim_end_matches('/'),
                key.trim_start_matches('/')
            )
        };
        match v {
            Value::Mapping(m) => collect_sections(m, &name, out)?,
            _ => {
                return Err(format!(
                    "{name}: expected ros__parameters or a nested node name"
                ));
            }
        }
    }
    Ok(())
}

/// Whether a parameter-file node key (`/ns/node`, `/**`, `/**/node`, `/ns/*`)
/// matches a fully qualified node name.
pub fn node_key_matches(key: &str, node_fqn: &str) -> bool {
    let pat: Vec<&str> = key.split('/').filter(|s| !s.is_empty()).collect();
    let name: Vec<&str> = node_fqn.split('/').filter(|s| !s.is_empty()).collect();
    fn m(pat: &[&str], name: &[&str]) -> bool {
        match pat.split_first() {
            None => name.is_empty(),
            Some((&"**", rest)) => (0..=name.len()).any(|i| m(rest, &name[i..])),
            Some((p, rest)) => match name.split_first() {
                Some((n, nrest)) => (*p == "*" || p == n) && m(rest, nrest),
                None => false,
            },
        }
    }
    m(&pat, &name)
}

fn flatten_params(
    value: &Value,
    prefix: &str,
    out: &mut BTreeMap<String, ParameterValue>,
) -> Result<(), RosArgsError> {
    let Value::Mapping(map) = value else {
        return Ok(()); // `ros__parameters:` with nothing under it
    };
    for (k, v) in map {
        let key = match k {
            Value::String(s) => s.clone(),
            Value::Number(n) => n.to_string(),
            Value::Bool(b) => b.to_string(),
            _ => {
                return Err(RosArgsError::BadValue {
                    name: format!("{prefix}{k:?}"),
                    reason: "key is not a scalar".into(),
                });
            }
        };
        let name = if prefix.is_empty() {
            key
        } else {
            format!("{prefix}.{key}")
        };
        match v {
            Value::Mapping(_) => flatten_params(v, &name, out)?,
            _ => {
                let value = yaml_to_param(&name, v)?;
                out.insert(name, value);
            }
        }
    }
    Ok(())
}

/// Converts a YAML value to a ROS parameter value.
pub fn yaml_to_param(name: &str, v: &Value) -> Result<ParameterValue, RosArgsError> {
    let bad = |reason: &str| RosArgsError::BadValue {
        name: name.to_string(),
        reason: reason.to_string(),
    };
    Ok(match v {
        Value::Bool(b) => ParameterValue::Boolean(*b),
        Value::Number(n) => match n.as_i64() {
            Some(i) => ParameterValue::Integer(i),
            None if n.is_f64() => ParameterValue::Double(n.as_f64().unwrap_or(f64::NAN)),
            None => return Err(bad("integer out of the int64 range")),
        },
        Value::String(s) => ParameterValue::String(s.clone()),
        Value::Tagged(t) => yaml_to_param(name, &t.value)?,
        Value::Null => return Err(bad("empty value (null is not a ROS parameter type)")),
        Value::Mapping(_) => return Err(bad("a mapping is not a parameter value")),
        Value::Sequence(seq) => {
            if seq.is_empty() {
                ParameterValue::StringArray(Vec::new())
            } else if seq.iter().all(Value::is_bool) {
                ParameterValue::BooleanArray(seq.iter().filter_map(Value::as_bool).collect())
            } else if seq.iter().all(Value::is_i64) {
                ParameterValue::IntegerArray(seq.iter().filter_map(Value::as_i64).collect())
            } else if seq.iter().all(Value::is_number) {
                ParameterValue::DoubleArray(seq.iter().filter_map(Value::as_f64).collect())
            } else if seq.iter().all(Value::is_string) {
                ParameterValue::StringArray(
                    seq.iter()
                        .filter_map(|s| s.as_str().map(str::to_string))
                        .collect(),
                )
            } else {
                return Err(bad(
                    "array elements must all be bool, all numbers or all strings",
                ));
            }
        }
    })
}

/// Converts a ROS parameter value to YAML.
pub fn param_to_yaml(v: &ParameterValue) -> Value {
    fn seq<T: Into<Value> + Clone>(xs: &[T]) -> Value {
        Value::Sequence(xs.iter().cloned().map(Into::into).collect())
    }
    match v {
        ParameterValue::NotSet => Value::Null,
        ParameterValue::Boolean(b) => Value::Bool(*b),
        ParameterValue::Integer(i) => Value::from(*i),
        ParameterValue::Double(d) => Value::from(*d),
        ParameterValue::String(s) => Value::String(s.clone()),
        ParameterValue::ByteArray(b) => seq(b),
        ParameterValue::BooleanArray(b) => seq(b),
        ParameterValue::IntegerArray(i) => seq(i),
        ParameterValue::DoubleArray(d) => seq(d),
        ParameterValue::StringArray(s) => seq(s),
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
mod tests {
    use super::*;

    fn args(s: &str) -> Vec<String> {
        s.split_whitespace().map(str::to_string).collect()
    }

    #[test]
    fn parses_every_flag_and_keeps_user_args() {
        let a = RosArgs::parse(args(
            "model.urdf --ros-args --params-file a.yaml -p rate:=50.0 -p name:=wheelie \
             -r odom:=/robot/odom -r __node:=cd -r __ns:=robot --log-level debug -e /enc -- --verbose",
        ))
        .unwrap();
        assert_eq!(a.user_args, vec!["model.urdf", "--verbose"]);
        assert_eq!(a.params_files, vec![PathBuf::from("a.yaml")]);
        assert_eq!(a.params[0].value, ParameterValue::Double(50.0));
        assert_eq!(a.params[1].value, ParameterValue::String("wheelie".into()));
        assert_eq!(
            a.remaps,
            vec![RemapRule {
                node: None,
                from: "odom".into(),
                to: "/robot/odom".into()
            }]
        );
        assert_eq!(a.node_name.as_deref(), Some("cd"));
        assert_eq!(a.namespace.as_deref(), Some("/robot"));
        assert_eq!(a.log_levels, vec!["debug"]);
        assert_eq!(a.ignored, vec!["-e /enc"]);
    }

    #[test]
    fn several_ros_args_sections_and_long_forms() {
        let a = RosArgs::parse(args(
            "--ros-args --param a:=1 -- x --ros-args --remap __name:=n2",
        ))
        .unwrap();
        assert_eq!(a.user_args, vec!["x"]);
        assert_eq!(a.params[0].value, ParameterValue::Integer(1));
        assert_eq!(a.node_name.as_deref(), Some("n2"));
    }

    #[test]
    fn param_values_are_typed_like_yaml() {
        let a = RosArgs::parse(args(
            "--ros-args -p b:=true -p i:=-3 -p d:=1e-3 -p s:='x' -p da:=[1.0,2] -p ia:=[1,2] -p sa:=[a,b] -p ba:=[true,false]",
        ))
        .unwrap();
        let v: Vec<_> = a.params.iter().map(|p| p.value.clone()).collect();
        assert_eq!(
            v,
            vec![
                ParameterValue::Boolean(true),
                ParameterValue::Integer(-3),
                ParameterValue::Double(1e-3),
                ParameterValue::String("x".into()),
                ParameterValue::DoubleArray(vec![1.0, 2.0]),
                ParameterValue::IntegerArray(vec![1, 2]),
                ParameterValue::StringArray(vec!["a".into(), "b".into()]),
                ParameterValue::BooleanArray(vec![true, false]),
            ]
        );
    }

    #[test]
    fn errors_are_reported() {
        assert!(matches!(
            RosArgs::parse(args("--ros-args -p")),
            Err(RosArgsError::MissingValue(_))
        ));
        assert!(matches!(
            RosArgs::parse(args("--ros-args --bogus")),
            Err(RosArgsError::UnknownArgument(_))
        ));
        assert!(matches!(
            RosArgs::parse(args("--ros-args -p novalue")),
            Err(RosArgsError::MalformedRule(_))
        ));
        assert!(matches!(
            RosArgs::parse(args("--ros-args -r __node:=9x")),
            Err(RosArgsError::InvalidName { .. })
        ));
        assert!(matches!(
            RosArgs::parse(args("--ros-args -r __ns:=/a/")),
            Err(RosArgsError::InvalidName { .. })
        ));
        assert!(matches!(
            RosArgs::parse(args("--ros-args -p m:=[1,a]")),
            Err(RosArgsError::BadValue { .. })
        ));
        // Without --ros-args nothing is a ROS argument.
        assert_eq!(
            RosArgs::parse(args("-p x")).unwrap().user_args,
            vec!["-p", "x"]
        );
    }

    #[test]
    fn remapping_resolves_relative_private_and_node_scoped_rules() {
        let a = RosArgs::parse(args(
            "--ros-args -r cmd_vel:=/nav/cmd_vel -r other:~/x:=y -r /abs:=rel -r ~/priv:=/p",
        ))
        .unwrap();
        assert_eq!(a.resolve_topic("/robot", "cd", "cmd_vel"), "/nav/cmd_vel");
        assert_eq!(
            a.resolve_topic("/robot", "cd", "/robot/cmd_vel"),
            "/nav/cmd_vel"
        );
        assert_eq!(a.resolve_topic("/robot", "cd", "~/x"), "/robot/cd/x"); // rule is for node "other"
        assert_eq!(a.resolve_topic("/robot", "other", "~/x"), "/robot/y");
        assert_eq!(a.resolve_topic("/", "cd", "/abs"), "/rel");
        assert_eq!(a.resolve_topic("/", "cd", "~/priv"), "/p");
        assert_eq!(a.resolve_topic("/", "cd", "odom"), "/odom");
    }

    const FILE: &str = r#"
/**:
  ros__parameters:
    use_sim_time: false
    rate: 10.0
    solver: { tolerance: 1.0e-6 }
constraint_dynamics:
  ros__parameters:
    rate: 100.0
    frames: [odom, base_link]
    solver:
      tolerance: 1.0e-9
      max_iter: 50
/**/other:
  ros__parameters:
    rate: 1.0
robot:
  nested_node:
    ros__parameters:
      gains: [1, 2.5]
"#;

    #[test]
    fn params_file_node_specific_wins_over_wildcard() {
        let p = parse_params_yaml(FILE, "/constraint_dynamics").unwrap();
        assert_eq!(p.get("rate"), Some(&ParameterValue::Double(100.0)));
        assert_eq!(p.get("use_sim_time"), Some(&ParameterValue::Boolean(false)));
        assert_eq!(
            p.get("solver.tolerance"),
            Some(&ParameterValue::Double(1e-9))
        );
        assert_eq!(p.get("solver.max_iter"), Some(&ParameterValue::Integer(50)));
        assert_eq!(
            p.get("frames"),
            Some(&ParameterValue::StringArray(vec![
                "odom".into(),
                "base_link".into()
            ]))
        );
        // Specific-after-wildcard also when the wildcard comes later in the file.
        let reordered =
            "n:\n  ros__parameters:\n    a: 1\n/**:\n  ros__parameters:\n    a: 2\n    b: 3\n";
        let p = parse_params_yaml(reordered, "/n").unwrap();
        assert_eq!(p.get("a"), Some(&ParameterValue::Integer(1)));
        assert_eq!(p.get("b"), Some(&ParameterValue::Integer(3)));
    }

    #[test]
    fn params_file_namespaces_and_wildcards() {
        // A key without leading slash is in the root namespace, as in rclcpp.
        let p = parse_params_yaml(FILE, "/robot/constraint_dynamics").unwrap();
        assert_eq!(p.get("rate"), Some(&ParameterValue::Double(10.0)));
        let p = parse_params_yaml(FILE, "/a/b/other").unwrap();
        assert_eq!(p.get("rate"), Some(&ParameterValue::Double(1.0)));
        let p = parse_params_yaml(FILE, "/robot/nested_node").unwrap();
        assert_eq!(
            p.get("gains"),
            Some(&ParameterValue::DoubleArray(vec![1.0, 2.5]))
        );
        assert!(node_key_matches("/ns/*", "/ns/n"));
        assert!(!node_key_matches("/ns/*", "/ns/a/n"));
        assert!(node_key_matches("/**", "/"));
        assert!(!node_key_matches("/x", "/y"));
    }

    #[test]
    fn params_file_errors() {
        assert!(parse_params_yaml("ros__parameters: {a: 1}", "/n").is_err());
        assert!(parse_params_yaml("n: 3", "/n").is_err());
        assert!(parse_params_yaml("n:\n  ros__parameters:\n    a: ~\n", "/n").is_err());
        assert!(parse_params_yaml("", "/n").unwrap().values.is_empty());
    }

    #[test]
    fn files_then_overrides_and_typed_struct() {
        let dir = std::env::temp_dir().join(format!("cd_ros_args_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f1 = dir.join("a.yaml");
        let f2 = dir.join("b.yaml");
        std::fs::write(&f1, FILE).unwrap();
        std::fs::write(
            &f2,
            "constraint_dynamics:\n  ros__parameters:\n    rate: 200.0\n",
        )
        .unwrap();
        let a = RosArgs::parse(vec![
            "--ros-args".to_string(),
            "--params-file".into(),
            f1.display().to_string(),
            "--params-file".into(),
            f2.display().to_string(),
            "-p".into(),
            "solver.max_iter:=7".into(),
            "-p".into(),
            "someone_else:use_sim_time:=true".into(),
        ])
        .unwrap();
        let p = a.parameters("/constraint_dynamics").unwrap();
        assert_eq!(p.get("rate"), Some(&ParameterValue::Double(200.0)));
        assert_eq!(p.get("solver.max_iter"), Some(&ParameterValue::Integer(7)));
        assert_eq!(p.get("use_sim_time"), Some(&ParameterValue::Boolean(false)));

        #[derive(serde::Deserialize, Debug)]
        #[serde(deny_unknown_fields)]
        #[allow(dead_code)]
        struct Solver {
            tolerance: f64,
            max_iter: u32,
        }
        #[derive(serde::Deserialize, Debug)]
        #[serde(deny_unknown_fields)]
        #[allow(dead_code)]
        struct Params {
            rate: f64,
            use_sim_time: bool,
            frames: Vec<String>,
            solver: Solver,
        }
        let typed: Params = p.deserialize().unwrap();
        assert_eq!(typed.rate, 200.0);
        assert_eq!(typed.solver.max_iter, 7);
        assert_eq!(typed.solver.tolerance, 1e-9);

        #[derive(serde::Deserialize, Debug)]
        #[serde(deny_unknown_fields)]
        #[allow(dead_code)]
        struct Narrow {
            rate: f64,
        }
        let err = p.deserialize::<Narrow>().unwrap_err().to_string();
        assert!(err.contains("unknown field"), "{err}");

        let missing = RosArgs::parse(args("--ros-args --params-file /nonexistent/x.yaml")).unwrap();
        assert!(matches!(
            missing.parameters("/n"),
            Err(RosArgsError::Io { .. })
        ));
        std::fs::remove_dir_all(&dir).ok();
    }
}
