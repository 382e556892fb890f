//! Visibility along segments and rays (design.md section 3): does any
//! surface cross the open segment between a subsource point and a
//! receiving vertex (the shadow query), and which surface does a ray meet
//! first (the closest-hit query)?
//!
//! [`brute::BruteForce`] tests every surface, as Wallace et al. (1989) did;
//! it is the oracle every accelerator is tested against. [`bsp::Bsp`] walks
//! a BSP tree front to back from the segment's origin (Wong & Tsang,
//! section 3); [`bvh::Bvh`] is a surface-area-heuristic bounding-volume
//! hierarchy, the modern answer, kept beside it for comparison. The segment
//! test itself, [`segment_crosses`], is shared by all of them. As in pbrt's
//! `IntersectP` beside `Intersect`, the cheap shadow query
//! ([`Occluder::occluded`]) stops at the first blocker and the closest-hit
//! query ([`Occluder::closest_hit`]) sits beside it.
//!
//! # Closest hit
//!
//! A ray `origin + t direction` with `0 < t < max_t` is the open segment
//! from `origin` to `end = origin + direction * max_t`, and it hits exactly
//! the surfaces that segment crosses by [`segment_crosses`]: so, for any
//! ray that can hit something (below), `occluded(origin, end, skip)` holds
//! exactly when `closest_hit(origin, direction, max_t, skip)` finds a
//! surface. The hit's `t` is `max_t` times the crossing parameter the
//! segment test computes ([`segment_crossing`]), the same number in every
//! accelerator, and the nearest wins. The edge cases follow from the
//! segment test:
//!
//! * A ray through an edge or corner shared by two surfaces crosses both
//!   (edges count as inside, within [`EDGE_TOLERANCE`]): rays cannot slip
//!   between neighbours. The nearer crossing is the hit; at the same
//!   parameter (the shared edge of two surfaces in one plane) the lower
//!   surface index wins, so every accelerator returns the same surface
//!   whatever order it tests them in.
//! * A surface whose plane holds the origin exactly is not hit (`t = 0` is
//!   not a crossing), whichever way the ray leaves, as a shadow segment is
//!   not blocked by the surfaces at its ends. A point computed on a tilted
//!   surface is off its plane by round-off, and the surface may then be hit
//!   at a `t` of that order: a ray leaving a surface should skip its id,
//!   as shadow segments skip theirs.
//! * A surface whose plane holds the end is not hit either: `max_t` is
//!   exclusive, a surface exactly at the maximum distance is not met.
//! * A ray lying in a surface's plane never hits it (it grazes it).
//! * A ray with `max_t` not greater than 0 (or NaN), or whose end is not
//!   finite, hits nothing; a zero direction hits nothing.

pub mod brute;
pub mod bsp;
pub mod bvh;
pub mod shaft;

use glam::{DVec2, DVec3};

use crate::geometry::{self, clip};
use crate::scene::Surface;

crate::choice::named_choice! {
    /// Which shadow-ray accelerator answers visibility queries.
    pub enum Accel: "accelerator" {
        /// Every surface is tested (the oracle).
        Brute = "brute",
        /// A BSP tree over the surfaces, walked front to back (paper section 3).
        Bsp = "bsp",
        /// A surface-area-heuristic bounding-volume hierarchy (beyond the
        /// paper: the modern answer, kept beside the BSP for comparison).
        Bvh = "bvh",
    }
}

impl Accel {
    /// Builds the accelerator over the scene's surfaces.
    #[must_use]
    pub fn build(self, surfaces: &[Surface]) -> Box<dyn Occluder + '_> {
        match self {
            Accel::Brute => Box::new(brute::BruteForce::new(surfaces)),
            Accel::Bsp => Box::new(bsp::Bsp::new(surfaces)),
            Accel::Bvh => Box::new(bvh::Bvh::new(surfaces)),
        }
    }
}

/// A broken invariant of a built accelerator, found by
/// [`Occluder::validate`]: what is wrong and where.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct InvalidTree(pub String);

/// The surface a ray meets first: the answer of [`Occluder::closest_hit`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Index of the surface in the slice the accelerator was built over.
    pub surface: u32,
    /// Ray parameter of the crossing: the point is `origin + t direction`,
    /// `0 < t < max_t` up to round-off (the distance along the ray when the
    /// direction is a unit vector).
    pub t: f64,
}

/// The last blockers of one caller's shadow segments, for
/// [`Occluder::occluded_cached`]: segments cast one after another from
/// nearby points to nearby points (a receiver's rays to a shooter's
/// samples) are mostly blocked by the same surface or its neighbour. One
/// a thread; how it is used never changes an answer. Two blockers: on
/// Sponza's first 60 shots one answered 25.8% of the rays and two 31.7%,
/// four 36.8% but no faster (each costs an exact test on every ray it
/// does not answer).
///
/// A caller whose segments start from a few points in turn (a receiver's
/// rays to each of a source's sample elements, receiver after receiver)
/// names each segment's origin with [`ShadowCache::from_origin`]: the
/// blocker last found for a segment from the same origin is then tested
/// first, since the next receiver's segment from there passes beside the
/// last one, while the segment just before came from another origin, in
/// another direction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShadowCache {
    /// The accelerator's handles of the last two blockers, the latest
    /// first; `u32::MAX` for none.
    pub(crate) last: [u32; 2],
    /// The blocker last found from each origin, by slot
    /// ([`ShadowCache::slot`]); `u32::MAX` for none.
    pub(crate) by_origin: [u32; ORIGIN_SLOTS],
    /// The surface that last met a shaft from each origin, by slot;
    /// `u32::MAX` for none.
    pub(crate) by_shaft: [u32; ORIGIN_SLOTS],
    /// The origin of the next segment, `u32::MAX` for none named.
    origin: u32,
    /// Segments answered by the cached blocker.
    pub hits: u64,
}

/// Origins a [`ShadowCache`] remembers a blocker for (a direct-mapped
/// table: an origin takes the slot its hash names, replacing the one
/// there).
const ORIGIN_SLOTS: usize = 64;

impl Default for ShadowCache {
    fn default() -> ShadowCache {
        ShadowCache {
            last: [u32::MAX; 2],
            by_origin: [u32::MAX; ORIGIN_SLOTS],
            by_shaft: [u32::MAX; ORIGIN_SLOTS],
            origin: u32::MAX,
            hits: 0,
        }
    }
}

impl ShadowCache {
    /// Names the origin of the next segments (any number the caller uses
    /// for one point, such as the element it lies on), or none with
    /// `u32::MAX`.
    pub fn from_origin(&mut self, origin: u32) {
        self.origin = origin;
    }

    /// Records `blocker` as the latest found, from anywhere and from the
    /// named origin: moved to the front of the last two (or put there,
    /// pushing out the older), and kept for the origin's slot.
    pub(crate) fn remember(&mut self, blocker: u32) {
        match self.last.iter().position(|&b| b == blocker) {
            Some(k) => self.last[..=k].rotate_right(1),
            None => {
                self.last.rotate_right(1);
                self.last[0] = blocker;
            }
        }
        if let Some(s) = self.slot() {
            self.by_origin[s] = blocker;
        }
    }

    /// The slot of the named origin, if one is named (Fibonacci hashing,
    /// so consecutive numbers spread over the table).
    pub(crate) fn slot(&self) -> Option<usize> {
        const BITS: u32 = ORIGIN_SLOTS.trailing_zeros();
        (self.origin != u32::MAX)
            .then(|| (self.origin.wrapping_mul(0x9E37_79B1) >> (32 - BITS)) as usize)
    }
}

/// A visibility query structure over a scene's surfaces: shadow segments
/// and closest hits.
pub trait Occluder: Sync {
    /// True when a surface whose [`Surface::group`] is neither `skip[0]` nor
    /// `skip[1]` crosses the open segment `from -> to`. Callers pass the
    /// surface ids of the source and the receiver as `skip`: a planar surface
    /// cannot hide its own points from a point in front of it, and skipping
    /// them makes the test immune to round-off at both ends.
    fn occluded(&self, from: DVec3, to: DVec3, skip: [u32; 2]) -> bool;

    /// [`Occluder::occluded`] with a shadow cache (Haines & Greenberg
    /// 1986, "The light buffer"): the surfaces that blocked the caller's
    /// last blocked segments are tested first, and where one blocks this
    /// one too the walk is spared. The answer is [`Occluder::occluded`]'s to
    /// the bit: a surface that blocks is a blocker whichever way it is
    /// found. Without a cache of its own an accelerator answers as
    /// [`Occluder::occluded`] does.
    fn occluded_cached(
        &self,
        from: DVec3,
        to: DVec3,
        skip: [u32; 2],
        cache: &mut ShadowCache,
    ) -> bool {
        let _ = cache;
        self.occluded(from, to, skip)
    }

    /// True when no surface whose [`Surface::group`] is neither `skip[0]`
    /// nor `skip[1]` meets `shaft` (Haines & Wallace 1991): then no segment
    /// between the shaft's ball and polygon is blocked. False where one
    /// may meet it, and by default (an accelerator that cannot tell).
    /// The surface that last met a shaft from the cache's origin is tested
    /// first; how the cache is used never changes an answer.
    fn shaft_clear(&self, shaft: &shaft::Shaft, skip: [u32; 2], cache: &mut ShadowCache) -> bool {
        let _ = (shaft, skip, cache);
        false
    }

    /// The nearest surface whose [`Surface::group`] is neither `skip[0]`
    /// nor `skip[1]` crossed by the ray `origin + t direction`, `0 < t <
    /// max_t`; `None` when there is none. The ray crosses exactly the
    /// surfaces [`Occluder::occluded`] finds on the segment `origin ->
    /// origin + direction * max_t`; ties go to the lower surface index;
    /// see the module notes for the edge cases.
    fn closest_hit(
        &self,
        origin: DVec3,
        direction: DVec3,
        max_t: f64,
        skip: [u32; 2],
    ) -> Option<Hit>;

    /// Like [`Occluder::occluded`], also returning how many surfaces were
    /// tested with [`segment_crosses`] and how many nodes (or child boxes)
    /// were visited: `(blocked, tested, visited)`, for benchmarks and for
    /// the tests that check an accelerator tests fewer surfaces than brute
    /// force.
    fn occluded_counting(&self, from: DVec3, to: DVec3, skip: [u32; 2]) -> (bool, u32, u32);

    /// Checks the structure's invariants (see each accelerator's own
    /// `validate`); the accelerator tests call it on every structure they
    /// build.
    fn validate(&self) -> Result<(), InvalidTree>;

    /// Build statistics worth reporting (name, value), e.g. a tree's node
    /// count and depth; none by default.
    fn build_statistics(&self) -> Vec<(&'static str, usize)> {
        Vec::new()
    }
}

/// Relative amount by which a shadow segment is shortened at each end, so a
/// receiver on the edge where two surfaces meet is not hidden by the
/// neighbour it touches.
pub const SEGMENT_EPSILON: f64 = 1e-6;

/// Shortens `from -> to` by [`SEGMENT_EPSILON`] of its length at both ends.
#[must_use]
pub fn shorten(from: DVec3, to: DVec3) -> (DVec3, DVec3) {
    let d = (to - from) * SEGMENT_EPSILON;
    (from + d, to - d)
}

/// Tolerance of the segment test: a crossing point up to this fraction of
/// the square root of the surface's area outside an edge still counts as
/// inside, so rays cannot slip through the shared edge of two surfaces.
pub const EDGE_TOLERANCE: f64 = 1e-9;

/// True when the segment `from -> to` passes strictly from one side of the
/// surface's plane to the other through the polygon (edges included, with
/// [`EDGE_TOLERANCE`]). The definition every accelerator answers to; they
/// evaluate it through [`PreparedSurfaces`], which gives the same answers
/// faster.
#[must_use]
pub fn segment_crosses(surface: &Surface, from: DVec3, to: DVec3) -> bool {
    segment_crossing(surface, from, to).is_some()
}

/// Where the segment `from -> to` crosses the surface, as the parameter `s`
/// of the crossing point `from + s (to - from)`, when [`segment_crosses`]
/// holds; `None` otherwise. A closest hit's distance is `max_t` times this
/// parameter (see the module notes).
#[must_use]
pub fn segment_crossing(surface: &Surface, from: DVec3, to: DVec3) -> Option<f64> {
    let d0 = surface.normal.dot(from) - surface.offset;
    let d1 = surface.normal.dot(to) - surface.offset;
    if d0 == 0.0 || d1 == 0.0 || (d0 > 0.0) == (d1 > 0.0) {
        return None;
    }
    let t = d0 / (d0 - d1);
    let p = from + (to - from) * t;
    let tolerance = EDGE_TOLERANCE * surface.area.sqrt();
    geometry::convex_contains(&surface.polygon, surface.normal, p, tolerance).then_some(t)
}

/// The end `origin + direction * max_t` of a closest-hit ray, or `None`
/// for a ray that can hit nothing: `max_t` not greater than 0 (or NaN), or
/// an end that is not finite (see the module notes).
#[must_use]
pub(crate) fn ray_end(origin: DVec3, direction: DVec3, max_t: f64) -> Option<DVec3> {
    let end = origin + direction * max_t;
    (max_t > 0.0 && origin.is_finite() && end.is_finite()).then_some(end)
}

/// The nearest crossing a closest-hit query has found so far, as a
/// parameter of its segment. Ties go to the lower surface index, so the
/// answer does not depend on the order an accelerator tests surfaces in.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Nearest {
    best: Option<(f64, u32)>,
}

impl Nearest {
    /// Keeps surface `surface` crossed at parameter `s` if it is nearer.
    #[inline]
    pub(crate) fn offer(&mut self, surface: u32, s: f64) {
        if self
            .best
            .is_none_or(|(t, id)| s < t || (s == t && surface < id))
        {
            self.best = Some((s, surface));
        }
    }

    /// The segment parameter beyond which no crossing can be the answer:
    /// the nearest so far (a crossing there may still win on its index),
    /// else the segment's end.
    #[inline]
    pub(crate) fn limit(&self) -> f64 {
        self.best.map_or(1.0, |(s, _)| s)
    }

    /// The answer of a ray whose segment is `max_t` long in parameter.
    pub(crate) fn hit(self, max_t: f64) -> Option<Hit> {
        self.best.map(|(s, surface)| Hit {
            surface,
            t: s * max_t,
        })
    }
}

/// The surfaces laid out for [`segment_crosses`]: each one's plane and, per
/// edge, the in-plane inward normal `n x e` with its offset and squared
/// tolerance, so the inside test is three multiply-adds an edge instead of
/// a cross product. One flat array, shared by every accelerator: the answer
/// to a query never depends on which accelerator asked.
#[derive(Clone, Debug, Default)]
pub struct PreparedSurfaces {
    planes: Vec<PreparedPlane>,
    edges: Vec<PreparedEdge>,
}

#[derive(Clone, Copy, Debug)]
struct PreparedPlane {
    normal: DVec3,
    offset: f64,
    first_edge: u32,
    end_edge: u32,
    group: u32,
}

#[derive(Clone, Copy, Debug)]
struct PreparedEdge {
    /// `n x (b - a)`, pointing into the polygon.
    inward: DVec3,
    /// `inward . a`.
    offset: f64,
    /// `tolerance^2 |b - a|^2`: a point outside by less is still inside.
    slack: f64,
}

impl PreparedSurfaces {
    /// Precomputes the planes and edges of `surfaces`.
    #[must_use]
    pub fn new(surfaces: &[Surface]) -> PreparedSurfaces {
        let mut prepared = PreparedSurfaces::default();
        for surface in surfaces {
            let first_edge = prepared.edges.len() as u32;
            let tolerance = EDGE_TOLERANCE * surface.area.sqrt();
            let n = surface.polygon.len();
            for i in 0..n {
                let a = surface.polygon[i];
                let edge = surface.polygon[(i + 1) % n] - a;
                let inward = surface.normal.cross(edge);
                prepared.edges.push(PreparedEdge {
                    inward,
                    offset: inward.dot(a),
                    slack: tolerance * tolerance * edge.length_squared(),
                });
            }
            prepared.planes.push(PreparedPlane {
                normal: surface.normal,
                offset: surface.offset,
                first_edge,
                end_edge: prepared.edges.len() as u32,
                group: surface.group,
            });
        }
        prepared
    }

    /// Number of surfaces.
    #[must_use]
    pub fn len(&self) -> usize {
        self.planes.len()
    }

    /// True when there are no surfaces.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.planes.is_empty()
    }

    /// True when surface `id` belongs to one of the surface ids a query
    /// skips (see [`Occluder::occluded`]).
    #[must_use]
    #[inline]
    pub fn skips(&self, id: u32, skip: [u32; 2]) -> bool {
        let group = self.planes[id as usize].group;
        group == skip[0] || group == skip[1]
    }

    /// [`segment_crosses`] for surface `id`.
    #[must_use]
    #[inline]
    pub fn crosses(&self, id: u32, from: DVec3, to: DVec3) -> bool {
        self.crossing(id, from, to).is_some()
    }

    /// [`segment_crossing`] for surface `id`: the same parameter, bit for
    /// bit, wherever both accept the crossing point. Every accelerator's
    /// closest hit is computed with it, so their distances are equal, not
    /// merely close.
    #[must_use]
    #[inline(always)]
    pub fn crossing(&self, id: u32, from: DVec3, to: DVec3) -> Option<f64> {
        let plane = &self.planes[id as usize];
        let d0 = plane.normal.dot(from) - plane.offset;
        let d1 = plane.normal.dot(to) - plane.offset;
        if d0 == 0.0 || d1 == 0.0 || (d0 > 0.0) == (d1 > 0.0) {
            return None;
        }
        let t = d0 / (d0 - d1);
        let p = from + (to - from) * t;
        self.edges[plane.first_edge as usize..plane.end_edge as usize]
            .iter()
            .all(|e| {
                let side = e.inward.dot(p) - e.offset;
                side >= 0.0 || side * side <= e.slack
            })
            .then_some(t)
    }
}

/// The part of a surface's plane where [`segment_crosses`] can accept a
/// crossing point, with the edge tolerance taken `widen` times wider:
/// within the tolerance of every edge line, measured as the test measures
/// it (along `normal x edge`, divided by the 3-D edge length). Near a sharp
/// corner it reaches `tolerance / sin(angle / 2)` beyond the polygon, so the
/// accelerators size their culling (the BSP's reach, the BVH's boxes) from
/// it rather than from the corners.
pub(crate) enum AcceptanceRegion {
    /// A bounded region: the surface and the region in plane coordinates
    /// `origin + x u + y v`.
    Bounded {
        /// A point of the plane.
        origin: DVec3,
        /// In-plane axes.
        axes: [DVec3; 2],
        /// The surface's corners in plane coordinates.
        polygon: Vec<DVec2>,
        /// The region's corners in plane coordinates.
        region: Vec<DVec2>,
    },
    /// No point is accepted (the widened edges exclude each other).
    Empty,
    /// The edges do not bound a region: a degenerate polygon.
    Unbounded,
}

impl AcceptanceRegion {
    /// The region of `surface` with the tolerance `widen` times wider.
    pub(crate) fn of(surface: &Surface, widen: f64) -> AcceptanceRegion {
        let normal = surface.normal;
        let tolerance = widen * EDGE_TOLERANCE * surface.area.sqrt();
        let u = normal.any_orthonormal_vector();
        let v = normal.cross(u);
        let first = surface.polygon[0];
        let origin = first - normal * (normal.dot(first) - surface.offset);
        let flat: Vec<DVec2> = surface
            .polygon
            .iter()
            .map(|p| DVec2::new(u.dot(*p - origin), v.dot(*p - origin)))
            .collect();
        let n = flat.len();
        // The region is { q : inward . q >= c } for every edge.
        let edges: Vec<(DVec2, f64)> = (0..n)
            .filter_map(|i| {
                let length = (surface.polygon[(i + 1) % n] - surface.polygon[i]).length();
                let (a, b) = (flat[i], flat[(i + 1) % n]);
                let flat_length = (b - a).length();
                let inward = (b - a).perp().try_normalize()?;
                if length == 0.0 {
                    return None;
                }
                Some((inward, inward.dot(a) - tolerance * length / flat_length))
            })
            .collect();
        // Clip a square grown until the region lies well inside it.
        let mut half = 2.0 * geometry::diameter(&surface.polygon).max(tolerance);
        for _ in 0..60 {
            if !half.is_finite() {
                break;
            }
            let mut region = vec![
                DVec2::new(-half, -half),
                DVec2::new(half, -half),
                DVec2::new(half, half),
                DVec2::new(-half, half),
            ];
            let mut clipped = Vec::with_capacity(region.len() + edges.len());
            for &(inward, c) in &edges {
                clip::clip_into(&region, |q| inward.dot(q) - c, &mut clipped);
                std::mem::swap(&mut region, &mut clipped);
            }
            if region.is_empty() {
                return AcceptanceRegion::Empty;
            }
            if region
                .iter()
                .all(|q| q.x.abs() < 0.5 * half && q.y.abs() < 0.5 * half)
            {
                return AcceptanceRegion::Bounded {
                    origin,
                    axes: [u, v],
                    polygon: flat,
                    region,
                };
            }
            half *= 4.0;
        }
        AcceptanceRegion::Unbounded
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The prepared form answers exactly as the definition on random
    /// segments through the built-in room, edges and corners included.
    #[test]
    fn prepared_surfaces_agree_with_the_definition() {
        let scene = crate::scene::builtin::load("room").unwrap().unwrap();
        let prepared = PreparedSurfaces::new(&scene.surfaces);
        let (lo, hi) = scene.bounds();
        let mut random = test_scenes::uniform(0x2545_f491_4f6c_dd1d);
        let corners: Vec<DVec3> = scene
            .surfaces
            .iter()
            .flat_map(|s| s.polygon.clone())
            .collect();
        let mut crossings = 0;
        for i in 0..20_000 {
            let mut point = || lo + (hi - lo) * DVec3::new(random(), random(), random());
            let from = point();
            // Every fourth segment ends on a corner: the edge case.
            let to = if i % 4 == 0 {
                corners[i % corners.len()]
            } else {
                point()
            };
            for (id, surface) in scene.surfaces.iter().enumerate() {
                let expected = segment_crossing(surface, from, to);
                crossings += usize::from(expected.is_some());
                assert_eq!(prepared.crossing(id as u32, from, to), expected);
                assert_eq!(prepared.crosses(id as u32, from, to), expected.is_some());
            }
        }
        assert!(crossings > 1000);
    }
}

/// Small hand-made scenes for the accelerators' own unit tests (the suite
/// over every accelerator is `tests/accel.rs`).
#[cfg(test)]
pub(crate) mod test_scenes {
    use glam::DVec3;

    use crate::scene::Surface;

    /// No surface skipped.
    pub(crate) const NONE_SKIPPED: [u32; 2] = [u32::MAX; 2];

    /// A fixed-seed xorshift generator (Marsaglia 2003) for the tests'
    /// random queries: the same draws on every run and machine.
    pub(crate) fn xorshift(seed: u64) -> impl FnMut() -> u64 {
        let mut state = seed;
        move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        }
    }

    /// [`xorshift`]'s draws as uniform numbers in `[0, 1)`.
    pub(crate) fn uniform(seed: u64) -> impl FnMut() -> f64 {
        let mut next = xorshift(seed);
        move || (next() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// A grey quad with the given corners, surface id 0.
    pub(crate) fn quad(corners: [[f64; 3]; 4]) -> Surface {
        let p = corners.iter().map(|c| DVec3::from_array(*c)).collect();
        Surface::new(p, DVec3::splat(0.5), DVec3::ZERO, 0).unwrap()
    }

    /// The square `[-half, half]^2` at height `z`, facing `+z`.
    pub(crate) fn square_at_z(z: f64, half: f64) -> Surface {
        quad([
            [-half, -half, z],
            [half, -half, z],
            [half, half, z],
            [-half, half, z],
        ])
    }
}
