// One shot of adaptive shooting on the GPU: the CPU's per-receiver walk of
// the shooting node's subtree (radiosity::solver::adaptive, after the
// adaptive source subdivision of Wallace, Elmquist & Haines 1989, section
// 4), a thread a receiver (and, for a long walk, a thread a subtree of its
// frontier: `gather_items`), with the CPU's rules: a node
// is accepted whole when what it can send is negligible, or far and either
// dim or seen alike by four shadow rays; elements are the finest sources,
// their exact factor by the paper's equation (2) (Baum et al.'s contour
// integral) on the part in front of the receiver and a shadow ray from its
// centre. Appended to trace.wgsl, whose `segment_blocked` answers the
// rays. Every point is two f32s (hi + lo) relative to the scene's centre,
// and every vector the kernel computes with is a difference taken from
// the receiver (or the shot's centre), so its precision is f32's relative
// to the distances involved, not to the scene's size. The Rust twins of
// these structs are in gather.rs, checked against them by a test.

// A node of the element tree.
struct TreeNode {
    centre: vec3<f32>,
    radius: f32,
    centre_lo: vec3<f32>,
    // The second child; NONE for a leaf.
    second: u32,
    // The surface id all its elements share, or NONE.
    group: u32,
    // The surface of its first element (its plane, for a node of one id).
    surface: u32,
    // A leaf's element.
    element: u32,
    pad0: u32,
    // The middle of its box less its centre, and half the box's extent.
    box_middle: vec3<f32>,
    pad1: u32,
    box_half: vec3<f32>,
    pad2: u32,
}

struct Pane {
    a: vec3<f32>,
    pad0: u32,
    b: vec3<f32>,
    pad1: u32,
    c: vec3<f32>,
    pad2: u32, // 1: the edge from c to a is a diagonal inside the pane
    transmittance: vec3<f32>,
    pad3: u32,
}

struct Surface {
    normal: vec3<f32>,
    group: u32,
    corner: vec3<f32>,
    pad0: u32,
    corner_lo: vec3<f32>,
    pad1: u32,
}

struct Element {
    corners: array<vec4<f32>, 4>,
    corners_lo: array<vec4<f32>, 4>,
    centroid: vec3<f32>,
    surface: u32,
    centroid_lo: vec3<f32>,
    // 3 or 4.
    count: u32,
    area: f32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

struct Receiver {
    point: vec3<f32>,
    group: u32,
    point_lo: vec3<f32>,
    pad0: u32,
    normal: vec3<f32>,
    pad1: u32,
}

// A node of the shooting subtree as a source (indexed from its root).
struct NodeSource {
    // Luminance of its unshot power.
    weight: f32,
    first_bin: u32,
    bins: u32,
    pad0: u32,
    // A leaf's unshot radiosity.
    unshot: vec3<f32>,
    pad1: u32,
}

// A bin's point source: power, mean normal (unit, and the length of the
// mean), power-weighted centre relative to the shot's centre, and the
// covariance of its points.
struct Bin {
    power: vec3<f32>,
    weight: f32,
    normal: vec3<f32>,
    length: f32,
    centre: vec3<f32>,
    representative: u32,
    // xx, yy, zz.
    diagonal: vec3<f32>,
    axis: u32,
    // xy, xz, yz.
    off_diagonal: vec3<f32>,
    pad0: u32,
}

struct Shot {
    // The shooting node.
    root: u32,
    // The first receiver of this dispatch, and how many it has.
    first: u32,
    count: u32,
    // A receiver's negligible irradiance is this times its irradiance's
    // luminance over `mean`, if more than one.
    negligible: f32,
    // The shooting node's centre: the bins' origin.
    origin: vec3<f32>,
    mean: f32,
    origin_lo: vec3<f32>,
    // A receiver's walk is split into at most this many items once its
    // frontier holds this many nodes (`gather_items`); 1: never split.
    frontier: u32,
    // The items' workgroups at most (`size_items`).
    item_groups: u32,
}


@group(0) @binding(5) var<storage, read> tree: array<TreeNode>;
@group(0) @binding(6) var<storage, read> surfaces: array<Surface>;
@group(0) @binding(7) var<storage, read> elements: array<Element>;
@group(0) @binding(8) var<storage, read> receivers: array<Receiver>;
// Each receiver's irradiance so far (the device's order).
@group(0) @binding(9) var<storage, read_write> total: array<vec4<f32>>;
@group(0) @binding(10) var<storage, read> sources: array<NodeSource>;
@group(0) @binding(11) var<storage, read> bins: array<Bin>;
// What each receiver gathers in this shot.
@group(0) @binding(12) var<storage, read_write> shot_irradiance: array<vec4<f32>>;
@group(0) @binding(13) var<uniform> shot: Shot;
@group(0) @binding(14) var<storage, read_write> counters: array<atomic<u32>, 8>;
// Glass: the panes' triangles (one of no area when there is none).
@group(0) @binding(23) var<storage, read> panes: array<Pane>;
// The split walks of one chunk of receivers: first a header a receiver of
// the chunk (x: its first item, y: how many), then the items (before
// `gather_items`: x the subtree's node, y the receiver; after it, xyz the
// bits of what the subtree sends the receiver).
@group(0) @binding(24) var<storage, read_write> split: array<vec4<u32>>;
// The workgroups `gather_items` is dispatched with (indirect).
@group(0) @binding(25) var<storage, read_write> item_dispatch: array<u32, 3>;


// What one receiver's walk counted.
var<private> pairs: u32;
var<private> rays: u32;
var<private> visits: u32;
var<private> element_sources: u32;

fn luminance(rgb: vec3<f32>) -> f32 {
    return 0.2126 * rgb.x + 0.7152 * rgb.y + 0.0722 * rgb.z;
}

// a + b as hi + lo (Knuth's two-sum: lo is what rounding hi lost).
fn two_sum(a: vec3<f32>, b: vec3<f32>) -> array<vec3<f32>, 2> {
    let s = a + b;
    let bb = s - a;
    let err = (a - (s - bb)) + (b - bb);
    return array<vec3<f32>, 2>(s, err);
}

// Whether the receiver sees the point `offset` from it: the CPU's shadow
// ray from that point to the receiver, shortened at both ends.
fn visible(offset: vec3<f32>, r: Receiver, group: u32) -> bool {
    rays += 1u;
    let a = two_sum(r.point, offset * (1.0 - SEGMENT_EPSILON));
    let b = two_sum(r.point, offset * SEGMENT_EPSILON);
    return !segment_blocked(a[0], a[1] + r.point_lo, b[0], b[1] + r.point_lo, group, r.group);
}

// glass::transmittance: what passes every pane the shadow ray from the
// point `offset` from the receiver crosses (1 through none).
fn glass(offset: vec3<f32>, r: Receiver) -> vec3<f32> {
    var through = vec3<f32>(1.0);
    let p0 = r.point + offset * (1.0 - SEGMENT_EPSILON);
    let p1 = r.point + offset * SEGMENT_EPSILON;
    for (var i = 0u; i < arrayLength(&panes); i += 1u) {
        let p = panes[i];
        let n = cross(p.b - p.a, p.c - p.a);
        let da = dot(n, p0 - p.a);
        let db = dot(n, p1 - p.a);
        if (all(n == vec3<f32>(0.0)) || da == db || da == 0.0 || db == 0.0 || (da > 0.0) == (db > 0.0)) {
            continue;
        }
        let hit = p0 + (p1 - p0) * (da / (da - db));
        // The edge from c to a, where it is a diagonal inside the pane
        // (pad2), belongs to the next triangle: no ray counts twice.
        let closing = dot(cross(p.a - p.c, hit - p.c), n);
        if (dot(cross(p.b - p.a, hit - p.a), n) >= 0.0 && dot(cross(p.c - p.b, hit - p.b), n) >= 0.0
            && (closing > 0.0 || (closing == 0.0 && p.pad2 == 0u))) {
            through *= p.transmittance;
        }
    }
    return through;
}

// What passes from the point `offset` from the receiver: 0 where a surface
// blocks it, else the glass's transmittance.
fn passes(offset: vec3<f32>, r: Receiver, group: u32) -> vec3<f32> {
    if (!visible(offset, r, group)) {
        return vec3<f32>(0.0);
    }
    return glass(offset, r);
}

fn element_group(e: u32) -> u32 {
    return surfaces[elements[e].surface].group;
}

// What passes from the centre of element `e` to the receiver.
fn passes_from(e: u32, r: Receiver) -> vec3<f32> {
    let el = elements[e];
    let offset = minus(el.centroid, el.centroid_lo, r.point, r.point_lo);
    return passes(offset, r, surfaces[el.surface].group);
}

// `x` times the symmetric matrix of a bin's covariance.
fn covariance_times(b: Bin, x: vec3<f32>) -> vec3<f32> {
    let d = b.diagonal;
    let o = b.off_diagonal;
    return vec3<f32>(
        d.x * x.x + o.x * x.y + o.y * x.z,
        o.x * x.x + d.y * x.y + o.z * x.z,
        o.y * x.x + o.z * x.y + d.z * x.z,
    );
}

// hierarchy::sources::point_factor: irradiance per unit power of a bin
// seen as a point, corrected to second order for its extent; `from_origin`
// is the receiver less the shot's centre.
fn point_factor(b: Bin, from_origin: vec3<f32>, normal: vec3<f32>) -> f32 {
    let d = from_origin - b.centre;
    let q = dot(d, d);
    if (q <= 0.0 || b.length <= 0.0) {
        return 0.0;
    }
    let s = b.normal;
    let a = dot(s, d);
    let bb = dot(normal, d);
    if (a <= 0.0 || bb >= 0.0) {
        return 0.0;
    }
    let trace = b.diagonal.x + b.diagonal.y + b.diagonal.z;
    let c = dot(normal, covariance_times(b, s)) / (a * bb)
        - 4.0 * dot(d, covariance_times(b, normal * a + s * bb)) / (a * bb * q)
        - 2.0 * trace / q
        + 12.0 * dot(d, covariance_times(b, d)) / (q * q);
    return -b.length * a * bb / (PI * q * q) * (1.0 + clamp(c, -0.5, 0.5));
}

// The receiver's view of the corners of element `e`, relative to it
// (polygon.wgsl's `Polygon`).
fn element_polygon(e: u32, r: Receiver) -> Polygon {
    let el = elements[e];
    var out: Polygon;
    out.count = el.count;
    for (var i = 0u; i < el.count; i += 1u) {
        out.p[i] = minus(el.corners[i].xyz, el.corners_lo[i].xyz, r.point, r.point_lo);
    }
    return out;
}
// Transfer::front_point_factor: the part of element `e` in front of the
// receiver's tangent plane as a corrected point source of its area,
// centroid and covariance (PointSource::of_polygon, over its fan of
// triangles about the first corner).
fn front_point_factor(e: u32, r: Receiver) -> f32 {
    let part = clip(element_polygon(e, r), r.normal, 0.0);
    if (part.count < 3u) {
        return 0.0;
    }
    let normal = surfaces[elements[e].surface].normal;
    let first = part.p[0];
    var area = 0.0;
    var first_moment = vec3<f32>(0.0);
    var diagonal = vec3<f32>(0.0);
    var off_diagonal = vec3<f32>(0.0);
    for (var i = 1u; i + 1u < part.count; i += 1u) {
        let a = part.p[i] - first;
        let b = part.p[i + 1u] - first;
        let t = 0.5 * dot(cross(a, b), normal);
        let m = a + b;
        area += t;
        first_moment += m * (t / 3.0);
        diagonal += (a * a + b * b + m * m) * (t / 12.0);
        off_diagonal += (vec3<f32>(a.x * a.y, a.x * a.z, a.y * a.z)
            + vec3<f32>(b.x * b.y, b.x * b.z, b.y * b.z)
            + vec3<f32>(m.x * m.y, m.x * m.z, m.y * m.z)) * (t / 12.0);
    }
    if (area == 0.0) {
        return 0.0;
    }
    let c = first_moment / area;
    var source: Bin;
    source.normal = normal;
    source.length = 1.0;
    source.centre = first + c;
    source.diagonal = diagonal / area - c * c;
    source.off_diagonal = off_diagonal / area - vec3<f32>(c.x * c.y, c.x * c.z, c.y * c.z);
    // The polygon is relative to the receiver: the receiver is at 0.
    return abs(area) * point_factor(source, vec3<f32>(0.0), r.normal);
}

fn element_factor(e: u32, r: Receiver) -> f32 {
    return analytic(element_polygon(e, r), r.normal, surfaces[elements[e].surface].normal);
}

// Transfer::passing_element_factor: the factor of element `e` (w), if the
// receiver sees the centre of the part in front of it, and what passes
// along that ray (xyz).
fn visible_element_factor(e: u32, r: Receiver) -> vec4<f32> {
    let el = elements[e];
    let poly = element_polygon(e, r);
    let tolerance = 1e-9 * sqrt(el.area);
    var any_front = false;
    var all_front = true;
    for (var i = 0u; i < poly.count; i += 1u) {
        let h = dot(r.normal, poly.p[i]);
        any_front = any_front || h > tolerance;
        all_front = all_front && h > tolerance;
    }
    if (!any_front) {
        return vec4<f32>(0.0);
    }
    var origin = minus(el.centroid, el.centroid_lo, r.point, r.point_lo);
    if (!all_front) {
        let clipped = clip(poly, r.normal, 0.0);
        if (clipped.count < 3u || length(newell(clipped)) <= 0.0) {
            return vec4<f32>(0.0);
        }
        origin = centroid(clipped);
    }
    pairs += 1u;
    let through = passes(origin, r, surfaces[el.surface].group);
    if (all(through == vec3<f32>(0.0))) {
        return vec4<f32>(0.0);
    }
    return vec4<f32>(through, analytic(poly, r.normal, surfaces[el.surface].normal));
}

const SIDE_FRONT: u32 = 0u;
const SIDE_BEHIND: u32 = 1u;
const SIDE_ACROSS: u32 = 2u;

// Transfer::side: where element `e` lies against the receiver's tangent
// plane.
fn element_side(e: u32, r: Receiver, graze: f32) -> u32 {
    let poly = element_polygon(e, r);
    var low = 3.0e38;
    var high = -3.0e38;
    for (var i = 0u; i < poly.count; i += 1u) {
        let h = dot(r.normal, poly.p[i]);
        low = min(low, h);
        high = max(high, h);
    }
    if (high <= 0.0) {
        return SIDE_BEHIND;
    }
    return select(SIDE_ACROSS, SIDE_FRONT, low >= -graze);
}

fn node_offset(n: TreeNode, r: Receiver) -> vec3<f32> {
    return minus(n.centre, n.centre_lo, r.point, r.point_lo);
}

// Transfer::faces: whether any point of the node can light the receiver.
fn faces(n: TreeNode, r: Receiver) -> bool {
    if (dot(r.normal, node_offset(n, r)) < -n.radius) {
        return false;
    }
    if (n.group == NONE) {
        return true;
    }
    if (n.group == r.group) {
        return false;
    }
    let s = surfaces[n.surface];
    return dot(s.normal, minus(r.point, r.point_lo, s.corner, s.corner_lo)) > 0.0;
}

fn straddles(n: TreeNode, r: Receiver) -> bool {
    return abs(dot(r.normal, node_offset(n, r))) < n.radius;
}


// transfer::placement: which side of the receiver's tangent plane a node
// lies on, by its sphere and its box, in front also when it reaches
// behind by no more than GRAZE of its radius.
fn placement(n: TreeNode, r: Receiver) -> u32 {
    let h = dot(r.normal, node_offset(n, r));
    if (h >= n.radius) {
        return SIDE_FRONT;
    }
    if (h <= -n.radius) {
        return SIDE_BEHIND;
    }
    let middle = h + dot(r.normal, n.box_middle);
    let reach = dot(abs(r.normal), n.box_half);
    if (middle - reach >= -GRAZE * n.radius) {
        return SIDE_FRONT;
    }
    if (middle + reach <= 0.0) {
        return SIDE_BEHIND;
    }
    return SIDE_ACROSS;
}

// The receiver less the shot's centre.
fn from_origin(r: Receiver) -> vec3<f32> {
    return minus(r.point, r.point_lo, shot.origin, shot.origin_lo);
}

// Transfer::representative: the element of the node's heaviest bin (the
// last of equals, as Rust's max_by); NONE for a node with no power.
fn representative(n: u32) -> u32 {
    let s = sources[n - shot.root];
    var best = NONE;
    var weight = 0.0;
    for (var k = 0u; k < s.bins; k += 1u) {
        let b = bins[s.first_bin + k];
        if (best == NONE || b.weight >= weight) {
            best = b.representative;
            weight = b.weight;
        }
    }
    return best;
}

// The first of source `s`'s bins on `axis`; NONE if none is.
fn bin_slot(s: NodeSource, axis: u32) -> u32 {
    for (var j = 0u; j < s.bins; j += 1u) {
        if (bins[s.first_bin + j].axis == axis) {
            return j;
        }
    }
    return NONE;
}

// Irradiance of each of a node's bins, in its bins' order, with no
// occlusion (Transfer::node_geometry).
struct Geometry {
    e: array<vec3<f32>, 6>,
}


// Transfer::bound: the most irradiance (luminance) a node of power
// `weight` can send the receiver, from its box's nearest point at the
// smallest angles any point of the box makes; 3e38 when the receiver is
// inside the box.
fn bound(node: TreeNode, weight: f32, r: Receiver) -> f32 {
    let middle = node_offset(node, r) + node.box_middle;
    let clearance = length(max(abs(middle) - node.box_half, vec3<f32>(0.0)));
    if (clearance <= 0.0) {
        return 3.0e38;
    }
    let high = dot(r.normal, middle) + dot(abs(r.normal), node.box_half);
    let receiving = clamp(high / clearance, 0.0, 1.0);
    var sending = 1.0;
    if (node.group != NONE) {
        let normal = surfaces[node.surface].normal;
        let low = dot(normal, middle) - dot(abs(normal), node.box_half);
        sending = clamp(-low / clearance, 0.0, 1.0);
    }
    return weight * receiving * sending / (PI * clearance * clearance);
}

// `budget`: the error accepted (Transfer::node_geometry), 0 for none.
fn node_geometry(n: u32, r: Receiver, budget: f32) -> Geometry {
    var g: Geometry;
    let s = sources[n - shot.root];
    for (var k = 0u; k < 6u; k += 1u) {
        g.e[k] = vec3<f32>(0.0);
    }
    // The error a unit of the node's power may bring.
    let allowance = budget / s.weight;
    let offset = from_origin(r);
    var pieces: array<u32, WALK_STACK>;
    var depth = 1u;
    pieces[0] = n;
    while (depth > 0u) {
        depth -= 1u;
        let piece = pieces[depth];
        let node = tree[piece];
        let o = node_offset(node, r);
        let reach = QUADRATURE_RATIO * node.radius;
        let close = dot(o, o) < reach * reach;
        let side = placement(node, r);
        if (side == SIDE_BEHIND) {
            continue;
        }
        let straddling = side == SIDE_ACROSS;
        let leaf = node.second == NONE;
        // A piece that would be split or taken exactly, and can send so
        // little that any value up to its bound is within its share of the
        // budget: its point sources, capped at the bound.
        if ((close || straddling) && allowance > 0.0) {
            let ps = sources[piece - shot.root];
            let most = bound(node, ps.weight, r);
            if (most <= allowance * ps.weight) {
                var added: array<vec3<f32>, 6>;
                var sent = 0.0;
                for (var k = 0u; k < 6u; k += 1u) {
                    added[k] = vec3<f32>(0.0);
                }
                for (var k = 0u; k < ps.bins; k += 1u) {
                    let b = bins[ps.first_bin + k];
                    let slot = bin_slot(s, b.axis);
                    if (slot == NONE) {
                        continue;
                    }
                    let value = b.power * point_factor(b, offset, r.normal);
                    sent += luminance(value);
                    added[slot] += value;
                }
                let scale = select(1.0, most / sent, sent > most);
                for (var k = 0u; k < 6u; k += 1u) {
                    g.e[k] += added[k] * scale;
                }
                continue;
            }
        }
        if ((close || straddling) && !leaf) {
            pieces[depth] = node.second;
            pieces[depth + 1u] = piece + 1u;
            depth += 2u;
            continue;
        }
        // An element far away whose box the receiver's tangent plane cuts:
        // a point source if its corners lie in front, nothing if behind,
        // and if the plane cuts it, the point source of the part in front
        // (Transfer::side).
        var across = false;
        if (!close && straddling) {
            // A leaf with power has one bin, its element's.
            let own = sources[piece - shot.root];
            if (own.bins == 0u) {
                continue;
            }
            let corners = element_side(bins[own.first_bin].representative, r, GRAZE * node.radius);
            if (corners == SIDE_BEHIND) {
                continue;
            }
            across = corners == SIDE_ACROSS;
        }
        let ps = sources[piece - shot.root];
        for (var k = 0u; k < ps.bins; k += 1u) {
            let b = bins[ps.first_bin + k];
            let slot = bin_slot(s, b.axis);
            if (slot == NONE) {
                continue;
            }
            if (close) {
                // An element close by: its exact factor.
                g.e[slot] += element_factor(b.representative, r) * ps.unshot;
            } else if (across) {
                g.e[slot] += front_point_factor(b.representative, r) * ps.unshot;
            } else {
                g.e[slot] += b.power * point_factor(b, offset, r.normal);
            }
        }
    }
    return g;
}

fn geometry_sum(g: Geometry, count: u32) -> vec3<f32> {
    var sum = vec3<f32>(0.0);
    for (var k = 0u; k < count; k += 1u) {
        sum += g.e[k];
    }
    return sum;
}

// Transfer::dim_irradiance: the node's geometry behind one shadow ray
// from the representative of the bin that sends the most.
// Its geometry within DIM_SHARE of `small`, the negligible irradiance.
fn dim_irradiance(n: u32, r: Receiver, small: f32) -> vec3<f32> {
    let s = sources[n - shot.root];
    let g = node_geometry(n, r, DIM_SHARE * small);
    var best = NONE;
    var most = 0.0;
    for (var k = 0u; k < s.bins; k += 1u) {
        if (all(g.e[k] == vec3<f32>(0.0))) {
            continue;
        }
        let l = luminance(g.e[k]);
        if (best == NONE || l >= most) {
            best = k;
            most = l;
        }
    }
    if (best == NONE) {
        return vec3<f32>(0.0);
    }
    pairs += 1u;
    let through = passes_from(bins[s.first_bin + best].representative, r);
    if (all(through == vec3<f32>(0.0))) {
        return vec3<f32>(0.0);
    }
    return geometry_sum(g, s.bins) * through;
}

// Transfer::uniform_visibility: w 1 when up to four shadow rays spread
// over the node all see it (xyz the mean of what passes along them), 0
// when none does, 2 when they disagree (or there are none).
fn uniform_visibility(n: u32, r: Receiver) -> vec4<f32> {
    var samples: array<u32, 4>;
    var count = 0u;
    let node = tree[n];
    if (node.second == NONE) {
        samples[0] = n;
        count = 1u;
    } else {
        let children = array<u32, 2>(n + 1u, node.second);
        for (var i = 0u; i < 2u; i += 1u) {
            let child = children[i];
            let c = tree[child];
            if (c.second == NONE) {
                samples[count] = child;
                count += 1u;
            } else {
                samples[count] = child + 1u;
                samples[count + 1u] = c.second;
                count += 2u;
            }
        }
    }
    var answer = 2u;
    var through = vec3<f32>(0.0);
    var votes = 0.0;
    for (var i = 0u; i < count; i += 1u) {
        let e = representative(samples[i]);
        if (e == NONE) {
            continue;
        }
        pairs += 1u;
        let passing = passes_from(e, r);
        through += passing;
        votes += 1.0;
        let v = select(1u, 0u, all(passing == vec3<f32>(0.0)));
        if (answer == 2u) {
            answer = v;
        } else if (answer != v) {
            return vec4<f32>(0.0, 0.0, 0.0, 2.0);
        }
    }
    if (answer == 1u) {
        return vec4<f32>(through / votes, 1.0);
    }
    return vec4<f32>(0.0, 0.0, 0.0, f32(answer));
}

// One node of a receiver's walk (the CPU's Gatherer::gather): xyz what it
// sends when accepted whole, w 1 when the walk goes on to its children.
fn step(n: u32, r: Receiver, offset: vec3<f32>, small: f32) -> vec4<f32> {
    let node = tree[n];
    let source = sources[n - shot.root];
    visits += 1u;
    if (source.weight <= 0.0 || !faces(node, r)) {
        return vec4<f32>(0.0);
    }
    if (node.second == NONE) {
        element_sources += 1u;
        let f = visible_element_factor(node.element, r);
        return vec4<f32>(source.unshot * f.w * f.xyz, 0.0);
    }
    if (placement(node, r) == SIDE_BEHIND) {
        return vec4<f32>(0.0);
    }
    let distance = length(node_offset(node, r));
    if (distance < FAR_RATIO * node.radius || straddles(node, r)) {
        // Near: accepted whole only if even all its power at the nearest
        // point of its bounding sphere would be negligible.
        let clearance = distance - node.radius;
        if (clearance > 0.0 && source.weight <= small * PI * clearance * clearance) {
            return vec4<f32>(dim_irradiance(n, r, small), 0.0);
        }
    } else {
        // Far: the corrected point sources are accurate; what is left to
        // judge is occlusion.
        var estimate = 0.0;
        for (var k = 0u; k < source.bins; k += 1u) {
            let b = bins[source.first_bin + k];
            estimate += b.weight * point_factor(b, offset, r.normal);
        }
        if (estimate <= FAR_FACTOR * small) {
            return vec4<f32>(dim_irradiance(n, r, small), 0.0);
        }
        let seen = uniform_visibility(n, r);
        if (seen.w != 2.0) {
            if (seen.w == 1.0) {
                return vec4<f32>(geometry_sum(node_geometry(n, r, 0.0), source.bins) * seen.xyz, 0.0);
            }
            return vec4<f32>(0.0);
        }
    }
    return vec4<f32>(0.0, 0.0, 0.0, 1.0);
}

// What the subtree of node `start` sends one receiver, walked depth first
// in the CPU's order.
fn walk_from(start: u32, r: Receiver, small: f32) -> vec3<f32> {
    var sum = vec3<f32>(0.0);
    var stack: array<u32, WALK_STACK>;
    var depth = 1u;
    stack[0] = start;
    let offset = from_origin(r);
    while (depth > 0u) {
        depth -= 1u;
        let n = stack[depth];
        let s = step(n, r, offset, small);
        if (s.w == 0.0) {
            sum += s.xyz;
            continue;
        }
        stack[depth] = tree[n].second;
        stack[depth + 1u] = n + 1u;
        depth += 2u;
    }
    return sum;
}

// A receiver's negligible irradiance in this shot.
fn negligible_for(i: u32) -> f32 {
    return shot.negligible * max(luminance(total[i].xyz) / shot.mean, 1.0);
}

// (RING: the ring of nodes a receiver's walk takes breadth first before
// it is split holds at most `shot.frontier` (<= RING) at a time.)
// A receiver's walk, breadth first, until it is done or its frontier
// holds `shot.frontier` nodes; those are left as items, one subtree each,
// for `gather_items` (many threads for the receivers near the shooter,
// whose walks are long), their sums joined by `join_items` in the
// frontier's order, so the answer never depends on which thread got which
// item.
@compute @workgroup_size(WORKGROUP)
fn gather(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= shot.count) {
        return;
    }
    let i = shot.first + id.x;
    let r = receivers[i];
    pairs = 0u;
    rays = 0u;
    visits = 0u;
    element_sources = 0u;
    var irradiance = vec3<f32>(0.0);
    var walked = 0u;
    var first = 0u;
    var count = 0u;
    // A source of one surface id never lights that id's receivers.
    let root = tree[shot.root];
    if (sources[0].weight > 0.0 && (root.group == NONE || root.group != r.group)) {
        walked = 1u;
        let small = negligible_for(i);
        let offset = from_origin(r);
        var ring: array<u32, RING>;
        var head = 0u;
        var tail = 1u;
        ring[0] = shot.root;
        while (head < tail && tail - head < shot.frontier) {
            let n = ring[head % RING];
            head += 1u;
            let s = step(n, r, offset, small);
            if (s.w == 0.0) {
                irradiance += s.xyz;
                continue;
            }
            ring[tail % RING] = n + 1u;
            ring[(tail + 1u) % RING] = tree[n].second;
            tail += 2u;
        }
        count = tail - head;
        if (count > 0u) {
            first = shot.count + atomicAdd(&counters[ITEMS], count);
            for (var k = 0u; k < count; k += 1u) {
                split[first + k] = vec4<u32>(ring[(head + k) % RING], i, 0u, 0u);
            }
        }
    }
    shot_irradiance[i] = vec4<f32>(irradiance, 0.0);
    split[id.x] = vec4<u32>(first, count, 0u, 0u);
    atomicAdd(&counters[PAIRS], pairs);
    atomicAdd(&counters[RAYS], rays);
    atomicAdd(&counters[WALKS], walked);
    atomicAdd(&counters[VISITS], visits);
    atomicAdd(&counters[ELEMENTS], element_sources);
}

// The workgroups of `gather_items`: as many as the chunk's items need, at
// most `shot.item_groups` (never more than a dispatch may have).
@compute @workgroup_size(1)
fn size_items() {
    item_dispatch[0] = min((atomicLoad(&counters[ITEMS]) + WORKGROUP - 1u) / WORKGROUP, shot.item_groups);
    item_dispatch[1] = 1u;
    item_dispatch[2] = 1u;
}

// The items of split walks, each subtree walked depth first: a thread
// takes items a dispatch's width apart until none is left, so any number
// of workgroups walks them all.
@compute @workgroup_size(WORKGROUP)
fn gather_items(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let count = atomicLoad(&counters[ITEMS]);
    if (id.x >= count) {
        return;
    }
    pairs = 0u;
    rays = 0u;
    visits = 0u;
    element_sources = 0u;
    for (var t = id.x; t < count; t += groups.x * WORKGROUP) {
        let k = shot.count + t;
        let item = split[k];
        let i = item.y;
        let sum = walk_from(item.x, receivers[i], negligible_for(i));
        split[k] = vec4<u32>(bitcast<vec3<u32>>(sum), 0u);
    }
    atomicAdd(&counters[PAIRS], pairs);
    atomicAdd(&counters[RAYS], rays);
    atomicAdd(&counters[VISITS], visits);
    atomicAdd(&counters[ELEMENTS], element_sources);
}

// Each receiver's split walk joined, its items' sums in its frontier's
// order; the chunk's items are then free for the next chunk.
@compute @workgroup_size(WORKGROUP)
fn join_items(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x == 0u) {
        atomicStore(&counters[ITEMS], 0u);
    }
    if (id.x >= shot.count) {
        return;
    }
    let i = shot.first + id.x;
    let header = split[id.x];
    if (header.y == 0u) {
        return;
    }
    var sum = shot_irradiance[i].xyz;
    for (var k = 0u; k < header.y; k += 1u) {
        sum += bitcast<vec3<f32>>(split[header.x + k].xyz);
    }
    shot_irradiance[i] = vec4<f32>(sum, 0.0);
}
