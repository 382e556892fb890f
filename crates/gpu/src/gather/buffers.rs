//! The buffers of the transfer kernel (`gather/structs.wgsl`, beyond the paper:
//! the per-receiver source subdivision of Wallace, Elmquist & Haines 1989
//! on the GPU): each `#[repr(C)]` struct is the twin of a WGSL struct, its
//! sizes and offsets checked against naga's layout of the shader by a
//! test.

use bytemuck::{Pod, Zeroable};

/// A node of the element tree (WGSL `TreeNode`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuTreeNode {
    /// Centre.
    pub centre: [f32; 3],
    /// Bounding radius.
    pub radius: f32,
    /// Centre's round-off.
    pub centre_lo: [f32; 3],
    /// Second child, or [`NONE`](radiosity::solver::hierarchy::NONE).
    pub second: u32,
    /// Surface id, or [`NONE`](radiosity::solver::hierarchy::NONE).
    pub group: u32,
    /// Surface of its first element.
    pub surface: u32,
    /// A leaf's element.
    pub element: u32,
    /// Padding.
    pub pad0: u32,
    /// The middle of its box, less its centre.
    pub box_middle: [f32; 3],
    /// Padding.
    pub pad1: u32,
    /// Half its box's extent along each axis.
    pub box_half: [f32; 3],
    /// Padding.
    pub pad2: u32,
}

/// A surface's plane (WGSL `Surface`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuSurface {
    /// Unit normal.
    pub normal: [f32; 3],
    /// Surface id.
    pub group: u32,
    /// A corner.
    pub corner: [f32; 3],
    /// Padding.
    pub pad0: u32,
    /// The corner's round-off.
    pub corner_lo: [f32; 3],
    /// Padding.
    pub pad1: u32,
}

/// A triangle of a glass pane and its transmittance (WGSL `Pane`),
/// corners relative to the scene's centre.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuPane {
    /// First corner.
    pub a: [f32; 3],
    /// Padding.
    pub pad0: u32,
    /// Second corner.
    pub b: [f32; 3],
    /// Padding.
    pub pad1: u32,
    /// Third corner.
    pub c: [f32; 3],
    /// 1 when the edge from `c` to `a` is a diagonal inside the pane (a
    /// ray through it counts in the next triangle).
    pub pad2: u32,
    /// Fraction of the light let through, per channel.
    pub transmittance: [f32; 3],
    /// Padding.
    pub pad3: u32,
}

/// An element (WGSL `Element`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuElement {
    /// Corners (`w` unused).
    pub corners: [[f32; 4]; 4],
    /// Their round-offs.
    pub corners_lo: [[f32; 4]; 4],
    /// Centroid.
    pub centroid: [f32; 3],
    /// Its surface.
    pub surface: u32,
    /// Centroid's round-off.
    pub centroid_lo: [f32; 3],
    /// Corner count, 3 or 4.
    pub count: u32,
    /// Area.
    pub area: f32,
    /// Padding.
    pub pad0: u32,
    /// Padding.
    pub pad1: u32,
    /// Padding.
    pub pad2: u32,
}

/// A receiver (WGSL `Receiver`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuReceiver {
    /// Gathering point.
    pub point: [f32; 3],
    /// Surface id.
    pub group: u32,
    /// Point's round-off.
    pub point_lo: [f32; 3],
    /// Padding.
    pub pad0: u32,
    /// Unit normal.
    pub normal: [f32; 3],
    /// Padding.
    pub pad1: u32,
}

/// A node of the shooting subtree as a source (WGSL `NodeSource`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuNodeSource {
    /// Luminance of its unshot power.
    pub weight: f32,
    /// First of its bins.
    pub first_bin: u32,
    /// Its bins.
    pub bins: u32,
    /// Padding.
    pub pad0: u32,
    /// A leaf's unshot radiosity.
    pub unshot: [f32; 3],
    /// Padding.
    pub pad1: u32,
}

/// A bin as a corrected point source (WGSL `Bin`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuBin {
    /// Power per channel.
    pub power: [f32; 3],
    /// Its luminance.
    pub weight: f32,
    /// Unit mean normal.
    pub normal: [f32; 3],
    /// Length of the mean normal.
    pub length: f32,
    /// Power-weighted centre, relative to the shot's centre.
    pub centre: [f32; 3],
    /// Element the shadow rays start from.
    pub representative: u32,
    /// Covariance: xx, yy, zz.
    pub diagonal: [f32; 3],
    /// Dominant axis and sign of the normals.
    pub axis: u32,
    /// Covariance: xy, xz, yz.
    pub off_diagonal: [f32; 3],
    /// Padding.
    pub pad0: u32,
}

/// One dispatch of a shot (WGSL `Shot`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuShot {
    /// The shooting node.
    pub root: u32,
    /// First receiver of the dispatch.
    pub first: u32,
    /// Receivers in it.
    pub count: u32,
    /// A receiver's negligible irradiance is this times its irradiance's
    /// luminance over `mean`, if more than one.
    pub negligible: f32,
    /// The shooting node's centre.
    pub origin: [f32; 3],
    /// See `negligible`.
    pub mean: f32,
    /// The centre's round-off.
    pub origin_lo: [f32; 3],
    /// Nodes a receiver's walk leaves to other threads at most (1: none).
    pub frontier: u32,
    /// Workgroups the split walks' items are dispatched in at most.
    pub item_groups: u32,
    /// Padding to the uniform's 16-byte size.
    pub _pad: [u32; 3],
}

/// An element's book-keeping data (WGSL `ElementBook`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuElementBook {
    /// Its corners' receivers, in the device's order.
    pub corners: [u32; 4],
    /// Reflectance.
    pub rho: [f32; 3],
    /// Area.
    pub area: f32,
}

/// One workgroup's share of a shot's ledger (WGSL `Partial`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuPartial {
    /// Power received (`w` unused).
    pub incident: [f32; 4],
    /// Power absorbed.
    pub absorbed: [f32; 4],
    /// Unshot power left.
    pub unshot: [f32; 4],
    /// Unshot power left in magnitude, element by element.
    pub magnitude: [f32; 4],
}

/// A shot's book-keeping dispatches (WGSL `Book`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuBook {
    /// Elements the host asked for (`collect`), or left with a value
    /// (`leave_shooters`).
    pub count: u32,
    /// Shooters of more than `serial_items` elements
    /// (`large_shooter_powers`).
    pub large: u32,
    /// Elements.
    pub elements: u32,
    /// Receivers.
    pub receivers: u32,
    /// Shooters.
    pub shooters: u32,
    /// 1, or -1 for a pass sending negative light negated: the gathered
    /// irradiance is booked times this.
    pub sign: f32,
    /// A round takes the shooters whose power is above this fraction of
    /// the brightest's (`choose_next`).
    pub fraction: f32,
    /// A shooter of more elements has its power summed by a workgroup
    /// (`large_shooter_powers`), one of at most this many by one thread.
    pub serial_items: u32,
    /// The share of the gathered irradiance that is direct, per channel.
    pub direct: [f32; 3],
    /// Padding.
    pub pad3: u32,
}

/// What an element of a round's shooter is left with (WGSL `Leave`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuLeave {
    /// Its unshot radiosity from the round's end.
    pub value: [f32; 3],
    /// The element.
    pub element: u32,
}
