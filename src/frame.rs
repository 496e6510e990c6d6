//! [`Frame`]: one frame's scene and the caller's rendered frame, as
//! [`VolumetricShadows::prepare`](crate::VolumetricShadows::prepare) takes it.

use crate::gpu::Occluder;
use crate::light::LightKind;
use crate::scene::{Camera, Light, Medium, TextureChannels};

/// A light of the frame, with an optional texture for a spot light (any filterable format,
/// `TEXTURE_BINDING`, e.g. from [`LightTexture::upload`](crate::scene::LightTexture::upload)).
///
/// Used in the [crate-level example](crate#example).
#[derive(Clone, Copy)]
pub struct FrameLight<'a> {
    /// The light.
    pub light: Light,
    /// The spot's projected texture.
    pub texture: Option<&'a wgpu::Texture>,
    /// Which of the texture's channels count: its RGB (the default), or its red channel as a
    /// grey mask.
    pub texture_channels: TextureChannels,
    /// Indices into the frame's [`occluders`](Frame::occluders) of those that shadow this
    /// light (an engine's shadow-caster layers or flags); `None`: all of them. The planner's
    /// culling then works on these.
    pub casters: Option<&'a [usize]>,
}

impl FrameLight<'_> {
    /// What decides which pipelines this light's frames use (see [`Settings::warm_up`](crate::Settings::warm_up)).
    pub fn kind(&self) -> LightKind {
        self.light.model().kind(self.texture.is_some())
    }
}

impl From<Light> for FrameLight<'_> {
    fn from(light: Light) -> Self {
        Self {
            light,
            texture: None,
            texture_channels: TextureChannels::Rgb,
            casters: None,
        }
    }
}

/// One frame's scene and the caller's rendered frame.
///
/// Used in the [crate-level example](crate#example).
#[derive(Clone, Copy)]
pub struct Frame<'a> {
    /// The camera the frame was rendered with.
    pub camera: &'a Camera,
    /// Up to [`MAX_LIGHTS`](crate::nodes::MAX_LIGHTS) lights, summed.
    pub lights: &'a [FrameLight<'a>],
    /// The medium.
    pub medium: &'a Medium,
    /// The occluders (for every light).
    pub occluders: &'a [Occluder<'a>],
    /// The caller's shaded colour (float sample type, `TEXTURE_BINDING`), the output's size.
    pub scene_color: &'a wgpu::Texture,
    /// The caller's depth buffer (any depth format, `TEXTURE_BINDING`), the output's size.
    pub scene_depth: &'a wgpu::Texture,
    /// The surfaces' normals and albedo: when given (and the medium scatters), the composite
    /// adds the light the medium scatters onto them (see [`Surfaces`]); `None` leaves it out.
    pub surfaces: Option<Surfaces<'a>>,
}

/// Normals and albedo of the frame's surfaces, for the light the medium scatters onto them
/// (indirect single scattering, [`nodes::IssTableNode`](crate::nodes::IssTableNode)): each
/// surface pixel gets `(ρ/π)·E(P)` added to its colour before the medium attenuates it, `E(P)`
/// summed over the frame's point and spot lights (a spot's limited to its cone; see
/// [`CompositeSurfaces`](crate::nodes::CompositeSurfaces)), unshadowed. Sky pixels get none.
#[derive(Clone, Copy)]
pub struct Surfaces<'a> {
    /// World-space normals in rgb (any length; zero: no term), any format with a float sample
    /// type (`Rgba16Float`, `Rgba32Float`, `Rgba8Snorm`, …), usage `TEXTURE_BINDING`, the
    /// output's size.
    pub normal: &'a wgpu::Texture,
    /// Diffuse albedo `ρ` in rgb (zero: no term), any format with a float sample type, usage
    /// `TEXTURE_BINDING`, the output's size.
    pub albedo: &'a wgpu::Texture,
}
