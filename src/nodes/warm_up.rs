//! [`Cache::warm_up`]: every node's pipelines before the first frame. The one place that names
//! every node's pipelines, above them all (the [`Cache`] finds each by its type).

use crate::error::Result;
use crate::nodes::{self, Cache, CompositeNode, LightKind, MarchSettings, Scale};

impl Cache {
    /// Builds, before the first frame, every node's shaders and layouts and every pipeline
    /// that frames with `march` settings and output `format` can use for lights of the kinds
    /// in `lights`: the march's variants (each method's shadowed and unshadowed forms, with and
    /// without a soft light's grid), the upsample's for a reduced resolution, and the
    /// composite's for `format`. Without it each is built by the first frame that needs it,
    /// inside the node's creation or `prepare`: a pause of up to seconds on that frame. The
    /// pipelines are shared by every clone of the cache; warming twice builds nothing new.
    /// Through the facade, [`Settings::warm_up`](crate::Settings::warm_up) calls this with its
    /// settings.
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
        self.get::<nodes::light_texture::Pipelines>();
        self.get::<nodes::shadow_map::Pipelines>();
        self.get::<nodes::extents::Pipelines>();
        self.get::<nodes::airlight_table::Pipelines>();
        self.get::<nodes::iss_table::Pipelines>();
        self.get::<nodes::soft_shadow::Pipelines>();
        let (march_pipelines, upsample) = (
            self.get::<nodes::march::Pipelines>(),
            self.get::<nodes::upsample::Pipelines>(),
        );
        for &kind in lights {
            march_pipelines.warm_up(device, march, kind);
            if march.scale != Scale::Full {
                upsample.warm_up(device, kind);
            }
        }
        Ok(())
    }
}
