//! Adaptive shooting's transfers on the GPU (beyond the paper: the
//! per-receiver source subdivision of Wallace, Elmquist & Haines 1989,
//! section 4, with the analytic factor of the paper's equation (2) at the
//! elements, as the CPU's `radiosity::solver::adaptive` does it): one
//! thread a receiver walks the shooting node's subtree with the CPU's
//! acceptance rules, its shadow rays answered by the `trace/walk.wgsl` walk of
//! the scene's BVH in the same kernel (`gather/walk.wgsl`). A receiver whose
//! walk is long (near the shooter) leaves the subtrees of its frontier to
//! other threads, whose sums are joined in the frontier's order
//! ([`FRONTIER`]), so a shot does not last as long as one thread's walk of
//! the whole subtree.
//!
//! What is the same for a whole solve goes to the device once: the scene's
//! triangles and BVH, the element tree, the elements (corners, centroid,
//! area, reflectance), the surfaces' planes and the receivers in the
//! receiver tree's order (neighbours in one workgroup walk alike); so does
//! the state, each receiver's irradiance and each element's unshot
//! radiosity, which stays there (`transfers`). Each shot uploads its
//! subtree's sources (power in bins by normal, with their centres and
//! covariances worked out in `f64` on the host, so the kernel never
//! subtracts large sums), runs the walk and the book-keeping
//! (`book.wgsl`), and reads back the shooters' powers and the ledger's
//! sums. The loop, the choice of shooter and the preparation of its sources
//! stay on the host, shared with the CPU.
//!
//! Points are two `f32`s relative to the scene's centre, and the kernel
//! works with differences taken from the receiver (or the shot's centre),
//! so it is as precise as `f32` allows relative to the distances involved:
//! the gathering nudge of a receiver a micrometre off its surface keeps
//! its side of a neighbour's plane.

use std::sync::Arc;

use radiosity::solver::device::{AdaptiveSolve, AdaptiveTransfers, Backend, DeviceError};
use radiosity::solver::hierarchy::Tree;

mod buffers;
mod kernels;
mod memory;
mod scene;
mod transfers;

pub use self::buffers::{
    GpuBin, GpuBook, GpuElement, GpuElementBook, GpuLeave, GpuNodeSource, GpuPane, GpuPartial,
    GpuReceiver, GpuShot, GpuSurface, GpuTreeNode,
};
pub(crate) use self::kernels::Pipelines;
pub use self::memory::DeviceMemory;
use self::transfers::GpuTransfers;
use crate::Gpu;

/// The most workgroups a dispatch may have along one dimension: the
/// least every adapter allows (WebGPU's default limit, Vulkan's minimum).
pub const MAX_WORKGROUPS: u32 = 65_535;

/// Nodes a receiver's walk may leave to other threads: once the nodes it
/// has still to visit, breadth first, are this many, each is an item of
/// its own (`gather_items` in `gather/walk.wgsl`). The receivers near a
/// shooter walk most of its subtree, one thread each, and a shot lasts as
/// long as its longest walk; split, their work spreads over the device.
/// At most [`MAX_FRONTIER`].
pub const FRONTIER: u32 = 32;

pub use crate::shaders::MAX_FRONTIER;
use crate::shaders::{SERIAL_POWER_ITEMS, WALK_STACK, WORKGROUP};

/// The deepest element tree the kernel's walk stack holds: two less than
/// its entries (a visit pushes two children).
const MAX_TREE_DEPTH: usize = WALK_STACK as usize - 2;

/// Storage buffers the transfer kernel binds at once.
const STORAGE_BUFFERS: u32 = 13;

/// The GPU as a device for the solver's transfers.
#[derive(Clone)]
pub struct GpuBackend {
    gpu: Arc<Gpu>,
    /// The most device memory a solve may take (`--max-gpu-memory`).
    max_memory: Option<u64>,
    /// Receivers a dispatch of the walk takes at most; `None`: as many as
    /// the adapter binds ([`dispatch_receivers`]).
    dispatch_receivers: Option<usize>,
    /// Workgroups the split walks' items are dispatched in at most.
    item_workgroups: u32,
    /// Nodes a receiver's walk may leave to other threads.
    frontier: u32,
    /// Elements of a shooter whose power one thread sums at most.
    serial_power_items: u32,
}

impl GpuBackend {
    /// The back end on `gpu`.
    #[must_use]
    pub fn new(gpu: Gpu) -> GpuBackend {
        GpuBackend {
            gpu: Arc::new(gpu),
            max_memory: None,
            dispatch_receivers: None,
            item_workgroups: MAX_WORKGROUPS,
            frontier: FRONTIER,
            serial_power_items: SERIAL_POWER_ITEMS,
        }
    }

    /// The same, its walk dispatched `receivers` receivers at a time (at
    /// least one, at most what [`dispatch_receivers`] allows, which is the
    /// default): how the work is cut never changes the answer. Each
    /// dispatch is a submission of its own, between which a shot can be
    /// abandoned; fewer receivers a dispatch keep each one short on a slow
    /// device, at the price of a shot's time on a fast one (a dispatch
    /// lasts as long as its longest walk, and a small one leaves most of a
    /// large GPU idle).
    #[must_use]
    pub fn with_dispatch_receivers(mut self, receivers: usize) -> GpuBackend {
        self.dispatch_receivers = Some(receivers.max(1));
        self
    }

    /// The same, the split walks' items dispatched in at most `workgroups`
    /// workgroups (1 to [`MAX_WORKGROUPS`], the default), each thread
    /// walking items a dispatch's width apart until none is left: the
    /// same answer to the last bit, in any number of workgroups.
    #[must_use]
    pub fn with_item_workgroups(mut self, workgroups: u32) -> GpuBackend {
        self.item_workgroups = workgroups.clamp(1, MAX_WORKGROUPS);
        self
    }

    /// The same, a receiver's walk split once `nodes` are left to visit
    /// (1 to [`MAX_FRONTIER`]; 1 never splits; [`FRONTIER`] by default):
    /// the answer is the same but for the order of its sums.
    #[must_use]
    pub fn with_frontier(mut self, nodes: u32) -> GpuBackend {
        self.frontier = nodes.clamp(1, MAX_FRONTIER);
        self
    }

    /// The same, the unshot power of a shooter of more than `items`
    /// elements summed by a workgroup, of fewer by one thread
    /// ([`SERIAL_POWER_ITEMS`] by default; 0 sums every shooter by a
    /// workgroup): the answer is the same but for the order of its sums.
    #[must_use]
    pub fn with_serial_power_items(mut self, items: u32) -> GpuBackend {
        self.serial_power_items = items;
        self
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

    /// [`crate::policy::refuses`]: the default method only.
    fn refuses(&self, settings: &radiosity::solver::Settings) -> Option<String> {
        crate::policy::refuses(settings)
    }

    /// [`DeviceMemory::of`] against the adapter's largest buffer and
    /// `--max-gpu-memory`.
    fn check(
        &self,
        scene: &radiosity::scene::Scene,
        mesh: &radiosity::mesh::Mesh,
        receivers: usize,
    ) -> Result<u64, DeviceError> {
        let limits = self.gpu.device.limits();
        let chunk = self.chunk(&limits, receivers);
        let memory = DeviceMemory::of(scene, mesh, receivers, chunk, self.frontier);
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

    fn segments(
        &self,
        scene: &radiosity::scene::Scene,
    ) -> Result<Box<dyn radiosity::solver::device::Segments>, DeviceError> {
        crate::trace::SceneTracer::new(&self.gpu, &scene.surfaces)
            .map(|t| Box::new(t) as Box<dyn radiosity::solver::device::Segments>)
            .map_err(|e| DeviceError(e.to_string()))
    }

    fn adaptive(
        &self,
        solve: &AdaptiveSolve<'_>,
    ) -> Result<Box<dyn AdaptiveTransfers>, DeviceError> {
        let chunk = self.chunk(&self.gpu.device.limits(), solve.order.len());
        Ok(Box::new(GpuTransfers::new(
            self.gpu.clone(),
            solve,
            chunk,
            self.frontier,
            self.item_workgroups,
            self.serial_power_items,
        )?))
    }
}

impl GpuBackend {
    /// Receivers a dispatch of the walk takes, of `receivers`: as many as
    /// the adapter allows, or fewer if asked.
    fn chunk(&self, limits: &wgpu::Limits, receivers: usize) -> usize {
        let most = dispatch_receivers(limits, self.frontier);
        self.dispatch_receivers
            .map_or(most, |asked| asked.min(most))
            .min(receivers)
            .max(1)
    }
}

/// The most receivers one dispatch of the walk may take on an adapter
/// with `limits`, a receiver's walk split into at most `frontier` items:
/// its split walks (a header and `frontier` items a receiver) in one
/// binding, its workgroups within [`MAX_WORKGROUPS`].
///
/// The whole scene in one dispatch where that fits: a shot's walks then
/// overlap, and a large GPU is kept busy. Cut into dispatches of 32,768
/// receivers, Sponza's shots took 2.5 times as long on an H200 as in one
/// (`docs/experiments/gpu.md`).
#[must_use]
pub fn dispatch_receivers(limits: &wgpu::Limits, frontier: u32) -> usize {
    let binding = limits
        .max_storage_buffer_binding_size
        .min(limits.max_buffer_size);
    let by_binding = binding / kernels::split_bytes(1, 1, frontier);
    let by_workgroups = u64::from(MAX_WORKGROUPS) * u64::from(WORKGROUP);
    usize::try_from(by_binding.min(by_workgroups))
        .unwrap_or(usize::MAX)
        .max(1)
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
