//! What a solve on the GPU binds, made once a solve (adaptive shooting,
//! beyond the paper: the per-receiver source subdivision of Wallace,
//! Elmquist & Haines 1989, section 4, run in rounds on the device): the
//! uniforms are buffers of the solve that each pass and each round's end
//! rewrite through the queue (a write lands before the next submission and
//! after the ones before it), and the bind groups of every kernel are made
//! once and again only when a buffer they read had to grow (sources, bins,
//! leaves, wanted: by powers of two, so a few times a solve). What was made
//! after the setup is counted
//! ([`radiosity::solver::device::Traffic::made`]).

use std::sync::Arc;

use super::GpuTransfers;
use crate::Gpu;
use crate::gather::buffers::{GpuBook, GpuShot};
use crate::shaders::GatherBinding as G;
use crate::wgpu_io::entry;

/// The solve's uniform buffers, rewritten in place.
pub(super) struct Uniforms {
    /// Each chunk of receivers' walk parameters (`Shot`).
    pub(super) shots: Vec<wgpu::Buffer>,
    /// A pass's book-keeping: its sign and direct share (`gathered`).
    pub(super) pass_book: wgpu::Buffer,
    /// The round's end: the leaves and the round rule's fraction.
    pub(super) round_book: wgpu::Buffer,
    /// The elements the host asks for (`collect`).
    pub(super) wanted_book: wgpu::Buffer,
}

impl Uniforms {
    /// Uniforms for a solve whose receivers go in `chunks` dispatches.
    pub(super) fn new(gpu: &Gpu, chunks: usize) -> Uniforms {
        let make = |label: &str, size: usize| {
            gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        Uniforms {
            shots: (0..chunks.max(1))
                .map(|_| make("shot", size_of::<GpuShot>()))
                .collect(),
            pass_book: make("pass book", size_of::<GpuBook>()),
            round_book: make("round book", size_of::<GpuBook>()),
            wanted_book: make("wanted book", size_of::<GpuBook>()),
        }
    }
}

/// A chunk of receivers' bind groups: the walk, the items and their
/// sizing, the join (they read the sources and the bins).
pub(super) struct ChunkBinds {
    pub(super) walk: wgpu::BindGroup,
    pub(super) items: wgpu::BindGroup,
    pub(super) size: wgpu::BindGroup,
    pub(super) join: wgpu::BindGroup,
}

/// The bind groups of the kernels that read no growing buffer.
pub(super) struct FixedBinds {
    pub(super) gathered: wgpu::BindGroup,
    pub(super) receive: wgpu::BindGroup,
    pub(super) accumulate: wgpu::BindGroup,
    pub(super) powers: wgpu::BindGroup,
    pub(super) large_powers: wgpu::BindGroup,
    pub(super) choose: wgpu::BindGroup,
    pub(super) collect_next: wgpu::BindGroup,
}

/// The bind groups made so far, each until a buffer it reads grows.
#[derive(Default)]
pub(super) struct Binds {
    chunks: Option<Arc<Vec<ChunkBinds>>>,
    fixed: Option<Arc<FixedBinds>>,
    /// `leave_shooters`' (reads the leaves).
    leave: Option<Arc<wgpu::BindGroup>>,
    /// `collect`'s (reads the wanted elements).
    collect: Option<Arc<wgpu::BindGroup>>,
}

impl GpuTransfers {
    /// Writes `bytes` to the growing buffer `which`, dropping the bind
    /// groups that read the old one if it grew.
    pub(super) fn write_growing(&mut self, which: Which, bytes: &[u8]) {
        let gpu = self.gpu.clone();
        let buffer = match which {
            Which::Sources => &mut self.sources,
            Which::Bins => &mut self.bins,
            Which::Leaves => &mut self.leave_buffer,
            Which::Wanted => &mut self.wanted,
        };
        if buffer.write(&gpu, bytes) {
            match which {
                Which::Sources | Which::Bins => self.binds.chunks = None,
                Which::Leaves => self.binds.leave = None,
                Which::Wanted => self.binds.collect = None,
            }
            self.count_made(1);
        }
    }

    fn count_made(&self, objects: u64) {
        let mut traffic = self.traffic.get();
        traffic.made += objects;
        self.traffic.set(traffic);
    }

    /// The bind groups in `slot` of the cache, made by `make` (counting
    /// `count` of them made) where there are none.
    fn cached<T>(
        &mut self,
        slot: fn(&mut Binds) -> &mut Option<Arc<T>>,
        count: impl Fn(&T) -> u64,
        make: impl FnOnce(&Self) -> T,
    ) -> Arc<T> {
        if let Some(value) = slot(&mut self.binds) {
            return value.clone();
        }
        let value = make(self);
        self.count_made(count(&value));
        let value = Arc::new(value);
        *slot(&mut self.binds) = Some(value.clone());
        value
    }

    /// The chunks' bind groups.
    pub(super) fn chunk_binds(&mut self) -> Arc<Vec<ChunkBinds>> {
        self.cached(|b| &mut b.chunks, |c| 4 * c.len() as u64, Self::make_chunks)
    }

    /// The bind groups that read no growing buffer.
    pub(super) fn fixed_binds(&mut self) -> Arc<FixedBinds> {
        self.cached(|b| &mut b.fixed, |_| 7, Self::make_fixed)
    }

    /// `leave_shooters`' bind group.
    pub(super) fn leave_bind(&mut self) -> Arc<wgpu::BindGroup> {
        self.cached(
            |b| &mut b.leave,
            |_| 1,
            |t| {
                t.bind(
                    &t.pipelines.leave_shooters,
                    &[
                        entry(G::Unshot, &t.unshot),
                        entry(G::Leaves, &t.leave_buffer.buffer),
                        entry(G::Book, &t.uniforms.round_book),
                    ],
                )
            },
        )
    }

    /// `collect`'s bind group.
    pub(super) fn collect_bind(&mut self) -> Arc<wgpu::BindGroup> {
        self.cached(
            |b| &mut b.collect,
            |_| 1,
            |t| {
                t.bind(
                    &t.pipelines.collect,
                    &[
                        entry(G::Unshot, &t.unshot),
                        entry(G::Wanted, &t.wanted.buffer),
                        entry(G::Staging, &t.staging),
                        entry(G::Book, &t.uniforms.wanted_book),
                    ],
                )
            },
        )
    }

    fn make_chunks(&self) -> Vec<ChunkBinds> {
        let p = &self.pipelines;
        self.uniforms
            .shots
            .iter()
            .map(|shot| {
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
                    entry(G::Shot, shot),
                    entry(G::Counters, &self.counters),
                    entry(G::Panes, &self.panes),
                    entry(G::Split, &self.split),
                ];
                ChunkBinds {
                    walk: self.bind(
                        &p.gather,
                        &[
                            &walk_entries[..],
                            &[entry(G::ShotIrradiance, &self.shot_irradiance)],
                        ]
                        .concat(),
                    ),
                    items: self.bind(&p.gather_items, &walk_entries),
                    size: self.bind(
                        &p.size_items,
                        &[
                            entry(G::Shot, shot),
                            entry(G::Counters, &self.counters),
                            entry(G::ItemDispatch, &self.item_dispatch),
                        ],
                    ),
                    join: self.bind(
                        &p.join_items,
                        &[
                            entry(G::ShotIrradiance, &self.shot_irradiance),
                            entry(G::Shot, shot),
                            entry(G::Counters, &self.counters),
                            entry(G::Split, &self.split),
                        ],
                    ),
                }
            })
            .collect()
    }

    fn make_fixed(&self) -> FixedBinds {
        let p = &self.pipelines;
        let book = &self.uniforms.round_book;
        // What the shooters' powers read, small and large.
        let powers = [
            entry(G::Unshot, &self.unshot),
            entry(G::ElementBook, &self.element_book),
            entry(G::ShooterItems, &self.shooter_items),
            entry(G::Items, &self.items),
            entry(G::Powers, &self.powers),
            entry(G::Book, book),
        ];
        FixedBinds {
            gathered: self.bind(
                &p.gathered,
                &[
                    entry(G::ShotIrradiance, &self.shot_irradiance),
                    entry(G::RoundIrradiance, &self.round_irradiance),
                    entry(G::RoundDirect, &self.round_direct),
                    entry(G::Counters, &self.counters),
                    entry(G::Book, &self.uniforms.pass_book),
                ],
            ),
            receive: self.bind(
                &p.receive,
                &[
                    entry(G::Elements, &self.element_buffer),
                    entry(G::RoundIrradiance, &self.round_irradiance),
                    entry(G::Unshot, &self.unshot),
                    entry(G::ElementBook, &self.element_book),
                    entry(G::Partials, &self.partials),
                    entry(G::Book, book),
                ],
            ),
            accumulate: self.bind(
                &p.accumulate,
                &[
                    entry(G::Total, &self.total),
                    entry(G::RoundIrradiance, &self.round_irradiance),
                    entry(G::RoundDirect, &self.round_direct),
                    entry(G::Book, book),
                    entry(G::DirectTotal, &self.direct),
                ],
            ),
            powers: self.bind(&p.shooter_powers, &powers),
            large_powers: self.bind(
                &p.large_shooter_powers,
                &[
                    &powers[..],
                    &[entry(G::LargeShooters, &self.large_shooters)],
                ]
                .concat(),
            ),
            choose: self.bind(
                &p.choose_next,
                &[
                    entry(G::ShooterItems, &self.shooter_items),
                    entry(G::Powers, &self.powers),
                    entry(G::Book, book),
                    entry(G::Next, &self.next),
                    entry(G::RoundOffsets, &self.round_offsets),
                ],
            ),
            collect_next: self.bind(
                &p.collect_next,
                &[
                    entry(G::Unshot, &self.unshot),
                    entry(G::Items, &self.items),
                    entry(G::ShooterItems, &self.shooter_items),
                    entry(G::ItemShooter, &self.item_shooter),
                    entry(G::RoundOffsets, &self.round_offsets),
                    entry(G::Book, book),
                    entry(G::NextUnshot, &self.next_unshot),
                ],
            ),
        }
    }

    /// Writes `value` into the uniform `buffer`.
    pub(super) fn set_uniform<T: bytemuck::Pod>(&self, buffer: &wgpu::Buffer, value: &T) {
        self.gpu
            .queue
            .write_buffer(buffer, 0, bytemuck::bytes_of(value));
    }
}

/// A growing buffer of the solve ([`GpuTransfers::write_growing`]).
#[derive(Clone, Copy)]
pub(super) enum Which {
    Sources,
    Bins,
    Leaves,
    Wanted,
}
