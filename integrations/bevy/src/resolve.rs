//! A view's depth as the passes read it: one value per pixel, of the view's region of its
//! target. Multisampled depth is resolved (the median of each pixel's samples); a camera with a
//! viewport, or sharing its target, has its rectangle cut out.

use volshadow::wgpu;

use crate::viewport::{full_target_pipeline, Region, RegionUniform, FULL_TARGET_VERTEX};

/// Writes, for each pixel of a region of a depth texture, the one value the passes read into a
/// single-sampled texture of the region's size: the median sample where the source is
/// multisampled, the depth itself where not.
pub(crate) struct DepthResolve {
    multisampled: Resolve,
    single: Resolve,
}

/// One source kind's pipeline and layout.
struct Resolve {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
}

const REGION: &str = r"
// origin (xy) and size (zw) of the region read
@group(0) @binding(1) var<uniform> region: vec4<u32>;
";

// The median of the pixel's samples (the upper one for an even count): where two surfaces
// share a pixel, the depth of the one that covers most of its samples, which is most likely
// the one at its centre. The surfaces' decode reads its normal from the same sample.
pub(crate) const MEDIAN_SAMPLE: &str = r"
fn median_sample(depth_ms: texture_depth_multisampled_2d, pixel: vec2<i32>) -> i32 {
    let n = i32(textureNumSamples(depth_ms));
    var picked = 0;
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
            picked = i;
        }
    }
    return picked;
}
";

const MULTISAMPLED: &str = r"
@group(0) @binding(0) var depth_ms: texture_depth_multisampled_2d;

@fragment
fn fs(@builtin(position) p: vec4<f32>) -> @builtin(frag_depth) f32 {
    let pixel = vec2<i32>(p.xy) + vec2<i32>(region.xy);
    return textureLoad(depth_ms, pixel, median_sample(depth_ms, pixel));
}
";

const SINGLE: &str = r"
@group(0) @binding(0) var depth: texture_depth_2d;

@fragment
fn fs(@builtin(position) p: vec4<f32>) -> @builtin(frag_depth) f32 {
    return textureLoad(depth, vec2<i32>(p.xy) + vec2<i32>(region.xy), 0);
}
";

/// The resolved depth's format: what Bevy's 3D depth is.
const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

impl Resolve {
    fn new(device: &wgpu::Device, multisampled: bool) -> Self {
        let label = if multisampled {
            "volshadow_bevy depth resolve"
        } else {
            "volshadow_bevy depth crop"
        };
        let fragment = if multisampled {
            format!("{MEDIAN_SAMPLE}{MULTISAMPLED}")
        } else {
            SINGLE.to_string()
        };
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(label),
            source: wgpu::ShaderSource::Wgsl(
                format!("{FULL_TARGET_VERTEX}{REGION}{fragment}").into(),
            ),
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(label),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Depth,
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled,
                    },
                    count: None,
                },
                RegionUniform::layout_entry(1),
            ],
        });
        let pipeline = full_target_pipeline(
            device,
            label,
            &module,
            &layout,
            &[],
            Some(wgpu::DepthStencilState {
                format: FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Always),
                stencil: Default::default(),
                bias: Default::default(),
            }),
        );
        Self { pipeline, layout }
    }
}

impl DepthResolve {
    pub(crate) fn new(device: &wgpu::Device) -> Self {
        Self {
            multisampled: Resolve::new(device, true),
            single: Resolve::new(device, false),
        }
    }

    /// The single-sampled depth of `region` of `source` (`kept` when it was made for them),
    /// to be written by [`encode`](Self::encode) as the view records.
    pub(crate) fn prepare(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        kept: &mut Option<ResolvedDepth>,
        source: &wgpu::Texture,
        region: Region,
    ) -> wgpu::Texture {
        if let Some(r) = kept
            .as_mut()
            .filter(|r| r.source == *source && r.target.size() == region.extent())
        {
            r.region.set(queue, region);
            return r.target.clone();
        }
        let target = region.texture(
            device,
            "volshadow_bevy resolved depth",
            FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
        );
        let source_view = source.create_view(&wgpu::TextureViewDescriptor {
            aspect: wgpu::TextureAspect::DepthOnly,
            ..Default::default()
        });
        let resolve = self.of(source);
        let mut uniform = RegionUniform::new(device, "volshadow_bevy depth region");
        uniform.set(queue, region);
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("volshadow_bevy depth resolve"),
            layout: &resolve.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(&source_view),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: uniform.buffer.as_entire_binding(),
                },
            ],
        });
        *kept = Some(ResolvedDepth {
            source: source.clone(),
            target_view: target.create_view(&Default::default()),
            target: target.clone(),
            region: uniform,
            bind_group,
        });
        target
    }

    fn of(&self, source: &wgpu::Texture) -> &Resolve {
        if source.sample_count() > 1 {
            &self.multisampled
        } else {
            &self.single
        }
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
        pass.set_pipeline(&self.of(&resolved.source).pipeline);
        pass.set_bind_group(0, &resolved.bind_group, &[]);
        pass.draw(0..3, 0..1);
    }
}

/// A view's resolved depth: the single-sampled target, the region it reads and the bind group
/// reading the source it was made for (Bevy reuses a view's depth texture while its size
/// stays, so all are kept across frames).
pub(crate) struct ResolvedDepth {
    source: wgpu::Texture,
    target: wgpu::Texture,
    target_view: wgpu::TextureView,
    region: RegionUniform,
    bind_group: wgpu::BindGroup,
}
