//! The form-factor experiments of the paper's section 4 (Wong & Tsang 1993,
//! "Analytical Form-Factor Formula"):
//!
//! * [`fig4_2`]: the error tables of Figures 4.2 and 4.6, the relative
//!   errors of equations (1) and (3) against the exact factor of a disk, at
//!   1, 5 and 10 radii, under the paper's protocol and the other plausible
//!   ones;
//! * [`fig4_3`]: the colour-scale pictures of Figures 4.3 and 4.5, the
//!   factor from a unit square to a receiver on a cross-section of space
//!   above it, exact, with equation (1) and (3) on 3x3 disks, and with
//!   equation (2) on 3x3 squares, and their relative errors;
//! * [`formula_timing`]: the cost of the paper's 4,140 evaluations with
//!   each formula (the paper: 0.9 s for equation (2) against 0.1 s for
//!   equation (1) on an SGI Indigo).

use std::fmt::Write as _;
use std::hint::black_box;
use std::path::Path;
use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use super::plot::{self, ColourMap, Panel, Picture, Scale, Tick};
use super::{Context, Error, Report, table};
use crate::form_factor_accuracy::{DiskStudy, ErrorStats, Tilt};
use radiosity::form_factor::{FormFactor, Source, analytic, closed_form, disk, wallace};
use radiosity::mesh::subsources;

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

fn output_error(path: &Path) -> impl FnOnce(std::io::Error) -> Error + '_ {
    move |source| Error::Output {
        path: path.to_path_buf(),
        source,
    }
}

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
/// against [`closed_form::disk_exact`] over the paper's 4,140 receiver
/// positions and orientations at 1, 5 and 10 radii, under the paper's
/// protocol ([`Tilt::DiskAxis`], root-mean-square "average") beside the
/// paper's numbers, then under the other plausible protocols.
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

/// The cross-section of Figures 4.3 and 4.5: the factor from the unit
/// square source `[0, 1] x [0, 1]` in the plane `z = 0` (normal `+z`) to a
/// receiver facing straight down (`-z`, parallel to the source) at
/// `(x, 0.5, z)`, `x` in [`CrossSection::X_RANGE`], `z` in
/// [`CrossSection::Z_RANGE`], sampled at the centres of a `width x height`
/// grid (row 0 at the top, `z` largest).
#[derive(Clone, Debug)]
pub struct CrossSection {
    /// Samples per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// (a) Equation (2) on the whole square: the exact factor.
    pub exact: Vec<f64>,
    /// The closed form of a parallel rectangle
    /// ([`closed_form::parallel_rectangle`]), an independent check of (a).
    pub closed_form: Vec<f64>,
    /// (b) Equation (1) summed over 3x3 disks (the sub-squares' centroids
    /// and areas).
    pub wallace: Vec<f64>,
    /// (c) Equation (2) summed over the 3x3 sub-squares (Figure 4.5).
    pub analytic: Vec<f64>,
    /// (d) Equation (3) summed over 3x3 disks.
    pub disk: Vec<f64>,
}

impl CrossSection {
    /// Horizontal extent of the cross-section: half the source's width on
    /// either side of it.
    pub const X_RANGE: (f64, f64) = (-0.5, 1.5);
    /// Height above the source.
    pub const Z_RANGE: (f64, f64) = (0.0, 1.0);
    /// The plane of the cross-section, through the source's middle.
    pub const PLANE_Y: f64 = 0.5;
    /// Subsources per side, as in the paper's pictures.
    pub const SUBDIVISION: u32 = 3;

    /// The unit square source, counter-clockwise seen from `+z`.
    #[must_use]
    pub fn source() -> [DVec3; 4] {
        [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ]
    }

    /// The grid used: full size, or small in quick mode.
    #[must_use]
    pub fn grid(quick: bool) -> (usize, usize) {
        if quick { (80, 40) } else { (400, 200) }
    }

    /// The receiver at the centre of sample `(column, row)`.
    #[must_use]
    pub fn point(width: usize, height: usize, column: usize, row: usize) -> DVec3 {
        let (xl, xr) = Self::X_RANGE;
        let (zb, zt) = Self::Z_RANGE;
        let x = xl + (column as f64 + 0.5) / width as f64 * (xr - xl);
        let z = zt - (row as f64 + 0.5) / height as f64 * (zt - zb);
        DVec3::new(x, Self::PLANE_Y, z)
    }

    /// Evaluates every formula on a `width x height` grid.
    #[must_use]
    pub fn compute(width: usize, height: usize) -> CrossSection {
        let square = Self::source();
        let parts = subsources(&square, Self::SUBDIVISION);
        let normal = -DVec3::Z;
        let samples: Vec<[f64; 5]> = (0..width * height)
            .into_par_iter()
            .map(|i| {
                let x = Self::point(width, height, i % width, i / width);
                let exact = analytic(x, normal, &square);
                let closed = closed_form::parallel_rectangle(-x.x, 1.0 - x.x, -x.y, 1.0 - x.y, x.z);
                let (mut w, mut a, mut d) = (0.0, 0.0, 0.0);
                for part in &parts {
                    let source = Source {
                        polygon: &part.polygon,
                        centroid: part.centroid,
                        normal: DVec3::Z,
                        area: part.area,
                    };
                    w += wallace(x, normal, &source);
                    a += analytic(x, normal, &part.polygon);
                    d += disk(x, normal, &source);
                }
                [exact, closed, w, a, d]
            })
            .collect();
        let column = |k: usize| samples.iter().map(|s| s[k]).collect::<Vec<f64>>();
        CrossSection {
            width,
            height,
            exact: column(0),
            closed_form: column(1),
            wallace: column(2),
            analytic: column(3),
            disk: column(4),
        }
    }

    /// Signed relative errors `(F - F_exact) / F_exact` of one field.
    #[must_use]
    pub fn relative_errors(&self, field: &[f64]) -> Vec<f64> {
        field
            .iter()
            .zip(&self.exact)
            .map(|(f, e)| (f - e) / e)
            .collect()
    }

    /// Height of the receivers in `row`.
    #[must_use]
    pub fn z(&self, row: usize) -> f64 {
        Self::point(self.width, self.height, 0, row).z
    }
}

/// Largest and mean absolute value of `errors` over the rows whose height
/// passes `keep`.
fn region_stats(section: &CrossSection, errors: &[f64], keep: impl Fn(f64) -> bool) -> (f64, f64) {
    let (mut max, mut sum, mut n) = (0.0_f64, 0.0, 0usize);
    for row in 0..section.height {
        if !keep(section.z(row)) {
            continue;
        }
        for e in &errors[row * section.width..(row + 1) * section.width] {
            max = max.max(e.abs());
            sum += e.abs();
            n += 1;
        }
    }
    (max, sum / n.max(1) as f64)
}

fn ticks(values: &[(f64, &str)]) -> Vec<Tick> {
    values.iter().map(|&(v, s)| (v, s.to_string())).collect()
}

/// What Figures 4.3 and 4.5 show: the cross-section's factors and the
/// relative errors of (b), (c) and (d) against (a), signed and absolute.
#[derive(Clone, Debug)]
pub struct Fig43 {
    /// The factors.
    pub section: CrossSection,
    /// Signed relative errors of (b), (c), (d).
    pub signed: [Vec<f64>; 3],
    /// Their absolute values.
    pub absolute: [Vec<f64>; 3],
}

impl Fig43 {
    /// Evaluates the cross-section on the grid of [`CrossSection::grid`]
    /// and the errors.
    #[must_use]
    pub fn compute(quick: bool) -> Fig43 {
        let (width, height) = CrossSection::grid(quick);
        let section = CrossSection::compute(width, height);
        let signed = [&section.wallace, &section.analytic, &section.disk]
            .map(|field| section.relative_errors(field));
        let absolute = signed
            .each_ref()
            .map(|errors| errors.iter().map(|e| e.abs()).collect());
        Fig43 {
            section,
            signed,
            absolute,
        }
    }

    /// The ten pictures: the factors (a)-(d), the signed errors of (b)-(d)
    /// and their absolute values on log scales.
    fn figures(&self) -> [Figure<'_>; 10] {
        let section = &self.section;
        let [errors_b, errors_c, errors_d] = &self.signed;
        let [abs_b, abs_c, abs_d] = &self.absolute;
        let value = |values| {
            (
                values,
                ColourMap::Viridis,
                Scale::Linear { min: 0.0, max: 1.0 },
                ticks(&[
                    (0.0, "0"),
                    (0.2, "0.2"),
                    (0.4, "0.4"),
                    (0.6, "0.6"),
                    (0.8, "0.8"),
                    (1.0, "1"),
                ]),
            )
        };
        let signed = |values| {
            (
                values,
                ColourMap::Diverging,
                Scale::Linear {
                    min: -0.25,
                    max: 0.25,
                },
                ticks(&[
                    (-0.25, "<-25%"),
                    (-0.1, "-10%"),
                    (0.0, "0%"),
                    (0.1, "+10%"),
                    (0.25, ">+25%"),
                ]),
            )
        };
        let log = |values| {
            (
                values,
                ColourMap::Magma,
                Scale::Log10 {
                    min: 1e-4,
                    max: 1.0,
                },
                ticks(&[
                    (1e-4, "<1E-4"),
                    (1e-3, "0.1%"),
                    (1e-2, "1%"),
                    (1e-1, "10%"),
                    (1.0, "100%"),
                ]),
            )
        };
        let round_off = |values| {
            (
                values,
                ColourMap::Magma,
                Scale::Log10 {
                    min: 1e-17,
                    max: 1e-9,
                },
                ticks(&[
                    (1e-17, "<1E-17"),
                    (1e-15, "1E-15"),
                    (1e-13, "1E-13"),
                    (1e-11, "1E-11"),
                    (1e-9, ">1E-9"),
                ]),
            )
        };
        [
            (
                "fig4-3a-exact.png",
                "(a) exact: eq. (2), 1 square",
                "(a) the exact factor, eq. (2) on the whole square (Figure 4.3, left)",
                value(&section.exact),
            ),
            (
                "fig4-3b-wallace.png",
                "(b) eq. (1), 3x3 disks",
                "(b) Wallace's eq. (1) summed over 3x3 disks (Figure 4.3, right)",
                value(&section.wallace),
            ),
            (
                "fig4-3c-analytic-3x3.png",
                "(c) eq. (2), 3x3 squares",
                "(c) eq. (2) summed over the 3x3 sub-squares (Figure 4.5)",
                value(&section.analytic),
            ),
            (
                "fig4-3d-eq3.png",
                "(d) eq. (3), 3x3 disks",
                "(d) Wong & Tsang's eq. (3) summed over 3x3 disks",
                value(&section.disk),
            ),
            (
                "fig4-3b-error.png",
                "(b)-(a) / (a)",
                "signed relative error of (b); blue = too little",
                signed(errors_b),
            ),
            (
                "fig4-3c-error.png",
                "(c)-(a) / (a)",
                "signed relative error of (c): white, round-off only",
                signed(errors_c),
            ),
            (
                "fig4-3d-error.png",
                "(d)-(a) / (a)",
                "signed relative error of (d)",
                signed(errors_d),
            ),
            (
                "fig4-3b-log-error.png",
                "|(b)-(a)| / (a)",
                "|relative error| of (b), log scale",
                log(abs_b),
            ),
            (
                "fig4-3c-log-error.png",
                "|(c)-(a)| / (a)",
                "|relative error| of (c), log scale 1e-17..1e-9 of its own: round-off",
                round_off(abs_c),
            ),
            (
                "fig4-3d-log-error.png",
                "|(d)-(a)| / (a)",
                "|relative error| of (d), log scale",
                log(abs_d),
            ),
        ]
        .map(
            |(file, title, what, (values, map, scale, bar_ticks))| Figure {
                file,
                title,
                what,
                panel: Panel {
                    values,
                    width: section.width,
                    height: section.height,
                    map,
                    scale,
                    bar_ticks,
                    x_range: CrossSection::X_RANGE,
                    y_range: CrossSection::Z_RANGE,
                    x_ticks: ticks(&[
                        (-0.5, "-0.5"),
                        (0.0, "0"),
                        (0.5, "0.5"),
                        (1.0, "1"),
                        (1.5, "1.5"),
                    ]),
                    y_ticks: ticks(&[(0.0, "0"), (0.5, "0.5"), (1.0, "1")]),
                    marker: Some((0.0, 1.0)),
                },
            },
        )
    }
}

/// One picture of Figures 4.3 and 4.5: its file, title, description and
/// panel.
struct Figure<'a> {
    file: &'static str,
    title: &'static str,
    what: &'static str,
    panel: Panel<'a>,
}

/// The combined picture of Figures 4.3 and 4.5.
const FIG4_3_ALL: &str = "fig4-3-all.png";

/// Draws the pictures of Figures 4.3 and 4.5, each with its file name: the
/// ten panels, then all of them side by side (values (a)-(d) on the first
/// row, signed errors of (b)-(d) on the second, log errors on the third,
/// each error under its picture).
///
/// # Errors
///
/// If plotting fails.
pub fn fig4_3_plot(data: &Fig43) -> Result<Vec<(&'static str, Picture)>, Error> {
    let mut pictures = data
        .figures()
        .iter()
        .map(|f| Ok((f.file, f.panel.draw()?)))
        .collect::<Result<Vec<_>, Error>>()?;
    let panel = |i: usize| Some(&pictures[i].1);
    let cells = [
        panel(0),
        panel(1),
        panel(2),
        panel(3),
        None,
        panel(4),
        panel(5),
        panel(6),
        None,
        panel(7),
        panel(8),
        panel(9),
    ];
    let combined = plot::grid(&cells, 4, 8)?;
    pictures.push((FIG4_3_ALL, combined));
    Ok(pictures)
}

/// Figures 4.3 and 4.5: colour-scale pictures of the factor from a unit
/// square source to a receiver on the cross-section `y = 0.5` above it
/// (see [`CrossSection`]): (a) exact, (b) equation (1) on 3x3 disks,
/// (c) equation (2) on 3x3 squares, (d) equation (3) on 3x3 disks, and the
/// relative errors of (b), (c), (d) against (a).
pub fn fig4_3(context: &Context) -> Result<Report, Error> {
    let data = Fig43::compute(context.quick);
    let mut report = fig4_3_report(&data);
    for (file, picture) in fig4_3_plot(&data)? {
        let path = context.path(file);
        picture.write_png(&path).map_err(output_error(&path))?;
        report.files.push(path);
    }
    Ok(report)
}

/// The report of Figures 4.3 and 4.5: settings, checks, the error table,
/// the signs and the lowest row in words, and the list of pictures with
/// their axes.
#[must_use]
pub fn fig4_3_report(data: &Fig43) -> Report {
    let mut report = Report::default();
    let section = &data.section;
    let (width, height) = (section.width, section.height);
    let [errors_b, errors_c, errors_d] = &data.signed;
    report.setting(
        "source",
        "unit square [0,1] x [0,1] in the plane z = 0, facing +z; 3 x 3 subsources",
    );
    report.setting(
        "cross-section",
        "the plane y = 0.5, x in [-0.5, 1.5], z in [0, 1]; receiver normal -z (facing the source, parallel to it)",
    );
    report.setting(
        "grid",
        format!("{width} x {height} samples at pixel centres (one pixel per sample)"),
    );
    report.setting("value scale", "linear, 0 to 1, viridis, shared by (a)-(d)");
    report.setting(
        "error scales",
        "signed relative error, linear -25%..+25% (clamped), blue-white-red, shared by (b)-(d); |relative error|, log10, magma: 1e-4..1 for (b) and (d), 1e-17..1e-9 for (c) (clamped)",
    );

    let max_rel = |a: &[f64], b: &[f64]| {
        a.iter()
            .zip(b)
            .map(|(x, y)| ((x - y) / y).abs())
            .fold(0.0, f64::max)
    };
    let max_abs = |a: &[f64], b: &[f64]| {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
    };
    let closed_check = max_rel(&section.exact, &section.closed_form);
    let c_abs = max_abs(&section.analytic, &section.exact);
    let c_rel = max_rel(&section.analytic, &section.exact);

    report.paragraph(
        "The cross-section is the vertical plane y = 0.5 through the middle of \
         the unit square source (which lies in z = 0, corners (0,0) and (1,1), \
         facing +z), from x = -0.5 to 1.5 and z = 0 to 1; the grey bar under \
         each picture marks the source. The receiver at each point faces \
         straight down (-z), parallel to the source. Values share one linear \
         colour scale from 0 to 1 (viridis). Relative errors against (a) are \
         shown signed on one linear -25%..+25% blue-white-red scale (blue: too \
         small), and as |relative error| on a log scale (magma) from 1e-4 to 1 \
         for (b) and (d) and from 1e-17 to 1e-9 for (c), whose error is \
         round-off; every scale is clamped at its ends.",
    );
    report.paragraph(&format!(
        "Checks: (a), eq. (2) on the whole square, agrees with the closed form \
         of a parallel rectangle to {closed_check:.1e} relative. (c), eq. (2) \
         summed over the 9 sub-squares (Figure 4.5), equals (a) to round-off: \
         largest difference {c_abs:.1e} absolute, {c_rel:.1e} relative."
    ));

    let mut rows = Vec::new();
    // Near (z < 0.2), far (z > 0.5) and everywhere, as open intervals.
    let regions = [
        (f64::NEG_INFINITY, 0.2),
        (0.5, f64::INFINITY),
        (f64::NEG_INFINITY, f64::INFINITY),
    ];
    for (name, errors) in [
        ("(b) eq. (1), 3x3 disks", errors_b),
        ("(c) eq. (2), 3x3 squares", errors_c),
        ("(d) eq. (3), 3x3 disks", errors_d),
    ] {
        let mut row = vec![name.to_string()];
        for &(lo, hi) in &regions {
            let (max, mean) = region_stats(section, errors, |z| lo < z && z < hi);
            row.push(format_error(max));
            row.push(format_error(mean));
        }
        rows.push(row);
    }
    report
        .body
        .push_str("Relative errors against (a) over the cross-section:\n\n");
    report.body.push_str(&table(
        &[
            "picture",
            "max, z < 0.2",
            "mean, z < 0.2",
            "max, z > 0.5",
            "mean, z > 0.5",
            "max, all",
            "mean, all",
        ],
        &rows,
    ));

    let signed_range = |errors: &[f64]| {
        errors
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &e| {
                (lo.min(e), hi.max(e))
            })
    };
    let (b_lo, b_hi) = signed_range(errors_b);
    let (d_lo, d_hi) = signed_range(errors_d);
    let overestimates = |errors: &[f64]| {
        let points: Vec<DVec3> = errors
            .iter()
            .enumerate()
            .filter(|(_, e)| **e > 0.0)
            .map(|(i, _)| CrossSection::point(width, height, i % width, i / width))
            .collect();
        let outside = points.iter().filter(|p| p.x < 0.0 || p.x > 1.0).count();
        let highest = points.iter().map(|p| p.z).fold(0.0, f64::max);
        (points.len(), outside, highest)
    };
    let describe = |name: &str, lo: f64, hi: f64, errors: &[f64]| {
        let (count, outside, highest) = overestimates(errors);
        let over = if count == 0 {
            "never above the exact factor".to_string()
        } else {
            format!(
                "above the exact factor at {count} of {} samples ({outside} of them \
                 outside the square, all at z <= {highest:.4})",
                errors.len()
            )
        };
        format!(
            "{name} runs from {:+.2}% to {:+.2}%, {over}",
            100.0 * lo,
            100.0 * hi
        )
    };
    let radius = (1.0 / (9.0 * std::f64::consts::PI)).sqrt();
    let overhang = radius - 1.0 / 6.0;
    let mut signed = format!(
        "Signed, the relative error of {}; that of {}. Both disk formulas \
         underestimate almost everywhere.",
        describe("(b)", b_lo, b_hi, errors_b),
        describe("(d)", d_lo, d_hi, errors_d),
    );
    if overestimates(errors_d).0 > 0 {
        let _ = write!(
            signed,
            " The disks of equal area have radius {radius:.4}, so the outer \
             ones overhang the square's edges by {overhang:.4}: a receiver just \
             outside an edge, close to the source's plane, is near a disk's rim \
             but farther from the square, and eq. (3), accurate for the disk, \
             overestimates there."
        );
    }
    report.paragraph(&signed);

    let (row_b, _) = worst(section, errors_b);
    report.paragraph(&format!(
        "Lowest row (z = {:.4}): over the source, (b) ranges from {:.1}% to \
         {:.1}% of the exact factor and (d) from {:.1}% to {:.1}%; the exact \
         factor there is between {:.3} and {:.3}. The dark bands of (b) and \
         (d) sit between the disks' centres, the aliasing of Figure 4.3. The \
         worst error of (b) is at z = {:.4}.",
        section.z(height - 1),
        100.0 * over_source_ratio(section, &section.wallace, height - 1).0,
        100.0 * over_source_ratio(section, &section.wallace, height - 1).1,
        100.0 * over_source_ratio(section, &section.disk, height - 1).0,
        100.0 * over_source_ratio(section, &section.disk, height - 1).1,
        over_source_range(section, height - 1).0,
        over_source_range(section, height - 1).1,
        section.z(row_b),
    ));

    let figures = data.figures();
    let mut list = String::from(
        "Pictures (titles and tick labels are here, not in the pictures; the \
         tick marks are drawn):\n\n",
    );
    for f in &figures {
        let _ = writeln!(list, "- `{}`: {}; titled {}", f.file, f.what, f.title);
    }
    let _ = writeln!(
        list,
        "- `{FIG4_3_ALL}`: all of them side by side: values (a)-(d) on the \
         first row, signed errors of (b)-(d) on the second, log errors on the \
         third\n"
    );
    let _ = writeln!(
        list,
        "Axes of every picture: {}. Colour bar ticks of the signed errors: {}; \
         of the log errors of (b) and (d): {}; of (c): {}.\n",
        figures[0].panel.axes(),
        plot::labels(&figures[4].panel.bar_ticks),
        plot::labels(&figures[7].panel.bar_ticks),
        plot::labels(&figures[8].panel.bar_ticks),
    );
    report.body.push_str(&list);
    report
}

fn format_error(e: f64) -> String {
    if e >= 1e-3 {
        format!("{:.2}%", 100.0 * e)
    } else {
        format!("{e:.1e}")
    }
}

/// Row and column of the largest absolute error.
fn worst(section: &CrossSection, errors: &[f64]) -> (usize, usize) {
    let i = errors
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        .map_or(0, |(i, _)| i);
    (i / section.width, i % section.width)
}

/// Columns whose receivers lie above the source (0 < x < 1).
fn over_source(section: &CrossSection) -> impl Iterator<Item = usize> + '_ {
    (0..section.width).filter(move |&c| {
        let x = CrossSection::point(section.width, section.height, c, 0).x;
        x > 0.0 && x < 1.0
    })
}

/// Smallest and largest `field / exact` on `row` above the source.
fn over_source_ratio(section: &CrossSection, field: &[f64], row: usize) -> (f64, f64) {
    over_source(section)
        .map(|c| {
            let i = row * section.width + c;
            field[i] / section.exact[i]
        })
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        })
}

/// Smallest and largest exact factor on `row` above the source.
fn over_source_range(section: &CrossSection, row: usize) -> (f64, f64) {
    over_source(section)
        .map(|c| section.exact[row * section.width + c])
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        })
}

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
