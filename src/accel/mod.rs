//! Shadow-segment visibility (design.md section 3): does any surface cross
//! the open segment between a subsource point and a receiving vertex?
//!
//! [`brute::BruteForce`] tests every surface, as Wallace et al. (1989) did;
//! it is the oracle every accelerator is tested against. [`bsp::Bsp`] walks
//! a BSP tree front to back from the segment's origin (Wong & Tsang,
//! section 3); [`bvh::Bvh`] is a surface-area-heuristic bounding-volume
//! hierarchy, the modern answer, kept beside it for comparison. The segment test
//! itself, [`segment_crosses`], is shared by all of them.

pub mod brute;
pub mod bsp;
pub mod bvh;

use glam::DVec3;

use crate::geometry;
use crate::scene::Surface;

/// Which shadow-ray accelerator answers visibility queries.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Accel {
    /// Every surface is tested (the oracle).
    Brute,
    /// A BSP tree over the surfaces, walked front to back (paper section 3).
    Bsp,
    /// A surface-area-heuristic bounding-volume hierarchy (beyond the
    /// paper: the modern answer, kept beside the BSP for comparison).
    Bvh,
}

impl Accel {
    /// Every accelerator, in the order the command line lists them.
    pub const ALL: [Accel; 3] = [Accel::Brute, Accel::Bsp, Accel::Bvh];

    /// The name used on the command line and in statistics.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Accel::Brute => "brute",
            Accel::Bsp => "bsp",
            Accel::Bvh => "bvh",
        }
    }

    /// Parses a command-line name.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Accel> {
        Accel::ALL.into_iter().find(|a| a.name() == name)
    }

    /// Builds the accelerator over the scene's surfaces.
    #[must_use]
    pub fn build(self, surfaces: &[Surface]) -> Box<dyn Occluder + '_> {
        match self {
            Accel::Brute => Box::new(brute::BruteForce::new(surfaces)),
            Accel::Bsp => Box::new(bsp::Bsp::new(surfaces)),
            Accel::Bvh => Box::new(bvh::Bvh::new(surfaces)),
        }
    }
}

/// A shadow-segment query structure.
pub trait Occluder: Sync {
    /// True when a surface other than `skip[0]` and `skip[1]` crosses the
    /// open segment `from -> to`. Callers pass the source's and receiver's
    /// surfaces as `skip`: a planar convex surface cannot hide its own
    /// points from a point in front of it, and skipping them makes the test
    /// immune to round-off at both ends.
    fn occluded(&self, from: DVec3, to: DVec3, skip: [u32; 2]) -> bool;

    /// Build statistics worth reporting (name, value), e.g. a tree's node
    /// count and depth; none by default.
    fn build_statistics(&self) -> Vec<(&'static str, usize)> {
        Vec::new()
    }
}

/// Relative amount by which a shadow segment is shortened at each end, so a
/// receiver on the edge where two surfaces meet is not hidden by the
/// neighbour it touches.
pub const SEGMENT_EPSILON: f64 = 1e-6;

/// Shortens `from -> to` by [`SEGMENT_EPSILON`] of its length at both ends.
#[must_use]
pub fn shorten(from: DVec3, to: DVec3) -> (DVec3, DVec3) {
    let d = (to - from) * SEGMENT_EPSILON;
    (from + d, to - d)
}

/// True when the segment `from -> to` passes strictly from one side of the
/// surface's plane to the other through the polygon (edges included, with a
/// tolerance of 1e-9 of the surface's size so that rays cannot slip through
/// the shared edge of two surfaces).
#[must_use]
pub fn segment_crosses(surface: &Surface, from: DVec3, to: DVec3) -> bool {
    let d0 = surface.normal.dot(from) - surface.offset;
    let d1 = surface.normal.dot(to) - surface.offset;
    if d0 == 0.0 || d1 == 0.0 || (d0 > 0.0) == (d1 > 0.0) {
        return false;
    }
    let t = d0 / (d0 - d1);
    let p = from + (to - from) * t;
    let tolerance = 1e-9 * surface.area.sqrt();
    geometry::convex_contains(&surface.polygon, surface.normal, p, tolerance)
}
