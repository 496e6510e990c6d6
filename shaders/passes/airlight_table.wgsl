#import prelude.wgsl
// F′ table builder, first pass: one invocation per cell (j, i) of row γ_i = π t_i²,
// t_i = i / (rows − 1): the cell's integral ∫_{s_{j−1}}^{s_j} p exp(−σt (d + x − D)) ds,
// s_j = j / (n − 1), into entry j of row i of `cells_out`. The second pass (airlight_table_sum.wgsl)
// sums each row's cells into the heads T(γ_i, s_j) and the tails. Its sines are `vs_sin_poly`
// (relative precision; see `table_integrand`).
//
// A cell is integrated by 2-, 3- or 8-point Gauss–Legendre, the fewest points that its
// integrand's smoothness on the cell's scale allows (`rule`). The last cell, which ends where
// the attenuation drops to zero, is TAIL_PIECES geometric pieces of 8 points, one invocation
// each, in entries n − 1 … n + TAIL_PIECES − 2 (entry 0 holds nothing). Every invocation runs
// the same loop over its rule's nodes: one integrand in the code, however many points, so a
// SIMD machine that executes both sides of a branch (lavapipe) runs each lane's points only.

@group(0) @binding(0) var<storage, read> air: Airlight;
@group(0) @binding(1) var<storage, read_write> cells_out: array<vec4<f32>>; // row i at i·(n + TAIL_PIECES − 1)

// The last cell's pieces (set by the node, which sizes `cells_out` by it).
override TAIL_PIECES: u32;

@compute @workgroup_size(64)
fn cells(@builtin(global_invocation_id) gid: vec3<u32>) {
    let a = air; // one copy, not one per evaluation
    let rows = a.table_across;
    let n = a.table_along;
    let j = gid.x + 1u;
    let i = gid.y;
    if (j >= n - 1u + TAIL_PIECES || i >= rows) {
        return;
    }
    let t = f32(i) / f32(rows - 1u);
    let gamma = PI * t * t;
    // π − γ = π (1 − t)(1 + t) keeps relative precision near γ = π; the last row (γ = π,
    // light exactly behind) uses the limit w → 0, approached through a tiny w.
    let w = max(PI * (1.0 - t) * (1.0 + t), 1.0e-6);
    let sin_half_gamma = vs_sin_poly(0.5 * gamma);
    let ds = 1.0 / f32(n - 1u);
    // The interval [mid − half, mid + half], in s for a cell, in 1 − s for a piece of the last
    // cell, and the rule's first node and count.
    var mid: f32;
    var half: f32;
    var first = 5u;
    var count = 8u;
    let tail = j >= n - 1u;
    if (!tail) {
        half = 0.5 * ds;
        mid = (f32(j) - 0.5) * ds;
        count = rule(a, j, n, ds, w, gamma, sin_half_gamma);
        first = select(select(5u, 2u, count == 3u), 0u, count == 2u);
    } else {
        // The last cell ends at s = 1 (x = ∞), where exp(−σt (d + x − D)) drops to zero within
        // a sliver of width ~ 1/(σt D) that one Gauss–Legendre rule cannot see: split it
        // geometrically towards s = 1, in 1 − s, piece k = [ds 4^−(k+1), ds 4^−k] (the last
        // piece down to 0). Powers of two, so the ends are exact.
        let k = j - (n - 1u);
        let hi = ldexp(ds, -2 * i32(k));
        let lo = select(0.25 * hi, 0.0, k + 1u == TAIL_PIECES);
        half = 0.5 * (hi - lo);
        mid = 0.5 * (hi + lo);
    }
    // The sines and cosines at the interval's middle, by polynomial (`cos_sin`), then turned
    // to each node by the angle-addition formulas: a node lies within e = |s − s_mid|·w/2 ≤
    // w/(4(n − 1)) of the middle, whose sine and cosine two terms of their series give to
    // f32 precision. u = (1 − s)·w/2, a = s·w/2, each with its complement (γ + w = π).
    let s_mid = select(mid, 1.0 - mid, tail);
    let oms_mid = select(1.0 - mid, mid, tail);
    let cs_u = cos_sin(0.5 * oms_mid * w, 0.5 * (gamma + s_mid * w));
    let cs_a = cos_sin(0.5 * s_mid * w, 0.5 * (gamma + oms_mid * w));
    var acc = vec3<f32>(0.0);
    for (var q = first; q < first + count; q++) {
        let node = gl_node(q);
        // The node's change of s from the middle (1 − s grows along a piece of the tail).
        let e = select(1.0, -1.0, tail) * half * node.x * 0.5 * w;
        let e2 = e * e;
        let sin_e = e - e * e2 * (1.0 / 6.0);
        let cos_e = 1.0 - 0.5 * e2;
        let su = cs_u.y * cos_e - cs_u.x * sin_e;
        let cu = cs_u.x * cos_e + cs_u.y * sin_e;
        let sa = cs_a.y * cos_e + cs_a.x * sin_e;
        acc += node.y * table_integrand_trig(a, cu, su, sa, sin_half_gamma);
    }
    cells_out[i * (n - 1u + TAIL_PIECES) + j] = vec4<f32>(acc * half, 0.0);
}

// The fewest Gauss–Legendre points (2, 3 or 8) that keep the cell's integral to ~1e-7. An
// n-point rule's error on exp(−k s) over a cell of width h is C_n (k h)^2n (C_2 = 2.3e-4,
// C_3 = 5e-7, C_8 = 2e-23: its remainder term), and on a function analytic within distance d
// of the cell about (4d/h)^−2n. The integrand's nearest singularities: s = 1 (sin u = 0: the
// attenuation's essential singularity, and HG's backward peak for g < 0) and, for g > 0, HG's
// forward peak, a pole at s = (−γ ± i (1 − g)/√g) / w. Its steepest decay in the cell is at
// the cell's end, k = σt·2D sin(γ/2) (w/2) sin(w/2) / sin²((1 − s) w/2), bounded above here
// without a sine (sin x ≥ x − x³/6 below, sin(w/2) ≤ min(w/2, 1) above): a bound only ever
// asks for more points. 2 points where k h ≤ 0.145 and d ≥ 14 h; 3 where k h ≤ 0.75 and
// d ≥ 4 h; else 8. The thresholds were chosen on an f64 model of every cell of the default
// table (σt·D 1e-4 … 1000; isotropic, Rayleigh, HG 0.5, ±0.9, ±0.99): each head and tail
// within 4.2e-6 of the exact integral, where 8 points everywhere give 1.3e-9. The table
// itself is checked against the f64 reference by tests/gpu/airlight_table.rs.
fn rule(a: Airlight, j: u32, n: u32, ds: f32, w: f32, gamma: f32, sin_half_gamma: f32) -> u32 {
    let s_lo = f32(j - 1u) * ds;
    let s_hi = f32(j) * ds;
    var dist = 1.0 - s_hi;
    let g = a.hg_g;
    if (any(a.w_hg.xyz != vec3<f32>(0.0)) && g > 0.0) {
        let re = s_lo + gamma / w;
        let im = (1.0 - g) / (vs_sqrt(g) * w);
        dist = min(dist, vs_sqrt(re * re + im * im));
    }
    let x = 0.5 * (1.0 - s_hi) * w;
    let sd = x * (1.0 - x * x / 6.0);
    let sigma_d = max(max(a.sigma_t.x, a.sigma_t.y), a.sigma_t.z) * a.distance;
    let kh = sigma_d * sin_half_gamma * w * min(0.5 * w, 1.0) / max(sd * sd, 1.0e-30) * ds;
    if (kh <= 0.145 && dist >= 14.0 * ds) {
        return 2u;
    }
    if (kh <= 0.75 && dist >= 4.0 * ds) {
        return 3u;
    }
    return 8u;
}


// Gauss–Legendre node q on [−1, 1] and its weight: 2 points (q = 0, 1), 3 (2 … 4), 8 (5 … 12).
// A chain of selects, not an indexed array: a per-lane index into a constant array becomes a
// private copy and a gather on some drivers (lavapipe).
fn gl_node(q: u32) -> vec2<f32> {
    var r = vec2<f32>(-0.5773502691896258, 1.0);
    r = select(r, vec2<f32>(0.5773502691896258, 1.0), q == 1u);
    r = select(r, vec2<f32>(-0.7745966692414834, 0.5555555555555556), q == 2u);
    r = select(r, vec2<f32>(0.0, 0.8888888888888888), q == 3u);
    r = select(r, vec2<f32>(0.7745966692414834, 0.5555555555555556), q == 4u);
    r = select(r, vec2<f32>(-0.9602898564975363, 0.1012285362903763), q == 5u);
    r = select(r, vec2<f32>(-0.7966664774136267, 0.2223810344533745), q == 6u);
    r = select(r, vec2<f32>(-0.525532409916329, 0.3137066458778873), q == 7u);
    r = select(r, vec2<f32>(-0.1834346424956498, 0.362683783378362), q == 8u);
    r = select(r, vec2<f32>(0.1834346424956498, 0.362683783378362), q == 9u);
    r = select(r, vec2<f32>(0.525532409916329, 0.3137066458778873), q == 10u);
    r = select(r, vec2<f32>(0.7966664774136267, 0.2223810344533745), q == 11u);
    r = select(r, vec2<f32>(0.9602898564975363, 0.1012285362903763), q == 12u);
    return r;
}
