//! Lightmap texels from the solved element mesh: each texel's value is the
//! solution at a point of the surface it covers, found in the element mesh
//! and interpolated as the picture and the vertex bake interpolate it
//! (linearly over the mesh's conforming triangles, [`Mesh::triangles`]).
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

use glam::{DVec2, DVec3};
use rayon::prelude::*;

use crate::mesh::Mesh;
use crate::sensors::NORMAL_AGREEMENT;

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

/// The point of triangle `abc` (signed doubled area `area`) nearest to `p`:
/// its barycentric coordinates and distance. A degenerate triangle gives
/// its nearest corner.
fn nearest_on_triangle(p: DVec2, a: DVec2, b: DVec2, c: DVec2, area: f64) -> ([f64; 3], f64) {
    if area.abs() > 1e-12 {
        let u = (c - b).perp_dot(p - b) / area;
        let v = (a - c).perp_dot(p - c) / area;
        let w = 1.0 - u - v;
        if u >= 0.0 && v >= 0.0 && w >= 0.0 {
            return ([u, v, w], 0.0);
        }
    }
    // Outside: the nearest point lies on an edge.
    let mut best = ([1.0, 0.0, 0.0], p.distance(a));
    for (i, j, e0, e1) in [(0, 1, a, b), (1, 2, b, c), (2, 0, c, a)] {
        let d = e1 - e0;
        let t = if d.length_squared() > 0.0 {
            ((p - e0).dot(d) / d.length_squared()).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let distance = p.distance(e0 + t * d);
        if distance < best.1 {
            let mut bary = [0.0; 3];
            bary[i] = 1.0 - t;
            bary[j] = t;
            best = (bary, distance);
        }
    }
    best
}

/// The element mesh's conforming triangles, indexed by a uniform grid, for
/// finding the triangle under a surface point.
pub struct Locator {
    triangles: Vec<Flat>,
    lo: DVec3,
    cell: f64,
    dims: [usize; 3],
    /// Triangles of cell `k`: `items[start[k]..start[k + 1]]`.
    start: Vec<u32>,
    items: Vec<u32>,
    /// How far from its triangle a point may be, metres.
    tolerance: f64,
}

/// An element triangle in its own plane, set up once for the many points
/// looked up in it.
struct Flat {
    /// Its first corner, the origin of `u` and `v`.
    origin: DVec3,
    /// Unit normal.
    normal: DVec3,
    /// Unit axes in its plane.
    u: DVec3,
    v: DVec3,
    /// Corners in (`u`, `v`) coordinates.
    corners: [DVec2; 3],
    /// Doubled signed area in the plane.
    area: f64,
    /// Its mesh vertices.
    vertices: [u32; 3],
}

impl Flat {
    fn new(p: [DVec3; 3], vertices: [u32; 3]) -> Option<Flat> {
        let normal = (p[1] - p[0]).cross(p[2] - p[0]).try_normalize()?;
        let u = (p[1] - p[0]).normalize();
        let v = normal.cross(u);
        let corners = p.map(|q| DVec2::new((q - p[0]).dot(u), (q - p[0]).dot(v)));
        Some(Flat {
            origin: p[0],
            normal,
            u,
            v,
            area: (corners[1] - corners[0]).perp_dot(corners[2] - corners[0]),
            corners,
            vertices,
        })
    }
}

impl Locator {
    /// Indexes `mesh`'s triangles; a point may lie `tolerance` metres off
    /// its triangle.
    #[must_use]
    pub fn new(mesh: &Mesh, tolerance: f64) -> Locator {
        let position = |t: &[u32; 3]| t.map(|v| mesh.vertices[v as usize].position);
        let triangles: Vec<Flat> = mesh
            .triangles()
            .into_iter()
            .filter_map(|t| Flat::new(position(&t.corners), t.corners))
            .collect();
        let (lo, hi) = triangles
            .iter()
            .flat_map(|t| position(&t.vertices))
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p), hi.max(p))
            });
        let n = triangles.len().max(1) as f64;
        let extent = (hi - lo).max(DVec3::splat(tolerance.max(1e-9)));
        // About two cells per triangle, none thinner than the tolerance.
        let cell = ((extent.x * extent.y * extent.z) / (2.0 * n))
            .cbrt()
            .max(extent.max_element() / 1024.0)
            .max(4.0 * tolerance);
        let dims = (extent / cell)
            .ceil()
            .as_uvec3()
            .max(glam::UVec3::ONE)
            .to_array()
            .map(|d| d as usize);
        let index = |c: [usize; 3]| (c[2] * dims[1] + c[1]) * dims[0] + c[0];
        let cells_of = |t: &[DVec3; 3]| {
            let a = t[0].min(t[1]).min(t[2]) - tolerance;
            let b = t[0].max(t[1]).max(t[2]) + tolerance;
            let c0 = ((a - lo) / cell).floor().max(DVec3::ZERO);
            let c1 = ((b - lo) / cell).floor();
            let c0 = [0, 1, 2].map(|k| (c0[k] as usize).min(dims[k] - 1));
            let c1 = [0, 1, 2].map(|k| (c1[k].max(0.0) as usize).min(dims[k] - 1));
            (c0, c1)
        };
        let mut count = vec![0u32; dims[0] * dims[1] * dims[2] + 1];
        let visit = |t: &[DVec3; 3], f: &mut dyn FnMut(usize)| {
            let (c0, c1) = cells_of(t);
            for z in c0[2]..=c1[2] {
                for y in c0[1]..=c1[1] {
                    for x in c0[0]..=c1[0] {
                        f(index([x, y, z]));
                    }
                }
            }
        };
        for t in &triangles {
            visit(&position(&t.vertices), &mut |k| count[k + 1] += 1);
        }
        for k in 1..count.len() {
            count[k] += count[k - 1];
        }
        let start = count.clone();
        let mut items = vec![0u32; *count.last().unwrap_or(&0) as usize];
        for (i, t) in triangles.iter().enumerate() {
            visit(&position(&t.vertices), &mut |k| {
                items[count[k] as usize] = i as u32;
                count[k] += 1;
            });
        }
        Locator {
            triangles,
            lo,
            cell,
            dims,
            start,
            items,
            tolerance,
        }
    }

    /// The element triangle under `p` among those facing along the unit
    /// normal `normal` (dot product above [`NORMAL_AGREEMENT`], as sensor
    /// points are placed): its corner vertices and the barycentric weights
    /// of the nearest point, if one lies within the tolerance.
    #[must_use]
    pub fn locate(&self, p: DVec3, normal: DVec3) -> Option<([u32; 3], [f64; 3])> {
        // Clamped: a point on the far side of the bounds (a wall at the
        // scene's largest x) falls in the last cell, where its triangles
        // are; a point farther out finds none within the tolerance.
        let c = ((p - self.lo) / self.cell).floor();
        if !c.is_finite() {
            return None;
        }
        let c: [usize; 3] = [0, 1, 2].map(|k| (c[k].max(0.0) as usize).min(self.dims[k] - 1));
        let k = (c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0];
        let mut best: Option<([u32; 3], [f64; 3], f64)> = None;
        for &i in &self.items[self.start[k] as usize..self.start[k + 1] as usize] {
            let t = &self.triangles[i as usize];
            if t.normal.dot(normal) <= NORMAL_AGREEMENT {
                continue;
            }
            let q = p - t.origin;
            let off_plane = q.dot(t.normal);
            if off_plane.abs() > self.tolerance {
                continue;
            }
            // Nearest point within the plane, in the triangle's own frame.
            let [a, b, c] = t.corners;
            let (bary, d) =
                nearest_on_triangle(DVec2::new(q.dot(t.u), q.dot(t.v)), a, b, c, t.area);
            let distance = d.hypot(off_plane);
            if distance <= self.tolerance && best.is_none_or(|(_, _, e)| distance < e) {
                best = Some((t.vertices, bary, distance));
            }
        }
        best.map(|(v, b, _)| (v, b))
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

    #[test]
    fn points_on_the_far_bounds_are_found() {
        use crate::mesh::{Mesh, MeshSettings};
        use crate::scene::Surface;
        // A unit square facing +z at the far end of the scene's bounds.
        let square = Surface::new(
            vec![
                DVec3::new(0.0, 0.0, 1.0),
                DVec3::new(1.0, 0.0, 1.0),
                DVec3::new(1.0, 1.0, 1.0),
                DVec3::new(0.0, 1.0, 1.0),
            ],
            DVec3::splat(0.5),
            DVec3::ZERO,
            0,
        )
        .unwrap();
        let floor = Surface::new(
            vec![
                DVec3::ZERO,
                DVec3::new(0.0, 1.0, 0.0),
                DVec3::new(1.0, 1.0, 0.0),
                DVec3::new(1.0, 0.0, 0.0),
            ],
            DVec3::splat(0.5),
            DVec3::ZERO,
            1,
        )
        .unwrap();
        let settings = MeshSettings {
            patch_size: 0.5,
            element_size: 0.25,
            ..MeshSettings::default()
        };
        let scene = crate::scene::Scene {
            name: "test".into(),
            surfaces: vec![square, floor],
            lights: Vec::new(),
            panes: Vec::new(),
            portals: Vec::new(),
            camera: None,
            mesh_hint: None,
            warnings: Vec::new(),
        };
        let mesh = Mesh::build(&scene, &settings).unwrap();
        let locator = Locator::new(&mesh, 1e-6);
        // On the bounds, and a hair outside them (round-off of a
        // transformed position), within the tolerance.
        for p in [
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(-1e-9, 0.5, 1.0),
            DVec3::new(0.5, 1.0 + 1e-9, 1.0 + 1e-9),
            DVec3::new(0.3, 0.7, 1.0),
        ] {
            assert!(locator.locate(p, DVec3::Z).is_some(), "{p}");
            assert!(
                locator.locate(p, -DVec3::Z).is_none(),
                "{p}: nothing faces -z there"
            );
        }
        assert!(
            locator
                .locate(DVec3::new(1.0, 1.0, 0.0), -DVec3::Z)
                .is_some()
        );
    }

    #[test]
    fn nearest_point_outside_is_on_an_edge() {
        let (a, b, c) = (DVec2::ZERO, DVec2::new(4.0, 0.0), DVec2::new(0.0, 4.0));
        let area = (b - a).perp_dot(c - a);
        let (bary, d) = nearest_on_triangle(DVec2::new(2.0, -1.0), a, b, c, area);
        assert!((d - 1.0).abs() < 1e-12);
        assert!((bary[0] - 0.5).abs() < 1e-12 && (bary[1] - 0.5).abs() < 1e-12);
    }
}
