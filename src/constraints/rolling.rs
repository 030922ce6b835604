//! Rolling without slipping: a wheel (frame W, spin axis a_W, radius r, centre at W's origin) on
//! the plane n·x = h.
//!
//! Contact: u = −(n − (n·a)a)/|n − (n·a)a| (a = R_W a_W), p_c = c + r u + s a (s the axle
//! offset: an effective track, s = s₀ + k ω_n² with ω_n = n·ω the wheel's turn rate about the
//! normal: a wide tyre's track widens with the turn rate). The material point of the
//! wheel at p_c has zero velocity: `J v = v_c + ω × (p_c − c) = 0`, expressed on the basis
//! (t₁, t₂, n) — two nonholonomic tangential rows and one normal row. The normal row is left out
//! when the model cannot move the contact along n (a planar base already fixes the height).
//! φ = (0, 0, n·p_c − h). Because p_c moves over the rim,
//! γ = a_mat(p_c)|q̈=0 + ω × (ṗ_c − v_mat(p_c)) (not the material point's acceleration alone).
//! λ: contact force by the ground on the wheel at p_c [N] on (t₁, t₂, n).
//!
//! With k ≠ 0 the offset is read at the current turn rate and held over each evaluation: the
//! rows are those of a contact at that offset (force at the contact point), γ leaves out ṡ, and
//! the drift control carries the contact point along as the turn rate changes (the scene must
//! have one: docs/contacts.md). J v is then the contact's true slip, f(q, v) itself.
//!
//! With `lateral: tyre` the wheel's tyre (forces/tyre.rs) holds it sideways: the contact keeps
//! the row along its rolling direction t = a × n/|a × n| ([`ROLLING_ROW`]) and the normal one.
//! t turns with the wheel, so that row's γ adds ṫ·v_mat, v_mat sideways where the tyre creeps.

use super::{ConstraintRows, RowResiduals, RowSink};
use crate::algorithm::{Data, frame_placement, point_jacobian_rows};
use crate::model::Model;
use crate::spatial::SE3;
use nalgebra::{Matrix3, Vector3};

/// A wheel rolling without slipping on the plane n·x = h.
#[derive(Clone, Debug)]
pub struct RollingConstraint {
    /// Frame index of the wheel (origin at the wheel centre).
    pub wheel: usize,
    /// Spin axis in the wheel frame (unit).
    pub axis: Vector3<f64>,
    /// Radius [m].
    pub radius: f64,
    /// The contact point's offset along the spin axis at zero turn rate, s₀ [m] (an effective
    /// track).
    pub axle_offset: f64,
    /// k [m/(rad/s)²]: the offset grows by k ω_n² with the turn rate ω_n = n·ω (0: constant).
    pub axle_offset_turn_gain: f64,
    /// Columns t₁, t₂, n (world).
    pub basis: Matrix3<f64>,
    /// Plane height along n [m].
    pub height: f64,
    /// Which rows are kept: 0, 1, 2 for t₁, t₂, n, or [`ROLLING_ROW`] alone on the ground
    /// plane (with n or not) when the wheel's sideways grip is left to a tyre.
    pub rows: Vec<usize>,
    /// Coulomb coefficient μ (‖λ_t‖ ≤ μ λ_n), for the acceleration envelope.
    pub friction: Option<f64>,
}

/// The row along the wheel's rolling direction t = a × n/|a × n| (a contact whose lateral row
/// is left to a tyre: `lateral: tyre`).
pub const ROLLING_ROW: usize = 3;

/// Contact geometry at the current state.
pub struct Contact {
    /// World contact point [m].
    pub point: Vector3<f64>,
    /// Wheel centre [m].
    pub centre: Vector3<f64>,
    /// Spin axis (world).
    pub axis: Vector3<f64>,
}

impl RollingConstraint {
    /// Tangent basis for a unit normal: (x, y, n) when n = ±z, else a Gram–Schmidt completion.
    pub fn basis_for(n: &Vector3<f64>) -> Matrix3<f64> {
        let t1 = if n.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let t1 = (t1 - n * n.dot(&t1)).normalize();
        let t2 = n.cross(&t1);
        Matrix3::from_columns(&[t1, t2, *n])
    }

    /// Unit plane normal n, world axes.
    pub fn normal(&self) -> Vector3<f64> {
        self.basis.column(2).into()
    }

    /// Whether the contact leaves its sideways grip to a tyre (only the rolling row on the
    /// ground plane).
    pub fn lateral_free(&self) -> bool {
        self.rows.contains(&ROLLING_ROW)
    }

    /// The world direction of kept row `row` for the world spin axis `a`.
    pub fn row_direction(&self, row: usize, a: &Vector3<f64>) -> Vector3<f64> {
        if row == ROLLING_ROW {
            rolling_direction(a, &self.normal())
        } else {
            self.basis.column(row).into()
        }
    }

    /// The axle offset s [m] at the wheel's angular velocity `omega` (world axes) [rad/s].
    pub fn offset_at(&self, omega: &Vector3<f64>) -> f64 {
        let turn = self.normal().dot(omega);
        self.axle_offset + self.axle_offset_turn_gain * turn * turn
    }

    /// The wheel body's angular velocity, world axes [rad/s] (after a kinematics pass with
    /// velocities).
    pub(crate) fn omega(&self, model: &Model, data: &Data) -> Vector3<f64> {
        let body = model.frames[self.wheel].body;
        data.o_m_i[body].rotation * data.v[body].ang
    }

    /// Contact point, centre and world axis (after a kinematics pass with velocities).
    pub fn contact(&self, model: &Model, data: &Data) -> Contact {
        let offset = self.offset_at(&self.omega(model, data));
        self.contact_at(&frame_placement(model, data, self.wheel), offset)
    }

    /// Contact point, centre and world axis for the wheel frame's world placement `o_m_w` and
    /// the axle offset `offset` [m].
    fn contact_at(&self, o_m_w: &SE3, offset: f64) -> Contact {
        let a = o_m_w.rotation * self.axis;
        let n = self.normal();
        let w = n - a * n.dot(&a);
        let u = -w / w.norm().max(f64::MIN_POSITIVE);
        Contact {
            point: o_m_w.translation + u * self.radius + a * offset,
            centre: o_m_w.translation,
            axis: a,
        }
    }
}

impl ConstraintRows for RollingConstraint {
    fn dim(&self) -> usize {
        self.rows.len()
    }

    fn fill(&self, model: &Model, data: &Data, out: &mut RowSink) {
        let o_m_w = frame_placement(model, data, self.wheel);
        let offset = self.offset_at(&self.omega(model, data));
        let Contact {
            point: pc, axis: a, ..
        } = self.contact_at(&o_m_w, offset);
        let f = &model.frames[self.wheel];
        let mut dirs = [Vector3::zeros(); 3];
        for (d, &row) in dirs.iter_mut().zip(&self.rows) {
            *d = self.row_direction(row, &a);
        }
        let dirs = &dirs[..self.rows.len()];
        point_jacobian_rows(model, data, f.body, &pc, dirs, out.j, out.row0);
        // The body's twist and bias acceleration at the contact's material point, straight from
        // the body placement (no round trip through the wheel frame): v_mat = R vp,
        // a_mat = R (a_lin + α × p + ω_b × vp), vp = v_lin + ω_b × p, p = Rᵀ (p_c − t).
        let (ob, vb, ab) = (&data.o_m_i[f.body], &data.v[f.body], &data.a[f.body]);
        let rb = ob.rotation;
        let omega = rb * vb.ang;
        let v_c = rb * (vb.lin + vb.ang.cross(&f.placement.translation));
        let pb = ob.act_inv_point(&pc);
        let vp = vb.lin + vb.ang.cross(&pb);
        let v_mat = rb * vp;
        let a_mat = rb * (ab.lin + ab.ang.cross(&pb) + vb.ang.cross(&vp));
        // ṗ_c = v_c + r u̇ + s ȧ, u = −w/|w|, w = n − (n·a)a, ȧ = ω × a.
        let n = self.normal();
        let adot = omega.cross(&a);
        let w = n - a * n.dot(&a);
        let wdot = -(a * n.dot(&adot) + adot * n.dot(&a));
        let wn = w.norm().max(f64::MIN_POSITIVE);
        let udot = -(wdot / wn - w * (w.dot(&wdot) / (wn * wn * wn)));
        let pc_dot = v_c + udot * self.radius + adot * offset;
        let gamma_w = a_mat + omega.cross(&(pc_dot - v_mat));
        let phi_n = n.dot(&pc) - self.height;
        for (k, (&row, dir)) in self.rows.iter().zip(dirs).enumerate() {
            let (phi, hol) = if row == 2 {
                (phi_n, true)
            } else {
                (0.0, false)
            };
            // The rolling direction turns with the wheel: d/dt (t·v_mat) = t·g + ṫ·v_mat.
            let turning = if row == ROLLING_ROW {
                rolling_direction_rate(&a, &adot, &n).dot(&v_mat)
            } else {
                0.0
            };
            out.finish(out.row0 + k, phi, dir.dot(&gamma_w) + turning, hol);
        }
    }

    /// J v = the contact's material-point velocity on each kept direction; φ as in `fill`.
    fn residuals(&self, model: &Model, data: &Data, out: RowResiduals) -> bool {
        let Contact {
            point: pc, axis: a, ..
        } = self.contact(model, data);
        let body = model.frames[self.wheel].body;
        let (ob, vb) = (&data.o_m_i[body], &data.v[body]);
        let v_mat = ob.rotation * (vb.lin + vb.ang.cross(&ob.act_inv_point(&pc)));
        for (k, &row) in self.rows.iter().enumerate() {
            let dir = self.row_direction(row, &a);
            out.jv[k] = dir.dot(&v_mat);
            (out.phi[k], out.holonomic[k]) = if row == 2 {
                (dir.dot(&pc) - self.height, true)
            } else {
                (0.0, false)
            };
        }
        true
    }
}

/// The rolling direction t = a × n/|a × n| of a wheel with world spin axis a on a plane of
/// normal n (a is never parallel to n: the scene is refused).
pub fn rolling_direction(a: &Vector3<f64>, n: &Vector3<f64>) -> Vector3<f64> {
    let p = a.cross(n);
    p / p.norm().max(f64::MIN_POSITIVE)
}

/// ṫ for the axis' rate ȧ: the derivative of a × n/|a × n|.
pub fn rolling_direction_rate(
    a: &Vector3<f64>,
    a_dot: &Vector3<f64>,
    n: &Vector3<f64>,
) -> Vector3<f64> {
    let p = a.cross(n);
    let pn = p.norm().max(f64::MIN_POSITIVE);
    let t = p / pn;
    let pd = a_dot.cross(n);
    (pd - t * t.dot(&pd)) / pn
}

/// The variation of ṫ = [`rolling_direction_rate`]`(a, ȧ, n)` for variations `d_a` of a and
/// `d_a_dot` of ȧ.
pub fn rolling_direction_rate_variation(
    a: &Vector3<f64>,
    a_dot: &Vector3<f64>,
    d_a: &Vector3<f64>,
    d_a_dot: &Vector3<f64>,
    n: &Vector3<f64>,
) -> Vector3<f64> {
    let pn = a.cross(n).norm().max(f64::MIN_POSITIVE);
    let t = rolling_direction(a, n);
    let pd = a_dot.cross(n);
    // δt is ṫ's formula with δa for ȧ.
    let (t_dot, dt) = (
        rolling_direction_rate(a, a_dot, n),
        rolling_direction_rate(a, d_a, n),
    );
    let dpd = d_a_dot.cross(n);
    (dpd - dt * t.dot(&pd) - t * (dt.dot(&pd) + t.dot(&dpd))) / pn
        - t_dot * (t.dot(&d_a.cross(n)) / pn)
}
