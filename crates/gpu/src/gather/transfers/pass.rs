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

use super::{GpuTransfers, Which};
use crate::device_scene::split;
use crate::gather::WORKGROUP;
use crate::gather::buffers::{GpuBin, GpuBook, GpuLeave, GpuNodeSource, GpuShot};
use crate::gather::kernels::Stage;
use crate::shaders::BOOK_WORKGROUP;
use crate::wgpu_io::nonempty;

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
        self.write_growing(Which::Sources, bytemuck::cast_slice(&nonempty(nodes)));
        self.write_growing(Which::Bins, bytemuck::cast_slice(&nonempty(bins)));
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
        let book = GpuBook {
            count: 0,
            ..self.book_data(shot.sign, shot.direct)
        };
        self.set_uniform(&self.uniforms.pass_book, &book);
        let mut encoder = self.encoder("pass");
        if self.round_passes == 0 {
            encoder.clear_buffer(&self.counters, 0, None);
        }
        // Each chunk's receivers, in its uniform.
        let mut groups = Vec::new();
        for (k, start) in (0..count).step_by(self.dispatch_receivers).enumerate() {
            let n = self.dispatch_receivers.min(count - start);
            let parameters = GpuShot {
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
            };
            self.set_uniform(&self.uniforms.shots[k], &parameters);
            groups.push((n as u32).div_ceil(WORKGROUP));
        }
        let chunk_binds = self.chunk_binds();
        let gathered = self.fixed_binds();
        let kernel_start = Instant::now();
        let chunks = groups.len();
        let mut encoder = Some(encoder);
        for (k, (&workgroups, chunk)) in groups.iter().zip(chunk_binds.iter()).enumerate() {
            if k > 0 && shot.abort.fired() {
                self.drop_round();
                return Ok(false);
            }
            let mut commands = encoder.take().unwrap_or_else(|| self.encoder("walk"));
            // A pass each: the walks, the items' workgroups, the items
            // the walks left, the joins.
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
                let mut p = pass(&mut commands, "walk", slots[0]);
                p.set_pipeline(&self.pipelines.gather);
                p.set_bind_group(0, &chunk.walk, &[]);
                p.dispatch_workgroups(workgroups, 1, 1);
            }
            {
                let mut p = pass(&mut commands, "size items", slots[1]);
                p.set_pipeline(&self.pipelines.size_items);
                p.set_bind_group(0, &chunk.size, &[]);
                p.dispatch_workgroups(1, 1, 1);
            }
            {
                let mut p = pass(&mut commands, "items", slots[2]);
                p.set_pipeline(&self.pipelines.gather_items);
                p.set_bind_group(0, &chunk.items, &[]);
                p.dispatch_workgroups_indirect(&self.item_dispatch, 0);
            }
            {
                let mut p = pass(&mut commands, "join", slots[3]);
                p.set_pipeline(&self.pipelines.join_items);
                p.set_bind_group(0, &chunk.join, &[]);
                p.dispatch_workgroups(workgroups, 1, 1);
            }
            if k + 1 == chunks {
                let mut p = pass(&mut commands, "gathered", gathered_slot);
                p.set_pipeline(&self.pipelines.gathered);
                p.set_bind_group(0, &gathered.gathered, &[]);
                p.dispatch_workgroups((count as u32).div_ceil(BOOK_WORKGROUP).max(1), 1, 1);
            }
            gpu.queue.submit([commands.finish()]);
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
