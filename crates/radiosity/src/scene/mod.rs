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
//! faces one surface id. (The default camera of a scene that brings none
//! is placed by [`crate::view`], above the accelerators it traces sight
//! lines with.)

pub mod builtin;
pub mod glass;
pub mod gltf;
pub mod ies;
pub mod light;
pub mod merge;
pub mod mtl;
pub mod obj;
pub mod polygon;
pub mod portal;
pub mod sky;
pub mod text;

use std::fmt;
use std::path::{Path, PathBuf};

use glam::DVec3;

use crate::geometry;
pub use light::{Light, LightKind};
use text::quoted;

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

/// A pinhole camera: eye, target, up and vertical field of view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub eye: DVec3,
    /// Point looked at.
    pub target: DVec3,
    /// Approximate up direction.
    pub up: DVec3,
    /// Vertical field of view in degrees.
    pub fov_degrees: f64,
}

impl Camera {
    /// Parses `eye,target,up,fov` as ten numbers separated by commas or
    /// white space, as `--camera` and the `#@camera` directive take it.
    pub fn parse(text: &str) -> Result<Camera, CameraError> {
        let numbers: Vec<f64> = text
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|t| !t.is_empty())
            .map(|t| {
                t.parse::<f64>()
                    .map_err(|_| CameraError::NotANumber(quoted(t)))
                    .and_then(|v| {
                        if v.is_finite() {
                            Ok(v)
                        } else {
                            Err(CameraError::NotFinite(quoted(t)))
                        }
                    })
            })
            .collect::<Result<_, _>>()?;
        if numbers.len() != 10 {
            return Err(CameraError::Count(numbers.len()));
        }
        let v = |i: usize| DVec3::new(numbers[i], numbers[i + 1], numbers[i + 2]);
        let camera = Camera {
            eye: v(0),
            target: v(3),
            up: v(6),
            fov_degrees: numbers[9],
        };
        camera.validate()?;
        Ok(camera)
    }

    /// Checks that the camera defines a view.
    pub fn validate(&self) -> Result<(), CameraError> {
        let forward = self.target - self.eye;
        if forward.length() <= 1e-12 {
            return Err(CameraError::EyeAtTarget);
        }
        if forward.cross(self.up).length() <= 1e-12 * forward.length() * self.up.length() {
            return Err(CameraError::Up);
        }
        if !(self.fov_degrees > 0.0 && self.fov_degrees < 180.0) {
            return Err(CameraError::FieldOfView(self.fov_degrees));
        }
        Ok(())
    }

    /// A camera that frames the whole bounding box `[lo, hi]` from the front
    /// (+z side), a little above, for scenes that bring no camera.
    #[must_use]
    pub fn framing(lo: DVec3, hi: DVec3) -> Camera {
        let centre = 0.5 * (lo + hi);
        let radius = 0.5 * (hi - lo).length().max(1e-6);
        let fov_degrees: f64 = 45.0;
        let distance = radius / (0.5 * fov_degrees.to_radians()).sin();
        let direction = DVec3::new(0.35, 0.3, 1.0).normalize();
        Camera {
            eye: centre + direction * distance,
            target: centre,
            up: DVec3::Y,
            fov_degrees,
        }
    }
}

/// Why a camera ([`Camera::parse`], [`Camera::validate`]) defines no view.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CameraError {
    /// A token that is no number (quoted as given).
    #[error("{0} is not a number")]
    NotANumber(String),
    /// An infinite or NaN number (quoted as given).
    #[error("{0} is not a finite number")]
    NotFinite(String),
    /// Not ten numbers.
    #[error(
        "a camera needs 10 numbers (eye x,y,z, target x,y,z, up x,y,z, fov in degrees), found {0}"
    )]
    Count(usize),
    /// Eye and target coincide.
    #[error("the camera's eye and target coincide")]
    EyeAtTarget,
    /// No usable up direction.
    #[error("the camera's up direction is zero or along the view direction")]
    Up,
    /// A field of view outside (0, 180) degrees.
    #[error("field of view {0} degrees is not between 0 and 180")]
    FieldOfView(f64),
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

/// Where in the input a problem is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Location {
    /// The file (or built-in scene path).
    pub path: PathBuf,
    /// 1-based line, where the problem is on one line.
    pub line: Option<usize>,
}

impl Location {
    /// A whole file.
    #[must_use]
    pub fn file(path: &Path) -> Location {
        Location {
            path: path.to_path_buf(),
            line: None,
        }
    }

    /// One line of a file.
    #[must_use]
    pub fn line(path: &Path, line: usize) -> Location {
        Location {
            path: path.to_path_buf(),
            line: Some(line),
        }
    }
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(line) => write!(f, "{}:{}", self.path.display(), line),
            None => write!(f, "{}", self.path.display()),
        }
    }
}

/// Why a scene could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read.
    #[error("{location}: {source}")]
    Io {
        /// The file.
        location: Location,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// The file was read but its content is wrong.
    #[error("{location}: {message}")]
    Invalid {
        /// The file and line.
        location: Location,
        /// What is wrong, in words a user can act on.
        message: String,
    },
    /// The name is neither a file nor a built-in scene.
    #[error("'{0}' is neither a file nor a built-in scene (built-in scenes: {names})", names = builtin::names().join(", "))]
    NotFound(String),
}

/// Bounds on what a scene may hold, so that no input can make a load run
/// for hours or exhaust memory. Each default is generous for real scenes
/// (the conference room of `../shared/scenes`: 277k triangles, 155k
/// vertices, a 10 MB OBJ) and each error names the option that raises it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Largest input file (OBJ or MTL), bytes; `--max-file-size` (MiB).
    pub max_file_bytes: u64,
    /// Longest line, bytes (continuation lines joined);
    /// `--max-line-length`.
    pub max_line_bytes: usize,
    /// Most corners of one face; `--max-corners`.
    pub max_corners: usize,
    /// Most faces (`f` statements; glTF triangles, counted once per node
    /// that instances their mesh); `--max-faces`.
    pub max_faces: usize,
    /// Most vertices (`v` statements); `--max-vertices`.
    pub max_vertices: usize,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_file_bytes: 1 << 30,
            max_line_bytes: 4 << 20,
            max_corners: 100_000,
            max_faces: 5_000_000,
            max_vertices: 10_000_000,
        }
    }
}

/// Default `--reflectance-cap`: glTF base colours of 1 (white) are common,
/// and a closed scene with a reflectance of 1 never converges.
pub const DEFAULT_REFLECTANCE_CAP: f64 = 0.9;

/// How glTF materials map to radiosity (OBJ's `Kd` and `Ke` are already
/// reflectance and exitance, so these do not apply to it).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoadOptions {
    /// Bounds on what the input may hold.
    pub limits: Limits,
    /// Largest reflectance per channel; higher values are clamped with a
    /// warning (`--reflectance-cap`).
    pub reflectance_cap: f64,
    /// Exitance in W/m^2 is `pi x emission_scale x emissive x strength`
    /// (`--emission-scale`).
    pub emission_scale: f64,
    /// A sun and sky to add to any scene (`--sun`, `--sky`).
    pub daylight: sky::Daylight,
}

impl Default for LoadOptions {
    fn default() -> LoadOptions {
        LoadOptions {
            limits: Limits::default(),
            reflectance_cap: DEFAULT_REFLECTANCE_CAP,
            emission_scale: 1.0,
            daylight: sky::Daylight::default(),
        }
    }
}

/// Reads an input file whole, after checking that it is a regular file (not
/// a folder, device or pipe, which could be endless) no larger than
/// `limits.max_file_bytes`.
pub fn read_input(path: &Path, limits: &Limits) -> Result<Vec<u8>, SceneError> {
    use std::io::Read;
    let io = |source: std::io::Error| SceneError::Io {
        location: Location::file(path),
        source,
    };
    let invalid = |message: String| SceneError::Invalid {
        location: Location::file(path),
        message,
    };
    let metadata = std::fs::metadata(path).map_err(io)?;
    if metadata.is_dir() {
        return Err(invalid("this is a folder, not a file".into()));
    }
    if !metadata.is_file() {
        return Err(invalid(
            "this is not a regular file (a device, pipe or socket can be endless): give a file"
                .into(),
        ));
    }
    let too_large = |bytes: u64| {
        invalid(format!(
            "the file is {bytes} bytes, more than the limit of {} MiB (raise it with \
             --max-file-size)",
            limits.max_file_bytes >> 20
        ))
    };
    if metadata.len() > limits.max_file_bytes {
        return Err(too_large(metadata.len()));
    }
    let mut bytes = Vec::with_capacity(metadata.len() as usize);
    // `take` guards against a file that grows while it is read.
    std::fs::File::open(path)
        .map_err(io)?
        .take(limits.max_file_bytes + 1)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > limits.max_file_bytes {
        return Err(too_large(bytes.len() as u64));
    }
    Ok(bytes)
}

impl LoadOptions {
    /// Checks the options are usable.
    pub fn validate(&self) -> Result<(), LoadOptionsError> {
        if !(self.reflectance_cap > 0.0 && self.reflectance_cap < 1.0) {
            return Err(LoadOptionsError::ReflectanceCap(self.reflectance_cap));
        }
        if !(self.emission_scale.is_finite() && self.emission_scale > 0.0) {
            return Err(LoadOptionsError::EmissionScale(self.emission_scale));
        }
        self.daylight.lights().map_err(LoadOptionsError::Daylight)?;
        Ok(())
    }
}

/// Load options that cannot be used ([`LoadOptions::validate`]).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LoadOptionsError {
    /// A reflectance cap outside (0, 1).
    #[error("--reflectance-cap must be above 0 and below 1, not {0}")]
    ReflectanceCap(f64),
    /// An emission scale that is not a positive number.
    #[error("--emission-scale must be a positive number, not {0}")]
    EmissionScale(f64),
    /// A sun or sky out of range (the message names the flag).
    #[error("{0}")]
    Daylight(String),
}

/// A loaded scene and, for glTF input, what the irradiance bake needs to
/// keep the original materials.
#[derive(Clone, Debug)]
pub struct Loaded {
    /// The surfaces, camera and hints.
    pub scene: Scene,
    /// Materials, textures and texture coordinates of a glTF input.
    pub appearance: Option<gltf::Appearance>,
}

/// True when the path names a glTF file (`.gltf` or `.glb`).
#[must_use]
pub fn is_gltf(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("gltf") || e.eq_ignore_ascii_case("glb"))
}

/// Loads a scene given on the command line: the name of a built-in scene,
/// or the path of an `.obj`, `.gltf` or `.glb` file, with default options.
pub fn load(name_or_path: &str) -> Result<Scene, SceneError> {
    load_with(name_or_path, &LoadOptions::default()).map(|l| l.scene)
}

/// [`load`] with options, keeping a glTF input's appearance: the scene
/// with the options' daylight added, refused if nothing lights it (no
/// emitting surface, no light, no daylight).
pub fn load_with(name_or_path: &str, options: &LoadOptions) -> Result<Loaded, SceneError> {
    let mut loaded = load_file_or_builtin(name_or_path, options)?;
    let scene = &mut loaded.scene;
    let path = Path::new(name_or_path);
    let daylight = options
        .daylight
        .lights()
        .map_err(|message| SceneError::Invalid {
            location: Location::file(path),
            message,
        })?;
    scene.lights.extend(daylight);
    // Whether the marked portals see the sky is checked where rays are
    // traced ([`crate::solver::sky::portals::check_scene`]).
    let has_sky = scene.lights.iter().any(|l| l.sky().is_some());
    if !scene.portals.is_empty() && !has_sky {
        scene.warnings.push(format!(
            "{}: {} portal face(s): portals serve the sky (--sky), and there is none",
            path.display(),
            scene.portals.len()
        ));
    }
    if !scene.panes.is_empty() {
        let mut materials: Vec<&str> = scene.panes.iter().map(|p| p.material.as_str()).collect();
        materials.dedup();
        materials.truncate(5);
        scene.warnings.push(format!(
            "{}: {} glass pane(s) ({}): they dim the light that crosses them by their \
             transmittance (the paper's presets and --shooting cuts dim only lights' and \
             daylight's)",
            path.display(),
            scene.panes.len(),
            materials.join(", ")
        ));
    }
    if scene.lights.is_empty() && !scene.surfaces.iter().any(Surface::is_emitter) {
        let emitters = if is_gltf(path) {
            "no material has an emissiveFactor > 0 and no node has a KHR_lights_punctual light"
        } else {
            "no face uses a material with Ke > 0 and there is no #@light directive"
        };
        return Err(SceneError::Invalid {
            location: Location::file(path),
            message: format!(
                "the scene has no emitter: {emitters}; give it an emitting surface, a light, or \
                 daylight (--sun, --sky)"
            ),
        });
    }
    Ok(loaded)
}

/// The scene as its file or the built-in scenes give it.
fn load_file_or_builtin(name_or_path: &str, options: &LoadOptions) -> Result<Loaded, SceneError> {
    let path = Path::new(name_or_path);
    let looks_like_path = path.extension().is_some() || path.components().count() > 1;
    if !looks_like_path && let Some(scene) = builtin::load(name_or_path) {
        return scene.map(|scene| Loaded {
            scene,
            appearance: None,
        });
    }
    if path.exists() {
        if is_gltf(path) {
            let (scene, appearance) = gltf::load_file(path, options)?;
            return Ok(Loaded {
                scene,
                appearance: Some(appearance),
            });
        }
        return obj::load_file_with(path, &options.limits).map(|scene| Loaded {
            scene,
            appearance: None,
        });
    }
    if looks_like_path {
        return Err(SceneError::Io {
            location: Location::file(path),
            source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
        });
    }
    Err(SceneError::NotFound(name_or_path.to_string()))
}
