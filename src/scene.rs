//! The scene file (YAML): which URDF, the base, gravity, locked joints, a payload, the initial
//! state and the constraints. Unknown keys are an error that names the key.

use crate::actuators::Actuators;
use crate::actuators::ActuatorsSpec;
use crate::constraints::ConstraintSet;
use crate::constraints::ConstraintSpec;
use crate::dynamics::{Baumgarte, Formulation};
use crate::error::{Error, Result};
use crate::forces::ForceElements;
use crate::forces::ForcesSpec;
use crate::model::{BaseType, InertiaPolicy, Model, ModelOptions, Payload};
use crate::predict::{IntegrationSettings, PredictionBudget, Predictor};
use crate::system::{DynamicsOptions, System};
use nalgebra::Vector3;
use serde::Deserialize;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Initial state by coordinate name; missing coordinates are neutral (0, identity quaternion).
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InitialState {
    /// `q:` configuration coordinate name (`q_names`) → value [rad or m] (default: neutral).
    #[serde(default)]
    pub q: BTreeMap<String, f64>,
    /// `v:` velocity coordinate name (`v_names`) → value [rad/s or m/s] (default: 0).
    #[serde(default)]
    pub v: BTreeMap<String, f64>,
}

/// The scene file as written.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// URDF path, relative to the scene file.
    pub urdf: String,
    /// `base:` `fixed`, `planar` or `floating` attachment of the root link (default `fixed`).
    #[serde(default)]
    pub base: BaseType,
    /// Gravity, world axes [m/s²]; default (0, 0, −9.81).
    #[serde(default)]
    pub gravity: Option<[f64; 3]>,
    /// Joint name → position [rad or m].
    #[serde(default)]
    pub locked_joints: BTreeMap<String, f64>,
    /// `initial_state:` initial q and v by name (default: neutral q, zero v).
    #[serde(default)]
    pub initial_state: InitialState,
    /// `passive_joints:` joints with no actuator (τ = 0 in the acceleration envelope); every
    /// other joint is actuated within its URDF `<limit effort>` (default none; the base is
    /// never actuated).
    #[serde(default)]
    pub passive_joints: Vec<String>,
    /// `constraints:` list of constraints, each with a `kind:` (default none).
    #[serde(default)]
    pub constraints: Vec<ConstraintSpec>,
    /// `dynamics:` formulation and Baumgarte stabilisation (default: auto, no stabilisation).
    #[serde(default)]
    pub dynamics: DynamicsSettings,
    /// `integration:` integrator settings for prediction (defaults per field).
    #[serde(default)]
    pub integration: IntegrationSettings,
    /// `forces:` springs, dampers, joint torques and frame forces (default none).
    #[serde(default)]
    pub forces: ForcesSpec,
    /// `actuators:` actuator models (default none).
    #[serde(default)]
    pub actuators: ActuatorsSpec,
    /// `uncertainty:` process noise of propagated covariances (default none).
    #[serde(default)]
    pub uncertainty: crate::predict::UncertaintySpec,
    /// `model:` how the URDF is read (default: inertias checked, not repaired).
    #[serde(default)]
    pub model: ModelSettings,
    /// `payload:` a rigid payload on a frame (`frame`, `mass` [kg], `com` [m] and `inertia`
    /// [kg·m²] about the centre of mass, in the frame); default none (mass 0).
    #[serde(default)]
    pub payload: Payload,
    /// `rollouts:` a sampling planner's rollouts at other settings than the scene's own
    /// predictions ([`Scene::rollout_scene`]); default none (the same).
    #[serde(default)]
    pub rollouts: Option<RolloutsSpec>,
}

/// `rollouts:` in a scene: the controllers' model in time and the integration settings of a
/// planner's rollouts (`Predictor::rollouts`), cheaper than the scene's own predictions and
/// held to their accuracy by a test against the scene's own settings.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RolloutsSpec {
    /// `hold:` `zero_order` or `continuous` (default: the scene's `actuators.hold`).
    #[serde(default)]
    pub hold: Option<crate::actuators::Hold>,
    /// `integration:` the rollouts' integration settings, whole (defaults per field, as the
    /// scene's `integration:`).
    pub integration: IntegrationSettings,
}

/// `model:` in a scene.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelSettings {
    /// `inertia:` `check` (refuse a moving body whose merged inertia is not physical) or
    /// `repair` (use the nearest physical tensor, reported in the model's warnings).
    #[serde(default)]
    pub inertia: InertiaPolicy,
}

/// How the constrained dynamics is solved.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DynamicsSettings {
    /// auto (embedded unless forces are asked for) | multipliers | embedded.
    #[serde(default)]
    pub formulation: Formulation,
    /// Baumgarte stabilisation as a residual time constant T [s] (K_d = 2/T, K_p = 1/T²).
    #[serde(default)]
    pub baumgarte_time_constant: Option<f64>,
    /// Or explicit gains K_p [1/s²], K_d [1/s].
    #[serde(default)]
    pub baumgarte: Option<Baumgarte>,
}

impl DynamicsSettings {
    /// Validated gains and formulation.
    pub fn settings(&self) -> Result<(Baumgarte, Formulation)> {
        let b = match (self.baumgarte_time_constant, self.baumgarte) {
            (Some(_), Some(_)) => {
                return Err(Error::Invalid(
                    "dynamics: give baumgarte_time_constant or baumgarte gains, not both".into(),
                ));
            }
            (Some(t), None) => {
                let (lo, hi) = crate::limits::BAUMGARTE_TIME_CONSTANT;
                crate::limits::check_range("dynamics.baumgarte_time_constant", t, lo, hi, "s")?;
                Baumgarte::from_time_constant(t)
            }
            (None, Some(g)) => {
                let (kp, kd) = crate::limits::MAX_BAUMGARTE_GAINS;
                crate::limits::check_range("dynamics.baumgarte.kp", g.kp, 0.0, kp, "1/s²")?;
                crate::limits::check_range("dynamics.baumgarte.kd", g.kd, 0.0, kd, "1/s")?;
                g
            }
            (None, None) => Baumgarte::default(),
        };
        Ok((b, self.formulation))
    }
}

/// A loaded scene: the model built as the file asks, its constraint declarations and initial state.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Path of the scene file (errors name it; the URDF path is relative to it).
    pub path: PathBuf,
    /// The parsed scene file.
    pub file: SceneFile,
    /// The model built from the URDF with the scene's base, gravity and locked joints,
    /// carrying [`Scene::payload`]; shared, never copied, by every system built from the scene.
    pub model: Arc<Model>,
    /// The same model without a payload (what [`Scene::with_payload`] adds to).
    pub urdf_model: Arc<Model>,
    /// The payload `model` carries: the file's `payload:` unless replaced by
    /// [`Scene::with_payload`].
    pub payload: Payload,
    /// Initial configuration (nq) and velocity (nv).
    pub q0: Vec<f64>,
    /// Initial velocity (nv) [m/s, rad/s].
    pub v0: Vec<f64>,
}

impl Scene {
    /// Load a scene file and the URDF it names.
    pub fn load(path: impl AsRef<Path>) -> Result<Scene> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| Error::Io {
            path: path.display().to_string(),
            source: e,
        })?;
        let file: SceneFile = serde_yaml::from_str(&text).map_err(|e| Error::Scene {
            file: path.display().to_string(),
            message: match e.to_string() {
                m if m.starts_with("constraints") => {
                    crate::scene_errors::locate_constraint_error(&text).unwrap_or(m)
                }
                m => m,
            },
        })?;
        let urdf = path.parent().unwrap_or(Path::new(".")).join(&file.urdf);
        let urdf_text = std::fs::read_to_string(&urdf).map_err(|e| Error::Io {
            path: urdf.display().to_string(),
            source: e,
        })?;
        Self::from_parts(path, file, &urdf_text, &urdf.display().to_string())
    }

    /// Build from an already parsed scene and URDF text (e.g. from `/robot_description`).
    pub fn from_parts(
        path: &Path,
        file: SceneFile,
        urdf_text: &str,
        urdf_name: &str,
    ) -> Result<Scene> {
        let scene_err = |message: String| Error::Scene {
            file: path.display().to_string(),
            message,
        };
        let opts = ModelOptions {
            base: file.base,
            gravity: file
                .gravity
                .map(Vector3::from)
                .unwrap_or(Vector3::new(0.0, 0.0, -9.81)),
            locked_joints: file
                .locked_joints
                .iter()
                .map(|(k, v)| (k.clone(), *v))
                .collect(),
            inertia: file.model.inertia,
        };
        let urdf_model = Model::from_urdf_str(urdf_text, urdf_name, &opts)?;
        let model = urdf_model
            .with_payload(&file.payload)
            .map_err(|e| scene_err(e.to_string()))?;
        let mut q0 = model.neutral();
        let mut v0 = vec![0.0; model.nv];
        // Names looked up through one map each (a search per name is quadratic in the
        // robot's size); an unknown name gets the model's own message.
        let index = |names: &[String]| -> HashMap<String, usize> {
            names
                .iter()
                .enumerate()
                .map(|(i, n)| (n.clone(), i))
                .collect()
        };
        let (q_at, v_at) = (index(&model.q_names), index(&model.v_names));
        for (name, value) in &file.initial_state.q {
            let i = match q_at.get(name) {
                Some(&i) => i,
                None => model
                    .q_index(name)
                    .map_err(|e| scene_err(format!("initial_state.q: {e}")))?,
            };
            q0[i] = *value;
        }
        for (name, value) in &file.initial_state.v {
            let i = match v_at.get(name) {
                Some(&i) => i,
                None => model
                    .v_index(name)
                    .map_err(|e| scene_err(format!("initial_state.v: {e}")))?,
            };
            v0[i] = *value;
        }
        model.normalize(&mut q0);
        if let Some(r) = &file.rollouts {
            (r.integration.validate()).map_err(|e| scene_err(format!("rollouts: {e}")))?;
        }
        for name in &file.passive_joints {
            match model.joint_body(name) {
                Ok(b) if model.bodies[b].parent != 0 || model.base == BaseType::Fixed => {}
                Ok(_) => {
                    return Err(scene_err(format!(
                        "passive_joints: '{name}' is the base, which is never actuated"
                    )));
                }
                Err(e) => return Err(scene_err(format!("passive_joints: {e}"))),
            }
        }
        Ok(Scene {
            path: path.to_path_buf(),
            payload: file.payload.clone(),
            file,
            model: Arc::new(model),
            urdf_model: Arc::new(urdf_model),
            q0,
            v0,
        })
    }

    /// The scene a planner's rollouts run: `rollouts:`'s hold and integration settings in
    /// place of the scene's, where it has them; otherwise the same scene.
    pub fn rollout_scene(&self) -> Scene {
        let mut scene = self.clone();
        if let Some(r) = &self.file.rollouts {
            if let Some(hold) = r.hold {
                scene.file.actuators.hold = hold;
            }
            scene.file.integration = r.integration.clone();
        }
        scene
    }

    /// The same scene carrying `payload` instead of its own (mass 0: none); the initial state
    /// and everything else unchanged. Errors name the payload's field.
    pub fn with_payload(&self, payload: &Payload) -> Result<Scene> {
        let model = self
            .urdf_model
            .with_payload(payload)
            .map_err(|e| Error::Scene {
                file: self.path.display().to_string(),
                message: e.to_string(),
            })?;
        Ok(Scene {
            model: Arc::new(model),
            payload: payload.clone(),
            ..self.clone()
        })
    }

    /// Whether a rolling contact leaves its sideways grip to a tyre (`lateral: tyre`).
    pub fn has_sideways_tyres(&self) -> bool {
        (self.file.constraints.iter()).any(|c| {
            matches!(
                c,
                crate::constraints::ConstraintSpec::Rolling {
                    lateral: crate::constraints::LateralGrip::Tyre,
                    ..
                }
            )
        })
    }

    /// The same scene with every rolling contact rigid sideways (`lateral: rigid`), as the
    /// instantaneous answers take it — the velocity projection, the acceleration envelope: a
    /// tyre's sideways creep is a slip its force builds over time, not a velocity to command.
    pub fn rigid_sideways(&self) -> Scene {
        let mut scene = self.clone();
        for c in &mut scene.file.constraints {
            if let crate::constraints::ConstraintSpec::Rolling { lateral, .. } = c {
                *lateral = crate::constraints::LateralGrip::Rigid;
            }
        }
        scene
    }
}

/// The scene builds what it declares: the system (model and constraints) and the predictor
/// (with its force elements, controllers, `integration:` and `uncertainty:`).
impl System {
    /// Build from a loaded scene (constraints validated at the scene's initial configuration).
    pub fn from_scene(scene: &Scene) -> Result<Self> {
        let set = ConstraintSet::new(&scene.model, &scene.file.constraints, &scene.q0)?;
        let (b, f) = scene.file.dynamics.settings()?;
        let mut sys = Self::new(Arc::clone(&scene.model), set, b, f);
        if let Some(singular) = &scene.model.singular {
            // M is singular: only constraints can give that joint its dynamics (a massless rod
            // pinned by a loop closure). Refused at load unless the KKT form factors at q0.
            let zero = vec![0.0; sys.model().nv];
            if sys.constraints().is_empty()
                || matches!(
                    sys.forward_dynamics_with(&scene.q0, &zero, &zero, DynamicsOptions::default()),
                    Err(crate::Error::SingularMass { .. })
                )
            {
                return Err(singular.error());
            }
        }
        Ok(sys)
    }
}

impl crate::envelope::EnvelopeModel {
    /// The envelope of a system built from `scene`: its contacts and the scene's
    /// `passive_joints:`.
    pub fn from_scene(scene: &Scene, sys: &System) -> Result<Self> {
        Self::new(sys.model(), sys.constraints(), &scene.file.passive_joints)
    }
}

impl Predictor {
    /// Build from a loaded scene: system, `forces:`, `actuators:`, `integration:` and
    /// `uncertainty:`.
    pub fn from_scene(scene: &Scene) -> Result<Self> {
        let sys = System::from_scene(scene)?;
        let forces = ForceElements::new(sys.model(), &scene.file.forces)?;
        let actuators = Actuators::new(sys.model(), &scene.file.actuators)?;
        Ok(
            Self::new(sys, forces, actuators, scene.file.integration.clone())?
                .with_uncertainty(scene.file.uncertainty.clone()),
        )
    }
}

impl Scene {
    /// The work budget of this scene's predictions: `integration:` and the controllers'
    /// period, before a model is built (the ROS nodes check their parameters against it).
    pub fn prediction_budget(&self) -> PredictionBudget {
        PredictionBudget::new(
            self.file.integration.clone(),
            self.file.actuators.control_period_s(),
        )
    }
}
