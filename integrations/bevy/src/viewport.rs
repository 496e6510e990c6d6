//! Cameras that draw part of their target, or share it with other cameras: volshadow runs on
//! the camera's rectangle of the target (its [`Region`]) in textures of the view's own, and
//! [`RegionWrite`] writes the post-process target, the scene as it is outside the rectangle and
//! the fogged rectangle inside it.
//!
//! Cameras on one target share Bevy's main textures, and each post-process pass of each camera
//! swaps them, so which of the two holds a camera's scene is known only when it records: such
//! a view copies its rectangle out of the current one when it records, and its write pass binds
//! the textures of that moment, as Bevy's own post-process passes do.

use volshadow::wgpu;

/// A rectangle of a view's target in physical pixels, from its top-left corner.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Region {
    pub(crate) origin: [u32; 2],
    pub(crate) size: [u32; 2],
}

impl Region {
    /// The whole of a target `size` wide and high.
    pub(crate) fn whole(size: wgpu::Extent3d) -> Self {
        Self {
            origin: [0, 0],
            size: [size.width, size.height],
        }
    }

    /// The part of `viewport` (origin, size) inside a target of `size`; `None` where nothing of
    /// it is.
    pub(crate) fn clamped(viewport: ([u32; 2], [u32; 2]), size: wgpu::Extent3d) -> Option<Self> {
        let (origin, extent) = viewport;
        let limit = [size.width, size.height];
        let end = [0, 1].map(|i| origin[i].saturating_add(extent[i]).min(limit[i]));
        let size = [0, 1].map(|i| end[i].saturating_sub(origin[i]));
        (size[0] > 0 && size[1] > 0).then_some(Self { origin, size })
    }

    pub(crate) fn extent(self) -> wgpu::Extent3d {
        wgpu::Extent3d {
            width: self.size[0],
            height: self.size[1],
            depth_or_array_layers: 1,
        }
    }

    /// A single-sampled 2D texture of the region's size.
    pub(crate) fn texture(
        self,
        device: &wgpu::Device,
        label: &str,
        format: wgpu::TextureFormat,
        usage: wgpu::TextureUsages,
    ) -> wgpu::Texture {
        device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: self.extent(),
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        })
    }

    /// The uniform the shaders read: origin, then size.
    fn uniform(self) -> [u32; 4] {
        [self.origin[0], self.origin[1], self.size[0], self.size[1]]
    }
}

/// The region's uniform buffer (`vec4<u32>`: origin, size), written by the queue when the
/// region changes.
pub(crate) struct RegionUniform {
    region: Option<Region>,
    pub(crate) buffer: wgpu::Buffer,
}

impl RegionUniform {
    pub(crate) fn new(device: &wgpu::Device, label: &str) -> Self {
        Self {
            region: None,
            buffer: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: 16,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
        }
    }

    /// The layout entry of a fragment shader's region uniform at `binding`.
    pub(crate) fn layout_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
        wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: wgpu::BufferSize::new(16),
            },
            count: None,
        }
    }

    pub(crate) fn set(&mut self, queue: &wgpu::Queue, region: Region) {
        if self.region != Some(region) {
            let bytes: Vec<u8> = region
                .uniform()
                .iter()
                .flat_map(|v| v.to_le_bytes())
                .collect();
            queue.write_buffer(&self.buffer, 0, &bytes);
            self.region = Some(region);
        }
    }
}

/// A view's own textures for its region: the scene's colour copied out of the target, and the
/// facade's output, both of the region's size and the target's format.
pub(crate) struct RegionTextures {
    pub(crate) region: Region,
    pub(crate) color: wgpu::Texture,
    pub(crate) output: wgpu::Texture,
    output_view: wgpu::TextureView,
    uniform: RegionUniform,
}

impl RegionTextures {
    /// The textures for `region` of a target of `format`: `kept` when it was made for them.
    pub(crate) fn prepare<'a>(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        kept: &'a mut Option<RegionTextures>,
        region: Region,
        format: wgpu::TextureFormat,
    ) -> &'a RegionTextures {
        let fits =
            |t: &RegionTextures| t.color.format() == format && t.color.size() == region.extent();
        if !kept.as_ref().is_some_and(fits) {
            let texture = |label, usage| region.texture(device, label, format, usage);
            let color = texture(
                "volshadow_bevy region colour",
                wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            );
            let output = texture(
                "volshadow_bevy region output",
                wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            );
            *kept = Some(RegionTextures {
                region,
                color,
                output_view: output.create_view(&Default::default()),
                output,
                uniform: RegionUniform::new(device, "volshadow_bevy region"),
            });
        }
        let textures = kept.as_mut().expect("made above");
        textures.region = region;
        textures.uniform.set(queue, region);
        textures
    }

    /// Copies the region of `source` (the view's main texture as the view records) into
    /// [`color`](Self::color).
    pub(crate) fn copy_in(&self, encoder: &mut wgpu::CommandEncoder, source: &wgpu::Texture) {
        let [x, y] = self.region.origin;
        encoder.copy_texture_to_texture(
            wgpu::TexelCopyTextureInfo {
                texture: source,
                mip_level: 0,
                origin: wgpu::Origin3d { x, y, z: 0 },
                aspect: wgpu::TextureAspect::All,
            },
            self.color.as_image_copy(),
            self.region.extent(),
        );
    }
}

/// A full-target pass's pipeline: [`FULL_TARGET_VERTEX`]'s `vs` and `module`'s `fs`, one bind
/// group of `layout`, writing `targets` (and `depth`).
pub(crate) fn full_target_pipeline(
    device: &wgpu::Device,
    label: &str,
    module: &wgpu::ShaderModule,
    layout: &wgpu::BindGroupLayout,
    targets: &[Option<wgpu::ColorTargetState>],
    depth_stencil: Option<wgpu::DepthStencilState>,
) -> wgpu::RenderPipeline {
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    });
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(&pipeline_layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some("vs"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: Default::default(),
        depth_stencil,
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some("fs"),
            compilation_options: Default::default(),
            targets,
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// The plugin's full-target passes' vertex stage: one triangle covering the target.
pub(crate) const FULL_TARGET_VERTEX: &str = r"
@vertex
fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}
";

const SHADER: &str = r"
@group(0) @binding(0) var scene: texture_2d<f32>;
@group(0) @binding(1) var fog: texture_2d<f32>;
// origin (xy) and size (zw) of the fogged rectangle
@group(0) @binding(2) var<uniform> region: vec4<u32>;

@fragment
fn fs(@builtin(position) p: vec4<f32>) -> @location(0) vec4<f32> {
    let pixel = vec2<u32>(p.xy);
    // Below the origin the difference wraps to a huge value: outside too.
    let local = pixel - region.xy;
    if (all(local < region.zw)) {
        return textureLoad(fog, local, 0);
    }
    return textureLoad(scene, pixel, 0);
}
";

/// The write pass: the post-process target from the scene and a region's fogged rectangle.
/// One pipeline per target format, made when a view of that format first needs it.
pub(crate) struct RegionWrite {
    module: wgpu::ShaderModule,
    layout: wgpu::BindGroupLayout,
    pipelines: Vec<(wgpu::TextureFormat, wgpu::RenderPipeline)>,
    /// An empty region's uniform, for a write of the scene alone.
    none: wgpu::Buffer,
}

impl RegionWrite {
    pub(crate) fn new(device: &wgpu::Device) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("volshadow_bevy region write"),
            source: wgpu::ShaderSource::Wgsl(format!("{FULL_TARGET_VERTEX}{SHADER}").into()),
        });
        let texture = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: false },
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled: false,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("volshadow_bevy region write"),
            entries: &[texture(0), texture(1), RegionUniform::layout_entry(2)],
        });
        let none = RegionUniform::new(device, "volshadow_bevy no region").buffer;
        Self {
            module,
            layout,
            pipelines: Vec::new(),
            none,
        }
    }

    /// Makes the pipeline for targets of `format`, unless made already.
    pub(crate) fn prepare(&mut self, device: &wgpu::Device, format: wgpu::TextureFormat) {
        if self.pipelines.iter().any(|(f, _)| *f == format) {
            return;
        }
        let pipeline = full_target_pipeline(
            device,
            "volshadow_bevy region write",
            &self.module,
            &self.layout,
            &[Some(format.into())],
            None,
        );
        self.pipelines.push((format, pipeline));
    }

    /// Writes `destination`: `scene`, with `fogged`'s output in its region when given. The
    /// bind group is made here, for the textures of this moment (as Bevy's post-process passes
    /// make theirs). Nothing is recorded where no pipeline was prepared for the format.
    pub(crate) fn encode(
        &self,
        device: &wgpu::Device,
        encoder: &mut wgpu::CommandEncoder,
        scene: &wgpu::Texture,
        fogged: Option<&RegionTextures>,
        destination: &wgpu::Texture,
    ) {
        let Some((_, pipeline)) = self
            .pipelines
            .iter()
            .find(|(f, _)| *f == destination.format())
        else {
            return;
        };
        let scene_view = scene.create_view(&Default::default());
        let (fog, region) = match fogged {
            Some(t) => (&t.output_view, &t.uniform.buffer),
            None => (&scene_view, &self.none),
        };
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("volshadow_bevy region write"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(&scene_view),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(fog),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: region.as_entire_binding(),
                },
            ],
        });
        let target = destination.create_view(&Default::default());
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("volshadow_bevy region write"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &target,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &bind_group, &[]);
        pass.draw(0..3, 0..1);
    }
}
