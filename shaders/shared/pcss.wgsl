#import prelude.wgsl
// Shadow-map visibility, hard and soft: shared by the march and the soft-shadow volume, which
// import it (`#import pcss.wgsl`). It declares what it reads, bind group 1 of its importer's
// pipelines: the light with its shadow map (`ShadowBinding` in src/nodes/groups/shadow.rs, which
// builds the layout, the group and the parameters for both importers).

// A light with a radius, as the soft estimate reads it (`SoftLight` in src/nodes/soft_shadow.rs).
struct SoftLight {
    nearest: f32,      // the least distance from the light of any occluder's bounds
    spheres: u32,      // bounding spheres (and planes) in `shadow.spheres` and `shadow.planes`
    cell_angle: f32,   // the soft-shadow grid: the angle (radians) a cell subtends; else 0
    reproject: u32,    // 1: the filter's taps move to their own blocker's distance (`soft_filter`)
    groups: u32,       // groups of four of the occluders' triangles in `soft_triangles`
                       // (`soft_exact`); 0: none
}

// The light and its shadow map's parameters (`ShadowUniform` in src/nodes/groups/shadow.rs).
struct LightShadow {
    light: Light,
    faces: array<mat4x4<f32>, 6>,  // each layer's clip_from_world
    spheres: array<vec4<f32>, 8>,  // occluders' world bounding spheres (centre, radius)
    planes: array<vec4<f32>, 8>,   // each sphere's occluder in n·x ≤ d, (n, d); zero: none
    depth_bias: f32,               // the shadow map's relative depth bias
    cube_near: f32,                // a point light's cube faces' near plane where they are the
                                   // shadow-map node's own (see `cube_clip`), else 0
    soft: SoftLight,
}

@group(1) @binding(0) var<storage, read> shadow: LightShadow;
// The front surfaces, and the back faces of closed occluders (the front map again where
// there is none): depth arrays, a layer per cube face or cascade.
@group(1) @binding(1) var shadow_map: texture_depth_2d_array;
@group(1) @binding(2) var shadow_back: texture_depth_2d_array;
@group(1) @binding(3) var shadow_sampler: sampler_comparison;
// The occluders' triangles in world space, `shadow.soft.groups` groups of four, each 16 vec4:
// the corners (w unused), a sphere bounding them (centre, radius), three unused (see
// `soft_exact`; src/nodes/shadow_map.rs gathers them).
@group(1) @binding(4) var<storage, read> soft_triangles: array<vec4<f32>>;
// The half-plane table of `soft_exact` (`half_plane_masks` in src/nodes/groups/shadow.rs): row k,
// the line whose normal makes the angle 2π(k + ½)/256 with the frame's first axis; texels 2j
// and 2j + 1, its offset −1 + 2(j + ½)/128: the bits of the directions on the normal's side.
@group(1) @binding(5) var soft_masks: texture_2d<u32>;
// Whether `soft_search` takes `soft_exact` where the triangles are given: the grid's build
// and the march through the grid do; brute force keeps the shadow map's estimate.
override SOFT_EXACT: bool = true;

// The shadow map's layer holding the world point `p`: the cube face of a point light (+X, −X,
// +Y, −Y, +Z, −Z), else the one layer.
fn shadow_face(p: vec3<f32>) -> u32 {
    if (LIGHT != LIGHT_POINT) {
        return 0u;
    }
    let rel = p - shadow.light.position;
    let m = abs(rel);
    if (m.x >= m.y && m.x >= m.z) {
        return select(1u, 0u, rel.x > 0.0);
    } else if (m.y >= m.z) {
        return select(3u, 2u, rel.y > 0.0);
    }
    return select(5u, 4u, rel.z > 0.0);
}

// Shadow-map visibility of a world point, in [0, 1] (2×2 percentage-closer filtered).
fn visibility(p: vec3<f32>) -> f32 {
    return visibility_of(map_point(p));
}

// Where a world point falls in the shadow map: its layer, its texture coordinates and its own
// depth there (ndc z); `inside` false behind a spot light or outside the map.
struct MapPoint {
    face: u32,
    uv: vec2<f32>,
    depth: f32,
    inside: bool,
}

fn map_point(p: vec3<f32>) -> MapPoint {
    if (LIGHT == LIGHT_DIRECTIONAL) {
        return cascade_point(p);
    }
    let face = shadow_face(p);
    let near = shadow.cube_near;
    if (LIGHT == LIGHT_POINT && near > 0.0) {
        return map_point_of_clip(face, cube_clip(face, p - shadow.light.position, near));
    }
    return map_point_of_clip(face, shadow.faces[face] * vec4<f32>(p, 1.0));
}

// A directional light's cascades (one orthographic layer each, nearest the eye first): the
// first layer whose square holds `p` within a texel of its edge (the 2×2 filter reads a
// neighbour) and whose far plane (ndc z = 0) it is not beyond. In no square: outside (lit). In
// squares but beyond each one's far plane (beyond the shadow distance): the last such layer,
// at its far plane (shadowed where it holds an occluder; anything farther along the light
// than its region was left out of it). The depth carries the bias: DIRECTIONAL_BIAS_TEXELS of
// the layer's texels in world units (1 / row 0's length is the square's half width; row 2's
// length is depth per world unit), so it means the same at any range and scale.
const DIRECTIONAL_BIAS_TEXELS: f32 = 2.0;

fn cascade_point(p: vec3<f32>) -> MapPoint {
    let layers = textureNumLayers(shadow_map);
    let size = f32(textureDimensions(shadow_map).x);
    let edge = 1.0 - 2.0 / size;
    var found = MapPoint(0u, vec2<f32>(0.0), 0.0, false);
    for (var k = 0u; k < layers; k++) {
        let m = shadow.faces[k];
        let c = m * vec4<f32>(p, 1.0);
        if (all(abs(c.xy) <= vec2<f32>(edge))) {
            let half = 1.0 / length(vec3<f32>(m[0].x, m[1].x, m[2].x));
            let per_unit = length(vec3<f32>(m[0].z, m[1].z, m[2].z));
            let bias = DIRECTIONAL_BIAS_TEXELS * 2.0 * half / size * per_unit;
            found = MapPoint(k, vec2<f32>(0.5 + 0.5 * c.x, 0.5 - 0.5 * c.y), max(c.z, 0.0) + bias, true);
            if (c.z >= 0.0) {
                break;
            }
        }
    }
    return found;
}

// The clip coordinates of the offset `rel` from a point light in cube face `face`, where the
// faces are the shadow-map node's own (`shadow.cube_near` > 0, their near plane): a signed
// permutation of `rel`, in place of the face's matrix, which each SIMD lane would read for its
// own face (on llvmpipe, the march at ½ resolution 0.9 of its time on the report's soft scene).
// The faces look along ±X, ±Y, ±Z with up +Y, +Z, +Y; x = (dir × up)·rel, y = up·rel.
fn cube_clip(face: u32, rel: vec3<f32>, near: f32) -> vec4<f32> {
    let sign = select(1.0, -1.0, (face & 1u) == 1u);
    if (face < 2u) {
        return vec4<f32>(sign * rel.z, rel.y, near, sign * rel.x);
    }
    if (face < 4u) {
        return vec4<f32>(sign * rel.x, rel.z, near, sign * rel.y);
    }
    return vec4<f32>(-sign * rel.x, rel.y, near, sign * rel.z);
}

// The `MapPoint` of clip coordinates `clip` in layer `face`.
fn map_point_of_clip(face: u32, clip: vec4<f32>) -> MapPoint {
    if (clip.w <= 0.0) {
        return MapPoint(face, vec2<f32>(0.0), 0.0, false);
    }
    let ndc = clip.xyz / clip.w;
    if (any(abs(ndc.xy) > vec2<f32>(1.0))) {
        return MapPoint(face, vec2<f32>(0.0), 0.0, false);
    }
    return MapPoint(face, vec2<f32>(0.5 + 0.5 * ndc.x, 0.5 - 0.5 * ndc.y), ndc.z, true);
}

// `visibility` of a point where it falls in the map.
fn visibility_of(m: MapPoint) -> f32 {
    if (!m.inside) {
        return 1.0; // behind a spot light (outside its cone, which the support already excludes), or outside the map
    }
    // Reversed Z: depth = near / distance; nearer than the occluder ⇔ larger depth. The bias
    // is relative, so it means the same at every scene scale.
    var reference = m.depth / (1.0 - shadow.depth_bias);
    if (LIGHT == LIGHT_DIRECTIONAL) {
        // `cascade_point` clamped it to the far plane and added the bias in world units.
        reference = m.depth;
    }
    return textureSampleCompareLevel(shadow_map, shadow_sampler, m.uv, i32(m.face), reference);
}

// Soft shadows. Taps on a disc: golden-angle spiral, equal areas (Vogel 1979).
// Taps a blocker-search round: 16 cost more and were no more accurate in the soft tests
// (tests/gpu/soft.rs, tests/gpu/soft_grid.rs); 6 were worse.
const SOFT_SEARCH_TAPS: u32 = 8u;
const SOFT_FILTER_TAPS: u32 = 32u;
// cos and sin of the golden angle π(3 − √5).
const GOLDEN_COS: f32 = -0.7373688780783197;
const GOLDEN_SIN: f32 = 0.6754902942615238;

// The projection of an estimate's taps, hoisted out of its loops: the clip coordinates of the
// light's position and of the basis vectors u, e1, e2 in the layer of u's direction. A tap
// projected through it takes no face choice, no matrix read (a gather, where each SIMD lane
// has its own cube face) and half the arithmetic of projecting its world point. Measured on
// the report's soft scene, alternated in one process with the projection per tap: the
// grid's build 0.87–0.95 of its time.
struct TapFrame {
    face: u32,
    light: vec4<f32>,
    u: vec4<f32>,
    e1: vec4<f32>,
    e2: vec4<f32>,
}

fn tap_frame(b: SoftBasis) -> TapFrame {
    let face = shadow_face(shadow.light.position + b.u);
    let m = shadow.faces[face];
    return TapFrame(face, m * vec4<f32>(shadow.light.position, 1.0), m * vec4<f32>(b.u, 0.0), m * vec4<f32>(b.e1, 0.0), m * vec4<f32>(b.e2, 0.0));
}

// Where the tap falls in the map: the point at the distance of `p` from the light (b), in
// the direction u tilted by `t` (tangent of the angle) towards `cs` (a unit vector in the
// frame (e1, e2)); through the hoisted projection where it lies in u's layer, else (a cube
// map's neighbouring face) as any point.
fn tap_point(f: TapFrame, b: SoftBasis, t: f32, cs: vec2<f32>) -> MapPoint {
    let d = b.u + t * (cs.x * b.e1 + cs.y * b.e2);
    let k = b.dist * vs_inverse_sqrt(dot(d, d));
    let m = map_point_of_clip(f.face, f.light + k * (f.u + t * (cs.x * f.e1 + cs.y * f.e2)));
    if (m.inside || LIGHT == LIGHT_SPOT) {
        return m;
    }
    return map_point(shadow.light.position + k * d);
}

// Tap k of n on the spiral: its radius on the unit disc (equal areas).
fn spiral_radius(k: u32, n: u32) -> f32 {
    return vs_sqrt((f32(k) + 0.5) / f32(n));
}

// The next tap's direction on the spiral: `cs` turned by the golden angle. A rotation per tap
// in place of a sine and a cosine (the drift over 32 taps is ~1e-6).
fn spiral_next(cs: vec2<f32>) -> vec2<f32> {
    return vec2<f32>(GOLDEN_COS * cs.x - GOLDEN_SIN * cs.y, GOLDEN_SIN * cs.x + GOLDEN_COS * cs.y);
}

// The distance from the light of the occluder in the shadow map towards `q`, as a fraction of
// |q − light| (< 1, or 2 where nothing is in front of q): between its front surface and its
// back face (both before q; see below), where a convex occluder's outline lies near its rim.
// The lines from a point to the light's disc graze the outline; its front surface alone is
// nearer the light and widens the filter, which brightens the deep penumbra (with the eye in
// an umbra looking away from the light, tests/gpu/soft_grid.rs: p95 41% with the front surface).
fn blocker_ratio(q: vec3<f32>) -> f32 {
    return blocker_ratio_of(map_point(q));
}

// `blocker_ratio` of a point where it falls in the map.
fn blocker_ratio_of(m: MapPoint) -> f32 {
    let t = map_texel_of(m);
    if (!t.inside) {
        return 2.0;
    }
    let depth = textureLoad(shadow_map, t.texel, i32(t.face), 0);
    // Reversed Z: depth = near / distance along the face's axis, so the ratio of distances
    // along one direction is the inverse ratio of depths.
    if (depth * (1.0 - shadow.depth_bias) > t.depth) {
        let front = t.depth / depth;
        // Reversed Z: the back face is at most as deep as the front; 0 where none was drawn.
        let back_depth = textureLoad(shadow_back, t.texel, i32(t.face), 0);
        let back = select(front, min(t.depth / back_depth, 1.0), back_depth > 0.0 && back_depth <= depth);
        // Between the chord's midpoint m and the geometric mean g = √(front·back): for a
        // sphere, m is its centre's distance where the chord passes through the centre, and g
        // its tangent distance on every chord (the power of the light's point). Even with the
        // sphere's exact outline in place of the map, a planar blocker at the centre's
        // distance sets the deep penumbra (visible fraction 0.02 to 0.2) too dark, by 4% to
        // 43% for ρ/L from 0.1 to 0.4, and at the tangent distance too bright, by 12% to 22%
        // (a CPU model against the exact cap overlap). m^¾ g^¼, a fit, leaves the grid's cells
        // of the seeded scenes without bias there (tests/gpu/soft_grid.rs).
        let mid = 0.5 * (front + back);
        // (max: a point so far that its depth is 0 has mid = 0, and 0/0 would be NaN.)
        return mid * vs_sqrt(vs_sqrt(vs_sqrt(front * back) / max(mid, 1.0e-30)));
    }
    return 2.0;
}

// The shadow map's texel holding the world point `p`: its layer, texel and `p`'s own depth
// there (ndc z); `inside` false behind a spot light or outside the map.
struct MapTexel {
    face: u32,
    texel: vec2<i32>,
    depth: f32,
    inside: bool,
}

fn map_texel(p: vec3<f32>) -> MapTexel {
    return map_texel_of(map_point(p));
}

fn map_texel_of(m: MapPoint) -> MapTexel {
    if (!m.inside) {
        return MapTexel(m.face, vec2<i32>(0), 0.0, false);
    }
    let size = vec2<f32>(textureDimensions(shadow_map));
    let texel = vec2<i32>(clamp(m.uv * size, vec2<f32>(0.0), size - 1.0));
    return MapTexel(m.face, texel, m.depth, true);
}

// The fraction of the light's disc visible from `p` (percentage-closer soft shadows, Fernando
// 2005, in the one shadow map): a blocker search over the directions, seen from the light,
// where a line from `p` to the disc can meet an occluder, then the mean of the hard
// visibility over the directions where the lines from `p` to the disc cross the blockers'
// mean distance. Taps are points at the distance of `p`, so a cube map's faces are chosen
// per tap.
fn visibility_soft(p: vec3<f32>) -> f32 {
    return soft_estimate(p).x;
}

// `visibility_soft` and the tangent of the angular radius (seen from the light) of the region
// around p's direction it found the penumbra's outline within: its filter's, or where it
// stopped at the blocker search (nothing in front of p there, or all of it), the search's;
// −1 where it took no tap (nearer than every occluder, outside every penumbra cone).
fn soft_estimate(p: vec3<f32>) -> vec2<f32> {
    let found = soft_search(p);
    if (found.z < 0.0) {
        return found.xy;
    }
    let f = soft_filter_at(p, found.z);
    if (soft_is_deep(f)) {
        return vec2<f32>(soft_deepen(p, found.z, f), found.z);
    }
    return vec2<f32>(f, found.z);
}

// What the stages of `soft_estimate` share about a point: its distance from the light, the
// unit direction u to it, a frame (e1, e2) around u and the spiral's first direction there.
struct SoftBasis {
    dist: f32,
    u: vec3<f32>,
    e1: vec3<f32>,
    e2: vec3<f32>,
    start: vec2<f32>,
}

fn soft_basis(p: vec3<f32>) -> SoftBasis {
    let rel = p - shadow.light.position;
    let dist = length(rel);
    let u = rel / dist;
    let frame = soft_frame(u);
    let turn = soft_turn(p);
    // Any rotation will do: WGSL's 2^-11 on each of cos and sin scales the taps' radius by at
    // most 7e-4.
    return SoftBasis(dist, u, frame[0], frame[1], vec2<f32>(vs_cos(turn), vs_sin(turn)));
}

// Whether the last `soft_search` (and so `soft_estimate`, `visibility_soft`) took two layers
// of blockers: occluders at clearly different distances, one's penumbra over the other's,
// where the shadow map may hide part of the far one behind the near one.
var<private> soft_two_layers: bool;

// The least distance from the light of any occluder (its bounds), at least 1e-3 of the
// light's radius: a point nearer sees all of the light.
fn soft_nearest() -> f32 {
    return max(shadow.soft.nearest, 1.0e-3 * shadow.light.radius);
}

// The filter's width (a tangent) for a point at `dist` from the light and blockers at `ratio`
// of that distance: a line from the point to the light's point at lateral offset radius·w
// meets the sphere of distance b around the light in the direction tilted by
// radius·(1/b − 1/dist)·w. At most the search's width (blockers at the nearest distance;
// `ratio` 0 gives it).
fn soft_width(dist: f32, ratio: f32) -> f32 {
    let radius = shadow.light.radius;
    let nearest = soft_nearest();
    return min(radius * (1.0 / max(dist * ratio, nearest) - 1.0 / dist), radius * (1.0 / nearest - 1.0 / dist));
}

// The first stage of `soft_estimate`, the blocker search: (visibility, region, −1) where it
// decides alone (no tap needed, lit, umbra, or two layers, whose filter it takes), else
// (·, ·, width): the filter's width for `soft_filter_at`, the next stage.
fn soft_search(p: vec3<f32>) -> vec3<f32> {
    soft_two_layers = false;
    let radius = shadow.light.radius;
    let dist0 = length(p - shadow.light.position);
    if (dist0 <= radius) {
        return vec3<f32>(1.0, -1.0, -1.0); // inside the light's sphere: all of it is visible (as the reference)
    }
    if (!(dist0 > soft_nearest()) || !may_be_hidden(p)) {
        return vec3<f32>(1.0, -1.0, -1.0); // nearer than every occluder, or outside every penumbra cone
    }
    if (SOFT_EXACT && shadow.soft.groups > 0u) {
        return vec3<f32>(soft_exact(p, soft_width(dist0, 0.0)), -1.0);
    }
    let basis = soft_basis(p);
    let tf = tap_frame(basis);
    let dist = basis.dist;
    let start = basis.start;
    let search = soft_width(dist, 0.0);
    var sum = 0.0;
    var count = 0.0;
    var cs = start;
    // The blockers found (their distance ratios, 2 for none) and the nearest of them: blockers
    // at clearly different distances are two layers (see below).
    var found: array<f32, SOFT_FOUND_TAPS>;
    var least = 2.0;
    for (var k = 0u; k < SOFT_SEARCH_TAPS; k++) {
        let b = blocker_ratio_of(tap_point(tf, basis, search * spiral_radius(k, SOFT_SEARCH_TAPS), cs));
        cs = spiral_next(cs);
        found[k] = b;
        if (b < 1.0) {
            sum = max(sum, b);
            count += 1.0;
            least = min(least, b);
        }
    }
    let centre = blocker_ratio(p);
    found[SOFT_FOUND_TAPS - 1u] = centre;
    if (centre < 1.0) {
        sum = max(sum, centre);
        count += 1.0;
        least = min(least, centre);
    }
    if (count == 0.0) {
        return vec3<f32>(1.0, search, -1.0); // no blocker within `search` of p's direction
    }
    var width = soft_width(dist, sum);
    // Once more over the directions the filter will cover: the blockers nearest to where the
    // lines from p to the disc graze them (a convex occluder's outline) decide.
    var blocked = 0u;
    cs = start;
    for (var k = 0u; k < SOFT_SEARCH_TAPS; k++) {
        let b = blocker_ratio_of(tap_point(tf, basis, width * spiral_radius(k, SOFT_SEARCH_TAPS), cs));
        cs = spiral_next(cs);
        found[SOFT_SEARCH_TAPS + k] = b;
        if (b < 1.0) {
            sum = max(sum, b);
            blocked++;
            least = min(least, b);
        }
    }
    // Every tap of both rounds blocked: the umbra (the filter covers no more than the second
    // round did).
    if (blocked == SOFT_SEARCH_TAPS && count == f32(SOFT_SEARCH_TAPS + 1u)) {
        return vec3<f32>(0.0, search, -1.0);
    }
    width = soft_width(dist, sum);
    if (sum > LAYER_SPLIT * least) {
        soft_two_layers = true;
        // Two layers: occluders at clearly different distances (one's penumbra over the
        // other's), each with its own filter width, the farthest blocker of its own layer. A
        // line from p to the disc's point at the spiral's tap k is blocked if either layer
        // hides the tap's direction at its width (the union, not a product of fractions).
        // Measured (tests/gpu/soft_grid.rs, overlapping penumbrae): p95 4.63% → 4.13%; scenes
        // with one occluder never take this branch.
        let split = vs_sqrt(sum * least);
        var near = least;
        for (var k = 0u; k < SOFT_FOUND_TAPS; k++) {
            if (found[k] < split) {
                near = max(near, found[k]);
            }
        }
        let near_width = soft_width(dist, near);
        var lit = 0.0;
        var far_hits = 0u;
        cs = start;
        for (var k = 0u; k < SOFT_FILTER_TAPS; k++) {
            let r = spiral_radius(k, SOFT_FILTER_TAPS);
            let far_b = blocker_ratio_of(tap_point(tf, basis, width * r, cs));
            let near_b = blocker_ratio_of(tap_point(tf, basis, near_width * r, cs));
            cs = spiral_next(cs);
            let far_hidden = far_b < 1.0 && far_b >= split;
            let near_hidden = near_b < split;
            far_hits += select(0u, 1u, far_hidden);
            lit += select(1.0, 0.0, far_hidden || near_hidden);
        }
        // The region the visibility changes within: the far layer's, unless it hides none of
        // the taps and lies just in front of p's distance (a receiver p is above, such as a
        // ground that casts shadows: its edge is its own surface, which the grid marks
        // between slices). Its width would mark the cell sharp, and the march would blend in
        // the shadow map's hard edge in place of the near layer's wide penumbra (tests/gpu/soft_grid.rs:
        // the ground and overlapping-penumbrae scenes).
        let receiver = far_hits == 0u && sum >= RECEIVER_RATIO;
        let region = select(width, near_width, receiver);
        return vec3<f32>(lit / f32(SOFT_FILTER_TAPS), region, -1.0);
    }
    return vec3<f32>(0.0, width, width);
}

// The second stage of `soft_estimate`: the filter's mean over its taps at `width`.
fn soft_filter_at(p: vec3<f32>, width: f32) -> f32 {
    let b = soft_basis(p);
    return soft_filter(b, width, SOFT_FILTER_TAPS, b.start);
}

// Whether the filter's fraction `f` is in the deep penumbra, which `soft_deepen` refines.
fn soft_is_deep(f: f32) -> bool {
    return f > 0.0 && f <= SOFT_DEEP;
}

// The third stage: the deep penumbra, the filter's fraction `f` with more taps on a second
// spiral, turned a quarter, so that a small fraction is not one or two taps' worth of it.
fn soft_deepen(p: vec3<f32>, width: f32, f: f32) -> f32 {
    let b = soft_basis(p);
    let more = soft_filter(b, width, SOFT_DEEP_TAPS, vec2<f32>(-b.start.y, b.start.x));
    return (f * f32(SOFT_FILTER_TAPS) + more * f32(SOFT_DEEP_TAPS)) / f32(SOFT_FILTER_TAPS + SOFT_DEEP_TAPS);
}

// Where the filter's 32 taps find a visible fraction of at most SOFT_DEEP (12 taps lit), it
// takes SOFT_DEEP_TAPS more: each tap is lit or not, so over a small fraction the estimate's
// error is large relative to it, and a pixel lit by the deep penumbra (the eye in an umbra, in
// a thick medium) shows it (tests/gpu/soft_grid.rs: the grid cells' deep-penumbra error; the eye
// in an umbra looking away).
const SOFT_DEEP: f32 = 0.375;
const SOFT_DEEP_TAPS: u32 = 96u;

// Taps whose blockers `soft_estimate` keeps: both search rounds and the centre.
const SOFT_FOUND_TAPS: u32 = 2u * SOFT_SEARCH_TAPS + 1u;
// A far layer at least this fraction of p's distance from the light, hiding none of p's
// taps, is a receiver p lies just above (see `soft_estimate`).
const RECEIVER_RATIO: f32 = 0.9;
// Blockers' distances further apart than this ratio are two layers in `soft_estimate`.
const LAYER_SPLIT: f32 = 1.5;

// The mean hard visibility over `n` taps of the disc of angular radius `width` (its tangent)
// around the direction u from the light, at distance `dist` (the filter of `soft_estimate`).
fn soft_filter(b: SoftBasis, width: f32, n: u32, start: vec2<f32>) -> f32 {
    let tf = tap_frame(b);
    var lit = 0.0;
    var cs = start;
    for (var k = 0u; k < n; k++) {
        let r = spiral_radius(k, n);
        var m = tap_point(tf, b, width * r, cs);
        // The tap where its line crosses its own blocker (where occluders may leave gaps):
        // `width` puts every tap on the sphere at the farthest blocker's distance, but a plate
        // turned to the light lies nearer on one side and farther on the other, and the
        // lines to a gap near its edge cross it elsewhere. One step towards that crossing: at
        // the distance of the blocker the map holds where the tap first fell (brute force at
        // 256 steps on a square hole 1.25 of the light's diameter, tests/gpu/soft_grid.rs:
        // p95 6.14% → 1.67%). A convex occluder alone keeps the one distance, which
        // `blocker_ratio_of` is fitted to (with the step, an eye in a sphere's umbra looking
        // away: p95 4.64% → 14.3%).
        if (shadow.soft.reproject != 0u) {
            let bk = blocker_ratio_of(m);
            if (bk < 1.0) {
                m = tap_point(tf, b, soft_width(b.dist, bk) * r, cs);
            }
        }
        lit += visibility_of(m);
        cs = spiral_next(cs);
    }
    return lit / f32(n);
}

// An orthonormal frame (e1, e2) around the unit vector u (Duff et al., "Building an
// Orthonormal Basis, Revisited", 2017).
fn soft_frame(u: vec3<f32>) -> array<vec3<f32>, 2> {
    let sgn = select(-1.0, 1.0, u.z >= 0.0);
    let fa = -1.0 / (sgn + u.z);
    let fb = u.x * u.y * fa;
    return array<vec3<f32>, 2>(
        vec3<f32>(1.0 + sgn * u.x * u.x * fa, sgn * fb, -sgn * u.x),
        vec3<f32>(fb, sgn + u.y * u.y * fa, -u.y),
    );
}

// The spiral's turn at p, in [−π, π): a hash of the point, so that successive steps of a ray
// see different taps and the pattern's error averages out along it instead of adding up. An
// integer hash of the coordinates' bits, the same on every GPU (`sin` of a large argument,
// the usual shader hash, has no precision WGSL promises outside [−π, π], and gave each GPU its
// own pattern). The pattern is noise the soft tests' measured limits sit within: see the
// soft-shadow notes in docs/METHOD.md for how the constant was chosen.
fn soft_turn(p: vec3<f32>) -> f32 {
    let b = bitcast<vec3<u32>>(p);
    var h = (b.x * 0x8da6b343u) ^ (b.y * 0xd8163841u) ^ (b.z * 0xcb1ab31fu) ^ 0x89abcdefu;
    h ^= h >> 16u;
    h *= 0x7feb352du;
    h ^= h >> 15u;
    h *= 0x846ca68bu;
    h ^= h >> 16u;
    return (f32(h >> 8u) * (1.0 / 8388608.0) - 1.0) * PI;
}

// The relative margin on the sine of a penumbra cone's half-angle (`may_be_hidden`, and the
// march's `penumbra_cone`): the filter's penumbra reaches a little beyond the occluder's own,
// where the blockers' distance it takes is nearer the light than where the lines to the disc
// graze the occluder, and the grid interpolates across the cone's edge. Measured on the
// seeded spot scenes of tests/gpu/soft_grid.rs, with the occluders' tight bounding spheres: 1.05
// left seed 210 at RMSE 2.04%, 1.10 at 1.16% (1.15 and 1.3 no better there, and worst p95
// 7.4% against 7.5%, for a longer march: on the report's soft scene 18.4 steps a pixel at
// ½ resolution with 1.15, 16.1 with 1.05). With the bounding boxes' circumspheres, √3
// times a sphere's radius, 1.05 had been enough.
const PENUMBRA_CONE_MARGIN: f32 = 1.10;

// Whether p lies in one of the cones of `penumbra_cone` (all of space without bounds).
fn may_be_hidden(p: vec3<f32>) -> bool {
    let count = shadow.soft.spheres;
    if (count == 0u) {
        return true;
    }
    let radius = shadow.light.radius;
    for (var i = 0u; i < count; i++) {
        // Beyond the occluder's plane, away from it: no line to the light meets it.
        if (dot(shadow.planes[i].xyz, p) > shadow.planes[i].w) {
            continue;
        }
        let to_c = shadow.spheres[i].xyz - shadow.light.position;
        let rho = shadow.spheres[i].w;
        let l = length(to_c);
        let sin_t = PENUMBRA_CONE_MARGIN * (radius + rho) / max(l, 1.0e-30);
        if (sin_t >= 0.999) {
            return true;
        }
        let axis = to_c / l;
        let rel = p - (shadow.light.position + axis * (l * radius / (radius + rho)));
        if (dot(axis, rel) >= vs_sqrt(1.0 - sin_t * sin_t) * length(rel)) {
            return true;
        }
    }
    return false;
}

// The turn of `soft_exact`'s directions about the axis, in turns: a caller sets `exact_seed`
// (a pixel's or a cell's, in [0, 1)), and each turn of the invocation (`exact_calls`) adds a
// further `EXACT_TURN`. 256 fixed directions cover a sliver of the light (a door ajar seen
// from beside its shaft) by whole directions, the same ones at every point of a ray that the
// sliver crosses slowly; turned, their errors average out along the ray (see `soft_exact`).
var<private> exact_seed: f32 = 0.0;
var<private> exact_calls: u32 = 0u;

// A seed for `exact_seed` from a pixel's or a cell's integer coordinates: interleaved gradient
// noise (Jimenez 2014), so that neighbours' directions are turned apart.
fn exact_seed_at(at: vec3<f32>) -> f32 {
    return fract(52.982918 * fract(dot(at, vec3<f32>(0.06711056, 0.00583715, 0.2360680))));
}

// The directions `soft_exact` tests: 256 points of the unit disc (a golden-angle spiral,
// equal areas) in 8 rings of 32, a `u32` of bits each, scaled to the light's disc.
const EXACT_RINGS: u32 = 8u;
const MASK_ANGLES: f32 = 256.0;
const MASK_OFFSETS: u32 = 128u;

// A set of the 256 directions (bit i of word i / 32 for direction i).
struct Mask {
    lo: vec4<u32>,
    hi: vec4<u32>,
}

// The directions d = (tan α · q, 1) of the frame of `soft_exact` with dot(d, m) ≥ 0: the
// half-plane q·m.xy ≥ −m.z / tan α of the disc, from the table, the line's angle and offset
// each to the nearest of the table's (1/256 of a turn, 1/64 of the disc's radius; atan2's
// 4096 ULP are 1e-3 rad at most, a twenty-fifth of a bin).
fn half_plane(m: vec3<f32>, tan_a: f32) -> Mask {
    let all = Mask(vec4<u32>(0xffffffffu), vec4<u32>(0xffffffffu));
    let none = Mask(vec4<u32>(0u), vec4<u32>(0u));
    let l = length(m.xy);
    let c = -m.z / (tan_a * l);
    if (!(l > 0.0) || !(c > -1.0)) {
        // The line misses the disc (or m is along the axis): all of it or none.
        if (m.z >= 0.0) {
            return all;
        }
        return none;
    }
    if (c > 1.0) {
        return none;
    }
    let turn = atan2(m.y, m.x) * (0.5 / PI);
    let k = i32(floor(fract(turn + 1.0) * MASK_ANGLES)) % i32(MASK_ANGLES);
    let j = i32(min(u32((c + 1.0) * 0.5 * f32(MASK_OFFSETS)), MASK_OFFSETS - 1u));
    return Mask(textureLoad(soft_masks, vec2<i32>(2 * j, k), 0), textureLoad(soft_masks, vec2<i32>(2 * j + 1, k), 0));
}

fn mask_and(a: Mask, b: Mask) -> Mask {
    return Mask(a.lo & b.lo, a.hi & b.hi);
}

// 1 − cos θ for tan²θ = x, without cancellation.
fn exact_versine(x: f32) -> f32 {
    let r = vs_sqrt(1.0 + x);
    return x / (r * (1.0 + r));
}

// What one triangle hides of the light (see `soft_exact`): its directions, and the least
// distance from p along the axis where it does (where its plane meets the axis, within its
// corners' range).
struct Hidden {
    mask: Mask,
    z: f32,
}

// `soft_exact`'s triangle (a, b, c relative to p, in its frame), cut at z = `cut`.
fn exact_triangle(a0: vec3<f32>, b0: vec3<f32>, c0: vec3<f32>, cut: f32, tan_a: f32) -> Hidden {
    var out = Hidden(Mask(vec4<u32>(0u), vec4<u32>(0u)), 3.4e38);
    var a = a0;
    var b = b0;
    var c = c0;
    // Cut at z = cut: none, one or two corners beyond leave a triangle or a quad
    // (v0, v1, v2, v3 in the triangle's order; v3 = v0 for a triangle).
    let beyond = u32(a.z >= cut) + u32(b.z >= cut) + u32(c.z >= cut);
    if (beyond == 3u) {
        return out;
    }
    if (beyond == 1u) {
        // The corner beyond last: (a, b, c) turned.
        if (a.z >= cut) {
            let o = a;
            a = b;
            b = c;
            c = o;
        } else if (b.z >= cut) {
            let o = c;
            c = b;
            b = a;
            a = o;
        }
    } else if (beyond == 2u) {
        // The corner kept first.
        if (b.z < cut) {
            let o = a;
            a = b;
            b = c;
            c = o;
        } else if (c.z < cut) {
            let o = c;
            c = b;
            b = a;
            a = o;
        }
    }
    let v0 = a;
    var v1 = b;
    var v2 = c;
    var v3 = a;
    if (beyond == 1u) {
        v2 = b + (c - b) * ((cut - b.z) / (c.z - b.z));
        v3 = a + (c - a) * ((cut - a.z) / (c.z - a.z));
    } else if (beyond == 2u) {
        v1 = a + (b - a) * ((cut - a.z) / (b.z - a.z));
        v2 = a + (c - a) * ((cut - a.z) / (c.z - a.z));
    }
    let det = dot(v0, cross(v1, v2));
    if (det == 0.0) {
        return out; // p in the triangle's plane (or a zero triangle): the lines graze it
    }
    let s = select(-1.0, 1.0, det > 0.0);
    var m = mask_and(half_plane(s * cross(v0, v1), tan_a), mask_and(half_plane(s * cross(v1, v2), tan_a), half_plane(s * cross(v2, v3), tan_a)));
    if (beyond == 1u) {
        m = mask_and(m, half_plane(s * cross(v3, v0), tan_a));
    }
    out.mask = m;
    if (any((m.lo | m.hi) != vec4<u32>(0u))) {
        let n = cross(v1 - v0, v2 - v0);
        let lo = min(min(v0.z, v1.z), min(v2.z, v3.z));
        let hi = max(max(v0.z, v1.z), max(v2.z, v3.z));
        var z = lo;
        if (n.z != 0.0) {
            z = clamp(dot(n, v0) / n.z, lo, hi);
        }
        out.z = max(z, 0.0);
    }
    return out;
}

// The fraction of the light's sphere visible from `p` (outside it), from the occluders'
// triangles themselves (`soft_triangles`), not the shadow map: bitmask soft shadows
// (Schwarz and Stamminger, "Bitmask Soft Shadows", 2007) with the triangles in place of
// shadow-map texels. A shadow map sees the occluders from the light's centre alone, and
// through a gap narrower than the light (a slit, blinds, a door ajar) a point sees parts of
// the light past faces the centre does not see (see docs/METHOD.md, "Gaps narrower than the
// light").
//
// The light's cap, seen from p in a frame whose third axis points at the light's centre, is
// the disc of radius tan α of the plane one unit from p, and a direction there is d =
// (tan α · q, 1) for q in the unit disc. A line from p along d meets a triangle (a, b, c
// relative to p) ahead of p exactly when d is a positive combination of a, b, c: when d lies
// on the inner side of the three planes through p and an edge, each a half-plane of the disc
// (`half_plane`). A triangle hides the directions of its three half-planes; the occluders
// hide their union. The 256 directions lie in 8 rings of equal area of the disc, whose solid
// angles weigh them (exact per ring: the plane's rings are not equal caps of the sphere).
// The part of a triangle beyond the plane where the cone of lines from p touches the light's
// sphere is cut off: every line has entered the sphere there (an occluder reaching into the
// light's sphere is beyond this model). One pass over groups of four triangles, each group culled
// by its bounding sphere against the cone of lines to the light: llvmpipe ends every loop of
// an invocation once its loops together reach 65 535 iterations (Mesa's
// LP_MAX_TGSI_LOOP_ITERATIONS), and the march takes this at many points of a ray, so the
// directions are words of bits and the four triangles of a group are not a loop.
//
// Where the last call found a sliver of the light, more turns of the directions over the
// groups the first did not cull refine the fraction (`EXACT_FEW`).
//
// Returns (fraction, region) as `soft_search` does: the region is the filter width
// (`soft_width`) of a blocker at the least distance from p, along the axis, of a triangle
// that hides a direction, or `search` where none or all of the light is hidden.
fn soft_exact(p: vec3<f32>, search: f32) -> vec2<f32> {
    let to_light = shadow.light.position - p;
    let dist = length(to_light);
    let light = exact_light(p, to_light / dist, dist);
    // How many turns: from the fraction the previous call of this invocation found (the
    // previous step of a ray), not from this one's first turn. Refining only where the first
    // turn saw a direction would leave a sliver's points that saw none at 0 and average down
    // those that saw one: darker than the sliver on average.
    var passes = 1u;
    if (exact_last > 0.0 && exact_last < f32(EXACT_FEW) / f32(EXACT_SAMPLES)) {
        let wanted = ceil(f32(EXACT_FEW) / (exact_last * f32(EXACT_SAMPLES)));
        passes = u32(min(wanted, f32(EXACT_PASSES)));
    }
    let first = exact_pass(light, false);
    let hidden = first.mask;
    var f = exact_fraction(hidden, light);
    let listed = exact_listed_count;
    if (passes > 1u && listed > 0u && listed <= EXACT_LISTED) {
        // More turns over the groups the first did not cull (the same cone, whatever the
        // turn), as many as keep the call within one turn over `EXACT_BUDGET` groups.
        let turns = min(passes, 1u + (EXACT_BUDGET - min(shadow.soft.groups, EXACT_BUDGET)) / listed);
        var sum = f;
        for (var k = 1u; k < turns; k++) {
            sum += exact_fraction(exact_pass(light, true).mask, light);
        }
        f = sum / f32(turns);
    }
    exact_last = f;
    let blocked = hidden.lo | hidden.hi;
    let all_hidden = all((hidden.lo & hidden.hi) == vec4<u32>(0xffffffffu));
    if (all(blocked == vec4<u32>(0u)) || all_hidden) {
        return vec2<f32>(f, search);
    }
    return vec2<f32>(f, soft_width(dist, clamp(1.0 - min(first.z, dist) / dist, 0.0, 1.0)));
}

// Where `soft_exact` sees the light from, the same at every turn: the point, the unit axis to
// the light's centre, its distance, the cap's half-angle α (sin, cos, tan), the plane of the
// cut along the axis, and the rings' solid angles over the cap's (`exact_fraction`).
struct ExactLight {
    p: vec3<f32>,
    axis: vec3<f32>,
    dist: f32,
    sin_a: f32,
    cos_a: f32,
    tan_a: f32,
    cut: f32,
    ring_lo: vec4<f32>,
    ring_hi: vec4<f32>,
    whole: f32,
}

fn exact_light(p: vec3<f32>, axis: vec3<f32>, dist: f32) -> ExactLight {
    let radius = shadow.light.radius;
    let sin_a = min(radius / dist, 1.0);
    let cos_a = vs_sqrt(max(1.0 - sin_a * sin_a, 0.0));
    let tan_a = sin_a / max(cos_a, 1.0e-30);
    // Where the lines to the light's sphere have all entered it, along the axis: the plane of
    // the circle where the cone of lines from p touches it (d·cos²α). A point of the cone
    // nearer p and outside the sphere lies before the sphere on its line; one beyond lies
    // behind where its line entered the sphere.
    let cut = dist - radius * sin_a;
    // Ring k spans tan²θ from tan²α·k/8 to tan²α·(k + 1)/8 of the plane.
    let t2 = tan_a * tan_a;
    let whole = exact_versine(t2);
    let eighth = t2 / f32(EXACT_RINGS);
    let v = vec4<f32>(exact_versine(eighth), exact_versine(2.0 * eighth), exact_versine(3.0 * eighth), exact_versine(4.0 * eighth));
    let u = vec4<f32>(exact_versine(5.0 * eighth), exact_versine(6.0 * eighth), exact_versine(7.0 * eighth), whole);
    return ExactLight(p, axis, dist, sin_a, cos_a, tan_a, cut, v - vec4<f32>(0.0, v.xyz), u - vec4<f32>(v.w, u.xyz), whole);
}

// Slivers. Where the invocation's last call (the previous refined step of a ray) found less
// than `EXACT_FEW` directions' worth of the light (1/8 of it), a call takes ceil(EXACT_FEW /
// that) turns of the directions, at most `EXACT_PASSES`, and averages them: a sliver a few
// directions wide is counted by whole directions, ±1 of a few at each turn (see
// docs/METHOD.md, "Gaps narrower than the light"). The turns after the first test only the
// groups the first did not cull, when they are at most `EXACT_LISTED`, and no more of them
// than keep a call within `EXACT_BUDGET` groups' iterations, one turn over 512 triangles
// (`MAX_EXACT_TRIANGLES`: llvmpipe's loop limit, below).
const EXACT_FEW: u32 = 32u;
const EXACT_PASSES: u32 = 8u;
const EXACT_LISTED: u32 = 16u;
const EXACT_BUDGET: u32 = 128u;
const EXACT_SAMPLES: u32 = 256u;
var<private> exact_listed: array<u32, EXACT_LISTED>;
var<private> exact_listed_count: u32;
// The visible fraction the invocation's last `soft_exact` found (1 before any).
var<private> exact_last: f32 = 1.0;
// The turn between an invocation's calls, in turns: 1/ρ for ρ the plastic number (the first
// coordinate of Roberts' R2 sequence, 2018). Not the golden fraction: turned by it the
// golden-angle spiral of the directions falls nearly onto itself, each direction near the
// angle of the next one in, and a sliver at the disc's edge sees few new angles (the door
// ajar by 0.23 of the light's diameter, seed 411: p95 1.3–3.1% over four seeds' shifts, 1.1–
// 1.2% with this).
const EXACT_TURN: f32 = 0.75487767;

// The visible fraction of the cap from a mask of hidden directions: each ring's solid angle
// over the cap's.
fn exact_fraction(hidden: Mask, light: ExactLight) -> f32 {
    let lit_lo = vec4<f32>(countOneBits(~hidden.lo)) / 32.0;
    let lit_hi = vec4<f32>(countOneBits(~hidden.hi)) / 32.0;
    if (!(light.whole > 0.0)) {
        // A light so small seen from p that tan²α flushes to 0: the rings weigh alike.
        return 0.125 * (dot(lit_lo, vec4<f32>(1.0)) + dot(lit_hi, vec4<f32>(1.0)));
    }
    return clamp((dot(light.ring_lo, lit_lo) + dot(light.ring_hi, lit_hi)) / light.whole, 0.0, 1.0);
}

// One turn of `soft_exact`'s directions: the directions the triangles hide, and the least
// distance along the axis of a triangle that hides one. Over every group (listing those not
// culled in `exact_listed`, up to `EXACT_LISTED`), or over the listed ones when `listed`.
fn exact_pass(light: ExactLight, listed: bool) -> Hidden {
    let p = light.p;
    let axis = light.axis;
    let frame = soft_frame(axis);
    // The directions turned (any turn keeps them a sample of the disc with the same weights).
    let spin = PI * (2.0 * fract(exact_seed + EXACT_TURN * f32(exact_calls)) - 1.0);
    exact_calls += 1u;
    // In [−π, π), where WGSL bounds sin and cos (2^-11 absolute: a turn that far from a
    // rotation moves a direction by a thirtieth of the table's offset step).
    let turn = vec2<f32>(vs_cos(spin), vs_sin(spin));
    let e1 = frame[0] * turn.x + frame[1] * turn.y;
    let e2 = frame[1] * turn.x - frame[0] * turn.y;
    let sin_a = light.sin_a;
    let cos_a = light.cos_a;
    let tan_a = light.tan_a;
    let cut = light.cut;
    var hidden = Mask(vec4<u32>(0u), vec4<u32>(0u));
    var nearest_z = 3.4e38;
    let count = select(shadow.soft.groups, exact_listed_count, listed);
    if (!listed) {
        exact_listed_count = 0u;
    }
    for (var i = 0u; i < count; i++) {
        var g = i;
        if (listed) {
            g = exact_listed[i];
        } else {
            let bound = soft_triangles[16u * g + 12u];
            let w = bound.xyz - p;
            let along = dot(w, axis);
            let across = length(w - along * axis);
            // Behind p, beyond the cut, or outside the cone of lines to the light.
            if (along + bound.w <= 0.0 || along - bound.w >= cut || across * cos_a - along * sin_a > bound.w) {
                continue;
            }
            if (exact_listed_count < EXACT_LISTED) {
                exact_listed[exact_listed_count] = g;
            }
            exact_listed_count += 1u;
        }
        // The group's 12 corners in the frame, one triangle at a time.
        var h = exact_triangle(exact_corner(g, 0u, p, e1, e2, axis), exact_corner(g, 1u, p, e1, e2, axis), exact_corner(g, 2u, p, e1, e2, axis), cut, tan_a);
        hidden = Mask(hidden.lo | h.mask.lo, hidden.hi | h.mask.hi);
        nearest_z = min(nearest_z, h.z);
        h = exact_triangle(exact_corner(g, 3u, p, e1, e2, axis), exact_corner(g, 4u, p, e1, e2, axis), exact_corner(g, 5u, p, e1, e2, axis), cut, tan_a);
        hidden = Mask(hidden.lo | h.mask.lo, hidden.hi | h.mask.hi);
        nearest_z = min(nearest_z, h.z);
        h = exact_triangle(exact_corner(g, 6u, p, e1, e2, axis), exact_corner(g, 7u, p, e1, e2, axis), exact_corner(g, 8u, p, e1, e2, axis), cut, tan_a);
        hidden = Mask(hidden.lo | h.mask.lo, hidden.hi | h.mask.hi);
        nearest_z = min(nearest_z, h.z);
        h = exact_triangle(exact_corner(g, 9u, p, e1, e2, axis), exact_corner(g, 10u, p, e1, e2, axis), exact_corner(g, 11u, p, e1, e2, axis), cut, tan_a);
        hidden = Mask(hidden.lo | h.mask.lo, hidden.hi | h.mask.hi);
        nearest_z = min(nearest_z, h.z);
    }
    return Hidden(hidden, nearest_z);
}

// Corner k of group g relative to p, in the frame (e1, e2, axis) of `soft_exact`.
fn exact_corner(g: u32, k: u32, p: vec3<f32>, e1: vec3<f32>, e2: vec3<f32>, axis: vec3<f32>) -> vec3<f32> {
    let w = soft_triangles[16u * g + k].xyz - p;
    return vec3<f32>(dot(w, e1), dot(w, e2), dot(w, axis));
}
