//! A material point of a body and its variations along a q-column or a velocity: the piece
//! every point-based constraint row (point, distance, weld translation) is made of.
//!
//! At world position p: dp = S_lin + S_ang × p along q-column j; ṗ = v₀ + ω × p and
//! p̈ = a₀ + α × p + ω × ṗ vary with the body's twist and acceleration (rnea.rs).

use super::DerivativeData;
use super::rnea::{body_variation_q, body_variation_v};
use crate::algorithm::{Data, point_position};
use crate::model::Model;
use nalgebra::Vector3;

/// A material point of a body: position, velocity, classical acceleration (world, at q̈).
pub(crate) struct PointKin {
    pub body: usize,
    pub p: Vector3<f64>,
    pub pd: Vector3<f64>,
    pub pdd: Vector3<f64>,
}

impl PointKin {
    pub fn new(
        model: &Model,
        data: &Data,
        dd: &DerivativeData,
        frame: usize,
        point: &Vector3<f64>,
    ) -> Self {
        let body = model.frames[frame].body;
        let p = point_position(model, data, frame, point);
        let (v, a) = (dd.o_v[body], dd.o_a[body]);
        let pd = v.lin + v.ang.cross(&p);
        // o_a carries the gravity offset on its linear part; α (angular) does not.
        let a0 = a.lin + model.gravity;
        let pdd = a0 + a.ang.cross(&p) + v.ang.cross(&pd);
        PointKin { body, p, pd, pdd }
    }

    /// (dp, dṗ, dp̈) along q-column j, None when the point does not move.
    pub fn by_q(&self, model: &Model, dd: &DerivativeData, j: usize) -> Option<[Vector3<f64>; 3]> {
        if self.body == 0 {
            return None;
        }
        let (dv, da) = body_variation_q(model, dd, self.body, j)?;
        let s = dd.o_s[j];
        let (w, alpha) = (dd.o_v[self.body].ang, dd.o_a[self.body].ang);
        let dp = s.lin + s.ang.cross(&self.p);
        let dpd = dv.lin + dv.ang.cross(&self.p) + w.cross(&dp);
        let dpdd = da.lin
            + da.ang.cross(&self.p)
            + alpha.cross(&dp)
            + dv.ang.cross(&self.pd)
            + w.cross(&dpd);
        Some([dp, dpd, dpdd])
    }

    /// (dṗ, dp̈) along v_j, None when the point does not move.
    pub fn by_v(&self, model: &Model, dd: &DerivativeData, j: usize) -> Option<[Vector3<f64>; 2]> {
        if self.body == 0 {
            return None;
        }
        let (_, da) = body_variation_v(model, dd, self.body, j)?;
        let s = dd.o_s[j];
        let w = dd.o_v[self.body].ang;
        let dpd = s.lin + s.ang.cross(&self.p);
        let dpdd = da.lin + da.ang.cross(&self.p) + s.ang.cross(&self.pd) + w.cross(&dpd);
        Some([dpd, dpdd])
    }
}
