//! Rollouts for sampling planners (MPPI-style): one start state, N command sequences, N
//! trajectories, spread over the cores with rayon.
//!
//! Each worker thread owns one clone of the predictor (model, `Data` and every workspace), made
//! at its first rollout and reused for the next ones, so the stepping loop stays allocation-free
//! and nothing is shared between threads but the read-only request. A rollout is exactly one
//! [`Predictor::predict`] call (commands started at 0, step, 2·step, …, horizon
//! len · step, a sample after every step): its result equals that single prediction bit for bit.

use super::predictor::Predictor;
use super::request::{PredictionBudget, PredictionRequest};
use super::trajectory::Trajectory;
use crate::actuators::Command;
use crate::error::{Error, Result};
use rayon::prelude::*;
use std::sync::Mutex;

/// How a batch of rollouts is cut and spread.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RolloutOptions {
    /// Each command of a sequence is held for this long, and a sample is taken after each [s]
    /// (Nav2 MPPI's `model_dt`: 0.05).
    pub step: f64,
    /// Worker threads; 0: one per core.
    pub threads: usize,
}

impl Default for RolloutOptions {
    fn default() -> Self {
        Self {
            step: 0.05,
            threads: 0,
        }
    }
}

impl Predictor {
    /// One trajectory per command sequence, all from the request's start state and under its
    /// integration overrides, forces and covariance, in the order of `sequences`: sequence k
    /// holds `sequences[k][i]` over [i·step, (i+1)·step), a sample after each step (the sample
    /// period is `step`). The request's own commands and horizon must be unset: each sequence
    /// gives its own. Planners turn the error estimate off (`error_estimate: Some(false)`): its
    /// companion run doubles each rollout's work. Fails with the first failing rollout's error.
    /// The whole batch's work is bounded by the scene's `max_work`, checked before running for
    /// the fixed-step methods.
    pub fn rollouts(
        &self,
        req: &PredictionRequest,
        sequences: &[Vec<Command>],
        opts: RolloutOptions,
    ) -> Result<Vec<Trajectory>> {
        if !req.commands.is_empty() || req.horizon.is_some() {
            return Err(Error::Invalid(
                "rollouts: each command sequence sets its own commands and horizon; leave the \
                 request's unset"
                    .into(),
            ));
        }
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
        let mut overrides = req.integration;
        overrides.sample_period = Some(opts.step);
        let single = self.budget(&overrides)?;
        let mut batch = single.settings().clone();
        batch.max_steps *= n;
        batch.max_samples *= n;
        PredictionBudget::new(batch, single.control_period())
            .with_system(&self.sys)
            .check(longest * n)?;
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(opts.threads)
            .build()
            .map_err(|e| Error::Invalid(format!("rollout worker threads: {e}")))?;
        // One predictor per worker, indexed by the worker's index in the pool: a worker only
        // ever locks its own slot, so the locks are never contended.
        let workers: Vec<Mutex<Option<Predictor>>> = (0..pool.current_num_threads())
            .map(|_| Mutex::new(None))
            .collect();
        pool.install(|| {
            sequences
                .par_iter()
                .map(|seq| {
                    let i = rayon::current_thread_index().unwrap_or(0);
                    let mut slot = workers[i].lock().unwrap_or_else(|e| e.into_inner());
                    // The pool already fills the cores: a covariance stays on its rollout's
                    // thread (the same P either way, covariance/worker.rs).
                    let p = slot.get_or_insert_with(|| {
                        let mut p = self.clone().with_parallel_covariance(false);
                        p.config.settings.max_work /= n;
                        p
                    });
                    let timed: Vec<(f64, Command)> = seq
                        .iter()
                        .enumerate()
                        .map(|(k, c)| (k as f64 * opts.step, c.clone()))
                        .collect();
                    let horizon = seq.len() as f64 * opts.step;
                    let one = PredictionRequest {
                        commands: &timed,
                        horizon: Some(horizon),
                        integration: overrides,
                        ..*req
                    };
                    p.predict(&one)
                })
                .collect()
        })
    }
}
