// The book-keeping of a round on the GPU (design.md section 2, step 5, as
// radiosity::solver does it on the host for the CPU). Each pass of a
// round's shooters adds what the receivers gathered, times its sign, to the
// round's irradiance and its direct share to the round's direct part
// (gathered); an overshooting shot that sends negative light does so in a
// second pass, its irradiance times the sign -1. When the round ends: the
// shooters' unshot radiosity set to what they are left with (zero, or minus
// their overshoot), each element's reflected share rho * (mean of its
// corners' round irradiance) added to its own, each receiver's irradiance
// and direct part accumulated, the ledger's sums (power received,
// absorbed, unshot left, in sign and in magnitude) per workgroup in a fixed
// order, each shooter's unshot power (in magnitude). After the gather
// files; its bindings are declared by shaders.rs. No float atomics: a rerun
// gives the same result to the last bit.

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

// What an element of a round's shooter is left with.
struct Leave {
    value: vec3<f32>,
    element: u32,
}

struct Book {
    // Elements whose unshot radiosity the host asked for (collect), or
    // that are left with a value (leave_shooters).
    count: u32,
    // Shooters of more than serial_items elements.
    large: u32,
    elements: u32,
    receivers: u32,
    shooters: u32,
    // 1, or -1 for a pass of negative light sent negated.
    sign: f32,
    // A round takes the shooters above this fraction of the brightest.
    fraction: f32,
    // A shooter of more elements is summed in large_shooter_powers.
    serial_items: u32,
    // The share of the gathered irradiance that is direct, per channel
    // (the shooter's own emission's share of its power).
    direct: vec3<f32>,
    pad3: u32,
}

var<workgroup> sum_incident: array<vec3<f32>, BOOK_WORKGROUP>;
var<workgroup> sum_absorbed: array<vec3<f32>, BOOK_WORKGROUP>;
var<workgroup> sum_unshot: array<vec3<f32>, BOOK_WORKGROUP>;
var<workgroup> sum_magnitude: array<vec3<f32>, BOOK_WORKGROUP>;

// The unshot radiosity of the elements the host asks for (wanted), in
// that order, for it to prepare their sources.
@compute @workgroup_size(BOOK_WORKGROUP)
fn collect(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= book.count) {
        return;
    }
    staging[id.x] = unshot[wanted[id.x]];
}

// A pass of one of the round's shooters: what the receivers gathered,
// times its sign, into the round's irradiance, its direct share into the
// round's direct part. The walks' longest threads are added to the round's
// (the passes run one after another).
@compute @workgroup_size(BOOK_WORKGROUP)
fn gathered(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x == 0u) {
        atomicAdd(&counters[ROUND_LONGEST_WALK], atomicExchange(&counters[LONGEST_WALK], 0u));
        atomicAdd(&counters[ROUND_LONGEST_ITEM], atomicExchange(&counters[LONGEST_ITEM], 0u));
    }
    if (id.x >= book.receivers) {
        return;
    }
    let g = book.sign * shot_irradiance[id.x];
    round_irradiance[id.x] += g;
    if (any(book.direct != vec3<f32>(0.0))) {
        round_direct[id.x] += vec4<f32>(book.direct, 0.0) * g;
    }
}

// The round has shot: its shooters' elements are left with what the host
// listed (zero, or minus their overshoot).
@compute @workgroup_size(BOOK_WORKGROUP)
fn leave_shooters(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= book.count) {
        return;
    }
    let l = leaves[id.x];
    unshot[l.element] = vec4<f32>(l.value, 0.0);
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
            sum += round_irradiance[b.corners[k]].xyz;
        }
        let mean = sum / f32(count);
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

// Each receiver's irradiance and its direct part: what it had, plus the
// round's; the round's cleared for the next.
@compute @workgroup_size(BOOK_WORKGROUP)
fn accumulate(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= book.receivers) {
        return;
    }
    total[id.x] += round_irradiance[id.x];
    direct_total[id.x] += round_direct[id.x];
    round_irradiance[id.x] = vec4<f32>(0.0);
    round_direct[id.x] = vec4<f32>(0.0);
}

// The unshot power element `e` adds to its shooter's.
fn element_power(e: u32) -> f32 {
    return abs(luminance(unshot[e].xyz)) * element_book[e].area;
}

// Each shooter's unshot power (luminance, element by element in
// magnitude), over its elements in the tree's order: here a shooter of at
// most book.serial_items elements, by one thread; a larger one in
// large_shooter_powers.
@compute @workgroup_size(WORKGROUP)
fn shooter_powers(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= book.shooters) {
        return;
    }
    let range = shooter_items[id.x];
    if (range.y - range.x > book.serial_items) {
        return;
    }
    var power = 0.0;
    for (var i = range.x; i < range.y; i += 1u) {
        power += element_power(items[i]);
    }
    powers[id.x] = power;
}

var<workgroup> power_sums: array<f32, BOOK_WORKGROUP>;

// The power of a shooter of more than book.serial_items elements, a
// workgroup each: each thread sums every BOOK_WORKGROUPth element from
// its own, then the threads' sums are added pairwise. The order depends
// only on the shooter's elements, so a rerun sums them alike.
@compute @workgroup_size(BOOK_WORKGROUP)
fn large_shooter_powers(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) t: u32,
) {
    let k = group.x + group.y * groups.x;
    if (k >= book.large) {
        return;
    }
    let s = large_shooters[k];
    let range = shooter_items[s];
    var power = 0.0;
    for (var i = range.x + t; i < range.y; i += BOOK_WORKGROUP) {
        power += element_power(items[i]);
    }
    power_sums[t] = power;
    workgroupBarrier();
    for (var half = BOOK_WORKGROUP / 2u; half > 0u; half /= 2u) {
        if (t < half) {
            power_sums[t] += power_sums[t + half];
        }
        workgroupBarrier();
    }
    if (t == 0u) {
        powers[s] = power_sums[0];
    }
}

var<workgroup> best_power: array<f32, BOOK_WORKGROUP>;
var<workgroup> best_index: array<u32, BOOK_WORKGROUP>;
var<workgroup> round_best: u32;
var<workgroup> round_bar: f32;
var<workgroup> scan_elements: array<u32, BOOK_WORKGROUP>;
var<workgroup> scan_shooters: array<u32, BOOK_WORKGROUP>;
// Shooters and elements taken by the blocks before.
var<workgroup> running: vec2<u32>;

// The next round as the host chooses it (round.rs): the shooter with the
// most unshot power after this round (the first of the largest; a NaN
// never wins; the first shooter when none is more than minus infinity)
// and, when the fraction is below 1 and that power above 0, every shooter
// whose power is more than the fraction of it (compared in f32, as the
// host compares the powers the device reports). Each chosen shooter's
// first element in the round's list, by shooter index (an exclusive scan,
// block by block), into round_offsets (NONE for the others); next holds
// the brightest, the shooters chosen and their elements. One workgroup.
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
        var top = best_power[0];
        if (chosen == NONE) {
            chosen = 0u;
            top = 0.0;
        }
        round_best = chosen;
        // Above every power: the brightest alone.
        round_bar = bitcast<f32>(0x7f800000u);
        if (book.fraction < 1.0 && top > 0.0) {
            round_bar = book.fraction * top;
        }
        running = vec2<u32>(0u);
        next[0] = chosen;
    }
    workgroupBarrier();
    let best = round_best;
    let bar = round_bar;
    for (var base = 0u; base < book.shooters; base += BOOK_WORKGROUP) {
        let i = base + t;
        var size = 0u;
        var flag = 0u;
        if (i < book.shooters && (i == best || powers[i] > bar)) {
            let range = shooter_items[i];
            size = range.y - range.x;
            flag = 1u;
        }
        scan_elements[t] = size;
        scan_shooters[t] = flag;
        workgroupBarrier();
        // An inclusive scan over the block (Hillis & Steele).
        for (var s = 1u; s < BOOK_WORKGROUP; s *= 2u) {
            var a = 0u;
            var b = 0u;
            if (t >= s) {
                a = scan_elements[t - s];
                b = scan_shooters[t - s];
            }
            workgroupBarrier();
            scan_elements[t] += a;
            scan_shooters[t] += b;
            workgroupBarrier();
        }
        if (i < book.shooters) {
            var offset = NONE;
            if (flag == 1u) {
                offset = running.y + scan_elements[t] - size;
            }
            round_offsets[i] = offset;
        }
        workgroupBarrier();
        if (t == BOOK_WORKGROUP - 1u) {
            running += vec2<u32>(scan_shooters[t], scan_elements[t]);
        }
        workgroupBarrier();
    }
    if (t == 0u) {
        next[1] = running.x;
        next[2] = running.y;
    }
}

// The next round's shooters' elements' unshot radiosity, shooter by
// shooter in index order, each in the tree's order: the list the host
// prepares their sources from.
@compute @workgroup_size(BOOK_WORKGROUP)
fn collect_next(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= book.elements) {
        return;
    }
    let s = item_shooter[i];
    if (s == NONE) {
        return;
    }
    let offset = round_offsets[s];
    if (offset == NONE) {
        return;
    }
    next_unshot[offset + i - shooter_items[s].x] = unshot[items[i]];
}
