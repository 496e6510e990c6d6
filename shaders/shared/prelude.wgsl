// volshadow prelude: the maths shared by every node (phase functions, the bounded airlight
// integrand of the stable airlight form, the F′ table lookup). Each node's WGSL file is appended to this one.

// The kinds of light (`LightUniform::kind` in src/light/gpu.rs).
const LIGHT_POINT: u32 = 0u;
const LIGHT_SPOT: u32 = 1u;
const LIGHT_DIRECTIONAL: u32 = 2u;

// Pipeline constant of every per-pixel node: the kind of light, so that a point light's pixels
// do not pay for a spot's cone (a support that may start away from the eye) and a directional
// light's parallel rays are a separate path. What a pass asks of a light goes through
// light.wgsl, which chooses among the kinds' files in light/ by this constant.
override LIGHT: u32 = LIGHT_POINT;

// A light as every node reads it, resolved once from the scene's light (`LightUniform` in
// src/light/gpu.rs, which each kind of light fills in its own file of src/light/).
struct Light {
    position: vec3<f32>,   // a point or spot light's position; a directional light's unit
                           // direction of travel
    kind: u32,             // LIGHT_POINT, LIGHT_SPOT or LIGHT_DIRECTIONAL
    intensity: vec3<f32>,  // radiant intensity I0 (a directional light: irradiance E)
    radius: f32,           // the light's radius (0: a point source)
    axis: vec3<f32>,       // a spot's unit axis, else 0
    cos_half: f32,         // a spot's cos(half apex angle), else 0
}

const PI: f32 = 3.14159265358979;
const INV_4PI: f32 = 0.0795774715459477;
// Larger than any radiance we produce; outputs are clamped to it so nothing reaches Inf.
const MAX_RADIANCE: f32 = 1.0e30;
// The distance of "no end": the sky, an unbounded piece of a ray, no crossing found.
const FAR: f32 = 3.4e38;

// Per-frame airlight parameters. The phase function is a per-channel mixture of
// five lobes, so every PhaseFunction variant (and Hoffman–Preetham's RGB mix) is one code path.
// Mirrors `AirlightUniform` in src/nodes/groups/uniforms.rs field by field.
struct Airlight {
    light_pos: vec3<f32>,
    distance: f32,          // D = |P − E|
    eye: vec3<f32>,
    pixel_radius: f32,      // angular radius of a pixel at the image centre (radians)
    intensity: vec3<f32>,   // I0
    hg_g: f32,              // Henyey–Greenstein g
    sigma_s: vec3<f32>,
    table_along: u32,       // F′ table entries along the ray (s)
    sigma_t: vec3<f32>,     // σt = σs + σa
    table_across: u32,      // F′ table rows across rays (γ)
    w_iso: vec4<f32>,       // per-channel (rgb) lobe weights, summing to 1
    w_rayleigh: vec4<f32>,
    w_hg: vec4<f32>,
    w_hazy: vec4<f32>,
    w_murky: vec4<f32>,
}

// Phase function at scattering angle θ, given 1 − cos θ and 1 + cos θ computed without
// cancellation (the forward peak of HG g = 0.95 lives where 1 − cos θ ≈ 1e-3).
fn phase(a: Airlight, one_minus_mu: f32, one_plus_mu: f32) -> vec3<f32> {
    let mu = 0.5 * (one_plus_mu - one_minus_mu);
    var p = a.w_iso.xyz * INV_4PI;
    p += a.w_rayleigh.xyz * (3.0 / (16.0 * PI)) * (1.0 + mu * mu);
    if (any(a.w_hg.xyz != vec3<f32>(0.0))) {
        let g = a.hg_g;
        // 1 + g² − 2gμ as a sum of non-negative terms for either sign of g.
        var denom = (1.0 - g) * (1.0 - g) + 2.0 * g * one_minus_mu;
        if (g < 0.0) {
            denom = (1.0 + g) * (1.0 + g) - 2.0 * g * one_plus_mu;
        }
        p += a.w_hg.xyz * (1.0 - g * g) * INV_4PI / (denom * vs_sqrt(denom));
    }
    let half_fwd = 0.5 * one_plus_mu;          // (1 + cos θ) / 2
    let h2 = half_fwd * half_fwd;
    let h8 = h2 * h2 * h2 * h2;
    p += a.w_hazy.xyz * (1.0 + 9.0 * h8) / (8.0 * PI);
    let h32 = h8 * h8 * h8 * h8;
    p += a.w_murky.xyz * 33.0 * (1.0 + 50.0 * h32) / (332.0 * PI);
    return p;
}

// A ray's constants for the airlight. w = π − γ is kept separately so that f32
// keeps its relative precision when the light is behind the eye (γ → π).
struct AirRay {
    gamma: f32,            // angle between the view ray and the direction to the light
    w: f32,                // π − γ
    sin_half_gamma: f32,   // sin(γ/2)
    c: f32,                // |v × (P − E)| = D sin γ
    dotv: f32,             // v · (P − E) = D cos γ
    prefactor: vec3<f32>,  // I0 σs exp(−σt D) w / (D sin γ), sin γ clamped by the pixel footprint
}

// (cos h, sin h) of an angle h ∈ [0, π/2] whose complement π/2 − h the caller computed
// without cancellation (`co`), each to a few ULP relative: the sine of a small h, and the
// cosine of an h near π/2, are the quantities whose relative precision WGSL's `sin` and `cos`
// (absolute 2^-11) do not keep.
// Branch-free: one sine and one cosine polynomial of whichever angle is the smaller (a SIMD
// machine that runs both sides of a branch would evaluate four).
fn cos_sin(h: f32, co: f32) -> vec2<f32> {
    let swap = h > 0.25 * PI;
    let x = select(h, co, swap);
    let c = vs_cos_poly(x);
    let s = vs_sin_poly(x);
    return select(vec2<f32>(c, s), vec2<f32>(s, c), swap);
}

// sin θ for θ ∈ [0, π] given θ and its supplement π − θ (computed without cancellation), to a
// few ULP relative.
fn sin_supplement(theta: f32, supplement: f32) -> f32 {
    return vs_sin_poly(min(theta, supplement));
}

// The bounded integrand of form (2) in the normalised scattering angle s = (2ξ − γ)/(π − γ):
// T(γ, s) = ∫₀^s p(cos 2ξ) exp(−σt (d + x − D)) ds'. Everything is computed from
// a = ξ − γ/2 and u = π/2 − ξ, so no difference of nearly equal numbers appears:
//   d + x − D = 2 D sin(γ/2) sin(a) / sin(u),   1 ± cos 2ξ = 2 sin²(u) resp. 2 cos²(u).
// The sines and cosines are `vs_sin_poly` / `vs_cos_poly` (relative precision): the light
// behind the eye makes w = π − γ small, and sin(u) of a small u with WGSL's absolute 2^-11
// error moved the table's tails by up to 33 times their value.
fn table_integrand(a: Airlight, s: f32, w: f32, gamma: f32, sin_half_gamma: f32) -> vec3<f32> {
    return table_integrand_split(a, s, 1.0 - s, w, gamma, sin_half_gamma);
}

// The same with 1 − s given separately, so the tail next to s = 1 (where the attenuation
// falls to zero within a sliver of width ~ 1/(σt·D)) keeps its relative precision.
fn table_integrand_split(a: Airlight, s: f32, one_minus_s: f32, w: f32, gamma: f32, sin_half_gamma: f32) -> vec3<f32> {
    // u = (1 − s)·w/2 and π/2 − u = (γ + s·w)/2 (γ + w = π).
    let u = cos_sin(0.5 * one_minus_s * w, 0.5 * (gamma + s * w));
    return table_integrand_trig(a, u.x, u.y, vs_sin_poly(0.5 * s * w), sin_half_gamma);
}

// The same from cos u, sin u and sin(s·w/2), however the caller got them (the table builder
// turns them from a cell's middle to each quadrature node).
fn table_integrand_trig(a: Airlight, cu: f32, su: f32, sin_half_a: f32, sin_half_gamma: f32) -> vec3<f32> {
    let ratio = min(sin_half_a / max(su, 1.0e-30), 1.0e20);
    let tau = (2.0 * a.distance * sin_half_gamma * ratio) * a.sigma_t;
    return phase(a, 2.0 * cu * cu, 2.0 * su * su) * vs_exp3(-tau);
}

// Normalised scattering angle of the point at distance x along the ray, from the two angles of
// the eye–point–light triangle: δ at the light and β at the point, s = δ / (δ + β).
fn scattering_s(a: Airlight, r: AirRay, x: f32) -> f32 {
    let d = a.distance;
    let delta = vs_atan2_poly(x * r.c, d * d - x * r.dotv);
    let beta = vs_atan2_poly(r.c, x - r.dotv);
    return clamp(delta / max(delta + beta, 1.0e-30), 0.0, 1.0);
}

// Reads T at (row, entry) of the table with the γ rows interpolated linearly.
fn table_row_mix(table: texture_2d<f32>, a: Airlight, gamma: f32, j: u32) -> vec3<f32> {
    let rows = a.table_across;
    let tg = vs_sqrt(clamp(gamma / PI, 0.0, 1.0)) * f32(rows - 1u);
    let i0 = min(u32(tg), rows - 2u);
    let f = clamp(tg - f32(i0), 0.0, 1.0);
    let t0 = textureLoad(table, vec2<u32>(j, i0), 0).xyz;
    let t1 = textureLoad(table, vec2<u32>(j, i0 + 1u), 0).xyz;
    // Where the two rows differ by more than a factor ROW_RATIO, T is nearly exponential in γ
    // (an optically thick medium, far from the integrand's peak: the optical path grows
    // linearly with γ there), and a linear mix overestimates it: mix the logarithms instead.
    let lo = min(t0, t1);
    let hi = max(t0, t1);
    let geometric = t0 * vs_pow3(t1 / max(t0, vec3<f32>(1.0e-37)), vec3<f32>(f));
    return select(mix(t0, t1, f), geometric, (lo > vec3<f32>(0.0)) & (hi > ROW_RATIO * lo));
}

// See `table_row_mix`. Measured (tests/gpu/exact.rs, 200 spot-light scenes in thick fog): with a
// linear mix everywhere, 198 within p95 1%, the others 2.4% and 11.8% (0.19% and 0.59% with
// four times the rows); with the logarithms mixed above a ratio of 2, 198 and worst 5.5%;
// above 1.2, 199 and worst 1.04%. The table's own test and the frame tests are unchanged.
const ROW_RATIO: f32 = 1.2;

// ∫ from the table's entry j (at or below s) to s, by 3-point Gauss–Legendre.
fn table_partial(a: Airlight, r: AirRay, s: f32, j: u32) -> vec3<f32> {
    let s0 = f32(j) / f32(a.table_along - 1u);
    let half_len = 0.5 * (s - s0);
    if (!(half_len > 0.0)) {
        return vec3<f32>(0.0);
    }
    let mid = s0 + half_len;
    let k = 0.7745966692414834 * half_len;
    let f = 0.5555555555555556 * (table_integrand(a, mid - k, r.w, r.gamma, r.sin_half_gamma)
                                + table_integrand(a, mid + k, r.w, r.gamma, r.sin_half_gamma))
          + 0.8888888888888888 * table_integrand(a, mid, r.w, r.gamma, r.sin_half_gamma);
    return f * half_len;
}

// T at s both ways: from the eye (head) and to the end (tail). `t_between` takes an interval's
// integral from whichever holds less beyond it.
struct TT {
    head: vec3<f32>,
    tail: vec3<f32>,
}

// ∫ over [s_a, s_b] (s_a ≤ s_b) from T at its ends: the difference of the heads, whose
// rounding is relative to the head at b, or of the tails, relative to the tail at a, per
// channel whichever is smaller. In an optically thick medium the integrand peaks sharply, and
// an interval beyond the peak (a spot's cone that leaves it outside) is a small difference of
// two heads that both hold it: at σt·D = 81, off by up to 106%.
fn t_between(a: TT, b: TT) -> vec3<f32> {
    return select(b.head - a.head, a.tail - b.tail, b.head > a.tail);
}

// A ray's lit support (light.wgsl's `support_x`): up to two intervals of distance (a spot's
// cone may cut the ray twice).
struct Support {
    x: array<vec2<f32>, 2>,
    count: u32,
}

// The same in the normalised scattering angle s (light.wgsl's `support_s`).
struct SupportS {
    s: array<vec2<f32>, 2>,
    count: u32,
}

fn clamp_radiance(v: vec3<f32>) -> vec3<f32> {
    return min(v, vec3<f32>(MAX_RADIANCE));
}

// Camera constants shared by the per-pixel passes: rays are built in view space so that
// large world coordinates do not cost the ray direction its precision.
// Mirrors `ViewUniform` in src/nodes/groups/uniforms.rs.
struct View {
    view_from_clip: mat4x4<f32>,
    world_from_view: mat4x4<f32>,
    size: vec2<f32>,     // pixels of the pass
    far_depth: f32,      // the depth of the sky
}

// Unit world-space ray direction and eye distance for a pixel centre; distance < 0 means sky.
struct PixelRay {
    dir: vec3<f32>,
    distance: f32,
    // World distance along the ray per unit of view depth (−z): converts view depths to
    // distances for any view matrix, rigid or scaled.
    depth_to_distance: f32,
    // This pixel's angular radius relative to the image centre's: cos^1.5 of its angle to the
    // view axis (a rectilinear pixel's solid angle falls as cos³), so a 175° view does not
    // blur the light's glow over the whole image.
    footprint: f32,
}

fn pixel_ray(v: View, pixel: vec2<f32>, depth: f32) -> PixelRay {
    let ndc = vec2<f32>(pixel.x / v.size.x * 2.0 - 1.0, 1.0 - pixel.y / v.size.y * 2.0);
    let far_depth = v.far_depth;
    let near_depth = 1.0 - far_depth;
    let near_h = v.view_from_clip * vec4<f32>(ndc, near_depth, 1.0);
    let dir_view = near_h.xyz / near_h.w;
    let m = mat3x3<f32>(v.world_from_view[0].xyz, v.world_from_view[1].xyz, v.world_from_view[2].xyz);
    var out: PixelRay;
    out.dir = normalize(m * dir_view);
    out.distance = -1.0;
    out.depth_to_distance = length(m * dir_view) / max(-dir_view.z, 1.0e-30);
    let cos_axis = clamp(-dir_view.z / length(dir_view), 0.0, 1.0);
    out.footprint = cos_axis * vs_sqrt(cos_axis);
    if (depth != far_depth) {
        let p = v.view_from_clip * vec4<f32>(ndc, depth, 1.0);
        // Behind the far end (w of the wrong sign or zero) reads as sky too.
        if (p.w * near_h.w > 0.0) {
            out.distance = length(m * (p.xyz / p.w));
        }
    }
    return out;
}

// The fullscreen triangle of the passes that cover their target; uv (0, 0) at the top left.
struct Fullscreen {
    @builtin(position) position: vec4<f32>,
    @location(0) uv: vec2<f32>,
}

@vertex
fn vs_fullscreen(@builtin(vertex_index) i: u32) -> Fullscreen {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    var out: Fullscreen;
    out.position = vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
    out.uv = vec2<f32>(uv.x, 1.0 - uv.y);
    return out;
}
