//! Quickstart: a lit foggy scene rendered headless to `out/quickstart.png`.
//!
//! The "application" here draws its own frame (a ground plane and two spheres, ray-cast in a
//! fragment shader that writes colour and depth); volshadow then adds the light scattered in
//! the fog, with the dark shafts the spheres cut through it, recorded into the application's
//! encoder by `VolumetricShadows` (its plan and per-pass GPU times are printed).
//!
//! ```text
//! cargo run --release --example quickstart [-- -o OUTPUT.png] [--size WxH]
//! ```
//!
//! `--help` prints the options (`volshadow_harness::cli`). The scene is built in code, so no
//! input file exists that the output could overwrite.
//!
//! Every volshadow call is in this file; what comes from `volshadow_harness` is the
//! application's side: the command line, the app's own full-screen pass that draws the ground
//! and the spheres (`ScenePass`, `SPHERES`), and the quiet headless start. Its test,
//! `quickstart.rs` beside this file, runs [`run`] against the f64 reference (`cargo test
//! --example quickstart`; the crate's `cargo test` runs it too).

use std::time::Instant;

use volshadow::glam::{camera::rh, Mat4, Vec3};
use volshadow::scene::shapes;
use volshadow::{
    AdapterKind, Camera, Frame, HeadlessGpu, Light, Medium, Occluder, OccluderMesh, PhaseFunction,
    PointLight, Settings, VolumetricShadows,
};
use volshadow_harness::fullscreen::texture_desc;
use volshadow_harness::quickstart_scene::{ScenePass, SPHERES};
use volshadow_harness::{cli, headless_env};

#[cfg(test)]
mod quickstart;

/// The PNG's exposure.
pub const EXPOSURE: f32 = 1.6;

/// The light's position: about level with the spheres and behind them, so that both cut dark
/// shafts that open towards the camera.
pub const LIGHT_POSITION: Vec3 = Vec3::new(-0.1, 2.1, -5.0);
/// The light's intensity (RGB).
pub const LIGHT_INTENSITY: Vec3 = Vec3::new(90.0, 78.0, 60.0);

/// The scene for a frame of `width × height`: the camera, the light at [`LIGHT_POSITION`] and
/// hazy air.
pub fn scene(width: u32, height: u32) -> volshadow::Result<(Camera, PointLight, Medium)> {
    let camera = Camera::new(
        rh::view::look_at_mat4(Vec3::new(0.0, 1.6, 7.0), Vec3::new(0.0, 1.3, 0.0), Vec3::Y),
        rh::proj::directx::perspective(
            55f32.to_radians(),
            width as f32 / height as f32,
            0.05,
            200.0,
        ),
    )?;
    let light = PointLight::new(LIGHT_POSITION, LIGHT_INTENSITY)?;
    let medium = Medium::new(
        Vec3::new(0.10, 0.11, 0.13), // σs per RGB channel
        Vec3::splat(0.01),           // σa
        PhaseFunction::HenyeyGreenstein { g: 0.7 },
    )?;
    Ok((camera, light, medium))
}

/// The spheres the app draws ([`SPHERES`]) as volshadow's occluder meshes (48 × 24 segments),
/// uploaded once.
pub fn sphere_meshes(device: &wgpu::Device) -> volshadow::Result<Vec<OccluderMesh>> {
    SPHERES
        .iter()
        .map(|&(centre, radius)| {
            Ok(OccluderMesh::new(
                device,
                &shapes::uv_sphere(centre, radius, 48, 24)?,
            ))
        })
        .collect()
}

/// What a run produced: the composited image and the in-scatter alone (linear, row-major).
pub struct Rendered {
    /// Composited radiance.
    pub output: Vec<[f32; 4]>,
    /// In-scattered radiance of the light (full resolution).
    pub inscatter: Vec<[f32; 4]>,
}

/// Draws the app's frame, then renders `frames` frames through `VolumetricShadows`, printing
/// each frame's plan and per-pass GPU times.
pub fn run(
    gpu: &HeadlessGpu,
    width: u32,
    height: u32,
    settings: Settings,
    frames: usize,
) -> Result<Rendered, Box<dyn std::error::Error>> {
    run_with(gpu, (width, height), settings, frames, true, LIGHT_POSITION)
}

/// [`run`], with the spheres passed to volshadow as occluders or not (`false`: the same app
/// frame with unshadowed fog, what the picture's shafts are judged against) and the light at
/// `light`.
pub fn run_with(
    gpu: &HeadlessGpu,
    (width, height): (u32, u32),
    settings: Settings,
    frames: usize,
    shadows: bool,
    light: Vec3,
) -> Result<Rendered, Box<dyn std::error::Error>> {
    let (camera, _, medium) = scene(width, height)?;
    let point = PointLight::new(light, LIGHT_INTENSITY)?;

    // The application's own frame: colour (linear radiance) and depth.
    let usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING;
    let texture = |label, format| {
        let desc = texture_desc(label, (width, height), format, usage);
        gpu.device.create_texture(&desc)
    };
    let color = texture("scene colour", wgpu::TextureFormat::Rgba16Float);
    let depth = texture("scene depth", wgpu::TextureFormat::Depth32Float);
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    ScenePass::new(&gpu.device).encode(
        &gpu.queue,
        &mut encoder,
        (&color, &depth),
        (&camera, &point, &medium),
        true,
    );
    gpu.submit_and_wait(encoder)?;

    // volshadow: a shared cache, the occluder meshes (uploaded once), the facade.
    let cache = volshadow::Cache::new(&gpu.device);
    let meshes = sphere_meshes(&gpu.device)?;
    let occluders: Vec<Occluder> = meshes
        .iter()
        .filter(|_| shadows)
        .map(|mesh| Occluder {
            mesh,
            transform: Mat4::IDENTITY,
        })
        .collect();
    let settings = Settings {
        output_format: wgpu::TextureFormat::Rgba32Float,
        ..settings
    };
    let mut volumetric = VolumetricShadows::new(&gpu.device, &gpu.queue, &cache, settings)?;
    let output = gpu.device.create_texture(&texture_desc(
        "output",
        (width, height),
        wgpu::TextureFormat::Rgba32Float,
        wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
    ));

    // Every frame: prepare (validate, upload, plan), record into our encoder, submit.
    let lights = [Light::from(point).into()];
    let frame = Frame {
        camera: &camera,
        lights: &lights,
        medium: &medium,
        occluders: &occluders,
        scene_color: &color,
        scene_depth: &depth,
        surfaces: None,
    };
    for frame_index in 0..frames {
        let start = Instant::now();
        let plan = volumetric.prepare(&gpu.device, &gpu.queue, &frame)?;
        println!("frame {frame_index} plan:\n{plan}");
        // On a driver that compiles a pipeline when it first runs (lavapipe), the first
        // frame's times include that compilation.
        let note = if volumetric.is_first_frame() {
            " (first frame: includes any first-use shader compilation)"
        } else {
            ""
        };
        // An app records into its own encoder and submits (`volumetric.encode`); this one
        // also times each pass: by timestamp queries, or on a CPU adapter (lavapipe) by
        // running each pass alone.
        let timings = volumetric.run_timed(gpu, &output, &[])?;
        let wall = start.elapsed().as_secs_f64() * 1e3;
        let gpu_ms: f64 = timings.iter().map(|t| t.ms).sum();
        let per_pass: Vec<String> = timings
            .iter()
            .map(|t| format!("{} {:.2} ms", t.pass, t.ms))
            .collect();
        println!(
            "frame {frame_index}{note}: GPU {gpu_ms:.2} ms ({}); wall clock {wall:.1} ms at {width}x{height}",
            per_pass.join(", ")
        );
    }
    Ok(Rendered {
        output: gpu.read_rgba32f(&output)?,
        inscatter: gpu.read_rgba32f(volumetric.inscatter(0).expect("rendered"))?,
    })
}

fn main() {
    // No false `error: XDG_RUNTIME_DIR ...` line from Mesa's Vulkan layer when headless.
    headless_env::quiet_display_probe();
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = cli::parse_quickstart(&args).and_then(|parsed| match parsed {
        cli::Parsed::Help => {
            println!("{}", cli::QUICKSTART_HELP);
            Ok(())
        }
        cli::Parsed::Run(options) => render_to(&options.output, options.size),
    });
    if let Err(e) = result {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}

/// Renders the scene at `width × height` and writes the PNG to `output` (creating its folder).
fn render_to(
    output: &std::path::Path,
    (width, height): (u32, u32),
) -> Result<(), Box<dyn std::error::Error>> {
    let gpu = HeadlessGpu::with_optional_features(wgpu::Features::TIMESTAMP_QUERY)?;
    println!("adapter: {}", gpu.adapter_summary());
    // Two frames: the second shows what the planner skips when nothing changed.
    let rendered = run(
        &gpu,
        width,
        height,
        Settings::for_adapter(AdapterKind::of(&gpu.device)),
        2,
    )?;
    if let Some(dir) = output.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    }
    // Reinhard and sRGB (`volshadow::tone_map`).
    let rgba = volshadow::tone_map(&rendered.output, EXPOSURE);
    image::RgbaImage::from_raw(width, height, rgba)
        .ok_or("tone-mapped image of the wrong size")?
        .save_with_format(output, image::ImageFormat::Png)
        .map_err(|e| format!("cannot write {}: {e}", output.display()))?;
    println!("wrote {}", output.display());
    Ok(())
}
