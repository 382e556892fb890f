//! What the experiments that run the solver share (Wong & Tsang 1993,
//! Figure 2.1 of section 2, Figures 5.1 and 5.2 of section 5): a built-in
//! scene meshed at its suggested sizes or at about the paper's vertex count,
//! a timed solve, the seconds of their tables, and the paper's steps of
//! Figures 5.1 and 5.2 (9, 48 and 72 subsources, with the paper's times).

use std::time::Instant;

use super::Error;
use radiosity::app;
use radiosity::mesh::{Mesh, MeshSettings};
use radiosity::scene::{self, Scene};
use radiosity::solver::{Flow, Settings, Solver};

/// A scene meshed with its suggested sizes, or with an element size chosen
/// to give about `target_vertices` vertices.
pub(crate) fn meshed(name: &str, target_vertices: Option<usize>) -> Result<(Scene, Mesh), Error> {
    let scene = scene::load(name).map_err(app::Error::from)?;
    let sizes = scene.default_mesh_sizes();
    let settings = |element_size: f64| MeshSettings {
        patch_size: sizes.patch_size,
        element_size,
        ..MeshSettings::default()
    };
    let build = |element_size: f64| {
        Mesh::build(&scene, &settings(element_size)).map_err(|e| Error::App(app::Error::Mesh(e)))
    };
    let Some(target) = target_vertices else {
        let mesh = build(sizes.element_size)?;
        return Ok((scene, mesh));
    };
    // Vertex count falls as the element size grows: bisect on a log scale.
    let (mut small, mut large) = (sizes.element_size / 20.0, sizes.element_size * 20.0);
    for _ in 0..40 {
        let mid = (small * large).sqrt();
        if build(mid)?.vertices.len() > target {
            small = mid;
        } else {
            large = mid;
        }
    }
    let below = build(large)?;
    let above = build(small)?;
    let mesh = if target.abs_diff(below.vertices.len()) <= target.abs_diff(above.vertices.len()) {
        below
    } else {
        above
    };
    Ok((scene, mesh))
}

/// Solves with `settings`, timing the solver's construction (the
/// accelerator's build) and the shots.
pub(crate) fn timed_solve<'a>(
    scene: &'a Scene,
    mesh: &'a Mesh,
    settings: &Settings,
) -> (Solver<'a>, f64) {
    let start = Instant::now();
    let mut solver = Solver::new(scene, mesh, settings.clone());
    solver.run(|_| Flow::Continue);
    let seconds = start.elapsed().as_secs_f64();
    (solver, seconds)
}

/// Seconds for the tables: milliseconds below 10 ms.
pub(crate) fn seconds(s: f64) -> String {
    if s < 0.01 {
        format!("{:.2} ms", s * 1e3)
    } else {
        format!("{s:.3}")
    }
}

/// The subsource counts of Figure 5.1 and the paper's times (Figure 5.2):
/// (subsources, Wallace's seconds, Wong & Tsang's seconds, sources shot).
pub(crate) const PAPER_STEPS: [(u64, f64, f64, u32); 3] = [
    (9, 116.8, 55.1, 1),
    (48, 554.7, 243.0, 16),
    (72, 826.0, 363.5, 29),
];
