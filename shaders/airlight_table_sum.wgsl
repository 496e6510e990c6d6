// F′ table builder, second pass: one invocation per row, summing the first pass's cells
// (airlight_table.wgsl) in order. Entry j holds T(γ_i, s_j) = ∫₀^{s_j}, the cells 1 … j; entry
// n + j the tail ∫_{s_j}^1, the cells j + 1 … n − 1 summed from s = 1 (never a difference of
// heads). Compensated (Kahan) sums: a row of 255 cells keeps the f32 sum to ~1e-7 relative.

@group(0) @binding(0) var<storage, read> air: Airlight;
@group(0) @binding(1) var cells_in: texture_2d<f32>;
@group(0) @binding(2) var table_out: texture_storage_2d<rgba32float, write>;

@compute @workgroup_size(64)
fn sum(@builtin(global_invocation_id) gid: vec3<u32>) {
    let rows = air.table_across;
    let n = air.table_along;
    let i = gid.x;
    if (i >= rows) {
        return;
    }
    // Columns [0, n): T from the eye (s = 0) to s_j. Columns [n, 2n): the tail, T from s_j to
    // the end (s = 1): an interval far from where the integrand peaks (an optically thick
    // medium) is a small difference of two large heads, but of two small tails when it lies
    // beyond the peak (see `t_between` in prelude.wgsl).
    var total = vec3<f32>(0.0);
    var carry = vec3<f32>(0.0);
    textureStore(table_out, vec2<u32>(0u, i), vec4<f32>(0.0));
    for (var j = 1u; j < n; j++) {
        let y = textureLoad(cells_in, vec2<u32>(j, i), 0).xyz - carry;
        let next = total + y;
        carry = (next - total) - y;
        total = next;
        textureStore(table_out, vec2<u32>(j, i), vec4<f32>(total, 0.0));
    }
    total = vec3<f32>(0.0);
    carry = vec3<f32>(0.0);
    textureStore(table_out, vec2<u32>(2u * n - 1u, i), vec4<f32>(0.0));
    for (var j = n - 1u; j >= 1u; j--) {
        let y = textureLoad(cells_in, vec2<u32>(j, i), 0).xyz - carry;
        let next = total + y;
        carry = (next - total) - y;
        total = next;
        textureStore(table_out, vec2<u32>(n + j - 1u, i), vec4<f32>(total, 0.0));
    }
}
