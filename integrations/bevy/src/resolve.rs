//! Multisampled depth to one value per pixel, for the passes that read single-sampled depth.

use volshadow::wgpu;

/// Writes the median sample of each pixel of a multisampled depth texture into a single-sampled
/// one.
pub(crate) struct DepthResolve {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
}

const SHADER: &str = r"
@group(0) @binding(0) var depth_ms: texture_depth_multisampled_2d;

@vertex
fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

// The median of the pixel's samples (the upper one for an even count): where two surfaces
// share a pixel, the depth of the one that covers most of its samples, which is most likely
// the one at its centre.
@fragment
fn fs(@builtin(position) p: vec4<f32>) -> @builtin(frag_depth) f32 {
    let pixel = vec2<i32>(p.xy);
    let n = i32(textureNumSamples(depth_ms));
    var picked = textureLoad(depth_ms, pixel, 0);
    for (var i = 0; i < n; i++) {
        let d = textureLoad(depth_ms, pixel, i);
        var below = 0;
        var equal = 0;
        for (var j = 0; j < n; j++) {
            let e = textureLoad(depth_ms, pixel, j);
            below += select(0, 1, e < d);
            equal += select(0, 1, e == d);
        }
        if (below <= n / 2 && n / 2 < below + equal) {
            picked = d;
        }
    }
    return picked;
}
";

/// The resolved depth's format: what Bevy's 3D depth is.
const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

impl DepthResolve {
    pub(crate) fn new(device: &wgpu::Device) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("volshadow_bevy depth resolve"),
            source: wgpu::ShaderSource::Wgsl(SHADER.into()),
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("volshadow_bevy depth resolve"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Depth,
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: true,
                },
                count: None,
            }],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("volshadow_bevy depth resolve"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("volshadow_bevy depth resolve"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: Default::default(),
            depth_stencil: Some(wgpu::DepthStencilState {
                format: FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Always),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs"),
                compilation_options: Default::default(),
                targets: &[],
            }),
            multiview_mask: None,
            cache: None,
        });
        Self { pipeline, layout }
    }

    /// The single-sampled target for `source` and the bind group that reads it: `kept` while
    /// it was made for this source texture, else a new one (kept in `kept`).
    pub(crate) fn prepare(
        &self,
        device: &wgpu::Device,
        kept: &mut Option<ResolvedDepth>,
        source: &wgpu::Texture,
    ) -> wgpu::Texture {
        if let Some(r) = kept.as_ref().filter(|r| r.source == *source) {
            return r.target.clone();
        }
        let target = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("volshadow_bevy resolved depth"),
            size: source.size(),
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let source_view = source.create_view(&wgpu::TextureViewDescriptor {
            aspect: wgpu::TextureAspect::DepthOnly,
            ..Default::default()
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("volshadow_bevy depth resolve"),
            layout: &self.layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::TextureView(&source_view),
            }],
        });
        let resolved = ResolvedDepth {
            source: source.clone(),
            target_view: target.create_view(&Default::default()),
            target: target.clone(),
            bind_group,
        };
        *kept = Some(resolved);
        target
    }

    /// Records the resolve that [`prepare`](Self::prepare) set up.
    pub(crate) fn encode(&self, encoder: &mut wgpu::CommandEncoder, resolved: &ResolvedDepth) {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("volshadow_bevy depth resolve"),
            color_attachments: &[],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &resolved.target_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(0.0),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &resolved.bind_group, &[]);
        pass.draw(0..3, 0..1);
    }
}

/// A view's resolved depth: the single-sampled target and the bind group reading the
/// multisampled source it was made for (Bevy reuses a view's depth texture while its size
/// stays, so both are kept across frames).
pub(crate) struct ResolvedDepth {
    source: wgpu::Texture,
    target: wgpu::Texture,
    target_view: wgpu::TextureView,
    bind_group: wgpu::BindGroup,
}
