// Where a node lies from a receiver and what it can send
// (hierarchy::transfer's placement, bound, node geometry and quadrature):
// in front, behind or across the tangent plane; the bound of its
// irradiance; a near node's elements integrated (dim_irradiance); the
// visibility of a far node from four rays.

// Transfer::side: where element `e` lies against the receiver's tangent
// plane.
fn element_side(e: u32, r: Receiver, graze: f32) -> u32 {
    return polygon_side(element_polygon(e, r), r.normal, graze);
}

// transfer::side: where a polygon relative to the receiver lies against
// its tangent plane (of `normal`).
fn polygon_side(poly: Polygon, normal: vec3<f32>, graze: f32) -> u32 {
    var low = 3.0e38;
    var high = -3.0e38;
    for (var i = 0u; i < poly.count; i += 1u) {
        let h = dot(normal, poly.p[i]);
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
    var s: Surface;
    if (n.group != NONE) {
        s = surfaces[n.surface];
    }
    return faces_plane(n, r, s.normal, s.corner, s.corner_lo);
}

// transfer::faces, a node within one surface on the plane through
// `corner` (and its round-off) of `normal`.
fn faces_plane(
    n: TreeNode,
    r: Receiver,
    normal: vec3<f32>,
    corner: vec3<f32>,
    corner_lo: vec3<f32>,
) -> bool {
    if (dot(r.normal, node_offset(n, r)) < -n.radius) {
        return false;
    }
    if (n.group == NONE) {
        return true;
    }
    if (n.group == r.group) {
        return false;
    }
    return dot(normal, minus(r.point, r.point_lo, corner, corner_lo)) > 0.0;
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
    var sending = vec3<f32>(0.0);
    if (node.group != NONE) {
        sending = surfaces[node.surface].normal;
    }
    return box_bound(node, weight, r, sending);
}

// transfer::bound, `sending` the normal of a node within one surface.
fn box_bound(node: TreeNode, weight: f32, r: Receiver, sending_normal: vec3<f32>) -> f32 {
    let middle = node_offset(node, r) + node.box_middle;
    let clearance = length(max(abs(middle) - node.box_half, vec3<f32>(0.0)));
    if (clearance <= 0.0) {
        return 3.0e38;
    }
    let high = dot(r.normal, middle) + dot(abs(r.normal), node.box_half);
    let receiving = clamp(high / clearance, 0.0, 1.0);
    var sending = 1.0;
    if (node.group != NONE) {
        let normal = sending_normal;
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
