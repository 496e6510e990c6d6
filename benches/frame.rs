//! The whole-frame cost of the facade on the standard scenes, the light and the camera moving
//! every frame.
//!
//! ```text
//! cargo bench --bench frame [-- [--size WxH] [--scenes A.json,B.json] [--method METHOD]
//!                                [--frames N] [--warmup N] [--passes] [--raster-composite]
//!                                [--raster-crossings] [--work] [--out FILE.json]]
//! ```
//!
//! `benches/scenes/` holds scenes for this bench alone (the tests do not draw them):
//! `door_ajar.json`, a room lit through a door ajar by a lamp wider than the gap, the exact
//! soft shadows' costly case (`--scenes benches/scenes/door_ajar.json`).
//!
//! Per scene (default: every `scenes/*.json`), after `--warmup` frames (default 5), `--frames`
//! frames (default 30) are recorded and submitted back to back, as an application's frame loop
//! would: each frame moves the lights (by a hundred-thousandth of their distance) and turns the
//! camera (by 1e-4 rad), so every pass that depends on them runs and nothing is recreated. The
//! application's own colour and depth are drawn once (a real application redraws them; their
//! cost is not volshadow's).
//!
//! * **GPU time per frame**: on a GPU, one timestamp pair around each frame's passes (an empty
//!   compute pass before and after them); on a CPU adapter (lavapipe), whose timestamps do not
//!   bracket compute dispatches, the wall clock of the frame's submission waited for alone
//!   (there the submission is the run). Median, p10 and p90 over the frames.
//! * **Wall time per frame**: the frames submitted back to back without waiting, the time to
//!   the last one's completion divided by their number (prepare and recording included).
//! * `--passes`: each pass's median GPU time as well (`VolumetricShadows::run_timed`, one extra
//!   round of frames).
//! * `--raster-composite`: the output target without `STORAGE_BINDING`, so that the composite
//!   goes through the rasteriser instead of a compute pass.
//! * `--raster-crossings`: the exact method's crossing lists built by the rasteriser
//!   ([`CrossingsBuild::Raster`](volshadow::nodes::CrossingsBuild)) instead of compute passes.
//! * `--work`: instead of times, the work of one frame (after the warm-up), which any adapter
//!   counts alike: render and compute passes recorded ([`volshadow::passes_recorded`]),
//!   shadow-map texels cleared (the layers each shadow-map step renders; for a map drawn on
//!   demand, only in a frame whose gate opened) and written (those holding an occluder's
//!   depth after the frame), and per pixel of each light's march, from
//!   its work counters ([`VolumetricShadows::set_work_counters`], a pipeline constant the
//!   frame's own pipelines leave off): crossings stored and visited, shadow-map lookups,
//!   light-texture samples (with the cells of its flat-region map read) and march steps, as
//!   mean and p99 over the march's pixels (texture samples also as the mean over the pixels
//!   that take any: the lit ones).
//!
//! `--size` defaults to 1920x1080 on a GPU and 256x144 on a CPU adapter; `--method` to each
//! scene's own (`render`'s syntax: `exact[:SCALE]`, `hybrid:STEPS:SCALE`, `brute:STEPS`,
//! `textbook:STEPS`, `analytic`). Prints a table and writes JSON (default
//! `target/bench-frame.json`). Adapter choice: `WGPU_BACKEND`, `WGPU_ADAPTER_NAME`.

use std::path::PathBuf;
use std::time::Instant;

use lexopt::prelude::*;
use volshadow::glam::Mat4;
use volshadow::plan::Pass;
use volshadow::scene_file::{Method, SceneDescription};
use volshadow::{Cache, Camera, FrameLight, HeadlessGpu, Settings, VolumetricShadows};
use volshadow_harness::app::{parse_size, with_aspect, BoxError};
use volshadow_harness::render_scene::{GpuScene, RenderMethod};
use volshadow_harness::report::moved_lights;

struct Options {
    size: Option<(u32, u32)>,
    scenes: Vec<PathBuf>,
    method: Option<RenderMethod>,
    frames: usize,
    warmup: usize,
    passes: bool,
    raster_composite: bool,
    raster_crossings: bool,
    work: bool,
    out: PathBuf,
}

const USAGE: &str = "usage: cargo bench --bench frame [-- [--size WxH] [--scenes A.json,B.json] \
[--method METHOD] [--frames N] [--warmup N] [--passes] [--raster-composite] \
[--raster-crossings] [--work] [--out FILE.json]]";

fn parse() -> Result<Options, BoxError> {
    let mut o = Options {
        size: None,
        scenes: Vec::new(),
        method: None,
        frames: 30,
        warmup: 5,
        passes: false,
        raster_composite: false,
        raster_crossings: false,
        work: false,
        out: PathBuf::from("target/bench-frame.json"),
    };
    let mut parser = lexopt::Parser::from_env();
    while let Some(arg) = parser.next()? {
        match arg {
            Long("size") => o.size = Some(parse_size(&parser.value()?.string()?)?),
            Long("scenes") => {
                o.scenes = parser
                    .value()?
                    .string()?
                    .split(',')
                    .map(PathBuf::from)
                    .collect()
            }
            Long("method") => o.method = Some(RenderMethod::parse(&parser.value()?.string()?)?),
            Long("frames") => o.frames = parser.value()?.parse()?,
            Long("warmup") => o.warmup = parser.value()?.parse()?,
            Long("passes") => o.passes = true,
            Long("raster-composite") => o.raster_composite = true,
            Long("raster-crossings") => o.raster_crossings = true,
            Long("work") => o.work = true,
            Long("out") => o.out = parser.value()?.into(),
            // `cargo bench` passes `--bench` to every bench binary.
            Long("bench") => {}
            Long("help") | Short('h') => {
                println!("{USAGE}");
                std::process::exit(0);
            }
            _ => return Err(format!("{}\n{USAGE}", arg.unexpected()).into()),
        }
    }
    if o.frames == 0 {
        return Err("--frames must be at least 1".into());
    }
    if o.scenes.is_empty() {
        let mut all: Vec<PathBuf> = std::fs::read_dir("scenes")?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "json"))
            .collect();
        all.sort();
        o.scenes = all;
    }
    Ok(o)
}

/// The value at quantile `q` of sorted `v`.
fn quantile(v: &[f64], q: f64) -> f64 {
    v[((v.len() - 1) as f64 * q).round() as usize]
}

struct Row {
    scene: String,
    method: String,
    frame_ms: [f64; 3],
    wall_ms: f64,
    passes: Vec<(String, f64)>,
    work: Option<Work>,
}

/// One frame's work (`--work`).
struct Work {
    render_passes: u64,
    compute_passes: u64,
    /// Shadow-map texels cleared and written, over every light's map.
    map_cleared: u64,
    map_written: u64,
    /// Per light with a march.
    lights: Vec<LightWork>,
}

/// Mean and p99 of a per-pixel count.
#[derive(Clone, Copy)]
struct Spread {
    mean: f64,
    p99: f64,
}

impl Spread {
    fn of(v: &[u32]) -> Self {
        if v.is_empty() {
            return Spread {
                mean: 0.0,
                p99: 0.0,
            };
        }
        let mut sorted = v.to_vec();
        sorted.sort_unstable();
        Spread {
            mean: v.iter().map(|&x| f64::from(x)).sum::<f64>() / v.len() as f64,
            p99: f64::from(sorted[((sorted.len() - 1) as f64 * 0.99).round() as usize]),
        }
    }

    fn json(self) -> serde_json::Value {
        serde_json::json!({ "mean": self.mean, "p99": self.p99 })
    }
}

struct LightWork {
    light: usize,
    pixels: usize,
    stored: Spread,
    visited: Spread,
    lookups: Spread,
    samples: Spread,
    /// Texture samples per pixel over the pixels with any.
    samples_lit: f64,
    steps: Spread,
}

/// Records and runs one frame with the marches' work counters on, and counts its work.
fn count_work(
    gpu: &HeadlessGpu,
    vs: &mut VolumetricShadows,
    frame: &volshadow::Frame<'_>,
    output: &wgpu::Texture,
) -> Result<Work, BoxError> {
    vs.set_work_counters(true);
    vs.prepare(&gpu.device, &gpu.queue, frame)?;
    let mut work = Work {
        render_passes: 0,
        compute_passes: 0,
        map_cleared: 0,
        map_written: 0,
        lights: Vec::new(),
    };
    // Step by step, so that each shadow map's render passes (one per layer it clears and
    // draws) are its own.
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    let steps: Vec<(Pass, Option<usize>)> =
        vs.plan().steps.iter().map(|s| (s.pass, s.light)).collect();
    // Per light, the render passes of its shadow-map step.
    let mut map_passes = vec![0u64; frame.lights.len()];
    for (index, (pass, light)) in steps.into_iter().enumerate() {
        let before = volshadow::passes_recorded();
        vs.encode_step(&mut encoder, output, index)?;
        let passes = volshadow::passes_recorded() - before;
        work.render_passes += passes.render;
        work.compute_passes += passes.compute;
        if let (Pass::ShadowMap, Some(l)) = (pass, light) {
            map_passes[l] += passes.render;
        }
    }
    gpu.submit_and_wait(encoder)?;
    for (light, &passes) in map_passes.iter().enumerate() {
        // A map drawn whenever it changes clears each layer it renders; one drawn on demand
        // touches its layers only in a frame whose gate opened (its passes load the layer and
        // draw from zeroed arguments otherwise).
        let map = match (vs.shadow_map(light), vs.shadow_map_on_demand(light)) {
            (Some(map), _) => Some(map),
            (None, Some((map, gate))) => {
                let state: Vec<u32> = bytemuck::pod_collect_to_vec(&gpu.read_buffer_bytes(gate)?);
                (state.get(1) == Some(&1)).then_some(map)
            }
            (None, None) => None,
        };
        if let Some(map) = map {
            let t = map.texture;
            work.map_cleared += passes * u64::from(t.width()) * u64::from(t.height());
            let depths: Vec<f32> =
                bytemuck::pod_collect_to_vec(&gpu.read_all_layers_bytes(map.texture)?);
            // Cleared to 0 (reversed Z: at infinity); an occluder's depth is above it.
            work.map_written += depths.iter().filter(|&&d| d > 0.0).count() as u64;
        }
        let ran = vs.plan().runs(Pass::March, Some(light));
        let (Some(stats), Some(steps), true) = (vs.march_stats(light), vs.step_counts(light), ran)
        else {
            continue;
        };
        let counters = volshadow::nodes::MarchWork::from_bytes(&gpu.read_buffer_bytes(stats)?)
            .ok_or("the march wrote no work counters")?;
        let steps: Vec<u32> = bytemuck::pod_collect_to_vec(&gpu.read_texture_bytes(steps)?);
        let lit: Vec<u32> = counters
            .texture_samples
            .iter()
            .copied()
            .filter(|&n| n > 0)
            .collect();
        work.lights.push(LightWork {
            light,
            pixels: steps.len(),
            stored: Spread::of(&counters.crossings_stored),
            visited: Spread::of(&counters.crossings_visited),
            lookups: Spread::of(&counters.lookups),
            samples: Spread::of(&counters.texture_samples),
            samples_lit: Spread::of(&lit).mean,
            steps: Spread::of(&steps),
        });
    }
    vs.set_work_counters(false);
    Ok(work)
}

fn bench_scene(gpu: &HeadlessGpu, o: &Options, path: &PathBuf) -> Result<Row, BoxError> {
    let cpu = gpu.adapter.get_info().device_type == wgpu::DeviceType::Cpu;
    let scene = SceneDescription::load(path)?;
    let size = o
        .size
        .unwrap_or(if cpu { (256, 144) } else { (1920, 1080) });
    let camera = with_aspect(&scene.camera, size.0 as f32 / size.1 as f32)?;
    let turned = Camera::new(
        Mat4::from_rotation_y(1e-4) * camera.view(),
        camera.projection(),
    )?;
    let method = o
        .method
        .unwrap_or_else(|| RenderMethod::from_scene(scene.method));
    if method == RenderMethod::Reference {
        return Err("--method reference is the CPU reference, not a GPU frame".into());
    }
    let gpu_scene = GpuScene::new(gpu, &scene, &camera, size, method != RenderMethod::Analytic)?;
    let gpu_method = match method {
        RenderMethod::Gpu(m) => m,
        _ => Method::default(),
    };
    let mut march = gpu_method
        .march_settings()
        .ok_or("a GPU method has march settings")?;
    if o.raster_crossings {
        march.crossings_build = volshadow::nodes::CrossingsBuild::Raster;
    }
    let settings = Settings {
        march,
        upsample: gpu_method.upsample(),
        output_format: wgpu::TextureFormat::Rgba32Float,
        ..Settings::default()
    };
    let cache = Cache::new(&gpu.device);
    let mut vs = VolumetricShadows::new(&gpu.device, &gpu.queue, &cache, settings)?;
    // The composite writes a target with STORAGE_BINDING by a compute pass, one without by
    // the rasteriser.
    let output = if o.raster_composite {
        gpu_scene.output_with(gpu, wgpu::TextureUsages::empty())
    } else {
        gpu_scene.output(gpu)
    };
    let lights = gpu_scene.lights();
    let moved: Vec<FrameLight> = moved_lights(&lights)?;
    let occluders = gpu_scene.occluders();
    // Frame k: the lights and the camera as they were, or moved.
    let frame_of = |k: usize| {
        let mut f = gpu_scene.frame(
            if k.is_multiple_of(2) { &lights } else { &moved },
            &occluders,
        );
        f.camera = if k.is_multiple_of(2) {
            &camera
        } else {
            &turned
        };
        f
    };
    let run = |vs: &mut VolumetricShadows, k: usize, wait: bool| -> Result<(), BoxError> {
        vs.prepare(&gpu.device, &gpu.queue, &frame_of(k))?;
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        vs.encode(&mut encoder, &output)?;
        if wait {
            gpu.submit_and_wait(encoder)?;
        } else {
            gpu.queue.submit([encoder.finish()]);
        }
        Ok(())
    };
    for k in 0..o.warmup.max(2) {
        run(&mut vs, k, true)?;
    }
    if o.work {
        let work = count_work(gpu, &mut vs, &frame_of(o.warmup.max(2)), &output)?;
        return Ok(Row {
            // The file's stem: a table column (the names can be long).
            scene: path
                .file_stem()
                .map_or_else(|| scene.name.clone(), |s| s.to_string_lossy().into_owned()),
            method: method.describe(),
            frame_ms: [f64::NAN; 3],
            wall_ms: f64::NAN,
            passes: Vec::new(),
            work: Some(work),
        });
    }

    // GPU time per frame.
    let mut frame_ms = Vec::with_capacity(o.frames);
    if cpu {
        for k in 0..o.frames {
            vs.prepare(&gpu.device, &gpu.queue, &frame_of(k))?;
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            vs.encode(&mut encoder, &output)?;
            let start = Instant::now();
            gpu.submit_and_wait(encoder)?;
            frame_ms.push(start.elapsed().as_secs_f64() * 1e3);
        }
    } else if gpu
        .device
        .features()
        .contains(wgpu::Features::TIMESTAMP_QUERY)
    {
        let count = 2 * o.frames as u32;
        let set = gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("bench frame timestamps"),
            ty: wgpu::QueryType::Timestamp,
            count,
        });
        let resolve = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bench frame timestamps"),
            size: u64::from(count) * 8,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let stamp = |encoder: &mut wgpu::CommandEncoder, index: u32, begin: bool| {
            let writes = wgpu::ComputePassTimestampWrites {
                query_set: &set,
                beginning_of_pass_write_index: begin.then_some(index),
                end_of_pass_write_index: (!begin).then_some(index),
            };
            encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("bench frame timestamp"),
                timestamp_writes: Some(writes),
            });
        };
        for k in 0..o.frames {
            vs.prepare(&gpu.device, &gpu.queue, &frame_of(k))?;
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            stamp(&mut encoder, 2 * k as u32, true);
            vs.encode(&mut encoder, &output)?;
            stamp(&mut encoder, 2 * k as u32 + 1, false);
            gpu.queue.submit([encoder.finish()]);
        }
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        encoder.resolve_query_set(&set, 0..count, &resolve, 0);
        gpu.submit_and_wait(encoder)?;
        let ticks: Vec<u64> = bytemuck::pod_collect_to_vec(&gpu.read_buffer_bytes(&resolve)?);
        let period = f64::from(gpu.queue.get_timestamp_period()) * 1e-6;
        frame_ms = ticks
            .chunks(2)
            .map(|t| t[1].saturating_sub(t[0]) as f64 * period)
            .collect();
    }
    frame_ms.sort_by(f64::total_cmp);
    let frame = if frame_ms.is_empty() {
        [f64::NAN; 3]
    } else {
        [
            quantile(&frame_ms, 0.5),
            quantile(&frame_ms, 0.1),
            quantile(&frame_ms, 0.9),
        ]
    };

    // Wall time per frame, back to back.
    let start = Instant::now();
    for k in 0..o.frames {
        run(&mut vs, k, false)?;
    }
    gpu.submit_and_wait(gpu.device.create_command_encoder(&Default::default()))?;
    let wall_ms = start.elapsed().as_secs_f64() * 1e3 / o.frames as f64;

    // Per pass.
    let mut passes: Vec<(String, Vec<f64>)> = Vec::new();
    if o.passes {
        for k in 0..o.frames {
            vs.prepare(&gpu.device, &gpu.queue, &frame_of(k))?;
            for t in vs.run_timed(gpu, &output, &[])? {
                let name = match t.light {
                    Some(l) => format!("{} (light {l})", t.pass),
                    None => t.pass.to_string(),
                };
                match passes.iter_mut().find(|(n, _)| *n == name) {
                    Some((_, v)) => v.push(t.ms),
                    None => passes.push((name, vec![t.ms])),
                }
            }
        }
    }
    let passes = passes
        .into_iter()
        .map(|(name, mut v)| {
            v.sort_by(f64::total_cmp);
            (name, quantile(&v, 0.5))
        })
        .collect();
    Ok(Row {
        scene: scene.name.clone(),
        method: method.describe(),
        frame_ms: frame,
        wall_ms,
        passes,
        work: None,
    })
}

fn main() {
    volshadow_harness::headless_env::quiet_display_probe();
    if let Err(e) = run() {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), BoxError> {
    let o = parse()?;
    let gpu = HeadlessGpu::with_optional_features(wgpu::Features::TIMESTAMP_QUERY)?;
    let adapter = gpu.adapter_summary();
    println!("adapter: {adapter}");
    println!(
        "composite: {}",
        if o.raster_composite {
            "through the rasteriser (--raster-composite)"
        } else {
            "a compute pass (the target has STORAGE_BINDING)"
        }
    );
    println!(
        "crossing lists: {}",
        if o.raster_crossings {
            "through the rasteriser (--raster-crossings)"
        } else {
            "compute passes"
        }
    );
    let mut rows = Vec::new();
    if o.work {
        println!(
            "work of one frame; per pixel of each light's march: mean/p99 (texture samples: \
             mean/p99, and mean over the pixels with any)"
        );
        println!(
            "{:<14} {:>6} {:>9} {:>11} {:>11} {:>5} {:>13} {:>13} {:>13} {:>19} {:>13}",
            "scene",
            "passes",
            "r/c",
            "map cleared",
            "map written",
            "light",
            "crossings",
            "visited",
            "lookups",
            "texture samples",
            "steps"
        );
    }
    for path in &o.scenes {
        let row = bench_scene(&gpu, &o, path)?;
        if let Some(w) = &row.work {
            let pair = |s: Spread| format!("{:.2}/{:.0}", s.mean, s.p99);
            let head = format!(
                "{:<14} {:>6} {:>9} {:>11} {:>11}",
                row.scene,
                w.render_passes + w.compute_passes,
                format!("{}/{}", w.render_passes, w.compute_passes),
                w.map_cleared,
                w.map_written
            );
            if w.lights.is_empty() {
                println!("{head}");
            }
            for (i, l) in w.lights.iter().enumerate() {
                println!(
                    "{:<59} {:>5} {:>13} {:>13} {:>13} {:>19} {:>13}",
                    if i == 0 { head.as_str() } else { "" },
                    l.light,
                    pair(l.stored),
                    pair(l.visited),
                    pair(l.lookups),
                    format!("{} ({:.1})", pair(l.samples), l.samples_lit),
                    pair(l.steps)
                );
            }
            rows.push(row);
            continue;
        }
        println!(
            "{:<14} {:<44} frame {:>9.3} ms (p10 {:.3}, p90 {:.3}), wall {:>9.3} ms/frame",
            row.scene, row.method, row.frame_ms[0], row.frame_ms[1], row.frame_ms[2], row.wall_ms
        );
        for (name, ms) in &row.passes {
            println!("    {name:<32} {ms:>9.3} ms");
        }
        rows.push(row);
    }
    let size = o.size.map(|(w, h)| format!("{w}x{h}"));
    let json = serde_json::json!({
        "adapter": adapter,
        "composite": if o.raster_composite { "raster" } else { "compute" },
        "crossings": if o.raster_crossings { "raster" } else { "compute" },
        "size": size,
        "frames": o.frames,
        "warmup": o.warmup,
        "scenes": rows.iter().map(|r| serde_json::json!({
            "scene": r.scene,
            "method": r.method,
            "frame_ms": { "median": r.frame_ms[0], "p10": r.frame_ms[1], "p90": r.frame_ms[2] },
            "wall_ms_per_frame": r.wall_ms,
            "passes_ms": r.passes.iter().map(|(n, ms)| serde_json::json!({ "pass": n, "median": ms })).collect::<Vec<_>>(),
            "work": r.work.as_ref().map(|w| serde_json::json!({
                "render_passes": w.render_passes,
                "compute_passes": w.compute_passes,
                "shadow_map_texels_cleared": w.map_cleared,
                "shadow_map_texels_written": w.map_written,
                "lights": w.lights.iter().map(|l| serde_json::json!({
                    "light": l.light,
                    "pixels": l.pixels,
                    "crossings_stored": l.stored.json(),
                    "crossings_visited": l.visited.json(),
                    "shadow_map_lookups": l.lookups.json(),
                    "texture_samples": l.samples.json(),
                    "texture_samples_per_lit_pixel": l.samples_lit,
                    "march_steps": l.steps.json(),
                })).collect::<Vec<_>>(),
            })),
        })).collect::<Vec<_>>(),
    });
    if let Some(dir) = o.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)?;
    }
    std::fs::write(&o.out, serde_json::to_string_pretty(&json)?)?;
    println!("wrote {}", o.out.display());
    Ok(())
}
