//! Choosing and opening the device the GPU back end runs on, beyond the
//! paper (whose solver, Wallace et al. 1989 and Wong & Tsang 1993, ran on
//! the CPU alone), the way wgpu's own examples do it:
//! adapters are enumerated, never assumed; the one chosen is named in what
//! a run reports; limits are asked of the adapter. `auto` takes a real GPU
//! (discrete before integrated before virtual) and otherwise leaves the
//! work to the CPU; a software adapter such as Mesa's lavapipe, correct but
//! slower than the CPU path, only when asked for by `gpu`.

use std::fmt;
use std::sync::{Arc, Mutex};

use crate::kernel_cache::{CacheState, KernelCache};

/// Which device a run uses (`--device`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DeviceChoice {
    /// A real GPU, integrated or discrete, when there is one; else the CPU.
    #[default]
    Auto,
    /// The CPU, whatever adapters there are.
    Cpu,
    /// A GPU adapter, software ones included; an error when there is none.
    Gpu,
}

/// Why the GPU could not be used.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No adapter at all (or none but software ones, for `auto`).
    #[error(
        "no GPU adapter: wgpu found no Vulkan, Metal or DX12 device (on Linux, a Vulkan \
         driver: Mesa's mesa-vulkan-drivers has a software one, lavapipe)"
    )]
    NoAdapter,
    /// The adapter would not open a device.
    #[error("cannot open the GPU {adapter}: {message}")]
    Device {
        /// The adapter's name.
        adapter: String,
        /// What wgpu said.
        message: String,
    },
    /// A kernel or a transfer failed (a lost device, an out-of-memory).
    #[error("the GPU {adapter} failed: {message}")]
    Failed {
        /// The adapter's name.
        adapter: String,
        /// What wgpu said.
        message: String,
    },
}

/// An open device and its queue (a clone is another handle to the same
/// device).
#[derive(Clone)]
pub struct Gpu {
    /// The device kernels and buffers are made on.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
    /// The last scene uploaded, shared by the solves on this device
    /// ([`crate::device_scene::DeviceScene`]).
    pub(crate) scene: Arc<Mutex<Option<Arc<crate::device_scene::DeviceScene>>>>,
    /// The transfer kernels, compiled once for the solves on this device.
    pub(crate) pipelines: Arc<Mutex<Option<Arc<crate::gather::Pipelines>>>>,
    /// The compiled kernels kept across runs.
    pub(crate) kernels: Arc<KernelCache>,
}

impl fmt::Debug for Gpu {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Gpu")
            .field("adapter", &self.name())
            .finish()
    }
}

/// Preference among adapters: lower is better; `None` is never taken by
/// `auto`.
fn rank(kind: wgpu::DeviceType) -> Option<u8> {
    match kind {
        wgpu::DeviceType::DiscreteGpu => Some(0),
        wgpu::DeviceType::IntegratedGpu => Some(1),
        wgpu::DeviceType::VirtualGpu => Some(2),
        wgpu::DeviceType::Other => Some(3),
        wgpu::DeviceType::Cpu => None,
    }
}

impl Gpu {
    /// Opens the device `choice` asks for: `Ok(None)` for
    /// [`DeviceChoice::Cpu`], and for [`DeviceChoice::Auto`] when there is
    /// no hardware adapter; [`GpuError::NoAdapter`] for
    /// [`DeviceChoice::Gpu`] when there is none at all.
    ///
    /// # Errors
    ///
    /// No adapter for `gpu`, or an adapter that will not open a device.
    pub fn open(choice: DeviceChoice) -> Result<Option<Gpu>, GpuError> {
        if choice == DeviceChoice::Cpu {
            return Ok(None);
        }
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
        let mut ranked: Vec<(u8, usize, wgpu::Adapter)> = adapters
            .into_iter()
            .enumerate()
            .filter_map(|(i, adapter)| {
                let kind = adapter.get_info().device_type;
                match (rank(kind), choice) {
                    (Some(r), _) => Some((r, i, adapter)),
                    (None, DeviceChoice::Gpu) => Some((u8::MAX, i, adapter)),
                    (None, _) => None,
                }
            })
            .collect();
        ranked.sort_by_key(|&(r, i, _)| (r, i));
        let Some((_, _, adapter)) = ranked.into_iter().next() else {
            return match choice {
                DeviceChoice::Gpu => Err(GpuError::NoAdapter),
                _ => Ok(None),
            };
        };
        let info = adapter.get_info();
        let descriptor = wgpu::DeviceDescriptor {
            label: Some("radiosity"),
            // As much as the adapter allows: big scenes need big buffers.
            required_limits: adapter.limits(),
            // Timestamps, where the adapter has them: where a shot's time
            // goes (`--stats`' device_stage_seconds); a pipeline cache,
            // where it has one: the kernels kept across runs.
            required_features: adapter.features()
                & (wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::PIPELINE_CACHE),
            ..wgpu::DeviceDescriptor::default()
        };
        let (device, queue) =
            pollster::block_on(adapter.request_device(&descriptor)).map_err(|e| {
                GpuError::Device {
                    adapter: info.name.clone(),
                    message: e.to_string(),
                }
            })?;
        let kernels = Arc::new(KernelCache::open(&device, &info));
        Ok(Some(Gpu {
            device,
            queue,
            info,
            scene: Arc::default(),
            pipelines: Arc::default(),
            kernels,
        }))
    }

    /// Drops the scene and kernels kept for the next solve: after a
    /// failure while making them, the next solve makes its own.
    pub(crate) fn forget(&self) {
        *self
            .scene
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner) = None;
        *self
            .pipelines
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner) = None;
    }

    /// The adapter's name and backend, as runs report it:
    /// `NVIDIA H100 (Vulkan)`, `llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan,
    /// software)`.
    #[must_use]
    pub fn name(&self) -> String {
        let software = if self.is_software() { ", software" } else { "" };
        format!("{} ({:?}{software})", self.info.name, self.info.backend)
    }

    /// How this device's kernels were made ([`CacheState`]) and the time
    /// making them took so far.
    #[must_use]
    pub fn kernels(&self) -> (CacheState, std::time::Duration) {
        (self.kernels.state(), self.kernels.time())
    }

    /// Whether the adapter runs on the CPU (lavapipe, WARP, SwiftShader).
    #[must_use]
    pub fn is_software(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// A failure of this device, named.
    pub(crate) fn failed(&self, message: impl fmt::Display) -> GpuError {
        GpuError::Failed {
            adapter: self.info.name.clone(),
            message: message.to_string(),
        }
    }
}
