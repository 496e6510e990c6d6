//! The `report` example: error against GPU time for every method and setting on the standard
//! scenes (DESIGN §6).
//!
//! ```text
//! report [--scenes a,b,…] [--size N] [--frames N] [--out DIR] [--full] [--quick]
//! ```
//!
//! For each scene file (default: every `scenes/*.json`) at `N × N` (default 512) it renders
//! * the **analytic floor**: the same frame without occluders (unshadowed airlight);
//! * **brute force** at 16, 32, …, 1024 steps (full resolution);
//! * **paper 003**'s configuration: brute force at ¼ resolution with the separable bilateral;
//! * the **hybrid** at 8 … 256 steps × scattering at full, ½ and ¼ resolution × upsampling
//!   bilinear (depth-blind: "none") / depth-aware 3×3 / separable × refinement (2 bisections)
//!   off / on;
//! * the **error-target** settings ([`Settings::for_error_target`]) for p95 5%, 2% and 1%,
//!   each checked against its tolerance.
//!
//! Timing: per pass, median of `--frames` (default 5) frames after a warm-up frame (which is
//! also the frame whose error is measured). On a CPU adapter (lavapipe) each pass is submitted
//! on its own and timed by the wall clock — there the "GPU" is the CPU running the submission,
//! and lavapipe's timestamps do not bracket compute dispatches; elsewhere by timestamp queries
//! when the device has them. The passes whose work is the same for every configuration — F′
//! table, shadow map, composite — are timed once per scene, in frames in which everything is
//! rebuilt, and counted in every configuration's total, as in a frame where the camera and the
//! light moved; a configuration's total is the sum of its passes' medians. At reduced
//! resolution the filters share one march, timed once.
//!
//! Error: against the f64 reference (cached on disk under `OUT/cache`, keyed by a hash of the
//! scene file, the size and the reference's source), over every pixel but a light's own
//! (within 1.5 pixels of its centre, where the in-scatter is singular): RMSE relative to the
//! mean in-scatter, and the 95th and 99th percentile of the per-pixel relative error
//! `max_c |gpu_c − ref_c| / max_c ref_c` over pixels whose reference is above 1% of the
//! image's 99th-percentile brightness (not its maximum: with a light in view that lies in the
//! light's glow, and only the glow would count).
//!
//! Every sweep of step counts (brute force, paper 003, each hybrid curve) stops once its p95
//! is below [`SWEEP_STOP_P95`] or no longer improves by 10% per doubling, unless `--full`:
//! beyond that point its cost only grows and no comparison the report makes reads it.
//!
//! Writes `OUT/report.md`, `OUT/report.csv`, `OUT/error_vs_time.svg` and
//! `OUT/error_table.rs` (the measured table the planner's error target is built from) to `OUT`
//! (default `target/volshadow-report`). `--quick` runs a few configurations only (the test).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use volshadow::glam::DVec3;
use volshadow::nodes::{MarchMethod, MarchSettings, Scale, UpsampleFilter};
use volshadow::plan::Pass;
use volshadow::reference::{camera_ray, pixel_ndc};
use volshadow::scene_file::SceneDescription;
use volshadow::{Cache, Frame, HeadlessGpu, Settings, VolumetricShadows};

use super::render_scene::{reference_inscatter, GpuScene};
use super::{read_inscatter, BoxError};

/// The command line, for error messages.
pub const USAGE: &str =
    "usage: report [--scenes a,b,...] [--size N] [--frames N] [--out DIR] [--full] [--quick]";

/// A step sweep stops once its p95 relative error is below this (half the tightest tolerance
/// the report checks).
pub const SWEEP_STOP_P95: f64 = 0.005;

/// The tolerances (p95 relative error) the error-target check runs.
pub const TOLERANCES: [f32; 3] = [0.05, 0.02, 0.01];

/// Bisections of "refinement on".
const REFINE: u32 = 2;

/// The separable filter of seed paper 003 as the report runs it.
const SEPARABLE: UpsampleFilter = UpsampleFilter::Separable {
    taps: 7,
    sigma_spatial: 1.5,
    sigma_depth: 0.05,
};

/// Parsed command line.
#[derive(Debug, Clone)]
pub struct Options {
    /// Scene files.
    pub scenes: Vec<PathBuf>,
    /// Image width and height.
    pub size: u32,
    /// Timed frames per configuration (after one warm-up frame).
    pub frames: usize,
    /// Output directory.
    pub out: PathBuf,
    /// Run every step count of the sweeps.
    pub full: bool,
    /// A few configurations only.
    pub quick: bool,
}

impl Options {
    /// Parses the arguments after the program name.
    pub fn parse(args: &[String]) -> Result<Self, BoxError> {
        let mut options = Options {
            scenes: Vec::new(),
            size: 512,
            frames: 5,
            out: PathBuf::from("target/volshadow-report"),
            full: false,
            quick: false,
        };
        let mut it = args.iter();
        while let Some(arg) = it.next() {
            let mut value = |flag: &str| {
                it.next()
                    .ok_or_else(|| -> BoxError { format!("{flag} needs a value\n{USAGE}").into() })
            };
            let number = |flag: &str, text: &str| -> Result<u32, BoxError> {
                match text.parse::<u32>() {
                    Ok(n) if n > 0 => Ok(n),
                    _ => {
                        Err(format!("{flag} must be a positive whole number, got {text:?}").into())
                    }
                }
            };
            match arg.as_str() {
                "--scenes" => {
                    options.scenes = value(arg)?
                        .split(',')
                        .map(|name| {
                            let path = PathBuf::from(name);
                            if path.extension().is_some() {
                                path
                            } else {
                                Path::new("scenes").join(format!("{name}.json"))
                            }
                        })
                        .collect()
                }
                "--size" => options.size = number(arg, value(arg)?)?,
                "--frames" => options.frames = number(arg, value(arg)?)? as usize,
                "--out" => options.out = PathBuf::from(value(arg)?),
                "--full" => options.full = true,
                "--quick" => options.quick = true,
                "-h" | "--help" => return Err(USAGE.into()),
                other => return Err(format!("unknown argument {other:?}\n{USAGE}").into()),
            }
        }
        if options.scenes.is_empty() {
            let mut scenes: Vec<PathBuf> = std::fs::read_dir("scenes")
                .map_err(|e| format!("cannot list scenes/: {e} (run from the crate root)"))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|e| e == "json"))
                .collect();
            scenes.sort();
            options.scenes = scenes;
        }
        Ok(options)
    }
}

/// A plotted method: one curve of the plot, one group of the table.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Curve {
    /// No occluders: the unshadowed airlight (one point).
    Analytic,
    /// Brute force at full resolution.
    Brute,
    /// Brute force at ¼ resolution with the separable bilateral (seed paper 003).
    Paper003,
    /// The hybrid: scale divisor, filter, bisections.
    Hybrid(u32, Filter, u32),
    /// The exact method: scale divisor, filter.
    Exact(u32, Filter),
    /// The textbook march in distance (the baseline most engines ship).
    Textbook,
    /// The error-target settings for this tolerance (in units of 0.1%).
    Target(u32),
}

/// The upsampling filter of a configuration (`None` at full resolution).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Filter {
    /// Full resolution: nothing to upsample.
    None,
    /// Plain bilinear (depth-blind).
    Bilinear,
    /// Depth-aware 3×3.
    Box3,
    /// Separable bilateral.
    Separable,
}

impl Filter {
    fn of(filter: UpsampleFilter, scale: Scale) -> Self {
        match (scale, filter) {
            (Scale::Full, _) => Filter::None,
            (_, UpsampleFilter::Bilinear) => Filter::Bilinear,
            (_, UpsampleFilter::Separable { .. }) => Filter::Separable,
            _ => Filter::Box3,
        }
    }

    fn name(self) -> &'static str {
        match self {
            Filter::None => "none",
            Filter::Bilinear => "bilinear",
            Filter::Box3 => "3x3",
            Filter::Separable => "separable",
        }
    }

    fn upsample(self) -> UpsampleFilter {
        match self {
            Filter::Bilinear => UpsampleFilter::Bilinear,
            Filter::Separable => SEPARABLE,
            Filter::None | Filter::Box3 => UpsampleFilter::DepthAware3x3,
        }
    }
}

impl Curve {
    /// The curve's name in the table and the plot's legend.
    pub fn name(self) -> String {
        match self {
            Curve::Analytic => "analytic floor".into(),
            Curve::Brute => "brute force".into(),
            Curve::Paper003 => "paper 003 (brute 1/4 + separable)".into(),
            Curve::Hybrid(1, _, b) => format!("hybrid full{}", refine_suffix(b)),
            Curve::Hybrid(d, f, b) => format!("hybrid 1/{d} {}{}", f.name(), refine_suffix(b)),
            Curve::Exact(1, _) => "exact full".into(),
            Curve::Exact(d, f) => format!("exact 1/{d} {}", f.name()),
            Curve::Textbook => "textbook march".into(),
            Curve::Target(t) => format!("error target {:.1}%", f64::from(t) / 10.0),
        }
    }
}

fn refine_suffix(bisections: u32) -> &'static str {
    if bisections > 0 {
        " +refine"
    } else {
        ""
    }
}

/// Errors of one image against the reference.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Errors {
    /// RMSE over pixels and channels, relative to the mean reference in-scatter.
    pub rmse: f64,
    /// 95th percentile of the per-pixel relative error (pixels above 1% of the frame's
    /// 99th-percentile brightness).
    pub p95: f64,
    /// 99th percentile, likewise.
    pub p99: f64,
}

/// One measured configuration.
#[derive(Debug, Clone)]
pub struct Row {
    /// Scene name.
    pub scene: String,
    /// Whether a light of the scene is textured.
    pub textured: bool,
    /// Method.
    pub curve: Curve,
    /// Steps per marched interval (0 for the floor).
    pub steps: u32,
    /// Scale divisor.
    pub scale: u32,
    /// Filter.
    pub filter: Filter,
    /// Bisections.
    pub bisections: u32,
    /// Median ms per pass (table and shadow map from the scene's full-rebuild frames).
    pub passes: BTreeMap<&'static str, f64>,
    /// Sum of the passes.
    pub total_ms: f64,
    /// Error against the reference.
    pub errors: Errors,
}

/// Pass columns, in pipeline order.
const PASS_COLUMNS: [&str; 7] = [
    "light texture",
    "shadow map",
    "F' table",
    "extents",
    "march",
    "upsample",
    "composite",
];

/// Passes timed once per scene and added to every configuration's total.
const FIXED_PASSES: [&str; 3] = ["shadow map", "F' table", "composite"];

/// A step sweep's stop rule (see the module docs).
#[derive(Debug, Clone, Default)]
struct Sweep {
    previous: Option<f64>,
    stopped: bool,
}

impl Sweep {
    /// Records a point; true (and says why) when the sweep stops after it.
    fn stops(&mut self, ctx: &Context, curve: Curve, steps: u32, p95: f64) -> bool {
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

/// One error-target check: the scene, the tolerance (p95) and the p95 achieved (∞ when no
/// settings could be made for the tolerance).
#[derive(Debug, Clone, PartialEq)]
pub struct Check {
    /// Scene name.
    pub scene: String,
    /// Tolerance.
    pub tolerance: f32,
    /// Achieved p95.
    pub p95: f64,
}

/// A hybrid configuration: steps, scale divisor, filter, bisections.
/// (exact?, steps, scale divisor, filter, bisections).
type ConfigKey = (bool, u32, u32, Filter, u32);

/// What a run produced.
pub struct Report {
    /// Every measured configuration.
    pub rows: Vec<Row>,
    /// The error-target checks: scene, tolerance, achieved p95.
    pub checks: Vec<Check>,
    /// Files written.
    pub files: Vec<PathBuf>,
}

/// How passes are timed.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Clock {
    /// Each pass submitted alone, wall clock around submit-and-wait (CPU adapters).
    WallPerPass,
    /// Timestamp queries.
    Timestamps,
}

struct Context<'a> {
    gpu: &'a HeadlessGpu,
    cache: Cache,
    clock: Clock,
    frames: usize,
    start: Instant,
}

impl Context<'_> {
    fn progress(&self, text: &str) {
        println!("[{:7.1} s] {text}", self.start.elapsed().as_secs_f64());
    }
}

/// Parses `args` and runs the report: the whole example.
pub fn run(args: &[String]) -> Result<Report, BoxError> {
    report(&Options::parse(args)?)
}

/// Runs the report as `options` say.
pub fn report(options: &Options) -> Result<Report, BoxError> {
    let gpu = HeadlessGpu::with_optional_features(wgpu::Features::TIMESTAMP_QUERY)?;
    let adapter = gpu.adapter_summary();
    let is_cpu = gpu.adapter.get_info().device_type == wgpu::DeviceType::Cpu;
    let clock = if is_cpu {
        Clock::WallPerPass
    } else if gpu
        .device
        .features()
        .contains(wgpu::Features::TIMESTAMP_QUERY)
    {
        Clock::Timestamps
    } else {
        return Err("a GPU adapter without TIMESTAMP_QUERY: no per-pass times to report".into());
    };
    let overhead_ms = {
        let mut samples: Vec<f64> = (0..21)
            .map(|_| {
                let encoder = gpu.device.create_command_encoder(&Default::default());
                let start = Instant::now();
                gpu.submit_and_wait(encoder)
                    .map(|_| start.elapsed().as_secs_f64() * 1e3)
            })
            .collect::<Result<_, _>>()?;
        median(&mut samples)
    };
    let ctx = Context {
        gpu: &gpu,
        cache: Cache::new(&gpu.device),
        clock,
        frames: options.frames,
        start: Instant::now(),
    };
    let date = today();
    println!("volshadow report, {date}: {adapter}");
    println!(
        "timing: {}, median of {} frames after a warm-up frame",
        match clock {
            Clock::WallPerPass => "each pass submitted alone, wall clock (CPU adapter)",
            Clock::Timestamps => "timestamp queries",
        },
        options.frames
    );
    if clock == Clock::WallPerPass {
        println!(
            "an empty submission takes {overhead_ms:.3} ms (median of 21), included in each pass"
        );
    }
    std::fs::create_dir_all(options.out.join("cache"))
        .map_err(|e| format!("cannot create {}: {e}", options.out.display()))?;

    let mut rows = Vec::new();
    let mut checks = Vec::new();
    for (index, path) in options.scenes.iter().enumerate() {
        let scene = SceneDescription::load(path)?;
        ctx.progress(&format!(
            "scene {}/{}: {} ({})",
            index + 1,
            options.scenes.len(),
            scene.name,
            path.display()
        ));
        let (scene_rows, scene_checks) = run_scene(&ctx, options, path, &scene)?;
        rows.extend(scene_rows);
        checks.extend(scene_checks);
    }
    let files = write_outputs(options, &adapter, &date, clock, &rows, &checks)?;
    println!("\n{}", summary(&rows, &checks));
    ctx.progress(&format!("done; wrote {}", options.out.display()));
    Ok(Report {
        rows,
        checks,
        files,
    })
}

/// Everything measured on one scene.
fn run_scene(
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
    // composite): timed once per scene, in frames that rebuild everything.
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
            errors,
        };
        ctx.progress(&format!(
            "  {:<42} {:>5} steps  {:>9.1} ms  p95 {:>7.3}%  p99 {:>7.3}%  RMSE {:>7.3}%",
            curve.name(),
            row.steps,
            row.total_ms,
            100.0 * errors.p95,
            100.0 * errors.p99,
            100.0 * errors.rmse
        ));
        rows.borrow_mut().push(row.clone());
        row
    };

    // The floor.
    let s = settings(MarchMethod::Hybrid, 8, Scale::Full, Filter::None, 0);
    let (passes, image) = measure(s, &unshadowed, false)?;
    record(Curve::Analytic, &s, passes, &image, &floor_fixed);

    // Brute force, and paper 003's configuration.
    let sweep: Vec<u32> = if options.quick {
        vec![16, 32]
    } else {
        vec![16, 32, 64, 128, 256, 512, 1024]
    };
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
        for &steps in &sweep {
            let s = settings(method, steps, scale, filter, 0);
            let (passes, image) = measure(s, &shadowed, false)?;
            let p95 = record(curve, &s, passes, &image, &fixed).errors.p95;
            if !options.full && sweep_state.stops(ctx, curve, steps, p95) {
                break;
            }
        }
    }

    // The exact method: no steps (they only march pixels whose crossing list overflowed).
    for scale in [Scale::Full, Scale::Half, Scale::Quarter] {
        let filters = if scale == Scale::Full {
            vec![Filter::None]
        } else {
            vec![Filter::Box3, Filter::Separable]
        };
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
    let (steps_list, scales, refines): (Vec<u32>, Vec<Scale>, Vec<u32>) = if options.quick {
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
    };
    for &bisections in &refines {
        for &scale in &scales {
            let filters = if scale == Scale::Full {
                vec![Filter::None]
            } else {
                vec![Filter::Box3, Filter::Separable, Filter::Bilinear]
            };
            let mut sweeps = vec![Sweep::default(); filters.len()];
            for &steps in &steps_list {
                let mut march_passes: Option<BTreeMap<&'static str, f64>> = None;
                for (&filter, sweep_state) in filters.iter().zip(&mut sweeps) {
                    if sweep_state.stopped {
                        continue;
                    }
                    let s = settings(MarchMethod::Hybrid, steps, scale, filter, bisections);
                    let (mut passes, image) = measure(s, &shadowed, march_passes.is_some())?;
                    share_march(&mut passes, &mut march_passes);
                    let curve = Curve::Hybrid(scale.divisor(), filter, bisections);
                    let p95 = record(curve, &s, passes, &image, &fixed).errors.p95;
                    if !options.full {
                        sweep_state.stops(ctx, curve, steps, p95);
                    }
                }
                if sweeps.iter().all(|s| s.stopped) {
                    break;
                }
            }
        }
    }

    // The error target.
    let mut checks = Vec::new();
    for tolerance in TOLERANCES {
        let target = match Settings::for_error_target(tolerance) {
            Ok(target) => target,
            Err(e) => {
                ctx.progress(&format!("  error target {:.0}%: {e}", 100.0 * tolerance));
                checks.push(Check {
                    scene: scene.name.clone(),
                    tolerance,
                    p95: f64::INFINITY,
                });
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
        let ok = row.errors.p95 <= f64::from(tolerance);
        ctx.progress(&format!(
            "  error target {:.0}%: p95 {:.3}% {}",
            100.0 * tolerance,
            100.0 * row.errors.p95,
            if ok { "meets it" } else { "MISSES it" }
        ));
        checks.push(Check {
            scene: scene.name.clone(),
            tolerance,
            p95: row.errors.p95,
        });
    }
    Ok((rows.into_inner(), checks))
}

/// One configuration: a warm-up frame (whose image is measured), then `frames` timed frames;
/// the median per pass. With `reuse_march` the march and extents are not recorded (the
/// previous configuration's march output, from identical inputs, is upsampled again).
fn measure(
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
            // Passes that ran only in the first frame (table, shadow map, light texture) are
            // timed apart.
            if !matches!(pass, "F' table" | "shadow map" | "light texture") {
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

/// Times the passes that are the same for every configuration of a scene (F′ table, shadow
/// map, composite), median of `frames` frames in which everything is rebuilt.
fn time_fixed(
    ctx: &Context,
    settings: Settings,
    frame: &Frame,
    view: &wgpu::Texture,
) -> Result<BTreeMap<&'static str, f64>, BoxError> {
    let mut volumetric =
        VolumetricShadows::new(&ctx.gpu.device, &ctx.gpu.queue, &ctx.cache, settings)?;
    let mut samples: BTreeMap<&'static str, Vec<f64>> = BTreeMap::new();
    for index in 0..=ctx.frames {
        volumetric.invalidate();
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

/// Prepares and runs one frame, leaving out the `skip` passes (on a CPU adapter); the time of
/// each pass run, by report column.
fn run_frame(
    ctx: &Context,
    volumetric: &mut VolumetricShadows,
    frame: &Frame,
    view: &wgpu::Texture,
    skip: &[Pass],
) -> Result<Vec<(&'static str, f64)>, BoxError> {
    volumetric.prepare(&ctx.gpu.device, &ctx.gpu.queue, frame)?;
    let mut times: Vec<(&'static str, f64)> = Vec::new();
    for t in ctx.gpu.run_timed(volumetric, view, skip)? {
        // Timestamp labels of the nodes, or pass names on a CPU adapter.
        let column = match t.label {
            "extrude" | "extents" => "extents",
            "airlight table" | "F' table" => "F' table",
            other => PASS_COLUMNS
                .iter()
                .find(|c| **c == other)
                .copied()
                .unwrap_or("march"),
        };
        match times.iter_mut().find(|(c, _)| *c == column) {
            Some((_, ms)) => *ms += t.ms,
            None => times.push((column, t.ms)),
        }
    }
    Ok(times)
}

fn median(values: &mut [f64]) -> f64 {
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

/// Pixels the error is measured on: all but those within 1.5 pixels of a light's centre.
fn keep_mask(
    scene: &SceneDescription,
    camera: &volshadow::Camera,
    (w, h): (u32, u32),
) -> Vec<bool> {
    let pixel_angle = 2.0 * f64::from(camera.pixel_angular_radius(h));
    (0..w * h)
        .map(|i| {
            let (eye, dir) = camera_ray(camera, pixel_ndc(w, h, i % w, i / w));
            scene.lights.iter().all(|l| {
                let to_light = l.light.position().as_dvec3() - eye;
                dir.angle_between(to_light) >= 1.5 * pixel_angle
            })
        })
        .collect()
}

/// RMSE relative to the mean, and percentiles of the per-pixel relative error.
pub fn errors(image: &[DVec3], reference: &[DVec3], keep: &[bool]) -> Errors {
    let mut sum_sq = 0.0;
    let mut sum_ref = 0.0;
    let mut count = 0usize;
    let mut brightness = Vec::new();
    for ((g, r), &k) in image.iter().zip(reference).zip(keep) {
        if k {
            sum_sq += (*g - *r).length_squared();
            sum_ref += r.x + r.y + r.z;
            count += 3;
            brightness.push(r.max_element());
        }
    }
    // The frame's brightness scale: its 99th percentile, not its maximum. With a light in view
    // the maximum sits in the light's 1/h glow, and 1% of it would leave only the pixels
    // around the light counted (where no shadow falls).
    brightness.sort_by(f64::total_cmp);
    let peak = brightness
        .get((brightness.len().saturating_sub(1) as f64 * 0.99) as usize)
        .copied()
        .unwrap_or(0.0);
    let mut relative: Vec<f64> = image
        .iter()
        .zip(reference)
        .zip(keep)
        .filter(|((_, r), &k)| k && r.max_element() > 0.01 * peak)
        .map(|((g, r), _)| {
            let e = (*g - *r).abs().max_element() / r.max_element();
            if e.is_finite() {
                e
            } else {
                f64::INFINITY
            }
        })
        .collect();
    relative.sort_by(f64::total_cmp);
    let percentile = |p: f64| {
        if relative.is_empty() {
            0.0
        } else {
            let index = ((p * relative.len() as f64).ceil() as usize).clamp(1, relative.len()) - 1;
            relative[index]
        }
    };
    let mean = sum_ref / count.max(1) as f64;
    Errors {
        rmse: if mean > 0.0 {
            (sum_sq / count.max(1) as f64).sqrt() / mean
        } else {
            0.0
        },
        p95: percentile(0.95),
        p99: percentile(0.99),
    }
}

/// The reference in-scatter, from the cache or computed and cached.
fn cached_reference(
    ctx: &Context,
    options: &Options,
    path: &Path,
    scene: &SceneDescription,
    camera: &volshadow::Camera,
    size: (u32, u32),
) -> Result<Vec<DVec3>, BoxError> {
    let text = std::fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    let key = reference_key(&text, size);
    let file = options.out.join("cache").join(format!(
        "{}-{}x{}-{key:016x}.f64",
        scene.name, size.0, size.1
    ));
    let pixels = (size.0 * size.1) as usize;
    if let Ok(bytes) = std::fs::read(&file) {
        if bytes.len() == pixels * 24 {
            ctx.progress(&format!("  reference from the cache ({})", file.display()));
            return Ok(bytes
                .chunks_exact(24)
                .map(|c| {
                    let f = |i: usize| {
                        f64::from_le_bytes(c[i * 8..i * 8 + 8].try_into().expect("8 bytes"))
                    };
                    DVec3::new(f(0), f(1), f(2))
                })
                .collect());
        }
    }
    ctx.progress(&format!(
        "  reference: f64 integrator at {}x{} (not cached yet) …",
        size.0, size.1
    ));
    let start = Instant::now();
    let image = reference_inscatter(scene, camera, size);
    let bytes: Vec<u8> = image
        .iter()
        .flat_map(|v| [v.x, v.y, v.z])
        .flat_map(f64::to_le_bytes)
        .collect();
    std::fs::write(&file, bytes).map_err(|e| format!("cannot write {}: {e}", file.display()))?;
    ctx.progress(&format!(
        "  reference done in {:.1} s, cached as {}",
        start.elapsed().as_secs_f64(),
        file.display()
    ));
    Ok(image)
}

/// Filters after the first of one march reuse its march and extents: the first measurement
/// keeps their times in `shared`, the later ones take them from it.
fn share_march(
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

/// The source files the reference images depend on: the integrator, the scene types, the
/// scene-file and glTF loaders and the ray caster that finds each pixel's surface. Whole
/// folders are listed at run time, so a file added to them cannot be forgotten.
pub fn reference_sources() -> Vec<std::path::PathBuf> {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    for dir in ["src/reference", "src/scene", "src/scene_file", "src/gltf"] {
        if let Ok(entries) = std::fs::read_dir(root.join(dir)) {
            files.extend(
                entries
                    .filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|p| p.extension().is_some_and(|x| x == "rs")),
            );
        }
    }
    for file in [
        "src/load.rs",
        "src/error.rs",
        "examples/common/render_scene.rs",
        "examples/common/gltf_scene.rs",
    ] {
        files.push(root.join(file));
    }
    files.sort();
    files
}

/// FNV-1a over the scene file, the size and every source the reference depends on
/// ([`reference_sources`]): a change to the integrator or the scene loader invalidates the
/// cache.
fn reference_key(scene_file: &[u8], (w, h): (u32, u32)) -> u64 {
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            hash ^= u64::from(b);
            hash = hash.wrapping_mul(0x0100_0000_01b3);
        }
    };
    eat(scene_file);
    eat(&w.to_le_bytes());
    eat(&h.to_le_bytes());
    for source in reference_sources() {
        eat(source.to_string_lossy().as_bytes());
        // A missing file hashes as its name alone, which still differs from its contents.
        eat(&std::fs::read(&source).unwrap_or_default());
    }
    hash
}

/// Today's date (UTC), `YYYY-MM-DD`, from the system clock.
fn today() -> String {
    let days = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs() / 86_400) as i64;
    // Howard Hinnant's civil-from-days.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!("{year:04}-{month:02}-{day:02}")
}

/// The cheapest row of `curve`-matching rows of `scene` with p95 ≤ `p95`.
fn cheapest<'a>(
    rows: &'a [Row],
    scene: &str,
    p95: f64,
    filter: impl Fn(&Row) -> bool,
) -> Option<&'a Row> {
    rows.iter()
        .filter(|r| r.scene == scene && filter(r) && r.errors.p95 <= p95)
        .min_by(|a, b| a.total_ms.total_cmp(&b.total_ms))
}

/// The per-scene summary and the error-target checks, as printed and written.
pub fn summary(rows: &[Row], checks: &[Check]) -> String {
    let mut out = String::new();
    let mut scenes: Vec<&str> = Vec::new();
    for r in rows {
        if !scenes.contains(&r.scene.as_str()) {
            scenes.push(&r.scene);
        }
    }
    let _ = writeln!(out, "## Summary\n");
    let is_exact = |r: &Row| matches!(r.curve, Curve::Exact(..));
    let _ = writeln!(
        out,
        "| scene | textbook march at p95 ≤ 2% | brute force at p95 ≤ 2% | exact at p95 ≤ 2% | exact vs textbook | exact vs brute force | exact 1/2 3x3 (p95) / analytic floor |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|---|");
    for scene in &scenes {
        let floor = rows
            .iter()
            .find(|r| r.scene == *scene && r.curve == Curve::Analytic);
        let textbook = cheapest(rows, scene, 0.02, |r| r.curve == Curve::Textbook);
        let brute = cheapest(rows, scene, 0.02, |r| r.curve == Curve::Brute);
        let exact = cheapest(rows, scene, 0.02, is_exact);
        let half = rows
            .iter()
            .find(|r| r.scene == *scene && r.curve == Curve::Exact(2, Filter::Box3));
        let describe = |r: Option<&Row>| match r {
            Some(r) if r.curve == Curve::Textbook || r.curve == Curve::Brute => format!(
                "{} steps: {:.1} ms (p95 {:.2}%)",
                r.steps,
                r.total_ms,
                100.0 * r.errors.p95
            ),
            Some(r) => format!(
                "{}: {:.1} ms (p95 {:.2}%)",
                r.curve.name(),
                r.total_ms,
                100.0 * r.errors.p95
            ),
            None => "not reached".into(),
        };
        // A baseline that never reached 2%: a lower bound from its most expensive point.
        let speedup = |baseline: Option<&Row>, curve: Curve| match (baseline, exact) {
            (Some(b), Some(e)) => format!("{:.1}x", b.total_ms / e.total_ms),
            (None, Some(e)) => rows
                .iter()
                .filter(|r| r.scene == *scene && r.curve == curve)
                .max_by(|a, b| a.total_ms.total_cmp(&b.total_ms))
                .map_or("n/a".into(), |b| {
                    format!(
                        "> {:.1}x (at {} steps p95 {:.2}%)",
                        b.total_ms / e.total_ms,
                        b.steps,
                        100.0 * b.errors.p95
                    )
                }),
            _ => "n/a".into(),
        };
        let ratio = match (half, floor) {
            (Some(h), Some(f)) => format!(
                "{:.2}x ({:.1} / {:.1} ms, p95 {:.2}%)",
                h.total_ms / f.total_ms,
                h.total_ms,
                f.total_ms,
                100.0 * h.errors.p95
            ),
            _ => "n/a".into(),
        };
        let _ = writeln!(
            out,
            "| {scene} | {} | {} | {} | {} | {} | {ratio} |",
            describe(textbook),
            describe(brute),
            describe(exact),
            speedup(textbook, Curve::Textbook),
            speedup(brute, Curve::Brute),
        );
    }
    let _ = writeln!(out);
    let _ = writeln!(
        out,
        "| scene | brute force at p95 ≤ 2% | hybrid at p95 ≤ 2% | speedup | 1/4-res pipeline at p95 ≤ 2% | its cost / analytic floor |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|");
    let is_hybrid = |r: &Row| matches!(r.curve, Curve::Hybrid(..));
    for scene in scenes {
        let floor = rows
            .iter()
            .find(|r| r.scene == scene && r.curve == Curve::Analytic);
        let brute = cheapest(rows, scene, 0.02, |r| r.curve == Curve::Brute);
        let hybrid = cheapest(rows, scene, 0.02, is_hybrid);
        let quarter = cheapest(rows, scene, 0.02, |r| is_hybrid(r) && r.scale == 4);
        let describe = |r: Option<&Row>| match r {
            Some(r) => format!(
                "{} {} steps: {:.1} ms (p95 {:.2}%)",
                r.curve.name(),
                r.steps,
                r.total_ms,
                100.0 * r.errors.p95
            ),
            None => "not reached".into(),
        };
        let speedup = match (brute, hybrid) {
            (Some(b), Some(h)) => format!("{:.1}x", b.total_ms / h.total_ms),
            (None, Some(h)) => {
                // Brute force never got there: a lower bound from its most expensive point.
                let best = rows
                    .iter()
                    .filter(|r| r.scene == scene && r.curve == Curve::Brute)
                    .max_by(|a, b| a.total_ms.total_cmp(&b.total_ms));
                best.map_or("n/a".into(), |b| {
                    format!(
                        "> {:.1}x (brute force at {} steps: p95 {:.2}%)",
                        b.total_ms / h.total_ms,
                        b.steps,
                        100.0 * b.errors.p95
                    )
                })
            }
            _ => "n/a".into(),
        };
        let ratio = match (quarter, floor) {
            (Some(q), Some(f)) => {
                let static_light = q.total_ms - q.passes.get("shadow map").copied().unwrap_or(0.0);
                format!(
                    "{:.2}x ({:.1} / {:.1} ms); {:.2}x with the light static (no shadow map)",
                    q.total_ms / f.total_ms,
                    q.total_ms,
                    f.total_ms,
                    static_light / f.total_ms
                )
            }
            _ => "n/a".into(),
        };
        let _ = writeln!(
            out,
            "| {scene} | {} | {} | {speedup} | {} | {ratio} |",
            describe(brute),
            describe(hybrid),
            describe(quarter)
        );
    }
    let _ = writeln!(out, "\n## Error-target check\n");
    let _ = writeln!(out, "| scene | tolerance (p95) | achieved p95 | result |");
    let _ = writeln!(out, "|---|---|---|---|");
    for Check {
        scene,
        tolerance,
        p95,
    } in checks
    {
        let tolerance = f64::from(*tolerance);
        let result = if *p95 <= tolerance {
            "pass".to_string()
        } else if p95.is_infinite() {
            "FAIL: no configuration of the error table reaches it with headroom".to_string()
        } else {
            format!(
                "FAIL by {:.2} points ({:.2}x)",
                100.0 * (p95 - tolerance),
                p95 / tolerance
            )
        };
        let _ = writeln!(
            out,
            "| {scene} | {:.0}% | {} | {result} |",
            100.0 * tolerance,
            if p95.is_finite() {
                format!("{:.3}%", 100.0 * p95)
            } else {
                "–".into()
            }
        );
    }
    out
}

fn write_outputs(
    options: &Options,
    adapter: &str,
    date: &str,
    clock: Clock,
    rows: &[Row],
    checks: &[Check],
) -> Result<Vec<PathBuf>, BoxError> {
    let write = |name: &str, text: &str| -> Result<PathBuf, BoxError> {
        let path = options.out.join(name);
        std::fs::write(&path, text).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        Ok(path)
    };
    // CSV.
    let mut csv = String::from("scene,method,steps,scale,filter,bisections");
    for c in PASS_COLUMNS {
        let _ = write!(
            csv,
            ",{}_ms",
            c.replace("F' ", "").replace(' ', "_").to_lowercase()
        );
    }
    csv.push_str(",total_ms,rmse_rel,p95,p99\n");
    for r in rows {
        let _ = write!(
            csv,
            "{},{},{},{},{},{}",
            r.scene,
            r.curve.name(),
            r.steps,
            r.scale,
            r.filter.name(),
            r.bisections
        );
        for c in PASS_COLUMNS {
            let _ = write!(csv, ",{:.3}", r.passes.get(c).copied().unwrap_or(0.0));
        }
        let _ = writeln!(
            csv,
            ",{:.3},{:.6},{:.6},{:.6}",
            r.total_ms, r.errors.rmse, r.errors.p95, r.errors.p99
        );
    }
    // Markdown.
    let mut md = format!(
        "# volshadow: error against time\n\n{date}, {adapter}, {}x{} pixels. Timing: {}, median of {} frames after a warm-up frame; F' table and shadow map timed in frames that rebuild everything and counted in every total. Error against the f64 reference: RMSE relative to the mean in-scatter; p95/p99 of the per-pixel relative error where the reference is above 1% of its 99th percentile (not of its maximum, which a light in view puts in its own glow); the light's own pixels left out. Regenerate: `cargo run --release --example report`.\n\n",
        options.size,
        options.size,
        match clock {
            Clock::WallPerPass => "each pass submitted alone and timed by the wall clock (CPU adapter)",
            Clock::Timestamps => "timestamp queries",
        },
        options.frames
    );
    md.push_str(&summary(rows, checks));
    md.push_str("\n## All configurations\n\n| scene | method | steps | ");
    for c in PASS_COLUMNS {
        let _ = write!(md, "{c} ms | ");
    }
    md.push_str("total ms | RMSE | p95 | p99 |\n|---|---|---|");
    md.push_str(&"---|".repeat(PASS_COLUMNS.len() + 4));
    md.push('\n');
    for r in rows {
        let _ = write!(md, "| {} | {} | {} | ", r.scene, r.curve.name(), r.steps);
        for c in PASS_COLUMNS {
            match r.passes.get(c) {
                Some(ms) => {
                    let _ = write!(md, "{ms:.1} | ");
                }
                None => md.push_str("– | "),
            }
        }
        let _ = writeln!(
            md,
            "{:.1} | {:.3}% | {:.3}% | {:.3}% |",
            r.total_ms,
            100.0 * r.errors.rmse,
            100.0 * r.errors.p95,
            100.0 * r.errors.p99
        );
    }
    let mut files = vec![write("report.csv", &csv)?, write("report.md", &md)?];
    files.push(plot(options, rows, adapter, date)?);
    files.push(write("error_table.rs", &error_table(rows))?);
    Ok(files)
}

/// Hybrid configurations over the scenes with untextured lights (under an error target a
/// textured spot scatters at full resolution): the worst p95 and the mean cost relative to
/// each scene's analytic floor, Pareto-optimal ones only, as rows of `volshadow::plan`'s table.
/// Only configurations measured on every such scene count (a sweep that stopped early on one
/// scene leaves its later step counts out).
fn error_table(rows: &[Row]) -> String {
    let rows: Vec<Row> = rows.iter().filter(|r| !r.textured).cloned().collect();
    let rows = rows.as_slice();
    let mut groups: BTreeMap<ConfigKey, Vec<&Row>> = BTreeMap::new();
    for r in rows
        .iter()
        .filter(|r| matches!(r.curve, Curve::Hybrid(..) | Curve::Exact(..)))
    {
        let exact = matches!(r.curve, Curve::Exact(..));
        groups
            .entry((exact, r.steps, r.scale, r.filter, r.bisections))
            .or_default()
            .push(r);
    }
    let scenes = rows.iter().filter(|r| r.curve == Curve::Analytic).count();
    let floor = |scene: &str| {
        rows.iter()
            .find(|r| r.scene == scene && r.curve == Curve::Analytic)
            .map_or(1.0, |r| r.total_ms)
    };
    let mut candidates: Vec<(f64, f64, ConfigKey)> = groups
        .into_iter()
        .filter(|(_, v)| v.len() == scenes)
        .map(|(key, v)| {
            let worst = v.iter().map(|r| r.errors.p95).fold(0.0, f64::max);
            let cost = v.iter().map(|r| r.total_ms / floor(&r.scene)).sum::<f64>() / v.len() as f64;
            (worst, cost, key)
        })
        .collect();
    candidates.sort_by(|a, b| a.1.total_cmp(&b.1));
    let mut out = String::from(
        "// Measured by `cargo run --release --example report`: exact and hybrid configurations\n\
         // on the Pareto front of worst-scene p95 against mean cost over the analytic floor.\n",
    );
    let mut best = f64::INFINITY;
    for (worst, cost, (exact, steps, scale, filter, bisections)) in candidates {
        if worst < best {
            best = worst;
            let filter = match filter {
                Filter::None | Filter::Box3 => "UpsampleFilter::DepthAware3x3".to_string(),
                Filter::Bilinear => "UpsampleFilter::Bilinear".to_string(),
                Filter::Separable => "SEPARABLE".to_string(),
            };
            let scale = match scale {
                1 => "Scale::Full",
                2 => "Scale::Half",
                _ => "Scale::Quarter",
            };
            let method = if exact { "Exact" } else { "Hybrid" };
            let _ = writeln!(
                out,
                "    measured(MarchMethod::{method}, {worst:.4}, {cost:.3}, {steps}, {scale}, {filter}, {bisections}),"
            );
        }
    }
    out
}

/// `error_vs_time.svg`: per scene, p95 error (log) against total time (log), one curve per
/// method.
fn plot(options: &Options, rows: &[Row], adapter: &str, date: &str) -> Result<PathBuf, BoxError> {
    use plotters::prelude::*;
    let path = options.out.join("error_vs_time.svg");
    let mut scenes: Vec<&str> = Vec::new();
    for r in rows {
        if !scenes.contains(&r.scene.as_str()) {
            scenes.push(&r.scene);
        }
    }
    let columns = 2usize;
    let panel_rows = scenes.len().div_ceil(columns).max(1);
    let file = path.clone();
    let header = 90;
    let root = SVGBackend::new(&file, (1200, header + 420 * panel_rows as u32)).into_drawing_area();
    root.fill(&WHITE)?;
    let (title, body) = root.split_vertically(header);
    title.draw(&Text::new(
        format!(
            "volshadow: p95 relative error against frame time, {}x{} ({date}, {adapter})",
            options.size, options.size
        ),
        (10, 10),
        ("sans-serif", 16).into_font(),
    ))?;
    let panels = body.split_evenly((panel_rows, columns));
    // The plotted curves: brute force, paper 003, and the hybrid with refinement on.
    let plotted = |c: Curve| match c {
        Curve::Brute | Curve::Paper003 | Curve::Textbook | Curve::Exact(..) => true,
        Curve::Hybrid(_, f, b) => b > 0 && f != Filter::Bilinear,
        _ => false,
    };
    let palette = [
        RGBColor(0, 0, 0),
        RGBColor(120, 120, 120),
        RGBColor(214, 39, 40),
        RGBColor(31, 119, 180),
        RGBColor(44, 160, 44),
        RGBColor(255, 127, 14),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
    ];
    // One colour per method across all panels, and one legend for all of them.
    let mut curves: Vec<Curve> = rows
        .iter()
        .map(|r| r.curve)
        .filter(|c| plotted(*c))
        .collect();
    curves.sort();
    curves.dedup();
    let color_of = |c: Curve| {
        let i = curves.iter().position(|k| *k == c).unwrap_or(0);
        palette[i % palette.len()]
    };
    let floor_grey = RGBColor(160, 160, 160);
    let mut legend: Vec<(String, RGBColor)> =
        curves.iter().map(|c| (c.name(), color_of(*c))).collect();
    legend.push(("analytic floor (its time)".into(), floor_grey));
    for (i, (name, color)) in legend.iter().enumerate() {
        let (x, y) = (10 + 295 * (i % 4) as i32, 38 + 22 * (i / 4) as i32);
        title.draw(&PathElement::new(
            vec![(x, y + 7), (x + 24, y + 7)],
            color.stroke_width(2),
        ))?;
        title.draw(&Text::new(
            name.clone(),
            (x + 30, y),
            ("sans-serif", 13).into_font(),
        ))?;
    }
    for (panel, scene) in panels.iter().zip(&scenes) {
        let scene_rows: Vec<&Row> = rows.iter().filter(|r| r.scene == *scene).collect();
        let (mut t0, mut t1, mut e0, mut e1) = (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64);
        for r in &scene_rows {
            if r.total_ms > 0.0 {
                t0 = t0.min(r.total_ms);
                t1 = t1.max(r.total_ms);
            }
            if r.errors.p95 > 0.0 && r.errors.p95.is_finite() {
                e0 = e0.min(r.errors.p95);
                e1 = e1.max(r.errors.p95);
            }
        }
        if !(t0 < t1 && e0 < e1) {
            continue;
        }
        let mut chart = ChartBuilder::on(panel)
            .caption(*scene, ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(
                (t0 * 0.8..t1 * 1.25).log_scale(),
                (e0 * 0.8..e1 * 1.25).log_scale(),
            )?;
        chart
            .configure_mesh()
            .light_line_style(RGBColor(238, 238, 238))
            .bold_line_style(RGBColor(200, 200, 200))
            .x_labels(8)
            .y_labels(8)
            .x_desc("frame time, ms (sum of pass medians)")
            .y_desc("p95 relative error")
            .x_label_formatter(&|v| format!("{v:.0}"))
            .y_label_formatter(&|v| format!("{:.2}%", 100.0 * v))
            .draw()?;
        for curve in curves
            .iter()
            .filter(|c| scene_rows.iter().any(|r| r.curve == **c))
        {
            let color = color_of(*curve);
            let mut points: Vec<(f64, f64)> = scene_rows
                .iter()
                .filter(|r| r.curve == *curve && r.errors.p95 > 0.0)
                .map(|r| (r.total_ms, r.errors.p95))
                .collect();
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            chart.draw_series(LineSeries::new(points.clone(), color.stroke_width(2)))?;
            chart.draw_series(
                points
                    .into_iter()
                    .map(|p| Circle::new(p, 3, color.filled())),
            )?;
        }
        if let Some(floor) = scene_rows.iter().find(|r| r.curve == Curve::Analytic) {
            chart.draw_series(LineSeries::new(
                vec![(floor.total_ms, e0 * 0.8), (floor.total_ms, e1 * 1.25)],
                floor_grey.stroke_width(1),
            ))?;
        }
    }
    root.present()?;
    Ok(path)
}
