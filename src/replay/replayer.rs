//! One thread's share of an evaluation: its own predictor, start assembler and controllers,
//! replaying the starts it is given (evaluate.rs spreads the starts over the threads).

use super::ReplayError;
use super::record::{EvaluationSettings, PredictionRecord, score, to_nanos};
use super::series::{Nanos, Recording, show_stamp};
use super::start::StartAssembler;
use crate::actuators::{Actuators, Command};
use crate::predict::{CovarianceSamples, IntegrationOverrides, PredictionRequest, Predictor};
use crate::{Error, Scene};

/// The recording's origin and end [ns].
#[derive(Clone, Copy)]
pub(super) struct Span {
    pub origin: Nanos,
    pub end: Nanos,
}

/// One thread's replay: its own predictor, start assembler and controllers.
pub(super) struct Replayer<'a> {
    scene: &'a Scene,
    recording: &'a Recording,
    settings: &'a EvaluationSettings,
    span: Span,
    predictor: Predictor,
    assembler: StartAssembler,
    held: Vec<(String, usize)>,
    drive: bool,
    actuators: Actuators,
    integrals: Vec<f64>,
}

impl<'a> Replayer<'a> {
    pub fn new(
        scene: &'a Scene,
        recording: &'a Recording,
        settings: &'a EvaluationSettings,
        span: Span,
    ) -> Result<Self, ReplayError> {
        let assembler = StartAssembler::new(scene, recording, settings.joint_noise)?;
        Ok(Replayer {
            scene,
            recording,
            settings,
            span,
            predictor: Predictor::from_scene(scene)?,
            held: assembler.held_joints(),
            assembler,
            drive: scene.file.actuators.diff_drive.is_some(),
            actuators: Actuators::new(&scene.model, &scene.file.actuators)?,
            integrals: vec![0.0; scene.model.nv],
        })
    }

    /// The predictions from `t0`, one per horizon that fits in the recording.
    pub fn start(&mut self, t0: Nanos) -> Result<Vec<PredictionRecord>, ReplayError> {
        let (scene, recording, settings) = (self.scene, self.recording, self.settings);
        let Span { origin, end } = self.span;
        let (held, drive) = (&self.held, self.drive);
        let (predictor, actuators, integrals) =
            (&mut self.predictor, &self.actuators, &mut self.integrals);
        let start = self.assembler.at(recording, t0, origin)?;
        let mut records = Vec::new();
        let at = |t: Nanos| (t - t0) as f64 * 1e-9;
        let command = |twist: [f64; 2]| Command {
            base_twist: drive.then_some(twist),
            joint_position: held
                .iter()
                .map(|(n, iq)| (n.clone(), start.q[*iq]))
                .collect(),
            ..Default::default()
        };
        let in_force_at = |t: Nanos| {
            (recording.commands.at_or_before(t))
                .filter(|(tc, _)| (t - tc) as f64 * 1e-9 <= settings.command_timeout_s)
                .map_or(start.hold_twist, |(_, c)| *c)
        };
        let in_force = in_force_at(t0);
        // The wheel controllers' integrals from the efforts they gave, under the command in
        // force when those were measured.
        integrals.fill(0.0);
        if let Some(t_effort) = start
            .measured
            .at
            .filter(|_| settings.integrals_from_efforts)
        {
            actuators.integrals_from_efforts(
                &command(in_force_at(t_effort)),
                &start.measured.v,
                &start.measured.effort,
                integrals,
            );
        }
        for &h in &settings.horizons_s {
            let t_end = t0 + to_nanos(h);
            if t_end > end {
                continue;
            }
            let (t_ref, reference) =
                recording
                    .reference
                    .at_or_before(t_end)
                    .ok_or_else(|| ReplayError::NoStart {
                        series: recording.reference.name.clone(),
                        at_s: (t_end - origin) as f64 * 1e-9,
                        stamp: show_stamp(t_end),
                    })?;
            // Predicted to the reference's own stamp: a reference 10 ms older than t0 + h
            // (a 0.25 s horizon on 50 Hz odometry) would otherwise count 10 ms of motion as
            // error. A reference from before t0 is compared with the prediction at t0 + h.
            let predicted_to = if *t_ref > t0 {
                (*t_ref - t0) as f64 * 1e-9
            } else {
                h
            };
            let mut commands = vec![(0.0, command(in_force))];
            commands.extend(
                (recording.commands.between(t0, t_end).iter())
                    .map(|(tc, c)| (at(*tc), command(*c))),
            );
            let p0 = start
                .covariance
                .as_ref()
                .filter(|_| settings.propagate_covariance);
            let request = PredictionRequest {
                commands: &commands,
                horizon: Some(predicted_to),
                start_covariance: p0,
                covariance_samples: CovarianceSamples::Last,
                controller_integrals: integrals,
                integration: IntegrationOverrides {
                    error_estimate: (!settings.error_estimate).then_some(false),
                    ..Default::default()
                },
                ..PredictionRequest::new(&start.q, &start.v)
            };
            let failed = |source: Error| ReplayError::Prediction {
                at_s: (t0 - origin) as f64 * 1e-9,
                stamp: show_stamp(t0),
                horizon_s: h,
                source: Box::new(source),
            };
            let (traj, refused) = match predictor.predict(&request) {
                Err(Error::ErrorEstimateExceeded { .. }) => {
                    let unbounded = PredictionRequest {
                        integration: IntegrationOverrides {
                            max_error: Some(f64::INFINITY),
                            ..request.integration
                        },
                        ..request
                    };
                    (predictor.predict(&unbounded).map_err(failed)?, true)
                }
                r => (r.map_err(failed)?, false),
            };
            let last = (traj.samples.last())
                .ok_or_else(|| failed(Error::Invalid("the prediction has no samples".into())))?;
            let record = score(
                &scene.model,
                (
                    &last.q,
                    last.covariance.as_deref(),
                    last.position_error_estimate(),
                ),
                reference,
                settings.floors,
            )
            .ok_or_else(|| {
                ReplayError::Settings(format!(
                    "prediction from {:.3} s over {h} s: the predicted plus the reference \
                 covariance is singular; give floors > 0",
                    (t0 - origin) as f64 * 1e-9
                ))
            })?;
            records.push(PredictionRecord {
                t0_s: (t0 - origin) as f64 * 1e-9,
                horizon_s: h,
                refused,
                saturated_s: traj.saturated_s,
                reference_t_s: (t_ref - origin) as f64 * 1e-9,
                ..record
            });
        }
        Ok(records)
    }
}
