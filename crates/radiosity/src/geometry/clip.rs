//! The one polygon clipper: Sutherland & Hodgman's re-entrant clip against
//! a plane ("Reentrant polygon clipping", CACM 1974), used by the
//! subsource clip of design.md section 2 (step 3), the analytic factor's
//! front half-space (paper equation (2)), the hemicube's frustum (paper
//! section 2), the BSP's splits, the acceptance region of the shadow test
//! and the renderer's near plane.
//!
//! Beyond the textbook: each cut point is interpolated from the edge's end
//! nearer the plane (the inside end on a tie), a choice that depends on the
//! edge and the plane only, not on the direction the edge is walked. So the
//! edge two polygons share, walked in opposite directions, is cut at the
//! bit-identical point from both sides, and clipped neighbours stay
//! watertight; [`split_into`] gives its two parts the same cut. This is the
//! hemicube's former rule (interpolate from the inside end) with the same
//! guarantee and less round-off: the error of `p + (q - p) t` grows with the
//! distance interpolated, and a long edge cut near one end is interpolated
//! the short way. A cut that would coincide with a kept corner on the plane
//! is not emitted twice.
//!
//! The clipper is generic over the corner type ([`Lerp`]: 2-D and 3-D
//! points, or a point with an attribute such as a colour) and takes the
//! signed distance as a closure, so one routine serves planes in any
//! coordinates; it writes into a caller's buffer or streams corners to a
//! closure, and never allocates.

use glam::{DVec2, DVec3};

/// A corner the clipper can interpolate along an edge.
pub trait Lerp: Copy {
    /// The point at parameter `t` from `self` (0) to `to` (1).
    #[must_use]
    fn lerp_to(self, to: Self, t: f64) -> Self;
}

impl Lerp for DVec2 {
    #[inline]
    fn lerp_to(self, to: Self, t: f64) -> Self {
        self + (to - self) * t
    }
}

impl Lerp for DVec3 {
    #[inline]
    fn lerp_to(self, to: Self, t: f64) -> Self {
        self + (to - self) * t
    }
}

/// A corner with an attribute (a position and a colour, say), both
/// interpolated with the same parameter.
impl<A: Lerp, B: Lerp> Lerp for (A, B) {
    #[inline]
    fn lerp_to(self, to: Self, t: f64) -> Self {
        (self.0.lerp_to(to.0, t), self.1.lerp_to(to.1, t))
    }
}

/// Streams the corners of `polygon` clipped to `distance(p) >= 0` to `emit`,
/// in order. Corners with `distance >= -tolerance` count as inside; an edge
/// between an inside and an outside corner is cut where it crosses
/// `distance = 0` itself (not the tolerance band), interpolated from the
/// end nearer the plane. Each corner's distance is evaluated once.
#[inline]
pub fn clip_each<V: Lerp>(
    polygon: &[V],
    distance: impl Fn(V) -> f64,
    tolerance: f64,
    mut emit: impl FnMut(V),
) {
    for_each_edge(polygon, distance, |(a, da), (b, db)| {
        let (a_in, b_in) = (da >= -tolerance, db >= -tolerance);
        if a_in {
            emit(a);
        }
        if a_in != b_in {
            let (p, dp, q, dq) = if a_in { (a, da, b, db) } else { (b, db, a, da) };
            // An inside end on the plane (or in the tolerance band) is the
            // cut itself, and is emitted as a corner.
            if dp > 0.0 {
                emit(crossing(p, dp, q, dq));
            }
        }
    });
}

/// Clips `polygon` to `distance(p) >= 0` into `out` (cleared first): see
/// [`clip_each`].
#[inline]
pub fn clip_into<V: Lerp>(polygon: &[V], distance: impl Fn(V) -> f64, out: &mut Vec<V>) {
    out.clear();
    clip_each(polygon, distance, 0.0, |v| out.push(v));
}

/// Cuts `polygon` at `distance(p) = 0` into the part with `distance >= 0`
/// (`front`) and the part with `distance <= 0` (`back`), both cleared
/// first; corners on the plane go to both. Each cut point is computed once
/// (from the end nearer the plane), goes to both parts and is passed to
/// `cut`.
#[inline]
pub fn split_into<V: Lerp>(
    polygon: &[V],
    distance: impl Fn(V) -> f64,
    front: &mut Vec<V>,
    back: &mut Vec<V>,
    mut cut: impl FnMut(V),
) {
    front.clear();
    back.clear();
    for_each_edge(polygon, distance, |(a, da), (b, db)| {
        if da >= 0.0 {
            front.push(a);
        }
        if da <= 0.0 {
            back.push(a);
        }
        if (da > 0.0 && db < 0.0) || (da < 0.0 && db > 0.0) {
            let (p, dp, q, dq) = if da > 0.0 {
                (a, da, b, db)
            } else {
                (b, db, a, da)
            };
            let c = crossing(p, dp, q, dq);
            front.push(c);
            back.push(c);
            cut(c);
        }
    });
}

/// Calls `f` on the polygon's edges in order, as
/// `((a, distance(a)), (b, distance(b)))`, with each corner's distance
/// evaluated once.
#[inline]
fn for_each_edge<V: Lerp>(
    polygon: &[V],
    distance: impl Fn(V) -> f64,
    mut f: impl FnMut((V, f64), (V, f64)),
) {
    let Some(&first) = polygon.first() else {
        return;
    };
    let first = (first, distance(first));
    let mut a = first;
    for &v in &polygon[1..] {
        let b = (v, distance(v));
        f(a, b);
        a = b;
    }
    f(a, first);
}

/// Where the edge from `p` (distance `dp > 0`) to `q` (`dq < 0`) crosses
/// the plane, interpolated from the end nearer the plane (`p` on a tie).
#[inline]
fn crossing<V: Lerp>(p: V, dp: f64, q: V, dq: f64) -> V {
    if -dq < dp {
        q.lerp_to(p, dq / (dq - dp))
    } else {
        p.lerp_to(q, dp / (dp - dq))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> [DVec3; 4] {
        [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ]
    }

    #[test]
    fn a_shared_edge_clips_to_the_same_corner_both_ways() {
        let p = DVec3::new(-0.7, 0.31, 0.9);
        let q = DVec3::new(1.9, -0.13, 0.45);
        let form = DVec3::new(-1.0, 0.0, 1.0);
        let distance = |v: DVec3| form.dot(v);
        let (mut one, mut other) = (Vec::new(), Vec::new());
        // Two triangles sharing p-q, walked in opposite directions.
        clip_into(&[p, q, DVec3::new(0.0, -1.0, 2.0)], distance, &mut one);
        clip_into(&[q, p, DVec3::new(0.0, 1.0, 2.0)], distance, &mut other);
        let crossing = |v: &[DVec3]| {
            v.iter()
                .copied()
                .find(|c| *c != p && *c != q && (*c - p).cross(q - p).length() < 1e-12)
                .expect("the edge is cut")
        };
        assert_eq!(crossing(&one).to_array(), crossing(&other).to_array());

        // The same edge split by the plane: both neighbours and both parts
        // share the cut.
        let (mut front, mut back, mut cuts) = (Vec::new(), Vec::new(), Vec::new());
        split_into(
            &[p, q, DVec3::new(0.0, -1.0, 2.0)],
            distance,
            &mut front,
            &mut back,
            |c| cuts.push(c),
        );
        split_into(
            &[q, p, DVec3::new(0.0, 1.0, 2.0)],
            distance,
            &mut one,
            &mut other,
            |c| cuts.push(c),
        );
        let shared = crossing(&front);
        assert_eq!(shared.to_array(), crossing(&back).to_array());
        assert_eq!(shared.to_array(), crossing(&one).to_array());
        assert!(cuts.iter().filter(|c| **c == shared).count() == 2);
    }

    #[test]
    fn a_corner_on_the_plane_is_emitted_once() {
        // The plane x = 1 passes through two corners of the square.
        let mut out = Vec::new();
        clip_into(&square(), |v| 1.0 - v.x, &mut out);
        assert_eq!(out, square());
        // x = 0.5 cuts two edges; the tolerance band keeps a corner just
        // outside, but the cut still lies on the plane itself.
        let tilted = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.5 - 1e-13, 1.0, 0.0),
        ];
        out.clear();
        clip_each(&tilted, |v| v.x - 0.5, 1e-12, |v| out.push(v));
        assert_eq!(out, [DVec3::new(0.5, 0.0, 0.0), tilted[1], tilted[2]]);
    }

    #[test]
    fn split_parts_tile_the_polygon_and_carry_attributes() {
        let coloured: Vec<(DVec3, DVec3)> = square().iter().map(|&p| (p, p * 2.0)).collect();
        let (mut front, mut back) = (Vec::new(), Vec::new());
        split_into(
            &coloured,
            |(p, _)| p.x - 0.25,
            &mut front,
            &mut back,
            |_| {},
        );
        let area = |v: &[(DVec3, DVec3)]| {
            let points: Vec<DVec3> = v.iter().map(|c| c.0).collect();
            crate::geometry::area(&points)
        };
        assert!((area(&front) - 0.75).abs() < 1e-15);
        assert!((area(&back) - 0.25).abs() < 1e-15);
        for (p, colour) in front.iter().chain(&back) {
            assert_eq!(*colour, *p * 2.0);
        }
        // The 2-D clipper keeps the whole of a polygon inside.
        let mut flat = Vec::new();
        let triangle = [DVec2::ZERO, DVec2::X, DVec2::Y];
        clip_into(&triangle, |q| 2.0 - q.x - q.y, &mut flat);
        assert_eq!(flat, triangle);
    }
}
