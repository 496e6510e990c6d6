//! The indirect single scattering table: the light a homogeneous medium scatters onto a
//! Lambertian surface, as a function of two numbers, built per frame by a compute pass.
//!
//! A surface point `P` with normal `n` lit by a point light at distance `D` (intensity `I0`)
//! receives, besides the attenuated direct light, the airlight of every ray leaving it into its
//! hemisphere (Biri, Arquès and Michelin, "Real Time Rendering of Atmospheric Scattering and
//! Volumetric Shadows", 2006, §III.C, after Sun, Ramamoorthi, Narasimhan and Nayar, "A
//! Practical Analytic Single Scattering Model for Real Time Rendering", 2005), with the medium
//! extending to infinity along each ray and no shadowing:
//!
//! ```text
//! E(P) = ∫_{ω·n > 0} L_ss(P, ω, ∞)·(ω·n) dω = σs·I0·e^{−σt·D}/D · G(σt·D, α)
//! ```
//!
//! per RGB channel, `α` the angle between `n` and the direction to the light; a surface of
//! diffuse reflectivity `kd` (`ρ/π` for an albedo `ρ`) adds `kd·E(P)`. `G` depends only on
//! `τ = σt·D`, `α` and the phase function (see [`crate::reference::surface_inscatter_normalised`]
//! for its derivation). The node tabulates `ln G` by its own quadrature (composite 8-point
//! Gauss–Legendre on geometrically graded segments, in f32) on the axes
//!
//! ```text
//! u = ln(τ/τ₀) / ln(τ₁/τ₀),  τ clamped to [τ₀, τ₁] = ISS_TAU_RANGE = [1e-4, 200],
//! v = 1/2 − asinh(s·cos α) / (2·asinh s),  s = 4 + τ,
//! ```
//!
//! (`v` gathers nodes about `α = π/2`, where `G` falls over a width of about `1/τ`), nodes at
//! `u = i/(N_τ − 1)`, `v = j/(N_α − 1)`. Below `τ₀` `G` is within `O(τ·ln τ)` (≈1e-3
//! relative) of its value there; above `τ₁` the factor `e^{−τ}` is below f32's range.
//!
//! # Accuracy
//!
//! Measured on lavapipe by `tests/gpu/iss_table.rs` against the f64 reference
//! ([`crate::reference::surface_inscatter_normalised`], its own adaptive quadrature) over
//! `τ ∈ [1e-3, 50]`, `α ∈ [0, π]`, isotropic, Henyey–Greenstein 0.8 and Rayleigh phases, where
//! `G` is above 1e-6 of its maximum: the entries are within 4.3e-4 relative (3.1e-4 / 1.6e-4 /
//! 4.3e-4), and the default [`IssTableSize`] (96 × 128) interpolated bilinearly in `ln G` (as
//! [`ISS_WGSL`](crate::ISS_WGSL) does) is within 6.4e-4 at its cell centres (5.8e-4 / 6.4e-4 /
//! 5.3e-4). The interpolation error is set mostly by the `τ` axis: 48 × 192 gives 2.5e-3.
//!
//! # Use
//!
//! [`ISS_WGSL`](crate::ISS_WGSL) is a self-contained WGSL module whose `volshadow_iss` function
//! a caller's surface shader calls with [`IssTableNode::view`]; the composite adds the term
//! itself when given normals and albedo.
//!
//! # Output
//!
//! [`IssTableNode::texture`]: `Rgba32Float`, `N_τ × N_α` (width × height), usages
//! `STORAGE_BINDING | TEXTURE_BINDING | COPY_SRC`; rgb = `ln G` per channel, a = 0. It is read
//! with `textureLoad` and interpolated in the shader: f32 textures are not filterable on every
//! device, and hardware filtering's 8-bit weights would cost the table its accuracy.

use crate::error::{Error, Result};
use crate::gpu::pipeline::{bind_group, compute_pipeline, dispatch, layout, module, Binding};
use crate::gpu::wgsl::wgsl_file;
use crate::gpu::ShaderPrecision;
use crate::gpu::{texture_2d, GpuTimer, UniformBuffer};
use crate::nodes::cache::CachedPipelines;
use crate::nodes::groups::uniforms::AirlightUniform;
use crate::nodes::Cache;
use crate::nodes::{Encode, Node};
use crate::pass::Pass;
use crate::scene::Medium;

/// The phase function as [`ISS_WGSL`](crate::ISS_WGSL)'s `VolshadowIssPhase` reads it (the
/// spot form `volshadow_iss_spot` takes it; the point form's table holds the phase already):
/// 96 bytes, to upload as a storage or uniform buffer with [`IssPhase::as_bytes`].
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct IssPhase {
    /// Per-channel (rgb, a unused) weights of the isotropic, Rayleigh, Henyey–Greenstein,
    /// Mie hazy and Mie murky lobes, summing to 1 per channel.
    pub weights: [[f32; 4]; 5],
    /// The Henyey–Greenstein lobe's `g` (then three pads).
    pub hg_g: [f32; 4],
}

impl IssPhase {
    /// The phase function of `medium`.
    pub fn new(medium: &Medium) -> Self {
        let u = AirlightUniform::phase_only(medium, 0, 0);
        Self {
            weights: [u.w_iso, u.w_rayleigh, u.w_hg, u.w_hazy, u.w_murky],
            hg_g: [u.hg_g, 0.0, 0.0, 0.0],
        }
    }

    /// The bytes to upload.
    pub fn as_bytes(&self) -> &[u8] {
        bytemuck::bytes_of(self)
    }
}

/// The range of optical distance `σt·D` the table covers; outside it the lookup clamps.
pub const ISS_TAU_RANGE: [f32; 2] = [1e-4, 200.0];

/// Size of the indirect single scattering table (default 96 × 128: within 6.4e-4 of the
/// reference between its entries; see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct IssTableSize {
    /// Nodes along `ln τ` (the texture's width). At least [`IssTableSize::MIN`].
    pub tau: u32,
    /// Nodes along the warped angle axis (the texture's height). At least [`IssTableSize::MIN`].
    pub alpha: u32,
}

impl Default for IssTableSize {
    fn default() -> Self {
        Self {
            tau: 96,
            alpha: 128,
        }
    }
}

impl IssTableSize {
    /// Fewest nodes along either axis.
    pub const MIN: u32 = 4;
    /// Most nodes along either axis (the core limit for 2D textures).
    pub const MAX: u32 = 8192;

    fn validate(&self) -> Result<()> {
        let ok = |n: u32| (Self::MIN..=Self::MAX).contains(&n);
        if ok(self.tau) && ok(self.alpha) {
            Ok(())
        } else {
            Err(Error::InvalidSize {
                field: "iss table size",
                width: self.tau,
                height: self.alpha,
                min: Self::MIN,
                max: Self::MAX,
            })
        }
    }
}

/// The table's binding table: `@binding(i)` of `shaders/passes/iss_table.wgsl` is entry `i`.
const BINDINGS: [Binding; 2] = [
    Binding::Params,                                    // air
    Binding::Storage(wgpu::TextureFormat::Rgba32Float), // table_out
];

/// The table's layout and pipeline, held by the [`Cache`].
#[derive(Clone)]
pub(crate) struct Pipelines {
    layout: wgpu::BindGroupLayout,
    build: wgpu::ComputePipeline,
}

impl CachedPipelines for Pipelines {
    fn build(device: &wgpu::Device, precision: ShaderPrecision) -> Self {
        Self::new(device, precision)
    }
}

impl Pipelines {
    pub(crate) fn new(device: &wgpu::Device, precision: ShaderPrecision) -> Self {
        let label = "volshadow ISS table";
        let layout = layout(device, label, wgpu::ShaderStages::COMPUTE, &BINDINGS);
        let module = module(device, &wgsl_file!("iss_table.wgsl"), precision);
        let build = compute_pipeline(device, label, &[&layout], &module, "build", &[]);
        Self { layout, build }
    }
}

/// Builds the indirect single scattering table. `prepare` decides whether it needs rebuilding
/// (only when the phase function or the size changed: the table depends on nothing else);
/// `encode` records the compute pass only then.
pub struct IssTableNode {
    size: IssTableSize,
    texture: wgpu::Texture,
    view: wgpu::TextureView,
    uniform: UniformBuffer<AirlightUniform>,
    bind_group: wgpu::BindGroup,
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
    pending: bool,
}

impl IssTableNode {
    /// Creates the table texture.
    ///
    /// # Errors
    ///
    /// [`Error::InvalidSize`] naming `iss table size` for a size out of range.
    pub fn new(device: &wgpu::Device, cache: &Cache, size: IssTableSize) -> Result<Self> {
        size.validate()?;
        let uniform = UniformBuffer::new(device, "volshadow ISS table uniform");
        let (texture, view, bind_group) =
            Self::resources(device, &cache.get::<Pipelines>().layout, &uniform, size);
        Ok(Self {
            size,
            texture,
            view,
            uniform,
            bind_group,
            layout: cache.get::<Pipelines>().layout.clone(),
            pipeline: cache.get::<Pipelines>().build.clone(),
            pending: false,
        })
    }

    fn resources(
        device: &wgpu::Device,
        layout: &wgpu::BindGroupLayout,
        uniform: &UniformBuffer<AirlightUniform>,
        size: IssTableSize,
    ) -> (wgpu::Texture, wgpu::TextureView, wgpu::BindGroup) {
        let texture = texture_2d(
            device,
            "volshadow ISS table",
            (size.tau, size.alpha, 1),
            wgpu::TextureFormat::Rgba32Float,
            wgpu::TextureUsages::STORAGE_BINDING
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
        );
        let view = texture.create_view(&Default::default());
        let bind_group = bind_group(
            device,
            "volshadow ISS table",
            layout,
            [uniform.binding(), wgpu::BindingResource::TextureView(&view)],
        );
        (texture, view, bind_group)
    }

    /// Changes the size (validated); the texture is recreated only when it differs, and the
    /// next `prepare` then rebuilds the table.
    ///
    /// # Errors
    ///
    /// [`Error::InvalidSize`] naming `iss table size` for a size out of range.
    pub fn set_size(&mut self, device: &wgpu::Device, size: IssTableSize) -> Result<()> {
        size.validate()?;
        if size != self.size {
            let (texture, view, bind_group) =
                Self::resources(device, &self.layout, &self.uniform, size);
            (self.texture, self.view, self.bind_group, self.size) =
                (texture, view, bind_group, size);
        }
        Ok(())
    }

    /// The table texture (see the module docs for its layout).
    pub fn texture(&self) -> &wgpu::Texture {
        &self.texture
    }

    /// A view of the whole table, to bind as the `texture_2d<f32>` (non-filterable float,
    /// read with `textureLoad`) that [`ISS_WGSL`](crate::ISS_WGSL)'s functions take.
    pub fn view(&self) -> &wgpu::TextureView {
        &self.view
    }

    /// The table's size.
    pub fn size(&self) -> IssTableSize {
        self.size
    }
}

impl Node for IssTableNode {
    type Inputs<'a> = crate::scene::Medium;

    /// Uploads the parameters for a frame (the medium's phase function). Returns whether the
    /// next [`encode`](Self::encode) rebuilds the table: they changed now (or the size did), or
    /// they changed at an earlier `prepare` that no `encode` followed.
    fn prepare(
        &mut self,
        _device: &wgpu::Device,
        queue: &wgpu::Queue,
        medium: &Medium,
    ) -> Result<bool> {
        let key = AirlightUniform::phase_only(medium, self.size.tau, self.size.alpha);
        self.pending |= self.uniform.write(queue, key);
        Ok(self.pending)
    }
}

impl Encode for IssTableNode {
    /// Records the table build into `encoder` if [`prepare`](Self::prepare) found a change since
    /// the last build; otherwise records nothing.
    fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        timer: Option<&mut GpuTimer>,
    ) -> Result<()> {
        if !std::mem::take(&mut self.pending) {
            return Ok(());
        }
        let groups = (self.size.tau.div_ceil(8), self.size.alpha.div_ceil(8), 1);
        let (pipeline, bind_group) = (&self.pipeline, &self.bind_group);
        dispatch(
            encoder,
            timer,
            Pass::IssTable,
            "volshadow ISS table",
            &[(pipeline, &[bind_group], groups)],
        );
        Ok(())
    }
}
