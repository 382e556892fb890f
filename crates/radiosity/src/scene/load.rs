//! Loading a scene (design.md section 6): a built-in's name or a file
//! (OBJ with its MTL, glTF), read within [`Limits`] after checking it is a
//! regular file of a sane size, with the options of [`LoadOptions`]; every
//! error names the file and line ([`Location`], [`SceneError`]). The
//! loaded scene is checked for light and for portals without a sky. The
//! paper reads one room of patches; reading real files, bounded and with
//! clear errors, goes beyond it.

use std::fmt;
use std::path::{Path, PathBuf};

use super::{Scene, Surface, builtin, gltf, obj, sky};

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
