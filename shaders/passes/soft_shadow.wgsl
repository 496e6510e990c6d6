#import prelude.wgsl
#import pcss.wgsl
// Soft-shadow node: the fraction of a light's disc visible from each cell of a light-space
// grid (it imports the prelude and pcss.wgsl), which the march reads with one trilinear
// lookup per step instead of a percentage-closer soft shadow (PCSS) estimate of 49 shadow-map
// taps (145 in the deep penumbra). Cells: per shadow-map layer, `size`² directions (the layer's texel grid, coarser) by
// `slices` distances uniform in q = nearest / distance ∈ (0, 1], nearest being the least
// distance of an occluder from the light. A penumbra's width at distance d, seen from the
// light, is radius · (1/d_blocker − 1/d): linear in q, so uniform steps in q are uniform
// steps in penumbra width, and q ∈ (0, 1] reaches infinity.

// Mirrors `SoftShadowUniform` in src/nodes/soft_shadow.rs. The light, its shadow map and the
// occluders' bounds are pcss.wgsl's (group 1, `shadow`).
struct SoftShadowParams {
    // Per layer, in blocks of 2 × 2 directions (the anchor's index, see `rest_block`),
    // [x0, y0) to [x1, y1): those the build runs over (`built`: the penumbra cones reach
    // their directions or their neighbours'; the grid is lit elsewhere), and those `fill_lit`
    // sets lit first (`lit`: the last build's, which may hold a shadow no longer there).
    built: array<vec4<u32>, 6>,
    lit: array<vec4<u32>, 6>,
    world_from_clip: array<mat4x4<f32>, 6>,  // the inverses of the shadow map's layers
    size: u32,                               // cells across a layer
    slices: u32,                             // cells along the distance from the light
    layers: u32,                             // 6 (point) or 1 (spot)
}

@group(0) @binding(0) var<storage, read> mp: SoftShadowParams;
// x, y: the cell's direction in its layer; z: layer · slices + slice.
@group(0) @binding(1) var volume: texture_storage_3d<rgba16float, write>;
// The anchors: the cells of the directions at even indices in both axes, `anchor_count()`²
// per layer (x, y: the direction's index halved; z: layer · slices + slice), r = visible
// fraction, g = 1 where marked sharp. `build_anchors` writes them, `build_rest` reads them (a
// binding of each entry point's own layout).
@group(0) @binding(2) var anchors_out: texture_storage_3d<rgba16float, write>;
@group(0) @binding(2) var anchors_in: texture_3d<f32>;
// Cells before their marks (the grid's layout; r = visible fraction, g = the estimate's
// region as `soft_estimate` returns it): `estimate_listed` writes the estimated ones,
// `build_rest` the interpolated cells of the other directions' columns with listed cells;
// `between_anchors`, `store_anchors` and `store_rest` read them.
@group(0) @binding(3) var rest_out: texture_storage_3d<rg32float, write>;
@group(0) @binding(3) var rest_in: texture_3d<f32>;
// A list of cells to estimate, packed by `list_cell` (`build_anchors`, `between_anchors`
// and `build_rest` each fill one, `estimate_listed` estimates it), and its indirect dispatch:
// workgroups (x, y, z), then the number of cells listed. `estimate_listed` reads both (its
// dispatch's own arguments cannot be bound for writing).
@group(0) @binding(4) var<storage, read_write> work: array<u32>;
@group(0) @binding(4) var<storage, read> listed: array<u32>;
@group(0) @binding(5) var<storage, read_write> work_args: array<atomic<u32>, 4>;
@group(0) @binding(5) var<storage, read> listed_args: array<u32, 4>;
// Per block of `build_rest` (see `block_index`): bit j set where its
// column j has listed cells, which `store_rest` then stores; `build_rest` stores the others.
@group(0) @binding(6) var<storage, read_write> listed_columns: array<u32>;
@group(0) @binding(6) var<storage, read> listed_columns_in: array<u32>;
// Per anchor (its block's `block_index`): its slices inside a penumbra cone, [lo, hi) as
// lo | hi << 8.
@group(0) @binding(7) var<storage, read_write> anchor_ranges: array<u32>;
@group(0) @binding(7) var<storage, read> anchor_ranges_in: array<u32>;

// Most slices a thread holds (SoftShadowSize::MAX_SLICES).
const MAX_SLICES: u32 = 64u;
// A penumbra narrower than this many cells (filter radius) is marked sharp: the march blends in
// the shadow map's own visibility there. Measured (tests/gpu/soft_grid.rs, tests/gpu/soft.rs): 4 cells
// or a fade from 2 to 4 are worse on the torus and the sphere, where hard edges are too sharp
// for such penumbrae.
const SHARP_CELLS: f32 = 2.0;
// A change of visibility between neighbouring slices above which the interpolation in depth
// would smear an occluder's surface (lit in front of it, dark behind): both cells are marked
// (b, see `store_column`).
const DEPTH_JUMP: f32 = 0.35;

// q = nearest / distance at the centre of slice k of s (slice 0 nearest the light).
fn slice_q(k: u32, s: u32) -> f32 {
    return 1.0 - (f32(k) + 0.5) / f32(s);
}

// The grid is built estimating only where interpolation would not do. The anchors, the
// directions at even indices (a quarter of them), take an estimate at their even slices and
// the last, then at each odd slice whose two neighbours are not `interpolable` (else their
// mean). Each other direction's cell takes the mean of its two or four anchor neighbours
// (the midpoint of a bilinear interpolation) where they are `interpolable`, and an estimate
// where not: near an outline, a surface, a narrow penumbra or the deep penumbra. A mean of
// neighbours is also a mean of their taps: the spiral's pattern noise averages out (the
// report's soft scene p95 2.6% -> 2.1%).
//
// The estimates run from lists, one cell a thread (`estimate_listed`): a SIMD batch pays for
// its busiest lane, and a thread that estimated its own cells made its batch wait for the
// longest list among its lanes, where most had few or none. The passes: `build_anchors` lists
// the anchors' even slices and last; `between_anchors` their odd slices that need an
// estimate; `store_anchors` writes the anchors' columns; `build_rest` interpolates the other
// directions and lists what it cannot; `store_rest` writes the columns with listed cells.
// Each list is estimated between the pass that fills it and the next. Measured: see
// SoftShadowNode's docs.
// See `interpolable`. Measured: an absolute spread of 0.02 in place of the relative one
// interpolated the deep penumbra away (the eye in an umbra looking away from the light,
// tests/gpu/soft_grid.rs: p95 22.9%, 6.0% relative); looser bounds (0.15, 2 cells, 0.4) saved
// under 10% of the build.
const FLAT_SPREAD: f32 = 0.05;
const WIDE_CELLS: f32 = 4.0;
const WIDE_FOOT: f32 = 0.7;

// Anchors across a layer: the directions at even indices.
fn anchor_count() -> u32 {
    return (mp.size + 1u) / 2u;
}

// The unit direction from the light of cell (x, y) of `layer`.
fn cell_direction(x: u32, y: u32, layer: u32) -> vec3<f32> {
    let uv = (vec2<f32>(f32(x), f32(y)) + 0.5) / f32(mp.size);
    // Any depth inside the frustum names the direction; 0.5 is within reversed-Z's range for
    // the perspective layers.
    let w = mp.world_from_clip[layer] * vec4<f32>(2.0 * uv.x - 1.0, 1.0 - 2.0 * uv.y, 0.5, 1.0);
    return normalize(w.xyz / w.w - shadow.light.position);
}

// The cell of slice k in direction `dir`, as a world point.
fn cell_point(dir: vec3<f32>, k: u32, s: u32) -> vec3<f32> {
    let nearest = soft_nearest();
    return shadow.light.position + (nearest / slice_q(k, s)) * dir;
}

// The slices of `dir` inside an occluder's penumbra cone, [lo, hi): only those take taps. A
// direction outside every cone (most of a cube map's) then costs no estimate at all.
fn cone_slices(dir: vec3<f32>, s: u32) -> vec2<u32> {
    var lo = s;
    var hi = 0u;
    for (var k = 0u; k < s; k++) {
        if (may_be_hidden(cell_point(dir, k, s))) {
            lo = min(lo, k);
            hi = k + 1u;
        }
    }
    return vec2<u32>(lo, hi);
}

// The columns of cells a thread holds (one in the anchors' passes, three in `build_rest` and
// `store_rest`): the visible fraction and the estimate's region as `soft_estimate` returns
// it. Private globals, not arguments: llvmpipe copied an array passed by value at every call
// (1.7× the build).
var<private> columns: array<array<vec2<f32>, MAX_SLICES>, 3>;
// The grid coordinates (x, y) of the thread's columns.
var<private> column_xy: array<vec2<u32>, 3>;
// The cells a thread lists, column j and slice k as j · MAX_SLICES + k.
var<private> todo: array<u32, 3u * MAX_SLICES>;

// Threads of a workgroup of `estimate_listed`, and workgroups along x of its dispatch (the
// core limit per dimension; more go along y).
const LIST_GROUP: u32 = 64u;
const LIST_ROW: u32 = 65535u;

// A cell of a list: x and y (11 bits each, up to SoftShadowSize::MAX_DIRECTIONS) and
// z = layer · slices + slice (below 6 · 64).
fn list_cell(xy: vec2<u32>, z: u32) -> u32 {
    return xy.x | (xy.y << 11u) | (z << 22u);
}

// Appends the first `count` cells of `todo` (columns at `column_xy`, in `layer`) to the
// list, and widens its dispatch to cover them. The list holds every cell of a pass (the node
// sizes it so), so none is dropped.
fn list_todo(count: u32, layer: u32) {
    if (count == 0u) {
        return;
    }
    let base = atomicAdd(&work_args[3], count);
    for (var i = 0u; i < count; i++) {
        let j = todo[i] / MAX_SLICES;
        let k = todo[i] % MAX_SLICES;
        work[base + i] = list_cell(column_xy[j], layer * mp.slices + k);
    }
    let groups = (base + count + LIST_GROUP - 1u) / LIST_GROUP;
    atomicMax(&work_args[0], min(groups, LIST_ROW));
    atomicMax(&work_args[1], (groups + LIST_ROW - 1u) / LIST_ROW);
    atomicMax(&work_args[2], 1u);
}

// The cells of a workgroup of `estimate_listed` that a stage leaves to the next (their list
// index and filter width; the filter's fraction for the deep penumbra), and their counts.
var<workgroup> filter_cells: array<u32, LIST_GROUP>;
var<workgroup> filter_widths: array<f32, LIST_GROUP>;
var<workgroup> filter_count: atomic<u32>;
var<workgroup> deep_cells: array<u32, LIST_GROUP>;
var<workgroup> deep_widths: array<f32, LIST_GROUP>;
var<workgroup> deep_fractions: array<f32, LIST_GROUP>;
var<workgroup> deep_count: atomic<u32>;

// The grid cell of list entry `cell`, and its point.
fn listed_texel(cell: u32) -> vec3<u32> {
    return vec3<u32>(cell & 0x7ffu, (cell >> 11u) & 0x7ffu, cell >> 22u);
}

fn listed_point(t: vec3<u32>) -> vec3<f32> {
    let dir = cell_direction(t.x, t.y, t.z / mp.slices);
    return cell_point(dir, t.z % mp.slices, min(mp.slices, MAX_SLICES));
}

// One listed cell a thread: `soft_estimate` at its point, to `rest_out`, a stage at a time
// over the workgroup: the blocker search for every cell, then the filter for the cells the
// search left open, then the deep penumbra's taps for those the filter found in it, each
// stage's cells gathered onto the workgroup's first threads. A SIMD batch pays for its
// busiest lane: in one pass over the stages a batch with one lane in the deep penumbra
// (145 taps) held its other seven, most at 9 or 49. The same values as `soft_estimate`.
@compute @workgroup_size(64, 1, 1)
fn estimate_listed(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_index) local: u32,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let i = gid.x + gid.y * groups.x * LIST_GROUP;
    if (local == 0u) {
        atomicStore(&filter_count, 0u);
        atomicStore(&deep_count, 0u);
    }
    workgroupBarrier();
    if (i < min(listed_args[3], arrayLength(&listed))) {
        let t = listed_texel(listed[i]);
        // Neighbouring cells' exact directions turned apart (see `exact_seed` in pcss.wgsl):
        // the march's trilinear lookup averages eight of them.
        exact_seed = exact_seed_at(vec3<f32>(t));
        let found = soft_search(listed_point(t));
        if (found.z < 0.0) {
            textureStore(rest_out, t, vec4<f32>(found.xy, 0.0, 0.0));
        } else {
            let slot = atomicAdd(&filter_count, 1u);
            filter_cells[slot] = listed[i];
            filter_widths[slot] = found.z;
        }
    }
    workgroupBarrier();
    if (local < atomicLoad(&filter_count)) {
        let t = listed_texel(filter_cells[local]);
        let width = filter_widths[local];
        let f = soft_filter_at(listed_point(t), width);
        if (soft_is_deep(f)) {
            let slot = atomicAdd(&deep_count, 1u);
            deep_cells[slot] = filter_cells[local];
            deep_widths[slot] = width;
            deep_fractions[slot] = f;
        } else {
            textureStore(rest_out, t, vec4<f32>(f, width, 0.0, 0.0));
        }
    }
    workgroupBarrier();
    if (local < atomicLoad(&deep_count)) {
        let t = listed_texel(deep_cells[local]);
        let width = deep_widths[local];
        let f = soft_deepen(listed_point(t), width, deep_fractions[local]);
        textureStore(rest_out, t, vec4<f32>(f, width, 0.0, 0.0));
    }
}

// g of a cell: 1 where the estimate's region was narrower than SHARP_CELLS cells (a
// penumbra, or the edge between lit and umbra, too sharp for the grid's interpolation across
// directions): the march blends in the shadow map's own visibility there.
fn is_sharp(e: vec2<f32>) -> bool {
    return e.y >= 0.0 && e.y < SHARP_CELLS * vs_tan_poly(shadow.soft.cell_angle);
}

// Writes a direction's column to the grid. b: 1 where the visibility jumps to a neighbouring
// slice (an occluder's surface between them): the march does not interpolate across it.
fn store_column(x: u32, y: u32, layer: u32, j: u32, s: u32) {
    for (var k = 0u; k < s; k++) {
        let e = columns[j][k];
        var jump = false;
        if (k > 0u) {
            jump = jump || abs(e.x - columns[j][k - 1u].x) > DEPTH_JUMP;
        }
        if (k + 1u < s) {
            jump = jump || abs(e.x - columns[j][k + 1u].x) > DEPTH_JUMP;
        }
        let sharp = select(0.0, 1.0, is_sharp(e));
        let surface = select(0.0, 1.0, jump);
        textureStore(volume, vec3<u32>(x, y, layer * mp.slices + k), vec4<f32>(e.x, sharp, surface, 0.0));
    }
}

// The block (its anchor's index x, y, and its layer) of thread `thread` of a pass over
// `built`'s blocks: the dispatch covers the largest layer's, from each layer's corner.
fn block_of(thread: vec3<u32>) -> vec3<u32> {
    let corner = mp.built[min(thread.z, 5u)].xy;
    return vec3<u32>(thread.xy + corner, thread.z);
}

// Whether block `gid` (see `block_of`) is one of `built`'s; with `anchors`, also one past
// them right and below (their anchors, which `build_rest` reads as neighbours).
fn on_block(gid: vec3<u32>, anchors: bool) -> bool {
    if (gid.z >= mp.layers) {
        return false;
    }
    let r = mp.built[gid.z];
    if (r.z <= r.x || r.w <= r.y) {
        return false; // no block of this layer
    }
    let end = min(r.zw + select(0u, 1u, anchors), vec2<u32>(anchor_count()));
    return all(gid.xy >= r.xy) && all(gid.xy < end);
}

// The index of block `gid`'s in the per-block buffers (`anchor_ranges`, `listed_columns`).
fn block_index(gid: vec3<u32>) -> u32 {
    let a = anchor_count();
    return gid.x + a * (gid.y + a * gid.z);
}

// The cells of the last build's blocks (`lit`) outside this build's (`built`, whose cells
// the build writes), lit: the grid is lit outside `built`, and a cell the last build
// shadowed may be outside it now.
@compute @workgroup_size(8, 8, 1)
fn fill_lit(@builtin(global_invocation_id) thread: vec3<u32>) {
    if (thread.z >= mp.layers) {
        return;
    }
    let r = mp.lit[thread.z];
    let b = thread.xy + r.xy;
    if (b.x >= r.z || b.y >= r.w || on_block(vec3<u32>(b, thread.z), false)) {
        return; // not the last build's, or this build's (which writes all its cells)
    }
    for (var j = 0u; j < 4u; j++) {
        let xy = 2u * b + vec2<u32>(j & 1u, j >> 1u);
        if (xy.x < mp.size && xy.y < mp.size) {
            for (var k = 0u; k < mp.slices; k++) {
                textureStore(volume, vec3<u32>(xy, thread.z * mp.slices + k), vec4<f32>(1.0, 0.0, 0.0, 0.0));
            }
        }
    }
}

// One thread per anchor direction, through all its slices (a cell's surface mark needs its
// neighbours in depth), in three passes with the lists' estimates between them. The slices
// inside a penumbra cone (the others take no tap) and the first list: the even slices and
// the last.
@compute @workgroup_size(8, 8, 1)
fn build_anchors(@builtin(global_invocation_id) thread: vec3<u32>) {
    let gid = block_of(thread);
    if (!on_block(gid, true)) {
        return;
    }
    let s = min(mp.slices, MAX_SLICES);
    let layer = gid.z;
    column_xy[0] = 2u * gid.xy;
    let range = cone_slices(cell_direction(column_xy[0].x, column_xy[0].y, layer), s);
    anchor_ranges[block_index(gid)] = range.x | (range.y << 8u);
    var count = 0u;
    for (var k = range.x; k < range.y; k++) {
        if (k % 2u == 0u || k + 1u == s) {
            todo[count] = k;
            count++;
        }
    }
    list_todo(count, layer);
}

// An anchor's column as far as the lists have estimated it: the cells of the first list
// from `rest_in`, lit elsewhere, and with `between` the odd slices too, each the mean of its
// neighbours where they are `interpolable` (else from `rest_in`, `between_anchors` having
// listed it). Returns the number of odd slices to list in `todo` (without `between`).
fn anchor_column(gid: vec3<u32>, s: u32, between: bool) -> u32 {
    let layer = gid.z;
    column_xy[0] = 2u * gid.xy;
    let packed = anchor_ranges_in[block_index(gid)];
    let range = vec2<u32>(packed & 0xffu, packed >> 8u);
    for (var k = 0u; k < s; k++) {
        columns[0][k] = vec2<f32>(1.0, -1.0);
        if (k >= range.x && k < range.y && (k % 2u == 0u || k + 1u == s)) {
            columns[0][k] = textureLoad(rest_in, vec3<u32>(column_xy[0], layer * mp.slices + k), 0).xy;
        }
    }
    var count = 0u;
    for (var k = range.x | 1u; k + 1u < min(range.y + 1u, s); k += 2u) {
        let before = columns[0][k - 1u];
        let after = columns[0][k + 1u];
        let c0 = summary(before);
        let c1 = summary(after);
        if (interpolable(min(c0, c1), max(c0, c1))) {
            // The region: the narrower estimate's (as the rest pass reads it).
            let region = select(min(before.y, after.y), max(before.y, after.y), min(before.y, after.y) < 0.0);
            columns[0][k] = vec2<f32>(0.5 * (before.x + after.x), region);
        } else if (between) {
            columns[0][k] = textureLoad(rest_in, vec3<u32>(column_xy[0], layer * mp.slices + k), 0).xy;
        } else {
            todo[count] = k;
            count++;
        }
    }
    return count;
}

// The second list: the anchors' odd slices between two that do not agree.
@compute @workgroup_size(8, 8, 1)
fn between_anchors(@builtin(global_invocation_id) thread: vec3<u32>) {
    let gid = block_of(thread);
    if (!on_block(gid, true)) {
        return;
    }
    let s = min(mp.slices, MAX_SLICES);
    list_todo(anchor_column(gid, s, false), gid.z);
}

// The anchors' columns, complete, to the grid and to the anchors `build_rest` reads.
@compute @workgroup_size(8, 8, 1)
fn store_anchors(@builtin(global_invocation_id) thread: vec3<u32>) {
    let gid = block_of(thread);
    if (!on_block(gid, true)) {
        return;
    }
    let s = min(mp.slices, MAX_SLICES);
    anchor_column(gid, s, true);
    let layer = gid.z;
    store_column(column_xy[0].x, column_xy[0].y, layer, 0u, s);
    for (var k = 0u; k < s; k++) {
        textureStore(anchors_out, vec3<u32>(gid.x, gid.y, layer * mp.slices + k), vec4<f32>(summary(columns[0][k]), 1.0));
    }
}

// What decides whether a cell between others may be interpolated from them: its visible
// fraction, 1 where marked sharp, and the estimate's region in cells (many where it took no
// tap: nothing to resolve).
fn summary(e: vec2<f32>) -> vec3<f32> {
    let sharp = select(0.0, 1.0, is_sharp(e));
    let wide = select(min(e.y / vs_tan_poly(shadow.soft.cell_angle), 1.0e4), 1.0e4, e.y < 0.0);
    return vec3<f32>(e.x, sharp, wide);
}

// Whether the cell midway between cells whose `summary` spans [lo, hi] (component-wise) may
// take their mean: none is sharp, and they agree within FLAT_SPREAD of the larger (lit,
// umbra: relative, so that the deep penumbra, where the visible fraction is small, is
// resolved), or lie on a penumbra at least WIDE_CELLS wide, away from its foot, where the
// fraction rises as a power of the distance from the umbra (the mean of 0 and f(2) would be
// f(1) · 2^0.5).
fn interpolable(lo: vec3<f32>, hi: vec3<f32>) -> bool {
    let flat = hi.x - lo.x <= FLAT_SPREAD * hi.x;
    let wide = lo.z >= WIDE_CELLS && lo.x >= WIDE_FOOT * hi.x;
    return hi.y == 0.0 && (flat || wide);
}

// Whether block `gid` (see `block_of`) of `build_rest` and `store_rest` is one of `built`'s:
// 2 × 2 directions (its anchor's, at even indices, and the three others), whose other
// directions it puts in `column_xy`: (1, 0), (0, 1), (1, 1) from the anchor.
fn rest_block(gid: vec3<u32>) -> bool {
    if (!on_block(gid, false)) {
        return false;
    }
    column_xy = array<vec2<u32>, 3>(
        vec2<u32>(2u * gid.x + 1u, 2u * gid.y),
        vec2<u32>(2u * gid.x, 2u * gid.y + 1u),
        vec2<u32>(2u * gid.x + 1u, 2u * gid.y + 1u),
    );
    return true;
}

// The other directions: one thread per block (see `rest_block`), reading the four anchors
// around the three once a slice.
@compute @workgroup_size(8, 8, 1)
fn build_rest(@builtin(global_invocation_id) thread: vec3<u32>) {
    let gid = block_of(thread);
    if (!rest_block(gid)) {
        return;
    }
    let a = anchor_count();
    let n = mp.size;
    let s = min(mp.slices, MAX_SLICES);
    let layer = gid.z;
    let xy = column_xy;
    // Each interpolates its anchor neighbours where they all exist: x ± 1 where x is odd.
    let right = gid.x + 1u < a && 2u * gid.x + 2u < n;
    let below = gid.y + 1u < a && 2u * gid.y + 2u < n;
    let ax = vec2<u32>(gid.x, min(gid.x + 1u, a - 1u));
    let ay = vec2<u32>(gid.y, min(gid.y + 1u, a - 1u));
    // Four anchors outside every penumbra cone: all lit, as the mean of their lit cells
    // would be (the same values, without the loads).
    var lit_block = true;
    for (var i = 0u; i < 4u; i++) {
        let packed = anchor_ranges_in[ax[i & 1u] + a * (ay[i >> 1u] + a * layer)];
        lit_block = lit_block && (packed & 0xffu) >= (packed >> 8u);
    }
    if (lit_block) {
        listed_columns[block_index(gid)] = 0u;
        for (var j = 0u; j < 3u; j++) {
            if (xy[j].x < n && xy[j].y < n) {
                for (var k = 0u; k < s; k++) {
                    textureStore(volume, vec3<u32>(xy[j], layer * mp.slices + k), vec4<f32>(1.0, 0.0, 0.0, 0.0));
                }
            }
        }
        return;
    }
    var dirs: array<vec3<f32>, 3>;
    for (var j = 0u; j < 3u; j++) {
        dirs[j] = cell_direction(min(xy[j].x, n - 1u), min(xy[j].y, n - 1u), layer);
    }
    var count = 0u;
    for (var k = 0u; k < s; k++) {
        let z = layer * mp.slices + k;
        let c00 = textureLoad(anchors_in, vec3<u32>(ax.x, ay.x, z), 0).xyz;
        let c10 = textureLoad(anchors_in, vec3<u32>(ax.y, ay.x, z), 0).xyz;
        let c01 = textureLoad(anchors_in, vec3<u32>(ax.x, ay.y, z), 0).xyz;
        let c11 = textureLoad(anchors_in, vec3<u32>(ax.y, ay.y, z), 0).xyz;
        for (var j = 0u; j < 3u; j++) {
            // (1, 0) between c00 and c10; (0, 1) between c00 and c01; (1, 1) amid all four.
            var lo = c00;
            var hi = c00;
            var sum = c00.x;
            var bounded = right && below;
            if (j != 1u) {
                lo = min(lo, c10);
                hi = max(hi, c10);
                sum += c10.x;
            }
            if (j != 0u) {
                lo = min(lo, c01);
                hi = max(hi, c01);
                sum += c01.x;
            }
            if (j == 2u) {
                lo = min(lo, c11);
                hi = max(hi, c11);
                sum += c11.x;
            } else {
                bounded = select(below, right, j == 0u);
            }
            let agree = bounded && interpolable(lo, hi);
            columns[j][k] = vec2<f32>(sum / f32(select(2u, 4u, j == 2u)), -1.0);
            if (!agree) {
                columns[j][k] = vec2<f32>(1.0, -1.0);
                if (xy[j].x < n && xy[j].y < n && may_be_hidden(cell_point(dirs[j], k, s))) {
                    todo[count] = j * MAX_SLICES + k;
                    count++;
                }
            }
        }
    }
    var listed_mask = 0u;
    for (var i = 0u; i < count; i++) {
        listed_mask |= 1u << (todo[i] / MAX_SLICES);
    }
    list_todo(count, layer);
    listed_columns[block_index(gid)] = listed_mask;
    // A column with listed cells waits for them in `rest_out`; the others are complete.
    for (var j = 0u; j < 3u; j++) {
        if (xy[j].x < n && xy[j].y < n) {
            if ((listed_mask & (1u << j)) != 0u) {
                for (var k = 0u; k < s; k++) {
                    textureStore(rest_out, vec3<u32>(xy[j], layer * mp.slices + k), vec4<f32>(columns[j][k], 0.0, 0.0));
                }
            } else {
                store_column(xy[j].x, xy[j].y, layer, j, s);
            }
        }
    }
}

// The other directions' columns with listed cells, from `rest_in`, to the grid with their
// marks: one thread a block, as `build_rest`.
@compute @workgroup_size(8, 8, 1)
fn store_rest(@builtin(global_invocation_id) thread: vec3<u32>) {
    let gid = block_of(thread);
    if (!rest_block(gid)) {
        return;
    }
    let a = anchor_count();
    let s = min(mp.slices, MAX_SLICES);
    let layer = gid.z;
    let xy = column_xy;
    let listed_mask = listed_columns_in[block_index(gid)];
    for (var j = 0u; j < 3u; j++) {
        if ((listed_mask & (1u << j)) != 0u) {
            for (var k = 0u; k < s; k++) {
                columns[j][k] = textureLoad(rest_in, vec3<u32>(xy[j], layer * mp.slices + k), 0).xy;
            }
            store_column(xy[j].x, xy[j].y, layer, j, s);
        }
    }
}

// The grid as the build left it (binding 3 of the other entry points, written there), and its
// copy with the shaft mark (a = 1 near a narrow shaft), which the march reads: the entry
// point `mark_shafts` reads the one and writes the other.
@group(0) @binding(1) var grid_in: texture_3d<f32>;
@group(0) @binding(2) var marked: texture_storage_3d<rgba16float, write>;

// Cells on either side of a cell that `mark_shafts` looks at, along each axis of a layer.
// Measured on the gap scenes of tests/gpu/soft_grid.rs (12²), on slits 1.30 and 1.34 of the
// light's diameter (seeds 404, 408), whose plateaus are wide: with 8, seed 404 at p95 3.19%;
// with 12, 2.41% and 4.00%; with 20, 0.58% and 0.51%.
const SHAFT_REACH: i32 = 20;
// How far a peak's visible fraction must rise above the lowest cell on each side of it (and
// how much more of the light the slice before a cell must see for the cell to lie just behind
// a surface): about three of the filter's 32 taps, above its noise. Measured on the gap scenes
// of tests/gpu/soft_grid.rs (12²): a square hole 1.25 of the light's diameter in a plate
// turned to the light (seed 406), whose deep penumbra beside the shaft rises little, p95 4.34%
// with 0.2, 3.83% with 0.15, 2.62% with 0.1; blinds of 7 slats (seed 401) 2.97% with 0.2 and
// 0.1, 2.60% with 0.05, where the hole is at 2.94%.
const SHAFT_RISE: f32 = 0.1;
// The highest visible fraction a shaft's peak may have: through a gap narrower than the light
// no point sees all of it, where a lit gap between two occluders' shadows reaches 1 and keeps
// the grid.
const SHAFT_PEAK: f32 = 0.95;
// A workgroup's cells across (one slice of one layer), and the tile of the grid it reads:
// its cells and SHAFT_REACH more on every side.
const SHAFT_GROUP: u32 = 8u;
const SHAFT_SPAN: u32 = 48u; // SHAFT_GROUP + 2 · SHAFT_REACH
var<workgroup> shaft_tile: array<f32, 2304>; // SHAFT_SPAN²
// The tile's least and greatest visible fraction (the bits of non-negative floats order as
// the floats do).
var<workgroup> shaft_low: atomic<u32>;
var<workgroup> shaft_high: atomic<u32>;

// Whether, within SHAFT_REACH cells of the tile's cell `t` along `axis`, a cell's visible
// fraction rises above the lowest on both of its sides by SHAFT_RISE. A cell just behind a
// surface (stored as -1 in the tile) is neither a peak nor a side: the lowest on a side is
// taken from beyond the nearest such cell only. A receiver that a penumbra falls on darkens
// the slices behind it, and those are not the side of a gap.
fn shaft_along(t: vec2<u32>, axis: vec2<u32>, reach: u32) -> bool {
    var v: array<f32, 41>; // 2 · SHAFT_REACH + 1
    // The lowest fraction from the cell back to the nearest cell just behind a surface.
    var lowest_before: array<f32, 41>;
    var low = 2.0;
    let first = t - reach * axis;
    let count = 2u * reach + 1u;
    for (var i = 0u; i < count; i++) {
        let q = first + i * axis;
        v[i] = shaft_tile[q.y * SHAFT_SPAN + q.x];
        low = select(min(low, v[i]), 2.0, v[i] < 0.0);
        lowest_before[i] = low;
    }
    low = 2.0;
    for (var i = i32(count) - 1; i >= 0; i--) {
        low = select(min(low, v[i]), 2.0, v[i] < 0.0);
        let peak = v[i] >= 0.0 && v[i] < SHAFT_PEAK;
        if (peak && v[i] - lowest_before[i] > SHAFT_RISE && v[i] - low > SHAFT_RISE) {
            return true;
        }
    }
    return false;
}

// Where the cells are exact (the occluders' triangles given, `soft_exact`), `mark_shafts`
// marks a cell whose second difference along the layer's two axes or the slices exceeds a
// tenth of the largest of the three cells' fractions, at most CURVE_MARK and at least
// CURVE_FLOOR: the trilinear lookup's error between cells is about an eighth of it, and a
// sliver beside a shaft, at 1% of the light, needs it relative (the gap scenes of
// tests/gpu/soft_grid.rs, a door ajar by 0.23 of the light's diameter, seed 411: p95 62.5%
// with 0.04 alone, 1.27% so). Its marks near a shaft reach EXACT_SHAFT_REACH cells, not
// SHAFT_REACH: a shaft many cells wide, far from its gap, is smooth enough for the lookup,
// and the marks reaching 20 cells covered a whole room lit through a door ajar
// (benches/scenes/door_ajar, 256² on lavapipe: 6.96 s a frame with 20 cells and every step
// between lit and umbra refined, 5.12 s so). With the curvature's marks and none near a
// shaft, a door ajar by 24° (seed 443) went from p95 2.30% to 3.31%.
const CURVE_MARK: f32 = 0.04;
const CURVE_MARK_OF_V: f32 = 0.1;
const CURVE_FLOOR: f32 = 1.0e-4;
const EXACT_SHAFT_REACH: u32 = 6u;

// Whether the exact cell `c` of slice `z` is curved (see CURVE_MARK; along the axes it has
// neighbours on both sides in its layer and slices).
fn curved(c: vec2<i32>, z: i32) -> bool {
    let n = i32(mp.size);
    let v = textureLoad(grid_in, vec3<i32>(c, z), 0).x;
    var most = 0.0;
    var high = v;
    for (var a = 0; a < 3; a++) {
        var lo = vec3<i32>(c, z);
        var hi = lo;
        if (a < 2) {
            let step = select(vec2<i32>(0, 1), vec2<i32>(1, 0), a == 0);
            if (any(c - step < vec2<i32>(0)) || any(c + step >= vec2<i32>(n))) {
                continue;
            }
            lo = vec3<i32>(c - step, z);
            hi = vec3<i32>(c + step, z);
        } else {
            let k = u32(z) % mp.slices;
            if (k == 0u || k + 1u >= mp.slices) {
                continue;
            }
            lo = vec3<i32>(c, z - 1);
            hi = vec3<i32>(c, z + 1);
        }
        let a_lo = textureLoad(grid_in, lo, 0).x;
        let a_hi = textureLoad(grid_in, hi, 0).x;
        most = max(most, abs(a_lo + a_hi - 2.0 * v));
        high = max(high, max(a_lo, a_hi));
    }
    return most > max(CURVE_FLOOR, min(CURVE_MARK, CURVE_MARK_OF_V * high));
}

// The cells of `layer` whose marks this build may change, [x0, y0) to [x1, y1): the blocks
// it writes (`built`) or sets lit (`lit`), and SHAFT_REACH cells around them. Elsewhere the
// grid, and so its copy, is as the last build left it.
fn mark_region(layer: u32) -> vec4<u32> {
    var r = vec4<u32>(mp.size, mp.size, 0u, 0u);
    for (var i = 0u; i < 2u; i++) {
        let b = select(mp.lit[layer], mp.built[layer], i == 0u);
        if (b.z > b.x && b.w > b.y) {
            r = vec4<u32>(min(r.xy, 2u * b.xy), max(r.zw, 2u * b.zw));
        }
    }
    let reach = u32(SHAFT_REACH);
    return vec4<u32>(max(r.xy, vec2<u32>(reach)) - reach, min(r.zw + reach, vec2<u32>(mp.size)));
}

// The grid's copy for the march, with a = 1 where a cell lies within SHAFT_REACH cells of a
// narrow shaft: a visible fraction that falls on both sides across the layer, as through a
// gap narrower than the light (exact cells: within EXACT_SHAFT_REACH, or curved, see
// CURVE_MARK). The march's trilinear lookup cuts the corners of such a
// profile where it meets the umbra (too bright at the shaft's foot) and the shadow map's own
// visibility, which it blends in at marked cells, is the light's centre alone (0 or 1); the
// march takes the per-point estimate at its steps there instead (where it takes one layer of
// blockers: see `refined_step` in march.wgsl). An occluder's own penumbra falls one way only
// (lit to umbra), so a scene without gaps has no mark and costs no estimate; nor does the
// shadow that a surface under a penumbra casts on the slices behind it (see `shaft_along`).
@compute @workgroup_size(8, 8, 1)
fn mark_shafts(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(local_invocation_id) local: vec3<u32>,
    @builtin(local_invocation_index) index: u32,
) {
    let n = i32(mp.size);
    let z = i32(group.z);
    // A tile outside the region: nothing to change (the same for the whole workgroup).
    let region = mark_region(group.z / mp.slices);
    let corner = group.xy * SHAFT_GROUP;
    if (any(corner >= region.zw) || any(corner + SHAFT_GROUP <= region.xy)) {
        return;
    }
    if (index == 0u) {
        atomicStore(&shaft_low, bitcast<u32>(2.0));
        atomicStore(&shaft_high, 0u);
    }
    workgroupBarrier();
    // The tile, clamped to the layer's edges.
    let origin = vec2<i32>(group.xy * SHAFT_GROUP) - SHAFT_REACH;
    var low = 2.0;
    var high = 0.0;
    for (var i = index; i < SHAFT_SPAN * SHAFT_SPAN; i += SHAFT_GROUP * SHAFT_GROUP) {
        let q = clamp(origin + vec2<i32>(vec2<u32>(i % SHAFT_SPAN, i / SHAFT_SPAN)), vec2<i32>(0), vec2<i32>(n - 1));
        let v = clamp(textureLoad(grid_in, vec3<i32>(q, z), 0).x, 0.0, 1.0);
        // Just behind a surface: the slice before (nearer the light) saw more than SHAFT_RISE
        // more of the light.
        var behind = false;
        if (u32(z) % mp.slices > 0u) {
            let before = clamp(textureLoad(grid_in, vec3<i32>(q, z - 1), 0).x, 0.0, 1.0);
            behind = before - v > SHAFT_RISE;
        }
        shaft_tile[i] = select(v, -1.0, behind);
        low = min(low, v);
        high = max(high, v);
    }
    atomicMin(&shaft_low, bitcast<u32>(low));
    atomicMax(&shaft_high, bitcast<u32>(high));
    workgroupBarrier();
    let cell = group.xy * SHAFT_GROUP + local.xy;
    if (any(cell >= vec2<u32>(mp.size))) {
        return;
    }
    let g = textureLoad(grid_in, vec3<i32>(vec2<i32>(cell), z), 0);
    // A tile whose fractions all lie within SHAFT_RISE of each other holds no peak.
    var shaft = false;
    var reach = u32(SHAFT_REACH);
    if (shadow.soft.groups > 0u) {
        shaft = curved(vec2<i32>(cell), z);
        reach = EXACT_SHAFT_REACH;
    }
    if (bitcast<f32>(atomicLoad(&shaft_high)) - bitcast<f32>(atomicLoad(&shaft_low)) > SHAFT_RISE) {
        let t = local.xy + u32(SHAFT_REACH);
        shaft = shaft || shaft_along(t, vec2<u32>(1u, 0u), reach) || shaft_along(t, vec2<u32>(0u, 1u), reach);
    }
    textureStore(marked, vec3<i32>(vec2<i32>(cell), z), vec4<f32>(g.xyz, select(0.0, 1.0, shaft)));
}
