#import prelude.wgsl
#import iss.wgsl
// Composite node: L = (Ls + kd·E) · exp(−σt ds) + Σ L_sctr (one per light; kd·E the light the
// medium scatters onto the surface, when normals and albedo are given) into the caller's target
// (the prelude's fullscreen triangle).

// Mirrors `CompositeUniform` in src/nodes/groups/uniforms.rs.
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

// The surface term (indirect single scattering, shaders/shared/iss.wgsl precedes this file).
// Mirrors `SurfacesUniform` in src/nodes/groups/uniforms.rs (its layout test: the composite node's
// `params_layouts_match_the_wgsl`); WGSL's alignment pads both structs.
struct Surfaces {
    sigma_s: vec3<f32>,
    count: u32,           // lights (0: no surface term)
    lights: array<Light, 4>,   // point and spot lights
    lattice: u32,         // the spot term's lattice spacing in pixels (0: no lattice)
}
@group(0) @binding(8) var<storage, read> surf: Surfaces;
@group(0) @binding(9) var surface_normal: texture_2d<f32>;
@group(0) @binding(10) var surface_albedo: texture_2d<f32>;
@group(0) @binding(11) var iss_table: texture_2d<f32>;
@group(0) @binding(12) var<storage, read> surf_phase: VolshadowIssPhase;
// The spot lights' summed E(P) at every `surf.lattice`-th pixel (rgb) and whether that pixel
// holds a surface (a), written by `cs_spot_lattice` before the composite.
@group(0) @binding(13) var spot_lattice: texture_2d<f32>;

// Pipeline constant: surfaces (normals and albedo) are given. Without them the term's code is
// left out of the pipeline, so frames without surfaces do not pay for it.
override SURFACES: bool = false;

// A pixel's surface point and unit normal; `ok` false on sky, without albedo, or for a zero or
// non-finite normal (no surface term there).
struct SurfacePoint {
    p: vec3<f32>,
    n: vec3<f32>,
    ok: bool,
}

fn surface_point(pixel: vec2<u32>) -> SurfacePoint {
    let ray = pixel_ray(view, vec2<f32>(pixel) + 0.5, textureLoad(scene_depth, pixel, 0));
    let n = textureLoad(surface_normal, pixel, 0).xyz;
    let kd = textureLoad(surface_albedo, pixel, 0).xyz;
    let finite = all(abs(n) < vec3<f32>(FAR));
    let len = select(0.0, length(n), finite);
    let ok = ray.distance >= 0.0 && any(kd != vec3<f32>(0.0)) && len > 0.0;
    let p = view.world_from_view[3].xyz + ray.dir * max(ray.distance, 0.0);
    return SurfacePoint(p, n / max(len, 1.0e-30), ok);
}

// Σ over the spot lights of E(P), evaluated (the cone-limited quadrature of
// shaders/shared/iss.wgsl).
fn spot_irradiance(p: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    var e = vec3<f32>(0.0);
    for (var i = 0u; i < min(surf.count, 4u); i++) {
        let l = surf.lights[i];
        if (l.kind == LIGHT_SPOT) {
            e += volshadow_iss_spot(surf_phase, p, n, l.position, l.axis, l.cos_half,
                                    l.intensity, surf.sigma_s, comp.sigma_t);
        }
    }
    return e;
}

// When a pixel interpolates the lattice: the four nodes around it lie on its surface (normals
// within 1.8° of its own, points within 2.9° of its tangent plane: depth-buffer rounding moves
// a point by about 1e-2 of the nodes' distance at a metre with a 1 cm near plane), and the
// interpolation's error estimated from the nodes' second differences, fx(1 − fx)·|Δ²x| +
// fy(1 − fy)·|Δ²y| (twice the bilinear error of a smooth function with those second
// differences, which covers a kink between two nodes, such as the term's at a cone's edge), is
// at most 0.2% of the smallest node per channel.
const LATTICE_NORMAL_DOT: f32 = 0.9995;
const LATTICE_PLANE: f32 = 5.0e-2;
const LATTICE_TOLERANCE: f32 = 2.0e-3;

// Lattice node `c`, clamped to the lattice (a clamped node repeats its neighbour, so the second
// difference there is a first difference: stricter at the frame's border).
fn lattice_node(c: vec2<i32>) -> vec4<f32> {
    let last = vec2<i32>(textureDimensions(spot_lattice)) - vec2<i32>(1);
    return textureLoad(spot_lattice, clamp(c, vec2<i32>(0), last), 0);
}

// The larger |second difference| at the two inner nodes of the run a, b, c, d (b and c the
// cell's); FAR when an outer node holds no surface.
fn lattice_curvature(a: vec4<f32>, b: vec4<f32>, c: vec4<f32>, d: vec4<f32>) -> vec3<f32> {
    if (a.w < 0.5 || d.w < 0.5) {
        return vec3<f32>(FAR);
    }
    return max(abs(a.xyz - 2.0 * b.xyz + c.xyz), abs(b.xyz - 2.0 * c.xyz + d.xyz));
}

// The spot lights' E(P) at `pixel` (surface point `s`): interpolated bilinearly between the
// lattice nodes around it where the tests above pass, else evaluated. The term is smooth across
// a surface (it varies over the light's distance, the glow's width 1/σt and the band at the
// cone's edge), so on a large frame most pixels interpolate; geometric edges and the places
// where the term bends within a few pixels (the apex's surroundings, a cone's edge on a small
// frame) are evaluated.
fn spot_term(pixel: vec2<u32>, s: SurfacePoint) -> vec3<f32> {
    let stride = surf.lattice;
    if (stride > 1u) {
        let size = textureDimensions(scene_depth);
        let cell = pixel / stride;
        let lo_px = cell * stride;
        let hi_px = min(lo_px + stride, size - 1u);
        let f = select(vec2<f32>(0.0), vec2<f32>(pixel - lo_px) / vec2<f32>(hi_px - lo_px),
                       hi_px > lo_px);
        let ci = vec2<i32>(cell);
        var v: array<vec4<f32>, 4>;
        var acc = vec3<f32>(0.0);
        var lo = vec3<f32>(FAR);
        var ok = true;
        for (var k = 0u; k < 4u; k++) {
            let c = vec2<u32>(k & 1u, k >> 1u);
            v[k] = lattice_node(ci + vec2<i32>(c));
            let w = select(1.0 - f.x, f.x, c.x == 1u) * select(1.0 - f.y, f.y, c.y == 1u);
            if (w > 0.0) {
                let q = surface_point(select(lo_px, hi_px, c == vec2<u32>(1u)));
                let d = q.p - s.p;
                ok = ok && v[k].w > 0.5 && q.ok && dot(q.n, s.n) >= LATTICE_NORMAL_DOT
                    && abs(dot(d, s.n)) <= LATTICE_PLANE * length(d);
                acc += w * v[k].xyz;
                lo = min(lo, v[k].xyz);
            }
        }
        var err = vec3<f32>(0.0);
        if (ok && f.x > 0.0) {
            var bend = lattice_curvature(lattice_node(ci + vec2<i32>(-1, 0)), v[0], v[1],
                                         lattice_node(ci + vec2<i32>(2, 0)));
            if (f.y > 0.0) {
                bend = max(bend, lattice_curvature(lattice_node(ci + vec2<i32>(-1, 1)), v[2], v[3],
                                                   lattice_node(ci + vec2<i32>(2, 1))));
            }
            err += f.x * (1.0 - f.x) * bend;
        }
        if (ok && f.y > 0.0) {
            var bend = lattice_curvature(lattice_node(ci + vec2<i32>(0, -1)), v[0], v[2],
                                         lattice_node(ci + vec2<i32>(0, 2)));
            if (f.x > 0.0) {
                bend = max(bend, lattice_curvature(lattice_node(ci + vec2<i32>(1, -1)), v[1], v[3],
                                                   lattice_node(ci + vec2<i32>(1, 2))));
            }
            err += f.y * (1.0 - f.y) * bend;
        }
        if (ok && all(err <= LATTICE_TOLERANCE * lo)) {
            return acc;
        }
    }
    return spot_irradiance(s.p, s.n);
}

// (ρ/π)·E(P) at the pixel's surface point, summed over the lights; 0 on sky.
fn surface_term(pixel: vec2<u32>, ray: PixelRay) -> vec3<f32> {
    if (!SURFACES || surf.count == 0u || ray.distance < 0.0) {
        return vec3<f32>(0.0);
    }
    let s = surface_point(pixel);
    if (!s.ok) {
        return vec3<f32>(0.0);
    }
    let kd = textureLoad(surface_albedo, pixel, 0).xyz * (1.0 / PI);
    var e = vec3<f32>(0.0);
    var spots = false;
    for (var i = 0u; i < min(surf.count, 4u); i++) {
        let l = surf.lights[i];
        if (l.kind == LIGHT_SPOT) {
            spots = true;
        } else {
            e += volshadow_iss(iss_table, s.p, s.n, l.position, l.intensity, surf.sigma_s, comp.sigma_t);
        }
    }
    if (spots) {
        // Only the medium inside a cone scatters (a quadrature over the hemisphere, no table).
        e += spot_term(pixel, s);
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
