//! Shots from lights that are not surfaces ([`crate::scene::light`]):
//! beyond the paper, whose shooters are all patches. A light shoots once,
//! before any surface: every receiver that faces it gets the light's
//! irradiance `I(w) cos(theta) / d^2` (the sun's `E cos(theta)`) if one
//! shadow segment from the light (for the sun, from a point beyond the
//! scene towards it) reaches the receiver unblocked. This is the
//! point-source transfer of Wallace, Elmquist & Haines (1989) evaluated
//! exactly at each receiver: a point light has no area to subdivide, so
//! the only error left is the receiving mesh's.
//!
//! Receivers are independent, so the result does not depend on the number
//! of threads.

use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use super::Stats;
use super::method::ShotInputs;
use crate::accel;
use crate::scene::{Light, Scene};

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

/// The irradiance `light` sends to each receiver, or `None` if the shot's
/// abort fired first.
pub fn gather(light: &Light, inputs: &ShotInputs<'_>, stats: &mut Stats) -> Option<Vec<DVec3>> {
    let start = Instant::now();
    let reach = sun_reach(inputs.scene);
    let mut irradiance = vec![DVec3::ZERO; inputs.receivers.len()];
    let mut pairs = 0u64;
    let mut rays = 0u64;
    for (chunk, out) in inputs
        .receivers
        .chunks(CHUNK)
        .zip(irradiance.chunks_mut(CHUNK))
    {
        if inputs.abort.fired() {
            return None;
        }
        let counts = chunk
            .par_iter()
            .zip(out.par_iter_mut())
            .map(|(r, e)| {
                let (unblocked, from) = light.irradiance(r.point, r.normal, reach);
                if unblocked == DVec3::ZERO {
                    return (0, 0);
                }
                let (a, b) = accel::shorten(from, r.point);
                // A point light skips no surface; the sun's far end none
                // either (it lies outside the scene).
                let skip = [NO_SURFACE, r.group];
                if !inputs.occluder.occluded(a, b, skip) {
                    *e = unblocked;
                }
                (1, 1)
            })
            .reduce(|| (0, 0), |x, y| (x.0 + y.0, x.1 + y.1));
        pairs += counts.0;
        rays += counts.1;
    }
    stats.pairs += pairs;
    stats.rays_cast += rays;
    stats.gather_time += start.elapsed();
    Some(irradiance)
}
