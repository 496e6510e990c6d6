struct Light {
    position: vec4<f32>,
    intensity: vec4<f32>,
    direction: vec4<f32>,
    frame: mat4x4<f32>,
    params: vec4<f32>,
}
struct Scene {
    clip_from_world: mat4x4<f32>,
    eye: vec4<f32>,
    sigma_t: vec4<f32>,
    ambient: vec4<f32>,
    light_count: vec4<u32>,
    lights: array<Light, 4>,
}
@group(0) @binding(0) var<uniform> scene: Scene;
@group(0) @binding(1) var texture0: texture_2d<f32>;
@group(0) @binding(2) var texture1: texture_2d<f32>;
@group(0) @binding(3) var texture2: texture_2d<f32>;
@group(0) @binding(4) var texture3: texture_2d<f32>;
@group(0) @binding(5) var linear: sampler;
// Surface shadows (volshadow::SHADOW_WGSL precedes this file): light i is shadowed when
// lights[i].params.y = 1.
@group(0) @binding(6) var shadow0: texture_depth_2d_array;
@group(0) @binding(7) var shadow1: texture_depth_2d_array;
@group(0) @binding(8) var shadow2: texture_depth_2d_array;
@group(0) @binding(9) var shadow3: texture_depth_2d_array;
@group(0) @binding(10) var shadow_cmp: sampler_comparison;
@group(0) @binding(11) var<storage, read> shadows: array<VolshadowShadow, 4>;

fn surface_visibility(i: u32, p: vec3<f32>, n: vec3<f32>) -> f32 {
    if (i == 0u) { return volshadow_shadow(shadow0, shadow_cmp, shadows[0], p, n); }
    if (i == 1u) { return volshadow_shadow(shadow1, shadow_cmp, shadows[1], p, n); }
    if (i == 2u) { return volshadow_shadow(shadow2, shadow_cmp, shadows[2], p, n); }
    return volshadow_shadow(shadow3, shadow_cmp, shadows[3], p, n);
}

struct Varyings {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) albedo: vec3<f32>,
}

@vertex fn vs(@location(0) position: vec3<f32>, @location(1) normal: vec3<f32>,
              @location(2) albedo: vec3<f32>) -> Varyings {
    var out: Varyings;
    out.clip = scene.clip_from_world * vec4<f32>(position, 1.0);
    out.world = position;
    out.normal = normal;
    out.albedo = albedo;
    return out;
}

fn light_texel(i: u32, uv: vec2<f32>) -> vec3<f32> {
    if (i == 0u) { return textureSampleLevel(texture0, linear, uv, 0.0).rgb; }
    if (i == 1u) { return textureSampleLevel(texture1, linear, uv, 0.0).rgb; }
    if (i == 2u) { return textureSampleLevel(texture2, linear, uv, 0.0).rgb; }
    return textureSampleLevel(texture3, linear, uv, 0.0).rgb;
}

struct Targets {
    @location(0) color: vec4<f32>,
    @location(1) normal: vec4<f32>,   // unit world-space normal, facing the eye
    @location(2) albedo: vec4<f32>,
}

@fragment fn fs(in: Varyings) -> Targets {
    var n = in.normal;
    if (dot(n, scene.eye.xyz - in.world) < 0.0) { n = -n; }
    var irradiance = vec3<f32>(0.0);
    for (var i = 0u; i < scene.light_count.x; i++) {
        let light = scene.lights[i];
        var to_light = light.position.xyz - in.world;
        let directional = light.position.w > 1.5; // xyz: unit, towards the light
        if (directional) { to_light = light.position.xyz; }
        let d = max(length(to_light), 1e-6);
        let l = to_light / d;
        var emitted = light.intensity.rgb;
        if (light.position.w > 0.5) {
            if (dot(-l, light.direction.xyz) < light.direction.w) { continue; }
            if (light.intensity.w > 0.5) {
                let v = light.frame * vec4<f32>(in.world, 1.0);
                let s = 0.5 / (-v.z * light.params.x);
                emitted *= light_texel(i, vec2<f32>(0.5 + v.x * s, 0.5 - v.y * s));
            }
        }
        if (light.params.y > 0.5) {
            emitted *= surface_visibility(i, in.world, n);
        }
        var falloff = exp(-scene.sigma_t.xyz * d) / (d * d);
        if (directional) { falloff = vec3<f32>(1.0); } // E arrives in the medium
        irradiance += emitted * max(dot(n, l), 0.0) * falloff;
    }
    let radiance = in.albedo / 3.14159265 * irradiance + in.albedo * scene.ambient.xyz;
    return Targets(vec4<f32>(radiance, 1.0), vec4<f32>(normalize(n), 0.0), vec4<f32>(in.albedo, 1.0));
}
