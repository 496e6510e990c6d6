//! The light as every node's shader reads it: WGSL `Light` (`shaders/prelude.wgsl`), resolved
//! from the scene's [`Light`] by [`LightUniform::new`], and the `LIGHT` pipeline constant that
//! specialises a pipeline for a kind of light. These are the one place where a light's kind
//! becomes GPU data; a node copies the uniform into its parameters rather than matching on the
//! light.

use bytemuck::{Pod, Zeroable};

use crate::nodes::LightKind;
use crate::scene::Light;

/// WGSL `LIGHT_POINT`, `LIGHT_SPOT` and `LIGHT_DIRECTIONAL`: the values of [`LightUniform::kind`]
/// and of the `LIGHT` pipeline constant.
pub(crate) const LIGHT_POINT: u32 = 0;
pub(crate) const LIGHT_SPOT: u32 = 1;
pub(crate) const LIGHT_DIRECTIONAL: u32 = 2;

/// WGSL `Light`, field by field (see there what each holds).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub(crate) struct LightUniform {
    pub position: [f32; 3],
    pub kind: u32,
    pub intensity: [f32; 3],
    pub radius: f32,
    pub axis: [f32; 3],
    pub cos_half: f32,
}

impl LightUniform {
    /// The light as the shaders read it.
    pub fn new(light: &Light) -> Self {
        let mut out = Self {
            kind: Self::kind_of(light),
            intensity: light.intensity().to_array(),
            radius: light.radius(),
            ..Self::zeroed()
        };
        match light {
            Light::Point(p) => out.position = p.position().to_array(),
            Light::Spot(s) => {
                out.position = s.position().to_array();
                out.axis = s.direction().to_array();
                out.cos_half = s.cos_half_angle();
            }
            Light::Directional(d) => out.position = d.direction().to_array(),
        }
        out
    }

    /// [`LightUniform::kind`] of `light`.
    pub fn kind_of(light: &Light) -> u32 {
        match light {
            Light::Point(_) => LIGHT_POINT,
            Light::Spot(_) => LIGHT_SPOT,
            Light::Directional(_) => LIGHT_DIRECTIONAL,
        }
    }
}

/// The `LIGHT` pipeline constant of a pipeline for lights of `kind`.
pub(crate) fn light_constant(kind: u32) -> (&'static str, f64) {
    ("LIGHT", f64::from(kind))
}

impl LightKind {
    /// [`LightUniform::kind`] of lights of this kind.
    pub(crate) fn gpu(self) -> u32 {
        match self {
            LightKind::Point { .. } => LIGHT_POINT,
            LightKind::Spot { .. } => LIGHT_SPOT,
            LightKind::Directional => LIGHT_DIRECTIONAL,
        }
    }

    /// Lights of this kind have a radius (soft shadows).
    pub(crate) fn soft(self) -> bool {
        matches!(
            self,
            LightKind::Point { soft: true } | LightKind::Spot { soft: true, .. }
        )
    }

    /// Frames give lights of this kind a projected texture.
    pub(crate) fn textured(self) -> bool {
        matches!(self, LightKind::Spot { textured: true, .. })
    }
}

#[cfg(test)]
mod tests {
    use super::{LightUniform, LIGHT_DIRECTIONAL, LIGHT_POINT, LIGHT_SPOT};
    use crate::nodes::layout::{assert_constants, assert_same, rust_layout};

    #[test]
    fn the_light_s_layout_and_kinds_match_the_wgsl() {
        let rust = rust_layout!(LightUniform {
            position,
            kind,
            intensity,
            radius,
            axis,
            cos_half,
        });
        assert_same(rust, "#import prelude.wgsl", "Light");
        assert_constants(
            "#import prelude.wgsl",
            &[
                ("LIGHT_POINT", LIGHT_POINT),
                ("LIGHT_SPOT", LIGHT_SPOT),
                ("LIGHT_DIRECTIONAL", LIGHT_DIRECTIONAL),
            ],
        );
    }
}
