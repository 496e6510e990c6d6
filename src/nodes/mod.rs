//! Render-graph nodes. Each has the same three steps: `new` (long-lived resources), `prepare`
//! (validate inputs, resize, upload what changed) and `encode` (record into the caller's
//! `CommandEncoder`; never submits). Each module documents the format, usage and size of every
//! texture it reads or writes.

mod airlight_table;
mod composite;
mod extents;
mod light_texture;
mod march;
mod shadow_map;
mod upsample;

pub use airlight_table::{AirlightTableNode, TableSize};
pub use composite::{CompositeInputs, CompositeNode, OutputTarget, MAX_LIGHTS};
pub use extents::{
    Crossings, CrossingsRequest, ExtentsInputs, ExtentsNode, EXTENTS_NEAR, MAX_CROSSINGS_PER_PIXEL,
};
pub use light_texture::LightTextureNode;
pub use march::{
    Extents, MarchInputs, MarchMethod, MarchNode, MarchSettings, MarchStats, Shadows,
    DEFAULT_CROSSINGS,
};
pub use shadow_map::{ShadowMap, ShadowMapNode, ShadowMapSettings};
pub use upsample::{Scale, UpsampleFilter, UpsampleInputs, UpsampleNode};
