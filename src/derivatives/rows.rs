//! Each constraint kind's part of the constrained derivatives:
//! - the forces λ puts on the bodies, registered as point forces before inverse dynamics
//!   ([`register_constraint_forces`]), and the corrections after it where a force's point or
//!   direction does not move with its body ([`force_corrections`]);
//! - the variations of its acceleration-level rows `J q̈ + γ + K_d J v + K_p φ` at fixed q̈
//!   ([`row_derivatives`]).
//!
//! A point of a body at world position p moves along q-column j by dp = S_lin + S_ang × p; its
//! velocity ṗ = v₀ + ω × p and classical acceleration p̈ = a₀ + α × p + ω × ṗ vary with the
//! body's twist and acceleration (rnea.rs).

use super::DerivativeData;
use super::point::PointKin;
use super::rnea::{
    body_variation_q, body_variation_v, subtract_force_variation, subtract_force_variation_v,
};
use super::rolling::RollingState;
use super::weld::WeldState;
use crate::algorithm::{Data, frame_placement, point_position};
use crate::constraints::{
    Constraint, ConstraintData, ConstraintSet, ROLLING_ROW, RollingConstraint,
};
use crate::dynamics::Baumgarte;
use crate::model::Model;
use crate::spatial::Force;
use nalgebra::Vector3;

/// Kinds with derivatives.
pub(crate) fn supported(c: &Constraint) -> bool {
    matches!(
        c,
        Constraint::Point(_)
            | Constraint::Coupling(_)
            | Constraint::Rolling(_)
            | Constraint::Distance(_)
            | Constraint::NoSideSlip(_)
            | Constraint::Weld(_)
    )
}

/// Relative kinematics d = p_A − p_B of two points and their variations.
struct Pair {
    a: PointKin,
    b: PointKin,
}

impl Pair {
    fn d(&self) -> [Vector3<f64>; 3] {
        [
            self.a.p - self.b.p,
            self.a.pd - self.b.pd,
            self.a.pdd - self.b.pdd,
        ]
    }
    fn by_q(&self, model: &Model, dd: &DerivativeData, j: usize) -> Option<[Vector3<f64>; 3]> {
        let (x, y) = (self.a.by_q(model, dd, j), self.b.by_q(model, dd, j));
        if x.is_none() && y.is_none() {
            return None;
        }
        let z = [Vector3::zeros(); 3];
        let (x, y) = (x.unwrap_or(z), y.unwrap_or(z));
        Some([x[0] - y[0], x[1] - y[1], x[2] - y[2]])
    }
    fn by_v(&self, model: &Model, dd: &DerivativeData, j: usize) -> Option<[Vector3<f64>; 2]> {
        let (x, y) = (self.a.by_v(model, dd, j), self.b.by_v(model, dd, j));
        if x.is_none() && y.is_none() {
            return None;
        }
        let z = [Vector3::zeros(); 2];
        let (x, y) = (x.unwrap_or(z), y.unwrap_or(z));
        Some([x[0] - y[0], x[1] - y[1]])
    }
}

fn pair(
    model: &Model,
    data: &Data,
    dd: &DerivativeData,
    a: (usize, &Vector3<f64>),
    b: (usize, &Vector3<f64>),
) -> Pair {
    Pair {
        a: PointKin::new(model, data, dd, a.0, a.1),
        b: PointKin::new(model, data, dd, b.0, b.1),
    }
}

/// The world force of a rolling contact's rows: Σ λ_r t_row(r).
fn rolling_force(rc: &RollingConstraint, a: &Vector3<f64>, lambda: &[f64]) -> Vector3<f64> {
    let mut f = Vector3::zeros();
    for (r, &row) in rc.rows.iter().enumerate() {
        f += rc.row_direction(row, a) * lambda[r];
    }
    f
}

/// The world direction of a no-side-slip row and its frame origin.
fn knife_edge(
    model: &Model,
    data: &Data,
    frame: usize,
    axis: &Vector3<f64>,
) -> (usize, Vector3<f64>, Vector3<f64>) {
    let m = frame_placement(model, data, frame);
    (model.frames[frame].body, m.rotation * axis, m.translation)
}

/// Registers λ's forces on the bodies as point forces (world axes, at body points).
pub(crate) fn register_constraint_forces(
    model: &Model,
    data: &Data,
    set: &ConstraintSet,
    lambda: &[f64],
    dd: &mut DerivativeData,
) {
    dd.clear_point_forces();
    for (k, c) in set.items.iter().enumerate() {
        let lam = &lambda[set.ranges[k].clone()];
        let add = |dd: &mut DerivativeData, frame: usize, point: &Vector3<f64>, f: Vector3<f64>| {
            let body = model.frames[frame].body;
            if body > 0 {
                let p = point_position(model, data, frame, point);
                dd.add_point_force(body, &p, &f);
            }
        };
        match c {
            Constraint::Point(pc) => {
                let mut f = Vector3::zeros();
                for (r, &ax) in pc.axes.iter().enumerate() {
                    f[ax] += lam[r];
                }
                add(dd, pc.frame_a, &pc.point_a, f);
                add(dd, pc.frame_b, &pc.point_b, -f);
            }
            Constraint::Distance(dc) => {
                let pa = point_position(model, data, dc.frame_a, &dc.point_a);
                let pb = point_position(model, data, dc.frame_b, &dc.point_b);
                let n = (pa - pb) / (pa - pb).norm().max(f64::MIN_POSITIVE);
                add(dd, dc.frame_a, &dc.point_a, n * lam[0]);
                add(dd, dc.frame_b, &dc.point_b, -n * lam[0]);
            }
            Constraint::NoSideSlip(nc) => {
                let (_, e, _) = knife_edge(model, data, nc.frame, &nc.axis);
                add(dd, nc.frame, &Vector3::zeros(), e * lam[0]);
            }
            Constraint::Rolling(rc) => {
                let st = RollingState::new(model, data, dd, rc);
                dd.add_point_force(st.body, &st.pc, &rolling_force(rc, &st.a, lam));
            }
            Constraint::Weld(w) => WeldState::new(model, data, dd, w).register(dd, w, lam),
            Constraint::Coupling(_) => {}
            // Refused by `supported` before any derivative is formed (velocity-expression rows
            // have no analytic derivatives).
            Constraint::Velocity(_) => {}
        }
    }
}

/// After RNEA with the registered forces: the rolling contact point sliding over the rim, the
/// distance force turning with n, the knife-edge force turning with its frame.
pub(crate) fn force_corrections(
    model: &Model,
    data: &Data,
    set: &ConstraintSet,
    lambda: &[f64],
    dd: &mut DerivativeData,
) {
    for (k, c) in set.items.iter().enumerate() {
        let lam = &lambda[set.ranges[k].clone()];
        match c {
            Constraint::Rolling(rc) => {
                // δ = dp_c − (S_lin + S_ang × p_c) = r (du − S_ang × u): f acts at δ from
                // where the material point took it.
                // With a turn gain the point also moves along a with the wheel's turn rate,
                // δs a, along q and v alike.
                let st = RollingState::new(model, data, dd, rc);
                let f = rolling_force(rc, &st.a, lam);
                for j in 0..model.nv {
                    let Some((dv, _)) = body_variation_q(model, dd, st.body, j) else {
                        continue;
                    };
                    let s = dd.o_s[j];
                    let delta = st.contact_variation(&s) - s.lin - s.ang.cross(&st.pc)
                        + st.turn_shift(&dv.ang);
                    subtract_force_variation(
                        model,
                        dd,
                        st.body,
                        j,
                        Force::new(Vector3::zeros(), delta.cross(&f)),
                    );
                }
                // A rolling row's direction turns with the wheel: δf = δt λ at p_c.
                if let Some(r) = rc.rows.iter().position(|&row| row == ROLLING_ROW) {
                    for j in 0..model.nv {
                        if body_variation_q(model, dd, st.body, j).is_none() {
                            continue;
                        }
                        let s = dd.o_s[j];
                        let df = st.rolling_direction_variation(&s.ang.cross(&st.a)) * lam[r];
                        subtract_force_variation(
                            model,
                            dd,
                            st.body,
                            j,
                            Force::new(df, st.pc.cross(&df)),
                        );
                    }
                }
                if rc.axle_offset_turn_gain != 0.0 {
                    for j in 0..model.nv {
                        let Some((dv, _)) = body_variation_v(model, dd, st.body, j) else {
                            continue;
                        };
                        let delta = st.turn_shift(&dv.ang);
                        subtract_force_variation_v(
                            model,
                            dd,
                            st.body,
                            j,
                            Force::new(Vector3::zeros(), delta.cross(&f)),
                        );
                    }
                }
            }
            Constraint::Distance(dc) => {
                let pr = pair(
                    model,
                    data,
                    dd,
                    (dc.frame_a, &dc.point_a),
                    (dc.frame_b, &dc.point_b),
                );
                let [d, _, _] = pr.d();
                let len = d.norm().max(f64::MIN_POSITIVE);
                let n = d / len;
                for j in 0..model.nv {
                    let Some([dd_q, _, _]) = pr.by_q(model, dd, j) else {
                        continue;
                    };
                    let dn = (dd_q - n * n.dot(&dd_q)) / len;
                    let df = dn * lam[0];
                    for (pt, sign) in [(&pr.a, 1.0), (&pr.b, -1.0)] {
                        if pt.body > 0 {
                            let f = df * sign;
                            subtract_force_variation(
                                model,
                                dd,
                                pt.body,
                                j,
                                Force::new(f, pt.p.cross(&f)),
                            );
                        }
                    }
                }
            }
            Constraint::NoSideSlip(nc) => {
                let (body, e, p) = knife_edge(model, data, nc.frame, &nc.axis);
                for j in 0..model.nv {
                    if body == 0 || body_variation_q(model, dd, body, j).is_none() {
                        continue;
                    }
                    let f = dd.o_s[j].ang.cross(&e) * lam[0];
                    subtract_force_variation(model, dd, body, j, Force::new(f, p.cross(&f)));
                }
            }
            Constraint::Weld(w) => {
                WeldState::new(model, data, dd, w).corrections(model, dd, w, lam);
            }
            _ => {}
        }
    }
}

/// ∂/∂q and ∂/∂v of the acceleration-level rows `J q̈ + γ + K_d J v + K_p φ` at fixed q̈ into
/// `dd.rows_dq`, `dd.rows_dv` (the world kinematics of the last RNEA pass, at q̈).
pub(crate) fn row_derivatives(
    model: &Model,
    data: &Data,
    set: &ConstraintSet,
    cd: &ConstraintData,
    dd: &mut DerivativeData,
    stab: Baumgarte,
) {
    dd.rows_dq.as_mut_slice().fill(0.0);
    dd.rows_dv.as_mut_slice().fill(0.0);
    let (kp, kd) = (stab.kp, stab.kd);
    for (k, c) in set.items.iter().enumerate() {
        let r0 = set.ranges[k].start;
        match c {
            Constraint::Point(pc) => {
                let pr = pair(
                    model,
                    data,
                    dd,
                    (pc.frame_a, &pc.point_a),
                    (pc.frame_b, &pc.point_b),
                );
                for j in 0..model.nv {
                    if let Some([dp, dpd, dpdd]) = pr.by_q(model, dd, j) {
                        let x = dpdd + dpd * kd + dp * kp;
                        for (r, &ax) in pc.axes.iter().enumerate() {
                            dd.rows_dq[(r0 + r, j)] = x[ax];
                        }
                    }
                    if let Some([dpd, dpdd]) = pr.by_v(model, dd, j) {
                        let x = dpdd + dpd * kd;
                        for (r, &ax) in pc.axes.iter().enumerate() {
                            dd.rows_dv[(r0 + r, j)] = x[ax];
                        }
                    }
                }
            }
            Constraint::Distance(dc) => {
                // L = |d|, L̇ = n·ḋ, L̈ = n·d̈ + (|ḋ|² − (n·ḋ)²)/L.
                let pr = pair(
                    model,
                    data,
                    dd,
                    (dc.frame_a, &dc.point_a),
                    (dc.frame_b, &dc.point_b),
                );
                let [d, dd1, dd2] = pr.d();
                let len = d.norm().max(f64::MIN_POSITIVE);
                let n = d / len;
                let (nd, sq) = (n.dot(&dd1), dd1.norm_squared());
                let row = |dn: Vector3<f64>, dl: f64, v1: Vector3<f64>, v2: Vector3<f64>| {
                    let dnd = dn.dot(&dd1) + n.dot(&v1);
                    let acc =
                        dn.dot(&dd2) + n.dot(&v2) + (2.0 * dd1.dot(&v1) - 2.0 * nd * dnd) / len
                            - (sq - nd * nd) * dl / (len * len);
                    (acc, dnd)
                };
                for j in 0..model.nv {
                    if let Some([v0, v1, v2]) = pr.by_q(model, dd, j) {
                        let dl = n.dot(&v0);
                        let dn = (v0 - n * dl) / len;
                        let (acc, vel) = row(dn, dl, v1, v2);
                        dd.rows_dq[(r0, j)] = acc + kd * vel + kp * dl;
                    }
                    if let Some([v1, v2]) = pr.by_v(model, dd, j) {
                        let (acc, vel) = row(Vector3::zeros(), 0.0, v1, v2);
                        dd.rows_dv[(r0, j)] = acc + kd * vel;
                    }
                }
            }
            Constraint::NoSideSlip(nc) => {
                // Row e·(a₀ + α × p) (the body-frame derivative of e·v_F), velocity e·ṗ;
                // e turns with the frame.
                let (body, e, p) = knife_edge(model, data, nc.frame, &nc.axis);
                if body == 0 {
                    continue;
                }
                let (v, a) = (dd.o_v[body], dd.o_a[body]);
                let acc_sp = a.lin + model.gravity + a.ang.cross(&p);
                let pd = v.lin + v.ang.cross(&p);
                for j in 0..model.nv {
                    let s = dd.o_s[j];
                    if let Some((dv, da)) = body_variation_q(model, dd, body, j) {
                        let de = s.ang.cross(&e);
                        let dp = s.lin + s.ang.cross(&p);
                        let d_acc = da.lin + da.ang.cross(&p) + a.ang.cross(&dp);
                        let d_pd = dv.lin + dv.ang.cross(&p) + v.ang.cross(&dp);
                        dd.rows_dq[(r0, j)] =
                            de.dot(&acc_sp) + e.dot(&d_acc) + kd * (de.dot(&pd) + e.dot(&d_pd));
                    }
                    if let Some((_, da)) = body_variation_v(model, dd, body, j) {
                        let d_acc = da.lin + da.ang.cross(&p);
                        let d_pd = s.lin + s.ang.cross(&p);
                        dd.rows_dv[(r0, j)] = e.dot(&d_acc) + kd * e.dot(&d_pd);
                    }
                }
            }
            // Refused by `supported` before any derivative is formed (velocity-expression rows
            // have no analytic derivatives).
            Constraint::Velocity(_) => {}
            // Constant rows: γ = 0 and J v, φ linear, so only K_p φ and K_d J v vary.
            Constraint::Coupling(_) => {
                for r in set.ranges[k].clone() {
                    for j in 0..model.nv {
                        dd.rows_dq[(r, j)] = kp * cd.j[(r, j)];
                        dd.rows_dv[(r, j)] = kd * cd.j[(r, j)];
                    }
                }
            }
            Constraint::Rolling(rc) => {
                let st = RollingState::new(model, data, dd, rc);
                for j in 0..model.nv {
                    let s = dd.o_s[j];
                    if let Some((dv, da)) = body_variation_q(model, dd, st.body, j) {
                        let var = st.by_q(dd, &s, &dv, &da, kd);
                        for (r, &row) in rc.rows.iter().enumerate() {
                            dd.rows_dq[(r0 + r, j)] =
                                var.on_row(&rc.row_direction(row, &st.a), row, kp);
                        }
                    }
                    if let Some((_, da)) = body_variation_v(model, dd, st.body, j) {
                        // φ_n varies with v only where a turn gain moves the contact.
                        let var = st.by_v(dd, &s, &da, kd);
                        for (r, &row) in rc.rows.iter().enumerate() {
                            dd.rows_dv[(r0 + r, j)] =
                                var.on_row(&rc.row_direction(row, &st.a), row, kp);
                        }
                    }
                }
            }
            Constraint::Weld(w) => {
                let st = WeldState::new(model, data, dd, w);
                for j in 0..model.nv {
                    let xq = st.variation(model, dd, j, true, kp, kd);
                    let xv = st.variation(model, dd, j, false, 0.0, kd);
                    for (r, &row) in w.rows.iter().enumerate() {
                        dd.rows_dq[(r0 + r, j)] = xq[row / 3][row % 3];
                        dd.rows_dv[(r0 + r, j)] = xv[row / 3][row % 3];
                    }
                }
            }
        }
    }
}
