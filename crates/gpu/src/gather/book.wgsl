// The book-keeping of a shot on the GPU (design.md section 2, step 5, as
// radiosity::solver does it on the host for the CPU): each receiver's
// irradiance accumulated, the shooter's unshot radiosity set to what it is
// left with (zero, or minus its overshoot), each element's reflected share
// rho * (mean of its corners' irradiance) added to its own, the ledger's
// sums (power received, absorbed, unshot left, in sign and in magnitude)
// per workgroup in a fixed order, each shooter's unshot power (in
// magnitude). An overshooting shot that sends negative light books it in
// a second pass, its irradiance times the sign -1. After the gather files;
// its bindings are declared by shaders.rs. No float atomics: a rerun gives the same result to the
// last bit.

// An element's book-keeping data (by element id).
struct ElementBook {
    // Its corners' receivers, in the device's order (count in Element).
    corners: vec4<u32>,
    rho: vec3<f32>,
    area: f32,
}

// One workgroup's share of the ledger.
struct Partial {
    incident: vec4<f32>,
    absorbed: vec4<f32>,
    unshot: vec4<f32>,
    magnitude: vec4<f32>,
}

struct Book {
    // The shooter's elements: items[first..last].
    first: u32,
    last: u32,
    elements: u32,
    receivers: u32,
    shooters: u32,
    // 1, or -1 for a pass of negative light sent negated.
    sign: f32,
    // 1: set the shooter's elements to the staging buffer's values first.
    leave: u32,
    pad2: u32,
    // The share of the gathered irradiance that is direct, per channel
    // (the shooter's own emission's share of its power).
    direct: vec3<f32>,
    pad3: u32,
}

var<workgroup> sum_incident: array<vec3<f32>, BOOK_WORKGROUP>;
var<workgroup> sum_absorbed: array<vec3<f32>, BOOK_WORKGROUP>;
var<workgroup> sum_unshot: array<vec3<f32>, BOOK_WORKGROUP>;
var<workgroup> sum_magnitude: array<vec3<f32>, BOOK_WORKGROUP>;

// The shooter's elements' unshot radiosity, in the tree's order, for the
// host to prepare its sources.
@compute @workgroup_size(BOOK_WORKGROUP)
fn collect(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = book.first + id.x;
    if (i >= book.last) {
        return;
    }
    staging[id.x] = unshot[items[i]];
}

// The shooter has shot: its elements are left with what the host wrote
// into the staging buffer (zero, or minus their overshoot); a second pass
// leaves them.
@compute @workgroup_size(BOOK_WORKGROUP)
fn leave_shooter(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = book.first + id.x;
    if (i >= book.last || book.leave == 0u) {
        return;
    }
    unshot[items[i]] = staging[id.x];
}

// Each element's mean irradiance from its corners: its reflected share
// becomes unshot radiosity; the power it received, absorbed and still has
// to shoot summed per workgroup (a fixed tree of additions).
@compute @workgroup_size(BOOK_WORKGROUP)
fn receive(@builtin(global_invocation_id) id: vec3<u32>, @builtin(local_invocation_index) local: u32, @builtin(workgroup_id) group: vec3<u32>) {
    let e = id.x;
    var incident = vec3<f32>(0.0);
    var absorbed = vec3<f32>(0.0);
    var left = vec3<f32>(0.0);
    var magnitude = vec3<f32>(0.0);
    if (e < book.elements) {
        let b = element_book[e];
        let count = elements[e].count;
        var sum = vec3<f32>(0.0);
        for (var k = 0u; k < count; k += 1u) {
            sum += shot_irradiance[b.corners[k]].xyz;
        }
        let mean = book.sign * (sum / f32(count));
        let u = unshot[e].xyz + b.rho * mean;
        unshot[e] = vec4<f32>(u, 0.0);
        incident = mean * b.area;
        absorbed = (vec3<f32>(1.0) - b.rho) * mean * b.area;
        left = u * b.area;
        magnitude = abs(u) * b.area;
    }
    sum_incident[local] = incident;
    sum_absorbed[local] = absorbed;
    sum_unshot[local] = left;
    sum_magnitude[local] = magnitude;
    workgroupBarrier();
    for (var stride = BOOK_WORKGROUP / 2u; stride > 0u; stride = stride / 2u) {
        if (local < stride) {
            sum_incident[local] += sum_incident[local + stride];
            sum_absorbed[local] += sum_absorbed[local + stride];
            sum_unshot[local] += sum_unshot[local + stride];
            sum_magnitude[local] += sum_magnitude[local + stride];
        }
        workgroupBarrier();
    }
    if (local == 0u) {
        partials[group.x] = Partial(
            vec4<f32>(sum_incident[0], 0.0),
            vec4<f32>(sum_absorbed[0], 0.0),
            vec4<f32>(sum_unshot[0], 0.0),
            vec4<f32>(sum_magnitude[0], 0.0),
        );
    }
}

// Each receiver's irradiance: what it had, plus the shot's; its direct
// part, plus the shot's direct share.
@compute @workgroup_size(BOOK_WORKGROUP)
fn accumulate(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= book.receivers) {
        return;
    }
    let gathered = book.sign * shot_irradiance[id.x];
    total[id.x] += gathered;
    if (any(book.direct != vec3<f32>(0.0))) {
        direct_total[id.x] += vec4<f32>(book.direct, 0.0) * gathered;
    }
}

// Each shooter's unshot power (luminance, element by element in
// magnitude), over its elements in the tree's order.
@compute @workgroup_size(WORKGROUP)
fn shooter_powers(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= book.shooters) {
        return;
    }
    let range = shooter_items[id.x];
    var power = 0.0;
    for (var i = range.x; i < range.y; i += 1u) {
        let e = items[i];
        power += abs(luminance(unshot[e].xyz)) * element_book[e].area;
    }
    powers[id.x] = power;
}

var<workgroup> best_power: array<f32, BOOK_WORKGROUP>;
var<workgroup> best_index: array<u32, BOOK_WORKGROUP>;

// The shooter with the most unshot power after the shot, as the host
// chooses it (the first of the largest; a NaN never wins; the first
// shooter when none is more than minus infinity), so that its elements'
// unshot radiosity comes back with the shot's ledger (collect_next) and
// the next shot needs no readback of its own. One workgroup.
@compute @workgroup_size(BOOK_WORKGROUP)
fn choose_next(@builtin(local_invocation_index) t: u32) {
    var p = bitcast<f32>(0xff800000u);
    var k = NONE;
    for (var i = t; i < book.shooters; i += BOOK_WORKGROUP) {
        let q = powers[i];
        if (q > p) {
            p = q;
            k = i;
        }
    }
    best_power[t] = p;
    best_index[t] = k;
    workgroupBarrier();
    for (var s = BOOK_WORKGROUP / 2u; s > 0u; s /= 2u) {
        if (t < s) {
            let q = best_power[t + s];
            let j = best_index[t + s];
            let i = best_index[t];
            if (j != NONE && (i == NONE || q > best_power[t] || (q == best_power[t] && j < i))) {
                best_power[t] = q;
                best_index[t] = j;
            }
        }
        workgroupBarrier();
    }
    if (t == 0u) {
        var chosen = best_index[0];
        if (chosen == NONE) {
            chosen = 0u;
        }
        let range = shooter_items[chosen];
        next[0] = chosen;
        next[1] = range.x;
        next[2] = range.y;
    }
}

// The chosen shooter's elements' unshot radiosity, in the tree's order.
@compute @workgroup_size(BOOK_WORKGROUP)
fn collect_next(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = next[1] + id.x;
    if (i >= next[2]) {
        return;
    }
    next_unshot[id.x] = unshot[items[i]];
}
