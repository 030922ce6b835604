//! A URDF `<inertial>`: read as a body's [`Inertia`] (its origin and rotation applied), and
//! checked — a mass and entries that no merging can repair are errors, while whether the
//! rotational inertia is physical is judged later, on the merged body (`check.rs`).

use super::check;
use crate::spatial::{Inertia, rotation_from_rpy};
use nalgebra::{Matrix3, Vector3};

/// The rotational inertia of `<inertia>` about the centre of mass, in the `<origin>`'s axes.
fn inertia_tensor(t: &urdf_rs::Inertia) -> Matrix3<f64> {
    Matrix3::new(
        t.ixx, t.ixy, t.ixz, t.ixy, t.iyy, t.iyz, t.ixz, t.iyz, t.izz,
    )
}

/// The body inertia of a link's `<inertial>` (link frame).
pub(super) fn link_inertia(i: &urdf_rs::Inertial) -> Inertia {
    let ic = inertia_tensor(&i.inertia);
    let r = rotation_from_rpy(&i.origin.rpy.0);
    Inertia::new(
        i.mass.value,
        Vector3::from(i.origin.xyz.0),
        r * ic * r.transpose(),
    )
}

/// Mass ≥ 0 and finite entries (errors); whether the rotational inertia is physical is
/// returned apart, to be judged on the merged body (`check_bodies`).
pub(super) fn validate_inertial(
    i: &urdf_rs::Inertial,
) -> std::result::Result<Option<String>, String> {
    let m = i.mass.value;
    if !m.is_finite() || m < 0.0 {
        return Err(format!("<inertial>: mass {m} kg is negative or not finite"));
    }
    let ic = inertia_tensor(&i.inertia);
    if ic.iter().any(|x| !x.is_finite()) {
        return Err("<inertia>: entry not finite".into());
    }
    Ok(check::inertia_defect(m, &ic))
}
