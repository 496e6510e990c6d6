// volshadow: indirect single scattering on Lambertian surfaces (the light a homogeneous medium
// scatters onto a surface, unshadowed, with the medium extending to infinity around it).
//
// Self-contained: paste or concatenate it into a surface shader. It reads the table built by
// `volshadow::nodes::IssTableNode` (`Rgba32Float`, read with `textureLoad`, no sampler), which
// holds ln G(τ, α) per RGB channel, and returns
//
//   E(P) = σs · I0 · exp(−σt·D) / D · G(σt·D, α)
//
// per channel, D = |light − P|, α the angle between the normal and the direction to the light.
// The added radiance of a Lambertian surface is kd · E(P) (kd = ρ/π for an albedo ρ).
//
// Table axes (node (i, j) of an N_τ × N_α table at u = i/(N_τ − 1), v = j/(N_α − 1)):
//   u = ln(τ/τ₀) / ln(τ₁/τ₀),  τ clamped to [τ₀, τ₁] = [1e-4, 200],
//   v = 1/2 − asinh(s·cos α) / (2·asinh s),  s = 4 + τ,
// which gathers the α nodes about α = π/2, where G falls over a width of about 1/τ.

const VOLSHADOW_ISS_TAU_MIN: f32 = 1.0e-4;
const VOLSHADOW_ISS_TAU_MAX: f32 = 200.0;
const VOLSHADOW_ISS_WARP: f32 = 4.0;
// Larger than any radiance returned (keeps a surface touching the light finite).
const VOLSHADOW_ISS_MAX: f32 = 1.0e30;

// Table coordinates (u, v) ∈ [0, 1]² of optical distance τ and cos α.
fn volshadow_iss_coords(tau: f32, cos_alpha: f32) -> vec2<f32> {
    let t = clamp(tau, VOLSHADOW_ISS_TAU_MIN, VOLSHADOW_ISS_TAU_MAX);
    let u = vs_log(t / VOLSHADOW_ISS_TAU_MIN) / vs_log(VOLSHADOW_ISS_TAU_MAX / VOLSHADOW_ISS_TAU_MIN);
    let s = VOLSHADOW_ISS_WARP + t;
    let v = 0.5 - vs_asinh(s * clamp(cos_alpha, -1.0, 1.0)) / (2.0 * vs_asinh(s));
    return clamp(vec2<f32>(u, v), vec2<f32>(0.0), vec2<f32>(1.0));
}

// ln G of channel `c` at table coordinates `uv`, bilinear between the four nearest nodes.
fn volshadow_iss_ln_g(table: texture_2d<f32>, uv: vec2<f32>, c: u32) -> f32 {
    let size = vec2<u32>(textureDimensions(table));
    let x = uv * vec2<f32>(size - vec2<u32>(1u));
    let i = min(vec2<u32>(x), size - vec2<u32>(2u));
    let f = clamp(x - vec2<f32>(i), vec2<f32>(0.0), vec2<f32>(1.0));
    let a = textureLoad(table, i, 0)[c];
    let b = textureLoad(table, i + vec2<u32>(1u, 0u), 0)[c];
    let d = textureLoad(table, i + vec2<u32>(0u, 1u), 0)[c];
    let e = textureLoad(table, i + vec2<u32>(1u, 1u), 0)[c];
    return mix(mix(a, b, f.x), mix(d, e, f.x), f.y);
}

// G(τ_c, α) per channel c (τ = σt·D differs per channel; so may the phase function).
fn volshadow_iss_g(table: texture_2d<f32>, tau: vec3<f32>, cos_alpha: f32) -> vec3<f32> {
    var g = vec3<f32>(0.0);
    for (var c = 0u; c < 3u; c++) {
        g[c] = vs_exp(volshadow_iss_ln_g(table, volshadow_iss_coords(tau[c], cos_alpha), c));
    }
    return g;
}

// E(P) per RGB channel: the irradiance the medium scatters onto the surface point `p` with
// normal `n` (any length) from a point light at `light_pos` of intensity `intensity`, in a
// medium with scattering `sigma_s` and extinction `sigma_t` (per channel). Multiply by the
// surface's kd for the radiance it adds. Finite everywhere (clamped to 1e30 at the light).
fn volshadow_iss(table: texture_2d<f32>, p: vec3<f32>, n: vec3<f32>, light_pos: vec3<f32>,
                 intensity: vec3<f32>, sigma_s: vec3<f32>, sigma_t: vec3<f32>) -> vec3<f32> {
    let to_light = light_pos - p;
    let d = length(to_light);
    let nl = length(n);
    if (!(nl > 0.0)) {
        return vec3<f32>(0.0);
    }
    let cos_alpha = select(1.0, dot(n, to_light) / (nl * d), d > 0.0);
    let g = volshadow_iss_g(table, sigma_t * d, cos_alpha);
    // In log space: exp(−σt·D) underflows f32 where I0·exp(−σt·D) may still be visible;
    // log(0) = −inf gives 0, never NaN.
    let scale = vs_exp3(vs_log3(intensity) + vs_log3(sigma_s) - sigma_t * d) / max(d, 1.0e-30);
    return min(scale * g, vec3<f32>(VOLSHADOW_ISS_MAX));
}
