//! One receiver's cut through the tree of all unshot power (Walter et al.
//! 2005, Lightcuts, applied to a pass of radiosity): the set of element-tree
//! nodes that together hold every element once, each taken as one source,
//! refined where the error it may carry is above the tolerance times what
//! the receiver gathers.
//!
//! A node's error is measured, not assumed (Hasenfratz et al. 1999 found
//! clustering misbehaves on clutter): an element is exact (the paper's
//! equation (2) and one shadow ray, kept from pass to pass); a node far from
//! the receiver (beyond [`FAR_RATIO`] of its radii, its box wholly in front)
//! has an accurate unoccluded transfer ([`Transfer::node_geometry`]) and
//! errs only by its visibility, which is unknown (its whole transfer) until
//! four shadow rays spread over it agree (no error) or disagree (a quarter
//! of it, their power-weighted fraction being the estimate); a node near the
//! receiver is only bounded, by all its power sent from its box's nearest
//! point ([`Transfer::bound`]), and integrated (with one shadow ray) only if
//! that bound is small enough to accept it. Visibilities are
//! geometry and outlive the pass; a cut is never coarsened, so later passes
//! re-use the rays of the first ones.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use glam::DVec3;

use crate::luminance;
use crate::solver::Receiver;
use crate::solver::hierarchy::transfer::{
    Cost, FAR_RATIO, Scratch, Transfer, box_distance, box_straddles,
};

/// What a cut entry knows of its node's visibility.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Seen {
    /// Nothing yet.
    Unknown,
    /// One shadow ray's answer (`visibility` is 0 or 1).
    OneRay,
    /// Four rays that agreed (`visibility` is 0 or 1).
    Agreed,
    /// Four rays that disagreed (`visibility` their weighted fraction).
    Mixed,
    /// A single element whose visible factor is `factor`.
    Element,
}

/// One node of a receiver's cut.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Entry {
    node: u32,
    /// Visible factor of an element, once known.
    factor: f32,
    /// Visibility of an inner node, as `seen` says.
    visibility: f32,
    seen: Seen,
}

impl Entry {
    /// A node not looked at yet.
    pub(crate) fn new(node: u32) -> Entry {
        Entry {
            node,
            factor: 0.0,
            visibility: 1.0,
            seen: Seen::Unknown,
        }
    }
}

/// The error of the visibility of a node whose four rays disagreed, as a
/// fraction of its unoccluded transfer: their weighted fraction is off by
/// at most a quarter on average over the pieces they stand for.
const MIXED_ERROR: f64 = 0.25;

/// The cut refinement of one pass: the transfer, the tolerance and the
/// pass's floor for a receiver's threshold.
pub(crate) struct Refiner<'t> {
    pub(crate) transfer: Transfer<'t>,
    /// Relative error accepted in what a receiver gathers.
    pub(crate) tolerance: f64,
    /// Irradiance (luminance) below which a receiver's threshold stops
    /// falling.
    pub(crate) floor: f64,
}

/// What refining cuts did.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Work {
    pub(crate) cost: Cost,
    /// Nodes replaced by their children.
    pub(crate) splits: u64,
    /// Nodes whose visibility was sampled by four rays.
    pub(crate) sampled: u64,
    /// Entries evaluated.
    pub(crate) evaluations: u64,
}

impl std::ops::AddAssign for Work {
    fn add_assign(&mut self, o: Work) {
        self.cost += o.cost;
        self.splits += o.splits;
        self.sampled += o.sampled;
        self.evaluations += o.evaluations;
    }
}

/// Buffers a task reuses from receiver to receiver.
#[derive(Default)]
pub(crate) struct CutScratch {
    transfer: Scratch,
    values: Vec<DVec3>,
    /// Unoccluded transfer of each far entry (luminance), 0 otherwise.
    unoccluded: Vec<DVec3>,
    /// How each entry was estimated.
    kinds: Vec<Kind>,
    heap: BinaryHeap<Candidate>,
}

/// An entry waiting for refinement, by its error.
#[derive(Clone, Copy, Debug)]
struct Candidate {
    error: f64,
    index: u32,
}

impl PartialEq for Candidate {
    fn eq(&self, o: &Self) -> bool {
        self.cmp(o) == Ordering::Equal
    }
}
impl Eq for Candidate {}
impl PartialOrd for Candidate {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Candidate {
    fn cmp(&self, o: &Self) -> Ordering {
        // Ties by index, so the order of refinement (and the result) does
        // not depend on the heap's internals.
        self.error
            .total_cmp(&o.error)
            .then_with(|| o.index.cmp(&self.index))
    }
}

/// How an entry was estimated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    /// An element, or nothing to send: exact.
    Exact,
    /// A far node: its unoccluded transfer, errs by its visibility.
    Far,
    /// A near node, only bounded so far: its value is zero until settled.
    Near,
}

/// One entry's estimate this pass.
struct Estimate {
    /// What it sends the receiver.
    value: DVec3,
    /// Its unoccluded transfer when it is a far node (else zero).
    unoccluded: DVec3,
    /// What kind of estimate it is.
    kind: Kind,
    /// What that may be off by (luminance).
    error: f64,
}

impl Refiner<'_> {
    /// Refines receiver `r`'s cut for this pass and returns what it
    /// gathers.
    pub(crate) fn gather(
        &self,
        r: &Receiver,
        cut: &mut Vec<Entry>,
        scratch: &mut CutScratch,
        work: &mut Work,
    ) -> DVec3 {
        let CutScratch {
            transfer: ts,
            values,
            unoccluded,
            kinds,
            heap,
        } = scratch;
        values.clear();
        unoccluded.clear();
        kinds.clear();
        heap.clear();
        let mut total = DVec3::ZERO;
        for (i, entry) in cut.iter_mut().enumerate() {
            let e = self.estimate(entry, r, ts, work);
            total += e.value;
            values.push(e.value);
            unoccluded.push(e.unoccluded);
            kinds.push(e.kind);
            if e.error > 0.0 {
                heap.push(Candidate {
                    error: e.error,
                    index: i as u32,
                });
            }
        }
        while let Some(&top) = heap.peek() {
            if top.error <= self.tolerance * luminance(total).max(self.floor) {
                break;
            }
            heap.pop();
            let i = top.index as usize;
            let entry = cut[i];
            total -= values[i];
            if kinds[i] == Kind::Far
                && matches!(entry.seen, Seen::Unknown | Seen::OneRay)
                && unoccluded[i] != DVec3::ZERO
            {
                // A far node of unknown visibility: four rays first.
                let e = self.sample(&mut cut[i], unoccluded[i], r, work);
                total += e.value;
                values[i] = e.value;
                if e.error > 0.0 {
                    heap.push(Candidate {
                        error: e.error,
                        index: i as u32,
                    });
                }
                continue;
            }
            let node = self.transfer.source_node(entry.node);
            debug_assert!(!node.is_leaf(), "an element has no error");
            let (first, second) = (entry.node + 1, node.second);
            for (k, child) in [first, second].into_iter().enumerate() {
                let mut c = Entry::new(child);
                if matches!(entry.seen, Seen::Agreed) {
                    // Rays that agreed over the parent stand for its
                    // children until they are asked again.
                    c.seen = Seen::OneRay;
                    c.visibility = entry.visibility;
                }
                let e = self.estimate(&mut c, r, ts, work);
                let index = if k == 0 {
                    cut[i] = c;
                    values[i] = e.value;
                    unoccluded[i] = e.unoccluded;
                    kinds[i] = e.kind;
                    i
                } else {
                    cut.push(c);
                    values.push(e.value);
                    unoccluded.push(e.unoccluded);
                    kinds.push(e.kind);
                    cut.len() - 1
                };
                total += e.value;
                if e.error > 0.0 {
                    heap.push(Candidate {
                        error: e.error,
                        index: index as u32,
                    });
                }
            }
            work.splits += 1;
        }
        // Nodes accepted without a ray, and near nodes accepted on their
        // bound: integrated and one ray each now.
        let mut gathered = DVec3::ZERO;
        for (i, entry) in cut.iter_mut().enumerate() {
            if kinds[i] == Kind::Near {
                unoccluded[i] = self.unoccluded(entry.node, r, ts, work);
            }
            if kinds[i] != Kind::Exact && unoccluded[i] != DVec3::ZERO {
                if entry.seen == Seen::Unknown {
                    let visible = self.one_ray(entry.node, r, work);
                    entry.seen = Seen::OneRay;
                    entry.visibility = if visible { 1.0 } else { 0.0 };
                }
                values[i] = unoccluded[i] * f64::from(entry.visibility);
            }
            gathered += values[i];
        }
        gathered
    }

    /// An entry's estimate from what it knows, casting rays only for an
    /// element seen for the first time.
    fn estimate(
        &self,
        entry: &mut Entry,
        r: &Receiver,
        ts: &mut Scratch,
        work: &mut Work,
    ) -> Estimate {
        work.evaluations += 1;
        let zero = Estimate {
            value: DVec3::ZERO,
            unoccluded: DVec3::ZERO,
            kind: Kind::Exact,
            error: 0.0,
        };
        let t = &self.transfer;
        let node = t.source_node(entry.node);
        if node.is_leaf() {
            let e = t.hierarchy.tree.items[node.first as usize];
            let unshot = t.unshot[e as usize];
            if unshot == DVec3::ZERO {
                return zero;
            }
            if entry.seen != Seen::Element {
                entry.factor = t.visible_element_factor(e, r, ts, &mut work.cost) as f32;
                entry.seen = Seen::Element;
            }
            return Estimate {
                value: unshot * f64::from(entry.factor),
                ..zero
            };
        }
        let weight = t.source(entry.node).weight;
        if weight <= 0.0 || !t.faces(node, r) {
            return zero;
        }
        if box_distance(node, r.point) <= 0.0 {
            // The receiver is inside its box: no estimate bounds it.
            return Estimate {
                error: f64::INFINITY,
                ..zero
            };
        }
        let far = box_distance(node, r.point) >= FAR_RATIO * node.radius && !box_straddles(node, r);
        if !far {
            // Near: bounded until it is either refined or accepted, and
            // only then integrated (see `Refiner::settle`).
            return Estimate {
                kind: Kind::Near,
                error: t.bound(entry.node, weight, r),
                ..zero
            };
        }
        let unoccluded = self.unoccluded(entry.node, r, ts, work);
        let g = luminance(unoccluded);
        let visibility = f64::from(entry.visibility);
        let (value, error) = match entry.seen {
            Seen::Unknown => (unoccluded, g),
            Seen::OneRay => (unoccluded * visibility, g),
            Seen::Agreed => (unoccluded * visibility, 0.0),
            Seen::Mixed => (unoccluded * visibility, MIXED_ERROR * g),
            Seen::Element => unreachable!("an inner node is not an element"),
        };
        Estimate {
            value,
            unoccluded,
            kind: Kind::Far,
            error,
        }
    }

    /// A node's transfer to the receiver, ignoring occlusion.
    fn unoccluded(&self, n: u32, r: &Receiver, ts: &mut Scratch, work: &mut Work) -> DVec3 {
        self.transfer
            .node_geometry(n, r, 0.0, ts, &mut work.cost)
            .iter()
            .sum::<DVec3>()
            .max(DVec3::ZERO)
    }

    /// Samples a far node's visibility by four rays.
    fn sample(
        &self,
        entry: &mut Entry,
        unoccluded: DVec3,
        r: &Receiver,
        work: &mut Work,
    ) -> Estimate {
        work.sampled += 1;
        let g = luminance(unoccluded);
        let (visibility, agreed) = self
            .transfer
            .sampled_visibility(entry.node, r, &mut work.cost)
            .unwrap_or((0.0, true));
        entry.visibility = visibility as f32;
        entry.seen = if agreed { Seen::Agreed } else { Seen::Mixed };
        Estimate {
            value: unoccluded * visibility,
            unoccluded,
            kind: Kind::Far,
            error: if agreed { 0.0 } else { MIXED_ERROR * g },
        }
    }

    /// One shadow ray from the representative of a node's brightest bin.
    fn one_ray(&self, n: u32, r: &Receiver, work: &mut Work) -> bool {
        let t = &self.transfer;
        match t.representative(n) {
            Some(e) => {
                work.cost.pairs += 1;
                t.visible_from(e, r, &mut work.cost)
            }
            None => false,
        }
    }
}
