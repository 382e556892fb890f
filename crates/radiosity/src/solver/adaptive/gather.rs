//! The transfers of one adaptive shot ([`super`]): the shooting node's
//! sources refined against the receivers' tree. A group of receivers far
//! from a dim source shares one estimate of its visibility (a *link*);
//! otherwise each receiver refines the source for itself (the adaptive
//! source subdivision of Wallace, Elmquist & Haines 1989, section 4), down
//! to elements, each its exact factor by the paper's equation (2) and a
//! shadow ray.

use std::f64::consts::PI;
use std::time::{Duration, Instant};

use glam::DVec3;

use super::hierarchy::{Hierarchy, NONE, Node, Tree};
use super::sources::{Bin, NodeSource, Sources, point_factor};
use super::{
    ABORT_CHECK_RECEIVERS, FAR_FACTOR, FAR_RATIO, LINK_FACTOR, LINK_MIN_RECEIVERS, LINK_SPREAD,
    PARALLEL_RECEIVERS, QUADRATURE_RATIO, TIMING_SAMPLE,
};
use crate::accel::{self, Occluder};
use crate::form_factor::{FormFactor, Source};
use crate::geometry;
use crate::luminance;
use crate::mesh::Mesh;
use crate::scene::Scene;
use crate::solver::{Abort, Counter, Receiver};

/// Counters of a part of a shot.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Counters {
    pub(super) pairs: u64,
    pub(super) rays: u64,
    pub(super) factors: u64,
    /// Receiver groups that shared one visibility estimate (links).
    pub(super) links: u64,
    /// Receivers served by links.
    pub(super) linked_receivers: u64,
    /// Receivers that walked the source tree for themselves.
    pub(super) walks: u64,
    /// Source nodes those walks visited.
    pub(super) node_visits: u64,
    /// Elements taken as exact sources.
    pub(super) element_sources: u64,
    pub(super) ray_time: Duration,
    pub(super) form_factor_time: Duration,
}

impl Counters {
    /// The counters the statistics file reports (adaptive shooting's own).
    pub(super) fn list(&self) -> Vec<(&'static str, Counter)> {
        vec![
            ("links", Counter::Count(self.links)),
            ("linked_receivers", Counter::Count(self.linked_receivers)),
            ("receiver_walks", Counter::Count(self.walks)),
            ("walk_node_visits", Counter::Count(self.node_visits)),
            ("element_sources", Counter::Count(self.element_sources)),
        ]
    }
}

impl std::ops::AddAssign for Counters {
    fn add_assign(&mut self, o: Counters) {
        self.pairs += o.pairs;
        self.rays += o.rays;
        self.factors += o.factors;
        self.links += o.links;
        self.linked_receivers += o.linked_receivers;
        self.walks += o.walks;
        self.node_visits += o.node_visits;
        self.element_sources += o.element_sources;
        self.ray_time += o.ray_time;
        self.form_factor_time += o.form_factor_time;
    }
}
/// Buffers a task reuses from receiver to receiver.
#[derive(Default)]
struct Scratch {
    /// Nodes still to visit.
    stack: Vec<u32>,
    /// Pieces of a node still to integrate.
    pieces: Vec<u32>,
    /// An element's corners.
    polygon: Vec<DVec3>,
    /// The part of an element in front of the receiver.
    clipped: Vec<DVec3>,
}

/// Everything a shot's transfers read.
pub(super) struct Gatherer<'s> {
    pub(super) scene: &'s Scene,
    pub(super) mesh: &'s Mesh,
    pub(super) hierarchy: &'s Hierarchy,
    pub(super) receiver_tree: &'s Tree,
    pub(super) receivers: &'s [Receiver],
    /// Negligible irradiance per receiver-tree node.
    pub(super) negligible: &'s [f64],
    pub(super) unshot: &'s [DVec3],
    pub(super) sources: &'s Sources,
    /// The shooting node.
    pub(super) root: u32,
    /// Its centre, the origin of the bins' sums.
    pub(super) origin: DVec3,
    pub(super) occluder: &'s dyn Occluder,
    pub(super) form_factor: FormFactor,
    /// Checked between groups of receivers.
    pub(super) abort: &'s Abort,
}

impl Gatherer<'_> {
    fn source(&self, n: u32) -> &NodeSource {
        &self.sources.nodes[(n - self.root) as usize]
    }

    fn bins_of(&self, n: u32) -> &[Bin] {
        let s = self.source(n);
        &self.sources.bins[s.first_bin as usize..s.first_bin as usize + s.bins as usize]
    }

    fn source_node(&self, n: u32) -> &Node {
        &self.hierarchy.tree.nodes[n as usize]
    }

    /// The transfer from source node `s` to receiver node `r`, added to
    /// `out` (the irradiance of `r`'s receivers, in tree order).
    pub(super) fn refine(&self, s: u32, r: u32, out: &mut [DVec3]) -> Counters {
        let mut counters = Counters::default();
        let mut scratch = Scratch::default();
        self.refine_into(s, r, out, &mut scratch, &mut counters);
        counters
    }

    fn refine_into(
        &self,
        s: u32,
        r: u32,
        out: &mut [DVec3],
        scratch: &mut Scratch,
        counters: &mut Counters,
    ) {
        let source = self.source(s);
        if source.weight <= 0.0 {
            return;
        }
        let sn = self.source_node(s);
        let rn = &self.receiver_tree.nodes[r as usize];
        if sn.group != NONE && sn.group == rn.group {
            return;
        }
        if rn.is_leaf() {
            let receiver = &self.receivers[self.receiver_tree.items[rn.first as usize] as usize];
            out[0] += self.gather(s, receiver, self.negligible[r as usize], scratch, counters);
            return;
        }
        if !self.may_reach(sn, rn) {
            return;
        }
        if rn.last - rn.first >= ABORT_CHECK_RECEIVERS && self.abort.fired() {
            return;
        }
        // A link: every receiver of `r` is far enough from `s` for its own
        // corrected point sources to be accurate, `r` is small as seen from
        // `s`, and `s` sends it little; then only occlusion is shared, and
        // only if rays spread over both ends agree. A transfer too bright
        // to share visibility goes on to each receiver, which refines the
        // source for itself.
        let distance = sn.centre.distance(rn.centre);
        let clearance = distance - sn.radius - rn.radius;
        let dim = clearance > 0.0
            && source.weight
                <= LINK_FACTOR * self.negligible[r as usize] * PI * clearance * clearance;
        if dim
            && !sn.is_leaf()
            && rn.last - rn.first >= LINK_MIN_RECEIVERS
            && distance - rn.radius >= FAR_RATIO * sn.radius
            && rn.radius <= LINK_SPREAD * distance
            && let Some(visible) = self.shared_visibility(s, r, counters)
        {
            if visible {
                self.link(s, r, out, scratch, counters);
            }
            return;
        }
        // Split the receivers, never the source: each receiver refines the
        // source for itself far more cheaply than pairs of pieces could (a
        // source split down to elements against a group of receivers would
        // cost every receiver every element).
        let second = rn.second;
        let split = (self.receiver_tree.nodes[second as usize].first - rn.first) as usize;
        let (a, b) = out.split_at_mut(split);
        if rn.last - rn.first >= PARALLEL_RECEIVERS {
            let (ca, cb) = rayon::join(|| self.refine(s, r + 1, a), || self.refine(s, second, b));
            *counters += ca;
            *counters += cb;
        } else {
            self.refine_into(s, r + 1, a, scratch, counters);
            self.refine_into(s, second, b, scratch, counters);
        }
    }

    /// False when no point of source node `sn` can light a receiver of
    /// `rn`: within one surface, one is behind the other's plane.
    fn may_reach(&self, sn: &Node, rn: &Node) -> bool {
        if rn.group != NONE {
            let first = &self.receivers[self.receiver_tree.items[rn.first as usize] as usize];
            if first.normal.dot(sn.centre - rn.centre) < -(sn.radius + rn.radius) {
                return false;
            }
        }
        if sn.group != NONE {
            let surface = self.plane_of(sn);
            if surface.normal.dot(rn.centre) - surface.offset < -rn.radius {
                return false;
            }
        }
        true
    }

    /// The surface of a node within one surface id.
    fn plane_of(&self, node: &Node) -> &crate::scene::Surface {
        let e = self.hierarchy.tree.items[node.first as usize];
        &self.scene.surfaces[self.mesh.elements[e as usize].surface as usize]
    }

    /// Whether every receiver of `r` sees all of source `s` or none of it,
    /// judged by shadow rays between up to four points spread over each;
    /// `None` when they disagree.
    fn shared_visibility(&self, s: u32, r: u32, counters: &mut Counters) -> Option<bool> {
        let sources = self.samples(&self.hierarchy.tree, s);
        let receivers = self.samples(self.receiver_tree, r);
        let (ns, nr) = (sources.1, receivers.1);
        unanimous((0..ns.max(nr)).filter_map(|i| {
            let e = self.representative(sources.0[i % ns])?;
            let receiver = &self.receivers[self.receiver_tree.items
                [self.receiver_tree.nodes[receivers.0[i % nr] as usize].first as usize]
                as usize];
            counters.pairs += 1;
            Some(self.visible_from(e, receiver, counters))
        }))
    }

    /// Up to four nodes spread over node `n`: its grandchildren, or children
    /// where the tree ends, or itself.
    fn samples(&self, tree: &Tree, n: u32) -> ([u32; 4], usize) {
        let mut out = [n; 4];
        let node = &tree.nodes[n as usize];
        if node.is_leaf() {
            return (out, 1);
        }
        let mut count = 0;
        for child in [n + 1, node.second] {
            let c = &tree.nodes[child as usize];
            if c.is_leaf() {
                out[count] = child;
                count += 1;
            } else {
                out[count] = child + 1;
                out[count + 1] = c.second;
                count += 2;
            }
        }
        (out, count)
    }

    /// The representative element of a source node's brightest bin.
    fn representative(&self, n: u32) -> Option<u32> {
        self.bins_of(n)
            .iter()
            .max_by(|a, b| a.weight.total_cmp(&b.weight))
            .map(|b| b.representative)
    }

    /// A link: every receiver of `r` takes source `s`'s corrected point
    /// sources, visible.
    fn link(
        &self,
        s: u32,
        r: u32,
        out: &mut [DVec3],
        scratch: &mut Scratch,
        counters: &mut Counters,
    ) {
        let bins = self.bins_of(s);
        let sn = self.source_node(s);
        counters.links += 1;
        counters.linked_receivers += u64::from(self.receiver_tree.nodes[r as usize].last)
            - u64::from(self.receiver_tree.nodes[r as usize].first);
        for (i, &index) in self.receiver_tree.items_of(r).iter().enumerate() {
            let receiver = &self.receivers[index as usize];
            if straddles(sn, receiver) {
                // Its horizon cuts the source: no point source will do.
                let negligible = self.negligible[r as usize];
                out[i] += self.gather(s, receiver, negligible, scratch, counters);
                continue;
            }
            for bin in bins {
                out[i] +=
                    bin.power * point_factor(bin, self.origin, receiver.point, receiver.normal);
            }
        }
        counters.pairs += 1;
    }

    /// The irradiance source node `s` sends to one receiver.
    fn gather(
        &self,
        s: u32,
        r: &Receiver,
        negligible: f64,
        scratch: &mut Scratch,
        counters: &mut Counters,
    ) -> DVec3 {
        let mut sum = DVec3::ZERO;
        let mut stack = std::mem::take(&mut scratch.stack);
        stack.clear();
        stack.push(s);
        counters.walks += 1;
        while let Some(n) = stack.pop() {
            let node = self.source_node(n);
            let source = self.source(n);
            counters.node_visits += 1;
            if source.weight <= 0.0 || !self.faces(node, r) {
                continue;
            }
            if node.is_leaf() {
                counters.element_sources += 1;
                let e = self.hierarchy.tree.items[node.first as usize];
                sum += self.element_irradiance(e, r, scratch, counters);
                continue;
            }
            let distance = node.centre.distance(r.point);
            if distance < FAR_RATIO * node.radius || straddles(node, r) {
                // Near: accepted whole only if even all its power at the
                // nearest point of its bounding sphere would be negligible.
                let clearance = distance - node.radius;
                if clearance > 0.0 && source.weight <= negligible * PI * clearance * clearance {
                    sum += self.dim_irradiance(n, r, scratch, counters);
                    continue;
                }
            } else {
                // Far: the corrected point sources are accurate; what is
                // left to judge is occlusion.
                let estimate: f64 = self
                    .bins_of(n)
                    .iter()
                    .map(|b| b.weight * point_factor(b, self.origin, r.point, r.normal))
                    .sum();
                if estimate <= FAR_FACTOR * negligible {
                    sum += self.dim_irradiance(n, r, scratch, counters);
                    continue;
                }
                if let Some(visible) = self.uniform_visibility(n, r, counters) {
                    if visible {
                        sum += self
                            .node_geometry(n, r, scratch, counters)
                            .iter()
                            .sum::<DVec3>();
                    }
                    continue;
                }
            }
            stack.push(node.second);
            stack.push(n + 1);
        }
        scratch.stack = stack;
        sum
    }

    /// False when no point of `node` can send light to the receiver: its
    /// sphere is behind the receiver's tangent plane, it lies in the
    /// receiver's own surface, or (within one surface) the receiver is
    /// behind its plane.
    fn faces(&self, node: &Node, r: &Receiver) -> bool {
        if r.normal.dot(node.centre - r.point) < -node.radius {
            return false;
        }
        if node.group == NONE {
            return true;
        }
        if node.group == r.group {
            return false;
        }
        let surface = self.plane_of(node);
        surface.normal.dot(r.point) - surface.offset > 0.0
    }

    /// A node that can send the receiver little, as up to six sources by
    /// normal direction behind one shadow ray, from the representative of
    /// the bin that sends the most: an error in its visibility costs at
    /// most what the node sends.
    fn dim_irradiance(
        &self,
        n: u32,
        r: &Receiver,
        scratch: &mut Scratch,
        counters: &mut Counters,
    ) -> DVec3 {
        let geometry = self.node_geometry(n, r, scratch, counters);
        let Some((bin, _)) = self
            .bins_of(n)
            .iter()
            .zip(&geometry)
            .filter(|(_, g)| **g != DVec3::ZERO)
            .max_by(|a, b| luminance(*a.1).total_cmp(&luminance(*b.1)))
        else {
            return DVec3::ZERO;
        };
        counters.pairs += 1;
        if self.visible_from(bin.representative, r, counters) {
            geometry.iter().sum()
        } else {
            DVec3::ZERO
        }
    }

    /// Whether the receiver sees all of a node or none of it, judged by
    /// shadow rays from up to four points spread over it (the
    /// representatives of its grandchildren, or children where the tree
    /// ends); `None` when they disagree, and the node must be refined. A
    /// bright source's node is accepted this way only in full view or full
    /// shadow, so penumbrae are resolved down to elements while open view
    /// costs four rays.
    fn uniform_visibility(&self, n: u32, r: &Receiver, counters: &mut Counters) -> Option<bool> {
        let (samples, count) = self.samples(&self.hierarchy.tree, n);
        unanimous(samples[..count].iter().filter_map(|&piece| {
            let e = self.representative(piece)?;
            counters.pairs += 1;
            Some(self.visible_from(e, r, counters))
        }))
    }

    /// The irradiance each of a node's bins sends to the receiver, ignoring
    /// occlusion. The geometry of each is integrated over pieces of the node
    /// (its descendants) small enough to be seen as points, at least
    /// [`QUADRATURE_RATIO`] of their radii away (elements nearer than that
    /// by their exact factor): the midpoint rule over a node seen from three
    /// of its radii errs by a few per cent, over pieces seen from four with
    /// the correction of [`point_factor`] by far less, and the extra factors
    /// cost no rays.
    fn node_geometry(
        &self,
        n: u32,
        r: &Receiver,
        scratch: &mut Scratch,
        counters: &mut Counters,
    ) -> Vec<DVec3> {
        let timed = counters.factors.is_multiple_of(TIMING_SAMPLE);
        let t0 = timed.then(Instant::now);
        let axes: Vec<u8> = self.bins_of(n).iter().map(|b| b.axis).collect();
        let mut geometry = vec![DVec3::ZERO; axes.len()];
        let slot = |axis: u8| axes.iter().position(|&a| a == axis);
        let mut pieces = std::mem::take(&mut scratch.pieces);
        pieces.clear();
        pieces.push(n);
        while let Some(piece) = pieces.pop() {
            let node = self.source_node(piece);
            let near = r.point.distance_squared(node.centre)
                < (QUADRATURE_RATIO * node.radius).powi(2)
                || straddles(node, r);
            if near && !node.is_leaf() {
                pieces.push(node.second);
                pieces.push(piece + 1);
                continue;
            }
            for bin in self.bins_of(piece) {
                let Some(k) = slot(bin.axis) else { continue };
                geometry[k] += if near {
                    // An element close by: its exact factor.
                    let e = bin.representative;
                    self.element_factor(e, r, &mut scratch.polygon) * self.unshot[e as usize]
                } else {
                    bin.power * point_factor(bin, self.origin, r.point, r.normal)
                };
            }
        }
        scratch.pieces = pieces;
        counters.factors += 1;
        if let Some(t0) = t0 {
            counters.form_factor_time += t0.elapsed() * TIMING_SAMPLE as u32;
        }
        geometry
    }

    /// One element as a source: its polygon's factor (clipped to the
    /// receiver's front) and a shadow ray from the centre of the part in
    /// front.
    fn element_irradiance(
        &self,
        e: u32,
        r: &Receiver,
        scratch: &mut Scratch,
        counters: &mut Counters,
    ) -> DVec3 {
        let element = &self.mesh.elements[e as usize];
        let surface = &self.scene.surfaces[element.surface as usize];
        let polygon = &mut scratch.polygon;
        polygon.clear();
        polygon.extend(
            element
                .vertices()
                .iter()
                .map(|&v| self.mesh.vertices[v as usize].position),
        );
        let tolerance = 1e-9 * element.area.sqrt().max(1e-300);
        let (mut any_front, mut all_front) = (false, true);
        for c in polygon.iter() {
            let h = r.normal.dot(*c - r.point);
            any_front |= h > tolerance;
            all_front &= h > tolerance;
        }
        if !any_front {
            return DVec3::ZERO;
        }
        let origin = if all_front {
            self.hierarchy.centroids[e as usize]
        } else {
            geometry::clip_to_half_space(polygon, r.point, r.normal, 0.0, &mut scratch.clipped);
            if geometry::area(&scratch.clipped) <= 0.0 {
                return DVec3::ZERO;
            }
            geometry::centroid(&scratch.clipped)
        };
        counters.pairs += 1;
        if !self.visible(origin, r, surface.group, counters) {
            return DVec3::ZERO;
        }
        let factor = self.element_factor(e, r, &mut scratch.polygon);
        self.unshot[e as usize] * factor
    }

    /// The factor of element `e`'s polygon at the receiver (clipped to its
    /// front by the formula).
    fn element_factor(&self, e: u32, r: &Receiver, polygon: &mut Vec<DVec3>) -> f64 {
        let element = &self.mesh.elements[e as usize];
        let surface = &self.scene.surfaces[element.surface as usize];
        polygon.clear();
        polygon.extend(
            element
                .vertices()
                .iter()
                .map(|&v| self.mesh.vertices[v as usize].position),
        );
        self.form_factor.evaluate(
            r.point,
            r.normal,
            &Source {
                polygon,
                centroid: self.hierarchy.centroids[e as usize],
                normal: surface.normal,
                area: element.area,
            },
        )
    }

    /// Whether the receiver sees the centre of element `e`.
    fn visible_from(&self, e: u32, r: &Receiver, counters: &mut Counters) -> bool {
        let e = e as usize;
        let group = self.scene.surfaces[self.mesh.elements[e].surface as usize].group;
        self.visible(self.hierarchy.centroids[e], r, group, counters)
    }

    fn visible(&self, origin: DVec3, r: &Receiver, group: u32, counters: &mut Counters) -> bool {
        let timed = counters.rays.is_multiple_of(TIMING_SAMPLE);
        let t0 = timed.then(Instant::now);
        let (from, to) = accel::shorten(origin, r.point);
        let blocked = self.occluder.occluded(from, to, [group, r.group]);
        counters.rays += 1;
        if let Some(t0) = t0 {
            counters.ray_time += t0.elapsed() * TIMING_SAMPLE as u32;
        }
        !blocked
    }
}
/// The answer every vote gives, `None` when there are none or two differ;
/// stops drawing votes (shadow rays) at the first that differs.
fn unanimous(mut votes: impl Iterator<Item = bool>) -> Option<bool> {
    let first = votes.next()?;
    votes.all(|v| v == first).then_some(first)
}

/// True when the receiver's tangent plane cuts the node's bounding sphere:
/// part of the node may be behind the receiver and part in front, which no
/// point source (whose centre is on one side) can stand for; such a node is
/// refined down to elements, whose factors clip exactly.
fn straddles(node: &Node, r: &Receiver) -> bool {
    r.normal.dot(node.centre - r.point).abs() < node.radius
}
