//! The experiments that run the solver: Figure 2.1 (one subsource shot with
//! and without the hemicube pre-test, paper section 2), Figure 5.1 (the
//! room after 9, 48 and 72 subsources, both methods, section 5) and
//! Figure 5.2 (their solve times).

use std::time::Instant;

use glam::{DVec3, Vec3};

use super::{Context, Error, Report, median, table};
use radiosity::accel::Accel;
use radiosity::export::{self, Staged};
use radiosity::form_factor::FormFactor;
use radiosity::mesh::{Mesh, MeshSettings};
use radiosity::render::{self, Exposure, Image, RenderSettings};
use radiosity::scene::{self, Scene};
use radiosity::solver::{Flow, Preset, Settings, Solver, Stats, Visibility};
use radiosity::{app, luminance, view};

/// A scene meshed with its suggested sizes, or with an element size chosen
/// to give about `target_vertices` vertices.
fn meshed(name: &str, target_vertices: Option<usize>) -> Result<(Scene, Mesh), Error> {
    let scene = scene::load(name).map_err(app::Error::from)?;
    let sizes = scene.default_mesh_sizes();
    let settings = |element_size: f64| MeshSettings {
        patch_size: sizes.patch_size,
        element_size,
        ..MeshSettings::default()
    };
    let build = |element_size: f64| {
        Mesh::build(&scene, &settings(element_size)).map_err(|e| Error::App(app::Error::Mesh(e)))
    };
    let Some(target) = target_vertices else {
        let mesh = build(sizes.element_size)?;
        return Ok((scene, mesh));
    };
    // Vertex count falls as the element size grows: bisect on a log scale.
    let (mut small, mut large) = (sizes.element_size / 20.0, sizes.element_size * 20.0);
    for _ in 0..40 {
        let mid = (small * large).sqrt();
        if build(mid)?.vertices.len() > target {
            small = mid;
        } else {
            large = mid;
        }
    }
    let below = build(large)?;
    let above = build(small)?;
    let mesh = if target.abs_diff(below.vertices.len()) <= target.abs_diff(above.vertices.len()) {
        below
    } else {
        above
    };
    Ok((scene, mesh))
}

/// Solves with `settings`, timing the solver's construction (the
/// accelerator's build) and the shots.
fn timed_solve<'a>(scene: &'a Scene, mesh: &'a Mesh, settings: &Settings) -> (Solver<'a>, f64) {
    let start = Instant::now();
    let mut solver = Solver::new(scene, mesh, settings.clone());
    solver.run(|_| Flow::Continue);
    let seconds = start.elapsed().as_secs_f64();
    (solver, seconds)
}

fn seconds(s: f64) -> String {
    if s < 0.01 {
        format!("{:.2} ms", s * 1e3)
    } else {
        format!("{s:.3}")
    }
}

/// The median time of the first shot alone (the solver, with its
/// accelerator and item buffers, built beforehand), and its counters.
fn median_first_shot(
    scene: &Scene,
    mesh: &Mesh,
    settings: &Settings,
    repetitions: usize,
) -> (f64, Stats) {
    let mut times = Vec::with_capacity(repetitions);
    let mut stats = Stats::default();
    for _ in 0..repetitions {
        let mut solver = Solver::new(scene, mesh, settings.clone());
        let start = Instant::now();
        solver.shoot();
        times.push(start.elapsed().as_secs_f64());
        stats = solver.stats().clone();
    }
    (median(&mut times), stats)
}

/// The scenes of Figure 2.1: name, the paper's vertex count, and the paper's
/// seconds per subsource (ray casting; pre-test with hardware and with
/// software rasterisation).
const FIG2_1_SCENES: [(&str, usize, [&str; 3]); 2] = [
    ("cornell", 796, ["1.2", "1.2", "5.3"]),
    ("room", 4311, ["21.6", "6.8", "12.0"]),
];

/// One measurement of Figure 2.1: the first shot of one scene with one
/// visibility method and accelerator.
#[derive(Clone, Debug)]
pub struct FirstShot {
    /// Scene name.
    pub scene: &'static str,
    /// The scene's surfaces.
    pub surfaces: usize,
    /// The mesh's vertices (the paper's size, approximately).
    pub vertices: usize,
    /// The paper's seconds per subsource: ray casting, pre-test with
    /// hardware and with software rasterisation.
    pub paper: [&'static str; 3],
    /// Shadow-ray accelerator.
    pub accel: Accel,
    /// Visibility method.
    pub visibility: Visibility,
    /// Median time of the shot, in seconds.
    pub seconds: f64,
    /// The shot's counters (of the last repetition).
    pub stats: Stats,
}

/// What Figure 2.1 measures: every scene, accelerator and visibility
/// method, in that nesting order.
#[derive(Clone, Debug)]
pub struct Fig21 {
    /// Repetitions of each shot (the median is kept).
    pub repetitions: usize,
    /// One measurement per scene, accelerator and visibility method.
    pub shots: Vec<FirstShot>,
}

/// Times the first shot, with ray casting for every pair and with the
/// hemicube pre-test, on scenes of about 796 and 4,311 vertices (the
/// paper's sizes), for every accelerator.
///
/// # Errors
///
/// If a scene does not load or mesh.
pub fn fig2_1_compute(repetitions: usize) -> Result<Fig21, Error> {
    let mut shots = Vec::new();
    for (name, target, paper) in FIG2_1_SCENES {
        let (scene, mesh) = meshed(name, Some(target))?;
        for accel in Accel::ALL {
            for visibility in Visibility::ALL {
                let settings = Settings {
                    accel,
                    visibility,
                    form_factor: FormFactor::Analytic,
                    ..Settings::wallace89()
                };
                let (seconds, stats) = median_first_shot(&scene, &mesh, &settings, repetitions);
                shots.push(FirstShot {
                    scene: name,
                    surfaces: scene.surfaces.len(),
                    vertices: mesh.vertices.len(),
                    paper,
                    accel,
                    visibility,
                    seconds,
                    stats,
                });
            }
        }
    }
    Ok(Fig21 { repetitions, shots })
}

/// Figure 2.1: the time to shoot one subsource, with ray casting for every
/// pair and with the hemicube pre-test, on scenes of about 796 and 4,311
/// vertices (the paper's sizes), for every accelerator.
pub fn fig2_1(context: &Context) -> Result<Report, Error> {
    Ok(fig2_1_report(&fig2_1_compute(context.repetitions())?))
}

/// The report of Figure 2.1: time per subsource beside the paper's, the
/// rays the pre-test avoids, and each accelerator's ray throughput.
#[must_use]
pub fn fig2_1_report(data: &Fig21) -> Report {
    let mut report = Report::default();
    let mut rows = Vec::new();
    let mut counts = Vec::new();
    let mut throughput = Vec::new();
    for shot in &data.shots {
        let FirstShot {
            scene: name,
            accel,
            visibility,
            paper,
            ref stats,
            ..
        } = *shot;
        let per_subsource = shot.seconds / stats.subsources as f64;
        if visibility == Visibility::Ray {
            throughput.push(vec![
                format!("{name} ({} surfaces)", shot.surfaces),
                accel.name().to_string(),
                format!(
                    "{:.2} M",
                    stats.rays_cast as f64 / stats.ray_time.as_secs_f64() / 1e6
                ),
            ]);
        }
        let paper_value = match (accel, visibility) {
            (Accel::Brute, Visibility::Ray) => paper[0].to_string(),
            (Accel::Brute, Visibility::HemicubePretest) => {
                format!("{} (hardware), {} (software)", paper[1], paper[2])
            }
            _ => "-".to_string(),
        };
        rows.push(vec![
            format!("{name} ({} vertices)", shot.vertices),
            visibility.name().to_string(),
            accel.name().to_string(),
            seconds(per_subsource),
            paper_value,
        ]);
        if accel == Accel::Brute {
            counts.push(vec![
                format!("{name} ({} vertices)", shot.vertices),
                visibility.name().to_string(),
                (stats.pairs / stats.subsources).to_string(),
                (stats.rays_cast / stats.subsources).to_string(),
                (stats.pretest_visible / stats.subsources).to_string(),
                (stats.pretest_hidden / stats.subsources).to_string(),
                format!(
                    "{:.1}%",
                    100.0 * (1.0 - stats.rays_cast as f64 / stats.pairs.max(1) as f64)
                ),
            ]);
        }
    }
    report.setting("shot", "the first shot (the brightest light), 3 x 3 subsources, analytic form factor; time per subsource = median shot time / 9, hemicube rasterisation included, accelerator build excluded (it is done once per solve)");
    report.setting(
        "hemicube resolution",
        radiosity::hemicube::DEFAULT_RESOLUTION,
    );
    report.setting("repetitions", data.repetitions);
    report.body.push_str(&table(
        &[
            "scene",
            "visibility",
            "accelerator",
            "ours (s per subsource)",
            "paper (s, SGI Indigo)",
        ],
        &rows,
    ));
    report.paragraph("Rays avoided by the pre-test, per subsource:");
    report.body.push_str(&table(
        &[
            "scene",
            "visibility",
            "pairs",
            "rays cast",
            "pre-test visible",
            "pre-test hidden",
            "rays avoided",
        ],
        &counts,
    ));
    report.paragraph(
        "Shadow-ray throughput of each accelerator on the same shots (rays per second per \
         core: rays cast over the thread time spent casting them):",
    );
    report.body.push_str(&table(
        &["scene", "accelerator", "rays per second per core"],
        &throughput,
    ));
    report
}

/// The subsource counts of Figure 5.1 and the paper's times (Figure 5.2):
/// (subsources, Wallace's seconds, Wong & Tsang's seconds, sources shot).
const PAPER_STEPS: [(u64, f64, f64, u32); 3] = [
    (9, 116.8, 55.1, 1),
    (48, 554.7, 243.0, 16),
    (72, 826.0, 363.5, 29),
];

/// The configurations of Figure 5.2: the two presets and each improvement
/// alone on top of `wallace89`.
fn configurations() -> Vec<(&'static str, Settings)> {
    let base = Settings::wallace89();
    vec![
        (Preset::Wallace89.name(), base.clone()),
        (
            "+ hemicube pre-test only",
            Settings {
                visibility: Visibility::HemicubePretest,
                ..base.clone()
            },
        ),
        (
            "+ BSP only",
            Settings {
                accel: Accel::Bsp,
                ..base.clone()
            },
        ),
        (
            "+ analytic factor only",
            Settings {
                form_factor: FormFactor::Analytic,
                ..base
            },
        ),
        (Preset::WongTsang93.name(), Preset::WongTsang93.settings()),
        (
            "wong-tsang93 with BVH instead of BSP",
            Settings {
                accel: Accel::Bvh,
                ..Settings::wong_tsang93()
            },
        ),
    ]
}

/// One configuration's solves in Figure 5.2.
#[derive(Clone, Debug)]
pub struct Fig52Configuration {
    /// Its name (see `configurations`).
    pub label: &'static str,
    /// Median solve time in seconds at each of the paper's steps.
    pub seconds: Vec<f64>,
    /// Shots at each step.
    pub shots: Vec<u64>,
}

/// What Figure 5.2 measures: solve times of every configuration at 9, 48
/// and 72 subsources, and wong-tsang93's at 72 by thread count.
#[derive(Clone, Debug)]
pub struct Fig52 {
    /// The room's surfaces.
    pub surfaces: usize,
    /// Its patches.
    pub patches: usize,
    /// Its elements.
    pub elements: usize,
    /// Its vertices.
    pub vertices: usize,
    /// Repetitions of every solve (interleaved; the median is kept).
    pub repetitions: usize,
    /// One entry per configuration, wallace89 first.
    pub configurations: Vec<Fig52Configuration>,
    /// wong-tsang93 at 72 subsources: (threads, median seconds), one
    /// thread first.
    pub threads: Vec<(usize, f64)>,
}

/// Solves the room with every configuration up to each of the paper's
/// subsource counts, and wong-tsang93 at 72 on one thread and on the pool
/// in use.
///
/// # Errors
///
/// If the room does not load or mesh, or a thread pool cannot be built.
pub fn fig5_2_compute(repetitions: usize) -> Result<Fig52, Error> {
    let (scene, mesh) = meshed("room", None)?;
    let configurations = configurations();
    // Repetitions interleave every configuration and step, so drift in the
    // machine's speed (it is shared) falls on all of them alike.
    let mut samples = vec![vec![Vec::new(); PAPER_STEPS.len()]; configurations.len()];
    let mut shots = vec![vec![0; PAPER_STEPS.len()]; configurations.len()];
    for _ in 0..repetitions {
        for (c, (_, base)) in configurations.iter().enumerate() {
            for (s, (subsources, ..)) in PAPER_STEPS.iter().enumerate() {
                let settings = Settings {
                    max_subsources: Some(*subsources),
                    converge: 0.0,
                    ..base.clone()
                };
                let (solver, time) = timed_solve(&scene, &mesh, &settings);
                samples[c][s].push(time);
                shots[c][s] = solver.stats().shots;
            }
        }
    }
    let solves = configurations
        .iter()
        .zip(&mut samples)
        .zip(shots)
        .map(|(((label, _), samples), shots)| Fig52Configuration {
            label,
            seconds: samples.iter_mut().map(|s| median(s)).collect(),
            shots,
        })
        .collect();

    // Threads: the 72-subsource solve of wong-tsang93 on one thread and on
    // the pool in use.
    let settings = Settings {
        max_subsources: Some(72),
        converge: 0.0,
        ..Settings::wong_tsang93()
    };
    let all = rayon::current_num_threads();
    let pools = [1, all]
        .into_iter()
        .map(|threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .map(|pool| (threads, pool))
                .map_err(|e| Error::Experiment(format!("a pool of {threads} threads: {e}")))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut thread_samples = vec![Vec::new(); pools.len()];
    for _ in 0..repetitions {
        for ((_, pool), samples) in pools.iter().zip(&mut thread_samples) {
            samples.push(pool.install(|| timed_solve(&scene, &mesh, &settings).1));
        }
    }
    let threads = pools
        .iter()
        .zip(&mut thread_samples)
        .map(|((threads, _), samples)| (*threads, median(samples)))
        .collect();
    Ok(Fig52 {
        surfaces: scene.surfaces.len(),
        patches: mesh.patches.len(),
        elements: mesh.elements.len(),
        vertices: mesh.vertices.len(),
        repetitions,
        configurations: solves,
        threads,
    })
}

/// Figure 5.2: solve times at 9, 48 and 72 subsources.
pub fn fig5_2(context: &Context) -> Result<Report, Error> {
    Ok(fig5_2_report(&fig5_2_compute(context.repetitions())?))
}

/// The report of Figure 5.2: solve times, speed-ups over wallace89, the
/// paper's times, and the speed-up from threads.
#[must_use]
pub fn fig5_2_report(data: &Fig52) -> Report {
    let mut report = Report::default();
    let rows: Vec<Vec<String>> = data
        .configurations
        .iter()
        .map(|configuration| {
            let mut row = vec![configuration.label.to_string()];
            for (time, shots) in configuration.seconds.iter().zip(&configuration.shots) {
                row.push(format!("{} ({shots} shots)", seconds(*time)));
            }
            row
        })
        .collect();
    let wallace = &data.configurations[0].seconds;
    let ratios: Vec<Vec<String>> = data
        .configurations
        .iter()
        .map(|configuration| {
            let mut row = vec![configuration.label.to_string()];
            for (w, t) in wallace.iter().zip(&configuration.seconds) {
                row.push(format!("{:.2}x", w / t));
            }
            row
        })
        .collect();
    let mut paper = vec![
        vec!["wallace89 (paper)".to_string()],
        vec!["wong-tsang93 (paper)".to_string()],
        vec!["ratio (paper)".to_string()],
    ];
    for (_, w, t, _) in PAPER_STEPS {
        paper[0].push(format!("{w}"));
        paper[1].push(format!("{t}"));
        paper[2].push(format!("{:.2}x", w / t));
    }
    let headers = [
        "configuration",
        "9 subsources",
        "48 subsources",
        "72 subsources",
    ];
    report.setting(
        "scene",
        format!(
            "room: {} surfaces, {} patches, {} elements, {} vertices",
            data.surfaces, data.patches, data.elements, data.vertices
        ),
    );
    report.setting(
        "subsources per shot",
        "3 x 3 (the solve stops once the count is reached, so 48 means 6 shots = 54 subsources)",
    );
    report.setting("repetitions", format!("{} (interleaved)", data.repetitions));
    report.paragraph("Solve time in seconds (median; solver construction, including the BSP build, and all shots):");
    report.body.push_str(&table(&headers, &rows));
    report.paragraph("Speed-up over wallace89:");
    report.body.push_str(&table(&headers, &ratios));
    report.paragraph("The paper's Figure 5.2 (seconds on an SGI IRIS Indigo):");
    report.body.push_str(&table(&headers, &paper));

    let one_thread = data.threads[0].1;
    let thread_rows: Vec<Vec<String>> = data
        .threads
        .iter()
        .map(|(threads, time)| {
            vec![
                threads.to_string(),
                seconds(*time),
                format!("{:.2}x", one_thread / time),
            ]
        })
        .collect();
    report.paragraph("wong-tsang93 at 72 subsources by thread count:");
    report
        .body
        .push_str(&table(&["threads", "seconds", "speed-up"], &thread_rows));
    report
}

/// Draws the room's display radiosity with a given exposure.
fn picture(scene: &Scene, mesh: &Mesh, solver: &Solver<'_>, width: u32, height: u32) -> Image {
    let settings = RenderSettings {
        width,
        height,
        camera: view::camera_or_framing(scene),
        supersampling: 2,
    };
    render::render(scene, mesh, &solver.display_radiosity(true), &settings)
}

/// Writes a PNG of 8-bit RGB pixels.
fn write_png(
    context: &Context,
    name: &str,
    width: u32,
    height: u32,
    rgb: &[u8],
) -> Result<std::path::PathBuf, Error> {
    let path = context.path(name);
    Staged::write(&path, |w| export::write_png(w, width, height, rgb))
        .and_then(Staged::commit)
        .map_err(|source| Error::Output {
            path: path.clone(),
            source,
        })?;
    Ok(path)
}

/// One row of Figure 5.1: both methods after `subsources` subsources.
pub struct Fig51Step {
    /// Subsources shot.
    pub subsources: u64,
    /// The paper's sources at this step.
    pub sources: u32,
    /// Shots of wong-tsang93.
    pub shots: u64,
    /// wong-tsang93's picture (linear radiance).
    pub ours: Image,
    /// wallace89's picture.
    pub theirs: Image,
    /// Mean and maximum per-vertex difference of the displayed luminance,
    /// relative to the mean over non-emitting vertices.
    pub vertex: (f64, f64),
    /// Per-pixel difference of the pictures.
    pub pixel: PixelDifference,
}

/// What Figure 5.1 shows: the room by both methods at each of the paper's
/// steps, in the paper's order, and the one exposure of every picture.
pub struct Fig51 {
    /// Picture width in pixels.
    pub width: u32,
    /// Picture height in pixels.
    pub height: u32,
    /// The auto-exposure of wong-tsang93 at the largest count.
    pub exposure: f64,
    /// One step per row (9, 48, 72 subsources).
    pub steps: Vec<Fig51Step>,
}

/// Solves the room with wong-tsang93 and wallace89 up to each of the
/// paper's subsource counts and renders both.
///
/// # Errors
///
/// If the room does not load or mesh.
pub fn fig5_1_compute(quick: bool) -> Result<Fig51, Error> {
    let (scene, mesh) = meshed("room", None)?;
    let (width, height) = if quick { (160, 120) } else { (480, 360) };
    let mut steps = Vec::new();
    let mut exposure = None;
    // Largest count first so its exposure serves every picture.
    for &(subsources, .., sources) in PAPER_STEPS.iter().rev() {
        let solve = |settings: Settings| {
            timed_solve(
                &scene,
                &mesh,
                &Settings {
                    max_subsources: Some(subsources),
                    converge: 0.0,
                    ..settings
                },
            )
        };
        let (ours, _) = solve(Settings::wong_tsang93());
        let (theirs, _) = solve(Settings::wallace89());
        let ours_image = picture(&scene, &mesh, &ours, width, height);
        let theirs_image = picture(&scene, &mesh, &theirs, width, height);
        exposure.get_or_insert_with(|| ours_image.exposure_scale(Exposure::Auto { ev: 0.0 }));
        steps.push(Fig51Step {
            subsources,
            sources,
            shots: ours.stats().shots,
            pixel: pixel_difference(&ours_image, &theirs_image),
            vertex: vertex_difference(&scene, &mesh, &ours, &theirs),
            ours: ours_image,
            theirs: theirs_image,
        });
    }
    steps.reverse();
    Ok(Fig51 {
        width,
        height,
        exposure: exposure.unwrap_or(1.0),
        steps,
    })
}

/// An 8-bit RGB picture to write: file name, width, height, pixels.
pub type Rgb8 = (String, u32, u32, Vec<u8>);

/// The pictures of Figure 5.1, largest count first: each step's
/// wong-tsang93, wallace89 and difference pictures, then `fig5-1.png`,
/// every step's three side by side, one row per step.
#[must_use]
pub fn fig5_1_plot(data: &Fig51) -> Vec<Rgb8> {
    let (width, height) = (data.width, data.height);
    let mut pictures = Vec::new();
    let mut sheet: Vec<Vec<u8>> = Vec::new();
    for step in data.steps.iter().rev() {
        let subsources = step.subsources;
        let difference = difference_picture(&step.ours, &step.theirs, data.exposure);
        let strip = [
            ("wong-tsang93", step.ours.to_srgb8(data.exposure)),
            ("wallace89", step.theirs.to_srgb8(data.exposure)),
            ("difference", difference),
        ];
        sheet.push(side_by_side(
            &strip.each_ref().map(|(_, rgb)| rgb.as_slice()),
            width,
            height,
        ));
        for (label, rgb) in strip {
            pictures.push((
                format!("fig5-1-{label}-{subsources}.png"),
                width,
                height,
                rgb,
            ));
        }
    }
    sheet.reverse();
    pictures.push(("fig5-1.png".into(), width * 3, height * 3, sheet.concat()));
    pictures
}

/// Figure 5.1: the room after 9, 48 and 72 subsources, by both methods,
/// side by side with their difference.
pub fn fig5_1(context: &Context) -> Result<Report, Error> {
    let data = fig5_1_compute(context.quick)?;
    let mut report = fig5_1_report(&data);
    for (name, width, height, rgb) in fig5_1_plot(&data) {
        report
            .files
            .push(write_png(context, &name, width, height, &rgb)?);
    }
    Ok(report)
}

/// The report of Figure 5.1: the picture and the table of differences.
#[must_use]
pub fn fig5_1_report(data: &Fig51) -> Report {
    let mut report = Report::default();
    let (width, height) = (data.width, data.height);
    let rows: Vec<Vec<String>> = data
        .steps
        .iter()
        .map(|step| {
            let (vertex_mean, vertex_max) = step.vertex;
            vec![
                format!(
                    "{} ({} shots; paper: {} sources)",
                    step.subsources, step.shots, step.sources
                ),
                format!("{:.2}%", 100.0 * vertex_mean),
                format!("{:.2}%", 100.0 * vertex_max),
                format!("{:.2}%", 100.0 * step.pixel.mean),
                format!("{:.2}%", 100.0 * step.pixel.p99),
            ]
        })
        .collect();
    report.setting("pictures", format!("{width} x {height}, 2 x 2 supersampling, one exposure for all (auto-exposure of wong-tsang93 at 72)"));
    report.paragraph(
        "Rows: after 9, 48 and 72 subsources. Columns: wong-tsang93 (the paper's left \
         column), wallace89 (its right column), and the difference |ours - Wallace's| in \
         display luminance, scaled x8.",
    );
    report.paragraph("![Figure 5.1](fig5-1.png)");
    report.paragraph(
        "Differences between the two methods: per vertex, of the displayed radiosity \
         (B + rho * ambient, luminance), relative to the mean over non-emitting vertices; per \
         pixel, relative to the mean pixel luminance.",
    );
    report.body.push_str(&table(
        &[
            "subsources",
            "vertex mean",
            "vertex max",
            "pixel mean",
            "pixel 99th percentile",
        ],
        &rows,
    ));
    report
}

/// Mean and 99th percentile of a per-pixel relative difference.
pub struct PixelDifference {
    /// Mean of `|a - b| / mean(a)` in luminance.
    pub mean: f64,
    /// Its 99th percentile.
    pub p99: f64,
}

/// |a - b| in luminance relative to a's mean luminance, per pixel.
fn pixel_difference(a: &Image, b: &Image) -> PixelDifference {
    let lum = |p: Vec3| luminance(p.as_dvec3());
    let mean_a = a.pixels.iter().map(|p| lum(*p)).sum::<f64>() / a.pixels.len() as f64;
    let mut relative: Vec<f64> = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .map(|(p, q)| (lum(*p) - lum(*q)).abs() / mean_a.max(1e-30))
        .collect();
    let mean = relative.iter().sum::<f64>() / relative.len() as f64;
    let k = ((relative.len() - 1) as f64 * 0.99) as usize;
    let (_, p99, _) = relative.select_nth_unstable_by(k, f64::total_cmp);
    PixelDifference { mean, p99: *p99 }
}

/// The difference picture: |a - b| in luminance at exposure `scale`, x8,
/// grey.
fn difference_picture(a: &Image, b: &Image, scale: f64) -> Vec<u8> {
    let lum = |p: Vec3| luminance(p.as_dvec3());
    a.pixels
        .iter()
        .zip(&b.pixels)
        .flat_map(|(p, q)| {
            let d = ((lum(*p) - lum(*q)).abs() * scale * 8.0).min(1.0);
            let v = (255.0 * d.powf(1.0 / 2.2)) as u8;
            [v, v, v]
        })
        .collect()
}

/// Mean and maximum per-vertex difference of displayed luminance, relative
/// to the mean over non-emitting vertices.
fn vertex_difference(scene: &Scene, mesh: &Mesh, a: &Solver<'_>, b: &Solver<'_>) -> (f64, f64) {
    let (da, db) = (a.display_radiosity(true), b.display_radiosity(true));
    let reflecting: Vec<(DVec3, DVec3)> = mesh
        .vertices
        .iter()
        .zip(da.iter().zip(&db))
        .filter(|(v, _)| !scene.surfaces[v.surface as usize].is_emitter())
        .map(|(_, (x, y))| (*x, *y))
        .collect();
    let mean = reflecting.iter().map(|(x, _)| luminance(*x)).sum::<f64>() / reflecting.len() as f64;
    let diffs: Vec<f64> = reflecting
        .iter()
        .map(|(x, y)| (luminance(*x) - luminance(*y)).abs() / mean)
        .collect();
    let max = diffs.iter().copied().fold(0.0, f64::max);
    (diffs.iter().sum::<f64>() / diffs.len() as f64, max)
}

/// Places equally sized RGB pictures left to right.
fn side_by_side(pictures: &[&[u8]], width: u32, height: u32) -> Vec<u8> {
    let row = 3 * width as usize;
    let mut out = Vec::with_capacity(pictures.len() * row * height as usize);
    for y in 0..height as usize {
        for p in pictures {
            out.extend_from_slice(&p[y * row..(y + 1) * row]);
        }
    }
    out
}
