//! The example programs' output helpers: tone mapping, EXR/PNG writing, eye distances from a
//! depth buffer, the `--size WxH` syntax and the timing of a frame (`render`, `gltf`, the report
//! and the frame bench).

use std::path::Path;

use std::time::Instant;

use volshadow::glam::{DVec3, DVec4};
use volshadow::gpu::PassTime;
use volshadow::{Camera, Frame, HeadlessGpu, VolumetricShadows};

/// The boxed error the examples return: any problem becomes a message and exit status 1.
pub type BoxError = Box<dyn std::error::Error>;

/// Eye distance written to the depth EXR for sky pixels (nothing drawn): large and finite, so
/// that image tools and tests need no special case for infinity.
pub const SKY_DISTANCE: f32 = 1e9;

/// GPU frames each example renders; the last one (warm: pipelines built, shadow maps and
/// tables reused) is the one timed.
pub const FRAMES: usize = 3;

/// What the last of [`render_frames`]'s frames did and cost.
pub struct FrameStats {
    /// The plan, one line per pass run or left out.
    pub plan: Vec<String>,
    /// GPU time per pass (empty without timestamp queries).
    pub timings: Vec<PassTime>,
    /// Wall-clock time of the frame: prepare, encode, submit and wait, in ms.
    pub wall_ms: f64,
}

/// Renders `frame` [`FRAMES`] times through `volumetric` into `output` (a `RENDER_ATTACHMENT`
/// texture of the settings' format), as an app's frame loop would: prepare, record into a new
/// encoder, submit. Prints the first and last plan and every frame's timings.
pub fn render_frames(
    gpu: &HeadlessGpu,
    volumetric: &mut VolumetricShadows,
    frame: &Frame,
    output: &wgpu::Texture,
) -> Result<FrameStats, BoxError> {
    let mut stats = FrameStats {
        plan: Vec::new(),
        timings: Vec::new(),
        wall_ms: 0.0,
    };
    for index in 0..FRAMES {
        let start = Instant::now();
        let plan = volumetric
            .prepare(&gpu.device, &gpu.queue, frame)?
            .to_string();
        // Per-pass times: timestamp queries, or on a CPU adapter each pass alone.
        stats.timings = volumetric.run_timed(gpu, output, &[])?;
        stats.wall_ms = start.elapsed().as_secs_f64() * 1e3;
        if index == 0 || index + 1 == FRAMES {
            println!("frame {index} plan:\n{plan}");
        }
        println!(
            "frame {index}{}: {}; wall clock {:.1} ms",
            first_frame_note(volumetric),
            timings_line(&stats.timings),
            stats.wall_ms
        );
        stats.plan = plan.lines().map(str::to_owned).collect();
    }
    Ok(stats)
}

/// A note for a frame's timing line when it is the first of its kind
/// ([`VolumetricShadows::is_first_frame`]): on a driver that compiles pipelines when they
/// first run, its times include that compilation.
pub fn first_frame_note(volumetric: &VolumetricShadows) -> &'static str {
    if volumetric.is_first_frame() {
        " (first of its kind: on a driver that compiles pipelines at first use, as lavapipe \
         does, its times include that compilation)"
    } else {
        ""
    }
}

/// The in-scattered radiance of the last frame, summed over its `lights` lights (zero for a
/// medium that does not scatter, where no in-scatter pass runs).
pub fn read_inscatter(
    gpu: &HeadlessGpu,
    volumetric: &VolumetricShadows,
    frame: &Frame,
) -> Result<Vec<DVec3>, BoxError> {
    let pixels = (frame.scene_depth.width() * frame.scene_depth.height()) as usize;
    let mut sum = vec![DVec3::ZERO; pixels];
    if frame.medium.sigma_s().max_element() > 0.0 {
        for i in 0..frame.lights.len() {
            let texture = volumetric
                .inscatter(i)
                .ok_or("no in-scatter after a frame")?;
            let image = gpu.read_rgba32f(texture)?;
            sum.iter_mut().zip(&image).for_each(|(s, p)| *s += rgb(p));
        }
    }
    Ok(sum)
}

/// The RGB of an RGBA texel, in f64.
pub fn rgb(p: &[f32; 4]) -> DVec3 {
    DVec3::new(p[0].into(), p[1].into(), p[2].into())
}

/// Parses `WxH` (e.g. `640x400`), each 1..=8192.
pub fn parse_size(text: &str) -> Result<(u32, u32), BoxError> {
    let bad = || format!("--size wants WxH with each in 1..=8192 (e.g. 640x400), got {text:?}");
    let (w, h) = text.split_once(['x', 'X']).ok_or_else(bad)?;
    let (w, h): (u32, u32) = (w.parse().map_err(|_| bad())?, h.parse().map_err(|_| bad())?);
    if !(1..=8192).contains(&w) || !(1..=8192).contains(&h) {
        return Err(bad().into());
    }
    Ok((w, h))
}

/// The camera for another aspect ratio: the projection's x scale becomes its y scale over
/// `aspect` (exact for the perspective matrices of `glam::camera::rh::proj`).
pub fn with_aspect(camera: &Camera, aspect: f32) -> volshadow::Result<Camera> {
    let mut projection = camera.projection();
    projection.x_axis.x = projection.y_axis.y / aspect;
    Camera::new(camera.view(), projection)
}

/// Eye distance per pixel (row-major, top row first) from a depth buffer's values, in f64
/// through the inverse view-projection; `f64::INFINITY` where the depth is the camera's far
/// depth (sky).
pub fn eye_distances(camera: &Camera, (width, height): (u32, u32), depth: &[f32]) -> Vec<f64> {
    let world_from_clip = (camera.projection().as_dmat4() * camera.view().as_dmat4()).inverse();
    let eye = camera.eye().as_dvec3();
    depth
        .iter()
        .enumerate()
        .map(|(i, &z)| {
            if z == camera.far_depth() {
                return f64::INFINITY;
            }
            let (px, py) = (i as u32 % width, i as u32 / width);
            let ndc = volshadow::reference::pixel_ndc(width, height, px, py);
            let p = world_from_clip * DVec4::new(ndc.x, ndc.y, f64::from(z), 1.0);
            let d = (p.truncate() / p.w).distance(eye);
            if d.is_finite() {
                d
            } else {
                f64::INFINITY
            }
        })
        .collect()
}

/// Reads a `Depth32Float` texture (usage `COPY_SRC`) back.
pub fn read_depth(
    gpu: &volshadow::HeadlessGpu,
    texture: &wgpu::Texture,
) -> volshadow::Result<Vec<f32>> {
    Ok(bytemuck::pod_collect_to_vec(
        &gpu.read_texture_bytes(texture)?,
    ))
}

/// Linear RGB as an OpenEXR file (32-bit float channels R, G, B).
pub fn write_exr(path: &Path, (width, height): (u32, u32), rgb: &[DVec3]) -> Result<(), BoxError> {
    let data: Vec<f32> = rgb.iter().flat_map(|c| c.as_vec3().to_array()).collect();
    let image = image::Rgb32FImage::from_raw(width, height, data).ok_or("image size mismatch")?;
    image
        .save_with_format(path, image::ImageFormat::OpenExr)
        .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    Ok(())
}

/// The exposure that maps the 99th percentile of the luminance to 2.5 before Reinhard (0.71
/// after it): robust to the few pixels around a light in view, and independent of the scene's
/// units. 1 for a black image.
pub fn auto_exposure(rgb: &[DVec3]) -> f64 {
    let mut luminance: Vec<f64> = rgb
        .iter()
        .map(|c| c.dot(DVec3::new(0.2126, 0.7152, 0.0722)))
        .filter(|y| y.is_finite())
        .collect();
    if luminance.is_empty() {
        return 1.0;
    }
    let k = (luminance.len() - 1) * 99 / 100;
    let (_, p99, _) = luminance.select_nth_unstable_by(k, f64::total_cmp);
    if *p99 > 0.0 {
        2.5 / *p99
    } else {
        1.0
    }
}

/// `volshadow::tone_map` (exposure, Reinhard, sRGB) of f64 radiance, as an RGB image.
pub fn tone_map((width, height): (u32, u32), rgb: &[DVec3], exposure: f64) -> image::RgbImage {
    let pixels: Vec<[f32; 4]> = rgb
        .iter()
        .map(|c| [c.x as f32, c.y as f32, c.z as f32, 1.0])
        .collect();
    let rgba = volshadow::tone_map(&pixels, exposure as f32);
    image::RgbImage::from_fn(width, height, |x, y| {
        let i = 4 * (y * width + x) as usize;
        image::Rgb([rgba[i], rgba[i + 1], rgba[i + 2]])
    })
}

/// Writes a PNG, naming the file in the error.
pub fn write_png(path: &Path, image: &image::RgbImage) -> Result<(), BoxError> {
    image
        .save_with_format(path, image::ImageFormat::Png)
        .map_err(|e| format!("cannot write {}: {e}", path.display()).into())
}

/// GPU time per pass as JSON objects `{"pass", "ms"}`, and their sum (`None` without
/// timestamp queries).
pub fn timings_json(timings: &[PassTime]) -> (Vec<serde_json::Value>, Option<f64>) {
    let passes = timings
        .iter()
        .map(|t| serde_json::json!({ "pass": t.pass.name(), "ms": t.ms }))
        .collect();
    let total = (!timings.is_empty()).then(|| timings.iter().map(|t| t.ms).sum());
    (passes, total)
}

/// One line of per-pass GPU times, for the console.
pub fn timings_line(timings: &[PassTime]) -> String {
    if timings.is_empty() {
        return "no timestamp queries on this device".into();
    }
    let total: f64 = timings.iter().map(|t| t.ms).sum();
    let passes: Vec<String> = timings
        .iter()
        .map(|t| format!("{} {:.3}", t.pass, t.ms))
        .collect();
    format!("GPU {total:.3} ms ({})", passes.join(", "))
}
