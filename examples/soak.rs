//! Soak: the facade for many frames with everything animated — the camera, a point light and a
//! textured spot light, three spheres move every frame, the medium's density breathes, the
//! frame is resized every `--resize-every` frames and the settings are switched every
//! `--settings-every` frames (four settings: the default hybrid, an error target, brute force
//! with a smaller table and shadow map, quarter-resolution bilinear).
//!
//! It first renders one frame in every size and settings (as a game compiles its pipelines
//! while loading), then every `--report-every` frames it prints the resident set size (`VmRSS`), the median frame
//! time of the block, the NaN/Inf count of the output and of each light's in-scatter (read
//! back at the block's last frame) and the wgpu validation errors so far (an uncaptured-error
//! handler counts them). It exits non-zero on any error, NaN or validation error, or when the
//! RSS grows by more than 5% from the first block after `--warmup` frames to the end (compared
//! between blocks of the same size and settings: textures live in host memory on a CPU
//! adapter, so different configurations have different footprints).
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

use volshadow::glam::{Mat4, Vec3};
use volshadow::nodes::UpsampleFilter;
use volshadow::nodes::{MarchMethod, MarchSettings, Scale, ShadowMapSettings, TableSize};
use volshadow::scene::{shapes, LightTexture};
use volshadow::{
    Cache, Camera, Frame, FrameLight, HeadlessGpu, Light, Medium, Occluder, OccluderMesh,
    PhaseFunction, PointLight, Settings, SpotLight, VolumetricShadows,
};

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
        let mut it = args.iter();
        while let Some(flag) = it.next() {
            let mut value = || {
                it.next()
                    .ok_or_else(|| format!("{flag} needs a value"))
                    .cloned()
            };
            match flag.as_str() {
                "--frames" => o.frames = value()?.parse()?,
                "--size" => {
                    let v = value()?;
                    let (w, h) = v.split_once('x').ok_or("--size is WIDTHxHEIGHT")?;
                    o.size = (w.parse()?, h.parse()?);
                }
                "--report-every" => o.report_every = value()?.parse()?,
                "--resize-every" => o.resize_every = value()?.parse()?,
                "--settings-every" => o.settings_every = value()?.parse()?,
                "--warmup" => o.warmup = value()?.parse()?,
                "--max-seconds" => o.max_seconds = Some(value()?.parse()?),
                other => return Err(format!("unknown argument {other}").into()),
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

const APP_WGSL: &str = r#"
struct App {
    world_from_clip: mat4x4<f32>,
    clip_from_world: mat4x4<f32>,
    eye: vec4<f32>,
    light: vec4<f32>,   // xyz position, w: far depth
    size: vec4<f32>,
    spheres: array<vec4<f32>, 3>,
}
@group(0) @binding(0) var<storage, read> app: App;

struct Out {
    @location(0) color: vec4<f32>,
    @builtin(frag_depth) depth: f32,
}

@vertex fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

fn hit_sphere(o: vec3<f32>, d: vec3<f32>, s: vec4<f32>) -> f32 {
    let oc = o - s.xyz;
    let b = dot(oc, d);
    let disc = b * b - (dot(oc, oc) - s.w * s.w);
    if (disc < 0.0) { return -1.0; }
    let t = -b - sqrt(disc);
    return select(-1.0, t, t > 1e-4);
}

@fragment fn fs(@builtin(position) p: vec4<f32>) -> Out {
    let ndc = vec2<f32>(p.x / app.size.x * 2.0 - 1.0, 1.0 - p.y / app.size.y * 2.0);
    let a = app.world_from_clip * vec4<f32>(ndc, 0.0, 1.0);
    let b = app.world_from_clip * vec4<f32>(ndc, 0.5, 1.0);
    let o = app.eye.xyz;
    let d = normalize(b.xyz / b.w - a.xyz / a.w);
    var t = 1e30;
    var n = vec3<f32>(0.0, 1.0, 0.0);
    if (d.y < 0.0) { t = -o.y / d.y; }
    for (var k = 0; k < 3; k++) {
        let ts = hit_sphere(o, d, app.spheres[k]);
        if (ts > 0.0 && ts < t) {
            t = ts;
            n = normalize(o + t * d - app.spheres[k].xyz);
        }
    }
    var out: Out;
    if (t >= 1e30) {
        out.color = vec4<f32>(0.0, 0.0, 0.0, 1.0);
        out.depth = app.light.w;
        return out;
    }
    let x = o + t * d;
    let l = app.light.xyz - x;
    let e = 20.0 / dot(l, l);
    out.color = vec4<f32>(vec3<f32>(0.5 / 3.14159265 * e * max(dot(n, normalize(l)), 0.0) + 0.01), 1.0);
    let clip = app.clip_from_world * vec4<f32>(x, 1.0);
    out.depth = clip.z / clip.w;
    return out;
}
"#;

/// The app's colour, depth and volshadow's output at one size.
struct Targets {
    size: (u32, u32),
    color: wgpu::Texture,
    depth: wgpu::Texture,
    output: wgpu::Texture,
}

impl Targets {
    fn new(device: &wgpu::Device, size: (u32, u32)) -> Self {
        let tex = |label, format, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width: size.0,
                    height: size.1,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
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
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("soak app"),
        source: wgpu::ShaderSource::Wgsl(APP_WGSL.into()),
    });
    let app_pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("soak app"),
        layout: None,
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: Default::default(),
        depth_stencil: Some(wgpu::DepthStencilState {
            format: wgpu::TextureFormat::Depth32Float,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Always),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("fs"),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::TextureFormat::Rgba16Float.into())],
        }),
        multiview_mask: None,
        cache: None,
    });
    let app_buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("soak app parameters"),
        size: std::mem::size_of::<AppParams>() as u64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let app_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("soak app"),
        layout: &app_pipeline.get_bind_group_layout(0),
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: app_buffer.as_entire_binding(),
        }],
    });

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
        let t = frame as f32 * 0.02;
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
        gpu.queue
            .write_buffer(&app_buffer, 0, bytemuck::bytes_of(&params));
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let color = targets.color.create_view(&Default::default());
            let depth = targets.depth.create_view(&Default::default());
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("soak app"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &color,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &depth,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(camera.far_depth()),
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&app_pipeline);
            pass.set_bind_group(0, &app_bind_group, &[]);
            pass.draw(0..3, 0..1);
        }
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

#[path = "common/headless_env.rs"]
mod headless_env;

fn main() {
    headless_env::quiet_display_probe();
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = Options::parse(&args).and_then(|options| {
        let gpu = HeadlessGpu::new()?;
        run(&gpu, &options)
    });
    match result {
        Ok(summary) if summary.failures().is_empty() => println!("soak passed"),
        Ok(summary) => {
            eprintln!("soak FAILED: {}", summary.failures().join("; "));
            std::process::exit(1);
        }
        Err(e) => {
            eprintln!("soak FAILED: {e}");
            std::process::exit(1);
        }
    }
}
