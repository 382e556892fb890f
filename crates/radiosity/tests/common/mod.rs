//! Scenes built in code for the physics tests.

#![allow(dead_code)]

pub mod rng;
pub mod soup;

use std::path::{Path, PathBuf};

use glam::DVec3;
use radiosity::scene::{Light, LightKind, Scene, Surface};

/// The clone's root: two levels above the core crate (this file is shared
/// with the command's tests at the root, whose manifest folder is the
/// clone's root).
fn repository_root() -> PathBuf {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    if manifest.join("crates").is_dir() {
        manifest.to_path_buf()
    } else {
        manifest.join("../..")
    }
}

/// A file of the repository's test inputs, `tests/data/` at its root (the
/// glTF scenes, also read by tools/fuzz.sh and the web tests).
pub fn test_data(name: &str) -> PathBuf {
    repository_root().join("tests").join("data").join(name)
}

/// A file of the shared real scenes (`shared/scenes/`): beside the clone in
/// CI, two levels up from a worktree under `wt/`.
pub fn shared_scene(relative: &str) -> PathBuf {
    let root = repository_root();
    [
        root.join("../shared/scenes"),
        root.join("../../shared/scenes"),
    ]
    .into_iter()
    .map(|folder| folder.join(relative))
    .find(|p| p.exists())
    .unwrap_or_else(|| panic!("shared/scenes/{relative} is not beside the repository"))
}

/// A quad with corners `origin`, `origin + u`, `origin + u + v`,
/// `origin + v`; its front is `u x v`.
pub fn quad(origin: DVec3, u: DVec3, v: DVec3, rho: f64, emission: f64, face: u32) -> Surface {
    Surface::new(
        vec![origin, origin + u, origin + u + v, origin + v],
        DVec3::splat(rho),
        DVec3::splat(emission),
        face,
    )
    .expect("quad has area")
}

/// The 4 x 4 m floor of the light tests: centred on the origin in the
/// plane y = 0, facing up, reflectance `rho`, surface id 0.
pub fn floor(rho: f64) -> Surface {
    quad(
        DVec3::new(-2.0, 0.0, -2.0),
        DVec3::Z * 4.0,
        DVec3::X * 4.0,
        rho,
        0.0,
        0,
    )
}

/// A black square lamp of side `side` and exitance `exitance` facing down
/// at `height` above the origin, over the 4 x 4 m [`floor`] of reflectance
/// `rho` (surface ids: floor 0, lamp 1).
pub fn lamp_over_floor(rho: f64, side: f64, height: f64, exitance: f64) -> Vec<Surface> {
    let h = side / 2.0;
    let lamp = quad(
        DVec3::new(-h, height, -h),
        DVec3::X * side,
        DVec3::Z * side,
        0.0,
        exitance,
        1,
    );
    assert_eq!(lamp.normal, -DVec3::Y, "the lamp faces the floor");
    vec![floor(rho), lamp]
}

/// The six inward faces of the cube `[0, side]^3`, all with the same
/// reflectance and emission (the furnace).
pub fn furnace(side: f64, rho: f64, emission: f64) -> Scene {
    let (x, y, z) = (DVec3::X * side, DVec3::Y * side, DVec3::Z * side);
    let o = DVec3::ZERO;
    let faces = [
        (o, z, x), // floor, normal +y
        (y, x, z), // ceiling, normal -y
        (o, y, z), // x = 0 wall, normal +x
        (x, z, y), // x = side wall, normal -x
        (o, x, y), // z = 0 wall, normal +z
        (z, y, x), // z = side wall, normal -z
    ];
    let surfaces = faces
        .iter()
        .enumerate()
        .map(|(i, (origin, u, v))| quad(*origin, *u, *v, rho, emission, i as u32))
        .collect::<Vec<_>>();
    let centre = DVec3::splat(0.5 * side);
    for s in &surfaces {
        assert!(
            s.normal.dot(centre - s.polygon[0]) > 0.0,
            "faces point inwards"
        );
    }
    scene_of(surfaces)
}

/// A 1 x 1 m black board 1 m above a 6 x 6 m floor, a
/// parallel sun 60 degrees high from +x.
pub fn board_in_the_sun() -> Scene {
    let floor = quad(
        DVec3::new(-3.0, 0.0, -3.0),
        DVec3::Z * 6.0,
        DVec3::X * 6.0,
        0.5,
        0.0,
        0,
    );
    let board = quad(DVec3::new(-0.5, 1.0, -0.5), DVec3::Z, DVec3::X, 0.0, 0.0, 1);
    assert!(floor.normal.y > 0.99 && board.normal.y > 0.99);
    let mut scene = scene_of(vec![floor, board]);
    let elevation = 60f64.to_radians();
    scene.lights.push(Light {
        name: "sun".into(),
        kind: LightKind::Sun(radiosity::scene::light::Sun {
            direction: DVec3::new(-elevation.cos(), -elevation.sin(), 0.0),
        }),
        colour: DVec3::ONE,
        intensity: 100_000.0,
    });
    scene
}

/// A scene from surfaces.
pub fn scene_of(surfaces: Vec<Surface>) -> Scene {
    Scene {
        name: "test".into(),
        surfaces,
        lights: Vec::new(),
        panes: Vec::new(),
        portals: Vec::new(),
        camera: None,
        mesh_hint: None,
        warnings: Vec::new(),
    }
}

/// Solves `scene` with `settings`, gathering at `points` (on surfaces, with
/// their normals) too, and returns the irradiance there (W/m^2 per
/// channel), having checked that every light shot and that the ledger
/// balances ([`assert_ledger_balances`]).
pub fn sensor_irradiance(
    scene: &Scene,
    settings: radiosity::solver::Settings,
    points: &[(DVec3, DVec3)],
) -> Vec<DVec3> {
    let sensor_points: Vec<radiosity::sensors::SensorPoint> = points
        .iter()
        .enumerate()
        .map(|(i, &(position, normal))| radiosity::sensors::SensorPoint {
            position,
            normal,
            line: i + 1,
        })
        .collect();
    let receivers =
        radiosity::sensors::receivers(scene, &sensor_points, Path::new("points")).unwrap();
    let mesh = radiosity::mesh::Mesh::build(scene, &settings.mesh.sized_for(scene)).unwrap();
    let mut solver = radiosity::solver::Solver::with_sensors(scene, &mesh, settings, receivers);
    solver.run(|_| radiosity::solver::Flow::Continue);
    assert_eq!(solver.lights_pending(), 0);
    assert_ledger_balances(&solver);
    solver.sensor_irradiance().to_vec()
}

/// `emitted = unshot + absorbed + escaped`, per channel, to 1e-9.
pub fn assert_ledger_balances(solver: &radiosity::solver::Solver<'_>) {
    let e = solver.energy();
    let unshot = solver.unshot_power();
    for c in 0..3 {
        let rhs = unshot[c] + e.absorbed[c] + e.escaped[c];
        assert!(
            (e.emitted[c] - rhs).abs() <= 1e-9 * e.emitted[c].abs().max(1e-300),
            "channel {c}: emitted {} != unshot {} + absorbed {} + escaped {}",
            e.emitted[c],
            unshot[c],
            e.absorbed[c],
            e.escaped[c]
        );
    }
}

/// The final pass's points at `mesh`'s vertices, each seeded by its index.
pub fn vertex_points(mesh: &radiosity::mesh::Mesh) -> Vec<radiosity::final_gather::Point> {
    mesh.vertices
        .iter()
        .enumerate()
        .map(|(i, v)| radiosity::final_gather::Point {
            surface: v.surface,
            position: v.position,
            sample: None,
            seed: i as u64,
        })
        .collect()
}

/// The default settings with adaptive shooting's own changed by `change`,
/// solved to `converge`, on the base mesh (no refinement: two solves then
/// share their vertices).
pub fn adaptive_on_base_mesh(
    converge: f64,
    change: impl FnOnce(&mut radiosity::solver::adaptive::AdaptiveSettings),
) -> radiosity::solver::Settings {
    let mut settings = radiosity::solver::Settings::adaptive();
    let radiosity::solver::MethodSettings::Adaptive(adaptive) = &mut settings.method else {
        panic!("the default method is adaptive shooting");
    };
    change(adaptive);
    settings.converge = converge;
    settings.mesh.refine.refine_levels = 0;
    settings
}

/// `settings` with the mesh sizes `scene` suggests (its refinement kept).
pub fn sized_for(
    scene: &Scene,
    mut settings: radiosity::solver::Settings,
) -> radiosity::solver::Settings {
    settings.mesh = radiosity::mesh::MeshSettings {
        refine: settings.mesh.refine,
        ..settings.mesh.sized_for(scene)
    };
    settings
}

/// The L1 distance of `a` from `b` relative to `b`, over every channel.
pub fn l1(a: &[DVec3], b: &[DVec3]) -> f64 {
    let diff: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| (*x - *y).abs().element_sum())
        .sum();
    diff / b.iter().map(|y| y.abs().element_sum()).sum::<f64>()
}
