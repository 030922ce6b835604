//! Deterministic command sequences for the rollout test and bench (one copy for both).

use constraint_dynamics::actuators::Command;

/// Deterministic command sequences: (v, ω) in [−0.5, 0.5] m/s × [−1, 1] rad/s, as a planner's
/// noisy candidates around a nominal command.
pub fn sequences(n: usize, steps: usize) -> Vec<Vec<Command>> {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut uniform = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    (0..n)
        .map(|_| {
            (0..steps)
                .map(|_| Command {
                    base_twist: Some([0.5 * uniform(), uniform()]),
                    ..Default::default()
                })
                .collect()
        })
        .collect()
}
