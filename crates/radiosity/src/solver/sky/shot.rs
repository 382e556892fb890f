//! The sky's shot over a chunk of receivers: the directions of every
//! receiver's plan ([`super::SkyPlan`]) traced at once, by the scene's
//! occluder or a device, then the cells to refine, then each receiver's
//! sum in its own order (the point-source transfer of Wallace, Elmquist &
//! Haines 1989, from each of the sky's directions).

use glam::DVec3;
use rayon::prelude::*;

use super::{SkyDraw, SkyPlan};
use crate::scene::Light;
use crate::solver::Receiver;
use crate::solver::device::{DeviceError, Segment, Segments};
use crate::solver::lights::{NO_SURFACE, answer, segment, sun_reach};
use crate::solver::method::ShotInputs;

/// A chunk of receivers' sky: every receiver's first
/// round of rays answered at once, then its second round (the portal cells
/// to refine), then each receiver's irradiance into `out`. Returns the
/// receivers that drew a ray and the rays.
pub(in crate::solver) fn gather(
    plan: &SkyPlan,
    light: &Light,
    inputs: &ShotInputs<'_>,
    device: Option<&dyn Segments>,
    chunk: &[Receiver],
    first: usize,
    out: &mut [DVec3],
) -> Result<(u64, u64), DeviceError> {
    let reach = sun_reach(inputs.scene);
    // The sky's far ends lie outside the scene: a segment skips the
    // receiver's own surface only.
    let segments = |draws: &[SkyDraw], refined: bool| -> Vec<Segment> {
        draws
            .iter()
            .zip(chunk)
            .flat_map(|(d, r)| {
                let rays = if refined { &d.refined } else { &d.rays };
                rays.iter()
                    .map(move |&(_, from)| segment(from, r.point, [NO_SURFACE, r.group], true))
            })
            .collect()
    };
    let split = |passed: &[DVec3], draws: &[SkyDraw], refined: bool| -> Vec<Vec<DVec3>> {
        let mut next = 0;
        draws
            .iter()
            .map(|d| {
                let n = if refined {
                    d.refined.len()
                } else {
                    d.rays.len()
                };
                next += n;
                passed[next - n..next].to_vec()
            })
            .collect()
    };
    let mut draws: Vec<SkyDraw> = chunk
        .par_iter()
        .enumerate()
        .map(|(k, r)| plan.pilot(light, (first + k) as u64, r.point, r.normal, reach))
        .collect();
    let first_round = segments(&draws, false);
    let passed = split(&answer(inputs, device, &first_round)?, &draws, false);
    draws
        .par_iter_mut()
        .zip(&passed)
        .for_each(|(d, p)| plan.refine(light, d, p));
    let second_round = segments(&draws, true);
    let refined = if second_round.is_empty() {
        vec![Vec::new(); draws.len()]
    } else {
        split(&answer(inputs, device, &second_round)?, &draws, true)
    };
    let mut pairs = 0;
    for (((e, d), p), q) in out.iter_mut().zip(&draws).zip(&passed).zip(&refined) {
        *e = plan.finish(d, p, q);
        pairs += u64::from(!d.rays.is_empty());
    }
    Ok((pairs, (first_round.len() + second_round.len()) as u64))
}
