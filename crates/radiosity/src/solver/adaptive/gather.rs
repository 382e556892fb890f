//! The transfers of one adaptive shot ([`super`]): the shooting node's
//! sources refined against the receivers' tree. The tree only prunes
//! (groups no point of the source can reach) and spreads the work over
//! threads; each receiver refines the source for itself (the adaptive
//! source subdivision of Wallace, Elmquist & Haines 1989, section 4), down
//! to elements, each its exact factor by the paper's equation (2) and a
//! shadow ray. Receivers never share a visibility estimate: a group's
//! shared estimate (a link, Smits, Arvo & Greenberg 1994) smeared shadow
//! edges and contacts over the group for no measurable speed.

use std::f64::consts::PI;

use glam::DVec3;

use super::{ABORT_CHECK_RECEIVERS, FAR_FACTOR, FAR_RATIO, PARALLEL_RECEIVERS};
use crate::solver::hierarchy::sources::{MAX_BINS, point_factor};
use crate::solver::hierarchy::transfer::{
    Cost, DIM_SHARE, Scratch, Side, Transfer, placement, straddles,
};
use crate::solver::hierarchy::{NONE, Node, Tree};
use crate::solver::{Abort, Counter, Receiver};

/// Counters of a part of a shot.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Counters {
    /// Pairs, rays and factors, and their times.
    pub(super) cost: Cost,
    /// Receivers that walked the source tree for themselves.
    pub(super) walks: u64,
    /// Source nodes those walks visited.
    pub(super) node_visits: u64,
    /// Elements taken as exact sources.
    pub(super) element_sources: u64,
}

impl Counters {
    /// The counters the statistics file reports (adaptive shooting's own).
    pub(super) fn list(&self) -> Vec<(&'static str, Counter)> {
        vec![
            ("receiver_walks", Counter::Count(self.walks)),
            ("walk_node_visits", Counter::Count(self.node_visits)),
            ("element_sources", Counter::Count(self.element_sources)),
            ("shadow_cache_hits", Counter::Count(self.cost.shadow.hits)),
        ]
    }
}

impl std::ops::AddAssign for Counters {
    fn add_assign(&mut self, o: Counters) {
        self.cost += o.cost;
        self.walks += o.walks;
        self.node_visits += o.node_visits;
        self.element_sources += o.element_sources;
    }
}

/// Everything a shot's transfers read.
pub(super) struct Gatherer<'s> {
    /// The sources.
    pub(super) transfer: Transfer<'s>,
    /// The receivers' tree.
    pub(super) receiver_tree: &'s Tree,
    /// The receivers.
    pub(super) receivers: &'s [Receiver],
    /// Negligible irradiance per receiver-tree node.
    pub(super) negligible: &'s [f64],
    /// Checked between groups of receivers.
    pub(super) abort: &'s Abort,
}

impl Gatherer<'_> {
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
        let source = self.transfer.source(s);
        if source.weight <= 0.0 {
            return;
        }
        let sn = self.transfer.source_node(s);
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
            let surface = self.transfer.plane_of(sn);
            if surface.normal.dot(rn.centre) - surface.offset < -rn.radius {
                return false;
            }
        }
        true
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
            let node = self.transfer.source_node(n);
            let source = self.transfer.source(n);
            counters.node_visits += 1;
            if source.weight <= 0.0 || !self.transfer.faces(node, r) {
                continue;
            }
            if node.is_leaf() {
                counters.element_sources += 1;
                let e = self.transfer.hierarchy.tree.items[node.first as usize];
                sum += self
                    .transfer
                    .element_irradiance(e, r, scratch, &mut counters.cost);
                continue;
            }
            // A node whose box lies behind the receiver's plane sends
            // nothing, whatever its sphere.
            if placement(node, r) == Side::Behind {
                continue;
            }
            let distance = node.centre.distance(r.point);
            if distance < FAR_RATIO * node.radius || straddles(node, r) {
                // Near: accepted whole only if even all its power at the
                // nearest point of its bounding sphere would be negligible.
                let clearance = distance - node.radius;
                if clearance > 0.0 && source.weight <= negligible * PI * clearance * clearance {
                    sum +=
                        self.transfer
                            .dim_irradiance(n, r, negligible, scratch, &mut counters.cost);
                    continue;
                }
            } else {
                // Far: the corrected point sources are accurate; what is
                // left to judge is occlusion.
                let bins = self.transfer.bins_of(n);
                let mut factors = [0.0; MAX_BINS];
                for (f, b) in factors.iter_mut().zip(bins) {
                    *f = point_factor(b, self.transfer.origin, r.point, r.normal);
                }
                let estimate: f64 = bins.iter().zip(&factors).map(|(b, f)| b.weight * f).sum();
                // The node's geometry, where it is needed: its bins'
                // factors as they are where the quadrature would take it
                // whole.
                let cost = &mut counters.cost;
                let geometry = |budget: f64, scratch: &mut Scratch, cost: &mut Cost| {
                    if self.transfer.whole(n, r) {
                        self.transfer.whole_geometry(n, &factors, cost)
                    } else {
                        self.transfer.node_geometry(n, r, budget, scratch, cost)
                    }
                };
                if estimate <= FAR_FACTOR * negligible {
                    let g = geometry(DIM_SHARE * negligible, scratch, cost);
                    sum += self.transfer.dim_irradiance_of(n, r, &g, cost);
                    continue;
                }
                if let Some(passing) = self.transfer.uniform_visibility(n, r, cost) {
                    if passing != DVec3::ZERO {
                        sum += geometry(0.0, scratch, cost).iter().sum::<DVec3>() * passing;
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
}
