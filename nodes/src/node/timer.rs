//! A period on the ROS clock for the worker's ticks and diagnostics.

use std::time::{Duration, Instant};

use crate::msg::builtin_interfaces::Time;

/// A period on the ROS clock: wall time, or `/clock` under `use_sim_time` (then it follows the
/// simulation's time, faster or slower than real time, and stops with it).
pub(crate) struct RosTimer {
    period: Duration,
    next_wall: Instant,
    next_sim: Option<Time>,
}

impl RosTimer {
    pub(crate) fn new(period: Duration) -> Self {
        RosTimer {
            period,
            next_wall: Instant::now(),
            next_sim: None,
        }
    }

    /// Fire at the next check.
    pub(crate) fn reset(&mut self) {
        self.next_wall = Instant::now();
        self.next_sim = None;
    }

    /// How long the worker may sleep before this timer needs a check.
    pub(crate) fn wait(&self, sim: bool) -> Duration {
        if sim {
            Duration::from_secs(3600) // /clock messages wake the worker
        } else {
            self.next_wall.saturating_duration_since(Instant::now())
        }
    }

    /// True (once) when the period has passed; behind, it does not catch up.
    pub(crate) fn due(&mut self, sim: Option<Option<Time>>) -> bool {
        match sim {
            Some(Some(now)) => {
                if self.next_sim.is_none_or(|n| now.to_nanos() >= n.to_nanos()) {
                    self.next_sim = Some(crate::convert::time_plus(now, self.period.as_secs_f64()));
                    return true;
                }
                false
            }
            Some(None) => false,
            None => {
                if Instant::now() < self.next_wall {
                    return false;
                }
                self.next_wall += self.period;
                if self.next_wall < Instant::now() {
                    self.next_wall = Instant::now() + self.period;
                }
                true
            }
        }
    }
}

/// Niceness of a periodic worker's thread: the predictor's predictions (tens of ms of CPU
/// each) yield to the threads that serve requests, so a service call does not wait behind a
/// prediction for a core (on two cores it otherwise does: see docs/nodes.md, "Load and churn").
pub(crate) const PERIODIC_NICE: i32 = 10;

/// Time slice [ns] asked for a periodic worker's thread: the scheduler's minimum (Linux ≥ 6.12
/// takes a fair thread's slice from `sched_attr.sched_runtime`, clamped to 0.1–100 ms; older
/// kernels ignore it). Once picked, a thread runs its slice before a waking thread of the same
/// class may preempt it (EEVDF's run-to-parity), so a request woken on the predictor's core
/// waits up to the slice behind a prediction: by default 0.7 ms × (1 + log₂ cores). Measured
/// (nodes/tests/it/suite_load.rs, idle 2-core VM, alternated runs): p99 of the service calls
/// 0.87–1.06 ms with this slice against 1.39 ms with the default 1.4 ms, calls over 2 ms 363–542
/// against 829–868 of ~109 000, the predictor's rate 10 Hz with either.
const PERIODIC_SLICE_NS: u64 = 100_000;

/// `struct sched_attr` of sched_setattr(2), its first version (48 bytes).
#[repr(C)]
struct SchedAttr {
    size: u32,
    sched_policy: u32,
    sched_flags: u64,
    sched_nice: i32,
    sched_priority: u32,
    sched_runtime: u64,
    sched_deadline: u64,
    sched_period: u64,
}

/// Lowers the calling thread's scheduling priority (Linux: all three are per thread): the batch
/// policy, so that its wake-up at every tick does not preempt a thread serving a request (a
/// niced thread may still preempt one on waking; the kernel never preempts on behalf of a
/// waking batch thread), [`PERIODIC_NICE`], its share of a busy core, and
/// [`PERIODIC_SLICE_NS`], how long it holds a core against a waking request. Not `SCHED_IDLE`:
/// under a steady request load that starves the predictor. A failure only costs latency, so it
/// is ignored (without sched_setattr, sched_setscheduler and setpriority set the policy and
/// niceness, and the slice stays the kernel's).
pub(crate) fn lower_priority() {
    let attr = SchedAttr {
        size: std::mem::size_of::<SchedAttr>() as u32,
        sched_policy: libc::SCHED_BATCH as u32,
        sched_flags: 0,
        sched_nice: PERIODIC_NICE,
        sched_priority: 0,
        sched_runtime: PERIODIC_SLICE_NS,
        sched_deadline: 0,
        sched_period: 0,
    };
    // SAFETY: gettid has no preconditions; sched_setattr reads `attr.size` bytes of a live
    // struct of that size; sched_setscheduler and setpriority on our own thread id only change
    // this thread's policy and niceness.
    unsafe {
        let tid = libc::syscall(libc::SYS_gettid) as libc::pid_t;
        if libc::syscall(
            libc::SYS_sched_setattr,
            tid,
            &attr as *const SchedAttr,
            0u32,
        ) == 0
        {
            return;
        }
        let param = libc::sched_param { sched_priority: 0 };
        libc::sched_setscheduler(tid, libc::SCHED_BATCH, &param);
        libc::setpriority(libc::PRIO_PROCESS, tid as libc::id_t, PERIODIC_NICE);
    }
}

#[cfg(test)]
mod tests {
    /// Whether the running kernel's release is at least `major.minor`.
    fn kernel_at_least(major: u32, minor: u32) -> bool {
        let release = std::fs::read_to_string("/proc/sys/kernel/osrelease").unwrap_or_default();
        let mut parts = release.split(|c: char| !c.is_ascii_digit());
        let mut next = || {
            parts
                .next()
                .and_then(|p| p.parse::<u32>().ok())
                .unwrap_or(0)
        };
        (next(), next()) >= (major, minor)
    }

    /// The kernel's own account of the thread (`/proc/thread-self/sched`): `field` as a number.
    fn sched_field(field: &str) -> Option<f64> {
        let text = std::fs::read_to_string("/proc/thread-self/sched").ok()?;
        text.lines().find_map(|l| {
            let (k, v) = l.split_once(':')?;
            (k.trim() == field).then(|| v.trim().parse().ok())?
        })
    }

    #[test]
    fn lower_priority_gives_batch_nice_and_the_short_slice() {
        let got = std::thread::spawn(|| {
            let before = sched_field("se.slice");
            super::lower_priority();
            (
                sched_field("policy"),
                sched_field("prio"),
                before,
                sched_field("se.slice"),
            )
        })
        .join()
        .unwrap();
        let (policy, prio, before, slice) = got;
        assert_eq!(policy, Some(libc::SCHED_BATCH as f64), "policy");
        // prio = 120 + nice for the fair classes.
        assert_eq!(prio, Some(120.0 + super::PERIODIC_NICE as f64), "prio");
        // Kernels that take a custom slice (≥ 6.12; they report it): the default is
        // 0.7 ms × (1 + log₂ cores), never the 0.1 ms asked for.
        if kernel_at_least(6, 12) {
            let (before, slice) = (before.expect("se.slice"), slice.expect("se.slice"));
            assert!(before > 1.5e5, "default slice {before} ns");
            assert_eq!(slice, super::PERIODIC_SLICE_NS as f64, "slice [ns]");
        }
    }
}
