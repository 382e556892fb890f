//! A solved job's outputs (design.md section 6), each its own function:
//! the picture, the glTF or lightmap bake, the PLY, the vertex CSV and the
//! sensors' values, shown through the final pass ([`crate::final_gather`])
//! where it is on. Each is staged and moved into place only once all are
//! complete; one a stop left incomplete is named and not written.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use glam::DVec3;

use super::prepare::Prepared;
use super::{
    Error, FINAL_PASS_INTERVAL, ImageJob, Job, Observer, PictureView, bake_colours, bake_values,
};
use crate::export::gltf::{Bake, BakeMode, BakeTarget};
use crate::export::lightmap::LightmapReport;
use crate::export::{self, Staged};
use crate::final_gather::{FinalGather, FinalPass, Point};
use crate::render::{self, Exposure};
use crate::scene::Camera;
use crate::solver::Solver;

/// What the outputs left: the files staged, those a stop left unwritten,
/// the lightmap's report, and the final pass's time.
pub(super) struct Outputs {
    pub staged: Vec<Staged>,
    pub unwritten: Vec<PathBuf>,
    pub lightmap: Option<LightmapReport>,
    /// The final pass's time, where it ran.
    pub final_gather_time: Option<Duration>,
}

/// What every output shows: the solve, seen from the job's view (the
/// bake and the PLY take the picture's exposure, so a picture is drawn
/// for them even when none is written), through the final pass.
struct Shown<'a> {
    job: &'a Job,
    prepared: &'a Prepared,
    solver: &'a Solver<'a>,
    view: ImageJob,
    camera: Camera,
    display: Vec<DVec3>,
    ambient: DVec3,
    pass: Option<FinalPass<'a>>,
}

/// Writes every output `job` asks for.
pub(super) fn write(
    job: &Job,
    prepared: &Prepared,
    solver: &Solver<'_>,
    observer: &mut dyn Observer,
) -> Result<Outputs, Error> {
    observer.writing("making the outputs");
    let view = job.image.clone().unwrap_or(ImageJob {
        path: PathBuf::new(),
        width: super::DEFAULT_PICTURE[0],
        height: super::DEFAULT_PICTURE[1],
        camera: None,
        supersampling: 1,
        exposure: Exposure::Auto { ev: 0.0 },
        ambient: true,
    });
    let camera = view
        .camera
        .unwrap_or_else(|| crate::view::camera_or_framing(&prepared.scene));
    let ambient = if view.ambient {
        solver.ambient()
    } else {
        DVec3::ZERO
    };
    let lightmap = job
        .bake
        .as_ref()
        .is_some_and(|b| b.target == BakeTarget::Lightmap);
    let drawn = job.image.is_some() || job.bake.is_some() || job.ply.is_some();
    let final_gather = job.final_gather;
    let final_start = Instant::now();
    let pass = (final_gather != FinalGather::Off && (drawn || lightmap || job.sensors.is_some()))
        .then(|| {
            let mut pass = FinalPass::new(solver, final_gather);
            if let Some(flag) = observer.abort() {
                pass.stop_on(flag);
            }
            pass
        });
    let mut final_gather_time = final_start.elapsed();
    let shown = Shown {
        job,
        prepared,
        solver,
        display: solver.display_radiosity(view.ambient),
        view,
        camera,
        ambient,
        pass,
    };
    let mut out = Outputs {
        staged: Vec::new(),
        unwritten: Vec::new(),
        lightmap: None,
        final_gather_time: None,
    };
    let exposure = if drawn {
        let (exposure, seconds) = picture(&shown, observer, &mut out)?;
        final_gather_time += seconds;
        exposure
    } else {
        None
    };
    if let (Some(bake_job), Some(exposure)) = (&job.bake, exposure) {
        bake(&shown, bake_job, exposure, observer, &mut out)?;
    }
    if let (Some(path), Some(exposure)) = (&job.ply, exposure) {
        out.staged.push(stage(path, &mut |w| {
            export::write_ply(
                w,
                &prepared.mesh,
                &shown.display,
                exposure,
                solver.radiosity(),
            )
        })?);
    }
    if let Some(path) = &job.vertices_csv {
        out.staged.push(stage(path, &mut |w| {
            export::write_vertices_csv(w, &prepared.scene, &prepared.mesh, solver.radiosity())
        })?);
    }
    final_gather_time += sensor_values(&shown, observer, &mut out)?;
    out.final_gather_time = shown.pass.is_some().then_some(final_gather_time);
    Ok(out)
}

/// Stages a file written by `write`.
fn stage(
    path: &Path,
    write: &mut dyn FnMut(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<Staged, Error> {
    Staged::write(path, write).map_err(|source| Error::Output {
        path: path.to_path_buf(),
        source,
    })
}

/// Draws the picture (written where the job asks for one): its exposure,
/// `None` where a stop left it incomplete (nothing that takes its exposure
/// is written then), and the time it took.
fn picture(
    shown: &Shown<'_>,
    observer: &mut dyn Observer,
    out: &mut Outputs,
) -> Result<(Option<f64>, Duration), Error> {
    let (job, view) = (shown.job, &shown.view);
    let start = Instant::now();
    let image = super::picture(
        shown.solver,
        shown.pass.as_ref(),
        &PictureView {
            width: view.width,
            height: view.height,
            camera: shown.camera,
            supersampling: view.supersampling,
            ambient: view.ambient,
        },
        observer,
    );
    let seconds = start.elapsed();
    let scale = image.exposure_scale(view.exposure);
    if shown.pass.as_ref().is_some_and(FinalPass::cut_short) {
        out.unwritten
            .extend(job.image.iter().map(|i| i.path.clone()));
        out.unwritten
            .extend(job.bake.iter().map(|b| b.path.clone()));
        out.unwritten.extend(job.ply.iter().cloned());
        return Ok((None, seconds));
    }
    if let Some(image_job) = &job.image {
        let extension = image_job
            .path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        out.staged.push(match extension.as_deref() {
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
    Ok((Some(scale), seconds))
}

/// The glTF vertex bake or the lightmap bake, at the picture's `exposure`.
fn bake(
    shown: &Shown<'_>,
    bake_job: &super::BakeJob,
    exposure: f64,
    observer: &mut dyn Observer,
    out: &mut Outputs,
) -> Result<(), Error> {
    let (prepared, solver, view) = (shown.prepared, shown.solver, &shown.view);
    let (scene, mesh) = (&prepared.scene, &prepared.mesh);
    let output = |source| Error::Output {
        path: bake_job.path.clone(),
        source,
    };
    let aspect_ratio = f64::from(view.width) / f64::from(view.height);
    let files = match bake_job.target {
        BakeTarget::Vertices => {
            let (colours, metadata) = bake_colours(
                solver,
                bake_job.mode,
                &shown.display,
                exposure,
                view.ambient,
            );
            let bake = Bake {
                scene,
                mesh,
                appearance: prepared.appearance.as_ref(),
                colours: &colours,
                mode: bake_job.mode,
                camera: shown.camera,
                aspect_ratio,
                metadata,
            };
            export::gltf::bake(&bake, &bake_job.path).map_err(output)?
        }
        BakeTarget::Lightmap => {
            observer.writing("baking the lightmap: charts, texels, files");
            let (values, metadata) = bake_values(
                solver,
                bake_job.mode,
                &shown.display,
                exposure,
                view.ambient,
            );
            // The mesh's part at the vertices, and the final pass's at
            // each texel, in the bake's units.
            let scale = metadata["color_scale"].as_f64().unwrap_or(1.0);
            let pass = &shown.pass;
            let values = match pass {
                Some(pass) => mesh_part(
                    pass,
                    solver,
                    bake_job.mode,
                    &shown.display,
                    shown.ambient,
                    scale,
                ),
                None => values,
            };
            let texel_shade = |points: &[Point]| -> Vec<DVec3> {
                let Some(pass) = pass else {
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
            let appearance = match prepared.appearance.as_ref() {
                Some(a) => a,
                None => {
                    own = export::lightmap::appearance_of_scene(scene).map_err(output)?;
                    &own
                }
            };
            let bake = export::lightmap::LightmapBake {
                scene,
                mesh,
                appearance,
                values: &values,
                shade: pass.is_some().then_some(&texel_shade as render::Shade<'_>),
                mode: bake_job.mode,
                settings: bake_job.lightmap,
                camera: shown.camera,
                aspect_ratio,
                metadata,
            };
            let (files, report) = match pass {
                Some(pass) => with_progress(observer, "lightmap", pass, &AtomicU64::new(0), || {
                    export::lightmap::bake(&bake, &bake_job.path)
                }),
                None => export::lightmap::bake(&bake, &bake_job.path),
            }
            .map_err(output)?;
            out.lightmap = Some(report);
            if pass.as_ref().is_some_and(FinalPass::cut_short) {
                out.unwritten.push(bake_job.path.clone());
                Vec::new()
            } else {
                files
            }
        }
    };
    for (path, bytes) in files {
        out.staged
            .push(stage(&path, &mut |w| std::io::Write::write_all(w, &bytes))?);
    }
    Ok(())
}

/// The sensors' values (written where the job has sensors); the final
/// pass's time on them.
fn sensor_values(
    shown: &Shown<'_>,
    observer: &mut dyn Observer,
    out: &mut Outputs,
) -> Result<Duration, Error> {
    let (job, prepared, solver) = (shown.job, shown.prepared, shown.solver);
    let start = Instant::now();
    let irradiance = match &shown.pass {
        Some(pass) if job.final_gather == FinalGather::Full && job.sensors.is_some() => {
            let count = AtomicU64::new(prepared.sensor_receivers.len() as u64);
            with_progress(observer, "sensors", pass, &count, || pass.sensors(solver))
        }
        Some(pass) => pass.sensors(solver),
        None => solver.sensor_irradiance().to_vec(),
    };
    let seconds = start.elapsed();
    let Some(sensor_job) = &job.sensors else {
        return Ok(seconds);
    };
    if shown.pass.as_ref().is_some_and(FinalPass::cut_short) {
        out.unwritten.push(sensor_job.out.clone());
    } else {
        out.staged.push(stage(&sensor_job.out, &mut |w| {
            export::write_sensors_csv(
                w,
                &prepared.scene,
                &prepared.sensor_points,
                &prepared.sensor_receivers,
                &irradiance,
                prepared.daylight_factor,
            )
        })?);
    }
    Ok(seconds)
}

/// Runs `work` (the final pass shading `what` through `pass`) on this
/// thread and the pool, while a thread of its own tells `observer` the
/// points shaded against `total` (read as it is known) every
/// [`FINAL_PASS_INTERVAL`], and once more when done.
pub(super) fn with_progress<R>(
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
