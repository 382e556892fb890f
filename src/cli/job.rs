//! The second stage of the command line: flags checked and turned into a
//! [`Job`] for [`radiosity::app::run`].

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Result, anyhow};

use super::args::{OnOff, RenderArgs};
use radiosity::app::{BakeJob, ImageJob, Job, SensorJob};
use radiosity::export::lightmap::AtlasSettings;
use radiosity::final_gather::FinalGather;
use radiosity::mesh::MAX_REFINE_LEVELS;
use radiosity::render::Exposure;
use radiosity::scene::{Camera, Limits};
use radiosity::sensors;
use radiosity::solver::Preset;
use radiosity_gpu::policy;

impl RenderArgs {
    /// The validated job (second stage after clap's raw values), with
    /// warnings about flags it does not use.
    pub fn job(&self) -> Result<(Job, Vec<String>)> {
        let mut warnings = Vec::new();
        let mut settings = self.preset.settings();
        if let Some(shooting) = self.shooting {
            settings.switch_method(shooting)?;
        }
        warnings.extend(settings.set_parameters(&self.method.given)?);
        if let Some(switch) = self.merge_coplanar {
            settings.merge_coplanar = switch == OnOff::On;
        }
        if let Some(form_factor) = self.form_factor {
            settings.form_factor = form_factor;
        }
        if let Some(accel) = self.accel {
            settings.accel = accel;
        }
        if let Some(converge) = self.converge {
            settings.converge = converge;
        }
        if let Some(levels) = self.refine_levels {
            if levels > MAX_REFINE_LEVELS {
                return Err(anyhow!(
                    "--refine-levels must be at most {MAX_REFINE_LEVELS} (each level can \
                     multiply an element by four), not {levels}"
                ));
            }
            settings.mesh.refine.refine_levels = levels;
        }
        if let Some(tolerance) = self.refine_tolerance {
            settings.mesh.refine.refine_tolerance = tolerance;
        }
        if let Some(n) = self.max_elements {
            settings.mesh.max_elements = n;
        }
        let defaults = Limits::default();
        let limits = Limits {
            max_file_bytes: self
                .max_file_size
                .map_or(defaults.max_file_bytes, |mib| mib.saturating_mul(1 << 20)),
            max_line_bytes: self.max_line_length.unwrap_or(defaults.max_line_bytes),
            max_corners: self.max_corners.unwrap_or(defaults.max_corners),
            max_faces: self.max_faces.unwrap_or(defaults.max_faces),
            max_vertices: self.max_vertices.unwrap_or(defaults.max_vertices),
        };
        let options = policy::Options::from_env(self.max_gpu_memory).map_err(|e| anyhow!(e))?;
        let preset = (self.preset != Preset::Adaptive).then(|| self.preset.name());
        let (device, warning) = policy::open(self.device.into(), &settings, preset, &options)
            .map_err(|e| anyhow!(e))?;
        warnings.extend(warning);
        settings.device = device;
        settings.max_shots = self.max_shots;
        settings.max_subsources = self.max_subsources;
        if let Some(seconds) = self.time_limit {
            if !(seconds.is_finite() && seconds > 0.0 && seconds <= 1e9) {
                return Err(anyhow!(
                    "--time-limit must be a positive number of seconds, not {seconds}"
                ));
            }
            settings.time_limit = Some(Duration::from_secs_f64(seconds));
        }
        let camera = self
            .camera
            .as_deref()
            .map(Camera::parse)
            .transpose()
            .map_err(|m| anyhow!("--camera: {m}"))?;
        if !self.exposure.is_finite() {
            return Err(anyhow!("--exposure must be a finite number of stops"));
        }
        let stem = std::path::Path::new(&self.scene)
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "render".into());
        let job = Job {
            scene: self.scene.clone(),
            settings,
            patch_size: self.patch_size,
            element_size: self.element_size,
            final_gather: self
                .final_gather
                .unwrap_or(FinalGather::of_preset(self.preset)),
            image: Some(ImageJob {
                path: self
                    .output
                    .clone()
                    .unwrap_or_else(|| PathBuf::from(format!("{stem}.png"))),
                width: self.width,
                height: self.height,
                camera,
                supersampling: self.supersampling,
                exposure: Exposure::Auto { ev: self.exposure },
                ambient: !self.no_ambient,
            }),
            vertices_csv: self.vertices.clone(),
            stats_json: self.stats.clone(),
            load: self.load.options(limits),
            bake: self.bake.clone().map(|path| BakeJob {
                path,
                mode: self.bake_mode,
                target: self.bake_target,
                lightmap: AtlasSettings {
                    density: self.lightmap_density,
                    max_size: self.lightmap_max_size,
                    ..AtlasSettings::default()
                },
            }),
            ply: self.ply.clone(),
            sensors: match (&self.sensors, &self.sensors_out) {
                (Some(points), Some(out)) => Some(SensorJob {
                    points: points.clone(),
                    out: out.clone(),
                    max_points: self.max_sensors.unwrap_or(sensors::DEFAULT_MAX_SENSORS),
                    daylight_factor: self.daylight_factor,
                }),
                _ => None,
            },
            max_memory: self.max_memory,
        };
        Ok((job, warnings))
    }
}
