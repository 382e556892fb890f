//! The accuracy study of the paper's section 4 (Figures 4.2 and 4.6): the
//! relative error of a point-to-disk formula, equation (1) or (3), against
//! the exact disk factor ([`closed_form::disk_exact`]) over a grid of
//! receiver positions and orientations.
//!
//! The disk has unit radius, centre at the origin and normal `+z`. The
//! receiver sits at distance `r` (in radii) from the centre, at angle
//! `theta_k` from the disk's normal in the `x-z` plane (the plane of
//! incidence): `x = r (sin theta_k, 0, cos theta_k)`. Its normal depends on
//! the [`Tilt`]. `theta_k` and `theta_j` run over whole degrees. With
//! [`Tilt::DiskAxis`], `theta_k` in 0..=89 and `theta_j` in 0..=45 (the
//! paper's 4,140 orientations and positions), the root-mean-square and
//! maximum relative errors reproduce the paper's figures: its "average" is
//! the root mean square.

use glam::DVec3;

use radiosity::form_factor::{FormFactor, Source, closed_form};

/// How the receiver's normal is set from `theta_j`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tilt {
    /// The paper's protocol: the disk's reversed normal `-z` tilted by
    /// `theta_j` in the plane of incidence, towards the centre as seen from
    /// the receiver, `n = (-sin theta_j, 0, -cos theta_j)` (at
    /// `theta_j = theta_k` it points at the centre).
    DiskAxis,
    /// The normal points at the disk's centre, then turns by `theta_j`
    /// about `+y` (the normal of the plane of incidence), away from the
    /// disk's axis: its angle from `-z` becomes `theta_k + theta_j`.
    InPlane,
    /// The normal points at the disk's centre, then turns by `theta_j`
    /// towards `+y`, out of the plane of incidence. Equation (3) is exact
    /// here whenever the whole disk is in front of the receiver: the
    /// component its derivation neglects is the one in the plane of
    /// incidence.
    Sideways,
}

/// One run of the study: distance and angle ranges, and the tilt.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiskStudy {
    /// Distance from the disk's centre, in disk radii.
    pub distance: f64,
    /// Largest `theta_k` in degrees (from 0, whole degrees).
    pub max_theta_k: u32,
    /// Largest `theta_j` in degrees (from 0, whole degrees).
    pub max_theta_j: u32,
    /// How `theta_j` orients the receiver.
    pub tilt: Tilt,
}

/// Relative-error statistics of one formula over a study's grid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ErrorStats {
    /// Mean of `|F - F_exact| / F_exact`.
    pub mean: f64,
    /// Root mean square of the relative error (the paper's "average").
    pub rms: f64,
    /// Largest relative error.
    pub max: f64,
    /// Grid points with a non-zero exact factor (the others are skipped).
    pub samples: usize,
}

impl DiskStudy {
    /// The paper's grid at `distance` radii: `theta_k` 0..=89, `theta_j`
    /// 0..=45, [`Tilt::DiskAxis`].
    #[must_use]
    pub fn paper(distance: f64) -> DiskStudy {
        DiskStudy {
            distance,
            max_theta_k: 89,
            max_theta_j: 45,
            tilt: Tilt::DiskAxis,
        }
    }

    /// Receiver position and unit normal for angles in degrees.
    #[must_use]
    pub fn receiver(&self, theta_k: f64, theta_j: f64) -> (DVec3, DVec3) {
        let (tk, tj) = (theta_k.to_radians(), theta_j.to_radians());
        let (sin_k, cos_k) = tk.sin_cos();
        let (sin_j, cos_j) = tj.sin_cos();
        let position = self.distance * DVec3::new(sin_k, 0.0, cos_k);
        let normal = match self.tilt {
            Tilt::DiskAxis => DVec3::new(-sin_j, 0.0, -cos_j),
            Tilt::InPlane => {
                let (s, c) = (tk + tj).sin_cos();
                DVec3::new(-s, 0.0, -c)
            }
            Tilt::Sideways => DVec3::new(-sin_k * cos_j, sin_j, -cos_k * cos_j),
        };
        (position, normal)
    }

    /// Relative errors of `formula` against the exact disk factor. The
    /// source handed to `formula` is the unit disk, with a 2048-gon of equal
    /// area as its polygon (so [`FormFactor::Analytic`] measures the
    /// polygon-for-disk error, about `1e-12`).
    #[must_use]
    pub fn errors(&self, formula: FormFactor) -> ErrorStats {
        let polygon = closed_form::disk_polygon(DVec3::ZERO, DVec3::Z, 1.0, 2048);
        let source = Source {
            polygon: &polygon,
            centroid: DVec3::ZERO,
            normal: DVec3::Z,
            area: std::f64::consts::PI,
        };
        let (mut sum, mut sum_squares, mut max, mut samples) = (0.0, 0.0, 0.0_f64, 0);
        for k in 0..=self.max_theta_k {
            for j in 0..=self.max_theta_j {
                let (x, n) = self.receiver(f64::from(k), f64::from(j));
                let exact = closed_form::disk_exact(x, n, DVec3::ZERO, DVec3::Z, 1.0);
                if exact <= 0.0 {
                    continue;
                }
                let error = ((formula.evaluate(x, n, &source) - exact) / exact).abs();
                sum += error;
                sum_squares += error * error;
                max = max.max(error);
                samples += 1;
            }
        }
        let count = samples.max(1) as f64;
        ErrorStats {
            mean: sum / count,
            rms: (sum_squares / count).sqrt(),
            max,
            samples,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_tilt_points_at_the_centre_when_untilted() {
        for tilt in [Tilt::InPlane, Tilt::Sideways] {
            let study = DiskStudy {
                distance: 3.0,
                max_theta_k: 0,
                max_theta_j: 0,
                tilt,
            };
            let (x, n) = study.receiver(30.0, 0.0);
            assert!((n + x.normalize()).length() < 1e-15);
        }
        let (x, n) = DiskStudy::paper(3.0).receiver(30.0, 30.0);
        assert!((n + x.normalize()).length() < 1e-15);
    }

    #[test]
    fn tilts_move_the_normal_by_theta_j() {
        for tilt in [Tilt::DiskAxis, Tilt::InPlane, Tilt::Sideways] {
            let study = DiskStudy {
                distance: 2.0,
                max_theta_k: 0,
                max_theta_j: 0,
                tilt,
            };
            let (_, n0) = study.receiver(20.0, 0.0);
            let (_, n) = study.receiver(20.0, 25.0);
            assert!((n.length() - 1.0).abs() < 1e-15);
            assert!(
                (n.dot(n0).acos().to_degrees() - 25.0).abs() < 1e-9,
                "{tilt:?}"
            );
        }
    }
}
