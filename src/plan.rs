//! The planner: the one place that decides which passes a frame records, and says why the
//! others are left out. It plans from cheap facts (lights, occluders left after culling,
//! settings); the facade then prepares exactly the planned steps, and the steps whose node
//! found nothing changed are left out as [`Reason::Unchanged`].

use std::fmt;

use crate::error::{Error, Result};
use crate::nodes::{MarchMethod, Scale, UpsampleFilter};

pub use crate::pass::Pass;

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
    /// Nothing it depends on changed since the last frame; last frame's result is reused.
    Unchanged,
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
            Reason::Unchanged => "unchanged since last frame",
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
    /// The scattering resolution of each light.
    pub(crate) scales: Vec<Scale>,
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
    /// The scattering resolution of `light` (full for a light the plan does not know).
    pub(crate) fn scale(&self, light: usize) -> Scale {
        self.scales.get(light).copied().unwrap_or_default()
    }
    /// Leaves out the steps at `indices` (ascending), whose nodes found nothing changed.
    pub(crate) fn unchanged(&mut self, indices: &[usize]) {
        for &index in indices.iter().rev() {
            let step = self.steps.remove(index);
            self.skipped.push(Skip {
                pass: step.pass,
                light: step.light,
                reason: Reason::Unchanged,
            });
        }
        // Per light (the frame's last), in pipeline order.
        self.skipped
            .sort_by_key(|s| (s.light.unwrap_or(usize::MAX), s.pass as u8));
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

/// What the planner knows about one light this frame.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct LightFacts {
    pub textured: bool,
    /// Occluders left after culling.
    pub occluders: usize,
    /// A directional light (no F′ table).
    pub directional: bool,
    /// A light with a radius (soft shadows).
    pub soft: bool,
    /// A light with a radius whose penumbrae are narrower than a shadow-map texel, drawn hard
    /// (`soft` is then false).
    pub penumbra_below_texel: bool,
}

/// What the planner knows about the frame.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct FrameFacts {
    pub scatters: bool,
    pub lights: Vec<LightFacts>,
    pub method: MarchMethod,
    pub steps: u32,
    /// Crossing list entries per pixel (exact method).
    pub crossings: u32,
    pub scale: Scale,
    pub filter: UpsampleFilter,
    pub culled: Vec<Culled>,
    pub error_target: Option<f32>,
    /// Surface normals and albedo were given (the indirect single scattering term).
    pub surfaces: bool,
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
/// they apply; [`Plan::unchanged`] leaves them out when their node has nothing new to record.
pub(crate) fn plan(facts: &FrameFacts) -> Plan {
    let mut plan = Plan {
        culled: facts.culled.clone(),
        ..Plan::default()
    };
    let mut run = |pass, light, detail: String| {
        plan.steps.push(Step {
            pass,
            light,
            detail,
        })
    };
    let mut skips = Vec::new();
    let mut skip = |pass, light, reason| {
        skips.push(Skip {
            pass,
            light,
            reason,
        })
    };
    for (i, l) in facts.lights.iter().enumerate() {
        let light = Some(i);
        let shadowed = l.occluders > 0;
        let scale = light_scale(facts.scale, shadowed, l.textured, facts.error_target);
        plan.scales.push(scale);
        if !facts.scatters {
            for pass in [
                Pass::LightTexture,
                Pass::ShadowMap,
                Pass::Extents,
                Pass::SoftShadow,
                Pass::AirlightTable,
                Pass::March,
                Pass::Upsample,
            ] {
                skip(pass, light, Reason::NoScattering);
            }
            continue;
        }
        if l.textured {
            run(Pass::LightTexture, light, "blurred mip chain".into());
        } else {
            skip(Pass::LightTexture, light, Reason::Untextured);
        }
        if !shadowed {
            skip(Pass::ShadowMap, light, Reason::NoOccluders);
            skip(Pass::Extents, light, Reason::NoOccluders);
            skip(Pass::SoftShadow, light, Reason::NoOccluders);
        } else {
            run(
                Pass::ShadowMap,
                light,
                format!("{} occluder(s)", l.occluders),
            );
            if l.soft && matches!(facts.method, MarchMethod::Hybrid | MarchMethod::Exact) {
                skip(Pass::Extents, light, Reason::SoftLight);
            } else if facts.method == MarchMethod::Hybrid {
                run(Pass::Extents, light, format!("at 1/{}", scale.divisor()));
            } else if facts.method == MarchMethod::Exact {
                run(
                    Pass::Extents,
                    light,
                    format!(
                        "crossing lists of {} per pixel, at 1/{}",
                        facts.crossings,
                        scale.divisor()
                    ),
                );
            } else {
                skip(Pass::Extents, light, Reason::BruteForce);
            }
            if l.penumbra_below_texel {
                skip(Pass::SoftShadow, light, Reason::PenumbraBelowTexel);
            } else if !l.soft {
                skip(Pass::SoftShadow, light, Reason::HardLight);
            } else if matches!(facts.method, MarchMethod::Hybrid | MarchMethod::Exact) {
                run(
                    Pass::SoftShadow,
                    light,
                    "visible fraction of the light's disc on a light-space grid".into(),
                );
            } else {
                skip(Pass::SoftShadow, light, Reason::BruteForce);
            }
        }
        if l.directional {
            skip(Pass::AirlightTable, light, Reason::ClosedFormAirlight);
        } else {
            run(Pass::AirlightTable, light, "rebuilt".into());
        }
        let method = match (shadowed, facts.method) {
            (false, _) => "analytic".to_string(),
            (true, MarchMethod::Hybrid | MarchMethod::Exact) if l.soft => format!(
                "penumbra cones marched through the soft-shadow grid (half a step a cell, at most {})",
                facts.steps
            ),
            (true, MarchMethod::Hybrid) => format!("hybrid, {} steps", facts.steps),
            (true, MarchMethod::BruteForce) => format!("brute force, {} steps", facts.steps),
            (true, MarchMethod::Exact) => format!(
                "exact between crossings, overflowing pixels marched with {} steps",
                facts.steps
            ),
            (_, MarchMethod::Textbook) => format!("textbook march, {} steps", facts.steps),
        };
        run(
            Pass::March,
            light,
            format!("{method}, at 1/{}", scale.divisor()),
        );
        if scale == Scale::Full && facts.scale != Scale::Full && shadowed && l.textured {
            skip(Pass::Upsample, light, Reason::TexturedUnderErrorTarget);
        } else if scale == Scale::Full {
            skip(Pass::Upsample, light, Reason::FullResolution);
        } else {
            run(Pass::Upsample, light, format!("{:?}", facts.filter));
        }
    }
    if !facts.surfaces {
        skip(Pass::IssTable, None, Reason::NoSurfaceInput);
    } else if !facts.scatters {
        skip(Pass::IssTable, None, Reason::NoScattering);
    } else {
        run(Pass::IssTable, None, "rebuilt".into());
    }
    run(
        Pass::Composite,
        None,
        format!("{} light(s)", facts.lights.len()),
    );
    plan.skipped = skips;
    plan
}

/// Upper bound of how much an occluder can change the in-scatter of any pixel, relative to the
/// unshadowed in-scatter of a ray that reaches it: every point it shadows is at
/// least `r` from the light and `e` from the eye, so its loss is at most
/// `σs·p_max·I0·exp(−σt (r + e))·π/r`, while the first `l = min(e, D)/2` of that ray gather at
/// least `l·σs·p_min·I0·exp(−σt (D + 2l))/(D + l)²`. Returns ∞ when no bound applies (the eye or
/// the light inside the occluder's bounds, a spot light whose cone may exclude that segment).
/// For a light of radius `R` a point it partially shadows is beyond the occluder on a line from
/// a point of the light, so at least `r − 2R` from the centre: `r` is reduced by `2R` (∞ when
/// that leaves nothing).
pub(crate) fn occluder_bound(
    eye: glam::Vec3,
    light: &crate::scene::Light,
    medium: &crate::scene::Medium,
    bounds: (glam::Vec3, glam::Vec3),
) -> f64 {
    if !matches!(light, crate::scene::Light::Point(_)) {
        return f64::INFINITY;
    }
    let Some(p) = light.position() else {
        return f64::INFINITY;
    };
    let r = f64::from(p.clamp(bounds.0, bounds.1).distance(p)) - 2.0 * f64::from(light.radius());
    let e = f64::from(eye.clamp(bounds.0, bounds.1).distance(eye));
    let d = f64::from(p.distance(eye));
    if r <= 0.0 || e <= 0.0 || d <= 0.0 {
        return f64::INFINITY;
    }
    let l = 0.5 * e.min(d);
    let (p_min, p_max) = medium.phase().range();
    let sigma_s = medium.sigma_s();
    let sigma_t = medium.sigma_t();
    (0..3)
        .filter(|&c| sigma_s[c] > 0.0)
        .map(|c| {
            let log = (f64::from(p_max[c]) / f64::from(p_min[c])).ln()
                + (std::f64::consts::PI / r).ln()
                + 2.0 * (d + l).ln()
                - l.ln()
                - f64::from(sigma_t[c]) * (r + e - d - 2.0 * l);
            log.exp()
        })
        .fold(0.0, f64::max)
}

/// A configuration the error target can pick, with what the report
/// (`cargo run --release --example report -- --scenes all`, at 512×512) measured for it on the
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

#[cfg(test)]
mod tests {
    use super::occluder_bound;
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
}
