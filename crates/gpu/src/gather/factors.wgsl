// Factors at a receiver: a bin's point factor (the point-to-disk
// transfer of Wallace et al. 1989 with the bin's spread,
// hierarchy::sources), an element's exact factor on its front part
// (polygon.wgsl's analytic) and the visible share from its centre.

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
    return polygon_point_factor(part, surfaces[elements[e].surface].normal, r.normal);
}

// transfer::polygon_point_factor: polygon `part` (relative to the
// receiver, in front of it, of `normal`) as a corrected point source.
fn polygon_point_factor(part: Polygon, normal: vec3<f32>, receiver_normal: vec3<f32>) -> f32 {
    if (part.count < 3u) {
        return 0.0;
    }
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
    return abs(area) * point_factor(source, vec3<f32>(0.0), receiver_normal);
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

