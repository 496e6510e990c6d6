//! A light resolved once: everything the planner and the nodes ask of a light, answered by its
//! kind's own file (`point.rs`, `spot.rs`, `directional.rs`) through one trait,
//! [`LightModel`], so that nothing above this module branches on which light it has.
//!
//! What a pass asks: where the light's rays come from ([`Source`]: point-like or
//! direction-like, the question the reference's geometry asks too), its GPU form
//! ([`LightUniform`]), its shadow projection (layers, faces, near plane, what reaches each
//! layer), what its map's texels resolve (whether a radius is worth drawing), its cull bound,
//! whether it has a cone or a texture frame, and its pipeline [`LightKind`]. The shaders' side
//! is `shaders/light/`: one file per kind behind one switch on the `LIGHT` constant.
//!
//! Adding a kind: its public type and `Light` variant (`scene/light.rs`), its file here
//! implementing [`LightModel`], its WGSL file, its scene-file form and the reference's
//! integration of it.

mod cube;
mod directional;
mod gpu;
mod point;
mod spot;

use glam::{Mat4, Vec3, Vec4};

use crate::scene::{Light, Medium};

pub(crate) use gpu::{light_constant, LightUniform};
#[cfg(test)]
pub(crate) use gpu::{LIGHT_DIRECTIONAL, LIGHT_POINT, LIGHT_SPOT};
pub(crate) use spot::spot_fov;

/// Where a light's rays come from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Source {
    /// A point-like light at this position (its rays spread from it).
    At(Vec3),
    /// A direction-like light: parallel rays travelling along this unit direction.
    Along(Vec3),
}

/// What the planner and the nodes ask of a light, answered by each kind in its own file.
/// [`Light::model`] gives a light's.
pub(crate) trait LightModel {
    /// Where its rays come from.
    fn source(&self) -> Source;
    /// Its radius (0: a point, or a light that has none).
    fn radius(&self) -> f32;
    /// What decides its pipelines; `textured`: frames give it a projected texture.
    fn kind(&self, textured: bool) -> LightKind;
    /// Its GPU form, as every shader reads it.
    fn gpu(&self) -> LightUniform;
    /// The same light with radius 0 (itself where it has none).
    fn without_radius(&self) -> Light;
    /// Its shadow map's layers.
    fn layers(&self) -> u32;
    /// Its shadow map's face matrices with near plane `near` (reversed-Z infinite
    /// perspectives), `occluder_distance` the least distance from the light to an occluder.
    /// Empty for a light whose faces are fitted to the camera (a sun's cascades).
    fn faces(&self, near: f32, occluder_distance: f32) -> Vec<Mat4>;
    /// Per layer, the bounding spheres (indices) that reach it (what the layer draws), where
    /// the layers see different parts of the scene; `None`: every layer draws every occluder.
    fn layer_draws(&self, _spheres: &[Vec4]) -> Option<Vec<Vec<u32>>> {
        None
    }
    /// Which of its layers any of `spheres` reaches; `None`: all of them.
    fn layers_reached(&self, _spheres: &[Vec4]) -> Option<[bool; 6]> {
        None
    }
    /// The tangent of half its map's field of view (square faces), with `occluder_distance`
    /// as for [`faces`](Self::faces).
    fn map_half_tan(&self, _occluder_distance: f32) -> f32 {
        1.0
    }
    /// The finest texel of its map, one texel across (a tangent; divide by the resolution),
    /// were it drawn without its radius: what its penumbrae must exceed to be worth drawing
    /// soft. `None`: a light without a radius to lose.
    fn finest_texel(&self, _occluder_distance: f32) -> Option<f32> {
        None
    }
    /// What its map depends on besides its source and the occluders (as bits).
    fn map_key(&self) -> Vec<u32> {
        Vec::new()
    }
    /// The near plane of `faces` where they are the cube faces [`faces`](Self::faces) gives
    /// (the shaders then project by permutation), else 0.
    fn cube_near(&self, _faces: &[Mat4]) -> f32 {
        0.0
    }
    /// Its cone: unit axis and cosine of half the apex angle.
    fn cone(&self) -> Option<(Vec3, f32)> {
        None
    }
    /// The frame a projected texture is drawn in and the tangent of half the cone's angle:
    /// `None` for a light that takes no texture.
    fn texture_frame(&self) -> Option<(Mat4, f32)> {
        None
    }
    /// An upper bound of how much an occluder with world `bounds` can change any pixel's
    /// in-scatter relative to the unshadowed in-scatter of a ray that reaches it (see
    /// [`crate::plan`]'s culling); infinite where no bound applies.
    fn cull_bound(&self, _eye: Vec3, _medium: &Medium, _bounds: (Vec3, Vec3)) -> f64 {
        f64::INFINITY
    }
    /// The light fitted to what the medium lets be seen from `eye`, with the distance its
    /// shadows stop at, where that differs from the light as given (a sun whose occluders,
    /// of world `bounds`, reach beyond the medium's shadow reach gets that as its shadow
    /// distance); `None`: as given.
    fn within_reach(
        &self,
        _eye: Vec3,
        _medium: &Medium,
        _bounds: &mut dyn Iterator<Item = (Vec3, Vec3)>,
    ) -> Option<(Light, f32)> {
        None
    }
}

impl Light {
    /// What the planner and the nodes ask of this light: the one match on its kind.
    pub(crate) fn model(&self) -> &dyn LightModel {
        match self {
            Light::Point(l) => l,
            Light::Spot(l) => l,
            Light::Directional(l) => l,
        }
    }
}

/// What decides which pipelines a light's frames use (see
/// [`Cache::warm_up`](crate::Cache::warm_up)); a frame's light gives its own with
/// [`FrameLight::kind`](crate::FrameLight::kind).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LightKind {
    /// A point light; `soft` when it has a radius.
    Point {
        /// The light has a radius (soft shadows).
        soft: bool,
    },
    /// A spot light; `soft` when it has a radius, `textured` when frames give it a texture.
    Spot {
        /// The light has a radius (soft shadows).
        soft: bool,
        /// Frames give the spot a projected texture.
        textured: bool,
    },
    /// A directional light.
    Directional,
}

impl LightKind {
    /// Every kind.
    pub const ALL: [LightKind; 7] = [
        LightKind::Point { soft: false },
        LightKind::Point { soft: true },
        LightKind::Spot {
            soft: false,
            textured: false,
        },
        LightKind::Spot {
            soft: true,
            textured: false,
        },
        LightKind::Spot {
            soft: false,
            textured: true,
        },
        LightKind::Spot {
            soft: true,
            textured: true,
        },
        LightKind::Directional,
    ];
}

impl LightKind {
    /// [`LightUniform::kind`] of lights of this kind.
    pub(crate) fn gpu(self) -> u32 {
        match self {
            LightKind::Point { .. } => gpu::LIGHT_POINT,
            LightKind::Spot { .. } => gpu::LIGHT_SPOT,
            LightKind::Directional => gpu::LIGHT_DIRECTIONAL,
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
