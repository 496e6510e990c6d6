// Composite node: L = (Ls + kd·E) · exp(−σt ds) + Σ L_sctr (one per light; kd·E the light the
// medium scatters onto the surface, when normals and albedo are given) into the caller's target
// (the prelude's fullscreen triangle).

// Mirrors `CompositeUniform` in src/gpu/uniforms.rs.
struct Composite {
    sigma_t: vec3<f32>,
    count: u32,   // how many in-scatter inputs (one per light, 0 ..= 4) to add
}

@group(0) @binding(0) var<storage, read> comp: Composite;
@group(0) @binding(1) var<storage, read> view: View;
@group(0) @binding(2) var scene_color: texture_2d<f32>;
@group(0) @binding(3) var scene_depth: texture_depth_2d;
@group(0) @binding(4) var inscatter0: texture_2d<f32>;
@group(0) @binding(5) var inscatter1: texture_2d<f32>;
@group(0) @binding(6) var inscatter2: texture_2d<f32>;
@group(0) @binding(7) var inscatter3: texture_2d<f32>;

// The surface term (indirect single scattering, shaders/iss.wgsl precedes this file).
// Mirrors `SurfacesUniform` in src/gpu/uniforms.rs.
struct SurfaceLight {
    position: vec3<f32>,
    cos_half: f32,        // a spot's cos(half apex angle)
    intensity: vec3<f32>,
    spot: u32,            // 1: limited to the cone
    direction: vec3<f32>, // a spot's unit axis
    pad: f32,
}
struct Surfaces {
    sigma_s: vec3<f32>,
    count: u32,           // lights (0: no surface term)
    lights: array<SurfaceLight, 4>,
}
@group(0) @binding(8) var<storage, read> surf: Surfaces;
@group(0) @binding(9) var surface_normal: texture_2d<f32>;
@group(0) @binding(10) var surface_albedo: texture_2d<f32>;
@group(0) @binding(11) var iss_table: texture_2d<f32>;
@group(0) @binding(12) var<storage, read> surf_phase: VolshadowIssPhase;

// Pipeline constant: surfaces (normals and albedo) are given. Without them the term's code is
// left out of the pipeline, so frames without surfaces do not pay for it.
override SURFACES: bool = false;

// (ρ/π)·E(P) at the pixel's surface point, summed over the lights; 0 on sky.
fn surface_term(pixel: vec2<u32>, ray: PixelRay) -> vec3<f32> {
    if (!SURFACES || surf.count == 0u || ray.distance < 0.0) {
        return vec3<f32>(0.0);
    }
    let n = textureLoad(surface_normal, pixel, 0).xyz;
    let kd = textureLoad(surface_albedo, pixel, 0).xyz * (1.0 / PI);
    if (all(kd == vec3<f32>(0.0)) || !all(abs(n) < vec3<f32>(FAR))) {
        return vec3<f32>(0.0);
    }
    let p = view.world_from_view[3].xyz + ray.dir * ray.distance;
    var e = vec3<f32>(0.0);
    for (var i = 0u; i < min(surf.count, 4u); i++) {
        let l = surf.lights[i];
        if (l.spot != 0u) {
            // Only the medium inside the cone scatters (a fixed quadrature; no table).
            e += volshadow_iss_spot(surf_phase, p, n, l.position, l.direction, l.cos_half,
                                    l.intensity, surf.sigma_s, comp.sigma_t);
        } else {
            e += volshadow_iss(iss_table, p, n, l.position, l.intensity, surf.sigma_s, comp.sigma_t);
        }
    }
    return clamp_radiance(kd * e);
}

// The composited pixel `pixel` (its centre at `pixel + 0.5`).
fn composite_pixel(pixel: vec2<u32>) -> vec4<f32> {
    let color = textureLoad(scene_color, pixel, 0);
    let depth = textureLoad(scene_depth, pixel, 0);
    let ray = pixel_ray(view, vec2<f32>(pixel) + 0.5, depth);
    // Sky: an infinite homogeneous medium hides it, unless a channel does not attenuate at all.
    var transmittance = select(vec3<f32>(0.0), vec3<f32>(1.0), comp.sigma_t == vec3<f32>(0.0));
    if (ray.distance >= 0.0) {
        transmittance = vs_exp3(-comp.sigma_t * ray.distance);
    }
    // One in-scatter texture per light; unused slots hold placeholders and are not read.
    var sctr = vec3<f32>(0.0);
    let n = comp.count;
    if (n > 0u) { sctr += textureLoad(inscatter0, pixel, 0).xyz; }
    if (n > 1u) { sctr += textureLoad(inscatter1, pixel, 0).xyz; }
    if (n > 2u) { sctr += textureLoad(inscatter2, pixel, 0).xyz; }
    if (n > 3u) { sctr += textureLoad(inscatter3, pixel, 0).xyz; }
    let surface = color.xyz + surface_term(pixel, ray);
    return vec4<f32>(clamp_radiance(surface * transmittance + sctr), color.w);
}

// Through the rasteriser, into a render attachment.
@fragment
fn fs_composite(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<f32> {
    return composite_pixel(vec2<u32>(frag.xy));
}

// As a compute pass, into a storage texture: `cs_composite`, appended by src/nodes/composite.rs
// with `composite_out` declared in the target's format, calls `composite_pixel` for each pixel.
// A compute pass runs on every multiprocessor, also on GPUs whose graphics units are a small
// part of the chip (NVIDIA's H100 and H200 run fragment shaders on 2 of their 66 texture
// processing clusters).
