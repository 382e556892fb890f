//! Shadow segments on the GPU: the any-hit query of
//! [`radiosity::accel::Occluder::occluded`] (design.md section 3, beyond
//! the paper) for many segments at once. The scene's convex surfaces are
//! cut into fans of triangles; the CPU's BVH build ([`FlatTree`], binned
//! SAH, the very tree the CPU walks before it is widened) is made over
//! their boxes; nodes and triangles, in leaf order, stay on the device; the
//! `occluded` kernel of `trace.wgsl` walks the tree, one thread a segment,
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
use radiosity::accel::bvh::{BvhSettings, FlatTree};
use radiosity::scene::Surface;
use wgpu::util::DeviceExt;

use crate::{Gpu, GpuError};

/// The most segments one dispatch traces.
pub const DISPATCH_SEGMENTS: usize = 1 << 18;

/// Threads of a workgroup (`@workgroup_size` in `trace.wgsl`).
const WORKGROUP: u32 = 64;

/// A BVH node as the kernel reads it (WGSL `Node`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuNode {
    /// Low corner.
    pub lo: [f32; 3],
    /// Interior: right child. Leaf: first triangle.
    pub link: u32,
    /// High corner.
    pub hi: [f32; 3],
    /// Interior: `FLAT_INTERIOR` | axis. Leaf: triangle count.
    pub kind: u32,
}

/// A triangle as the kernel reads it (WGSL `Triangle`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuTriangle {
    /// First corner.
    pub a: [f32; 3],
    /// Its surface id ([`Surface::group`]).
    pub group: u32,
    /// Second corner.
    pub b: [f32; 3],
    /// Padding.
    pub pad0: u32,
    /// Third corner.
    pub c: [f32; 3],
    /// Padding.
    pub pad1: u32,
    /// First corner's round-off: `a + a_lo` is the corner.
    pub a_lo: [f32; 3],
    /// Padding.
    pub pad2: u32,
    /// Second corner's round-off.
    pub b_lo: [f32; 3],
    /// Padding.
    pub pad3: u32,
    /// Third corner's round-off.
    pub c_lo: [f32; 3],
    /// Padding.
    pub pad4: u32,
    /// The surface's unit normal.
    pub normal: [f32; 3],
    /// Padding.
    pub pad5: u32,
}

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

/// A scene's triangles and their BVH on the device, in the kernels'
/// layouts: built and uploaded once a scene, and shared by the kernels of
/// every solve on the same [`Gpu`] (the coarse pass of receiver
/// refinement, the solve that goes on from it, the lights' segments).
pub(crate) struct DeviceScene {
    /// The scene's centre, the origin of the device's coordinates.
    pub(crate) origin: DVec3,
    /// The BVH's nodes.
    pub(crate) nodes: wgpu::Buffer,
    /// The triangles, in its leaves' order.
    pub(crate) triangles: wgpu::Buffer,
    /// How many triangles.
    pub(crate) count: usize,
    /// A hash of the triangles the scene was made of, and the origin.
    key: u64,
}

impl DeviceScene {
    /// `surfaces`' triangles and BVH on `gpu`: the scene `gpu` last held
    /// if it is the same, else built, uploaded and kept for the next solve.
    pub(crate) fn of(gpu: &Gpu, surfaces: &[Surface]) -> Arc<DeviceScene> {
        use std::hash::{Hash, Hasher};
        let (origin, scale) = centre_and_scale(surfaces);
        let triangles = triangles(surfaces, origin);
        let mut hasher = std::collections::hash_map::DefaultHasher::new();
        bytemuck::cast_slice::<GpuTriangle, u8>(&triangles).hash(&mut hasher);
        origin.to_array().map(f64::to_bits).hash(&mut hasher);
        let key = hasher.finish();
        let mut cache = gpu
            .scene
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some(scene) = cache.as_ref()
            && scene.key == key
            && scene.count == triangles.len()
        {
            return scene.clone();
        }
        // A few f32 round-offs of the scene's size: the slab test's error.
        let pad = 8.0 * f64::from(f32::EPSILON) * scale;
        let (nodes, ordered) = tree(&triangles, pad);
        // An empty buffer cannot be bound: one unused element instead.
        let scene = Arc::new(DeviceScene {
            origin,
            nodes: storage(gpu, "nodes", &nonempty(nodes)),
            triangles: storage(gpu, "triangles", &nonempty(ordered)),
            count: triangles.len(),
            key,
        });
        *cache = Some(scene.clone());
        scene
    }
}

/// Errors `gpu` reports outside an error scope (a lost device) from now
/// on, kept (the first) instead of wgpu's default, which panics.
pub(crate) fn catch_uncaptured(gpu: &Gpu) -> Arc<Mutex<Option<String>>> {
    let uncaptured = Arc::new(Mutex::new(None));
    let sink = uncaptured.clone();
    gpu.device
        .on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            if let Ok(mut slot) = sink.lock() {
                slot.get_or_insert_with(|| e.to_string());
            }
        }));
    uncaptured
}

/// `p - origin` as two `f32`s: the nearest, and what rounding it lost.
pub(crate) fn split(p: DVec3, origin: DVec3) -> ([f32; 3], [f32; 3]) {
    let r = p - origin;
    let hi = r.as_vec3();
    (hi.to_array(), (r - hi.as_dvec3()).as_vec3().to_array())
}

/// The triangles of `surfaces` (fans of each convex polygon) relative to
/// `origin`.
pub(crate) fn triangles(surfaces: &[Surface], origin: DVec3) -> Vec<GpuTriangle> {
    surfaces
        .iter()
        .flat_map(|s| {
            let p = &s.polygon;
            (1..p.len().saturating_sub(1)).map(move |i| {
                let (a, a_lo) = split(p[0], origin);
                let (b, b_lo) = split(p[i], origin);
                let (c, c_lo) = split(p[i + 1], origin);
                GpuTriangle {
                    a,
                    group: s.group,
                    b,
                    c,
                    a_lo,
                    b_lo,
                    c_lo,
                    normal: s.normal.as_vec3().to_array(),
                    ..GpuTriangle::default()
                }
            })
        })
        .collect()
}

/// The tree over `triangles` (boxes of their `f32` corners padded by
/// `pad`), its nodes for the kernel, and the triangles in leaf order.
pub(crate) fn tree(triangles: &[GpuTriangle], pad: f64) -> (Vec<GpuNode>, Vec<GpuTriangle>) {
    let boxes: Vec<(DVec3, DVec3)> = triangles
        .iter()
        .map(|t| {
            let corners = [t.a, t.b, t.c].map(|c| DVec3::from(c.map(f64::from)));
            let lo = corners[0].min(corners[1]).min(corners[2]);
            let hi = corners[0].max(corners[1]).max(corners[2]);
            (lo - DVec3::splat(pad), hi + DVec3::splat(pad))
        })
        .collect();
    let flat = FlatTree::build(&boxes, BvhSettings::sah());
    let nodes = flat
        .nodes
        .iter()
        .map(|n| GpuNode {
            lo: n.min,
            link: n.link,
            hi: n.max,
            kind: n.kind,
        })
        .collect();
    let ordered = flat
        .primitives
        .iter()
        .map(|&p| triangles[p as usize])
        .collect();
    (nodes, ordered)
}

/// The centre of the surfaces' box (the origin of the device's
/// coordinates) and its largest side.
pub(crate) fn centre_and_scale(surfaces: &[Surface]) -> (DVec3, f64) {
    let (lo, hi) = surfaces
        .iter()
        .flat_map(|s| s.polygon.iter())
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &p| {
            (lo.min(p), hi.max(p))
        });
    if lo.is_finite() && hi.is_finite() {
        (
            0.5 * (lo + hi),
            (hi - lo).max_element().max(f64::MIN_POSITIVE),
        )
    } else {
        (DVec3::ZERO, 1.0)
    }
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
        let module = gpu
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("trace.wgsl"),
                source: wgpu::ShaderSource::Wgsl(include_str!("trace.wgsl").into()),
            });
        let pipeline = gpu
            .device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("occluded"),
                layout: None,
                module: &module,
                entry_point: Some("occluded"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                cache: None,
            });
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
                    entry(0, &self.scene.nodes),
                    entry(1, &self.scene.triangles),
                    entry(2, &segment_buffer),
                    entry(3, &results),
                    entry(4, &uniform),
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

/// The first `bytes` of `readback`, once the device has done what was
/// submitted (the copy into it last); a device error on the way, or one
/// reported outside a scope (`uncaptured`), is the caller's.
pub(crate) fn read_back(
    gpu: &Gpu,
    readback: &wgpu::Buffer,
    bytes: u64,
    uncaptured: &Mutex<Option<String>>,
) -> Result<Vec<u8>, GpuError> {
    let slice = readback.slice(..bytes.max(4));
    let (sender, receiver) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = sender.send(r);
    });
    gpu.device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| gpu.failed(e))?;
    match receiver.recv() {
        Ok(Ok(())) => {}
        Ok(Err(e)) => return Err(gpu.failed(e)),
        Err(_) => return Err(gpu.failed("the readback was never mapped")),
    }
    if let Some(message) = uncaptured.lock().ok().and_then(|s| s.clone()) {
        return Err(gpu.failed(message));
    }
    let out = {
        let view = slice.get_mapped_range().map_err(|e| gpu.failed(e))?;
        view[..bytes as usize].to_vec()
    };
    readback.unmap();
    Ok(out)
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

/// `items`, or one zeroed element when there are none.
pub(crate) fn nonempty<T: Pod + Default>(mut items: Vec<T>) -> Vec<T> {
    if items.is_empty() {
        items.push(T::default());
    }
    items
}

/// A read-only storage buffer holding `items`.
pub(crate) fn storage<T: Pod>(gpu: &Gpu, label: &str, items: &[T]) -> wgpu::Buffer {
    gpu.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: bytemuck::cast_slice(items),
            usage: wgpu::BufferUsages::STORAGE,
        })
}

/// Binding `binding` of the kernel's group to all of `buffer`.
pub(crate) fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{DeviceChoice, REQUIRE_ADAPTER};

    /// A scene is built and uploaded once a device: the same surfaces
    /// give the very scene kept, other surfaces a new one (kept in its
    /// place), and a failure forgets it.
    #[test]
    fn a_scene_is_uploaded_once_a_device() {
        let gpu = match Gpu::open(DeviceChoice::Gpu) {
            Ok(Some(gpu)) => gpu,
            other => {
                let required = std::env::var(REQUIRE_ADAPTER).is_ok_and(|v| v != "0");
                assert!(!required, "{REQUIRE_ADAPTER} is set: {other:?}");
                eprintln!("GPU test did not run: no adapter");
                return;
            }
        };
        let room = radiosity::scene::load("room").unwrap();
        let cornell = radiosity::scene::load("cornell").unwrap();
        let first = DeviceScene::of(&gpu, &room.surfaces);
        assert!(Arc::ptr_eq(&first, &DeviceScene::of(&gpu, &room.surfaces)));
        // A clone of the device shares what it keeps.
        assert!(Arc::ptr_eq(
            &first,
            &DeviceScene::of(&gpu.clone(), &room.surfaces)
        ));
        let other = DeviceScene::of(&gpu, &cornell.surfaces);
        assert!(!Arc::ptr_eq(&first, &other));
        assert!(Arc::ptr_eq(
            &other,
            &DeviceScene::of(&gpu, &cornell.surfaces)
        ));
        let kept = DeviceScene::of(&gpu, &room.surfaces);
        assert!(!Arc::ptr_eq(&first, &kept));
        gpu.forget();
        let again = DeviceScene::of(&gpu, &room.surfaces);
        assert!(!Arc::ptr_eq(&kept, &again));
        assert_eq!(again.count, first.count);
    }
}
