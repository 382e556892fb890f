//! Shots from lights that are not surfaces ([`crate::scene::light`]):
//! beyond the paper, whose shooters are all patches. A light shoots once,
//! before any surface: every receiver that faces it gets the light's
//! irradiance `I(w) cos(theta) / d^2` (the sun's `E cos(theta)`) if one
//! shadow segment from the light (for the sun, from a point beyond the
//! scene towards it) reaches the receiver unblocked. This is the
//! point-source transfer of Wallace, Elmquist & Haines (1989) evaluated
//! exactly at each receiver: a point light has no area to subdivide, so
//! the only error left is the receiving mesh's. That error is in what the
//! elements reflect, which the book-keeping takes from their corners: an
//! element that a shadow's or a cone's edge crosses is integrated over a
//! grid of points instead ([`element_means`]), so a sun patch sends on the
//! power its opening lets in.
//!
//! A sky ([`crate::scene::sky`]) shoots the same way from one direction
//! drawn in each of its patches per receiver: one shadow segment each.
//!
//! Receivers are independent (a sky's directions come from a generator
//! seeded by the receiver's index), so the result does not depend on the
//! number of threads.

use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use super::Stats;
use super::method::ShotInputs;
use crate::accel;
use crate::scene::{Light, LightKind, Scene, sky};

/// Receivers gathered between two checks of the shot's abort.
const CHUNK: usize = 4096;

/// A shadow segment's surface id that matches no surface.
const NO_SURFACE: u32 = u32::MAX;

/// The order lights shoot in: point and spot lights by decreasing flux
/// (luminance), then suns in input order.
#[must_use]
pub fn shooting_order(lights: &[Light]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..lights.len()).collect();
    let key = |i: usize| lights[i].flux().map_or(f64::NEG_INFINITY, crate::luminance);
    order.sort_by(|&a, &b| key(b).total_cmp(&key(a)).then(a.cmp(&b)));
    order
}

/// How far beyond a receiver the sun's shadow segment starts: past every
/// surface of the scene whatever the receiver.
#[must_use]
pub fn sun_reach(scene: &Scene) -> f64 {
    let (lo, hi) = scene.bounds();
    let diagonal = (hi - lo).length();
    if diagonal.is_finite() {
        2.0 * diagonal + 1.0
    } else {
        1.0
    }
}

/// What a light's shot produced.
pub struct LightShot {
    /// One per receiver, in the order of [`ShotInputs::receivers`].
    pub irradiance: Vec<DVec3>,
    /// Each element's mean irradiance where it is known better than its
    /// corners' mean ([`element_means`]); `None` for a sky.
    pub element_means: Option<Vec<DVec3>>,
}

/// `light`'s shot: its irradiance at every receiver ([`gather`]) and the
/// elements integrated across its edges ([`element_means`]); `None` if the
/// shot's abort fired.
pub fn shoot(light: &Light, inputs: &ShotInputs<'_>, stats: &mut Stats) -> Option<LightShot> {
    let irradiance = gather(light, inputs, stats)?;
    let element_means = element_means(light, inputs, &irradiance, stats)?;
    Some(LightShot {
        irradiance,
        element_means,
    })
}

/// The irradiance `light` sends to each receiver, or `None` if the shot's
/// abort fired first.
pub fn gather(light: &Light, inputs: &ShotInputs<'_>, stats: &mut Stats) -> Option<Vec<DVec3>> {
    let start = Instant::now();
    let reach = sun_reach(inputs.scene);
    let distant = light.position().is_none();
    let mut irradiance = vec![DVec3::ZERO; inputs.receivers.len()];
    let mut pairs = 0u64;
    let mut rays = 0u64;
    let mut chunk_start = 0;
    let patches = match &light.kind {
        LightKind::Sky { subdivision, .. } => sky::patches(*subdivision),
        _ => Vec::new(),
    };
    for (chunk, out) in inputs
        .receivers
        .chunks(CHUNK)
        .zip(irradiance.chunks_mut(CHUNK))
    {
        if inputs.abort.fired() {
            return None;
        }
        let first = chunk_start;
        let counts = chunk
            .par_iter()
            .zip(out.par_iter_mut())
            .enumerate()
            .map(|(k, (r, e))| {
                // A point light skips no surface; the sun's or the sky's
                // far end none either (it lies outside the scene).
                let skip = [NO_SURFACE, r.group];
                let unblocked = |(unblocked, from): (DVec3, DVec3)| {
                    if unblocked == DVec3::ZERO {
                        return None;
                    }
                    let seen = sees(inputs.occluder, from, r.point, skip, distant);
                    Some(seen.then_some(unblocked))
                };
                if patches.is_empty() {
                    return match unblocked(light.irradiance(r.point, r.normal, reach)) {
                        None => (0, 0),
                        Some(seen) => {
                            *e = seen.unwrap_or(DVec3::ZERO);
                            (1, 1)
                        }
                    };
                }
                let mut random = Stream::new((first + k) as u64);
                let mut rays = 0;
                let mut sum = DVec3::ZERO;
                for patch in &patches {
                    let uv = (random.next(), random.next());
                    if let Some(seen) =
                        unblocked(light.sky_sample(patch, uv, r.point, r.normal, reach))
                    {
                        rays += 1;
                        sum += seen.unwrap_or(DVec3::ZERO);
                    }
                }
                *e = sum;
                (u64::from(rays > 0), rays)
            })
            .reduce(|| (0, 0), |x, y| (x.0 + y.0, x.1 + y.1));
        chunk_start += chunk.len();
        pairs += counts.0;
        rays += counts.1;
    }
    stats.pairs += pairs;
    stats.rays_cast += rays;
    stats.gather_time += start.elapsed();
    Some(irradiance)
}

/// Whether the shadow segment from `from` (a light, or for a distant light
/// a point beyond the scene) to `point` is clear of every surface but those
/// of `skip`.
fn sees(
    occluder: &dyn crate::accel::Occluder,
    from: DVec3,
    point: DVec3,
    skip: [u32; 2],
    distant: bool,
) -> bool {
    let (a, b) = if distant {
        // The far end lies outside the scene. The receiver's end stays
        // where it is: moved towards the sky it could step through a
        // surface meeting the receiver's at an edge (a ceiling over a wall's
        // top vertices, which lie only the gathering nudge below it). It
        // lies off every other surface already: the nudge moves it well
        // inside its own, away from any neighbour's edge tolerance, and its
        // own surface id is skipped.
        (from, point)
    } else {
        accel::shorten(from, point)
    };
    !occluder.occluded(a, b, skip)
}

/// Points per side of an element integrated across a light's edge.
const SIDE: usize = 8;

/// Each element's mean irradiance from `light` where its corners disagree
/// (the darkest below half the brightest: a shadow's or a cone's edge
/// crosses it, or the light is close), by an 8 x 8 grid of points over it
/// each with its shadow segment; `None` where the corners' mean is kept.
/// The mean of an element's corners is what the element reflects in the
/// end: across a sun patch's edge it errs by the share of the element lit,
/// which over a whole patch edge does not cancel (a window's sun patch
/// lost 6% of its power at the default mesh). `Some(None)` for a sky, whose
/// shadows are soft; `None` if the shot's abort fired.
pub fn element_means(
    light: &Light,
    inputs: &ShotInputs<'_>,
    vertex_irradiance: &[DVec3],
    stats: &mut Stats,
) -> Option<Option<Vec<DVec3>>> {
    if matches!(light.kind, LightKind::Sky { .. }) {
        return Some(None);
    }
    let start = Instant::now();
    let (scene, mesh) = (inputs.scene, inputs.mesh);
    let reach = sun_reach(scene);
    let distant = light.position().is_none();
    let corner_mean = |e: &crate::mesh::Element| {
        let corners = e.vertices();
        corners
            .iter()
            .map(|&c| vertex_irradiance[c as usize])
            .sum::<DVec3>()
            / corners.len() as f64
    };
    let integrate = |e: &crate::mesh::Element| {
        let corners = e.vertices();
        let values = corners
            .iter()
            .map(|&c| crate::luminance(vertex_irradiance[c as usize]));
        let (min, max) = values.fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
        if !(max > 0.0 && min < 0.5 * max) {
            return (corner_mean(e), 0);
        }
        let surface = &scene.surfaces[e.surface as usize];
        let skip = [NO_SURFACE, surface.group];
        let p: Vec<DVec3> = corners
            .iter()
            .map(|&c| mesh.vertices[c as usize].position)
            .collect();
        let (mut sum, mut weights, mut rays) = (DVec3::ZERO, 0.0, 0);
        for i in 0..SIDE {
            for j in 0..SIDE {
                let u = (i as f64 + 0.5) / SIDE as f64;
                let v = (j as f64 + 0.5) / SIDE as f64;
                // A triangle takes the square by the square-root map
                // (uniform in area, no point on an edge); a quad is
                // mapped bilinearly, each point weighted by the map's
                // area there.
                let (point, weight) = if p.len() == 3 {
                    let r = u.sqrt();
                    (
                        p[0] * (1.0 - r) + p[1] * (r * (1.0 - v)) + p[2] * (r * v),
                        1.0,
                    )
                } else {
                    let at = |u: f64, v: f64| {
                        p[0] * ((1.0 - u) * (1.0 - v))
                            + p[1] * (u * (1.0 - v))
                            + p[2] * (u * v)
                            + p[3] * ((1.0 - u) * v)
                    };
                    let du = (p[1] - p[0]) * (1.0 - v) + (p[2] - p[3]) * v;
                    let dv = (p[3] - p[0]) * (1.0 - u) + (p[2] - p[1]) * u;
                    (at(u, v), du.cross(dv).length())
                };
                weights += weight;
                let (unblocked, from) = light.irradiance(point, surface.normal, reach);
                if unblocked == DVec3::ZERO {
                    continue;
                }
                rays += 1;
                if sees(inputs.occluder, from, point, skip, distant) {
                    sum += unblocked * weight;
                }
            }
        }
        if weights > 0.0 {
            (sum / weights, rays)
        } else {
            (corner_mean(e), rays)
        }
    };
    let mut integrated: Vec<(DVec3, u64)> = Vec::with_capacity(mesh.elements.len());
    for chunk in mesh.elements.chunks(CHUNK) {
        if inputs.abort.fired() {
            return None;
        }
        integrated.par_extend(chunk.par_iter().map(integrate));
    }
    stats.rays_cast += integrated.iter().map(|r| r.1).sum::<u64>();
    stats.gather_time += start.elapsed();
    Some(Some(integrated.into_iter().map(|r| r.0).collect()))
}

/// Sight lines cast from a point or spot light to tell whether it is shut
/// inside something.
const ENCLOSURE_RAYS: usize = 64;

/// Whether the point-like `light` is shut inside closed geometry: every
/// sight line from it meets a surface, and three in four meet one from
/// behind (inside a closed solid, whose faces point out; the rest may meet
/// a surface the solid rests on, coincident with its base). A light in a
/// closed room sees the room's faces from the front and is not enclosed.
#[must_use]
pub fn enclosed(
    light: &Light,
    scene: &Scene,
    occluder: &dyn crate::accel::Occluder,
    reach: f64,
) -> bool {
    let Some(origin) = light.position() else {
        return false;
    };
    let mut behind = 0;
    for k in 0..ENCLOSURE_RAYS {
        // Fibonacci directions: even over the sphere.
        let z = 1.0 - (2.0 * k as f64 + 1.0) / ENCLOSURE_RAYS as f64;
        let phi = k as f64 * std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let r = (1.0 - z * z).sqrt();
        let direction = DVec3::new(r * phi.cos(), z, r * phi.sin());
        let Some(hit) = occluder.closest_hit(origin, direction, reach, [NO_SURFACE; 2]) else {
            return false;
        };
        let normal = scene.surfaces[hit.surface as usize].normal;
        behind += usize::from(normal.dot(direction) > 0.0);
    }
    4 * behind >= 3 * ENCLOSURE_RAYS
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
