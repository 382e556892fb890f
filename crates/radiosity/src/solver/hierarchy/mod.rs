//! The hierarchies of the clustered methods (adaptive shooting and its
//! successors): binary trees over the mesh's elements (the sources) and
//! over its receivers (vertices and sensors), whose nodes are the pieces a
//! transfer may treat as one; a node's unshot power as a source
//! ([`sources`]) and one receiver's transfer from a node or an element
//! ([`transfer`]).
//!
//! Wallace, Elmquist & Haines (1989, section 4) subdivided a source per
//! receiver until its form factor was accurate; hierarchical radiosity
//! (Hanrahan, Salzman & Aupperle 1991) subdivides both ends of a transfer
//! until it is; here both subdivisions are precomputed as trees and each
//! transfer takes the coarsest accurate pair of nodes.
//! Below the level of a surface a tree splits one surface's items (planar
//! nodes, one surface id); above it, it groups whole surfaces, or pieces of
//! large ones, that are near each other (clusters, as in the clustering
//! radiosity of Smits, Arvo & Greenberg 1994 and Sillion 1995), so a chair
//! of a thousand triangles can shoot, or be lit, as one. The *shooters* are
//! the largest source nodes no bigger than the patch size: shots to
//! convergence then depend on the scene's extent, not on how finely it was
//! tessellated.
//!
//! Nodes are stored depth-first: a node's subtree is the contiguous range
//! `index..end`, its first child is `index + 1`, its items are the
//! contiguous range `first..last` of [`Tree::items`]. Splits are at the
//! median along the longest axis of the item (or piece) centres, so a tree
//! is balanced and its depth is `O(log n)`.

pub mod sources;
pub mod transfer;

use glam::{DMat3, DVec3};

use crate::geometry;
use crate::mesh::Mesh;
use crate::scene::Scene;

use crate::solver::Receiver;

/// No such node.
pub const NONE: u32 = u32::MAX;

/// A node: a set of items that may act as one.
#[derive(Clone, Copy, Debug)]
pub struct Node {
    /// First of its items in [`Tree::items`].
    pub first: u32,
    /// One past its last item.
    pub last: u32,
    /// One past the last node of its subtree (its children are `index + 1`
    /// and `second`).
    pub end: u32,
    /// Its second child ([`NONE`] for a leaf, a single item).
    pub second: u32,
    /// Total weight (area) of its items.
    pub area: f64,
    /// Weighted centre of its items.
    pub centre: DVec3,
    /// Radius of a sphere about `centre` holding all its items.
    pub radius: f64,
    /// Lower corner of the box holding all its items.
    pub lo: DVec3,
    /// Upper corner of that box.
    pub hi: DVec3,
    /// The surface id all its items share, or [`NONE`] for a cluster of
    /// several.
    pub group: u32,
}

impl Node {
    /// True for a single item.
    #[must_use]
    pub fn is_leaf(&self) -> bool {
        self.second == NONE
    }
}

/// What a tree is built over: a thing with a place, an extent, a weight and
/// a surface id.
#[derive(Clone, Copy, Debug)]
pub struct Item {
    /// Its centre.
    pub centre: DVec3,
    /// Radius of a sphere about `centre` holding it.
    pub radius: f64,
    /// Lower corner of a box holding it.
    pub lo: DVec3,
    /// Upper corner of that box.
    pub hi: DVec3,
    /// Its weight in centres (area).
    pub area: f64,
    /// Its surface id.
    pub group: u32,
}

/// A tree of nodes over items.
#[derive(Clone, Debug, Default)]
pub struct Tree {
    /// Nodes, depth-first; node 0 is the root.
    pub nodes: Vec<Node>,
    /// Item indices in tree order.
    pub items: Vec<u32>,
}

impl Tree {
    /// Builds the tree over `items`: each surface id's items cut into
    /// pieces at most `piece_size` across (or single items), clusters of
    /// pieces above them.
    #[must_use]
    pub fn build(items: &[Item], piece_size: f64) -> Tree {
        let mut builder = Builder {
            items,
            piece_size,
            order: (0..items.len() as u32).collect(),
            nodes: Vec::with_capacity(2 * items.len()),
        };
        builder.order.sort_by_key(|&i| (items[i as usize].group, i));
        let mut pieces = Vec::new();
        let mut start = 0;
        while start < builder.order.len() {
            let group = items[builder.order[start] as usize].group;
            let mut end = start + 1;
            while end < builder.order.len() && items[builder.order[end] as usize].group == group {
                end += 1;
            }
            builder.cut_into_pieces(start, end, &mut pieces);
            start = end;
        }
        if !pieces.is_empty() {
            // The cluster levels reorder the pieces, so the items are laid
            // out again in the order the tree visits them.
            let mut order = Vec::with_capacity(builder.order.len());
            builder.cluster(&mut pieces, &mut order);
            builder.order = order;
        }
        Tree {
            nodes: builder.nodes,
            items: builder.order,
        }
    }

    /// The items of node `n`.
    #[must_use]
    pub fn items_of(&self, n: u32) -> &[u32] {
        let node = &self.nodes[n as usize];
        &self.items[node.first as usize..node.last as usize]
    }

    /// The largest nodes at most `size` across (by their bounding sphere),
    /// or leaves, that together hold every item, in depth-first order.
    #[must_use]
    pub fn cut(&self, size: f64) -> Vec<u32> {
        let mut out = Vec::new();
        let mut stack = if self.nodes.is_empty() {
            Vec::new()
        } else {
            vec![0u32]
        };
        while let Some(n) = stack.pop() {
            let node = &self.nodes[n as usize];
            if 2.0 * node.radius <= size || node.is_leaf() {
                out.push(n);
            } else {
                stack.push(node.second);
                stack.push(n + 1);
            }
        }
        out
    }
}

/// The element tree with its shooters and the per-element data shooting
/// needs.
#[derive(Clone, Debug, Default)]
pub struct Hierarchy {
    /// The tree over the mesh's elements.
    pub tree: Tree,
    /// The roots of the shooters' subtrees.
    pub shooters: Vec<u32>,
    /// The shooter each element belongs to.
    pub shooter_of: Vec<u32>,
    /// Each element's centroid.
    pub centroids: Vec<DVec3>,
    /// Each element's second moment about its centroid per unit area (the
    /// covariance of its points).
    pub covariances: Vec<DMat3>,
}

impl Hierarchy {
    /// Builds the tree over `mesh`'s elements, with shooters no larger than
    /// `shooter_size` metres across (a single element may be larger).
    #[must_use]
    pub fn build(scene: &Scene, mesh: &Mesh, shooter_size: f64) -> Hierarchy {
        let mut centroids = Vec::with_capacity(mesh.elements.len());
        let mut covariances = Vec::with_capacity(mesh.elements.len());
        let mut items = Vec::with_capacity(mesh.elements.len());
        let mut corners = Vec::with_capacity(4);
        for e in &mesh.elements {
            corners.clear();
            corners.extend(
                e.vertices()
                    .iter()
                    .map(|&v| mesh.vertices[v as usize].position),
            );
            let centre = geometry::centroid(&corners);
            let radius = corners
                .iter()
                .map(|c| c.distance(centre))
                .fold(0.0, f64::max);
            centroids.push(centre);
            covariances.push(second_moment(&corners, centre));
            let (lo, hi) = corners.iter().fold(
                (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
                |(lo, hi), c| (lo.min(*c), hi.max(*c)),
            );
            items.push(Item {
                centre,
                radius,
                lo,
                hi,
                area: e.area,
                group: scene.surfaces[e.surface as usize].group,
            });
        }
        let tree = Tree::build(&items, shooter_size);
        let shooters = tree.cut(shooter_size);
        let mut shooter_of = vec![NONE; mesh.elements.len()];
        for (s, &n) in shooters.iter().enumerate() {
            for &e in tree.items_of(n) {
                shooter_of[e as usize] = s as u32;
            }
        }
        Hierarchy {
            tree,
            shooters,
            shooter_of,
            centroids,
            covariances,
        }
    }
}

/// The tree over receivers (points of no extent, weighted alike), cut into
/// pieces `piece_size` across within each surface id.
#[must_use]
pub fn receiver_tree(receivers: &[Receiver], piece_size: f64) -> Tree {
    let items: Vec<Item> = receivers
        .iter()
        .map(|r| Item {
            centre: r.point,
            radius: 0.0,
            lo: r.point,
            hi: r.point,
            area: 1.0,
            group: r.group,
        })
        .collect();
    Tree::build(&items, piece_size)
}

/// A run of items of one surface id no larger than the piece size (or a
/// single item): what clusters are made of.
#[derive(Clone, Copy, Debug)]
struct Piece {
    first: u32,
    last: u32,
    centre: DVec3,
}

struct Builder<'a> {
    items: &'a [Item],
    piece_size: f64,
    order: Vec<u32>,
    nodes: Vec<Node>,
}

impl Builder<'_> {
    /// Weighted centre and enclosing radius of `order[start..end]`.
    fn sphere(&self, start: usize, end: usize) -> (DVec3, f64) {
        let (mut sum, mut area) = (DVec3::ZERO, 0.0);
        for &i in &self.order[start..end] {
            let item = &self.items[i as usize];
            sum += item.centre * item.area;
            area += item.area;
        }
        let centre = if area > 0.0 {
            sum / area
        } else {
            self.items[self.order[start] as usize].centre
        };
        let radius = self.order[start..end]
            .iter()
            .map(|&i| {
                let item = &self.items[i as usize];
                item.centre.distance(centre) + item.radius
            })
            .fold(0.0, f64::max);
        (centre, radius)
    }

    /// Cuts one surface id's items into pieces no larger than the piece
    /// size.
    fn cut_into_pieces(&mut self, start: usize, end: usize, pieces: &mut Vec<Piece>) {
        let (centre, radius) = self.sphere(start, end);
        if end - start == 1 || 2.0 * radius <= self.piece_size {
            pieces.push(Piece {
                first: start as u32,
                last: end as u32,
                centre,
            });
            return;
        }
        let items = self.items;
        let mid = split_at_median(&mut self.order[start..end], |i| items[i as usize].centre);
        self.cut_into_pieces(start, start + mid, pieces);
        self.cut_into_pieces(start + mid, end, pieces);
    }

    /// Emits the cluster levels over `pieces` (and below them each piece's
    /// planar subtree), appending the items in visiting order to `order`.
    fn cluster(&mut self, pieces: &mut [Piece], order: &mut Vec<u32>) -> u32 {
        if let [piece] = pieces {
            let base = order.len();
            order.extend_from_slice(&self.order[piece.first as usize..piece.last as usize]);
            let end = order.len();
            return self.planar(order, base, end);
        }
        let index = self.push_inner(order.len());
        let mid = split_at_median(pieces, |p| p.centre);
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
            let item = &self.items[order[start] as usize];
            self.nodes.push(Node {
                first: start as u32,
                last: end as u32,
                end: index + 1,
                second: NONE,
                area: item.area,
                centre: item.centre,
                radius: item.radius,
                lo: item.lo,
                hi: item.hi,
                group: item.group,
            });
            return index;
        }
        self.push_inner(start);
        let items = self.items;
        let mid = start + split_at_median(&mut order[start..end], |i| items[i as usize].centre);
        let first = self.planar(order, start, mid);
        let second = self.planar(order, mid, end);
        self.finish_inner(index, first, second, end as u32);
        index
    }

    fn push_inner(&mut self, first: usize) -> u32 {
        let index = self.nodes.len() as u32;
        self.nodes.push(Node {
            first: first as u32,
            last: 0,
            end: 0,
            second: NONE,
            area: 0.0,
            centre: DVec3::ZERO,
            radius: 0.0,
            lo: DVec3::ZERO,
            hi: DVec3::ZERO,
            group: NONE,
        });
        index
    }

    /// Fills in an inner node from its two children: weighted centre, a
    /// bounding sphere holding theirs, the shared surface id if any.
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
        node.lo = a.lo.min(b.lo);
        node.hi = a.hi.max(b.hi);
        node.group = if a.group == b.group { a.group } else { NONE };
    }
}

/// Reorders `values` about their median along the longest axis of their
/// centres' box (ties by position in the slice's order of values' keys) and
/// returns the split point, at least 1.
fn split_at_median<T: Copy>(values: &mut [T], centre: impl Fn(T) -> DVec3) -> usize {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for &v in values.iter() {
        lo = lo.min(centre(v));
        hi = hi.max(centre(v));
    }
    let extent = hi - lo;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let mid = values.len() / 2;
    values.select_nth_unstable_by(mid, |&a, &b| centre(a)[axis].total_cmp(&centre(b)[axis]));
    mid.max(1)
}

/// The second moment about `centre` of the points of a convex polygon, per
/// unit area, `(1/A) int (y - c)(y - c)^T dA` (its trace is the mean
/// squared distance from `centre`): over its fan of triangles, each
/// contributing its own covariance, `(1/12) sum_i (p_i - g)(p_i - g)^T`
/// about its centroid `g`, and by the parallel-axis rule its offset
/// `(g - c)(g - c)^T`, weighted by area.
#[must_use]
pub fn second_moment(polygon: &[DVec3], centre: DVec3) -> DMat3 {
    let outer = |v: DVec3| DMat3::from_cols(v * v.x, v * v.y, v * v.z);
    let (mut moment, mut area) = (DMat3::ZERO, 0.0);
    for i in 1..polygon.len().saturating_sub(1) {
        let (a, b, c) = (polygon[0], polygon[i], polygon[i + 1]);
        let t = 0.5 * (b - a).cross(c - a).length();
        let g = (a + b + c) / 3.0;
        let own = (outer(a - g) + outer(b - g) + outer(c - g)) * (1.0 / 12.0);
        moment += (own + outer(g - centre)) * t;
        area += t;
    }
    if area > 0.0 {
        moment * (1.0 / area)
    } else {
        DMat3::ZERO
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Items on two surfaces: every node's sphere holds its items, its
    /// items are a contiguous run of the tree's order, and the cut covers
    /// every item once with pieces no larger than asked.
    #[test]
    fn nodes_hold_their_items_and_a_cut_covers_them_once() {
        let mut items = Vec::new();
        for i in 0..40 {
            for j in 0..25 {
                let item = |centre: DVec3, area: f64, group: u32| Item {
                    centre,
                    radius: 0.07,
                    lo: centre - DVec3::splat(0.05),
                    hi: centre + DVec3::splat(0.05),
                    area,
                    group,
                };
                items.push(item(
                    DVec3::new(i as f64 * 0.1, 0.0, j as f64 * 0.1),
                    0.01 + 0.001 * ((i * 7 + j) % 5) as f64,
                    0,
                ));
                items.push(item(
                    DVec3::new(i as f64 * 0.1, j as f64 * 0.1, 0.0),
                    0.01,
                    1,
                ));
            }
        }
        let tree = Tree::build(&items, 0.8);
        let mut seen = vec![0; items.len()];
        for &i in &tree.items {
            seen[i as usize] += 1;
        }
        assert!(seen.iter().all(|&s| s == 1));
        for (n, node) in tree.nodes.iter().enumerate() {
            for &i in tree.items_of(n as u32) {
                let item = &items[i as usize];
                assert!(item.centre.distance(node.centre) + item.radius <= node.radius + 1e-12);
                assert!(item.lo.cmpge(node.lo).all() && item.hi.cmple(node.hi).all());
                if node.group != NONE {
                    assert_eq!(item.group, node.group);
                }
            }
            if !node.is_leaf() {
                let (a, b) = (&tree.nodes[n + 1], &tree.nodes[node.second as usize]);
                assert_eq!(
                    (a.first, a.last, b.first, b.last),
                    (node.first, b.first, a.last, node.last)
                );
                assert_eq!(b.end, node.end);
            }
        }
        let cut = tree.cut(0.8);
        let mut covered = vec![0; items.len()];
        for &n in &cut {
            assert!(2.0 * tree.nodes[n as usize].radius <= 0.8 || tree.nodes[n as usize].is_leaf());
            for &i in tree.items_of(n) {
                covered[i as usize] += 1;
            }
        }
        assert!(covered.iter().all(|&c| c == 1));
    }

    #[test]
    fn second_moments_of_a_rectangle_and_a_triangle() {
        // A 2 x 1 rectangle: a^2/12 and b^2/12 along its sides about its
        // centre, nothing across its plane or between its axes.
        let rectangle = [
            DVec3::ZERO,
            DVec3::X * 2.0,
            DVec3::new(2.0, 1.0, 0.0),
            DVec3::Y,
        ];
        let centre = DVec3::new(1.0, 0.5, 0.0);
        let m = second_moment(&rectangle, centre);
        let expected = DMat3::from_diagonal(DVec3::new(4.0 / 12.0, 1.0 / 12.0, 0.0));
        assert!(m.abs_diff_eq(expected, 1e-12), "{m}");
        // About another point, plus the offset's outer product.
        let offset = DVec3::new(0.0, 0.0, 3.0);
        let m = second_moment(&rectangle, centre + offset);
        let shifted = expected + DMat3::from_diagonal(DVec3::new(0.0, 0.0, 9.0));
        assert!(m.abs_diff_eq(shifted, 1e-12), "{m}");
        // A right triangle with legs 3 and 4: its polar moment per area is
        // the sum of its squared sides over 36.
        let tri = [DVec3::ZERO, DVec3::X * 3.0, DVec3::Y * 4.0];
        let centroid = DVec3::new(1.0, 4.0 / 3.0, 0.0);
        let m = second_moment(&tri, centroid);
        assert!((m.x_axis.x + m.y_axis.y + m.z_axis.z - 50.0 / 36.0).abs() < 1e-12);
        // Its product of inertia about the centroid, -a^2 b^2 / 72 over its
        // area a b / 2: -1/3.
        assert!((m.y_axis.x + 1.0 / 3.0).abs() < 1e-12, "{m}");
        assert!((m.x_axis.y + 1.0 / 3.0).abs() < 1e-12, "{m}");
    }
}
