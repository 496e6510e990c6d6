// The quickstart scene as the application draws it: a ground plane and two spheres, ray-cast
// per pixel, lit by the point light (inverse square, attenuated through the medium; shadowed by
// the spheres when `scene.size.z` is 1). Writes linear radiance and depth. SPHERES repeats
// `quickstart_scene::SPHERES`.
struct Scene {
    clip_from_world: mat4x4<f32>,
    world_from_clip: mat4x4<f32>,
    eye: vec4<f32>,
    light: vec4<f32>,
    intensity: vec4<f32>,
    sigma_t: vec4<f32>,
    size: vec4<f32>,
}
@group(0) @binding(0) var<storage, read> scene: Scene;

struct Out {
    @location(0) color: vec4<f32>,
    @builtin(frag_depth) depth: f32,
}

@vertex fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

const SPHERES = array<vec4<f32>, 2>(vec4<f32>(-0.6, 2.2, -2.2, 0.5), vec4<f32>(0.8, 1.7, -1.4, 0.4));

fn hit_sphere(o: vec3<f32>, d: vec3<f32>, s: vec4<f32>) -> f32 {
    let oc = o - s.xyz;
    let b = dot(oc, d);
    let c = dot(oc, oc) - s.w * s.w;
    let disc = b * b - c;
    if (disc < 0.0) { return -1.0; }
    let t = -b - sqrt(disc);
    return select(-1.0, t, t > 1e-4);
}

@fragment fn fs(@builtin(position) p: vec4<f32>) -> Out {
    let ndc = vec2<f32>(p.x / scene.size.x * 2.0 - 1.0, 1.0 - p.y / scene.size.y * 2.0);
    let a = scene.world_from_clip * vec4<f32>(ndc, 0.0, 1.0);
    let b = scene.world_from_clip * vec4<f32>(ndc, 0.5, 1.0);
    let o = scene.eye.xyz;
    let d = normalize(b.xyz / b.w - a.xyz / a.w);
    var t = 1e30;
    var n = vec3<f32>(0.0);
    var albedo = vec3<f32>(0.0);
    if (d.y < 0.0) {
        t = -o.y / d.y;
        n = vec3<f32>(0.0, 1.0, 0.0);
        let hit = o + t * d;
        let checker = (i32(floor(hit.x)) + i32(floor(hit.z))) & 1;
        albedo = select(vec3<f32>(0.55), vec3<f32>(0.35), checker == 1);
    }
    for (var k = 0; k < 2; k++) {
        let ts = hit_sphere(o, d, SPHERES[k]);
        if (ts > 0.0 && ts < t) {
            t = ts;
            n = normalize(o + t * d - SPHERES[k].xyz);
            albedo = vec3<f32>(0.7, 0.45, 0.3);
        }
    }
    var out: Out;
    if (t >= 1e30) {
        out.color = vec4<f32>(0.0, 0.0, 0.0, 1.0);
        out.depth = 1.0;
        return out;
    }
    let x = o + t * d;
    let to_light = scene.light.xyz - x;
    let dist = length(to_light);
    let l = to_light / dist;
    var lit = 1.0;
    if (scene.size.z > 0.5) {
        for (var k = 0; k < 2; k++) {
            let ts = hit_sphere(x + n * 1e-3, l, SPHERES[k]);
            if (ts > 0.0 && ts < dist) { lit = 0.0; }
        }
    }
    let e = scene.intensity.xyz * exp(-scene.sigma_t.xyz * dist) / (dist * dist);
    out.color = vec4<f32>(albedo / 3.14159265 * e * max(dot(n, l), 0.0) * lit + 0.01 * albedo, 1.0);
    let clip = scene.clip_from_world * vec4<f32>(x, 1.0);
    out.depth = clip.z / clip.w;
    return out;
}
