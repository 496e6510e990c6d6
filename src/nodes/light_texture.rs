//! The light-texture node: a textured spot light's texture as a blurred mip chain, and the map
//! of its flat regions.
//!
//! # Input
//! The caller's texture (e.g. from [`LightTexture::upload`](crate::scene::LightTexture::upload)):
//! 2D, one array layer, single-sampled, usage `TEXTURE_BINDING`, a format that can be filtered on this device
//! (`Rgba8Unorm[Srgb]`, `Rgba16Float`, …; `Rgba32Float` only with `FLOAT32_FILTERABLE`), linear
//! RGB radiance multipliers, row 0 at the top of the spot's frame.
//!
//! # Output
//! - [`texture`](LightTextureNode::texture): `Rgba16Float`, the input's size, a full mip chain
//!   (each level a 4×4 tent of the one above);
//! - [`flats`](LightTextureNode::flats): `Rgba8Uint`, one texel per cell between four texel
//!   centres of level 0 (`max(w − 1, 1)` by `max(h − 1, 1)`; a cell is flat when its four
//!   texels are equal): per quadrant (+x+y, −x+y, +x−y, −x−y), the side of the largest square
//!   of flat cells, at most 63, that has the cell at its corner and extends into that quadrant;
//!   0 where the cell is not flat. Bilinear lookups anywhere in such a square return one value,
//!   so the march crosses it in one step (`shaders/passes/light_texture_flats.wgsl`).
//!
//! Both are rebuilt only when the input texture changes.

use crate::error::{Error, Result};
use crate::gpu::pipeline::{bind_group, fullscreen_pipeline, layout, module, Binding};
use crate::gpu::wgsl::wgsl_file;
use crate::gpu::GpuTimer;
use crate::gpu::ShaderPrecision;
use crate::nodes::cache::CachedPipelines;
use crate::nodes::Cache;
use crate::nodes::{Encode, Node};
use crate::pass::Pass;
use crate::scene::TextureChannels;

/// The binding table: `@binding(i)` of `shaders/passes/light_texture.wgsl` is entry `i`.
const BINDINGS: [Binding; 2] = [
    Binding::Filterable, // source
    Binding::Sampler,    // linear_sampler
];

/// The flat-region passes' binding table (`shaders/passes/light_texture_flats.wgsl`).
const FLATS_BINDINGS: [Binding; 2] = [
    Binding::Texture,     // source (level 0 of the mip chain)
    Binding::UintTexture, // previous (the previous pass's output)
];

/// The flat-region passes: entry point, output's label and format (the last is the map).
const FLATS_PASSES: [(&str, &str, wgpu::TextureFormat); 3] = [
    (
        "fs_flags",
        "volshadow light texture flat cells",
        wgpu::TextureFormat::R8Uint,
    ),
    (
        "fs_runs",
        "volshadow light texture flat runs",
        wgpu::TextureFormat::Rg8Uint,
    ),
    (
        "fs_squares",
        "volshadow light texture flats",
        wgpu::TextureFormat::Rgba8Uint,
    ),
];

/// The node's layouts and pipelines (level 0, the levels below; the flat-region map's flags,
/// rows and columns), held by the [`Cache`].
#[derive(Clone)]
pub(crate) struct Pipelines {
    layout: wgpu::BindGroupLayout,
    /// Level 0 from RGB, the levels below, level 0 from red.
    levels: [wgpu::RenderPipeline; 3],
    flats_layout: wgpu::BindGroupLayout,
    flats: [wgpu::RenderPipeline; 3],
}

impl CachedPipelines for Pipelines {
    fn build(device: &wgpu::Device, precision: ShaderPrecision) -> Self {
        Self::new(device, precision)
    }
}

impl Pipelines {
    pub(crate) fn new(device: &wgpu::Device, precision: ShaderPrecision) -> Self {
        let flats_label = "volshadow light texture flats";
        let flats_layout = layout(
            device,
            flats_label,
            wgpu::ShaderStages::FRAGMENT,
            &FLATS_BINDINGS,
        );
        let flats_module = module(device, &wgsl_file!("light_texture_flats.wgsl"), precision);
        let flats = FLATS_PASSES.map(|(entry, _, format)| {
            fullscreen_pipeline(
                device,
                flats_label,
                &flats_layout,
                &flats_module,
                entry,
                format,
                &[],
            )
        });
        let label = "volshadow light texture";
        let layout = layout(device, label, wgpu::ShaderStages::FRAGMENT, &BINDINGS);
        let module = module(device, &wgsl_file!("light_texture.wgsl"), precision);
        let format = wgpu::TextureFormat::Rgba16Float;
        let levels = ["fs_copy", "fs_down", "fs_copy_red"]
            .map(|entry| fullscreen_pipeline(device, label, &layout, &module, entry, format, &[]));
        Self {
            layout,
            levels,
            flats_layout,
            flats,
        }
    }
}

/// A prepared light texture as the march reads it: the node's two outputs (see the module
/// docs), from [`LightTextureNode::maps`].
#[derive(Debug, Clone, Copy)]
pub struct LightTextureMaps<'a> {
    /// The blurred mip chain.
    pub mips: &'a wgpu::Texture,
    /// The flat-region map of the chain's level 0.
    pub flats: &'a wgpu::Texture,
}

/// Builds and holds the blurred mip chain of a light texture and the map of its flat regions.
pub struct LightTextureNode {
    pipelines: Pipelines,
    sampler: wgpu::Sampler,
    source: Option<wgpu::Texture>,
    channels: TextureChannels,
    mips: Option<wgpu::Texture>,
    /// Per level: the bind group reading the level above (or the source) and the target view.
    levels: Vec<(wgpu::BindGroup, wgpu::TextureView)>,
    /// The flat cells, their runs along x and the flat-region map (see the module docs).
    flats: Option<[wgpu::Texture; 3]>,
    /// The flags, runs and squares passes: each one's bind group and target view.
    flat_passes: Vec<(wgpu::BindGroup, wgpu::TextureView)>,
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
            channels: TextureChannels::Rgb,
            mips: None,
            levels: Vec::new(),
            flats: None,
            flat_passes: Vec::new(),
            pending: false,
        })
    }

    /// The mip chain (`None` before the first `prepare`).
    pub fn texture(&self) -> Option<&wgpu::Texture> {
        self.mips.as_ref()
    }

    /// The flat-region map of the mip chain's level 0 (see the module docs; `None` before the
    /// first `prepare`).
    pub fn flats(&self) -> Option<&wgpu::Texture> {
        self.flats.as_ref().map(|f| &f[2])
    }

    /// Both outputs, for [`MarchInputs::light_texture`](crate::nodes::MarchInputs::light_texture)
    /// (`None` before the first `prepare`).
    pub fn maps(&self) -> Option<LightTextureMaps<'_>> {
        Some(LightTextureMaps {
            mips: self.mips.as_ref()?,
            flats: self.flats()?,
        })
    }
}

/// The light-texture node's input: the caller's texture and which of its channels count.
#[derive(Debug, Clone, Copy)]
pub struct LightTextureInput<'a> {
    /// The texture (see the module docs).
    pub texture: &'a wgpu::Texture,
    /// Its RGB, or its red channel as a grey mask.
    pub channels: TextureChannels,
}

impl Node for LightTextureNode {
    type Inputs<'a> = LightTextureInput<'a>;

    /// Validates the texture and schedules a rebuild when it or the channels differ from the
    /// last ones. Returns whether the next [`encode`](Self::encode) rebuilds the mip chain.
    ///
    /// # Errors
    ///
    /// [`Error::InvalidTexture`] naming `light_texture` for a texture that is not a filterable 2D
    /// colour texture with `TEXTURE_BINDING`.
    fn prepare(
        &mut self,
        device: &wgpu::Device,
        _queue: &wgpu::Queue,
        input: &LightTextureInput<'_>,
    ) -> Result<bool> {
        let texture = input.texture;
        check_texture(device, texture)?;
        if self.source.as_ref() == Some(texture) && self.channels == input.channels {
            return Ok(self.pending);
        }
        self.build_mips(device, texture);
        self.build_flats(device, texture);
        self.source = Some(texture.clone());
        self.channels = input.channels;
        self.pending = true;
        Ok(true)
    }
}

impl LightTextureNode {
    /// (Re)creates the mip chain for `texture` and each level's bind group (reading the level
    /// above, or the source) and target view.
    fn build_mips(&mut self, device: &wgpu::Device, texture: &wgpu::Texture) {
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
    }

    /// (Re)creates the flat-region textures of the chain's level 0 (cells of `texture`'s size
    /// less one) and the bind group and target of each of the flags, runs and squares passes.
    fn build_flats(&mut self, device: &wgpu::Device, texture: &wgpu::Texture) {
        let (w, h) = (texture.width(), texture.height());
        let mips = self.mips.as_ref().expect("created with the levels");
        let cells = wgpu::Extent3d {
            width: (w - 1).max(1),
            height: (h - 1).max(1),
            depth_or_array_layers: 1,
        };
        let flats = FLATS_PASSES.map(|(_, label, format)| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: cells,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                    | wgpu::TextureUsages::TEXTURE_BINDING
                    | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            })
        });
        let level0 = mips.create_view(&wgpu::TextureViewDescriptor {
            base_mip_level: 0,
            mip_level_count: Some(1),
            ..Default::default()
        });
        let views = flats.each_ref().map(|t| t.create_view(&Default::default()));
        // Each pass reads the one before (the first, which reads only the source, is bound
        // the runs it does not read).
        self.flat_passes = [(1, 0), (0, 1), (1, 2)]
            .into_iter()
            .map(|(read, write)| {
                let bind_group = bind_group(
                    device,
                    "volshadow light texture flats pass",
                    &self.pipelines.flats_layout,
                    [
                        wgpu::BindingResource::TextureView(&level0),
                        wgpu::BindingResource::TextureView(&views[read]),
                    ],
                );
                (bind_group, views[write].clone())
            })
            .collect();
        self.flats = Some(flats);
    }
}

/// Checks that `texture` is a filterable single-sampled 2D colour texture of one layer, with
/// `TEXTURE_BINDING`.
fn check_texture(device: &wgpu::Device, texture: &wgpu::Texture) -> Result<()> {
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
    Ok(())
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
        let levels = self
            .levels
            .iter()
            .enumerate()
            .map(|(level, (bind_group, target))| {
                let pipeline = match (level, self.channels) {
                    (0, TextureChannels::Rgb) => 0,
                    (0, TextureChannels::Red) => 2,
                    _ => 1,
                };
                (&self.pipelines.levels[pipeline], bind_group, target)
            });
        let flats = self
            .pipelines
            .flats
            .iter()
            .zip(&self.flat_passes)
            .map(|(pipeline, (bind_group, target))| (pipeline, bind_group, target));
        for (pipeline, bind_group, target) in levels.chain(flats) {
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
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, bind_group, &[]);
            pass.draw(0..3, 0..1);
        }
        Ok(())
    }
}
