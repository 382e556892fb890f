//! One render job from scene to files: load, mesh, solve (design.md
//! section 2), then write the picture, the vertex CSV and the statistics of
//! design.md section 6, plus the glTF bake, PLY and EXR outputs, the
//! values at sensor points ([`crate::sensors`]) and [`export_scene`]. A
//! front end (the `radiosity` command, the live view) only builds a
//! [`Job`] and calls [`run`].

mod bake;
mod error;
mod job;
mod outcome;
mod progress;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

pub use self::bake::{bake_colours, bake_values};
pub use self::error::Error;
pub use self::job::{BakeJob, ImageJob, Job, MAX_SAMPLES, SensorJob, validate};
use self::job::{check_output, mesh_error};
pub use self::outcome::{Counts, Outcome, StatsFile};
pub use self::progress::{FINAL_PASS_INTERVAL, Observer, Progress, ProgressMeter, progress_of};
use glam::DVec3;

use crate::export::gltf::{Bake, BakeMode, BakeTarget};
use crate::export::{self, Staged};
use crate::final_gather::{FinalGather, FinalPass, Point};
use crate::memory;
use crate::mesh::Mesh;
use crate::render::{self, Exposure, RenderSettings};
use crate::scene::{self, LoadOptions, Scene};
use crate::sensors;
use crate::solver::{self, Settings, Solver};

/// Whether the solve of `mesh` fits the settings' device
/// ([`solver::device::Backend::check`]): a device asked for by name that
/// cannot hold it is an error; one taken because it was there leaves the
/// solve to the CPU, with a note.
fn check_device(
    settings: &mut Settings,
    scene: &Scene,
    mesh: &Mesh,
    receivers: usize,
    notes: &mut Vec<String>,
) -> Result<(), Error> {
    let Some(backend) = settings.device.get() else {
        return Ok(());
    };
    match backend.check(scene, mesh, receivers) {
        Ok(_) => Ok(()),
        Err(e) if settings.device.required() => Err(Error::Device(e.0)),
        Err(e) => {
            notes.push(format!("--device auto: {}; the solve runs on the CPU", e.0));
            settings.device = solver::device::Device::cpu();
            Ok(())
        }
    }
}

/// Runs a job in the current rayon pool.
pub fn run(job: &Job, observer: &mut dyn Observer) -> Result<Outcome, Error> {
    let start = Instant::now();
    validate(job)?;
    // The points are read first: a mistake in them is found in a moment.
    let sensor_points = match &job.sensors {
        Some(s) => sensors::read(&s.points, &job.load.limits, s.max_points)?,
        None => Vec::new(),
    };
    let load_start = Instant::now();
    let loaded = scene::load_with(&job.scene, &job.load)?;
    solver::portals::check_scene(&loaded.scene)?;
    // What a lightmap bake cannot rewrite is said before the solve.
    if let (Some(bake), Some(appearance)) = (&job.bake, &loaded.appearance)
        && bake.target == BakeTarget::Lightmap
    {
        export::lightmap::check_input(appearance).map_err(|message| Error::LightmapInput {
            path: job.scene.clone(),
            message,
        })?;
    }
    let mut scene = loaded.scene;
    if job.settings.merge_coplanar {
        scene::merge::merge_coplanar(&mut scene.surfaces);
    }
    let load_time = load_start.elapsed();
    let sensor_receivers = match &job.sensors {
        Some(s) => sensors::receivers(&scene, &sensor_points, &s.points)?,
        None => Vec::new(),
    };
    let daylight_factor = match &job.sensors {
        Some(s) => match (scene::sky::overcast_alone(&scene), s.daylight_factor) {
            (Ok(lux), _) => Some(lux),
            (Err(why), true) => return Err(Error::DaylightFactor(why)),
            (Err(_), false) => None,
        },
        None => None,
    };
    let suggested = scene.default_mesh_sizes();
    let mut settings = job.settings_for(&suggested);
    let mut device_notes = Vec::new();
    let mesh_start = Instant::now();
    let base = Mesh::build(&scene, &settings.mesh)
        .map_err(|e| mesh_error(e, job, &suggested, &settings))?;
    // Checked on the base mesh before the coarse pass solves it, and again
    // on the refined mesh before the solve.
    let method_memory = settings.method.method().memory();
    let estimate =
        |mesh: &Mesh| memory::estimate(&memory_sizes(job, &scene, mesh), method_memory.clone());
    memory::check(&estimate(&base), job.max_memory).map_err(Error::Memory)?;
    let receivers = |mesh: &Mesh| mesh.vertices.len() + sensor_receivers.len();
    check_device(
        &mut settings,
        &scene,
        &base,
        receivers(&base) + base.elements.len(),
        &mut device_notes,
    )?;
    if settings.mesh.refine.refine_levels > 0 {
        observer.refining();
    }
    let coarse = memory::GoingOn {
        elements: base.elements.len() as u64,
        vertices: base.vertices.len() as u64,
        lights: scene.lights.len() as u64,
    };
    let mut refined = solver::refine::refine_base(
        &scene,
        &settings,
        base,
        observer.interrupt(),
        &sensor_receivers,
    )
    .map_err(|e| mesh_error(e, job, &suggested, &settings))?;
    let refined_seconds = refined.seconds;
    let going_on = refined.start.take();
    let mesh = refined.mesh;
    let mesh_time = mesh_start.elapsed();
    let mut counts = Counts {
        base_elements: refined.base_elements,
        refined_elements: refined.split_elements,
        coarse_shots: refined.coarse_shots,
        coarse_stop_reason: refined.coarse_stop,
        coarse_device_shots: refined.coarse_device.device_shots,
        replayed_receivers: going_on.as_ref().map_or(0, |s| s.replayed_receivers),
        replayed_shots: going_on.as_ref().map_or(0, |s| s.replayed_shots),
        ..Counts::of(&scene, &mesh)
    };
    let memory_estimate = memory::estimate(
        &memory::Sizes {
            going_on: going_on.is_some().then_some(coarse),
            ..memory_sizes(job, &scene, &mesh)
        },
        method_memory.clone(),
    );
    memory::check(&memory_estimate, job.max_memory).map_err(Error::Memory)?;
    check_device(
        &mut settings,
        &scene,
        &mesh,
        receivers(&mesh),
        &mut device_notes,
    )?;
    observer.started(&scene, &mesh);

    let solve_start = Instant::now();
    let occluder = settings.accel.build(&scene.surfaces);
    let accel_build_time = solve_start.elapsed();
    let mut solver = Solver::resume_or_new(
        &scene,
        &mesh,
        Settings {
            // The coarse pass has had its share of the time limit.
            time_limit: settings
                .time_limit
                .map(|t| t.saturating_sub(Duration::from_secs_f64(refined_seconds))),
            ..settings.clone()
        },
        going_on,
        sensor_receivers.clone(),
        occluder,
    );
    if let Some(flag) = observer.interrupt() {
        solver.interrupt_on(flag);
    }
    let enclosed: Vec<String> = solver
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
    counts.patches = solver.shooters();
    let stop = solver.run(|s| observer.shot(s));
    let solve_time = solve_start.elapsed();
    observer.finished(&solver, stop);

    let write_start = Instant::now();
    observer.writing("making the outputs");
    let abort = observer.abort();
    let mut unwritten: Vec<PathBuf> = Vec::new();
    let mut staged = Vec::new();
    let stage = |path: &Path,
                 write: &mut dyn FnMut(
        &mut std::io::BufWriter<std::fs::File>,
    ) -> std::io::Result<()>| {
        Staged::write(path, write).map_err(|source| Error::Output {
            path: path.to_path_buf(),
            source,
        })
    };
    // The bake and the PLY show what the picture shows: the same view
    // fixes the exposure, so a picture is drawn for them even when none is
    // written.
    let view = job.image.clone().unwrap_or(ImageJob {
        path: PathBuf::new(),
        width: 800,
        height: 600,
        camera: None,
        supersampling: 1,
        exposure: Exposure::Auto { ev: 0.0 },
        ambient: true,
    });
    let camera = view
        .camera
        .unwrap_or_else(|| crate::view::camera_or_framing(&scene));
    let display = solver.display_radiosity(view.ambient);
    let ambient = if view.ambient {
        solver.ambient()
    } else {
        DVec3::ZERO
    };
    let lightmap = job
        .bake
        .as_ref()
        .is_some_and(|b| b.target == BakeTarget::Lightmap);
    let shown = job.image.is_some() || job.bake.is_some() || job.ply.is_some();
    let mut final_gather_time = Duration::ZERO;
    let final_start = Instant::now();
    let pass = (settings.final_gather != FinalGather::Off
        && (shown || lightmap || job.sensors.is_some()))
    .then(|| {
        let mut pass = FinalPass::new(&solver, settings.final_gather);
        if let Some(flag) = &abort {
            pass.stop_on(std::sync::Arc::clone(flag));
        }
        pass
    });
    final_gather_time += final_start.elapsed();
    let mut exposure = None;
    if shown {
        let settings = RenderSettings {
            width: view.width,
            height: view.height,
            camera,
            supersampling: view.supersampling,
        };
        let render_start = Instant::now();
        let image = match &pass {
            Some(pass) => {
                let planned = AtomicU64::new(0);
                let colours = pass.vertex_display(&display, ambient);
                with_progress(observer, "picture", pass, &planned, || {
                    render::render_planned(
                        &scene,
                        &mesh,
                        &colours,
                        &settings,
                        Some(&|points: &[Point]| pass.shade(points)),
                        &|n| planned.store(n, Ordering::Relaxed),
                    )
                })
            }
            None => render::render(&scene, &mesh, &display, &settings),
        };
        final_gather_time += render_start.elapsed();
        let scale = image.exposure_scale(view.exposure);
        // A picture the final pass left incomplete is not written, nor is
        // what takes its exposure (the bake, the PLY).
        let complete = pass.as_ref().is_none_or(|p| !p.cut_short());
        exposure = complete.then_some(scale);
        if !complete {
            unwritten.extend(job.image.iter().map(|i| i.path.clone()));
            unwritten.extend(job.bake.iter().map(|b| b.path.clone()));
            unwritten.extend(job.ply.iter().cloned());
        } else if let Some(image_job) = &job.image {
            let extension = image_job
                .path
                .extension()
                .and_then(|e| e.to_str())
                .map(str::to_ascii_lowercase);
            staged.push(match extension.as_deref() {
                Some("pfm") => stage(&image_job.path, &mut |w| export::write_pfm(w, &image))?,
                Some("exr") => stage(&image_job.path, &mut |w| export::write_exr(w, &image))?,
                _ => {
                    let rgb = image.to_srgb8(scale);
                    stage(&image_job.path, &mut |w| {
                        export::write_png(w, image.width, image.height, &rgb)
                    })?
                }
            });
        }
    }
    let mut lightmap_report = None;
    if let (Some(bake_job), Some(exposure)) = (&job.bake, exposure) {
        let output = |source| Error::Output {
            path: bake_job.path.clone(),
            source,
        };
        let aspect_ratio = f64::from(view.width) / f64::from(view.height);
        let files = match bake_job.target {
            BakeTarget::Vertices => {
                let (colours, metadata) =
                    bake_colours(&solver, bake_job.mode, &display, exposure, view.ambient);
                let bake = Bake {
                    scene: &scene,
                    mesh: &mesh,
                    appearance: loaded.appearance.as_ref(),
                    colours: &colours,
                    mode: bake_job.mode,
                    camera,
                    aspect_ratio,
                    metadata,
                };
                export::gltf::bake(&bake, &bake_job.path).map_err(output)?
            }
            BakeTarget::Lightmap => {
                observer.writing("baking the lightmap: charts, texels, files");
                let (values, metadata) =
                    bake_values(&solver, bake_job.mode, &display, exposure, view.ambient);
                // The mesh's part at the vertices, and the final pass's at
                // each texel, in the bake's units.
                let scale = metadata["color_scale"].as_f64().unwrap_or(1.0);
                let values = match &pass {
                    Some(pass) => mesh_part(pass, &solver, bake_job.mode, &display, ambient, scale),
                    None => values,
                };
                let texel_shade = |points: &[Point]| -> Vec<DVec3> {
                    let Some(pass) = &pass else {
                        return vec![DVec3::ZERO; points.len()];
                    };
                    let added = match bake_job.mode {
                        BakeMode::Lit => pass.shade(points),
                        BakeMode::Irradiance => pass.irradiance(points),
                    };
                    added
                        .into_iter()
                        .map(|v| v * (scale / std::f64::consts::PI))
                        .collect()
                };
                let own;
                let appearance = match loaded.appearance.as_ref() {
                    Some(a) => a,
                    None => {
                        own = export::lightmap::appearance_of_scene(&scene).map_err(output)?;
                        &own
                    }
                };
                let bake = export::lightmap::LightmapBake {
                    scene: &scene,
                    mesh: &mesh,
                    appearance,
                    values: &values,
                    shade: pass.is_some().then_some(&texel_shade as render::Shade<'_>),
                    mode: bake_job.mode,
                    settings: bake_job.lightmap,
                    camera,
                    aspect_ratio,
                    metadata,
                };
                let (files, report) = match &pass {
                    Some(pass) => {
                        with_progress(observer, "lightmap", pass, &AtomicU64::new(0), || {
                            export::lightmap::bake(&bake, &bake_job.path)
                        })
                    }
                    None => export::lightmap::bake(&bake, &bake_job.path),
                }
                .map_err(output)?;
                lightmap_report = Some(report);
                if pass.as_ref().is_some_and(FinalPass::cut_short) {
                    unwritten.push(bake_job.path.clone());
                    Vec::new()
                } else {
                    files
                }
            }
        };
        for (path, bytes) in files {
            staged.push(stage(&path, &mut |w| std::io::Write::write_all(w, &bytes))?);
        }
    }
    if let (Some(path), Some(exposure)) = (&job.ply, exposure) {
        staged.push(stage(path, &mut |w| {
            export::write_ply(w, &mesh, &display, exposure, solver.radiosity())
        })?);
    }
    if let Some(path) = &job.vertices_csv {
        staged.push(stage(path, &mut |w| {
            export::write_vertices_csv(w, &scene, &mesh, solver.radiosity())
        })?);
    }
    let sensor_start = Instant::now();
    let sensor_irradiance = match &pass {
        Some(pass) if settings.final_gather == FinalGather::Full && job.sensors.is_some() => {
            let count = AtomicU64::new(sensor_receivers.len() as u64);
            with_progress(observer, "sensors", pass, &count, || pass.sensors(&solver))
        }
        Some(pass) => pass.sensors(&solver),
        None => solver.sensor_irradiance().to_vec(),
    };
    if pass.is_some() {
        final_gather_time += sensor_start.elapsed();
    }
    let sensors_complete = pass.as_ref().is_none_or(|p| !p.cut_short());
    if let Some(sensor_job) = &job.sensors
        && !sensors_complete
    {
        unwritten.push(sensor_job.out.clone());
    } else if let Some(sensor_job) = &job.sensors {
        staged.push(stage(&sensor_job.out, &mut |w| {
            export::write_sensors_csv(
                w,
                &scene,
                &sensor_points,
                &sensor_receivers,
                &sensor_irradiance,
                daylight_factor,
            )
        })?);
    }
    let threads = rayon::current_num_threads();
    let device = solver.device_report();
    let device_fault = [&refined.coarse_device, &device]
        .into_iter()
        .find_map(|d| d.fault.as_ref().map(|f| (d.name.clone(), f.clone())))
        .map(|(name, fault)| {
            format!(
                "the device {} failed ({fault}): the solve went back to its last checkpoint and \
                 on on the CPU",
                name.unwrap_or_default()
            )
        });
    let mut outcome = Outcome {
        scene: scene.name.clone(),
        counts,
        stats: solver.stats().clone(),
        counters: solver.counters(),
        stop,
        unshot_fraction: solver.unshot_fraction(),
        load_time,
        mesh_time,
        solve_time,
        accel_build_time,
        write_time: Duration::ZERO,
        final_gather_time: if pass.is_some() {
            final_gather_time
        } else {
            Duration::ZERO
        },
        total_time: Duration::ZERO,
        threads,
        accel_statistics: solver.accel_statistics(),
        written: Vec::new(),
        unwritten,
        warnings: scene
            .warnings
            .iter()
            .cloned()
            .chain(enclosed)
            .chain(lightmap_report.iter().flat_map(|r| r.warnings.clone()))
            .chain(device_notes)
            .chain(device_fault)
            .collect(),
        peak_memory_bytes: None,
        memory_estimate,
        lights: outcome::LightPower::of(&scene, solver.light_power()),
        lightmap: lightmap_report,
        device,
    };
    outcome.peak_memory_bytes = memory::peak_resident_bytes();
    outcome.write_time = write_start.elapsed();
    if let Some(path) = &job.stats_json {
        outcome.total_time = start.elapsed();
        let file = StatsFile::of(&settings, &outcome);
        staged.push(stage(path, &mut |w| file.write(w))?);
    }
    outcome.written = commit_all(staged)?;
    outcome.total_time = start.elapsed();
    outcome.peak_memory_bytes = memory::peak_resident_bytes();
    Ok(outcome)
}

/// Runs `work` (the final pass shading `what` through `pass`) on this
/// thread and the pool, while a thread of its own tells `observer` the
/// points shaded against `total` (read as it is known) every
/// [`FINAL_PASS_INTERVAL`], and once more when done.
fn with_progress<R>(
    observer: &mut dyn Observer,
    what: &str,
    pass: &FinalPass<'_>,
    total: &AtomicU64,
    work: impl FnOnce() -> R,
) -> R {
    let start = Instant::now();
    let base = pass.shaded();
    let finished = AtomicBool::new(false);
    std::thread::scope(|scope| {
        let teller = scope.spawn(|| {
            loop {
                let done = finished.load(Ordering::Acquire);
                let total = total.load(Ordering::Relaxed);
                let shaded = pass.shaded() - base;
                // Points left unshaded by a stop count as done.
                let shown = if done { total.max(shaded) } else { shaded };
                observer.final_pass(what, shown, total, start.elapsed());
                if done {
                    break;
                }
                std::thread::park_timeout(FINAL_PASS_INTERVAL);
            }
        });
        let result = work();
        finished.store(true, Ordering::Release);
        teller.thread().unpark();
        result
    })
}

/// A lightmap's values at the mesh's vertices under the final pass: its
/// mesh part ([`FinalPass::vertex_part`]) in the bake's units (`scale`
/// times radiance), the final pass adding the rest at each texel.
fn mesh_part(
    pass: &FinalPass<'_>,
    solver: &Solver<'_>,
    mode: BakeMode,
    display: &[DVec3],
    ambient: DVec3,
    scale: f64,
) -> Vec<DVec3> {
    let per = scale / std::f64::consts::PI;
    match mode {
        BakeMode::Lit => pass
            .vertex_display(display, ambient)
            .into_iter()
            .map(|b| b * per)
            .collect(),
        BakeMode::Irradiance => pass
            .vertex_part(ambient)
            .into_iter()
            .zip(solver.irradiance())
            .map(|(part, e)| part.unwrap_or(*e + ambient) * per)
            .collect(),
    }
}

/// The counts a run's memory estimate takes: the meshed scene's, and the
/// picture drawn for the image, bake or PLY (800 x 600 when none is asked
/// for, as [`run`] draws it).
fn memory_sizes(job: &Job, scene: &Scene, mesh: &Mesh) -> memory::Sizes {
    let drawn = job.image.is_some() || job.bake.is_some() || job.ply.is_some();
    let (width, height, supersampling, camera) = match &job.image {
        Some(image) => (
            image.width,
            image.height,
            image.supersampling,
            image.camera.is_some(),
        ),
        None => (800, 600, 1, false),
    };
    let pixels = if drawn {
        u64::from(width) * u64::from(height)
    } else {
        0
    };
    memory::Sizes {
        surfaces: scene.surfaces.len() as u64,
        patches: mesh.patches.len() as u64,
        elements: mesh.elements.len() as u64,
        vertices: mesh.vertices.len() as u64,
        samples: pixels * u64::from(supersampling).pow(2),
        pixels,
        view: drawn && !camera && scene.camera.is_none(),
        bake: job.bake.is_some(),
        lightmap_texels: job
            .bake
            .as_ref()
            .filter(|b| b.target == BakeTarget::Lightmap)
            .map_or(0, |b| {
                // The scene's area at the density, packed at half the
                // space (well below uvunwrap's packing), within the size cap.
                let area: f64 = scene.surfaces.iter().map(|s| s.area).sum();
                let cap = u64::from(b.lightmap.max_size).pow(2);
                (2.0 * area * b.lightmap.density.powi(2)).min(cap as f64) as u64
            }),
        final_gather: job.settings.final_gather,
        going_on: None,
    }
}

/// `radiosity export-scene`: writes a built-in or file scene as glTF
/// (`.glb`, or `.gltf` with its `.bin`), staged like every output. Returns
/// the files written.
pub fn export_scene(scene: &str, out: &Path, load: &LoadOptions) -> Result<Vec<PathBuf>, Error> {
    load.validate()?;
    check_output(out, &["glb", "gltf"], "export-scene")?;
    let loaded = scene::load_with(scene, load)?;
    solver::portals::check_scene(&loaded.scene)?;
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
