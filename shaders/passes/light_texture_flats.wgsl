#import prelude.wgsl
// The light texture's flat regions, for the march to cross them in few steps. A cell of the
// texture lies between four texel centres: cell (i, j) spans texel coordinates (i + ½, j + ½)
// to (i + 1½, j + 1½), and every bilinear lookup inside it reads texels i, i + 1 by j, j + 1
// (clamped to the edges, as the light's sampler is). A cell is flat when those four texels are
// equal: the lookup is then that value everywhere in it, exactly. Two cells that touch (edge or
// corner) share a texel, so flat cells that touch have one value, and so does every square of
// flat cells.
//
// The map holds, per cell and per quadrant (+x+y, −x+y, +x−y, −x−y), the side k of the largest
// square of flat cells (at most REACH) that has the cell at its corner and extends from it into
// that quadrant: cells c + (a·sx, b·sy), 0 ≤ a, b < k. 0 where the cell is not flat. A ray's
// image moving into a quadrant crosses that square in one step. Built in three passes over the
// cells: `fs_flags` marks each cell (1 flat, 0 not), `fs_runs` counts the flat cells from each
// cell along +x and −x (itself included, at most REACH), and `fs_squares` takes per quadrant the
// largest k such that the runs of the k cells from it along ±y are all at least k.

@group(0) @binding(0) var source: texture_2d<f32>;
@group(0) @binding(1) var previous: texture_2d<u32>;

// The largest side stored (the map is Rgba8Uint); a flat region wider is crossed in several
// steps.
const REACH: i32 = 63;

fn texel(c: vec2<i32>) -> vec3<f32> {
    let last = vec2<i32>(textureDimensions(source, 0)) - vec2<i32>(1);
    return textureLoad(source, clamp(c, vec2<i32>(0), last), 0).xyz;
}

@fragment
fn fs_flags(in: Fullscreen) -> @location(0) vec4<u32> {
    let c = vec2<i32>(in.position.xy);
    let a = texel(c);
    let same = all(texel(c + vec2<i32>(1, 0)) == a) && all(texel(c + vec2<i32>(0, 1)) == a)
        && all(texel(c + vec2<i32>(1, 1)) == a);
    return vec4<u32>(select(0u, 1u, same), 0u, 0u, 0u);
}

fn inside(c: vec2<i32>) -> bool {
    return all(c >= vec2<i32>(0)) && all(c < vec2<i32>(textureDimensions(previous, 0)));
}

// Flat cells from `c` along `step` (c included), at most REACH.
fn run(c: vec2<i32>, step: vec2<i32>) -> u32 {
    var k = 0;
    while (k < REACH && inside(c + k * step) && textureLoad(previous, c + k * step, 0).x != 0u) {
        k++;
    }
    return u32(k);
}

@fragment
fn fs_runs(in: Fullscreen) -> @location(0) vec4<u32> {
    let c = vec2<i32>(in.position.xy);
    return vec4<u32>(run(c, vec2<i32>(1, 0)), run(c, vec2<i32>(-1, 0)), 0u, 0u);
}

// The side of the largest flat square from `c` along `sy` in y, its runs along x in `channel`
// of the runs (0: +x, 1: −x).
fn square(c: vec2<i32>, sy: i32, channel: u32) -> u32 {
    var shortest = u32(REACH);
    var k = 0u;
    loop {
        let row = c + vec2<i32>(0, sy * i32(k));
        if (k >= shortest || !inside(row)) {
            break;
        }
        shortest = min(shortest, textureLoad(previous, row, 0)[channel]);
        if (k >= shortest) {
            break;
        }
        k++;
    }
    return k;
}

@fragment
fn fs_squares(in: Fullscreen) -> @location(0) vec4<u32> {
    let c = vec2<i32>(in.position.xy);
    return vec4<u32>(square(c, 1, 0u), square(c, 1, 1u), square(c, -1, 0u), square(c, -1, 1u));
}
