// A point light's answers to what the passes ask of a light (`light.wgsl` chooses them by
// `LIGHT`): its airlight ray, T along the ray from the F′ table, and the normalised scattering
// angle s of a distance x and back. A spot light is a point light limited to its cone
// (`light/spot.wgsl`) and answers the same here.
#import prelude.wgsl

fn point_air_ray(a: Airlight, ray: PixelRay) -> AirRay {
    let dir = ray.dir;
    let to_light = a.light_pos - a.eye;
    let d = a.distance;
    var r: AirRay;
    r.c = length(cross(dir, to_light));
    r.dotv = dot(dir, to_light);
    // Both angles from their own well-conditioned atan2 (relative precision to the last few
    // bits whichever is small): γ near π (the light behind the eye) makes w small, and the
    // table's integrand divides by the sines of fractions of w.
    r.gamma = vs_atan2_poly(r.c, r.dotv);
    r.w = vs_atan2_poly(r.c, -r.dotv);
    r.sin_half_gamma = vs_sin_poly(0.5 * r.gamma);
    // The singular 1/h of form (2): clamped by the pixel's footprint at the light when looking
    // towards it (a point light seen through fog is infinitely bright at γ = 0); towards γ = π
    // the ratio w / sin γ tends to 1 and needs no clamp.
    var sin_gamma = r.c / d;
    var ratio = 1.0;
    if (r.gamma < 0.5 * PI) {
        sin_gamma = max(sin_gamma, a.pixel_radius * ray.footprint);
        ratio = r.w / sin_gamma;
    } else if (sin_gamma > 1.0e-30) {
        ratio = r.w / sin_gamma;
    }
    // In log space, every factor in the one exponent: at σt·D = 100, exp(−σt D) = 4e-44 is
    // below f32's normal range (a GPU may flush it to zero) while I0 · exp(−σt D) · w / (D sin γ)
    // may still be a visible radiance. log(0) = −inf gives exp = 0, no NaN.
    r.prefactor = vs_exp3(vs_log3(a.intensity) + vs_log3(a.sigma_s) - a.sigma_t * d
                          + vec3<f32>(vs_log(ratio / d)));
    return r;
}

// T(γ, s): the table entry at or below s (rows interpolated in γ), plus the rest of the cell
// integrated exactly at this ray's own γ by 3-point Gauss–Legendre. Interpolating T along s
// would be wrong exactly where the image is brightest (steep rise near the light, optically
// deep media); the partial cell costs three integrand evaluations and removes that error.
fn point_t(table: texture_2d<f32>, a: Airlight, r: AirRay, s: f32) -> vec3<f32> {
    let n = a.table_along;
    let j = min(u32(s * f32(n - 1u)), n - 1u);
    return table_row_mix(table, a, r.gamma, j) + table_partial(a, r, s, j);
}

// The tail is the entry at or below s less the same partial cell the head adds: head + tail
// is the row's total, and the cell's rounding stays within the cell.
fn point_tt(table: texture_2d<f32>, a: Airlight, r: AirRay, s: f32) -> TT {
    let n = a.table_along;
    let j = min(u32(s * f32(n - 1u)), n - 1u);
    let partial = table_partial(a, r, s, j);
    let head = table_row_mix(table, a, r.gamma, j) + partial;
    let tail = max(table_row_mix(table, a, r.gamma, n + j) - partial, vec3<f32>(0.0));
    return TT(head, tail);
}

// Normalised scattering angle s of the point at distance x along the ray (the sky, x = FAR,
// is s = 1).
fn point_s_of_x(a: Airlight, r: AirRay, x: f32) -> f32 {
    if (x >= FAR) {
        return 1.0;
    }
    return scattering_s(a, r, x);
}

// Distance along the ray of the point with normalised scattering angle s (law of sines in the
// eye–point–light triangle: x = D sin δ / sin β, δ = s w, β = (1 − s) w). Each sine is taken
// of the angle or its supplement (sin β = sin(γ + δ), sin δ = sin(γ + β)), whichever is smaller,
// by `vs_sin_poly`: a small sine keeps its relative precision.
fn point_x_of_s(a: Airlight, r: AirRay, s: f32) -> f32 {
    let sc = min(s, 1.0 - 1.0e-6);
    let beta = (1.0 - sc) * r.w;
    let delta = sc * r.w;
    let sin_beta = sin_supplement(beta, r.gamma + delta);
    return a.distance * sin_supplement(delta, r.gamma + beta) / max(sin_beta, 1.0e-30);
}

// The lit support in s: the whole ray, [0, s(x_end)].
fn point_support_s(a: Airlight, r: AirRay, x_end: f32) -> SupportS {
    var out: SupportS;
    out.count = 1u;
    out.s[0] = vec2<f32>(0.0, point_s_of_x(a, r, x_end));
    return out;
}

// Unshadowed T over the lit support: from the eye, where T = 0.
fn point_unshadowed_t(table: texture_2d<f32>, a: Airlight, r: AirRay, sup: SupportS) -> vec3<f32> {
    var t = vec3<f32>(0.0);
    for (var i = 0u; i < sup.count; i++) {
        t += point_t(table, a, r, sup.s[i].y);
    }
    return t;
}
