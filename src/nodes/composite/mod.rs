//! The composite node: `Ls · exp(−σt · ds) + L_sctr` into the caller's target.
//!
//! # Inputs (all the same size, single-sampled, usage `TEXTURE_BINDING`)
//! * `scene_color`: the caller's shaded colour Ls, linear radiance, any format with a float
//!   sample type (`Rgba16Float`, `Rgba32Float`, `Rgba8Unorm`, …). Alpha is passed through.
//! * `scene_depth`: the caller's depth buffer, any depth format; far depth is sky (see
//!   [`Camera::far_depth`]), which an attenuating medium hides completely.
//! * `inscatter`: up to [`MAX_LIGHTS`] in-scatter textures, one per light, added together:
//!   [`MarchNode::output`](crate::nodes::MarchNode::output) at full scale, or
//!   [`UpsampleNode::output`](crate::nodes::UpsampleNode::output). Empty for a medium that
//!   does not scatter (attenuation only).
//!
//! # Output
//! An [`OutputTarget`]: one mip level and array layer of a single-sampled 2D texture with usage
//! `RENDER_ATTACHMENT`, of the format given to [`CompositeNode::new`] (or its sRGB twin), whose
//! size *at that mip level* is the inputs' size, and not one of the inputs. Every pixel is
//! written (linear radiance; tone mapping is the caller's).
//!
//! A target with usage `STORAGE_BINDING` in the node's own format, where that is a storage
//! format (`Rgba8Unorm`, `Rgba8Snorm`, `Rgba16Float`, `Rgba32Float`, and `Bgra8Unorm` on a
//! device with `BGRA8UNORM_STORAGE`), is written by a compute pass instead of the rasteriser
//! (it then needs no `RENDER_ATTACHMENT`), the same values to the bit. Give your target that
//! usage where you can: on GPUs whose graphics units are a small part of the chip (NVIDIA's
//! H100 and H200 shade fragments on 2 of their 66 texture processing clusters), the compute
//! pass is far cheaper; `cargo bench --bench frame` measures both. The node takes the texture and the
//! subresource rather than a `wgpu::TextureView`, because a view does not tell its size, mip
//! level or layer: checking the texture behind a view would accept a view of the wrong mip
//! level (and write a crop) and reject a correct one.

use std::hash::{Hash, Hasher};
use std::sync::atomic::{AtomicU64, Ordering};

use bytemuck::Zeroable;

use crate::error::{Error, Result};
use crate::gpu::pipeline::bind_group;
use crate::gpu::{
    check_depth_texture, check_float_texture, check_size, depth_view, texture_2d, GpuTimer,
    UniformBuffer,
};
use crate::nodes::groups::uniforms::{CompositeUniform, SurfacesUniform, ViewUniform};
use crate::nodes::Cache;
use crate::nodes::{IssPhase, IssTableNode};
use crate::pass::Pass;
use crate::scene::{Camera, Light, Medium};

mod pipelines;

pub(crate) use pipelines::Pipelines;

use pipelines::{lattice_size, Storing, LATTICE_FORMAT, WORKGROUP};

/// What the composite reads in a frame.
#[derive(Debug, Clone, Copy)]
pub struct CompositeInputs<'a> {
    /// The camera the frame was rendered with.
    pub camera: &'a Camera,
    /// The medium (its σt attenuates the scene colour).
    pub medium: &'a Medium,
    /// The caller's shaded colour.
    pub scene_color: &'a wgpu::Texture,
    /// The caller's depth buffer.
    pub scene_depth: &'a wgpu::Texture,
    /// The in-scattered radiance of each light (0 ..= [`MAX_LIGHTS`] textures).
    pub inscatter: &'a [&'a wgpu::Texture],
    /// The surface term: the light the medium scatters onto the surfaces (`None`: none).
    pub surfaces: Option<&'a CompositeSurfaces<'a>>,
}

/// The surfaces' normals and albedo, for the light the medium scatters onto them (indirect
/// single scattering): the composite then writes `(Ls + (ρ/π)·E(P))·exp(−σt·ds) + L_sctr`,
/// with `E(P)` the irradiance of [`ISS_WGSL`](crate::ISS_WGSL)'s `volshadow_iss` summed over
/// `lights`, at the surface point `P` reconstructed from the depth buffer, unshadowed.
///
/// A spot light's term counts only the medium inside its cone (`volshadow_iss_spot` of
/// [`ISS_WGSL`](crate::ISS_WGSL), a fixed quadrature over the hemisphere with the cone's
/// wedges in closed form; see `docs/METHOD.md`), evaluated on a lattice of pixels and
/// interpolated where that is safe ([`CompositeNode::set_spot_lattice`]). Its accuracy against
/// the f64 reference is measured by `tests/gpu/iss_spot.rs` (figures in `docs/ACCURACY.md`).
#[derive(Clone, Copy)]
pub struct CompositeSurfaces<'a> {
    /// World-space surface normals in rgb (any length; zero or non-finite: no term), any format
    /// with a float sample type (`Rgba16Float`, `Rgba32Float`, `Rgba8Snorm`, …), usage
    /// `TEXTURE_BINDING`, the size of `scene_color`.
    pub normal: &'a wgpu::Texture,
    /// Diffuse albedo `ρ` in rgb (the surface reflects `ρ/π` of its irradiance per steradian;
    /// zero: no term), any format with a float sample type, usage `TEXTURE_BINDING`, the size
    /// of `scene_color`.
    pub albedo: &'a wgpu::Texture,
    /// The indirect single scattering table, built for this frame's medium.
    pub table: &'a IssTableNode,
    /// Up to [`MAX_LIGHTS`] point or spot lights whose scattered light reaches the surfaces.
    pub lights: &'a [Light],
}

impl std::fmt::Debug for CompositeSurfaces<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CompositeSurfaces")
            .field("normal", self.normal)
            .field("albedo", self.albedo)
            .field("lights", &self.lights)
            .finish_non_exhaustive()
    }
}

/// The most lights one composite adds.
pub const MAX_LIGHTS: usize = 4;

/// Where the composite writes: mip level `mip_level` and array layer `array_layer` of
/// `texture`, viewed in the texture's own format. `From<&wgpu::Texture>` gives mip 0, layer 0.
#[derive(Debug, Clone, Copy)]
pub struct OutputTarget<'a> {
    /// A single-sampled 2D texture with usage `RENDER_ATTACHMENT`, or `STORAGE_BINDING` in a
    /// storage format (see the module docs).
    pub texture: &'a wgpu::Texture,
    /// The mip level written.
    pub mip_level: u32,
    /// The array layer written.
    pub array_layer: u32,
}

impl<'a> OutputTarget<'a> {
    /// Mip 0, layer 0 of `texture`.
    pub fn new(texture: &'a wgpu::Texture) -> Self {
        Self {
            texture,
            mip_level: 0,
            array_layer: 0,
        }
    }

    /// The size of the written mip level (`None` if the level does not exist).
    pub fn size(&self) -> Option<(u32, u32)> {
        (self.mip_level < self.texture.mip_level_count()).then(|| {
            (
                (self.texture.width() >> self.mip_level).max(1),
                (self.texture.height() >> self.mip_level).max(1),
            )
        })
    }
}

impl<'a> From<&'a wgpu::Texture> for OutputTarget<'a> {
    fn from(texture: &'a wgpu::Texture) -> Self {
        Self::new(texture)
    }
}

/// Checks that the composite can write `format`: a colour format with a float sample type
/// (float, unorm or snorm; the shader writes `vec4<f32>`), usable as a render attachment on
/// every device with the device's features.
pub(crate) fn check_output_format(
    device: &wgpu::Device,
    format: wgpu::TextureFormat,
) -> Result<()> {
    let features = format.guaranteed_format_features(device.features());
    let renderable = features
        .allowed_usages
        .contains(wgpu::TextureUsages::RENDER_ATTACHMENT);
    let float = matches!(
        format.sample_type(None, Some(device.features())),
        Some(wgpu::TextureSampleType::Float { .. })
    );
    if format.is_depth_stencil_format() || format.is_compressed() || !renderable || !float {
        return Err(Error::InvalidTexture {
            field: "output_format",
            problem: format!(
                "{format:?} is not a renderable float, unorm or snorm colour format (the \
                 composite writes floating-point radiance)"
            ),
        });
    }
    Ok(())
}

/// Writes the attenuated scene plus in-scattered light into the caller's target.
pub struct CompositeNode {
    device: wgpu::Device,
    format: wgpu::TextureFormat,
    /// The compute pass's pipelines without and with the surface term (`None`: the format is
    /// not a storage format, and the composite always goes through the rasteriser).
    storing: Option<[Storing; 2]>,
    /// The render pipelines, one per format written (the node's format, and its sRGB twin
    /// when an output is in it) and surface term: the cache's, shared.
    pipelines: Pipelines,
    layout: wgpu::BindGroupLayout,
    uniform: UniformBuffer<CompositeUniform>,
    view: UniformBuffer<ViewUniform>,
    placeholder: wgpu::Texture,
    bound: Option<Bound>,
    surf: UniformBuffer<SurfacesUniform>,
    /// The hash of the last output texture found to be on the node's device (0: none), so an
    /// engine's target, the same every frame, is bound once to check it; a swapchain's
    /// textures, new each frame, are checked each frame (about 25 µs of CPU on lavapipe).
    checked_output: AtomicU64,
    /// The phase function, for the spot lights' surface term.
    surf_phase: UniformBuffer<IssPhase>,
    /// Normal, albedo and table textures of the surface term (`None`: no term).
    surfaces: Option<[wgpu::Texture; 3]>,
    /// The surface term's lights, as uploaded (with the lattice spacing set by `prepare`).
    surf_value: SurfacesUniform,
    /// Whether a spot light adds a surface term.
    spots: bool,
    /// The spot term's lattice spacing in pixels (1: every pixel evaluated).
    spot_lattice: u32,
    lattice: Storing,
    lattice_texture: Option<wgpu::Texture>,
}

struct Bound {
    textures: Vec<wgpu::Texture>,
    bind_group: wgpu::BindGroup,
    /// The lattice pass's bind groups (the composite's with a placeholder for the lattice, and
    /// the output) and its size, when the spot term uses a lattice this frame.
    lattice: Option<(wgpu::BindGroup, wgpu::BindGroup, (u32, u32))>,
}

impl CompositeNode {
    /// A composite writing `output_format`, which must be a float, unorm or snorm colour format
    /// usable as a render attachment on every device (e.g. `Rgba16Float`, `Rgba8UnormSrgb`; not
    /// an integer or depth format).
    ///
    /// # Errors
    ///
    /// [`Error::InvalidTexture`] when `output_format` is an integer or depth format or not
    /// renderable.
    pub fn new(
        device: &wgpu::Device,
        cache: &Cache,
        output_format: wgpu::TextureFormat,
    ) -> Result<Self> {
        check_output_format(device, output_format)?;
        let pipelines = cache.get::<Pipelines>();
        let storing = pipelines
            .storing(device, output_format, false)
            .zip(pipelines.storing(device, output_format, true))
            .map(|(plain, surfaces)| [plain, surfaces]);
        // Built now for the node's format; its sRGB twin's on first use.
        pipelines.writing(device, output_format, false);
        pipelines.writing(device, output_format, true);
        Ok(Self {
            device: device.clone(),
            format: output_format,
            storing,
            layout: pipelines.layout.clone(),
            uniform: UniformBuffer::new(device, "volshadow composite"),
            view: UniformBuffer::new(device, "volshadow composite view"),
            placeholder: texture_2d(
                device,
                "volshadow no in-scatter",
                (1, 1, 1),
                wgpu::TextureFormat::Rgba32Float,
                wgpu::TextureUsages::TEXTURE_BINDING,
            ),
            bound: None,
            surf: UniformBuffer::new(device, "volshadow composite surfaces"),
            checked_output: AtomicU64::new(0),
            surf_phase: UniformBuffer::new(device, "volshadow composite phase"),
            surfaces: None,
            surf_value: SurfacesUniform::zeroed(),
            spots: false,
            spot_lattice: Self::DEFAULT_SPOT_LATTICE,
            lattice: pipelines.lattice(device),
            pipelines,
            lattice_texture: None,
        })
    }

    /// The default spacing of the spot term's lattice, in pixels.
    pub const DEFAULT_SPOT_LATTICE: u32 = 4;

    /// The largest spacing [`set_spot_lattice`](Self::set_spot_lattice) takes.
    pub const MAX_SPOT_LATTICE: u32 = 64;

    /// Sets the spacing of the spot lights' surface-term lattice (default
    /// [`DEFAULT_SPOT_LATTICE`](Self::DEFAULT_SPOT_LATTICE)); 1 evaluates it at every pixel.
    ///
    /// A spot light's term is a quadrature over the hemisphere (tens of times a point light's
    /// table lookup), and it is smooth across a surface, so a compute pass evaluates it at
    /// every `stride`-th pixel in each direction, and the composite interpolates between the
    /// four nodes around a pixel where they lie on the pixel's surface (normals within 1.8°,
    /// points within 2.9° of its tangent plane) and the interpolation's error, estimated from
    /// the nodes' second differences, is at most 0.2% per channel; elsewhere (geometric edges,
    /// the surroundings of the apex, a cone's edge on a small frame) it evaluates the term.
    /// Takes effect at the next [`prepare`](Self::prepare).
    ///
    /// # Errors
    ///
    /// [`Error::InvalidSetting`] naming `spot_lattice` outside `1 ..=`
    /// [`MAX_SPOT_LATTICE`](Self::MAX_SPOT_LATTICE); nothing changes then.
    pub fn set_spot_lattice(&mut self, stride: u32) -> Result<()> {
        if !(1..=Self::MAX_SPOT_LATTICE).contains(&stride) {
            return Err(Error::InvalidSetting {
                field: "spot_lattice",
                problem: format!("{stride} pixels, expected 1 ..= {}", Self::MAX_SPOT_LATTICE),
            });
        }
        self.spot_lattice = stride;
        Ok(())
    }

    /// Sets (or, with `None`, removes) the surface term; `prepare` then checks the textures'
    /// sizes against the frame. Nothing changes on an error.
    fn set_surfaces(
        &mut self,
        queue: &wgpu::Queue,
        medium: &Medium,
        surfaces: Option<&CompositeSurfaces<'_>>,
    ) -> Result<()> {
        let Some(s) = surfaces else {
            self.surfaces = None;
            self.spots = false;
            self.surf_value = SurfacesUniform::zeroed();
            self.surf.write(queue, self.surf_value);
            return Ok(());
        };
        check_float_texture("surface_normal", s.normal)?;
        check_float_texture("surface_albedo", s.albedo)?;
        if s.lights.len() > MAX_LIGHTS {
            return Err(Error::InvalidSetting {
                field: "lights",
                problem: format!("{} lights, at most {MAX_LIGHTS}", s.lights.len()),
            });
        }
        self.surfaces = Some([
            s.normal.clone(),
            s.albedo.clone(),
            s.table.texture().clone(),
        ]);
        self.surf_value = SurfacesUniform::new(medium, s.lights);
        self.spots = s.lights.iter().any(|l| l.model().cone().is_some());
        self.surf.write(queue, self.surf_value);
        self.surf_phase.write(queue, IssPhase::new(medium));
        Ok(())
    }

    /// Validates the inputs and uploads what changed. Returns `true` (the composite is
    /// recorded every frame).
    ///
    /// # Errors
    ///
    /// [`Error::InvalidTexture`] naming the input (`scene_color`, `scene_depth`, an in-scatter
    /// texture, `surface_normal`, `surface_albedo`) for a wrong format, usage, layer count or
    /// size, and [`Error::InvalidSetting`] for more in-scatter textures or surface lights than
    /// the composite takes.
    pub fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        inputs: &CompositeInputs<'_>,
    ) -> Result<bool> {
        let (width, height) = check_inputs(inputs)?;
        self.set_surfaces(queue, inputs.medium, inputs.surfaces)?;
        if let Some([normal, albedo, _]) = &self.surfaces {
            check_size("surface_normal", normal, width, height)?;
            check_size("surface_albedo", albedo, width, height)?;
        }
        // The spot term's lattice, when a spot light adds a surface term.
        let stride = self.spot_lattice;
        let lattice = (self.surfaces.is_some() && self.spots && stride > 1)
            .then(|| lattice_size(width, height, stride));
        let textures = self.textures(device, inputs, lattice);
        if self.bound.as_ref().is_none_or(|b| b.textures != textures) {
            self.bound = Some(self.bind(device, textures, lattice));
        }
        let surf = SurfacesUniform {
            lattice: if lattice.is_some() { stride } else { 0 },
            ..self.surf_value
        };
        self.surf.write(queue, surf);
        self.uniform.write(
            queue,
            CompositeUniform {
                sigma_t: inputs.medium.sigma_t().to_array(),
                count: inputs.inscatter.len() as u32,
            },
        );
        self.view
            .write(queue, ViewUniform::new(inputs.camera, width, height));
        Ok(true)
    }

    /// The textures the composite reads this frame, in binding order: the scene's colour and
    /// depth, the in-scatter textures (the placeholder for each one missing), the surfaces'
    /// normal, albedo and ISS table (or placeholders), and the spot lattice of size `lattice`
    /// ((re)created when its size changed; the placeholder without).
    fn textures(
        &mut self,
        device: &wgpu::Device,
        inputs: &CompositeInputs<'_>,
        lattice: Option<(u32, u32)>,
    ) -> Vec<wgpu::Texture> {
        let mut textures = vec![inputs.scene_color.clone(), inputs.scene_depth.clone()];
        textures.extend((0..MAX_LIGHTS).map(|i| {
            inputs
                .inscatter
                .get(i)
                .map_or(&self.placeholder, |t| *t)
                .clone()
        }));
        match &self.surfaces {
            Some(s) => textures.extend(s.iter().cloned()),
            None => textures.extend([0, 1, 2].map(|_| self.placeholder.clone())),
        }
        match lattice {
            Some((w, h)) => {
                if self
                    .lattice_texture
                    .as_ref()
                    .is_none_or(|t| (t.width(), t.height()) != (w, h))
                {
                    self.lattice_texture = Some(texture_2d(
                        device,
                        "volshadow spot lattice",
                        (w, h, 1),
                        LATTICE_FORMAT,
                        wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::TEXTURE_BINDING,
                    ));
                }
                textures.extend(self.lattice_texture.clone());
            }
            None => textures.push(self.placeholder.clone()),
        }
        textures
    }

    /// The bind groups of `textures` (see [`textures`](Self::textures)): the composite's, and
    /// with a `lattice` of that size the lattice pass's and its output's.
    fn bind(
        &self,
        device: &wgpu::Device,
        textures: Vec<wgpu::Texture>,
        lattice: Option<(u32, u32)>,
    ) -> Bound {
        let color = textures[0].create_view(&Default::default());
        let depth = depth_view(&textures[1]);
        // In-scatter 0..4, then surface normal, albedo, ISS table and the spot lattice.
        let views: Vec<wgpu::TextureView> = textures[2..]
            .iter()
            .map(|t| t.create_view(&Default::default()))
            .collect();
        let placeholder = self.placeholder.create_view(&Default::default());
        let view = wgpu::BindingResource::TextureView;
        let group = |label, lattice: &wgpu::TextureView| {
            bind_group(
                device,
                label,
                &self.layout,
                [
                    self.uniform.binding(),
                    self.view.binding(),
                    view(&color),
                    view(&depth),
                    view(&views[0]),
                    view(&views[1]),
                    view(&views[2]),
                    view(&views[3]),
                    self.surf.binding(),
                    view(&views[4]),
                    view(&views[5]),
                    view(&views[6]),
                    self.surf_phase.binding(),
                    wgpu::BindingResource::TextureView(lattice),
                ],
            )
        };
        let composite_group = group("volshadow composite", &views[7]);
        // The lattice pass writes the lattice, so its composite bindings hold the
        // placeholder there (a texture is not written and read in one dispatch).
        let lattice = lattice.map(|size| {
            let output = bind_group(
                device,
                "volshadow spot lattice output",
                &self.lattice.output_layout,
                [view(&views[7])],
            );
            (group("volshadow spot lattice", &placeholder), output, size)
        });
        Bound {
            textures,
            bind_group: composite_group,
            lattice,
        }
    }

    /// Checks that the composite can write `output` (see the module docs for what it must be)
    /// and that `prepare` has succeeded.
    ///
    /// # Errors
    ///
    /// [`Error::InvalidTexture`] naming `output` when its texture has another format or size
    /// (at its mip level) than prepared, lacks `RENDER_ATTACHMENT`, or is one of the
    /// composite's inputs, or when `prepare` has not succeeded.
    ///
    /// [`Error::Validation`] when the texture was made on another device than the node (found
    /// by binding it, in a pass or a bind group never submitted, as wgpu's public API cannot
    /// tell a texture's device).
    pub fn check_output(&self, output: &OutputTarget<'_>) -> Result<()> {
        self.check_output_texture(output)?;
        self.check_output_device(output)
    }

    /// [`check_output`](Self::check_output) less the device: what the texture's own
    /// properties say.
    fn check_output_texture(&self, output: &OutputTarget<'_>) -> Result<()> {
        let problem = |p: String| Error::InvalidTexture {
            field: "output",
            problem: p,
        };
        let Some(bound) = &self.bound else {
            return Err(problem(
                "CompositeNode::prepare has not succeeded yet".into(),
            ));
        };
        let target = output.texture;
        if target.format().remove_srgb_suffix() != self.format.remove_srgb_suffix() {
            return Err(problem(format!(
                "format {:?}, the node was made for {:?}",
                target.format(),
                self.format
            )));
        }
        if !target
            .usage()
            .contains(wgpu::TextureUsages::RENDER_ATTACHMENT)
            && !self.stores_into(target)
        {
            return Err(problem(match self.storing {
                Some(_) => format!(
                    "needs TextureUsages::RENDER_ATTACHMENT, or STORAGE_BINDING in {:?}",
                    self.format
                ),
                None => "needs TextureUsages::RENDER_ATTACHMENT".into(),
            }));
        }
        if target.dimension() != wgpu::TextureDimension::D2 {
            return Err(problem("must be a 2D texture".into()));
        }
        if target.sample_count() != 1 {
            return Err(problem(format!(
                "must be single-sampled, has {} samples",
                target.sample_count()
            )));
        }
        if output.array_layer >= target.depth_or_array_layers() {
            return Err(problem(format!(
                "array layer {} of a texture with {} layers",
                output.array_layer,
                target.depth_or_array_layers()
            )));
        }
        let Some((width, height)) = output.size() else {
            return Err(problem(format!(
                "mip level {} of a texture with {} levels",
                output.mip_level,
                target.mip_level_count()
            )));
        };
        let expected = (bound.textures[0].width(), bound.textures[0].height());
        if (width, height) != expected {
            return Err(problem(format!(
                "mip level {} is {width}x{height}, expected {}x{}",
                output.mip_level, expected.0, expected.1
            )));
        }
        if bound.textures.contains(target) {
            return Err(problem("must not be one of the composite's inputs".into()));
        }
        Ok(())
    }

    /// Refuses a texture made on another device than the node's before anything is recorded
    /// into the caller's encoder: wgpu reports a render pass's attachments only when its
    /// encoder finishes, after `encode` would have returned `Ok`, and that error invalidates
    /// the caller's whole encoder. So the output is bound as `encode` binds it (an empty pass in
    /// an encoder of the node's own, finished and dropped, never submitted; or the compute
    /// path's bind group) inside a validation scope.
    fn check_output_device(&self, output: &OutputTarget<'_>) -> Result<()> {
        let key = {
            let mut hasher = std::hash::DefaultHasher::new();
            output.texture.hash(&mut hasher);
            hasher.finish().max(1)
        };
        if self.checked_output.load(Ordering::Relaxed) == key {
            return Ok(());
        }
        let view = output_view(output);
        crate::gpu::scope::validated(&self.device, "encode (the output's device)", || {
            if let Some(storing) = self
                .storing
                .as_ref()
                .filter(|_| self.stores_into(output.texture))
            {
                drop(bind_group(
                    &self.device,
                    "volshadow output check",
                    &storing[0].output_layout,
                    [wgpu::BindingResource::TextureView(&view)],
                ));
                return Ok(());
            }
            let mut probe = self
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("volshadow output check"),
                });
            drop(crate::gpu::passes::begin_unsubmitted_render(
                &mut probe,
                &wgpu::RenderPassDescriptor {
                    label: Some("volshadow output check"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: &view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Load,
                            store: wgpu::StoreOp::Store,
                        },
                    })],
                    ..Default::default()
                },
            ));
            drop(probe.finish());
            Ok(())
        })?;
        self.checked_output.store(key, Ordering::Relaxed);
        Ok(())
    }

    /// Whether the composite writes `target` with a compute pass (see the module docs).
    pub fn stores_into(&self, target: &wgpu::Texture) -> bool {
        self.storing.is_some()
            && target.format() == self.format
            && target
                .usage()
                .contains(wgpu::TextureUsages::STORAGE_BINDING)
    }

    /// Records the composite into `output` (see the module docs for what it must be).
    ///
    /// # Errors
    ///
    /// Those of [`check_output`](Self::check_output), recording nothing.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        output: &OutputTarget<'_>,
        timer: Option<&mut GpuTimer>,
    ) -> Result<()> {
        self.check_output(output)?;
        self.encode_checked(encoder, output, timer)
    }

    /// [`encode`](Self::encode) into an output [`check_output`](Self::check_output) passed
    /// this frame (the facade checks it before its first pass).
    pub(crate) fn encode_checked(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        output: &OutputTarget<'_>,
        timer: Option<&mut GpuTimer>,
    ) -> Result<()> {
        self.check_output_texture(output)?;
        let Some(bound) = &self.bound else {
            return Err(Error::InvalidTexture {
                field: "output",
                problem: "CompositeNode::prepare has not succeeded yet".into(),
            });
        };
        let target = output.texture;
        let view = output_view(output);
        let surfaces = usize::from(self.surfaces.is_some());
        if let Some(storing) = self
            .storing
            .as_ref()
            .filter(|_| self.stores_into(target))
            .map(|s| &s[surfaces])
        {
            let output_group = bind_group(
                &self.device,
                "volshadow composite output",
                &storing.output_layout,
                [wgpu::BindingResource::TextureView(&view)],
            );
            let (width, height) = output.size().unwrap_or((1, 1));
            let mut pass = crate::gpu::passes::begin_compute(
                encoder,
                &wgpu::ComputePassDescriptor {
                    label: Some("volshadow composite"),
                    timestamp_writes: timer.and_then(|t| t.compute_pass(Pass::Composite)),
                },
            );
            self.dispatch_lattice(&mut pass, bound);
            pass.set_pipeline(&storing.pipeline);
            pass.set_bind_group(0, &bound.bind_group, &[]);
            pass.set_bind_group(1, &output_group, &[]);
            pass.dispatch_workgroups(width.div_ceil(WORKGROUP), height.div_ceil(WORKGROUP), 1);
            return Ok(());
        }
        let mut timer = timer;
        if bound.lattice.is_some() {
            let mut pass = crate::gpu::passes::begin_compute(
                encoder,
                &wgpu::ComputePassDescriptor {
                    label: Some("volshadow spot lattice"),
                    timestamp_writes: timer
                        .as_deref_mut()
                        .and_then(|t| t.compute_pass(Pass::Composite)),
                },
            );
            self.dispatch_lattice(&mut pass, bound);
        }
        let mut pass = crate::gpu::passes::begin_render(
            encoder,
            &wgpu::RenderPassDescriptor {
                label: Some("volshadow composite"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: timer.and_then(|t| t.render_pass(Pass::Composite)),
                occlusion_query_set: None,
                multiview_mask: None,
            },
        );
        // The pipeline for the texture's own format: the view is in it, and a render pass
        // takes only a pipeline built for its attachment's format (the node's format and its
        // sRGB twin are both accepted, see `check_output`).
        let pipeline =
            self.pipelines
                .writing(&self.device, target.format(), self.surfaces.is_some());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &bound.bind_group, &[]);
        pass.draw(0..3, 0..1);
        Ok(())
    }

    /// Records the spot term's lattice pass into `pass` when this frame uses one (the
    /// composite's dispatch that follows reads it; wgpu orders the two).
    fn dispatch_lattice(&self, pass: &mut wgpu::ComputePass<'_>, bound: &Bound) {
        if let Some((group, output, (w, h))) = &bound.lattice {
            pass.set_pipeline(&self.lattice.pipeline);
            pass.set_bind_group(0, group, &[]);
            pass.set_bind_group(1, output, &[]);
            pass.dispatch_workgroups(w.div_ceil(WORKGROUP), h.div_ceil(WORKGROUP), 1);
        }
    }
}

/// The view the composite writes: mip `output.mip_level`, layer `output.array_layer`. A fresh
/// one each frame: keeping one would keep the caller's texture (a swapchain image, say) alive
/// past its frame.
fn output_view(output: &OutputTarget<'_>) -> wgpu::TextureView {
    output.texture.create_view(&wgpu::TextureViewDescriptor {
        label: Some("volshadow composite output"),
        dimension: Some(wgpu::TextureViewDimension::D2),
        base_mip_level: output.mip_level,
        mip_level_count: Some(1),
        base_array_layer: output.array_layer,
        array_layer_count: Some(1),
        ..Default::default()
    })
}

/// Checks the scene's colour and depth and the in-scatter textures (their number, formats and
/// sizes); returns the colour's size.
fn check_inputs(inputs: &CompositeInputs<'_>) -> Result<(u32, u32)> {
    check_float_texture("scene_color", inputs.scene_color)?;
    check_depth_texture("scene_depth", inputs.scene_depth)?;
    let (width, height) = (inputs.scene_color.width(), inputs.scene_color.height());
    check_size("scene_depth", inputs.scene_depth, width, height)?;
    if inputs.inscatter.len() > MAX_LIGHTS {
        return Err(Error::InvalidSetting {
            field: "inscatter",
            problem: format!(
                "{} in-scatter inputs, at most {MAX_LIGHTS}",
                inputs.inscatter.len()
            ),
        });
    }
    for t in inputs.inscatter {
        check_float_texture("inscatter", t)?;
        check_size("inscatter", t, width, height)?;
    }
    Ok((width, height))
}
