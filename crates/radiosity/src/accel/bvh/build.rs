//! The BVH's build: the flattened binary layout, the top-down build with
//! the binned surface area heuristic (Goldsmith & Salmon 1987; MacDonald &
//! Booth 1990; Wald 2007) and the conservative box of each surface it is
//! built over (see the parent module for why the boxes are conservative).

use super::*;

// -------------------------------------------------------------------- layout

/// An axis-aligned box in `f64`, as the build sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Aabb {
    pub(super) min: DVec3,
    pub(super) max: DVec3,
}

impl Aabb {
    pub(super) const EMPTY: Aabb = Aabb {
        min: DVec3::INFINITY,
        max: DVec3::NEG_INFINITY,
    };

    pub(super) const EVERYWHERE: Aabb = Aabb {
        min: DVec3::NEG_INFINITY,
        max: DVec3::INFINITY,
    };

    pub(super) fn of_points(points: impl IntoIterator<Item = DVec3>) -> Aabb {
        points.into_iter().fold(Aabb::EMPTY, |b, p| Aabb {
            min: b.min.min(p),
            max: b.max.max(p),
        })
    }

    pub(super) fn union(self, other: Aabb) -> Aabb {
        Aabb {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    pub(super) fn centre(self) -> DVec3 {
        0.5 * (self.min + self.max)
    }

    /// Half the surface area (the heuristic only compares ratios); 0 for an
    /// empty box.
    pub(super) fn half_area(self) -> f64 {
        let d = self.max - self.min;
        if d.min_element() < 0.0 {
            return 0.0;
        }
        d.x * d.y + d.y * d.z + d.z * d.x
    }
}

/// Marks a node's `kind` word as an interior node (the low bits hold the
/// split axis); a leaf's `kind` is its primitive count.
pub(super) const INTERIOR: u32 = 1 << 31;

/// One node: an `f32` box rounded outward, 32 bytes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Node {
    pub(super) min: [f32; 3],
    /// Interior: index of the right child. Leaf: first primitive.
    pub(super) link: u32,
    pub(super) max: [f32; 3],
    /// Interior: [`INTERIOR`] | split axis. Leaf: primitive count (>= 1).
    pub(super) kind: u32,
}

impl Node {
    pub(super) fn new(bounds: Aabb, link: u32, kind: u32) -> Node {
        let (min, max) = round_outward(bounds);
        Node {
            min,
            link,
            max,
            kind,
        }
    }

    pub(super) fn is_leaf(&self) -> bool {
        self.kind & INTERIOR == 0
    }

    /// The split axis of an interior node.
    pub(super) fn axis(&self) -> usize {
        (self.kind & !INTERIOR) as usize
    }

    /// The primitive range of a leaf.
    pub(super) fn primitives(&self) -> std::ops::Range<usize> {
        self.link as usize..self.link as usize + self.kind as usize
    }

    pub(super) fn contains(&self, other: &Node) -> bool {
        (0..3).all(|i| self.min[i] <= other.min[i] && self.max[i] >= other.max[i])
    }
}

/// The smallest `f32` box containing `b`.
pub(super) fn round_outward(b: Aabb) -> ([f32; 3], [f32; 3]) {
    let down = |v: f64| {
        let r = v as f32;
        if f64::from(r) > v { r.next_down() } else { r }
    };
    let up = |v: f64| {
        let r = v as f32;
        if f64::from(r) < v { r.next_up() } else { r }
    };
    (
        [down(b.min.x), down(b.min.y), down(b.min.z)],
        [up(b.max.x), up(b.max.y), up(b.max.z)],
    )
}

/// The hierarchy over primitive indices.
#[derive(Clone, Debug, Default)]
pub(super) struct Tree {
    /// Depth first; the root is node 0 (none for no primitives).
    pub(super) nodes: Vec<Node>,
    /// Primitive ids, leaf by leaf in depth-first order.
    pub(super) primitives: Vec<u32>,
}

// --------------------------------------------------------------------- build

/// What the build knows about the primitives: their boxes and centroids.
pub(super) struct Builder<'s> {
    pub(super) boxes: &'s [Aabb],
    pub(super) centroids: Vec<DVec3>,
    pub(super) settings: BvhSettings,
}

/// How a node is divided.
pub(super) enum Decision {
    Leaf,
    /// Primitives `first..mid` go left (reordered already), `mid..end` right.
    Split {
        axis: usize,
        mid: usize,
    },
}

impl Tree {
    /// Builds the tree over `boxes` (primitive `i` has box `boxes[i]`).
    pub(super) fn build(boxes: &[Aabb], settings: BvhSettings) -> (Tree, BvhStats) {
        let mut tree = Tree {
            nodes: Vec::with_capacity(2 * boxes.len()),
            primitives: (0..boxes.len() as u32).collect(),
        };
        let mut stats = BvhStats::default();
        if boxes.is_empty() {
            return (tree, stats);
        }
        let builder = Builder {
            boxes,
            // Centroids of the finite part of each box, so an infinite box
            // still bins somewhere.
            centroids: boxes
                .iter()
                .map(|b| {
                    let c = b.centre();
                    if c.is_finite() { c } else { DVec3::ZERO }
                })
                .collect(),
            settings,
        };
        tree.build_node(&builder, 0, boxes.len(), 1, &mut stats);
        stats.nodes = tree.nodes.len();
        (tree, stats)
    }

    /// Builds the subtree over `primitives[first..end]` at `depth` (root =
    /// 1), returning its index.
    pub(super) fn build_node(
        &mut self,
        builder: &Builder,
        first: usize,
        end: usize,
        depth: usize,
        stats: &mut BvhStats,
    ) -> u32 {
        let index = self.nodes.len() as u32;
        stats.depth = stats.depth.max(depth);
        let bounds = self.primitives[first..end]
            .iter()
            .fold(Aabb::EMPTY, |b, &p| b.union(builder.boxes[p as usize]));
        let placeholder = Node::new(bounds, 0, 0);
        self.nodes.push(placeholder);
        match self.decide(builder, bounds, first, end, depth) {
            Decision::Leaf => {
                let count = end - first;
                stats.leaves += 1;
                stats.max_leaf_size = stats.max_leaf_size.max(count);
                self.nodes[index as usize] = Node::new(bounds, first as u32, count as u32);
            }
            Decision::Split { axis, mid } => {
                self.build_node(builder, first, mid, depth + 1, stats);
                let right = self.build_node(builder, mid, end, depth + 1, stats);
                self.nodes[index as usize] = Node::new(bounds, right, INTERIOR | axis as u32);
            }
        }
        index
    }

    pub(super) fn decide(
        &mut self,
        builder: &Builder,
        bounds: Aabb,
        first: usize,
        end: usize,
        depth: usize,
    ) -> Decision {
        let settings = &builder.settings;
        let count = end - first;
        if count <= settings.leaf_size {
            return Decision::Leaf;
        }
        if settings.split == SplitMethod::ObjectMedian || depth >= MEDIAN_FROM_DEPTH {
            return self.median_split(builder, first, end);
        }
        match self.best_sah_split(builder, bounds, first, end) {
            Some((cost, axis, bin)) => {
                let leaf_cost = settings.primitive_cost * count as f64;
                if cost >= leaf_cost && count <= settings.max_leaf_size {
                    return Decision::Leaf;
                }
                let (lo, scale) = self.bin_mapping(builder, first, end, axis);
                let slice = &mut self.primitives[first..end];
                let left = partition(slice, |&p| {
                    bin_of(
                        builder.centroids[p as usize][axis],
                        lo,
                        scale,
                        settings.bins,
                    ) <= bin
                });
                Decision::Split {
                    axis,
                    mid: first + left,
                }
            }
            // Coincident centroids or boxes without a finite area: the
            // heuristic cannot choose.
            None if count <= settings.max_leaf_size => Decision::Leaf,
            None => self.median_split(builder, first, end),
        }
    }

    /// Half the primitives on each side, by centroid along the axis of
    /// widest centroid spread (ties by index, so the split is
    /// deterministic); simply halves the range when all centroids coincide.
    pub(super) fn median_split(&mut self, builder: &Builder, first: usize, end: usize) -> Decision {
        let (lo, hi) = centroid_bounds(builder, &self.primitives[first..end]);
        let spread = hi - lo;
        let axis = if spread.x >= spread.y && spread.x >= spread.z {
            0
        } else if spread.y >= spread.z {
            1
        } else {
            2
        };
        let half = (end - first) / 2;
        if spread[axis] > 0.0 {
            let c = &builder.centroids;
            self.primitives[first..end].select_nth_unstable_by(half, |&a, &b| {
                c[a as usize][axis]
                    .total_cmp(&c[b as usize][axis])
                    .then(a.cmp(&b))
            });
        }
        Decision::Split {
            axis,
            mid: first + half,
        }
    }

    /// Lowest centroid and bins per unit length along `axis`.
    pub(super) fn bin_mapping(
        &self,
        builder: &Builder,
        first: usize,
        end: usize,
        axis: usize,
    ) -> (f64, f64) {
        let (lo, hi) = centroid_bounds(builder, &self.primitives[first..end]);
        (
            lo[axis],
            builder.settings.bins as f64 / (hi[axis] - lo[axis]),
        )
    }

    /// The cheapest bin boundary over all axes: `(cost, axis, last bin on
    /// the left)`, or `None` when no axis has a spread of centroids or no
    /// split has a finite cost. The cost is the surface area heuristic,
    /// `traversal + primitive * (A_left N_left + A_right N_right) / A`.
    pub(super) fn best_sah_split(
        &self,
        builder: &Builder,
        bounds: Aabb,
        first: usize,
        end: usize,
    ) -> Option<(f64, usize, usize)> {
        let settings = &builder.settings;
        let area = bounds.half_area();
        if !(area.is_finite() && area > 0.0) {
            return None;
        }
        let primitives = &self.primitives[first..end];
        let (lo, hi) = centroid_bounds(builder, primitives);
        let bins = settings.bins;
        let mut best: Option<(f64, usize, usize)> = None;
        let mut bin_box = [Aabb::EMPTY; MAX_BINS];
        let mut bin_count = [0usize; MAX_BINS];
        let mut right_area = [0.0f64; MAX_BINS];
        for axis in 0..3 {
            let spread = hi[axis] - lo[axis];
            if !(spread > 0.0 && spread.is_finite()) {
                continue;
            }
            let scale = bins as f64 / spread;
            bin_box[..bins].fill(Aabb::EMPTY);
            bin_count[..bins].fill(0);
            for &p in primitives {
                let b = bin_of(builder.centroids[p as usize][axis], lo[axis], scale, bins);
                bin_box[b] = bin_box[b].union(builder.boxes[p as usize]);
                bin_count[b] += 1;
            }
            // Sweep from the right: right_area[b] covers bins b + 1 ..
            let mut acc = Aabb::EMPTY;
            for b in (0..bins - 1).rev() {
                acc = acc.union(bin_box[b + 1]);
                right_area[b] = acc.half_area();
            }
            let mut left = Aabb::EMPTY;
            let mut left_count = 0;
            for b in 0..bins - 1 {
                left = left.union(bin_box[b]);
                left_count += bin_count[b];
                let right_count = primitives.len() - left_count;
                if left_count == 0 || right_count == 0 {
                    continue;
                }
                let cost = settings.traversal_cost
                    + settings.primitive_cost
                        * (left.half_area() * left_count as f64
                            + right_area[b] * right_count as f64)
                        / area;
                if cost.is_finite() && best.is_none_or(|(c, _, _)| cost < c) {
                    best = Some((cost, axis, b));
                }
            }
        }
        best
    }
}

/// The bin of centroid coordinate `c`; the lowest centroid is in bin 0 and
/// the highest in the last.
pub(super) fn bin_of(c: f64, lo: f64, scale: f64, bins: usize) -> usize {
    (((c - lo) * scale) as usize).min(bins - 1)
}

pub(super) fn centroid_bounds(builder: &Builder, primitives: &[u32]) -> (DVec3, DVec3) {
    let b = Aabb::of_points(primitives.iter().map(|&p| builder.centroids[p as usize]));
    (b.min, b.max)
}

/// Moves the elements satisfying `left` to the front; returns how many.
pub(super) fn partition(slice: &mut [u32], left: impl Fn(&u32) -> bool) -> usize {
    let mut count = 0;
    for i in 0..slice.len() {
        if left(&slice[i]) {
            slice.swap(i, count);
            count += 1;
        }
    }
    count
}

// ---------------------------------------------------- conservative surface box

/// The query margin relative to the largest coordinate of the query and the
/// scene: about 34 units of `f32` round-off (see the module notes).
pub(super) const QUERY_MARGIN: f64 = 2e-6;

/// The margin of the `f64` recheck of a leaf child's box
/// ([`ExactSlabs`](super::traverse::ExactSlabs)), relative to the same
/// reference: its round-off is under `10 ε ≈ 2.2e-15` of it, and
/// `segment_crosses` accepts crossings within tens of `ε` of it off the
/// exact segment and plane; the margin covers both about a hundred times.
pub(super) const EXACT_MARGIN: f64 = 1e-12;

/// Above this coordinate magnitude (of the query or the scene) a query
/// tests every surface instead of using `f32` boxes.
pub(super) const F32_SAFE_COORDINATE: f64 = 1e30;

/// A box containing every point [`segment_crosses`](super::segment_crosses) can accept on the
/// surface, and its corners.
///
/// The accepted points lie on the surface's plane and within the tolerance
/// of every edge line, measured as `segment_crosses` measures it: the
/// distance along `normal x edge` divided by the 3-D edge length. In plane
/// coordinates that is a half-plane per edge, so the region is their
/// intersection, found by clipping a square grown until the region lies
/// well inside it (as the BSP's reach is computed).
pub(super) fn crossing_box(surface: &Surface) -> Aabb {
    let corners = Aabb::of_points(surface.polygon.iter().copied());
    match AcceptanceRegion::of(surface, 4.0) {
        AcceptanceRegion::Bounded {
            origin,
            axes: [u, v],
            region,
            ..
        } => {
            let lifted = region.iter().map(|q| origin + u * q.x + v * q.y);
            Aabb::of_points(lifted).union(corners)
        }
        // An empty or unbounded region: a degenerate polygon. Always tested.
        AcceptanceRegion::Empty | AcceptanceRegion::Unbounded => Aabb::EVERYWHERE,
    }
}
