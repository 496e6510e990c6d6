//! Indirect single scattering: the light the medium scatters onto a Lambertian surface.
//!
//! A surface point `P` with unit normal `n` and diffuse albedo `kd` receives, besides the
//! attenuated direct light, the airlight of every ray leaving it into its hemisphere (Biri,
//! Arquès and Michelin, "Real Time Rendering of Atmospheric Scattering and Volumetric Shadows",
//! 2006, §III.C, after Sun, Ramamoorthi, Narasimhan and Nayar, "A Practical Analytic Single
//! Scattering Model for Real Time Rendering", 2005), with the medium assumed to extend to
//! infinity along each ray and no shadowing:
//!
//! ```text
//! L_iss(P) = kd · E(P),   E(P) = ∫_{ω·n > 0} L_ss(P, ω, ∞) · (ω·n) dω
//! ```
//!
//! [`surface_inscatter`] is `E(P)` per RGB channel; the caller multiplies it by `kd` (and
//! `kd/π` is *not* implied: `kd` is the reflectivity of the paper's eq. 9, so a white
//! Lambertian surface of radiance `L = (ρ/π)·E` has `kd = ρ/π`).
//!
//! # Reduction to two numbers (point light)
//!
//! Let `D = |L − P|` (light at `L`, intensity `I0`), `l = (L − P)/D`, `γ` the angle between
//! `ω` and `l`, and `α` the angle between `n` and `l`. The closed form of
//! [`inscatter_closed_form`] along the ray from `P` (distance of
//! the light from its line `h = D·sin γ`) is, with `ds = ∞`,
//!
//! ```text
//! L_ss(P, ω, ∞) = (2·σs·I0·e^{−σt·D} / (D·sin γ)) · ∫_{γ/2}^{π/2} p(cos 2ξ) · e^{−τ·sin γ·(tan ξ − tan(γ/2))} dξ
//! ```
//!
//! where `τ = σt·D`: every length enters only through `σt·h = τ·sin γ`. So
//! `L_ss = (σs·I0·e^{−τ}/D) · b(τ, γ) / sin γ` with `b` the bounded factor
//! `b(τ, γ) = 2∫_{γ/2}^{π/2} p(cos 2ξ)·e^{−τ·sin γ·(tan ξ − tan(γ/2))} dξ ∈ (0, 2∫p]`.
//! In spherical coordinates `(γ, φ)` about `l`, `dω = sin γ dγ dφ` cancels the `1/sin γ`
//! (the integrable singularity towards the light), and with `ω·n = cos α cos γ + sin α sin γ
//! cos φ` the integral over `φ` of its positive part is closed-form:
//!
//! ```text
//! E(P) = scale · G(τ, α),   scale = σs·I0·e^{−σt·D} / D,
//! G(τ, α) = ∫₀^π b(τ, γ) · W(α, γ) dγ,
//! W(α, γ) = ∫₀^{2π} (a + c·cos φ)₊ dφ = 2·(a·φ₀ + c·sin φ₀),   a = cos α cos γ,  c = sin α sin γ,
//! ```
//!
//! with `φ₀ = acos(−a/c)` where `c > |a|`, `W = 2π·max(a, 0)` otherwise. `G` depends only on
//! `τ`, `α` and the phase function, per channel (`τ` and, for Hoffman–Preetham, `p` differ per
//! channel): [`surface_inscatter_normalised`] evaluates it and [`surface_inscatter_scale`] the
//! scale. `e^{−τ}` is in the scale (every path from the light to `P` is at least `D` long),
//! so `G` stays of order one: `G → G(0, α)` as `τ → 0` and `G = O(log τ / τ)` as `τ → ∞`.
//! `G(τ, α) − G(τ, π − α) = cos α · ∫₀^π b(τ, γ)·2π cos γ dγ` (the two hemispheres make the
//! whole sphere with `ω·n` signed); for an isotropic medium and `τ = 0`,
//! `b = (π − γ)/(4π)` and that difference is exactly `cos α`, with `G(0, 0) = π/4 + 1/2`.
//!
//! `G` is smooth in `log τ` and in `α` except along `α = π/2`, where the horizon passes
//! through the peak towards the light: there `∂²G/∂α²` has a logarithmic singularity and, for
//! large `τ`, `G` drops over a width of about `1/τ` in `α`. [`iss_table_coords`] maps
//! `(τ, α)` to table coordinates that resolve it. Measured (`tests/cpu/reference_iss.rs`,
//! `table_size_study`: f32 tables, f32 bilinear, checked at every cell centre and edge
//! midpoint over `τ ∈ [1e-3, 50]`, `α ∈ [0, π]`), max relative error for isotropic / HG 0.8 /
//! Rayleigh: storing `G`, 33 × 65 nodes (`τ × α`): 1.5e-2 / 1.3e-2 / 1.4e-2; storing `ln G`,
//! 33 × 33: 3.2e-3 / 7.9e-3 / 8.0e-3, 65 × 33: 3.2e-3 / 7.6e-3 / 8.0e-3, 33 × 65: 3.1e-3 /
//! 2.6e-3 / 2.8e-3. The error is dominated by the `α` axis at large `τ` and falls as the
//! square of its spacing.
//!
//! # The reference
//!
//! [`surface_inscatter`] does not use this reduction: it integrates `L_ss·(ω·n)` by nested
//! adaptive Gauss–Kronrod quadrature, outer in `γ` (breakpoints where the visible arc changes
//! shape and on a ladder `k/τ` near the light's direction), inner in `φ` over the visible arc
//! `|φ| < φ₀`, evaluating the airlight along each world-space direction: the closed form for a
//! point light, [`inscatter`] with the cone (and texture) and no occluders
//! for a spot light, whose term is then limited to its cone.

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};

use glam::DVec3;

use super::phase::{self, Cosine};
use super::quadrature::integrate;
use super::{
    inscatter, inscatter_closed_form, unit, LightSource, MAX_BISECTIONS, RELATIVE_TOLERANCE,
};
use crate::scene::{Light, Medium, PhaseFunction};

/// Relative tolerances of the outer (`γ`) and inner (`φ`) integrals of [`surface_inscatter`]:
/// the inner one stays above the airlight's own noise (its tolerance is
/// [`RELATIVE_TOLERANCE`]), or the inner quadrature would chase it.
const OUTER_TOLERANCE: f64 = 1e-10;
const INNER_TOLERANCE: f64 = 1e-10;

/// `E(P) = ∫_{ω·n>0} L_ss(P, ω, ∞)·(ω·n) dω` per RGB channel (multiply by the albedo `kd` for
/// the radiance `L_iss`; see the [module docs](self)), from `light` (`&PointLight`,
/// `&SpotLight`, `&Light` or `&TexturedSpot`), unshadowed, by nested adaptive quadrature over
/// the hemisphere of `n` with the direction to the light on the pole.
///
/// Accuracy: within 1e-10 relative of `scale · G` (`tests/cpu/reference_iss.rs`: 2.5e-13 worst over
/// random scenes) and 2e-13 from the same integral at ten times tighter tolerances.
///
/// `n` need not be unit length. Returns zero for a zero or non-finite `n` or non-finite
/// positions, and `+∞` in the channels with `σs·I0 > 0` when `p` is the light's position.
pub fn surface_inscatter(p: DVec3, n: DVec3, medium: &Medium, light: &impl LightSource) -> DVec3 {
    surface_inscatter_to(p, n, medium, light, [OUTER_TOLERANCE, INNER_TOLERANCE])
}

/// [`surface_inscatter`] with the relative tolerances `[outer, inner]`.
pub(crate) fn surface_inscatter_to(
    p: DVec3,
    n: DVec3,
    medium: &Medium,
    light: &impl LightSource,
    [tol, inner_tol]: [f64; 2],
) -> DVec3 {
    let source = light.light();
    let to_light = match (source, source.position()) {
        // The direction towards a directional light.
        (Light::Directional(sun), _) => -sun.direction().as_dvec3(),
        (_, Some(q)) => q.as_dvec3() - p,
        (_, None) => DVec3::NAN,
    };
    let coef = medium.sigma_s().as_dvec3() * source.intensity().as_dvec3();
    let Some(n) = unit(n) else {
        return DVec3::ZERO;
    };
    if !to_light.is_finite() || coef == DVec3::ZERO {
        return DVec3::ZERO;
    }
    let Some(axis) = unit(to_light) else {
        return DVec3::from_array(
            coef.to_array()
                .map(|c| if c > 0.0 { f64::INFINITY } else { 0.0 }),
        );
    };
    let (cos_a, sin_a) = (n.dot(axis), n.cross(axis).length());
    // `e1`: `n`'s part across the axis, orthogonalised twice (with `n` nearly (anti)parallel
    // to the axis, one pass leaves round-off along it); any normal when `sin α` is round-off.
    let perp = n - axis * cos_a;
    let e1 = match unit(perp - axis * perp.dot(axis)) {
        Some(e1) if sin_a > 1e-12 => e1,
        _ => axis.any_orthonormal_vector(),
    };
    let e2 = axis.cross(e1);
    let point = match (source, light.texture()) {
        (Light::Point(point), None) => Some(point),
        _ => None,
    };
    let radiance = |w: DVec3| match &point {
        Some(point) => inscatter_closed_form(p, w, f64::INFINITY, medium, point),
        None => inscatter(p, w, f64::INFINITY, medium, light, &[]),
    };
    let taus = medium.sigma_t().as_dvec3() * to_light.length();
    let outer = |_, g: f64| {
        let (sin_g, cos_g) = g.sin_cos();
        let Some(half) = visible_arc(cos_a * cos_g, sin_a * sin_g) else {
            return DVec3::ZERO;
        };
        let inner = integrate(
            |_, f: f64| {
                let (sin_f, cos_f) = f.sin_cos();
                let w = axis * cos_g + (e1 * cos_f + e2 * sin_f) * sin_g;
                radiance(w) * (cos_a * cos_g + sin_a * sin_g * cos_f).max(0.0)
            },
            &[(0, -half, 0.0), (0, 0.0, half)],
            inner_tol,
            MAX_BISECTIONS,
        );
        inner * sin_g
    };
    integrate(
        outer,
        &gamma_segments(cos_a, sin_a, taus),
        tol,
        MAX_BISECTIONS,
    )
}

/// Half-width `φ₀` of the arc of the circle at angle `γ` from the pole where
/// `ω·n = a + c·cos φ > 0` (`a = cos α cos γ`, `c = sin α sin γ ≥ 0`): `π` for the whole
/// circle, `None` for none of it.
fn visible_arc(a: f64, c: f64) -> Option<f64> {
    if c <= a.abs() {
        (a > 0.0).then_some(PI)
    } else {
        Some((-a / c).acos())
    }
}

/// Outer breakpoints in `γ ∈ [0, π]`: where the visible arc changes shape (`γ = |π/2 − α|`
/// and `π − |π/2 − α|`) and a ladder `k/τ` where the peak towards the light falls off.
fn gamma_segments(cos_a: f64, sin_a: f64, taus: DVec3) -> Vec<(usize, f64, f64)> {
    let edge = (FRAC_PI_2 - sin_a.atan2(cos_a)).abs();
    let mut points = vec![0.0, PI, edge, PI - edge];
    for tau in taus.to_array() {
        if tau > 0.0 {
            points.extend([1.0 / 16.0, 0.25, 1.0, 4.0, 16.0].map(|k| k / tau));
        }
    }
    points.retain(|&g| (0.0..=PI).contains(&g));
    points.sort_by(f64::total_cmp);
    points.dedup();
    points.windows(2).map(|w| (0, w[0], w[1])).collect()
}

/// The scale of the [module docs](self): `σs·I0·e^{−σt·D}/D` per channel, so that for a point
/// light of intensity `intensity` at distance `distance` from `P`,
/// `E(P)[c] = scale[c] · surface_inscatter_normalised(σt[c]·D, α, phase)[c]`.
/// `+∞` (where `σs·I0 > 0`) for `distance = 0`; zero for a negative or NaN `distance`.
pub fn surface_inscatter_scale(medium: &Medium, intensity: DVec3, distance: f64) -> DVec3 {
    if !(distance >= 0.0) {
        return DVec3::ZERO;
    }
    let coef = medium.sigma_s().as_dvec3() * intensity;
    let decay = (-medium.sigma_t().as_dvec3() * distance).exp();
    DVec3::from_array(std::array::from_fn(|c| {
        if coef[c] > 0.0 {
            coef[c] * decay[c] / distance
        } else {
            0.0
        }
    }))
}

/// `G(τ, α)` of the [module docs](self), per channel of `phase` (all channels equal except for
/// Hoffman–Preetham): the hemisphere integral for `σs = I0 = D = 1`, `σt = τ`, without the
/// factor `e^{−τ}`, computed in these normalised units through the closed-form `φ` integral
/// and adaptive quadrature in `γ` of its own airlight factor `b(τ, γ)` (independent of
/// [`surface_inscatter`]'s code path). `alpha` is clamped to `[0, π]`; `τ = ∞` gives 0;
/// a negative or NaN `τ` or a NaN `alpha` gives zero.
pub fn surface_inscatter_normalised(tau: f64, alpha: f64, phase: &PhaseFunction) -> DVec3 {
    if !(tau >= 0.0) || alpha.is_nan() || tau == f64::INFINITY {
        return DVec3::ZERO;
    }
    let (sin_a, cos_a) = alpha.clamp(0.0, PI).sin_cos();
    integrate(
        |_, g: f64| {
            let (sin_g, cos_g) = g.sin_cos();
            let (a, c) = (cos_a * cos_g, sin_a * sin_g);
            match visible_arc(a, c) {
                Some(half) => airlight_factor(tau, g, phase) * (2.0 * (a * half + c * half.sin())),
                None => DVec3::ZERO,
            }
        },
        &gamma_segments(cos_a, sin_a, DVec3::splat(tau)),
        OUTER_TOLERANCE,
        MAX_BISECTIONS,
    )
}

/// The range of `τ` a table of `G` covers, `[1e-3, 50]`; below it `G` is within `O(τ·log τ)` of
/// its `τ = 0` value.
pub const ISS_TABLE_TAU: [f64; 2] = [1e-3, 50.0];

/// The warp `s(τ) = S0 + S1·τ` of the angle axis of [`iss_table_coords`].
const WARP: [f64; 2] = [4.0, 1.0];

/// Coordinates `(u, v) ∈ [0, 1]²` of `(τ, α)` in a table of `G` ([`surface_inscatter_normalised`])
/// with nodes at `u = i/(N_τ − 1)`, `v = j/(N_α − 1)`:
///
/// ```text
/// u = (ln τ − ln τ₀)/(ln τ₁ − ln τ₀)   (clamped; [τ₀, τ₁] = ISS_TABLE_TAU),
/// v = ½ − asinh(s·cos α)/(2·asinh s),   s = 4 + τ,
/// ```
///
/// `v` runs from 0 (`α = 0`, facing the light) to 1 (`α = π`) and gathers nodes about
/// `α = π/2`, where `G` falls over a width of about `1/τ`. [`iss_table_point`] is the inverse.
pub fn iss_table_coords(tau: f64, alpha: f64) -> (f64, f64) {
    let [lo, hi] = ISS_TABLE_TAU.map(f64::ln);
    let tau = tau.clamp(ISS_TABLE_TAU[0], ISS_TABLE_TAU[1]);
    let s = WARP[0] + WARP[1] * tau;
    let u = (tau.ln() - lo) / (hi - lo);
    (u, 0.5 - (s * alpha.cos()).asinh() / (2.0 * s.asinh()))
}

/// The `(τ, α)` at table coordinates `(u, v) ∈ [0, 1]²`: the inverse of [`iss_table_coords`]
/// (where a table's builder evaluates `G`).
pub fn iss_table_point(u: f64, v: f64) -> (f64, f64) {
    let [lo, hi] = ISS_TABLE_TAU.map(f64::ln);
    let tau = (lo + u.clamp(0.0, 1.0) * (hi - lo)).exp();
    let s = WARP[0] + WARP[1] * tau;
    let cos = ((1.0 - 2.0 * v.clamp(0.0, 1.0)) * s.asinh()).sinh() / s;
    (tau, cos.clamp(-1.0, 1.0).acos())
}

/// `b(τ, γ) = 2∫_{γ/2}^{π/2} p(cos 2ξ)·e^{−τ·sin γ·(tan ξ − tan(γ/2))} dξ`, integrated in
/// `s = ξ − γ/2 ∈ [0, (π − γ)/2]` with `tan ξ − tan(γ/2) = sin s/(cos ξ·cos(γ/2))`.
fn airlight_factor(tau: f64, gamma: f64, phase: &PhaseFunction) -> DVec3 {
    let half = 0.5 * gamma;
    let width = FRAC_PI_2 - half;
    let cos_half = half.cos();
    let k = tau * gamma.sin();
    let f = |_, s: f64| {
        let (sin_xi, cos_xi) = if half + s <= FRAC_PI_4 {
            (half + s).sin_cos()
        } else {
            let (sin_e, cos_e) = (width - s).sin_cos();
            (cos_e, sin_e)
        };
        let cosine = Cosine {
            mu: (cos_xi - sin_xi) * (cos_xi + sin_xi),
            one_minus: 2.0 * sin_xi * sin_xi,
            one_plus: 2.0 * cos_xi * cos_xi,
        };
        let decay = if k > 0.0 {
            (-k * s.sin() / (cos_xi * cos_half)).exp()
        } else {
            1.0
        };
        phase::eval(phase, cosine) * (2.0 * decay)
    };
    let mut points = vec![0.0, width];
    if k > 0.0 {
        let scale = cos_half * cos_half / k;
        points.extend([1.0, 4.0, 16.0, 64.0].map(|m| m * scale));
    }
    points.retain(|&s| (0.0..=width).contains(&s));
    points.sort_by(f64::total_cmp);
    points.dedup();
    let segments: Vec<_> = points.windows(2).map(|w| (0, w[0], w[1])).collect();
    integrate(f, &segments, RELATIVE_TOLERANCE, MAX_BISECTIONS)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::PointLight;
    use glam::Vec3;

    #[test]
    fn accuracy_by_refining_the_tolerance() {
        let medium = Medium::new(
            Vec3::new(0.2, 0.5, 1.0),
            Vec3::splat(0.1),
            PhaseFunction::HenyeyGreenstein { g: 0.8 },
        )
        .unwrap();
        let light = PointLight::new(Vec3::new(0.3, 2.0, -0.5), Vec3::splat(10.0)).unwrap();
        let mut worst = 0.0f64;
        for n in [DVec3::Y, DVec3::new(1.0, 0.2, 0.0), DVec3::NEG_Y] {
            let fine = surface_inscatter_to(DVec3::ZERO, n, &medium, &light, [1e-12, 1e-11]);
            let t = std::time::Instant::now();
            let value = surface_inscatter(DVec3::ZERO, n, &medium, &light);
            let el = t.elapsed();
            let rel = ((value - fine) / fine).abs().max_element();
            println!("n {n}: {value} vs tol 1e-12 {fine}: rel {rel:e}, {el:?}");
            worst = worst.max(rel);
        }
        assert!(worst <= 1e-6, "{worst:e}");
    }
}
