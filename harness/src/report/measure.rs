//! Measuring: every configuration of a scene, its per-pass GPU times (median of the timed
//! frames) and its image, and the sweeps' stop rule.

use std::collections::BTreeMap;
use std::path::Path;
use std::time::{Duration, Instant};

use volshadow::glam::{DVec3, Vec3};
use volshadow::nodes::{MarchMethod, MarchSettings, Scale};
use volshadow::plan::Pass;
use volshadow::scene_file::SceneDescription;
use volshadow::{
    AdapterKind, Cache, DirectionalLight, Frame, FrameLight, HeadlessGpu, Light, PointLight,
    Settings, SpotLight, Surfaces, VolumetricShadows,
};

use super::cache::cached_reference;
use super::metrics::{errors, keep_mask};
use super::render_scene::GpuScene;
use super::ERROR_TABLE_SIZE;
use super::{read_inscatter, BoxError, Check, Curve, Filter, Options, Row, Verdict};
use super::{HardTwin, FIXED_PASSES, REFINE, SWEEP_STOP_P95, TOLERANCES};

/// A step sweep's stop rule (see the module docs).
#[derive(Debug, Clone, Default)]
pub struct Sweep {
    previous: Option<f64>,
    stopped: bool,
}

impl Sweep {
    /// Records a point; true (and says why) when the sweep stops after it.
    pub fn stops(&mut self, ctx: &Context, curve: Curve, steps: u32, p95: f64) -> bool {
        let converged = self.previous.is_some_and(|p| p95 > 0.9 * p);
        self.previous = Some(p95);
        if p95 < SWEEP_STOP_P95 || converged {
            ctx.progress(&format!(
                "  {} stops at {steps} steps: p95 {:.3}% {}",
                curve.name(),
                100.0 * p95,
                if p95 < SWEEP_STOP_P95 {
                    "is below the stop threshold"
                } else {
                    "no longer improves by 10% per doubling"
                }
            ));
            self.stopped = true;
        }
        self.stopped
    }
}

/// How passes are timed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Clock {
    /// Each pass submitted alone, wall clock around submit-and-wait (CPU adapters).
    WallPerPass,
    /// Timestamp queries.
    Timestamps,
}

pub struct Context<'a> {
    pub gpu: &'a HeadlessGpu,
    pub cache: Cache,
    pub frames: usize,
    pub start: Instant,
    /// What is left to do, for the estimate of the time left.
    pub progress: Eta,
}

impl Context<'_> {
    /// A progress line, to stderr.
    pub fn progress(&self, text: &str) {
        eprintln!("[{:7.1} s] {text}", self.start.elapsed().as_secs_f64());
    }
}

/// The estimate of the time left: the configurations still to measure, at the pace of those
/// measured so far, plus the scenes still to set up (the app's frame, the passes timed once per
/// scene) and the references still to compute, each at the mean time of those done (both kept
/// out of the configurations' pace). A step sweep stops early (unless `--full`): a sweep not
/// finished is expected to run the share of its steps that the finished sweeps ran (half
/// before one has finished).
#[derive(Debug)]
pub struct Eta {
    state: std::cell::RefCell<EtaState>,
}

#[derive(Debug)]
struct EtaState {
    start: Instant,
    /// Configurations measured.
    done: usize,
    /// Planned configurations outside the sweeps, not measured yet.
    fixed_left: usize,
    /// The planned steps of the sweeps not finished, and the configurations they measured.
    open_steps: usize,
    open_ran: usize,
    /// The planned steps of the finished sweeps, and the configurations they measured.
    finished_steps: usize,
    finished_ran: usize,
    /// The share of its steps a sweep is expected to run before one has finished.
    prior: f64,
    references_left: usize,
    references_done: usize,
    reference_time: Duration,
    setups_left: usize,
    setups_done: usize,
    setup_time: Duration,
}

impl Eta {
    /// `full`: the sweeps run every step.
    pub fn new(full: bool) -> Self {
        Self {
            state: std::cell::RefCell::new(EtaState {
                start: Instant::now(),
                done: 0,
                fixed_left: 0,
                open_steps: 0,
                open_ran: 0,
                finished_steps: 0,
                finished_ran: 0,
                prior: if full { 1.0 } else { 0.5 },
                references_left: 0,
                references_done: 0,
                reference_time: Duration::ZERO,
                setups_left: 0,
                setups_done: 0,
                setup_time: Duration::ZERO,
            }),
        }
    }

    /// Adds a scene: its planned configurations, and whether its reference is to compute.
    pub fn plan(&self, planned: &Planned, reference: bool) {
        let mut s = self.state.borrow_mut();
        s.fixed_left += planned.fixed;
        s.open_steps += planned.sweeps.iter().sum::<usize>();
        s.references_left += usize::from(reference);
        s.setups_left += 1;
    }

    /// One configuration measured (`sweep`: a step of a sweep).
    pub fn measured(&self, sweep: bool) {
        let mut s = self.state.borrow_mut();
        s.done += 1;
        if sweep {
            s.open_ran += 1;
        } else {
            s.fixed_left = s.fixed_left.saturating_sub(1);
        }
    }

    /// A planned configuration outside the sweeps that will not be measured.
    pub fn fixed_skipped(&self) {
        let mut s = self.state.borrow_mut();
        s.fixed_left = s.fixed_left.saturating_sub(1);
    }

    /// A sweep of `steps` planned steps finished after measuring `ran` of them.
    pub fn sweep_done(&self, steps: usize, ran: usize) {
        let mut s = self.state.borrow_mut();
        s.open_steps = s.open_steps.saturating_sub(steps);
        s.open_ran = s.open_ran.saturating_sub(ran);
        s.finished_steps += steps;
        s.finished_ran += ran;
    }

    /// A scene set up in `time` (after its reference, before its first configuration).
    pub fn setup_done(&self, time: Duration) {
        let mut s = self.state.borrow_mut();
        s.setups_left = s.setups_left.saturating_sub(1);
        s.setups_done += 1;
        s.setup_time += time;
    }

    /// A reference computed in `time`.
    pub fn reference_done(&self, time: Duration) {
        let mut s = self.state.borrow_mut();
        s.references_left = s.references_left.saturating_sub(1);
        s.references_done += 1;
        s.reference_time += time;
    }

    /// `configuration k of about n, about T left`.
    pub fn line(&self) -> String {
        let s = self.state.borrow();
        let share = if s.finished_steps > 0 {
            s.finished_ran as f64 / s.finished_steps as f64
        } else {
            s.prior
        };
        let configurations_left =
            s.fixed_left as f64 + (s.open_steps as f64 * share - s.open_ran as f64).max(0.0);
        let elapsed = s
            .start
            .elapsed()
            .saturating_sub(s.reference_time + s.setup_time);
        let mut left =
            (s.done > 0).then(|| elapsed.as_secs_f64() / s.done as f64 * configurations_left);
        let mut unknown = Vec::new();
        for (what, count, done, time) in [
            (
                "scene(s) to set up",
                s.setups_left,
                s.setups_done,
                s.setup_time,
            ),
            (
                "reference(s) to compute",
                s.references_left,
                s.references_done,
                s.reference_time,
            ),
        ] {
            if count == 0 {
                continue;
            }
            if done > 0 {
                let mean = time.as_secs_f64() / done as f64;
                left = left.map(|l| l + mean * count as f64);
            } else {
                unknown.push(format!("{count} {what}"));
            }
        }
        let mut text = format!(
            "configuration {} of about {}",
            s.done,
            s.done + configurations_left.round() as usize
        );
        match left {
            Some(left) => text.push_str(&format!(", about {} left", duration(left))),
            None => text.push_str(", time left: estimating"),
        }
        if !unknown.is_empty() {
            text.push_str(&format!(" + {}", unknown.join(" + ")));
        }
        text
    }
}

/// `42 s`, `3 min 05 s`, `1 h 02 min`.
fn duration(seconds: f64) -> String {
    let s = seconds.max(0.0).round() as u64;
    match s {
        0..=59 => format!("{s} s"),
        60..=3599 => format!("{} min {:02} s", s / 60, s % 60),
        _ => format!("{} h {:02} min", s / 3600, s / 60 % 60),
    }
}

/// The step counts of the brute-force, paper-003 and textbook sweeps.
fn brute_sweep(options: &Options) -> Vec<u32> {
    if options.quick {
        vec![16, 32]
    } else {
        vec![16, 32, 64, 128, 256, 512, 1024]
    }
}

/// The hybrid's step counts, scales and bisections.
fn hybrid_sweep(options: &Options) -> (Vec<u32>, Vec<Scale>, Vec<u32>) {
    if options.quick {
        (
            vec![8, 32],
            vec![Scale::Full, Scale::Quarter],
            vec![0, REFINE],
        )
    } else {
        (
            vec![8, 16, 32, 64, 128, 256],
            vec![Scale::Full, Scale::Half, Scale::Quarter],
            vec![0, REFINE],
        )
    }
}

/// The upsampling filters run at `scale` by the exact method (`hybrid: false`) or the hybrid.
fn filters(scale: Scale, hybrid: bool) -> Vec<Filter> {
    match (scale, hybrid) {
        (Scale::Full, _) => vec![Filter::None],
        (_, false) => vec![Filter::Box3, Filter::Separable],
        (_, true) => vec![Filter::Box3, Filter::Separable, Filter::Bilinear],
    }
}

/// What [`run_scene`] measures on a scene when no sweep stops early: the configurations
/// outside the step sweeps, and each sweep's step count.
#[derive(Debug, Clone, PartialEq)]
pub struct Planned {
    pub fixed: usize,
    pub sweeps: Vec<usize>,
}

/// What [`run_scene`] plans to measure on `scene`: what the estimate of the time left starts
/// from.
pub fn planned_configurations(options: &Options, scene: &SceneDescription) -> Planned {
    if scene.lights.iter().any(|l| l.light.radius() > 0.0) {
        // The floor, four grid configurations (each with its hard twin), brute force.
        return Planned {
            fixed: 6,
            sweeps: Vec::new(),
        };
    }
    let exact: usize = [Scale::Full, Scale::Half, Scale::Quarter]
        .into_iter()
        .map(|s| filters(s, false).len())
        .sum();
    // Brute force, paper 003 and the textbook march; the hybrid's curves.
    let mut sweeps = vec![brute_sweep(options).len(); 3];
    let (steps, scales, refines) = hybrid_sweep(options);
    for _ in &refines {
        for &scale in &scales {
            sweeps.extend(filters(scale, true).iter().map(|_| steps.len()));
        }
    }
    Planned {
        fixed: 1 + exact + TOLERANCES.len(),
        sweeps,
    }
}

/// Everything measured on one scene.
pub fn run_scene(
    ctx: &Context,
    options: &Options,
    path: &Path,
    scene: &SceneDescription,
) -> Result<(Vec<Row>, Vec<Check>), BoxError> {
    let size = (options.size, options.size);
    let camera = if scene.size.0 == scene.size.1 {
        scene.camera
    } else {
        super::with_aspect(&scene.camera, 1.0)?
    };
    let reference = cached_reference(ctx, options, path, scene, &camera, size)?;
    let setup = Instant::now();
    let keep = keep_mask(scene, &camera, size);
    // Every configuration marches a textured spot's lit parts with the error target's budget,
    // the one its table was measured with.
    let texture_steps = volshadow::plan::ERROR_TARGET_TEXTURE_STEPS;

    let gpu_scene = GpuScene::new(ctx.gpu, scene, &camera, size, true)?;
    let output = gpu_scene.output(ctx.gpu);
    let view = &output;
    let lights = gpu_scene.lights();
    let occluders = gpu_scene.occluders();
    let shadowed = gpu_scene.frame(&lights, &occluders);
    let unshadowed = gpu_scene.frame(&lights, &[]);
    let mut facade: Option<VolumetricShadows> = None;
    let mut measure = |settings: Settings, frame: &Frame, reuse: bool| {
        measure(ctx, &mut facade, settings, frame, view, reuse)
    };
    let base = Settings {
        output_format: wgpu::TextureFormat::Rgba32Float,
        cull_threshold: 0.0,
        ..Settings::default()
    };
    let settings = |method, steps, scale, filter: Filter, bisections| Settings {
        march: MarchSettings {
            method,
            steps,
            bisections,
            scale,
            texture_steps,
            ..MarchSettings::default()
        },
        upsample: filter.upsample(),
        ..base
    };

    // Passes whose work does not depend on the configuration (F′ table, shadow map,
    // composite): timed once per scene, in frames in which the light moves.
    let fixed = time_fixed(
        ctx,
        settings(MarchMethod::Hybrid, 8, Scale::Full, Filter::None, 0),
        &shadowed,
        view,
    )?;
    let floor_fixed = time_fixed(
        ctx,
        settings(MarchMethod::Hybrid, 8, Scale::Full, Filter::None, 0),
        &unshadowed,
        view,
    )?;

    // The light the medium scatters onto surfaces: the same frame with the app's normals and
    // albedo, at the default settings, against it without them (not for a light with a radius: its
    // march alone takes seconds a frame here).
    if scene.lights.iter().all(|l| l.light.radius() == 0.0) {
        let surfaces = Frame {
            surfaces: Some(Surfaces {
                normal: &gpu_scene.app.normal,
                albedo: &gpu_scene.app.albedo,
            }),
            ..shadowed
        };
        surface_term_cost(ctx, base, &surfaces, &shadowed, view)?;
    }

    ctx.progress.setup_done(setup.elapsed());
    let rows = std::cell::RefCell::new(Vec::<Row>::new());
    let record = |curve: Curve,
                  settings: &Settings,
                  mut passes: BTreeMap<&'static str, f64>,
                  image: &[DVec3],
                  fixed: &BTreeMap<&'static str, f64>|
     -> Row {
        for (pass, ms) in fixed {
            passes.insert(pass, *ms);
        }
        let errors = errors(image, &reference, &keep);
        let scale = settings.march.scale;
        let row = Row {
            scene: scene.name.clone(),
            textured: scene.lights.iter().any(|l| l.texture.is_some()),
            soft: scene.lights.iter().any(|l| l.light.radius() > 0.0),
            curve,
            steps: if curve == Curve::Analytic {
                0
            } else {
                settings.march.steps
            },
            scale: scale.divisor(),
            filter: Filter::of(settings.upsample, scale),
            bisections: settings.march.bisections,
            total_ms: passes.values().sum(),
            passes,
            hard: None,
            errors,
        };
        // A step of a sweep (hard shadows: brute force, paper 003, textbook, hybrid).
        let sweep = !row.soft
            && matches!(
                curve,
                Curve::Brute | Curve::Paper003 | Curve::Textbook | Curve::Hybrid(..)
            );
        ctx.progress.measured(sweep);
        ctx.progress(&format!(
            "  {:<42} {:>5} steps  {:>9.1} ms  p95 {:>7.3}%  p99 {:>7.3}%  RMSE {:>7.3}%  [{}]",
            curve.name(),
            row.steps,
            row.total_ms,
            100.0 * errors.p95,
            100.0 * errors.p99,
            100.0 * errors.rmse,
            ctx.progress.line()
        ));
        rows.borrow_mut().push(row.clone());
        row
    };

    // The floor.
    let s = settings(MarchMethod::Hybrid, 8, Scale::Full, Filter::None, 0);
    let (passes, image) = measure(s, &unshadowed, false)?;
    record(Curve::Analytic, &s, passes, &image, &floor_fixed);

    // A light with a radius: the exact method and the hybrid (which read the soft-shadow grid)
    // at full resolution and at the defaults' reduced ones, and brute force (which estimates
    // every step from the shadow map, the grid's own estimator); each grid configuration
    // also on the same scene with radius 0, for the cost of soft over hard shadows at equal
    // settings. The hard sweeps and the error target do not apply.
    if scene.lights.iter().any(|l| l.light.radius() > 0.0) {
        let mut hard_scene = scene.clone();
        for l in &mut hard_scene.lights {
            l.light = match l.light {
                Light::Point(p) => Light::Point(p.with_radius(0.0)?),
                Light::Spot(p) => Light::Spot(p.with_radius(0.0)?),
                other => other,
            };
        }
        let hard_gpu = GpuScene::new(ctx.gpu, &hard_scene, &camera, size, true)?;
        let (hard_lights, hard_occluders) = (hard_gpu.lights(), hard_gpu.occluders());
        let hard = hard_gpu.frame(&hard_lights, &hard_occluders);
        for (method, curve, scale, filter) in [
            (
                MarchMethod::Exact,
                Curve::Exact(1, Filter::None),
                Scale::Full,
                Filter::None,
            ),
            (
                MarchMethod::Exact,
                Curve::Exact(2, Filter::Box3),
                Scale::Half,
                Filter::Box3,
            ),
            (
                MarchMethod::Hybrid,
                Curve::Hybrid(1, Filter::None, 0),
                Scale::Full,
                Filter::None,
            ),
            (
                MarchMethod::Hybrid,
                Curve::Hybrid(4, Filter::Box3, 0),
                Scale::Quarter,
                Filter::Box3,
            ),
        ] {
            let s = settings(method, 64, scale, filter, 0);
            let (passes, image) = measure(s, &shadowed, false)?;
            let soft_row = record(curve, &s, passes, &image, &fixed);
            let (cost, hard_image) = soft_against_hard(ctx, s, &shadowed, &hard, view)?;
            let twin = HardTwin {
                p95: errors(&hard_image, &reference, &keep).p95,
                ..cost
            };
            ctx.progress(&format!(
                "  soft vs hard shadows, {}: {:.1} ms vs {:.1} ms ({:.2}x; light static {:.2}x)",
                soft_row.curve.name(),
                twin.soft_ms,
                twin.hard_ms,
                twin.moving,
                twin.fixed_light
            ));
            if let Some(last) = rows.borrow_mut().last_mut() {
                last.hard = Some(twin);
            }
        }
        let s = settings(MarchMethod::BruteForce, 16, Scale::Full, Filter::None, 0);
        let (passes, image) = measure(s, &shadowed, false)?;
        record(Curve::Brute, &s, passes, &image, &fixed);
        return Ok((rows.into_inner(), Vec::new()));
    }

    // Brute force, and paper 003's configuration.
    let sweep = brute_sweep(options);
    for (curve, method, scale, filter) in [
        (
            Curve::Brute,
            MarchMethod::BruteForce,
            Scale::Full,
            Filter::None,
        ),
        (
            Curve::Paper003,
            MarchMethod::BruteForce,
            Scale::Quarter,
            Filter::Separable,
        ),
        (
            Curve::Textbook,
            MarchMethod::Textbook,
            Scale::Full,
            Filter::None,
        ),
    ] {
        let mut sweep_state = Sweep::default();
        let mut ran = 0;
        for &steps in &sweep {
            let s = settings(method, steps, scale, filter, 0);
            let (passes, image) = measure(s, &shadowed, false)?;
            let p95 = record(curve, &s, passes, &image, &fixed).errors.p95;
            ran += 1;
            if !options.full && sweep_state.stops(ctx, curve, steps, p95) {
                break;
            }
        }
        ctx.progress.sweep_done(sweep.len(), ran);
    }

    // The exact method: no steps (they only march pixels whose crossing list overflowed).
    for scale in [Scale::Full, Scale::Half, Scale::Quarter] {
        let filters = filters(scale, false);
        let mut march_passes: Option<BTreeMap<&'static str, f64>> = None;
        for filter in filters {
            let s = settings(MarchMethod::Exact, 64, scale, filter, REFINE);
            let (mut passes, image) = measure(s, &shadowed, march_passes.is_some())?;
            share_march(&mut passes, &mut march_passes);
            record(
                Curve::Exact(scale.divisor(), filter),
                &s,
                passes,
                &image,
                &fixed,
            );
        }
    }

    // The hybrid.
    let (steps_list, scales, refines) = hybrid_sweep(options);
    for &bisections in &refines {
        for &scale in &scales {
            let filters = filters(scale, true);
            let mut sweeps = vec![Sweep::default(); filters.len()];
            let mut ran = vec![0; filters.len()];
            for &steps in &steps_list {
                let mut march_passes: Option<BTreeMap<&'static str, f64>> = None;
                for ((&filter, sweep_state), ran) in filters.iter().zip(&mut sweeps).zip(&mut ran) {
                    if sweep_state.stopped {
                        continue;
                    }
                    let s = settings(MarchMethod::Hybrid, steps, scale, filter, bisections);
                    let (mut passes, image) = measure(s, &shadowed, march_passes.is_some())?;
                    share_march(&mut passes, &mut march_passes);
                    let curve = Curve::Hybrid(scale.divisor(), filter, bisections);
                    let p95 = record(curve, &s, passes, &image, &fixed).errors.p95;
                    *ran += 1;
                    if !options.full {
                        sweep_state.stops(ctx, curve, steps, p95);
                    }
                }
                if sweeps.iter().all(|s| s.stopped) {
                    break;
                }
            }
            for ran in ran {
                ctx.progress.sweep_done(steps_list.len(), ran);
            }
        }
    }

    // The error target.
    let mut checks = Vec::new();
    for tolerance in TOLERANCES {
        let target = match Settings::for_error_target(tolerance, AdapterKind::of(&ctx.gpu.device)) {
            Ok(target) => target,
            Err(e) => {
                ctx.progress(&format!("  error target {:.0}%: {e}", 100.0 * tolerance));
                checks.push(Check {
                    scene: scene.name.clone(),
                    tolerance,
                    p95: f64::INFINITY,
                    size: options.size,
                });
                ctx.progress.fixed_skipped();
                continue;
            }
        };
        let s = Settings {
            output_format: base.output_format,
            cull_threshold: base.cull_threshold,
            ..target
        };
        let curve = Curve::Target((tolerance * 1000.0).round() as u32);
        // The configuration the plan actually runs (a textured spot scatters at full
        // resolution under an error target); a sweep may have measured it already.
        let plan = VolumetricShadows::new(&ctx.gpu.device, &ctx.gpu.queue, &ctx.cache, s)?
            .prepare(&ctx.gpu.device, &ctx.gpu.queue, &shadowed)?
            .clone();
        let scale = if plan.count(Pass::Upsample) == 0 {
            Scale::Full
        } else {
            s.march.scale
        };
        let exact = s.march.method == MarchMethod::Exact;
        let same = |r: &&Row| {
            (if exact {
                matches!(r.curve, Curve::Exact(..))
            } else {
                matches!(r.curve, Curve::Hybrid(..))
            }) && r.steps == s.march.steps
                && r.scale == scale.divisor()
                && r.filter == Filter::of(s.upsample, scale)
                && r.bisections == s.march.bisections
        };
        let measured = rows.borrow().iter().find(same).cloned();
        let row = match measured {
            Some(r) => {
                ctx.progress.measured(false);
                ctx.progress(&format!(
                    "  error target {:.0}%: the plan runs {} {} steps, measured above",
                    100.0 * tolerance,
                    r.curve.name(),
                    r.steps
                ));
                let row = Row { curve, ..r };
                rows.borrow_mut().push(row.clone());
                row
            }
            None => {
                let (passes, image) = measure(s, &shadowed, false)?;
                record(curve, &s, passes, &image, &fixed)
            }
        };
        let check = Check {
            scene: scene.name.clone(),
            tolerance,
            p95: row.errors.p95,
            size: options.size,
        };
        ctx.progress(&format!(
            "  error target {:.0}%: p95 {:.3}% {}",
            100.0 * tolerance,
            100.0 * row.errors.p95,
            match check.verdict() {
                Verdict::Pass => "meets it".to_string(),
                Verdict::Fail => "MISSES it".to_string(),
                Verdict::NotJudged => format!(
                    "(not judged: the table was built at {ERROR_TABLE_SIZE}x{ERROR_TABLE_SIZE})"
                ),
            }
        ));
        checks.push(check);
    }
    Ok((rows.into_inner(), checks))
}

/// One configuration: a warm-up frame (whose image is measured), then `frames` timed frames;
/// the median per pass. With `reuse_march` the march and extents are not recorded (the
/// previous configuration's march output, from identical inputs, is upsampled again).
pub fn measure(
    ctx: &Context,
    facade: &mut Option<VolumetricShadows>,
    settings: Settings,
    frame: &Frame,
    view: &wgpu::Texture,
    reuse_march: bool,
) -> Result<(BTreeMap<&'static str, f64>, Vec<DVec3>), BoxError> {
    let volumetric = match facade.as_mut() {
        Some(v) if reuse_march => {
            v.set_settings(settings)?;
            v
        }
        _ => facade.insert(VolumetricShadows::new(
            &ctx.gpu.device,
            &ctx.gpu.queue,
            &ctx.cache,
            settings,
        )?),
    };
    // The composite is timed per scene ([`time_fixed`]); the error is read before it.
    let skip: &[Pass] = if reuse_march {
        &[Pass::March, Pass::Extents, Pass::Composite]
    } else {
        &[Pass::Composite]
    };
    let mut samples: BTreeMap<&'static str, Vec<f64>> = BTreeMap::new();
    let mut image = Vec::new();
    for index in 0..=ctx.frames {
        let times = run_frame(ctx, volumetric, frame, view, skip)?;
        if index == 0 {
            image = read_inscatter(ctx.gpu, volumetric, frame)?;
            continue;
        }
        for (pass, ms) in times {
            // Passes that ran only in the first frame (table, shadow map, soft-shadow grid,
            // light texture) are timed apart.
            if !matches!(
                pass,
                "F' table" | "shadow map" | "soft shadow" | "light texture"
            ) {
                samples.entry(pass).or_default().push(ms);
            }
        }
    }
    let medians = samples
        .into_iter()
        .map(|(pass, mut v)| (pass, median(&mut v)))
        .collect();
    Ok((medians, image))
}

/// `lights`, each moved by a hundred-thousandth of its distance from the origin (at least
/// 1e-5): a frame between it and the original is one in which the light moved, so every
/// pass that depends on the light runs, and no resource is recreated (as when a light moves
/// in an app; [`VolumetricShadows::invalidate`] also recreates them, and a new grid is set
/// lit everywhere before its first build).
pub fn moved_lights<'a>(lights: &[FrameLight<'a>]) -> Result<Vec<FrameLight<'a>>, BoxError> {
    lights
        .iter()
        .map(|l| {
            let nudge = |p: Vec3| p + Vec3::splat(1e-5 * p.length().max(1.0));
            let light = match l.light {
                Light::Point(p) => Light::Point(
                    PointLight::new(nudge(p.position()), p.intensity())?.with_radius(p.radius())?,
                ),
                Light::Spot(s) => Light::Spot(
                    SpotLight::new(
                        nudge(s.position()),
                        s.direction(),
                        s.cone_angle(),
                        s.intensity(),
                    )?
                    .with_radius(s.radius())?,
                ),
                Light::Directional(d) => {
                    let moved =
                        DirectionalLight::new(nudge(d.direction()).normalize(), d.irradiance())?;
                    Light::Directional(match d.shadow_distance() {
                        Some(distance) => moved.with_shadow_distance(distance)?,
                        None => moved,
                    })
                }
                other => other,
            };
            Ok(FrameLight { light, ..*l })
        })
        .collect()
}

/// Times `settings` on a soft frame and its hard twin in the same rounds (see [`HardTwin`]):
/// every pass of both, the light moving every frame ([`moved_lights`]), one soft frame then
/// one hard frame a round,
/// `2 · frames + 1` rounds after a warm-up round; each pass's median over the rounds.
/// Returns the costs (p95 left 0) and the hard image.
fn soft_against_hard(
    ctx: &Context,
    settings: Settings,
    soft: &Frame,
    hard: &Frame,
    view: &wgpu::Texture,
) -> Result<(HardTwin, Vec<DVec3>), BoxError> {
    let new = || VolumetricShadows::new(&ctx.gpu.device, &ctx.gpu.queue, &ctx.cache, settings);
    let (soft_moved, hard_moved) = (moved_lights(soft.lights)?, moved_lights(hard.lights)?);
    let moved = [
        Frame {
            lights: &soft_moved,
            ..*soft
        },
        Frame {
            lights: &hard_moved,
            ..*hard
        },
    ];
    let mut runs = [(new()?, soft), (new()?, hard)];
    let mut samples: [BTreeMap<&'static str, Vec<f64>>; 2] = Default::default();
    let mut hard_image = Vec::new();
    for index in 0..=2 * ctx.frames + 1 {
        for (k, (facade, frame)) in runs.iter_mut().enumerate() {
            // The light moves every frame, between the frame's and a moved copy.
            let frame = if index % 2 == 1 { &moved[k] } else { *frame };
            let times = run_frame(ctx, facade, frame, view, &[])?;
            if index == 0 {
                if k == 1 {
                    hard_image = read_inscatter(ctx.gpu, facade, frame)?;
                }
                continue;
            }
            for (pass, ms) in times {
                samples[k].entry(pass).or_default().push(ms);
            }
        }
    }
    // The whole frame (light moving), and less the shadow map and the grid (light static).
    let [(soft_ms, soft_static), (hard_ms, hard_static)] = samples.map(|passes| {
        passes
            .into_iter()
            .fold((0.0, 0.0), |(all, fixed), (pass, mut v)| {
                let ms = median(&mut v);
                let rebuilt = matches!(pass, "shadow map" | "soft shadow");
                (all + ms, if rebuilt { fixed } else { fixed + ms })
            })
    });
    Ok((
        HardTwin {
            soft_ms,
            hard_ms,
            moving: soft_ms / hard_ms.max(1e-9),
            fixed_light: soft_static / hard_static.max(1e-9),
            p95: 0.0,
        },
        hard_image,
    ))
}

/// Times the passes that are the same for every configuration of a scene (F′ table, shadow
/// map, soft-shadow grid, composite), median of `frames` frames in which the light moves
/// ([`moved_lights`]).
pub fn time_fixed(
    ctx: &Context,
    settings: Settings,
    frame: &Frame,
    view: &wgpu::Texture,
) -> Result<BTreeMap<&'static str, f64>, BoxError> {
    let mut volumetric =
        VolumetricShadows::new(&ctx.gpu.device, &ctx.gpu.queue, &ctx.cache, settings)?;
    let mut samples: BTreeMap<&'static str, Vec<f64>> = BTreeMap::new();
    let lights = moved_lights(frame.lights)?;
    let moved = Frame {
        lights: &lights,
        ..*frame
    };
    for index in 0..=ctx.frames {
        // The light moves every frame, between the frame's and a moved copy.
        let frame = if index % 2 == 1 { &moved } else { frame };
        // The march and what feeds it do not change these passes' work: left out (the
        // composite reads an in-scatter texture of the same size either way).
        let times = run_frame(
            ctx,
            &mut volumetric,
            frame,
            view,
            &[Pass::Extents, Pass::March, Pass::Upsample],
        )?;
        if index == 0 {
            continue;
        }
        for (pass, ms) in times {
            if FIXED_PASSES.contains(&pass) {
                samples.entry(pass).or_default().push(ms);
            }
        }
    }
    Ok(samples
        .into_iter()
        .map(|(pass, mut v)| (pass, median(&mut v)))
        .collect())
}

/// Prints the cost of the light scattered onto surfaces: the ISS table's build (first frame;
/// later frames reuse it until the phase function changes), and the composite's and the whole
/// frame's time with the term against without it, medians of `frames` frames after the first.
fn surface_term_cost(
    ctx: &Context,
    settings: Settings,
    with: &Frame,
    without: &Frame,
    view: &wgpu::Texture,
) -> Result<(), BoxError> {
    // [frame, composite] medians, with and without the term.
    let mut medians = [[0.0; 2]; 2];
    let mut table_ms = 0.0;
    for (k, frame) in [with, without].into_iter().enumerate() {
        let mut volumetric =
            VolumetricShadows::new(&ctx.gpu.device, &ctx.gpu.queue, &ctx.cache, settings)?;
        let (mut frame_ms, mut composite_ms) = (Vec::new(), Vec::new());
        for index in 0..=ctx.frames {
            let times = run_frame(ctx, &mut volumetric, frame, view, &[])?;
            let pass = |name: &str| -> f64 {
                times
                    .iter()
                    .filter(|(p, _)| *p == name)
                    .map(|(_, ms)| ms)
                    .sum()
            };
            if index == 0 {
                if k == 0 {
                    table_ms = pass(Pass::IssTable.name());
                }
                continue;
            }
            frame_ms.push(times.iter().map(|(_, ms)| ms).sum::<f64>());
            composite_ms.push(pass(Pass::Composite.name()));
        }
        medians[k] = [median(&mut frame_ms), median(&mut composite_ms)];
    }
    let [[with_ms, with_composite], [without_ms, without_composite]] = medians;
    ctx.progress(&format!(
        "  surface term (default settings): ISS table {table_ms:.1} ms once (rebuilt only when \
         the phase function changes); composite {with_composite:.2} ms with the term vs \
         {without_composite:.2} ms without ({:+.1}% of the {with_ms:.1} ms frame; whole frames \
         {with_ms:.1} vs {without_ms:.1} ms)",
        100.0 * (with_composite - without_composite) / with_ms.max(1e-9)
    ));
    Ok(())
}

/// Prepares and runs one frame, leaving out the `skip` passes (on a CPU adapter); the time of
/// each pass run, by report column.
pub fn run_frame(
    ctx: &Context,
    volumetric: &mut VolumetricShadows,
    frame: &Frame,
    view: &wgpu::Texture,
    skip: &[Pass],
) -> Result<Vec<(&'static str, f64)>, BoxError> {
    volumetric.prepare(&ctx.gpu.device, &ctx.gpu.queue, frame)?;
    let mut times: Vec<(&'static str, f64)> = Vec::new();
    for t in volumetric.run_timed(ctx.gpu, view, skip)? {
        let column = t.pass.name();
        match times.iter_mut().find(|(c, _)| *c == column) {
            Some((_, ms)) => *ms += t.ms,
            None => times.push((column, t.ms)),
        }
    }
    Ok(times)
}

pub fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n == 0 {
        0.0
    } else if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    }
}

/// Filters after the first of one march reuse its march and extents: the first measurement
/// keeps their times in `shared`, the later ones take them from it.
pub fn share_march(
    passes: &mut BTreeMap<&'static str, f64>,
    shared: &mut Option<BTreeMap<&'static str, f64>>,
) {
    match shared {
        Some(times) => passes.extend(times.iter().map(|(k, v)| (*k, *v))),
        None => {
            *shared = Some(
                passes
                    .iter()
                    .filter(|(k, _)| matches!(**k, "march" | "extents"))
                    .map(|(k, v)| (*k, *v))
                    .collect(),
            )
        }
    }
}
