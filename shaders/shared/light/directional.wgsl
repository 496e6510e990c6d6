// A directional light's answers (`light.wgsl` chooses them by `LIGHT`): parallel rays, so
// the scattering angle is the same along a view ray and T is in closed form (no F′ table).
// `Airlight` holds the direction of travel d in `light_pos`, the irradiance E in `intensity`,
// and in `distance` the length L of the ray parameter s = x / (x + L).
#import prelude.wgsl

// A directional light's ray: the scattering angle θ is the same at every point, so the
// prefactor is σs·p(cos θ)·E and T(x) = ∫₀ˣ e^{−σt x'} dx' (see `directional_t`). With d the
// direction of travel, cos θ = −v·d; 1 ∓ cos θ = |v ± d|²/2 keep their relative precision.
fn directional_air_ray(a: Airlight, ray: PixelRay) -> AirRay {
    let v = ray.dir;
    let d = a.light_pos;
    var r: AirRay;
    r.gamma = 0.0;
    r.w = 1.0;
    r.sin_half_gamma = 0.0;
    r.c = 0.0;
    r.dotv = 0.0;
    let one_minus_mu = 0.5 * dot(v + d, v + d);
    let one_plus_mu = 0.5 * dot(v - d, v - d);
    r.prefactor = a.sigma_s * phase(a, one_minus_mu, one_plus_mu) * a.intensity;
    return r;
}

// (1 − e^{−z}) / z for z ≥ 0 per channel, to f32 precision: its alternating Taylor series below
// z = 1 (no cancellation, and exactly 1 at z = 0), the direct form above.
fn one_minus_exp_ratio(z: vec3<f32>) -> vec3<f32> {
    var f = vec3<f32>(1.0);
    for (var k = 11.0; k >= 2.0; k -= 1.0) {
        f = 1.0 - z / k * f;
    }
    return select(f, (1.0 - vs_exp3(-z)) / max(z, vec3<f32>(1.0e-30)), z >= vec3<f32>(1.0));
}

// A directional light's T(x) = ∫₀ˣ e^{−σt x'} dx' = (1 − e^{−σt x}) / σt per channel: x at
// σt = 0, 1/σt at x = ∞ (x = FAR), finite for any σt·x (σt·FAR may overflow to ∞: then 1/σt).
fn directional_t(a: Airlight, x: f32) -> vec3<f32> {
    let z = a.sigma_t * x;
    let small = x * one_minus_exp_ratio(min(z, vec3<f32>(1.0)));
    let large = (1.0 - vs_exp3(-z)) / max(a.sigma_t, vec3<f32>(1.0e-38));
    return select(small, large, z >= vec3<f32>(1.0));
}

// A directional light's ray parameter: s = x / (x + L) maps [0, ∞] onto [0, 1] (the sky is
// s = 1), and its inverse.
fn directional_s(a: Airlight, x: f32) -> f32 {
    if (x >= FAR) {
        return 1.0;
    }
    return x / (x + a.distance);
}

fn directional_x(a: Airlight, s: f32) -> f32 {
    if (s >= 1.0) {
        return FAR;
    }
    return min(a.distance * s / (1.0 - s), FAR);
}

// T at s both ways, as differences of heads (no table: T is in closed form).
fn directional_tt(a: Airlight, s: f32) -> TT {
    let t = directional_t(a, directional_x(a, s));
    return TT(t, -t);
}

// The lit support in s: the whole ray, [0, s(x_end)].
fn directional_support_s(a: Airlight, x_end: f32) -> SupportS {
    var out: SupportS;
    out.count = 1u;
    out.s[0] = vec2<f32>(0.0, directional_s(a, x_end));
    return out;
}

// Unshadowed T over the lit support: from the eye, where T = 0.
fn directional_unshadowed_t(a: Airlight, sup: SupportS) -> vec3<f32> {
    var t = vec3<f32>(0.0);
    for (var i = 0u; i < sup.count; i++) {
        t += directional_t(a, directional_x(a, sup.s[i].y));
    }
    return t;
}
