//! What `calibrate` can fit, and where each value goes in a scene file. A fitted value is
//! written into the scene's YAML (a `serde_yaml::Value`), so the calibrated scene keeps every
//! other key of the user's file as it was.

use crate::Model;
use crate::algorithm::Data;
use crate::algorithm::{forward_kinematics_pos, frame_placement};
use serde_yaml::Value;

/// A quantity of the robot a recorded drive can determine.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum FitParameter {
    /// Every rolling contact's `radius:` [m], one shared value: the effective rolling radius
    /// (worn or soft tyres roll on less than their nominal radius).
    RollingRadius,
    /// Every rolling contact's `axle_offset:` [m], outward from the robot's middle: the
    /// effective half-track minus the nominal one (a scrubbing tyre turns the robot as if its
    /// track were wider).
    TrackOffset,
    /// A payload [kg] on the base link at the base's centre of mass: a chassis heavier than its
    /// URDF says. Only for a scene without its own `payload:`.
    BaseMass,
    /// Every `forces.turning_resistance` entry's `friction:` (μ, one shared value). Only for a
    /// scene that declares turning resistance.
    TurningFriction,
    /// The diff drive's `traction_torque:` [N·m]: the wheel torque at which the tyres skid.
    /// Only a drive that reaches it determines it.
    TractionTorque,
}

impl FitParameter {
    /// Every parameter, in the order the output lists them.
    pub const ALL: [FitParameter; 5] = [
        FitParameter::RollingRadius,
        FitParameter::TrackOffset,
        FitParameter::BaseMass,
        FitParameter::TurningFriction,
        FitParameter::TractionTorque,
    ];

    /// The name `--fit` takes and the output prints.
    pub fn name(self) -> &'static str {
        match self {
            FitParameter::RollingRadius => "rolling_radius",
            FitParameter::TrackOffset => "track_offset",
            FitParameter::BaseMass => "base_mass",
            FitParameter::TurningFriction => "turning_friction",
            FitParameter::TractionTorque => "traction_torque",
        }
    }

    /// Its unit.
    pub fn unit(self) -> &'static str {
        match self {
            FitParameter::RollingRadius | FitParameter::TrackOffset => "m",
            FitParameter::BaseMass => "kg",
            FitParameter::TurningFriction => "1",
            FitParameter::TractionTorque => "N·m",
        }
    }

    /// The parameter named `name`; the error lists the known names.
    pub fn parse(name: &str) -> Result<FitParameter, String> {
        Self::ALL
            .into_iter()
            .find(|p| p.name() == name)
            .ok_or_else(|| {
                let known: Vec<&str> = Self::ALL.iter().map(|p| p.name()).collect();
                format!(
                    "unknown fit parameter '{name}' (known: {})",
                    known.join(", ")
                )
            })
    }
}

/// Where the parameters of one scene go, found once from the scene and its model.
#[derive(Clone, Debug)]
pub struct SceneParameters {
    /// Indices of the rolling contacts in `constraints:`, with the sign that makes a positive
    /// track offset point away from the robot's middle.
    rolling: Vec<(usize, f64)>,
    /// The base link's name and its centre of mass in it [m].
    base: (String, [f64; 3]),
    /// The joints the rolling contacts' wheels turn on.
    wheel_joints: Vec<String>,
    /// How many `forces.turning_resistance` entries the scene declares.
    turning: usize,
    /// The diff drive's wheel torque clamp [N·m]: its `traction_torque:`, else the wheels'
    /// least URDF effort (infinite where the URDF gives none); `None` without a diff drive.
    traction: Option<f64>,
    has_payload: bool,
}

fn constraints(scene: &Value) -> &[Value] {
    scene
        .get("constraints")
        .and_then(Value::as_sequence)
        .map_or(&[], |s| s.as_slice())
}

fn number(v: Option<&Value>) -> Option<f64> {
    v.and_then(Value::as_f64)
}

impl SceneParameters {
    /// Reads where each parameter goes in `scene` (the scene file's YAML) for `model`, the
    /// model the scene builds.
    pub fn new(scene: &Value, model: &Model) -> Result<SceneParameters, String> {
        let mut data = Data::new(model);
        let q = model.neutral();
        forward_kinematics_pos(model, &mut data, &q);
        let mut wheels = Vec::new();
        let mut wheel_joints = Vec::new();
        for (i, c) in constraints(scene).iter().enumerate() {
            if c.get("kind").and_then(Value::as_str) != Some("rolling") {
                continue;
            }
            let wheel = c.get("wheel").and_then(Value::as_str).unwrap_or("");
            let frame = model
                .frame_id(wheel)
                .map_err(|e| format!("constraints[{i}].wheel: {e}"))?;
            let axis: Vec<f64> = (c.get("axis").and_then(Value::as_sequence))
                .map(|s| s.iter().filter_map(Value::as_f64).collect())
                .unwrap_or_default();
            if axis.len() != 3 {
                return Err(format!("constraints[{i}].axis: must be [x, y, z]"));
            }
            let m = frame_placement(model, &data, frame);
            let a = m.rotation * nalgebra::Vector3::new(axis[0], axis[1], axis[2]);
            wheels.push((i, m.translation, a));
            wheel_joints.push(model.bodies[model.frames[frame].body].joint.name.clone());
        }
        let middle = wheels
            .iter()
            .fold(nalgebra::Vector3::zeros(), |s, w| s + w.1)
            / (wheels.len().max(1) as f64);
        let rolling = wheels
            .iter()
            .map(|(i, p, a)| {
                (
                    *i,
                    if a.dot(&(p - middle)) >= 0.0 {
                        1.0
                    } else {
                        -1.0
                    },
                )
            })
            .collect();
        let base_body = (1..model.bodies.len())
            .find(|&b| model.bodies[b].parent == 0)
            .ok_or("the model has no body")?;
        let body = &model.bodies[base_body];
        let com = body.inertia.com;
        let turning = scene
            .get("forces")
            .and_then(|f| f.get("turning_resistance"))
            .and_then(Value::as_sequence)
            .map_or(0, |s| s.len());
        let drive = scene.get("actuators").and_then(|a| a.get("diff_drive"));
        let traction = drive.map(|d| {
            number(d.get("traction_torque")).unwrap_or_else(|| {
                ["left_joint", "right_joint"]
                    .iter()
                    .filter_map(|k| d.get(*k).and_then(Value::as_str))
                    .filter_map(|j| model.joint_body(j).ok())
                    .map(|b| model.limits.effort[model.bodies[b].joint.idx_v])
                    .fold(f64::INFINITY, f64::min)
            })
        });
        let has_payload =
            number(scene.get("payload").and_then(|p| p.get("mass"))).is_some_and(|m| m != 0.0);
        Ok(SceneParameters {
            rolling,
            wheel_joints,
            base: (body.name.clone(), [com.x, com.y, com.z]),
            turning,
            traction,
            has_payload,
        })
    }

    /// Why `p` cannot be fitted on this scene, if it cannot.
    pub fn unavailable(&self, p: FitParameter) -> Option<String> {
        match p {
            FitParameter::RollingRadius | FitParameter::TrackOffset if self.rolling.is_empty() => {
                Some("the scene has no rolling contact".into())
            }
            FitParameter::BaseMass if self.has_payload => {
                Some("the scene declares its own payload".into())
            }
            FitParameter::TurningFriction if self.turning == 0 => {
                Some("the scene declares no forces.turning_resistance".into())
            }
            FitParameter::TractionTorque => match self.traction {
                None => Some("the scene has no actuators.diff_drive".into()),
                Some(t) if !t.is_finite() => Some(
                    "the wheels have no effort limit: declare actuators.diff_drive.\
                     traction_torque to start from"
                        .into(),
                ),
                _ => None,
            },
            _ => None,
        }
    }

    /// The scene's own value of `p`: the first rolling contact's radius and offset (outward),
    /// the base payload's mass (0), the first turning-resistance entry's μ.
    pub fn value(&self, scene: &Value, p: FitParameter) -> f64 {
        let cs = constraints(scene);
        let first = self.rolling.first();
        match p {
            FitParameter::RollingRadius => first
                .and_then(|(i, _)| number(cs[*i].get("radius")))
                .unwrap_or(0.0),
            FitParameter::TrackOffset => first
                .map(|(i, s)| s * number(cs[*i].get("axle_offset")).unwrap_or(0.0))
                .unwrap_or(0.0),
            FitParameter::BaseMass => 0.0,
            FitParameter::TurningFriction => number(
                scene
                    .get("forces")
                    .and_then(|f| f.get("turning_resistance"))
                    .and_then(|t| t.get(0))
                    .and_then(|e| e.get("friction")),
            )
            .unwrap_or(0.0),
            FitParameter::TractionTorque => self.traction.unwrap_or(f64::INFINITY),
        }
    }

    /// Writes `value` of `p` into `scene`.
    pub fn set(&self, scene: &mut Value, p: FitParameter, value: f64) {
        let put = |map: &mut Value, key: &str, x: f64| {
            if let Some(m) = map.as_mapping_mut() {
                m.insert(Value::from(key), Value::from(x));
            }
        };
        match p {
            FitParameter::RollingRadius | FitParameter::TrackOffset => {
                let Some(cs) = scene
                    .get_mut("constraints")
                    .and_then(Value::as_sequence_mut)
                else {
                    return;
                };
                for (i, sign) in &self.rolling {
                    match p {
                        FitParameter::RollingRadius => put(&mut cs[*i], "radius", value),
                        _ => put(&mut cs[*i], "axle_offset", sign * value),
                    }
                }
            }
            FitParameter::BaseMass => {
                let mut payload = serde_yaml::Mapping::new();
                payload.insert("frame".into(), self.base.0.clone().into());
                payload.insert("mass".into(), value.max(0.0).into());
                payload.insert(
                    "com".into(),
                    Value::Sequence(self.base.1.iter().map(|&x| x.into()).collect()),
                );
                if let Some(m) = scene.as_mapping_mut() {
                    m.insert("payload".into(), Value::Mapping(payload));
                }
            }
            FitParameter::TurningFriction => {
                let entries = scene
                    .get_mut("forces")
                    .and_then(|f| f.get_mut("turning_resistance"))
                    .and_then(Value::as_sequence_mut);
                for e in entries.into_iter().flatten() {
                    put(e, "friction", value.max(0.0));
                }
            }
            FitParameter::TractionTorque => {
                let drive = scene
                    .get_mut("actuators")
                    .and_then(|a| a.get_mut("diff_drive"));
                if let Some(d) = drive {
                    put(d, "traction_torque", value.max(1e-6));
                }
            }
        }
    }

    /// The joints the rolling contacts' wheels turn on: where the process noise goes.
    pub fn wheel_joints(&self) -> &[String] {
        &self.wheel_joints
    }

    /// Writes `uncertainty.acceleration_noise: σ` [(rad/s²)/√Hz] for every wheel joint,
    /// keeping the scene's other entries.
    pub fn set_wheel_noise(&self, scene: &mut Value, sigma: f64) {
        let Some(root) = scene.as_mapping_mut() else {
            return;
        };
        let u = root
            .entry("uncertainty".into())
            .or_insert_with(|| Value::Mapping(Default::default()));
        if !u.is_mapping() {
            *u = Value::Mapping(Default::default());
        }
        let Some(u) = u.as_mapping_mut() else { return };
        let noise = u
            .entry("acceleration_noise".into())
            .or_insert_with(|| Value::Mapping(Default::default()));
        if !noise.is_mapping() {
            *noise = Value::Mapping(Default::default());
        }
        if let Some(noise) = noise.as_mapping_mut() {
            for j in &self.wheel_joints {
                noise.insert(j.clone().into(), sigma.into());
            }
        }
    }

    /// How far the parameter is moved to see its effect, and the size a change must reach to
    /// matter (the fit's parameter scaling): 1 mm of radius, 1 cm of track, a tenth of the
    /// robot's mass, 0.1 of μ, a tenth of the traction torque.
    pub fn scale(&self, p: FitParameter, model: &Model) -> f64 {
        match p {
            FitParameter::TractionTorque => 0.1 * self.traction.unwrap_or(1.0),
            FitParameter::RollingRadius => 1e-3,
            FitParameter::TrackOffset => 1e-2,
            FitParameter::BaseMass => 0.1 * model.total_mass(),
            FitParameter::TurningFriction => 0.1,
        }
    }
}
