//! BSP-tree visibility: Wong & Tsang (1993), section 3 and Figure 3.2
//! (design.md section 3, improvement 2).
//!
//! The tree is an auto-partition built once over the scene's surfaces: every
//! splitting plane is the plane of an input surface; fragments lying on a
//! node's plane are stored at that node; a fragment straddling the plane is
//! split by it and both pieces keep their surface id (the BSP tree of Fuchs,
//! Kedem & Naylor 1980, as used by Chin & Feiner 1989). A shadow segment walks
//! the tree front to back from its origin: at each node it visits the child
//! on the origin's side, and only when the segment reaches the node's plane
//! does it test the surfaces stored there and then visit the far child. A
//! segment that stays on one side of a plane never visits the other side
//! (the pruning of the paper's Figure 3.2). The walk stops at the first
//! blocker.
//!
//! # Agreement with the brute-force oracle
//!
//! The tree only decides *which* surfaces to test; the blocking decision is
//! always [`segment_crosses`](super::segment_crosses) on the original surface, so an answer can only
//! differ from [`BruteForce`](super::brute::BruteForce) if the walk misses a
//! surface the segment crosses. It cannot, because every tolerance is
//! conservative:
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
//! * The walk treats a segment as reaching a node's plane when it comes
//!   within the node's tolerance `c + max reach + round-off` of it. A surface
//!   the segment crosses at `p` therefore always has a fragment in a visited
//!   node: `p` is within `reach` of a fragment, and a fragment is only ever
//!   left out of a visited region when it is more than `c + reach` away.
//!
//! # Plane choice
//!
//! Each node tries a deterministic, evenly spaced sample of the planes of its
//! fragments ([`BspSettings::candidates`]) and keeps the one minimising
//! `split_weight * splits + |front - back|` (Fuchs, Abram & Grant 1983; the
//! classic heuristic for a small, balanced tree); ties go to the earlier
//! candidate. There is no randomness: the same scene always gives the same
//! tree.
//!
//! # Layout
//!
//! Nodes live in one `Vec` in depth-first order (the front child usually
//! follows its parent), children by index; each node's surfaces are a range
//! of one `Vec<u32>` of surface ids. Queries walk the tree iteratively with a
//! fixed stack of [`MAX_DEPTH`] entries: no allocation and no interior
//! mutability, so any number of threads can query one tree.

use glam::{DVec2, DVec3};

use super::{AcceptanceRegion, Occluder, PreparedSurfaces};
use crate::geometry;
use crate::scene::Surface;

/// The deepest a tree may grow, and the size of the query stack. Fragments
/// still unplaced at this depth go to one leaf bucket, tested whenever the
/// walk reaches it.
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

/// How the tree is built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BspSettings {
    /// Candidate planes tried per node, an evenly spaced sample of the
    /// node's fragments; `0` tries every fragment's plane.
    pub candidates: usize,
    /// Cost of one split, in units of one fragment of front/back imbalance.
    pub split_weight: f64,
    /// Distance within which a fragment counts as lying on a plane, relative
    /// to the scene's scale (its bounding-box diagonal or largest
    /// coordinate, whichever is larger).
    pub coplanar_tolerance: f64,
    /// Depth at which the remaining fragments go to a leaf bucket; at most
    /// [`MAX_DEPTH`].
    pub max_depth: usize,
}

impl BspSettings {
    /// The default: 16 candidates per node, a split costing 8 fragments of
    /// imbalance.
    #[must_use]
    pub fn balanced() -> BspSettings {
        BspSettings {
            candidates: 16,
            split_weight: 8.0,
            coplanar_tolerance: 1e-9,
            max_depth: MAX_DEPTH,
        }
    }

    /// The first fragment's plane at every node, as the paper's description
    /// reads: cheapest to build, possibly deep and unbalanced.
    #[must_use]
    pub fn fastest_build() -> BspSettings {
        BspSettings {
            candidates: 1,
            ..BspSettings::balanced()
        }
    }

    /// Every fragment's plane tried at every node: slowest to build
    /// (quadratic in the fragments of a node), smallest trees.
    #[must_use]
    pub fn thorough() -> BspSettings {
        BspSettings {
            candidates: 0,
            ..BspSettings::balanced()
        }
    }

    /// Every preset with its name, for tests and benchmarks.
    #[must_use]
    pub fn presets() -> [(&'static str, BspSettings); 3] {
        [
            ("fastest-build", BspSettings::fastest_build()),
            ("balanced", BspSettings::balanced()),
            ("thorough", BspSettings::thorough()),
        ]
    }

    /// The settings with out-of-range values replaced: a negative or
    /// non-finite weight or tolerance takes the default, the depth is
    /// clamped to `1..=MAX_DEPTH`.
    #[must_use]
    pub fn sanitized(self) -> BspSettings {
        let default = BspSettings::balanced();
        let ok = |v: f64| v.is_finite() && v >= 0.0;
        BspSettings {
            candidates: self.candidates,
            split_weight: if ok(self.split_weight) {
                self.split_weight
            } else {
                default.split_weight
            },
            coplanar_tolerance: if ok(self.coplanar_tolerance) {
                self.coplanar_tolerance
            } else {
                default.coplanar_tolerance
            },
            max_depth: self.max_depth.clamp(1, MAX_DEPTH),
        }
    }
}

impl Default for BspSettings {
    fn default() -> Self {
        BspSettings::balanced()
    }
}

/// Size of a built tree.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct BspStats {
    /// Nodes, leaf buckets included.
    pub nodes: usize,
    /// Nodes on the longest root-to-leaf path (0 for an empty tree).
    pub depth: usize,
    /// Stored polygon pieces: surfaces plus splits.
    pub fragments: usize,
    /// Fragments cut in two by a splitting plane.
    pub splits: usize,
    /// Leaf buckets made because the tree reached its maximum depth.
    pub buckets: usize,
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
    /// Range of `Bsp::entries` (and `Bsp::fragments`) lying on the plane.
    first: u32,
    end: u32,
}

/// A fragment's corners: a range of `Bsp::fragment_corners`.
#[derive(Clone, Copy, Debug)]
struct FragmentRange {
    first: u32,
    end: u32,
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

/// A BSP tree over a scene's surfaces answering shadow-segment queries.
pub struct Bsp<'a> {
    surfaces: &'a [Surface],
    /// The surfaces laid out for the segment test.
    prepared: PreparedSurfaces,
    nodes: Vec<Node>,
    /// Surface id of each stored fragment, with [`SPLIT_FLAG`] when the
    /// surface has several fragments; node ranges index it.
    entries: Vec<u32>,
    /// Corners of each entry's fragment (parallel to `entries`).
    fragments: Vec<FragmentRange>,
    fragment_corners: Vec<DVec3>,
    /// How far an accepted crossing point can be from each surface.
    reach: Vec<f64>,
    coplanar: f64,
    round_off: f64,
    settings: BspSettings,
    stats: BspStats,
}

impl<'a> Bsp<'a> {
    /// Builds the tree with [`BspSettings::balanced`].
    #[must_use]
    pub fn new(surfaces: &'a [Surface]) -> Bsp<'a> {
        Bsp::with_settings(surfaces, BspSettings::balanced())
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
            fragments: Vec::new(),
            fragment_corners: Vec::new(),
            reach: surfaces.iter().map(crossing_reach).collect(),
            coplanar: settings.coplanar_tolerance * scale,
            round_off: ROUND_OFF * scale,
            settings,
            stats: BspStats::default(),
        };
        let pieces = surfaces
            .iter()
            .enumerate()
            .map(|(i, s)| Piece {
                surface: i as u32,
                polygon: s.polygon.clone(),
            })
            .collect();
        bsp.build(pieces, 1);
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

    /// Like [`Occluder::occluded`], also returning how many surfaces were
    /// tested with [`segment_crosses`](super::segment_crosses) (for benchmarks; brute force tests
    /// surfaces in input order up to the first blocker).
    #[must_use]
    pub fn occluded_counting(&self, from: DVec3, to: DVec3, skip: [u32; 2]) -> (bool, u32, u32) {
        self.walk(from, to, skip)
    }

    /// Checks the tree's invariants: a well-formed depth-first node array;
    /// every fragment on its node's plane and on the correct side of every
    /// ancestor's plane (within the coplanar tolerance); every fragment on
    /// its surface's plane and inside its polygon; each surface's fragments
    /// adding up to its area (1e-9 relative, both computed about the
    /// polygon's first corner to keep their digits); node tolerances
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
            let is_bucket = node.normal == DVec3::ZERO;
            if is_bucket && node.children != [NONE; 2] {
                return Err(format!("leaf bucket {i} has children"));
            }
            if !is_bucket && (node.normal.length() - 1.0).abs() > 1e-9 {
                return Err(format!("node {i}: normal is not a unit vector"));
            }
        }
        if expected_first as usize != self.entries.len()
            || self.fragments.len() != self.entries.len()
        {
            return Err("node ranges do not cover the fragment list exactly".into());
        }
        let max_depth = depth.iter().copied().max().unwrap_or(0);
        if max_depth != self.stats.depth || max_depth > self.settings.max_depth {
            return Err(format!(
                "depth {max_depth}, statistics say {}, limit {}",
                self.stats.depth, self.settings.max_depth
            ));
        }
        let buckets = nodes.iter().filter(|n| n.normal == DVec3::ZERO).count();
        if self.stats.nodes != nodes.len()
            || self.stats.fragments != self.entries.len()
            || self.stats.fragments != self.surfaces.len() + self.stats.splits
            || self.stats.buckets != buckets
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
                let polygon = self.fragment(k as usize);
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
                let inside = 1e-9 * surface.area.sqrt() + self.round_off;
                if !polygon.iter().all(|p| {
                    geometry::convex_contains(&surface.polygon, surface.normal, *p, inside)
                }) {
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
            if (area[id] - expected).abs() > 1e-9 * expected {
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

    fn fragment(&self, k: usize) -> &[DVec3] {
        let r = self.fragments[k];
        &self.fragment_corners[r.first as usize..r.end as usize]
    }

    /// Builds the subtree over `pieces` at `depth` (root = 1) and returns its
    /// index, or [`NONE`] for no pieces.
    fn build(&mut self, pieces: Vec<Piece>, depth: usize) -> u32 {
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
        if depth >= self.settings.max_depth && pieces.len() > 1 {
            self.stats.buckets += 1;
            let first = self.entries.len() as u32;
            for piece in &pieces {
                self.store(piece);
            }
            self.nodes.push(Node {
                normal: DVec3::ZERO,
                offset: 0.0,
                tolerance,
                children: [NONE; 2],
                first,
                end: self.entries.len() as u32,
            });
            return index;
        }
        let chosen = pieces[self.choose_plane(&pieces)].surface;
        let plane = &self.surfaces[chosen as usize];
        let (normal, offset) = (plane.normal, plane.offset);

        let mut front = Vec::new();
        let mut back = Vec::new();
        let first = self.entries.len() as u32;
        for piece in pieces {
            // The plane's own surface always lies on it, even when a
            // non-planar input polygon leaves it by more than the tolerance.
            let side = if piece.surface == chosen {
                Side::On
            } else {
                classify(&piece.polygon, normal, offset, self.coplanar)
            };
            match side {
                Side::On => self.store(&piece),
                Side::Front => front.push(piece),
                Side::Back => back.push(piece),
                Side::Both => {
                    self.stats.splits += 1;
                    let (f, b) = split(&piece.polygon, normal, offset);
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
        self.nodes.push(Node {
            normal,
            offset,
            tolerance,
            children: [NONE; 2],
            first,
            end: self.entries.len() as u32,
        });
        let f = self.build(front, depth + 1);
        let b = self.build(back, depth + 1);
        self.nodes[index as usize].children = [f, b];
        index
    }

    fn store(&mut self, piece: &Piece) {
        let first = self.fragment_corners.len() as u32;
        self.fragment_corners.extend_from_slice(&piece.polygon);
        self.fragments.push(FragmentRange {
            first,
            end: self.fragment_corners.len() as u32,
        });
        self.entries.push(piece.surface);
    }

    /// Index of the piece whose plane minimises `split_weight * splits +
    /// |front - back|` among an evenly spaced sample of the pieces.
    fn choose_plane(&self, pieces: &[Piece]) -> usize {
        let n = pieces.len();
        let k = match self.settings.candidates {
            0 => n,
            c => c.min(n),
        };
        if k <= 1 {
            return 0;
        }
        let mut best = (f64::INFINITY, 0);
        for c in 0..k {
            let candidate = c * n / k;
            let plane = &self.surfaces[pieces[candidate].surface as usize];
            let (mut front, mut back, mut splits) = (0i64, 0i64, 0i64);
            for piece in pieces {
                match classify(&piece.polygon, plane.normal, plane.offset, self.coplanar) {
                    Side::On => {}
                    Side::Front => front += 1,
                    Side::Back => back += 1,
                    Side::Both => {
                        front += 1;
                        back += 1;
                        splits += 1;
                    }
                }
            }
            let score = self.settings.split_weight * splits as f64 + (front - back).abs() as f64;
            if score < best.0 {
                best = (score, candidate);
            }
        }
        best.1
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

    /// The front-to-back walk of Figure 3.2.
    fn walk(&self, from: DVec3, to: DVec3, skip: [u32; 2]) -> (bool, u32, u32) {
        if self.nodes.is_empty() {
            return (false, 0, 0);
        }
        let mut visited = 0u32;
        let round_off = QUERY_ROUND_OFF * from.abs().max_element().max(to.abs().max_element());
        // Nodes whose surfaces and far side are still to do; a node is only
        // pushed above its ancestors, so the depth bounds the stack.
        let mut pending = [0u32; MAX_DEPTH];
        let mut top = 0;
        let mut tested_split = [0u32; TESTED_MEMORY];
        let mut remembered = 0;
        let mut tests = 0u32;
        let mut current = 0u32;
        loop {
            if current != NONE {
                visited += 1;
                let node = &self.nodes[current as usize];
                let d0 = node.normal.dot(from) - node.offset;
                let d1 = node.normal.dot(to) - node.offset;
                let tolerance = node.tolerance + round_off;
                let reaches_plane = d0.min(d1) <= tolerance && d0.max(d1) >= -tolerance;
                if reaches_plane {
                    pending[top] = current;
                    top += 1;
                }
                current = node.children[usize::from(d0 < 0.0)];
                continue;
            }
            if top == 0 {
                return (false, tests, visited);
            }
            top -= 1;
            let index = pending[top];
            let node = &self.nodes[index as usize];
            for &entry in &self.entries[node.first as usize..node.end as usize] {
                let id = entry & !SPLIT_FLAG;
                if id == skip[0] || id == skip[1] {
                    continue;
                }
                let split = entry & SPLIT_FLAG != 0;
                if split && tested_split[..remembered].contains(&id) {
                    continue;
                }
                tests += 1;
                if self.prepared.crosses(id, from, to) {
                    return (true, tests, visited);
                }
                if split && remembered < TESTED_MEMORY {
                    tested_split[remembered] = id;
                    remembered += 1;
                }
            }
            let d0 = node.normal.dot(from) - node.offset;
            current = node.children[usize::from(d0 >= 0.0)];
        }
    }
}

impl Occluder for Bsp<'_> {
    fn occluded(&self, from: DVec3, to: DVec3, skip: [u32; 2]) -> bool {
        self.walk(from, to, skip).0
    }

    fn build_statistics(&self) -> Vec<(&'static str, usize)> {
        let s = self.stats();
        vec![
            ("nodes", s.nodes),
            ("depth", s.depth),
            ("fragments", s.fragments),
            ("splits", s.splits),
            ("buckets", s.buckets),
        ]
    }
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
            (false, 0)
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
        let (blocked, tests) = bsp.occluded_counting(
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
        assert_eq!(bsp.stats().buckets, 1);
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
        let s = BspSettings {
            candidates: 3,
            split_weight: f64::NAN,
            coplanar_tolerance: -1.0,
            max_depth: 1000,
        }
        .sanitized();
        assert_eq!(s.split_weight, BspSettings::balanced().split_weight);
        assert_eq!(
            s.coplanar_tolerance,
            BspSettings::balanced().coplanar_tolerance
        );
        assert_eq!(s.max_depth, MAX_DEPTH);
        assert_eq!(s.candidates, 3);
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
