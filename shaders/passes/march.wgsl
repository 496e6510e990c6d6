#import prelude.wgsl
#import pcss.wgsl
#import light.wgsl
// March node: in-scattered radiance per pixel (Wyman and Ramsey 2008, §3.1; Biri et al. 2006).
//
// Everything is done in the normalised scattering angle s of the F′ table: the airlight over
// [s0, s1] is prefactor · (T(s1) − T(s0)). Uniform steps in s are uniform steps in the angle
// seen from the light (Wyman and Ramsey 2008, Fig. 4): dense near the light where the integrand is large,
// and the sky is just s = 1.
//   analytic:    the whole lit support at once (no occluders);
//   hybrid:      analytic outside the shadow-volume extents, `steps` steps inside them;
//   brute force: `steps` steps over the whole support;
//   exact:       the sorted shadow-volume crossings of the ray split it into intervals of
//                constant visibility, each integrated analytically (Biri et al. 2006);
//   textbook:    a Riemann sum of the integrand in distance (a baseline only).
// Lit support: [0, ds] for a point light; its intersection with the cone for a spot light.
// A piece of the support that crosses no shadow-volume face has one visibility, sampled once
// in its middle: never assumed lit (the eye may stand in a shadow it never leaves).

// Pipeline constants, one pipeline per combination (the march node picks it): code a variant
// does not need is not compiled into it. That matters most on CPU rasterisers such as
// lavapipe, which execute both sides of every branch under a mask.
// The march's method, `MODE` (the Rust `Mode` enum's values; a unit test compares them).
const MODE_ANALYTIC: u32 = 0u;
const MODE_HYBRID: u32 = 1u;
const MODE_BRUTE_FORCE: u32 = 2u;
const MODE_EXACT: u32 = 3u;
const MODE_TEXTBOOK: u32 = 4u;
override MODE: u32 = MODE_ANALYTIC;  // one of the above (and the prelude's LIGHT)
override TEXTURED: bool = false;   // textured spot
override BISECTIONS: u32 = 0u;     // bisection steps per lit/shadow transition
override SOFT: bool = false;       // the light has a radius: fractional visibility (soft shadows)
override SOFT_GRID: bool = false;  // SOFT: visibility read from the soft-shadow grid (`soft_volume`)
override SOFT_SHAFTS: bool = false; // SOFT_GRID: the grid's cells are marked near narrow shafts (w)
// Work counters for benches and tests (`MarchNode::set_work_counters`): each pixel's shadow-map
// lookups, light-texture samples, crossing-list entries read and entries stored, written to
// `stats[4 + 4p ..]`. Off in every pipeline a frame uses, which compiles them out.
override COUNT_WORK: bool = false;

// The pixel's work so far (COUNT_WORK): shadow-map visibility queries, light-texture samples,
// crossing-list entries read.
var<private> work: vec3<u32>;

fn count_lookup() {
    if (COUNT_WORK) {
        work.x += 1u;
    }
}

// Most transitions a marched interval records before it evaluates T at them (more just take
// another round of the step loop).
const MAX_EDGES: u32 = 8u;
// The textbook march stops where the transmittance from the eye is below 1e-4 (−ln 1e-4).
const TEXTBOOK_DEPTH: f32 = 9.2103404;

// Mirrors `MarchUniform` in src/nodes/march.rs. The light, its shadow map and the occluders'
// bounds are pcss.wgsl's (group 1, `shadow`), bound in every mode (a point or spot light's
// cone and position are read from there without shadows too).
struct MarchParams {
    tex_frame: mat4x4<f32>,  // textured spot: the spot's texture frame (view matrix)
    steps: u32,              // steps per marched interval
    list_entries: u32,       // exact: crossing list entries per pixel
    texture_steps: u32,      // textured spot: steps before and after the extents
    lit_fraction: u32,       // 1: write the lit fraction (reduced resolution)
    extents_near: f32,       // the extents' projection near plane
    tan_half_angle: f32,     // textured spot: tan(half apex angle)
    tex_width: f32,          // textured spot: texture width (texels)
    tex_mips: f32,           // textured spot: mip levels
    soft_grid: SoftGrid,     // the soft-shadow grid (shaders/passes/soft_shadow.wgsl)
}

// The soft-shadow grid the march reads (`SoftGridUniform` in src/nodes/march.rs).
struct SoftGrid {
    directions: u32,   // cells across a layer
    slices: u32,       // cells along the distance from the light
    layers: u32,       // the shadow map's layers
    cell_angle: f32,   // the angle (radians) a cell subtends at the light (0: no grid bound)
}

@group(0) @binding(0) var<storage, read> air: Airlight;
@group(0) @binding(1) var<storage, read> view: View;
@group(0) @binding(2) var table: texture_2d<f32>;
@group(0) @binding(3) var scene_depth: texture_depth_2d;
@group(0) @binding(4) var inscatter_out: texture_storage_2d<rgba32float, write>;
@group(0) @binding(5) var<storage, read> mp: MarchParams;
@group(0) @binding(6) var extent_front: texture_depth_2d;
@group(0) @binding(7) var extent_back_near: texture_depth_2d;
@group(0) @binding(8) var extent_back_far: texture_depth_2d;
@group(0) @binding(9) var steps_out: texture_storage_2d<r32uint, write>;
@group(0) @binding(10) var light_tex: texture_2d<f32>;
@group(0) @binding(11) var light_sampler: sampler;
// Exact mode: the extents node's crossing lists (per pixel: count | open-mesh bit 31,
// ~nearest bits, farthest bits, net volumes entered behind the surface; then K signed view
// depths per pixel, negative where the ray enters a volume).
@group(0) @binding(12) var<storage, read> heads: array<u32>;
@group(0) @binding(13) var<storage, read> crossings: array<f32>;
// Overflowed pixels, pixels with more crossings than half the list holds, most crossings
// among those, unused.
// Four counters of the whole pass (`MarchStats`), then with COUNT_WORK four per pixel.
@group(0) @binding(14) var<storage, read_write> stats: array<atomic<u32>>;
// A light with a radius: the visible fraction of its disc on a light-space grid (read through
// `light_sampler`, trilinear, clamped to the edges).
@group(0) @binding(15) var soft_volume: texture_3d<f32>;
// A textured spot: the flat regions of its texture's level 0
// (`shaders/passes/light_texture_flats.wgsl`: per cell between four texel centres and per quadrant,
// the side of the largest square of flat cells from the cell into that quadrant; 0 where the cell
// is not flat).
@group(0) @binding(16) var light_flats: texture_2d<u32>;

// Distance along the ray of the point with normalised scattering angle s (light.wgsl).
fn x_of_s(r: AirRay, s: f32) -> f32 {
    return light_x_of_s(air, r, s);
}

fn vis_at(ray: PixelRay, r: AirRay, s: f32) -> f32 {
    if (SOFT) {
        let p = air.eye + x_of_s(r, s) * ray.dir;
        if (SOFT_GRID) {
            return soft_grid_visibility(p, false);
        }
        count_lookup();
        return visibility_soft(p);
    }
    count_lookup();
    return visibility(air.eye + x_of_s(r, s) * ray.dir);
}

// The soft-shadow grid at `p` (see shaders/passes/soft_shadow.wgsl): x the visible fraction of the
// light's disc, y > 0 where a cell around p is marked for a narrow penumbra, z > 0 for an
// occluder's surface between two slices, w > 0 near a shaft narrower than a few cells. One
// trilinear lookup between the cells around p (its layer's directions, and the slices in q =
// nearest / distance), in place of `visibility_soft`'s 49 shadow-map taps (145 in the deep
// penumbra).
fn soft_grid(p: vec3<f32>) -> vec4<f32> {
    return soft_grid_at(p, false);
}

// `soft_grid`; with `near_side` the slice at or before p (nearer the light) instead of an
// interpolation between slices: in front of a surface, the value on p's side of it.
fn soft_grid_at(p: vec3<f32>, near_side: bool) -> vec4<f32> {
    let dist = length(p - air.light_pos);
    let nearest = soft_nearest();
    if (dist <= max(nearest, shadow.light.radius)) {
        // As visibility_soft: nearer than every occluder (the grid holds 1 outside the cones).
        return vec4<f32>(1.0, 0.0, 0.0, 0.0);
    }
    return soft_grid_of(map_point(p), dist, near_side);
}

// `soft_grid_at` of a point at `dist` from the light beyond the nearest occluder, where it
// falls in the shadow map (the grid's layers and directions are the map's).
fn soft_grid_of(m: MapPoint, dist: f32, near_side: bool) -> vec4<f32> {
    if (!m.inside) {
        return vec4<f32>(1.0, 0.0, 0.0, 0.0);
    }
    let nearest = soft_nearest();
    let slices = f32(mp.soft_grid.slices);
    // Cell k's centre lies at (1 − q)·slices = k + 0.5; clamped inside the layer's own slices
    // so that the lookup never blends two layers.
    var k = clamp((1.0 - nearest / dist) * slices, 0.5, slices - 0.5);
    if (near_side) {
        k = floor(k - 0.5) + 0.5;
    }
    let z = (f32(m.face) * slices + k) / (f32(mp.soft_grid.layers) * slices);
    return textureSampleLevel(soft_volume, light_sampler, vec3<f32>(m.uv, z), 0.0);
}

// Whether a point, where it falls in the map, lies in front of the occluder surface the map
// holds in its direction (or outside the map): as `visibility`'s test, at its own texel.
fn in_front_of_surface(m: MapPoint) -> bool {
    count_lookup();
    let t = map_texel_of(m);
    return !t.inside || !(textureLoad(shadow_map, t.texel, i32(t.face), 0) * (1.0 - shadow.depth_bias) > t.depth);
}

// The visible fraction at `p` from the soft-shadow grid where its cells are not marked, and
// where they are (see `march_soft_grid`), the shadow map's own visibility blended in by the
// interpolated marks: at an occluder's surface between two slices, for a point in front of it
// the grid's slice on its side, behind it the hard visibility; with `sharp`, for a narrow
// penumbra the hard visibility, whose edges are the occluders'. A textured spot's march reads
// it at each of its uniform steps without `sharp`, which makes the textured spot's error worse
// (tests/gpu/textured_spot.rs), as does the grid's value alone (in cells marked for a surface).
fn soft_grid_visibility(p: vec3<f32>, sharp: bool) -> f32 {
    // One projection into the map for all of the point's lookups (the grid's layers and
    // directions are the map's), not one per lookup.
    let dist = length(p - air.light_pos);
    if (dist <= max(soft_nearest(), shadow.light.radius)) {
        return 1.0; // as soft_grid_at: nearer than every occluder
    }
    let m = map_point(p);
    let g = soft_grid_of(m, dist, false);
    let blend = select(0.0, g.y, sharp);
    if (!(blend > 0.0 || g.z > 0.0)) {
        return g.x;
    }
    count_lookup();
    let hard = visibility_of(m);
    var base = g.x;
    if (g.z > 0.0) {
        var side = hard;
        if (in_front_of_surface(m)) {
            side = soft_grid_of(m, dist, true).x;
        }
        base = mix(g.x, side, g.z);
    }
    return mix(base, hard, blend);
}

// The steps of an interval among which `march_soft_grid` finds those to refine: the first
// 64, one bit each (later ones keep their one sample). Every marked step among them is
// refined: a step in `pieces` pieces, so at most `steps` + n pieces in all. Refining at most
// 16 would leave a thin plate's marked steps beyond the 16th at the grid's value (the gap
// scenes of tests/gpu/soft_grid.rs, seed 400: RMSE 6.5% with 16, 0.6% with all).
const SHARP_STEP_BITS: u32 = 64u;

// ∫ V dT over [s0, s1] (T known at both ends) in n uniform steps through the soft-shadow grid,
// each sampled at its midpoint and weighted by dT/ds there, the weights normalised to the
// exact T(s1) − T(s0) (one integrand a step in place of an exact T at every step boundary:
// the march took half the time on the soft scene of the report, p95 unchanged). Where the
// cells around a step are marked sharp (a penumbra narrower than two cells, near an
// occluder's outline, or an occluder's surface between two slices) the grid's interpolation
// would smear it: there the shadow map's own 2×2-filtered visibility, whose edges are the
// occluders', is blended in by the interpolated mark. On the
// torus of tests/gpu/soft.rs the grid alone is off by RMSE 3.8% (p95 6.5%) in the rows through the
// torus, with the blend 1.1% (p95 1.9%). At an occluder's surface between two slices a point
// in front of it takes instead the grid's slice on its own side, not interpolated across the
// surface: a ground far below an occluder receives a wide penumbra, which the hard visibility
// would sharpen (the report's soft scene with its ground casting shadows, 128², p95 6.9% with
// the hard visibility, 5.2% with the slice); behind it, the hard visibility. Such a step's
// edge is as sharp as a hard shadow's, so it is marched again at the resolution of `steps`
// (a small light's penumbrae are sharp
// almost everywhere: seed 2 of tests/gpu/soft_grid.rs, p95 3.9% at the grid's half step a cell,
// 1.8% refined). Near a narrow shaft (the grid's w, see `mark_shafts` in
// shaders/passes/soft_shadow.wgsl) neither the grid nor the hard visibility holds: a step there is
// refined with the per-point estimate, `visibility_soft` (the gap scenes of
// tests/gpu/soft_grid.rs, seed 400, a slit 0.66 of the light's diameter: p95 10.2% → 1.8%).
// Where the occluders' triangles are given (`soft_exact` in pcss.wgsl: the grid's cells and
// the per-point estimate are then exact but for its 256 directions), the marks near a shaft
// reach 6 cells, not 20, and also cover the cells the trilinear lookup between exact cells
// cannot be trusted around (`curved` in soft_shadow.wgsl); those steps, and the steps marked
// for a narrow penumbra or a surface whose grid value lies strictly between 0 and 1, are
// refined with the per-point estimate. The lookup still cuts a narrow shaft's corners
// (blinds of 7 slats, seed 401: p95 4.33% with the shafts' marks alone), and the shadow
// map's hard visibility at the sharp marks is worse than the exact cells (with the curvature
// marks alone, a square hole, seed 402, 4.63%; the door ajar by 0.23, 411, 62.5%, which the
// curvature relative to the cells' fraction brings to 1.27%). Refining every step strictly
// between 0 and 1 holds the same accuracy and costs more where a light shines
// through a gap into a room, which then lies in the gap's penumbra (benches/scenes/door_ajar
// at 256² on lavapipe: 6.96 s a frame, 5.12 s so). The
// refinement runs after the step loop (no shadow-map lookup in the main loop, which every
// step would pay for on a SIMD device); marked steps beyond SHARP_STEP_BITS keep the grid's
// value. The step loop keeps the marked steps as bits, not in an array indexed by a
// variable, which some compilers (llvmpipe's) spill to memory for every lane.
fn march_soft_grid(ray: PixelRay, r: AirRay, s0: f32, s1: f32, t0: TT, t1: TT, n: u32) -> Marched {
    var out: Marched;
    out.t = vec3<f32>(0.0);
    out.steps = n;
    if (!(s1 > s0)) {
        return out;
    }
    let ds = (s1 - s0) / f32(n);
    // Bit i of (x, y): step i (x: below 32) is marked; `count` of them.
    var mask = vec2<u32>(0u);
    var count = 0u;
    // The same bits for the marked steps near a narrow shaft (the grid's w).
    var shafts = vec2<u32>(0u);
    // Σ w_i and Σ V_i w_i over the steps, w_i = dT/ds at step i's midpoint; Σ V_i (for an
    // interval whose weights underflow).
    var weights = vec3<f32>(0.0);
    var lit = vec3<f32>(0.0);
    var plain = 0.0;
    // The half angles at the steps' midpoints, δ/2 = s·w/2 at the light and u = β/2 at the
    // point (β = (1 − s)·w), as (cos, sin), each turned by ds·w/2 a step: dT/ds (as
    // `table_integrand`) and x (as `x_of_s`, x = D sin δ / sin β) without a sine or cosine.
    // cos u starts as sin((γ + δ)/2), exact where β is near π.
    let mid0 = s0 + 0.5 * ds;
    let turn = 0.5 * ds * r.w;
    let rot = cos_sin(turn, 0.5 * PI - turn);
    // δ/2 = s·w/2 with complement (γ + β)/2, β/2 with complement (γ + δ)/2.
    var half_delta = cos_sin(0.5 * mid0 * r.w, 0.5 * (r.gamma + (1.0 - mid0) * r.w));
    var half_beta = cos_sin(0.5 * (1.0 - mid0) * r.w, 0.5 * (r.gamma + mid0 * r.w));
    for (var i = 0u; i < n; i++) {
        let su = half_beta.y;
        let cu = half_beta.x;
        let ratio = min(half_delta.y / max(su, 1.0e-30), 1.0e20);
        let tau = (2.0 * air.distance * r.sin_half_gamma * ratio) * air.sigma_t;
        let w = phase(air, 2.0 * cu * cu, 2.0 * su * su) * vs_exp3(-tau);
        let x = air.distance * (half_delta.y * half_delta.x) / max(su * cu, 1.0e-30);
        half_delta = vec2<f32>(half_delta.x * rot.x - half_delta.y * rot.y, half_delta.y * rot.x + half_delta.x * rot.y);
        half_beta = vec2<f32>(half_beta.x * rot.x + half_beta.y * rot.y, half_beta.y * rot.x - half_beta.x * rot.y);
        weights += w;
        let p = air.eye + x * ray.dir;
        let g = soft_grid(p);
        // Near a narrow shaft (triangles given: or curved), or (triangles given) at a sharp or
        // surface mark anywhere but lit or umbra.
        let shaft = SOFT_SHAFTS && (g.w > 0.0 || (shadow.soft.groups > 0u && (g.y > 0.0 || g.z > 0.0) && g.x > 0.0 && g.x < 1.0));
        if ((g.y > 0.0 || g.z > 0.0 || shaft) && i < SHARP_STEP_BITS) {
            let bit = step_bit(i);
            mask |= bit;
            if (shaft) {
                shafts |= bit;
            }
            count++;
        } else {
            lit += g.x * w;
            plain += g.x;
        }
    }
    // The marked steps again, each in as many pieces as make them `steps` to the interval:
    // first those refined through the grid, then those near a narrow shaft with the
    // per-point estimate, in one loop (one `refined_step` to compile, not two).
    let pieces = max(1u, (mp.steps + n - 1u) / n);
    mask &= ~shafts;
    let near_shafts = countOneBits(shafts.x) + countOneBits(shafts.y);
    var thirds_left = REFINE_THIRDS;
    for (var m = 0u; m < count; m++) {
        let shaft = SOFT_SHAFTS && m >= count - near_shafts;
        var step = 0u;
        if (shaft) {
            step = lowest_step(&shafts);
        } else {
            step = lowest_step(&mask);
        }
        let o = refined_step(ray, r, s0, ds, step, pieces, shaft, &thirds_left);
        lit += o.lit;
        plain += o.plain;
        out.steps += o.samples;
    }
    // The midpoint weights normalised to the exact T over the interval: exact where V is
    // constant, and for uniform steps exact too where dT/ds is exponential in s (an optically
    // thick medium), whose midpoint-to-integral ratio is then the same for every step.
    let total = t_between(t0, t1);
    out.t = select(vec3<f32>(plain / f32(n)) * total, total * lit / weights, weights > vec3<f32>(0.0));
    return out;
}

// Bit `step` (below 64) of a vec2<u32> of steps or pieces (x: below 32).
fn step_bit(step: u32) -> vec2<u32> {
    return select(vec2<u32>(0u, 1u << (step & 31u)), vec2<u32>(1u << (step & 31u), 0u), step < 32u);
}

// The lowest step (or piece) of `bits` (see `march_soft_grid`), which it clears.
fn lowest_step(bits: ptr<function, vec2<u32>>) -> u32 {
    if ((*bits).x != 0u) {
        let step = firstTrailingBit((*bits).x);
        (*bits).x &= (*bits).x - 1u;
        return step;
    }
    let step = 32u + firstTrailingBit((*bits).y);
    (*bits).y &= (*bits).y - 1u;
    return step;
}

// Step `step` (of width ds from s0) of `march_soft_grid` in `pieces` pieces: V averaged over
// them (weighted by dT/ds at theirs) stands for the step's V. Returns that V times dT/ds at
// the step's midpoint, as the step loop took it (to rounding), V's plain mean, and how many
// points it sampled. V: near a narrow shaft (`shaft`) the per-point estimate (`soft_exact`
// where the triangles are given), else (and where the shadow map's estimate takes two layers
// of blockers) the grid with the hard visibility blended in (`soft_grid_visibility`).
// Two layers: a lit gap between two occluders' shadows at clearly different distances, where
// the shadow map hides part of the far occluder behind the near one and the grid's mean of
// neighbouring estimates is closer (tests/gpu/soft_grid.rs, overlapping penumbrae: p95 4.64%
// with the per-point estimate there, 2.65% with the grid).
// A piece whose V differs from a neighbour's by more than REFINE_JUMP (below) is sampled
// again at its thirds' midpoints (its own midpoint kept as the middle third's): a thin shaft
// crossed at a slant lies within a piece or two, and one midpoint a piece aliases it, the
// error changing sign from pixel to pixel (the gap scenes of tests/gpu/soft_grid.rs, a door
// ajar by 31° seen beside its shaft: p95 7.34% with one midpoint a piece, 2.33% so, near 256
// steps' 2.21%, with every step between lit and umbra refined; its frame at 48² on lavapipe
// 0.29 s → 0.35 s). One loop samples the
// midpoints and then the thirds of the pieces marked (bits, the first 64 pieces), so that the
// per-point estimate is compiled once. `thirds_left`: how many more pieces of the marched
// interval may be split (REFINE_THIRDS in all), which it counts down.
fn refined_step(
    ray: PixelRay,
    r: AirRay,
    s0: f32,
    ds: f32,
    step: u32,
    pieces: u32,
    shaft: bool,
    thirds_left: ptr<function, u32>,
) -> Refined {
    let dp = ds / f32(pieces);
    let first = s0 + ds * f32(step) + 0.5 * dp;
    var piece_lit = vec3<f32>(0.0);
    var piece_weights = vec3<f32>(0.0);
    var piece_plain = 0.0;
    // Bit j: piece j is to be sampled at its thirds.
    var thirds = vec2<u32>(0u);
    // The previous midpoint's V and dT/ds, and whether it differed from the one before.
    var v_prev = 0.0;
    var w_prev = vec3<f32>(0.0);
    var jump_prev = false;
    // Of a piece's two thirds, the second next.
    var second = false;
    var piece = 0u;
    var i = 0u;
    for (; ; i++) {
        var s = first + dp * f32(i);
        let third = i >= pieces;
        if (third) {
            if (!second) {
                if (all(thirds == vec2<u32>(0u))) {
                    break;
                }
                piece = lowest_step(&thirds);
            }
            s = first + dp * (f32(piece) + select(-1.0, 1.0, second) / 3.0);
            second = !second;
        }
        let v = piece_visibility(ray, r, s, shaft);
        let w = table_integrand(air, s, r.w, r.gamma, r.sin_half_gamma);
        if (third) {
            piece_lit += v * w / 3.0;
            piece_weights += w / 3.0;
            piece_plain += v / 3.0;
            continue;
        }
        let jump = i > 0u && abs(v - v_prev) > max(REFINE_JUMP, REFINE_JUMP_OF_V * max(v, v_prev));
        // Piece i − 1 once both its neighbours are seen, and the last piece with its one.
        if (i > 0u) {
            let marked = (jump_prev || jump) && i - 1u < 64u && *thirds_left > 0u;
            let h = select(1.0, 1.0 / 3.0, marked);
            piece_lit += v_prev * w_prev * h;
            piece_weights += w_prev * h;
            piece_plain += v_prev * h;
            if (marked) {
                thirds |= step_bit(i - 1u);
                *thirds_left -= 1u;
            }
        }
        if (i + 1u == pieces) {
            let marked = jump && i < 64u && *thirds_left > 0u;
            let h = select(1.0, 1.0 / 3.0, marked);
            piece_lit += v * w * h;
            piece_weights += w * h;
            piece_plain += v * h;
            if (marked) {
                thirds |= step_bit(i);
                *thirds_left -= 1u;
            }
        }
        jump_prev = jump;
        v_prev = v;
        w_prev = w;
    }
    let v_step = piece_plain / f32(pieces);
    let w_step = table_integrand(air, s0 + ds * (f32(step) + 0.5), r.w, r.gamma, r.sin_half_gamma);
    let v_mean = select(vec3<f32>(v_step), piece_lit / piece_weights, piece_weights > vec3<f32>(0.0));
    return Refined(v_mean * w_step, v_step, i);
}

// What `refined_step` returns: V·dT/ds for the step, V's plain mean, the points sampled.
struct Refined {
    lit: vec3<f32>,
    plain: f32,
    samples: u32,
}

// A piece of `refined_step` is split in thirds where its V and a neighbour's differ by more
// than an eighth of the light and more than a quarter of the larger. At a sixteenth the door
// ajar of `refined_step` is unchanged (p95 2.33%) and its frame takes 0.41 s, not 0.35 s.
const REFINE_JUMP: f32 = 0.125;
const REFINE_JUMP_OF_V: f32 = 0.25;

// Most pieces of a marched interval split in thirds: 64 more samples at most, each up to
// EXACT_BUDGET groups' loop iterations in `soft_exact` (pcss.wgsl), which keeps a ray's loops
// within llvmpipe's limit (see `MAX_EXACT_TRIANGLES` in src/nodes/shadow_map.rs). A thin shaft
// crossed twice marks about four.
const REFINE_THIRDS: u32 = 32u;


// V at s for `refined_step`.
fn piece_visibility(ray: PixelRay, r: AirRay, s: f32, shaft: bool) -> f32 {
    let q = air.eye + x_of_s(r, s) * ray.dir;
    var v = 0.0;
    if (shaft) {
        count_lookup();
        v = visibility_soft(q);
    }
    if (!shaft || soft_two_layers) {
        v = soft_grid_visibility(q, true);
    }
    return v;
}

// Steps per grid cell a marched interval crosses: the grid's trilinear interpolation is smooth
// between cells, and steps in sharp cells are refined (on the soft scene of the report, p95
// 1.77% at 0.5 a cell, 2.08% at 0.25).
const SOFT_STEPS_PER_CELL: f32 = 0.5;

// Steps for [s0, s1] through the soft-shadow grid: SOFT_STEPS_PER_CELL per cell the interval
// crosses, at least 2, at most `steps`. Cells across: the
// angle the interval subtends at the light (s is that angle over w) over a cell's angle;
// slices: the change of q = nearest / distance, through the point nearest the light.
fn soft_grid_steps(ray: PixelRay, r: AirRay, s0: f32, s1: f32) -> u32 {
    let across = (s1 - s0) * r.w / mp.soft_grid.cell_angle;
    let x0 = x_of_s(r, s0);
    let x1 = x_of_s(r, s1);
    let xc = clamp(dot(air.light_pos - air.eye, ray.dir), x0, x1);
    let nearest = soft_nearest();
    let slices = f32(mp.soft_grid.slices);
    let k0 = slices * (1.0 - nearest / max(length(air.eye + x0 * ray.dir - air.light_pos), nearest));
    let kc = slices * (1.0 - nearest / max(length(air.eye + xc * ray.dir - air.light_pos), nearest));
    let k1 = slices * (1.0 - nearest / max(length(air.eye + x1 * ray.dir - air.light_pos), nearest));
    let cells = across + abs(k0 - kc) + abs(kc - k1);
    return clamp(u32(ceil(SOFT_STEPS_PER_CELL * cells)), 2u, mp.steps);
}

// The cone of lines tangent to both the light's sphere and the sphere (c, rho) that cross
// between them, beyond its apex: the only points from which the sphere can hide part of the
// light. Its pieces along the ray as cone_support finds them (up to two intervals).
fn penumbra_cone(dir: vec3<f32>, x_end: f32, c: vec3<f32>, rho: f32) -> vec2<f32> {
    let radius = shadow.light.radius;
    let to_c = c - air.light_pos;
    let l = length(to_c);
    // With a margin (see PENUMBRA_CONE_MARGIN).
    let sin_t = PENUMBRA_CONE_MARGIN * (radius + rho) / max(l, 1.0e-30);
    if (sin_t >= 0.999) {
        return vec2<f32>(0.0, x_end); // the spheres (nearly) touch: anywhere
    }
    let axis = to_c / l;
    let apex = air.light_pos + axis * (l * radius / (radius + rho));
    let c2 = 1.0 - sin_t * sin_t;
    var cuts = cone_cuts(apex, axis, c2, air.eye, dir, x_end);
    let k = cuts.count;
    var hull = vec2<f32>(FAR, -1.0);
    let cos_t = vs_sqrt(c2);
    for (var i = 0u; i < k; i++) {
        let piece = cut_piece(cuts, i);
        let a = piece.x;
        let b = piece.y;
        var mid = 0.5 * (a + b);
        if (b >= FAR) {
            mid = a + 1.0 + 2.0 * abs(a) + 1.0e3 * air.distance;
        }
        let rel = air.eye + mid * dir - apex;
        if (b > a && dot(axis, rel) >= cos_t * length(rel)) {
            hull = vec2<f32>(min(hull.x, a), max(hull.y, b));
        }
    }
    return hull;
}

// The part of the ray interval [h.x, h.y] (x) in n·x ≤ d for plane = (n, d) (ShadowMap::planes):
// where the occluder can cast a penumbra; empty: h.x > h.y.
fn beneath_plane(h: vec2<f32>, dir: vec3<f32>, plane: vec4<f32>) -> vec2<f32> {
    let f0 = dot(plane.xyz, air.eye) - plane.w;
    let f1 = dot(plane.xyz, dir);
    if (f1 > 0.0) {
        return vec2<f32>(h.x, min(h.y, -f0 / f1));
    }
    if (f1 < 0.0) {
        return vec2<f32>(max(h.x, -f0 / f1), h.y);
    }
    return select(vec2<f32>(1.0, 0.0), h, f0 <= 0.0);
}

// Where a soft shadow may be along the ray, in s: the hull of the occluders' penumbra cones
// (empty: (1, 0)). Brute force marches all of it, and so does a shadow map without bounds.
fn soft_extents(ray: PixelRay, r: AirRay, x_end: f32) -> vec2<f32> {
    if (MODE == MODE_BRUTE_FORCE) {
        return vec2<f32>(0.0, 1.0);
    }
    let count = shadow.soft.spheres;
    if (count == 0u) {
        return vec2<f32>(0.0, 1.0); // no bounds given: anywhere
    }
    var hull = vec2<f32>(FAR, -1.0);
    for (var i = 0u; i < count; i++) {
        var h = penumbra_cone(ray.dir, x_end, shadow.spheres[i].xyz, shadow.spheres[i].w);
        h = beneath_plane(h, ray.dir, shadow.planes[i]);
        // A piece within rounding of a point (a ray ending on a ground's plane) holds no
        // penumbra: it would only be marched.
        if (h.y - h.x > 1.0e-4 * abs(h.y)) {
            hull = vec2<f32>(min(hull.x, h.x), max(hull.y, h.y));
        }
    }
    if (!(hull.x <= hull.y)) {
        return vec2<f32>(1.0, 0.0);
    }
    return vec2<f32>(s_of_x(air, r, hull.x * 0.999), s_of_x(air, r, min(hull.y * 1.001, FAR)));
}

// The lit/shadow transition in [lo, hi] located by BISECTIONS halvings; `lo` is on the side
// whose visibility is `v_lo`.
fn bisect(ray: PixelRay, r: AirRay, lo_start: f32, hi_start: f32, v_lo: f32) -> f32 {
    var lo = lo_start;
    var hi = hi_start;
    for (var b = 0u; b < BISECTIONS; b++) {
        let m = 0.5 * (lo + hi);
        if ((vis_at(ray, r, m) >= 0.5) == (v_lo >= 0.5)) {
            lo = m;
        } else {
            hi = m;
        }
    }
    return 0.5 * (lo + hi);
}

struct Marched {
    t: vec3<f32>,
    steps: u32,
}

// The light texture's uv of a point given in the spot's frame (in front of the light).
fn texture_uv(v: vec3<f32>) -> vec2<f32> {
    let k = 1.0 / (max(-v.z, 1.0e-30) * mp.tan_half_angle);
    return vec2<f32>(0.5 + 0.5 * v.x * k, 0.5 - 0.5 * v.y * k);
}

// The textured spot's I0 multiplier at a world point, read at the mip level whose texel
// matches `step_angle` (the angle a march step subtends at the light; Wyman and Ramsey 2008, §3.3).
fn light_texture(p: vec3<f32>, step_angle: f32) -> vec3<f32> {
    if (COUNT_WORK) {
        work.y += 1u;
    }
    let uv = texture_uv((mp.tex_frame * vec4<f32>(p, 1.0)).xyz);
    let texel_angle = 2.0 * mp.tan_half_angle / mp.tex_width;
    let lod = clamp(vs_log2(max(step_angle / texel_angle, 1.0)), 0.0, mp.tex_mips - 1.0);
    return textureSampleLevel(light_tex, light_sampler, uv, lod).xyz;
}

// Steps for a textured spot's march over [a, b]: as many as the texels of the light's texture
// the piece's image can cross, at most `texture_steps`. The piece subtends (b − a)·w at the
// light (s is the angle there over w), and a texel subtends at least 2 tan(h) / (W (1 + tan²h))
// (at the cone's edge, h its half angle); steps uniform in s are uniform in that angle, so each
// spans at most one texel, and a piece that crosses three texels takes three steps.
fn texture_steps_for(r: AirRay, a: f32, b: f32) -> u32 {
    let t = mp.tan_half_angle;
    let texel = 2.0 * t / (mp.tex_width * (1.0 + t * t));
    let texels = (b - a) * r.w / max(texel, 1.0e-30);
    if (!(texels < f32(mp.texture_steps))) {
        return mp.texture_steps;
    }
    return max(1u, u32(ceil(texels)));
}

// The texture weight of the step [a, b]: the mean of two samples at its Gauss–Legendre
// points. The texture is only piecewise smooth, and its edges dominate the error of a
// one-sample step.
fn step_texture(ray: PixelRay, r: AirRay, a: f32, b: f32, footprint: f32) -> vec3<f32> {
    let mid = 0.5 * (a + b);
    let h = 0.2886751 * (b - a);
    return 0.5 * (light_texture(air.eye + x_of_s(r, mid - h) * ray.dir, footprint)
                + light_texture(air.eye + x_of_s(r, mid + h) * ray.dir, footprint));
}

// ∫ tex dT over [s0, s1], nothing shadowed on it (a textured spot's lit piece), one step per
// region of the texture that the piece's image crosses. The image of a segment in the light's
// texture is a segment (a central projection), traced here through the texture's cells
// (`light_flats`): a square of flat cells (one bilinear value everywhere in it) in one step,
// the largest that starts at the image's cell and extends the way the image moves; a cell that
// is not flat (one bilinear patch) in one step sampled at its middle. Each step ends where the
// image leaves the square or cell. Consecutive flat squares touch, so they have one value: it
// is read once per run of them, and T is taken only at the run's ends, at the point of the
// segment where the image is there (the fraction λ of the image is the fraction
// μ = λ z0 / (λ z0 + (1 − λ) z1) of the segment, z the depth in the spot's frame), then its s.
// The trace takes at most `texture_steps`; the rest of a piece that crosses more (a texture
// without flat regions seen across many texels) is marched in uniform steps, as if untraced.
fn march_texture(ray: PixelRay, r: AirRay, s0: f32, s1: f32) -> Marched {
    var out: Marched;
    out.t = vec3<f32>(0.0);
    out.steps = 0u;
    if (!(s1 > s0)) {
        return out;
    }
    let x0 = x_of_s(r, s0);
    let x1 = x_of_s(r, s1);
    let v0 = (mp.tex_frame * vec4<f32>(air.eye + x0 * ray.dir, 1.0)).xyz;
    let v1 = (mp.tex_frame * vec4<f32>(air.eye + x1 * ray.dir, 1.0)).xyz;
    let z0 = max(-v0.z, 1.0e-30);
    let z1 = max(-v1.z, 1.0e-30);
    let size = vec2<f32>(textureDimensions(light_tex, 0));
    let last_texel = vec2<i32>(size) - vec2<i32>(1);
    let cells = vec2<i32>(textureDimensions(light_flats, 0));
    // The image in cell coordinates (cell i spans [i, i + 1]: texel centres i and i + 1).
    let q0 = texture_uv(v0) * size - 0.5;
    let d = texture_uv(v1) * size - 0.5 - q0;
    let reach = max(abs(d.x), abs(d.y));
    // Each step's cell is found 1/128 cell further along the image than where it starts, so a
    // step that ends on a cell's edge starts the next one in the next cell.
    let ahead = select(0.0, (1.0 / 128.0) / reach, reach > 0.0);
    let forward = d >= vec2<f32>(0.0);
    let moving = d != vec2<f32>(0.0);
    let d_safe = select(vec2<f32>(1.0), d, moving);
    // The map's channel for the quadrant the image moves into.
    let quadrant = select(1u, 0u, forward.x) + select(2u, 0u, forward.y);
    var lambda = 0.0;
    var s_a = s0;
    var t_a = table_tt(table, air, r, s0);
    // A run of flat squares in progress: its value (T at its start is t_a).
    var run = false;
    var run_value = vec3<f32>(0.0);
    var n = 0u;
    loop {
        if (!(lambda < 1.0) || n >= mp.texture_steps) {
            break;
        }
        let cell = clamp(vec2<i32>(floor(q0 + (lambda + ahead) * d)), vec2<i32>(0), cells - 1);
        let k = i32(textureLoad(light_flats, cell, 0)[quadrant]);
        if (COUNT_WORK) {
            work.y += 1u;
        }
        n++;
        // The square (a cell not flat: the cell itself); its face ahead, unbounded where it
        // reaches the map's edge: beyond it the clamped lookups repeat the edge's cells.
        let side = max(k, 1);
        let ahead_face = select(cell + 1 - side, cell + side, forward);
        let beyond = select(ahead_face <= vec2<i32>(0), ahead_face >= cells, forward);
        let face = select(vec2<f32>(ahead_face), select(vec2<f32>(-1.0e30), vec2<f32>(1.0e30), forward), beyond);
        let exits = select(vec2<f32>(2.0), (face - q0) / d_safe, moving);
        let lambda_b = min(1.0, max(min(exits.x, exits.y), lambda + ahead));
        if (k > 0) {
            if (!run) {
                run = true;
                run_value = textureLoad(light_tex, min(cell, last_texel), 0).xyz;
                if (COUNT_WORK) {
                    work.y += 1u;
                }
            }
            lambda = lambda_b;
            continue;
        }
        // A cell that is not flat: close the run before it, then the cell.
        if (run) {
            let s_m = s_at_image(r, x0, x1, z0, z1, lambda, s_a, s1);
            let t_m = table_tt(table, air, r, s_m);
            out.t += t_between(t_a, t_m) * run_value;
            t_a = t_m;
            s_a = s_m;
            run = false;
        }
        let s_b = s_at_image(r, x0, x1, z0, z1, lambda_b, s_a, s1);
        let t_b = table_tt(table, air, r, s_b);
        let q = q0 + 0.5 * (lambda + lambda_b) * d;
        let value = textureSampleLevel(light_tex, light_sampler, (q + 0.5) / size, 0.0).xyz;
        if (COUNT_WORK) {
            work.y += 1u;
        }
        out.t += t_between(t_a, t_b) * value;
        t_a = t_b;
        s_a = s_b;
        lambda = lambda_b;
    }
    if (run) {
        let s_m = s_at_image(r, x0, x1, z0, z1, lambda, s_a, s1);
        let t_m = table_tt(table, air, r, s_m);
        out.t += t_between(t_a, t_m) * run_value;
        t_a = t_m;
        s_a = s_m;
    }
    out.steps = n;
    if (lambda < 1.0) {
        let rest = march_textured(ray, r, s_a, s1, texture_steps_for(r, s_a, s1));
        out.t += rest.t;
        out.steps += rest.steps;
    }
    return out;
}

// The s of the point of the segment [x0, x1] whose image is at the fraction `lambda` of the
// image (z0, z1 the ends' depths in the spot's frame), within [lo, s1]; s1 itself at the end.
fn s_at_image(r: AirRay, x0: f32, x1: f32, z0: f32, z1: f32, lambda: f32, lo: f32, s1: f32) -> f32 {
    if (!(lambda < 1.0)) {
        return s1;
    }
    let mu = lambda * z0 / (lambda * z0 + (1.0 - lambda) * z1);
    return clamp(s_of_x(air, r, x0 + mu * (x1 - x0)), lo, s1);
}

// ∫ tex dT over [s0, s1] in n uniform steps (the rest of a piece `march_texture` did not
// finish).
fn march_textured(ray: PixelRay, r: AirRay, s0: f32, s1: f32, n: u32) -> Marched {
    var out: Marched;
    out.t = vec3<f32>(0.0);
    out.steps = 0u;
    if (!(s1 > s0)) {
        return out;
    }
    let ds = (s1 - s0) / f32(n);
    let footprint = 0.5 * ds * r.w;
    var t_a = table_tt(table, air, r, s0);
    for (var i = 0u; i < n; i++) {
        let a = s0 + ds * f32(i);
        let b = select(s0 + ds * f32(i + 1u), s1, i + 1u == n);
        let t_b = table_tt(table, air, r, b);
        out.t += t_between(t_a, t_b) * step_texture(ray, r, a, b, footprint);
        t_a = t_b;
    }
    out.steps = n;
    return out;
}

// ∫ V dT over [s0, s1] (T known at both ends: t0, t1) in n uniform steps, each sampled at its
// midpoint (so the ends of a hybrid interval, which sit on shadow-volume faces, are never
// half-lit). The sum Σ Vᵢ (T(bᵢ) − T(aᵢ)) telescopes over each run of steps with equal
// visibility, so a step costs one shadow-map lookup and T is evaluated only where the
// visibility changes. The step loop only records those transitions; T (and, with bisection
// on, the located edge between the two midpoints that disagree) is computed for them
// afterwards, outside the loop every step executes.
fn march_shadowed(ray: PixelRay, r: AirRay, s0: f32, s1: f32, t0: TT, t1: TT, n: u32) -> Marched {
    var out: Marched;
    out.t = vec3<f32>(0.0);
    out.steps = 0u;
    if (!(s1 > s0)) {
        return out;
    }
    let ds = (s1 - s0) / f32(n);
    var t_run = t0;  // T where the current run of equal visibility began
    var v_run = vis_at(ray, r, s0 + 0.5 * ds);
    var v_prev = v_run;
    var i = 1u;
    var edges: array<vec2<f32>, MAX_EDGES>;  // (step index, its visibility) where a run begins
    loop {
        var count = 0u;
        for (; i < n && count < MAX_EDGES; i++) {
            let v = vis_at(ray, r, s0 + (f32(i) + 0.5) * ds);
            if (v != v_prev) {
                edges[count] = vec2<f32>(f32(i), v);
                count++;
            }
            v_prev = v;
        }
        for (var k = 0u; k < count; k++) {
            let j = edges[k].x;
            let v = edges[k].y;
            var edge = s0 + j * ds;
            if (BISECTIONS > 0u && (v >= 0.5) != (v_run >= 0.5)) {
                // The transition lies between the two midpoints.
                edge = bisect(ray, r, edge - 0.5 * ds, edge + 0.5 * ds, v_run);
                out.steps += BISECTIONS;
            }
            let t_edge = table_tt(table, air, r, edge);
            out.t += t_between(t_run, t_edge) * v_run;
            t_run = t_edge;
            v_run = v;
        }
        if (i >= n) {
            break;
        }
    }
    out.t += t_between(t_run, t1) * v_run;
    out.steps += n;
    return out;
}

// The same for a textured spot: the texture weight changes at nearly every step, so T is
// evaluated at every step boundary; two texture samples per step, and the bisection inline.
fn march_shadowed_textured(ray: PixelRay, r: AirRay, s0: f32, s1: f32, n: u32) -> Marched {
    var out: Marched;
    out.t = vec3<f32>(0.0);
    out.steps = 0u;
    if (!(s1 > s0)) {
        return out;
    }
    let ds = (s1 - s0) / f32(n);
    let footprint = 0.5 * ds * r.w;
    var t_a = table_tt(table, air, r, s0);
    var v_prev = 1.0;
    var w_prev = vec3<f32>(1.0);
    for (var i = 0u; i < n; i++) {
        let a = s0 + ds * f32(i);
        let b = select(s0 + ds * f32(i + 1u), s1, i + 1u == n);
        let mid = 0.5 * (a + b);
        let t_b = table_tt(table, air, r, b);
        let v = vis_at(ray, r, mid);
        let w = step_texture(ray, r, a, b, footprint);
        out.t += t_between(t_a, t_b) * (v * w);
        if (BISECTIONS > 0u && i > 0u && (v >= 0.5) != (v_prev >= 0.5)) {
            // Move the edge the midpoint rule assumed (at a) to the located transition.
            let t_edge = table_tt(table, air, r, bisect(ray, r, a - 0.5 * ds, mid, v_prev));
            out.t += t_between(t_a, t_edge) * (v_prev * w_prev - v * w);
            out.steps += BISECTIONS;
        }
        t_a = t_b;
        v_prev = v;
        w_prev = w;
    }
    out.steps += n;
    return out;
}

// The textbook march (MODE_TEXTBOOK, a baseline): the midpoint rule on the integrand of the model,
// σs·p(θ)·I0·V·e^{−σt(d + x)}/d², at `n` steps uniform in distance over each lit piece, up to the
// surface or to where the transmittance from the eye is below 1e-4.
struct Textbook {
    lit: vec3<f32>,
    open: vec3<f32>,
}

fn march_textbook(ray: PixelRay, r: AirRay, x_end: f32, n: u32) -> Textbook {
    if (LIGHT == LIGHT_DIRECTIONAL) {
        return march_textbook_directional(ray, r, x_end, n);
    }
    var out: Textbook;
    out.lit = vec3<f32>(0.0);
    out.open = vec3<f32>(0.0);
    let d_light = air.distance;
    let sigma_min = min(air.sigma_t.x, min(air.sigma_t.y, air.sigma_t.z));
    let x_cap = min(x_end, select(100.0 * d_light, TEXTBOOK_DEPTH / sigma_min, sigma_min > 0.0));
    let log_si = vs_log3(air.sigma_s) + vs_log3(air.intensity);
    let sup = support_x(air, shadow.light, ray.dir, x_cap);
    // The pixel footprint at the light bounds 1/d² as the closed form's prefactor is bounded.
    let d_min = d_light * max(air.pixel_radius * ray.footprint, 1.0e-6);
    for (var i = 0u; i < sup.count; i++) {
        let x0 = sup.x[i].x;
        let x1 = min(sup.x[i].y, x_cap);
        if (!(x1 > x0)) {
            continue;
        }
        let dx = (x1 - x0) / f32(n);
        for (var k = 0u; k < n; k++) {
            let x = x0 + (f32(k) + 0.5) * dx;
            let p = air.eye + x * ray.dir;
            let to_p = p - air.light_pos;
            let d = max(length(to_p), d_min);
            let mu = dot(to_p, -ray.dir) / max(length(to_p), 1.0e-30);
            // σs I e^{−σt (d + x)} / d² in log space: e^{−σt (d + x)} alone may be subnormal
            // (a GPU may flush it to zero) where the product is a visible radiance.
            var f = phase(air, 1.0 - mu, 1.0 + mu)
                  * vs_exp3(log_si - air.sigma_t * (d + x) - vec3<f32>(2.0 * vs_log(d))) * dx;
            if (TEXTURED) {
                f *= light_texture(p, dx / d);
            }
            out.open += f;
            count_lookup();
            out.lit += f * visibility(p);
        }
    }
    return out;
}

// The same for a directional light: σs·p(θ)·E·V·e^{−σt x} (θ constant along the ray), up to
// the surface, to transmittance 1e-4, or (a clear medium's sky) 100 L.
fn march_textbook_directional(ray: PixelRay, r: AirRay, x_end: f32, n: u32) -> Textbook {
    var out: Textbook;
    out.lit = vec3<f32>(0.0);
    out.open = vec3<f32>(0.0);
    let sigma_min = min(air.sigma_t.x, min(air.sigma_t.y, air.sigma_t.z));
    let x_cap = min(x_end, select(100.0 * air.distance, TEXTBOOK_DEPTH / sigma_min, sigma_min > 0.0));
    let dx = x_cap / f32(n);
    for (var k = 0u; k < n; k++) {
        let x = (f32(k) + 0.5) * dx;
        let f = r.prefactor * vs_exp3(-air.sigma_t * x) * dx;
        out.open += f;
        count_lookup();
        out.lit += f * visibility(air.eye + x * ray.dir);
    }
    return out;
}

// Pixel `p`'s work counters (COUNT_WORK; see `work`), after the pass's four.
fn store_work(p: u32, stored: u32) {
    if (COUNT_WORK) {
        atomicStore(&stats[4u + 4u * p], work.x);
        atomicStore(&stats[5u + 4u * p], work.y);
        atomicStore(&stats[6u + 4u * p], work.z);
        atomicStore(&stats[7u + 4u * p], stored);
    }
}

@compute @workgroup_size(8, 8)
fn march(@builtin(global_invocation_id) gid: vec3<u32>) {
    // Neighbouring pixels' exact soft-shadow directions turned apart, so that the upsample's
    // filter averages them too.
    exact_seed = exact_seed_at(vec3<f32>(vec2<f32>(gid.xy), 0.0));
    let size = vec2<u32>(view.size.xy);
    if (gid.x >= size.x || gid.y >= size.y) {
        return;
    }
    // At reduced resolution the ray goes through this pass's pixel centre (where the extents
    // were rasterised) and ends at the depth of the output pixel under that centre.
    let full = textureDimensions(scene_depth);
    let under = min(vec2<u32>((vec2<f32>(gid.xy) + 0.5) * vec2<f32>(full) / view.size.xy), full - 1u);
    let depth = textureLoad(scene_depth, under, 0);
    let ray = pixel_ray(view, vec2<f32>(gid.xy) + 0.5, depth);
    let r = air_ray(air, ray);
    let x_end = select(FAR, ray.distance, ray.distance >= 0.0);

    let sup = support_s(air, r, shadow.light, ray.dir, x_end);

    if (MODE == MODE_TEXTBOOK) {
        let tb = march_textbook(ray, r, x_end, mp.steps);
        var value = clamp_radiance(tb.lit);
        if (mp.lit_fraction != 0u) {
            value = select(vec3<f32>(1.0), min(tb.lit / tb.open, vec3<f32>(1.0)), tb.open > vec3<f32>(0.0));
        }
        textureStore(inscatter_out, gid.xy, vec4<f32>(value, ray.distance));
        textureStore(steps_out, gid.xy, vec4<u32>(mp.steps, 0u, 0u, 0u));
        store_work(gid.y * size.x + gid.x, 0u);
        return;
    }

    // Shadow-volume extents in s (hybrid): start at 0 when the nearest face is a back face
    // (eye inside a volume, or its front cut away by the near plane), else at the nearest front
    // face; end at the farthest back face (0 depth = at infinity).
    var ext = vec2<f32>(1.0, 0.0); // empty
    // Exact mode: the pixel's crossings (unsorted in the list), when it held them all.
    var exact = false;
    var n_cross = 0u;
    var list_base = 0u;
    // Volumes around the eye, counted back from the far end; < 0: not known (open meshes).
    var around_eye = -1;
    // The crossings the pixel's list stored (COUNT_WORK).
    var stored = 0u;
    // Soft shadows with the occluders' bounds: outside their penumbra cones no occluder hides
    // any of the light (and the grid holds 1), so the pieces outside `soft_extents` take
    // visibility 1 without a lookup.
    let lit_outside = SOFT && MODE != MODE_BRUTE_FORCE && shadow.soft.spheres > 0u;
    if (SOFT) {
        // Soft shadows: the shadow volumes bound the hard shadow, not the penumbra; march
        // inside the penumbra cones instead.
        ext = soft_extents(ray, r, x_end);
    } else if (MODE == MODE_HYBRID) {
        let front = textureLoad(extent_front, gid.xy, 0);
        let back_near = textureLoad(extent_back_near, gid.xy, 0);
        let back_far = textureLoad(extent_back_far, gid.xy, 0);
        let has_front = front > 0.0;
        let has_back = back_far < 1.0;
        if (has_front || has_back) {
            let to_x = mp.extents_near * ray.depth_to_distance;
            var x0 = 0.0;
            if (has_front && back_near <= front) {
                x0 = to_x / front;
            }
            var x1 = FAR;
            if (has_back && back_far > 0.0) {
                x1 = to_x / back_far;
            }
            // Widening is always safe (the shadow map decides visibility): a relative margin covers rasterisation
            // and depth rounding.
            ext = vec2<f32>(s_of_x(air, r, x0 * 0.999), s_of_x(air, r, min(x1 * 1.001, FAR)));
        }
    } else if (MODE == MODE_BRUTE_FORCE) {
        ext = vec2<f32>(0.0, 1.0);
    } else if (MODE == MODE_EXACT) {
        let p = gid.y * size.x + gid.x;
        let head = heads[4u * p];
        let count = head & 0x7fffffffu;
        stored = min(count, mp.list_entries);
        let k = mp.list_entries;
        // Statistics for sizing the lists, kept off the common path: one counter for every
        // pixel would serialise the pass on its atomics.
        if (2u * count > k) {
            atomicAdd(&stats[1], 1u);
            atomicMax(&stats[2], count);
        }
        if (count > k) {
            // The list overflowed: march, as the hybrid does, between the nearest and the
            // farthest crossing (the pieces outside hold no crossing).
            atomicAdd(&stats[0], 1u);
            let z0 = bitcast<f32>(~heads[4u * p + 1u]);
            let z1 = bitcast<f32>(heads[4u * p + 2u]);
            ext = vec2<f32>(s_of_x(air, r, z0 * ray.depth_to_distance * 0.999),
                            s_of_x(air, r, min(z1 * ray.depth_to_distance * 1.001, FAR)));
        } else {
            exact = true;
            n_cross = count;
            list_base = k * p;
            var net = bitcast<i32>(heads[4u * p + 3u]);
            for (var i = 0u; i < count; i++) {
                net += select(-1, 1, crossings[list_base + i] < 0.0);
            }
            if (COUNT_WORK) {
                work.z += count;
            }
            if ((head & 0x80000000u) == 0u) {
                // Volumes around the eye: those around the far end, less those entered before.
                around_eye = -net;
            }
        }
    }

    var total = vec3<f32>(0.0);
    var open = vec3<f32>(0.0);  // the unshadowed T over the support
    var steps = 0u;
    for (var i = 0u; i < sup.count; i++) {
        let u0 = sup.s[i].x;
        let u1 = sup.s[i].y;
        let t_u0 = table_tt(table, air, r, u0);
        let t_u1 = table_tt(table, air, r, u1);
        open += t_between(t_u0, t_u1);
        if (MODE == MODE_ANALYTIC) {
            // No occluders: all of it is lit. (MODE_ANALYTIC lets the compiler drop the shadow
            // code from the analytic pipeline.)
            if (TEXTURED) {
                let all = march_texture(ray, r, u0, u1);
                total += all.t;
                steps += all.steps;
            } else {
                total += t_between(t_u0, t_u1);
            }
            continue;
        }
        if (MODE == MODE_EXACT && exact) {
            // Consecutive crossings (and the piece's ends) bound intervals of constant
            // visibility: closed form times one visibility sample inside each.
            // The crossings are taken in order along the ray without sorting them into a
            // private array (which every pixel would pay for): each step takes the nearest
            // one beyond the last taken, ties broken by list position. Lists are short.
            var a = u0;
            var t_a = t_u0;
            var around = around_eye;
            var last_z = -1.0;
            var last_i = -1;
            loop {
                var next_z = FAR;
                var next_i = -1;
                var next_e = 0;
                if (COUNT_WORK) {
                    work.z += n_cross;
                }
                for (var i = 0u; i < n_cross; i++) {
                    let c = crossings[list_base + i];
                    let z = abs(c);
                    let after = z > last_z || (z == last_z && i32(i) > last_i);
                    if (after && (z < next_z || next_i < 0)) {
                        next_z = z;
                        next_i = i32(i);
                        next_e = select(-1, 1, c < 0.0);
                    }
                }
                var b = u1;
                var t_b = t_u1;
                if (next_i >= 0) {
                    let s_c = s_of_x(air, r, next_z * ray.depth_to_distance);
                    if (!(s_c > a)) {
                        // Before this piece of the support: it only changes the count.
                        around += next_e;
                        last_z = next_z;
                        last_i = next_i;
                        continue;
                    }
                    if (s_c < u1) {
                        b = s_c;
                        t_b = table_tt(table, air, r, b);
                    }
                }
                // The number of volumes around the interval decides whether it is lit, when
                // it is known (closed meshes: counted from the far end, as z-fail shadow
                // volumes count, so a face cut by the near plane does not matter). Otherwise
                // (a face of an open or non-manifold mesh crossed the pixel) the shadow map
                // says which side of the faces the interval is on.
                var v = 0.0;
                if (around_eye >= 0 && around >= 0) {
                    v = select(0.0, 1.0, around == 0);
                } else {
                    v = vis_at(ray, r, 0.5 * (a + b));
                }
                if (TEXTURED) {
                    // The texture still needs steps: one per region of it the piece crosses.
                    if (v > 0.0) {
                        let m = march_texture(ray, r, a, b);
                        total += v * m.t;
                        steps += m.steps;
                    }
                } else {
                    total += v * t_between(t_a, t_b);
                }
                if (!(b < u1)) {
                    break;
                }
                around += next_e;
                last_z = next_z;
                last_i = next_i;
                a = b;
                t_a = t_b;
            }
            continue;
        }
        let m0 = max(u0, ext.x);
        let m1 = min(u1, ext.y);
        if (!(m0 < m1)) {
            // No shadow-volume face on this piece: one visibility for all of it.
            var v = 1.0;
            if (!lit_outside) {
                v = vis_at(ray, r, 0.5 * (u0 + u1));
            }
            if (TEXTURED) {
                if (v > 0.0) {
                    let all = march_texture(ray, r, u0, u1);
                    total += v * all.t;
                    steps += all.steps;
                }
            } else {
                total += v * t_between(t_u0, t_u1);
            }
            continue;
        }
        // Before, between and after the extents: one visibility sample each outside them
        // (no face there); for a textured spot marched with its own step budget, only inside
        // the cone.
        var t_m0 = t_u0;
        if (m0 != u0) {
            t_m0 = table_tt(table, air, r, m0);
        }
        var t_m1 = t_u1;
        if (m1 != u1) {
            t_m1 = table_tt(table, air, r, m1);
        }
        var inside: Marched;
        if (TEXTURED) {
            // The hybrid gives the texture its own resolution inside the extents too; brute
            // force marches everything with its `steps`, texture included.
            let n = select(mp.steps, max(mp.steps, texture_steps_for(r, m0, m1)), MODE != MODE_BRUTE_FORCE);
            inside = march_shadowed_textured(ray, r, m0, m1, n);
        } else {
            if (SOFT && SOFT_GRID) {
                inside = march_soft_grid(ray, r, m0, m1, t_m0, t_m1, soft_grid_steps(ray, r, m0, m1));
            } else {
                inside = march_shadowed(ray, r, m0, m1, t_m0, t_m1, mp.steps);
            }
        }
        total += inside.t;
        steps += inside.steps;
        var v_before = 0.0;
        if (m0 > u0) {
            v_before = 1.0;
            if (!lit_outside) {
                v_before = vis_at(ray, r, 0.5 * (u0 + m0));
            }
        }
        var v_after = 0.0;
        if (u1 > m1) {
            v_after = 1.0;
            if (!lit_outside) {
                v_after = vis_at(ray, r, 0.5 * (m1 + u1));
            }
        }
        if (TEXTURED) {
            if (v_before > 0.0) {
                let before = march_texture(ray, r, u0, m0);
                total += v_before * before.t;
                steps += before.steps;
            }
            if (v_after > 0.0) {
                let after = march_texture(ray, r, m1, u1);
                total += v_after * after.t;
                steps += after.steps;
            }
        } else {
            total += v_before * t_between(t_u0, t_m0) + v_after * t_between(t_m1, t_u1);
        }
    }
    total = max(total, vec3<f32>(0.0));
    var value = clamp_radiance(r.prefactor * total);
    if (mp.lit_fraction != 0u) {
        // Reduced resolution: the fraction of the unshadowed airlight that arrives, which the
        // upsample multiplies into a full-resolution analytic airlight. It is smooth where the
        // airlight itself is peaked (around the light) and keeps hard edges only at shadows.
        value = select(vec3<f32>(1.0), min(total / open, vec3<f32>(1.0)), open > vec3<f32>(0.0));
    }
    textureStore(inscatter_out, gid.xy, vec4<f32>(value, ray.distance));
    textureStore(steps_out, gid.xy, vec4<u32>(steps, 0u, 0u, 0u));
    store_work(gid.y * size.x + gid.x, stored);
}

