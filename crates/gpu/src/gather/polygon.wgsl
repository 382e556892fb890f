// Polygons as the transfer kernel sees them, relative to the receiver:
// the one clipper (geometry::clip), Newell's normal, the centroid, and the
// paper's equation (2) by Baum et al.'s contour integral
// (form_factor::analytic), each the CPU's rule in f32, each tested against
// it (tests/twins.rs). Put together with the other files of the transfer
// module by shaders.rs.

// Up to six corners (a quad clipped by one plane).
struct Polygon {
    p: array<vec3<f32>, 6>,
    count: u32,
}


// geometry::clip: the edge from p (distance dp > 0) to q (dq < 0) cut at
// the plane, interpolated from the end nearer it.
fn crossing(p: vec3<f32>, dp: f32, q: vec3<f32>, dq: f32) -> vec3<f32> {
    if (-dq < dp) {
        return q + (p - q) * (dq / (dq - dp));
    }
    return p + (q - p) * (dp / (dp - dq));
}

// The part of `poly` where dot(normal, p) >= -tolerance (clip_each).
fn clip(poly: Polygon, normal: vec3<f32>, tolerance: f32) -> Polygon {
    var out: Polygon;
    out.count = 0u;
    for (var i = 0u; i < poly.count; i += 1u) {
        let a = poly.p[i];
        let b = poly.p[(i + 1u) % poly.count];
        let da = dot(normal, a);
        let db = dot(normal, b);
        let a_in = da >= -tolerance;
        let b_in = db >= -tolerance;
        if (a_in) {
            out.p[out.count] = a;
            out.count += 1u;
        }
        if (a_in != b_in) {
            var p = a;
            var dp = da;
            var q = b;
            var dq = db;
            if (!a_in) {
                p = b;
                dp = db;
                q = a;
                dq = da;
            }
            if (dp > 0.0) {
                out.p[out.count] = crossing(p, dp, q, dq);
                out.count += 1u;
            }
        }
    }
    return out;
}

fn newell(poly: Polygon) -> vec3<f32> {
    var sum = vec3<f32>(0.0);
    let o = poly.p[0];
    for (var i = 0u; i < poly.count; i += 1u) {
        sum += cross(poly.p[i] - o, poly.p[(i + 1u) % poly.count] - o);
    }
    return sum;
}

// geometry::centroid: area-weighted, about the first corner.
fn centroid(poly: Polygon) -> vec3<f32> {
    let o = poly.p[0];
    let axis = newell(poly);
    var weighted = vec3<f32>(0.0);
    var total = 0.0;
    var mean = o;
    for (var i = 1u; i + 1u < poly.count; i += 1u) {
        let b = poly.p[i];
        let c = poly.p[i + 1u];
        let w = dot(cross(b - o, c - o), axis);
        weighted += w * (o + b + c) / 3.0;
        total += w;
        mean += b;
    }
    if (abs(total) <= 1.17549435e-38) {
        mean += poly.p[poly.count - 1u];
        return mean / f32(poly.count);
    }
    return weighted / total;
}

// One edge of form_factor::analytic's contour (a and b relative to the
// receiver).
fn contour_edge(p: vec3<f32>, q: vec3<f32>, normal: vec3<f32>, approach: vec3<f32>, at_receiver: f32) -> f32 {
    var a = p;
    var b = q;
    let here = at_receiver * at_receiver;
    let la2 = dot(a, a);
    let lb2 = dot(b, b);
    if (la2 <= here && lb2 <= here) {
        return 0.0;
    }
    if (la2 <= here) {
        a = -approach * sqrt(lb2);
    } else if (lb2 <= here) {
        b = -approach * sqrt(la2);
    }
    let c = cross(a, b);
    let s = length(c);
    let cosine = dot(a, b);
    if (cosine > 0.0) {
        var angle_over_sine = 1.0 / cosine;
        if (s > 0.0) {
            angle_over_sine = atan2(s, cosine) / s;
        }
        return dot(normal, c) * angle_over_sine;
    }
    let edge = b - a;
    if (s > at_receiver * length(edge)) {
        return dot(normal, c) * atan2(s, cosine) / s;
    }
    let axis = cross(edge, approach);
    let l = length(axis);
    if (l <= 0.0) {
        return 0.0;
    }
    return PI * dot(normal, axis / l);
}

// form_factor::analytic: the exact factor of a polygon (relative to the
// receiver, its unit normal `source_normal`) at the receiver, clipped to
// its front.
fn analytic(poly: Polygon, normal: vec3<f32>, source_normal: vec3<f32>) -> f32 {
    if (poly.count < 3u) {
        return 0.0;
    }
    var scale2 = 0.0;
    for (var i = 0u; i < poly.count; i += 1u) {
        scale2 = max(scale2, dot(poly.p[i], poly.p[i]));
    }
    let scale = sqrt(scale2);
    if (!(scale > 0.0)) {
        return 0.0;
    }
    let facing = dot(normal, source_normal);
    let tangential = source_normal - facing * normal;
    var approach = source_normal;
    if (length(tangential) > DEGENERATE) {
        approach = normalize(tangential);
    } else if (facing > 0.0) {
        return 0.0;
    }
    let clipped = clip(poly, normal, ON_PLANE * scale);
    let at_receiver = DEGENERATE * scale;
    var sum = 0.0;
    for (var i = 0u; i < clipped.count; i += 1u) {
        sum += contour_edge(clipped.p[i], clipped.p[(i + 1u) % clipped.count], normal, approach, at_receiver);
    }
    let f = -sum / TAU;
    if (f != f) {
        return 0.0;
    }
    return clamp(f, 0.0, 1.0);
}
