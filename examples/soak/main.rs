//! Soak: the facade for many frames with everything animated — the camera, a point light and a
//! textured spot light, three spheres move every frame, the medium's density breathes, the
//! frame is resized every `--resize-every` frames and the settings are switched every
//! `--settings-every` frames (four settings: the default (exact), an error target, brute force
//! with a smaller table and shadow map, quarter-resolution bilinear).
//!
//! It first renders one frame in every size and settings (as a game compiles its pipelines
//! while loading), then every `--report-every` frames it prints the resident set size (`VmRSS`), the median frame
//! time of the block, the NaN/Inf count of the output and of each light's in-scatter (read
//! back at the block's last frame) and the wgpu validation errors so far (an uncaptured-error
//! handler counts them). It exits non-zero on any error, NaN or validation error, or when the
//! RSS grows by more than 5% from the first block after `--warmup` frames to the end (compared
//! between blocks of the same size and settings: textures live in host memory on a CPU
//! adapter, so different configurations have different footprints), or when a block's median
//! frame time is more than 20% from the first block of the same configuration. The animation
//! repeats with the cycle of sizes and settings, so those blocks render the same frames.
//!
//! ```text
//! cargo run --release --example soak -- [--frames 2000] [--size 256x144] [--report-every 100]
//!     [--resize-every 100] [--settings-every 200] [--warmup 300] [--max-seconds S]
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
    Cache, Camera, Frame, FrameLight, HeadlessGpu, Light, Medium, Occluder, OccluderMesh,
    PhaseFunction, PointLight, Settings, SpotLight, VolumetricShadows,
};

#[path = "../common/fullscreen.rs"]
mod fullscreen;
#[path = "../common/headless_env.rs"]
mod headless_env;

use fullscreen::{texture_desc, FullscreenPass};

type BoxError = Box<dyn std::error::Error>;

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
    /// Frames before the RSS baseline.
    pub warmup: u32,
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
            max_seconds: None,
        }
    }
}

impl Options {
    /// Parses the command line (see the module docs).
    pub fn parse(args: &[String]) -> Result<Self, BoxError> {
        let mut o = Options::default();
        let mut parser = lexopt::Parser::from_args(args);
        while let Some(arg) = parser.next()? {
            match arg {
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
                Long("max-seconds") => o.max_seconds = Some(parser.value()?.parse()?),
                _ => return Err(arg.unexpected().into()),
            }
        }
        if o.frames == 0 || o.report_every == 0 || o.resize_every == 0 || o.settings_every == 0 {
            return Err("frame counts must be positive".into());
        }
        if o.size.0 < 8 || o.size.1 < 8 {
            return Err("--size must be at least 8x8".into());
        }
        Ok(o)
    }
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
    /// Median frame time in the block, ms.
    pub median_ms: f64,
    /// Non-finite values read back at the block's last frame.
    pub nans: usize,
    /// Plans (passes with their details) first seen in this block: a new plan may compile a
    /// new pipeline variant, a one-time cost in time and memory.
    pub new_plans: usize,
}

/// What a soak measured.
#[derive(Debug, Clone)]
pub struct Summary {
    /// Every block.
    pub blocks: Vec<Block>,
    /// wgpu validation (and other uncaptured) errors.
    pub validation_errors: usize,
    /// RSS growth from the first block after the warmup to the end, same configuration.
    pub rss_growth: f64,
    /// Largest relative difference of a block's median frame time from the first block after
    /// the warmup with the same configuration.
    pub frame_time_spread: f64,
    /// Whether the wall-clock budget ran out.
    pub over_budget: bool,
    /// Wall-clock seconds.
    pub seconds: f64,
}

impl Summary {
    /// Problems that make the soak fail (empty: passed).
    pub fn failures(&self) -> Vec<String> {
        let mut f = Vec::new();
        if self.validation_errors > 0 {
            f.push(format!("{} wgpu validation errors", self.validation_errors));
        }
        let nans: usize = self.blocks.iter().map(|b| b.nans).sum();
        if nans > 0 {
            f.push(format!("{nans} non-finite values read back"));
        }
        // The issue's bound: RSS flat within 5% after the warmup.
        if self.rss_growth > 0.05 {
            f.push(format!(
                "RSS grew by {:.1}% after the warmup",
                100.0 * self.rss_growth
            ));
        }
        if self.over_budget {
            f.push(format!("over the time budget ({:.0} s)", self.seconds));
        }
        f
    }

    /// Frame time that is not flat: a block's median more than 20% (the issue's bound) from
    /// the first block of the same size, settings and animation phase. Checked by the example
    /// only: timings on a shared machine are not test assertions.
    pub fn timing_failures(&self) -> Vec<String> {
        if self.frame_time_spread > 0.2 {
            vec![format!(
                "frame time moved by {:.1}% between blocks of the same configuration",
                100.0 * self.frame_time_spread
            )]
        } else {
            Vec::new()
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
pub fn settings_cycle() -> Result<Vec<Settings>, BoxError> {
    let format = wgpu::TextureFormat::Rgba16Float;
    let default = Settings {
        output_format: format,
        ..Settings::default()
    };
    Ok(vec![
        default,
        Settings {
            output_format: format,
            ..Settings::for_error_target(0.05)?
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
fn sizes((w, h): (u32, u32)) -> [(u32, u32); 2] {
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

    // The app's pass: one pipeline, parameters in a storage buffer.
    let app_pass = FullscreenPass::new(
        device,
        "soak app",
        include_str!("app.wgsl"),
        std::mem::size_of::<AppParams>(),
    );

    // volshadow.
    let cache = Cache::new(device);
    let sphere = OccluderMesh::new(device, &shapes::uv_sphere(Vec3::ZERO, 1.0, 32, 16).unwrap());
    let spot_texture =
        LightTexture::checkerboard(64, 8, Vec3::new(1.0, 0.8, 0.5), Vec3::new(0.2, 0.4, 1.0))?
            .upload(device, &gpu.queue);
    let cycle = settings_cycle()?;
    let sizes = sizes(options.size);
    let config = |frame: u32| {
        (
            (frame / options.resize_every) as usize % sizes.len(),
            (frame / options.settings_every) as usize % cycle.len(),
        )
    };
    // The animation repeats with the sizes and settings, so blocks of the same configuration
    // render the same frames and their times compare like with like.
    let period = lcm(
        sizes.len() as u32 * options.resize_every,
        cycle.len() as u32 * options.settings_every,
    );
    let mut vs = VolumetricShadows::new(device, &gpu.queue, &cache, cycle[0])?;
    let mut targets: Option<Targets> = None;

    let start = Instant::now();
    let mut blocks: Vec<Block> = Vec::new();
    let mut times: Vec<f64> = Vec::new();
    let mut plans_seen = std::collections::HashSet::new();
    let mut new_plans = 0;
    let mut over_budget = false;
    println!(
        "soak: {} frames after {} warm-up frames, sizes {:?}, {} settings, on {}",
        options.frames,
        sizes.len() * cycle.len(),
        sizes,
        cycle.len(),
        gpu.adapter_summary()
    );
    // One frame in every size and settings first, as a game compiles its pipelines while
    // loading: first use of a configuration compiles pipeline variants and grows the driver's
    // and the allocator's pools once; the soak measures what happens after that.
    let combos: Vec<(usize, usize)> = (0..cycle.len())
        .flat_map(|s| (0..sizes.len()).map(move |z| (z, s)))
        .collect();
    let warm = combos.len() as u32;
    for step in 0..warm + options.frames {
        let t0 = Instant::now();
        let (frame, (size_index, settings_index)) = match step.checked_sub(warm) {
            Some(frame) => (frame, config(frame)),
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
        let t = (frame % period) as f32 * 0.02;
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
        let point_pos = Vec3::new(2.0 * t.cos(), 3.5 + 0.5 * (1.3 * t).sin(), 2.0 * t.sin());
        let point = Light::from(PointLight::new(point_pos, Vec3::new(40.0, 36.0, 30.0))?);
        let spot = Light::from(SpotLight::new(
            Vec3::new(-2.0, 4.5, 0.5 * t.sin()),
            Vec3::new(0.4 * (0.8 * t).cos(), -1.0, 0.4 * (0.8 * t).sin()),
            0.7,
            Vec3::splat(30.0),
        )?);
        let lights = [
            FrameLight::from(point),
            FrameLight {
                light: spot,
                texture: Some(&spot_texture),
            },
        ];
        let density = 1.0 + 0.2 * (0.9 * t).sin();
        let medium = Medium::new(
            density * Vec3::new(0.10, 0.11, 0.13),
            Vec3::splat(0.01),
            PhaseFunction::HenyeyGreenstein { g: 0.6 },
        )?;
        let spheres: [(Vec3, f32); 3] = [
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
        let occluders: Vec<Occluder> = spheres
            .iter()
            .map(|&(c, r)| Occluder {
                mesh: &sphere,
                transform: Mat4::from_translation(c) * Mat4::from_scale(Vec3::splat(r)),
            })
            .collect();

        // The app's frame, then volshadow, in one encoder.
        let params = AppParams {
            world_from_clip: camera.world_from_clip().to_cols_array(),
            clip_from_world: (camera.projection() * camera.view()).to_cols_array(),
            eye: eye.extend(1.0).to_array(),
            light: point_pos.extend(camera.far_depth()).to_array(),
            size: [size.0 as f32, size.1 as f32, 0.0, 0.0],
            spheres: spheres.map(|(c, r)| c.extend(r).to_array()),
        };
        let mut encoder = device.create_command_encoder(&Default::default());
        let app_targets = (&targets.color, &targets.depth);
        app_pass.encode(
            &gpu.queue,
            &mut encoder,
            &params,
            app_targets,
            camera.far_depth(),
        );
        vs.prepare(
            device,
            &gpu.queue,
            &Frame {
                camera: &camera,
                lights: &lights,
                medium: &medium,
                occluders: &occluders,
                scene_color: &targets.color,
                scene_depth: &targets.depth,
                surfaces: None,
            },
        )?;
        let plan: Vec<String> = vs
            .plan()
            .steps
            .iter()
            .map(|s| format!("{:?} {} {}", s.light, s.pass, s.detail))
            .collect();
        if plans_seen.insert((settings_index, plan)) && step >= warm {
            new_plans += 1;
        }
        vs.encode(&mut encoder, &targets.output)?;
        gpu.submit_and_wait(encoder)?;
        if step < warm {
            continue;
        }
        times.push(t0.elapsed().as_secs_f64() * 1e3);

        let done = frame + 1;
        if done % options.report_every == 0 || done == options.frames {
            let mut nans = non_finite(gpu, &targets.output)?;
            for light in 0..lights.len() {
                if let Some(inscatter) = vs.inscatter(light) {
                    nans += non_finite(gpu, inscatter)?;
                }
            }
            let block = Block {
                frames: done,
                config: (size_index, settings_index),
                rss: rss_bytes(),
                median_ms: median(&mut times),
                nans,
                new_plans: std::mem::take(&mut new_plans),
            };
            times.clear();
            println!(
                "frame {:5}  RSS {:7.1} MB  frame {:7.2} ms (median)  size {}x{}  settings {}  \
                 new plans {}  NaN/Inf {}  validation errors {}",
                block.frames,
                block.rss as f64 / 1e6,
                block.median_ms,
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

    // RSS growth and frame-time spread after the warmup, each block against the first block
    // after the warmup with the same size and settings.
    let after: Vec<&Block> = blocks
        .iter()
        .filter(|b| b.frames > options.warmup)
        .collect();
    let baseline = |b: &Block| after.iter().find(|a| a.config == b.config).copied();
    let rss_growth = after.last().map_or(0.0, |last| {
        let base = baseline(last).unwrap_or(after[0]);
        last.rss as f64 / base.rss as f64 - 1.0
    });
    let frame_time_spread = after
        .iter()
        .filter_map(|b| baseline(b).map(|base| (b.median_ms / base.median_ms - 1.0).abs()))
        .fold(0.0, f64::max);
    let summary = Summary {
        blocks,
        validation_errors: errors.load(Ordering::Relaxed),
        rss_growth,
        frame_time_spread,
        over_budget,
        seconds: start.elapsed().as_secs_f64(),
    };
    println!(
        "RSS growth after frame {}: {:+.2}% (same configuration); frame time spread across \
         same-configuration blocks: {:.1}%; {} validation errors; {:.0} s",
        options.warmup,
        100.0 * summary.rss_growth,
        100.0 * summary.frame_time_spread,
        summary.validation_errors,
        summary.seconds
    );
    Ok(summary)
}

fn lcm(a: u32, b: u32) -> u32 {
    let (mut x, mut y) = (a, b);
    while y != 0 {
        (x, y) = (y, x % y);
    }
    a / x.max(1) * b
}

fn main() {
    headless_env::quiet_display_probe();
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = Options::parse(&args).and_then(|options| {
        let gpu = HeadlessGpu::new()?;
        run(&gpu, &options)
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
