//! The shadow-map node: occluder depth seen from the light.
//!
//! A point light gets a cube of six faces (+X, −X, +Y, −Y, +Z, −Z, 90° each), a spot light one
//! face covering its cone. Each face uses a reversed-Z infinite perspective projection
//! ([`ShadowMapNode::face_matrices`]): depth = near / (distance along the face's axis), so the
//! nearest occluder has the largest depth and nothing is clipped far away.
//!
//! A directional light gets cascaded orthographic maps (rendered by
//! [`ShadowMapNode::prepare`] (the camera in [`ShadowMapInputs`]); Engel 2006, "Cascaded shadow maps", ShaderX⁵; the
//! splits of Zhang et al. 2006, "Parallel-split shadow maps for large-scale virtual
//! environments"): the view depth from the eye to the light's
//! [shadow distance](crate::DirectionalLight::with_shadow_distance) is split into
//! [`cascades`](crate::DirectionalLight::with_cascades) ranges ([`ShadowMapNode::cascade_splits`]),
//! shorter near the eye, and each range gets one layer ([`ShadowMapNode::directional_matrix`])
//! fitted to the bounding sphere of the view pyramid's slice, so its size does not change as
//! the camera turns, with its centre snapped to whole texels in the light's frame, so that a
//! moving camera does not make the shadows' edges shimmer. Depth is reversed and linear along
//! the light's direction (1 at the side towards the light). A layer holds only the occluders
//! that can shadow its region (those whose box, seen along the direction, overlaps the
//! layer's square and begins before the region's far side), and its depth spans the region and
//! those occluders alone: an occluder beyond the region along the direction (a terrain
//! kilometres below) can shadow none of it and neither is drawn nor widens the range.
//!
//! A point takes the first layer whose square holds it (within a texel of the edge) and whose
//! far plane it is not beyond; it counts as lit where it lies in no layer's square; in a
//! square but beyond every such layer's far plane (beyond the shadow distance) it is compared
//! at the far plane of the last of them: shadowed where that layer holds an occluder. Its
//! depth bias is [`DIRECTIONAL_BIAS_TEXELS`] texels of its layer in world units, so it means
//! the same at every scale and range.
//!
//! # Output
//! [`ShadowMap`]: a `Depth32Float` 2D array texture, `resolution²`, 6 layers (point), 1
//! (spot) or one per cascade (directional), usages `RENDER_ATTACHMENT | TEXTURE_BINDING`,
//! cleared to 0 (nothing); plus the face matrices and the depth bias. A shadow map the caller renders itself can be passed to the
//! march instead, in the same layout and convention (any depth format that can be sampled).
//!
//! For a light with a radius the node also renders [`ShadowMap::back`]: the same faces again
//! with closed occluders' faces turned towards the light culled, which keeps each one's
//! nearest back face (open meshes, which have no inside, draw both sides: their nearest face).
//! The soft shadows take a blocker's distance between the two (between their midpoint and
//! their geometric mean), where a convex occluder's outline lies; the front surface alone is
//! nearer and made the deep penumbra up to
//! 41% too bright (see [`SoftShadowNode`](crate::nodes::SoftShadowNode)). It doubles the
//! pass's draws for such a light, less the cube faces no occluder's bounding sphere reaches:
//! their front layer holds no blocker, so their back layer is never read, and is not drawn.

use glam::{Mat4, Vec3, Vec4};

use crate::error::{finite, Error, Result};
use crate::gpu::pipeline::{
    bind_group, compute_pipeline, depth_pipeline, dispatch, layout, module, Binding,
};
use crate::gpu::wgsl::wgsl_file;
use crate::gpu::ShaderPrecision;
use crate::gpu::{GpuTimer, Occluder};
use crate::nodes::cache::CachedPipelines;
use crate::nodes::shadow_gate::{arguments, Gate, GatePipelines};
use crate::nodes::{Cache, Crossings};
use crate::nodes::{Encode, Node};
use crate::pass::Pass;
use crate::scene::{Camera, DirectionalLight, Light};

/// The binding table: `@binding(i)` of `shaders/shadow_map.wgsl` is entry `i`.
const BINDINGS: [Binding; 2] = [
    Binding::DynamicParams(FACE_BYTES), // face: clip_from_world and centre, one slot per face
    Binding::DynamicParams(INSTANCE_BYTES), // instance: world_from_object and clip reach
];

/// `vs_shadow_clipped`'s: [`BINDINGS`], then the occluder's mesh read as storage.
const CLIPPED_BINDINGS: [Binding; 4] = [
    Binding::DynamicParams(FACE_BYTES),     // face
    Binding::DynamicParams(INSTANCE_BYTES), // instance
    Binding::VertexParams,                  // clip_positions
    Binding::VertexParams,                  // clip_indices
];

/// WGSL `ShadowFace`: the face's matrix and the light's position.
const FACE_BYTES: u64 = 80;
/// WGSL `Instance`: the occluder's transform and its [`clip_reach`] (0: none).
const INSTANCE_BYTES: u64 = 80;

/// An occluder reaching farther from the light than this times its distance is clipped to a
/// cube of that half-side around the light before it is drawn ([`clip_reach`]).
const CLIP_REACH: f32 = 4096.0;

/// The fan triangles (instances) a clipped triangle is drawn as: a triangle clipped by a
/// cube's six planes keeps at most nine vertices.
const FAN: u32 = 7;

/// The binding table of `shaders/triangles.wgsl` (the occluders' triangles for the exact
/// visible fraction, [`ShadowMap::triangles`]).
const TRIANGLE_BINDINGS: [Binding; 4] = [
    Binding::Params,    // instance: world_from_object, the occluder's slot
    Binding::Params,    // positions
    Binding::Params,    // indices
    Binding::ReadWrite, // triangles: this occluder's range
];

/// Bytes of one group of four triangles of [`ShadowMap::triangles`]: their corners and a
/// sphere bounding them, in 16 `vec4<f32>` (`shaders/triangles.wgsl`).
pub(crate) const GROUP_BYTES: u64 = 256;

/// Most triangles (all occluders together) for which the node gathers
/// [`ShadowMap::triangles`]: each exact visible fraction tests every group of four's bounding
/// sphere, and the triangles of those in its cone of lines to the light, and the march takes
/// one at each piece of up to 64 refined steps of a marched interval (and two more in each of
/// at most 32 pieces split in thirds), with at most as many loop iterations as one turn over
/// 128 groups when it refines a sliver of the light. More, and the soft shadows take the
/// shadow map's estimate alone. On llvmpipe, which ends every loop of a shader invocation once
/// its loops together reach 65 535 iterations, 128 groups keep a ray's two intervals (a spot
/// light's cone may cut it in two), each at most 128 pieces and 32 of them in thirds, at
/// 2 × (128 + 64) × 128 = 49 152.
pub const MAX_EXACT_TRIANGLES: u32 = 512;

/// The node's layout and pipeline, held by the [`Cache`].
#[derive(Clone)]
pub(crate) struct Pipelines {
    layout: wgpu::BindGroupLayout,
    /// Every face: the nearest surface.
    depth: wgpu::RenderPipeline,
    /// Faces turned away from the light only: a closed occluder's nearest back face.
    back: wgpu::RenderPipeline,
    /// `depth` and `back` for occluders far larger than their distance to the light, whose
    /// triangles are clipped around the light first (`vs_shadow_clipped`, [`clip_reach`]).
    clipped_layout: wgpu::BindGroupLayout,
    depth_clipped: wgpu::RenderPipeline,
    back_clipped: wgpu::RenderPipeline,
    /// The occluders' triangles in world space (`shaders/triangles.wgsl`).
    gather_layout: wgpu::BindGroupLayout,
    gather: wgpu::ComputePipeline,
    /// A gated map's clear: depth 0 over the layer, drawn indirectly (`vs_clear`).
    clear: wgpu::RenderPipeline,
    /// The gate's scan of the crossing lists ([`shadow_gate`](crate::nodes::shadow_gate)).
    gate: GatePipelines,
}

impl CachedPipelines for Pipelines {
    fn build(device: &wgpu::Device, precision: ShaderPrecision) -> Self {
        Self::new(device, precision)
    }
}

impl Pipelines {
    pub(crate) fn new(device: &wgpu::Device, precision: ShaderPrecision) -> Self {
        let gather_layout = layout(
            device,
            "volshadow occluder triangles",
            wgpu::ShaderStages::COMPUTE,
            &TRIANGLE_BINDINGS,
        );
        let gather = compute_pipeline(
            device,
            "volshadow occluder triangles",
            &[&gather_layout],
            &module(device, &wgsl_file!("triangles.wgsl"), precision),
            "gather",
            &[],
        );
        let label = "volshadow shadow map";
        let layout = layout(device, label, wgpu::ShaderStages::VERTEX, &BINDINGS);
        let module = module(device, &wgsl_file!("shadow_map.wgsl"), precision);
        let pipeline = |cull_mode| {
            depth_pipeline(
                device,
                label,
                &[&layout],
                &module,
                "vs_shadow",
                None,
                &[wgpu::VertexBufferLayout {
                    array_stride: 16,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &wgpu::vertex_attr_array![0 => Float32x4],
                }],
                Some(wgpu::CompareFunction::Greater),
                cull_mode,
            )
        };
        let clipped_layout = crate::gpu::pipeline::layout(
            device,
            "volshadow shadow map clipped",
            wgpu::ShaderStages::VERTEX,
            &CLIPPED_BINDINGS,
        );
        let clipped = |cull_mode| {
            depth_pipeline(
                device,
                "volshadow shadow map clipped",
                &[&clipped_layout],
                &module,
                "vs_shadow_clipped",
                None,
                &[],
                Some(wgpu::CompareFunction::Greater),
                cull_mode,
            )
        };
        let clear = depth_pipeline(
            device,
            "volshadow shadow map clear",
            &[&layout],
            &module,
            "vs_clear",
            None,
            &[],
            Some(wgpu::CompareFunction::Always),
            None,
        );
        Self {
            gather_layout,
            gather,
            clear,
            gate: GatePipelines::new(device, precision),
            depth: pipeline(None),
            // Counter-clockwise is front (wgpu's default), as the crate's meshes wind faces
            // seen from outside.
            back: pipeline(Some(wgpu::Face::Front)),
            depth_clipped: clipped(None),
            back_clipped: clipped(Some(wgpu::Face::Front)),
            clipped_layout,
            layout,
        }
    }
}

/// What the shadow map is rendered for.
#[derive(Clone, Copy)]
pub struct ShadowMapInputs<'a> {
    /// The light.
    pub light: &'a Light,
    /// The occluders.
    pub occluders: &'a [Occluder<'a>],
    /// The view: a directional light's map is fitted to what it sees (point and spot lights do
    /// not read it).
    pub camera: &'a Camera,
    /// `Some`: the map is read only where these crossing lists (of this frame, recorded
    /// before the map) cannot be counted: a list that overflowed, or a face of an open or
    /// non-manifold mesh (bit 31 of a pixel's count). The map is then drawn only in a frame
    /// with such a pixel, decided on the GPU, and not again until its inputs change; in any
    /// other frame it is left as it was and its texels are not all valid, so it must not be
    /// read elsewhere (the exact method's march, for a light without a radius, reads it only
    /// there). `None`: drawn whenever its inputs change.
    pub fallback: Option<Crossings<'a>>,
}

/// Shadow-map settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShadowMapSettings {
    /// Width and height of each face, in texels ([`ShadowMapSettings::MIN_RESOLUTION`] ..=
    /// device limit). Default 1024.
    pub resolution: u32,
    /// Relative depth bias: a point counts as lit while its distance from the light is below
    /// `(1 + bias)`-ish times the occluder's (exactly: depth ≥ stored · (1 − bias)). It is
    /// relative so it works at any scene scale. Default 2e-3; must be in [0, 0.5).
    pub depth_bias: f32,
    /// Keep every light's map whole, for shadowing the caller's surfaces with
    /// [`SHADOW_WGSL`](crate::SHADOW_WGSL) ([`VolumetricShadows::shadow_map`](crate::VolumetricShadows::shadow_map)).
    /// Default `false`: under the exact method a light without a radius draws its map only in
    /// a frame where a pixel's crossings cannot be counted (see
    /// [`LightPlan::map_on_demand`](crate::plan::LightPlan::map_on_demand)), usually none.
    pub surfaces: bool,
}

impl ShadowMapSettings {
    /// The smallest resolution accepted. Set by measurement (`tests/gpu/shadows.rs`: a sphere's
    /// shadow in fog under a point light, hybrid march, against the f64 reference): the p95
    /// relative error of the in-scatter is 1.2% at 32², within the 2% the hybrid march is held
    /// to, and 3.8% at 16², 7.8% at 8², 22% at 2² (0.67% at 64², 0.15% at 256², 0.11% at
    /// 1024²). A floor against broken settings, not a recommendation: an occluder that covers
    /// fewer texels needs more.
    pub const MIN_RESOLUTION: u32 = 32;
}

impl Default for ShadowMapSettings {
    fn default() -> Self {
        Self::DEFAULT
    }
}

impl ShadowMapSettings {
    /// The default: 1024² texels a layer, depth bias 2e-3, maps drawn only where the march
    /// reads them.
    pub const DEFAULT: ShadowMapSettings = ShadowMapSettings {
        resolution: 1024,
        depth_bias: 2e-3,
        surfaces: false,
    };
}

/// A shadow map as the march reads it.
#[derive(Clone, Copy)]
pub struct ShadowMap<'a> {
    /// Depth 2D array texture: 6 layers (cube faces +X, −X, +Y, −Y, +Z, −Z), 1 (spot), or one
    /// per cascade (directional, 1 to
    /// [`DirectionalLight::MAX_CASCADES`](crate::DirectionalLight::MAX_CASCADES), nearest
    /// first).
    pub texture: &'a wgpu::Texture,
    /// clip_from_world of each layer, reversed-Z infinite perspective, or for a directional
    /// light reversed-Z orthographic (see the module docs).
    pub faces: &'a [Mat4],
    /// Relative depth bias of a point or spot light's map (a directional map's is
    /// [`DIRECTIONAL_BIAS_TEXELS`] texels of each cascade, from its face).
    pub depth_bias: f32,
    /// The occluders' world-space bounding spheres (centre, radius), which bound where a light
    /// with a radius can cast a penumbra. [`ShadowMapNode`] takes each mesh's farthest vertex
    /// from its box's centre, so that a sphere's is its own radius, not its box's
    /// circumsphere (√3 times as large: on the report's soft scene its penumbra cone made the
    /// march at ½ resolution 1.44–1.49 times as long, alternated in one process). Empty (a
    /// shadow map rendered by the caller without them): a soft light's rays are marched whole.
    pub bounds: &'a [Vec4],
    /// For each of `bounds` (same order; missing or zero: none), a plane `(n, d)` with the
    /// occluder in `n·x ≤ d` and the light's sphere strictly beyond it: no line from a point
    /// beyond the plane to the light meets the occluder, so its penumbra lies in `n·x ≤ d`. A
    /// flat occluder such as a ground, whose bounding sphere holds the light, is bounded by it.
    pub planes: &'a [Vec4],
    /// A lower bound on the least distance from the light to an occluder: the distance to its
    /// bounding box, in its own frame or the world's, whichever is larger (tighter than
    /// `bounds`' spheres); 0 when not known.
    pub occluder_distance: f32,
    /// For a light with a radius: the nearest back faces (turned away from the light) of closed
    /// occluders, and the nearest faces of open ones, same size, format and layout as
    /// `texture`. Along a direction, a distance between the two surfaces estimates where the
    /// lines from a point to the light's disc graze the occluder (a sphere's silhouette), which
    /// the front surface alone puts too near the light. It is read only where `texture`
    /// holds a blocker (the node leaves a cube face no occluder reaches undrawn). `None`: the
    /// front surface is taken.
    pub back: Option<&'a wgpu::Texture>,
    /// Whether its occluders may leave gaps narrower than a light with a radius, through which
    /// it shines as a narrow shaft: more than one occluder, or one that is not convex
    /// ([`OccluderMesh::is_convex`](crate::gpu::OccluderMesh::is_convex)). Without, the
    /// [`SoftShadowNode`](crate::nodes::SoftShadowNode) skips its search for shafts. `true`
    /// where not known (a map the caller renders).
    pub gaps: bool,
    /// For a point or spot light with a radius whose occluders may leave gaps (see
    /// [`gaps`](Self::gaps)), at most [`MAX_EXACT_TRIANGLES`] triangles in all: the occluders'
    /// triangles in world space, in groups of four (each 16 `vec4<f32>`: the corners, then a
    /// sphere bounding them; zero triangles pad a group), from which the soft
    /// shadows take the light's visible fraction exactly in place of the shadow map's
    /// estimate, which sees the occluders from the light's centre alone (see
    /// [`SoftShadowNode`](crate::nodes::SoftShadowNode)). `None`: the estimate.
    pub triangles: Option<&'a wgpu::Buffer>,
    /// Changes whenever the map's contents do, so that what is derived from it (the
    /// [`SoftShadowNode`](crate::nodes::SoftShadowNode)'s grid) is rebuilt only then:
    /// [`ShadowMapNode`] counts its renders. A map the caller renders must change it at
    /// every render.
    pub generation: u64,
}

impl ShadowMap<'_> {
    /// The groups of four triangles in [`triangles`](Self::triangles), 0 without.
    pub(crate) fn triangle_groups(&self) -> u32 {
        self.triangles
            .map_or(0, |b| (b.size() / GROUP_BYTES) as u32)
    }

    /// Checks [`triangles`](Self::triangles): a storage buffer of whole groups of four, at most
    /// [`MAX_EXACT_TRIANGLES`] triangles.
    pub(crate) fn check_triangles(&self) -> Result<()> {
        let Some(buffer) = self.triangles else {
            return Ok(());
        };
        let problem = if !buffer.usage().contains(wgpu::BufferUsages::STORAGE) {
            Some(format!("usage {:?} lacks STORAGE", buffer.usage()))
        } else if buffer.size() == 0 || buffer.size() % GROUP_BYTES != 0 {
            Some(format!(
                "{} bytes: not whole groups of {GROUP_BYTES} bytes",
                buffer.size()
            ))
        } else if buffer.size() / GROUP_BYTES * 4 > u64::from(MAX_EXACT_TRIANGLES) {
            Some(format!(
                "{} groups of four triangles: more than {MAX_EXACT_TRIANGLES} triangles",
                buffer.size() / GROUP_BYTES
            ))
        } else {
            None
        };
        match problem {
            Some(problem) => Err(Error::InvalidBuffer {
                field: "shadow_map.triangles",
                problem,
            }),
            None => Ok(()),
        }
    }

    /// Checks [`back`](Self::back) against the map: a depth array of the same size and layers.
    pub(crate) fn check_back(&self) -> Result<()> {
        let Some(back) = self.back else {
            return Ok(());
        };
        crate::gpu::check_depth_layers(
            "shadow_map.back",
            back,
            self.texture.depth_or_array_layers(),
        )?;
        if (back.width(), back.height()) != (self.texture.width(), self.texture.height()) {
            return Err(Error::InvalidTexture {
                field: "shadow_map.back",
                problem: format!(
                    "is {}x{}, the shadow map {}x{}",
                    back.width(),
                    back.height(),
                    self.texture.width(),
                    self.texture.height()
                ),
            });
        }
        Ok(())
    }

    /// The parameters [`SHADOW_WGSL`](crate::SHADOW_WGSL)'s `volshadow_shadow` takes (its
    /// `VolshadowShadow` struct), for the `light` this map was rendered for, with a normal
    /// offset of `normal_offset` × the distance from the light, or for a directional light
    /// `normal_offset` world units in its first cascade and as many texels in each other
    /// (`None`: two texels' angular size at this map's resolution, or two texels of a
    /// directional map's cascade, which keeps lit surfaces free of self-shadowing acne down to
    /// grazing angles of about 25°). The light's [radius](Light::radius) goes in
    /// [`ShadowParams::radius`], which makes a point or spot light's surface shadows soft.
    pub fn params(&self, light: &Light, normal_offset: Option<f32>) -> ShadowParams {
        let mut faces = [[0.0; 16]; 6];
        for (slot, m) in faces.iter_mut().zip(self.faces) {
            *slot = m.to_cols_array();
        }
        let texels = self.texture.width().max(1) as f32;
        let (light_position, directional, default_offset) = match light {
            Light::Directional(d) => {
                // The first cascade's half width, from its first row (1 / half width).
                let half = self
                    .faces
                    .first()
                    .map(|m| 1.0 / m.row(0).truncate().length())
                    .filter(|h| h.is_finite() && *h > 0.0)
                    .unwrap_or(0.0);
                (d.direction(), 1, 4.0 * half / texels)
            }
            _ => (light.position().unwrap_or_default(), 0, 4.0 / texels),
        };
        let radius = if directional == 1 {
            0.0
        } else {
            light.radius()
        };
        ShadowParams {
            faces,
            light_position: light_position.to_array(),
            depth_bias: self.depth_bias,
            layers: self.faces.len() as u32,
            normal_offset: normal_offset.unwrap_or(default_offset),
            directional,
            radius,
        }
    }
}

/// WGSL `VolshadowShadow` of [`SHADOW_WGSL`](crate::SHADOW_WGSL), byte for byte (upload it with
/// `bytemuck::bytes_of`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ShadowParams {
    /// clip_from_world of each layer, column-major (unused layers zero).
    pub faces: [[f32; 16]; 6],
    /// The light's position (a directional light: its direction of travel).
    pub light_position: [f32; 3],
    /// Relative depth bias.
    pub depth_bias: f32,
    /// 6 (point light, cube), 1 (spot light), or the cascades (directional light).
    pub layers: u32,
    /// Offset along the normal, relative to the distance from the light (a directional light:
    /// in world units in the first cascade, as many texels in the others).
    pub normal_offset: f32,
    /// 1 for a directional light's orthographic map, else 0.
    pub directional: u32,
    /// The light's radius ([`Light::radius`]): above 0, `volshadow_shadow` takes soft shadows
    /// (a blocker search and a filter, see [`SHADOW_WGSL`](crate::SHADOW_WGSL)); 0 (and a
    /// directional light, always 0 here) the hard lookup. Set it to 0 for hard surface shadows
    /// from a soft light's map.
    pub radius: f32,
}

/// Renders the occluders' depth from the light. Re-renders only when the light, an occluder or
/// a transform changed since the last render.
pub struct ShadowMapNode {
    settings: ShadowMapSettings,
    pipelines: Pipelines,
    texture: Option<wgpu::Texture>,
    /// See [`ShadowMap::back`]: only for a light with a radius.
    back: Option<wgpu::Texture>,
    faces: Vec<Mat4>,
    bounds: Vec<Vec4>,
    planes: Vec<Vec4>,
    /// Per layer, whether `back` is drawn there: a cube face no occluder's bounding sphere
    /// reaches holds no blocker in the front layer, so its back layer is never read.
    back_layers: Vec<bool>,
    face_buffer: wgpu::Buffer,
    instance_buffer: Option<wgpu::Buffer>,
    bind_group: Option<wgpu::BindGroup>,
    draws: Vec<Draw>,
    key: Vec<u32>,
    pending: bool,
    /// Counts the renders `prepare` has planned (see [`ShadowMap::generation`]).
    generation: u64,
    /// Per layer, the occluders (indices into `draws`) drawn there: a directional light's
    /// cascades, those that can shadow its region; a point light's cube faces, those whose
    /// bounding sphere reaches the face ([`cube_faces_touched`]). `None`: every occluder in
    /// every layer.
    layer_draws: Option<Vec<Vec<u32>>>,
    /// Per layer of `texture`, whether it holds depth drawn since it was last cleared: a layer
    /// with nothing to draw that is already clear (a new texture reads as cleared: zero, at
    /// infinity) is neither cleared nor drawn again, and its lookups read lit.
    dirty: Vec<bool>,
    /// See [`ShadowMap::occluder_distance`].
    occluder_distance: f32,
    /// Whether the occluders may leave gaps (see [`ShadowMap::gaps`]).
    gaps: bool,
    /// See [`ShadowMap::triangles`], and per occluder its gather's bind group and workgroups.
    triangles: Option<wgpu::Buffer>,
    gathers: Vec<(wgpu::BindGroup, u32)>,
    /// The gate of a map drawn only where the crossings cannot be counted
    /// ([`ShadowMapInputs::fallback`]); `None` while the map is drawn whenever it changes.
    gate: Option<Gate>,
}

struct Draw {
    positions: wgpu::Buffer,
    indices: wgpu::Buffer,
    index_count: u32,
    closed: bool,
    /// For an occluder with a [`clip_reach`]: its bind group of `CLIPPED_BINDINGS`, drawn by
    /// `vs_shadow_clipped` (`index_count` vertices, [`FAN`] instances).
    clipped: Option<wgpu::BindGroup>,
}

impl Draw {
    /// Records the draw with `pipelines`' `depth` or `back` pipeline (`back`: faces turned away
    /// from the light, an open mesh's nearest face), with the face and instance slots
    /// `offsets`.
    fn record(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        pipelines: &Pipelines,
        group: &wgpu::BindGroup,
        offsets: [u32; 2],
        back: bool,
    ) {
        let back = back && self.closed;
        if let Some(clipped) = &self.clipped {
            pass.set_pipeline(if back {
                &pipelines.back_clipped
            } else {
                &pipelines.depth_clipped
            });
            pass.set_bind_group(0, clipped, &offsets);
            pass.draw(0..self.index_count, 0..FAN);
            return;
        }
        pass.set_pipeline(if back {
            &pipelines.back
        } else {
            &pipelines.depth
        });
        pass.set_bind_group(0, group, &offsets);
        pass.set_vertex_buffer(0, self.positions.slice(..));
        pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed(0..self.index_count, 0, 0..1);
    }
}

/// The half-side of the cube around the light that `occluder`'s triangles are clipped to
/// before the rasteriser clips them (`vs_shadow_clipped`), where they need it: [`CLIP_REACH`]
/// times the distance from a point or spot light to the occluder's bounds, where the bounds
/// reach farther than that from the light (in some axis). One value for all its triangles, so
/// that two triangles sharing an edge cut it at the same points, bit for bit: each triangle's
/// own distance would give neighbours different cubes, and the points each computes on a
/// shared edge 1e7 long are off the edge by f32 steps of its far end, which opened a wedge
/// beside the light that the light leaked through. `None` for a directional light, an occluder
/// within its cube, and a light inside the bounds (its distance to them is 0; see the
/// crate's Limits).
fn clip_reach(light: &Light, occluder: &Occluder<'_>) -> Option<f32> {
    let p = light.position()?;
    let (lo, hi) = occluder.world_bounds();
    let reach = CLIP_REACH * p.clamp(lo, hi).distance(p);
    let farthest = (p - lo).abs().max((p - hi).abs()).max_element();
    (reach > 0.0 && farthest > reach).then_some(reach)
}

/// A point light's six cube faces (+X, −X, +Y, −Y, +Z, −Z) around `position`: 90°
/// reversed-Z infinite perspectives with near plane `near`, looking along each axis.
fn cube_faces(position: Vec3, near: f32) -> [Mat4; 6] {
    use glam::camera::rh::{proj::directx::perspective_infinite_reverse, view::look_to_mat4};
    let proj = perspective_infinite_reverse(std::f32::consts::FRAC_PI_2, 1.0, near);
    [
        (Vec3::X, Vec3::Y),
        (Vec3::NEG_X, Vec3::Y),
        (Vec3::Y, Vec3::Z),
        (Vec3::NEG_Y, Vec3::Z),
        (Vec3::Z, Vec3::Y),
        (Vec3::NEG_Z, Vec3::Y),
    ]
    .map(|(dir, up)| proj * look_to_mat4(position, dir, up))
}

/// Which of a point light's cube faces (+X, −X, +Y, −Y, +Z, −Z) at `position` the spheres
/// `(centre, radius)` may reach, conservatively: a face's pyramid is four half-spaces through
/// the light (`±x_a ≥ |x_b|` for the face's axis `a` and each other axis `b`), and a sphere
/// inside it reaches into each of them. The back layer of a face none reaches is not drawn.
/// Per cube face of a point light at `position`, the spheres (indices) that reach it
/// ([`cube_faces_touched`] of each): what its layer draws.
pub(crate) fn cube_face_draws(position: Vec3, spheres: &[Vec4]) -> Vec<Vec<u32>> {
    let mut faces = vec![Vec::new(); 6];
    for (i, sphere) in (0u32..).zip(spheres) {
        for (face, reached) in cube_faces_touched(position, std::slice::from_ref(sphere))
            .into_iter()
            .enumerate()
        {
            if reached {
                faces[face].push(i);
            }
        }
    }
    faces
}

pub(crate) fn cube_faces_touched(position: Vec3, spheres: &[Vec4]) -> [bool; 6] {
    let mut touched = [false; 6];
    for sphere in spheres {
        let c = sphere.truncate() - position;
        let r = sphere.w * std::f32::consts::SQRT_2;
        for (face, reached) in touched.iter_mut().enumerate() {
            let a = face / 2;
            let along = if face % 2 == 0 { c[a] } else { -c[a] };
            let (b, d) = ((a + 1) % 3, (a + 2) % 3);
            // n·c ≥ −r for n = (±e_a ∓ e_b)/√2, times √2; a non-finite sphere reaches all.
            let inside = along - c[b].abs() >= -r && along - c[d].abs() >= -r;
            *reached |= inside || !(along.is_finite() && r.is_finite());
        }
    }
    touched
}

/// The near plane of `faces` where they are the cube faces this node draws for a point light
/// at `position` ([`ShadowMapNode::face_matrices`]), entry by entry to within 1e-5 of each
/// entry's size, else 0. The shaders then project a point into a face with a few selects on
/// its offset from the light (`cube_clip` in `shaders/pcss.wgsl`) in place of the face's
/// matrix, which each SIMD lane reads for its own face: on the report's soft scene on
/// llvmpipe the march at ½ resolution took about 0.9 of its time, and so did the soft-shadow
/// grid's build. A caller's map with other faces keeps the matrices.
pub(crate) fn standard_cube_near(faces: &[Mat4], position: Vec3) -> f32 {
    // Reversed-Z infinite perspective: clip z = near (the matrix's column w, row z).
    let near = faces.first().map_or(0.0, |f| f.w_axis.z);
    let standard = faces.len() == 6
        && near.is_finite()
        && near > 0.0
        && position.is_finite()
        && faces.iter().zip(cube_faces(position, near)).all(|(a, b)| {
            a.to_cols_array()
                .iter()
                .zip(b.to_cols_array())
                .all(|(x, y)| (x - y).abs() <= 1.0e-5 * y.abs().max(1.0))
        });
    if standard {
        near
    } else {
        0.0
    }
}

/// Uniform slots are 256 bytes apart (the core minimum dynamic-offset alignment).
const SLOT: u64 = 256;

/// The first `size` bytes of `buffer`, bound at a dynamic offset of one [`SLOT`] per item.
fn slot(buffer: &wgpu::Buffer, size: u64) -> wgpu::BindingResource<'_> {
    wgpu::BindingResource::Buffer(wgpu::BufferBinding {
        buffer,
        offset: 0,
        size: wgpu::BufferSize::new(size),
    })
}

/// WGSL `ShadowFace`'s words: the matrix's columns, then the centre.
fn slot_words((face, centre): (Mat4, Vec4)) -> [u32; 20] {
    let mut words = [0u32; 20];
    for (w, f) in words
        .iter_mut()
        .zip(face.to_cols_array().into_iter().chain(centre.to_array()))
    {
        *w = f.to_bits();
    }
    words
}

/// A directional map's depth bias in texels of the cascade a point falls in (world units:
/// this times the cascade's texel). A point of the medium counts as lit while it lies less
/// than this far beyond the stored occluder surface along the light: a surface sloped at up
/// to atan(2) ≈ 63° to the light within a texel's width stays on its own side. Tied to the
/// texel, not to the depth range, which an occluder far along the direction may stretch to
/// kilometres.
pub const DIRECTIONAL_BIAS_TEXELS: f32 = 2.0;

/// The widest ratio of a directional light's shadow distance to the start of its logarithmic
/// cascade splits ([`ShadowMapNode::cascade_splits`]).
pub const CASCADE_RANGE: f32 = 1000.0;

/// One cascade's square in the light's frame: centre (`cx`, `cy`, snapped to texels; `ct`
/// along the direction), half width `radius`.
#[derive(Debug, Clone, Copy)]
struct CascadeFit {
    right: Vec3,
    up: Vec3,
    cx: f32,
    cy: f32,
    ct: f32,
    radius: f32,
}

impl CascadeFit {
    fn new(light: &DirectionalLight, camera: &Camera, slice: (f32, f32), resolution: u32) -> Self {
        let d = light.direction();
        let (right, up) = d.any_orthonormal_pair();
        // The view pyramid's corners at view depths `slice.0` and `slice.1`: two rings around
        // the axis.
        let eye = camera.eye();
        let view = camera.view();
        let ring = |depth: f32| {
            let mut corners = [Vec3::ZERO; 4];
            for (k, corner) in corners.iter_mut().enumerate() {
                let x = if k & 1 == 0 { -1.0 } else { 1.0 };
                let y = if k & 2 == 0 { -1.0 } else { 1.0 };
                let dir = camera.ray_direction(x, y);
                let depth_per_unit = (-view.transform_vector3(dir).z).max(1e-6);
                *corner = eye + dir * (depth / depth_per_unit);
            }
            let mid = 0.25 * corners.iter().copied().sum::<Vec3>();
            let half = corners.iter().map(|c| c.distance(mid)).fold(0.0, f32::max);
            (mid, half)
        };
        let (near_mid, near_half) = ring(slice.0.max(0.0));
        let (far_mid, far_half) = ring(slice.1.max(slice.0.max(0.0)));
        let (a, b) = (near_mid.distance(eye), far_mid.distance(eye));
        // The smallest sphere around both rings with its centre on the axis: where the
        // distances to the two rings are equal, clamped between them.
        let axis = (far_mid - eye).normalize_or(Vec3::NEG_Z);
        let (centre, radius) = if b > a {
            let t = ((b * b + far_half * far_half - a * a - near_half * near_half)
                / (2.0 * (b - a)))
                .clamp(a, b);
            let r = ((t - a).hypot(near_half)).max((b - t).hypot(far_half));
            (eye + axis * t, r)
        } else {
            (far_mid, far_half.max(near_half))
        };
        let texels = resolution.max(1) as f32;
        let radius = radius.max(1e-6) * (1.0 + 6.0 / texels);
        let radius = ((radius.log2() * 16.0).ceil() / 16.0).exp2();
        let texel = 2.0 * radius / texels;
        let snap = |v: f32| (v / texel).round() * texel;
        Self {
            right,
            up,
            cx: snap(centre.dot(right)),
            cy: snap(centre.dot(up)),
            ct: centre.dot(d),
            radius,
        }
    }

    /// The far side of the region along the direction.
    fn t_far(&self) -> f32 {
        self.ct + self.radius
    }

    /// Whether a box with corners projected to `[lo, hi]` (right, up, along) can shadow a point
    /// of the cascade's square prism up to its far side.
    fn reaches(&self, lo: Vec3, hi: Vec3) -> bool {
        let r = self.radius;
        // Non-finite bounds reach everything (they cannot be ruled out).
        !(lo.is_finite() && hi.is_finite())
            || (lo.x <= self.cx + r
                && hi.x >= self.cx - r
                && lo.y <= self.cy + r
                && hi.y >= self.cy - r
                && lo.z < self.t_far())
    }

    fn matrix(&self, d: Vec3, nearest: f32) -> Mat4 {
        let r = self.radius;
        let t_far = self.t_far();
        let t_near = if nearest.is_finite() {
            (self.ct - r).min(nearest)
        } else {
            self.ct - r
        };
        let depth = 1.0 / (t_far - t_near).max(1e-20);
        Mat4::from_cols(
            (self.right / r).extend(-self.cx / r),
            (self.up / r).extend(-self.cy / r),
            (-d * depth).extend(t_far * depth),
            Vec4::W,
        )
        .transpose()
    }
}

/// An occluder's world box seen in a light frame: the least and greatest (right, up, along)
/// coordinates of its corners.
fn light_frame_bounds(lo: Vec3, hi: Vec3, right: Vec3, up: Vec3, d: Vec3) -> (Vec3, Vec3) {
    let (mut a, mut b) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for i in 0..8 {
        let corner = Vec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        );
        let p = Vec3::new(corner.dot(right), corner.dot(up), corner.dot(d));
        a = a.min(p);
        b = b.max(p);
    }
    (a, b)
}

impl ShadowMapNode {
    /// Creates the node. Errors on a zero or too large resolution or a bias outside [0, 0.5).
    ///
    /// # Errors
    ///
    /// [`Error::InvalidSize`] for a zero resolution or one beyond the device's limits,
    /// [`Error::NonFinite`] or [`Error::InvalidSetting`] for a depth bias outside [0, 0.5).
    pub fn new(device: &wgpu::Device, cache: &Cache, settings: ShadowMapSettings) -> Result<Self> {
        let max = device.limits().max_texture_dimension_2d;
        let min = ShadowMapSettings::MIN_RESOLUTION;
        if settings.resolution < min || settings.resolution > max {
            return Err(Error::InvalidSize {
                field: "shadow map resolution",
                width: settings.resolution,
                height: settings.resolution,
                min,
                max,
            });
        }
        finite("shadow_map.depth_bias", &[settings.depth_bias])?;
        if !(0.0..0.5).contains(&settings.depth_bias) {
            return Err(Error::InvalidSetting {
                field: "shadow_map.depth_bias",
                problem: format!("must lie in [0, 0.5), got {}", settings.depth_bias),
            });
        }
        Ok(Self {
            settings,
            pipelines: cache.get::<Pipelines>(),
            texture: None,
            back: None,
            faces: Vec::new(),
            bounds: Vec::new(),
            back_layers: Vec::new(),
            planes: Vec::new(),
            face_buffer: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("volshadow shadow faces"),
                size: 6 * SLOT,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            instance_buffer: None,
            bind_group: None,
            draws: Vec::new(),
            key: Vec::new(),
            pending: false,
            generation: 0,
            layer_draws: None,
            dirty: Vec::new(),
            occluder_distance: 0.0,
            gaps: true,
            triangles: None,
            gathers: Vec::new(),
            gate: None,
        })
    }

    /// The face matrices this node uses for `light`, with near plane `near`: reversed-Z
    /// infinite perspective per face (90° cube faces, or the spot cone plus a small margin,
    /// widened for a light with a radius by the penumbra's reach beyond the cone: see
    /// [`spot_fov`](Self::spot_fov), with `occluder_distance` the least distance from the
    /// light to an occluder). None for a directional light, whose face depends on the camera
    /// ([`directional_matrix`](Self::directional_matrix)).
    pub fn face_matrices(light: &Light, near: f32, occluder_distance: f32) -> Vec<Mat4> {
        let p = light.position().unwrap_or_default();
        match light {
            Light::Directional(_) => Vec::new(),
            Light::Point(_) => cube_faces(p, near).to_vec(),
            Light::Spot(spot) => {
                use glam::camera::rh::proj::directx::perspective_infinite_reverse;
                let fov = Self::spot_fov(spot, occluder_distance);
                let proj = perspective_infinite_reverse(fov, 1.0, near);
                vec![proj * spot.texture_frame()]
            }
        }
    }

    /// The view depths bounding a directional light's cascades: `cascades + 1` increasing
    /// values from 0 (the eye) to `distance`. The splits are logarithmic (Zhang et al. 2006:
    /// the split that spreads perspective aliasing evenly), `n · (distance / n)^(i / cascades)`
    /// from `n` the camera's near plane or `distance / CASCADE_RANGE`, whichever is farther: a
    /// cascade's texels grow with its distance from the eye, as the pixels they are seen
    /// through do, and a near plane far closer than the distance does not leave the first
    /// cascades covering nothing.
    pub fn cascade_splits(camera: &Camera, distance: f32, cascades: u32) -> Vec<f32> {
        let n = cascades.max(1);
        let distance = if distance.is_finite() && distance > 0.0 {
            distance
        } else {
            1.0
        };
        // The near plane's view depth (an infinite or reversed projection's near plane
        // unprojects like any other).
        let near_ndc = if camera.far_depth() == 1.0 { 0.0 } else { 1.0 };
        let p = camera.projection().inverse() * Vec4::new(0.0, 0.0, near_ndc, 1.0);
        let near = (-p.z / p.w).abs();
        let floor = distance / CASCADE_RANGE;
        let near = if near.is_finite() {
            near.clamp(floor, distance)
        } else {
            floor
        };
        let mut splits = vec![0.0];
        for i in 1..n {
            let split = near * (distance / near).powf(i as f32 / n as f32);
            splits.push(split.clamp(*splits.last().unwrap_or(&0.0), distance));
        }
        splits.push(distance);
        splits
    }

    /// A directional light's `clip_from_world` for a square map of `resolution²` texels:
    /// orthographic, in a basis built from the light's direction alone, covering the bounding
    /// sphere (centred on the view axis) of the camera's view pyramid between view depths
    /// `slice.0` and `slice.1`, its radius widened by 3 texels (a point within a texel of the
    /// square's edge takes the next cascade) and rounded up to 1/16 of an octave so that
    /// rounding noise cannot change it, with the centre snapped to whole texels. Depth is
    /// `(t_far − t)/(t_far − t_near)` for `t` the coordinate along the direction, `t_far` the
    /// sphere's far side and `t_near` its near side or `nearest`, whichever is less (the
    /// nearest occluder that can shadow the sphere: see [`ShadowMapNode`]'s module docs).
    pub fn directional_matrix(
        light: &DirectionalLight,
        camera: &Camera,
        slice: (f32, f32),
        resolution: u32,
        nearest: f32,
    ) -> Mat4 {
        let fit = CascadeFit::new(light, camera, slice, resolution);
        fit.matrix(light.direction(), nearest)
    }

    /// A spot map's field of view: the cone inscribed in the square frustum, with a texel of
    /// margin. For a light of radius r the lines from a point inside the cone to the light's
    /// disc reach occluders outside it: one at distance b from the light lies up to
    /// atan(r / b) off the point's direction, so the field widens by twice that at the least
    /// occluder distance b (an occluder cut off by the map's edge would light its penumbra),
    /// but at most to twice the cone's half-width on the map's plane (texels at most twice as
    /// coarse: an occluder around the light, b = 0, would otherwise take the field to 179°).
    /// Radius 0: the cone alone, as for hard shadows. Never wider than 179°
    /// ([`SpotLight::MAX_CONE_ANGLE`](crate::SpotLight::MAX_CONE_ANGLE), the widest cone, which
    /// the map then covers without margin).
    pub fn spot_fov(spot: &crate::scene::SpotLight, occluder_distance: f32) -> f32 {
        let cone = spot.cone_angle() * 1.02;
        // The widest field: the widest cone a spot may have (see `MAX_CONE_ANGLE` for why), so
        // every point of any cone is in its map.
        let max = crate::scene::SpotLight::MAX_CONE_ANGLE;
        if spot.radius() <= 0.0 {
            return cone.min(max);
        }
        let widened = cone + 2.0 * (spot.radius() / occluder_distance.max(0.0)).atan();
        let twice = 2.0 * (2.0 * (0.5 * cone).tan()).atan();
        widened.min(twice).min(max)
    }

    /// Whether `light`'s penumbrae are narrower than the finest texel of its shadow map of
    /// `resolution` texels across, wherever they are: its radius is then below what the map
    /// resolves, and hard shadows (radius 0) are the better image. Seen from the light, a
    /// penumbra cast by an occluder at distance b spans `2 · radius · (1/b − 1/d)` (as a
    /// tangent) at distance d, less than `2 · radius / occluder_distance`; a map's texels span
    /// `2 · tan(fov/2) / resolution` at its centre and `cos²(fov/2)` times that at the edge
    /// of a spot's map, a third of it at a cube face's corner. False for a radius of 0 (hard
    /// already), a directional light, or an occluder distance of 0.
    ///
    /// [`VolumetricShadows`](crate::VolumetricShadows) draws such a light hard: the exact
    /// method's integration between the shadow's boundaries beats marching a penumbra the map
    /// cannot show (`tests/gpu/soft_grid.rs`'s extreme-lights test compares the two;
    /// `docs/ACCURACY.md`).
    pub fn penumbra_below_texel(light: &Light, occluder_distance: f32, resolution: u32) -> bool {
        let radius = light.radius();
        if !(radius > 0.0 && occluder_distance > 0.0) || resolution == 0 {
            return false;
        }
        let finest = match light {
            Light::Point(_) => 2.0 / 3.0,
            Light::Spot(spot) => {
                // The map it would then be drawn with: the hard light's, the cone's own.
                let hard = spot.with_radius(0.0).unwrap_or(*spot);
                let half = 0.5 * Self::spot_fov(&hard, occluder_distance);
                2.0 * half.tan() * half.cos().powi(2)
            }
            _ => return false,
        } / resolution as f32;
        2.0 * radius / occluder_distance <= finest
    }

    /// Cosine of the widest angle between a face's axis and a direction inside its frustum
    /// (a corner of the square): the near plane lies along the axis, so a point at distance r
    /// can be as near as r times this along it.
    fn corner_cosine(light: &Light, occluder_distance: f32) -> f32 {
        let half_tan = match light {
            Light::Point(_) => 1.0,
            Light::Spot(spot) => (0.5 * Self::spot_fov(spot, occluder_distance)).tan(),
            Light::Directional(_) => 1.0,
        };
        1.0 / (1.0 + 2.0 * half_tan * half_tan).sqrt()
    }

    fn prepare_for(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        inputs: &ShadowMapInputs<'_>,
        camera: Option<&Camera>,
    ) -> Result<bool> {
        let ShadowMapInputs {
            light, occluders, ..
        } = *inputs;
        for occluder in occluders {
            occluder.validate()?;
            occluder.check_device(device)?;
        }
        let needed = (occluders.len().max(1) as u64) * SLOT;
        crate::gpu::check_buffer_allocation(device, "occluder transforms", needed)?;
        let recreate = self.allocate(device, light, needed);
        // Re-render only when something the map depends on changed.
        let directional = match (light, camera) {
            (Light::Directional(l), Some(camera)) => {
                Some(self.directional_faces(l, camera, occluders))
            }
            _ => None,
        };
        let mut key = Self::key(light, occluders, directional.as_ref());
        // Switching between a gated map and one drawn whenever it changes re-renders it.
        key.push(u32::from(inputs.fallback.is_some()));
        let changed = recreate || key != self.key;
        if changed {
            self.key = key;
            self.place(light, occluders, directional);
            self.upload(device, queue, light, occluders);
            self.gather_triangles(device, light, occluders);
            self.pending = true;
            self.generation += 1;
        }
        let Some(crossings) = inputs.fallback else {
            self.gate = None;
            // Still pending when an earlier prepare's render was never encoded.
            return Ok(self.pending);
        };
        let gate = self
            .gate
            .get_or_insert_with(|| Gate::new(device, &self.pipelines.gate));
        if changed {
            // The layers a gated frame records: those with draws, and those that may hold an
            // earlier frame's depth (cleared when the gate opens). Which the GPU drew is not
            // known here, so a layer once drawn stays in the list.
            let mut layers = Vec::new();
            for layer in 0..self.faces.len() {
                let drawn: Vec<(u32, u32, u32)> = match self.layer_draws.as_ref() {
                    Some(l) => l.get(layer).map_or(&[][..], Vec::as_slice).to_vec(),
                    None => (0..self.draws.len() as u32).collect(),
                }
                .into_iter()
                .map(|i| {
                    let draw = &self.draws[i as usize];
                    let instances = if draw.clipped.is_some() { FAN } else { 1 };
                    (i, draw.index_count, instances)
                })
                .collect();
                let dirty = self.dirty.get_mut(layer);
                let was = dirty.as_deref().copied().unwrap_or(true);
                if drawn.is_empty() && !was {
                    continue;
                }
                if let Some(d) = dirty {
                    *d = true;
                }
                layers.push((layer as u32, drawn));
            }
            gate.set_arguments(device, queue, arguments(&layers));
        }
        gate.bind(device, queue, &crossings);
        // The scan runs every frame: only the GPU knows whether this one needs the map.
        Ok(true)
    }

    /// For benches and tests: a gated map's two `u32` (whether it was drawn since its inputs
    /// last changed, and whether the last recorded frame drew it), `None` for a map drawn
    /// whenever it changes ([`ShadowMapInputs::fallback`]).
    pub fn gate_state(&self) -> Option<&wgpu::Buffer> {
        Some(self.gate.as_ref()?.state())
    }

    /// (Re)creates the map (and its back faces' layer for a light with a radius) when its
    /// layers changed, and the occluders' transforms buffer when it is smaller than `needed`
    /// bytes. Returns whether the map was recreated.
    fn allocate(&mut self, device: &wgpu::Device, light: &Light, needed: u64) -> bool {
        let layers = match light {
            Light::Point(_) => 6,
            Light::Directional(d) => d.cascades(),
            _ => 1,
        };
        let resolution = self.settings.resolution;
        let map = |label| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width: resolution,
                    height: resolution,
                    depth_or_array_layers: layers,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::Depth32Float,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                    | wgpu::TextureUsages::TEXTURE_BINDING
                    | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            })
        };
        let wants_back = light.radius() > 0.0;
        let recreate = self
            .texture
            .as_ref()
            .is_none_or(|t| t.depth_or_array_layers() != layers)
            || wants_back != self.back.is_some();
        if recreate {
            self.texture = Some(map("volshadow shadow map"));
            self.back = wants_back.then(|| map("volshadow shadow map back faces"));
            // wgpu zero-initialises a texture before its first use: every layer reads clear.
            self.dirty = vec![false; layers as usize];
        }
        if self
            .instance_buffer
            .as_ref()
            .is_none_or(|b| b.size() < needed)
        {
            let buffer = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("volshadow shadow instances"),
                size: needed,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            self.bind_group = Some(bind_group(
                device,
                "volshadow shadow map",
                &self.pipelines.layout,
                [
                    slot(&self.face_buffer, FACE_BYTES),
                    slot(&buffer, INSTANCE_BYTES),
                ],
            ));
            self.instance_buffer = Some(buffer);
        }
        recreate
    }

    /// What the map depends on: the light's placement, the directional cascades' faces, the
    /// occluders' meshes and transforms.
    fn key(
        light: &Light,
        occluders: &[Occluder<'_>],
        directional: Option<&(Vec<Mat4>, Vec<Vec<u32>>)>,
    ) -> Vec<u32> {
        let bits = |v: &[f32]| v.iter().map(|f| f.to_bits()).collect::<Vec<u32>>();
        let mut key = match (light.position(), &directional) {
            (Some(p), _) => bits(&p.to_array()),
            (None, Some((faces, _))) => faces
                .iter()
                .flat_map(|f| bits(&f.to_cols_array()))
                .collect(),
            (None, None) => Vec::new(),
        };
        if let Light::Spot(s) = light {
            key.extend(bits(&s.direction().to_array()));
            key.push(s.cone_angle().to_bits());
            // The radius widens the map's field of view (`spot_fov`).
            key.push(s.radius().to_bits());
        }
        for o in occluders {
            key.extend([o.mesh.id() as u32, (o.mesh.id() >> 32) as u32]);
            key.extend(bits(&o.transform.to_cols_array()));
        }
        key
    }

    /// The faces' matrices, the occluders' bounds and their separating planes for this light.
    fn place(
        &mut self,
        light: &Light,
        occluders: &[Occluder<'_>],
        directional: Option<(Vec<Mat4>, Vec<Vec<u32>>)>,
    ) {
        // The least distance from the light to an occluder's bounds, each in its own frame as
        // well as the world's (0 without occluders or with the light inside their bounds): a
        // spot map widens by it for a light with a radius (`spot_fov`).
        self.occluder_distance = match light.position() {
            Some(p) => occluders
                .iter()
                .map(|o| o.distance_lower_bound(p))
                .fold(f32::INFINITY, f32::min),
            None => 0.0,
        };
        if !self.occluder_distance.is_finite() {
            self.occluder_distance = 0.0;
        }

        // Near plane: half the distance to the nearest occluder's bounds, or less for a wide
        // spot cone (measured along the axis, an occluder near the frustum's edge is nearer
        // than its distance: a 165° cone clipped a sphere 84° off axis), so every occluder is
        // in front of it. Depth is near / distance in f32 (reversed Z), whose relative
        // precision is the same at every distance, so a tiny near plane costs nothing: no
        // floor relative to the scene's size (a terrain-sized occluder elsewhere would push
        // it past a small occluder next to the light). When the light is inside an occluder's
        // bounds the distance is 0; then a floor of about one f32 step of the light's
        // coordinates (nothing nearer can be placed) keeps the projection finite.
        self.bounds = occluders.iter().map(|o| o.world_sphere()).collect();
        if let Some((faces, drawn)) = directional {
            self.faces = faces;
            self.layer_draws = Some(drawn);
        } else {
            self.layer_draws = match light {
                Light::Point(point) => Some(cube_face_draws(point.position(), &self.bounds)),
                _ => None,
            };
            let p = light.position().unwrap_or_default();
            let along_axis = (0.9 * Self::corner_cosine(light, self.occluder_distance)).min(0.5);
            let mut near = f32::INFINITY;
            for o in occluders {
                near = near.min(along_axis * o.distance_lower_bound(p));
            }
            let floor = 1e-7 * p.abs().max_element().max(1e-3);
            let near = if near.is_finite() {
                near.max(floor)
            } else {
                floor
            };
            self.faces = Self::face_matrices(light, near, self.occluder_distance);
        }
        self.gaps = occluders.len() > 1 || occluders.iter().any(|o| !o.mesh.is_convex());
        self.back_layers = match light {
            Light::Point(point) => cube_faces_touched(point.position(), &self.bounds).to_vec(),
            _ => vec![true; self.faces.len()],
        };
        self.planes = occluders
            .iter()
            .map(|o| {
                light
                    .position()
                    .map_or(Vec4::ZERO, |p| o.separating_plane(p, light.radius()))
            })
            .collect();
    }

    /// Writes the faces' matrices and the occluders' transforms, and lists the draws.
    fn upload(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        light: &Light,
        occluders: &[Occluder<'_>],
    ) {
        let centre = light.position().unwrap_or_default().extend(1.0);
        for (i, face) in self.faces.iter().enumerate() {
            let words = slot_words((*face, centre));
            queue.write_buffer(
                &self.face_buffer,
                i as u64 * SLOT,
                bytemuck::cast_slice(&words),
            );
        }
        let instances = self.instance_buffer.as_ref().expect("just created");
        self.draws.clear();
        for (i, o) in occluders.iter().enumerate() {
            let mut words = [0f32; 20];
            words[..16].copy_from_slice(&o.transform.to_cols_array());
            let reach = clip_reach(light, o);
            words[16] = reach.unwrap_or(0.0);
            queue.write_buffer(instances, i as u64 * SLOT, bytemuck::cast_slice(&words));
            let clipped = reach.map(|_| {
                bind_group(
                    device,
                    "volshadow shadow map clipped",
                    &self.pipelines.clipped_layout,
                    [
                        slot(&self.face_buffer, FACE_BYTES),
                        slot(instances, INSTANCE_BYTES),
                        o.mesh.positions.as_entire_binding(),
                        o.mesh.indices.as_entire_binding(),
                    ],
                )
            });
            self.draws.push(Draw {
                positions: o.mesh.positions.clone(),
                indices: o.mesh.indices.clone(),
                index_count: o.mesh.triangle_count * 3,
                closed: o.mesh.is_closed(),
                clipped,
            });
        }
    }

    /// Lists the gathers of [`ShadowMap::triangles`] where the soft shadows take them (a point
    /// or spot light with a radius, occluders that may leave gaps, at most
    /// [`MAX_EXACT_TRIANGLES`] in all), each occluder's in groups of four.
    fn gather_triangles(
        &mut self,
        device: &wgpu::Device,
        light: &Light,
        occluders: &[Occluder<'_>],
    ) {
        self.gathers.clear();
        let groups = |o: &Occluder<'_>| o.mesh.triangle_count.div_ceil(4);
        let total: u64 = occluders.iter().map(|o| u64::from(groups(o))).sum();
        let wanted = light.radius() > 0.0
            && light.position().is_some()
            && self.gaps
            && total > 0
            && 4 * total <= u64::from(MAX_EXACT_TRIANGLES);
        if !wanted {
            self.triangles = None;
            return;
        }
        let size = total * GROUP_BYTES;
        if self.triangles.as_ref().is_none_or(|b| b.size() != size) {
            self.triangles = Some(device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("volshadow occluder triangles"),
                size,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }));
        }
        let (Some(triangles), Some(instances)) = (&self.triangles, &self.instance_buffer) else {
            return;
        };
        let mut first = 0u64;
        for (i, o) in occluders.iter().enumerate() {
            let count = groups(o);
            let range = u64::from(count) * GROUP_BYTES;
            let group = bind_group(
                device,
                "volshadow occluder triangles",
                &self.pipelines.gather_layout,
                [
                    wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: instances,
                        offset: i as u64 * SLOT,
                        size: wgpu::BufferSize::new(64),
                    }),
                    o.mesh.positions.as_entire_binding(),
                    o.mesh.indices.as_entire_binding(),
                    wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: triangles,
                        offset: first,
                        size: wgpu::BufferSize::new(range),
                    }),
                ],
            );
            self.gathers.push((group, count.div_ceil(64)));
            first += range;
        }
    }

    /// The directional map's cascades for this camera and these occluders: each one's face,
    /// and which occluders can shadow its region (the only ones drawn into it).
    fn directional_faces(
        &self,
        light: &DirectionalLight,
        camera: &Camera,
        occluders: &[Occluder<'_>],
    ) -> (Vec<Mat4>, Vec<Vec<u32>>) {
        let d = light.direction();
        let (right, up) = d.any_orthonormal_pair();
        let eye = camera.eye();
        let mut farthest = 0.0f32;
        let boxes: Vec<(Vec3, Vec3)> = occluders
            .iter()
            .map(|o| {
                let (lo, hi) = o.world_bounds();
                // The farthest corner.
                farthest = farthest.max((eye - lo).abs().max((eye - hi).abs()).length());
                light_frame_bounds(lo, hi, right, up, d)
            })
            .collect();
        let distance =
            light
                .shadow_distance()
                .unwrap_or(if farthest > 0.0 && farthest.is_finite() {
                    farthest
                } else {
                    1.0
                });
        let splits = Self::cascade_splits(camera, distance, light.cascades());
        let resolution = self.settings.resolution;
        let mut faces = Vec::new();
        let mut drawn = Vec::new();
        for slice in splits.windows(2) {
            let fit = CascadeFit::new(light, camera, (slice[0], slice[1]), resolution);
            let mut nearest = f32::INFINITY;
            let mut layer = Vec::new();
            for (i, &(lo, hi)) in boxes.iter().enumerate() {
                if fit.reaches(lo, hi) {
                    nearest = nearest.min(lo.z);
                    layer.push(i as u32);
                }
            }
            faces.push(fit.matrix(d, nearest));
            drawn.push(layer);
        }
        (faces, drawn)
    }

    /// The shadow map for the march (`None` before the first `prepare`).
    pub fn shadow_map(&self) -> Option<ShadowMap<'_>> {
        Some(ShadowMap {
            texture: self.texture.as_ref()?,
            back: self.back.as_ref(),
            faces: &self.faces,
            depth_bias: self.settings.depth_bias,
            bounds: &self.bounds,
            planes: &self.planes,
            occluder_distance: self.occluder_distance,
            gaps: self.gaps,
            triangles: self.triangles.as_ref(),
            generation: self.generation,
        })
    }
}

/// A depth-only render pass over one layer of `target`, loading it as `load` says.
fn layer_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    target: &wgpu::Texture,
    layer: u32,
    load: wgpu::LoadOp<f32>,
    timer: Option<&mut GpuTimer>,
) -> wgpu::RenderPass<'e> {
    let view = target.create_view(&wgpu::TextureViewDescriptor {
        label: Some("volshadow shadow face"),
        dimension: Some(wgpu::TextureViewDimension::D2),
        base_array_layer: layer,
        array_layer_count: Some(1),
        ..Default::default()
    });
    crate::gpu::passes::begin_render(
        encoder,
        &wgpu::RenderPassDescriptor {
            label: Some("volshadow shadow map"),
            color_attachments: &[],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &view,
                depth_ops: Some(wgpu::Operations {
                    load,
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: timer.and_then(|t| t.render_pass(Pass::ShadowMap)),
            occlusion_query_set: None,
            multiview_mask: None,
        },
    )
}

impl ShadowMapNode {
    /// Records a gated map ([`ShadowMapInputs::fallback`]): the gate's scan, then each listed
    /// layer's render pass, which loads the layer and draws its clear and its occluders from
    /// the gate's arguments (zero, drawing nothing, unless the gate opened).
    fn encode_gated(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        mut timer: Option<&mut GpuTimer>,
    ) -> Result<()> {
        let (Some(texture), Some(bind_group), Some(gate)) =
            (&self.texture, &self.bind_group, self.gate.as_mut())
        else {
            return Ok(());
        };
        gate.encode(encoder, timer.as_deref_mut());
        let Some(live) = gate.live() else {
            return Ok(());
        };
        for layer in &gate.layers {
            let timer = timer.as_deref_mut();
            let mut pass = layer_pass(encoder, texture, layer.layer, wgpu::LoadOp::Load, timer);
            let face = layer.layer * SLOT as u32;
            pass.set_pipeline(&self.pipelines.clear);
            pass.set_bind_group(0, bind_group, &[face, 0]);
            pass.draw_indirect(live, layer.clear);
            for &(i, at) in &layer.draws {
                let draw = &self.draws[i as usize];
                let offsets = [face, i * SLOT as u32];
                if let Some(clipped) = &draw.clipped {
                    pass.set_pipeline(&self.pipelines.depth_clipped);
                    pass.set_bind_group(0, clipped, &offsets);
                    pass.draw_indirect(live, at);
                    continue;
                }
                pass.set_pipeline(&self.pipelines.depth);
                pass.set_bind_group(0, bind_group, &offsets);
                pass.set_vertex_buffer(0, draw.positions.slice(..));
                pass.set_index_buffer(draw.indices.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed_indirect(live, at);
            }
        }
        Ok(())
    }
}

impl Node for ShadowMapNode {
    type Inputs<'a> = ShadowMapInputs<'a>;

    /// Validates the occluders and decides whether the map must be re-rendered. Returns
    /// whether the next [`encode`](Encode::encode) will render. A directional light's
    /// orthographic map is fitted to what `inputs.camera` sees up to the light's
    /// [shadow distance](DirectionalLight::with_shadow_distance), or, without one, up to the
    /// farthest corner of the occluders' bounds (see [`directional_matrix`](Self::directional_matrix)),
    /// and re-renders only when the fitted map moved by a texel, the light or an occluder
    /// changed; point and spot lights do not read the camera.
    ///
    /// # Errors
    ///
    /// [`Error::NonFinite`] or [`Error::SingularMatrix`] for an occluder's transform.
    fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        inputs: &ShadowMapInputs<'_>,
    ) -> Result<bool> {
        let camera = matches!(inputs.light, Light::Directional(_)).then_some(inputs.camera);
        self.prepare_for(device, queue, inputs, camera)
    }
}

impl Encode for ShadowMapNode {
    /// Records the render of every face, if [`prepare`](Self::prepare) found a change.
    fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        mut timer: Option<&mut GpuTimer>,
    ) -> Result<()> {
        let pending = std::mem::take(&mut self.pending);
        if self.gate.is_some() {
            return self.encode_gated(encoder, timer);
        }
        if !pending {
            return Ok(());
        }
        let (Some(texture), Some(bind_group)) = (&self.texture, &self.bind_group) else {
            return Ok(());
        };
        // The front surfaces, then (a light with a radius) the back faces.
        let targets = std::iter::once((texture, false)).chain(self.back.iter().map(|b| (b, true)));
        for (target, back) in targets {
            for layer in 0..target.depth_or_array_layers() {
                if back
                    && !self
                        .back_layers
                        .get(layer as usize)
                        .copied()
                        .unwrap_or(true)
                {
                    continue;
                }
                let drawn = self
                    .layer_draws
                    .as_ref()
                    .and_then(|l| l.get(layer as usize));
                let draws = drawn.map_or(self.draws.len(), Vec::len);
                if !back {
                    // A layer with nothing to draw that is already clear stays as it is.
                    let dirty = self.dirty.get_mut(layer as usize);
                    if draws == 0 && dirty.as_deref() == Some(&false) {
                        continue;
                    }
                    if let Some(d) = dirty {
                        *d = draws > 0;
                    }
                }
                let timer = timer.as_deref_mut();
                let mut pass = layer_pass(encoder, target, layer, wgpu::LoadOp::Clear(0.0), timer);
                let mut all = 0..self.draws.len() as u32;
                let mut listed = drawn.map(|l| l.iter().copied());
                let indices: &mut dyn Iterator<Item = u32> = match listed.as_mut() {
                    Some(l) => l,
                    None => &mut all,
                };
                for i in indices {
                    // An open mesh has no inside: its back layer is its nearest face.
                    self.draws[i as usize].record(
                        &mut pass,
                        &self.pipelines,
                        bind_group,
                        [layer * SLOT as u32, i * SLOT as u32],
                        back,
                    );
                }
            }
        }
        if !self.gathers.is_empty() {
            let groups: Vec<[&wgpu::BindGroup; 1]> =
                self.gathers.iter().map(|(g, _)| [g]).collect();
            let dispatches: Vec<_> = self
                .gathers
                .iter()
                .zip(&groups)
                .map(|((_, n), g)| (&self.pipelines.gather, &g[..], (*n, 1, 1)))
                .collect();
            dispatch(
                encoder,
                timer,
                Pass::ShadowMap,
                "volshadow occluder triangles",
                &dispatches,
            );
        }
        Ok(())
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// `SHADOW_WGSL` is pasted by callers on its own, so its spiral's hash (`volshadow_turn`)
    /// is a copy of the medium's (`soft_turn`, pcss.wgsl), the integer hash chosen for WGSL's
    /// precision (docs/METHOD.md §6): a change to one must reach the other.
    #[test]
    fn the_surface_and_the_medium_hash_alike() {
        let body = |source: &str, name: &str| -> String {
            let start = source
                .find(&format!("fn {name}("))
                .unwrap_or_else(|| panic!("{name} missing"));
            let rest = &source[start..];
            let from = rest.find("let b = bitcast").expect("the hash's first line");
            let to = rest.find("return").expect("the hash's return");
            rest[from..to].split_whitespace().collect()
        };
        let surface = body(crate::SHADOW_WGSL, "volshadow_turn");
        let medium = body(include_str!("../../shaders/pcss.wgsl"), "soft_turn");
        assert!(surface.len() > 100, "the hash's text was not found");
        assert_eq!(
            surface, medium,
            "shadow.wgsl's hash differs from pcss.wgsl's"
        );
    }

    /// Every point of the view pyramid's slice of each cascade lies in that cascade's square,
    /// at least a texel inside its edge (where the shaders take it), and within its depth
    /// range: seeded views, sun directions, distances from 1e-2 to 1e5 and 1 to 6 cascades,
    /// 500 points per slice. (A square of the fitted sphere's own radius, without the 3 texels'
    /// widening, was tried as the broken variant: it too holds every point, so this test does
    /// not show that the widening is needed.)
    #[test]
    fn every_point_of_a_slice_lies_in_its_cascade() {
        let mut next = uniform(0x0dd_ba11_cafe_f00d);
        for case in 0..60 {
            let scale = [1.0e-2_f32, 1.0, 1.0e3, 1.0e5][case % 4];
            let eye = Vec3::new(next(), next(), next()) * scale;
            let target =
                eye + Vec3::new(next(), next() * 0.5, next()).normalize_or(Vec3::X) * scale;
            let fov = 0.4 + 1.2 * next().abs();
            let camera = Camera::new(
                glam::camera::rh::view::look_at_mat4(eye, target, Vec3::Y),
                glam::camera::rh::proj::directx::perspective(fov, 1.3, 0.01 * scale, 1e4 * scale),
            )
            .unwrap();
            let dir = Vec3::new(next(), -next().abs() - 0.05, next());
            let light = DirectionalLight::new(dir, Vec3::ONE).unwrap();
            let cascades = 1 + (case % 6) as u32;
            let distance = scale * (1.0 + 100.0 * next().abs());
            let resolution = 1024;
            let splits = ShadowMapNode::cascade_splits(&camera, distance, cascades);
            assert_eq!(splits.len(), cascades as usize + 1);
            assert!(splits.windows(2).all(|w| w[0] <= w[1]), "{splits:?}");
            for (k, slice) in splits.windows(2).enumerate() {
                let fit = CascadeFit::new(&light, &camera, (slice[0], slice[1]), resolution);
                let face = fit.matrix(light.direction(), f32::INFINITY);
                let edge = 1.0 - 2.0 / resolution as f32;
                for _ in 0..500 {
                    let (x, y) = (next(), next());
                    let depth = slice[0] + (slice[1] - slice[0]) * (0.5 + 0.5 * next());
                    let ray = camera.ray_direction(x, y);
                    let per_unit = -camera.view().transform_vector3(ray).z;
                    let p = eye + ray * (depth / per_unit);
                    let c = face * p.extend(1.0);
                    let tol = 1e-4;
                    assert!(
                        c.x.abs() <= edge + tol && c.y.abs() <= edge + tol,
                        "case {case}, cascade {k}: {p} at {c}"
                    );
                    assert!(
                        c.z >= -tol && c.z <= 1.0 + tol,
                        "case {case}, cascade {k}: depth {}",
                        c.z
                    );
                }
            }
        }
    }

    /// Seeded numbers uniform in [−1, 1) (xorshift64).
    pub(crate) fn uniform(mut seed: u64) -> impl FnMut() -> f32 {
        move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f32 / (1u64 << 53) as f32 * 2.0 - 1.0
        }
    }

    /// `cube_clip` of shaders/pcss.wgsl, line for line: a face's clip coordinates as a signed
    /// permutation of the offset from the light.
    fn cube_clip(face: usize, rel: Vec3, near: f32) -> Vec4 {
        let sign = if face & 1 == 1 { -1.0 } else { 1.0 };
        match face {
            0 | 1 => Vec4::new(sign * rel.z, rel.y, near, sign * rel.x),
            2 | 3 => Vec4::new(sign * rel.x, rel.z, near, sign * rel.y),
            _ => Vec4::new(-sign * rel.x, rel.y, near, sign * rel.z),
        }
    }

    /// The node's own cube faces are recognised, with their near plane, at light positions and
    /// near planes from 1e-3 to 1e5, and there the shaders' permutation gives the faces'
    /// projection (ndc within 1e-5 over seeded points of each face); a caller's faces that
    /// differ (another up vector, another order, a spot's one face, a uniform scale that
    /// projects the same but is not the node's) are not, and keep their matrices. A
    /// permutation with one sign wrong fails the projection check, so it can tell.
    #[test]
    fn the_node_s_cube_faces_project_by_permutation() {
        let mut next = uniform(0x2545_f491_4f6c_dd1d);
        let mut wrong_sign_failed = 0;
        for &scale in &[1.0e-3_f32, 1.0, 37.0, 1.0e5] {
            let position = Vec3::new(next(), next(), next()) * scale;
            let near = 1.0e-3 * scale.max(1.0);
            let faces = cube_faces(position, near);
            assert_eq!(standard_cube_near(&faces, position), near, "scale {scale}");
            for _ in 0..2000 {
                let rel = Vec3::new(next(), next(), next()) * scale;
                let face = {
                    let m = rel.abs();
                    let axis = if m.x >= m.y && m.x >= m.z {
                        0
                    } else if m.y >= m.z {
                        1
                    } else {
                        2
                    };
                    2 * axis + usize::from(rel[axis] <= 0.0)
                };
                let ndc = |c: Vec4| c.truncate() / c.w;
                let by_matrix = ndc(faces[face] * (position + rel).extend(1.0));
                let by_permutation = ndc(cube_clip(face, rel, near));
                let err = (by_matrix - by_permutation).abs();
                assert!(
                    err.x <= 1.0e-5 && err.y <= 1.0e-5 && err.z <= 1.0e-5 * by_matrix.z.abs(),
                    "face {face}, rel {rel}: matrix {by_matrix}, permutation {by_permutation}"
                );
                let mut flipped = cube_clip(face, rel, near);
                flipped.x = -flipped.x;
                if (ndc(flipped) - by_matrix).abs().max_element() > 1.0e-3 {
                    wrong_sign_failed += 1;
                }
            }
            let mut other_up = faces;
            other_up[0] = {
                use glam::camera::rh::{
                    proj::directx::perspective_infinite_reverse, view::look_to_mat4,
                };
                perspective_infinite_reverse(std::f32::consts::FRAC_PI_2, 1.0, near)
                    * look_to_mat4(position, Vec3::X, Vec3::NEG_Y)
            };
            assert_eq!(standard_cube_near(&other_up, position), 0.0);
            let mut reordered = faces;
            reordered.swap(2, 3);
            assert_eq!(standard_cube_near(&reordered, position), 0.0);
            assert_eq!(standard_cube_near(&faces[..1], position), 0.0);
            let scaled = faces.map(|f| f * 1.001);
            assert_eq!(standard_cube_near(&scaled, position), 0.0);
            assert_eq!(standard_cube_near(&faces, position + Vec3::X * scale), 0.0);
        }
        assert!(wrong_sign_failed > 7000, "{wrong_sign_failed}");
    }

    /// Every point of a sphere lies in a face `cube_faces_touched` marks (2000 seeded spheres
    /// around lights at scales 1e-3 to 1e5, 200 points each, on and inside the surface), and a
    /// small sphere on an axis marks its face alone, so the test can skip faces. Marking only
    /// the face of the sphere's centre leaves points out, so the test can tell.
    #[test]
    fn every_point_of_a_sphere_lies_in_a_touched_face() {
        let mut next = uniform(0x9e37_79b9_7f4a_7c15);
        let face_of = |p: Vec3| {
            let m = p.abs();
            let a = if m.x >= m.y && m.x >= m.z {
                0
            } else if m.y >= m.z {
                1
            } else {
                2
            };
            2 * a + usize::from(p[a] < 0.0)
        };
        let mut centre_only_missed = 0;
        for i in 0..2000 {
            let scale = [1.0e-3_f32, 1.0, 1.0e5][i % 3];
            let light = Vec3::new(next(), next(), next()) * scale;
            let centre = light + Vec3::new(next(), next(), next()) * 2.0 * scale;
            let radius = (0.5 * next() + 0.55) * scale;
            let touched = cube_faces_touched(light, &[centre.extend(radius)]);
            for _ in 0..200 {
                let dir = Vec3::new(next(), next(), next()).normalize_or(Vec3::X);
                let depth = if next() > 0.0 { 1.0 } else { next().abs() };
                let p = centre + dir * radius * depth - light;
                assert!(
                    touched[face_of(p)],
                    "sphere {centre} r {radius}, light {light}: point {p} in face {}, marked {touched:?}",
                    face_of(p)
                );
                if face_of(p) != face_of(centre - light) {
                    centre_only_missed += 1;
                }
            }
        }
        assert!(centre_only_missed > 1000, "{centre_only_missed}");
        let small = cube_faces_touched(Vec3::ZERO, &[Vec4::new(0.0, 0.0, -5.0, 1.0)]);
        assert_eq!(small, [false, false, false, false, false, true]);
    }
}

#[cfg(test)]
#[test]
fn params_layout_matches_shadow_wgsl() {
    use crate::nodes::layout::{assert_same, rust_layout};
    let rust = rust_layout!(ShadowParams {
        faces,
        light_position,
        depth_bias,
        layers,
        normal_offset,
        directional,
        radius,
    });
    assert_same(rust, crate::SHADOW_WGSL, "VolshadowShadow");
}
