//! Which device a run takes (`--device`), decided by the back end: what
//! settings the GPU runs ([`refuses`]: the default method only, as the
//! kernels implement it; the paper's presets of Wallace, Elmquist & Haines
//! 1989 and Wong & Tsang 1993 stay on the CPU in `f64`, their experiments
//! reproducible), and how a choice opens a device ([`open`]): `auto` takes
//! a real GPU when the settings run on one and leaves the rest on the CPU,
//! with a warning when an adapter would not open; `gpu` takes any adapter,
//! software ones included, and is an error otherwise; `cpu` never opens
//! one. What happens when the opened device cannot hold a solve is the
//! device's own rule ([`radiosity::solver::device::Device::fit`]): a device
//! asked for by name is an error, one taken because it was there leaves
//! the solve to the CPU.

use std::sync::Arc;

use radiosity::accel::Accel;
use radiosity::form_factor::FormFactor;
use radiosity::solver::device::Device;
use radiosity::solver::{Settings, Shooting};

use crate::adapter::{DeviceChoice, Gpu, GpuError};
use crate::gather::GpuBackend;

/// The setting, as its flag, that keeps `settings` off the GPU, which runs
/// the default method only: adaptive shooting, BVH shadow rays, the
/// analytic factor.
#[must_use]
pub fn refuses(settings: &Settings) -> Option<String> {
    if settings.method.shooting() != Shooting::Adaptive {
        Some(format!("--shooting {}", settings.method.shooting()))
    } else if settings.accel != Accel::Bvh {
        Some(format!("--accel {}", settings.accel))
    } else if settings.form_factor != FormFactor::Analytic {
        Some(format!("--form-factor {}", settings.form_factor))
    } else {
        None
    }
}

/// How the GPU back end is set up once opened.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Options {
    /// `--max-gpu-memory`, bytes.
    pub max_memory: Option<u64>,
    /// Nodes of the element tree walked per receiver in one pass
    /// ([`GpuBackend::with_frontier`]); `None` takes the default.
    pub frontier: Option<u32>,
    /// Receivers per dispatch ([`GpuBackend::with_dispatch_receivers`]);
    /// `None` takes the default.
    pub dispatch_receivers: Option<usize>,
}

impl Options {
    /// `max_memory` with the two knobs for measuring the kernels
    /// (DEVELOPERS.md) from the environment: `RADIOSITY_GPU_FRONTIER` and
    /// `RADIOSITY_GPU_DISPATCH_RECEIVERS`.
    ///
    /// # Errors
    ///
    /// When one is set to something other than a whole number of at least 1.
    pub fn from_env(max_memory: Option<u64>) -> Result<Options, String> {
        let knob = |name: &str| -> Result<Option<u32>, String> {
            match std::env::var(name) {
                Ok(value) => match value.trim().parse::<u32>() {
                    Ok(n) if n >= 1 => Ok(Some(n)),
                    _ => Err(format!(
                        "{name}={value}: a whole number of at least 1 was expected"
                    )),
                },
                Err(_) => Ok(None),
            }
        };
        Ok(Options {
            max_memory,
            frontier: knob("RADIOSITY_GPU_FRONTIER")?,
            dispatch_receivers: knob("RADIOSITY_GPU_DISPATCH_RECEIVERS")?.map(|n| n as usize),
        })
    }

    fn backend(&self, gpu: Gpu) -> GpuBackend {
        let mut backend = GpuBackend::new(gpu).with_max_memory(self.max_memory);
        if let Some(nodes) = self.frontier {
            backend = backend.with_frontier(nodes);
        }
        if let Some(receivers) = self.dispatch_receivers {
            backend = backend.with_dispatch_receivers(receivers);
        }
        backend
    }
}

/// The device `choice` gives `settings`, opened, and a warning when `auto`
/// fell back to the CPU because an adapter would not open.
///
/// # Errors
///
/// `gpu` with settings the GPU does not run ([`refuses`]; the message
/// names the flag, and the preset when `preset` is not the default's), with
/// no adapter, or with one that will not open.
pub fn open(
    choice: DeviceChoice,
    settings: &Settings,
    preset: Option<&str>,
    options: &Options,
) -> Result<(Device, Option<String>), String> {
    match choice {
        DeviceChoice::Cpu => Ok((Device::cpu(), None)),
        DeviceChoice::Auto => {
            if refuses(settings).is_some() {
                return Ok((Device::cpu(), None));
            }
            match Gpu::open(choice) {
                Ok(Some(gpu)) => Ok((Device::preferred(Arc::new(options.backend(gpu))), None)),
                Ok(None) => Ok((Device::cpu(), None)),
                Err(e) => Ok((
                    Device::cpu(),
                    Some(format!("--device auto: {e}; the solve runs on the CPU")),
                )),
            }
        }
        DeviceChoice::Gpu => {
            if let Some(setting) = refuses(settings) {
                let setting = match preset {
                    Some(preset) => format!("the {preset} preset ({setting})"),
                    None => setting,
                };
                return Err(format!(
                    "--device gpu runs the default method (adaptive shooting, BVH shadow \
                     rays, the analytic factor), not {setting}: use --device cpu (the \
                     paper's presets run on the CPU, in f64)"
                ));
            }
            let gpu = Gpu::open(choice)
                .map_err(|e| format!("--device gpu: {e}"))?
                .ok_or_else(|| format!("--device gpu: {}", GpuError::NoAdapter))?;
            Ok((Device::backend(Arc::new(options.backend(gpu))), None))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use radiosity::solver::{MethodSettings, Preset};

    /// The default runs on the GPU, overshooting included; the paper's
    /// presets and the other accelerators and factors do not, and the
    /// refusal names the flag.
    #[test]
    fn the_gpu_runs_the_default_method_only() {
        for overshoot in [0.0, 1.0, 2.0] {
            let mut settings = Preset::Adaptive.settings();
            if let MethodSettings::Adaptive(a) = &mut settings.method {
                a.overshoot = overshoot;
            }
            assert_eq!(refuses(&settings), None, "overshoot {overshoot}");
        }
        assert_eq!(
            refuses(&Preset::WongTsang93.settings()).as_deref(),
            Some("--shooting patches")
        );
        let settings = Settings {
            accel: Accel::Bsp,
            ..Preset::Adaptive.settings()
        };
        assert_eq!(refuses(&settings).as_deref(), Some("--accel bsp"));
        let settings = Settings {
            form_factor: FormFactor::Wallace,
            ..Preset::Adaptive.settings()
        };
        assert!(refuses(&settings).unwrap().starts_with("--form-factor"));
    }

    /// `--device gpu` with the paper's preset is refused before any
    /// adapter is looked for, naming the preset; `cpu` opens nothing.
    #[test]
    fn a_refused_gpu_is_an_error_and_cpu_opens_nothing() {
        let options = Options::default();
        let error = open(
            DeviceChoice::Gpu,
            &Preset::Wallace89.settings(),
            Some("wallace89"),
            &options,
        )
        .unwrap_err();
        assert!(
            error.contains("the wallace89 preset (--shooting patches)"),
            "{error}"
        );
        let (device, warning) = open(
            DeviceChoice::Cpu,
            &Preset::Adaptive.settings(),
            None,
            &options,
        )
        .unwrap();
        assert!(device.get().is_none() && warning.is_none());
        let (device, _) = open(
            DeviceChoice::Auto,
            &Preset::WongTsang93.settings(),
            None,
            &options,
        )
        .unwrap();
        assert!(device.get().is_none());
    }
}
