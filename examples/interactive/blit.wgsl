override ENCODE_SRGB: bool = false;
const EXPOSURE: f32 = 1.6;

struct Blit {
    world_from_clip: mat4x4<f32>,
    eye: vec4<f32>,
    sigma_t: vec4<f32>,
    params: vec4<f32>,
    sizes: vec4<f32>,
}

@group(0) @binding(0) var hdr: texture_2d<f32>;
@group(0) @binding(1) var scene_color: texture_2d<f32>;
@group(0) @binding(2) var scene_depth: texture_depth_2d;
@group(0) @binding(3) var inscatter: texture_2d<f32>;
@group(0) @binding(4) var reference_image: texture_2d<f32>;
@group(0) @binding(5) var<uniform> u: Blit;

@vertex fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

fn srgb(v: vec3<f32>) -> vec3<f32> {
    return select(1.055 * pow(v, vec3<f32>(1.0 / 2.4)) - 0.055, 12.92 * v, v <= vec3<f32>(0.0031308));
}

fn tone(c: vec3<f32>) -> vec4<f32> {
    let e = EXPOSURE * max(c, vec3<f32>(0.0));
    var v = e / (1.0 + e);
    if (ENCODE_SRGB) {
        v = srgb(v);
    }
    return vec4<f32>(v, 1.0);
}

fn luminance(c: vec3<f32>) -> f32 {
    return dot(c, vec3<f32>(0.2126, 0.7152, 0.0722));
}

// The low-resolution reference at window pixel p, bilinear between its pixel centres.
fn reference_at(p: vec2<f32>) -> vec3<f32> {
    let size = u.sizes.xy;
    let q = p / u.sizes.zw * size - 0.5;
    let q0 = floor(q);
    let f = q - q0;
    let last = vec2<i32>(size) - 1;
    let i0 = clamp(vec2<i32>(q0), vec2<i32>(0), last);
    let i1 = clamp(vec2<i32>(q0) + 1, vec2<i32>(0), last);
    let a = textureLoad(reference_image, vec2<i32>(i0.x, i0.y), 0).rgb;
    let b = textureLoad(reference_image, vec2<i32>(i1.x, i0.y), 0).rgb;
    let c = textureLoad(reference_image, vec2<i32>(i0.x, i1.y), 0).rgb;
    let d = textureLoad(reference_image, vec2<i32>(i1.x, i1.y), 0).rgb;
    return mix(mix(a, b, f.x), mix(c, d, f.x), f.y);
}

// Relative error: black 0, blue 2%, yellow 5%, red 10% or more.
fn heat(e: f32) -> vec3<f32> {
    let blue = vec3<f32>(0.1, 0.2, 1.0);
    let yellow = vec3<f32>(1.0, 0.9, 0.1);
    let red = vec3<f32>(1.0, 0.1, 0.05);
    if (e < 0.02) {
        return blue * (e / 0.02);
    }
    if (e < 0.05) {
        return mix(blue, yellow, (e - 0.02) / 0.03);
    }
    return mix(yellow, red, clamp((e - 0.05) / 0.05, 0.0, 1.0));
}

@fragment fn fs(@builtin(position) p: vec4<f32>) -> @location(0) vec4<f32> {
    let pixel = vec2<i32>(p.xy);
    let mode = u.params.x;
    if (mode < 0.5 || u.params.z < 0.5) {
        return tone(textureLoad(hdr, pixel, 0).rgb);
    }
    if (mode < 1.5) {
        let split = u.params.y;
        if (abs(p.x - split) < 1.0) {
            return vec4<f32>(1.0);
        }
        if (p.x < split) {
            return tone(textureLoad(hdr, pixel, 0).rgb);
        }
        // The app's colour attenuated to the eye, plus the reference's in-scatter.
        let color = textureLoad(scene_color, pixel, 0).rgb;
        let z = textureLoad(scene_depth, pixel, 0);
        let ndc = vec2<f32>(p.x / u.sizes.z * 2.0 - 1.0, 1.0 - p.y / u.sizes.w * 2.0);
        let w = u.world_from_clip * vec4<f32>(ndc, z, 1.0);
        let d = length(w.xyz / w.w - u.eye.xyz);
        var t = exp(-u.sigma_t.xyz * d);
        if (!(d < 1e30)) {
            t = vec3<f32>(0.0);
        }
        return tone(color * t + reference_at(p.xy));
    }
    let g = luminance(textureLoad(inscatter, pixel, 0).rgb);
    let r = luminance(reference_at(p.xy));
    return vec4<f32>(heat(abs(g - r) / max(r, 0.01 * u.params.w)), 1.0);
}
