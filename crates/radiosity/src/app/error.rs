//! Why a render job failed: one variant per kind of bad input or failed
//! output, each message naming the file, flag or setting at fault.

use std::path::PathBuf;

use super::MAX_SAMPLES;
use crate::memory;
use crate::mesh::MeshError;
use crate::render;
use crate::scene::{CameraError, LoadOptionsError, SceneError};
use crate::solver::SettingsError;

/// Why a run failed.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The scene could not be loaded.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// The scene could not be meshed.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// A solver setting is out of range.
    #[error(transparent)]
    Settings(#[from] SettingsError),
    /// A load option is out of range.
    #[error(transparent)]
    Load(#[from] LoadOptionsError),
    /// The picture's camera defines no view.
    #[error("--camera: {0}")]
    Camera(CameraError),
    /// An output's file name has none of the extensions it may have.
    #[error("{flag} {path}: the file name must end in .{}", extensions.join(" or ."), path = path.display())]
    FileType {
        /// The flag that named the file.
        flag: &'static str,
        /// The file.
        path: PathBuf,
        /// The extensions it may have.
        extensions: &'static [&'static str],
    },
    /// A picture side outside 1 to [`render::MAX_SIDE`].
    #[error("{flag} must be between 1 and {}, not {side}", render::MAX_SIDE)]
    PictureSide {
        /// `--width` or `--height`.
        flag: &'static str,
        /// The side asked for.
        side: u32,
    },
    /// A picture of more than [`MAX_SAMPLES`] samples.
    #[error(
        "a {width}x{height} picture with {supersampling}x{supersampling} supersampling needs \
         {samples} samples, more than {MAX_SAMPLES}: lower --width, --height or --supersampling"
    )]
    TooManySamples {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
        /// Supersampling per axis.
        supersampling: u32,
        /// The samples it would take.
        samples: u64,
    },
    /// Supersampling outside 1 to 8.
    #[error("--supersampling must be between 1 and 8, not {0}")]
    Supersampling(u32),
    /// `--lightmap-density` out of range.
    #[error(
        "--lightmap-density must be a number of texels per metre above 0 and at most {max}, not {0}",
        max = crate::export::lightmap::MAX_DENSITY
    )]
    LightmapDensity(f64),
    /// `--lightmap-max-size` out of range.
    #[error(
        "--lightmap-max-size must be between 16 and {max} texels, not {0}",
        max = crate::export::lightmap::MAX_MAX_SIZE
    )]
    LightmapSize(u32),
    /// An input a lightmap bake cannot rewrite.
    #[error("{path}: --bake-target lightmap: {message}")]
    LightmapInput {
        /// The scene file.
        path: String,
        /// What stands in the way.
        message: String,
    },
    /// `--daylight-factor` where the scene is not lit by an overcast sky
    /// alone.
    #[error("--daylight-factor: {0}")]
    DaylightFactor(String),
    /// `--max-sensors 0`.
    #[error("--max-sensors must be at least 1")]
    NoSensors,
    /// Mesh sizes given in [`super::Job::settings`], where they are not read.
    #[error("a job's mesh sizes are its patch_size and element_size, not its settings' mesh sizes")]
    MeshSizesInSettings,
    /// The mesh would exceed `--max-elements`.
    #[error(
        "meshing would create {elements} elements, more than the limit of {limit}: {remedy}, or \
         raise --max-elements"
    )]
    MeshTooLarge {
        /// Elements the mesh would have.
        elements: u128,
        /// `--max-elements`.
        limit: usize,
        /// The size to change and where it came from.
        remedy: String,
    },
    /// The run would need more memory than it may use.
    #[error("{0}")]
    Memory(memory::TooLarge),
    /// The solve does not fit the device asked for (`--device gpu`).
    #[error("--device gpu: {0}")]
    Device(String),
    /// An output file could not be written.
    #[error("{path}: cannot write: {source}", path = path.display())]
    Output {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },
}
