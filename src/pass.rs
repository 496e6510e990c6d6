//! The passes a frame can record: a leaf module that the nodes, the GPU timer and the planner
//! all name passes by.

use std::fmt;

/// A pass the facade can record.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Pass {
    /// A textured spot light's blurred mip chain and the map of its flat regions.
    LightTexture,
    /// Occluder depth from the light.
    ShadowMap,
    /// Shadow-volume extents along each view ray.
    Extents,
    /// The per-frame F′ table.
    AirlightTable,
    /// In-scattered light per pixel (analytic, hybrid or brute force).
    March,
    /// Low-resolution scattering brought to the output resolution.
    Upsample,
    /// Attenuated scene plus in-scattered light into the caller's target.
    Composite,
    /// The indirect single scattering table (light the medium scatters onto surfaces).
    IssTable,
    /// A light with a radius: the visible fraction of its disc on a light-space grid.
    SoftShadow,
}

impl Pass {
    /// Every pass, in the order a frame records them: each light's, then the frame's.
    pub const ALL: [Pass; 9] = [
        Pass::LightTexture,
        Pass::ShadowMap,
        Pass::Extents,
        Pass::SoftShadow,
        Pass::AirlightTable,
        Pass::March,
        Pass::Upsample,
        Pass::IssTable,
        Pass::Composite,
    ];

    /// Whether the pass records once per light (else once per frame).
    pub fn per_light(self) -> bool {
        !matches!(self, Pass::IssTable | Pass::Composite)
    }

    /// Whether the pass exists for the light the medium scatters, so that a frame whose
    /// medium scatters nothing (σs = 0) leaves it out; the composite still attenuates.
    pub fn needs_scattering(self) -> bool {
        !matches!(self, Pass::Composite)
    }

    /// The pass's name, as `Display` writes it.
    pub fn name(self) -> &'static str {
        match self {
            Pass::LightTexture => "light texture",
            Pass::ShadowMap => "shadow map",
            Pass::Extents => "extents",
            Pass::AirlightTable => "F' table",
            Pass::March => "march",
            Pass::Upsample => "upsample",
            Pass::Composite => "composite",
            Pass::IssTable => "ISS table",
            Pass::SoftShadow => "soft shadow",
        }
    }
}

impl fmt::Display for Pass {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::Pass;

    /// [`Pass::ALL`] holds every pass once: the match below is exhaustive, so a new pass does
    /// not compile here until it has a place, and that place must be its index in `ALL`.
    #[test]
    fn all_holds_every_pass_once_in_recording_order() {
        let place = |p: Pass| match p {
            Pass::LightTexture => 0,
            Pass::ShadowMap => 1,
            Pass::Extents => 2,
            Pass::SoftShadow => 3,
            Pass::AirlightTable => 4,
            Pass::March => 5,
            Pass::Upsample => 6,
            Pass::IssTable => 7,
            Pass::Composite => 8,
        };
        for (i, p) in Pass::ALL.into_iter().enumerate() {
            assert_eq!(place(p), i, "{p} at {i}");
        }
    }
}
