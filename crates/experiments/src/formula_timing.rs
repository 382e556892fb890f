//! The timing of section 4 of Wong & Tsang 1993 ("Analytical Form-Factor
//! Formula"), `radiosity experiment formula-timing`: the cost of the
//! paper's 4,140 form-factor evaluations with each formula, equation (1)
//! and equation (3) on a disk and equation (2) on a square of the same
//! area, on one thread (the paper: 0.9 s for equation (2) against 0.1 s
//! for equation (1) on an SGI IRIS Indigo).

use std::hint::black_box;
use std::time::Instant;

use glam::DVec3;

use super::{Context, Error, Report, table};
use crate::form_factor_accuracy::DiskStudy;
use radiosity::form_factor::{Source, analytic, closed_form, disk, wallace};

/// Seconds for `passes` passes over `cases`, and the sum of the factors.
/// Inputs and the sum go through `black_box` so nothing is optimised away.
/// Generic, so the formula is inlined as in a solver's inner loop (no
/// dynamic call per evaluation).
fn run_passes<F: Fn(DVec3, DVec3) -> f64>(
    cases: &[(DVec3, DVec3)],
    evaluate: F,
    passes: usize,
) -> (f64, f64) {
    let start = Instant::now();
    let mut sum = 0.0;
    for _ in 0..passes {
        for &(x, n) in cases {
            sum += evaluate(black_box(x), black_box(n));
        }
    }
    (start.elapsed().as_secs_f64(), black_box(sum))
}

/// Times every runner (a function of the number of passes): calibrates the
/// passes per repetition so that one lasts at least `target` seconds, then
/// runs `repetitions` rounds, each timing every runner once in turn (so a
/// change of load on a shared machine hits all of them alike). Returns, per
/// runner, (median seconds per pass, passes per repetition, checksum).
fn measure(
    runners: &[&dyn Fn(usize) -> (f64, f64)],
    target: f64,
    repetitions: usize,
) -> Vec<(f64, usize, f64)> {
    let passes: Vec<usize> = runners
        .iter()
        .map(|run| {
            let (one, _) = run(1);
            ((target / one.max(1e-9)).ceil() as usize).max(1)
        })
        .collect();
    let mut times = vec![Vec::with_capacity(repetitions); runners.len()];
    let mut checksums = vec![0.0; runners.len()];
    for _ in 0..repetitions.max(1) {
        for (i, run) in runners.iter().enumerate() {
            let (seconds, sum) = run(passes[i]);
            checksums[i] = sum;
            times[i].push(seconds / passes[i] as f64);
        }
    }
    times
        .iter_mut()
        .zip(passes.iter().zip(&checksums))
        .map(|(t, (&p, &c))| (super::median(t), p, c))
        .collect()
}

/// The rows of the formula timing: formula, source, the paper's time.
const FORMULA_TIMING_ROWS: [(&str, &str, &str); 5] = [
    ("eq. (1) Wallace", "disk, R = 1", "0.1 s (1x)"),
    (
        "eq. (3) Wong-Tsang",
        "disk, R = 1",
        "\"as fast as Wallace's\"",
    ),
    (
        "eq. (2) analytic (Baum)",
        "square, side sqrt(pi)",
        "0.9 s (9x)",
    ),
    ("exact disk (closed_form::disk_exact)", "disk, R = 1", "-"),
    ("loop only (no formula)", "-", "-"),
];

/// The cost of one formula over all the cases.
#[derive(Clone, Copy, Debug)]
pub struct FormulaCost {
    /// Median seconds for one pass over the cases.
    pub seconds: f64,
    /// Passes per repetition.
    pub passes: usize,
    /// Sum of the factors of the last repetition.
    pub checksum: f64,
}

/// What the formula timing measures.
#[derive(Clone, Debug)]
pub struct FormulaTiming {
    /// Distance of the receivers, in disk radii.
    pub distance: f64,
    /// Receivers (the paper's 4,140).
    pub cases: usize,
    /// Receivers for which part of the square is behind the tangent plane.
    pub clipped: usize,
    /// Minimum seconds of one repetition.
    pub target: f64,
    /// Repetitions (the median is kept).
    pub repetitions: usize,
    /// The 1, 5 and 15 minute load averages at the end, if known.
    pub load: Option<String>,
    /// One cost per row of `FORMULA_TIMING_ROWS`: eq. (1), eq. (3),
    /// eq. (2), the exact disk, the loop alone.
    pub costs: Vec<FormulaCost>,
}

/// Times the paper's 4,140 receiver positions and orientations (the
/// [`DiskStudy::paper`] grid at 5 radii) evaluated with equation (1) and
/// equation (3) on a disk and with equation (2) on a square of the same
/// area, on one thread: the median over `repetitions` of the time per
/// evaluation, each repetition looping over the 4,140 cases for at least
/// 20 ms (2 ms when `quick`).
#[must_use]
pub fn formula_timing_compute(quick: bool, repetitions: usize) -> FormulaTiming {
    let distance = 5.0;
    let study = DiskStudy::paper(distance);
    let cases: Vec<(DVec3, DVec3)> = (0..=study.max_theta_k)
        .flat_map(|k| (0..=study.max_theta_j).map(move |j| (k, j)))
        .map(|(k, j)| study.receiver(f64::from(k), f64::from(j)))
        .collect();

    // The unit disk for eq. (1) and (3); a square of the same area (side
    // sqrt(pi)), centred on the disk, for eq. (2).
    let half = std::f64::consts::PI.sqrt() / 2.0;
    let square = [
        DVec3::new(-half, -half, 0.0),
        DVec3::new(half, -half, 0.0),
        DVec3::new(half, half, 0.0),
        DVec3::new(-half, half, 0.0),
    ];
    let disk_source = Source {
        polygon: &[],
        centroid: DVec3::ZERO,
        normal: DVec3::Z,
        area: std::f64::consts::PI,
    };
    // Receivers for which part of the square is behind the tangent plane
    // (eq. (2) then clips the polygon first).
    let clipped = cases
        .iter()
        .filter(|(x, nn)| square.iter().any(|p| nn.dot(*p - *x) < 0.0))
        .count();

    let target = if quick { 0.002 } else { 0.02 };
    let costs = measure(
        &[
            &|p| run_passes(&cases, |x, nn| wallace(x, nn, black_box(&disk_source)), p),
            &|p| run_passes(&cases, |x, nn| disk(x, nn, black_box(&disk_source)), p),
            &|p| run_passes(&cases, |x, nn| analytic(x, nn, black_box(&square)), p),
            &|p| {
                run_passes(
                    &cases,
                    |x, nn| closed_form::disk_exact(x, nn, DVec3::ZERO, black_box(DVec3::Z), 1.0),
                    p,
                )
            },
            &|p| run_passes(&cases, |x, nn| x.z + nn.z, p),
        ],
        target,
        repetitions,
    )
    .into_iter()
    .map(|(seconds, passes, checksum)| FormulaCost {
        seconds,
        passes,
        checksum,
    })
    .collect();
    let load = std::fs::read_to_string("/proc/loadavg").ok().map(|load| {
        load.split_whitespace()
            .take(3)
            .collect::<Vec<_>>()
            .join(", ")
    });
    FormulaTiming {
        distance,
        cases: cases.len(),
        clipped,
        target,
        repetitions,
        load,
        costs,
    }
}

/// Section 4's timing: the paper's 4,140 receiver positions and
/// orientations (the [`DiskStudy::paper`] grid at 5 radii) evaluated with
/// equation (1) and equation (3) on a disk and with equation (2) on a square
/// of the same area, on one thread. Reports the median over
/// [`Context::repetitions`] of the time per evaluation, each repetition
/// looping over the 4,140 cases for at least 20 ms.
pub fn formula_timing(context: &Context) -> Result<Report, Error> {
    Ok(formula_timing_report(&formula_timing_compute(
        context.quick,
        context.repetitions(),
    )))
}

/// The report of the formula timing: the paper's protocol and ours, the
/// table of costs and the ratios that matter.
#[must_use]
pub fn formula_timing_report(data: &FormulaTiming) -> Report {
    let mut report = Report::default();
    let FormulaTiming {
        distance,
        cases: n,
        clipped,
        target,
        repetitions,
        ..
    } = *data;
    let results: Vec<f64> = data.costs.iter().map(|c| c.seconds).collect();
    report.setting(
        "cases",
        format!("{n} (DiskStudy::paper grid at r = {distance}R)"),
    );
    report.setting("threads", "1 (the calling thread)");
    if let Some(load) = &data.load {
        report.setting("load average at the end (1, 5, 15 min)", load);
    }
    report.setting("repetitions", repetitions);
    report.setting(
        "per repetition",
        format!("loops over the {n} cases for >= {} ms", target * 1e3),
    );
    report.paragraph(&format!(
        "The paper times \"the form-factors from a square source patch to a \
         differential area in 4140 different orientations and positions\": \
         0.9 s with Baum's formula (eq. 2) and 0.1 s \"when the source was \
         assumed to be a circular disk and Wallace's formula was used\" \
         (eq. 1), on an SGI IRIS Indigo. The 4,140 cases here are the receivers \
         of the error study (theta_k 0..89 x theta_j 0..45, `Tilt::DiskAxis`) \
         at r = {distance}R. Eq. (1) and eq. (3) see the unit disk (only its \
         centre, normal and area enter them); eq. (2) sees a square of the \
         same area, side sqrt(pi), centred on the disk, as in the paper; \
         for {clipped} of the {n} receivers part of the square is behind the \
         receiver's tangent plane and eq. (2) clips it first. Times \
         are the median of {repetitions} repetition(s) on one thread, the \
         formulas taking turns within each repetition, inputs and results \
         passed through `std::hint::black_box`."
    ));

    let base = results[0];
    let mut rows = Vec::new();
    for ((label, source, paper), cost) in FORMULA_TIMING_ROWS.iter().zip(&data.costs) {
        let FormulaCost {
            seconds, passes, ..
        } = cost;
        rows.push(vec![
            (*label).to_string(),
            (*source).to_string(),
            format!("{:.1}", seconds / n as f64 * 1e9),
            format!("{:.3}", seconds * 1e3),
            format!("{:.2}x", seconds / base),
            passes.to_string(),
            (*paper).to_string(),
        ]);
    }
    report.body.push_str(&table(
        &[
            "formula",
            "source",
            "ns per evaluation",
            "ms for 4,140",
            "ratio to eq. (1)",
            "passes per repetition",
            "paper (4,140 evaluations)",
        ],
        &rows,
    ));
    let ratio = results[2] / base;
    report.paragraph(&format!(
        "Eq. (2) costs {ratio:.1} times eq. (1) here, against 9 times in the \
         paper (0.9 s / 0.1 s). The 4,140 evaluations take {:.2} ms with eq. (2) \
         against the paper's 900 ms: about {:.0} times faster hardware and \
         compiler. Eq. (3) costs {:.1} times eq. (1). The loop alone (two \
         loads through `black_box` and an add) takes {:.1} ns per case and is \
         included in every row; without it the ratio of eq. (2) to eq. (1) is \
         {:.1}. On a shared machine (see the load average) the absolute times \
         vary by tens of percent from run to run; the ratios less.",
        results[2] * 1e3,
        0.9 / results[2],
        results[1] / base,
        results[4] / n as f64 * 1e9,
        (results[2] - results[4]) / (base - results[4]),
    ));
    let checks: Vec<String> = data.costs[..4]
        .iter()
        .map(|c| format!("{:.6e}", c.checksum))
        .collect();
    report.setting(
        "checksums (sum of factors per repetition)",
        checks.join(", "),
    );
    report
}
