//! The binary tree the BVH build makes (module notes of [`super`],
//! "Layout"), before it is collapsed to the eight-wide tree the CPU walks:
//! exported for walkers of their own, such as the GPU back end's kernels,
//! which then walk exactly the tree the CPU built (beyond the paper, as the
//! BVH is; design.md section 3).

use glam::DVec3;

use super::BvhSettings;
use super::BvhStats;
use super::build::{Aabb, INTERIOR, Tree};

/// One node of a [`FlatTree`]: an `f32` box rounded outward and two words,
/// 32 bytes, in the layout the build makes (module notes, "Layout").
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlatNode {
    /// The box's low corner.
    pub min: [f32; 3],
    /// Interior: index of the right child (the left is the next node).
    /// Leaf: index of its first primitive in [`FlatTree::primitives`].
    pub link: u32,
    /// The box's high corner.
    pub max: [f32; 3],
    /// Interior: [`FLAT_INTERIOR`] | split axis. Leaf: primitive count.
    pub kind: u32,
}

/// The bit of [`FlatNode::kind`] that marks an interior node.
pub const FLAT_INTERIOR: u32 = INTERIOR;

/// The binary tree the build makes, before it is collapsed to the
/// eight-wide tree the CPU walks: for walkers of their own (the GPU back
/// end's kernels), which then walk exactly the tree the CPU built.
#[derive(Clone, Debug, Default)]
pub struct FlatTree {
    /// Depth first; the root is node 0 (none for no primitives).
    pub nodes: Vec<FlatNode>,
    /// Primitive ids, leaf by leaf in depth-first order.
    pub primitives: Vec<u32>,
    /// Its size.
    pub stats: BvhStats,
}

impl FlatTree {
    /// Builds the tree over boxes `(min, max)` (primitive `i` has box
    /// `boxes[i]`) with `settings`.
    #[must_use]
    pub fn build(boxes: &[(DVec3, DVec3)], settings: BvhSettings) -> FlatTree {
        let boxes: Vec<Aabb> = boxes.iter().map(|&(min, max)| Aabb { min, max }).collect();
        let (tree, stats) = Tree::build(&boxes, settings);
        FlatTree {
            nodes: tree
                .nodes
                .iter()
                .map(|n| FlatNode {
                    min: n.min,
                    link: n.link,
                    max: n.max,
                    kind: n.kind,
                })
                .collect(),
            primitives: tree.primitives,
            stats,
        }
    }
}
