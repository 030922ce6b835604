//! Kernels on a handful of coordinates (a step's W, the constant dynamics form), where loop
//! control costs as much as the arithmetic: the same generic body built for each size up to
//! [`FIXED_MAX`] (loops of known length, unrolled, no bounds checks) and picked at run time,
//! with a general path above it. A built size does the same operations in the same order as the
//! general path, so both give the same numbers.

/// The largest size with kernels built for it.
pub(crate) const FIXED_MAX: usize = 12;

/// `$f::<n>($args)` for the sizes built ([`FIXED_MAX`] and below), else `$general`.
macro_rules! by_size {
    ($n:expr, $f:ident($($arg:expr),*), $general:expr) => {
        match $n {
            1 => $f::<1>($($arg),*),
            2 => $f::<2>($($arg),*),
            3 => $f::<3>($($arg),*),
            4 => $f::<4>($($arg),*),
            5 => $f::<5>($($arg),*),
            6 => $f::<6>($($arg),*),
            7 => $f::<7>($($arg),*),
            8 => $f::<8>($($arg),*),
            9 => $f::<9>($($arg),*),
            10 => $f::<10>($($arg),*),
            11 => $f::<11>($($arg),*),
            $crate::linalg::FIXED_MAX => $f::<{ $crate::linalg::FIXED_MAX }>($($arg),*),
            _ => $general,
        }
    };
}
