//! One thread's share of an evaluation: its own predictor, start assembler and controllers,
//! replaying the starts it is given (evaluate.rs spreads the starts over the threads).

use super::ReplayError;
use super::record::{EvaluationSettings, PredictionRecord, score, to_nanos};
use super::series::{Nanos, Odometry, Recording, show_stamp};
use super::start::{StartAssembler, StartState};
use crate::actuators::{Actuators, Command, CommandLag};
use crate::predict::{
    CovarianceSamples, IntegrationOverrides, PredictionRequest, Predictor, Sample, Trajectory,
};
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
    ///
    /// One run to the longest horizon serves every horizon whose reference stamp is one of its
    /// samples: a shorter prediction's steps, controller ticks and samples are that run's up
    /// to its end (the commands after it start later). A horizon the run cannot serve as its
    /// own prediction would — the run refused or refined by the error bound, or no sample at
    /// its reference's stamp (odometry off the sample period's grid) — is predicted alone.
    pub fn start(&mut self, t0: Nanos) -> Result<Vec<PredictionRecord>, ReplayError> {
        let (recording, settings) = (self.recording, self.settings);
        let Span { origin, end } = self.span;
        let start = self.assembler.at(recording, t0, origin)?;
        let targets = (settings.horizons_s.iter())
            .filter(|&&h| t0 + to_nanos(h) <= end)
            .map(|&h| {
                let t_end = t0 + to_nanos(h);
                let (t_ref, reference) =
                    recording.reference.at_or_before(t_end).ok_or_else(|| {
                        ReplayError::NoStart {
                            series: recording.reference.name.clone(),
                            at_s: (t_end - origin) as f64 * 1e-9,
                            stamp: show_stamp(t_end),
                        }
                    })?;
                // Predicted to the reference's own stamp: a reference 10 ms older than t0 + h
                // (a 0.25 s horizon on 50 Hz odometry) would otherwise count 10 ms of motion
                // as error. A reference from before t0 is compared with the prediction at
                // t0 + h.
                let predicted_to = if *t_ref > t0 {
                    (*t_ref - t0) as f64 * 1e-9
                } else {
                    h
                };
                Ok(Target {
                    horizon_s: h,
                    t_end,
                    t_ref: *t_ref,
                    reference,
                    predicted_to,
                })
            })
            .collect::<Result<Vec<_>, ReplayError>>()?;
        let Some(longest) = targets
            .iter()
            .max_by(|a, b| a.predicted_to.total_cmp(&b.predicted_to))
        else {
            return Ok(Vec::new());
        };
        self.start_integrals(&start);
        let times: Vec<f64> = targets.iter().map(|t| t.predicted_to).collect();
        let shared = match self.predict(&start, t0, longest, &times, None) {
            Ok(traj) if traj.refinements == 0 => Some(traj),
            Ok(_) | Err(Error::ErrorEstimateExceeded { .. }) => None,
            Err(source) => return Err(failed(origin, t0, longest.horizon_s, source)),
        };
        let mut records = Vec::with_capacity(targets.len());
        for target in &targets {
            let served = shared.as_ref().and_then(|traj| {
                let sample =
                    (traj.samples.iter()).find(|s| (s.t - target.predicted_to).abs() <= 1e-9)?;
                Some((sample.clone(), false))
            });
            let (sample, refused) = match served {
                Some(s) => s,
                None => self.predict_alone(&start, t0, target)?,
            };
            records.push(self.record(t0, target, &sample, refused)?);
        }
        Ok(records)
    }

    /// The wheel controllers' integrals at `t0`: zero, or with `integrals_from_efforts` where
    /// the efforts they gave put them, under the command in force when those were measured.
    fn start_integrals(&mut self, start: &StartState) {
        self.integrals.fill(0.0);
        if let Some(t_effort) = (start.measured.at).filter(|_| self.settings.integrals_from_efforts)
        {
            // The twist the wheel controllers followed then: under a lag, the lagged one.
            let twist = (self.lagged_at(start, t_effort))
                .unwrap_or_else(|| self.in_force_at(start, t_effort));
            let command = self.command(start, twist);
            (self.actuators).integrals_from_efforts(
                &command,
                &start.measured.v,
                &start.measured.effort,
                &mut self.integrals,
            );
        }
    }

    /// The command the nodes give for base twist (v [m/s], ω [rad/s]): the twist to the drive,
    /// every arm joint held where the start has it.
    fn command(&self, start: &StartState, twist: [f64; 2]) -> Command {
        Command {
            base_twist: self.drive.then_some(twist),
            joint_position: (self.held.iter())
                .map(|(n, iq)| (n.clone(), start.q[*iq]))
                .collect(),
            ..Default::default()
        }
    }

    /// The twist in force at `t`: the last command at or before it if no older than the
    /// command timeout, else the start's own (the node's `hold` fallback).
    fn in_force_at(&self, start: &StartState, t: Nanos) -> [f64; 2] {
        (self.recording.commands.at_or_before(t))
            .filter(|(tc, _)| (t - tc) as f64 * 1e-9 <= self.settings.command_timeout_s)
            .map_or(start.hold_twist, |(_, c)| *c)
    }

    /// Under a command lag, the drive's lagged command at `t0`, as the node keeps it: the
    /// recorded commands before `t0` run through the lag, from the one in force 10 τ earlier
    /// (e⁻¹⁰ of what came before is left); without a recorded one, the command in force.
    fn lagged_at(&self, start: &StartState, t0: Nanos) -> Option<[f64; 2]> {
        let tau = self.actuators.command_lag_s()?;
        let commands = &self.recording.commands;
        let from = t0 - to_nanos(10.0 * tau);
        let seconds = |t: Nanos| (t - t0) as f64 * 1e-9;
        let mut lag = CommandLag::new(tau);
        if let Some((_, c)) = commands.at_or_before(from) {
            lag.push(seconds(from), *c);
        }
        for (t, c) in commands.between(from, t0) {
            lag.push(seconds(*t), *c);
        }
        lag.at(0.0).or(Some(self.in_force_at(start, t0)))
    }

    /// The prediction from `t0` to `target`'s reference stamp under the recorded commands,
    /// its covariance read at `times` [s from t0] and the end; `max_error` overrides the
    /// scene's bound.
    fn predict(
        &mut self,
        start: &StartState,
        t0: Nanos,
        target: &Target,
        times: &[f64],
        max_error: Option<f64>,
    ) -> Result<Trajectory, Error> {
        let at = |t: Nanos| (t - t0) as f64 * 1e-9;
        let mut commands = vec![(0.0, self.command(start, self.in_force_at(start, t0)))];
        commands.extend(
            (self.recording.commands.between(t0, target.t_end).iter())
                .map(|(tc, c)| (at(*tc), self.command(start, *c))),
        );
        let settings = self.settings;
        let request = PredictionRequest {
            commands: &commands,
            horizon: Some(target.predicted_to),
            start_covariance: (start.covariance.as_ref()).filter(|_| settings.propagate_covariance),
            covariance_samples: CovarianceSamples::At(times),
            controller_integrals: &self.integrals,
            lagged_command: self.lagged_at(start, t0),
            integration: IntegrationOverrides {
                error_estimate: (!settings.error_estimate).then_some(false),
                max_error,
                ..Default::default()
            },
            ..PredictionRequest::new(&start.q, &start.v)
        };
        self.predictor.predict(&request)
    }

    /// `target`'s prediction on its own, as the node would make it: its last sample, and
    /// whether the error bound refused it (then rerun without the bound).
    fn predict_alone(
        &mut self,
        start: &StartState,
        t0: Nanos,
        target: &Target,
    ) -> Result<(Sample, bool), ReplayError> {
        let origin = self.span.origin;
        let failed = |source| failed(origin, t0, target.horizon_s, source);
        let (traj, refused) = match self.predict(start, t0, target, &[], None) {
            Err(Error::ErrorEstimateExceeded { .. }) => (
                (self.predict(start, t0, target, &[], Some(f64::INFINITY))).map_err(failed)?,
                true,
            ),
            r => (r.map_err(failed)?, false),
        };
        let last = (traj.samples.into_iter().next_back())
            .ok_or_else(|| failed(Error::Invalid("the prediction has no samples".into())))?;
        Ok((last, refused))
    }

    /// `target`'s record: the prediction's sample at its reference's stamp, scored.
    fn record(
        &self,
        t0: Nanos,
        target: &Target,
        sample: &Sample,
        refused: bool,
    ) -> Result<PredictionRecord, ReplayError> {
        let origin = self.span.origin;
        let record = score(
            &self.scene.model,
            (
                &sample.q,
                sample.covariance.as_deref(),
                sample.position_error_estimate(),
            ),
            target.reference,
            self.settings.floors,
        )
        .ok_or_else(|| {
            ReplayError::Settings(format!(
                "prediction from {:.3} s over {} s: the predicted plus the reference \
                 covariance is singular; give floors > 0",
                (t0 - origin) as f64 * 1e-9,
                target.horizon_s
            ))
        })?;
        Ok(PredictionRecord {
            t0_s: (t0 - origin) as f64 * 1e-9,
            horizon_s: target.horizon_s,
            refused,
            saturated_s: sample.saturated_s,
            reference_t_s: (target.t_ref - origin) as f64 * 1e-9,
            ..record
        })
    }
}

/// One horizon of a start: its reference and when the prediction is read.
struct Target<'a> {
    horizon_s: f64,
    /// t0 + h [ns].
    t_end: Nanos,
    /// The reference's stamp, the last at or before `t_end` [ns], and the reference.
    t_ref: Nanos,
    reference: &'a Odometry,
    /// The time the prediction is read at [s from t0].
    predicted_to: f64,
}

/// A prediction's error, with the start and horizon it came from.
fn failed(origin: Nanos, t0: Nanos, horizon_s: f64, source: Error) -> ReplayError {
    ReplayError::Prediction {
        at_s: (t0 - origin) as f64 * 1e-9,
        stamp: show_stamp(t0),
        horizon_s,
        source: Box::new(source),
    }
}
