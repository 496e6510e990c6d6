//! The `report` example: error against GPU time for every method and setting on the standard
//! scenes (DESIGN §6).
//!
//! ```text
//! report [--scenes a,b,…|all] [--size N] [--frames N] [--out DIR] [--full] [--quick]
//! ```
//!
//! By default a quick set ([`options::DEFAULT_SCENES`] at [`options::DEFAULT_SIZE`]², a few
//! minutes on two CPU cores); `--full` runs every `scenes/*.json` at [`ERROR_TABLE_SIZE`]² with
//! every step count. For each scene it renders
//! * the **analytic floor**: the same frame without occluders (unshadowed airlight);
//! * **brute force** and the **textbook march** at 16, 32, …, 1024 steps (full resolution);
//! * **paper 003**'s configuration: brute force at ¼ resolution with the separable bilateral;
//! * the **exact** method at full, ½ and ¼ resolution (3×3 and separable upsampling);
//! * the **hybrid** at 8 … 256 steps × scattering at full, ½ and ¼ resolution × upsampling
//!   bilinear (depth-blind: "none") / depth-aware 3×3 / separable × refinement (2 bisections)
//!   off / on;
//! * the **error-target** settings ([`Settings::for_error_target`](volshadow::Settings::for_error_target)) for p95 5%, 2% and 1%,
//!   each checked against its tolerance — judged only at [`ERROR_TABLE_SIZE`]², the size the
//!   planner's table was measured at (elsewhere "not judged"); a failed check makes the
//!   binary exit with status 1 ([`Report::verdict`]).
//!
//! A scene whose light has a radius (soft shadows, whose penumbra is marched whatever the
//! method) runs only the floor, the exact method and the hybrid at 64 steps, each also timed
//! on the same scene with radius 0 (printed: the cost of soft over hard shadows at equal
//! settings); the planner's table (`error_table.rs`, measured on hard shadows) leaves it out,
//! as it leaves out textured spots.
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
//! (default `target/volshadow-report`); a run that would write over one of its inputs (a scene
//! file or a file it names) is refused before anything is written. `--quick` runs a few
//! configurations only (the test). Progress goes to stderr, each line with an estimate of the
//! time left; the summary to stdout.
//!
//! Files by job: `options` (command line), `measure` (timing, sweeps), `metrics` (errors),
//! `cache` (reference images on disk), `output` (summary, tables, plot); here the run.

mod cache;
mod measure;
mod metrics;
mod options;
mod output;

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

use volshadow::nodes::{Scale, UpsampleFilter};
use volshadow::scene_file::SceneDescription;
use volshadow::{Cache, HeadlessGpu};

use measure::{median, planned_configurations, run_scene, Clock, Context};
pub use options::{help, Options, USAGE};
pub use output::summary;
use output::{today, write_outputs};
// For the tools' tests (`tools/tests/tools/report.rs`).
pub use {cache::reference_sources, metrics::errors};
pub use {
    options::{DEFAULT_SCENES, DEFAULT_SIZE},
    output::{legend_box, legend_layout, series_style, FLOOR_GREY},
};
// For `benches/frame.rs`.
pub use measure::moved_lights;

use crate::app::{read_inscatter, with_aspect, BoxError};
use crate::cli::{input_files, refuse_overwrite, usage_line, Parsed};
use crate::metric;
use crate::render_scene;

/// The image size (width and height) the planner's error tables (`volshadow::plan::error_table`)
/// were measured at: the error-target checks are judged at this size only.
pub const ERROR_TABLE_SIZE: u32 = 512;

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
    /// Whether a light of the scene has a radius (soft shadows).
    pub soft: bool,
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
    /// A scene with a light with a radius: the same configuration on the scene with radius 0.
    pub hard: Option<HardTwin>,
}

/// A soft scene's configuration against the same configuration drawn with hard shadows
/// (radius 0), for the cost of soft over hard shadows at equal settings: both timed in the
/// same rounds, a soft frame then a hard one, each with its own passes (a hard light's
/// shadow map draws no back faces, and it has no grid), so that the machine's drift between
/// measurements does not enter the ratio; each pass's median over the rounds.
#[derive(Debug, Clone, Copy)]
pub struct HardTwin {
    /// The whole frame, every pass rebuilt (light moving): soft, then hard.
    pub soft_ms: f64,
    pub hard_ms: f64,
    /// soft / hard: light moving (every pass), and light static (less the shadow map and the
    /// grid, which are then reused).
    pub moving: f64,
    pub fixed_light: f64,
    /// Its p95 against the soft reference (how far hard shadows are from the soft image).
    pub p95: f64,
}

/// Pass columns, in pipeline order.
const PASS_COLUMNS: [&str; 8] = [
    "light texture",
    "shadow map",
    "F' table",
    "extents",
    "soft shadow",
    "march",
    "upsample",
    "composite",
];

/// Passes timed once per scene and added to every configuration's total.
const FIXED_PASSES: [&str; 4] = ["shadow map", "soft shadow", "F' table", "composite"];

/// One error-target check: the scene, the tolerance (p95), the p95 achieved (∞ when no
/// settings could be made for the tolerance) and the image size it was measured at.
#[derive(Debug, Clone, PartialEq)]
pub struct Check {
    /// Scene name.
    pub scene: String,
    /// Tolerance.
    pub tolerance: f32,
    /// Achieved p95.
    pub p95: f64,
    /// Width and height of the images.
    pub size: u32,
}

/// What a check says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Within its tolerance at [`ERROR_TABLE_SIZE`]².
    Pass,
    /// Over it at [`ERROR_TABLE_SIZE`]², or no settings for it.
    Fail,
    /// Measured at another size than the table's: errors there say nothing about the table.
    NotJudged,
}

impl Check {
    /// Judged only at the size the error table was built for.
    pub fn verdict(&self) -> Verdict {
        if self.size != ERROR_TABLE_SIZE {
            Verdict::NotJudged
        } else if self.p95 <= f64::from(self.tolerance) {
            Verdict::Pass
        } else {
            Verdict::Fail
        }
    }
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

impl Report {
    /// The checks that failed.
    pub fn failures(&self) -> Vec<&Check> {
        self.checks
            .iter()
            .filter(|c| c.verdict() == Verdict::Fail)
            .collect()
    }

    /// `Ok` unless an error-target check failed (the binary's exit status: 1 on `Err`).
    pub fn verdict(&self) -> Result<(), BoxError> {
        let failed = self.failures();
        if failed.is_empty() {
            return Ok(());
        }
        let list: Vec<String> = failed
            .iter()
            .map(|c| {
                format!(
                    "{} at {:.0}%: p95 {:.3}%",
                    c.scene,
                    100.0 * c.tolerance,
                    100.0 * c.p95
                )
            })
            .collect();
        Err(format!(
            "{} error-target check(s) FAIL: {}",
            failed.len(),
            list.join("; ")
        )
        .into())
    }
}

/// Parses `args` and runs the report (what the tests call; `--help`, which the binary prints,
/// is an error here). A failed check is not an error here: see [`Report::verdict`].
pub fn run(args: &[String]) -> Result<Report, BoxError> {
    match Options::parse(args)? {
        Parsed::Run(options) => report(&options),
        Parsed::Help => Err(format!("--help runs nothing\n{}", usage_line(USAGE)).into()),
    }
}

/// Every file the run writes: the four outputs and each scene's cached reference.
fn outputs(
    options: &Options,
    scenes: &[(PathBuf, SceneDescription)],
) -> Result<Vec<PathBuf>, BoxError> {
    let mut files: Vec<PathBuf> = output::FILES.iter().map(|f| options.out.join(f)).collect();
    for (path, scene) in scenes {
        files.push(cache::cache_file(
            options,
            path,
            scene,
            (options.size, options.size),
        )?);
    }
    Ok(files)
}

/// Runs the report as `options` say: every scene file is loaded first (a bad one stops the run
/// before any work), and a run whose outputs include an input file is refused
/// ([`WouldOverwriteInput`](super::cli::WouldOverwriteInput)) before anything is written.
pub fn report(options: &Options) -> Result<Report, BoxError> {
    let scenes: Vec<(PathBuf, SceneDescription)> = options
        .scenes
        .iter()
        .map(|path| Ok((path.clone(), SceneDescription::load(path)?)))
        .collect::<Result<_, BoxError>>()?;
    let inputs: Vec<PathBuf> = options.scenes.iter().flat_map(|p| input_files(p)).collect();
    refuse_overwrite(&inputs, &outputs(options, &scenes)?)?;

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
        frames: options.frames,
        start: Instant::now(),
        progress: measure::Eta::new(options.full),
    };
    // What the estimate of the time left counts: configurations, and references to compute.
    for (path, scene) in &scenes {
        ctx.progress.plan(
            &planned_configurations(options, scene),
            !cache::is_cached(options, path, scene, (options.size, options.size))?,
        );
    }
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
    for (index, (path, scene)) in scenes.iter().enumerate() {
        ctx.progress(&format!(
            "scene {}/{}: {} ({})  [{}]",
            index + 1,
            scenes.len(),
            scene.name,
            path.display(),
            ctx.progress.line()
        ));
        let (scene_rows, scene_checks) = run_scene(&ctx, options, path, scene)?;
        rows.extend(scene_rows);
        checks.extend(scene_checks);
    }
    let files = write_outputs(options, &adapter, &date, clock, &rows, &checks)?;
    println!("\n{}", summary(&rows, &checks));
    for line in output::metric_lines(options, &adapter, &rows, &checks) {
        println!("{line}");
    }
    ctx.progress(&format!("done; wrote {}", options.out.display()));
    Ok(Report {
        rows,
        checks,
        files,
    })
}
