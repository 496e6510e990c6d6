#import prelude.wgsl
#import clip.wgsl
// Shadow-map node: occluder depth from the light, one layer per face (six for a point light's
// cube, one for a spot light). Reversed-Z infinite perspective: depth = near / distance along
// the face's axis, so nearer occluders win with `Greater` and nothing is clipped far away.

struct ShadowFace {
    clip_from_world: mat4x4<f32>,
    // xyz: the light's position (a point or spot light), read by `vs_shadow_clipped`.
    centre: vec4<f32>,
}
struct Instance {
    world_from_object: mat4x4<f32>,
    // x: the half-side of the cube around the light `vs_shadow_clipped` clips the occluder's
    // triangles to (0 where the plain `vs_shadow` draws it).
    reach: vec4<f32>,
}

@group(0) @binding(0) var<storage, read> face: ShadowFace;
@group(0) @binding(1) var<storage, read> instance: Instance;

@vertex
fn vs_shadow(@location(0) position: vec4<f32>) -> @builtin(position) vec4<f32> {
    return face.clip_from_world * (instance.world_from_object * vec4<f32>(position.xyz, 1.0));
}

// An occluder far larger than its distance to the light (`ShadowMapNode`'s `clip_reach`): the
// rasteriser clips a triangle to the face's frustum in f32, and where its vertices lie beyond
// about 2^24 times the depth of the clipped points (a roof 1e8 wide three units above the
// light), the clipped polygon loses its place and the shadow leaks. So each of its triangles is
// first clipped here to a cube around the light of half-side `instance.reach` (4096 times the
// distance from the light to the occluder's bounds), and drawn as the fan of the clipped
// polygon: a triangle against six planes keeps at most nine vertices, seven fan triangles, one
// per instance (`instance_index`), three invocations each reading the whole triangle (vertex
// pulling, `vertex_index` = 3 · triangle + corner). A fan triangle the polygon does not have is
// degenerate outside the clip volume. What is cut away lies farther from the light than 4096
// times the occluder's distance: it can shadow only fog farther than that, lit by less than
// 1/4096² of what the fog beside the occluder gets. A triangle inside the cube is drawn from
// its own vertices, as `vs_shadow` draws it.

@group(0) @binding(2) var<storage, read> clip_positions: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> clip_indices: array<u32>;

@vertex
fn vs_shadow_clipped(@builtin(vertex_index) v: u32, @builtin(instance_index) fan: u32)
    -> @builtin(position) vec4<f32> {
    let t = v / 3u;
    let corner = v - 3u * t;
    var p: array<vec3<f32>, 9>;
    for (var c = 0u; c < 3u; c++) {
        let object = clip_positions[clip_indices[3u * t + c]].xyz;
        p[c] = (instance.world_from_object * vec4<f32>(object, 1.0)).xyz;
    }
    let l = face.centre.xyz;
    let reach = instance.reach.x;
    var n = 3u;
    let inside = max(max_abs(p[0] - l), max(max_abs(p[1] - l), max_abs(p[2] - l))) <= reach;
    if (!inside) {
        // Sutherland–Hodgman against the cube's six planes, `reach - s (p - l)[axis] >= 0`.
        var q: array<vec3<f32>, 9>;
        for (var plane = 0u; plane < 6u; plane++) {
            let axis = plane / 2u;
            let s = select(1.0, -1.0, (plane & 1u) == 1u);
            var m = 0u;
            for (var i = 0u; i < n; i++) {
                let a = p[i];
                let b = p[select(i + 1u, 0u, i + 1u == n)];
                let da = reach - s * (a[axis] - l[axis]);
                let db = reach - s * (b[axis] - l[axis]);
                if (da >= 0.0 && m < 9u) {
                    q[m] = a;
                    m++;
                }
                if ((da >= 0.0) != (db >= 0.0) && m < 9u) {
                    // From the edge's lesser end, so the triangle across the edge finds the
                    // same point, bit for bit: no crack between the two.
                    if (precedes(vec4<f32>(a, 0.0), vec4<f32>(b, 0.0))) {
                        q[m] = a + (b - a) * (da / (da - db));
                    } else {
                        q[m] = b + (a - b) * (db / (db - da));
                    }
                    m++;
                }
            }
            n = m;
            for (var i = 0u; i < n; i++) {
                p[i] = q[i];
            }
        }
    }
    if (fan + 2u >= n) {
        return vec4<f32>(2.0, 2.0, 2.0, 1.0);
    }
    let k = select(select(fan + 2u, fan + 1u, corner == 1u), 0u, corner == 0u);
    return face.clip_from_world * vec4<f32>(p[k], 1.0);
}

// The gated map's clear (`shaders/passes/shadow_gate.wgsl`): a triangle covering the layer at depth
// 0 (at infinity: nothing), drawn with `Always` where a render pass cannot clear, because it
// loads the layer so that a frame that draws nothing costs nothing.
@vertex
fn vs_clear(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let xy = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u)) * 2.0 - 1.0;
    return vec4<f32>(xy, 0.0, 1.0);
}
