//! Direct light from a square emitter onto a floor, against the closed-form
//! point-to-parallel-rectangle factor, and shadows cast by an occluder.

mod common;

use common::{quad, scene_of};
use glam::DVec3;
use radiosity::form_factor::closed_form;
use radiosity::mesh::{Mesh, MeshSettings};
use radiosity::scene::Scene;
use radiosity::solver::patches::PatchSettings;
use radiosity::solver::{Flow, Settings, Solver};

const HEIGHT: f64 = 1.0;
const SIDE: f64 = 0.5;
const RHO: f64 = 0.5;
const SUBSOURCES: u32 = 3;

/// A 4 x 4 m floor at y = 0 under a square emitter of side 0.5 m at
/// height 1 m facing down, plus `extra` surfaces.
fn scene(extra: Vec<radiosity::scene::Surface>) -> Scene {
    let mut surfaces = common::lamp_over_floor(RHO, SIDE, HEIGHT, 1.0);
    surfaces.extend(extra);
    scene_of(surfaces)
}

/// Radiosity after the emitter's one shot.
fn first_shot(scene: &Scene) -> (Mesh, Vec<DVec3>) {
    let settings = Settings {
        mesh: MeshSettings {
            patch_size: 4.0,
            element_size: 0.25,
            max_elements: 100_000,
            bisect_triangles: false,
            refine: Default::default(),
            conform: false,
        },
        method: PatchSettings {
            subsources: SUBSOURCES,
            ..PatchSettings::default()
        }
        .into(),
        max_shots: Some(1),
        ..Settings::wallace89()
    };
    let mesh = Mesh::build(scene, &settings.mesh).unwrap();
    let radiosity = {
        let mut solver = Solver::new(scene, &mesh, settings);
        solver.run(|_| Flow::Continue);
        solver.radiosity().to_vec()
    };
    (mesh, radiosity)
}

/// The exact factor from a floor point to the emitter.
fn exact(p: DVec3) -> f64 {
    let h = SIDE / 2.0;
    closed_form::parallel_rectangle(-h - p.x, h - p.x, -h - p.z, h - p.z, HEIGHT)
}

/// How far eq. (1) on 3 x 3 subsources may be from the exact factor at
/// height `h`, relative. Two effects, each to leading order in `s / h`
/// (`s` the subsource side):
///
/// * Sampling: the sum evaluates the kernel `f = h^2 / (pi (h^2 + rho^2)^2)`
///   once per subsource at its centre (midpoint rule), relative error
///   `(s^2 / 24) |lap f| / f`; here `lap f / f = (16 rho^2 - 8 h^2) /
///   (h^2 + rho^2)^2`, at most `8 / h^2` in magnitude, so at most
///   `s^2 / (3 h^2)`.
/// * The disk term: eq. (1) divides by `pi r^2 + A_k` instead of
///   `pi r^2`, a relative change of at most `A_k / (pi h^2) = s^2 / (pi h^2)`.
///
/// Together `s^2 / h^2 (1/3 + 1/pi)`; a factor 1.5 covers the higher-order
/// terms (fourth order in `s / h`).
fn eq1_tolerance() -> f64 {
    let s = SIDE / f64::from(SUBSOURCES);
    1.5 * (s * s) / (HEIGHT * HEIGHT) * (1.0 / 3.0 + 1.0 / std::f64::consts::PI)
}

#[test]
fn floor_vertices_match_the_closed_form_within_eq1_tolerance() {
    let scene = scene(Vec::new());
    let (mesh, radiosity) = first_shot(&scene);
    let tolerance = eq1_tolerance();
    let mut worst = 0.0f64;
    let mut checked = 0;
    for (v, b) in mesh.vertices.iter().zip(&radiosity) {
        if v.surface != 0 {
            continue;
        }
        let expected = RHO * exact(v.position);
        let error = (b.x - expected).abs() / expected;
        worst = worst.max(error);
        assert!(
            error < tolerance,
            "at {}: B = {}, exact {expected}, relative error {error} > {tolerance}",
            v.position,
            b.x
        );
        assert_eq!(b.x, b.y);
        checked += 1;
    }
    assert_eq!(checked, 17 * 17);
    eprintln!("eq. (1) direct light: worst relative error {worst:.5} (allowed {tolerance:.5})");
}

#[test]
fn an_occluder_casts_a_full_shadow_and_leaves_clear_points_lit() {
    // A 1 x 1 m board at half height, centred under the light.
    let board = quad(
        DVec3::new(-0.5, HEIGHT / 2.0, -0.5),
        DVec3::Z,
        DVec3::X,
        RHO,
        0.0,
        2,
    );
    let scene = scene(vec![board]);
    let (mesh, radiosity) = first_shot(&scene);
    let floor_value = |x: f64, z: f64| {
        let (v, b) = mesh
            .vertices
            .iter()
            .zip(&radiosity)
            .find(|(v, _)| v.surface == 0 && (v.position - DVec3::new(x, 0.0, z)).length() < 1e-9)
            .expect("a floor vertex there");
        (v.position, b.x)
    };
    // Under the board's centre every line to the light crosses the board:
    // no direct light at all.
    for (x, z) in [(0.0, 0.0), (0.25, 0.0), (-0.25, 0.25)] {
        let (_, b) = floor_value(x, z);
        assert_eq!(b, 0.0, "({x}, {z}) should be in full shadow");
    }
    // Far to the side every line to the light passes the board: full
    // direct light, as without the board.
    for (x, z) in [(1.75, 1.75), (-2.0, 1.5), (2.0, -2.0)] {
        let (p, b) = floor_value(x, z);
        let expected = RHO * exact(p);
        assert!(b > 0.0);
        assert!(
            (b - expected).abs() / expected < eq1_tolerance(),
            "({x}, {z}): {b} vs {expected}"
        );
    }
    // The board's top receives light; its vertices are not shadowed by the
    // board itself.
    let top = mesh
        .vertices
        .iter()
        .zip(&radiosity)
        .filter(|(v, _)| v.surface == 2)
        .all(|(_, b)| b.x > 0.0);
    assert!(top);
}
