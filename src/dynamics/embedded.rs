//! The multiplier-free (embedded) form, after Voronets: the constraints `J v = 0` are solved for
//! dependent velocities, `v_d = B v_i` with `B = −J_d⁻¹ J_i`, so `v = N v_i`, `N = P [I; B]`
//! (P the column permutation), and the accelerations `q̈ = N q̈_i + q̈_p` with
//! `q̈_p = P [0; J_d⁻¹ b]`, b = −γ − K_d J v − K_p φ. Projecting the dynamics on N removes the
//! multipliers (Nᵀ Jᵀ = 0):
//!   (Nᵀ M N) q̈_i = Nᵀ (τ − h − M q̈_p),
//! nv − rank(J) equations instead of nv + nc. Redundant rows are dropped first (row-pivoted QR);
//! the dependent columns are the best-conditioned ones (column-pivoted QR), or first the ones a
//! `velocity` constraint names under `dependent:`; those are also solved from f(q, v, t) = 0 by
//! Newton before anything else (seed 001, eq. 2: v_d is a function of q, v_i, t), so the
//! equations are evaluated where f = 0 exactly (`EmbeddedWorkspace::solved_velocities`).
//! Every buffer lives in the [`EmbeddedWorkspace`]: a solve allocates nothing once the workspace
//! is sized ([`EmbeddedWorkspace::new`], or grown by the first solve), except on
//! `velocity_determined` rows, whose B comes as a list.

use super::Baumgarte;
use super::partition::{Partition, PartitionWorkspace, partition_into};
use crate::algorithm::{
    DENSE_EAGER_NV, Data, bias_forces_after_kinematics, crba_full_after_kinematics,
};
use crate::constraints::{Constraint, ConstraintData, ConstraintSet};
use crate::error::{Error, Result};
use crate::linalg::{cholesky_in_place, cholesky_solve, lu_in_place, lu_solve};
use crate::model::Model;
use nalgebra::{DMatrix, DVector};

/// Workspace of the embedded form: the partition, N and every intermediate (sizes nv, nc).
#[derive(Clone, Debug, Default)]
pub struct EmbeddedWorkspace {
    /// The partition used at the last solve.
    pub partition: Partition,
    /// q̈ (nv).
    pub qdd: DVector<f64>,
    partition_ws: PartitionWorkspace,
    /// (row, velocity) of each `velocity` constraint naming a dependent velocity; those
    /// velocities (the preferred dependent columns).
    declared: Vec<(usize, usize)>,
    preferred: Vec<usize>,
    /// v with the declared dependent velocities solved from f = 0 (valid when `solved`).
    v_solved: Vec<f64>,
    solved: bool,
    /// N (leading nv × ni), N_B for velocity-determined rows, M N, the reduced matrix (ni × ni).
    n: DMatrix<f64>,
    nb: DMatrix<f64>,
    mn: DMatrix<f64>,
    reduced: DMatrix<f64>,
    /// J_d (r × r) and its LU pivots (also Newton's matrix on the declared velocities).
    jd: DMatrix<f64>,
    piv: Vec<usize>,
    /// b (nc), q̈_p (nv), τ − h − M q̈_p (nv), one column (nc), the reduced unknowns (nv).
    b: Vec<f64>,
    qdd_p: Vec<f64>,
    rhs: Vec<f64>,
    col: Vec<f64>,
    z: Vec<f64>,
}

impl EmbeddedWorkspace {
    /// Size every buffer for the model (nv) and constraint set (nc).
    pub fn new(model: &Model, set: &ConstraintSet) -> Self {
        let mut ws = Self::default();
        ws.fit(model.nv, set.nrows);
        ws
    }

    /// The v the last solve used when the scene names dependent velocities: the given v with
    /// those solved from f = 0 (None otherwise).
    pub fn solved_velocities(&self) -> Option<&[f64]> {
        self.solved.then_some(self.v_solved.as_slice())
    }

    /// Grow the buffers to nv, nc (a no-op once sized).
    fn fit(&mut self, nv: usize, nc: usize) {
        if self.qdd.len() == nv && self.b.len() == nc {
            return;
        }
        let r = nc.min(nv);
        self.partition = Partition {
            independent: Vec::with_capacity(nv),
            dependent: Vec::with_capacity(nv),
            rows: Vec::with_capacity(nc),
        };
        self.qdd = DVector::zeros(nv);
        self.partition_ws = PartitionWorkspace::new(nc, nv);
        self.declared = Vec::with_capacity(nc);
        self.preferred = Vec::with_capacity(nc);
        self.v_solved = vec![0.0; nv];
        if nv <= DENSE_EAGER_NV {
            self.size_square(nv);
        }
        self.jd = DMatrix::zeros(nc.max(r), nc.max(r));
        self.piv = vec![0; nc.max(nv)];
        self.b = vec![0.0; nc];
        self.qdd_p = vec![0.0; nv];
        self.rhs = vec![0.0; nv];
        self.col = vec![0.0; nc.max(nv)];
        self.z = vec![0.0; nv];
    }

    /// Size N, N_B, M N and the reduced matrix to nv × nv when they are not (a large
    /// model's first embedded solve: its unconstrained evaluations never hold them).
    fn size_square(&mut self, nv: usize) {
        if self.n.shape() != (nv, nv) {
            self.n = DMatrix::zeros(nv, nv);
            self.nb = DMatrix::zeros(nv, nv);
            self.mn = DMatrix::zeros(nv, nv);
            self.reduced = DMatrix::zeros(nv, nv);
        }
    }
}

/// The `velocity` rows whose constraint names a dependent velocity: (row, velocity index).
fn declared_dependents(set: &ConstraintSet, out: &mut Vec<(usize, usize)>) {
    out.clear();
    out.extend(
        set.items
            .iter()
            .zip(&set.ranges)
            .filter_map(|(c, rg)| match c {
                Constraint::Velocity(vc) => vc.dependent.map(|d| (rg.start, d)),
                _ => None,
            }),
    );
}

/// The seed's eq. (2): the declared dependent velocities solved from f(q, v_i, v_d, t) = 0 by
/// Newton's method, the other velocities held, into `ws.v_solved` (`ws.solved` false when
/// nothing is declared). Leaves `cd` evaluated at the corrected state.
#[allow(clippy::too_many_arguments)]
fn solve_dependent_velocities(
    model: &Model,
    data: &mut Data,
    set: &ConstraintSet,
    cd: &mut ConstraintData,
    ws: &mut EmbeddedWorkspace,
    t: f64,
    q: &[f64],
    v: &[f64],
) -> Result<()> {
    ws.solved = false;
    let decl = &ws.declared;
    if decl.is_empty() {
        return Ok(());
    }
    let v_s = &mut ws.v_solved;
    v_s.copy_from_slice(v);
    let n = decl.len();
    let names = || {
        decl.iter()
            .map(|&(r, _)| {
                let k = set
                    .ranges
                    .iter()
                    .position(|rg| rg.contains(&r))
                    .unwrap_or(0);
                set.names[k].clone()
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    for _ in 0..NEWTON_ITERATIONS {
        set.evaluate(model, data, cd, t, q, v_s);
        set.check_finite(cd)?;
        let f = &mut ws.col[..n];
        for (a, &(row, _)) in decl.iter().enumerate() {
            f[a] = cd.jv[row];
        }
        let scale = decl.iter().map(|&(_, d)| v_s[d].abs()).fold(1.0, f64::max);
        if f.iter().fold(0.0f64, |m, x| m.max(x.abs())) <= NEWTON_TOL * scale {
            ws.solved = true;
            return Ok(());
        }
        for (i, &(row, _)) in decl.iter().enumerate() {
            for (k, &(_, d)) in decl.iter().enumerate() {
                ws.jd[(i, k)] = cd.j[(row, d)];
            }
        }
        if !lu_in_place(&mut ws.jd, &mut ws.piv[..n]) {
            return Err(Error::InconsistentConstraints {
                message: format!(
                    "∂f/∂(dependent velocities) is singular at this state (constraints: {})",
                    names()
                ),
            });
        }
        lu_solve(&ws.jd, &ws.piv[..n], f);
        for (i, &(_, d)) in decl.iter().enumerate() {
            v_s[d] -= f[i];
        }
    }
    Err(Error::InconsistentConstraints {
        message: format!(
            "Newton's method found no dependent velocities satisfying f = 0 in \
             {NEWTON_ITERATIONS} iterations (constraints: {})",
            names()
        ),
    })
}

/// Newton on the dependent velocities: iterations and the residual tolerance relative to
/// max(1, |v_d|) (quadratic convergence reaches round-off in a few steps from a nearby state).
const NEWTON_ITERATIONS: usize = 30;
const NEWTON_TOL: f64 = 1e-14;

/// q̈ of the constrained system without multipliers (into `ws.qdd`) at (q, v, τ) and time `t`
/// [s] (what `velocity` rows read); `ws.partition` is chosen afresh at every call from the
/// current J.
#[allow(clippy::too_many_arguments)]
pub fn embedded_forward_dynamics(
    model: &Model,
    data: &mut Data,
    set: &ConstraintSet,
    cd: &mut ConstraintData,
    ws: &mut EmbeddedWorkspace,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    t: f64,
    stab: Baumgarte,
) -> Result<()> {
    let (nv, nc) = (model.nv, set.nrows);
    ws.fit(nv, nc);
    // Dependent velocities the scene names are functions of the others (eq. 2): solve them
    // from f first, so the equations below hold at a state that satisfies f = 0 exactly.
    declared_dependents(set, &mut ws.declared);
    solve_dependent_velocities(model, data, set, cd, ws, t, q, v)?;
    // Taken out of the workspace while it is borrowed below (no allocation), put back after.
    let v_solved = std::mem::take(&mut ws.v_solved);
    let v = if ws.solved { v_solved.as_slice() } else { v };
    let result = solve(model, data, set, cd, ws, t, q, v, tau, stab);
    ws.v_solved = v_solved;
    result
}

#[allow(clippy::too_many_arguments)]
fn solve(
    model: &Model,
    data: &mut Data,
    set: &ConstraintSet,
    cd: &mut ConstraintData,
    ws: &mut EmbeddedWorkspace,
    t: f64,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    stab: Baumgarte,
) -> Result<()> {
    let (nv, nc) = (model.nv, set.nrows);
    ws.size_square(nv);
    // One kinematics pass at (q, v, q̈ = 0) serves the constraints, M and h.
    set.evaluate(model, data, cd, t, q, v);
    set.check_finite(cd)?;
    crba_full_after_kinematics(model, data);
    bias_forces_after_kinematics(model, data);
    for k in 0..nc {
        ws.b[k] = -cd.gamma[k] - stab.kd * cd.jv[k] - stab.kp * cd.phi[k];
    }
    ws.preferred.clear();
    ws.preferred.extend(ws.declared.iter().map(|&(_, d)| d));
    partition_into(
        &cd.j,
        &ws.preferred,
        &mut ws.partition_ws,
        &mut ws.partition,
    );
    let p = &ws.partition;
    let (nd, ni) = (p.dependent.len(), p.independent.len());
    // J_d (rows kept × dependent columns) factored; B = −J_d⁻¹ J_i into N's dependent rows,
    // q̈_d0 = J_d⁻¹ b_r into q̈_p.
    for (a, &r) in p.rows.iter().enumerate() {
        for (k, &c) in p.dependent.iter().enumerate() {
            ws.jd[(a, k)] = cd.j[(r, c)];
        }
    }
    if nd > 0 && !lu_in_place(&mut ws.jd, &mut ws.piv[..nd]) {
        return Err(singular(set));
    }
    ws.qdd_p.iter_mut().for_each(|x| *x = 0.0);
    for a in 0..ni {
        for c in 0..nv {
            ws.n[(c, a)] = 0.0;
        }
    }
    for (a, &c) in p.independent.iter().enumerate() {
        ws.n[(c, a)] = 1.0;
        if nd > 0 {
            let col = &mut ws.col[..nd];
            for (k, &r) in p.rows.iter().enumerate() {
                col[k] = -cd.j[(r, c)];
            }
            lu_solve(&ws.jd, &ws.piv[..nd], col);
            for (k, &d) in p.dependent.iter().enumerate() {
                ws.n[(d, a)] = col[k];
            }
        }
    }
    if nd > 0 {
        let col = &mut ws.col[..nd];
        for (k, &r) in p.rows.iter().enumerate() {
            col[k] = ws.b[r];
        }
        lu_solve(&ws.jd, &ws.piv[..nd], col);
        for (k, &d) in p.dependent.iter().enumerate() {
            ws.qdd_p[d] = col[k];
        }
    }
    // The dropped rows must be satisfied too (consistency of redundant constraints).
    let (mut resid, mut bmax) = (0.0f64, 0.0f64);
    for k in 0..nc {
        let jq: f64 = (0..nv).map(|c| cd.j[(k, c)] * ws.qdd_p[c]).sum();
        resid = resid.max((jq - ws.b[k]).abs());
        bmax = bmax.max(ws.b[k].abs());
    }
    if super::disagree_beyond_rounding(resid, bmax) {
        return Err(Error::InconsistentConstraints {
            message: format!("redundant constraint rows disagree by {resid:.3e}"),
        });
    }
    let m = &data.mass_matrix;
    for i in 0..nv {
        let mq: f64 = (0..nv).map(|c| m[(i, c)] * ws.qdd_p[c]).sum();
        ws.rhs[i] = tau[i] - data.tau[i] - mq;
    }
    // M N (nv × ni).
    for a in 0..ni {
        for i in 0..nv {
            ws.mn[(i, a)] = (0..nv).map(|c| m[(i, c)] * ws.n[(c, a)]).sum();
        }
    }
    // Chetaev: the virtual displacements are N δv_i (NᵀJᵀ = 0, NᵀMN symmetric positive
    // definite). Velocity-determined rows project on N_B instead (seed eq. 10 with eq. 6's B),
    // and N_Bᵀ M N is not symmetric.
    let projected = velocity_determined_projection(set, cd, ws, q, v)?;
    let test = if projected { &ws.nb } else { &ws.n };
    for a in 0..ni {
        for b in 0..ni {
            ws.reduced[(a, b)] = (0..nv).map(|c| test[(c, a)] * ws.mn[(c, b)]).sum();
        }
        ws.z[a] = (0..nv).map(|c| test[(c, a)] * ws.rhs[c]).sum();
    }
    let z = &mut ws.z[..ni];
    if !projected {
        cholesky_in_place(&mut ws.reduced, ni, 0.0).map_err(|_| Error::SingularMass {
            message: "the reduced mass matrix NᵀMN is not positive definite".into(),
        })?;
        cholesky_solve(&ws.reduced, ni, z);
    } else {
        if !lu_in_place(&mut ws.reduced, &mut ws.piv[..ni]) {
            return Err(Error::SingularMass {
                message: "the reduced matrix N_BᵀMN of the velocity-determined form is singular"
                    .into(),
            });
        }
        lu_solve(&ws.reduced, &ws.piv[..ni], z);
    }
    for i in 0..nv {
        ws.qdd[i] = ws.qdd_p[i] + (0..ni).map(|a| ws.n[(i, a)] * z[a]).sum::<f64>();
    }
    Ok(())
}

/// Fill `ws.nb`, N with the rows of velocity-determined constraints' dependent velocities
/// replaced by the seed's B (eq. 6, `VelocityConstraint::velocity_determined_b`); false when
/// there are none. Row d of N is Chetaev's −(∂f/∂v_α)/(∂f/∂v_d) only when d appears in no other
/// row and f's other velocities are independent; other cases are refused by name.
fn velocity_determined_projection(
    set: &ConstraintSet,
    cd: &ConstraintData,
    ws: &mut EmbeddedWorkspace,
    q: &[f64],
    v: &[f64],
) -> Result<bool> {
    let p = &ws.partition;
    let mut any = false;
    for (k, c) in set.items.iter().enumerate() {
        let Constraint::Velocity(vc) = c else {
            continue;
        };
        let (true, Some(d)) = (vc.velocity_determined, vc.dependent) else {
            continue;
        };
        let row = set.ranges[k].start;
        let unsupported = |why: &str| Error::Unsupported {
            what: format!("velocity_determined constraint '{}'", set.names[k]),
            why: why.into(),
        };
        if !p.dependent.contains(&d) {
            return Err(unsupported(
                "its dependent velocity is not independent of the other constraints here",
            ));
        }
        if (0..set.nrows).any(|r| r != row && cd.j[(r, d)] != 0.0) {
            return Err(unsupported(
                "its dependent velocity also appears in other constraint rows (B is defined for \
                 a velocity only this constraint determines)",
            ));
        }
        let b = vc
            .velocity_determined_b(q, v, cd.t)
            .map_err(|m| Error::Constraint {
                name: set.names[k].clone(),
                message: format!("velocity-determined B: {m}"),
            })?;
        if !any {
            ws.nb.copy_from(&ws.n);
            any = true;
        }
        ws.nb.row_mut(d).fill(0.0);
        for (alpha, b_alpha) in b {
            let a = p
                .independent
                .iter()
                .position(|&c| c == alpha)
                .ok_or_else(|| {
                    unsupported("another velocity of f is dependent in the embedded partition")
                })?;
            ws.nb[(d, a)] = b_alpha;
        }
    }
    Ok(any)
}

fn singular(set: &ConstraintSet) -> Error {
    Error::InconsistentConstraints {
        message: format!(
            "the dependent block of J is singular (constraints: {})",
            set.names.join(", ")
        ),
    }
}
