//! Figure 5.2 of Wong & Tsang 1993 (section 5), `radiosity experiment
//! fig5-2`: the solve times of the room up to 9, 48 and 72 subsources with
//! Wallace's method (`wallace89`), with each of the paper's improvements
//! alone on top of it, with all of them (`wong-tsang93`) and with the BVH
//! in place of the BSP, beside the paper's times; and `wong-tsang93`'s
//! speed-up from threads.

use super::solving::{PAPER_STEPS, meshed, seconds, timed_solve};
use super::{Context, Error, Report, median, table};
use radiosity::accel::Accel;
use radiosity::form_factor::FormFactor;
use radiosity::solver::patches::PatchSettings;
use radiosity::solver::{MethodSettings, Preset, Settings, Visibility};

/// The configurations of Figure 5.2: the two presets and each improvement
/// alone on top of `wallace89`.
fn configurations() -> Vec<(&'static str, Settings)> {
    let base = Settings::wallace89();
    vec![
        (Preset::Wallace89.name(), base.clone()),
        (
            "+ hemicube pre-test only",
            Settings {
                method: MethodSettings::Patches(PatchSettings {
                    visibility: Visibility::HemicubePretest,
                    ..PatchSettings::default()
                }),
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
