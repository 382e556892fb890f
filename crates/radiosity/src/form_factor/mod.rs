//! Point-to-polygon form factors (paper section 4): the factor from a
//! differential receiving area at a vertex to a subsource.
//!
//! * [`wallace`]: Wallace, Elmquist & Haines' disk approximation, the
//!   paper's equation (1), the baseline of the `wallace89` preset.
//! * [`disk`]: Wong & Tsang's better disk approximation, equation (3),
//!   derived in the paper's appendix; as cheap as equation (1).
//! * [`analytic()`]: the exact factor of Baum et al. (Lambert's contour
//!   formula), equation (2), used by the `wong-tsang93` preset.
//!
//! [`closed_form`] holds the exact answers of the heat-transfer literature
//! that the tests (and the experiments) compare these against; the paper's
//! error study of equations (1) and (3) (Figures 4.2 and 4.6) is in the
//! experiments crate (`radiosity_experiments::form_factor_accuracy`).
//!
//! The factor returned is always `F_jk`, from the differential area at the
//! receiver to the finite subsource (design.md section 4); a receiver gathers
//! `rho_j * dB_i * sum_k delta_kj * F_jk`. A negative cosine means the pair
//! does not see each other and gives 0.

pub mod analytic;
pub mod angle;
pub mod closed_form;

pub use analytic::analytic;

use glam::DVec3;

crate::choice::named_choice! {
    /// Which point-to-polygon formula the solver evaluates.
    pub enum FormFactor: "form factor" {
        /// Wallace et al.'s disk approximation, equation (1).
        Wallace = "wallace",
        /// Wong & Tsang's disk approximation, equation (3).
        Disk = "disk",
        /// The exact contour formula of Baum et al., equation (2).
        Analytic = "analytic",
    }
}

impl FormFactor {
    /// Evaluates the factor from the differential area at `receiver`
    /// (unit normal `receiver_normal`) to `source`.
    #[must_use]
    pub fn evaluate(self, receiver: DVec3, receiver_normal: DVec3, source: &Source<'_>) -> f64 {
        match self {
            FormFactor::Wallace => wallace(receiver, receiver_normal, source),
            FormFactor::Disk => disk(receiver, receiver_normal, source),
            FormFactor::Analytic => analytic(receiver, receiver_normal, source.polygon),
        }
    }
}

/// A subsource as the form factors see it: its polygon and the quantities
/// the disk formulas take from it.
#[derive(Clone, Copy, Debug)]
pub struct Source<'a> {
    /// Corners, counter-clockwise seen from the front.
    pub polygon: &'a [DVec3],
    /// Area-weighted centroid `c_k`.
    pub centroid: DVec3,
    /// Unit normal of the emitting side.
    pub normal: DVec3,
    /// Area `A_k`.
    pub area: f64,
}

/// The geometry both disk formulas take from a receiver and a subsource's
/// centre: the offset `d = x - c_k`, its length `r` and the two cosines, or
/// `None` when the pair does not face each other (a negative cosine) or the
/// receiver sits on the centre (the cosines undefined).
struct DiskView {
    d: DVec3,
    r: f64,
    cos_j: f64,
    cos_k: f64,
}

impl DiskView {
    fn of(receiver: DVec3, receiver_normal: DVec3, source: &Source<'_>) -> Option<DiskView> {
        let d = receiver - source.centroid;
        let r = d.length();
        if r == 0.0 {
            return None;
        }
        let cos_k = source.normal.dot(d) / r;
        let cos_j = -receiver_normal.dot(d) / r;
        (cos_k > 0.0 && cos_j > 0.0).then_some(DiskView { d, r, cos_j, cos_k })
    }
}

/// Equation (1): `F = A_k cos(theta_j) cos(theta_k) / (pi r^2 + A_k)`, the
/// subsource treated as a disk of equal area centred at `c_k`.
#[must_use]
pub fn wallace(receiver: DVec3, receiver_normal: DVec3, source: &Source<'_>) -> f64 {
    let Some(DiskView {
        r, cos_j, cos_k, ..
    }) = DiskView::of(receiver, receiver_normal, source)
    else {
        return 0.0;
    };
    source.area * cos_j * cos_k / (std::f64::consts::PI * r * r + source.area)
}

/// Equation (3), Wong & Tsang's approximation for a disk of radius
/// `R = sqrt(A_k / pi)` centred at `c_k`:
///
/// `F = A_k cos(theta_j) cos(theta_k) / (pi r^2 + A_k - 2 pi r R sin(theta_k))
///      * sqrt(r^2 + R^2 - 2 r R sin(theta_k)) / sqrt(r^2 + R^2 + 2 r R sin(theta_k))`.
///
/// It is evaluated in the equivalent form
/// `F = R^2 cos(theta_j) cos(theta_k) / sqrt(D_- D_+)` with
/// `D_+- = r^2 + R^2 +- 2 r R sin(theta_k)`, and `D_-` as
/// `(r - R sin(theta_k))^2 + (R cos(theta_k))^2`, free of cancellation. The
/// denominator the paper guards against, `D_-`, vanishes only when
/// `cos(theta_k) = 0` and `r = R`, where the cosine clamp already gives 0;
/// elsewhere `D_- >= R^2 cos^2(theta_k)` and `D_+ >= R^2`, so the factor never
/// exceeds `cos(theta_j)`: it is finite and in `[0, 1]` for every receiver,
/// including `r ~ R sin(theta_k)` (the receiver above the disk's rim). A
/// receiver at the centroid itself (`r = 0`, the cosines undefined) gets 0,
/// as in [`wallace`].
#[must_use]
pub fn disk(receiver: DVec3, receiver_normal: DVec3, source: &Source<'_>) -> f64 {
    let Some(DiskView { d, r, cos_j, cos_k }) = DiskView::of(receiver, receiver_normal, source)
    else {
        return 0.0;
    };
    let radius = (source.area.max(0.0) / std::f64::consts::PI).sqrt();
    // From the cross product, not sqrt(1 - cos^2), which loses half the
    // digits of a small sine.
    let sin_k = source.normal.cross(d).length() / r;
    let (along, across) = (radius * sin_k, radius * cos_k);
    let near = (r - along).powi(2) + across * across;
    let far = (r + along).powi(2) + across * across;
    clamp_factor(radius * radius * cos_j * cos_k / (near.sqrt() * far.sqrt()))
}

/// Clamps a factor to `[0, 1]`, mapping NaN (from non-finite input) to 0 so
/// that no formula hands the solver a NaN.
pub(crate) fn clamp_factor(f: f64) -> f64 {
    if f.is_nan() { 0.0 } else { f.clamp(0.0, 1.0) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wallace_is_exact_on_the_axis_of_a_parallel_disk() {
        // On the axis of a parallel disk of radius R at height h the exact
        // factor is R^2 / (h^2 + R^2); eq. (1) reproduces it there.
        let (radius, h) = (0.3_f64, 1.7_f64);
        let area = std::f64::consts::PI * radius * radius;
        let src = Source {
            polygon: &[],
            centroid: DVec3::ZERO,
            normal: DVec3::Z,
            area,
        };
        let f = wallace(DVec3::new(0.0, 0.0, h), -DVec3::Z, &src);
        let exact = radius * radius / (h * h + radius * radius);
        assert!((f - exact).abs() < 1e-15);
        assert_eq!(wallace(DVec3::new(0.0, 0.0, -h), DVec3::Z, &src), 0.0);
    }

    fn unit_disk() -> Source<'static> {
        Source {
            polygon: &[],
            centroid: DVec3::ZERO,
            normal: DVec3::Z,
            area: std::f64::consts::PI,
        }
    }

    #[test]
    fn disk_is_exact_on_the_axis_and_equals_wallace_there() {
        let src = unit_disk();
        for h in [0.01, 0.5, 1.0, 7.0] {
            let x = DVec3::new(0.0, 0.0, h);
            let exact = 1.0 / (h * h + 1.0);
            assert!((disk(x, -DVec3::Z, &src) - exact).abs() < 1e-15);
            assert!((disk(x, -DVec3::Z, &src) - wallace(x, -DVec3::Z, &src)).abs() < 1e-15);
        }
    }

    #[test]
    fn disk_is_finite_at_its_degenerate_points() {
        let src = unit_disk();
        // At the centre, on the rim (r = R, theta_k -> 90 degrees), above the
        // rim (r = R sin theta_k) and nearly in the disk's plane.
        assert_eq!(disk(DVec3::ZERO, -DVec3::Z, &src), 0.0);
        for x in [
            DVec3::new(1.0, 0.0, 1e-300),
            DVec3::new(1.0, 0.0, 1e-12),
            DVec3::new(1.0, 0.0, 1.0),
            DVec3::new(1e-9, 0.0, 1e-12),
        ] {
            for n in [
                -DVec3::Z,
                -x.normalize(),
                DVec3::new(-1.0, 0.0, -1.0).normalize(),
            ] {
                let f = disk(x, n, &src);
                assert!(f.is_finite() && (0.0..=1.0).contains(&f), "{x} {n}: {f}");
            }
        }
        assert_eq!(disk(DVec3::new(0.3, 0.0, -1.0), DVec3::Z, &src), 0.0);
    }

    #[test]
    fn names_round_trip_and_evaluate_dispatches() {
        for f in FormFactor::ALL {
            assert_eq!(f.name().parse::<FormFactor>(), Ok(f));
        }
        assert!("baum".parse::<FormFactor>().is_err());
        let square = [
            DVec3::new(-0.5, -0.5, 0.0),
            DVec3::new(0.5, -0.5, 0.0),
            DVec3::new(0.5, 0.5, 0.0),
            DVec3::new(-0.5, 0.5, 0.0),
        ];
        let src = Source {
            polygon: &square,
            centroid: DVec3::ZERO,
            normal: DVec3::Z,
            area: 1.0,
        };
        let (x, n) = (
            DVec3::new(0.2, 0.1, 1.5),
            DVec3::new(0.1, 0.0, -1.0).normalize(),
        );
        assert_eq!(
            FormFactor::Analytic.evaluate(x, n, &src),
            analytic(x, n, &square)
        );
        assert_eq!(FormFactor::Disk.evaluate(x, n, &src), disk(x, n, &src));
        assert_eq!(
            FormFactor::Wallace.evaluate(x, n, &src),
            wallace(x, n, &src)
        );
    }
}
