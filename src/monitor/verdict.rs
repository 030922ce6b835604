//! The monitor's verdict: whether the model still matches what arrives, and if not, the likely
//! cause — the efforts off while the odometry matches (a load the model does not have: a
//! payload added without telling the node), the poses off beyond their covariance (the base
//! does not move as modelled: a slippery floor, wrong wheel radius or track), or both; the
//! poses off because the drive answers its commands later than its model (a lag,
//! [`super::response`]); and the measured states off the velocity constraints (the wheels slip
//! on the floor).

use super::{HorizonReport, ResponseFit};

/// When the verdict calls the model off.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Thresholds {
    /// Samples a horizon's window needs before it may call anything (≥ 1).
    pub min_samples: usize,
    /// The median NEES above which the poses are off (χ²₃'s median is 2.37; its 99.9th
    /// percentile 16.3), and the mean NEES above which a lag is called (χ²₃'s mean is 3).
    pub nees: f64,
    /// The |median signed effort error| of a joint above which its efforts are off [N·m or N].
    pub effort: f64,
    /// The measured states' median velocity residual off the constraints above which the
    /// wheels are called slipping [m/s or rad/s].
    pub slip: f64,
    /// The lag [s] beyond which the drive is called late (when the lag also exceeds three
    /// standard errors, over at least `min_samples` predictions whose mean NEES exceeds
    /// `nees`).
    pub lag: f64,
    /// A called cause clears once its figure falls below this fraction of its threshold (in
    /// (0, 1]).
    pub clear_ratio: f64,
}

/// What is off, with the figures that show it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Cause {
    /// Joint `joint`'s effort is off by `error` (median, measured − predicted) at `horizon`
    /// [s] while the poses match.
    Efforts {
        /// v index of the joint.
        joint: usize,
        /// [N·m or N]
        error: f64,
        /// [s]
        horizon: f64,
    },
    /// The poses are off beyond their covariance at `horizon`: median position error [m], yaw
    /// error [rad] and NEES.
    Poses {
        /// [s]
        horizon: f64,
        /// [m]
        position: f64,
        /// [rad]
        yaw: f64,
        /// Median NEES.
        nees: f64,
        /// How the drive answers its commands at that horizon (over at least `min_samples`
        /// predictions): its travel and turn shortfalls point at the radius and the track.
        response: Option<ResponseFit>,
    },
    /// The measured states lie off the velocity constraints by a median ‖J v‖ of `residual`
    /// [m/s or rad/s]: the wheels turn faster or slower than the base moves over the floor.
    /// Named before the poses, which it explains, and before the efforts alone; poses and
    /// efforts both off are [`Cause::Both`].
    Slip {
        /// [m/s or rad/s]
        residual: f64,
    },
    /// The poses at `horizon` [s] follow the gap between each start's velocity and its
    /// command: the drive closes it `lag_s` [s] later than its model (± `lag_std_error_s`).
    /// Named before the others, whose figures it explains. Only the predictions started while
    /// the drive catches up are off, so it shows in no median: it is called on its own.
    Lag {
        /// [s]
        horizon: f64,
        /// [s]
        lag_s: f64,
        /// [s]
        lag_std_error_s: f64,
        /// Mean NEES (a few predictions far off).
        nees_mean: f64,
    },
    /// Both: the joint whose efforts are most off and its median error, the horizon whose
    /// poses are most off and its median NEES.
    Both {
        /// v index of the joint.
        joint: usize,
        /// [N·m or N]
        error: f64,
        /// [s]
        horizon: f64,
        /// Median NEES.
        nees: f64,
    },
}

impl Cause {
    /// One sentence naming the likely cause, `joint_name` naming joint indices.
    pub fn describe(&self, joint_name: &dyn Fn(usize) -> String) -> String {
        match *self {
            Cause::Efforts {
                joint,
                error,
                horizon,
            } => format!(
                "{}'s effort is off by {error:+.2} (median, measured − predicted) at {horizon} s \
                 while the odometry matches: a payload added without ~/set_payload?",
                joint_name(joint)
            ),
            Cause::Poses {
                horizon,
                position,
                yaw,
                nees,
                response,
            } => {
                let mut s = format!(
                    "the odometry is off the prediction at {horizon} s (median {:.1} mm, {:.1} \
                     mrad, NEES {nees:.1} ≫ 3): a slippery floor or wrong wheel parameters \
                     (radius, track)?",
                    position * 1e3,
                    yaw * 1e3
                );
                if let Some(f) = response {
                    s += &format!(
                        " The base travels {:+.1} % and turns {:+.1} % of its commands beyond \
                         the model (radius and track: calibrate)",
                        f.travel_ratio * 100.0,
                        f.turn_ratio * 100.0
                    );
                }
                s
            }
            Cause::Slip { residual } => format!(
                "the wheels' speeds are off the base's measured motion (the measured states' \
                 median velocity residual off the constraints {residual:.3} m/s): the wheels \
                 slip, a slippery floor?"
            ),
            Cause::Lag {
                horizon,
                lag_s,
                lag_std_error_s,
                nees_mean,
            } => format!(
                "the odometry is off the predictions at {horizon} s (mean NEES {nees_mean:.1}) \
                 the way a late drive is: it reaches its commands {lag_s:.3} ± \
                 {lag_std_error_s:.3} s later than the model (a motor controller's own lag? \
                 declare actuators.diff_drive.command_lag, or lengthen it)"
            ),
            Cause::Both {
                joint,
                error,
                horizon,
                nees,
            } => format!(
                "the odometry (NEES {nees:.1} ≫ 3) and {}'s effort ({error:+.2}) are off the \
                 prediction at {horizon} s: the robot's mass, payload or wheels differ from the \
                 model",
                joint_name(joint)
            ),
        }
    }
}

/// Matching, or off with a cause.
pub type Verdict = Option<Cause>;

/// Which causes are called (the hysteresis state).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Hysteresis {
    poses: bool,
    efforts: bool,
    slip: bool,
    lag: bool,
}

impl Hysteresis {
    /// The verdict on `reports` and the slip statistic (`slip`: the measured states' median
    /// velocity residual, None before its window is full) under `t`, and whether it changed
    /// what is called.
    pub(super) fn update(
        &mut self,
        reports: &[HorizonReport],
        slip: Option<f64>,
        t: &Thresholds,
    ) -> (Verdict, bool) {
        let enough = |n: usize| n >= t.min_samples.max(1);
        let clear = t.clear_ratio;
        // The horizon whose poses are most off, and the joint whose efforts are most off.
        let poses = reports
            .iter()
            .filter(|r| enough(r.odometry_samples) && r.nees_median.is_finite())
            .max_by(|a, b| a.nees_median.total_cmp(&b.nees_median));
        let efforts = reports
            .iter()
            .filter(|r| enough(r.effort_samples))
            .filter_map(|r| r.effort_worst.map(|(j, e)| (r.horizon, j, e)))
            .max_by(|a, b| a.2.abs().total_cmp(&b.2.abs()));
        let before = (self.poses, self.efforts, self.slip, self.lag);
        let nees = poses.map_or(0.0, |r| r.nees_median);
        self.poses = match self.poses {
            false => nees > t.nees,
            true => nees >= clear * t.nees,
        };
        let error = efforts.map_or(0.0, |e| e.2.abs());
        self.efforts = match self.efforts {
            false => error > t.effort,
            true => error >= clear * t.effort,
        };
        let residual = slip.filter(|r| r.is_finite()).unwrap_or(0.0);
        self.slip = match self.slip {
            false => residual > t.slip,
            true => residual >= clear * t.slip,
        };
        // The lag, read at the longest horizon with enough predictions fitted (where a lag
        // has moved the poses furthest).
        let late = reports
            .iter()
            .filter_map(|r| r.response.map(|f| (r, f)))
            .filter(|(_, f)| enough(f.samples))
            .max_by(|a, b| a.0.horizon.total_cmp(&b.0.horizon));
        let lag = late.map_or(0.0, |(_, f)| match f.lag_s > 3.0 * f.lag_std_error_s {
            true => f.lag_s,
            false => 0.0,
        });
        // And only where it matters: the predictions off by more than their covariance on
        // average (a lag moves a few of them far, which the mean NEES shows and no median).
        let nees_mean = late.map_or(0.0, |(r, _)| r.nees_mean);
        self.lag = match self.lag {
            false => lag > t.lag && nees_mean > t.nees,
            true => lag >= clear * t.lag && nees_mean >= clear * t.nees,
        };
        let changed = before != (self.poses, self.efforts, self.slip, self.lag);
        if let (true, Some((r, f))) = (self.lag, late) {
            let cause = Cause::Lag {
                horizon: r.horizon,
                lag_s: f.lag_s,
                lag_std_error_s: f.lag_std_error_s,
                nees_mean: r.nees_mean,
            };
            return (Some(cause), changed);
        }
        let verdict = match (poses, efforts, self.poses, self.efforts) {
            (Some(p), Some((_, joint, error)), true, true) => Some(Cause::Both {
                joint,
                error,
                horizon: p.horizon,
                nees: p.nees_median,
            }),
            _ if self.slip => Some(Cause::Slip { residual }),
            (Some(p), _, true, _) => Some(Cause::Poses {
                horizon: p.horizon,
                position: p.position_median,
                yaw: p.yaw_median,
                nees: p.nees_median,
                response: p.response.filter(|f| enough(f.samples)),
            }),
            (_, Some((horizon, joint, error)), _, true) => Some(Cause::Efforts {
                joint,
                error,
                horizon,
            }),
            _ => None,
        };
        (verdict, changed)
    }
}
