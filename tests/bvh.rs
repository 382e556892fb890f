//! The BVH against the brute-force oracle: the built-in room and Cornell box,
//! random polygon soups (coplanar, edge-sharing, slivers, needles, tiny
//! polygons, far from the origin) and degenerate inputs, with every settings
//! preset. Answers must be identical, not merely close.

use glam::DVec3;
use proptest::prelude::*;
use radiosity::accel::brute::BruteForce;
use radiosity::accel::bvh::{Bvh, BvhSettings, MAX_DEPTH, SplitMethod};
use radiosity::accel::{Occluder, shorten};
use radiosity::mesh::{Mesh, MeshSettings, subsources};
use radiosity::scene::Surface;

mod common;

use common::soup::{
    Rng, bounds, builtin, grid_rectangle, numbered, random_point, random_skip, real_file_soup,
    shared_edge_group, surface,
};

const NOTHING_SKIPPED: [u32; 2] = [u32::MAX; 2];

/// Asserts that the tree and the oracle agree, with and without counting.
fn assert_agrees(
    bvh: &Bvh,
    brute: &BruteForce,
    from: DVec3,
    to: DVec3,
    skip: [u32; 2],
    what: &str,
) -> bool {
    let expected = brute.occluded(from, to, skip);
    let (answer, tested, visited) = bvh.occluded_counting(from, to, skip);
    assert_eq!(
        answer, expected,
        "{what}: from {from:?} to {to:?} skipping {skip:?}"
    );
    assert_eq!(bvh.occluded(from, to, skip), expected, "{what}");
    // Boxes tested: four per node of the four-wide tree, each at most once.
    assert!(visited as usize <= 4 * bvh.stats().wide_nodes, "{what}");
    let stats = bvh.stats();
    assert!(
        tested as usize <= stats.leaves * stats.max_leaf_size,
        "{what}"
    );
    answer
}

/// Runs `count` random queries (raw and shortened, with and without
/// skipped surfaces). Returns `(blocked, surfaces tested, nodes visited)`.
fn agree_on_random_segments(
    bvh: &Bvh,
    surfaces: &[Surface],
    rng: &mut Rng,
    count: usize,
    what: &str,
) -> (usize, u64, u64) {
    let brute = BruteForce::new(surfaces);
    let (lo, hi) = bounds(surfaces);
    let (mut blocked, mut tested, mut visited) = (0, 0u64, 0u64);
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
        blocked += usize::from(assert_agrees(bvh, &brute, from, to, skip, what));
        let (_, t, v) = bvh.occluded_counting(from, to, skip);
        tested += u64::from(t);
        visited += u64::from(v);
    }
    (blocked, tested, visited)
}

/// Segments ending exactly on every corner, on edge midpoints and at the
/// centroid of each surface (up to `limit` surfaces), from random points and
/// from other surfaces' corners.
fn agree_on_segments_ending_on_surfaces(
    bvh: &Bvh,
    surfaces: &[Surface],
    rng: &mut Rng,
    limit: usize,
    what: &str,
) {
    let brute = BruteForce::new(surfaces);
    let (lo, hi) = bounds(surfaces);
    let step = surfaces.len().div_ceil(limit).max(1);
    for (id, s) in surfaces.iter().enumerate().step_by(step) {
        let n = s.polygon.len();
        let mut targets: Vec<DVec3> = s.polygon.clone();
        targets.extend((0..n).map(|i| s.polygon[i].lerp(s.polygon[(i + 1) % n], 0.5)));
        targets.push(radiosity::geometry::centroid(&s.polygon));
        for to in targets {
            for _ in 0..3 {
                let from = if rng.chance(0.5) {
                    random_point(rng, surfaces, lo, hi)
                } else {
                    let other = &surfaces[rng.below(surfaces.len())].polygon;
                    other[rng.below(other.len())]
                };
                for skip in [
                    NOTHING_SKIPPED,
                    [id as u32, u32::MAX],
                    random_skip(rng, surfaces.len()),
                ] {
                    assert_agrees(bvh, &brute, from, to, skip, what);
                    assert_agrees(bvh, &brute, to, from, skip, what);
                }
            }
        }
    }
}

/// Every preset, plus variants that exercise leaf-size and bin limits.
fn all_settings() -> Vec<(&'static str, BvhSettings)> {
    let mut all = BvhSettings::presets().to_vec();
    all.push((
        "sah-2-bins-leaf-1",
        BvhSettings {
            bins: 2,
            leaf_size: 1,
            max_leaf_size: 1,
            ..BvhSettings::sah()
        },
    ));
    all.push((
        "sah-big-leaves",
        BvhSettings {
            leaf_size: 4,
            max_leaf_size: 32,
            primitive_cost: 0.1,
            ..BvhSettings::sah()
        },
    ));
    all
}

fn check_scene(name: &str, surfaces: &[Surface], seed: u64, count: usize) {
    let numbered = numbered(surfaces);
    let surfaces = &numbered[..];
    for (preset, settings) in all_settings() {
        let bvh = Bvh::with_settings(surfaces, settings);
        if let Err(e) = bvh.validate() {
            panic!("{name}, {preset}: {e}");
        }
        let stats = bvh.stats();
        assert!(stats.depth <= MAX_DEPTH, "{name}, {preset}: {stats:?}");
        assert!(stats.max_leaf_size <= bvh.settings().max_leaf_size);
        let mut rng = Rng(seed);
        let what = format!("{name}, {preset}");
        agree_on_random_segments(&bvh, surfaces, &mut rng, count, &what);
        agree_on_segments_ending_on_surfaces(&bvh, surfaces, &mut rng, 60, &what);
    }
}

// ------------------------------------------------------- the built-in scenes

#[test]
fn builtin_trees_are_valid_and_shallow() {
    for name in ["room", "cornell"] {
        let scene = builtin(name);
        for (preset, settings) in all_settings() {
            let bvh = Bvh::with_settings(&scene.surfaces, settings);
            bvh.validate()
                .unwrap_or_else(|e| panic!("{name}, {preset}: {e}"));
            let stats = bvh.stats();
            println!(
                "{name}, {preset}: {} surfaces, {stats:?}",
                scene.surfaces.len()
            );
            assert_eq!(stats.nodes, 2 * stats.leaves - 1, "{name}, {preset}");
            // A balanced-ish binary tree: depth within a few times log2(n).
            let log = (scene.surfaces.len() as f64).log2().ceil() as usize;
            assert!(stats.depth <= 3 * log + 2, "{name}, {preset}: {stats:?}");
        }
        let names: Vec<&str> = Bvh::new(&scene.surfaces)
            .build_statistics()
            .iter()
            .map(|(k, _)| *k)
            .collect();
        assert_eq!(
            names,
            [
                "nodes",
                "leaves",
                "depth",
                "max_leaf_size",
                "wide_nodes",
                "bytes"
            ]
        );
    }
}

#[test]
fn room_random_segments_agree_with_brute_force() {
    check_scene("room", &builtin("room").surfaces, 1, 12_000);
}

#[test]
fn cornell_random_segments_agree_with_brute_force() {
    check_scene("cornell", &builtin("cornell").surfaces, 2, 12_000);
}

/// Shadow segments as the solver casts them: from subsource centres to mesh
/// vertices, shortened, skipping the source's and receiver's surfaces; the
/// same unshortened and without skipping (ends exactly on surfaces and
/// shared edges); and vertex to vertex.
#[test]
fn subsource_to_vertex_segments_agree_with_brute_force() {
    for name in ["room", "cornell"] {
        let scene = builtin(name);
        let surfaces = &scene.surfaces;
        let mesh = Mesh::build(&scene, &MeshSettings::default()).expect("the scene meshes");
        let brute = BruteForce::new(surfaces);
        let mut rng = Rng(3);
        let mut sources = Vec::new();
        for patch in &mesh.patches {
            for sub in subsources(&patch.polygon, 2) {
                sources.push((sub.centroid, patch.surface));
            }
        }
        for (preset, settings) in all_settings() {
            let bvh = Bvh::with_settings(surfaces, settings);
            let what = format!("{name}, {preset}");
            for _ in 0..6_000 {
                let (c, source) = sources[rng.below(sources.len())];
                let v = &mesh.vertices[rng.below(mesh.vertices.len())];
                let (from, to) = if rng.chance(0.3) {
                    (c, v.position)
                } else {
                    shorten(c, v.position)
                };
                for skip in [[source, v.surface], NOTHING_SKIPPED, [v.surface, u32::MAX]] {
                    assert_agrees(&bvh, &brute, from, to, skip, &what);
                }
            }
            for _ in 0..6_000 {
                let a = &mesh.vertices[rng.below(mesh.vertices.len())];
                let b = &mesh.vertices[rng.below(mesh.vertices.len())];
                for skip in [[a.surface, b.surface], NOTHING_SKIPPED] {
                    assert_agrees(&bvh, &brute, a.position, b.position, skip, &what);
                }
            }
        }
    }
}

/// Not a timing: how many surfaces and nodes a solver-like query tests,
/// against brute force's all of them. Run with `--nocapture` to see them.
#[test]
fn room_queries_test_far_fewer_surfaces_than_brute_force() {
    let scene = builtin("room");
    let surfaces = &scene.surfaces;
    let mesh = Mesh::build(&scene, &MeshSettings::default()).expect("the room meshes");
    for (preset, settings) in all_settings() {
        let bvh = Bvh::with_settings(surfaces, settings);
        let mut rng = Rng(4);
        let (mut tested, mut visited, mut count) = (0u64, 0u64, 0u64);
        for _ in 0..20_000 {
            let patch = &mesh.patches[rng.below(mesh.patches.len())];
            let v = &mesh.vertices[rng.below(mesh.vertices.len())];
            let c = radiosity::geometry::centroid(&patch.polygon);
            let (from, to) = shorten(c, v.position);
            let (_, t, n) = bvh.occluded_counting(from, to, [patch.surface, v.surface]);
            tested += u64::from(t);
            visited += u64::from(n);
            count += 1;
        }
        let tested = tested as f64 / count as f64;
        let visited = visited as f64 / count as f64;
        println!(
            "room, {preset}: {:?}; patch-to-vertex: {tested:.1} surfaces tested, {visited:.1} nodes \
             visited per query; brute force: {}",
            bvh.stats(),
            surfaces.len()
        );
        assert!(tested < 0.25 * surfaces.len() as f64, "{preset}: {tested}");
    }
}

#[test]
fn queries_from_many_threads_agree() {
    let scene = builtin("room");
    let surfaces = &scene.surfaces;
    let bvh = Bvh::new(surfaces);
    let brute = BruteForce::new(surfaces);
    std::thread::scope(|scope| {
        for t in 0..4u64 {
            let (bvh, brute): (&dyn Occluder, &dyn Occluder) = (&bvh, &brute);
            scope.spawn(move || {
                let mut rng = Rng(100 + t);
                let (lo, hi) = bounds(surfaces);
                for _ in 0..3_000 {
                    let from = random_point(&mut rng, surfaces, lo, hi);
                    let to = random_point(&mut rng, surfaces, lo, hi);
                    assert_eq!(
                        bvh.occluded(from, to, NOTHING_SKIPPED),
                        brute.occluded(from, to, NOTHING_SKIPPED)
                    );
                }
            });
        }
    });
}

// ------------------------------------------------------------ polygon soups

/// A random triangle or planar convex quad of size about `size` somewhere in
/// the box `[0, 4]^3`.
fn random_polygon(rng: &mut Rng, size: f64) -> Option<Surface> {
    let a = rng.point_in(DVec3::ZERO, DVec3::splat(4.0));
    let (u, v) = (rng.direction() * size, rng.direction() * size);
    if rng.chance(0.5) {
        surface(vec![a, a + u, a + v])
    } else {
        // A parallelogram, or a kite made convex by construction.
        let far = if rng.chance(0.5) {
            a + u + v
        } else {
            a + (u + v) * rng.range(0.6, 1.5)
        };
        surface(vec![a, a + u, far, a + v])
    }
}

/// A needle: a long edge and a tip angle down to 1e-6 radians.
fn needle(rng: &mut Rng, sharpness: i32) -> Option<Surface> {
    let a = rng.point_in(DVec3::ZERO, DVec3::splat(4.0));
    let u = rng.direction();
    let w = u.any_orthonormal_vector() * u.length() * 10f64.powi(-sharpness);
    surface(vec![a, a + u * 3.0, a + u * 3.0 + w])
}

fn soup(seed: u64, count: usize) -> Vec<Surface> {
    let mut rng = Rng(seed);
    let mut surfaces = Vec::new();
    while surfaces.len() < count {
        match rng.below(7) {
            0 | 1 => {
                let size = random_size(&mut rng);
                surfaces.extend(random_polygon(&mut rng, size));
            }
            2 | 3 => surfaces.extend(grid_rectangle(&mut rng)),
            4 => {
                let sharpness = 1 + rng.below(6) as i32;
                surfaces.extend(needle(&mut rng, sharpness));
            }
            _ => shared_edge_group(&mut rng, &mut surfaces),
        }
    }
    surfaces
}

/// Polygon sizes from tiny (1e-6) to large (2).
fn random_size(rng: &mut Rng) -> f64 {
    if rng.chance(0.2) {
        10f64.powi(-(2 + rng.below(5) as i32))
    } else {
        rng.range(0.2, 2.0)
    }
}

#[test]
fn random_soups_agree_with_brute_force() {
    for seed in 0..10u64 {
        let surfaces = soup(seed, 40 + 25 * seed as usize);
        check_scene(&format!("soup {seed}"), &surfaces, 1000 + seed, 2_500);
    }
}

/// The real files' mess in miniature (tessellated floor and column, tiny
/// triangles, needles, faces back to back), near the origin and 10 km from
/// it, with random segments and with segments from one surface's point to
/// another's, shortened and skipping both, as the solver casts them.
#[test]
fn real_file_shaped_soup_agrees_with_brute_force() {
    for (k, offset) in [DVec3::ZERO, DVec3::new(1.0e4, 30.0, -7.0e3)]
        .into_iter()
        .enumerate()
    {
        let mut rng = Rng(60 + k as u64);
        let surfaces = real_file_soup(&mut rng, offset);
        check_scene(
            &format!("real-file soup {k}"),
            &surfaces,
            70 + k as u64,
            3_000,
        );
        let brute = BruteForce::new(&surfaces);
        for (preset, settings) in all_settings() {
            let bvh = Bvh::with_settings(&surfaces, settings);
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
                let what = format!("real-file soup {k}, {preset}");
                blocked += usize::from(assert_agrees(
                    &bvh,
                    &brute,
                    from,
                    to,
                    [i as u32, j as u32],
                    &what,
                ));
            }
            assert!(
                blocked > 100 && blocked < 2_900,
                "{preset}: {blocked} blocked"
            );
        }
    }
}

#[test]
fn soups_far_from_the_origin_agree_with_brute_force() {
    // Round-off grows with the coordinates, not with the scene's size: at
    // 1e6 an f32 box coordinate is only good to 0.06.
    for (seed, offset) in [
        (77, DVec3::new(1.0e4, -3.0e3, 7.0e3)),
        (78, DVec3::new(-2.5e6, 1.0e6, 3.3e5)),
    ] {
        let surfaces: Vec<Surface> = soup(seed, 150)
            .into_iter()
            .filter_map(|s| surface(s.polygon.iter().map(|p| *p + offset).collect()))
            .collect();
        check_scene(&format!("soup at {offset}"), &surfaces, seed, 4_000);
    }
}

#[test]
fn tiny_slivers_and_near_coplanar_surfaces_agree_with_brute_force() {
    let mut surfaces = Vec::new();
    let mut rng = Rng(5);
    for i in 0..30 {
        surfaces.extend(needle(&mut rng, i % 7));
    }
    for k in 0..30 {
        // Squares tilted from z = 2 by 1e-12 .. 1e-5 radians.
        let tilt = 10f64.powi(-5 - (k % 8));
        let x0 = 0.13 * f64::from(k);
        surfaces.extend(surface(vec![
            DVec3::new(x0, 0.0, 2.0),
            DVec3::new(x0 + 1.0, 0.0, 2.0 + tilt),
            DVec3::new(x0 + 1.0, 1.0, 2.0 + tilt),
            DVec3::new(x0, 1.0, 2.0),
        ]));
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
    for _ in 0..40 {
        // Tiny polygons: 1e-9 .. 1e-4 across.
        let size = 10f64.powi(-4 - rng.below(6) as i32);
        surfaces.extend(random_polygon(&mut rng, size));
    }
    surfaces.extend(soup(6, 60));
    check_scene("slivers", &surfaces, 6, 6_000);
}

/// `segment_crosses` accepts points within a tolerance of each edge line,
/// which beyond a needle's tip reaches far past the tip (`tolerance /
/// half-angle`): the needle's box must include that region. The sharper
/// needle's region reaches further than the query's round-off margin.
#[test]
fn crossings_beyond_a_needle_tip_are_found() {
    for h in [1.5e-6, 1e-9] {
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
        let mut furthest = 0.0f64;
        for (preset, settings) in all_settings() {
            let bvh = Bvh::with_settings(&surfaces, settings);
            bvh.validate().unwrap();
            for k in 0..300 {
                let x = 1e-8 * 1.05f64.powi(k);
                let from = DVec3::new(x, 1e-13, 1.0);
                let to = DVec3::new(x, -1e-13, -1.0);
                if assert_agrees(&bvh, &brute, from, to, NOTHING_SKIPPED, preset) {
                    blocked_beyond_tip += 1;
                    furthest = furthest.max(x);
                }
            }
        }
        assert!(blocked_beyond_tip > 0, "h = {h}: the case is not exercised");
        if h < 1e-8 {
            // Beyond the 2e-6 relative margin on a scene of scale 6.
            assert!(furthest > 1e-4, "h = {h}: blocked up to {furthest}");
        }
    }
}

/// Found by the property test below against an early tree without the
/// tolerance region or the round-off margin: a segment from a triangle's
/// corner.
#[test]
fn segment_from_a_corner_of_a_tilted_triangle() {
    let surfaces = vec![
        surface(vec![
            DVec3::new(1.5, 0.5, 1.0),
            DVec3::new(0.5, 0.0, 0.5),
            DVec3::new(0.0, 1.0, 0.0),
        ])
        .unwrap(),
    ];
    let brute = BruteForce::new(&surfaces);
    let (a, b) = (DVec3::new(0.0, 1.0, 0.0), DVec3::new(0.5, 0.0, 0.0));
    for (preset, settings) in all_settings() {
        let bvh = Bvh::with_settings(&surfaces, settings);
        for (from, to) in [(a, b), shorten(a, b), (b, a), shorten(b, a)] {
            assert_agrees(&bvh, &brute, from, to, NOTHING_SKIPPED, preset);
        }
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
    check_scene("parallel", &surfaces, 14, 3_000);
    // A short segment between two neighbouring planes tests at most a leaf
    // or two.
    let bvh = Bvh::new(&surfaces);
    let (blocked, tested, _) = bvh.occluded_counting(
        DVec3::new(0.5, 0.5, 1.502),
        DVec3::new(0.4, 0.6, 1.508),
        NOTHING_SKIPPED,
    );
    assert!(!blocked);
    assert!(tested <= 2 * bvh.stats().max_leaf_size as u32, "{tested}");
}

/// A geometric series of planes, which a surface-area split cuts into a
/// lopsided tree; the median fallback keeps its depth within the stack.
#[test]
fn lopsided_scene_stays_within_the_depth_limit() {
    let surfaces: Vec<Surface> = (0..400)
        .map(|k| {
            let z = 1.0 - 0.97f64.powi(k);
            surface(vec![
                DVec3::new(0.0, 0.0, z),
                DVec3::new(1.0, 0.0, z),
                DVec3::new(1.0, 1.0, z),
                DVec3::new(0.0, 1.0, z),
            ])
            .unwrap()
        })
        .collect();
    for (preset, settings) in all_settings() {
        let bvh = Bvh::with_settings(&surfaces, settings);
        bvh.validate().unwrap_or_else(|e| panic!("{preset}: {e}"));
        assert!(bvh.stats().depth <= MAX_DEPTH);
    }
    check_scene("geometric", &surfaces, 15, 2_000);
}

// --------------------------------------------------------- degenerate input

#[test]
fn empty_scene() {
    for (preset, settings) in all_settings() {
        let bvh = Bvh::with_settings(&[], settings);
        bvh.validate().unwrap_or_else(|e| panic!("{preset}: {e}"));
        assert_eq!(bvh.stats().nodes, 0);
        assert!(!bvh.occluded(DVec3::ZERO, DVec3::ONE, NOTHING_SKIPPED));
        assert_eq!(
            bvh.build_statistics(),
            [
                ("nodes", 0),
                ("leaves", 0),
                ("depth", 0),
                ("max_leaf_size", 0),
                ("wide_nodes", 0),
                ("bytes", 0)
            ]
        );
    }
}

#[test]
fn one_surface() {
    let surfaces = vec![surface(vec![DVec3::ZERO, DVec3::X, DVec3::Y]).unwrap()];
    for (preset, settings) in all_settings() {
        let bvh = Bvh::with_settings(&surfaces, settings);
        bvh.validate().unwrap();
        let s = bvh.stats();
        assert_eq!(
            (s.nodes, s.leaves, s.depth, s.max_leaf_size),
            (1, 1, 1, 1),
            "{preset}"
        );
    }
    check_scene("one triangle", &surfaces, 9, 3_000);
    // The corners and edges themselves, crossed from every side.
    let bvh = Bvh::new(&surfaces);
    let brute = BruteForce::new(&surfaces);
    for p in [
        DVec3::ZERO,
        DVec3::X,
        DVec3::Y,
        DVec3::new(0.5, 0.5, 0.0),
        DVec3::new(0.5, 0.0, 0.0),
        DVec3::new(0.0, 0.25, 0.0),
    ] {
        for d in [
            DVec3::Z,
            DVec3::new(0.3, -0.2, 1.0),
            DVec3::new(-1e-9, 1e-9, 1.0),
            DVec3::X,
        ] {
            assert_agrees(&bvh, &brute, p - d, p + d, NOTHING_SKIPPED, "triangle");
            assert_agrees(&bvh, &brute, p, p + d, NOTHING_SKIPPED, "triangle");
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
    check_scene("coplanar", &surfaces, 12, 5_000);
    // Segments through the grid's shared edges and corners, and lying in
    // the plane.
    let brute = BruteForce::new(&surfaces);
    for (preset, settings) in all_settings() {
        let bvh = Bvh::with_settings(&surfaces, settings);
        for _ in 0..1_000 {
            let (x, y) = (f64::from(rng.below(7) as u32), rng.range(0.0, 6.0));
            let p = if rng.chance(0.5) {
                DVec3::new(x, y, 1.0)
            } else {
                DVec3::new(y, x, 1.0)
            };
            let d = rng.direction();
            assert_agrees(&bvh, &brute, p - d, p + d, NOTHING_SKIPPED, preset);
            let from = DVec3::new(rng.range(-1.0, 7.0), rng.range(-1.0, 7.0), 1.0);
            let to = DVec3::new(rng.range(-1.0, 7.0), rng.range(-1.0, 7.0), 1.0);
            assert_agrees(&bvh, &brute, from, to, NOTHING_SKIPPED, preset);
        }
    }
}

#[test]
fn median_preset_builds_a_balanced_tree() {
    let surfaces = soup(21, 500);
    let bvh = Bvh::with_settings(&surfaces, BvhSettings::median());
    assert_eq!(bvh.settings().split, SplitMethod::ObjectMedian);
    bvh.validate().unwrap();
    let stats = bvh.stats();
    // Halving 500 down to leaves of at most 4: depth 8 (root = 1).
    assert_eq!(stats.depth, 8, "{stats:?}");
    assert!(stats.max_leaf_size <= 4);
}

#[test]
fn builds_are_deterministic() {
    let surfaces = soup(22, 300);
    for (preset, settings) in all_settings() {
        let a = Bvh::with_settings(&surfaces, settings);
        let b = Bvh::with_settings(&surfaces, settings);
        assert_eq!(a.stats(), b.stats(), "{preset}");
        let mut rng = Rng(23);
        let (lo, hi) = bounds(&surfaces);
        for _ in 0..500 {
            let from = random_point(&mut rng, &surfaces, lo, hi);
            let to = random_point(&mut rng, &surfaces, lo, hi);
            assert_eq!(
                a.occluded_counting(from, to, NOTHING_SKIPPED),
                b.occluded_counting(from, to, NOTHING_SKIPPED),
                "{preset}"
            );
        }
    }
}

// ------------------------------------------------------------------ proptest

/// A point on a coarse grid, so polygons share corners and edges and
/// segments pass exactly through them.
fn grid_point() -> impl Strategy<Value = DVec3> {
    (0..5i32, 0..5i32, 0..5i32)
        .prop_map(|(x, y, z)| DVec3::new(f64::from(x), f64::from(y), f64::from(z)) * 0.5)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn grid_triangles_agree_with_brute_force(
        triangles in prop::collection::vec((grid_point(), grid_point(), grid_point()), 0..40),
        segments in prop::collection::vec((grid_point(), grid_point(), 0u32..45, 0u32..45), 1..60),
    ) {
        let surfaces: Vec<Surface> = triangles
            .into_iter()
            .filter_map(|(a, b, c)| surface(vec![a, b, c]))
            .collect();
        let brute = BruteForce::new(&surfaces);
        for (_, settings) in all_settings() {
            let bvh = Bvh::with_settings(&surfaces, settings);
            prop_assert!(bvh.validate().is_ok());
            for &(from, to, s0, s1) in &segments {
                for (from, to) in [(from, to), shorten(from, to)] {
                    let skip = [s0, s1];
                    prop_assert_eq!(bvh.occluded(from, to, skip), brute.occluded(from, to, skip));
                }
            }
        }
    }
}
