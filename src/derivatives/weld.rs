//! A weld's part of the constrained derivatives (constraints/weld.rs): translation rows as a
//! point constraint between A's origin and B's material point at t*, rotation rows
//! φ = log(R), R = R_A (R_B R*)ᵀ, velocity ω_A − ω_B, acceleration α_A − α_B (world axes);
//! with `axes: local` every block is R_Bᵀ (c − ω_B × ċ_vel …):
//! `row_B = R_Bᵀ (c_W − ω_B × vel_W + K_d vel_W + K_p φ_W)`, which varies as
//! `R_Bᵀ (δy − δ_B × y)` when B turns by δ_B.
//!
//! A world rotation δ_A of A and δ_B of B move φ by `J_l⁻¹(φ) (δ_A − R δ_B)` (J_l the left
//! Jacobian of SO(3)).

use super::DerivativeData;
use super::point::PointKin;
use super::rnea::{body_variation_q, body_variation_v};
use crate::algorithm::{Data, frame_placement};
use crate::constraints::WeldConstraint;
use crate::model::Model;
use crate::spatial::{Force, SE3, skew};
use nalgebra::{Matrix3, Vector3};

/// J_l⁻¹(φ) = 1 − ½[φ]× + (1/θ² − (1 + cos θ)/(2 θ sin θ)) [φ]×².
fn left_jacobian_inv(phi: &Vector3<f64>) -> Matrix3<f64> {
    let th = phi.norm();
    let k = skew(phi);
    let c = if th < 1e-4 {
        1.0 / 12.0 + th * th / 720.0
    } else {
        1.0 / (th * th) - (1.0 + th.cos()) / (2.0 * th * th.sin())
    };
    Matrix3::identity() - k * 0.5 + k * k * c
}

/// The weld's state: both frames' bodies, rotations, points and rates (world).
pub(crate) struct WeldState {
    body_a: usize,
    body_b: usize,
    r_b: Matrix3<f64>,
    r: Matrix3<f64>,
    jl_inv: Matrix3<f64>,
    /// Per block (translation, rotation): φ, velocity, acceleration (world).
    phi: [Vector3<f64>; 2],
    vel: [Vector3<f64>; 2],
    acc: [Vector3<f64>; 2],
    /// A's origin and B's material point at t*.
    a: PointKin,
    b: PointKin,
    local: bool,
}

impl WeldState {
    pub fn new(model: &Model, data: &Data, dd: &DerivativeData, w: &WeldConstraint) -> Self {
        let (body_a, body_b) = (model.frames[w.frame_a].body, model.frames[w.frame_b].body);
        let o_a = frame_placement(model, data, w.frame_a);
        let o_b = frame_placement(model, data, w.frame_b);
        let r = o_a.rotation * (o_b.rotation * w.target.rotation).transpose();
        let phi_r = SE3::new(r, Vector3::zeros()).log().ang;
        let a = PointKin::new(model, data, dd, w.frame_a, &Vector3::zeros());
        let b = PointKin::new(model, data, dd, w.frame_b, &w.target.translation);
        // The world (body 0) has no twist or acceleration; its o_a carries only the gravity
        // offset, which is linear, so α_B = 0 there as well.
        let (wa, aa) = (dd.o_v[body_a].ang, dd.o_a[body_a].ang);
        let (wb, ab) = (dd.o_v[body_b].ang, dd.o_a[body_b].ang);
        Self {
            body_a,
            body_b,
            r_b: o_b.rotation,
            r,
            jl_inv: left_jacobian_inv(&phi_r),
            phi: [a.p - b.p, phi_r],
            vel: [a.pd - b.pd, wa - wb],
            acc: [a.pdd - b.pdd, aa - ab],
            a,
            b,
            local: w.local,
        }
    }

    fn moving(&self, model: &Model, dd: &DerivativeData, body: usize, j: usize) -> bool {
        body > 0 && body_variation_q(model, dd, body, j).is_some()
    }

    /// Row values' variation (both blocks, in the rows' axes) along q-column j (`by_q`) or
    /// velocity j, with the gains.
    pub fn variation(
        &self,
        model: &Model,
        dd: &DerivativeData,
        j: usize,
        by_q: bool,
        kp: f64,
        kd: f64,
    ) -> [Vector3<f64>; 2] {
        let z = Vector3::zeros();
        // Per side: (rotation δ, δp, δṗ, δp̈) of the point and (δω, δα) of its body, zero when
        // the body does not move.
        let var = |pt: &PointKin| {
            let zero = (z, z, z, z, z, z);
            if by_q {
                let Some([dp, dpd, dpdd]) = pt.by_q(model, dd, j) else {
                    return zero;
                };
                let (dv, da) = body_variation_q(model, dd, pt.body, j).expect("moving body");
                (dd.o_s[j].ang, dp, dpd, dpdd, dv.ang, da.ang)
            } else {
                let Some([dpd, dpdd]) = pt.by_v(model, dd, j) else {
                    return zero;
                };
                let (dv, da) = body_variation_v(model, dd, pt.body, j).expect("moving body");
                (z, z, dpd, dpdd, dv.ang, da.ang)
            }
        };
        let (ra, pa1, pa2, pa3, wa, aa) = var(&self.a);
        let (rb, pb1, pb2, pb3, wb, ab) = var(&self.b);
        let d_phi = [pa1 - pb1, self.jl_inv * (ra - self.r * rb)];
        let d_vel = [pa2 - pb2, wa - wb];
        let d_acc = [pa3 - pb3, aa - ab];
        let mut out = [z; 2];
        for blk in 0..2 {
            if self.local {
                let w_b = dd.o_v[self.body_b].ang;
                let y = self.acc[blk] - w_b.cross(&self.vel[blk])
                    + self.vel[blk] * kd
                    + self.phi[blk] * kp;
                let dy = d_acc[blk] - wb.cross(&self.vel[blk]) - w_b.cross(&d_vel[blk])
                    + d_vel[blk] * kd
                    + d_phi[blk] * kp;
                out[blk] = self.r_b.transpose() * (dy - rb.cross(&y));
            } else {
                out[blk] = d_acc[blk] + d_vel[blk] * kd + d_phi[blk] * kp;
            }
        }
        out
    }

    /// The wrench of the rows' λ in world axes: (force at A's origin, moment), on A (its
    /// opposite on B at t*).
    pub fn wrench(&self, w: &WeldConstraint, lambda: &[f64]) -> (Vector3<f64>, Vector3<f64>) {
        let (mut f, mut m) = (Vector3::zeros(), Vector3::zeros());
        for (k, &row) in w.rows.iter().enumerate() {
            if row < 3 {
                f[row] += lambda[k];
            } else {
                m[row - 3] += lambda[k];
            }
        }
        if self.local {
            (self.r_b * f, self.r_b * m)
        } else {
            (f, m)
        }
    }

    /// Registers the wrench on both bodies.
    pub fn register(&self, dd: &mut DerivativeData, w: &WeldConstraint, lambda: &[f64]) {
        let (f, m) = self.wrench(w, lambda);
        if self.body_a > 0 {
            dd.add_point_force(self.body_a, &self.a.p, &f);
            dd.add_moment(self.body_a, &m);
        }
        if self.body_b > 0 {
            dd.add_point_force(self.body_b, &self.b.p, &-f);
            dd.add_moment(self.body_b, &-m);
        }
    }

    /// With local axes the wrench turns with B: for the columns that turn B, the variation
    /// (δ_B × f, δ_B × m) on A and its opposite on B, as generalized forces above each body.
    pub fn corrections(
        &self,
        model: &Model,
        dd: &mut DerivativeData,
        w: &WeldConstraint,
        lambda: &[f64],
    ) {
        if !self.local {
            return;
        }
        let (f, m) = self.wrench(w, lambda);
        for j in 0..model.nv {
            if !self.moving(model, dd, self.body_b, j) {
                continue;
            }
            let rb = dd.o_s[j].ang;
            let (df, dm) = (rb.cross(&f), rb.cross(&m));
            for (body, p, sign) in [(self.body_a, self.a.p, 1.0), (self.body_b, self.b.p, -1.0)] {
                if body > 0 {
                    let (ff, mm) = (df * sign, dm * sign);
                    super::rnea::subtract_force_variation(
                        model,
                        dd,
                        body,
                        j,
                        Force::new(ff, p.cross(&ff) + mm),
                    );
                }
            }
        }
    }
}
