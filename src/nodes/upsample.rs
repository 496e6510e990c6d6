//! Low-resolution scattering and the bilateral upsample node (seed papers 000 §3.3 and 003).

use crate::error::{finite, Error, Result};

/// Resolution of the scattering passes (extents and march) relative to the output.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Scale {
    /// Same as the output: no upsample pass.
    #[default]
    Full,
    /// Half the output's width and height.
    Half,
    /// A quarter of the output's width and height.
    Quarter,
}

impl Scale {
    /// 1, 2 or 4.
    pub fn divisor(self) -> u32 {
        match self {
            Scale::Full => 1,
            Scale::Half => 2,
            Scale::Quarter => 4,
        }
    }

    /// The scale whose divisor is `divisor`; any other value is an error.
    pub fn from_divisor(divisor: u32) -> Result<Self> {
        match divisor {
            1 => Ok(Scale::Full),
            2 => Ok(Scale::Half),
            4 => Ok(Scale::Quarter),
            _ => Err(Error::InvalidSetting {
                field: "scattering scale",
                problem: format!("must be 1, 1/2 or 1/4 of the output, got 1/{divisor}"),
            }),
        }
    }

    /// The scattering size for an output size (at least one pixel each way).
    pub fn apply(self, width: u32, height: u32) -> (u32, u32) {
        let d = self.divisor();
        (width.div_ceil(d).max(1), height.div_ceil(d).max(1))
    }
}

/// How low-resolution scattering is brought to the output resolution.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum UpsampleFilter {
    /// Plain bilinear, blind to depth: blends across depth edges. A baseline for tests.
    Bilinear,
    /// Seed 000 §3.3: a 3×3 Gaussian over the low-resolution samples whose depth matches the
    /// full-resolution pixel's; falls back to the nearest-depth sample when none matches.
    DepthAware3x3,
    /// Seed 003: a separable N-tap bilateral (horizontal then vertical), weights
    /// `exp(−d²/2σs²) · exp(−Δz²/2σz²)` with Δz relative to the pixel's depth.
    Separable {
        /// Taps per direction (odd, 3 ..= 31).
        taps: u32,
        /// Spatial sigma in low-resolution pixels (> 0).
        sigma_spatial: f32,
        /// Depth sigma, relative to the pixel's eye distance (> 0).
        sigma_depth: f32,
    },
}

impl Default for UpsampleFilter {
    fn default() -> Self {
        UpsampleFilter::DepthAware3x3
    }
}

impl UpsampleFilter {
    /// Checks the separable filter's parameters.
    pub fn validate(&self) -> Result<()> {
        if let UpsampleFilter::Separable {
            taps,
            sigma_spatial,
            sigma_depth,
        } = *self
        {
            if !(3..=31).contains(&taps) || taps % 2 == 0 {
                return Err(Error::InvalidSetting {
                    field: "upsample.taps",
                    problem: format!("must be odd and in 3..=31, got {taps}"),
                });
            }
            finite("upsample.sigma_spatial", &[sigma_spatial])?;
            finite("upsample.sigma_depth", &[sigma_depth])?;
            if sigma_spatial <= 0.0 || sigma_depth <= 0.0 {
                return Err(Error::InvalidSetting {
                    field: "upsample sigma",
                    problem: format!(
                        "sigmas must be > 0, got spatial {sigma_spatial}, depth {sigma_depth}"
                    ),
                });
            }
        }
        Ok(())
    }
}
