//! `radiosity experiment scale`, beyond the paper (whose largest scene is its
//! room): what a whole render job costs as scenes grow from the paper's room
//! (171 faces) through the Sponza atrium (66k triangles) to the conference room
//! (277k triangles). Each scene is rendered with the default preset (adaptive
//! shooting, [`Settings::adaptive`]), the default with the other shadow-ray
//! accelerator forced (the BSP of Wong & Tsang 1993, section 3, beside the
//! default's BVH) and, on the built-in scenes, the paper's preset
//! (`wong-tsang93`).
//!
//! Every case is the binary's own job, run as a child process
//! (`radiosity render SCENE --stats FILE.json ...`): the peak resident
//! memory is per process, so each case's peak is its own. The child loads
//! the scene, meshes it, builds the accelerator, solves until the unshot
//! power falls below its preset's `--converge` or the case's time
//! limit ([`ScaleScene::time_limit`]) ends the solve, draws an 800 x 600
//! picture and writes it and the vertices CSV. The report tables its
//! `--stats`: sizes, the time of each phase, shots, the unshot fraction
//! left, rays and their rate, the peak memory, and where the solve's time
//! goes (form factors, shadow rays, refinement, book-keeping); a plot shows
//! solve time and peak memory against the number of input faces, both
//! logarithmic. Each scene's default job is run again stopped after 2, 5
//! and 10 seconds of solve, and its vertex radiosity scored against the
//! full run's ([`crate::early`]): how useful a time-limited picture is.
//! The pictures and statistics files stay in the output folder; the
//! vertices CSVs (hundreds of MB for the conference room) are written, to
//! time the writing, and removed.
//!
//! A case that fails (a memory refusal, a child that outlives its watchdog)
//! is reported as such and the others still run.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use plotters::prelude::*;

mod report;

pub use self::report::markdown;
use super::charts;
use super::early::{self, EARLY_SECONDS, Early};
use super::rays::{SceneSpec, scenes_folder};
use super::{Context, Error, Report, write_file};
use radiosity::accel::Accel;
use radiosity::solver::{Preset, Settings};

/// A scene of the experiment and the time its solve may take.
#[derive(Clone, Debug)]
pub struct ScaleScene {
    /// Name and origin (built in or in the shared scenes' folder).
    pub spec: SceneSpec,
    /// `--time-limit` of each case's solve, seconds: the solve stops there
    /// and the outputs are written from the state reached.
    pub time_limit: u64,
}

impl ScaleScene {
    /// The solve's time limit in seconds, shortened in quick mode for the
    /// shared (large) scenes. The built-in scenes keep theirs: a safety net
    /// far above the second or so they take, so what a quick run measures
    /// (converged or not, the mesh its coarse pass found) does not depend
    /// on how fast or busy the machine is.
    #[must_use]
    pub fn effective_time_limit(&self, quick: bool) -> u64 {
        if quick && self.spec.shared {
            self.time_limit.min(QUICK_TIME_LIMIT)
        } else {
            self.time_limit
        }
    }
}

/// The scenes of `radiosity experiment scale`, smallest first. The
/// built-in scenes and the measured box converge well within their time
/// limits; Sponza's (360 s) and the conference room's (960 s) lie beyond
/// the CPU path's targets for them (1% unshot in 300 s and 900 s on two
/// cores), so the report shows whether a solve meets its target or how
/// far it got. The whole experiment takes about an hour on two cores.
pub const SCENES: [ScaleScene; 5] = [
    ScaleScene {
        spec: SceneSpec {
            name: "cornell",
            source: "cornell",
            shared: false,
        },
        time_limit: 120,
    },
    ScaleScene {
        spec: SceneSpec {
            name: "cornell_box",
            source: "cornell_box/cornell_box.obj",
            shared: true,
        },
        time_limit: 120,
    },
    ScaleScene {
        spec: SceneSpec {
            name: "room",
            source: "room",
            shared: false,
        },
        time_limit: 120,
    },
    ScaleScene {
        spec: SceneSpec {
            name: "sponza",
            source: "sponza_dabrovic/sponza_dabrovic.obj",
            shared: true,
        },
        time_limit: 360,
    },
    ScaleScene {
        spec: SceneSpec {
            name: "conference",
            source: "conference/conference.obj",
            shared: true,
        },
        time_limit: 960,
    },
];

/// The built-in scenes of [`SCENES`] only: what runs without the shared
/// scenes, in seconds (the tests' subset).
#[must_use]
pub fn builtin_scenes() -> Vec<ScaleScene> {
    SCENES.iter().filter(|s| !s.spec.shared).cloned().collect()
}

/// Time limit of the shared scenes' cases in quick mode, seconds.
const QUICK_TIME_LIMIT: u64 = 20;

/// Quick mode meshes this many times coarser than the scene's suggestion.
const QUICK_COARSENING: f64 = 3.0;

/// How much longer than its solve's time limit a child may run before it
/// is killed: loading, meshing and writing the largest scene take minutes.
fn watchdog(time_limit: u64) -> Duration {
    Duration::from_secs(4 * time_limit + 600)
}

/// One configuration: its name in the tables and the `render` flags that
/// make it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Configuration {
    /// Name in the tables.
    pub name: String,
    /// Flags added to `radiosity render`.
    pub flags: Vec<String>,
}

/// The configurations run on a scene: the default; the default with
/// overshooting (`--overshoot 1`, the lever that takes fewer shots); on
/// built-in scenes, the default with each accelerator it does not already
/// use (BSP and BVH: the default's row is its own accelerator's; `rays`
/// compares them on the shared scenes) and the paper's preset (not in
/// quick mode: it shoots patches with hemicubes and takes seconds even on
/// the room).
#[must_use]
pub fn configurations(scene: &ScaleScene, quick: bool) -> Vec<Configuration> {
    let default = Settings::adaptive().accel;
    let mut list = vec![
        Configuration {
            name: format!("adaptive ({})", default.name()),
            flags: Vec::new(),
        },
        Configuration {
            name: "adaptive, --overshoot 1".into(),
            flags: vec!["--overshoot".into(), "1".into()],
        },
    ];
    for accel in [Accel::Bsp, Accel::Bvh] {
        if accel != default && !scene.spec.shared {
            list.push(Configuration {
                name: format!("adaptive, --accel {}", accel.name()),
                flags: vec!["--accel".into(), accel.name().into()],
            });
        }
    }
    if !scene.spec.shared && !quick {
        list.push(Configuration {
            name: Preset::WongTsang93.name().into(),
            flags: vec!["--preset".into(), Preset::WongTsang93.name().into()],
        });
    }
    list
}

/// What one case's `--stats` says.
#[derive(Clone, Debug, PartialEq)]
pub struct Run {
    /// Input faces (planar convex polygons after loading).
    pub faces: u64,
    /// Surfaces after merging adjacent coplanar faces (surface ids).
    pub surfaces: u64,
    /// Receiving elements.
    pub elements: u64,
    /// Shared vertices.
    pub vertices: u64,
    /// Reading the scene and merging its faces, seconds.
    pub load_seconds: f64,
    /// Building the mesh, seconds.
    pub mesh_seconds: f64,
    /// Building the shadow-ray accelerator, seconds.
    pub accel_build_seconds: f64,
    /// The solve after the accelerator's build (solver set-up and shots),
    /// seconds.
    pub solve_seconds: f64,
    /// Drawing the picture and writing the outputs, seconds.
    pub write_seconds: f64,
    /// The whole job as the child timed it, seconds.
    pub total_seconds: f64,
    /// Shooters shot.
    pub shots: u64,
    /// Unshot power over emitted power at the end.
    pub unshot_fraction: f64,
    /// Why the solve stopped (`converged`, `time limit reached`, ...).
    pub stop_reason: String,
    /// Why receiver refinement's coarse pass stopped (`None` without one):
    /// "time limit reached" when its share of the limit cut it short.
    pub coarse_stop_reason: Option<String>,
    /// Shadow rays traced.
    pub rays: u64,
    /// Thread time spent tracing shadow rays, summed over threads, seconds.
    pub ray_thread_seconds: f64,
    /// Thread time spent in form factors (point and element factors),
    /// seconds.
    pub form_factor_thread_seconds: f64,
    /// The rest of the gathering's thread time: refinement (choosing
    /// which parts of a source each receiver takes) or the paper's
    /// hemicube pre-test, seconds.
    pub refinement_thread_seconds: f64,
    /// Wall time of the shots' gathering, seconds.
    pub gather_seconds: f64,
    /// Wall time of the book-keeping after each shot, seconds.
    pub bookkeeping_seconds: f64,
    /// Worker threads.
    pub threads: u64,
    /// Peak resident memory of the child, bytes, where the system says.
    pub peak_memory_bytes: Option<u64>,
    /// The child's own estimate of its memory, bytes.
    pub estimated_memory_bytes: u64,
    /// The device its transfers ran on (`cpu`, or the GPU adapter).
    pub device: String,
    /// Shots whose transfers ran on that device.
    pub device_shots: u64,
    /// Shots of the coarse pass that ran on it.
    pub coarse_device_shots: u64,
    /// The device's shots' seconds preparing and sending data, in kernels,
    /// and reading back.
    pub device_seconds: [f64; 3],
}

impl Run {
    /// Reads a `--stats` object.
    pub fn from_stats(stats: &serde_json::Value) -> Result<Run, String> {
        let number = |key: &str| {
            stats[key]
                .as_f64()
                .ok_or_else(|| format!("the statistics have no number {key}"))
        };
        let count = |key: &str| {
            stats[key]
                .as_u64()
                .ok_or_else(|| format!("the statistics have no count {key}"))
        };
        let solve = number("solve_seconds")?;
        let build = number("accel_build_seconds")?;
        Ok(Run {
            faces: count("surfaces")?,
            surfaces: count("surface_ids")?,
            elements: count("elements")?,
            vertices: count("vertices")?,
            load_seconds: number("load_seconds")?,
            mesh_seconds: number("mesh_seconds")?,
            accel_build_seconds: build,
            solve_seconds: solve - build,
            write_seconds: number("write_seconds")?,
            total_seconds: number("total_seconds")?,
            shots: count("shots")?,
            unshot_fraction: number("unshot_fraction")?,
            stop_reason: stats["stop_reason"]
                .as_str()
                .ok_or("the statistics have no stop_reason")?
                .to_string(),
            coarse_stop_reason: stats["coarse_stop_reason"].as_str().map(str::to_string),
            rays: count("rays_cast")?,
            ray_thread_seconds: number("ray_thread_seconds")?,
            form_factor_thread_seconds: number("form_factor_thread_seconds")?,
            refinement_thread_seconds: number("pretest_thread_seconds")?,
            gather_seconds: number("gather_seconds")?,
            bookkeeping_seconds: number("bookkeeping_seconds")?,
            threads: count("threads")?,
            peak_memory_bytes: stats["peak_memory_bytes"].as_u64(),
            estimated_memory_bytes: count("estimated_memory_bytes")?,
            device: stats["device"].as_str().unwrap_or("cpu").to_string(),
            device_shots: stats["device_shots"].as_u64().unwrap_or(0),
            coarse_device_shots: stats["coarse_device_shots"].as_u64().unwrap_or(0),
            device_seconds: ["upload", "kernel", "readback"].map(|part| {
                stats[format!("device_{part}_seconds").as_str()]
                    .as_f64()
                    .unwrap_or(0.0)
            }),
        })
    }

    /// Whether the solve reached its preset's `--converge` (rather than
    /// its time limit).
    #[must_use]
    pub fn converged(&self) -> bool {
        self.stop_reason == "converged"
    }

    /// Rays traced per second of solve (after the build) per thread: the
    /// solve's throughput, form factors and book-keeping included.
    #[must_use]
    pub fn rays_per_second_per_thread(&self) -> f64 {
        self.rays as f64 / (self.solve_seconds * self.threads.max(1) as f64).max(1e-9)
    }

    /// Rays traced per second of tracing thread time: the accelerator's own
    /// rate.
    #[must_use]
    pub fn tracing_rays_per_second(&self) -> f64 {
        self.rays as f64 / self.ray_thread_seconds.max(1e-9)
    }
}

/// One scene in one configuration.
#[derive(Clone, Debug)]
pub struct Case {
    /// The scene's name.
    pub scene: &'static str,
    /// The configuration's name.
    pub configuration: String,
    /// The solve's time limit, seconds.
    pub time_limit: u64,
    /// The child's wall time, process start and exit included, seconds.
    pub wall_seconds: f64,
    /// What it measured, or why it failed.
    pub result: Result<Run, String>,
    /// The default configuration's early pictures against its final state
    /// ([`early`]); empty for the others.
    pub early: Vec<Early>,
}

/// `radiosity experiment scale`: every scene of [`SCENES`], each case a
/// child process of the running binary.
pub fn scale(context: &Context) -> Result<Report, Error> {
    let binary = std::env::current_exe()
        .map_err(|e| Error::Experiment(format!("cannot find the radiosity binary: {e}")))?;
    let cases = measure(context, &SCENES, &binary)?;
    report(context, &SCENES, &cases)
}

/// Runs every configuration of every scene with `binary` (a `radiosity`
/// executable) and returns the cases in order. Fails only when the shared
/// scenes are missing or the output folder cannot be written; a failing
/// case is recorded.
pub fn measure(
    context: &Context,
    scenes: &[ScaleScene],
    binary: &Path,
) -> Result<Vec<Case>, Error> {
    let specs: Vec<SceneSpec> = scenes.iter().map(|s| s.spec.clone()).collect();
    let folder = scenes_folder(context, &specs)?;
    std::fs::create_dir_all(&context.out).map_err(|source| Error::Output {
        path: context.out.clone(),
        source,
    })?;
    let threads = rayon::current_num_threads();
    // With a GPU (`--device`), the default on it too; the CPU's rows are
    // pinned to the CPU whatever `auto` would take.
    let gpu = radiosity_gpu::Gpu::open(context.device)
        .map_err(|e| Error::Experiment(format!("--device: {e}")))?
        .is_some();
    let mut cases = Vec::new();
    for scene in scenes {
        let source = if scene.spec.shared {
            folder.join(scene.spec.source).display().to_string()
        } else {
            scene.spec.source.to_string()
        };
        let time_limit = scene.effective_time_limit(context.quick);
        let mut common = vec!["--threads".to_string(), threads.to_string()];
        if context.quick {
            let element_size = radiosity::scene::load(&source)
                .map_err(radiosity::app::Error::from)?
                .default_mesh_sizes()
                .element_size;
            common.extend([
                "--element-size".into(),
                format!("{}", QUICK_COARSENING * element_size),
            ]);
        }
        let mut list = configurations(scene, context.quick);
        for c in &mut list {
            c.flags.extend(["--device".to_string(), "cpu".to_string()]);
        }
        if gpu {
            list.push(Configuration {
                name: format!(
                    "adaptive ({}), --device gpu",
                    Settings::adaptive().accel.name()
                ),
                flags: vec!["--device".into(), "gpu".into()],
            });
        }
        for (k, configuration) in list.into_iter().enumerate() {
            let stem = stem(scene.spec.name, &configuration.name);
            let mut args = common.clone();
            args.extend(configuration.flags.iter().cloned());
            // The default configuration keeps its vertices for its early
            // pictures to be scored against.
            let keep = k == 0;
            let (wall_seconds, result) =
                run_case(context, binary, &source, &stem, &args, time_limit, keep)?;
            let early = if keep {
                early_pictures(context, binary, &source, &stem, &args, time_limit)?
            } else {
                Vec::new()
            };
            cases.push(Case {
                scene: scene.spec.name,
                configuration: configuration.name,
                time_limit,
                wall_seconds,
                result,
                early,
            });
        }
    }
    Ok(cases)
}

/// The file name, without extension, of a case's picture and statistics.
fn stem(scene: &str, configuration: &str) -> String {
    format!("scale-{scene}-{}", slug(configuration))
}

/// A configuration's name as a file name's part.
fn slug(name: &str) -> String {
    let mut out = String::new();
    for c in name.chars() {
        if c.is_ascii_alphanumeric() {
            out.push(c.to_ascii_lowercase());
        } else if !out.ends_with('-') && !out.is_empty() {
            out.push('-');
        }
    }
    out.trim_end_matches('-').to_string()
}

/// Runs one `radiosity render` child with `--time-limit time_limit` and
/// `args`: its picture and statistics go to
/// `STEM.png` and `STEM.json` in the output folder, its vertices to
/// `STEM-vertices.csv` (removed afterwards unless `keep`), its error output
/// to `STEM.log` (removed when the run succeeds). Returns its wall time and
/// what it measured.
fn run_case(
    context: &Context,
    binary: &Path,
    source: &str,
    stem: &str,
    args: &[String],
    time_limit: u64,
    keep: bool,
) -> Result<(f64, Result<Run, String>), Error> {
    let picture = context.path(&format!("{stem}.png"));
    let stats = context.path(&format!("{stem}.json"));
    let vertices = context.path(&format!("{stem}-vertices.csv"));
    let log = context.path(&format!("{stem}.log"));
    let output = |path: &Path| {
        let path = path.to_path_buf();
        move |source| Error::Output { path, source }
    };
    let _ = std::fs::remove_file(&stats);
    let stderr = std::fs::File::create(&log).map_err(output(&log))?;
    let start = Instant::now();
    let mut child = Command::new(binary)
        .arg("render")
        .arg(source)
        .arg("--output")
        .arg(&picture)
        .arg("--vertices")
        .arg(&vertices)
        .arg("--stats")
        .arg(&stats)
        .arg("--quiet")
        .arg("--time-limit")
        .arg(time_limit.to_string())
        .args(args)
        .stdout(Stdio::null())
        .stderr(stderr)
        .spawn()
        .map_err(|e| Error::Experiment(format!("cannot run {}: {e}", binary.display())))?;
    let deadline = watchdog(time_limit);
    let status = loop {
        match child.try_wait() {
            Ok(Some(status)) => break Ok(status),
            Ok(None) if start.elapsed() > deadline => {
                let _ = child.kill();
                let _ = child.wait();
                break Err(format!(
                    "killed after {:.0} s (watchdog: {} s)",
                    start.elapsed().as_secs_f64(),
                    deadline.as_secs()
                ));
            }
            Ok(None) => std::thread::sleep(Duration::from_millis(50)),
            Err(e) => break Err(format!("cannot wait for the child: {e}")),
        }
    };
    let wall_seconds = start.elapsed().as_secs_f64();
    if !keep {
        let _ = std::fs::remove_file(&vertices);
    }
    let result = status.and_then(|status| {
        if status.success() {
            let text =
                std::fs::read_to_string(&stats).map_err(|e| format!("{}: {e}", stats.display()))?;
            let value: serde_json::Value =
                serde_json::from_str(&text).map_err(|e| format!("{}: {e}", stats.display()))?;
            Run::from_stats(&value)
        } else {
            let text = std::fs::read_to_string(&log).unwrap_or_default();
            let last = text.lines().rev().find(|l| !l.trim().is_empty());
            Err(format!("{status}: {}", last.unwrap_or("no message").trim()))
        }
    });
    if result.is_ok() {
        let _ = std::fs::remove_file(&log);
    }
    Ok((wall_seconds, result))
}

/// The default configuration's early pictures: the same job (`args`) with
/// `--time-limit` each of [`EARLY_SECONDS`] shorter than the case's own
/// limit, its vertices scored against the final state's (kept by the full
/// run, case `stem`); their files and the final state's vertices are
/// removed.
fn early_pictures(
    context: &Context,
    binary: &Path,
    source: &str,
    stem: &str,
    args: &[String],
    time_limit: u64,
) -> Result<Vec<Early>, Error> {
    let reference = context.path(&format!("{stem}-vertices.csv"));
    let final_state = early::vertex_radiosity(&reference);
    let _ = std::fs::remove_file(&reference);
    let Ok(final_state) = final_state else {
        return Ok(Vec::new());
    };
    let mut out = Vec::new();
    for seconds in EARLY_SECONDS.into_iter().filter(|&s| s < time_limit) {
        let early_stem = format!("{stem}-after-{seconds}s");
        let (_, run) = run_case(context, binary, source, &early_stem, args, seconds, true)?;
        let vertices = context.path(&format!("{early_stem}-vertices.csv"));
        let (stop_reason, coarse_stop_reason) = match &run {
            Ok(run) => (
                Some(run.stop_reason.clone()),
                run.coarse_stop_reason.clone(),
            ),
            Err(_) => (None, None),
        };
        let result = run.and_then(|run| {
            let values = early::vertex_radiosity(&vertices)?;
            Ok((early::l1(&values, &final_state)?, run.unshot_fraction))
        });
        for extension in ["png", "json", "log"] {
            let _ = std::fs::remove_file(context.path(&format!("{early_stem}.{extension}")));
        }
        let _ = std::fs::remove_file(&vertices);
        out.push(Early {
            seconds,
            result,
            stop_reason,
            coarse_stop_reason,
        });
    }
    Ok(out)
}

/// The plot's file in the output folder.
pub(crate) const PLOT_FILE: &str = "scale.svg";

/// The report and its files: the Markdown of [`markdown`], the plot of
/// [`plot`] written to `scale.svg`, and every successful case's picture and
/// statistics (written by [`measure`]) listed.
///
/// # Errors
///
/// If the plot cannot be drawn or written.
pub fn report(context: &Context, scenes: &[ScaleScene], cases: &[Case]) -> Result<Report, Error> {
    let mut report = markdown(context.quick, scenes, cases);
    let svg = plot(cases)?;
    let path = context.path(PLOT_FILE);
    write_file(&path, svg.as_bytes())?;
    report.files.push(path);
    for case in cases {
        if case.result.is_ok() {
            let stem = stem(case.scene, &case.configuration);
            for extension in ["png", "json"] {
                report
                    .files
                    .push(context.path(&format!("{stem}.{extension}")));
            }
        }
    }
    Ok(report)
}

/// Colours of the configurations, in order of appearance.
const PALETTE: [RGBColor; 4] = [
    RGBColor(0x1f, 0x77, 0xb4),
    RGBColor(0xd6, 0x27, 0x28),
    RGBColor(0x2c, 0xa0, 0x2c),
    RGBColor(0x94, 0x67, 0xbd),
];

/// Solve seconds and peak memory (MB) against input faces, log-log, one
/// series per configuration, side by side, as SVG.
pub fn plot(cases: &[Case]) -> Result<String, Error> {
    let runs: Vec<(&str, &Run)> = cases
        .iter()
        .filter_map(|c| {
            c.result
                .as_ref()
                .ok()
                .map(|r| (c.configuration.as_str(), r))
        })
        .collect();
    let mut series: Vec<&str> = Vec::new();
    for (name, _) in &runs {
        if !series.contains(name) {
            series.push(name);
        }
    }
    type Value = fn(&Run) -> f64;
    let panels: [(&str, &str, Value); 2] = [
        (
            "solve time",
            "solve seconds (after the accelerator's build)",
            |r| r.solve_seconds.max(1e-3),
        ),
        ("peak memory", "peak resident memory (MB)", |r| {
            r.peak_memory_bytes.map_or(f64::NAN, |b| b as f64 / 1e6)
        }),
    ];
    let range = |values: &mut dyn Iterator<Item = f64>| {
        let (lo, hi) = values
            .filter(|v| v.is_finite() && *v > 0.0)
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            });
        if lo.is_finite() {
            (lo / 1.5)..(hi * 1.5)
        } else {
            1.0..10.0
        }
    };
    let x_range = range(&mut runs.iter().map(|(_, r)| r.faces as f64));
    let mut svg = String::new();
    let failed = |e: &dyn std::fmt::Display| Error::Experiment(format!("plot scale: {e}"));
    {
        let root = SVGBackend::with_string(&mut svg, (1200, 520)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| failed(&e))?;
        for (area, (title, label, value)) in root.split_evenly((1, 2)).iter().zip(panels) {
            let y_range = range(&mut runs.iter().map(|(_, r)| value(r)));
            let mut chart = charts::log_log(
                area,
                &format!("{title} against scene size"),
                20,
                (x_range.clone(), "input faces"),
                (y_range, label),
            )
            .map_err(|e| failed(&e))?;
            for (i, name) in series.iter().enumerate() {
                let colour = PALETTE[i % PALETTE.len()];
                let mut points: Vec<(f64, f64, bool)> = runs
                    .iter()
                    .filter(|(n, r)| n == name && value(r).is_finite())
                    .map(|(_, r)| (r.faces as f64, value(r), r.converged()))
                    .collect();
                points.sort_by(|a, b| a.0.total_cmp(&b.0));
                charts::line(&mut chart, name, colour, points.iter().map(|p| (p.0, p.1)))
                    .map_err(|e| failed(&e))?;
                chart
                    .draw_series(points.iter().map(|&(x, y, converged)| {
                        let style = if converged {
                            colour.filled()
                        } else {
                            colour.stroke_width(2)
                        };
                        Circle::new((x, y), 5, style)
                    }))
                    .map_err(|e| failed(&e))?;
            }
            charts::legend(&mut chart, SeriesLabelPosition::UpperLeft).map_err(|e| failed(&e))?;
        }
        root.present().map_err(|e| failed(&e))?;
    }
    Ok(svg)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slugs_are_file_name_parts() {
        assert_eq!(slug("adaptive (bvh)"), "adaptive-bvh");
        assert_eq!(slug("adaptive, --accel bsp"), "adaptive-accel-bsp");
        assert_eq!(slug("wong-tsang93"), "wong-tsang93");
    }

    #[test]
    fn the_default_accelerator_is_not_run_twice() {
        for scene in &SCENES {
            let list = configurations(scene, false);
            let default = Settings::adaptive().accel.name();
            assert!(list[0].flags.is_empty());
            assert!(list[0].name.contains(default));
            assert!(!list.iter().any(|c| c.flags.iter().any(|f| f == default)));
            assert!(list.iter().any(|c| c.flags == ["--overshoot", "1"]));
            assert_eq!(
                list.iter().any(|c| c.name == "wong-tsang93"),
                !scene.spec.shared
            );
        }
    }
}
