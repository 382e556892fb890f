//! A solve's state and shots on the GPU (adaptive shooting, beyond the
//! paper: the per-receiver source subdivision of Wallace, Elmquist &
//! Haines 1989, section 4, as `radiosity::solver::adaptive` makes it on the
//! CPU): the scene, the element tree, the elements and the receivers go to
//! the device once; so do each receiver's irradiance and each element's
//! unshot radiosity, which then stay there. Each pass of a round's shooters
//! uploads its sources and runs the walk (`gather/walk.wgsl`), adding what
//! the receivers gathered to the round's sums (`book.wgsl`), submitted
//! without waiting; the round's end runs the book-keeping and the choice of
//! the next round in one submission and reads back the ledger's sums per
//! workgroup (added on the host in `f64`, in a fixed order), the shooters'
//! powers, the walks' counts and the next round's unshot light; the state
//! comes back only when asked ([`AdaptiveTransfers::state`]). A shooter's
//! pass is `pass.rs`, the round's end `book.rs`.

mod binds;
mod book;
mod pass;

use std::sync::{Arc, Mutex};

use glam::DVec3;
use radiosity::solver::device::{
    AdaptiveShot, AdaptiveSolve, AdaptiveTransfers, Booked, DeviceError, Kernels, Traffic,
};

use super::buffers::{GpuBook, GpuLeave, GpuPartial};
use super::kernels::{Growing, Pipelines, Timer, dvec3, split_bytes, state_buffer, vec4};
use super::scene::SceneData;
use super::{MAX_TREE_DEPTH, STORAGE_BUFFERS, depth};
use crate::Gpu;
use crate::device_scene::DeviceScene;
use crate::wgpu_io::{catch_uncaptured, nonempty, read_back, storage};
use binds::{Binds, Uniforms, Which};

use crate::shaders::counter::COUNTERS;

/// Bytes of the next shooter's record (`next` in `book.wgsl`).
const NEXT_BYTES: u64 = 16;
use crate::shaders::BOOK_WORKGROUP;

/// `f`'s result, and the first validation or memory error `gpu` reported
/// while it ran.
fn caught<T>(gpu: &Gpu, f: impl FnOnce() -> T) -> (T, Option<wgpu::Error>) {
    let scope = gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);
    let memory = gpu.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let result = f();
    let out_of_memory = pollster::block_on(memory.pop());
    let invalid = pollster::block_on(scope.pop());
    (result, out_of_memory.or(invalid))
}

/// A solve on the GPU.
pub(super) struct GpuTransfers {
    gpu: Arc<Gpu>,
    /// The scene's centre, the origin of the device's coordinates.
    origin: DVec3,
    /// Each device receiver's index among the solver's receivers.
    order: Vec<u32>,
    /// Leaves' elements, by tree node (`NONE` for inner nodes).
    leaf_element: Vec<u32>,
    /// Each tree node's items, `first..last`.
    ranges: Vec<[u32; 2]>,
    /// The element tree's items (elements in the tree's order).
    tree_items: Vec<u32>,
    elements: u32,
    shooters: u32,
    /// Receivers a dispatch of the walk takes at most.
    dispatch_receivers: usize,
    /// Nodes a receiver's walk may leave to other threads (`Shot::frontier`).
    frontier: u32,
    /// Workgroups the items are dispatched in at most (`Shot::item_groups`).
    item_workgroups: u32,
    pipelines: Arc<Pipelines>,
    /// The scene's triangles and BVH (shared with other solves).
    scene: Arc<DeviceScene>,
    tree: wgpu::Buffer,
    surfaces: wgpu::Buffer,
    /// The glass panes' triangles.
    panes: wgpu::Buffer,
    element_buffer: wgpu::Buffer,
    receivers: wgpu::Buffer,
    element_book: wgpu::Buffer,
    shooter_items: wgpu::Buffer,
    items: wgpu::Buffer,
    /// Each receiver's irradiance (state).
    total: wgpu::Buffer,
    /// Its direct part (state).
    direct: wgpu::Buffer,
    /// Each element's unshot radiosity (state).
    unshot: wgpu::Buffer,
    shot_irradiance: wgpu::Buffer,
    /// What each receiver gathered in the round so far.
    round_irradiance: wgpu::Buffer,
    /// Its direct part.
    round_direct: wgpu::Buffer,
    /// What the round's shooters' elements are left with, at its end.
    leaves: Vec<GpuLeave>,
    leave_buffer: Growing,
    /// The elements whose unshot radiosity the host asks for.
    wanted: Growing,
    /// Passes sent in the round so far.
    round_passes: u32,
    /// Time preparing and sending them (host clock).
    round_upload: std::time::Duration,
    /// A chunk's split walks: a header a receiver, then the items.
    split: wgpu::Buffer,
    /// Timestamps around a round's passes, where the device has them.
    timer: Option<Timer>,
    /// `gather_items`' workgroups, an indirect dispatch's arguments.
    item_dispatch: wgpu::Buffer,
    counters: wgpu::Buffer,
    partials: wgpu::Buffer,
    powers: wgpu::Buffer,
    staging: wgpu::Buffer,
    sources: Growing,
    bins: Growing,
    /// The next round as the device chose it, and its elements' unshot
    /// radiosity (`choose_next`, `collect_next`).
    next: wgpu::Buffer,
    round_offsets: wgpu::Buffer,
    item_shooter: wgpu::Buffer,
    next_unshot: wgpu::Buffer,
    /// The shooters of more than `serial_items` elements, and how many.
    large_shooters: wgpu::Buffer,
    large: u32,
    /// Elements of a shooter whose power one thread sums at most.
    serial_items: u32,
    /// `--round` ([`AdaptiveSolve::round`]).
    fraction: f32,
    /// Elements of the next round read back with a round: four times the
    /// most a round has taken (at least the largest shooter's, at most
    /// all).
    prefetch: u32,
    readback: wgpu::Buffer,
    uncaptured: Arc<Mutex<Option<String>>>,
    /// What crossed between host and device so far.
    traffic: std::cell::Cell<Traffic>,
    /// The uniforms, rewritten in place.
    uniforms: Uniforms,
    /// The kernels' bind groups, each until a buffer it reads grows.
    binds: Binds,
}

impl GpuTransfers {
    pub(super) fn new(
        gpu: Arc<Gpu>,
        solve: &AdaptiveSolve<'_>,
        dispatch_receivers: usize,
        frontier: u32,
        item_workgroups: u32,
        serial_items: u32,
    ) -> Result<GpuTransfers, DeviceError> {
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
        let uncaptured = catch_uncaptured(&gpu);
        let scope = gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let memory = gpu.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let device_scene = DeviceScene::of(&gpu, &solve.scene.surfaces);
        let origin = device_scene.origin;
        let SceneData {
            tree: gpu_tree,
            leaf_element,
            surfaces,
            elements,
            receivers,
            element_book,
            shooter_items,
            item_shooter,
            panes,
        } = SceneData::of(solve, origin);
        let largest_shooter = shooter_items.iter().map(|r| r[1] - r[0]).max().unwrap_or(0) as u64;
        let large: Vec<u32> = (0..shooter_items.len() as u32)
            .filter(|&s| {
                let [first, last] = shooter_items[s as usize];
                last - first > serial_items
            })
            .collect();

        let pipelines = Pipelines::on(&gpu);
        let r = receivers.len() as u64;
        let e = elements.len() as u64;
        let s = shooter_items.len() as u64;
        let vec4_bytes = 16u64;
        let partial_count = e.div_ceil(u64::from(BOOK_WORKGROUP)).max(1);
        let timer = Timer::on(&gpu);
        let round_readback = 4 * s
            + partial_count * size_of::<GpuPartial>() as u64
            + 4 * COUNTERS as u64
            + NEXT_BYTES
            + e * vec4_bytes
            + 16 * u64::from(Timer::SLOTS);
        let readback_bytes = round_readback.max((2 * r + e) * vec4_bytes).max(16);
        let transfers = GpuTransfers {
            origin,
            order: solve.order.to_vec(),
            leaf_element,
            ranges: tree.nodes.iter().map(|n| [n.first, n.last]).collect(),
            tree_items: tree.items.clone(),
            elements: e as u32,
            shooters: s as u32,
            dispatch_receivers,
            frontier,
            item_workgroups,
            timer,
            pipelines,
            scene: device_scene,
            tree: storage(&gpu, "element tree", &nonempty(gpu_tree)),
            surfaces: storage(&gpu, "surfaces", &nonempty(surfaces)),
            panes: storage(&gpu, "panes", &nonempty(panes)),
            element_buffer: storage(&gpu, "elements", &nonempty(elements)),
            receivers: storage(&gpu, "receivers", &nonempty(receivers)),
            element_book: storage(&gpu, "element book", &nonempty(element_book)),
            shooter_items: storage(&gpu, "shooter items", &nonempty(shooter_items)),
            items: storage(&gpu, "items", &nonempty(tree.items.clone())),
            total: state_buffer(&gpu, "irradiance", r * vec4_bytes),
            direct: state_buffer(&gpu, "direct irradiance", r * vec4_bytes),
            unshot: state_buffer(&gpu, "unshot", e * vec4_bytes),
            shot_irradiance: state_buffer(&gpu, "shot irradiance", r * vec4_bytes),
            round_irradiance: state_buffer(&gpu, "round irradiance", r * vec4_bytes),
            round_direct: state_buffer(&gpu, "round direct irradiance", r * vec4_bytes),
            leaves: Vec::new(),
            leave_buffer: Growing::new(&gpu, "leaves"),
            wanted: Growing::new(&gpu, "wanted"),
            round_passes: 0,
            round_upload: std::time::Duration::ZERO,
            split: state_buffer(
                &gpu,
                "split walks",
                split_bytes(r as usize, dispatch_receivers, frontier),
            ),
            item_dispatch: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("item dispatch"),
                size: 16,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::INDIRECT,
                mapped_at_creation: false,
            }),
            counters: state_buffer(&gpu, "counters", 4 * COUNTERS as u64),
            partials: state_buffer(
                &gpu,
                "partials",
                partial_count * size_of::<GpuPartial>() as u64,
            ),
            powers: state_buffer(&gpu, "shooter powers", 4 * s),
            staging: state_buffer(&gpu, "staging", e * vec4_bytes),
            next: state_buffer(&gpu, "next round", NEXT_BYTES),
            round_offsets: state_buffer(&gpu, "next round's offsets", 4 * s),
            item_shooter: storage(&gpu, "item shooters", &nonempty(item_shooter)),
            next_unshot: state_buffer(&gpu, "next round's unshot", e * vec4_bytes),
            large: large.len() as u32,
            serial_items,
            large_shooters: storage(&gpu, "large shooters", &nonempty(large)),
            fraction: solve.round as f32,
            prefetch: largest_shooter as u32,
            sources: Growing::new(&gpu, "sources"),
            bins: Growing::new(&gpu, "bins"),
            readback: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("readback"),
                size: readback_bytes,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            uncaptured,
            traffic: std::cell::Cell::default(),
            uniforms: Uniforms::new(&gpu, (r as usize).div_ceil(dispatch_receivers)),
            binds: Binds::default(),
            gpu,
        };
        let out_of_memory = pollster::block_on(memory.pop());
        let invalid = pollster::block_on(scope.pop());
        if let Some(e) = out_of_memory.or(invalid) {
            transfers.gpu.forget();
            return Err(transfers.failed(e));
        }
        Ok(transfers)
    }

    fn failed(&self, e: impl std::fmt::Display) -> DeviceError {
        DeviceError(self.gpu.failed(e).to_string())
    }

    /// A bind group of `pipeline` holding `entries`.
    fn bind(
        &self,
        pipeline: &wgpu::ComputePipeline,
        entries: &[wgpu::BindGroupEntry<'_>],
    ) -> wgpu::BindGroup {
        self.gpu
            .device
            .create_bind_group(&wgpu::BindGroupDescriptor {
                label: None,
                layout: &pipeline.get_bind_group_layout(0),
                entries,
            })
    }

    /// The book-keeping's parameters for a pass booked times `sign`,
    /// `direct` its direct share.
    fn book_data(&self, sign: f64, direct: DVec3) -> GpuBook {
        GpuBook {
            large: self.large,
            serial_items: self.serial_items,
            elements: self.elements,
            receivers: self.order.len() as u32,
            shooters: self.shooters,
            sign: sign as f32,
            direct: direct.as_vec3().to_array(),
            ..GpuBook::default()
        }
    }

    /// Submits `encoder`, whose last commands copy `bytes` into the
    /// readback buffer, and returns those bytes once the device is done;
    /// any error the device reported on the way is this call's.
    fn finish(&self, encoder: wgpu::CommandEncoder, bytes: u64) -> Result<Vec<u8>, DeviceError> {
        let gpu = &self.gpu;
        gpu.queue.submit([encoder.finish()]);
        let mut traffic = self.traffic.get();
        traffic.host_waits += 1;
        traffic.submissions += 1;
        traffic.bytes_read += bytes;
        self.traffic.set(traffic);
        read_back(gpu, &self.readback, bytes, &self.uncaptured)
            .map_err(|e| DeviceError(e.to_string()))
    }

    /// [`Self::finish`] for a checkpoint: counted apart (its wait, its
    /// submission, its bytes), as the checkpoints come by the clock, not by
    /// the shot.
    fn finish_checkpoint(
        &self,
        encoder: wgpu::CommandEncoder,
        bytes: u64,
    ) -> Result<Vec<u8>, DeviceError> {
        let out = self.finish(encoder, bytes);
        let mut traffic = self.traffic.get();
        traffic.host_waits -= 1;
        traffic.submissions -= 1;
        traffic.bytes_read -= bytes;
        traffic.checkpoints += 1;
        self.traffic.set(traffic);
        out
    }

    /// `f`, with the device's validation and memory errors caught.
    fn scoped<T>(&self, f: impl FnOnce() -> Result<T, DeviceError>) -> Result<T, DeviceError> {
        let (result, error) = caught(&self.gpu, f);
        match error {
            Some(e) => Err(self.failed(e)),
            None => result,
        }
    }

    /// [`Self::scoped`] for `f` that changes the solve.
    fn scoped_mut<T>(
        &mut self,
        f: impl FnOnce(&mut Self) -> Result<T, DeviceError>,
    ) -> Result<T, DeviceError> {
        let gpu = self.gpu.clone();
        let (result, error) = caught(&gpu, || f(self));
        match error {
            Some(e) => Err(self.failed(e)),
            None => result,
        }
    }

    /// The timestamps around a pass given `slot` ([`Timer::slot`]).
    fn timestamps(&self, slot: Option<u32>) -> Option<wgpu::ComputePassTimestampWrites<'_>> {
        let index = slot?;
        self.timer
            .as_ref()
            .map(|timer| wgpu::ComputePassTimestampWrites {
                query_set: &timer.set,
                beginning_of_pass_write_index: Some(2 * index),
                end_of_pass_write_index: Some(2 * index + 1),
            })
    }

    /// One compute pass on `encoder`: `pipeline` with `group` over
    /// `workgroups`, timed in `slot` where given.
    fn dispatch(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        label: &str,
        (pipeline, group, workgroups): (&wgpu::ComputePipeline, &wgpu::BindGroup, u32),
        slot: Option<u32>,
    ) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(label),
            timestamp_writes: self.timestamps(slot),
        });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, group, &[]);
        pass.dispatch_workgroups(workgroups, 1, 1);
    }

    fn encoder(&self, label: &str) -> wgpu::CommandEncoder {
        self.gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) })
    }
}

impl AdaptiveTransfers for GpuTransfers {
    fn traffic(&self) -> Traffic {
        self.traffic.get()
    }

    fn kernels(&self) -> Kernels {
        let (state, time) = self.gpu.kernels();
        Kernels {
            time,
            cache: Some(state.name()),
        }
    }

    fn begin(
        &mut self,
        irradiance: &[DVec3],
        direct: &[DVec3],
        unshot: &[DVec3],
    ) -> Result<(), DeviceError> {
        let total: Vec<[f32; 4]> = self
            .order
            .iter()
            .map(|&r| vec4(irradiance[r as usize]))
            .collect();
        let direct: Vec<[f32; 4]> = self
            .order
            .iter()
            .map(|&r| vec4(direct.get(r as usize).copied().unwrap_or(DVec3::ZERO)))
            .collect();
        let unshot: Vec<[f32; 4]> = unshot.iter().map(|&u| vec4(u)).collect();
        self.scoped(|| {
            self.gpu
                .queue
                .write_buffer(&self.total, 0, bytemuck::cast_slice(&total));
            self.gpu
                .queue
                .write_buffer(&self.direct, 0, bytemuck::cast_slice(&direct));
            self.gpu
                .queue
                .write_buffer(&self.unshot, 0, bytemuck::cast_slice(&unshot));
            Ok(())
        })
    }

    fn unshot(&mut self, elements: &[u32]) -> Result<Vec<DVec3>, DeviceError> {
        if elements.is_empty() {
            return Ok(Vec::new());
        }
        self.scoped_mut(|t| {
            t.write_growing(Which::Wanted, bytemuck::cast_slice(elements));
            let book = GpuBook {
                count: elements.len() as u32,
                ..t.book_data(1.0, DVec3::ZERO)
            };
            t.set_uniform(&t.uniforms.wanted_book, &book);
            let group = t.collect_bind();
            let mut encoder = t.encoder("collect");
            let workgroups = (elements.len() as u32).div_ceil(BOOK_WORKGROUP);
            t.dispatch(
                &mut encoder,
                "collect",
                (&t.pipelines.collect, &group, workgroups),
                None,
            );
            let bytes = 16 * elements.len() as u64;
            encoder.copy_buffer_to_buffer(&t.staging, 0, &t.readback, 0, bytes);
            let data = t.finish(encoder, bytes)?;
            let words: &[f32] = bytemuck::cast_slice(&data);
            Ok(words.chunks_exact(4).map(dvec3).collect())
        })
    }

    fn send(&mut self, shot: &AdaptiveShot<'_>) -> Result<bool, DeviceError> {
        if shot.abort.fired() {
            self.drop_round();
            return Ok(false);
        }
        if self.order.is_empty() || shot.sources.nodes.is_empty() {
            return Err(DeviceError("a shot with no receivers or no sources".into()));
        }
        self.scoped_mut(|t| t.pass(shot))
    }

    fn book(&mut self) -> Result<Booked, DeviceError> {
        self.scoped_mut(Self::book_round)
    }

    fn state(
        &mut self,
        irradiance: &mut [DVec3],
        direct: &mut [DVec3],
        unshot: &mut [DVec3],
    ) -> Result<(), DeviceError> {
        let r = 16 * self.order.len() as u64;
        let e = 16 * u64::from(self.elements);
        let data = self.scoped(|| {
            let mut encoder = self.encoder("state");
            if r > 0 {
                encoder.copy_buffer_to_buffer(&self.total, 0, &self.readback, 0, r);
                encoder.copy_buffer_to_buffer(&self.direct, 0, &self.readback, r, r);
            }
            if e > 0 {
                encoder.copy_buffer_to_buffer(&self.unshot, 0, &self.readback, 2 * r, e);
            }
            self.finish_checkpoint(encoder, 2 * r + e)
        })?;
        let words: &[f32] = bytemuck::cast_slice(&data);
        let (total_words, rest) = words.split_at((r / 4) as usize);
        let (direct_words, unshot_words) = rest.split_at((r / 4) as usize);
        for ((&k, v), d) in self
            .order
            .iter()
            .zip(total_words.chunks_exact(4))
            .zip(direct_words.chunks_exact(4))
        {
            irradiance[k as usize] = dvec3(v);
            if let Some(slot) = direct.get_mut(k as usize) {
                *slot = dvec3(d);
            }
        }
        for (u, v) in unshot.iter_mut().zip(unshot_words.chunks_exact(4)) {
            *u = dvec3(v);
        }
        Ok(())
    }
}
