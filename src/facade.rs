//! `VolumetricShadows`: owns the nodes, asks the planner what to run, records it.

use crate::error::{Error, Result};
use crate::gpu::headless::HeadlessGpu;
use crate::gpu::{GpuTimer, Occluder, PassTime};
use crate::nodes::{
    AirlightTableNode, CompositeInputs, CompositeNode, CompositeSurfaces, CrossingsBuild,
    CrossingsRequest, ExtentsInputs, ExtentsNode, IssTableNode, IssTableSize, LightTextureNode,
    MarchInputs, MarchMethod, MarchNode, MarchSettings, OutputTarget, Scale, ShadowMapInputs,
    ShadowMapNode, ShadowMapSettings, Shadows, SoftShadowInputs, SoftShadowNode, SoftShadowSize,
    TableInputs, TableSize, UpsampleFilter, UpsampleInputs, UpsampleNode, MAX_LIGHTS,
};
use crate::nodes::{Cache, Encode, LightKind, Node};
use crate::plan::{self, AdapterKind, Culled, FrameFacts, LightFacts, Pass, Plan};
use crate::scene::{Camera, Light, Medium};

/// Everything that is fixed for a `VolumetricShadows` (change it with [`VolumetricShadows::set_settings`]).
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
    /// filter and bisections from [`plan::error_table`]`(kind)`, measured by the report on the
    /// standard scenes with untextured lights, keeping headroom
    /// ([`plan::ERROR_TARGET_MARGIN`]); textured spots scatter at full resolution with
    /// [`plan::ERROR_TARGET_TEXTURE_STEPS`]. Everything else is [`Settings::for_adapter`]'s.
    /// A tolerance tighter than any measured configuration reaches is an error.
    ///
    /// # Errors
    ///
    /// [`Error::InvalidSetting`] naming `error_target` for a tolerance that is not finite and
    /// positive, or tighter than every measured configuration reaches.
    pub fn for_error_target(p95: f32, kind: AdapterKind) -> Result<Settings> {
        let picked = plan::for_error_target(p95, kind)?;
        Ok(Settings {
            march: MarchSettings {
                method: picked.method,
                steps: picked.steps,
                bisections: picked.bisections,
                scale: picked.scale,
                texture_steps: plan::ERROR_TARGET_TEXTURE_STEPS,
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
    /// cost of half; on a CPU adapter it costs twice as much ([`plan::error_table`]).
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
    /// Builds, before the first frame, every pipeline that a [`VolumetricShadows`] with these
    /// settings can use for lights of the kinds in `lights` ([`FrameLight::kind`], or
    /// [`LightKind::ALL`]): [`Cache::warm_up`] with the march settings and the output format.
    /// Without it each variant is built by the first frame that needs it, inside
    /// [`prepare`](VolumetricShadows::prepare): a pause of up to seconds on that frame.
    ///
    /// # Errors
    ///
    /// Those of [`VolumetricShadows::new`] and of [`Cache::warm_up`]
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

/// A light of the frame, with an optional texture for a spot light (any filterable format,
/// `TEXTURE_BINDING`, e.g. from [`LightTexture::upload`](crate::scene::LightTexture::upload)).
///
/// Used in the [crate-level example](crate#example).
#[derive(Clone, Copy)]
pub struct FrameLight<'a> {
    /// The light.
    pub light: Light,
    /// The spot's projected texture.
    pub texture: Option<&'a wgpu::Texture>,
}

impl FrameLight<'_> {
    /// What decides which pipelines this light's frames use (see [`Settings::warm_up`]).
    pub fn kind(&self) -> LightKind {
        let soft = self.light.radius() > 0.0;
        match self.light {
            Light::Point(_) => LightKind::Point { soft },
            Light::Spot(_) => LightKind::Spot {
                soft,
                textured: self.texture.is_some(),
            },
            Light::Directional(_) => LightKind::Directional,
        }
    }
}

impl From<Light> for FrameLight<'_> {
    fn from(light: Light) -> Self {
        Self {
            light,
            texture: None,
        }
    }
}

/// One frame's scene and the caller's rendered frame.
///
/// Used in the [crate-level example](crate#example).
#[derive(Clone, Copy)]
pub struct Frame<'a> {
    /// The camera the frame was rendered with.
    pub camera: &'a Camera,
    /// Up to [`MAX_LIGHTS`] lights, summed.
    pub lights: &'a [FrameLight<'a>],
    /// The medium.
    pub medium: &'a Medium,
    /// The occluders (for every light).
    pub occluders: &'a [Occluder<'a>],
    /// The caller's shaded colour (float sample type, `TEXTURE_BINDING`), the output's size.
    pub scene_color: &'a wgpu::Texture,
    /// The caller's depth buffer (any depth format, `TEXTURE_BINDING`), the output's size.
    pub scene_depth: &'a wgpu::Texture,
    /// The surfaces' normals and albedo: when given (and the medium scatters), the composite
    /// adds the light the medium scatters onto them (see [`Surfaces`]); `None` leaves it out.
    pub surfaces: Option<Surfaces<'a>>,
}

/// Normals and albedo of the frame's surfaces, for the light the medium scatters onto them
/// (indirect single scattering, [`nodes::IssTableNode`](crate::nodes::IssTableNode)): each
/// surface pixel gets `(ρ/π)·E(P)` added to its colour before the medium attenuates it, `E(P)`
/// summed over the frame's point and spot lights (a spot's limited to its cone; see
/// [`CompositeSurfaces`](crate::nodes::CompositeSurfaces)), unshadowed. Sky pixels get none.
#[derive(Clone, Copy)]
pub struct Surfaces<'a> {
    /// World-space normals in rgb (any length; zero: no term), any format with a float sample
    /// type (`Rgba16Float`, `Rgba32Float`, `Rgba8Snorm`, …), usage `TEXTURE_BINDING`, the
    /// output's size.
    pub normal: &'a wgpu::Texture,
    /// Diffuse albedo `ρ` in rgb (zero: no term), any format with a float sample type, usage
    /// `TEXTURE_BINDING`, the output's size.
    pub albedo: &'a wgpu::Texture,
}

/// The nodes of one light.
struct LightSlot {
    texture: LightTextureNode,
    shadow: ShadowMapNode,
    extents: ExtentsNode,
    table: AirlightTableNode,
    march: MarchNode,
    upsample: UpsampleNode,
    /// Created on the first frame that plans it (most lights never do).
    soft: Option<SoftShadowNode>,
}

/// What one light's step of a frame reads.
struct StepInputs<'a, 'f> {
    frame: &'a Frame<'f>,
    /// The light as drawn (see `VolumetricShadows::gather`).
    light: &'a Light,
    /// Its occluders after culling.
    occluders: &'a [Occluder<'f>],
    /// Its index in the frame.
    index: usize,
}

impl LightSlot {
    fn new(device: &wgpu::Device, cache: &Cache, settings: &Settings) -> Result<Self> {
        Ok(LightSlot {
            texture: LightTextureNode::new(device, cache)?,
            shadow: ShadowMapNode::new(device, cache, settings.shadow_map)?,
            extents: ExtentsNode::new(device, cache)?,
            table: AirlightTableNode::new(device, cache, settings.table)?,
            march: MarchNode::new(device, cache, settings.march)?,
            upsample: UpsampleNode::new(device, cache, settings.upsample)?,
            soft: None,
        })
    }

    /// Prepares this light's planned step `pass`; returns whether it records work.
    #[allow(clippy::too_many_arguments)]
    fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        cache: &Cache,
        settings: &Settings,
        plan: &Plan,
        pass: Pass,
        step: &StepInputs<'_, '_>,
    ) -> Result<bool> {
        let (frame, light, occluders, i) = (step.frame, step.light, step.occluders, step.index);
        let (camera, medium) = (frame.camera, frame.medium);
        let fl = &frame.lights[i];
        let (width, height) = (frame.scene_depth.width(), frame.scene_depth.height());
        Ok(match pass {
            Pass::LightTexture => match fl.texture {
                Some(t) => self.texture.prepare(device, queue, t)?,
                None => false,
            },
            Pass::ShadowMap => {
                let inputs = ShadowMapInputs {
                    light,
                    occluders,
                    camera,
                };
                self.shadow.prepare(device, queue, &inputs)?
            }
            Pass::Extents => self.extents.prepare(
                device,
                queue,
                &ExtentsInputs {
                    camera,
                    light,
                    occluders,
                    size: plan.scale(i).apply(width, height),
                    crossings: (settings.march.method == MarchMethod::Exact).then_some(
                        CrossingsRequest {
                            per_pixel: settings.march.crossings,
                            scene_depth: frame.scene_depth,
                            build: settings.march.crossings_build,
                        },
                    ),
                },
            )?,
            Pass::SoftShadow => {
                let soft = match &mut self.soft {
                    Some(node) => node,
                    None => {
                        self.soft
                            .insert(SoftShadowNode::new(device, cache, settings.soft_shadow)?)
                    }
                };
                let Some(shadow_map) = self.shadow.shadow_map() else {
                    return Err(Error::NotPrepared {
                        reason: "the plan names a soft shadow without a shadow map",
                    });
                };
                soft.prepare(device, queue, &SoftShadowInputs { light, shadow_map })?
            }
            Pass::AirlightTable => {
                let eye = camera.eye();
                let inputs = TableInputs { eye, light, medium };
                self.table.prepare(device, queue, &inputs)?
            }
            Pass::March => {
                self.march.set_settings(MarchSettings {
                    scale: plan.scale(i),
                    ..settings.march
                })?;
                let light_index = Some(i);
                let shadows = plan.runs(Pass::ShadowMap, light_index).then(|| {
                    Some(Shadows {
                        shadow_map: self.shadow.shadow_map()?,
                        extents: plan
                            .runs(Pass::Extents, light_index)
                            .then(|| self.extents.extents())
                            .flatten(),
                        soft: plan
                            .runs(Pass::SoftShadow, light_index)
                            .then(|| self.soft.as_ref()?.output())
                            .flatten(),
                    })
                });
                let inputs = MarchInputs {
                    camera,
                    light,
                    medium,
                    table: &self.table,
                    scene_depth: frame.scene_depth,
                    shadows: shadows.flatten(),
                    light_texture: fl.texture.and(self.texture.texture()),
                };
                self.march.prepare(device, queue, &inputs)?
            }
            Pass::Upsample => {
                self.upsample.set_settings(settings.upsample)?;
                let inputs = UpsampleInputs {
                    camera,
                    scene_depth: frame.scene_depth,
                    low: self.march.output().expect("prepared by the planned march"),
                    table: &self.table,
                    light,
                    medium,
                };
                self.upsample.prepare(device, queue, &inputs)?
            }
            Pass::Composite | Pass::IssTable => true,
        })
    }

    /// The light's in-scatter at the output resolution: the upsample's when it is planned.
    fn inscatter(&self, plan: &Plan, light: usize) -> Option<&wgpu::Texture> {
        match plan.runs(Pass::Upsample, Some(light)) {
            true => self.upsample.output(),
            false => self.march.output(),
        }
    }
}

/// Volumetric shadows for a view: prepare a frame, then record it into the caller's encoder.
///
/// Used in the [crate-level example](crate#example).
pub struct VolumetricShadows {
    cache: Cache,
    settings: Settings,
    slots: Vec<LightSlot>,
    composite: CompositeNode,
    /// The indirect single scattering table, made by the first frame with surfaces.
    iss: Option<IssTableNode>,
    plan: Plan,
    timer: Option<GpuTimer>,
    /// `None` when the last `prepare` succeeded and nothing dropped its frame since; otherwise
    /// why `encode` has nothing to record.
    unprepared: Option<&'static str>,
    /// The forms of the steps recorded since the settings last changed (see
    /// [`VolumetricShadows::is_first_frame`]).
    seen: std::collections::HashSet<StepShape>,
    /// Whether the last prepared frame has a step of a form not in `seen` before it.
    first_frame: bool,
}

/// What decides the pipeline variant a step records: its pass, its light's kind, whether the
/// light has a shadow map, extents and a soft-shadow grid this frame and scatters at full
/// resolution, and whether the composite adds the surface term.
type StepShape = (Pass, Option<(LightKind, [bool; 4])>, bool);

impl VolumetricShadows {
    /// Creates the composite for `settings.output_format` and validates the settings. Per-light
    /// nodes are created by the first frame that needs them.
    ///
    /// # Errors
    ///
    /// [`Error::InvalidSetting`] or [`Error::NonFinite`] naming the field of `settings` that is out
    /// of range (upsample taps and sigmas, error target, cull threshold), and
    /// [`Error::InvalidTexture`] when `output_format` is not a renderable colour format. The
    /// per-light settings are checked by the first [`prepare`](Self::prepare) that needs them.
    /// See the [crate-level example](crate#example).
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        cache: &Cache,
        settings: Settings,
    ) -> Result<Self> {
        validate(&settings)?;
        let timer = device
            .features()
            .contains(wgpu::Features::TIMESTAMP_QUERY)
            .then(|| GpuTimer::new(device, queue, 128));
        Ok(Self {
            cache: cache.clone(),
            composite: CompositeNode::new(device, cache, settings.output_format)?,
            settings,
            slots: Vec::new(),
            iss: None,
            plan: Plan::default(),
            timer,
            unprepared: Some("no frame has been prepared yet"),
            seen: Default::default(),
            first_frame: false,
        })
    }

    /// The settings.
    pub fn settings(&self) -> Settings {
        self.settings
    }

    /// Changes the settings (validated; the output format must stay the same). The next
    /// `encode` needs a `prepare` with the new settings first.
    ///
    /// # Errors
    ///
    /// As [`VolumetricShadows::new`], and [`Error::InvalidSetting`] for a different
    /// `output_format`.
    pub fn set_settings(&mut self, settings: Settings) -> Result<()> {
        validate(&settings)?;
        if settings.output_format != self.settings.output_format {
            return Err(Error::InvalidSetting {
                field: "output_format",
                problem: "create a new VolumetricShadows for another output format".into(),
            });
        }
        if settings.table != self.settings.table
            || settings.shadow_map != self.settings.shadow_map
            || settings.soft_shadow != self.settings.soft_shadow
        {
            self.slots.clear();
        }
        self.settings = settings;
        self.seen.clear();
        self.unprepared = Some("set_settings changed the settings after the last prepare");
        Ok(())
    }

    /// Validates the frame, uploads what changed, and plans the passes. Records nothing. After
    /// an error, `encode` refuses to record until a `prepare` succeeds (it never records a frame
    /// mixing this one's uploads with the last one's).
    ///
    /// # Errors
    ///
    /// Nothing is recorded and the previous plan is kept on any error:
    ///
    /// * [`Error::InvalidSetting`] naming `lights` for more than [`MAX_LIGHTS`](crate::nodes::MAX_LIGHTS) lights;
    /// * [`Error::InvalidTexture`] naming `scene_color`, `scene_depth`, a light texture,
    ///   `surface_normal` or `surface_albedo` for a wrong format, usage, layer count or size
    ///   (all must be the colour's size);
    /// * [`Error::InvalidSize`] for a frame larger than the device's texture limits;
    /// * [`Error::NonFinite`], [`Error::SingularMatrix`] or [`Error::InvalidTransform`] for an
    ///   occluder's transform;
    /// * [`Error::DeviceLimitExceeded`], naming the buffer and the `wgpu::Limits` field, for
    ///   every buffer beyond the device's limits: the occluders' shadow volumes or transforms,
    ///   the exact method's crossing lists (16 bytes a pixel: 4096² at full resolution is
    ///   beyond the core 128 MiB binding), a soft light's grid list;
    /// * on the first frame that creates a light's nodes, [`Error::InvalidSize`] for a shadow-map
    ///   resolution or table size out of range and [`Error::InvalidSetting`] for march steps or
    ///   bisections out of range (see [`Settings`]).
    ///
    /// See the [crate-level example](crate#example) for a frame that passes.
    pub fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        frame: &Frame<'_>,
    ) -> Result<&Plan> {
        self.unprepared = Some("the last prepare failed");
        self.prepare_frame(device, queue, frame)?;
        self.unprepared = None;
        Ok(&self.plan)
    }

    fn prepare_frame(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        frame: &Frame<'_>,
    ) -> Result<()> {
        if frame.lights.len() > MAX_LIGHTS {
            return Err(Error::InvalidSetting {
                field: "lights",
                problem: format!("{} lights, at most {MAX_LIGHTS}", frame.lights.len()),
            });
        }
        while self.slots.len() < frame.lights.len() {
            self.slots
                .push(LightSlot::new(device, &self.cache, &self.settings)?);
        }
        // Cheap facts first (no GPU work), then the plan, then exactly the planned steps.
        let (facts, kept, drawn) = self.gather(frame)?;
        let mut plan = plan::plan(&facts);
        if plan.runs(Pass::IssTable, None) && self.iss.is_none() {
            let size = IssTableSize::default();
            self.iss = Some(IssTableNode::new(device, &self.cache, size)?);
        }
        let mut unchanged = Vec::new();
        for (index, step) in plan.steps.iter().enumerate() {
            let work = match (step.pass, step.light) {
                (Pass::IssTable, _) => match self.iss.as_mut() {
                    Some(iss) => iss.prepare(device, queue, frame.medium)?,
                    None => true,
                },
                (_, None) => true,
                (pass, Some(i)) => {
                    let inputs = StepInputs {
                        frame,
                        light: &drawn[i],
                        occluders: &kept[i],
                        index: i,
                    };
                    let (cache, settings) = (&self.cache, &self.settings);
                    self.slots[i].prepare(device, queue, cache, settings, &plan, pass, &inputs)?
                }
            };
            if !work {
                unchanged.push(index);
            }
        }
        plan.unchanged(&unchanged);
        self.plan = plan;
        let surface_term = self.prepare_composite(device, queue, frame, facts.scatters)?;
        self.first_frame = self.note_forms(frame, &drawn, surface_term);
        Ok(())
    }

    /// The frame's facts for the planner: each light's occluders after culling (those whose
    /// effect is provably below the threshold stay out of its shadow map and extents), and
    /// the lights as drawn (one whose penumbrae the shadow map cannot resolve, hard).
    #[allow(clippy::type_complexity)]
    fn gather<'f>(
        &self,
        frame: &Frame<'f>,
    ) -> Result<(FrameFacts, Vec<Vec<Occluder<'f>>>, Vec<Light>)> {
        let settings = &self.settings;
        let mut facts = FrameFacts {
            scatters: frame.medium.sigma_s().max_element() > 0.0,
            lights: Vec::new(),
            method: settings.march.method,
            steps: settings.march.steps,
            crossings: settings.march.crossings,
            scale: settings.march.scale,
            filter: settings.upsample,
            culled: Vec::new(),
            error_target: settings.error_target,
            surfaces: frame.surfaces.is_some(),
        };
        let (mut kept, mut drawn) = (Vec::new(), Vec::new());
        for (i, fl) in frame.lights.iter().enumerate() {
            let mut light_kept = Vec::new();
            for (j, o) in frame.occluders.iter().enumerate() {
                o.validate()?;
                let eye = frame.camera.eye();
                let bound = plan::occluder_bound(eye, &fl.light, frame.medium, o.world_bounds());
                if bound < f64::from(settings.cull_threshold) {
                    facts.culled.push(Culled {
                        light: i,
                        occluder: j,
                        bound,
                    });
                } else {
                    light_kept.push(*o);
                }
            }
            let penumbra_below_texel = ShadowMapNode::penumbra_below_texel(
                &fl.light,
                nearest_occluder(&fl.light, &light_kept),
                settings.shadow_map.resolution,
            );
            let light = if penumbra_below_texel {
                without_radius(fl.light)
            } else {
                fl.light
            };
            facts.lights.push(LightFacts {
                textured: fl.texture.is_some(),
                occluders: light_kept.len(),
                directional: matches!(fl.light, Light::Directional(_)),
                soft: light.radius() > 0.0,
                penumbra_below_texel,
            });
            kept.push(light_kept);
            drawn.push(light);
        }
        Ok((facts, kept, drawn))
    }

    /// The composite's inputs: each light's in-scatter (none where the medium does not
    /// scatter, `scatters` as the frame's facts say) and the surface term. Returns whether the
    /// surface term is on.
    fn prepare_composite(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        frame: &Frame<'_>,
        scatters: bool,
    ) -> Result<bool> {
        let inscatter: Vec<&wgpu::Texture> = if scatters {
            let slots = self.slots.iter().enumerate().take(frame.lights.len());
            slots
                .map(|(i, slot)| slot.inscatter(&self.plan, i).expect("prepared"))
                .collect()
        } else {
            Vec::new()
        };
        let lights: Vec<Light> = frame.lights.iter().map(|l| l.light).collect();
        let surfaces = match (frame.surfaces, &self.iss) {
            (Some(s), Some(table)) if scatters => Some(CompositeSurfaces {
                normal: s.normal,
                albedo: s.albedo,
                table,
                lights: &lights,
            }),
            _ => None,
        };
        let surface_term = surfaces.is_some();
        self.composite.prepare(
            device,
            queue,
            &CompositeInputs {
                camera: frame.camera,
                medium: frame.medium,
                scene_color: frame.scene_color,
                scene_depth: frame.scene_depth,
                inscatter: &inscatter,
                surfaces: surfaces.as_ref(),
            },
        )?;
        Ok(surface_term)
    }

    /// Records the forms this frame's steps take (see [`is_first_frame`](Self::is_first_frame));
    /// returns whether one is new.
    fn note_forms(&mut self, frame: &Frame<'_>, drawn: &[Light], surface_term: bool) -> bool {
        let plan = &self.plan;
        let present = |pass, light| {
            plan.runs(pass, light)
                || plan.skip_reason(pass, light) == Some(&plan::Reason::Unchanged)
        };
        let mut first = false;
        for step in &plan.steps {
            let light = step.light.map(|i| {
                let kind = FrameLight {
                    light: drawn[i],
                    texture: frame.lights[i].texture,
                }
                .kind();
                let light = Some(i);
                let forms = [
                    present(Pass::ShadowMap, light),
                    present(Pass::Extents, light),
                    present(Pass::SoftShadow, light),
                    plan.scale(i) == crate::nodes::Scale::Full,
                ];
                (kind, forms)
            });
            first |= self.seen.insert((step.pass, light, surface_term));
        }
        first
    }

    /// Whether the last prepared frame records a step in a form (its pass, its light's
    /// [`LightKind`], whether the light has shadows, extents and a soft-shadow grid, its
    /// resolution, the surface term) that this `VolumetricShadows` had not recorded since it
    /// was created or its settings changed: the first frame, and any that brings a new light
    /// kind or shadow configuration. Such a frame may run pipelines for the first time.
    /// Drivers that compile a pipeline when it first runs rather than when it is created
    /// (Mesa's lavapipe) spend that compilation, up to seconds, in this frame's submission, so
    /// its wall-clock times (and [`run_timed`](Self::run_timed)'s on
    /// a CPU adapter) are not the steady state. Elsewhere [`Settings::warm_up`] builds every
    /// pipeline before the first frame, and timestamp queries ([`read_timings`](Self::read_timings))
    /// measure GPU work only.
    pub fn is_first_frame(&self) -> bool {
        self.first_frame
    }

    /// Records the planned passes into `encoder` and the composite into `output`: a texture
    /// (mip 0, layer 0) or an [`OutputTarget`] naming a mip level and array layer of one.
    /// It must be a single-sampled 2D `RENDER_ATTACHMENT` texture of the settings' output format
    /// (or its sRGB twin), or a `STORAGE_BINDING` one in that format where it is a storage
    /// format (the composite is then a compute pass: see [`CompositeNode`]), whose size at that
    /// mip level is the frame's, and not one of the frame's inputs. The facade takes the texture rather than a `wgpu::TextureView` because
    /// a view does not tell its size, mip level or layer, so it could not be checked. Never
    /// submits.
    ///
    /// # Errors
    ///
    /// Recording nothing: [`Error::NotPrepared`] without a successful
    /// [`prepare`](Self::prepare) of the current frame (before the first, after a failed one,
    /// after [`invalidate`](Self::invalidate) or [`set_settings`](Self::set_settings));
    /// [`Error::InvalidTexture`] naming `output` when it is not such a texture. See the
    /// [crate-level example](crate#example).
    pub fn encode<'o>(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        output: impl Into<OutputTarget<'o>>,
    ) -> Result<()> {
        let output = output.into();
        self.check_prepared()?;
        self.composite.check_output(&output)?;
        if let Some(t) = self.timer.as_mut() {
            t.clear();
        }
        for index in 0..self.plan.steps.len() {
            self.record(encoder, &output, index)?;
        }
        if let Some(t) = &self.timer {
            t.resolve(encoder);
        }
        Ok(())
    }

    /// Records only step `index` of the plan (`plan().steps[index]`), untimed: for profilers
    /// that submit each pass on its own and time the submission — the way to time passes on
    /// a CPU adapter such as lavapipe, whose timestamps do not bracket compute work. Steps
    /// must be recorded in plan order within a frame; each reads what earlier steps wrote.
    ///
    /// # Errors
    ///
    /// [`Error::InvalidSetting`] naming `index` when it is not a step of the plan, and those of
    /// [`encode`](Self::encode).
    pub fn encode_step<'o>(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        output: impl Into<OutputTarget<'o>>,
        index: usize,
    ) -> Result<()> {
        let output = output.into();
        self.check_prepared()?;
        if index >= self.plan.steps.len() {
            return Err(Error::InvalidSetting {
                field: "index",
                problem: format!(
                    "the plan has {} steps, got index {index}",
                    self.plan.steps.len()
                ),
            });
        }
        let timer = self.timer.take();
        let result = self.record(encoder, &output, index);
        self.timer = timer;
        result
    }

    fn check_prepared(&self) -> Result<()> {
        match self.unprepared {
            Some(reason) => Err(Error::NotPrepared { reason }),
            None => Ok(()),
        }
    }

    fn record(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        output: &OutputTarget<'_>,
        index: usize,
    ) -> Result<()> {
        let step = &self.plan.steps[index];
        let mut timer = self.timer.as_mut();
        if let Some(t) = timer.as_deref_mut() {
            t.light = step.light;
        }
        let Some(i) = step.light else {
            return match (step.pass, self.iss.as_mut()) {
                (Pass::IssTable, Some(iss)) => iss.encode(encoder, timer),
                (Pass::IssTable, None) => Err(Error::NotPrepared {
                    reason: "the plan names the ISS table, which has no resources",
                }),
                _ => self.composite.encode(encoder, output, timer),
            };
        };
        // Slots and plan are built together by a successful prepare; a stale plan is refused
        // by `check_prepared`, never indexed.
        let Some(slot) = self.slots.get_mut(i) else {
            return Err(Error::NotPrepared {
                reason: "the plan names a light that has no resources",
            });
        };
        let node: &mut dyn Encode = match step.pass {
            Pass::LightTexture => &mut slot.texture,
            Pass::ShadowMap => &mut slot.shadow,
            Pass::Extents => &mut slot.extents,
            Pass::AirlightTable => &mut slot.table,
            Pass::March => &mut slot.march,
            Pass::Upsample => &mut slot.upsample,
            Pass::Composite => return self.composite.encode(encoder, output, timer),
            Pass::IssTable => return Ok(()), // a frame step, recorded above
            Pass::SoftShadow => match slot.soft.as_mut() {
                Some(node) => node,
                None => {
                    return Err(Error::NotPrepared {
                        reason: "the plan names a soft shadow that has no resources",
                    })
                }
            },
        };
        node.encode(encoder, timer)
    }

    /// Forgets every per-light resource, so the next frame rebuilds all of it (shadow maps,
    /// tables, light textures) as a first frame does: to measure a frame in which everything
    /// moved, or after changing a caller texture's contents in place, which `prepare` cannot
    /// see. The next `encode` needs a `prepare` first.
    pub fn invalidate(&mut self) {
        self.slots.clear();
        self.iss = None;
        self.unprepared = Some("invalidate() dropped the prepared frame");
    }

    /// The plan of the last `prepare`.
    pub fn plan(&self) -> &Plan {
        &self.plan
    }

    /// GPU time per pass of the last submitted frame (timestamp queries; empty when the device
    /// lacks `TIMESTAMP_QUERY`: time the submission with the wall clock then). Blocks until
    /// the GPU is done.
    ///
    /// # Errors
    ///
    /// [`Error::Readback`] when mapping the query buffer fails.
    pub fn read_timings(&self, device: &wgpu::Device) -> Result<Vec<PassTime>> {
        match &self.timer {
            Some(t) => t.read(device),
            None => Ok(Vec::new()),
        }
    }

    /// Records and runs on `gpu` the frame last prepared into `output`, leaving out the
    /// passes in `skip`, and returns each pass's time. On a CPU adapter (lavapipe) each pass is
    /// submitted alone and timed by the wall clock: there the submission *is* the pass's run,
    /// and lavapipe's timestamp queries do not bracket compute dispatches. Elsewhere the frame
    /// is one submission timed by timestamp queries, every planned pass runs (`skip` is
    /// ignored), and the result is empty without `TIMESTAMP_QUERY`. Labels: the pass names of
    /// [`Pass`]'s `Display` on a CPU adapter, the nodes' timer labels
    /// otherwise.
    ///
    /// # Errors
    ///
    /// Those of [`encode`](Self::encode) and
    /// [`encode_step`](Self::encode_step), and [`Error::Readback`] when waiting
    /// for the device or reading the timestamps fails.
    pub fn run_timed<'o>(
        &mut self,
        gpu: &HeadlessGpu,
        output: impl Into<OutputTarget<'o>>,
        skip: &[Pass],
    ) -> Result<Vec<PassTime>> {
        let output = output.into();
        if gpu.adapter.get_info().device_type != wgpu::DeviceType::Cpu {
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            self.encode(&mut encoder, output)?;
            gpu.submit_and_wait(encoder)?;
            return self.read_timings(&gpu.device);
        }
        let steps = self.plan().steps.clone();
        let mut times = Vec::new();
        for (index, step) in steps.iter().enumerate() {
            if skip.contains(&step.pass) {
                continue;
            }
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            self.encode_step(&mut encoder, output, index)?;
            let start = std::time::Instant::now();
            gpu.submit_and_wait(encoder)?;
            times.push(PassTime {
                pass: step.pass,
                light: step.light,
                ms: start.elapsed().as_secs_f64() * 1e3,
            });
        }
        Ok(times)
    }

    /// The in-scatter each light added last frame (full resolution, `Rgba32Float`), for
    /// debugging and tests.
    pub fn inscatter(&self, light: usize) -> Option<&wgpu::Texture> {
        self.slots.get(light)?.inscatter(&self.plan, light)
    }

    /// The shadow map of `light` rendered by the last frame that planned one (`None` when
    /// none was, e.g. for a light without occluders), for shadowing surfaces with
    /// [`SHADOW_WGSL`](crate::SHADOW_WGSL): record the frame's shadow-map steps
    /// ([`encode_step`](Self::encode_step)) before the surfaces that sample it.
    pub fn shadow_map(&self, light: usize) -> Option<crate::nodes::ShadowMap<'_>> {
        let planned = self.plan.runs(Pass::ShadowMap, Some(light))
            || self.plan.skip_reason(Pass::ShadowMap, Some(light))
                == Some(&plan::Reason::Unchanged);
        planned
            .then(|| self.slots.get(light)?.shadow.shadow_map())
            .flatten()
    }

    /// March steps per pixel of a light's last march (`R32Uint`, at the march's resolution).
    pub fn step_counts(&self, light: usize) -> Option<&wgpu::Texture> {
        self.slots.get(light)?.march.step_counts()
    }
}

/// The least distance from a light to an occluder's world-space box (0 inside one, infinite
/// without occluders or for a directional light).
fn nearest_occluder(light: &Light, occluders: &[Occluder<'_>]) -> f32 {
    let Some(p) = light.position() else {
        return f32::INFINITY;
    };
    occluders
        .iter()
        .map(|o| {
            let (lo, hi) = o.world_bounds();
            p.clamp(lo, hi).distance(p)
        })
        .fold(f32::INFINITY, f32::min)
}

/// The light with radius 0.
fn without_radius(light: Light) -> Light {
    match light {
        Light::Point(l) => l.with_radius(0.0).map_or(light, Light::from),
        Light::Spot(l) => l.with_radius(0.0).map_or(light, Light::from),
        other => other,
    }
}

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
