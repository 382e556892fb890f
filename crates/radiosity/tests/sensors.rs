//! Values at sensor points, through the library: a sensor at a vertex
//! gets the vertex's value exactly; sensors under a square light get the
//! closed-form direct light; a point on no surface is refused with its
//! file, line and problem; values do not depend on the thread count. The
//! command's `--sensors` is tested in tests/sensors.rs at the root.

mod common;

use std::path::Path;

use approx::assert_relative_eq;
use common::{quad, scene_of};
use glam::DVec3;
use radiosity::form_factor::closed_form;
use radiosity::mesh::{Mesh, MeshSettings};
use radiosity::scene::{self, Scene};
use radiosity::sensors::{self, SensorPoint};
use radiosity::solver::adaptive::AdaptiveSettings;
use radiosity::solver::{Flow, MethodSettings, Settings, Shooting, Solver};

/// A closed 2 x 1.5 x 1.8 m box (floor, ceiling, four walls facing in)
/// with a 0.6 m square light 0.1 m below the ceiling, facing down: no two
/// surfaces facing the same way are within the placement tolerance of one
/// another, so a point at a vertex is placed on the vertex's own surface.
fn lit_box() -> Scene {
    let (w, h, d) = (2.0, 1.5, 1.8);
    let (x, y, z) = (DVec3::X * w, DVec3::Y * h, DVec3::Z * d);
    let o = DVec3::ZERO;
    let mut surfaces = vec![
        quad(o, z, x, 0.7, 0.0, 0),  // floor
        quad(y, x, z, 0.6, 0.0, 1),  // ceiling
        quad(o, y, z, 0.5, 0.0, 2),  // x = 0
        quad(x, z, y, 0.4, 0.0, 3),  // x = w
        quad(o, x, y, 0.65, 0.0, 4), // z = 0
        quad(z, y, x, 0.55, 0.0, 5), // z = d
    ];
    surfaces.push(quad(
        DVec3::new(0.7, h - 0.1, 0.6),
        DVec3::X * 0.6,
        DVec3::Z * 0.6,
        0.0,
        20.0,
        6,
    ));
    scene_of(surfaces)
}

fn box_mesh(scene: &Scene, settings: &Settings) -> Mesh {
    Mesh::build(
        scene,
        &MeshSettings {
            patch_size: 0.6,
            element_size: 0.2,
            ..settings.mesh
        },
    )
    .unwrap()
}

/// A sensor at every vertex, with the vertex's normal.
fn vertex_points(mesh: &Mesh) -> Vec<SensorPoint> {
    mesh.vertices
        .iter()
        .enumerate()
        .map(|(i, v)| SensorPoint {
            position: v.position,
            normal: v.normal,
            line: i + 1,
        })
        .collect()
}

/// Patch shooting gathers each receiver on its own: a sensor at a vertex
/// (the same gathering point, normal and surface) gets the same sums, bit
/// for bit. Adaptive shooting shares links among neighbouring receivers
/// (its receiver tree), so a sensor beside a vertex may be linked
/// differently and the two agree only as far as the solver is accurate: at
/// the default tolerance (1e-3) they differed by up to 0.46% (a ceiling
/// point beside the light's shadow), at 1e-5 by at most 6e-5 (converged to
/// 1e-4); the test asks 1e-5 for agreement within 1e-3.
#[test]
fn sensors_at_vertices_get_the_vertex_values() {
    let scene = lit_box();
    for settings in [
        Settings::wong_tsang93(),
        Settings::wallace89(),
        Settings::adaptive(),
    ] {
        let exact = settings.method.shooting() == Shooting::Patches;
        let settings = Settings {
            converge: 0.02,
            method: if exact {
                settings.method.clone()
            } else {
                AdaptiveSettings {
                    tolerance: 1e-5,
                    ..AdaptiveSettings::default()
                }
                .into()
            },
            ..settings
        };
        let mesh = box_mesh(&scene, &settings);
        let points = vertex_points(&mesh);
        let receivers = sensors::receivers(&scene, &points, Path::new("p.txt")).unwrap();
        for (r, v) in receivers.iter().zip(&mesh.vertices) {
            assert_eq!(r.surface, v.surface, "placed on another surface");
        }
        let mut solver = Solver::with_sensors(&scene, &mesh, settings.clone(), receivers.clone());
        solver.run(|_| Flow::Continue);
        assert!(solver.stats().shots > 3);
        let vertex_e = solver.irradiance();
        let sensor_e = solver.sensor_irradiance();
        assert_eq!(sensor_e.len(), mesh.vertices.len());
        let mut worst = 0.0f64;
        for i in 0..mesh.vertices.len() {
            let difference =
                (sensor_e[i] - vertex_e[i]).abs().max_element() / vertex_e[i].max_element();
            worst = worst.max(difference);
            if exact {
                assert_eq!(
                    sensor_e[i],
                    vertex_e[i],
                    "vertex {i}, {:?}",
                    settings.method.shooting()
                );
                // B = Ke + Kd E at once, against the vertex's B accumulated
                // shot by shot: equal to round-off.
                let b = sensors::radiosity(&scene, &receivers[i], sensor_e[i]);
                let vb = solver.radiosity()[i];
                assert!(
                    (b - vb).abs().max_element() <= 1e-12 * vb.max_element().max(1e-300),
                    "vertex {i}: {b} vs {vb}"
                );
            } else {
                assert!(
                    difference <= 1e-3,
                    "vertex {i}: {} vs {}",
                    sensor_e[i],
                    vertex_e[i]
                );
            }
        }
        assert!(sensor_e.iter().all(|e| e.max_element() > 0.0));
        eprintln!(
            "{:?}: worst relative difference sensor - vertex {worst:.2e}",
            settings.method.shooting()
        );
    }
}

const HEIGHT: f64 = 1.0;
const SIDE: f64 = 0.5;
const EXITANCE: f64 = 3.0;

/// A 4 x 4 m floor (reflectance 0.5) under a square light of side 0.5 m at
/// height 1 m facing down. Nothing the floor reflects comes back to it, so
/// its irradiance is the light's direct light alone.
fn square_light() -> Scene {
    let floor = common::floor(0.5);
    let h = SIDE / 2.0;
    let light = quad(
        DVec3::new(-h, HEIGHT, -h),
        DVec3::X * SIDE,
        DVec3::Z * SIDE,
        0.0,
        EXITANCE,
        1,
    );
    scene_of(vec![floor, light])
}

/// Floor points that are not vertices of the mesh (off the element grid).
fn floor_points() -> Vec<SensorPoint> {
    let mut points = Vec::new();
    for i in 0..9 {
        for j in 0..7 {
            points.push(SensorPoint {
                position: DVec3::new(
                    -1.93 + 0.43 * f64::from(i),
                    0.0,
                    -1.61 + 0.47 * f64::from(j),
                ),
                normal: DVec3::Y,
                line: points.len() + 1,
            });
        }
    }
    points
}

#[test]
fn sensors_under_a_square_light_get_the_closed_form() {
    let scene = square_light();
    let points = floor_points();
    for settings in [Settings::adaptive(), Settings::wong_tsang93()] {
        let mesh = Mesh::build(
            &scene,
            &MeshSettings {
                patch_size: 4.0,
                element_size: 0.5,
                ..settings.mesh
            },
        )
        .unwrap();
        let receivers = sensors::receivers(&scene, &points, Path::new("p.txt")).unwrap();
        let mut solver = Solver::with_sensors(&scene, &mesh, settings.clone(), receivers.clone());
        solver.run(|_| Flow::Continue);
        let mut worst = 0.0f64;
        for ((p, r), e) in points
            .iter()
            .zip(&receivers)
            .zip(solver.sensor_irradiance())
        {
            let h = SIDE / 2.0;
            // At the gathering point: the given one nudged a millionth of
            // the way to the floor's centre.
            let x = r.point;
            assert!(x.distance(p.position) <= 1e-6 * p.position.length() * (1.0 + 1e-9));
            let exact = EXITANCE
                * closed_form::parallel_rectangle(-h - x.x, h - x.x, -h - x.z, h - x.z, HEIGHT);
            let error = (e.x - exact).abs() / exact;
            worst = worst.max(error);
            // Patches: the analytic factor of every unoccluded subsource is
            // exact. Adaptive: a far part of the source may be taken as a
            // corrected point source, within the tolerance.
            let allowed = match &settings.method {
                MethodSettings::Patches(_) => 1e-9,
                MethodSettings::Adaptive(a) => a.tolerance,
                MethodSettings::Cuts(c) => c.error,
            };
            assert!(
                error < allowed,
                "{:?} at {x}: E = {}, exact {exact}",
                settings.method.shooting(),
                e.x
            );
            assert_eq!(e.x, e.z);
            let b = sensors::radiosity(&scene, r, *e);
            assert_eq!(b, 0.5 * *e);
            // White light: lux = 179 E.
            assert_relative_eq!(
                sensors::lux(*e),
                179.0 * e.x,
                epsilon = 0.0,
                max_relative = 1e-12
            );
        }
        eprintln!(
            "{:?}: worst relative error {worst:.2e}",
            settings.method.shooting()
        );
    }
}

#[test]
fn a_point_on_no_surface_is_an_error_naming_its_line() {
    let scene = square_light();
    let mut points = floor_points();
    let error = |points: &[SensorPoint]| {
        sensors::receivers(&scene, points, Path::new("grid.txt"))
            .unwrap_err()
            .to_string()
    };
    points[5].position = DVec3::new(-1.5, 0.2, 0.5);
    points[5].line = 17;
    assert_eq!(
        error(&points),
        "grid.txt:17: the point (-1.5, 0.2, 0.5) lies on no surface facing along its normal \
         (0.000, 1.000, 0.000): the nearest surface facing that way is 20.0 cm away, and a \
         point must lie within 0.57 mm of its surface"
    );
    points[5].position.y = 0.0;
    points[7].position = DVec3::new(-1.5, 0.0, -1.6);
    points[7].normal = -DVec3::Y;
    points[7].line = 30;
    assert_eq!(
        error(&points),
        "grid.txt:30: the point (-1.5, 0, -1.6) lies on no surface facing along its normal \
         (0.000, -1.000, 0.000): the nearest surface facing that way is 2.094 m away, and a \
         point must lie within 0.57 mm of its surface; it lies on a surface facing (0.000, \
         1.000, 0.000): give the normal of the side to measure"
    );
    points[7].normal = DVec3::X;
    assert_eq!(
        error(&points),
        "grid.txt:30: the point (-1.5, 0, -1.6) lies on no surface facing along its normal \
         (1.000, 0.000, 0.000): no surface of the scene faces that way; it lies on a surface \
         facing (0.000, 1.000, 0.000): give the normal of the side to measure"
    );
    // Within the tolerance of the surface, and just outside its edge: placed.
    points[7].normal = DVec3::Y;
    points[7].position = DVec3::new(2.0003, 0.0004, 0.3);
    let receivers = sensors::receivers(&scene, &points, Path::new("grid.txt")).unwrap();
    assert_eq!(receivers[7].surface, 0);
    assert!(receivers[7].point.distance(DVec3::new(2.0, 0.0, 0.3)) < 1e-5);
    assert_eq!(receivers[7].point.y, 0.0);
}

#[test]
fn sensor_values_do_not_depend_on_the_thread_count() {
    let scene = scene::load("cornell").unwrap();
    let mut scene = scene;
    scene::merge::merge_coplanar(&mut scene.surfaces);
    // A grid on the floor (y = 0) and on the back wall (z = 0.5592 facing -z).
    let mut points = Vec::new();
    for i in 1..12 {
        for j in 1..12 {
            let (u, v) = (0.045 * f64::from(i), 0.045 * f64::from(j));
            points.push(SensorPoint {
                position: DVec3::new(u, 0.0, v),
                normal: DVec3::Y,
                line: points.len() + 1,
            });
            points.push(SensorPoint {
                position: DVec3::new(u, v, 0.5592),
                normal: -DVec3::Z,
                line: points.len() + 1,
            });
        }
    }
    let settings = Settings {
        converge: 0.05,
        ..Settings::adaptive()
    };
    let mesh = Mesh::build(&scene, &settings.mesh.sized_for(&scene)).unwrap();
    let solve = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let receivers = sensors::receivers(&scene, &points, Path::new("p.txt")).unwrap();
                let mut solver = Solver::with_sensors(&scene, &mesh, settings.clone(), receivers);
                solver.run(|_| Flow::Continue);
                solver.sensor_irradiance().to_vec()
            })
    };
    let one = solve(1);
    let two = solve(2);
    let three = solve(3);
    assert_eq!(one, two);
    assert_eq!(one, three);
    // Points under the blocks are dark; the rest are lit.
    let lit = one.iter().filter(|e| e.max_element() > 0.0).count();
    assert!(lit > one.len() * 3 / 4, "{lit} of {} lit", one.len());
}
