#import prelude.wgsl
// F′ table builder, second pass: each row's cells (airlight_table.wgsl) summed into its entries.
// Entry j holds T(γ_i, s_j) = ∫₀^{s_j}, the cells 1 … j; entry n + j the tail ∫_{s_j}^1, the
// cells j + 1 … n − 1 summed from s = 1 (never a difference of heads: an interval far beyond
// the integrand's peak is a small difference of two small tails, see `t_between`). The last
// cell comes as TAIL_PIECES pieces (entries n − 1 onwards), added smallest first.
//
// Every cell is positive, so a sum's relative rounding error is at most its depth (the
// additions on the longest path to it) times 2^-24, whatever the magnitudes: no compensation
// (which drivers may compile away: lavapipe folds TwoSum's error term to zero). Both entry
// points keep the depth near 2√n rather than n:
// * `sum_serial`, one invocation a row (a CPU adapter, where the rows alone keep the cores
//   busy): runs of RUN cells summed apart, then added to the total of the runs before;
// * `sum_scan`, one workgroup a row (a GPU): each invocation sums a run of cells, and the runs'
//   totals are scanned across the workgroup from either end (depth log₂ 256 = 8).

@group(0) @binding(0) var<storage, read> air: Airlight;
@group(0) @binding(1) var<storage, read> cells_in: array<vec4<f32>>;
@group(0) @binding(2) var table_out: texture_storage_2d<rgba32float, write>;

override TAIL_PIECES: u32;

fn entry(t: vec3<f32>) -> vec4<f32> {
    return vec4<f32>(t, 0.0);
}

// Row i's cells start here.
fn row_start(i: u32, n: u32) -> u32 {
    return i * (n - 1u + TAIL_PIECES);
}

// The last cell: its pieces, smallest first.
fn last_cell(i: u32, n: u32) -> vec3<f32> {
    var last = vec3<f32>(0.0);
    for (var k = TAIL_PIECES; k >= 1u; k--) {
        last += cells_in[row_start(i, n) + n - 2u + k].xyz;
    }
    return last;
}

// Cell j (1 ≤ j ≤ n − 1) of row i, given the row's last cell.
fn cell(j: u32, i: u32, n: u32, last: vec3<f32>) -> vec3<f32> {
    return select(cells_in[row_start(i, n) + j].xyz, last, j == n - 1u);
}

// Cells per run of `sum_serial`.
const RUN: u32 = 16u;

@compute @workgroup_size(64)
fn sum_serial(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    let n = air.table_along;
    if (i >= air.table_across) {
        return;
    }
    let last = last_cell(i, n);
    // Heads: the runs before (`base`) plus the current run's cells so far.
    var base = vec3<f32>(0.0);
    var run = vec3<f32>(0.0);
    textureStore(table_out, vec2<u32>(0u, i), vec4<f32>(0.0));
    for (var j = 1u; j < n; j++) {
        run += cell(j, i, n, last);
        textureStore(table_out, vec2<u32>(j, i), entry(base + run));
        if (j % RUN == 0u) {
            base += run;
            run = vec3<f32>(0.0);
        }
    }
    // Tails, the same from the end: the tail of entry j − 1 is the cells j … n − 1.
    base = vec3<f32>(0.0);
    run = vec3<f32>(0.0);
    textureStore(table_out, vec2<u32>(2u * n - 1u, i), vec4<f32>(0.0));
    for (var j = n - 1u; j >= 1u; j--) {
        run += cell(j, i, n, last);
        textureStore(table_out, vec2<u32>(n + j - 1u, i), entry(base + run));
        if ((n - j) % RUN == 0u) {
            base += run;
            run = vec3<f32>(0.0);
        }
    }
}

const WG: u32 = 256u;

var<workgroup> scan: array<vec3<f32>, WG>;
var<workgroup> shared_last: vec3<f32>;

// The sum of the runs before invocation l's (`from_end`: after it), over the workgroup
// (Hillis–Steele).
fn exclusive_scan(own: vec3<f32>, l: u32, from_end: bool) -> vec3<f32> {
    let p = select(l, WG - 1u - l, from_end);
    var acc = own;
    for (var offset = 1u; offset < WG; offset *= 2u) {
        scan[p] = acc;
        workgroupBarrier();
        if (p >= offset) {
            acc = scan[p - offset] + acc;
        }
        workgroupBarrier();
    }
    // Inclusive → exclusive: the preceding position's inclusive sum.
    scan[p] = acc;
    workgroupBarrier();
    var before = vec3<f32>(0.0);
    if (p >= 1u) {
        before = scan[p - 1u];
    }
    workgroupBarrier();
    return before;
}

@compute @workgroup_size(WG)
fn sum_scan(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) l: u32) {
    let i = wg.x;
    let n = air.table_along;
    if (l == 0u) {
        shared_last = last_cell(i, n);
    }
    workgroupBarrier();
    let last = shared_last;
    // This invocation's run of cells [lo, hi) within 1 … n − 1.
    let m = (n - 1u + WG - 1u) / WG;
    let lo = min(1u + l * m, n);
    let hi = min(lo + m, n);
    var run = vec3<f32>(0.0);
    for (var j = lo; j < hi; j++) {
        run += cell(j, i, n, last);
    }
    let before = exclusive_scan(run, l, false);
    let after = exclusive_scan(run, l, true);
    if (l == 0u) {
        textureStore(table_out, vec2<u32>(0u, i), vec4<f32>(0.0));
        textureStore(table_out, vec2<u32>(2u * n - 1u, i), vec4<f32>(0.0));
    }
    var head = vec3<f32>(0.0);
    for (var j = lo; j < hi; j++) {
        head += cell(j, i, n, last);
        textureStore(table_out, vec2<u32>(j, i), entry(before + head));
    }
    var tail = vec3<f32>(0.0);
    for (var j = hi; j > lo; j--) {
        tail += cell(j - 1u, i, n, last);
        textureStore(table_out, vec2<u32>(n + j - 2u, i), entry(after + tail));
    }
}
