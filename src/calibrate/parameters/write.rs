//! Where each fitted value goes in a scene's YAML (the user's other keys kept as they are).

use super::{FitParameter, LATERAL_FRICTION, SceneParameters, number, tyres_mut};
use serde_yaml::Value;

impl SceneParameters {
    /// Writes `value` of `p` into `scene`.
    pub fn set(&self, scene: &mut Value, p: FitParameter, value: f64) {
        match p {
            FitParameter::TyreSlipSpeed => {
                for t in tyres_mut(scene) {
                    put(t, "slip_speed_scale", value.max(1e-6));
                }
            }
            FitParameter::LateralCreep => self.set_lateral_creep(scene, value),
            FitParameter::RollingRadius
            | FitParameter::TrackOffset
            | FitParameter::TrackTurnGain => {
                if p == FitParameter::RollingRadius {
                    for (i, t) in tyres_mut(scene).iter_mut().enumerate() {
                        if self.tyres.0.contains(&i) {
                            put(t, "radius", value.max(1e-6));
                        }
                    }
                }
                let Some(cs) = scene
                    .get_mut("constraints")
                    .and_then(Value::as_sequence_mut)
                else {
                    return;
                };
                for (i, sign) in &self.rolling {
                    match p {
                        FitParameter::RollingRadius => put(&mut cs[*i], "radius", value),
                        FitParameter::TrackTurnGain => {
                            put(&mut cs[*i], "axle_offset_turn_gain", sign * value)
                        }
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
                put_drive(scene, "traction_torque", value.max(1e-6));
            }
            FitParameter::TractionLoadTransfer => {
                put_drive(scene, "traction_load_transfer", value.max(0.0));
            }
            FitParameter::CommandLag => put_drive(scene, "command_lag", value.max(0.0)),
        }
    }

    /// Leaves every rolling contact's sideways grip to a tyre creeping at `creep` [(m/s)/N]
    /// (none at 0 or below: the contacts stay rigid).
    fn set_lateral_creep(&self, scene: &mut Value, creep: f64) {
        if creep <= 0.0 {
            return;
        }
        let mut added = Vec::new();
        if let Some(cs) = scene
            .get_mut("constraints")
            .and_then(Value::as_sequence_mut)
        {
            for (i, _) in &self.rolling {
                let c = &mut cs[*i];
                let mu = number(c.get("friction")).unwrap_or(LATERAL_FRICTION);
                let mut t = serde_yaml::Mapping::new();
                for key in ["wheel", "axis", "radius", "plane_normal", "plane_height"] {
                    if let Some(v) = c.get(key) {
                        t.insert(key.into(), v.clone());
                    }
                }
                t.insert("friction".into(), mu.into());
                t.insert("normal_force".into(), self.weight_share.into());
                t.insert(
                    "slip_speed_scale".into(),
                    (creep * mu * self.weight_share).into(),
                );
                added.push(Value::Mapping(t));
                if let Some(m) = c.as_mapping_mut() {
                    m.insert("lateral".into(), "tyre".into());
                }
            }
        }
        let Some(root) = scene.as_mapping_mut() else {
            return;
        };
        let forces = root
            .entry("forces".into())
            .or_insert_with(|| Value::Mapping(Default::default()));
        if let Some(f) = forces.as_mapping_mut() {
            f.insert("tyres".into(), Value::Sequence(added));
        }
    }

    /// Writes `uncertainty.<field>: σ` (`effort_noise` [(N·m)/√Hz]) for every wheel joint,
    /// keeping the scene's other entries.
    pub fn set_wheel_noise(&self, scene: &mut Value, field: &str, sigma: f64) {
        set_noise(scene, field, &self.wheel_joints, sigma);
    }

    /// Writes `uncertainty.slip_noise: σ_s` [rad/√s] on the base's yaw, if the base has one.
    pub fn set_yaw_slip(&self, scene: &mut Value, sigma: f64) {
        set_noise(scene, "slip_noise", self.base_yaw.as_slice(), sigma);
    }

    /// Writes `uncertainty.saturation_slip: σ_k` [m/s] on the base's two horizontal
    /// translations, if the base has them.
    pub fn set_skid_slide(&self, scene: &mut Value, sigma: f64) {
        set_noise(scene, "saturation_slip", &self.base_horizontal, sigma);
    }

    /// Writes `uncertainty.saturation_slip: σ_t` [rad/s] on the base's yaw, if the base has
    /// one: the skid's turn, beside its slide.
    pub fn set_skid_turn(&self, scene: &mut Value, sigma: f64) {
        set_noise(scene, "saturation_slip", self.base_yaw.as_slice(), sigma);
    }
}

/// Writes `uncertainty.<field>.<coordinate>: σ` for each of `coordinates`, keeping the scene's
/// other entries.
fn set_noise(scene: &mut Value, field: &str, coordinates: &[String], sigma: f64) {
    let Some(root) = scene.as_mapping_mut().filter(|_| !coordinates.is_empty()) else {
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
        .entry(field.into())
        .or_insert_with(|| Value::Mapping(Default::default()));
    if !noise.is_mapping() {
        *noise = Value::Mapping(Default::default());
    }
    if let Some(noise) = noise.as_mapping_mut() {
        for c in coordinates {
            noise.insert(c.clone().into(), sigma.into());
        }
    }
}

/// `actuators.diff_drive.KEY: value`, where the scene has a diff drive.
fn put_drive(scene: &mut Value, key: &str, value: f64) {
    let drive = (scene.get_mut("actuators")).and_then(|a| a.get_mut("diff_drive"));
    if let Some(d) = drive {
        put(d, key, value);
    }
}

/// `key: x` in the mapping `map` (nothing where it is not a mapping).
fn put(map: &mut Value, key: &str, x: f64) {
    if let Some(m) = map.as_mapping_mut() {
        m.insert(Value::from(key), Value::from(x));
    }
}
