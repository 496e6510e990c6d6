//! A spot light: one perspective face around its cone (widened for a light with a radius),
//! the cone the passes limit it to, and the frame its projected texture is drawn in.

use glam::{Mat4, Vec3};

use super::gpu::{LightUniform, LIGHT_SPOT};
use super::{LightKind, LightModel, Source};
use crate::scene::{Light, SpotLight};

/// A spot map's field of view: the cone inscribed in the square frustum, with a texel of
/// margin. For a light of radius r the lines from a point inside the cone to the light's
/// disc reach occluders outside it: one at distance b from the light lies up to
/// atan(r / b) off the point's direction, so the field widens by twice that at the least
/// occluder distance b (an occluder cut off by the map's edge would light its penumbra),
/// but at most to twice the cone's half-width on the map's plane (texels at most twice as
/// coarse: an occluder around the light, b = 0, would otherwise take the field to 179°).
/// Radius 0: the cone alone, as for hard shadows. Never wider than 179°
/// ([`SpotLight::MAX_CONE_ANGLE`], the widest cone, which the map then covers without
/// margin).
pub(crate) fn spot_fov(spot: &SpotLight, occluder_distance: f32) -> f32 {
    let cone = spot.cone_angle() * 1.02;
    // The widest field: the widest cone a spot may have (see `MAX_CONE_ANGLE` for why), so
    // every point of any cone is in its map.
    let max = SpotLight::MAX_CONE_ANGLE;
    if spot.radius() <= 0.0 {
        return cone.min(max);
    }
    let widened = cone + 2.0 * (spot.radius() / occluder_distance.max(0.0)).atan();
    let twice = 2.0 * (2.0 * (0.5 * cone).tan()).atan();
    widened.min(twice).min(max)
}

impl LightModel for SpotLight {
    fn source(&self) -> Source {
        Source::At(self.position())
    }
    fn radius(&self) -> f32 {
        SpotLight::radius(self)
    }
    fn kind(&self, textured: bool) -> LightKind {
        LightKind::Spot {
            soft: self.radius() > 0.0,
            textured,
        }
    }
    fn gpu(&self) -> LightUniform {
        let mut out =
            LightUniform::common(LIGHT_SPOT, self.position(), self.intensity(), self.radius());
        out.axis = self.direction().to_array();
        out.cos_half = self.cos_half_angle();
        out
    }
    fn without_radius(&self) -> Light {
        Light::Spot(self.with_radius(0.0).unwrap_or(*self))
    }
    fn layers(&self) -> u32 {
        1
    }
    fn faces(&self, near: f32, occluder_distance: f32) -> Vec<Mat4> {
        use glam::camera::rh::proj::directx::perspective_infinite_reverse;
        let fov = spot_fov(self, occluder_distance);
        let proj = perspective_infinite_reverse(fov, 1.0, near);
        vec![proj * self.texture_frame()]
    }
    fn map_half_tan(&self, occluder_distance: f32) -> f32 {
        (0.5 * spot_fov(self, occluder_distance)).tan()
    }
    /// The map it would then be drawn with is the hard light's, the cone's own; its texels
    /// are finest at the edge, `cos²(fov/2)` times the centre's.
    fn finest_texel(&self, occluder_distance: f32) -> Option<f32> {
        let hard = self.with_radius(0.0).unwrap_or(*self);
        let half = 0.5 * spot_fov(&hard, occluder_distance);
        Some(2.0 * half.tan() * half.cos().powi(2))
    }
    /// The axis, the cone and the radius (which widens the map's field: [`spot_fov`]).
    fn map_key(&self) -> Vec<u32> {
        let mut key: Vec<u32> = self.direction().to_array().map(f32::to_bits).to_vec();
        key.push(self.cone_angle().to_bits());
        key.push(self.radius().to_bits());
        key
    }
    fn cone(&self) -> Option<(Vec3, f32)> {
        Some((self.direction(), self.cos_half_angle()))
    }
    fn texture_frame(&self) -> Option<(Mat4, f32)> {
        Some((
            SpotLight::texture_frame(self),
            (0.5 * self.cone_angle()).tan(),
        ))
    }
}
