//! Render-graph nodes. Each lives in one file with its GPU definition (binding table, layout,
//! pipelines, parameter struct; its WGSL is `shaders/<node>.wgsl`) and keeps one contract:
//!
//! * `new(device, &Cache, settings) -> Result<Self>`: long-lived resources (`settings` left out
//!   where a node has none); `settings()` and `set_settings(settings) -> Result<()>` where they
//!   can change between frames (the march, the upsample), taking effect at the next `prepare`;
//! * `prepare(device, queue, &inputs) -> Result<bool>`: validates the inputs, resizes, uploads
//!   what changed; returns whether the next `encode` records work (`false` only for the
//!   passes whose result is kept while nothing changes: table, shadow map, light texture);
//! * `encode(&mut self, encoder, timer) -> Result<()>`: records into the caller's
//!   `CommandEncoder` (never submits), timed by `timer` when given; a node whose output
//!   depends on every frame returns [`Error::NotPrepared`](crate::Error::NotPrepared) before its
//!   first successful `prepare`. The composite also takes the target it writes;
//! * accessors for its outputs, `None` before the first `prepare`.
//!
//! Each module documents the format, usage and size of every texture it reads or writes.

pub(crate) mod airlight_table;
pub(crate) mod cache;
pub(crate) mod composite;
pub(crate) mod extents;
pub(crate) mod iss_table;
#[cfg(test)]
pub(crate) mod layout;
pub(crate) mod light_texture;
pub(crate) mod march;
pub(crate) mod shadow_map;
pub(crate) mod soft_shadow;
pub(crate) mod uniforms;
pub(crate) mod upsample;

pub use airlight_table::{AirlightTableNode, TableInputs, TableSize};
pub use cache::{Cache, LightKind};
pub use composite::{CompositeInputs, CompositeNode, CompositeSurfaces, OutputTarget, MAX_LIGHTS};
pub use extents::{
    Crossings, CrossingsBuild, CrossingsRequest, Extents, ExtentsInputs, ExtentsNode, EXTENTS_NEAR,
    MAX_CROSSINGS_PER_PIXEL,
};
pub use iss_table::{IssPhase, IssTableNode, IssTableSize, ISS_TAU_RANGE};
pub use light_texture::LightTextureNode;
pub use march::{
    MarchInputs, MarchMethod, MarchNode, MarchSettings, MarchStats, Shadows, DEFAULT_CROSSINGS,
};
pub use shadow_map::{
    ShadowMap, ShadowMapInputs, ShadowMapNode, ShadowMapSettings, ShadowParams, CASCADE_RANGE,
    DIRECTIONAL_BIAS_TEXELS,
};
pub use soft_shadow::{SoftShadow, SoftShadowInputs, SoftShadowNode, SoftShadowSize};
pub use upsample::{Scale, UpsampleFilter, UpsampleInputs, UpsampleNode};
