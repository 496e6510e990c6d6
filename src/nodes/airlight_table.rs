//! The per-frame airlight table F′, built by a compute pass of two dispatches: each cell's
//! integral (8-point Gauss–Legendre), one invocation a cell, into an intermediate
//! `Rgba32Float` texture of `along_ray × across_rays`; then each row's compensated sums of its
//! cells, from either end, one invocation a row. The cells are the work (every integrand
//! evaluation), so they spread over the GPU; the sums are additions.
//!
//! Within a frame D = |P − E|, σt and the phase are fixed, so the bounded integral of the
//! stable form of Sun et al.'s airlight (see [`crate::reference`]) is a function of two numbers: the ray's angle γ to the light and the
//! normalised scattering angle s = (2ξ − γ)/(π − γ) of the end point. The table stores, per
//! RGB channel,
//!
//! ```text
//! T(γ_i, s_j) = ∫₀^{s_j} p(cos 2ξ) · exp(−σt · (d + x − D)) ds,   γ_i = π (i / (rows − 1))²,
//!                                                                   s_j = j / (n − 1)
//! ```
//!
//! which is bounded by the phase function's maximum for every σt·D (no `exp(−σt D cos γ)` that
//! overflows with the light behind the eye). The march multiplies by the singular prefactor
//! `σs · exp(−σt D) · (π − γ) / (D sin γ)` per pixel, and completes each lookup with the
//! partial cell integrated exactly at the ray's own γ, so only the γ direction is interpolated.
//!
//! # Accuracy
//!
//! The default [`TableSize`] (256 × 256) is checked by `tests/airlight_table.rs` against the
//! f64 reference over σt·D ∈ {1e-4 … 100}, γ ∈ [1e-3, π − 1e-3], light in front of and behind
//! the eye, isotropic, HG ±0.9 and Rayleigh phases: the largest relative error of an entry
//! (heads above 1e-6 of their row's maximum; tails where the reference's own difference keeps
//! 1e-9 of the row's total) is below 1e-3 (see the README for the figure measured on
//! lavapipe).
//!
//! # Output
//!
//! [`AirlightTableNode::texture`]: `Rgba32Float`, `2·along_ray × across_rays`, usages
//! `STORAGE_BINDING | TEXTURE_BINDING | COPY_SRC`; rgb = T, a = 0. Row i is γ_i; column j < n
//! (n = `along_ray`) is `T(γ_i, s_j)`, column `n + j` the tail `∫_{s_j}^1`, summed from `s = 1`.
//! An interval of `s` beyond the integrand's peak (an optically thick medium, a spot's cone
//! or a lit piece far from the light) is then a difference of two small tails, not of two
//! heads that hold the peak: a spot light at σt·D = 81 whose cone left the peak outside was
//! off by up to 106% from heads alone (see `docs/METHOD.md`).

use crate::error::{Error, Result};
use crate::gpu::cache::{bind_group, compute_pipeline, dispatch, layout, module, Binding};
use crate::gpu::uniforms::AirlightUniform;
use crate::gpu::ShaderPrecision;
use crate::gpu::{texture_2d, Cache, GpuTimer, UniformBuffer};
use crate::plan::Pass;
use crate::scene::{Light, Medium};

/// Size of the F′ table: entries along each ray (s) and rows across rays (γ).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TableSize {
    /// Entries along the ray, in normalised scattering angle s ∈ [0, 1]. At least
    /// [`TableSize::MIN_ALONG_RAY`].
    pub along_ray: u32,
    /// Rows across rays, in γ = π t², t ∈ [0, 1]. At least [`TableSize::MIN_ACROSS_RAYS`].
    pub across_rays: u32,
}

impl Default for TableSize {
    fn default() -> Self {
        Self {
            along_ray: 256,
            across_rays: 256,
        }
    }
}

impl TableSize {
    /// Largest dimension accepted: half the core limit for 2D textures (8192), as a row holds
    /// its entries twice (see the module docs).
    pub const MAX: u32 = 4096;
    /// Fewest entries along the ray accepted. Set by measurement (`tests/airlight_table.rs`):
    /// with 8 entries (and 256 rows) the p95 relative error of a whole unshadowed frame against
    /// the f64 reference stays within 0.2% for isotropic, HG 0.9 and HG −0.5 media, under a
    /// third of the tightest configuration the error target offers; with 4 it reaches 0.4%,
    /// with 2 57%.
    pub const MIN_ALONG_RAY: u32 = 8;
    /// Fewest rows across rays accepted, by the same measurement: 128 rows keep the p95 within
    /// 0.2%; 64 give 0.6% (HG 0.9), 16 give 11%, 2 give 875%.
    pub const MIN_ACROSS_RAYS: u32 = 128;

    fn validate(&self) -> Result<()> {
        let ok = |n: u32, min: u32| (min..=Self::MAX).contains(&n);
        if ok(self.along_ray, Self::MIN_ALONG_RAY) && ok(self.across_rays, Self::MIN_ACROSS_RAYS) {
            Ok(())
        } else {
            Err(Error::InvalidSize {
                field: "airlight table size",
                width: self.along_ray,
                height: self.across_rays,
                min: if ok(self.along_ray, Self::MIN_ALONG_RAY) {
                    Self::MIN_ACROSS_RAYS
                } else {
                    Self::MIN_ALONG_RAY
                },
                max: Self::MAX,
            })
        }
    }
}

/// The first pass's binding table: `@binding(i)` of `shaders/airlight_table.wgsl` is entry `i`.
const CELL_BINDINGS: [Binding; 2] = [
    Binding::Params,                                    // air
    Binding::Storage(wgpu::TextureFormat::Rgba32Float), // cells_out
];

/// The second pass's: `@binding(i)` of `shaders/airlight_table_sum.wgsl` is entry `i`.
const SUM_BINDINGS: [Binding; 3] = [
    Binding::Params,                                    // air
    Binding::Texture,                                   // cells_in
    Binding::Storage(wgpu::TextureFormat::Rgba32Float), // table_out
];

/// The table's layouts and pipelines, held by the [`Cache`]: the cells' integrals, one
/// invocation each, then their sums along each row.
#[derive(Clone)]
pub(crate) struct Pipelines {
    cell_layout: wgpu::BindGroupLayout,
    sum_layout: wgpu::BindGroupLayout,
    cells: wgpu::ComputePipeline,
    sum: wgpu::ComputePipeline,
}

impl Pipelines {
    pub(crate) fn new(device: &wgpu::Device, precision: ShaderPrecision) -> Self {
        let label = "volshadow F' table cells";
        let cell_layout = layout(device, label, wgpu::ShaderStages::COMPUTE, &CELL_BINDINGS);
        let source = include_str!("../../shaders/airlight_table.wgsl");
        let cell_module = module(device, "volshadow airlight_table.wgsl", source, precision);
        let cells = compute_pipeline(device, label, &cell_layout, &cell_module, "cells", &[]);
        let label = "volshadow F' table sums";
        let sum_layout = layout(device, label, wgpu::ShaderStages::COMPUTE, &SUM_BINDINGS);
        let source = include_str!("../../shaders/airlight_table_sum.wgsl");
        let sum_module = module(
            device,
            "volshadow airlight_table_sum.wgsl",
            source,
            precision,
        );
        let sum = compute_pipeline(device, label, &sum_layout, &sum_module, "sum", &[]);
        Self {
            cell_layout,
            sum_layout,
            cells,
            sum,
        }
    }
}

/// What the table is built for: it depends on the light only through the eye–light distance.
#[derive(Clone, Copy)]
pub struct TableInputs<'a> {
    /// The eye.
    pub eye: glam::Vec3,
    /// The light.
    pub light: &'a Light,
    /// The medium.
    pub medium: &'a Medium,
}

/// Builds the F′ table. `prepare` decides whether the table needs rebuilding (only when D, σt,
/// the phase or the size changed); `encode` records the compute pass only then.
pub struct AirlightTableNode {
    size: TableSize,
    texture: wgpu::Texture,
    uniform: UniformBuffer<AirlightUniform>,
    cell_group: wgpu::BindGroup,
    sum_group: wgpu::BindGroup,
    pipelines: Pipelines,
    pending: bool,
}

impl AirlightTableNode {
    /// Creates the table texture.
    ///
    /// # Errors
    ///
    /// [`Error::InvalidSize`] for a table size out of range.
    pub fn new(device: &wgpu::Device, cache: &Cache, size: TableSize) -> Result<Self> {
        size.validate()?;
        let texture = texture_2d(
            device,
            "volshadow F' table",
            (2 * size.along_ray, size.across_rays, 1),
            wgpu::TextureFormat::Rgba32Float,
            wgpu::TextureUsages::STORAGE_BINDING
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
        );
        // Each cell's integral (column j: the cell [s_{j−1}, s_j]; column 0 unused), between
        // the two passes.
        let cells = texture_2d(
            device,
            "volshadow F' table cells",
            (size.along_ray, size.across_rays, 1),
            wgpu::TextureFormat::Rgba32Float,
            wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::TEXTURE_BINDING,
        );
        let uniform = UniformBuffer::new(device, "volshadow F' table uniform");
        let view = texture.create_view(&Default::default());
        let cells_view = cells.create_view(&Default::default());
        let cell_group = bind_group(
            device,
            "volshadow F' table cells",
            &cache.table.cell_layout,
            [
                uniform.binding(),
                wgpu::BindingResource::TextureView(&cells_view),
            ],
        );
        let sum_group = bind_group(
            device,
            "volshadow F' table sums",
            &cache.table.sum_layout,
            [
                uniform.binding(),
                wgpu::BindingResource::TextureView(&cells_view),
                wgpu::BindingResource::TextureView(&view),
            ],
        );
        Ok(Self {
            size,
            texture,
            uniform,
            cell_group,
            sum_group,
            pipelines: cache.table.clone(),
            pending: false,
        })
    }

    /// Uploads the parameters for a frame. Returns whether the next [`encode`](Self::encode)
    /// rebuilds the table: it changed now, or it changed at an earlier `prepare` that no
    /// `encode` followed.
    pub fn prepare(
        &mut self,
        _device: &wgpu::Device,
        queue: &wgpu::Queue,
        inputs: &TableInputs<'_>,
    ) -> Result<bool> {
        // The table depends on the light only through D = |P − E| (the key drops the rest).
        let key = AirlightUniform::new(inputs.eye, inputs.light, inputs.medium, 0.0, self.size)
            .table_key();
        self.pending |= self.uniform.write(queue, key);
        Ok(self.pending)
    }

    /// Records the table build into `encoder` if [`prepare`](Self::prepare) found a change since
    /// the last build; otherwise records nothing.
    pub fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        timer: Option<&mut GpuTimer>,
    ) -> Result<()> {
        if !std::mem::take(&mut self.pending) {
            return Ok(());
        }
        let (n, rows) = (self.size.along_ray, self.size.across_rays);
        let p = &self.pipelines;
        dispatch(
            encoder,
            timer,
            Pass::AirlightTable,
            "volshadow F' table",
            &[
                (&p.cells, &self.cell_group, ((n - 1).div_ceil(64), rows, 1)),
                (&p.sum, &self.sum_group, (rows.div_ceil(64), 1, 1)),
            ],
        );
        Ok(())
    }

    /// The table texture (see the module docs for its layout).
    pub fn texture(&self) -> &wgpu::Texture {
        &self.texture
    }

    /// The table's size.
    pub fn size(&self) -> TableSize {
        self.size
    }
}
