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
//! Karras & Laine 2017). A
//! shadow segment walks it depth first, nearer children first, and stops at
//! the first blocker (an any-hit query); through a shadow cache (Haines &
//! Greenberg 1986) the blocker last met from the segment's origin, when
//! the caller names it, and the last two blockers a thread met are tested
//! first, and one that blocks spares the walk. A closest-hit ray walks it the
//! same way but to the end, skipping every box entered beyond the nearest
//! crossing found so far (the ray shrinks as hits are found).
//!
//! The module is in files, one concern each: the settings and [`Bvh`],
//! which ties the tree to the scene, here; `build` (the flattened layout,
//! the build and the conservative box of a surface); `collapse` (the
//! binary tree grouped into the wide one); `flat` (the binary
//! tree as it is built, for walkers of their own: the GPU's); `traverse` (the
//! segment prepared for the walk, the wide layout and its two walks); and
//! `validate`. The tree itself
//! knows primitive indices, never geometry: the build takes boxes, the
//! traversals take a closure deciding whether primitive `i` blocks, or
//! testing it and returning how far the ray still reaches.
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
//! allocation, no interior mutability, any number of threads.

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
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BvhStats {
    /// Nodes, leaves included.
    pub nodes: usize,
    /// Leaves.
    pub leaves: usize,
    /// Nodes on the longest root-to-leaf path (0 for an empty tree).
    pub depth: usize,
    /// Surfaces in the largest leaf.
    pub max_leaf_size: usize,
    /// Nodes of the eight-wide tree the queries walk.
    pub wide_nodes: usize,
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
        let magnitude = from.abs().max_element().max(to.abs().max_element());
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
        let reference = magnitude.max(self.scale);
        let representable = from.is_finite() && to.is_finite() && reference < F32_SAFE_COORDINATE;
        if !representable {
            (0..self.surfaces.len() as u32).any(&mut blocks);
            return (found, tested, 0);
        }
        let query = SegmentQuery::new(from, to, QUERY_MARGIN * reference);
        let leaf = |first, count| (first..first + count).any(&mut blocks);
        let (_, visited) = wide_any_hit(&self.wide, &query, leaf);
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
        let magnitude = origin.abs().max_element().max(end.abs().max_element());
        let reference = magnitude.max(self.scale);
        let visited = if reference < F32_SAFE_COORDINATE {
            let query = SegmentQuery::new(origin, end, QUERY_MARGIN * reference);
            wide_closest_hit(&self.wide, &query, offer)
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
            ("bytes", self.memory_bytes()),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::brute::BruteForce;

    use crate::accel::test_scenes::{NONE_SKIPPED, square_at_z, xorshift};

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
        // One wide node: its child boxes (one used) are tested.
        let up = DVec3::new(0.0, 0.0, 2.0);
        assert_eq!(
            bvh.occluded_counting(DVec3::ZERO, up, NONE_SKIPPED),
            (true, 1, WIDTH as u32)
        );
        assert_eq!(
            bvh.occluded_counting(DVec3::ZERO, up, [0, u32::MAX]),
            (false, 0, WIDTH as u32)
        );
        // A segment short of the box tests no surface.
        let short = DVec3::new(0.0, 0.0, 0.5);
        assert_eq!(
            bvh.occluded_counting(DVec3::ZERO, short, NONE_SKIPPED),
            (false, 0, WIDTH as u32)
        );
        // Nor does one passing beside it.
        let beside = DVec3::new(3.0, 0.0, 0.0);
        assert_eq!(
            bvh.occluded_counting(beside, beside + up, NONE_SKIPPED),
            (false, 0, WIDTH as u32)
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
    fn closest_hit_walks_front_to_back() {
        let surfaces: Vec<Surface> = (0..40).map(|i| square_at_z(f64::from(i), 1.0)).collect();
        let brute = BruteForce::new(&surfaces);
        for (name, settings) in BvhSettings::presets() {
            let bvh = Bvh::with_settings(&surfaces, settings);
            for (z, up) in [(-0.5, 1.0), (20.5, 1.0), (39.5, -1.0), (12.25, -1.0)] {
                let origin = DVec3::new(0.1, -0.2, z);
                let direction = DVec3::new(0.0, 0.0, up);
                let (hit, tested, _) =
                    bvh.closest_hit_counting(origin, direction, 50.0, NONE_SKIPPED);
                assert_eq!(
                    hit,
                    brute.closest_hit(origin, direction, 50.0, NONE_SKIPPED),
                    "{name}"
                );
                let expected = if up > 0.0 { z.ceil() } else { z.floor() };
                assert_eq!(hit.unwrap().surface, expected as u32, "{name}");
                assert!((hit.unwrap().t - (expected - z).abs()).abs() < 1e-12);
                // Boxes beyond the first hit are skipped: a leaf or two of
                // the 40 squares.
                assert!(
                    tested <= 2 * settings.max_leaf_size as u32,
                    "{name}: {tested}"
                );
            }
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

    /// Walks in two groups of four lanes (a processor without AVX) give
    /// the same answers, surface tests and box counts as the walks this
    /// processor runs, any-hit and closest-hit, on random segments
    /// through the built-in room and from its vertices (segments that
    /// graze corners and edges).
    #[test]
    fn four_lanes_walk_as_eight() {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx") {
            // The walks this processor runs are the eight-lane ones.
            assert_eq!(slab_lanes(), 8);
        } else {
            eprintln!("no AVX here: the four-lane walk is compared with itself");
        }
        #[cfg(not(target_arch = "x86_64"))]
        eprintln!("not x86-64: the four-lane walk is compared with itself");
        let scene = crate::scene::builtin::load("room").unwrap().unwrap();
        let bvh = Bvh::new(&scene.surfaces);
        let corners: Vec<DVec3> = scene
            .surfaces
            .iter()
            .flat_map(|s| s.polygon.iter().copied())
            .collect();
        let mut next = xorshift(0x2545_f491_4f6c_dd1d);
        let (mut blocked, mut hits) = (0, 0);
        for _ in 0..5_000 {
            let mut point = || {
                let c = corners[(next() % corners.len() as u64) as usize];
                if next().is_multiple_of(2) {
                    c
                } else {
                    c + DVec3::new(
                        (next() % 1000) as f64 / 500.0 - 1.0,
                        (next() % 1000) as f64 / 500.0 - 1.0,
                        (next() % 1000) as f64 / 500.0 - 1.0,
                    )
                }
            };
            let (from, to) = (point(), point());
            let skip = [(next() % 8) as u32, u32::MAX];
            let eight = bvh.occluded_counting(from, to, skip);
            let four = traverse::four_lanes_only(|| bvh.occluded_counting(from, to, skip));
            assert_eq!(eight, four, "{from} -> {to}");
            blocked += usize::from(eight.0);
            let eight = bvh.closest_hit_counting(from, to - from, 1.0, skip);
            let four =
                traverse::four_lanes_only(|| bvh.closest_hit_counting(from, to - from, 1.0, skip));
            assert_eq!(eight, four, "{from} -> {to}");
            hits += usize::from(eight.0.is_some());
        }
        assert!(blocked > 500 && hits > 500, "{blocked} {hits}");
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
