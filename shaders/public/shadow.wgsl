// volshadow: shadow-map visibility of a surface point, from the shadow maps volshadow renders
// for its volumetric shadows (`nodes::ShadowMapNode`, `VolumetricShadows::shadow_map`).
//
// Self-contained: paste or concatenate it into a surface shader. Layout of the shadow map:
// a depth 2D array texture, 6 layers for a point light (cube faces +X, −X, +Y, −Y, +Z, −Z,
// 90° each) or 1 for a spot light, each face a reversed-Z infinite perspective from the light
// (depth = near / distance along the face's axis: nearer occluders have larger depths; 0 =
// nothing); a directional light: one orthographic layer per cascade (nearest the eye first),
// depth falling linearly along the direction of travel (again larger = nearer the light). `VolshadowShadow` holds the faces' clip_from_world matrices and the light (upload
// `nodes::ShadowMap::params()` as a storage or uniform buffer). Bind the texture as
// `texture_depth_2d_array` and a comparison sampler with `GreaterEqual` and linear filtering
// (2×2 percentage-closer filtering).
//
// Bias: the point is moved along its normal by `normal_offset` × its distance from the light
// (a relative offset, so it holds at any scene scale; 2 texels' angular size by default), then
// counts as lit while its depth ≥ stored × (1 − depth_bias), the bias the volumetric shadows
// use. Points outside every face (behind a spot) count as lit: a spot's cone is the caller's.
// A directional light: the point takes the first cascade whose square holds it (within a
// texel of the edge) and whose far plane it is not beyond, else the last whose square holds
// it (at its far plane), else it is lit; it moves `normal_offset` world units in the first
// cascade and as many texels in the others (2 texels by default), and counts as lit while it
// lies less than 2 of its cascade's texels beyond the stored depth (the volumetric shadows'
// bias).
//
// Soft shadows: `volshadow_shadow` is soft by itself for a point or spot light whose `radius`
// (`VolshadowShadow.radius`, from `params()`) is above 0; radius 0, and a directional light
// (which has no radius), take the hard lookup above unchanged. Soft: the fraction of the
// light's disc the point sees, by percentage-closer soft shadows (Fernando 2005) in the front
// layer, the geometry of the volumetric shadows' own: a blocker search (two rounds of 8 taps,
// the first centred, over the region where the lines from the point to the disc can meet an
// occluder no nearer than the map's near plane, then over the filter's own region; the
// farthest blocker found sets the filter), then the mean of 32 2×2-filtered lookups over the
// disc of tilt R·(1/b − 1/d), taps on a golden-angle spiral turned by an integer hash of the
// point: at most 16 `textureLoad`s and 32 comparison samples, no other loop. The taps lie on
// the surface's tangent plane (a convex surface does not shadow its own filter). Times the
// part of the light above that plane (the surface's own horizon: a convex occluder hides
// exactly what lies below its tangent plane from a point on it), `n` taken as the outward
// normal of the side being lit: a point whose plane has all of the light below it reads 0
// (the hard lookup turns `n` towards the light instead). A point inside the light's sphere
// reads 1. The map's second layer of back faces (`ShadowMap::back`, a separate texture)
// is not read: the front surface alone makes the deep penumbra too bright (see
// docs/METHOD.md).

struct VolshadowShadow {
    faces: array<mat4x4<f32>, 6>,  // clip_from_world of each layer (unused ones zero)
    light_position: vec3<f32>,     // a directional light: its direction of travel
    depth_bias: f32,               // relative depth bias
    layers: u32,                   // 6: point light (cube), 1: spot, directional: cascades
    normal_offset: f32,            // relative offset along the normal (directional: world
                                   // units in the first cascade)
    directional: u32,              // 1: orthographic map of a directional light
    radius: f32,                   // the light's radius (0: a point; soft shadows above 0)
}

// A directional light's cascade for `p` (see the header), `layers` when none holds it.
fn volshadow_cascade(sm: VolshadowShadow, size: f32, p: vec3<f32>) -> u32 {
    let edge = 1.0 - 2.0 / size;
    var found = sm.layers;
    for (var k = 0u; k < min(sm.layers, 6u); k++) {
        let c = sm.faces[k] * vec4<f32>(p, 1.0);
        if (all(abs(c.xy) <= vec2<f32>(edge))) {
            found = k;
            if (c.z >= 0.0) {
                break;
            }
        }
    }
    return found;
}

// The cube face (+X, −X, +Y, −Y, +Z, −Z: 0 to 5) that holds the direction `rel` from the light.
fn volshadow_cube_face(rel: vec3<f32>) -> u32 {
    let m = abs(rel);
    if (m.x >= m.y && m.x >= m.z) {
        return select(1u, 0u, rel.x > 0.0);
    } else if (m.y >= m.z) {
        return select(3u, 2u, rel.y > 0.0);
    }
    return select(5u, 4u, rel.z > 0.0);
}

// Half the width of an orthographic layer's square.
fn volshadow_half_width(m: mat4x4<f32>) -> f32 {
    return 1.0 / length(vec3<f32>(m[0].x, m[1].x, m[2].x));
}

// Visibility in [0, 1] of the surface point `p` with normal `n` (any length; zero: no offset):
// hard (`volshadow_hard`) for a light without a radius and for a directional light, soft
// (`volshadow_soft`) for a point or spot light with a radius.
fn volshadow_shadow(map: texture_depth_2d_array, cmp: sampler_comparison, sm: VolshadowShadow,
                    p: vec3<f32>, n: vec3<f32>) -> f32 {
    if (sm.radius > 0.0 && sm.directional == 0u) {
        return volshadow_soft(map, cmp, sm, p, n);
    }
    return volshadow_hard(map, cmp, sm, p, n);
}

// The hard visibility: one 2×2-filtered lookup (see the header).
fn volshadow_hard(map: texture_depth_2d_array, cmp: sampler_comparison, sm: VolshadowShadow,
                  p: vec3<f32>, n: vec3<f32>) -> f32 {
    let directional = sm.directional != 0u;
    var to_light = sm.light_position - p;
    var scale = sm.normal_offset * length(to_light);
    let size = f32(textureDimensions(map).x);
    if (directional) {
        to_light = -sm.light_position;
        // As many texels in the point's cascade as `normal_offset` is in the first.
        let k = volshadow_cascade(sm, size, p);
        if (k >= sm.layers) {
            return 1.0;
        }
        scale = sm.normal_offset * volshadow_half_width(sm.faces[k])
            / volshadow_half_width(sm.faces[0]);
    }
    var offset = vec3<f32>(0.0);
    let nl = length(n);
    if (nl > 0.0) {
        // Towards the light's side of the surface, so a two-sided normal works either way.
        let n1 = n / nl;
        offset = select(-n1, n1, dot(n1, to_light) >= 0.0) * scale;
    }
    let q = p + offset;
    let rel = q - sm.light_position;
    var face = 0u;
    if (directional) {
        face = volshadow_cascade(sm, size, q);
        if (face >= sm.layers) {
            return 1.0;
        }
    } else if (sm.layers == 6u) {
        face = volshadow_cube_face(rel);
    }
    let clip = sm.faces[face] * vec4<f32>(q, 1.0);
    if (clip.w <= 0.0) {
        return 1.0;
    }
    let ndc = clip.xyz / clip.w;
    if (any(abs(ndc.xy) > vec2<f32>(1.0))) {
        return 1.0;
    }
    let uv = vec2<f32>(0.5 + 0.5 * ndc.x, 0.5 - 0.5 * ndc.y);
    var reference = ndc.z / (1.0 - sm.depth_bias);
    if (directional) {
        // Beyond the far plane: at it. The bias: 2 texels in world units, as depth (row 2's
        // length is depth per world unit).
        let m = sm.faces[face];
        let per_unit = length(vec3<f32>(m[0].z, m[1].z, m[2].z));
        reference = max(ndc.z, 0.0) + 4.0 * volshadow_half_width(m) / size * per_unit;
    }
    return textureSampleCompareLevel(map, cmp, uv, i32(face), reference);
}

// Soft shadows of a point or spot light with a radius R (percentage-closer soft shadows,
// Fernando 2005, as the volumetric shadows' `pcss.wgsl`, in the front layer alone): a line
// from the point (at distance d from the light) to the light's point at lateral offset R·w
// meets the sphere of distance b around the light in the direction tilted by R·(1/b − 1/d)·w.
// Taps on a golden-angle spiral (Vogel 1979) turned by an integer hash of the point.
const VOLSHADOW_SEARCH_TAPS: u32 = 8u; // per round of the blocker search (two rounds)
const VOLSHADOW_FILTER_TAPS: u32 = 32u;
// The widest search, as a tangent seen from the light (45°): the taps stay near the point's
// own direction whatever the near plane.
const VOLSHADOW_SEARCH_MAX: f32 = 1.0;
// The least sine of the light's centre's elevation above the taps' plane (see
// `volshadow_soft`).
const VOLSHADOW_LEAST_ELEVATION: f32 = 0.01;
const VOLSHADOW_PI: f32 = 3.141592653589793;
// cos and sin of the golden angle π(3 − √5).
const VOLSHADOW_GOLDEN_COS: f32 = -0.7373688780783197;
const VOLSHADOW_GOLDEN_SIN: f32 = 0.6754902942615238;

// What the soft lookup's taps share: the light, the point q (moved off its surface), its
// distance and unit direction from the light, a frame (e1, e2) around it, the receiver's
// plane (unit normal towards the light, zero: none) and the spiral's first direction.
struct VolshadowSoft {
    light: vec3<f32>,
    q: vec3<f32>,
    dist: f32,
    u: vec3<f32>,
    e1: vec3<f32>,
    e2: vec3<f32>,
    n: vec3<f32>,
    start: vec2<f32>,
}

// A tap seen in the map: its layer, texel coordinates (uv), its own depth (ndc z) and its
// distance from the light; `inside` false outside the map (behind a spot light).
struct VolshadowTap {
    face: u32,
    uv: vec2<f32>,
    depth: f32,
    dist: f32,
    inside: bool,
}

// The tap in the direction u tilted by `t` (a tangent) towards `cs` (a unit vector in the
// frame): the point where that direction from the light meets the receiver's plane, or at the
// point's distance where that is nearer or it does not meet it. On the receiver's plane, a
// convex receiver (its surface lies beyond its tangent plane, seen from the light) does not
// shadow its own taps; at the point's distance alone, it would (acne of the filter).
fn volshadow_tap(sm: VolshadowShadow, s: VolshadowSoft, t: f32, cs: vec2<f32>) -> VolshadowTap {
    let dir = normalize(s.u + t * (cs.x * s.e1 + cs.y * s.e2));
    var k = s.dist;
    let num = dot(s.n, s.q - s.light);
    let den = dot(s.n, dir);
    if (num < 0.0 && den < 0.0) {
        k = min(num / den, s.dist);
    }
    let rel = k * dir;
    var face = 0u;
    if (sm.layers == 6u) {
        face = volshadow_cube_face(rel);
    }
    let clip = sm.faces[face] * vec4<f32>(s.light + rel, 1.0);
    if (!(clip.w > 0.0)) {
        return VolshadowTap(face, vec2<f32>(0.0), 0.0, k, false);
    }
    let ndc = clip.xyz / clip.w;
    if (any(abs(ndc.xy) > vec2<f32>(1.0))) {
        return VolshadowTap(face, vec2<f32>(0.0), 0.0, k, false);
    }
    return VolshadowTap(face, vec2<f32>(0.5 + 0.5 * ndc.x, 0.5 - 0.5 * ndc.y), ndc.z, k, true);
}

// The distance from the light of the occluder the map holds in front of the tap, as a fraction
// of the point's distance (2 where there is none).
fn volshadow_blocker(map: texture_depth_2d_array, sm: VolshadowShadow, s: VolshadowSoft,
                     tap: VolshadowTap) -> f32 {
    if (!tap.inside) {
        return 2.0;
    }
    let size = vec2<f32>(textureDimensions(map));
    let texel = vec2<i32>(clamp(tap.uv * size, vec2<f32>(0.0), size - 1.0));
    let stored = textureLoad(map, texel, i32(tap.face), 0);
    // Reversed Z: depth = near / distance along the face's axis, so along one direction the
    // ratio of distances is the inverse ratio of depths.
    if (stored > 0.0 && stored * (1.0 - sm.depth_bias) > tap.depth) {
        return tap.dist / s.dist * (tap.depth / stored);
    }
    return 2.0;
}

// The tap's hard visibility (2×2 filtered, the map's relative bias).
fn volshadow_lit(map: texture_depth_2d_array, cmp: sampler_comparison, sm: VolshadowShadow,
                 tap: VolshadowTap) -> f32 {
    if (!tap.inside) {
        return 1.0;
    }
    return textureSampleCompareLevel(map, cmp, tap.uv, i32(tap.face), tap.depth / (1.0 - sm.depth_bias));
}

// Tap k of n on the spiral: its radius on the unit disc (equal areas).
fn volshadow_spiral_radius(k: u32, n: u32) -> f32 {
    return sqrt((f32(k) + 0.5) / f32(n));
}

// The next tap's direction on the spiral: `cs` turned by the golden angle.
fn volshadow_spiral_next(cs: vec2<f32>) -> vec2<f32> {
    return vec2<f32>(VOLSHADOW_GOLDEN_COS * cs.x - VOLSHADOW_GOLDEN_SIN * cs.y,
                     VOLSHADOW_GOLDEN_SIN * cs.x + VOLSHADOW_GOLDEN_COS * cs.y);
}

// The spiral's turn at p, in [−π, π): an integer hash of the coordinates' bits, the same on
// every GPU (`sin` of a large argument has no precision WGSL promises).
fn volshadow_turn(p: vec3<f32>) -> f32 {
    let b = bitcast<vec3<u32>>(p);
    var h = (b.x * 0x8da6b343u) ^ (b.y * 0xd8163841u) ^ (b.z * 0xcb1ab31fu) ^ 0x89abcdefu;
    h ^= h >> 16u;
    h *= 0x7feb352du;
    h ^= h >> 15u;
    h *= 0x846ca68bu;
    h ^= h >> 16u;
    return (f32(h >> 8u) * (1.0 / 8388608.0) - 1.0) * VOLSHADOW_PI;
}

// The fraction of the light's disc (angular radius α, sin_a = sin α) above the receiver's
// plane, whose normal makes the angle asin(s) with the direction to the light: the disc seen
// through the plane's horizon, as the segment of a disc cut by a chord (in the gnomonic
// projection around the light's direction, where the horizon is a line, at tan(asin s) from
// the centre for a disc of radius tan α).
fn volshadow_horizon(s: f32, sin_a: f32) -> f32 {
    let cos_a = sqrt(max(1.0 - sin_a * sin_a, 0.0));
    let num = s * cos_a;
    let den = sin_a * sqrt(max(1.0 - s * s, 0.0));
    if (num >= den) {
        return 1.0;
    }
    if (num <= -den) {
        return 0.0;
    }
    let t = clamp(num / den, -1.0, 1.0);
    let w = sqrt(max(1.0 - t * t, 0.0));
    return clamp(1.0 - (atan2(w, t) - t * w) / VOLSHADOW_PI, 0.0, 1.0);
}

// Soft visibility of the surface point `p` with normal `n` (see `volshadow_shadow`).
fn volshadow_soft(map: texture_depth_2d_array, cmp: sampler_comparison, sm: VolshadowShadow,
                  p: vec3<f32>, n: vec3<f32>) -> f32 {
    let radius = sm.radius;
    let light = sm.light_position;
    let dist0 = length(p - light);
    if (!(dist0 > radius)) {
        return 1.0; // inside the light's sphere: all of it is visible
    }
    let sin_a = radius / dist0;
    let to_light = (light - p) / dist0;
    // The receiver's own horizon: the part of the light below its tangent plane is hidden by
    // the surface itself (exactly so for a convex surface). The normal is taken as given: the
    // side of the surface being lit (not turned towards the light, as the hard lookup does).
    var n1 = vec3<f32>(0.0);
    // The plane the taps lie on (see `volshadow_tap`; zero: none).
    var plane = vec3<f32>(0.0);
    var horizon = 1.0;
    var lift = 0.0;
    let nl = length(n);
    if (nl > 0.0) {
        n1 = n / nl;
        plane = n1;
        let s = dot(n1, to_light);
        horizon = volshadow_horizon(s, sin_a);
        if (horizon <= 0.0) {
            return 0.0; // all of the light below the surface's plane
        }
        if (s < VOLSHADOW_LEAST_ELEVATION) {
            // The light's centre (nearly) on or below the plane: part of the light is hidden
            // by the surface itself, which the horizon above counts; the map must not count it
            // again. The line from the point to the centre enters a closed surface there:
            // lifted by d·(1/cos e − 1) for the elevation e = asin(s) < 0, it clears a sphere
            // of radius up to d curving away. And the taps lie on the plane turned about its
            // horizon to just below the centre, in front of the surface.
            let c = sqrt(max(1.0 - s * s, 0.25));
            lift = dist0 * (min(s, 0.0) * s) / (c * (1.0 + c));
            let perp = n1 - s * to_light;
            let pl = length(perp);
            plane = select(vec3<f32>(0.0), perp / max(pl, 1.0e-30) * sqrt(1.0 - VOLSHADOW_LEAST_ELEVATION * VOLSHADOW_LEAST_ELEVATION) + VOLSHADOW_LEAST_ELEVATION * to_light, pl > 1.0e-6);
        }
    }
    let q = p + n1 * (sm.normal_offset * dist0 + lift);
    let rel = q - light;
    let dist = length(rel);
    if (!(dist > radius)) {
        return horizon;
    }
    let u = rel / dist;
    // An orthonormal frame around u (Duff et al. 2017).
    let sgn = select(-1.0, 1.0, u.z >= 0.0);
    let fa = -1.0 / (sgn + u.z);
    let fb = u.x * u.y * fa;
    let e1 = vec3<f32>(1.0 + sgn * u.x * u.x * fa, sgn * fb, -sgn * u.x);
    let e2 = vec3<f32>(fb, sgn + u.y * u.y * fa, -u.y);
    let turn = volshadow_turn(p);
    let s = VolshadowSoft(light, q, dist, u, e1, e2, plane, vec2<f32>(cos(turn), sin(turn)));

    // The blocker search. Its region: the lines from q to the light's disc over occluders as
    // near as the map's near plane (clip z of a reversed-Z infinite perspective), at most
    // VOLSHADOW_SEARCH_MAX.
    let centre = volshadow_tap(sm, s, 0.0, s.start);
    let near = (sm.faces[centre.face] * vec4<f32>(q, 1.0)).z;
    let nearest = clamp(near, 1.0e-3 * radius, dist);
    let search = min(radius * (1.0 / nearest - 1.0 / dist), VOLSHADOW_SEARCH_MAX);
    // The farthest blocker found (as a fraction of dist): the one whose outline the lines
    // from q to the disc graze.
    var far = volshadow_blocker(map, sm, s, centre);
    var count = select(0u, 1u, far < 1.0);
    far = select(0.0, far, far < 1.0);
    var cs = s.start;
    for (var k = 1u; k < VOLSHADOW_SEARCH_TAPS; k++) {
        let b = volshadow_blocker(map, sm, s, volshadow_tap(sm, s, search * volshadow_spiral_radius(k, VOLSHADOW_SEARCH_TAPS), cs));
        cs = volshadow_spiral_next(cs);
        if (b < 1.0) {
            far = max(far, b);
            count++;
        }
    }
    if (count == 0u) {
        return horizon; // no blocker near the point's direction
    }
    var width = min(radius * (1.0 / max(dist * far, nearest) - 1.0 / dist), search);
    // Once more over the filter's own region.
    var blocked = 0u;
    cs = s.start;
    for (var k = 0u; k < VOLSHADOW_SEARCH_TAPS; k++) {
        let b = volshadow_blocker(map, sm, s, volshadow_tap(sm, s, width * volshadow_spiral_radius(k, VOLSHADOW_SEARCH_TAPS), cs));
        cs = volshadow_spiral_next(cs);
        if (b < 1.0) {
            far = max(far, b);
            blocked++;
        }
    }
    if (blocked == VOLSHADOW_SEARCH_TAPS && count == VOLSHADOW_SEARCH_TAPS) {
        return 0.0; // the umbra: every tap of both rounds blocked
    }
    width = min(radius * (1.0 / max(dist * far, nearest) - 1.0 / dist), search);
    // The filter: the mean hard visibility over the disc of that tilt.
    var lit = 0.0;
    cs = s.start;
    for (var k = 0u; k < VOLSHADOW_FILTER_TAPS; k++) {
        lit += volshadow_lit(map, cmp, sm, volshadow_tap(sm, s, width * volshadow_spiral_radius(k, VOLSHADOW_FILTER_TAPS), cs));
        cs = volshadow_spiral_next(cs);
    }
    return horizon * lit / f32(VOLSHADOW_FILTER_TAPS);
}
