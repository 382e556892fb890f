//! Figure 2.1 of Wong & Tsang 1993 (section 2, the hemicube pre-test),
//! `radiosity experiment fig2-1`: the time to shoot one subsource with ray
//! casting for every vertex-subsource pair and with the hemicube pre-test
//! deciding most pairs without a ray, on scenes of about the paper's 796
//! and 4,311 vertices, for every shadow-ray accelerator; with the rays the
//! pre-test avoids and each accelerator's ray throughput.

use std::time::Instant;

use super::solving::{meshed, seconds};
use super::{Context, Error, Report, median, table};
use radiosity::accel::Accel;
use radiosity::form_factor::FormFactor;
use radiosity::mesh::Mesh;
use radiosity::scene::Scene;
use radiosity::solver::patches::PatchSettings;
use radiosity::solver::{MethodSettings, Settings, Solver, Stats, Visibility};

/// The median time of the first shot alone (the solver, with its
/// accelerator and item buffers, built beforehand), and its counters.
fn median_first_shot(
    scene: &Scene,
    mesh: &Mesh,
    settings: &Settings,
    repetitions: usize,
) -> (f64, Stats, [u64; 2]) {
    let mut times = Vec::with_capacity(repetitions);
    let mut stats = Stats::default();
    let mut pretest = [0; 2];
    for _ in 0..repetitions {
        let mut solver = Solver::new(scene, mesh, settings.clone());
        let start = Instant::now();
        solver.shoot();
        times.push(start.elapsed().as_secs_f64());
        stats = solver.stats().clone();
        pretest = ["pretest_visible", "pretest_hidden"].map(|name| solver.count(name));
    }
    (median(&mut times), stats, pretest)
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
    /// Pairs the pre-test found visible and hidden (of the last
    /// repetition).
    pub pretest: [u64; 2],
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
                    method: MethodSettings::Patches(PatchSettings {
                        visibility,
                        ..PatchSettings::default()
                    }),
                    form_factor: FormFactor::Analytic,
                    ..Settings::wallace89()
                };
                let (seconds, stats, pretest) =
                    median_first_shot(&scene, &mesh, &settings, repetitions);
                shots.push(FirstShot {
                    scene: name,
                    surfaces: scene.surfaces.len(),
                    vertices: mesh.vertices.len(),
                    paper,
                    accel,
                    visibility,
                    seconds,
                    stats,
                    pretest,
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
                (shot.pretest[0] / stats.subsources).to_string(),
                (shot.pretest[1] / stats.subsources).to_string(),
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
