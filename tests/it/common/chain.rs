//! A chain of n revolute links, generated (a rope, a cable, a tether), free or held at both
//! ends: what the linear-time dynamics are measured on (`benches/chain.rs`,
//! `tools/chain_cost.py`) and tested against the dense path (`tests/it/linear_dynamics.rs`,
//! `tests/it/linear_constrained_dynamics.rs`).
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

/// Where the end of link n (0.1 m below its joint) is [m, world] at q: the chain's own
/// geometry composed here (each joint 0.1 m below the last along its parent's −z, about y for
/// odd k and x for even k), not read from the model.
pub fn chain_tip(q: &[f64]) -> [f64; 3] {
    let mut r = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let mut p = [0.0; 3];
    let below = |r: &[[f64; 3]; 3], p: &mut [f64; 3]| {
        for (i, x) in p.iter_mut().enumerate() {
            *x -= 0.1 * r[i][2];
        }
    };
    for (k, &qk) in q.iter().enumerate() {
        if k > 0 {
            below(&r, &mut p);
        }
        let (s, c) = qk.sin_cos();
        // R ← R · Rot(axis, q): about y for joint 1, 3, …; about x for joint 2, 4, ….
        let rot = if k % 2 == 0 {
            [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]
        } else {
            [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]
        };
        let mut out = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                out[i][j] = (0..3).map(|l| r[i][l] * rot[l][j]).sum();
            }
        }
        r = out;
    }
    below(&r, &mut p);
    p
}

/// The chain's scene with its free end held where it is at the coiled start (a `point`
/// constraint, three rows): a rope fixed at both ends, closed into a loop through the world.
pub fn chain_loop_scene_yaml(n: usize, urdf: &str) -> String {
    let tip = chain_tip(&chain_q0(n));
    let mut s = chain_scene_yaml(n, urdf).replacen(
        "# An unconstrained chain",
        "# A chain held at both ends",
        1,
    );
    let _ = writeln!(
        s,
        "constraints:\n  - {{name: held_end, kind: point, frame_a: link{n}, point_a: [0.0, 0.0, \
         -0.1], frame_b: world, point_b: [{:.17e}, {:.17e}, {:.17e}], rows: [x, y, z]}}",
        tip[0], tip[1], tip[2]
    );
    s
}

/// The scene of the n-link chain, free or `held` at both ends, written with its URDF to a
/// directory of its own under the system's temporary directory and read back as a scene file
/// is (the start state by name), the directory removed again.
pub fn load_chain_scene(n: usize, held: bool) -> constraint_dynamics::Scene {
    static NEXT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let k = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("cd_chain_{}_{k}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary directory");
    std::fs::write(dir.join("chain.urdf"), chain_urdf(n)).expect("the chain's URDF written");
    let yaml = if held {
        chain_loop_scene_yaml(n, "chain.urdf")
    } else {
        chain_scene_yaml(n, "chain.urdf")
    };
    std::fs::write(dir.join("chain.yaml"), yaml).expect("the chain's scene written");
    let scene = constraint_dynamics::Scene::load(dir.join("chain.yaml")).expect("the chain loads");
    let _ = std::fs::remove_dir_all(&dir);
    scene
}
