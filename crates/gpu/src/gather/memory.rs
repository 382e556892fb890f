//! What a solve keeps on the GPU (the transfers of adaptive shooting,
//! beyond the paper's CPU-only solver), estimated before it starts, so
//! that a solve the device cannot hold is refused or left to the CPU
//! before anything is uploaded.

use super::{
    GpuBin, GpuElement, GpuElementBook, GpuNodeSource, GpuPartial, GpuReceiver, GpuSurface,
    GpuTreeNode,
};
use crate::device_scene as trace;

/// What a solve keeps on the device, estimated before it starts: each
/// buffer's bytes, by name.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DeviceMemory {
    /// The buffers, largest first.
    pub buffers: Vec<(&'static str, u64)>,
}

impl DeviceMemory {
    /// The buffers of a solve of `mesh` with `receivers` receivers: the
    /// scene's triangles and their tree (at most two nodes a triangle), the
    /// element tree (at most two nodes an element), the elements with their
    /// book-keeping data and unshot radiosity, the surfaces, the receivers
    /// with their irradiance, a shot's, a round's and the readback, and a
    /// shot's sources (at most the whole tree, one bin a node; the
    /// shooters' powers, the staging of a round's shooters' elements and
    /// what they are left with at most one an element), and the split walks of a dispatch of `dispatch_receivers`
    /// receivers, each split into at most `frontier` items.
    #[must_use]
    pub fn of(
        scene: &radiosity::scene::Scene,
        mesh: &radiosity::mesh::Mesh,
        receivers: usize,
        dispatch_receivers: usize,
        frontier: u32,
    ) -> DeviceMemory {
        let triangles: usize = scene
            .surfaces
            .iter()
            .map(|s| s.polygon.len().saturating_sub(2))
            .sum();
        let elements = mesh.elements.len();
        let bytes = |count: usize, each: usize| (count * each) as u64;
        let mut buffers = vec![
            (
                "triangles",
                bytes(triangles, size_of::<trace::GpuTriangle>()),
            ),
            (
                "triangle tree",
                bytes(2 * triangles, size_of::<trace::GpuNode>()),
            ),
            (
                "element tree",
                bytes(2 * elements, size_of::<GpuTreeNode>()),
            ),
            ("elements", bytes(elements, size_of::<GpuElement>())),
            (
                "surfaces",
                bytes(scene.surfaces.len(), size_of::<GpuSurface>()),
            ),
            ("receivers", bytes(receivers, size_of::<GpuReceiver>())),
            (
                "glass panes",
                bytes(
                    scene
                        .panes
                        .iter()
                        .map(|p| p.polygon.len().saturating_sub(2))
                        .sum::<usize>()
                        .max(1),
                    size_of::<super::buffers::GpuPane>(),
                ),
            ),
            ("irradiance", bytes(receivers, 16)),
            ("shot irradiance", bytes(receivers, 16)),
            ("round irradiance", bytes(receivers, 16)),
            ("round direct irradiance", bytes(receivers, 16)),
            ("direct irradiance", bytes(receivers, 16)),
            (
                "split walks",
                super::kernels::split_bytes(receivers, dispatch_receivers, frontier),
            ),
            ("unshot radiosity", bytes(elements, 16)),
            ("element book", bytes(elements, size_of::<GpuElementBook>())),
            (
                "ledger partials",
                bytes(elements.div_ceil(256), size_of::<GpuPartial>()),
            ),
            ("shooter powers", bytes(elements, 4)),
            ("staging", bytes(elements, 16)),
            ("wanted elements", bytes(elements, 4)),
            ("round leaves", bytes(elements, 16)),
            ("next round's unshot", bytes(elements, 16)),
            ("next round's offsets", bytes(elements, 4)),
            ("item shooters", bytes(elements, 4)),
            (
                "large shooters",
                bytes(
                    elements.div_ceil(crate::shaders::SERIAL_POWER_ITEMS as usize),
                    4,
                ),
            ),
            ("readback", bytes(2 * receivers + elements, 16)),
            ("sources", bytes(2 * elements, size_of::<GpuNodeSource>())),
            ("bins", bytes(2 * elements, size_of::<GpuBin>())),
        ];
        buffers.sort_by_key(|b| std::cmp::Reverse(b.1));
        DeviceMemory { buffers }
    }

    /// All of them.
    #[must_use]
    pub fn total(&self) -> u64 {
        self.buffers.iter().map(|b| b.1).sum()
    }
}
