//! The source hierarchy of adaptive shooting: a binary tree over the mesh's
//! elements whose nodes are the pieces a receiver may take as one source.
//!
//! Wallace, Elmquist & Haines (1989, section 4) subdivided a source per
//! receiver until its form factor was accurate; here the subdivision is
//! precomputed as a tree and each receiver takes the coarsest cut of it that
//! is accurate for it ([`super::adaptive`]). Below the level of a surface
//! the tree splits one surface's elements (planar nodes, one surface id);
//! above it, it groups whole surfaces, or pieces of large ones, that are
//! near each other (clusters, as in the clustering radiosity of Smits, Arvo
//! & Greenberg 1994 and Sillion 1995), so a chair of a thousand triangles can
//! shoot as one. The *shooters* are the largest nodes no bigger than the
//! patch size: shots to convergence then depend on the scene's extent, not
//! on how finely it was tessellated.
//!
//! Nodes are stored depth-first: a node's subtree is the contiguous range
//! `index..end`, its first child is `index + 1`, its elements are the
//! contiguous range `first..last` of [`Hierarchy::elements`]. Splits are at
//! the median along the longest axis of the element (or piece) centroids,
//! so the tree is balanced and its depth is `O(log n)`.

use glam::DVec3;

use crate::geometry;
use crate::mesh::Mesh;
use crate::scene::Scene;

/// No such node.
pub const NONE: u32 = u32::MAX;

/// A node: a set of elements that may act as one source.
#[derive(Clone, Copy, Debug)]
pub struct Node {
    /// First of its elements in [`Hierarchy::elements`].
    pub first: u32,
    /// One past its last element.
    pub last: u32,
    /// One past the last node of its subtree (its children are `index + 1`
    /// and `second`).
    pub end: u32,
    /// Its second child ([`NONE`] for a leaf, a single element).
    pub second: u32,
    /// Total area of its elements.
    pub area: f64,
    /// Area-weighted centroid of its elements.
    pub centre: DVec3,
    /// Radius of a sphere about `centre` holding all its elements.
    pub radius: f64,
    /// The surface id all its elements share, or [`NONE`] for a cluster of
    /// several.
    pub group: u32,
}

impl Node {
    /// True for a single element.
    #[must_use]
    pub fn is_leaf(&self) -> bool {
        self.second == NONE
    }
}

/// The tree, its shooters and the per-element data shooting needs.
#[derive(Clone, Debug, Default)]
pub struct Hierarchy {
    /// Nodes, depth-first.
    pub nodes: Vec<Node>,
    /// Element indices in tree order.
    pub elements: Vec<u32>,
    /// The roots of the shooters' subtrees.
    pub shooters: Vec<u32>,
    /// The shooter each element belongs to.
    pub shooter_of: Vec<u32>,
    /// Each element's centroid.
    pub centroids: Vec<DVec3>,
    /// Each element's spread: the mean squared distance of its points from
    /// its centroid (its polar second moment per unit area).
    pub spreads: Vec<f64>,
}

/// A run of elements of one surface id no larger than the shooter size (or a
/// single element): the pieces clusters are made of.
#[derive(Clone, Copy, Debug)]
struct Piece {
    first: u32,
    last: u32,
    centre: DVec3,
}

impl Hierarchy {
    /// Builds the tree over `mesh`'s elements, with shooters no larger than
    /// `shooter_size` metres across (a single element may be larger).
    #[must_use]
    pub fn build(scene: &Scene, mesh: &Mesh, shooter_size: f64) -> Hierarchy {
        let centroids: Vec<DVec3> = mesh
            .elements
            .iter()
            .map(|e| {
                let corners: Vec<DVec3> = e
                    .vertices()
                    .iter()
                    .map(|&v| mesh.vertices[v as usize].position)
                    .collect();
                geometry::centroid(&corners)
            })
            .collect();
        let mut builder = Builder {
            scene,
            mesh,
            centroids: &centroids,
            shooter_size,
            elements: (0..mesh.elements.len() as u32).collect(),
            nodes: Vec::with_capacity(2 * mesh.elements.len()),
        };
        // Elements grouped by surface id, in order of id then index.
        builder.elements.sort_by_key(|&e| {
            let element = &mesh.elements[e as usize];
            (scene.surfaces[element.surface as usize].group, e)
        });
        let mut pieces = Vec::new();
        let mut start = 0;
        while start < builder.elements.len() {
            let group = builder.group_of(builder.elements[start]);
            let mut end = start + 1;
            while end < builder.elements.len() && builder.group_of(builder.elements[end]) == group {
                end += 1;
            }
            builder.cut_into_pieces(start, end, &mut pieces);
            start = end;
        }
        if !pieces.is_empty() {
            // The pieces now own contiguous runs of `elements`; the cluster
            // levels reorder the pieces, so lay the elements out again in
            // the order the tree visits them.
            let mut order = Vec::with_capacity(builder.elements.len());
            builder.cluster(&mut pieces, &mut order);
            builder.elements = order;
        }
        let spreads = mesh
            .elements
            .iter()
            .zip(&centroids)
            .map(|(e, c)| {
                let corners: Vec<DVec3> = e
                    .vertices()
                    .iter()
                    .map(|&v| mesh.vertices[v as usize].position)
                    .collect();
                spread(&corners, *c)
            })
            .collect();
        let mut hierarchy = Hierarchy {
            nodes: builder.nodes,
            elements: builder.elements,
            shooters: Vec::new(),
            shooter_of: vec![NONE; mesh.elements.len()],
            centroids,
            spreads,
        };
        hierarchy.choose_shooters(shooter_size);
        hierarchy
    }

    /// The shooters are the largest nodes at most `size` across (by their
    /// bounding sphere), or leaves.
    fn choose_shooters(&mut self, size: f64) {
        let mut stack = if self.nodes.is_empty() {
            Vec::new()
        } else {
            vec![0u32]
        };
        while let Some(n) = stack.pop() {
            let node = self.nodes[n as usize];
            if 2.0 * node.radius <= size || node.is_leaf() {
                let shooter = self.shooters.len() as u32;
                self.shooters.push(n);
                for &e in &self.elements[node.first as usize..node.last as usize] {
                    self.shooter_of[e as usize] = shooter;
                }
            } else {
                stack.push(node.second);
                stack.push(n + 1);
            }
        }
    }

    /// The elements of node `n`.
    #[must_use]
    pub fn elements_of(&self, n: u32) -> &[u32] {
        let node = &self.nodes[n as usize];
        &self.elements[node.first as usize..node.last as usize]
    }
}

struct Builder<'a> {
    scene: &'a Scene,
    mesh: &'a Mesh,
    centroids: &'a [DVec3],
    shooter_size: f64,
    elements: Vec<u32>,
    nodes: Vec<Node>,
}

impl Builder<'_> {
    fn group_of(&self, element: u32) -> u32 {
        let e = &self.mesh.elements[element as usize];
        self.scene.surfaces[e.surface as usize].group
    }

    fn area_of(&self, element: u32) -> f64 {
        self.mesh.elements[element as usize].area
    }

    /// Area-weighted centroid of `elements[start..end]`.
    fn centre(&self, start: usize, end: usize) -> DVec3 {
        let (mut sum, mut area) = (DVec3::ZERO, 0.0);
        for &e in &self.elements[start..end] {
            let a = self.area_of(e);
            sum += self.centroids[e as usize] * a;
            area += a;
        }
        if area > 0.0 {
            sum / area
        } else {
            self.centroids[self.elements[start] as usize]
        }
    }

    /// Radius about `centre` of a sphere holding the corners of
    /// `elements[start..end]`.
    fn radius(&self, start: usize, end: usize, centre: DVec3) -> f64 {
        let mut r2: f64 = 0.0;
        for &e in &self.elements[start..end] {
            for &v in self.mesh.elements[e as usize].vertices() {
                r2 = r2.max(
                    self.mesh.vertices[v as usize]
                        .position
                        .distance_squared(centre),
                );
            }
        }
        r2.sqrt()
    }

    /// Sorts `elements[start..end]` about their median along the longest
    /// axis of their centroids' box and returns the split point.
    fn split_elements(&mut self, start: usize, end: usize) -> usize {
        let centroids = self.centroids;
        let axis = longest_axis(
            self.elements[start..end]
                .iter()
                .map(|&e| centroids[e as usize]),
        );
        let mid = start + (end - start) / 2;
        self.elements[start..end].select_nth_unstable_by(mid - start, |&a, &b| {
            centroids[a as usize][axis]
                .total_cmp(&centroids[b as usize][axis])
                .then(a.cmp(&b))
        });
        mid
    }

    /// Cuts one surface id's elements into pieces no larger than the
    /// shooter size.
    fn cut_into_pieces(&mut self, start: usize, end: usize, pieces: &mut Vec<Piece>) {
        let centre = self.centre(start, end);
        if end - start == 1 || 2.0 * self.radius(start, end, centre) <= self.shooter_size {
            pieces.push(Piece {
                first: start as u32,
                last: end as u32,
                centre,
            });
            return;
        }
        let mid = self.split_elements(start, end);
        self.cut_into_pieces(start, mid, pieces);
        self.cut_into_pieces(mid, end, pieces);
    }

    /// Emits the cluster levels over `pieces` (and below them each piece's
    /// planar subtree), appending the elements in visiting order to `order`.
    fn cluster(&mut self, pieces: &mut [Piece], order: &mut Vec<u32>) -> u32 {
        if let [piece] = pieces {
            let piece = *piece;
            let run: Vec<u32> = self.elements[piece.first as usize..piece.last as usize].to_vec();
            let base = order.len();
            order.extend_from_slice(&run);
            let end = order.len();
            return self.planar(order, base, end);
        }
        let index = self.nodes.len() as u32;
        self.nodes.push(Node {
            first: order.len() as u32,
            last: 0,
            end: 0,
            second: NONE,
            area: 0.0,
            centre: DVec3::ZERO,
            radius: 0.0,
            group: NONE,
        });
        let axis = longest_axis(pieces.iter().map(|p| p.centre));
        let mid = pieces.len() / 2;
        pieces.select_nth_unstable_by(mid, |a, b| {
            a.centre[axis]
                .total_cmp(&b.centre[axis])
                .then(a.first.cmp(&b.first))
        });
        let (left, right) = pieces.split_at_mut(mid);
        let first = self.cluster(left, order);
        let second = self.cluster(right, order);
        self.finish_inner(index, first, second, order.len() as u32);
        index
    }

    /// Emits the planar subtree over `order[start..end]` (one surface id).
    fn planar(&mut self, order: &mut [u32], start: usize, end: usize) -> u32 {
        let index = self.nodes.len() as u32;
        if end - start == 1 {
            let e = order[start];
            let centre = self.centroids[e as usize];
            let mut r2: f64 = 0.0;
            for &v in self.mesh.elements[e as usize].vertices() {
                r2 = r2.max(
                    self.mesh.vertices[v as usize]
                        .position
                        .distance_squared(centre),
                );
            }
            self.nodes.push(Node {
                first: start as u32,
                last: end as u32,
                end: index + 1,
                second: NONE,
                area: self.area_of(e),
                centre,
                radius: r2.sqrt(),
                group: self.group_of(e),
            });
            return index;
        }
        self.nodes.push(Node {
            first: start as u32,
            last: end as u32,
            end: 0,
            second: NONE,
            area: 0.0,
            centre: DVec3::ZERO,
            radius: 0.0,
            group: NONE,
        });
        let centroids = self.centroids;
        let axis = longest_axis(order[start..end].iter().map(|&e| centroids[e as usize]));
        let mid = start + (end - start) / 2;
        order[start..end].select_nth_unstable_by(mid - start, |&a, &b| {
            centroids[a as usize][axis]
                .total_cmp(&centroids[b as usize][axis])
                .then(a.cmp(&b))
        });
        let first = self.planar(order, start, mid);
        let second = self.planar(order, mid, end);
        self.finish_inner(index, first, second, end as u32);
        index
    }

    /// Fills in an inner node from its two children: area-weighted centre,
    /// a bounding sphere holding theirs, the shared surface id if any.
    fn finish_inner(&mut self, index: u32, first: u32, second: u32, last: u32) {
        let (a, b) = (self.nodes[first as usize], self.nodes[second as usize]);
        let area = a.area + b.area;
        let centre = if area > 0.0 {
            (a.centre * a.area + b.centre * b.area) / area
        } else {
            0.5 * (a.centre + b.centre)
        };
        let radius =
            (centre.distance(a.centre) + a.radius).max(centre.distance(b.centre) + b.radius);
        let end = self.nodes.len() as u32;
        let node = &mut self.nodes[index as usize];
        node.last = last;
        node.end = end;
        node.second = second;
        node.area = area;
        node.centre = centre;
        node.radius = radius;
        node.group = if a.group == b.group { a.group } else { NONE };
    }
}

/// Mean squared distance from `centre` of the points of a convex polygon:
/// over its fan of triangles, each contributing its own polar moment (area
/// times the sum of its squared sides over 36) and, by the parallel-axis
/// rule, its area times its centroid's squared distance from `centre`.
#[must_use]
pub fn spread(polygon: &[DVec3], centre: DVec3) -> f64 {
    let (mut moment, mut area) = (0.0, 0.0);
    for i in 1..polygon.len().saturating_sub(1) {
        let (a, b, c) = (polygon[0], polygon[i], polygon[i + 1]);
        let t = 0.5 * (b - a).cross(c - a).length();
        let sides = a.distance_squared(b) + b.distance_squared(c) + c.distance_squared(a);
        let g = (a + b + c) / 3.0;
        moment += t * (sides / 36.0 + g.distance_squared(centre));
        area += t;
    }
    if area > 0.0 { moment / area } else { 0.0 }
}

/// The axis along which points spread most.
fn longest_axis(points: impl Iterator<Item = DVec3>) -> usize {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for p in points {
        lo = lo.min(p);
        hi = hi.max(p);
    }
    let extent = hi - lo;
    if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    }
}
