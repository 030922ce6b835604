//! The predictor's acceleration envelope: from the prediction's start state, the core's
//! [`acceleration_envelope`] (how hard the base can accelerate, brake and turn) as a
//! `constraint_dynamics_msgs/AccelerationLimits` for `~/acceleration_limits`, and its four
//! values for `/diagnostics` — at every tick while the limits are taken, else once per
//! diagnostics period (`PredictorInput::LimitsWanted`).
//!
//! The [`EnvelopeModel`] and [`EnvelopeData`] are built once, with the node's logic, and reused:
//! after the first tick only Clarabel's solves allocate. A failure at one tick is logged
//! (throttled) and that tick publishes no limits; the prediction goes on.

use std::time::Instant;

use constraint_dynamics::Scene;
use constraint_dynamics::applied::applied_generalized_force;
use constraint_dynamics::envelope::{
    Envelope, EnvelopeData, EnvelopeModel, Limit, Reach, acceleration_envelope,
};
use constraint_dynamics::forces::ForceElements;
use constraint_dynamics::model::{Model, StateMap};
use constraint_dynamics::system::System;

use crate::msg::builtin_interfaces::Time;
use crate::msg::constraint_dynamics_msgs::{AccelerationLimit, AccelerationLimits};
use crate::msg::diagnostic_msgs::KeyValue;
use crate::msg::std_msgs::Header;
use crate::node::health::kv;
use crate::ros::logging::{DropLog, NodeLog};

/// A scene of its own for the envelope (`envelope.scene_file`): a variant of the predictor's
/// robot, and where each of its coordinates comes from in the predictor's state.
pub struct EnvelopeScene {
    sys: System,
    elements: ForceElements,
    /// The predictor's state in this scene's coordinates.
    map: StateMap,
    /// The state in the envelope scene's coordinates (its initial state where the predictor
    /// says nothing: the base's height on a floating base).
    q: Vec<f64>,
    v: Vec<f64>,
}

impl EnvelopeScene {
    /// The scene `scene` for a predictor of `model`: every joint coordinate of the scene must
    /// be one of the model's, by name.
    pub fn new(scene: &Scene, model: &Model) -> Result<Self, String> {
        let sys = System::from_scene(scene).map_err(|e| e.to_string())?;
        let elements =
            ForceElements::new(sys.model(), &scene.file.forces).map_err(|e| e.to_string())?;
        let map = StateMap::new(model, sys.model())
            .map_err(|e| format!("against the predictor's robot: {e}"))?;
        Ok(EnvelopeScene {
            q: scene.q0.clone(),
            v: scene.v0.clone(),
            sys,
            elements,
            map,
        })
    }

    /// The predictor's state (q, v) of `model` in this scene's coordinates (a planar base says
    /// nothing of the height: the scene's own stays).
    fn map(&mut self, model: &Model, (q, v): (&[f64], &[f64])) {
        let target = self.sys.model();
        (self.map).apply((model, target), (q, v), (&mut self.q, &mut self.v));
    }
}

/// The envelope's model, workspace and last result.
pub struct StartEnvelope {
    /// `envelope.scene_file`'s scene, when the envelope has one of its own.
    own: Option<EnvelopeScene>,
    /// The scene's limits as declared; None when the scene has no envelope (no mobile base),
    /// the reason in `last`.
    declared: Option<EnvelopeModel>,
    /// The limits in use (the declared ones with `slip.friction_coefficient` where a contact
    /// declares no μ) and their workspace, with that μ; rebuilt when the parameter changes.
    solver: Option<(EnvelopeModel, EnvelopeData, f64)>,
    /// The force elements' generalized force at the state (nv) and nv zeros.
    applied: Vec<f64>,
    zero: Vec<f64>,
    /// The four maxima of the last tick for `/diagnostics`, or why there are none.
    last: Result<[LimitSummary; 4], String>,
    log: DropLog,
}

/// One limit as `/diagnostics` shows it.
#[derive(Clone, Debug, PartialEq)]
pub struct LimitSummary {
    reach: Reach,
    max: f64,
    binding: String,
}

/// The four limits' names and units, in message order.
const LIMITS: [(&str, &str); 4] = [
    ("forward acceleration", "m/s²"),
    ("forward deceleration", "m/s²"),
    ("yaw acceleration left", "rad/s²"),
    ("yaw acceleration right", "rad/s²"),
];

impl StartEnvelope {
    /// The envelope of `sys` (the predictor's start-state system) with the scene's
    /// `passive_joints`, or of `own` (`envelope.scene_file`) with its own; a scene without a
    /// mobile base gets none (logged once).
    pub fn new(
        sys: &System,
        passive_joints: &[String],
        own: Option<(EnvelopeScene, Vec<String>)>,
        log: &NodeLog,
    ) -> Self {
        let (sys, passive_joints) = match &own {
            Some((scene, passive)) => (&scene.sys, &passive[..]),
            None => (sys, passive_joints),
        };
        let nv = sys.model().nv;
        let (declared, last) =
            match EnvelopeModel::new(sys.model(), sys.constraints(), passive_joints) {
                Ok(em) => (Some(em), Err("not computed yet".to_string())),
                Err(e) => {
                    let why = format!("unavailable for this scene: {e}");
                    log.info(&format!("acceleration envelope {why}"));
                    (None, Err(why))
                }
            };
        let own = own.map(|(scene, _)| scene);
        StartEnvelope {
            own,
            declared,
            solver: None,
            applied: vec![0.0; nv],
            zero: vec![0.0; nv],
            last,
            log: DropLog::default(),
        }
    }

    /// The envelope at (q, v), stamped `stamp` in `base_frame`, with `mu` [-] (the node's
    /// `slip.friction_coefficient`) for the contacts that declare no friction; None (logged,
    /// throttled) when it cannot be computed.
    #[allow(clippy::too_many_arguments)]
    pub fn at(
        &mut self,
        sys: &mut System,
        elements: &mut ForceElements,
        (q, v): (&[f64], &[f64]),
        mu: f64,
        header: (Time, &str),
        log: &NodeLog,
    ) -> Option<AccelerationLimits> {
        let declared = self.declared.as_ref()?;
        // The envelope's own scene: the predictor's state in its coordinates.
        let (sys, elements, q, v) = match self.own.as_mut() {
            Some(own) => {
                own.map(sys.model(), (q, v));
                (&mut own.sys, &mut own.elements, &own.q[..], &own.v[..])
            }
            None => (sys, elements, q, v),
        };
        if self.solver.as_ref().is_none_or(|(_, _, m)| *m != mu) {
            let em = declared.clone().assume_friction(mu);
            let ed = EnvelopeData::new(&em);
            self.solver = Some((em, ed, mu));
        }
        let (em, ed, _) = self.solver.as_mut()?;
        // The scene's force elements (springs, dampers, URDF damping) at (q, v) act as well, as
        // in the CLI's `envelope`.
        applied_generalized_force(sys, elements, (0.0, q, v), &self.zero, &mut self.applied);
        match acceleration_envelope(sys, em, ed, q, v, &self.applied) {
            Ok(env) => {
                let msg = limits_msg(sys.model(), em, env, header);
                self.last = Ok(summaries(&msg));
                Some(msg)
            }
            Err(e) => {
                let why = format!("failed at the start state: {e}");
                let level = self.log.level("envelope", &why, Instant::now());
                log.log(
                    level,
                    &format!("acceleration envelope {why}; no acceleration_limits this tick"),
                );
                self.last = Err(why);
                None
            }
        }
    }

    /// `/diagnostics` values: each limit with its unit and what binds it.
    pub fn key_values(&self) -> Vec<KeyValue> {
        match &self.last {
            Ok(limits) => LIMITS
                .iter()
                .zip(limits)
                .map(|((name, unit), l)| kv(&format!("{name} limit [{unit}]"), &l.text()))
                .collect(),
            Err(why) => vec![kv("acceleration envelope", why)],
        }
    }

    /// A WARN for `/diagnostics` when a limit is infeasible or ≤ 0: the robot cannot hold that
    /// direction's acceleration at 0 with every contact holding.
    pub fn warning(&self) -> Option<String> {
        let limits = self.last.as_ref().ok()?;
        let bad: Vec<String> = LIMITS
            .iter()
            .zip(limits)
            .filter(|(_, l)| {
                l.reach == Reach::Infeasible || (l.reach == Reach::Bounded && l.max <= 0.0)
            })
            .map(|((name, unit), l)| format!("{name} {}", l.text_with(unit)))
            .collect();
        (!bad.is_empty()).then(|| {
            format!(
                "acceleration envelope: {} (the base cannot keep every contact in that direction)",
                bad.join(", ")
            )
        })
    }
}

impl LimitSummary {
    fn text(&self) -> String {
        match self.reach {
            Reach::Bounded => format!("{:.4} ({})", self.max, self.binding),
            Reach::Unbounded => "unbounded".to_string(),
            Reach::Infeasible => "infeasible".to_string(),
        }
    }

    fn text_with(&self, unit: &str) -> String {
        match self.reach {
            Reach::Bounded => format!("{:.4} {unit} ({})", self.max, self.binding),
            _ => self.text(),
        }
    }
}

/// The message of one envelope (allocates: names for output).
pub fn limits_msg(
    model: &Model,
    em: &EnvelopeModel,
    env: &Envelope,
    (stamp, frame): (Time, &str),
) -> AccelerationLimits {
    let limit = |l: &Limit| {
        let (status, max) = match l.reach {
            Reach::Bounded => (AccelerationLimit::BOUNDED, l.max),
            Reach::Unbounded => (AccelerationLimit::UNBOUNDED, 0.0),
            Reach::Infeasible => (AccelerationLimit::INFEASIBLE, 0.0),
        };
        AccelerationLimit {
            status,
            // Nothing non-finite leaves the node: a bounded maximum is finite by construction.
            max: if max.is_finite() { max } else { 0.0 },
            binding_kinds: l
                .binding
                .iter()
                .map(|b| b.kind.name().to_string())
                .collect(),
            binding_names: l
                .binding
                .iter()
                .map(|b| em.binding_name(model, b).to_string())
                .collect(),
        }
    };
    AccelerationLimits {
        header: Header {
            stamp,
            frame_id: frame.to_string(),
        },
        forward_acceleration: limit(&env.forward_acceleration),
        forward_deceleration: limit(&env.forward_deceleration),
        yaw_acceleration_left: limit(&env.yaw_acceleration_left),
        yaw_acceleration_right: limit(&env.yaw_acceleration_right),
        unchecked_kinds: em
            .unchecked
            .iter()
            .map(|(k, _)| k.name().to_string())
            .collect(),
        unchecked_names: em.unchecked.iter().map(|(_, n)| n.clone()).collect(),
    }
}

fn summaries(m: &AccelerationLimits) -> [LimitSummary; 4] {
    [
        &m.forward_acceleration,
        &m.forward_deceleration,
        &m.yaw_acceleration_left,
        &m.yaw_acceleration_right,
    ]
    .map(|l| LimitSummary {
        reach: match l.status {
            AccelerationLimit::BOUNDED => Reach::Bounded,
            AccelerationLimit::UNBOUNDED => Reach::Unbounded,
            _ => Reach::Infeasible,
        },
        max: l.max,
        binding: l
            .binding_kinds
            .iter()
            .zip(&l.binding_names)
            .map(|(k, n)| format!("{k}: {n}"))
            .collect::<Vec<_>>()
            .join(", "),
    })
}
