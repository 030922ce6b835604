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
/// prediction for a core (on two cores it did: see docs/nodes.md, "Load and churn").
pub(crate) const PERIODIC_NICE: i32 = 10;

/// Lowers the calling thread's scheduling priority (Linux: both are per thread): the batch
/// policy, so that its wake-up at every tick does not preempt a thread serving a request (a
/// niced thread may still preempt one on waking; the kernel never preempts on behalf of a
/// waking batch thread), and [`PERIODIC_NICE`], its share of a busy core. Not `SCHED_IDLE`: under a steady request
/// load that starves the predictor. A failure only costs latency, so it is ignored.
pub(crate) fn lower_priority() {
    // SAFETY: gettid has no preconditions; sched_setscheduler and setpriority on our own
    // thread id only change this thread's policy and niceness.
    unsafe {
        let tid = libc::syscall(libc::SYS_gettid) as libc::pid_t;
        let param = libc::sched_param { sched_priority: 0 };
        libc::sched_setscheduler(tid, libc::SCHED_BATCH, &param);
        libc::setpriority(libc::PRIO_PROCESS, tid as libc::id_t, PERIODIC_NICE);
    }
}
