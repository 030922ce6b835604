//! Scoring a predictor's own past predictions against the measurements that arrive.
//!
//! Each periodic prediction leaves, per monitored horizon h, one predicted sample: the planar
//! base pose (x, y, yaw) in the odom frame with its covariance P, and the joints' positions and
//! efforts, due at t₀ + h. The first odometry (and joint state) at or after that time is its
//! measurement (no interpolation; a measurement more than `max_lag` late is not one). A
//! prediction holds the command of its start over its horizon: one whose command changed
//! within (t₀, t₀ + h] ([`PredictionMonitor::command_changed`]) predicted another drive than
//! the one measured, and is not scored (counted apart). The odometry's pose
//! is carried back to the due time along its own twist (the lag is a fraction of the
//! odometry's period, and at 0.5 m/s even 10 ms are 5 mm, more than the errors scored). Per
//! horizon the monitor keeps, over its last `window` samples, the median position error
//! |(dx, dy)| [m], yaw error |dyaw| [rad], the NEES eᵀ (P + R)⁻¹ e of e = (dx, dy, dyaw) with R
//! the odometry's own covariance, and each joint's median signed position error [rad or m]
//! and effort error [N·m or N] (measured − predicted), and how the drive answers its commands
//! (a lag and a travel and turn shortfall the model does not have, [`response`]). [`verdict`]
//! turns these into a verdict with hysteresis (the poses, the efforts and the lag; the joint
//! positions and the shortfalls are reported).
//!
//! Apart from the predictions, the monitor keeps the median over the last `slip_window`
//! measured start states of how far each lay off the velocity constraints before its projection
//! (‖J v‖: for rolling wheels, their surface speed against the base's measured motion). It
//! needs no prediction and no held command: on a slippery floor the wheels spin and slide while
//! the robot accelerates, the moments whose predictions a changing command leaves unscored.
//!
//! Everything is allocated at construction: recording a prediction and scoring a measurement
//! allocate nothing.

mod response;
mod stats;
pub mod verdict;

pub use response::{ResponseFit, ResponseWindow, ScoredResponse};
pub use stats::{PlanarCovariance, PlanarPose, Window, nees, yaw_difference};
pub use verdict::{Cause, Thresholds, Verdict};

/// How the monitor scores.
#[derive(Clone, Debug, PartialEq)]
pub struct MonitorSettings {
    /// The horizons scored [s] (> 0).
    pub horizons: Vec<f64>,
    /// Samples per statistic window (≥ 1).
    pub window: usize,
    /// Predictions awaiting their measurement, per horizon (≥ 1): at least the prediction
    /// rate × the longest horizon, or the oldest are dropped.
    pub pending: usize,
    /// The latest a measurement may arrive after a predicted sample's time and still be its
    /// measurement [s].
    pub max_lag: f64,
    /// Measured start states the slip statistic's median is over (≥ 1).
    pub slip_window: usize,
    /// When the verdict calls the model off.
    pub thresholds: Thresholds,
}

/// What one periodic prediction predicts at one horizon.
#[derive(Clone, Copy, Debug)]
pub struct PredictedSample<'a> {
    /// When the prediction started (its start state's time) [s].
    pub start: f64,
    /// When it is due (the prediction's start + the sample's time) [s].
    pub t: f64,
    /// The base's pose in the odom frame.
    pub pose: PlanarPose,
    /// Its covariance (the propagated one and the node's floors).
    pub covariance: PlanarCovariance,
    /// The joints' efforts (actuator torques) [N·m or N], one per joint the monitor was built
    /// with (or none: not scored).
    pub effort: &'a [f64],
    /// The joints' positions [rad or m], one per joint (NaN: not scored; or none).
    pub position: &'a [f64],
    /// The base command held over the horizon (v [m/s], ω [rad/s]; NaN: none, the drive's
    /// response not scored).
    pub command: [f64; 2],
    /// The base's measured velocity at the start (forward v [m/s], ω [rad/s]).
    pub start_velocity: [f64; 2],
}

/// A measured odometry: time [s], pose, covariance and twist in the base frame (vx [m/s], vy
/// [m/s], ωz [rad/s]).
#[derive(Clone, Copy, Debug)]
pub struct MeasuredOdometry {
    /// Its stamp [s].
    pub t: f64,
    /// The base's pose in the odom frame.
    pub pose: PlanarPose,
    /// The pose's covariance (the odometry's own).
    pub covariance: PlanarCovariance,
    /// The base's twist in its own frame.
    pub twist: [f64; 3],
}

/// A pending predicted sample's odometry part.
#[derive(Clone, Copy, Debug, Default)]
struct PendingPose {
    start: f64,
    t: f64,
    pose: PlanarPose,
    covariance: PlanarCovariance,
    /// Its command changed before it was due.
    command_changed: bool,
    /// The command held and the start's measured velocity (v, ω).
    command: [f64; 2],
    start_velocity: [f64; 2],
}

/// A ring of pending samples, ordered by due time, its joints in flat arrays beside it. The
/// n-th sample recorded (n from 0) sits in slot n mod capacity; the odometry, and each joint's
/// position and effort apart (joint states may each give some joints only), keep the number
/// of the next sample they score.
#[derive(Clone, Debug)]
struct Pending {
    poses: Vec<PendingPose>,
    /// Slot i's efforts at [i·ne, (i+1)·ne).
    efforts: Vec<f64>,
    /// Slot i's joint positions at [i·ne, (i+1)·ne).
    positions: Vec<f64>,
    /// Samples recorded.
    recorded: u64,
    /// The next sample the odometry scores.
    pose_next: u64,
    /// The next sample each joint's position (j) and effort (ne + j) scores.
    joint_next: Vec<u64>,
}

impl Pending {
    fn slot(&self, n: u64) -> usize {
        (n % self.poses.len() as u64) as usize
    }

    /// Forgets every pending sample.
    fn clear(&mut self) {
        self.pose_next = self.recorded;
        self.joint_next.fill(self.recorded);
    }
}

/// One horizon's statistics.
#[derive(Clone, Debug)]
struct Track {
    horizon: f64,
    pending: Pending,
    position: Window,
    yaw: Window,
    nees: Window,
    /// One window of signed effort errors per joint.
    effort: Vec<Window>,
    /// One window of signed position errors per joint.
    position_joint: Vec<Window>,
    /// Predictions whose measurement came too late or never (overwritten while pending).
    unmatched: usize,
    /// Predictions not scored: their command changed before they were due.
    command_changed: usize,
    response: ResponseWindow,
}

/// One horizon's figures (NaN where there are no samples yet).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HorizonReport {
    /// [s]
    pub horizon: f64,
    /// Odometry samples in the window.
    pub odometry_samples: usize,
    /// Median |(dx, dy)| [m].
    pub position_median: f64,
    /// Median |dyaw| [rad].
    pub yaw_median: f64,
    /// Median NEES (χ²₃ under a consistent model: median 2.366).
    pub nees_median: f64,
    /// Mean NEES (χ²₃: 3).
    pub nees_mean: f64,
    /// Joint state samples in the window (of the joint with the most).
    pub effort_samples: usize,
    /// The joint whose median signed effort error is largest in magnitude, and that median
    /// [N·m or N] (None before any joint state).
    pub effort_worst: Option<(usize, f64)>,
    /// Joint position samples in the window (of the joint with the most).
    pub joint_position_samples: usize,
    /// The joint whose median signed position error is largest in magnitude, and that median
    /// [rad or m] (None before any joint state with positions).
    pub joint_position_worst: Option<(usize, f64)>,
    /// Predictions not matched by a measurement in time.
    pub unmatched: usize,
    /// Predictions not scored because their command changed before they were due.
    pub command_changed: usize,
    /// How the drive answers its commands over the window (None below four predictions or
    /// where the commands do not determine it).
    pub response: Option<ResponseFit>,
}

/// The measured start states' velocity residual off the constraints.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlipReport {
    /// Measured states in the window.
    pub samples: usize,
    /// Their median ‖J v‖ before the projection [m/s or rad/s] (NaN before any).
    pub residual_median: f64,
}

/// Scores past predictions (see the module's documentation).
#[derive(Clone, Debug)]
pub struct PredictionMonitor {
    settings: MonitorSettings,
    joints: usize,
    tracks: Vec<Track>,
    /// The measured start states' velocity residuals.
    slip: Window,
    scratch: Vec<f64>,
    reports: Vec<HorizonReport>,
    verdict: verdict::Hysteresis,
}

impl PredictionMonitor {
    /// A monitor of `joints` efforts (0: poses only).
    pub fn new(settings: MonitorSettings, joints: usize) -> Self {
        let cap = settings.pending.max(1);
        let window = settings.window.max(1);
        let tracks = settings
            .horizons
            .iter()
            .map(|&horizon| Track {
                horizon,
                pending: Pending {
                    poses: vec![PendingPose::default(); cap],
                    efforts: vec![0.0; cap * joints],
                    positions: vec![0.0; cap * joints],
                    recorded: 0,
                    pose_next: 0,
                    joint_next: vec![0; 2 * joints],
                },
                position: Window::new(window),
                yaw: Window::new(window),
                nees: Window::new(window),
                effort: vec![Window::new(window); joints],
                position_joint: vec![Window::new(window); joints],
                unmatched: 0,
                command_changed: 0,
                response: ResponseWindow::new(window),
            })
            .collect();
        let reports = Vec::with_capacity(settings.horizons.len());
        let slip_window = settings.slip_window.max(1);
        PredictionMonitor {
            slip: Window::new(slip_window),
            scratch: vec![0.0; window.max(slip_window)],
            verdict: verdict::Hysteresis::default(),
            settings,
            joints,
            tracks,
            reports,
        }
    }

    /// The settings it scores with.
    pub fn settings(&self) -> &MonitorSettings {
        &self.settings
    }

    /// Forgets every pending prediction and statistic (a new model, a jump in time).
    pub fn reset(&mut self) {
        for tr in &mut self.tracks {
            tr.pending.clear();
            tr.position.clear();
            tr.yaw.clear();
            tr.nees.clear();
            tr.effort.iter_mut().for_each(Window::clear);
            tr.position_joint.iter_mut().for_each(Window::clear);
            tr.unmatched = 0;
            tr.command_changed = 0;
            tr.response.clear();
        }
        self.slip.clear();
        self.verdict = verdict::Hysteresis::default();
    }

    /// Records the predicted sample of horizon `index` (in `settings.horizons`). A sample due
    /// before one already pending (time went back) restarts that horizon's queue.
    pub fn record(&mut self, index: usize, s: &PredictedSample) {
        let ne = self.joints;
        let Some(tr) = self.tracks.get_mut(index) else {
            return;
        };
        let p = &mut tr.pending;
        let cap = p.poses.len() as u64;
        if p.recorded > 0 && s.t < p.poses[p.slot(p.recorded - 1)].t {
            p.clear();
        }
        // A full ring drops its oldest (an unmatched prediction).
        let oldest_kept = (p.recorded + 1).saturating_sub(cap);
        if p.pose_next < oldest_kept {
            p.pose_next = oldest_kept;
            tr.unmatched += 1;
        }
        for n in &mut p.joint_next {
            *n = (*n).max(oldest_kept);
        }
        let i = p.slot(p.recorded);
        p.poses[i] = PendingPose {
            start: s.start,
            t: s.t,
            pose: s.pose,
            covariance: s.covariance,
            command_changed: false,
            command: s.command,
            start_velocity: s.start_velocity,
        };
        for (from, to) in [(s.effort, &mut p.efforts), (s.position, &mut p.positions)] {
            let slot = &mut to[i * ne..(i + 1) * ne];
            match from.len() == ne {
                true => slot.copy_from_slice(from),
                false => slot.fill(f64::NAN),
            }
        }
        p.recorded += 1;
    }

    /// The command changed at `t` [s]: the pending predictions that started before `t` and are
    /// due at or after it held another command than the robot had, and are not scored.
    pub fn command_changed(&mut self, t: f64) {
        for tr in &mut self.tracks {
            for p in &mut tr.pending.poses {
                if p.start < t && t <= p.t {
                    p.command_changed = true;
                }
            }
        }
    }

    /// Scores the pending predictions due at or before `m.t` against the odometry `m`.
    pub fn odometry(&mut self, m: &MeasuredOdometry) {
        let max_lag = self.settings.max_lag;
        for tr in &mut self.tracks {
            let p = &mut tr.pending;
            while p.pose_next < p.recorded && p.poses[p.slot(p.pose_next)].t <= m.t {
                let due = p.poses[p.slot(p.pose_next)];
                p.pose_next += 1;
                let lag = m.t - due.t;
                if lag > max_lag {
                    tr.unmatched += 1;
                    continue;
                }
                if due.command_changed {
                    tr.command_changed += 1;
                    continue;
                }
                let back = pose_back_along(&m.pose, &m.twist, lag);
                let e = [
                    back[0] - due.pose[0],
                    back[1] - due.pose[1],
                    yaw_difference(back[2], due.pose[2]),
                ];
                if !e.iter().all(|x| x.is_finite()) {
                    continue;
                }
                tr.position.push(e[0].hypot(e[1]));
                tr.yaw.push(e[2].abs());
                let mut s = due.covariance;
                for (r, mr) in s.iter_mut().zip(&m.covariance) {
                    for (x, mx) in r.iter_mut().zip(mr) {
                        *x += mx;
                    }
                }
                if let Some(n) = nees(e, &s) {
                    tr.nees.push(n);
                }
                tr.response.push(&ScoredResponse {
                    error: e,
                    predicted_yaw: due.pose[2],
                    covariance: &s,
                    command: due.command,
                    start_velocity: due.start_velocity,
                    horizon: due.t - due.start,
                });
            }
        }
    }

    /// Scores the pending predictions due at or before `t` [s] against the joints' measured
    /// positions [rad or m] and efforts [N·m or N], one of each per joint (NaN: not in this
    /// joint state, whose predictions wait for one that gives it). Position errors are wrapped
    /// to (−π, π]: a revolute joint reported modulo 2π scores its true error, and a prismatic
    /// joint's errors are far below π m.
    pub fn joint_states(&mut self, t: f64, position: &[f64], effort: &[f64]) {
        let (ne, max_lag) = (self.joints, self.settings.max_lag);
        if ne == 0 || effort.len() != ne || position.len() != ne {
            return;
        }
        for tr in &mut self.tracks {
            let p = &mut tr.pending;
            let measured = position.iter().chain(effort);
            for (k, (&m, next)) in measured.zip(p.joint_next.iter_mut()).enumerate() {
                if !m.is_finite() {
                    continue;
                }
                let (j, is_position) = (k % ne, k < ne);
                let (predicted, window) = match is_position {
                    true => (&p.positions, &mut tr.position_joint[j]),
                    false => (&p.efforts, &mut tr.effort[j]),
                };
                let cap = p.poses.len() as u64;
                while *next < p.recorded && p.poses[(*next % cap) as usize].t <= t {
                    let i = (*next % cap) as usize;
                    *next += 1;
                    let due = &p.poses[i];
                    if t - due.t > max_lag || due.command_changed {
                        continue;
                    }
                    let pr = predicted[i * ne + j];
                    let e = match is_position {
                        true => yaw_difference(m, pr),
                        false => m - pr,
                    };
                    if e.is_finite() {
                        window.push(e);
                    }
                }
            }
        }
    }

    /// A measured start state lay `velocity_residual` ‖J v‖ [m/s or rad/s] off the velocity
    /// constraints before its projection (a non-finite one is not taken).
    pub fn measured_state(&mut self, velocity_residual: f64) {
        if velocity_residual.is_finite() {
            self.slip.push(velocity_residual);
        }
    }

    /// The measured states' velocity residual, computed now.
    pub fn slip_report(&mut self) -> SlipReport {
        SlipReport {
            samples: self.slip.len(),
            residual_median: self.slip.median(&mut self.scratch),
        }
    }

    /// Each horizon's figures, computed now (no allocation after the first call).
    pub fn reports(&mut self) -> &[HorizonReport] {
        self.reports.clear();
        let s = &mut self.scratch;
        for tr in &self.tracks {
            let worst = |windows: &[Window], s: &mut [f64]| {
                windows
                    .iter()
                    .enumerate()
                    .filter(|(_, w)| !w.is_empty())
                    .map(|(j, w)| (j, w.median(s)))
                    .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
            };
            let most = |windows: &[Window]| windows.iter().map(Window::len).max().unwrap_or(0);
            self.reports.push(HorizonReport {
                horizon: tr.horizon,
                odometry_samples: tr.position.len(),
                position_median: tr.position.median(s),
                yaw_median: tr.yaw.median(s),
                nees_median: tr.nees.median(s),
                nees_mean: tr.nees.mean(),
                effort_samples: most(&tr.effort),
                effort_worst: worst(&tr.effort, s),
                joint_position_samples: most(&tr.position_joint),
                joint_position_worst: worst(&tr.position_joint, s),
                unmatched: tr.unmatched,
                command_changed: tr.command_changed,
                response: tr.response.fit(),
            });
        }
        &self.reports
    }

    /// The verdict on the latest figures, with hysteresis: a cause is called once its figure
    /// passes its threshold over at least `min_samples` samples (the slip: over a full
    /// `slip_window`), and cleared once it falls below `clear_ratio` × the threshold. Returns
    /// it and whether it changed.
    pub fn assess(&mut self) -> (Verdict, bool) {
        self.reports();
        let slip = (self.slip.len() >= self.settings.slip_window.max(1))
            .then(|| self.slip_report().residual_median);
        let t = &self.settings.thresholds;
        self.verdict.update(&self.reports, slip, t)
    }
}

/// `pose` carried back by `lag` [s] along `twist` (base frame; first order).
fn pose_back_along(pose: &PlanarPose, twist: &[f64; 3], lag: f64) -> PlanarPose {
    if lag <= 0.0 || !twist.iter().all(|x| x.is_finite()) {
        return *pose;
    }
    let (s, c) = pose[2].sin_cos();
    [
        pose[0] - lag * (c * twist[0] - s * twist[1]),
        pose[1] - lag * (s * twist[0] + c * twist[1]),
        pose[2] - lag * twist[2],
    ]
}

#[cfg(test)]
mod response_tests;
#[cfg(test)]
mod tests;
