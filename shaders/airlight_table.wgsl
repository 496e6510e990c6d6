// F′ table builder, first pass: one invocation per cell (j, i) of row γ_i = π t_i²,
// t_i = i / (rows − 1): the cell's integral ∫_{s_{j−1}}^{s_j} p exp(−σt (d + x − D)) ds,
// s_j = j / (n − 1), by 8-point Gauss–Legendre, into column j of `cells_out`. The second pass
// (airlight_table_sum.wgsl) sums each row's cells into the heads T(γ_i, s_j) and the tails.
// Its sines are `vs_sin_poly` (relative precision; see `table_integrand`).

@group(0) @binding(0) var<storage, read> air: Airlight;
@group(0) @binding(1) var cells_out: texture_storage_2d<rgba32float, write>;

const GL8_X = array<f32, 4>(0.1834346424956498, 0.5255324099163290, 0.7966664774136267, 0.9602898564975363);
const GL8_W = array<f32, 4>(0.3626837833783620, 0.3137066458778873, 0.2223810344533745, 0.1012285362903763);

@compute @workgroup_size(64)
fn cells(@builtin(global_invocation_id) gid: vec3<u32>) {
    let rows = air.table_across;
    let n = air.table_along;
    let j = gid.x + 1u;
    let i = gid.y;
    if (j >= n || i >= rows) {
        return;
    }
    let t = f32(i) / f32(rows - 1u);
    let gamma = PI * t * t;
    // π − γ = π (1 − t)(1 + t) keeps relative precision near γ = π; the last row (γ = π,
    // light exactly behind) uses the limit w → 0, approached through a tiny w.
    let w = max(PI * (1.0 - t) * (1.0 + t), 1.0e-6);
    let sin_half_gamma = vs_sin_poly(0.5 * gamma);
    let ds = 1.0 / f32(n - 1u);
    textureStore(cells_out, vec2<u32>(j, i), vec4<f32>(cell(j, n, ds, w, gamma, sin_half_gamma), 0.0));
}

// ∫ over cell j, [s_{j−1}, s_j], of a row.
fn cell(j: u32, n: u32, ds: f32, w: f32, gamma: f32, sin_half_gamma: f32) -> vec3<f32> {
    if (j + 1u < n) {
        return gl8(0.5 * ds, (f32(j) - 0.5) * ds, w, gamma, sin_half_gamma);
    }
    // The last cell ends at s = 1 (x = ∞), where exp(−σt (d + x − D)) drops to zero within a
    // sliver of width ~ 1/(σt D) that one Gauss–Legendre rule cannot see: split it
    // geometrically towards s = 1, in 1 − s.
    var acc = vec3<f32>(0.0);
    var hi = ds;
    for (var k = 0u; k < 24u; k++) {
        let lo = select(0.25 * hi, 0.0, k == 23u);
        acc += gl8_tail(0.5 * (hi - lo), 0.5 * (hi + lo), w, gamma, sin_half_gamma);
        hi = lo;
    }
    return acc;
}

// ∫ over [mid − half, mid + half] in s.
fn gl8(half: f32, mid: f32, w: f32, gamma: f32, sin_half_gamma: f32) -> vec3<f32> {
    var acc = vec3<f32>(0.0);
    for (var k = 0u; k < 4u; k++) {
        let off = half * GL8_X[k];
        acc += GL8_W[k] * (table_integrand(air, mid - off, w, gamma, sin_half_gamma)
                         + table_integrand(air, mid + off, w, gamma, sin_half_gamma));
    }
    return acc * half;
}

// ∫ over 1 − s ∈ [mid − half, mid + half].
fn gl8_tail(half: f32, mid: f32, w: f32, gamma: f32, sin_half_gamma: f32) -> vec3<f32> {
    var acc = vec3<f32>(0.0);
    for (var k = 0u; k < 4u; k++) {
        let off = half * GL8_X[k];
        let r0 = mid - off;
        let r1 = mid + off;
        acc += GL8_W[k] * (table_integrand_split(air, 1.0 - r0, r0, w, gamma, sin_half_gamma)
                         + table_integrand_split(air, 1.0 - r1, r1, w, gamma, sin_half_gamma));
    }
    return acc * half;
}
