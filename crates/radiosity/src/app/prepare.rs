//! A job made ready to solve (design.md section 2's first steps): the
//! sensor points read, the scene loaded and checked, meshed and refined
//! (the coarse pass of the default), the settings the device allows, and
//! the run's memory checked against the machine's before anything large
//! is built.

use std::time::{Duration, Instant};

use super::job::mesh_error;
use super::{Counts, DEFAULT_PICTURE, Error, Job, Observer};
use crate::export;
use crate::export::gltf::BakeTarget;
use crate::memory;
use crate::mesh::Mesh;
use crate::scene::{self, Scene};
use crate::sensors::{self, SensorPoint};
use crate::solver::device::DeviceReport;
use crate::solver::{self, Receiver, Settings, Start};

/// What a solve starts from.
pub(super) struct Prepared {
    /// The scene, its coplanar faces merged where asked.
    pub scene: Scene,
    /// A glTF input's materials and texture coordinates.
    pub appearance: Option<scene::gltf::Appearance>,
    /// The sensor points as read, and where they lie on the surfaces.
    pub sensor_points: Vec<SensorPoint>,
    pub sensor_receivers: Vec<Receiver>,
    /// The overcast sky's unobstructed horizontal illuminance, for the
    /// daylight factor column.
    pub daylight_factor: Option<f64>,
    /// The settings for this scene and device.
    pub settings: Settings,
    /// The mesh solved (refined where the coarse pass asked).
    pub mesh: Mesh,
    /// The coarse pass's time and device.
    pub refined_seconds: f64,
    pub coarse_device: DeviceReport,
    pub counts: Counts,
    pub memory_estimate: memory::Estimate,
    /// What the device check said.
    pub device_notes: Vec<String>,
    pub load_time: Duration,
    pub mesh_time: Duration,
}

/// Reads, loads, meshes and refines `job`'s scene, checking memory and
/// the device on the base mesh and again on the refined one; with the
/// coarse pass's state the solve goes on from.
pub(super) fn prepare(
    job: &Job,
    observer: &mut dyn Observer,
) -> Result<(Prepared, Option<Start>), Error> {
    // The points are read first: a mistake in them is found in a moment.
    let sensor_points = match &job.sensors {
        Some(s) => sensors::read(&s.points, &job.load.limits, s.max_points)?,
        None => Vec::new(),
    };
    let load_start = Instant::now();
    let loaded = scene::load_with(&job.scene, &job.load)?;
    solver::sky::portals::check_scene(&loaded.scene)?;
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
    let receivers = |mesh: &Mesh| mesh.vertices.len() + sensor_receivers.len();
    check_resources(
        job,
        &scene,
        &base,
        None,
        receivers(&base) + base.elements.len(),
        &mut settings,
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
    let going_on = refined.start.take();
    let mesh = refined.mesh;
    let mesh_time = mesh_start.elapsed();
    let counts = Counts {
        base_elements: refined.base_elements,
        refined_elements: refined.split_elements,
        coarse_shots: refined.coarse_shots,
        coarse_stop_reason: refined.coarse_stop,
        coarse_device_shots: refined.coarse_device.device_shots,
        replayed_receivers: going_on.as_ref().map_or(0, |s| s.replayed_receivers),
        replayed_shots: going_on.as_ref().map_or(0, |s| s.replayed_shots),
        ..Counts::of(&scene, &mesh)
    };
    let memory_estimate = check_resources(
        job,
        &scene,
        &mesh,
        going_on.is_some().then_some(coarse),
        receivers(&mesh),
        &mut settings,
        &mut device_notes,
    )?;
    observer.started(&scene, &mesh);
    Ok((
        Prepared {
            scene,
            appearance: loaded.appearance,
            sensor_points,
            sensor_receivers,
            daylight_factor,
            settings,
            mesh,
            refined_seconds: refined.seconds,
            coarse_device: refined.coarse_device,
            counts,
            memory_estimate,
            device_notes,
            load_time,
            mesh_time,
        },
        going_on,
    ))
}

/// The run's memory estimate on `mesh` (with the coarse pass `going_on`
/// still held), refused over the job's limit, then the device's check
/// ([`solver::device::Device::fit`]); returns the estimate.
fn check_resources(
    job: &Job,
    scene: &Scene,
    mesh: &Mesh,
    going_on: Option<memory::GoingOn>,
    receivers: usize,
    settings: &mut Settings,
    notes: &mut Vec<String>,
) -> Result<memory::Estimate, Error> {
    let estimate = memory::estimate(
        &memory::Sizes {
            going_on,
            ..memory_sizes(job, scene, mesh)
        },
        settings.method.method().memory(),
    );
    memory::check(&estimate, job.max_memory).map_err(Error::Memory)?;
    if let Some(note) = settings
        .device
        .fit(scene, mesh, receivers)
        .map_err(|e| Error::Device(e.0))?
    {
        notes.push(note);
    }
    Ok(estimate)
}

/// The counts a run's memory estimate takes: the meshed scene's, and the
/// picture drawn for the image, bake or PLY ([`DEFAULT_PICTURE`] when none is asked
/// for, as [`super::run`] draws it).
fn memory_sizes(job: &Job, scene: &Scene, mesh: &Mesh) -> memory::Sizes {
    let drawn = job.image.is_some() || job.bake.is_some() || job.ply.is_some();
    let (width, height, supersampling, camera) = match &job.image {
        Some(image) => (
            image.width,
            image.height,
            image.supersampling,
            image.camera.is_some(),
        ),
        None => (DEFAULT_PICTURE[0], DEFAULT_PICTURE[1], 1, false),
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
        final_gather: job.final_gather,
        going_on: None,
    }
}
