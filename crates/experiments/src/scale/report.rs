//! The scale experiment's report ([`super`]): its settings and tables
//! (sizes and phases, solves, where the solve's time goes, the early
//! pictures), in Markdown.

use std::fmt::Write as _;

use super::{Case, PLOT_FILE, QUICK_COARSENING, ScaleScene};
use crate::early::{EARLY_SECONDS, Early};
use crate::{Report, table};
use radiosity::solver::ADAPTIVE_CONVERGE;

/// The Markdown of the report: the settings, the tables (sizes and
/// phases, solves, where the solve's time goes, the early pictures), and
/// the link to the plot.
#[must_use]
pub fn markdown(quick: bool, scenes: &[ScaleScene], cases: &[Case]) -> Report {
    let mut report = Report::default();
    report.setting(
        "cases",
        "each a child `radiosity render SCENE --output STEM.png --vertices STEM.csv --stats \
         STEM.json --quiet --time-limit S --threads N [flags]`",
    );
    report.setting("threads", rayon::current_num_threads());
    let limits: Vec<String> = scenes
        .iter()
        .map(|s| format!("{} {} s", s.spec.name, s.effective_time_limit(quick)))
        .collect();
    report.setting("solve time limits", limits.join(", "));
    report.setting("converge", ADAPTIVE_CONVERGE);
    if quick {
        report.setting(
            "quick mode",
            format!("elements {QUICK_COARSENING} times the scene's suggested size"),
        );
    }
    let failed = |case: &Case, message: &str, columns: usize| {
        let mut row = vec![case.scene.to_string(), case.configuration.clone()];
        row.push(format!("failed: {}", message.replace('|', "/")));
        row.extend(std::iter::repeat_n("-".to_string(), columns - 3));
        row
    };
    let mut size_rows = Vec::new();
    let mut solve_rows = Vec::new();
    for case in cases {
        match &case.result {
            Ok(run) => {
                size_rows.push(vec![
                    case.scene.to_string(),
                    case.configuration.clone(),
                    run.faces.to_string(),
                    run.surfaces.to_string(),
                    run.elements.to_string(),
                    run.vertices.to_string(),
                    seconds(run.load_seconds),
                    seconds(run.mesh_seconds),
                    seconds(run.accel_build_seconds),
                    seconds(run.solve_seconds),
                    seconds(run.write_seconds),
                    seconds(run.total_seconds),
                    seconds(case.wall_seconds),
                ]);
                solve_rows.push(vec![
                    case.scene.to_string(),
                    case.configuration.clone(),
                    run.shots.to_string(),
                    format!("{:.3}%", 100.0 * run.unshot_fraction),
                    if run.converged() {
                        "converged".to_string()
                    } else {
                        format!("{} ({} s)", run.stop_reason, case.time_limit)
                    },
                    run.rays.to_string(),
                    format!("{:.0}", run.rays_per_second_per_thread()),
                    format!("{:.0}", run.tracing_rays_per_second()),
                    megabytes(run.peak_memory_bytes),
                    megabytes(Some(run.estimated_memory_bytes)),
                ]);
            }
            Err(message) => {
                size_rows.push(failed(case, message, 13));
                solve_rows.push(failed(case, message, 10));
            }
        }
    }
    report.paragraph(
        "Sizes and the time of each phase, seconds of wall time in the child: load (reading \
         the scene, merging coplanar faces), mesh, accel build (the shadow-ray accelerator), \
         solve (solver set-up and shots, after the build), write (drawing the 800 x 600 \
         picture, writing it and the vertices CSV), total (the whole job, process start and \
         the statistics file excepted), process (the child's wall time, start to exit). Faces: input polygons after loading (the shared \
         scenes' are triangles); surfaces: after merging adjacent coplanar faces.",
    );
    report.body.push_str(&table(
        &[
            "scene",
            "configuration",
            "faces",
            "surfaces",
            "elements",
            "vertices",
            "load s",
            "mesh s",
            "accel build s",
            "solve s",
            "write s",
            "total s",
            "process s",
        ],
        &size_rows,
    ));
    report.paragraph(&format!(
        "The solves: shots, the unshot power left over the emitted power, whether it fell \
         below {:.1}% (converged) or the time limit stopped the solve, shadow rays traced, rays \
         per second of solve per thread (throughput, form factors and book-keeping included) \
         and per second of tracing thread time (the accelerator's own rate), the child's peak \
         resident memory and its own estimate (MB).",
        100.0 * ADAPTIVE_CONVERGE
    ));
    report.body.push_str(&table(
        &[
            "scene",
            "configuration",
            "shots",
            "unshot",
            "stopped",
            "rays",
            "rays/s/thread",
            "tracing rays/s/thread",
            "peak MB",
            "estimated MB",
        ],
        &solve_rows,
    ));
    phase_table(&mut report, cases);
    device_paragraph(&mut report, cases);
    early_table(&mut report, cases);
    let _ = writeln!(
        report.body,
        "![solve time and peak memory against faces]({PLOT_FILE})\n"
    );
    report.paragraph(
        "Filled markers: converged; open markers: stopped at the time limit (the solve time \
         is then the limit, not the cost of converging).",
    );
    report
}

/// Where a solve's time goes: the gathering's thread time split into form
/// factors, shadow rays and the rest (refinement, or the paper's pre-test),
/// and the book-keeping.
fn phase_table(report: &mut Report, cases: &[Case]) {
    let share = |part: f64, whole: f64| format!("{:.0}%", 100.0 * part / whole.max(1e-12));
    let rows: Vec<Vec<String>> = cases
        .iter()
        .filter_map(|case| {
            let run = case.result.as_ref().ok()?;
            if run.device != "cpu" {
                return None;
            }
            let threads = run.threads.max(1) as f64;
            let gathering = run.gather_seconds * threads;
            Some(vec![
                case.scene.to_string(),
                case.configuration.clone(),
                seconds(run.solve_seconds),
                seconds(run.gather_seconds),
                share(run.form_factor_thread_seconds, gathering),
                share(run.ray_thread_seconds, gathering),
                share(run.refinement_thread_seconds, gathering),
                seconds(run.bookkeeping_seconds),
            ])
        })
        .collect();
    report.paragraph(
        "Where the solve's time goes: the gathering (wall seconds), and its thread time \
         (wall seconds times threads) in form factors, in shadow rays and in the rest \
         (refinement: walking the source and receiver trees; the pre-test for the paper's \
         preset), from the solver's own sampled clocks; then the book-keeping after the \
         shots (wall seconds).",
    );
    report.body.push_str(&table(
        &[
            "scene",
            "configuration",
            "solve s",
            "gathering s",
            "form factors",
            "shadow rays",
            "refinement",
            "book-keeping s",
        ],
        &rows,
    ));
}

/// The cases run on a GPU: the adapter and the shots it made.
fn device_paragraph(report: &mut Report, cases: &[Case]) {
    let lines: Vec<String> = cases
        .iter()
        .filter_map(|case| {
            let run = case.result.as_ref().ok()?;
            (run.device != "cpu").then(|| {
                format!(
                    "{} on {}: {} of {} shots on the GPU ({} of the coarse pass's); mesh {} \
                     (the coarse pass included), solve {} \
                     (of which the GPU's shots: upload {}, kernels {}, readback {}; \
                     book-keeping on the host {})",
                    case.scene,
                    run.device,
                    run.device_shots,
                    run.shots,
                    run.coarse_device_shots,
                    seconds(run.mesh_seconds),
                    seconds(run.solve_seconds),
                    seconds(run.device_seconds[0]),
                    seconds(run.device_seconds[1]),
                    seconds(run.device_seconds[2]),
                    seconds(run.bookkeeping_seconds),
                )
            })
        })
        .collect();
    if !lines.is_empty() {
        report.paragraph(&format!(
            "On the GPU: {}. Its shots' thread times are not sampled (the shares above are the \
             CPU's only).",
            lines.join("; ")
        ));
    }
}

/// The early pictures of each scene's default configuration.
fn early_table(report: &mut Report, cases: &[Case]) {
    let rows: Vec<Vec<String>> = cases
        .iter()
        .filter(|c| !c.early.is_empty())
        .filter_map(|case| {
            let run = case.result.as_ref().ok()?;
            let mut row = vec![
                case.scene.to_string(),
                if run.converged() {
                    format!("converged, {} s", seconds(run.solve_seconds))
                } else {
                    format!("not converged: the state after {} s", case.time_limit)
                },
            ];
            for seconds in EARLY_SECONDS {
                row.push(match case.early.iter().find(|e| e.seconds == seconds) {
                    Some(
                        early @ Early {
                            result: Ok((l1, unshot)),
                            ..
                        },
                    ) => format!(
                        "{:.2}% ({:.0}% unshot{})",
                        100.0 * l1,
                        100.0 * unshot,
                        if early.coarse_pass_cut() {
                            "; coarse pass cut by the limit"
                        } else {
                            ""
                        }
                    ),
                    Some(
                        early @ Early {
                            result: Err(message),
                            ..
                        },
                    ) if early.coarse_pass_cut() => format!(
                        "another mesh (coarse pass cut by the limit): {}",
                        message.replace('|', "/")
                    ),
                    Some(Early {
                        result: Err(message),
                        ..
                    }) => format!("failed: {}", message.replace('|', "/")),
                    None => "-".into(),
                });
            }
            Some(row)
        })
        .collect();
    report.paragraph(
        "The picture early: each scene's default job again with `--time-limit` 2, 5 and 10 s, \
         its vertex radiosity's L1 error against the final state (the full run's: converged, \
         or where its time limit stopped it), and the unshot power it had left. A limit at or \
         above the scene's own is not run (-). Refinement's coarse pass has a quarter of the \
         limit: where that cut it short, the mesh is refined from less light (said so), or is \
         another mesh altogether.",
    );
    report.body.push_str(&table(
        &[
            "scene",
            "final state",
            "after 2 s",
            "after 5 s",
            "after 10 s",
        ],
        &rows,
    ));
}

pub(super) fn seconds(s: f64) -> String {
    if s < 0.01 {
        format!("{s:.4}")
    } else if s < 10.0 {
        format!("{s:.2}")
    } else {
        format!("{s:.1}")
    }
}

fn megabytes(bytes: Option<u64>) -> String {
    bytes.map_or("-".into(), |b| format!("{:.0}", b as f64 / 1e6))
}
