//! Soak: the facade for many frames with everything animated — the camera, a point light and a
//! textured spot light, three spheres move every frame, the medium's density breathes, the
//! frame is resized every `--resize-every` frames and the settings are switched every
//! `--settings-every` frames (four settings: the default (exact), an error target, brute force
//! with a smaller table and shadow map, quarter-resolution bilinear).
//!
//! It first renders one frame in every size and settings (as a game compiles its pipelines
//! while loading), then every `--report-every` frames it prints the resident set size (`VmRSS`),
//! the bytes its device has allocated (wgpu's allocator report), the median frame
//! time of the block, the NaN/Inf count of the output and of each light's in-scatter (read
//! back at the block's last frame) and the wgpu validation errors so far (an uncaptured-error
//! handler counts them). See [`USAGE`] for the rules it judges and how (`soak --help`).
//!
//! ```text
//! cargo run --release -p volshadow_tools --bin soak -- [--frames 2000] [--size 256x144] [--report-every 100]
//!     [--resize-every 100] [--settings-every 200] [--warmup 300] [--probe-every 5]
//!     [--max-seconds S] [--help]
//! ```
//!
//! The application's own pass (a ray-cast ground and spheres writing colour and depth) reads
//! its per-frame parameters from a storage buffer, as volshadow's nodes do: on Mesa's lavapipe
//! a uniform buffer whose contents change costs a shader compile and about a megabyte per
//! frame, which would hide what the soak measures.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use lexopt::prelude::*;
use volshadow::glam::{Mat4, Vec3};
use volshadow::nodes::UpsampleFilter;
use volshadow::nodes::{MarchMethod, MarchSettings, Scale, ShadowMapSettings, TableSize};
use volshadow::scene::{shapes, LightTexture};
use volshadow::{
    AdapterKind, Cache, Camera, Frame, FrameLight, HeadlessGpu, Light, Medium, Occluder,
    OccluderMesh, PhaseFunction, PointLight, Settings, SpotLight, VolumetricShadows,
};

use volshadow_harness::fullscreen::{texture_desc, FullscreenPass};
use volshadow_harness::headless_env;

type BoxError = Box<dyn std::error::Error>;

/// What `soak --help` prints.
pub const USAGE: &str = "\
soak: the volshadow facade for many frames with everything animated (camera, a point light, a
textured spot light, three moving spheres, a breathing medium), resized and switched between
four settings as it runs; prints RSS, device memory, frame time, NaN/Inf and validation errors
per block.

usage: cargo run --release -p volshadow_tools --bin soak -- [OPTIONS]

options:
  --frames N          frames to run after the warm-up frames (default 2000)
  --size WxH          the larger frame size; the other is about 3/4 of it (default 256x144)
  --report-every N    frames per printed block (default 100)
  --resize-every N    frames between resizes (default 100)
  --settings-every N  frames between settings switches (default 200)
  --warmup N          frames before RSS and frame time are judged (default 300)
  --probe-every N     a probe frame after every N-th frame, for the frame-time rule
                      (default 5; 0: no probe, and the frame-time rule is not judged)
  --max-seconds S     fail when the run takes longer than S seconds (default: no limit)
  -h, --help          print this and exit

rules (exit status 1 when one fails):
  errors       any error returned, NaN/Inf read back, or wgpu validation error: fail.
  RSS          the last block's RSS against the first block after the warm-up with the same
               size and settings (textures live in host memory on a CPU adapter, so
               configurations differ): fail above +5%. The whole process's: anything else it
               runs at the same time counts too.
  device memory  the same comparison of the bytes the soak's own device has allocated
               (wgpu's allocator report): fail above +5%. Not judged on a backend without
               the report. Nothing else in the process moves it.
  frame time   judged against an interleaved probe, so that the machine's load cancels: a
               second facade renders one fixed frame after every N-th soak frame, and each
               block's frame time is its median over the probe's median in the same block.
               That ratio, against the first block after the warm-up with the same size and
               settings: fail when it moves by more than 20%. Where it moved but the probe
               itself moved by more than 20% between the two blocks (the machine's load
               changed too much within them for the ratio to cancel it), the block is reported
               as not judged instead of failing.
  A rule needs two blocks of the same configuration after the warm-up; the configurations
  repeat every lcm(2 x resize-every, 4 x settings-every) frames (800 by default), so a
  shorter run says \"not judged: needs >= N frames\" for it instead of passing.
";

/// What the command line asks for.
#[derive(Debug, Clone)]
pub enum Command {
    /// Run the soak.
    Run(Options),
    /// Print [`USAGE`] and exit successfully.
    Help,
}

/// The soak's parameters.
#[derive(Debug, Clone)]
pub struct Options {
    /// Frames to run.
    pub frames: u32,
    /// Largest frame size (the other size is about ¾ of it, odd).
    pub size: (u32, u32),
    /// Frames per printed block.
    pub report_every: u32,
    /// Frames between resizes.
    pub resize_every: u32,
    /// Frames between settings switches.
    pub settings_every: u32,
    /// Frames before the RSS and frame-time baselines.
    pub warmup: u32,
    /// A probe frame after every `probe_every`-th frame (0: none, frame time not judged).
    pub probe_every: u32,
    /// Wall-clock budget: exceeding it is a failure (`None`: unlimited).
    pub max_seconds: Option<f64>,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            frames: 2000,
            size: (256, 144),
            report_every: 100,
            resize_every: 100,
            settings_every: 200,
            warmup: 300,
            probe_every: 5,
            max_seconds: None,
        }
    }
}

impl Options {
    /// Parses the command line (see [`USAGE`]): `--help` or `-h` anywhere is [`Command::Help`].
    pub fn parse(args: &[String]) -> Result<Command, BoxError> {
        let mut o = Options::default();
        let mut parser = lexopt::Parser::from_args(args);
        while let Some(arg) = parser.next()? {
            match arg {
                Short('h') | Long("help") => return Ok(Command::Help),
                Long("frames") => o.frames = parser.value()?.parse()?,
                Long("size") => {
                    let v = parser.value()?.string()?;
                    let (w, h) = v.split_once('x').ok_or("--size is WIDTHxHEIGHT")?;
                    o.size = (w.parse()?, h.parse()?);
                }
                Long("report-every") => o.report_every = parser.value()?.parse()?,
                Long("resize-every") => o.resize_every = parser.value()?.parse()?,
                Long("settings-every") => o.settings_every = parser.value()?.parse()?,
                Long("warmup") => o.warmup = parser.value()?.parse()?,
                Long("probe-every") => o.probe_every = parser.value()?.parse()?,
                Long("max-seconds") => o.max_seconds = Some(parser.value()?.parse()?),
                _ => {
                    return Err(format!("{} (see --help)", arg.unexpected()).into());
                }
            }
        }
        if o.frames == 0 || o.report_every == 0 || o.resize_every == 0 || o.settings_every == 0 {
            return Err("frame counts must be positive".into());
        }
        if o.size.0 < 8 || o.size.1 < 8 {
            return Err("--size must be at least 8x8".into());
        }
        Ok(Command::Run(o))
    }

    /// The size and settings indices of frame `frame` (after the warm-up frames).
    pub fn config(&self, frame: u32) -> (usize, usize) {
        (
            (frame / self.resize_every) as usize % SIZES,
            (frame / self.settings_every) as usize % SETTINGS,
        )
    }

    /// Frames after which the sizes and settings (and the animation) repeat.
    pub fn period(&self) -> u32 {
        lcm(
            SIZES as u32 * self.resize_every,
            SETTINGS as u32 * self.settings_every,
        )
    }

    /// The frame counts at which a run of `frames` frames prints a block.
    fn block_ends(&self, frames: u32) -> impl Iterator<Item = u32> + '_ {
        (1..=frames).filter(move |&d| d % self.report_every == 0 || d == frames)
    }

    /// The least frame count, a multiple of `--report-every`, whose run judges `rule`
    /// (`None`: none within two periods after the warm-up, which the cycle rules out).
    pub fn frames_to_judge(&self, rule: Rule) -> Option<u32> {
        let limit = self.warmup + 2 * self.period() + 2 * self.report_every;
        (1..=limit / self.report_every)
            .map(|k| k * self.report_every)
            .find(|&frames| {
                let ends: Vec<u32> = self.block_ends(frames).collect();
                !pairs(self, &ends, rule).is_empty()
            })
    }
}

/// Sizes the soak alternates between.
const SIZES: usize = 2;
/// Settings the soak cycles through ([`settings_cycle`]).
const SETTINGS: usize = 4;

/// A rule that compares blocks of the same configuration after the warm-up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rule {
    /// The last block's RSS against the first block after the warm-up with its configuration.
    Rss,
    /// Every block's load-normalised frame time against the first with its configuration.
    FrameTime,
}

/// The (block, baseline) index pairs that `rule` compares among blocks ending at `ends`: each
/// block after the warm-up (for RSS only the last) with the first earlier block after the
/// warm-up of the same configuration.
fn pairs(options: &Options, ends: &[u32], rule: Rule) -> Vec<(usize, usize)> {
    let config = |i: usize| options.config(ends[i] - 1);
    let after: Vec<usize> = (0..ends.len())
        .filter(|&i| ends[i] > options.warmup)
        .collect();
    let judged: Vec<usize> = match rule {
        Rule::Rss => after.last().copied().into_iter().collect(),
        Rule::FrameTime => after.clone(),
    };
    judged
        .into_iter()
        .filter_map(|i| {
            after
                .iter()
                .copied()
                .find(|&j| j < i && config(j) == config(i))
                .map(|j| (i, j))
        })
        .collect()
}

/// A rule's outcome.
#[derive(Debug, Clone, PartialEq)]
pub enum Verdict {
    /// Judged and within its bound; what was measured.
    Passed(String),
    /// Judged and beyond its bound; what was measured.
    Failed(String),
    /// The run cannot judge it (too short, or no probe); why.
    NotJudged(String),
}

impl std::fmt::Display for Verdict {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Verdict::Passed(m) => write!(f, "passed: {m}"),
            Verdict::Failed(m) => write!(f, "FAILED: {m}"),
            Verdict::NotJudged(m) => write!(f, "not judged: {m}"),
        }
    }
}

/// The device-memory rule on `blocks` (see [`USAGE`]): the RSS rule's pair of blocks, by
/// the bytes the soak's device has allocated.
pub fn judge_device_memory(options: &Options, blocks: &[Block]) -> Verdict {
    let ends: Vec<u32> = blocks.iter().map(|b| b.frames).collect();
    match pairs(options, &ends, Rule::Rss).first().copied() {
        None => Verdict::NotJudged(format!(
            "no two blocks of the same size and settings after frame {}",
            options.warmup
        )),
        Some((_, j)) if blocks[j].device_bytes == 0 => {
            Verdict::NotJudged("the backend gives no allocator report".into())
        }
        Some((i, j)) => {
            let growth = blocks[i].device_bytes as f64 / blocks[j].device_bytes as f64 - 1.0;
            let what = format!(
                "{:+.2}% from frame {} to {} ({:.1} MB to {:.1} MB; same size and settings; \
                 bound +5%)",
                100.0 * growth,
                blocks[j].frames,
                blocks[i].frames,
                blocks[j].device_bytes as f64 / 1e6,
                blocks[i].device_bytes as f64 / 1e6
            );
            if growth > 0.05 {
                Verdict::Failed(what)
            } else {
                Verdict::Passed(what)
            }
        }
    }
}

/// The verdicts of the RSS and frame-time rules on `blocks` (see [`USAGE`]).
pub fn judge(options: &Options, blocks: &[Block]) -> (Verdict, Verdict) {
    let ends: Vec<u32> = blocks.iter().map(|b| b.frames).collect();
    let too_short = |rule| {
        let period = options.period();
        Verdict::NotJudged(match options.frames_to_judge(rule) {
            Some(n) => format!(
                "needs >= {n} frames (two blocks of the same size and settings after frame {}; \
                 they repeat every {period} frames)",
                options.warmup
            ),
            None => format!(
                "no two blocks of the same size and settings after frame {} (they repeat every \
                 {period} frames)",
                options.warmup
            ),
        })
    };
    let rss = match pairs(options, &ends, Rule::Rss).first().copied() {
        None => too_short(Rule::Rss),
        Some((i, j)) => {
            let growth = blocks[i].rss as f64 / blocks[j].rss as f64 - 1.0;
            let what = format!(
                "{:+.2}% from frame {} to {} (same size and settings; bound +5%)",
                100.0 * growth,
                blocks[j].frames,
                blocks[i].frames
            );
            if growth > 0.05 {
                Verdict::Failed(what)
            } else {
                Verdict::Passed(what)
            }
        }
    };
    let compared = pairs(options, &ends, Rule::FrameTime);
    let frame_time = if options.probe_every == 0 {
        Verdict::NotJudged("--probe-every 0: no probe to cancel the machine's load".into())
    } else if compared.is_empty() {
        too_short(Rule::FrameTime)
    } else {
        let mut worst = (0.0f64, 0, 0);
        let mut unjudged = Vec::new();
        let mut failed = Vec::new();
        for &(i, j) in &compared {
            let (b, base) = (&blocks[i], &blocks[j]);
            let moved = (b.ratio() / base.ratio() - 1.0).abs();
            let load = b.probe_ms / base.probe_ms - 1.0;
            if moved > 0.2 && load.abs() > 0.2 {
                unjudged.push(format!(
                    "frame {} (ratio {:+.1}%, probe {:+.1}%)",
                    b.frames,
                    100.0 * (b.ratio() / base.ratio() - 1.0),
                    100.0 * load
                ));
                continue;
            }
            if moved > worst.0 {
                worst = (moved, i, j);
            }
            if moved > 0.2 {
                failed.push(b.frames);
            }
        }
        let (moved, i, j) = worst;
        let mut what = format!(
            "{} block pairs; largest move of frame time over the probe's {:.1}% (frame {} \
             against {}; bound 20%)",
            compared.len() - unjudged.len(),
            100.0 * moved,
            blocks[i].frames,
            blocks[j].frames
        );
        if !unjudged.is_empty() {
            what += &format!(
                "; not judged, the machine's load moved by more than 20% between the blocks: {}",
                unjudged.join(", ")
            );
        }
        if !failed.is_empty() {
            Verdict::Failed(format!("{what}; beyond the bound at frames {failed:?}"))
        } else if compared.len() == unjudged.len() {
            Verdict::NotJudged(what)
        } else {
            Verdict::Passed(what)
        }
    };
    (rss, frame_time)
}

/// One printed block.
#[derive(Debug, Clone)]
pub struct Block {
    /// Frames done at the end of the block.
    pub frames: u32,
    /// Size index and settings index of the block's last frame.
    pub config: (usize, usize),
    /// Resident set size at the end of the block, bytes.
    pub rss: u64,
    /// Bytes the soak's device has allocated at the end of the block (wgpu's allocator
    /// report; 0 where the backend gives none).
    pub device_bytes: u64,
    /// Median frame time in the block, ms.
    pub median_ms: f64,
    /// Median time of the block's probe frames (the same fixed frame every time, by a second
    /// facade), ms; 0 without probes.
    pub probe_ms: f64,
    /// Non-finite values read back at the block's last frame.
    pub nans: usize,
    /// Plans (passes with their details) first seen in this block: a new plan may compile a
    /// new pipeline variant, a one-time cost in time and memory.
    pub new_plans: usize,
}

impl Block {
    /// The block's frame time over its probe's: what the machine's load moves alike cancels.
    pub fn ratio(&self) -> f64 {
        self.median_ms / self.probe_ms
    }
}

/// What a soak measured.
#[derive(Debug, Clone)]
pub struct Summary {
    /// Every block.
    pub blocks: Vec<Block>,
    /// wgpu validation (and other uncaptured) errors.
    pub validation_errors: usize,
    /// The RSS rule (see [`USAGE`]).
    pub rss: Verdict,
    /// The device-memory rule (see [`USAGE`]).
    pub device_memory: Verdict,
    /// The frame-time rule (see [`USAGE`]).
    pub frame_time: Verdict,
    /// Whether the wall-clock budget ran out.
    pub over_budget: bool,
    /// Wall-clock seconds.
    pub seconds: f64,
}

impl Summary {
    /// Problems that make the soak fail (empty: passed): [`device_failures`](Self::device_failures),
    /// the process's RSS and the time budget.
    pub fn failures(&self) -> Vec<String> {
        let mut f = self.device_failures();
        // RSS flat within 5% after the warm-up.
        if let Verdict::Failed(what) = &self.rss {
            f.push(format!("RSS {what}"));
        }
        if self.over_budget {
            f.push(format!("over the time budget ({:.0} s)", self.seconds));
        }
        f
    }

    /// What the soak's own device did wrong, whatever else the process runs meanwhile (empty:
    /// nothing): validation errors, non-finite values read back, device memory growing.
    pub fn device_failures(&self) -> Vec<String> {
        let mut f = Vec::new();
        if self.validation_errors > 0 {
            f.push(format!("{} wgpu validation errors", self.validation_errors));
        }
        let nans: usize = self.blocks.iter().map(|b| b.nans).sum();
        if nans > 0 {
            f.push(format!("{nans} non-finite values read back"));
        }
        if let Verdict::Failed(what) = &self.device_memory {
            f.push(format!("device memory {what}"));
        }
        f
    }

    /// Frame time that is not flat against the interleaved probe (see [`USAGE`]). Checked by
    /// the example only: timings on a shared machine are not test assertions.
    pub fn timing_failures(&self) -> Vec<String> {
        match &self.frame_time {
            Verdict::Failed(what) => vec![format!("frame time {what}")],
            _ => Vec::new(),
        }
    }
}

/// Resident set size of this process (`VmRSS`), bytes.
pub fn rss_bytes() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmRSS:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|v| v.parse::<u64>().ok())
        })
        .map_or(0, |kb| kb * 1024)
}

/// The four settings the soak cycles through (all writing `Rgba16Float`).
pub fn settings_cycle(kind: AdapterKind) -> Result<Vec<Settings>, BoxError> {
    let format = wgpu::TextureFormat::Rgba16Float;
    let default = Settings {
        output_format: format,
        ..Settings::for_adapter(kind)
    };
    Ok(vec![
        default,
        Settings {
            output_format: format,
            ..Settings::for_error_target(0.05, kind)?
        },
        Settings {
            march: MarchSettings {
                method: MarchMethod::BruteForce,
                steps: 32,
                scale: Scale::Full,
                ..default.march
            },
            table: TableSize {
                along_ray: 64,
                across_rays: 128,
            },
            shadow_map: ShadowMapSettings {
                resolution: 512,
                ..default.shadow_map
            },
            ..default
        },
        Settings {
            march: MarchSettings {
                scale: Scale::Quarter,
                bisections: 0,
                ..default.march
            },
            upsample: UpsampleFilter::Bilinear,
            shadow_map: ShadowMapSettings {
                resolution: 768,
                ..default.shadow_map
            },
            ..default
        },
    ])
}

/// The frame sizes the soak alternates between.
fn sizes((w, h): (u32, u32)) -> [(u32, u32); SIZES] {
    [(w, h), ((w * 3 / 4) | 1, (h * 3 / 4) | 1)]
}

/// The app's per-frame parameters (WGSL `App`).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct AppParams {
    world_from_clip: [f32; 16],
    clip_from_world: [f32; 16],
    eye: [f32; 4],
    light: [f32; 4],
    size: [f32; 4],
    spheres: [[f32; 4]; 3],
}

/// The app's colour, depth and volshadow's output at one size.
struct Targets {
    size: (u32, u32),
    color: wgpu::Texture,
    depth: wgpu::Texture,
    output: wgpu::Texture,
}

impl Targets {
    fn new(device: &wgpu::Device, size: (u32, u32)) -> Self {
        let tex =
            |label, format, usage| device.create_texture(&texture_desc(label, size, format, usage));
        let attach = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING;
        Self {
            size,
            color: tex("soak colour", wgpu::TextureFormat::Rgba16Float, attach),
            depth: tex("soak depth", wgpu::TextureFormat::Depth32Float, attach),
            output: tex(
                "soak output",
                wgpu::TextureFormat::Rgba16Float,
                wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            ),
        }
    }
}

/// Counts the non-finite values of a `Rgba16Float` or `Rgba32Float` texture.
fn non_finite(gpu: &HeadlessGpu, texture: &wgpu::Texture) -> Result<usize, BoxError> {
    let bytes = gpu.read_texture_bytes(texture)?;
    Ok(match texture.format() {
        wgpu::TextureFormat::Rgba16Float => bytemuck::pod_collect_to_vec::<u8, half::f16>(&bytes)
            .iter()
            .filter(|v| !v.is_finite())
            .count(),
        _ => bytemuck::pod_collect_to_vec::<u8, f32>(&bytes)
            .iter()
            .filter(|v| !v.is_finite())
            .count(),
    })
}

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values.get(values.len() / 2).copied().unwrap_or(0.0)
}

/// Everything that moves, at animation time `t` (seconds / 50) for a frame of `size`.
struct Scene {
    camera: Camera,
    eye: Vec3,
    point: Vec3,
    spot: Light,
    medium: Medium,
    spheres: [(Vec3, f32); 3],
}

impl Scene {
    fn at(t: f32, size: (u32, u32)) -> Result<Self, BoxError> {
        let eye = Vec3::new(
            6.0 * (0.3 * t).sin(),
            1.8 + 0.3 * (0.7 * t).sin(),
            6.0 * (0.3 * t).cos(),
        );
        let camera = Camera::new(
            volshadow::glam::camera::rh::view::look_at_mat4(eye, Vec3::new(0.0, 1.0, 0.0), Vec3::Y),
            volshadow::glam::camera::rh::proj::directx::perspective(
                (55.0 + 10.0 * (0.5 * t).sin()).to_radians(),
                size.0 as f32 / size.1 as f32,
                0.05,
                200.0,
            ),
        )?;
        let point = Vec3::new(2.0 * t.cos(), 3.5 + 0.5 * (1.3 * t).sin(), 2.0 * t.sin());
        let spot = Light::from(SpotLight::new(
            Vec3::new(-2.0, 4.5, 0.5 * t.sin()),
            Vec3::new(0.4 * (0.8 * t).cos(), -1.0, 0.4 * (0.8 * t).sin()),
            0.7,
            Vec3::splat(30.0),
        )?);
        let density = 1.0 + 0.2 * (0.9 * t).sin();
        let medium = Medium::new(
            density * Vec3::new(0.10, 0.11, 0.13),
            Vec3::splat(0.01),
            PhaseFunction::HenyeyGreenstein { g: 0.6 },
        )?;
        let spheres = [
            (
                Vec3::new(1.2 * (0.6 * t).cos(), 1.6, 1.2 * (0.6 * t).sin()),
                0.5,
            ),
            (Vec3::new(-1.0, 1.2 + 0.4 * (0.9 * t).sin(), 0.5), 0.4),
            (
                Vec3::new(0.3, 2.3, -1.0 + 0.5 * (0.4 * t).cos()),
                0.3 + 0.05 * t.sin(),
            ),
        ];
        Ok(Self {
            camera,
            eye,
            point,
            spot,
            medium,
            spheres,
        })
    }
}

/// What every frame draws with: the app's pass, the sphere mesh, the spot's texture.
struct Assets {
    app_pass: FullscreenPass,
    sphere: OccluderMesh,
    spot_texture: wgpu::Texture,
}

/// The app's pass and `vs` for `scene` into `targets`, submitted and waited for; returns the
/// plan (passes with their details).
fn render(
    gpu: &HeadlessGpu,
    assets: &Assets,
    vs: &mut VolumetricShadows,
    targets: &Targets,
    scene: &Scene,
) -> Result<Vec<String>, BoxError> {
    let device = &gpu.device;
    let size = targets.size;
    let camera = &scene.camera;
    let point = Light::from(PointLight::new(scene.point, Vec3::new(40.0, 36.0, 30.0))?);
    let lights = [
        FrameLight::from(point),
        FrameLight {
            light: scene.spot,
            texture: Some(&assets.spot_texture),
            casters: None,
            texture_channels: Default::default(),
        },
    ];
    let occluders: Vec<Occluder> = scene
        .spheres
        .iter()
        .map(|&(c, r)| Occluder {
            mesh: &assets.sphere,
            transform: Mat4::from_translation(c) * Mat4::from_scale(Vec3::splat(r)),
        })
        .collect();

    // The app's frame, then volshadow, in one encoder.
    let params = AppParams {
        world_from_clip: camera.world_from_clip().to_cols_array(),
        clip_from_world: (camera.projection() * camera.view()).to_cols_array(),
        eye: scene.eye.extend(1.0).to_array(),
        light: scene.point.extend(camera.far_depth()).to_array(),
        size: [size.0 as f32, size.1 as f32, 0.0, 0.0],
        spheres: scene.spheres.map(|(c, r)| c.extend(r).to_array()),
    };
    let mut encoder = device.create_command_encoder(&Default::default());
    assets.app_pass.encode(
        &gpu.queue,
        &mut encoder,
        &params,
        (&targets.color, &targets.depth),
        camera.far_depth(),
    );
    vs.prepare(
        device,
        &gpu.queue,
        &Frame {
            camera,
            lights: &lights,
            medium: &scene.medium,
            occluders: &occluders,
            scene_color: &targets.color,
            scene_depth: &targets.depth,
            surfaces: None,
        },
    )?;
    let plan = vs
        .plan()
        .steps
        .iter()
        .map(|s| format!("{:?} {} {}", s.light, s.pass, s.detail))
        .collect();
    vs.encode(&mut encoder, &targets.output)?;
    gpu.submit_and_wait(encoder)?;
    Ok(plan)
}

/// Runs the soak on `gpu`, printing a line per block.
pub fn run(gpu: &HeadlessGpu, options: &Options) -> Result<Summary, BoxError> {
    let device = &gpu.device;
    let errors = Arc::new(AtomicUsize::new(0));
    let first_error = Arc::new(Mutex::new(None::<String>));
    {
        let (errors, first_error) = (errors.clone(), first_error.clone());
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            errors.fetch_add(1, Ordering::Relaxed);
            let mut first = first_error.lock().unwrap_or_else(|p| p.into_inner());
            if first.is_none() {
                *first = Some(e.to_string());
            }
        }));
    }

    // The app's pass (one pipeline, parameters in a storage buffer) and volshadow's inputs.
    let assets = Assets {
        app_pass: FullscreenPass::new(
            device,
            "soak app",
            include_str!("soak.wgsl"),
            std::mem::size_of::<AppParams>(),
        ),
        sphere: OccluderMesh::new(device, &shapes::uv_sphere(Vec3::ZERO, 1.0, 32, 16).unwrap()),
        spot_texture: LightTexture::checkerboard(
            64,
            8,
            Vec3::new(1.0, 0.8, 0.5),
            Vec3::new(0.2, 0.4, 1.0),
        )?
        .upload(device, &gpu.queue),
    };
    let cache = Cache::new(device);
    let cycle = settings_cycle(AdapterKind::of(device))?;
    let sizes = sizes(options.size);
    // The animation repeats with the sizes and settings, so blocks of the same configuration
    // render the same frames and their times compare like with like.
    let period = options.period();
    let mut vs = VolumetricShadows::new(device, &gpu.queue, &cache, cycle[0])?;
    let mut targets: Option<Targets> = None;
    // The probe: a second facade rendering one fixed frame (the first frame's size, settings
    // and animation) after every `probe_every`-th soak frame. It never changes, so its time
    // follows only the machine's load, which it shares with the soak frames around it.
    let mut probe_vs = VolumetricShadows::new(device, &gpu.queue, &cache, cycle[0])?;
    let probe_targets = Targets::new(device, sizes[0]);
    let probe_scene = Scene::at(0.0, sizes[0])?;

    let start = Instant::now();
    let mut blocks: Vec<Block> = Vec::new();
    let mut times: Vec<f64> = Vec::new();
    let mut probe_times: Vec<f64> = Vec::new();
    let mut plans_seen = std::collections::HashSet::new();
    let mut new_plans = 0;
    let mut over_budget = false;
    println!(
        "soak: {} frames after {} warm-up frames, sizes {:?}, {} settings (repeating every {} \
         frames), a probe frame after every {} frames, on {}",
        options.frames,
        sizes.len() * cycle.len(),
        sizes,
        cycle.len(),
        period,
        options.probe_every,
        gpu.adapter_summary()
    );
    // One frame in every size and settings first, as a game compiles its pipelines while
    // loading: first use of a configuration compiles pipeline variants and grows the driver's
    // and the allocator's pools once; the soak measures what happens after that.
    let combos: Vec<(usize, usize)> = (0..cycle.len())
        .flat_map(|s| (0..sizes.len()).map(move |z| (z, s)))
        .collect();
    let warm = combos.len() as u32;
    if options.probe_every > 0 {
        render(gpu, &assets, &mut probe_vs, &probe_targets, &probe_scene)?;
    }
    for step in 0..warm + options.frames {
        let t0 = Instant::now();
        let (frame, (size_index, settings_index)) = match step.checked_sub(warm) {
            Some(frame) => (frame, options.config(frame)),
            None => (0, combos[step as usize]),
        };
        let size = sizes[size_index];
        if targets.as_ref().is_none_or(|t| t.size != size) {
            targets = Some(Targets::new(device, size));
        }
        let targets = targets.as_ref().expect("made above");
        if vs.settings() != cycle[settings_index] {
            vs.set_settings(cycle[settings_index])?;
        }

        // Everything moves.
        let scene = Scene::at((frame % period) as f32 * 0.02, size)?;
        let plan = render(gpu, &assets, &mut vs, targets, &scene)?;
        if plans_seen.insert((settings_index, plan)) && step >= warm {
            new_plans += 1;
        }
        if step < warm {
            continue;
        }
        times.push(t0.elapsed().as_secs_f64() * 1e3);
        if options.probe_every > 0 && (frame + 1) % options.probe_every == 0 {
            let t1 = Instant::now();
            render(gpu, &assets, &mut probe_vs, &probe_targets, &probe_scene)?;
            probe_times.push(t1.elapsed().as_secs_f64() * 1e3);
        }

        let done = frame + 1;
        if done % options.report_every == 0 || done == options.frames {
            let mut nans = non_finite(gpu, &targets.output)?;
            for light in 0..2 {
                if let Some(inscatter) = vs.inscatter(light) {
                    nans += non_finite(gpu, inscatter)?;
                }
            }
            let block = Block {
                frames: done,
                config: (size_index, settings_index),
                rss: rss_bytes(),
                device_bytes: gpu
                    .device
                    .generate_allocator_report()
                    .map_or(0, |r| r.total_allocated_bytes),
                median_ms: median(&mut times),
                probe_ms: median(&mut probe_times),
                nans,
                new_plans: std::mem::take(&mut new_plans),
            };
            times.clear();
            probe_times.clear();
            println!(
                "frame {:5}  RSS {:7.1} MB  device {:7.1} MB  frame {:7.2} ms (median)  \
                 probe {:7.2} ms  size {}x{}  settings {}  new plans {}  NaN/Inf {}  \
                 validation errors {}",
                block.frames,
                block.rss as f64 / 1e6,
                block.device_bytes as f64 / 1e6,
                block.median_ms,
                block.probe_ms,
                size.0,
                size.1,
                settings_index,
                block.new_plans,
                block.nans,
                errors.load(Ordering::Relaxed)
            );
            blocks.push(block);
        }
        if options
            .max_seconds
            .is_some_and(|s| start.elapsed().as_secs_f64() > s)
        {
            over_budget = true;
            println!(
                "time budget of {:?} s spent at frame {done}",
                options.max_seconds
            );
            break;
        }
    }
    if let Some(e) = first_error
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .as_ref()
    {
        println!("first validation error: {e}");
    }

    let (rss, frame_time) = judge(options, &blocks);
    let device_memory = judge_device_memory(options, &blocks);
    let summary = Summary {
        blocks,
        validation_errors: errors.load(Ordering::Relaxed),
        rss,
        device_memory,
        frame_time,
        over_budget,
        seconds: start.elapsed().as_secs_f64(),
    };
    let nans: usize = summary.blocks.iter().map(|b| b.nans).sum();
    println!(
        "errors: {} validation errors, {nans} NaN/Inf read back",
        summary.validation_errors
    );
    println!("RSS after frame {}: {}", options.warmup, summary.rss);
    println!(
        "device memory after frame {}: {}",
        options.warmup, summary.device_memory
    );
    println!(
        "frame time (each block's median over its interleaved probe's), after frame {}: {}",
        options.warmup, summary.frame_time
    );
    println!("{:.0} s", summary.seconds);
    Ok(summary)
}

fn lcm(a: u32, b: u32) -> u32 {
    let (mut x, mut y) = (a, b);
    while y != 0 {
        (x, y) = (y, x % y);
    }
    a / x.max(1) * b
}

/// The `soak` binary: parses the command line, runs, prints the verdict; exit status 1 when a
/// rule fails.
pub fn main() {
    headless_env::quiet_display_probe();
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = Options::parse(&args).and_then(|command| match command {
        Command::Help => {
            print!("{USAGE}");
            std::process::exit(0);
        }
        Command::Run(options) => {
            let gpu = HeadlessGpu::new()?;
            run(&gpu, &options)
        }
    });
    match result {
        Ok(summary) if summary.failures().is_empty() && summary.timing_failures().is_empty() => {
            println!("soak passed")
        }
        Ok(summary) => {
            let failures = [summary.failures(), summary.timing_failures()].concat();
            eprintln!("soak FAILED: {}", failures.join("; "));
            std::process::exit(1);
        }
        Err(e) => {
            eprintln!("soak FAILED: {e}");
            std::process::exit(1);
        }
    }
}
