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
//! It stops at the first blocker.
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
//!
//! # Layout
//!
//! Nodes live in one `Vec` in depth-first order (the front child usually
//! follows its parent), children by index; each node's surfaces are a range
//! of one `Vec<u32>` of surface ids. Queries walk the tree iteratively with a
//! fixed stack of `2 x` [`MAX_DEPTH`] entries: no allocation and no interior
//! mutability, so any number of threads can query one tree.

use glam::{DVec2, DVec3};

use super::{AcceptanceRegion, Occluder, PreparedSurfaces};
use crate::geometry;
use crate::scene::Surface;

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
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
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

/// What the walk still has to do, on its stack.
#[derive(Clone, Copy, Debug, Default)]
struct Pending {
    node: u32,
    /// Test the node's own fragments (else walk its subtree).
    plane: bool,
    /// The segment's parameter interval inside the node's region.
    t0: f64,
    t1: f64,
}

/// A query's memory of split surfaces already tested: the last
/// [`TESTED_MEMORY`], in a ring.
struct Tested {
    ids: [u32; TESTED_MEMORY],
    len: usize,
    next: usize,
}

/// A BSP tree over a scene's surfaces answering shadow-segment queries.
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
        let scale = scene_scale(surfaces);
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
        let cell = Cell::around(surfaces);
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

    /// Checks the tree's invariants: a well-formed depth-first node array;
    /// every fragment on its node's plane and on the correct side of every
    /// ancestor's plane (within the coplanar tolerance); every fragment on
    /// its surface's plane and inside its polygon; each surface's fragments
    /// adding up to its area (1e-9 relative, plus the corners' round-off,
    /// plus the tilt of the fragments of a slightly non-planar polygon; the
    /// areas computed about the polygon's first corner to keep their digits);
    /// node tolerances
    /// covering the surfaces below them; statistics matching the tree.
    pub fn validate(&self) -> Result<(), String> {
        let nodes = &self.nodes;
        let mut parent = vec![NONE; nodes.len()];
        let mut depth = vec![0usize; nodes.len()];
        let mut expected_first = 0u32;
        for (i, node) in nodes.iter().enumerate() {
            if node.first != expected_first || node.end < node.first {
                return Err(format!(
                    "node {i}: fragment range does not follow its predecessor's"
                ));
            }
            expected_first = node.end;
            if i == 0 {
                depth[0] = 1;
            } else if parent[i] == NONE {
                return Err(format!("node {i} has no parent (or comes before it)"));
            }
            for &child in &node.children {
                if child == NONE {
                    continue;
                }
                let c = child as usize;
                if c <= i || c >= nodes.len() {
                    return Err(format!("node {i}: child {child} out of depth-first order"));
                }
                if parent[c] != NONE {
                    return Err(format!("node {c} has two parents"));
                }
                parent[c] = i as u32;
                depth[c] = depth[i] + 1;
            }
            if node.is_leaf() && node.children != [NONE; 2] {
                return Err(format!("leaf bucket {i} has children"));
            }
            if !node.is_leaf() && (node.normal.length() - 1.0).abs() > 1e-9 {
                return Err(format!("node {i}: normal is not a unit vector"));
            }
        }
        if expected_first as usize != self.entries.len() {
            return Err("node ranges do not cover the fragment list exactly".into());
        }
        let max_depth = depth.iter().copied().max().unwrap_or(0);
        if max_depth != self.stats.depth || max_depth > self.settings.max_depth {
            return Err(format!(
                "depth {max_depth}, statistics say {}, limit {}",
                self.stats.depth, self.settings.max_depth
            ));
        }
        let leaves = nodes.iter().filter(|n| n.is_leaf()).count();
        let largest = nodes
            .iter()
            .filter(|n| n.is_leaf())
            .map(|n| (n.end - n.first) as usize)
            .max()
            .unwrap_or(0);
        if self.stats.nodes != nodes.len()
            || self.stats.fragments != self.entries.len()
            || self.stats.fragments != self.surfaces.len() + self.stats.splits
            || self.stats.leaves != leaves
            || self.stats.largest_leaf != largest
        {
            return Err(format!("statistics {:?} do not match the tree", self.stats));
        }

        let slack = self.coplanar + self.round_off;
        let mut area = vec![0.0; self.surfaces.len()];
        let mut count = vec![0usize; self.surfaces.len()];
        let mut max_reach = vec![0.0f64; nodes.len()];
        for (i, node) in nodes.iter().enumerate() {
            for k in node.first..node.end {
                let entry = self.entries[k as usize];
                let id = (entry & !SPLIT_FLAG) as usize;
                let Some(surface) = self.surfaces.get(id) else {
                    return Err(format!("node {i}: surface id {id} out of range"));
                };
                let polygon = &self.replay(id as u32, i, &parent);
                if polygon.len() < 3 {
                    return Err(format!(
                        "node {i}: fragment of surface {id} has fewer than 3 corners"
                    ));
                }
                area[id] += local_area(polygon);
                count[id] += 1;
                let (lo, hi) = distance_range(polygon, surface.normal, surface.offset);
                let off_plane = self.reach[id] + self.round_off;
                if lo < -off_plane || hi > off_plane {
                    return Err(format!(
                        "a fragment of surface {id} leaves the surface's plane"
                    ));
                }
                // Containment about the polygon's first corner, with the
                // normal computed there: far from the origin, a tiny
                // polygon's own normal (Newell's sum about the origin) can
                // have lost its digits.
                let origin = surface.polygon[0];
                let local: Vec<DVec3> = surface.polygon.iter().map(|p| *p - origin).collect();
                let local_normal = geometry::normal(&local).unwrap_or(surface.normal);
                let inside = 1e-9 * surface.area.sqrt() + self.round_off;
                if !polygon
                    .iter()
                    .all(|p| geometry::convex_contains(&local, local_normal, *p - origin, inside))
                {
                    return Err(format!(
                        "a fragment of surface {id} leaves the surface's polygon"
                    ));
                }
                // The fragment lies on its node's plane and on the right side
                // of every ancestor's.
                let mut at = i;
                let mut child = NONE;
                loop {
                    let n = &nodes[at];
                    max_reach[at] = max_reach[at].max(self.reach[id]);
                    if n.normal != DVec3::ZERO {
                        let (lo, hi) = distance_range(polygon, n.normal, n.offset);
                        let ok = if child == NONE {
                            let on = slack + self.reach[id];
                            lo >= -on && hi <= on
                        } else if child == n.children[0] {
                            lo >= -slack
                        } else {
                            hi <= slack
                        };
                        if !ok {
                            return Err(format!(
                                "a fragment of surface {id} stored at node {i} is on the wrong side of node {at}'s plane"
                            ));
                        }
                    }
                    if parent[at] == NONE {
                        break;
                    }
                    child = at as u32;
                    at = parent[at] as usize;
                }
            }
        }
        for (i, node) in nodes.iter().enumerate() {
            if node.tolerance < self.coplanar + 2.0 * max_reach[i] {
                return Err(format!(
                    "node {i}: tolerance does not cover the surfaces below it"
                ));
            }
        }
        for (id, surface) in self.surfaces.iter().enumerate() {
            if count[id] == 0 {
                return Err(format!("surface {id} has no fragment"));
            }
            let expected = local_area(&surface.polygon);
            // Split corners are rounded to the coordinates' precision, which
            // far from the origin is coarse next to a tiny polygon.
            let corner_round_off = 16.0 * f64::EPSILON * self.round_off / ROUND_OFF;
            let diameter = geometry::diameter(&surface.polygon);
            let perimeter = 4.0 * diameter;
            // A slightly non-planar polygon (as the OBJ loader accepts them)
            // splits into fragments tilted from its plane by up to about
            // `4 d / diameter`, `d` its corners' largest distance from the
            // plane; each fragment's area exceeds its projection by half
            // the square of that, so the pieces' areas add up to a little
            // more than the whole's.
            let bend = surface
                .polygon
                .iter()
                .map(|p| (surface.normal.dot(*p) - surface.offset).abs())
                .fold(0.0, f64::max);
            let tilt = if diameter > 0.0 {
                4.0 * bend / diameter
            } else {
                0.0
            };
            let slack = (1e-9 + 0.5 * tilt * tilt) * expected + corner_round_off * perimeter;
            if (area[id] - expected).abs() > slack {
                return Err(format!(
                    "surface {id}: fragments cover {} m^2 of {expected} m^2",
                    area[id]
                ));
            }
        }
        for k in 0..self.entries.len() {
            let entry = self.entries[k];
            let split = count[(entry & !SPLIT_FLAG) as usize] > 1;
            if (entry & SPLIT_FLAG != 0) != split {
                return Err(format!("entry {k}: split flag is wrong"));
            }
        }
        Ok(())
    }

    /// The fragment of surface `id` stored at node `at`, rebuilt by
    /// replaying the build's classifications and splits down the path from
    /// the root (the same arithmetic in the same order gives the same
    /// corners), so the tree need not keep fragment geometry.
    fn replay(&self, id: u32, at: usize, parent: &[u32]) -> Vec<DVec3> {
        let surface = &self.surfaces[id as usize];
        let mut path = Vec::new();
        let mut node = at;
        while parent[node] != NONE {
            path.push((parent[node] as usize, node as u32));
            node = parent[node] as usize;
        }
        let mut polygon = surface.polygon.clone();
        for &(ancestor, child) in path.iter().rev() {
            let n = &self.nodes[ancestor];
            // A surface always lies on its own plane (see `side`).
            let own = n.normal == surface.normal && n.offset == surface.offset;
            if !own && classify(&polygon, n.normal, n.offset, self.coplanar) == Side::Both {
                let (front, back) = split(&polygon, n.normal, n.offset);
                polygon = if child == n.children[0] { front } else { back };
            }
        }
        polygon
    }

    /// Builds the subtree over `pieces` in `cell` at `depth` (root = 1),
    /// allowed to create `allowance` new fragments by splitting, and returns
    /// its index, or [`NONE`] for no pieces.
    fn build(
        &mut self,
        pieces: Vec<Piece>,
        cell: Cell,
        depth: usize,
        allowance: usize,
        scratch: &mut Scratch,
    ) -> u32 {
        if pieces.is_empty() {
            return NONE;
        }
        self.stats.depth = self.stats.depth.max(depth);
        let max_reach = pieces
            .iter()
            .map(|p| self.reach[p.surface as usize])
            .fold(0.0, f64::max);
        // A fragment on the plane lies within the coplanar tolerance or its
        // surface's non-planarity of it, and a crossing point within its
        // reach of the fragment; both are below the reach.
        let tolerance = self.coplanar + 2.0 * max_reach + self.round_off;
        let index = self.nodes.len() as u32;
        let chosen = if pieces.len() <= self.settings.leaf_size || depth >= self.settings.max_depth
        {
            None
        } else {
            let common = self.common_plane(&pieces);
            self.choose_plane(&pieces, &cell, common, allowance, scratch)
        };
        let Some(plane) = chosen else {
            return self.leaf(&pieces, tolerance);
        };

        let n = pieces.len();
        let sides: Vec<Side> = pieces.iter().map(|p| self.side(p, &plane)).collect();
        let splits = sides.iter().filter(|&&s| s == Side::Both).count();
        if splits > allowance {
            // The sampled estimate was too low for this subtree's budget.
            self.stats.refused += 1;
            return self.leaf(&pieces, tolerance);
        }
        if splits == n {
            // Every fragment straddles (fragments meeting at a point, or
            // smaller than the coplanar tolerance): cutting divides
            // nothing.
            return self.leaf(&pieces, tolerance);
        }
        let mut front = Vec::new();
        let mut back = Vec::new();
        let mut on = Vec::new();
        for (piece, side) in pieces.into_iter().zip(sides) {
            match side {
                Side::On => on.push(piece),
                Side::Front => front.push(piece),
                Side::Back => back.push(piece),
                Side::Both => {
                    let (f, b) = split(&piece.polygon, plane.normal, plane.offset);
                    front.push(Piece {
                        surface: piece.surface,
                        polygon: f,
                    });
                    back.push(Piece {
                        surface: piece.surface,
                        polygon: b,
                    });
                }
            }
        }
        // Many fragments on the plane would all be tested by every segment
        // crossing it anywhere in the region: with the surface area
        // heuristic they go to the child of smaller area instead, to be
        // divided there (as kd-trees place planar primitives; Wald & Havran
        // 2006), unless that child would then hold everything.
        if self.settings.cost == PlaneCost::SurfaceArea && on.len() > self.settings.leaf_size {
            let (f, b, _) = cell.split_areas(plane.normal, plane.offset, scratch);
            let (smaller, larger) = if f <= b {
                (&mut front, &mut back)
            } else {
                (&mut back, &mut front)
            };
            if smaller.len() + on.len() < n {
                smaller.append(&mut on);
            } else if larger.len() + on.len() < n {
                larger.append(&mut on);
            }
        }
        let first = self.entries.len() as u32;
        for piece in &on {
            self.store(piece);
        }
        self.stats.splits += splits;
        self.nodes.push(Node {
            normal: plane.normal,
            offset: plane.offset,
            tolerance,
            children: [NONE; 2],
            first,
            end: self.entries.len() as u32,
        });
        let left = allowance - splits;
        let total = (front.len() + back.len()).max(1);
        let front_allowance = (left as u128 * front.len() as u128 / total as u128) as usize;
        let back_allowance = left - front_allowance;
        let (front_cell, back_cell) = cell.split(plane.normal, plane.offset, scratch);
        let f = self.build(front, front_cell, depth + 1, front_allowance, scratch);
        let b = self.build(back, back_cell, depth + 1, back_allowance, scratch);
        self.nodes[index as usize].children = [f, b];
        index
    }

    /// A node for pieces that are not divided further: a plane node when
    /// they all lie on the first one's plane (tested only by segments that
    /// reach it), else a leaf bucket (tested by every segment that visits
    /// it).
    fn leaf(&mut self, pieces: &[Piece], tolerance: f64) -> u32 {
        let index = self.nodes.len() as u32;
        let common = self.common_plane(pieces);
        let first = self.entries.len() as u32;
        for piece in pieces {
            self.store(piece);
        }
        let (normal, offset) = if let Some(plane) = common {
            (plane.normal, plane.offset)
        } else {
            self.stats.leaves += 1;
            self.stats.largest_leaf = self.stats.largest_leaf.max(pieces.len());
            (DVec3::ZERO, 0.0)
        };
        self.nodes.push(Node {
            normal,
            offset,
            tolerance,
            children: [NONE; 2],
            first,
            end: self.entries.len() as u32,
        });
        index
    }

    /// The first piece's plane, if every piece lies on it.
    fn common_plane(&self, pieces: &[Piece]) -> Option<Plane> {
        let own = pieces.first()?.surface;
        let surface = &self.surfaces[own as usize];
        let plane = Plane {
            normal: surface.normal,
            offset: surface.offset,
            own: Some(own),
        };
        pieces
            .iter()
            .all(|p| self.side(p, &plane) == Side::On)
            .then_some(plane)
    }

    fn side(&self, piece: &Piece, plane: &Plane) -> Side {
        if plane.own == Some(piece.surface) {
            Side::On
        } else {
            classify(&piece.polygon, plane.normal, plane.offset, self.coplanar)
        }
    }

    fn store(&mut self, piece: &Piece) {
        self.entries.push(piece.surface);
    }

    /// The surface planes a node tries: those of an evenly spaced sample of
    /// its fragments.
    fn surface_candidates(&self, pieces: &[Piece], out: &mut Vec<Plane>) {
        out.clear();
        let n = pieces.len();
        let k = match self.settings.candidates {
            0 => n,
            c => c.min(n),
        };
        let mut last = u32::MAX;
        for c in 0..k {
            let id = pieces[c * n / k].surface;
            // Consecutive fragments of one surface share its plane.
            if id == last {
                continue;
            }
            last = id;
            let s = &self.surfaces[id as usize];
            out.push(Plane {
                normal: s.normal,
                offset: s.offset,
                own: Some(id),
            });
        }
    }

    /// The cheapest candidate plane, or `None` when the node should be a
    /// leaf: no candidate fits the fragment budget or divides anything, or
    /// (surface area heuristic) none costs less than testing every
    /// fragment.
    ///
    /// Surface planes are scored by classifying a sample of the fragments
    /// against each. Axis-aligned planes are the `bins + 1` boundaries of
    /// `bins` equal slabs across the fragments' bounding box on each axis,
    /// scored together by binning (Wald & Havran 2006): each sampled
    /// fragment's lowest and highest coordinate is put in a slab, and
    /// running sums give, for every boundary, the fragments wholly above it
    /// and wholly below it; the rest straddle it. The box's own faces are
    /// boundaries too: cutting off empty space.
    fn choose_plane(
        &self,
        pieces: &[Piece],
        cell: &Cell,
        common: Option<Plane>,
        allowance: usize,
        scratch: &mut Scratch,
    ) -> Option<Plane> {
        // Fragments all in one plane: a segment meets that plane at one
        // point, so the chance of testing a part of them is the share of
        // their extent in the plane (their bounding rectangle there) that
        // part covers: a two-dimensional surface area heuristic. Their own
        // plane divides nothing.
        let section = match (self.settings.cost, common) {
            (PlaneCost::SurfaceArea, Some(p)) => in_plane_bounds(pieces, p.normal),
            _ => None,
        };
        let section_area = section.as_ref().map_or(0.0, |s| geometry::area(s));
        let n = pieces.len();
        let sample = match self.settings.cost_sample {
            0 => n,
            s => s.min(n),
        };
        let scale = n as f64 / sample as f64;
        let sampled = |i: usize| &pieces[i * n / sample];
        let area = cell.area();
        let mut best: Option<(f64, Plane)> = None;
        // Counts are `[on, front, back, both]` in the sample.
        let mut consider = |plane: Plane, counts: [usize; 4], scratch: &mut Scratch| {
            let [on, front, back, both] = counts.map(|c| c as f64 * scale);
            if both > allowance as f64 {
                return;
            }
            let cost = match self.settings.cost {
                PlaneCost::SurfaceArea if section.is_some() => {
                    // Cutting off empty space does not shrink the
                    // fragments' extent: only planes dividing them count.
                    if !(section_area > 0.0 && section_area.is_finite())
                        || front + both == 0.0
                        || back + both == 0.0
                    {
                        return;
                    }
                    let section = section.as_deref().unwrap_or_default();
                    let (f, b) = polygon_split_areas(section, plane.normal, plane.offset, scratch);
                    self.settings.traversal_cost
                        + (f * (front + both) + b * (back + both)) / section_area
                }
                PlaneCost::SurfaceArea => {
                    if !(area > 0.0 && area.is_finite()) {
                        return;
                    }
                    let (f, b, cap) = cell.split_areas(plane.normal, plane.offset, scratch);
                    // Fragments on the plane: stored at the node, or in the
                    // smaller child when many (see `build`).
                    let planar = if on > self.settings.leaf_size as f64 {
                        f.min(b) * on
                    } else {
                        2.0 * cap * on
                    };
                    self.settings.traversal_cost
                        + (f * (front + both) + b * (back + both) + planar) / area
                }
                PlaneCost::SplitsAndBalance { split_weight } => {
                    // A plane holding nothing and leaving everything on one
                    // side would divide nothing.
                    if on == 0.0 && (front == 0.0 || back == 0.0) {
                        return;
                    }
                    split_weight * both + (front - back).abs()
                }
            };
            if cost.is_finite() && best.is_none_or(|(c, _)| cost < c) {
                best = Some((cost, plane));
            }
        };

        let mut candidates = std::mem::take(&mut scratch.candidates);
        self.surface_candidates(pieces, &mut candidates);
        if section.is_some() {
            candidates.clear();
        }
        for plane in &candidates {
            let mut counts = [0usize; 4];
            for i in 0..sample {
                let k = match self.side(sampled(i), plane) {
                    Side::On => 0,
                    Side::Front => 1,
                    Side::Back => 2,
                    Side::Both => 3,
                };
                counts[k] += 1;
            }
            consider(*plane, counts, scratch);
        }
        scratch.candidates = candidates;

        let bins = self.settings.axis_candidates;
        if bins > 0 {
            let mut lo = DVec3::INFINITY;
            let mut hi = DVec3::NEG_INFINITY;
            for p in pieces.iter().flat_map(|p| &p.polygon) {
                lo = lo.min(*p);
                hi = hi.max(*p);
            }
            let (cell_lo, cell_hi) = cell.bounds();
            let mut best_axis: Option<(f64, Plane, [usize; 4])> = None;
            let mut low_count = std::mem::take(&mut scratch.low_count);
            let mut high_count = std::mem::take(&mut scratch.high_count);
            for axis in 0..3 {
                let extent = hi[axis] - lo[axis];
                if !(extent > 0.0 && extent.is_finite()) {
                    continue;
                }
                let width = extent / bins as f64;
                // Boundary `j` is at `lo + j width`. A fragment is wholly
                // above boundary `j` when its lowest coordinate is at or
                // above it: `j <= floor((low - lo) / width)`; wholly below
                // when its highest is at or below: `j >= ceil((high - lo) /
                // width)`. Flooring and ceiling are taken at the coplanar
                // tolerance, as the exact classification does.
                low_count.clear();
                low_count.resize(bins + 1, 0usize);
                high_count.clear();
                high_count.resize(bins + 1, 0usize);
                for i in 0..sample {
                    let polygon = &sampled(i).polygon;
                    let (low, high) = polygon
                        .iter()
                        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
                            (a.min(p[axis]), b.max(p[axis]))
                        });
                    let low_bin = ((low + self.coplanar - lo[axis]) / width).floor();
                    let high_bin = ((high - self.coplanar - lo[axis]) / width).ceil();
                    low_count[low_bin.clamp(0.0, bins as f64) as usize] += 1;
                    high_count[high_bin.clamp(0.0, bins as f64) as usize] += 1;
                }
                // above[j] = sum of low_count[j..], below[j] = sum of
                // high_count[..=j].
                let mut above: usize = low_count.iter().sum();
                let mut below = 0usize;
                let mut normal = DVec3::ZERO;
                normal[axis] = 1.0;
                for j in 0..=bins {
                    below += high_count[j];
                    // Fragments both wholly above and wholly below lie on
                    // the plane.
                    let on = (above + below).saturating_sub(sample);
                    let (front, back) = (above - on, below - on);
                    let both = sample - on - front - back;
                    let offset = if j == bins {
                        hi[axis]
                    } else {
                        lo[axis] + width * j as f64
                    };
                    // Scored on the region's bounding box, cheaply; the
                    // best axis-aligned plane is then scored exactly
                    // beside the surface planes.
                    let (f, b) = match &section {
                        Some(section) => polygon_split_areas(section, normal, offset, scratch),
                        None => box_split_areas(cell_lo, cell_hi, axis, offset),
                    };
                    let counts = [on, front, back, both];
                    let estimate = f * (front + both) as f64 + b * (back + both) as f64;
                    if (both as f64) * scale <= allowance as f64
                        && best_axis.as_ref().is_none_or(|(e, _, _)| estimate < *e)
                    {
                        let plane = Plane {
                            normal,
                            offset,
                            own: None,
                        };
                        best_axis = Some((estimate, plane, counts));
                    }
                    above -= low_count[j];
                }
            }
            scratch.low_count = low_count;
            scratch.high_count = high_count;
            if let Some((_, plane, counts)) = best_axis {
                consider(plane, counts, scratch);
            }
        }

        let (cost, plane) = best?;
        if self.settings.cost == PlaneCost::SurfaceArea && cost >= n as f64 {
            return None;
        }
        Some(plane)
    }

    /// Marks the entries of surfaces that were split.
    fn flag_split_surfaces(&mut self) {
        let mut count = vec![0u32; self.surfaces.len()];
        for &e in &self.entries {
            count[e as usize] += 1;
        }
        for e in &mut self.entries {
            if count[*e as usize] > 1 {
                *e |= SPLIT_FLAG;
            }
        }
    }

    /// Tests the node's fragments; true at the first blocker.
    #[inline]
    fn test_entries(
        &self,
        node: &Node,
        from: DVec3,
        to: DVec3,
        skip: [u32; 2],
        tested: &mut Tested,
        tests: &mut u32,
    ) -> bool {
        for &entry in &self.entries[node.first as usize..node.end as usize] {
            let id = entry & !SPLIT_FLAG;
            if self.prepared.skips(id, skip) {
                continue;
            }
            let split = entry & SPLIT_FLAG != 0;
            if split && tested.ids[..tested.len].contains(&id) {
                continue;
            }
            *tests += 1;
            if self.prepared.crosses(id, from, to) {
                return true;
            }
            if split {
                tested.ids[tested.next] = id;
                tested.next = (tested.next + 1) % TESTED_MEMORY;
                tested.len = (tested.len + 1).min(TESTED_MEMORY);
            }
        }
        false
    }

    /// The front-to-back walk of Figure 3.2, carrying the segment's
    /// parameter interval inside the current region: `(blocked, surfaces
    /// tested, nodes visited)`.
    fn walk(&self, from: DVec3, to: DVec3, skip: [u32; 2]) -> (bool, u32, u32) {
        if self.nodes.is_empty() {
            return (false, 0, 0);
        }
        let round_off = QUERY_ROUND_OFF * from.abs().max_element().max(to.abs().max_element());
        // Far children and planes still to do: each node pushes at most two
        // entries above its ancestors', so twice the depth bounds the stack.
        let mut pending = [Pending::default(); 2 * MAX_DEPTH];
        let mut top = 0;
        let mut tested = Tested {
            ids: [0; TESTED_MEMORY],
            len: 0,
            next: 0,
        };
        let (mut tests, mut visited) = (0u32, 0u32);
        let mut current = 0u32;
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        loop {
            while current != NONE {
                visited += 1;
                let node = &self.nodes[current as usize];
                if node.is_leaf() {
                    if self.test_entries(node, from, to, skip, &mut tested, &mut tests) {
                        return (true, tests, visited);
                    }
                    break;
                }
                let d0 = node.normal.dot(from) - node.offset;
                let dd = node.normal.dot(to) - node.offset - d0;
                let tolerance = node.tolerance + round_off;
                // The common cases first, without a division: the part of
                // the segment in this region stays on one side.
                let (da, db) = (d0 + t0 * dd, d0 + t1 * dd);
                if da.min(db) > tolerance {
                    current = node.children[0];
                    continue;
                }
                if da.max(db) < -tolerance {
                    current = node.children[1];
                    continue;
                }
                // Parameters whose point is on (or within the tolerance of)
                // each side: `d0 + t dd >= -tolerance` and `<= tolerance`.
                let (front, back) = if dd > 0.0 {
                    (
                        (t0.max((-tolerance - d0) / dd), t1),
                        (t0, t1.min((tolerance - d0) / dd)),
                    )
                } else if dd < 0.0 {
                    (
                        (t0, t1.min((-tolerance - d0) / dd)),
                        (t0.max((tolerance - d0) / dd), t1),
                    )
                } else {
                    let empty = (1.0, 0.0);
                    (
                        if d0 >= -tolerance { (t0, t1) } else { empty },
                        if d0 <= tolerance { (t0, t1) } else { empty },
                    )
                };
                let reaches = [front.0 <= front.1, back.0 <= back.1];
                let near = usize::from(d0 + t0 * dd < 0.0);
                let far = 1 - near;
                let intervals = [front, back];
                if reaches[far] {
                    let child = node.children[far];
                    if child != NONE {
                        pending[top] = Pending {
                            node: child,
                            plane: false,
                            t0: intervals[far].0,
                            t1: intervals[far].1,
                        };
                        top += 1;
                    }
                    if reaches[near] && node.end > node.first {
                        pending[top] = Pending {
                            node: current,
                            plane: true,
                            t0: 0.0,
                            t1: 0.0,
                        };
                        top += 1;
                    }
                }
                if reaches[near] {
                    current = node.children[near];
                    (t0, t1) = intervals[near];
                } else {
                    current = NONE;
                }
            }
            if top == 0 {
                return (false, tests, visited);
            }
            top -= 1;
            let next = pending[top];
            if next.plane {
                let node = &self.nodes[next.node as usize];
                if self.test_entries(node, from, to, skip, &mut tested, &mut tests) {
                    return (true, tests, visited);
                }
                current = NONE;
            } else {
                current = next.node;
                (t0, t1) = (next.t0, next.t1);
            }
        }
    }
}

impl Occluder for Bsp<'_> {
    fn occluded(&self, from: DVec3, to: DVec3, skip: [u32; 2]) -> bool {
        self.walk(from, to, skip).0
    }

    fn occluded_counting(&self, from: DVec3, to: DVec3, skip: [u32; 2]) -> (bool, u32, u32) {
        Bsp::occluded_counting(self, from, to, skip)
    }

    fn validate(&self) -> Result<(), String> {
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

/// Reusable buffers of the build.
#[derive(Default)]
struct Scratch {
    candidates: Vec<Plane>,
    low_count: Vec<usize>,
    high_count: Vec<usize>,
    points: Vec<DVec3>,
    polygon: Vec<DVec3>,
    flat: Vec<(f64, DVec2)>,
}

/// A convex polyhedron, as its faces: a node's region of space (the
/// scene's box cut by the planes above it), for the surface-area cost.
#[derive(Clone, Debug)]
struct Cell {
    faces: Vec<Vec<DVec3>>,
}

impl Cell {
    /// The surfaces' bounding box, grown by a tenth of its diagonal so no
    /// face is flat.
    fn around(surfaces: &[Surface]) -> Cell {
        let mut lo = DVec3::INFINITY;
        let mut hi = DVec3::NEG_INFINITY;
        for p in surfaces.iter().flat_map(|s| &s.polygon) {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        if !(lo.is_finite() && hi.is_finite()) {
            return Cell { faces: Vec::new() };
        }
        let margin = 0.1 * (hi - lo).length().max(f64::MIN_POSITIVE.sqrt());
        let (lo, hi) = (lo - margin, hi + margin);
        let c = |x: bool, y: bool, z: bool| {
            DVec3::new(
                if x { hi.x } else { lo.x },
                if y { hi.y } else { lo.y },
                if z { hi.z } else { lo.z },
            )
        };
        let (f, t) = (false, true);
        Cell {
            faces: vec![
                vec![c(f, f, f), c(f, t, f), c(f, t, t), c(f, f, t)],
                vec![c(t, f, f), c(t, f, t), c(t, t, t), c(t, t, f)],
                vec![c(f, f, f), c(f, f, t), c(t, f, t), c(t, f, f)],
                vec![c(f, t, f), c(t, t, f), c(t, t, t), c(f, t, t)],
                vec![c(f, f, f), c(t, f, f), c(t, t, f), c(f, t, f)],
                vec![c(f, f, t), c(f, t, t), c(t, t, t), c(t, f, t)],
            ],
        }
    }

    fn area(&self) -> f64 {
        self.faces.iter().map(|f| geometry::area(f)).sum()
    }

    fn bounds(&self) -> (DVec3, DVec3) {
        self.faces
            .iter()
            .flatten()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(*p), hi.max(*p))
            })
    }

    /// Areas of the parts in front of and behind the plane, caps included,
    /// and of the cap (the plane's section of the cell).
    fn split_areas(&self, normal: DVec3, offset: f64, scratch: &mut Scratch) -> (f64, f64, f64) {
        let (mut front, mut back) = (0.0, 0.0);
        scratch.points.clear();
        for face in &self.faces {
            let (lo, hi) = distance_range(face, normal, offset);
            if lo <= 0.0 && hi >= 0.0 {
                scratch
                    .points
                    .extend(face.iter().filter(|p| normal.dot(**p) == offset));
            }
            if lo >= 0.0 {
                front += geometry::area(face);
                continue;
            }
            if hi <= 0.0 {
                back += geometry::area(face);
                continue;
            }
            clip_keep(
                face,
                normal,
                offset,
                &mut scratch.polygon,
                &mut scratch.points,
            );
            let f = geometry::area(&scratch.polygon);
            clip_keep(
                face,
                -normal,
                -offset,
                &mut scratch.polygon,
                &mut scratch.points,
            );
            let b = geometry::area(&scratch.polygon);
            front += f;
            back += b;
        }
        let cap = convex_area(&scratch.points, normal, &mut scratch.flat);
        (front + cap, back + cap, cap)
    }

    /// The parts in front of and behind the plane.
    fn split(&self, normal: DVec3, offset: f64, scratch: &mut Scratch) -> (Cell, Cell) {
        let mut front = Vec::with_capacity(self.faces.len() + 1);
        let mut back = Vec::with_capacity(self.faces.len() + 1);
        scratch.points.clear();
        for face in &self.faces {
            let (lo, hi) = distance_range(face, normal, offset);
            if lo >= 0.0 && hi > 0.0 {
                front.push(face.clone());
            } else if hi <= 0.0 && lo < 0.0 {
                back.push(face.clone());
            } else if lo < 0.0 && hi > 0.0 {
                clip_keep(
                    face,
                    normal,
                    offset,
                    &mut scratch.polygon,
                    &mut scratch.points,
                );
                front.push(scratch.polygon.clone());
                clip_keep(
                    face,
                    -normal,
                    -offset,
                    &mut scratch.polygon,
                    &mut scratch.points,
                );
                back.push(scratch.polygon.clone());
            }
            // A face lying in the plane is replaced by the cap.
            scratch
                .points
                .extend(face.iter().filter(|p| normal.dot(**p) == offset));
        }
        let cap = convex_polygon(&scratch.points, normal, &mut scratch.flat);
        if cap.len() >= 3 {
            front.push(cap.clone());
            back.push(cap);
        }
        (Cell { faces: front }, Cell { faces: back })
    }
}

/// The bounding rectangle, in their common plane, of pieces lying in the
/// plane with this normal; `None` if it has no area.
fn in_plane_bounds(pieces: &[Piece], normal: DVec3) -> Option<Vec<DVec3>> {
    let u = normal.any_orthonormal_vector();
    let v = normal.cross(u);
    let first = pieces.first()?.polygon[0];
    let along = normal.dot(first);
    let (mut lo, mut hi) = (DVec2::INFINITY, DVec2::NEG_INFINITY);
    for p in pieces.iter().flat_map(|p| &p.polygon) {
        let q = DVec2::new(u.dot(*p), v.dot(*p));
        lo = lo.min(q);
        hi = hi.max(q);
    }
    let extent = hi - lo;
    if !(extent.x > 0.0 && extent.y > 0.0 && extent.is_finite()) {
        return None;
    }
    let at = |x: f64, y: f64| normal * along + u * x + v * y;
    Some(vec![
        at(lo.x, lo.y),
        at(hi.x, lo.y),
        at(hi.x, hi.y),
        at(lo.x, hi.y),
    ])
}

/// Areas of the parts of a convex polygon in front of and behind a plane.
fn polygon_split_areas(
    polygon: &[DVec3],
    normal: DVec3,
    offset: f64,
    scratch: &mut Scratch,
) -> (f64, f64) {
    clip_keep(
        polygon,
        normal,
        offset,
        &mut scratch.polygon,
        &mut scratch.points,
    );
    let f = geometry::area(&scratch.polygon);
    clip_keep(
        polygon,
        -normal,
        -offset,
        &mut scratch.polygon,
        &mut scratch.points,
    );
    (f, geometry::area(&scratch.polygon))
}

/// Surface areas of the parts of the box `lo..hi` above and below the
/// plane `p[axis] = offset` (the plane clamped into the box).
fn box_split_areas(lo: DVec3, hi: DVec3, axis: usize, offset: f64) -> (f64, f64) {
    let d = (hi - lo).max(DVec3::ZERO);
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let face = d[u] * d[v];
    let rim = 2.0 * (d[u] + d[v]);
    let below = (offset - lo[axis]).clamp(0.0, d[axis]);
    let above = d[axis] - below;
    (2.0 * face + rim * above, 2.0 * face + rim * below)
}

/// Keeps the part of a convex polygon with `normal . p >= offset`, into
/// `out`, adding the points where it crosses the plane to `crossings`.
fn clip_keep(
    polygon: &[DVec3],
    normal: DVec3,
    offset: f64,
    out: &mut Vec<DVec3>,
    crossings: &mut Vec<DVec3>,
) {
    out.clear();
    let n = polygon.len();
    for i in 0..n {
        let a = polygon[i];
        let b = polygon[(i + 1) % n];
        let da = normal.dot(a) - offset;
        let db = normal.dot(b) - offset;
        if da >= 0.0 {
            out.push(a);
        }
        if (da > 0.0 && db < 0.0) || (da < 0.0 && db > 0.0) {
            let p = a + (b - a) * (da / (da - db));
            out.push(p);
            crossings.push(p);
        }
    }
}

/// The convex hull of points lying in a plane, as a polygon ordered around
/// their centre (`flat` is scratch space).
fn convex_polygon(points: &[DVec3], normal: DVec3, flat: &mut Vec<(f64, DVec2)>) -> Vec<DVec3> {
    if points.len() < 3 {
        return Vec::new();
    }
    let u = normal.any_orthonormal_vector();
    let v = normal.cross(u);
    let centre = points.iter().copied().sum::<DVec3>() / points.len() as f64;
    order_around(points, centre, u, v, flat);
    flat.iter()
        .map(|(_, q)| centre + u * q.x + v * q.y)
        .collect()
}

/// Area of the convex hull of points lying in a plane.
fn convex_area(points: &[DVec3], normal: DVec3, flat: &mut Vec<(f64, DVec2)>) -> f64 {
    if points.len() < 3 {
        return 0.0;
    }
    let u = normal.any_orthonormal_vector();
    let v = normal.cross(u);
    let centre = points.iter().copied().sum::<DVec3>() / points.len() as f64;
    order_around(points, centre, u, v, flat);
    let n = flat.len();
    let twice: f64 = (0..n)
        .map(|i| flat[i].1.perp_dot(flat[(i + 1) % n].1))
        .sum();
    0.5 * twice.abs()
}

/// The points in plane coordinates about `centre`, sorted by angle. Points
/// crossing the plane from several faces repeat; repeats add no area.
fn order_around(points: &[DVec3], centre: DVec3, u: DVec3, v: DVec3, flat: &mut Vec<(f64, DVec2)>) {
    flat.clear();
    flat.extend(points.iter().map(|p| {
        let q = DVec2::new(u.dot(*p - centre), v.dot(*p - centre));
        (q.y.atan2(q.x), q)
    }));
    flat.sort_by(|a, b| a.0.total_cmp(&b.0));
}

/// The larger of the bounding-box diagonal and the largest coordinate: the
/// scale of both the geometry and its round-off.
fn scene_scale(surfaces: &[Surface]) -> f64 {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for p in surfaces.iter().flat_map(|s| &s.polygon) {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    if surfaces.is_empty() {
        return 1.0;
    }
    let scale = (hi - lo)
        .length()
        .max(lo.abs().max_element())
        .max(hi.abs().max_element());
    if scale.is_finite() && scale > 0.0 {
        scale
    } else {
        1.0
    }
}

/// A polygon's area computed about its first corner, so it keeps its
/// digits far from the origin (Newell's sum about the origin loses them).
fn local_area(polygon: &[DVec3]) -> f64 {
    let origin = polygon[0];
    let local: Vec<DVec3> = polygon.iter().map(|p| *p - origin).collect();
    geometry::area(&local)
}

/// Smallest and largest signed distance of the corners from a plane.
fn distance_range(polygon: &[DVec3], normal: DVec3, offset: f64) -> (f64, f64) {
    polygon
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            let d = normal.dot(*p) - offset;
            (lo.min(d), hi.max(d))
        })
}

fn classify(polygon: &[DVec3], normal: DVec3, offset: f64, coplanar: f64) -> Side {
    let (lo, hi) = distance_range(polygon, normal, offset);
    match (lo >= -coplanar, hi <= coplanar) {
        (true, true) => Side::On,
        (true, false) => Side::Front,
        (false, true) => Side::Back,
        (false, false) => Side::Both,
    }
}

/// Cuts a convex polygon exactly at the plane: `(front, back)`; corners on
/// the plane go to both.
fn split(polygon: &[DVec3], normal: DVec3, offset: f64) -> (Vec<DVec3>, Vec<DVec3>) {
    let mut front = Vec::with_capacity(polygon.len() + 1);
    let mut back = Vec::with_capacity(polygon.len() + 1);
    let n = polygon.len();
    for i in 0..n {
        let a = polygon[i];
        let b = polygon[(i + 1) % n];
        let da = normal.dot(a) - offset;
        let db = normal.dot(b) - offset;
        if da >= 0.0 {
            front.push(a);
        }
        if da <= 0.0 {
            back.push(a);
        }
        if (da > 0.0 && db < 0.0) || (da < 0.0 && db > 0.0) {
            let p = a + (b - a) * (da / (da - db));
            front.push(p);
            back.push(p);
        }
    }
    (front, back)
}

/// How far from the convex hull of a surface's corners a point accepted by
/// [`segment_crosses`](super::segment_crosses) can lie: the crossing point is on the surface's plane
/// (which a non-planar input polygon leaves by up to its non-planarity) and
/// within the edge tolerance of every edge line, a region that near a sharp
/// corner reaches `tolerance / sin(angle / 2)` beyond it. The region is
/// computed exactly (in the plane) with four times the tolerance, and its
/// farthest corner's distance from the polygon is the reach.
fn crossing_reach(surface: &Surface) -> f64 {
    let (lo, hi) = distance_range(&surface.polygon, surface.normal, surface.offset);
    let non_planarity = (-lo).max(hi).max(0.0);
    let tolerance = 4.0 * CROSSING_TOLERANCE * surface.area.sqrt();
    match AcceptanceRegion::of(surface, 4.0) {
        AcceptanceRegion::Bounded {
            polygon, region, ..
        } => {
            let excess = region
                .iter()
                .map(|q| distance_to_polygon_2d(&polygon, *q))
                .fold(0.0, f64::max);
            excess + non_planarity + tolerance
        }
        AcceptanceRegion::Empty => non_planarity + tolerance,
        // The edges do not bound a region: a degenerate polygon. Every
        // segment then reaches every plane, which is slow but still exact.
        AcceptanceRegion::Unbounded => f64::INFINITY,
    }
}

/// Distance from `q` to a convex 2-D polygon, counter-clockwise (0 inside).
fn distance_to_polygon_2d(polygon: &[DVec2], q: DVec2) -> f64 {
    let n = polygon.len();
    let mut inside = true;
    let mut nearest = f64::INFINITY;
    for i in 0..n {
        let a = polygon[i];
        let b = polygon[(i + 1) % n];
        let e = b - a;
        if e.perp_dot(q - a) < 0.0 {
            inside = false;
        }
        let t = if e.length_squared() > 0.0 {
            ((q - a).dot(e) / e.length_squared()).clamp(0.0, 1.0)
        } else {
            0.0
        };
        nearest = nearest.min(q.distance(a + e * t));
    }
    if inside { 0.0 } else { nearest }
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
        let cell = Cell::around(std::slice::from_ref(&square));
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
