//! Phase functions in f64, written independently of the GPU's WGSL versions.

use std::f64::consts::PI;

use glam::DVec3;

use crate::scene::PhaseFunction;

/// The cosine `μ` of a scattering angle together with `1 − μ` and `1 + μ`, each computed by the
/// caller without cancellation, so that strongly peaked lobes keep their relative precision at
/// `μ → ±1`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Cosine {
    pub mu: f64,
    pub one_minus: f64,
    pub one_plus: f64,
}

impl Cosine {
    /// From `μ` alone (clamped to [−1, 1]).
    pub(crate) fn from_mu(mu: f64) -> Self {
        let mu = if mu.is_nan() {
            0.0
        } else {
            mu.clamp(-1.0, 1.0)
        };
        Self {
            mu,
            one_minus: 1.0 - mu,
            one_plus: 1.0 + mu,
        }
    }
}

/// Henyey–Greenstein with `1 + g² − 2gμ` written as a sum of non-negative terms.
fn henyey_greenstein(g: f64, c: Cosine) -> f64 {
    let base = if g >= 0.0 {
        (1.0 - g) * (1.0 - g) + 2.0 * g * c.one_minus
    } else {
        (1.0 + g) * (1.0 + g) - 2.0 * g * c.one_plus
    };
    if base <= 0.0 {
        // Only reachable for |g| = 1 (rejected by `PhaseFunction::validate`): a delta lobe.
        return if c.one_minus.min(c.one_plus) == 0.0 {
            f64::INFINITY
        } else {
            0.0
        };
    }
    (1.0 - g * g) / (4.0 * PI * base * base.sqrt())
}

fn rayleigh(c: Cosine) -> f64 {
    3.0 / (16.0 * PI) * (1.0 + c.mu * c.mu)
}

pub(crate) fn eval(phase: &PhaseFunction, c: Cosine) -> DVec3 {
    match *phase {
        PhaseFunction::Isotropic => DVec3::splat(1.0 / (4.0 * PI)),
        PhaseFunction::HenyeyGreenstein { g } => DVec3::splat(henyey_greenstein(g as f64, c)),
        PhaseFunction::Rayleigh => DVec3::splat(rayleigh(c)),
        PhaseFunction::HoffmanPreetham {
            rayleigh: r,
            mie,
            g,
        } => {
            let (r, m) = (r.as_dvec3(), mie.as_dvec3());
            let (pr, pm) = (rayleigh(c), henyey_greenstein(g as f64, c));
            let channel = |r: f64, m: f64| {
                let sum = r + m;
                if sum > 0.0 {
                    (r * pr + m * pm) / sum
                } else {
                    // Rejected by validation; fall back to an even mix instead of 0/0.
                    0.5 * (pr + pm)
                }
            };
            DVec3::new(channel(r.x, m.x), channel(r.y, m.y), channel(r.z, m.z))
        }
        PhaseFunction::MieHazy => {
            let u = 0.5 * c.one_plus;
            DVec3::splat((1.0 + 9.0 * u.powi(8)) / (8.0 * PI))
        }
        PhaseFunction::MieMurky => {
            let u = 0.5 * c.one_plus;
            DVec3::splat(33.0 * (1.0 + 50.0 * u.powi(32)) / (332.0 * PI))
        }
    }
}

/// The phase function `phase` at `mu`, the cosine of the scattering angle between the light's
/// direction of travel and the direction towards the eye (`mu = 1`: forward scattering, looking
/// straight at the light), in f64 and per RGB channel. Normalised: its integral over the sphere
/// is 1. `mu` is clamped to [−1, 1] (NaN reads as 0).
///
/// Formulas (written independently of the WGSL ones):
/// isotropic `1/(4π)`; Henyey–Greenstein `(1−g²)/(4π(1+g²−2gμ)^{3/2})`; Rayleigh
/// `3/(16π)(1+μ²)`; Hoffman–Preetham per channel `(βR·Rayleigh + βM·HG_g)/(βR + βM)`;
/// Mie hazy `(1 + 9((1+μ)/2)^8)/(8π)`; Mie murky `33(1 + 50((1+μ)/2)^32)/(332π)`.
pub fn phase(phase: &PhaseFunction, mu: f64) -> DVec3 {
    eval(phase, Cosine::from_mu(mu))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::quadrature::integrate;
    use glam::Vec3;

    #[test]
    fn every_phase_function_integrates_to_one() {
        let phases = [
            PhaseFunction::Isotropic,
            PhaseFunction::HenyeyGreenstein { g: 0.0 },
            PhaseFunction::HenyeyGreenstein { g: 0.5 },
            PhaseFunction::HenyeyGreenstein { g: 0.9 },
            PhaseFunction::HenyeyGreenstein { g: -0.9 },
            PhaseFunction::HenyeyGreenstein { g: 0.99 },
            PhaseFunction::Rayleigh,
            PhaseFunction::HoffmanPreetham {
                rayleigh: Vec3::new(5.8e-3, 1.35e-2, 3.31e-2),
                mie: Vec3::new(2e-2, 1e-2, 0.0),
                g: 0.76,
            },
            PhaseFunction::MieHazy,
            PhaseFunction::MieMurky,
        ];
        let mut worst = 0.0f64;
        for p in phases {
            // ∫ over the sphere = 2π ∫_{-1}^{1} p(μ) dμ, with breakpoints near the forward peak.
            let pieces = [-1.0, 0.0, 0.9, 0.99, 0.999, 1.0];
            let segments: Vec<(usize, f64, f64)> =
                pieces.windows(2).map(|w| (0, w[0], w[1])).collect();
            let total = integrate(|_, mu| phase(&p, mu), &segments, 1e-14, 10_000);
            for c in 0..3 {
                let err = (2.0 * PI * total[c] - 1.0).abs();
                worst = worst.max(err);
                assert!(err <= 1e-10, "{p:?} channel {c}: integral - 1 = {err:e}");
            }
        }
        println!("max |integral - 1| over the phase functions: {worst:e}");
    }

    #[test]
    fn cosine_forms_agree() {
        let p = PhaseFunction::HenyeyGreenstein { g: -0.95 };
        let a = phase(&p, -0.3);
        let b = eval(
            &p,
            Cosine {
                mu: -0.3,
                one_minus: 1.3,
                one_plus: 0.7,
            },
        );
        assert!((a - b).abs().max_element() <= 1e-15 * a.max_element());
    }
}
