//! One render job from scene to files, in four steps ([`run`]): prepare
//! (read the sensor points, load, mesh and refine, the memory and the
//! device checked: `prepare`), solve (design.md section 2), the outputs
//! (the picture, the vertex CSV, the glTF bake, PLY and EXR outputs, the
//! values at sensor points, [`crate::sensors`]: `outputs`, one function
//! each), and the report with the statistics of design.md section 6; and
//! [`export_scene`]. A front end (the `radiosity` command, the live view)
//! only builds a [`Job`] and calls [`run`].

mod bake;
mod error;
mod job;
mod outcome;
mod outputs;
mod prepare;
mod progress;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

pub use self::bake::{bake_colours, bake_values};
pub use self::error::Error;
use self::job::check_output;
pub use self::job::{BakeJob, DEFAULT_PICTURE, ImageJob, Job, MAX_SAMPLES, SensorJob, validate};
pub use self::outcome::{Counts, Outcome, RunSettings, StatsFile};
pub use self::progress::{FINAL_PASS_INTERVAL, Observer, Progress, ProgressMeter, progress_of};

use crate::export::{self, Staged};
use crate::final_gather::{FinalPass, Point};
use crate::memory;
use crate::render;
use crate::scene::{self, LoadOptions};
use crate::solver::{self, Settings, Solver};

/// Runs a job in the current rayon pool: prepare (read, load, mesh, the
/// resources checked), solve, write the outputs, report.
pub fn run(job: &Job, observer: &mut dyn Observer) -> Result<Outcome, Error> {
    let start = Instant::now();
    validate(job)?;
    let (prepared, going_on) = prepare::prepare(job, observer)?;
    let solved = solve(job, &prepared, going_on, observer);
    let write_start = Instant::now();
    let outputs = outputs::write(job, &prepared, &solved.solver, observer)?;
    report(job, &prepared, &solved, outputs, (start, write_start))
}

/// How a picture shows a solve: its size, view and supersampling, and
/// whether the ambient term is added.
#[derive(Clone, Copy, Debug)]
pub struct PictureView {
    /// Pixels across.
    pub width: u32,
    /// Pixels down.
    pub height: u32,
    /// The view.
    pub camera: crate::scene::Camera,
    /// `n x n` samples a pixel.
    pub supersampling: u32,
    /// Whether the ambient term is added (design.md section 5).
    pub ambient: bool,
}

/// The picture of `solver`'s solution, as `radiosity render` writes it and
/// the live view shows it: through the final pass `pass` where one is
/// given (its progress told to `observer` as `picture`; a pass stopped
/// mid-way leaves the rest black, [`FinalPass::cut_short`]), else the
/// mesh's values. Linear radiance; the caller exposes it.
#[must_use]
pub fn picture(
    solver: &Solver<'_>,
    pass: Option<&FinalPass<'_>>,
    view: &PictureView,
    observer: &mut dyn Observer,
) -> render::Image {
    let (scene, mesh) = (solver.scene(), solver.mesh());
    let settings = render::RenderSettings {
        width: view.width,
        height: view.height,
        camera: view.camera,
        supersampling: view.supersampling,
    };
    let display = solver.display_radiosity(view.ambient);
    match pass {
        Some(pass) => {
            let ambient = if view.ambient {
                solver.ambient()
            } else {
                glam::DVec3::ZERO
            };
            let planned = AtomicU64::new(0);
            let colours = pass.vertex_display(&display, ambient);
            outputs::with_progress(observer, "picture", pass, &planned, || {
                render::render_planned(
                    scene,
                    mesh,
                    &colours,
                    &settings,
                    Some(&|points: &[Point]| pass.shade(points)),
                    &|n| planned.store(n, Ordering::Relaxed),
                )
            })
        }
        None => render::render(scene, mesh, &display, &settings),
    }
}

/// A finished solve.
struct Solved<'a> {
    solver: Solver<'a>,
    stop: solver::StopReason,
    solve_time: Duration,
    accel_build_time: Duration,
    /// Warnings: lights shut inside closed geometry.
    enclosed: Vec<String>,
}

/// Solves the prepared mesh, going on from the coarse pass's state.
fn solve<'a>(
    job: &Job,
    prepared: &'a prepare::Prepared,
    going_on: Option<solver::Start>,
    observer: &mut dyn Observer,
) -> Solved<'a> {
    let (scene, settings) = (&prepared.scene, &prepared.settings);
    let solve_start = Instant::now();
    let occluder = settings.accel.build(&scene.surfaces);
    let accel_build_time = solve_start.elapsed();
    let mut solver = Solver::resume_or_new(
        scene,
        &prepared.mesh,
        Settings {
            // The coarse pass has had its share of the time limit.
            time_limit: settings
                .time_limit
                .map(|t| t.saturating_sub(Duration::from_secs_f64(prepared.refined_seconds))),
            ..settings.clone()
        },
        going_on,
        prepared.sensor_receivers.clone(),
        occluder,
    );
    if let Some(flag) = observer.interrupt() {
        solver.interrupt_on(flag);
    }
    let enclosed = solver
        .enclosed_lights()
        .into_iter()
        .map(|i| {
            format!(
                "{}: {} is inside closed geometry (its sight lines meet surfaces from behind): \
                 its light cannot get out",
                job.scene, scene.lights[i].name
            )
        })
        .collect();
    let stop = solver.run(|s| observer.shot(s));
    let solve_time = solve_start.elapsed();
    observer.finished(&solver, stop);
    Solved {
        solver,
        stop,
        solve_time,
        accel_build_time,
        enclosed,
    }
}

/// What the run did, with the statistics file staged when asked for, and
/// every staged output moved into place.
fn report(
    job: &Job,
    prepared: &prepare::Prepared,
    solved: &Solved<'_>,
    outputs: outputs::Outputs,
    (start, write_start): (Instant, Instant),
) -> Result<Outcome, Error> {
    let (scene, solver) = (&prepared.scene, &solved.solver);
    let device = solver.device_report();
    let device_fault = [&prepared.coarse_device, &device]
        .into_iter()
        .find_map(|d| d.fault.as_ref().map(|f| (d.name.clone(), f.clone())))
        .map(|(name, fault)| {
            format!(
                "the device {} failed ({fault}): the solve went back to its last checkpoint and \
                 on on the CPU",
                name.unwrap_or_default()
            )
        });
    let mut staged = outputs.staged;
    let mut outcome = Outcome {
        scene: scene.name.clone(),
        counts: Counts {
            patches: solver.shooters(),
            ..prepared.counts
        },
        stats: solver.stats().clone(),
        counters: solver.counters(),
        stop: solved.stop,
        unshot_fraction: solver.unshot_fraction(),
        energy: *solver.energy(),
        load_time: prepared.load_time,
        mesh_time: prepared.mesh_time,
        solve_time: solved.solve_time,
        accel_build_time: solved.accel_build_time,
        write_time: Duration::ZERO,
        final_gather_time: outputs.final_gather_time.unwrap_or(Duration::ZERO),
        total_time: Duration::ZERO,
        threads: rayon::current_num_threads(),
        accel_statistics: solver.accel_statistics(),
        written: Vec::new(),
        unwritten: outputs.unwritten,
        warnings: scene
            .warnings
            .iter()
            .cloned()
            .chain(solved.enclosed.iter().cloned())
            .chain(outputs.lightmap.iter().flat_map(|r| r.warnings.clone()))
            .chain(prepared.device_notes.iter().cloned())
            .chain(device_fault)
            .collect(),
        peak_memory_bytes: None,
        memory_estimate: prepared.memory_estimate.clone(),
        lights: outcome::LightPower::of(scene, solver.light_power()),
        lightmap: outputs.lightmap,
        device,
    };
    outcome.peak_memory_bytes = memory::peak_resident_bytes();
    outcome.write_time = write_start.elapsed();
    if let Some(path) = &job.stats_json {
        outcome.total_time = start.elapsed();
        let file = StatsFile::of(&prepared.settings, job.final_gather, &outcome);
        staged.push(
            Staged::write(path, |w| file.write(w)).map_err(|source| Error::Output {
                path: path.clone(),
                source,
            })?,
        );
    }
    outcome.written = commit_all(staged)?;
    outcome.total_time = start.elapsed();
    outcome.peak_memory_bytes = memory::peak_resident_bytes();
    Ok(outcome)
}

/// `radiosity export-scene`: writes a built-in or file scene as glTF
/// (`.glb`, or `.gltf` with its `.bin`), staged like every output. Returns
/// the files written.
pub fn export_scene(scene: &str, out: &Path, load: &LoadOptions) -> Result<Vec<PathBuf>, Error> {
    load.validate()?;
    check_output(out, &["glb", "gltf"], "export-scene")?;
    let loaded = scene::load_with(scene, load)?;
    solver::sky::portals::check_scene(&loaded.scene)?;
    let files = export::gltf::export_scene(&loaded.scene, out).map_err(|source| Error::Output {
        path: out.to_path_buf(),
        source,
    })?;
    let mut staged = Vec::new();
    for (path, bytes) in &files {
        staged.push(
            Staged::write(path, |w| std::io::Write::write_all(w, bytes)).map_err(|source| {
                Error::Output {
                    path: path.clone(),
                    source,
                }
            })?,
        );
    }
    commit_all(staged)
}

/// Moves every staged file into place (once all are complete); returns
/// their paths.
fn commit_all(staged: Vec<Staged>) -> Result<Vec<PathBuf>, Error> {
    let mut written = Vec::new();
    for file in staged {
        let path = file.destination().to_path_buf();
        file.commit().map_err(|source| Error::Output {
            path: path.clone(),
            source,
        })?;
        written.push(path);
    }
    Ok(written)
}
