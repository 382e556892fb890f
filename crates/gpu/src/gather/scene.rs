//! What a solve of adaptive shooting (the per-receiver source subdivision
//! of Wallace, Elmquist & Haines 1989, section 4, beyond the paper's
//! CPU-only solver) sends the GPU once, in the kernels' layouts: the
//! scene's triangles and their BVH, the element tree, the surfaces' planes,
//! the elements with their book-keeping data, the receivers in the
//! device's order and each shooter's elements. Points are two `f32`s
//! relative to the scene's centre ([`crate::trace`]).

use glam::DVec3;
use radiosity::solver::device::AdaptiveSolve;
use radiosity::solver::hierarchy::NONE;

use super::buffers::{GpuElement, GpuElementBook, GpuPane, GpuReceiver, GpuSurface, GpuTreeNode};
use crate::device_scene::split;

/// A solve's data for the device (the scene's triangles and BVH apart:
/// [`crate::device_scene::DeviceScene`]).
pub(super) struct SceneData {
    /// The element tree.
    pub(super) tree: Vec<GpuTreeNode>,
    /// Each tree node's element if a leaf, else `NONE`.
    pub(super) leaf_element: Vec<u32>,
    /// The surfaces' planes.
    pub(super) surfaces: Vec<GpuSurface>,
    /// The elements.
    pub(super) elements: Vec<GpuElement>,
    /// The receivers, in the device's order.
    pub(super) receivers: Vec<GpuReceiver>,
    /// The elements' book-keeping data.
    pub(super) element_book: Vec<GpuElementBook>,
    /// Each shooter's items in the element tree's order, `first..last`.
    pub(super) shooter_items: Vec<[u32; 2]>,
    /// The shooter of each of the element tree's items (`NONE` for none).
    pub(super) item_shooter: Vec<u32>,
    /// The glass panes' triangles (fans of their polygons).
    pub(super) panes: Vec<GpuPane>,
}

impl SceneData {
    /// `solve`'s data, its points relative to `origin`.
    pub(super) fn of(solve: &AdaptiveSolve<'_>, origin: DVec3) -> SceneData {
        let tree = &solve.hierarchy.tree;
        let scene = solve.scene;
        let mesh = solve.mesh;

        let gpu_tree: Vec<GpuTreeNode> = tree
            .nodes
            .iter()
            .map(|n| {
                let (centre, centre_lo) = split(n.centre, origin);
                let first = tree.items[n.first as usize];
                GpuTreeNode {
                    centre,
                    radius: n.radius as f32,
                    centre_lo,
                    second: n.second,
                    group: n.group,
                    surface: mesh.elements[first as usize].surface,
                    element: if n.is_leaf() { first } else { NONE },
                    box_middle: (0.5 * (n.lo + n.hi) - n.centre).as_vec3().to_array(),
                    box_half: (0.5 * (n.hi - n.lo)).as_vec3().to_array(),
                    ..GpuTreeNode::default()
                }
            })
            .collect();
        let leaf_element = gpu_tree.iter().map(|n| n.element).collect();
        let surfaces: Vec<GpuSurface> = scene
            .surfaces
            .iter()
            .map(|s| {
                let (corner, corner_lo) =
                    split(s.polygon.first().copied().unwrap_or_default(), origin);
                GpuSurface {
                    normal: s.normal.as_vec3().to_array(),
                    group: s.group,
                    corner,
                    corner_lo,
                    ..GpuSurface::default()
                }
            })
            .collect();
        let elements: Vec<GpuElement> = mesh
            .elements
            .iter()
            .zip(&solve.hierarchy.centroids)
            .map(|(e, &c)| {
                let mut out = GpuElement {
                    surface: e.surface,
                    count: u32::from(e.corner_count),
                    area: e.area as f32,
                    ..GpuElement::default()
                };
                for (k, &v) in e.vertices().iter().enumerate() {
                    let (hi, lo) = split(mesh.vertices[v as usize].position, origin);
                    out.corners[k] = [hi[0], hi[1], hi[2], 0.0];
                    out.corners_lo[k] = [lo[0], lo[1], lo[2], 0.0];
                }
                (out.centroid, out.centroid_lo) = split(c, origin);
                out
            })
            .collect();
        let receivers: Vec<GpuReceiver> = solve
            .order
            .iter()
            .map(|&r| {
                let r = &solve.receivers[r as usize];
                let (point, point_lo) = split(r.point, origin);
                GpuReceiver {
                    point,
                    group: r.group,
                    point_lo,
                    normal: r.normal.as_vec3().to_array(),
                    ..GpuReceiver::default()
                }
            })
            .collect();

        let mut device_index = vec![0u32; solve.receivers.len()];
        for (i, &r) in solve.order.iter().enumerate() {
            device_index[r as usize] = i as u32;
        }
        let element_book: Vec<GpuElementBook> = mesh
            .elements
            .iter()
            .map(|e| {
                let mut corners = [0u32; 4];
                for (k, &v) in e.vertices().iter().enumerate() {
                    corners[k] = device_index[v as usize];
                }
                GpuElementBook {
                    corners,
                    rho: scene.surfaces[e.surface as usize].rho.as_vec3().to_array(),
                    area: e.area as f32,
                }
            })
            .collect();
        let shooter_items: Vec<[u32; 2]> = solve
            .hierarchy
            .shooters
            .iter()
            .map(|&n| {
                let node = &tree.nodes[n as usize];
                [node.first, node.last]
            })
            .collect();
        let mut item_shooter = vec![NONE; tree.items.len()];
        for (s, &[first, last]) in shooter_items.iter().enumerate() {
            item_shooter[first as usize..last as usize].fill(s as u32);
        }
        SceneData {
            item_shooter,
            tree: gpu_tree,
            leaf_element,
            surfaces,
            elements,
            receivers,
            element_book,
            shooter_items,
            panes: panes(scene, origin),
        }
    }
}

/// The scene's glass panes as triangles (fans of their convex polygons),
/// relative to `origin`.
fn panes(scene: &radiosity::scene::Scene, origin: DVec3) -> Vec<GpuPane> {
    let at = |p: DVec3| (p - origin).as_vec3().to_array();
    scene
        .panes
        .iter()
        .flat_map(|pane| {
            let p = &pane.polygon;
            let last = p.len() - 2;
            (1..=last).map(move |i| GpuPane {
                a: at(p[0]),
                b: at(p[i]),
                c: at(p[i + 1]),
                transmittance: pane.transmittance.as_vec3().to_array(),
                // The edge from c back to a is a diagonal inside the
                // polygon but for the last triangle: a ray through it
                // counts in the next triangle, whose edge from a to b it is.
                pad2: u32::from(i < last),
                ..GpuPane::default()
            })
        })
        .collect()
}
