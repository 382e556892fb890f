//! What only the BSP tree (Wong & Tsang 1993, section 3) has: its size,
//! depth, fragments and leaf buckets on the built-in room and on degenerate
//! inputs, with every settings preset. Its answers against the brute-force
//! oracle, its `validate()` and the statistics invariants on every scene are
//! checked with every other accelerator's in `tests/accel.rs`.

use glam::DVec3;
use radiosity::accel::Occluder;
use radiosity::accel::bsp::{Bsp, BspSettings, MAX_DEPTH};

mod common;

use common::soup::{Rng, bsp_settings, builtin, coplanar_grid, one_triangle, parallel_squares};

const NOTHING_SKIPPED: [u32; 2] = [u32::MAX; 2];

#[test]
fn room_tree_is_valid_and_small() {
    let scene = builtin("room");
    for (preset, settings) in bsp_settings() {
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
fn one_surface_is_one_node() {
    let surfaces = one_triangle();
    for (preset, settings) in bsp_settings() {
        let bsp = Bsp::with_settings(&surfaces, settings);
        bsp.validate().unwrap();
        let stats = bsp.stats();
        assert_eq!(
            (stats.nodes, stats.depth, stats.fragments, stats.splits),
            (1, 1, 1, 0),
            "{preset}"
        );
    }
}

#[test]
fn all_surfaces_coplanar_need_no_splits_of_their_plane() {
    let surfaces = coplanar_grid(&mut Rng(11));
    for (preset, settings) in bsp_settings() {
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
}

#[test]
fn many_parallel_planes() {
    let surfaces = parallel_squares();
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
fn empty_scene_has_no_nodes() {
    let bsp = Bsp::new(&[]);
    Occluder::validate(&bsp).unwrap();
    assert_eq!(bsp.stats().nodes, 0);
}
