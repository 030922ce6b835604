//! Runge–Kutta on the configuration Lie group (Munthe-Kaas): stages are taken as
//! `q_i = q_n ⊕ Θ_i` and the tangent increments use the inverse of the right-trivialised
//! exponential derivative, `Θ̇ = dexp⁻¹_{−Θ}(v) = v + ½[Θ, v] + 1/12 [Θ, [Θ, v]] − 1/720 ad_Θ⁴ v`,
//! so that RK4 and DOPRI5 keep their order for free-flyer (SE(3)) and planar (SE(2)) joints. For
//! 1-DOF joints the correction vanishes.

use crate::model::{JointKind, Model};
use crate::spatial::Motion;
use nalgebra::{DMatrix, Vector3};

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
        if matches!(j.kind, JointKind::Planar) {
            dexp_inv_planar(&theta[iv..iv + 3], &v[iv..iv + 3], &mut out[iv..iv + 3]);
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

/// [`dexp_inv`]'s series on one planar joint, Θ = (x, y, θ) and v = (vx, vy, ω) in its body
/// axes: se(2)'s ad_Θ (vx, vy, ω) = (−θ vy + y ω, θ vx − x ω, 0), the 6-D cross products
/// without their zero terms (the same operations on the non-zero ones, in the same order).
fn dexp_inv_planar(theta: &[f64], v: &[f64], out: &mut [f64]) {
    let (x, y, w) = (theta[0], theta[1], theta[2]);
    let ad = |(ax, ay): (f64, f64), az: f64| (-w * ay + y * az, w * ax - x * az);
    let ad1 = ad((v[0], v[1]), v[2]);
    let ad2 = ad(ad1, 0.0);
    let ad4 = ad(ad(ad2, 0.0), 0.0);
    out[0] = v[0] + ad1.0 * 0.5 + ad2.0 * (1.0 / 12.0) - ad4.0 * (1.0 / 720.0);
    out[1] = v[1] + ad1.1 * 0.5 + ad2.1 * (1.0 / 12.0) - ad4.1 * (1.0 / 720.0);
    out[2] = v[2];
}

/// Writes a joint's twist back into its coordinates (free-flyer: 6, planar: vx, vy, ωz).
fn write_motion(kind: &JointKind, m: &Motion, out: &mut [f64]) {
    match kind {
        JointKind::FreeFlyer => {
            out[..3].copy_from_slice(m.lin.as_slice());
            out[3..6].copy_from_slice(m.ang.as_slice());
        }
        _ => {
            out[0] = m.lin.x;
            out[1] = m.lin.y;
            out[2] = m.ang.z;
        }
    }
}

/// Applies a per-joint linear map `op(Θ_joint, x_joint)` to the group joints and the identity
/// to 1-DOF joints (whose group is the line).
fn per_joint(
    model: &Model,
    theta: &[f64],
    x: &[f64],
    out: &mut [f64],
    op: impl Fn(&Motion, &Motion) -> Motion,
) {
    for b in model.bodies.iter().skip(1) {
        let j = &b.joint;
        let (iv, nv) = (j.idx_v, j.kind.nv());
        if nv == 1 {
            out[iv] = x[iv];
            continue;
        }
        let th = motion_of(&j.kind, &theta[iv..iv + nv]);
        let xx = motion_of(&j.kind, &x[iv..iv + nv]);
        write_motion(&j.kind, &op(&th, &xx), &mut out[iv..iv + nv]);
    }
}

/// `out = Ad(Exp(−Θ)) x`: a right perturbation x of q carried to q ⊕ Θ,
/// `(q ⊕ x) ⊕ Θ = (q ⊕ Θ) ⊕ Ad(Exp(−Θ)) x`.
pub fn transport(model: &Model, theta: &[f64], x: &[f64], out: &mut [f64]) {
    per_joint(model, theta, x, out, |th, xx| {
        crate::spatial::SE3::exp(th).act_inv_motion(xx)
    });
}

/// `out = J_r(Θ) x`, the right Jacobian of the exponential: `q ⊕ (Θ + x) = (q ⊕ Θ) ⊕ J_r(Θ) x`
/// to first order; the series `Σ (−ad_Θ)^k x / (k+1)!` to 24 terms (|Θ| per step is small; the
/// terms fall as |Θ|^k/(k+1)!).
pub fn right_jacobian(model: &Model, theta: &[f64], x: &[f64], out: &mut [f64]) {
    per_joint(model, theta, x, out, |th, xx| {
        let mut term = *xx;
        let mut sum = *xx;
        for k in 1..24 {
            term = th.cross_motion(&term) * (-1.0 / (k as f64 + 1.0));
            sum += term;
        }
        sum
    });
}

/// Derivative of [`dexp_inv`] (the integrator's truncated series) with respect to Θ along `d`:
/// `½[d, v] + 1/12 ([d, [Θ, v]] + [Θ, [d, v]]) − 1/720 Σ ad_Θ^a ad_d ad_Θ^(3−a) v`.
pub fn dexp_inv_dtheta(model: &Model, theta: &[f64], v: &[f64], d: &[f64], out: &mut [f64]) {
    for b in model.bodies.iter().skip(1) {
        let j = &b.joint;
        let (iv, nv) = (j.idx_v, j.kind.nv());
        if nv == 1 {
            out[iv] = 0.0;
            continue;
        }
        let th = motion_of(&j.kind, &theta[iv..iv + nv]);
        let vv = motion_of(&j.kind, &v[iv..iv + nv]);
        let dd = motion_of(&j.kind, &d[iv..iv + nv]);
        let ad = |a: &Motion, x: &Motion| a.cross_motion(x);
        let tv = ad(&th, &vv);
        let mut r = ad(&dd, &vv) * 0.5 + (ad(&dd, &tv) + ad(&th, &ad(&dd, &vv))) * (1.0 / 12.0);
        // Σ over the position of ad_d in ad_Θ⁴.
        let mut fourth = Motion::zero();
        for pos in 0..4 {
            let mut x = vv;
            for k in (0..4).rev() {
                x = if k == pos { ad(&dd, &x) } else { ad(&th, &x) };
            }
            fourth += x;
        }
        r -= fourth * (1.0 / 720.0);
        write_motion(&j.kind, &r, &mut out[iv..iv + nv]);
    }
}

/// The linear maps of one Runge–Kutta stage at (Θ, V) as dense nv × nv matrices, block
/// diagonal (a group joint's block; identity, or zero for the derivative, on 1-DOF joints): a
/// linearization applies them to all its seed columns at once by matrix products, instead of
/// joint by joint per column (where the exponentials' sin/cos were recomputed 2nv times).
#[derive(Clone, Debug)]
pub struct StageMaps {
    /// x ↦ Ad(Exp(−Θ)) x ([`transport`]).
    pub transport: DMatrix<f64>,
    /// x ↦ J_r(Θ) x ([`right_jacobian`]).
    pub right_jacobian: DMatrix<f64>,
    /// d ↦ ∂dexp⁻¹_{−Θ}(V)/∂Θ [d] ([`dexp_inv_dtheta`]).
    pub dexp_inv_dtheta: DMatrix<f64>,
    /// x ↦ dexp⁻¹_{−Θ}(x) ([`dexp_inv`]).
    pub dexp_inv: DMatrix<f64>,
    unit: Vec<f64>,
    out: Vec<f64>,
}

impl StageMaps {
    /// Sized for nv velocity coordinates.
    pub fn new(nv: usize) -> Self {
        Self {
            transport: DMatrix::zeros(nv, nv),
            right_jacobian: DMatrix::zeros(nv, nv),
            dexp_inv_dtheta: DMatrix::zeros(nv, nv),
            dexp_inv: DMatrix::zeros(nv, nv),
            unit: vec![0.0; nv],
            out: vec![0.0; nv],
        }
    }

    /// The maps at Θ, and with `vel` = Some(V) also the two dexp⁻¹ maps (the end of a step
    /// needs only the first two).
    pub fn build(&mut self, model: &Model, theta: &[f64], vel: Option<&[f64]>) {
        self.transport.as_mut_slice().fill(0.0);
        self.right_jacobian.as_mut_slice().fill(0.0);
        if vel.is_some() {
            self.dexp_inv_dtheta.as_mut_slice().fill(0.0);
            self.dexp_inv.as_mut_slice().fill(0.0);
        }
        for b in model.bodies.iter().skip(1) {
            let j = &b.joint;
            let (iv, nv) = (j.idx_v, j.kind.nv());
            if nv == 1 {
                self.transport[(iv, iv)] = 1.0;
                self.right_jacobian[(iv, iv)] = 1.0;
                self.dexp_inv[(iv, iv)] = 1.0;
                continue;
            }
            for k in iv..iv + nv {
                // Column k of a per-joint map: the map of the unit vector, which is zero on
                // every other joint.
                self.unit[k] = 1.0;
                let maps: [(&mut DMatrix<f64>, bool); 4] = [
                    (&mut self.transport, true),
                    (&mut self.right_jacobian, true),
                    (&mut self.dexp_inv_dtheta, vel.is_some()),
                    (&mut self.dexp_inv, vel.is_some()),
                ];
                for (which, (m, wanted)) in maps.into_iter().enumerate() {
                    if !wanted {
                        continue;
                    }
                    match which {
                        0 => transport(model, theta, &self.unit, &mut self.out),
                        1 => right_jacobian(model, theta, &self.unit, &mut self.out),
                        2 => dexp_inv_dtheta(
                            model,
                            theta,
                            vel.unwrap_or(&[]),
                            &self.unit,
                            &mut self.out,
                        ),
                        _ => dexp_inv(model, theta, &self.unit, &mut self.out),
                    }
                    for r in iv..iv + nv {
                        m[(r, k)] = self.out[r];
                    }
                }
                self.unit[k] = 0.0;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The planar joint's series equals the 6-D one bit for bit, at rotations and velocities
    /// of a step (|θ| up to 0.3 rad) and beyond.
    #[test]
    fn the_planar_series_is_the_6d_one() {
        for (theta, v) in [
            ([0.01, -0.002, 0.05], [0.4, 0.0, -1.5]),
            ([-0.2, 0.15, -0.3], [-0.8, 0.3, 3.0]),
            ([1.0, 2.0, 2.5], [5.0, -4.0, 7.0]),
        ] {
            let th = motion_of(&JointKind::Planar, &theta);
            let vv = motion_of(&JointKind::Planar, &v);
            let ad1 = th.cross_motion(&vv);
            let ad2 = th.cross_motion(&ad1);
            let ad4 = th.cross_motion(&th.cross_motion(&ad2));
            let r = vv + ad1 * 0.5 + ad2 * (1.0 / 12.0) - ad4 * (1.0 / 720.0);
            let mut out = [0.0; 3];
            dexp_inv_planar(&theta, &v, &mut out);
            let general = [r.lin.x, r.lin.y, r.ang.z];
            assert_eq!(
                out.map(f64::to_bits),
                general.map(f64::to_bits),
                "{theta:?} {v:?}"
            );
        }
    }
}
