#import prelude.wgsl
#import iss.wgsl
// Indirect single scattering table builder (appended to the prelude and shaders/shared/iss.wgsl):
// one invocation per entry (τ_i, α_j) writes ln G(τ, α) per RGB channel, where
//
//   G(τ, α) = ∫₀^π b(τ, γ) · W(α, γ) dγ,
//   b(τ, γ) = 2 ∫_{γ/2}^{π/2} p(cos 2ξ) · exp(−2τ·sin(γ/2)·sin(ξ − γ/2) / cos ξ) dξ,
//   W(α, γ) = ∫₀^{2π} (cos α cos γ + sin α sin γ cos φ)₊ dφ   (closed form),
//
// γ the angle between a ray leaving the surface and the direction to the light. Both integrals
// are composite 8-point Gauss–Legendre on segments graded geometrically towards the places
// where the integrand changes over short scales: γ → 0 (the glow towards the light, width
// ~1/τ, and a forward phase peak), γ → π (a backward peak), the kinks of W at
// γ = |π/2 − α| and π − |π/2 − α|, and, inside b, the start of the ray (decay over 1/(2τ·tan(γ/2)))
// and the phase peaks.

@group(0) @binding(0) var<storage, read> air: Airlight;
@group(0) @binding(1) var table_out: texture_storage_2d<rgba32float, write>;

const ISS_GL_X = array<f32, 4>(0.1834346424956498, 0.5255324099163290, 0.7966664774136267, 0.9602898564975363);
const ISS_GL_W = array<f32, 4>(0.3626837833783620, 0.3137066458778873, 0.2223810344533745, 0.1012285362903763);
// ln G is stored no lower than this (G underflowing would give −inf, and NaN in a blend).
const ISS_LN_FLOOR: f32 = -80.0;

// Angular half-widths (in ξ, half the scattering angle) of the forward and backward phase
// peaks of this medium's lobes: 1 where the phase function has none.
fn iss_peak_widths() -> vec2<f32> {
    var fwd = 1.0;
    var back = 1.0;
    if (any(air.w_hg.xyz != vec3<f32>(0.0))) {
        let g = air.hg_g;
        if (g > 0.0) {
            fwd = min(fwd, 0.5 * (1.0 - g));
        } else {
            back = min(back, 0.5 * (1.0 + g));
        }
    }
    if (any(air.w_hazy.xyz != vec3<f32>(0.0))) {
        fwd = min(fwd, 0.2);
    }
    if (any(air.w_murky.xyz != vec3<f32>(0.0))) {
        fwd = min(fwd, 0.1);
    }
    return vec2<f32>(max(fwd, 1.0e-3), max(back, 1.0e-3));
}

// Geometric grading levels for a segment of length `len` whose integrand changes over `scale`
// at one end: enough halvings that the smallest piece is an eighth of the scale.
fn iss_levels(len: f32, scale: f32) -> u32 {
    return u32(clamp(ceil(vs_log2(max(len / scale, 1.0))) + 3.0, 1.0, 18.0));
}

// The integrand of b in s = ξ − γ/2 ∈ [0, width], width = (π − γ)/2, all channels.
fn iss_b_integrand(s: f32, tau: vec3<f32>, half_gamma: f32, width: f32) -> vec3<f32> {
    var sin_xi: f32;
    var cos_xi: f32;
    if (half_gamma + s <= 0.25 * PI) {
        sin_xi = vs_sin_poly(half_gamma + s);
        cos_xi = vs_cos_poly(half_gamma + s);
    } else {
        // cos ξ = sin(width − s) keeps its relative precision as ξ → π/2.
        sin_xi = vs_cos_poly(width - s);
        cos_xi = vs_sin_poly(width - s);
    }
    // Small sines by `vs_sin_poly` (relative precision; WGSL's sin is absolute 2^-11).
    let k = 2.0 * vs_sin_poly(half_gamma) * vs_sin_poly(s) / max(cos_xi, 1.0e-30);
    return 2.0 * phase(air, 2.0 * sin_xi * sin_xi, 2.0 * cos_xi * cos_xi) * vs_exp3(-tau * min(k, 1.0e30));
}

// ∫ over [a, b] of the b integrand, 8-point Gauss–Legendre.
fn iss_b_segment(a: f32, b: f32, tau: vec3<f32>, half_gamma: f32, width: f32) -> vec3<f32> {
    let h = 0.5 * (b - a);
    let m = 0.5 * (a + b);
    var acc = vec3<f32>(0.0);
    for (var k = 0u; k < 4u; k++) {
        let o = h * ISS_GL_X[k];
        acc += ISS_GL_W[k] * (iss_b_integrand(m - o, tau, half_gamma, width)
                            + iss_b_integrand(m + o, tau, half_gamma, width));
    }
    return acc * h;
}

// b(τ, γ) per channel (τ per channel; the largest sets the grading).
fn iss_b(tau: vec3<f32>, gamma: f32, widths: vec2<f32>) -> vec3<f32> {
    let half_gamma = 0.5 * gamma;
    let width = 0.5 * PI - half_gamma;
    if (width <= 0.0) {
        return vec3<f32>(0.0);
    }
    let t = max(max(tau.x, tau.y), tau.z);
    // Decay rate at the start, 2τ·tan(γ/2); the forward peak sits at s = −γ/2.
    let rate = 2.0 * t * vs_tan_poly(min(half_gamma, 0.5 * PI - 1.0e-6));
    let start_scale = min(1.0 / max(rate, 1.0e-30), max(half_gamma, widths.x));
    let mid = 0.5 * width;
    var acc = vec3<f32>(0.0);
    // First half, graded towards s = 0.
    let n0 = iss_levels(mid, start_scale);
    var hi = mid;
    for (var l = 0u; l < n0; l++) {
        let lo = select(0.5 * hi, 0.0, l + 1u == n0);
        acc += iss_b_segment(lo, hi, tau, half_gamma, width);
        hi = lo;
    }
    // Second half, graded towards s = width (ξ = π/2: the backward peak).
    let n1 = iss_levels(mid, widths.y);
    var lo = mid;
    for (var l = 0u; l < n1; l++) {
        let up = select(0.5 * (lo + width), width, l + 1u == n1);
        acc += iss_b_segment(lo, up, tau, half_gamma, width);
        lo = up;
    }
    return acc;
}

// W(α, γ) = ∫₀^{2π} (a + c cos φ)₊ dφ, a = cos α cos γ, c = sin α sin γ ≥ 0.
fn iss_w(cos_a: f32, sin_a: f32, gamma: f32) -> f32 {
    let cs = vs_cos_sin_pi(gamma);
    let a = cos_a * cs.x;
    let c = sin_a * cs.y;
    if (c <= abs(a)) {
        return 2.0 * PI * max(a, 0.0);
    }
    let phi0 = vs_acos_poly(clamp(-a / c, -1.0, 1.0));
    // c · sin φ0 = sqrt((c − a)(c + a)).
    return 2.0 * (a * phi0 + vs_sqrt(max((c - a) * (c + a), 0.0)));
}

fn iss_g_segment(a: f32, b: f32, tau: vec3<f32>, cos_a: f32, sin_a: f32, widths: vec2<f32>) -> vec3<f32> {
    let h = 0.5 * (b - a);
    let m = 0.5 * (a + b);
    var acc = vec3<f32>(0.0);
    for (var k = 0u; k < 4u; k++) {
        let o = h * ISS_GL_X[k];
        let g0 = m - o;
        let g1 = m + o;
        acc += ISS_GL_W[k] * (iss_b(tau, g0, widths) * iss_w(cos_a, sin_a, g0)
                            + iss_b(tau, g1, widths) * iss_w(cos_a, sin_a, g1));
    }
    return acc * h;
}

// ∫ over [a, b] of b·W, graded towards a over `scale_a` and towards b over `scale_b`.
fn iss_g_region(a: f32, b: f32, scale_a: f32, scale_b: f32, tau: vec3<f32>, cos_a: f32, sin_a: f32,
                widths: vec2<f32>) -> vec3<f32> {
    if (b <= a) {
        return vec3<f32>(0.0);
    }
    let mid = 0.5 * (a + b);
    var acc = vec3<f32>(0.0);
    let n0 = iss_levels(mid - a, scale_a);
    var hi = mid;
    for (var l = 0u; l < n0; l++) {
        let lo = select(0.5 * (a + hi), a, l + 1u == n0);
        acc += iss_g_segment(lo, hi, tau, cos_a, sin_a, widths);
        hi = lo;
    }
    let n1 = iss_levels(b - mid, scale_b);
    var lo = mid;
    for (var l = 0u; l < n1; l++) {
        let up = select(0.5 * (lo + b), b, l + 1u == n1);
        acc += iss_g_segment(lo, up, tau, cos_a, sin_a, widths);
        lo = up;
    }
    return acc;
}

@compute @workgroup_size(8, 8)
fn build(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n_tau = air.table_along;
    let n_alpha = air.table_across;
    if (gid.x >= n_tau || gid.y >= n_alpha) {
        return;
    }
    let u = f32(gid.x) / f32(n_tau - 1u);
    let v = f32(gid.y) / f32(n_alpha - 1u);
    let t = VOLSHADOW_ISS_TAU_MIN * vs_exp(u * vs_log(VOLSHADOW_ISS_TAU_MAX / VOLSHADOW_ISS_TAU_MIN));
    let s = VOLSHADOW_ISS_WARP + t;
    let cos_a = clamp(vs_sinh((1.0 - 2.0 * v) * vs_asinh(s)) / s, -1.0, 1.0);
    let sin_a = vs_sqrt(max((1.0 - cos_a) * (1.0 + cos_a), 0.0));
    let tau = vec3<f32>(t);
    let widths = iss_peak_widths();
    // The kinks of W: γ = e and π − e, e = |π/2 − α| = |asin(cos α)|.
    let e = abs(vs_asin_poly(cos_a));
    // Near γ = 0 the integrand changes over the glow's width ~1/τ and the forward peak's 2·w;
    // near γ = π over the backward peak's.
    let near0 = min(1.0 / t, 2.0 * widths.x);
    let nearpi = 2.0 * widths.y;
    // Each kink is a 3/2-power: grade towards it over a tenth of its region.
    var g = iss_g_region(0.0, e, near0, max(0.1 * e, 1.0e-6), tau, cos_a, sin_a, widths);
    g += iss_g_region(e, PI - e, max(near0, e), max(nearpi, e), tau, cos_a, sin_a, widths);
    g += iss_g_region(PI - e, PI, max(0.1 * e, 1.0e-6), nearpi, tau, cos_a, sin_a, widths);
    let ln_g = max(vs_log3(max(g, vec3<f32>(1.0e-37))), vec3<f32>(ISS_LN_FLOOR));
    textureStore(table_out, vec2<u32>(gid.x, gid.y), vec4<f32>(ln_g, 0.0));
}
