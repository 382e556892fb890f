//! BSP-tree visibility: Wong & Tsang (1993), section 3 and Figure 3.2
//! (design.md section 3, improvement 2), built with a cost model so that it
//! scales to scenes of hundreds of thousands of triangles.
//!
//! # The tree
//!
//! Every splitting plane is chosen by a cost among a sample of candidate
//! planes: the planes of the node's surfaces (the paper's auto-partition:
//! "the planes are induced by a set of polygons in the scene") and, in the
//! default preset, a few axis-aligned planes (see *Plane choice*). Fragments
//! lying on a node's plane are stored at that node; a fragment straddling the
//! plane is split by it and both pieces keep their surface id (the BSP tree
//! of Fuchs, Kedem & Naylor 1980, as used by Chin & Feiner 1989). A node whose
//! fragments are few, or not worth dividing, is a *leaf bucket* holding them
//! all.
//!
//! # The walk
//!
//! A shadow segment walks the tree front to back from its origin: at each
//! node it visits the child on its origin's side, then, only if the segment
//! reaches the node's plane, the surfaces stored there and the far child (the
//! pruning of the paper's Figure 3.2: a segment that stays on one side of a
//! plane never visits the other). The walk carries the part of the segment
//! inside the current node's region (a parameter interval, as kd-tree and BSP
//! ray walks do; Ize, Wald & Parker 2008): a child is visited only if that
//! part reaches it, so a segment visits only the regions it passes through,
//! not every region on the far side of a plane it crosses somewhere else.
//! It stops at the first blocker. A closest-hit ray takes the same walk to
//! its end: front to back, the first crossing found is usually the answer,
//! and every region or plane band the ray enters beyond the nearest
//! crossing so far is skipped (the bands overlap by their tolerance, so
//! the order is only nearly front to back and the walk cannot stop at the
//! first hit).
//!
//! # Plane choice
//!
//! [`BspSettings::cost`] selects the score. The default is the surface area
//! heuristic adapted to arbitrary planes (MacDonald & Booth 1990; Havran
//! 2000, section 4; Ize, Wald & Parker 2008): each node keeps its region as
//! a convex polyhedron (the scene's box cut by the planes above it), and a
//! segment crossing a region meets a convex part of it with probability
//! proportional to that part's surface area. A candidate plane cuts the
//! region into a front part `F`, a back part `B` and a cap `P` (the plane's
//! section of the region), and costs
//!
//! ```text
//! cost = traversal + (S(F) n_F + S(B) n_B + 2 S(P) n_P) / S(region)
//! ```
//!
//! in units of one surface test, where `n_F` and `n_B` count the fragments
//! on each side (a fragment the plane splits counts on both: the cost of
//! splitting) and `n_P` those lying on the plane, which the walk tests only
//! when the segment crosses the cap. Many fragments on one plane (a floor
//! of a thousand triangles) would all be tested by every segment crossing
//! the cap anywhere, so beyond [`BspSettings::leaf_size`] of them they go to
//! the child of smaller area instead and are divided there (as kd-trees
//! place planar primitives; Wald & Havran 2006), costed `min(S(F), S(B))
//! n_P`. A node whose fragments all lie in one plane is scored in two
//! dimensions: a segment meets that plane once, so a part is tested with
//! the probability of the share of the fragments' extent in the plane it
//! covers. A node becomes a leaf when it holds at most
//! [`BspSettings::leaf_size`] fragments or when no candidate costs less than
//! testing all its fragments (`n`); a leaf whose fragments share a plane is
//! a plane node without children (tested only when reached), else a
//! bucket. At large nodes the counts are estimated from an evenly spaced
//! sample of [`BspSettings::cost_sample`] fragments. The older score
//! `split_weight * splits + |n_F - n_B|` (Fuchs, Abram & Grant 1983) remains
//! as [`PlaneCost::SplitsAndBalance`] for comparison; it never stops early.
//!
//! Candidates: [`BspSettings::candidates`] surface planes, the planes of an
//! evenly spaced sample of the node's fragments, and the boundaries of
//! [`BspSettings::axis_candidates`] equal slabs per axis across the
//! fragments' bounding box, all scored at once by binning and the best one
//! then scored exactly. Surface planes alone separate flat architecture well
//! but not curved, finely tessellated objects: the planes of a convex
//! shell's facets each have the whole shell behind them, so an
//! auto-partition peels one facet per level (Sponza's columns and arches,
//! the conference room's chairs), nor can they divide the triangles of one
//! floor. Measured on the recorded shadow segments of Sponza (`radiosity
//! experiment rays`, EXPERIMENTS.md), surface planes only test several
//! times as many surfaces per ray as with the axis-aligned candidates,
//! which are what brings the default tree within 3x of the BVH there; the
//! `auto-partition` preset keeps the paper's surface planes only.
//!
//! Splitting is bounded: a subtree may create at most its share of
//! `(max_growth - 1) x surfaces` new fragments (each node's share passed to
//! its children in proportion to their fragments), a candidate needing more
//! is refused, and a node left without an affordable candidate becomes a
//! leaf. The depth is bounded by [`BspSettings::max_depth`] (at most
//! [`MAX_DEPTH`]), below which the remaining fragments form a leaf. So the
//! build's memory is linear in the surfaces and its time `O(k n log n)` for
//! `k` candidates.
//!
//! # Agreement with the brute-force oracle
//!
//! The tree only decides *which* surfaces to test; the blocking decision is
//! always [`segment_crosses`](super::segment_crosses) on the original
//! surface, so an answer can only differ from
//! [`BruteForce`](super::brute::BruteForce) if the walk misses a surface the
//! segment crosses. It cannot, because every tolerance is conservative:
//!
//! * `segment_crosses` accepts a crossing point up to `1e-9 sqrt(area)` from
//!   each edge line, which near a sharp corner reaches further than that from
//!   the polygon, and a non-planar input polygon lies off its own plane. At
//!   build time each surface gets a *reach*: how far an accepted crossing
//!   point can be from the polygon's corners' convex hull (computed from the
//!   exact tolerance region, not assumed).
//! * A fragment is coplanar with a node (stored there) when all its corners
//!   are within the coplanar tolerance `c` of the plane, in front when none is
//!   more than `c` behind, behind when none is more than `c` in front, and is
//!   otherwise split exactly at the plane, so fragment areas add up to the
//!   surface's area.
//! * The walk gives a child the parameters `t` of the segment (within the
//!   parent's interval) whose point is on the child's side of the plane or
//!   within the node's tolerance `c + 2 max reach + round-off` of it, and
//!   tests the node's own fragments when that band is reached. A surface the
//!   segment crosses at `p = from + t (to - from)` has a fragment within
//!   `reach` of `p`, on the correct side of every ancestor's plane within
//!   `c`: so `t` lies in every interval down to that fragment's node. The
//!   intervals are computed afresh from the plane distances of the
//!   segment's ends at each node, so their round-off (a few units of 1e-16
//!   of the segment) does not accumulate with depth; the query's round-off
//!   allowance covers it.
//! * A closest-hit walk skips a region or a plane band only when its
//!   interval starts beyond the nearest crossing found so far: a nearer
//!   crossing lies in the intervals down to its fragment's node, so none
//!   is skipped.
//!
//! # Layout
//!
//! Nodes live in one `Vec` in depth-first order (the front child usually
//! follows its parent), children by index; each node's surfaces are a range
//! of one `Vec<u32>` of surface ids. Queries walk the tree iteratively with a
//! fixed stack of `2 x` [`MAX_DEPTH`] entries: no allocation and no interior
//! mutability, so any number of threads can query one tree.

use glam::{DVec2, DVec3};

use super::{AcceptanceRegion, Hit, InvalidTree, Nearest, Occluder, PreparedSurfaces, ray_end};
use crate::geometry::{self, clip};
use crate::scene::{self, Surface};

mod build;
mod cell;
mod traverse;
mod validate;

use build::*;
use cell::*;

/// The deepest a tree may grow; half the size of the query stack.
pub const MAX_DEPTH: usize = 64;

/// The segment test's edge tolerance (its reach here is taken four times
/// wider, so a slightly larger tolerance there would still be covered).
const CROSSING_TOLERANCE: f64 = super::EDGE_TOLERANCE;

/// Round-off allowance relative to the scene's scale (largest coordinate or
/// diagonal): covers the classification, splitting and crossing-point
/// arithmetic, whose errors are a few units of 1e-16 per step.
const ROUND_OFF: f64 = 1e-11;

/// Round-off allowance relative to a query's largest endpoint coordinate.
const QUERY_ROUND_OFF: f64 = 1e-13;

/// Marks an entry whose surface was split into several fragments, so a
/// query remembers having tested it.
const SPLIT_FLAG: u32 = 1 << 31;

/// No child.
const NONE: u32 = u32::MAX;

/// How many split surfaces a query remembers having tested.
const TESTED_MEMORY: usize = 16;

/// How a node's splitting plane is scored.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PlaneCost {
    /// The surface area heuristic over the node's convex region (see the
    /// module notes); a node whose best candidate costs more than testing
    /// its fragments becomes a leaf.
    SurfaceArea,
    /// `split_weight * splits + |front - back|` (Fuchs, Abram & Grant 1983),
    /// the classic score for a small, balanced tree; nodes are split down to
    /// [`BspSettings::leaf_size`] fragments.
    SplitsAndBalance {
        /// Cost of one split, in fragments of imbalance.
        split_weight: f64,
    },
}

/// How the tree is built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BspSettings {
    /// The score of a candidate plane.
    pub cost: PlaneCost,
    /// Surface planes tried per node, those of an evenly spaced sample of
    /// the node's fragments; `0` tries every fragment's plane.
    pub candidates: usize,
    /// Axis-aligned planes tried per axis and node: the boundaries of this
    /// many equal slabs across the fragments' bounding box (its faces
    /// included), scored by binning; `0` keeps to surface planes (a pure
    /// auto-partition, as the paper).
    pub axis_candidates: usize,
    /// Cost of visiting a node, in surface tests
    /// ([`PlaneCost::SurfaceArea`]).
    pub traversal_cost: f64,
    /// A node with at most this many fragments is a leaf.
    pub leaf_size: usize,
    /// Fragments may number at most this many times the surfaces (splits
    /// beyond are refused; at least 1).
    pub max_growth: f64,
    /// Fragments classified per candidate to estimate its counts at a large
    /// node; `0` classifies them all.
    pub cost_sample: usize,
    /// Distance within which a fragment counts as lying on a plane, relative
    /// to the scene's scale (its bounding-box diagonal or largest
    /// coordinate, whichever is larger).
    pub coplanar_tolerance: f64,
    /// Depth at which the remaining fragments go to a leaf; at most
    /// [`MAX_DEPTH`].
    pub max_depth: usize,
}

impl BspSettings {
    /// The default: the surface area heuristic over 16 surface planes and
    /// the 17 boundaries of 16 slabs per axis, leaves of up to 2 fragments,
    /// fragments at most three times the surfaces. Measured on 100,000 of
    /// the recorded shadow segments of Sponza and the conference room (as
    /// `radiosity experiment rays` records them): with 4, 8, 16 and 32 slabs
    /// per axis Sponza's tree tests 12.6, 13.0, 11.9 and 9.0 surfaces per
    /// ray, the conference room's 10.5 with 16 and 12.3 with 32 (and is
    /// slower), all for about the same build time; a budget of 2 tests 2.6
    /// times as many surfaces as 3 on Sponza, 4 a fifth fewer for 30% more
    /// nodes.
    #[must_use]
    pub fn sah() -> BspSettings {
        BspSettings {
            cost: PlaneCost::SurfaceArea,
            candidates: 16,
            axis_candidates: 16,
            traversal_cost: 1.0,
            leaf_size: 2,
            max_growth: 3.0,
            cost_sample: 512,
            coplanar_tolerance: 1e-9,
            max_depth: MAX_DEPTH,
        }
    }

    /// The surface area heuristic over surface planes only: the paper's
    /// auto-partition with a cost model and leaf buckets.
    #[must_use]
    pub fn auto_partition() -> BspSettings {
        BspSettings {
            axis_candidates: 0,
            ..BspSettings::sah()
        }
    }

    /// The previous default: 16 surface planes scored by `8 splits +
    /// |front - back|`, split down to single fragments.
    #[must_use]
    pub fn classic() -> BspSettings {
        BspSettings {
            cost: PlaneCost::SplitsAndBalance { split_weight: 8.0 },
            axis_candidates: 0,
            leaf_size: 1,
            max_growth: 4.0,
            ..BspSettings::sah()
        }
    }

    /// The first fragment's plane at every node, as the paper's description
    /// reads: cheapest to build, possibly deep and unbalanced.
    #[must_use]
    pub fn fastest_build() -> BspSettings {
        BspSettings {
            candidates: 1,
            ..BspSettings::classic()
        }
    }

    /// Every preset with its name, for tests and benchmarks.
    #[must_use]
    pub fn presets() -> [(&'static str, BspSettings); 4] {
        [
            ("sah", BspSettings::sah()),
            ("auto-partition", BspSettings::auto_partition()),
            ("classic", BspSettings::classic()),
            ("fastest-build", BspSettings::fastest_build()),
        ]
    }

    /// The settings with out-of-range values replaced: a negative or
    /// non-finite weight, cost or tolerance takes the default, the growth
    /// is at least 1, the leaf size at least 1, the depth is clamped to
    /// `1..=MAX_DEPTH`.
    #[must_use]
    pub fn sanitized(self) -> BspSettings {
        let default = BspSettings::sah();
        let ok = |v: f64| v.is_finite() && v >= 0.0;
        let or_default = |v: f64, d: f64| if ok(v) { v } else { d };
        BspSettings {
            cost: match self.cost {
                PlaneCost::SurfaceArea => PlaneCost::SurfaceArea,
                PlaneCost::SplitsAndBalance { split_weight } => PlaneCost::SplitsAndBalance {
                    split_weight: or_default(split_weight, 8.0),
                },
            },
            candidates: self.candidates,
            axis_candidates: self.axis_candidates.min(1024),
            traversal_cost: or_default(self.traversal_cost, default.traversal_cost),
            leaf_size: self.leaf_size.max(1),
            max_growth: if self.max_growth >= 1.0 {
                self.max_growth
            } else {
                default.max_growth
            },
            cost_sample: self.cost_sample,
            coplanar_tolerance: or_default(self.coplanar_tolerance, default.coplanar_tolerance),
            max_depth: self.max_depth.clamp(1, MAX_DEPTH),
        }
    }
}

impl Default for BspSettings {
    fn default() -> Self {
        BspSettings::sah()
    }
}

/// Size of a built tree.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BspStats {
    /// Nodes, leaves included.
    pub nodes: usize,
    /// Leaf buckets.
    pub leaves: usize,
    /// Nodes on the longest root-to-leaf path (0 for an empty tree).
    pub depth: usize,
    /// Stored polygon pieces: surfaces plus splits.
    pub fragments: usize,
    /// Fragments cut in two by a splitting plane.
    pub splits: usize,
    /// Fragments in the largest leaf.
    pub largest_leaf: usize,
    /// Splits refused because a subtree had used its share of the fragment
    /// budget ([`BspSettings::max_growth`]).
    pub refused: usize,
}

/// One tree node: a splitting plane, its children and the surfaces lying on
/// it. A leaf bucket has a zero normal, so every segment "reaches" its plane
/// and its surfaces are always tested.
#[derive(Clone, Copy, Debug)]
struct Node {
    normal: DVec3,
    offset: f64,
    /// Distance from the plane within which a segment counts as reaching it.
    tolerance: f64,
    /// `[front, back]`, or [`NONE`].
    children: [u32; 2],
    /// Range of `Bsp::entries` lying on the plane (or in the bucket).
    first: u32,
    end: u32,
}

impl Node {
    fn is_leaf(&self) -> bool {
        self.normal == DVec3::ZERO
    }
}

/// A fragment during construction.
struct Piece {
    surface: u32,
    polygon: Vec<DVec3>,
}

/// Where a fragment lies relative to a plane.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Side {
    On,
    Front,
    Back,
    Both,
}

/// A candidate splitting plane.
#[derive(Clone, Copy, Debug)]
struct Plane {
    normal: DVec3,
    offset: f64,
    /// The surface whose plane it is: its fragments lie on it whatever
    /// their corners' round-off or non-planarity.
    own: Option<u32>,
}

/// A BSP tree over a scene's surfaces answering shadow-segment and
/// closest-hit queries.
pub struct Bsp<'a> {
    surfaces: &'a [Surface],
    /// The surfaces laid out for the segment test.
    prepared: PreparedSurfaces,
    nodes: Vec<Node>,
    /// Surface id of each stored fragment, with [`SPLIT_FLAG`] when the
    /// surface has several fragments; node ranges index it.
    entries: Vec<u32>,
    /// How far an accepted crossing point can be from each surface.
    reach: Vec<f64>,
    coplanar: f64,
    round_off: f64,
    settings: BspSettings,
    stats: BspStats,
}

impl<'a> Bsp<'a> {
    /// Builds the tree with [`BspSettings::sah`].
    #[must_use]
    pub fn new(surfaces: &'a [Surface]) -> Bsp<'a> {
        Bsp::with_settings(surfaces, BspSettings::sah())
    }

    /// Builds the tree with the given settings (sanitised first, see
    /// [`BspSettings::sanitized`]).
    ///
    /// # Panics
    /// With 2^31 surfaces or more, which would not fit in memory anyway.
    #[must_use]
    pub fn with_settings(surfaces: &'a [Surface], settings: BspSettings) -> Bsp<'a> {
        assert!(
            surfaces.len() < SPLIT_FLAG as usize,
            "a BSP tree holds fewer than 2^31 surfaces"
        );
        let settings = settings.sanitized();
        let bounds = scene::bounds_of(surfaces);
        let scale = scene_scale(bounds);
        let mut bsp = Bsp {
            surfaces,
            prepared: PreparedSurfaces::new(surfaces),
            nodes: Vec::new(),
            entries: Vec::new(),
            reach: surfaces.iter().map(crossing_reach).collect(),
            coplanar: settings.coplanar_tolerance * scale,
            round_off: ROUND_OFF * scale,
            settings,
            stats: BspStats::default(),
        };
        let pieces: Vec<Piece> = surfaces
            .iter()
            .enumerate()
            .map(|(i, s)| Piece {
                surface: i as u32,
                polygon: s.polygon.clone(),
            })
            .collect();
        let cell = Cell::around(bounds);
        let allowance = ((settings.max_growth - 1.0) * surfaces.len() as f64).min(1e15) as usize;
        let mut scratch = Scratch::default();
        bsp.build(pieces, cell, 1, allowance, &mut scratch);
        bsp.flag_split_surfaces();
        bsp.stats.nodes = bsp.nodes.len();
        bsp.stats.fragments = bsp.entries.len();
        bsp
    }

    /// Size of the tree.
    #[must_use]
    pub fn stats(&self) -> BspStats {
        self.stats
    }

    /// The settings the tree was built with (after sanitising).
    #[must_use]
    pub fn settings(&self) -> BspSettings {
        self.settings
    }

    /// Bytes of the tree's own arrays (nodes, fragment entries, reaches),
    /// without the prepared surfaces every accelerator shares.
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        use std::mem::size_of;
        self.nodes.capacity() * size_of::<Node>()
            + self.entries.capacity() * size_of::<u32>()
            + self.reach.capacity() * size_of::<f64>()
    }

    /// Like [`Occluder::occluded`], also returning how many surfaces were
    /// tested with [`segment_crosses`](super::segment_crosses) and how many
    /// nodes were visited (for benchmarks; brute force tests surfaces in
    /// input order up to the first blocker).
    #[must_use]
    pub fn occluded_counting(&self, from: DVec3, to: DVec3, skip: [u32; 2]) -> (bool, u32, u32) {
        self.walk(from, to, skip)
    }
}

impl Occluder for Bsp<'_> {
    fn occluded(&self, from: DVec3, to: DVec3, skip: [u32; 2]) -> bool {
        self.walk(from, to, skip).0
    }

    fn occluded_counting(&self, from: DVec3, to: DVec3, skip: [u32; 2]) -> (bool, u32, u32) {
        Bsp::occluded_counting(self, from, to, skip)
    }

    fn closest_hit(&self, o: DVec3, d: DVec3, max_t: f64, skip: [u32; 2]) -> Option<Hit> {
        self.closest_hit_counting(o, d, max_t, skip).0
    }

    fn validate(&self) -> Result<(), InvalidTree> {
        Bsp::validate(self)
    }

    fn build_statistics(&self) -> Vec<(&'static str, usize)> {
        let s = self.stats();
        vec![
            ("nodes", s.nodes),
            ("leaves", s.leaves),
            ("depth", s.depth),
            ("fragments", s.fragments),
            ("splits", s.splits),
            ("largest_leaf", s.largest_leaf),
            ("refused", s.refused),
            ("bytes", self.memory_bytes()),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::brute::BruteForce;

    use crate::accel::test_scenes::{NONE_SKIPPED, quad, square_at_z};

    #[test]
    fn empty_scene_blocks_nothing() {
        let bsp = Bsp::new(&[]);
        assert_eq!(bsp.stats(), BspStats::default());
        bsp.validate().unwrap();
        assert!(!bsp.occluded(DVec3::ZERO, DVec3::ONE, NONE_SKIPPED));
    }

    #[test]
    fn one_square_is_one_node() {
        let surfaces = [square_at_z(1.0, 1.0)];
        let bsp = Bsp::new(&surfaces);
        bsp.validate().unwrap();
        let stats = bsp.stats();
        assert_eq!(
            (stats.nodes, stats.depth, stats.fragments, stats.splits),
            (1, 1, 1, 0)
        );
        assert!(bsp.occluded(DVec3::ZERO, DVec3::new(0.0, 0.0, 2.0), NONE_SKIPPED));
        assert!(!bsp.occluded(DVec3::ZERO, DVec3::new(0.0, 0.0, 2.0), [0, u32::MAX]));
        // Segments that stay on one side never test the square.
        assert_eq!(
            bsp.occluded_counting(DVec3::ZERO, DVec3::new(0.0, 0.0, 0.5), NONE_SKIPPED),
            (false, 0, 1)
        );
    }

    #[test]
    fn straddling_surface_is_split_and_keeps_its_area() {
        // A wall in the plane x = 0 crossing the floor z = 0.
        let surfaces = [
            square_at_z(0.0, 2.0),
            quad([
                [0.0, -1.0, -1.0],
                [0.0, 1.0, -1.0],
                [0.0, 1.0, 1.0],
                [0.0, -1.0, 1.0],
            ]),
        ];
        let bsp = Bsp::with_settings(&surfaces, BspSettings::fastest_build());
        bsp.validate().unwrap();
        let stats = bsp.stats();
        assert_eq!(stats.splits, 1);
        assert_eq!(stats.fragments, 3);
        assert_eq!(stats.depth, 2);
        let brute = BruteForce::new(&surfaces);
        for (from, to) in [
            (DVec3::new(-1.0, 0.0, 0.5), DVec3::new(1.0, 0.0, 0.5)),
            (DVec3::new(-1.0, 0.0, -0.5), DVec3::new(1.0, 0.0, -0.5)),
            (DVec3::new(-1.0, 0.0, 0.5), DVec3::new(1.0, 0.0, -0.5)),
            (DVec3::new(0.5, 0.5, 1.0), DVec3::new(0.5, 0.5, -1.0)),
        ] {
            assert_eq!(
                bsp.occluded(from, to, NONE_SKIPPED),
                brute.occluded(from, to, NONE_SKIPPED)
            );
        }
        // The split wall is tested once even though both pieces are visited.
        let (blocked, tests, _) = bsp.occluded_counting(
            DVec3::new(-1.0, 3.0, 0.5),
            DVec3::new(1.0, 3.0, -0.5),
            NONE_SKIPPED,
        );
        assert!(!blocked);
        assert_eq!(tests, 2);
    }

    #[test]
    fn depth_limit_makes_a_bucket_that_is_always_tested() {
        let surfaces: Vec<Surface> = (0..10).map(|i| square_at_z(f64::from(i), 1.0)).collect();
        let settings = BspSettings {
            max_depth: 2,
            ..BspSettings::fastest_build()
        };
        let bsp = Bsp::with_settings(&surfaces, settings);
        bsp.validate().unwrap();
        assert_eq!(bsp.stats().leaves, 1);
        assert_eq!(bsp.stats().depth, 2);
        let brute = BruteForce::new(&surfaces);
        for i in 0..10 {
            let from = DVec3::new(0.1, 0.2, f64::from(i) - 0.5);
            let to = DVec3::new(-0.3, 0.1, 9.5 - f64::from(i));
            assert_eq!(
                bsp.occluded(from, to, NONE_SKIPPED),
                brute.occluded(from, to, NONE_SKIPPED)
            );
        }
    }

    #[test]
    fn settings_are_sanitized() {
        let default = BspSettings::sah();
        let s = BspSettings {
            cost: PlaneCost::SplitsAndBalance {
                split_weight: f64::NAN,
            },
            candidates: 3,
            traversal_cost: -1.0,
            leaf_size: 0,
            max_growth: 0.5,
            coplanar_tolerance: -1.0,
            max_depth: 1000,
            ..default
        }
        .sanitized();
        assert_eq!(s.cost, PlaneCost::SplitsAndBalance { split_weight: 8.0 });
        assert_eq!(s.traversal_cost, default.traversal_cost);
        assert_eq!(s.leaf_size, 1);
        assert_eq!(s.max_growth, default.max_growth);
        assert_eq!(s.coplanar_tolerance, default.coplanar_tolerance);
        assert_eq!(s.max_depth, MAX_DEPTH);
        assert_eq!(s.candidates, 3);
    }

    #[test]
    fn cells_split_into_parts_whose_areas_add_up() {
        let square = square_at_z(0.0, 1.0);
        // The box around it: [-1.2, 1.2] x [-1.2, 1.2] x [-0.28, 0.28] (a
        // tenth of the diagonal added on every side).
        let cell = Cell::around(scene::bounds_of(std::slice::from_ref(&square)));
        let mut scratch = Scratch::default();
        let area = cell.area();
        let (lo, hi) = cell.bounds();
        let d = hi - lo;
        assert!((area - 2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)).abs() < 1e-12);
        // Halved across x: each half has the cap plus half the rest.
        let (f, b, cap) = cell.split_areas(DVec3::X, 0.0, &mut scratch);
        assert!((cap - d.y * d.z).abs() < 1e-12, "{cap}");
        assert!((f - (0.5 * area + cap)).abs() < 1e-12 && (b - f).abs() < 1e-12);
        // An oblique plane: the parts add up to the whole plus two caps,
        // and the cells `split` makes have those areas.
        let normal = DVec3::new(1.0, 2.0, 3.0).normalize();
        let (f, b, cap) = cell.split_areas(normal, 0.1, &mut scratch);
        assert!(cap > 0.0 && (f + b - area - 2.0 * cap).abs() < 1e-12);
        let (front, back) = cell.split(normal, 0.1, &mut scratch);
        assert!((front.area() - f).abs() < 1e-12 && (back.area() - b).abs() < 1e-12);
        // A plane missing the cell leaves it whole on one side.
        let (f, b, cap) = cell.split_areas(DVec3::Z, -5.0, &mut scratch);
        assert_eq!((b, cap), (0.0, 0.0));
        assert!((f - area).abs() < 1e-12);
        // The box-only estimate agrees on an axis-aligned cut.
        let (bf, bb) = box_split_areas(lo, hi, 0, 0.0);
        let (f, b, _) = cell.split_areas(DVec3::X, 0.0, &mut scratch);
        assert!((bf - f).abs() < 1e-12 && (bb - b).abs() < 1e-12);
    }

    #[test]
    fn coplanar_fragments_are_divided_by_axis_planes() {
        // A 16 x 16 grid of unit squares in one plane: auto-partition can
        // only store them on one node, the default divides them so a
        // segment through one square tests a few, not all.
        let surfaces: Vec<Surface> = (0..256)
            .map(|k| {
                let (x, y) = (f64::from(k % 16), f64::from(k / 16));
                quad([
                    [x, y, 0.0],
                    [x + 1.0, y, 0.0],
                    [x + 1.0, y + 1.0, 0.0],
                    [x, y + 1.0, 0.0],
                ])
            })
            .collect();
        let from = DVec3::new(7.3, 7.6, 1.0);
        let to = DVec3::new(7.4, 7.5, -1.0);
        let paper = Bsp::with_settings(&surfaces, BspSettings::auto_partition());
        paper.validate().unwrap();
        assert_eq!(paper.stats().nodes, 1);
        let (blocked, tests, _) = paper.occluded_counting(from, to, NONE_SKIPPED);
        assert!(blocked && tests >= 1);
        let bsp = Bsp::new(&surfaces);
        bsp.validate().unwrap();
        assert!(bsp.stats().nodes > 16, "{:?}", bsp.stats());
        let (blocked, tests, _) = bsp.occluded_counting(from, to, NONE_SKIPPED);
        assert!(blocked && tests <= 4, "{tests}");
        // Missing the grid's plane, nothing is tested.
        let (blocked, tests, _) = bsp.occluded_counting(
            DVec3::new(3.0, 3.0, 1.0),
            DVec3::new(9.0, 2.0, 0.5),
            NONE_SKIPPED,
        );
        assert_eq!((blocked, tests), (false, 0));
    }

    #[test]
    fn the_walk_only_visits_regions_the_segment_passes_through() {
        // Two stacks of 32 parallel squares far apart along x: a segment in
        // the first stack, crossing the planes of the second (which extend
        // across all space) but not the second stack itself, tests none of
        // the second stack's squares.
        let mut surfaces = Vec::new();
        for i in 0..32 {
            let z = f64::from(i);
            surfaces.push(quad([
                [0.0, 0.0, z],
                [1.0, 0.0, z],
                [1.0, 1.0, z],
                [0.0, 1.0, z],
            ]));
            let z = z + 0.5;
            surfaces.push(quad([
                [100.0, 0.0, z],
                [101.0, 0.0, z],
                [101.0, 1.0, z],
                [100.0, 1.0, z],
            ]));
        }
        let bsp = Bsp::new(&surfaces);
        bsp.validate().unwrap();
        // From z = 3.2 to 9.9 inside the first stack: blocked by z = 4.
        let (from, to) = (DVec3::new(0.5, 0.5, 3.2), DVec3::new(0.6, 0.4, 9.9));
        let (blocked, tests, visited) = bsp.occluded_counting(from, to, NONE_SKIPPED);
        assert!(blocked);
        assert!(tests <= 4, "{tests} tests");
        assert!(
            visited <= 2 * bsp.stats().depth as u32,
            "{visited} nodes visited"
        );
        // Through the first stack from below, skipping nothing: the first
        // square blocks.
        let brute = BruteForce::new(&surfaces);
        for (from, to) in [
            (DVec3::new(0.5, 0.5, -1.0), DVec3::new(0.5, 0.5, 40.0)),
            (DVec3::new(0.5, 0.5, 31.5), DVec3::new(100.5, 0.5, 31.7)),
            (DVec3::new(-5.0, 0.5, 10.2), DVec3::new(105.0, 0.5, 10.7)),
        ] {
            assert_eq!(
                bsp.occluded(from, to, NONE_SKIPPED),
                brute.occluded(from, to, NONE_SKIPPED)
            );
        }
    }

    #[test]
    fn reach_grows_at_sharp_corners() {
        let square = square_at_z(0.0, 1.0);
        let r = crossing_reach(&square);
        let tol = 4.0 * CROSSING_TOLERANCE * 2.0;
        // A square's widened corner is sqrt(2) tolerances from the corner.
        assert!(r >= tol * 2f64.sqrt() && r < 3.0 * tol, "{r}");
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
        let t = 4.0 * CROSSING_TOLERANCE * needle.area.sqrt();
        // Half-angle 5e-4 rad: the tip's region reaches ~t / 5e-4.
        let r = crossing_reach(&needle);
        assert!(r > 1000.0 * t && r < 5000.0 * t, "{r} vs {t}");
    }
}
