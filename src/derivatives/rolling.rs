//! Variations of a rolling contact's rows (constraints/rolling.rs) along a q-column and along a
//! velocity coordinate, and of its contact point.
//!
//! World axes; wheel body twist (v₀, ω) and spatial acceleration (a₀, α); centre c, spin axis
//! a, plane normal n, w = n − (n·a) a, ŵ = w/|w|, u = −ŵ, contact p_c = c + r u + s a (s the
//! axle offset). The rows are
//! t·(g + K_d v_mat) (+ K_p n·p_c on the normal row) with g = J q̈ + γ = a₀ + α × p_c + ω × ṗ_c,
//! v_mat = v₀ + ω × p_c and ṗ_c = v₀ + ω × c + r u̇ + s ȧ, u̇ = −(ẇ − ŵ(ŵ·ẇ))/|w|,
//! ẇ = −(ȧ (n·a) + a (n·ȧ)), ȧ = ω × a. A perturbation moves the body (its twist and
//! acceleration as in rnea.rs) and with it c and a; the contact point slides over the rim.
//! With a turn gain (s = s₀ + k ω_n², ω_n = n·ω) a perturbation of ω moves the contact point
//! along a by δs = 2 k ω_n n·δω too, in the rows and as the force's point of application.
//! A rolling row (`lateral: tyre`) lies along t = a × n/|a × n|, which turns with the wheel:
//! its row is t·(g + K_d v_mat) + ṫ·v_mat, and a perturbation of the axis turns t (and the
//! row's force) by δt, of its rate ṫ by δṫ.

use super::DerivativeData;
use crate::algorithm::{Data, frame_placement};
use crate::constraints::{
    ROLLING_ROW, RollingConstraint, rolling_direction, rolling_direction_rate,
    rolling_direction_rate_variation,
};
use crate::model::Model;
use crate::spatial::Motion;
use nalgebra::Vector3;

/// The contact geometry and its rates at the current state.
pub(crate) struct RollingState {
    /// Wheel body.
    pub body: usize,
    c: Vector3<f64>,
    /// Spin axis (world).
    pub a: Vector3<f64>,
    n: Vector3<f64>,
    w_hat: Vector3<f64>,
    w_norm: f64,
    /// Contact point p_c (world) [m].
    pub pc: Vector3<f64>,
    a_dot: Vector3<f64>,
    w_dot: Vector3<f64>,
    pc_dot: Vector3<f64>,
    radius: f64,
    offset: f64,
    /// ds/dω_n = 2 k ω_n [m/(rad/s)].
    offset_slope: f64,
    /// Whether the contact keeps a rolling row (its sideways grip a tyre's).
    rolling_row: bool,
}

/// Variations of one column: the 3-vector `g + K_d v_mat`, n·p_c, and the rolling row's.
pub(crate) struct RowVariation {
    pub g_plus_kd_v: Vector3<f64>,
    pub phi_n: f64,
    /// The rolling row's variation, t·(g + K_d v_mat) + ṫ·v_mat with t turning with the wheel
    /// (0 without a rolling row).
    pub rolling: f64,
}

impl RowVariation {
    /// The variation of the row along `dir` (`row` 2 is the normal one, with K_p φ;
    /// [`ROLLING_ROW`] the rolling one, whose direction varies too).
    pub fn on_row(&self, dir: &Vector3<f64>, row: usize, kp: f64) -> f64 {
        match row {
            ROLLING_ROW => self.rolling,
            2 => dir.dot(&self.g_plus_kd_v) + kp * self.phi_n,
            _ => dir.dot(&self.g_plus_kd_v),
        }
    }
}

impl RollingState {
    pub fn new(model: &Model, data: &Data, dd: &DerivativeData, rc: &RollingConstraint) -> Self {
        let body = model.frames[rc.wheel].body;
        let m = frame_placement(model, data, rc.wheel);
        let (c, a, n) = (m.translation, m.rotation * rc.axis, rc.normal());
        let w = n - a * n.dot(&a);
        let w_norm = w.norm().max(f64::MIN_POSITIVE);
        let w_hat = w / w_norm;
        let u = -w_hat;
        let vk = dd.o_v[body];
        // The turn rate from the forward dynamics' kinematics: the forces are registered before
        // the derivative pass fills `dd.o_v`.
        let omega = rc.omega(model, data);
        let offset = rc.offset_at(&omega);
        let offset_slope = 2.0 * rc.axle_offset_turn_gain * n.dot(&omega);
        let pc = c + u * rc.radius + a * offset;
        let a_dot = vk.ang.cross(&a);
        let w_dot = -(a_dot * n.dot(&a) + a * n.dot(&a_dot));
        let u_dot = -(w_dot - w_hat * w_hat.dot(&w_dot)) / w_norm;
        let pc_dot = vk.lin + vk.ang.cross(&c) + u_dot * rc.radius + a_dot * offset;
        Self {
            body,
            c,
            a,
            n,
            w_hat,
            w_norm,
            pc,
            a_dot,
            w_dot,
            pc_dot,
            radius: rc.radius,
            offset,
            offset_slope,
            rolling_row: rc.lateral_free(),
        }
    }

    /// The rolling direction's variation δt for a variation `d_a` of the axis.
    pub fn rolling_direction_variation(&self, d_a: &Vector3<f64>) -> Vector3<f64> {
        rolling_direction_rate(&self.a, d_a, &self.n)
    }

    /// The rolling row's variation: δ[t·(g + K_d v_mat) + ṫ·v_mat] for variations d_a, dȧ of
    /// the axis and its rate and dg, dv_mat of g and v_mat.
    fn rolling_variation(
        &self,
        dd: &DerivativeData,
        (d_a, d_a_dot): (&Vector3<f64>, &Vector3<f64>),
        (dg, dvmat): (&Vector3<f64>, &Vector3<f64>),
        kd: f64,
    ) -> f64 {
        if !self.rolling_row {
            return 0.0;
        }
        let (vk, ak) = (&dd.o_v[self.body], &dd.o_a[self.body]);
        let v_mat = vk.lin + vk.ang.cross(&self.pc);
        let g = ak.lin + ak.ang.cross(&self.pc) + vk.ang.cross(&self.pc_dot);
        let t = rolling_direction(&self.a, &self.n);
        let t_dot = rolling_direction_rate(&self.a, &self.a_dot, &self.n);
        let dt = self.rolling_direction_variation(d_a);
        let dt_dot = rolling_direction_rate_variation(&self.a, &self.a_dot, d_a, d_a_dot, &self.n);
        dt.dot(&(g + v_mat * kd))
            + t.dot(&(dg + dvmat * kd))
            + dt_dot.dot(&v_mat)
            + t_dot.dot(dvmat)
    }

    /// d(u̇) for variations dw of w and dẇ of ẇ.
    fn u_dot_variation(&self, dw: &Vector3<f64>, dw_dot: &Vector3<f64>) -> Vector3<f64> {
        let (wh, wn, wd) = (&self.w_hat, self.w_norm, &self.w_dot);
        let dwh = (dw - wh * wh.dot(dw)) / wn;
        let p_wd = wd - wh * wh.dot(wd);
        let d_p_wd = dw_dot - dwh * wh.dot(wd) - wh * (dwh.dot(wd) + wh.dot(dw_dot));
        -(d_p_wd / wn - p_wd * (wh.dot(dw) / (wn * wn)))
    }

    /// dw for a variation d_a of the axis.
    fn w_variation(&self, d_a: &Vector3<f64>) -> Vector3<f64> {
        -(d_a * self.n.dot(&self.a) + self.a * self.n.dot(d_a))
    }

    /// dẇ for variations d_a of a and dȧ of ȧ.
    fn w_dot_variation(&self, d_a: &Vector3<f64>, d_a_dot: &Vector3<f64>) -> Vector3<f64> {
        let (n, a, ad) = (&self.n, &self.a, &self.a_dot);
        -(d_a_dot * n.dot(a) + ad * n.dot(d_a) + d_a * n.dot(ad) + a * n.dot(d_a_dot))
    }

    /// The offset's variation δs [m] for a variation `d_omega` of the wheel's world angular
    /// velocity (zero without a turn gain).
    fn offset_variation(&self, d_omega: &Vector3<f64>) -> f64 {
        self.offset_slope * self.n.dot(d_omega)
    }

    /// The contact point's shift δs a along the axle for that variation.
    pub fn turn_shift(&self, d_omega: &Vector3<f64>) -> Vector3<f64> {
        self.a * self.offset_variation(d_omega)
    }

    /// Variation of the contact point for the body motion S (q-column): dc + r du + s da.
    pub fn contact_variation(&self, s: &Motion) -> Vector3<f64> {
        let d_a = s.ang.cross(&self.a);
        let dw = self.w_variation(&d_a);
        let du = -(dw - self.w_hat * self.w_hat.dot(&dw)) / self.w_norm;
        s.lin + s.ang.cross(&self.c) + du * self.radius + d_a * self.offset
    }

    /// Along q-column S with body variations (dv, da) and K_d.
    pub fn by_q(
        &self,
        dd: &DerivativeData,
        s: &Motion,
        dv: &Motion,
        da: &Motion,
        kd: f64,
    ) -> RowVariation {
        let w = dd.o_v[self.body].ang;
        let alpha = dd.o_a[self.body].ang;
        let d_a = s.ang.cross(&self.a);
        let dc = s.lin + s.ang.cross(&self.c);
        let dw = self.w_variation(&d_a);
        let ds = self.offset_variation(&dv.ang);
        let dpc = self.contact_variation(s) + self.a * ds;
        let d_a_dot = dv.ang.cross(&self.a) + w.cross(&d_a);
        let d_u_dot = self.u_dot_variation(&dw, &self.w_dot_variation(&d_a, &d_a_dot));
        let dpc_dot = dv.lin
            + dv.ang.cross(&self.c)
            + w.cross(&dc)
            + d_u_dot * self.radius
            + d_a_dot * self.offset
            + self.a_dot * ds;
        let dg = da.lin
            + da.ang.cross(&self.pc)
            + alpha.cross(&dpc)
            + dv.ang.cross(&self.pc_dot)
            + w.cross(&dpc_dot);
        let dvmat = dv.lin + dv.ang.cross(&self.pc) + w.cross(&dpc);
        RowVariation {
            g_plus_kd_v: dg + dvmat * kd,
            phi_n: self.n.dot(&dpc),
            rolling: self.rolling_variation(dd, (&d_a, &d_a_dot), (&dg, &dvmat), kd),
        }
    }

    /// Along velocity coordinate S with acceleration variation da and K_d.
    pub fn by_v(&self, dd: &DerivativeData, s: &Motion, da: &Motion, kd: f64) -> RowVariation {
        let w = dd.o_v[self.body].ang;
        let d_a_dot = s.ang.cross(&self.a);
        let dw_dot = self.w_dot_variation(&Vector3::zeros(), &d_a_dot);
        let d_u_dot = self.u_dot_variation(&Vector3::zeros(), &dw_dot);
        let ds = self.offset_variation(&s.ang);
        let dpc = self.a * ds;
        let dpc_dot = s.lin
            + s.ang.cross(&self.c)
            + d_u_dot * self.radius
            + d_a_dot * self.offset
            + self.a_dot * ds;
        let alpha = dd.o_a[self.body].ang;
        let dg = da.lin
            + da.ang.cross(&self.pc)
            + alpha.cross(&dpc)
            + s.ang.cross(&self.pc_dot)
            + w.cross(&dpc_dot);
        let dvmat = s.lin + s.ang.cross(&self.pc) + w.cross(&dpc);
        RowVariation {
            g_plus_kd_v: dg + dvmat * kd,
            phi_n: self.n.dot(&dpc),
            rolling: self.rolling_variation(dd, (&Vector3::zeros(), &d_a_dot), (&dg, &dvmat), kd),
        }
    }
}
