// The walk of the shooter's subtree from each receiver
// (solver::adaptive::gather): a node accepted whole or opened, breadth
// first to a frontier that other threads take as items; the entry points
// `gather`, `size_items`, `gather_items`, `join_items`.

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
    atomicMax(&counters[LONGEST_WALK], visits);
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
    atomicMax(&counters[LONGEST_ITEM], visits);
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
