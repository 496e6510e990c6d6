struct App {
    world_from_clip: mat4x4<f32>,
    clip_from_world: mat4x4<f32>,
    eye: vec4<f32>,
    light: vec4<f32>,   // xyz position, w: far depth
    size: vec4<f32>,
    spheres: array<vec4<f32>, 3>,
}
@group(0) @binding(0) var<storage, read> app: App;

struct Out {
    @location(0) color: vec4<f32>,
    @builtin(frag_depth) depth: f32,
}

@vertex fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

fn hit_sphere(o: vec3<f32>, d: vec3<f32>, s: vec4<f32>) -> f32 {
    let oc = o - s.xyz;
    let b = dot(oc, d);
    let disc = b * b - (dot(oc, oc) - s.w * s.w);
    if (disc < 0.0) { return -1.0; }
    let t = -b - sqrt(disc);
    return select(-1.0, t, t > 1e-4);
}

@fragment fn fs(@builtin(position) p: vec4<f32>) -> Out {
    let ndc = vec2<f32>(p.x / app.size.x * 2.0 - 1.0, 1.0 - p.y / app.size.y * 2.0);
    let a = app.world_from_clip * vec4<f32>(ndc, 0.0, 1.0);
    let b = app.world_from_clip * vec4<f32>(ndc, 0.5, 1.0);
    let o = app.eye.xyz;
    let d = normalize(b.xyz / b.w - a.xyz / a.w);
    var t = 1e30;
    var n = vec3<f32>(0.0, 1.0, 0.0);
    if (d.y < 0.0) { t = -o.y / d.y; }
    for (var k = 0; k < 3; k++) {
        let ts = hit_sphere(o, d, app.spheres[k]);
        if (ts > 0.0 && ts < t) {
            t = ts;
            n = normalize(o + t * d - app.spheres[k].xyz);
        }
    }
    var out: Out;
    if (t >= 1e30) {
        out.color = vec4<f32>(0.0, 0.0, 0.0, 1.0);
        out.depth = app.light.w;
        return out;
    }
    let x = o + t * d;
    let l = app.light.xyz - x;
    let e = 20.0 / dot(l, l);
    out.color = vec4<f32>(vec3<f32>(0.5 / 3.14159265 * e * max(dot(n, normalize(l)), 0.0) + 0.01), 1.0);
    let clip = app.clip_from_world * vec4<f32>(x, 1.0);
    out.depth = clip.z / clip.w;
    return out;
}
