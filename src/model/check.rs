//! What the loader checks on the assembled model, where the physics is decided: the inertia of
//! each moving body after fixed and locked joints have welded its links together, and whether
//! the joint-space inertia matrix M is (nearly) singular.
//!
//! A dummy, sensor or antenna link whose own inertia is not physical does not matter once it is
//! welded to a real body: only the merged body moves. Such links give a warning; a moving body
//! whose merged inertia is not physical is an error naming it, its links and its moments.

use super::{InertiaPolicy, Model, SingularJoint};
use crate::error::{Error, Result};
use crate::spatial::Inertia;
use nalgebra::{DMatrix, Matrix3, Matrix6, SymmetricEigen};

/// Relative tolerance of the inertia checks: principal moments below `−TOL·scale` are negative
/// and the triangle inequality may be missed by `TOL·scale` (rounding in a CAD export).
const REL_TOL: f64 = 1e-9;
/// The absolute part of the scale [m]: a body of mass m is judged on moments of at least
/// m·(1 mm)², so that noise-level entries (2.4e-35 kg·m² in icub) on a near point mass pass.
const ABS_LENGTH: f64 = 1e-3;

/// The tolerance of a moving body's merged inertia, as a fraction of m·ℓ² (m its mass, ℓ its
/// `extent`): the scale of the inertia the body presents at its joint. A principal moment below
/// 0 or a triangle-inequality excess within it is a CAD approximation (romeo_laas_small's
/// elbow: 1.1 % of m·ℓ², 12 % of its largest moment), kept as written — as Pinocchio does —
/// with a warning; beyond it the body is refused (romeo_small's shoulder and elbow: 22 % and
/// 15 %).
pub const BODY_TOL: f64 = 0.05;

/// Below this, a joint's effective inertia with the joints below it free (ABA's pivot D) is
/// noise against its inertia with them locked (M's diagonal entry): M is singular there to
/// working precision and q̈ would come out of rounding errors (icub's point-mass head on a
/// 3-axis neck: 1e-17, which gave q̈ = −2.8e9 with a fixed base).
pub const MIN_PIVOT_RATIO: f64 = 1e-9;

/// Why a rotational inertia is not that of a rigid body, within the tolerance: negative
/// principal moments or a violated triangle inequality (`None` when it is physical).
pub(super) fn inertia_defect(mass: f64, inertia_com: &Matrix3<f64>) -> Option<String> {
    let ev = SymmetricEigen::new(*inertia_com).eigenvalues;
    let (a, b, c) = (ev[0], ev[1], ev[2]);
    let tol = REL_TOL * ev.abs().max().max(mass * ABS_LENGTH * ABS_LENGTH);
    if ev.iter().any(|&e| e < -tol) {
        return Some(format!(
            "<inertia> is not positive definite: principal moments {a:.6e}, {b:.6e}, {c:.6e} kg·m²"
        ));
    }
    if a + b < c - tol || a + c < b - tol || b + c < a - tol {
        return Some(format!(
            "<inertia> violates the triangle inequality: principal moments {a:.6e}, {b:.6e}, \
             {c:.6e} kg·m²"
        ));
    }
    None
}

/// By how much a rotational inertia misses being physical [kg·m²]: the most negative principal
/// moment, or the triangle-inequality excess c − a − b (sorted a ≤ b ≤ c), whichever is larger;
/// ≤ 0 when it is physical.
fn unphysical_amount(inertia_com: &Matrix3<f64>) -> f64 {
    let e = SymmetricEigen::new(*inertia_com).eigenvalues;
    let mut ev = [e[0], e[1], e[2]];
    ev.sort_by(f64::total_cmp);
    (-ev[0]).max(ev[2] - ev[0] - ev[1])
}

/// A body's extent ℓ [m]: the largest distance from its joint frame to its centre of mass,
/// to the frames of the links welded to it and to the joints of the bodies below it.
pub(super) fn extent(model: &Model, body: usize) -> f64 {
    let b = &model.bodies[body];
    let links = model
        .frames
        .iter()
        .filter(|f| f.body == body)
        .map(|f| f.placement.translation.norm());
    let children = model
        .bodies
        .iter()
        .skip(1)
        .filter(|c| c.parent == body)
        .map(|c| c.placement.translation.norm());
    links.chain(children).fold(b.inertia.com.norm(), f64::max)
}

/// m·ℓ² of a body [kg·m²] (ℓ at least 1 mm).
fn merged_scale(model: &Model, body: usize) -> f64 {
    let l = extent(model, body).max(ABS_LENGTH);
    model.bodies[body].inertia.mass * l * l
}

/// The nearest physical rotational inertia with the same principal axes: negative moments
/// raised to 0, then a triangle excess δ = c − a − b > 0 removed by moving (a, b, c) by
/// (δ/3, δ/3, −δ/3), the orthogonal projection onto the face c = a + b.
pub(super) fn nearest_physical(inertia_com: &Matrix3<f64>) -> Matrix3<f64> {
    let e = SymmetricEigen::new(*inertia_com);
    let mut m: Vec<f64> = e.eigenvalues.iter().map(|x| x.max(0.0)).collect();
    let (hi, _) = m.iter().enumerate().fold(
        (0, f64::MIN),
        |acc, (i, &x)| if x > acc.1 { (i, x) } else { acc },
    );
    let excess = m[hi] - (m.iter().sum::<f64>() - m[hi]);
    if excess > 0.0 {
        for (i, x) in m.iter_mut().enumerate() {
            *x += if i == hi { -excess / 3.0 } else { excess / 3.0 };
        }
    }
    let d = Matrix3::from_diagonal(&nalgebra::Vector3::new(m[0], m[1], m[2]));
    e.eigenvectors * d * e.eigenvectors.transpose()
}

/// The links (frames) of each body, in file order.
pub(super) fn links_of(model: &Model, body: usize) -> Vec<&str> {
    model
        .frames
        .iter()
        .filter(|f| f.body == body && f.name != "world")
        .map(|f| f.name.as_str())
        .collect()
}

/// `D_k / M_kk` of every velocity coordinate at q (ABA's pivots over CRBA's diagonal), with
/// the worst one first: `(body, ratio, M_kk)`. World-axes articulated inertias, O(n).
pub fn pivot_ratios(model: &Model, q: &[f64]) -> Vec<(usize, f64, f64)> {
    let nb = model.nbodies();
    let mut o_m_i = vec![crate::spatial::SE3::identity(); nb];
    for i in 1..nb {
        let b = &model.bodies[i];
        let j = &b.joint;
        let li = j
            .kind
            .placed(&b.placement, &q[j.idx_q..j.idx_q + j.kind.nq()]);
        o_m_i[i] = o_m_i[b.parent].compose(&li);
    }
    let rigid: Vec<Matrix6<f64>> = (0..nb)
        .map(|i| model.bodies[i].inertia.transformed(&o_m_i[i]).matrix())
        .collect();
    let (mut articulated, mut composite) = (rigid.clone(), rigid);
    let mut out = vec![];
    for i in (1..nb).rev() {
        let b = &model.bodies[i];
        let nv = b.joint.kind.nv();
        let s = DMatrix::from_fn(6, nv, |r, k| {
            o_m_i[i].act_motion(&b.joint.subspace[k]).to_vector()[r]
        });
        let u = articulated[i] * &s;
        let d = s.transpose() * &u;
        let c = s.transpose() * composite[i] * &s;
        let (ratio, diag) = generalized_min_ratio(&d, &c);
        out.push((i, ratio, diag));
        let mut passed = articulated[i];
        if let Some(dinv) = d.clone().try_inverse().filter(|_| ratio > 0.0) {
            passed -= Matrix6::from_column_slice((&u * dinv * u.transpose()).as_slice());
        }
        let p = b.parent;
        if p != 0 {
            articulated[p] += passed;
            let ci = composite[i];
            composite[p] += ci;
        }
    }
    out.sort_by(|a, b| a.1.total_cmp(&b.1));
    out
}

/// Smallest λ of D x = λ C x (1 DOF: D/C) and C's largest diagonal entry; ratio 0 when C is
/// singular (the joint moves no inertia at all).
fn generalized_min_ratio(d: &DMatrix<f64>, c: &DMatrix<f64>) -> (f64, f64) {
    let diag = (0..c.nrows()).map(|k| c[(k, k)]).fold(0.0, f64::max);
    if c.nrows() == 1 {
        return (
            if c[(0, 0)] > 0.0 {
                d[(0, 0)] / c[(0, 0)]
            } else {
                0.0
            },
            diag,
        );
    }
    let Some(chol) = c.clone().cholesky() else {
        return (0.0, diag);
    };
    let linv = chol.l().try_inverse().unwrap_or_else(|| c.clone() * 0.0);
    let m = &linv * d * linv.transpose();
    let ev = SymmetricEigen::new((&m + m.transpose()) * 0.5).eigenvalues;
    (ev.min(), diag)
}

/// Mass of each body's subtree [kg] (the body itself included).
pub(super) fn subtree_mass(model: &Model) -> Vec<f64> {
    let mut m: Vec<f64> = model.bodies.iter().map(|b| b.inertia.mass).collect();
    for i in (1..model.nbodies()).rev() {
        let p = model.bodies[i].parent;
        m[p] += m[i];
    }
    m
}

/// A merged body's inertia (for messages): mass and principal moments.
pub(super) fn describe(i: &Inertia) -> String {
    let ev = SymmetricEigen::new(i.inertia_com).eigenvalues;
    format!(
        "mass {:.4e} kg, principal moments {:.3e}, {:.3e}, {:.3e} kg·m²",
        i.mass, ev[0], ev[1], ev[2]
    )
}

/// Find whether M is singular or nearly so (at the neutral configuration and at a
/// generic one, so that a coincidental alignment alone does not decide), naming the joint:
/// a joint that moves no mass, or whose effective inertia with the joints below it free is
/// below `MIN_PIVOT_RATIO` of its locked inertia.
pub(super) fn singular_joint(m: &Model, file: &str) -> Option<SingularJoint> {
    if m.nv == 0 {
        return None;
    }
    let masses = subtree_mass(m);
    let mut generic = m.neutral();
    for b in m.bodies.iter().skip(1) {
        let j = &b.joint;
        if j.kind.nq() == 1 {
            // Irrational-looking angles, different per joint, inside most limits.
            generic[j.idx_q] = 0.3 + 0.137 * ((j.idx_q * 7919) % 11) as f64 / 11.0;
        }
    }
    let mut worst: Option<(usize, f64, f64)> = None;
    for q in [m.neutral(), generic] {
        let ratios = pivot_ratios(m, &q);
        let Some(&(i, r, c)) = ratios.first() else {
            continue;
        };
        if r >= MIN_PIVOT_RATIO {
            return None;
        }
        if worst.is_none_or(|w| r > w.1) {
            worst = Some((i, r, c));
        }
    }
    let (i, ratio, c) = worst?;
    let body = &m.bodies[i];
    let moved: Vec<&str> = m
        .frames
        .iter()
        .filter(|f| {
            let mut b = f.body;
            while b != 0 && b != i {
                b = m.bodies[b].parent;
            }
            b == i && f.body != 0
        })
        .map(|f| f.name.as_str())
        .collect();
    let message = if masses[i] <= 0.0 || c <= 0.0 {
        format!(
            "moves no mass: its links {} are all massless, so M is singular (give them \
             mass and inertia, or declare the joint fixed or locked)",
            moved.join(", ")
        )
    } else {
        format!(
            "the joint-space inertia matrix is singular to working precision here: with the \
             joints below it free this joint moves an effective inertia of {ratio:.1e} of \
             its locked inertia {c:.3e} (limit {MIN_PIVOT_RATIO:e}), so q̈ would be rounding \
             noise; links moved: {} (point masses or massless links on several joints; \
             give them rotational inertia, or lock joints)",
            moved.join(", ")
        )
    };
    Some(SingularJoint {
        file: file.to_string(),
        joint: body.joint.name.clone(),
        message,
    })
}

/// Judge what moves: each moving body's merged inertia must be physical (an error naming
/// the body, its links and its moments); a link whose own inertia is not physical but that
/// is welded to a sound body, or to the world, is a warning naming it.
pub(super) fn bodies(
    model: &mut Model,
    links: &[urdf_rs::Link],
    link_defects: &[Option<String>],
    policy: InertiaPolicy,
    file: &str,
) -> Result<()> {
    for (li, l) in links.iter().enumerate() {
        let Some(defect) = &link_defects[li] else {
            continue;
        };
        let Some(f) = model.frames.iter().find(|f| f.name == l.name) else {
            continue;
        };
        let body = f.body;
        let links = links_of(model, body);
        let merged = &model.bodies[body].inertia;
        if body != 0 && inertia_defect(merged.mass, &merged.inertia_com).is_some() {
            if policy == InertiaPolicy::Repair {
                let before = describe(&model.bodies[body].inertia);
                let b = &mut model.bodies[body].inertia;
                b.inertia_com = nearest_physical(&b.inertia_com);
                model.warnings.push(format!(
                    "{}: link '{l}' ({defect}): the moving body of joint '{}' was repaired \
                     (model.inertia: repair): {before} → {}",
                    file,
                    model.bodies[body].joint.name,
                    describe(&model.bodies[body].inertia),
                    l = l.name,
                ));
                continue;
            }
            let (amount, scale) = (
                unphysical_amount(&merged.inertia_com),
                merged_scale(model, body),
            );
            if amount <= BODY_TOL * scale {
                model.warnings.push(format!(
                    "{file}: link '{l}' ({defect}): the moving body of joint '{}' misses being \
                     physical by {amount:.3e} kg·m², {:.2} % of m·ℓ² = {scale:.3e} kg·m² \
                     (ℓ = {:.3} m, its extent), within the {:.0} % tolerance: kept as written",
                    model.bodies[body].joint.name,
                    100.0 * amount / scale,
                    extent(model, body),
                    100.0 * BODY_TOL,
                    l = l.name,
                ));
                continue;
            }
            let element = if links.len() == 1 {
                format!("link '{}'", l.name)
            } else {
                format!(
                    "link '{}' (moving body of joint '{}' with welded links {})",
                    l.name,
                    model.bodies[body].joint.name,
                    links.join(", ")
                )
            };
            return Err(Error::Urdf {
                file: file.to_string(),
                element,
                message: format!(
                    "{defect}; the merged body ({}) is not physical either, by {amount:.3e} \
                     kg·m², {:.1} % of m·ℓ² = {scale:.3e} kg·m² (tolerance {:.0} %; fix the \
                     URDF, or set model.inertia: repair in the scene for the nearest physical \
                     tensor)",
                    describe(&model.bodies[body].inertia),
                    100.0 * amount / scale,
                    100.0 * BODY_TOL,
                ),
            });
        }
        let onto = if body == 0 {
            "the world".to_string()
        } else {
            format!("body '{}'", model.bodies[body].name)
        };
        model.warnings.push(format!(
            "{}: link '{}': {defect}; ignored: it is welded to {onto}, whose merged inertia \
             is physical",
            file, l.name
        ));
    }
    Ok(())
}
