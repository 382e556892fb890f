//! Portals as the scene file marks them (beyond the paper): faces of a
//! portal material (`#@portal MATERIAL` in OBJ, `"extras": {"radiosity":
//! {"portal": true}}` on a glTF material), as pbrt-v4's, Mitsuba's and
//! Cycles' portals are marked, kept apart from the surfaces; and the
//! [`Portal`] an opening is, found or marked. Finding openings in the
//! geometry and checking marked ones trace rays: that is the solver's
//! ([`crate::solver::sky::portals`]).

use glam::DVec3;

use super::Location;
use crate::geometry;

/// An opening, as planar convex pieces.
#[derive(Clone, Debug, PartialEq)]
pub struct Portal {
    /// Planar convex polygons that tile the opening.
    pub pieces: Vec<Vec<DVec3>>,
    /// Unit normal of its plane (either side: light passes both ways).
    pub normal: DVec3,
    /// Area, square metres.
    pub area: f64,
}

/// An opening the scene file marks: a planar convex face of a portal
/// material, not a surface of the solve.
#[derive(Clone, Debug, PartialEq)]
pub struct Marked {
    /// Corners, in order.
    pub polygon: Vec<DVec3>,
    /// The material's name.
    pub material: String,
    /// Where the face is, for messages.
    pub location: Location,
}

impl Marked {
    /// As a [`Portal`].
    #[must_use]
    pub fn portal(&self) -> Option<Portal> {
        Some(Portal {
            pieces: vec![self.polygon.clone()],
            normal: geometry::normal(&self.polygon)?,
            area: geometry::area(&self.polygon),
        })
    }
}
