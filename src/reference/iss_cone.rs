//! The cone-limited surface term of a spot light, in f64, by its own reduction.
//!
//! Directions `ω` leaving `P` are taken about `l`, the unit direction to the apex:
//! `ω = cos γ·l + sin γ·(cos φ·e1 + sin φ·e2)`. The ray at `(γ, φ)` lies in the half-plane
//! bounded by the line through `P` and the apex at angle `φ`, and the cone (a set of rays from
//! the apex) meets that half-plane in a wedge of directions from the apex: with `β` the angle
//! from the direction apex → `P`, `u(β) = cos β·p̂ + sin β·e_φ` is inside iff
//! `a·u = R·cos(β − β₀) ≥ c` (`R = |(a·p̂, a·e_φ)|`), so `β ∈ [β₀ − δ, β₀ + δ] ∩ [0, π]`,
//! `δ = acos(c/R)`. A point of the ray seen from the apex at angle `β` is where the airlight's
//! half scattering angle is `ξ = (γ + β)/2` (the triangle apex, `P`, point), so the in-cone part
//! of the ray is `ξ ∈ [(γ + β₁)/2, min((γ + β₂)/2, π/2)]`, and in units of the point light's
//! scale `σs·I0·e^{−σt·D}/D`
//!
//! ```text
//! G_cone = ∫₀^{2π} dφ ∫₀^π dγ (ω·n)₊ · 2∫_{ξ range} p(cos 2ξ)·e^{−τ·sin γ·(tan ξ − tan(γ/2))} dξ
//! ```
//!
//! (the point light's `G` has `β₁ = 0`, `β₂ = π`). [`surface_inscatter_cone`] integrates it by
//! nested adaptive Gauss–Kronrod quadrature, each level split where its integrand has a kink
//! (the ends of the wedge's `φ` range, the limits of `ω·n > 0`, `γ = π − β₂`, and the decay
//! scales of the glow and of the attenuation). `tests/gpu/iss_spot.rs` checks it against a brute-
//! force midpoint rule over the sphere with [`super::inscatter`] along each direction.

use std::f64::consts::{FRAC_PI_2, PI};

use glam::DVec3;

use super::phase::{self, Cosine};
use super::quadrature::integrate;
use super::unit;
use crate::scene::{Medium, SpotLight};

/// Relative tolerance of each level.
const TOLERANCE: f64 = 1e-9;
const BISECTIONS: usize = 200;

/// `E(P)` per RGB channel from `spot` (its cone only), unshadowed, the medium extending to
/// infinity: the same quantity as [`super::surface_inscatter`] for a spot light, computed
/// through its wedge reduction ([`crate::method`], §4). Zero for a zero or non-finite `n`;
/// `+∞` (where `σs·I0 > 0`) at the apex.
pub fn surface_inscatter_cone(p: DVec3, n: DVec3, medium: &Medium, spot: &SpotLight) -> DVec3 {
    let apex = spot.position().as_dvec3();
    let coef = medium.sigma_s().as_dvec3() * spot.intensity().as_dvec3();
    let Some(n) = unit(n) else {
        return DVec3::ZERO;
    };
    let w0 = p - apex;
    let d = w0.length();
    if !w0.is_finite() || coef == DVec3::ZERO {
        return DVec3::ZERO;
    }
    if d == 0.0 {
        return DVec3::from_array(
            coef.to_array()
                .map(|c| if c > 0.0 { f64::INFINITY } else { 0.0 }),
        );
    }
    let to_p = w0 / d;
    let l = -to_p;
    let axis = spot.direction().as_dvec3().normalize();
    let c = f64::from(spot.cos_half_angle());
    let ca = n.dot(l);
    let perp = n - l * ca;
    let sa = perp.length();
    let e1 = if sa > 1e-12 {
        perp / sa
    } else {
        l.any_orthonormal_vector()
    };
    let e2 = l.cross(e1);
    let (ap, a1, a2) = (axis.dot(to_p), axis.dot(e1), axis.dot(e2));
    let sigma_t = medium.sigma_t().as_dvec3();
    let tau = sigma_t * d;
    let phase_fn = medium.phase();
    let tmax = tau.max_element();

    // The ξ integral of one ray: s = ξ − γ/2 over [lo/2, hi/2].
    let xi_integral = |g: f64, lo: f64, hi: f64| -> DVec3 {
        let (a, b) = (0.5 * lo, 0.5 * hi);
        if !(b > a) {
            return DVec3::ZERO;
        }
        let rest = 0.5 * (PI - g);
        let half_c = (0.5 * g).cos();
        let k = tau * g.sin();
        let f = |_, s: f64| {
            let comp = (rest - s).max(0.0);
            let (cos_xi, sin_xi) = comp.sin_cos();
            let cosine = Cosine {
                mu: (cos_xi - sin_xi) * (cos_xi + sin_xi),
                one_minus: 2.0 * sin_xi * sin_xi,
                one_plus: 2.0 * cos_xi * cos_xi,
            };
            let r = if cos_xi > 0.0 {
                s.sin() / (cos_xi * half_c)
            } else {
                f64::INFINITY
            };
            let decay = DVec3::from_array(std::array::from_fn(|i| {
                if k[i] > 0.0 {
                    (-k[i] * r).exp()
                } else {
                    1.0
                }
            }));
            phase::eval(&phase_fn, cosine) * decay * 2.0
        };
        let mut pts = vec![a, b];
        let kmax = k.max_element();
        if kmax > 0.0 {
            let cos0 = (rest - a).max(0.0).sin();
            let scale = cos0 * cos0 / kmax;
            pts.extend([1.0, 4.0, 16.0, 64.0].map(|m| a + m * scale));
        }
        pts.retain(|&s| (a..=b).contains(&s));
        pts.sort_by(f64::total_cmp);
        pts.dedup();
        let segs: Vec<_> = pts.windows(2).map(|w| (0, w[0], w[1])).collect();
        integrate(f, &segs, TOLERANCE, BISECTIONS)
    };

    // The γ integral of the half-plane at φ.
    let half_plane = |f: f64| -> DVec3 {
        let (sf, cf) = f.sin_cos();
        let ae = a1 * cf + a2 * sf;
        let r2c2 = ap * ap + ae * ae - c * c;
        if !(r2c2 > 0.0) {
            return DVec3::ZERO;
        }
        let beta0 = ae.atan2(ap);
        let delta = r2c2.sqrt().atan2(c);
        let (b1, b2) = ((beta0 - delta).max(0.0), (beta0 + delta).min(PI));
        if !(b2 > b1) {
            return DVec3::ZERO;
        }
        let sc = sa * cf;
        let gn = sc.atan2(ca);
        let (mut lo, mut hi) = ((gn - FRAC_PI_2).max(0.0), (gn + FRAC_PI_2).min(PI));
        if gn < -FRAC_PI_2 {
            (lo, hi) = (gn + 1.5 * PI, PI);
        }
        hi = hi.min(PI - b1);
        if !(hi > lo) {
            return DVec3::ZERO;
        }
        let mut pts = vec![lo, hi, PI - b2];
        if tmax > 0.0 {
            pts.extend([1.0 / 16.0, 0.25, 1.0, 4.0].map(|m| m / tmax));
        }
        pts.retain(|&g| (lo..=hi).contains(&g));
        pts.sort_by(f64::total_cmp);
        pts.dedup();
        let segs: Vec<_> = pts.windows(2).map(|w| (0, w[0], w[1])).collect();
        integrate(
            |_, g: f64| {
                let cos_n = ca * g.cos() + sc * g.sin();
                if cos_n <= 0.0 {
                    return DVec3::ZERO;
                }
                xi_integral(g, b1, b2.min(PI - g)) * cos_n
            },
            &segs,
            TOLERANCE,
            BISECTIONS,
        )
    };

    let g = if ap.abs() >= c {
        // Every half-plane meets the cone; split where ω·n's limits switch (cos φ = 0).
        let segs = [
            (0, 0.0, FRAC_PI_2),
            (0, FRAC_PI_2, PI),
            (0, PI, 1.5 * PI),
            (0, 1.5 * PI, 2.0 * PI),
        ];
        integrate(|_, f| half_plane(f), &segs, TOLERANCE, BISECTIONS)
    } else {
        let big_a = a1.hypot(a2);
        let s = ((c - ap) * (c + ap)).max(0.0).sqrt();
        if !(big_a > s) {
            return DVec3::ZERO;
        }
        let w = ((big_a - s) * (big_a + s)).max(0.0).sqrt().atan2(s);
        let phia = a2.atan2(a1);
        // φ = φa + w·sin t smooths the square-root ends of the arc.
        let mut pts = vec![-FRAC_PI_2, 0.0, FRAC_PI_2];
        // Where cos φ = 0 inside the arc.
        for k in -3..=3 {
            let fz = FRAC_PI_2 + PI * f64::from(k);
            let x = (fz - phia) / w;
            if x.abs() < 1.0 {
                pts.push(x.asin());
            }
        }
        pts.sort_by(f64::total_cmp);
        pts.dedup();
        let segs: Vec<_> = pts.windows(2).map(|w| (0, w[0], w[1])).collect();
        integrate(
            |_, t: f64| half_plane(phia + w * t.sin()) * (w * t.cos()),
            &segs,
            TOLERANCE,
            BISECTIONS,
        )
    };
    let decay = (-sigma_t * d).exp();
    DVec3::from_array(std::array::from_fn(|i| {
        if coef[i] > 0.0 {
            coef[i] * decay[i] / d * g[i]
        } else {
            0.0
        }
    }))
}
