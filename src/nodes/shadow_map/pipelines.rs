//! The shadow-map node's binding tables, pipelines and uniform slots.

use glam::{Mat4, Vec4};

use crate::gpu::pipeline::{compute_pipeline, depth_pipeline, layout, module, Binding};
use crate::gpu::wgsl::wgsl_file;
use crate::gpu::ShaderPrecision;
use crate::nodes::cache::CachedPipelines;
use crate::nodes::shadow_gate::GatePipelines;

/// The binding table: `@binding(i)` of `shaders/passes/shadow_map.wgsl` is entry `i`.
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
pub(super) const FACE_BYTES: u64 = 80;
/// WGSL `Instance`: the occluder's transform and its [`clip_reach`](super::draw::clip_reach) (0:
/// none).
pub(super) const INSTANCE_BYTES: u64 = 80;

/// The binding table of `shaders/passes/triangles.wgsl` (the occluders' triangles for the exact
/// visible fraction, [`ShadowMap::triangles`](super::ShadowMap::triangles)).
const TRIANGLE_BINDINGS: [Binding; 4] = [
    Binding::Params,    // instance: world_from_object, the occluder's slot
    Binding::Params,    // positions
    Binding::Params,    // indices
    Binding::ReadWrite, // triangles: this occluder's range
];

/// The node's layout and pipeline, held by the [`Cache`](crate::nodes::Cache).
#[derive(Clone)]
pub(crate) struct Pipelines {
    pub(super) layout: wgpu::BindGroupLayout,
    /// Every face: the nearest surface.
    pub(super) depth: wgpu::RenderPipeline,
    /// Faces turned away from the light only: a closed occluder's nearest back face.
    pub(super) back: wgpu::RenderPipeline,
    /// `depth` and `back` for occluders far larger than their distance to the light, whose
    /// triangles are clipped around the light first (`vs_shadow_clipped`, [`clip_reach`]).
    pub(super) clipped_layout: wgpu::BindGroupLayout,
    pub(super) depth_clipped: wgpu::RenderPipeline,
    pub(super) back_clipped: wgpu::RenderPipeline,
    /// The occluders' triangles in world space (`shaders/passes/triangles.wgsl`).
    pub(super) gather_layout: wgpu::BindGroupLayout,
    pub(super) gather: wgpu::ComputePipeline,
    /// A gated map's clear: depth 0 over the layer, drawn indirectly (`vs_clear`).
    pub(super) clear: wgpu::RenderPipeline,
    /// The gate's scan of the crossing lists ([`shadow_gate`](crate::nodes::shadow_gate)).
    pub(super) gate: GatePipelines,
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

/// Uniform slots are 256 bytes apart (the core minimum dynamic-offset alignment).
pub(super) const SLOT: u64 = 256;

/// The first `size` bytes of `buffer`, bound at a dynamic offset of one [`SLOT`] per item.
pub(super) fn slot(buffer: &wgpu::Buffer, size: u64) -> wgpu::BindingResource<'_> {
    wgpu::BindingResource::Buffer(wgpu::BufferBinding {
        buffer,
        offset: 0,
        size: wgpu::BufferSize::new(size),
    })
}

/// WGSL `ShadowFace`'s words: the matrix's columns, then the centre.
pub(super) fn slot_words((face, centre): (Mat4, Vec4)) -> [u32; 20] {
    let mut words = [0u32; 20];
    for (w, f) in words
        .iter_mut()
        .zip(face.to_cols_array().into_iter().chain(centre.to_array()))
    {
        *w = f.to_bits();
    }
    words
}
