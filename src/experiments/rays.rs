//! Shadow-ray accelerators on real scenes (Wong & Tsang 1993, section 3,
//! at the scale of issue 9): the BSP tree of the paper against the BVH, the
//! brute-force oracle and, when a Python with the `embreex` package is
//! given, Intel's Embree, all on the same shadow segments.
//!
//! The segments are the solver's own: a real solve (the default
//! `wong-tsang93` preset, its hemicube pre-test included, visibility answered
//! by a BVH wrapped in a recorder) runs a few shots on each scene, and every
//! segment it casts during the recorded shots (subsource centre to vertex
//! gathering point, shortened by [`accel::shorten`], skipping the source's
//! and receiver's surfaces) is kept. They are put in receiver order, so the
//! sample does not depend on the thread count, and a deterministic sample of
//! blocks of consecutive segments is timed: one thread answers the whole
//! list with each accelerator in turn, repetitions interleaved, and the
//! median per ray is reported. Every accelerator must give the same answer
//! on every segment (the brute-force oracle on an evenly spaced sample): the
//! experiment fails otherwise.
//!
//! Embree (`tools/embree_rays.py`) reads the same triangles (our convex
//! surfaces fanned) and segments from a binary file and times
//! `rtcOccluded1` over them with `tfar` the segment's length, between our
//! own repetitions. It does not skip the source's and receiver's surfaces
//! and works in `f32`, so its answers can differ from ours on a few grazing
//! segments; the agreement is reported.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use glam::DVec3;

use super::{Context, Error, Report, median, table};
use crate::accel::Occluder;
use crate::accel::brute::BruteForce;
use crate::accel::bsp::Bsp;
use crate::accel::bvh::Bvh;
use crate::app;
use crate::mesh::{Mesh, MeshSettings};
use crate::scene::{self, Scene};
use crate::solver::{Flow, Settings, Solver};

/// The Embree benchmark script, written next to its data when it is run.
const EMBREE_SCRIPT: &str = include_str!("../../tools/embree_rays.py");

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
fn scenes_folder(context: &Context, wanted: &[SceneSpec]) -> Result<PathBuf, Error> {
    let candidates: Vec<PathBuf> = match &context.scenes {
        Some(dir) => vec![dir.clone()],
        None => vec![
            PathBuf::from(DEFAULT_SCENES),
            Path::new(env!("CARGO_MANIFEST_DIR")).join(DEFAULT_SCENES),
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
    let looked: Vec<String> = candidates
        .iter()
        .map(|d| format!("{}", d.display()))
        .collect();
    Err(Error::Experiment(format!(
        "the real scenes ({}) are not in {}: give the folder holding them with --scenes DIR",
        needed.join(", "),
        looked.join(" nor in ")
    )))
}

/// `radiosity experiment rays`: every scene of [`SCENES`].
pub fn rays(context: &Context) -> Result<Report, Error> {
    rays_on(context, &SCENES)
}

/// Timings of one accelerator on one scene.
#[derive(Clone, Debug, Default)]
struct Timing {
    build_seconds: Vec<f64>,
    ns_per_ray: Vec<f64>,
}

/// The experiment on the given scenes.
pub fn rays_on(context: &Context, scenes: &[SceneSpec]) -> Result<Report, Error> {
    let folder = if scenes.iter().any(|s| s.shared) {
        Some(scenes_folder(context, scenes)?)
    } else {
        None
    };
    let mut report = Report::default();
    let repetitions = context.repetitions();
    report.setting("repetitions (interleaved; medians)", repetitions);
    report.setting(
        "recorded shots",
        format!("{:?}", recorded_shots(context.quick)),
    );
    report.setting(
        "threads",
        "one per accelerator while timing (the recording solve uses every core)",
    );
    if let Some(folder) = &folder {
        report.setting("scenes", folder.display());
    }
    report.setting(
        "embree",
        match &context.embree_python {
            Some(p) => format!("{} tools/embree_rays.py", p.display()),
            None => "not measured (give --embree-python PYTHON with embreex installed)".into(),
        },
    );
    let mut segment_rows = Vec::new();
    let mut time_rows = Vec::new();
    let mut build_rows = Vec::new();
    for spec in scenes {
        let path = match (&folder, spec.shared) {
            (Some(folder), true) => folder.join(spec.source).display().to_string(),
            _ => spec.source.to_string(),
        };
        let scene = scene::load(&path).map_err(app::Error::from)?;
        let sizes = scene.default_mesh_sizes();
        let mesh = Mesh::build(
            &scene,
            &MeshSettings {
                patch_size: sizes.patch_size,
                element_size: sizes.element_size,
                ..MeshSettings::default()
            },
        )
        .map_err(|e| Error::App(app::Error::Mesh(e)))?;
        let shots = recorded_shots(context.quick);
        let recorded = record(&scene, &mesh, shots);
        let segments = sample(&recorded, segment_budget(context.quick));
        let outcome = measure(context, spec.name, &scene, &segments)?;
        segment_rows.push(vec![
            spec.name.to_string(),
            scene.surfaces.len().to_string(),
            mesh.vertices.len().to_string(),
            recorded.len().to_string(),
            segments.len().to_string(),
            format!(
                "{:.1}%",
                100.0 * outcome.blocked as f64 / segments.len().max(1) as f64
            ),
            outcome.brute_checked.to_string(),
            match outcome.embree_agreement {
                Some(a) => format!("{:.3}%", 100.0 * a),
                None => "-".into(),
            },
        ]);
        let ns = |t: &Timing| median(&mut t.ns_per_ray.clone());
        let (bsp, bvh) = (ns(&outcome.bsp), ns(&outcome.bvh));
        let embree = outcome.embree.as_ref().map(ns);
        let cell = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.0}"));
        time_rows.push(vec![
            spec.name.to_string(),
            format!("{bsp:.0}"),
            format!("{bvh:.0}"),
            cell(embree),
            format!("{:.0}", ns(&outcome.brute)),
            format!("{:.2}", bsp / bvh),
            embree.map_or("-".to_string(), |e| format!("{:.2}", e / bvh)),
        ]);
        for (name, timing, stats, per_ray) in [
            (
                "bsp",
                &outcome.bsp,
                &outcome.bsp_stats,
                &outcome.bsp_per_ray,
            ),
            (
                "bvh",
                &outcome.bvh,
                &outcome.bvh_stats,
                &outcome.bvh_per_ray,
            ),
        ] {
            let stat = |key: &str| {
                stats
                    .iter()
                    .find(|(k, _)| *k == key)
                    .map_or("-".to_string(), |(_, v)| v.to_string())
            };
            build_rows.push(vec![
                spec.name.to_string(),
                name.to_string(),
                format!("{:.3}", median(&mut timing.build_seconds.clone())),
                stat("nodes"),
                stat("depth"),
                stat("fragments"),
                stats
                    .iter()
                    .find(|(k, _)| *k == "bytes")
                    .map_or("-".to_string(), |(_, v)| format!("{:.1}", *v as f64 / 1e6)),
                format!("{:.1}", per_ray[0]),
                format!("{:.1}", per_ray[1]),
            ]);
        }
        if let Some(e) = &outcome.embree {
            build_rows.push(vec![
                spec.name.to_string(),
                "embree".into(),
                format!("{:.3}", median(&mut e.build_seconds.clone())),
                "-".into(),
                "-".into(),
                "-".into(),
                "-".into(),
                "-".into(),
                "-".into(),
            ]);
        }
    }
    report.paragraph(
        "Segments: those the solver cast in the recorded shots, then a deterministic sample \
         of blocks of 256 consecutive ones (in receiver order). Blocked: the share every \
         accelerator found blocked; brute force checked the answers on an evenly spaced \
         sample; Embree's agreement is with our answers.",
    );
    report.body.push_str(&table(
        &[
            "scene",
            "surfaces",
            "vertices",
            "segments recorded",
            "segments timed",
            "blocked",
            "checked by brute force",
            "embree agrees",
        ],
        &segment_rows,
    ));
    report.paragraph(
        "Time per shadow ray, one thread (nanoseconds, median of the interleaved repetitions; \
         brute force on its sample). bsp/bvh is the BSP's time over the BVH's (target: at \
         most 3); embree/bvh is Embree's time over the BVH's (target: at least 0.5, i.e. the \
         BVH reaches half of Embree's throughput).",
    );
    report.body.push_str(&table(
        &[
            "scene",
            "bsp ns",
            "bvh ns",
            "embree ns",
            "brute ns",
            "bsp/bvh",
            "embree/bvh",
        ],
        &time_rows,
    ));
    report.paragraph(
        "Builds (median seconds, one thread for ours; Embree's own build uses its thread \
         pool) and sizes: bytes are the accelerator's own arrays (the prepared surfaces they \
         share with brute force excluded). Per ray: surfaces tested with the exact segment \
         test and tree nodes visited, means over the timed segments.",
    );
    report.body.push_str(&table(
        &[
            "scene",
            "accelerator",
            "build s",
            "nodes",
            "depth",
            "fragments",
            "MB",
            "tests/ray",
            "nodes/ray",
        ],
        &build_rows,
    ));
    Ok(report)
}

/// Runs a solve (the `wong-tsang93` preset, visibility by a recording BVH)
/// and returns the segments cast during `shots` (1-based), in receiver
/// order.
pub fn record(scene: &Scene, mesh: &Mesh, shots: &[u64]) -> Vec<Segment> {
    let log = Mutex::new(Vec::new());
    let recording = AtomicBool::new(shots.contains(&1));
    let last = shots.iter().copied().max().unwrap_or(0);
    {
        let settings = Settings {
            max_shots: Some(last),
            ..Settings::wong_tsang93()
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

/// What [`measure`] found on one scene.
struct Outcome {
    bsp: Timing,
    bvh: Timing,
    brute: Timing,
    embree: Option<Timing>,
    bsp_stats: Vec<(&'static str, usize)>,
    bvh_stats: Vec<(&'static str, usize)>,
    /// Mean surfaces tested and nodes visited per ray.
    bsp_per_ray: [f64; 2],
    bvh_per_ray: [f64; 2],
    blocked: usize,
    brute_checked: usize,
    embree_agreement: Option<f64>,
}

/// Seconds for one thread to answer every segment; the answers' count of
/// blocked ones goes to `blocked`.
fn time_queries(occluder: &dyn Occluder, segments: &[Segment], blocked: &mut usize) -> f64 {
    let start = Instant::now();
    let mut count = 0;
    for s in segments {
        count += usize::from(occluder.occluded(std::hint::black_box(s.from), s.to, s.skip));
    }
    let seconds = start.elapsed().as_secs_f64();
    *blocked = count;
    seconds
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
        bsp: Timing::default(),
        bvh: Timing::default(),
        brute: Timing::default(),
        embree: None,
        bsp_stats: Vec::new(),
        bvh_stats: Vec::new(),
        bsp_per_ray: [0.0; 2],
        bvh_per_ray: [0.0; 2],
        blocked: 0,
        brute_checked: 0,
        embree_agreement: None,
    };
    // Builds, interleaved.
    for _ in 0..repetitions.min(3) {
        let start = Instant::now();
        let bsp = Bsp::new(surfaces);
        outcome
            .bsp
            .build_seconds
            .push(start.elapsed().as_secs_f64());
        outcome.bsp_stats = bsp.build_statistics();
        drop(bsp);
        let start = Instant::now();
        let bvh = Bvh::new(surfaces);
        outcome
            .bvh
            .build_seconds
            .push(start.elapsed().as_secs_f64());
        outcome.bvh_stats = bvh.build_statistics();
    }
    let bsp = Bsp::new(surfaces);
    let bvh = Bvh::new(surfaces);
    let brute = BruteForce::new(surfaces);

    // Answers: identical everywhere, brute force on its sample.
    let answers: Vec<bool> = segments
        .iter()
        .map(|s| bvh.occluded(s.from, s.to, s.skip))
        .collect();
    let (mut bsp_tests, mut bsp_nodes, mut bvh_tests, mut bvh_nodes) = (0u64, 0u64, 0u64, 0u64);
    for (s, &expected) in segments.iter().zip(&answers) {
        let (b, tests, nodes) = bsp.occluded_counting(s.from, s.to, s.skip);
        bsp_tests += u64::from(tests);
        bsp_nodes += u64::from(nodes);
        let (v, tests, nodes) = bvh.occluded_counting(s.from, s.to, s.skip);
        bvh_tests += u64::from(tests);
        bvh_nodes += u64::from(nodes);
        if b != expected || v != expected {
            return Err(Error::Experiment(format!(
                "{name}: the BSP says {b} and the BVH {v} for the segment {:?} -> {:?} \
                 skipping {:?}",
                s.from, s.to, s.skip
            )));
        }
    }
    for s in &brute_sample {
        let expected = brute.occluded(s.from, s.to, s.skip);
        if bvh.occluded(s.from, s.to, s.skip) != expected {
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
    outcome.bsp_per_ray = [bsp_tests as f64 / n, bsp_nodes as f64 / n];
    outcome.bvh_per_ray = [bvh_tests as f64 / n, bvh_nodes as f64 / n];

    let embree = match &context.embree_python {
        Some(python) => Some(EmbreeRun::prepare(python, name, scene, segments, &answers)?),
        None => None,
    };
    // Timings, interleaved: each round runs every accelerator once, the
    // starting one rotating.
    let mut embree_timing = Timing::default();
    for round in 0..repetitions {
        for k in 0..4 {
            let mut blocked = 0;
            match (round + k) % 4 {
                0 => {
                    let s = time_queries(&bsp, segments, &mut blocked);
                    outcome.bsp.ns_per_ray.push(1e9 * s / n);
                }
                1 => {
                    let s = time_queries(&bvh, segments, &mut blocked);
                    outcome.bvh.ns_per_ray.push(1e9 * s / n);
                }
                2 => {
                    let s = time_queries(&brute, &brute_sample, &mut blocked);
                    outcome
                        .brute
                        .ns_per_ray
                        .push(1e9 * s / brute_sample.len().max(1) as f64);
                }
                _ => {
                    if let Some(run) = &embree {
                        let result = run.run()?;
                        embree_timing.ns_per_ray.push(result.ns_per_ray);
                        embree_timing.build_seconds.push(result.build_seconds);
                        outcome.embree_agreement = Some(result.agreement);
                    }
                }
            }
        }
    }
    if embree.is_some() {
        outcome.embree = Some(embree_timing);
    }
    Ok(outcome)
}

/// The Embree script and its data in a temporary folder, removed on drop.
struct EmbreeRun {
    python: PathBuf,
    dir: PathBuf,
}

/// One run of the Embree script.
struct EmbreeResult {
    ns_per_ray: f64,
    build_seconds: f64,
    agreement: f64,
}

impl EmbreeRun {
    fn prepare(
        python: &Path,
        name: &str,
        scene: &Scene,
        segments: &[Segment],
        answers: &[bool],
    ) -> Result<EmbreeRun, Error> {
        let dir =
            std::env::temp_dir().join(format!("radiosity-rays-{}-{name}", std::process::id()));
        let output = |source| Error::Output {
            path: std::env::temp_dir(),
            source,
        };
        std::fs::create_dir_all(&dir).map_err(output)?;
        let run = EmbreeRun {
            python: python.to_path_buf(),
            dir,
        };
        std::fs::write(run.dir.join("embree_rays.py"), EMBREE_SCRIPT).map_err(output)?;
        let file = std::fs::File::create(run.dir.join("rays.bin")).map_err(output)?;
        let mut w = std::io::BufWriter::new(file);
        write_rays(&mut w, scene, segments, answers)
            .and_then(|()| w.flush())
            .map_err(output)?;
        Ok(run)
    }

    fn run(&self) -> Result<EmbreeResult, Error> {
        let out = Command::new(&self.python)
            .arg(self.dir.join("embree_rays.py"))
            .arg(self.dir.join("rays.bin"))
            .output()
            .map_err(|e| Error::Experiment(format!("cannot run {}: {e}", self.python.display())))?;
        let text = String::from_utf8_lossy(&out.stdout);
        if !out.status.success() {
            return Err(Error::Experiment(format!(
                "{} tools/embree_rays.py failed: {}",
                self.python.display(),
                String::from_utf8_lossy(&out.stderr).trim()
            )));
        }
        let value: serde_json::Value = serde_json::from_str(text.trim()).map_err(|e| {
            Error::Experiment(format!("tools/embree_rays.py printed {text:?}: {e}"))
        })?;
        let field = |k: &str| {
            value[k].as_f64().ok_or_else(|| {
                Error::Experiment(format!("tools/embree_rays.py gave no {k} in {text:?}"))
            })
        };
        Ok(EmbreeResult {
            ns_per_ray: field("ns_per_ray")?,
            build_seconds: field("build_seconds")?,
            agreement: field("agreement")?,
        })
    }
}

impl Drop for EmbreeRun {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// The binary file `tools/embree_rays.py` reads, little-endian:
/// `b"RADRAYS1"`, the triangle count `T` and segment count `S` (`u64`),
/// `T x 9` `f64` triangle corners (each convex surface fanned from its
/// first corner), `S x 6` `f64` segment ends (`from`, `to`), `S` bytes of
/// our answers (1 = blocked).
pub fn write_rays(
    w: &mut impl std::io::Write,
    scene: &Scene,
    segments: &[Segment],
    answers: &[bool],
) -> std::io::Result<()> {
    let triangles: Vec<[DVec3; 3]> = scene
        .surfaces
        .iter()
        .flat_map(|s| {
            let p = &s.polygon;
            (1..p.len() - 1).map(move |i| [p[0], p[i], p[i + 1]])
        })
        .collect();
    w.write_all(b"RADRAYS1")?;
    w.write_all(&(triangles.len() as u64).to_le_bytes())?;
    w.write_all(&(segments.len() as u64).to_le_bytes())?;
    for t in &triangles {
        for p in t {
            for c in p.to_array() {
                w.write_all(&c.to_le_bytes())?;
            }
        }
    }
    for s in segments {
        for c in s.from.to_array().into_iter().chain(s.to.to_array()) {
            w.write_all(&c.to_le_bytes())?;
        }
    }
    let bytes: Vec<u8> = answers.iter().map(|&a| u8::from(a)).collect();
    w.write_all(&bytes)
}
