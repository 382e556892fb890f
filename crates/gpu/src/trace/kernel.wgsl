// The trace kernel (trace.rs): one thread a shadow segment of a dispatch,
// through the walk of walk.wgsl. Its bindings are declared by shaders.rs.

struct Segment {
    // Start and end (`from` and `to` are WGSL keywords).
    p0: vec3<f32>,
    skip0: u32,
    p1: vec3<f32>,
    skip1: u32,
    p0_lo: vec3<f32>,
    pad0: u32,
    p1_lo: vec3<f32>,
    pad1: u32,
}

struct Dispatch {
    // The first segment of this dispatch, and how many it has.
    first: u32,
    count: u32,
    pad0: u32,
    pad1: u32,
}

@compute @workgroup_size(WORKGROUP)
fn occluded(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= dispatch.count) {
        return;
    }
    let i = dispatch.first + id.x;
    let s = segments[i];
    blocked[i] = select(0u, 1u, segment_blocked(s.p0, s.p0_lo, s.p1, s.p1_lo, s.skip0, s.skip1));
}
