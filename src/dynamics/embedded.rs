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
//! This path allocates: it serves when nobody asks for constraint forces, not in the
//! allocation-free loop.

use super::Baumgarte;
use crate::algorithm::{Data, crba, nonlinear_effects};
use crate::constraints::{Constraint, ConstraintData, ConstraintSet};
use crate::error::{Error, Result};
use crate::linalg::independent_columns;
use crate::model::Model;
use nalgebra::{DMatrix, DVector};

/// The coordinate partition chosen from J: independent and dependent velocity indices.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Partition {
    /// Independent velocity indices (v_i).
    pub independent: Vec<usize>,
    /// Dependent velocity indices (v_d = B v_i).
    pub dependent: Vec<usize>,
    /// Rows of J kept (independent rows).
    pub rows: Vec<usize>,
}

/// Workspace of the embedded form.
#[derive(Clone, Debug, Default)]
pub struct EmbeddedWorkspace {
    /// The partition used at the last solve.
    pub partition: Partition,
    /// N (nv × (nv − r)).
    pub n: DMatrix<f64>,
    /// q̈ (nv).
    pub qdd: DVector<f64>,
    /// The v the last solve used when the scene names dependent velocities: the given v with
    /// those solved from f = 0 (None otherwise).
    pub solved_velocities: Option<Vec<f64>>,
}

/// Choose the partition at the current J.
pub fn partition(j: &DMatrix<f64>) -> Partition {
    partition_preferring(j, &[])
}

/// Choose the partition at the current J, taking the `preferred` velocity columns (the scene's
/// `dependent:`) as dependent first where they are independent, and completing with the
/// best-conditioned of the others (column-pivoted QR of their part outside the span of the
/// preferred columns).
pub fn partition_preferring(j: &DMatrix<f64>, preferred: &[usize]) -> Partition {
    let nv = j.ncols();
    let rows = independent_columns(&j.transpose(), 1e-10);
    let jr = j.select_rows(rows.iter());
    let mut dependent: Vec<usize> = if preferred.is_empty() {
        vec![]
    } else {
        let jp = jr.select_columns(preferred.iter());
        independent_columns(&jp, 1e-10)
            .iter()
            .map(|&k| preferred[k])
            .collect()
    };
    if dependent.len() < rows.len() {
        let others: Vec<usize> = (0..nv).filter(|c| !dependent.contains(c)).collect();
        let mut rest = jr.select_columns(others.iter());
        if !dependent.is_empty() {
            let u = jr.select_columns(dependent.iter()).qr().q();
            rest -= &u * (u.transpose() * &rest);
        }
        let more = independent_columns(&rest, 1e-10);
        let need = rows.len() - dependent.len();
        dependent.extend(more.iter().take(need).map(|&k| others[k]));
    }
    dependent.sort();
    let independent = (0..nv).filter(|c| !dependent.contains(c)).collect();
    let mut rows = rows;
    rows.sort();
    Partition {
        independent,
        dependent,
        rows,
    }
}

/// The `velocity` rows whose constraint names a dependent velocity: (row, velocity index).
fn declared_dependents(set: &ConstraintSet) -> Vec<(usize, usize)> {
    set.items
        .iter()
        .zip(&set.ranges)
        .filter_map(|(c, rg)| match c {
            Constraint::Velocity(vc) => vc.dependent.map(|d| (rg.start, d)),
            _ => None,
        })
        .collect()
}

/// The seed's eq. (2): the declared dependent velocities solved from f(q, v_i, v_d, t) = 0 by
/// Newton's method, the other velocities held. Returns the corrected v (None when nothing is
/// declared). Leaves `cd` evaluated at the corrected state.
#[allow(clippy::too_many_arguments)]
fn solve_dependent_velocities(
    model: &Model,
    data: &mut Data,
    set: &ConstraintSet,
    cd: &mut ConstraintData,
    decl: &[(usize, usize)],
    q: &[f64],
    v: &[f64],
) -> Result<Option<Vec<f64>>> {
    if decl.is_empty() {
        return Ok(None);
    }
    let mut v = v.to_vec();
    let n = decl.len();
    let name = |r: usize| {
        let k = set
            .ranges
            .iter()
            .position(|rg| rg.contains(&r))
            .unwrap_or(0);
        set.names[k].clone()
    };
    for _ in 0..NEWTON_ITERATIONS {
        set.evaluate(model, data, cd, q, &v);
        set.check_finite(cd)?;
        let f = DVector::from_fn(n, |a, _| cd.jv[decl[a].0]);
        let scale = decl.iter().map(|&(_, d)| v[d].abs()).fold(1.0, f64::max);
        if f.amax() <= NEWTON_TOL * scale {
            return Ok(Some(v));
        }
        let a = DMatrix::from_fn(n, n, |i, k| cd.j[(decl[i].0, decl[k].1)]);
        let step = a
            .lu()
            .solve(&f)
            .ok_or_else(|| Error::InconsistentConstraints {
                message: format!(
                    "∂f/∂(dependent velocities) is singular at this state (constraints: {})",
                    decl.iter()
                        .map(|&(r, _)| name(r))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            })?;
        for (i, &(_, d)) in decl.iter().enumerate() {
            v[d] -= step[i];
        }
    }
    Err(Error::InconsistentConstraints {
        message: format!(
            "Newton's method found no dependent velocities satisfying f = 0 in \
             {NEWTON_ITERATIONS} iterations (constraints: {})",
            decl.iter()
                .map(|&(r, _)| name(r))
                .collect::<Vec<_>>()
                .join(", ")
        ),
    })
}

/// Newton on the dependent velocities: iterations and the residual tolerance relative to
/// max(1, |v_d|) (quadratic convergence reaches round-off in a few steps from a nearby state).
const NEWTON_ITERATIONS: usize = 30;
const NEWTON_TOL: f64 = 1e-14;

/// q̈ of the constrained system without multipliers (into `ws.qdd`); `ws.partition` is chosen
/// afresh unless `keep_partition` and it still has the right rank.
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
    stab: Baumgarte,
) -> Result<()> {
    // Dependent velocities the scene names are functions of the others (eq. 2): solve them
    // from f first, so the equations below hold at a state that satisfies f = 0 exactly.
    let decl = declared_dependents(set);
    let corrected = solve_dependent_velocities(model, data, set, cd, &decl, q, v)?;
    let v = corrected.as_deref().unwrap_or(v);
    set.evaluate(model, data, cd, q, v);
    set.check_finite(cd)?;
    crba(model, data, q);
    nonlinear_effects(model, data, q, v);
    let nv = model.nv;
    let b_full = DVector::from_fn(set.nrows, |k, _| {
        -cd.gamma[k] - stab.kd * cd.jv[k] - stab.kp * cd.phi[k]
    });
    let preferred: Vec<usize> = decl.iter().map(|&(_, d)| d).collect();
    ws.partition = partition_preferring(&cd.j, &preferred);
    let p = &ws.partition;
    let jr = cd.j.select_rows(p.rows.iter());
    let br = b_full.select_rows(p.rows.iter());
    let jd = jr.select_columns(p.dependent.iter());
    let ji = jr.select_columns(p.independent.iter());
    let lu = jd.clone().lu();
    let (nd, ni) = (p.dependent.len(), p.independent.len());
    let bmat = if nd > 0 {
        -lu.solve(&ji).ok_or_else(|| singular(set))?
    } else {
        DMatrix::zeros(0, ni)
    };
    let qdd_d0 = if nd > 0 {
        lu.solve(&br).ok_or_else(|| singular(set))?
    } else {
        DVector::zeros(0)
    };
    // The dropped rows must be satisfied too (consistency of redundant constraints).
    let mut n = DMatrix::zeros(nv, ni);
    let mut qdd_p = DVector::zeros(nv);
    for (a, &c) in p.independent.iter().enumerate() {
        n[(c, a)] = 1.0;
    }
    for (k, &c) in p.dependent.iter().enumerate() {
        for a in 0..ni {
            n[(c, a)] = bmat[(k, a)];
        }
        qdd_p[c] = qdd_d0[k];
    }
    let resid = &cd.j * &qdd_p - &b_full;
    if resid.amax() > 1e-7 * b_full.amax().max(1.0) {
        return Err(Error::InconsistentConstraints {
            message: format!("redundant constraint rows disagree by {:.3e}", resid.amax()),
        });
    }
    let m = &data.mass_matrix;
    let rhs_full = DVector::from_fn(nv, |i, _| tau[i] - data.tau[i]) - m * &qdd_p;
    // Chetaev: the virtual displacements are N δv_i (NᵀJᵀ = 0, NᵀMN symmetric positive
    // definite). Velocity-determined rows project on N_B instead (seed eq. 10 with eq. 6's B),
    // and N_Bᵀ M N is not symmetric.
    let z = match velocity_determined_projection(set, cd, p, &n, q, v)? {
        None => (n.transpose() * m * &n)
            .cholesky()
            .ok_or_else(|| Error::SingularMass {
                message: "the reduced mass matrix NᵀMN is not positive definite".into(),
            })?
            .solve(&(n.transpose() * rhs_full)),
        Some(nb) => (nb.transpose() * m * &n)
            .lu()
            .solve(&(nb.transpose() * rhs_full))
            .ok_or_else(|| Error::SingularMass {
                message: "the reduced matrix N_BᵀMN of the velocity-determined form is singular"
                    .into(),
            })?,
    };
    ws.qdd = &n * z + qdd_p;
    ws.n = n;
    ws.solved_velocities = corrected;
    Ok(())
}

/// N with the rows of velocity-determined constraints' dependent velocities replaced by the
/// seed's B (eq. 6, `VelocityConstraint::velocity_determined_b`); None when there are none.
/// Row d of N is Chetaev's −(∂f/∂v_α)/(∂f/∂v_d) only when d appears in no other row and f's
/// other velocities are independent; other cases are refused by name.
fn velocity_determined_projection(
    set: &ConstraintSet,
    cd: &ConstraintData,
    p: &Partition,
    n: &DMatrix<f64>,
    q: &[f64],
    v: &[f64],
) -> Result<Option<DMatrix<f64>>> {
    let mut nb: Option<DMatrix<f64>> = None;
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
        let nbm = nb.get_or_insert_with(|| n.clone());
        nbm.row_mut(d).fill(0.0);
        for (alpha, b_alpha) in b {
            let a = p
                .independent
                .iter()
                .position(|&c| c == alpha)
                .ok_or_else(|| {
                    unsupported("another velocity of f is dependent in the embedded partition")
                })?;
            nbm[(d, a)] = b_alpha;
        }
    }
    Ok(nb)
}

fn singular(set: &ConstraintSet) -> Error {
    Error::InconsistentConstraints {
        message: format!(
            "the dependent block of J is singular (constraints: {})",
            set.names.join(", ")
        ),
    }
}
