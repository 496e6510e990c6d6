//! What a light's map resolves: a spot map's field of view, and whether a light's penumbrae
//! are narrower than a texel (the planner's [`penumbra_below_texel`]). The answers are the
//! light's own ([`crate::light`]); these are the node's public names for them.
//!
//! [`penumbra_below_texel`]: ShadowMapNode::penumbra_below_texel

use crate::scene::Light;

use super::ShadowMapNode;

impl ShadowMapNode {
    /// A spot map's field of view: the cone inscribed in the square frustum, with a texel of
    /// margin. For a light of radius r the lines from a point inside the cone to the light's
    /// disc reach occluders outside it: one at distance b from the light lies up to
    /// atan(r / b) off the point's direction, so the field widens by twice that at the least
    /// occluder distance b (an occluder cut off by the map's edge would light its penumbra),
    /// but at most to twice the cone's half-width on the map's plane (texels at most twice as
    /// coarse: an occluder around the light, b = 0, would otherwise take the field to 179°).
    /// Radius 0: the cone alone, as for hard shadows. Never wider than 179°
    /// ([`SpotLight::MAX_CONE_ANGLE`](crate::SpotLight::MAX_CONE_ANGLE), the widest cone, which
    /// the map then covers without margin).
    pub fn spot_fov(spot: &crate::scene::SpotLight, occluder_distance: f32) -> f32 {
        crate::light::spot_fov(spot, occluder_distance)
    }

    /// Whether `light`'s penumbrae are narrower than the finest texel of its shadow map of
    /// `resolution` texels across, wherever they are: its radius is then below what the map
    /// resolves, and hard shadows (radius 0) are the better image. Seen from the light, a
    /// penumbra cast by an occluder at distance b spans `2 · radius · (1/b − 1/d)` (as a
    /// tangent) at distance d, less than `2 · radius / occluder_distance`; a map's texels span
    /// `2 · tan(fov/2) / resolution` at its centre and `cos²(fov/2)` times that at the edge
    /// of a spot's map, a third of it at a cube face's corner. False for a radius of 0 (hard
    /// already), a directional light, or an occluder distance of 0.
    ///
    /// [`VolumetricShadows`](crate::VolumetricShadows) draws such a light hard: the exact
    /// method's integration between the shadow's boundaries beats marching a penumbra the map
    /// cannot show (`tests/gpu/soft_grid.rs`'s extreme-lights test compares the two;
    /// `docs/ACCURACY.md`).
    pub fn penumbra_below_texel(light: &Light, occluder_distance: f32, resolution: u32) -> bool {
        let radius = light.radius();
        if !(radius > 0.0 && occluder_distance > 0.0) || resolution == 0 {
            return false;
        }
        let Some(finest) = light.model().finest_texel(occluder_distance) else {
            return false;
        };
        2.0 * radius / occluder_distance <= finest / resolution as f32
    }

    /// Cosine of the widest angle between a face's axis and a direction inside its frustum
    /// (a corner of the square): the near plane lies along the axis, so a point at distance r
    /// can be as near as r times this along it.
    pub(super) fn corner_cosine(light: &Light, occluder_distance: f32) -> f32 {
        let half_tan = light.model().map_half_tan(occluder_distance);
        1.0 / (1.0 + 2.0 * half_tan * half_tan).sqrt()
    }
}
