//! One render job from scene to files: load, mesh, solve (design.md
//! section 2), then write the picture, the vertex CSV and the statistics of
//! design.md section 6, plus the glTF bake, PLY and EXR outputs, the
//! values at sensor points ([`crate::sensors`]) and [`export_scene`]. The binary only parses flags into a [`Job`] and calls
//! [`run`].

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use crate::export::gltf::{Bake, BakeMode};
use crate::export::{self, Staged};
use crate::memory;
use crate::mesh::{Mesh, MeshError, MeshSettings};
use crate::render::{self, Exposure, RenderSettings};
use crate::scene::{
    self, Camera, CameraError, LoadOptions, LoadOptionsError, MeshHint, Scene, SceneError,
};
use crate::sensors;
use crate::solver::{Flow, Settings, SettingsError, Solver, Stats, StopReason};

/// What to draw and where.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageJob {
    /// `.png` (tone-mapped sRGB), `.pfm` or `.exr` (linear radiosity).
    pub path: PathBuf,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// The view; `None` takes the scene's camera or frames the scene.
    pub camera: Option<Camera>,
    /// Supersampling factor per axis.
    pub supersampling: u32,
    /// Brightness.
    pub exposure: Exposure,
    /// Add the ambient term for display.
    pub ambient: bool,
}

/// A whole run.
#[derive(Clone, Debug, PartialEq)]
pub struct Job {
    /// A built-in scene's name or an `.obj` path.
    pub scene: String,
    /// Solver settings, but for the mesh sizes: the two below give those
    /// ([`Job::settings_for`]), and a job whose settings hold sizes other
    /// than [`MeshSettings::default`]'s is refused ([`validate`]) rather
    /// than have them ignored.
    pub settings: Settings,
    /// `--patch-size`; `None` takes the scene's suggestion.
    pub patch_size: Option<f64>,
    /// `--element-size`; `None` takes the scene's suggestion.
    pub element_size: Option<f64>,
    /// The picture, if any.
    pub image: Option<ImageJob>,
    /// `--vertices FILE.csv`.
    pub vertices_csv: Option<PathBuf>,
    /// `--stats FILE.json`.
    pub stats_json: Option<PathBuf>,
    /// Bounds on the scene file (`--max-file-size`, `--max-corners`, ...)
    /// and how glTF materials map to reflectance and exitance.
    pub load: LoadOptions,
    /// `--bake FILE.glb|.gltf`.
    pub bake: Option<BakeJob>,
    /// `--ply FILE.ply`.
    pub ply: Option<PathBuf>,
    /// `--max-memory`: the memory the run may use, bytes; `None` takes what
    /// the machine has available ([`memory::check`]).
    pub max_memory: Option<u64>,
    /// `--sensors POINTS.txt --sensors-out FILE.csv`.
    pub sensors: Option<SensorJob>,
}

impl Job {
    /// The settings of a run on a scene that suggests `suggested`:
    /// [`Job::settings`] with the mesh sizes of [`Job::patch_size`] and
    /// [`Job::element_size`], each defaulting to the suggestion. The one
    /// place a run's mesh sizes are decided.
    #[must_use]
    pub fn settings_for(&self, suggested: &MeshHint) -> Settings {
        let mut settings = self.settings.clone();
        settings.mesh.patch_size = self.patch_size.unwrap_or(suggested.patch_size);
        settings.mesh.element_size = self.element_size.unwrap_or(suggested.element_size);
        settings
    }
}

/// `--sensors`: values at the points of a Radiance `rtrace -I` points file
/// ([`crate::sensors`]).
#[derive(Clone, Debug, PartialEq)]
pub struct SensorJob {
    /// The points file.
    pub points: PathBuf,
    /// The CSV to write.
    pub out: PathBuf,
    /// Most points the file may hold (`--max-sensors`).
    pub max_points: usize,
}

/// `--bake`: the element mesh as glTF with baked vertex colours.
#[derive(Clone, Debug, PartialEq)]
pub struct BakeJob {
    /// `.glb`, or `.gltf` (written with a `.bin` beside it).
    pub path: PathBuf,
    /// What `COLOR_0` holds.
    pub mode: BakeMode,
}

/// Why a run failed.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The scene could not be loaded.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// The scene could not be meshed.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// A solver setting is out of range.
    #[error(transparent)]
    Settings(#[from] SettingsError),
    /// A load option is out of range.
    #[error(transparent)]
    Load(#[from] LoadOptionsError),
    /// The picture's camera defines no view.
    #[error("--camera: {0}")]
    Camera(CameraError),
    /// An output's file name has none of the extensions it may have.
    #[error("{flag} {path}: the file name must end in .{}", extensions.join(" or ."), path = path.display())]
    FileType {
        /// The flag that named the file.
        flag: &'static str,
        /// The file.
        path: PathBuf,
        /// The extensions it may have.
        extensions: &'static [&'static str],
    },
    /// A picture side outside 1 to [`render::MAX_SIDE`].
    #[error("{flag} must be between 1 and {}, not {side}", render::MAX_SIDE)]
    PictureSide {
        /// `--width` or `--height`.
        flag: &'static str,
        /// The side asked for.
        side: u32,
    },
    /// A picture of more than [`MAX_SAMPLES`] samples.
    #[error(
        "a {width}x{height} picture with {supersampling}x{supersampling} supersampling needs \
         {samples} samples, more than {MAX_SAMPLES}: lower --width, --height or --supersampling"
    )]
    TooManySamples {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
        /// Supersampling per axis.
        supersampling: u32,
        /// The samples it would take.
        samples: u64,
    },
    /// Supersampling outside 1 to 8.
    #[error("--supersampling must be between 1 and 8, not {0}")]
    Supersampling(u32),
    /// `--max-sensors 0`.
    #[error("--max-sensors must be at least 1")]
    NoSensors,
    /// Mesh sizes given in [`Job::settings`], where they are not read.
    #[error("a job's mesh sizes are its patch_size and element_size, not its settings' mesh sizes")]
    MeshSizesInSettings,
    /// The mesh would exceed `--max-elements`.
    #[error(
        "meshing would create {elements} elements, more than the limit of {limit}: {remedy}, or \
         raise --max-elements"
    )]
    MeshTooLarge {
        /// Elements the mesh would have.
        elements: u128,
        /// `--max-elements`.
        limit: usize,
        /// The size to change and where it came from.
        remedy: String,
    },
    /// The run would need more memory than it may use.
    #[error("{0}")]
    Memory(memory::TooLarge),
    /// An output file could not be written.
    #[error("{path}: cannot write: {source}", path = path.display())]
    Output {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },
}

/// Progress after a shot, for a progress display.
#[derive(Clone, Copy, Debug)]
pub struct Progress {
    /// Patches shot so far.
    pub shots: u64,
    /// Subsources shot so far.
    pub subsources: u64,
    /// Unshot power over emitted power.
    pub unshot_fraction: f64,
    /// Estimated completion in [0, 1], from whichever stopping rule is
    /// nearest.
    pub completion: f64,
    /// Time since the solve started.
    pub elapsed: Duration,
    /// Shadow rays per second over the recent past.
    pub rays_per_second: f64,
    /// Estimated time until a stopping rule holds, once there is enough
    /// history to say.
    pub remaining: Option<Duration>,
}

/// Follows a solve to estimate its speed and the time left: rays per
/// second, and the time until the first stopping rule holds, extrapolated
/// from the recent past (the last third of the run, at least ten seconds).
/// Convergence is followed on a log scale: the unshot fraction falls
/// roughly geometrically with the shots, but ever more slowly as the
/// brightest shooters are done, so only the recent rate predicts the rest.
#[derive(Clone, Debug)]
pub struct ProgressMeter {
    start: Instant,
    /// `(elapsed, ln unshot fraction, rays, shots)` after recent shots.
    history: std::collections::VecDeque<(Duration, f64, u64, u64)>,
}

impl Default for ProgressMeter {
    fn default() -> Self {
        ProgressMeter::new()
    }
}

impl ProgressMeter {
    /// Starts timing now.
    #[must_use]
    pub fn new() -> ProgressMeter {
        ProgressMeter {
            start: Instant::now(),
            history: std::collections::VecDeque::new(),
        }
    }

    /// Records the solver's state after a shot and estimates progress.
    pub fn update(&mut self, solver: &Solver<'_>) -> Progress {
        let mut progress = progress_of(solver);
        let elapsed = self.start.elapsed();
        let stats = solver.stats();
        let ln_fraction = progress.unshot_fraction.max(1e-300).ln();
        self.history
            .push_back((elapsed, ln_fraction, stats.rays_cast, stats.shots));
        let window = (elapsed / 3).max(Duration::from_secs(10));
        while self.history.len() > 2 && elapsed - self.history[1].0 >= window {
            self.history.pop_front();
        }
        progress.elapsed = elapsed;
        let (t0, f0, rays0, shots0) = self.history[0];
        let span = (elapsed - t0).as_secs_f64();
        if span > 0.0 {
            progress.rays_per_second = (stats.rays_cast - rays0) as f64 / span;
        }
        let settings = solver.settings();
        let mut remaining: Option<f64> = None;
        let mut nearest = |t: f64| {
            if t.is_finite() && t >= 0.0 {
                remaining = Some(remaining.map_or(t, |r: f64| r.min(t)));
            }
        };
        if span >= 1.0 && self.history.len() >= 3 {
            let rate = (f0 - ln_fraction) / span;
            if settings.converge > 0.0 && rate > 0.0 {
                nearest(((ln_fraction - settings.converge.ln()) / rate).max(0.0));
            }
            let shot_rate = (stats.shots - shots0) as f64 / span;
            if let Some(max) = settings.max_shots
                && shot_rate > 0.0
            {
                nearest(max.saturating_sub(stats.shots) as f64 / shot_rate);
            }
        }
        if let Some(limit) = settings.time_limit {
            nearest(limit.saturating_sub(elapsed).as_secs_f64());
        }
        progress.remaining = remaining.map(Duration::from_secs_f64);
        progress
    }
}

/// Watches a run: told when the mesh is ready and after every shot, and
/// able to stop the solve (the outputs are then written from the state
/// reached). Progress displays, Ctrl-C handling and the live view are
/// observers.
pub trait Observer {
    /// The scene is loaded and meshed; the solve is about to start.
    fn started(&mut self, _scene: &Scene, _mesh: &Mesh) {}

    /// A shot has completed. Return [`Flow::Stop`] to end the solve.
    fn shot(&mut self, _solver: &Solver<'_>) -> Flow {
        Flow::Continue
    }

    /// A flag that, once raised, stops the solve at once, abandoning the
    /// shot under way (see [`Solver::interrupt_on`]): for Ctrl-C and stop
    /// buttons, which should not wait for a long shot to end.
    fn interrupt(&self) -> Option<Arc<AtomicBool>> {
        None
    }

    /// The solve has ended, for `stop`, and the outputs are about to be
    /// written from `solver`'s state: the last state a live view shows
    /// (the last [`Observer::shot`] cannot know it is the last).
    fn finished(&mut self, _solver: &Solver<'_>, _stop: StopReason) {}
}

/// An observer that watches nothing.
impl Observer for () {}

/// A closure called with each shot's [`Progress`] is an observer.
impl<F: FnMut(Progress)> Observer for F {
    fn shot(&mut self, solver: &Solver<'_>) -> Flow {
        self(progress_of(solver));
        Flow::Continue
    }
}

/// What a run did.
#[derive(Clone, Debug)]
pub struct Outcome {
    /// Scene name.
    pub scene: String,
    /// Surface, patch, element and vertex counts.
    pub counts: Counts,
    /// Solver counters.
    pub stats: Stats,
    /// Why the solve stopped.
    pub stop: StopReason,
    /// Unshot fraction at the end.
    pub unshot_fraction: f64,
    /// Time to read the scene and merge its coplanar faces.
    pub load_time: Duration,
    /// Time to build the element mesh.
    pub mesh_time: Duration,
    /// Time of the solve alone: building the accelerator, setting up the
    /// solver and shooting.
    pub solve_time: Duration,
    /// Time to build the shadow-ray accelerator (part of `solve_time`).
    pub accel_build_time: Duration,
    /// Time to draw the picture and write the outputs, the statistics file
    /// excepted (it cannot time its own writing).
    pub write_time: Duration,
    /// Time of the whole run.
    pub total_time: Duration,
    /// Worker threads.
    pub threads: usize,
    /// The accelerator's build statistics.
    pub accel_statistics: Vec<(&'static str, usize)>,
    /// Files written.
    pub written: Vec<PathBuf>,
    /// Warnings from loading.
    pub warnings: Vec<String>,
    /// The most memory the process held resident, bytes, when the outputs
    /// were written (`None` where the system does not say).
    pub peak_memory_bytes: Option<u64>,
    /// The estimate the run was checked against before its solve.
    pub memory_estimate: memory::Estimate,
}

/// Sizes of a meshed scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Counts {
    /// Planar convex input surfaces.
    pub surfaces: usize,
    /// Surface ids: surfaces after merging adjacent coplanar faces.
    pub surface_ids: usize,
    /// Shooting units: patches, or the shooters of adaptive shooting.
    pub patches: usize,
    /// Receiving elements.
    pub elements: usize,
    /// Shared vertices.
    pub vertices: usize,
}

impl Counts {
    /// Counts of a meshed scene.
    #[must_use]
    pub fn of(scene: &Scene, mesh: &Mesh) -> Counts {
        let mut ids: Vec<u32> = scene.surfaces.iter().map(|s| s.group).collect();
        ids.sort_unstable();
        ids.dedup();
        Counts {
            surfaces: scene.surfaces.len(),
            surface_ids: ids.len(),
            patches: mesh.patches.len(),
            elements: mesh.elements.len(),
            vertices: mesh.vertices.len(),
        }
    }
}

/// Most samples (pixels times supersampling) a picture may take: about
/// 2.5 GB of frame buffer.
pub const MAX_SAMPLES: u64 = 150_000_000;

/// Checks outputs before any work: known picture format, a folder that
/// exists and can be written to (a file is created there and removed).
fn check_output(
    path: &Path,
    extensions: &'static [&'static str],
    flag: &'static str,
) -> Result<(), Error> {
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    if !extensions.contains(&extension.as_str()) {
        return Err(Error::FileType {
            flag,
            path: path.to_path_buf(),
            extensions,
        });
    }
    let folder = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let output_error = |source: std::io::Error| Error::Output {
        path: path.to_path_buf(),
        source,
    };
    if !folder.is_dir() {
        let problem = if folder.exists() {
            format!("{} is a file, not a folder", folder.display())
        } else {
            format!("folder {} does not exist", folder.display())
        };
        return Err(output_error(std::io::Error::new(
            std::io::ErrorKind::NotFound,
            problem,
        )));
    }
    export::probe_writable(path).map_err(output_error)
}

/// Validates a job's settings and outputs without doing any work.
pub fn validate(job: &Job) -> Result<(), Error> {
    job.settings.validate()?;
    let defaults = MeshSettings::default();
    if (job.settings.mesh.patch_size, job.settings.mesh.element_size)
        != (defaults.patch_size, defaults.element_size)
    {
        return Err(Error::MeshSizesInSettings);
    }
    job.load.validate()?;
    if let Some(bake) = &job.bake {
        check_output(&bake.path, &["glb", "gltf"], "--bake")?;
    }
    if let Some(path) = &job.ply {
        check_output(path, &["ply"], "--ply")?;
    }
    if let Some(image) = &job.image {
        check_output(&image.path, &["png", "pfm", "exr"], "--output")?;
        for (flag, side) in [("--width", image.width), ("--height", image.height)] {
            if !(1..=render::MAX_SIDE).contains(&side) {
                return Err(Error::PictureSide { flag, side });
            }
        }
        let samples = u64::from(image.width)
            * u64::from(image.height)
            * u64::from(image.supersampling).pow(2);
        if samples > MAX_SAMPLES {
            return Err(Error::TooManySamples {
                width: image.width,
                height: image.height,
                supersampling: image.supersampling,
                samples,
            });
        }
        if !(1..=8).contains(&image.supersampling) {
            return Err(Error::Supersampling(image.supersampling));
        }
        if let Some(camera) = &image.camera {
            camera.validate().map_err(Error::Camera)?;
        }
    }
    if let Some(path) = &job.vertices_csv {
        check_output(path, &["csv"], "--vertices")?;
    }
    if let Some(path) = &job.stats_json {
        check_output(path, &["json"], "--stats")?;
    }
    if let Some(sensors) = &job.sensors {
        check_output(&sensors.out, &["csv"], "--sensors-out")?;
        if sensors.max_points == 0 {
            return Err(Error::NoSensors);
        }
    }
    Ok(())
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
    let mut scene = loaded.scene;
    if job.settings.merge_coplanar {
        scene::merge::merge_coplanar(&mut scene.surfaces);
    }
    let load_time = load_start.elapsed();
    let sensor_receivers = match &job.sensors {
        Some(s) => sensors::receivers(&scene, &sensor_points, &s.points)?,
        None => Vec::new(),
    };
    let suggested = scene.default_mesh_sizes();
    let settings = job.settings_for(&suggested);
    let mesh_start = Instant::now();
    let mesh = Mesh::build(&scene, &settings.mesh)
        .map_err(|e| mesh_error(e, job, &suggested, &settings))?;
    let mesh_time = mesh_start.elapsed();
    let mut counts = Counts::of(&scene, &mesh);
    let memory_estimate = memory::estimate(&memory_sizes(job, &scene, &mesh), &settings);
    memory::check(&memory_estimate, job.max_memory).map_err(Error::Memory)?;
    observer.started(&scene, &mesh);

    let solve_start = Instant::now();
    let occluder = settings.accel.build(&scene.surfaces);
    let accel_build_time = solve_start.elapsed();
    let mut solver = Solver::with_sensors_and_occluder(
        &scene,
        &mesh,
        settings.clone(),
        sensor_receivers.clone(),
        occluder,
    );
    if let Some(flag) = observer.interrupt() {
        solver.interrupt_on(flag);
    }
    counts.patches = solver.shooters();
    let stop = solver.run(|s| observer.shot(s));
    let solve_time = solve_start.elapsed();
    observer.finished(&solver, stop);

    let write_start = Instant::now();
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
    let mut exposure = None;
    if job.image.is_some() || job.bake.is_some() || job.ply.is_some() {
        let settings = RenderSettings {
            width: view.width,
            height: view.height,
            camera,
            supersampling: view.supersampling,
        };
        let image = render::render(&scene, &mesh, &display, &settings);
        let scale = image.exposure_scale(view.exposure);
        exposure = Some(scale);
        if let Some(image_job) = &job.image {
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
    if let (Some(bake_job), Some(exposure)) = (&job.bake, exposure) {
        let (colours, metadata) =
            bake_colours(&solver, bake_job.mode, &display, exposure, view.ambient);
        let bake = Bake {
            scene: &scene,
            mesh: &mesh,
            appearance: loaded.appearance.as_ref(),
            colours: &colours,
            mode: bake_job.mode,
            camera,
            aspect_ratio: f64::from(view.width) / f64::from(view.height),
            metadata,
        };
        let files = export::gltf::bake(&bake, &bake_job.path).map_err(|source| Error::Output {
            path: bake_job.path.clone(),
            source,
        })?;
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
    if let Some(sensor_job) = &job.sensors {
        staged.push(stage(&sensor_job.out, &mut |w| {
            export::write_sensors_csv(
                w,
                &scene,
                &sensor_points,
                &sensor_receivers,
                solver.sensor_irradiance(),
            )
        })?);
    }
    let threads = rayon::current_num_threads();
    let mut outcome = Outcome {
        scene: scene.name.clone(),
        counts,
        stats: solver.stats().clone(),
        stop,
        unshot_fraction: solver.unshot_fraction(),
        load_time,
        mesh_time,
        solve_time,
        accel_build_time,
        write_time: Duration::ZERO,
        total_time: Duration::ZERO,
        threads,
        accel_statistics: solver.accel_statistics(),
        written: Vec::new(),
        warnings: scene.warnings.clone(),
        peak_memory_bytes: None,
        memory_estimate,
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
    }
}

/// The `COLOR_0` values of a bake and the metadata recorded beside them
/// (see [`export::gltf`]): `COLOR_0 = min(1, color_scale x radiance)`, the
/// radiance being `B_shown / pi` (lit) or `(E + ambient) / pi`
/// (irradiance). Lit uses the picture's exposure; irradiance uses it too
/// unless that would clip a vertex, then the largest scale that does not.
#[must_use]
pub fn bake_colours(
    solver: &Solver<'_>,
    mode: BakeMode,
    display: &[glam::DVec3],
    exposure: f64,
    ambient: bool,
) -> (Vec<glam::DVec3>, serde_json::Value) {
    use std::f64::consts::PI;
    let ambient_term = if ambient {
        solver.ambient()
    } else {
        glam::DVec3::ZERO
    };
    let (radiance, mut scale, quantity): (Vec<glam::DVec3>, f64, &str) = match mode {
        BakeMode::Lit => (
            display.iter().map(|b| *b / PI).collect(),
            PI * exposure,
            "radiance shown by the picture, B/pi with the ambient term, W/(m^2 sr)",
        ),
        BakeMode::Irradiance => (
            solver
                .irradiance()
                .iter()
                .map(|e| (*e + ambient_term) / PI)
                .collect(),
            PI * exposure,
            "irradiance over pi, (E + ambient)/pi, W/(m^2 sr): multiply by the base colour",
        ),
    };
    if mode == BakeMode::Irradiance {
        let peak = radiance.iter().map(|r| r.max_element()).fold(0.0, f64::max);
        if peak * scale > 1.0 {
            scale = 1.0 / peak;
        }
    }
    let colours = radiance
        .iter()
        .map(|r| (*r * scale).clamp(glam::DVec3::ZERO, glam::DVec3::ONE))
        .collect();
    let metadata = serde_json::json!({
        "bake_mode": mode.name(),
        "color_0": quantity,
        "color_scale": scale,
        "ambient": ambient_term.to_array(),
        "picture_exposure": exposure,
    });
    (colours, metadata)
}

/// `radiosity export-scene`: writes a built-in or file scene as glTF
/// (`.glb`, or `.gltf` with its `.bin`), staged like every output. Returns
/// the files written.
pub fn export_scene(scene: &str, out: &Path, load: &LoadOptions) -> Result<Vec<PathBuf>, Error> {
    load.validate()?;
    check_output(out, &["glb", "gltf"], "export-scene")?;
    let loaded = scene::load_with(scene, load)?;
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

/// A mesh that would be too large, explained with the size at fault and
/// where it came from: the flag the user gave, the scene's `#@mesh`
/// directive (file and line), or the default derived from the scene's
/// extent.
fn mesh_error(error: MeshError, job: &Job, suggested: &MeshHint, settings: &Settings) -> Error {
    let MeshError::TooManyElements {
        elements,
        patches,
        limit,
        ..
    } = error
    else {
        return Error::Mesh(error);
    };
    // Patches alone beyond the limit: the patch size is at fault.
    let (what, flag, size, given, fraction) = if patches > limit as u128 {
        (
            "patch",
            "--patch-size",
            settings.mesh.patch_size,
            job.patch_size,
            3,
        )
    } else {
        (
            "element",
            "--element-size",
            settings.mesh.element_size,
            job.element_size,
            40,
        )
    };
    // 1e-9 rather than 0.000000001.
    let size = if size < 1e-3 {
        format!("{size:e}")
    } else {
        format!("{size}")
    };
    let remedy = if given.is_some() {
        format!("raise {flag} (now {size} m)")
    } else if let Some(directive) = &suggested.directive {
        format!(
            "raise the {what} size of the #@mesh directive at {directive} (now {size} m) or give \
             a larger {flag}"
        )
    } else {
        format!(
            "give a {flag} larger than {size} m (the default: 1/{fraction} of the scene's size)"
        )
    };
    Error::MeshTooLarge {
        elements,
        limit,
        remedy,
    }
}

/// Progress of a solver, with completion estimated from the nearest
/// stopping rule (convergence on a log scale).
#[must_use]
pub fn progress_of(solver: &Solver<'_>) -> Progress {
    let stats = solver.stats();
    let settings = solver.settings();
    let fraction = solver.unshot_fraction();
    let mut completion: f64 = 0.0;
    if settings.converge > 0.0 {
        completion =
            completion.max((fraction.max(1e-300).ln() / settings.converge.ln()).clamp(0.0, 1.0));
    }
    if let Some(m) = settings.max_shots {
        completion = completion.max(stats.shots as f64 / m.max(1) as f64);
    }
    if let Some(m) = settings.max_subsources {
        completion = completion.max(stats.subsources as f64 / m.max(1) as f64);
    }
    Progress {
        shots: stats.shots,
        subsources: stats.subsources,
        unshot_fraction: fraction,
        completion: completion.min(1.0),
        elapsed: Duration::ZERO,
        rays_per_second: 0.0,
        remaining: None,
    }
}

/// The `--stats` file of design.md section 6: one JSON object of the run's
/// counts, counters, phase times (seconds) and the settings in force. The
/// keys are written sorted, whatever the order of the fields below.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct StatsFile {
    /// Scene name.
    pub scene: String,
    /// `surfaces`, `surface_ids`, `patches` (shooters), `elements`,
    /// `vertices`.
    #[serde(flatten)]
    pub counts: Counts,
    /// `shots`, `subsources`, `pairs`, `rays_cast`, `pretest_visible`,
    /// `pretest_hidden` and the solver's times: `hemicube_seconds`,
    /// `gather_seconds`, `pretest_thread_seconds`, `ray_thread_seconds`,
    /// `form_factor_thread_seconds`, `bookkeeping_seconds`.
    #[serde(flatten)]
    pub solver: Stats,
    /// Unshot power left over emitted power.
    pub unshot_fraction: f64,
    /// Why the solve stopped ([`StopReason::describe`]).
    pub stop_reason: &'static str,
    /// Reading the scene and merging its coplanar faces.
    pub load_seconds: f64,
    /// Building the element mesh.
    pub mesh_seconds: f64,
    /// The solve: accelerator build, solver set-up and shooting.
    pub solve_seconds: f64,
    /// Building the shadow-ray accelerator (part of `solve_seconds`).
    pub accel_build_seconds: f64,
    /// Drawing the picture and writing the other outputs.
    pub write_seconds: f64,
    /// The whole run up to writing this file.
    pub total_seconds: f64,
    /// Most memory held resident, bytes (`null` where the system does not
    /// say).
    pub peak_memory_bytes: Option<u64>,
    /// The estimate the run was checked against before its solve, bytes.
    pub estimated_memory_bytes: u64,
    /// Worker threads.
    pub threads: usize,
    /// The accelerator's build statistics by name
    /// ([`crate::accel::Occluder::build_statistics`]).
    pub accel_build: std::collections::BTreeMap<&'static str, usize>,
    /// The settings in force, the mesh sizes being those the run used.
    pub settings: Settings,
}

impl StatsFile {
    /// The statistics of a run that used `settings`.
    #[must_use]
    pub fn of(settings: &Settings, outcome: &Outcome) -> StatsFile {
        StatsFile {
            scene: outcome.scene.clone(),
            counts: outcome.counts,
            solver: outcome.stats.clone(),
            unshot_fraction: outcome.unshot_fraction,
            stop_reason: outcome.stop.describe(),
            load_seconds: outcome.load_time.as_secs_f64(),
            mesh_seconds: outcome.mesh_time.as_secs_f64(),
            solve_seconds: outcome.solve_time.as_secs_f64(),
            accel_build_seconds: outcome.accel_build_time.as_secs_f64(),
            write_seconds: outcome.write_time.as_secs_f64(),
            total_seconds: outcome.total_time.as_secs_f64(),
            peak_memory_bytes: outcome.peak_memory_bytes,
            estimated_memory_bytes: outcome.memory_estimate.total(),
            threads: outcome.threads,
            accel_build: outcome.accel_statistics.iter().copied().collect(),
            settings: settings.clone(),
        }
    }

    /// Writes the file as pretty-printed JSON with its keys sorted, and a
    /// final newline.
    pub fn write(&self, w: &mut dyn std::io::Write) -> std::io::Result<()> {
        // Through a `Value`, whose objects keep their keys sorted.
        let value = serde_json::to_value(self)?;
        serde_json::to_writer_pretty(&mut *w, &value)?;
        w.write_all(b"\n")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn job(patch_size: Option<f64>, element_size: Option<f64>) -> Job {
        Job {
            scene: "room".into(),
            settings: Settings::adaptive(),
            patch_size,
            element_size,
            image: None,
            vertices_csv: None,
            stats_json: None,
            load: LoadOptions::default(),
            bake: None,
            ply: None,
            max_memory: None,
            sensors: None,
        }
    }

    #[test]
    fn mesh_sizes_come_from_the_job_else_the_scene() {
        let suggested = MeshHint {
            patch_size: 1.0,
            element_size: 0.1,
            directive: None,
        };
        let mesh = job(None, None).settings_for(&suggested).mesh;
        assert_eq!((mesh.patch_size, mesh.element_size), (1.0, 0.1));
        let mesh = job(Some(2.0), None).settings_for(&suggested).mesh;
        assert_eq!((mesh.patch_size, mesh.element_size), (2.0, 0.1));
        let mesh = job(None, Some(0.2)).settings_for(&suggested).mesh;
        assert_eq!((mesh.patch_size, mesh.element_size), (1.0, 0.2));
    }

    #[test]
    fn mesh_sizes_in_a_jobs_settings_are_refused_not_ignored() {
        assert!(validate(&job(None, None)).is_ok());
        let mut refused = job(None, None);
        refused.settings.mesh.element_size = 0.05;
        let message = validate(&refused).unwrap_err().to_string();
        assert!(message.contains("element_size"), "{message}");
    }
}
