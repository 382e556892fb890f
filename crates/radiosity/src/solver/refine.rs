//! The element mesh a solve runs on, refined where a first, coarse solve
//! finds the light varying: the two-pass scheme of Cohen, Greenberg, Immel
//! & Brock (1986), whose elements are subdivided where a first solution's
//! radiosity varies, then solved again (see [`crate::mesh::split_depths`] and [`Mesh::refine`] for the
//! error estimate and the split).
//!
//! The coarse pass solves the base mesh with the run's own settings and
//! gathers, besides the vertices, at every element's centre. It takes as
//! many shots as there are lights and emitting patches (the direct light,
//! which makes the shadows and shows the contacts; measured, a coarse pass
//! four times as long found no better mesh and cost the conference room
//! 287 s), or fewer if its unshot power falls below [`COARSE_CONVERGE`] of
//! the emitted power first; under a `--time-limit` it takes at most
//! [`COARSE_TIME_SHARE`] of it. Its shots are kept, and the final solve
//! goes on from it on the refined mesh ([`super::Solver::go_on`]): the new
//! vertices get the shots so far replayed to them, split elements' pieces
//! take their share of the unshot light and the ledger the difference, so
//! no shot is made twice. A method that cannot replay its shots (the
//! paper's patches) starts afresh on the refined mesh instead, every
//! vertex gathering from every shot.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use glam::DVec3;

use super::{Flow, Receiver, Settings, Solver};
use crate::mesh::{self, Mesh, MeshError};
use crate::scene::Scene;

/// The coarse pass stops once its unshot power is below this fraction of
/// the emitted power.
pub const COARSE_CONVERGE: f64 = 0.1;

/// The coarse pass takes at most this many shots per light and emitting
/// patch.
pub const COARSE_SHOTS_PER_SOURCE: u64 = 1;

/// Under a time limit, the coarse pass takes at most this share of it
/// (the final solve has the rest: see [`Refined::seconds`]).
pub const COARSE_TIME_SHARE: f64 = 0.25;

/// A mesh ready to solve, and what its refinement did.
pub struct Refined {
    /// The mesh.
    pub mesh: Mesh,
    /// Elements of the base mesh.
    pub base_elements: usize,
    /// Base elements that were split.
    pub split_elements: usize,
    /// Shots of the coarse pass (0 without refinement).
    pub coarse_shots: u64,
    /// Why the coarse pass stopped (`None` without one): its own rules
    /// (converged, its shot budget), or a time limit or an interrupt that
    /// cut it short, after which the mesh is refined from (or, when
    /// interrupted, is) what it had reached.
    pub coarse_stop: Option<super::StopReason>,
    /// Seconds of the coarse pass and the split.
    pub seconds: f64,
    /// Where the coarse pass's shots ran.
    pub coarse_device: super::device::DeviceReport,
    /// The coarse pass's state on the refined mesh, to go on from
    /// ([`Solver::resume_or_new`]); `None` when there was no coarse pass, or its
    /// method cannot replay its shots (the final solve then starts afresh).
    pub start: Option<super::Start>,
}

/// The receivers at the centres of `mesh`'s elements, placed as vertices
/// are ([`super::GATHER_NUDGE`]).
#[must_use]
pub fn centre_receivers(scene: &Scene, mesh: &Mesh) -> Vec<Receiver> {
    super::surface_receivers(
        scene,
        mesh.elements
            .iter()
            .map(|e| (e.surface, mesh::element_centre(mesh, e))),
    )
}

/// The mesh `settings` ask for: the base grid, refined after a coarse
/// solve when `settings.mesh.refine.refine_levels > 0`. The coarse pass
/// stops early when `interrupt` is raised (the base mesh is then kept).
///
/// # Errors
///
/// When the base mesh or its refinement is refused ([`MeshError`]).
pub fn refined_mesh(
    scene: &Scene,
    settings: &Settings,
    interrupt: Option<Arc<AtomicBool>>,
) -> Result<Refined, MeshError> {
    refine_base(
        scene,
        settings,
        Mesh::build(scene, &settings.mesh)?,
        interrupt,
        &[],
    )
}

/// [`refined_mesh`] from a base mesh built already (with
/// `settings.mesh`), so a caller can check it before the coarse pass. The
/// splits stop short of `settings.mesh.max_elements`: when the depths the
/// estimate asks for would exceed it, the deepest are lowered a level at a
/// time until the mesh fits (the base mesh at worst). The coarse pass's
/// shots are kept and replayed to the refined mesh's new vertices and to
/// `sensors`, so the final solve can go on from it ([`Refined::start`]).
///
/// # Errors
///
/// When the refined mesh is refused ([`MeshError`]).
pub fn refine_base(
    scene: &Scene,
    settings: &Settings,
    base: Mesh,
    interrupt: Option<Arc<AtomicBool>>,
    sensors: &[Receiver],
) -> Result<Refined, MeshError> {
    let start = Instant::now();
    let levels = settings.mesh.refine.refine_levels;
    let base_elements = base.elements.len();
    // The base mesh as it is, when nothing is refined.
    let unrefined = |mut mesh: Mesh,
                     coarse_shots: u64,
                     coarse_stop,
                     coarse_device: &super::device::DeviceReport| {
        if settings.mesh.conform {
            mesh.share_coplanar_edge_vertices();
        }
        Ok(Refined {
            mesh,
            base_elements,
            split_elements: 0,
            coarse_shots,
            coarse_stop,
            seconds: start.elapsed().as_secs_f64(),
            coarse_device: coarse_device.clone(),
            start: None,
        })
    };
    if levels == 0 || base.elements.is_empty() {
        return unrefined(base, 0, None, &super::device::DeviceReport::default());
    }
    let sources = scene.lights.len() as u64
        + base
            .patches
            .iter()
            .filter(|p| scene.surfaces[p.surface as usize].emission != DVec3::ZERO)
            .count() as u64;
    let mut coarse = settings.clone();
    coarse.converge = settings.converge.max(COARSE_CONVERGE);
    coarse.max_shots = Some(
        sources
            .max(1)
            .saturating_mul(COARSE_SHOTS_PER_SOURCE)
            .min(settings.max_shots.unwrap_or(u64::MAX)),
    );
    coarse.max_subsources = None;
    coarse.time_limit = settings.time_limit.map(|t| t.mul_f64(COARSE_TIME_SHARE));
    let centres = centre_receivers(scene, &base);
    let mut solver = Solver::with_sensors(scene, &base, coarse, centres.clone());
    if let Some(flag) = &interrupt {
        solver.interrupt_on(flag.clone());
    }
    solver.record_shots();
    let stop = solver.run(|_| Flow::Continue);
    let coarse_shots = solver.stats().shots;
    let coarse_device = solver.device_report();
    if stop == super::StopReason::Stopped {
        drop(solver);
        return unrefined(base, coarse_shots, Some(stop), &coarse_device);
    }
    let centre_radiosity: Vec<DVec3> = centres
        .iter()
        .zip(solver.sensor_irradiance())
        .map(|(r, e)| scene.surfaces[r.surface as usize].radiosity(*e))
        .collect();
    let mut depths = mesh::split_depths(
        &base,
        solver.radiosity(),
        &centre_radiosity,
        settings.mesh.refine.refine_tolerance,
        levels,
    );
    let limit = settings.mesh.max_elements as u128;
    while mesh::refined_count(base.elements.len(), &depths) > limit {
        let deepest = depths.iter().copied().max().unwrap_or(0);
        for d in &mut depths {
            *d = (*d).min(deepest.saturating_sub(1));
        }
    }
    let split_elements = depths.iter().filter(|&&d| d > 0).count();
    let (mut mesh, parents) = base.refine_with_parents(
        &depths,
        settings.mesh.max_elements,
        settings.mesh.element_size,
    )?;
    if settings.mesh.conform {
        mesh.share_coplanar_edge_vertices();
    }
    let resume = solver.go_on(&mesh, &parents, sensors.to_vec());
    drop(solver);
    Ok(Refined {
        mesh,
        base_elements,
        split_elements,
        coarse_shots,
        coarse_stop: Some(stop),
        seconds: start.elapsed().as_secs_f64(),
        coarse_device,
        start: resume,
    })
}
