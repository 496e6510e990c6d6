#import prelude.wgsl
#import light.wgsl
// Upsample node: the low-resolution lit fraction (rgb in [0, 1], a = eye distance, −1 sky)
// brought to the output resolution without blending across depth discontinuities (Wyman and
// Ramsey 2008, §3.3; SoftBiF-VS 2017), times the full-resolution analytic airlight of each output pixel.
//   filter 0: plain bilinear (depth-blind baseline)
//   filter 1: 3×3 Gaussian over the low-resolution samples whose depth matches the pixel's
//   filter 2: separable N-tap bilateral, horizontal pass then vertical pass

// Mirrors `UpsampleUniform` in src/nodes/upsample.rs.
// The filters of `Upsample.kind` (the Rust `FILTER_*` constants; a unit test compares them).
const FILTER_BILINEAR: u32 = 0u;
const FILTER_3X3: u32 = 1u;
const FILTER_SEPARABLE: u32 = 2u;

struct Upsample {
    kind: u32,            // the filter: one of FILTER_*
    taps: u32,            // separable: taps per direction
    sigma_spatial: f32,   // separable: in low-resolution pixels
    sigma_depth: f32,     // separable: relative to the pixel's eye distance
    low_size: vec2<f32>,
    out_size: vec2<f32>,
}

@group(0) @binding(0) var<storage, read> up: Upsample;
@group(0) @binding(1) var<storage, read> view: View;          // output resolution
@group(0) @binding(2) var low: texture_2d<f32>;
@group(0) @binding(3) var scene_depth: texture_depth_2d;
@group(0) @binding(4) var mid: texture_2d<f32>;           // horizontal pass result (separable)
@group(0) @binding(5) var out_tex: texture_storage_2d<rgba32float, write>;
@group(0) @binding(6) var table: texture_2d<f32>;
@group(0) @binding(7) var<storage, read> air: Airlight;
@group(0) @binding(8) var<storage, read> light: Light;

// Unshadowed airlight of an output pixel, analytic at full resolution.
fn airlight_full(p: vec2<u32>) -> vec4<f32> {
    let ray = pixel_ray(view, vec2<f32>(p) + 0.5, textureLoad(scene_depth, p, 0));
    let r = air_ray(air, ray);
    let x_end = select(FAR, ray.distance, ray.distance >= 0.0);
    let sup = support_s(air, r, light, ray.dir, x_end);
    return vec4<f32>(r.prefactor * unshadowed_t(table, air, r, sup), ray.distance);
}

// Depth matching within this relative tolerance counts as "the same surface" for the 3×3.
const SAME_SURFACE: f32 = 0.05;

fn full_distance(p: vec2<u32>) -> f32 {
    return pixel_ray(view, vec2<f32>(p) + 0.5, textureLoad(scene_depth, p, 0)).distance;
}

// Relative depth difference; sky (< 0) matches only sky.
fn depth_delta(a: f32, b: f32) -> f32 {
    if (a < 0.0 || b < 0.0) {
        return select(1.0e30, 0.0, a < 0.0 && b < 0.0);
    }
    return abs(a - b) / max(min(a, b), 1.0e-30);
}

fn low_at(p: vec2<i32>) -> vec4<f32> {
    let size = vec2<i32>(up.low_size);
    return textureLoad(low, clamp(p, vec2<i32>(0), size - 1), 0);
}

// Continuous low-resolution coordinate of an output pixel's centre (texel centres at +0.5).
fn low_coord(p: vec2<u32>) -> vec2<f32> {
    return (vec2<f32>(p) + 0.5) * up.low_size / up.out_size - 0.5;
}

@compute @workgroup_size(8, 8)
fn upsample(@builtin(global_invocation_id) gid: vec3<u32>) {
    let full = vec2<u32>(up.out_size);
    if (gid.x >= full.x || gid.y >= full.y) {
        return;
    }
    let analytic = airlight_full(gid.xy);
    let z = analytic.w;
    let q = low_coord(gid.xy);
    var result = vec3<f32>(0.0);
    if (up.kind == FILTER_BILINEAR) {
        let b = floor(q);
        let f = q - b;
        let i = vec2<i32>(b);
        result = mix(mix(low_at(i).xyz, low_at(i + vec2<i32>(1, 0)).xyz, f.x),
                     mix(low_at(i + vec2<i32>(0, 1)).xyz, low_at(i + vec2<i32>(1, 1)).xyz, f.x), f.y);
    } else {
        let centre = vec2<i32>(floor(q + 0.5));
        var sum = vec3<f32>(0.0);
        var weight = 0.0;
        var nearest = low_at(centre).xyz;
        var nearest_delta = 1.0e38;
        for (var j = -1; j <= 1; j++) {
            for (var i = -1; i <= 1; i++) {
                let c = centre + vec2<i32>(i, j);
                let s = low_at(c);
                let delta = depth_delta(s.w, z);
                if (delta < nearest_delta) {
                    nearest_delta = delta;
                    nearest = s.xyz;
                }
                if (delta <= SAME_SURFACE) {
                    let d = vec2<f32>(c) - q;
                    let w = vs_exp(-0.5 * dot(d, d));
                    sum += w * s.xyz;
                    weight += w;
                }
            }
        }
        result = select(nearest, sum / weight, weight > 1.0e-6);
    }
    textureStore(out_tex, gid.xy, vec4<f32>(clamp_radiance(result * analytic.xyz), z));
}

fn bilateral_weight(offset: f32, delta: f32) -> f32 {
    let s = offset / up.sigma_spatial;
    let d = delta / up.sigma_depth;
    return vs_exp(-0.5 * (s * s + d * d));
}

// One direction of the separable bilateral around the continuous coordinate `c`: along x of
// `low` (horizontal) or along y of `mid` (vertical), against the reference distance `z`.
fn separable(gid: vec2<u32>, c: f32, z: f32, vertical: bool) -> vec3<f32> {
    let half = i32(up.taps) / 2;
    let base = i32(floor(c + 0.5));
    var sum = vec3<f32>(0.0);
    var weight = 0.0;
    var nearest = vec3<f32>(0.0);
    var nearest_delta = 1.0e38;
    for (var k = -half; k <= half; k++) {
        let t = base + k;
        var s: vec4<f32>;
        if (vertical) {
            s = textureLoad(mid, vec2<i32>(i32(gid.x), clamp(t, 0, i32(up.low_size.y) - 1)), 0);
        } else {
            s = low_at(vec2<i32>(t, i32(gid.y)));
        }
        let delta = depth_delta(s.w, z);
        if (delta < nearest_delta) {
            nearest_delta = delta;
            nearest = s.xyz;
        }
        let w = bilateral_weight(f32(t) - c, delta);
        sum += w * s.xyz;
        weight += w;
    }
    return select(nearest, sum / weight, weight > 1.0e-6);
}

// Horizontal pass: output width × low-res height; each row's reference depth is the output
// pixel that the march sampled for that low-res row.
@compute @workgroup_size(8, 8)
fn separable_h(@builtin(global_invocation_id) gid: vec3<u32>) {
    let full = vec2<u32>(up.out_size);
    if (gid.x >= full.x || gid.y >= u32(up.low_size.y)) {
        return;
    }
    let row = min(u32((f32(gid.y) + 0.5) * up.out_size.y / up.low_size.y), full.y - 1u);
    let z = full_distance(vec2<u32>(gid.x, row));
    let cx = (f32(gid.x) + 0.5) * up.low_size.x / up.out_size.x - 0.5;
    textureStore(out_tex, gid.xy, vec4<f32>(separable(gid.xy, cx, z, false), z));
}

// Vertical pass over the horizontal result, against each output pixel's own depth.
@compute @workgroup_size(8, 8)
fn separable_v(@builtin(global_invocation_id) gid: vec3<u32>) {
    let full = vec2<u32>(up.out_size);
    if (gid.x >= full.x || gid.y >= full.y) {
        return;
    }
    let analytic = airlight_full(gid.xy);
    let cy = (f32(gid.y) + 0.5) * up.low_size.y / up.out_size.y - 0.5;
    let value = separable(gid.xy, cy, analytic.w, true);
    textureStore(out_tex, gid.xy, vec4<f32>(clamp_radiance(value * analytic.xyz), analytic.w));
}
