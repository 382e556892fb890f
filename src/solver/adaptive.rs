//! Adaptive shooting, beyond the paper: shooters carry their radiosity at
//! element resolution and each receiver refines the shooter until the part
//! it takes as one source is accurate for it.
//!
//! The paper's patches shoot one uniform unshot radiosity, so a receiver
//! near a large patch whose radiosity varies across it (a wall brighter near
//! the light) gets the patch's average. Here:
//!
//! * **Unshot radiosity per element.** An element's share of a shot is the
//!   mean of its vertices' irradiance times its reflectance; a shooter sends
//!   each element's own unshot radiosity. Book-keeping is exact: the power
//!   shot, received, absorbed and reflected balance to round-off
//!   ([`super::Energy`]).
//! * **Shooters from the source hierarchy** ([`super::hierarchy`]): the
//!   largest clusters of elements no bigger than the patch size, chosen by
//!   unshot power as in Wallace et al. (1989) and Cohen et al. (1988).
//! * **Per-receiver refinement** (the adaptive source subdivision of Wallace,
//!   Elmquist & Haines 1989, section 4, with the error estimate of
//!   hierarchical radiosity, Hanrahan, Salzman & Aupperle 1991): walking the
//!   shooter's tree from its root, a receiver accepts a node as one source
//!   when the irradiance it can send is negligible (below
//!   `tolerance x` the scene's mean radiosity, bounded from the node's
//!   bounding sphere), or when the receiver is more than [`FAR_RATIO`] of
//!   the node's radius away and the irradiance is below [`FAR_FACTOR`] times
//!   that; otherwise it visits the node's children. Elements are the finest
//!   sources: the analytic factor of the paper's equation (2) on the
//!   element's polygon (clipped to the receiver's front), a shadow ray from
//!   its centre. So the near field sees element resolution and the far field
//!   a few sources.
//! * **A node as a source.** Its elements' unshot power is kept in up to six
//!   bins by the dominant axis of their normals (one for a node within one
//!   surface): each bin is a disk-like source of its area, power,
//!   power-weighted centre and mean normal, seen through Wallace's equation
//!   (1), `dE = P cos(theta_s) cos(theta_r) / (pi r^2 + A)`, its visibility
//!   a shadow ray from the centre of its element nearest that centre (a
//!   point on a real surface, not in the air between a cluster's members).

use std::f64::consts::PI;
use std::time::{Duration, Instant};

use glam::DVec3;
use rayon::prelude::*;

use super::hierarchy::{Hierarchy, NONE, Node};
use super::{Received, Receiver, Settings, Shot, ShotInputs, Stats};
use crate::accel::{self, Occluder};
use crate::form_factor::{FormFactor, Source};
use crate::geometry;
use crate::luminance;
use crate::mesh::Mesh;
use crate::scene::Scene;

/// A node is far from a receiver beyond this many of its radii: a disk seen
/// from three radii is within a few per cent of equation (1).
pub const FAR_RATIO: f64 = 3.0;

/// A far node is accepted while the irradiance it can send is below this
/// many times the negligible irradiance.
pub const FAR_FACTOR: f64 = 30.0;

/// An accepted node's geometry is integrated over pieces at least this
/// many of their radii from the receiver, each a corrected point source
/// ([`point_factor`]).
pub const QUADRATURE_RATIO: f64 = 4.0;

/// Receivers handled together by one task.
const RECEIVERS_PER_CHUNK: usize = 64;

/// The state of adaptive shooting.
pub(crate) struct AdaptiveShooting {
    hierarchy: Hierarchy,
    /// Unshot radiosity of each element.
    unshot: Vec<DVec3>,
    /// Unshot power (luminance) of each shooter.
    shooter_power: Vec<f64>,
    /// Irradiance (luminance, W/m^2) a source may send and still be
    /// accepted whole: the tolerance times the scene's mean radiosity, or
    /// times a receiver's irradiance so far where that is larger.
    negligible: f64,
    /// The scene's mean radiosity, estimated (luminance).
    mean_radiosity: f64,
    /// Per-node source data of the current shot, reused.
    sources: Vec<NodeSource>,
}

/// Up to six bins of unshot power by normal direction.
#[derive(Clone, Copy, Debug, Default)]
struct NodeSource {
    bins: [Bin; 6],
    /// Bins in use, a bit each.
    used: u8,
    /// Total luminance power.
    weight: f64,
}

/// Unshot power of elements whose normals share a dominant axis, with the
/// power-weighted sums that make it a point source with a second-order
/// correction for its extent.
#[derive(Clone, Copy, Debug, Default)]
struct Bin {
    /// Power per channel, `sum A_e dB_e`.
    power: DVec3,
    /// Luminance of the power: the weight of the sums below.
    weight: f64,
    /// Weighted sum of normals.
    normal: DVec3,
    /// Weighted sum of element centroids, relative to the shooter's centre
    /// (so the spread below loses no digits far from the origin).
    position: DVec3,
    /// Weighted sum of squared distances from the shooter's centre, each
    /// element's own spread included.
    moment: f64,
    /// The element whose centroid the shadow rays start from.
    representative: u32,
}

impl AdaptiveShooting {
    /// Unshot radiosity `E` on every element; the hierarchy over the mesh.
    pub(crate) fn new(scene: &Scene, mesh: &Mesh, settings: &Settings) -> AdaptiveShooting {
        let hierarchy = Hierarchy::build(scene, mesh, settings.mesh.patch_size);
        let unshot: Vec<DVec3> = mesh
            .elements
            .iter()
            .map(|e| scene.surfaces[e.surface as usize].emission)
            .collect();
        // The mean radiosity of the converged solution, estimated from the
        // emitted power and the mean reflectance as the ambient term is.
        let (mut area, mut power, mut rho) = (0.0, 0.0, 0.0);
        for (e, u) in mesh.elements.iter().zip(&unshot) {
            area += e.area;
            power += luminance(*u) * e.area;
            rho += luminance(scene.surfaces[e.surface as usize].rho) * e.area;
        }
        let mean_radiosity = if area > 0.0 {
            power / area / (1.0 - rho / area).max(1e-3)
        } else {
            0.0
        };
        let mut shooting = AdaptiveShooting {
            shooter_power: vec![0.0; hierarchy.shooters.len()],
            hierarchy,
            unshot,
            negligible: settings.tolerance * mean_radiosity,
            mean_radiosity: mean_radiosity.max(f64::MIN_POSITIVE),
            sources: Vec::new(),
        };
        shooting.total_shooter_power(mesh);
        shooting
    }

    /// Number of shooters.
    pub(crate) fn shooters(&self) -> usize {
        self.hierarchy.shooters.len()
    }

    /// Unshot power, per channel.
    pub(crate) fn unshot_power(&self, mesh: &Mesh) -> DVec3 {
        mesh.elements
            .iter()
            .zip(&self.unshot)
            .map(|(e, u)| *u * e.area)
            .sum()
    }

    fn total_shooter_power(&mut self, mesh: &Mesh) {
        self.shooter_power.fill(0.0);
        for ((e, u), s) in mesh
            .elements
            .iter()
            .zip(&self.unshot)
            .zip(&self.hierarchy.shooter_of)
        {
            self.shooter_power[*s as usize] += luminance(*u) * e.area;
        }
    }

    /// Adds the reflected part of what the elements received to their
    /// unshot radiosity.
    pub(crate) fn receive(&mut self, scene: &Scene, mesh: &Mesh, irradiance: &[DVec3]) -> Received {
        let unshot = &mut self.unshot;
        let received = super::receive_at_elements(scene, mesh, irradiance, |e, radiosity| {
            unshot[e] += radiosity;
        });
        self.total_shooter_power(mesh);
        received
    }

    /// One shot of the shooter with the most unshot power; its elements'
    /// unshot radiosity is zeroed.
    pub(crate) fn shoot(&mut self, inputs: &ShotInputs<'_>, stats: &mut Stats) -> Shot {
        let start = Instant::now();
        let (scene, mesh) = (inputs.scene, inputs.mesh);
        let shooter = self
            .shooter_power
            .iter()
            .enumerate()
            .fold((0, f64::NEG_INFINITY), |best, (i, &p)| {
                if p > best.1 { (i, p) } else { best }
            })
            .0;
        let root = self.hierarchy.shooters[shooter];
        self.prepare_sources(scene, mesh, root);
        let mut power = DVec3::ZERO;
        let mut elements = 0u64;
        for &e in self.hierarchy.elements_of(root) {
            power += self.unshot[e as usize] * mesh.elements[e as usize].area;
            elements += 1;
        }

        let gather_start = Instant::now();
        let context = Gatherer {
            scene,
            mesh,
            hierarchy: &self.hierarchy,
            unshot: &self.unshot,
            sources: &self.sources,
            root,
            origin: self.hierarchy.nodes[root as usize].centre,
            occluder: inputs.occluder,
            form_factor: inputs.settings.form_factor,
            negligible: self.negligible,
            mean_radiosity: self.mean_radiosity,
        };
        let gathered: Vec<(Vec<DVec3>, Counters)> = inputs
            .receivers
            .par_chunks(RECEIVERS_PER_CHUNK)
            .zip(inputs.irradiance.par_chunks(RECEIVERS_PER_CHUNK))
            .map(|(chunk, irradiance)| context.gather_chunk(chunk, irradiance))
            .collect();
        let gather_end = Instant::now();

        let mut irradiance = Vec::with_capacity(inputs.receivers.len());
        for (chunk, counters) in gathered {
            irradiance.extend(chunk);
            stats.pairs += counters.pairs;
            stats.rays_cast += counters.rays;
            stats.pretest_time += counters.refine;
            stats.ray_time += counters.ray_time;
            stats.form_factor_time += counters.form_factor_time;
        }
        for &e in self.hierarchy.elements_of(root) {
            self.unshot[e as usize] = DVec3::ZERO;
        }
        stats.subsources += elements;
        stats.gather_time += gather_end - gather_start;
        if std::env::var("RAD_DEBUG").is_ok() {
            let node = &self.hierarchy.nodes[root as usize];
            eprintln!(
                "shot {} shooter {shooter} elements {elements} radius {:.2} group {} power {:.3e} rays {} time {:.2}s",
                stats.shots,
                node.radius,
                node.group,
                luminance(power),
                stats.rays_cast,
                (gather_end - gather_start).as_secs_f64()
            );
        }
        Shot {
            irradiance,
            power,
            selection_time: gather_start - start,
        }
    }

    /// Fills `sources` for the nodes of the subtree at `root`, children
    /// before parents.
    fn prepare_sources(&mut self, scene: &Scene, mesh: &Mesh, root: u32) {
        let nodes = &self.hierarchy.nodes;
        let end = nodes[root as usize].end;
        let origin = nodes[root as usize].centre;
        let count = (end - root) as usize;
        self.sources.clear();
        self.sources.resize(count, NodeSource::default());
        for n in (root..end).rev() {
            let node = &nodes[n as usize];
            let source = if node.is_leaf() {
                let e = self.hierarchy.elements[node.first as usize];
                let element = &mesh.elements[e as usize];
                let unshot = self.unshot[e as usize];
                let power = unshot * element.area;
                let weight = luminance(power);
                let mut source = NodeSource::default();
                if weight > 0.0 {
                    let normal = scene.surfaces[element.surface as usize].normal;
                    let offset = self.hierarchy.centroids[e as usize] - origin;
                    let b = bin_of(normal);
                    source.bins[b] = Bin {
                        power,
                        weight,
                        normal: normal * weight,
                        position: offset * weight,
                        moment: (offset.length_squared() + self.hierarchy.spreads[e as usize])
                            * weight,
                        representative: e,
                    };
                    source.used = 1 << b;
                    source.weight = weight;
                }
                source
            } else {
                let a = self.sources[(n + 1 - root) as usize];
                let b = self.sources[(node.second - root) as usize];
                merge_sources(&a, &b, &self.hierarchy.centroids, origin)
            };
            self.sources[(n - root) as usize] = source;
        }
    }
}

/// The bin of a normal: the axis and sign of its largest component.
fn bin_of(normal: DVec3) -> usize {
    let a = normal.abs();
    let axis = if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    };
    2 * axis + usize::from(normal[axis] < 0.0)
}

/// The source of a node from its children's.
fn merge_sources(a: &NodeSource, b: &NodeSource, centroids: &[DVec3], origin: DVec3) -> NodeSource {
    let mut out = NodeSource {
        used: a.used | b.used,
        weight: a.weight + b.weight,
        ..NodeSource::default()
    };
    for k in 0..6 {
        let (x, y) = (&a.bins[k], &b.bins[k]);
        out.bins[k] = match (a.used & (1 << k) != 0, b.used & (1 << k) != 0) {
            (false, false) => continue,
            (true, false) => *x,
            (false, true) => *y,
            (true, true) => {
                let weight = x.weight + y.weight;
                let position = x.position + y.position;
                let centre = origin + position / weight;
                let nearer =
                    |p: &Bin| centroids[p.representative as usize].distance_squared(centre);
                Bin {
                    power: x.power + y.power,
                    weight,
                    normal: x.normal + y.normal,
                    position,
                    moment: x.moment + y.moment,
                    representative: if nearer(y) < nearer(x) {
                        y.representative
                    } else {
                        x.representative
                    },
                }
            }
        };
    }
    out
}

/// Irradiance at the receiver per unit power of `bin` seen as a point:
/// `cos(theta_s) cos(theta_r) / (pi r^2)`, times `1 + c` where `c` is the
/// second-order term of the kernel's Taylor expansion over a flat source of
/// polar second moment `M` per unit power about its centre (taken
/// isotropic): `c = (2 M / r^2) (1 - 3 cos^2(theta_s) - (n_r . s) cos(theta_s)
/// / cos(theta_r))` with `s` the source normal. On the axis of a disk of
/// radius `R` it gives `R^2 / (r^2 + R^2)` to fourth order; seen from three
/// of its radii a square is within 0.3% of its exact factor, where the plain
/// point errs by 7% and equation (1) by 12% (tested). Clamped where the
/// expansion fails (a receiver seeing the source almost edge-on, whose factor
/// is then small anyway).
fn point_factor(bin: &Bin, origin: DVec3, r: &Receiver) -> f64 {
    let w = bin.weight;
    let centre = bin.position / w;
    let d = r.point - origin - centre;
    let r2 = d.length_squared();
    let mean_normal = bin.normal / w;
    let length = mean_normal.length();
    if r2 <= 0.0 || length <= 0.0 {
        return 0.0;
    }
    let distance = r2.sqrt();
    let direction = d / distance;
    let s = mean_normal / length;
    let cos_s = s.dot(direction);
    let cos_r = -r.normal.dot(direction);
    if cos_s <= 0.0 || cos_r <= 0.0 {
        return 0.0;
    }
    let spread = (bin.moment / w - centre.length_squared()).max(0.0);
    let bracket = 1.0 - 3.0 * cos_s * cos_s - r.normal.dot(s) * cos_s / cos_r;
    let correction = (2.0 * spread / r2 * bracket).clamp(-0.5, 0.5);
    length * cos_s * cos_r / (PI * r2) * (1.0 + correction)
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

/// Counters of one chunk of receivers.
#[derive(Clone, Copy, Debug, Default)]
struct Counters {
    pairs: u64,
    rays: u64,
    refine: Duration,
    ray_time: Duration,
    form_factor_time: Duration,
}

/// Everything a receiver needs to gather from the shooter.
struct Gatherer<'s> {
    scene: &'s Scene,
    mesh: &'s Mesh,
    hierarchy: &'s Hierarchy,
    unshot: &'s [DVec3],
    sources: &'s [NodeSource],
    root: u32,
    /// The shooter's centre, the origin of the bins' sums.
    origin: DVec3,
    occluder: &'s dyn Occluder,
    form_factor: FormFactor,
    /// Negligible irradiance for a receiver with no more than the mean
    /// radiosity.
    negligible: f64,
    mean_radiosity: f64,
}

impl Gatherer<'_> {
    fn gather_chunk(&self, receivers: &[Receiver], irradiance: &[DVec3]) -> (Vec<DVec3>, Counters) {
        let start = Instant::now();
        let mut counters = Counters::default();
        let mut scratch = Scratch::default();
        let out = receivers
            .iter()
            .zip(irradiance)
            .map(|(r, e)| {
                // Errors are weighed against what the receiver has already
                // gathered (or, before it has, the scene's mean radiosity):
                // a bright source is shot carefully everywhere, a dim one
                // coarsely where it adds little to what is there.
                let negligible = self.negligible * (luminance(*e) / self.mean_radiosity).max(1.0);
                self.gather(r, negligible, &mut scratch, &mut counters)
            })
            .collect();
        // Rays and factors are timed where they are cast; the rest is the
        // walk choosing the sources.
        counters.refine = start
            .elapsed()
            .saturating_sub(counters.ray_time + counters.form_factor_time);
        (out, counters)
    }

    /// The irradiance the shooter sends to one receiver.
    fn gather(
        &self,
        r: &Receiver,
        negligible: f64,
        scratch: &mut Scratch,
        counters: &mut Counters,
    ) -> DVec3 {
        let Scratch {
            stack,
            pieces,
            polygon,
            clipped,
        } = scratch;
        let nodes = &self.hierarchy.nodes;
        let mut sum = DVec3::ZERO;
        stack.clear();
        stack.push(self.root);
        while let Some(n) = stack.pop() {
            let node = &nodes[n as usize];
            let source = &self.sources[(n - self.root) as usize];
            if source.weight <= 0.0 || !self.faces(node, r) {
                continue;
            }
            if node.is_leaf() {
                let e = self.hierarchy.elements[node.first as usize];
                sum += self.element_irradiance(e, r, polygon, clipped, counters);
                continue;
            }
            let distance = node.centre.distance(r.point);
            if distance < FAR_RATIO * node.radius {
                // Near: accepted whole only if even all its power at the
                // nearest point of its bounding sphere would be negligible.
                let clearance = distance - node.radius;
                if clearance > 0.0 && source.weight <= negligible * PI * clearance * clearance {
                    sum += self.bins_irradiance(n, source, r, pieces, polygon, counters);
                    continue;
                }
            } else {
                // Far: the corrected point sources are accurate; what is
                // left to judge is occlusion.
                let estimate: f64 = (0..6)
                    .filter(|k| source.used & (1 << k) != 0)
                    .map(|k| {
                        let bin = &source.bins[k];
                        bin.weight * point_factor(bin, self.origin, r)
                    })
                    .sum();
                if estimate <= FAR_FACTOR * negligible {
                    sum += self.bins_irradiance(n, source, r, pieces, polygon, counters);
                    continue;
                }
                if let Some(visible) = self.uniform_visibility(n, r, counters) {
                    if visible {
                        let geometry = self.node_geometry(n, r, pieces, polygon, counters);
                        sum += geometry.iter().sum::<DVec3>();
                    }
                    continue;
                }
            }
            stack.push(node.second);
            stack.push(n + 1);
        }
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
        let e = self.hierarchy.elements[node.first as usize];
        let surface = &self.scene.surfaces[self.mesh.elements[e as usize].surface as usize];
        surface.normal.dot(r.point) - surface.offset > 0.0
    }

    /// A node as up to six sources by normal direction, each behind one
    /// shadow ray from its representative element's centre.
    fn bins_irradiance(
        &self,
        n: u32,
        source: &NodeSource,
        r: &Receiver,
        pieces: &mut Vec<u32>,
        polygon: &mut Vec<DVec3>,
        counters: &mut Counters,
    ) -> DVec3 {
        let geometry = self.node_geometry(n, r, pieces, polygon, counters);
        let mut sum = DVec3::ZERO;
        for (k, bin) in source.bins.iter().enumerate() {
            if source.used & (1 << k) == 0 || geometry[k] == DVec3::ZERO {
                continue;
            }
            counters.pairs += 1;
            if self.visible_from(bin.representative, r, counters) {
                sum += geometry[k];
            }
        }
        sum
    }

    /// Whether the receiver sees all of a node or none of it, judged by
    /// shadow rays from up to four points spread over it (the
    /// representatives of its grandchildren, or children where the tree
    /// ends); `None` when they disagree, and the node must be refined. A
    /// bright source's node is accepted this way only in full view or full
    /// shadow, so penumbrae are resolved down to elements while open view
    /// costs four rays.
    fn uniform_visibility(&self, n: u32, r: &Receiver, counters: &mut Counters) -> Option<bool> {
        let nodes = &self.hierarchy.nodes;
        let node = &nodes[n as usize];
        let mut samples = [NONE; 4];
        let mut count = 0;
        for child in [n + 1, node.second] {
            let c = &nodes[child as usize];
            if c.is_leaf() {
                samples[count] = child;
                count += 1;
            } else {
                samples[count] = child + 1;
                samples[count + 1] = c.second;
                count += 2;
            }
        }
        let mut seen = None;
        for &piece in &samples[..count] {
            let source = &self.sources[(piece - self.root) as usize];
            let Some(bin) = (0..6)
                .filter(|k| source.used & (1 << k) != 0)
                .map(|k| &source.bins[k])
                .max_by(|a, b| a.weight.total_cmp(&b.weight))
            else {
                continue;
            };
            counters.pairs += 1;
            let visible = self.visible_from(bin.representative, r, counters);
            match seen {
                None => seen = Some(visible),
                Some(v) if v != visible => return None,
                Some(_) => {}
            }
        }
        seen
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
        pieces: &mut Vec<u32>,
        polygon: &mut Vec<DVec3>,
        counters: &mut Counters,
    ) -> [DVec3; 6] {
        let nodes = &self.hierarchy.nodes;
        let t0 = Instant::now();
        let mut geometry = [DVec3::ZERO; 6];
        pieces.clear();
        pieces.push(n);
        while let Some(piece) = pieces.pop() {
            let node = &nodes[piece as usize];
            let near =
                r.point.distance_squared(node.centre) < (QUADRATURE_RATIO * node.radius).powi(2);
            if near && !node.is_leaf() {
                pieces.push(node.second);
                pieces.push(piece + 1);
                continue;
            }
            let sub = &self.sources[(piece - self.root) as usize];
            if near {
                // An element close by: its exact factor.
                let e = self.hierarchy.elements[node.first as usize];
                let k = sub.used.trailing_zeros() as usize;
                if k < 6 {
                    geometry[k] += self.element_factor(e, r, polygon) * self.unshot[e as usize];
                }
                continue;
            }
            for (k, bin) in sub.bins.iter().enumerate() {
                if sub.used & (1 << k) != 0 {
                    geometry[k] += bin.power * point_factor(bin, self.origin, r);
                }
            }
        }
        counters.form_factor_time += t0.elapsed();
        geometry
    }

    /// One element as a source: its polygon's factor (clipped to the
    /// receiver's front) and a shadow ray from the centre of the part in
    /// front.
    fn element_irradiance(
        &self,
        e: u32,
        r: &Receiver,
        polygon: &mut Vec<DVec3>,
        clipped: &mut Vec<DVec3>,
        counters: &mut Counters,
    ) -> DVec3 {
        let element = &self.mesh.elements[e as usize];
        let surface = &self.scene.surfaces[element.surface as usize];
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
        let centroid = self.hierarchy.centroids[e as usize];
        let origin = if all_front {
            centroid
        } else {
            geometry::clip_to_half_space(polygon, r.point, r.normal, 0.0, clipped);
            if geometry::area(clipped) <= 0.0 {
                return DVec3::ZERO;
            }
            geometry::centroid(clipped)
        };
        counters.pairs += 1;
        if !self.visible(origin, r, surface.group, counters) {
            return DVec3::ZERO;
        }
        let t0 = Instant::now();
        let factor = self.form_factor.evaluate(
            r.point,
            r.normal,
            &Source {
                polygon,
                centroid,
                normal: surface.normal,
                area: element.area,
            },
        );
        counters.form_factor_time += t0.elapsed();
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
        let t0 = Instant::now();
        let (from, to) = accel::shorten(origin, r.point);
        let blocked = self.occluder.occluded(from, to, [group, r.group]);
        counters.rays += 1;
        counters.ray_time += t0.elapsed();
        !blocked
    }
}
