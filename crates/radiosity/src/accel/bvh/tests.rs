//! Unit tests of the BVH: its build, both walks, their agreement with the
//! brute-force oracle, the settings and the layout.

use super::*;
use crate::accel::brute::BruteForce;

use crate::accel::test_scenes::{NONE_SKIPPED, square_at_z, xorshift};

#[test]
fn empty_scene_blocks_nothing() {
    for (_, settings) in BvhSettings::presets() {
        let bvh = Bvh::with_settings(&[], settings);
        assert_eq!(bvh.stats(), BvhStats::default());
        bvh.validate().unwrap();
        assert_eq!(
            bvh.occluded_counting(DVec3::ZERO, DVec3::ONE, NONE_SKIPPED),
            (false, 0, 0)
        );
    }
}

#[test]
fn one_square_is_one_leaf() {
    let surfaces = [square_at_z(1.0, 1.0)];
    let bvh = Bvh::new(&surfaces);
    bvh.validate().unwrap();
    assert_eq!(
        bvh.stats(),
        BvhStats {
            nodes: 1,
            leaves: 1,
            depth: 1,
            max_leaf_size: 1,
            wide_nodes: 1,
            wide_max_leaf_size: 1,
        }
    );
    // One wide node: its child boxes (one used) are tested.
    let up = DVec3::new(0.0, 0.0, 2.0);
    assert_eq!(
        bvh.occluded_counting(DVec3::ZERO, up, NONE_SKIPPED),
        (true, 1, WIDTH as u32)
    );
    assert_eq!(
        bvh.occluded_counting(DVec3::ZERO, up, [0, u32::MAX]),
        (false, 0, WIDTH as u32)
    );
    // A segment short of the box tests no surface.
    let short = DVec3::new(0.0, 0.0, 0.5);
    assert_eq!(
        bvh.occluded_counting(DVec3::ZERO, short, NONE_SKIPPED),
        (false, 0, WIDTH as u32)
    );
    // Nor does one passing beside it.
    let beside = DVec3::new(3.0, 0.0, 0.0);
    assert_eq!(
        bvh.occluded_counting(beside, beside + up, NONE_SKIPPED),
        (false, 0, WIDTH as u32)
    );
}

#[test]
fn stacked_squares_split_and_agree() {
    let surfaces: Vec<Surface> = (0..40).map(|i| square_at_z(f64::from(i), 1.0)).collect();
    let brute = BruteForce::new(&surfaces);
    for (name, settings) in BvhSettings::presets() {
        let bvh = Bvh::with_settings(&surfaces, settings);
        bvh.validate().unwrap();
        let stats = bvh.stats();
        assert!(stats.leaves > 1 && stats.depth < 12, "{name}: {stats:?}");
        for i in 0..40 {
            let from = DVec3::new(0.1, 0.2, f64::from(i) - 0.5);
            let to = DVec3::new(-0.3, 0.1, 39.5 - f64::from(i));
            assert_eq!(
                bvh.occluded(from, to, NONE_SKIPPED),
                brute.occluded(from, to, NONE_SKIPPED)
            );
        }
        // Between two neighbouring planes: one leaf's worth of tests.
        let (blocked, tested, _) = bvh.occluded_counting(
            DVec3::new(0.5, 0.5, 20.2),
            DVec3::new(0.4, 0.6, 20.8),
            NONE_SKIPPED,
        );
        assert!(!blocked);
        assert!(tested <= settings.max_leaf_size as u32, "{name}: {tested}");
    }
}

#[test]
fn closest_hit_walks_front_to_back() {
    let surfaces: Vec<Surface> = (0..40).map(|i| square_at_z(f64::from(i), 1.0)).collect();
    let brute = BruteForce::new(&surfaces);
    for (name, settings) in BvhSettings::presets() {
        let bvh = Bvh::with_settings(&surfaces, settings);
        for (z, up) in [(-0.5, 1.0), (20.5, 1.0), (39.5, -1.0), (12.25, -1.0)] {
            let origin = DVec3::new(0.1, -0.2, z);
            let direction = DVec3::new(0.0, 0.0, up);
            let (hit, tested, _) = bvh.closest_hit_counting(origin, direction, 50.0, NONE_SKIPPED);
            assert_eq!(
                hit,
                brute.closest_hit(origin, direction, 50.0, NONE_SKIPPED),
                "{name}"
            );
            let expected = if up > 0.0 { z.ceil() } else { z.floor() };
            assert_eq!(hit.unwrap().surface, expected as u32, "{name}");
            assert!((hit.unwrap().t - (expected - z).abs()).abs() < 1e-12);
            // Boxes beyond the first hit are skipped: a leaf or two of
            // the 40 squares.
            assert!(
                tested <= 2 * settings.max_leaf_size as u32,
                "{name}: {tested}"
            );
        }
    }
}

#[test]
fn sah_keeps_separate_clusters_apart() {
    // Two far-apart clusters of 8 squares: the root splits between them.
    let mut surfaces: Vec<Surface> = (0..8)
        .map(|i| square_at_z(f64::from(i) * 0.1, 1.0))
        .collect();
    surfaces.extend((0..8).map(|i| {
        let mut s = square_at_z(100.0 + f64::from(i) * 0.1, 1.0);
        s.polygon.iter_mut().for_each(|p| p.x += 50.0);
        Surface::new(s.polygon, s.rho, s.emission, 0).unwrap()
    }));
    let bvh = Bvh::new(&surfaces);
    bvh.validate().unwrap();
    let root = &bvh.tree.nodes[0];
    let left = &bvh.tree.nodes[1];
    let right = &bvh.tree.nodes[root.link as usize];
    assert!(
        left.max[2] < 50.0 && right.min[2] > 50.0,
        "{left:?} {right:?}"
    );
}

#[test]
fn coincident_centroids_still_split() {
    // 30 copies of one square: no heuristic split exists, the median
    // fallback halves the list down to leaves of at most 8.
    let surfaces: Vec<Surface> = (0..30).map(|_| square_at_z(0.0, 1.0)).collect();
    for (name, settings) in BvhSettings::presets() {
        let bvh = Bvh::with_settings(&surfaces, settings);
        bvh.validate().unwrap();
        assert!(
            bvh.stats().max_leaf_size <= settings.max_leaf_size,
            "{name}"
        );
        assert!(bvh.occluded(DVec3::NEG_Z, DVec3::Z, NONE_SKIPPED));
    }
}

#[test]
fn crossing_box_covers_the_tolerance_region() {
    let square = square_at_z(0.0, 1.0);
    let b = crossing_box(&square);
    let tol = 4.0 * crate::accel::EDGE_TOLERANCE * 2.0;
    // Edge lines moved out by the tolerance: the box grows by it.
    assert!((b.max.x - (1.0 + tol)).abs() < 1e-15, "{b:?}");
    assert!((b.min.y + 1.0 + tol).abs() < 1e-15, "{b:?}");
    assert_eq!((b.min.z, b.max.z), (0.0, 0.0));
    // A needle's tip region reaches about tolerance / half-angle beyond
    // the tip.
    let needle = Surface::new(
        vec![
            DVec3::ZERO,
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1e-3, 0.0),
        ],
        DVec3::splat(0.5),
        DVec3::ZERO,
        0,
    )
    .unwrap();
    let t = 4.0 * crate::accel::EDGE_TOLERANCE * needle.area.sqrt();
    let reach = -crossing_box(&needle).min.x;
    assert!(reach > 1000.0 * t && reach < 5000.0 * t, "{reach} vs {t}");
}

#[test]
fn far_away_and_non_finite_queries_agree() {
    let surfaces: Vec<Surface> = (0..10).map(|i| square_at_z(f64::from(i), 1.0)).collect();
    let brute = BruteForce::new(&surfaces);
    let bvh = Bvh::new(&surfaces);
    for (from, to) in [
        (DVec3::new(0.0, 0.0, -1e35), DVec3::new(0.0, 0.0, 1e35)),
        (DVec3::new(0.1, 0.0, -1e20), DVec3::new(0.0, 0.0, 1e20)),
        (DVec3::new(f64::NAN, 0.0, 0.0), DVec3::Z),
        (
            DVec3::new(0.0, 0.0, -5.0),
            DVec3::new(0.0, 0.0, f64::INFINITY),
        ),
    ] {
        assert_eq!(
            bvh.occluded(from, to, NONE_SKIPPED),
            brute.occluded(from, to, NONE_SKIPPED),
            "{from:?} -> {to:?}"
        );
    }
}

#[test]
fn settings_are_sanitized() {
    let s = BvhSettings {
        split: SplitMethod::BinnedSah,
        bins: 1,
        leaf_size: 0,
        max_leaf_size: 1000,
        traversal_cost: f64::NAN,
        primitive_cost: -1.0,
    }
    .sanitized();
    assert_eq!(s.bins, 2);
    assert_eq!(s.leaf_size, 1);
    assert_eq!(s.max_leaf_size, MAX_LEAF_SIZE);
    assert_eq!(s.traversal_cost, BvhSettings::sah().traversal_cost);
    assert_eq!(s.primitive_cost, BvhSettings::sah().primitive_cost);
    let s = BvhSettings {
        leaf_size: 10,
        max_leaf_size: 3,
        bins: 10_000,
        ..BvhSettings::sah()
    }
    .sanitized();
    assert_eq!((s.leaf_size, s.max_leaf_size, s.bins), (10, 10, MAX_BINS));
}

/// Walks in two groups of four lanes (a processor without AVX) give
/// the same answers, surface tests and box counts as the walks this
/// processor runs, any-hit and closest-hit, on random segments
/// through the built-in room and from its vertices (segments that
/// graze corners and edges).
#[test]
fn four_lanes_walk_as_eight() {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        // The walks this processor runs are the eight-lane ones.
        assert_eq!(slab_lanes(), 8);
    } else {
        eprintln!("no AVX here: the four-lane walk is compared with itself");
    }
    #[cfg(not(target_arch = "x86_64"))]
    eprintln!("not x86-64: the four-lane walk is compared with itself");
    let scene = crate::scene::builtin::load("room").unwrap().unwrap();
    let bvh = Bvh::new(&scene.surfaces);
    let corners: Vec<DVec3> = scene
        .surfaces
        .iter()
        .flat_map(|s| s.polygon.iter().copied())
        .collect();
    let mut next = xorshift(0x2545_f491_4f6c_dd1d);
    let (mut blocked, mut hits) = (0, 0);
    for _ in 0..5_000 {
        let mut point = || {
            let c = corners[(next() % corners.len() as u64) as usize];
            if next().is_multiple_of(2) {
                c
            } else {
                c + DVec3::new(
                    (next() % 1000) as f64 / 500.0 - 1.0,
                    (next() % 1000) as f64 / 500.0 - 1.0,
                    (next() % 1000) as f64 / 500.0 - 1.0,
                )
            }
        };
        let (from, to) = (point(), point());
        let skip = [(next() % 8) as u32, u32::MAX];
        let eight = bvh.occluded_counting(from, to, skip);
        let four = traverse::four_lanes_only(|| bvh.occluded_counting(from, to, skip));
        assert_eq!(eight, four, "{from} -> {to}");
        blocked += usize::from(eight.0);
        let eight = bvh.closest_hit_counting(from, to - from, 1.0, skip);
        let four =
            traverse::four_lanes_only(|| bvh.closest_hit_counting(from, to - from, 1.0, skip));
        assert_eq!(eight, four, "{from} -> {to}");
        hits += usize::from(eight.0.is_some());
    }
    assert!(blocked > 500 && hits > 500, "{blocked} {hits}");
}

#[test]
fn node_is_32_bytes() {
    assert_eq!(std::mem::size_of::<Node>(), 32);
}

#[test]
fn boxes_round_outward() {
    let b = Aabb {
        min: DVec3::splat(0.1),
        max: DVec3::splat(0.1),
    };
    let (lo, hi) = round_outward(b);
    assert!(f64::from(lo[0]) <= 0.1 && f64::from(hi[0]) >= 0.1);
    assert!(lo[0] < hi[0]);
    let (lo, hi) = round_outward(Aabb::EVERYWHERE);
    assert_eq!((lo[1], hi[2]), (f32::NEG_INFINITY, f32::INFINITY));
}

/// The `f64` recheck of a leaf's box never culls a box the segment meets,
/// even one it touches only at an end, on a corner, a face or an edge of
/// the box, or one reaching to infinity, at scales from 1e-4 to 1e4; and
/// it culls the same box moved beyond the segment's end by a thousand
/// times its margin.
#[test]
fn exact_recheck_keeps_every_box_the_segment_meets() {
    let mut rng = crate::accel::test_scenes::uniform(11);
    let mut signed = move || 2.0 * rng() - 1.0;
    for case in 0..200_000 {
        let scale = 10f64.powi(case % 9 - 4);
        // A corner with `f32` coordinates, the segment ending (or
        // starting) exactly there.
        let corner = DVec3::new(signed(), signed(), signed()) * scale;
        let corner = corner.as_vec3().as_dvec3();
        let mut d = DVec3::new(signed(), signed(), signed()) * scale;
        // Some segments parallel to an axis or a plane.
        for axis in 0..3 {
            if (case / 3 + axis as i32) % 5 == 0 {
                d[axis] = 0.0;
            }
        }
        if d == DVec3::ZERO {
            continue;
        }
        let starts_there = case % 2 == 1;
        let (from, to) = if starts_there {
            (corner, corner + d)
        } else {
            (corner - d, corner)
        };
        // The box reaches away from the corner on each axis by a random
        // `f32` extent, some of them zero (flat boxes).
        let mut node = WideNode::UNUSED;
        let mut far = [0.0f32; 3];
        for axis in 0..3 {
            let c = corner[axis] as f32;
            let extent = if (case + axis as i32) % 4 == 0 {
                0.0
            } else {
                (signed() * scale) as f32
            };
            far[axis] = c + extent;
            node.bounds[axis][0][0] = c.min(c + extent);
            node.bounds[axis][1][0] = c.max(c + extent);
        }
        // Some boxes reach to infinity on one side of one axis.
        let unbounded = case % 11 == 0;
        if unbounded {
            let axis = (case / 11 % 3) as usize;
            let side = (case / 33 % 2) as usize;
            node.bounds[axis][side][0] = if side == 0 {
                f32::NEG_INFINITY
            } else {
                f32::INFINITY
            };
        }
        node.link[0] = 0;
        let reference = [from, to, DVec3::from(far.map(f64::from))]
            .iter()
            .map(|p| p.abs().max_element())
            .fold(0.0, f64::max);
        let exact = ExactSlabs::new(from, to, EXACT_MARGIN * reference);
        assert!(
            exact.meets(&node, 0),
            "case {case}: {from:?} to {to:?} misses {:?}",
            node.child_box(0)
        );
        // Beyond the end along the segment's longest axis, the box
        // reaching further that way: missed.
        if !starts_there && !unbounded {
            let axis = d.abs().max_position();
            let gap = (1e-9 * reference) as f32;
            let up = d[axis] > 0.0;
            let c = corner[axis] as f32;
            let mut near = if up { c + gap } else { c - gap };
            if near == c {
                near = if up { c.next_up() } else { c.next_down() };
            }
            let farther = if up { near + gap } else { near - gap };
            node.bounds[axis][0][0] = near.min(farther);
            node.bounds[axis][1][0] = near.max(farther);
            assert!(
                !exact.meets(&node, 0),
                "case {case}: {from:?} to {to:?} meets {:?}",
                node.child_box(0)
            );
        }
    }
}
