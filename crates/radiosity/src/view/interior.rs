//! The default view of an interior (beyond the paper, which always brings
//! its camera): when a scene brings no camera and its surfaces enclose the
//! space its lights are in (Sponza's atrium, the conference room),
//! [`camera_or_framing`](super::camera_or_framing) looks from inside, at
//! eye height along the longest horizontal axis, instead of framing the
//! bounding box from outside, which shows the outer walls.
//!
//! The rule, with y up:
//!
//! 1. **Candidates.** Eyes at [`EYE_HEIGHT`] (1.6 m) above the bottom of
//!    the bounding box when the scene's height is that of a building in
//!    metres (between [`METRIC_HEIGHTS`]`.0` and `.1`, at most 60% of it),
//!    else at half the height (a scene in centimetres or a small box); at
//!    [`ALONG`] of the longest horizontal axis from either end and
//!    [`ACROSS`] of the other one. Each looks towards the far end of the
//!    long axis, at the middle of its height, with a vertical field of view
//!    that fits the far end's cross-section, kept within [`FOV_DEGREES`].
//! 2. **Sight lines.** From each eye, [`SPHERE_RAYS`] rays in all directions
//!    and a [`VIEW_RAYS`] grid over its 4:3 view are traced through a BVH
//!    of the scene ([`crate::accel::bvh`]) with closest-hit queries
//!    ([`Occluder::closest_hit`]): a ray's free distance is that of the
//!    first surface it meets, and a ray that meets none before leaving the
//!    bounding box escapes. For the sphere rays, the side of the surface met
//!    is noted: the back, unless a surface facing the eye is crossed within
//!    [`COINCIDENT`] of the ray's length beyond it (a wall modelled as two
//!    faces back to back shows its front from either side).
//! 3. **Rejects.** An eye is rejected when more than [`MAX_BACK`] of its
//!    sphere rays meet a surface from behind (it is inside a solid, or
//!    behind a wall) or more than [`MAX_VIEW_ESCAPE`] of its view rays escape
//!    (it looks out of an opening).
//! 4. **Interior.** The scene is an interior when it has lights and, over
//!    the eyes not inside solids, at most [`MAX_ESCAPE`] of the sphere rays
//!    escape: the surfaces close around the space. A box with an open side
//!    (the Cornell box: a sixth of all directions from its centre) or an
//!    object on a ground plane (half) is seen from outside.
//! 5. **Choice.** Of the eyes not rejected, the one whose view rays have
//!    the longest mean free distance (capped at the bounding-box diagonal)
//!    sees the most of the space. Sights within [`SIGHT_TIE`] of each other
//!    tie (the mirror-image eyes of a symmetric scene differ by round-off
//!    only), and ties go to the first in candidate order, so the choice is
//!    deterministic.
//!
//! No candidate passing, or no light, gives `None`: the framing camera.

use glam::DVec3;
use rayon::prelude::*;

use crate::accel::bvh::Bvh;
use crate::accel::{Hit, Occluder};
use crate::scene::{Camera, Scene, Surface};

/// Eye height above the floor for scenes in metres.
pub const EYE_HEIGHT: f64 = 1.6;

/// Scene heights (the bounding box's y extent) taken to be buildings in
/// metres; outside this range the eye is at half the height.
pub const METRIC_HEIGHTS: (f64, f64) = (2.0, 100.0);

/// Eye positions along the long horizontal axis, as fractions of it from
/// each end.
pub const ALONG: [f64; 3] = [0.1, 0.25, 0.4];

/// Eye positions across the other horizontal axis, as fractions of it.
pub const ACROSS: [f64; 3] = [0.5, 0.3, 0.7];

/// Range of the vertical field of view, degrees.
pub const FOV_DEGREES: (f64, f64) = (55.0, 75.0);

/// Aspect ratio the view is planned for (the default picture is 800 x 600).
pub const ASPECT: f64 = 4.0 / 3.0;

/// Rays in all directions from each eye.
pub const SPHERE_RAYS: usize = 48;

/// Rays across each eye's view: columns and rows.
pub const VIEW_RAYS: (usize, usize) = (9, 7);

/// Largest share of an eye's sphere rays meeting a surface from behind.
pub const MAX_BACK: f64 = 0.2;

/// Largest share of an eye's view rays leaving the bounding box.
pub const MAX_VIEW_ESCAPE: f64 = 0.1;

/// Largest share of sphere rays leaving the bounding box, over the eyes not
/// inside solids, for the scene to count as an interior.
pub const MAX_ESCAPE: f64 = 0.05;

/// Faces back to back (a panel modelled once per side, as real files have
/// them) are crossed at nearly the same distance, in either order: a sight
/// line whose first surface faces away from the eye still meets a front
/// when a surface facing the eye is crossed within this fraction of the
/// line's length (to the bounding box's exit) beyond it. 2^-16, a
/// millimetre or less in a building.
pub const COINCIDENT: f64 = 1.0 / 65_536.0;

/// Relative difference of mean sights within which two eyes tie (rule 5):
/// above the round-off that tells mirror-image eyes apart, far below any
/// difference a view shows.
pub const SIGHT_TIE: f64 = 1e-6;

/// One candidate eye and what its sight lines found.
#[derive(Clone, Debug)]
pub struct Candidate {
    /// The view from it.
    pub camera: Camera,
    /// Share of its sphere rays that leave the bounding box.
    pub escape: f64,
    /// Share of its sphere rays whose first surface faces away from it.
    pub back: f64,
    /// Share of its view rays that leave the bounding box.
    pub view_escape: f64,
    /// Mean free distance of its view rays over the bounding-box diagonal
    /// (escaping rays count 0).
    pub sight: f64,
}

impl Candidate {
    /// True when the eye is neither inside a solid nor behind a wall nor
    /// looking out of an opening (rule 3).
    #[must_use]
    pub fn usable(&self) -> bool {
        self.back <= MAX_BACK && self.view_escape <= MAX_VIEW_ESCAPE
    }
}

/// What the rule found for a scene.
#[derive(Clone, Debug)]
pub struct Analysis {
    /// Every candidate, in the order of [`ALONG`] (each from the low end,
    /// then from the high end) and [`ACROSS`].
    pub candidates: Vec<Candidate>,
    /// Mean escape share of the candidates not inside solids (rule 4).
    pub escape: f64,
    /// Whether the scene has lights and encloses them (rule 4).
    pub interior: bool,
    /// The chosen candidate (rule 5), for an interior with a usable eye.
    pub chosen: Option<usize>,
}

impl Analysis {
    /// The chosen view, if any.
    #[must_use]
    pub fn camera(&self) -> Option<Camera> {
        self.chosen.map(|i| self.candidates[i].camera)
    }
}

/// Applies the rule to a scene; `None` for a scene with no light or with no
/// horizontal or vertical extent.
#[must_use]
pub fn analyse(scene: &Scene) -> Option<Analysis> {
    if scene.lights.is_empty() && !scene.surfaces.iter().any(Surface::is_emitter) {
        return None;
    }
    let (lo, hi) = scene.bounds();
    let size = hi - lo;
    let diagonal = size.length();
    if !(diagonal.is_finite() && size.min_element() > 1e-9 * diagonal) {
        return None;
    }
    let (long, across) = if size.x >= size.z { (0, 2) } else { (2, 0) };
    let height = size.y;
    let eye_height = if (METRIC_HEIGHTS.0..=METRIC_HEIGHTS.1).contains(&height) {
        EYE_HEIGHT.min(0.6 * height)
    } else {
        0.5 * height
    };
    let mut eyes = Vec::new();
    for from_high in [false, true] {
        for along in ALONG {
            for side in ACROSS {
                let mut eye = lo;
                eye[long] += size[long] * if from_high { 1.0 - along } else { along };
                eye[across] += size[across] * side;
                eye.y += eye_height;
                let mut target = eye;
                target[long] = if from_high { lo[long] } else { hi[long] };
                target.y = lo.y + 0.5 * height;
                let distance = (target[long] - eye[long]).abs();
                let half = (0.5 * height).max(0.5 * size[across] / ASPECT);
                let fov = (2.0 * (half / distance).atan())
                    .to_degrees()
                    .clamp(FOV_DEGREES.0, FOV_DEGREES.1);
                eyes.push(Camera {
                    eye,
                    target,
                    up: DVec3::Y,
                    fov_degrees: fov,
                });
            }
        }
    }
    let bvh = Bvh::new(&scene.surfaces);
    let tracer = Tracer {
        scene,
        occluder: &bvh,
        lo,
        hi,
        diagonal,
    };
    let sphere = crate::geometry::spherical::sphere_directions(SPHERE_RAYS);
    let candidates: Vec<Candidate> = eyes
        .par_iter()
        .map(|camera| tracer.candidate(*camera, &sphere))
        .collect();
    let open: Vec<&Candidate> = candidates.iter().filter(|c| c.back <= MAX_BACK).collect();
    let escape = if open.is_empty() {
        1.0
    } else {
        open.iter().map(|c| c.escape).sum::<f64>() / open.len() as f64
    };
    let interior = escape <= MAX_ESCAPE;
    let mut chosen: Option<usize> = None;
    if interior {
        for (i, c) in candidates.iter().enumerate() {
            let better = |b: usize| c.sight > candidates[b].sight * (1.0 + SIGHT_TIE);
            if c.usable() && chosen.is_none_or(better) {
                chosen = Some(i);
            }
        }
    }
    Some(Analysis {
        candidates,
        escape,
        interior,
        chosen,
    })
}

/// The interior view of a scene, when the rule gives one.
#[must_use]
pub fn interior_camera(scene: &Scene) -> Option<Camera> {
    analyse(scene).and_then(|a| a.camera())
}

/// Where a sight line ends.
enum Sight {
    /// It leaves the bounding box without meeting a surface.
    Escapes,
    /// It meets a surface first: this one, at this distance.
    Hits(Hit),
}

/// Sight lines through the scene's BVH.
struct Tracer<'a> {
    scene: &'a Scene,
    occluder: &'a dyn Occluder,
    lo: DVec3,
    hi: DVec3,
    diagonal: f64,
}

/// A query skips no surface.
const NO_SKIP: [u32; 2] = [u32::MAX, u32::MAX];

impl Tracer<'_> {
    fn candidate(&self, camera: Camera, sphere: &[DVec3]) -> Candidate {
        let eye = camera.eye;
        let mut escaped = 0;
        let mut back = 0;
        for &d in sphere {
            match self.sight(eye, d) {
                Sight::Escapes => escaped += 1,
                Sight::Hits(hit) => {
                    if !self.front_facing(eye, d, hit) {
                        back += 1;
                    }
                }
            }
        }
        let forward = (camera.target - eye).normalize();
        let right = forward.cross(camera.up).normalize();
        let up = right.cross(forward);
        let tan_v = (0.5 * camera.fov_degrees.to_radians()).tan();
        let tan_h = tan_v * ASPECT;
        let (columns, rows) = VIEW_RAYS;
        let mut view_escaped = 0;
        let mut sight = 0.0;
        for i in 0..columns {
            for j in 0..rows {
                let u = 2.0 * (i as f64 + 0.5) / columns as f64 - 1.0;
                let v = 2.0 * (j as f64 + 0.5) / rows as f64 - 1.0;
                let d = (forward + right * (u * tan_h) + up * (v * tan_v)).normalize();
                match self.sight(eye, d) {
                    Sight::Escapes => view_escaped += 1,
                    Sight::Hits(hit) => sight += hit.t.min(self.diagonal) / self.diagonal,
                }
            }
        }
        let views = (columns * rows) as f64;
        Candidate {
            camera,
            escape: escaped as f64 / sphere.len() as f64,
            back: back as f64 / sphere.len() as f64,
            view_escape: view_escaped as f64 / views,
            sight: sight / views,
        }
    }

    /// Distance along `d` (unit) from `eye` to where the ray leaves the
    /// bounding box, a hundredth of the diagonal beyond it.
    fn exit(&self, eye: DVec3, d: DVec3) -> f64 {
        let mut t = f64::INFINITY;
        for axis in 0..3 {
            if d[axis] > 0.0 {
                t = t.min((self.hi[axis] - eye[axis]) / d[axis]);
            } else if d[axis] < 0.0 {
                t = t.min((self.lo[axis] - eye[axis]) / d[axis]);
            }
        }
        t.max(0.0) + 0.01 * self.diagonal
    }

    /// The first surface met along `d` (unit) from `eye` before the ray
    /// leaves the bounding box, and its distance.
    fn sight(&self, eye: DVec3, d: DVec3) -> Sight {
        match self
            .occluder
            .closest_hit(eye, d, self.exit(eye, d), NO_SKIP)
        {
            Some(hit) => Sight::Hits(hit),
            None => Sight::Escapes,
        }
    }

    /// Whether the ray from `eye` along `d` meets a front at `hit`: the
    /// surface hit faces the eye, or one facing it is crossed within
    /// [`COINCIDENT`] of the ray's length beyond. The surfaces behind the
    /// first are found by asking again with the ids already seen skipped,
    /// so up to three are looked at (a query skips two ids).
    fn front_facing(&self, eye: DVec3, d: DVec3, hit: Hit) -> bool {
        let reach = hit.t + COINCIDENT * self.exit(eye, d);
        let mut skip = NO_SKIP;
        let mut surface = &self.scene.surfaces[hit.surface as usize];
        for slot in 0..skip.len() {
            if surface.normal.dot(d) < 0.0 {
                return true;
            }
            skip[slot] = surface.group;
            match self.occluder.closest_hit(eye, d, reach, skip) {
                Some(next) => surface = &self.scene.surfaces[next.surface as usize],
                None => return false,
            }
        }
        surface.normal.dot(d) < 0.0
    }
}
