//! The matrix of the linearly implicit steps (ROS2, SDIRK2's Newton), `W = I − g F`, for the
//! state Jacobian's shape `F = [[0, I], [A, B]]` (A = ∂q̈/∂δq, B = ∂q̈/∂v, nv × nv each:
//! integrators/mod.rs, `state_jacobian`), factored through its Schur complement
//!
//! `S = I − g B − g² A`:  `W [x; y] = [a; b]`  ⇔  `S y = b + g A a`,  `x = a + g y`,
//!
//! so det W = det S, and a factor and a solve cost an nv × nv LU and its solve plus one product
//! with A, not a 2nv × 2nv LU: an eighth of the factor's operations.
//!
//! A step factors and solves with W once or twice, on a handful of coordinates: up to
//! `linalg::FIXED_MAX` coordinates the kernels are built for each size (linalg/sized.rs).

use crate::algorithm::DENSE_EAGER_NV;
use crate::linalg::{by_size, lu_in_place, lu_solve};
use nalgebra::DMatrix;

/// The factored `W = I − g F` (module doc). Sized once per model: at build up to
/// `DENSE_EAGER_NV` coordinates, by its first factor above (an explicit prediction of a large
/// tree never holds its 2 nv² entries).
#[derive(Clone, Debug, Default)]
pub(in crate::predict) struct ShiftedFactor {
    g: f64,
    /// A (nv × nv), as F held it when factored.
    a: DMatrix<f64>,
    /// The LU of S, and its pivots.
    s: DMatrix<f64>,
    piv: Vec<usize>,
}

impl ShiftedFactor {
    pub(in crate::predict) fn new(nv: usize) -> Self {
        let mut w = Self {
            g: f64::NAN,
            ..Self::default()
        };
        if nv <= DENSE_EAGER_NV {
            w.size(nv);
        }
        w
    }

    /// A and S sized for nv coordinates, when they are not.
    fn size(&mut self, nv: usize) {
        if self.piv.len() != nv {
            self.a = DMatrix::zeros(nv, nv);
            self.s = DMatrix::zeros(nv, nv);
            self.piv = vec![0; nv];
        }
    }

    /// Factor `I − g F` from F (2nv × 2nv, of the shape in the module doc; its upper blocks are
    /// not read). False when W is singular (a zero or non-finite pivot of S).
    pub(in crate::predict) fn factor(&mut self, f: &DMatrix<f64>, g: f64) -> bool {
        let nv = f.nrows() / 2;
        self.size(nv);
        self.g = g;
        let (f, a, s) = (f.as_slice(), self.a.as_mut_slice(), self.s.as_mut_slice());
        let piv = &mut self.piv[..];
        by_size!(nv, factor_fixed(f, g, a, s, piv), {
            form_s(f, g, nv, a, s);
            lu_in_place(&mut self.s, &mut self.piv)
        })
    }

    /// Solve `W x = rhs` in place (2nv).
    pub(in crate::predict) fn solve(&self, x: &mut [f64]) {
        let nv = self.piv.len();
        let (a, s) = (self.a.as_slice(), self.s.as_slice());
        by_size!(nv, solve_fixed(a, s, &self.piv, self.g, x), {
            let (top, bottom) = x.split_at_mut(nv);
            add_g_a_top(a, self.g, top, bottom);
            lu_solve(&self.s, &self.piv, bottom);
            for (t, &y) in top.iter_mut().zip(bottom.iter()) {
                *t += self.g * y;
            }
        })
    }
}

/// bottom += g A top (A column-major, nv × nv).
#[inline(always)]
fn add_g_a_top(a: &[f64], g: f64, top: &[f64], bottom: &mut [f64]) {
    let nv = top.len();
    for (&ac, col) in top.iter().zip(a.chunks_exact(nv)) {
        let gac = g * ac;
        if gac != 0.0 {
            for (b, &arc) in bottom.iter_mut().zip(col) {
                *b += arc * gac;
            }
        }
    }
}

/// A and S from F (module doc).
#[inline(always)]
fn form_s(f: &[f64], g: f64, nv: usize, a: &mut [f64], s: &mut [f64]) {
    let g2 = g * g;
    let n = 2 * nv;
    for c in 0..nv {
        let fa = &f[c * n + nv..(c + 1) * n];
        let fb = &f[(nv + c) * n + nv..(nv + c + 1) * n];
        let (ac, sc) = (&mut a[c * nv..(c + 1) * nv], &mut s[c * nv..(c + 1) * nv]);
        for r in 0..nv {
            ac[r] = fa[r];
            sc[r] = -g * fb[r] - g2 * fa[r];
        }
        sc[c] += 1.0;
    }
}

/// [`form_s`] and [`lu_in_place`] for nv = N known when compiled: indexed, because the general
/// LU's column iterators do not unroll at these sizes.
fn factor_fixed<const N: usize>(
    f: &[f64],
    g: f64,
    a: &mut [f64],
    s: &mut [f64],
    piv: &mut [usize],
) -> bool {
    let (f, a, s, piv) = (
        &f[..4 * N * N],
        &mut a[..N * N],
        &mut s[..N * N],
        &mut piv[..N],
    );
    form_s(f, g, N, a, s);
    for k in 0..N {
        let (mut p, mut best) = (k, s[k * N + k].abs());
        for r in k + 1..N {
            let x = s[k * N + r].abs();
            if x > best {
                (p, best) = (r, x);
            }
        }
        if !(best > 0.0 && best.is_finite()) {
            return false;
        }
        piv[k] = p;
        if p != k {
            for c in 0..N {
                s.swap(c * N + p, c * N + k);
            }
        }
        let d = s[k * N + k];
        for r in k + 1..N {
            s[k * N + r] /= d;
        }
        for c in k + 1..N {
            let akc = s[c * N + k];
            for r in k + 1..N {
                let l = s[k * N + r];
                if l != 0.0 {
                    s[c * N + r] -= l * akc;
                }
            }
        }
    }
    true
}

/// [`ShiftedFactor::solve`] for nv = N known when compiled: the same operations as the general
/// path ([`add_g_a_top`], [`lu_solve`]).
fn solve_fixed<const N: usize>(a: &[f64], s: &[f64], piv: &[usize], g: f64, x: &mut [f64]) {
    let (a, s, piv) = (&a[..N * N], &s[..N * N], &piv[..N]);
    let (top, bottom) = x[..2 * N].split_at_mut(N);
    for c in 0..N {
        let gac = g * top[c];
        if gac != 0.0 {
            for r in 0..N {
                bottom[r] += a[c * N + r] * gac;
            }
        }
    }
    for k in 0..N {
        bottom.swap(k, piv[k]);
    }
    for k in 0..N {
        let bk = bottom[k];
        if bk != 0.0 {
            for r in k + 1..N {
                bottom[r] -= s[k * N + r] * bk;
            }
        }
    }
    for k in (0..N).rev() {
        bottom[k] /= s[k * N + k];
        let bk = bottom[k];
        if bk != 0.0 {
            for r in 0..k {
                bottom[r] -= s[k * N + r] * bk;
            }
        }
    }
    for r in 0..N {
        top[r] += g * bottom[r];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The residual ‖W x − b‖ of random F of the shape, with g dt near ROS2's at 20 ms and stiff
    /// entries (10³ /s), on sizes with their own kernels, above them and above
    /// `DENSE_EAGER_NV` (sized by the first factor); and the fixed-size
    /// kernels give the general path's factor and solve bit for bit.
    #[test]
    fn solves_w() {
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut rnd = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        for nv in [
            1,
            5,
            9,
            crate::linalg::FIXED_MAX,
            crate::linalg::FIXED_MAX + 3,
            DENSE_EAGER_NV + 1,
        ] {
            let mut f = DMatrix::zeros(2 * nv, 2 * nv);
            for i in 0..nv {
                f[(i, nv + i)] = 1.0;
                for j in 0..2 * nv {
                    f[(nv + i, j)] = 1e3 * rnd();
                }
            }
            let g = 0.02 * (1.0 - std::f64::consts::FRAC_1_SQRT_2);
            let w = DMatrix::identity(2 * nv, 2 * nv) - &f * g;
            let mut sf = ShiftedFactor::new(nv);
            assert!(sf.factor(&f, g));
            let b = nalgebra::DVector::from_fn(2 * nv, |_, _| rnd());
            let mut x = b.clone();
            sf.solve(x.as_mut_slice());
            let residual = (&w * &x - &b).amax();
            // The LU's rounding grows with its size: 2.9e-12 at nv = 257 (the size sized by its
            // first factor).
            let tol = 1e-12 * (nv as f64 / crate::linalg::FIXED_MAX as f64).max(1.0);
            assert!(residual < tol, "nv {nv}: {residual:e}");
            // S as the factor forms it: −g B − g² A, then the identity added.
            let mut general =
                -(f.view((nv, nv), (nv, nv)) * g) - f.view((nv, 0), (nv, nv)) * (g * g);
            for i in 0..nv {
                general[(i, i)] += 1.0;
            }
            let mut piv = vec![0; nv];
            assert!(lu_in_place(&mut general, &mut piv));
            assert_eq!(piv, sf.piv, "nv {nv}");
            assert!(
                general
                    .iter()
                    .zip(sf.s.iter())
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "nv {nv}"
            );
            // The general path's solve with that factor.
            let mut y = b.clone();
            let (top, bottom) = y.as_mut_slice().split_at_mut(nv);
            add_g_a_top(sf.a.as_slice(), g, top, bottom);
            lu_solve(&general, &piv, bottom);
            for (t, &yb) in top.iter_mut().zip(bottom.iter()) {
                *t += g * yb;
            }
            assert!(
                y.iter()
                    .zip(x.iter())
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "nv {nv}"
            );
        }
    }
}
