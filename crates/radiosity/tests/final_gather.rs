//! The final pass ([`radiosity::final_gather`]): a sun's shadow drawn as
//! sharp as the pixels, whatever the mesh; the split of a vertex's light
//! into its direct and indirect parts adding up to the solve's total; the
//! direct light of an emitting patch against its closed form; `full`'s
//! gather against the furnace's closed form.

mod common;

use glam::DVec3;
use radiosity::final_gather::{FinalGather, FinalPass, Point};
use radiosity::form_factor::closed_form;
use radiosity::mesh::Mesh;
use radiosity::render::{self, RenderSettings};
use radiosity::scene::{Camera, Light, LightKind};
use radiosity::solver::{Preset, Settings, Solver};

use common::{quad, scene_of};

/// Pixels from `from` to `to` (inclusive, along a row or a column) whose
/// luminance lies strictly between 10% and 90% of the lit level `lit`
/// above a shadow of level 0.
fn ramp_width(image: &render::Image, pixels: impl Iterator<Item = (u32, u32)>, lit: f64) -> usize {
    pixels
        .filter(|&(x, y)| {
            let v = f64::from(image.pixels[(y * image.width + x) as usize].y);
            v > 0.1 * lit && v < 0.9 * lit
        })
        .count()
}

/// Seen from 6 m above at 800 x 600 (a pixel is 4 mm on the floor), at the
/// default supersampling, the default preset's picture draws the board's
/// shadow with edges at most 2 pixels wide (10% to 90% of the lit level),
/// across the sun's direction and along it; the mesh alone (`off`) cannot.
#[test]
fn a_sun_shadow_edge_is_at_most_two_pixels_wide() {
    let scene = common::board_in_the_sun();
    let settings = Settings::adaptive();
    assert_eq!(
        FinalGather::of_preset(Preset::Adaptive),
        FinalGather::Direct
    );
    let mut mesh_settings = settings.mesh;
    let hint = scene.default_mesh_sizes();
    mesh_settings.patch_size = hint.patch_size;
    mesh_settings.element_size = hint.element_size;
    let mesh = Mesh::build(&scene, &mesh_settings).unwrap();
    let mut solver = Solver::new(&scene, &mesh, settings.clone());
    solver.run(|_| radiosity::solver::Flow::Continue);
    // The shadow spans x in [-1.077, -0.077], z in [-0.5, 0.5]; the eye is
    // above its left half, which the board does not hide.
    // Off the pixel grid by a fraction of a pixel, so no edge falls on a
    // pixel boundary.
    let eye = DVec3::new(-0.8013, 6.0, 0.0017);
    let fov = 2.0 * (1.2f64 / 6.0).atan().to_degrees();
    let view = RenderSettings {
        width: 800,
        height: 600,
        camera: Camera {
            eye,
            target: DVec3::new(eye.x, 0.0, eye.z),
            up: -DVec3::Z,
            fov_degrees: fov,
        },
        supersampling: 3,
    };
    let pixel = 2.4 / 600.0;
    let column = |x: f64| (400.0 + (x - eye.x) / pixel) as u32;
    let row = |z: f64| (300.0 + (z - eye.z) / pixel) as u32;
    let lit = |image: &render::Image| {
        f64::from(image.pixels[(row(-1.0) * 800 + column(-1.5)) as usize].y)
    };
    let widths = |image: &render::Image| {
        let level = lit(image);
        // Across the sun: along the row z = 0 over the edge x = -1.077.
        let across = ramp_width(
            image,
            (column(-1.35)..=column(-0.85)).map(|x| (x, row(0.0))),
            level,
        );
        // Along the sun: down the column x = -0.8 over the edge z = 0.5.
        let along = ramp_width(
            image,
            (row(0.25)..=row(0.75)).map(|y| (column(-0.8), y)),
            level,
        );
        (across, along)
    };
    let pass = FinalPass::new(&solver, FinalGather::Direct);
    let display = solver.display_radiosity(true);
    let ambient = solver.ambient();
    let sharp = render::render_shaded(
        &scene,
        &mesh,
        &pass.vertex_display(&display, ambient),
        &view,
        Some(&|points: &[Point]| pass.shade(points)),
    );
    let mesh_only = render::render(&scene, &mesh, &display, &view);
    assert!(lit(&sharp) > 0.0);
    assert!(
        (lit(&sharp) / lit(&mesh_only) - 1.0).abs() < 1e-3,
        "the lit floor reads the same: {} and {}",
        lit(&sharp),
        lit(&mesh_only)
    );
    // The shadow is there: dark inside (the board is black, the floor
    // cannot see itself).
    let inside = sharp.pixels[(row(0.0) * 800 + column(-0.8)) as usize].y;
    assert!(
        f64::from(inside) < 0.01 * lit(&sharp),
        "{inside} in the shadow"
    );
    let (across, along) = widths(&sharp);
    println!("direct: edges {across} and {along} pixels wide");
    assert!(
        across <= 2 && along <= 2,
        "edges {across} and {along} pixels wide"
    );
    let (across, along) = widths(&mesh_only);
    println!("the mesh alone: edges {across} and {along} pixels wide");
    assert!(across.max(along) > 2, "the mesh alone: {across}, {along}");
}

/// A lamp over a floor, a shelf between and a point light: at every vertex
/// the direct part the solve booked (the light's shot, the lamp's first
/// shot) plus the mesh's indirect part is the solve's total; the booked
/// direct part agrees with the final pass's own evaluation at the vertex
/// where the lamp is in full view (both exact there, up to the solve's
/// tolerance), and on the whole; the indirect part is never below zero.
#[test]
fn direct_and_indirect_add_up_to_the_total_at_every_vertex() {
    let mut surfaces = common::lamp_over_floor(0.6, 0.5, 1.5, 50.0);
    surfaces.push(quad(
        DVec3::new(-0.3, 0.4, -0.3),
        DVec3::Z * 0.6,
        DVec3::X * 0.6,
        0.7,
        0.0,
        9,
    ));
    let mut scene = scene_of(surfaces);
    scene.lights.push(Light {
        name: "bulb".into(),
        kind: LightKind::Point(radiosity::scene::light::Point {
            position: DVec3::new(1.0, 1.0, 0.5),
        }),
        colour: DVec3::new(1.0, 0.8, 0.6),
        intensity: 30.0,
    });
    let settings = Settings::adaptive();
    let mut mesh_settings = settings.mesh;
    let hint = scene.default_mesh_sizes();
    mesh_settings.patch_size = hint.patch_size;
    mesh_settings.element_size = hint.element_size;
    let mesh = Mesh::build(&scene, &mesh_settings).unwrap();
    let mut solver = Solver::new(&scene, &mesh, settings);
    solver.run(|_| radiosity::solver::Flow::Continue);
    let pass = FinalPass::new(&solver, FinalGather::Direct);
    let points = common::vertex_points(&mesh);
    let evaluated = pass.direct(&points);
    let booked = &solver.direct_irradiance()[..mesh.vertices.len()];
    assert!(solver.direct_complete());
    let (mut sum_booked, mut sum_evaluated) = (0.0, 0.0);
    let mut compared = 0;
    for (((d, e), i), total) in booked
        .iter()
        .zip(&evaluated)
        .zip(pass.vertex_indirect())
        .zip(solver.irradiance())
    {
        let scale = total.max_element().max(1e-12);
        assert!(
            (*d + *i - *total).abs().max_element() <= 1e-12 * scale,
            "{d} + {i} against {total}"
        );
        assert!(i.min_element() >= -1e-9 * scale, "indirect {i} of {total}");
        sum_booked += d.y;
        sum_evaluated += e.y;
        // Where nothing shadows (the point light and the lamp in view:
        // above the shelf's height or well outside its shadow), the two
        // agree closely.
        if d.y > 0.0 && (e.y / d.y - 1.0).abs() < 0.02 {
            compared += 1;
        }
    }
    assert!(
        (sum_evaluated / sum_booked - 1.0).abs() < 0.01,
        "evaluated {sum_evaluated}, booked {sum_booked}"
    );
    assert!(
        compared > mesh.vertices.len() * 3 / 4,
        "{compared} of {} vertices agree within 2%",
        mesh.vertices.len()
    );
}

/// What the lamp (an emitting axis-aligned rectangle facing down,
/// `height` above the floor) sends to the floor point `at` with nothing
/// between: its exitance times the closed form of a parallel rectangle.
fn lamp_closed_form(lamp: &radiosity::scene::Surface, at: DVec3, height: f64) -> DVec3 {
    let (lo, hi) = lamp
        .polygon
        .iter()
        .fold((DVec3::MAX, DVec3::MIN), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        });
    lamp.emission
        * closed_form::parallel_rectangle(
            lo.x - at.x,
            hi.x - at.x,
            lo.z - at.z,
            hi.z - at.z,
            height,
        )
}

/// An emitting square over a floor point, nothing between: the direct
/// part is its exitance times the exact factor (the closed form of a
/// parallel rectangle), to 1e-6 (the point gathers a millionth of the way
/// towards its surface's centroid, as every receiver does); with an opaque square between covering
/// the whole lamp, zero.
#[test]
fn an_emitting_patch_gives_its_closed_form() {
    let (side, height, exitance) = (0.5, 1.5, 40.0);
    let surfaces = common::lamp_over_floor(0.5, side, height, exitance);
    let scene = scene_of(surfaces.clone());
    let settings = Settings::adaptive();
    let mut mesh_settings = settings.mesh;
    mesh_settings.patch_size = 0.25;
    mesh_settings.element_size = 0.25;
    let mesh = Mesh::build(&scene, &mesh_settings).unwrap();
    let solver = Solver::new(&scene, &mesh, settings.clone());
    let pass = FinalPass::new(&solver, FinalGather::Direct);
    let floor = scene
        .surfaces
        .iter()
        .position(|s| s.normal.y > 0.5 && s.emission == DVec3::ZERO)
        .unwrap() as u32;
    let lamp = scene.surfaces.iter().find(|s| s.is_emitter()).unwrap();
    let centre = lamp.polygon.iter().sum::<DVec3>() / lamp.polygon.len() as f64;
    let below = DVec3::new(centre.x + 0.1, 0.0, centre.z - 0.05);
    let e = pass.direct(&[Point {
        surface: floor,
        position: below,
        sample: None,
        seed: 0,
    }])[0];
    let expected = lamp_closed_form(lamp, below, height);
    assert!(
        (e - expected).abs().max_element() <= 1e-6 * expected.max_element(),
        "{e} against {expected}"
    );

    // A black square between, larger than the lamp: dark.
    let mut blocked = surfaces;
    blocked.push(quad(
        DVec3::new(centre.x - 0.5, 0.7, centre.z - 0.5),
        DVec3::Z,
        DVec3::X,
        0.0,
        0.0,
        7,
    ));
    let scene = scene_of(blocked);
    let mesh = Mesh::build(&scene, &mesh_settings).unwrap();
    let solver = Solver::new(&scene, &mesh, settings);
    let pass = FinalPass::new(&solver, FinalGather::Direct);
    let e = pass.direct(&[Point {
        surface: floor,
        position: below,
        sample: Some((3, 9)),
        seed: 5,
    }])[0];
    assert_eq!(e, DVec3::ZERO);
}

/// The furnace: every face of a closed cube emits `M` and reflects `rho`,
/// so every point's irradiance is `M / (1 - rho)`. `full`'s direct part
/// (every face's emission, seen over the whole hemisphere: `M`) plus its
/// gather of the mesh's reflected light gives it within 1%, and `direct`
/// exactly what the mesh has.
#[test]
fn a_full_gather_in_the_furnace_gives_the_closed_form() {
    let (rho, emission) = (0.6, 10.0);
    let scene = common::furnace(2.0, rho, emission);
    let settings = Settings {
        converge: 1e-5,
        ..Settings::adaptive()
    };
    let mut mesh_settings = settings.mesh;
    mesh_settings.patch_size = 0.5;
    mesh_settings.element_size = 0.25;
    let mesh = Mesh::build(&scene, &mesh_settings).unwrap();
    let mut solver = Solver::new(&scene, &mesh, settings);
    solver.run(|_| radiosity::solver::Flow::Continue);
    let expected = emission / (1.0 - rho);
    let points: Vec<Point> = [
        (0, DVec3::new(0.3, 0.0, 1.7)),
        (1, DVec3::new(1.0, 2.0, 1.0)),
        (2, DVec3::new(0.0, 0.05, 0.05)),
        (5, DVec3::new(1.9, 1.2, 2.0)),
    ]
    .iter()
    .enumerate()
    .map(|(i, &(surface, position))| Point {
        surface,
        position,
        sample: None,
        seed: i as u64,
    })
    .collect();
    let full = FinalPass::new(&solver, FinalGather::Full);
    for (p, e) in points.iter().zip(full.irradiance(&points)) {
        assert!(
            (e / expected - DVec3::ONE).abs().max_element() < 0.01,
            "{p:?}: {e} against {expected}"
        );
    }
    let direct = FinalPass::new(&solver, FinalGather::Direct);
    for (p, e) in points.iter().zip(direct.direct(&points)) {
        assert!(
            (e / emission - DVec3::ONE).abs().max_element() < 1e-6,
            "{p:?}: direct {e} against {emission}"
        );
    }
}

/// A ceiling of 400 small emitting tiles over a floor with a black table
/// between: more sources than a point's budget, so the final pass traces a
/// cut of its light tree. Each floor point's mean over many seeds is its
/// value with every tile traced (the brute-force oracle, budgets above the
/// tile count), within five standard errors, at vertices, texels and
/// sensors (`sample: None`) and at a picture's samples; and where no tile
/// is hidden, one seed alone is within 5% of it.
#[test]
fn many_emitters_through_the_light_tree_are_unbiased() {
    let mut surfaces = vec![common::floor(0.5)];
    let tiles = 20;
    let pitch = 4.0 / f64::from(tiles);
    for i in 0..tiles {
        for j in 0..tiles {
            let exitance = 20.0 + 30.0 * f64::from((i * 7 + j * 3) % 5);
            surfaces.push(quad(
                DVec3::new(
                    -2.0 + pitch * f64::from(i) + 0.02,
                    2.5,
                    -2.0 + pitch * f64::from(j) + 0.02,
                ),
                DVec3::X * (pitch - 0.04),
                DVec3::Z * (pitch - 0.04),
                0.0,
                exitance,
                1 + i * tiles + j,
            ));
        }
    }
    // A black table top, seen from below and above.
    let top = |y: f64, flip: bool| {
        let (u, v) = if flip {
            (DVec3::X * 1.2, DVec3::Z * 0.8)
        } else {
            (DVec3::Z * 0.8, DVec3::X * 1.2)
        };
        quad(DVec3::new(-0.6, y, -0.4), u, v, 0.0, 0.0, 1000)
    };
    surfaces.push(top(0.75, true));
    surfaces.push(top(0.76, false));
    let scene = scene_of(surfaces);
    let settings = Settings::adaptive();
    let mut mesh_settings = settings.mesh;
    mesh_settings.patch_size = 0.5;
    mesh_settings.element_size = 0.5;
    let mesh = Mesh::build(&scene, &mesh_settings).unwrap();
    let solver = Solver::new(&scene, &mesh, settings);
    let pass = FinalPass::new(&solver, FinalGather::Direct);
    assert_eq!(pass.sources(), 400);
    let oracle = FinalPass::new(&solver, FinalGather::Direct).with_budgets(1000, 1000);
    // Under the table's edge (a penumbra), under its middle (the tiles
    // above hidden, the rest seen), and in the open.
    let places = [
        DVec3::new(0.6, 0.0, 0.1),
        DVec3::new(0.0, 0.0, 0.0),
        DVec3::new(1.5, 0.0, -1.3),
    ];
    for (sample, seeds) in [(None, 400u64), (Some((0, 1)), 2000)] {
        for (p, place) in places.iter().enumerate() {
            let points: Vec<Point> = (0..seeds)
                .map(|seed| Point {
                    surface: 0,
                    position: *place,
                    sample,
                    seed: seed * 7919 + p as u64,
                })
                .collect();
            let estimates = pass.direct(&points);
            let exact = oracle.direct(&points);
            let truth = exact.iter().map(|e| e.y).sum::<f64>() / seeds as f64;
            let n = seeds as f64;
            let mean = estimates.iter().map(|e| e.y).sum::<f64>() / n;
            let square = estimates.iter().map(|e| e.y * e.y).sum::<f64>() / n;
            let oracle_square = exact.iter().map(|e| e.y * e.y).sum::<f64>() / n;
            // Both are estimates for a picture's sample (its points in the
            // pieces are random); the oracle's own error counts too.
            let error =
                (((square - mean * mean).max(0.0) + (oracle_square - truth * truth).max(0.0)) / n)
                    .sqrt();
            println!("{sample:?} at {place}: tree {mean} against {truth} (standard error {error})");
            assert!(truth > 1.0, "{place} is lit");
            assert!(
                (mean - truth).abs() <= 5.0 * error + 1e-9 * truth,
                "{sample:?} at {place}: tree {mean} against every tile {truth} (standard error \
                 {error})"
            );
            if p == 2 && sample.is_none() {
                for e in &estimates {
                    assert!(
                        (e.y / truth - 1.0).abs() < 0.05,
                        "one seed: {} against {truth}",
                        e.y
                    );
                }
            }
        }
    }
}

/// A pixel's samples shade together. Under a lamp wholly in view (the
/// shaft between the pixel and the lamp is clear: no ray is cast), the
/// samples share the lamp's exact factor at their centroid, so the pixel
/// (their mean) reads the mean of the closed form to the second order of
/// their spread, with no noise; a pixel whose samples spread wide next to
/// the lamp takes the exact factor at each sample. Where a board hides half
/// the lamp (a penumbra), each sample casts its own four rays, as alone,
/// the pieces weighed once for the pixel: the pixel's mean is the one its
/// samples give shaded alone.
#[test]
fn a_pixel_in_full_view_is_exact_and_one_in_a_penumbra_takes_every_ray() {
    let (side, height, exitance) = (0.5, 1.5, 40.0);
    let surfaces = common::lamp_over_floor(0.5, side, height, exitance);
    let settings = Settings::adaptive();
    let mut mesh_settings = settings.mesh;
    mesh_settings.patch_size = 0.25;
    mesh_settings.element_size = 0.25;
    let pixel = |centre: DVec3, spacing: f64, seed: u64| -> Vec<Point> {
        (0..9u32)
            .map(|k| Point {
                surface: 0,
                position: centre
                    + DVec3::new(f64::from(k % 3) * spacing, 0.0, f64::from(k / 3) * spacing),
                sample: Some((k, 9)),
                seed,
            })
            .collect()
    };
    let mean = |values: &[DVec3]| values.iter().sum::<DVec3>() / values.len() as f64;

    let scene = scene_of(surfaces.clone());
    let mesh = Mesh::build(&scene, &mesh_settings).unwrap();
    let solver = Solver::new(&scene, &mesh, settings.clone());
    let pass = FinalPass::new(&solver, FinalGather::Direct);
    let lamp = scene.surfaces.iter().find(|s| s.is_emitter()).unwrap();
    let points = pixel(DVec3::new(0.3, 0.0, -0.2), 1e-3, 11);
    let got = pass.direct(&points);
    let truth: Vec<DVec3> = points
        .iter()
        .map(|p| lamp_closed_form(lamp, p.position, height))
        .collect();
    let centroid = points.iter().map(|p| p.position).sum::<DVec3>() / 9.0;
    let at_centroid = lamp_closed_form(lamp, centroid, height);
    for (p, e) in points.iter().zip(&got) {
        assert!(
            (*e - at_centroid).abs().max_element() <= 1e-6 * at_centroid.max_element(),
            "{p:?}: {e} against {at_centroid} at the samples' centroid"
        );
    }
    // The mean within the bound `PIXEL_SHARE` documents, `10 (spread /
    // distance)^2` (here 9e-6), and the 1e-6 of the receivers' nudge.
    let (got_mean, true_mean) = (mean(&got), mean(&truth));
    let spread = points
        .iter()
        .map(|p| p.position.distance(centroid))
        .fold(0.0, f64::max);
    let lamp_centre = lamp.polygon.iter().sum::<DVec3>() / 4.0;
    let lamp_radius = lamp
        .polygon
        .iter()
        .map(|c| c.distance(lamp_centre))
        .fold(0.0, f64::max);
    let distance = centroid.distance(lamp_centre) - lamp_radius;
    let bound = 10.0 * (spread / distance).powi(2) + 1e-6;
    assert!(
        (got_mean - true_mean).abs().max_element() <= bound * true_mean.max_element(),
        "the pixel: {got_mean} against {true_mean} (bound {bound})"
    );
    // Samples 5 cm apart 1.5 m under the lamp's edge: each its own factor.
    let points = pixel(DVec3::new(0.2, 0.0, 0.2), 0.05, 11);
    for (p, e) in points.iter().zip(pass.direct(&points)) {
        let expected = lamp_closed_form(lamp, p.position, height);
        assert!(
            (e - expected).abs().max_element() <= 1e-6 * expected.max_element(),
            "{p:?}: {e} against {expected}"
        );
    }

    // A black board at mid-height over x < 0: from x = 0 below, it hides
    // the lamp's half x < 0.
    let mut blocked = surfaces;
    blocked.push(quad(
        DVec3::new(-2.0, 0.75, -2.0),
        DVec3::Z * 4.0,
        DVec3::X * 2.0,
        0.0,
        0.0,
        7,
    ));
    let scene = scene_of(blocked);
    let mesh = Mesh::build(&scene, &mesh_settings).unwrap();
    let solver = Solver::new(&scene, &mesh, settings);
    let pass = FinalPass::new(&solver, FinalGather::Direct);
    let points = pixel(DVec3::new(0.0005, 0.0, 0.0), 1e-3, 23);
    let together = pass.direct(&points);
    let unblocked = lamp_closed_form(lamp, DVec3::ZERO, height).y;
    let alone: Vec<DVec3> = points
        .iter()
        .map(|p| pass.direct(std::slice::from_ref(p))[0])
        .collect();
    for (p, (e, a)) in points.iter().zip(together.iter().zip(&alone)) {
        assert!(e.y > 0.0 && e.y < unblocked, "{p:?}: {e} of {unblocked}");
        // The same rays: what they let through differs only by the
        // pieces' weights, taken at the centroid.
        assert!(
            (e.y / a.y - 1.0).abs() < 0.01,
            "{p:?}: {e} against {a} alone"
        );
    }
    let (together, alone) = (mean(&together), mean(&alone));
    assert!(
        (together.y / alone.y - 1.0).abs() < 1e-4,
        "the pixel: {together} against {alone} alone"
    );
}
