//! `radiosity experiment pictures`, beyond the paper (whose Figure 5.1
//! shows the mesh's vertex radiosities, Gouraud-shaded): how close the
//! *pictures* are to the light, under each final pass
//! ([`radiosity::final_gather`]: the mesh alone; the direct light evaluated
//! at each sample, after Wallace, Elmquist & Haines 1989's ray-traced final
//! pass; and a one-bounce gather from the mesh, after Lischinski, Tampieri &
//! Greenberg 1993).
//!
//! For each scene, solved once at the default preset: the picture the
//! command line draws (its camera, 800 x 600, 3 x 3 supersampling) under
//! `off`, `direct` and `full`; 2,000 pixel centres drawn at random (a fixed
//! sequence) whose ray from the eye meets the front of a surface that is not
//! an emitter, and whose four neighbours' rays meet the same surface (away
//! from silhouettes); the Radiance reference at those surface points (the
//! shared harness, as `--sensors` are scored) against the linear pixel
//! values. Reported: the mean absolute relative error over the bright
//! points (`score.py`'s: reference above 2% of its 95th percentile), L1, the
//! bias, the reference's noise floor, the picture's grain ([`grain`]: the
//! noise left in its smooth parts, 8-bit levels) and the final pass's
//! seconds.

use std::fmt::Write as _;
use std::time::Instant;

use glam::DVec3;

use super::grain;
use super::reference::{self, Harness};
use super::validate::{SCENES, SceneCase, camera_of, scene_file, uniform, write_rows};
use super::{Context, Error, Report, table};
use radiosity::app;
use radiosity::final_gather::{FinalGather, FinalPass, Point};
use radiosity::render::{self, RenderSettings};
use radiosity::scene::{self, Camera, LoadOptions, Scene};
use radiosity::solver::{Flow, Settings, Solver, refine};

/// The scenes drawn: the room and both Cornell boxes.
pub const PICTURE_SCENES: [&str; 3] = ["room", "cornell", "cornell_box"];

/// Pixel centres scored per scene.
pub const PIXELS: usize = 2000;

/// The picture's size and supersampling: the command line's defaults.
const WIDTH: u32 = 800;
const HEIGHT: u32 = 600;
const SUPERSAMPLING: u32 = 3;

/// A scored pixel: its index, and its centre's surface point.
struct Pixel {
    index: usize,
    surface: usize,
    position: DVec3,
}

/// The ray from the eye through `(x, y)` (pixel units, y down), as the
/// rasteriser projects.
fn pixel_ray(camera: &Camera, x: f64, y: f64) -> DVec3 {
    let forward = (camera.target - camera.eye).normalize();
    let right = forward.cross(camera.up).normalize();
    let up = right.cross(forward);
    let tan_half = (0.5 * camera.fov_degrees.to_radians()).tan();
    let half_height = 0.5 * f64::from(HEIGHT);
    let sx = (x - 0.5 * f64::from(WIDTH)) / half_height * tan_half;
    let sy = (half_height - y) / half_height * tan_half;
    (forward + right * sx + up * sy).normalize()
}

/// The front surface (and point) the eye sees through `(x, y)`.
fn seen(solver: &Solver<'_>, camera: &Camera, x: f64, y: f64) -> Option<(usize, DVec3)> {
    let scene = solver.scene();
    let direction = pixel_ray(camera, x, y);
    let (lo, hi) = scene.bounds();
    let reach = 4.0 * (hi - lo).length() + (camera.eye - lo).length();
    let hit = solver
        .occluder()
        .closest_hit(camera.eye, direction, reach, [u32::MAX; 2])?;
    let s = &scene.surfaces[hit.surface as usize];
    (s.normal.dot(direction) < 0.0).then(|| (hit.surface as usize, camera.eye + direction * hit.t))
}

/// [`PIXELS`] pixels away from silhouettes, on surfaces that do not emit.
fn pixels(solver: &Solver<'_>, camera: &Camera) -> Vec<Pixel> {
    let scene = solver.scene();
    let mut unit = uniform(0x91C7);
    let mut out = Vec::new();
    let mut tries = 0;
    while out.len() < PIXELS && tries < 100 * PIXELS {
        tries += 1;
        let x = (unit() * f64::from(WIDTH))
            .floor()
            .min(f64::from(WIDTH - 1));
        let y = (unit() * f64::from(HEIGHT))
            .floor()
            .min(f64::from(HEIGHT - 1));
        let Some((surface, position)) = seen(solver, camera, x + 0.5, y + 0.5) else {
            continue;
        };
        if scene.surfaces[surface].is_emitter() {
            continue;
        }
        let group = scene.surfaces[surface].group;
        let same = [(-1.0, 0.0), (1.0, 0.0), (0.0, -1.0), (0.0, 1.0)]
            .iter()
            .all(|(dx, dy)| {
                seen(solver, camera, x + 0.5 + dx, y + 0.5 + dy)
                    .is_some_and(|(s, _)| scene.surfaces[s].group == group)
            });
        if same {
            out.push(Pixel {
                index: (y as usize) * WIDTH as usize + x as usize,
                surface,
                position,
            });
        }
    }
    out
}

/// One mode's scores on one scene.
struct Scored {
    mode: FinalGather,
    mean_relative: f64,
    l1: f64,
    bias: f64,
    noise: f64,
    points: usize,
    grain: Option<grain::Grain>,
    seconds: f64,
}

/// Mean of `|B / Bref - 1|` over the bright points of `score`.
fn mean_relative(score: &reference::Score) -> f64 {
    let r: Vec<f64> = score.relative.iter().flatten().map(|r| r.abs()).collect();
    r.iter().sum::<f64>() / r.len().max(1) as f64
}

fn draw(solver: &Solver<'_>, mode: FinalGather, camera: Camera) -> (render::Image, f64) {
    let start = Instant::now();
    let settings = RenderSettings {
        width: WIDTH,
        height: HEIGHT,
        camera,
        supersampling: SUPERSAMPLING,
    };
    let display = solver.display_radiosity(true);
    let image = if mode == FinalGather::Off {
        render::render(solver.scene(), solver.mesh(), &display, &settings)
    } else {
        let pass = FinalPass::new(solver, mode);
        render::render_shaded(
            solver.scene(),
            solver.mesh(),
            &pass.vertex_display(&display, solver.ambient()),
            &settings,
            Some(&|points: &[Point]| pass.shade(points)),
        )
    };
    (image, start.elapsed().as_secs_f64())
}

fn load(context: &Context, case: &SceneCase) -> Result<(std::path::PathBuf, Scene), Error> {
    let path = scene_file(context, case)?;
    let mut scene = scene::load_with(&path.to_string_lossy(), &LoadOptions::default())
        .map_err(app::Error::from)?
        .scene;
    if Settings::adaptive().merge_coplanar {
        scene::merge::merge_coplanar(&mut scene.surfaces);
    }
    Ok((path, scene))
}

/// Runs the experiment (by name only: it needs the reference harness and
/// minutes of Radiance per new set of points).
///
/// # Errors
/// When the harness is missing or fails, or a scene does not load.
pub fn pictures(context: &Context) -> Result<Report, Error> {
    let harness = Harness::find(context)?;
    let mut report = Report::default();
    let mut rows = Vec::new();
    let names: &[&str] = if context.quick {
        &PICTURE_SCENES[1..2]
    } else {
        &PICTURE_SCENES
    };
    for case in SCENES.iter().filter(|c| names.contains(&c.name)) {
        let (path, scene) = load(context, case)?;
        let mut settings = Settings::adaptive();
        settings.mesh = settings.mesh.sized_for(&scene);
        let mut refined = refine::refined_mesh(&scene, &settings, None)
            .map_err(|e| Error::App(app::Error::Mesh(e)))?;
        let going_on = refined.start.take();
        let occluder = settings.accel.build(&scene.surfaces);
        let mut solver = Solver::resume_or_new(
            &scene,
            &refined.mesh,
            settings,
            going_on,
            Vec::new(),
            occluder,
        );
        solver.run(|_| Flow::Continue);
        let camera = camera_of(case, &scene);
        let chosen = pixels(&solver, &camera);
        let mut scored = Vec::new();
        for mode in FinalGather::ALL {
            let (image, seconds) = draw(&solver, mode, camera);
            let b: Vec<DVec3> = chosen
                .iter()
                .map(|p| image.pixels[p.index].as_dvec3())
                .collect();
            let csv_rows: Vec<(DVec3, DVec3, u32, DVec3)> = chosen
                .iter()
                .zip(&b)
                .map(|(p, b)| {
                    let s = &scene.surfaces[p.surface];
                    (p.position, s.normal, s.face, *b)
                })
                .collect();
            let stem = format!("pictures-{}-{}", case.name, mode.name());
            let csv = context.path(&format!("{stem}.csv"));
            write_rows(&csv, &csv_rows)?;
            let answer = harness.score_rows(
                &path,
                &csv,
                if context.quick { "medium" } else { "high" },
                &context.path(&format!("{stem}.json")),
                None,
                PIXELS,
            )?;
            let ours: Vec<DVec3> = answer.rows.iter().map(|&r| b[r]).collect();
            let score = reference::score(&ours, &answer.reference);
            score.check_against(&answer, &stem)?;
            let rgb = image.to_srgb8(image.exposure_scale(render::Exposure::Auto { ev: 0.0 }));
            let grain = grain::grain(
                &grain::luma(&rgb),
                image.width as usize,
                image.height as usize,
                &|i| image.coverage[i] >= 1.0,
            );
            if mode != FinalGather::Off {
                let png = context.path(&format!("{stem}.png"));
                let mut bytes = Vec::new();
                radiosity::export::write_png(&mut bytes, image.width, image.height, &rgb).map_err(
                    |source| Error::Output {
                        path: png.clone(),
                        source,
                    },
                )?;
                super::write_file(&png, &bytes)?;
                report.files.push(png);
            }
            scored.push(Scored {
                mode,
                mean_relative: mean_relative(&score),
                l1: score.l1,
                bias: score.bias,
                noise: answer.noise,
                points: score.points,
                grain,
                seconds,
            });
        }
        for s in &scored {
            rows.push(vec![
                case.name.to_string(),
                s.mode.name().to_string(),
                format!("{:.2}%", 100.0 * s.mean_relative),
                format!("{:.2}%", 100.0 * s.l1),
                format!("{:+.2}%", 100.0 * s.bias),
                format!("{:.2}%", 100.0 * s.noise),
                s.points.to_string(),
                s.grain.map_or_else(
                    || "-".to_string(),
                    |g| format!("{:.2} ({:.2})", g.p95, g.worst),
                ),
                format!("{:.2}", s.seconds),
            ]);
        }
    }
    report.body.push_str(&table(
        &[
            "scene",
            "final gather",
            "mean abs. relative",
            "L1",
            "bias",
            "reference noise",
            "points",
            "grain p95 (worst)",
            "picture s",
        ],
        &rows,
    ));
    let mut notes = String::new();
    let _ = write!(
        notes,
        "Pictures at {WIDTH} x {HEIGHT}, {SUPERSAMPLING} x {SUPERSAMPLING} supersampling, the \
         default preset's solve; {PIXELS} pixel centres per scene away from silhouettes (their \
         four neighbours see the same surface), emitters left out; linear pixel values against \
         the Radiance reference at the centres' surface points. Mean absolute relative error \
         over the bright points (reference above 2% of its 95th percentile); L1 = sum |B - Bref| \
         / sum Bref; reference noise: score.py's rough floor. Grain: the rms of the picture's \
         luma less its 5 x 5 median over 16 x 16 tiles away from edges, 8-bit levels, the 95th \
         percentile of tiles (the worst). 'picture s': drawing the picture, \
         final pass included, {} threads.",
        rayon::current_num_threads()
    );
    report.paragraph(&notes);
    report.setting("pixels", PIXELS);
    report.setting(
        "picture",
        format!("{WIDTH}x{HEIGHT}, supersampling {SUPERSAMPLING}"),
    );
    Ok(report)
}
