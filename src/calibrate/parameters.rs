//! What `calibrate` can fit, and where each value goes in a scene file. A fitted value is
//! written into the scene's YAML (a `serde_yaml::Value`), so the calibrated scene keeps every
//! other key of the user's file as it was.

use crate::Model;
use crate::algorithm::Data;
use crate::algorithm::{forward_kinematics_pos, frame_placement};
use crate::model::base_covariance::rep103_indices;
use serde_yaml::Value;

/// A quantity of the robot a recorded drive can determine.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum FitParameter {
    /// Every rolling contact's and every wheel tyre's (`forces.tyres` with an `axis:`)
    /// `radius:` [m], one shared value: the effective rolling radius (worn or soft tyres roll
    /// on less than their nominal radius).
    RollingRadius,
    /// Every rolling contact's `axle_offset:` [m], outward from the robot's middle: the
    /// effective half-track minus the nominal one (a scrubbing tyre turns the robot as if its
    /// track were wider).
    TrackOffset,
    /// Every rolling contact's `axle_offset_turn_gain:` [m/(rad/s)²], outward: how much wider
    /// the effective track gets with the square of the turn rate (a wide tyre scrubs more in a
    /// fast turn). Only for a scene with drift control.
    TrackTurnGain,
    /// A payload [kg] on the base link at the base's centre of mass: a chassis heavier than its
    /// URDF says. Only for a scene without its own `payload:`.
    BaseMass,
    /// Every `forces.turning_resistance` entry's `friction:` (μ, one shared value). Only for a
    /// scene that declares turning resistance.
    TurningFriction,
    /// The diff drive's `traction_torque:` [N·m]: the wheel torque at which the tyres skid.
    /// Only a drive that reaches it determines it.
    TractionTorque,
    /// The diff drive's `traction_load_transfer:` κ (1): the traction the wheels lose per
    /// newton-metre of their mean torque as the base pitches onto its caster or skid. Only for
    /// a scene that declares one (its estimate, e.g. μ h/ℓ, is where the fit starts).
    TractionLoadTransfer,
    /// The diff drive's `command_lag:` τ [s]: how late the drive follows its commands (a motor
    /// controller's own velocity loop). Only for a scene that declares one (its estimate is
    /// where the fit starts).
    CommandLag,
    /// Every `forces.tyres` entry's `slip_speed_scale:` [m/s], one shared value: the slip
    /// speed below which a tyre creeps rather than skids (how soft its grip is).
    TyreSlipSpeed,
    /// The wheels' sideways creep [(m/s)/N], the slip speed per newton of sideways force: every
    /// rolling contact's sideways grip left to a tyre (`lateral: tyre`, with a `forces.tyres`
    /// entry on its wheel: its radius, μ its `friction:` or [`LATERAL_FRICTION`], N its share
    /// of the robot's weight, s₀ = c μ N). 0 is the rigid contact. Only for a scene with
    /// rolling contacts and no `forces.tyres` of its own (`tyre_slip_speed` fits those).
    LateralCreep,
}

/// μ of a sideways tyre `lateral_creep` adds to a rolling contact without a `friction:` (rubber
/// on a floor). Below the grip's limit only the creep c = s₀/(μ N) matters.
pub const LATERAL_FRICTION: f64 = 0.8;

impl FitParameter {
    /// Every parameter, in the order the output lists them.
    pub const ALL: [FitParameter; 10] = [
        FitParameter::RollingRadius,
        FitParameter::TrackOffset,
        FitParameter::TrackTurnGain,
        FitParameter::BaseMass,
        FitParameter::TurningFriction,
        FitParameter::TractionTorque,
        FitParameter::TractionLoadTransfer,
        FitParameter::CommandLag,
        FitParameter::TyreSlipSpeed,
        FitParameter::LateralCreep,
    ];

    /// The name `--fit` takes and the output prints.
    pub fn name(self) -> &'static str {
        match self {
            FitParameter::RollingRadius => "rolling_radius",
            FitParameter::TrackOffset => "track_offset",
            FitParameter::TrackTurnGain => "track_turn_gain",
            FitParameter::BaseMass => "base_mass",
            FitParameter::TurningFriction => "turning_friction",
            FitParameter::TractionTorque => "traction_torque",
            FitParameter::TractionLoadTransfer => "traction_load_transfer",
            FitParameter::CommandLag => "command_lag",
            FitParameter::TyreSlipSpeed => "tyre_slip_speed",
            FitParameter::LateralCreep => "lateral_creep",
        }
    }

    /// Its unit.
    pub fn unit(self) -> &'static str {
        match self {
            FitParameter::RollingRadius | FitParameter::TrackOffset => "m",
            FitParameter::TyreSlipSpeed => "m/s",
            FitParameter::LateralCreep => "m/(N·s)",
            FitParameter::TrackTurnGain => "m/(rad/s)²",
            FitParameter::BaseMass => "kg",
            FitParameter::TurningFriction | FitParameter::TractionLoadTransfer => "1",
            FitParameter::TractionTorque => "N·m",
            FitParameter::CommandLag => "s",
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
    /// Indices of the wheel tyres (with an axis) in `forces.tyres`, and how many tyres there
    /// are in all (balls included).
    tyres: (Vec<usize>, usize),
    /// The base link's name and its centre of mass in it [m].
    base: (String, [f64; 3]),
    /// The joints the rolling contacts' wheels turn on.
    wheel_joints: Vec<String>,
    /// The velocity coordinate of the base's yaw (a planar base's `wz`, a floating base's
    /// `wz_local`; `None` for a fixed base).
    base_yaw: Option<String>,
    /// The velocity coordinates of the base's two horizontal translations (REP-103's x and y,
    /// in the base's frame); empty for a fixed base.
    base_horizontal: Vec<String>,
    /// How many `forces.turning_resistance` entries the scene declares.
    turning: usize,
    /// The diff drive's wheel torque clamp [N·m]: its `traction_torque:`, else the wheels'
    /// least URDF effort (infinite where the URDF gives none); `None` without a diff drive.
    traction: Option<f64>,
    /// The diff drive's `traction_load_transfer:`, where it declares one.
    load_transfer: Option<f64>,
    /// The diff drive's `command_lag:` [s], where it declares one.
    command_lag: Option<f64>,
    has_payload: bool,
    /// The scene's `integration.drift` is `none`.
    no_drift_control: bool,
    /// A wheel tyre turns a wheel without a rolling contact (the tyre carries it).
    tyres_carry_wheels: bool,
    /// Each rolling contact's weight share N [N] (the robot's weight over the contacts).
    weight_share: f64,
}

fn constraints(scene: &Value) -> &[Value] {
    scene
        .get("constraints")
        .and_then(Value::as_sequence)
        .map_or(&[], |s| s.as_slice())
}

fn tyres(scene: &Value) -> &[Value] {
    scene
        .get("forces")
        .and_then(|f| f.get("tyres"))
        .and_then(Value::as_sequence)
        .map_or(&[], |s| s.as_slice())
}

/// `forces.tyres`' default `slip_speed_scale` [m/s] (forces/tyre.rs).
const DEFAULT_SLIP_SPEED: f64 = 0.01;

fn tyres_mut(scene: &mut Value) -> &mut [Value] {
    scene
        .get_mut("forces")
        .and_then(|f| f.get_mut("tyres"))
        .and_then(Value::as_sequence_mut)
        .map_or(&mut [], |s| s.as_mut_slice())
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
        let rolling_joints = wheel_joints.clone();
        let mut tyres_carry_wheels = false;
        let mut wheel_tyres = Vec::new();
        for (i, t) in tyres(scene).iter().enumerate() {
            if t.get("axis").is_none() {
                continue;
            }
            wheel_tyres.push(i);
            let wheel = t.get("wheel").and_then(Value::as_str).unwrap_or("");
            let frame = model
                .frame_id(wheel)
                .map_err(|e| format!("forces.tyres[{i}].wheel: {e}"))?;
            let joint = &model.bodies[model.frames[frame].body].joint.name;
            tyres_carry_wheels |= !rolling_joints.contains(joint);
            if !wheel_joints.contains(joint) {
                wheel_joints.push(joint.clone());
            }
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
        let load_transfer = number(drive.and_then(|d| d.get("traction_load_transfer")));
        let command_lag = number(drive.and_then(|d| d.get("command_lag")));
        let has_payload =
            number(scene.get("payload").and_then(|p| p.get("mass"))).is_some_and(|m| m != 0.0);
        let no_drift_control = scene
            .get("integration")
            .and_then(|i| i.get("drift"))
            .and_then(Value::as_str)
            == Some("none");
        let weight_share = model.total_mass() * model.gravity.norm() / (wheels.len().max(1) as f64);
        // The base's coordinates come first, yaw (REP-103's rz) last among them.
        let base_yaw =
            (rep103_indices(model.base).len().checked_sub(1)).map(|i| model.v_names[i].clone());
        // x and y come first where the base has them (a planar or a floating base).
        let base_horizontal = if rep103_indices(model.base).len() >= 3 {
            model.v_names[..2].to_vec()
        } else {
            Vec::new()
        };
        Ok(SceneParameters {
            base_yaw,
            base_horizontal,
            no_drift_control,
            tyres_carry_wheels,
            weight_share,
            rolling,
            tyres: (wheel_tyres, tyres(scene).len()),
            wheel_joints,
            base: (body.name.clone(), [com.x, com.y, com.z]),
            turning,
            traction,
            load_transfer,
            command_lag,
            has_payload,
        })
    }

    /// Every parameter this scene can take, in [`FitParameter::ALL`]'s order: what a fit
    /// asked for none fits (the CLI's `--fit default`).
    pub fn available(&self) -> Vec<FitParameter> {
        (FitParameter::ALL.into_iter())
            .filter(|p| self.unavailable(*p).is_none())
            .collect()
    }

    /// Why `p` cannot be fitted on this scene, if it cannot.
    pub fn unavailable(&self, p: FitParameter) -> Option<String> {
        match p {
            FitParameter::RollingRadius if self.rolling.is_empty() && self.tyres.0.is_empty() => {
                Some("the scene has no rolling contact nor wheel tyre".into())
            }
            FitParameter::TrackOffset | FitParameter::TrackTurnGain if self.rolling.is_empty() => {
                Some("the scene has no rolling contact".into())
            }
            FitParameter::TrackTurnGain if self.no_drift_control => Some(
                "the scene's integration.drift is none: a turn gain needs drift control".into(),
            ),
            FitParameter::TyreSlipSpeed if self.tyres.1 == 0 => {
                Some("the scene declares no forces.tyres".into())
            }
            FitParameter::LateralCreep if self.rolling.is_empty() => {
                Some("the scene has no rolling contact".into())
            }
            FitParameter::LateralCreep if self.tyres.1 > 0 => {
                Some("the scene declares forces.tyres: their softness is tyre_slip_speed".into())
            }
            FitParameter::BaseMass if self.has_payload => {
                Some("the scene declares its own payload".into())
            }
            FitParameter::TurningFriction if self.turning == 0 => {
                Some("the scene declares no forces.turning_resistance".into())
            }
            FitParameter::TractionLoadTransfer if self.load_transfer.is_none() => {
                Some("the scene declares no actuators.diff_drive.traction_load_transfer".into())
            }
            FitParameter::CommandLag if self.traction.is_none() => {
                Some("the scene has no actuators.diff_drive".into())
            }
            FitParameter::CommandLag if self.command_lag.is_none() => {
                Some("the scene declares no actuators.diff_drive.command_lag".into())
            }
            FitParameter::TractionTorque | FitParameter::TractionLoadTransfer => {
                match self.traction {
                    None => Some("the scene has no actuators.diff_drive".into()),
                    Some(t) if !t.is_finite() => Some(
                        "the wheels have no effort limit: declare actuators.diff_drive.\
                     traction_torque to start from"
                            .into(),
                    ),
                    _ => None,
                }
            }
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
                .or_else(|| {
                    let i = *self.tyres.0.first()?;
                    number(tyres(scene)[i].get("radius"))
                })
                .unwrap_or(0.0),
            FitParameter::TyreSlipSpeed => tyres(scene)
                .first()
                .and_then(|t| number(t.get("slip_speed_scale")))
                .unwrap_or(DEFAULT_SLIP_SPEED),
            FitParameter::TrackOffset => first
                .map(|(i, s)| s * number(cs[*i].get("axle_offset")).unwrap_or(0.0))
                .unwrap_or(0.0),
            FitParameter::TrackTurnGain => first
                .map(|(i, s)| s * number(cs[*i].get("axle_offset_turn_gain")).unwrap_or(0.0))
                .unwrap_or(0.0),
            FitParameter::BaseMass | FitParameter::LateralCreep => 0.0,
            FitParameter::TurningFriction => number(
                scene
                    .get("forces")
                    .and_then(|f| f.get("turning_resistance"))
                    .and_then(|t| t.get(0))
                    .and_then(|e| e.get("friction")),
            )
            .unwrap_or(0.0),
            FitParameter::TractionTorque => self.traction.unwrap_or(f64::INFINITY),
            FitParameter::TractionLoadTransfer => self.load_transfer.unwrap_or(0.0),
            FitParameter::CommandLag => self.command_lag.unwrap_or(0.0),
        }
    }

    /// The joints the rolling contacts' wheels turn on: where the process noise goes.
    pub fn wheel_joints(&self) -> &[String] {
        &self.wheel_joints
    }

    /// The velocity coordinate of the base's yaw, if the base has one.
    pub fn base_yaw(&self) -> Option<&str> {
        self.base_yaw.as_deref()
    }

    /// The velocity coordinates of the base's horizontal translations (none for a fixed base).
    pub fn base_horizontal(&self) -> &[String] {
        &self.base_horizontal
    }

    /// True when a tyre carries a wheel in place of a rolling contact (`forces.tyres`): its grip
    /// and the wheel's controller then reject noise on the wheels. A sideways tyre
    /// beside a rolling contact does not.
    pub fn tyres_carry_wheels(&self) -> bool {
        self.tyres_carry_wheels
    }

    /// How far the parameter is moved to see its effect, and the size a change must reach to
    /// matter (the fit's parameter scaling): 1 mm of radius, 1 cm of track (and of its widening
    /// at 1 rad/s), a tenth of the robot's mass, 0.1 of μ, a tenth of the traction torque, 0.1
    /// of its load transfer, 10 ms of command lag, 1 cm/s of slip speed, 1 mm/s of sideways
    /// creep per newton.
    pub fn scale(&self, p: FitParameter, model: &Model) -> f64 {
        match p {
            FitParameter::TractionTorque => 0.1 * self.traction.unwrap_or(1.0),
            FitParameter::RollingRadius => 1e-3,
            FitParameter::TrackOffset | FitParameter::TrackTurnGain => 1e-2,
            FitParameter::BaseMass => 0.1 * model.total_mass(),
            FitParameter::TurningFriction | FitParameter::TractionLoadTransfer => 0.1,
            FitParameter::TyreSlipSpeed | FitParameter::CommandLag => 0.01,
            // 1 mm/s of sideways slip under 1 N.
            FitParameter::LateralCreep => 1e-3,
        }
    }
}

mod write;

#[cfg(test)]
#[path = "parameters_tests.rs"]
mod tests;
