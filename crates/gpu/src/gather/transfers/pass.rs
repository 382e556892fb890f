//! One pass of a round's shooter on the GPU (adaptive shooting, beyond
//! the paper: the per-receiver source subdivision of Wallace, Elmquist &
//! Haines 1989, section 4, as `radiosity::solver::adaptive` makes it on the
//! CPU): its sources as the kernel reads them, the receivers' walks in
//! chunks, a submission each that the host does not wait for, and what the
//! receivers gathered added to the round's sums (`gather/walk.wgsl`,
//! `book.wgsl`'s `gathered`); a round abandoned between them is dropped.

use std::time::Instant;

use glam::DVec3;

use radiosity::solver::device::{AdaptiveShot, DeviceError};
use radiosity::solver::hierarchy::NONE;

use super::GpuTransfers;
use crate::device_scene::split;
use crate::gather::WORKGROUP;
use crate::gather::buffers::{GpuBin, GpuLeave, GpuNodeSource, GpuShot};
use crate::gather::kernels::{Stage, uniform};
use crate::shaders::{BOOK_WORKGROUP, GatherBinding as G};
use crate::wgpu_io::{entry, nonempty};

impl GpuTransfers {
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

    /// One pass's commands (inside an error scope): the walk in chunks of
    /// receivers, a submission each (none runs long enough to trip a
    /// driver's watchdog, and the round can be abandoned between them),
    /// the last one also adding what the receivers gathered to the
    /// round's. False when abandoned: the round is dropped.
    pub(super) fn pass(&mut self, shot: &AdaptiveShot<'_>) -> Result<bool, DeviceError> {
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
    pub(super) fn drop_round(&mut self) {
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
}
