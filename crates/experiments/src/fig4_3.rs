//! Figures 4.3 and 4.5 of Wong & Tsang 1993 (section 4, "Analytical
//! Form-Factor Formula"), `radiosity experiment fig4-3`: colour-scale
//! pictures of the factor from a unit square source to a receiver on a
//! cross-section of space above it ([`CrossSection`]): (a) exact, equation
//! (2) on the whole square; (b) equation (1) on 3x3 disks (Figure 4.3);
//! (c) equation (2) on the 3x3 sub-squares (Figure 4.5); (d) equation (3)
//! on 3x3 disks; and the relative errors of (b), (c) and (d) against (a),
//! signed and on log scales, drawn with [`super::plot`].

use std::fmt::Write as _;
use std::path::Path;

use glam::DVec3;
use rayon::prelude::*;

use super::plot::{self, ColourMap, Panel, Picture, Scale, Tick};
use super::{Context, Error, Report, table};
use radiosity::form_factor::{Source, analytic, closed_form, disk, wallace};
use radiosity::mesh::subsources;

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

/// A failure to write `path`, as [`Error::Output`].
fn output_error(path: &Path) -> impl FnOnce(std::io::Error) -> Error + '_ {
    move |source| Error::Output {
        path: path.to_path_buf(),
        source,
    }
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
