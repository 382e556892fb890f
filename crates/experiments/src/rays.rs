//! Shadow-ray accelerators on real scenes (Wong & Tsang 1993, section 3,
//! at the scale of the Sponza atrium and the conference room, 66k and 277k
//! triangles, beside the paper's room): the BSP tree of the paper against
//! the BVH, the brute-force oracle and, when a Python with the `embreex`
//! package is given, Intel's Embree, all on the same shadow segments.
//!
//! The segments are the solver's own: a real solve (the paper's `wong-tsang93`
//! preset, its hemicube pre-test included, visibility answered by a BVH wrapped
//! in a recorder) runs a few shots on each scene, and every segment it casts
//! during the recorded shots (subsource centre to vertex gathering point,
//! shortened by [`radiosity::accel::shorten`], skipping the source's and
//! receiver's surfaces) is kept. They are put in receiver order, so the sample
//! does not depend on the thread count, and a deterministic sample of blocks of
//! consecutive segments is timed: one thread answers the whole list with each
//! accelerator in turn, repetitions interleaved, and the median per ray is
//! reported. Times are the timing thread's CPU time where the system has that
//! clock, so a shared machine's other jobs (waiting for a core) do not count;
//! they still share the caches. Every accelerator must give the same answer on
//! every segment (the brute-force oracle on an evenly spaced sample): the
//! experiment fails otherwise.
//!
//! With `--device gpu` (or a real GPU under the default `auto`), [`gpu`]
//! also traces every recorded segment on the GPU and reports its
//! throughput beside the CPU's.
//!
//! Embree ([`embree`], `tools/embree_rays.py`) reads the same triangles
//! (our convex surfaces fanned) and segments from a binary file and times
//! `rtcOccluded1` over them with `tfar` the segment's length, between our
//! own repetitions. It does not skip the source's and receiver's surfaces
//! and works in `f32`, so its answers can differ from ours on a few grazing
//! segments; the agreement is reported.

pub mod embree;
pub mod gpu;
pub mod own;
mod report;

pub use report::rays_report;

use std::path::PathBuf;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use glam::DVec3;

use super::{Context, Error, Report, median};
use embree::EmbreeRun;
use radiosity::accel::brute::BruteForce;
use radiosity::accel::bsp::{Bsp, BspSettings};
use radiosity::accel::bvh::Bvh;
use radiosity::accel::{Hit, Occluder};
use radiosity::app;
use radiosity::mesh::{Mesh, MeshSettings};
use radiosity::scene::{self, Scene, Surface};
use radiosity::solver::{Flow, Settings, Solver};

/// Where the shared scenes are looked for when no folder is given, relative
/// to the working directory and to the source tree.
const DEFAULT_SCENES: &str = "../shared/scenes";

/// One shadow query as the solver asked it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    /// Start (on the subsource side, already shortened).
    pub from: DVec3,
    /// End (at the receiver, already shortened).
    pub to: DVec3,
    /// The surfaces the query skips.
    pub skip: [u32; 2],
}

/// An occluder that logs every query while `recording` is set.
struct Recorder<'a> {
    inner: Box<dyn Occluder + 'a>,
    log: &'a Mutex<Vec<Segment>>,
    recording: &'a AtomicBool,
}

impl Occluder for Recorder<'_> {
    fn occluded(&self, from: DVec3, to: DVec3, skip: [u32; 2]) -> bool {
        if self.recording.load(Ordering::Relaxed) {
            let mut log = self
                .log
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner);
            log.push(Segment { from, to, skip });
        }
        self.inner.occluded(from, to, skip)
    }

    /// Not logged: only [`Occluder::occluded`] is what the solver calls.
    fn occluded_counting(&self, from: DVec3, to: DVec3, skip: [u32; 2]) -> (bool, u32, u32) {
        self.inner.occluded_counting(from, to, skip)
    }

    /// Not logged: the solver casts shadow segments only.
    fn closest_hit(
        &self,
        origin: DVec3,
        direction: DVec3,
        max_t: f64,
        skip: [u32; 2],
    ) -> Option<Hit> {
        self.inner.closest_hit(origin, direction, max_t, skip)
    }

    fn validate(&self) -> Result<(), radiosity::accel::InvalidTree> {
        self.inner.validate()
    }
}

/// A scene of the experiment and where it comes from.
#[derive(Clone, Debug)]
pub struct SceneSpec {
    /// Short name for the tables.
    pub name: &'static str,
    /// A built-in name, or a path relative to the scenes folder.
    pub source: &'static str,
    /// Whether `source` is in the scenes folder (else built in).
    pub shared: bool,
}

/// The scenes of `radiosity experiment rays`.
pub const SCENES: [SceneSpec; 3] = [
    SceneSpec {
        name: "room",
        source: "room",
        shared: false,
    },
    SceneSpec {
        name: "sponza",
        source: "sponza_dabrovic/sponza_dabrovic.obj",
        shared: true,
    },
    SceneSpec {
        name: "conference",
        source: "conference/conference.obj",
        shared: true,
    },
];

/// Shots whose segments are recorded (1-based): the first shots come from
/// the light sources, the later ones from reflectors.
fn recorded_shots(quick: bool) -> &'static [u64] {
    if quick { &[1] } else { &[1, 2, 12, 13] }
}

/// Segments timed per scene.
fn segment_budget(quick: bool) -> usize {
    if quick { 4_096 } else { 200_000 }
}

/// Segments checked against (and timed with) brute force per scene: it
/// costs a test of every surface.
fn brute_budget(quick: bool, surfaces: usize) -> usize {
    let full = if quick {
        200
    } else {
        400_000_000 / surfaces.max(1)
    };
    full.clamp(50, 20_000)
}

/// Consecutive segments kept together when sampling, so the sample keeps
/// the solver's locality (a receiver's segments from every subsource).
const BLOCK: usize = 256;

/// The folder holding the shared scenes: the context's, or
/// [`DEFAULT_SCENES`] from the working directory or the source tree.
pub(crate) fn scenes_folder(context: &Context, wanted: &[SceneSpec]) -> Result<PathBuf, Error> {
    let candidates: Vec<PathBuf> = match &context.scenes {
        Some(dir) => vec![dir.clone()],
        None => vec![
            PathBuf::from(DEFAULT_SCENES),
            crate::reference::source_root().join(DEFAULT_SCENES),
        ],
    };
    let needed: Vec<&str> = wanted
        .iter()
        .filter(|s| s.shared)
        .map(|s| s.source)
        .collect();
    for dir in &candidates {
        if needed.iter().all(|f| dir.join(f).is_file()) {
            return Ok(dir.clone());
        }
    }
    Err(Error::Experiment(format!(
        "the real scenes ({}) are not in {}: give the folder holding them with --scenes DIR",
        needed.join(", "),
        crate::reference::nor_in(&candidates)
    )))
}

/// `radiosity experiment rays`: every scene of [`SCENES`].
pub fn rays(context: &Context) -> Result<Report, Error> {
    rays_on(context, &SCENES)
}

/// Timings of one accelerator on one scene.
#[derive(Clone, Debug, Default)]
pub struct Timing {
    /// Seconds of each build.
    pub build_seconds: Vec<f64>,
    /// Nanoseconds per ray of each timed repetition.
    pub ns_per_ray: Vec<f64>,
}

impl Timing {
    /// The median build time in seconds.
    #[must_use]
    pub fn build(&self) -> f64 {
        median(&mut self.build_seconds.clone())
    }

    /// The median time per ray in nanoseconds.
    #[must_use]
    pub fn per_ray(&self) -> f64 {
        median(&mut self.ns_per_ray.clone())
    }
}

/// Our accelerators, in the tables' order: the default BSP, the BSP on
/// surface planes only (the paper's auto-partition), the BVH.
pub const OURS: [&str; 3] = ["bsp", "bsp, surface planes only", "bvh"];

/// One of [`OURS`], built.
enum Built<'a> {
    Bsp(Bsp<'a>),
    Bvh(Bvh<'a>),
}

impl<'a> Built<'a> {
    fn new(k: usize, surfaces: &'a [Surface]) -> Built<'a> {
        match k {
            0 => Built::Bsp(Bsp::with_settings(surfaces, BspSettings::sah())),
            1 => Built::Bsp(Bsp::with_settings(surfaces, BspSettings::auto_partition())),
            _ => Built::Bvh(Bvh::new(surfaces)),
        }
    }

    fn occluder(&self) -> &dyn Occluder {
        match self {
            Built::Bsp(b) => b,
            Built::Bvh(b) => b,
        }
    }

    /// `(blocked, surfaces tested, nodes or child boxes visited)`.
    fn counting(&self, s: &Segment) -> (bool, u32, u32) {
        match self {
            Built::Bsp(b) => b.occluded_counting(s.from, s.to, s.skip),
            Built::Bvh(b) => b.occluded_counting(s.from, s.to, s.skip),
        }
    }
}

/// What `measure` found on one scene.
#[derive(Clone, Debug)]
pub struct Outcome {
    /// Per accelerator of [`OURS`].
    pub ours: Vec<Timing>,
    /// Per accelerator of [`OURS`], its build statistics (name, value).
    pub stats: Vec<Vec<(&'static str, usize)>>,
    /// Per accelerator of [`OURS`], mean surfaces tested and nodes visited
    /// per ray.
    pub per_ray: Vec<[f64; 2]>,
    /// Brute force on its sample of the segments.
    pub brute: Timing,
    /// Embree, when a Python with `embreex` was given.
    pub embree: Option<Timing>,
    /// Segments found blocked.
    pub blocked: usize,
    /// Segments checked against brute force.
    pub brute_checked: usize,
    /// The share of segments on which Embree agrees with us.
    pub embree_agreement: Option<f64>,
}

/// One scene of the `rays` experiment.
#[derive(Clone, Debug)]
pub struct RaysScene {
    /// The scene's name in [`SCENES`].
    pub name: &'static str,
    /// Its surfaces.
    pub surfaces: usize,
    /// Segments the solver cast in the recorded shots.
    pub recorded: usize,
    /// Segments timed (the sample of the recorded ones).
    pub timed: usize,
    /// What the accelerators did on them.
    pub outcome: Outcome,
    /// The BVH and Embree on the default method's own segments.
    pub own: own::Own,
    /// What the GPU did on every recorded segment, when one was used.
    pub gpu: Option<gpu::GpuRun>,
}

/// What the `rays` experiment measures, and how.
#[derive(Clone, Debug)]
pub struct Rays {
    /// Repetitions of every timing (interleaved; medians).
    pub repetitions: usize,
    /// The shots whose segments are recorded (1-based).
    pub recorded_shots: &'static [u64],
    /// Whether times are the thread's CPU time (else wall time).
    pub thread_clock: bool,
    /// The SIMD lanes the BVH's walks tested a node's boxes in
    /// ([`radiosity::accel::bvh::slab_lanes`]).
    pub slab_lanes: usize,
    /// The folder of the shared scenes, if any was needed.
    pub folder: Option<PathBuf>,
    /// The Python that ran Embree, if any.
    pub embree_python: Option<PathBuf>,
    /// The GPU adapter used, if any (name and backend).
    pub adapter: Option<String>,
    /// One entry per scene, in the order given.
    pub scenes: Vec<RaysScene>,
}

/// Records each scene's shadow segments and times every accelerator on
/// them.
///
/// # Errors
///
/// If a scene is missing or does not mesh, the accelerators disagree, or
/// Embree fails.
pub fn rays_compute(context: &Context, scenes: &[SceneSpec]) -> Result<Rays, Error> {
    let folder = if scenes.iter().any(|s| s.shared) {
        Some(scenes_folder(context, scenes)?)
    } else {
        None
    };
    let device = radiosity_gpu::Gpu::open(context.device)
        .map_err(|e| Error::Experiment(format!("--device: {e}")))?;
    let mut measured = Vec::new();
    for spec in scenes {
        let path = match (&folder, spec.shared) {
            (Some(folder), true) => folder.join(spec.source).display().to_string(),
            _ => spec.source.to_string(),
        };
        let scene = scene::load(&path).map_err(app::Error::from)?;
        let mesh = Mesh::build(&scene, &MeshSettings::default().sized_for(&scene))
            .map_err(|e| Error::App(app::Error::Mesh(e)))?;
        let recorded = record(&scene, &mesh, recorded_shots(context.quick));
        let segments = sample(&recorded, segment_budget(context.quick));
        let own = own::measure(context, spec.name, &scene, &mesh)?;
        drop(mesh);
        let outcome = measure(context, spec.name, &scene, &segments)?;
        let gpu = match &device {
            Some(device) => Some(gpu::measure(
                device,
                &scene,
                &recorded,
                context.repetitions(),
            )?),
            None => None,
        };
        measured.push(RaysScene {
            name: spec.name,
            surfaces: scene.surfaces.len(),
            recorded: recorded.len(),
            timed: segments.len(),
            outcome,
            own,
            gpu,
        });
    }
    Ok(Rays {
        repetitions: context.repetitions(),
        recorded_shots: recorded_shots(context.quick),
        thread_clock: thread_cpu_seconds().is_some(),
        slab_lanes: radiosity::accel::bvh::slab_lanes(),
        folder,
        embree_python: context.embree_python.clone(),
        adapter: device.as_ref().map(radiosity_gpu::Gpu::name),
        scenes: measured,
    })
}

/// The experiment on the given scenes.
pub fn rays_on(context: &Context, scenes: &[SceneSpec]) -> Result<Report, Error> {
    Ok(rays_report(&rays_compute(context, scenes)?))
}

/// Runs a solve (the `wong-tsang93` preset, visibility by a recording BVH)
/// and returns the segments cast during `shots` (1-based), in receiver
/// order.
pub fn record(scene: &Scene, mesh: &Mesh, shots: &[u64]) -> Vec<Segment> {
    record_with(scene, mesh, shots, Settings::wong_tsang93())
}

/// [`record`] with the solve's settings given (their shot limit replaced).
pub fn record_with(scene: &Scene, mesh: &Mesh, shots: &[u64], settings: Settings) -> Vec<Segment> {
    let log = Mutex::new(Vec::new());
    let recording = AtomicBool::new(shots.contains(&1));
    let last = shots.iter().copied().max().unwrap_or(0);
    {
        let settings = Settings {
            max_shots: Some(last),
            ..settings
        };
        let recorder = Recorder {
            inner: Box::new(Bvh::new(&scene.surfaces)),
            log: &log,
            recording: &recording,
        };
        let mut solver = Solver::with_occluder(scene, mesh, settings, Box::new(recorder));
        solver.run(|s| {
            let next = s.stats().shots + 1;
            recording.store(shots.contains(&next), Ordering::Relaxed);
            Flow::Continue
        });
    }
    let mut segments = log
        .into_inner()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let key =
        |s: &Segment| [s.to.x, s.to.y, s.to.z, s.from.x, s.from.y, s.from.z].map(f64::to_bits);
    segments.sort_unstable_by_key(key);
    segments
}

/// About `budget` segments: blocks of 256 consecutive ones, evenly
/// spaced.
pub fn sample(segments: &[Segment], budget: usize) -> Vec<Segment> {
    if segments.len() <= budget {
        return segments.to_vec();
    }
    let blocks = budget.div_ceil(BLOCK);
    let stride = segments.len() / blocks;
    (0..blocks)
        .flat_map(|b| {
            let start = b * stride;
            segments[start..(start + BLOCK).min(segments.len())]
                .iter()
                .copied()
        })
        .take(budget)
        .collect()
}

/// Seconds of CPU time the calling thread has used
/// (`CLOCK_THREAD_CPUTIME_ID`), where the system has that clock.
fn thread_cpu_seconds() -> Option<f64> {
    #[cfg(unix)]
    {
        let mut t = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: `clock_gettime` only writes the `timespec` it is given,
        // which lives on this stack frame.
        let status = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &raw mut t) };
        (status == 0).then_some(t.tv_sec as f64 + t.tv_nsec as f64 * 1e-9)
    }
    #[cfg(not(unix))]
    None
}

/// A clock for timings: the thread's CPU time where available, else wall
/// time.
struct Clock(Option<f64>, Instant);

impl Clock {
    fn start() -> Clock {
        Clock(thread_cpu_seconds(), Instant::now())
    }

    fn seconds(&self) -> f64 {
        match (self.0, thread_cpu_seconds()) {
            (Some(a), Some(b)) => b - a,
            _ => self.1.elapsed().as_secs_f64(),
        }
    }
}

/// Seconds for one thread to answer every segment.
fn time_queries(occluder: &dyn Occluder, segments: &[Segment]) -> f64 {
    let clock = Clock::start();
    let mut count = 0usize;
    for s in segments {
        count += usize::from(occluder.occluded(std::hint::black_box(s.from), s.to, s.skip));
    }
    std::hint::black_box(count);
    clock.seconds()
}

fn measure(
    context: &Context,
    name: &str,
    scene: &Scene,
    segments: &[Segment],
) -> Result<Outcome, Error> {
    let surfaces = &scene.surfaces;
    let repetitions = context.repetitions();
    let brute_count = brute_budget(context.quick, surfaces.len()).min(segments.len());
    let brute_sample: Vec<Segment> = (0..brute_count)
        .map(|i| segments[i * segments.len() / brute_count.max(1)])
        .collect();
    let mut outcome = Outcome {
        ours: vec![Timing::default(); OURS.len()],
        stats: vec![Vec::new(); OURS.len()],
        per_ray: vec![[0.0; 2]; OURS.len()],
        brute: Timing::default(),
        embree: None,
        blocked: 0,
        brute_checked: 0,
        embree_agreement: None,
    };
    // Builds, interleaved; the last one of each is kept.
    let mut built: Vec<Option<Built>> = (0..OURS.len()).map(|_| None).collect();
    for _ in 0..repetitions.min(3) {
        for (k, slot) in built.iter_mut().enumerate() {
            *slot = None;
            let clock = Clock::start();
            let b = Built::new(k, surfaces);
            outcome.ours[k].build_seconds.push(clock.seconds());
            outcome.stats[k] = b.occluder().build_statistics();
            *slot = Some(b);
        }
    }
    let built: Vec<Built> = built.into_iter().flatten().collect();
    let brute = BruteForce::new(surfaces);

    // Answers: identical everywhere, brute force on its sample.
    let mut answers = Vec::with_capacity(segments.len());
    let mut totals = vec![[0u64; 2]; OURS.len()];
    for s in segments {
        let mut first = None;
        for (k, b) in built.iter().enumerate() {
            let (blocked, tests, nodes) = b.counting(s);
            totals[k][0] += u64::from(tests);
            totals[k][1] += u64::from(nodes);
            match first {
                None => first = Some(blocked),
                Some(f) if f != blocked => {
                    return Err(Error::Experiment(format!(
                        "{name}: {} says {blocked} and {} says {f} for the segment {:?} -> {:?} \
                         skipping {:?}",
                        OURS[k], OURS[0], s.from, s.to, s.skip
                    )));
                }
                Some(_) => {}
            }
        }
        answers.push(first.unwrap_or(false));
    }
    for (k, s) in brute_sample.iter().enumerate() {
        let expected = brute.occluded(s.from, s.to, s.skip);
        let index = k * segments.len() / brute_count.max(1);
        if answers[index] != expected {
            return Err(Error::Experiment(format!(
                "{name}: brute force says {expected} for the segment {:?} -> {:?} skipping \
                 {:?}, the accelerators do not",
                s.from, s.to, s.skip
            )));
        }
    }
    outcome.brute_checked = brute_sample.len();
    outcome.blocked = answers.iter().filter(|&&a| a).count();
    let n = segments.len().max(1) as f64;
    outcome.per_ray = totals
        .iter()
        .map(|t| [t[0] as f64 / n, t[1] as f64 / n])
        .collect();

    let embree = match &context.embree_python {
        Some(python) => Some(EmbreeRun::prepare(python, name, scene, segments, &answers)?),
        None => None,
    };
    // Timings, interleaved: each round runs every accelerator once, the
    // starting one rotating.
    let mut embree_timing = Timing::default();
    let contestants = OURS.len() + 2;
    for round in 0..repetitions {
        for i in 0..contestants {
            let k = (round + i) % contestants;
            if k < OURS.len() {
                let seconds = time_queries(built[k].occluder(), segments);
                outcome.ours[k].ns_per_ray.push(1e9 * seconds / n);
            } else if k == OURS.len() {
                let seconds = time_queries(&brute, &brute_sample);
                outcome
                    .brute
                    .ns_per_ray
                    .push(1e9 * seconds / brute_sample.len().max(1) as f64);
            } else if let Some(run) = &embree {
                outcome.embree_agreement = Some(run.time_into(&mut embree_timing)?);
            }
        }
    }
    if embree.is_some() {
        outcome.embree = Some(embree_timing);
    }
    Ok(outcome)
}
