//! Which element triangle lies under a surface point: the one point
//! locator (beyond the paper) that sensors, lightmap texels and the final
//! pass share, over the element mesh's conforming triangles
//! ([`Mesh::triangles`]), indexed by a uniform grid. A point is matched
//! only to triangles lying in its plane and facing its way, within a
//! tolerance, never by distance alone, so no point near a wall or a floor
//! takes light from the other side of it.

use glam::{DVec2, DVec3};

use super::Mesh;

/// A point belongs to a surface only if their unit normals' dot product is
/// above this (about 26 degrees apart at most), as in the reference
/// harness.
pub const NORMAL_AGREEMENT: f64 = 0.9;

/// How far a point may be from its surface, as a fraction of the scene's
/// bounding-box diagonal (the reference harness's tolerance).
pub const RELATIVE_TOLERANCE: f64 = 1e-4;

/// The point of triangle `abc` (signed doubled area `area`) nearest to `p`:
/// its barycentric coordinates and distance. A degenerate triangle gives
/// its nearest corner.
pub(crate) fn nearest_on_triangle(
    p: DVec2,
    a: DVec2,
    b: DVec2,
    c: DVec2,
    area: f64,
) -> ([f64; 3], f64) {
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

#[cfg(test)]
mod tests {
    use super::*;

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
