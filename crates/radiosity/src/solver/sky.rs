//! The sky's irradiance at a receiver: what a sky ([`crate::scene::sky`])
//! sends through openings ([`crate::scene::portal`]) and over the rest of
//! its dome and the ground, as unblocked irradiances each with the far end
//! of its shadow segment. Beyond the paper, whose sources are surfaces.
//!
//! One estimator for every receiver (vertices, sensors, texels): the
//! directions are split between the *active* portals (the openings in
//! front of the receiver that pass the most light, at most
//! [`MAX_ACTIVE`]) and the rest of the sky. Each active portal is sampled
//! uniformly in the solid angle it subtends (stratified, Arvo 1995),
//! counting only the directions for which it is the nearest active portal
//! crossed; the rest is sampled as before, one direction in each of the
//! sky's patches (and the ground's), counting only directions that cross no
//! active portal. Every direction is counted by exactly one of the two, so
//! the estimate is unbiased whatever the portals; where daylight comes in
//! through openings (a window, a skylight, a slit, a courtyard) it is
//! sampled where it is, not found by a handful of patches that happen to
//! see it. Random numbers come from a generator seeded by the receiver's
//! index: the same answer on any number of threads.

use glam::DVec3;

use crate::accel::Occluder;
use crate::geometry::{self, spherical};
use crate::scene::portal::{self, Portal};
use crate::scene::sky::{self, Patch};
use crate::scene::{Light, LightKind, Scene};

/// Most portals sampled at one receiver: those that pass it the most.
pub const MAX_ACTIVE: usize = 16;

/// Directions drawn through a receiver's active portals, shared among them
/// by the light each passes (at least [`MIN_PORTAL_RAYS`] each).
pub const PORTAL_RAYS: usize = 64;

/// Points per side of the midpoint rule that integrates a portal's
/// unblocked light over each of its spherical triangles.
const QUADRATURE: usize = 16;

/// Fewest directions drawn through an active portal.
pub const MIN_PORTAL_RAYS: usize = 4;

/// A portal's convex piece, with what the crossing test needs.
struct Piece {
    corners: Vec<DVec3>,
    normal: DVec3,
}

/// A portal prepared for many receivers.
struct Prepared {
    pieces: Vec<Piece>,
    centre: DVec3,
    radius: f64,
}

/// What a sky needs at every receiver: its patches, the ground's, and the
/// scene's openings.
pub struct SkyPlan {
    patches: Vec<Patch>,
    ground: Vec<Patch>,
    portals: Vec<Prepared>,
}

/// A portal as one receiver sees it: the spherical triangles of its pieces
/// clipped to the receiver's front, their cumulative solid angles, and the
/// pieces for the nearest-portal test.
struct Active {
    triangles: Vec<[DVec3; 3]>,
    cumulative: Vec<f64>,
    pieces: Vec<Piece>,
    power: f64,
    /// A cone holding every direction through it: its axis and the cosine
    /// of its half-angle (-1: the whole sphere).
    axis: DVec3,
    cos_half: f64,
}

impl Active {
    /// Whether `towards` may cross the portal: inside its cone.
    fn may_cross(&self, towards: DVec3) -> bool {
        towards.dot(self.axis) >= self.cos_half
    }

    /// Where the ray from `point` along `towards` crosses it, if it does.
    fn crossing(&self, point: DVec3, towards: DVec3) -> Option<f64> {
        if self.may_cross(towards) {
            crossing(&self.pieces, point, towards)
        } else {
            None
        }
    }

    /// Whether some direction may cross both this portal and `other`.
    fn overlaps(&self, other: &Active) -> bool {
        if self.cos_half <= 0.0 || other.cos_half <= 0.0 {
            return true;
        }
        let between = self.axis.dot(other.axis).clamp(-1.0, 1.0).acos();
        between <= self.cos_half.acos() + other.cos_half.acos()
    }
}

impl SkyPlan {
    /// The plan for `light` if it is a sky: its patches and the openings of
    /// `scene` (found with `occluder`); `None` for any other light.
    #[must_use]
    pub fn new(light: &Light, scene: &Scene, occluder: &dyn Occluder) -> Option<SkyPlan> {
        let LightKind::Sky { sky, subdivision } = &light.kind else {
            return None;
        };
        let ground = if sky.ground() > 0.0 {
            sky::ground_patches((*subdivision / 2).max(1))
        } else {
            Vec::new()
        };
        // The openings, those marked, and the glass (a pane in an opening
        // found from the geometry overlaps it: each direction is counted by
        // the nearer, or the first listed).
        let mut portals: Vec<Prepared> = portal::openings(&scene.surfaces, occluder)
            .iter()
            .map(prepare)
            .collect();
        portals.extend(
            scene
                .portals
                .iter()
                .filter_map(|m| m.portal())
                .map(|p| prepare(&p)),
        );
        portals.extend(scene.panes.iter().map(|pane| {
            prepare(&Portal {
                pieces: vec![pane.polygon.clone()],
                normal: pane.normal,
                area: geometry::area(&pane.polygon),
            })
        }));
        Some(SkyPlan {
            patches: sky::patches(*subdivision),
            ground,
            portals,
        })
    }

    /// The openings found.
    #[must_use]
    pub fn portal_count(&self) -> usize {
        self.portals.len()
    }

    /// The receiver's candidates: each an unblocked irradiance (W/m^2 per
    /// channel) and the far end of its shadow segment, `reach` metres out.
    /// `index` seeds the receiver's random numbers.
    #[must_use]
    pub fn candidates(
        &self,
        light: &Light,
        index: u64,
        point: DVec3,
        normal: DVec3,
        reach: f64,
    ) -> Vec<(DVec3, DVec3)> {
        let LightKind::Sky { sky, .. } = &light.kind else {
            return Vec::new();
        };
        let radiometric = light.radiometric();
        let mut random = Stream::new(index);
        let active = self.active(sky, point, normal);
        let mut out = Vec::new();
        for patch in self.patches.iter().chain(&self.ground) {
            let uv = (random.next(), random.next());
            let towards = patch.direction(uv.0, uv.1);
            let cos = normal.dot(towards);
            if cos <= 0.0
                || active
                    .iter()
                    .any(|a| crossing(&a.pieces, point, towards).is_some())
            {
                continue;
            }
            let weight = sky.relative_luminance(towards) * cos * patch.solid_angle();
            if weight > 0.0 {
                out.push((radiometric * weight, point + towards * reach));
            }
        }
        let total: f64 = active.iter().map(|a| a.power).sum();
        for (k, a) in active.iter().enumerate() {
            // The other portals some direction through this one may cross.
            let others: Vec<(usize, &Active)> = active
                .iter()
                .enumerate()
                .filter(|&(m, b)| m != k && a.overlaps(b))
                .collect();
            let share = (PORTAL_RAYS as f64 * a.power / total).round() as usize;
            let n = share.max(MIN_PORTAL_RAYS);
            let columns = (n as f64).sqrt().ceil() as usize;
            let rows = n.div_ceil(columns);
            // What a direction through this portal brings, per steradian
            // (0 where a nearer active portal counts it).
            let value = |towards: DVec3| {
                let cos = normal.dot(towards);
                if cos <= 0.0 {
                    return 0.0;
                }
                if others.is_empty() {
                    return sky.relative_luminance(towards) * cos;
                }
                let here = crossing(&a.pieces, point, towards).unwrap_or(f64::INFINITY);
                // Nearer, or as near (a pane in an opening) and listed
                // first.
                let nearer = others.iter().any(|&(m, b)| {
                    b.crossing(point, towards).is_some_and(|s| {
                        s < here - 1e-9 * here || (s <= here + 1e-9 * here && m < k)
                    })
                });
                if nearer {
                    0.0
                } else {
                    sky.relative_luminance(towards) * cos
                }
            };
            // The rays: stratified in the portal's solid angle.
            let first = out.len();
            let omega = *a.cumulative.last().unwrap_or(&0.0);
            let mut drawn = 0.0;
            for i in 0..columns {
                for j in 0..rows {
                    let u = (i as f64 + random.next()) / columns as f64;
                    let v = (j as f64 + random.next()) / rows as f64;
                    let towards = a.direction(u, v);
                    let f = value(towards);
                    if f > 0.0 {
                        drawn += f;
                        out.push((radiometric * f, point + towards * reach));
                    }
                }
            }
            if drawn > 0.0 {
                // Each ray's share of the unblocked integral, found without
                // rays by the midpoint rule on a grid of directions over
                // each spherical triangle (smooth there; not across two,
                // where the map from `u` jumps): the rays then estimate only
                // the fraction blocked, which is exact where nothing is (a
                // ratio estimator).
                let mut unblocked = 0.0;
                let mut before = 0.0;
                for (t, &cumulative) in a.triangles.iter().zip(&a.cumulative) {
                    let size = cumulative - before;
                    before = cumulative;
                    // Twice as many points a side as the triangle's rays,
                    // 2 to QUADRATURE.
                    let rays = (columns * rows) as f64 * size / omega;
                    let m = ((2.0 * rays.sqrt()).ceil() as usize).clamp(2, QUADRATURE);
                    let mut sum = 0.0;
                    for i in 0..m {
                        for j in 0..m {
                            let u = (i as f64 + 0.5) / m as f64;
                            let v = (j as f64 + 0.5) / m as f64;
                            sum += value(spherical::sample_triangle(t[0], t[1], t[2], size, u, v));
                        }
                    }
                    let sum = sum / (m * m) as f64;
                    unblocked += sum * size;
                }
                let scale = unblocked / drawn;
                for c in &mut out[first..] {
                    c.0 *= scale;
                }
            }
        }
        out
    }

    /// The portals in front of the receiver, the most light first, at most
    /// [`MAX_ACTIVE`].
    fn active(&self, sky: &sky::Sky, point: DVec3, normal: DVec3) -> Vec<Active> {
        let mut out: Vec<Active> = Vec::new();
        let mut clipped = Vec::new();
        let mut half = Vec::new();
        for p in &self.portals {
            // Wholly behind the receiver's plane.
            if normal.dot(p.centre - point) < -p.radius {
                continue;
            }
            let scale = 1.0 + point.abs().max_element() + p.radius;
            let front = point + normal * (1e-9 * scale);
            let mut a = Active {
                triangles: Vec::new(),
                cumulative: Vec::new(),
                pieces: Vec::new(),
                power: 0.0,
                axis: DVec3::ZERO,
                cos_half: -1.0,
            };
            let mut omega = 0.0;
            for piece in &p.pieces {
                geometry::clip_to_half_space(&piece.corners, front, normal, 0.0, &mut clipped);
                if clipped.len() < 3 {
                    continue;
                }
                // Above and below the receiver's horizon apart: the
                // luminance jumps there from the sky's to the ground's, and
                // each part's integrand is smooth.
                for up in [DVec3::Y, -DVec3::Y] {
                    geometry::clip_to_half_space(&clipped, point, up, 0.0, &mut half);
                    if half.len() < 3 {
                        continue;
                    }
                    let unit: Vec<DVec3> = half.iter().map(|&c| (c - point).normalize()).collect();
                    for i in 1..unit.len() - 1 {
                        let t = [unit[0], unit[i], unit[i + 1]];
                        let w = spherical::solid_angle(t[0], t[1], t[2]);
                        if w.is_nan() || w <= 0.0 {
                            continue;
                        }
                        let middle = (t[0] + t[1] + t[2]).normalize();
                        a.power += w * sky.relative_luminance(middle) * normal.dot(middle).max(0.0);
                        omega += w;
                        a.triangles.push(t);
                        a.cumulative.push(omega);
                    }
                }
                a.pieces.push(Piece {
                    corners: clipped.clone(),
                    normal: piece.normal,
                });
            }
            if a.power > 0.0 {
                // The cone: about the corners' mean direction, out to the
                // farthest corner (a cap holding the corners holds their
                // spherical hull, the pieces, when under a hemisphere), a
                // little wider for round-off.
                let corners = a.pieces.iter().flat_map(|p| &p.corners);
                let sum: DVec3 = corners.clone().map(|&c| (c - point).normalize()).sum();
                let axis = sum.normalize_or_zero();
                if axis != DVec3::ZERO {
                    let cos = corners
                        .map(|&c| (c - point).normalize().dot(axis))
                        .fold(1.0, f64::min);
                    a.axis = axis;
                    a.cos_half = if cos > 0.0 { cos - 1e-9 } else { -1.0 };
                }
                out.push(a);
            }
        }
        out.sort_by(|a, b| b.power.total_cmp(&a.power));
        out.truncate(MAX_ACTIVE);
        out
    }
}

impl Active {
    /// The direction at `(u, v)` in `[0, 1)^2`: `u` picks a triangle by its
    /// share of the solid angle and its place in it, `v` the rest.
    fn direction(&self, u: f64, v: f64) -> DVec3 {
        let omega = *self.cumulative.last().unwrap_or(&0.0);
        let target = u * omega;
        let k = self
            .cumulative
            .partition_point(|&c| c < target)
            .min(self.triangles.len() - 1);
        let before = if k == 0 { 0.0 } else { self.cumulative[k - 1] };
        let size = self.cumulative[k] - before;
        let local = if size > 0.0 {
            ((target - before) / size).clamp(0.0, 1.0)
        } else {
            0.5
        };
        let [a, b, c] = self.triangles[k];
        spherical::sample_triangle(a, b, c, size, local, v)
    }
}

/// A portal's pieces with their normals, centre and bounding radius.
fn prepare(portal: &Portal) -> Prepared {
    let pieces: Vec<Piece> = portal
        .pieces
        .iter()
        .map(|corners| Piece {
            normal: geometry::normal(corners).unwrap_or(portal.normal),
            corners: corners.clone(),
        })
        .collect();
    let corners = portal.pieces.iter().flatten();
    let count = corners.clone().count().max(1);
    let centre = corners.clone().sum::<DVec3>() / count as f64;
    let radius = corners.map(|c| c.distance(centre)).fold(0.0, f64::max);
    Prepared {
        pieces,
        centre,
        radius,
    }
}

/// Where the ray from `point` along `towards` crosses one of `pieces`
/// (its distance), if it does.
fn crossing(pieces: &[Piece], point: DVec3, towards: DVec3) -> Option<f64> {
    pieces.iter().find_map(|piece| {
        let denominator = piece.normal.dot(towards);
        if denominator == 0.0 {
            return None;
        }
        let s = piece.normal.dot(piece.corners[0] - point) / denominator;
        if s.is_nan() || s <= 0.0 {
            return None;
        }
        let hit = point + towards * s;
        geometry::convex_contains(&piece.corners, piece.normal, hit, 0.0).then_some(s)
    })
}

/// A stream of numbers in `[0, 1)` seeded by a receiver's index
/// (SplitMix64, Steele et al. 2014): each receiver draws its own, so the
/// sky's samples do not depend on the number of threads.
struct Stream(u64);

impl Stream {
    fn new(seed: u64) -> Stream {
        Stream(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0xD1B5_4A32_D192_ED03)
    }

    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        // The top 53 bits, as a fraction.
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}
