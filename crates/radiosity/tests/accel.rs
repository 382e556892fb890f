//! Every shadow-ray accelerator against the brute-force oracle, written
//! once: each test loops over [`Accel::ALL`] (a new accelerator is tested
//! without touching this file) and over each accelerator's settings
//! variants, and calls [`Occluder::validate`] on every structure it builds.
//! The scenes: the built-in room and Cornell box, random polygon soups
//! (coplanar, edge-sharing, slivers, needles, tiny polygons, far from the
//! origin), soups shaped like the real files, and degenerate inputs.
//! Answers must be identical, not merely close.
//!
//! Checks only one accelerator can make (tree sizes, depth limits, balance,
//! determinism) are in `tests/bsp.rs` and `tests/bvh.rs`; the per-structure
//! and per-query invariants of the trees are hooked in here through
//! [`Built`], so they hold on every scene below.

use glam::DVec3;
use proptest::prelude::*;
use radiosity::accel::Accel;
use radiosity::accel::brute::BruteForce;
use radiosity::accel::bsp::{self, Bsp};
use radiosity::accel::bvh::{self, Bvh};
use radiosity::accel::{Occluder, shorten};
use radiosity::mesh::{Mesh, MeshSettings, subsources};
use radiosity::scene::{Surface, bounds_of};

mod common;

use common::soup::{
    Rng, bsp_settings, builtin, bvh_settings, coplanar_grid, geometric_stack, needle, numbered,
    offset, one_triangle, parallel_squares, random_point, random_polygon_of_size, random_skip,
    real_file_soup, soup, surface, varied_soup,
};

const NOTHING_SKIPPED: [u32; 2] = [u32::MAX; 2];

// ------------------------------------------------------------ the variants

/// One structure built by one accelerator with one settings variant; the
/// tree types are kept so their own invariants can be checked.
enum Built<'a> {
    Bsp(Bsp<'a>),
    Bvh(Bvh<'a>),
    /// Brute force, and any accelerator without settings variants here.
    Other(Box<dyn Occluder + 'a>),
}

struct Variant<'a> {
    /// `accelerator` or `accelerator/preset`.
    name: String,
    built: Built<'a>,
}

impl Variant<'_> {
    fn occluder(&self) -> &dyn Occluder {
        match &self.built {
            Built::Bsp(b) => b,
            Built::Bvh(b) => b,
            Built::Other(b) => b.as_ref(),
        }
    }

    /// `validate()` and the statistics invariants of the tree over
    /// `surfaces` surfaces.
    fn check_structure(&self, surfaces: usize, what: &str) {
        let name = &self.name;
        if let Err(e) = self.occluder().validate() {
            panic!("{what}, {name}: {e}");
        }
        match &self.built {
            Built::Bsp(b) => {
                let (stats, settings) = (b.stats(), b.settings());
                assert_eq!(stats.fragments, surfaces + stats.splits, "{what}, {name}");
                assert!(stats.depth <= settings.max_depth.min(bsp::MAX_DEPTH));
                if settings.axis_candidates == 0 {
                    // Every node of a pure auto-partition stores a fragment.
                    assert!(stats.nodes <= stats.fragments, "{what}, {name}: {stats:?}");
                } else {
                    // Axis-aligned cuts of empty space add nodes without
                    // fragments, each only if it lowers the cost: a few per
                    // leaf.
                    assert!(
                        stats.nodes <= 3 * stats.fragments,
                        "{what}, {name}: {stats:?}"
                    );
                }
            }
            Built::Bvh(b) => {
                let stats = b.stats();
                assert!(stats.depth <= bvh::MAX_DEPTH, "{what}, {name}: {stats:?}");
                assert!(stats.max_leaf_size <= b.settings().max_leaf_size);
            }
            Built::Other(_) => {}
        }
    }

    /// Per-query bounds on the counts `occluded_counting` returns.
    fn check_counts(&self, tested: u32, visited: u32, what: &str) {
        if let Built::Bvh(b) = &self.built {
            // Boxes tested: four per node of the four-wide tree, each at
            // most once.
            let stats = b.stats();
            assert!(visited as usize <= 4 * stats.wide_nodes, "{what}");
            assert!(
                tested as usize <= stats.leaves * stats.max_leaf_size,
                "{what}"
            );
        }
    }
}

/// Every settings variant of `accel` over `surfaces`; an accelerator
/// without variants listed here is built with its defaults.
fn variants_of(accel: Accel, surfaces: &[Surface]) -> Vec<Variant<'_>> {
    let name = |preset: &str| format!("{}/{preset}", accel.name());
    match accel {
        Accel::Bsp => bsp_settings()
            .into_iter()
            .map(|(preset, settings)| Variant {
                name: name(preset),
                built: Built::Bsp(Bsp::with_settings(surfaces, settings)),
            })
            .collect(),
        Accel::Bvh => bvh_settings()
            .into_iter()
            .map(|(preset, settings)| Variant {
                name: name(preset),
                built: Built::Bvh(Bvh::with_settings(surfaces, settings)),
            })
            .collect(),
        _ => vec![Variant {
            name: accel.name().to_string(),
            built: Built::Other(accel.build(surfaces)),
        }],
    }
}

/// Every settings variant of every accelerator over `surfaces`.
fn all_variants(surfaces: &[Surface]) -> Vec<Variant<'_>> {
    Accel::ALL
        .into_iter()
        .flat_map(|accel| variants_of(accel, surfaces))
        .collect()
}

/// Asserts that the variant and the oracle agree, with and without
/// counting; returns the answer.
fn assert_agrees(
    variant: &Variant,
    brute: &BruteForce,
    from: DVec3,
    to: DVec3,
    skip: [u32; 2],
    what: &str,
) -> bool {
    let expected = brute.occluded(from, to, skip);
    let occluder = variant.occluder();
    let (answer, tested, visited) = occluder.occluded_counting(from, to, skip);
    let name = &variant.name;
    assert_eq!(
        answer, expected,
        "{what}, {name}: from {from:?} to {to:?} skipping {skip:?}"
    );
    assert_eq!(
        occluder.occluded(from, to, skip),
        expected,
        "{what}, {name}"
    );
    variant.check_counts(tested, visited, &format!("{what}, {name}"));
    answer
}

/// Runs `count` random queries (raw and shortened, with and without
/// skipped surfaces). Returns `(blocked, surfaces tested)`.
fn agree_on_random_segments(
    variant: &Variant,
    surfaces: &[Surface],
    rng: &mut Rng,
    count: usize,
    what: &str,
) -> (usize, u64) {
    let brute = BruteForce::new(surfaces);
    let (lo, hi) = bounds_of(surfaces);
    let (mut blocked, mut tested) = (0, 0u64);
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
        blocked += usize::from(assert_agrees(variant, &brute, from, to, skip, what));
        tested += u64::from(variant.occluder().occluded_counting(from, to, skip).1);
    }
    (blocked, tested)
}

/// Segments ending exactly on every corner, on edge midpoints and at the
/// centroid of each surface (up to `limit` surfaces), from random points and
/// from other surfaces' corners.
fn agree_on_segments_ending_on_surfaces(
    variant: &Variant,
    surfaces: &[Surface],
    rng: &mut Rng,
    limit: usize,
    what: &str,
) {
    let brute = BruteForce::new(surfaces);
    let (lo, hi) = bounds_of(surfaces);
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
                    assert_agrees(variant, &brute, from, to, skip, what);
                    assert_agrees(variant, &brute, to, from, skip, what);
                }
            }
        }
    }
}

/// Builds every variant over the surfaces (each its own surface id),
/// checks its structure, and runs `count` random segments (from a generator
/// seeded with `seed`) and segments ending on up to 60 surfaces.
fn check_scene(name: &str, surfaces: &[Surface], seed: u64, count: usize) {
    let numbered = numbered(surfaces);
    let surfaces = &numbered[..];
    for variant in all_variants(surfaces) {
        variant.check_structure(surfaces.len(), name);
        let mut rng = Rng(seed);
        agree_on_random_segments(&variant, surfaces, &mut rng, count, name);
        agree_on_segments_ending_on_surfaces(&variant, surfaces, &mut rng, 60, name);
    }
}

/// A point of triangle `p[0], p[1], p[2]` of a surface.
fn point_on(rng: &mut Rng, s: &Surface) -> DVec3 {
    let p = &s.polygon;
    let (a, b) = (rng.unit(), rng.unit());
    let (a, b) = if a + b > 1.0 {
        (1.0 - a, 1.0 - b)
    } else {
        (a, b)
    };
    p[0] + (p[1] - p[0]) * a + (p[2] - p[0]) * b
}

/// Every accelerator of [`Accel::ALL`] has variants here, named after it;
/// the BSP and the BVH with each of their settings variants.
#[test]
fn every_accelerator_is_tested() {
    let surfaces = one_triangle();
    for accel in Accel::ALL {
        let variants = variants_of(accel, &surfaces);
        assert!(!variants.is_empty(), "{}", accel.name());
        for variant in &variants {
            assert!(variant.name.starts_with(accel.name()), "{}", variant.name);
        }
        let expected = match accel {
            Accel::Bsp => bsp_settings().len(),
            Accel::Bvh => bvh_settings().len(),
            _ => 1,
        };
        assert_eq!(variants.len(), expected, "{}", accel.name());
    }
}

// ------------------------------------------------------- the built-in scenes

#[test]
fn room_random_segments_agree_with_brute_force() {
    check_scene("room", &builtin("room").surfaces, 1, 20_000);
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
    for (name, seed, count) in [
        ("room", 2, 15_000),
        ("room", 3, 6_000),
        ("cornell", 3, 6_000),
    ] {
        let scene = builtin(name);
        let surfaces = &scene.surfaces;
        let mesh = Mesh::build(&scene, &MeshSettings::default()).expect("the scene meshes");
        let brute = BruteForce::new(surfaces);
        let mut rng = Rng(seed);
        let mut sources = Vec::new();
        for patch in &mesh.patches {
            for sub in subsources(&patch.polygon, 2) {
                sources.push((sub.centroid, patch.surface));
            }
        }
        for variant in all_variants(surfaces) {
            for _ in 0..count {
                let (c, source) = sources[rng.below(sources.len())];
                let v = &mesh.vertices[rng.below(mesh.vertices.len())];
                let (from, to) = if rng.chance(0.3) {
                    (c, v.position)
                } else {
                    shorten(c, v.position)
                };
                for skip in [[source, v.surface], NOTHING_SKIPPED, [v.surface, u32::MAX]] {
                    assert_agrees(&variant, &brute, from, to, skip, name);
                }
            }
            for _ in 0..count {
                let a = &mesh.vertices[rng.below(mesh.vertices.len())];
                let b = &mesh.vertices[rng.below(mesh.vertices.len())];
                for skip in [[a.surface, b.surface], NOTHING_SKIPPED] {
                    assert_agrees(&variant, &brute, a.position, b.position, skip, name);
                }
            }
        }
    }
}

/// Not a timing: how many surfaces a solver-like query tests, against
/// brute force's all of them. Run with `--nocapture` to see the figures.
#[test]
fn room_queries_test_far_fewer_surfaces_than_brute_force() {
    let scene = builtin("room");
    let surfaces = &scene.surfaces;
    let mesh = Mesh::build(&scene, &MeshSettings::default()).expect("the room meshes");
    for accel in Accel::ALL {
        // The BVH was held to a quarter, the BSP to half; brute force is
        // the baseline.
        let fraction = match accel {
            Accel::Brute => 1.0,
            Accel::Bvh => 0.25,
            _ => 0.5,
        };
        for variant in variants_of(accel, surfaces) {
            let name = &variant.name;
            let mut rng = Rng(3);
            let (blocked, tested) =
                agree_on_random_segments(&variant, surfaces, &mut rng, 20_000, "room");
            let random_mean = tested as f64 / 20_000.0;
            for seed in [3, 4] {
                if seed == 4 {
                    rng = Rng(4);
                }
                // Solver-like queries: subsource centre of a patch to a vertex.
                let (mut solver_tested, mut visited) = (0u64, 0u64);
                for _ in 0..20_000 {
                    let patch = &mesh.patches[rng.below(mesh.patches.len())];
                    let v = &mesh.vertices[rng.below(mesh.vertices.len())];
                    let c = radiosity::geometry::centroid(&patch.polygon);
                    let (from, to) = shorten(c, v.position);
                    let (_, t, n) =
                        variant
                            .occluder()
                            .occluded_counting(from, to, [patch.surface, v.surface]);
                    solver_tested += u64::from(t);
                    visited += u64::from(n);
                }
                let solver_mean = solver_tested as f64 / 20_000.0;
                let visited = visited as f64 / 20_000.0;
                println!(
                    "room, {name}, seed {seed}: {:?}; random segments: {random_mean:.1} surfaces \
                     tested per query ({:.0}% blocked); patch-to-vertex: {solver_mean:.1} \
                     surfaces tested, {visited:.1} nodes visited; brute force: {}",
                    variant.occluder().build_statistics(),
                    100.0 * blocked as f64 / 20_000.0,
                    surfaces.len()
                );
                let limit = fraction * surfaces.len() as f64;
                assert!(
                    solver_mean < limit || (accel == Accel::Brute && solver_mean <= limit),
                    "{name}: {solver_mean}"
                );
            }
        }
    }
}

#[test]
fn queries_from_many_threads_agree() {
    let scene = builtin("room");
    let surfaces = &scene.surfaces;
    let brute = BruteForce::new(surfaces);
    for accel in Accel::ALL {
        let built = accel.build(surfaces);
        let (built, brute): (&dyn Occluder, &dyn Occluder) = (built.as_ref(), &brute);
        std::thread::scope(|scope| {
            for t in 0..4u64 {
                scope.spawn(move || {
                    let mut rng = Rng(100 + t);
                    let (lo, hi) = bounds_of(surfaces);
                    for _ in 0..5_000 {
                        let from = random_point(&mut rng, surfaces, lo, hi);
                        let to = random_point(&mut rng, surfaces, lo, hi);
                        assert_eq!(
                            built.occluded(from, to, NOTHING_SKIPPED),
                            brute.occluded(from, to, NOTHING_SKIPPED),
                            "{}",
                            accel.name()
                        );
                    }
                });
            }
        });
    }
}

// ------------------------------------------------------------ polygon soups

#[test]
fn random_soups_agree_with_brute_force() {
    for seed in 0..12u64 {
        let surfaces = soup(seed, 40 + 20 * seed as usize);
        check_scene(&format!("soup {seed}"), &surfaces, 1000 + seed, 4_000);
    }
    for seed in 0..10u64 {
        let surfaces = varied_soup(seed, 40 + 25 * seed as usize);
        check_scene(
            &format!("varied soup {seed}"),
            &surfaces,
            1000 + seed,
            2_500,
        );
    }
}

#[test]
fn soups_far_from_the_origin_agree_with_brute_force() {
    // Round-off grows with the coordinates, not with the scene's size: at
    // 1e6 an f32 box coordinate is only good to 0.06.
    let near = DVec3::new(1.0e4, -3.0e3, 7.0e3);
    let far = DVec3::new(-2.5e6, 1.0e6, 3.3e5);
    check_scene("far soup", &offset(soup(77, 150), near), 78, 6_000);
    for (seed, at) in [(77, near), (78, far)] {
        let surfaces = offset(varied_soup(seed, 150), at);
        check_scene(&format!("varied soup at {at}"), &surfaces, seed, 4_000);
    }
}

/// The real files' mess in miniature: tessellated floor and column, tiny
/// triangles, needles, faces back to back; near the origin and 10 km from
/// it. Besides random segments, segments as the solver casts them: from a
/// point of one surface to a point of another (often on the column or a
/// back-to-back pair), shortened, skipping both.
#[test]
fn real_file_shaped_soup_agrees_with_brute_force() {
    for (soup_seed, check_seed) in [(40, 50), (60, 70)] {
        for (k, at) in [DVec3::ZERO, DVec3::new(1.0e4, 30.0, -7.0e3)]
            .into_iter()
            .enumerate()
        {
            let mut rng = Rng(soup_seed + k as u64);
            let surfaces = real_file_soup(&mut rng, at);
            assert!(surfaces.len() > 1500, "{}", surfaces.len());
            let what = format!("real-file soup {soup_seed}, {k}");
            check_scene(&what, &surfaces, check_seed + k as u64, 3_000);
            let brute = BruteForce::new(&surfaces);
            for variant in all_variants(&surfaces) {
                let mut blocked = 0;
                for _ in 0..3_000 {
                    let (i, j) = (rng.below(surfaces.len()), rng.below(surfaces.len()));
                    let (from, to) = shorten(
                        point_on(&mut rng, &surfaces[i]),
                        point_on(&mut rng, &surfaces[j]),
                    );
                    let skip = [i as u32, j as u32];
                    blocked += usize::from(assert_agrees(&variant, &brute, from, to, skip, &what));
                }
                assert!(
                    blocked > 100 && blocked < 2_900,
                    "{what}, {}: {blocked} blocked",
                    variant.name
                );
            }
        }
    }
}

/// Needles with tip angles down to 1e-6 radians, squares tilted from
/// z = 2 by 1e-12 .. 1e-5 radians (inside and just outside the coplanar
/// tolerance), slightly non-planar quads as the OBJ loader accepts them,
/// and (`tiny`) polygons 1e-9 .. 1e-4 across, on top of a soup.
fn slivers(tiny: bool) -> Vec<Surface> {
    let mut surfaces = Vec::new();
    let mut rng = Rng(5);
    for i in 0..30 {
        surfaces.extend(needle(&mut rng, i % 7));
    }
    for k in 0..30 {
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
        let a = rng.point_in(DVec3::ZERO, DVec3::splat(3.0));
        let bend = DVec3::Z * rng.range(-1e-4, 1e-4);
        surfaces.extend(surface(vec![
            a,
            a + DVec3::X,
            a + DVec3::X + DVec3::Y + bend,
            a + DVec3::Y,
        ]));
    }
    if tiny {
        for _ in 0..40 {
            let size = 10f64.powi(-4 - rng.below(6) as i32);
            surfaces.extend(random_polygon_of_size(&mut rng, size));
        }
        surfaces.extend(varied_soup(6, 60));
    } else {
        surfaces.extend(soup(6, 60));
    }
    surfaces
}

#[test]
fn needles_and_near_coplanar_surfaces_agree_with_brute_force() {
    check_scene("needles", &slivers(false), 6, 8_000);
    check_scene("tiny slivers", &slivers(true), 6, 6_000);
}

/// `segment_crosses` accepts points within a tolerance of each edge line,
/// which beyond a needle's tip reaches far past the tip (`tolerance /
/// half-angle`): a segment passing just beyond it, wholly in front of
/// another surface's plane through the tip, is blocked, and the structure
/// must still find the needle (the BSP behind that plane, the BVH in its
/// box). The sharper needle's region reaches further than the BVH query's
/// round-off margin.
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
        for variant in all_variants(&surfaces) {
            variant.check_structure(surfaces.len(), "needle tip");
            for k in 0..300 {
                let x = 1e-8 * 1.05f64.powi(k);
                let from = DVec3::new(x, 1e-13, 1.0);
                let to = DVec3::new(x, -1e-13, -1.0);
                let what = format!("h = {h}, x = {x}");
                if assert_agrees(&variant, &brute, from, to, NOTHING_SKIPPED, &what) {
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

/// Found by the property test below against an early BVH without the
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
    for variant in all_variants(&surfaces) {
        for (from, to) in [(a, b), shorten(a, b), (b, a), shorten(b, a)] {
            assert_agrees(&variant, &brute, from, to, NOTHING_SKIPPED, "corner");
        }
    }
}

#[test]
fn many_parallel_planes() {
    let surfaces = parallel_squares();
    check_scene("parallel", &surfaces, 14, 5_000);
    // A short segment between two neighbouring planes is not blocked.
    let brute = BruteForce::new(&surfaces);
    for variant in all_variants(&surfaces) {
        let (from, to) = (DVec3::new(0.5, 0.5, 1.502), DVec3::new(0.4, 0.6, 1.508));
        assert!(!assert_agrees(
            &variant,
            &brute,
            from,
            to,
            NOTHING_SKIPPED,
            "between planes"
        ));
    }
}

/// A geometric series of planes, which a surface-area split cuts into a
/// lopsided tree.
#[test]
fn lopsided_scene_agrees_with_brute_force() {
    check_scene("geometric", &geometric_stack(), 15, 2_000);
}

// --------------------------------------------------------- degenerate input

#[test]
fn empty_scene() {
    for variant in all_variants(&[]) {
        variant.check_structure(0, "empty");
        let occluder = variant.occluder();
        assert!(!occluder.occluded(DVec3::ZERO, DVec3::ONE, NOTHING_SKIPPED));
        assert_eq!(
            occluder.occluded_counting(DVec3::ZERO, DVec3::ONE, NOTHING_SKIPPED),
            (false, 0, 0),
            "{}",
            variant.name
        );
    }
}

#[test]
fn one_surface() {
    let surfaces = one_triangle();
    check_scene("one triangle", &surfaces, 9, 5_000);
    // The corners and edges themselves, crossed from every side.
    let brute = BruteForce::new(&surfaces);
    for variant in all_variants(&surfaces) {
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
                assert_agrees(&variant, &brute, p - d, p + d, NOTHING_SKIPPED, "triangle");
                assert_agrees(&variant, &brute, p, p + d, NOTHING_SKIPPED, "triangle");
            }
        }
    }
}

#[test]
fn all_surfaces_coplanar() {
    let mut rng = Rng(11);
    let surfaces = coplanar_grid(&mut rng);
    let after_scene = rng.0;
    check_scene("coplanar", &surfaces, 12, 8_000);
    let brute = BruteForce::new(&surfaces);
    let squares = &surfaces[..36];
    for accel in Accel::ALL {
        for (variant, only_squares) in variants_of(accel, &surfaces)
            .into_iter()
            .zip(variants_of(accel, squares))
        {
            let name = variant.name.clone();
            let mut rng = Rng(after_scene);
            // Segments lying in the plane: the exact squares never block
            // them; a random triangle's plane is z = 1 only up to round-off,
            // so the oracle decides.
            for _ in 0..2_000 {
                let from = DVec3::new(rng.range(-1.0, 7.0), rng.range(-1.0, 7.0), 1.0);
                let to = DVec3::new(rng.range(-1.0, 7.0), rng.range(-1.0, 7.0), 1.0);
                assert!(
                    !only_squares.occluder().occluded(from, to, NOTHING_SKIPPED),
                    "{name}"
                );
                assert_agrees(&variant, &brute, from, to, NOTHING_SKIPPED, "in the plane");
            }
            // Segments through the grid's shared edges and corners, and
            // lying in the plane.
            let mut rng = Rng(after_scene);
            for _ in 0..1_000 {
                let (x, y) = (f64::from(rng.below(7) as u32), rng.range(0.0, 6.0));
                let p = if rng.chance(0.5) {
                    DVec3::new(x, y, 1.0)
                } else {
                    DVec3::new(y, x, 1.0)
                };
                let d = rng.direction();
                assert_agrees(&variant, &brute, p - d, p + d, NOTHING_SKIPPED, "edges");
                let from = DVec3::new(rng.range(-1.0, 7.0), rng.range(-1.0, 7.0), 1.0);
                let to = DVec3::new(rng.range(-1.0, 7.0), rng.range(-1.0, 7.0), 1.0);
                assert_agrees(&variant, &brute, from, to, NOTHING_SKIPPED, "in the plane");
            }
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
        for variant in all_variants(&surfaces) {
            prop_assert!(variant.occluder().validate().is_ok(), "{}", variant.name);
            for &(from, to, s0, s1) in &segments {
                for (from, to) in [(from, to), shorten(from, to)] {
                    let skip = [s0, s1];
                    prop_assert_eq!(
                        variant.occluder().occluded(from, to, skip),
                        brute.occluded(from, to, skip),
                        "{}", variant.name
                    );
                }
            }
        }
    }
}
