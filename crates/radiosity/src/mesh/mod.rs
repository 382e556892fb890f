//! Meshing: surfaces -> patches (the shooting units) -> elements (the
//! receiving mesh) -> shared vertices (design.md section 1; Wallace et al.
//! 1989, section 3: sources are patches, receivers are element vertices).
//!
//! Each surface gets one regular grid: a quad a bilinear `Nu x Nv` grid, a
//! triangle a barycentric grid of `N^2` triangles, a convex n-gon a fan of
//! such triangles with one common `N`. Patches are blocks of that grid, so
//! elements of one surface share their vertices and no T-vertices arise.
//! Vertices are shared within a surface id ([`Surface::group`]: the faces
//! of one merged surface), never between ids (their normals differ). Points
//! on a polygon's edge are computed from the edge's ends in a canonical
//! order, so two faces that share an edge and cut it into the same number
//! of pieces share its vertices; faces cutting it differently meet at
//! T-vertices, which [`Mesh::triangles`] closes for everything shown and written.
//!
//! Beyond the paper, [`Mesh::refine`] splits elements where a first solve finds
//! the light varying (Cohen et al. 1986), and [`Mesh::triangles`] cuts the mesh
//! into triangles with no T-vertex (Baum et al. 1991).
//!
//! [`Surface::group`]: crate::scene::Surface::group

mod conform;
pub mod locator;
mod refine;
mod subsources;

use std::collections::HashMap;
use std::ops::Range;

use glam::DVec3;

pub use self::conform::Triangle;
pub use self::refine::{
    DEFAULT_REFINE_TOLERANCE, MAX_REFINE_LEVELS, RefineSettings, element_centre, refined_count,
    split_depths,
};
pub use self::subsources::{Subsource, subsources};
use crate::geometry;
use crate::scene::Scene;

/// How finely to cut surfaces. Serialised (in the `--stats` file's
/// settings) as its two sizes.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct MeshSettings {
    /// Longest edge of a patch, metres.
    pub patch_size: f64,
    /// Longest edge of an element, metres.
    pub element_size: f64,
    /// Refuse meshes with more elements than this.
    #[serde(skip)]
    pub max_elements: usize,
    /// Cut triangles by longest-edge bisection (each surface one patch)
    /// instead of the regular grid; see the mesh's bisection grid.
    #[serde(skip)]
    pub bisect_triangles: bool,
    /// Receiver refinement: elements split where a first, coarse solve
    /// finds the light varying ([`Mesh::refine`], [`split_depths`]).
    #[serde(flatten)]
    pub refine: RefineSettings,
    /// Give coplanar surface ids each other's edge vertices
    /// ([`Mesh::share_coplanar_edge_vertices`]), so the triangles shown and
    /// written have no T-vertex anywhere.
    pub conform: bool,
}

impl Default for MeshSettings {
    fn default() -> Self {
        MeshSettings {
            patch_size: DEFAULT_PATCH_SIZE,
            element_size: DEFAULT_ELEMENT_SIZE,
            max_elements: 4_000_000,
            bisect_triangles: false,
            refine: RefineSettings::default(),
            conform: false,
        }
    }
}

impl MeshSettings {
    /// These settings with the patch and element sizes `scene` suggests
    /// ([`Scene::default_mesh_sizes`]: its `#@mesh` hint, else sizes from
    /// its extent).
    #[must_use]
    pub fn sized_for(self, scene: &Scene) -> MeshSettings {
        let hint = scene.default_mesh_sizes();
        MeshSettings {
            patch_size: hint.patch_size,
            element_size: hint.element_size,
            ..self
        }
    }
}

/// Default `--patch-size`: the built-in room then has about the paper's 181
/// patches.
pub const DEFAULT_PATCH_SIZE: f64 = 2.5;
/// Default `--element-size`: the built-in room then has about the paper's
/// 5,562 elements and 7,167 vertices.
pub const DEFAULT_ELEMENT_SIZE: f64 = 0.15;

/// A shooting unit: a surface or a block of its grid.
#[derive(Clone, Debug)]
pub struct Patch {
    /// Index of its surface.
    pub surface: u32,
    /// Corners (3 or 4), counter-clockwise seen from the front.
    pub polygon: Vec<DVec3>,
    /// Area, m^2.
    pub area: f64,
    /// The elements cut from it.
    pub elements: Range<usize>,
}

/// A receiving element: a quad or triangle of its surface's grid.
#[derive(Clone, Copy, Debug)]
pub struct Element {
    /// Vertex indices, counter-clockwise; the 4th is unused for triangles.
    pub corners: [u32; 4],
    /// 3 or 4.
    pub corner_count: u8,
    /// Area, m^2.
    pub area: f64,
    /// The patch it belongs to.
    pub patch: u32,
    /// The surface it was cut from.
    pub surface: u32,
}

impl Element {
    /// The used vertex indices.
    #[must_use]
    pub fn vertices(&self) -> &[u32] {
        &self.corners[..self.corner_count as usize]
    }
}

/// A node of the element mesh, where radiosity is gathered.
#[derive(Clone, Copy, Debug)]
pub struct Vertex {
    /// Position, metres.
    pub position: DVec3,
    /// Unit normal of its surface.
    pub normal: DVec3,
    /// Index of the surface that created it (vertices are shared within a
    /// surface id, so other surfaces of its id may use it too).
    pub surface: u32,
    /// Its surface id ([`Surface::group`](crate::scene::Surface::group)).
    pub group: u32,
}

/// The meshed scene.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// Shooting units.
    pub patches: Vec<Patch>,
    /// Receiving elements, grouped by patch.
    pub elements: Vec<Element>,
    /// Shared vertices.
    pub vertices: Vec<Vertex>,
}

/// Why a scene cannot be meshed.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// The settings would make too many elements.
    #[error(
        "meshing would create {elements} elements, more than the limit of {limit}; \
         raise --element-size (now {element_size} m)"
    )]
    TooManyElements {
        /// Elements the settings would create.
        elements: u128,
        /// Patches the settings would create (when they alone exceed the
        /// limit, the patch size is at fault).
        patches: u128,
        /// The limit.
        limit: usize,
        /// The element size asked for.
        element_size: f64,
    },
    /// A size is not a positive finite number.
    #[error("{0} must be a positive number of metres")]
    BadSize(&'static str),
}

/// Number of pieces a length is cut into so none exceeds `size`.
fn pieces(length: f64, size: f64) -> u64 {
    ((length / size) - 1e-9).ceil().max(1.0) as u64
}

/// The product of counts, saturating: an absurd size (1e-300 m) gives
/// counts beyond `u64`, and a wrapped product could pass the element limit.
fn saturating_product(factors: &[u64]) -> u128 {
    factors
        .iter()
        .fold(1u128, |acc, &f| acc.saturating_mul(u128::from(f)))
}

/// The grid chosen for one surface.
#[derive(Clone, Copy, Debug)]
enum Grid {
    /// Quad: patches `pu x pv`, elements per patch `mu x mv`.
    Quad { pu: u64, pv: u64, mu: u64, mv: u64 },
    /// Triangle fan of `fans` triangles: `p^2` patches of `m^2` elements each.
    Fan { fans: u64, p: u64, m: u64 },
    /// Triangle fan whose triangles are halved across their longest edge
    /// until no edge is longer than the element size (Rivara 1984), one
    /// patch for the surface: `elements` of them. A regular grid cuts a
    /// triangle into `n^2` pieces by its longest edge, so a sliver 10 m by
    /// 5 cm (common in exported models) becomes a hundred needles;
    /// bisection makes it sixteen pieces no thinner than it.
    Bisect { elements: u64 },
}

impl Grid {
    fn choose(polygon: &[DVec3], settings: &MeshSettings) -> Grid {
        if settings.bisect_triangles && polygon.len() != 4 {
            let budget = settings.max_elements as u64 + 1;
            let mut elements = 0;
            for pair in polygon[1..].windows(2) {
                elements += bisection_count(
                    [polygon[0], pair[0], pair[1]],
                    settings.element_size,
                    budget - elements.min(budget),
                );
            }
            return Grid::Bisect { elements };
        }
        if polygon.len() == 4 {
            let [v0, v1, v2, v3] = [polygon[0], polygon[1], polygon[2], polygon[3]];
            let lu = v0.distance(v1).max(v3.distance(v2));
            let lv = v0.distance(v3).max(v1.distance(v2));
            let pu = pieces(lu, settings.patch_size);
            let pv = pieces(lv, settings.patch_size);
            Grid::Quad {
                pu,
                pv,
                mu: pieces(lu / pu as f64, settings.element_size),
                mv: pieces(lv / pv as f64, settings.element_size),
            }
        } else {
            let v0 = polygon[0];
            let longest = (1..polygon.len() - 1)
                .map(|i| {
                    let (a, b) = (polygon[i], polygon[i + 1]);
                    v0.distance(a).max(a.distance(b)).max(b.distance(v0))
                })
                .fold(0.0, f64::max);
            let p = pieces(longest, settings.patch_size);
            Grid::Fan {
                fans: polygon.len() as u64 - 2,
                p,
                m: pieces(longest / p as f64, settings.element_size),
            }
        }
    }

    fn patch_count(self) -> u128 {
        match self {
            Grid::Quad { pu, pv, .. } => saturating_product(&[pu, pv]),
            Grid::Fan { fans, p, .. } => saturating_product(&[fans, p, p]),
            Grid::Bisect { .. } => 1,
        }
    }

    fn element_count(self) -> u128 {
        match self {
            Grid::Quad { pu, pv, mu, mv } => saturating_product(&[pu, mu, pv, mv]),
            Grid::Fan { fans, p, m } => saturating_product(&[fans, p, m, p, m]),
            Grid::Bisect { elements } => elements as u128,
        }
    }
}

/// The corners of `tri` reordered so its longest edge runs from the first
/// to the second (keeping the winding), with that edge's length.
fn longest_edge_first(tri: [DVec3; 3]) -> ([DVec3; 3], f64) {
    let lengths = [
        tri[0].distance(tri[1]),
        tri[1].distance(tri[2]),
        tri[2].distance(tri[0]),
    ];
    let k = if lengths[0] >= lengths[1] && lengths[0] >= lengths[2] {
        0
    } else if lengths[1] >= lengths[2] {
        1
    } else {
        2
    };
    ([tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]], lengths[k])
}

/// Pieces longest-edge bisection cuts `tri` into, counting at most `budget`.
fn bisection_count(tri: [DVec3; 3], size: f64, budget: u64) -> u64 {
    let (t, longest) = longest_edge_first(tri);
    if budget <= 1 || longest <= size {
        return 1;
    }
    let m = edge_point(t[0], t[1], 1, 2);
    let first = bisection_count([t[0], m, t[2]], size, budget - 1);
    first + bisection_count([m, t[1], t[2]], size, budget.saturating_sub(first))
}

impl Mesh {
    /// Cuts every surface of the scene into patches, elements and vertices.
    pub fn build(scene: &Scene, settings: &MeshSettings) -> Result<Mesh, MeshError> {
        if !(settings.patch_size.is_finite() && settings.patch_size > 0.0) {
            return Err(MeshError::BadSize("--patch-size"));
        }
        if !(settings.element_size.is_finite() && settings.element_size > 0.0) {
            return Err(MeshError::BadSize("--element-size"));
        }
        let grids: Vec<Grid> = scene
            .surfaces
            .iter()
            .map(|s| Grid::choose(&s.polygon, settings))
            .collect();
        let total: u128 = grids
            .iter()
            .fold(0u128, |acc, g| acc.saturating_add(g.element_count()));
        if total > settings.max_elements as u128 {
            return Err(MeshError::TooManyElements {
                elements: total,
                patches: grids
                    .iter()
                    .fold(0u128, |acc, g| acc.saturating_add(g.patch_count())),
                limit: settings.max_elements,
                element_size: settings.element_size,
            });
        }
        let mut mesh = Mesh::default();
        let mut lookup = HashMap::new();
        for (index, (surface, grid)) in scene.surfaces.iter().zip(grids).enumerate() {
            let mut builder = SurfaceBuilder {
                mesh: &mut mesh,
                surface: index as u32,
                group: surface.group,
                normal: surface.normal,
                lookup: &mut lookup,
            };
            match grid {
                Grid::Quad { pu, pv, mu, mv } => builder.quad(&surface.polygon, pu, pv, mu, mv),
                Grid::Fan { p, m, .. } => {
                    let v0 = surface.polygon[0];
                    for pair in surface.polygon[1..].windows(2) {
                        builder.triangle([v0, pair[0], pair[1]], p, m);
                    }
                }
                Grid::Bisect { elements } => {
                    let mut cells = Vec::with_capacity(elements as usize);
                    let v0 = surface.polygon[0];
                    for pair in surface.polygon[1..].windows(2) {
                        bisect([v0, pair[0], pair[1]], settings.element_size, &mut cells);
                    }
                    builder.push_patch(surface.polygon.clone(), &cells);
                }
            }
        }
        Ok(mesh)
    }

    /// Total area of all patches.
    #[must_use]
    pub fn total_area(&self) -> f64 {
        self.patches.iter().map(|p| p.area).sum()
    }
}

impl Mesh {
    /// The index of the vertex of `vertex.group` at `vertex.position`,
    /// pushing `vertex` first when there is none (`lookup`:
    /// [`Mesh::vertex_lookup`] kept up to date).
    fn shared_vertex(&mut self, lookup: &mut HashMap<(u32, [u64; 3]), u32>, vertex: Vertex) -> u32 {
        let next = self.vertices.len() as u32;
        let v = *lookup
            .entry((vertex.group, point_key(vertex.position)))
            .or_insert(next);
        if v == next {
            self.vertices.push(vertex);
        }
        v
    }

    /// Each vertex by its surface id and exact position ([`point_key`]):
    /// the map that shares vertices.
    fn vertex_lookup(&self) -> HashMap<(u32, [u64; 3]), u32> {
        self.vertices
            .iter()
            .enumerate()
            .map(|(i, v)| ((v.group, point_key(v.position)), i as u32))
            .collect()
    }
}

/// The exact bits of a point, the key that shares vertices.
fn point_key(p: DVec3) -> [u64; 3] {
    // `+ 0.0` folds -0.0 into 0.0 so the sign of a zero cannot split a vertex.
    [
        (p.x + 0.0).to_bits(),
        (p.y + 0.0).to_bits(),
        (p.z + 0.0).to_bits(),
    ]
}

/// The point `k / n` of the way from `a` to `b`, computed from whichever end
/// has the smaller [`point_key`], so that every polygon with this edge gets
/// the same bits; the ends themselves exactly.
fn edge_point(a: DVec3, b: DVec3, k: u64, n: u64) -> DVec3 {
    if k == 0 {
        a
    } else if k == n {
        b
    } else if point_key(a) <= point_key(b) {
        a + (b - a) * (k as f64 / n as f64)
    } else {
        b + (a - b) * ((n - k) as f64 / n as f64)
    }
}

/// Adds one surface's patches, elements and vertices, sharing vertices
/// within its surface id by their exact coordinates (shared grid points are
/// computed by identical arithmetic, see [`SurfaceBuilder::triangle`] and
/// [`edge_point`]).
struct SurfaceBuilder<'a> {
    mesh: &'a mut Mesh,
    surface: u32,
    group: u32,
    normal: DVec3,
    lookup: &'a mut HashMap<(u32, [u64; 3]), u32>,
}

impl SurfaceBuilder<'_> {
    fn vertex(&mut self, p: DVec3) -> u32 {
        let vertex = Vertex {
            position: p,
            normal: self.normal,
            surface: self.surface,
            group: self.group,
        };
        self.mesh.shared_vertex(self.lookup, vertex)
    }

    fn push_patch(&mut self, polygon: Vec<DVec3>, elements: &[([DVec3; 4], u8)]) {
        let patch = self.mesh.patches.len() as u32;
        let start = self.mesh.elements.len();
        for (corners, count) in elements {
            let count = *count as usize;
            let mut ids = [0u32; 4];
            for (id, p) in ids.iter_mut().zip(&corners[..count]) {
                *id = self.vertex(*p);
            }
            self.mesh.elements.push(Element {
                corners: ids,
                corner_count: count as u8,
                area: geometry::area(&corners[..count]),
                patch,
                surface: self.surface,
            });
        }
        let area = geometry::area(&polygon);
        self.mesh.patches.push(Patch {
            surface: self.surface,
            polygon,
            area,
            elements: start..self.mesh.elements.len(),
        });
    }

    fn quad(&mut self, polygon: &[DVec3], pu: u64, pv: u64, mu: u64, mv: u64) {
        let (nu, nv) = (pu * mu, pv * mv);
        let [v0, v1, v2, v3] = [polygon[0], polygon[1], polygon[2], polygon[3]];
        let point = |i: u64, j: u64| {
            if j == 0 {
                edge_point(v0, v1, i, nu)
            } else if j == nv {
                edge_point(v3, v2, i, nu)
            } else if i == 0 {
                edge_point(v0, v3, j, nv)
            } else if i == nu {
                edge_point(v1, v2, j, nv)
            } else {
                bilinear(polygon, i as f64 / nu as f64, j as f64 / nv as f64)
            }
        };
        let mut cells = Vec::with_capacity((mu * mv) as usize);
        for b in 0..pv {
            for a in 0..pu {
                cells.clear();
                for j in b * mv..(b + 1) * mv {
                    for i in a * mu..(a + 1) * mu {
                        cells.push((
                            [
                                point(i, j),
                                point(i + 1, j),
                                point(i + 1, j + 1),
                                point(i, j + 1),
                            ],
                            4,
                        ));
                    }
                }
                let outline = vec![
                    point(a * mu, b * mv),
                    point((a + 1) * mu, b * mv),
                    point((a + 1) * mu, (b + 1) * mv),
                    point(a * mu, (b + 1) * mv),
                ];
                self.push_patch(outline, &cells);
            }
        }
    }

    /// A triangle `v0 v1 v2` on a barycentric grid of `n = p m` steps; the
    /// point `(i, j)` is `v0 + (i/n)(v1 - v0) + (j/n)(v2 - v0)`, or on an edge
    /// its [`edge_point`], so a fan's shared diagonals and the edges other
    /// faces share get the same bits from both sides.
    fn triangle(&mut self, tri: [DVec3; 3], p: u64, m: u64) {
        let n = p * m;
        let point = |i: u64, j: u64| {
            if j == 0 {
                edge_point(tri[0], tri[1], i, n)
            } else if i == 0 {
                edge_point(tri[0], tri[2], j, n)
            } else if i + j == n {
                edge_point(tri[1], tri[2], j, n)
            } else {
                barycentric(tri, i as f64 / n as f64, j as f64 / n as f64)
            }
        };
        // Coarse patch (I, J, up?) -> its fine triangles.
        let mut groups: Vec<Vec<([DVec3; 4], u8)>> = vec![Vec::new(); (2 * p * p) as usize];
        let group = |ci: u64, cj: u64, up: bool| ((ci * p + cj) * 2 + u64::from(!up)) as usize;
        for j in 0..n {
            for i in 0..n - j {
                let (ci, cj, li, lj) = (i / m, j / m, i % m, j % m);
                let up = [point(i, j), point(i + 1, j), point(i, j + 1), DVec3::ZERO];
                groups[group(ci, cj, li + lj < m)].push((up, 3));
                if i + j + 2 <= n {
                    let down = [
                        point(i + 1, j),
                        point(i + 1, j + 1),
                        point(i, j + 1),
                        DVec3::ZERO,
                    ];
                    groups[group(ci, cj, li + lj + 2 <= m)].push((down, 3));
                }
            }
        }
        for cj in 0..p {
            for ci in 0..p - cj {
                let (i0, j0) = (ci * m, cj * m);
                let up = vec![point(i0, j0), point(i0 + m, j0), point(i0, j0 + m)];
                let cells = std::mem::take(&mut groups[group(ci, cj, true)]);
                self.push_patch(up, &cells);
                if ci + cj + 2 <= p {
                    let down = vec![point(i0 + m, j0), point(i0 + m, j0 + m), point(i0, j0 + m)];
                    let cells = std::mem::take(&mut groups[group(ci, cj, false)]);
                    self.push_patch(down, &cells);
                }
            }
        }
    }
}

/// Cuts `tri` by longest-edge bisection into pieces no longer than `size`,
/// appending them (counter-clockwise) to `out`. Midpoints are
/// [`edge_point`]s, so two faces halving a shared edge share its midpoint.
fn bisect(tri: [DVec3; 3], size: f64, out: &mut Vec<([DVec3; 4], u8)>) {
    let (t, longest) = longest_edge_first(tri);
    if longest <= size {
        out.push(([tri[0], tri[1], tri[2], DVec3::ZERO], 3));
        return;
    }
    let m = edge_point(t[0], t[1], 1, 2);
    bisect([t[0], m, t[2]], size, out);
    bisect([m, t[1], t[2]], size, out);
}

/// The point at `(s, t)` of the bilinear map of a quad `v0 v1 v2 v3` (`s`
/// along `v0 -> v1`, `t` along `v0 -> v3`).
fn bilinear(quad: &[DVec3], s: f64, t: f64) -> DVec3 {
    quad[0] * ((1.0 - s) * (1.0 - t))
        + quad[1] * (s * (1.0 - t))
        + quad[2] * (s * t)
        + quad[3] * ((1.0 - s) * t)
}

/// The point `v0 + s (v1 - v0) + t (v2 - v0)` of a triangle. In a fan the
/// shared diagonal `v0 v_k` is `(0, t)` of one triangle and `(t, 0)` of the
/// next, which this computes to the same bits (adding an exact zero).
fn barycentric(tri: [DVec3; 3], s: f64, t: f64) -> DVec3 {
    tri[0] + (tri[1] - tri[0]) * s + (tri[2] - tri[0]) * t
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Surface;

    fn scene_of(polygons: Vec<Vec<DVec3>>) -> Scene {
        Scene {
            name: "t".into(),
            surfaces: polygons
                .into_iter()
                .enumerate()
                .map(|(i, p)| Surface::new(p, DVec3::splat(0.5), DVec3::ONE, i as u32).unwrap())
                .collect(),
            lights: Vec::new(),
            panes: Vec::new(),
            portals: Vec::new(),
            camera: None,
            mesh_hint: None,
            warnings: Vec::new(),
        }
    }

    fn rect(w: f64, h: f64) -> Vec<DVec3> {
        vec![
            DVec3::ZERO,
            DVec3::new(w, 0.0, 0.0),
            DVec3::new(w, h, 0.0),
            DVec3::new(0.0, h, 0.0),
        ]
    }

    /// Each element's area sums to its patch's, each patch's to its
    /// surface's; every interior edge is shared by exactly two elements
    /// (no T-vertices, no cracks).
    fn check_conforming(scene: &Scene, mesh: &Mesh) {
        for (p, patch) in mesh.patches.iter().enumerate() {
            let sum: f64 = mesh.elements[patch.elements.clone()]
                .iter()
                .map(|e| e.area)
                .sum();
            assert!((sum - patch.area).abs() < 1e-9 * patch.area.max(1.0));
            assert!(
                mesh.elements[patch.elements.clone()]
                    .iter()
                    .all(|e| e.patch as usize == p)
            );
        }
        for (s, surface) in scene.surfaces.iter().enumerate() {
            let sum: f64 = mesh
                .patches
                .iter()
                .filter(|p| p.surface as usize == s)
                .map(|p| p.area)
                .sum();
            assert!((sum - surface.area).abs() < 1e-9 * surface.area.max(1.0));
        }
        let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
        for e in &mesh.elements {
            let v = e.vertices();
            for k in 0..v.len() {
                let (a, b) = (v[k], v[(k + 1) % v.len()]);
                *edges.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        // Boundary edges of a surface appear once, interior ones twice; a
        // T-vertex would leave an interior edge used once, which shows as a
        // boundary length exceeding the surface perimeter.
        let mut boundary = vec![0.0; scene.surfaces.len()];
        for ((a, b), count) in &edges {
            assert!(*count <= 2);
            if *count == 1 {
                let va = mesh.vertices[*a as usize];
                let vb = mesh.vertices[*b as usize];
                boundary[va.surface as usize] += va.position.distance(vb.position);
            }
        }
        for (s, surface) in scene.surfaces.iter().enumerate() {
            let perimeter: f64 = (0..surface.polygon.len())
                .map(|i| {
                    surface.polygon[i].distance(surface.polygon[(i + 1) % surface.polygon.len()])
                })
                .sum();
            assert!(
                (boundary[s] - perimeter).abs() < 1e-9 * perimeter,
                "surface {s}: boundary {} vs perimeter {perimeter}",
                boundary[s]
            );
        }
    }

    #[test]
    fn quad_grid_counts() {
        let scene = scene_of(vec![rect(6.0, 3.0)]);
        let settings = MeshSettings {
            patch_size: 2.5,
            element_size: 0.2,
            max_elements: 1_000_000,
            bisect_triangles: false,
            refine: RefineSettings::default(),
            conform: false,
        };
        let mesh = Mesh::build(&scene, &settings).unwrap();
        // 6 m: 3 patches of 2 m, 10 elements each; 3 m: 2 patches of 1.5 m,
        // 8 elements each.
        assert_eq!(mesh.patches.len(), 6);
        assert_eq!(mesh.elements.len(), 30 * 16);
        assert_eq!(mesh.vertices.len(), 31 * 17);
        check_conforming(&scene, &mesh);
    }

    #[test]
    fn triangle_and_fan_are_conforming() {
        let tri = vec![
            DVec3::ZERO,
            DVec3::new(3.0, 0.0, 0.0),
            DVec3::new(0.5, 2.0, 0.0),
        ];
        let hexagon: Vec<DVec3> = (0..6)
            .map(|k| {
                let a = k as f64 * std::f64::consts::PI / 3.0;
                DVec3::new(a.cos(), 0.0, -a.sin()) * 2.0 + DVec3::Y
            })
            .collect();
        let scene = scene_of(vec![tri, hexagon]);
        let settings = MeshSettings {
            patch_size: 1.0,
            element_size: 0.3,
            max_elements: 1_000_000,
            bisect_triangles: false,
            refine: RefineSettings::default(),
            conform: false,
        };
        let mesh = Mesh::build(&scene, &settings).unwrap();
        check_conforming(&scene, &mesh);
        // Triangle: p = 3, m = 4 -> 9 patches, 144 elements, 13*14/2 vertices.
        let tri_vertices = mesh.vertices.iter().filter(|v| v.surface == 0).count();
        assert_eq!(tri_vertices, 13 * 14 / 2);
    }

    #[test]
    fn too_many_elements_is_an_error_not_an_allocation() {
        let scene = scene_of(vec![rect(1000.0, 1000.0)]);
        let settings = MeshSettings {
            patch_size: 1.0,
            element_size: 1e-4,
            max_elements: 1_000_000,
            bisect_triangles: false,
            refine: RefineSettings::default(),
            conform: false,
        };
        let err = Mesh::build(&scene, &settings).unwrap_err();
        assert!(err.to_string().contains("--element-size"), "{err}");
    }
}
