//! Every shadow-ray accelerator against the brute-force oracle, written
//! once: each test loops over [`Accel::ALL`] (a new accelerator is tested
//! without touching this file) and over each accelerator's settings
//! variants, and calls [`Occluder::validate`] on every structure it builds.
//! The scenes: the built-in room and Cornell box, random polygon soups
//! (coplanar, edge-sharing, slivers, needles, tiny polygons, far from the
//! origin), soups shaped like the real files, and degenerate inputs.
//! Answers must be identical, not merely close: for shadow segments the
//! same yes or no; for closest hits the same surface at the same distance,
//! bit for bit (every accelerator computes a crossing's distance with the
//! same arithmetic, and ties go to the lower surface index), the oracle
//! itself checked against a plain minimum over the segment test, and a hit
//! found exactly when `occluded` finds a blocker.
//!
//! Checks only one accelerator can make (tree sizes, depth limits, balance,
//! determinism) are in `tests/bsp.rs` and `tests/bvh.rs`; the per-structure
//! and per-query invariants of the trees are hooked in here through
//! [`Built`], so they hold on every scene below.

use glam::DVec3;
use proptest::prelude::*;
use radiosity::accel::brute::BruteForce;
use radiosity::accel::bsp::{self, Bsp};
use radiosity::accel::bvh::{self, Bvh};
use radiosity::accel::{Accel, Hit, Occluder, PreparedSurfaces, shorten};
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

    /// The tree's `closest_hit_counting`: `(hit, surfaces tested, nodes or
    /// boxes visited)`; `None` for an accelerator without counts.
    fn closest_hit_counting(
        &self,
        origin: DVec3,
        direction: DVec3,
        max_t: f64,
        skip: [u32; 2],
    ) -> Option<(Option<Hit>, u32, u32)> {
        match &self.built {
            Built::Bsp(b) => Some(b.closest_hit_counting(origin, direction, max_t, skip)),
            Built::Bvh(b) => Some(b.closest_hit_counting(origin, direction, max_t, skip)),
            Built::Other(_) => None,
        }
    }

    /// Per-query bounds on the counts `occluded_counting` returns.
    fn check_counts(&self, tested: u32, visited: u32, what: &str) {
        if let Built::Bvh(b) = &self.built {
            // Boxes tested: WIDTH per node of the wide tree, each at most
            // once.
            let stats = b.stats();
            assert!(visited as usize <= bvh::WIDTH * stats.wide_nodes, "{what}");
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

/// A closest-hit query.
#[derive(Clone, Copy, Debug)]
struct Ray {
    origin: DVec3,
    direction: DVec3,
    max_t: f64,
    skip: [u32; 2],
}

impl Ray {
    /// The ray skipping nothing.
    fn new(origin: DVec3, direction: DVec3, max_t: f64) -> Ray {
        Ray {
            origin,
            direction,
            max_t,
            skip: NOTHING_SKIPPED,
        }
    }

    fn skipping(self, skip: [u32; 2]) -> Ray {
        Ray { skip, ..self }
    }

    /// The end of its segment, when it can hit anything.
    fn end(&self) -> Option<DVec3> {
        let end = self.origin + self.direction * self.max_t;
        (self.max_t > 0.0 && self.origin.is_finite() && end.is_finite()).then_some(end)
    }

    fn closest_hit(&self, occluder: &dyn Occluder) -> Option<Hit> {
        occluder.closest_hit(self.origin, self.direction, self.max_t, self.skip)
    }
}

/// The oracle of the closest-hit tests: brute force, and the plain
/// minimum it should compute.
struct Oracle {
    brute: BruteForce,
    prepared: PreparedSurfaces,
    groups: Vec<u32>,
}

impl Oracle {
    fn new(surfaces: &[Surface]) -> Oracle {
        Oracle {
            brute: BruteForce::new(surfaces),
            prepared: PreparedSurfaces::new(surfaces),
            groups: surfaces.iter().map(|s| s.group).collect(),
        }
    }

    /// The closest hit by the definition: the segment test on every
    /// surface not skipped, the smallest parameter winning, ties to the
    /// lower index; nothing for a ray that can hit nothing.
    fn by_definition(&self, ray: Ray) -> Option<Hit> {
        let end = ray.end()?;
        let mut best: Option<(f64, usize)> = None;
        for (i, group) in self.groups.iter().enumerate() {
            if ray.skip.contains(group) {
                continue;
            }
            if let Some(p) = self.prepared.crossing(i as u32, ray.origin, end)
                && best.is_none_or(|(b, _)| p < b)
            {
                best = Some((p, i));
            }
        }
        best.map(|(p, i)| Hit {
            surface: i as u32,
            t: p * ray.max_t,
        })
    }
}

/// Asserts that the variant's closest hit is the oracle's (the same
/// surface at the same distance), that the oracle's is the definition's
/// (once per ray: on brute force's own turn), that a hit is found exactly when `occluded` finds the ray's segment
/// blocked, and that the counting form agrees; returns the hit.
fn assert_closest_agrees(variant: &Variant, oracle: &Oracle, ray: Ray, what: &str) -> Option<Hit> {
    let name = &variant.name;
    let expected = ray.closest_hit(&oracle.brute);
    if *name == Accel::Brute.name() {
        assert_eq!(
            expected,
            oracle.by_definition(ray),
            "{what}, brute force against the definition: {ray:?}"
        );
    }
    let occluder = variant.occluder();
    let hit = ray.closest_hit(occluder);
    assert_eq!(hit, expected, "{what}, {name}: {ray:?}");
    if let Some((counted, tested, visited)) =
        variant.closest_hit_counting(ray.origin, ray.direction, ray.max_t, ray.skip)
    {
        assert_eq!(counted, hit, "{what}, {name}: {ray:?}");
        variant.check_counts(tested, visited, &format!("{what}, {name}: {ray:?}"));
    }
    if let Some(hit) = hit {
        assert!(
            (0.0..=ray.max_t).contains(&hit.t),
            "{what}, {name}: {ray:?} {hit:?}"
        );
        let group = oracle.groups[hit.surface as usize];
        assert!(
            !ray.skip.contains(&group),
            "{what}, {name}: {ray:?} {hit:?}"
        );
    }
    if let Some(end) = ray.end() {
        assert_eq!(
            occluder.occluded(ray.origin, end, ray.skip),
            hit.is_some(),
            "{what}, {name}, occluded: {ray:?}"
        );
    }
    hit
}

/// Runs `count` random rays: towards interesting points (their exact
/// distance, beyond them or short of them) and in random directions, as
/// segments (`max_t = 1`) and with unit directions, from random points and
/// from points on surfaces, with and without skipped surfaces; on every
/// fourth ray also checks that a longer ray's hit falls within the
/// segment exactly when the segment is blocked. Returns the rays that hit.
fn agree_on_random_rays(
    variant: &Variant,
    surfaces: &[Surface],
    rng: &mut Rng,
    count: usize,
    what: &str,
) -> usize {
    let oracle = Oracle::new(surfaces);
    let (lo, hi) = bounds_of(surfaces);
    let diagonal = (hi - lo).length();
    let mut hits = 0;
    for i in 0..count {
        let origin = if rng.chance(0.3) {
            let id = rng.below(surfaces.len());
            point_on(rng, &surfaces[id])
        } else {
            random_point(rng, surfaces, lo, hi)
        };
        let target = random_point(rng, surfaces, lo, hi);
        let skip = if rng.chance(0.5) {
            NOTHING_SKIPPED
        } else {
            random_skip(rng, surfaces.len())
        };
        let (direction, max_t) = match rng.below(4) {
            0 => (target - origin, 1.0),
            1 => (target - origin, rng.range(0.5, 3.0)),
            2 => {
                let d = target - origin;
                let length = d.length();
                (d / length, length)
            }
            _ => (rng.unit_vector(), rng.range(0.0, 2.0) * diagonal),
        };
        let ray = Ray::new(origin, direction, max_t).skipping(skip);
        let hit = assert_closest_agrees(variant, &oracle, ray, what);
        hits += usize::from(hit.is_some());
        if i % 4 == 0 {
            check_longer_ray(variant, surfaces, (origin, target), skip, what);
        }
    }
    hits
}

/// The segment `from -> to` shortened as the solver shortens it is
/// blocked when, and only when, the ray along it twice as long hits
/// something within it. Not where the two segments' round-off may differ:
/// a hit at the segment's end, or a surface whose plane holds both
/// segments within round-off (a sliver the segment runs along, crossed by
/// one and not the other).
fn check_longer_ray(
    variant: &Variant,
    surfaces: &[Surface],
    (from, to): (DVec3, DVec3),
    skip: [u32; 2],
    what: &str,
) {
    let (a, b) = shorten(from, to);
    let direction = b - a;
    let far = a + direction * 2.0;
    let scale = a.abs().max(far.abs()).max_element().max(1.0);
    let grazed = surfaces.iter().any(|s| {
        let near = |p: DVec3| (s.normal.dot(p) - s.offset).abs() < 1e-12 * scale;
        near(a) && near(far)
    });
    if a + direction != b || grazed {
        return;
    }
    let occluder = variant.occluder();
    let blocked = occluder.occluded(a, b, skip);
    let hit = occluder.closest_hit(a, direction, 2.0, skip);
    let message = format!(
        "{what}, {}: {a:?} -> {b:?} skipping {skip:?}: {hit:?}",
        variant.name
    );
    match hit {
        Some(hit) if (hit.t - 1.0).abs() < 1e-9 => {}
        Some(hit) if hit.t < 1.0 => assert!(blocked, "{message}"),
        _ => assert!(!blocked, "{message}"),
    }
}

/// Builds every variant over the surfaces (each its own surface id),
/// checks its structure, and runs `count` random segments (from a generator
/// seeded with `seed`), segments ending on up to 60 surfaces and `count /
/// 4` random closest-hit rays.
fn check_scene(name: &str, surfaces: &[Surface], seed: u64, count: usize) {
    let numbered = numbered(surfaces);
    let surfaces = &numbered[..];
    for variant in all_variants(surfaces) {
        variant.check_structure(surfaces.len(), name);
        let mut rng = Rng(seed);
        agree_on_random_segments(&variant, surfaces, &mut rng, count, name);
        agree_on_segments_ending_on_surfaces(&variant, surfaces, &mut rng, 60, name);
        let mut rng = Rng(seed ^ RAY_SEED);
        agree_on_random_rays(&variant, surfaces, &mut rng, count / 4, name);
    }
}

/// Mixed into a scene's seed for its closest-hit rays.
const RAY_SEED: u64 = 0x5eed_0f0a_7500;

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

// --------------------------------------------------------------- closest hit

/// Random rays on random soups: the same surface at the same distance as
/// brute force, from every variant (`check_scene` runs such rays on every
/// other scene of this file too).
#[test]
fn closest_hits_on_random_soups_agree_with_brute_force() {
    for seed in 0..6u64 {
        let plain = numbered(&soup(100 + seed, 60 + 30 * seed as usize));
        let varied = numbered(&varied_soup(100 + seed, 60 + 30 * seed as usize));
        for (name, surfaces) in [("soup", &plain), ("varied soup", &varied)] {
            let what = format!("{name} {seed}");
            for variant in all_variants(surfaces) {
                let mut rng = Rng(3000 + seed);
                let hits = agree_on_random_rays(&variant, surfaces, &mut rng, 1_500, &what);
                assert!(hits > 300, "{what}, {}: {hits} hits", variant.name);
            }
        }
    }
}

/// Random segments, shortened as the solver shortens them: the segment as
/// a ray (`max_t = 1`, or a unit direction and its length) hits a surface
/// exactly when `occluded` finds it blocked, and a ray twice as long hits
/// within the segment exactly then.
#[test]
fn closest_hit_is_consistent_with_occluded() {
    let mut rng = Rng(41);
    let scenes = [
        ("room", numbered(&builtin("room").surfaces)),
        ("soup", numbered(&soup(42, 200))),
        (
            "real-file soup",
            numbered(&real_file_soup(&mut rng, DVec3::ZERO)),
        ),
    ];
    for (name, surfaces) in &scenes {
        let oracle = Oracle::new(surfaces);
        let (lo, hi) = bounds_of(surfaces);
        for variant in all_variants(surfaces) {
            let mut rng = Rng(43);
            let mut blocked = 0;
            for _ in 0..2_000 {
                let from = random_point(&mut rng, surfaces, lo, hi);
                let to = random_point(&mut rng, surfaces, lo, hi);
                let skip = if rng.chance(0.5) {
                    NOTHING_SKIPPED
                } else {
                    random_skip(&mut rng, surfaces.len())
                };
                let (a, b) = shorten(from, to);
                let segment = Ray::new(a, b - a, 1.0).skipping(skip);
                let hit = assert_closest_agrees(&variant, &oracle, segment, name);
                if a + (b - a) == b {
                    let occluded = variant.occluder().occluded(a, b, skip);
                    assert_eq!(occluded, hit.is_some(), "{name}, {}", variant.name);
                }
                blocked += usize::from(hit.is_some());
                let length = (b - a).length();
                if length > 0.0 {
                    let unit = Ray::new(a, (b - a) / length, length).skipping(skip);
                    assert_closest_agrees(&variant, &oracle, unit, name);
                }
                check_longer_ray(&variant, surfaces, (from, to), skip, name);
            }
            assert!(
                blocked > 200 && blocked < 1_800,
                "{name}, {}: {blocked} blocked",
                variant.name
            );
        }
    }
}

/// Ten squares stacked along z, surface ids 0..9 from the bottom.
fn stacked_squares() -> Vec<Surface> {
    let squares: Vec<Surface> = (0..10)
        .filter_map(|i| {
            let z = f64::from(i);
            surface(vec![
                DVec3::new(-1.0, -1.0, z),
                DVec3::new(1.0, -1.0, z),
                DVec3::new(1.0, 1.0, z),
                DVec3::new(-1.0, 1.0, z),
            ])
        })
        .collect();
    numbered(&squares)
}

#[test]
fn closest_hit_degenerate_inputs() {
    for variant in all_variants(&[]) {
        let occluder = variant.occluder();
        assert_eq!(
            occluder.closest_hit(DVec3::ZERO, DVec3::ONE, 1.0, NOTHING_SKIPPED),
            None
        );
        if let Some(counts) =
            variant.closest_hit_counting(DVec3::ZERO, DVec3::ONE, 1.0, NOTHING_SKIPPED)
        {
            assert_eq!(counts, (None, 0, 0), "{}", variant.name);
        }
    }
    let surfaces = stacked_squares();
    let oracle = Oracle::new(&surfaces);
    let below = DVec3::new(0.1, 0.2, -0.5);
    let nothing = [
        Ray::new(below, DVec3::ZERO, 5.0),
        Ray::new(below, DVec3::Z, 0.0),
        Ray::new(below, DVec3::Z, -0.0),
        Ray::new(DVec3::new(0.1, 0.2, 3.5), DVec3::Z, -3.0),
        Ray::new(below, DVec3::Z, f64::NAN),
        Ray::new(below, DVec3::Z, f64::INFINITY),
        Ray::new(below, DVec3::new(0.0, 0.0, f64::INFINITY), 1.0),
        Ray::new(below, DVec3::new(f64::NAN, 0.0, 1.0), 20.0),
        Ray::new(DVec3::new(f64::NAN, 0.0, 0.0), DVec3::Z, 20.0),
        Ray::new(below, DVec3::Z * 1e300, 1e300),
        // In the squares' planes, or beside them.
        Ray::new(DVec3::new(-3.0, 0.0, 2.0), DVec3::X, 6.0),
        Ray::new(DVec3::new(3.0, 0.0, -1.0), DVec3::Z, 20.0),
    ];
    let huge = [
        // Far beyond what the BVH's f32 boxes hold: every surface tested.
        Ray::new(DVec3::new(0.0, 0.0, -1e35), DVec3::Z * 2e35, 1.0),
        Ray::new(
            DVec3::new(0.1, 0.0, -1e20),
            DVec3::new(-0.1, 0.0, 2e20),
            1.0,
        ),
        Ray::new(DVec3::new(0.1, 0.0, 1e20), -DVec3::Z, 1e21),
    ];
    for variant in all_variants(&surfaces) {
        for ray in nothing {
            let hit = assert_closest_agrees(&variant, &oracle, ray, "degenerate");
            assert_eq!(hit, None, "{}: {ray:?}", variant.name);
        }
        for ray in huge {
            let hit = assert_closest_agrees(&variant, &oracle, ray, "huge");
            assert!(hit.is_some(), "{}: {ray:?}", variant.name);
        }
    }
}

/// The 6 x 6 grid of unit squares sharing edges in the plane z = 1 (ids
/// `6 i + j` for the square at `(i, j)`), facing both ways, and the same
/// with random triangles in the plane: rays through the shared edges and
/// corners at random slopes never slip between neighbours and meet the
/// plane there, on the lower-indexed of the squares meeting at the point
/// (they are crossed at the same distance); rays lying in the plane,
/// along the grid lines or across them, hit no square. Then the closed
/// tetrahedra of the soups, through the midpoints of their edges: a hit at
/// the edge at the latest, and one at the edge is on one of the two faces
/// sharing it.
#[test]
fn closest_hit_along_and_through_shared_edges() {
    let mut rng = Rng(11);
    let surfaces = numbered(&coplanar_grid(&mut rng));
    let squares = &surfaces[..36];
    let oracle = Oracle::new(&surfaces);
    let oracle_squares = Oracle::new(squares);
    for (variant, only_squares) in all_variants(&surfaces)
        .into_iter()
        .zip(all_variants(squares))
    {
        let mut rng = Rng(12);
        for _ in 0..1_500 {
            let (line, along) = (f64::from(rng.below(7) as u32), rng.range(0.0, 6.0));
            let (x, y) = if rng.chance(0.5) {
                (line, along)
            } else {
                (along, line)
            };
            let p = DVec3::new(x, y, 1.0);
            let mut d = rng.direction();
            if d.z.abs() < 0.05 {
                d.z = 0.5;
            }
            let ray = Ray::new(p - d, d, 2.0);
            assert_closest_agrees(&variant, &oracle, ray, "through edges");
            let hit = assert_closest_agrees(&only_squares, &oracle_squares, ray, "through edges")
                .unwrap_or_else(|| panic!("{}: {ray:?} slips through", variant.name));
            assert!((hit.t - 1.0).abs() < 1e-12, "{ray:?}: {hit:?}");
            let lowest = (0..36u32)
                .find(|&k| {
                    let (i, j) = (f64::from(k / 6), f64::from(k % 6));
                    (i..=i + 1.0).contains(&x) && (j..=j + 1.0).contains(&y)
                })
                .unwrap();
            assert_eq!(hit.surface, lowest, "{}: {ray:?}", variant.name);
            // In the plane: along this grid line, or across the grid.
            let d = if x == line { DVec3::Y } else { DVec3::X };
            let along_line = Ray::new(p - d * 3.0, d, 6.0);
            let across = Ray::new(p, rng.direction() * DVec3::new(1.0, 1.0, 0.0), 3.0);
            for ray in [along_line, across] {
                assert_eq!(ray.closest_hit(only_squares.occluder()), None, "{ray:?}");
                assert_closest_agrees(&variant, &oracle, ray, "in the plane");
            }
        }
    }
    // Closed tetrahedra: faces [0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3].
    let mut rng = Rng(13);
    let mut tetrahedra = Vec::new();
    let mut corners = Vec::new();
    for k in 0..8 {
        // Three apart along x: a ray within 0.5 of one meets no other.
        let base = DVec3::new(3.0 * f64::from(k), rng.unit(), rng.unit());
        let p = [
            base,
            base + DVec3::new(rng.range(0.3, 1.0), 0.0, 0.0),
            base + DVec3::new(0.0, rng.range(0.3, 1.0), 0.0),
            base + DVec3::new(0.0, 0.0, rng.range(0.3, 1.0)),
        ];
        for [i, j, k] in [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]] {
            tetrahedra.push(surface(vec![p[i], p[j], p[k]]).unwrap());
        }
        corners.push(p);
    }
    let tetrahedra = numbered(&tetrahedra);
    let oracle = Oracle::new(&tetrahedra);
    let faces = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    for variant in all_variants(&tetrahedra) {
        let mut rng = Rng(14);
        let mut at_edge = 0;
        for (n, p) in corners.iter().enumerate() {
            for (a, b) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
                let sharing: Vec<u32> = (0..4)
                    .filter(|&f| faces[f].contains(&a) && faces[f].contains(&b))
                    .map(|f| (4 * n + f) as u32)
                    .collect();
                let m = p[a].lerp(p[b], 0.5);
                for _ in 0..20 {
                    let d = rng.unit_vector() * 0.5;
                    let ray = Ray::new(m - d, d, 2.0);
                    let hit = assert_closest_agrees(&variant, &oracle, ray, "tetra");
                    // From outside beyond another face, the ray may
                    // enter through it first.
                    let hit = hit.unwrap_or_else(|| panic!("{ray:?} slips through"));
                    assert!(hit.t < 1.0 + 1e-9, "{ray:?}: {hit:?}");
                    if (hit.t - 1.0).abs() < 1e-9 {
                        assert!(sharing.contains(&hit.surface), "{ray:?}: {hit:?}");
                        at_edge += 1;
                    }
                }
            }
        }
        assert!(
            at_edge > 480,
            "{}: {at_edge} hits at the edge",
            variant.name
        );
    }
}

/// Rays from points on surfaces. From exactly on a plane (the grid's
/// corners and points with few binary digits in z = 1), no surface of that
/// plane is hit, whichever way the ray leaves; the layer above or the
/// floor below is. From a point of a tilted surface (off its plane by
/// round-off), the surface itself may be hit at a distance of round-off
/// unless its id is skipped, as shadow rays skip theirs; the accelerators
/// agree either way.
#[test]
fn closest_hit_from_a_surface() {
    let mut rng = Rng(21);
    let grid = coplanar_grid(&mut rng);
    let mut layers: Vec<Surface> = grid[..36].to_vec();
    for s in &grid[..36] {
        layers.extend(surface(
            s.polygon.iter().map(|p| *p + DVec3::Z * 2.0).collect(),
        ));
    }
    layers.extend(surface(vec![
        DVec3::new(-1.0, -1.0, -1.0),
        DVec3::new(7.0, -1.0, -1.0),
        DVec3::new(7.0, 7.0, -1.0),
        DVec3::new(-1.0, 7.0, -1.0),
    ]));
    let layers = numbered(&layers);
    let oracle = Oracle::new(&layers);
    for variant in all_variants(&layers) {
        let mut rng = Rng(22);
        for _ in 0..2_000 {
            let quarter = |rng: &mut Rng| 0.25 * f64::from(rng.below(25) as u32);
            let origin = DVec3::new(quarter(&mut rng), quarter(&mut rng), 1.0);
            let d = rng.unit_vector();
            let hit = assert_closest_agrees(&variant, &oracle, Ray::new(origin, d, 20.0), "on");
            if let Some(hit) = hit {
                assert!(
                    hit.surface >= 36,
                    "{}: hits its own plane: {hit:?}",
                    variant.name
                );
                let z = origin.z + d.z * hit.t;
                assert!((z - 3.0).abs() < 1e-9 || (z + 1.0).abs() < 1e-9, "{z}");
            }
        }
    }
    for (seed, at) in [(23, DVec3::ZERO), (24, DVec3::new(1.0e4, 30.0, -7.0e3))] {
        let mut rng = Rng(seed);
        let surfaces = numbered(&real_file_soup(&mut rng, at));
        let oracle = Oracle::new(&surfaces);
        for variant in all_variants(&surfaces) {
            let mut rng = Rng(seed);
            let mut hits = 0;
            for _ in 0..1_500 {
                let id = rng.below(surfaces.len());
                let origin = point_on(&mut rng, &surfaces[id]);
                let d = rng.unit_vector();
                let ray = Ray::new(origin, d, 4.0);
                assert_closest_agrees(&variant, &oracle, ray, "from a surface");
                let skipping = ray.skipping([id as u32, u32::MAX]);
                let hit = assert_closest_agrees(&variant, &oracle, skipping, "skipping");
                hits += usize::from(hit.is_some());
            }
            assert!(hits > 100, "{}: {hits} hits", variant.name);
        }
    }
}

/// `max_t` is exclusive: a ray whose end lies exactly on a surface's plane
/// does not hit it, and one a hair longer does; a ray from one square's
/// plane to the next one's hits neither. Also rays ending exactly on the
/// corners, edge midpoints and centroids of the soups' surfaces.
#[test]
fn closest_hit_with_max_distance_exactly_at_a_surface() {
    let surfaces = stacked_squares();
    let oracle = Oracle::new(&surfaces);
    let origin = DVec3::new(0.25, 0.5, 0.25);
    for variant in all_variants(&surfaces) {
        let check = |ray: Ray| assert_closest_agrees(&variant, &oracle, ray, "exact");
        for direction in [DVec3::Z, DVec3::Z * 0.5, DVec3::new(0.125, -0.25, 1.0)] {
            // To the plane z = 1 exactly, and past it.
            let to_plane = 0.75 / direction.z;
            assert_eq!(check(Ray::new(origin, direction, to_plane)), None);
            let hair = to_plane * (1.0 + 1e-12);
            let hit = check(Ray::new(origin, direction, hair)).unwrap();
            assert_eq!(hit.surface, 1);
            assert!((hit.t - to_plane).abs() <= 1e-12 * to_plane, "{hit:?}");
            let hit = check(Ray::new(origin, direction, 10.0)).unwrap();
            assert_eq!(hit.surface, 1);
            // From the plane z = 1 to z = 2 exactly.
            let on = origin + direction * to_plane;
            assert_eq!(on.z, 1.0);
            assert_eq!(check(Ray::new(on, direction, 1.0 / direction.z)), None);
            let hit = check(Ray::new(on, direction, 1.5 / direction.z)).unwrap();
            assert_eq!(hit.surface, 2);
        }
    }
    for (seed, surfaces) in [(31, soup(31, 120)), (32, varied_soup(32, 120))] {
        let surfaces = numbered(&surfaces);
        let oracle = Oracle::new(&surfaces);
        let (lo, hi) = bounds_of(&surfaces);
        for variant in all_variants(&surfaces) {
            let mut rng = Rng(seed);
            for (id, s) in surfaces.iter().enumerate().step_by(3) {
                let n = s.polygon.len();
                let mut targets = s.polygon.clone();
                targets.extend((0..n).map(|i| s.polygon[i].lerp(s.polygon[(i + 1) % n], 0.5)));
                targets.push(radiosity::geometry::centroid(&s.polygon));
                for to in targets {
                    let from = random_point(&mut rng, &surfaces, lo, hi);
                    let ray = Ray::new(from, to - from, 1.0);
                    for ray in [ray, ray.skipping([id as u32, u32::MAX])] {
                        assert_closest_agrees(&variant, &oracle, ray, "to a surface");
                    }
                }
            }
        }
    }
}

/// Not a timing: a closest-hit ray up through a stack of 300 squares tests
/// a few of them, not all: the trees walk front to back and shrink the ray
/// at the first hit. Run with `--nocapture` to see the figures.
#[test]
fn closest_hit_through_a_stack_tests_few_surfaces() {
    let surfaces = numbered(&parallel_squares());
    let oracle = Oracle::new(&surfaces);
    let ray = Ray::new(
        DVec3::new(0.1, 0.2, -0.5),
        DVec3::new(0.01, -0.02, 1.0),
        4.0,
    );
    for variant in all_variants(&surfaces) {
        let hit = assert_closest_agrees(&variant, &oracle, ray, "stack");
        assert!(hit.is_some());
        let Some((_, tested, visited)) =
            variant.closest_hit_counting(ray.origin, ray.direction, ray.max_t, ray.skip)
        else {
            continue;
        };
        println!(
            "{}: {tested} surfaces tested, {visited} visited",
            variant.name
        );
        assert!(tested < 30, "{}: {tested} surfaces tested", variant.name);
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
    fn grid_triangles_closest_hits_agree_with_brute_force(
        triangles in prop::collection::vec((grid_point(), grid_point(), grid_point()), 0..40),
        rays in prop::collection::vec(
            (grid_point(), grid_point(), 0u32..45, 0u32..45, 1u32..5),
            1..40,
        ),
    ) {
        let surfaces: Vec<Surface> = triangles
            .into_iter()
            .filter_map(|(a, b, c)| surface(vec![a, b, c]))
            .collect();
        let surfaces = numbered(&surfaces);
        let oracle = Oracle::new(&surfaces);
        for variant in all_variants(&surfaces) {
            for &(origin, target, s0, s1, quarters) in &rays {
                // Ends at a quarter, half, three quarters or exactly at
                // the target, all grid points or on grid planes.
                let max_t = 0.25 * f64::from(quarters);
                let ray = Ray::new(origin, target - origin, max_t).skipping([s0, s1]);
                assert_closest_agrees(&variant, &oracle, ray, "grid");
                let (a, b) = shorten(origin, target);
                let shortened = Ray::new(a, b - a, 1.0).skipping([s0, s1]);
                assert_closest_agrees(&variant, &oracle, shortened, "grid, shortened");
            }
        }
    }

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
