//! The march node: in-scattered radiance `L_sctr` per pixel (the hybrid of Wyman and Ramsey,
//! "Interactive Volumetric Shadows in Participating Media with Single-Scattering", 2008, §3.1,
//! and the exact integration between shadow planes of Biri, Arquès and Michelin, "Real Time
//! Rendering of Atmospheric Scattering and Volumetric Shadows", 2006).
//!
//! Without shadows every ray is integrated analytically from the [`AirlightTableNode`]'s table:
//! `I0 · F′(ds)`, with the singular prefactor clamped by the pixel's footprint when looking into
//! the light (where the true value is infinite). With shadows, [`MarchMethod::Hybrid`] keeps the analytic form outside
//! the shadow-volume extents and marches only between them, sampling the shadow map and adding
//! `I0 · (F′(x₁) − F′(x₀))` over lit steps; [`MarchMethod::BruteForce`] marches the whole ray
//! (the baseline). Steps are uniform in the normalised scattering angle, i.e. in the angle seen
//! from the light (Wyman and Ramsey 2008, Fig. 4). A spot light contributes only inside its cone, whose entry
//! and exit along each ray are found analytically.
//!
//! A directional light reads no table: the scattering angle is the same along a ray, so the
//! airlight over `[0, x]` is `σs·p(cos θ)·E·(1 − e^{−σt x})/σt` per channel, evaluated in a form
//! exact at `σt → 0`, for large `σt·x` and for sky rays; its steps are uniform in
//! `s = x/(x + L)`, with `L` one extinction length (at most the shadow map's half width).
//!
//! # Inputs
//! * `scene_depth`: the caller's depth buffer, any depth format (`Depth16Unorm`, `Depth24Plus`,
//!   `Depth24PlusStencil8`, `Depth32Float`, …), single-sampled, usage `TEXTURE_BINDING`; its
//!   size divided by [`MarchSettings::scale`] is the size of the pass. Depth values equal to the camera's far depth
//!   ([`Camera::far_depth`]) are sky.
//! * the table from [`AirlightTableNode`], prepared for the same eye, light and medium.
//! * optionally [`Shadows`]: a [`ShadowMap`] and, for the hybrid, the [`Extents`] of the same
//!   size as `scene_depth`.
//!
//! # Output
//! [`MarchNode::output`]: `Rgba32Float`, the size of `scene_depth` divided by
//! [`MarchSettings::scale`] (rounded up), usages
//! `STORAGE_BINDING | TEXTURE_BINDING | COPY_SRC`; a = eye distance of the pixel's surface
//! (−1 for sky). At full scale rgb is the in-scattered radiance; at reduced scale it is the
//! fraction of the unshadowed airlight that arrives (in [0, 1]), which
//! [`UpsampleNode`](crate::nodes::UpsampleNode) multiplies into the full-resolution analytic
//! airlight — so the peak around the light stays sharp and only shadows are low-resolution. [`MarchNode::step_counts`]: `R32Uint`, same
//! size: march steps (and bisections) each pixel executed.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use crate::error::{Error, Result};
use crate::gpu::pipeline::{
    bind_group, cached, compute_pipeline, dispatch, layout, module, Binding,
};
use crate::gpu::wgsl::{wgsl_file, Wgsl};
use crate::gpu::ShaderPrecision;
use crate::gpu::{
    check_depth_layers, check_depth_texture, check_size, check_target_size, depth_view, texture_2d,
    texture_3d, GpuTimer, UniformBuffer,
};
use crate::light::{light_constant, Source};
use crate::nodes::cache::CachedPipelines;
use crate::nodes::extents::{CrossingsBuild, Extents};
use crate::nodes::groups::shadow::{cell_angle, shadow_layout, ShadowBinding, ShadowUniform};
use crate::nodes::groups::uniforms::{AirlightUniform, ViewUniform};
use crate::nodes::light_texture::LightTextureMaps;
use crate::nodes::shadow_map::ShadowMap;
use crate::nodes::soft_shadow::SoftShadow;
use crate::nodes::Cache;
use crate::nodes::{AirlightTableNode, Scale};
use crate::nodes::{Encode, Node};
use crate::pass::Pass;
use crate::scene::{Camera, Light, Medium};

mod mode;
mod stats;

pub use mode::{MarchMethod, MarchMode, ShadowForms};
pub use stats::{MarchStats, MarchWork};

use stats::stats_buffer;

/// The march's binding table: `@binding(i)` of `shaders/passes/march.wgsl`'s group 0 is entry `i`
/// (group 1, the light and its shadow map, is [`ShadowBinding`]'s).
const BINDINGS: [Binding; 17] = [
    Binding::Params,                                    // air
    Binding::Params,                                    // view
    Binding::Texture,                                   // table
    Binding::Depth,                                     // scene_depth
    Binding::Storage(wgpu::TextureFormat::Rgba32Float), // inscatter_out
    Binding::Params,                                    // mp
    Binding::Depth,                                     // extent_front
    Binding::Depth,                                     // extent_back_near
    Binding::Depth,                                     // extent_back_far
    Binding::Storage(wgpu::TextureFormat::R32Uint),     // steps_out
    Binding::Filterable,                                // light_tex
    Binding::Sampler,                                   // light_sampler
    Binding::Params,                                    // heads
    Binding::Params,                                    // crossings
    Binding::ReadWrite,                                 // stats
    Binding::Volume,                                    // soft_volume
    Binding::UintTexture,                               // light_flats
];

/// The march shader's pipeline constants: one pipeline each.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
struct Variant {
    mode: MarchMode,
    /// The `LIGHT` constant ([`LightUniform::kind`]).
    light: u32,
    textured: bool,
    bisections: u32,
    soft: bool,
    /// `soft` with the soft-shadow grid bound.
    soft_grid: bool,
    /// `soft_grid` with its cells marked near narrow shafts ([`SoftShadow::shafts`]).
    shafts: bool,
    /// Per-pixel work counters ([`MarchNode::set_work_counters`]); never in a frame's own
    /// pipelines.
    work: bool,
}

impl Variant {
    /// The variant of `mode` for a light of this kind (`grid`: a soft-shadow grid is bound,
    /// and whether its cells are marked near narrow shafts).
    fn new(
        mode: MarchMode,
        light: u32,
        textured: bool,
        soft: bool,
        (grid, shafts): (bool, bool),
        bisections: u32,
    ) -> Self {
        Variant {
            mode,
            light,
            textured,
            bisections: if mode == MarchMode::Analytic || soft {
                0
            } else {
                bisections
            },
            soft: soft && !matches!(mode, MarchMode::Analytic | MarchMode::Textbook),
            soft_grid: soft && grid && mode == MarchMode::Hybrid,
            shafts: soft && grid && shafts && mode == MarchMode::Hybrid,
            work: false,
        }
    }
}

/// The march's layout and its pipelines, one per [`Variant`] built on first use; held by the
/// [`Cache`].
#[derive(Clone)]
pub(crate) struct Pipelines {
    layout: wgpu::BindGroupLayout,
    /// Group 1, the light and its shadow map ([`ShadowBinding`]).
    shadow_layout: wgpu::BindGroupLayout,
    module: wgpu::ShaderModule,
    variants: Arc<Mutex<HashMap<Variant, wgpu::ComputePipeline>>>,
}

/// The march's WGSL (it imports the shared shadow-map visibility, `pcss.wgsl`).
const SOURCE: Wgsl<'static> = wgsl_file!("march.wgsl");

impl CachedPipelines for Pipelines {
    fn build(device: &wgpu::Device, precision: ShaderPrecision) -> Self {
        Self::new(device, precision)
    }
}

impl Pipelines {
    pub(crate) fn new(device: &wgpu::Device, precision: ShaderPrecision) -> Self {
        Self {
            layout: layout(
                device,
                "volshadow march",
                wgpu::ShaderStages::COMPUTE,
                &BINDINGS,
            ),
            shadow_layout: shadow_layout(device),
            module: module(device, &SOURCE, precision),
            variants: Arc::default(),
        }
    }

    /// Builds every variant that frames of the facade with `settings` can use for lights of
    /// `kind` (see [`Cache::warm_up`]): a superset of what [`MarchNode::prepare`] picks, since a
    /// light may lose its radius (a penumbra below a texel), its occluders (culled or none), its
    /// extents' crossing lists or its soft-shadow grid from frame to frame.
    pub(crate) fn warm_up(
        &self,
        device: &wgpu::Device,
        settings: &MarchSettings,
        kind: crate::nodes::LightKind,
    ) {
        let textured = kind.textured();
        // Every mode `MarchMode::choose` can pick for this method: without occluders, and
        // with each set of shadow inputs the facade binds (crossing lists with the exact
        // method's extents).
        let crossings = settings.method == MarchMethod::Exact;
        let forms = [(false, false), (true, false), (false, true), (true, true)].map(
            |(extents, soft_grid)| {
                Some(ShadowForms {
                    extents,
                    crossings: extents && crossings,
                    soft_grid,
                })
            },
        );
        let softness: &[bool] = if kind.soft() {
            &[false, true]
        } else {
            &[false]
        };
        for &soft in softness {
            for shadows in std::iter::once(None).chain(forms) {
                let mode = MarchMode::choose(settings.method, soft, shadows);
                let grid = shadows.is_some_and(|s| s.soft_grid);
                // A grid with shaft marks or without (its shadow map's occluders may leave
                // gaps or not).
                for shafts in [false, grid] {
                    self.variant(
                        device,
                        Variant::new(
                            mode,
                            kind.gpu(),
                            textured,
                            soft,
                            (grid, shafts),
                            settings.bisections,
                        ),
                    );
                }
            }
        }
    }

    fn variant(&self, device: &wgpu::Device, v: Variant) -> wgpu::ComputePipeline {
        cached(&self.variants, v, || {
            let flag = |b: bool| if b { 1.0 } else { 0.0 };
            let constants = [
                ("MODE", f64::from(v.mode as u32)),
                light_constant(v.light),
                ("TEXTURED", flag(v.textured)),
                ("BISECTIONS", f64::from(v.bisections)),
                ("SOFT", flag(v.soft)),
                ("SOFT_GRID", flag(v.soft_grid)),
                ("SOFT_SHAFTS", flag(v.shafts)),
                ("SOFT_EXACT", flag(v.soft_grid)),
                ("COUNT_WORK", flag(v.work)),
            ];
            let label = "volshadow march";
            compute_pipeline(
                device,
                label,
                &[&self.layout, &self.shadow_layout],
                &self.module,
                "march",
                &constants,
            )
        })
    }
}

/// March settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MarchSettings {
    /// How shadowed rays are integrated. Default [`MarchMethod::Exact`].
    pub method: MarchMethod,
    /// Steps per marched interval (1 ..= 4096): the hybrid's between the extents, brute
    /// force's and the textbook march's per ray, the exact method's only where a pixel's
    /// crossing list overflowed. Default 64.
    pub steps: u32,
    /// Bisection steps locating each lit/shadow transition between two samples (0 = off,
    /// at most 16). Default 0.
    pub bisections: u32,
    /// Resolution of the march relative to `scene_depth` (full, ½, ¼). Default full.
    pub scale: Scale,
    /// Textured spot lights: the most steps a piece of a ray takes for the texture's sake
    /// (1 ..= 4096; default 32). Where nothing shadows it (before and after the shadow-volume
    /// extents, between the exact method's crossings) a piece takes one step per flat region
    /// of the texture its image crosses and one per cell between texel centres that is not
    /// flat ([`LightTextureNode::flats`](crate::nodes::LightTextureNode::flats)), up to this
    /// many, then uniform steps for the rest. The hybrid between the extents takes uniform
    /// steps, one per texel the piece's image can cross (the angle it subtends at the light
    /// over the smallest texel's), at least `steps` and at most this many or `steps`; brute
    /// force marches everything with its `steps`.
    pub texture_steps: u32,
    /// Exact method: shadow-volume crossings recorded per pixel
    /// (1 ..= [`MAX_CROSSINGS_PER_PIXEL`](crate::nodes::MAX_CROSSINGS_PER_PIXEL)). Default
    /// [`DEFAULT_CROSSINGS`].
    pub crossings: u32,
    /// Exact method: how the crossing lists are built. Default [`CrossingsBuild::Compute`]
    /// (`Settings::for_adapter` picks [`CrossingsBuild::Raster`] on a CPU adapter).
    pub crossings_build: CrossingsBuild,
}

/// The default list length of the exact method, chosen by measurement on the standard scenes
/// (see the README's error-against-time section): long enough that no pixel of a smooth
/// occluder's shadow overflows, short enough to keep the lists' memory small.
pub const DEFAULT_CROSSINGS: u32 = 24;

impl Default for MarchSettings {
    fn default() -> Self {
        Self::DEFAULT
    }
}

impl MarchSettings {
    /// The default: the exact method at full resolution, 64 steps where a crossing list
    /// overflows, no bisection, 32 steps through a textured spot's cone, crossing lists of
    /// [`DEFAULT_CROSSINGS`] built by compute passes.
    pub const DEFAULT: MarchSettings = MarchSettings {
        method: MarchMethod::Exact,
        steps: 64,
        bisections: 0,
        scale: Scale::Full,
        texture_steps: 32,
        crossings: DEFAULT_CROSSINGS,
        crossings_build: CrossingsBuild::Compute,
    };
    pub(crate) fn validate(&self) -> Result<()> {
        if !(1..=4096).contains(&self.steps) {
            return Err(Error::InvalidSetting {
                field: "march.steps",
                problem: format!("must be in 1..=4096, got {}", self.steps),
            });
        }
        if !(1..=4096).contains(&self.texture_steps) {
            return Err(Error::InvalidSetting {
                field: "march.texture_steps",
                problem: format!("must be in 1..=4096, got {}", self.texture_steps),
            });
        }
        if !(1..=crate::nodes::MAX_CROSSINGS_PER_PIXEL).contains(&self.crossings) {
            return Err(Error::InvalidSetting {
                field: "march.crossings",
                problem: format!(
                    "must be in 1..={}, got {}",
                    crate::nodes::MAX_CROSSINGS_PER_PIXEL,
                    self.crossings
                ),
            });
        }
        if self.bisections > 16 {
            return Err(Error::InvalidSetting {
                field: "march.bisections",
                problem: format!("must be at most 16, got {}", self.bisections),
            });
        }
        Ok(())
    }
}

/// What shadows the march: the shadow map, and for the hybrid the extents.
#[derive(Clone, Copy)]
pub struct Shadows<'a> {
    /// Visibility from the light.
    pub shadow_map: ShadowMap<'a>,
    /// Where the shadow volumes are along each ray: the hybrid needs the depth textures, the
    /// exact method the crossing lists. `None` (or extents without what the method needs)
    /// marches the whole ray, as brute force.
    pub extents: Option<Extents<'a>>,
    /// A light with a radius: its [`SoftShadowNode`](crate::nodes::SoftShadowNode) grid, which
    /// the exact and hybrid methods read instead of estimating each step's visibility from
    /// the shadow map. `None`: every step is estimated from the shadow map (as brute force
    /// always does). Ignored for a light without a radius.
    pub soft: Option<SoftShadow<'a>>,
}

/// What the march reads in a frame.
#[derive(Clone, Copy)]
pub struct MarchInputs<'a> {
    /// The camera the depth buffer was rendered with.
    pub camera: &'a Camera,
    /// The light.
    pub light: &'a Light,
    /// The medium.
    pub medium: &'a Medium,
    /// The F′ table, prepared for the same eye, light and medium (not read for a directional
    /// light: any table node will do, prepared or not).
    pub table: &'a AirlightTableNode,
    /// The caller's depth buffer (see the module docs).
    pub scene_depth: &'a wgpu::Texture,
    /// Occluders' shadows; `None`: no occluders, analytic everywhere.
    pub shadows: Option<Shadows<'a>>,
    /// How each ray is integrated: [`MarchMode::choose`] for the settings' method, the light's
    /// radius and these `shadows`' [`ShadowForms`] (the planner's
    /// [`LightPlan::march`](crate::plan::LightPlan::march) in the facade).
    pub mode: MarchMode,
    /// A spot light's texture as a blurred mip chain and the map of its flat regions
    /// ([`LightTextureNode::maps`](crate::nodes::LightTextureNode::maps)), encoded before the
    /// march; `None` for an untextured light.
    pub light_texture: Option<LightTextureMaps<'a>>,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
/// WGSL `MarchParams` (`shaders/passes/march.wgsl`), field by field.
struct MarchUniform {
    tex_frame: [f32; 16],
    steps: u32,
    list_entries: u32,
    texture_steps: u32,
    lit_fraction: u32,
    extents_near: f32,
    tan_half_angle: f32,
    tex_width: f32,
    tex_mips: f32,
    soft_grid: SoftGridUniform,
}

/// WGSL `SoftGrid` (`shaders/passes/march.wgsl`): the soft-shadow grid the march reads.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct SoftGridUniform {
    directions: u32,
    slices: u32,
    layers: u32,
    /// The angle (radians) a cell subtends at a layer's centre (0: no grid).
    cell_angle: f32,
}

/// Half the width of an orthographic shadow map's square, from its `clip_from_world` (`None`
/// when it is not a finite positive length).
fn ortho_half_width(m: &glam::Mat4) -> Option<f32> {
    let row = m.row(0).truncate().length();
    let half = 1.0 / row;
    (half.is_finite() && half > 0.0).then_some(half)
}

/// Computes in-scattered radiance per pixel into its own `Rgba32Float` texture.
///
/// # Soft shadows
///
/// For a light with a [`radius`](crate::scene::PointLight::radius) (see its model there),
/// visibility is the fraction of the light's disc seen from a point. It is estimated from the
/// one shadow map by percentage-closer soft shadows (Fernando, "Percentage-Closer Soft
/// Shadows", 2005): a blocker search over the directions (seen from the light) where a line
/// from the point to the disc can meet an occluder, then the mean of 32 hard 2×2-filtered
/// lookups over the directions where the lines from the point to the disc cross the blockers.
/// The blockers' distance is the *farthest* one found, in two search rounds of 8 taps and the
/// point's own direction (the second round over the filter's own footprint; 16 taps a round
/// cost 1.4× as much to build the grid and were no more accurate on any scene of the crate's
/// tests): for a convex occluder the lines graze its outline, and the
/// mean front-surface distance made the penumbra up to 12% too wide (on the sphere scene of
/// `tests/gpu/soft.rs`, p95 5.9% against the reference, 2.2% with the farthest blocker). Where
/// [`ShadowMap::back`] is given, each blocker's distance is taken between its front surface
/// and its back face (see [`SoftShadowNode`](crate::nodes::SoftShadowNode)), where a convex
/// occluder's outline lies: on the same sphere p95 0.67% (1.79% with the front surface), and
/// with the eye in an umbra looking away from the light, where the deep penumbra dominates,
/// 4.6% (41.1%). The taps
/// lie on a golden-angle spiral turned by a hash of the point (with a fixed spiral, or 16
/// taps, the error grows). Shifted shadow maps from several points of the light (the
/// alternative of Ali, Sunar and Kolivand, "Soft Bilateral Filtering Volumetric Shadows
/// Using Cube Shadow Maps", 2017) were not implemented: each point costs a
/// shadow-map render and a lookup per step, and the visible fraction then moves in steps of
/// one over their count.
///
/// That estimate costs 49 shadow-map taps (145 in the deep penumbra), so [`MarchMethod::Exact`] and
/// [`MarchMethod::Hybrid`] do not make it per step: they read it from the
/// [`SoftShadowNode`](crate::nodes::SoftShadowNode)'s light-space grid
/// ([`Shadows::soft`]), one trilinear lookup per step, with about half a step per grid cell
/// the ray crosses (at most `steps`). Where the grid marks its cells (a penumbra, or the edge
/// between lit and umbra, narrower than two cells; an occluder's surface between two slices),
/// those steps are marched again at the resolution of `steps`: in a narrow penumbra the shadow
/// map's own visibility is blended in (near an occluder the penumbra narrows to the hard
/// shadow's edge, which the grid cannot resolve); at a surface, a point in front of it takes
/// the grid's slice on its side, not interpolated across the surface, and a point behind it the
/// shadow map's visibility. Each step's visible fraction is weighted by `dT/ds` at its
/// midpoint, the weights normalised to the exact in-scattered `T` over the marched interval
/// (exact where the visibility is constant, and for an optically thick medium, where `dT/ds`
/// is exponential); see the [`SoftShadowNode`](crate::nodes::SoftShadowNode) docs for where
/// the estimate is known to fall short. [`MarchMethod::BruteForce`] (and the exact and hybrid
/// methods without a grid) estimate every step from the shadow map: the baseline the grid is
/// measured against.
///
/// Rays are marched only where a penumbra can be: inside the cones of lines tangent to the
/// light's sphere and to an occluder's bounding sphere ([`ShadowMap::bounds`]) that cross
/// between them (with a 5% margin on their opening), and integrated in closed form outside
/// them, where nothing hides any part of the light. This replaces the shadow-volume crossings
/// of the exact method and the extents of the hybrid for such a light (they bound the hard
/// shadow, not the penumbra); brute force marches the whole ray, and the textbook march stays
/// hard. A radius of 0 runs exactly the code of a point light.
pub struct MarchNode {
    settings: MarchSettings,
    pipelines: Pipelines,
    /// The pipeline of the last `prepare`'s variant.
    pipeline: Option<wgpu::ComputePipeline>,
    airlight: UniformBuffer<AirlightUniform>,
    view: UniformBuffer<ViewUniform>,
    params: UniformBuffer<MarchUniform>,
    /// Group 1: the light and its shadow map.
    shadow: ShadowBinding,
    linear: wgpu::Sampler,
    dummy_light: wgpu::Texture,
    dummy_flats: wgpu::Texture,
    dummy_depth: wgpu::Texture,
    dummy_buffer: wgpu::Buffer,
    dummy_volume: wgpu::Texture,
    /// The pass's four counters ([`MarchStats`]), then with work counters four per pixel.
    stats: wgpu::Buffer,
    /// Per-pixel work counters on ([`MarchNode::set_work_counters`]).
    work: bool,
    outputs: Option<[wgpu::Texture; 2]>,
    bound: Option<Bound>,
}

/// The bind group and the textures it was made for, so it is rebuilt only when they change.
struct Bound {
    textures: Vec<wgpu::Texture>,
    buffers: Vec<wgpu::Buffer>,
    bind_group: wgpu::BindGroup,
    size: (u32, u32),
}

impl MarchNode {
    /// Creates the node; textures are allocated by the first [`prepare`](Self::prepare).
    ///
    /// # Errors
    ///
    /// [`Error::InvalidSetting`] naming the field for steps or texture steps outside `1..=4096`
    /// or more than 16 bisections.
    pub fn new(device: &wgpu::Device, cache: &Cache, settings: MarchSettings) -> Result<Self> {
        settings.validate()?;
        let sampled = wgpu::TextureUsages::TEXTURE_BINDING;
        Ok(Self {
            settings,
            pipelines: cache.get::<Pipelines>(),
            pipeline: None,
            airlight: UniformBuffer::new(device, "volshadow march airlight"),
            view: UniformBuffer::new(device, "volshadow march view"),
            params: UniformBuffer::new(device, "volshadow march params"),
            shadow: ShadowBinding::new(
                device,
                &cache.get::<Pipelines>().shadow_layout,
                "volshadow march light",
            ),
            linear: device.create_sampler(&wgpu::SamplerDescriptor {
                label: Some("volshadow light texture"),
                mag_filter: wgpu::FilterMode::Linear,
                min_filter: wgpu::FilterMode::Linear,
                mipmap_filter: wgpu::MipmapFilterMode::Linear,
                ..Default::default()
            }),
            dummy_light: texture_2d(
                device,
                "volshadow no light texture",
                (1, 1, 1),
                wgpu::TextureFormat::Rgba16Float,
                sampled,
            ),
            dummy_flats: texture_2d(
                device,
                "volshadow no light texture flats",
                (1, 1, 1),
                wgpu::TextureFormat::R8Uint,
                sampled,
            ),
            dummy_depth: texture_2d(
                device,
                "volshadow no extents",
                (1, 1, 1),
                wgpu::TextureFormat::Depth32Float,
                sampled,
            ),
            dummy_buffer: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("volshadow no crossings"),
                size: 16,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            }),
            dummy_volume: texture_3d(
                device,
                "volshadow no soft shadow",
                (1, 1, 1),
                wgpu::TextureFormat::Rgba16Float,
                sampled,
            ),
            stats: stats_buffer(device, 16),
            work: false,
            outputs: None,
            bound: None,
        })
    }

    /// The settings.
    pub fn settings(&self) -> MarchSettings {
        self.settings
    }

    /// Changes the settings (validated); takes effect at the next `prepare`.
    ///
    /// # Errors
    ///
    /// As [`MarchNode::new`].
    pub fn set_settings(&mut self, settings: MarchSettings) -> Result<()> {
        settings.validate()?;
        self.settings = settings;
        Ok(())
    }

    /// The in-scatter texture (see the module docs); `None` before the first `prepare`.
    pub fn output(&self) -> Option<&wgpu::Texture> {
        self.outputs.as_ref().map(|o| &o[0])
    }

    /// What the last recorded march met: four `u32` ([`MarchStats::from_bytes`] decodes them),
    /// cleared and written by every `encode` (`STORAGE | COPY_SRC`, 16 bytes; with work
    /// counters on, followed by four `u32` per pixel: see
    /// [`set_work_counters`](Self::set_work_counters)).
    pub fn stats_buffer(&self) -> &wgpu::Buffer {
        &self.stats
    }

    /// Steps each pixel executed (`R32Uint`); `None` before the first `prepare`.
    pub fn step_counts(&self) -> Option<&wgpu::Texture> {
        self.outputs.as_ref().map(|o| &o[1])
    }

    /// Turns per-pixel work counters on or off (default off), from the next `prepare`: for
    /// benches and tests that count what a frame does on any adapter. With them on, the march
    /// runs a pipeline built with the shader's `COUNT_WORK` constant (the pipelines of a frame
    /// without them do not contain the counting code) and [`stats_buffer`](Self::stats_buffer)
    /// holds, after its four pass counters, four `u32` per pixel of the march (row-major at its
    /// resolution): shadow-map visibility queries, light-texture reads (samples, and cells of
    /// its flat-region map), crossing-list entries read and crossing-list entries stored.
    /// [`MarchWork::from_bytes`] decodes them.
    pub fn set_work_counters(&mut self, on: bool) {
        self.work = on;
    }
}

impl Node for MarchNode {
    type Inputs<'a> = MarchInputs<'a>;

    /// Validates the inputs, (re)creates the outputs when the size changed, and uploads the
    /// uniforms that changed. Returns `true` (the march is recorded every frame).
    ///
    /// # Errors
    ///
    /// [`Error::InvalidTexture`] naming the input (`scene_depth`, `shadow_map`, `extents`,
    /// the light texture) for a wrong format, usage, layer count or size, or a texture on a light
    /// that is not a spot; [`Error::InvalidSize`] for a size beyond the device's limits;
    /// [`Error::InvalidSetting`] naming `mode` when the inputs lack what
    /// [`MarchInputs::mode`] reads (extents for the hybrid, crossing lists for the exact
    /// method, a shadow map for both and for brute force).
    fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        inputs: &MarchInputs<'_>,
    ) -> Result<bool> {
        let (width, height) = self.validate(device, inputs)?;
        let grid = soft_grid(inputs)?;
        self.allocate(device, width, height);
        let stats_size = if self.work {
            16 + 16 * u64::from(width) * u64::from(height)
        } else {
            16
        };
        if self.stats.size() != stats_size {
            self.stats = stats_buffer(device, stats_size);
            self.bound = None;
        }
        self.bind(device, inputs, grid, (width, height));
        self.upload(queue, inputs, grid, (width, height));
        let (mode, soft) = (inputs.mode, inputs.light.radius() > 0.0);
        let variant = Variant {
            work: self.work,
            ..Variant::new(
                mode,
                inputs.light.model().gpu().kind,
                inputs.light_texture.is_some(),
                soft,
                (grid.is_some(), grid.is_some_and(|g| g.shafts)),
                self.settings.bisections,
            )
        };
        self.pipeline = Some(self.pipelines.variant(device, variant));
        Ok(true)
    }
}

impl MarchNode {
    /// Checks the inputs (see [`MarchNode::prepare`]); returns the march's size.
    fn validate(&self, device: &wgpu::Device, inputs: &MarchInputs<'_>) -> Result<(u32, u32)> {
        check_depth_texture("scene_depth", inputs.scene_depth)?;
        let (full_width, full_height) = (inputs.scene_depth.width(), inputs.scene_depth.height());
        check_target_size("scene_depth size", device, full_width, full_height)?;
        let (width, height) = self.settings.scale.apply(full_width, full_height);
        if let Some(shadows) = &inputs.shadows {
            let expected = inputs.light.model().layers();
            check_depth_layers("shadow_map", shadows.shadow_map.texture, expected)?;
            shadows.shadow_map.check_back()?;
            shadows.shadow_map.check_triangles()?;
            if shadows.shadow_map.faces.len() != expected as usize {
                return Err(Error::InvalidTexture {
                    field: "shadow_map",
                    problem: format!(
                        "has {} face matrices; this light needs {expected}",
                        shadows.shadow_map.faces.len()
                    ),
                });
            }
            if let Some(extents) = &shadows.extents {
                for t in extents.textures {
                    check_depth_texture("extents", t)?;
                    check_size("extents", t, width, height)?;
                }
            }
        }

        if inputs.light_texture.is_some() && inputs.light.model().texture_frame().is_none() {
            return Err(Error::InvalidTexture {
                field: "light_texture",
                problem: "only a spot light can be textured".into(),
            });
        }
        if let Some(missing) = inputs.mode.missing(inputs) {
            return Err(Error::InvalidSetting {
                field: "mode",
                problem: format!(
                    "the {} mode reads {missing}, which the inputs lack (see MarchMode::choose)",
                    inputs.mode
                ),
            });
        }
        Ok((width, height))
    }

    /// (Re)creates the outputs when the size changed.
    fn allocate(&mut self, device: &wgpu::Device, width: u32, height: u32) {
        if !self
            .outputs
            .as_ref()
            .is_some_and(|o| o[0].width() == width && o[0].height() == height)
        {
            let storage = wgpu::TextureUsages::STORAGE_BINDING
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC;
            self.outputs = Some([
                texture_2d(
                    device,
                    "volshadow in-scatter",
                    (width, height, 1),
                    wgpu::TextureFormat::Rgba32Float,
                    storage,
                ),
                texture_2d(
                    device,
                    "volshadow march steps",
                    (width, height, 1),
                    wgpu::TextureFormat::R32Uint,
                    storage,
                ),
            ]);
        }
    }

    /// Binds the inputs and outputs, building a bind group when one of them changed.
    fn bind(
        &mut self,
        device: &wgpu::Device,
        inputs: &MarchInputs<'_>,
        grid: Option<SoftShadow<'_>>,
        (width, height): (u32, u32),
    ) {
        let table = inputs.table;
        let outputs = self.outputs.as_ref().expect("created above");
        self.shadow
            .bind(device, inputs.shadows.as_ref().map(|s| &s.shadow_map));
        let extents = inputs.shadows.as_ref().and_then(|s| s.extents);
        let extent_textures: [&wgpu::Texture; 3] = match &extents {
            Some(e) => [&e.textures[0], &e.textures[1], &e.textures[2]],
            None => [&self.dummy_depth; 3],
        };
        let textures: Vec<wgpu::Texture> = [
            table.texture(),
            inputs.scene_depth,
            &outputs[0],
            extent_textures[0],
            extent_textures[1],
            extent_textures[2],
            &outputs[1],
            inputs.light_texture.map_or(&self.dummy_light, |t| t.mips),
            grid.map_or(&self.dummy_volume, |g| g.texture),
            inputs.light_texture.map_or(&self.dummy_flats, |t| t.flats),
        ]
        .into_iter()
        .cloned()
        .collect();
        let crossings = extents.and_then(|e| e.crossings);
        let buffers: Vec<wgpu::Buffer> = match &crossings {
            Some(c) => vec![c.heads.clone(), c.list.clone()],
            None => vec![self.dummy_buffer.clone(), self.dummy_buffer.clone()],
        };
        if self
            .bound
            .as_ref()
            .is_none_or(|b| b.textures != textures || b.buffers != buffers)
        {
            let views: Vec<wgpu::TextureView> = textures
                .iter()
                .enumerate()
                .map(|(i, t)| match i {
                    1 | 3..=5 => depth_view(t),
                    _ => t.create_view(&Default::default()),
                })
                .collect();
            let view = |i: usize| wgpu::BindingResource::TextureView(&views[i]);
            let bind_group = bind_group(
                device,
                "volshadow march",
                &self.pipelines.layout,
                [
                    self.airlight.binding(),
                    self.view.binding(),
                    view(0),
                    view(1),
                    view(2),
                    self.params.binding(),
                    view(3),
                    view(4),
                    view(5),
                    view(6),
                    view(7),
                    wgpu::BindingResource::Sampler(&self.linear),
                    buffers[0].as_entire_binding(),
                    buffers[1].as_entire_binding(),
                    self.stats.as_entire_binding(),
                    view(8),
                    view(9),
                ],
            );
            self.bound = Some(Bound {
                textures,
                buffers,
                bind_group,
                size: (width, height),
            });
        }
    }

    /// Writes the uniforms.
    fn upload(
        &mut self,
        queue: &wgpu::Queue,
        inputs: &MarchInputs<'_>,
        grid: Option<SoftShadow<'_>>,
        (width, height): (u32, u32),
    ) {
        let (table, soft) = (inputs.table, inputs.light.radius() > 0.0);
        let extents = inputs.shadows.as_ref().and_then(|s| s.extents);
        let crossings = extents.and_then(|e| e.crossings);
        let camera = inputs.camera;
        let mut airlight = AirlightUniform::new(
            camera.eye(),
            inputs.light,
            inputs.medium,
            camera.pixel_angular_radius(height),
            table.size().dims(),
        );
        if let (Source::Along(_), Some(s)) = (inputs.light.model().source(), &inputs.shadows) {
            // Steps uniform in s = x / (x + L) reach at least across the shadow map's region
            // (its last, widest cascade).
            if let Some(radius) = s.shadow_map.faces.last().and_then(ortho_half_width) {
                airlight.distance = airlight.distance.min(radius);
            }
        }
        self.airlight.write(queue, airlight);
        self.view
            .write(queue, ViewUniform::new(camera, width, height));

        self.shadow.write(
            queue,
            match &inputs.shadows {
                Some(s) => ShadowUniform::new(inputs.light, &s.shadow_map, soft),
                None => ShadowUniform::unshadowed(inputs.light),
            },
        );
        let extents_near = extents.map_or(0.0, |e| e.near);
        let (tex_frame, [tan_half_angle, tex_width, tex_mips]) =
            match (inputs.light.model().texture_frame(), inputs.light_texture) {
                (Some((frame, tan_half_angle)), Some(t)) => (
                    frame.to_cols_array(),
                    [
                        tan_half_angle,
                        t.mips.width() as f32,
                        t.mips.mip_level_count() as f32,
                    ],
                ),
                _ => ([0.0; 16], [0.0; 3]),
            };
        self.params.write(
            queue,
            MarchUniform {
                tex_frame,
                steps: self.settings.steps,
                list_entries: crossings.map_or(0, |c| c.per_pixel),
                texture_steps: self.settings.texture_steps,
                lit_fraction: u32::from(self.settings.scale != Scale::Full),
                extents_near,
                tan_half_angle,
                tex_width,
                tex_mips,
                soft_grid: match (grid, &inputs.shadows) {
                    (Some(g), Some(s)) => SoftGridUniform {
                        directions: g.size.directions,
                        slices: g.size.slices,
                        layers: s.shadow_map.faces.len() as u32,
                        cell_angle: cell_angle(&s.shadow_map.faces[0], g.size.directions),
                    },
                    _ => SoftGridUniform::default(),
                },
            },
        );
    }
}

/// The soft-shadow grid the march reads (a light with a radius, in a mode that reads it),
/// checked against the light's shadow map.
fn soft_grid<'a>(inputs: &MarchInputs<'a>) -> Result<Option<SoftShadow<'a>>> {
    let soft = inputs.light.radius() > 0.0;
    let grid = inputs
        .shadows
        .as_ref()
        .and_then(|s| s.soft)
        .filter(|_| soft && inputs.mode != MarchMode::BruteForce);
    if let Some(g) = &grid {
        let t = g.texture;
        let layers = inputs
            .shadows
            .map_or(0, |s| s.shadow_map.faces.len() as u32);
        if t.dimension() != wgpu::TextureDimension::D3
            || t.format() != wgpu::TextureFormat::Rgba16Float
            || !t.usage().contains(wgpu::TextureUsages::TEXTURE_BINDING)
            || (t.width(), t.height(), t.depth_or_array_layers())
                != (g.size.directions, g.size.directions, layers * g.size.slices)
        {
            return Err(Error::InvalidTexture {
                field: "soft",
                problem:
                    "is not the 3D Rgba16Float grid of a SoftShadowNode for this light's shadow map"
                        .into(),
            });
        }
    }
    Ok(grid)
}

impl Encode for MarchNode {
    /// Records the march.
    ///
    /// # Errors
    ///
    /// [`Error::NotPrepared`] before the first successful `prepare`, recording nothing.
    fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        timer: Option<&mut GpuTimer>,
    ) -> Result<()> {
        let (Some(bound), Some(pipeline), Some(shadow)) =
            (&self.bound, &self.pipeline, self.shadow.group())
        else {
            return Err(Error::NotPrepared {
                reason: "MarchNode::prepare has not succeeded yet",
            });
        };
        encoder.clear_buffer(&self.stats, 0, None);
        let groups = (bound.size.0.div_ceil(8), bound.size.1.div_ceil(8), 1);
        dispatch(
            encoder,
            timer,
            Pass::March,
            "volshadow march",
            &[(pipeline, &[&bound.bind_group, shadow], groups)],
        );
        Ok(())
    }
}

#[cfg(test)]
#[test]
fn params_layout_matches_the_wgsl() {
    use crate::nodes::layout::{assert_same, rust_layout};
    let rust = rust_layout!(MarchUniform {
        tex_frame,
        steps,
        list_entries,
        texture_steps,
        lit_fraction,
        extents_near,
        tan_half_angle,
        tex_width,
        tex_mips,
        soft_grid,
    });
    assert_same(rust, SOURCE.text, "MarchParams");
    let grid = rust_layout!(SoftGridUniform {
        directions,
        slices,
        layers,
        cell_angle,
    });
    assert_same(grid, SOURCE.text, "SoftGrid");
    crate::nodes::layout::assert_constants(
        SOURCE.text,
        &[
            ("MODE_ANALYTIC", MarchMode::Analytic as u32),
            ("MODE_HYBRID", MarchMode::Hybrid as u32),
            ("MODE_BRUTE_FORCE", MarchMode::BruteForce as u32),
            ("MODE_EXACT", MarchMode::Exact as u32),
            ("MODE_TEXTBOOK", MarchMode::Textbook as u32),
        ],
    );
}
