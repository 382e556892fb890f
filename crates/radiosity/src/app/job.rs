//! A render job as a front end describes it ([`Job`]: the scene, the
//! settings, the outputs) and the checks made before any work: settings in
//! range, outputs of a known kind in folders that can be written to, a
//! picture that fits in memory; and the message for a mesh too large,
//! naming the size at fault and where it came from.

use std::path::{Path, PathBuf};

use super::Error;
use crate::export;
use crate::export::gltf::{BakeMode, BakeTarget};
use crate::export::lightmap::{self, AtlasSettings};
use crate::final_gather::FinalGather;
use crate::mesh::{MeshError, MeshSettings};
use crate::render::{self, Exposure};
use crate::scene::{Camera, LoadOptions, MeshHint};
use crate::solver::Settings;

/// A picture's size when none is given (`--width`, `--height`, the live
/// view's first frame), and the view the bake and the PLY take their
/// exposure from when no picture is written.
pub const DEFAULT_PICTURE: [u32; 2] = [800, 600];

/// What to draw and where.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageJob {
    /// `.png` (tone-mapped sRGB), `.pfm` or `.exr` (linear radiosity).
    pub path: PathBuf,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// The view; `None` takes the scene's camera or frames the scene.
    pub camera: Option<Camera>,
    /// Supersampling factor per axis.
    pub supersampling: u32,
    /// Brightness.
    pub exposure: Exposure,
    /// Add the ambient term for display.
    pub ambient: bool,
}

/// A whole run.
#[derive(Clone, Debug, PartialEq)]
pub struct Job {
    /// A built-in scene's name or an `.obj` path.
    pub scene: String,
    /// Solver settings, but for the mesh sizes: the two below give those
    /// ([`Job::settings_for`]), and a job whose settings hold sizes other
    /// than [`MeshSettings::default`]'s is refused ([`validate`]) rather
    /// than have them ignored.
    pub settings: Settings,
    /// `--patch-size`; `None` takes the scene's suggestion.
    pub patch_size: Option<f64>,
    /// `--element-size`; `None` takes the scene's suggestion.
    pub element_size: Option<f64>,
    /// What pictures, lightmap texels and sensors show (`--final-gather`;
    /// [`FinalGather::of_preset`] when not given).
    pub final_gather: FinalGather,
    /// The picture, if any.
    pub image: Option<ImageJob>,
    /// `--vertices FILE.csv`.
    pub vertices_csv: Option<PathBuf>,
    /// `--stats FILE.json`.
    pub stats_json: Option<PathBuf>,
    /// Bounds on the scene file (`--max-file-size`, `--max-corners`, ...)
    /// and how glTF materials map to reflectance and exitance.
    pub load: LoadOptions,
    /// `--bake FILE.glb|.gltf`.
    pub bake: Option<BakeJob>,
    /// `--ply FILE.ply`.
    pub ply: Option<PathBuf>,
    /// `--max-memory`: the memory the run may use, bytes; `None` takes what
    /// the machine has available ([`crate::memory::check`]).
    pub max_memory: Option<u64>,
    /// `--sensors POINTS.txt --sensors-out FILE.csv`.
    pub sensors: Option<SensorJob>,
}

impl Job {
    /// The settings of a run on a scene that suggests `suggested`:
    /// [`Job::settings`] with the mesh sizes of [`Job::patch_size`] and
    /// [`Job::element_size`], each defaulting to the suggestion. The one
    /// place a run's mesh sizes are decided.
    #[must_use]
    pub fn settings_for(&self, suggested: &MeshHint) -> Settings {
        let mut settings = self.settings.clone();
        settings.mesh.patch_size = self.patch_size.unwrap_or(suggested.patch_size);
        settings.mesh.element_size = self.element_size.unwrap_or(suggested.element_size);
        settings
    }
}

/// `--sensors`: values at the points of a Radiance `rtrace -I` points file
/// ([`crate::sensors`]).
#[derive(Clone, Debug, PartialEq)]
pub struct SensorJob {
    /// The points file.
    pub points: PathBuf,
    /// The CSV to write.
    pub out: PathBuf,
    /// Most points the file may hold (`--max-sensors`).
    pub max_points: usize,
    /// `--daylight-factor`: the CSV must have the `daylight_factor` column
    /// (an error when the scene is not lit by an overcast sky alone); it
    /// has it anyway when the scene is.
    pub daylight_factor: bool,
}

/// `--bake`: light baked into glTF, as vertex colours of the element mesh
/// or as a lightmap on the input's own meshes.
#[derive(Clone, Debug, PartialEq)]
pub struct BakeJob {
    /// `.glb`, or `.gltf` (written with a `.bin` beside it).
    pub path: PathBuf,
    /// What the baked values hold.
    pub mode: BakeMode,
    /// Vertex colours or lightmap.
    pub target: BakeTarget,
    /// The lightmap's density and size (`--lightmap-density`,
    /// `--lightmap-max-size`).
    pub lightmap: AtlasSettings,
}

impl BakeJob {
    /// A vertex bake to `path` in `mode`, lightmap settings at their
    /// defaults.
    #[must_use]
    pub fn vertices(path: PathBuf, mode: BakeMode) -> BakeJob {
        BakeJob {
            path,
            mode,
            target: BakeTarget::Vertices,
            lightmap: AtlasSettings::default(),
        }
    }
}

/// Most samples (pixels times supersampling) a picture may take: about
/// 2.5 GB of frame buffer.
pub const MAX_SAMPLES: u64 = 150_000_000;

/// Checks outputs before any work: known picture format, a folder that
/// exists and can be written to (a file is created there and removed).
pub(super) fn check_output(
    path: &Path,
    extensions: &'static [&'static str],
    flag: &'static str,
) -> Result<(), Error> {
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    if !extensions.contains(&extension.as_str()) {
        return Err(Error::FileType {
            flag,
            path: path.to_path_buf(),
            extensions,
        });
    }
    let folder = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let output_error = |source: std::io::Error| Error::Output {
        path: path.to_path_buf(),
        source,
    };
    if !folder.is_dir() {
        let problem = if folder.exists() {
            format!("{} is a file, not a folder", folder.display())
        } else {
            format!("folder {} does not exist", folder.display())
        };
        return Err(output_error(std::io::Error::new(
            std::io::ErrorKind::NotFound,
            problem,
        )));
    }
    export::probe_writable(path).map_err(output_error)
}

/// Validates a job's settings and outputs without doing any work.
pub fn validate(job: &Job) -> Result<(), Error> {
    job.settings.validate()?;
    let defaults = MeshSettings::default();
    if (job.settings.mesh.patch_size, job.settings.mesh.element_size)
        != (defaults.patch_size, defaults.element_size)
    {
        return Err(Error::MeshSizesInSettings);
    }
    job.load.validate()?;
    if let Some(bake) = &job.bake {
        check_output(&bake.path, &["glb", "gltf"], "--bake")?;
        let density = bake.lightmap.density;
        if !(density.is_finite() && density > 0.0 && density <= lightmap::MAX_DENSITY) {
            return Err(Error::LightmapDensity(density));
        }
        if !(16..=lightmap::MAX_MAX_SIZE).contains(&bake.lightmap.max_size) {
            return Err(Error::LightmapSize(bake.lightmap.max_size));
        }
    }
    if let Some(path) = &job.ply {
        check_output(path, &["ply"], "--ply")?;
    }
    if let Some(image) = &job.image {
        check_output(&image.path, &["png", "pfm", "exr"], "--output")?;
        for (flag, side) in [("--width", image.width), ("--height", image.height)] {
            if !(1..=render::MAX_SIDE).contains(&side) {
                return Err(Error::PictureSide { flag, side });
            }
        }
        let samples = u64::from(image.width)
            * u64::from(image.height)
            * u64::from(image.supersampling).pow(2);
        if samples > MAX_SAMPLES {
            return Err(Error::TooManySamples {
                width: image.width,
                height: image.height,
                supersampling: image.supersampling,
                samples,
            });
        }
        if !(1..=8).contains(&image.supersampling) {
            return Err(Error::Supersampling(image.supersampling));
        }
        if let Some(camera) = &image.camera {
            camera.validate().map_err(Error::Camera)?;
        }
    }
    if let Some(path) = &job.vertices_csv {
        check_output(path, &["csv"], "--vertices")?;
    }
    if let Some(path) = &job.stats_json {
        check_output(path, &["json"], "--stats")?;
    }
    if let Some(sensors) = &job.sensors {
        check_output(&sensors.out, &["csv"], "--sensors-out")?;
        if sensors.max_points == 0 {
            return Err(Error::NoSensors);
        }
    }
    Ok(())
}

/// A mesh that would be too large, explained with the size at fault and
/// where it came from: the flag the user gave, the scene's `#@mesh`
/// directive (file and line), or the default derived from the scene's
/// extent.
pub(super) fn mesh_error(
    error: MeshError,
    job: &Job,
    suggested: &MeshHint,
    settings: &Settings,
) -> Error {
    let MeshError::TooManyElements {
        elements,
        patches,
        limit,
        ..
    } = error
    else {
        return Error::Mesh(error);
    };
    // Patches alone beyond the limit: the patch size is at fault.
    let (what, flag, size, given, fraction) = if patches > limit as u128 {
        (
            "patch",
            "--patch-size",
            settings.mesh.patch_size,
            job.patch_size,
            3,
        )
    } else {
        (
            "element",
            "--element-size",
            settings.mesh.element_size,
            job.element_size,
            40,
        )
    };
    // 1e-9 rather than 0.000000001.
    let size = if size < 1e-3 {
        format!("{size:e}")
    } else {
        format!("{size}")
    };
    let remedy = if given.is_some() {
        format!("raise {flag} (now {size} m)")
    } else if let Some(directive) = &suggested.directive {
        format!(
            "raise the {what} size of the #@mesh directive at {directive} (now {size} m) or give \
             a larger {flag}"
        )
    } else {
        format!(
            "give a {flag} larger than {size} m (the default: 1/{fraction} of the scene's size)"
        )
    };
    Error::MeshTooLarge {
        elements,
        limit,
        remedy,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn job(patch_size: Option<f64>, element_size: Option<f64>) -> Job {
        Job {
            scene: "room".into(),
            settings: Settings::adaptive(),
            patch_size,
            element_size,
            final_gather: FinalGather::Direct,
            image: None,
            vertices_csv: None,
            stats_json: None,
            load: LoadOptions::default(),
            bake: None,
            ply: None,
            max_memory: None,
            sensors: None,
        }
    }

    #[test]
    fn mesh_sizes_come_from_the_job_else_the_scene() {
        let suggested = MeshHint {
            patch_size: 1.0,
            element_size: 0.1,
            directive: None,
        };
        let mesh = job(None, None).settings_for(&suggested).mesh;
        assert_eq!((mesh.patch_size, mesh.element_size), (1.0, 0.1));
        let mesh = job(Some(2.0), None).settings_for(&suggested).mesh;
        assert_eq!((mesh.patch_size, mesh.element_size), (2.0, 0.1));
        let mesh = job(None, Some(0.2)).settings_for(&suggested).mesh;
        assert_eq!((mesh.patch_size, mesh.element_size), (1.0, 0.2));
    }

    #[test]
    fn mesh_sizes_in_a_jobs_settings_are_refused_not_ignored() {
        assert!(validate(&job(None, None)).is_ok());
        let mut refused = job(None, None);
        refused.settings.mesh.element_size = 0.05;
        let message = validate(&refused).unwrap_err().to_string();
        assert!(message.contains("element_size"), "{message}");
    }
}
