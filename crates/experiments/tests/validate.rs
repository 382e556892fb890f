//! The parts of `radiosity experiment validate` and `accuracy-curve` that
//! need no Radiance: score.py's arithmetic on a hand-made reference, the
//! error picture (colours, occlusion, the side a point faces) and the
//! message when the harness's Python environment is missing.

#[path = "../../radiosity/tests/common/mod.rs"]
mod common;

use std::path::Path;

use approx::abs_diff_eq;
use common::{quad, scene_of};
use glam::DVec3;
use radiosity::mesh::{Mesh, MeshSettings};
use radiosity::scene::Camera;
use radiosity_experiments::Context;
use radiosity_experiments::plot::{ColourMap, GREY};
use radiosity_experiments::reference::{self, Harness, Scored};
use radiosity_experiments::validate::{ERROR_RANGE, ErrorPoint, error_picture};

/// Four points with a reference and one without (the harness matched no
/// face). Channel means: reference 1, 2, 4, 0.01; ours 1.1, 1.7, 4.2,
/// 0.02. By hand (numpy gives the same): L1 = (0.1 + 0.3 + 0.2 + 0.01) /
/// 7.01; bias = 7.02 / 7.01 - 1; the 95th percentile of the reference is
/// 2 + 0.85 x 2 = 3.7, so the bright points are those above 0.074, the
/// first three, with relative errors +0.1, -0.15, +0.05: median 0.1, p90
/// (linear, position 1.8 of 0..2) 0.1 + 0.8 x 0.05 = 0.14.
#[test]
fn scores_follow_score_py_on_a_hand_made_reference() {
    let reference = vec![
        Some(DVec3::new(0.5, 1.0, 1.5)),
        Some(DVec3::new(2.0, 2.0, 2.0)),
        Some(DVec3::new(6.0, 3.0, 3.0)),
        Some(DVec3::new(0.0, 0.01, 0.02)),
        None,
    ];
    let ours = vec![
        DVec3::new(0.6, 1.2, 1.5),
        DVec3::new(1.7, 1.7, 1.7),
        DVec3::new(6.0, 3.3, 3.3),
        DVec3::new(0.02, 0.02, 0.02),
        DVec3::new(100.0, 100.0, 100.0),
    ];
    let score = reference::score(&ours, &reference);
    let close = |a: f64, b: f64| abs_diff_eq!(a, b, epsilon = 1e-12);
    assert!(close(score.l1, 0.61 / 7.01), "{}", score.l1);
    assert!(close(score.bias, 7.02 / 7.01 - 1.0), "{}", score.bias);
    assert!(close(score.median, 0.1), "{}", score.median);
    assert!(close(score.p90, 0.14), "{}", score.p90);
    assert_eq!(score.points, 4);
    let relative: Vec<Option<f64>> = score
        .relative
        .iter()
        .map(|r| r.map(|r| (r * 1e9).round() / 1e9))
        .collect();
    assert_eq!(relative, [Some(0.1), Some(-0.15), Some(0.05), None, None]);

    // The check against score.py's own numbers passes on round-off and
    // fails on a real difference.
    let scored = |l1: f64| Scored {
        rows: vec![0, 1, 2, 3, 4],
        reference: reference.clone(),
        l1,
        bias: 7.02 / 7.01 - 1.0,
        median: 0.1,
        p90: 0.14,
        points: 4,
        noise: 0.0,
        reference_seconds: None,
    };
    assert!(
        score
            .check_against(&scored(0.61 / 7.01 + 1e-16), "t")
            .is_ok()
    );
    let error = score
        .check_against(&scored(0.0871), "t")
        .unwrap_err()
        .to_string();
    assert!(error.contains("differs from score.py's"), "{error}");
}

/// A 4 x 4 m floor under a light, seen straight down from 5 m with a
/// 90-degree view: a floor point (x, 0, z) appears at pixel (100 + 20 x,
/// 100 + 20 z) of a 200 x 200 view. A board at 2 m hides the floor seen
/// behind it (x and z from 0.83 to 1.67).
#[test]
fn the_error_picture_colours_visible_points_by_their_error() {
    let floor = common::floor(0.5);
    let light = quad(
        DVec3::new(-3.0, 6.0, -3.0),
        DVec3::X * 6.0,
        DVec3::Z * 6.0,
        0.0,
        1.0,
        1,
    );
    let board = quad(
        DVec3::new(0.5, 2.0, 0.5),
        DVec3::Z * 0.5,
        DVec3::X * 0.5,
        0.5,
        0.0,
        2,
    );
    let scene = scene_of(vec![floor, light, board]);
    let mesh = Mesh::build(
        &scene,
        &MeshSettings {
            patch_size: 4.0,
            element_size: 0.5,
            ..MeshSettings::default()
        },
    )
    .unwrap();
    let display = vec![DVec3::splat(0.5); mesh.vertices.len()];
    let camera = Camera {
        eye: DVec3::new(0.0, 5.0, 0.0),
        target: DVec3::ZERO,
        up: -DVec3::Z,
        fov_degrees: 90.0,
    };
    let on_floor = |x: f64, z: f64, relative: Option<f64>| ErrorPoint {
        position: DVec3::new(x, 0.0, z),
        normal: DVec3::Y,
        group: 0,
        relative,
    };
    let points = [
        on_floor(-1.0, -1.0, Some(ERROR_RANGE)),
        on_floor(1.0, -1.0, Some(-2.0 * ERROR_RANGE)),
        on_floor(-1.0, 1.0, None),
        on_floor(0.0, 0.0, Some(0.0)),
        // Under the board: hidden.
        on_floor(1.25, 1.25, Some(ERROR_RANGE)),
        // Facing away from the camera: not drawn.
        ErrorPoint {
            position: DVec3::new(-1.5, 0.0, 0.0),
            normal: -DVec3::Y,
            group: 0,
            relative: Some(ERROR_RANGE),
        },
    ];
    let picture = error_picture(&scene, &mesh, &display, camera, &points, (200, 200)).unwrap();
    assert_eq!((picture.width, picture.height), (200, 200));
    let at = |x: f64, z: f64| {
        picture
            .pixel((100.0 + 20.0 * x) as usize, (100.0 + 20.0 * z) as usize)
            .unwrap()
    };
    let red = ColourMap::Diverging.colour(1.0);
    let blue = ColourMap::Diverging.colour(0.0);
    let white = ColourMap::Diverging.colour(0.5);
    assert_eq!(at(-1.0, -1.0), red);
    assert_eq!(at(1.0, -1.0), blue, "clamped to the end of the bar");
    assert_eq!(at(-1.0, 1.0), GREY);
    assert_eq!(at(0.0, 0.0), white);
    let grey = |c: [u8; 3]| c[0] == c[1] && c[1] == c[2];
    assert!(grey(at(1.25, 1.25)), "a hidden point is not drawn");
    assert!(grey(at(-1.5, 0.0)), "a point facing away is not drawn");
    // Off the dots: the solution in grey.
    assert!(grey(at(0.5, -1.5)));
}

#[test]
fn a_missing_python_environment_says_how_to_install_it() {
    let dir = tempfile::tempdir().unwrap();
    let context = Context {
        out: dir.path().to_path_buf(),
        quick: true,
        command: "test".into(),
        scenes: None,
        embree_python: None,
        reference: None,
        device: radiosity_gpu::DeviceChoice::Cpu,
    };
    let error = Harness::with_python(
        &context,
        Path::new("/somewhere/shared/reference"),
        Path::new("/nonexistent/refvenv/bin/python"),
    )
    .unwrap_err()
    .to_string();
    assert_eq!(
        error,
        "the reference harness needs its Python environment (/nonexistent/refvenv/bin/python \
         with pyradiance and numpy), which is missing: install it with `bash \
         /somewhere/shared/reference/setup.sh` (a few minutes, from PyPI)"
    );
    // And a harness folder that is not there names the option to give.
    let context = Context {
        reference: Some(dir.path().join("nothing")),
        ..context
    };
    let error = Harness::find(&context).unwrap_err().to_string();
    assert!(
        error.contains("is not in") && error.contains("--reference DIR"),
        "{error}"
    );
}

/// Every scene `validate` scores is written out and loads without a
/// warning, with light (its own emitters, or the lights and daylight its
/// case names); the rooms off a corridor are closed, so the ledger's
/// escaped light there is what the elements' estimate loses (a shot's
/// irradiance from its corners), under 2% of the emitted power at the
/// default.
#[test]
fn the_validate_scenes_load_and_the_suite_is_closed() {
    use radiosity::scene::{self, LoadOptions};
    use radiosity_experiments::validate::{SCENES, daylight, scene_file, solve_then};
    let dir = tempfile::tempdir().unwrap();
    let shared = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes");
    let context = Context {
        out: dir.path().to_path_buf(),
        quick: true,
        command: "test".into(),
        scenes: Some(shared),
        embree_python: None,
        reference: None,
        device: radiosity_gpu::DeviceChoice::Cpu,
    };
    for case in &SCENES {
        let path = scene_file(&context, case).unwrap();
        let loaded = scene::load_with(
            &path.to_string_lossy(),
            &LoadOptions {
                daylight: daylight(case.lights.unwrap_or("")).unwrap(),
                ..LoadOptions::default()
            },
        )
        .unwrap();
        let scene = loaded.scene;
        assert!(!scene.surfaces.is_empty(), "{}", case.name);
        let lit =
            scene.surfaces.iter().any(|s| s.emission != DVec3::ZERO) || !scene.lights.is_empty();
        assert!(lit, "{}: no light", case.name);
        if case.shared {
            continue;
        }
        assert!(
            scene.warnings.is_empty(),
            "{}: {:?}",
            case.name,
            scene.warnings
        );
    }
    let suite = SCENES.iter().find(|c| c.name == "suite").unwrap();
    let path = scene_file(&context, suite).unwrap();
    let settings = radiosity::solver::Preset::Adaptive.settings();
    let (_, energy) = solve_then(
        &path,
        daylight("").unwrap(),
        &settings,
        None,
        &[],
        |solver| *solver.energy(),
    )
    .unwrap();
    let escaped = radiosity::luminance(energy.escaped) / radiosity::luminance(energy.emitted);
    assert!((-0.02..0.02).contains(&escaped), "escaped {escaped}");
}
