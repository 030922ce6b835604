//! Forward dynamics of a tree without constraint rows in O(n) time and memory: q̈ = M⁻¹(τ − h)
//! by the articulated-body algorithm, with no n × n matrix. The dense path (CRBA, bias forces,
//! the sparse LTL factor of M and its solves) costs O(Σ depth²) time and n² memory — cubic and
//! quadratic on a chain — but fewer operations per coordinate, so it stays where
//! [`takes_linear_path`] says it is the faster (docs/performance.md measures the crossover).
//!
//! Both paths accept the same models: ABA's pivots D_k are the LTL factor's (L_kk² of
//! M = LᵀL, the joint's inertia with the joints below it free), so the same checks — each
//! pivot against `MIN_PIVOT_RATIO` of M_kk and against 1e-14 of max diag(M) — decide; where a
//! check fails the caller takes the dense path, which errs or takes its augmented form as
//! before.

use crate::algorithm::{DENSE_EAGER_NV, Data, aba, mass_diagonal_after_kinematics};
use crate::linalg::NO_PARENT;
use crate::model::{MIN_PIVOT_RATIO, Model};
use nalgebra::Matrix6;

/// The mean depth of a velocity coordinate in the tree (its ancestors, itself included) from
/// which ABA is the faster: the dense path's work per coordinate grows with it (M's entries in
/// its column, the LTL factor's products), ABA's does not. Measured on chains (mean depth
/// (n + 1)/2): dense/linear time 0.83 at n = 16, 1.03 at n = 24 (docs/performance.md); the
/// four example robots, mean depth ≤ 10, are 1.2–1.4× faster dense.
pub const LINEAR_MIN_MEAN_DEPTH: f64 = 12.0;

/// Whether a system on `model` without constraint rows evaluates its forward dynamics by ABA
/// (`System::forward_dynamics_with`): where it is the faster (mean depth at least
/// [`LINEAR_MIN_MEAN_DEPTH`]), and above `DENSE_EAGER_NV` coordinates whatever the shape, so
/// that no n × n matrix is held unless asked for.
pub fn takes_linear_path(model: &Model) -> bool {
    let nv = model.nv;
    if nv > DENSE_EAGER_NV {
        return true;
    }
    // Coordinates are numbered depth-first: a parent comes before its children.
    let mut depth = vec![0usize; nv];
    for k in 0..nv {
        let p = model.v_parent[k];
        depth[k] = if p == NO_PARENT { 1 } else { depth[p] + 1 };
    }
    nv > 0 && depth.iter().sum::<usize>() as f64 >= LINEAR_MIN_MEAN_DEPTH * nv as f64
}

/// The LTL factor's pivot tolerance relative to max diag(M) (`multipliers::factor_mass`).
const LTL_REL_TOL: f64 = 1e-14;

/// Workspace of the linear-time path: M's diagonal and the ABA pivots (nv each).
#[derive(Clone, Debug, Default)]
pub struct TreeWorkspace {
    diag: Vec<f64>,
    pivots: Vec<f64>,
}

impl TreeWorkspace {
    /// Sized for the model's nv.
    pub fn new(model: &Model) -> Self {
        Self {
            diag: vec![0.0; model.nv],
            pivots: vec![0.0; model.nv],
        }
    }
}

/// q̈ = M⁻¹(τ − h) at (q, v, τ) by ABA into `data.qdd`, O(nb). Returns false, with `data.qdd`
/// not to be used, when a pivot fails the dense path's checks or q̈ is not finite: M is
/// singular or nearly so to working precision there, and the dense path decides.
pub fn tree_forward_dynamics(
    model: &Model,
    data: &mut Data,
    ws: &mut TreeWorkspace,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
) -> bool {
    let nv = model.nv;
    if ws.diag.len() != nv {
        *ws = TreeWorkspace::new(model);
    }
    aba(model, data, q, v, tau);
    if !data.qdd.iter().all(|x| x.is_finite()) {
        return false;
    }
    aba_pivots(model, data, &mut ws.pivots);
    mass_diagonal_after_kinematics(model, data, &mut ws.diag);
    let scale = ws
        .diag
        .iter()
        .fold(0.0f64, |m, x| m.max(x.abs()))
        .max(f64::MIN_POSITIVE);
    ws.pivots
        .iter()
        .zip(&ws.diag)
        .all(|(&d, &m_kk)| d > LTL_REL_TOL * scale && d >= MIN_PIVOT_RATIO * m_kk)
}

/// The pivots L_kk² of M = LᵀL from ABA's last call: D = Sᵀ IA S of each joint (IA its
/// articulated inertia), for a multi-DOF joint factored within its block as LTL does, last
/// coordinate first.
fn aba_pivots(model: &Model, data: &Data, out: &mut [f64]) {
    for (i, b) in model.bodies.iter().enumerate().skip(1) {
        let j = &b.joint;
        let k = j.kind.nv();
        if k == 1 {
            out[j.idx_v] = 1.0 / data.d_inv[i][(0, 0)];
            continue;
        }
        // D = Sᵀ U with U = IA S (ABA's u_mat).
        let mut d = Matrix6::<f64>::zeros();
        for r in 0..k {
            let s = j.subspace[r].to_vector();
            for c in 0..k {
                d[(r, c)] = s.dot(&data.u_mat[i].column(c));
            }
        }
        for p in (0..k).rev() {
            let dpp = d[(p, p)];
            out[j.idx_v + p] = dpp;
            if dpp <= 0.0 || dpp.is_nan() {
                // The caller's check fails on this pivot; the rest do not matter.
                break;
            }
            for r in 0..p {
                for c in 0..=r {
                    d[(r, c)] -= d[(p, r)] * d[(p, c)] / dpp;
                }
            }
            for r in 0..p {
                for c in 0..r {
                    d[(c, r)] = d[(r, c)];
                }
            }
        }
    }
}
