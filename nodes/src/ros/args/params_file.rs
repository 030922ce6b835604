//! ROS parameter files (`node: ros__parameters: {...}`, `/**` wildcards) and the typed
//! values they hold; the rules are in the parent module's documentation.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use ros2_client::ParameterValue;
use serde::de::DeserializeOwned;
use serde_yaml::Value;

use super::RosArgsError;

/// Node parameters: dotted name → value, sorted by name.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Parameters {
    /// The values.
    pub values: BTreeMap<String, ParameterValue>,
    /// The names set only for every node: by wildcard sections (`/**`, `/ns/*`) and `-p`
    /// without a node name. As in rclcpp, a node ignores such a parameter when it does not
    /// have it; a name its own section or `-p NODE:NAME` sets is its own (see
    /// [`Parameters::drop_shared`]).
    pub shared: BTreeSet<String>,
}

impl Parameters {
    /// Sets `name`; `shared` when the source addresses every node (a wildcard section, `-p`
    /// without a node name). A name once set by the node's own source stays its own.
    pub fn set(&mut self, name: String, value: ParameterValue, shared: bool) {
        let own = self.values.contains_key(&name) && !self.shared.contains(&name);
        if shared && !own {
            self.shared.insert(name.clone());
        } else {
            self.shared.remove(&name);
        }
        self.values.insert(name, value);
    }

    /// Overlays `other` on `self` (`other` wins).
    pub fn merge(&mut self, other: Parameters) {
        for (name, value) in other.values {
            let shared = other.shared.contains(&name);
            self.set(name, value, shared);
        }
    }

    /// Removes the shared names (set for every node) for which `has` is false, and returns
    /// them: a node ignores the parameters of other nodes given to all (rclcpp ignores
    /// overrides a node does not declare). Its own names stay, so a misspelt one is refused.
    pub fn drop_shared(&mut self, has: impl Fn(&str) -> bool) -> Vec<String> {
        let foreign: Vec<String> = self.shared.iter().filter(|n| !has(n)).cloned().collect();
        for name in &foreign {
            self.values.remove(name);
            self.shared.remove(name);
        }
        foreign
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
        Self::deserialize_value(self.to_yaml())
    }

    /// A typed struct from part of [`Parameters::to_yaml`]'s mapping.
    pub fn deserialize_value<T: DeserializeOwned>(v: Value) -> Result<T, RosArgsError> {
        serde_path_to_error::deserialize(v).map_err(|e| RosArgsError::Deserialize {
            path: e.path().to_string(),
            source: e.into_inner(),
        })
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
        Value::Mapping(m) => collect_sections(m, "", &mut sections)?,
        _ => return Err(file_err("top level must be a mapping of node names".into())),
    }
    // Wildcard sections first, node-specific ones after, so node-specific wins;
    // file order is kept within each group.
    let mut params = Parameters::default();
    for wildcard in [true, false] {
        for (key, body) in &sections {
            if key.contains('*') == wildcard && node_key_matches(key, node_fqn) {
                let mut section = BTreeMap::new();
                flatten_params(body, "", &mut section)?;
                for (name, value) in section {
                    params.set(name, value, wildcard);
                }
            }
        }
    }
    Ok(params)
}

/// A malformed node section of parameter YAML given as text.
fn section_error(reason: String) -> RosArgsError {
    RosArgsError::ParamsFile {
        path: PathBuf::from("<string>"),
        reason,
    }
}

fn collect_sections<'a>(
    map: &'a serde_yaml::Mapping,
    prefix: &str,
    out: &mut Vec<(String, &'a Value)>,
) -> Result<(), RosArgsError> {
    for (k, v) in map {
        let key = k
            .as_str()
            .ok_or_else(|| section_error(format!("node key {k:?} is not a string")))?;
        if key == "ros__parameters" {
            if prefix.is_empty() {
                return Err(section_error(
                    "ros__parameters at top level: it must be under a node name".into(),
                ));
            }
            let body = match v {
                Value::Mapping(_) | Value::Null => v,
                _ => {
                    return Err(section_error(format!(
                        "{prefix}: ros__parameters must be a mapping"
                    )));
                }
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
                return Err(section_error(format!(
                    "{name}: expected ros__parameters or a nested node name"
                )));
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
