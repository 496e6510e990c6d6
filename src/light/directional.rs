//! A directional light (the sun): parallel rays, cascaded maps fitted to the camera (drawn by
//! the shadow map node, which knows the occluders), a shadow distance stopped at what the
//! medium lets be seen.

use glam::{Mat4, Vec3};

use super::gpu::{LightUniform, LIGHT_DIRECTIONAL};
use super::{LightKind, LightModel, Source};
use crate::scene::{DirectionalLight, Light, Medium};

impl LightModel for DirectionalLight {
    fn source(&self) -> Source {
        Source::Along(self.direction())
    }
    fn radius(&self) -> f32 {
        0.0
    }
    fn kind(&self, _textured: bool) -> LightKind {
        LightKind::Directional
    }
    fn gpu(&self) -> LightUniform {
        LightUniform::common(LIGHT_DIRECTIONAL, self.direction(), self.irradiance(), 0.0)
    }
    fn without_radius(&self) -> Light {
        Light::Directional(*self)
    }
    /// One layer per cascade.
    fn layers(&self) -> u32 {
        self.cascades()
    }
    /// None here: the cascades are fitted to the camera.
    fn faces(&self, _near: f32, _occluder_distance: f32) -> Vec<Mat4> {
        Vec::new()
    }
    /// A sun without a shadow distance of its own gets the medium's
    /// [`shadow_reach`](crate::scene::Medium::shadow_reach) where its occluders reach farther
    /// from the eye than that: its cascades then cover the fog that can be seen, not the
    /// occluders' extent (the shadow map's default). A ground 1e5 wide spread them over its own
    /// size, and the map lost a roof's shadow above the eye (`tests/gpu/large_occluders.rs`).
    fn within_reach(
        &self,
        eye: Vec3,
        medium: &Medium,
        bounds: &mut dyn Iterator<Item = (Vec3, Vec3)>,
    ) -> Option<(Light, f32)> {
        let reach = medium
            .shadow_reach()
            .filter(|_| self.shadow_distance().is_none())?;
        let farthest = bounds
            .map(|(lo, hi)| (eye - lo).abs().max((eye - hi).abs()).length())
            .fold(0.0f32, f32::max);
        let stopped = self.with_shadow_distance(reach).ok();
        stopped
            .filter(|_| farthest > reach)
            .map(|sun| (Light::from(sun), reach))
    }
}
