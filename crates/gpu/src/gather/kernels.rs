//! The parts of a solve on the GPU that are not its state (adaptive
//! shooting, beyond the paper: the per-receiver source subdivision of
//! Wallace, Elmquist & Haines 1989, section 4): the transfer kernels'
//! pipelines, compiled once a device; the timestamps around a shot's
//! passes; the buffers a shot's uploads grow; and the small helpers that
//! make buffers and move vectors between the host's `f64` and the
//! device's `f32`.

use std::sync::Arc;
use std::time::Duration;

use glam::DVec3;
use radiosity::solver::device::StageTimes;

use crate::Gpu;

/// A buffer that grows to hold what a shot uploads.
pub(super) struct Growing {
    pub(super) label: &'static str,
    pub(super) buffer: wgpu::Buffer,
    pub(super) capacity: u64,
}

impl Growing {
    pub(super) fn new(gpu: &Gpu, label: &'static str) -> Growing {
        Growing {
            label,
            buffer: Growing::make(gpu, label, 256),
            capacity: 256,
        }
    }

    pub(super) fn make(gpu: &Gpu, label: &str, size: u64) -> wgpu::Buffer {
        gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    }

    /// Writes `bytes` at the start, growing the buffer first if need be
    /// (a new buffer: commands already submitted read the old one); true
    /// if it grew.
    pub(super) fn write(&mut self, gpu: &Gpu, bytes: &[u8]) -> bool {
        let size = (bytes.len() as u64).max(16).next_multiple_of(4);
        let grew = size > self.capacity;
        if grew {
            self.capacity = size.next_power_of_two();
            self.buffer = Growing::make(gpu, self.label, self.capacity);
        }
        gpu.queue.write_buffer(&self.buffer, 0, bytes);
        grew
    }
}

/// The kernels, one pipeline an entry point of one module.
pub(crate) struct Pipelines {
    pub(super) gather: wgpu::ComputePipeline,
    pub(super) size_items: wgpu::ComputePipeline,
    pub(super) gather_items: wgpu::ComputePipeline,
    pub(super) join_items: wgpu::ComputePipeline,
    pub(super) collect: wgpu::ComputePipeline,
    pub(super) gathered: wgpu::ComputePipeline,
    pub(super) leave_shooters: wgpu::ComputePipeline,
    pub(super) receive: wgpu::ComputePipeline,
    pub(super) accumulate: wgpu::ComputePipeline,
    pub(super) shooter_powers: wgpu::ComputePipeline,
    pub(super) large_shooter_powers: wgpu::ComputePipeline,
    pub(super) choose_next: wgpu::ComputePipeline,
    pub(super) collect_next: wgpu::ComputePipeline,
}

impl Pipelines {
    /// The kernels on `gpu`: compiled for its first solve, and kept for
    /// the next (the solve that goes on from a coarse pass).
    pub(super) fn on(gpu: &Gpu) -> Arc<Pipelines> {
        let mut kept = gpu
            .pipelines
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        kept.get_or_insert_with(|| Arc::new(Pipelines::new(gpu)))
            .clone()
    }

    pub(super) fn new(gpu: &Gpu) -> Pipelines {
        let made = std::time::Instant::now();
        let source = crate::shaders::gather_source();
        let module = gpu
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("gather"),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            });
        let pipeline = |entry: &str| {
            gpu.device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(entry),
                    layout: None,
                    module: &module,
                    entry_point: Some(entry),
                    compilation_options: wgpu::PipelineCompilationOptions::default(),
                    cache: gpu.kernels.get(),
                })
        };
        let pipelines = Pipelines {
            gather: pipeline("gather"),
            size_items: pipeline("size_items"),
            gather_items: pipeline("gather_items"),
            join_items: pipeline("join_items"),
            collect: pipeline("collect"),
            gathered: pipeline("gathered"),
            leave_shooters: pipeline("leave_shooters"),
            receive: pipeline("receive"),
            accumulate: pipeline("accumulate"),
            shooter_powers: pipeline("shooter_powers"),
            large_shooter_powers: pipeline("large_shooter_powers"),
            choose_next: pipeline("choose_next"),
            collect_next: pipeline("collect_next"),
        };
        gpu.kernels.made(made.elapsed());
        pipelines
    }
}

/// Which stage a timed pass belongs to ([`StageTimes`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Stage {
    Walk,
    Items,
    Join,
    Book,
}

/// The device's timestamps around each pass of a round, a begin and an
/// end a slot, slots given out in the order the passes are encoded.
pub(super) struct Timer {
    pub(super) set: wgpu::QuerySet,
    /// Where they are resolved, to be copied into the readback.
    pub(super) resolve: wgpu::Buffer,
    /// Nanoseconds a tick.
    pub(super) period: f64,
    /// The stage of each slot given out this round.
    pub(super) slots: Vec<Stage>,
    /// Passes this round found no slot for (its stages are then unknown).
    pub(super) missed: bool,
}

impl Timer {
    /// Passes a round can time: as many as a query set holds.
    pub(super) const SLOTS: u32 = wgpu::QUERY_SET_MAX_QUERIES / 2;

    /// Timestamps around the passes of a round on `gpu`: `None` where the
    /// device has none.
    pub(super) fn on(gpu: &Gpu) -> Option<Timer> {
        let count = 2 * Timer::SLOTS;
        if !gpu
            .device
            .features()
            .contains(wgpu::Features::TIMESTAMP_QUERY)
        {
            return None;
        }
        Some(Timer {
            set: gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("round timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count,
            }),
            resolve: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("round timestamps"),
                size: 8 * u64::from(count),
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            period: f64::from(gpu.queue.get_timestamp_period()),
            slots: Vec::new(),
            missed: false,
        })
    }

    /// A slot for a pass of `stage`, its begin and end query; `None` when
    /// the round has used them all.
    pub(super) fn slot(&mut self, stage: Stage) -> Option<u32> {
        let index = self.slots.len() as u32;
        if index >= Timer::SLOTS {
            self.missed = true;
            return None;
        }
        self.slots.push(stage);
        Some(index)
    }

    /// The stages' time from the round's timestamps read back (`bytes`, a
    /// begin and an end a slot); `None` when some pass went untimed. The
    /// slots are given out afresh for the next round.
    pub(super) fn stages(&mut self, bytes: &[u8]) -> Option<StageTimes> {
        let tick = |k: usize| {
            bytes
                .get(8 * k..8 * k + 8)
                .map_or(0, |b| u64::from_le_bytes(b.try_into().unwrap_or_default()))
        };
        let mut stages = StageTimes::default();
        for (i, stage) in self.slots.iter().enumerate() {
            let ticks = tick(2 * i + 1).saturating_sub(tick(2 * i));
            let time = Duration::from_nanos((ticks as f64 * self.period) as u64);
            let slot = match stage {
                Stage::Walk => &mut stages.walk,
                Stage::Items => &mut stages.items,
                Stage::Join => &mut stages.join,
                Stage::Book => &mut stages.book,
            };
            *slot += time;
        }
        self.slots.clear();
        let known = !std::mem::take(&mut self.missed);
        known.then_some(stages)
    }
}

/// Bytes of the split walks of one chunk of `dispatch_receivers` (of
/// `receivers`): a header a receiver and at most `frontier` items each.
pub(super) fn split_bytes(receivers: usize, dispatch_receivers: usize, frontier: u32) -> u64 {
    let chunk = receivers.min(dispatch_receivers).max(1) as u64;
    16 * chunk * (1 + u64::from(frontier))
}

/// A buffer the kernels read and write, and copies go in and out of.
pub(super) fn state_buffer(gpu: &Gpu, label: &str, bytes: u64) -> wgpu::Buffer {
    gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes.max(16),
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// `v` as the device keeps it.
pub(super) fn vec4(v: DVec3) -> [f32; 4] {
    let v = v.as_vec3();
    [v.x, v.y, v.z, 0.0]
}

/// A device `vec4` read back.
pub(super) fn dvec3(v: &[f32]) -> DVec3 {
    DVec3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2]))
}
