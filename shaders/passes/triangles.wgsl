#import prelude.wgsl
// The shadow-map node's occluder triangles in world space, for the soft shadows' exact
// visible fraction (`soft_exact` in pcss.wgsl): one dispatch per occluder, one thread per
// group of four of its triangles. A group is 16 vec4 (256 bytes, the storage offset
// alignment): the four triangles' corners (12, w = 0), then a sphere bounding them (centre,
// radius), then three unused. A group's slots past the mesh's triangles hold zero triangles
// (all corners at the origin), which `soft_exact` skips; a group of none has radius 0.

struct Instance {
    world_from_object: mat4x4<f32>,
}

@group(0) @binding(0) var<storage, read> instance: Instance;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> indices: array<u32>;
// This occluder's groups.
@group(0) @binding(3) var<storage, read_write> groups: array<vec4<f32>>;

fn corner(index: u32) -> vec3<f32> {
    return (instance.world_from_object * vec4<f32>(positions[indices[index]].xyz, 1.0)).xyz;
}

@compute @workgroup_size(64, 1, 1)
fn gather(@builtin(global_invocation_id) id: vec3<u32>) {
    let g = id.x;
    if (16u * g + 15u >= arrayLength(&groups)) {
        return;
    }
    let triangles = arrayLength(&indices) / 3u;
    var lo = vec3<f32>(3.4e38);
    var hi = vec3<f32>(-3.4e38);
    for (var k = 0u; k < 4u; k++) {
        let t = 4u * g + k;
        var a = vec3<f32>(0.0);
        var b = vec3<f32>(0.0);
        var c = vec3<f32>(0.0);
        if (t < triangles) {
            a = corner(3u * t);
            b = corner(3u * t + 1u);
            c = corner(3u * t + 2u);
            lo = min(lo, min(a, min(b, c)));
            hi = max(hi, max(a, max(b, c)));
        }
        groups[16u * g + 3u * k] = vec4<f32>(a, 0.0);
        groups[16u * g + 3u * k + 1u] = vec4<f32>(b, 0.0);
        groups[16u * g + 3u * k + 2u] = vec4<f32>(c, 0.0);
    }
    var centre = vec3<f32>(0.0);
    var radius = 0.0;
    if (4u * g < triangles) {
        centre = 0.5 * (lo + hi);
        for (var k = 0u; k < 12u; k++) {
            if (4u * g + k / 3u < triangles) {
                radius = max(radius, length(groups[16u * g + k].xyz - centre));
            }
        }
        // A relative margin for the rounding of the culling test.
        radius = radius * (1.0 + 1.0e-5);
    }
    groups[16u * g + 12u] = vec4<f32>(centre, radius);
    groups[16u * g + 13u] = vec4<f32>(0.0);
    groups[16u * g + 14u] = vec4<f32>(0.0);
    groups[16u * g + 15u] = vec4<f32>(0.0);
}
