//! What only the BVH has: its shape on the built-in scenes, its depth limit,
//! the median preset's balance, deterministic builds and its statistics,
//! with every settings preset. Its answers against the brute-force oracle,
//! its `validate()` and its per-structure and per-query bounds on every
//! scene are checked with every other accelerator's in `tests/accel.rs`.

use glam::DVec3;
use radiosity::accel::bvh::{Bvh, BvhSettings, MAX_DEPTH, SplitMethod};
use radiosity::accel::{Occluder, ShadowCache};
use radiosity::scene::bounds_of;

mod common;

use common::soup::{
    Rng, builtin, bvh_settings, geometric_stack, numbered, one_triangle, parallel_squares,
    random_point, random_skip, surface, varied_soup,
};

const NOTHING_SKIPPED: [u32; 2] = [u32::MAX; 2];

#[test]
fn builtin_trees_are_valid_and_shallow() {
    for name in ["room", "cornell"] {
        let scene = builtin(name);
        for (preset, settings) in bvh_settings() {
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
                "wide_max_leaf_size",
                "bytes"
            ]
        );
    }
}

#[test]
fn a_segment_between_parallel_planes_tests_a_leaf_or_two() {
    let surfaces = parallel_squares();
    let bvh = Bvh::new(&surfaces);
    let (blocked, tested, _) = bvh.occluded_counting(
        DVec3::new(0.5, 0.5, 1.502),
        DVec3::new(0.4, 0.6, 1.508),
        NOTHING_SKIPPED,
    );
    assert!(!blocked);
    assert!(
        tested <= 2 * bvh.stats().wide_max_leaf_size as u32,
        "{tested}"
    );
}

/// The shadow cache changes no answer: runs of segments from one point to
/// points near one another (as a receiver's rays to a shooter's samples),
/// each run with its own surfaces skipped, answered through one cache
/// carried across all of them, equal [`Occluder::occluded`]'s answers,
/// on the built-in scenes and a soup of polygons that share planes and
/// edges. The cache answers many of them, and a blocker the next run
/// skips is not taken from it.
#[test]
fn a_shadow_cache_answers_as_the_walk_does() {
    let mut rng = Rng(0x5eed_cac8e);
    let scenes = [
        builtin("room").surfaces,
        builtin("cornell").surfaces,
        varied_soup(7, 300),
    ];
    for surfaces in scenes {
        let bvh = Bvh::new(&surfaces);
        let (lo, hi) = radiosity::scene::bounds_of(&surfaces);
        let mut cache = ShadowCache::default();
        let (mut blocked, mut total) = (0u64, 0u64);
        for _ in 0..400 {
            let from = random_point(&mut rng, &surfaces, lo, hi);
            let towards = random_point(&mut rng, &surfaces, lo, hi);
            let skip = random_skip(&mut rng, surfaces.len());
            let spread = 0.02 * (hi - lo).length();
            for _ in 0..16 {
                let to = towards
                    + (rng.point_in(lo, hi) - 0.5 * (lo + hi)) * spread / (hi - lo).length();
                blocked += u64::from(cached_as_walked(&bvh, from, to, skip, &mut cache));
                total += 1;
            }
        }
        println!(
            "{total} segments, {blocked} blocked, {} by the cache",
            cache.hits
        );
        assert!(blocked > 0 && cache.hits > 0 && cache.hits <= blocked);
    }
    // A segment blocked by one square only, then the same segment with
    // the square skipped: the cached square must not answer for it.
    let square = |z: f64| {
        surface(vec![
            DVec3::new(-1.0, -1.0, z),
            DVec3::new(1.0, -1.0, z),
            DVec3::new(1.0, 1.0, z),
            DVec3::new(-1.0, 1.0, z),
        ])
        .unwrap()
    };
    let surfaces = numbered(&[square(0.0), square(5.0)]);
    let bvh = Bvh::new(&surfaces);
    let mut cache = ShadowCache::default();
    let (from, to) = (DVec3::new(0.5, 0.5, -1.0), DVec3::new(0.5, 0.5, 1.0));
    assert!(bvh.occluded_cached(from, to, NOTHING_SKIPPED, &mut cache));
    assert!(!bvh.occluded_cached(from, to, [surfaces[0].group, u32::MAX], &mut cache));
    assert!(bvh.occluded_cached(from, to, [surfaces[1].group, u32::MAX], &mut cache));
    assert_eq!(cache.hits, 1);
}

/// A receiver's segments to several origins in turn, receiver after
/// receiver, as the solver casts them: naming each segment's origin lets
/// the cache test the blocker last found from there, which the next
/// receiver's segment from the same origin meets too, where the last two
/// blockers found (from other origins, in other directions) rarely block.
/// The answers stay the walk's.
#[test]
fn a_shadow_cache_remembers_a_blocker_per_origin() {
    // A lattice of squares at z = 1 with gaps between them.
    let mut squares = Vec::new();
    for i in -10..10 {
        for j in -10..10 {
            let (x, y) = (f64::from(i), f64::from(j));
            squares.push(
                surface(vec![
                    DVec3::new(x, y, 1.0),
                    DVec3::new(x + 0.8, y, 1.0),
                    DVec3::new(x + 0.8, y + 0.8, 1.0),
                    DVec3::new(x, y + 0.8, 1.0),
                ])
                .unwrap(),
            );
        }
    }
    let surfaces = numbered(&squares);
    let bvh = Bvh::new(&surfaces);
    let origins: Vec<DVec3> = (0..8)
        .map(|k| {
            let a = std::f64::consts::TAU * f64::from(k) / 8.0;
            DVec3::new(4.0 * a.cos(), 4.0 * a.sin(), 2.0)
        })
        .collect();
    let mut hits = [0u64; 2];
    let mut blocked = 0u64;
    for (named, hits) in [false, true].into_iter().zip(&mut hits) {
        let mut cache = ShadowCache::default();
        blocked = 0;
        for step in 0..600 {
            let receiver = DVec3::new(-3.0 + 0.01 * f64::from(step), 0.3, 0.0);
            for (k, &origin) in origins.iter().enumerate() {
                cache.from_origin(if named { k as u32 } else { u32::MAX });
                blocked += u64::from(cached_as_walked(
                    &bvh,
                    origin,
                    receiver,
                    NOTHING_SKIPPED,
                    &mut cache,
                ));
            }
        }
        *hits = cache.hits;
    }
    println!("{blocked} blocked; the cache answered {hits:?} (origins unnamed, named)");
    assert!(blocked > 1000 && hits[1] <= blocked);
    assert!(
        hits[1] > blocked * 9 / 10 && hits[1] > 2 * hits[0],
        "{hits:?} of {blocked}"
    );
}

/// The segment's answer through `cache`, checked against the walk's.
fn cached_as_walked(
    bvh: &Bvh,
    from: DVec3,
    to: DVec3,
    skip: [u32; 2],
    cache: &mut ShadowCache,
) -> bool {
    let walk = bvh.occluded(from, to, skip);
    assert_eq!(
        bvh.occluded_cached(from, to, skip, cache),
        walk,
        "{from} -> {to}, skipping {skip:?}"
    );
    walk
}

/// A geometric series of planes, which a surface-area split cuts into a
/// lopsided tree; the median fallback keeps its depth within the stack.
#[test]
fn lopsided_scene_stays_within_the_depth_limit() {
    let surfaces = geometric_stack();
    for (preset, settings) in bvh_settings() {
        let bvh = Bvh::with_settings(&surfaces, settings);
        bvh.validate().unwrap_or_else(|e| panic!("{preset}: {e}"));
        assert!(bvh.stats().depth <= MAX_DEPTH);
    }
}

#[test]
fn empty_scene_statistics() {
    for (preset, settings) in bvh_settings() {
        let bvh = Bvh::with_settings(&[], settings);
        Occluder::validate(&bvh).unwrap_or_else(|e| panic!("{preset}: {e}"));
        assert_eq!(bvh.stats().nodes, 0);
        assert_eq!(
            bvh.build_statistics(),
            [
                ("nodes", 0),
                ("leaves", 0),
                ("depth", 0),
                ("max_leaf_size", 0),
                ("wide_nodes", 0),
                ("wide_max_leaf_size", 0),
                ("bytes", 0)
            ]
        );
    }
}

#[test]
fn one_surface_is_one_leaf() {
    let surfaces = one_triangle();
    for (preset, settings) in bvh_settings() {
        let bvh = Bvh::with_settings(&surfaces, settings);
        bvh.validate().unwrap();
        let s = bvh.stats();
        assert_eq!(
            (s.nodes, s.leaves, s.depth, s.max_leaf_size),
            (1, 1, 1, 1),
            "{preset}"
        );
    }
}

#[test]
fn median_preset_builds_a_balanced_tree() {
    let surfaces = varied_soup(21, 500);
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
    let surfaces = varied_soup(22, 300);
    for (preset, settings) in bvh_settings() {
        let a = Bvh::with_settings(&surfaces, settings);
        let b = Bvh::with_settings(&surfaces, settings);
        assert_eq!(a.stats(), b.stats(), "{preset}");
        let mut rng = Rng(23);
        let (lo, hi) = bounds_of(&surfaces);
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
