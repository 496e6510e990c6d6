// Composite node: L = Ls · exp(−σt ds) + Σ L_sctr (one per light) into the caller's target
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

@fragment
fn fs_composite(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<f32> {
    let pixel = vec2<u32>(frag.xy);
    let color = textureLoad(scene_color, pixel, 0);
    let depth = textureLoad(scene_depth, pixel, 0);
    let ray = pixel_ray(view, frag.xy, depth);
    // Sky: an infinite homogeneous medium hides it, unless a channel does not attenuate at all.
    var transmittance = select(vec3<f32>(0.0), vec3<f32>(1.0), comp.sigma_t == vec3<f32>(0.0));
    if (ray.distance >= 0.0) {
        transmittance = exp(-comp.sigma_t * ray.distance);
    }
    // One in-scatter texture per light; unused slots hold placeholders and are not read.
    var sctr = vec3<f32>(0.0);
    let n = comp.count;
    if (n > 0u) { sctr += textureLoad(inscatter0, pixel, 0).xyz; }
    if (n > 1u) { sctr += textureLoad(inscatter1, pixel, 0).xyz; }
    if (n > 2u) { sctr += textureLoad(inscatter2, pixel, 0).xyz; }
    if (n > 3u) { sctr += textureLoad(inscatter3, pixel, 0).xyz; }
    return vec4<f32>(clamp_radiance(color.xyz * transmittance + sctr), color.w);
}
