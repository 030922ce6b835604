//! No allocation on the hot paths: every test that runs a computation under the counting
//! allocator and asserts it allocates nothing (or, for a prediction, nothing per step) — one
//! target, one file per subject.
//!
//! - `hot_paths`: RNEA, CRBA, ABA, the constrained dynamics, the derivatives, `linearize_step`;
//! - `scenes`: the constrained dynamics of every bundled scene, in both formulations;
//! - `monitor`: recording, scoring and assessing past predictions (`monitor/`);
//! - `propagation`: the stepping loop (a prediction of 4× the steps makes as many allocations).

mod dynamic_projection;
mod envelope;
mod hot_paths;
mod monitor;
mod propagation;
mod scenes;
