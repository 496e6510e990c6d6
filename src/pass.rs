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
