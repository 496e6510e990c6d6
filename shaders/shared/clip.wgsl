// Helpers of the clipped vertex stages (`vs_shadow_clipped` in shadow_map.wgsl, around the
// light; `vs_volume_clipped` in extents.wgsl, around the eye), which clip a triangle before the
// rasteriser does.

fn max_abs(v: vec3<f32>) -> f32 {
    let a = abs(v);
    return max(a.x, max(a.y, a.z));
}

// Whether `a` precedes `b` in lexicographic order (x, then y, z, w): a clipped edge is cut from
// its lesser end, so that the two triangles sharing it cut it at the same point.
fn precedes(a: vec4<f32>, b: vec4<f32>) -> bool {
    if (a.x != b.x) {
        return a.x < b.x;
    }
    if (a.y != b.y) {
        return a.y < b.y;
    }
    if (a.z != b.z) {
        return a.z < b.z;
    }
    return a.w < b.w;
}
