//! What the state inputs say beyond the state: their age on the ROS clock (stale or not,
//! `state.timeout`) and the start covariance they give (`/odom`'s covariances, the joint-noise
//! parameters, the scene's process noise over the age). Used by the predictor and by
//! `~/predict`.

use constraint_dynamics::Model;
use constraint_dynamics::predict::UncertaintySpec;
use nalgebra::DMatrix;

use super::state::StateEstimate;
use crate::covariance::{AgeNoise, JointSigma, start_covariance};
use crate::error::NodeError;
use crate::msg::builtin_interfaces::Time;
use crate::params::{ParamsError, StateParams};

/// The ages of the subscribed state inputs at one tick.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct InputAges {
    /// (input name, age [s]) of every subscribed input received at least once.
    pub ages: Vec<(&'static str, f64)>,
}

impl InputAges {
    /// The ages at ROS time `now` of the inputs `params` subscribes to.
    pub fn at(state: &StateEstimate, params: &StateParams, now: Time) -> Self {
        let age = |at: Time| (now.to_nanos() - at.to_nanos()) as f64 * 1e-9;
        let mut ages = Vec::new();
        for (name, topic, at) in [
            ("odom", &params.odom_topic, state.odom_at),
            (
                "joint_states",
                &params.joint_states_topic,
                state.joint_states_at,
            ),
        ] {
            if let (false, Some(at)) = (topic.is_empty(), at) {
                ages.push((name, age(at)));
            }
        }
        InputAges { ages }
    }

    /// The age of the state: that of its oldest input [s] (0 when none was received: the
    /// scene's initial state is not a measurement that ages).
    pub fn oldest(&self) -> f64 {
        self.ages.iter().map(|(_, a)| *a).fold(0.0, f64::max)
    }

    /// Inputs older than `timeout` [s], as "odom 0.62 s".
    pub fn stale(&self, timeout: f64) -> Vec<String> {
        self.ages
            .iter()
            .filter(|(_, a)| *a > timeout)
            .map(|(n, a)| format!("{n} {a:.2} s"))
            .collect()
    }
}

/// The start-covariance model of one robot: per-joint noise and the scene's process noise.
#[derive(Clone, Debug)]
pub struct StartCovariance {
    joints: Vec<(usize, JointSigma)>,
    /// The scene's process noise over the state's age (`uncertainty:`).
    noise: AgeNoise,
}

impl StartCovariance {
    /// From the parameters and the scene; a joint named in `state.joint_noise.joints` that the
    /// model does not have is an error naming it.
    pub fn new(
        model: &Model,
        params: &StateParams,
        uncertainty: &UncertaintySpec,
    ) -> Result<Self, NodeError> {
        let jn = &params.joint_noise;
        let one_dof: Vec<(String, usize)> = model
            .bodies
            .iter()
            .skip(1)
            .map(|b| &b.joint)
            .filter(|j| j.kind.nv() == 1)
            .map(|j| (j.name.clone(), j.idx_v))
            .collect();
        if let Some(name) = jn
            .joints
            .keys()
            .find(|n| !one_dof.iter().any(|(m, _)| m == *n))
        {
            return Err(ParamsError::invalid(
                &format!("state.joint_noise.joints.{name}"),
                format!(
                    "names no 1-DOF joint of model '{}' (joints: {})",
                    model.name,
                    one_dof
                        .iter()
                        .map(|(n, _)| n.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            )
            .into());
        }
        let joints = one_dof
            .iter()
            .map(|(name, iv)| {
                let (position, velocity) = jn.of(name);
                (*iv, JointSigma { position, velocity })
            })
            .collect();
        // The core checked the names and values when it built its predictor.
        let noise = AgeNoise::new(model, uncertainty).unwrap_or_default();
        Ok(StartCovariance { joints, noise })
    }

    /// The start covariance at configuration q of a state `age` [s] old.
    pub fn at(&self, model: &Model, q: &[f64], state: &StateEstimate, age: f64) -> DMatrix<f64> {
        let (pose, twist) = &state.odom_covariance;
        let mut p = start_covariance(model, q, pose, twist, &self.joints);
        self.noise.add_to(&mut p, age);
        p
    }

    /// [`StartCovariance::at`], or `None` when the propagated covariance would be exactly zero
    /// (a zero start and no process noise): propagation costs several times the prediction, so
    /// inputs without covariance (all zeros, as many drivers send) cost nothing extra.
    pub fn nonzero_at(
        &self,
        model: &Model,
        q: &[f64],
        state: &StateEstimate,
        age: f64,
    ) -> Option<DMatrix<f64>> {
        let p = self.at(model, q, state, age);
        let zero = p.iter().all(|x| *x == 0.0) && self.noise.is_zero();
        (!zero).then_some(p)
    }
}
