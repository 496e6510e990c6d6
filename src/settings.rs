//! [`Settings`]: what is fixed for a [`VolumetricShadows`](crate::VolumetricShadows), the
//! presets built from the nodes' defaults, and the error tables that
//! [`Settings::for_error_target`] picks from.

use crate::error::{Error, Result};
use crate::nodes::{
    Cache, CrossingsBuild, LightKind, MarchMethod, MarchSettings, Scale, ShadowMapSettings,
    SoftShadowSize, TableSize, UpsampleFilter,
};

/// Everything that is fixed for a `VolumetricShadows` (change it with [`VolumetricShadows::set_settings`](crate::VolumetricShadows::set_settings)).
///
/// Used in the [crate-level example](crate#example).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// Method, steps, bisections and scattering resolution of the march.
    pub march: MarchSettings,
    /// How reduced-resolution scattering is brought to the output.
    pub upsample: UpsampleFilter,
    /// The F′ table's size.
    pub table: TableSize,
    /// Shadow-map resolution and bias.
    pub shadow_map: ShadowMapSettings,
    /// The soft-shadow grid's resolution (lights with a radius; see
    /// [`SoftShadowNode`](crate::nodes::SoftShadowNode)).
    pub soft_shadow: SoftShadowSize,
    /// The format of the caller's output target.
    pub output_format: wgpu::TextureFormat,
    /// An occluder whose effect on every pixel is provably below this fraction of the
    /// in-scatter is left out of the shadow map and extents (0 = never).
    pub cull_threshold: f32,
    /// The p95 relative error these settings were chosen for by
    /// [`Settings::for_error_target`] (`None`: chosen by hand). The planner reads it: under an
    /// error target a textured spot's scattering runs at full resolution.
    pub error_target: Option<f32>,
}

impl Settings {
    /// Reproducible settings for test images (as egui-wgpu's `PREDICTABLE`): each node's
    /// `DEFAULT` ([`MarchSettings::DEFAULT`]: the exact method at full resolution, 64 steps
    /// where a crossing list overflows, no bisection), the 3×3 depth-aware upsample, no
    /// culling, `Rgba16Float` output.
    pub const PREDICTABLE: Settings = Settings {
        march: MarchSettings::DEFAULT,
        upsample: UpsampleFilter::DepthAware3x3,
        table: TableSize::DEFAULT,
        shadow_map: ShadowMapSettings::DEFAULT,
        soft_shadow: SoftShadowSize::DEFAULT,
        output_format: wgpu::TextureFormat::Rgba16Float,
        cull_threshold: 0.0,
        error_target: None,
    };
}

impl Settings {
    /// Settings whose 95th-percentile per-pixel relative error of the in-scatter stays within
    /// `p95` (0.02 = 2%) at the least cost on adapters of `kind` ([`AdapterKind::of`] your
    /// device): the planner picks the method (exact or hybrid), steps, scattering resolution,
    /// filter and bisections from [`error_table`]`(kind)`, measured by the report on the
    /// standard scenes with untextured lights, keeping headroom
    /// ([`ERROR_TARGET_MARGIN`]); textured spots scatter at full resolution with
    /// [`ERROR_TARGET_TEXTURE_STEPS`]. Everything else is [`Settings::for_adapter`]'s.
    /// A tolerance tighter than any measured configuration reaches is an error.
    ///
    /// # Errors
    ///
    /// [`Error::InvalidSetting`] naming `error_target` for a tolerance that is not finite and
    /// positive, or tighter than every measured configuration reaches.
    pub fn for_error_target(p95: f32, kind: AdapterKind) -> Result<Settings> {
        let picked = for_error_target(p95, kind)?;
        Ok(Settings {
            march: MarchSettings {
                method: picked.method,
                steps: picked.steps,
                bisections: picked.bisections,
                scale: picked.scale,
                texture_steps: ERROR_TARGET_TEXTURE_STEPS,
                ..MarchSettings::default()
            },
            upsample: picked.upsample,
            error_target: Some(p95),
            ..Settings::for_adapter(kind)
        })
    }

    /// Real-time defaults for adapters of `kind` ([`AdapterKind::of`] your device): the exact
    /// method (64 steps and 2 bisections where a crossing list overflows), occluders culled
    /// below 1e-3, scattering at full resolution on a GPU and at half resolution with the 3×3
    /// depth-aware upsample on a CPU adapter, and the crossing lists built by compute passes
    /// on a GPU and by the rasteriser on a CPU adapter ([`CrossingsBuild`]). On a GPU the exact method at full resolution is
    /// exact (worst p95 0.03% on the standard scenes, against 3.4% at half) for 1.5 times the
    /// cost of half; on a CPU adapter it costs twice as much ([`error_table`]).
    pub fn for_adapter(kind: AdapterKind) -> Settings {
        Settings {
            march: MarchSettings {
                scale: match kind {
                    AdapterKind::Gpu => Scale::Full,
                    AdapterKind::Cpu => Scale::Half,
                },
                bisections: 2,
                // The compute build scales with a GPU's compute units; on a CPU adapter the
                // rasteriser's build costs a third to a sixth as much (frame bench, lavapipe).
                crossings_build: match kind {
                    AdapterKind::Gpu => CrossingsBuild::Compute,
                    AdapterKind::Cpu => CrossingsBuild::Raster,
                },
                ..MarchSettings::default()
            },
            cull_threshold: 1e-3,
            ..Settings::PREDICTABLE
        }
    }
}

impl Settings {
    /// Builds, before the first frame, every pipeline that a [`VolumetricShadows`](crate::VolumetricShadows) with these
    /// settings can use for lights of the kinds in `lights` ([`FrameLight::kind`](crate::FrameLight::kind), or
    /// [`LightKind::ALL`]): [`Cache::warm_up`] with the march settings and the output format.
    /// Without it each variant is built by the first frame that needs it, inside
    /// [`prepare`](crate::VolumetricShadows::prepare): a pause of up to seconds on that frame.
    ///
    /// # Errors
    ///
    /// Those of [`VolumetricShadows::new`](crate::VolumetricShadows::new) and of [`Cache::warm_up`]
    /// ([`Error::InvalidSetting`] naming the field), building nothing.
    pub fn warm_up(
        &self,
        device: &wgpu::Device,
        cache: &Cache,
        lights: &[LightKind],
    ) -> Result<()> {
        validate(self)?;
        cache.warm_up(device, &self.march, self.output_format, lights)
    }
}

impl Default for Settings {
    /// [`Settings::for_adapter`]`(AdapterKind::Gpu)`: the exact method at full resolution. On a
    /// CPU adapter, [`Settings::for_adapter`] with [`AdapterKind::of`] the device halves the
    /// resolution.
    fn default() -> Self {
        Settings::for_adapter(AdapterKind::Gpu)
    }
}

/// Checks what [`VolumetricShadows::new`](crate::VolumetricShadows::new) checks.
pub(crate) fn validate(settings: &Settings) -> Result<()> {
    settings.upsample.validate()?;
    settings.soft_shadow.validate()?;
    if let Some(p95) = settings.error_target {
        if !(p95.is_finite() && p95 > 0.0) {
            return Err(Error::InvalidSetting {
                field: "error_target",
                problem: format!("must be a positive relative error, got {p95}"),
            });
        }
    }
    crate::error::finite("cull_threshold", &[settings.cull_threshold])?;
    if !(0.0..=1.0).contains(&settings.cull_threshold) {
        return Err(Error::InvalidSetting {
            field: "cull_threshold",
            problem: format!("must be in [0, 1], got {}", settings.cull_threshold),
        });
    }
    Ok(())
}

/// A configuration the error target can pick, with what the report
/// (`cargo run --release -p volshadow_tools --bin report -- --scenes all`, at 512×512) measured for it on the
/// standard scenes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeasuredConfig {
    /// The march method (exact or hybrid).
    pub method: MarchMethod,
    /// Worst 95th-percentile relative error over the standard scenes.
    pub p95: f32,
    /// Mean frame time over the analytic floor's (unshadowed airlight) on the same scenes.
    pub cost: f32,
    /// Steps per marched interval.
    pub steps: u32,
    /// Scattering resolution.
    pub scale: Scale,
    /// Upsampling filter (ignored at full resolution).
    pub upsample: UpsampleFilter,
    /// Bisections per lit/shadow transition.
    pub bisections: u32,
}

const fn measured(
    method: MarchMethod,
    p95: f32,
    cost: f32,
    steps: u32,
    scale: Scale,
    upsample: UpsampleFilter,
    bisections: u32,
) -> MeasuredConfig {
    MeasuredConfig {
        method,
        p95,
        cost,
        steps,
        scale,
        upsample,
        bisections,
    }
}

/// Steps a textured spot's lit stretches outside the shadow volumes get under an error target
/// (the budget the error tables were measured with; untextured lights never use it).
pub const ERROR_TARGET_TEXTURE_STEPS: u32 = 256;

/// The error target keeps this fraction of the tolerance as headroom for scenes unlike the
/// standard ones: it picks configurations whose measured worst p95 is at most
/// `ERROR_TARGET_MARGIN × tolerance`.
pub const ERROR_TARGET_MARGIN: f32 = 0.8;

/// The kind of adapter a device runs on, for the choices whose cost differs between them
/// ([`Settings::for_adapter`](crate::Settings::for_adapter),
/// [`Settings::for_error_target`](crate::Settings::for_error_target)).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AdapterKind {
    /// A GPU (discrete, integrated or virtual): the passes run in parallel, and the fixed
    /// passes (shadow maps, crossing lists) dominate a frame, so full resolution costs little
    /// more than less.
    Gpu,
    /// A CPU rasteriser (lavapipe, llvmpipe, SwiftShader, WARP): cost grows with the pixels
    /// marched, so reduced resolution pays.
    Cpu,
}

impl AdapterKind {
    /// The kind of `device`'s adapter.
    pub fn of(device: &wgpu::Device) -> Self {
        Self::from_device_type(device.adapter_info().device_type)
    }

    /// The kind of an adapter of `device_type` (`Other`, which a driver reports when it does not
    /// say, counts as a GPU).
    pub fn from_device_type(device_type: wgpu::DeviceType) -> Self {
        match device_type {
            wgpu::DeviceType::Cpu => AdapterKind::Cpu,
            _ => AdapterKind::Gpu,
        }
    }
}

/// The Pareto front of worst-scene p95 against cost on a GPU, cheapest first, as written to
/// `target/volshadow-report/error_table.rs` by the report (`--full` on an NVIDIA H200, driver
/// 580.159.04, Vulkan, 512×512, the eight standard scenes with untextured lights without
/// a radius, p95 over pixels above 1% of each frame's 99th-percentile brightness). Only the
/// exact method is on it: at every tolerance it was cheaper than the hybrid there. Full
/// resolution costs 1.5 times half (the crossing lists scale with the pixels) and is exact.
#[rustfmt::skip]
pub const ERROR_TABLE_GPU: &[MeasuredConfig] = &[
    // measured(method, p95, cost, steps, scale, upsample, bisections)
    measured(MarchMethod::Exact, 0.0613, 18.003, 64, Scale::Quarter, UpsampleFilter::DepthAware3x3, 2),
    measured(MarchMethod::Exact, 0.0341, 20.521, 64, Scale::Half, UpsampleFilter::DepthAware3x3, 2),
    measured(MarchMethod::Exact, 0.0003, 30.519, 64, Scale::Full, UpsampleFilter::DepthAware3x3, 2),
];

/// The Pareto front on a CPU adapter, as [`ERROR_TABLE_GPU`] (the report on llvmpipe, 512×512,
/// six of the standard scenes: not the soft and stiff-fog ones). The window scene's thin sun shafts set the
/// reduced-resolution rows (exact at ½: 3.4%; every other scene ≤ 0.9%). The exact method's
/// rows list 64 steps and 2 bisections: those only march pixels whose crossing list
/// overflowed.
#[rustfmt::skip]
pub const ERROR_TABLE_CPU: &[MeasuredConfig] = &[
    // measured(method, p95, cost, steps, scale, upsample, bisections)
    measured(MarchMethod::Hybrid, 1.0000, 1.685, 8, Scale::Quarter, UpsampleFilter::DepthAware3x3, 0),
    measured(MarchMethod::Hybrid, 0.4460, 1.726, 16, Scale::Quarter, UpsampleFilter::DepthAware3x3, 0),
    measured(MarchMethod::Hybrid, 0.3303, 1.872, 16, Scale::Quarter, UpsampleFilter::Separable { taps: 7, sigma_spatial: 1.5, sigma_depth: 0.05 }, 0),
    measured(MarchMethod::Hybrid, 0.3097, 1.905, 16, Scale::Quarter, UpsampleFilter::DepthAware3x3, 2),
    measured(MarchMethod::Exact, 0.0614, 1.909, 64, Scale::Quarter, UpsampleFilter::DepthAware3x3, 2),
    measured(MarchMethod::Exact, 0.0342, 2.834, 64, Scale::Half, UpsampleFilter::DepthAware3x3, 2),
    measured(MarchMethod::Exact, 0.0003, 5.522, 64, Scale::Full, UpsampleFilter::DepthAware3x3, 2),
];

/// The error table measured on adapters of `kind`.
pub fn error_table(kind: AdapterKind) -> &'static [MeasuredConfig] {
    match kind {
        AdapterKind::Gpu => ERROR_TABLE_GPU,
        AdapterKind::Cpu => ERROR_TABLE_CPU,
    }
}

/// The cheapest configuration of [`error_table`]`(kind)` whose measured worst p95 is within
/// [`ERROR_TARGET_MARGIN`] of `p95` (a relative error: 0.02 = 2%).
///
/// # Errors
///
/// [`Error::InvalidSetting`] naming `error_target` for a tolerance that is not finite and
/// positive, or tighter than every configuration of the table reaches.
pub fn for_error_target(p95: f32, kind: AdapterKind) -> Result<MeasuredConfig> {
    if !(p95.is_finite() && p95 > 0.0) {
        return Err(Error::InvalidSetting {
            field: "error_target",
            problem: format!("must be a positive relative error, got {p95}"),
        });
    }
    let allowed = ERROR_TARGET_MARGIN * p95;
    let table = error_table(kind);
    table
        .iter()
        .filter(|c| c.p95 <= allowed)
        .min_by(|a, b| a.cost.total_cmp(&b.cost))
        .copied()
        .ok_or_else(|| {
            let best = table.iter().map(|c| c.p95).fold(f32::INFINITY, f32::min);
            Error::InvalidSetting {
                field: "error_target",
                problem: format!(
                    "p95 {:.3}% is below what any measured configuration reaches with headroom \
                     (best {:.3}%, headroom {ERROR_TARGET_MARGIN})",
                    100.0 * p95,
                    100.0 * best
                ),
            }
        })
}
