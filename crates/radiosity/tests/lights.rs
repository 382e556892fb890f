//! Point, spot and sun lights against their closed forms at sensor points:
//! the inverse-square cosine law, the spot's cones, the sun's sharp
//! shadow; the energy ledger with lights; a scene lit by lights alone; the
//! `#@light` directive as the OBJ reader takes it.

mod common;

use std::path::Path;

use approx::assert_relative_eq;
use glam::DVec3;
use radiosity::final_gather::{FinalGather, FinalPass};
use radiosity::mesh::Mesh;
use radiosity::scene::light::cone;
use radiosity::scene::sky::{self, Daylight, SkyModel, SkySpec, SunSpec};
use radiosity::scene::{Light, LightKind, Scene, obj};
use radiosity::sensors::lux;
use radiosity::solver::{Preset, Settings, Solver};

use common::{assert_ledger_balances, floor, furnace, quad, scene_of};

/// The lux at each of `points` (on surfaces, with their normals) once
/// `scene` is solved with `settings` ([`common::sensor_irradiance`]).
fn lux_at(scene: &Scene, settings: Settings, points: &[(DVec3, DVec3)]) -> Vec<f64> {
    common::sensor_irradiance(scene, settings, points)
        .into_iter()
        .map(lux)
        .collect()
}

fn with_lights(surfaces: Vec<radiosity::scene::Surface>, lights: Vec<Light>) -> Scene {
    let mut scene = scene_of(surfaces);
    scene.lights = lights;
    scene
}

fn point_light(position: DVec3, candela: f64) -> Light {
    Light {
        name: "test point".into(),
        kind: LightKind::Point(radiosity::scene::light::Point { position }),
        colour: DVec3::ONE,
        intensity: candela,
    }
}

/// Points of the 4 x 4 m floor (y = 0), facing up.
fn floor_points() -> Vec<(DVec3, DVec3)> {
    let mut points = Vec::new();
    for i in 0..7 {
        for j in 0..7 {
            let x = -1.8 + 0.6 * f64::from(i);
            let z = -1.8 + 0.6 * f64::from(j);
            points.push((DVec3::new(x, 0.0, z), DVec3::Y));
        }
    }
    points
}

#[test]
fn a_point_light_gives_candela_times_cosine_over_distance_squared_in_lux() {
    let light_at = DVec3::new(0.3, 2.0, -0.2);
    let candela = 150.0;
    // One floor: nothing it reflects comes back, so the sensors see the
    // light alone.
    let scene = with_lights(vec![floor(0.5)], vec![point_light(light_at, candela)]);
    let points = floor_points();
    for preset in [Preset::Adaptive, Preset::WongTsang93, Preset::Wallace89] {
        let got = lux_at(&scene, preset.settings(), &points);
        for (&(p, _), lux) in points.iter().zip(got) {
            let d = light_at - p;
            let expected = candela * d.y / d.length().powi(3);
            assert_relative_eq!(lux, expected, max_relative = 1e-5);
        }
    }
}

#[test]
fn a_coloured_light_scales_by_its_colours_luminance() {
    let mut light = point_light(DVec3::new(0.0, 2.0, 0.0), 100.0);
    light.colour = DVec3::new(1.0, 0.5, 0.0);
    let scene = with_lights(vec![floor(0.5)], vec![light]);
    let got = lux_at(&scene, Settings::adaptive(), &[(DVec3::ZERO, DVec3::Y)]);
    let luminance = 0.265 + 0.670 * 0.5;
    assert_relative_eq!(got[0], 100.0 / 4.0 * luminance, max_relative = 1e-5);
}

#[test]
fn a_spot_is_full_inside_its_inner_cone_and_dark_outside_its_outer() {
    let (inner, outer) = cone(20.0, 35.0).unwrap();
    let height = 2.0;
    let spot = Light {
        name: "test spot".into(),
        kind: LightKind::Spot(radiosity::scene::light::Spot {
            position: DVec3::new(0.0, height, 0.0),
            direction: -DVec3::Y,
            inner,
            outer,
        }),
        colour: DVec3::ONE,
        intensity: 400.0,
    };
    let scene = with_lights(vec![floor(0.5)], vec![spot]);
    let at_angle = |degrees: f64| DVec3::new(height * degrees.to_radians().tan(), 0.0, 0.0);
    let angles = [0.0, 10.0, 19.0, 25.0, 30.0, 36.0, 45.0];
    let points: Vec<_> = angles.iter().map(|&a| (at_angle(a), DVec3::Y)).collect();
    let got = lux_at(&scene, Settings::adaptive(), &points);
    let (ci, co) = (inner.cos(), outer.cos());
    for (&a, lux) in angles.iter().zip(got) {
        let c = a.to_radians().cos();
        let d = height / c;
        let falloff = if a <= 20.0 {
            1.0
        } else if a >= 35.0 {
            0.0
        } else {
            ((c - co) / (ci - co)).powi(2)
        };
        let expected = 400.0 * falloff * c / (d * d);
        if falloff == 0.0 {
            assert_eq!(lux, 0.0, "{a} degrees, outside the outer cone");
        } else {
            assert_relative_eq!(lux, expected, max_relative = 1e-5);
        }
    }
}

#[test]
fn the_sun_casts_a_sharp_shadow() {
    // A 1 m square 1 m above the floor, facing up (its light goes up and
    // never reaches the floor); the sun from above, slanted.
    let blocker = quad(DVec3::new(-0.5, 1.0, -0.5), DVec3::Z, DVec3::X, 0.5, 0.0, 1);
    assert_eq!(blocker.normal, DVec3::Y);
    let direction = DVec3::new(0.37, -1.0, 0.13).normalize();
    let illuminance = 50_000.0;
    let sun = Light {
        name: "test sun".into(),
        kind: LightKind::Sun(radiosity::scene::light::Sun { direction }),
        colour: DVec3::ONE,
        intensity: illuminance,
    };
    let scene = with_lights(vec![floor(0.5), blocker], vec![sun]);
    // The shadow is the square moved 1 m along the light's direction, per
    // metre of height dropped.
    let shift = DVec3::new(direction.x, 0.0, direction.z) / -direction.y;
    let in_shadow = |p: DVec3| {
        let q = p - shift;
        q.x.abs() < 0.5 && q.z.abs() < 0.5
    };
    // Distance to the shadow's outline.
    let margin = |p: DVec3| {
        let q = p - shift;
        let (dx, dz) = (q.x.abs() - 0.5, q.z.abs() - 0.5);
        if dx < 0.0 && dz < 0.0 {
            (-dx).min(-dz)
        } else {
            DVec3::new(dx.max(0.0), 0.0, dz.max(0.0)).length()
        }
    };
    let mut points = floor_points();
    points.push((shift, DVec3::Y));
    points.push((shift + DVec3::new(0.45, 0.0, 0.0), DVec3::Y));
    points.push((shift + DVec3::new(0.55, 0.0, 0.0), DVec3::Y));
    let got = lux_at(&scene, Settings::adaptive(), &points);
    let (mut shadowed, mut lit) = (0, 0);
    for (&(p, _), lux) in points.iter().zip(got) {
        assert!(margin(p) > 0.02, "{p} is too near the shadow's edge");
        if in_shadow(p) {
            shadowed += 1;
            assert_eq!(lux, 0.0, "{p} is in the shadow");
        } else {
            lit += 1;
            assert_relative_eq!(lux, illuminance * -direction.y, max_relative = 1e-9);
        }
    }
    assert!(shadowed >= 3 && lit >= 40, "{shadowed} shadowed, {lit} lit");
}

#[test]
fn a_point_light_in_a_closed_box_sends_all_its_flux_to_the_walls() {
    let side = 2.0;
    let rho = 0.5;
    let mut scene = furnace(side, rho, 0.0);
    scene.lights = vec![point_light(DVec3::new(0.9, 1.2, 1.0), 300.0)];
    let flux = scene.lights[0].flux().unwrap();
    let settings = Settings {
        converge: 1e-3,
        ..Settings::adaptive()
    };
    let mesh = Mesh::build(&scene, &settings.mesh.sized_for(&scene)).unwrap();
    let mut solver = Solver::new(&scene, &mesh, settings);
    solver.run(|_| radiosity::solver::Flow::Continue);
    assert_ledger_balances(&solver);
    let energy = solver.energy();
    assert_relative_eq!(energy.emitted.x, flux.x, max_relative = 1e-12);
    // Closed: what escapes is only the vertices' estimate of the incident
    // power missing the exact flux.
    assert!(
        energy.escaped.x.abs() < 0.01 * flux.x,
        "escaped {} of {}",
        energy.escaped.x,
        flux.x
    );
    // Every watt is absorbed in the end: (1 - rho) of the walls' total
    // incident power, so the power reflected is rho / (1 - rho) times the
    // flux (the closed form of an enclosure of one reflectance).
    let absorbed = energy.absorbed.x + solver.unshot_power().x;
    assert_relative_eq!(absorbed, flux.x, max_relative = 0.01);
}

#[test]
fn a_scene_lit_only_by_the_sun_is_solved() {
    let sun = Light {
        name: "sun".into(),
        kind: LightKind::Sun(radiosity::scene::light::Sun {
            direction: -DVec3::Y,
        }),
        colour: DVec3::ONE,
        intensity: 1000.0,
    };
    // An open box (no ceiling): the sun lights the floor, which lights the
    // walls.
    let mut scene = furnace(1.0, 0.6, 0.0);
    scene.surfaces.remove(1);
    scene.lights = vec![sun];
    let settings = Settings::adaptive();
    let mesh = Mesh::build(&scene, &settings.mesh.sized_for(&scene)).unwrap();
    let mut solver = Solver::new(&scene, &mesh, settings);
    assert_eq!(solver.energy().emitted, DVec3::ZERO);
    assert!(solver.stop_reason().is_none(), "the sun is still to shoot");
    let reason = solver.run(|_| radiosity::solver::Flow::Continue);
    assert_eq!(reason, radiosity::solver::StopReason::Converged);
    assert_ledger_balances(&solver);
    // The floor's 1 m^2 receives 1000 lux straight down: 1000 / 179 W.
    assert_relative_eq!(
        solver.energy().emitted.x,
        1000.0 / 179.0,
        max_relative = 1e-9
    );
    assert!(solver.radiosity().iter().all(|b| b.x >= 0.0));
}

#[test]
fn the_obj_reader_takes_light_directives_and_names_bad_ones() {
    let resolve = &mut |_: &str| -> Result<(std::path::PathBuf, String), _> {
        Ok(("m.mtl".into(), "newmtl grey\nKd 0.5 0.5 0.5\n".to_string()))
    };
    let body = "mtllib m.mtl\nusemtl grey\nv 0 0 0\nv 0 0 1\nv 1 0 1\nv 1 0 0\nf 1 2 3 4\n";
    let text = format!(
        "#@light point 0 2 0 100\n#@light spot 0 3 0 0 -1 0 50 10 20 1 0.8 0.6\n\
         #@light sun 0 -1 0 20000\n{body}"
    );
    let scene = obj::parse("t", Path::new("t.obj"), &text, resolve).unwrap();
    assert_eq!(scene.lights.len(), 3);
    assert_eq!(scene.lights[0].name, "#@light at line 1");
    assert_eq!(scene.lights[1].colour, DVec3::new(1.0, 0.8, 0.6));
    // Lit by lights alone: no emitter needed.
    assert!(!scene.surfaces.iter().any(|s| s.is_emitter()));
    let bad = format!("{body}#@light spot 0 3 0 0 -1 0 50 30 20\n");
    let error = obj::parse("t", Path::new("t.obj"), &bad, resolve)
        .unwrap_err()
        .to_string();
    assert!(
        error.starts_with("t.obj:8: bad #@light directive:") && error.contains("inner 30"),
        "{error}"
    );
    // A scene with neither emitters nor lights is refused when loaded.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("m.mtl"), "newmtl grey\nKd 0.5 0.5 0.5\n").unwrap();
    std::fs::write(dir.path().join("dark.obj"), body).unwrap();
    let dark = dir.path().join("dark.obj");
    let error = radiosity::scene::load(dark.to_str().unwrap())
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("dark.obj: the scene has no emitter")
            && error.contains("no #@light directive")
            && error.contains("--sun, --sky"),
        "{error}"
    );
    // Daylight from the options lights it.
    let options = radiosity::scene::LoadOptions {
        daylight: Daylight {
            sun: Some(SunSpec {
                altitude: 40.0,
                azimuth: 180.0,
                illuminance: 50_000.0,
            }),
            sky: None,
        },
        ..Default::default()
    };
    let scene = radiosity::scene::load_with(dark.to_str().unwrap(), &options)
        .unwrap()
        .scene;
    assert_eq!(scene.lights.len(), 1);
    // Due south, 40 degrees up: the light travels north (-z) and down.
    let LightKind::Sun(radiosity::scene::light::Sun { direction }) = scene.lights[0].kind else {
        panic!("{:?}", scene.lights[0].kind)
    };
    let expected = -DVec3::new(0.0, 40f64.to_radians().sin(), 40f64.to_radians().cos());
    assert!((direction - expected).length() < 1e-12, "{direction}");
}

/// A quadrant-symmetric downlight: 0-90 degrees from the nadir, C0 and
/// C90 differing, multiplier 2.
const DOWNLIGHT: &str = "IESNA:LM-63-2002\n[TEST] test downlight\nTILT=NONE\n\
    1 -1 2 3 2 1 2 0.1 0.1 0\n1 1 20\n0 45 90\n0 90\n\
    100 60 0\n200 80 0\n";

/// Loads OBJ `text` whose library `m.mtl` is grey and whose other files
/// come from `files`.
fn load_with_files(text: &str, files: &[(&str, &str)]) -> Result<Scene, String> {
    let files: Vec<(String, String)> = files
        .iter()
        .map(|(n, t)| (n.to_string(), t.to_string()))
        .collect();
    obj::parse_bytes(
        "t",
        Path::new("t.obj"),
        text.as_bytes(),
        &radiosity::scene::Limits::default(),
        &mut |name: &str| {
            if name == "m.mtl" {
                return Ok(("m.mtl".into(), b"newmtl grey\nKd 0.5 0.5 0.5\n".to_vec()));
            }
            files
                .iter()
                .find(|(n, _)| n == name)
                .map(|(n, t)| (n.into(), t.as_bytes().to_vec()))
                .ok_or_else(|| radiosity::scene::SceneError::Io {
                    location: radiosity::scene::Location::file(Path::new(name)),
                    source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
                })
        },
    )
    .map_err(|e| e.to_string())
}

const FLOOR_OBJ: &str = "mtllib m.mtl\nusemtl grey\nv -2 0 -2\nv -2 0 2\nv 2 0 2\nv 2 0 -2\n\
    f 1 2 3 4\n";

#[test]
fn an_ies_luminaire_gives_its_tabulated_candela_at_the_sensors() {
    let text = format!("#@light ies lamp.ies 0 2 0\n{FLOOR_OBJ}");
    let scene = load_with_files(&text, &[("lamp.ies", DOWNLIGHT)]).unwrap();
    assert_eq!(scene.lights.len(), 1);
    // Straight below: 200 cd (100 x 2) at 2 m: 50 lux. At 45 degrees
    // along +x (C0): 120 cd; along -z (C90): 160 cd; d^2 = 8, cos = 1/sqrt 2.
    let points = [
        (DVec3::ZERO, DVec3::Y),
        (DVec3::new(2.0, 0.0, 0.0) * 0.999_999, DVec3::Y),
        (DVec3::new(0.0, 0.0, -2.0) * 0.999_999, DVec3::Y),
        (DVec3::new(1.0, 0.0, 0.0), DVec3::Y),
    ];
    let got = lux_at(&scene, Settings::adaptive(), &points);
    let c45 = std::f64::consts::FRAC_1_SQRT_2;
    assert_relative_eq!(got[0], 50.0, max_relative = 1e-5);
    assert_relative_eq!(got[1], 120.0 * c45 / 8.0, max_relative = 1e-4);
    assert_relative_eq!(got[2], 160.0 * c45 / 8.0, max_relative = 1e-4);
    // Between the tabulated angles: bilinear in the vertical angle.
    let gamma = 0.5f64.atan().to_degrees();
    let candela = 200.0 + (120.0 - 200.0) * gamma / 45.0;
    let cos = 2.0 / 5f64.sqrt();
    assert_relative_eq!(got[3], candela * cos / 5.0, max_relative = 1e-4);
    // The flux the ledger counts is the profile's integral.
    let flux = scene.lights[0].flux().unwrap().x * 179.0;
    assert!(
        flux > 0.0 && flux < 2.0 * std::f64::consts::PI * 200.0,
        "{flux}"
    );
}

#[test]
fn ies_directives_name_the_file_and_its_problem() {
    let cases = [
        (
            "#@light ies missing.ies 0 2 0\n",
            "t.obj:1: bad #@light directive: cannot read 'missing.ies'",
        ),
        ("#@light ies\n", "'ies' needs a file name"),
        (
            "#@light ies lamp.ies 0 2\n",
            "2 numbers after the file name",
        ),
        (
            "#@light ies lamp.ies 0 2 0 0 0 0\n",
            "direction has no length",
        ),
        ("#@light ies lamp.ies 0 2 0 -1\n", "intensity -1"),
        (
            "#@light ies bad.ies 0 2 0\n",
            "t.obj:1: bad #@light directive: bad.ies:2: photometric type 2",
        ),
    ];
    let bad = "TILT=NONE\n1 -1 1 2 1 2 2 0 0 0\n1 1 0\n0 90\n0\n1 1\n";
    for (directive, says) in cases {
        let text = format!("{directive}{FLOOR_OBJ}");
        let error =
            load_with_files(&text, &[("lamp.ies", DOWNLIGHT), ("bad.ies", bad)]).unwrap_err();
        assert!(error.contains(says), "{directive}: {error}");
    }
}

/// The sky lights of a spec.
fn sky_lights(
    model: SkyModel,
    illuminance: f64,
    subdivision: usize,
    sun: Option<SunSpec>,
) -> Vec<Light> {
    Daylight {
        sun,
        sky: Some(SkySpec {
            model,
            illuminance,
            subdivision,
            ground_reflectance: sky::DEFAULT_GROUND_REFLECTANCE,
        }),
    }
    .lights()
    .unwrap()
}

#[test]
fn an_open_floor_under_a_sky_receives_its_horizontal_illuminance() {
    let sun = Some(SunSpec {
        altitude: 30.0,
        azimuth: 120.0,
        illuminance: 0.0,
    });
    // The clear sky's bright circumsolar region needs finer patches for
    // the same noise.
    for (model, sun, subdivision) in [
        (SkyModel::Uniform, None, 2),
        (SkyModel::Overcast, None, 2),
        (SkyModel::Clear, sun, 6),
    ] {
        let mut lights = sky_lights(model, 10_000.0, subdivision, sun);
        // The sun of no illuminance only places the clear sky's peak.
        lights.retain(|l| matches!(l.kind, LightKind::Sky(_)));
        let scene = with_lights(vec![floor(0.5)], lights);
        let points = floor_points();
        let got = lux_at(&scene, Settings::adaptive(), &points);
        for lux in got {
            assert!((lux / 10_000.0 - 1.0).abs() < 0.01, "{model:?}: {lux} lux");
        }
    }
}

/// A closed 4 x 3 x 4 m room whose ceiling has a 1 x 1 m opening over
/// [1.5, 2.5]^2, every surface of reflectance `rho`.
fn skylight_room(rho: f64) -> Vec<radiosity::scene::Surface> {
    let (w, h) = (4.0, 3.0);
    let wall = |origin: DVec3, u: DVec3, v: DVec3, id: u32| quad(origin, u, v, rho, 0.0, id);
    let mut surfaces = vec![
        wall(DVec3::ZERO, DVec3::Z * w, DVec3::X * w, 0),
        wall(DVec3::ZERO, DVec3::Y * h, DVec3::Z * w, 1),
        wall(DVec3::X * w, DVec3::Z * w, DVec3::Y * h, 2),
        wall(DVec3::ZERO, DVec3::X * w, DVec3::Y * h, 3),
        wall(DVec3::Z * w, DVec3::Y * h, DVec3::X * w, 4),
    ];
    // The ceiling (facing down) around the opening [1.5, 2.5]^2.
    let ceiling = |x0: f64, z0: f64, x1: f64, z1: f64, id: u32| {
        wall(
            DVec3::new(x0, h, z0),
            DVec3::X * (x1 - x0),
            DVec3::Z * (z1 - z0),
            id,
        )
    };
    surfaces.push(ceiling(0.0, 0.0, w, 1.5, 5));
    surfaces.push(ceiling(0.0, 2.5, w, w, 6));
    surfaces.push(ceiling(0.0, 1.5, 1.5, 2.5, 7));
    surfaces.push(ceiling(2.5, 1.5, w, 2.5, 8));
    for s in &surfaces[5..] {
        assert_eq!(s.normal, -DVec3::Y);
    }
    surfaces
}

#[test]
fn a_sun_patch_sends_the_power_its_opening_lets_in() {
    // The sun through the skylight: the floor's patch must reflect the
    // power that comes in, E sin(altitude) x 1 m^2, however the element
    // edges cut the patch's outline.
    for altitude in [50.0f64, 65.0, 80.0] {
        let lights = Daylight {
            sun: Some(SunSpec {
                altitude,
                azimuth: 30.0,
                illuminance: 50_000.0,
            }),
            sky: None,
        }
        .lights()
        .unwrap();
        let scene = with_lights(skylight_room(0.5), lights);
        let settings = Settings::adaptive();
        let mesh = Mesh::build(&scene, &settings.mesh.sized_for(&scene)).unwrap();
        let mut solver = Solver::new(&scene, &mesh, settings);
        solver.run(|_| radiosity::solver::Flow::Continue);
        let power = solver.light_power()[0].x;
        let exact = 50_000.0 / 179.0 * altitude.to_radians().sin();
        assert_relative_eq!(power, exact, max_relative = 0.01);
    }
}

#[test]
fn an_overcast_sky_through_a_skylight_gives_its_luminance_integrated_over_the_opening() {
    // A closed 4 x 3 x 4 m room of black walls whose ceiling has a 1 x 1 m
    // opening over the floor's centre: the floor there receives the sky
    // seen through the opening, and nothing else.
    let h = 3.0;
    let surfaces = skylight_room(0.0);
    let illuminance = 10_000.0;
    let lights = sky_lights(SkyModel::Overcast, illuminance, 16, None);
    let mut scene = with_lights(surfaces, lights);
    scene.mesh_hint = Some(radiosity::scene::MeshHint {
        patch_size: 2.0,
        element_size: 1.0,
        directive: None,
    });
    let centre = DVec3::new(2.0, 0.0, 2.0);
    let off_centre = DVec3::new(2.6, 0.0, 1.7);
    // A floor corner, where three black walls meet: light must not leak
    // in along the edges.
    let corner = DVec3::ZERO;
    let got = lux_at(
        &scene,
        Settings::adaptive(),
        &[
            (centre, DVec3::Y),
            (off_centre, DVec3::Y),
            (corner, DVec3::Y),
        ],
    );
    // The closed form, by a fine midpoint rule over the opening: the
    // overcast luminance L_z (1 + 2 cos theta) / 3 (lux per sr) times
    // cos^2 theta / r^2 dA (both cosines equal: the opening is parallel to
    // the floor).
    let lz = 9.0 * illuminance / (7.0 * std::f64::consts::PI);
    let through = |p: DVec3| {
        let n = 400;
        let mut sum = 0.0;
        for i in 0..n {
            for j in 0..n {
                let q = DVec3::new(
                    1.5 + (f64::from(i) + 0.5) / f64::from(n),
                    h,
                    1.5 + (f64::from(j) + 0.5) / f64::from(n),
                );
                let d = q - p;
                let r2 = d.length_squared();
                let cos = d.y / r2.sqrt();
                sum += lz * (1.0 + 2.0 * cos) / 3.0 * cos * cos / r2;
            }
        }
        sum / f64::from(n * n)
    };
    assert_relative_eq!(got[0], through(centre), max_relative = 0.01);
    assert_relative_eq!(got[1], through(off_centre), max_relative = 0.01);
    assert_relative_eq!(got[2], through(corner), max_relative = 0.05);
}

#[test]
fn a_light_shut_inside_a_solid_is_found_and_one_in_a_room_is_not() {
    // A closed 1 m box facing out (a solid) resting on the floor, a light
    // inside it and one above the floor; and the furnace (a closed room
    // facing in) with a light inside.
    let (x, y, z) = (DVec3::X, DVec3::Y, DVec3::Z);
    let o = DVec3::new(0.5, 0.0, 0.5);
    let faces = [
        (o, x, z),     // bottom, -y
        (o + y, z, x), // top, +y
        (o, z, y),     // x = 3, -x
        (o + x, y, z), // x = 4, +x
        (o, y, x),     // z = 3, -z
        (o + z, x, y), // z = 4, +z
    ];
    let mut surfaces: Vec<_> = faces
        .iter()
        .enumerate()
        .map(|(i, &(origin, u, v))| quad(origin, u, v, 0.5, 0.0, i as u32 + 1))
        .collect();
    let centre = o + DVec3::splat(0.5);
    for s in &surfaces {
        assert!(s.normal.dot(s.polygon[0] - centre) > 0.0, "faces point out");
    }
    surfaces.insert(0, floor(0.5));
    let scene = with_lights(
        surfaces,
        vec![
            point_light(centre, 10.0),
            point_light(DVec3::new(0.0, 2.0, 0.0), 10.0),
        ],
    );
    let settings = Settings::adaptive();
    let mesh = Mesh::build(&scene, &settings.mesh.sized_for(&scene)).unwrap();
    let solver = Solver::new(&scene, &mesh, settings.clone());
    assert_eq!(solver.enclosed_lights(), [0]);
    let mut room = furnace(2.0, 0.5, 0.0);
    room.lights = vec![point_light(DVec3::splat(1.0), 10.0)];
    let mesh = Mesh::build(&room, &settings.mesh.sized_for(&room)).unwrap();
    let solver = Solver::new(&room, &mesh, settings);
    assert!(solver.enclosed_lights().is_empty());
}

#[test]
fn export_scene_writes_lights_that_read_back_as_they_were() {
    let dir = tempfile::tempdir().unwrap();
    let text = format!(
        "#@light point 0.5 2 -0.25 120 1 0.5 0.25\n\
         #@light spot 1 2.5 0 0.3 -1 0.2 400 15 30\n\
         #@light sun 0.2 -1 0.4 50000\n#@light spot 0 2.5 1 0 -1 0 100 10 90\n{FLOOR_OBJ}"
    );
    std::fs::write(dir.path().join("lit.obj"), text).unwrap();
    std::fs::write(dir.path().join("m.mtl"), "newmtl grey\nKd 0.5 0.5 0.5\n").unwrap();
    let obj = dir.path().join("lit.obj");
    let glb = dir.path().join("lit.glb");
    radiosity::app::export_scene(obj.to_str().unwrap(), &glb, &Default::default()).unwrap();
    let before = radiosity::scene::load(obj.to_str().unwrap()).unwrap();
    let after = radiosity::scene::load(glb.to_str().unwrap()).unwrap();
    // (The widest cone, 90 degrees, is a hair more in f32 radians.)
    assert_eq!(after.lights.len(), 4);
    let close = |a: DVec3, b: DVec3| (a - b).length() < 1e-6 * (1.0 + b.length());
    for (a, b) in after.lights.iter().zip(&before.lights) {
        // The colour scaled to a largest channel of 1, the intensity up.
        assert!(
            close(a.colour * a.intensity, b.colour * b.intensity),
            "{}",
            b.name
        );
        match (&a.kind, &b.kind) {
            (
                LightKind::Point(radiosity::scene::light::Point { position: p }),
                LightKind::Point(radiosity::scene::light::Point { position: q }),
            ) => {
                assert!(close(*p, *q));
            }
            (
                LightKind::Spot(radiosity::scene::light::Spot {
                    position: p,
                    direction: d,
                    inner: i,
                    outer: o,
                }),
                LightKind::Spot(radiosity::scene::light::Spot {
                    position: q,
                    direction: e,
                    inner: j,
                    outer: u,
                }),
            ) => {
                assert!(close(*p, *q) && close(*d, *e), "{d} {e}");
                assert!((i - j).abs() < 1e-6 && (o - u).abs() < 1e-6);
            }
            (
                LightKind::Sun(radiosity::scene::light::Sun { direction: d }),
                LightKind::Sun(radiosity::scene::light::Sun { direction: e }),
            ) => {
                assert!(close(*d, *e), "{d} {e}");
            }
            (a, b) => panic!("{a:?} read back as {b:?}"),
        }
    }
}

#[test]
fn a_blender_scene_renders_with_its_point_spot_and_sun_lights() {
    // tests/data/blender-lights.glb, written by tools/blender_lights.py
    // with Blender 5.0's glTF exporter: a 60 W point lamp, a 200 W spot
    // (50 degrees, blend 0.3) and a sun of strength 5 in a room with a
    // window; no emitting surface.
    let path = common::test_data("blender-lights.glb");
    let mut scene = radiosity::scene::load(path.to_str().unwrap()).unwrap();
    assert!(!scene.surfaces.iter().any(|s| s.is_emitter()));
    let kinds: Vec<&str> = scene.lights.iter().map(|l| l.kind.name()).collect();
    assert_eq!(kinds, ["point", "spot", "sun"]);
    // The exporter's physical units: W x 683 / (4 pi) candela for point
    // and spot lights, W/m^2 x 683 lux for the sun.
    let candela = |watts: f64| watts * 683.0 / (4.0 * std::f64::consts::PI);
    assert_relative_eq!(
        scene.lights[0].intensity,
        candela(60.0),
        max_relative = 1e-6
    );
    assert_relative_eq!(
        scene.lights[1].intensity,
        candela(200.0),
        max_relative = 1e-6
    );
    assert_relative_eq!(scene.lights[2].intensity, 5.0 * 683.0, max_relative = 1e-6);
    scene.mesh_hint = Some(radiosity::scene::MeshHint {
        patch_size: 1.5,
        element_size: 0.5,
        directive: None,
    });
    // Each light's direct light where it falls: under the lamp (2.7 m up),
    // on the table under the spot, and on the floor where the sun comes in
    // through the middle of the window (x 1.5..3.5, y 0.9..2.1, z = 0).
    let LightKind::Point(radiosity::scene::light::Point { position: lamp }) = scene.lights[0].kind
    else {
        unreachable!()
    };
    let LightKind::Spot(radiosity::scene::light::Spot {
        position: spot,
        direction: spot_axis,
        ..
    }) = scene.lights[1].kind
    else {
        unreachable!()
    };
    let LightKind::Sun(radiosity::scene::light::Sun { direction: sun }) = scene.lights[2].kind
    else {
        unreachable!()
    };
    assert!(
        (spot_axis + DVec3::Y).length() < 1e-6,
        "the spot points down"
    );
    let under_lamp = DVec3::new(lamp.x, 0.0, lamp.z);
    let on_table = DVec3::new(spot.x, 0.75, spot.z);
    let window = DVec3::new(2.5, 1.5, 0.0);
    let sunlit = window + sun * (-window.y / sun.y);
    assert!(
        sunlit.z < -0.5 && sunlit.z > -3.5 && sunlit.x > 0.5 && sunlit.x < 4.5,
        "{sunlit}"
    );
    let points = [
        (under_lamp, DVec3::Y),
        (on_table, DVec3::Y),
        (sunlit, DVec3::Y),
    ];
    let got = lux_at(&scene, Settings::adaptive(), &points);
    let direct = [
        scene.lights[0].intensity / lamp.y.powi(2),
        scene.lights[1].intensity / (spot.y - 0.75).powi(2),
        scene.lights[2].intensity * -sun.y,
    ];
    // Each light gives at least its own direct light where it falls: the
    // solution with it less the solution without it.
    for (k, what) in ["lamp", "spot", "sun"].iter().enumerate() {
        let mut without = scene.clone();
        without.lights.remove(k);
        let rest = lux_at(&without, Settings::adaptive(), &points);
        let own = got[k] - rest[k];
        assert!(
            own > 0.999 * direct[k],
            "{what}: {own} lux of its own at its point, direct {}",
            direct[k]
        );
    }
}

#[test]
fn lights_and_daylight_give_the_same_solution_on_any_number_of_threads() {
    let mut lights = Daylight {
        sun: Some(SunSpec {
            altitude: 60.0,
            azimuth: 20.0,
            illuminance: 40_000.0,
        }),
        sky: Some(SkySpec {
            model: SkyModel::Clear,
            illuminance: 10_000.0,
            subdivision: 1,
            ground_reflectance: sky::DEFAULT_GROUND_REFLECTANCE,
        }),
    }
    .lights()
    .unwrap();
    lights.push(point_light(DVec3::new(1.0, 2.5, 1.0), 200.0));
    let scene = with_lights(skylight_room(0.5), lights);
    let settings = Settings::adaptive();
    let mesh = Mesh::build(&scene, &settings.mesh.sized_for(&scene)).unwrap();
    let solve = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let mut solver = Solver::new(&scene, &mesh, settings.clone());
                solver.run(|_| radiosity::solver::Flow::Continue);
                solver.radiosity().to_vec()
            })
    };
    let one = solve(1);
    assert!(one.iter().any(|b| b.x > 0.0));
    assert_eq!(one, solve(2));
}

#[test]
fn an_asymmetric_luminaire_sends_c90_counter_clockwise_from_c0_seen_from_above() {
    // 0-360 degrees: 100 cd towards C90 only (straight out sideways).
    let profile = "TILT=NONE\n1 -1 1 3 5 1 2 0 0 0\n1 1 0\n0 45 90\n0 90 180 270 360\n\
                   0 0 0\n0 0 100\n0 0 0\n0 0 0\n0 0 0\n";
    let text = format!("#@light ies lamp.ies 0 2 0\n{FLOOR_OBJ}");
    let scene = load_with_files(&text, &[("lamp.ies", profile)]).unwrap();
    // Hanging straight down, C0 along +x: seen from above (looking down
    // -y, +x to the right and -z up the page), counter-clockwise from +x
    // is -z.
    let LightKind::Luminaire(_) = scene.lights[0].kind else {
        panic!()
    };
    let towards_minus_z = scene.lights[0].falloff(-DVec3::Z);
    let towards_plus_z = scene.lights[0].falloff(DVec3::Z);
    assert_relative_eq!(towards_minus_z, 100.0);
    assert_eq!(towards_plus_z, 0.0);
}

#[test]
fn a_scene_lit_by_lights_alone_takes_the_tolerance_as_one_with_emitters_does() {
    // The adaptive method's tolerance scales with the power brought in:
    // a light's counts once it has shot, so a looser tolerance casts fewer
    // rays here as it does with emitting surfaces.
    let mut scene = furnace(4.0, 0.5, 0.0);
    scene.lights = vec![point_light(DVec3::new(2.0, 3.0, 2.0), 200.0)];
    let rays = |tolerance: f64| {
        let mut settings = Settings::adaptive();
        // At the stopping rule this was written for: the tail of shots a
        // tighter --converge adds costs the same at either tolerance.
        settings.converge = radiosity::solver::DEFAULT_CONVERGE;
        settings
            .method
            .method_mut()
            .set(
                "tolerance",
                &radiosity::solver::method::Value::Number(tolerance),
            )
            .unwrap();
        let mesh = Mesh::build(&scene, &settings.mesh.sized_for(&scene)).unwrap();
        let mut solver = Solver::new(&scene, &mesh, settings);
        solver.run(|_| radiosity::solver::Flow::Continue);
        solver.stats().rays_cast
    };
    let (tight, loose) = (rays(1e-3), rays(1e-1));
    assert!(loose * 2 < tight, "{loose} rays at 0.1, {tight} at 0.001");
}

/// The worked example of a new kind of light (`scene/light/lambert.rs`,
/// registered by one line): a Lambertian point read from its `#@light`
/// directive gives `I0 cos(theta) cos(theta') / d^2` at the sensors under
/// every preset, its flux `pi I0` is what the energy ledger and the
/// statistics count, and the final pass evaluates the same closed form at
/// the mesh's vertices.
#[test]
fn a_lambertian_point_light_gives_its_closed_form_everywhere() {
    let at = DVec3::new(0.3, 2.0, -0.2);
    let axis = DVec3::new(0.4, -1.0, 0.2).normalize();
    let candela = 150.0;
    let text = format!(
        "#@light lambert {} {} {} {} {} {} {candela}\n{FLOOR_OBJ}",
        at.x, at.y, at.z, axis.x, axis.y, axis.z
    );
    let scene = load_with_files(&text, &[]).unwrap();
    assert_eq!(scene.lights[0].kind.name(), "lambert");
    let expected = |p: DVec3| {
        let d = at - p;
        let cos_light = axis.dot(-d.normalize()).max(0.0);
        candela * cos_light * d.y / d.length().powi(3)
    };
    let points = floor_points();
    for preset in [Preset::Adaptive, Preset::WongTsang93, Preset::Wallace89] {
        let got = lux_at(&scene, preset.settings(), &points);
        for (&(p, _), lux) in points.iter().zip(got) {
            assert_relative_eq!(lux, expected(p), max_relative = 1e-5);
        }
    }
    // Its flux: pi I0 in lumens, 1/179 of it in watts per channel.
    let flux = scene.lights[0].flux().unwrap();
    assert_relative_eq!(
        flux.x * radiosity::photometry::LUMINOUS_EFFICACY,
        std::f64::consts::PI * candela,
        max_relative = 1e-12
    );
    // The final pass: the direct light at each vertex of the floor.
    let settings = Settings::adaptive();
    let mesh = Mesh::build(&scene, &settings.mesh.sized_for(&scene)).unwrap();
    let mut solver = Solver::new(&scene, &mesh, settings);
    solver.run(|_| radiosity::solver::Flow::Continue);
    let pass = FinalPass::new(&solver, FinalGather::Direct);
    let vertices = common::vertex_points(&mesh);
    for (v, e) in vertices.iter().zip(pass.direct(&vertices)) {
        // (The pass evaluates a hair off the surface, as the sensors do.)
        assert_relative_eq!(
            lux(e),
            expected(v.position),
            max_relative = 1e-5,
            epsilon = 1e-9
        );
    }
}
