//! Rigid-body spatial inertia in the compact form (mass, centre of mass, rotational inertia at the COM).

use super::{Force, Motion, SE3, skew};
use nalgebra::{Matrix3, Matrix6, Vector3};

/// Spatial inertia of a rigid body expressed in a frame F.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Inertia {
    /// Mass [kg].
    pub mass: f64,
    /// Centre of mass in F [m].
    pub com: Vector3<f64>,
    /// Rotational inertia about the COM, F axes [kg·m²].
    pub inertia_com: Matrix3<f64>,
}

impl Default for Inertia {
    fn default() -> Self {
        Self::zero()
    }
}

impl Inertia {
    /// Zero inertia (massless body).
    pub fn zero() -> Self {
        Self {
            mass: 0.0,
            com: Vector3::zeros(),
            inertia_com: Matrix3::zeros(),
        }
    }

    /// From mass [kg], COM in F [m] and rotational inertia about the COM [kg·m²].
    pub fn new(mass: f64, com: Vector3<f64>, inertia_com: Matrix3<f64>) -> Self {
        Self {
            mass,
            com,
            inertia_com,
        }
    }

    /// `f = I v`: momentum `h = m (v − c × ω)`, angular momentum about the origin `I_c ω + c × h`.
    #[inline]
    pub fn mul_motion(&self, v: &Motion) -> Force {
        let lin = (v.lin - self.com.cross(&v.ang)) * self.mass;
        Force {
            lin,
            ang: self.inertia_com * v.ang + self.com.cross(&lin),
        }
    }

    /// The same inertia expressed in frame a, given `a_m_f`.
    #[inline]
    pub fn transformed(&self, a_m_f: &SE3) -> Inertia {
        let r = &a_m_f.rotation;
        Inertia {
            mass: self.mass,
            com: a_m_f.act_point(&self.com),
            inertia_com: r * self.inertia_com * r.transpose(),
        }
    }

    /// Sum of two inertias expressed in the same frame (parallel-axis theorem:
    /// `I_c = Σ I_k + m_k (|d_k|² 1 − d_k d_kᵀ)`, `d_k = c_k − c`).
    #[inline]
    pub fn add(&self, o: &Inertia) -> Inertia {
        let m = self.mass + o.mass;
        if m <= 0.0 {
            return Inertia::zero();
        }
        let c = (self.com * self.mass + o.com * o.mass) / m;
        // Σ m_k (|d_k|² 1 − d_k d_kᵀ) with d₁ = (m₂/m) δ, d₂ = −(m₁/m) δ, δ = c₁ − c₂, equals
        // μ (|δ|² 1 − δ δᵀ) with μ = m₁ m₂ / m.
        let delta = self.com - o.com;
        let mu = self.mass * o.mass / m;
        let mut ic = self.inertia_com + o.inertia_com - delta * delta.transpose() * mu;
        let d2 = delta.norm_squared() * mu;
        ic[(0, 0)] += d2;
        ic[(1, 1)] += d2;
        ic[(2, 2)] += d2;
        Inertia {
            mass: m,
            com: c,
            inertia_com: ic,
        }
    }

    /// The 6×6 matrix form on `[lin; ang]`.
    pub fn matrix(&self) -> Matrix6<f64> {
        let m = self.mass;
        let c = skew(&self.com);
        let mut out = Matrix6::zeros();
        out.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(Matrix3::identity() * m));
        out.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-c * m));
        out.fixed_view_mut::<3, 3>(3, 0).copy_from(&(c * m));
        out.fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&(self.inertia_com - c * c * m));
        out
    }

    /// Kinetic energy `½ vᵀ I v = ½ (m |v − c × ω|² + ωᵀ I_c ω)` [J] (the cross terms of
    /// [`Self::mul_motion`] cancel).
    pub fn kinetic_energy(&self, v: &Motion) -> f64 {
        let u = v.lin - self.com.cross(&v.ang);
        0.5 * (self.mass * u.norm_squared() + v.ang.dot(&(self.inertia_com * v.ang)))
    }
}

/// A spatial inertia about the frame origin in its additive form: mass m, first moment
/// h = m c and rotational inertia about the origin I_O = I_c + m (|c|² 1 − c cᵀ), the latter
/// symmetric and stored as `[xx, yy, zz, xy, xz, yz]`. Inertias of bodies expressed in one frame
/// add component by component in this form, with no division or parallel-axis shift (as
/// [`Inertia::add`] needs), which is what CRBA's composite inertias do on every body.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OriginInertia {
    /// Mass [kg].
    pub mass: f64,
    /// First moment m c [kg·m].
    pub h: Vector3<f64>,
    /// Rotational inertia about the origin, `[xx, yy, zz, xy, xz, yz]` [kg·m²].
    pub i_o: [f64; 6],
}

impl OriginInertia {
    /// `inertia` (given in frame F) expressed in frame a, given `a_m_f`. Always inlined: CRBA
    /// calls it once per body, and an out-of-line call measured +1.4 % instructions on panda.
    #[inline(always)]
    pub fn transformed(inertia: &Inertia, a_m_f: &SE3) -> Self {
        let r = &a_m_f.rotation;
        let m = inertia.mass;
        let c = a_m_f.act_point(&inertia.com);
        // R I_c Rᵀ: B = R I_c, then only the six distinct entries of B Rᵀ.
        let b = r * inertia.inertia_com;
        let e = |i: usize, j: usize| {
            b[(i, 0)] * r[(j, 0)] + b[(i, 1)] * r[(j, 1)] + b[(i, 2)] * r[(j, 2)]
        };
        let h = c * m;
        let (xx, yy, zz) = (h.x * c.x, h.y * c.y, h.z * c.z);
        Self {
            mass: m,
            h,
            i_o: [
                e(0, 0) + yy + zz,
                e(1, 1) + xx + zz,
                e(2, 2) + xx + yy,
                e(0, 1) - h.x * c.y,
                e(0, 2) - h.x * c.z,
                e(1, 2) - h.y * c.z,
            ],
        }
    }

    /// The same inertia about the origin of frame b and in b's axes, given `a_m_b` (this
    /// inertia being about a's origin, in a's axes): the inverse of [`Self::transformed`]'s
    /// placement. Moving the reference point to b's origin p (a's axes) keeps m, makes the first
    /// moment h − m p and the rotational inertia
    ///   `I_p = I_O − (2 h·p − m |p|²) 1 + h pᵀ + p hᵀ − m p pᵀ`
    /// (a point mass m at c: `m (|c − p|² 1 − (c − p)(c − p)ᵀ)`, expanded); then both are
    /// turned into b's axes, `Rᵀ (h − m p)` and `Rᵀ I_p R`.
    #[inline]
    pub fn expressed_in(&self, a_m_b: &SE3) -> Self {
        let (r, p) = (&a_m_b.rotation, &a_m_b.translation);
        let m = self.mass;
        let [xx, yy, zz, xy, xz, yz] = self.i_o;
        let d = m * p.norm_squared() - 2.0 * self.h.dot(p);
        let mp = p * m;
        // Entry (i, j) of h pᵀ + p hᵀ − m p pᵀ.
        let t = |i: usize, j: usize| self.h[i] * p[j] + p[i] * self.h[j] - mp[i] * p[j];
        let (a_xy, a_xz, a_yz) = (xy + t(0, 1), xz + t(0, 2), yz + t(1, 2));
        #[rustfmt::skip]
        let i_p = Matrix3::new(
            xx + d + t(0, 0), a_xy, a_xz,
            a_xy, yy + d + t(1, 1), a_yz,
            a_xz, a_yz, zz + d + t(2, 2),
        );
        // Rᵀ I_p R: B = I_p R, then only the six distinct entries of Rᵀ B.
        let b = i_p * r;
        let e = |i: usize, j: usize| {
            r[(0, i)] * b[(0, j)] + r[(1, i)] * b[(1, j)] + r[(2, i)] * b[(2, j)]
        };
        Self {
            mass: m,
            h: r.tr_mul(&(self.h - mp)),
            i_o: [e(0, 0), e(1, 1), e(2, 2), e(0, 1), e(0, 2), e(1, 2)],
        }
    }

    /// `f = I v`: `f = m v_O − h × ω`, `n_O = I_O ω + h × v_O`.
    #[inline]
    pub fn mul_motion(&self, v: &Motion) -> Force {
        let [xx, yy, zz, xy, xz, yz] = self.i_o;
        let w = &v.ang;
        let iw = Vector3::new(
            xx * w.x + xy * w.y + xz * w.z,
            xy * w.x + yy * w.y + yz * w.z,
            xz * w.x + yz * w.y + zz * w.z,
        );
        Force {
            lin: v.lin * self.mass - self.h.cross(w),
            ang: iw + self.h.cross(&v.lin),
        }
    }
}

impl std::ops::AddAssign for OriginInertia {
    #[inline]
    fn add_assign(&mut self, o: Self) {
        self.mass += o.mass;
        self.h += o.h;
        for (a, b) in self.i_o.iter_mut().zip(o.i_o) {
            *a += b;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    fn pose(rpy: [f64; 3], t: [f64; 3]) -> SE3 {
        let r = Rotation3::from_euler_angles(rpy[0], rpy[1], rpy[2]);
        SE3::new(*r.matrix(), Vector3::from(t))
    }

    /// A body's inertia placed in frame a and then expressed in frame b is the body placed
    /// in b directly (`b_m_f = a_m_b⁻¹ a_m_f`), both frames turned and the COM 2.65 m from b's
    /// origin: |h| = 9.8 kg·m, I_O's entries up to 25 kg·m²; measured differences 0 and
    /// 3.6e-15 (a few ulps).
    #[test]
    fn expressed_in_undoes_a_placement() {
        let i_c = Matrix3::new(0.31, 0.02, -0.05, 0.02, 0.27, 0.01, -0.05, 0.01, 0.12);
        let body = Inertia::new(3.7, Vector3::new(0.11, -0.23, 0.05), i_c);
        let a_m_f = pose([0.3, -1.1, 2.0], [1.2, -0.4, 0.9]);
        let a_m_b = pose([-0.7, 0.4, -2.5], [-0.6, 1.5, 1.1]);
        let via_a = OriginInertia::transformed(&body, &a_m_f).expressed_in(&a_m_b);
        let direct = OriginInertia::transformed(&body, &a_m_b.inverse().compose(&a_m_f));
        assert_eq!(via_a.mass, direct.mass);
        assert!((via_a.h - direct.h).norm() < 2e-15, "{via_a:?} {direct:?}");
        for (x, y) in via_a.i_o.iter().zip(direct.i_o) {
            assert!((x - y).abs() < 8e-15, "{via_a:?} {direct:?}");
        }
    }
}
