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
//! comes back only when asked ([`AdaptiveTransfers::state`]).

use std::sync::{Arc, Mutex};
use std::time::Instant;

use glam::DVec3;
use radiosity::solver::device::{
    AdaptiveShot, AdaptiveSolve, AdaptiveTransfers, Booked, DeviceError, NextRound, Traffic,
};
use radiosity::solver::hierarchy::NONE;
use radiosity::solver::method::Received;

use super::buffers::{GpuBin, GpuBook, GpuLeave, GpuNodeSource, GpuPartial, GpuShot};
use super::kernels::{
    Growing, Pipelines, Stage, Timer, dvec3, split_bytes, state_buffer, uniform, vec4,
};
use super::scene::SceneData;
use super::{MAX_TREE_DEPTH, STORAGE_BUFFERS, WORKGROUP, depth};
use crate::Gpu;
use crate::device_scene::{DeviceScene, split};
use crate::wgpu_io::{catch_uncaptured, entry, nonempty, read_back, storage};

use crate::shaders::counter::{self, COUNTERS};

/// Bytes of the next shooter's record (`next` in `book.wgsl`).
const NEXT_BYTES: u64 = 16;
use crate::shaders::{BOOK_WORKGROUP, GatherBinding as G};

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
    /// `--round` ([`AdaptiveSolve::round`]).
    fraction: f32,
    /// Elements of the next round read back with a round: twice the most
    /// a round has taken (at least the largest shooter's, at most all).
    prefetch: u32,
    readback: wgpu::Buffer,
    uncaptured: Arc<Mutex<Option<String>>>,
    /// What crossed between host and device so far.
    traffic: std::cell::Cell<Traffic>,
}

impl GpuTransfers {
    pub(super) fn new(
        gpu: Arc<Gpu>,
        solve: &AdaptiveSolve<'_>,
        dispatch_receivers: usize,
        frontier: u32,
        item_workgroups: u32,
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
            elements: self.elements,
            receivers: self.order.len() as u32,
            shooters: self.shooters,
            sign: sign as f32,
            direct: direct.as_vec3().to_array(),
            ..GpuBook::default()
        }
    }

    /// The book-keeping's uniform: `count` elements asked for, a pass
    /// booked times `sign`, `direct` its direct share.
    fn book_uniform(&self, count: u32, sign: f64, direct: DVec3) -> wgpu::Buffer {
        uniform(
            &self.gpu,
            "book",
            &GpuBook {
                count,
                ..self.book_data(sign, direct)
            },
        )
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

    fn encoder(&self, label: &str) -> wgpu::CommandEncoder {
        self.gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) })
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
                // The point source the CPU's point_factor uses, derived once.
                let p = &b.point;
                let covariance = p.covariance;
                GpuBin {
                    power: b.power.as_vec3().to_array(),
                    weight: b.weight as f32,
                    normal: p.normal.as_vec3().to_array(),
                    length: p.length as f32,
                    centre: p.centre.as_vec3().to_array(),
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

    /// One pass's commands (inside an error scope): the walk in chunks of
    /// receivers, a submission each (none runs long enough to trip a
    /// driver's watchdog, and the round can be abandoned between them),
    /// the last one also adding what the receivers gathered to the
    /// round's. False when abandoned: the round is dropped.
    fn pass(&mut self, shot: &AdaptiveShot<'_>) -> Result<bool, DeviceError> {
        let gpu = self.gpu.clone();
        let upload_start = Instant::now();
        let (nodes, bins) = self.sources(shot);
        self.sources
            .write(&gpu, bytemuck::cast_slice(&nonempty(nodes)));
        self.bins.write(&gpu, bytemuck::cast_slice(&nonempty(bins)));
        let (origin, origin_lo) = split(shot.origin, self.origin);
        let count = self.order.len();
        let [first, last] = self.ranges[shot.root as usize];
        if let Some(leave) = shot.leave {
            // What the shooter's elements are left with, at the round's end.
            let elements = &self.tree_items[first as usize..last as usize];
            self.leaves
                .extend(leave.iter().zip(elements).map(|(u, &element)| GpuLeave {
                    value: u.as_vec3().to_array(),
                    element,
                }));
        }
        let book = self.book_uniform(0, shot.sign, shot.direct);
        let mut encoder = self.encoder("pass");
        if self.round_passes == 0 {
            encoder.clear_buffer(&self.counters, 0, None);
        }
        let mut groups = Vec::new();
        let mut item_binds = Vec::new();
        for start in (0..count).step_by(self.dispatch_receivers) {
            let n = self.dispatch_receivers.min(count - start);
            let uniform = uniform(
                &gpu,
                "shot",
                &GpuShot {
                    root: shot.root,
                    first: start as u32,
                    count: n as u32,
                    negligible: shot.negligible as f32,
                    origin,
                    mean: shot.mean_radiosity as f32,
                    origin_lo,
                    frontier: self.frontier,
                    item_groups: self.item_workgroups,
                    _pad: [0; 3],
                },
            );
            // What the walks and the split walks' items both read.
            let walk_entries = [
                entry(G::Nodes, &self.scene.nodes),
                entry(G::Triangles, &self.scene.triangles),
                entry(G::Tree, &self.tree),
                entry(G::Surfaces, &self.surfaces),
                entry(G::Elements, &self.element_buffer),
                entry(G::Receivers, &self.receivers),
                entry(G::Total, &self.total),
                entry(G::Sources, &self.sources.buffer),
                entry(G::Bins, &self.bins.buffer),
                entry(G::Shot, &uniform),
                entry(G::Counters, &self.counters),
                entry(G::Panes, &self.panes),
                entry(G::Split, &self.split),
            ];
            let group = self.bind(
                &self.pipelines.gather,
                &[
                    &walk_entries[..],
                    &[entry(G::ShotIrradiance, &self.shot_irradiance)],
                ]
                .concat(),
            );
            let items = self.bind(&self.pipelines.gather_items, &walk_entries);
            let size = self.bind(
                &self.pipelines.size_items,
                &[
                    entry(G::Shot, &uniform),
                    entry(G::Counters, &self.counters),
                    entry(G::ItemDispatch, &self.item_dispatch),
                ],
            );
            let join = self.bind(
                &self.pipelines.join_items,
                &[
                    entry(G::ShotIrradiance, &self.shot_irradiance),
                    entry(G::Shot, &uniform),
                    entry(G::Counters, &self.counters),
                    entry(G::Split, &self.split),
                ],
            );
            groups.push([
                (group, (n as u32).div_ceil(WORKGROUP)),
                (join, (n as u32).div_ceil(WORKGROUP)),
            ]);
            item_binds.push([items, size]);
        }
        let gathered = self.bind(
            &self.pipelines.gathered,
            &[
                entry(G::ShotIrradiance, &self.shot_irradiance),
                entry(G::RoundIrradiance, &self.round_irradiance),
                entry(G::RoundDirect, &self.round_direct),
                entry(G::Counters, &self.counters),
                entry(G::Book, &book),
            ],
        );
        let kernel_start = Instant::now();
        let chunks = groups.len();
        let mut encoder = Some(encoder);
        for (k, chunk_groups) in groups.iter().enumerate() {
            if k > 0 && shot.abort.fired() {
                self.drop_round();
                return Ok(false);
            }
            let mut chunk = encoder.take().unwrap_or_else(|| self.encoder("walk"));
            // A pass each: the walks, the items' workgroups, the items
            // the walks left, the joins.
            let [(walk, walk_groups), (join, join_groups)] = chunk_groups;
            let slots = [Stage::Walk, Stage::Items, Stage::Items, Stage::Join]
                .map(|stage| self.timer.as_mut().and_then(|t| t.slot(stage)));
            let gathered_slot = if k + 1 == chunks {
                self.timer.as_mut().and_then(|t| t.slot(Stage::Book))
            } else {
                None
            };
            let pass = |chunk: &mut wgpu::CommandEncoder, label: &str, slot: Option<u32>| {
                chunk
                    .begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some(label),
                        timestamp_writes: self.timestamps(slot),
                    })
                    .forget_lifetime()
            };
            {
                let mut p = pass(&mut chunk, "walk", slots[0]);
                p.set_pipeline(&self.pipelines.gather);
                p.set_bind_group(0, walk, &[]);
                p.dispatch_workgroups(*walk_groups, 1, 1);
            }
            {
                let mut p = pass(&mut chunk, "size items", slots[1]);
                p.set_pipeline(&self.pipelines.size_items);
                p.set_bind_group(0, &item_binds[k][1], &[]);
                p.dispatch_workgroups(1, 1, 1);
            }
            {
                let mut p = pass(&mut chunk, "items", slots[2]);
                p.set_pipeline(&self.pipelines.gather_items);
                p.set_bind_group(0, &item_binds[k][0], &[]);
                p.dispatch_workgroups_indirect(&self.item_dispatch, 0);
            }
            {
                let mut p = pass(&mut chunk, "join", slots[3]);
                p.set_pipeline(&self.pipelines.join_items);
                p.set_bind_group(0, join, &[]);
                p.dispatch_workgroups(*join_groups, 1, 1);
            }
            if k + 1 == chunks {
                let mut p = pass(&mut chunk, "gathered", gathered_slot);
                p.set_pipeline(&self.pipelines.gathered);
                p.set_bind_group(0, &gathered, &[]);
                p.dispatch_workgroups((count as u32).div_ceil(BOOK_WORKGROUP).max(1), 1, 1);
            }
            gpu.queue.submit([chunk.finish()]);
            let mut traffic = self.traffic.get();
            traffic.submissions += 1;
            self.traffic.set(traffic);
        }
        self.round_passes += 1;
        self.round_upload += kernel_start - upload_start;
        Ok(true)
    }

    /// Drops the round sent so far: the round's sums zeroed (a submission,
    /// not waited for), nothing of it left to book.
    fn drop_round(&mut self) {
        let mut encoder = self.encoder("drop round");
        encoder.clear_buffer(&self.round_irradiance, 0, None);
        encoder.clear_buffer(&self.round_direct, 0, None);
        self.gpu.queue.submit([encoder.finish()]);
        let mut traffic = self.traffic.get();
        traffic.submissions += 1;
        self.traffic.set(traffic);
        self.leaves.clear();
        self.round_passes = 0;
        self.round_upload = std::time::Duration::ZERO;
        if let Some(timer) = self.timer.as_mut() {
            timer.stages(&[]);
        }
    }

    /// The round's book-keeping and readback (inside an error scope).
    fn book_round(&mut self) -> Result<Booked, DeviceError> {
        let gpu = self.gpu.clone();
        let upload_start = Instant::now();
        let leaves = std::mem::take(&mut self.leaves);
        self.leave_buffer
            .write(&gpu, bytemuck::cast_slice(&nonempty(leaves.clone())));
        let book = GpuBook {
            count: leaves.len() as u32,
            fraction: self.fraction,
            ..self.book_data(1.0, DVec3::ZERO)
        };
        let book = uniform(&self.gpu, "book", &book);
        let leave = self.bind(
            &self.pipelines.leave_shooters,
            &[
                entry(G::Unshot, &self.unshot),
                entry(G::Leaves, &self.leave_buffer.buffer),
                entry(G::Book, &book),
            ],
        );
        let receive = self.bind(
            &self.pipelines.receive,
            &[
                entry(G::Elements, &self.element_buffer),
                entry(G::RoundIrradiance, &self.round_irradiance),
                entry(G::Unshot, &self.unshot),
                entry(G::ElementBook, &self.element_book),
                entry(G::Partials, &self.partials),
                entry(G::Book, &book),
            ],
        );
        let accumulate = self.bind(
            &self.pipelines.accumulate,
            &[
                entry(G::Total, &self.total),
                entry(G::RoundIrradiance, &self.round_irradiance),
                entry(G::RoundDirect, &self.round_direct),
                entry(G::Book, &book),
                entry(G::DirectTotal, &self.direct),
            ],
        );
        let powers = self.bind(
            &self.pipelines.shooter_powers,
            &[
                entry(G::Unshot, &self.unshot),
                entry(G::ElementBook, &self.element_book),
                entry(G::ShooterItems, &self.shooter_items),
                entry(G::Items, &self.items),
                entry(G::Powers, &self.powers),
                entry(G::Book, &book),
            ],
        );
        let choose = self.bind(
            &self.pipelines.choose_next,
            &[
                entry(G::ShooterItems, &self.shooter_items),
                entry(G::Powers, &self.powers),
                entry(G::Book, &book),
                entry(G::Next, &self.next),
                entry(G::RoundOffsets, &self.round_offsets),
            ],
        );
        let collect = self.bind(
            &self.pipelines.collect_next,
            &[
                entry(G::Unshot, &self.unshot),
                entry(G::Items, &self.items),
                entry(G::ShooterItems, &self.shooter_items),
                entry(G::ItemShooter, &self.item_shooter),
                entry(G::RoundOffsets, &self.round_offsets),
                entry(G::Book, &book),
                entry(G::NextUnshot, &self.next_unshot),
            ],
        );
        let kernel_start = Instant::now();
        let mut encoder = self.encoder("book");
        let count = self.order.len() as u32;
        let stages: [(&wgpu::ComputePipeline, &wgpu::BindGroup, u32); 4] = [
            (
                &self.pipelines.leave_shooters,
                &leave,
                (leaves.len() as u32).div_ceil(BOOK_WORKGROUP).max(1),
            ),
            (
                &self.pipelines.receive,
                &receive,
                self.elements.div_ceil(BOOK_WORKGROUP).max(1),
            ),
            (
                &self.pipelines.accumulate,
                &accumulate,
                count.div_ceil(BOOK_WORKGROUP).max(1),
            ),
            (
                &self.pipelines.shooter_powers,
                &powers,
                self.shooters.div_ceil(WORKGROUP).max(1),
            ),
        ];
        // A pass a stage: each reads what the one before wrote.
        for (pipeline, group, workgroups) in stages {
            let slot = self.timer.as_mut().and_then(|t| t.slot(Stage::Book));
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("book"),
                timestamp_writes: self.timestamps(slot),
            });
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, group, &[]);
            pass.dispatch_workgroups(workgroups, 1, 1);
        }
        // The next round and its elements' unshot radiosity, read back
        // with the ledger: the next round waits for nothing else.
        let next_stages = [
            (&self.pipelines.choose_next, &choose, 1),
            (
                &self.pipelines.collect_next,
                &collect,
                self.elements.div_ceil(BOOK_WORKGROUP).max(1),
            ),
        ];
        for (pipeline, group, workgroups) in next_stages {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("next"),
                timestamp_writes: None,
            });
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, group, &[]);
            pass.dispatch_workgroups(workgroups, 1, 1);
        }
        let powers_bytes = 4 * u64::from(self.shooters);
        let partial_count = u64::from(self.elements.div_ceil(BOOK_WORKGROUP).max(1));
        let partial_bytes = partial_count * size_of::<GpuPartial>() as u64;
        let counter_bytes = 4 * COUNTERS as u64;
        if powers_bytes > 0 {
            encoder.copy_buffer_to_buffer(&self.powers, 0, &self.readback, 0, powers_bytes);
        }
        encoder.copy_buffer_to_buffer(
            &self.partials,
            0,
            &self.readback,
            powers_bytes,
            partial_bytes,
        );
        encoder.copy_buffer_to_buffer(
            &self.counters,
            0,
            &self.readback,
            powers_bytes + partial_bytes,
            counter_bytes,
        );
        let next_at = powers_bytes + partial_bytes + counter_bytes;
        let next_unshot_bytes = 16 * u64::from(self.prefetch);
        encoder.copy_buffer_to_buffer(&self.next, 0, &self.readback, next_at, NEXT_BYTES);
        if next_unshot_bytes > 0 {
            encoder.copy_buffer_to_buffer(
                &self.next_unshot,
                0,
                &self.readback,
                next_at + NEXT_BYTES,
                next_unshot_bytes,
            );
        }
        let timestamps_at = next_at + NEXT_BYTES + next_unshot_bytes;
        let mut read = timestamps_at;
        if let Some(timer) = &self.timer
            && !timer.slots.is_empty()
        {
            let queries = 2 * timer.slots.len() as u32;
            encoder.resolve_query_set(&timer.set, 0..queries, &timer.resolve, 0);
            let bytes = 8 * u64::from(queries);
            encoder.copy_buffer_to_buffer(&timer.resolve, 0, &self.readback, read, bytes);
            read += bytes;
        }
        let bytes = self.finish(encoder, read)?;
        let stages = self
            .timer
            .as_mut()
            .and_then(|timer| timer.stages(&bytes[timestamps_at as usize..]));
        let upload_time = std::mem::take(&mut self.round_upload) + (kernel_start - upload_start);
        self.round_passes = 0;
        let readback_start = Instant::now();
        let words: &[f32] = bytemuck::cast_slice(&bytes);
        let shooter_power = words[..self.shooters as usize]
            .iter()
            .map(|&p| f64::from(p))
            .collect();
        let partials: &[GpuPartial] = bytemuck::cast_slice(
            &bytes[powers_bytes as usize..(powers_bytes + partial_bytes) as usize],
        );
        let (mut incident, mut absorbed, mut unshot_power, mut unshot_magnitude) =
            (DVec3::ZERO, DVec3::ZERO, DVec3::ZERO, DVec3::ZERO);
        for p in partials {
            incident += dvec3(&p.incident);
            absorbed += dvec3(&p.absorbed);
            unshot_power += dvec3(&p.unshot);
            unshot_magnitude += dvec3(&p.magnitude);
        }
        let counts: &[u32] =
            bytemuck::cast_slice(&bytes[(powers_bytes + partial_bytes) as usize..]);
        let next: &[u32] =
            bytemuck::cast_slice(&bytes[next_at as usize..(next_at + NEXT_BYTES) as usize]);
        let (next_shooters, next_count) = (next[1] as usize, next[2] as usize);
        let next_words: &[f32] =
            bytemuck::cast_slice(&bytes[(next_at + NEXT_BYTES) as usize..timestamps_at as usize]);
        let next_round = (next_count <= self.prefetch as usize).then(|| NextRound {
            shooters: next_shooters,
            unshot: next_words[..4 * next_count]
                .chunks_exact(4)
                .map(dvec3)
                .collect(),
        });
        // Room for twice the largest round so far: rounds grow as the
        // light spreads over more shooters of like power.
        self.prefetch = self
            .prefetch
            .max(next[2].saturating_mul(2))
            .min(self.elements);
        Ok(Booked {
            received: Received { incident, absorbed },
            unshot_power,
            unshot_magnitude,
            shooter_power,
            pairs: u64::from(counts[counter::PAIRS]),
            rays: u64::from(counts[counter::RAYS]),
            walks: u64::from(counts[counter::WALKS]),
            node_visits: u64::from(counts[counter::VISITS]),
            element_sources: u64::from(counts[counter::ELEMENTS]),
            longest_walk: u64::from(counts[counter::ROUND_LONGEST_WALK]),
            longest_item: u64::from(counts[counter::ROUND_LONGEST_ITEM]),
            next_round,
            upload_time,
            kernel_time: readback_start - kernel_start,
            readback_time: readback_start.elapsed(),
            stages,
        })
    }
}

impl AdaptiveTransfers for GpuTransfers {
    fn traffic(&self) -> Traffic {
        self.traffic.get()
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
        let gpu = self.gpu.clone();
        self.wanted.write(&gpu, bytemuck::cast_slice(elements));
        self.scoped(|| {
            let book = self.book_uniform(elements.len() as u32, 1.0, DVec3::ZERO);
            let group = self.bind(
                &self.pipelines.collect,
                &[
                    entry(G::Unshot, &self.unshot),
                    entry(G::Wanted, &self.wanted.buffer),
                    entry(G::Staging, &self.staging),
                    entry(G::Book, &book),
                ],
            );
            let mut encoder = self.encoder("collect");
            {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("collect"),
                    timestamp_writes: None,
                });
                pass.set_pipeline(&self.pipelines.collect);
                pass.set_bind_group(0, &group, &[]);
                pass.dispatch_workgroups((elements.len() as u32).div_ceil(BOOK_WORKGROUP), 1, 1);
            }
            let bytes = 16 * elements.len() as u64;
            encoder.copy_buffer_to_buffer(&self.staging, 0, &self.readback, 0, bytes);
            let data = self.finish(encoder, bytes)?;
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
