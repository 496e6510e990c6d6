//! The f64 reference: an independent integrator of the single-scattering model, the ground
//! truth every GPU test compares with.
//!
//! It shares no code with the GPU path (no wgpu, no shaders, nothing from `nodes` or `gpu`)
//! beyond the scene types ([`Medium`], [`PhaseFunction`], [`Light`] ([`PointLight`],
//! [`SpotLight`]), [`Camera`]), whose f32 values it converts to f64 on entry.
//!
//! # The model
//!
//! For a ray from the eye `E` in the unit direction `v`, ending at distance `ds` (infinite for
//! sky), a point light at `P` with intensity `I0` and a medium with scattering `σs`, extinction
//! `σt = σs + σa` and phase function `p` (per RGB channel), the in-scattered radiance is
//!
//! ```text
//! L_sctr = ∫₀^ds V(x) · σs · p(cos θ(x)) · I0 · exp(−σt·(d(x) + x)) / d(x)² dx,
//! d(x) = |E + x·v − P|,   cos θ(x) = v·(P − X)/d(x)
//! ```
//!
//! where `θ` is the scattering angle between the light's direction of travel at `X = E + x·v`
//! and the direction towards the eye (looking straight at the light is `θ = 0`), and
//! `V(x) ∈ {0, 1}` is 1 iff the segment from `X` to `P` meets no occluder surface.
//!
//! A [`SpotLight`] is the same point light with `V(x)` also 0 outside its cone: `X` is lit
//! iff `a·(X − P) ≥ c·|X − P|` (axis `a = direction()`, `c = cos_half_angle()`, the f32 values
//! in f64, not renormalised) and the segment to `P` is unoccluded, with a hard edge and the
//! same `I0` everywhere inside. Along a ray
//! `w(x) = E − P + x·v` the cone's surface is where the quadratic
//! `f(x) = (a·w)² − c²·|w|² = A·x² + 2·B·x + C` vanishes, with
//!
//! ```text
//! A = (a·v)² − c²,   B = (a·w₀)(a·v) − c²·(v·w₀),   C = (a·w₀)² − c²·|w₀|²,   w₀ = E − P,
//! ```
//!
//! so the ray's entry into and exit from the cone are its real roots (the nappe behind the
//! light, `a·w < 0`, is the other half of the zero set and is discarded by the membership test).
//! These roots are breakpoints of [`light_intervals`] like the occluders' ones, so the cone's
//! edge is exact, not sampled.
//!
//! A [`TexturedSpot`] (a spot light with a [`LightTexture`]) has the same lit intervals, and
//! inside them `I0` becomes `I0·bilinear(texture, uv(X))` ([`TexturedSpot::uv`],
//! [`bilinear`]: the definition in [`LightTexture`]'s docs, in f64). The integrand is then
//! only piecewise smooth along the ray: the bilinear lookup has a kink wherever `uv` crosses a
//! texel-centre line `u = (i + 0.5)/W` or `v = (j + 0.5)/H`. Each such line is a plane through
//! the light, so each kink is one ray–plane intersection, and since `u` and `v` are monotonic
//! along a ray inside the cone (ratios of affine functions of `x`), each line is crossed at
//! most once and only the lines between the ends' `uv` need testing. All of them are added as
//! breakpoints, so every quadrature panel is smooth and the adaptive rule keeps its accuracy
//! ([`RELATIVE_TOLERANCE`]).
//!
//! Cost: one Gauss–Kronrod panel (15 integrand evaluations, each with one bilinear lookup) per
//! crossed line, on top of the untextured ray's; a ray across the whole cone crosses about
//! `W + H` lines (at most `W + H`), a ray along the axis or near the light far fewer.
//! Measured (`tests/cpu/reference_texture.rs`, one ray across a 50° cone, noise textures, the
//! crate's optimised dev profile): untextured 30 µs; 8² 35 µs; 64² 0.13 ms; 256² 0.45 ms;
//! 1024² 18 ms; 4096² 30–40 ms. Without these breakpoints the same rays took 0.5 ms (8²) and
//! 12 ms (64², where the bisection cap was reached and the error was 1e-8).
//!
//! * [`inscatter`] integrates this with exact visibility ([`light_intervals`], which for a
//!   point light is [`lit_intervals`]) and adaptive Gauss–Kronrod quadrature in `x`, split
//!   where the integrand is sharp (and, for a textured spot, at the texture's kinks). It takes
//!   any light by reference (`&PointLight`, `&SpotLight`, `&Light`, `&TexturedSpot`: see
//!   [`LightSource`]).
//! * [`inscatter_closed_form`] evaluates the unshadowed integral of a *point* light through the
//!   substitution `x = t + h·tan θ`, `ξ = π/4 + θ/2` (an integral in the half scattering
//!   angle `ξ`; Sun et al., "A Practical Analytic Single Scattering Model for Real Time
//!   Rendering", 2005, in a bounded form), computed
//!   separately: the two check each other. (A spot light's unshadowed value is the point
//!   light's closed form over the cone's intervals: the integrand inside is the same.)
//! * [`inscatter_image`] does a whole frame for a [`Camera`], for per-pixel comparisons.
//!
//! A [`DirectionalLight`](crate::DirectionalLight) travelling along the unit direction `d` delivers the irradiance `E`
//! at every point that sees it (it is at infinity, with no attenuation on the light path), so
//! the scattering angle is the same at every point of the ray and
//!
//! ```text
//! L_sctr = ∫₀^ds V(x) · σs · p(μ) · E · exp(−σt·x) dx,   μ = cos θ = −v·d,
//! ```
//!
//! with `V(x) = 1` iff the half-line from `X` towards `−d` meets no occluder. Over a lit
//! interval `[x₀, x₁]` this is `σs·p(μ)·E·(e^{−σt·x₀} − e^{−σt·x₁})/σt` per channel.
//! [`inscatter_directional`] integrates this over the exact [`directional_lit_intervals`] by
//! quadrature, [`inscatter_directional_closed_form`] evaluates the unshadowed value in closed
//! form (the two check each other) and [`inscatter_image_directional`] does a whole frame.
//!
//! All results are finite for finite input, except where a ray passes exactly through the light
//! (distance `h = 0` from the light and the light within `[0, ds]`): the integral diverges there
//! and the channels with `σs·I0 > 0` are `+∞`.

// `!(x > 0.0)` is used on purpose throughout: it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod bvh;
mod cone;
mod directional;
pub mod iss;
mod iss_cone;
mod metric;
mod occluder;
mod phase;
pub(crate) mod quadrature;
mod rows;
pub mod soft;
mod texture;
mod visibility;

use std::sync::Mutex;

use glam::{DVec2, DVec3, DVec4};

use crate::scene::{Camera, Light, LightTexture, Medium, PhaseFunction, PointLight, SpotLight};

pub use directional::{
    directional_lit_intervals, inscatter_directional, inscatter_directional_closed_form,
    inscatter_image_directional,
};
pub use iss::{
    iss_table_coords, iss_table_point, surface_inscatter, surface_inscatter_normalised,
    surface_inscatter_scale, ISS_TABLE_TAU,
};
pub use iss_cone::surface_inscatter_cone;
pub use metric::ImageError;
pub use occluder::{Cuboid, Occluder, Sphere, TriangleMesh};
pub use phase::phase;
pub use soft::{inscatter_image_soft, inscatter_soft, visible_fraction};
pub use texture::{bilinear, texture_axes, TexturedSpot};
pub use visibility::{light_intervals, lit_intervals};

use phase::Cosine;
use quadrature::integrate;
use texture::Projection;

/// The relative tolerance every integral of this module is computed to (estimated error of the
/// adaptive Gauss–Kronrod quadrature, per channel). Measured agreement between [`inscatter`]
/// and [`inscatter_closed_form`] is well below 1e-12.
pub const RELATIVE_TOLERANCE: f64 = 1e-12;

/// Most bisections one adaptive integral may spend (a cap that only pathological input reaches).
const MAX_BISECTIONS: usize = 4000;

/// A light the reference integrates: [`PointLight`], [`SpotLight`], the [`Light`] enum or a
/// [`TexturedSpot`], taken by reference by [`inscatter`], [`inscatter_image`] and
/// [`light_intervals`], so that `&point`, `&spot`, `&light` and `&textured` all work at the call
/// site. (A reference parameter rather than `impl Into<Light>`, which would make clippy's
/// `needless_borrows_for_generic_args` flag every existing `&light` argument.)
pub trait LightSource {
    /// This light as a [`Light`] (a copy): its position, intensity and, for a spot light, cone.
    fn light(&self) -> Light;

    /// The texture the light projects, if any: the emission towards `X` inside the cone is
    /// then `intensity × bilinear(texture, uv(X))` (see [`TexturedSpot`]). Only used when
    /// [`light`](Self::light) is a [`Light::Spot`]; ignored for any other light. `None` by
    /// default.
    fn texture(&self) -> Option<&LightTexture> {
        None
    }
}

impl LightSource for PointLight {
    fn light(&self) -> Light {
        Light::Point(*self)
    }
}

impl LightSource for SpotLight {
    fn light(&self) -> Light {
        Light::Spot(*self)
    }
}

impl LightSource for crate::scene::DirectionalLight {
    fn light(&self) -> Light {
        Light::Directional(*self)
    }
}

impl LightSource for Light {
    fn light(&self) -> Light {
        *self
    }
}

impl LightSource for TexturedSpot<'_> {
    fn light(&self) -> Light {
        Light::Spot(self.spot)
    }

    fn texture(&self) -> Option<&LightTexture> {
        Some(self.texture)
    }
}

/// Transmittance of the medium over a distance `ds`: `exp(−σt·ds)` per channel. `ds = ∞` gives
/// 0 where `σt > 0` and 1 where `σt = 0`; `ds ≤ 0` (or NaN) gives 1.
pub fn transmittance(medium: &Medium, ds: f64) -> DVec3 {
    let sigma_t = medium.sigma_t().as_dvec3();
    if !(ds > 0.0) {
        return DVec3::ONE;
    }
    DVec3::from_array(
        sigma_t
            .to_array()
            .map(|s| if s > 0.0 { (-s * ds).exp() } else { 1.0 }),
    )
}

/// Geometry of a ray relative to the light, in f64.
#[derive(Debug, Clone, Copy)]
struct RayLight {
    /// Unit direction.
    v: DVec3,
    /// Distance from the eye to the light, `D`.
    distance: f64,
    /// Distance along the ray to the closest approach, `t = v·(P − E) = D cos γ`.
    t: f64,
    /// Distance of the light from the ray's line, `h = |v × (P − E)| = D sin γ`.
    h: f64,
    /// The closest approach minus the light, `E + t·v − P` (length `h`, perpendicular to `v`):
    /// the point at `x = t + w` is `P + offset + w·v`.
    offset: DVec3,
}

/// `dir` normalised (rescaled first, so that huge or tiny finite vectors work); `None` for a
/// zero or non-finite vector.
pub(crate) fn unit(dir: DVec3) -> Option<DVec3> {
    let largest = dir.abs().max_element();
    if !(largest > 0.0 && largest.is_finite()) {
        return None;
    }
    let scaled = dir / largest;
    Some(scaled / scaled.length())
}

impl RayLight {
    fn new(origin: DVec3, dir: DVec3, light: DVec3) -> Option<Self> {
        if !(origin.is_finite() && light.is_finite()) {
            return None;
        }
        let v = unit(dir)?;
        let to_light = light - origin;
        let t = v.dot(to_light);
        Some(Self {
            v,
            distance: to_light.length(),
            t,
            h: v.cross(to_light).length(),
            offset: v * t - to_light,
        })
    }
}

/// Per-ray constants of the integrand of (1).
struct Integrand<'a> {
    geo: RayLight,
    /// `σs·I0` per channel.
    coef: DVec3,
    sigma_t: DVec3,
    phase: PhaseFunction,
    /// A textured spot light's projection: `I0` is then `coef` times its texel.
    projection: Option<Projection<'a>>,
}

impl<'a> Integrand<'a> {
    /// `intensity` is the light's `I0` (inside the cone, for a spot light).
    fn new(geo: RayLight, medium: &Medium, intensity: glam::Vec3) -> Self {
        Self {
            geo,
            coef: medium.sigma_s().as_dvec3() * intensity.as_dvec3(),
            sigma_t: medium.sigma_t().as_dvec3(),
            phase: medium.phase(),
            projection: None,
        }
    }

    /// The same, with `I0` modulated by a spot light's texture.
    fn textured(self, projection: Option<Projection<'a>>) -> Self {
        Self { projection, ..self }
    }

    /// `exp(−σt·path)` per channel (1 where `σt = 0`, so that `path = ∞` is no NaN).
    fn attenuation(&self, path: f64) -> DVec3 {
        DVec3::from_array(self.sigma_t.to_array().map(|s| {
            if s > 0.0 {
                (-s * path).exp()
            } else {
                1.0
            }
        }))
    }

    /// The integrand of (1) with `V = 1`, multiplied by `scale`, at `x = t + w`: the argument is
    /// the signed offset `w` from the closest approach to the light, so that a peak of width
    /// `h` far smaller than the spacing of f64 numbers near `t` is still resolved.
    fn at(&self, w: f64, scale: f64) -> DVec3 {
        let RayLight { t, h, .. } = self.geo;
        let d = h.hypot(w);
        if !(d > 0.0) {
            return DVec3::ZERO;
        }
        // μ = v·(P − X)/d = −w/d; 1 − μ, 1 + μ and d + w without cancellation.
        let (one_minus, one_plus, d_plus_w) = if w <= 0.0 {
            let dm = d - w;
            ((h / d) * (h / dm), dm / d, (h / dm) * h)
        } else {
            let dp = d + w;
            (dp / d, (h / d) * (h / dp), dp)
        };
        let cosine = Cosine {
            mu: -w / d,
            one_minus,
            one_plus,
        };
        let p = phase::eval(&self.phase, cosine);
        let coef = match &self.projection {
            Some(projection) => self.coef * projection.texel(self.geo.offset + self.geo.v * w),
            None => self.coef,
        };
        // d + x = (d + w) + t ≥ D.
        coef * p * self.attenuation(d_plus_w + t) * ((scale / d) * (1.0 / d))
    }

    /// `+∞` in the channels that scatter at all, 0 in the others: the value of an interval
    /// `[a, b]` that reaches the light itself (`h = 0`, `a ≤ t ≤ b`). For a textured light the
    /// emission along the ray is the texel towards `−v` before the light and towards `+v`
    /// after it, and only the channels where one of those (on a side within `[a, b]`) is
    /// non-zero diverge.
    fn divergent(&self, a: f64, b: f64) -> DVec3 {
        let coef = match &self.projection {
            Some(projection) => {
                let v = self.geo.v;
                let t = self.geo.t;
                let before = if a < t {
                    projection.texel(-v)
                } else {
                    DVec3::ZERO
                };
                let after = if t < b {
                    projection.texel(v)
                } else {
                    DVec3::ZERO
                };
                self.coef * before.max(after)
            }
            None => self.coef,
        };
        DVec3::from_array(
            coef.to_array()
                .map(|c| if c > 0.0 { f64::INFINITY } else { 0.0 }),
        )
    }

    /// ∫ over `[a, b]` (`b` may be `∞`) of the unshadowed integrand, by adaptive Gauss–Kronrod
    /// in `x` with breakpoints where it is sharp.
    fn integrate_x(&self, a: f64, b: f64) -> DVec3 {
        let RayLight { distance, t, h, .. } = self.geo;
        if !(a < b) || self.coef == DVec3::ZERO {
            return DVec3::ZERO;
        }
        if h == 0.0 && a <= t && t <= b {
            return self.divergent(a, b); // the ray runs through the light
        }
        // Work in w = x − t. Breakpoints: the closest approach w = 0 and a geometric ladder
        // ±base·4^j around it (the peak of 1/d² has width h; with h = 0 the light is outside
        // [a, b] and the integrand varies on the scale of the distance to it), and the
        // extinction lengths from a.
        let (wa, wb) = (a - t, b - t);
        let base = if h > 0.0 {
            h
        } else if wa > 0.0 {
            wa
        } else {
            -wb
        };
        let reach = if b.is_finite() {
            wa.abs().max(wb.abs())
        } else {
            64.0 * distance.max(h).max(wa.abs())
        };
        let mut points = vec![0.0];
        let mut step = base / 16.0;
        for _ in 0..80 {
            if !(step <= reach) {
                break;
            }
            points.extend([-step, step]);
            step *= 4.0;
        }
        for s in self.sigma_t.to_array() {
            if s > 0.0 {
                points.extend([0.25, 1.0, 4.0, 16.0].map(|k| wa + k / s));
            }
        }
        if let Some(projection) = &self.projection {
            // The kinks of the bilinear lookup (see `Projection::crossings`).
            projection.crossings(self.geo.offset, self.geo.v, wa, wb, &mut points);
        }
        points.retain(|&w| w > wa && w < wb && w.is_finite());
        points.push(wa);
        points.sort_by(f64::total_cmp);
        points.dedup();
        let mut segments: Vec<(usize, f64, f64)> =
            points.windows(2).map(|p| (0, p[0], p[1])).collect();
        let last = *points.last().unwrap_or(&wa);
        // Tail [last, ∞) mapped onto z ∈ [0, 1): w = last + L·z/(1 − z).
        let tail_len = (last - wa)
            .max(distance)
            .max(h)
            .max(f64::MIN_POSITIVE.sqrt());
        if b.is_finite() {
            segments.push((0, last, wb));
        } else {
            segments.push((1, 0.0, 1.0));
        }
        // Factor the singular 1/h out of the integrand so that the peak 1/h² cannot overflow.
        let scale = if h > 0.0 { h } else { 1.0 };
        let value = integrate(
            |map, u| {
                if map == 0 {
                    self.at(u, scale)
                } else {
                    let one_minus = 1.0 - u;
                    let w = last + tail_len * u / one_minus;
                    self.at(w, scale) * (tail_len / (one_minus * one_minus))
                }
            },
            &segments,
            RELATIVE_TOLERANCE,
            MAX_BISECTIONS,
        );
        value / scale
    }
}

/// In-scattered radiance (RGB) along the ray `origin + x·dir`, `0 ≤ x ≤ ds` (`ds = ∞` for
/// sky), from `light` (`&PointLight`, `&SpotLight`, `&Light` or `&TexturedSpot`, see
/// [`LightSource`]), with
/// shadows: the integral (1) of the [module docs](self) over the [`light_intervals`] (the
/// unoccluded parts of the ray, and for a spot light only those inside its cone, whose edges
/// are found exactly), each by adaptive Gauss–Kronrod (7, 15) quadrature in `x` to
/// [`RELATIVE_TOLERANCE`], split at the closest approach to the light, on a geometric ladder
/// around it, at the extinction length scales and, for a [`TexturedSpot`], where the ray
/// crosses a texel-centre line of the texture (see the [module docs](self)); infinite tails
/// are mapped onto a finite interval. Includes `σs` and `I0` (times the texel for a textured
/// spot), excludes the attenuated surface term (see [`transmittance`]).
///
/// `dir` need not be unit length. Returns zero for `ds ≤ 0`, NaN `ds`, a zero or non-finite
/// `dir` or non-finite positions; `+∞` (in the channels with `σs·I0 > 0`) where the ray passes
/// exactly through the light inside a lit interval (for a spot light: a ray through the apex
/// that enters the cone there; for a textured spot only the channels whose texel along the
/// ray is non-zero); finite values otherwise. A ray that never enters a spot light's cone
/// gives exactly 0, and one that stays inside an untextured cone gives exactly the point
/// light's value.
pub fn inscatter(
    origin: DVec3,
    dir: DVec3,
    ds: f64,
    medium: &Medium,
    light: &impl LightSource,
    occluders: &[Occluder],
) -> DVec3 {
    inscatter_light(
        origin,
        dir,
        ds,
        medium,
        light.light(),
        light.texture(),
        occluders,
    )
}

/// [`inscatter`] for `light` projecting `texture` (used only for a spot light).
fn inscatter_light(
    origin: DVec3,
    dir: DVec3,
    ds: f64,
    medium: &Medium,
    light: Light,
    texture: Option<&LightTexture>,
    occluders: &[Occluder],
) -> DVec3 {
    let position = match light {
        Light::Directional(sun) => {
            return inscatter_directional(origin, dir, ds, medium, &sun, occluders);
        }
        _ => light.position().unwrap_or_default(),
    };
    let Some(geo) = RayLight::new(origin, dir, position.as_dvec3()) else {
        return DVec3::ZERO;
    };
    if !(ds > 0.0) {
        return DVec3::ZERO;
    }
    let projection = match (light, texture) {
        (Light::Spot(spot), Some(texture)) => Some(Projection::new(&spot, texture)),
        _ => None,
    };
    let integrand = Integrand::new(geo, medium, light.intensity()).textured(projection);
    light_intervals(origin, geo.v, ds, &light, occluders)
        .into_iter()
        .map(|(a, b)| integrand.integrate_x(a, b))
        .sum()
}

/// The unshadowed in-scattered radiance of [`inscatter`] with no occluders, for a point light
/// only, evaluated independently through the closed form in the half scattering angle:
///
/// ```text
/// (2·σs·I0·exp(−σt·D) / h) · ∫_{γ/2}^{ξ(ds)} p(cos 2ξ) · exp(−σt·h·(tan ξ − tan(γ/2))) dξ
/// ```
///
/// with `D = |P − E|`, `γ` the angle between `dir` and `P − E`, `h = D sin γ`,
/// `ξ(x) = π/4 + ½·atan((x − D cos γ)/h)`, `ξ(∞) = π/2`; the scattering angle at `ξ` is `2ξ`.
/// The integral is taken by adaptive Gauss–Kronrod in `s = ξ − γ/2`, whose range (half the
/// angle that `[E, E + ds·v]` subtends at the light) is computed directly, and in which the
/// exponent is `σt·h·sin s/(cos ξ · cos(γ/2))`; `ξ` itself is formed as `γ/2 + s` below π/4 and
/// as `π/2 − (η₀ − s)` above (`η₀ = (π − γ)/2`), so every factor keeps its relative precision
/// with the light straight ahead (`γ → 0`), behind the eye (`γ → π`) or for tiny `ds`.
///
/// When the light lies exactly on the ray's line (`h = 0`) the substitution does not exist: the
/// result is `+∞` if the light lies within `[0, ds]` (as for [`inscatter`]) and otherwise the
/// integral (1) taken in `x`. Degenerate input is handled as in [`inscatter`].
///
/// There is no spot-light variant: a spot light's cone is a set of intervals in `x`
/// ([`light_intervals`]), and over each the integrand is the point light's, so [`inscatter`]
/// is its reference.
pub fn inscatter_closed_form(
    origin: DVec3,
    dir: DVec3,
    ds: f64,
    medium: &Medium,
    light: &PointLight,
) -> DVec3 {
    let Some(geo) = RayLight::new(origin, dir, light.position().as_dvec3()) else {
        return DVec3::ZERO;
    };
    if !(ds > 0.0) {
        return DVec3::ZERO;
    }
    let integrand = Integrand::new(geo, medium, light.intensity());
    let RayLight { distance, t, h, .. } = geo;
    if integrand.coef == DVec3::ZERO {
        return DVec3::ZERO;
    }
    if h == 0.0 {
        return integrand.integrate_x(0.0, ds);
    }
    // Integrate in s = ξ − γ/2 ∈ [0, S]: the width S is computed directly (half the angle that
    // [E, X(ds)] subtends at the light), not as a difference of two angles, and the exponent
    // is sin(s)/(cos ξ·cos(γ/2)) with no cancellation. ξ is formed from whichever of γ/2 + s
    // and π/2 − (η0 − s) keeps its relative precision (η0 = π/2 − γ/2 = (π − γ)/2).
    let half_gamma = 0.5 * h.atan2(t);
    let eta0 = 0.5 * h.atan2(-t);
    let width = if ds.is_finite() {
        // angle at P between E − P and X − P = (E − P) + ds·v: atan2(ds·h, D² − ds·t).
        0.5 * (ds * h).atan2(distance * distance - ds * t)
    } else {
        eta0
    };
    if !(width > 0.0) {
        return DVec3::ZERO;
    }
    let cos_half_gamma = eta0.sin();
    let sigma_h = integrand.sigma_t * h;
    let phase = integrand.phase;
    let f = |s: f64| {
        let xi = half_gamma + s;
        let (sin_xi, cos_xi) = if xi <= std::f64::consts::FRAC_PI_4 {
            xi.sin_cos()
        } else {
            let (sin_eta, cos_eta) = (eta0 - s).sin_cos();
            (cos_eta, sin_eta)
        };
        // Scattering angle 2ξ: μ = cos 2ξ, 1 − μ = 2 sin²ξ, 1 + μ = 2 cos²ξ.
        let cosine = Cosine {
            mu: (cos_xi - sin_xi) * (cos_xi + sin_xi),
            one_minus: 2.0 * sin_xi * sin_xi,
            one_plus: 2.0 * cos_xi * cos_xi,
        };
        let p = phase::eval(&phase, cosine);
        // tan ξ − tan(γ/2) = sin(ξ − γ/2) / (cos ξ · cos(γ/2)) ≥ 0.
        let excess = s.sin() / (cos_xi * cos_half_gamma);
        let decay = DVec3::from_array(sigma_h.to_array().map(|sh| {
            if sh > 0.0 {
                (-sh * excess).exp()
            } else {
                1.0
            }
        }));
        p * decay
    };
    // Breakpoints where the exponential falls off (scale cos²(γ/2) / (σt·h) in s).
    let mut points = vec![0.0, width];
    for sh in sigma_h.to_array() {
        if sh > 0.0 {
            let scale = cos_half_gamma * cos_half_gamma / sh;
            points.extend([1.0, 4.0, 16.0, 64.0].map(|k| k * scale));
        }
    }
    points.retain(|&s| (0.0..=width).contains(&s));
    points.sort_by(f64::total_cmp);
    points.dedup();
    let segments: Vec<(usize, f64, f64)> = points.windows(2).map(|w| (0, w[0], w[1])).collect();
    let bounded = integrate(|_, s| f(s), &segments, RELATIVE_TOLERANCE, MAX_BISECTIONS);
    2.0 * integrand.coef * integrand.attenuation(distance) * (bounded / h)
}

/// Normalised device coordinates of the centre of pixel `(px, py)` in a `width × height` image
/// (row 0 at the top): `x = (px + 0.5)/width·2 − 1`, `y = 1 − (py + 0.5)/height·2`.
pub fn pixel_ndc(width: u32, height: u32, px: u32, py: u32) -> DVec2 {
    DVec2::new(
        (px as f64 + 0.5) / width.max(1) as f64 * 2.0 - 1.0,
        1.0 - (py as f64 + 0.5) / height.max(1) as f64 * 2.0,
    )
}

/// The eye position and unit world-space ray direction through the NDC point `ndc`, computed in
/// f64 from the camera's view and projection matrices: the eye is `view⁻¹·(0, 0, 0, 1)`; the
/// NDC point is unprojected at depth 0 and at depth 1 through `projection⁻¹`, and the one that
/// is finite (unprojected `w` not ~0) and nearer the eye is used, so standard and reversed Z,
/// finite and infinite far planes all work; the view-space point is taken to world space by
/// `view⁻¹`, and the direction is it minus the eye, normalised.
pub fn camera_ray(camera: &Camera, ndc: DVec2) -> (DVec3, DVec3) {
    let inv_view = camera.view().as_dmat4().inverse();
    let inv_proj = camera.projection().as_dmat4().inverse();
    let eye_h = inv_view * DVec4::new(0.0, 0.0, 0.0, 1.0);
    let eye = eye_h.truncate() / eye_h.w;
    let mut best: Option<(f64, DVec3)> = None;
    for depth in [0.0, 1.0] {
        let p = inv_proj * DVec4::new(ndc.x, ndc.y, depth, 1.0);
        let xyz = p.truncate();
        if !(p.w.abs() > 1e-12 * xyz.length()) {
            continue; // at infinity
        }
        let point = xyz / p.w; // view space, eye at the origin
        let dist = point.length();
        if dist.is_finite() && dist > 0.0 && best.is_none_or(|(d, _)| dist < d) {
            best = Some((dist, point));
        }
    }
    let view_point = best.map_or(DVec3::NEG_Z, |(_, p)| p);
    let world = inv_view * view_point.extend(1.0);
    let dir = (world.truncate() / world.w - eye).normalize_or(DVec3::NEG_Z);
    (eye, dir)
}

/// [`inscatter`] for every pixel of a `width × height` image seen by `camera`, row-major with
/// row 0 at the top. Pixel `(px, py)` uses the ray of [`camera_ray`] through [`pixel_ndc`], and
/// `distance(eye, dir)` gives its `ds` (`f64::INFINITY` for sky). `light` is any light, as for
/// [`inscatter`]. Rows are shared among `std::thread::available_parallelism()` threads.
pub fn inscatter_image(
    camera: &Camera,
    width: u32,
    height: u32,
    distance: impl Fn(DVec3, DVec3) -> f64 + Sync,
    medium: &Medium,
    light: &impl LightSource,
    occluders: &[Occluder],
) -> Vec<DVec3> {
    let texture = light.texture();
    let light = light.light();
    render(camera, width, height, |eye, dir| {
        let ds = distance(eye, dir);
        inscatter_light(eye, dir, ds, medium, light, texture, occluders)
    })
}

/// `pixel(eye, dir)` for the ray of every pixel (see [`inscatter_image`]), rows shared among
/// threads.
pub(crate) fn render(
    camera: &Camera,
    width: u32,
    height: u32,
    pixel: impl Fn(DVec3, DVec3) -> DVec3 + Sync,
) -> Vec<DVec3> {
    let (w, h) = (width as usize, height as usize);
    let mut image = vec![DVec3::ZERO; w * h];
    if w == 0 || h == 0 {
        return image;
    }
    let rows = Mutex::new(image.chunks_mut(w).enumerate());
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(h);
    let work = || loop {
        let next = rows.lock().map(|mut it| it.next()).unwrap_or(None);
        let Some((py, row)) = next else { break };
        for (px, out) in row.iter_mut().enumerate() {
            let (eye, dir) = camera_ray(camera, pixel_ndc(width, height, px as u32, py as u32));
            *out = pixel(eye, dir);
        }
    };
    std::thread::scope(|scope| {
        for _ in 1..threads {
            scope.spawn(work);
        }
        work();
    });
    image
}
