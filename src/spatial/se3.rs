//! Rigid transforms `a_m_b = (R, t)`.

use super::{Force, Motion};
use nalgebra::{Matrix3, Matrix6, Vector3};

/// Skew-symmetric matrix `[v]×` with `[v]× w = v × w`.
#[inline]
pub fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// A rigid transform `a_m_b`: `p_a = rotation · p_b + translation` [m].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SE3 {
    /// Rotation of frame b expressed in frame a.
    pub rotation: Matrix3<f64>,
    /// Origin of frame b expressed in frame a [m].
    pub translation: Vector3<f64>,
}

impl Default for SE3 {
    fn default() -> Self {
        Self::identity()
    }
}

impl SE3 {
    /// `a_m_b` from the rotation of b in a and the origin of b in a [m].
    pub fn new(rotation: Matrix3<f64>, translation: Vector3<f64>) -> Self {
        Self {
            rotation,
            translation,
        }
    }

    /// The identity transform.
    pub fn identity() -> Self {
        Self {
            rotation: Matrix3::identity(),
            translation: Vector3::zeros(),
        }
    }

    /// Composition `a_m_c = a_m_b * b_m_c`.
    #[inline]
    pub fn compose(&self, b_m_c: &SE3) -> SE3 {
        SE3 {
            rotation: self.rotation * b_m_c.rotation,
            translation: self.rotation * b_m_c.translation + self.translation,
        }
    }

    /// `b_m_a` from `a_m_b`.
    #[inline]
    pub fn inverse(&self) -> SE3 {
        let rt = self.rotation.transpose();
        SE3 {
            rotation: rt,
            translation: -(rt * self.translation),
        }
    }

    /// Point in b → point in a.
    #[inline]
    pub fn act_point(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * p + self.translation
    }

    /// Point in a → point in b.
    #[inline]
    pub fn act_inv_point(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rotation.tr_mul(&(p - self.translation))
    }

    /// Twist in b → twist in a: `ω_a = R ω`, `v_a = R v + t × R ω`.
    #[inline]
    pub fn act_motion(&self, m: &Motion) -> Motion {
        let ang = self.rotation * m.ang;
        Motion {
            lin: self.rotation * m.lin + self.translation.cross(&ang),
            ang,
        }
    }

    /// Twist in a → twist in b: `ω_b = Rᵀ ω`, `v_b = Rᵀ (v − t × ω)`.
    #[inline]
    pub fn act_inv_motion(&self, m: &Motion) -> Motion {
        Motion {
            lin: self
                .rotation
                .tr_mul(&(m.lin - self.translation.cross(&m.ang))),
            ang: self.rotation.tr_mul(&m.ang),
        }
    }

    /// Wrench in b → wrench in a: `f_a = R f`, `τ_a = R τ + t × R f`.
    #[inline]
    pub fn act_force(&self, f: &Force) -> Force {
        let lin = self.rotation * f.lin;
        Force {
            lin,
            ang: self.rotation * f.ang + self.translation.cross(&lin),
        }
    }

    /// Wrench in a → wrench in b.
    #[inline]
    pub fn act_inv_force(&self, f: &Force) -> Force {
        Force {
            lin: self.rotation.tr_mul(&f.lin),
            ang: self
                .rotation
                .tr_mul(&(f.ang - self.translation.cross(&f.lin))),
        }
    }

    /// The 6×6 matrix of `act_motion` on `[lin; ang]`: `[R, [t]×R; 0, R]`.
    pub fn motion_matrix(&self) -> Matrix6<f64> {
        let mut x = Matrix6::zeros();
        let tr = skew(&self.translation) * self.rotation;
        x.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.rotation);
        x.fixed_view_mut::<3, 3>(0, 3).copy_from(&tr);
        x.fixed_view_mut::<3, 3>(3, 3).copy_from(&self.rotation);
        x
    }

    /// Articulated (6×6, symmetric) inertia in b → in a: `X⁻ᵀ I X⁻¹` with `X` = act_inv on motions.
    /// By blocks, I = [[A, B], [Bᵀ, C]]: turned into a's axes (R A Rᵀ, R B Rᵀ, R C Rᵀ, then
    /// A', B', C'), and moved to a's origin with T = [t]× (a motion's velocity at b's origin is
    /// v − T ω): `[[A', B' − A' T], [·, C' + T (B' − A' T) + (T B')ᵀ]]`. Nine 3×3 products,
    /// against two 6×6 ones (four times the multiplications, most of them by X's zero block).
    #[inline]
    pub fn act_inertia_matrix(&self, ib: &Matrix6<f64>) -> Matrix6<f64> {
        let r = &self.rotation;
        let turned = |blk: Matrix3<f64>| r * blk * r.transpose();
        let a = turned(ib.fixed_view::<3, 3>(0, 0).into_owned());
        let b = turned(ib.fixed_view::<3, 3>(0, 3).into_owned());
        let c = turned(ib.fixed_view::<3, 3>(3, 3).into_owned());
        let t = skew(&self.translation);
        let b2 = b - a * t;
        let c2 = c + t * b2 + (t * b).transpose();
        let mut out = Matrix6::zeros();
        out.fixed_view_mut::<3, 3>(0, 0).copy_from(&a);
        out.fixed_view_mut::<3, 3>(0, 3).copy_from(&b2);
        out.fixed_view_mut::<3, 3>(3, 0).copy_from(&b2.transpose());
        out.fixed_view_mut::<3, 3>(3, 3).copy_from(&c2);
        out
    }

    /// Exponential map of a body twist `ν = [v; ω]` applied for unit time (SE(3) exp).
    pub fn exp(nu: &Motion) -> SE3 {
        let w = nu.ang;
        let theta = w.norm();
        let k = skew(&w);
        let k2 = k * k;
        let (a, b, c) = if theta < 1e-6 {
            let t2 = theta * theta;
            (1.0 - t2 / 6.0, 0.5 - t2 / 24.0, 1.0 / 6.0 - t2 / 120.0)
        } else {
            let (s, co) = theta.sin_cos();
            let t2 = theta * theta;
            (s / theta, (1.0 - co) / t2, (theta - s) / (t2 * theta))
        };
        let r = Matrix3::identity() + k * a + k2 * b;
        let v = Matrix3::identity() + k * b + k2 * c;
        SE3 {
            rotation: r,
            translation: v * nu.lin,
        }
    }

    /// Logarithm: the body twist `ν` with `exp(ν) = self`.
    pub fn log(&self) -> Motion {
        let r = &self.rotation;
        let cos = ((r.trace() - 1.0) * 0.5).clamp(-1.0, 1.0);
        let theta = cos.acos();
        let vee = Vector3::new(
            r[(2, 1)] - r[(1, 2)],
            r[(0, 2)] - r[(2, 0)],
            r[(1, 0)] - r[(0, 1)],
        );
        let w = if theta < 1e-6 {
            vee * 0.5 * (1.0 + theta * theta / 6.0)
        } else if std::f64::consts::PI - theta < 1e-6 {
            // Near π: axis from the symmetric part.
            let b = (r + Matrix3::identity()) * 0.5;
            let i = (0..3)
                .max_by(|&i, &j| b[(i, i)].total_cmp(&b[(j, j)]))
                .unwrap_or(0);
            let mut axis: Vector3<f64> = b.column(i).into();
            axis /= axis.norm().max(f64::MIN_POSITIVE);
            if axis.dot(&vee) < 0.0 {
                axis = -axis;
            }
            axis * theta
        } else {
            vee * (theta / (2.0 * theta.sin()))
        };
        let t = w.norm();
        let k = skew(&w);
        // V⁻¹ = I − ½[ω]× + (1/θ²)(1 − θ sinθ / (2(1 − cosθ)))[ω]×²
        let c = if t < 1e-6 {
            1.0 / 12.0 + t * t / 720.0
        } else {
            (1.0 - t * t.sin() / (2.0 * (1.0 - t.cos()))) / (t * t)
        };
        let vinv = Matrix3::identity() - k * 0.5 + k * k * c;
        Motion {
            lin: vinv * self.translation,
            ang: w,
        }
    }
}
