//! Numerical kernels shared by the dynamics, the projection and the integrators: in place, on
//! preallocated storage, no allocation.

#[macro_use]
mod wide;
pub(crate) use wide_fn;
mod dense;
#[cfg(target_arch = "x86_64")]
mod gemm_avx2;
mod ltl;
mod lu;
mod min_norm;
mod pivot;
mod rank;
#[macro_use]
mod sized;
pub(crate) use by_size;
pub(crate) use sized::FIXED_MAX;

pub use dense::{
    cholesky_in_place, cholesky_solve, dot_unrolled, gemm_columns, gemm_into, gemm_nt_into,
    gemm_tr_into, inverse_from_cholesky, mat_tr_vec, mat_vec, mat_vec_add, solve_lower,
    solve_lower_transpose, spd_inverse,
};
pub use ltl::{NO_PARENT, ltl_factor, ltl_inverse, ltl_solve_l, ltl_solve_lt, ltl_solve_lt_rows};
pub use lu::{lu_in_place, lu_solve};
pub use min_norm::MinNormSolver;
pub use pivot::ColumnPivotedQr;
pub use rank::{
    rank_revealing_cholesky, semidefinite_cholesky, semidefinite_solve, semidefinite_solve_columns,
};
