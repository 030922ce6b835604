//! The covariance on a second thread, one flush behind the prediction.
//!
//! Why: where a stiff mode keeps the covariance's chunks to one step, its linearized steps cost
//! more than the prediction's own (the suite's mobile manipulator over a 1 s tick: 0.65 G of
//! its 1.13 G instructions). P depends on the nominal trajectory, never the reverse, so a worker
//! can linearize the steps up to one sample while the prediction integrates the next.
//!
//! How: two step records circulate. The prediction fills one; at a sample, or when the record
//! is full, it sends it to the worker with the time and the sample's index, and takes the other
//! back, waiting only while the worker still flushes it (at most one flush in flight). The
//! worker owns the propagator and a clone of the predictor's `System` (its own kinematics and
//! factorization buffers); a flush computes there exactly what it computes inline, so every P
//! is the same to the bit (tests/it/covariance_worker.rs). The samples' covariances are attached
//! when the run ends; a worker's error is the run's error (it concerns an earlier time than
//! anything the prediction met after it).

use super::CovariancePropagator;
use crate::actuators::Feedback;
use crate::error::{Error, Result};
use crate::predict::covariance::chunks::StepRecord;
use crate::predict::integrators::Method;
use crate::system::System;
use nalgebra::DMatrix;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};

/// A full record for the worker: P is brought up to its end, at time `t` [s], and read there
/// for sample `sample` (None: the record was full between samples).
#[derive(Debug)]
struct Job {
    record: StepRecord,
    t: f64,
    sample: Option<usize>,
}

/// What the worker hands back when the prediction is done with it.
pub(in crate::predict) struct Finished {
    pub propagator: CovariancePropagator,
    /// (sample index, P row-major) per sample.
    pub snapshots: Vec<(usize, Vec<Vec<f64>>)>,
    pub error: Option<Error>,
}

/// The two records' meeting point: the job for the worker (at most one: the prediction hands
/// a record over only after the worker returned the other), the record coming back, and who
/// has left. A mutex and a condition variable (futexes) rather than channels: blocking on
/// them allocates nothing, and the stepping loop stays allocation-free
/// (tests/it/no_alloc/propagation.rs).
#[derive(Debug, Default)]
struct Exchange {
    state: Mutex<Slots>,
    changed: Condvar,
}

#[derive(Debug, Default)]
struct Slots {
    job: Option<Job>,
    /// An emptied record, with whether every flush so far succeeded.
    back: Option<(StepRecord, bool)>,
    /// The prediction is done (no more jobs); the worker is gone (it returns nothing more).
    closed: bool,
    worker_gone: bool,
}

impl Exchange {
    fn slots(&self) -> MutexGuard<'_, Slots> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }
    fn wait<'a>(&self, g: MutexGuard<'a, Slots>) -> MutexGuard<'a, Slots> {
        self.changed.wait(g).unwrap_or_else(|e| e.into_inner())
    }
}

/// The prediction's end of the pipe.
#[derive(Debug)]
pub(in crate::predict) struct CovariancePipe {
    exchange: Arc<Exchange>,
    current: StepRecord,
}

/// Closes the exchange however the prediction's side leaves it.
struct Closing<'a>(&'a Exchange);

impl Drop for Closing<'_> {
    fn drop(&mut self) {
        self.0.slots().closed = true;
        self.0.changed.notify_all();
    }
}

/// Marks the worker gone however it leaves (a panic included), so the prediction never waits
/// for it in vain.
struct Leaving<'a>(&'a Exchange);

impl Drop for Leaving<'_> {
    fn drop(&mut self) {
        self.0.slots().worker_gone = true;
        self.0.changed.notify_all();
    }
}

/// The pipe's slot in a predictor: empty outside a run, and in a clone. (A `Mutex` only to
/// keep the predictor `Sync` for the rollouts' workers; it is reached through `&mut`, never
/// locked.)
#[derive(Debug, Default)]
pub(in crate::predict) struct PipeSlot(Mutex<Option<CovariancePipe>>);

impl Clone for PipeSlot {
    fn clone(&self) -> Self {
        Self::default()
    }
}

impl PipeSlot {
    pub(in crate::predict) fn get_mut(&mut self) -> Option<&mut CovariancePipe> {
        self.slot().as_mut()
    }
    pub(in crate::predict) fn set(&mut self, pipe: Option<CovariancePipe>) {
        *self.slot() = pipe;
    }
    fn slot(&mut self) -> &mut Option<CovariancePipe> {
        self.0.get_mut().unwrap_or_else(|e| e.into_inner())
    }
}

/// Where the answer's steps go: the propagator itself, or the worker's pipe.
pub(in crate::predict) enum CovarianceFeed<'a> {
    Inline(&'a mut CovariancePropagator),
    Worker(&'a mut CovariancePipe),
}

impl CovarianceFeed<'_> {
    /// Record one step of the prediction (`StepRecord::push`: from `start` under the held
    /// generalized force τ and the controllers' `feedback` for h [s] to `end`, at time `t`
    /// [s], after drift control); when the record is full P catches up, inline or on the
    /// worker. An error when the worker has failed: a placeholder, the run returns the
    /// worker's own.
    #[allow(clippy::too_many_arguments)]
    pub(in crate::predict) fn record_step(
        &mut self,
        sys: &mut System,
        method: Method,
        start: (&[f64], &[f64]),
        tau: &[f64],
        feedback: impl Iterator<Item = Feedback>,
        step: Option<(&DMatrix<f64>, &[f64])>,
        h: f64,
        (t, end): (f64, (&[f64], &[f64])),
    ) -> Result<()> {
        let record = match self {
            Self::Inline(c) => &mut c.record,
            Self::Worker(p) => &mut p.current,
        };
        if !record.push(start, tau, feedback, step, h, (t, end.0, end.1)) {
            return Ok(());
        }
        match self {
            Self::Inline(c) => c.flush(sys, method, false),
            Self::Worker(p) => p.handoff(t, None),
        }
    }
}

/// Stands for the worker's error until the worker is joined.
fn worker_failed() -> Error {
    Error::Invalid("the covariance worker failed".into())
}

impl CovariancePipe {
    /// Send the current record (P up to time `t`, read for `sample`) and continue in the
    /// other one.
    pub(in crate::predict) fn handoff(&mut self, t: f64, sample: Option<usize>) -> Result<()> {
        let ex = &*self.exchange;
        let mut g = ex.slots();
        let (next, ok) = loop {
            if let Some(b) = g.back.take() {
                break b;
            }
            if g.worker_gone {
                return Err(worker_failed());
            }
            g = ex.wait(g);
        };
        let record = std::mem::replace(&mut self.current, next);
        g.job = Some(Job { record, t, sample });
        drop(g);
        ex.changed.notify_all();
        if ok { Ok(()) } else { Err(worker_failed()) }
    }
}

/// P's rows for a sample at time t [s], refused if it overflowed.
pub(in crate::predict) fn covariance_rows(p: &DMatrix<f64>, t: f64) -> Result<Vec<Vec<f64>>> {
    crate::error::check_output(
        &format!("sample at t = {t} s: covariance"),
        p.as_slice(),
        "the propagated covariance overflowed; reduce the start covariance or the horizon",
    )?;
    Ok((0..p.nrows())
        .map(|i| p.row(i).iter().copied().collect())
        .collect())
}

/// Run `body` with the propagator on a worker thread fed through the pipe it is given; returns
/// body's result and what the worker finished with.
pub(in crate::predict) fn with_worker<R>(
    propagator: CovariancePropagator,
    mut worker_sys: System,
    method: Method,
    body: impl FnOnce(CovariancePipe) -> R,
) -> (R, Finished) {
    let exchange = Arc::new(Exchange::default());
    exchange.slots().back = Some((propagator.record.like(&worker_sys), true));
    let pipe = CovariancePipe {
        exchange: Arc::clone(&exchange),
        current: propagator.record.like(&worker_sys),
    };
    std::thread::scope(|scope| {
        let ex = &*exchange;
        let worker = scope.spawn(move || {
            let _leaving = Leaving(ex);
            let mut done = Finished {
                propagator,
                snapshots: vec![],
                error: None,
            };
            loop {
                let mut g = ex.slots();
                let Job {
                    mut record,
                    t,
                    sample,
                } = loop {
                    if let Some(job) = g.job.take() {
                        break job;
                    }
                    if g.closed {
                        return done;
                    }
                    g = ex.wait(g);
                };
                drop(g);
                if done.error.is_none() {
                    let c = &mut done.propagator;
                    let flushed = c
                        .flush_record(&mut worker_sys, method, &mut record, sample.is_some())
                        .and_then(|()| {
                            if let Some(k) = sample {
                                done.snapshots.push((k, covariance_rows(&c.reading.p, t)?));
                            }
                            Ok(())
                        });
                    done.error = flushed.err();
                } else {
                    // After a failure the records only circulate until the prediction stops.
                    record.clear();
                }
                ex.slots().back = Some((record, done.error.is_none()));
                ex.changed.notify_all();
            }
        });
        // The worker's loop ends when the body is done, even if it panics with the pipe still
        // stored somewhere (the scope would otherwise wait for the worker forever).
        let closing = Closing(ex);
        let result = body(pipe);
        drop(closing);
        let done = worker
            .join()
            .unwrap_or_else(|e| std::panic::resume_unwind(e));
        (result, done)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Scene;
    use crate::forces::ForceElements;

    /// A prediction side that panics with the pipe still stored elsewhere does not leave the
    /// worker, and with it the scope, waiting forever: the panic comes through.
    #[test]
    fn a_panicking_prediction_does_not_hang_the_worker() {
        let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"));
        let scene = Scene::load(root.join("params/diff_drive.yaml")).unwrap();
        let mut sys = System::from_scene(&scene).unwrap();
        let forces = ForceElements::new(sys.model(), &scene.file.forces).unwrap();
        let n = 2 * sys.model().nv;
        let p0 = DMatrix::identity(n, n) * 1e-6;
        let (q, v) = (&scene.q0, &scene.v0);
        let spec = Default::default();
        let gains = sys.baumgarte();
        let prop =
            CovariancePropagator::start(&mut sys, gains, &forces, &[], &spec, &p0, (0.0, q, v))
                .unwrap();
        let kept = Mutex::new(None);
        let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            with_worker(prop, sys.clone(), Method::Rk4, |pipe| {
                *kept.lock().unwrap() = Some(pipe);
                panic!("the prediction failed");
            })
        }));
        assert!(outcome.is_err());
        assert!(kept.lock().unwrap_or_else(|e| e.into_inner()).is_some());
    }
}
