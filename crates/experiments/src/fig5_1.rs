//! Figure 5.1 of Wong & Tsang 1993 (section 5), `radiosity experiment
//! fig5-1`: the room after 9, 48 and 72 subsources, solved with the
//! paper's method (`wong-tsang93`, the figure's left column) and with
//! Wallace's (`wallace89`, its right column), drawn with one exposure, side
//! by side with their difference; and the per-vertex and per-pixel
//! differences between the two methods.

use glam::{DVec3, Vec3};

use super::solving::{PAPER_STEPS, meshed, timed_solve};
use super::{Context, Error, Report, table};
use radiosity::export::{self, Staged};
use radiosity::luminance;
use radiosity::mesh::Mesh;
use radiosity::render::{self, Exposure, Image, RenderSettings};
use radiosity::scene::Scene;
use radiosity::solver::{Settings, Solver};

/// Draws the room's display radiosity with a given exposure.
fn picture(scene: &Scene, mesh: &Mesh, solver: &Solver<'_>, width: u32, height: u32) -> Image {
    let settings = RenderSettings {
        width,
        height,
        camera: radiosity::view::camera_or_framing(scene),
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
