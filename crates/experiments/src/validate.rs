//! `radiosity experiment validate`, beyond the paper (Wong & Tsang 1993 compare
//! their method with Wallace's, never with the light a physically based
//! renderer finds): the built-in scenes and the measured Cornell box, solved
//! with the default preset and the paper's, each scored against the Radiance
//! reference harness ([`super::reference`]) as `score.py` scores a vertices
//! CSV: L1, bias, median and 90th-percentile relative error over 600 sampled
//! vertices, with the solve's time and the reference's. Each scene gets an
//! error picture: the relative error `B / Bref - 1` at every sampled vertex the
//! scene's camera sees, drawn as a dot on the rasterised solution in grey (blue
//! too dark, red too bright), with a colour bar.
//!
//! The reference takes minutes for each new mesh (it is cached by mesh in
//! `$REFCACHE`, default `/tmp/reference-cache`); the solves take seconds.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::DVec3;

pub use super::error_picture::{ERROR_RANGE, ErrorPoint, error_picture, error_pictures};
use super::plot::Picture;
pub use super::points::{SENSOR_POINTS, random_points, uniform, write_rows};
use super::reference::{self, Harness};
use super::{Context, Error, Report, table, write_file};
use radiosity::app;
use radiosity::export;
use radiosity::final_gather::{FinalGather, FinalPass};
use radiosity::luminance;
use radiosity::mesh::{Mesh, MeshSettings};
use radiosity::scene::sky::{
    DEFAULT_GROUND_REFLECTANCE, DEFAULT_SUBDIVISION, Daylight, SkySpec, SunSpec,
};
use radiosity::scene::{self, Camera, LoadOptions, Scene, builtin};
use radiosity::sensors::{self, SensorPoint};
use radiosity::solver::{Flow, Preset, Settings, Shooting, Solver, refine};
use radiosity::view;

/// A scene of the experiments and where its OBJ comes from.
#[derive(Clone, Copy, Debug)]
pub struct SceneCase {
    /// Name in the tables and file names.
    pub name: &'static str,
    /// A built-in scene's name, or a path under the shared scenes' folder.
    pub source: &'static str,
    /// Whether `source` is in the shared scenes' folder.
    pub shared: bool,
    /// A scene lit by lights that are not surfaces (`#@light` in its file,
    /// daylight): the daylight flags its solve and its reference take
    /// (`--sun ALTITUDE AZIMUTH LUX --sky MODEL --sky-illuminance LUX`, or
    /// empty), scored with `tools/reference_lights.py`; `None` for a scene
    /// lit by its surfaces alone.
    pub lights: Option<&'static str>,
    /// More flags for `tools/reference_lights.py` alone (its sample
    /// counts), where the default leaves the reference noisier than the
    /// error to measure.
    pub reference: &'static str,
}

/// The scenes `validate` scores.
pub const SCENES: [SceneCase; 7] = [
    SceneCase {
        name: "room",
        source: "room",
        shared: false,
        lights: None,
        reference: "",
    },
    SceneCase {
        name: "cornell",
        source: "cornell",
        shared: false,
        lights: None,
        reference: "",
    },
    SceneCase {
        name: "tworooms",
        source: "tworooms",
        shared: false,
        lights: None,
        reference: "",
    },
    SceneCase {
        name: "cornell_box",
        source: "cornell_box/cornell_box.obj",
        shared: true,
        lights: None,
        reference: "",
    },
    SceneCase {
        name: "lamp_room",
        source: "lamp_room",
        shared: false,
        lights: Some(""),
        reference: "",
    },
    SceneCase {
        name: "window_room",
        source: "window_room",
        shared: false,
        lights: Some("--sun 35 200 60000 --sky clear --sky-illuminance 12000"),
        // Four times the paths and sky rays of `high`: the sky through the
        // window and skylight brings the reference's noise below 0.5%.
        reference: "--paths 16384 --sky-rays 262144",
    },
    // Rooms off a corridor, joined by doors, lit in one room alone
    // (`tools/gen_scenes.py`'s `suite`): light crossing enclosures.
    SceneCase {
        name: "suite",
        source: "suite",
        shared: false,
        lights: None,
        reference: "",
    },
];

/// The scenes shipped with the experiments rather than built in: the
/// rooms lit by lights that are not surfaces (written by
/// `scenes/make_light_scenes.py`) and the rooms off a corridor (written by
/// `tools/gen_scenes.py`): name, OBJ, MTL.
const EXPERIMENT_SCENES: [(&str, &str, &str); 3] = [
    (
        "lamp_room",
        include_str!("../scenes/lamp_room.obj"),
        include_str!("../scenes/lamp_room.mtl"),
    ),
    (
        "window_room",
        include_str!("../scenes/window_room.obj"),
        include_str!("../scenes/window_room.mtl"),
    ),
    (
        "suite",
        include_str!("../scenes/suite.obj"),
        include_str!("../scenes/suite.mtl"),
    ),
];

/// Daylight from the flags of [`SceneCase::lights`].
///
/// # Errors
///
/// If a flag or its values are not understood.
pub fn daylight(flags: &str) -> Result<Daylight, Error> {
    let bad = || Error::Experiment(format!("daylight flags '{flags}' not understood"));
    let words: Vec<&str> = flags.split_whitespace().collect();
    let number = |i: usize| -> Result<f64, Error> {
        words.get(i).and_then(|w| w.parse().ok()).ok_or_else(bad)
    };
    let mut daylight = Daylight::default();
    let (mut model, mut illuminance) = (None, None);
    let mut i = 0;
    while i < words.len() {
        match words[i] {
            "--sun" => {
                daylight.sun = Some(SunSpec {
                    altitude: number(i + 1)?,
                    azimuth: number(i + 2)?,
                    illuminance: number(i + 3)?,
                });
                i += 4;
            }
            "--sky" => {
                model = Some(
                    words
                        .get(i + 1)
                        .ok_or_else(bad)?
                        .parse()
                        .map_err(|_| bad())?,
                );
                i += 2;
            }
            "--sky-illuminance" => {
                illuminance = Some(number(i + 1)?);
                i += 2;
            }
            _ => return Err(bad()),
        }
    }
    if let (Some(model), Some(illuminance)) = (model, illuminance) {
        daylight.sky = Some(SkySpec {
            model,
            illuminance,
            subdivision: DEFAULT_SUBDIVISION,
            ground_reflectance: DEFAULT_GROUND_REFLECTANCE,
        });
    }
    Ok(daylight)
}

/// The presets compared: the default and the paper's.
#[must_use]
pub fn presets() -> [(&'static str, Settings); 2] {
    [Preset::Adaptive, Preset::WongTsang93].map(|p| (p.name(), p.settings()))
}

/// The name of the default preset's row on the GPU.
pub const ON_GPU: &str = "adaptive-gpu";

/// The name of the default preset's row with `--overshoot 1`.
pub const OVERSHOOT: &str = "adaptive-overshoot";

/// The default preset with overshooting (`--overshoot 1`).
#[must_use]
pub fn overshooting() -> Settings {
    let mut settings = Preset::Adaptive.settings();
    if let radiosity::solver::MethodSettings::Adaptive(a) = &mut settings.method {
        a.overshoot = 1.0;
    }
    settings
}

/// The name of the default preset's row with `--round 1`: one shooter at
/// a time, as the paper's loop.
pub const ONE_BY_ONE: &str = "adaptive-round-1";

/// The default preset shooting one shooter a round (`--round 1`).
#[must_use]
pub fn one_by_one() -> Settings {
    let mut settings = Preset::Adaptive.settings();
    if let radiosity::solver::MethodSettings::Adaptive(a) = &mut settings.method {
        a.round = 1.0;
    }
    settings
}

/// [`presets`], the default with overshooting ([`OVERSHOOT`]) and one
/// shooter a round ([`ONE_BY_ONE`]), and the default on the GPU when
/// `--device` opens one.
///
/// # Errors
///
/// When `--device gpu` finds no adapter.
pub fn presets_on(context: &Context) -> Result<Vec<(&'static str, Settings)>, Error> {
    let mut presets = presets().to_vec();
    presets.push((OVERSHOOT, overshooting()));
    presets.push((ONE_BY_ONE, one_by_one()));
    if let Some(device) = crate::gpu_device(context)? {
        presets.push((
            ON_GPU,
            Settings {
                device,
                ..Preset::Adaptive.settings()
            },
        ));
    }
    Ok(presets)
}

/// The OBJ file of a scene: a built-in one is written (OBJ and MTL, as
/// shipped) into `scenes/` of the output folder for the harness to read.
pub fn scene_file(context: &Context, case: &SceneCase) -> Result<PathBuf, Error> {
    if case.shared {
        return reference::shared_scene(context, case.source);
    }
    let embedded = EXPERIMENT_SCENES
        .iter()
        .find(|(name, _, _)| *name == case.source)
        .map(|(name, obj, mtl)| (*obj, format!("{name}.mtl"), *mtl));
    let (obj, mtl_name, mtl) = match embedded {
        Some(files) => files,
        None => builtin::files(case.source)
            .map(|(obj, mtl_name, mtl)| (obj, mtl_name.to_string(), mtl))
            .ok_or_else(|| Error::Experiment(format!("no built-in scene {}", case.source)))?,
    };
    let folder = context.path("scenes");
    std::fs::create_dir_all(&folder).map_err(|source| Error::Output {
        path: folder.clone(),
        source,
    })?;
    let path = folder.join(format!("{}.obj", case.source));
    write_file(&path, obj.as_bytes())?;
    write_file(&folder.join(&mtl_name), mtl.as_bytes())?;
    Ok(path)
}

/// The view of a scene's pictures: its own camera; the measured Cornell
/// box, which brings none, is seen from the built-in box's camera (the same
/// box, measured by the same lab).
#[must_use]
pub fn camera_of(case: &SceneCase, scene: &Scene) -> Camera {
    if case.name == "cornell_box"
        && let Some(Ok(cornell)) = builtin::load("cornell")
        && let Some(camera) = cornell.camera
    {
        return camera;
    }
    view::camera_or_framing(scene)
}

/// A scene solved as `radiosity render` solves it.
pub struct Solved {
    /// The scene (coplanar faces merged if the settings say so).
    pub scene: Scene,
    /// Its mesh.
    pub mesh: Mesh,
    /// `B` per vertex.
    pub radiosity: Vec<DVec3>,
    /// What the picture shows per vertex (ambient term included).
    pub display: Vec<DVec3>,
    /// `E` at each sensor.
    pub sensor_irradiance: Vec<DVec3>,
    /// `E` at each sensor under `--final-gather full` (its direct light and
    /// a gather of the mesh's reflected light over its hemisphere); empty
    /// for a preset whose final pass is off, or without sensors.
    pub sensor_full: Vec<DVec3>,
    /// Seconds of the solve: receiver refinement's coarse pass, the
    /// solver's construction (accelerator build) and its shots (`--stats`
    /// reports the coarse pass in `mesh_seconds`).
    pub solve_seconds: f64,
    /// Elements of the base grid before refinement.
    pub base_elements: usize,
    /// Shots taken.
    pub shots: u64,
    /// Unshot fraction at the end.
    pub unshot: f64,
    /// Shots whose transfers ran on the settings' device (0 on the CPU).
    pub device_shots: u64,
}

/// Loads, meshes and solves the scene at `path` with `settings` (mesh sizes
/// from `patch_size` or the scene's suggestion), gathering at `points` too.
pub fn solve(
    path: &Path,
    settings: &Settings,
    patch_size: Option<f64>,
    points: &[SensorPoint],
) -> Result<Solved, Error> {
    solve_lit(path, Daylight::default(), settings, patch_size, points)
}

/// [`solve`] with `daylight` added to the scene.
pub fn solve_lit(
    path: &Path,
    daylight: Daylight,
    settings: &Settings,
    patch_size: Option<f64>,
    points: &[SensorPoint],
) -> Result<Solved, Error> {
    solve_then(path, daylight, settings, patch_size, points, |_| ()).map(|(solved, ())| solved)
}

/// [`solve_lit`], calling `then` with the solver before it is dropped
/// (for what needs the solve's own state: the final pass).
pub fn solve_then<T>(
    path: &Path,
    daylight: Daylight,
    settings: &Settings,
    patch_size: Option<f64>,
    points: &[SensorPoint],
    then: impl FnOnce(&Solver<'_>) -> T,
) -> Result<(Solved, T), Error> {
    let name = path.to_string_lossy();
    let options = LoadOptions {
        daylight,
        ..LoadOptions::default()
    };
    let mut scene = scene::load_with(&name, &options)
        .map_err(app::Error::from)?
        .scene;
    if settings.merge_coplanar {
        scene::merge::merge_coplanar(&mut scene.surfaces);
    }
    let receivers = if points.is_empty() {
        Vec::new()
    } else {
        sensors::receivers(&scene, points, Path::new("sensor points")).map_err(app::Error::from)?
    };
    // The rows of the default method show the final pass; the paper's
    // presets' rows their mesh's values, as the paper did.
    let shows_final_pass = settings.method.shooting() == Shooting::Adaptive;
    let mut settings = settings.clone();
    let sized = settings.mesh.sized_for(&scene);
    settings.mesh = MeshSettings {
        patch_size: patch_size.unwrap_or(sized.patch_size),
        ..sized
    };
    let start = Instant::now();
    // As a render runs it: the coarse pass goes on on the refined mesh.
    let base = Mesh::build(&scene, &settings.mesh).map_err(|e| Error::App(app::Error::Mesh(e)))?;
    let mut refined = refine::refine_base(&scene, &settings, base, None, &receivers)
        .map_err(|e| Error::App(app::Error::Mesh(e)))?;
    let going_on = refined.start.take();
    let (mesh, base_elements) = (refined.mesh, refined.base_elements);
    let occluder = settings.accel.build(&scene.surfaces);
    let mut solver = Solver::resume_or_new(&scene, &mesh, settings, going_on, receivers, occluder);
    solver.run(|_| Flow::Continue);
    let solve_seconds = start.elapsed().as_secs_f64();
    let sensor_irradiance = solver.sensor_irradiance().to_vec();
    let sensor_full = if points.is_empty() || !shows_final_pass {
        Vec::new()
    } else {
        FinalPass::new(&solver, FinalGather::Full).sensors(&solver)
    };
    let radiosity = solver.radiosity().to_vec();
    let display = solver.display_radiosity(true);
    let shots = solver.stats().shots;
    let unshot = solver.unshot_fraction();
    let device_shots = solver.device_report().device_shots;
    let after = then(&solver);
    drop(solver);
    let solved = Solved {
        scene,
        mesh,
        radiosity,
        display,
        sensor_irradiance,
        sensor_full,
        solve_seconds,
        base_elements,
        shots,
        unshot,
        device_shots,
    };
    Ok((solved, after))
}

/// The vertices CSV of a solve, as `--vertices` writes it.
pub fn write_vertices(path: &Path, solved: &Solved) -> Result<(), Error> {
    export::Staged::write(path, |w| {
        export::write_vertices_csv(w, &solved.scene, &solved.mesh, &solved.radiosity)
    })
    .and_then(export::Staged::commit)
    .map_err(|source| Error::Output {
        path: path.to_path_buf(),
        source,
    })
}

/// Percent with two decimals.
fn percent(x: f64) -> String {
    format!("{:.2}%", 100.0 * x)
}

/// Signed percent with two decimals.
fn signed_percent(x: f64) -> String {
    format!("{:+.2}%", 100.0 * x)
}

/// Seconds, readable.
pub fn seconds(s: f64) -> String {
    if s < 10.0 {
        format!("{s:.2}")
    } else {
        format!("{s:.0}")
    }
}

/// One scene solved with one preset and scored against the reference.
pub struct Validated {
    /// The scene.
    pub case: SceneCase,
    /// The preset's name.
    pub preset: &'static str,
    /// The solution.
    pub solved: Solved,
    /// What the harness sampled and `score.py` said.
    pub scored: reference::Scored,
    /// Our score of the same points (checked against `scored`).
    pub ours: reference::Score,
    /// `score.py`'s score of the values at [`SENSOR_POINTS`] random
    /// points ([`random_points`]), gathered as sensors.
    pub sensors: reference::Scored,
    /// The same under `--final-gather full` ([`Solved::sensor_full`]),
    /// where the preset has a final pass.
    pub sensors_full: Option<reference::Scored>,
    /// The vertices scored against `tools/reference_edges.py` (points on a
    /// face's edge moved off it): the default preset on the scenes lit by
    /// their surfaces.
    pub edges: Option<reference::Scored>,
}

/// The reference's accuracy: `high`, or `medium` in quick mode.
fn accuracy(context: &Context) -> &'static str {
    if context.quick { "medium" } else { "high" }
}

/// Solves every scene (only the built-in Cornell box in quick mode) with
/// each preset, writes its vertices CSV (`validate-SCENE-PRESET.csv`) and
/// has the harness score it (`.json` beside it); checks our score against
/// `score.py`'s.
///
/// # Errors
///
/// If a scene does not load, the harness fails, or the scores disagree.
pub fn validate_compute(context: &Context, harness: &Harness) -> Result<Vec<Validated>, Error> {
    let cases: &[SceneCase] = if context.quick {
        &SCENES[1..2]
    } else {
        &SCENES
    };
    let presets = presets_on(context)?;
    let mut results = Vec::new();
    for case in cases {
        let path = scene_file(context, case)?;
        let daylight = daylight(case.lights.unwrap_or(""))?;
        let scene = scene::load_with(
            &path.to_string_lossy(),
            &LoadOptions {
                daylight,
                ..LoadOptions::default()
            },
        )
        .map_err(app::Error::from)?
        .scene;
        let drawn = random_points(&scene, SENSOR_POINTS);
        let points: Vec<SensorPoint> = drawn.iter().map(|(p, _)| *p).collect();
        for (preset, settings) in &presets {
            let preset = *preset;
            let solved = solve_lit(&path, daylight, settings, None, &points)?;
            let reference_flags = case.lights.map(|l| format!("{l} {}", case.reference));
            let stem = format!("validate-{}-{preset}", case.name);
            let csv = context.path(&format!("{stem}.csv"));
            write_vertices(&csv, &solved)?;
            let scored = harness.score(
                &path,
                &csv,
                accuracy(context),
                &context.path(&format!("{stem}.json")),
                reference_flags.as_deref(),
            )?;
            let b: Vec<DVec3> = scored.rows.iter().map(|&r| solved.radiosity[r]).collect();
            let ours = reference::score(&b, &scored.reference);
            ours.check_against(&scored, &format!("{} {preset}", case.name))?;
            // The sensors' `B` from their irradiance, scored as a vertices CSV.
            let score_sensors = |irradiance: &[DVec3], stem: &str| {
                let rows: Vec<(DVec3, DVec3, u32, DVec3)> = drawn
                    .iter()
                    .zip(irradiance)
                    .map(|(&(p, surface), e)| {
                        let s = &scene.surfaces[surface];
                        (p.position, p.normal, s.face, s.emission + s.rho * *e)
                    })
                    .collect();
                let csv = context.path(&format!("{stem}.csv"));
                write_rows(&csv, &rows)?;
                harness.score(
                    &path,
                    &csv,
                    accuracy(context),
                    &context.path(&format!("{stem}.json")),
                    reference_flags.as_deref(),
                )
            };
            let sensors = score_sensors(&solved.sensor_irradiance, &format!("{stem}-sensors"))?;
            let sensors_full = if solved.sensor_full.is_empty() {
                None
            } else {
                Some(score_sensors(
                    &solved.sensor_full,
                    &format!("{stem}-sensors-full"),
                )?)
            };
            let edges = if case.lights.is_none() && preset == Preset::Adaptive.name() {
                Some(harness.score_edges(
                    &path,
                    &csv,
                    accuracy(context),
                    &context.path(&format!("{stem}-edges.json")),
                )?)
            } else {
                None
            };
            results.push(Validated {
                case: *case,
                preset,
                solved,
                scored,
                ours,
                sensors,
                sensors_full,
                edges,
            });
        }
    }
    Ok(results)
}

/// The error picture of one scene: its results' panels (see
/// [`error_picture`]) side by side with the colour bar.
///
/// # Errors
///
/// If plotting fails.
pub fn validate_plot(results: &[&Validated], size: (u32, u32)) -> Result<Picture, Error> {
    let panels = results
        .iter()
        .map(|v| {
            let points: Vec<ErrorPoint> = v
                .scored
                .rows
                .iter()
                .zip(&v.ours.relative)
                .map(|(&r, relative)| {
                    let vertex = &v.solved.mesh.vertices[r];
                    ErrorPoint {
                        position: vertex.position,
                        normal: vertex.normal,
                        group: vertex.group,
                        relative: *relative,
                    }
                })
                .collect();
            error_picture(
                &v.solved.scene,
                &v.solved.mesh,
                &v.solved.display,
                camera_of(&v.case, &v.solved.scene),
                &points,
                size,
            )
        })
        .collect::<Result<Vec<_>, Error>>()?;
    error_pictures(&panels)
}

/// The default on the GPU against the default on the CPU, scene by scene:
/// the difference of their scores and of the two solves' values at the
/// sensor points (the same points whatever mesh each refined), and the
/// shots the GPU made. `None` without a GPU row.
fn gpu_comparison(results: &[Validated]) -> Option<String> {
    let mut lines = Vec::new();
    for scene in by_scene(results) {
        let find = |name: &str| scene.iter().find(|v| v.preset == name);
        let (Some(cpu), Some(gpu)) = (find(Preset::Adaptive.name()), find(ON_GPU)) else {
            continue;
        };
        let (mut diff, mut total) = (0.0, 0.0);
        for (g, c) in gpu
            .solved
            .sensor_irradiance
            .iter()
            .zip(&cpu.solved.sensor_irradiance)
        {
            diff += (luminance(*g) - luminance(*c)).abs();
            total += luminance(*c).abs();
        }
        let sensors = if total > 0.0 { diff / total } else { 0.0 };
        lines.push(format!(
            "{}: L1 {} on the GPU, {} on the CPU ({:+.3} points); sensors L1 {} and {} \
             ({:+.3} points); the two solves' irradiance at the sensors differs by {} (L1); \
             {} of {} shots on the GPU",
            scene[0].case.name,
            percent(gpu.ours.l1),
            percent(cpu.ours.l1),
            100.0 * (gpu.ours.l1 - cpu.ours.l1),
            percent(gpu.sensors.l1),
            percent(cpu.sensors.l1),
            100.0 * (gpu.sensors.l1 - cpu.sensors.l1),
            percent(sensors),
            gpu.solved.device_shots,
            gpu.solved.shots,
        ));
    }
    (!lines.is_empty()).then(|| {
        format!(
            "The default on the GPU ({ON_GPU}, `--device`) against the CPU: {}. Each refines \
             its own mesh from its own coarse pass, so the two are compared at the sensor \
             points.",
            lines.join("; ")
        )
    })
}

/// The results of each scene, in order.
fn by_scene(results: &[Validated]) -> Vec<Vec<&Validated>> {
    let mut scenes: Vec<Vec<&Validated>> = Vec::new();
    for v in results {
        match scenes.last_mut() {
            Some(last) if last[0].case.name == v.case.name => last.push(v),
            _ => scenes.push(vec![v]),
        }
    }
    scenes
}

/// The picture file of a scene.
fn picture_file(case: &SceneCase) -> String {
    format!("validate-{}.png", case.name)
}

/// `radiosity experiment validate`: [`validate_compute`], a picture per
/// scene ([`validate_plot`]) and [`validate_report`].
pub fn validate(context: &Context) -> Result<Report, Error> {
    let harness = Harness::find(context)?;
    let results = validate_compute(context, &harness)?;
    let mut report = validate_report(context, &harness, &results);
    let size = if context.quick {
        (240, 180)
    } else {
        (480, 360)
    };
    for mut scene in by_scene(&results) {
        // The pictures show the default and the paper's; overshooting's
        // and one shooter a round's rows are in the table.
        scene.retain(|v| v.preset != OVERSHOOT && v.preset != ONE_BY_ONE);
        let path = context.path(&picture_file(&scene[0].case));
        validate_plot(&scene, size)?
            .write_png(&path)
            .map_err(|source| Error::Output {
                path: path.clone(),
                source,
            })?;
        report.files.push(path);
    }
    Ok(report)
}

/// The report of `validate`: the settings, the table of scores and the
/// error pictures with their panels' titles.
#[must_use]
pub fn validate_report(context: &Context, harness: &Harness, results: &[Validated]) -> Report {
    let accuracy = accuracy(context);
    let mut report = Report::default();
    report.setting("reference harness", harness.dir.display());
    report.setting(
        "reference",
        format!(
            "reference.py --accuracy {accuracy} at the 600 vertices score.py samples, cached in \
             $REFCACHE (default /tmp/reference-cache)"
        ),
    );
    report.setting(
        "presets",
        if results.iter().any(|v| v.preset == ON_GPU) {
            "adaptive (the default) and wong-tsang93 (the paper's), each at its default \
             settings; adaptive-overshoot: the default with --overshoot 1; adaptive-round-1: \
             the default with --round 1 (one shooter a round); adaptive-gpu: the default on the \
             GPU (--device)"
        } else {
            "adaptive (the default) and wong-tsang93 (the paper's), each at its default \
             settings; adaptive-overshoot: the default with --overshoot 1; adaptive-round-1: \
             the default with --round 1 (one shooter a round)"
        },
    );
    report.setting("threads", rayon::current_num_threads());
    let rows: Vec<Vec<String>> = results
        .iter()
        .map(|v| {
            let (solved, ours) = (&v.solved, &v.ours);
            vec![
                v.case.name.to_string(),
                v.preset.to_string(),
                if solved.mesh.elements.len() == solved.base_elements {
                    solved.mesh.elements.len().to_string()
                } else {
                    format!(
                        "{} ({} base)",
                        solved.mesh.elements.len(),
                        solved.base_elements
                    )
                },
                solved.mesh.vertices.len().to_string(),
                percent(ours.l1),
                v.edges
                    .as_ref()
                    .map_or_else(|| "-".into(), |e| percent(e.l1)),
                percent(v.sensors.l1),
                v.sensors_full
                    .as_ref()
                    .map_or_else(|| "-".into(), |s| percent(s.l1)),
                signed_percent(ours.bias),
                percent(ours.median),
                percent(ours.p90),
                format!("{} / {:.2}%", solved.shots, 100.0 * solved.unshot),
                seconds(solved.solve_seconds),
                v.scored
                    .reference_seconds
                    .map_or_else(|| "-".into(), seconds),
            ]
        })
        .collect();
    report.body.push_str(&table(
        &[
            "scene",
            "preset",
            "elements",
            "vertices",
            "L1",
            "L1, edges fixed",
            "sensors L1",
            "sensors L1, full",
            "bias",
            "median",
            "p90",
            "shots / unshot",
            "solve s",
            "reference s",
        ],
        &rows,
    ));
    report.paragraph(
        "L1 = sum |B - Bref| / sum Bref over the sampled vertices (channel means); sensors L1: \
         the same over 300 points drawn uniformly by area over the surfaces (a fixed sequence), \
         gathered as `--sensors` (as `off` and `direct` give them: a sensor gathers every shot          at its own point); sensors L1, full: the same points under `--final-gather full` (the          direct light there plus a gather of the mesh's reflected light over the hemisphere);          elements: after receiver refinement (the base grid's count \
         in brackets when it split some); L1, edges fixed: the same vertices against \
         tools/reference_edges.py, the harness's reference.py with points on an edge of their \
         face moved off that edge (reference.py can leave them within Radiance's 1e-6 m of the \
         surface meeting the edge, where its rays pass through it: 35-40% low at the top of a \
         lamp's side under the ceiling), for the default preset on the scenes lit by their \
         surfaces; bias = sum B / sum Bref - 1; median and p90: of |B / Bref - 1| over the points brighter than 2% of the \
         95th percentile of Bref. These are score.py's numbers (every score is checked against \
         its own output). Solve seconds: receiver refinement (the base mesh, its coarse pass and \
         the split), the solver's construction (accelerator build) and its shots, not \
         loading. Reference seconds: when the reference was computed \
         (2 cores), read from its cache.",
    );
    report.paragraph(
        "Error pictures: each sampled vertex the scene's camera sees, as a dot coloured by B / \
         Bref - 1 (blue: too dark, white: right, red: too bright; the bar spans -20% to +20%, \
         tick marks every 10%, beyond which the end colours stay), on the solution in grey. Grey dots: vertices \
         darker than 2% of the 95th percentile, which score.py leaves out of the median and \
         p90. The measured Cornell box is seen from the built-in box's camera.",
    );
    if let Some(paragraph) = gpu_comparison(results) {
        report.paragraph(&paragraph);
    }
    for scene in by_scene(results) {
        let titles: Vec<String> = scene
            .iter()
            .map(|v| format!("{} (L1 {})", v.preset, percent(v.ours.l1)))
            .collect();
        let name = scene[0].case.name;
        let _ = write!(
            report.body,
            "{name}, left to right: {}.\n\n![{name}]({})\n\n",
            titles.join(", "),
            picture_file(&scene[0].case)
        );
    }
    report
}
