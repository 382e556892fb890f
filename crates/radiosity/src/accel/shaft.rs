//! Shafts (Haines & Wallace 1991, "Shaft culling for efficient ray-traced
//! radiosity"; beyond the paper): the convex region that holds every
//! segment between a ball of receiving points and a convex source
//! polygon. Where no surface meets it, no segment between them is
//! blocked, and none of their shadow rays need be cast: one walk of the
//! tree answers for all of them.
//!
//! The region is bounded by a plane through the ball's centre and each of
//! the polygon's edges, moved out by the ball's radius, by the polygon's
//! plane, and by the box of the ball and the polygon. A box or a surface
//! lying wholly beyond one of these (by more than a tolerance that covers
//! round-off and [`super::segment_crosses`]'s edge tolerance) cannot meet
//! a segment of the shaft; anything else is taken as meeting it, so a
//! shaft is only ever declared clear when it is.

use glam::DVec3;

use crate::geometry;

/// The most corners of a polygon a shaft is made for (surfaces are
/// triangles and quads but for a few large polygons, which are left to
/// shadow rays).
pub const MAX_CORNERS: usize = 8;

const MAX_PLANES: usize = MAX_CORNERS + 2;

/// The fraction of the tolerance within which a point before the source
/// polygon's plane counts as on it: `1e-6` of the tolerance, `1e-12` of
/// the scale, round-off of the plane's own computation.
const SHAFT_ROUND_OFF: f64 = 1e-6;

/// The region between a ball and a convex polygon (module notes).
#[derive(Clone, Copy, Debug)]
pub struct Shaft {
    /// `(n, d)`: the region lies where `n . p <= d` (the first
    /// `count`); the polygon's plane first.
    planes: [(DVec3, f64); MAX_PLANES],
    /// The ball's centre.
    origin: DVec3,
    count: usize,
    /// A second plane that lying on counts as outside (see
    /// [`Shaft::on_plane`]); `0` for none.
    strict: usize,
    lo: DVec3,
    hi: DVec3,
    /// How far beyond a plane a point must lie to count as outside.
    tolerance: f64,
}

/// The tolerance of a shaft's tests, relative to the largest coordinate
/// of the points it was made from: far beyond both `f64` round-off in the
/// planes (a few `1e-16`) and the segment test's edge tolerance (`1e-9` of
/// a surface's size).
pub const SHAFT_TOLERANCE: f64 = 1e-6;

impl Shaft {
    /// The shaft between the ball of `radius` about `centre` and the convex
    /// planar `polygon`; `None` where the ball is not wholly before or
    /// behind the polygon's plane, or the polygon is degenerate, not
    /// finite or has more than [`MAX_CORNERS`] corners.
    #[must_use]
    pub fn between(centre: DVec3, radius: f64, polygon: &[DVec3]) -> Option<Shaft> {
        let normal = geometry::normal(polygon)?;
        Shaft::around(centre, radius, polygon, normal, geometry::centroid(polygon))
    }

    /// [`Shaft::between`] with the polygon's unit normal (either side)
    /// and a point inside it (its centroid) given.
    #[must_use]
    pub fn around(
        centre: DVec3,
        radius: f64,
        polygon: &[DVec3],
        normal: DVec3,
        middle: DVec3,
    ) -> Option<Shaft> {
        if polygon.len() > MAX_CORNERS || !(0.0..f64::INFINITY).contains(&radius) {
            return None;
        }
        let height = normal.dot(centre - polygon[0]);
        if height.is_nan() || height.abs() <= radius {
            return None;
        }
        let scale = polygon
            .iter()
            .chain(std::iter::once(&centre))
            .map(|p| p.abs().max_element())
            .fold(radius, f64::max);
        if !scale.is_finite() {
            return None;
        }
        let inward = normal * height.signum();
        let mut planes = [(DVec3::ZERO, 0.0); MAX_PLANES];
        // Not behind the polygon's plane (seen from the ball).
        planes[0] = (-inward, -inward.dot(polygon[0]));
        for (i, &a) in polygon.iter().enumerate() {
            let b = polygon[(i + 1) % polygon.len()];
            let mut n = (a - centre).cross(b - centre);
            let length = n.length();
            if length.is_nan() || length <= 0.0 {
                return None;
            }
            n /= length;
            if n.dot(middle - centre) > 0.0 {
                n = -n;
            }
            planes[i + 1] = (n, n.dot(centre) + radius);
        }
        let (mut lo, mut hi) = (centre - DVec3::splat(radius), centre + DVec3::splat(radius));
        for p in polygon {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        Some(Shaft {
            planes,
            count: polygon.len() + 1,
            strict: 0,
            origin: centre,
            lo,
            hi,
            tolerance: SHAFT_TOLERANCE * scale,
        })
    }

    /// The shaft with its tolerance at least [`SHAFT_TOLERANCE`] of
    /// `scale` (the largest coordinate of the surfaces tested against it).
    #[must_use]
    pub fn widened(mut self, scale: f64) -> Shaft {
        if scale.is_finite() {
            self.tolerance = self.tolerance.max(SHAFT_TOLERANCE * scale);
        }
        self
    }

    /// The shaft of a ball whose points all lie on the plane through its
    /// centre with unit normal `normal` (a pixel's samples on one
    /// surface), bounded by that plane too: where the polygon lies wholly
    /// before it, what lies on it or behind (the receiving surface's
    /// neighbours in its plane, the wall it is laid on) meets the segments
    /// nowhere but at their ends, as for the polygon's own plane.
    #[must_use]
    pub fn on_plane(mut self, normal: DVec3, polygon: &[DVec3]) -> Shaft {
        if self.count == MAX_PLANES || !normal.is_finite() {
            return self;
        }
        // How far behind the plane the polygon reaches.
        let behind = polygon
            .iter()
            .map(|c| -normal.dot(*c - self.origin))
            .fold(0.0, f64::max);
        self.planes[self.count] = (-normal, -normal.dot(self.origin) + behind);
        if polygon
            .iter()
            .all(|c| normal.dot(*c - self.origin) > self.tolerance)
        {
            self.strict = self.count;
        }
        self.count += 1;
        self
    }

    fn planes(&self) -> &[(DVec3, f64)] {
        &self.planes[..self.count]
    }

    /// Whether the box `lo..hi` lies wholly outside the shaft.
    #[must_use]
    #[inline]
    pub fn misses_box(&self, lo: DVec3, hi: DVec3) -> bool {
        let t = self.tolerance;
        if lo.cmpgt(self.hi + t).any() || hi.cmplt(self.lo - t).any() {
            return true;
        }
        self.planes().iter().enumerate().any(|(i, &(n, d))| {
            // The box's corner least far along `n`.
            let near = DVec3::select(n.cmpgt(DVec3::ZERO), lo, hi);
            n.dot(near) > d + self.beyond(i)
        })
    }

    /// Whether the convex polygon with these corners lies wholly outside
    /// the shaft.
    #[must_use]
    pub fn misses_polygon(&self, corners: &[DVec3]) -> bool {
        let t = self.tolerance;
        let outside_box = (0..3).any(|axis| {
            corners.iter().all(|c| c[axis] > self.hi[axis] + t)
                || corners.iter().all(|c| c[axis] < self.lo[axis] - t)
        });
        outside_box
            || self.planes().iter().enumerate().any(|(i, &(n, d))| {
                let beyond = d + self.beyond(i);
                corners.iter().all(|c| n.dot(*c) > beyond)
            })
    }

    /// How far beyond plane `i` a point must lie to be outside: the
    /// tolerance, but for the polygon's own plane, where lying on it is
    /// enough (up to round-off, `SHAFT_ROUND_OFF` of the tolerance): the
    /// segments leave the polygon's front, and what lies behind it or on
    /// its plane (the polygon's own frame, a ceiling it is flush with)
    /// meets them nowhere but at their ends, which are not part of them.
    fn beyond(&self, i: usize) -> f64 {
        if i == 0 || i == self.strict {
            -SHAFT_ROUND_OFF * self.tolerance
        } else {
            self.tolerance
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::Shaft;
    use crate::accel::brute::BruteForce;
    use crate::accel::bvh::Bvh;
    use crate::accel::test_scenes::{quad, uniform};
    use crate::accel::{Occluder, ShadowCache};

    /// Against the brute-force oracle in the built-in room: wherever the
    /// BVH calls a shaft clear (between a ball about a random point and a
    /// random surface of the room, the ball's own surface and the source's
    /// skipped), no segment between random points of the ball and of the
    /// surface is blocked; and the shadow cache never changes an answer.
    #[test]
    fn a_clear_shaft_has_no_blocked_segment() {
        let scene = crate::scene::builtin::load("room").unwrap().unwrap();
        let bvh = Bvh::new(&scene.surfaces);
        let brute = BruteForce::new(&scene.surfaces);
        let (lo, hi) = scene.bounds();
        let mut random = uniform(0x9e37_79b9_7f4a_7c15);
        let (mut clear, mut met) = (0, 0);
        let mut warm = ShadowCache::default();
        for i in 0..4000 {
            let source = &scene.surfaces[i % scene.surfaces.len()];
            let centre = lo + (hi - lo) * DVec3::new(random(), random(), random());
            let radius = 0.05 * random();
            let Some(shaft) = Shaft::between(centre, radius, &source.polygon) else {
                continue;
            };
            let skip = [source.group, u32::MAX];
            let answer = bvh.shaft_clear(&shaft, skip, &mut ShadowCache::default());
            warm.from_origin(i as u32 % 7);
            assert_eq!(bvh.shaft_clear(&shaft, skip, &mut warm), answer);
            if !answer {
                met += 1;
                continue;
            }
            clear += 1;
            for _ in 0..64 {
                // A point of the ball, a point of the convex polygon.
                let offset = DVec3::new(random(), random(), random()) * 2.0 - 1.0;
                let from = centre + offset.normalize_or_zero() * radius * random();
                let weights: Vec<f64> = source.polygon.iter().map(|_| random()).collect();
                let total: f64 = weights.iter().sum();
                let to = source
                    .polygon
                    .iter()
                    .zip(&weights)
                    .map(|(c, w)| *c * (w / total))
                    .sum::<DVec3>();
                assert!(
                    !brute.occluded(from, to, skip),
                    "a clear shaft from {centre} ({radius}) to surface {i}: {from} -> {to} blocked"
                );
            }
        }
        assert!(clear > 200 && met > 200, "{clear} clear, {met} met");
    }

    /// A board across the shaft meets it; the lamp's own housing behind
    /// its plane and the floor the ball lies on (with
    /// [`Shaft::on_plane`]) do not.
    #[test]
    fn what_meets_a_shaft() {
        let lamp = quad([
            [-0.5, 2.0, -0.5],
            [-0.5, 2.0, 0.5],
            [0.5, 2.0, 0.5],
            [0.5, 2.0, -0.5],
        ]);
        let housing = quad([
            [-0.5, 2.0, -0.5],
            [0.5, 2.0, -0.5],
            [0.5, 2.3, -0.5],
            [-0.5, 2.3, -0.5],
        ]);
        let floor = quad([
            [-3.0, 0.0, -3.0],
            [-3.0, 0.0, 3.0],
            [3.0, 0.0, 3.0],
            [3.0, 0.0, -3.0],
        ]);
        let board = quad([
            [-0.2, 1.0, -0.2],
            [-0.2, 1.0, 0.2],
            [0.2, 1.0, 0.2],
            [0.2, 1.0, -0.2],
        ]);
        let centre = DVec3::new(0.1, 0.0, 0.1);
        let shaft = Shaft::between(centre, 0.01, &lamp.polygon)
            .unwrap()
            .on_plane(DVec3::Y, &lamp.polygon);
        let meets = |s: &crate::scene::Surface| !shaft.misses_polygon(&s.polygon);
        assert!(meets(&board));
        assert!(!meets(&housing));
        assert!(!meets(&floor));
        // Beside the shaft, not in it.
        let aside = quad([
            [2.0, 1.0, -0.2],
            [2.0, 1.0, 0.2],
            [2.4, 1.0, 0.2],
            [2.4, 1.0, -0.2],
        ]);
        assert!(!meets(&aside));
        // Without the floor's plane, the floor is taken as meeting it.
        let loose = Shaft::between(centre, 0.01, &lamp.polygon).unwrap();
        assert!(!loose.misses_polygon(&floor.polygon));
        // A ball crossing the lamp's plane has no shaft.
        assert!(Shaft::between(DVec3::new(0.0, 2.0, 0.0), 0.1, &lamp.polygon).is_none());
        // Through the BVH: the board is found, the rest are not.
        let mut scene = vec![lamp.clone(), housing, floor, aside];
        for (i, s) in scene.iter_mut().enumerate() {
            s.group = i as u32;
        }
        let bvh = Bvh::new(&scene);
        let mut cache = ShadowCache::default();
        assert!(bvh.shaft_clear(&shaft, [0, 2], &mut cache));
        let mut with_board = scene.clone();
        let mut board = board;
        board.group = 9;
        with_board.push(board);
        let bvh = Bvh::new(&with_board);
        assert!(!bvh.shaft_clear(&shaft, [0, 2], &mut cache));
    }
}
