//! Lightmap texels from the solved element mesh: each texel's value is the
//! solution at a point of the surface it covers, found in the element mesh
//! and interpolated as the picture and the vertex bake interpolate it
//! (linearly over the mesh's conforming triangles, [`crate::mesh::Mesh::triangles`]).
//!
//! Rasterisation is conservative: a texel takes the triangle nearest to its
//! centre within [`REACH`] texels, at the point of that triangle nearest to
//! the centre, so every texel a bilinear lookup inside a chart reads holds a
//! value of that chart's own surface (generated charts lie at least four
//! texels apart; the input's own coordinates may leave less); passes of
//! dilation then fill the padding around charts. The point is looked up among the element
//! triangles lying in its triangle's plane and facing its way, never by
//! distance alone, so no texel near a wall or a floor takes light from the
//! other side of it: the two complaints bakers' users file most, seams and
//! leaks, are avoided by construction.

use glam::DVec2;
use rayon::prelude::*;

use crate::mesh::locator::nearest_on_triangle;

/// How far from a triangle (texels) a texel centre may lie and still take
/// its value: a bilinear lookup at a point of the triangle reads texels
/// whose centres are up to `sqrt(2)` texels away.
pub const REACH: f64 = std::f64::consts::SQRT_2 + 1e-3;

/// Calls `f` with the index of every texel of a `width x height` image whose
/// centre lies inside the triangle `corners` (texel units, `(0, 0)` the
/// image's top-left corner).
pub fn for_texels_inside(
    corners: &[[f64; 2]; 3],
    width: u32,
    height: u32,
    mut f: impl FnMut(usize),
) {
    reach_texels(corners, width, height, 0.0, |texel, _, distance| {
        if distance == 0.0 {
            f(texel);
        }
    });
}

/// Calls `f` with the index of every texel whose centre lies strictly
/// inside the triangle `corners` (a centre on an edge shared by two
/// triangles counts for neither).
pub fn for_texels_strictly_inside(
    corners: &[[f64; 2]; 3],
    width: u32,
    height: u32,
    mut f: impl FnMut(usize),
) {
    let [a, b, c] = corners.map(DVec2::from);
    let area = (b - a).perp_dot(c - a);
    if area.abs() <= 1e-12 {
        return;
    }
    let scale = 1e-9 * area.abs();
    reach_texels(corners, width, height, 0.0, |texel, _, distance| {
        if distance == 0.0 {
            let p = DVec2::new(
                (texel % width as usize) as f64 + 0.5,
                (texel / width as usize) as f64 + 0.5,
            );
            let w = [
                (c - b).perp_dot(p - b),
                (a - c).perp_dot(p - c),
                (b - a).perp_dot(p - a),
            ];
            if w.iter().all(|&w| w * area.signum() > scale) {
                f(texel);
            }
        }
    });
}

/// Calls `f(texel, barycentric, distance)` for every texel whose centre is
/// within `reach` texels of the triangle `corners`, with the barycentric
/// coordinates of the triangle's point nearest to the centre.
fn reach_texels(
    corners: &[[f64; 2]; 3],
    width: u32,
    height: u32,
    reach: f64,
    mut f: impl FnMut(usize, [f64; 3], f64),
) {
    let [a, b, c] = corners.map(DVec2::from);
    if !(a.is_finite() && b.is_finite() && c.is_finite()) {
        return;
    }
    let lo = a.min(b).min(c) - reach;
    let hi = a.max(b).max(c) + reach;
    let x0 = (lo.x - 0.5).ceil().max(0.0) as u32;
    let y0 = (lo.y - 0.5).ceil().max(0.0) as u32;
    let x1 = ((hi.x - 0.5).floor().min(f64::from(width) - 1.0)).max(-1.0);
    let y1 = ((hi.y - 0.5).floor().min(f64::from(height) - 1.0)).max(-1.0);
    if x1 < 0.0 || y1 < 0.0 {
        return;
    }
    let (x1, y1) = (x1 as u32, y1 as u32);
    let area = (b - a).perp_dot(c - a);
    for y in y0..=y1 {
        for x in x0..=x1 {
            let p = DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5);
            let (bary, distance) = nearest_on_triangle(p, a, b, c, area);
            if distance <= reach {
                f(y as usize * width as usize + x as usize, bary, distance);
            }
        }
    }
}

/// One lightmap texel's surface point: the placed primitive, its triangle
/// and the barycentric weights of the point on it.
#[derive(Clone, Copy, Debug)]
pub struct Claim {
    /// The placed primitive.
    pub primitive: u32,
    /// The triangle within it.
    pub triangle: u32,
    /// Barycentric weights of the point.
    pub bary: [f32; 3],
    /// Distance from the texel centre to the triangle, texels (0: inside).
    pub distance: f32,
}

/// For every texel of a `width x height` lightmap, the surface point it
/// shows (see the module documentation), given each primitive's triangles
/// in lightmap coordinates (`[0, 1]` over the image).
#[must_use]
pub fn claims(width: u32, height: u32, uv_triangles: &[Vec<[[f32; 2]; 3]>]) -> Vec<Option<Claim>> {
    let mut out: Vec<Option<Claim>> = vec![None; width as usize * height as usize];
    let (w, h) = (f64::from(width), f64::from(height));
    for (p, triangles) in uv_triangles.iter().enumerate() {
        for (t, uv) in triangles.iter().enumerate() {
            let corners = uv.map(|c| [f64::from(c[0]) * w, f64::from(c[1]) * h]);
            reach_texels(&corners, width, height, REACH, |texel, bary, distance| {
                let slot = &mut out[texel];
                if slot.is_none_or(|c| f64::from(c.distance) > distance) {
                    *slot = Some(Claim {
                        primitive: p as u32,
                        triangle: t as u32,
                        bary: bary.map(|x| x as f32),
                        distance: distance as f32,
                    });
                }
            });
        }
    }
    out
}

/// Fills empty texels (NaN) next to filled ones with the mean of their
/// filled neighbours (8-connected), `passes` times: the padding around
/// charts, so that filtering and mipmaps near a chart's edge read its own
/// light.
pub fn dilate(values: &mut [glam::Vec3], width: u32, height: u32, passes: u32) {
    let (w, h) = (width as usize, height as usize);
    for _ in 0..passes {
        let fills: Vec<(usize, glam::Vec3)> = (0..w * h)
            .into_par_iter()
            .filter(|&i| values[i].is_nan())
            .filter_map(|i| {
                let (x, y) = (i % w, i / w);
                let mut sum = glam::Vec3::ZERO;
                let mut n = 0u32;
                for ny in y.saturating_sub(1)..=(y + 1).min(h - 1) {
                    for nx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
                        let v = values[ny * w + nx];
                        if !v.is_nan() {
                            sum += v;
                            n += 1;
                        }
                    }
                }
                (n > 0).then(|| (i, sum / n as f32))
            })
            .collect();
        if fills.is_empty() {
            break;
        }
        // Written after the pass: a pass reads only what the one before left.
        for (i, v) in fills {
            values[i] = v;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inside_texels_of_a_corner_triangle() {
        // Centres (x + 0.5, y + 0.5) with x + y + 1 <= 8.2: x + y <= 7.
        let mut n = 0;
        for_texels_inside(&[[0.0, 0.0], [8.2, 0.0], [0.0, 8.2]], 8, 8, |_| n += 1);
        assert_eq!(n, 36);
    }
}
