//! Returning freed heap to the operating system.
//!
//! DDS discovery allocates for every participant that appears (SEDP samples, receive buffers,
//! topic records) and frees it when the participant leaves. glibc's malloc keeps most freed
//! memory in its per-thread arenas rather than giving it back, so a suite on a network where
//! participants come and go grows in RSS although its live heap does not: 7–10 MB over 1 000
//! participants in `tests/suite_churn.rs`, about 3 MB with [`release_free_heap`] run every
//! [`PERIOD`]. The suite's main thread calls [`HeapTrimmer::tick`] between its sleeps.

use std::time::{Duration, Instant};

/// How often freed heap is returned. Wall-clock time: this is process housekeeping, not a
/// ROS timer, so it runs the same under `use_sim_time`. A trim walks every arena under its
/// lock: 0.1–3.6 ms for this suite's heap (measured during the churn test), so a call that
/// allocates meanwhile may wait that long once per period.
pub const PERIOD: Duration = Duration::from_secs(5);

/// Calls [`release_free_heap`] at most once per [`PERIOD`].
pub struct HeapTrimmer {
    last: Instant,
}

impl Default for HeapTrimmer {
    fn default() -> Self {
        Self {
            last: Instant::now(),
        }
    }
}

impl HeapTrimmer {
    /// Trims when [`PERIOD`] has passed since the last trim.
    pub fn tick(&mut self) {
        if self.last.elapsed() < PERIOD {
            return;
        }
        self.last = Instant::now();
        if let Some(r) = release_free_heap() {
            log::debug!(
                target: "constraint_dynamics_nodes",
                "heap trim: RSS {} → {} kB in {:.2} ms",
                r.rss_before_kb,
                r.rss_after_kb,
                r.took.as_secs_f64() * 1e3
            );
        }
    }
}

/// What a trim did.
#[derive(Debug, Clone, Copy)]
pub struct Released {
    /// Resident set size before the trim [kB].
    pub rss_before_kb: u64,
    /// Resident set size after the trim [kB].
    pub rss_after_kb: u64,
    /// Wall-clock time of the trim.
    pub took: Duration,
}

/// Returns the memory malloc holds free to the OS (`malloc_trim(0)`); `None` on a C library
/// without it.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
pub fn release_free_heap() -> Option<Released> {
    let rss_before_kb = rss_kb();
    let started = Instant::now();
    // SAFETY: malloc_trim only rearranges malloc's own bookkeeping under its locks; it is
    // safe to call from any thread at any time.
    unsafe { libc::malloc_trim(0) };
    Some(Released {
        rss_before_kb,
        rss_after_kb: rss_kb(),
        took: started.elapsed(),
    })
}

/// Returns the memory malloc holds free to the OS: not available outside glibc.
#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
pub fn release_free_heap() -> Option<Released> {
    None
}

/// This process's resident set size [kB] (0 when /proc is unreadable).
fn rss_kb() -> u64 {
    std::fs::read_to_string("/proc/self/statm")
        .ok()
        .and_then(|s| s.split_whitespace().nth(1)?.parse::<u64>().ok())
        .map_or(0, |pages| pages * page_size_kb())
}

fn page_size_kb() -> u64 {
    // SAFETY: sysconf reads a constant of the running system.
    let bytes = unsafe { libc::sysconf(libc::_SC_PAGESIZE) };
    (bytes.max(4096) as u64) / 1024
}
