//! The BVH's traversal: the segment prepared for the slab test, the
//! four-wide layout the binary tree is collapsed into (Dammertz et al. 2008;
//! Wald et al. 2008), its depth-first any-hit walk for shadow segments and
//! its front-to-back closest-hit walk, which shrinks the segment as hits
//! are found.

use super::*;

/// A segment `origin + t * direction`, `t` in `[0, 1]`, prepared for `f32`
/// slab tests, its origin pushed out by the round-off margin: lower planes
/// are met from `origin + margin`, upper planes from `origin - margin`,
/// which widens every box by the margin at no cost per node. The boxes are
/// `f32` so four of them fit one SIMD register per coordinate.
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

/// Children per node of the traversed tree.
pub(super) const WIDTH: usize = 4;

/// No child in a slot.
pub(super) const EMPTY_SLOT: u32 = u32::MAX;

/// A node of the four-wide tree the queries walk: the boxes of up to four
/// children side by side, one array per coordinate (structure of arrays),
/// so one pass of four-lane arithmetic tests them all (Dammertz et al.
/// 2008, "Shallow bounding volume hierarchies"; Wald et al. 2008, "Getting
/// rid of packets"). 128 bytes: two cache lines.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub(super) struct WideNode {
    /// Lower corners: `min[axis][child]`.
    pub(super) min: [[f32; WIDTH]; 3],
    /// Upper corners.
    pub(super) max: [[f32; WIDTH]; 3],
    /// Interior child: its node index. Leaf child: its first primitive.
    /// [`EMPTY_SLOT`] for no child.
    pub(super) link: [u32; WIDTH],
    /// Primitives of a leaf child; 0 for an interior child or no child.
    pub(super) count: [u32; WIDTH],
}

impl WideNode {
    pub(super) const UNUSED: WideNode = WideNode {
        min: [[f32::INFINITY; WIDTH]; 3],
        max: [[f32::NEG_INFINITY; WIDTH]; 3],
        link: [EMPTY_SLOT; WIDTH],
        count: [0; WIDTH],
    };
}

/// The binary tree collapsed into a four-wide one: each wide node takes the
/// place of a binary node and holds up to four of its descendants, found by
/// opening the child of largest surface area until there are four (the
/// usual collapse of a binary SAH tree; the boxes are the binary nodes'
/// own, so every box still contains what is below it).
pub(super) fn collapse(tree: &Tree) -> Vec<WideNode> {
    if tree.nodes.is_empty() {
        return Vec::new();
    }
    let mut wide = Vec::with_capacity(tree.nodes.len() / 2 + 1);
    collapse_node(tree, 0, &mut wide);
    wide
}

pub(super) fn half_area_of(node: &Node) -> f32 {
    let d = [0, 1, 2].map(|i| node.max[i] - node.min[i]);
    let area = d[0] * d[1] + d[1] * d[2] + d[2] * d[0];
    if area.is_nan() { f32::INFINITY } else { area }
}

/// Collapses the subtree of binary node `at` into wide nodes; returns the
/// index of its wide node.
pub(super) fn collapse_node(tree: &Tree, at: u32, wide: &mut Vec<WideNode>) -> u32 {
    let index = wide.len() as u32;
    wide.push(WideNode::UNUSED);
    let node = &tree.nodes[at as usize];
    let mut children: Vec<u32> = if node.is_leaf() {
        vec![at]
    } else {
        vec![at + 1, node.link]
    };
    while children.len() < WIDTH {
        let open = children
            .iter()
            .enumerate()
            .filter(|(_, c)| !tree.nodes[**c as usize].is_leaf())
            .max_by(|a, b| {
                half_area_of(&tree.nodes[*a.1 as usize])
                    .total_cmp(&half_area_of(&tree.nodes[*b.1 as usize]))
            })
            .map(|(i, _)| i);
        let Some(i) = open else { break };
        let c = children[i];
        let right = tree.nodes[c as usize].link;
        children[i] = c + 1;
        children.insert(i + 1, right);
    }
    let mut out = WideNode::UNUSED;
    for (slot, &c) in children.iter().enumerate() {
        let child = tree.nodes[c as usize];
        for axis in 0..3 {
            out.min[axis][slot] = child.min[axis];
            out.max[axis][slot] = child.max[axis];
        }
        if child.is_leaf() {
            out.link[slot] = child.link;
            out.count[slot] = child.kind;
        } else {
            out.link[slot] = collapse_node(tree, c, wide);
        }
    }
    wide[index as usize] = out;
    index
}

/// Asks the processor to start loading a node about to be visited (the
/// walk is bound by memory latency on large scenes); a no-op elsewhere.
#[inline]
pub(super) fn prefetch(nodes: &[WideNode], index: u32) {
    #[cfg(target_arch = "x86_64")]
    if let Some(node) = nodes.get(index as usize) {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let p = std::ptr::from_ref(node).cast::<i8>();
        // SAFETY: prefetching is a hint: it never faults, and `p` and
        // `p + 64` lie within the node (128 bytes).
        unsafe {
            _mm_prefetch::<_MM_HINT_T0>(p);
            _mm_prefetch::<_MM_HINT_T0>(p.add(64));
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (nodes, index);
}

/// Walks the wide tree: every child box the segment meets is entered,
/// nearer first; the primitives of a leaf child are offered to `blocks` at
/// once, by position in the leaf order. Returns the answer and the number
/// of child boxes tested.
pub(super) fn wide_any_hit(
    nodes: &[WideNode],
    query: &SegmentQuery,
    mut blocks: impl FnMut(u32) -> bool,
) -> (bool, u32) {
    if nodes.is_empty() {
        return (false, 0);
    }
    // Each node pushes at most WIDTH - 1 entries above its ancestors'.
    let mut stack = [0u32; (WIDTH - 1) * MAX_DEPTH + 1];
    let mut top = 0;
    let mut at = 0u32;
    let mut tested = 0u32;
    let o_min = query.origin_for_min.to_array();
    let o_max = query.origin_for_max.to_array();
    let inv = query.inverse_direction.to_array();
    // Per axis, which face the segment meets first: the lower one unless
    // it runs towards lower coordinates (`1 / -0` counts as running down,
    // as its infinite parameter does). Lower faces are met from the origin
    // moved up by the margin and upper faces from it moved down, so
    // choosing the face once per segment keeps the widening.
    let negative = inv.map(f32::is_sign_negative);
    let o_near = [0, 1, 2].map(|a| if negative[a] { o_max[a] } else { o_min[a] });
    let o_far = [0, 1, 2].map(|a| if negative[a] { o_min[a] } else { o_max[a] });
    loop {
        let node = &nodes[at as usize];
        tested += WIDTH as u32;
        // Unused slots have an empty box (lower corner +inf, upper -inf),
        // which enters at +inf: never hit. A NaN parameter (the origin
        // exactly on a widened face while parallel to it) fails the
        // comparisons and so leaves that axis unconstrained: a hit costs a
        // test, never an answer.
        let mut enter = [0.0f32; WIDTH];
        let mut exit = [1.0f32; WIDTH];
        for axis in 0..3 {
            let (near, far) = if negative[axis] {
                (&node.max[axis], &node.min[axis])
            } else {
                (&node.min[axis], &node.max[axis])
            };
            for k in 0..WIDTH {
                let t_near = (near[k] - o_near[axis]) * inv[axis];
                let t_far = (far[k] - o_far[axis]) * inv[axis];
                enter[k] = if t_near > enter[k] { t_near } else { enter[k] };
                exit[k] = if t_far < exit[k] { t_far } else { exit[k] };
            }
        }
        // Hit children, nearest first (insertion sort of at most four).
        let mut order = [0usize; WIDTH];
        let mut hits = 0;
        for k in 0..WIDTH {
            if enter[k] <= exit[k] {
                let mut i = hits;
                while i > 0 && enter[order[i - 1]] > enter[k] {
                    order[i] = order[i - 1];
                    i -= 1;
                }
                order[i] = k;
                hits += 1;
            }
        }
        // Leaf children first (their tests may end the walk), then the
        // nearest interior child is walked next without a trip through the
        // stack, the others pushed farthest first.
        let mut next = EMPTY_SLOT;
        for &k in &order[..hits] {
            let count = node.count[k];
            if count > 0 {
                let first = node.link[k];
                for p in first..first + count {
                    if blocks(p) {
                        return (true, tested);
                    }
                }
            } else if next == EMPTY_SLOT {
                next = node.link[k];
            }
        }
        if next != EMPTY_SLOT {
            for &k in order[..hits].iter().rev() {
                let link = node.link[k];
                if node.count[k] == 0 && link != next {
                    prefetch(nodes, link);
                    stack[top] = link;
                    top += 1;
                }
            }
            at = next;
            continue;
        }
        if top == 0 {
            return (false, tested);
        }
        top -= 1;
        at = stack[top];
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
    query: &SegmentQuery,
    mut offer: impl FnMut(u32) -> f64,
) -> u32 {
    if nodes.is_empty() {
        return 0;
    }
    // Each node pushes at most WIDTH - 1 entries above its ancestors',
    // each with the parameter where its box is entered.
    let mut stack = [(0u32, 0.0f32); (WIDTH - 1) * MAX_DEPTH + 1];
    let mut top = 0;
    let mut at = 0u32;
    let mut limit = 1.0f32;
    let mut tested = 0u32;
    let o_min = query.origin_for_min.to_array();
    let o_max = query.origin_for_max.to_array();
    let inv = query.inverse_direction.to_array();
    // The faces met first and last per axis, as in `wide_any_hit`.
    let negative = inv.map(f32::is_sign_negative);
    let o_near = [0, 1, 2].map(|a| if negative[a] { o_max[a] } else { o_min[a] });
    let o_far = [0, 1, 2].map(|a| if negative[a] { o_min[a] } else { o_max[a] });
    loop {
        let node = &nodes[at as usize];
        tested += WIDTH as u32;
        // As in `wide_any_hit`, but the segment ends at the limit.
        let mut enter = [0.0f32; WIDTH];
        let mut exit = [limit; WIDTH];
        for axis in 0..3 {
            let (near, far) = if negative[axis] {
                (&node.max[axis], &node.min[axis])
            } else {
                (&node.min[axis], &node.max[axis])
            };
            for k in 0..WIDTH {
                let t_near = (near[k] - o_near[axis]) * inv[axis];
                let t_far = (far[k] - o_far[axis]) * inv[axis];
                enter[k] = if t_near > enter[k] { t_near } else { enter[k] };
                exit[k] = if t_far < exit[k] { t_far } else { exit[k] };
            }
        }
        let mut order = [0usize; WIDTH];
        let mut hits = 0;
        for k in 0..WIDTH {
            if enter[k] <= exit[k] {
                let mut i = hits;
                while i > 0 && enter[order[i - 1]] > enter[k] {
                    order[i] = order[i - 1];
                    i -= 1;
                }
                order[i] = k;
                hits += 1;
            }
        }
        // Leaf children in order of entry, each while it can still hold
        // the answer (a hit lowers the limit); then the nearest interior
        // child still within the limit is walked next, the others pushed
        // farthest first.
        for &k in &order[..hits] {
            let count = node.count[k];
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
                stack[top] = farther;
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
            let (node, entered) = stack[top];
            if entered <= limit {
                at = node;
                break;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::f32_at_least;

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
