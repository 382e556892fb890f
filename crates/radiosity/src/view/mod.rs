//! The default view of a scene (beyond the paper, which always brings its
//! camera): the scene's own camera, else a view from inside when the scene
//! is an interior ([`interior`]), else one framing its bounding box from
//! outside ([`Camera::framing`]).
//!
//! It sits above both the scenes and the accelerators in the pipeline:
//! whether a scene is an interior, and where its eye goes, is found by
//! tracing sight lines through a BVH of its surfaces with closest-hit
//! queries ([`crate::accel::Occluder::closest_hit`]).

pub mod interior;

use crate::scene::{Camera, Scene};

/// The scene's camera; for a scene that brings none, a view from inside
/// when it is an interior, else one framing its bounds from outside
/// ([`Camera::framing`]).
///
/// An interior is a scene with lights whose surfaces close around the
/// space: of sight lines cast in all directions from candidate eyes inside
/// its bounding box, at most 5% leave the box. Its view is taken at eye
/// height (1.6 m above the bottom of the box for a scene 2 to 100 m tall,
/// else half its height), from near one end of the longest horizontal axis
/// looking along it, from the candidate eye that is not inside a solid,
/// behind a wall or looking out of an opening and whose view has the
/// longest free sight lines. Sight lines are traced through a BVH of the
/// scene, so the first call on a large scene takes a fraction of a second;
/// the rule and its constants are in [`interior`]. A box with an open side
/// (the Cornell box) or an object on a ground plane is framed from outside.
#[must_use]
pub fn camera_or_framing(scene: &Scene) -> Camera {
    scene
        .camera
        .or_else(|| interior::interior_camera(scene))
        .unwrap_or_else(|| {
            let (lo, hi) = scene.bounds();
            Camera::framing(lo, hi)
        })
}
