// What passes along a ray from a source point to the receiver: the CPU's
// shadow ray (accel's shortened segment, through trace/walk.wgsl) and the
// glass it crosses (scene::glass's transmittance).

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
