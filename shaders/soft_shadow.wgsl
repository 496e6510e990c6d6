// Soft-shadow node: the fraction of a light's disc visible from each cell of a light-space
// grid (composed after the prelude and pcss.wgsl), which the march reads with one trilinear
// lookup per step instead of a percentage-closer soft shadow (PCSS) estimate of 49 shadow-map
// taps. Cells: per shadow-map layer, `size`² directions (the layer's texel grid, coarser) by
// `slices` distances uniform in q = nearest / distance ∈ (0, 1], nearest being the least
// distance of an occluder from the light. A penumbra's width at distance d, seen from the
// light, is radius · (1/d_blocker − 1/d): linear in q, so uniform steps in q are uniform
// steps in penumbra width, and q ∈ (0, 1] reaches infinity.

// Mirrors `SoftShadowUniform` in src/nodes/soft_shadow.rs.
struct SoftShadowParams {
    faces: array<mat4x4<f32>, 6>,            // clip_from_world of each layer (the shadow map's)
    world_from_clip: array<mat4x4<f32>, 6>,  // their inverses
    light: vec4<f32>,                        // xyz: the light's position
    depth_bias: f32,                         // the shadow map's relative depth bias
    size: u32,                               // cells across a layer
    slices: u32,                             // cells along the distance from the light
    layers: u32,                             // 6 (point) or 1 (spot)
    soft: vec4<f32>,                         // as the march's: radius, nearest, sphere count,
                                             // and the angle (radians) a cell subtends
    spheres: array<vec4<f32>, 8>,            // occluders' bounding spheres
    planes: array<vec4<f32>, 8>,             // and their planes, as the march's
}

@group(0) @binding(0) var<storage, read> mp: SoftShadowParams;
@group(0) @binding(1) var shadow_map: texture_depth_2d_array;
@group(0) @binding(2) var shadow_sampler: sampler_comparison;
// x, y: the cell's direction in its layer; z: layer · slices + slice.
@group(0) @binding(3) var volume: texture_storage_3d<rgba16float, write>;
// The shadow map's back faces (ShadowMap::back), or the map itself without them.
@group(0) @binding(4) var shadow_back: texture_depth_2d_array;

fn pcss_light() -> vec3<f32> {
    return mp.light.xyz;
}

// Most slices a thread holds (SoftShadowSize::MAX_SLICES).
const MAX_SLICES: u32 = 64u;
// A penumbra narrower than this many cells (filter radius) is marked sharp: the march blends in
// the shadow map's own visibility there. Measured (tests/soft_grid.rs, tests/soft.rs): 4 cells
// or a fade from 2 to 4 are worse on the torus and the sphere, where hard edges are too sharp
// for such penumbrae.
const SHARP_CELLS: f32 = 2.0;
// A change of visibility between neighbouring slices above which the interpolation in depth
// would smear an occluder's surface (lit in front of it, dark behind): both cells are marked
// sharp.
const DEPTH_JUMP: f32 = 0.35;

// q = nearest / distance at the centre of slice k of s (slice 0 nearest the light).
fn slice_q(k: u32, s: u32) -> f32 {
    return 1.0 - (f32(k) + 0.5) / f32(s);
}

// One thread per direction of a layer, through all its slices: each cell's sharpness needs
// its neighbours in depth.
@compute @workgroup_size(8, 8, 1)
fn build(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = mp.size;
    let s = min(mp.slices, MAX_SLICES);
    if (gid.x >= n || gid.y >= n || gid.z >= mp.layers) {
        return;
    }
    let layer = gid.z;
    let uv = (vec2<f32>(gid.xy) + 0.5) / f32(n);
    // Any depth inside the frustum names the direction; 0.5 is within reversed-Z's range for
    // the perspective layers.
    let w = mp.world_from_clip[layer] * vec4<f32>(2.0 * uv.x - 1.0, 1.0 - 2.0 * uv.y, 0.5, 1.0);
    let light = pcss_light();
    let dir = normalize(w.xyz / w.w - light);
    let nearest = max(mp.soft.y, 1.0e-3 * mp.soft.x);
    let narrow = SHARP_CELLS * tan(mp.soft.w);
    // The slices inside an occluder's penumbra cone, [lo, hi): only those take taps. A
    // direction outside every cone (most of a cube map's) then costs no estimate at all.
    var lo = s;
    var hi = 0u;
    var cells: array<vec2<f32>, MAX_SLICES>;
    for (var k = 0u; k < s; k++) {
        cells[k] = vec2<f32>(1.0, -1.0);
        if (may_be_hidden(light + (nearest / slice_q(k, s)) * dir)) {
            lo = min(lo, k);
            hi = k + 1u;
        }
    }
    for (var k = lo; k < hi; k++) {
        cells[k] = soft_estimate(light + (nearest / slice_q(k, s)) * dir);
    }
    for (var k = 0u; k < s; k++) {
        let e = cells[k];
        // g: 1 where the estimate's region was narrower than SHARP_CELLS cells (a penumbra, or
        // the edge between lit and umbra, too sharp for the grid's interpolation across
        // directions): the march blends in the shadow map's own visibility there. b: 1 where
        // the visibility jumps to a neighbouring slice (an occluder's surface between them):
        // the march does not interpolate across it.
        var sharp = select(0.0, 1.0, e.y >= 0.0 && e.y < narrow);
        var jump = false;
        if (k > 0u) {
            jump = jump || abs(e.x - cells[k - 1u].x) > DEPTH_JUMP;
        }
        if (k + 1u < s) {
            jump = jump || abs(e.x - cells[k + 1u].x) > DEPTH_JUMP;
        }
        let surface = select(0.0, 1.0, jump);
        let texel = vec3<u32>(gid.x, gid.y, layer * mp.slices + k);
        textureStore(volume, texel, vec4<f32>(e.x, sharp, surface, 1.0));
    }
}
