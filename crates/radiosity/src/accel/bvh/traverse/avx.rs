//! The walks compiled for AVX, with the eight child boxes tested in one
//! group of eight lanes: half the instructions of two groups of four, the
//! same operations lane by lane (`vmaxps` and `vminps` keep SSE's rule for
//! NaN, the comparison is ordered), so the same answers; and the leaf
//! children's `f64` recheck four lanes at a time, likewise. Chosen at run
//! time, so one build runs everywhere and uses AVX where it is.

use std::arch::x86_64::{
    __m256, __m256d, _CMP_LE_OQ, _mm_loadu_ps, _mm256_add_pd, _mm256_cmp_pd, _mm256_cmp_ps,
    _mm256_cvtps_pd, _mm256_load_ps, _mm256_max_pd, _mm256_max_ps, _mm256_min_pd, _mm256_min_ps,
    _mm256_movemask_pd, _mm256_movemask_ps, _mm256_mul_pd, _mm256_mul_ps, _mm256_set1_pd,
    _mm256_set1_ps, _mm256_setzero_pd, _mm256_setzero_ps, _mm256_storeu_ps, _mm256_sub_pd,
    _mm256_sub_ps,
};

use super::{
    ChildBoxes, ExactSlabs, LeafBoxes, Slabs, WIDTH, WideNode, any_hit_with, closest_hit_with,
};

/// [`ExactSlabs`] in four `f64` lanes.
pub(super) struct Exact8 {
    from: [__m256d; 3],
    inverse: [__m256d; 3],
    down: [bool; 3],
    margin: __m256d,
}

impl Exact8 {
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

impl Slabs8 {
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
    slabs: &Slabs,
    exact: &super::ExactSlabs,
    blocks: impl FnMut(u32, u32) -> bool,
) -> (bool, u32) {
    any_hit_with(nodes, &Slabs8::new(slabs), &Exact8::new(exact), blocks)
}

/// [`super::wide_closest_hit`]'s walk with the eight-lane test.
#[target_feature(enable = "avx")]
pub(super) fn closest_hit(nodes: &[WideNode], slabs: &Slabs, offer: impl FnMut(u32) -> f64) -> u32 {
    closest_hit_with(nodes, &Slabs8::new(slabs), offer)
}
