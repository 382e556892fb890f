//! Bounding-volume-hierarchy visibility (design.md section 3, "beyond the
//! paper"): the modern answer to shadow rays, kept beside the BSP so the two
//! can be compared honestly.
//!
//! The tree is a binary BVH over one axis-aligned box per surface, built top
//! down with the surface area heuristic (Goldsmith & Salmon 1987; MacDonald
//! & Booth 1990) evaluated on a fixed number of centroid bins per axis
//! (Wald 2007, "On fast construction of SAH-based bounding volume
//! hierarchies"), then collapsed into an eight-wide tree (Dammertz et al.
//! 2008; Wald et al. 2008) whose eight child boxes are tested at once, the
//! grouping chosen by the heuristic's cost of the wide tree itself (Ylitie,
//! Karras & Laine 2017). A shadow segment walks it depth first, nearer
//! children first, and stops at the first blocker (an any-hit query);
//! through a shadow cache (Haines & Greenberg 1986) the blocker last met
//! from the segment's origin, when the caller names it, and the last two
//! blockers a thread met are tested first, and one that blocks spares the
//! walk. A closest-hit ray walks it the
//! same way but to the end, skipping every box entered beyond the nearest
//! crossing found so far (the ray shrinks as hits are found).
//!
//! The module is in files, one concern each: the settings and [`Bvh`],
//! which ties the tree to the scene, here; `build` (the flattened layout,
//! the build and the conservative box of a surface); `collapse` (the
//! binary tree grouped into the wide one); `flat` (the binary
//! tree as it is built, for walkers of their own: the GPU's); `traverse` (the
//! segment prepared for the walk, the wide layout and its two walks, with
//! their AVX versions in `traverse/avx.rs`);
//! `validate`; and the unit tests, in `tests`. The tree itself
//! knows primitive indices, never geometry: the build takes boxes, the
//! any-hit walk takes a closure deciding whether a leaf (its first
//! primitive and its count) holds a blocker, the closest-hit walk one
//! testing primitive `i` and returning how far the ray still reaches.
//!
//! # Agreement with the brute-force oracle
//!
//! Boxes only cull. The blocking decision is always [`segment_crosses`](super::segment_crosses) on
//! the original surface, so an answer can only differ from
//! [`BruteForce`](super::brute::BruteForce) if the walk fails to offer a
//! surface the segment crosses. It cannot, because every box is
//! conservative (and a closest-hit walk compares box entries with the
//! nearest crossing's parameter rounded up to `f32`, entries at it
//! included):
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
//! * A shadow segment's walk rechecks each leaf child's box in `f64` before
//!   testing its surfaces, with a margin (`EXACT_MARGIN`, 1e-12 of the same
//!   reference). It must cover that test's round-off (under `10 ε`, 2.2e-15
//!   of the reference) and how far off the exact segment and plane
//!   `segment_crosses`'s own `f64` arithmetic can accept a crossing (tens
//!   of `ε`): about a hundred times over. It culls the leaves the wide
//!   `f32` margin lets in at the segment's ends, never one holding a
//!   surface the exact test accepts.
//!
//! # Layout
//!
//! The binary tree's nodes live in one `Vec` in depth-first order: an
//! interior node's left child is the next node, its right child is stored
//! by index. A node is 32 bytes: an `f32` box, a link (right child or first
//! primitive) and a word that is either the leaf's primitive count or the
//! interior node's split axis. Leaves' primitives are ranges of one
//! `Vec<u32>` of surface ids. The eight-wide nodes the queries walk are
//! 256 bytes (four cache lines): the eight boxes coordinate by coordinate
//! and side by side, tested as two groups of four lanes (SSE on x86-64),
//! or as one group of eight where the processor has AVX (the same
//! operations lane by lane, so the same answers), the eight links, the
//! leaf children's counts and a mask of which children are leaves. A walk
//! visits about a third fewer nodes than on the four-wide tree, and each
//! visit is a chain of dependent loads and compares whose length barely
//! grows with the width; the walk prefetches a node when it pushes it. The
//! surfaces' prepared planes and edges are stored in leaf order, so a
//! leaf's tests read adjacent memory; the skip rule compares surface ids,
//! in one closure. Queries use a fixed stack, left uninitialised: no
//! allocation, no interior mutability, any number of threads. A query's
//! set-up (the segment in `f32` and, for shadow segments, `f64`, its
//! inverse direction, its widened origins, spread over the lanes) is
//! computed for the three axes at once in vector lanes where the processor
//! has AVX: a query is a few hundred instructions, and its walk cannot
//! start before its set-up is done.

use glam::{DVec3, Vec3A};

use super::{
    AcceptanceRegion, Hit, InvalidTree, Nearest, Occluder, PreparedSurfaces, ShadowCache, ray_end,
};
use crate::scene::Surface;

mod build;
mod collapse;
mod flat;
mod traverse;
mod validate;

use build::*;
pub use flat::{FLAT_INTERIOR, FlatNode, FlatTree};
use traverse::*;
pub use traverse::{WIDTH, slab_lanes};

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
    /// heuristic prefers a leaf; `leaf_size..=MAX_LEAF_SIZE`. The wide
    /// tree's leaves, which may join binary leaves, hold at most as many.
    pub max_leaf_size: usize,
    /// Cost of visiting a node (one box test), for the binary tree's
    /// heuristic (the wide tree's grouping has its own costs, in
    /// `collapse`).
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
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BvhStats {
    /// Nodes, leaves included.
    pub nodes: usize,
    /// Leaves.
    pub leaves: usize,
    /// Nodes on the longest root-to-leaf path (0 for an empty tree).
    pub depth: usize,
    /// Surfaces in the binary tree's largest leaf.
    pub max_leaf_size: usize,
    /// Nodes of the eight-wide tree the queries walk.
    pub wide_nodes: usize,
    /// Surfaces in the wide tree's largest leaf (which may join binary
    /// leaves, up to the settings' `max_leaf_size`): the most a leaf
    /// visit tests.
    pub wide_max_leaf_size: usize,
}

// ----------------------------------------------------------------------- Bvh

/// A BVH over a scene's surfaces answering shadow-segment and closest-hit
/// queries.
pub struct Bvh<'a> {
    surfaces: &'a [Surface],
    /// The surfaces laid out for the segment test, in leaf order (the
    /// order of `tree.primitives`), so a leaf's tests read adjacent memory.
    prepared: PreparedSurfaces,
    /// The binary tree as built (kept for `validate`).
    tree: Tree,
    /// The same tree collapsed eight-wide, which queries walk.
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
        let wide = collapse::collapse(&tree, settings.max_leaf_size);
        stats.wide_nodes = wide.len();
        stats.wide_max_leaf_size = wide
            .iter()
            .flat_map(|n| n.count)
            .max()
            .map_or(0, usize::from);
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

    /// Bytes of the hierarchy's own arrays (binary and eight-wide nodes,
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
    /// child boxes of the eight-wide tree were tested (for benchmarks).
    #[must_use]
    pub fn occluded_counting(&self, from: DVec3, to: DVec3, skip: [u32; 2]) -> (bool, u32, u32) {
        let (blocker, tested, visited) = self.blocker(from, to, skip);
        (blocker.is_some(), tested, visited)
    }

    /// The surface (its position in leaf order) at which the any-hit walk
    /// found the segment blocked, if any, with the surfaces and child
    /// boxes tested.
    fn blocker(&self, from: DVec3, to: DVec3, skip: [u32; 2]) -> (Option<u32>, u32, u32) {
        let magnitude = largest_magnitude(from, to);
        let mut tested = 0u32;
        let mut found = None;
        // `position` is in leaf order; the skip rule is on surface ids.
        let mut blocks = |position: u32| {
            if self.prepared.skips(position, skip) {
                return false;
            }
            tested += 1;
            let blocked = self.prepared.crosses(position, from, to);
            if blocked {
                found = Some(position);
            }
            blocked
        };
        // NaN or huge coordinates: the f32 walk could not be trusted.
        let reference = larger(magnitude, self.scale);
        // `0 x` is 0 for every finite `x`, NaN for infinities and NaN: one
        // comparison a coordinate.
        let zero = from * 0.0 + to * 0.0;
        let finite = zero.x == 0.0 && zero.y == 0.0 && zero.z == 0.0;
        let representable = finite && reference < F32_SAFE_COORDINATE;
        if !representable {
            (0..self.surfaces.len() as u32).any(&mut blocks);
            return (found, tested, 0);
        }
        // Each leaf's box rechecked in `f64` before its surfaces' tests.
        let margins = (QUERY_MARGIN * reference, EXACT_MARGIN * reference);
        let leaf = |first, count| (first..first + count).any(&mut blocks);
        let (_, visited) = wide_any_hit(&self.wide, (from, to), margins, leaf);
        (found, tested, visited)
    }

    /// Like [`Occluder::closest_hit`], also returning how many surfaces
    /// were tested and how many child boxes of the eight-wide tree were
    /// tested (for benchmarks and tests).
    #[must_use]
    pub fn closest_hit_counting(
        &self,
        origin: DVec3,
        direction: DVec3,
        max_t: f64,
        skip: [u32; 2],
    ) -> (Option<Hit>, u32, u32) {
        let Some(end) = ray_end(origin, direction, max_t) else {
            return (None, 0, 0);
        };
        let mut nearest = Nearest::default();
        let mut tested = 0u32;
        // `position` is in leaf order; answers and ties are on surface ids.
        let mut offer = |position: u32| {
            if !self.prepared.skips(position, skip) {
                tested += 1;
                if let Some(s) = self.prepared.crossing(position, origin, end) {
                    nearest.offer(self.tree.primitives[position as usize], s);
                }
            }
            nearest.limit()
        };
        // `ray_end` has checked that both ends are finite.
        let reference = larger(largest_magnitude(origin, end), self.scale);
        let visited = if reference < F32_SAFE_COORDINATE {
            wide_closest_hit(&self.wide, (origin, end), QUERY_MARGIN * reference, offer)
        } else {
            // Huge coordinates: the f32 walk could not be trusted.
            for p in 0..self.surfaces.len() as u32 {
                offer(p);
            }
            0
        };
        (nearest.hit(max_t), tested, visited)
    }

    /// Checks the tree's invariants: a well-formed depth-first node array
    /// (left child next, right child later, one parent each, depth at most
    /// [`MAX_DEPTH`]); every surface in exactly one leaf, leaves at most
    /// [`BvhSettings::max_leaf_size`]; every node's box containing its
    /// children's boxes and its surfaces' conservative boxes, and those
    /// containing the surfaces' corners; statistics matching the tree; the
    /// eight-wide tree the queries walk reaching every wide node once and
    /// every surface once, each child box containing everything below it.
    pub fn validate(&self) -> Result<(), InvalidTree> {
        let boxes: Vec<Aabb> = self.surfaces.iter().map(crossing_box).collect();
        for (id, (surface, b)) in self.surfaces.iter().zip(&boxes).enumerate() {
            let inside = surface
                .polygon
                .iter()
                .all(|p| p.cmpge(b.min).all() && p.cmple(b.max).all());
            if !inside {
                return Err(InvalidTree(format!(
                    "surface {id}'s box does not contain its corners"
                )));
            }
        }
        self.tree.validate(&boxes, &self.settings, &self.stats)?;
        self.validate_wide(&boxes)
    }
}

/// `a` if it is greater than `b`, else `b`: `f64::max` for the numbers
/// other than NaN, one instruction where `f64::max`'s rule for NaN takes
/// several.
fn larger(a: f64, b: f64) -> f64 {
    if a > b { a } else { b }
}

/// The largest magnitude of the coordinates of `a` and `b`, in a balanced
/// tree of plain comparisons: exact for finite coordinates, whatever the
/// order, and a short chain of dependent instructions, paid before every
/// walk can start (with `f64::max` it was a long one). A NaN coordinate
/// may be ignored or returned: callers check finiteness themselves.
fn largest_magnitude(a: DVec3, b: DVec3) -> f64 {
    let (a, b) = (a.abs(), b.abs());
    larger(larger(larger(a.x, a.y), larger(a.z, b.x)), larger(b.y, b.z))
}

impl Occluder for Bvh<'_> {
    fn occluded(&self, from: DVec3, to: DVec3, skip: [u32; 2]) -> bool {
        self.occluded_counting(from, to, skip).0
    }

    fn occluded_counting(&self, from: DVec3, to: DVec3, skip: [u32; 2]) -> (bool, u32, u32) {
        Bvh::occluded_counting(self, from, to, skip)
    }

    /// The cached blocker given the exact test first: if it blocks, the
    /// walk would have found a blocker too (every box is conservative, so
    /// the walk finds a blocker whenever one exists).
    fn occluded_cached(
        &self,
        from: DVec3,
        to: DVec3,
        skip: [u32; 2],
        cache: &mut ShadowCache,
    ) -> bool {
        let blocks = |c: u32| {
            (c as usize) < self.prepared.len()
                && !self.prepared.skips(c, skip)
                && self.prepared.crosses(c, from, to)
        };
        // The blocker last found from this origin first, then the last two
        // found from anywhere.
        let mine = cache.slot().map_or(u32::MAX, |s| cache.by_origin[s]);
        if mine != u32::MAX && blocks(mine) {
            cache.hits += 1;
            return true;
        }
        for last in cache.last {
            if last != mine && blocks(last) {
                cache.hits += 1;
                cache.remember(last);
                return true;
            }
        }
        let (blocker, _, _) = self.blocker(from, to, skip);
        if let Some(position) = blocker {
            cache.remember(position);
        }
        blocker.is_some()
    }

    /// The eight-wide tree walked with the shaft's box and plane tests,
    /// each surface in a box that meets it tested by its corners.
    fn shaft_clear(
        &self,
        shaft: &super::shaft::Shaft,
        skip: [u32; 2],
        cache: &mut ShadowCache,
    ) -> bool {
        if self.wide.is_empty() {
            return true;
        }
        let shaft = shaft.widened(self.scale);
        let meets = |position: u32| {
            !self.prepared.skips(position, skip)
                && !shaft.misses_polygon(
                    &self.surfaces[self.tree.primitives[position as usize] as usize].polygon,
                )
        };
        let slot = cache.slot();
        if let Some(s) = slot {
            let last = cache.by_shaft[s];
            if (last as usize) < self.prepared.len() && meets(last) {
                cache.hits += 1;
                return false;
            }
        }
        // Each node pushes at most WIDTH - 1 entries above its ancestors';
        // a deeper tree than the stack holds is taken as meeting it.
        let mut stack = [0u32; 8 * WIDTH];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let node = &self.wide[stack[top] as usize];
            for k in 0..WIDTH {
                if node.link[k] == EMPTY_SLOT {
                    continue;
                }
                let corner = |side: usize| {
                    DVec3::new(
                        f64::from(node.bounds[0][side][k]),
                        f64::from(node.bounds[1][side][k]),
                        f64::from(node.bounds[2][side][k]),
                    )
                };
                if shaft.misses_box(corner(0), corner(1)) {
                    continue;
                }
                if node.leaves & (1 << k) == 0 {
                    if top == stack.len() {
                        return false;
                    }
                    stack[top] = node.link[k];
                    top += 1;
                    continue;
                }
                let first = node.link[k];
                for position in first..first + u32::from(node.count[k]) {
                    if meets(position) {
                        if let Some(s) = slot {
                            cache.by_shaft[s] = position;
                        }
                        return false;
                    }
                }
            }
        }
        true
    }

    fn closest_hit(
        &self,
        origin: DVec3,
        direction: DVec3,
        max_t: f64,
        skip: [u32; 2],
    ) -> Option<Hit> {
        self.closest_hit_counting(origin, direction, max_t, skip).0
    }

    fn validate(&self) -> Result<(), InvalidTree> {
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
            ("wide_max_leaf_size", s.wide_max_leaf_size),
            ("bytes", self.memory_bytes()),
        ]
    }
}

#[cfg(test)]
mod tests;
