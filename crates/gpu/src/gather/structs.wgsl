// One shot of adaptive shooting on the GPU: the CPU's per-receiver walk of
// the shooting node's subtree (radiosity::solver::adaptive, after the
// adaptive source subdivision of Wallace, Elmquist & Haines 1989, section
// 4), a thread a receiver (and, for a long walk, a thread a subtree of its
// frontier: `gather_items`), with the CPU's rules: a node
// is accepted whole when what it can send is negligible, or far and either
// dim or seen alike by four shadow rays; elements are the finest sources,
// their exact factor by the paper's equation (2) (Baum et al.'s contour
// integral) on the part in front of the receiver and a shadow ray from its
// centre. After trace/walk.wgsl, whose `segment_blocked` answers the
// rays. Every point is two f32s (hi + lo) relative to the scene's centre,
// and every vector the kernel computes with is a difference taken from
// the receiver (or the shot's centre), so its precision is f32's relative
// to the distances involved, not to the scene's size. The Rust twins of
// these structs are in gather.rs, checked against them by a test.

// This file: the buffers' structs, the walk's counts, two helpers. The
// bindings are declared by shaders.rs.

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

// What one receiver's walk counted.
var<private> pairs: u32;
var<private> rays: u32;
var<private> visits: u32;
var<private> element_sources: u32;

// photometry::luminance.
fn luminance(rgb: vec3<f32>) -> f32 {
    return LUMINANCE_R * rgb.x + LUMINANCE_G * rgb.y + LUMINANCE_B * rgb.z;
}

// a + b as hi + lo (Knuth's two-sum: lo is what rounding hi lost).
fn two_sum(a: vec3<f32>, b: vec3<f32>) -> array<vec3<f32>, 2> {
    let s = a + b;
    let bb = s - a;
    let err = (a - (s - bb)) + (b - bb);
    return array<vec3<f32>, 2>(s, err);
}
