//! `payload.*`: a rigid payload the robot carries, changeable at run time (parameters or the
//! `~/set_payload` service). The model is rebuilt with it (`Model::with_payload`): predictions,
//! constraint forces, projections and limits all see it.

use constraint_dynamics::model::Payload;
use serde::{Deserialize, Serialize};

use super::ParamsError;

/// `payload.*`. With `frame` empty and `mass` 0 (the default) the scene's `payload:` is used;
/// with `frame` set this payload replaces it (`mass` 0 = none). Set `frame` before `mass`: a
/// mass on no frame is refused.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PayloadParams {
    /// Frame (URDF link) the payload is rigidly attached to; "" = the scene's payload.
    pub frame: String,
    /// Mass [kg] (≥ 0; 0 = none).
    pub mass: f64,
    /// Centre of mass in `frame`, `[x, y, z]` [m] (empty = the frame's origin).
    pub com: Vec<f64>,
    /// Rotational inertia about the centre of mass in `frame`'s axes,
    /// `[ixx, ixy, ixz, iyy, iyz, izz]` [kg·m²] (empty = a point mass).
    pub inertia: Vec<f64>,
}

impl Default for PayloadParams {
    fn default() -> Self {
        // Zeros, not empty lists: declared as double arrays, they take double arrays.
        PayloadParams {
            frame: String::new(),
            mass: 0.0,
            com: vec![0.0; 3],
            inertia: vec![0.0; 6],
        }
    }
}

impl PayloadParams {
    /// The payload these parameters ask for: `None` = the scene's; errors name the parameter.
    /// Every value is checked, also while `frame` is empty and the values unused: a value
    /// accepted now must not block a later set of another `payload.*` parameter.
    pub fn payload(&self) -> Result<Option<Payload>, ParamsError> {
        let com = fixed::<3>("payload.com", &self.com, "[x, y, z] [m]")?;
        let inertia = fixed::<6>(
            "payload.inertia",
            &self.inertia,
            "[ixx, ixy, ixz, iyy, iyz, izz] [kg·m²]",
        )?;
        let p = Payload {
            frame: self.frame.clone(),
            mass: self.mass,
            com,
            inertia,
        };
        p.validate().map_err(|e| {
            // The core's message starts with the field's dotted name, the parameter's name.
            let text = e.to_string();
            match text.split_once(": ") {
                Some((name, reason)) => ParamsError::invalid(name, format!("= {reason}")),
                None => ParamsError::invalid("payload", text),
            }
        })?;
        if self.frame.trim().is_empty() {
            if self.mass != 0.0 {
                return Err(ParamsError::invalid(
                    "payload.frame",
                    format!(
                        "is empty but payload.mass = {} kg: name the frame that carries the \
                         payload first (or set both in one request)",
                        self.mass
                    ),
                ));
            }
            return Ok(None);
        }
        Ok(Some(p))
    }

    /// Checks every value, naming the one that is wrong (the frame is checked against the
    /// model when the node is configured and on every run-time set).
    pub fn validate(&self) -> Result<(), ParamsError> {
        self.payload().map(|_| ())
    }
}

/// `values` as `[f64; N]`: empty is all zeros; another length is an error naming `name`.
fn fixed<const N: usize>(name: &str, values: &[f64], form: &str) -> Result<[f64; N], ParamsError> {
    let mut out = [0.0; N];
    match values.len() {
        0 => {}
        n if n == N => out.copy_from_slice(values),
        _ => {
            return Err(ParamsError::invalid(
                name,
                format!("= {values:?} must be {form} ({N} numbers)"),
            ));
        }
    }
    Ok(out)
}
