//! Low-resolution scattering and the bilateral upsample node (Wyman and Ramsey 2008, §3.3, and
//! Ali, Sunar and Kolivand, "Soft Bilateral Filtering Volumetric Shadows Using Cube Shadow
//! Maps", PLOS ONE, 2017: SoftBiF-VS).

use crate::error::{finite, Error, Result};
use crate::nodes::{Encode, Node};

/// Resolution of the scattering passes (extents and march) relative to the output.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Scale {
    /// Same as the output: no upsample pass.
    #[default]
    Full,
    /// Half the output's width and height.
    Half,
    /// A quarter of the output's width and height.
    Quarter,
}

impl Scale {
    /// 1, 2 or 4.
    pub fn divisor(self) -> u32 {
        match self {
            Scale::Full => 1,
            Scale::Half => 2,
            Scale::Quarter => 4,
        }
    }

    /// The scale whose divisor is `divisor`; any other value is an error.
    ///
    /// # Errors
    ///
    /// [`Error::InvalidSetting`] for a divisor other than 1, 2 or 4.
    pub fn from_divisor(divisor: u32) -> Result<Self> {
        match divisor {
            1 => Ok(Scale::Full),
            2 => Ok(Scale::Half),
            4 => Ok(Scale::Quarter),
            _ => Err(Error::InvalidSetting {
                field: "scattering scale",
                problem: format!("must be 1, 1/2 or 1/4 of the output, got 1/{divisor}"),
            }),
        }
    }

    /// The scattering size for an output size (at least one pixel each way).
    pub fn apply(self, width: u32, height: u32) -> (u32, u32) {
        let d = self.divisor();
        (width.div_ceil(d).max(1), height.div_ceil(d).max(1))
    }
}

/// How low-resolution scattering is brought to the output resolution.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[non_exhaustive]
pub enum UpsampleFilter {
    /// Plain bilinear, blind to depth: blends across depth edges. A baseline for tests.
    Bilinear,
    /// Wyman and Ramsey 2008, §3.3: a 3×3 Gaussian over the low-resolution samples whose depth matches the
    /// full-resolution pixel's; falls back to the nearest-depth sample when none matches.
    #[default]
    DepthAware3x3,
    /// SoftBiF-VS (Ali, Sunar and Kolivand 2017): a separable N-tap bilateral (horizontal then vertical), weights
    /// `exp(−d²/2σs²) · exp(−Δz²/2σz²)` with Δz relative to the pixel's depth.
    Separable {
        /// Taps per direction (odd, 3 ..= 31).
        taps: u32,
        /// Spatial sigma in low-resolution pixels (> 0).
        sigma_spatial: f32,
        /// Depth sigma, relative to the pixel's eye distance (> 0).
        sigma_depth: f32,
    },
}

impl UpsampleFilter {
    /// Checks the separable filter's parameters.
    ///
    /// # Errors
    ///
    /// For [`UpsampleFilter::Separable`]: [`Error::InvalidSetting`] for a tap count that is even or
    /// outside `3..=31`, [`Error::NonFinite`] or [`Error::InvalidSetting`] for a sigma that is not
    /// finite and positive. The other filters have no parameters and never fail.
    pub fn validate(&self) -> Result<()> {
        if let UpsampleFilter::Separable {
            taps,
            sigma_spatial,
            sigma_depth,
        } = *self
        {
            if !(3..=31).contains(&taps) || taps % 2 == 0 {
                return Err(Error::InvalidSetting {
                    field: "upsample.taps",
                    problem: format!("must be odd and in 3..=31, got {taps}"),
                });
            }
            finite("upsample.sigma_spatial", &[sigma_spatial])?;
            finite("upsample.sigma_depth", &[sigma_depth])?;
            if sigma_spatial <= 0.0 || sigma_depth <= 0.0 {
                return Err(Error::InvalidSetting {
                    field: "upsample sigma",
                    problem: format!(
                        "sigmas must be > 0, got spatial {sigma_spatial}, depth {sigma_depth}"
                    ),
                });
            }
        }
        Ok(())
    }
}

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use crate::gpu::pipeline::{bind_group, cached, compute_pipeline, layout, module, Binding};
use crate::gpu::wgsl::wgsl_file;
use crate::gpu::ShaderPrecision;
use crate::gpu::{check_depth_texture, check_float_texture, GpuTimer, UniformBuffer};
use crate::light::{light_constant, LightUniform};
use crate::nodes::cache::CachedPipelines;
use crate::nodes::groups::uniforms::ViewUniform;
use crate::nodes::Cache;
use crate::pass::Pass;
use crate::scene::Camera;

/// The upsample's binding table: `@binding(i)` of `shaders/passes/upsample.wgsl` is entry `i`.
const BINDINGS: [Binding; 9] = [
    Binding::Params,                                    // up
    Binding::Params,                                    // view
    Binding::Texture,                                   // low
    Binding::Depth,                                     // scene_depth
    Binding::Texture,                                   // mid
    Binding::Storage(wgpu::TextureFormat::Rgba32Float), // out_tex
    Binding::Texture,                                   // table
    Binding::Params,                                    // air
    Binding::Params,                                    // light
];

/// The upsample's entry points for one kind of light: the single pass (bilinear and 3×3), and
/// the separable filter's horizontal and vertical passes.
type EntryPoints = [wgpu::ComputePipeline; 3];

/// The upsample's layout and pipelines, per kind of light (built on first use); held by the
/// [`Cache`].
#[derive(Clone)]
pub(crate) struct Pipelines {
    layout: wgpu::BindGroupLayout,
    module: wgpu::ShaderModule,
    /// Keyed by the `LIGHT` constant ([`LightUniform::kind`]).
    lights: Arc<Mutex<HashMap<u32, EntryPoints>>>,
}

impl CachedPipelines for Pipelines {
    fn build(device: &wgpu::Device, precision: ShaderPrecision) -> Self {
        Self::new(device, precision)
    }
}

impl Pipelines {
    pub(crate) fn new(device: &wgpu::Device, precision: ShaderPrecision) -> Self {
        let label = "volshadow upsample";
        Self {
            layout: layout(device, label, wgpu::ShaderStages::COMPUTE, &BINDINGS),
            module: module(device, &wgsl_file!("upsample.wgsl"), precision),
            lights: Arc::default(),
        }
    }

    /// Builds the pipelines a light of `kind` uses (see [`Cache::warm_up`]).
    pub(crate) fn warm_up(&self, device: &wgpu::Device, kind: crate::nodes::LightKind) {
        self.for_light(device, kind.gpu());
    }

    fn for_light(&self, device: &wgpu::Device, light: u32) -> EntryPoints {
        cached(&self.lights, light, || {
            let constants = [light_constant(light)];
            ["upsample", "separable_h", "separable_v"].map(|entry| {
                let label = "volshadow upsample";
                compute_pipeline(
                    device,
                    label,
                    &[&self.layout],
                    &self.module,
                    entry,
                    &constants,
                )
            })
        })
    }
}

/// What the upsample reads in a frame.
#[derive(Clone, Copy)]
pub struct UpsampleInputs<'a> {
    /// The camera of the frame.
    pub camera: &'a Camera,
    /// The caller's full-resolution depth buffer (any depth format, `TEXTURE_BINDING`); its size
    /// is the output size.
    pub scene_depth: &'a wgpu::Texture,
    /// The reduced-scale march output ([`MarchNode::output`](crate::nodes::MarchNode::output)):
    /// `Rgba32Float`, rgb = lit fraction, a = eye distance (−1 sky).
    pub low: &'a wgpu::Texture,
    /// The frame's F′ table, for the full-resolution analytic airlight (not read for a
    /// directional light, whose airlight is in closed form).
    pub table: &'a crate::nodes::AirlightTableNode,
    /// The light.
    pub light: &'a crate::scene::Light,
    /// The medium.
    pub medium: &'a crate::scene::Medium,
}

/// `UpsampleUniform::kind` for each filter: WGSL `FILTER_*` of `shaders/passes/upsample.wgsl`.
const FILTER_BILINEAR: u32 = 0;
const FILTER_3X3: u32 = 1;
const FILTER_SEPARABLE: u32 = 2;

#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
struct UpsampleUniform {
    kind: u32,
    taps: u32,
    sigma_spatial: f32,
    sigma_depth: f32,
    low_size: [f32; 2],
    out_size: [f32; 2],
}

/// Brings low-resolution in-scatter to the output resolution with a depth-aware filter.
///
/// # Output
/// [`UpsampleNode::output`]: `Rgba32Float`, the size of `scene_depth`, usages
/// `STORAGE_BINDING | TEXTURE_BINDING | COPY_SRC`; rgb = in-scatter, a = eye distance (−1 sky).
pub struct UpsampleNode {
    filter: UpsampleFilter,
    pipelines: Pipelines,
    /// The entry points for the last `prepare`'s kind of light.
    entry_points: Option<EntryPoints>,
    uniform: UniformBuffer<UpsampleUniform>,
    view: UniformBuffer<ViewUniform>,
    airlight: UniformBuffer<crate::nodes::groups::uniforms::AirlightUniform>,
    light: UniformBuffer<LightUniform>,
    dummy: wgpu::Texture,
    output: Option<wgpu::Texture>,
    intermediate: Option<wgpu::Texture>,
    bound: Option<(Vec<wgpu::Texture>, Vec<wgpu::BindGroup>)>,
    size: (u32, u32),
    low_height: u32,
}

impl UpsampleNode {
    /// Creates the node for `filter` (validated).
    ///
    /// # Errors
    ///
    /// Those of [`UpsampleFilter::validate`].
    pub fn new(device: &wgpu::Device, cache: &Cache, filter: UpsampleFilter) -> Result<Self> {
        filter.validate()?;
        Ok(Self {
            filter,
            pipelines: cache.get::<Pipelines>(),
            entry_points: None,
            uniform: UniformBuffer::new(device, "volshadow upsample"),
            view: UniformBuffer::new(device, "volshadow upsample view"),
            airlight: UniformBuffer::new(device, "volshadow upsample airlight"),
            light: UniformBuffer::new(device, "volshadow upsample light"),
            dummy: storage_texture(device, "volshadow upsample dummy", 1, 1),
            output: None,
            intermediate: None,
            bound: None,
            size: (0, 0),
            low_height: 0,
        })
    }

    /// The filter.
    pub fn settings(&self) -> UpsampleFilter {
        self.filter
    }

    /// Changes the filter (validated); takes effect at the next `prepare`.
    ///
    /// # Errors
    ///
    /// Those of [`UpsampleFilter::validate`].
    pub fn set_settings(&mut self, filter: UpsampleFilter) -> Result<()> {
        filter.validate()?;
        self.filter = filter;
        Ok(())
    }

    /// The upsampled in-scatter; `None` before the first `prepare`.
    pub fn output(&self) -> Option<&wgpu::Texture> {
        self.output.as_ref()
    }
}

impl Node for UpsampleNode {
    type Inputs<'a> = UpsampleInputs<'a>;

    /// Validates the inputs, (re)creates textures when sizes change, uploads what changed.
    /// Returns `true` (the upsample is recorded every frame).
    ///
    /// # Errors
    ///
    /// [`Error::InvalidTexture`] naming the input (`scene_depth`, `low`) for a wrong format,
    /// usage or layer count, or a `low` texture larger than the output.
    fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        inputs: &UpsampleInputs<'_>,
    ) -> Result<bool> {
        let (w, h, lh) = validate(inputs)?;
        self.allocate(device, (w, h), lh);
        self.bind(device, inputs);
        self.upload(queue, inputs);
        let light = LightUniform::new(inputs.light);
        self.light.write(queue, light);
        self.entry_points = Some(self.pipelines.for_light(device, light.kind));
        self.size = (w, h);
        self.low_height = lh;
        Ok(true)
    }
}

/// Checks the inputs (see [`UpsampleNode::prepare`]); returns the output's size and the
/// reduced-resolution input's height.
fn validate(inputs: &UpsampleInputs<'_>) -> Result<(u32, u32, u32)> {
    check_depth_texture("scene_depth", inputs.scene_depth)?;
    check_float_texture("low", inputs.low)?;
    let (w, h) = (inputs.scene_depth.width(), inputs.scene_depth.height());
    let (lw, lh) = (inputs.low.width(), inputs.low.height());
    if lw > w || lh > h {
        return Err(Error::InvalidTexture {
            field: "low",
            problem: format!("is {lw}x{lh}, larger than the output {w}x{h}"),
        });
    }
    Ok((w, h, lh))
}

impl UpsampleNode {
    /// (Re)creates the output, and the separable filter's intermediate, when a size changed.
    fn allocate(&mut self, device: &wgpu::Device, (w, h): (u32, u32), lh: u32) {
        if self
            .output
            .as_ref()
            .is_none_or(|t| (t.width(), t.height()) != (w, h))
        {
            self.output = Some(storage_texture(
                device,
                "volshadow upsampled in-scatter",
                w,
                h,
            ));
        }
        let separable = matches!(self.filter, UpsampleFilter::Separable { .. });
        if separable
            && self
                .intermediate
                .as_ref()
                .is_none_or(|t| (t.width(), t.height()) != (w, lh))
        {
            self.intermediate = Some(storage_texture(
                device,
                "volshadow upsample horizontal",
                w,
                lh,
            ));
        }
    }

    /// Binds the inputs and outputs, building the bind groups when one of them changed.
    fn bind(&mut self, device: &wgpu::Device, inputs: &UpsampleInputs<'_>) {
        let separable = matches!(self.filter, UpsampleFilter::Separable { .. });
        let output = self.output.clone().expect("created above");
        let mid = if separable {
            self.intermediate.clone().expect("created above")
        } else {
            self.dummy.clone()
        };
        let textures = vec![
            inputs.low.clone(),
            inputs.scene_depth.clone(),
            mid.clone(),
            output.clone(),
            inputs.table.texture().clone(),
        ];
        if self.bound.as_ref().is_none_or(|(t, _)| *t != textures) {
            let low_view = inputs.low.create_view(&Default::default());
            let table_view = inputs.table.texture().create_view(&Default::default());
            let depth = crate::gpu::depth_view(inputs.scene_depth);
            let make = |mid_sampled: &wgpu::Texture, out: &wgpu::Texture| {
                let mid_view = mid_sampled.create_view(&Default::default());
                let out_view = out.create_view(&Default::default());
                let view = wgpu::BindingResource::TextureView;
                bind_group(
                    device,
                    "volshadow upsample",
                    &self.pipelines.layout,
                    [
                        self.uniform.binding(),
                        self.view.binding(),
                        view(&low_view),
                        view(&depth),
                        view(&mid_view),
                        view(&out_view),
                        view(&table_view),
                        self.airlight.binding(),
                        self.light.binding(),
                    ],
                )
            };
            let groups = if separable {
                // Horizontal: writes the intermediate; vertical: reads it, writes the output.
                vec![make(&self.dummy, &mid), make(&mid, &output)]
            } else {
                vec![make(&self.dummy, &output)]
            };
            self.bound = Some((textures, groups));
        }
    }

    /// Writes the filter's, view's and airlight's uniforms.
    fn upload(&mut self, queue: &wgpu::Queue, inputs: &UpsampleInputs<'_>) {
        let (w, h) = (inputs.scene_depth.width(), inputs.scene_depth.height());
        let (lw, lh) = (inputs.low.width(), inputs.low.height());
        let (kind, taps, sigma_spatial, sigma_depth) = match self.filter {
            UpsampleFilter::Bilinear => (FILTER_BILINEAR, 0, 1.0, 1.0),
            UpsampleFilter::DepthAware3x3 => (FILTER_3X3, 3, 1.0, 1.0),
            UpsampleFilter::Separable {
                taps,
                sigma_spatial,
                sigma_depth,
            } => (FILTER_SEPARABLE, taps, sigma_spatial, sigma_depth),
        };
        self.uniform.write(
            queue,
            UpsampleUniform {
                kind,
                taps,
                sigma_spatial,
                sigma_depth,
                low_size: [lw as f32, lh as f32],
                out_size: [w as f32, h as f32],
            },
        );
        self.view
            .write(queue, ViewUniform::new(inputs.camera, w, h));
        let camera = inputs.camera;
        self.airlight.write(
            queue,
            crate::nodes::groups::uniforms::AirlightUniform::new(
                camera.eye(),
                inputs.light,
                inputs.medium,
                camera.pixel_angular_radius(h),
                inputs.table.size().dims(),
            ),
        );
    }
}

impl Encode for UpsampleNode {
    /// Records the upsample (one pass, or two for the separable filter).
    ///
    /// # Errors
    ///
    /// [`Error::NotPrepared`] before the first successful `prepare`, recording nothing.
    fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        timer: Option<&mut GpuTimer>,
    ) -> Result<()> {
        let (Some((_, groups)), Some([single, horizontal_pipeline, vertical_pipeline])) =
            (&self.bound, &self.entry_points)
        else {
            return Err(Error::NotPrepared {
                reason: "UpsampleNode::prepare has not succeeded yet",
            });
        };
        let timestamp_writes = timer.and_then(|t| t.compute_pass(Pass::Upsample));
        let mut pass = crate::gpu::passes::begin_compute(
            encoder,
            &wgpu::ComputePassDescriptor {
                label: Some("volshadow upsample"),
                timestamp_writes,
            },
        );
        let (w, h) = self.size;
        if let [horizontal, vertical] = groups.as_slice() {
            pass.set_pipeline(horizontal_pipeline);
            pass.set_bind_group(0, horizontal, &[]);
            pass.dispatch_workgroups(w.div_ceil(8), self.low_height.div_ceil(8), 1);
            pass.set_pipeline(vertical_pipeline);
            pass.set_bind_group(0, vertical, &[]);
            pass.dispatch_workgroups(w.div_ceil(8), h.div_ceil(8), 1);
        } else {
            pass.set_pipeline(single);
            pass.set_bind_group(0, &groups[0], &[]);
            pass.dispatch_workgroups(w.div_ceil(8), h.div_ceil(8), 1);
        }
        Ok(())
    }
}

fn storage_texture(device: &wgpu::Device, label: &str, width: u32, height: u32) -> wgpu::Texture {
    crate::gpu::texture_2d(
        device,
        label,
        (width, height, 1),
        wgpu::TextureFormat::Rgba32Float,
        wgpu::TextureUsages::STORAGE_BINDING
            | wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::COPY_SRC,
    )
}

#[cfg(test)]
#[test]
fn params_layout_matches_the_wgsl() {
    use crate::nodes::layout::{assert_same, rust_layout};
    let rust = rust_layout!(UpsampleUniform {
        kind,
        taps,
        sigma_spatial,
        sigma_depth,
        low_size,
        out_size,
    });
    let source = include_str!("../../shaders/passes/upsample.wgsl");
    assert_same(rust, source, "Upsample");
    crate::nodes::layout::assert_constants(
        source,
        &[
            ("FILTER_BILINEAR", FILTER_BILINEAR),
            ("FILTER_3X3", FILTER_3X3),
            ("FILTER_SEPARABLE", FILTER_SEPARABLE),
        ],
    );
}
