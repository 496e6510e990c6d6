// volshadow: shadow-map visibility of a surface point, from the shadow maps volshadow renders
// for its volumetric shadows (`nodes::ShadowMapNode`, `VolumetricShadows::shadow_map`).
//
// Self-contained: paste or concatenate it into a surface shader. Layout of the shadow map:
// a depth 2D array texture, 6 layers for a point light (cube faces +X, −X, +Y, −Y, +Z, −Z,
// 90° each) or 1 for a spot light, each face a reversed-Z infinite perspective from the light
// (depth = near / distance along the face's axis: nearer occluders have larger depths; 0 =
// nothing); a directional light: 1 orthographic layer, depth falling linearly along the
// direction of travel (again larger = nearer the light). `VolshadowShadow` holds the faces' clip_from_world matrices and the light (upload
// `nodes::ShadowMap::params()` as a storage or uniform buffer). Bind the texture as
// `texture_depth_2d_array` and a comparison sampler with `GreaterEqual` and linear filtering
// (2×2 percentage-closer filtering).
//
// Bias: the point is moved along its normal by `normal_offset` × its distance from the light
// (a relative offset, so it holds at any scene scale; 2 texels' angular size by default; for a
// directional light `normal_offset` world units, 2 texels by default), then
// counts as lit while its depth ≥ stored × (1 − depth_bias), the bias the volumetric shadows
// use. Points outside every face (behind a spot) count as lit: a spot's cone is the caller's.

struct VolshadowShadow {
    faces: array<mat4x4<f32>, 6>,  // clip_from_world of each layer (unused ones zero)
    light_pos: vec3<f32>,          // a directional light: its direction of travel
    depth_bias: f32,               // relative depth bias
    layers: u32,                   // 6: point light (cube), 1: spot or directional light
    normal_offset: f32,            // relative offset along the normal (directional: world units)
    directional: u32,              // 1: orthographic map of a directional light
    pad: f32,
}

// Visibility in [0, 1] of the surface point `p` with normal `n` (any length; zero: no offset).
fn volshadow_shadow(map: texture_depth_2d_array, cmp: sampler_comparison, sm: VolshadowShadow,
                    p: vec3<f32>, n: vec3<f32>) -> f32 {
    let directional = sm.directional != 0u;
    var to_light = sm.light_pos - p;
    var scale = sm.normal_offset * length(to_light);
    if (directional) {
        to_light = -sm.light_pos;
        scale = sm.normal_offset;
    }
    var offset = vec3<f32>(0.0);
    let nl = length(n);
    if (nl > 0.0) {
        // Towards the light's side of the surface, so a two-sided normal works either way.
        let n1 = n / nl;
        offset = select(-n1, n1, dot(n1, to_light) >= 0.0) * scale;
    }
    let q = p + offset;
    let rel = q - sm.light_pos;
    var face = 0u;
    if (sm.layers == 6u) {
        let m = abs(rel);
        if (m.x >= m.y && m.x >= m.z) {
            face = select(1u, 0u, rel.x > 0.0);
        } else if (m.y >= m.z) {
            face = select(3u, 2u, rel.y > 0.0);
        } else {
            face = select(5u, 4u, rel.z > 0.0);
        }
    }
    let clip = sm.faces[face] * vec4<f32>(q, 1.0);
    if (clip.w <= 0.0) {
        return 1.0;
    }
    let ndc = clip.xyz / clip.w;
    if (any(abs(ndc.xy) > vec2<f32>(1.0))) {
        return 1.0;
    }
    let uv = vec2<f32>(0.5 + 0.5 * ndc.x, 0.5 - 0.5 * ndc.y);
    var z = ndc.z;
    if (directional) {
        z = max(z, 0.0); // beyond the orthographic far plane: behind every occluder in the map
    }
    return textureSampleCompareLevel(map, cmp, uv, i32(face), z / (1.0 - sm.depth_bias));
}
