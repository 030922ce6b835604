//! The matrix of the linearly implicit steps (ROS2, SDIRK2's Newton), `W = I − g F`, for the
//! state Jacobian's shape `F = [[0, I], [A, B]]` (A = ∂q̈/∂δq, B = ∂q̈/∂v, nv × nv each:
//! integrators/mod.rs, `state_jacobian`), factored through its Schur complement
//!
//! `S = I − g B − g² A`:  `W [x; y] = [a; b]`  ⇔  `S y = b + g A a`,  `x = a + g y`,
//!
//! so det W = det S, and a factor and a solve cost an nv × nv LU and its solve plus one product
//! with A, not a 2nv × 2nv LU: an eighth of the factor's operations.

use crate::linalg::{lu_in_place, lu_solve};
use nalgebra::DMatrix;

/// The factored `W = I − g F` (module doc). Sized once per model.
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
        Self {
            g: f64::NAN,
            a: DMatrix::zeros(nv, nv),
            s: DMatrix::zeros(nv, nv),
            piv: vec![0; nv],
        }
    }

    /// Factor `I − g F` from F (2nv × 2nv, of the shape in the module doc; its upper blocks are
    /// not read). False when W is singular (a zero or non-finite pivot of S).
    pub(in crate::predict) fn factor(&mut self, f: &DMatrix<f64>, g: f64) -> bool {
        let nv = self.piv.len();
        debug_assert_eq!(f.nrows(), 2 * nv);
        self.g = g;
        let g2 = g * g;
        let n = 2 * nv;
        let f = f.as_slice();
        let (a, s) = (self.a.as_mut_slice(), self.s.as_mut_slice());
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
        lu_in_place(&mut self.s, &mut self.piv)
    }

    /// Solve `W x = rhs` in place (2nv).
    pub(in crate::predict) fn solve(&self, x: &mut [f64]) {
        let nv = self.piv.len();
        let (top, bottom) = x.split_at_mut(nv);
        for (&ac, col) in top.iter().zip(self.a.as_slice().chunks_exact(nv)) {
            let gac = self.g * ac;
            if gac != 0.0 {
                for (b, &arc) in bottom.iter_mut().zip(col) {
                    *b += arc * gac;
                }
            }
        }
        lu_solve(&self.s, &self.piv, bottom);
        for (t, &y) in top.iter_mut().zip(bottom.iter()) {
            *t += self.g * y;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The residual ‖W x − b‖ of a random F of the shape, with g dt near ROS2's at 20 ms and
    /// stiff entries (10³ /s).
    #[test]
    fn solves_w() {
        let nv = 5;
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut rnd = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
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
        assert!(residual < 1e-12, "{residual:e}");
    }
}
