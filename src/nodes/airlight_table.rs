//! The per-frame airlight table F′, built by a compute pass of two dispatches. First each
//! cell's integral, one invocation a cell, by 2-, 3- or 8-point Gauss–Legendre (the fewest
//! points the integrand's smoothness on the cell allows; the last cell of a row, which ends
//! where the attenuation drops to zero, in 12 geometric pieces), into an intermediate storage
//! buffer. Then each row's sums of its cells from either end: on a GPU one workgroup a row, a
//! scan across it; on a CPU adapter (lavapipe) one invocation a row, in runs of 16, as the
//! scan's barriers there cost more than the sums. See `docs/METHOD.md` §2 for the rules and
//! the measured times.
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
//! The default [`TableSize`] (256 × 256) is checked by `tests/gpu/airlight_table.rs` against the
//! f64 reference over σt·D ∈ {1e-4 … 100}, γ ∈ [1e-3, π − 1e-3], light in front of and behind
//! the eye, isotropic, HG ±0.9 and Rayleigh phases: the largest relative error of an entry
//! (heads above 1e-6 of their row's maximum; tails where the reference's own difference keeps
//! 1e-9 of the row's total) is below 1e-3 (the current figure is in `docs/ACCURACY.md`).
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
use crate::gpu::pipeline::{bind_group, compute_pipeline, dispatch, layout, module, Binding};
use crate::gpu::wgsl::wgsl_file;
use crate::gpu::ShaderPrecision;
use crate::gpu::{check_buffer_size, texture_2d, GpuTimer, UniformBuffer};
use crate::nodes::cache::CachedPipelines;
use crate::nodes::groups::uniforms::AirlightUniform;
use crate::nodes::Cache;
use crate::nodes::{Encode, Node};
use crate::pass::Pass;
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

impl TableSize {
    /// (entries along the ray, rows across rays): the airlight uniform's table fields.
    pub(crate) fn dims(self) -> (u32, u32) {
        (self.along_ray, self.across_rays)
    }
}

impl Default for TableSize {
    fn default() -> Self {
        Self::DEFAULT
    }
}

impl TableSize {
    /// The default: 256 × 256.
    pub const DEFAULT: TableSize = TableSize {
        along_ray: 256,
        across_rays: 256,
    };
    /// Largest dimension accepted: half the core limit for 2D textures (8192), as a row holds
    /// its entries twice (see the module docs).
    pub const MAX: u32 = 4096;
    /// Fewest entries along the ray accepted. Set by measurement (`tests/gpu/airlight_table.rs`):
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

/// The pieces of each row's last cell, which ends where the attenuation drops to zero: piece k
/// spans `1 − s ∈ [ds·4^−(k+1), ds·4^−k]` (the last one down to 0), each its own invocation.
/// The last piece holds at most 4^−11 = 2.4e-7 of the cell wherever the integrand is bounded
/// across it, so however poorly its 8 points see an attenuation that falls to zero inside it,
/// the cell keeps f32 precision.
const TAIL_PIECES: u32 = 12;

/// The first pass's binding table: `@binding(i)` of `shaders/passes/airlight_table.wgsl` is entry
/// `i`.
const CELL_BINDINGS: [Binding; 2] = [
    Binding::Params,    // air
    Binding::ReadWrite, // cells_out
];

/// The second pass's: `@binding(i)` of `shaders/passes/airlight_table_sum.wgsl` is entry `i`.
const SUM_BINDINGS: [Binding; 3] = [
    Binding::Params,                                    // air
    Binding::Params,                                    // cells_in (read-only storage)
    Binding::Storage(wgpu::TextureFormat::Rgba32Float), // table_out
];

/// How the second pass sums each row: `sum_scan` or `sum_serial` of
/// `shaders/passes/airlight_table_sum.wgsl` (the same sums).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum RowSum {
    /// One workgroup of 256 a row, its runs' totals scanned across it (a GPU).
    Scan,
    /// One invocation a row (a CPU adapter, where a workgroup barrier switches between
    /// invocations: the scan took 8 times the serial sum's time on lavapipe).
    Serial,
}

impl RowSum {
    /// The row sum for `device`'s kind of adapter.
    pub(crate) fn for_device(device: &wgpu::Device) -> Self {
        match device.adapter_info().device_type {
            wgpu::DeviceType::Cpu => RowSum::Serial,
            _ => RowSum::Scan,
        }
    }
}

/// The table's layouts and pipelines, held by the [`Cache`]: the cells' integrals, one
/// invocation each, then their sums along each row.
#[derive(Clone)]
pub(crate) struct Pipelines {
    cell_layout: wgpu::BindGroupLayout,
    sum_layout: wgpu::BindGroupLayout,
    cells: wgpu::ComputePipeline,
    sum: wgpu::ComputePipeline,
    row_sum: RowSum,
}

impl CachedPipelines for Pipelines {
    fn build(device: &wgpu::Device, precision: ShaderPrecision) -> Self {
        Self::new(device, precision)
    }
}

impl Pipelines {
    pub(crate) fn new(device: &wgpu::Device, precision: ShaderPrecision) -> Self {
        Self::with_row_sum(device, precision, RowSum::for_device(device))
    }

    pub(crate) fn with_row_sum(
        device: &wgpu::Device,
        precision: ShaderPrecision,
        row_sum: RowSum,
    ) -> Self {
        let label = "volshadow F' table cells";
        let cell_layout = layout(device, label, wgpu::ShaderStages::COMPUTE, &CELL_BINDINGS);
        let cell_module = module(device, &wgsl_file!("airlight_table.wgsl"), precision);
        let constants = [("TAIL_PIECES", f64::from(TAIL_PIECES))];
        let cells = compute_pipeline(
            device,
            label,
            &[&cell_layout],
            &cell_module,
            "cells",
            &constants,
        );
        let label = "volshadow F' table sums";
        let sum_layout = layout(device, label, wgpu::ShaderStages::COMPUTE, &SUM_BINDINGS);
        let sum_module = module(device, &wgsl_file!("airlight_table_sum.wgsl"), precision);
        let entry = match row_sum {
            RowSum::Scan => "sum_scan",
            RowSum::Serial => "sum_serial",
        };
        let sum = compute_pipeline(
            device,
            label,
            &[&sum_layout],
            &sum_module,
            entry,
            &constants,
        );
        Self {
            cell_layout,
            sum_layout,
            cells,
            sum,
            row_sum,
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
    /// [`Error::InvalidSize`] for a table size out of range;
    /// [`Error::DeviceLimitExceeded`] when the cells of a large table (16 bytes each,
    /// `(along_ray + 11) × across_rays` of them) do not fit one storage buffer binding on
    /// `device` (128 MiB by default, which holds 4096 × 2042).
    pub fn new(device: &wgpu::Device, cache: &Cache, size: TableSize) -> Result<Self> {
        Self::with_pipelines(device, cache.get::<Pipelines>(), size)
    }

    pub(crate) fn with_pipelines(
        device: &wgpu::Device,
        pipelines: Pipelines,
        size: TableSize,
    ) -> Result<Self> {
        size.validate()?;
        // Each cell's integral, row by row, between the two passes: entry j < n − 1 of a row
        // is the cell [s_{j−1}, s_j] (entry 0 unused), entries n − 1 onwards the last cell's
        // pieces.
        let cell_bytes = u64::from(size.along_ray + TAIL_PIECES - 1)
            * u64::from(size.across_rays)
            * std::mem::size_of::<[f32; 4]>() as u64;
        check_buffer_size(device, "airlight table cells", cell_bytes)?;
        let cells = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("volshadow F' table cells"),
            size: cell_bytes,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let texture = texture_2d(
            device,
            "volshadow F' table",
            (2 * size.along_ray, size.across_rays, 1),
            wgpu::TextureFormat::Rgba32Float,
            wgpu::TextureUsages::STORAGE_BINDING
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
        );
        let uniform = UniformBuffer::new(device, "volshadow F' table uniform");
        let view = texture.create_view(&Default::default());
        let cell_group = bind_group(
            device,
            "volshadow F' table cells",
            &pipelines.cell_layout,
            [uniform.binding(), cells.as_entire_binding()],
        );
        let sum_group = bind_group(
            device,
            "volshadow F' table sums",
            &pipelines.sum_layout,
            [
                uniform.binding(),
                cells.as_entire_binding(),
                wgpu::BindingResource::TextureView(&view),
            ],
        );
        Ok(Self {
            size,
            texture,
            uniform,
            cell_group,
            sum_group,
            pipelines,
            pending: false,
        })
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

impl Node for AirlightTableNode {
    type Inputs<'a> = TableInputs<'a>;

    /// Uploads the parameters for a frame. Returns whether the next [`encode`](Self::encode)
    /// rebuilds the table: it changed now, or it changed at an earlier `prepare` that no
    /// `encode` followed.
    fn prepare(
        &mut self,
        _device: &wgpu::Device,
        queue: &wgpu::Queue,
        inputs: &TableInputs<'_>,
    ) -> Result<bool> {
        // The table depends on the light only through D = |P − E| (the key drops the rest).
        let key = AirlightUniform::new(
            inputs.eye,
            inputs.light,
            inputs.medium,
            0.0,
            self.size.dims(),
        )
        .table_key();
        self.pending |= self.uniform.write(queue, key);
        Ok(self.pending)
    }
}

impl Encode for AirlightTableNode {
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
        let (n, rows) = (self.size.along_ray, self.size.across_rays);
        let p = &self.pipelines;
        let sum_groups = match p.row_sum {
            RowSum::Scan => (rows, 1, 1),
            RowSum::Serial => (rows.div_ceil(64), 1, 1),
        };
        dispatch(
            encoder,
            timer,
            Pass::AirlightTable,
            "volshadow F' table",
            &[
                (
                    &p.cells,
                    &[&self.cell_group],
                    ((n + TAIL_PIECES - 2).div_ceil(64), rows, 1),
                ),
                (&p.sum, &[&self.sum_group], sum_groups),
            ],
        );
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::{AirlightTableNode, Pipelines, RowSum, TableInputs, TableSize};
    use crate::nodes::{Encode, Node};
    use crate::{HeadlessGpu, Light, Medium, PhaseFunction, PointLight, ShaderPrecision};
    use glam::Vec3;

    fn table(
        gpu: &HeadlessGpu,
        row_sum: RowSum,
        size: TableSize,
        medium: &Medium,
    ) -> Vec<[f32; 4]> {
        let pipelines = Pipelines::with_row_sum(&gpu.device, ShaderPrecision::Native, row_sum);
        let mut node = AirlightTableNode::with_pipelines(&gpu.device, pipelines, size).unwrap();
        let eye = Vec3::new(0.5, 1.0, -2.0);
        let light: Light = PointLight::new(eye + Vec3::new(0.0, 0.0, 3.0), Vec3::ONE)
            .unwrap()
            .into();
        let inputs = TableInputs {
            eye,
            light: &light,
            medium,
        };
        assert!(node.prepare(&gpu.device, &gpu.queue, &inputs).unwrap());
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        node.encode(&mut encoder, None).unwrap();
        gpu.submit_and_wait(encoder).unwrap();
        gpu.read_rgba32f(node.texture()).unwrap()
    }

    /// The row sums a GPU gets (a scan across a workgroup) and a CPU adapter gets (one
    /// invocation a row, in runs of 16) fill the same table, at lengths that give each
    /// invocation of the scan one cell (256), none for most of the workgroup (8), and runs of
    /// four with a shorter last run (1000), in thin and thick media. Every cell is positive,
    /// so each sum's relative error is at most its depth times 2^-24: the two may differ by
    /// the sum of their depths, (⌈(n − 1)/16⌉ + 16) + (⌈(n − 1)/256⌉ + 8) additions, 2^-24
    /// each (2.5e-6 at 256 entries). The default's entries are checked against the f64
    /// reference by `tests/gpu/airlight_table.rs`; this ties the other to it. A scan that shifted
    /// a run by one cell, or dropped the last cell, is off by a whole cell (~1/n).
    #[test]
    fn scan_and_serial_row_sums_agree() {
        let gpu = match HeadlessGpu::new() {
            Ok(gpu) => gpu,
            Err(e) => panic!("GPU tests need a wgpu adapter (lavapipe works): {e}"),
        };
        for along_ray in [256, 8, 1000] {
            let size = TableSize {
                along_ray,
                across_rays: 128,
            };
            for optical_depth in [1e-3_f32, 1.0, 60.0] {
                let sigma_t = optical_depth / 3.0;
                let medium = Medium::new(
                    Vec3::splat(0.6 * sigma_t),
                    Vec3::splat(0.4 * sigma_t),
                    PhaseFunction::HenyeyGreenstein { g: 0.7 },
                )
                .unwrap();
                let scan = table(&gpu, RowSum::Scan, size, &medium);
                let serial = table(&gpu, RowSum::Serial, size, &medium);
                let mut worst: f32 = 0.0;
                for (a, b) in scan.iter().zip(&serial) {
                    for c in 0..3 {
                        let scale = a[c].abs().max(b[c].abs());
                        if scale > 1e-30 {
                            worst = worst.max((a[c] - b[c]).abs() / scale);
                        }
                    }
                }
                let nonzero = serial.iter().filter(|t| t[0] > 0.0).count();
                println!(
                    "{along_ray} × 128, σt·D = {optical_depth}: scan vs serial, largest relative \
                     difference {worst:.2e} ({nonzero} non-zero entries)"
                );
                assert!(nonzero > serial.len() / 2, "the table is mostly empty");
                let depths = (along_ray - 1).div_ceil(16) + 16 + (along_ray - 1).div_ceil(256) + 8;
                let bound = depths as f32 * f32::EPSILON / 2.0;
                assert!(
                    worst <= bound,
                    "{along_ray}, σt·D = {optical_depth}: {worst:.2e} > {bound:.2e}"
                );
            }
        }
    }
}
