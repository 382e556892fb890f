//! The walks compiled for AVX, with the eight child boxes tested in one
//! group of eight lanes: half the instructions of two groups of four, the
//! same operations lane by lane (`vmaxps` and `vminps` keep SSE's rule for
//! NaN, the comparison is ordered), so the same answers; and the leaf
//! children's `f64` recheck four lanes at a time, likewise; a shadow
//! segment's set-up for both, for the three axes at once (`prepare8`).
//! Chosen at run time, so one build runs everywhere and uses AVX where it
//! is.

use std::arch::x86_64::{
    __m256, __m256d, _CMP_LE_OQ, _mm_add_ps, _mm_blendv_ps, _mm_div_ps, _mm_loadu_ps,
    _mm_movemask_ps, _mm_set1_ps, _mm_storeu_ps, _mm_sub_ps, _mm256_add_pd, _mm256_cmp_pd,
    _mm256_cmp_ps, _mm256_cvtpd_ps, _mm256_cvtps_pd, _mm256_div_pd, _mm256_load_ps, _mm256_max_pd,
    _mm256_max_ps, _mm256_min_pd, _mm256_min_ps, _mm256_movemask_pd, _mm256_movemask_ps,
    _mm256_mul_pd, _mm256_mul_ps, _mm256_set1_pd, _mm256_set1_ps, _mm256_setr_pd,
    _mm256_setzero_pd, _mm256_setzero_ps, _mm256_storeu_pd, _mm256_storeu_ps, _mm256_sub_pd,
    _mm256_sub_ps,
};

use glam::DVec3;

use super::{ChildBoxes, LeafBoxes, WIDTH, WideNode, any_hit_with, closest_hit_with};
#[cfg(test)]
use super::{ExactSlabs, Slabs};

/// [`ExactSlabs`] in four `f64` lanes.
pub(super) struct Exact8 {
    from: [__m256d; 3],
    inverse: [__m256d; 3],
    down: [bool; 3],
    margin: __m256d,
}

#[cfg(test)]
impl Exact8 {
    /// [`ExactSlabs`] spread over the lanes, the reference
    /// [`prepare8`] is tested against.
    #[target_feature(enable = "avx")]
    pub(super) fn new(exact: &ExactSlabs) -> Exact8 {
        Exact8 {
            from: [0, 1, 2].map(|a| _mm256_set1_pd(exact.from[a])),
            inverse: [0, 1, 2].map(|a| _mm256_set1_pd(exact.inverse[a])),
            down: [0, 1, 2].map(|a| exact.inverse[a].is_sign_negative()),
            margin: _mm256_set1_pd(exact.margin),
        }
    }
}

/// [`ExactSlabs::meets`] for the children in `mask`, four at a time.
#[target_feature(enable = "avx")]
#[inline]
fn keep8(node: &WideNode, exact: &Exact8, mask: u32) -> u32 {
    let mut met = 0;
    for half in 0..2 {
        if mask >> (4 * half) & 0xf == 0 {
            continue;
        }
        let mut enter = _mm256_setzero_pd();
        let mut exit = _mm256_set1_pd(1.0);
        for axis in 0..3 {
            let faces = &node.bounds[axis];
            // SAFETY: each side holds eight floats; these are four.
            let (lo, hi) = unsafe {
                (
                    _mm256_cvtps_pd(_mm_loadu_ps(faces[0][4 * half..].as_ptr())),
                    _mm256_cvtps_pd(_mm_loadu_ps(faces[1][4 * half..].as_ptr())),
                )
            };
            let lower = _mm256_sub_pd(lo, exact.margin);
            let upper = _mm256_add_pd(hi, exact.margin);
            let a = _mm256_mul_pd(_mm256_sub_pd(lower, exact.from[axis]), exact.inverse[axis]);
            let b = _mm256_mul_pd(_mm256_sub_pd(upper, exact.from[axis]), exact.inverse[axis]);
            let (near, far) = if exact.down[axis] { (b, a) } else { (a, b) };
            enter = _mm256_max_pd(near, enter);
            exit = _mm256_min_pd(far, exit);
        }
        let lanes = _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_LE_OQ>(enter, exit)) as u32;
        met |= lanes << (4 * half);
    }
    mask & met
}

impl LeafBoxes for Exact8 {
    #[inline(always)]
    fn keep(&self, node: &WideNode, mask: u32) -> u32 {
        // SAFETY: an `Exact8` is only made where the processor has AVX.
        unsafe { keep8(node, self, mask) }
    }
}

/// [`Slabs`] in all eight lanes.
pub(super) struct Slabs8 {
    down: [usize; 3],
    o_near: [__m256; 3],
    o_far: [__m256; 3],
    inv: [__m256; 3],
}

/// [`super::slab_test`] in one group of eight lanes.
#[target_feature(enable = "avx")]
#[inline]
fn slab_test8(node: &WideNode, slabs: &Slabs8, limit: f32) -> ([f32; WIDTH], u32) {
    let mut enter = _mm256_setzero_ps();
    let mut exit = _mm256_set1_ps(limit);
    for axis in 0..3 {
        let faces = &node.bounds[axis];
        let down = slabs.down[axis];
        // SAFETY: each side's eight coordinates are 32 bytes at an
        // offset of a multiple of 32 in a node aligned to 64.
        let (near, far) = unsafe {
            (
                _mm256_load_ps(faces[down].as_ptr()),
                _mm256_load_ps(faces[1 - down].as_ptr()),
            )
        };
        let t_near = _mm256_mul_ps(_mm256_sub_ps(near, slabs.o_near[axis]), slabs.inv[axis]);
        let t_far = _mm256_mul_ps(_mm256_sub_ps(far, slabs.o_far[axis]), slabs.inv[axis]);
        enter = _mm256_max_ps(t_near, enter);
        exit = _mm256_min_ps(t_far, exit);
    }
    let mut entries = [0.0f32; WIDTH];
    // SAFETY: `entries` holds eight floats.
    unsafe { _mm256_storeu_ps(entries.as_mut_ptr(), enter) };
    let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(enter, exit)) as u32;
    (entries, mask)
}

#[cfg(test)]
impl Slabs8 {
    /// [`Slabs`] spread over the lanes: the reference [`prepare8`] is
    /// tested against, and the eight-lane test's.
    #[target_feature(enable = "avx")]
    fn new(slabs: &Slabs) -> Slabs8 {
        let splat = |v: [glam::Vec4; 3]| v.map(|v| _mm256_set1_ps(v.x));
        Slabs8 {
            down: slabs.down.map(usize::from),
            o_near: splat(slabs.o_near),
            o_far: splat(slabs.o_far),
            inv: splat(slabs.inv),
        }
    }

    /// [`Slabs8::new`], where the caller has checked for AVX.
    pub(super) fn for_tests(slabs: &Slabs) -> Slabs8 {
        assert!(std::arch::is_x86_feature_detected!("avx"));
        // SAFETY: the processor has AVX, asserted just above.
        unsafe { Slabs8::new(slabs) }
    }
}

impl ChildBoxes for Slabs8 {
    #[inline(always)]
    fn test(&self, node: &WideNode, limit: f32) -> ([f32; WIDTH], u32) {
        // SAFETY: a `Slabs8` is only made where the processor has AVX.
        unsafe { slab_test8(node, self, limit) }
    }
}

/// [`super::wide_any_hit`]'s walk with the eight-lane test.
#[target_feature(enable = "avx")]
pub(super) fn any_hit(
    nodes: &[WideNode],
    ends: (DVec3, DVec3),
    margins: (f64, f64),
    blocks: impl FnMut(u32, u32) -> bool,
) -> (bool, u32) {
    let (slabs, exact) = prepare8(ends, margins);
    any_hit_with(nodes, &slabs, &exact, blocks)
}

/// The segment between `ends` prepared for the eight-lane walk, its
/// boxes widened by `margins` (the `f32` test's and the `f64` recheck's):
/// the values of `Slabs8::new` of `Slabs::new` of `SegmentQuery::new` and
/// of `Exact8::new` of `ExactSlabs::new`, bit for bit
/// (`prepared_at_once_as_step_by_step` compares them), computed for the
/// three axes at once in vector lanes.
/// A shadow query is short (a few hundred instructions on a real scene),
/// and its walk cannot start before this is done: building the same
/// values through those structures, axis by axis, cost a tenth of the
/// query's time on Sponza.
#[target_feature(enable = "avx")]
#[inline]
pub(super) fn prepare8(
    (from, to): (DVec3, DVec3),
    (margin, exact_margin): (f64, f64),
) -> (Slabs8, Exact8) {
    // The fourth lanes are unused (1, not 0, as the direction's, so no
    // division by zero is made there).
    let f = _mm256_setr_pd(from.x, from.y, from.z, 0.0);
    let t = _mm256_setr_pd(to.x, to.y, to.z, 1.0);
    // `to - from` and its inverse in `f64` (`ExactSlabs::new`); the origin
    // and direction rounded to `f32` and the inverse of the latter
    // (`SegmentQuery::new`).
    let d = _mm256_sub_pd(t, f);
    let inverse = _mm256_div_pd(_mm256_set1_pd(1.0), d);
    let origin = _mm256_cvtpd_ps(f);
    let d32 = _mm256_cvtpd_ps(d);
    let inv = _mm_div_ps(_mm_set1_ps(1.0), d32);
    let widen = _mm_set1_ps((margin as f32).next_up());
    let for_lower = _mm_add_ps(origin, widen);
    let for_upper = _mm_sub_ps(origin, widen);
    // Per axis, the near face is the lower one unless the segment runs
    // down (`Slabs::new`): a blend on the sign bit of the inverse, which
    // is the direction's (zeros included, `1 / -0` being `-inf`), so
    // taken from the direction the blends need not wait for the division.
    // Rounding to `f32` keeps the sign, so the same bits serve the `f64`
    // recheck (`ExactSlabs`' inverse in `f64`).
    let o_near = _mm_blendv_ps(for_lower, for_upper, d32);
    let o_far = _mm_blendv_ps(for_upper, for_lower, d32);
    let down = _mm_movemask_ps(d32);
    let mut lanes = [[0.0f32; 4]; 3];
    let mut wide = [0.0f64; 4];
    // SAFETY: each array holds four lanes.
    unsafe {
        _mm_storeu_ps(lanes[0].as_mut_ptr(), o_near);
        _mm_storeu_ps(lanes[1].as_mut_ptr(), o_far);
        _mm_storeu_ps(lanes[2].as_mut_ptr(), inv);
        _mm256_storeu_pd(wide.as_mut_ptr(), inverse);
    }
    let splat = |v: &[f32; 4]| {
        [
            _mm256_set1_ps(v[0]),
            _mm256_set1_ps(v[1]),
            _mm256_set1_ps(v[2]),
        ]
    };
    (
        Slabs8 {
            down: [
                (down & 1) as usize,
                (down >> 1 & 1) as usize,
                (down >> 2 & 1) as usize,
            ],
            o_near: splat(&lanes[0]),
            o_far: splat(&lanes[1]),
            inv: splat(&lanes[2]),
        },
        Exact8 {
            from: [
                _mm256_set1_pd(from.x),
                _mm256_set1_pd(from.y),
                _mm256_set1_pd(from.z),
            ],
            inverse: [
                _mm256_set1_pd(wide[0]),
                _mm256_set1_pd(wide[1]),
                _mm256_set1_pd(wide[2]),
            ],
            down: [down & 1 == 1, down & 2 == 2, down & 4 == 4],
            margin: _mm256_set1_pd(exact_margin),
        },
    )
}

/// [`super::wide_closest_hit`]'s walk with the eight-lane test, its
/// set-up as the shadow walk's ([`prepare8`], whose `f64` half, unused
/// here, the compiler drops).
#[target_feature(enable = "avx")]
pub(super) fn closest_hit(
    nodes: &[WideNode],
    ends: (DVec3, DVec3),
    margin: f64,
    offer: impl FnMut(u32) -> f64,
) -> u32 {
    let (slabs, _) = prepare8(ends, (margin, 0.0));
    closest_hit_with(nodes, &slabs, offer)
}

#[cfg(test)]
mod tests {
    use super::super::SegmentQuery;
    use super::*;

    fn bits(v: __m256) -> [u32; 8] {
        let mut out = [0.0f32; 8];
        // SAFETY: `out` holds eight floats; AVX is checked by the caller.
        unsafe { _mm256_storeu_ps(out.as_mut_ptr(), v) };
        out.map(f32::to_bits)
    }

    fn bits_d(v: __m256d) -> [u64; 4] {
        let mut out = [0.0f64; 4];
        // SAFETY: `out` holds four doubles; AVX is checked by the caller.
        unsafe { _mm256_storeu_pd(out.as_mut_ptr(), v) };
        out.map(f64::to_bits)
    }

    /// [`prepare8`] gives the values of the step-by-step preparation bit
    /// for bit: random segments, some with zero or negative-zero
    /// components (infinite inverses of either sign), some of zero length,
    /// some with coordinates that round in `f32`, with random margins
    /// (zero among them).
    #[test]
    fn prepared_at_once_as_step_by_step() {
        if !std::arch::is_x86_feature_detected!("avx") {
            eprintln!("did not run: this processor has no AVX");
            return;
        }
        let mut next = crate::accel::test_scenes::xorshift(0x2545_f491_4f6c_dd1d);
        let coordinate = |next: &mut dyn FnMut() -> u64| match next() % 8 {
            0 => 0.0,
            1 => -0.0,
            2 => 1.0 / 3.0,
            3 => 1e-300,
            _ => (next() >> 11) as f64 / (1u64 << 53) as f64 * 200.0 - 100.0,
        };
        for _ in 0..20_000 {
            let point = |next: &mut dyn FnMut() -> u64| {
                DVec3::new(coordinate(next), coordinate(next), coordinate(next))
            };
            let from = point(&mut next);
            let to = if next().is_multiple_of(16) {
                from
            } else {
                point(&mut next)
            };
            let reference = if next().is_multiple_of(8) {
                0.0
            } else {
                (next() >> 11) as f64 / (1u64 << 53) as f64 * 100.0
            };
            let margins = (2e-6 * reference, 1e-12 * reference);
            // SAFETY: the processor has AVX, checked above.
            let (slabs, exact) = unsafe { prepare8((from, to), margins) };
            let step = Slabs8::for_tests(&Slabs::new(&SegmentQuery::new(from, to, margins.0)));
            // SAFETY: as above.
            let step_exact = unsafe { Exact8::new(&ExactSlabs::new(from, to, margins.1)) };
            let case = format!("{from} {to} {margins:?}");
            assert_eq!(slabs.down, step.down, "{case}");
            for axis in 0..3 {
                assert_eq!(bits(slabs.o_near[axis]), bits(step.o_near[axis]), "{case}");
                assert_eq!(bits(slabs.o_far[axis]), bits(step.o_far[axis]), "{case}");
                assert_eq!(bits(slabs.inv[axis]), bits(step.inv[axis]), "{case}");
                assert_eq!(
                    bits_d(exact.from[axis]),
                    bits_d(step_exact.from[axis]),
                    "{case}"
                );
                assert_eq!(
                    bits_d(exact.inverse[axis]),
                    bits_d(step_exact.inverse[axis]),
                    "{case}"
                );
            }
            assert_eq!(exact.down, step_exact.down, "{case}");
            assert_eq!(bits_d(exact.margin), bits_d(step_exact.margin), "{case}");
        }
    }
}
