//! Figures 4.2 and 4.6 of Wong & Tsang 1993 (section 4, "Analytical
//! Form-Factor Formula"), `radiosity experiment fig4-2`: the relative errors
//! of equation (1) (Wallace's point-to-disk factor) and equation (3) (the
//! paper's) against the exact factor of a disk, over the paper's 4,140
//! receiver positions and orientations at 1, 5 and 10 radii, first under
//! the paper's protocol beside its printed numbers, then under the other
//! plausible protocols. The study itself (the grid, the tilts, the error
//! statistics) is [`crate::form_factor_accuracy`].

use rayon::prelude::*;

use super::{Context, Error, Report, table};
use crate::form_factor_accuracy::{DiskStudy, ErrorStats, Tilt};
use radiosity::form_factor::FormFactor;

/// The distances of Figures 4.2 and 4.6, in disk radii.
pub const PAPER_DISTANCES: [f64; 3] = [1.0, 5.0, 10.0];

/// Figure 4.2: (average, maximum) relative error of equation (1), in %, at
/// [`PAPER_DISTANCES`].
pub const PAPER_EQ1: [(f64, f64); 3] = [(55.38, 99.97), (5.55, 11.38), (1.44, 2.96)];

/// Figure 4.6: (average, maximum) relative error of equation (3), in %, at
/// [`PAPER_DISTANCES`].
pub const PAPER_EQ3: [(f64, f64); 3] = [(32.71, 98.25), (1.13, 4.0), (0.28, 1.0)];

/// The paper's numbers as printed (their digits decide the agreement test).
const PAPER_EQ1_TEXT: [(&str, &str); 3] = [("55.38", "99.97"), ("5.55", "11.38"), ("1.44", "2.96")];
const PAPER_EQ3_TEXT: [(&str, &str); 3] = [("32.71", "98.25"), ("1.13", "4.0"), ("0.28", "1.0")];

/// `value` (a fraction) in % with as many decimals as `like` has.
fn percent_like(value: f64, like: &str) -> String {
    let decimals = like.split_once('.').map_or(0, |(_, d)| d.len());
    format!("{:.*}", decimals, 100.0 * value)
}

fn tilt_name(tilt: Tilt) -> &'static str {
    match tilt {
        Tilt::DiskAxis => "DiskAxis",
        Tilt::InPlane => "InPlane",
        Tilt::Sideways => "Sideways",
    }
}

fn formula_label(formula: FormFactor) -> &'static str {
    match formula {
        FormFactor::Wallace => "eq. (1)",
        FormFactor::Disk => "eq. (3)",
        FormFactor::Analytic => "eq. (2)",
    }
}

/// The tilts of the receiver's normal compared in Figure 4.2's second table.
const TILTS: [Tilt; 3] = [Tilt::DiskAxis, Tilt::InPlane, Tilt::Sideways];

/// The formulas of Figures 4.2 (eq. (1)) and 4.6 (eq. (3)).
const DISK_FORMULAS: [FormFactor; 2] = [FormFactor::Wallace, FormFactor::Disk];

/// What Figures 4.2 and 4.6 measure: the error statistics of every
/// (tilt, formula, distance) and the check of the exact factor.
#[derive(Clone, Debug)]
pub struct DiskErrors {
    /// `(tilt, formula, index into PAPER_DISTANCES)` of each entry of
    /// [`DiskErrors::stats`].
    pub cases: Vec<(Tilt, FormFactor, usize)>,
    /// The errors of each case.
    pub stats: Vec<ErrorStats>,
    /// Equation (2) on a 2048-gon against the exact factor, per distance
    /// (over `theta_j = 0` only in quick mode).
    pub checks: Vec<ErrorStats>,
    /// Whether the check ran on the reduced grid.
    pub quick: bool,
}

impl DiskErrors {
    /// Computes every case of the study; cheap (75,000 closed forms), so
    /// quick mode runs the paper's full grid too. The check of the exact
    /// factor, the contour formula on a 2048-gon of the disk's area, runs
    /// over `theta_j = 0` only in quick mode, the polygon being costly.
    #[must_use]
    pub fn compute(quick: bool) -> DiskErrors {
        let cases: Vec<(Tilt, FormFactor, usize)> = TILTS
            .iter()
            .flat_map(|&t| {
                DISK_FORMULAS
                    .iter()
                    .flat_map(move |&f| (0..3).map(move |i| (t, f, i)))
            })
            .collect();
        let stats = cases
            .par_iter()
            .map(|&(tilt, f, i)| {
                DiskStudy {
                    tilt,
                    ..DiskStudy::paper(PAPER_DISTANCES[i])
                }
                .errors(f)
            })
            .collect();
        let check_grid = |distance: f64| {
            if quick {
                DiskStudy {
                    max_theta_j: 0,
                    ..DiskStudy::paper(distance)
                }
            } else {
                DiskStudy::paper(distance)
            }
        };
        let checks = PAPER_DISTANCES
            .par_iter()
            .map(|&d| check_grid(d).errors(FormFactor::Analytic))
            .collect();
        DiskErrors {
            cases,
            stats,
            checks,
            quick,
        }
    }

    /// The errors of one case.
    ///
    /// # Panics
    ///
    /// If the case was not computed.
    #[must_use]
    pub fn get(&self, tilt: Tilt, formula: FormFactor, distance: usize) -> ErrorStats {
        let at = self
            .cases
            .iter()
            .position(|c| *c == (tilt, formula, distance))
            .expect("every case is computed");
        self.stats[at]
    }
}

/// Figures 4.2 and 4.6: the relative errors of equations (1) and (3)
/// against the exact disk factor
/// ([`radiosity::form_factor::closed_form::disk_exact`]) over the paper's
/// 4,140 receiver positions and orientations at 1, 5 and 10 radii, under
/// the paper's protocol ([`Tilt::DiskAxis`], root-mean-square "average")
/// beside the paper's numbers, then under the other plausible protocols.
pub fn fig4_2(context: &Context) -> Result<Report, Error> {
    Ok(fig4_2_report(&DiskErrors::compute(context.quick)))
}

/// The report of Figures 4.2 and 4.6: the protocol, the check of the exact
/// factor, the paper's table beside ours and every protocol's.
#[must_use]
pub fn fig4_2_report(errors: &DiskErrors) -> Report {
    let mut report = Report::default();
    report.setting("disk", "unit radius R = 1, centre at the origin, normal +z");
    report.setting(
        "grid",
        "theta_k = 0..89 x theta_j = 0..45 whole degrees (4,140 receivers) at r = 1R, 5R, 10R",
    );
    report.setting(
        "paper protocol",
        "Tilt::DiskAxis, average = root mean square",
    );
    report.setting(
        "exact",
        "closed_form::disk_exact (Lambert's contour integral in closed form)",
    );

    report.paragraph(
        "Protocol. The source is a disk of radius R = 1 centred at the origin \
         with normal +z. The receiver sits at distance r from the centre, at \
         angle theta_k from the disk's normal in the x-z plane, \
         x = r (sin theta_k, 0, cos theta_k); its normal is the disk's reversed \
         normal -z tilted by theta_j in that plane towards the disk's centre, \
         n = (-sin theta_j, 0, -cos theta_j) (`Tilt::DiskAxis`). theta_k runs \
         over 0..89 and theta_j over 0..45 whole degrees: 90 x 46 = 4,140 \
         receivers, the paper's \"4140 different orientations and positions\". \
         The relative error is |F - F_exact| / F_exact; the paper's \
         \"average\" is reproduced by the root mean square of it (the \
         arithmetic mean is shown in the second table), its maximum by the \
         maximum.",
    );
    report.paragraph(&format!(
        "\"Exact\" is `closed_form::disk_exact`, Lambert's contour integral \
         around the rim evaluated in closed form (the part of the disk behind \
         the receiver's tangent plane, if any, cut off along a chord). It was \
         checked here against equation (2), the contour formula, on a \
         2048-sided polygon of the disk's area{}: the largest relative \
         difference is {:.1e} at 1R, {:.1e} at 5R and {:.1e} at 10R over {} \
         receivers each.",
        if errors.quick {
            " (quick mode: theta_j = 0 only)"
        } else {
            ""
        },
        errors.checks[0].max,
        errors.checks[1].max,
        errors.checks[2].max,
        errors.checks[0].samples,
    ));

    // Table 1: ours under the paper's protocol beside the paper.
    let mut rows = Vec::new();
    let mut agree = 0;
    let mut total = 0;
    let mut deviation = 0.0_f64;
    let mut misses = Vec::new();
    for (i, &r) in PAPER_DISTANCES.iter().enumerate() {
        let e1 = errors.get(Tilt::DiskAxis, FormFactor::Wallace, i);
        let e3 = errors.get(Tilt::DiskAxis, FormFactor::Disk, i);
        let (p1, p3) = (PAPER_EQ1_TEXT[i], PAPER_EQ3_TEXT[i]);
        let ours = [
            (e1.rms, p1.0),
            (e1.max, p1.1),
            (e3.rms, p3.0),
            (e3.max, p3.1),
        ];
        let mut row = vec![format!("{r}R")];
        for (value, paper) in ours {
            let mine = percent_like(value, paper);
            total += 1;
            if mine == paper {
                agree += 1;
            } else {
                misses.push(format!("{:.4}% against {paper}%", 100.0 * value));
            }
            let published: f64 = paper.parse().unwrap_or(f64::NAN);
            deviation = deviation.max((100.0 * value - published).abs());
            row.push(format!("{:.3}%", 100.0 * value));
            row.push(format!("{paper}%"));
        }
        row.push(e1.samples.to_string());
        rows.push(row);
    }
    report.body.push_str(
        "Figures 4.2 and 4.6 under the paper's protocol (DiskAxis tilt, RMS as \
         \"average\"):\n\n",
    );
    report.body.push_str(&table(
        &[
            "r",
            "eq. (1) average, ours",
            "eq. (1) average, paper",
            "eq. (1) max, ours",
            "eq. (1) max, paper",
            "eq. (3) average, ours",
            "eq. (3) average, paper",
            "eq. (3) max, ours",
            "eq. (3) max, paper",
            "receivers",
        ],
        &rows,
    ));
    report.paragraph(&format!(
        "{agree} of the paper's {total} numbers are reproduced when ours are \
         rounded to the digits it prints{}; all {total} are within {deviation:.3} \
         percentage points.",
        if misses.is_empty() {
            String::new()
        } else {
            format!(" (not: {})", misses.join(", "))
        }
    ));

    // Table 2: every protocol.
    let mut rows = Vec::new();
    for tilt in TILTS {
        for formula in DISK_FORMULAS {
            for (i, &r) in PAPER_DISTANCES.iter().enumerate() {
                let e = errors.get(tilt, formula, i);
                let paper = if formula == FormFactor::Wallace {
                    PAPER_EQ1_TEXT[i]
                } else {
                    PAPER_EQ3_TEXT[i]
                };
                rows.push(vec![
                    tilt_name(tilt).to_string(),
                    formula_label(formula).to_string(),
                    format!("{r}R"),
                    format!("{:.2}%", 100.0 * e.mean),
                    format!("{:.2}%", 100.0 * e.rms),
                    format!("{:.2}%", 100.0 * e.max),
                    format!("{}% / {}%", paper.0, paper.1),
                    e.samples.to_string(),
                ]);
            }
        }
    }
    report.body.push_str(
        "Every plausible protocol, same grid. `DiskAxis`: the receiver's normal \
         is -z tilted by theta_j in the plane of incidence (the paper's). \
         `InPlane`: it points at the disk's centre, then turns by theta_j in \
         the plane of incidence away from the axis. `Sideways`: it points at \
         the centre, then turns by theta_j out of the plane of incidence. \
         Mean and RMS are the arithmetic and root-mean-square averages of the \
         relative error.\n\n",
    );
    report.body.push_str(&table(
        &[
            "tilt",
            "formula",
            "r",
            "mean",
            "RMS",
            "max",
            "paper (average / max)",
            "receivers",
        ],
        &rows,
    ));
    let spread = |formula: FormFactor, i: usize, pick: fn(&ErrorStats) -> f64| {
        let values: Vec<f64> = TILTS
            .iter()
            .flat_map(|&t| {
                let e = errors.get(t, formula, i);
                [e.mean, pick(&e)]
            })
            .collect();
        let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = values.iter().copied().fold(0.0, f64::max);
        (lo, hi)
    };
    let (lo1, hi1) = spread(FormFactor::Wallace, 1, |e| e.rms);
    let (lo3, hi3) = spread(FormFactor::Disk, 1, |e| e.rms);
    report.paragraph(&format!(
        "At 5R the \"average\" error of eq. (1) ranges from {:.2}% to {:.2}% and \
         that of eq. (3) from {:.2}% to {:.2}% depending on the protocol (tilt \
         and mean or RMS): the protocol matters as much as the formula, and \
         only DiskAxis with RMS matches the paper. Under `Sideways` eq. (3) is \
         exact wherever the whole disk is in front of the receiver (its \
         derivation neglects only the in-plane component).",
        100.0 * lo1,
        100.0 * hi1,
        100.0 * lo3,
        100.0 * hi3,
    ));
    report
}
