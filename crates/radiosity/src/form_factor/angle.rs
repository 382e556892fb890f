//! The angle between two vectors from `atan2(|a x b|, a . b)`, faster than
//! the platform's `atan2`: the contour sum of equation (2) (Baum, Rushmeier
//! & Winget 1989) takes one an edge, and in the default method's transfers
//! those were a tenth of the threads' time. The reduction and polynomial
//! are fdlibm's `atan` (Sun Microsystems, 1993): the ratio of the smaller
//! to the larger argument in `[0, 1]`, cut at 7/16 and 11/16 around
//! `atan(1/2)` and `atan(1)` (each held as two doubles), and an odd
//! polynomial of degree 23 on `|x| < 7/16`. Within 2 units in the last
//! place of the platform's `atan2` (the tests measure it); the paper's
//! presets keep the platform's, so their results stay bit for bit.

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};

/// fdlibm's `aT`: `atan(x) = x - x (z aT0 + z^2 aT1 + ...)`, `z = x^2`.
#[allow(clippy::excessive_precision, reason = "fdlibm's digits, as published")]
const AT: [f64; 11] = [
    3.333_333_333_333_293_180_27e-1,
    -1.999_999_999_987_648_324_76e-1,
    1.428_571_427_250_346_637_11e-1,
    -1.111_111_040_546_235_578_80e-1,
    9.090_887_133_436_506_561_96e-2,
    -7.691_876_205_044_829_994_95e-2,
    6.661_073_137_387_531_206_69e-2,
    -5.833_570_133_790_573_486_45e-2,
    4.976_877_994_615_932_360_17e-2,
    -3.653_157_274_421_691_552_70e-2,
    1.628_582_011_536_578_236_23e-2,
];

/// `atan(1/2)` as a double and its round-off.
#[allow(clippy::excessive_precision, reason = "fdlibm's digits, as published")]
const ATAN_HALF: (f64, f64) = (
    4.636_476_090_008_060_935_15e-1,
    2.269_877_745_296_168_709_24e-17,
);

/// `atan(1)` as a double (the nearest, `FRAC_PI_4`) and its round-off.
#[allow(clippy::excessive_precision, reason = "fdlibm's digits, as published")]
const ATAN_ONE: (f64, f64) = (FRAC_PI_4, 3.061_616_997_868_383_017_93e-17);

/// `x (z aT0 + z^2 aT1 + ...)`, the polynomial's part beyond `x`.
#[inline(always)]
fn tail(x: f64) -> f64 {
    let z = x * x;
    let w = z * z;
    let odd = z * (AT[0] + w * (AT[2] + w * (AT[4] + w * (AT[6] + w * (AT[8] + w * AT[10])))));
    let even = w * (AT[1] + w * (AT[3] + w * (AT[5] + w * (AT[7] + w * AT[9]))));
    x * (odd + even)
}

/// `atan(t)` for `t` in `[0, 1]`.
#[inline(always)]
fn atan_unit(t: f64) -> f64 {
    if t < 0.4375 {
        return t - tail(t);
    }
    let ((hi, lo), x) = if t < 0.6875 {
        (ATAN_HALF, (2.0 * t - 1.0) / (2.0 + t))
    } else {
        (ATAN_ONE, (t - 1.0) / (t + 1.0))
    };
    hi - ((tail(x) - lo) - x)
}

/// `atan2(y, x)` for `y > 0` and finite `x`: the angle in `(0, pi)`
/// between `x` and a vector of length `sqrt(x^2 + y^2)` at `y` from its
/// line, as [`f64::atan2`] gives it to within 2 units in the last place.
#[inline]
#[must_use]
pub fn atan2_positive(y: f64, x: f64) -> f64 {
    let ax = x.abs();
    let angle = if y <= ax {
        atan_unit(y / ax)
    } else {
        FRAC_PI_2 - atan_unit(ax / y)
    };
    if x < 0.0 { PI - angle } else { angle }
}

#[cfg(test)]
mod tests {
    use super::atan2_positive;

    /// Units in the last place of `b` between `a` and `b`.
    fn ulps(a: f64, b: f64) -> f64 {
        let ulp = f64::from_bits(b.to_bits() + 1) - b;
        (a - b).abs() / ulp
    }

    #[test]
    fn within_two_ulps_of_the_platform() {
        // A fixed-seed walk over magnitudes 1e-12 to 1e4 and every octant
        // of the upper half plane, and the cut points themselves.
        let mut unit = crate::accel::test_scenes::uniform(0x9e37_79b9_7f4a_7c15);
        let mut worst = 0.0f64;
        for _ in 0..1_000_000 {
            let y = unit() * 10f64.powf(16.0 * unit() - 12.0);
            let x = (2.0 * unit() - 1.0) * 10f64.powf(16.0 * unit() - 12.0);
            if y > 0.0 {
                worst = worst.max(ulps(atan2_positive(y, x), y.atan2(x)));
            }
        }
        for t in [0.4375, 0.6875, 1.0, 1e-300, 1e300] {
            for x in [1.0, -1.0] {
                worst = worst.max(ulps(atan2_positive(t, x), t.atan2(x)));
                worst = worst.max(ulps(atan2_positive(1.0, t * x), 1.0f64.atan2(t * x)));
            }
        }
        assert!(worst <= 2.0, "{worst} units in the last place");
        assert_eq!(atan2_positive(1.0, 0.0), std::f64::consts::FRAC_PI_2);
    }
}
