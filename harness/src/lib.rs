//! What volshadow's tests, examples, bench and tools share; a workspace crate that is never
//! published (a dev-dependency of `volshadow`, and a dependency of `volshadow_tools`).
//!
//! The test tiers' helpers, here at the root: the binary's shared device and caches ([`gpu`],
//! [`cache`]), depth buffers written from known values, and the table → march → readback
//! chain ([`shadow_frame`]); with
//! * [`by_hand`]: the nodes wired by hand, for inputs the facade never gives them;
//! * [`files`]: GLB containers and files in a test's temporary folder;
//! * [`metric`]: the metric lines the tests and the report print, and their reader;
//! * [`rng`]: the tests' seeded random numbers;
//! * [`scene`]: scenes of triangle meshes measured against the f64 reference;
//! * [`visibility`]: how much of a picture its shadows change.
//!
//! The examples' plumbing (none of it a volshadow call an example is there to show):
//! * [`app`]: output helpers — tone mapping, EXR/PNG writing, eye distances from a depth
//!   buffer, the `--size WxH` syntax and the timing of a frame;
//! * [`cli`]: `--help`, the default output folder (`out/`) and the refusal to overwrite an
//!   input; the small programs' options;
//! * [`raster`]: the application's own frame (colour + depth) from triangle meshes;
//! * [`fullscreen`]: the app's full-screen ray-cast pass (`quickstart_scene`, the soak),
//!   texture descriptors;
//! * [`quickstart_scene`]: the quickstart scene's numbers and the app's pass that draws it;
//! * [`render_scene`]: the `render` example (a scene file → EXR, PNG, JSON report);
//! * `gltf_scene` (feature `gltf`): the `gltf` example (a glTF model's shafts → PNG);
//! * [`headless_env`]: no false `error:` line from Mesa's Vulkan layer on a headless machine.
//!
//! And the tools' shared parts: [`report`] (error against GPU time; the bench reuses its
//! moving lights) and [`docs`] (the measurement documents, which the README test checks).

pub mod app;
pub mod by_hand;
pub mod cli;
pub mod docs;
pub mod files;
pub mod fullscreen;
#[cfg(feature = "gltf")]
pub mod gltf_scene;
pub mod headless_env;
pub mod metric;
pub mod quickstart_scene;
pub mod raster;
pub mod render_scene;
pub mod report;
pub mod rng;
pub mod scene;
pub mod visibility;

/// The repository's root (volshadow's own folder, above `harness/`): where `scenes/`, `docs/`
/// and volshadow's sources are, whichever package's test or tool asks.
pub fn repo_root() -> &'static std::path::Path {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("the harness sits in the repository's root folder")
}

use glam::{DMat4, DVec3, DVec4, Vec3};
use volshadow::nodes::{MarchSettings, TableSize};
use volshadow::{Cache, Camera, HeadlessGpu, Light, Medium, PointLight};
use volshadow::{Frame, FrameLight, Settings, VolumetricShadows};

/// Every `scenes/*.json` of the repository, sorted.
pub fn scene_files() -> Vec<std::path::PathBuf> {
    let dir = repo_root().join("scenes");
    let mut files: Vec<std::path::PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("cannot list {}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .collect();
    files.sort();
    assert!(!files.is_empty(), "no scene files in {}", dir.display());
    files
}

/// A camera for node inputs only a directional light reads (a point or spot light's shadow
/// map ignores it).
pub fn unread_camera() -> Camera {
    Camera::new(
        glam::camera::rh::view::look_at_mat4(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y),
        glam::camera::rh::proj::directx::perspective(1.0, 1.0, 0.1, 100.0),
    )
    .expect("a valid camera")
}

/// The test binary's one device, shared by its tests (each gets a clone of the handles). A
/// missing adapter fails the test with the installation hint.
///
/// Pipelines are most of the suite's cost on lavapipe, which compiles each one with LLVM (71% of
/// four sampled GPU tests' time under `perf`, 88% of the warm-up test's), so the tests share one
/// device and, per shader precision, one [`Cache`] ([`cache`], [`cache_with`]): a node's
/// pipelines compile once per binary instead of once per test. Nothing else is shared: wgpu's
/// error scopes are per thread, so a test's scope sees only its own errors. A test that counts
/// what its device builds or holds makes its own device with `HeadlessGpu::new` (`warm_up.rs`).
pub fn gpu() -> HeadlessGpu {
    match shared() {
        Ok(gpu) => {
            metric::adapter(&gpu.adapter_summary());
            gpu.clone()
        }
        Err(e) => panic!("GPU tests need a wgpu adapter (lavapipe works): {e}"),
    }
}

/// The binary's device, made by the first test that asks.
fn shared() -> &'static Result<HeadlessGpu, String> {
    static SHARED: std::sync::OnceLock<Result<HeadlessGpu, String>> = std::sync::OnceLock::new();
    SHARED.get_or_init(|| HeadlessGpu::new().map_err(|e| e.to_string()))
}

/// A cache for `gpu` at native precision; see [`cache_with`].
pub fn cache(gpu: &HeadlessGpu) -> Cache {
    cache_with(gpu, volshadow::ShaderPrecision::Native)
}

/// A cache for `gpu`'s device at `precision`: for the binary's shared device ([`gpu`]) the one
/// shared cache of that precision (a clone, so pipelines built by any test serve the rest); for
/// any other device a new one. The instance is compared too: wgpu compares devices by their id
/// alone, and a device of another instance (`gpu_timed`) can have the same id (with the device
/// alone, 25 tests on such devices got the shared cache's layouts and wgpu-core panicked on
/// "non-existent resource").
pub fn cache_with(gpu: &HeadlessGpu, precision: volshadow::ShaderPrecision) -> Cache {
    static CACHES: std::sync::Mutex<Vec<(usize, Cache)>> = std::sync::Mutex::new(Vec::new());
    let device = &gpu.device;
    let Some(which) = [shared(), shared_timed()].iter().position(|s| {
        s.as_ref()
            .is_ok_and(|s| s.instance == gpu.instance && s.device == *device)
    }) else {
        return Cache::with_precision(device, precision);
    };
    let mut caches = CACHES.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((_, cache)) = caches
        .iter()
        .find(|(w, c)| *w == which && c.precision() == precision)
    {
        return cache.clone();
    }
    let cache = Cache::with_precision(device, precision);
    caches.push((which, cache.clone()));
    cache
}

/// WGSL's worst case for the shaders' transcendental built-ins, each result moved by the largest
/// error WGSL allows and subnormals flushed to zero (see `volshadow::ShaderPrecision`). The
/// accuracy tests run in it beside the driver's own maths, with the same bounds: lavapipe's maths
/// is nearly exact, a GPU's need not be, and an NVIDIA H200 failed six tests that lavapipe
/// passed until the shaders were written for WGSL's guarantees.
pub const WORST_CASE: volshadow::ShaderPrecision =
    volshadow::ShaderPrecision::WorstCase(volshadow::ErrorSign::Mixed);

/// The worst case with each of its error signs (up, down, mixed), for the cheaper tests.
pub const WORST_CASES: [volshadow::ShaderPrecision; 3] = [
    volshadow::ShaderPrecision::WorstCase(volshadow::ErrorSign::Up),
    volshadow::ShaderPrecision::WorstCase(volshadow::ErrorSign::Down),
    WORST_CASE,
];

/// Two tests of one body: `$native` runs `$body(ShaderPrecision::Native)`, `$worst` runs it at
/// each precision of `$cases` (WGSL's worst case: [`WORST_CASES`] or `[WORST_CASE]`). Attributes
/// before `$body` go on both (the sweep tier's `cfg_attr`).
#[macro_export]
macro_rules! at_each_precision {
    ($(#[$attr:meta])* $body:ident => $native:ident, $worst:ident, $cases:expr) => {
        #[test]
        $(#[$attr])*
        fn $native() {
            $body(volshadow::ShaderPrecision::Native);
        }

        #[test]
        $(#[$attr])*
        fn $worst() {
            for precision in $cases {
                $body(precision);
            }
        }
    };
}

/// NDC depth of a world point seen by `camera`, in f64.
pub fn ndc_depth(camera: &Camera, point: DVec3) -> f32 {
    let clip = (camera.projection().as_dmat4() * camera.view().as_dmat4())
        * DVec4::new(point.x, point.y, point.z, 1.0);
    (clip.z / clip.w) as f32
}

/// The depth buffer of `camera`, `width × height`, for rays ending at `distance(eye, dir)`
/// from the eye (not finite: at the far plane).
pub fn depths_at(
    camera: &Camera,
    width: u32,
    height: u32,
    distance: impl Fn(DVec3, DVec3) -> f64,
) -> Vec<f32> {
    (0..width * height)
        .map(|i| {
            let (o, d) = pixel_ray(camera, width, height, i % width, i / width);
            let t = distance(o, d);
            if t.is_finite() {
                ndc_depth(camera, o + t * d)
            } else {
                camera.far_depth()
            }
        })
        .collect()
}

/// Eye position and ray direction through the centre of pixel (px, py), in f64, computed from
/// the matrices (independent of the crate's shaders).
pub fn pixel_ray(camera: &Camera, width: u32, height: u32, px: u32, py: u32) -> (DVec3, DVec3) {
    let view: DMat4 = camera.view().as_dmat4();
    let proj: DMat4 = camera.projection().as_dmat4();
    let eye = view.inverse().w_axis.truncate();
    let ndc_x = (px as f64 + 0.5) / width as f64 * 2.0 - 1.0;
    let ndc_y = 1.0 - (py as f64 + 0.5) / height as f64 * 2.0;
    let near = if camera.far_depth() == 1.0 { 0.0 } else { 1.0 };
    let p = (proj * view).inverse() * DVec4::new(ndc_x, ndc_y, near, 1.0);
    (eye, (p.truncate() / p.w - eye).normalize())
}

/// A float texture holding `texels` (row-major, top row first).
pub fn rgba_texture(
    gpu: &HeadlessGpu,
    width: u32,
    height: u32,
    texels: &[[f32; 4]],
) -> wgpu::Texture {
    filled_texture(
        gpu,
        wgpu::TextureFormat::Rgba32Float,
        width,
        height,
        bytemuck::cast_slice(texels),
    )
}

/// A `format` texture (usage `TEXTURE_BINDING | COPY_DST`) holding `bytes`, row-major, top row
/// first, rows packed.
pub fn filled_texture(
    gpu: &HeadlessGpu,
    format: wgpu::TextureFormat,
    width: u32,
    height: u32,
    bytes: &[u8],
) -> wgpu::Texture {
    let t = texture(
        gpu,
        format,
        wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        (width, height, 1),
        1,
    );
    let texel = format
        .block_copy_size(None)
        .expect("an uncompressed colour format");
    gpu.queue.write_texture(
        t.as_image_copy(),
        bytes,
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(width * texel),
            rows_per_image: Some(height),
        },
        t.size(),
    );
    t
}

/// A `Depth32Float` texture holding `values` (row-major, top row first), written by a
/// fullscreen pass through `frag_depth` (buffer → depth copies are not in the core feature set).
/// A 2D texture of `size.2` layers and `mips` mip levels, for tests that need a specific
/// format, usage or shape.
pub fn texture(
    gpu: &HeadlessGpu,
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
    size: (u32, u32, u32),
    mips: u32,
) -> wgpu::Texture {
    gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: None,
        size: wgpu::Extent3d {
            width: size.0,
            height: size.1,
            depth_or_array_layers: size.2,
        },
        mip_level_count: mips,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    })
}

pub fn depth_texture(gpu: &HeadlessGpu, width: u32, height: u32, values: &[f32]) -> wgpu::Texture {
    depth_texture_with_format(
        gpu,
        width,
        height,
        values,
        wgpu::TextureFormat::Depth32Float,
    )
}

pub fn depth_texture_with_format(
    gpu: &HeadlessGpu,
    width: u32,
    height: u32,
    values: &[f32],
    format: wgpu::TextureFormat,
) -> wgpu::Texture {
    assert_eq!(values.len(), (width * height) as usize);
    let device = &gpu.device;
    let source = filled_texture(
        gpu,
        wgpu::TextureFormat::R32Float,
        width,
        height,
        bytemuck::cast_slice(values),
    );
    let depth = texture(
        gpu,
        format,
        wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::RENDER_ATTACHMENT,
        (width, height, 1),
        1,
    );
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("depth writer"),
        source: wgpu::ShaderSource::Wgsl(
            r#"
@group(0) @binding(0) var values: texture_2d<f32>;
@vertex fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}
@fragment fn fs(@builtin(position) p: vec4<f32>) -> @builtin(frag_depth) f32 {
    return textureLoad(values, vec2<u32>(p.xy), 0).x;
}"#
            .into(),
        ),
    });
    let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("depth writer"),
        layout: None,
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: Default::default(),
        depth_stencil: Some(wgpu::DepthStencilState {
            format,
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
            targets: &[],
        }),
        multiview_mask: None,
        cache: None,
    });
    let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: wgpu::BindingResource::TextureView(&source.create_view(&Default::default())),
        }],
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let view = depth.create_view(&Default::default());
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("write depth"),
            color_attachments: &[],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(0.0),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &bind_group, &[]);
        pass.draw(0..3, 0..1);
    }
    gpu.submit_and_wait(encoder).expect("depth upload");
    depth
}

/// One frame of `light` without occluders through the facade (the table and the analytic
/// march at full resolution, `table_size`'s F′ table); returns the in-scatter texture's texels
/// (rgb radiance, a = distance).
pub fn march_frame(
    gpu: &HeadlessGpu,
    cache: &Cache,
    table_size: TableSize,
    camera: &Camera,
    light: &PointLight,
    medium: &Medium,
    depth: &wgpu::Texture,
) -> Vec<[f32; 4]> {
    let settings = Settings {
        table: table_size,
        ..Settings::PREDICTABLE
    };
    let lights = [FrameLight::from(Light::from(light))];
    let mut vs = FacadeFrame::new(gpu, cache, settings, depth);
    let vs = vs.run(gpu, camera, &lights, medium, &[]);
    gpu.read_rgba32f(vs.inscatter(0).unwrap()).unwrap()
}

/// A facade and the colour and output textures one of its frames reads and writes, the depth
/// buffer's size.
pub struct FacadeFrame<'d> {
    vs: VolumetricShadows,
    depth: &'d wgpu::Texture,
    color: wgpu::Texture,
    output: wgpu::Texture,
}

impl<'d> FacadeFrame<'d> {
    pub fn new(
        gpu: &HeadlessGpu,
        cache: &Cache,
        settings: Settings,
        depth: &'d wgpu::Texture,
    ) -> Self {
        let size = (depth.width(), depth.height(), 1);
        let usage = wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST;
        let color = texture(gpu, wgpu::TextureFormat::Rgba16Float, usage, size, 1);
        let usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC;
        let output = texture(gpu, settings.output_format, usage, size, 1);
        let vs = VolumetricShadows::new(&gpu.device, &gpu.queue, cache, settings).unwrap();
        Self {
            vs,
            depth,
            color,
            output,
        }
    }

    /// Prepares, records and runs one frame; returns the facade to read its results.
    pub fn run(
        &mut self,
        gpu: &HeadlessGpu,
        camera: &Camera,
        lights: &[FrameLight<'_>],
        medium: &Medium,
        occluders: &[volshadow::gpu::Occluder<'_>],
    ) -> &VolumetricShadows {
        let frame = Frame {
            camera,
            lights,
            medium,
            occluders,
            scene_color: &self.color,
            scene_depth: self.depth,
            surfaces: None,
        };
        self.vs.prepare(&gpu.device, &gpu.queue, &frame).unwrap();
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        self.vs.encode(&mut encoder, &self.output).unwrap();
        gpu.submit_and_wait(encoder).unwrap();
        &self.vs
    }
}

/// A right-handed look-at camera with a standard-Z perspective projection.
pub fn look_at(eye: Vec3, target: Vec3, fov_y_deg: f32, aspect: f32) -> Camera {
    Camera::new(
        glam::camera::rh::view::look_at_mat4(eye, target, Vec3::Y),
        glam::camera::rh::proj::directx::perspective(fov_y_deg.to_radians(), aspect, 0.05, 500.0),
    )
    .unwrap()
}

pub fn max_abs_rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(f64::MIN_POSITIVE)
}

/// A device with timestamp queries when the adapter has them (lavapipe does), shared by the
/// binary's tests as [`gpu`] is, with its own caches.
pub fn gpu_timed() -> HeadlessGpu {
    match shared_timed() {
        Ok(gpu) => {
            metric::adapter(&gpu.adapter_summary());
            gpu.clone()
        }
        Err(e) => panic!("GPU tests need a wgpu adapter (lavapipe works): {e}"),
    }
}

/// The binary's timed device, made by the first test that asks.
fn shared_timed() -> &'static Result<HeadlessGpu, String> {
    static SHARED: std::sync::OnceLock<Result<HeadlessGpu, String>> = std::sync::OnceLock::new();
    SHARED.get_or_init(|| {
        HeadlessGpu::with_optional_features(wgpu::Features::TIMESTAMP_QUERY)
            .map_err(|e| e.to_string())
    })
}

/// What a shadowed frame produced.
pub struct ShadowFrame {
    pub inscatter: Vec<[f32; 4]>,
    pub steps: Vec<u32>,
    /// Front, back-near, back-far extents depths (`None` where the plan has no extents: a
    /// light with a radius, brute force, the textbook march).
    pub extents: Option<[Vec<f32>; 3]>,
    pub times: Vec<volshadow::gpu::PassTime>,
    /// What the exact method met (zeros for the other methods).
    pub stats: volshadow::nodes::MarchStats,
}

impl ShadowFrame {
    pub fn has_extents(&self, i: usize) -> bool {
        let e = self
            .extents
            .as_ref()
            .expect("a frame whose plan has extents");
        e[0][i] > 0.0 || e[2][i] < 1.0
    }
    pub fn time_ms(&self, label: &str) -> f64 {
        self.times
            .iter()
            .filter(|t| t.pass.name() == label)
            .map(|t| t.ms)
            .sum()
    }
}

/// Shadow map + extents + table + march (+ upsample) for one frame, timed when the device
/// allows: the frame's inputs, and the options with their defaults (`MarchSettings::default()`,
/// a 1024² shadow map, the depth-aware 3×3 upsampling, no light texture).
#[derive(Clone, Copy)]
pub struct ShadowPasses<'a> {
    camera: &'a Camera,
    light: &'a Light,
    medium: &'a Medium,
    depth: &'a wgpu::Texture,
    occluders: &'a [volshadow::gpu::Occluder<'a>],
    settings: MarchSettings,
    shadow_resolution: u32,
    filter: volshadow::nodes::UpsampleFilter,
    texture: Option<&'a wgpu::Texture>,
    channels: volshadow::scene::TextureChannels,
    /// Wired by hand with the faces scaled by this (see [`by_hand`]), not through the facade.
    by_hand: Option<f32>,
}

impl<'a> ShadowPasses<'a> {
    pub fn new(
        camera: &'a Camera,
        light: &'a Light,
        medium: &'a Medium,
        depth: &'a wgpu::Texture,
        occluders: &'a [volshadow::gpu::Occluder<'a>],
    ) -> Self {
        Self {
            camera,
            light,
            medium,
            depth,
            occluders,
            settings: MarchSettings::default(),
            shadow_resolution: 1024,
            filter: volshadow::nodes::UpsampleFilter::DepthAware3x3,
            texture: None,
            channels: volshadow::scene::TextureChannels::Rgb,
            by_hand: None,
        }
    }

    pub fn settings(self, settings: MarchSettings) -> Self {
        Self { settings, ..self }
    }

    pub fn shadow_resolution(self, shadow_resolution: u32) -> Self {
        Self {
            shadow_resolution,
            ..self
        }
    }

    /// The filter that brings a march at `settings.scale` back to full resolution (the
    /// in-scatter is full resolution; steps and extents are at the march's).
    pub fn filter(self, filter: volshadow::nodes::UpsampleFilter) -> Self {
        Self { filter, ..self }
    }

    /// A spot light's texture.
    pub fn texture(self, texture: Option<&'a wgpu::Texture>) -> Self {
        Self { texture, ..self }
    }

    /// Which of the texture's channels count (default: RGB).
    pub fn channels(self, channels: volshadow::scene::TextureChannels) -> Self {
        Self { channels, ..self }
    }

    /// The nodes wired by hand instead of the facade, the shadow map's faces times
    /// `face_scale` (see [`by_hand::frame`]).
    pub fn by_hand(self, face_scale: f32) -> Self {
        Self {
            by_hand: Some(face_scale),
            ..self
        }
    }
}

/// Runs `passes` (see [`ShadowPasses`]) through the facade, as one frame of
/// [`Settings::PREDICTABLE`] with the passes' march settings, shadow-map resolution and filter.
pub fn shadow_frame(gpu: &HeadlessGpu, cache: &Cache, passes: &ShadowPasses) -> ShadowFrame {
    let ShadowPasses {
        camera,
        light,
        medium,
        depth,
        occluders,
        settings,
        shadow_resolution,
        filter,
        texture,
        channels,
        by_hand,
    } = *passes;
    if let Some(face_scale) = by_hand {
        return by_hand::frame(gpu, cache, passes, face_scale);
    }
    let settings = Settings {
        march: settings,
        upsample: filter,
        shadow_map: volshadow::nodes::ShadowMapSettings {
            resolution: shadow_resolution,
            ..volshadow::nodes::ShadowMapSettings::DEFAULT
        },
        ..Settings::PREDICTABLE
    };
    let lights = [FrameLight {
        light: *light,
        texture,
        casters: None,
        texture_channels: channels,
    }];
    let mut frame = FacadeFrame::new(gpu, cache, settings, depth);
    let vs = frame.run(gpu, camera, &lights, medium, occluders);
    let times = vs.read_timings(&gpu.device).unwrap();
    let read_depth = |t: &wgpu::Texture| -> Vec<f32> {
        bytemuck::pod_collect_to_vec(&gpu.read_texture_bytes(t).unwrap())
    };
    let steps_bytes = gpu.read_texture_bytes(vs.step_counts(0).unwrap()).unwrap();
    ShadowFrame {
        inscatter: gpu.read_rgba32f(vs.inscatter(0).unwrap()).unwrap(),
        steps: bytemuck::pod_collect_to_vec(&steps_bytes),
        stats: volshadow::nodes::MarchStats::from_bytes(
            &gpu.read_buffer_bytes(vs.march_stats(0).unwrap()).unwrap(),
        )
        .unwrap(),
        extents: vs.extents(0).map(|e| e.textures.each_ref().map(read_depth)),
        times,
    }
}
