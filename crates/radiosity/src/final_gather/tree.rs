//! A tree of light sources for choosing, at each point shown, the few
//! sources worth tracing, whatever their number (beyond the paper: the
//! paper's shooters send their light to every vertex, but a final pass
//! that traced every emitter at every pixel would cost as many rays a
//! pixel as the scene has emitting faces).
//!
//! The tree is Conty Estevez & Kulla's light BVH (*Importance Sampling of
//! Many Lights with Adaptive Tree Splitting*, HPG 2018): each node bounds
//! its sources' positions (a box), the directions they send light in (a
//! cone of normals `theta_o` wide plus a spread `theta_e` about each) and
//! their power, which bound what the node can send to a point with a given
//! normal (its *importance*, their equation 3). A point takes a *cut* of
//! the tree, as Yuksel's stochastic lightcuts do (*Stochastic Lightcuts*,
//! HPG 2019): starting from the root, the most important node of the cut
//! is replaced by its children until the cut holds `budget` nodes; a leaf
//! of the cut is traced for sure, and each inner node stands for one of
//! its sources, drawn by descending the tree with probabilities in
//! proportion to the children's importance, its light divided by the
//! probability of drawing it. The estimate is unbiased, its rays bounded
//! by the budget, and exact (every source traced) where the point sees no
//! more sources than the budget. A node whose bound is zero (every source
//! in it faces away from the point, or lies behind the point's surface)
//! is left out: it sends nothing.

use std::f64::consts::{FRAC_PI_2, PI};

use glam::DVec3;

/// What a source (or a node, of its sources) can send: where it lies, the
/// directions it sends light in and how much.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    /// The box holding it.
    pub lo: DVec3,
    /// The box's far corner.
    pub hi: DVec3,
    /// Its radiant intensity scale, in one channel: what it sends along
    /// its axis at unit distance (W/sr; a Lambertian emitter's exitance
    /// times its area over pi).
    pub power: f64,
    /// The axis of its cone of normals (unit length).
    pub axis: DVec3,
    /// Half-angle of the cone of normals about `axis`, radians in
    /// `[0, pi]` (`pi`: every direction).
    pub theta_o: f64,
    /// How far beyond its normals it sends light, radians in `[0, pi/2]`
    /// (`pi/2`: a Lambertian surface; 0: a spot's cone).
    pub theta_e: f64,
}

impl Bounds {
    /// Bounds holding both.
    #[must_use]
    pub fn union(&self, other: &Bounds) -> Bounds {
        let (axis, theta_o) = cone_union((self.axis, self.theta_o), (other.axis, other.theta_o));
        Bounds {
            lo: self.lo.min(other.lo),
            hi: self.hi.max(other.hi),
            power: self.power + other.power,
            axis,
            theta_o,
            theta_e: self.theta_e.max(other.theta_e),
        }
    }

    /// An estimate of what these sources send to `point`, whose surface's
    /// front is along `normal`, zero only where they surely send nothing
    /// (Conty Estevez & Kulla 2018, equation 3): the power over the
    /// squared distance to the box's centre, times the least angles to
    /// the emitting cone and to the receiver's normal that any point of
    /// the box allows.
    #[must_use]
    pub fn importance(&self, point: DVec3, normal: DVec3) -> f64 {
        Bound::of(self).importance(point, normal)
    }
}

/// [`Bounds`] as the cut reads them: the box as a sphere, the cone's
/// angles as cosines and sines, so an importance takes no trigonometric
/// function (as pbrt-v4's light bounds do).
#[derive(Clone, Copy, Debug)]
struct Bound {
    centre: DVec3,
    /// The box's half-extents.
    half: DVec3,
    radius: f64,
    power: f64,
    axis: DVec3,
    cos_o: f64,
    sin_o: f64,
    cos_e: f64,
}

/// `cos(max(0, a - b))` from the sines and cosines of `a` and `b` in
/// `[0, pi]`.
fn cos_less(sin_a: f64, cos_a: f64, sin_b: f64, cos_b: f64) -> f64 {
    if cos_a > cos_b {
        1.0
    } else {
        cos_a * cos_b + sin_a * sin_b
    }
}

/// `sin(max(0, a - b))`, as [`cos_less`].
fn sin_less(sin_a: f64, cos_a: f64, sin_b: f64, cos_b: f64) -> f64 {
    if cos_a > cos_b {
        0.0
    } else {
        sin_a * cos_b - cos_a * sin_b
    }
}

impl Bound {
    fn of(b: &Bounds) -> Bound {
        Bound {
            centre: 0.5 * (b.lo + b.hi),
            half: 0.5 * (b.hi - b.lo),
            radius: 0.5 * (b.hi - b.lo).length(),
            power: b.power,
            axis: b.axis,
            cos_o: b.theta_o.cos(),
            sin_o: b.theta_o.sin().max(0.0),
            // Exactly 0 for a Lambertian spread (pi/2).
            cos_e: if b.theta_e >= FRAC_PI_2 {
                0.0
            } else {
                b.theta_e.cos()
            },
        }
    }

    fn importance(&self, point: DVec3, normal: DVec3) -> f64 {
        if self.power <= 0.0 {
            return 0.0;
        }
        let to_point = point - self.centre;
        // The box wholly behind the receiver's tangent plane, or (sources
        // that all face one way) the point behind every source's plane:
        // nothing arrives, wherever the point is (the sphere's bounds below
        // cannot tell from inside it).
        let reach = |direction: DVec3| direction.abs().dot(self.half);
        if normal.dot(-to_point) + reach(normal) <= 0.0
            || (self.sin_o == 0.0
                && self.cos_o > 0.0
                && self.cos_e <= 0.0
                && self.axis.dot(to_point) + reach(self.axis) <= 0.0)
        {
            return 0.0;
        }
        let d2 = to_point.length_squared();
        let r2 = self.radius * self.radius;
        if d2 <= r2 {
            // Inside the box's sphere: every direction is possible.
            return self.power / d2.max(r2 * 0.25).max(f64::MIN_POSITIVE);
        }
        let d = d2.sqrt();
        let towards = to_point / d;
        // The half-angle `u` the box's sphere subtends from the point.
        let sin_u = self.radius / d;
        let cos_u = (1.0 - sin_u * sin_u).max(0.0).sqrt();
        // The emitting side: the least angle between a normal of the cone
        // and a direction from the box to the point, `theta - o - u`.
        let cos_w = self.axis.dot(towards).clamp(-1.0, 1.0);
        let sin_w = (1.0 - cos_w * cos_w).max(0.0).sqrt();
        let cos_x = cos_less(sin_w, cos_w, self.sin_o, self.cos_o);
        let sin_x = sin_less(sin_w, cos_w, self.sin_o, self.cos_o);
        let cos_emit = cos_less(sin_x, cos_x, sin_u, cos_u);
        if cos_emit <= self.cos_e {
            return 0.0;
        }
        // The receiving side: the least angle between its normal and a
        // direction from the point into the box.
        let cos_i = (-normal.dot(towards)).clamp(-1.0, 1.0);
        let sin_i = (1.0 - cos_i * cos_i).max(0.0).sqrt();
        let cos_receive = cos_less(sin_i, cos_i, sin_u, cos_u);
        if cos_receive <= 0.0 {
            return 0.0;
        }
        self.power * cos_emit * cos_receive / d2
    }
}

/// The smallest cone found holding two cones `(axis, half-angle)`
/// (Conty Estevez & Kulla 2018, algorithm 1).
fn cone_union(a: (DVec3, f64), b: (DVec3, f64)) -> (DVec3, f64) {
    let (a, b) = if b.1 > a.1 { (b, a) } else { (a, b) };
    let theta_d = a.0.dot(b.0).clamp(-1.0, 1.0).acos();
    if (theta_d + b.1).min(PI) <= a.1 {
        return a;
    }
    let theta_o = 0.5 * (a.1 + theta_d + b.1);
    if theta_o >= PI {
        return (a.0, PI);
    }
    // The new axis: `a`'s turned towards `b`'s by what the cone grew.
    let turn = theta_o - a.1;
    let across = b.0 - a.0 * a.0.dot(b.0);
    let Some(across) = across.try_normalize() else {
        // Opposite axes: no plane to turn in.
        return (a.0, PI);
    };
    let axis = (a.0 * turn.cos() + across * turn.sin()).normalize();
    (axis, theta_o)
}

/// A node: its bounds and either one source or two children.
#[derive(Clone, Debug)]
struct Node {
    bounds: Bounds,
    bound: Bound,
    /// A leaf's source, or an inner node's first child (the second is
    /// `child + 1`).
    index: u32,
    leaf: bool,
}

/// One of a point's sources to trace, and what its light is multiplied by
/// (one over the probability of having drawn it; 1 for a leaf of the cut).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pick {
    /// The source's index.
    pub source: u32,
    /// The weight of its light.
    pub weight: f64,
    /// Its importance at the point (what `importance` gave).
    pub importance: f64,
}

/// The tree over a list of sources.
#[derive(Clone, Debug)]
pub struct LightTree {
    nodes: Vec<Node>,
}

impl LightTree {
    /// Builds the tree over sources with these bounds (their indices are
    /// what [`Pick::source`] names): each node's sources split in two at
    /// the median of their boxes' centres along its box's longest side.
    #[must_use]
    pub fn new(sources: &[Bounds]) -> LightTree {
        let mut tree = LightTree { nodes: Vec::new() };
        if sources.is_empty() {
            return tree;
        }
        let mut order: Vec<u32> = (0..sources.len() as u32).collect();
        tree.nodes.push(Node {
            bounds: sources[0],
            bound: Bound::of(&sources[0]),
            index: 0,
            leaf: true,
        });
        tree.build(0, &mut order, sources);
        tree
    }

    /// Fills node `at` with the sources `order` lists.
    fn build(&mut self, at: usize, order: &mut [u32], sources: &[Bounds]) {
        if let [only] = order {
            self.nodes[at] = Node {
                bounds: sources[*only as usize],
                bound: Bound::of(&sources[*only as usize]),
                index: *only,
                leaf: true,
            };
            return;
        }
        let centre = |i: u32| {
            let b = &sources[i as usize];
            0.5 * (b.lo + b.hi)
        };
        let (lo, hi) = order
            .iter()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &i| {
                (lo.min(centre(i)), hi.max(centre(i)))
            });
        let extent = hi - lo;
        let axis = if extent.x >= extent.y && extent.x >= extent.z {
            0
        } else if extent.y >= extent.z {
            1
        } else {
            2
        };
        let middle = order.len() / 2;
        order.select_nth_unstable_by(middle, |&a, &b| {
            centre(a)[axis].total_cmp(&centre(b)[axis]).then(a.cmp(&b))
        });
        let first = self.nodes.len();
        let placeholder = self.nodes[at].clone();
        self.nodes.push(placeholder.clone());
        self.nodes.push(placeholder);
        let (left, right) = order.split_at_mut(middle);
        self.build(first, left, sources);
        self.build(first + 1, right, sources);
        let bounds = self.nodes[first]
            .bounds
            .union(&self.nodes[first + 1].bounds);
        self.nodes[at] = Node {
            bounds,
            bound: Bound::of(&bounds),
            index: first as u32,
            leaf: false,
        };
    }

    /// The number of sources.
    #[must_use]
    pub fn sources(&self) -> usize {
        self.nodes.len().div_ceil(2)
    }

    /// The sources to trace at `point` (its surface's front along
    /// `normal`), at most `budget` (at least 1), into `out`: the cut's
    /// leaves with weight 1 and, for each inner node of the cut, one of
    /// its sources drawn with the `k`-th of `draws` uniform numbers in
    /// `[0, 1)` (`draw(k)`). `importance` gives a source's importance at
    /// the point (an exact figure where one is at hand; zero only where it
    /// sends nothing); inner nodes take their bounds'.
    pub fn cut(
        &self,
        point: DVec3,
        normal: DVec3,
        budget: usize,
        importance: &dyn Fn(u32) -> f64,
        draw: &dyn Fn(usize) -> f64,
        out: &mut Vec<Pick>,
    ) {
        out.clear();
        if self.nodes.is_empty() {
            return;
        }
        let weigh = |node: usize| -> f64 {
            let n = &self.nodes[node];
            if n.leaf {
                importance(n.index)
            } else {
                n.bound.importance(point, normal)
            }
        };
        // The cut's inner nodes, with their importance, largest last.
        let mut inner: Vec<(f64, usize)> = Vec::with_capacity(budget + 1);
        let place =
            |node: usize, value: f64, inner: &mut Vec<(f64, usize)>, out: &mut Vec<Pick>| {
                if value <= 0.0 || !value.is_finite() {
                    return;
                }
                let n = &self.nodes[node];
                if n.leaf {
                    out.push(Pick {
                        source: n.index,
                        weight: 1.0,
                        importance: value,
                    });
                } else {
                    let at = inner.partition_point(|(v, i)| (*v, *i) < (value, node));
                    inner.insert(at, (value, node));
                }
            };
        place(0, weigh(0), &mut inner, out);
        let budget = budget.max(1);
        while let Some(&(_, node)) = inner.last() {
            if out.len() + inner.len() >= budget {
                break;
            }
            inner.pop();
            let first = self.nodes[node].index as usize;
            for child in [first, first + 1] {
                place(child, weigh(child), &mut inner, out);
            }
        }
        for (k, (value, node)) in inner.into_iter().enumerate() {
            if let Some(pick) = self.descend(node, value, draw(k), &weigh) {
                out.push(pick);
            }
        }
    }

    /// One source of `node`'s, drawn with the uniform number `u` by
    /// choosing each child in proportion to its importance, weighted by
    /// one over the probability of that draw.
    fn descend(
        &self,
        mut node: usize,
        mut value: f64,
        mut u: f64,
        weigh: &dyn Fn(usize) -> f64,
    ) -> Option<Pick> {
        let mut probability = 1.0;
        loop {
            let n = &self.nodes[node];
            if n.leaf {
                return (value > 0.0).then_some(Pick {
                    source: n.index,
                    weight: 1.0 / probability,
                    importance: value,
                });
            }
            let first = n.index as usize;
            let (left, right) = (weigh(first), weigh(first + 1));
            let (left, right) = (left.max(0.0), right.max(0.0));
            let total = left + right;
            if total <= 0.0 || !total.is_finite() {
                return None;
            }
            let p = left / total;
            if u < p {
                node = first;
                value = left;
                probability *= p;
                u /= p;
            } else {
                node = first + 1;
                value = right;
                probability *= 1.0 - p;
                u = (u - p) / (1.0 - p);
            }
            // Keep `u` in `[0, 1)` despite rounding.
            u = u.clamp(0.0, 1.0 - f64::EPSILON);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small Lambertian emitter at `at`, facing `normal`.
    fn emitter(at: DVec3, normal: DVec3, power: f64) -> Bounds {
        Bounds {
            lo: at - DVec3::splat(0.05),
            hi: at + DVec3::splat(0.05),
            power,
            axis: normal,
            theta_o: 0.0,
            theta_e: FRAC_PI_2,
        }
    }

    fn xorshift(state: &mut u64) -> f64 {
        *state ^= *state << 13;
        *state ^= *state >> 7;
        *state ^= *state << 17;
        (*state >> 11) as f64 / (1u64 << 53) as f64
    }

    fn grid(count: usize, seed: u64) -> Vec<Bounds> {
        let mut state = seed;
        (0..count)
            .map(|_| {
                let at = DVec3::new(
                    10.0 * xorshift(&mut state),
                    3.0 + xorshift(&mut state),
                    10.0 * xorshift(&mut state),
                );
                let normal =
                    DVec3::new(xorshift(&mut state) - 0.5, -1.0, xorshift(&mut state) - 0.5)
                        .normalize();
                emitter(at, normal, 0.1 + xorshift(&mut state))
            })
            .collect()
    }

    #[test]
    fn a_node_bounds_its_sources() {
        let sources = grid(300, 7);
        let tree = LightTree::new(&sources);
        assert_eq!(tree.sources(), 300);
        let mut seen = vec![0u32; 300];
        for node in &tree.nodes {
            if node.leaf {
                seen[node.index as usize] += 1;
                continue;
            }
            let first = node.index as usize;
            for child in [first, first + 1] {
                let c = &tree.nodes[child].bounds;
                assert!(node.bounds.lo.cmple(c.lo).all() && node.bounds.hi.cmpge(c.hi).all());
                // The child's cone lies within the node's.
                let apart = node.bounds.axis.dot(c.axis).clamp(-1.0, 1.0).acos();
                assert!(apart + c.theta_o <= node.bounds.theta_o + 1e-6);
            }
            let sum = tree.nodes[first].bounds.power + tree.nodes[first + 1].bounds.power;
            assert!((node.bounds.power - sum).abs() <= 1e-12 * sum);
        }
        assert!(seen.iter().all(|&n| n == 1), "every source in one leaf");
    }

    #[test]
    fn importance_is_zero_only_where_nothing_arrives() {
        // A node's importance is zero only if every source in it is, for
        // points around and inside the sources.
        // Sources facing every way, and sources all facing down (a
        // ceiling of panels: their nodes' cones are one direction).
        let facing_down: Vec<Bounds> = grid(64, 13)
            .into_iter()
            .map(|b| Bounds {
                axis: -DVec3::Y,
                ..b
            })
            .collect();
        for sources in [grid(64, 11), facing_down] {
            zero_only_where_nothing_arrives(&sources);
        }
    }

    fn zero_only_where_nothing_arrives(sources: &[Bounds]) {
        let tree = LightTree::new(sources);
        let mut state = 5u64;
        for _ in 0..2000 {
            let point = DVec3::new(
                12.0 * xorshift(&mut state) - 1.0,
                5.0 * xorshift(&mut state),
                12.0 * xorshift(&mut state) - 1.0,
            );
            let normal = DVec3::new(
                xorshift(&mut state) - 0.5,
                xorshift(&mut state) - 0.5,
                xorshift(&mut state) - 0.5,
            )
            .normalize();
            for node in &tree.nodes {
                if node.bounds.importance(point, normal) > 0.0 || node.leaf {
                    continue;
                }
                // Every source below sends nothing: the point lies behind
                // each (beyond its cone) or each lies behind the point.
                let mut stack = vec![node.index as usize, node.index as usize + 1];
                while let Some(i) = stack.pop() {
                    let n = &tree.nodes[i];
                    if !n.leaf {
                        stack.extend([n.index as usize, n.index as usize + 1]);
                        continue;
                    }
                    let b = &sources[n.index as usize];
                    for corner in 0..8 {
                        let c = DVec3::new(
                            if corner & 1 == 0 { b.lo.x } else { b.hi.x },
                            if corner & 2 == 0 { b.lo.y } else { b.hi.y },
                            if corner & 4 == 0 { b.lo.z } else { b.hi.z },
                        );
                        let out = point - c;
                        let sends = b.axis.dot(out) > 0.0 && normal.dot(-out) > 0.0;
                        assert!(!sends, "a zero bound over a source that sends light");
                    }
                }
            }
        }
    }

    #[test]
    fn the_cut_takes_every_source_within_the_budget() {
        let sources = grid(12, 3);
        let tree = LightTree::new(&sources);
        let point = DVec3::new(5.0, 0.0, 5.0);
        let importance = |i: u32| sources[i as usize].importance(point, DVec3::Y);
        let mut picks = Vec::new();
        tree.cut(point, DVec3::Y, 12, &importance, &|_| 0.5, &mut picks);
        let mut named: Vec<u32> = picks.iter().map(|p| p.source).collect();
        named.sort_unstable();
        let expected: Vec<u32> = (0..12).filter(|&i| importance(i) > 0.0).collect();
        assert_eq!(named, expected);
        assert!(picks.iter().all(|p| p.weight == 1.0));
    }

    #[test]
    fn the_cut_is_unbiased_and_within_its_budget() {
        // Each source's light is the importance itself: the cut's mean
        // over many draws must be their sum.
        let sources = grid(500, 9);
        let tree = LightTree::new(&sources);
        let mut state = 17u64;
        for budget in [1usize, 4, 16] {
            for _ in 0..4 {
                let point = DVec3::new(
                    10.0 * xorshift(&mut state),
                    0.5 * xorshift(&mut state),
                    10.0 * xorshift(&mut state),
                );
                let importance = |i: u32| sources[i as usize].importance(point, DVec3::Y);
                let exact: f64 = (0..500u32).map(importance).sum();
                let light = |i: u32| {
                    // Light that is not in proportion to the importance.
                    importance(i) * (1.0 + 0.5 * f64::from(i % 3))
                };
                let exact_light: f64 = (0..500u32).map(light).sum();
                assert!(exact > 0.0);
                let rounds = 20_000;
                let mut sum = 0.0;
                let mut square = 0.0;
                let mut picks = Vec::new();
                for _ in 0..rounds {
                    let draws: Vec<f64> = (0..budget).map(|_| xorshift(&mut state)).collect();
                    tree.cut(
                        point,
                        DVec3::Y,
                        budget,
                        &importance,
                        &|k| draws[k],
                        &mut picks,
                    );
                    assert!(picks.len() <= budget);
                    let estimate: f64 = picks.iter().map(|p| light(p.source) * p.weight).sum();
                    sum += estimate;
                    square += estimate * estimate;
                }
                let n = f64::from(rounds);
                let mean = sum / n;
                let error = ((square / n - mean * mean).max(0.0) / n).sqrt();
                assert!(
                    (mean - exact_light).abs() <= 5.0 * error + 1e-9 * exact_light,
                    "budget {budget}: mean {mean} against {exact_light} (standard error {error})"
                );
            }
        }
    }

    #[test]
    fn cones_join_into_one_holding_both() {
        let mut state = 23u64;
        for _ in 0..5000 {
            let direction = |state: &mut u64| {
                DVec3::new(
                    xorshift(state) - 0.5,
                    xorshift(state) - 0.5,
                    xorshift(state) - 0.5,
                )
                .normalize()
            };
            let a = (direction(&mut state), xorshift(&mut state) * PI);
            let b = (direction(&mut state), xorshift(&mut state) * PI);
            let (axis, theta) = cone_union(a, b);
            assert!((axis.length() - 1.0).abs() < 1e-9);
            for (c, t) in [a, b] {
                let apart = axis.dot(c).clamp(-1.0, 1.0).acos();
                assert!(
                    apart + t <= theta + 1e-6 || theta >= PI,
                    "{a:?} {b:?} -> {axis:?} {theta} ({apart} {t})"
                );
            }
        }
    }
}
