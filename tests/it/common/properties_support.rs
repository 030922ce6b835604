//! Shared by the property tests (`properties.rs`, `properties_scenes.rs`): proptest's settings and
//! configurations drawn from uniform numbers.
#![allow(dead_code)]

use constraint_dynamics::Model;
use constraint_dynamics::model::JointKind;
use proptest::test_runner::{Config, RngSeed};

/// 64 cases and a fixed seed unless the environment says otherwise.
pub fn config() -> Config {
    let mut c = Config::default();
    if std::env::var_os("PROPTEST_CASES").is_none() {
        c.cases = 64;
    }
    if std::env::var_os("PROPTEST_RNG_SEED").is_none() {
        c.rng_seed = RngSeed::Fixed(0x00c0_ffee);
    }
    c.failure_persistence = None;
    c
}

/// A configuration from uniform numbers in [−1, 1): revolute angles in [−π, π), prismatic
/// positions in [−0.5, 0.5) m, free-flyer positions in [−1, 1) m with a unit quaternion, planar
/// (x, y) in [−1, 1) m and yaw in [−π, π).
pub fn config_from(model: &Model, u: &[f64]) -> Vec<f64> {
    let pi = std::f64::consts::PI;
    let mut q = vec![0.0; model.nq];
    let mut k = 0;
    let mut next = || {
        let x = u[k % u.len()];
        k += 1;
        x
    };
    for b in model.bodies.iter().skip(1) {
        let j = &b.joint;
        let q = &mut q[j.idx_q..j.idx_q + j.kind.nq()];
        match j.kind {
            JointKind::Revolute { .. } => q[0] = pi * next(),
            JointKind::Prismatic { .. } => q[0] = 0.5 * next(),
            JointKind::FreeFlyer => {
                for x in q.iter_mut().take(3) {
                    *x = next();
                }
                // Four numbers kept away from the zero quaternion, then normalised.
                let raw = [next(), next(), next(), 1.5 + next()];
                let n = raw.iter().map(|x| x * x).sum::<f64>().sqrt();
                for i in 0..4 {
                    q[3 + i] = raw[i] / n;
                }
            }
            JointKind::Planar => {
                q[0] = next();
                q[1] = next();
                q[2] = pi * next();
            }
        }
    }
    q
}

/// n numbers: `u` repeated, times `scale`.
pub fn scaled(u: &[f64], n: usize, scale: f64) -> Vec<f64> {
    (0..n).map(|i| scale * u[i % u.len()]).collect()
}
