//! The scene on the device (beyond the paper): the surfaces' triangles
//! (fans of each convex polygon) relative to the scene's centre, each
//! coordinate a pair of `f32`s (the nearest and its round-off), and the
//! CPU's own BVH over them ([`FlatTree`]), in the layouts the kernels read
//! (`trace/walk.wgsl`, the trace and gather kernels); built and uploaded once a scene and
//! shared by every solve on the same device.

use std::sync::Arc;

use bytemuck::{Pod, Zeroable};
use glam::DVec3;
use radiosity::accel::bvh::{BvhSettings, FlatTree};
use radiosity::scene::Surface;

use crate::Gpu;
use crate::wgpu_io::{nonempty, storage};

/// A BVH node as the kernel reads it (WGSL `Node`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuNode {
    /// Low corner.
    pub lo: [f32; 3],
    /// Interior: right child. Leaf: first triangle.
    pub link: u32,
    /// High corner.
    pub hi: [f32; 3],
    /// Interior: `FLAT_INTERIOR` | axis. Leaf: triangle count.
    pub kind: u32,
}

/// A triangle as the kernel reads it (WGSL `Triangle`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuTriangle {
    /// First corner.
    pub a: [f32; 3],
    /// Its surface id ([`Surface::group`]).
    pub group: u32,
    /// Second corner.
    pub b: [f32; 3],
    /// Padding.
    pub pad0: u32,
    /// Third corner.
    pub c: [f32; 3],
    /// Padding.
    pub pad1: u32,
    /// First corner's round-off: `a + a_lo` is the corner.
    pub a_lo: [f32; 3],
    /// Padding.
    pub pad2: u32,
    /// Second corner's round-off.
    pub b_lo: [f32; 3],
    /// Padding.
    pub pad3: u32,
    /// Third corner's round-off.
    pub c_lo: [f32; 3],
    /// Padding.
    pub pad4: u32,
    /// The surface's unit normal.
    pub normal: [f32; 3],
    /// Padding.
    pub pad5: u32,
}

/// A scene's triangles and their BVH on the device, in the kernels'
/// layouts: built and uploaded once a scene, and shared by the kernels of
/// every solve on the same [`Gpu`] (the coarse pass of receiver
/// refinement, the solve that goes on from it, the lights' segments).
pub(crate) struct DeviceScene {
    /// The scene's centre, the origin of the device's coordinates.
    pub(crate) origin: DVec3,
    /// The BVH's nodes.
    pub(crate) nodes: wgpu::Buffer,
    /// The triangles, in its leaves' order.
    pub(crate) triangles: wgpu::Buffer,
    /// How many triangles.
    pub(crate) count: usize,
    /// A hash of the triangles the scene was made of, and the origin.
    key: u64,
}

impl DeviceScene {
    /// `surfaces`' triangles and BVH on `gpu`: the scene `gpu` last held
    /// if it is the same, else built, uploaded and kept for the next solve.
    pub(crate) fn of(gpu: &Gpu, surfaces: &[Surface]) -> Arc<DeviceScene> {
        use std::hash::{Hash, Hasher};
        let (origin, scale) = centre_and_scale(surfaces);
        let triangles = triangles(surfaces, origin);
        let mut hasher = std::collections::hash_map::DefaultHasher::new();
        bytemuck::cast_slice::<GpuTriangle, u8>(&triangles).hash(&mut hasher);
        origin.to_array().map(f64::to_bits).hash(&mut hasher);
        let key = hasher.finish();
        let mut cache = gpu
            .scene
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some(scene) = cache.as_ref()
            && scene.key == key
            && scene.count == triangles.len()
        {
            return scene.clone();
        }
        // A few f32 round-offs of the scene's size: the slab test's error.
        let pad = 8.0 * f64::from(f32::EPSILON) * scale;
        let (nodes, ordered) = tree(&triangles, pad);
        // An empty buffer cannot be bound: one unused element instead.
        let scene = Arc::new(DeviceScene {
            origin,
            nodes: storage(gpu, "nodes", &nonempty(nodes)),
            triangles: storage(gpu, "triangles", &nonempty(ordered)),
            count: triangles.len(),
            key,
        });
        *cache = Some(scene.clone());
        scene
    }
}

/// `p - origin` as two `f32`s: the nearest, and what rounding it lost.
pub(crate) fn split(p: DVec3, origin: DVec3) -> ([f32; 3], [f32; 3]) {
    let r = p - origin;
    let hi = r.as_vec3();
    (hi.to_array(), (r - hi.as_dvec3()).as_vec3().to_array())
}

/// The triangles of `surfaces` (fans of each convex polygon) relative to
/// `origin`.
pub(crate) fn triangles(surfaces: &[Surface], origin: DVec3) -> Vec<GpuTriangle> {
    surfaces
        .iter()
        .flat_map(|s| {
            let p = &s.polygon;
            (1..p.len().saturating_sub(1)).map(move |i| {
                let (a, a_lo) = split(p[0], origin);
                let (b, b_lo) = split(p[i], origin);
                let (c, c_lo) = split(p[i + 1], origin);
                GpuTriangle {
                    a,
                    group: s.group,
                    b,
                    c,
                    a_lo,
                    b_lo,
                    c_lo,
                    normal: s.normal.as_vec3().to_array(),
                    ..GpuTriangle::default()
                }
            })
        })
        .collect()
}

/// The tree over `triangles` (boxes of their `f32` corners padded by
/// `pad`), its nodes for the kernel, and the triangles in leaf order.
pub(crate) fn tree(triangles: &[GpuTriangle], pad: f64) -> (Vec<GpuNode>, Vec<GpuTriangle>) {
    let boxes: Vec<(DVec3, DVec3)> = triangles
        .iter()
        .map(|t| {
            let corners = [t.a, t.b, t.c].map(|c| DVec3::from(c.map(f64::from)));
            let lo = corners[0].min(corners[1]).min(corners[2]);
            let hi = corners[0].max(corners[1]).max(corners[2]);
            (lo - DVec3::splat(pad), hi + DVec3::splat(pad))
        })
        .collect();
    let flat = FlatTree::build(&boxes, BvhSettings::sah());
    let nodes = flat
        .nodes
        .iter()
        .map(|n| GpuNode {
            lo: n.min,
            link: n.link,
            hi: n.max,
            kind: n.kind,
        })
        .collect();
    let ordered = flat
        .primitives
        .iter()
        .map(|&p| triangles[p as usize])
        .collect();
    (nodes, ordered)
}

/// The centre of the surfaces' box (the origin of the device's
/// coordinates) and its largest side.
pub(crate) fn centre_and_scale(surfaces: &[Surface]) -> (DVec3, f64) {
    let (lo, hi) = surfaces
        .iter()
        .flat_map(|s| s.polygon.iter())
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &p| {
            (lo.min(p), hi.max(p))
        });
    if lo.is_finite() && hi.is_finite() {
        (
            0.5 * (lo + hi),
            (hi - lo).max_element().max(f64::MIN_POSITIVE),
        )
    } else {
        (DVec3::ZERO, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{DeviceChoice, REQUIRE_ADAPTER};

    /// A scene is built and uploaded once a device: the same surfaces
    /// give the very scene kept, other surfaces a new one (kept in its
    /// place), and a failure forgets it.
    #[test]
    fn a_scene_is_uploaded_once_a_device() {
        let gpu = match Gpu::open(DeviceChoice::Gpu) {
            Ok(Some(gpu)) => gpu,
            other => {
                let required = std::env::var(REQUIRE_ADAPTER).is_ok_and(|v| v != "0");
                assert!(!required, "{REQUIRE_ADAPTER} is set: {other:?}");
                eprintln!("GPU test did not run: no adapter");
                return;
            }
        };
        let room = radiosity::scene::load("room").unwrap();
        let cornell = radiosity::scene::load("cornell").unwrap();
        let first = DeviceScene::of(&gpu, &room.surfaces);
        assert!(Arc::ptr_eq(&first, &DeviceScene::of(&gpu, &room.surfaces)));
        // A clone of the device shares what it keeps.
        assert!(Arc::ptr_eq(
            &first,
            &DeviceScene::of(&gpu.clone(), &room.surfaces)
        ));
        let other = DeviceScene::of(&gpu, &cornell.surfaces);
        assert!(!Arc::ptr_eq(&first, &other));
        assert!(Arc::ptr_eq(
            &other,
            &DeviceScene::of(&gpu, &cornell.surfaces)
        ));
        let kept = DeviceScene::of(&gpu, &room.surfaces);
        assert!(!Arc::ptr_eq(&first, &kept));
        gpu.forget();
        let again = DeviceScene::of(&gpu, &room.surfaces);
        assert!(!Arc::ptr_eq(&kept, &again));
        assert_eq!(again.count, first.count);
    }
}
