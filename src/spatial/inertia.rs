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

    /// Kinetic energy `½ vᵀ I v` [J].
    pub fn kinetic_energy(&self, v: &Motion) -> f64 {
        0.5 * v.dot(&self.mul_motion(v))
    }
}
