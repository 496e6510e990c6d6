//! Lights.

use glam::Vec3;

use crate::error::{finite, non_negative, Error, Result};

/// An isotropic point light: radiant intensity `intensity` (RGB, per steradian) at `position`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointLight {
    position: Vec3,
    intensity: Vec3,
}

impl PointLight {
    /// A point light. The position must be finite; the intensity finite, non-negative and
    /// non-zero in at least one channel.
    pub fn new(position: Vec3, intensity: Vec3) -> Result<Self> {
        finite("point_light.position", &position.to_array())?;
        non_negative("point_light.intensity", &intensity.to_array())?;
        if intensity.max_element() <= 0.0 {
            return Err(Error::ZeroIntensity {
                field: "point_light.intensity",
            });
        }
        Ok(Self {
            position,
            intensity,
        })
    }
    /// World-space position.
    pub fn position(&self) -> Vec3 {
        self.position
    }
    /// Radiant intensity, RGB.
    pub fn intensity(&self) -> Vec3 {
        self.intensity
    }
}
