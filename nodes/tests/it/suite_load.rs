//! Load: two clients, each its own DDS participant (as two processes would be), call
//! `~/get_constraint_forces` and `~/project_velocity` alternately at 1 kHz each for
//! `CD_LOAD_SECONDS` (default 60 s), the predictor inactive for their first 15 s and predicting
//! at 10 Hz after. Asserted: every call answered (a call without a reply within 2 s counts as
//! lost); the p99 latency while predicting under 3 ms or, where the same calls without
//! predictions are slower, under `latency_bar_ms` of theirs (a probe thread beside the load
//! also prints the machine's own scheduling tail); the suite's RSS growth from 20 s on under 5 %;
//! the prediction rate under load held (0.65 of the lower of the rates before and after the
//! clients) or its drop reported on `/diagnostics`, and never starved; then SIGINT under 1 s.
//! A client that pipelines its requests is `suite_load_pipelined`.
//!
//! Measured figures are printed (`-- --nocapture`); docs/nodes.md ("Load and churn") has them.

use crate::common;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use common::*;
use constraint_dynamics_nodes::msg::constraint_dynamics_msgs::srv::{
    GetConstraintForces, GetConstraintForcesRequest, ProjectVelocity, ProjectVelocityRequest,
};
use constraint_dynamics_nodes::msg::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus};
use constraint_dynamics_nodes::msg::lifecycle_msgs::{ChangeState, ChangeStateRequest, Transition};
use constraint_dynamics_nodes::msg::nav_msgs::Path;

const TEST: &str = "two_clients_at_1khz_every_call_answered";
/// A call without a reply this long is lost.
const LOST_AFTER: Duration = Duration::from_secs(2);
/// Latencies are counted after this (discovery settling, first allocations).
const WARM_UP: Duration = Duration::from_secs(5);
/// The predictor is inactive (lifecycle) until this point of the run: the calls from `WARM_UP`
/// to here are the same clients on the same machine without predictions, the reference the
/// calls under predictions are judged against.
const PREDICTOR_FROM: Duration = Duration::from_secs(15);
/// Calls and predictions are counted this long after the predictor is activated again.
const SETTLE: Duration = Duration::from_secs(2);
/// The predictor's `/diagnostics` rate is over its last 100 ticks (node/health.rs), 10 s at
/// 10 Hz: for that long after it is activated it still spans the inactive time.
const RATE_WINDOW: Duration = Duration::from_secs(10);
/// RSS growth is measured from this point of the run on: the suite's RSS rises for the first
/// ~20–40 s of load (allocator arenas and DDS caches reaching their working size: measured
/// 24 → 37 MB in 42 s, then flat for the rest of a 60 s run) — a leak keeps growing after.
const RSS_FROM: Duration = Duration::from_secs(20);

/// What one client measured.
#[derive(Default)]
struct ClientStats {
    /// Answered calls after `WARM_UP`: (seconds into the run at the call, round trip [ms]).
    latencies_ms: Vec<(f64, f64)>,
    /// Calls without a reply within `LOST_AFTER`: (seconds into the run, service).
    lost: Vec<(f64, &'static str)>,
    /// Replies with success = false, or transport errors.
    errors: Vec<String>,
}

/// One client: its own participant, forces and projection alternately every `period` until
/// `stop` (no catch-up: a late call is followed by the next at once, then the schedule
/// resumes).
fn client(id: usize, period: Duration, stop: Arc<AtomicBool>, t0: Instant) -> ClientStats {
    let mut node = TestNode::new(&format!("cd_load_client_{id}"));
    let forces = node.client::<GetConstraintForces>("/cd_forces/get_constraint_forces");
    let project = node.client::<ProjectVelocity>("/cd_projection/project_velocity");
    let forces_req = GetConstraintForcesRequest {
        use_latest_state: true,
        ..Default::default()
    };
    let project_req = ProjectVelocityRequest {
        use_latest_state: true,
        use_twist: true,
        base_twist: twist(0.2, 0.1),
        ..Default::default()
    };
    let mut s = ClientStats::default();
    let mut next = Instant::now();
    let mut k = 0u64;
    while !stop.load(Ordering::Relaxed) {
        let now = Instant::now();
        if next > now {
            std::thread::sleep(next - now);
        }
        next = next.max(Instant::now() - period) + period;
        let started = Instant::now();
        let (service, reply) = if k.is_multiple_of(2) {
            let r = block_on_timeout(LOST_AFTER, forces.async_call_service(forces_req.clone()));
            ("forces", r.map(|r| r.map(|r| (r.success, r.message))))
        } else {
            let r = block_on_timeout(LOST_AFTER, project.async_call_service(project_req.clone()));
            ("projection", r.map(|r| r.map(|r| (r.success, r.message))))
        };
        k += 1;
        match reply {
            None => s.lost.push((t0.elapsed().as_secs_f64(), service)),
            Some(Err(e)) => s.errors.push(format!("{service}: {e:?}")),
            Some(Ok((false, m))) => s.errors.push(format!("{service}: {m}")),
            Some(Ok((true, _))) => {
                let at = started.duration_since(t0);
                if at > WARM_UP {
                    let ms = started.elapsed().as_secs_f64() * 1e3;
                    s.latencies_ms.push((at.as_secs_f64(), ms));
                }
            }
        }
    }
    s
}

/// The machine's scheduling noise while the load runs: a thread that sleeps 1 ms over and over
/// and records how late it wakes [ms]. On an idle machine its p99 is ~0.1 ms; with other
/// builds on the two cores it is milliseconds, and every thread hop of a service call (client,
/// DDS receive, executor, worker and back) can wait that long.
fn wake_up_lateness(stop: Arc<AtomicBool>) -> Vec<f64> {
    let mut late = Vec::new();
    while !stop.load(Ordering::Relaxed) {
        let t = Instant::now();
        std::thread::sleep(Duration::from_millis(1));
        late.push((t.elapsed().as_secs_f64() - 1e-3) * 1e3);
    }
    late
}

/// Messages per second on `sub` over `window`.
fn count(sub: &ros2_client::Subscription<Path>, window: Duration) -> f64 {
    let end = Instant::now() + window;
    let mut n = 0;
    while let Some(left) = end.checked_duration_since(Instant::now()) {
        if let Some(Ok(_)) = block_on_timeout(left, sub.async_take()) {
            n += 1;
        }
    }
    n as f64 / window.as_secs_f64()
}

/// One `/diagnostics` status of the predictor: seconds into the run, level, message, and its
/// last tick's duration [ms] ("last tick [ms] (covariance)").
type PredictorStatus = (f64, u8, String, Option<f64>);

/// The predictor's `/diagnostics` statuses while the load runs. Its own participant and
/// thread, so that the monitor's one-second counts of predictions are not disturbed.
fn predictor_statuses(stop: Arc<AtomicBool>, t0: Instant) -> Vec<PredictorStatus> {
    let mut t = TestNode::new("cd_load_diagnostics");
    let sub = t.subscribe::<DiagnosticArray>("/diagnostics");
    let mut seen = Vec::new();
    while !stop.load(Ordering::Relaxed) {
        if let Some(Ok((m, _))) = block_on_timeout(Duration::from_millis(200), sub.async_take()) {
            for s in m.status.iter().filter(|s| s.name == "/cd_predictor") {
                let tick_ms = (s.values.iter())
                    .find(|kv| kv.key.starts_with("last tick [ms]"))
                    .and_then(|kv| kv.value.split_whitespace().next()?.parse().ok());
                let at = t0.elapsed().as_secs_f64();
                seen.push((at, s.level, s.message.clone(), tick_ms));
            }
        }
    }
    seen
}

/// The p99 latency bar [ms] for the calls while the predictor predicts, given the p99 of the
/// same calls with the predictor inactive, measured in the same run (`idle99_ms`), and the
/// predictor's median tick (`tick_ms`). Predictions may slow a call by sharing the two cores,
/// but a call must not wait behind one: then the calls arriving during a tick (a tick's share
/// of the time, ~7 %) would wait up to its whole length, and the p99 would rise by most of a
/// tick. The bar — 3 ms, or half a tick beyond the inactive p99 — fails that on any machine.
/// Measured (p99 inactive → predicting, tick): 0.79 → 2.59 ms and 1.95 → 2.19 ms at 7.0 ms on
/// an idle 2-core VM. The machine's own tail moves both: a 10 s reference read 0.79 ms in one
/// run and 1.95 ms in the next, and calls with predictions read 0.87–1.06 ms on an idle VM on
/// one day and 2.3–3.2 ms on another, with the same code.
fn latency_bar_ms(idle99_ms: f64, tick_ms: f64) -> f64 {
    3.0f64.max(idle99_ms + 0.5 * tick_ms)
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

#[test]
#[ignore = "needs root (a loopback-only network namespace): run by tools/test.sh"]
fn two_clients_at_1khz_every_call_answered() {
    let _group = crate::common::exclusive_group(module_path!());
    if !in_namespace_or_reexec(TEST) {
        return;
    }
    let seconds: u64 = std::env::var("CD_LOAD_SECONDS")
        .map(|s| s.parse().expect("CD_LOAD_SECONDS: whole seconds"))
        .unwrap_or(60);
    let mut t = TestNode::new("cd_load_monitor");
    let paths = t.subscribe::<Path>("/cd_predictor/predicted_path");
    let mut suite = SuiteProcess::spawn(
        env!("CARGO_BIN_EXE_constraint_dynamics_suite"),
        &["--ros-args", "--params-file", "params/default.yaml"],
        "load",
    );
    take_until(&paths, WAIT, |_| Ok(())).expect("no predicted_path from the suite");
    // The prediction rate without the clients, on the machine as it is now.
    let reference = count(&paths, Duration::from_secs(10));
    // The first calls meet an inactive predictor (`PREDICTOR_FROM`).
    let lifecycle = t.client::<ChangeState>("/cd_predictor/change_state");
    let transition = |id: u8, label: &str| {
        let request = ChangeStateRequest {
            transition: Transition {
                id,
                label: label.into(),
            },
        };
        assert!(call(&lifecycle, request).success, "cd_predictor: {label}");
    };
    transition(4, "deactivate");
    let stop = Arc::new(AtomicBool::new(false));
    let probe = {
        let stop = stop.clone();
        std::thread::spawn(move || wake_up_lateness(stop))
    };
    let t0 = Instant::now();
    let diagnostics = {
        let stop = stop.clone();
        std::thread::spawn(move || predictor_statuses(stop, t0))
    };
    let clients: Vec<_> = (0..2)
        .map(|id| {
            let stop = stop.clone();
            std::thread::spawn(move || client(id, Duration::from_millis(1), stop, t0))
        })
        .collect();

    // Monitor: RSS and predictions per second.
    let pid = suite.child.id();
    let mut rss = Vec::new(); // (s, kB)
    let mut predictions = Vec::new(); // per second once the predictor has settled
    let end = t0 + Duration::from_secs(seconds);
    let mut inactive = true;
    while Instant::now() < end {
        if inactive && t0.elapsed() >= PREDICTOR_FROM {
            transition(3, "activate");
            inactive = false;
        }
        let second = Instant::now() + Duration::from_secs(1);
        let mut n = 0;
        while let Some(left) = second.checked_duration_since(Instant::now()) {
            if let Some(Ok(_)) = block_on_timeout(left, paths.async_take()) {
                n += 1;
            }
        }
        assert!(
            suite.alive(),
            "the suite exited under load:\n{}",
            suite.log()
        );
        rss.push((t0.elapsed().as_secs_f64(), rss_kb(pid)));
        if t0.elapsed() > PREDICTOR_FROM + SETTLE + Duration::from_secs(1) {
            predictions.push(n);
        }
    }
    stop.store(true, Ordering::Relaxed);
    let stats: Vec<ClientStats> = clients.into_iter().map(|c| c.join().unwrap()).collect();
    let mut noise = probe.join().unwrap();
    let statuses = diagnostics.join().unwrap();
    noise.sort_by(f64::total_cmp);
    let after = count(&paths, Duration::from_secs(10));
    let (stopped, clean) = suite.interrupt_timed(Duration::from_secs(10));

    // ---- figures ----------------------------------------------------------------------------
    let answered = stats.iter().flat_map(|s| s.latencies_ms.iter().copied());
    let sorted = |keep: &dyn Fn(f64) -> bool| {
        let mut ms: Vec<f64> = (answered.clone().filter(|&(at, _)| keep(at)))
            .map(|(_, ms)| ms)
            .collect();
        ms.sort_by(f64::total_cmp);
        ms
    };
    let paused = PREDICTOR_FROM.as_secs_f64();
    let predicting = (PREDICTOR_FROM + SETTLE).as_secs_f64();
    let idle = sorted(&|at| at < paused);
    let lat = sorted(&|at| at >= predicting);
    assert!(!lat.is_empty() && !idle.is_empty(), "no call answered");
    let (p50, p99, max) = (
        percentile(&lat, 0.5),
        percentile(&lat, 0.99),
        lat[lat.len() - 1],
    );
    let (idle50, idle99) = (percentile(&idle, 0.5), percentile(&idle, 0.99));
    let during = |t: f64| t > predicting && t <= seconds as f64;
    let mut ticks_ms: Vec<f64> = (statuses.iter())
        .filter(|s| during(s.0))
        .filter_map(|s| s.3)
        .collect();
    ticks_ms.sort_by(f64::total_cmp);
    assert!(!ticks_ms.is_empty(), "no tick duration on /diagnostics");
    let tick_ms = percentile(&ticks_ms, 0.5);
    let over_2ms = lat.iter().filter(|&&x| x > 2.0).count();
    let lost: Vec<_> = stats.iter().flat_map(|s| s.lost.clone()).collect();
    let errors: Vec<_> = stats.iter().flat_map(|s| s.errors.clone()).collect();
    let calls = answered.count() + lost.len() + errors.len();
    // The suite returns freed heap every `heap::PERIOD` (nodes/src/ros/heap.rs), so its RSS is
    // a sawtooth sampled once a second, and a leak raises its peaks: growth compares the first
    // half of the span from `RSS_FROM` with the second half (20 s, four trim periods each, in a
    // 60 s run; at least two), each by the upper median of its trim periods' peaks. A leak
    // raises every later peak; one tooth that reaches higher does not: with each half's single
    // highest sample, one tooth at 39.4 MB among peaks of 37.1–37.2 MB failed a run
    // (+6.16 %). With two trim periods per end a tooth sampled before its top decided the
    // figure: +5.27 % in a run whose peaks from 20 s on were 35.0–36.9 MB, flat.
    let from = RSS_FROM.as_secs_f64();
    let end = rss[rss.len() - 1].0;
    let window =
        ((end - from) / 2.0).max(2.0 * constraint_dynamics_nodes::ros::heap::PERIOD.as_secs_f64());
    let peak_in = |lo: f64, hi: f64| {
        rss.iter()
            .filter(|(s, _)| *s >= lo && *s <= hi)
            .map(|r| r.1)
            .max()
    };
    let period = constraint_dynamics_nodes::ros::heap::PERIOD.as_secs_f64();
    let median_peak = |lo: f64, hi: f64| {
        let mut peaks: Vec<_> = (0..)
            .map(|k| lo + k as f64 * period)
            .take_while(|&s| s < hi)
            .filter_map(|s| peak_in(s, (s + period).min(hi)))
            .collect();
        peaks.sort_unstable();
        peaks.get(peaks.len() / 2).copied()
    };
    let base = median_peak(from, from + window).unwrap_or(rss[0].1);
    let last = median_peak(end - window, end).unwrap_or(rss[rss.len() - 1].1);
    let peak = rss.iter().map(|r| r.1).max().unwrap_or(0);
    let growth = (last as f64 - base as f64) / base as f64;
    let rate = predictions.iter().sum::<usize>() as f64 / predictions.len() as f64;
    let worst5 = predictions
        .windows(5)
        .map(|w| w.iter().sum::<usize>() as f64 / 5.0)
        .fold(f64::INFINITY, f64::min);
    let measured_s = seconds as f64 - WARM_UP.as_secs_f64();
    let noise99 = percentile(&noise, 0.99);
    let predicting_s = seconds as f64 - predicting;
    println!(
        "{TEST}: 2 clients for {seconds} s; the predictor inactive from {WARM_UP:?} to \
         {PREDICTOR_FROM:?}: {} calls, latency p50 {idle50:.3} ms, p99 {idle99:.3} ms; \
         predicting, the last {predicting_s} s: {} calls ({:.0}/s), latency p50 {p50:.3} ms, \
         p99 {p99:.3} ms, max {max:.1} ms, {over_2ms} over 2 ms; lost {}, errors {}; a \
         prediction takes {tick_ms:.1} ms (median on /diagnostics)",
        idle.len(),
        lat.len(),
        lat.len() as f64 / predicting_s,
        lost.len(),
        errors.len()
    );
    println!(
        "{TEST}: machine: load average {}, a 1 ms sleep wakes late by p50 {:.3} ms, p99 {noise99:.3} \
         ms, max {:.1} ms",
        std::fs::read_to_string("/proc/loadavg")
            .unwrap_or_default()
            .trim(),
        percentile(&noise, 0.5),
        noise[noise.len() - 1]
    );
    println!(
        "{TEST}: suite RSS {base} kB at {RSS_FROM:?} → {last} kB at the end (peak {peak} kB; \
         halves' median trim-period peaks: growth {:+.2} %); predictions {reference:.2} Hz \
         before, {rate:.2} Hz under load (worst 5 s window {worst5:.1} Hz), {after:.2} Hz after; \
         SIGINT → exit in {:?}",
        100.0 * growth,
        stopped
    );
    println!("{TEST}: RSS over time [s, kB]: {rss:?}");
    println!("{TEST}: predictions per second: {predictions:?}");

    // ---- assertions ---------------------------------------------------------------------------
    assert!(
        lost.is_empty(),
        "{} of {calls} calls never answered: {lost:?}",
        lost.len()
    );
    assert!(
        errors.is_empty(),
        "errors: {:?}",
        &errors[..errors.len().min(10)]
    );
    // The clients wait for each reply (as a controller or planner plugin calling a service
    // does), so their rate is bounded by the round trip: 1 962/s on an idle VM, 1 492/s in a
    // CI run whose 1 ms sleep woke late by p99 5.6 ms. 1.2 kHz in all shows the load was
    // applied; the latency bar below is what judges the suite.
    assert!(
        calls as f64 >= 0.6 * 2000.0 * measured_s,
        "only {calls} calls in {measured_s} s"
    );
    // Against the same calls without predictions (`latency_bar_ms`): the predictor's worker
    // runs at a lower priority with a short slice (`node::timer::PERIODIC_NICE`), so a call
    // shares the cores with a prediction but does not queue behind it. The figures are
    // printed and reported (docs/nodes.md).
    let bar = latency_bar_ms(idle99, tick_ms);
    assert!(
        p99 < bar,
        "p99 {p99:.3} ms ≥ {bar:.2} ms while predicting (the same calls with the predictor \
         inactive: p99 {idle99:.3} ms; machine: a 1 ms sleep wakes late by p99 {noise99:.3} ms)"
    );
    assert!(
        growth < 0.05,
        "RSS grew {:.2} % (limit 5 %)",
        100.0 * growth
    );
    // Held, or said: under the clients the predictor keeps at least 0.65 of the lower of its
    // rates in the 10 s before and after them (10 Hz is not assumed: other builds on the
    // machine move its rate between 3 and 7 Hz from one minute to the next), or its
    // `/diagnostics` status says the rate is below the one asked (the requirement: the
    // prediction rate held, or a diagnostic says why not). Its worker yields the CPU to the service threads by
    // design (`node::timer::PERIODIC_NICE`), and 2 000 calls/s take a share of the two cores:
    // the ratio was 0.79–0.86 on idle machines, 0.61 in a CI run with the scheduling tail
    // above. Never starved (it must not stop publishing): every 5 s window keeps a
    // quarter of that rate.
    let without = reference.min(after);
    let rate_warnings = statuses
        .iter()
        .filter(|(t, level, m, _)| {
            *t > (PREDICTOR_FROM + RATE_WINDOW).as_secs_f64()
                && during(*t)
                && *level == DiagnosticStatus::WARN
                && m.contains("< requested")
        })
        .count();
    println!(
        "{TEST}: /diagnostics: {} predictor statuses during the load, {rate_warnings} of them \
         WARN on its rate; the last: {:?}",
        statuses.iter().filter(|s| during(s.0)).count(),
        statuses.last()
    );
    assert!(
        rate >= 0.65 * without || rate_warnings > 0,
        "prediction rate {rate:.2} Hz under load, {reference:.2} Hz before and {after:.2} Hz \
         after the clients, and no WARN on /diagnostics said so"
    );
    assert!(
        worst5 >= 0.25 * without,
        "predictions starved: {worst5:.2} Hz in the worst 5 s window, {without:.2} Hz without \
         the clients"
    );
    let stopped = stopped.unwrap_or_else(|| panic!("SIGINT: still running after 10 s"));
    assert!(
        clean && stopped < Duration::from_secs(1),
        "SIGINT took {stopped:?}"
    );
}
