//! The participating medium: scattering and absorption per RGB channel, and its phase function.

use glam::Vec3;

use crate::error::{finite, non_negative, Error, Result};

/// How a medium scatters light, as a function of the scattering angle θ between the light's
/// direction of travel and the direction towards the eye. Every variant is normalised so that its
/// integral over the sphere is 1 (isotropic = 1/(4π)).
///
/// Validated by [`Medium::new`] (and [`PhaseFunction::validate`]).
///
/// Used in the [crate-level example](crate#example).
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum PhaseFunction {
    /// `1/(4π)`.
    Isotropic,
    /// Henyey–Greenstein, `(1 − g²) / (4π (1 + g² − 2g cos θ)^{3/2})`, with `g` in (−1, 1):
    /// positive `g` scatters forward (bright halo looking towards the light).
    HenyeyGreenstein {
        /// Asymmetry parameter, the mean cosine of the scattering angle.
        g: f32,
    },
    /// Rayleigh (small particles, clear air), `3/(16π) (1 + cos² θ)`.
    Rayleigh,
    /// Hoffman–Preetham's sky model: Rayleigh plus a Henyey–Greenstein Mie lobe, mixed per
    /// channel in proportion to the two scattering coefficients. `rayleigh` and `mie` are the
    /// coefficients βR and βM (per world unit); [`Medium::hoffman_preetham`] also sets the
    /// medium's σs to their sum.
    HoffmanPreetham {
        /// Rayleigh scattering coefficient βR, RGB.
        rayleigh: Vec3,
        /// Mie scattering coefficient βM, RGB.
        mie: Vec3,
        /// Asymmetry of the Mie lobe, in (−1, 1).
        g: f32,
    },
    /// Nishita's "hazy" Mie approximation, `∝ 1 + 9 ((1 + cos θ)/2)^8` (Biri et al. 2006).
    MieHazy,
    /// Nishita's "murky" Mie approximation, `∝ 1 + 50 ((1 + cos θ)/2)^32` (Biri et al. 2006).
    MieMurky,
}

impl PhaseFunction {
    /// Checks the parameters: finite, `|g| < 1`, non-negative Hoffman–Preetham coefficients
    /// with a non-zero sum in every channel.
    ///
    /// # Errors
    ///
    /// [`Error::NonFinite`] for a non-finite parameter, [`Error::AsymmetryOutOfRange`] for `|g| ≥ 1`,
    /// [`Error::Negative`] for a negative Hoffman–Preetham coefficient, and [`Error::ZeroPhaseWeight`]
    /// when `rayleigh + mie` is zero in a channel.
    pub fn validate(&self) -> Result<()> {
        let check_g = |g: f32| {
            finite("phase.g", &[g])?;
            if g.abs() >= 1.0 {
                return Err(Error::AsymmetryOutOfRange { g });
            }
            Ok(())
        };
        match *self {
            PhaseFunction::Isotropic | PhaseFunction::Rayleigh => Ok(()),
            PhaseFunction::MieHazy | PhaseFunction::MieMurky => Ok(()),
            PhaseFunction::HenyeyGreenstein { g } => check_g(g),
            PhaseFunction::HoffmanPreetham { rayleigh, mie, g } => {
                check_g(g)?;
                non_negative("phase.rayleigh", &rayleigh.to_array())?;
                non_negative("phase.mie", &mie.to_array())?;
                let sum = rayleigh + mie;
                match (0..3).find(|&c| sum[c] <= 0.0) {
                    Some(channel) => Err(Error::ZeroPhaseWeight {
                        field: "phase (Hoffman-Preetham rayleigh + mie)",
                        channel,
                    }),
                    None => Ok(()),
                }
            }
        }
    }
}

/// A homogeneous participating medium. σs (scattering) and σa (absorption) are per world unit
/// and per RGB channel; the extinction σt = σs + σa attenuates, σs alone scatters.
///
/// Used in the [crate-level example](crate#example).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Medium {
    sigma_s: Vec3,
    sigma_a: Vec3,
    phase: PhaseFunction,
}

impl Medium {
    /// A medium with scattering `sigma_s`, absorption `sigma_a` (both ≥ 0 and finite, per
    /// channel) and a phase function.
    ///
    /// Used in the [crate-level example](crate#example).
    ///
    /// # Errors
    ///
    /// [`Error::NonFinite`] or [`Error::Negative`] naming `medium.sigma_s` or `medium.sigma_a`, and
    /// those of [`PhaseFunction::validate`] for the phase function.
    pub fn new(sigma_s: Vec3, sigma_a: Vec3, phase: PhaseFunction) -> Result<Self> {
        non_negative("medium.sigma_s", &sigma_s.to_array())?;
        non_negative("medium.sigma_a", &sigma_a.to_array())?;
        phase.validate()?;
        Ok(Self {
            sigma_s,
            sigma_a,
            phase,
        })
    }

    /// Hoffman–Preetham: σs = βR + βM, phase mixed per channel by βR and βM.
    ///
    /// # Errors
    ///
    /// Those of [`PhaseFunction::validate`] (non-finite or negative coefficients, `|g| ≥ 1`, a channel
    /// where `beta_rayleigh + beta_mie` is zero) and of [`Medium::new`] for `sigma_a`.
    pub fn hoffman_preetham(
        beta_rayleigh: Vec3,
        beta_mie: Vec3,
        g: f32,
        sigma_a: Vec3,
    ) -> Result<Self> {
        let phase = PhaseFunction::HoffmanPreetham {
            rayleigh: beta_rayleigh,
            mie: beta_mie,
            g,
        };
        phase.validate()?;
        Self::new(beta_rayleigh + beta_mie, sigma_a, phase)
    }

    /// Scattering coefficient σs, RGB.
    pub fn sigma_s(&self) -> Vec3 {
        self.sigma_s
    }
    /// Absorption coefficient σa, RGB.
    pub fn sigma_a(&self) -> Vec3 {
        self.sigma_a
    }
    /// Extinction coefficient σt = σs + σa, RGB.
    pub fn sigma_t(&self) -> Vec3 {
        self.sigma_s + self.sigma_a
    }

    /// The fraction of a ray's unshadowed in-scatter that [`shadow_reach`](Self::shadow_reach)
    /// leaves beyond it: far below every accuracy bar the crate is held to (the tightest is
    /// 1e-3 of the mean).
    pub const SHADOW_REACH_FRACTION: f32 = 1e-6;

    /// The distance along a ray beyond which the medium holds less than
    /// [`SHADOW_REACH_FRACTION`](Self::SHADOW_REACH_FRACTION) of the ray's unshadowed in-scatter
    /// (light of one direction, in every channel): `ln(1/fraction) / σt` for the least σt. The
    /// in-scatter beyond distance `D` is `e^(−σt·D)` of the whole ray's. `None` where a channel
    /// does not attenuate (its light reaches any distance). The planner bounds a directional
    /// light's default shadow distance by it.
    pub fn shadow_reach(&self) -> Option<f32> {
        let least = self.sigma_t().min_element();
        (least > 0.0).then(|| (1.0 / Self::SHADOW_REACH_FRACTION).ln() / least)
    }
    /// The phase function.
    pub fn phase(&self) -> PhaseFunction {
        self.phase
    }
}

impl PhaseFunction {
    /// Smallest and largest value of the phase function over all scattering angles, per RGB
    /// channel (exact for every variant; for Hoffman–Preetham, bounds of the per-channel mix).
    pub fn range(&self) -> (Vec3, Vec3) {
        use std::f32::consts::PI;
        let hg = |g: f32| {
            let a = g.abs();
            (
                (1.0 - a) / (4.0 * PI * (1.0 + a).powi(2)),
                (1.0 + a) / (4.0 * PI * (1.0 - a).powi(2)),
            )
        };
        let splat = |(lo, hi): (f32, f32)| (Vec3::splat(lo), Vec3::splat(hi));
        match *self {
            PhaseFunction::Isotropic => splat((0.25 / PI, 0.25 / PI)),
            PhaseFunction::HenyeyGreenstein { g } => splat(hg(g)),
            PhaseFunction::Rayleigh => splat((3.0 / (16.0 * PI), 6.0 / (16.0 * PI))),
            PhaseFunction::MieHazy => splat((1.0 / (8.0 * PI), 10.0 / (8.0 * PI))),
            PhaseFunction::MieMurky => splat((33.0 / (332.0 * PI), 33.0 * 51.0 / (332.0 * PI))),
            PhaseFunction::HoffmanPreetham { rayleigh, mie, g } => {
                let (rl, rh) = (3.0 / (16.0 * PI), 6.0 / (16.0 * PI));
                let (ml, mh) = hg(g);
                let sum = rayleigh + mie;
                (
                    (rayleigh * rl + mie * ml) / sum,
                    (rayleigh * rh + mie * mh) / sum,
                )
            }
        }
    }
}
