//! The default solver (adaptive shooting, src/solver/adaptive/) against
//! closed forms and brute force:
//!
//! * its book-keeping conserves energy exactly;
//! * the furnace, whose answer is 2 everywhere;
//! * direct light from a square emitter, against the closed-form factor;
//! * a wall lit from one end, whose radiosity varies across it: what a
//!   nearby floor receives from it, against a brute-force integral of the
//!   wall's exact radiosity (where one uniform radiosity per patch, the
//!   paper's shooting, errs by tens of per cent);
//! * answers that do not depend on the thread count.

mod common;

use approx::relative_eq;
use common::{quad, scene_of};
use glam::DVec3;
use radiosity::form_factor::{analytic, closed_form};
use radiosity::luminance;
use radiosity::mesh::{Mesh, MeshSettings};
use radiosity::scene::{self, Scene};
use radiosity::solver::{Flow, MethodSettings, Settings, Shooting, Solver};

/// The default settings with these mesh sizes, and the mesh they make.
fn adaptive(scene: &Scene, patch_size: f64, element_size: f64) -> (Settings, Mesh) {
    let settings = Settings {
        mesh: MeshSettings {
            patch_size,
            element_size,
            ..Settings::adaptive().mesh
        },
        ..Settings::adaptive()
    };
    let mesh = Mesh::build(scene, &settings.mesh).unwrap();
    (settings, mesh)
}

fn relative(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// After every shot (one shooter a round, and in the default's rounds),
/// per channel: emitted = unshot + absorbed + escaped,
/// to 1e-9 of the emitted power (the sums are of thousands of terms, each
/// exact to round-off). In the closed furnace almost nothing may escape:
/// what does is the difference between the exact transfer and its estimate
/// at the vertices, bounded here by 0.2% of the emitted power.
#[test]
fn energy_is_conserved_to_round_off() {
    let furnace = common::furnace(1.0, 0.5, 1.0);
    let cornell = scene::load("cornell").unwrap();
    let default_round = match Settings::adaptive().method {
        MethodSettings::Adaptive(a) => a.round,
        _ => unreachable!("the default method is adaptive shooting"),
    };
    for (name, scene, shots, closed, round) in [
        ("furnace", &furnace, 300, true, 1.0),
        ("cornell", &cornell, 200, false, 1.0),
        ("furnace in rounds", &furnace, 300, true, default_round),
        ("cornell in rounds", &cornell, 200, false, default_round),
    ] {
        let sizes = scene.default_mesh_sizes();
        let (settings, mesh) = if closed {
            adaptive(scene, 0.5, 0.125)
        } else {
            adaptive(scene, sizes.patch_size, sizes.element_size)
        };
        let mut settings = Settings {
            max_shots: Some(shots),
            converge: 1e-9,
            ..settings
        };
        if let MethodSettings::Adaptive(a) = &mut settings.method {
            a.round = round;
        }
        let mut solver = Solver::new(scene, &mesh, settings);
        let mut checked = 0;
        let reason = solver.run(|s| {
            let e = s.energy();
            let balance = s.unshot_power() + e.absorbed + e.escaped;
            for c in 0..3 {
                assert!(
                    relative_eq!(balance[c], e.emitted[c], epsilon = 0.0, max_relative = 1e-9),
                    "{name}, shot {}: {balance} against {}",
                    s.stats().shots,
                    e.emitted
                );
            }
            assert!((e.shot - e.received - e.escaped).abs().max_element() <= 1e-9 * e.emitted.x);
            checked += 1;
            Flow::Continue
        });
        // Checked after every round: one shooter each, or several.
        assert_eq!(checked, solver.stats().rounds, "{name}");
        assert_eq!(solver.stats().shots, shots, "{name}: {reason:?}");
        if round == 1.0 {
            assert!(checked > 50, "{name}: {checked} shots, {reason:?}");
        } else {
            assert!(
                checked > 3 && checked < shots / 4,
                "{name}: {checked} rounds"
            );
        }
        let e = solver.energy();
        if closed {
            assert!(
                e.escaped.x.abs() <= 2e-3 * e.emitted.x,
                "{name}: {}",
                e.escaped
            );
        } else {
            // The Cornell box is open at the front: much escapes.
            assert!(e.escaped.x > 0.05 * e.emitted.x, "{name}: {}", e.escaped);
        }
    }
}

/// The furnace: a closed cube, every face emitting 1 and reflecting 0.5, so
/// `B = 1 / (1 - 0.5) = 2` at every point. The elements' exact factors and
/// the corrected point sources (within 0.3% of exact beyond three radii,
/// tested in src/solver/hierarchy/sources.rs) bound the error at every vertex, edges
/// and corners included, by 0.5%; the mean is tighter.
#[test]
fn furnace_at_the_default_settings() {
    let scene = common::furnace(1.0, 0.5, 1.0);
    let (settings, mesh) = adaptive(&scene, 0.5, 0.125);
    let settings = Settings {
        converge: 1e-7,
        ..settings
    };
    let mut solver = Solver::new(&scene, &mesh, settings);
    solver.run(|_| Flow::Continue);
    let b: Vec<f64> = solver.radiosity().iter().map(|b| b.x).collect();
    let worst = b.iter().map(|x| relative(*x, 2.0)).fold(0.0, f64::max);
    let mean = b.iter().sum::<f64>() / b.len() as f64;
    assert!(worst < 5e-3, "worst {worst}");
    assert!(relative(mean, 2.0) < 1e-3, "mean {mean}");
}

/// A 4 x 4 m black floor 1 m under a 0.5 m square emitter facing down: the
/// first shot's irradiance at every floor vertex against the closed form of
/// a point under a parallel rectangle.
#[test]
fn direct_light_matches_the_closed_form() {
    let h = 0.25;
    let floor = common::floor(0.5);
    let light = quad(
        DVec3::new(-h, 1.0, -h),
        DVec3::X * 0.5,
        DVec3::Z * 0.5,
        0.0,
        1.0,
        1,
    );
    let scene = scene_of(vec![floor, light]);
    let (settings, mesh) = adaptive(&scene, 4.0, 0.2);
    let settings = Settings {
        max_shots: Some(1),
        ..settings
    };
    let mut solver = Solver::new(&scene, &mesh, settings);
    solver.run(|_| Flow::Continue);
    let mut worst: f64 = 0.0;
    for (v, e) in mesh.vertices.iter().zip(solver.irradiance()) {
        if v.surface != 0 {
            continue;
        }
        let p = v.position;
        let exact = closed_form::parallel_rectangle(-h - p.x, h - p.x, -h - p.z, h - p.z, 1.0);
        worst = worst.max((e.x - exact).abs() / exact.max(1e-3));
    }
    assert!(worst < 5e-3, "worst relative error {worst}");
}

/// A wall 4 m long, 2 m high, lit by a lamp near its left end, so its
/// radiosity falls by two orders of magnitude along it; a black floor in
/// front of it. The floor receives the lamp's direct light and the wall's
/// reflection. Brute force: the wall's exact radiosity at the centre of
/// each of 400 x 200 pieces (its reflectance times the lamp's analytic
/// factor) times each piece's analytic factor at the floor point, plus the
/// lamp's own. Nothing else reflects (floor and lamp are black), and no
/// surface comes between the wall and the floor points within 0.45 m of it
/// (the lamp hangs 0.5 m out), so that is the exact answer.
///
/// Adaptive shooting carries the wall's radiosity per element and refines
/// the wall near each receiver: within 1% at every near-field floor vertex.
/// The paper's shooting, the wall one patch of one uniform radiosity, gives
/// the floor near the lamp the wall's mean instead and errs by far more
/// there (checked, so the test can tell the two apart).
#[test]
fn a_radiosity_gradient_reaches_nearby_receivers() {
    let (length, height, rho) = (4.0, 2.0, 0.8);
    let wall = quad(
        DVec3::ZERO,
        DVec3::X * length,
        DVec3::Y * height,
        rho,
        0.0,
        0,
    );
    let floor = quad(DVec3::ZERO, DVec3::Z * 1.5, DVec3::X * length, 0.0, 0.0, 1);
    let lamp_corner = DVec3::new(0.1, 0.8, 0.5);
    let lamp = quad(lamp_corner, DVec3::Y * 0.4, DVec3::X * 0.4, 0.0, 200.0, 2);
    for (surface, normal) in [(&wall, DVec3::Z), (&floor, DVec3::Y), (&lamp, -DVec3::Z)] {
        assert!(surface.normal.distance(normal) < 1e-12);
    }
    let lamp_polygon = lamp.polygon.clone();
    let scene = scene_of(vec![wall, floor, lamp]);

    // Brute force, per floor point.
    let (nx, ny) = (400, 200);
    let (dx, dy) = (length / nx as f64, height / ny as f64);
    let mut pieces = Vec::with_capacity(nx * ny);
    for i in 0..nx {
        for j in 0..ny {
            let (x0, y0) = (i as f64 * dx, j as f64 * dy);
            let polygon = vec![
                DVec3::new(x0, y0, 0.0),
                DVec3::new(x0 + dx, y0, 0.0),
                DVec3::new(x0 + dx, y0 + dy, 0.0),
                DVec3::new(x0, y0 + dy, 0.0),
            ];
            let centre = DVec3::new(x0 + 0.5 * dx, y0 + 0.5 * dy, 0.0);
            let radiosity = rho * 200.0 * analytic(centre, DVec3::Z, &lamp_polygon);
            pieces.push((polygon, radiosity));
        }
    }
    let exact = |p: DVec3| -> f64 {
        let from_wall: f64 = pieces
            .iter()
            .map(|(polygon, b)| b * analytic(p, DVec3::Y, polygon))
            .sum();
        from_wall + 200.0 * analytic(p, DVec3::Y, &lamp_polygon)
    };

    let solve = |shooting: Shooting| {
        let mut settings = Settings {
            method: MethodSettings::default_for(shooting),
            converge: 1e-9,
            max_shots: Some(60),
            ..Settings::adaptive()
        };
        settings.mesh.patch_size = 10.0;
        settings.mesh.element_size = 0.1;
        let mesh = Mesh::build(&scene, &settings.mesh).unwrap();
        let mut solver = Solver::new(&scene, &mesh, settings);
        solver.run(|_| Flow::Continue);
        let floor: Vec<(DVec3, f64)> = mesh
            .vertices
            .iter()
            .zip(solver.irradiance())
            .filter(|(v, _)| v.surface == 1 && v.position.z > 0.0 && v.position.z <= 0.45)
            .map(|(v, e)| (v.position, e.x))
            .collect();
        floor
    };
    let adaptive_floor = solve(Shooting::Adaptive);
    let sampled: Vec<(DVec3, f64)> = adaptive_floor
        .iter()
        .filter(|(p, _)| (p.x * 2.0).fract().abs() < 1e-9)
        .map(|(p, _)| (*p, exact(*p)))
        .collect();
    let errors = |floor: &[(DVec3, f64)]| -> Vec<(DVec3, f64)> {
        sampled
            .iter()
            .map(|(p, reference)| {
                let (_, e) = floor
                    .iter()
                    .find(|(q, _)| q.distance(*p) < 1e-9)
                    .expect("both meshes have the point");
                (*p, relative(*e, *reference))
            })
            .collect()
    };
    let adaptive = errors(&adaptive_floor);
    assert!(adaptive.len() >= 20, "{} points", adaptive.len());
    for (p, error) in &adaptive {
        assert!(*error < 0.01, "adaptive shooting at {p}: {error}");
    }
    let uniform = errors(&solve(Shooting::Patches));
    let worst_uniform = uniform.iter().map(|(_, e)| *e).fold(0.0, f64::max);
    assert!(
        worst_uniform > 0.1,
        "uniform patch errs by only {worst_uniform}"
    );
}

/// The same answer, to the bit, with one and with three threads: every
/// receiver's sum is taken in a fixed order whatever the threads.
#[test]
fn the_thread_count_does_not_change_the_answer() {
    for name in ["cornell", "tworooms"] {
        let scene = scene::load(name).unwrap();
        let sizes = scene.default_mesh_sizes();
        let (settings, mesh) = adaptive(&scene, sizes.patch_size, sizes.element_size);
        let solve_with = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| {
                    let settings = Settings {
                        max_shots: Some(40),
                        ..settings.clone()
                    };
                    let mut solver = Solver::new(&scene, &mesh, settings);
                    solver.run(|_| Flow::Continue);
                    (solver.radiosity().to_vec(), solver.stats().rays_cast)
                })
        };
        let (one, rays_one) = solve_with(1);
        let (three, rays_three) = solve_with(3);
        assert_eq!(rays_one, rays_three, "{name}");
        assert!(one.iter().zip(&three).all(|(a, b)| a == b), "{name}");
        assert!(one.iter().map(|b| luminance(*b)).sum::<f64>() > 0.0);
    }
}
