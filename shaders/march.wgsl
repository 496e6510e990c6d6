// March node: in-scattered radiance per pixel. With no shadow-volume extents the whole ray is
// lit and the airlight is analytic: I0 · (F′(ds) − F′(0)) = I0 · F′(ds), F′(0) = 0.

@group(0) @binding(0) var<uniform> air: Airlight;
@group(0) @binding(1) var<uniform> view: View;
@group(0) @binding(2) var table: texture_2d<f32>;
@group(0) @binding(3) var scene_depth: texture_depth_2d;
@group(0) @binding(4) var inscatter_out: texture_storage_2d<rgba32float, write>;

@compute @workgroup_size(8, 8)
fn march(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = vec2<u32>(view.size.xy);
    if (gid.x >= size.x || gid.y >= size.y) {
        return;
    }
    let depth = textureLoad(scene_depth, gid.xy, 0);
    let ray = pixel_ray(view, vec2<f32>(gid.xy) + 0.5, depth);
    let r = air_ray(air, ray.dir);
    let radiance = fprime(table, air, r, ray.distance);
    textureStore(inscatter_out, gid.xy, vec4<f32>(clamp_radiance(radiance), ray.distance));
}
