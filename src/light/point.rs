//! A point light: six cube faces around it, layers drawing only the occluders that reach them,
//! and the one cull bound the planner has.

use glam::{Mat4, Vec3, Vec4};

use super::cube::{cube_face_draws, cube_faces, cube_faces_touched, standard_cube_near};
use super::gpu::{LightUniform, LIGHT_POINT};
use super::{LightKind, LightModel, Source};
use crate::scene::{Light, Medium, PointLight};

impl LightModel for PointLight {
    fn source(&self) -> Source {
        Source::At(self.position())
    }
    fn radius(&self) -> f32 {
        PointLight::radius(self)
    }
    fn kind(&self, _textured: bool) -> LightKind {
        LightKind::Point {
            soft: self.radius() > 0.0,
        }
    }
    fn gpu(&self) -> LightUniform {
        LightUniform::common(
            LIGHT_POINT,
            self.position(),
            self.intensity(),
            self.radius(),
        )
    }
    fn without_radius(&self) -> Light {
        Light::Point(self.with_radius(0.0).unwrap_or(*self))
    }
    fn layers(&self) -> u32 {
        6
    }
    fn faces(&self, near: f32, _occluder_distance: f32) -> Vec<Mat4> {
        cube_faces(self.position(), near).to_vec()
    }
    fn layer_draws(&self, spheres: &[Vec4]) -> Option<Vec<Vec<u32>>> {
        Some(cube_face_draws(self.position(), spheres))
    }
    fn layers_reached(&self, spheres: &[Vec4]) -> Option<[bool; 6]> {
        Some(cube_faces_touched(self.position(), spheres))
    }
    /// A cube face's texels are finest at its corners, a third of the centre's.
    fn finest_texel(&self, _occluder_distance: f32) -> Option<f32> {
        Some(2.0 / 3.0)
    }
    fn cube_near(&self, faces: &[Mat4]) -> f32 {
        standard_cube_near(faces, self.position())
    }
    /// Every point an occluder shadows is at least `r` from the light and `e` from the eye,
    /// so its loss is at most `σs·p_max·I0·exp(−σt (r + e))·π/r`, while the first
    /// `l = min(e, D)/2` of that ray gather at least `l·σs·p_min·I0·exp(−σt (D + 2l))/(D + l)²`.
    /// Infinite when the eye or the light is inside the bounds. For a light of radius `R` a
    /// point it partially shadows is beyond the occluder on a line from a point of the light,
    /// so at least `r − 2R` from the centre: `r` is reduced by `2R` (∞ when that leaves
    /// nothing).
    fn cull_bound(&self, eye: Vec3, medium: &Medium, bounds: (Vec3, Vec3)) -> f64 {
        let p = self.position();
        let r = f64::from(p.clamp(bounds.0, bounds.1).distance(p)) - 2.0 * f64::from(self.radius());
        let e = f64::from(eye.clamp(bounds.0, bounds.1).distance(eye));
        let d = f64::from(p.distance(eye));
        if r <= 0.0 || e <= 0.0 || d <= 0.0 {
            return f64::INFINITY;
        }
        let l = 0.5 * e.min(d);
        let (p_min, p_max) = medium.phase().range();
        let sigma_s = medium.sigma_s();
        let sigma_t = medium.sigma_t();
        (0..3)
            .filter(|&c| sigma_s[c] > 0.0)
            .map(|c| {
                let log = (f64::from(p_max[c]) / f64::from(p_min[c])).ln()
                    + (std::f64::consts::PI / r).ln()
                    + 2.0 * (d + l).ln()
                    - l.ln()
                    - f64::from(sigma_t[c]) * (r + e - d - 2.0 * l);
                log.exp()
            })
            .fold(0.0, f64::max)
    }
}
