//! The BVH's traversal: the segment prepared for the slab test, the
//! eight-wide layout the binary tree is collapsed into (Dammertz et al.
//! 2008; Wald et al. 2008; the collapse itself is `collapse`), the slab
//! test of a node's eight child boxes in two groups of four SIMD lanes (or
//! one group of eight where the processor has AVX, chosen at run time), the
//! `f64` recheck of leaf children, the depth-first any-hit walk
//! for shadow segments and the front-to-back closest-hit walk, which
//! shrinks the segment as hits are found.

use std::mem::MaybeUninit;

use glam::Vec4;

use super::*;

/// A segment `origin + t * direction`, `t` in `[0, 1]`, prepared for `f32`
/// slab tests, its origin pushed out by the round-off margin: lower planes
/// are met from `origin + margin`, upper planes from `origin - margin`,
/// which widens every box by the margin at no cost per node. The boxes are
/// `f32` so four of them fit one SSE register per coordinate (eight one
/// AVX register).
pub(super) struct SegmentQuery {
    pub(super) origin_for_min: Vec3A,
    pub(super) origin_for_max: Vec3A,
    pub(super) inverse_direction: Vec3A,
}

impl SegmentQuery {
    pub(super) fn new(from: DVec3, to: DVec3, margin: f64) -> SegmentQuery {
        let origin = from.as_vec3a();
        let direction = (to - from).as_vec3a();
        // Round the margin up: it must not shrink.
        let margin = Vec3A::splat((margin as f32).next_up());
        SegmentQuery {
            origin_for_min: origin + margin,
            origin_for_max: origin - margin,
            inverse_direction: direction.recip(),
        }
    }
}

// ---------------------------------------------------------------- wide layout

/// Children per node of the tree the queries walk: the child boxes a node
/// visit tests (the count `occluded_counting` reports per node).
pub const WIDTH: usize = 8;

/// Entries of a walk's stack: each node pushes at most `WIDTH - 1` above
/// its ancestors'.
const STACK: usize = (WIDTH - 1) * MAX_DEPTH + 1;

/// The SIMD lanes the walks test a node's child boxes in on this
/// processor: 8 where it has AVX (one group), 4 elsewhere (two groups).
#[must_use]
pub fn slab_lanes() -> usize {
    if eight_lanes() { 8 } else { 4 }
}

/// Whether the walks test a node's boxes in one group of eight lanes:
/// where the processor has AVX (and, in tests, unless the thread asked
/// for four, see [`four_lanes_only`]).
#[inline]
fn eight_lanes() -> bool {
    #[cfg(test)]
    if FOUR_LANES_ONLY.with(std::cell::Cell::get) {
        return false;
    }
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        return true;
    }
    false
}

#[cfg(test)]
thread_local! {
    static FOUR_LANES_ONLY: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Runs `f` with this thread's walks in two groups of four lanes, as on a
/// processor without AVX.
#[cfg(test)]
pub(super) fn four_lanes_only<T>(f: impl FnOnce() -> T) -> T {
    FOUR_LANES_ONLY.with(|flag| flag.set(true));
    let result = f();
    FOUR_LANES_ONLY.with(|flag| flag.set(false));
    result
}

/// No child in a slot.
pub(super) const EMPTY_SLOT: u32 = u32::MAX;

/// A node of the eight-wide tree the queries walk: the boxes of up to
/// eight children side by side, one array per coordinate and side
/// (structure of arrays), so two passes of four-lane arithmetic, or one of
/// eight with AVX, test them all (Dammertz et al. 2008, "Shallow bounding
/// volume hierarchies"; Wald et al. 2008, "Getting rid of packets"). 256
/// bytes: four cache lines.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub(super) struct WideNode {
    /// `bounds[axis][0][child]` is the lower corner's coordinate,
    /// `bounds[axis][1][child]` the upper one's: a segment's near face on
    /// an axis is `bounds[axis][runs_down]`, its far face the other one.
    pub(super) bounds: [[[f32; WIDTH]; 2]; 3],
    /// Interior child: its node index. Leaf child: its first primitive.
    /// [`EMPTY_SLOT`] for no child.
    pub(super) link: [u32; WIDTH],
    /// Primitives of a leaf child; 0 for an interior child or no child.
    pub(super) count: [u8; WIDTH],
    /// Bit `k` set where child `k` is a leaf.
    pub(super) leaves: u32,
}

impl WideNode {
    pub(super) const UNUSED: WideNode = WideNode {
        bounds: [[[f32::INFINITY; WIDTH], [f32::NEG_INFINITY; WIDTH]]; 3],
        link: [EMPTY_SLOT; WIDTH],
        count: [0; WIDTH],
        leaves: 0,
    };

    /// Child `k`'s lower and upper corners.
    pub(super) fn child_box(&self, k: usize) -> ([f32; 3], [f32; 3]) {
        (
            [0, 1, 2].map(|a| self.bounds[a][0][k]),
            [0, 1, 2].map(|a| self.bounds[a][1][k]),
        )
    }
}

/// Asks the processor to start loading a node about to be visited (the
/// walk is bound by memory latency on large scenes); a no-op elsewhere.
#[inline]
pub(super) fn prefetch(nodes: &[WideNode], index: u32) {
    #[cfg(target_arch = "x86_64")]
    if let Some(node) = nodes.get(index as usize) {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let p = std::ptr::from_ref(node).cast::<i8>();
        // SAFETY: prefetching is a hint: it never faults, and every line
        // prefetched lies within the node.
        unsafe {
            for line in 0..size_of::<WideNode>() / 64 {
                _mm_prefetch::<_MM_HINT_T0>(p.add(64 * line));
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (nodes, index);
}

/// A segment prepared for [`slab_test`]: per axis, whether it runs towards
/// lower coordinates and the origins its near and far faces are met from,
/// and its inverse direction, each in all four lanes of a group.
struct Slabs {
    down: [bool; 3],
    o_near: [Vec4; 3],
    o_far: [Vec4; 3],
    inv: [Vec4; 3],
}

impl Slabs {
    fn new(query: &SegmentQuery) -> Slabs {
        let o_min = query.origin_for_min.to_array();
        let o_max = query.origin_for_max.to_array();
        let inv = query.inverse_direction.to_array();
        // Per axis, which face the segment meets first: the lower one
        // unless it runs towards lower coordinates (`1 / -0` counts as
        // running down, as its infinite parameter does). Lower faces are
        // met from the origin moved up by the margin and upper faces from
        // it moved down, so choosing the face once per segment keeps the
        // widening.
        let down = inv.map(f32::is_sign_negative);
        let pick =
            |a: usize, lower: bool| Vec4::splat(if down[a] == lower { o_max[a] } else { o_min[a] });
        Slabs {
            down,
            o_near: [0, 1, 2].map(|a| pick(a, true)),
            o_far: [0, 1, 2].map(|a| pick(a, false)),
            inv: inv.map(Vec4::splat),
        }
    }
}

/// A slab test of a node's [`WIDTH`] child boxes against one segment,
/// prepared once per walk: [`slab_test`] in two groups of four lanes
/// everywhere, and the same arithmetic in one group of eight where the
/// processor has AVX (`avx`). Both give the same entries and mask, bit for
/// bit, so a walk never depends on which ran.
trait ChildBoxes {
    /// The parameters where the segment enters the child boxes of `node`,
    /// and a mask with bit `k` set where it meets child `k` before `limit`.
    fn test(&self, node: &WideNode, limit: f32) -> ([f32; WIDTH], u32);
}

impl ChildBoxes for Slabs {
    #[inline(always)]
    fn test(&self, node: &WideNode, limit: f32) -> ([f32; WIDTH], u32) {
        slab_test(node, self, limit)
    }
}

/// The parameters where the segment enters the child boxes of
/// `node`, and a mask with bit `k` set where it meets child `k` before
/// `limit`. Unused slots have an empty box (lower corner +inf, upper -inf),
/// which is entered at +inf: never met. A NaN parameter (the origin exactly
/// on a widened face while parallel to it) loses every `max` and `min`
/// below and so leaves that axis unconstrained: a hit costs a test, never
/// an answer.
#[inline(always)]
fn slab_test(node: &WideNode, slabs: &Slabs, limit: f32) -> ([f32; WIDTH], u32) {
    let mut entries = [0.0f32; WIDTH];
    let mut mask = 0;
    for group in 0..WIDTH / 4 {
        let lanes = 4 * group..4 * group + 4;
        let mut enter = Vec4::ZERO;
        let mut exit = Vec4::splat(limit);
        for axis in 0..3 {
            let faces = &node.bounds[axis];
            let down = usize::from(slabs.down[axis]);
            let near = Vec4::from_slice(&faces[down][lanes.clone()]);
            let far = Vec4::from_slice(&faces[1 - down][lanes.clone()]);
            let t_near = (near - slabs.o_near[axis]) * slabs.inv[axis];
            let t_far = (far - slabs.o_far[axis]) * slabs.inv[axis];
            enter = later(t_near, enter);
            exit = earlier(t_far, exit);
        }
        enter.write_to_slice(&mut entries[lanes]);
        mask |= enter.cmple(exit).bitmask() << (4 * group);
    }
    (entries, mask)
}

/// A segment prepared for [`ExactSlabs::meets`]: the slab test of one
/// child box in `f64`, against the segment itself rather than its `f32`
/// rounding widened by the walk's margin.
///
/// The walk's margin is wide (`QUERY_MARGIN`, about 6e-5 m at Sponza's
/// coordinates) next to how far the solver's segments stop short of their
/// end surfaces (a millionth of their length), so the `f32` test enters
/// every leaf at a segment's ends: the receiver's neighbours around the
/// vertex, the source's around its centre, which the exact test then
/// rejects at the cost of loading their planes. The `f64` test of the
/// leaf's box, whose round-off is some `1e-15` of the coordinates, culls
/// them first, four children at a time in `f64` lanes where the processor
/// has AVX (`avx`). Its margin covers that round-off and how far off the
/// segment the exact test's own arithmetic can accept a crossing, so it
/// never culls a box holding a surface the exact test accepts, and the
/// answers stay the exact test's.
pub(super) struct ExactSlabs {
    from: DVec3,
    inverse: DVec3,
    margin: f64,
}

impl ExactSlabs {
    /// The segment from `from` to `to`, every box widened by `margin`,
    /// which must cover the test's round-off (under `10 ε` of the largest
    /// coordinate of the segment and of the boxes it could meet) and the
    /// exact test's (tens of `ε` of it).
    pub(super) fn new(from: DVec3, to: DVec3, margin: f64) -> ExactSlabs {
        ExactSlabs {
            from,
            inverse: (to - from).recip(),
            margin,
        }
    }

    /// Whether the segment meets child `k` of `node`, widened by the
    /// margin. A NaN parameter (the origin on a widened face while parallel
    /// to it) leaves its axis unconstrained, as in the `f32` test.
    #[inline(always)]
    pub(super) fn meets(&self, node: &WideNode, k: usize) -> bool {
        let mut enter = 0.0f64;
        let mut exit = 1.0f64;
        for axis in 0..3 {
            let lower = f64::from(node.bounds[axis][0][k]) - self.margin;
            let upper = f64::from(node.bounds[axis][1][k]) + self.margin;
            let inverse = self.inverse[axis];
            let a = (lower - self.from[axis]) * inverse;
            let b = (upper - self.from[axis]) * inverse;
            let (near, far) = if inverse.is_sign_negative() {
                (b, a)
            } else {
                (a, b)
            };
            if near > enter {
                enter = near;
            }
            if far < exit {
                exit = far;
            }
        }
        enter <= exit
    }
}

/// The `f64` recheck of a node's leaf children ([`ExactSlabs::meets`]):
/// lane by lane in scalar code, or four lanes at a time with AVX (the same
/// operations, so the same mask).
trait LeafBoxes {
    /// `mask` with the bits of the children the segment misses cleared.
    fn keep(&self, node: &WideNode, mask: u32) -> u32;
}

impl LeafBoxes for ExactSlabs {
    #[inline(always)]
    fn keep(&self, node: &WideNode, mask: u32) -> u32 {
        let mut kept = mask;
        let mut bits = mask;
        while bits != 0 {
            let k = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            if !self.meets(node, k) {
                kept &= !(1 << k);
            }
        }
        kept
    }
}

/// `x > y ? x : y` lane by lane, so a NaN `x` gives `y` (not glam's `max`,
/// whose rule for NaN depends on the instruction set): SSE's `maxps` is
/// exactly this.
#[inline(always)]
fn later(x: Vec4, y: Vec4) -> Vec4 {
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: SSE is part of every x86-64 processor.
        Vec4::from(unsafe { std::arch::x86_64::_mm_max_ps(x.into(), y.into()) })
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        Vec4::select(x.cmpgt(y), x, y)
    }
}

/// `x < y ? x : y` lane by lane, so a NaN `x` gives `y` (SSE's `minps`).
#[inline(always)]
fn earlier(x: Vec4, y: Vec4) -> Vec4 {
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: SSE is part of every x86-64 processor.
        Vec4::from(unsafe { std::arch::x86_64::_mm_min_ps(x.into(), y.into()) })
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        Vec4::select(x.cmplt(y), x, y)
    }
}

/// Walks the wide tree for the segment between `ends`: every child box the
/// segment meets, widened by the first of `margins` ([`SegmentQuery`]'s),
/// is entered; the leaf children a node's segment meets, and the `f64`
/// recheck with the second ([`ExactSlabs`]') confirms, are offered to
/// `blocks` first, in slot order, each whole (its first primitive's
/// position in the leaf order and its count), then the interior children
/// nearer first. Returns the answer and the number of child boxes tested.
pub(super) fn wide_any_hit(
    nodes: &[WideNode],
    ends: (DVec3, DVec3),
    margins: (f64, f64),
    blocks: impl FnMut(u32, u32) -> bool,
) -> (bool, u32) {
    if nodes.is_empty() {
        return (false, 0);
    }
    #[cfg(target_arch = "x86_64")]
    if eight_lanes() {
        // SAFETY: the processor has AVX, checked by `eight_lanes`.
        return unsafe { avx::any_hit(nodes, ends, margins, blocks) };
    }
    let ((from, to), (margin, exact_margin)) = (ends, margins);
    let slabs = Slabs::new(&SegmentQuery::new(from, to, margin));
    let exact = ExactSlabs::new(from, to, exact_margin);
    any_hit_with(nodes, &slabs, &exact, blocks)
}

/// [`wide_any_hit`]'s walk, with the slab test `boxes`.
#[inline(always)]
fn any_hit_with(
    nodes: &[WideNode],
    boxes: &impl ChildBoxes,
    exact: &impl LeafBoxes,
    mut blocks: impl FnMut(u32, u32) -> bool,
) -> (bool, u32) {
    // Each node pushes at most WIDTH - 1 entries above its ancestors'.
    // Left uninitialised: zeroing it cost a `memset` of 1.8 kB per query,
    // and only entries below `top` are ever read.
    let mut stack = [MaybeUninit::<u32>::uninit(); STACK];
    let mut top = 0;
    let mut at = 0u32;
    let mut tested = 0u32;
    loop {
        let node = &nodes[at as usize];
        tested += WIDTH as u32;
        let (enter, hits) = boxes.test(node, 1.0);
        // Leaf children first: their tests may end the walk.
        let mut leaves = hits & node.leaves;
        if leaves != 0 {
            leaves = exact.keep(node, leaves);
        }
        while leaves != 0 {
            let k = leaves.trailing_zeros() as usize;
            leaves &= leaves - 1;
            if blocks(node.link[k], u32::from(node.count[k])) {
                return (true, tested);
            }
        }
        // Then the nearest interior child, walked next without a trip
        // through the stack; the others pushed farthest first.
        let interior = hits & !node.leaves;
        if interior == 0 {
            if top == 0 {
                return (false, tested);
            }
            top -= 1;
            // SAFETY: every entry below `top` was written by a push.
            at = unsafe { stack[top].assume_init() };
            continue;
        }
        let first = interior.trailing_zeros() as usize;
        let rest = interior & (interior - 1);
        if rest == 0 {
            at = node.link[first];
            continue;
        }
        let mut order = [0usize; WIDTH];
        let mut n = 0;
        let mut bits = interior;
        while bits != 0 {
            let k = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            // Insertion sort, farthest first.
            let mut i = n;
            while i > 0 && enter[order[i - 1]] < enter[k] {
                order[i] = order[i - 1];
                i -= 1;
            }
            order[i] = k;
            n += 1;
        }
        for &k in &order[..n - 1] {
            let link = node.link[k];
            prefetch(nodes, link);
            stack[top].write(link);
            top += 1;
        }
        at = node.link[order[n - 1]];
    }
}

/// `s` rounded up to `f32`: a box entered at or before `s` is entered at
/// or before it in `f32` too.
#[inline]
fn f32_at_least(s: f64) -> f32 {
    let rounded = s as f32;
    if f64::from(rounded) < s {
        rounded.next_up()
    } else {
        rounded
    }
}

/// Walks the wide tree front to back for the closest hit: the child boxes
/// the segment meets are taken in order of entry, and a box entered beyond
/// the limit is skipped, on the stack too. `offer(p)` tests the primitive
/// at leaf-order position `p` and returns the limit: the segment parameter
/// of the nearest crossing so far (1 while there is none), so the segment
/// shrinks as hits are found. A box entered exactly at the limit is still
/// entered, since a crossing there may win on its index. Returns the
/// number of child boxes tested.
pub(super) fn wide_closest_hit(
    nodes: &[WideNode],
    ends: (DVec3, DVec3),
    margin: f64,
    offer: impl FnMut(u32) -> f64,
) -> u32 {
    if nodes.is_empty() {
        return 0;
    }
    #[cfg(target_arch = "x86_64")]
    if eight_lanes() {
        // SAFETY: the processor has AVX, checked by `eight_lanes`.
        return unsafe { avx::closest_hit(nodes, ends, margin, offer) };
    }
    let slabs = Slabs::new(&SegmentQuery::new(ends.0, ends.1, margin));
    closest_hit_with(nodes, &slabs, offer)
}

/// [`wide_closest_hit`]'s walk, with the slab test `boxes`.
#[inline(always)]
fn closest_hit_with(
    nodes: &[WideNode],
    boxes: &impl ChildBoxes,
    mut offer: impl FnMut(u32) -> f64,
) -> u32 {
    // Each node pushes at most WIDTH - 1 entries above its ancestors',
    // each with the parameter where its box is entered.
    let mut stack = [MaybeUninit::<(u32, f32)>::uninit(); STACK];
    let mut top = 0;
    let mut at = 0u32;
    let mut limit = 1.0f32;
    let mut tested = 0u32;
    loop {
        let node = &nodes[at as usize];
        tested += WIDTH as u32;
        // As in `wide_any_hit`, but the segment ends at the limit.
        let (enter, mut mask) = boxes.test(node, limit);
        let mut order = [0usize; WIDTH];
        let mut hits = 0;
        while mask != 0 {
            let k = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            let mut i = hits;
            while i > 0 && enter[order[i - 1]] > enter[k] {
                order[i] = order[i - 1];
                i -= 1;
            }
            order[i] = k;
            hits += 1;
        }
        // Leaf children in order of entry, each while it can still hold
        // the answer (a hit lowers the limit); then the nearest interior
        // child still within the limit is walked next, the others pushed
        // farthest first.
        for &k in &order[..hits] {
            let count = u32::from(node.count[k]);
            if count > 0 && enter[k] <= limit {
                let first = node.link[k];
                for p in first..first + count {
                    limit = f32_at_least(offer(p));
                }
            }
        }
        let mut next: Option<(u32, f32)> = None;
        for &k in order[..hits].iter().rev() {
            if node.count[k] > 0 || enter[k] > limit {
                continue;
            }
            if let Some(farther) = next {
                prefetch(nodes, farther.0);
                stack[top].write(farther);
                top += 1;
            }
            next = Some((node.link[k], enter[k]));
        }
        if let Some((link, _)) = next {
            at = link;
            continue;
        }
        // The nearest pending box still within the limit.
        loop {
            if top == 0 {
                return tested;
            }
            top -= 1;
            // SAFETY: every entry below `top` was written by a push.
            let (node, entered) = unsafe { stack[top].assume_init() };
            if entered <= limit {
                at = node;
                break;
            }
        }
    }
}

/// The walks compiled for AVX (`traverse/avx.rs`).
#[cfg(target_arch = "x86_64")]
mod avx;

#[cfg(test)]
mod tests {
    use super::*;

    /// The eight-lane test gives the four-lane test's entries and mask bit
    /// for bit: random boxes (some empty, some flat, some with a face on
    /// the segment's origin) against random segments (some parallel to an
    /// axis, some with zero or negative-zero components), with limits below,
    /// at and above 1. So does the `f64` recheck of leaf children four lanes
    /// at a time against the scalar one, with and without a margin (without,
    /// faces on the origin give the NaN parameters).
    #[test]
    #[cfg(target_arch = "x86_64")]
    fn eight_lanes_test_boxes_as_two_groups_of_four() {
        if !std::arch::is_x86_feature_detected!("avx") {
            eprintln!("did not run: this processor has no AVX, so no eight-lane test to compare");
            return;
        }
        let mut next = crate::accel::test_scenes::xorshift(0x9e37_79b9_7f4a_7c15);
        let coordinate = |next: &mut dyn FnMut() -> u64| match next() % 8 {
            0 => 0.0,
            1 => -0.0,
            2 => 1.0,
            _ => (next() >> 11) as f64 / (1u64 << 53) as f64 * 4.0 - 2.0,
        };
        let mut compared = 0;
        for _ in 0..20_000 {
            let from = DVec3::new(
                coordinate(&mut next),
                coordinate(&mut next),
                coordinate(&mut next),
            );
            let to = DVec3::new(
                coordinate(&mut next),
                coordinate(&mut next),
                coordinate(&mut next),
            );
            let query = SegmentQuery::new(from, to, 1e-6);
            let slabs = Slabs::new(&query);
            let eight = avx::Slabs8::for_tests(&slabs);
            let mut node = WideNode::UNUSED;
            for k in 0..WIDTH {
                if next().is_multiple_of(6) {
                    continue; // an empty slot
                }
                for axis in 0..3 {
                    // Some faces where the segment's widened origin is: a
                    // parameter 0 * inf = NaN where it runs parallel.
                    let face = |next: &mut dyn FnMut() -> u64| match next() % 6 {
                        0 => slabs.o_near[axis].x,
                        1 => slabs.o_far[axis].x,
                        _ => coordinate(next) as f32,
                    };
                    let a = face(&mut next);
                    let b = if next().is_multiple_of(5) {
                        a
                    } else {
                        face(&mut next)
                    };
                    node.bounds[axis][0][k] = a.min(b);
                    node.bounds[axis][1][k] = a.max(b);
                }
            }
            for margin in [0.0, 1e-9] {
                let exact = ExactSlabs::new(from, to, margin);
                // SAFETY: the processor has AVX, checked above.
                let exact8 = unsafe { avx::Exact8::new(&exact) };
                let mask = (next() % 256) as u32;
                assert_eq!(
                    exact.keep(&node, mask),
                    exact8.keep(&node, mask),
                    "{node:?} {from} {to} {margin} {mask:b}"
                );
            }
            for limit in [0.5f32, 1.0, 2.0] {
                let (entries4, mask4) = slabs.test(&node, limit);
                let (entries8, mask8) = eight.test(&node, limit);
                assert_eq!(mask4, mask8, "{node:?} {from} {to} {limit}");
                assert_eq!(entries4.map(f32::to_bits), entries8.map(f32::to_bits));
                compared += 1;
            }
        }
        assert_eq!(compared, 60_000);
    }

    #[test]
    fn limits_round_up_to_f32() {
        for s in [
            0.0,
            1.0,
            0.1,
            1.0 / 3.0,
            0.999_999_999_9,
            1e-30,
            0.5 + 1e-12,
        ] {
            let limit = f32_at_least(s);
            assert!(f64::from(limit) >= s, "{s}");
            assert!(f64::from(limit.next_down()) < s, "{s}");
        }
    }
}
