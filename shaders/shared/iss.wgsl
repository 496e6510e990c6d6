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

// ---- Spot lights: the cone-limited term ----------------------------------------------------
//
// Only the medium inside a spot's cone scatters, so E(P) is the hemisphere integral of the
// airlight of the part of each ray that lies inside the cone. Directions ω leaving P are taken
// about l, the direction to the light: ω = cos γ·l + sin γ·(cos φ·e1 + sin φ·e2). The ray at
// (γ, φ) lies in the half-plane through the line PL at angle φ, and the cone meets that
// half-plane in a wedge of directions from the apex, β ∈ [β1(φ), β2(φ)], β measured from the
// direction apex → P (a cone of rays from the apex meets a half-plane bounded by a line through
// the apex in such a wedge, in closed form). A point of the ray seen from the apex at angle β
// scatters at the angle 2ξ = γ + β, so the in-cone part of the ray is ξ ∈ [(γ + β1)/2,
// min((γ + β2)/2, π/2)] and, in units of the point light's scale σs·I0·e^{−σt·D}/D,
//
//   G_cone = ∫dφ ∫dγ (ω·n)₊ · 2∫_{ξ range} p(cos 2ξ)·exp(−σt·D·sin γ·(tan ξ − tan(γ/2))) dξ
//
// (the point light's G has β1 = 0, β2 = π). Every limit is closed-form, so the integrand is
// smooth on each piece: φ by the periodic trapezoid rule (16 nodes, gathered where the wedge's
// far end rises steeply when P is near the cone's surface) when every half-plane meets the cone
// (P inside it or behind the light), else by 8-point Gauss–Legendre over the arc of
// half-planes that meet it (φ = φa + w·sin t, which smooths the square-root ends; two halves of
// 8 points); γ by 4-point Gauss–Legendre between the limits of ω·n > 0 and the wedge, split
// where the range of ξ reaches π/2 and at the width of the glow towards the light (1/(σt·D), or
// a forward phase peak's); ξ by 3-point Gauss–Legendre, split where the attenuation along the
// ray is steep. About 16 × 12 × 3 phase evaluations a point: a renderer evaluates it on a
// lattice of pixels and interpolates (volshadow's composite does; see CompositeNode).

// The phase function's lobes (per-channel weights, each summing to 1 over the lobes, and the
// Henyey–Greenstein g), as `volshadow::nodes::IssPhase` writes them.
struct VolshadowIssPhase {
    w_iso: vec4<f32>,
    w_rayleigh: vec4<f32>,
    w_hg: vec4<f32>,
    w_hazy: vec4<f32>,
    w_murky: vec4<f32>,
    hg_g: f32,
    pad0: f32,
    pad1: f32,
    pad2: f32,
}

const VOLSHADOW_ISS_PI: f32 = 3.14159265358979;
const VOLSHADOW_ISS_HALF_PI: f32 = 1.5707963267948966;

// Gauss–Legendre rules on [−1, 1] of 2, 3, 4 and 8 points, one after another: the n-point
// rule's node k is VOLSHADOW_ISS_GL[o + k] (x, w), o = volshadow_iss_gl_offset(n).
const VOLSHADOW_ISS_GL = array<vec2<f32>, 17>(
    vec2<f32>(-0.5773502691896258, 1.0), vec2<f32>(0.5773502691896258, 1.0),
    vec2<f32>(-0.7745966692414834, 0.5555555555555556), vec2<f32>(0.0, 0.8888888888888888),
    vec2<f32>(0.7745966692414834, 0.5555555555555556),
    vec2<f32>(-0.8611363115940526, 0.3478548451374538), vec2<f32>(-0.3399810435848563, 0.6521451548625461),
    vec2<f32>(0.3399810435848563, 0.6521451548625461), vec2<f32>(0.8611363115940526, 0.3478548451374538),
    vec2<f32>(-0.9602898564975363, 0.1012285362903763), vec2<f32>(-0.7966664774136267, 0.2223810344533745),
    vec2<f32>(-0.5255324099163290, 0.3137066458778873), vec2<f32>(-0.1834346424956498, 0.3626837833783620),
    vec2<f32>(0.1834346424956498, 0.3626837833783620), vec2<f32>(0.5255324099163290, 0.3137066458778873),
    vec2<f32>(0.7966664774136267, 0.2223810344533745), vec2<f32>(0.9602898564975363, 0.1012285362903763),
);

fn volshadow_iss_gl_offset(n: u32) -> u32 {
    return select(select(select(9u, 5u, n == 4u), 2u, n == 3u), 0u, n == 2u);
}

// The spot term's quadrature orders: nodes along the ray (ξ, per piece), across the wedge of
// rays (γ, per piece), half-planes about the line to the light (φ) when all meet the cone, and
// per half of the arc of half-planes that meet it otherwise.
const VOLSHADOW_ISS_XI_N: u32 = 3u;
const VOLSHADOW_ISS_GAMMA_N: u32 = 4u;
const VOLSHADOW_ISS_PHI_N: u32 = 16u;
const VOLSHADOW_ISS_ARC_N: u32 = 8u;

// The phase function at scattering angle θ from 1 − cos θ and 1 + cos θ (no cancellation in
// a forward peak), per channel.
fn volshadow_iss_phase(ph: VolshadowIssPhase, one_minus: f32, one_plus: f32) -> vec3<f32> {
    let inv4pi = 1.0 / (4.0 * VOLSHADOW_ISS_PI);
    let mu = 0.5 * (one_plus - one_minus);
    var p = ph.w_iso.xyz * inv4pi + ph.w_rayleigh.xyz * (3.0 / (16.0 * VOLSHADOW_ISS_PI)) * (1.0 + mu * mu);
    if (any(ph.w_hg.xyz != vec3<f32>(0.0))) {
        let g = ph.hg_g;
        // 1 + g² − 2gμ as a sum of non-negative terms for either sign of g.
        let denom = select((1.0 - g) * (1.0 - g) + 2.0 * g * one_minus,
                           (1.0 + g) * (1.0 + g) - 2.0 * g * one_plus, g < 0.0);
        p += ph.w_hg.xyz * (1.0 - g * g) * inv4pi / (denom * vs_sqrt(denom));
    }
    let h2 = 0.25 * one_plus * one_plus;
    let h8 = h2 * h2 * h2 * h2;
    p += ph.w_hazy.xyz * (1.0 + 9.0 * h8) / (8.0 * VOLSHADOW_ISS_PI);
    let h32 = h8 * h8 * h8 * h8;
    p += ph.w_murky.xyz * 33.0 * (1.0 + 50.0 * h32) / (332.0 * VOLSHADOW_ISS_PI);
    return p;
}

// The angular width of the phase function's sharpest forward peak (1 where it has none).
fn volshadow_iss_peak(ph: VolshadowIssPhase) -> f32 {
    var w = 1.0;
    if (any(ph.w_hg.xyz != vec3<f32>(0.0)) && ph.hg_g > 0.0) {
        w = min(w, 1.0 - ph.hg_g);
    }
    if (any(ph.w_hazy.xyz != vec3<f32>(0.0))) {
        w = min(w, 0.4);
    }
    if (any(ph.w_murky.xyz != vec3<f32>(0.0))) {
        w = min(w, 0.2);
    }
    return max(w, 1.0e-3);
}

// cos and sin of x ∈ [−π/2, π/2] (relative precision of the sine near 0).
fn volshadow_iss_cs(x: f32) -> vec2<f32> {
    return vec2<f32>(vs_cos_poly(x), vs_sin_poly(x));
}

// 4-point Gauss–Legendre of the ξ integrand over s = ξ − γ/2 ∈ [a, b] (`rest` = (π − γ)/2).
fn volshadow_iss_xi_piece(ph: VolshadowIssPhase, tau: vec3<f32>, sin_g: f32, half_c: f32,
                          rest: f32, a: f32, b: f32) -> vec3<f32> {
    let h = 0.5 * (b - a);
    let m = 0.5 * (a + b);
    var acc = vec3<f32>(0.0);
    let o = volshadow_iss_gl_offset(VOLSHADOW_ISS_XI_N);
    for (var k = 0u; k < VOLSHADOW_ISS_XI_N; k++) {
        let node = VOLSHADOW_ISS_GL[o + k];
        let s = m + h * node.x;
        // The complement π/2 − ξ = (π − γ)/2 − s keeps cos ξ's relative precision as ξ → π/2.
        let comp = max(rest - s, 0.0);
        let cos_xi = vs_sin_poly(comp);
        let sin_xi = vs_cos_poly(comp);
        // tan ξ − tan(γ/2) = sin(ξ − γ/2)/(cos ξ·cos(γ/2)).
        let r = min(vs_sin_poly(s) / max(cos_xi * half_c, 1.0e-30), 1.0e30);
        let p = volshadow_iss_phase(ph, 2.0 * sin_xi * sin_xi, 2.0 * cos_xi * cos_xi);
        acc += node.y * p * vs_exp3(-tau * (sin_g * r));
    }
    return h * acc;
}

// 2∫ p(cos 2ξ)·exp(−τ·sin γ·(tan ξ − tan(γ/2))) dξ over ξ ∈ [γ/2 + lo/2, γ/2 + hi/2]
// (`lo`, `hi` ≤ π − γ the wedge's β limits), per channel; `sin_g` = sin γ, `half_c` =
// cos(γ/2). The exponent falls at the rate λ = τ·sin γ/cos²ξ at the start; where the range
// spans more than one 1/λ it is split at 1/λ and 4/λ from the start (the decay resolved).
fn volshadow_iss_xi(ph: VolshadowIssPhase, tau: vec3<f32>, gamma: f32, sin_g: f32, half_c: f32,
                    lo: f32, hi: f32) -> vec3<f32> {
    let a = 0.5 * lo;
    let b = 0.5 * hi;
    let rest = 0.5 * (VOLSHADOW_ISS_PI - gamma);
    let cos0 = vs_sin_poly(max(rest - a, 0.0));
    let rate = max(max(tau.x, tau.y), tau.z) * sin_g / max(cos0 * cos0, 1.0e-30);
    let k1 = min(a + 1.0 / max(rate, 1.0e-30), b);
    let k2 = min(a + 4.0 / max(rate, 1.0e-30), b);
    var acc = volshadow_iss_xi_piece(ph, tau, sin_g, half_c, rest, a, k1);
    if (k1 < b) {
        acc += volshadow_iss_xi_piece(ph, tau, sin_g, half_c, rest, k1, k2);
    }
    if (k2 < b) {
        acc += volshadow_iss_xi_piece(ph, tau, sin_g, half_c, rest, k2, b);
    }
    return 2.0 * acc;
}

// ∫ over γ ∈ [a, b] of (ω·n)₊ times the wedge [b1, b2]'s ξ integral, 4-point Gauss–Legendre;
// ω·n = ca·cos γ + sc·sin γ.
fn volshadow_iss_gamma(ph: VolshadowIssPhase, tau: vec3<f32>, a: f32, b: f32, ca: f32, sc: f32,
                       b1: f32, b2: f32) -> vec3<f32> {
    if (!(b > a)) {
        return vec3<f32>(0.0);
    }
    let h = 0.5 * (b - a);
    let m = 0.5 * (a + b);
    var acc = vec3<f32>(0.0);
    let o = volshadow_iss_gl_offset(VOLSHADOW_ISS_GAMMA_N);
    for (var k = 0u; k < VOLSHADOW_ISS_GAMMA_N; k++) {
        let node = VOLSHADOW_ISS_GL[o + k];
        let g = m + h * node.x;
        let cg = vs_cos_sin_pi(g);
        let cos_n = ca * cg.x + sc * cg.y;
        // cos(γ/2), through the complement past π/2 (relative precision as γ → π).
        let half_c = select(vs_cos_poly(0.5 * g), vs_sin_poly(0.5 * (VOLSHADOW_ISS_PI - g)), g > VOLSHADOW_ISS_HALF_PI);
        let hi = min(b2, VOLSHADOW_ISS_PI - g);
        if (cos_n > 0.0 && hi > b1) {
            acc += node.y * cos_n
                 * volshadow_iss_xi(ph, tau, g, cg.y, half_c, b1, hi);
        }
    }
    return h * acc;
}

// The γ integral of one half-plane φ: `ae` = axis·e_φ, `cf` = cos φ.
fn volshadow_iss_half_plane(ph: VolshadowIssPhase, tau: vec3<f32>, near0: f32, ca: f32, sa: f32,
                            ap: f32, ae: f32, cf: f32, c: f32) -> vec3<f32> {
    // The wedge: axis·u(β) = ap·cos β + ae·sin β = R·cos(β − β0) ≥ c.
    let r2c2 = ap * ap + ae * ae - c * c;
    if (!(r2c2 > 0.0)) {
        return vec3<f32>(0.0);
    }
    let beta0 = vs_atan2_poly(ae, ap);
    let delta = vs_atan2_poly(vs_sqrt(r2c2), c);
    let b1 = max(beta0 - delta, 0.0);
    let b2 = min(beta0 + delta, VOLSHADOW_ISS_PI);
    if (!(b2 > b1)) {
        return vec3<f32>(0.0);
    }
    // ω·n = ca·cos γ + sc·sin γ > 0 on (γn − π/2, γn + π/2), γn = atan2(sc, ca); beyond
    // γ = π − b1 the ray misses the wedge.
    let sc = sa * cf;
    // (γn ∈ [−π, π]; below −π/2 the interval wraps round to (γn + 3π/2, π].)
    let gn = vs_atan2_poly(sc, ca);
    var lo = max(gn - VOLSHADOW_ISS_HALF_PI, 0.0);
    var hi = min(gn + VOLSHADOW_ISS_HALF_PI, VOLSHADOW_ISS_PI);
    if (gn < -VOLSHADOW_ISS_HALF_PI) {
        lo = gn + 3.0 * VOLSHADOW_ISS_HALF_PI;
        hi = VOLSHADOW_ISS_PI;
    }
    hi = min(hi, VOLSHADOW_ISS_PI - b1);
    // Breakpoints: where ξ's range reaches π/2 (γ = π − b2) and the glow's width.
    let k0 = clamp(min(near0, VOLSHADOW_ISS_PI - b2), lo, hi);
    let k1 = clamp(max(near0, VOLSHADOW_ISS_PI - b2), lo, hi);
    return volshadow_iss_gamma(ph, tau, lo, k0, ca, sc, b1, b2)
         + volshadow_iss_gamma(ph, tau, k0, k1, ca, sc, b1, b2)
         + volshadow_iss_gamma(ph, tau, k1, hi, ca, sc, b1, b2);
}

// The cone-limited G per channel (the spot's E(P) over the point light's scale), for the unit
// direction `to_p` from the apex to P, a unit normal `nn`, the cone's unit axis and cos(half
// apex angle) `c`, and τ = σt·D per channel.
fn volshadow_iss_cone_g(ph: VolshadowIssPhase, tau: vec3<f32>, to_p: vec3<f32>, nn: vec3<f32>,
                        axis: vec3<f32>, c: f32) -> vec3<f32> {
    let l = -to_p;
    let ca = clamp(dot(nn, l), -1.0, 1.0);
    let perp = nn - l * ca;
    let sa = length(perp);
    // e1: n's part across l (any normal to l when n is along it).
    var e1 = perp / max(sa, 1.0e-30);
    if (!(sa > 1.0e-6)) {
        let t = select(vec3<f32>(0.0, 1.0, 0.0), vec3<f32>(1.0, 0.0, 0.0), abs(l.x) < 0.9);
        e1 = normalize(t - l * dot(t, l));
    }
    let e2 = cross(l, e1);
    let ap = dot(axis, to_p);
    let a1 = dot(axis, e1);
    let a2 = dot(axis, e2);
    let near0 = min(1.0 / max(max(tau.x, tau.y), max(tau.z, 1.0e-30)), volshadow_iss_peak(ph));
    var acc = vec3<f32>(0.0);
    let big_a = length(vec2<f32>(a1, a2));
    if (abs(ap) >= c) {
        // P inside the cone or behind the light: every half-plane meets the cone. Near the
        // cone's surface (P an angle ε inside it, half apex angle θ) the wedge's far end rises
        // from about ε to about 2θ over a width of about ε/θ in φ, at φa ± π/2 (φa the axis's
        // direction across l): there the nodes are gathered by the periodic map
        // φ = ψ − (α/2)·sin 2(ψ − φa − π/2), whose node spacing is (1 − α) times the plain
        // rule's at those two places, α chosen so that it resolves the width.
        let step = 2.0 * VOLSHADOW_ISS_PI / f32(VOLSHADOW_ISS_PHI_N);
        var alpha = 0.0;
        if (ap > 0.0) {
            let theta = vs_atan2_poly(vs_sqrt(max((1.0 - c) * (1.0 + c), 0.0)), c);
            let eps = max(theta - vs_atan2_poly(big_a, ap), 0.0);
            alpha = clamp(1.0 - eps / max(2.0 * step * theta, 1.0e-30), 0.0, 0.9);
        }
        let centre = vs_atan2_poly(a2, a1) + VOLSHADOW_ISS_HALF_PI;
        for (var j = 0u; j < VOLSHADOW_ISS_PHI_N; j++) {
            let psi = (f32(j) + 0.5) * step;
            // 2(ψ − centre) reduced to [−π, π] for the polynomial sine and cosine.
            var u2 = 2.0 * (psi - centre);
            u2 -= 2.0 * VOLSHADOW_ISS_PI * round(u2 / (2.0 * VOLSHADOW_ISS_PI));
            let cs2 = vs_cos_sin_pi(abs(u2));
            let f = psi - 0.5 * alpha * sign(u2) * cs2.y;
            let cs = vec2<f32>(cos(f), sin(f));
            acc += (1.0 - alpha * cs2.x)
                 * volshadow_iss_half_plane(ph, tau, near0, ca, sa, ap, a1 * cs.x + a2 * cs.y, cs.x, c);
        }
        return acc * step;
    }
    // Outside: the half-planes with axis·e_φ > s, s = √(c² − ap²), an arc about φa.
    let s = vs_sqrt(max((c - ap) * (c + ap), 0.0));
    if (!(big_a > s)) {
        return vec3<f32>(0.0);
    }
    let w = vs_atan2_poly(vs_sqrt(max((big_a - s) * (big_a + s), 0.0)), s);
    let ca1 = a1 / big_a;
    let sa1 = a2 / big_a;
    // t ∈ [−π/2, π/2] in two halves of 8-point Gauss–Legendre.
    let o = volshadow_iss_gl_offset(VOLSHADOW_ISS_ARC_N);
    for (var k = 0u; k < 2u * VOLSHADOW_ISS_ARC_N; k++) {
        let node = VOLSHADOW_ISS_GL[o + k % VOLSHADOW_ISS_ARC_N];
        let t = (node.x + select(-1.0, 1.0, k >= VOLSHADOW_ISS_ARC_N)) * (0.5 * VOLSHADOW_ISS_HALF_PI);
        let st = volshadow_iss_cs(t);
        let psi = volshadow_iss_cs(w * st.y);  // φ − φa = w·sin t
        let cf = ca1 * psi.x - sa1 * psi.y;      // cos φ
        acc += node.y * w * st.x
             * volshadow_iss_half_plane(ph, tau, near0, ca, sa, ap, big_a * psi.x, cf, c);
    }
    return acc * (0.5 * VOLSHADOW_ISS_HALF_PI);
}

// E(P) per RGB channel from a spot light: as `volshadow_iss`, but only the medium inside the
// cone (apex `light_pos`, unit `axis`, `cos_half` the cosine of half the apex angle, in (0, 1])
// scatters, with the phase function `phase` (`volshadow::nodes::IssPhase`). No table: the term
// is a fixed quadrature over the hemisphere (see above), finite everywhere (1e30 at the apex).
fn volshadow_iss_spot(phase: VolshadowIssPhase, p: vec3<f32>, n: vec3<f32>, light_pos: vec3<f32>,
                      axis: vec3<f32>, cos_half: f32, intensity: vec3<f32>, sigma_s: vec3<f32>,
                      sigma_t: vec3<f32>) -> vec3<f32> {
    let from_light = p - light_pos;
    let d = length(from_light);
    let nl = length(n);
    let al = length(axis);
    if (!(nl > 0.0) || !(al > 0.0)) {
        return vec3<f32>(0.0);
    }
    let scale = vs_exp3(vs_log3(intensity) + vs_log3(sigma_s) - sigma_t * d) / max(d, 1.0e-30);
    if (!(d > 0.0)) {
        return min(scale, vec3<f32>(VOLSHADOW_ISS_MAX));
    }
    let g = volshadow_iss_cone_g(phase, sigma_t * d, from_light / d, n / nl, axis / al,
                                 clamp(cos_half, 0.0, 1.0));
    return min(scale * g, vec3<f32>(VOLSHADOW_ISS_MAX));
}
