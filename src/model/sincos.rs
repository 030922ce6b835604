//! Sine and cosine of a joint angle: musl's `sincos` (the `libm` crate's, fdlibm's algorithm)
//! with its common case written out inline and without branches on the quadrant.
//!
//! For |x| < 2²⁰ π/2 musl reduces x by the nearest multiple n of π/2 (`rem_pio2`'s "medium"
//! case: π/2 in two parts, a double-double remainder y0 + y1), evaluates its sine and cosine
//! kernels on the remainder and picks the pair by n mod 4. Here the same operations in the same
//! order, the pair picked by a swap and two sign flips, so the numbers are musl's; the cases
//! that need more (a remainder more than 2¹⁶ times smaller than x, where musl reduces a second
//! time; |x| ≥ 2²⁰ π/2; NaN and ±∞) call `libm::sincos` itself. The one difference: musl
//! switches between n = 1, 2, 3 and 4 at thresholds on x's leading 32 bits, which lie up to
//! 2⁻³² x past the odd multiples of π/4 where rounding x·2/π switches; in those slivers the
//! other n gives the other, equally accurate reduction (within an ulp of musl's result).
//! The kinematics passes call this once per revolute joint: musl's calls with their branches
//! on the quadrant measured ≈ 110 instructions each, this ≈ 55.

// fdlibm's coefficients, by their bits.
const S1: f64 = f64::from_bits(0xbfc5_5555_5555_5549);
const S2: f64 = f64::from_bits(0x3f81_1111_1110_f8a6);
const S3: f64 = f64::from_bits(0xbf2a_01a0_19c1_61d5);
const S4: f64 = f64::from_bits(0x3ec7_1de3_57b1_fe7d);
const S5: f64 = f64::from_bits(0xbe5a_e5e6_8a2b_9ceb);
const S6: f64 = f64::from_bits(0x3de5_d93a_5acf_d57c);
const C1: f64 = f64::from_bits(0x3fa5_5555_5555_554c);
const C2: f64 = f64::from_bits(0xbf56_c16c_16c1_5177);
const C3: f64 = f64::from_bits(0x3efa_01a0_19cb_1590);
const C4: f64 = f64::from_bits(0xbe92_7e4f_809c_52ad);
const C5: f64 = f64::from_bits(0x3e21_ee9e_bdb4_b1c4);
const C6: f64 = f64::from_bits(0xbda8_fae9_be88_38d4);
/// 1.5 · 2⁵²: adding and subtracting it rounds to the nearest integer.
const TO_INT: f64 = 1.5 / f64::EPSILON;
const INV_PIO2: f64 = f64::from_bits(0x3fe4_5f30_6dc9_c883);
/// The first 33 bits of π/2, and the next 53.
const PIO2_1: f64 = f64::from_bits(0x3ff9_21fb_5440_0000);
const PIO2_1T: f64 = f64::from_bits(0x3dd0_b461_1a62_6331);

/// (sin x, cos x), the same numbers as `libm::sincos(x)` but in the slivers described above.
#[inline(always)]
pub(crate) fn sin_cos(x: f64) -> (f64, f64) {
    let ix = (x.to_bits() >> 32) as u32 & 0x7fff_ffff;
    if ix <= 0x3fe9_21fb {
        // |x| ≲ π/4: no reduction (musl's kernels with y = 0, its tiny-angle case included).
        if ix < 0x3e46_a09e {
            return (x, 1.0);
        }
        let z = x * x;
        return (x + z * x * (S1 + z * sin_tail(z)), cos_kernel(x, 0.0, z));
    }
    if ix >= 0x4139_21fb {
        return libm::sincos(x);
    }
    let f_n = (x * INV_PIO2 + TO_INT) - TO_INT;
    let r = x - f_n * PIO2_1;
    let w = f_n * PIO2_1T;
    let y0 = r - w;
    let ey = (y0.to_bits() >> 52) as i32 & 0x7ff;
    if (ix >> 20) as i32 - ey > 16 {
        return libm::sincos(x);
    }
    let y1 = (r - y0) - w;
    let z = y0 * y0;
    let v = z * y0;
    let s = y0 - ((z * (0.5 * y1 - v * sin_tail(z)) - y1) - v * S1);
    let c = cos_kernel(y0, y1, z);
    // n mod 4 = 0: (s, c), 1: (c, −s), 2: (−s, −c), 3: (−c, s).
    let n = f_n as i64 as u64;
    let (a, b) = if n & 1 == 0 { (s, c) } else { (c, s) };
    let sin = f64::from_bits(a.to_bits() ^ ((n & 2) << 62));
    let cos = f64::from_bits(b.to_bits() ^ ((n.wrapping_add(1) & 2) << 62));
    (sin, cos)
}

/// musl's `k_sin` polynomial r(z) past its first term.
#[inline(always)]
fn sin_tail(z: f64) -> f64 {
    let w = z * z;
    S2 + z * (S3 + z * S4) + z * w * (S5 + z * S6)
}

/// musl's `k_cos(x, y)`, given z = x².
#[inline(always)]
fn cos_kernel(x: f64, y: f64, z: f64) -> f64 {
    let w = z * z;
    let r = z * (C1 + z * (C2 + z * C3)) + w * w * (C4 + z * (C5 + z * C6));
    let hz = 0.5 * z;
    let w = 1.0 - hz;
    w + (((1.0 - w) - hz) + (z * r - x * y))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bit for bit `libm::sincos` over ±2²⁰ π/2 (log-spaced magnitudes, both signs, the
    /// multiples of π/2 and their neighbours, where musl reduces twice), but within an ulp in
    /// the slivers at the odd multiples of π/4 where the two pick different quadrants.
    #[test]
    fn matches_musl() {
        let mut xs = vec![0.0, -0.0, 1e-300, 1e-9, 0.3, 0.785, 0.7854, 1.0, 2.0, 3.0, 1e6];
        let mut x = 1e-12;
        while x < 1.6e6 {
            xs.extend([x, -x]);
            x *= 1.0007;
        }
        for k in -40..=40 {
            let m = f64::from(k) * std::f64::consts::FRAC_PI_2;
            for d in -3..=3i64 {
                xs.push(f64::from_bits((m.to_bits() as i64 + d) as u64));
            }
        }
        let (mut same, mut near) = (0, 0);
        for x in xs {
            let (s, c) = sin_cos(x);
            let (s0, c0) = libm::sincos(x);
            if (s.to_bits(), c.to_bits()) == (s0.to_bits(), c0.to_bits()) {
                same += 1;
                continue;
            }
            let ulp = |a: f64| f64::EPSILON * a.abs().max(f64::MIN_POSITIVE);
            assert!(
                (s - s0).abs() <= ulp(s0) && (c - c0).abs() <= ulp(c0),
                "x = {x:e}: ({s:e}, {c:e}) against musl's ({s0:e}, {c0:e})"
            );
            let q = x.abs() / std::f64::consts::FRAC_PI_4;
            assert!((q - q.round()).abs() < 1e-8, "x = {x:e} is not at an odd multiple of π/4");
            near += 1;
        }
        assert!(same > 100 * near.max(1), "{same} identical, {near} within an ulp");
        for x in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            assert!(sin_cos(x).0.is_nan() && sin_cos(x).1.is_nan());
        }
    }
}
