#import prelude.wgsl
// Light-texture mip chain: each level is the level above it filtered by a 4×4 tent (four
// bilinear taps), a blurred pyramid the march reads at the level matching each step's footprint.

@group(0) @binding(0) var source: texture_2d<f32>;
@group(0) @binding(1) var linear_sampler: sampler;

// Level 0: the caller's texture, texel for texel (loaded, not sampled: a sample at the
// interpolated centre may mix in a neighbour, and the flat-region map compares texels exactly).
@fragment
fn fs_copy(in: Fullscreen) -> @location(0) vec4<f32> {
    return vec4<f32>(textureLoad(source, vec2<i32>(in.position.xy), 0).xyz, 1.0);
}

// Level 0 from the red channel alone, as a grey mask (`TextureChannels::Red`).
@fragment
fn fs_copy_red(in: Fullscreen) -> @location(0) vec4<f32> {
    return vec4<f32>(vec3<f32>(textureLoad(source, vec2<i32>(in.position.xy), 0).x), 1.0);
}

@fragment
fn fs_down(in: Fullscreen) -> @location(0) vec4<f32> {
    let texel = 1.0 / vec2<f32>(textureDimensions(source));
    var sum = vec3<f32>(0.0);
    for (var j = -1; j <= 1; j += 2) {
        for (var i = -1; i <= 1; i += 2) {
            sum += textureSampleLevel(source, linear_sampler, in.uv + vec2<f32>(f32(i), f32(j)) * texel, 0.0).xyz;
        }
    }
    return vec4<f32>(0.25 * sum, 1.0);
}
