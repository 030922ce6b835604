//! One run of the project's integrators: the prediction with its CPU time, its error against
//! the scene's reference (closed form, reference trajectories or final state) and its drift.

use super::Row;
use super::scenes::{Bench, Line, Reference, name};
use constraint_dynamics::predict::{
    DriftControl, Method, PredictionRequest, Predictor, Trajectory,
};
use constraint_dynamics::{Result, Scene};

/// The CPU time of this process [s] (CLOCK_PROCESS_CPUTIME_ID: all its threads, ns resolution):
/// unlike wall-clock time, it does not count the time other processes hold the core, and it is
/// what the peers measure (Python's `time.process_time`).
pub(super) fn process_cpu_s() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes one timespec through a valid pointer to a local.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
    if rc != 0 {
        return f64::NAN;
    }
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

/// A run shorter than this was a warm-up: it is repeated `REPEATS` times and the least time of
/// the repeats kept (the peers' rule: one warm-up call, then the least of 5).
const REPEAT_BELOW_S: f64 = 0.25;
/// Timed repeats after the warm-up of a run shorter than `REPEAT_BELOW_S`.
const REPEATS: usize = 5;

/// Predict with the given method, drift control and step/tolerance. The CPU time is that of the
/// one run when it takes `REPEAT_BELOW_S` or more; otherwise that run was a warm-up (caches,
/// allocator, branch predictors) and the time is the least of `REPEATS` further runs, as the
/// peers time their calls.
pub(super) fn predict(
    scene: &Scene,
    method: Method,
    drift: DriftControl,
    tolerance: bool,
    x: f64,
    horizon: f64,
) -> Result<(Trajectory, f64)> {
    // The sweeps reach coarse steps on purpose and measure the true error themselves; the time
    // is the integrator's alone, without the error estimate's companion run.
    let mut p = Predictor::from_scene(scene)?.with_settings(|s| {
        s.method = method;
        s.drift = drift;
        s.sample_period = horizon / 100.0;
        s.max_error = f64::INFINITY;
        s.error_estimate = false;
        s.adapt = false;
        if tolerance {
            (s.rtol, s.atol, s.dt) = (x, x, horizon / 1e4);
        } else {
            s.dt = x;
        }
    })?;
    let request = PredictionRequest::new(&scene.q0, &scene.v0).horizon(horizon);
    let c0 = process_cpu_s();
    let mut last = p.predict(&request)?;
    let first = process_cpu_s() - c0;
    if first >= REPEAT_BELOW_S {
        return Ok((last, first));
    }
    let mut best = f64::INFINITY;
    for _ in 0..REPEATS {
        let c0 = process_cpu_s();
        last = p.predict(&request)?;
        best = best.min(process_cpu_s() - c0);
    }
    Ok((last, best))
}

/// Max over the samples of |q ⊖ q_ref|∞.
pub(super) fn distance(scene: &Scene, t: &Trajectory, r: &Trajectory) -> f64 {
    let mut d = vec![0.0; scene.model.nv];
    let mut worst: f64 = 0.0;
    for (a, b) in t.samples.iter().zip(&r.samples) {
        scene.model.difference(&b.q, &a.q, &mut d);
        worst = d.iter().fold(worst, |m, x| m.max(x.abs()));
    }
    if t.samples.len() != r.samples.len() {
        return f64::NAN;
    }
    worst
}

/// |q ⊖ q_ref|∞ of two configurations.
pub(super) fn final_distance(scene: &Scene, q: &[f64], q_ref: &[f64]) -> f64 {
    let mut d = vec![0.0; scene.model.nv];
    scene.model.difference(q_ref, q, &mut d);
    d.iter().fold(0.0, |m: f64, x| m.max(x.abs()))
}

/// The references of a scene, computed once.
pub(super) enum Refs {
    None,
    /// Numerical: dopri5 (fixed-step rows) and RK4 (tolerance-driven rows) trajectories.
    Trajectories(Box<(Trajectory, Trajectory)>),
    /// Final: q at the end of the horizon, dopri5's and RK4's.
    Final {
        dopri: Vec<f64>,
        rk4: Vec<f64>,
    },
}

pub(super) fn measure(scene: &Scene, b: &Bench, line: &Line, x: f64, refs: &Refs) -> Row {
    let mut row = Row {
        line: line.label(),
        method: name(line.method),
        drift: name(line.drift),
        x,
        tolerance: line.tolerances,
        peer: false,
        steps: 0,
        evaluations: 0,
        jacobian_evaluations: None,
        cpu: f64::NAN,
        error: f64::NAN,
        phi: f64::NAN,
        jv: f64::NAN,
        energy: f64::NAN,
        least_squares: 0,
        status: "ok".into(),
    };
    let (t, cpu) = match predict(
        scene,
        line.method,
        line.drift,
        line.tolerances,
        x,
        b.horizon,
    ) {
        Ok(r) => r,
        Err(e) => {
            row.status = e.to_string();
            return row;
        }
    };
    row.error = match (&b.reference, refs) {
        (Reference::ClosedForm(f), _) => t.samples.iter().map(f).fold(0.0, f64::max),
        (_, Refs::Trajectories(pair)) => {
            let (dopri, rk4) = &**pair;
            distance(scene, &t, if line.tolerances { rk4 } else { dopri })
        }
        (_, Refs::Final { dopri, rk4 }) => t.samples.last().map_or(f64::NAN, |s| {
            final_distance(scene, &s.q, if line.tolerances { rk4 } else { dopri })
        }),
        _ => f64::NAN,
    };
    let e0 = t.samples[0].kinetic_energy + t.samples[0].potential_energy;
    row.energy = 0.0;
    row.phi = 0.0;
    row.jv = 0.0;
    for s in &t.samples {
        row.energy = row
            .energy
            .max((s.kinetic_energy + s.potential_energy - e0).abs());
        row.phi = row.phi.max(s.position_residual);
        row.jv = row.jv.max(s.velocity_residual);
    }
    (row.steps, row.evaluations, row.cpu) = (t.steps, t.evaluations, cpu);
    row.least_squares = t.least_squares_evaluations;
    // radau5's Newton Jacobians (the other methods count none), like the peers'.
    row.jacobian_evaluations = (t.jacobians > 0).then_some(t.jacobians);
    row
}
