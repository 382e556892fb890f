//! A shooting node's unshot power as a source ([`super`]): its elements'
//! unshot power kept in up to six bins by the dominant axis of their normals
//! (one for a node within one surface), each bin a point source of its
//! power, power-weighted centre, mean normal and second moment, corrected
//! for its extent to second order ([`point_factor`]). Its visibility is a
//! shadow ray from the centre of its element nearest that centre (a point
//! on a real surface, not in the air between a cluster's members).

use std::f64::consts::PI;

use glam::{DMat3, DVec3};

use super::Hierarchy;
use crate::luminance;
use crate::mesh::Mesh;
use crate::scene::Scene;

/// Most bins a node's power is kept in: one per axis and sign of its
/// elements' normals.
pub(crate) const MAX_BINS: usize = 6;

/// The sources of one shot: per node of the shooting subtree (indexed from
/// its root), its power and bins.
#[derive(Clone, Debug, Default)]
pub struct Sources {
    /// Per node, children before parents.
    pub nodes: Vec<NodeSource>,
    /// Their bins.
    pub bins: Vec<Bin>,
}

/// A node's unshot power, in bins by normal direction.
#[derive(Clone, Copy, Debug, Default)]
pub struct NodeSource {
    /// Total luminance power.
    pub weight: f64,
    /// First of its bins in [`Sources::bins`].
    pub first_bin: u32,
    /// Number of its bins.
    pub bins: u8,
}

/// Unshot power of elements whose normals share a dominant axis, with the
/// power-weighted sums that make it a point source with a second-order
/// correction for its extent.
#[derive(Clone, Copy, Debug, Default)]
pub struct Bin {
    /// Power per channel, `sum A_e dB_e`.
    pub power: DVec3,
    /// Luminance of the power: the weight of the sums below.
    pub weight: f64,
    /// Weighted sum of normals.
    pub normal: DVec3,
    /// Weighted sum of element centroids, relative to the shooting node's
    /// centre (so the spread below loses no digits far from the origin).
    pub position: DVec3,
    /// Weighted sum of the outer products of those offsets, each element's
    /// own second moment included.
    pub moment: DMat3,
    /// The element whose centroid the shadow rays start from.
    pub representative: u32,
    /// The dominant axis and sign of its normals (0..6).
    pub axis: u8,
    /// The point source the sums above make, derived from them once all
    /// bins are merged ([`Bin::finished`]) rather than at every receiver.
    pub point: PointSource,
}

/// A bin as [`point_factor`] uses it: its sums divided by its weight.
#[derive(Clone, Copy, Debug, Default)]
pub struct PointSource {
    /// The power-weighted centre, relative to the shooting node's centre.
    pub centre: DVec3,
    /// The unit mean normal.
    pub normal: DVec3,
    /// The length of the weighted mean of the normals (1 for a flat bin,
    /// less where its normals spread).
    pub length: f64,
    /// The covariance of the bin's points about its centre.
    pub covariance: DMat3,
    /// The covariance times the unit mean normal.
    pub spread: DVec3,
    /// The covariance's trace.
    pub trace: f64,
}

impl Bin {
    /// The bin with its [`PointSource`] derived from its sums.
    #[must_use]
    pub fn finished(mut self) -> Bin {
        let w = self.weight;
        let centre = self.position / w;
        let mean_normal = self.normal / w;
        let length = mean_normal.length();
        let covariance = self.moment * (1.0 / w) - outer(centre);
        let normal = mean_normal / length;
        self.point = PointSource {
            centre,
            normal,
            length,
            covariance,
            spread: covariance * normal,
            trace: covariance.x_axis.x + covariance.y_axis.y + covariance.z_axis.z,
        };
        self
    }
}

impl Sources {
    /// Fills the sources and their bins for the nodes of the subtree at `root`,
    /// children before parents.
    pub(crate) fn prepare(
        &mut self,
        scene: &Scene,
        mesh: &Mesh,
        hierarchy: &Hierarchy,
        unshot: &[DVec3],
        root: u32,
    ) {
        let nodes = &hierarchy.tree.nodes;
        let end = nodes[root as usize].end;
        let origin = nodes[root as usize].centre;
        self.nodes.clear();
        self.nodes
            .resize((end - root) as usize, NodeSource::default());
        self.bins.clear();
        let mut merged: Vec<Bin> = Vec::with_capacity(MAX_BINS);
        for n in (root..end).rev() {
            let node = &nodes[n as usize];
            merged.clear();
            if node.is_leaf() {
                let e = hierarchy.tree.items[node.first as usize];
                let element = &mesh.elements[e as usize];
                let power = unshot[e as usize] * element.area;
                let weight = luminance(power);
                if weight > 0.0 {
                    let normal = scene.surfaces[element.surface as usize].normal;
                    let offset = hierarchy.centroids[e as usize] - origin;
                    merged.push(Bin {
                        power,
                        weight,
                        normal: normal * weight,
                        position: offset * weight,
                        moment: (outer(offset) + hierarchy.covariances[e as usize]) * weight,
                        representative: e,
                        axis: axis_of(normal),
                        point: PointSource::default(),
                    });
                }
            } else {
                let a = self.nodes[(n + 1 - root) as usize];
                let b = self.nodes[(node.second - root) as usize];
                let bins_of = |s: &NodeSource| {
                    &self.bins[s.first_bin as usize..s.first_bin as usize + s.bins as usize]
                };
                merge_bins(
                    bins_of(&a),
                    bins_of(&b),
                    &hierarchy.centroids,
                    origin,
                    &mut merged,
                );
            }
            self.nodes[(n - root) as usize] = NodeSource {
                weight: merged.iter().map(|b| b.weight).sum(),
                first_bin: self.bins.len() as u32,
                bins: merged.len() as u8,
            };
            self.bins.extend_from_slice(&merged);
        }
        for bin in &mut self.bins {
            *bin = bin.finished();
        }
    }
}

/// The bin of a normal: the axis and sign of its largest component.
fn axis_of(normal: DVec3) -> u8 {
    let a = normal.abs();
    let axis = if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    };
    2 * axis as u8 + u8::from(normal[axis] < 0.0)
}

/// The bins of a node from its children's (each sorted by axis).
fn merge_bins(a: &[Bin], b: &[Bin], centroids: &[DVec3], origin: DVec3, out: &mut Vec<Bin>) {
    let (mut i, mut j) = (0, 0);
    while i < a.len() || j < b.len() {
        let take_a = j == b.len() || (i < a.len() && a[i].axis < b[j].axis);
        let take_b = i == a.len() || (j < b.len() && b[j].axis < a[i].axis);
        if take_a {
            out.push(a[i]);
            i += 1;
        } else if take_b {
            out.push(b[j]);
            j += 1;
        } else {
            let (x, y) = (&a[i], &b[j]);
            let weight = x.weight + y.weight;
            let position = x.position + y.position;
            let centre = origin + position / weight;
            let nearer = |p: &Bin| centroids[p.representative as usize].distance_squared(centre);
            out.push(Bin {
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
                axis: x.axis,
                point: PointSource::default(),
            });
            i += 1;
            j += 1;
        }
    }
}

/// `v v^T`.
pub fn outer(v: DVec3) -> DMat3 {
    DMat3::from_cols(v * v.x, v * v.y, v * v.z)
}

/// Irradiance at the receiver per unit power of `bin` seen as a point:
/// the kernel `K = cos(theta_s) cos(theta_r) / (pi r^2)` at the bin's
/// centre, times `1 + c`, `c` the second-order term of its Taylor expansion
/// over the bin's points, `tr(H C) / 2K` with `H` the kernel's Hessian in
/// the source point and `C` the covariance of the bin's points (its second
/// moment about its centre). With `d` from the centre to the receiver,
/// `a = s.d`, `b = n_r.d`, `q = d.d` (`s` the source normal, `n_r` the
/// receiver's):
///
/// `c = n_r.C s / (a b) - 4 d.C(a n_r + b s) / (a b q) - 2 tr(C) / q + 12 d.C d / q^2`.
///
/// On the axis of a disk of radius `R` it gives `R^2 / (r^2 + R^2)` to
/// fourth order; a square or a strip seen from three of its radii is within
/// 1.5% of its exact factor, from four within 0.6%, where the plain point
/// errs by several per cent and equation (1) by up to twelve (the test
/// below). This is the accuracy the far-field rules of adaptive shooting
/// rest on ([`super::transfer::FAR_RATIO`],
/// [`super::transfer::QUADRATURE_RATIO`]). Clamped
/// where the expansion fails (a receiver seeing the source almost edge-on,
/// whose factor is then small anyway).
pub fn point_factor(bin: &Bin, origin: DVec3, point: DVec3, normal: DVec3) -> f64 {
    bin.point.factor(origin, point, normal)
}

impl PointSource {
    /// A flat convex polygon with normal `normal` (its corners in either
    /// order) as a point source of uniform power: its centroid, its
    /// covariance and its area, from one pass over its fan of triangles
    /// about the first corner (`(1/12) t (a a^T + b b^T + (a + b)(a + b)^T)`
    /// the second moment of the triangle of area `t` with corners `0, a,
    /// b`). `None` when it has no area.
    #[must_use]
    pub fn of_polygon(polygon: &[DVec3], normal: DVec3) -> Option<(PointSource, f64)> {
        let first = *polygon.first()?;
        let (mut area, mut first_moment, mut moment) = (0.0, DVec3::ZERO, DMat3::ZERO);
        for pair in polygon[1..].windows(2) {
            let (a, b) = (pair[0] - first, pair[1] - first);
            let t = 0.5 * a.cross(b).dot(normal);
            area += t;
            first_moment += (a + b) * (t / 3.0);
            moment += (outer(a) + outer(b) + outer(a + b)) * (t / 12.0);
        }
        if area == 0.0 || !area.is_finite() {
            return None;
        }
        let centre = first_moment / area;
        let covariance = moment * (1.0 / area) - outer(centre);
        Some((
            PointSource {
                centre: first + centre,
                normal,
                length: 1.0,
                covariance,
                spread: covariance * normal,
                trace: covariance.x_axis.x + covariance.y_axis.y + covariance.z_axis.z,
            },
            area.abs(),
        ))
    }

    /// [`point_factor`] of this source, its centre relative to `origin`.
    #[must_use]
    pub fn factor(&self, origin: DVec3, point: DVec3, normal: DVec3) -> f64 {
        let PointSource {
            centre,
            normal: s,
            length,
            covariance,
            spread,
            trace,
        } = *self;
        let d = point - origin - centre;
        let q = d.length_squared();
        if q <= 0.0 || length <= 0.0 {
            return 0.0;
        }
        let (a, b) = (s.dot(d), normal.dot(d));
        if a <= 0.0 || b >= 0.0 {
            return 0.0;
        }
        // `C` is symmetric, so every term takes `C d` and the bin's own `C s`
        // and `tr(C)`: one product of a matrix and a vector, two divisions.
        let cd = covariance * d;
        let (inverse_ab, inverse_q) = (1.0 / (a * b), 1.0 / q);
        let c = (normal.dot(spread) - 4.0 * (a * normal.dot(cd) + b * d.dot(spread)) * inverse_q)
            * inverse_ab
            - (2.0 * trace - 12.0 * d.dot(cd) * inverse_q) * inverse_q;
        -length * a * b * inverse_q * inverse_q * (1.0 + c.clamp(-0.5, 0.5)) / PI
    }
}

#[cfg(test)]
mod tests {
    use super::super as hierarchy;
    use super::*;

    /// Numbers in `[0, 1)` from a xorshift generator seeded with `seed`.
    fn uniform(mut seed: u64) -> impl FnMut() -> f64 {
        move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// A direction from a source in the plane `z = 0` into the half space
    /// it faces (at least a little above the plane), and a receiver normal
    /// in any direction, drawn from `random` in that order.
    fn direction_and_normal(random: &mut impl FnMut() -> f64) -> (DVec3, DVec3) {
        let direction =
            DVec3::new(random() - 0.5, random() - 0.5, random() * 0.9 + 0.1).normalize();
        let normal = DVec3::new(random() - 0.5, random() - 0.5, random() - 0.5).normalize_or_zero();
        (direction, normal)
    }

    /// A `2 hx` by `2 hy` rectangle in the plane `z = 0` facing `+z`, its
    /// area, and the bin of its uniform unit power.
    fn rectangle_bin(hx: f64, hy: f64) -> ([DVec3; 4], f64, Bin) {
        let rectangle = [
            DVec3::new(-hx, -hy, 0.0),
            DVec3::new(hx, -hy, 0.0),
            DVec3::new(hx, hy, 0.0),
            DVec3::new(-hx, hy, 0.0),
        ];
        let area = 4.0 * hx * hy;
        let bin = Bin {
            power: DVec3::splat(area),
            weight: area,
            normal: DVec3::Z * area,
            position: DVec3::ZERO,
            moment: hierarchy::second_moment(&rectangle, DVec3::ZERO) * area,
            representative: 0,
            axis: 4,
            point: PointSource::default(),
        }
        .finished();
        (rectangle, area, bin)
    }

    /// The corrected point source against the exact factor (the analytic
    /// formula) of a square and of a 4:1 strip, from three to twelve of
    /// their radii, in random directions and receiver orientations (facing
    /// the source, or tilted as far as a floor under a ceiling lamp): within
    /// the bounds [`point_factor`] states, where the plain point formula
    /// errs by several per cent.
    #[test]
    fn corrected_point_source_matches_the_exact_factor() {
        let mut random = uniform(0x9e37_79b9_7f4a_7c15);
        for (hx, hy) in [(0.5, 0.5), (1.0, 0.25)] {
            let (rectangle, area, bin) = rectangle_bin(hx, hy);
            let radius = (hx * hx + hy * hy).sqrt();
            let (mut worst, mut worst_near, mut worst_plain): (f64, f64, f64) = (0.0, 0.0, 0.0);
            let mut tested = 0;
            while tested < 400 {
                let direction =
                    DVec3::new(random() - 0.5, random() - 0.5, random() * 0.9 + 0.1).normalize();
                let distance = radius * (3.0 + 9.0 * random());
                let point = direction * distance;
                // Half the receivers face the source, half face the source's
                // plane (a floor under a lamp), each tilted at random.
                let facing = if tested % 2 == 0 {
                    -direction
                } else {
                    -DVec3::Z
                };
                let normal = (facing
                    + 0.5 * DVec3::new(random() - 0.5, random() - 0.5, random() - 0.5))
                .normalize();
                let exact = crate::form_factor::analytic(point, normal, &rectangle);
                if exact < 0.1 * area / (PI * distance * distance) {
                    continue;
                }
                let corrected = area * point_factor(&bin, DVec3::ZERO, point, normal);
                let d = point.normalize();
                let plain = area * d.z * (-normal.dot(d)).max(0.0) / (PI * distance * distance);
                if distance >= 4.0 * radius {
                    worst = worst.max((corrected / exact - 1.0).abs());
                } else {
                    worst_near = worst_near.max((corrected / exact - 1.0).abs());
                }
                worst_plain = worst_plain.max((plain / exact - 1.0).abs());
                tested += 1;
            }
            assert!(
                worst < 6e-3,
                "{hx} x {hy}: beyond four radii, errs by {worst}"
            );
            assert!(
                worst_near < 1.5e-2,
                "{hx} x {hy}: at three radii, errs by {worst_near}"
            );
            assert!(
                worst_plain > 3e-2,
                "{hx} x {hy}: plain point source errs by {worst_plain}"
            );
        }
    }

    /// A far element at a grazing angle to the receiver's tangent plane,
    /// its corners all in front of it or reaching behind by no more than
    /// [`GRAZE`](super::super::transfer::GRAZE) of its radius
    /// ([`super::super::transfer::Side::Front`]): its corrected point
    /// source, unclipped, errs by little against the factor it could send
    /// head on, and by more where it reaches further behind.
    #[test]
    fn a_grazing_element_in_front_is_a_point_source() {
        let graze = super::super::transfer::GRAZE;
        let mut random = uniform(0x2545_f491_4f6c_dd1d);
        let (hx, hy) = (1.0, 0.25);
        let (rectangle, area, bin) = rectangle_bin(hx, hy);
        let radius = (hx * hx + hy * hy).sqrt();
        // The worst error where the element reaches behind by at most
        // `graze` of its radius, and by one to four times that.
        let (mut worst, mut worst_beyond, mut tested) = (0.0f64, 0.0f64, 0);
        while tested < 4000 {
            let (direction, normal) = direction_and_normal(&mut random);
            // The receiver moved along its normal until the lowest corner
            // is `reach` behind its plane (in front where negative).
            let beyond = tested % 2 == 1;
            let reach = if beyond {
                (1.0 + 3.0 * random()) * graze * radius
            } else {
                (2.0 * random() - 1.0) * graze * radius
            };
            let start = direction * radius * (4.0 + 8.0 * random());
            let lowest = rectangle
                .iter()
                .map(|&c| normal.dot(c - start))
                .fold(f64::INFINITY, f64::min);
            let point = start + normal * (lowest + reach);
            let distance = point.length();
            if distance < 4.0 * radius || normal.dot(-point).abs() >= radius {
                continue;
            }
            let exact = crate::form_factor::analytic(point, normal, &rectangle);
            let corrected = area * point_factor(&bin, DVec3::ZERO, point, normal);
            let error = (corrected - exact).abs() / (area / (PI * distance * distance));
            if beyond {
                worst_beyond = worst_beyond.max(error);
            } else {
                worst = worst.max(error);
            }
            tested += 1;
        }
        assert!(worst < 3e-3, "errs by {worst} of the head-on factor");
        assert!(
            worst_beyond > worst,
            "errs by {worst_beyond} reaching further behind, {worst} within"
        );
    }

    /// A polygon's own point source ([`PointSource::of_polygon`]) is the
    /// one its bin makes, whichever way its corners run.
    #[test]
    fn a_polygon_is_the_point_source_its_bin_makes() {
        let (rectangle, area, bin) = rectangle_bin(1.0, 0.25);
        let shifted = rectangle.map(|c| c + DVec3::new(0.3, -0.2, 0.0));
        let mut reversed = shifted;
        reversed.reverse();
        for corners in [shifted, reversed] {
            let (source, a) = PointSource::of_polygon(&corners, DVec3::Z).unwrap();
            assert!((a - area).abs() < 1e-12);
            assert!((source.centre - DVec3::new(0.3, -0.2, 0.0)).length() < 1e-12);
            let difference = source.covariance - bin.point.covariance;
            assert!(difference.to_cols_array().iter().all(|x| x.abs() < 1e-12));
        }
        assert!(PointSource::of_polygon(&rectangle[..2], DVec3::Z).is_none());
    }

    /// A far element that the receiver's tangent plane cuts, deeper than
    /// [`GRAZE`](super::super::transfer::GRAZE): the part in front as a
    /// corrected point source ([`PointSource::of_polygon`]) against its
    /// exact factor, clipped, for a square and a 4:1 strip from four to
    /// twelve of their radii: within a little of the factor it would have
    /// head on, where the midpoint rule over that part errs by more.
    #[test]
    fn the_part_in_front_of_a_cut_element_is_a_point_source() {
        let graze = super::super::transfer::GRAZE;
        let mut random = uniform(0x6a09_e667_f3bc_c909);
        let mut clipped = Vec::new();
        for (hx, hy) in [(0.5, 0.5), (1.0, 0.25)] {
            let (rectangle, area, _) = rectangle_bin(hx, hy);
            let radius = (hx * hx + hy * hy).sqrt();
            let (mut worst, mut worst_midpoint, mut tested) = (0.0f64, 0.0f64, 0);
            while tested < 4000 {
                let (direction, normal) = direction_and_normal(&mut random);
                let point = direction * radius * (4.0 + 8.0 * random());
                let heights = rectangle.map(|c| normal.dot(c - point));
                let low = heights.iter().copied().fold(f64::INFINITY, f64::min);
                let high = heights.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                if low >= -graze * radius || high <= 0.0 {
                    continue;
                }
                let exact = crate::form_factor::analytic(point, normal, &rectangle);
                crate::geometry::clip_to_half_space(&rectangle, point, normal, 0.0, &mut clipped);
                let (source, part) = PointSource::of_polygon(&clipped, DVec3::Z).unwrap();
                let corrected = part * source.factor(DVec3::ZERO, point, normal);
                let d = point - source.centre;
                let q = d.length_squared();
                let midpoint = part * d.z * (-normal.dot(d)).max(0.0) / (PI * q * q);
                let head_on = area / (PI * point.length_squared());
                worst = worst.max((corrected - exact).abs() / head_on);
                worst_midpoint = worst_midpoint.max((midpoint - exact).abs() / head_on);
                tested += 1;
            }
            assert!(
                worst < 2e-3,
                "{hx} x {hy}: errs by {worst} of the head-on factor"
            );
            assert!(
                worst_midpoint > 5.0 * worst,
                "{hx} x {hy}: the midpoint rule errs by {worst_midpoint}, {worst} corrected"
            );
        }
    }
}
