//! Runge–Kutta on the configuration Lie group (Munthe-Kaas): stages are taken as
//! `q_i = q_n ⊕ Θ_i` and the tangent increments use the inverse of the right-trivialised
//! exponential derivative, `Θ̇ = dexp⁻¹_{−Θ}(v) = v + ½[Θ, v] + 1/12 [Θ, [Θ, v]] − 1/720 ad_Θ⁴ v`,
//! so that RK4 and DOPRI5 keep their order for free-flyer (SE(3)) and planar (SE(2)) joints. For
//! 1-DOF joints the correction vanishes.

use crate::model::{JointKind, Model};
use crate::spatial::Motion;
use nalgebra::Vector3;

fn motion_of(kind: &JointKind, x: &[f64]) -> Motion {
    match kind {
        JointKind::FreeFlyer => Motion::new(
            Vector3::new(x[0], x[1], x[2]),
            Vector3::new(x[3], x[4], x[5]),
        ),
        _ => Motion::new(Vector3::new(x[0], x[1], 0.0), Vector3::new(0.0, 0.0, x[2])),
    }
}

/// `out = dexp⁻¹_{−Θ}(v)` joint by joint (Θ, v, out of length nv).
pub fn dexp_inv(model: &Model, theta: &[f64], v: &[f64], out: &mut [f64]) {
    for b in model.bodies.iter().skip(1) {
        let j = &b.joint;
        let (iv, nv) = (j.idx_v, j.kind.nv());
        if nv == 1 {
            out[iv] = v[iv];
            continue;
        }
        let th = motion_of(&j.kind, &theta[iv..iv + nv]);
        let vv = motion_of(&j.kind, &v[iv..iv + nv]);
        let ad1 = th.cross_motion(&vv);
        let ad2 = th.cross_motion(&ad1);
        let ad4 = th.cross_motion(&th.cross_motion(&ad2));
        let r = vv + ad1 * 0.5 + ad2 * (1.0 / 12.0) - ad4 * (1.0 / 720.0);
        match j.kind {
            JointKind::FreeFlyer => {
                out[iv..iv + 3].copy_from_slice(r.lin.as_slice());
                out[iv + 3..iv + 6].copy_from_slice(r.ang.as_slice());
            }
            _ => {
                out[iv] = r.lin.x;
                out[iv + 1] = r.lin.y;
                out[iv + 2] = r.ang.z;
            }
        }
    }
}
