//! Render-graph nodes. Each lives in one file (or, split by concern, one folder) with its GPU
//! definition (binding table, layout, pipelines, parameter struct; its WGSL is
//! `shaders/<node>.wgsl`) and keeps one contract:
//!
//! * `new(device, &Cache, settings) -> Result<Self>`: long-lived resources (`settings` left out
//!   where a node has none); `settings()` and `set_settings(settings) -> Result<()>` where they
//!   can change between frames (the march, the upsample), taking effect at the next `prepare`;
//! * [`Node::prepare`]`(device, queue, &inputs) -> Result<bool>`: validates the inputs,
//!   resizes, uploads what changed; returns whether the next `encode` records work (`false`
//!   only for the passes whose result is kept while nothing changes: table, shadow map, light
//!   texture);
//! * [`Encode::encode`]`(&mut self, encoder, timer) -> Result<()>`: records into the caller's
//!   `CommandEncoder` (never submits), timed by `timer` when given; a node whose output
//!   depends on every frame returns [`Error::NotPrepared`](crate::Error::NotPrepared) before its
//!   first successful `prepare`;
//! * accessors for its outputs, `None` before the first `prepare`.
//!
//! The composite keeps the same shape with its own methods: it writes the caller's target,
//! which `encode` takes.
//!
//! Nodes take decisions as inputs rather than making them: the march is told its
//! [`MarchMode`] (the facade's planner picks it with [`MarchMode::choose`], as a caller wiring
//! the nodes by hand does) and only checks that its inputs carry what that mode reads.
//!
//! Each module documents the format, usage and size of every texture it reads or writes.

pub(crate) mod airlight_table;
pub(crate) mod cache;
pub(crate) mod composite;
pub(crate) mod extents;
pub(crate) mod groups;
pub(crate) mod iss_table;
#[cfg(test)]
pub(crate) mod layout;
pub(crate) mod light_texture;
pub(crate) mod march;
pub(crate) mod shadow_gate;
pub(crate) mod shadow_map;
pub(crate) mod soft_shadow;
pub(crate) mod upsample;
mod warm_up;

use crate::error::Result;
use crate::gpu::GpuTimer;

/// A node's per-frame contract: `prepare` reads its [`Inputs`](Node::Inputs), uploads what
/// changed and says whether [`Encode::encode`] will record work. Bring it into scope
/// (`use volshadow::nodes::{Encode, Node};`) to drive nodes by hand.
pub trait Node: Encode {
    /// What `prepare` reads each frame.
    type Inputs<'a>: ?Sized;

    /// Validates `inputs`, (re)allocates and uploads what changed. Returns whether the next
    /// [`encode`](Encode::encode) records work (`false`: the last result stands).
    ///
    /// # Errors
    ///
    /// The node's own (see each node), never a wgpu validation error.
    fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        inputs: &Self::Inputs<'_>,
    ) -> Result<bool>;
}

/// Recording a prepared node into the caller's encoder (never submitting), timed by `timer`
/// when given. Object safe: a frame's steps are recorded through `&mut dyn Encode`.
pub trait Encode {
    /// Records the node's passes.
    ///
    /// # Errors
    ///
    /// [`Error::NotPrepared`](crate::Error::NotPrepared) where the node's output depends on
    /// every frame and no `prepare` succeeded yet.
    fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        timer: Option<&mut GpuTimer>,
    ) -> Result<()>;
}

pub use crate::light::LightKind;
pub use airlight_table::{AirlightTableNode, TableInputs, TableSize};
pub use cache::Cache;
pub use composite::{CompositeInputs, CompositeNode, CompositeSurfaces, OutputTarget, MAX_LIGHTS};
pub use extents::{
    Crossings, CrossingsBuild, CrossingsRequest, Extents, ExtentsInputs, ExtentsNode, EXTENTS_NEAR,
    MAX_CROSSINGS_PER_PIXEL,
};
pub use iss_table::{IssPhase, IssTableNode, IssTableSize, ISS_TAU_RANGE};
pub use light_texture::{LightTextureInput, LightTextureMaps, LightTextureNode};
pub use march::{
    MarchInputs, MarchMethod, MarchMode, MarchNode, MarchSettings, MarchStats, MarchWork,
    ShadowForms, Shadows, DEFAULT_CROSSINGS,
};
pub use shadow_map::{
    ShadowMap, ShadowMapInputs, ShadowMapNode, ShadowMapSettings, ShadowParams, CASCADE_RANGE,
    DIRECTIONAL_BIAS_TEXELS, MAX_EXACT_TRIANGLES,
};
pub use soft_shadow::{SoftShadow, SoftShadowInputs, SoftShadowNode, SoftShadowSize};
pub use upsample::{Scale, UpsampleFilter, UpsampleInputs, UpsampleNode};
