//! The end of a round on the GPU (design.md section 2, step 5, as
//! `radiosity::solver` books it on the host for the CPU): the shooters left
//! with what they keep, the round's light received and accumulated, the
//! shooters' powers, the next round chosen and collected (`book.wgsl`), in
//! one submission whose readback the host waits for: the ledger's sums per
//! workgroup (added in `f64`, in a fixed order), the walks' counts, the
//! round's timestamps and the next round's unshot light.

use std::time::Instant;

use glam::DVec3;
use radiosity::solver::device::{Booked, DeviceError, NextRound};
use radiosity::solver::method::Received;

use super::{GpuTransfers, NEXT_BYTES, Which};
use crate::gather::buffers::{GpuBook, GpuPartial};
use crate::gather::kernels::{Stage, dvec3};
use crate::gather::{MAX_WORKGROUPS, WORKGROUP};
use crate::shaders::BOOK_WORKGROUP;
use crate::shaders::counter::{self, COUNTERS};
use crate::wgpu_io::nonempty;

/// How many times the largest round so far the next round's readback
/// holds (a larger round's light comes back in a read of its own).
const PREFETCH_GROWTH: u32 = 4;

impl GpuTransfers {
    /// The round's book-keeping and readback (inside an error scope).
    pub(super) fn book_round(&mut self) -> Result<Booked, DeviceError> {
        let upload_start = Instant::now();
        let leaves = std::mem::take(&mut self.leaves);
        self.write_growing(
            Which::Leaves,
            bytemuck::cast_slice(&nonempty(leaves.clone())),
        );
        let book = GpuBook {
            count: leaves.len() as u32,
            fraction: self.fraction,
            ..self.book_data(1.0, DVec3::ZERO)
        };
        self.set_uniform(&self.uniforms.round_book, &book);
        let binds = self.fixed_binds();
        let leave = self.leave_bind();
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
                &binds.receive,
                self.elements.div_ceil(BOOK_WORKGROUP).max(1),
            ),
            (
                &self.pipelines.accumulate,
                &binds.accumulate,
                count.div_ceil(BOOK_WORKGROUP).max(1),
            ),
            (
                &self.pipelines.shooter_powers,
                &binds.powers,
                self.shooters.div_ceil(WORKGROUP).max(1),
            ),
        ];
        // A pass a stage: each reads what the one before wrote.
        for stage in stages {
            let slot = self.timer.as_mut().and_then(|t| t.slot(Stage::Book));
            self.dispatch(&mut encoder, "book", stage, slot);
        }
        if self.large > 0 {
            // A workgroup a large shooter, in rows within the limit.
            let slot = self.timer.as_mut().and_then(|t| t.slot(Stage::Book));
            let columns = self.large.min(MAX_WORKGROUPS);
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("large shooters' powers"),
                timestamp_writes: self.timestamps(slot),
            });
            pass.set_pipeline(&self.pipelines.large_shooter_powers);
            pass.set_bind_group(0, &binds.large_powers, &[]);
            pass.dispatch_workgroups(columns, self.large.div_ceil(columns), 1);
        }
        // The next round and its elements' unshot radiosity, read back
        // with the ledger: the next round waits for nothing else.
        let next_stages = [
            (&self.pipelines.choose_next, &binds.choose, 1),
            (
                &self.pipelines.collect_next,
                &binds.collect_next,
                self.elements.div_ceil(BOOK_WORKGROUP).max(1),
            ),
        ];
        for stage in next_stages {
            self.dispatch(&mut encoder, "next", stage, None);
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
        // Room for four times the largest round so far: rounds grow as
        // the light spreads over more shooters of like power, early on by
        // more than twice a round (the Cornell box: 49, 164, 345, 426, 919
        // elements).
        self.prefetch = self
            .prefetch
            .max(next[2].saturating_mul(PREFETCH_GROWTH))
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
