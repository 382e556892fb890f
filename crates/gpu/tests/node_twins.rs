//! The rules of the GPU's walk that judge a node or an element from a
//! receiver, each against its Rust twin through a small test kernel on the
//! device: `placement.wgsl`'s `polygon_side` (an element in front, behind
//! or across the receiver's tangent plane, in front within a graze),
//! `box_bound` (the most a node's box can send, Wallace, Elmquist & Haines
//! 1989's transfer bounded for refinement) and `faces_plane` (whether any
//! of a node can light the receiver), and `factors.wgsl`'s
//! `polygon_point_factor` (the part of an element in front of the
//! receiver as a corrected point source), against
//! `radiosity::solver::hierarchy::transfer`'s `side`, `bound`, `faces` and
//! `polygon_point_factor`. The inputs are random, with the cases that break
//! naive code drawn on purpose: polygons grazing the tangent plane,
//! coplanar with it, clipped to nothing, slivers; receivers inside a
//! node's box, on a node's plane, in its surface group. The Rust twin
//! reads the very `f32` values the device reads, in `f64`; a decision
//! within the inputs' `f32` round-off of its threshold may tip either way
//! and is left out, and each value's tolerance is stated in units of
//! `f32`'s round-off of its scale.
//!
//! Without an adapter the tests say they did not run, unless
//! `RADIOSITY_REQUIRE_GPU` is set (CI sets it): then they fail.

mod common;

use common::rng::Rng;
use common::{Case, EPS, NodeBox, case, f32s, gpu, node_box, read, run_kernel, split};
use glam::DVec3;
use radiosity::geometry;
use radiosity::solver::Receiver;
use radiosity::solver::hierarchy::transfer::{Side, bound, faces, polygon_point_factor, side};
use radiosity::solver::hierarchy::{NONE, Node};

/// The front test kernel: each case's polygon through `polygon_side`
/// (its tolerance as the graze) and, clipped to the receiver's front,
/// `polygon_point_factor`.
const FRONT_KERNEL: &str = r"
struct FrontCase {
    p: array<vec4<f32>, 4>,
    normal: vec4<f32>,
    source_normal: vec4<f32>,
    count: u32,
    tolerance: f32,
    pad0: u32,
    pad1: u32,
}

struct FrontOut {
    side: u32,
    factor: f32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(64) var<storage, read> front_cases: array<FrontCase>;
@group(0) @binding(65) var<storage, read_write> front_outs: array<FrontOut>;

@compute @workgroup_size(WORKGROUP)
fn front_twins(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= arrayLength(&front_cases)) {
        return;
    }
    let c = front_cases[i];
    var poly: Polygon;
    poly.count = c.count;
    for (var k = 0u; k < c.count; k += 1u) {
        poly.p[k] = c.p[k].xyz;
    }
    var o: FrontOut;
    o.side = polygon_side(poly, c.normal.xyz, c.tolerance);
    let part = clip(poly, c.normal.xyz, 0.0);
    o.factor = polygon_point_factor(part, c.source_normal.xyz, c.normal.xyz);
    front_outs[i] = o;
}
";

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct FrontOut {
    side: u32,
    factor: f32,
    pad: [u32; 2],
}

/// An element's side of the receiver's tangent plane and the point factor
/// of its part in front agree with their Rust twins on 8,000 random
/// polygons about a receiver, the grazing, coplanar, clipped-away and
/// sliver ones included.
#[test]
fn the_front_rules_agree_with_their_rust_twins() {
    let Some(gpu) = gpu() else {
        return;
    };
    let mut rng = Rng(0xf_2047);
    let cases: Vec<Case> = (0..8000)
        .map(|_| {
            let normal = if rng.chance(0.3) {
                DVec3::Y
            } else {
                rng.unit_vector()
            };
            case(&mut rng, read(f32s(normal)).normalize())
        })
        .collect();
    let source = radiosity_gpu::shaders::gather_source() + FRONT_KERNEL;
    let outs: Vec<FrontOut> = run_kernel(&gpu, &source, "front_twins", (64, 65), &cases);
    let (mut sides, mut across, mut factors, mut lit, mut worst) = (0, 0, 0, 0, 0.0_f64);
    for (i, (c, o)) in cases.iter().zip(&outs).enumerate() {
        let poly: Vec<DVec3> = c.p[..c.count as usize].iter().map(|p| read(*p)).collect();
        let normal = read(c.normal);
        let r = Receiver {
            point: DVec3::ZERO,
            normal,
            surface: 0,
            group: 0,
        };
        let scale = poly.iter().map(|p| p.length()).fold(0.0, f64::max);
        let graze = f64::from(c.tolerance);
        // A corner whose height is within round-off of 0 or of -graze
        // (but not on it exactly, as corners projected on an axis-aligned
        // plane are) may fall either way in f32.
        let near = |edge: f64| {
            poly.iter().any(|p| {
                let d = normal.dot(*p) + edge;
                d != 0.0 && d.abs() <= 8.0 * EPS * scale
            })
        };
        if !near(graze) && !near(0.0) {
            let expected = side(poly.iter().copied(), &r, graze);
            assert_eq!(o.side, expected as u32, "case {i}: side of {c:?}");
            sides += 1;
            across += usize::from(expected == Side::Across);
        }
        // The factor of the part in front, where the clip is decided and
        // the part is no sliver (its centroid and covariance divide by
        // its area).
        if near(0.0) {
            continue;
        }
        let mut part = Vec::new();
        geometry::clip_to_half_space(&poly, DVec3::ZERO, normal, 0.0, &mut part);
        let area = geometry::newell_area_vector(&part).length() / 2.0;
        if part.len() >= 3 && area < 1e-2 * scale * scale {
            continue;
        }
        let source_normal = read(c.source_normal);
        let expected = polygon_point_factor(&part, source_normal, &r);
        let got = f64::from(o.factor);
        factors += 1;
        lit += usize::from(expected > 0.0);
        if part.len() < 3 {
            assert_eq!(got, 0.0, "case {i}: nothing in front of {c:?}");
            continue;
        }
        // The source's distance and cosines: a round-off of the part's
        // centroid `d` moves a cosine by `|d|` round-offs, which is
        // `|d| / (n . d)` of it; the factor's scale is its area over
        // pi d^2 (the second-order correction is clamped within 50%).
        let d = part.iter().sum::<DVec3>() / part.len() as f64;
        let (a, b) = (source_normal.dot(d).abs(), normal.dot(d).abs());
        let length = d.length();
        if a <= 64.0 * EPS * scale || b <= 64.0 * EPS * scale {
            continue;
        }
        let conditioning = 1.0 + scale / a + scale / b + scale * scale / (length * length);
        let factor_scale = area / (std::f64::consts::PI * length * length);
        let error = (got - expected).abs() / (EPS * conditioning * factor_scale);
        worst = worst.max(error);
        assert!(
            error <= 16.0,
            "case {i}: factor {got} against {expected} ({error:.0} round-offs): {c:?}"
        );
    }
    eprintln!(
        "front: {sides} sides ({across} across), {factors} factors ({lit} lit), \
         worst {worst:.1} round-offs of the conditioned scale"
    );
    // The kinds drawn were met.
    assert!(sides > 6000, "{sides} sides compared of 8000");
    assert!(across > 600, "{across} across");
    assert!(factors > 5000, "{factors} factors compared");
    assert!(lit > 800, "{lit} positive factors");
}

/// The node test kernel: each (node, receiver) through `box_bound` and
/// `faces_plane`, the node and receiver made in the kernel as the
/// transfer module's structs.
const NODE_KERNEL: &str = r"
struct NodeCase {
    centre: vec4<f32>,
    centre_lo: vec4<f32>,
    box_middle: vec4<f32>,
    box_half: vec4<f32>,
    point: vec4<f32>,
    point_lo: vec4<f32>,
    normal: vec4<f32>,
    sending: vec4<f32>,
    corner: vec4<f32>,
    corner_lo: vec4<f32>,
    radius: f32,
    weight: f32,
    group: u32,
    receiver_group: u32,
}

struct NodeOut {
    bound: f32,
    faces: u32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(64) var<storage, read> node_cases: array<NodeCase>;
@group(0) @binding(65) var<storage, read_write> node_outs: array<NodeOut>;

@compute @workgroup_size(WORKGROUP)
fn node_twins(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= arrayLength(&node_cases)) {
        return;
    }
    let c = node_cases[i];
    var n: TreeNode;
    n.centre = c.centre.xyz;
    n.centre_lo = c.centre_lo.xyz;
    n.radius = c.radius;
    n.box_middle = c.box_middle.xyz;
    n.box_half = c.box_half.xyz;
    n.group = c.group;
    var r: Receiver;
    r.point = c.point.xyz;
    r.point_lo = c.point_lo.xyz;
    r.normal = c.normal.xyz;
    r.group = c.receiver_group;
    var o: NodeOut;
    o.bound = box_bound(n, c.weight, r, c.sending.xyz);
    o.faces = select(0u, 1u, faces_plane(n, r, c.sending.xyz, c.corner.xyz, c.corner_lo.xyz));
    node_outs[i] = o;
}
";

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct NodeCase {
    centre: [f32; 4],
    centre_lo: [f32; 4],
    box_middle: [f32; 4],
    box_half: [f32; 4],
    point: [f32; 4],
    point_lo: [f32; 4],
    normal: [f32; 4],
    sending: [f32; 4],
    corner: [f32; 4],
    corner_lo: [f32; 4],
    radius: f32,
    weight: f32,
    group: u32,
    receiver_group: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct NodeOut {
    bound: f32,
    faces: u32,
    pad: [u32; 2],
}

/// A node's bound and whether it faces the receiver agree with their
/// Rust twins on 8,000 random nodes and receivers: receivers inside the
/// box, beside it and far off, on the node's plane, in its group.
#[test]
fn the_node_rules_agree_with_their_rust_twins() {
    let Some(gpu) = gpu() else {
        return;
    };
    let mut rng = Rng(0xb_0c4d);
    let mut cases = Vec::new();
    let mut twins = Vec::new();
    for _ in 0..8000 {
        let NodeBox {
            lo,
            hi,
            middle,
            half,
            centre,
            radius,
        } = node_box(&mut rng);
        // The receiver: inside the box, just outside a face, or anywhere.
        let point = match rng.below(3) {
            0 => rng.point_in(lo, hi),
            1 => {
                let mut p = rng.point_in(lo, hi);
                let axis = rng.below(3);
                p[axis] = if rng.chance(0.5) { lo[axis] } else { hi[axis] }
                    + rng.range(-0.05, 0.05) * half[axis].max(0.01);
                p
            }
            _ => middle + rng.unit_vector() * rng.range(0.0, 20.0),
        };
        let normal = rng.unit_vector();
        // A node of one surface (its plane's normal and a corner on it),
        // or of several; the receiver in its group or not, sometimes on
        // its plane.
        let group = if rng.chance(0.3) { NONE } else { 7 };
        let receiver_group = if rng.chance(0.2) { 7 } else { 3 };
        let sending = rng.unit_vector();
        let corner = if rng.chance(0.2) {
            point + (rng.unit_vector() - sending * sending.dot(rng.unit_vector())) * 0.5
        } else {
            rng.point_in(lo, hi)
        };
        let weight = rng.range(0.01, 100.0);
        let (centre_hi, centre_lo) = split(centre);
        let (point_hi, point_lo) = split(point);
        let (corner_hi, corner_lo) = split(corner);
        let centre_read = read(centre_hi) + read(centre_lo);
        let case = NodeCase {
            centre: centre_hi,
            centre_lo,
            box_middle: f32s(middle - centre_read),
            box_half: f32s(half),
            point: point_hi,
            point_lo,
            normal: f32s(normal),
            sending: f32s(sending),
            corner: corner_hi,
            corner_lo,
            radius: radius as f32,
            weight: weight as f32,
            group,
            receiver_group,
        };
        // The Rust twin of the very values the device reads.
        let box_middle = centre_read + read(case.box_middle);
        let box_half = read(case.box_half);
        let node = Node {
            first: 0,
            last: 1,
            end: 1,
            second: NONE,
            area: 1.0,
            centre: centre_read,
            radius: f64::from(case.radius),
            lo: box_middle - box_half,
            hi: box_middle + box_half,
            group,
        };
        let r = Receiver {
            point: read(point_hi) + read(point_lo),
            normal: read(case.normal),
            surface: 0,
            group: receiver_group,
        };
        let plane_normal = read(case.sending);
        let plane_corner = read(corner_hi) + read(corner_lo);
        twins.push((node, r, plane_normal, plane_corner, f64::from(case.weight)));
        cases.push(case);
    }
    let source = radiosity_gpu::shaders::gather_source() + NODE_KERNEL;
    let outs: Vec<NodeOut> = run_kernel(&gpu, &source, "node_twins", (64, 65), &cases);
    let (mut facing, mut turned, mut inside, mut bounded, mut worst) = (0, 0, 0, 0, 0.0_f64);
    for (i, ((node, r, plane_normal, corner, weight), o)) in twins.iter().zip(&outs).enumerate() {
        let one_surface = node.group != NONE;
        let size = node.radius
            + node.centre.length()
            + r.point.length()
            + corner.length()
            + (node.hi - node.lo).length();
        let margin = 64.0 * EPS * size;
        // Faces: decided unless the receiver's plane or the node's plane
        // is within round-off of its threshold.
        let h = r.normal.dot(node.centre - r.point);
        let offset = plane_normal.dot(*corner);
        let on_plane = (plane_normal.dot(r.point) - offset).abs() <= margin;
        if (h + node.radius).abs() > margin && !(one_surface && on_plane) {
            let plane = one_surface.then_some((*plane_normal, offset));
            let expected = faces(node, r, plane);
            assert_eq!(o.faces == 1, expected, "case {i}: faces {node:?} {r:?}");
            facing += usize::from(expected);
            turned += usize::from(!expected);
        }
        // The bound: infinite inside the box (a huge f32 on the device);
        // outside, within round-off of the clearance's scale: a clamp's
        // ratio moves by `size / clearance` round-offs.
        let sending = one_surface.then_some(*plane_normal);
        let expected = bound(node, *weight, r, sending);
        let clearance = (node.lo - r.point)
            .max(r.point - node.hi)
            .max(DVec3::ZERO)
            .length();
        if clearance <= margin {
            if clearance == 0.0 {
                assert!(expected.is_infinite() && o.bound >= 1e38, "case {i}");
                inside += 1;
            }
            continue;
        }
        let got = f64::from(o.bound);
        let most = weight / (std::f64::consts::PI * clearance * clearance);
        let error = (got - expected).abs() / (EPS * most * (1.0 + size / clearance));
        worst = worst.max(error);
        assert!(
            error <= 16.0,
            "case {i}: bound {got} against {expected} ({error:.0} round-offs)"
        );
        bounded += usize::from(expected > 0.0);
    }
    eprintln!(
        "nodes: {facing} facing, {turned} turned away, {inside} inside, {bounded} bounded, \
         worst {worst:.1} round-offs of the conditioned scale"
    );
    assert!(facing > 2000, "{facing} facing");
    assert!(turned > 1500, "{turned} turned away");
    assert!(inside > 1500, "{inside} inside the box");
    assert!(bounded > 2000, "{bounded} positive bounds");
}
