//! A prediction's start state at t0 from a recording, assembled as the predictor node assembles
//! its latest state: the scene's initial state, overwritten by the last odometry at or before t0
//! (the base) and each joint's last joint state at or before t0, normalised and projected onto
//! the constraints (mass-weighted, positions and velocities: `drift::project`); its covariance
//! from the odometry's covariances, the joints' noise and the scene's process noise over the
//! state's age (model/base_covariance.rs).

use super::ReplayError;
use super::series::{JointTracks, Nanos, Recording, show_stamp};
use crate::dynamics::Formulation;
use crate::model::base_covariance::{AgeNoise, JointSigma, start_covariance};
use crate::predict::drift;
use crate::{Scene, System};
use nalgebra::DMatrix;

/// A start state and what it came from.
#[derive(Clone, Debug)]
pub struct StartState {
    /// Configuration (nq), projected onto the constraints.
    pub q: Vec<f64>,
    /// Velocity (nv), projected onto the constraints.
    pub v: Vec<f64>,
    /// Start covariance (2nv × 2nv, tangent space); None when exactly zero (nothing to
    /// propagate, as the node decides).
    pub covariance: Option<DMatrix<f64>>,
    /// Age of the oldest input at t0 [s].
    pub age_s: f64,
    /// The base twist (v, ω) of the start, the node's `hold` fallback command.
    pub hold_twist: [f64; 2],
    /// The joints' measured velocities and efforts as recorded (nv each, NaN where none), and
    /// the time of the latest of them: what the controllers' integrals are inferred from.
    pub measured: MeasuredEfforts,
}

/// The joints' last recorded velocities and efforts, before any projection.
#[derive(Clone, Debug, Default)]
pub struct MeasuredEfforts {
    /// Joint velocities (nv) [rad/s or m/s], NaN where none was recorded.
    pub v: Vec<f64>,
    /// Joint efforts (nv) [N·m or N], NaN where none was recorded.
    pub effort: Vec<f64>,
    /// When the latest recorded effort was measured; None without any.
    pub at: Option<Nanos>,
}

/// Assembles start states of one scene from one recording.
pub struct StartAssembler {
    scene: Scene,
    sys: System,
    /// 1-DOF joints: (name, q index, v index).
    joints: Vec<(String, usize, usize)>,
    tracks: JointTracks,
    /// (v index, σ) of every 1-DOF joint.
    joint_sigma: Vec<(usize, JointSigma)>,
    /// The scene's process noise over the start's age.
    noise: AgeNoise,
}

impl StartAssembler {
    /// For `scene` (its multiplier-form system) and `recording`; every 1-DOF joint's state
    /// noise is `joint_noise` (the node's `state.joint_noise`).
    pub fn new(
        scene: &Scene,
        recording: &Recording,
        joint_noise: JointSigma,
    ) -> Result<Self, ReplayError> {
        let sys = System::from_scene(scene)?.with_formulation(Formulation::Multipliers);
        let model = &scene.model;
        let joints: Vec<(String, usize, usize)> = (model.bodies.iter().skip(1))
            .map(|b| &b.joint)
            .filter(|j| j.kind.nq() == 1 && j.kind.nv() == 1)
            .map(|j| (j.name.clone(), j.idx_q, j.idx_v))
            .collect();
        let joint_sigma = joints.iter().map(|(_, _, iv)| (*iv, joint_noise)).collect();
        let noise = AgeNoise::new(model, &scene.file.uncertainty)?;
        Ok(StartAssembler {
            scene: scene.clone(),
            sys,
            joints,
            tracks: JointTracks::new(&recording.joint_states),
            joint_sigma,
            noise,
        })
    }

    /// The start state at `t0` [ns] (`origin`: the recording's start, for errors).
    pub fn at(
        &mut self,
        recording: &Recording,
        t0: Nanos,
        origin: Nanos,
    ) -> Result<StartState, ReplayError> {
        let model = self.scene.model.clone();
        let at_s = (t0 - origin) as f64 * 1e-9;
        let missing = |series: &str| ReplayError::NoStart {
            series: series.to_string(),
            at_s,
            stamp: show_stamp(t0),
        };
        let (t_odom, odom) = recording
            .odometry
            .at_or_before(t0)
            .ok_or_else(|| missing(&recording.odometry.name))?;
        let (mut q, mut v) = (self.scene.q0.clone(), self.scene.v0.clone());
        model.set_base(&odom.pose, &odom.twist, &mut q, &mut v);
        model.keep_unmeasured_tilt(&odom.pose_covariance, &self.scene.q0, &mut q);
        let mut oldest = *t_odom;
        let mut any_joint = false;
        let mut measured = MeasuredEfforts {
            v: vec![f64::NAN; model.nv],
            effort: vec![f64::NAN; model.nv],
            at: None,
        };
        for (name, iq, iv) in &self.joints {
            if let Some((t, p, w, e)) = self.tracks.at_or_before(name, t0) {
                q[*iq] = p.unwrap_or(q[*iq]);
                v[*iv] = w.unwrap_or(v[*iv]);
                oldest = oldest.min(t);
                any_joint = true;
                if let (Some(w), Some(e)) = (w, e) {
                    (measured.v[*iv], measured.effort[*iv]) = (w, e);
                    measured.at = measured.at.max(Some(t));
                }
            }
        }
        if !any_joint && !self.joints.is_empty() {
            return Err(missing(&recording.joint_states.name));
        }
        model.normalize(&mut q);
        drift::project(&mut self.sys, &mut q, &mut v, true).map_err(|source| {
            ReplayError::Start {
                at_s,
                stamp: show_stamp(t0),
                source: Box::new(source),
            }
        })?;
        let age_s = (t0 - oldest) as f64 * 1e-9;
        let mut p = start_covariance(
            &model,
            &q,
            &odom.pose_covariance,
            &odom.twist_covariance,
            &self.joint_sigma,
        );
        self.noise.add_to(&mut p, age_s);
        let zero = p.iter().all(|x| *x == 0.0) && self.noise.is_zero();
        let twist = model.base_twist(&v);
        Ok(StartState {
            q,
            v,
            covariance: (!zero).then_some(p),
            age_s,
            hold_twist: [twist.linear[0], twist.angular[2]],
            measured,
        })
    }

    /// The position-controlled joints the node holds, with their q index.
    pub fn held_joints(&self) -> Vec<(String, usize)> {
        (self.scene.file.actuators.position.iter())
            .filter_map(|c| {
                let j = self.joints.iter().find(|(n, _, _)| *n == c.joint)?;
                Some((j.0.clone(), j.1))
            })
            .collect()
    }
}
