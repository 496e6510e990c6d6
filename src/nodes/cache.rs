//! The shared, long-lived GPU objects: one handle holding each node's layouts and pipelines,
//! which the nodes define in their own files (as glyphon's `Cache`). One `Cache` serves any
//! number of nodes and views on the same device.

use crate::error::Result;
use crate::gpu::ShaderPrecision;
use crate::nodes::{self, CompositeNode, MarchSettings, Scale};

/// Every node's layouts and pipelines on one device. Cloning is cheap (handles).
///
/// Used in the [crate-level example](crate#example).
#[derive(Clone)]
pub struct Cache {
    pub(crate) light_texture: nodes::light_texture::Pipelines,
    pub(crate) shadow_map: nodes::shadow_map::Pipelines,
    pub(crate) extents: nodes::extents::Pipelines,
    pub(crate) table: nodes::airlight_table::Pipelines,
    pub(crate) march: nodes::march::Pipelines,
    pub(crate) upsample: nodes::upsample::Pipelines,
    pub(crate) composite: nodes::composite::Pipelines,
    pub(crate) iss_table: nodes::iss_table::Pipelines,
    pub(crate) soft_shadow: nodes::soft_shadow::Pipelines,
    precision: ShaderPrecision,
}

impl Cache {
    /// Compiles the shaders and builds the layouts and the pipelines that do not depend on a
    /// frame; pipeline variants (the march's method and light kind, the composite's output
    /// format) are built on first use.
    ///
    /// Used in the [crate-level example](crate#example).
    pub fn new(device: &wgpu::Device) -> Self {
        Self::with_precision(device, ShaderPrecision::Native)
    }

    /// As [`new`](Self::new), with the shaders' transcendental functions evaluated as
    /// `precision` says: [`ShaderPrecision::WorstCase`] is a test mode that shows, on a driver
    /// whose maths is nearly exact, what the least precise GPU that WGSL allows does to the
    /// images.
    pub fn with_precision(device: &wgpu::Device, precision: ShaderPrecision) -> Self {
        Self {
            light_texture: nodes::light_texture::Pipelines::new(device, precision),
            shadow_map: nodes::shadow_map::Pipelines::new(device, precision),
            extents: nodes::extents::Pipelines::new(device, precision),
            table: nodes::airlight_table::Pipelines::new(device, precision),
            march: nodes::march::Pipelines::new(device, precision),
            upsample: nodes::upsample::Pipelines::new(device, precision),
            composite: nodes::composite::Pipelines::new(device, precision),
            iss_table: nodes::iss_table::Pipelines::new(device, precision),
            soft_shadow: nodes::soft_shadow::Pipelines::new(device, precision),
            precision,
        }
    }

    /// The precision the shaders were compiled with.
    pub fn precision(&self) -> ShaderPrecision {
        self.precision
    }

    /// Builds, before the first frame, every pipeline that frames with `march` settings and
    /// output `format` can use for lights of the kinds in `lights`: the march's variants (each
    /// method's shadowed and unshadowed forms, with and without a soft light's grid), the
    /// upsample's for a reduced resolution, and the composite's for `format`. Without it each
    /// variant is built by the first frame that needs it, inside the node's `prepare`: a pause
    /// of up to seconds on that frame. The pipelines are shared by every clone of the cache;
    /// warming twice builds nothing new. Through the facade,
    /// [`Settings::warm_up`](crate::Settings::warm_up) calls this with its settings.
    ///
    /// Drivers that compile a pipeline only when it first runs (Mesa's lavapipe) still spend
    /// that time in the first frame's submission;
    /// [`VolumetricShadows::is_first_frame`](crate::VolumetricShadows::is_first_frame) marks
    /// such frames.
    ///
    /// # Errors
    ///
    /// [`MarchSettings`]' range checks and [`CompositeNode::new`]'s
    /// ([`Error::InvalidSetting`](crate::Error::InvalidSetting) naming the field), building
    /// nothing.
    pub fn warm_up(
        &self,
        device: &wgpu::Device,
        march: &MarchSettings,
        format: wgpu::TextureFormat,
        lights: &[LightKind],
    ) -> Result<()> {
        march.validate()?;
        // The node builds both composite paths (render and compute) for the format.
        CompositeNode::new(device, self, format)?;
        for &kind in lights {
            self.march.warm_up(device, march, kind);
            if march.scale != Scale::Full {
                self.upsample.warm_up(device, kind);
            }
        }
        Ok(())
    }
}

/// What decides which pipelines a light's frames use (see [`Cache::warm_up`]); a frame's
/// light gives its own with [`FrameLight::kind`](crate::FrameLight::kind).
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
