//! Bounding-volume-hierarchy visibility (design.md section 3, "beyond the
//! paper"): the modern answer to shadow rays, kept beside the BSP so the two
//! can be compared honestly.
//!
//! The tree is a binary BVH over one axis-aligned box per surface, built top
//! down with the surface area heuristic (Goldsmith & Salmon 1987; MacDonald
//! & Booth 1990) evaluated on a fixed number of centroid bins per axis
//! (Wald 2007, "On fast construction of SAH-based bounding volume
//! hierarchies"), then collapsed into a four-wide tree (Dammertz et al.
//! 2008; Wald et al. 2008) whose four child boxes are tested at once. A
//! shadow segment walks it depth first, nearer children first, and stops at
//! the first blocker (an any-hit query).
//!
//! The file is in sections, one concern each: settings; the flattened
//! layout; the build; the traversal (the segment prepared for it); the
//! wide layout and its walk; `validate`; the conservative box of a surface;
//! and [`Bvh`], which ties the tree to the scene. The tree itself
//! knows primitive indices, never geometry: the build takes boxes, the
//! traversal takes a closure deciding whether primitive `i` blocks.
//!
//! # Agreement with the brute-force oracle
//!
//! Boxes only cull. The blocking decision is always [`segment_crosses`](super::segment_crosses) on
//! the original surface, so an answer can only differ from
//! [`BruteForce`](super::brute::BruteForce) if the walk fails to offer a
//! surface the segment crosses. It cannot, because every box is
//! conservative:
//!
//! * `segment_crosses` accepts a crossing point on the surface's plane up to
//!   `1e-9 sqrt(area)` outside each edge line (further beyond a sharp corner,
//!   and a non-planar polygon's edges are measured in 3-D). A surface's box
//!   is the box of that tolerance region, computed exactly in the plane with
//!   four times the tolerance (`crossing_box`), joined with its corners'
//!   box. A degenerate polygon whose region is unbounded gets an infinite
//!   box: always tested, slow but exact.
//! * Node boxes are unions of these, rounded outward to `f32`, so every node
//!   contains its children and its surfaces exactly.
//! * The query runs in `f32` with the segment's origin pushed out by a margin
//!   of `QUERY_MARGIN` (2e-6) times the larger of the query's and the scene's
//!   largest coordinate. A slab test in `f32` computes the exact entry and
//!   exit parameters of a plane moved by at most `3u |b - o|` (`u` = 2^-24),
//!   and rounding the segment to `f32` moves it by at most `3u` of its
//!   largest coordinate: together under `9u ≈ 5.4e-7` of that scale, which
//!   the margin covers almost four times. Queries whose coordinates do not
//!   fit `f32` comfortably test every surface instead.
//!
//! # Layout
//!
//! The binary tree's nodes live in one `Vec` in depth-first order: an
//! interior node's left child is the next node, its right child is stored
//! by index. A node is 32 bytes: an `f32` box, a link (right child or first
//! primitive) and a word that is either the leaf's primitive count or the
//! interior node's split axis. Leaves' primitives are ranges of one
//! `Vec<u32>` of surface ids. The four-wide nodes the queries walk are 128
//! bytes (two cache lines), the four boxes coordinate by coordinate; the
//! walk prefetches a node when it pushes it, since on scenes of a hundred
//! thousand triangles it waits on memory more than it computes. The
//! surfaces' prepared planes and edges are stored in leaf order, so a
//! leaf's tests read adjacent memory; the skip rule compares surface ids,
//! in one closure. Queries use a fixed stack: no allocation, no interior
//! mutability, any number of threads.

use glam::{DVec3, Vec3A};

use super::{AcceptanceRegion, Occluder, PreparedSurfaces};
use crate::scene::Surface;

// ------------------------------------------------------------------ settings

/// The deepest a tree may grow, and the size of the query stack. Below depth
/// `MAX_DEPTH - 32` every split halves its node, so fewer than 2^32 surfaces
/// always fit.
pub const MAX_DEPTH: usize = 64;

/// Nodes at this depth or deeper split at the median, which bounds the depth
/// by [`MAX_DEPTH`] whatever the heuristic would have done.
const MEDIAN_FROM_DEPTH: usize = MAX_DEPTH - 32;

/// Largest accepted bin count.
pub const MAX_BINS: usize = 256;

/// Largest accepted leaf size.
pub const MAX_LEAF_SIZE: usize = 64;

/// How a node's surfaces are divided between its two children.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SplitMethod {
    /// The cheapest split by the surface area heuristic among the bin
    /// boundaries of every axis (Wald 2007).
    BinnedSah,
    /// Half the surfaces on each side, by centroid along the axis of widest
    /// centroid spread: cheapest to build, no cost model.
    ObjectMedian,
}

/// How the tree is built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhSettings {
    /// How nodes are split.
    pub split: SplitMethod,
    /// Centroid bins per axis for [`SplitMethod::BinnedSah`], `2..=MAX_BINS`.
    pub bins: usize,
    /// A node with at most this many surfaces is always a leaf.
    pub leaf_size: usize,
    /// A node with more surfaces than this is always split, even when the
    /// heuristic prefers a leaf; `leaf_size..=MAX_LEAF_SIZE`.
    pub max_leaf_size: usize,
    /// Cost of visiting a node (one box test), for the heuristic.
    pub traversal_cost: f64,
    /// Cost of testing one surface, in the same units.
    pub primitive_cost: f64,
}

impl BvhSettings {
    /// The default: binned SAH with 16 bins, leaves of up to 2 surfaces
    /// always and up to 8 when splitting would not pay, a surface test
    /// costing two box tests (about their ratio in instructions on the
    /// built-in room; the tree's speed there varies little between 1 and 4).
    #[must_use]
    pub fn sah() -> BvhSettings {
        BvhSettings {
            split: SplitMethod::BinnedSah,
            bins: 16,
            leaf_size: 2,
            max_leaf_size: 8,
            traversal_cost: 1.0,
            primitive_cost: 2.0,
        }
    }

    /// Object-median splits down to leaves of at most 4 surfaces: the
    /// fastest build, usually a slower tree.
    #[must_use]
    pub fn median() -> BvhSettings {
        BvhSettings {
            split: SplitMethod::ObjectMedian,
            leaf_size: 4,
            max_leaf_size: 4,
            ..BvhSettings::sah()
        }
    }

    /// Every preset with its name, for tests and benchmarks.
    #[must_use]
    pub fn presets() -> [(&'static str, BvhSettings); 2] {
        [
            ("sah", BvhSettings::sah()),
            ("median", BvhSettings::median()),
        ]
    }

    /// The settings with out-of-range values replaced: bins clamped to
    /// `2..=MAX_BINS`, `leaf_size` to `1..=MAX_LEAF_SIZE`, `max_leaf_size`
    /// to `leaf_size..=MAX_LEAF_SIZE`; a non-positive or non-finite cost
    /// takes the default.
    #[must_use]
    pub fn sanitized(self) -> BvhSettings {
        let default = BvhSettings::sah();
        let cost = |v: f64, d: f64| if v.is_finite() && v > 0.0 { v } else { d };
        let leaf_size = self.leaf_size.clamp(1, MAX_LEAF_SIZE);
        BvhSettings {
            split: self.split,
            bins: self.bins.clamp(2, MAX_BINS),
            leaf_size,
            max_leaf_size: self.max_leaf_size.clamp(leaf_size, MAX_LEAF_SIZE),
            traversal_cost: cost(self.traversal_cost, default.traversal_cost),
            primitive_cost: cost(self.primitive_cost, default.primitive_cost),
        }
    }
}

impl Default for BvhSettings {
    fn default() -> Self {
        BvhSettings::sah()
    }
}

/// Size of a built tree.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct BvhStats {
    /// Nodes, leaves included.
    pub nodes: usize,
    /// Leaves.
    pub leaves: usize,
    /// Nodes on the longest root-to-leaf path (0 for an empty tree).
    pub depth: usize,
    /// Surfaces in the largest leaf.
    pub max_leaf_size: usize,
    /// Nodes of the four-wide tree the queries walk.
    pub wide_nodes: usize,
}

// -------------------------------------------------------------------- layout

/// An axis-aligned box in `f64`, as the build sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Aabb {
    min: DVec3,
    max: DVec3,
}

impl Aabb {
    const EMPTY: Aabb = Aabb {
        min: DVec3::INFINITY,
        max: DVec3::NEG_INFINITY,
    };

    const EVERYWHERE: Aabb = Aabb {
        min: DVec3::NEG_INFINITY,
        max: DVec3::INFINITY,
    };

    fn of_points(points: impl IntoIterator<Item = DVec3>) -> Aabb {
        points.into_iter().fold(Aabb::EMPTY, |b, p| Aabb {
            min: b.min.min(p),
            max: b.max.max(p),
        })
    }

    fn union(self, other: Aabb) -> Aabb {
        Aabb {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    fn centre(self) -> DVec3 {
        0.5 * (self.min + self.max)
    }

    /// Half the surface area (the heuristic only compares ratios); 0 for an
    /// empty box.
    fn half_area(self) -> f64 {
        let d = self.max - self.min;
        if d.min_element() < 0.0 {
            return 0.0;
        }
        d.x * d.y + d.y * d.z + d.z * d.x
    }
}

/// Marks a node's `kind` word as an interior node (the low bits hold the
/// split axis); a leaf's `kind` is its primitive count.
const INTERIOR: u32 = 1 << 31;

/// One node: an `f32` box rounded outward, 32 bytes.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Node {
    min: [f32; 3],
    /// Interior: index of the right child. Leaf: first primitive.
    link: u32,
    max: [f32; 3],
    /// Interior: [`INTERIOR`] | split axis. Leaf: primitive count (>= 1).
    kind: u32,
}

impl Node {
    fn new(bounds: Aabb, link: u32, kind: u32) -> Node {
        let (min, max) = round_outward(bounds);
        Node {
            min,
            link,
            max,
            kind,
        }
    }

    fn is_leaf(&self) -> bool {
        self.kind & INTERIOR == 0
    }

    /// The split axis of an interior node.
    fn axis(&self) -> usize {
        (self.kind & !INTERIOR) as usize
    }

    /// The primitive range of a leaf.
    fn primitives(&self) -> std::ops::Range<usize> {
        self.link as usize..self.link as usize + self.kind as usize
    }

    fn contains(&self, other: &Node) -> bool {
        (0..3).all(|i| self.min[i] <= other.min[i] && self.max[i] >= other.max[i])
    }
}

/// The smallest `f32` box containing `b`.
fn round_outward(b: Aabb) -> ([f32; 3], [f32; 3]) {
    let down = |v: f64| {
        let r = v as f32;
        if f64::from(r) > v { r.next_down() } else { r }
    };
    let up = |v: f64| {
        let r = v as f32;
        if f64::from(r) < v { r.next_up() } else { r }
    };
    (
        [down(b.min.x), down(b.min.y), down(b.min.z)],
        [up(b.max.x), up(b.max.y), up(b.max.z)],
    )
}

/// The hierarchy over primitive indices.
#[derive(Clone, Debug, Default)]
struct Tree {
    /// Depth first; the root is node 0 (none for no primitives).
    nodes: Vec<Node>,
    /// Primitive ids, leaf by leaf in depth-first order.
    primitives: Vec<u32>,
}

// --------------------------------------------------------------------- build

/// What the build knows about the primitives: their boxes and centroids.
struct Builder<'s> {
    boxes: &'s [Aabb],
    centroids: Vec<DVec3>,
    settings: BvhSettings,
}

/// How a node is divided.
enum Decision {
    Leaf,
    /// Primitives `first..mid` go left (reordered already), `mid..end` right.
    Split {
        axis: usize,
        mid: usize,
    },
}

impl Tree {
    /// Builds the tree over `boxes` (primitive `i` has box `boxes[i]`).
    fn build(boxes: &[Aabb], settings: BvhSettings) -> (Tree, BvhStats) {
        let mut tree = Tree {
            nodes: Vec::with_capacity(2 * boxes.len()),
            primitives: (0..boxes.len() as u32).collect(),
        };
        let mut stats = BvhStats::default();
        if boxes.is_empty() {
            return (tree, stats);
        }
        let builder = Builder {
            boxes,
            // Centroids of the finite part of each box, so an infinite box
            // still bins somewhere.
            centroids: boxes
                .iter()
                .map(|b| {
                    let c = b.centre();
                    if c.is_finite() { c } else { DVec3::ZERO }
                })
                .collect(),
            settings,
        };
        tree.build_node(&builder, 0, boxes.len(), 1, &mut stats);
        stats.nodes = tree.nodes.len();
        (tree, stats)
    }

    /// Builds the subtree over `primitives[first..end]` at `depth` (root =
    /// 1), returning its index.
    fn build_node(
        &mut self,
        builder: &Builder,
        first: usize,
        end: usize,
        depth: usize,
        stats: &mut BvhStats,
    ) -> u32 {
        let index = self.nodes.len() as u32;
        stats.depth = stats.depth.max(depth);
        let bounds = self.primitives[first..end]
            .iter()
            .fold(Aabb::EMPTY, |b, &p| b.union(builder.boxes[p as usize]));
        let placeholder = Node::new(bounds, 0, 0);
        self.nodes.push(placeholder);
        match self.decide(builder, bounds, first, end, depth) {
            Decision::Leaf => {
                let count = end - first;
                stats.leaves += 1;
                stats.max_leaf_size = stats.max_leaf_size.max(count);
                self.nodes[index as usize] = Node::new(bounds, first as u32, count as u32);
            }
            Decision::Split { axis, mid } => {
                self.build_node(builder, first, mid, depth + 1, stats);
                let right = self.build_node(builder, mid, end, depth + 1, stats);
                self.nodes[index as usize] = Node::new(bounds, right, INTERIOR | axis as u32);
            }
        }
        index
    }

    fn decide(
        &mut self,
        builder: &Builder,
        bounds: Aabb,
        first: usize,
        end: usize,
        depth: usize,
    ) -> Decision {
        let settings = &builder.settings;
        let count = end - first;
        if count <= settings.leaf_size {
            return Decision::Leaf;
        }
        if settings.split == SplitMethod::ObjectMedian || depth >= MEDIAN_FROM_DEPTH {
            return self.median_split(builder, first, end);
        }
        match self.best_sah_split(builder, bounds, first, end) {
            Some((cost, axis, bin)) => {
                let leaf_cost = settings.primitive_cost * count as f64;
                if cost >= leaf_cost && count <= settings.max_leaf_size {
                    return Decision::Leaf;
                }
                let (lo, scale) = self.bin_mapping(builder, first, end, axis);
                let slice = &mut self.primitives[first..end];
                let left = partition(slice, |&p| {
                    bin_of(
                        builder.centroids[p as usize][axis],
                        lo,
                        scale,
                        settings.bins,
                    ) <= bin
                });
                Decision::Split {
                    axis,
                    mid: first + left,
                }
            }
            // Coincident centroids or boxes without a finite area: the
            // heuristic cannot choose.
            None if count <= settings.max_leaf_size => Decision::Leaf,
            None => self.median_split(builder, first, end),
        }
    }

    /// Half the primitives on each side, by centroid along the axis of
    /// widest centroid spread (ties by index, so the split is
    /// deterministic); simply halves the range when all centroids coincide.
    fn median_split(&mut self, builder: &Builder, first: usize, end: usize) -> Decision {
        let (lo, hi) = centroid_bounds(builder, &self.primitives[first..end]);
        let spread = hi - lo;
        let axis = if spread.x >= spread.y && spread.x >= spread.z {
            0
        } else if spread.y >= spread.z {
            1
        } else {
            2
        };
        let half = (end - first) / 2;
        if spread[axis] > 0.0 {
            let c = &builder.centroids;
            self.primitives[first..end].select_nth_unstable_by(half, |&a, &b| {
                c[a as usize][axis]
                    .total_cmp(&c[b as usize][axis])
                    .then(a.cmp(&b))
            });
        }
        Decision::Split {
            axis,
            mid: first + half,
        }
    }

    /// Lowest centroid and bins per unit length along `axis`.
    fn bin_mapping(&self, builder: &Builder, first: usize, end: usize, axis: usize) -> (f64, f64) {
        let (lo, hi) = centroid_bounds(builder, &self.primitives[first..end]);
        (
            lo[axis],
            builder.settings.bins as f64 / (hi[axis] - lo[axis]),
        )
    }

    /// The cheapest bin boundary over all axes: `(cost, axis, last bin on
    /// the left)`, or `None` when no axis has a spread of centroids or no
    /// split has a finite cost. The cost is the surface area heuristic,
    /// `traversal + primitive * (A_left N_left + A_right N_right) / A`.
    fn best_sah_split(
        &self,
        builder: &Builder,
        bounds: Aabb,
        first: usize,
        end: usize,
    ) -> Option<(f64, usize, usize)> {
        let settings = &builder.settings;
        let area = bounds.half_area();
        if !(area.is_finite() && area > 0.0) {
            return None;
        }
        let primitives = &self.primitives[first..end];
        let (lo, hi) = centroid_bounds(builder, primitives);
        let bins = settings.bins;
        let mut best: Option<(f64, usize, usize)> = None;
        let mut bin_box = [Aabb::EMPTY; MAX_BINS];
        let mut bin_count = [0usize; MAX_BINS];
        let mut right_area = [0.0f64; MAX_BINS];
        for axis in 0..3 {
            let spread = hi[axis] - lo[axis];
            if !(spread > 0.0 && spread.is_finite()) {
                continue;
            }
            let scale = bins as f64 / spread;
            bin_box[..bins].fill(Aabb::EMPTY);
            bin_count[..bins].fill(0);
            for &p in primitives {
                let b = bin_of(builder.centroids[p as usize][axis], lo[axis], scale, bins);
                bin_box[b] = bin_box[b].union(builder.boxes[p as usize]);
                bin_count[b] += 1;
            }
            // Sweep from the right: right_area[b] covers bins b + 1 ..
            let mut acc = Aabb::EMPTY;
            for b in (0..bins - 1).rev() {
                acc = acc.union(bin_box[b + 1]);
                right_area[b] = acc.half_area();
            }
            let mut left = Aabb::EMPTY;
            let mut left_count = 0;
            for b in 0..bins - 1 {
                left = left.union(bin_box[b]);
                left_count += bin_count[b];
                let right_count = primitives.len() - left_count;
                if left_count == 0 || right_count == 0 {
                    continue;
                }
                let cost = settings.traversal_cost
                    + settings.primitive_cost
                        * (left.half_area() * left_count as f64
                            + right_area[b] * right_count as f64)
                        / area;
                if cost.is_finite() && best.is_none_or(|(c, _, _)| cost < c) {
                    best = Some((cost, axis, b));
                }
            }
        }
        best
    }
}

/// The bin of centroid coordinate `c`; the lowest centroid is in bin 0 and
/// the highest in the last.
fn bin_of(c: f64, lo: f64, scale: f64, bins: usize) -> usize {
    (((c - lo) * scale) as usize).min(bins - 1)
}

fn centroid_bounds(builder: &Builder, primitives: &[u32]) -> (DVec3, DVec3) {
    let b = Aabb::of_points(primitives.iter().map(|&p| builder.centroids[p as usize]));
    (b.min, b.max)
}

/// Moves the elements satisfying `left` to the front; returns how many.
fn partition(slice: &mut [u32], left: impl Fn(&u32) -> bool) -> usize {
    let mut count = 0;
    for i in 0..slice.len() {
        if left(&slice[i]) {
            slice.swap(i, count);
            count += 1;
        }
    }
    count
}

// ----------------------------------------------------------------- traversal

/// A segment `origin + t * direction`, `t` in `[0, 1]`, prepared for `f32`
/// slab tests, its origin pushed out by the round-off margin: lower planes
/// are met from `origin + margin`, upper planes from `origin - margin`,
/// which widens every box by the margin at no cost per node. The boxes are
/// `f32` so four of them fit one SIMD register per coordinate.
struct SegmentQuery {
    origin_for_min: Vec3A,
    origin_for_max: Vec3A,
    inverse_direction: Vec3A,
}

impl SegmentQuery {
    fn new(from: DVec3, to: DVec3, margin: f64) -> SegmentQuery {
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
const WIDTH: usize = 4;

/// No child in a slot.
const EMPTY_SLOT: u32 = u32::MAX;

/// A node of the four-wide tree the queries walk: the boxes of up to four
/// children side by side, one array per coordinate (structure of arrays),
/// so one pass of four-lane arithmetic tests them all (Dammertz et al.
/// 2008, "Shallow bounding volume hierarchies"; Wald et al. 2008, "Getting
/// rid of packets"). 128 bytes: two cache lines.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
struct WideNode {
    /// Lower corners: `min[axis][child]`.
    min: [[f32; WIDTH]; 3],
    /// Upper corners.
    max: [[f32; WIDTH]; 3],
    /// Interior child: its node index. Leaf child: its first primitive.
    /// [`EMPTY_SLOT`] for no child.
    link: [u32; WIDTH],
    /// Primitives of a leaf child; 0 for an interior child or no child.
    count: [u32; WIDTH],
}

impl WideNode {
    const UNUSED: WideNode = WideNode {
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
fn collapse(tree: &Tree) -> Vec<WideNode> {
    if tree.nodes.is_empty() {
        return Vec::new();
    }
    let mut wide = Vec::with_capacity(tree.nodes.len() / 2 + 1);
    collapse_node(tree, 0, &mut wide);
    wide
}

fn half_area_of(node: &Node) -> f32 {
    let d = [0, 1, 2].map(|i| node.max[i] - node.min[i]);
    let area = d[0] * d[1] + d[1] * d[2] + d[2] * d[0];
    if area.is_nan() { f32::INFINITY } else { area }
}

/// Collapses the subtree of binary node `at` into wide nodes; returns the
/// index of its wide node.
fn collapse_node(tree: &Tree, at: u32, wide: &mut Vec<WideNode>) -> u32 {
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
fn prefetch(nodes: &[WideNode], index: u32) {
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
fn wide_any_hit(
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

// ------------------------------------------------------------------ validate

impl Tree {
    /// Checks the structure against the primitives' boxes: see
    /// [`Bvh::validate`].
    fn validate(
        &self,
        boxes: &[Aabb],
        settings: &BvhSettings,
        stats: &BvhStats,
    ) -> Result<(), String> {
        let nodes = &self.nodes;
        if boxes.is_empty() {
            return if nodes.is_empty()
                && self.primitives.is_empty()
                && *stats == BvhStats::default()
            {
                Ok(())
            } else {
                Err("an empty scene has a non-empty tree".into())
            };
        }
        if nodes.is_empty() {
            return Err("no nodes".into());
        }
        let mut parent = vec![u32::MAX; nodes.len()];
        let mut depth = vec![0usize; nodes.len()];
        depth[0] = 1;
        let mut next_primitive = 0usize;
        let mut leaves = 0;
        let mut largest = 0;
        let mut seen = vec![false; boxes.len()];
        for (i, node) in nodes.iter().enumerate() {
            if i > 0 && parent[i] == u32::MAX {
                return Err(format!("node {i} has no parent (or comes before it)"));
            }
            if node.is_leaf() {
                let range = node.primitives();
                if range.is_empty()
                    || range.start != next_primitive
                    || range.end > self.primitives.len()
                {
                    return Err(format!(
                        "leaf {i}: primitive range {range:?} is out of order"
                    ));
                }
                if range.len() > settings.max_leaf_size {
                    return Err(format!("leaf {i} holds {} primitives", range.len()));
                }
                next_primitive = range.end;
                leaves += 1;
                largest = largest.max(range.len());
                for &p in &self.primitives[range] {
                    let Some(b) = boxes.get(p as usize) else {
                        return Err(format!("leaf {i}: primitive {p} out of range"));
                    };
                    if std::mem::replace(&mut seen[p as usize], true) {
                        return Err(format!("primitive {p} is in two leaves"));
                    }
                    if !node.contains(&Node::new(*b, 0, 1)) {
                        return Err(format!("leaf {i}'s box does not contain primitive {p}'s"));
                    }
                }
                continue;
            }
            if node.axis() > 2 {
                return Err(format!("node {i}: split axis {}", node.axis()));
            }
            let right = node.link as usize;
            if right <= i + 1 || right >= nodes.len() {
                return Err(format!(
                    "node {i}: right child {right} out of depth-first order"
                ));
            }
            for child in [i + 1, right] {
                if parent[child] != u32::MAX {
                    return Err(format!("node {child} has two parents"));
                }
                parent[child] = i as u32;
                depth[child] = depth[i] + 1;
                if !node.contains(&nodes[child]) {
                    return Err(format!("node {i}'s box does not contain child {child}'s"));
                }
            }
        }
        if next_primitive != self.primitives.len() || self.primitives.len() != boxes.len() {
            return Err("leaves do not cover the primitive list exactly".into());
        }
        if let Some(p) = seen.iter().position(|s| !s) {
            return Err(format!("primitive {p} is in no leaf"));
        }
        let max_depth = depth.iter().copied().max().unwrap_or(0);
        if max_depth > MAX_DEPTH {
            return Err(format!("depth {max_depth} exceeds {MAX_DEPTH}"));
        }
        let actual = BvhStats {
            nodes: nodes.len(),
            leaves,
            depth: max_depth,
            max_leaf_size: largest,
            wide_nodes: stats.wide_nodes,
        };
        if actual != *stats {
            return Err(format!("statistics {stats:?}, tree {actual:?}"));
        }
        Ok(())
    }
}

// ---------------------------------------------------- conservative surface box

/// The query margin relative to the largest coordinate of the query and the
/// scene: about 34 units of `f32` round-off (see the module notes).
const QUERY_MARGIN: f64 = 2e-6;

/// Above this coordinate magnitude (of the query or the scene) a query
/// tests every surface instead of using `f32` boxes.
const F32_SAFE_COORDINATE: f64 = 1e30;

/// A box containing every point [`segment_crosses`](super::segment_crosses) can accept on the
/// surface, and its corners.
///
/// The accepted points lie on the surface's plane and within the tolerance
/// of every edge line, measured as `segment_crosses` measures it: the
/// distance along `normal x edge` divided by the 3-D edge length. In plane
/// coordinates that is a half-plane per edge, so the region is their
/// intersection, found by clipping a square grown until the region lies
/// well inside it (as the BSP's reach is computed).
fn crossing_box(surface: &Surface) -> Aabb {
    let corners = Aabb::of_points(surface.polygon.iter().copied());
    match AcceptanceRegion::of(surface, 4.0) {
        AcceptanceRegion::Bounded {
            origin,
            axes: [u, v],
            region,
            ..
        } => {
            let lifted = region.iter().map(|q| origin + u * q.x + v * q.y);
            Aabb::of_points(lifted).union(corners)
        }
        // An empty or unbounded region: a degenerate polygon. Always tested.
        AcceptanceRegion::Empty | AcceptanceRegion::Unbounded => Aabb::EVERYWHERE,
    }
}

// ----------------------------------------------------------------------- Bvh

/// A BVH over a scene's surfaces answering shadow-segment queries.
pub struct Bvh<'a> {
    surfaces: &'a [Surface],
    /// The surfaces laid out for the segment test, in leaf order (the
    /// order of `tree.primitives`), so a leaf's tests read adjacent memory.
    prepared: PreparedSurfaces,
    /// The binary tree as built (kept for `validate`).
    tree: Tree,
    /// The same tree collapsed four-wide, which queries walk.
    wide: Vec<WideNode>,
    /// Largest finite coordinate of any surface box: the scale of the
    /// boxes' round-off.
    scale: f64,
    settings: BvhSettings,
    stats: BvhStats,
}

impl<'a> Bvh<'a> {
    /// Builds the tree with [`BvhSettings::sah`].
    #[must_use]
    pub fn new(surfaces: &'a [Surface]) -> Bvh<'a> {
        Bvh::with_settings(surfaces, BvhSettings::sah())
    }

    /// Builds the tree with the given settings (sanitised first, see
    /// [`BvhSettings::sanitized`]).
    ///
    /// # Panics
    /// With 2^31 surfaces or more, which would not fit in memory anyway.
    #[must_use]
    pub fn with_settings(surfaces: &'a [Surface], settings: BvhSettings) -> Bvh<'a> {
        assert!(
            surfaces.len() < INTERIOR as usize,
            "a BVH holds fewer than 2^31 surfaces"
        );
        let settings = settings.sanitized();
        let boxes: Vec<Aabb> = surfaces.iter().map(crossing_box).collect();
        let scale = boxes
            .iter()
            .flat_map(|b| [b.min, b.max])
            .flat_map(|p| p.to_array())
            .map(f64::abs)
            .filter(|c| c.is_finite())
            .fold(0.0, f64::max);
        let (tree, mut stats) = Tree::build(&boxes, settings);
        let wide = collapse(&tree);
        stats.wide_nodes = wide.len();
        let in_leaf_order: Vec<Surface> = tree
            .primitives
            .iter()
            .map(|&id| surfaces[id as usize].clone())
            .collect();
        Bvh {
            surfaces,
            prepared: PreparedSurfaces::new(&in_leaf_order),
            wide,
            tree,
            scale,
            settings,
            stats,
        }
    }

    /// Size of the tree.
    #[must_use]
    pub fn stats(&self) -> BvhStats {
        self.stats
    }

    /// Bytes of the hierarchy's own arrays (binary and four-wide nodes,
    /// primitive ids), without the prepared surfaces every accelerator
    /// has.
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        use std::mem::size_of;
        self.tree.nodes.capacity() * size_of::<Node>()
            + self.tree.primitives.capacity() * size_of::<u32>()
            + self.wide.capacity() * size_of::<WideNode>()
    }

    /// The settings the tree was built with (after sanitising).
    #[must_use]
    pub fn settings(&self) -> BvhSettings {
        self.settings
    }

    /// Like [`Occluder::occluded`], also returning how many surfaces were
    /// tested with [`segment_crosses`](super::segment_crosses) and how many
    /// child boxes of the four-wide tree were tested (for benchmarks).
    #[must_use]
    pub fn occluded_counting(&self, from: DVec3, to: DVec3, skip: [u32; 2]) -> (bool, u32, u32) {
        let magnitude = from.abs().max_element().max(to.abs().max_element());
        let mut tested = 0u32;
        // `position` is in leaf order; the skip rule is on surface ids.
        let mut blocks = |position: u32| {
            if self.prepared.skips(position, skip) {
                return false;
            }
            tested += 1;
            self.prepared.crosses(position, from, to)
        };
        // NaN or huge coordinates: the f32 walk could not be trusted.
        let reference = magnitude.max(self.scale);
        let representable = from.is_finite() && to.is_finite() && reference < F32_SAFE_COORDINATE;
        if !representable {
            let blocked = (0..self.surfaces.len() as u32).any(&mut blocks);
            return (blocked, tested, 0);
        }
        let query = SegmentQuery::new(from, to, QUERY_MARGIN * reference);
        let (blocked, visited) = wide_any_hit(&self.wide, &query, blocks);
        (blocked, tested, visited)
    }

    /// Checks the tree's invariants: a well-formed depth-first node array
    /// (left child next, right child later, one parent each, depth at most
    /// [`MAX_DEPTH`]); every surface in exactly one leaf, leaves at most
    /// [`BvhSettings::max_leaf_size`]; every node's box containing its
    /// children's boxes and its surfaces' conservative boxes, and those
    /// containing the surfaces' corners; statistics matching the tree; the
    /// four-wide tree the queries walk reaching every wide node once and
    /// every surface once, each child box containing everything below it.
    pub fn validate(&self) -> Result<(), String> {
        let boxes: Vec<Aabb> = self.surfaces.iter().map(crossing_box).collect();
        for (id, (surface, b)) in self.surfaces.iter().zip(&boxes).enumerate() {
            let inside = surface
                .polygon
                .iter()
                .all(|p| p.cmpge(b.min).all() && p.cmple(b.max).all());
            if !inside {
                return Err(format!("surface {id}'s box does not contain its corners"));
            }
        }
        self.tree.validate(&boxes, &self.settings, &self.stats)?;
        self.validate_wide(&boxes)
    }

    fn validate_wide(&self, boxes: &[Aabb]) -> Result<(), String> {
        let wide = &self.wide;
        if wide.len() != self.stats.wide_nodes || wide.is_empty() != boxes.is_empty() {
            return Err(format!(
                "{} wide nodes for {} surfaces, statistics say {}",
                wide.len(),
                boxes.len(),
                self.stats.wide_nodes
            ));
        }
        let mut reached = vec![false; wide.len()];
        let mut seen = vec![false; boxes.len()];
        let mut todo = if wide.is_empty() {
            vec![]
        } else {
            vec![0usize]
        };
        let within = |outer: &WideNode, k: usize, min: [f32; 3], max: [f32; 3]| {
            (0..3).all(|a| outer.min[a][k] <= min[a] && outer.max[a][k] >= max[a])
        };
        while let Some(i) = todo.pop() {
            if std::mem::replace(&mut reached[i], true) {
                return Err(format!("wide node {i} is reached twice"));
            }
            let node = &wide[i];
            for k in 0..WIDTH {
                let link = node.link[k];
                if link == EMPTY_SLOT {
                    continue;
                }
                if node.count[k] == 0 {
                    let c = link as usize;
                    let Some(child) = wide.get(c) else {
                        return Err(format!("wide node {i}: child {c} out of range"));
                    };
                    for j in 0..WIDTH {
                        let (min, max) = (
                            [0, 1, 2].map(|a| child.min[a][j]),
                            [0, 1, 2].map(|a| child.max[a][j]),
                        );
                        if child.link[j] != EMPTY_SLOT && !within(node, k, min, max) {
                            return Err(format!("wide node {i}: box {k} does not contain {c}'s"));
                        }
                    }
                    todo.push(c);
                    continue;
                }
                let range = link as usize..link as usize + node.count[k] as usize;
                let Some(primitives) = self.tree.primitives.get(range) else {
                    return Err(format!("wide node {i}: leaf {k} out of range"));
                };
                for &p in primitives {
                    if std::mem::replace(&mut seen[p as usize], true) {
                        return Err(format!("surface {p} is in two wide leaves"));
                    }
                    let n = Node::new(boxes[p as usize], 0, 1);
                    if !within(node, k, n.min, n.max) {
                        return Err(format!(
                            "wide node {i}: box {k} does not contain surface {p}"
                        ));
                    }
                }
            }
        }
        if let Some(i) = reached.iter().position(|r| !r) {
            return Err(format!("wide node {i} is not reached"));
        }
        if let Some(p) = seen.iter().position(|s| !s) {
            return Err(format!("surface {p} is in no wide leaf"));
        }
        Ok(())
    }
}

impl Occluder for Bvh<'_> {
    fn occluded(&self, from: DVec3, to: DVec3, skip: [u32; 2]) -> bool {
        self.occluded_counting(from, to, skip).0
    }

    fn occluded_counting(&self, from: DVec3, to: DVec3, skip: [u32; 2]) -> (bool, u32, u32) {
        Bvh::occluded_counting(self, from, to, skip)
    }

    fn validate(&self) -> Result<(), String> {
        Bvh::validate(self)
    }

    fn build_statistics(&self) -> Vec<(&'static str, usize)> {
        let s = self.stats;
        vec![
            ("nodes", s.nodes),
            ("leaves", s.leaves),
            ("depth", s.depth),
            ("max_leaf_size", s.max_leaf_size),
            ("wide_nodes", s.wide_nodes),
            ("bytes", self.memory_bytes()),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::brute::BruteForce;

    const NONE_SKIPPED: [u32; 2] = [u32::MAX; 2];

    fn quad(corners: [[f64; 3]; 4]) -> Surface {
        let p = corners.iter().map(|c| DVec3::from_array(*c)).collect();
        Surface::new(p, DVec3::splat(0.5), DVec3::ZERO, 0).unwrap()
    }

    fn square_at_z(z: f64, half: f64) -> Surface {
        quad([
            [-half, -half, z],
            [half, -half, z],
            [half, half, z],
            [-half, half, z],
        ])
    }

    #[test]
    fn empty_scene_blocks_nothing() {
        for (_, settings) in BvhSettings::presets() {
            let bvh = Bvh::with_settings(&[], settings);
            assert_eq!(bvh.stats(), BvhStats::default());
            bvh.validate().unwrap();
            assert_eq!(
                bvh.occluded_counting(DVec3::ZERO, DVec3::ONE, NONE_SKIPPED),
                (false, 0, 0)
            );
        }
    }

    #[test]
    fn one_square_is_one_leaf() {
        let surfaces = [square_at_z(1.0, 1.0)];
        let bvh = Bvh::new(&surfaces);
        bvh.validate().unwrap();
        assert_eq!(
            bvh.stats(),
            BvhStats {
                nodes: 1,
                leaves: 1,
                depth: 1,
                max_leaf_size: 1,
                wide_nodes: 1,
            }
        );
        // One wide node: its four child boxes (one used) are tested.
        let up = DVec3::new(0.0, 0.0, 2.0);
        assert_eq!(
            bvh.occluded_counting(DVec3::ZERO, up, NONE_SKIPPED),
            (true, 1, 4)
        );
        assert_eq!(
            bvh.occluded_counting(DVec3::ZERO, up, [0, u32::MAX]),
            (false, 0, 4)
        );
        // A segment short of the box tests no surface.
        let short = DVec3::new(0.0, 0.0, 0.5);
        assert_eq!(
            bvh.occluded_counting(DVec3::ZERO, short, NONE_SKIPPED),
            (false, 0, 4)
        );
        // Nor does one passing beside it.
        let beside = DVec3::new(3.0, 0.0, 0.0);
        assert_eq!(
            bvh.occluded_counting(beside, beside + up, NONE_SKIPPED),
            (false, 0, 4)
        );
    }

    #[test]
    fn stacked_squares_split_and_agree() {
        let surfaces: Vec<Surface> = (0..40).map(|i| square_at_z(f64::from(i), 1.0)).collect();
        let brute = BruteForce::new(&surfaces);
        for (name, settings) in BvhSettings::presets() {
            let bvh = Bvh::with_settings(&surfaces, settings);
            bvh.validate().unwrap();
            let stats = bvh.stats();
            assert!(stats.leaves > 1 && stats.depth < 12, "{name}: {stats:?}");
            for i in 0..40 {
                let from = DVec3::new(0.1, 0.2, f64::from(i) - 0.5);
                let to = DVec3::new(-0.3, 0.1, 39.5 - f64::from(i));
                assert_eq!(
                    bvh.occluded(from, to, NONE_SKIPPED),
                    brute.occluded(from, to, NONE_SKIPPED)
                );
            }
            // Between two neighbouring planes: one leaf's worth of tests.
            let (blocked, tested, _) = bvh.occluded_counting(
                DVec3::new(0.5, 0.5, 20.2),
                DVec3::new(0.4, 0.6, 20.8),
                NONE_SKIPPED,
            );
            assert!(!blocked);
            assert!(tested <= settings.max_leaf_size as u32, "{name}: {tested}");
        }
    }

    #[test]
    fn sah_keeps_separate_clusters_apart() {
        // Two far-apart clusters of 8 squares: the root splits between them.
        let mut surfaces: Vec<Surface> = (0..8)
            .map(|i| square_at_z(f64::from(i) * 0.1, 1.0))
            .collect();
        surfaces.extend((0..8).map(|i| {
            let mut s = square_at_z(100.0 + f64::from(i) * 0.1, 1.0);
            s.polygon.iter_mut().for_each(|p| p.x += 50.0);
            Surface::new(s.polygon, s.rho, s.emission, 0).unwrap()
        }));
        let bvh = Bvh::new(&surfaces);
        bvh.validate().unwrap();
        let root = &bvh.tree.nodes[0];
        let left = &bvh.tree.nodes[1];
        let right = &bvh.tree.nodes[root.link as usize];
        assert!(
            left.max[2] < 50.0 && right.min[2] > 50.0,
            "{left:?} {right:?}"
        );
    }

    #[test]
    fn coincident_centroids_still_split() {
        // 30 copies of one square: no heuristic split exists, the median
        // fallback halves the list down to leaves of at most 8.
        let surfaces: Vec<Surface> = (0..30).map(|_| square_at_z(0.0, 1.0)).collect();
        for (name, settings) in BvhSettings::presets() {
            let bvh = Bvh::with_settings(&surfaces, settings);
            bvh.validate().unwrap();
            assert!(
                bvh.stats().max_leaf_size <= settings.max_leaf_size,
                "{name}"
            );
            assert!(bvh.occluded(DVec3::NEG_Z, DVec3::Z, NONE_SKIPPED));
        }
    }

    #[test]
    fn crossing_box_covers_the_tolerance_region() {
        let square = square_at_z(0.0, 1.0);
        let b = crossing_box(&square);
        let tol = 4.0 * crate::accel::EDGE_TOLERANCE * 2.0;
        // Edge lines moved out by the tolerance: the box grows by it.
        assert!((b.max.x - (1.0 + tol)).abs() < 1e-15, "{b:?}");
        assert!((b.min.y + 1.0 + tol).abs() < 1e-15, "{b:?}");
        assert_eq!((b.min.z, b.max.z), (0.0, 0.0));
        // A needle's tip region reaches about tolerance / half-angle beyond
        // the tip.
        let needle = Surface::new(
            vec![
                DVec3::ZERO,
                DVec3::new(1.0, 0.0, 0.0),
                DVec3::new(1.0, 1e-3, 0.0),
            ],
            DVec3::splat(0.5),
            DVec3::ZERO,
            0,
        )
        .unwrap();
        let t = 4.0 * crate::accel::EDGE_TOLERANCE * needle.area.sqrt();
        let reach = -crossing_box(&needle).min.x;
        assert!(reach > 1000.0 * t && reach < 5000.0 * t, "{reach} vs {t}");
    }

    #[test]
    fn far_away_and_non_finite_queries_agree() {
        let surfaces: Vec<Surface> = (0..10).map(|i| square_at_z(f64::from(i), 1.0)).collect();
        let brute = BruteForce::new(&surfaces);
        let bvh = Bvh::new(&surfaces);
        for (from, to) in [
            (DVec3::new(0.0, 0.0, -1e35), DVec3::new(0.0, 0.0, 1e35)),
            (DVec3::new(0.1, 0.0, -1e20), DVec3::new(0.0, 0.0, 1e20)),
            (DVec3::new(f64::NAN, 0.0, 0.0), DVec3::Z),
            (
                DVec3::new(0.0, 0.0, -5.0),
                DVec3::new(0.0, 0.0, f64::INFINITY),
            ),
        ] {
            assert_eq!(
                bvh.occluded(from, to, NONE_SKIPPED),
                brute.occluded(from, to, NONE_SKIPPED),
                "{from:?} -> {to:?}"
            );
        }
    }

    #[test]
    fn settings_are_sanitized() {
        let s = BvhSettings {
            split: SplitMethod::BinnedSah,
            bins: 1,
            leaf_size: 0,
            max_leaf_size: 1000,
            traversal_cost: f64::NAN,
            primitive_cost: -1.0,
        }
        .sanitized();
        assert_eq!(s.bins, 2);
        assert_eq!(s.leaf_size, 1);
        assert_eq!(s.max_leaf_size, MAX_LEAF_SIZE);
        assert_eq!(s.traversal_cost, BvhSettings::sah().traversal_cost);
        assert_eq!(s.primitive_cost, BvhSettings::sah().primitive_cost);
        let s = BvhSettings {
            leaf_size: 10,
            max_leaf_size: 3,
            bins: 10_000,
            ..BvhSettings::sah()
        }
        .sanitized();
        assert_eq!((s.leaf_size, s.max_leaf_size, s.bins), (10, 10, MAX_BINS));
    }

    #[test]
    fn node_is_32_bytes() {
        assert_eq!(std::mem::size_of::<Node>(), 32);
    }

    #[test]
    fn boxes_round_outward() {
        let b = Aabb {
            min: DVec3::splat(0.1),
            max: DVec3::splat(0.1),
        };
        let (lo, hi) = round_outward(b);
        assert!(f64::from(lo[0]) <= 0.1 && f64::from(hi[0]) >= 0.1);
        assert!(lo[0] < hi[0]);
        let (lo, hi) = round_outward(Aabb::EVERYWHERE);
        assert_eq!((lo[1], hi[2]), (f32::NEG_INFINITY, f32::INFINITY));
    }
}
