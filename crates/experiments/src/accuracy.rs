//! `radiosity experiment accuracy-curve`, beyond the paper (its Figure 5.2
//! times the methods, [`super::validate`] scores them; this puts the two
//! together): accuracy against the Radiance reference, against time, on the
//! built-in Cornell box and the measured one, for the paper's preset
//! (`wong-tsang93`, the old default) at its default patch size and finer ones,
//! the default (`adaptive`) at several tolerances and convergence thresholds,
//! and Radiance's `rtrace -I` itself with and without its irradiance cache.
//!
//! Every method is scored at the same points: the 600 vertices `score.py`
//! samples from the default preset's mesh (so the reference computed for
//! `validate` serves here too). Our solves gather there as sensors
//! ([`radiosity::sensors`]); Radiance evaluates there after the harness's own
//! point offsets. Each result is written as a vertices CSV of those points
//! and scored by the harness's `score.py` ([`super::reference`]).
//!
//! What is timed: for ours, the solve (solver construction and shots, not
//! loading and meshing; the median of three runs when a run takes under
//! two seconds); for Radiance, the wall time of the `rtrace` call (not the
//! scene's conversion and `oconv`). Both on two threads: a rayon pool of
//! two, `rtrace -n 2`.

use std::fmt::Write as _;

use glam::DVec3;
use plotters::prelude::*;

use super::charts;
use super::reference::{self, Harness, Scored};
use super::validate::{self, SceneCase, seconds, solve, write_rows};
use super::{Context, Error, Report, median, table, write_file};
use radiosity::sensors::SensorPoint;
use radiosity::solver::adaptive::AdaptiveSettings;
use radiosity::solver::{MethodSettings, Settings};

/// The scenes of the curve.
pub const SCENES: [SceneCase; 2] = [
    SceneCase {
        name: "cornell",
        source: "cornell",
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
];

/// Threads (ours) and processes (rtrace) of every run.
pub const THREADS: usize = 2;

/// One of our configurations.
#[derive(Clone, Debug)]
struct Ours {
    series: &'static str,
    setting: String,
    settings: Settings,
    patch_size: Option<f64>,
}

/// Our configurations: the paper's preset at its default patch size and
/// finer ones, the default preset at several tolerances and two
/// convergence thresholds.
fn ours(quick: bool) -> Vec<Ours> {
    let mut list = Vec::new();
    let patch_sizes: &[Option<f64>] = if quick {
        &[None]
    } else {
        &[None, Some(0.2), Some(0.1), Some(0.05)]
    };
    for &patch_size in patch_sizes {
        list.push(Ours {
            series: "wong-tsang93 (patch size)",
            setting: patch_size
                .map_or_else(|| "default patches".into(), |p| format!("--patch-size {p}")),
            settings: Settings::wong_tsang93(),
            patch_size,
        });
    }
    let tolerances: &[f64] = if quick {
        &[1e-2]
    } else {
        &[1e-2, 3e-3, 1e-3, 3e-4]
    };
    for (series, converge) in [
        ("adaptive, --converge 1e-2 (tolerance)", 1e-2),
        ("adaptive, --converge 1e-3 (tolerance)", 1e-3),
    ] {
        for &tolerance in tolerances {
            list.push(Ours {
                series,
                setting: format!("--tolerance {tolerance:e} --converge {converge:e}"),
                settings: Settings {
                    method: MethodSettings::Adaptive(AdaptiveSettings {
                        tolerance,
                        ..AdaptiveSettings::default()
                    }),
                    converge,
                    ..Settings::adaptive()
                },
                patch_size: None,
            });
        }
    }
    list
}

/// Radiance's runs: (series, name, rtrace options after `-I`).
fn radiance_runs(quick: bool) -> Vec<(&'static str, String, String)> {
    let mut runs = vec![(
        "rtrace -ab 8 -aa 0 (no cache)",
        "-ab 8 -aa 0 -ad 1024".to_string(),
        "-ab 8 -aa 0 -ad 1024".to_string(),
    )];
    let divisions: &[u32] = if quick { &[64] } else { &[256, 1024, 4096] };
    for &ad in divisions {
        // As the harness's ambient method: Russian roulette rather than a
        // depth cut-off, -lw small enough never to reduce the divisions,
        // no ambient super-sampling (documented as biased).
        runs.push((
            "rtrace -ab 64 -aa 0 (-ad)",
            format!("-ab 64 -aa 0 -ad {ad}"),
            format!(
                "-ab 64 -aa 0 -ad {ad} -as 0 -lr 0 -lw {:e}",
                0.05 / f64::from(ad)
            ),
        ));
    }
    if !quick {
        runs.push((
            "rtrace, irradiance cache",
            "-ab 5 -aa 0.1 -ar 256 -ad 1024 -as 512".to_string(),
            "-ab 5 -aa 0.1 -ar 256 -ad 1024 -as 512".to_string(),
        ));
        // A finer cached run (-ab 8 -aa 0.05 -ar 512 -ad 4096 -as 2048)
        // was tried and dropped: on the Cornell box's 600 points it had not
        // finished after 25 minutes on two cores.
    }
    runs
}

/// One point of the curve.
#[derive(Clone, Debug)]
pub struct Measured {
    /// The series (line) it belongs to.
    pub series: &'static str,
    /// Its setting within the series.
    pub setting: String,
    /// Seconds timed (see the module's documentation).
    pub seconds: f64,
    /// Its score against the reference.
    pub score: reference::Score,
}

/// One scene of the curve.
#[derive(Clone, Debug)]
pub struct AccuracyScene {
    /// The scene's name in [`SCENES`].
    pub name: &'static str,
    /// Points scored (score.py's sample).
    pub points: usize,
    /// Vertices of the default preset's mesh they are sampled from.
    pub vertices: usize,
    /// The default preset's score at those vertices.
    pub vertex_l1: f64,
    /// The reference's own noise floor (score.py's estimate).
    pub noise: f64,
    /// Every method's point: ours, then Radiance's.
    pub measured: Vec<Measured>,
}

/// What the accuracy curve measures.
#[derive(Clone, Debug)]
pub struct AccuracyCurve {
    /// The reference harness's folder.
    pub harness: std::path::PathBuf,
    /// The reference's `--accuracy`.
    pub accuracy: &'static str,
    /// One entry per scene.
    pub scenes: Vec<AccuracyScene>,
}

/// `radiosity experiment accuracy-curve`.
pub fn accuracy_curve(context: &Context) -> Result<Report, Error> {
    let harness = Harness::find(context)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(THREADS)
        .build()
        .map_err(|e| Error::Experiment(format!("cannot start worker threads: {e}")))?;
    let data = pool.install(|| accuracy_compute(context, &harness))?;
    let mut report = accuracy_report(&data);
    for (file, svg) in accuracy_plot(&data)? {
        let path = context.path(&file);
        write_file(&path, svg.as_bytes())?;
        report.files.push(path);
    }
    Ok(report)
}

/// The plot's file of a scene.
fn plot_file(scene: &str) -> String {
    format!("accuracy-{scene}.svg")
}

/// Solves, runs Radiance and scores every method on each scene (the
/// intermediate CSVs and score.py's JSONs are written into the output
/// folder), on the calling thread pool.
///
/// # Errors
///
/// If a scene is missing, a solve, Radiance or score.py fails, or a score
/// disagrees with score.py's.
pub fn accuracy_compute(context: &Context, harness: &Harness) -> Result<AccuracyCurve, Error> {
    let accuracy = if context.quick { "medium" } else { "high" };
    let mut scenes = Vec::new();
    let cases: &[SceneCase] = if context.quick { &SCENES[..1] } else { &SCENES };
    for case in cases {
        let path = validate::scene_file(context, case)?;
        // The points: score.py's sample of the default preset's vertices.
        let base = solve(&path, &Settings::adaptive(), None, &[])?;
        let stem = format!("accuracy-{}", case.name);
        let base_csv = context.path(&format!("{stem}-vertices.csv"));
        validate::write_vertices(&base_csv, &base)?;
        let sampled = harness.score_lit(
            &path,
            &base_csv,
            accuracy,
            &context.path(&format!("{stem}-vertices.json")),
        )?;
        let points: Vec<SensorPoint> = sampled
            .rows
            .iter()
            .enumerate()
            .map(|(i, &r)| SensorPoint {
                position: base.mesh.vertices[r].position,
                normal: base.mesh.vertices[r].normal,
                line: i + 1,
            })
            .collect();
        let vertex_score = reference::score(
            &sampled
                .rows
                .iter()
                .map(|&r| base.radiosity[r])
                .collect::<Vec<_>>(),
            &sampled.reference,
        );
        vertex_score.check_against(&sampled, case.name)?;
        // Each point is scored as the vertex it was sampled from: on that
        // vertex's own surface (a vertex on the edge between a light and the
        // ceiling is the light's, as in the vertices CSV, wherever the
        // sensor was placed), with B = Ke + Kd E of it.
        let own: Vec<&radiosity::scene::Surface> = sampled
            .rows
            .iter()
            .map(|&r| &base.scene.surfaces[base.mesh.vertices[r].surface as usize])
            .collect();
        let faces: Vec<u32> = own.iter().map(|s| s.face).collect();
        let mut measured = Vec::new();
        for (k, config) in ours(context.quick).iter().enumerate() {
            let mut times = Vec::new();
            let solved = solve(&path, &config.settings, config.patch_size, &points)?;
            times.push(solved.solve_seconds);
            if solved.solve_seconds < 2.0 {
                for _ in 0..2 {
                    times.push(
                        solve(&path, &config.settings, config.patch_size, &points)?.solve_seconds,
                    );
                }
            }
            let rows: Vec<(DVec3, DVec3, u32, DVec3)> = points
                .iter()
                .zip(&own)
                .zip(&solved.sensor_irradiance)
                .map(|((p, s), e)| (p.position, p.normal, s.face, s.emission + s.rho * *e))
                .collect();
            let score = score_rows(
                context,
                harness,
                &path,
                &sampled,
                &format!("{stem}-ours-{k}"),
                &rows,
                accuracy,
            )?;
            eprintln!(
                "  {} {}: L1 {:.2}% in {:.2} s",
                case.name,
                config.setting,
                100.0 * score.l1,
                median(&mut times.clone())
            );
            measured.push(Measured {
                series: config.series,
                setting: config.setting.clone(),
                seconds: median(&mut times),
                score,
            });
        }
        let located: Vec<(DVec3, DVec3, u32)> = points
            .iter()
            .zip(&faces)
            .map(|(p, f)| (p.position, p.normal, *f))
            .collect();
        let runs = radiance_runs(context.quick);
        let specs: Vec<(String, String)> = runs
            .iter()
            .map(|(_, name, options)| (name.clone(), options.clone()))
            .collect();
        let results = harness.radiance(
            &path,
            &located,
            &specs,
            THREADS,
            &context.path(&format!("{stem}-radiance")),
        )?;
        for (k, (run, (series, _, _))) in results.iter().zip(&runs).enumerate() {
            let rows: Vec<(DVec3, DVec3, u32, DVec3)> = located
                .iter()
                .zip(&run.radiosity)
                .map(|((p, n, f), b)| (*p, *n, *f, *b))
                .collect();
            let score = score_rows(
                context,
                harness,
                &path,
                &sampled,
                &format!("{stem}-radiance-{k}"),
                &rows,
                accuracy,
            )?;
            measured.push(Measured {
                series,
                setting: format!("`{}`", run.options),
                seconds: run.seconds,
                score,
            });
        }

        scenes.push(AccuracyScene {
            name: case.name,
            points: sampled.points,
            vertices: base.mesh.vertices.len(),
            vertex_l1: vertex_score.l1,
            noise: sampled.noise,
            measured,
        });
    }
    Ok(AccuracyCurve {
        harness: harness.dir.clone(),
        accuracy,
        scenes,
    })
}

/// The curves as SVG, one per scene: (file name, SVG).
///
/// # Errors
///
/// If plotters fails to draw.
pub fn accuracy_plot(data: &AccuracyCurve) -> Result<Vec<(String, String)>, Error> {
    data.scenes
        .iter()
        .map(|scene| {
            let title = format!("{}: L1 against time", scene.name);
            Ok((plot_file(scene.name), plot_curve(&title, &scene.measured)?))
        })
        .collect()
}

/// The report of the accuracy curve: per scene, the table of every method's
/// scores and time and its plot; then how Radiance was run.
#[must_use]
pub fn accuracy_report(data: &AccuracyCurve) -> Report {
    let mut report = Report::default();
    report.setting("reference harness", data.harness.display());
    report.setting(
        "reference",
        format!(
            "reference.py --accuracy {} at the points below",
            data.accuracy
        ),
    );
    report.setting(
        "timed",
        "ours: the solve (solver construction and shots; median of 3 when under 2 s); \
         Radiance: the rtrace call's wall time; both on 2 threads (a pool of 2, rtrace -n 2)",
    );
    for scene in &data.scenes {
        let _ = writeln!(report.body, "## {}\n", scene.name);
        report.paragraph(&format!(
            "{} points: score.py's sample of the default preset's {} vertices. The default \
             preset scored at those vertices (as `validate` does): L1 {:.2}%; as sensors at the \
             same points: the `adaptive, --converge 1e-2` row at tolerance 1e-3. The reference's \
             own noise floor (score.py's estimate): about {:.2}%.",
            scene.points,
            scene.vertices,
            100.0 * scene.vertex_l1,
            100.0 * scene.noise
        ));
        let rows: Vec<Vec<String>> = scene
            .measured
            .iter()
            .map(|m| {
                vec![
                    m.series.to_string(),
                    m.setting.clone(),
                    format!("{:.2}%", 100.0 * m.score.l1),
                    format!("{:+.2}%", 100.0 * m.score.bias),
                    format!("{:.2}%", 100.0 * m.score.median),
                    format!("{:.2}%", 100.0 * m.score.p90),
                    seconds(m.seconds),
                ]
            })
            .collect();
        report.body.push_str(&table(
            &[
                "method", "setting", "L1", "bias", "median", "p90", "seconds",
            ],
            &rows,
        ));
        let _ = writeln!(
            report.body,
            "![{} accuracy against time]({})\n",
            scene.name,
            plot_file(scene.name)
        );
    }
    report.paragraph(
        "Radiance: rtrace 6.0a from the pyradiance wheel on the scene as the harness's obj2rad.py \
         converts it, emitters as `light` (Radiance cannot make a source that also reflects: \
         the Cornell lights' reflectance 0.78 is dropped, about -1% of E in the box according \
         to the harness's README), at the harness's offset points, `-I -n 2`, other options at \
         rtrace's defaults. L1 = sum |B - Bref| / sum Bref; bias, median and p90 as score.py \
         computes them (each checked against its output).",
    );
    report
}

/// Writes `rows` as a vertices CSV, scores it with `score.py` (it must
/// reuse `sampled`'s reference: the same points) and returns the score.
fn score_rows(
    context: &Context,
    harness: &Harness,
    scene: &std::path::Path,
    sampled: &Scored,
    stem: &str,
    rows: &[(DVec3, DVec3, u32, DVec3)],
    accuracy: &str,
) -> Result<reference::Score, Error> {
    let csv = context.path(&format!("{stem}.csv"));
    write_rows(&csv, rows)?;
    let scored = harness.score_lit(
        scene,
        &csv,
        accuracy,
        &context.path(&format!("{stem}.json")),
    )?;
    if scored.rows.len() != rows.len() || scored.reference != sampled.reference {
        return Err(Error::Experiment(format!(
            "{}: score.py did not score the sampled points against their reference",
            csv.display()
        )));
    }
    let b: Vec<DVec3> = rows.iter().map(|r| r.3).collect();
    let score = reference::score(&b, &scored.reference);
    score.check_against(&scored, stem)?;
    Ok(score)
}

/// Colours of the series, in order of appearance.
const PALETTE: [RGBColor; 6] = [
    RGBColor(0x1f, 0x77, 0xb4),
    RGBColor(0xd6, 0x27, 0x28),
    RGBColor(0xff, 0x7f, 0x0e),
    RGBColor(0x2c, 0xa0, 0x2c),
    RGBColor(0x94, 0x67, 0xbd),
    RGBColor(0x8c, 0x56, 0x4b),
];

/// The curve as SVG: L1 (%) against seconds, both logarithmic, one line
/// per series.
fn plot_curve(title: &str, measured: &[Measured]) -> Result<String, Error> {
    let mut series: Vec<&'static str> = Vec::new();
    for m in measured {
        if !series.contains(&m.series) {
            series.push(m.series);
        }
    }
    let xs = measured.iter().map(|m| m.seconds.max(1e-3));
    let ys = measured.iter().map(|m| (100.0 * m.score.l1).max(1e-3));
    let (x_lo, x_hi) = xs.fold((f64::INFINITY, 0.0f64), |(lo, hi), x| {
        (lo.min(x), hi.max(x))
    });
    let (y_lo, y_hi) = ys.fold((f64::INFINITY, 0.0f64), |(lo, hi), y| {
        (lo.min(y), hi.max(y))
    });
    let x_range = (x_lo / 1.5)..(x_hi * 1.5);
    let y_range = (y_lo / 1.3)..(y_hi * 1.3);
    let mut svg = String::new();
    let failed = |e: &dyn std::fmt::Display| Error::Experiment(format!("plot {title}: {e}"));
    {
        let root = SVGBackend::with_string(&mut svg, (860, 560)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| failed(&e))?;
        let mut chart = charts::log_log(
            &root,
            title,
            22,
            (
                x_range,
                "seconds on 2 threads (ours: solve; Radiance: rtrace)",
            ),
            (y_range, "L1 against the reference (%)"),
        )
        .map_err(|e| failed(&e))?;
        for (i, name) in series.iter().enumerate() {
            let colour = PALETTE[i % PALETTE.len()];
            let mut points: Vec<(f64, f64)> = measured
                .iter()
                .filter(|m| m.series == *name)
                .map(|m| (m.seconds.max(1e-3), (100.0 * m.score.l1).max(1e-3)))
                .collect();
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            charts::line(&mut chart, name, colour, points.clone()).map_err(|e| failed(&e))?;
            chart
                .draw_series(points.iter().map(|&p| Circle::new(p, 4, colour.filled())))
                .map_err(|e| failed(&e))?;
        }
        charts::legend(&mut chart, SeriesLabelPosition::UpperRight).map_err(|e| failed(&e))?;
        root.present().map_err(|e| failed(&e))?;
    }
    Ok(svg)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_curve_plots_every_series_on_log_axes() {
        let score = |l1: f64| reference::Score {
            l1,
            bias: 0.0,
            median: 0.0,
            p90: 0.0,
            points: 1,
            relative: vec![],
        };
        let measured = vec![
            Measured {
                series: "a",
                setting: "1".into(),
                seconds: 0.5,
                score: score(0.02),
            },
            Measured {
                series: "a",
                setting: "2".into(),
                seconds: 5.0,
                score: score(0.005),
            },
            Measured {
                series: "b",
                setting: "1".into(),
                seconds: 50.0,
                score: score(0.01),
            },
        ];
        let svg = plot_curve("test", &measured).unwrap();
        assert!(svg.starts_with("<svg"));
        // plotters writes each text on its own line inside its element.
        let texts: Vec<&str> = svg
            .split("<text")
            .skip(1)
            .filter_map(|t| t.split('>').nth(1))
            .map(|t| t.split('<').next().unwrap_or("").trim())
            .collect();
        assert!(texts.contains(&"a") && texts.contains(&"b"), "legend");
        assert!(svg.contains("L1 against the reference"));
        assert_eq!(svg.matches("<circle").count(), 3);
    }
}
