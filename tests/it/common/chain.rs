//! An unconstrained chain of n revolute links, generated (a rope, a cable, a tether): what the
//! linear-time dynamics are measured on (`benches/chain.rs`, `tools/chain_cost.py`) and tested
//! against the dense path (`tests/it/linear_dynamics.rs`).
//!
//! Link k (1-based) is a 0.1 m rod of 0.1 kg hanging along its −z, centre of mass at its middle,
//! on a joint about y at the end of link k − 1 — every other joint about x, so that the chain is
//! spatial. The scene starts it coiled: q_k = 0.3 + 0.1 sin k rad. Straight, the chain has the
//! inertia of its whole length about its top joints against the pivots of its free links
//! (ratio ≈ 3/n³), which falls below `MIN_PIVOT_RATIO` near n = 1 500: M is refused as
//! singular to working precision there.

use std::fmt::Write;

/// The URDF text of the n-link chain.
pub fn chain_urdf(n: usize) -> String {
    let mut s = String::with_capacity(420 * n + 100);
    s.push_str("<?xml version=\"1.0\"?>\n<robot name=\"chain\">\n  <link name=\"link0\"/>\n");
    for k in 1..=n {
        let axis = if k % 2 == 0 { "1 0 0" } else { "0 1 0" };
        let drop = if k == 1 { 0.0 } else { -0.1 };
        let _ = writeln!(
            s,
            "  <link name=\"link{k}\"><inertial><origin xyz=\"0 0 -0.05\"/><mass value=\"0.1\"/>\
             <inertia ixx=\"8.4e-5\" ixy=\"0\" ixz=\"0\" iyy=\"8.4e-5\" iyz=\"0\" izz=\"1e-6\"/>\
             </inertial></link>\n  <joint name=\"joint{k}\" type=\"revolute\"><parent \
             link=\"link{}\"/><child link=\"link{k}\"/><origin xyz=\"0 0 {drop}\"/><axis \
             xyz=\"{axis}\"/><limit lower=\"-3.14\" upper=\"3.14\" effort=\"10\" \
             velocity=\"10\"/></joint>",
            k - 1
        );
    }
    s.push_str("</robot>\n");
    s
}

/// The coiled start q_k = 0.3 + 0.1 sin k [rad] (k = 1..n).
pub fn chain_q0(n: usize) -> Vec<f64> {
    (1..=n).map(|k| 0.3 + 0.1 * (k as f64).sin()).collect()
}

/// The scene file of the chain whose URDF is at `urdf` (fixed base, gravity −z, starting
/// coiled at rest).
pub fn chain_scene_yaml(n: usize, urdf: &str) -> String {
    let mut s = format!(
        "# An unconstrained chain of {n} revolute links (generated).\nurdf: {urdf}\nbase: \
         fixed\ngravity: [0.0, 0.0, -9.81]\ninitial_state:\n  q:\n"
    );
    for (k, q) in chain_q0(n).iter().enumerate() {
        let _ = writeln!(s, "    joint{}: {q:.17e}", k + 1);
    }
    s.push_str("  v: {}\n");
    s
}
