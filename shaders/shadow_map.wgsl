#import prelude.wgsl
// Shadow-map node: occluder depth from the light, one layer per face (six for a point light's
// cube, one for a spot light). Reversed-Z infinite perspective: depth = near / distance along
// the face's axis, so nearer occluders win with `Greater` and nothing is clipped far away.

struct ShadowFace {
    clip_from_world: mat4x4<f32>,
}
struct Instance {
    world_from_object: mat4x4<f32>,
}

@group(0) @binding(0) var<storage, read> face: ShadowFace;
@group(0) @binding(1) var<storage, read> instance: Instance;

@vertex
fn vs_shadow(@location(0) position: vec4<f32>) -> @builtin(position) vec4<f32> {
    return face.clip_from_world * (instance.world_from_object * vec4<f32>(position.xyz, 1.0));
}

// The gated map's clear (`shaders/shadow_gate.wgsl`): a triangle covering the layer at depth 0
// (at infinity: nothing), drawn with `Always` where a render pass cannot clear, because it
// loads the layer so that a frame that draws nothing costs nothing.
@vertex
fn vs_clear(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let xy = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u)) * 2.0 - 1.0;
    return vec4<f32>(xy, 0.0, 1.0);
}
