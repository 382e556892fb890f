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
//! A sky ([`crate::scene::sky`]) shoots the same way from many directions
//! per receiver, drawn through the scene's openings and over the rest of
//! the sky ([`super::sky`]): one shadow segment each.
//!
//! Receivers are independent (a sky's directions come from a generator
//! seeded by the receiver's index), so the result does not depend on the
//! number of threads. A shot works a chunk of receivers (or elements) at a
//! time: every point and direction drawn first, then all their shadow
//! segments answered at once, by the scene's occluder or by a device that
//! traces them in bulk ([`crate::solver::device::Segments`], the GPU), then
//! each receiver's sum in its own order: the same answer either way, to the
//! device's round-off.

use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use super::Receiver;
use super::Stats;
use super::device::{DeviceError, Segment, Segments};
use super::method::ShotInputs;
use super::sky::SkyPlan;
use crate::accel::{self, Occluder, ShadowCache};
use crate::scene::{Light, Scene, glass};

/// Receivers gathered between two checks of the shot's abort.
const CHUNK: usize = 4096;

/// A shadow segment's surface id that matches no surface.
pub(super) const NO_SURFACE: u32 = u32::MAX;

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
/// elements integrated across its edges ([`element_means`]); `Ok(None)` if
/// the shot's abort fired. Its shadow segments are answered by `device`,
/// many at a time, when one is given (an error when it fails: the shot can
/// be made again without it), else by the scene's occluder.
///
/// # Errors
///
/// When `device` fails.
pub fn shoot(
    light: &Light,
    inputs: &ShotInputs<'_>,
    device: Option<&dyn Segments>,
    stats: &mut Stats,
) -> Result<Option<LightShot>, DeviceError> {
    let mut counted = Stats::default();
    let Some(irradiance) = gather(light, inputs, device, &mut counted)? else {
        return Ok(None);
    };
    let Some(element_means) = element_means(light, inputs, &irradiance, device, &mut counted)?
    else {
        return Ok(None);
    };
    stats.pairs += counted.pairs;
    stats.rays_cast += counted.rays_cast;
    stats.sky_portals = stats.sky_portals.max(counted.sky_portals);
    stats.gather_time += counted.gather_time;
    Ok(Some(LightShot {
        irradiance,
        element_means,
    }))
}

/// What passes along each segment, per channel: 0 where a surface blocks
/// it (asked of `device`, or of the scene's occluder, in parallel), else
/// the transmittance of the glass it crosses ([`glass::transmittance`]),
/// 1 through none.
pub(super) fn answer(
    inputs: &ShotInputs<'_>,
    device: Option<&dyn Segments>,
    segments: &[Segment],
) -> Result<Vec<DVec3>, DeviceError> {
    let blocked = match device {
        Some(device) => device.occluded(segments)?,
        None => segments
            .par_iter()
            .map_init(ShadowCache::default, |cache, s| {
                inputs.occluder.occluded_cached(s.from, s.to, s.skip, cache)
            })
            .collect(),
    };
    let panes = &inputs.scene.panes;
    Ok(segments
        .par_iter()
        .zip(blocked)
        .map(|(s, blocked)| {
            if blocked {
                DVec3::ZERO
            } else if panes.is_empty() {
                DVec3::ONE
            } else {
                glass::transmittance(panes, s.from, s.to)
            }
        })
        .collect())
}

/// What `light` sends straight to the receiver `r`: its unblocked
/// irradiance there ([`Light::irradiance`]) if `occluder` finds its shadow
/// segment clear (asked through `cache`), dimmed by the glass it crosses;
/// zero for a sky. The answer [`gather`] gives a receiver, for points shown
/// one at a time.
#[must_use]
pub fn direct_at(
    light: &Light,
    r: &Receiver,
    scene: &Scene,
    occluder: &dyn Occluder,
    reach: f64,
    cache: &mut ShadowCache,
) -> DVec3 {
    // A sky's light comes from many directions, none of them this one:
    // its `transfer` is zero.
    let (unblocked, from) = light.irradiance(r.point, r.normal, reach);
    if unblocked == DVec3::ZERO {
        return DVec3::ZERO;
    }
    let s = segment(
        from,
        r.point,
        [NO_SURFACE, r.group],
        light.position().is_none(),
    );
    if occluder.occluded_cached(s.from, s.to, s.skip, cache) {
        DVec3::ZERO
    } else if scene.panes.is_empty() {
        unblocked
    } else {
        unblocked * glass::transmittance(&scene.panes, s.from, s.to)
    }
}

/// The shadow segment from `from` (a light, or for a distant light a point
/// beyond the scene) to `point`, clear when no surface but those of `skip`
/// crosses it.
pub(super) fn segment(from: DVec3, point: DVec3, skip: [u32; 2], distant: bool) -> Segment {
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
    Segment {
        from: a,
        to: b,
        skip,
    }
}

/// The irradiance `light` sends to each receiver, or `Ok(None)` if the
/// shot's abort fired first. A chunk of receivers at a time: what each
/// would receive unblocked and its shadow segments, then every segment of
/// the chunk answered at once (`answer`), then each receiver's sum in its
/// own order.
///
/// # Errors
///
/// When `device` fails.
pub fn gather(
    light: &Light,
    inputs: &ShotInputs<'_>,
    device: Option<&dyn Segments>,
    stats: &mut Stats,
) -> Result<Option<Vec<DVec3>>, DeviceError> {
    let start = Instant::now();
    let reach = sun_reach(inputs.scene);
    let distant = light.position().is_none();
    let mut irradiance = vec![DVec3::ZERO; inputs.receivers.len()];
    let mut pairs = 0u64;
    let mut rays = 0u64;
    let mut chunk_start = 0;
    let plan = SkyPlan::new(light, inputs.scene, inputs.occluder);
    if let Some(plan) = &plan {
        stats.sky_portals = stats.sky_portals.max(plan.portal_count() as u64);
    }
    for (chunk, out) in inputs
        .receivers
        .chunks(CHUNK)
        .zip(irradiance.chunks_mut(CHUNK))
    {
        if inputs.abort.fired() {
            return Ok(None);
        }
        let first = chunk_start;
        if let Some(plan) = &plan {
            let (chunk_pairs, chunk_rays) =
                super::sky::gather(plan, light, inputs, device, chunk, first, out)?;
            pairs += chunk_pairs;
            rays += chunk_rays;
            chunk_start += chunk.len();
            continue;
        }
        // Each receiver's unblocked irradiance and its segment.
        let candidates: Vec<Option<(DVec3, Segment)>> = chunk
            .par_iter()
            .map(|r| {
                // A point light skips no surface; the sun's far end none
                // either (it lies outside the scene).
                let skip = [NO_SURFACE, r.group];
                let (unblocked, from) = light.irradiance(r.point, r.normal, reach);
                (unblocked != DVec3::ZERO)
                    .then(|| (unblocked, segment(from, r.point, skip, distant)))
            })
            .collect();
        let segments: Vec<Segment> = candidates.iter().flatten().map(|c| c.1).collect();
        let passed = answer(inputs, device, &segments)?;
        let mut next = 0;
        for (e, candidate) in out.iter_mut().zip(&candidates) {
            *e = DVec3::ZERO;
            if let Some((unblocked, _)) = candidate {
                if passed[next] != DVec3::ZERO {
                    *e = *unblocked * passed[next];
                }
                next += 1;
                pairs += 1;
                rays += 1;
            }
        }
        chunk_start += chunk.len();
    }
    stats.pairs += pairs;
    stats.rays_cast += rays;
    stats.gather_time += start.elapsed();
    Ok(Some(irradiance))
}

/// An element's grid of points: each one's weighted unblocked irradiance
/// and shadow segment, and the sum of every point's weight.
type Grid = (Vec<(DVec3, Segment)>, f64);

/// Points per side of an element integrated across a light's edge.
const SIDE: usize = 8;

/// Each element's mean irradiance from `light` where its corners disagree
/// (the darkest below half the brightest: a shadow's or a cone's edge
/// crosses it, or the light is close), by an 8 x 8 grid of points over it
/// each with its shadow segment; `None` where the corners' mean is kept.
/// The mean of an element's corners is what the element reflects in the
/// end: across a sun patch's edge it errs by the share of the element lit,
/// which over a whole patch edge does not cancel (a window's sun patch
/// lost 6% of its power at the default mesh). `Ok(Some(None))` for a sky,
/// whose shadows are soft; `Ok(None)` if the shot's abort fired. The
/// segments of a chunk of elements are answered at once (`answer`).
///
/// # Errors
///
/// When `device` fails.
pub fn element_means(
    light: &Light,
    inputs: &ShotInputs<'_>,
    vertex_irradiance: &[DVec3],
    device: Option<&dyn Segments>,
    stats: &mut Stats,
) -> Result<Option<Option<Vec<DVec3>>>, DeviceError> {
    element_means_of(
        light,
        inputs,
        &inputs.mesh.elements,
        vertex_irradiance,
        device,
        stats,
    )
}

/// [`element_means`] of `elements` alone (elements of `inputs.mesh`'s
/// vertices, not necessarily its own: the pieces of split elements, when
/// a solve refines its mesh and replays the lights' shots to them).
///
/// # Errors
///
/// When `device` fails.
pub fn element_means_of(
    light: &Light,
    inputs: &ShotInputs<'_>,
    elements: &[crate::mesh::Element],
    vertex_irradiance: &[DVec3],
    device: Option<&dyn Segments>,
    stats: &mut Stats,
) -> Result<Option<Option<Vec<DVec3>>>, DeviceError> {
    if light.sky().is_some() {
        return Ok(Some(None));
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
    // An element's grid: the weighted unblocked irradiance of each point
    // and its segment, and the sum of all the points' weights; `None` when
    // its corners' mean is kept.
    let grid = |e: &crate::mesh::Element| -> Option<Grid> {
        let corners = e.vertices();
        let values = corners
            .iter()
            .map(|&c| crate::luminance(vertex_irradiance[c as usize]));
        let (min, max) = values.fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
        if !(max > 0.0 && min < 0.5 * max) {
            return None;
        }
        let surface = &scene.surfaces[e.surface as usize];
        let skip = [NO_SURFACE, surface.group];
        let p: Vec<DVec3> = corners
            .iter()
            .map(|&c| mesh.vertices[c as usize].position)
            .collect();
        let mut points = Vec::with_capacity(SIDE * SIDE);
        let mut weights = 0.0;
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
                points.push((unblocked * weight, segment(from, point, skip, distant)));
            }
        }
        Some((points, weights))
    };
    let mut integrated: Vec<DVec3> = Vec::with_capacity(elements.len());
    let mut rays = 0u64;
    for chunk in elements.chunks(CHUNK) {
        if inputs.abort.fired() {
            return Ok(None);
        }
        let grids: Vec<Option<Grid>> = chunk.par_iter().map(grid).collect();
        let segments: Vec<Segment> = grids
            .iter()
            .flatten()
            .flat_map(|(points, _)| points.iter().map(|p| p.1))
            .collect();
        let passed = answer(inputs, device, &segments)?;
        rays += segments.len() as u64;
        let mut next = 0;
        for (e, g) in chunk.iter().zip(&grids) {
            integrated.push(match g {
                None => corner_mean(e),
                Some((points, weights)) => {
                    let mut sum = DVec3::ZERO;
                    for (value, _) in points {
                        if passed[next] != DVec3::ZERO {
                            sum += *value * passed[next];
                        }
                        next += 1;
                    }
                    if *weights > 0.0 {
                        sum / *weights
                    } else {
                        corner_mean(e)
                    }
                }
            });
        }
    }
    stats.rays_cast += rays;
    stats.gather_time += start.elapsed();
    Ok(Some(Some(integrated)))
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
    for direction in crate::geometry::spherical::sphere_directions(ENCLOSURE_RAYS) {
        let Some(hit) = occluder.closest_hit(origin, direction, reach, [NO_SURFACE; 2]) else {
            return false;
        };
        let normal = scene.surfaces[hit.surface as usize].normal;
        behind += usize::from(normal.dot(direction) > 0.0);
    }
    4 * behind >= 3 * ENCLOSURE_RAYS
}
