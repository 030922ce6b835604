//! Which columns of a matrix are linearly independent: column-pivoted Householder QR on a
//! preallocated workspace (the rank decisions of the minimum-norm multipliers and of the embedded
//! form's partition), allocation-free once sized.

use nalgebra::DMatrix;

/// Workspace of a column-pivoted Householder QR of matrices up to a given size.
#[derive(Clone, Debug, Default)]
pub struct ColumnPivotedQr {
    a: DMatrix<f64>,
    order: Vec<usize>,
    diag: Vec<f64>,
}

impl ColumnPivotedQr {
    /// Workspace for matrices of up to `rows` × `cols`.
    pub fn new(rows: usize, cols: usize) -> Self {
        Self {
            a: DMatrix::zeros(rows, cols),
            order: Vec::with_capacity(cols),
            diag: Vec::with_capacity(cols),
        }
    }

    /// Indices (into 0..n) of a maximal set of linearly independent columns of the m × n matrix
    /// whose entries are `entry(i, j)`, in pivot order, written to `out`.
    ///
    /// The pivot of each step is the column holding the largest |entry| of the remaining block
    /// (the first in column-major order on ties, as nalgebra's `col_piv_qr` picks, so the
    /// partitions chosen are the same as with it); a column counts while |r_kk| > `tol` · max |r_kk|.
    /// Allocates only when the matrix is larger than the workspace.
    pub fn independent_columns(
        &mut self,
        m: usize,
        n: usize,
        entry: impl Fn(usize, usize) -> f64,
        tol: f64,
        out: &mut Vec<usize>,
    ) {
        out.clear();
        if m == 0 || n == 0 {
            return;
        }
        if self.a.nrows() < m || self.a.ncols() < n {
            self.a = DMatrix::zeros(m.max(self.a.nrows()), n.max(self.a.ncols()));
        }
        let a = &mut self.a;
        for j in 0..n {
            for i in 0..m {
                a[(i, j)] = entry(i, j);
            }
        }
        self.order.clear();
        self.order.extend(0..n);
        self.diag.clear();
        for k in 0..m.min(n) {
            let (mut best, mut piv) = (a[(k, k)].abs(), k);
            for j in k..n {
                for i in k..m {
                    if a[(i, j)].abs() > best {
                        (best, piv) = (a[(i, j)].abs(), j);
                    }
                }
            }
            if piv != k {
                for i in 0..m {
                    let t = a[(i, k)];
                    a[(i, k)] = a[(i, piv)];
                    a[(i, piv)] = t;
                }
                self.order.swap(k, piv);
            }
            self.diag.push(reflect(a, m, n, k));
        }
        let rmax = self.diag.iter().fold(0.0f64, |x, d| x.max(d.abs()));
        let rank = self
            .diag
            .iter()
            .take_while(|d| d.abs() > tol * rmax.max(f64::MIN_POSITIVE))
            .count();
        out.extend_from_slice(&self.order[..rank]);
    }
}

/// Householder reflection zeroing column k below the diagonal (rows k..m), applied to the
/// columns k+1..n; returns r_kk (± the norm of the column's remaining part).
fn reflect(a: &mut DMatrix<f64>, m: usize, n: usize, k: usize) -> f64 {
    let norm = (k..m).map(|i| a[(i, k)] * a[(i, k)]).sum::<f64>().sqrt();
    if norm == 0.0 {
        return 0.0;
    }
    let x0 = a[(k, k)];
    let alpha = if x0 >= 0.0 { -norm } else { norm };
    // v = x − α e₁, H = I − 2 v vᵀ / (vᵀ v); vᵀv = 2 (‖x‖² − α x₀).
    a[(k, k)] = x0 - alpha;
    let vtv = 2.0 * (norm * norm - alpha * x0);
    for j in k + 1..n {
        let dot: f64 = (k..m).map(|i| a[(i, k)] * a[(i, j)]).sum();
        let f = 2.0 * dot / vtv;
        for i in k..m {
            a[(i, j)] -= f * a[(i, k)];
        }
    }
    alpha
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_rank_and_independent_columns() {
        // Columns: c0, c1 = 2 c0, c2 independent, c3 = c0 + c2, c4 = 0.
        let a = DMatrix::from_row_slice(
            3,
            5,
            &[
                1.0, 2.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 1.0, 2.0, 3.0, 4.0, 0.0,
            ],
        );
        let mut qr = ColumnPivotedQr::new(3, 5);
        let mut out = vec![];
        qr.independent_columns(3, 5, |i, j| a[(i, j)], 1e-10, &mut out);
        assert_eq!(out.len(), 2);
        // The chosen columns span the others: rank of the selection is 2.
        let sel = a.select_columns(out.iter());
        assert_eq!(sel.rank(1e-10), 2);
    }
}
