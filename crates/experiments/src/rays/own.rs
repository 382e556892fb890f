//! The default method's own shadow segments (adaptive shooting, beyond
//! the paper), beside the paper preset's that the rest of the experiment
//! times: a shooter's node samples and elements to vertices, each receiver
//! walking the source for itself, so the segments a BVH answers in a real
//! default solve. A solve of the default settings (visibility by a
//! recording BVH, the base mesh) records the segments of `shots`; a
//! sample is checked against brute force and timed on the BVH and, when
//! given, Embree, interleaved, as the paper preset's are.

use radiosity::accel::brute::BruteForce;
use radiosity::accel::bvh::Bvh;
use radiosity::accel::{Occluder, ShadowCache};
use radiosity::mesh::Mesh;
use radiosity::scene::Scene;
use radiosity::solver::Settings;

use super::embree::EmbreeRun;
use super::report::share;
use super::{
    Clock, Rays, Segment, Timing, brute_budget, record_with, sample, segment_budget, time_queries,
};
use crate::{Context, Error, Report, table};

/// The default method's shots whose segments are recorded (1-based): the
/// first comes from a light source, the twelfth from a reflector
/// (one shot in quick mode).
fn shots(quick: bool) -> &'static [u64] {
    if quick { &[1] } else { &[1, 12] }
}

/// What the BVH and Embree did on the default method's segments of one
/// scene.
#[derive(Clone, Debug, Default)]
pub struct Own {
    /// The shots recorded (1-based).
    pub shots: &'static [u64],
    /// Segments the default solve cast in the recorded shots.
    pub recorded: usize,
    /// Segments timed (the sample).
    pub timed: usize,
    /// Of those, blocked.
    pub blocked: usize,
    /// Segments checked against brute force.
    pub brute_checked: usize,
    /// The BVH's timings.
    pub bvh: Timing,
    /// The BVH's through a shadow cache carried from segment to segment
    /// in the order the solve cast them.
    pub bvh_cached: Timing,
    /// Segments the shadow cache answered.
    pub cache_hits: u64,
    /// Mean surfaces tested and child boxes tested per ray by the BVH.
    pub per_ray: [f64; 2],
    /// Embree's, when a Python with `embreex` was given.
    pub embree: Option<Timing>,
    /// The share of segments on which Embree agrees with us.
    pub embree_agreement: Option<f64>,
}

/// Records the default method's segments on `mesh` and times them.
///
/// # Errors
///
/// When the BVH disagrees with brute force, or Embree fails.
pub fn measure(context: &Context, name: &str, scene: &Scene, mesh: &Mesh) -> Result<Own, Error> {
    let recorded = record_with(scene, mesh, shots(context.quick), Settings::adaptive());
    let segments = sample(&recorded, segment_budget(context.quick));
    let bvh = Bvh::new(&scene.surfaces);
    let brute = BruteForce::new(&scene.surfaces);
    let mut own = Own {
        shots: shots(context.quick),
        recorded: recorded.len(),
        timed: segments.len(),
        ..Own::default()
    };
    drop(recorded);
    let mut answers = Vec::with_capacity(segments.len());
    let mut totals = [0u64; 2];
    for s in &segments {
        let (blocked, tests, boxes) = bvh.occluded_counting(s.from, s.to, s.skip);
        totals[0] += u64::from(tests);
        totals[1] += u64::from(boxes);
        answers.push(blocked);
    }
    let n = segments.len().max(1);
    own.per_ray = totals.map(|t| t as f64 / n as f64);
    own.blocked = answers.iter().filter(|&&a| a).count();
    let checks = brute_budget(context.quick, scene.surfaces.len()).min(segments.len());
    for k in 0..checks {
        let i = k * segments.len() / checks.max(1);
        let s = &segments[i];
        if brute.occluded(s.from, s.to, s.skip) != answers[i] {
            return Err(Error::Experiment(format!(
                "{name}: on the default method's segment {:?} -> {:?} skipping {:?} the BVH \
                 and brute force disagree",
                s.from, s.to, s.skip
            )));
        }
    }
    own.brute_checked = checks;
    let embree = match &context.embree_python {
        Some(python) => Some(EmbreeRun::prepare(
            python,
            &format!("{name}-own"),
            scene,
            &segments,
            &answers,
        )?),
        None => None,
    };
    let mut embree_timing = Timing::default();
    for round in 0..context.repetitions() {
        for i in 0..2 {
            if (round + i) % 2 == 0 {
                let seconds = time_queries(&bvh, &segments);
                own.bvh.ns_per_ray.push(1e9 * seconds / n as f64);
                let (seconds, hits) = time_cached_queries(&bvh, &segments);
                own.bvh_cached.ns_per_ray.push(1e9 * seconds / n as f64);
                own.cache_hits = hits;
            } else if let Some(run) = &embree {
                own.embree_agreement = Some(run.time_into(&mut embree_timing)?);
            }
        }
    }
    if embree.is_some() {
        own.embree = Some(embree_timing);
    }
    Ok(own)
}

/// [`time_queries`] through one [`ShadowCache`] carried from segment to
/// segment, as a solver's thread carries it.
fn time_cached_queries(occluder: &dyn Occluder, segments: &[Segment]) -> (f64, u64) {
    let clock = Clock::start();
    let mut count = 0usize;
    let mut cache = ShadowCache::default();
    for s in segments {
        count += usize::from(occluder.occluded_cached(
            std::hint::black_box(s.from),
            s.to,
            s.skip,
            &mut cache,
        ));
    }
    std::hint::black_box(count);
    (clock.seconds(), cache.hits)
}

/// The report's table of the default method's segments.
pub fn report(data: &Rays, report: &mut Report) {
    let rows: Vec<Vec<String>> = data
        .scenes
        .iter()
        .map(|measured| {
            let own = &measured.own;
            let bvh = own.bvh.per_ray();
            let embree = own.embree.as_ref().map(Timing::per_ray);
            let cached = own.bvh_cached.per_ray();
            vec![
                measured.name.to_string(),
                own.recorded.to_string(),
                own.timed.to_string(),
                share(own.blocked as f64, own.timed as f64),
                own.brute_checked.to_string(),
                format!("{:.1}", own.per_ray[0]),
                format!("{:.1}", own.per_ray[1]),
                format!("{bvh:.0}"),
                format!("{cached:.0}"),
                share(own.cache_hits as f64, own.timed as f64),
                embree.map_or("-".into(), |e| format!("{e:.0}")),
                embree.map_or("-".into(), |e| format!("{:.2}", e / bvh)),
                embree.map_or("-".into(), |e| format!("{:.2}", e / cached)),
                own.embree_agreement
                    .map_or("-".into(), |a| format!("{:.2}%", 100.0 * a)),
            ]
        })
        .collect();
    let recorded = data.scenes.first().map_or(&[][..], |s| s.own.shots);
    report.paragraph(&format!(
        "The default method's own segments (adaptive shooting on the base mesh, shots \
         {recorded:?}: a shooter's node samples and elements to each receiver), sampled and \
         checked the same way, timed on the BVH and Embree only (interleaved; medians). Tests \
         and boxes: per ray, surfaces given the exact test and child boxes tested. Cached: the \
         BVH through a shadow cache (the last two blockers tested first), carried from segment \
         to segment in the order the solve cast them, as its threads carry it; cache hits: the \
         segments it answered; embree/cached: Embree's time over that."
    ));
    report.body.push_str(&table(
        &[
            "scene",
            "segments recorded",
            "segments timed",
            "blocked",
            "checked by brute force",
            "tests/ray",
            "boxes/ray",
            "bvh ns",
            "bvh, cached ns",
            "cache hits",
            "embree ns",
            "embree/bvh",
            "embree/cached",
            "embree agrees",
        ],
        &rows,
    ));
}
