//! The paper's subsources (Wong & Tsang 1993, section 2; design.md section
//! 2, step 2): a shooting patch split into an `n x n` grid of pieces, each
//! shooting from its area-weighted centroid.

use glam::DVec3;

use super::{barycentric, bilinear};
use crate::geometry;

/// A piece of a patch that shoots as one: its polygon, area-weighted
/// centroid `c_k`, area `A_k` (design.md section 2, step 2).
#[derive(Clone, Debug)]
pub struct Subsource {
    /// Corners (3 or 4), counter-clockwise.
    pub polygon: Vec<DVec3>,
    /// Area-weighted centroid.
    pub centroid: DVec3,
    /// Area, m^2.
    pub area: f64,
}

/// Splits a patch polygon into an `n x n` grid of subsources: `n^2`
/// bilinear sub-quads of a quad, `n^2` sub-triangles of a triangle.
#[must_use]
pub fn subsources(polygon: &[DVec3], n: u32) -> Vec<Subsource> {
    let n = u64::from(n.max(1));
    let mut out = Vec::with_capacity((n * n) as usize);
    let mut push = |polygon: Vec<DVec3>| {
        out.push(Subsource {
            centroid: geometry::centroid(&polygon),
            area: geometry::area(&polygon),
            polygon,
        });
    };
    if polygon.len() == 4 {
        let point = |i: u64, j: u64| bilinear(polygon, i as f64 / n as f64, j as f64 / n as f64);
        for j in 0..n {
            for i in 0..n {
                push(vec![
                    point(i, j),
                    point(i + 1, j),
                    point(i + 1, j + 1),
                    point(i, j + 1),
                ]);
            }
        }
    } else {
        let v0 = polygon[0];
        let fans = polygon.len().saturating_sub(2);
        for f in 0..fans {
            let tri = [v0, polygon[f + 1], polygon[f + 2]];
            let point = |i: u64, j: u64| barycentric(tri, i as f64 / n as f64, j as f64 / n as f64);
            for j in 0..n {
                for i in 0..n - j {
                    push(vec![point(i, j), point(i + 1, j), point(i, j + 1)]);
                    if i + j + 2 <= n {
                        push(vec![point(i + 1, j), point(i + 1, j + 1), point(i, j + 1)]);
                    }
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rect(w: f64, h: f64) -> Vec<DVec3> {
        vec![
            DVec3::ZERO,
            DVec3::new(w, 0.0, 0.0),
            DVec3::new(w, h, 0.0),
            DVec3::new(0.0, h, 0.0),
        ]
    }

    #[test]
    fn subsources_tile_the_patch() {
        for polygon in [
            rect(1.0, 2.0),
            vec![DVec3::ZERO, DVec3::X, DVec3::new(0.3, 1.0, 0.0)],
        ] {
            for n in 1..5 {
                let subs = subsources(&polygon, n);
                assert_eq!(subs.len(), (n * n) as usize);
                let total: f64 = subs.iter().map(|s| s.area).sum();
                assert!((total - geometry::area(&polygon)).abs() < 1e-12);
                // The area-weighted mean of the centroids is the centroid.
                let c: DVec3 = subs.iter().map(|s| s.centroid * s.area).sum::<DVec3>() / total;
                assert!((c - geometry::centroid(&polygon)).length() < 1e-12);
            }
        }
    }
}
