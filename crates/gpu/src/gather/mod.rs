//! Adaptive shooting's transfers on the GPU (beyond the paper: the
//! per-receiver source subdivision of Wallace, Elmquist & Haines 1989,
//! section 4, with the analytic factor of the paper's equation (2) at the
//! elements, as the CPU's `radiosity::solver::adaptive` does it): one
//! thread a receiver walks the shooting node's subtree with the CPU's
//! acceptance rules, its shadow rays answered by the `trace.wgsl` walk of
//! the scene's BVH in the same kernel (`gather.wgsl`).
//!
//! What is the same for a whole solve goes to the device once: the scene's
//! triangles and BVH, the element tree, the elements (corners, centroid,
//! area), the surfaces' planes and the receivers in the receiver tree's
//! order (neighbours in one workgroup walk alike). Each shot uploads its
//! subtree's sources (power in bins by normal, with their centres and
//! covariances worked out in `f64` on the host, so the kernel never
//! subtracts large sums) and each receiver's negligible irradiance, and
//! reads back each receiver's irradiance and counts. The loop, the choice
//! of shooter and the book-keeping stay on the host, shared with the CPU.
//!
//! Points are two `f32`s relative to the scene's centre, and the kernel
//! works with differences taken from the receiver (or the shot's centre),
//! so it is as precise as `f32` allows relative to the distances involved:
//! the gathering nudge of a receiver a micrometre off its surface keeps
//! its side of a neighbour's plane.

use std::sync::{Arc, Mutex};
use std::time::Instant;

use glam::{DMat3, DVec3};
use radiosity::solver::device::{
    AdaptiveShot, AdaptiveSolve, AdaptiveTransfers, Backend, DeviceError, Gathered,
};
use radiosity::solver::hierarchy::sources::outer;
use radiosity::solver::hierarchy::{NONE, Tree};
use wgpu::util::DeviceExt;

mod buffers;
mod memory;

pub use self::buffers::{
    GpuBin, GpuElement, GpuGathered, GpuNodeSource, GpuReceiver, GpuShot, GpuSurface, GpuTreeNode,
};
pub use self::memory::DeviceMemory;
use crate::Gpu;
use crate::trace::{self, entry, nonempty, split, storage};

/// Receivers one dispatch (and one submission) gathers for: small enough
/// that no dispatch runs long enough to trip a driver's watchdog on a
/// large shooter, and the shot can be abandoned between them.
pub const DISPATCH_RECEIVERS: usize = 1 << 15;

/// Threads of a workgroup (`@workgroup_size` in `gather.wgsl`).
const WORKGROUP: u32 = 64;

/// The deepest element tree the kernel's walk stack holds
/// (`WALK_STACK` in `gather.wgsl`, less the two a visit pushes).
const MAX_TREE_DEPTH: usize = 62;

/// Storage buffers the kernel binds at once.
const STORAGE_BUFFERS: u32 = 10;

/// The GPU as a device for the solver's transfers.
#[derive(Clone)]
pub struct GpuBackend {
    gpu: Arc<Gpu>,
    /// The most device memory a solve may take (`--max-gpu-memory`).
    max_memory: Option<u64>,
}

impl GpuBackend {
    /// The back end on `gpu`.
    #[must_use]
    pub fn new(gpu: Gpu) -> GpuBackend {
        GpuBackend {
            gpu: Arc::new(gpu),
            max_memory: None,
        }
    }

    /// The same, taking at most `bytes` of device memory a solve.
    #[must_use]
    pub fn with_max_memory(mut self, bytes: Option<u64>) -> GpuBackend {
        self.max_memory = bytes;
        self
    }

    /// The device.
    #[must_use]
    pub fn gpu(&self) -> &Gpu {
        &self.gpu
    }
}

impl Backend for GpuBackend {
    fn name(&self) -> String {
        self.gpu.name()
    }

    /// [`DeviceMemory::of`] against the adapter's largest buffer and
    /// `--max-gpu-memory`.
    fn check(
        &self,
        scene: &radiosity::scene::Scene,
        mesh: &radiosity::mesh::Mesh,
        receivers: usize,
    ) -> Result<u64, DeviceError> {
        let memory = DeviceMemory::of(scene, mesh, receivers);
        let limits = self.gpu.device.limits();
        let largest = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        if let Some(&(name, bytes)) = memory.buffers.first()
            && bytes > largest
        {
            return Err(DeviceError(format!(
                "the solve's {name} take {} in one buffer, more than the largest the GPU {} \
                 binds ({}): coarsen the mesh (--element-size) or use --device cpu",
                radiosity::memory::bytes(bytes),
                self.gpu.name(),
                radiosity::memory::bytes(largest)
            )));
        }
        let total = memory.total();
        if let Some(cap) = self.max_memory
            && total > cap
        {
            return Err(DeviceError(format!(
                "the solve would take about {} of GPU memory, over --max-gpu-memory {}",
                radiosity::memory::bytes(total),
                radiosity::memory::bytes(cap)
            )));
        }
        Ok(total)
    }

    fn adaptive(
        &self,
        solve: &AdaptiveSolve<'_>,
    ) -> Result<Box<dyn AdaptiveTransfers>, DeviceError> {
        Ok(Box::new(GpuTransfers::new(self.gpu.clone(), solve)?))
    }
}

/// The depth of a tree (a lone root is 1).
fn depth(tree: &Tree) -> usize {
    let mut deepest = 0;
    let mut stack = if tree.nodes.is_empty() {
        Vec::new()
    } else {
        vec![(0u32, 1usize)]
    };
    while let Some((n, d)) = stack.pop() {
        deepest = deepest.max(d);
        let node = &tree.nodes[n as usize];
        if !node.is_leaf() {
            stack.push((n + 1, d + 1));
            stack.push((node.second, d + 1));
        }
    }
    deepest
}

/// A buffer that grows to hold what a shot uploads.
struct Growing {
    label: &'static str,
    buffer: wgpu::Buffer,
    capacity: u64,
}

impl Growing {
    fn new(gpu: &Gpu, label: &'static str) -> Growing {
        Growing {
            label,
            buffer: Growing::make(gpu, label, 256),
            capacity: 256,
        }
    }

    fn make(gpu: &Gpu, label: &str, size: u64) -> wgpu::Buffer {
        gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    }

    /// Writes `bytes` at the start, growing the buffer first if need be.
    fn write(&mut self, gpu: &Gpu, bytes: &[u8]) {
        let size = (bytes.len() as u64).max(16).next_multiple_of(4);
        if size > self.capacity {
            self.capacity = size.next_power_of_two();
            self.buffer = Growing::make(gpu, self.label, self.capacity);
        }
        gpu.queue.write_buffer(&self.buffer, 0, bytes);
    }
}

/// A solve's transfers on the GPU.
struct GpuTransfers {
    gpu: Arc<Gpu>,
    /// The scene's centre, the origin of the device's coordinates.
    origin: DVec3,
    /// Each device receiver's index among the solver's receivers.
    order: Vec<u32>,
    /// Leaves' elements, by tree node (`NONE` for inner nodes).
    leaf_element: Vec<u32>,
    pipeline: wgpu::ComputePipeline,
    nodes: wgpu::Buffer,
    triangles: wgpu::Buffer,
    tree: wgpu::Buffer,
    surfaces: wgpu::Buffer,
    elements: wgpu::Buffer,
    receivers: wgpu::Buffer,
    negligible: Growing,
    sources: Growing,
    bins: Growing,
    gathered: wgpu::Buffer,
    readback: wgpu::Buffer,
    uncaptured: Arc<Mutex<Option<String>>>,
}

impl GpuTransfers {
    fn new(gpu: Arc<Gpu>, solve: &AdaptiveSolve<'_>) -> Result<GpuTransfers, DeviceError> {
        let fail = |e: crate::GpuError| DeviceError(e.to_string());
        let limits = gpu.device.limits();
        if limits.max_storage_buffers_per_shader_stage < STORAGE_BUFFERS {
            return Err(DeviceError(format!(
                "the GPU {} binds {} storage buffers at once; the transfer kernel needs {}",
                gpu.name(),
                limits.max_storage_buffers_per_shader_stage,
                STORAGE_BUFFERS
            )));
        }
        let tree = &solve.hierarchy.tree;
        let tree_depth = depth(tree);
        if tree_depth > MAX_TREE_DEPTH {
            return Err(DeviceError(format!(
                "the element tree is {tree_depth} deep; the GPU's walk holds {MAX_TREE_DEPTH}"
            )));
        }
        let scene = solve.scene;
        let mesh = solve.mesh;
        let (origin, scale) = trace::centre_and_scale(&scene.surfaces);
        let triangles = trace::triangles(&scene.surfaces, origin);
        let (bvh_nodes, ordered) = trace::tree(&triangles, 8.0 * f64::from(f32::EPSILON) * scale);

        let gpu_tree: Vec<GpuTreeNode> = tree
            .nodes
            .iter()
            .map(|n| {
                let (centre, centre_lo) = split(n.centre, origin);
                let first = tree.items[n.first as usize];
                GpuTreeNode {
                    centre,
                    radius: n.radius as f32,
                    centre_lo,
                    second: n.second,
                    group: n.group,
                    surface: mesh.elements[first as usize].surface,
                    element: if n.is_leaf() { first } else { NONE },
                    pad0: 0,
                }
            })
            .collect();
        let leaf_element = gpu_tree.iter().map(|n| n.element).collect();
        let surfaces: Vec<GpuSurface> = scene
            .surfaces
            .iter()
            .map(|s| {
                let (corner, corner_lo) =
                    split(s.polygon.first().copied().unwrap_or_default(), origin);
                GpuSurface {
                    normal: s.normal.as_vec3().to_array(),
                    group: s.group,
                    corner,
                    corner_lo,
                    ..GpuSurface::default()
                }
            })
            .collect();
        let elements: Vec<GpuElement> = mesh
            .elements
            .iter()
            .zip(&solve.hierarchy.centroids)
            .map(|(e, &c)| {
                let mut out = GpuElement {
                    surface: e.surface,
                    count: u32::from(e.corner_count),
                    area: e.area as f32,
                    ..GpuElement::default()
                };
                for (k, &v) in e.vertices().iter().enumerate() {
                    let (hi, lo) = split(mesh.vertices[v as usize].position, origin);
                    out.corners[k] = [hi[0], hi[1], hi[2], 0.0];
                    out.corners_lo[k] = [lo[0], lo[1], lo[2], 0.0];
                }
                (out.centroid, out.centroid_lo) = split(c, origin);
                out
            })
            .collect();
        let receivers: Vec<GpuReceiver> = solve
            .order
            .iter()
            .map(|&r| {
                let r = &solve.receivers[r as usize];
                let (point, point_lo) = split(r.point, origin);
                GpuReceiver {
                    point,
                    group: r.group,
                    point_lo,
                    normal: r.normal.as_vec3().to_array(),
                    ..GpuReceiver::default()
                }
            })
            .collect();

        let uncaptured = Arc::new(Mutex::new(None));
        let sink = uncaptured.clone();
        gpu.device
            .on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
                if let Ok(mut slot) = sink.lock() {
                    slot.get_or_insert_with(|| e.to_string());
                }
            }));
        let scope = gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let memory = gpu.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let source = [include_str!("../trace.wgsl"), include_str!("gather.wgsl")].concat();
        let module = gpu
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("gather.wgsl"),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            });
        let pipeline = gpu
            .device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("gather"),
                layout: None,
                module: &module,
                entry_point: Some("gather"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                cache: None,
            });
        let gathered_bytes = (size_of::<GpuGathered>() * receivers.len().max(1)) as u64;
        let transfers = GpuTransfers {
            origin,
            order: solve.order.to_vec(),
            leaf_element,
            pipeline,
            nodes: storage(&gpu, "nodes", &nonempty(bvh_nodes)),
            triangles: storage(&gpu, "triangles", &nonempty(ordered)),
            tree: storage(&gpu, "element tree", &nonempty(gpu_tree)),
            surfaces: storage(&gpu, "surfaces", &nonempty(surfaces)),
            elements: storage(&gpu, "elements", &nonempty(elements)),
            receivers: storage(&gpu, "receivers", &nonempty(receivers)),
            negligible: Growing::new(&gpu, "negligible"),
            sources: Growing::new(&gpu, "sources"),
            bins: Growing::new(&gpu, "bins"),
            gathered: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("gathered"),
                size: gathered_bytes,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            readback: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("gathered readback"),
                size: gathered_bytes,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            uncaptured,
            gpu,
        };
        let out_of_memory = pollster::block_on(memory.pop());
        let invalid = pollster::block_on(scope.pop());
        if let Some(e) = out_of_memory.or(invalid) {
            return Err(fail(transfers.gpu.failed(e)));
        }
        Ok(transfers)
    }

    fn failed(&self, e: impl std::fmt::Display) -> DeviceError {
        DeviceError(self.gpu.failed(e).to_string())
    }

    /// The shot's sources for the kernel: per node of the shooting subtree
    /// its weight, bins and (a leaf) unshot radiosity; the bins as centred
    /// point sources, worked out in `f64`.
    fn sources(&self, shot: &AdaptiveShot<'_>) -> (Vec<GpuNodeSource>, Vec<GpuBin>) {
        let nodes = shot
            .sources
            .nodes
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let element = self.leaf_element[shot.root as usize + i];
                let unshot = if element == NONE {
                    DVec3::ZERO
                } else {
                    shot.unshot[element as usize]
                };
                GpuNodeSource {
                    weight: s.weight as f32,
                    first_bin: s.first_bin,
                    bins: u32::from(s.bins),
                    pad0: 0,
                    unshot: unshot.as_vec3().to_array(),
                    pad1: 0,
                }
            })
            .collect();
        let bins = shot
            .sources
            .bins
            .iter()
            .map(|b| {
                let w = b.weight;
                let mean_normal = b.normal / w;
                let length = mean_normal.length();
                let centre = b.position / w;
                let covariance: DMat3 = b.moment * (1.0 / w) - outer(centre);
                GpuBin {
                    power: b.power.as_vec3().to_array(),
                    weight: w as f32,
                    normal: (mean_normal / length).as_vec3().to_array(),
                    length: length as f32,
                    centre: centre.as_vec3().to_array(),
                    representative: b.representative,
                    diagonal: [
                        covariance.x_axis.x as f32,
                        covariance.y_axis.y as f32,
                        covariance.z_axis.z as f32,
                    ],
                    axis: u32::from(b.axis),
                    off_diagonal: [
                        covariance.y_axis.x as f32,
                        covariance.z_axis.x as f32,
                        covariance.z_axis.y as f32,
                    ],
                    pad0: 0,
                }
            })
            .collect();
        (nodes, bins)
    }
}

impl AdaptiveTransfers for GpuTransfers {
    fn gather(&mut self, shot: &AdaptiveShot<'_>) -> Result<Option<Gathered>, DeviceError> {
        let count = self.order.len();
        if count == 0 || shot.sources.nodes.is_empty() {
            return Ok(Some(Gathered {
                irradiance: vec![DVec3::ZERO; count],
                ..Gathered::default()
            }));
        }
        let gpu = self.gpu.clone();
        let upload_start = Instant::now();
        let (nodes, bins) = self.sources(shot);
        let negligible: Vec<f32> = self
            .order
            .iter()
            .map(|&r| shot.negligible[r as usize] as f32)
            .collect();
        let scope = gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let memory = gpu.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        self.sources.write(&gpu, bytemuck::cast_slice(&nodes));
        self.bins.write(&gpu, bytemuck::cast_slice(&nonempty(bins)));
        self.negligible
            .write(&gpu, bytemuck::cast_slice(&negligible));
        let layout = self.pipeline.get_bind_group_layout(0);
        let (origin, origin_lo) = split(shot.origin, self.origin);
        let kernel_start = Instant::now();
        for first in (0..count).step_by(DISPATCH_RECEIVERS) {
            if shot.abort.fired() {
                let _ = pollster::block_on(memory.pop());
                let _ = pollster::block_on(scope.pop());
                return Ok(None);
            }
            let n = DISPATCH_RECEIVERS.min(count - first);
            let uniform = gpu
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("shot"),
                    contents: bytemuck::bytes_of(&GpuShot {
                        root: shot.root,
                        first: first as u32,
                        count: n as u32,
                        origin,
                        origin_lo,
                        ..GpuShot::default()
                    }),
                    usage: wgpu::BufferUsages::UNIFORM,
                });
            let group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("gather"),
                layout: &layout,
                entries: &[
                    entry(0, &self.nodes),
                    entry(1, &self.triangles),
                    entry(5, &self.tree),
                    entry(6, &self.surfaces),
                    entry(7, &self.elements),
                    entry(8, &self.receivers),
                    entry(9, &self.negligible.buffer),
                    entry(10, &self.sources.buffer),
                    entry(11, &self.bins.buffer),
                    entry(12, &self.gathered),
                    entry(13, &uniform),
                ],
            });
            let mut encoder = gpu
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("gather"),
                });
            {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("gather"),
                    timestamp_writes: None,
                });
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, &group, &[]);
                pass.dispatch_workgroups((n as u32).div_ceil(WORKGROUP), 1, 1);
            }
            gpu.queue.submit([encoder.finish()]);
            gpu.device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(|e| self.failed(e))?;
        }
        let readback_start = Instant::now();
        let bytes = (size_of::<GpuGathered>() * count) as u64;
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("gathered readback"),
            });
        encoder.copy_buffer_to_buffer(&self.gathered, 0, &self.readback, 0, bytes);
        gpu.queue.submit([encoder.finish()]);
        let out_of_memory = pollster::block_on(memory.pop());
        let invalid = pollster::block_on(scope.pop());
        if let Some(e) = out_of_memory.or(invalid) {
            return Err(self.failed(e));
        }
        let slice = self.readback.slice(..bytes);
        let (sender, receiver) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = sender.send(r);
        });
        gpu.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| self.failed(e))?;
        match receiver.recv() {
            Ok(Ok(())) => {}
            Ok(Err(e)) => return Err(self.failed(e)),
            Err(_) => return Err(self.failed("the readback was never mapped")),
        }
        if let Some(message) = self.uncaptured.lock().ok().and_then(|s| s.clone()) {
            return Err(self.failed(message));
        }
        let mut out = Gathered {
            irradiance: vec![DVec3::ZERO; count],
            ..Gathered::default()
        };
        {
            let view = slice.get_mapped_range().map_err(|e| self.failed(e))?;
            let gathered: &[GpuGathered] = bytemuck::cast_slice(&view);
            for (&r, g) in self.order.iter().zip(gathered) {
                out.irradiance[r as usize] = DVec3::from(g.irradiance.map(f64::from));
                out.pairs += u64::from(g.pairs);
                out.rays += u64::from(g.rays);
                out.walks += u64::from(g.walks);
                out.node_visits += u64::from(g.visits);
                out.element_sources += u64::from(g.elements);
            }
        }
        self.readback.unmap();
        out.upload_time = kernel_start - upload_start;
        out.kernel_time = readback_start - kernel_start;
        out.readback_time = readback_start.elapsed();
        Ok(Some(out))
    }
}
