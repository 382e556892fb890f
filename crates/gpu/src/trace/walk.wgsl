// Shadow segments against the scene on the GPU: the any-hit query of the
// CPU's `Occluder::occluded` (design.md section 3). One thread a segment
// walks the binary BVH the CPU's build made (depth first: an interior
// node's left child is the next node, its right child is `link`), and
// tests the triangles of the leaves it reaches with the watertight test of
// Woop, Benthin & Wald (2013, "Watertight ray/triangle intersection"),
// each half of the segment from its own end:
// a segment through an edge or a vertex shared by two triangles is found
// by one of them, never slips between. Coordinates are relative to the
// scene's centre, each a pair of f32s. The Rust twins of these structs are in trace.rs,
// checked against them by a test. This file: the scene's structs and the
// walk (`segment_blocked`), which the transfer kernels use too; its
// bindings (`nodes`, `triangles`) are declared by shaders.rs.

struct Node {
    lo: vec3<f32>,
    // Interior: the right child. Leaf: its first triangle.
    link: u32,
    hi: vec3<f32>,
    // Interior: INTERIOR | split axis. Leaf: its triangle count.
    kind: u32,
}

// Each point is two f32s, hi + lo, the second the first's round-off: the
// difference of two points is then accurate to f32's precision of their
// distance, not of the scene's size (a receiver a hair off its surface
// stays on its side of a neighbour's plane).
struct Triangle {
    a: vec3<f32>,
    // The surface id (Surface::group) it belongs to.
    group: u32,
    b: vec3<f32>,
    pad0: u32,
    c: vec3<f32>,
    pad1: u32,
    a_lo: vec3<f32>,
    pad2: u32,
    b_lo: vec3<f32>,
    pad3: u32,
    c_lo: vec3<f32>,
    pad4: u32,
    // The surface's unit normal (from its f64 plane).
    normal: vec3<f32>,
    pad5: u32,
}

// STACK_SIZE: the CPU's build bounds the depth by bvh::MAX_DEPTH.

// Whether the segment origin + t d, 0 <= t <= 1, meets the box (`inv` is
// 1 / d with no zero component).
fn box_hit(lo: vec3<f32>, hi: vec3<f32>, origin: vec3<f32>, inv: vec3<f32>) -> bool {
    let t0 = (lo - origin) * inv;
    let t1 = (hi - origin) * inv;
    let near = min(t0, t1);
    let far = max(t0, t1);
    let enter = max(max(near.x, near.y), max(near.z, 0.0));
    let exit = min(min(far.x, far.y), min(far.z, 1.0));
    return enter <= exit;
}

// The segment's frame for the watertight test: the axis of its largest
// component (kz) and the two after it (kx, ky, swapped to keep the winding
// when d[kz] < 0), and the shear that makes d point along kz.
struct Frame {
    k: vec3<u32>,
    shear: vec3<f32>,
}

fn frame_of(d: vec3<f32>) -> Frame {
    let a = abs(d);
    var kz = 2u;
    if (a.x >= a.y && a.x >= a.z) {
        kz = 0u;
    } else if (a.y >= a.z) {
        kz = 1u;
    }
    var kx = (kz + 1u) % 3u;
    var ky = (kx + 1u) % 3u;
    if (d[kz] < 0.0) {
        let t = kx;
        kx = ky;
        ky = t;
    }
    return Frame(vec3<u32>(kx, ky, kz), vec3<f32>(d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]));
}

// hi + lo minus origin_hi + origin_lo: exact where the two are within a
// factor of two of each other (Sterbenz), so as precise as f32 allows
// relative to their distance.
fn minus(hi: vec3<f32>, lo: vec3<f32>, origin_hi: vec3<f32>, origin_lo: vec3<f32>) -> vec3<f32> {
    return (hi - origin_hi) + (lo - origin_lo);
}

// Half segments overlap by this much of their length at the midpoint, so
// that no crossing falls between them whatever the round-off of each.
const OVERLAP: f32 = 1.0009765625;

// Whether the half segment origin + t d, 0 < t <= OVERLAP, crosses the
// triangle (its edges and corners included); `f` is d's frame.
fn crosses(t: Triangle, origin: vec3<f32>, origin_lo: vec3<f32>, f: Frame) -> bool {
    let a = minus(t.a, t.a_lo, origin, origin_lo);
    let b = minus(t.b, t.b_lo, origin, origin_lo);
    let c = minus(t.c, t.c_lo, origin, origin_lo);
    let ax = a[f.k.x] - f.shear.x * a[f.k.z];
    let ay = a[f.k.y] - f.shear.y * a[f.k.z];
    let bx = b[f.k.x] - f.shear.x * b[f.k.z];
    let by = b[f.k.y] - f.shear.y * b[f.k.z];
    let cx = c[f.k.x] - f.shear.x * c[f.k.z];
    let cy = c[f.k.y] - f.shear.y * c[f.k.z];
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    if ((u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0)) {
        return false;
    }
    let det = u + v + w;
    if (det == 0.0) {
        return false;
    }
    let az = f.shear.z * a[f.k.z];
    let bz = f.shear.z * b[f.k.z];
    let cz = f.shear.z * c[f.k.z];
    let t_scaled = u * az + v * bz + w * cz;
    // 0 < t_scaled / det <= OVERLAP, without the division.
    if (det > 0.0) {
        return t_scaled > 0.0 && t_scaled <= det * OVERLAP;
    }
    return t_scaled < 0.0 && t_scaled >= det * OVERLAP;
}

// Whether a surface other than those of `skip0` and `skip1` crosses the
// open segment p0 -> p1 (each point hi + lo): the CPU's
// `Occluder::occluded`.
fn segment_blocked(p0: vec3<f32>, p0_lo: vec3<f32>, p1: vec3<f32>, p1_lo: vec3<f32>, skip0: u32, skip1: u32) -> bool {
    let origin = p0;
    let d = minus(p1, p1_lo, p0, p0_lo);
    // A point crosses nothing (the CPU's test: both ends on one side).
    if (all(d == vec3<f32>(0.0))) {
        return false;
    }
    // No zero component: 1 / d stays finite, and 0 * it is 0, never NaN.
    let tiny = vec3<f32>(1e-30);
    let safe = select(tiny, d, abs(d) >= tiny);
    let inv = 1.0 / safe;
    // Each half of the segment is tested from its own end, so the points
    // near either end (a receiver a hair off its surface, beside a
    // neighbour's plane) are resolved relative to that end.
    let half = 0.5 * d;
    let f0 = frame_of(half);
    let f1 = frame_of(-half);
    var stack: array<u32, STACK_SIZE>;
    var depth = 0u;
    var node = 0u;
    loop {
        let n = nodes[node];
        if (box_hit(n.lo, n.hi, origin, inv)) {
            if ((n.kind & INTERIOR) != 0u) {
                stack[depth] = n.link;
                depth += 1u;
                node += 1u;
                continue;
            }
            for (var p = n.link; p < n.link + n.kind; p += 1u) {
                let t = triangles[p];
                if (t.group == skip0 || t.group == skip1) {
                    continue;
                }
                // The CPU's first rule: the ends strictly on either side of
                // the surface's plane, each measured from a corner.
                let e0 = dot(t.normal, minus(p0, p0_lo, t.a, t.a_lo));
                let e1 = dot(t.normal, minus(p1, p1_lo, t.a, t.a_lo));
                if (e0 == 0.0 || e1 == 0.0 || (e0 > 0.0) == (e1 > 0.0)) {
                    continue;
                }
                if (crosses(t, origin, p0_lo, f0) || crosses(t, p1, p1_lo, f1)) {
                    return true;
                }
            }
        }
        if (depth == 0u) {
            return false;
        }
        depth -= 1u;
        node = stack[depth];
    }
    return false;
}
