// volshadow: shadow-map visibility of a surface point, from the shadow maps volshadow renders
// for its volumetric shadows (`nodes::ShadowMapNode`, `VolumetricShadows::shadow_map`).
//
// Self-contained: paste or concatenate it into a surface shader. Layout of the shadow map:
// a depth 2D array texture, 6 layers for a point light (cube faces +X, −X, +Y, −Y, +Z, −Z,
// 90° each) or 1 for a spot light, each face a reversed-Z infinite perspective from the light
// (depth = near / distance along the face's axis: nearer occluders have larger depths; 0 =
// nothing); a directional light: one orthographic layer per cascade (nearest the eye first),
// depth falling linearly along the direction of travel (again larger = nearer the light). `VolshadowShadow` holds the faces' clip_from_world matrices and the light (upload
// `nodes::ShadowMap::params()` as a storage or uniform buffer). Bind the texture as
// `texture_depth_2d_array` and a comparison sampler with `GreaterEqual` and linear filtering
// (2×2 percentage-closer filtering).
//
// Bias: the point is moved along its normal by `normal_offset` × its distance from the light
// (a relative offset, so it holds at any scene scale; 2 texels' angular size by default), then
// counts as lit while its depth ≥ stored × (1 − depth_bias), the bias the volumetric shadows
// use. Points outside every face (behind a spot) count as lit: a spot's cone is the caller's.
// A directional light: the point takes the first cascade whose square holds it (within a
// texel of the edge) and whose far plane it is not beyond, else the last whose square holds
// it (at its far plane), else it is lit; it moves `normal_offset` world units in the first
// cascade and as many texels in the others (2 texels by default), and counts as lit while it
// lies less than 2 of its cascade's texels beyond the stored depth (the volumetric shadows'
// bias).

struct VolshadowShadow {
    faces: array<mat4x4<f32>, 6>,  // clip_from_world of each layer (unused ones zero)
    light_pos: vec3<f32>,          // a directional light: its direction of travel
    depth_bias: f32,               // relative depth bias
    layers: u32,                   // 6: point light (cube), 1: spot, directional: cascades
    normal_offset: f32,            // relative offset along the normal (directional: world
                                   // units in the first cascade)
    directional: u32,              // 1: orthographic map of a directional light
    pad: f32,
}

// A directional light's cascade for `p` (see the header), `layers` when none holds it.
fn volshadow_cascade(sm: VolshadowShadow, size: f32, p: vec3<f32>) -> u32 {
    let edge = 1.0 - 2.0 / size;
    var found = sm.layers;
    for (var k = 0u; k < min(sm.layers, 6u); k++) {
        let c = sm.faces[k] * vec4<f32>(p, 1.0);
        if (all(abs(c.xy) <= vec2<f32>(edge))) {
            found = k;
            if (c.z >= 0.0) {
                break;
            }
        }
    }
    return found;
}

// Half the width of an orthographic layer's square.
fn volshadow_half_width(m: mat4x4<f32>) -> f32 {
    return 1.0 / length(vec3<f32>(m[0].x, m[1].x, m[2].x));
}

// Visibility in [0, 1] of the surface point `p` with normal `n` (any length; zero: no offset).
fn volshadow_shadow(map: texture_depth_2d_array, cmp: sampler_comparison, sm: VolshadowShadow,
                    p: vec3<f32>, n: vec3<f32>) -> f32 {
    let directional = sm.directional != 0u;
    var to_light = sm.light_pos - p;
    var scale = sm.normal_offset * length(to_light);
    let size = f32(textureDimensions(map).x);
    if (directional) {
        to_light = -sm.light_pos;
        // As many texels in the point's cascade as `normal_offset` is in the first.
        let k = volshadow_cascade(sm, size, p);
        if (k >= sm.layers) {
            return 1.0;
        }
        scale = sm.normal_offset * volshadow_half_width(sm.faces[k])
            / volshadow_half_width(sm.faces[0]);
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
    if (directional) {
        face = volshadow_cascade(sm, size, q);
        if (face >= sm.layers) {
            return 1.0;
        }
    } else if (sm.layers == 6u) {
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
    var reference = ndc.z / (1.0 - sm.depth_bias);
    if (directional) {
        // Beyond the far plane: at it. The bias: 2 texels in world units, as depth (row 2's
        // length is depth per world unit).
        let m = sm.faces[face];
        let per_unit = length(vec3<f32>(m[0].z, m[1].z, m[2].z));
        reference = max(ndc.z, 0.0) + 4.0 * volshadow_half_width(m) / size * per_unit;
    }
    return textureSampleCompareLevel(map, cmp, uv, i32(face), reference);
}
