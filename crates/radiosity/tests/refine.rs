//! Receiver refinement and the conforming triangulation (src/mesh/refine.rs,
//! src/mesh/conform.rs, src/solver/refine.rs) against brute force:
//!
//! * split elements tile their surfaces exactly, and the triangles shown
//!   have no T-vertex (counted by testing every vertex against every
//!   triangle edge), strand no vertex and are not flat;
//! * coplanar surfaces of different materials get each other's edge
//!   vertices;
//! * the error estimate splits elements a step crosses and spares a smooth
//!   field;
//! * a refined solve keeps its energy ledger to round-off, does not depend
//!   on the thread count, and leaves the furnace (uniform light) unsplit and
//!   exact.

mod common;

use common::rng::Rng;
use common::{quad, scene_of};
use glam::DVec3;
use radiosity::geometry;
use radiosity::mesh::{self, Mesh, MeshSettings, RefineSettings, Triangle};
use radiosity::scene::{self, Scene};
use radiosity::solver::refine::refined_mesh;
use radiosity::solver::{Flow, Settings, Solver};

/// T-vertices by brute force: (vertex, triangle edge) pairs with the vertex
/// strictly inside the edge, facing the same way as the triangle's corner.
fn brute_t_vertices(mesh: &Mesh, triangles: &[Triangle]) -> usize {
    let mut count = 0;
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (t.corners[k], t.corners[(k + 1) % 3]);
            let (pa, pb) = (
                mesh.vertices[a as usize].position,
                mesh.vertices[b as usize].position,
            );
            let normal = mesh.vertices[a as usize].normal;
            let d = pb - pa;
            for (i, v) in mesh.vertices.iter().enumerate() {
                if i as u32 == a || i as u32 == b || v.normal.dot(normal) < 1.0 - 1e-9 {
                    continue;
                }
                let s = (v.position - pa).dot(d) / d.length_squared();
                if s <= 1e-6 || s >= 1.0 - 1e-6 {
                    continue;
                }
                if (v.position - (pa + d * s)).length() <= 1e-9 * d.length() {
                    count += 1;
                }
            }
        }
    }
    count
}

/// Every area adds up, every vertex is a corner of some triangle, no
/// triangle is flat or faces away from its surface, and no T-vertex.
fn check_conforming(scene: &Scene, mesh: &Mesh) {
    let triangles = mesh.triangles();
    let mut surface_area = vec![0.0; scene.surfaces.len()];
    let mut used = vec![false; mesh.vertices.len()];
    for t in &triangles {
        let element = &mesh.elements[t.element as usize];
        let p = t.corners.map(|v| mesh.vertices[v as usize].position);
        let normal = scene.surfaces[element.surface as usize].normal;
        let area2 = (p[1] - p[0]).cross(p[2] - p[0]).dot(normal);
        assert!(area2 > 0.0, "flat or flipped triangle {t:?}");
        surface_area[element.surface as usize] += area2 / 2.0;
        for v in t.corners {
            used[v as usize] = true;
        }
    }
    for (s, surface) in scene.surfaces.iter().enumerate() {
        assert!(
            (surface_area[s] - surface.area).abs() <= 1e-9 * surface.area,
            "surface {s}: triangles cover {} of {}",
            surface_area[s],
            surface.area
        );
        let elements: f64 = mesh
            .elements
            .iter()
            .filter(|e| e.surface as usize == s)
            .map(|e| e.area)
            .sum();
        assert!((elements - surface.area).abs() <= 1e-9 * surface.area);
    }
    assert!(used.iter().all(|u| *u), "a vertex belongs to no triangle");
    assert_eq!(brute_t_vertices(mesh, &triangles), 0);
    assert_eq!(mesh.t_vertices(&triangles), 0);
}

#[test]
fn randomly_refined_meshes_conform() {
    let scene = scene::load("cornell").unwrap();
    let sizes = scene.default_mesh_sizes();
    let settings = MeshSettings {
        patch_size: sizes.patch_size,
        element_size: 3.0 * sizes.element_size,
        conform: true,
        ..MeshSettings::default()
    };
    let mut rng = Rng(7);
    for round in 0..3 {
        let mut mesh = Mesh::build(&scene, &settings).unwrap();
        let depths: Vec<u8> = mesh
            .elements
            .iter()
            .map(|_| match rng.below(10) {
                0..=5 => 0,
                6..=8 => 1,
                _ => 2 + round,
            })
            .collect();
        let before = mesh.vertices.len();
        let refined = mesh.refine(&depths, 1_000_000, 1.0).unwrap();
        assert!(refined.vertices.len() > before);
        // Old vertices keep their indices.
        for (a, b) in mesh.vertices.iter().zip(&refined.vertices) {
            assert_eq!(a.position, b.position);
        }
        let expected: usize = depths.iter().map(|&d| 1usize << (2 * d)).sum();
        assert_eq!(refined.elements.len(), expected);
        mesh = refined;
        mesh.share_coplanar_edge_vertices();
        check_conforming(&scene, &mesh);
    }
}

/// Two coplanar quads of different reflectance side by side, 1 m and 2 m
/// along the line they share, so cut at different points along it:
/// T-vertices until they share their edge vertices.
#[test]
fn coplanar_surfaces_share_their_edge_vertices() {
    let a = quad(DVec3::ZERO, DVec3::Z * 1.0, DVec3::X * 1.0, 0.5, 0.0, 0);
    let b = quad(
        DVec3::new(1.0, 0.0, 0.0),
        DVec3::Z * 2.0,
        DVec3::X * 3.0,
        0.2,
        0.0,
        1,
    );
    let scene = scene_of(vec![a, b]);
    let settings = MeshSettings {
        patch_size: 10.0,
        element_size: 0.3,
        conform: true,
        ..MeshSettings::default()
    };
    let mut mesh = Mesh::build(&scene, &settings).unwrap();
    assert!(brute_t_vertices(&mesh, &mesh.triangles()) > 0);
    let added = mesh.share_coplanar_edge_vertices();
    assert!(added > 0);
    check_conforming(&scene, &mesh);
}

/// A unit square in 4 x 4 elements: radiosity stepping from 1 to 0.2 at
/// x = 0.6 splits the elements the step crosses, to the level cap; a
/// gentle linear field splits none.
#[test]
fn the_error_estimate_finds_a_step_and_spares_a_smooth_field() {
    let square = quad(DVec3::ZERO, DVec3::Z * 1.0, DVec3::X * 1.0, 0.5, 0.0, 0);
    let scene = scene_of(vec![square]);
    let settings = MeshSettings {
        patch_size: 10.0,
        element_size: 0.25,
        ..MeshSettings::default()
    };
    let mesh = Mesh::build(&scene, &settings).unwrap();
    assert_eq!(mesh.elements.len(), 16);
    let field = |f: &dyn Fn(DVec3) -> f64| -> (Vec<DVec3>, Vec<DVec3>) {
        let vertices = mesh
            .vertices
            .iter()
            .map(|v| DVec3::splat(f(v.position)))
            .collect();
        let centres = mesh
            .elements
            .iter()
            .map(|e| DVec3::splat(f(mesh::element_centre(&mesh, e))))
            .collect();
        (vertices, centres)
    };
    let step = |p: DVec3| if p.x < 0.6 { 1.0 } else { 0.2 };
    let (v, c) = field(&step);
    let depths = mesh::split_depths(&mesh, &v, &c, 0.1, 2);
    for (e, d) in mesh.elements.iter().zip(&depths) {
        let xs: Vec<f64> = e
            .vertices()
            .iter()
            .map(|&i| mesh.vertices[i as usize].position.x)
            .collect();
        let crosses = xs.iter().any(|&x| x < 0.6) && xs.iter().any(|&x| x > 0.6);
        assert_eq!(*d, if crosses { 2 } else { 0 }, "{xs:?}");
    }
    let (v, c) = field(&|p: DVec3| 1.0 + 0.1 * p.x + 0.05 * p.z);
    assert!(
        mesh::split_depths(&mesh, &v, &c, 0.1, 2)
            .iter()
            .all(|&d| d == 0)
    );
}

/// The default settings at a coarse element size on the Cornell box: the
/// coarse pass splits some elements; the solve on the refined mesh keeps
/// its ledger to 1e-9 after every shot; mesh and answer are the same, to
/// the bit, with one and three threads.
#[test]
fn a_refined_solve_balances_and_ignores_the_thread_count() {
    let scene = scene::load("cornell").unwrap();
    let sizes = scene.default_mesh_sizes();
    let mut settings = Settings::adaptive();
    settings.mesh.patch_size = sizes.patch_size;
    settings.mesh.element_size = 2.0 * sizes.element_size;
    settings.max_shots = Some(60);
    let solve_with = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let refined = refined_mesh(&scene, &settings, None).unwrap();
                assert!(refined.split_elements > 0);
                assert!(refined.mesh.elements.len() > refined.base_elements);
                let mut solver = Solver::new(&scene, &refined.mesh, settings.clone());
                solver.run(|s| {
                    let e = s.energy();
                    let balance = s.unshot_power() + e.absorbed + e.escaped;
                    assert!((balance - e.emitted).abs().max_element() <= 1e-9 * e.emitted.x);
                    Flow::Continue
                });
                let positions: Vec<DVec3> =
                    refined.mesh.vertices.iter().map(|v| v.position).collect();
                (positions, solver.radiosity().to_vec())
            })
    };
    let (mesh_one, one) = solve_with(1);
    let (mesh_three, three) = solve_with(3);
    assert_eq!(mesh_one, mesh_three);
    assert!(one.iter().zip(&three).all(|(a, b)| a == b));
}

/// The furnace's light is uniform: nothing to refine, and the answer stays
/// 2 everywhere within the adaptive solver's bound.
#[test]
fn uniform_light_refines_nothing() {
    let scene = common::furnace(1.0, 0.5, 1.0);
    let mut settings = Settings::adaptive();
    settings.mesh.patch_size = 0.5;
    settings.mesh.element_size = 0.125;
    settings.mesh.refine = RefineSettings {
        refine_levels: 2,
        ..RefineSettings::default()
    };
    settings.converge = 1e-7;
    let refined = refined_mesh(&scene, &settings, None).unwrap();
    assert_eq!(refined.split_elements, 0);
    assert_eq!(refined.mesh.elements.len(), refined.base_elements);
    let mut solver = Solver::new(&scene, &refined.mesh, settings);
    solver.run(|_| Flow::Continue);
    let worst = solver
        .radiosity()
        .iter()
        .map(|b| (b.x - 2.0).abs() / 2.0)
        .fold(0.0, f64::max);
    assert!(worst < 5e-3, "worst {worst}");
}

/// Areas of a refined element's pieces: a quad's four bilinear quarters
/// and a triangle's four halves-of-edges triangles tile it.
#[test]
fn pieces_tile_their_element() {
    let tri = scene::Surface::new(
        vec![
            DVec3::ZERO,
            DVec3::new(3.0, 0.0, 0.0),
            DVec3::new(0.5, 0.0, -2.0),
        ],
        DVec3::splat(0.5),
        DVec3::ZERO,
        0,
    )
    .unwrap();
    let scene = scene_of(vec![tri]);
    let settings = MeshSettings {
        patch_size: 10.0,
        element_size: 1.0,
        ..MeshSettings::default()
    };
    let mesh = Mesh::build(&scene, &settings).unwrap();
    let refined = mesh
        .refine(&vec![3; mesh.elements.len()], 1_000_000, 1.0)
        .unwrap();
    let total: f64 = refined.elements.iter().map(|e| e.area).sum();
    assert!((total - scene.surfaces[0].area).abs() < 1e-12 * total);
    for e in &refined.elements {
        let p: Vec<DVec3> = e
            .vertices()
            .iter()
            .map(|&v| refined.vertices[v as usize].position)
            .collect();
        assert!((geometry::area(&p) - e.area).abs() < 1e-15);
    }
    check_conforming(&scene, &refined);
}

/// The meshes the default settings show and write for the built-in room
/// and Cornell box (refined after their coarse pass, coplanar surfaces
/// sharing edge vertices): no T-vertex, counted by brute force (the fixed
/// grid had 44 and 92: faces of one plane cutting a shared edge apart).
#[test]
fn the_default_meshes_of_the_room_and_the_cornell_box_have_no_t_vertices() {
    for name in ["room", "cornell"] {
        let scene = scene::load(name).unwrap();
        let sizes = scene.default_mesh_sizes();
        let mut settings = Settings::adaptive();
        settings.mesh.patch_size = sizes.patch_size;
        settings.mesh.element_size = sizes.element_size;
        let mut merged = scene.clone();
        scene::merge::merge_coplanar(&mut merged.surfaces);
        let refined = refined_mesh(&merged, &settings, None).unwrap();
        assert!(refined.split_elements > 0, "{name}");
        let triangles = refined.mesh.triangles();
        assert_eq!(brute_t_vertices(&refined.mesh, &triangles), 0, "{name}");
        let fixed = Mesh::build(&merged, &settings.mesh).unwrap();
        assert!(brute_t_vertices(&fixed, &fixed.triangles()) > 0, "{name}");
    }
}

/// Refinement stops short of `--max-elements`: asked for more, it lowers
/// the deepest splits until the mesh fits, rather than failing after its
/// coarse pass.
#[test]
fn refinement_fits_under_the_element_limit() {
    let scene = scene::load("cornell").unwrap();
    let sizes = scene.default_mesh_sizes();
    let mut settings = Settings::adaptive();
    settings.mesh.patch_size = sizes.patch_size;
    settings.mesh.element_size = 2.0 * sizes.element_size;
    settings.mesh.refine.refine_tolerance = 0.01;
    let free = refined_mesh(&scene, &settings, None).unwrap();
    let base = free.base_elements;
    assert!(free.mesh.elements.len() > base + 100);
    settings.mesh.max_elements = base + 100;
    let capped = refined_mesh(&scene, &settings, None).unwrap();
    assert!(capped.mesh.elements.len() <= base + 100);
    assert!(capped.mesh.elements.len() >= base);
    check_conforming(&scene, &capped.mesh);
}

/// Vertices a split makes belong to the split element's own face, even in
/// a surface id of several merged faces whose first corner may lie on a
/// neighbour (a vertex tagged with the neighbour gathers at a point nudged
/// towards the wrong centroid, and bakes take the wrong face's UVs).
#[test]
fn split_vertices_lie_on_their_own_face() {
    let a = quad(DVec3::ZERO, DVec3::Z * 1.0, DVec3::X * 1.0, 0.5, 0.0, 0);
    let b = quad(
        DVec3::new(1.0, 0.0, 0.0),
        DVec3::Z * 1.0,
        DVec3::X * 1.0,
        0.5,
        0.0,
        1,
    );
    let mut scene = scene_of(vec![a, b]);
    scene::merge::merge_coplanar(&mut scene.surfaces);
    assert_eq!(scene.surfaces[0].group, scene.surfaces[1].group);
    let settings = MeshSettings {
        patch_size: 10.0,
        element_size: 0.5,
        ..MeshSettings::default()
    };
    let mesh = Mesh::build(&scene, &settings).unwrap();
    let refined = mesh
        .refine(&vec![2; mesh.elements.len()], 10_000, 0.5)
        .unwrap();
    for v in &refined.vertices[mesh.vertices.len()..] {
        let surface = &scene.surfaces[v.surface as usize];
        assert!(
            geometry::convex_contains(&surface.polygon, surface.normal, v.position, 1e-9),
            "{:?} tagged with face {}",
            v.position,
            v.surface
        );
    }
}
