//! One receiver and one node of the element tree as a source: the
//! primitives every clustered method's transfers are made of. A node is
//! taken as corrected point sources, one per bin of its unshot power by
//! normal direction ([`super::sources::point_factor`]), its visibility
//! judged by one shadow ray (a dim node) or by four spread over it (a
//! bright one, accepted only when they agree); an element is the finest
//! source, its exact factor by the paper's equation (2) on its polygon
//! clipped to the receiver's front and a shadow ray from the centre of
//! that part (design.md sections 3 and 4).

use std::time::{Duration, Instant};

use glam::DVec3;

use super::sources::{Bin, MAX_BINS, NodeSource, PointSource, Sources, point_factor};
use super::{Hierarchy, NONE, Node, Tree};
use crate::accel::{self, Occluder, ShadowCache};
use crate::form_factor::{FormFactor, Source};
use crate::geometry;
use crate::luminance;
use crate::mesh::Mesh;
use crate::scene::Scene;
use crate::solver::Receiver;

/// A node is far from a receiver beyond this many of its radii, where its
/// corrected point sources are accurate ([`point_factor`]).
pub const FAR_RATIO: f64 = 3.0;

/// An accepted node's geometry is integrated over pieces at least this
/// many of their radii from the receiver, each a corrected point source
/// ([`point_factor`]).
pub const QUADRATURE_RATIO: f64 = 4.0;

/// A dim node (accepted because what it can send the receiver is
/// negligible, or, far away, below a few tens of times that, and judged
/// by one shadow ray) has its geometry integrated to within this share
/// of the receiver's negligible irradiance, not to the quadrature's full
/// accuracy: pieces whose bound (`Transfer::bound`) is within their share
/// of that error are taken as they are (an error-driven refinement, as
/// Lischinski, Smits & Greenberg 1994 bound a link's error).
pub const DIM_SHARE: f64 = 0.05;

/// The irradiance each of a node's bins sends a receiver, ignoring
/// occlusion ([`Transfer::node_geometry`]): one value per bin, in the
/// bins' order, kept on the stack.
pub(crate) struct Geometry {
    values: [DVec3; MAX_BINS],
    count: usize,
}

impl std::ops::Deref for Geometry {
    type Target = [DVec3];

    fn deref(&self) -> &[DVec3] {
        &self.values[..self.count]
    }
}

/// One ray or factor in this many is timed, for the statistics' phase
/// times (a clock read costs a tenth of a ray).
pub(crate) const TIMING_SAMPLE: u64 = 16;

/// What transfers cost: pairs considered, shadow rays, factors, and the
/// (sampled) time in rays and factors.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Cost {
    /// Receiver-source pairs considered.
    pub(crate) pairs: u64,
    /// Shadow rays cast.
    pub(crate) rays: u64,
    /// Node geometries evaluated.
    pub(crate) factors: u64,
    /// Thread time in shadow rays.
    pub(crate) ray_time: Duration,
    /// Thread time in node geometries.
    pub(crate) form_factor_time: Duration,
    /// The task's last blocker, tested first by its next shadow ray, and
    /// how many rays it answered.
    pub(crate) shadow: ShadowCache,
}

impl std::ops::AddAssign for Cost {
    fn add_assign(&mut self, o: Cost) {
        self.pairs += o.pairs;
        self.rays += o.rays;
        self.factors += o.factors;
        self.ray_time += o.ray_time;
        self.form_factor_time += o.form_factor_time;
        self.shadow.hits += o.shadow.hits;
    }
}

/// Buffers a task reuses from receiver to receiver.
#[derive(Default)]
pub(crate) struct Scratch {
    /// Nodes still to visit.
    pub(crate) stack: Vec<u32>,
    /// Pieces of a node still to integrate.
    pub(crate) pieces: Vec<u32>,
    /// An element's corners.
    pub(crate) polygon: Vec<DVec3>,
    /// The part of an element in front of the receiver.
    pub(crate) clipped: Vec<DVec3>,
}

/// What a shot's transfers read of the sources.
pub(crate) struct Transfer<'s> {
    pub(crate) scene: &'s Scene,
    pub(crate) mesh: &'s Mesh,
    pub(crate) hierarchy: &'s Hierarchy,
    /// Unshot radiosity of each element.
    pub(crate) unshot: &'s [DVec3],
    /// The shooting subtree's sources.
    pub(crate) sources: &'s Sources,
    /// The shooting node.
    pub(crate) root: u32,
    /// Its centre, the origin of the bins' sums.
    pub(crate) origin: DVec3,
    pub(crate) occluder: &'s dyn Occluder,
    pub(crate) form_factor: FormFactor,
}

impl Transfer<'_> {
    pub(crate) fn source(&self, n: u32) -> &NodeSource {
        &self.sources.nodes[(n - self.root) as usize]
    }

    pub(crate) fn bins_of(&self, n: u32) -> &[Bin] {
        let s = self.source(n);
        &self.sources.bins[s.first_bin as usize..s.first_bin as usize + s.bins as usize]
    }

    pub(crate) fn source_node(&self, n: u32) -> &Node {
        &self.hierarchy.tree.nodes[n as usize]
    }

    /// The surface of a node within one surface id.
    pub(crate) fn plane_of(&self, node: &Node) -> &crate::scene::Surface {
        let e = self.hierarchy.tree.items[node.first as usize];
        &self.scene.surfaces[self.mesh.elements[e as usize].surface as usize]
    }

    /// Up to four nodes spread over node `n`: its grandchildren, or children
    /// where the tree ends, or itself.
    pub(crate) fn samples(&self, tree: &Tree, n: u32) -> ([u32; 4], usize) {
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
    pub(crate) fn representative(&self, n: u32) -> Option<u32> {
        self.bins_of(n)
            .iter()
            .max_by(|a, b| a.weight.total_cmp(&b.weight))
            .map(|b| b.representative)
    }

    /// False when no point of `node` can send light to the receiver: its
    /// sphere is behind the receiver's tangent plane, it lies in the
    /// receiver's own surface, or (within one surface) the receiver is
    /// behind its plane.
    pub(crate) fn faces(&self, node: &Node, r: &Receiver) -> bool {
        let plane = (node.group != NONE).then(|| {
            let surface = self.plane_of(node);
            (surface.normal, surface.offset)
        });
        faces(node, r, plane)
    }

    /// The most irradiance (luminance) node `n` can send the receiver
    /// whatever its visibility and however its power `weight` lies within
    /// its box: all of it from the box's nearest point, at the smallest
    /// angles to the receiver's normal and (within one surface) to the
    /// surface's normal that any point of the box makes; infinite when the
    /// receiver is inside the box.
    pub(crate) fn bound(&self, n: u32, weight: f64, r: &Receiver) -> f64 {
        let node = self.source_node(n);
        let sending = (node.group != NONE).then(|| self.plane_of(node).normal);
        bound(node, weight, r, sending)
    }

    /// A node that can send the receiver little, as up to six sources by
    /// normal direction behind one shadow ray, from the representative of
    /// the bin that sends the most: an error in its visibility costs at
    /// most what the node sends. Its geometry is integrated to within
    /// [`DIM_SHARE`] of `negligible`, the receiver's negligible irradiance.
    pub(crate) fn dim_irradiance(
        &self,
        n: u32,
        r: &Receiver,
        negligible: f64,
        scratch: &mut Scratch,
        cost: &mut Cost,
    ) -> DVec3 {
        let geometry = self.node_geometry(n, r, DIM_SHARE * negligible, scratch, cost);
        self.dim_irradiance_of(n, r, &geometry, cost)
    }

    /// [`Transfer::dim_irradiance`] with the node's geometry given.
    pub(crate) fn dim_irradiance_of(
        &self,
        n: u32,
        r: &Receiver,
        geometry: &Geometry,
        cost: &mut Cost,
    ) -> DVec3 {
        let Some((bin, _)) = self
            .bins_of(n)
            .iter()
            .zip(geometry.iter())
            .filter(|(_, g)| **g != DVec3::ZERO)
            .max_by(|a, b| luminance(*a.1).total_cmp(&luminance(*b.1)))
        else {
            return DVec3::ZERO;
        };
        cost.pairs += 1;
        let passing = self.passes_from(bin.representative, r, cost);
        if passing == DVec3::ZERO {
            DVec3::ZERO
        } else {
            geometry.iter().sum::<DVec3>() * passing
        }
    }

    /// Whether the receiver sees all of a node or none of it, judged by
    /// shadow rays from up to four points spread over it (the
    /// representatives of its grandchildren, or children where the tree
    /// ends); `None` when they disagree, and the node must be refined. A
    /// bright source's node is accepted this way only in full view or full
    /// shadow, so penumbrae are resolved down to elements while open view
    /// costs four rays.
    ///
    /// What passes is the rays' mean transmittance through glass (1, per
    /// channel, through none; 0 in full shadow).
    pub(crate) fn uniform_visibility(
        &self,
        n: u32,
        r: &Receiver,
        cost: &mut Cost,
    ) -> Option<DVec3> {
        let (samples, count) = self.samples(&self.hierarchy.tree, n);
        let mut passing = DVec3::ZERO;
        let mut votes = 0u32;
        let agreed = unanimous(samples[..count].iter().filter_map(|&piece| {
            let e = self.representative(piece)?;
            cost.pairs += 1;
            let through = self.passes_from(e, r, cost);
            passing += through;
            votes += 1;
            Some(through != DVec3::ZERO)
        }))?;
        // Through no glass, the mean of at most four ones: one, exactly.
        Some(if agreed {
            passing / f64::from(votes)
        } else {
            DVec3::ZERO
        })
    }

    /// The share of a node's power the receiver sees, judged by shadow rays
    /// from up to four points spread over it (as [`Transfer::uniform_visibility`]),
    /// each weighted by the power of the piece it stands for; and whether
    /// they all agreed. `None` when no piece has power.
    pub(crate) fn sampled_visibility(
        &self,
        n: u32,
        r: &Receiver,
        cost: &mut Cost,
    ) -> Option<(f64, bool)> {
        let (samples, count) = self.samples(&self.hierarchy.tree, n);
        let (mut seen, mut total) = (0.0, 0.0);
        let (mut any_visible, mut any_hidden) = (false, false);
        for &piece in &samples[..count] {
            let weight = self.source(piece).weight;
            let Some(e) = self.representative(piece) else {
                continue;
            };
            cost.pairs += 1;
            let visible = self.visible_from(e, r, cost);
            total += weight;
            if visible {
                seen += weight;
                any_visible = true;
            } else {
                any_hidden = true;
            }
        }
        (total > 0.0).then(|| (seen / total, !(any_visible && any_hidden)))
    }

    /// Whether [`Transfer::node_geometry`] takes node `n` as it is, its
    /// bins' point sources, at the receiver: at least [`QUADRATURE_RATIO`]
    /// of its radii away and in front of the receiver's tangent plane
    /// ([`placement`]).
    pub(crate) fn whole(&self, n: u32, r: &Receiver) -> bool {
        let node = self.source_node(n);
        r.point.distance_squared(node.centre) >= (QUADRATURE_RATIO * node.radius).powi(2)
            && placement(node, r) == Side::Front
    }

    /// [`Transfer::node_geometry`] of a node it takes [`Transfer::whole`],
    /// from its bins' point factors (`factors`, in the bins' order), already
    /// evaluated.
    pub(crate) fn whole_geometry(&self, n: u32, factors: &[f64], cost: &mut Cost) -> Geometry {
        let bins = self.bins_of(n);
        let mut geometry = Geometry {
            values: [DVec3::ZERO; MAX_BINS],
            count: bins.len(),
        };
        for ((value, bin), factor) in geometry.values.iter_mut().zip(bins).zip(factors) {
            *value += bin.power * *factor;
        }
        cost.factors += 1;
        geometry
    }

    /// The irradiance each of a node's bins sends to the receiver, ignoring
    /// occlusion. The geometry of each is integrated over pieces of the node
    /// (its descendants) small enough to be seen as points, at least
    /// [`QUADRATURE_RATIO`] of their radii away (elements nearer than that
    /// by their exact factor): the midpoint rule over a node seen from three
    /// of its radii errs by a few per cent, over pieces seen from four with
    /// the correction of [`point_factor`] by far less, and the extra factors
    /// cost no rays. A piece is placed against the receiver's tangent plane
    /// by its sphere and its box ([`placement`]): wholly behind it sends
    /// nothing, in front (touching the plane, or reaching behind it by no
    /// more than [`GRAZE`] of its radius) it is a point source like any
    /// other far piece, and one the plane cuts is split down to elements,
    /// each placed by its corners ([`Transfer::side`]) the same way: one
    /// the plane cuts is the point source of its part in front
    /// ([`Transfer::front_point_factor`]).
    ///
    /// `budget` (irradiance, luminance; 0 for none) is the error the caller
    /// accepts, shared among the pieces by power: a piece that the rules
    /// above would split or take exactly, and whose bound
    /// ([`Transfer::bound`]) is within its share, is taken as its point
    /// sources capped at that bound. Both lie between 0 and the bound, so
    /// the geometry errs by at most `budget` more than the quadrature's
    /// own (the test `a_budget_bounds_the_geometry_s_error`).
    pub(crate) fn node_geometry(
        &self,
        n: u32,
        r: &Receiver,
        budget: f64,
        scratch: &mut Scratch,
        cost: &mut Cost,
    ) -> Geometry {
        let timed = cost.factors.is_multiple_of(TIMING_SAMPLE);
        let t0 = timed.then(Instant::now);
        let bins = self.bins_of(n);
        let mut geometry = Geometry {
            values: [DVec3::ZERO; MAX_BINS],
            count: bins.len(),
        };
        let slot = |axis: u8| bins.iter().position(|b| b.axis == axis);
        // The error a unit of the node's power may bring.
        let allowance = budget / self.source(n).weight;
        let mut pieces = std::mem::take(&mut scratch.pieces);
        pieces.clear();
        pieces.push(n);
        while let Some(piece) = pieces.pop() {
            let node = self.source_node(piece);
            let close =
                r.point.distance_squared(node.centre) < (QUADRATURE_RATIO * node.radius).powi(2);
            let straddling = match placement(node, r) {
                Side::Behind => continue,
                Side::Front => false,
                Side::Across => true,
            };
            // A piece that would be split or taken exactly, and can send so
            // little that any value up to its bound is within its share of
            // the budget: its point sources, capped at the bound.
            if (close || straddling) && allowance > 0.0 {
                let weight = self.source(piece).weight;
                let most = self.bound(piece, weight, r);
                if most <= allowance * weight {
                    let mut values = [DVec3::ZERO; MAX_BINS];
                    let mut sent = 0.0;
                    for bin in self.bins_of(piece) {
                        let Some(k) = slot(bin.axis) else { continue };
                        values[k] = bin.power * point_factor(bin, self.origin, r.point, r.normal);
                        sent += luminance(values[k]);
                    }
                    let scale = if sent > most { most / sent } else { 1.0 };
                    for (total, value) in geometry.values.iter_mut().zip(values) {
                        *total += value * scale;
                    }
                    continue;
                }
            }
            if (close || straddling) && !node.is_leaf() {
                pieces.push(node.second);
                pieces.push(piece + 1);
                continue;
            }
            // An element far away whose box the receiver's tangent plane
            // cuts: a point source if its corners lie in front, nothing if
            // behind, and if the plane cuts it, the point source of the
            // part in front.
            let across = !close
                && straddling
                && match self.side(
                    self.hierarchy.tree.items[node.first as usize],
                    r,
                    GRAZE * node.radius,
                ) {
                    Side::Behind => continue,
                    Side::Front => false,
                    Side::Across => true,
                };
            for bin in self.bins_of(piece) {
                let Some(k) = slot(bin.axis) else { continue };
                let e = bin.representative;
                geometry.values[k] += if close {
                    // An element close by: its exact factor.
                    self.element_factor(e, r, &mut scratch.polygon) * self.unshot[e as usize]
                } else if across {
                    self.front_point_factor(e, r, scratch) * self.unshot[e as usize]
                } else {
                    bin.power * point_factor(bin, self.origin, r.point, r.normal)
                };
            }
        }
        scratch.pieces = pieces;
        cost.factors += 1;
        if let Some(t0) = t0 {
            cost.form_factor_time += t0.elapsed() * TIMING_SAMPLE as u32;
        }
        geometry
    }

    /// The factor of the part of element `e` in front of the receiver's
    /// tangent plane, that part taken as a corrected point source (its
    /// area, centroid and covariance, [`PointSource::of_polygon`]): for an
    /// element [`QUADRATURE_RATIO`] or more of its radii away, within
    /// 0.11% of the factor it would have head on (the test in
    /// [`super::sources`]), where its exact factor takes an angle an edge.
    fn front_point_factor(&self, e: u32, r: &Receiver, scratch: &mut Scratch) -> f64 {
        let element = &self.mesh.elements[e as usize];
        let polygon = &mut scratch.polygon;
        self.corners(e, polygon);
        geometry::clip_to_half_space(polygon, r.point, r.normal, 0.0, &mut scratch.clipped);
        let normal = self.scene.surfaces[element.surface as usize].normal;
        polygon_point_factor(&scratch.clipped, normal, r)
    }

    /// Which side of the receiver's tangent plane element `e` lies on, by
    /// its corners: in front also when it reaches behind by no more than
    /// `graze`.
    pub(crate) fn side(&self, e: u32, r: &Receiver, graze: f64) -> Side {
        let corners = self.mesh.elements[e as usize]
            .vertices()
            .iter()
            .map(|&v| self.mesh.vertices[v as usize].position);
        side(corners, r, graze)
    }

    /// One element as a source: its polygon's factor (clipped to the
    /// receiver's front) and a shadow ray from the centre of the part in
    /// front.
    pub(crate) fn element_irradiance(
        &self,
        e: u32,
        r: &Receiver,
        scratch: &mut Scratch,
        cost: &mut Cost,
    ) -> DVec3 {
        let (factor, passing) = self.passing_element_factor(e, r, scratch, cost);
        self.unshot[e as usize] * factor * passing
    }

    /// The factor of element `e` at the receiver times its visibility from
    /// the centre of the part in front of the receiver (one shadow ray): 0
    /// when the element is behind or hidden. Geometry only, so a method may
    /// keep it from pass to pass.
    pub(crate) fn visible_element_factor(
        &self,
        e: u32,
        r: &Receiver,
        scratch: &mut Scratch,
        cost: &mut Cost,
    ) -> f64 {
        self.passing_element_factor(e, r, scratch, cost).0
    }

    /// [`Transfer::visible_element_factor`] and what passes along its
    /// shadow ray: the transmittance of the glass it crosses (1 through
    /// none).
    pub(crate) fn passing_element_factor(
        &self,
        e: u32,
        r: &Receiver,
        scratch: &mut Scratch,
        cost: &mut Cost,
    ) -> (f64, DVec3) {
        let element = &self.mesh.elements[e as usize];
        let surface = &self.scene.surfaces[element.surface as usize];
        let polygon = &mut scratch.polygon;
        self.corners(e, polygon);
        let tolerance = 1e-9 * element.area.sqrt().max(1e-300);
        let (mut any_front, mut all_front) = (false, true);
        for c in polygon.iter() {
            let h = r.normal.dot(*c - r.point);
            any_front |= h > tolerance;
            all_front &= h > tolerance;
        }
        if !any_front {
            return (0.0, DVec3::ZERO);
        }
        let origin = if all_front {
            self.hierarchy.centroids[e as usize]
        } else {
            geometry::clip_to_half_space(polygon, r.point, r.normal, 0.0, &mut scratch.clipped);
            if geometry::area(&scratch.clipped) <= 0.0 {
                return (0.0, DVec3::ZERO);
            }
            geometry::centroid(&scratch.clipped)
        };
        cost.pairs += 1;
        cost.shadow.from_origin(e);
        let passing = self.passes(origin, r, surface.group, cost);
        if passing == DVec3::ZERO {
            return (0.0, DVec3::ZERO);
        }
        (self.polygon_factor(e, r, &scratch.polygon), passing)
    }

    /// The factor of element `e`'s polygon at the receiver (clipped to its
    /// front by the formula).
    pub(crate) fn element_factor(&self, e: u32, r: &Receiver, polygon: &mut Vec<DVec3>) -> f64 {
        self.corners(e, polygon);
        self.polygon_factor(e, r, polygon)
    }

    /// Element `e`'s corners, into `polygon`.
    fn corners(&self, e: u32, polygon: &mut Vec<DVec3>) {
        polygon.clear();
        polygon.extend(
            self.mesh.elements[e as usize]
                .vertices()
                .iter()
                .map(|&v| self.mesh.vertices[v as usize].position),
        );
    }

    /// [`Transfer::element_factor`], element `e`'s corners given.
    fn polygon_factor(&self, e: u32, r: &Receiver, polygon: &[DVec3]) -> f64 {
        let element = &self.mesh.elements[e as usize];
        let surface = &self.scene.surfaces[element.surface as usize];
        if self.form_factor == FormFactor::Analytic {
            // The element's normal is its surface's: not computed again.
            return crate::form_factor::analytic::analytic_facing_fast(
                r.point,
                r.normal,
                polygon,
                surface.normal,
            );
        }
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
    pub(crate) fn visible_from(&self, e: u32, r: &Receiver, cost: &mut Cost) -> bool {
        let e = e as usize;
        let group = self.scene.surfaces[self.mesh.elements[e].surface as usize].group;
        cost.shadow.from_origin(e as u32);
        self.visible(self.hierarchy.centroids[e], r, group, cost)
    }

    /// What passes from the centre of element `e` to the receiver: 0 where
    /// a surface blocks it, else the transmittance of the glass it crosses.
    pub(crate) fn passes_from(&self, e: u32, r: &Receiver, cost: &mut Cost) -> DVec3 {
        let group = self.scene.surfaces[self.mesh.elements[e as usize].surface as usize].group;
        cost.shadow.from_origin(e);
        self.passes(self.hierarchy.centroids[e as usize], r, group, cost)
    }

    /// What passes from `origin` to the receiver: 0 where a surface blocks
    /// it, else the transmittance of the glass it crosses (1, exactly,
    /// through none).
    pub(crate) fn passes(&self, origin: DVec3, r: &Receiver, group: u32, cost: &mut Cost) -> DVec3 {
        if !self.visible(origin, r, group, cost) {
            return DVec3::ZERO;
        }
        if self.scene.panes.is_empty() {
            return DVec3::ONE;
        }
        let (from, to) = accel::shorten(origin, r.point);
        crate::scene::glass::transmittance(&self.scene.panes, from, to)
    }

    pub(crate) fn visible(&self, origin: DVec3, r: &Receiver, group: u32, cost: &mut Cost) -> bool {
        let timed = cost.rays.is_multiple_of(TIMING_SAMPLE);
        let t0 = timed.then(Instant::now);
        let (from, to) = accel::shorten(origin, r.point);
        let blocked = self
            .occluder
            .occluded_cached(from, to, [group, r.group], &mut cost.shadow);
        cost.rays += 1;
        if let Some(t0) = t0 {
            cost.ray_time += t0.elapsed() * TIMING_SAMPLE as u32;
        }
        !blocked
    }
}

/// Where an element lies against a receiver's tangent plane.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// Every corner in front of the plane.
    Front,
    /// Every corner on or behind it: the element sends nothing.
    Behind,
    /// Corners on both sides.
    Across,
}

/// The answer every vote gives, `None` when there are none or two differ;
/// stops drawing votes (shadow rays) at the first that differs.
pub(crate) fn unanimous(mut votes: impl Iterator<Item = bool>) -> Option<bool> {
    let first = votes.next()?;
    votes.all(|v| v == first).then_some(first)
}

/// The distance from `point` to a node's box (0 inside it).
pub(crate) fn box_distance(node: &Node, point: DVec3) -> f64 {
    (node.lo - point)
        .max(point - node.hi)
        .max(DVec3::ZERO)
        .length()
}

/// The smallest and largest `direction . (x - point)` over a node's box.
pub(crate) fn box_extent(node: &Node, point: DVec3, direction: DVec3) -> (f64, f64) {
    let centre = 0.5 * (node.lo + node.hi);
    let half = 0.5 * (node.hi - node.lo);
    let middle = direction.dot(centre - point);
    let reach = direction.abs().dot(half);
    (middle - reach, middle + reach)
}

/// True when the receiver's tangent plane cuts a node's box: part of it
/// may be behind the receiver and part in front.
pub(crate) fn box_straddles(node: &Node, r: &Receiver) -> bool {
    let (low, high) = box_extent(node, r.point, r.normal);
    low < 0.0 && high > 0.0
}

/// A piece reaching behind the receiver's tangent plane by at most this
/// share of its radius is taken as lying in front.
pub const GRAZE: f64 = 1.0 / 16.0;

/// Which side of the receiver's tangent plane a node lies on, judged by
/// its sphere and its box: [`Side::Front`] also when it reaches behind by
/// no more than [`GRAZE`] of its radius.
pub fn placement(node: &Node, r: &Receiver) -> Side {
    let h = r.normal.dot(node.centre - r.point);
    if h >= node.radius {
        return Side::Front;
    }
    if h <= -node.radius {
        return Side::Behind;
    }
    let (low, high) = box_extent(node, r.point, r.normal);
    if low >= -GRAZE * node.radius {
        Side::Front
    } else if high <= 0.0 {
        Side::Behind
    } else {
        Side::Across
    }
}

/// True when the receiver's tangent plane cuts the node's bounding sphere:
/// part of the node may be behind the receiver and part in front, which no
/// point source (whose centre is on one side) can stand for; such a node is
/// refined down to elements, whose factors clip exactly.
pub fn straddles(node: &Node, r: &Receiver) -> bool {
    r.normal.dot(node.centre - r.point).abs() < node.radius
}

/// Whether any point of `node` can light the receiver: some of it in
/// front of the receiver's tangent plane and, for a node within one
/// surface whose plane (normal, offset) is `plane`, the receiver in front
/// of that plane and on another surface group.
pub fn faces(node: &Node, r: &Receiver, plane: Option<(DVec3, f64)>) -> bool {
    if r.normal.dot(node.centre - r.point) < -node.radius {
        return false;
    }
    let Some((normal, offset)) = plane else {
        return true;
    };
    if node.group == r.group {
        return false;
    }
    normal.dot(r.point) - offset > 0.0
}

/// The most irradiance (luminance) a node of power `weight` can send the
/// receiver whatever its visibility and however its power lies within
/// its box: all of it from the box's nearest point, at the smallest
/// angles to the receiver's normal and (for a node within one surface,
/// whose normal is `sending`) to the surface's normal that any point of
/// the box makes; infinite when the receiver is inside the box.
pub fn bound(node: &Node, weight: f64, r: &Receiver, sending: Option<DVec3>) -> f64 {
    let clearance = box_distance(node, r.point);
    if clearance <= 0.0 {
        return f64::INFINITY;
    }
    let receiving = (box_extent(node, r.point, r.normal).1 / clearance).clamp(0.0, 1.0);
    let sending = sending.map_or(1.0, |normal| {
        (-box_extent(node, r.point, normal).0 / clearance).clamp(0.0, 1.0)
    });
    weight * receiving * sending / (std::f64::consts::PI * clearance * clearance)
}

/// Which side of the receiver's tangent plane a polygon with `corners`
/// lies on: in front also when it reaches behind by no more than `graze`.
pub fn side(corners: impl IntoIterator<Item = DVec3>, r: &Receiver, graze: f64) -> Side {
    let (mut low, mut high) = (f64::INFINITY, f64::NEG_INFINITY);
    for corner in corners {
        let h = r.normal.dot(corner - r.point);
        low = low.min(h);
        high = high.max(h);
    }
    if high <= 0.0 {
        Side::Behind
    } else if low >= -graze {
        Side::Front
    } else {
        Side::Across
    }
}

/// The factor of a polygon `part` (in front of the receiver, of normal
/// `normal`) as a corrected point source of its area, centroid and
/// covariance ([`PointSource::of_polygon`]).
pub fn polygon_point_factor(part: &[DVec3], normal: DVec3, r: &Receiver) -> f64 {
    PointSource::of_polygon(part, normal).map_or(0.0, |(source, area)| {
        area * source.factor(DVec3::ZERO, r.point, r.normal)
    })
}

#[cfg(test)]
#[path = "transfer_tests.rs"]
mod tests;
