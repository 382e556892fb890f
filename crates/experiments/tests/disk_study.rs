//! The paper's error study of the disk formulas (section 4, Figures 4.2
//! and 4.6): equations (1) and (3) against the exact disk factor, their
//! fall-off with distance, and the paper's published numbers.

use approx::abs_diff_eq;
use radiosity::form_factor::FormFactor;
use radiosity_experiments::form_factor_accuracy::{DiskStudy, Tilt};

/// Relative-error statistics for equations (1) and (3) under `study`.
fn wallace_and_disk(study: DiskStudy) -> (f64, f64, f64, f64) {
    let wallace = study.errors(FormFactor::Wallace);
    let disk = study.errors(FormFactor::Disk);
    (wallace.mean, wallace.max, disk.mean, disk.max)
}

#[test]
fn disk_formulas_tend_to_the_exact_factor_far_away() {
    // Protocol (Tilt::InPlane): unit disk at the origin facing +z, receiver
    // at r (sin theta_k, 0, cos theta_k), normal pointing at the centre then
    // turned by theta_j about +y away from the disk's axis; theta_k 0..=60,
    // theta_j 0..=45 degrees. Also under the other two tilts.
    for tilt in [Tilt::InPlane, Tilt::Sideways, Tilt::DiskAxis] {
        let study = |distance| DiskStudy {
            distance,
            max_theta_k: 60,
            max_theta_j: 45,
            tilt,
        };
        let (w_mean, w_max, d_mean, d_max) = wallace_and_disk(study(30.0));
        // Equation (3) is within 0.1% everywhere at 30 R; equation (1) only
        // on average (its largest error there is 0.17-0.25%, it needs about
        // 50 R to be within 0.1% everywhere).
        assert!(d_max < 1e-3, "{tilt:?}: eq. 3 max {d_max}");
        assert!(w_mean < 1e-3, "{tilt:?}: eq. 1 mean {w_mean}");
        assert!(w_max < 3e-3, "{tilt:?}: eq. 1 max {w_max}");
        assert!(d_mean < w_mean);
        // Both errors fall like (R/r)^2: a quarter at twice the distance.
        let (w_mean_60, w_max_60, _, d_max_60) = wallace_and_disk(study(60.0));
        assert!(
            abs_diff_eq!(w_max_60 / w_max, 0.25, epsilon = 0.01),
            "{w_max_60} / {w_max}"
        );
        assert!(
            abs_diff_eq!(w_mean_60 / w_mean, 0.25, epsilon = 0.01),
            "{w_mean_60} / {w_mean}"
        );
        assert!(d_max_60 <= d_max * 0.26 + 1e-12, "{d_max_60} / {d_max}");
        let (w_max_50, d_max_50) = {
            let (_, w, _, d) = wallace_and_disk(study(50.0));
            (w, d)
        };
        assert!(w_max_50 < 1e-3 && d_max_50 < 1e-3);
    }
}

#[test]
fn disk_formula_beats_wallace_on_average_at_five_radii() {
    // theta_k 0..=89, theta_j 0..=45, under every tilt (Tilt::InPlane is
    // the protocol of the brief: pointing at the centre, turned about +y).
    for tilt in [Tilt::InPlane, Tilt::Sideways, Tilt::DiskAxis] {
        let study = DiskStudy {
            distance: 5.0,
            max_theta_k: 89,
            max_theta_j: 45,
            tilt,
        };
        let wallace = study.errors(FormFactor::Wallace);
        let disk = study.errors(FormFactor::Disk);
        assert_eq!(wallace.samples, 90 * 46);
        assert!(
            disk.mean < 0.5 * wallace.mean,
            "{tilt:?}: {disk:?} vs {wallace:?}"
        );
        assert!(disk.rms < wallace.rms && disk.max < wallace.max);
    }
}

#[test]
fn the_error_study_reproduces_the_papers_figures_4_2_and_4_6() {
    // Figures 4.2 (eq. 1) and 4.6 (eq. 3): "average" and maximum relative
    // error in percent at 1, 5 and 10 R. Under Tilt::DiskAxis the paper's
    // average is the root mean square; all twelve numbers agree within
    // 0.02 percentage points (the paper rounds to 0.01).
    let paper = [
        (1.0, (55.38, 99.97), (32.71, 98.25)),
        (5.0, (5.55, 11.38), (1.13, 4.0)),
        (10.0, (1.44, 2.96), (0.28, 1.0)),
    ];
    for (distance, (w_rms, w_max), (d_rms, d_max)) in paper {
        let study = DiskStudy::paper(distance);
        let wallace = study.errors(FormFactor::Wallace);
        let disk = study.errors(FormFactor::Disk);
        for (name, measured, published) in [
            ("eq. 1 average", wallace.rms, w_rms),
            ("eq. 1 max", wallace.max, w_max),
            ("eq. 3 average", disk.rms, d_rms),
            ("eq. 3 max", disk.max, d_max),
        ] {
            assert!(
                abs_diff_eq!(100.0 * measured, published, epsilon = 0.02),
                "{distance} R {name}: {:.4}% vs {published}%",
                100.0 * measured
            );
        }
    }
    // Equation (2) on a 2048-gon of the disk's area is exact by comparison
    // (on part of the grid: 2048 edges per sample is slow unoptimised).
    for distance in [1.0, 5.0, 10.0] {
        let study = DiskStudy {
            max_theta_j: 5,
            ..DiskStudy::paper(distance)
        };
        let analytic = study.errors(FormFactor::Analytic);
        assert!(analytic.max < 1e-9, "{analytic:?}");
    }
}
