//! A recording as plain time series: what a robot's odometry, joint states and velocity commands
//! said, and when. No message format: a log reader (the ROS 2 bag reader of the nodes crate) or
//! a live node fills these.
//!
//! Times are integer nanoseconds on the recording's clock, so that "the last sample at or before
//! t" is exact: a 50 Hz odometry and a start grid of 0.5 s meet on the same instants without a
//! rounding that would pick the sample 20 ms earlier.

use super::ReplayError;
use crate::model::{BasePose, BaseTwist};
use std::collections::HashMap;

/// A time on the recording's clock [ns] (e.g. a ROS stamp, sec × 10⁹ + nanosec).
pub type Nanos = i64;

/// `stamp` as "sec.nanosec" (a ROS stamp), for messages that name a sample.
pub fn show_stamp(stamp: Nanos) -> String {
    format!(
        "{}.{:09}",
        stamp.div_euclid(1_000_000_000),
        stamp.rem_euclid(1_000_000_000)
    )
}

/// One named series of timed samples (a topic), in time order.
#[derive(Clone, Debug)]
pub struct Series<T> {
    /// What the series is (a topic name such as `/odom`): errors name it.
    pub name: String,
    /// (time [ns], sample), non-decreasing in time.
    pub samples: Vec<(Nanos, T)>,
}

impl<T> Default for Series<T> {
    fn default() -> Self {
        Series::new("")
    }
}

impl<T> Series<T> {
    /// An empty series called `name`.
    pub fn new(name: impl Into<String>) -> Self {
        Series {
            name: name.into(),
            samples: Vec::new(),
        }
    }

    /// The last sample at or before `t`.
    pub fn at_or_before(&self, t: Nanos) -> Option<&(Nanos, T)> {
        let n = self.samples.partition_point(|(ts, _)| *ts <= t);
        n.checked_sub(1).map(|i| &self.samples[i])
    }

    /// The samples in (after, until], in order.
    pub fn between(&self, after: Nanos, until: Nanos) -> &[(Nanos, T)] {
        let a = self.samples.partition_point(|(ts, _)| *ts <= after);
        let b = self.samples.partition_point(|(ts, _)| *ts <= until);
        &self.samples[a..b.max(a)]
    }

    /// First and last time, or an error naming the series when it is empty.
    pub fn span(&self) -> Result<(Nanos, Nanos), ReplayError> {
        match (self.samples.first(), self.samples.last()) {
            (Some(a), Some(b)) => Ok((a.0, b.0)),
            _ => Err(ReplayError::Empty {
                series: self.name.clone(),
            }),
        }
    }

    /// Checks the order: no time going back, and (with `max_gap`) no gap longer than it [ns].
    /// `origin` is the recording's start, for the time an error states.
    pub fn check_times(&self, origin: Nanos, max_gap: Option<Nanos>) -> Result<(), ReplayError> {
        for w in self.samples.windows(2) {
            let (a, b) = (w[0].0, w[1].0);
            let at_s = (b - origin) as f64 * 1e-9;
            if b < a {
                return Err(ReplayError::TimeJump {
                    series: self.name.clone(),
                    at_s,
                    stamp: show_stamp(b),
                    back_s: (a - b) as f64 * 1e-9,
                });
            }
            if let Some(gap) = max_gap.filter(|g| b - a > *g) {
                return Err(ReplayError::Gap {
                    series: self.name.clone(),
                    after_s: (a - origin) as f64 * 1e-9,
                    stamp: show_stamp(a),
                    gap_s: (b - a) as f64 * 1e-9,
                    max_gap_s: gap as f64 * 1e-9,
                });
            }
        }
        Ok(())
    }
}

/// One odometry sample: the base pose in the world (odom) frame and its twist in the base frame,
/// with their covariances, each a row-major 6×6 over (x, y, z, rotation about X, Y, Z) and
/// (vx, vy, vz, ωx, ωy, ωz) — REP-103's layout (model/base_covariance.rs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Odometry {
    /// Base pose, world frame.
    pub pose: BasePose,
    /// Base twist, base frame.
    pub twist: BaseTwist,
    /// Pose covariance [m², m·rad, rad²].
    pub pose_covariance: [f64; 36],
    /// Twist covariance [(m/s)², …].
    pub twist_covariance: [f64; 36],
}

/// One joint-state sample: names with positions, velocities and efforts (each array empty or as
/// long as the names).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct JointStates {
    /// Joint names.
    pub name: Vec<String>,
    /// Positions [rad or m].
    pub position: Vec<f64>,
    /// Velocities [rad/s or m/s].
    pub velocity: Vec<f64>,
    /// Efforts [N·m or N].
    pub effort: Vec<f64>,
}

/// A recorded drive: the state inputs, the base commands and the poses predictions are scored
/// against (the odometry itself, or a ground truth).
#[derive(Clone, Debug, Default)]
pub struct Recording {
    /// Odometry: the start state's base.
    pub odometry: Series<Odometry>,
    /// Joint states: the start state's joints.
    pub joint_states: Series<JointStates>,
    /// Base commands (v [m/s], ω [rad/s]) as a differential drive takes them.
    pub commands: Series<[f64; 2]>,
    /// The poses predictions are compared with (with their covariances).
    pub reference: Series<Odometry>,
}

impl Recording {
    /// The earliest time of any series (the origin of the times errors and records state).
    pub fn origin(&self) -> Nanos {
        [
            self.odometry.samples.first().map(|s| s.0),
            self.joint_states.samples.first().map(|s| s.0),
            self.commands.samples.first().map(|s| s.0),
            self.reference.samples.first().map(|s| s.0),
        ]
        .into_iter()
        .flatten()
        .min()
        .unwrap_or(0)
    }

    /// Checks every series: the state inputs and the reference present, time never going back,
    /// no gap in the state inputs or the reference longer than `max_gap` [ns]; every sample's
    /// arrays consistent and its used values finite.
    pub fn check(&self, max_gap: Nanos) -> Result<(), ReplayError> {
        let origin = self.origin();
        self.odometry.span()?;
        self.joint_states.span()?;
        self.reference.span()?;
        self.odometry.check_times(origin, Some(max_gap))?;
        self.joint_states.check_times(origin, Some(max_gap))?;
        self.reference.check_times(origin, Some(max_gap))?;
        // Commands are events: a controller holds the last one, so a pause is no gap.
        self.commands.check_times(origin, None)?;
        let bad = |series: &str, t: Nanos, what: String| ReplayError::BadSample {
            series: series.to_string(),
            at_s: (t - origin) as f64 * 1e-9,
            stamp: show_stamp(t),
            what,
        };
        for s in [&self.odometry, &self.reference] {
            for (t, o) in &s.samples {
                if let Some(what) = odometry_fault(o) {
                    return Err(bad(&s.name, *t, what));
                }
            }
        }
        for (t, js) in &self.joint_states.samples {
            let n = js.name.len();
            for (what, a) in [
                ("position", &js.position),
                ("velocity", &js.velocity),
                ("effort", &js.effort),
            ] {
                if !a.is_empty() && a.len() != n {
                    let why = format!("{} {what} entries for {n} names", a.len());
                    return Err(bad(&self.joint_states.name, *t, why));
                }
                if let Some(x) = a.iter().find(|x| !x.is_finite()) {
                    let why = format!("a {what} is not finite ({x})");
                    return Err(bad(&self.joint_states.name, *t, why));
                }
            }
        }
        for (t, c) in &self.commands.samples {
            if !(c[0].is_finite() && c[1].is_finite()) {
                let why = format!("command (v, ω) = ({}, {}) is not finite", c[0], c[1]);
                return Err(bad(&self.commands.name, *t, why));
            }
        }
        Ok(())
    }
}

/// What makes an odometry sample unusable, if anything.
fn odometry_fault(o: &Odometry) -> Option<String> {
    let values = (o.pose.position.iter())
        .chain(&o.pose.orientation_xyzw)
        .chain(&o.twist.linear)
        .chain(&o.twist.angular)
        .chain(&o.pose_covariance)
        .chain(&o.twist_covariance);
    if let Some(x) = values.into_iter().find(|x| !x.is_finite()) {
        return Some(format!(
            "a pose, twist or covariance value is not finite ({x})"
        ));
    }
    let n2: f64 = o.pose.orientation_xyzw.iter().map(|x| x * x).sum();
    if n2 < 1e-12 {
        return Some("the orientation is a zero quaternion".into());
    }
    let negative = |c: &[f64; 36]| (0..6).any(|i| c[7 * i] < 0.0);
    if negative(&o.pose_covariance) || negative(&o.twist_covariance) {
        return Some("a covariance has a negative variance".into());
    }
    None
}

/// Each joint's own track through a joint-state series: (time, position, velocity, effort) of
/// every sample that names it, so that a start state takes each joint's last value even when joints
/// come in separate messages.
#[derive(Clone, Debug, Default)]
pub struct JointTracks {
    tracks: HashMap<String, Vec<JointPoint>>,
}

/// One joint at one time: (time, position if given, velocity if given, effort if given).
pub type JointPoint = (Nanos, Option<f64>, Option<f64>, Option<f64>);

impl JointTracks {
    /// The tracks of `series` (checked by [`Recording::check`]).
    pub fn new(series: &Series<JointStates>) -> Self {
        let mut tracks: HashMap<String, Vec<_>> = HashMap::new();
        for (t, js) in &series.samples {
            for (k, name) in js.name.iter().enumerate() {
                let p = js.position.get(k).copied();
                let v = js.velocity.get(k).copied();
                let e = js.effort.get(k).copied();
                tracks.entry(name.clone()).or_default().push((*t, p, v, e));
            }
        }
        JointTracks { tracks }
    }

    /// The last (time, position, velocity, effort) of joint `name` at or before `t`.
    pub fn at_or_before(&self, name: &str, t: Nanos) -> Option<JointPoint> {
        let track = self.tracks.get(name)?;
        let n = track.partition_point(|(ts, ..)| *ts <= t);
        n.checked_sub(1).map(|i| track[i])
    }
}
