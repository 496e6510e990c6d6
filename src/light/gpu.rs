//! The light as every node's shader reads it: WGSL `Light` (`shaders/shared/prelude.wgsl`), which
//! each kind fills in its [`gpu`](super::LightModel::gpu), and the `LIGHT` pipeline constant
//! that specialises a pipeline for a kind of light. A node copies the uniform into its
//! parameters rather than matching on the light.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

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
        light.model().gpu()
    }

    /// The fields every kind has: its kind, `position` (a direction-like light's direction of
    /// travel), its intensity and radius; no cone.
    pub(super) fn common(kind: u32, position: Vec3, intensity: Vec3, radius: f32) -> Self {
        Self {
            position: position.to_array(),
            kind,
            intensity: intensity.to_array(),
            radius,
            ..Self::zeroed()
        }
    }
}

/// The `LIGHT` pipeline constant of a pipeline for lights of `kind`.
pub(crate) fn light_constant(kind: u32) -> (&'static str, f64) {
    ("LIGHT", f64::from(kind))
}
