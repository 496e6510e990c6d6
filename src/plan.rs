//! The planner: the one place that decides which passes a frame records and how, and says why
//! the others are left out. From the frame and the settings it gathers cheap facts (the
//! occluders left after culling, the lights drawn hard) and returns the steps, the skips and,
//! per light, a [`LightPlan`]: the light as drawn, its occluders, its resolution and its
//! march's [`MarchMode`]. The facade prepares exactly the planned steps from it; the plan is
//! what was decided and is not edited afterwards: the steps whose node found nothing changed
//! (last frame's result stands) are in a [`FrameReport`] beside it.

use std::fmt;

use crate::error::{Error, Result};
use crate::frame::Frame;
use crate::gpu::Occluder;
use crate::light::{LightKind, Source};
use crate::nodes::{MarchMethod, MarchMode, Scale, ShadowForms, ShadowMapNode, UpsampleFilter};
use crate::scene::Light;
use crate::settings::Settings;

pub use crate::pass::Pass;
pub use crate::settings::{
    error_table, for_error_target, AdapterKind, MeasuredConfig, ERROR_TABLE_CPU, ERROR_TABLE_GPU,
    ERROR_TARGET_MARGIN, ERROR_TARGET_TEXTURE_STEPS,
};

/// Why a pass is left out.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Reason {
    /// The light has no occluders (or all were culled): the airlight is analytic everywhere.
    NoOccluders,
    /// σs = 0 in every channel: the medium only attenuates.
    NoScattering,
    /// The light has no texture.
    Untextured,
    /// Scattering runs at the output resolution.
    FullResolution,
    /// Brute force (and the textbook march) marches the whole ray and needs no shadow-volume
    /// extents.
    BruteForce,
    /// Under an error target a textured spot's scattering runs at full resolution: its
    /// projected texture's detail does not survive reduced-resolution scattering.
    TexturedUnderErrorTarget,
    /// A directional light's airlight is in closed form (the scattering angle is the same
    /// along a ray): no F′ table is built.
    ClosedFormAirlight,
    /// No surface input (normals and albedo) was given: the light the medium scatters onto
    /// surfaces is not added.
    NoSurfaceInput,
    /// The light has no radius: its shadows are hard.
    HardLight,
    /// A light with a radius: the march bounds its penumbra by cones around the occluders'
    /// bounding spheres, not by the hard shadow's volumes.
    SoftLight,
    /// A light with a radius whose penumbrae are all narrower than a shadow-map texel
    /// ([`ShadowMapNode::penumbra_below_texel`](crate::nodes::ShadowMapNode::penumbra_below_texel)):
    /// drawn hard.
    PenumbraBelowTexel,
}

impl fmt::Display for Reason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Reason::NoOccluders => "no occluders: analytic airlight only",
            Reason::NoScattering => "the medium does not scatter (sigma_s = 0): attenuation only",
            Reason::Untextured => "the light is not textured",
            Reason::FullResolution => "scattering already at output resolution",
            Reason::BruteForce => "this method marches the whole ray",
            Reason::TexturedUnderErrorTarget => {
                "error target: a textured spot scatters at full resolution"
            }
            Reason::ClosedFormAirlight => "directional light: the airlight is in closed form",
            Reason::NoSurfaceInput => {
                "no surface normals and albedo given: no light scattered onto surfaces"
            }
            Reason::HardLight => "the light has no radius: hard shadows",
            Reason::SoftLight => {
                "the light has a radius: penumbra cones around the occluders bound the march"
            }
            Reason::PenumbraBelowTexel => {
                "the light's penumbrae are narrower than a shadow-map texel: hard shadows"
            }
        })
    }
}

/// One planned pass, for one light (or for the frame).
#[derive(Debug, Clone, PartialEq)]
pub struct Step {
    /// The pass.
    pub pass: Pass,
    /// The light it serves (`None`: the whole frame).
    pub light: Option<usize>,
    /// What it does, in words (method, steps, resolution).
    pub detail: String,
}

/// One pass left out, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct Skip {
    /// The pass.
    pub pass: Pass,
    /// The light it would have served (`None`: the whole frame).
    pub light: Option<usize>,
    /// Why it does not run.
    pub reason: Reason,
}

/// An occluder left out of one light's shadow map and extents because its shadow lies
/// optically so deep that removing it changes no pixel by more than the cull threshold.
#[derive(Debug, Clone, PartialEq)]
pub struct Culled {
    /// The light.
    pub light: usize,
    /// Index into the frame's occluders.
    pub occluder: usize,
    /// Upper bound of the occluder's effect, relative to the in-scatter of a ray reaching it.
    pub bound: f64,
}

/// What a frame records and why the rest is left out. `Display` prints it as a table.
///
/// Used in the [crate-level example](crate#example).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Plan {
    /// Passes that run, in recording order.
    pub steps: Vec<Step>,
    /// Passes left out.
    pub skipped: Vec<Skip>,
    /// Occluders culled per light.
    pub culled: Vec<Culled>,
    /// What was decided for each light of the frame, in the frame's order.
    pub lights: Vec<LightPlan>,
    /// The medium scatters (σs > 0 in some channel); otherwise the frame only attenuates and
    /// no light adds in-scatter.
    pub scatters: bool,
}

/// What the plan decided for one light: the nodes receive it rather than deciding again.
#[derive(Debug, Clone, PartialEq)]
pub struct LightPlan {
    /// The light as drawn: the frame's, without its radius when its penumbrae are narrower
    /// than a shadow-map texel ([`Reason::PenumbraBelowTexel`]).
    pub light: Light,
    /// The pipelines the light as drawn uses (a light drawn hard is not soft).
    pub kind: LightKind,
    /// Indices into the frame's occluders of those that shadow it (the rest are [`Culled`]).
    pub occluders: Vec<usize>,
    /// The resolution its scattering runs at.
    pub scale: Scale,
    /// How its march integrates each ray.
    pub march: MarchMode,
    /// The shadow inputs its march reads (`None`: unshadowed), which the shadow-map, extents
    /// and soft-shadow steps make: the extents' crossing lists among them.
    pub shadows: Option<ShadowForms>,
    /// Its shadow map is drawn only in a frame where a pixel's crossings cannot be counted
    /// (a list that overflowed, an open mesh's face), decided on the GPU
    /// ([`ShadowMapInputs::fallback`](crate::nodes::ShadowMapInputs::fallback)): the exact
    /// method for a light without a radius, unless
    /// [`ShadowMapSettings::surfaces`](crate::nodes::ShadowMapSettings::surfaces) keeps the
    /// maps whole. Its extents step runs before its shadow map.
    pub map_on_demand: bool,
}

impl Plan {
    /// Whether `pass` runs for `light`.
    pub fn runs(&self, pass: Pass, light: Option<usize>) -> bool {
        self.steps
            .iter()
            .any(|s| s.pass == pass && s.light == light)
    }
    /// How many passes of this kind run (over all lights).
    pub fn count(&self, pass: Pass) -> usize {
        self.steps.iter().filter(|s| s.pass == pass).count()
    }
    /// The reason `pass` is left out for `light`, if it is.
    pub fn skip_reason(&self, pass: Pass, light: Option<usize>) -> Option<&Reason> {
        self.skipped
            .iter()
            .find(|s| s.pass == pass && s.light == light)
            .map(|s| &s.reason)
    }
}

impl fmt::Display for Plan {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let who = |light: Option<usize>| match light {
            Some(i) => format!("light {i}"),
            None => "frame".to_string(),
        };
        for s in &self.steps {
            writeln!(
                f,
                "  run   {:<8} {:<14} {}",
                who(s.light),
                s.pass.to_string(),
                s.detail
            )?;
        }
        for s in &self.skipped {
            writeln!(
                f,
                "  skip  {:<8} {:<14} {}",
                who(s.light),
                s.pass.to_string(),
                s.reason
            )?;
        }
        for c in &self.culled {
            writeln!(
                f,
                "  cull  light {:<2} occluder {} (effect below {:.1e} of the in-scatter)",
                c.light, c.occluder, c.bound
            )?;
        }
        Ok(())
    }
}

/// What a prepared frame found beside its [`Plan`]: the planned steps whose node had nothing
/// new to record, its inputs unchanged since the last frame, so that last frame's result
/// stands (a shadow map, a table, a light texture, a soft-shadow grid). Recording such a step
/// records nothing. `Display` prints one line per step.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FrameReport {
    /// The reused steps (pass and light), in the plan's order.
    pub reused: Vec<(Pass, Option<usize>)>,
}

impl FrameReport {
    /// Whether the planned `pass` of `light` reused last frame's result.
    pub fn reused(&self, pass: Pass, light: Option<usize>) -> bool {
        self.reused.contains(&(pass, light))
    }
}

impl fmt::Display for FrameReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (pass, light) in &self.reused {
            let who = match light {
                Some(i) => format!("light {i}"),
                None => "frame".to_string(),
            };
            writeln!(
                f,
                "  reuse {who:<8} {:<14} unchanged since last frame",
                pass.to_string()
            )?;
        }
        Ok(())
    }
}

/// What the planner knows about one light this frame.
#[derive(Debug, Clone, PartialEq)]
struct LightFacts {
    /// The light as drawn.
    light: Light,
    textured: bool,
    /// Indices of the occluders left after culling.
    occluders: Vec<usize>,
    /// A light with a radius whose penumbrae are narrower than a shadow-map texel, drawn hard.
    penumbra_below_texel: bool,
    /// A point light's cube faces that its occluders' bounding spheres reach (+X, −X, +Y, −Y,
    /// +Z, −Z): the shadow map draws only those; the others stay clear and read lit.
    faces: Option<[bool; 6]>,
    /// A sun's shadow distance where the planner set it (the medium's shadow reach).
    sun_reach: Option<f32>,
}

/// What the planner knows about the frame.
#[derive(Debug, Clone, PartialEq)]
struct FrameFacts {
    scatters: bool,
    lights: Vec<LightFacts>,
    method: MarchMethod,
    steps: u32,
    /// Crossing list entries per pixel (exact method).
    crossings: u32,
    scale: Scale,
    filter: UpsampleFilter,
    culled: Vec<Culled>,
    error_target: Option<f32>,
    /// Surface normals and albedo were given (the indirect single scattering term).
    surfaces: bool,
    /// Every shadow map is kept whole for the caller's surfaces
    /// ([`ShadowMapSettings::surfaces`](crate::nodes::ShadowMapSettings::surfaces)).
    surface_maps: bool,
}

/// Plans `frame` under `settings`: gathers the facts (culling, lights drawn hard) and decides
/// the passes. Needs no GPU work.
///
/// # Errors
///
/// Those of [`Occluder::validate`] for an occluder's transform.
pub(crate) fn plan_frame(frame: &Frame<'_>, settings: &Settings) -> Result<Plan> {
    Ok(plan(&gather(frame, settings)?))
}

/// The frame's facts: each light's occluders after culling (those whose effect is provably
/// below the threshold stay out of its shadow map and extents), and the lights as drawn (one
/// whose penumbrae the shadow map cannot resolve, hard).
fn gather(frame: &Frame<'_>, settings: &Settings) -> Result<FrameFacts> {
    for o in frame.occluders {
        o.validate()?;
    }
    let mut culled = Vec::new();
    let mut lights = Vec::new();
    let eye = frame.camera.eye();
    for (i, fl) in frame.lights.iter().enumerate() {
        if let Some(&j) = fl
            .casters
            .and_then(|c| c.iter().find(|&&j| j >= frame.occluders.len()))
        {
            return Err(Error::InvalidSetting {
                field: "frame.lights.casters",
                problem: format!(
                    "light {i} names occluder {j}, but the frame has {}",
                    frame.occluders.len()
                ),
            });
        }
        let mut kept = Vec::new();
        for (j, o) in frame.occluders.iter().enumerate() {
            if fl.casters.is_some_and(|c| !c.contains(&j)) {
                continue;
            }
            let bound = occluder_bound(eye, &fl.light, frame.medium, o.world_bounds());
            if bound < f64::from(settings.cull_threshold) {
                culled.push(Culled {
                    light: i,
                    occluder: j,
                    bound,
                });
            } else {
                kept.push(j);
            }
        }
        let nearest = nearest_occluder(&fl.light, kept.iter().map(|&j| &frame.occluders[j]));
        let model = fl.light.model();
        let spheres: Vec<_> = kept
            .iter()
            .map(|&j| frame.occluders[j].world_sphere())
            .collect();
        let faces = model.layers_reached(&spheres);
        let penumbra_below_texel =
            ShadowMapNode::penumbra_below_texel(&fl.light, nearest, settings.shadow_map.resolution);
        let mut bounds = kept.iter().map(|&j| frame.occluders[j].world_bounds());
        let (light, sun_reach) = match model.within_reach(eye, frame.medium, &mut bounds) {
            Some((light, reach)) => (light, Some(reach)),
            None => (fl.light, None),
        };
        lights.push(LightFacts {
            light: if penumbra_below_texel {
                light.model().without_radius()
            } else {
                light
            },
            textured: fl.texture.is_some(),
            occluders: kept,
            penumbra_below_texel,
            faces,
            sun_reach,
        });
    }
    Ok(FrameFacts {
        scatters: frame.medium.sigma_s().max_element() > 0.0,
        lights,
        method: settings.march.method,
        steps: settings.march.steps,
        crossings: settings.march.crossings,
        scale: settings.march.scale,
        filter: settings.upsample,
        culled,
        error_target: settings.error_target,
        surfaces: frame.surfaces.is_some(),
        surface_maps: settings.shadow_map.surfaces,
    })
}

/// The least distance from a light to an occluder's world-space box (0 inside one, infinite
/// without occluders or for a directional light).
fn nearest_occluder<'o>(light: &Light, occluders: impl Iterator<Item = &'o Occluder<'o>>) -> f32 {
    let Some(p) = light.position() else {
        return f32::INFINITY;
    };
    occluders
        .map(|o| {
            let (lo, hi) = o.world_bounds();
            p.clamp(lo, hi).distance(p)
        })
        .fold(f32::INFINITY, f32::min)
}

/// The resolution a light's scattering runs at. Without shadows the analytic airlight is
/// exact and costs one lookup per pixel, so it runs at the output resolution; under an error
/// target a textured spot does too (measured by the report on the stained-glass scene: p95
/// 9–49% at ½ and ¼, where the lit fraction is upsampled and the texture's detail is lost).
fn light_scale(scale: Scale, shadowed: bool, textured: bool, error_target: Option<f32>) -> Scale {
    if !shadowed || (textured && error_target.is_some()) {
        Scale::Full
    } else {
        scale
    }
}

/// Decides the passes of a frame. The light texture, shadow map and table are planned whenever
/// they apply; the [`FrameReport`] says which of them had nothing new to record.
fn plan(facts: &FrameFacts) -> Plan {
    let mut d = Decisions::default();
    let mut lights = Vec::new();
    for (i, l) in facts.lights.iter().enumerate() {
        lights.push(plan_light(&mut d, facts, i, l));
    }
    if !facts.surfaces {
        d.skip(Pass::IssTable, None, Reason::NoSurfaceInput);
    } else if !facts.scatters {
        d.skip(Pass::IssTable, None, Reason::NoScattering);
    } else {
        d.run(Pass::IssTable, None, "rebuilt".into());
    }
    d.run(
        Pass::Composite,
        None,
        format!("{} light(s)", facts.lights.len()),
    );
    Plan {
        steps: d.steps,
        skipped: d.skipped,
        culled: facts.culled.clone(),
        lights,
        scatters: facts.scatters,
    }
}

/// The steps and skips of a plan, in the order they are decided.
#[derive(Default)]
struct Decisions {
    steps: Vec<Step>,
    skipped: Vec<Skip>,
}

impl Decisions {
    /// `pass` runs for `light`, doing `detail`.
    fn run(&mut self, pass: Pass, light: Option<usize>, detail: String) {
        self.steps.push(Step {
            pass,
            light,
            detail,
        })
    }

    /// `pass` is left out for `light`, for `reason`.
    fn skip(&mut self, pass: Pass, light: Option<usize>, reason: Reason) {
        self.skipped.push(Skip {
            pass,
            light,
            reason,
        })
    }
}

/// Decides light `i`'s passes (`l` its facts) into `d`; returns its plan.
fn plan_light(d: &mut Decisions, facts: &FrameFacts, i: usize, l: &LightFacts) -> LightPlan {
    let light = Some(i);
    let shadowed = !l.occluders.is_empty();
    let soft = l.light.radius() > 0.0;
    // Parallel rays: the scattering angle is the same along a ray, the airlight closed form.
    let closed_form = matches!(l.light.model().source(), Source::Along(_));
    let scale = light_scale(facts.scale, shadowed, l.textured, facts.error_target);
    // The shadow inputs the march gets (none where nothing scatters). The hybrid and the exact
    // method bound the marched interval: by the shadow volumes' extents (with crossing lists
    // for the exact method), or for a light with a radius by the penumbra cones of the
    // soft-shadow grid.
    let bounded = matches!(facts.method, MarchMethod::Hybrid | MarchMethod::Exact);
    let forms = (shadowed && facts.scatters).then_some(ShadowForms {
        extents: bounded && !soft,
        crossings: facts.method == MarchMethod::Exact,
        soft_grid: bounded && soft,
    });
    let mut light_plan = LightPlan {
        light: l.light,
        kind: l.light.model().kind(l.textured),
        occluders: l.occluders.clone(),
        scale,
        march: MarchMode::choose(facts.method, soft, forms),
        shadows: forms,
        map_on_demand: false,
    };
    if !facts.scatters {
        for pass in Pass::ALL
            .into_iter()
            .filter(|p| p.per_light() && p.needs_scattering())
        {
            d.skip(pass, light, Reason::NoScattering);
        }
        return light_plan;
    }
    if l.textured {
        d.run(
            Pass::LightTexture,
            light,
            "blurred mip chain and flat regions".into(),
        );
    } else {
        d.skip(Pass::LightTexture, light, Reason::Untextured);
    }
    match forms {
        None => {
            d.skip(Pass::ShadowMap, light, Reason::NoOccluders);
            d.skip(Pass::Extents, light, Reason::NoOccluders);
            d.skip(Pass::SoftShadow, light, Reason::NoOccluders);
        }
        Some(f) => light_plan.map_on_demand = plan_shadows(d, facts, i, l, f, scale),
    }
    if closed_form {
        d.skip(Pass::AirlightTable, light, Reason::ClosedFormAirlight);
    } else {
        d.run(Pass::AirlightTable, light, "rebuilt".into());
    }
    let method = march_detail(light_plan.march, forms, facts.steps);
    d.run(
        Pass::March,
        light,
        format!("{method}, at 1/{}", scale.divisor()),
    );
    if scale == Scale::Full && facts.scale != Scale::Full && shadowed && l.textured {
        d.skip(Pass::Upsample, light, Reason::TexturedUnderErrorTarget);
    } else if scale == Scale::Full {
        d.skip(Pass::Upsample, light, Reason::FullResolution);
    } else {
        d.run(Pass::Upsample, light, format!("{:?}", facts.filter));
    }
    light_plan
}

/// Decides the shadow passes of light `i` (`l` its facts), whose march gets the shadow inputs
/// `f` at `scale`: the extents, the shadow map and the soft-shadow grid. Returns whether the
/// map is drawn on demand ([`LightPlan::map_on_demand`]).
fn plan_shadows(
    d: &mut Decisions,
    facts: &FrameFacts,
    i: usize,
    l: &LightFacts,
    f: ShadowForms,
    scale: Scale,
) -> bool {
    let light = Some(i);
    let soft = l.light.radius() > 0.0;
    let count = l.occluders.len();
    let faces = map_layers_detail(l);
    // The crossings decide every pixel they can count: the map only the rest.
    let on_demand = f.extents && f.crossings && !facts.surface_maps;
    let at = scale.divisor();
    // Extents first: a map drawn on demand reads the crossing lists.
    if f.extents && f.crossings {
        let per_pixel = facts.crossings;
        let detail = format!("crossing lists of {per_pixel} per pixel, at 1/{at}");
        d.run(Pass::Extents, light, detail);
    } else if f.extents {
        d.run(Pass::Extents, light, format!("at 1/{at}"));
    } else if f.soft_grid {
        d.skip(Pass::Extents, light, Reason::SoftLight);
    } else {
        d.skip(Pass::Extents, light, Reason::BruteForce);
    }
    let demand = if on_demand {
        "; drawn only in a frame where a pixel's crossings cannot be counted \
         (a full list, an open mesh), decided on the GPU"
    } else {
        ""
    };
    d.run(
        Pass::ShadowMap,
        light,
        format!("{count} occluder(s){faces}{demand}"),
    );
    if f.soft_grid {
        let detail = "visible fraction of the light's disc on a light-space grid";
        d.run(Pass::SoftShadow, light, detail.into());
    } else if l.penumbra_below_texel {
        d.skip(Pass::SoftShadow, light, Reason::PenumbraBelowTexel);
    } else if !soft {
        d.skip(Pass::SoftShadow, light, Reason::HardLight);
    } else {
        d.skip(Pass::SoftShadow, light, Reason::BruteForce);
    }
    on_demand
}

/// The shadow map's layers in words, for its step's detail: a point light's cube faces drawn,
/// or where a sun's cascades stop at the medium's shadow reach (empty otherwise).
fn map_layers_detail(l: &LightFacts) -> String {
    match l.faces {
        Some(faces) => {
            const NAMES: [&str; 6] = ["+X", "-X", "+Y", "-Y", "+Z", "-Z"];
            let drawn: Vec<&str> = NAMES
                .iter()
                .zip(faces)
                .filter_map(|(n, f)| f.then_some(*n))
                .collect();
            format!(
                ", cube faces {} ({} without occluders not drawn)",
                drawn.join(" "),
                6 - drawn.len()
            )
        }
        None => match l.sun_reach {
            Some(d) => format!(
                ", cascades to {d:.4} from the eye (the medium's shadow reach; the \
                 occluders reach farther)"
            ),
            None => String::new(),
        },
    }
}

/// The march's method in words, for its step's detail: `mode` with the shadow inputs `forms`
/// and `steps` steps.
fn march_detail(mode: MarchMode, forms: Option<ShadowForms>, steps: u32) -> String {
    match mode {
        MarchMode::Analytic => "analytic".to_string(),
        MarchMode::Hybrid if forms.is_some_and(|f| f.soft_grid) => format!(
            "penumbra cones marched through the soft-shadow grid (half a step a cell, at most {steps})"
        ),
        MarchMode::Hybrid => format!("hybrid, {steps} steps"),
        MarchMode::BruteForce => format!("brute force, {steps} steps"),
        MarchMode::Exact => {
            format!("exact between crossings, overflowing pixels marched with {steps} steps")
        }
        MarchMode::Textbook => format!("textbook march, {steps} steps"),
    }
}

/// Upper bound of how much an occluder with world `bounds` can change the in-scatter of any
/// pixel, relative to the unshadowed in-scatter of a ray that reaches it: the light's own
/// ([`LightModel::cull_bound`](crate::light::LightModel::cull_bound)); ∞ where no bound applies
/// (a spot light, whose cone may exclude the segment that bound needs; a directional light).
pub(crate) fn occluder_bound(
    eye: glam::Vec3,
    light: &crate::scene::Light,
    medium: &crate::scene::Medium,
    bounds: (glam::Vec3, glam::Vec3),
) -> f64 {
    light.model().cull_bound(eye, medium, bounds)
}

#[cfg(test)]
mod tests {
    use super::{occluder_bound, plan, FrameFacts, LightFacts, LightPlan, Pass};
    use crate::nodes::{MarchMethod, MarchMode, Scale, UpsampleFilter};
    use crate::scene::{Light, Medium, PhaseFunction, PointLight};
    use glam::Vec3;

    /// A light's radius widens where an occluder can shadow: an occluder far to the side of a
    /// point light in thick fog is culled at the default threshold (1e-3), the same occluder
    /// under a light of radius 7 is not, and once the light reaches within `2R` of its bounds
    /// no bound applies (the point light's bound would cull a penumbra).
    #[test]
    fn a_radius_loosens_the_cull_bound() {
        let medium = Medium::new(Vec3::splat(1.0), Vec3::ZERO, PhaseFunction::Isotropic).unwrap();
        let eye = Vec3::new(0.0, 0.0, 10.0);
        let bounds = (Vec3::new(-0.5, 19.5, -0.5), Vec3::new(0.5, 20.5, 0.5)); // r = 19.5
        let point = PointLight::new(Vec3::ZERO, Vec3::ONE).unwrap();
        let bound = |radius: f32| {
            let light = Light::from(point.with_radius(radius).unwrap());
            occluder_bound(eye, &light, &medium, bounds)
        };
        let (hard, soft, reaching) = (bound(0.0), bound(7.0), bound(9.75));
        eprintln!("cull bounds: radius 0 {hard:e}, 7 {soft:e}, 9.75 {reaching:e}");
        assert!(hard < 1e-3 && soft > 1e-3, "{hard} {soft}");
        assert_eq!(reaching, f64::INFINITY);
    }

    /// A sun over occluders that reach beyond the medium's shadow reach gets it as its shadow
    /// distance; within it, or with a distance of its own, or a medium that does not attenuate
    /// in some channel, it keeps what it had; a point light is untouched.
    #[test]
    fn a_suns_shadow_distance_is_bounded_by_the_mediums_reach() {
        use crate::scene::DirectionalLight;
        let medium = Medium::new(
            Vec3::splat(0.1),
            Vec3::splat(0.01),
            PhaseFunction::Isotropic,
        )
        .unwrap();
        let reach = medium.shadow_reach().unwrap();
        assert!((reach - 1e6f32.ln() / 0.11).abs() < 1e-3 * reach, "{reach}");
        let eye = Vec3::new(0.0, 1.6, 5.5);
        let sun = DirectionalLight::new(Vec3::new(0.3, -1.0, 0.2), Vec3::ONE).unwrap();
        let huge = (Vec3::new(-1e5, -0.3, -1e5), Vec3::new(1e5, -0.1, 1e5));
        let small = (Vec3::splat(-1.0), Vec3::splat(1.0));
        let distance = |light: Light| match light {
            Light::Directional(d) => d.shadow_distance(),
            _ => None,
        };
        let within = |light: Light, bounds: &[(Vec3, Vec3)], medium: &Medium| {
            let mut bounds = bounds.iter().copied();
            match light.model().within_reach(eye, medium, &mut bounds) {
                Some((fitted, reach)) => {
                    assert_eq!(distance(fitted), Some(reach));
                    fitted
                }
                None => light,
            }
        };
        let planned = |light, bounds: &[(Vec3, Vec3)], medium: &Medium| {
            distance(within(light, bounds, medium))
        };
        assert_eq!(planned(sun.into(), &[small, huge], &medium), Some(reach));
        assert_eq!(planned(sun.into(), &[small], &medium), None);
        let own = sun.with_shadow_distance(5e4).unwrap();
        assert_eq!(planned(own.into(), &[huge], &medium), Some(5e4));
        let clear_red = Medium::new(
            Vec3::new(0.0, 0.1, 0.1),
            Vec3::ZERO,
            PhaseFunction::Isotropic,
        )
        .unwrap();
        assert_eq!(planned(sun.into(), &[huge], &clear_red), None);
        let point: Light = PointLight::new(Vec3::ZERO, Vec3::ONE).unwrap().into();
        assert_eq!(within(point, &[huge], &medium), point);
        // The plan says so on the shadow map's step.
        let facts = FrameFacts {
            scatters: true,
            lights: vec![LightFacts {
                light: sun.with_shadow_distance(reach).unwrap().into(),
                textured: false,
                occluders: vec![0],
                penumbra_below_texel: false,
                faces: None,
                sun_reach: Some(reach),
            }],
            method: MarchMethod::Exact,
            steps: 64,
            crossings: 16,
            scale: Scale::Full,
            filter: UpsampleFilter::DepthAware3x3,
            culled: Vec::new(),
            error_target: None,
            surfaces: false,
            surface_maps: false,
        };
        let text = plan(&facts).to_string();
        assert!(text.contains("the medium's shadow reach"), "{text}");
    }

    /// Every light a frame can have, under every method: the march's mode in the plan reads
    /// only what the plan runs (the exact mode its crossing lists, the hybrid its extents or,
    /// for a light with a radius, its soft-shadow grid, the shadowed modes a shadow map), and
    /// the printed march step names that mode. A planner whose steps and march disagree fails
    /// here: one that runs the soft-shadow grid for the hybrid method only, while the exact
    /// method's march still reads it, was measured to.
    #[test]
    fn the_march_mode_reads_only_what_the_plan_runs() {
        let point = PointLight::new(Vec3::ZERO, Vec3::ONE).unwrap();
        let mut cases = 0;
        for method in [
            MarchMethod::Exact,
            MarchMethod::Hybrid,
            MarchMethod::BruteForce,
            MarchMethod::Textbook,
        ] {
            for (radius, penumbra_below_texel) in [(0.0, false), (0.0, true), (0.5, false)] {
                for occluders in [vec![], vec![0, 2]] {
                    let light = Light::from(point.with_radius(radius).unwrap());
                    let facts = FrameFacts {
                        scatters: true,
                        lights: vec![LightFacts {
                            light,
                            textured: false,
                            occluders,
                            penumbra_below_texel,
                            faces: None,
                            sun_reach: None,
                        }],
                        method,
                        steps: 64,
                        crossings: 16,
                        scale: Scale::Half,
                        filter: UpsampleFilter::DepthAware3x3,
                        culled: Vec::new(),
                        error_target: None,
                        surfaces: false,
                        surface_maps: false,
                    };
                    let plan = plan(&facts);
                    let LightPlan { march, .. } = plan.lights[0];
                    let runs = |pass| plan.runs(pass, Some(0));
                    let case = format!("{method:?}, radius {radius}, plan:\n{plan}");
                    let reads = match march {
                        MarchMode::Analytic => !runs(Pass::ShadowMap),
                        MarchMode::Textbook => method == MarchMethod::Textbook,
                        MarchMode::BruteForce => runs(Pass::ShadowMap),
                        MarchMode::Exact => runs(Pass::Extents) && method == MarchMethod::Exact,
                        MarchMode::Hybrid => {
                            runs(Pass::ShadowMap)
                                && (runs(Pass::Extents) || (radius > 0.0 && runs(Pass::SoftShadow)))
                        }
                    };
                    assert!(reads, "{march:?} reads what the plan does not run: {case}");
                    let step = plan.steps.iter().find(|s| s.pass == Pass::March).unwrap();
                    let named = match march {
                        MarchMode::Hybrid if runs(Pass::SoftShadow) => "penumbra cones",
                        MarchMode::Exact => "exact between crossings",
                        other => &other.to_string(),
                    };
                    assert!(step.detail.starts_with(named), "{named}: {case}");
                    cases += 1;
                }
            }
        }
        assert_eq!(cases, 24);
    }
}
