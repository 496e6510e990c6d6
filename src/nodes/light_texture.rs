//! The light-texture node: a textured spot light's texture as a blurred mip chain.
//!
//! # Input
//! The caller's texture (e.g. from [`LightTexture::upload`](crate::scene::LightTexture::upload)):
//! 2D, one array layer, single-sampled, usage `TEXTURE_BINDING`, a format that can be filtered on this device
//! (`Rgba8Unorm[Srgb]`, `Rgba16Float`, …; `Rgba32Float` only with `FLOAT32_FILTERABLE`), linear
//! RGB radiance multipliers, row 0 at the top of the spot's frame.
//!
//! # Output
//! `Rgba16Float`, the input's size, a full mip chain (each level a 4×4 tent of the one above),
//! rebuilt only when the input texture changes.

use crate::error::{Error, Result};
use crate::gpu::pipeline::{bind_group, fullscreen_pipeline, layout, module, Binding};
use crate::gpu::wgsl::wgsl_file;
use crate::gpu::GpuTimer;
use crate::gpu::ShaderPrecision;
use crate::nodes::cache::CachedPipelines;
use crate::nodes::Cache;
use crate::nodes::{Encode, Node};
use crate::pass::Pass;

/// The binding table: `@binding(i)` of `shaders/light_texture.wgsl` is entry `i`.
const BINDINGS: [Binding; 2] = [
    Binding::Filterable, // source
    Binding::Sampler,    // linear_sampler
];

/// The node's layout and its two pipelines (level 0, the levels below), held by the [`Cache`].
#[derive(Clone)]
pub(crate) struct Pipelines {
    layout: wgpu::BindGroupLayout,
    levels: [wgpu::RenderPipeline; 2],
}

impl CachedPipelines for Pipelines {
    fn build(device: &wgpu::Device, precision: ShaderPrecision) -> Self {
        Self::new(device, precision)
    }
}

impl Pipelines {
    pub(crate) fn new(device: &wgpu::Device, precision: ShaderPrecision) -> Self {
        let label = "volshadow light texture";
        let layout = layout(device, label, wgpu::ShaderStages::FRAGMENT, &BINDINGS);
        let module = module(device, &wgsl_file!("light_texture.wgsl"), precision);
        let format = wgpu::TextureFormat::Rgba16Float;
        let levels = ["fs_copy", "fs_down"]
            .map(|entry| fullscreen_pipeline(device, label, &layout, &module, entry, format, &[]));
        Self { layout, levels }
    }
}

/// Builds and holds the blurred mip chain of a light texture.
pub struct LightTextureNode {
    pipelines: Pipelines,
    sampler: wgpu::Sampler,
    source: Option<wgpu::Texture>,
    mips: Option<wgpu::Texture>,
    /// Per level: the bind group reading the level above (or the source) and the target view.
    levels: Vec<(wgpu::BindGroup, wgpu::TextureView)>,
    pending: bool,
}

impl LightTextureNode {
    /// Creates the node.
    pub fn new(device: &wgpu::Device, cache: &Cache) -> Result<Self> {
        Ok(Self {
            pipelines: cache.get::<Pipelines>(),
            sampler: device.create_sampler(&wgpu::SamplerDescriptor {
                label: Some("volshadow light texture"),
                mag_filter: wgpu::FilterMode::Linear,
                min_filter: wgpu::FilterMode::Linear,
                ..Default::default()
            }),
            source: None,
            mips: None,
            levels: Vec::new(),
            pending: false,
        })
    }

    /// The mip chain (`None` before the first `prepare`).
    pub fn texture(&self) -> Option<&wgpu::Texture> {
        self.mips.as_ref()
    }
}

impl Node for LightTextureNode {
    type Inputs<'a> = wgpu::Texture;

    /// Validates `texture` and schedules a rebuild when it differs from the last one. Returns
    /// whether the next [`encode`](Self::encode) rebuilds the mip chain.
    ///
    /// # Errors
    ///
    /// [`Error::InvalidTexture`] naming `light_texture` for a texture that is not a filterable 2D
    /// colour texture with `TEXTURE_BINDING`.
    fn prepare(
        &mut self,
        device: &wgpu::Device,
        _queue: &wgpu::Queue,
        texture: &wgpu::Texture,
    ) -> Result<bool> {
        let problem = |p: String| {
            Err(Error::InvalidTexture {
                field: "light_texture",
                problem: p,
            })
        };
        let format = texture.format();
        let filterable = format
            .guaranteed_format_features(device.features())
            .flags
            .contains(wgpu::TextureFormatFeatureFlags::FILTERABLE);
        let float = matches!(
            format.sample_type(None, Some(device.features())),
            Some(wgpu::TextureSampleType::Float { filterable: true })
        );
        if !(filterable && float) {
            return problem(format!("{format:?} cannot be filtered on this device"));
        }
        if texture.dimension() != wgpu::TextureDimension::D2 || texture.sample_count() != 1 {
            return problem("must be a single-sampled 2D texture".into());
        }
        if texture.depth_or_array_layers() != 1 {
            return problem(format!(
                "has {} array layers, expected 1",
                texture.depth_or_array_layers()
            ));
        }
        if !texture
            .usage()
            .contains(wgpu::TextureUsages::TEXTURE_BINDING)
        {
            return problem("needs TextureUsages::TEXTURE_BINDING".into());
        }
        if self.source.as_ref() == Some(texture) {
            return Ok(self.pending);
        }
        let (w, h) = (texture.width(), texture.height());
        let levels = 32 - w.max(h).leading_zeros();
        self.mips = Some(device.create_texture(&wgpu::TextureDescriptor {
            label: Some("volshadow light texture mips"),
            size: wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
            mip_level_count: levels,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba16Float,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        }));
        let mips = self.mips.as_ref().expect("created above");
        self.levels = (0..levels)
            .map(|level| {
                let input = if level == 0 {
                    // Mip 0 alone: the caller's texture may have a mip chain of its own.
                    texture.create_view(&wgpu::TextureViewDescriptor {
                        dimension: Some(wgpu::TextureViewDimension::D2),
                        mip_level_count: Some(1),
                        ..Default::default()
                    })
                } else {
                    mips.create_view(&wgpu::TextureViewDescriptor {
                        base_mip_level: level - 1,
                        mip_level_count: Some(1),
                        ..Default::default()
                    })
                };
                let target = mips.create_view(&wgpu::TextureViewDescriptor {
                    base_mip_level: level,
                    mip_level_count: Some(1),
                    ..Default::default()
                });
                let bind_group = bind_group(
                    device,
                    "volshadow light texture level",
                    &self.pipelines.layout,
                    [
                        wgpu::BindingResource::TextureView(&input),
                        wgpu::BindingResource::Sampler(&self.sampler),
                    ],
                );
                (bind_group, target)
            })
            .collect();
        self.source = Some(texture.clone());
        self.pending = true;
        Ok(true)
    }
}

impl Encode for LightTextureNode {
    /// Records the mip chain build if the texture changed since the last build.
    fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        mut timer: Option<&mut GpuTimer>,
    ) -> Result<()> {
        if !std::mem::take(&mut self.pending) {
            return Ok(());
        }
        for (level, (bind_group, target)) in self.levels.iter().enumerate() {
            let timestamp_writes = timer
                .as_deref_mut()
                .and_then(|t| t.render_pass(Pass::LightTexture));
            let mut pass = crate::gpu::passes::begin_render(
                encoder,
                &wgpu::RenderPassDescriptor {
                    label: Some("volshadow light texture level"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: target,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                            store: wgpu::StoreOp::Store,
                        },
                    })],
                    depth_stencil_attachment: None,
                    timestamp_writes,
                    occlusion_query_set: None,
                    multiview_mask: None,
                },
            );
            pass.set_pipeline(&self.pipelines.levels[usize::from(level > 0)]);
            pass.set_bind_group(0, bind_group, &[]);
            pass.draw(0..3, 0..1);
        }
        Ok(())
    }
}
