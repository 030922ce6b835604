//! `builtin_interfaces/msg/*`.

use serde::{Deserialize, Serialize};

/// `builtin_interfaces/msg/Time`: seconds and nanoseconds since the Unix epoch
/// (or since the start of simulated time).
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize,
)]
pub struct Time {
    /// Whole seconds [s].
    pub sec: i32,
    /// Nanoseconds past `sec`, in `0..1_000_000_000` [ns].
    pub nanosec: u32,
}

impl Time {
    /// From nanoseconds since the epoch (saturating at the `i32` range of `sec`).
    pub fn from_nanos(nanos: i64) -> Self {
        let sec = nanos.div_euclid(1_000_000_000);
        let nanosec = nanos.rem_euclid(1_000_000_000) as u32;
        Time {
            sec: sec.clamp(i32::MIN as i64, i32::MAX as i64) as i32,
            nanosec,
        }
    }

    /// The system clock (wall time, not simulated time).
    pub fn now() -> Self {
        let d = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap_or_default();
        Time::from_nanos(d.as_nanos().min(i64::MAX as u128) as i64)
    }

    /// Nanoseconds since the epoch.
    pub fn to_nanos(self) -> i64 {
        self.sec as i64 * 1_000_000_000 + self.nanosec as i64
    }

    /// Seconds as a float [s].
    pub fn to_secs(self) -> f64 {
        self.sec as f64 + self.nanosec as f64 * 1e-9
    }
}

impl From<ros2_client::ROSTime> for Time {
    fn from(t: ros2_client::ROSTime) -> Self {
        Time::from_nanos(t.to_nanos())
    }
}

/// `builtin_interfaces/msg/Duration`: a signed span of time.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Duration {
    /// Whole seconds [s].
    pub sec: i32,
    /// Nanoseconds past `sec`, in `0..1_000_000_000` [ns].
    pub nanosec: u32,
}

impl Duration {
    /// From seconds (rounded to the nanosecond; saturating; non-finite → zero).
    pub fn from_secs_f64(s: f64) -> Self {
        if !s.is_finite() {
            return Duration::default();
        }
        let t = Time::from_nanos((s * 1e9).round().clamp(i64::MIN as f64, i64::MAX as f64) as i64);
        Duration {
            sec: t.sec,
            nanosec: t.nanosec,
        }
    }
}

super::ros_messages!("builtin_interfaces": Time, Duration);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nanos_round_trip_including_negative() {
        for n in [
            0,
            1,
            999_999_999,
            1_000_000_000,
            1_700_000_123_456_789_012,
            -1,
            -1_500_000_000,
        ] {
            let t = Time::from_nanos(n);
            assert!(t.nanosec < 1_000_000_000);
            assert_eq!(t.to_nanos(), n);
        }
        assert_eq!(
            Time::from_nanos(-1),
            Time {
                sec: -1,
                nanosec: 999_999_999
            }
        );
    }
}
