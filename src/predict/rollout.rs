//! Rollouts for sampling planners (MPPI-style): one start state, N command sequences, N
//! trajectories, spread over the cores with rayon.
//!
//! Each worker thread owns one clone of the predictor (model, `Data` and every workspace), made
//! at its first rollout and reused for the next ones, so the stepping loop stays allocation-free
//! and nothing is shared between threads but the read-only request. A rollout is exactly one
//! [`Predictor::predict_with`] call (commands started at 0, step, 2·step, …, horizon
//! len · step, a sample after every step): its result equals that single prediction bit for bit.

use super::guard::check_work;
use super::run::Predictor;
use super::trajectory::{PredictOptions, Trajectory};
use crate::actuators::Command;
use crate::error::{Error, Result};
use rayon::prelude::*;
use std::sync::Mutex;

/// How a batch of rollouts runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RolloutOptions {
    /// Each command of a sequence is held for this long, and a sample is taken after each [s]
    /// (Nav2 MPPI's `model_dt`: 0.05).
    pub step: f64,
    /// λ and the constraint forces in every sample.
    pub forces: bool,
    /// Worker threads; 0: one per core.
    pub threads: usize,
}

impl Default for RolloutOptions {
    fn default() -> Self {
        Self {
            step: 0.05,
            forces: false,
            threads: 0,
        }
    }
}

impl Predictor {
    /// One trajectory per command sequence, all from (q0, v0), in the order of `sequences`:
    /// sequence k holds `sequences[k][i]` over [i·step, (i+1)·step). The scene's integration
    /// settings apply except the sample period, which is `step` — set `error_estimate: false`
    /// for planners: the estimate's companion run doubles each rollout's work. Fails with the
    /// first failing rollout's error. The whole batch's work is bounded by the scene's
    /// `max_work`, checked before running for the fixed-step methods.
    pub fn rollouts(
        &self,
        q0: &[f64],
        v0: &[f64],
        sequences: &[Vec<Command>],
        opts: RolloutOptions,
    ) -> Result<Vec<Trajectory>> {
        if !(opts.step.is_finite() && opts.step > 0.0) {
            return Err(Error::Invalid(format!(
                "rollout step = {} s must be positive and finite",
                opts.step
            )));
        }
        // The batch is bounded as a whole: its work (fixed-step methods: counted before running)
        // must fit `max_work` as one prediction over n × the longest horizon would, and each
        // rollout gets max_work / n of it (adaptive methods count while running).
        let n = sequences.len().max(1) as f64;
        let longest = sequences.iter().map(Vec::len).max().unwrap_or(0) as f64 * opts.step;
        let mut batch = self.settings.clone();
        batch.sample_period = opts.step;
        batch.max_steps *= n;
        batch.max_samples *= n;
        let control = (!self.actuators.is_empty()).then_some(self.actuators.control_period);
        check_work(&batch, &self.model, control, longest * n)?;
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(opts.threads)
            .build()
            .map_err(|e| Error::Invalid(format!("rollout worker threads: {e}")))?;
        // One predictor per worker, indexed by the worker's index in the pool: a worker only
        // ever locks its own slot, so the locks are never contended.
        let workers: Vec<Mutex<Option<Predictor>>> = (0..pool.current_num_threads())
            .map(|_| Mutex::new(None))
            .collect();
        let predict = PredictOptions {
            forces: opts.forces,
        };
        pool.install(|| {
            sequences
                .par_iter()
                .map(|seq| {
                    let i = rayon::current_thread_index().unwrap_or(0);
                    let mut slot = workers[i].lock().unwrap_or_else(|e| e.into_inner());
                    let p = slot.get_or_insert_with(|| {
                        let mut p = self.clone();
                        p.settings.sample_period = opts.step;
                        p.settings.max_work /= n;
                        // The pool already fills the cores: a covariance stays on its rollout's
                        // thread (the same P either way, covariance_worker.rs).
                        p.parallel_covariance = false;
                        p
                    });
                    let timed: Vec<(f64, Command)> = seq
                        .iter()
                        .enumerate()
                        .map(|(k, c)| (k as f64 * opts.step, c.clone()))
                        .collect();
                    let horizon = seq.len() as f64 * opts.step;
                    p.predict_with(q0, v0, &timed, horizon, predict)
                })
                .collect()
        })
    }
}
