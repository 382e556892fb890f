//! A conforming triangulation of the element mesh for everything shown and
//! written (pictures, `--ply`, bakes, the live view), as Baum, Mann, Smith &
//! Winget (1991) make radiosity meshes conform for display: a vertex of a
//! surface id that lies inside an edge of one of its elements (a T-vertex,
//! left where a refined element meets a coarser one, or where two faces of
//! a merged surface cut a shared edge differently) becomes a corner of that
//! element's triangles, so Gouraud shading is continuous across the edge
//! and no crack opens.
//!
//! Each element's polygon, with its edges' hanging vertices in order, is
//! cut into triangles by ear clipping that takes the best-shaped ear first
//! and never a flat one (the polygon is convex, so an ear always exists).
//! An element with no hanging vertex is cut as before: a quad into two
//! triangles from its first corner.

use std::collections::HashMap;

use glam::DVec3;

use super::{Mesh, Vertex, point_key};

/// A point lies on a segment when it is within this fraction of the
/// segment's length of the line, and beyond it of either end.
const ON_EDGE: f64 = 1e-9;

/// Vertices of each sheet (a surface id, or a plane) in cells of a
/// uniform grid, to find those lying on an edge.
struct VertexGrid {
    cell: f64,
    cells: HashMap<(u32, [i64; 3]), Vec<u32>>,
    /// Every vertex of each sheet, for edges spanning many cells.
    groups: HashMap<u32, Vec<u32>>,
}

/// Edges spanning more cells than this scan their surface id's vertices.
const MAX_CELLS: i64 = 512;

impl VertexGrid {
    /// The vertices of `mesh`, vertex `i` in sheet `sheet[i]`.
    fn new(mesh: &Mesh, sheet: &[u32]) -> VertexGrid {
        let mut lengths: Vec<f64> = mesh
            .elements
            .iter()
            .map(|e| {
                let v = e.vertices();
                mesh.vertices[v[0] as usize]
                    .position
                    .distance(mesh.vertices[v[1] as usize].position)
            })
            .filter(|l| *l > 0.0 && l.is_finite())
            .collect();
        let cell = if lengths.is_empty() {
            1.0
        } else {
            let mid = lengths.len() / 2;
            *lengths.select_nth_unstable_by(mid, f64::total_cmp).1
        };
        let mut grid = VertexGrid {
            cell,
            cells: HashMap::new(),
            groups: HashMap::new(),
        };
        for (i, v) in mesh.vertices.iter().enumerate() {
            grid.cells
                .entry((sheet[i], grid.key(v.position)))
                .or_default()
                .push(i as u32);
            grid.groups.entry(sheet[i]).or_default().push(i as u32);
        }
        grid
    }

    fn key(&self, p: DVec3) -> [i64; 3] {
        let k = (p / self.cell).floor();
        [k.x as i64, k.y as i64, k.z as i64]
    }

    /// The vertices of sheet `group` strictly inside segment `a b`, as
    /// `(t, vertex)` with `t` the fraction of the way from `a`, in order.
    fn on_segment(&self, mesh: &Mesh, group: u32, a: u32, b: u32, out: &mut Vec<(f64, u32)>) {
        out.clear();
        let (pa, pb) = (
            mesh.vertices[a as usize].position,
            mesh.vertices[b as usize].position,
        );
        let d = pb - pa;
        let length2 = d.length_squared();
        if length2.is_nan() || length2 <= 0.0 {
            return;
        }
        let length = length2.sqrt();
        let mut test = |v: u32| {
            if v == a || v == b {
                return;
            }
            let p = mesh.vertices[v as usize].position;
            let t = (p - pa).dot(d) / length2;
            if t <= ON_EDGE || t >= 1.0 - ON_EDGE {
                return;
            }
            if (p - (pa + d * t)).length() <= ON_EDGE * length {
                out.push((t, v));
            }
        };
        let slack = DVec3::splat(ON_EDGE * length);
        let (lo, hi) = (self.key(pa.min(pb) - slack), self.key(pa.max(pb) + slack));
        let span = (0..3).fold(1i64, |product, i| {
            product.saturating_mul(hi[i].saturating_sub(lo[i]).saturating_add(1))
        });
        if span > MAX_CELLS {
            for &v in self.groups.get(&group).map_or(&[][..], Vec::as_slice) {
                test(v);
            }
        } else {
            for x in lo[0]..=hi[0] {
                for y in lo[1]..=hi[1] {
                    for z in lo[2]..=hi[2] {
                        if let Some(list) = self.cells.get(&(group, [x, y, z])) {
                            for &v in list {
                                test(v);
                            }
                        }
                    }
                }
            }
        }
        out.sort_by(|x, y| x.0.total_cmp(&y.0));
        out.dedup_by_key(|x| x.1);
    }
}

/// A triangle of [`Mesh::triangles`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Triangle {
    /// Vertex indices, counter-clockwise seen from the front.
    pub corners: [u32; 3],
    /// The element it was cut from.
    pub element: u32,
}

impl Mesh {
    /// The mesh as triangles with no T-vertex: see the module's text.
    /// Elements keep their order, each giving its triangles in turn.
    #[must_use]
    pub fn triangles(&self) -> Vec<Triangle> {
        let groups: Vec<u32> = self.vertices.iter().map(|v| v.group).collect();
        let grid = VertexGrid::new(self, &groups);
        let mut out = Vec::with_capacity(self.elements.len() * 2);
        let mut polygon: Vec<u32> = Vec::with_capacity(16);
        let mut on_edge = Vec::new();
        let mut cut = Vec::with_capacity(16);
        for (index, element) in self.elements.iter().enumerate() {
            let corners = element.vertices();
            let group = self.vertices[corners[0] as usize].group;
            polygon.clear();
            cut.clear();
            for k in 0..corners.len() {
                let (a, b) = (corners[k], corners[(k + 1) % corners.len()]);
                polygon.push(a);
                grid.on_segment(self, group, a, b, &mut on_edge);
                polygon.extend(on_edge.iter().map(|x| x.1));
            }
            if polygon.len() == corners.len() {
                for i in 1..corners.len() - 1 {
                    cut.push([corners[0], corners[i], corners[i + 1]]);
                }
            } else {
                let normal = self.vertices[corners[0] as usize].normal;
                clip_ears(self, normal, &mut polygon, &mut cut);
            }
            out.extend(cut.iter().map(|&corners| Triangle {
                corners,
                element: index as u32,
            }));
        }
        out
    }

    /// The number of T-vertices of `triangles`: (vertex, triangle edge)
    /// pairs where the vertex lies strictly inside the edge, in the plane
    /// of the triangle's surface and facing the same way, without being the
    /// edge's end. Zero for [`Mesh::triangles`] of a mesh whose surfaces
    /// were made to share their edges' vertices
    /// ([`Mesh::share_coplanar_edge_vertices`]).
    #[must_use]
    pub fn t_vertices(&self, triangles: &[Triangle]) -> usize {
        let planes = self.vertex_planes();
        let grid = VertexGrid::new(self, &planes);
        let mut on_edge = Vec::new();
        let mut count = 0;
        for t in triangles.iter().map(|t| t.corners) {
            let plane = planes[t[0] as usize];
            for k in 0..3 {
                grid.on_segment(self, plane, t[k], t[(k + 1) % 3], &mut on_edge);
                count += on_edge.len();
            }
        }
        count
    }

    /// Gives each surface id a vertex wherever a coplanar surface id facing
    /// the same way (another material in the same plane, or faces the
    /// merge left apart) has one inside an edge of its elements, so their
    /// triangulations meet vertex to vertex. The new vertices are vertices
    /// like any other: the solve gathers at them. Returns how many were
    /// added.
    pub fn share_coplanar_edge_vertices(&mut self) -> usize {
        let planes = self.vertex_planes();
        let grid = VertexGrid::new(self, &planes);
        let mut lookup = self.vertex_lookup();
        let mut on_edge = Vec::new();
        let mut added = Vec::new();
        for element in &self.elements {
            let corners = element.vertices();
            let own = self.vertices[corners[0] as usize];
            let plane = planes[corners[0] as usize];
            for k in 0..corners.len() {
                let (a, b) = (corners[k], corners[(k + 1) % corners.len()]);
                grid.on_segment(self, plane, a, b, &mut on_edge);
                for &(_, v) in &on_edge {
                    let position = self.vertices[v as usize].position;
                    let key = (own.group, point_key(position));
                    if lookup.contains_key(&key) {
                        continue;
                    }
                    lookup.insert(key, (self.vertices.len() + added.len()) as u32);
                    added.push(Vertex {
                        position,
                        surface: element.surface,
                        ..own
                    });
                }
            }
        }
        let count = added.len();
        self.vertices.extend(added);
        count
    }

    /// A plane id per vertex: vertices of surface ids whose planes agree
    /// (unit normals and offsets equal to 1e-9, relative to the mesh's
    /// extent for the offset) share one.
    fn vertex_planes(&self) -> Vec<u32> {
        let extent = self
            .vertices
            .iter()
            .map(|v| v.position.abs().max_element())
            .fold(1e-300, f64::max);
        let mut planes: HashMap<[i64; 4], u32> = HashMap::new();
        let mut of_group: HashMap<u32, u32> = HashMap::new();
        self.vertices
            .iter()
            .map(|v| {
                *of_group.entry(v.group).or_insert_with(|| {
                    let n = v.normal;
                    let q = |x: f64| (x * 1e9).round() as i64;
                    let key = [q(n.x), q(n.y), q(n.z), q(n.dot(v.position) / extent)];
                    let next = planes.len() as u32;
                    *planes.entry(key).or_insert(next)
                })
            })
            .collect()
    }
}

/// Cuts the convex polygon `polygon` (vertex indices, counter-clockwise
/// about `normal`, possibly with straight angles) into triangles: each step
/// clips the ear whose smallest angle is largest among those that are not
/// flat and leave a polygon that is not flat either.
fn clip_ears(mesh: &Mesh, normal: DVec3, polygon: &mut Vec<u32>, out: &mut Vec<[u32; 3]>) {
    let at = |v: u32| mesh.vertices[v as usize].position;
    while polygon.len() > 3 {
        let n = polygon.len();
        let mut best: Option<(f64, usize)> = None;
        for i in 0..n {
            let (p, c, q) = (
                at(polygon[(i + n - 1) % n]),
                at(polygon[i]),
                at(polygon[(i + 1) % n]),
            );
            let quality = ear_quality(p, c, q, normal);
            if quality > 0.0
                && best.is_none_or(|(b, _)| quality > b)
                && leaves_area(mesh, normal, polygon, i)
            {
                best = Some((quality, i));
            }
        }
        let Some((_, i)) = best else {
            // Every corner is flat: the polygon has no area left.
            return;
        };
        out.push([polygon[(i + n - 1) % n], polygon[i], polygon[(i + 1) % n]]);
        polygon.remove(i);
    }
    let (p, c, q) = (at(polygon[0]), at(polygon[1]), at(polygon[2]));
    if ear_quality(p, c, q, normal) > 0.0 {
        out.push([polygon[0], polygon[1], polygon[2]]);
    }
}

/// Whether `polygon` without its vertex `skip` still has a corner that is
/// not flat: clipping an ear must not leave the rest of the polygon on one
/// line, stranding the vertices there in flat triangles.
fn leaves_area(mesh: &Mesh, normal: DVec3, polygon: &[u32], skip: usize) -> bool {
    let rest: Vec<DVec3> = polygon
        .iter()
        .enumerate()
        .filter(|&(i, _)| i != skip)
        .map(|(_, &v)| mesh.vertices[v as usize].position)
        .collect();
    let n = rest.len();
    n == 3 && ear_quality(rest[0], rest[1], rest[2], normal) > 0.0
        || n > 3
            && (0..n).any(|i| {
                ear_quality(rest[(i + n - 1) % n], rest[i], rest[(i + 1) % n], normal) > 0.0
            })
}

/// The sine of the smallest angle of triangle `p c q` if it turns
/// counter-clockwise about `normal` with a positive area, else 0.
fn ear_quality(p: DVec3, c: DVec3, q: DVec3, normal: DVec3) -> f64 {
    let area2 = (q - c).cross(p - c).dot(normal);
    let (a, b, d) = (p.distance(c), c.distance(q), q.distance(p));
    if area2.is_nan() || area2 <= ON_EDGE * (a * b).max(f64::MIN_POSITIVE) {
        return 0.0;
    }
    // sin of the angle at each corner = 2 area / (product of its sides).
    let product = (a * b).max(b * d).max(d * a);
    area2 / product
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::MeshSettings;
    use crate::scene::{Scene, Surface};

    /// Two unit squares side by side, the first split once: the midpoint
    /// it puts on the shared edge becomes a corner of the second's
    /// triangles, which a greedy ear choice once stranded in a flat
    /// triangle.
    #[test]
    fn a_hanging_midpoint_is_a_triangle_corner() {
        let polygon = vec![
            DVec3::ZERO,
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(2.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        let scene = Scene {
            name: "t".into(),
            surfaces: vec![Surface::new(polygon, DVec3::splat(0.5), DVec3::ONE, 0).unwrap()],
            lights: Vec::new(),
            panes: Vec::new(),
            portals: Vec::new(),
            camera: None,
            mesh_hint: None,
            warnings: Vec::new(),
        };
        let settings = MeshSettings {
            patch_size: 5.0,
            element_size: 1.0,
            ..MeshSettings::default()
        };
        let mesh = Mesh::build(&scene, &settings).unwrap();
        let refined = mesh.refine(&[1, 0], 100, 1.0).unwrap();
        let t = refined.triangles();
        assert_eq!(refined.elements.len(), 5);
        assert_eq!(t.len(), 8 + 3);
        assert_eq!(refined.t_vertices(&t), 0);
    }
}
