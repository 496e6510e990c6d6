//! Directional lights: exact lit intervals and the in-scatter integral, by quadrature and in
//! closed form (the model is in the [module docs](super)).

use glam::DVec3;

use super::occluder::{Occluder, Source};
use super::phase::{self, Cosine};
use super::quadrature::integrate;
use super::visibility::intervals;
use super::{render, unit, MAX_BISECTIONS, RELATIVE_TOLERANCE};
use crate::scene::{Camera, DirectionalLight, Medium};

/// The parts of the ray `origin + x·dir`, `0 ≤ x ≤ ds`, that see `light`: the half-line from
/// the point towards `−direction` meets no occluder surface ([`Occluder::ray_blocked`]). Same
/// conventions and degenerate cases as [`lit_intervals`](super::lit_intervals).
///
/// Exact, with no sampling: the candidate breakpoints are, in closed form, the ray's crossings
/// of each sphere and of its shadow cylinder (the sphere's radius, along the light's
/// direction); of each box face and of the planes spanned by each box edge and the light's
/// direction; of each mesh triangle's plane and of the planes spanned by the light's direction
/// and each mesh edge that can change visibility (silhouette edges with respect to the
/// direction, boundary and non-manifold edges). Visibility is decided inside each piece between
/// consecutive candidates as in [`lit_intervals`](super::lit_intervals).
pub fn directional_lit_intervals(
    origin: DVec3,
    dir: DVec3,
    ds: f64,
    light: &DirectionalLight,
    occluders: &[Occluder],
) -> Vec<(f64, f64)> {
    let Some(d) = unit(light.direction().as_dvec3()) else {
        return Vec::new();
    };
    intervals(origin, dir, ds, Source::Towards(-d), None, occluders)
}

/// The constants of one ray: `σs·p(μ)·E` and `σt` per channel.
struct Beam {
    coef: DVec3,
    sigma_t: DVec3,
}

impl Beam {
    /// `None` for a zero or non-finite `dir` or a non-finite `origin`.
    fn new(origin: DVec3, dir: DVec3, medium: &Medium, light: &DirectionalLight) -> Option<Self> {
        let v = unit(dir).filter(|_| origin.is_finite())?;
        let d = unit(light.direction().as_dvec3())?;
        // μ = −v·d; 1 − μ = |v + d|²/2 and 1 + μ = |v − d|²/2 keep their relative precision.
        let cosine = Cosine {
            mu: -v.dot(d),
            one_minus: 0.5 * (v + d).length_squared(),
            one_plus: 0.5 * (v - d).length_squared(),
        };
        let p = phase::eval(&medium.phase(), cosine);
        Some(Self {
            coef: medium.sigma_s().as_dvec3() * p * light.irradiance().as_dvec3(),
            sigma_t: medium.sigma_t().as_dvec3(),
        })
    }

    /// The integrand at `x` (0 in the channels with `σs·E = 0`, so `x = ∞` is no NaN).
    fn at(&self, x: f64) -> DVec3 {
        DVec3::from_array(std::array::from_fn(|c| {
            let (k, s) = (self.coef[c], self.sigma_t[c]);
            if k == 0.0 {
                0.0
            } else {
                k * (-s * x).exp()
            }
        }))
    }

    /// ∫ over `[a, b]` (`b` may be `∞`) by adaptive Gauss–Kronrod in `x`, split at the
    /// extinction lengths from `a`; an infinite tail is mapped onto `z ∈ [0, 1)`.
    fn quadrature(&self, a: f64, b: f64) -> DVec3 {
        if !(a < b) || self.coef == DVec3::ZERO {
            return DVec3::ZERO;
        }
        let mut points = vec![a];
        for s in self.sigma_t.to_array() {
            points.extend([0.25, 1.0, 4.0, 16.0].map(|k| a + k / s));
        }
        points.retain(|&x| x >= a && x < b && x.is_finite());
        points.sort_by(f64::total_cmp);
        points.dedup();
        let last = *points.last().unwrap_or(&a);
        let mut segments: Vec<(usize, f64, f64)> =
            points.windows(2).map(|p| (0, p[0], p[1])).collect();
        segments.push(if b.is_finite() {
            (0, last, b)
        } else {
            (1, 0.0, 1.0)
        });
        let tail = (last - a).max(a.abs()).max(f64::MIN_POSITIVE.sqrt());
        integrate(
            |map, u| {
                if map == 0 {
                    self.at(u)
                } else {
                    let one_minus = 1.0 - u;
                    self.at(last + tail * u / one_minus) * (tail / (one_minus * one_minus))
                }
            },
            &segments,
            RELATIVE_TOLERANCE,
            MAX_BISECTIONS,
        )
    }

    /// ∫ over `[a, b]` (`b` may be `∞`) in closed form: `k·e^{−σt·a}·(−expm1(−σt·(b − a)))/σt`,
    /// exact and finite as `σt → 0` (the limit `k·(b − a)`), for large `σt·a` and for `b = ∞`.
    fn closed_form(&self, a: f64, b: f64) -> DVec3 {
        if !(a < b) {
            return DVec3::ZERO;
        }
        DVec3::from_array(std::array::from_fn(|c| {
            let (k, s) = (self.coef[c], self.sigma_t[c]);
            if k == 0.0 {
                0.0
            } else if s > 0.0 {
                let fraction = if b.is_finite() {
                    -(-s * (b - a)).exp_m1()
                } else {
                    1.0
                };
                k * (-s * a).exp() * (fraction / s)
            } else {
                k * (b - a)
            }
        }))
    }
}

/// In-scattered radiance (RGB) along the ray `origin + x·dir`, `0 ≤ x ≤ ds` (`ds = ∞` for
/// sky), from a directional `light`, with shadows: the directional integral of the [module
/// docs](super) over the [`directional_lit_intervals`], each by adaptive Gauss–Kronrod
/// quadrature to [`RELATIVE_TOLERANCE`](super::RELATIVE_TOLERANCE). Includes `σs` and `E`,
/// excludes the attenuated surface term (see [`transmittance`](super::transmittance)).
///
/// `dir` need not be unit length. Zero for `ds ≤ 0`, NaN `ds`, a zero or non-finite `dir` or
/// a non-finite origin; finite for every finite input (and for `ds = ∞`, since `σt ≥ σs`).
pub fn inscatter_directional(
    origin: DVec3,
    dir: DVec3,
    ds: f64,
    medium: &Medium,
    light: &DirectionalLight,
    occluders: &[Occluder],
) -> DVec3 {
    let Some(beam) = Beam::new(origin, dir, medium, light) else {
        return DVec3::ZERO;
    };
    directional_lit_intervals(origin, dir, ds, light, occluders)
        .into_iter()
        .map(|(a, b)| beam.quadrature(a, b))
        .sum()
}

/// The unshadowed value of [`inscatter_directional`] (no occluders), computed independently in
/// closed form: `σs·p(μ)·E·(e^{−σt·0} − e^{−σt·ds})/σt` per channel, as
/// `−expm1(−σt·ds)/σt`, so that it stays exact and finite as `σt → 0`, for large `σt·ds` and
/// for sky rays (`ds = ∞`: `1/σt`). Degenerate input as for [`inscatter_directional`].
pub fn inscatter_directional_closed_form(
    origin: DVec3,
    dir: DVec3,
    ds: f64,
    medium: &Medium,
    light: &DirectionalLight,
) -> DVec3 {
    match Beam::new(origin, dir, medium, light) {
        Some(beam) => beam.closed_form(0.0, ds),
        None => DVec3::ZERO,
    }
}

/// [`inscatter_directional`] for every pixel of a `width × height` image seen by `camera`,
/// with the conventions of [`inscatter_image`](super::inscatter_image).
pub fn inscatter_image_directional(
    camera: &Camera,
    width: u32,
    height: u32,
    distance: impl Fn(DVec3, DVec3) -> f64 + Sync,
    medium: &Medium,
    light: &DirectionalLight,
    occluders: &[Occluder],
) -> Vec<DVec3> {
    render(camera, width, height, |eye, dir| {
        inscatter_directional(eye, dir, distance(eye, dir), medium, light, occluders)
    })
}
