//! The composite's binding table, WGSL and pipelines: one per output format and surface term,
//! drawn or (where the format is a storage format) computed, and the spot term's lattice pass.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use crate::gpu::pipeline::{cached, fullscreen_pipeline, layout, module, Binding};
use crate::gpu::wgsl::{wgsl_file, Wgsl};
use crate::gpu::ShaderPrecision;
use crate::nodes::cache::CachedPipelines;

use super::MAX_LIGHTS;

/// The composite's binding table: `@binding(i)` of `shaders/shared/composite.wgsl` is entry `i`.
const BINDINGS: [Binding; 10 + MAX_LIGHTS] = [
    Binding::Params,  // comp
    Binding::Params,  // view
    Binding::Texture, // scene_color
    Binding::Depth,   // scene_depth
    Binding::Texture, // inscatter0 ..
    Binding::Texture,
    Binding::Texture,
    Binding::Texture,
    Binding::Params,  // surf
    Binding::Texture, // surface_normal
    Binding::Texture, // surface_albedo
    Binding::Texture, // iss_table
    Binding::Params,  // surf_phase
    Binding::Texture, // spot_lattice
];

/// The composite's layout and its pipelines, one per output format and with or without the
/// surface term (built on first use); held by the [`Cache`](crate::nodes::Cache).
#[derive(Clone)]
pub(crate) struct Pipelines {
    pub(super) layout: wgpu::BindGroupLayout,
    pub(super) module: wgpu::ShaderModule,
    pub(super) precision: ShaderPrecision,
    pub(super) formats: Arc<Mutex<HashMap<(wgpu::TextureFormat, bool), wgpu::RenderPipeline>>>,
    /// The compute pass's pipelines, per storage format and surface term, with the layout of
    /// their second bind group (the output).
    pub(super) storing: Arc<Mutex<HashMap<(wgpu::TextureFormat, bool), Storing>>>,
    /// The spot term's lattice pass (`cs_spot_lattice`), with its output's layout.
    pub(super) lattice: Arc<Mutex<HashMap<(), Storing>>>,
}

/// A compute composite writing one storage format.
#[derive(Clone)]
pub(super) struct Storing {
    pub(super) pipeline: wgpu::ComputePipeline,
    pub(super) output_layout: wgpu::BindGroupLayout,
}

/// The compute composite's workgroup edge (`@workgroup_size` of `cs_composite`).
pub(super) const WORKGROUP: u32 = 8;

/// The spot term's lattice texture format (E(P) in rgb, whether the node is a surface in a).
pub(super) const LATTICE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;

/// The lattice's size for a `width × height` frame at spacing `stride`: node `(i, j)` is pixel
/// `min((i, j)·stride, size − 1)`, so the last pixel of each row and column is a node.
pub(super) fn lattice_size(width: u32, height: u32, stride: u32) -> (u32, u32) {
    ((width - 1) / stride + 2, (height - 1) / stride + 2)
}

/// The WGSL name of `format` when the composite can write it as a storage texture on `device`
/// (`None`: it writes it through the rasteriser only). sRGB formats are never storage formats.
pub(super) fn storage_format_name(
    device: &wgpu::Device,
    format: wgpu::TextureFormat,
) -> Option<&'static str> {
    use wgpu::TextureFormat as F;
    let name = match format {
        F::Rgba8Unorm => "rgba8unorm",
        F::Rgba8Snorm => "rgba8snorm",
        F::Rgba16Float => "rgba16float",
        F::Rgba32Float => "rgba32float",
        F::Bgra8Unorm => "bgra8unorm",
        _ => return None,
    };
    format
        .guaranteed_format_features(device.features())
        .allowed_usages
        .contains(wgpu::TextureUsages::STORAGE_BINDING)
        .then_some(name)
}

/// The composite's WGSL: the surface term's functions (`ISS_WGSL`'s), then the composite.
const SOURCE: Wgsl<'static> = wgsl_file!(shared "composite.wgsl");

impl CachedPipelines for Pipelines {
    fn build(device: &wgpu::Device, precision: ShaderPrecision) -> Self {
        Self::new(device, precision)
    }
}

impl Pipelines {
    pub(crate) fn new(device: &wgpu::Device, precision: ShaderPrecision) -> Self {
        let label = "volshadow composite";
        let stages = wgpu::ShaderStages::FRAGMENT | wgpu::ShaderStages::COMPUTE;
        Self {
            layout: layout(device, label, stages, &BINDINGS),
            module: module(device, &SOURCE, precision),
            precision,
            formats: Arc::default(),
            storing: Arc::default(),
            lattice: Arc::default(),
        }
    }

    /// The compute pipeline of the spot term's lattice (see [`CompositeNode::set_spot_lattice`]):
    /// the composite's bindings, and its output as `@group(1) @binding(0)`.
    pub(super) fn lattice(&self, device: &wgpu::Device) -> Storing {
        cached(&self.lattice, (), || {
            let label = "volshadow spot lattice";
            let source = format!(
                "#import composite.wgsl
@group(1) @binding(0) var lattice_out: texture_storage_2d<rgba32float, write>;

@compute @workgroup_size({WORKGROUP}, {WORKGROUP})
fn cs_spot_lattice(@builtin(global_invocation_id) id: vec3<u32>) {{
    if (any(id.xy >= textureDimensions(lattice_out))) {{
        return;
    }}
    let s = surface_point(min(id.xy * surf.lattice, textureDimensions(scene_depth) - 1u));
    var out = vec4<f32>(0.0);
    if (s.ok) {{
        out = vec4<f32>(spot_irradiance(s.p, s.n), 1.0);
    }}
    textureStore(lattice_out, id.xy, out);
}}
"
            );
            self.with_output(
                device,
                label,
                &source,
                "cs_spot_lattice",
                LATTICE_FORMAT,
                true,
            )
        })
    }

    /// A compute pipeline over the composite's bindings (group 0) and one storage texture of
    /// `format` (group 1), from `source`: an import of the composite's WGSL and an entry point.
    pub(super) fn with_output(
        &self,
        device: &wgpu::Device,
        label: &str,
        source: &str,
        entry: &str,
        format: wgpu::TextureFormat,
        surfaces: bool,
    ) -> Storing {
        let name = format!(
            "{} (composite.wgsl and its entry point {entry})",
            SOURCE.name
        );
        let module = module(
            device,
            &Wgsl {
                name: &name,
                text: source,
            },
            self.precision,
        );
        let output_layout = layout(
            device,
            label,
            wgpu::ShaderStages::COMPUTE,
            &[Binding::Storage(format)],
        );
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(label),
            bind_group_layouts: &[Some(&self.layout), Some(&output_layout)],
            immediate_size: 0,
        });
        let constants = [("SURFACES", if surfaces { 1.0 } else { 0.0 })];
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(label),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some(entry),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants: &constants,
                ..Default::default()
            },
            cache: None,
        });
        Storing {
            pipeline,
            output_layout,
        }
    }

    /// The compute pipeline storing `format` (see [`storage_format_name`]), adding the surface
    /// term if `surfaces`; `None` when `format` is not a storage format on `device`.
    pub(super) fn storing(
        &self,
        device: &wgpu::Device,
        format: wgpu::TextureFormat,
        surfaces: bool,
    ) -> Option<Storing> {
        let name = storage_format_name(device, format)?;
        Some(cached(&self.storing, (format, surfaces), || {
            let label = "volshadow composite (compute)";
            let source = format!(
                "#import composite.wgsl
@group(1) @binding(0) var composite_out: texture_storage_2d<{name}, write>;

@compute @workgroup_size({WORKGROUP}, {WORKGROUP})
fn cs_composite(@builtin(global_invocation_id) id: vec3<u32>) {{
    if (all(id.xy < textureDimensions(composite_out))) {{
        textureStore(composite_out, id.xy, composite_pixel(id.xy));
    }}
}}
"
            );
            self.with_output(device, label, &source, "cs_composite", format, surfaces)
        }))
    }

    /// The pipeline writing `format`, adding the surface term if `surfaces` (a pipeline
    /// constant: frames without surfaces do not pay for its code).
    pub(super) fn writing(
        &self,
        device: &wgpu::Device,
        format: wgpu::TextureFormat,
        surfaces: bool,
    ) -> wgpu::RenderPipeline {
        cached(&self.formats, (format, surfaces), || {
            let (label, entry) = ("volshadow composite", "fs_composite");
            let constants = [("SURFACES", if surfaces { 1.0 } else { 0.0 })];
            fullscreen_pipeline(
                device,
                label,
                &self.layout,
                &self.module,
                entry,
                format,
                &constants,
            )
        })
    }
}

#[cfg(test)]
#[test]
fn params_layouts_match_the_wgsl() {
    use crate::nodes::groups::uniforms::{CompositeUniform, SurfacesUniform};
    use crate::nodes::layout::{assert_same, rust_layout};
    assert_same(
        rust_layout!(CompositeUniform { sigma_t, count }),
        SOURCE.text,
        "Composite",
    );
    let surfaces = rust_layout!(SurfacesUniform {
        sigma_s,
        count,
        lights,
        lattice,
    });
    assert_same(surfaces, SOURCE.text, "Surfaces");
}
