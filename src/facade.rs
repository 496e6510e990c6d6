//! `VolumetricShadows`: owns the nodes, asks the planner what to run, records it.

use crate::error::{Error, Result};
use crate::frame::Frame;
use crate::gpu::headless::HeadlessGpu;
use crate::gpu::scope::validated;
use crate::gpu::{GpuTimer, Occluder, PassTime};
use crate::nodes::{
    AirlightTableNode, CompositeInputs, CompositeNode, CompositeSurfaces, CrossingsRequest,
    ExtentsInputs, ExtentsNode, IssTableNode, IssTableSize, LightTextureInput, LightTextureNode,
    MarchInputs, MarchNode, MarchSettings, OutputTarget, ShadowMapInputs, ShadowMapNode, Shadows,
    SoftShadowInputs, SoftShadowNode, TableInputs, UpsampleInputs, UpsampleNode, MAX_LIGHTS,
};
use crate::nodes::{Cache, Encode, LightKind, Node};
use crate::plan::{self, FrameReport, LightPlan, Pass, Plan};
use crate::scene::Light;
use crate::settings::{validate, Settings};

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
    /// What the plan decided for the light.
    planned: &'a LightPlan,
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

    /// Prepares this light's planned step `pass` from its light's plan (`step.planned`);
    /// returns whether it records work.
    fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        cache: &Cache,
        settings: &Settings,
        pass: Pass,
        step: &StepInputs<'_, '_>,
    ) -> Result<bool> {
        let (frame, occluders, i) = (step.frame, step.occluders, step.index);
        let (light, scale) = (&step.planned.light, step.planned.scale);
        let (camera, medium) = (frame.camera, frame.medium);
        let fl = &frame.lights[i];
        let (width, height) = (frame.scene_depth.width(), frame.scene_depth.height());
        Ok(match pass {
            Pass::LightTexture => match fl.texture {
                Some(texture) => {
                    let input = LightTextureInput {
                        texture,
                        channels: fl.texture_channels,
                    };
                    self.texture.prepare(device, queue, &input)?
                }
                None => false,
            },
            Pass::ShadowMap => self.prepare_shadow_map(device, queue, step)?,
            Pass::Extents => self.extents.prepare(
                device,
                queue,
                &ExtentsInputs {
                    camera,
                    light,
                    occluders,
                    size: scale.apply(width, height),
                    crossings: step.planned.shadows.is_some_and(|f| f.crossings).then_some(
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
            Pass::March => self.prepare_march(device, queue, settings, step)?,
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

    /// Prepares the light's shadow map: on demand ([`LightPlan::map_on_demand`]), with the
    /// crossing lists prepared by the extents step before it.
    fn prepare_shadow_map(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        step: &StepInputs<'_, '_>,
    ) -> Result<bool> {
        let light = &step.planned.light;
        let fallback = step
            .planned
            .map_on_demand
            .then(|| self.extents.extents()?.crossings)
            .flatten();
        if step.planned.map_on_demand && fallback.is_none() {
            return Err(Error::NotPrepared {
                reason: "the plan draws a shadow map on demand without crossing lists",
            });
        }
        let inputs = ShadowMapInputs {
            light,
            occluders: step.occluders,
            camera: step.frame.camera,
            fallback,
        };
        self.shadow.prepare(device, queue, &inputs)
    }

    /// Prepares the light's march at its planned scale and mode, with the shadow inputs the
    /// plan runs for it.
    fn prepare_march(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        settings: &Settings,
        step: &StepInputs<'_, '_>,
    ) -> Result<bool> {
        let (frame, i) = (step.frame, step.index);
        let (light, scale) = (&step.planned.light, step.planned.scale);
        let fl = &frame.lights[i];
        self.march.set_settings(MarchSettings {
            scale,
            ..settings.march
        })?;
        // The shadow inputs the plan gives the march, as their steps made them.
        let shadows = step.planned.shadows.and_then(|forms| {
            Some(Shadows {
                shadow_map: self.shadow.shadow_map()?,
                extents: forms.extents.then(|| self.extents.extents()).flatten(),
                soft: forms
                    .soft_grid
                    .then(|| self.soft.as_ref()?.output())
                    .flatten(),
            })
        });
        let inputs = MarchInputs {
            camera: frame.camera,
            light,
            medium: frame.medium,
            table: &self.table,
            scene_depth: frame.scene_depth,
            shadows,
            mode: step.planned.march,
            light_texture: fl.texture.and(self.texture.maps()),
        };
        self.march.prepare(device, queue, &inputs)
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
    /// What the last `prepare` found beside the plan.
    report: FrameReport,
    timer: Option<GpuTimer>,
    /// `None` when the last `prepare` succeeded and nothing dropped its frame since; otherwise
    /// why `encode` has nothing to record.
    unprepared: Option<&'static str>,
    /// The forms of the steps recorded since the settings last changed (see
    /// [`VolumetricShadows::is_first_frame`]).
    seen: std::collections::HashSet<StepShape>,
    /// Whether the last prepared frame has a step of a form not in `seen` before it.
    first_frame: bool,
    /// The prepared frame's light textures: inputs, so never the output.
    light_textures: Vec<wgpu::Texture>,
    /// The marches count their work ([`set_work_counters`](Self::set_work_counters)).
    work: bool,
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
        if device != cache.device() {
            return Err(Error::InvalidSetting {
                field: "cache",
                problem: "made for another device than the one passed".into(),
            });
        }
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
            report: FrameReport::default(),
            timer,
            unprepared: Some("no frame has been prepared yet"),
            seen: Default::default(),
            first_frame: false,
            light_textures: Vec::new(),
            work: false,
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
    ///   occluder's transform, [`Error::InvalidBuffer`] naming `occluder.mesh` for a mesh made
    ///   on another device;
    /// * [`Error::InvalidSetting`] naming `device` for another device than the facade's;
    ///   [`Error::Validation`] for a texture made on another device (wgpu's public API cannot
    ///   tell a texture's device, so `prepare` runs in a validation error scope and returns
    ///   what wgpu reports where it binds the texture, rather than `Ok` beside a validation
    ///   error; on native backends, where a scope's result is ready at once);
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
        if device != self.cache.device() {
            return Err(Error::InvalidSetting {
                field: "device",
                problem: "not the device the facade and its Cache were made for".into(),
            });
        }
        validated(device, "prepare", || {
            self.prepare_frame(device, queue, frame)
        })?;
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
        for o in frame.occluders {
            o.check_device(device)?;
        }
        self.light_textures = frame
            .lights
            .iter()
            .filter_map(|l| l.texture.cloned())
            .collect();
        while self.slots.len() < frame.lights.len() {
            let mut slot = LightSlot::new(device, &self.cache, &self.settings)?;
            slot.march.set_work_counters(self.work);
            self.slots.push(slot);
        }
        // The plan first (no GPU work), then exactly the planned steps.
        let plan = plan::plan_frame(frame, &self.settings)?;
        if plan.runs(Pass::IssTable, None) && self.iss.is_none() {
            let size = IssTableSize::default();
            self.iss = Some(IssTableNode::new(device, &self.cache, size)?);
        }
        let occluders: Vec<Vec<Occluder<'_>>> = plan
            .lights
            .iter()
            .map(|l| l.occluders.iter().map(|&j| frame.occluders[j]).collect())
            .collect();
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
                        planned: &plan.lights[i],
                        occluders: &occluders[i],
                        index: i,
                    };
                    let (cache, settings) = (&self.cache, &self.settings);
                    self.slots[i].prepare(device, queue, cache, settings, pass, &inputs)?
                }
            };
            if !work {
                unchanged.push(index);
            }
        }
        let reused = unchanged.iter().map(|&index| {
            let step: &crate::plan::Step = &plan.steps[index];
            (step.pass, step.light)
        });
        self.report = FrameReport {
            reused: reused.collect(),
        };
        let scatters = plan.scatters;
        self.plan = plan;
        let surface_term = self.prepare_composite(device, queue, frame, scatters)?;
        self.first_frame = self.note_forms(surface_term);
        Ok(())
    }

    /// The composite's inputs: each light's in-scatter (none where the medium does not
    /// scatter, as the plan says) and the surface term. Returns whether the
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
    fn note_forms(&mut self, surface_term: bool) -> bool {
        let plan = &self.plan;
        let mut first = false;
        for step in &plan.steps {
            let light = step.light.map(|i| {
                let planned = &plan.lights[i];
                let kind = planned.kind;
                let light = Some(i);
                let forms = [
                    plan.runs(Pass::ShadowMap, light),
                    plan.runs(Pass::Extents, light),
                    plan.runs(Pass::SoftShadow, light),
                    planned.scale == crate::nodes::Scale::Full,
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
    /// [`Error::InvalidTexture`] naming `output` when it is not such a texture;
    /// [`Error::Validation`] when it was made on another device (found by binding it in an
    /// encoder of the facade's own, never submitted; once per texture, so an engine's target
    /// is checked on its first frame and a swapchain's images each frame). See the
    /// [crate-level example](crate#example).
    pub fn encode<'o>(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        output: impl Into<OutputTarget<'o>>,
    ) -> Result<()> {
        let output = output.into();
        self.check_prepared()?;
        self.check_output(&output)?;
        let device = self.cache.device().clone();
        validated(&device, "encode", || {
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
        })
    }

    /// Records only step `index` of the plan (`plan().steps[index]`; nothing for a step the
    /// [`report`](Self::report) says reused last frame's result), untimed: for profilers
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
        if self.plan.steps[index].pass == Pass::Composite {
            self.check_output(&output)?;
        }
        let timer = self.timer.take();
        let device = self.cache.device().clone();
        let result = validated(&device, "encode", || self.record(encoder, &output, index));
        self.timer = timer;
        result
    }

    /// The composite's checks of `output`, and that it is none of the frame's light textures
    /// (which the composite does not read, but the frame does).
    fn check_output(&self, output: &OutputTarget<'_>) -> Result<()> {
        self.composite.check_output(output)?;
        if self.light_textures.contains(output.texture) {
            return Err(Error::InvalidTexture {
                field: "output",
                problem: "must not be one of the frame's light textures".into(),
            });
        }
        Ok(())
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
        if self.report.reused(step.pass, step.light) {
            return Ok(()); // last frame's result stands
        }
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
                _ => self.composite.encode_checked(encoder, output, timer),
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
            Pass::Composite => return self.composite.encode_checked(encoder, output, timer),
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

    /// The plan of the last `prepare`: what it decided.
    pub fn plan(&self) -> &Plan {
        &self.plan
    }

    /// What the last `prepare` found beside its plan: the planned steps whose node had
    /// nothing new to record, which reuse last frame's result (see [`FrameReport`]).
    pub fn report(&self) -> &FrameReport {
        &self.report
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

    /// The shadow map of `light` rendered by the last frame that planned one, for shadowing
    /// surfaces with [`SHADOW_WGSL`](crate::SHADOW_WGSL): record the frame's shadow-map steps
    /// ([`encode_step`](Self::encode_step)) before the surfaces that sample it. `None` when
    /// none was (a light without occluders), and when the map was drawn only on demand
    /// ([`LightPlan::map_on_demand`](crate::plan::LightPlan::map_on_demand)): set
    /// [`ShadowMapSettings::surfaces`](crate::nodes::ShadowMapSettings::surfaces) to keep
    /// every map whole.
    pub fn shadow_map(&self, light: usize) -> Option<crate::nodes::ShadowMap<'_>> {
        let on_demand = self.plan.lights.get(light)?.map_on_demand;
        (self.plan.runs(Pass::ShadowMap, Some(light)) && !on_demand)
            .then(|| self.slots.get(light)?.shadow.shadow_map())
            .flatten()
    }

    /// For benches and tests: a shadow map drawn on demand
    /// ([`LightPlan::map_on_demand`](crate::plan::LightPlan::map_on_demand)), whose texels are
    /// valid only where the march reads them, and two `u32` of its gate: whether it was drawn
    /// since its inputs last changed, and whether the last recorded frame drew it
    /// ([`ShadowMapNode::gate_state`](crate::nodes::ShadowMapNode::gate_state)). `None` for a
    /// map drawn whenever it changes.
    pub fn shadow_map_on_demand(
        &self,
        light: usize,
    ) -> Option<(crate::nodes::ShadowMap<'_>, &wgpu::Buffer)> {
        let shadow = &self.slots.get(light)?.shadow;
        Some((shadow.shadow_map()?, shadow.gate_state()?))
    }

    /// Turns every light's per-pixel march work counters on or off (default off; see
    /// [`MarchNode::set_work_counters`](crate::nodes::MarchNode::set_work_counters)), from the
    /// next `prepare`: for benches and tests. [`march_stats`](Self::march_stats) then holds
    /// them.
    pub fn set_work_counters(&mut self, on: bool) {
        self.work = on;
        for slot in &mut self.slots {
            slot.march.set_work_counters(on);
        }
    }

    /// March steps per pixel of a light's last march (`R32Uint`, at the march's resolution).
    pub fn step_counts(&self, light: usize) -> Option<&wgpu::Texture> {
        self.slots.get(light)?.march.step_counts()
    }

    /// What a light's last march met ([`MarchStats::from_bytes`](crate::nodes::MarchStats::from_bytes)
    /// reads it; see [`MarchNode::stats_buffer`]).
    pub fn march_stats(&self, light: usize) -> Option<&wgpu::Buffer> {
        Some(self.slots.get(light)?.march.stats_buffer())
    }

    /// The shadow volumes' extents of `light` in the last frame, when the plan has them.
    pub fn extents(&self, light: usize) -> Option<crate::nodes::Extents<'_>> {
        self.plan
            .runs(Pass::Extents, Some(light))
            .then(|| self.slots.get(light)?.extents.extents())
            .flatten()
    }
}
