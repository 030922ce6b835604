//! `actuators:` as a scene declares it (validated into [`super::Actuators`]).

use serde::Deserialize;

/// `actuators:` in a scene.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ActuatorsSpec {
    /// `velocity:` PI joint velocity controllers (default none).
    #[serde(default)]
    pub velocity: Vec<VelocityControllerSpec>,
    /// `position:` PD joint position controllers (default none).
    #[serde(default)]
    pub position: Vec<PositionControllerSpec>,
    /// `diff_drive:` differential drive over two wheel joints (default none).
    #[serde(default)]
    pub diff_drive: Option<DiffDriveSpec>,
    /// Control period [s]; default [`DEFAULT_CONTROL_PERIOD`].
    #[serde(default)]
    pub control_period: Option<f64>,
    /// How the torques are held between control ticks (module doc); default `zero_order`.
    #[serde(default)]
    pub hold: Hold,
}

/// `actuators.hold:` the controllers' model in time (module doc).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Hold {
    /// Torques computed every control period and held (a digital controller).
    #[default]
    ZeroOrder,
    /// Torques evaluated at every stage from (t, q, v): no control ticks.
    Continuous,
}

/// The control period of a scene's controllers when `actuators.control_period` is not given [s].
pub const DEFAULT_CONTROL_PERIOD: f64 = 0.001;

impl ActuatorsSpec {
    /// True when the scene declares a controller.
    pub fn is_empty(&self) -> bool {
        self.velocity.is_empty() && self.position.is_empty() && self.diff_drive.is_none()
    }

    /// The period [s] at which the controllers' torques are recomputed and held, None without
    /// controllers or with continuous ones (a prediction then has no control ticks).
    pub fn control_period_s(&self) -> Option<f64> {
        (!self.is_empty() && self.hold == Hold::ZeroOrder)
            .then(|| self.control_period.unwrap_or(DEFAULT_CONTROL_PERIOD))
    }
}

/// τ = kp (v* − v) + ki ∫(v* − v) dt, clamped to ±effort (no integration while clamped).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VelocityControllerSpec {
    /// `joint:` URDF name of the 1-DOF joint driven; required.
    pub joint: String,
    /// kp [N·m·s/rad or N·s/m].
    pub kp: f64,
    /// ki [N·m/rad or N/m].
    #[serde(default)]
    pub ki: f64,
}

/// τ = kp (q* − q) − kd v, clamped to ±effort.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PositionControllerSpec {
    /// `joint:` URDF name of the 1-DOF joint driven; required.
    pub joint: String,
    /// kp [N·m/rad or N/m].
    pub kp: f64,
    /// kd [N·m·s/rad or N·s/m].
    #[serde(default)]
    pub kd: f64,
}

/// Differential drive: ω_l = (v − ω b/2)/r, ω_r = (v + ω b/2)/r, each tracked by a PI.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DiffDriveSpec {
    /// `left_joint:` URDF name of the left wheel joint; required.
    pub left_joint: String,
    /// `right_joint:` URDF name of the right wheel joint; required.
    pub right_joint: String,
    /// r [m].
    pub wheel_radius: f64,
    /// b, distance between the wheel contact points [m].
    pub wheel_separation: f64,
    /// `kp:` wheel-speed PI proportional gain [N·m·s/rad]; required.
    pub kp: f64,
    /// `ki:` wheel-speed PI integral gain [N·m/rad] (default 0).
    #[serde(default)]
    pub ki: f64,
    /// `traction_torque:` the largest wheel torque the floor takes before the tyre skids
    /// [N·m], μ N r; each wheel's torque is clamped to the lesser of it and the URDF effort
    /// (default: the URDF effort alone). A skidding tyre passes μ N to the floor whatever the
    /// motor gives, so the base accelerates as under this clamp (docs/contacts.md).
    #[serde(default)]
    pub traction_torque: Option<f64>,
    /// `traction_load_transfer:` κ ≥ 0 (default 0; needs `traction_torque`): the traction lost
    /// per newton-metre of the wheels' mean torque τ_c. A common-mode torque accelerates the
    /// base and pitches it onto its caster or skid, which take weight off the wheels; each
    /// wheel's clamp is then T − κ |τ_c| (κ ≈ μ h / L for a centre of mass h above the floor and
    /// a support L from the axle), while a pure turn keeps T (docs/contacts.md).
    #[serde(default)]
    pub traction_load_transfer: Option<f64>,
    /// `command_lag:` τ [s] ≥ 0 (default none): the drive follows its commanded (v, ω) through
    /// a first-order lag of time constant τ before the wheel controllers see it — a motor
    /// controller's own velocity loop or a drive's smoothing the scene does not model
    /// (docs/propagation.md); below 1 µs it is none.
    #[serde(default)]
    pub command_lag: Option<f64>,
}
