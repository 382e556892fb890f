//! The BSP tree (Wong & Tsang 1993, section 3) against the brute-force
//! oracle: the built-in room, random polygon soups and degenerate inputs,
//! with every settings preset. Answers must be identical, not merely close.

use glam::DVec3;
use radiosity::accel::brute::BruteForce;
use radiosity::accel::bsp::{Bsp, BspSettings, MAX_DEPTH};
use radiosity::accel::{Occluder, shorten};
use radiosity::mesh::{Mesh, MeshSettings, subsources};
use radiosity::scene::Surface;

mod common;

use common::soup::{
    Rng, bounds, builtin, grid_rectangle, numbered, random_point, random_skip, real_file_soup,
    shared_edge_group, surface,
};

const NOTHING_SKIPPED: [u32; 2] = [u32::MAX; 2];

/// Runs `count` random queries (raw and shortened, with and without
/// skipped surfaces) and asserts the tree and the oracle agree on each.
/// Returns `(queries, blocked, surfaces tested by the tree)`.
fn agree_on_random_segments(
    bsp: &Bsp,
    surfaces: &[Surface],
    rng: &mut Rng,
    count: usize,
) -> (usize, usize, u64) {
    let brute = BruteForce::new(surfaces);
    let (lo, hi) = bounds(surfaces);
    let (mut blocked, mut tests) = (0, 0u64);
    for _ in 0..count {
        let a = random_point(rng, surfaces, lo, hi);
        let b = random_point(rng, surfaces, lo, hi);
        let (from, to) = if rng.chance(0.5) {
            shorten(a, b)
        } else {
            (a, b)
        };
        let skip = if rng.chance(0.5) {
            NOTHING_SKIPPED
        } else {
            random_skip(rng, surfaces.len())
        };
        let (answer, n, _) = bsp.occluded_counting(from, to, skip);
        assert_eq!(
            answer,
            brute.occluded(from, to, skip),
            "from {from:?} to {to:?} skipping {skip:?}"
        );
        assert_eq!(answer, bsp.occluded(from, to, skip));
        blocked += usize::from(answer);
        tests += u64::from(n);
    }
    (count, blocked, tests)
}

/// Every preset, plus a shallow tree that has to use leaf buckets and one
/// whose fragment budget refuses splits.
fn all_settings() -> Vec<(&'static str, BspSettings)> {
    let mut all = BspSettings::presets().to_vec();
    all.push((
        "depth-4",
        BspSettings {
            max_depth: 4,
            ..BspSettings::sah()
        },
    ));
    // A tight fragment budget: splits refused, large leaves.
    all.push((
        "growth-1.1",
        BspSettings {
            max_growth: 1.1,
            ..BspSettings::sah()
        },
    ));
    all
}

fn check_scene(name: &str, surfaces: &[Surface], seed: u64, count: usize) {
    let numbered = numbered(surfaces);
    let surfaces = &numbered[..];
    for (preset, settings) in all_settings() {
        let bsp = Bsp::with_settings(surfaces, settings);
        if let Err(e) = bsp.validate() {
            panic!("{name}, {preset}: {e}");
        }
        let stats = bsp.stats();
        assert_eq!(
            stats.fragments,
            surfaces.len() + stats.splits,
            "{name}, {preset}"
        );
        assert!(stats.depth <= settings.max_depth.min(MAX_DEPTH));
        if settings.axis_candidates == 0 {
            // Every node of a pure auto-partition stores a fragment.
            assert!(
                stats.nodes <= stats.fragments,
                "{name}, {preset}: {stats:?}"
            );
        } else {
            // Axis-aligned cuts of empty space add nodes without fragments,
            // each only if it lowers the cost: a few per leaf.
            assert!(
                stats.nodes <= 3 * stats.fragments,
                "{name}, {preset}: {stats:?}"
            );
        }
        let mut rng = Rng(seed);
        agree_on_random_segments(&bsp, surfaces, &mut rng, count);
    }
}

// ---------------------------------------------------------------- the room

#[test]
fn room_tree_is_valid_and_small() {
    let scene = builtin("room");
    for (preset, settings) in all_settings() {
        let bsp = Bsp::with_settings(&scene.surfaces, settings);
        bsp.validate().unwrap_or_else(|e| panic!("{preset}: {e}"));
        let stats = bsp.stats();
        println!(
            "room, {preset}: {} surfaces, {stats:?}",
            scene.surfaces.len()
        );
        assert_eq!(stats.fragments, scene.surfaces.len() + stats.splits);
    }
    let stats = Bsp::new(&scene.surfaces).stats();
    // Splits are what a poor plane choice costs; the room's boxes and
    // walls should need few of them.
    assert!(stats.fragments < 2 * scene.surfaces.len(), "{stats:?}");
    assert!(stats.depth < 40, "{stats:?}");
}

#[test]
fn room_random_segments_agree_with_brute_force() {
    let scene = builtin("room");
    check_scene("room", &scene.surfaces, 1, 20_000);
}

/// Shadow segments as the solver casts them: from subsource centres to mesh
/// vertices, shortened, skipping the source's and receiver's surfaces; and
/// the same without skipping (ends exactly on surfaces and shared edges).
#[test]
fn room_subsource_to_vertex_segments_agree_with_brute_force() {
    let scene = builtin("room");
    let surfaces = &scene.surfaces;
    let mesh = Mesh::build(&scene, &MeshSettings::default()).expect("the room meshes");
    let brute = BruteForce::new(surfaces);
    let mut rng = Rng(2);
    let mut sources = Vec::new();
    for patch in &mesh.patches {
        for sub in subsources(&patch.polygon, 2) {
            sources.push((sub.centroid, patch.surface));
        }
    }
    for (preset, settings) in all_settings() {
        let bsp = Bsp::with_settings(surfaces, settings);
        for _ in 0..15_000 {
            let (c, source) = sources[rng.below(sources.len())];
            let v = &mesh.vertices[rng.below(mesh.vertices.len())];
            let raw = rng.chance(0.3);
            let (from, to) = if raw {
                (c, v.position)
            } else {
                shorten(c, v.position)
            };
            for skip in [[source, v.surface], NOTHING_SKIPPED, [v.surface, u32::MAX]] {
                assert_eq!(
                    bsp.occluded(from, to, skip),
                    brute.occluded(from, to, skip),
                    "{preset}: {from:?} -> {to:?} skipping {skip:?}"
                );
            }
        }
        // Vertex to vertex: both ends on surfaces, many on shared edges.
        for _ in 0..15_000 {
            let a = &mesh.vertices[rng.below(mesh.vertices.len())];
            let b = &mesh.vertices[rng.below(mesh.vertices.len())];
            for skip in [[a.surface, b.surface], NOTHING_SKIPPED] {
                assert_eq!(
                    bsp.occluded(a.position, b.position, skip),
                    brute.occluded(a.position, b.position, skip),
                    "{preset}: {:?} -> {:?} skipping {skip:?}",
                    a.position,
                    b.position
                );
            }
        }
    }
}

/// Not a timing: how many surfaces a query tests, against brute force's
/// all of them. Run with `--nocapture` to see the figures.
#[test]
fn room_queries_test_far_fewer_surfaces_than_brute_force() {
    let scene = builtin("room");
    let surfaces = &scene.surfaces;
    let mesh = Mesh::build(&scene, &MeshSettings::default()).expect("the room meshes");
    for (preset, settings) in all_settings() {
        let bsp = Bsp::with_settings(surfaces, settings);
        let mut rng = Rng(3);
        let (count, blocked, tests) = agree_on_random_segments(&bsp, surfaces, &mut rng, 20_000);
        // Solver-like queries: subsource centre of a patch to a vertex.
        let (mut solver_tests, mut solver_count) = (0u64, 0u64);
        for _ in 0..20_000 {
            let patch = &mesh.patches[rng.below(mesh.patches.len())];
            let v = &mesh.vertices[rng.below(mesh.vertices.len())];
            let c = radiosity::geometry::centroid(&patch.polygon);
            let (from, to) = shorten(c, v.position);
            let (_, n, _) = bsp.occluded_counting(from, to, [patch.surface, v.surface]);
            solver_tests += u64::from(n);
            solver_count += 1;
        }
        let random_mean = tests as f64 / count as f64;
        let solver_mean = solver_tests as f64 / solver_count as f64;
        println!(
            "room, {preset}: {:?}; random segments: {random_mean:.1} surfaces tested per query \
             ({:.0}% blocked); patch-to-vertex: {solver_mean:.1}; brute force: {}",
            bsp.stats(),
            100.0 * blocked as f64 / count as f64,
            surfaces.len()
        );
        assert!(
            solver_mean < 0.5 * surfaces.len() as f64,
            "{preset}: {solver_mean}"
        );
    }
}

#[test]
fn queries_from_many_threads_agree() {
    let scene = builtin("room");
    let surfaces = &scene.surfaces;
    let bsp = Bsp::new(surfaces);
    let brute = BruteForce::new(surfaces);
    let occluders: [&dyn Occluder; 2] = [&bsp, &brute];
    std::thread::scope(|scope| {
        for t in 0..4u64 {
            scope.spawn(move || {
                let mut rng = Rng(100 + t);
                let (lo, hi) = bounds(surfaces);
                for _ in 0..5_000 {
                    let from = random_point(&mut rng, surfaces, lo, hi);
                    let to = random_point(&mut rng, surfaces, lo, hi);
                    assert_eq!(
                        occluders[0].occluded(from, to, NOTHING_SKIPPED),
                        occluders[1].occluded(from, to, NOTHING_SKIPPED)
                    );
                }
            });
        }
    });
}

// ------------------------------------------------------------ polygon soups

/// A random triangle or planar convex quad somewhere in the box `[0, 4]^3`.
fn random_polygon(rng: &mut Rng) -> Option<Surface> {
    let lo = DVec3::ZERO;
    let hi = DVec3::splat(4.0);
    let a = rng.point_in(lo, hi);
    let size = rng.range(0.2, 2.0);
    let mut dir = || {
        DVec3::new(
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
        ) * size
    };
    let (u, v) = (dir(), dir());
    if rng.chance(0.5) {
        surface(vec![a, a + u, a + v])
    } else {
        // A parallelogram, or a kite made convex by construction.
        let (u, v) = if u.cross(v).length() > 0.0 {
            (u, v)
        } else {
            (v, u)
        };
        let far = if rng.chance(0.5) {
            a + u + v
        } else {
            a + (u + v) * rng.range(0.6, 1.5)
        };
        surface(vec![a, a + u, far, a + v])
    }
}

fn soup(seed: u64, count: usize) -> Vec<Surface> {
    let mut rng = Rng(seed);
    let mut surfaces = Vec::new();
    while surfaces.len() < count {
        match rng.below(4) {
            0 | 1 => surfaces.extend(random_polygon(&mut rng)),
            2 => surfaces.extend(grid_rectangle(&mut rng)),
            _ => shared_edge_group(&mut rng, &mut surfaces),
        }
    }
    surfaces
}

#[test]
fn random_soups_agree_with_brute_force() {
    for seed in 0..12u64 {
        let surfaces = soup(seed, 40 + 20 * seed as usize);
        check_scene(&format!("soup {seed}"), &surfaces, 1000 + seed, 4_000);
    }
}

#[test]
fn soup_far_from_the_origin_agrees_with_brute_force() {
    // Round-off grows with the coordinates, not with the scene's size.
    let offset = DVec3::new(1.0e4, -3.0e3, 7.0e3);
    let surfaces: Vec<Surface> = soup(77, 150)
        .into_iter()
        .filter_map(|s| surface(s.polygon.iter().map(|p| *p + offset).collect()))
        .collect();
    check_scene("far soup", &surfaces, 78, 6_000);
}

/// The real files' mess in miniature: tessellated floor and column, tiny
/// triangles, needles, faces back to back; near the origin and 10 km from
/// it. Besides random segments, segments as the solver casts them: from a
/// point of one surface to a point of another (often on the column or a
/// back-to-back pair), shortened, skipping both.
#[test]
fn real_file_shaped_soup_agrees_with_brute_force() {
    for (k, offset) in [DVec3::ZERO, DVec3::new(1.0e4, 30.0, -7.0e3)]
        .into_iter()
        .enumerate()
    {
        let mut rng = Rng(40 + k as u64);
        let surfaces = real_file_soup(&mut rng, offset);
        assert!(surfaces.len() > 1500, "{}", surfaces.len());
        check_scene(
            &format!("real-file soup {k}"),
            &surfaces,
            50 + k as u64,
            3_000,
        );
        let brute = BruteForce::new(&surfaces);
        for (preset, settings) in all_settings() {
            let bsp = Bsp::with_settings(&surfaces, settings);
            let mut blocked = 0;
            for _ in 0..3_000 {
                let (i, j) = (rng.below(surfaces.len()), rng.below(surfaces.len()));
                let on = |rng: &mut Rng, s: &Surface| {
                    let p = &s.polygon;
                    let (a, b) = (rng.unit(), rng.unit());
                    let (a, b) = if a + b > 1.0 {
                        (1.0 - a, 1.0 - b)
                    } else {
                        (a, b)
                    };
                    p[0] + (p[1] - p[0]) * a + (p[2] - p[0]) * b
                };
                let (from, to) = shorten(on(&mut rng, &surfaces[i]), on(&mut rng, &surfaces[j]));
                let skip = [i as u32, j as u32];
                let expected = brute.occluded(from, to, skip);
                blocked += usize::from(expected);
                assert_eq!(
                    bsp.occluded(from, to, skip),
                    expected,
                    "{preset}: {from:?} -> {to:?} skipping {skip:?}"
                );
            }
            assert!(
                blocked > 100 && blocked < 2_900,
                "{preset}: {blocked} blocked"
            );
        }
    }
}

#[test]
fn needles_and_near_coplanar_surfaces_agree_with_brute_force() {
    let mut surfaces = Vec::new();
    let mut rng = Rng(5);
    for i in 0..30 {
        // Slivers: a long edge and a tip angle down to 1e-6 radians.
        let a = rng.point_in(DVec3::ZERO, DVec3::splat(4.0));
        let u = DVec3::new(
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
        );
        let w = u.any_orthonormal_vector() * u.length() * 10f64.powi(-(i % 7));
        surfaces.extend(surface(vec![a, a + u * 3.0, a + u * 3.0 + w]));
    }
    for k in 0..30 {
        // Squares tilted from z = 2 by 1e-12 .. 1e-5 radians, inside and
        // just outside the coplanar tolerance.
        let tilt = 10f64.powi(-5 - (k % 8));
        let x0 = 0.13 * k as f64;
        let p = vec![
            DVec3::new(x0, 0.0, 2.0),
            DVec3::new(x0 + 1.0, 0.0, 2.0 + tilt),
            DVec3::new(x0 + 1.0, 1.0, 2.0 + tilt),
            DVec3::new(x0, 1.0, 2.0),
        ];
        surfaces.extend(surface(p));
    }
    for _ in 0..20 {
        // Slightly non-planar quads, as the OBJ loader accepts them.
        let a = rng.point_in(DVec3::ZERO, DVec3::splat(3.0));
        let bend = DVec3::Z * rng.range(-1e-4, 1e-4);
        surfaces.extend(surface(vec![
            a,
            a + DVec3::X,
            a + DVec3::X + DVec3::Y + bend,
            a + DVec3::Y,
        ]));
    }
    surfaces.extend(soup(6, 60));
    check_scene("needles", &surfaces, 6, 8_000);
}

/// `segment_crosses` accepts points within a tolerance of each edge line,
/// which beyond a needle's tip reaches far past the tip: a segment passing
/// just beyond it, wholly in front of another surface's plane through the
/// tip, is blocked, and the tree must still find the needle behind that plane.
#[test]
fn crossings_beyond_a_needle_tip_are_found() {
    let h = 1.5e-6;
    let wall = surface(vec![
        DVec3::new(0.0, 5.0, -1.0),
        DVec3::new(0.0, 6.0, -1.0),
        DVec3::new(0.0, 6.0, 1.0),
        DVec3::new(0.0, 5.0, 1.0),
    ])
    .unwrap();
    let needle = surface(vec![
        DVec3::new(-3.0, -h, 0.0),
        DVec3::new(0.0, 0.0, 0.0),
        DVec3::new(-3.0, h, 0.0),
    ])
    .unwrap();
    let surfaces = vec![wall, needle];
    let brute = BruteForce::new(&surfaces);
    let mut blocked_beyond_tip = 0;
    for (preset, settings) in all_settings() {
        let bsp = Bsp::with_settings(&surfaces, settings);
        bsp.validate().unwrap();
        for k in 0..200 {
            let x = 1e-8 * 1.05f64.powi(k);
            let from = DVec3::new(x, 1e-13, 1.0);
            let to = DVec3::new(x, -1e-13, -1.0);
            let expected = brute.occluded(from, to, NOTHING_SKIPPED);
            blocked_beyond_tip += usize::from(expected);
            assert_eq!(
                bsp.occluded(from, to, NOTHING_SKIPPED),
                expected,
                "{preset}, x = {x}"
            );
        }
    }
    assert!(blocked_beyond_tip > 0, "the case is not exercised");
}

// --------------------------------------------------------- degenerate input

#[test]
fn one_surface() {
    let surfaces = vec![surface(vec![DVec3::ZERO, DVec3::X, DVec3::Y]).unwrap()];
    for (preset, settings) in all_settings() {
        let bsp = Bsp::with_settings(&surfaces, settings);
        bsp.validate().unwrap();
        let stats = bsp.stats();
        assert_eq!(
            (stats.nodes, stats.depth, stats.fragments, stats.splits),
            (1, 1, 1, 0),
            "{preset}"
        );
    }
    check_scene("one triangle", &surfaces, 9, 5_000);
    // The corners and edges themselves.
    let bsp = Bsp::new(&surfaces);
    let brute = BruteForce::new(&surfaces);
    for p in [
        DVec3::ZERO,
        DVec3::X,
        DVec3::Y,
        DVec3::new(0.5, 0.5, 0.0),
        DVec3::new(0.5, 0.0, 0.0),
    ] {
        for d in [DVec3::Z, DVec3::new(0.3, -0.2, 1.0), DVec3::X] {
            let (from, to) = (p - d, p + d);
            assert_eq!(
                bsp.occluded(from, to, NOTHING_SKIPPED),
                brute.occluded(from, to, NOTHING_SKIPPED),
                "{from:?} -> {to:?}"
            );
        }
    }
}

#[test]
fn all_surfaces_coplanar() {
    let mut rng = Rng(11);
    let mut surfaces = Vec::new();
    // A 6 x 6 grid of unit squares sharing edges, plus random triangles,
    // all in the plane z = 1, facing both ways.
    for i in 0..6 {
        for j in 0..6 {
            let (x, y) = (f64::from(i), f64::from(j));
            let mut p = vec![
                DVec3::new(x, y, 1.0),
                DVec3::new(x + 1.0, y, 1.0),
                DVec3::new(x + 1.0, y + 1.0, 1.0),
                DVec3::new(x, y + 1.0, 1.0),
            ];
            if (i + j) % 2 == 1 {
                p.reverse();
            }
            surfaces.push(surface(p).unwrap());
        }
    }
    for _ in 0..20 {
        let mut corner = || DVec3::new(rng.range(0.0, 6.0), rng.range(0.0, 6.0), 1.0);
        surfaces.extend(surface(vec![corner(), corner(), corner()]));
    }
    for (preset, settings) in all_settings() {
        let bsp = Bsp::with_settings(&surfaces, settings);
        bsp.validate().unwrap();
        let stats = bsp.stats();
        if settings.axis_candidates == 0 {
            // Surface planes only: one plane holds everything, one node,
            // nothing split.
            assert_eq!(
                (stats.nodes, stats.depth, stats.splits),
                (1, 1, 0),
                "{preset}"
            );
        } else {
            // Axis-aligned planes may divide the plane's fragments; none is
            // a leaf bucket (each node's fragments lie on its plane).
            assert_eq!(stats.leaves, 0, "{preset}: {stats:?}");
            if settings == BspSettings::sah() {
                assert!(stats.nodes > 1, "{preset}: {stats:?}");
            }
        }
    }
    check_scene("coplanar", &surfaces, 12, 8_000);
    // Segments lying in the plane: the exact squares never block them; a
    // random triangle's plane is z = 1 only up to round-off, so the oracle
    // decides.
    let brute = BruteForce::new(&surfaces);
    let squares = Bsp::new(&surfaces[..36]);
    let bsp = Bsp::new(&surfaces);
    for _ in 0..2_000 {
        let from = DVec3::new(rng.range(-1.0, 7.0), rng.range(-1.0, 7.0), 1.0);
        let to = DVec3::new(rng.range(-1.0, 7.0), rng.range(-1.0, 7.0), 1.0);
        assert!(!squares.occluded(from, to, NOTHING_SKIPPED));
        assert_eq!(
            bsp.occluded(from, to, NOTHING_SKIPPED),
            brute.occluded(from, to, NOTHING_SKIPPED)
        );
    }
}

#[test]
fn many_parallel_planes() {
    let mut rng = Rng(13);
    let mut surfaces = Vec::new();
    for k in 0..300 {
        let z = 0.01 * f64::from(k);
        let (x, y) = (rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
        let mut p = vec![
            DVec3::new(x, y, z),
            DVec3::new(x + 1.0, y, z),
            DVec3::new(x + 1.0, y + 1.0, z),
            DVec3::new(x, y + 1.0, z),
        ];
        if rng.chance(0.5) {
            p.reverse();
        }
        surfaces.push(surface(p).unwrap());
    }
    let balanced = Bsp::with_settings(&surfaces, BspSettings::classic());
    let stats = balanced.stats();
    // Parallel planes never split, and the balanced choice halves the stack.
    assert_eq!(stats.splits, 0);
    assert!(stats.depth <= 12, "{stats:?}");
    // The first-plane choice degenerates to a list, caught by the depth
    // limit.
    let fastest = Bsp::with_settings(&surfaces, BspSettings::fastest_build());
    fastest.validate().unwrap();
    assert_eq!(fastest.stats().depth, MAX_DEPTH);
    assert_eq!(fastest.stats().leaves, 1);
    check_scene("parallel", &surfaces, 14, 5_000);
    // A segment between two neighbouring planes tests nothing beyond them
    // (the classic tree stores each square on its own plane).
    let from = DVec3::new(0.5, 0.5, 1.502);
    let to = DVec3::new(0.4, 0.6, 1.508);
    let (blocked, tests, _) = balanced.occluded_counting(from, to, NOTHING_SKIPPED);
    assert_eq!((blocked, tests), (false, 0));
    // The surface area heuristic keeps thin stacks of a few squares in
    // leaf buckets (a random segment through such a stack crosses them
    // all), within its fragment budget.
    let sah = Bsp::new(&surfaces);
    let stats = sah.stats();
    assert!(stats.largest_leaf <= 16, "{stats:?}");
    assert!(
        stats.fragments as f64 <= sah.settings().max_growth * surfaces.len() as f64,
        "{stats:?}"
    );
}

#[test]
fn empty_scene() {
    let bsp = Bsp::new(&[]);
    bsp.validate().unwrap();
    assert_eq!(bsp.stats().nodes, 0);
    assert!(!bsp.occluded(DVec3::ZERO, DVec3::ONE, NOTHING_SKIPPED));
}
