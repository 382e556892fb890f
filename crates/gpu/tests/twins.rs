//! Each WGSL rule against its Rust twin, through a small test kernel on the
//! device: `polygon.wgsl` (the clipper, Newell's normal, the centroid and
//! the analytic factor of the paper's equation (2)), `placement.wgsl`'s
//! node placement and straddling (a node in front, behind or across a
//! receiver's tangent plane, in front within GRAZE) and `factors.wgsl`'s
//! point factor of a bin (the point-to-disk transfer of Wallace, Elmquist
//! & Haines 1989 corrected for the bin's extent). The inputs are random
//! triangles and quads around a receiver, with the cases that break naive
//! code drawn on purpose: corners on the receiver's tangent plane and
//! polygons crossing it (grazing), polygons in the plane (coplanar), behind
//! it (clipped to nothing), slivers. The Rust twin reads the same `f32`
//! inputs in `f64`, so the two differ only by the kernel's `f32`
//! arithmetic; each comparison states its tolerance in units of `f32`'s
//! round-off of the inputs' scale.
//!
//! Without an adapter the tests say they did not run, unless
//! `RADIOSITY_REQUIRE_GPU` is set (CI sets it, with Mesa's software Vulkan
//! installed): then they fail.

mod common;

use common::rng::Rng;
use common::{Case, EPS, NodeBox, case, f32s, gpu, node_box, read, run_kernel, split};
use glam::DVec3;
use radiosity::form_factor::analytic::analytic_facing;
use radiosity::geometry::{self, clip::clip_each};
use radiosity_gpu::Gpu;

/// The test kernel: each case's polygon through each rule.
const KERNEL: &str = r"
struct Case {
    p: array<vec4<f32>, 4>,
    normal: vec4<f32>,
    source_normal: vec4<f32>,
    count: u32,
    tolerance: f32,
    pad0: u32,
    pad1: u32,
}

struct Out {
    clipped: array<vec4<f32>, 6>,
    newell: vec4<f32>,
    centroid: vec4<f32>,
    clipped_count: u32,
    factor: f32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<storage, read> cases: array<Case>;
@group(0) @binding(1) var<storage, read_write> outs: array<Out>;

@compute @workgroup_size(WORKGROUP)
fn twins(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= arrayLength(&cases)) {
        return;
    }
    let c = cases[i];
    var poly: Polygon;
    poly.count = c.count;
    for (var k = 0u; k < c.count; k += 1u) {
        poly.p[k] = c.p[k].xyz;
    }
    var o: Out;
    let clipped = clip(poly, c.normal.xyz, c.tolerance);
    o.clipped_count = clipped.count;
    for (var k = 0u; k < clipped.count; k += 1u) {
        o.clipped[k] = vec4<f32>(clipped.p[k], 0.0);
    }
    o.newell = vec4<f32>(newell(poly), 0.0);
    o.centroid = vec4<f32>(centroid(poly), 0.0);
    o.factor = analytic(poly, c.normal.xyz, c.source_normal.xyz);
    outs[i] = o;
}
";

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct Out {
    clipped: [[f32; 4]; 6],
    newell: [f32; 4],
    centroid: [f32; 4],
    clipped_count: u32,
    factor: f32,
    pad: [u32; 2],
}

/// The polygon kernel's outputs for `cases`: `polygon.wgsl` alone, with
/// the prelude, and the test kernel.
fn run(gpu: &Gpu, cases: &[Case]) -> Vec<Out> {
    let source = radiosity_gpu::shaders::prelude()
        + radiosity_gpu::shaders::GATHER_FILES
            .iter()
            .find(|f| f.0 == "gather/polygon.wgsl")
            .unwrap()
            .1
        + KERNEL;
    run_kernel(gpu, &source, "twins", (0, 1), cases)
}

/// The clipper, Newell's normal, the centroid and the analytic factor on
/// the device agree with their Rust twins on 8,000 random polygons, the
/// grazing, coplanar, clipped-away and sliver ones included.
#[test]
fn the_polygon_rules_agree_with_their_rust_twins() {
    let Some(gpu) = gpu() else {
        return;
    };
    let mut rng = Rng(0x7_0715);
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
    let outs = run(&gpu, &cases);
    let (mut clipped_away, mut grazing, mut factors, mut compared) = (0, 0, 0, 0);
    for (i, (c, o)) in cases.iter().zip(&outs).enumerate() {
        let poly: Vec<DVec3> = c.p[..c.count as usize].iter().map(|p| read(*p)).collect();
        let normal = read(c.normal);
        let scale = poly.iter().map(|p| p.length()).fold(0.0, f64::max);
        // Clip: the same corners, each within 16 round-offs of the scale
        // (a crossing is interpolated from the end nearer the plane). A
        // corner within round-off of the band's edge or of the plane (but
        // not on it exactly, as corners projected on an axis-aligned plane
        // are) may fall either way in f32: those cases are left out.
        let tolerance = f64::from(c.tolerance);
        let near = |edge: f64| {
            poly.iter().any(|p| {
                let d = normal.dot(*p) + edge;
                d != 0.0 && d.abs() <= 8.0 * EPS * scale
            })
        };
        let undecided = near(tolerance) || near(0.0);
        let mut clipped = Vec::new();
        clip_each(&poly, |p| normal.dot(p), tolerance, |v| clipped.push(v));
        if !undecided {
            assert_eq!(clipped.len(), o.clipped_count as usize, "case {i}: {c:?}");
            for (k, p) in clipped.iter().enumerate() {
                let got = read(o.clipped[k]);
                assert!(
                    (got - *p).length() <= 16.0 * EPS * scale,
                    "case {i}: clipped corner {k}: {got} against {p}"
                );
            }
            clipped_away += usize::from(clipped.is_empty());
            compared += 1;
        }
        grazing += usize::from(poly.iter().any(|p| normal.dot(*p) == 0.0));
        // Newell's normal: each of its count cross products within 8
        // round-offs of scale^2.
        let newell = geometry::newell_area_vector(&poly);
        let got = read(o.newell);
        assert!(
            (got - newell).length() <= 8.0 * poly.len() as f64 * EPS * scale * scale,
            "case {i}: newell {got} against {newell}"
        );
        // The centroid, where the polygon has an area (a sliver's centroid
        // divides by it): within 64 round-offs of the scale.
        if newell.length() >= 1e-2 * scale * scale {
            let centroid = geometry::centroid(&poly);
            let got = read(o.centroid);
            assert!(
                (got - centroid).length() <= 64.0 * EPS * scale,
                "case {i}: centroid {got} against {centroid}"
            );
        }
        // The factor: within 64 round-offs (each edge's angle is a few
        // round-offs of pi), where no corner's side of the tangent plane is
        // undecided (its clip's tolerance is ON_PLANE of the scale, below
        // f32's resolution).
        if !near(0.0) {
            let source_normal = read(c.source_normal);
            let factor = analytic_facing(DVec3::ZERO, normal, &poly, source_normal);
            let got = f64::from(o.factor);
            assert!(
                (got - factor).abs() <= 64.0 * EPS,
                "case {i}: factor {got} against {factor}: {c:?}"
            );
            factors += usize::from(factor > 0.0);
        }
    }
    // The kinds drawn were met.
    // (The rest are grazing and coplanar polygons about a tilted normal,
    // whose corners' sides are round-off in f32; about an axis-aligned
    // normal they are exact, and compared.)
    assert!(compared > 5600, "{compared} clips compared of 8000");
    assert!(clipped_away > 600, "{clipped_away} polygons clipped away");
    assert!(
        grazing > 400,
        "{grazing} polygons touching the tangent plane"
    );
    assert!(factors > 1200, "{factors} positive factors");
}

/// The placement test kernel: each (node, receiver) through `placement`
/// and `straddles` (`gather/placement.wgsl`), the node and receiver made
/// in the kernel as the transfer module's structs.
const PLACEMENT_KERNEL: &str = r"
struct PlacementCase {
    centre: vec4<f32>,
    centre_lo: vec4<f32>,
    box_middle: vec4<f32>,
    box_half: vec4<f32>,
    point: vec4<f32>,
    point_lo: vec4<f32>,
    normal: vec4<f32>,
    radius: f32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(64) var<storage, read> placement_cases: array<PlacementCase>;
@group(0) @binding(65) var<storage, read_write> placement_outs: array<u32>;

@compute @workgroup_size(WORKGROUP)
fn placement_twins(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= arrayLength(&placement_cases)) {
        return;
    }
    let c = placement_cases[i];
    var n: TreeNode;
    n.centre = c.centre.xyz;
    n.centre_lo = c.centre_lo.xyz;
    n.radius = c.radius;
    n.box_middle = c.box_middle.xyz;
    n.box_half = c.box_half.xyz;
    var r: Receiver;
    r.point = c.point.xyz;
    r.point_lo = c.point_lo.xyz;
    r.normal = c.normal.xyz;
    placement_outs[i] = placement(n, r) | (select(0u, 16u, straddles(n, r)));
}
";

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct PlacementCase {
    centre: [f32; 4],
    centre_lo: [f32; 4],
    box_middle: [f32; 4],
    box_half: [f32; 4],
    point: [f32; 4],
    point_lo: [f32; 4],
    normal: [f32; 4],
    radius: f32,
    pad: [u32; 3],
}

/// A node's placement against a receiver's tangent plane and whether the
/// plane cuts its sphere, on the device, agree with the Rust rules
/// (`hierarchy::transfer::placement`, `straddles`) on 8,000 random nodes
/// and receivers, many of them grazing: the plane through the sphere, or
/// within GRAZE of the box's lowest corner.
#[test]
fn the_placement_rules_agree_with_their_rust_twins() {
    use radiosity::solver::Receiver;
    use radiosity::solver::hierarchy::transfer::{GRAZE, Side, placement, straddles};
    use radiosity::solver::hierarchy::{NONE, Node};
    let Some(gpu) = gpu() else {
        return;
    };
    let mut rng = Rng(0x9_1ace);
    let mut nodes = Vec::new();
    let mut cases = Vec::new();
    for _ in 0..8000 {
        let NodeBox {
            lo,
            hi,
            middle,
            half,
            centre,
            radius,
        } = node_box(&mut rng);
        let normal = rng.unit_vector();
        // The receiver's plane at a chosen height over the node: through
        // the sphere, near its lowest box corner, or anywhere.
        let reach = half.dot(normal.abs());
        let low = normal.dot(middle) - reach;
        let height = match rng.below(3) {
            0 => normal.dot(centre) + rng.range(-1.2, 1.2) * radius,
            1 => low + rng.range(-2.0, 2.0) * GRAZE * radius,
            _ => rng.range(-8.0, 8.0),
        };
        let along = rng.unit_vector();
        let point = normal * height + (along - normal * normal.dot(along)) * rng.range(0.0, 3.0);
        // As the device reads them, and the Rust twin the same values.
        let (centre_hi, centre_lo) = split(centre);
        let (point_hi, point_lo) = split(point);
        let normal32 = f32s(normal);
        let receiver = Receiver {
            point: read(point_hi) + read(point_lo),
            normal: read(normal32),
            surface: 0,
            group: 0,
        };
        let node = Node {
            first: 0,
            last: 1,
            end: 1,
            second: NONE,
            area: 1.0,
            centre: read(centre_hi) + read(centre_lo),
            radius: f64::from(radius as f32),
            lo,
            hi,
            group: NONE,
        };
        cases.push(PlacementCase {
            centre: centre_hi,
            centre_lo,
            box_middle: f32s(middle - node.centre),
            box_half: f32s(half),
            point: point_hi,
            point_lo,
            normal: normal32,
            radius: radius as f32,
            pad: [0; 3],
        });
        nodes.push((node, receiver));
    }
    let source = radiosity_gpu::shaders::gather_source() + PLACEMENT_KERNEL;
    let outs: Vec<u32> = run_kernel(&gpu, &source, "placement_twins", (64, 65), &cases);
    let (mut compared, mut across, mut grazing_front) = (0, 0, 0);
    for (i, ((node, r), out)) in nodes.iter().zip(&outs).enumerate() {
        // Each decision's margin in f64; one within f32's round-off of the
        // values compared may tip either way and is left out.
        let h = r.normal.dot(node.centre - r.point);
        let middle = h + r.normal.dot((node.lo + node.hi) / 2.0 - node.centre);
        let reach = r.normal.abs().dot((node.hi - node.lo) / 2.0);
        let size = node.radius + h.abs() + reach + r.point.length() + node.centre.length();
        let margins = [
            h - node.radius,
            h + node.radius,
            middle - reach + GRAZE * node.radius,
            middle + reach,
        ];
        if margins.iter().any(|m| m.abs() <= 64.0 * EPS * size) {
            continue;
        }
        compared += 1;
        let side = placement(node, r);
        let expected = side as u32 | if straddles(node, r) { 16 } else { 0 };
        assert_eq!(*out, expected, "case {i}: {node:?} {r:?}");
        across += usize::from(side == Side::Across);
        grazing_front += usize::from(side == Side::Front && middle - reach < 0.0);
    }
    assert!(compared > 7000, "{compared} of 8000 compared");
    assert!(across > 500, "{across} across");
    assert!(grazing_front > 200, "{grazing_front} in front within GRAZE");
}

/// The point factor test kernel: each (bin, receiver) through
/// `point_factor` (`gather/factors.wgsl`), the bin made in the kernel as
/// the transfer module's struct.
const POINT_FACTOR_KERNEL: &str = r"
struct PointFactorCase {
    centre: vec4<f32>,
    normal: vec4<f32>,
    diagonal: vec4<f32>,
    off_diagonal: vec4<f32>,
    from_origin: vec4<f32>,
    receiver_normal: vec4<f32>,
}

@group(0) @binding(64) var<storage, read> factor_cases: array<PointFactorCase>;
@group(0) @binding(65) var<storage, read_write> factor_outs: array<f32>;

@compute @workgroup_size(WORKGROUP)
fn point_factor_twins(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= arrayLength(&factor_cases)) {
        return;
    }
    let c = factor_cases[i];
    var b: Bin;
    b.centre = c.centre.xyz;
    b.normal = c.normal.xyz;
    b.length = c.normal.w;
    b.diagonal = c.diagonal.xyz;
    b.off_diagonal = c.off_diagonal.xyz;
    factor_outs[i] = point_factor(b, c.from_origin.xyz, c.receiver_normal.xyz);
}
";

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct PointFactorCase {
    centre: [f32; 4],
    /// The bin's mean normal, its length in `w`.
    normal: [f32; 4],
    diagonal: [f32; 4],
    off_diagonal: [f32; 4],
    from_origin: [f32; 4],
    receiver_normal: [f32; 4],
}

/// A bin's point factor, the second-order expansion of its extent
/// (`hierarchy::sources::point_factor`), on the device against its Rust
/// twin on 8,000 random bins (triangles and quads up to 2 m across, flat
/// or with their normals spread) and receivers: far, near (the expansion
/// clamped), grazing the bin's plane or the receiver's own, and behind
/// either. The Rust twin reads the device's `f32` inputs in `f64`. The
/// factor's round-off is that of `f32` in its terms, each at most the
/// bin's `length a b / (pi q^2)` or `length |C| / (pi q^2)` (`a`, `b` the
/// distances off the two planes, `q` the squared distance, `|C|` the
/// covariance's largest entry, six of them summed), times the cosines'
/// conditioning `1 + |d| / a + |d| / b` (an `f32` round-off of the offset
/// `d` moves `a` by `|d|` round-offs): the two agree within 8 `f32`
/// round-offs of that scale. Cases whose sign tests (in front of
/// the bin, the receiver facing it) are within round-off of zero are left
/// out: either answer is right there.
#[test]
fn the_point_factor_agrees_with_its_rust_twin() {
    use radiosity::solver::hierarchy::sources::PointSource;
    let Some(gpu) = gpu() else {
        return;
    };
    let mut rng = Rng(0xfac_7025);
    let mut cases = Vec::new();
    let mut twins = Vec::new();
    for _ in 0..8000 {
        // A polygon about the node's centre, in its own plane.
        let normal = rng.unit_vector();
        let u = normal.any_orthonormal_vector();
        let v = normal.cross(u);
        let size = rng.range(0.01, 2.0);
        let corners = 3 + rng.below(2);
        let centre = rng.point_in(DVec3::splat(-1.0), DVec3::splat(1.0));
        let polygon: Vec<DVec3> = (0..corners)
            .map(|k| {
                let angle =
                    std::f64::consts::TAU * (k as f64 + rng.range(0.0, 0.6)) / corners as f64;
                centre + (u * angle.cos() + v * angle.sin()) * size * rng.range(0.3, 1.0)
            })
            .collect();
        let Some((mut source, _)) = PointSource::of_polygon(&polygon, normal) else {
            continue;
        };
        // A bin of spread normals is shorter than one.
        source.length = if rng.chance(0.5) {
            1.0
        } else {
            rng.range(0.3, 1.0)
        };
        // The receiver: far, near, grazing either plane, or anywhere.
        let reach = size
            * match rng.below(3) {
                0 => rng.range(5.0, 50.0),
                1 => rng.range(0.3, 3.0),
                _ => rng.range(0.01, 10.0),
            };
        let direction = match rng.below(4) {
            // Grazing the bin's plane.
            0 => {
                let along = rng.unit_vector();
                (along - normal * normal.dot(along) + normal * rng.range(-0.02, 0.05)).normalize()
            }
            _ => rng.unit_vector(),
        };
        let point = source.centre + direction * reach;
        let facing = (source.centre - point).normalize();
        let receiver_normal = match rng.below(4) {
            // Grazing its own plane: the bin near the horizon.
            0 => {
                let side = facing.any_orthonormal_vector();
                (side + facing * rng.range(-0.02, 0.05)).normalize()
            }
            1 => (facing + rng.unit_vector() * 0.5).normalize(),
            _ => rng.unit_vector(),
        };
        let c = source.covariance;
        let case = PointFactorCase {
            centre: f32s(source.centre),
            normal: {
                let mut n = f32s(source.normal);
                n[3] = source.length as f32;
                n
            },
            diagonal: [c.x_axis.x as f32, c.y_axis.y as f32, c.z_axis.z as f32, 0.0],
            off_diagonal: [c.y_axis.x as f32, c.z_axis.x as f32, c.z_axis.y as f32, 0.0],
            from_origin: f32s(point),
            receiver_normal: f32s(receiver_normal),
        };
        // The Rust twin of the very values the device reads.
        let covariance = glam::DMat3::from_cols(
            DVec3::new(
                f64::from(case.diagonal[0]),
                f64::from(case.off_diagonal[0]),
                f64::from(case.off_diagonal[1]),
            ),
            DVec3::new(
                f64::from(case.off_diagonal[0]),
                f64::from(case.diagonal[1]),
                f64::from(case.off_diagonal[2]),
            ),
            DVec3::new(
                f64::from(case.off_diagonal[1]),
                f64::from(case.off_diagonal[2]),
                f64::from(case.diagonal[2]),
            ),
        );
        let s = read(case.normal);
        let twin = PointSource {
            centre: read(case.centre),
            normal: s,
            length: f64::from(case.normal[3]),
            covariance,
            spread: covariance * s,
            trace: covariance.x_axis.x + covariance.y_axis.y + covariance.z_axis.z,
        };
        cases.push(case);
        twins.push((twin, read(case.from_origin), read(case.receiver_normal)));
    }
    let source = radiosity_gpu::shaders::gather_source() + POINT_FACTOR_KERNEL;
    let outs: Vec<f32> = run_kernel(&gpu, &source, "point_factor_twins", (64, 65), &cases);
    let (mut compared, mut lit, mut clamped, mut worst) = (0, 0, 0, 0.0_f64);
    for ((twin, point, normal), &out) in twins.iter().zip(&outs) {
        let d = *point - twin.centre;
        let q = d.length_squared();
        let (a, b) = (twin.normal.dot(d), normal.dot(d));
        let length = d.length();
        if a.abs() <= 64.0 * EPS * length || b.abs() <= 64.0 * EPS * length {
            continue;
        }
        let expected = twin.factor(DVec3::ZERO, *point, *normal);
        let c = twin.covariance;
        let largest = c
            .x_axis
            .abs()
            .max(c.y_axis.abs())
            .max(c.z_axis.abs())
            .max_element();
        // The cosines' conditioning: an f32 round-off of `d` moves `a` by
        // `|d|` round-offs, which is `|d| / a` of it.
        let conditioning = 1.0 + length / a.abs() + length / b.abs();
        let scale = twin.length * ((a * b).abs() + 6.0 * largest) / (std::f64::consts::PI * q * q)
            * conditioning;
        let error = (f64::from(out) - expected).abs() / (EPS * scale);
        assert!(
            error <= 8.0,
            "point factor {out} against the Rust twin's {expected}: {error} round-offs of \
             {scale} (bin {twin:?}, receiver at {point} facing {normal})"
        );
        worst = worst.max(error);
        compared += 1;
        lit += usize::from(expected != 0.0);
        // The expansion clamped: near, or seen almost edge-on.
        let terms = (twin.covariance * d).length() / (a * b).abs().max(f64::MIN_POSITIVE);
        clamped += usize::from(expected != 0.0 && terms > 0.5);
    }
    println!(
        "{compared} compared, {lit} lit, {clamped} near or edge-on; worst {worst:.1} round-offs"
    );
    assert!(compared > 7000, "{compared} compared");
    assert!(lit > 1000, "{lit} lit");
    assert!(clamped > 100, "{clamped} near or edge-on");
}
