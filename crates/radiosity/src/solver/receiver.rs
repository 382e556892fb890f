//! Where light is gathered (design.md section 2's receivers; the paper
//! gathers at the element mesh's vertices): a vertex or a sensor, moved a
//! hair into its surface so a point on an edge takes the one-sided limit
//! its element's interior tends to.

use glam::DVec3;

use crate::geometry;
use crate::mesh::Mesh;
use crate::scene::Scene;

/// A point that gathers light: a mesh vertex or a sensor.
#[derive(Clone, Copy, Debug)]
pub struct Receiver {
    /// Where it gathers (a vertex is moved a hair into its surface, see
    /// [`GATHER_NUDGE`]).
    pub point: DVec3,
    /// Unit normal of its side.
    pub normal: DVec3,
    /// The surface it lies on.
    pub surface: u32,
    /// That surface's id ([`crate::scene::Surface::group`]).
    pub group: u32,
}

/// A vertex gathers at a point moved this fraction of the way towards its
/// surface's centroid. A vertex on the edge where two surfaces meet lies in
/// the neighbour's plane and sees it exactly edge-on (factor 0), while every
/// point of its own surface next to it sees the neighbour at up to half its
/// hemisphere; the displaced point takes the one-sided limit that the
/// element's interior tends to, and stays within 1e-6 of its size of the
/// vertex.
pub const GATHER_NUDGE: f64 = 1e-6;

/// The receivers of a mesh: its vertices at their gathering points.
#[must_use]
pub fn vertex_receivers(scene: &Scene, mesh: &Mesh) -> Vec<Receiver> {
    surface_receivers(scene, mesh.vertices.iter().map(|v| (v.surface, v.position)))
}

/// Receivers at `(surface, point)` pairs, each moved [`GATHER_NUDGE`] of
/// the way towards its surface's centroid, with the surface's normal.
pub fn surface_receivers(
    scene: &Scene,
    points: impl Iterator<Item = (u32, DVec3)>,
) -> Vec<Receiver> {
    let centroids: Vec<DVec3> = scene
        .surfaces
        .iter()
        .map(|s| geometry::centroid(&s.polygon))
        .collect();
    points
        .map(|(surface, p)| {
            let s = &scene.surfaces[surface as usize];
            Receiver {
                point: p + (centroids[surface as usize] - p) * GATHER_NUDGE,
                normal: s.normal,
                surface,
                group: s.group,
            }
        })
        .collect()
}
