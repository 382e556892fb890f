//! Planar-polygon geometry shared by every stage: Newell normals, areas,
//! centroids, clipping to a half-space and point-in-convex-polygon tests;
//! the one polygon clipper ([`clip`]) and the triangulation of simple
//! polygons ([`triangulate`]).
//!
//! These are the primitives behind the subsource split and receiver-side
//! clipping of design.md section 2 (step 3) and behind the shadow-segment test
//! of section 3. Everything is `f64`: the form factors near a source
//! (paper section 4) lose digits quickly in `f32`.

use glam::DVec3;

pub mod clip;
pub mod spherical;
pub mod triangulate;

/// Newell's normal of a polygon: twice the vector area, robust for slightly
/// non-planar or nearly collinear input. Zero for a degenerate polygon.
#[must_use]
pub fn newell_area_vector(polygon: &[DVec3]) -> DVec3 {
    // About the first corner rather than the origin: the same sum, but a
    // small polygon far from the origin keeps its digits (about the origin
    // each cross product is huge and they cancel).
    let Some(&origin) = polygon.first() else {
        return DVec3::ZERO;
    };
    let mut sum = DVec3::ZERO;
    for (i, a) in polygon.iter().enumerate() {
        let b = polygon[(i + 1) % polygon.len()];
        sum += (*a - origin).cross(b - origin);
    }
    sum
}

/// Area of a planar polygon.
#[must_use]
pub fn area(polygon: &[DVec3]) -> f64 {
    0.5 * newell_area_vector(polygon).length()
}

/// Unit normal by the right-hand rule (counter-clockwise seen from the
/// front), or `None` for a polygon with no area.
#[must_use]
pub fn normal(polygon: &[DVec3]) -> Option<DVec3> {
    newell_area_vector(polygon).try_normalize()
}

/// Area-weighted centroid of a planar polygon (not the mean of its corners,
/// which differs for anything but triangles and parallelograms).
#[must_use]
pub fn centroid(polygon: &[DVec3]) -> DVec3 {
    let n = polygon.len();
    if n == 0 {
        return DVec3::ZERO;
    }
    let origin = polygon[0];
    let mut weighted = DVec3::ZERO;
    let mut total = 0.0;
    let axis = newell_area_vector(polygon);
    for i in 1..n.saturating_sub(1) {
        let (b, c) = (polygon[i], polygon[i + 1]);
        let w = (b - origin).cross(c - origin).dot(axis);
        weighted += w * (origin + b + c) / 3.0;
        total += w;
    }
    if total.abs() <= f64::MIN_POSITIVE {
        polygon.iter().copied().sum::<DVec3>() / n as f64
    } else {
        weighted / total
    }
}

/// Largest distance between two corners: the scale that tolerances are
/// measured against.
#[must_use]
pub fn diameter(polygon: &[DVec3]) -> f64 {
    let mut d2: f64 = 0.0;
    for (i, a) in polygon.iter().enumerate() {
        for b in &polygon[i + 1..] {
            d2 = d2.max(a.distance_squared(*b));
        }
    }
    d2.sqrt()
}

/// Clips `polygon` to the half-space `normal . (p - point) >= 0`, writing
/// the result to `out`. Corners within `tolerance` of the plane count as
/// inside; cuts lie on the plane ([`clip::clip_each`]).
pub fn clip_to_half_space(
    polygon: &[DVec3],
    point: DVec3,
    normal: DVec3,
    tolerance: f64,
    out: &mut Vec<DVec3>,
) {
    out.clear();
    clip::clip_each(
        polygon,
        |p| normal.dot(p - point),
        tolerance,
        |p| {
            out.push(p);
        },
    );
}

/// True when `p` (assumed on the polygon's plane) lies inside the convex
/// polygon or within `tolerance` of its boundary. `normal` is the polygon's
/// unit normal.
#[must_use]
pub fn convex_contains(polygon: &[DVec3], normal: DVec3, p: DVec3, tolerance: f64) -> bool {
    let n = polygon.len();
    for i in 0..n {
        let a = polygon[i];
        let b = polygon[(i + 1) % n];
        let edge = b - a;
        // `side` is the signed distance of p from the edge line (positive
        // inside) times the edge's length; comparing squares avoids a
        // square root and a division on this hot path of every shadow ray.
        let side = normal.cross(edge).dot(p - a);
        if side < 0.0 && side * side > tolerance * tolerance * edge.length_squared() {
            return false;
        }
    }
    true
}

/// True when the polygon is convex (every turn the same way round its
/// normal), allowing collinear corners.
#[must_use]
pub fn is_convex(polygon: &[DVec3], normal: DVec3, tolerance: f64) -> bool {
    let n = polygon.len();
    for i in 0..n {
        let a = polygon[i];
        let b = polygon[(i + 1) % n];
        let c = polygon[(i + 2) % n];
        let turn = (b - a).cross(c - b).dot(normal);
        if turn < -tolerance {
            return false;
        }
    }
    true
}

/// The plane offset `d` with `normal . p = d` for points on the polygon.
#[must_use]
pub fn plane_offset(polygon: &[DVec3], normal: DVec3) -> f64 {
    polygon.iter().map(|p| normal.dot(*p)).sum::<f64>() / polygon.len() as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_square() -> Vec<DVec3> {
        vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ]
    }

    #[test]
    fn square_area_normal_centroid() {
        let sq = unit_square();
        assert!((area(&sq) - 1.0).abs() < 1e-15);
        assert_eq!(normal(&sq), Some(DVec3::Z));
        assert!((centroid(&sq) - DVec3::new(0.5, 0.5, 0.0)).length() < 1e-15);
    }

    #[test]
    fn a_small_triangle_far_from_the_origin_keeps_its_normal() {
        let far = DVec3::new(1e4, -3e3, 7e3);
        let tri = [far, far + DVec3::X * 1e-4, far + DVec3::Y * 1e-4];
        let n = normal(&tri).unwrap();
        assert!((n - DVec3::Z).length() < 1e-9, "{n}");
        // Corners are rounded to about 2e-12 at this distance.
        assert!((area(&tri) / 0.5e-8 - 1.0).abs() < 1e-6);
    }

    #[test]
    fn centroid_of_trapezoid_is_area_weighted() {
        // Trapezoid with parallel sides 2 and 1 at y=0 and y=1: centroid
        // height (h/3)(a+2b)/(a+b) = (1/3)(2+2)/3 = 4/9.
        let t = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(1.5, 1.0, 0.0),
            DVec3::new(0.5, 1.0, 0.0),
        ];
        let c = centroid(&t);
        assert!((c.y - 4.0 / 9.0).abs() < 1e-14, "{c}");
        assert!((c.x - 1.0).abs() < 1e-14);
    }

    #[test]
    fn clipping_halves_a_square() {
        let mut out = Vec::new();
        clip_to_half_space(
            &unit_square(),
            DVec3::new(0.5, 0.0, 0.0),
            DVec3::X,
            0.0,
            &mut out,
        );
        assert!((area(&out) - 0.5).abs() < 1e-15);
        assert!((centroid(&out) - DVec3::new(0.75, 0.5, 0.0)).length() < 1e-15);
    }

    #[test]
    fn contains_and_convexity() {
        let sq = unit_square();
        assert!(convex_contains(
            &sq,
            DVec3::Z,
            DVec3::new(0.5, 0.5, 0.0),
            0.0
        ));
        assert!(convex_contains(
            &sq,
            DVec3::Z,
            DVec3::new(1.0, 0.5, 0.0),
            1e-12
        ));
        assert!(!convex_contains(
            &sq,
            DVec3::Z,
            DVec3::new(1.1, 0.5, 0.0),
            1e-12
        ));
        assert!(is_convex(&sq, DVec3::Z, 0.0));
        let dart = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(1.0, 0.5, 0.0),
            DVec3::new(1.0, 2.0, 0.0),
        ];
        assert!(!is_convex(&dart, DVec3::Z, 1e-12));
    }
}
