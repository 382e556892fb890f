//! Scenes: the input surfaces with their materials, and the camera that
//! views them (design.md sections 1, 6 and 7).
//!
//! A [`Surface`] is one planar, convex, single-sided polygon carrying a
//! reflectance `rho` and an emitted radiant exitance `E`. Loading turns an
//! input file into surfaces: [`obj`] reads Wavefront OBJ with the MTL
//! material libraries [`mtl`] reads, both through [`text`] (decoding, lines,
//! numbers and how input appears in messages); [`gltf`] reads glTF 2.0
//! (`.gltf`, `.glb`), [`polygon`] turns a face into planar convex pieces and
//! [`builtin`] holds the scenes shipped inside the binary. Every load is
//! bounded by [`Limits`], and input files are checked to be regular files
//! of a sane size before they are read; [`merge`] gives adjacent coplanar
//! faces one surface id. This file holds the types; `load.rs` the loading
//! (which reader, the limits, the errors and where they are), `camera.rs`
//! the camera. (The default camera of a scene that brings none
//! is placed by [`crate::view`], above the accelerators it traces sight
//! lines with.)

pub mod builtin;
mod camera;
pub mod glass;
pub mod gltf;
pub mod ies;
pub mod light;
mod load;
pub mod merge;
pub mod mtl;
pub mod obj;
pub mod polygon;
pub mod portal;
pub mod sky;
pub mod text;

use glam::DVec3;

pub use self::camera::{Camera, CameraError};
pub use self::load::{
    DEFAULT_REFLECTANCE_CAP, Limits, LoadOptions, LoadOptionsError, Loaded, Location, SceneError,
    is_gltf, load, load_with, read_input,
};
use crate::geometry;
pub use light::{Light, LightKind};

/// One planar convex polygon of the input, the unit of visibility.
#[derive(Clone, Debug)]
pub struct Surface {
    /// Corners, counter-clockwise seen from the front.
    pub polygon: Vec<DVec3>,
    /// Unit normal of the front side.
    pub normal: DVec3,
    /// Plane offset: `normal . p = offset` on the surface.
    pub offset: f64,
    /// Area in square metres.
    pub area: f64,
    /// Diffuse reflectance per channel, each in [0, 1).
    pub rho: DVec3,
    /// Emitted radiant exitance per channel, W/m^2.
    pub emission: DVec3,
    /// Index of the input face this surface came from (0-based, input
    /// order); a concave face triangulated on loading gives several
    /// surfaces with the same face index.
    pub face: u32,
    /// The surface id of the paper ("newly created surfaces can still share
    /// the same surface id", section 2): surfaces with one id lie in one
    /// plane, are connected and share a material, so none can hide another's
    /// points. Item buffers store it, shadow rays skip the ids of their two
    /// ends, and vertices are shared within it. [`Surface::new`] gives a
    /// surface its face's id; [`merge::merge_coplanar`] gives adjacent
    /// coplanar faces of one material a common one.
    pub group: u32,
}

impl Surface {
    /// Its radiosity `B = Ke + Kd E` under irradiance `irradiance`
    /// (equation (1)'s left side at a point of it).
    #[must_use]
    pub fn radiosity(&self, irradiance: DVec3) -> DVec3 {
        self.emission + self.rho * irradiance
    }

    /// Builds a surface from a planar convex polygon. Returns `None` if the
    /// polygon has no area.
    #[must_use]
    pub fn new(polygon: Vec<DVec3>, rho: DVec3, emission: DVec3, face: u32) -> Option<Surface> {
        let normal = geometry::normal(&polygon)?;
        let offset = geometry::plane_offset(&polygon, normal);
        let area = geometry::area(&polygon);
        Some(Surface {
            polygon,
            normal,
            offset,
            area,
            rho,
            emission,
            face,
            group: face,
        })
    }

    /// True when the surface emits light.
    #[must_use]
    pub fn is_emitter(&self) -> bool {
        self.emission.max_element() > 0.0
    }
}

/// Patch and element sizes a scene file suggests, in metres.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshHint {
    /// Suggested `--patch-size`.
    pub patch_size: f64,
    /// Suggested `--element-size`.
    pub element_size: f64,
    /// The directive that gave them (`#@mesh` with its file and line), for
    /// messages about sizes that are too small; `None` for sizes derived
    /// from the scene's extent.
    pub directive: Option<Location>,
}

/// A loaded scene.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Short name: the built-in's name or the file's stem.
    pub name: String,
    /// The planar convex surfaces.
    pub surfaces: Vec<Surface>,
    /// Lights that are not surfaces: point, spot and sun lights
    /// ([`light`]).
    pub lights: Vec<Light>,
    /// Glass: transparent panes, not surfaces of the solve, that dim the
    /// shadow rays of lights and daylight crossing them ([`glass`]).
    pub panes: Vec<glass::Pane>,
    /// Openings the file marks for the sky to be sampled through
    /// (`#@portal MATERIAL`, a glTF material's `extras`), not surfaces
    /// ([`portal`]).
    pub portals: Vec<portal::Marked>,
    /// The camera the scene file suggests, if any.
    pub camera: Option<Camera>,
    /// The mesh sizes the scene file suggests (`#@mesh PATCH ELEMENT`).
    pub mesh_hint: Option<MeshHint>,
    /// Things a user should know that did not stop the load (dropped
    /// degenerate faces, ignored statements).
    pub warnings: Vec<String>,
}

/// Axis-aligned bounding box `(lo, hi)` of the surfaces' corners; for no
/// surfaces, `lo` is `+inf` and `hi` is `-inf`. The one place the scene's
/// extent is measured: the BSP and the hemicube take it from here.
#[must_use]
pub fn bounds_of(surfaces: &[Surface]) -> (DVec3, DVec3) {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for p in surfaces.iter().flat_map(|s| &s.polygon) {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    (lo, hi)
}

impl Scene {
    /// Axis-aligned bounding box of all surfaces ([`bounds_of`]).
    #[must_use]
    pub fn bounds(&self) -> (DVec3, DVec3) {
        bounds_of(&self.surfaces)
    }

    /// Patch and element sizes for this scene when the user gives none: the
    /// file's `#@mesh` hint, or sizes relative to the scene's extent
    /// (elements 1/40 and patches 1/3 of the bounding-box diagonal), so a
    /// scene modelled in centimetres meshes as finely as one in metres.
    #[must_use]
    pub fn default_mesh_sizes(&self) -> MeshHint {
        self.mesh_hint.clone().unwrap_or_else(|| {
            let (lo, hi) = self.bounds();
            let diagonal = (hi - lo).length().max(1e-9);
            MeshHint {
                patch_size: diagonal / 3.0,
                element_size: diagonal / 40.0,
                directive: None,
            }
        })
    }
}
