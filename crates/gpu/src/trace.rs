//! Shadow segments on the GPU: the any-hit query of
//! [`radiosity::accel::Occluder::occluded`] (design.md section 3, beyond
//! the paper) for many segments at once. The scene's convex surfaces are
//! cut into fans of triangles; the CPU's BVH build ([`FlatTree`](radiosity::accel::bvh::FlatTree), binned
//! SAH, the very tree the CPU walks before it is widened) is made over
//! their boxes; nodes and triangles, in leaf order, stay on the device; the
//! `occluded` kernel (`trace/kernel.wgsl`, its walk in `trace/walk.wgsl`) walks the tree, one thread a segment,
//! with a watertight triangle test (Woop, Benthin & Wald 2013).
//!
//! Coordinates are relative to the scene's centre, each a pair of `f32`s
//! (the nearest and its round-off), so the kernel's differences of points,
//! where the triangle test starts, are as precise as `f32` allows relative
//! to the points' distance rather than the scene's size: a receiver a hair
//! off its surface stays on its side of a neighbour's plane. A segment's
//! answer can still differ from the CPU's `f64` test where it grazes a
//! surface (passes within about `f32` round-off of its length from an
//! edge, or ends that close to the surface's plane). The kernel keeps the
//! CPU's rules in its order: the ends strictly on either side of the
//! surface's plane (its `f64` normal, distances measured from a corner),
//! then the crossing inside the triangle, each half of the segment tested
//! from its own end so that a receiver a hair off its surface is resolved
//! relative to itself. Measured on lavapipe (`radiosity experiment rays
//! --quick --device gpu`): 1 of Sponza's 858,881 recorded segments and 3
//! of the conference room's 3,748,149 answered otherwise than by the CPU. The tree's boxes, of
//! the nearest `f32`s, are padded by a few round-offs of the scene's size,
//! so the walk itself never loses a triangle.
//!
//! Work is split into dispatches of at most [`DISPATCH_SEGMENTS`] segments
//! (none runs long enough to trip a driver's watchdog), and into uploads
//! that fit the adapter's largest storage binding.

use std::sync::{Arc, Mutex};

use bytemuck::{Pod, Zeroable};
use glam::DVec3;
use radiosity::scene::Surface;
use wgpu::util::DeviceExt;

use crate::device_scene::{DeviceScene, split};
pub use crate::device_scene::{GpuNode, GpuTriangle};
use crate::wgpu_io::{catch_uncaptured, entry, read_back, storage};
use crate::{Gpu, GpuError};

/// The most segments one dispatch traces.
pub const DISPATCH_SEGMENTS: usize = 1 << 18;

use crate::shaders::{TraceBinding as T, WORKGROUP};

/// A segment as the kernel reads it (WGSL `Segment`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuSegment {
    /// Start.
    pub p0: [f32; 3],
    /// A surface id not to test.
    pub skip0: u32,
    /// End.
    pub p1: [f32; 3],
    /// Another surface id not to test.
    pub skip1: u32,
    /// Start's round-off.
    pub p0_lo: [f32; 3],
    /// Padding.
    pub pad0: u32,
    /// End's round-off.
    pub p1_lo: [f32; 3],
    /// Padding.
    pub pad1: u32,
}

/// Which segments a dispatch traces (WGSL `Dispatch`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuDispatch {
    /// The first.
    pub first: u32,
    /// How many.
    pub count: u32,
    /// Padding.
    pub pad0: u32,
    /// Padding.
    pub pad1: u32,
}

pub use radiosity::solver::device::Segment;

/// The scene's triangles and their BVH on the device, ready to trace.
pub struct SceneTracer {
    gpu: Gpu,
    origin: DVec3,
    pipeline: wgpu::ComputePipeline,
    scene: Arc<DeviceScene>,
    triangle_count: usize,
    /// Errors wgpu reports outside a scope (a lost device), kept instead of
    /// panicking.
    uncaptured: Arc<Mutex<Option<String>>>,
    /// The device's own time tracing the last call's segments (seconds),
    /// where it has timestamps.
    traced: Mutex<Option<f64>>,
}

impl SceneTracer {
    /// Uploads `surfaces`' triangles and their BVH to `gpu`.
    ///
    /// # Errors
    ///
    /// When the device refuses the buffers or the kernel.
    pub fn new(gpu: &Gpu, surfaces: &[Surface]) -> Result<SceneTracer, GpuError> {
        let uncaptured = catch_uncaptured(gpu);
        let scope = gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let memory = gpu.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let made = std::time::Instant::now();
        let module = gpu
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("trace"),
                source: wgpu::ShaderSource::Wgsl(crate::shaders::trace_source().into()),
            });
        let pipeline = gpu
            .device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("occluded"),
                layout: None,
                module: &module,
                entry_point: Some("occluded"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                cache: gpu.kernels.get(),
            });
        gpu.kernels.made(made.elapsed());
        let scene = DeviceScene::of(gpu, surfaces);
        let out_of_memory = pollster::block_on(memory.pop());
        let invalid = pollster::block_on(scope.pop());
        if let Some(e) = out_of_memory.or(invalid) {
            gpu.forget();
            return Err(gpu.failed(e));
        }
        Ok(SceneTracer {
            gpu: gpu.clone(),
            origin: scene.origin,
            pipeline,
            triangle_count: scene.count,
            scene,
            uncaptured,
            traced: Mutex::new(None),
        })
    }

    /// The device's own time, by its timestamps, that the kernel took
    /// over the last [`SceneTracer::occluded`]'s segments (the upload and
    /// the readback left out), seconds; `None` where the device has no
    /// timestamps.
    #[must_use]
    pub fn traced_seconds(&self) -> Option<f64> {
        *self
            .traced
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// How many triangles the surfaces were cut into.
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.triangle_count
    }

    /// Whether each segment is blocked.
    ///
    /// # Errors
    ///
    /// When the device fails (lost, out of memory): the caller can go on
    /// on the CPU.
    pub fn occluded(&self, segments: &[Segment]) -> Result<Vec<bool>, GpuError> {
        let mut blocked = Vec::with_capacity(segments.len());
        if self.triangle_count == 0 || segments.is_empty() {
            blocked.resize(segments.len(), false);
            return Ok(blocked);
        }
        let limits = self.gpu.device.limits();
        let binding = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size) as usize;
        let per_upload = (binding / size_of::<GpuSegment>()).clamp(1, 16 * DISPATCH_SEGMENTS);
        let mut traced = Some(0.0);
        for chunk in segments.chunks(per_upload) {
            let (answers, seconds) = self.occluded_chunk(chunk)?;
            blocked.extend(answers);
            traced = traced.zip(seconds).map(|(a, b)| a + b);
        }
        *self
            .traced
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner) = traced;
        Ok(blocked)
    }

    /// [`SceneTracer::occluded`] for segments that fit one upload, and the
    /// kernel's time by the device's timestamps where it has them.
    fn occluded_chunk(&self, segments: &[Segment]) -> Result<(Vec<bool>, Option<f64>), GpuError> {
        let gpu = &self.gpu;
        let gpu_segments: Vec<GpuSegment> = segments
            .iter()
            .map(|s| {
                let (p0, p0_lo) = split(s.from, self.origin);
                let (p1, p1_lo) = split(s.to, self.origin);
                GpuSegment {
                    p0,
                    skip0: s.skip[0],
                    p1,
                    skip1: s.skip[1],
                    p0_lo,
                    p1_lo,
                    ..GpuSegment::default()
                }
            })
            .collect();
        let scope = gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let memory = gpu.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let segment_buffer = storage(gpu, "segments", &gpu_segments);
        let bytes = (4 * segments.len()) as u64;
        let results = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("blocked"),
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        // Two timestamps, before the first dispatch and after the last,
        // read back after the answers.
        let timed = gpu
            .device
            .features()
            .contains(wgpu::Features::TIMESTAMP_QUERY);
        let stamps = timed.then(|| {
            (
                gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                    label: Some("occluded timestamps"),
                    ty: wgpu::QueryType::Timestamp,
                    count: 2,
                }),
                gpu.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("occluded timestamps"),
                    size: 16,
                    usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                }),
            )
        });
        let readback = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("blocked readback"),
            size: bytes + 16,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let dispatches = segments.len().div_ceil(DISPATCH_SEGMENTS);
        let layout = self.pipeline.get_bind_group_layout(0);
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("occluded"),
            });
        for (k, first) in (0..segments.len()).step_by(DISPATCH_SEGMENTS).enumerate() {
            let count = DISPATCH_SEGMENTS.min(segments.len() - first);
            let dispatch = GpuDispatch {
                first: first as u32,
                count: count as u32,
                ..GpuDispatch::default()
            };
            let uniform = gpu
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("dispatch"),
                    contents: bytemuck::bytes_of(&dispatch),
                    usage: wgpu::BufferUsages::UNIFORM,
                });
            let group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("occluded"),
                layout: &layout,
                entries: &[
                    entry(T::Nodes, &self.scene.nodes),
                    entry(T::Triangles, &self.scene.triangles),
                    entry(T::Segments, &segment_buffer),
                    entry(T::Blocked, &results),
                    entry(T::Dispatch, &uniform),
                ],
            });
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("occluded"),
                // A pass between the first and the last writes none (a
                // pass's writes name at least one timestamp).
                timestamp_writes: stamps
                    .as_ref()
                    .filter(|_| k == 0 || k + 1 == dispatches)
                    .map(|(set, _)| wgpu::ComputePassTimestampWrites {
                        query_set: set,
                        beginning_of_pass_write_index: (k == 0).then_some(0),
                        end_of_pass_write_index: (k + 1 == dispatches).then_some(1),
                    }),
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.dispatch_workgroups((count as u32).div_ceil(WORKGROUP), 1, 1);
        }
        encoder.copy_buffer_to_buffer(&results, 0, &readback, 0, bytes);
        let mut read = bytes;
        if let Some((set, resolve)) = &stamps {
            encoder.resolve_query_set(set, 0..2, resolve, 0);
            encoder.copy_buffer_to_buffer(resolve, 0, &readback, bytes, 16);
            read += 16;
        }
        gpu.queue.submit([encoder.finish()]);
        let out_of_memory = pollster::block_on(memory.pop());
        let invalid = pollster::block_on(scope.pop());
        if let Some(e) = out_of_memory.or(invalid) {
            return Err(gpu.failed(e));
        }
        let data = read_back(gpu, &readback, read, &self.uncaptured)?;
        let words: &[u32] = bytemuck::cast_slice(&data[..bytes as usize]);
        let seconds = stamps.map(|_| {
            let tick = |k: usize| {
                let at = bytes as usize + 8 * k;
                u64::from_le_bytes(data[at..at + 8].try_into().unwrap_or_default())
            };
            tick(1).saturating_sub(tick(0)) as f64
                * f64::from(gpu.queue.get_timestamp_period())
                * 1e-9
        });
        Ok((words.iter().map(|&w| w != 0).collect(), seconds))
    }
}

/// The lights' shadow segments of a solve on the GPU
/// ([`radiosity::solver::device::Segments`]).
impl radiosity::solver::device::Segments for SceneTracer {
    fn occluded(
        &self,
        segments: &[Segment],
    ) -> Result<Vec<bool>, radiosity::solver::device::DeviceError> {
        SceneTracer::occluded(self, segments)
            .map_err(|e| radiosity::solver::device::DeviceError(e.to_string()))
    }
}

/// Whether the CPU's answer (`occluder`'s) for `segment` changes when its
/// ends move by `distance` along any of the axes: the segment grazes a
/// surface, and an answer in `f32` may differ from the CPU's in `f64`
/// there. The test every difference between the back ends must pass.
#[must_use]
pub fn grazes(occluder: &dyn radiosity::accel::Occluder, segment: &Segment, distance: f64) -> bool {
    let answer = occluder.occluded(segment.from, segment.to, segment.skip);
    let directions = [
        DVec3::X,
        DVec3::Y,
        DVec3::Z,
        DVec3::NEG_X,
        DVec3::NEG_Y,
        DVec3::NEG_Z,
    ];
    directions.iter().any(|&a| {
        directions.iter().any(|&b| {
            occluder.occluded(
                segment.from + distance * a,
                segment.to + distance * b,
                segment.skip,
            ) != answer
        })
    })
}
