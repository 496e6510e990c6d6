//! Quickstart: a lit foggy scene rendered headless to `quickstart.png`.
//!
//! The "application" here draws its own frame (a ground plane and two spheres, ray-cast in a
//! fragment shader that writes colour and depth); volshadow then adds the light scattered in
//! the fog, with the dark shafts the spheres cut through it, recorded into the application's
//! encoder by `VolumetricShadows` (its plan and per-pass GPU times are printed).
//!
//! ```text
//! cargo run --release --example quickstart [-- OUTPUT.png]
//! ```

use std::time::Instant;

#[path = "common/headless_env.rs"]
mod headless_env;

use volshadow::glam::{Mat4, Vec3};
use volshadow::scene::shapes;
use volshadow::{
    Cache, Camera, Frame, HeadlessGpu, Light, Medium, Occluder, OccluderMesh, PhaseFunction,
    PointLight, Settings, VolumetricShadows,
};

/// The spheres of the scene (centre, radius): drawn by the app, and occluders for volshadow.
pub const SPHERES: [(Vec3, f32); 2] = [
    (Vec3::new(-0.6, 2.2, -2.2), 0.5),
    (Vec3::new(0.8, 1.7, -1.4), 0.4),
];

/// The scene: a camera, a point light behind two spheres, hazy air: the spheres cut dark shafts
/// towards the camera.
pub fn scene(width: u32, height: u32) -> volshadow::Result<(Camera, PointLight, Medium)> {
    let eye = Vec3::new(0.0, 1.6, 7.0);
    let camera = Camera::new(
        volshadow::glam::camera::rh::view::look_at_mat4(eye, Vec3::new(0.0, 1.3, 0.0), Vec3::Y),
        volshadow::glam::camera::rh::proj::directx::perspective(
            55f32.to_radians(),
            width as f32 / height as f32,
            0.05,
            200.0,
        ),
    )?;
    let light = PointLight::new(Vec3::new(0.1, 2.9, -4.6), Vec3::new(90.0, 78.0, 60.0))?;
    let medium = Medium::new(
        Vec3::new(0.10, 0.11, 0.13),
        Vec3::splat(0.01),
        PhaseFunction::HenyeyGreenstein { g: 0.7 },
    )?;
    Ok((camera, light, medium))
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
    let (camera, point, medium) = scene(width, height)?;

    // The application's own frame: colour (linear radiance) and depth.
    let (color, depth) = draw_scene(gpu, &camera, &point, &medium, width, height);

    // volshadow: a shared cache, the occluder meshes (uploaded once), the facade.
    let cache = Cache::new(&gpu.device);
    let meshes: Vec<OccluderMesh> = SPHERES
        .iter()
        .map(|&(c, r)| OccluderMesh::new(&gpu.device, &shapes::uv_sphere(c, r, 48, 24).unwrap()))
        .collect();
    let occluders: Vec<Occluder> = meshes
        .iter()
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
        wgpu::TextureFormat::Rgba32Float,
        wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        width,
        height,
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
    };
    for frame_index in 0..frames {
        let start = Instant::now();
        let plan = volumetric.prepare(&gpu.device, &gpu.queue, &frame)?;
        println!("frame {frame_index} plan:\n{plan}");
        // An app records into its own encoder and submits (`volumetric.encode`); this one
        // also times each pass: by timestamp queries, or on a CPU adapter (lavapipe) by
        // running each pass alone.
        let timings = gpu.run_timed(&mut volumetric, &output, &[])?;
        let wall = start.elapsed().as_secs_f64() * 1e3;
        let gpu_ms: f64 = timings.iter().map(|t| t.ms).sum();
        let per_pass: Vec<String> = timings
            .iter()
            .map(|t| format!("{} {:.2} ms", t.label, t.ms))
            .collect();
        println!(
            "frame {frame_index}: GPU {gpu_ms:.2} ms ({}); wall clock {wall:.1} ms at {width}x{height}",
            per_pass.join(", ")
        );
    }
    Ok(Rendered {
        output: gpu.read_rgba32f(&output)?,
        inscatter: gpu.read_rgba32f(volumetric.inscatter(0).expect("rendered"))?,
    })
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // No false `error: XDG_RUNTIME_DIR ...` line from Mesa's Vulkan layer when headless.
    headless_env::quiet_display_probe();
    let output_path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "quickstart.png".into());
    let gpu = HeadlessGpu::with_optional_features(wgpu::Features::TIMESTAMP_QUERY)?;
    println!("adapter: {}", gpu.adapter_summary());
    let (width, height) = (640, 400);
    // Two frames: the second shows what the planner skips when nothing changed.
    let rendered = run(&gpu, width, height, Settings::default(), 2)?;
    tone_map(&rendered.output, width, height).save(&output_path)?;
    println!("wrote {output_path}");
    Ok(())
}

fn texture_desc(
    label: &'static str,
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
    width: u32,
    height: u32,
) -> wgpu::TextureDescriptor<'static> {
    wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    }
}

/// Exposure, Reinhard and sRGB encoding for the PNG.
fn tone_map(pixels: &[[f32; 4]], width: u32, height: u32) -> image::RgbImage {
    let encode = |v: f32| {
        let v = 1.6 * v;
        let v = v / (1.0 + v);
        let s = if v <= 0.003_130_8 {
            12.92 * v
        } else {
            1.055 * v.powf(1.0 / 2.4) - 0.055
        };
        (s.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
    };
    image::RgbImage::from_fn(width, height, |x, y| {
        let p = pixels[(y * width + x) as usize];
        image::Rgb([encode(p[0]), encode(p[1]), encode(p[2])])
    })
}

/// The application's frame: ray-casts a ground plane and two spheres, shades them with the
/// point light (inverse square, attenuated through the medium, shadowed by the spheres), and
/// writes colour and depth.
fn draw_scene(
    gpu: &HeadlessGpu,
    camera: &Camera,
    light: &PointLight,
    medium: &Medium,
    width: u32,
    height: u32,
) -> (wgpu::Texture, wgpu::Texture) {
    let device = &gpu.device;
    let color = device.create_texture(&texture_desc(
        "scene colour",
        wgpu::TextureFormat::Rgba16Float,
        wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
        width,
        height,
    ));
    let depth = device.create_texture(&texture_desc(
        "scene depth",
        wgpu::TextureFormat::Depth32Float,
        wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
        width,
        height,
    ));
    #[repr(C)]
    #[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
    struct SceneUniform {
        clip_from_world: [f32; 16],
        world_from_clip: [f32; 16],
        eye: [f32; 4],
        light: [f32; 4],
        intensity: [f32; 4],
        sigma_t: [f32; 4],
        size: [f32; 4],
    }
    let clip_from_world: Mat4 = camera.projection() * camera.view();
    let uniform = SceneUniform {
        clip_from_world: clip_from_world.to_cols_array(),
        world_from_clip: camera.world_from_clip().to_cols_array(),
        eye: camera.eye().extend(0.0).to_array(),
        light: light.position().extend(0.0).to_array(),
        intensity: light.intensity().extend(0.0).to_array(),
        sigma_t: medium.sigma_t().extend(0.0).to_array(),
        size: [width as f32, height as f32, 0.0, 0.0],
    };
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("scene uniform"),
        size: std::mem::size_of::<SceneUniform>() as u64,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    gpu.queue
        .write_buffer(&buffer, 0, bytemuck::bytes_of(&uniform));
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("quickstart scene"),
        source: wgpu::ShaderSource::Wgsl(SCENE_WGSL.into()),
    });
    let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("quickstart scene"),
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
    let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: buffer.as_entire_binding(),
        }],
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let color_view = color.create_view(&Default::default());
        let depth_view = depth.create_view(&Default::default());
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("scene"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &color_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &depth_view,
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
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &bind_group, &[]);
        pass.draw(0..3, 0..1);
    }
    gpu.submit_and_wait(encoder).expect("scene pass");
    (color, depth)
}

const SCENE_WGSL: &str = r#"
struct Scene {
    clip_from_world: mat4x4<f32>,
    world_from_clip: mat4x4<f32>,
    eye: vec4<f32>,
    light: vec4<f32>,
    intensity: vec4<f32>,
    sigma_t: vec4<f32>,
    size: vec4<f32>,
}
@group(0) @binding(0) var<uniform> scene: Scene;

struct Out {
    @location(0) color: vec4<f32>,
    @builtin(frag_depth) depth: f32,
}

@vertex fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

const SPHERES = array<vec4<f32>, 2>(vec4<f32>(-0.6, 2.2, -2.2, 0.5), vec4<f32>(0.8, 1.7, -1.4, 0.4));

fn hit_sphere(o: vec3<f32>, d: vec3<f32>, s: vec4<f32>) -> f32 {
    let oc = o - s.xyz;
    let b = dot(oc, d);
    let c = dot(oc, oc) - s.w * s.w;
    let disc = b * b - c;
    if (disc < 0.0) { return -1.0; }
    let t = -b - sqrt(disc);
    return select(-1.0, t, t > 1e-4);
}

@fragment fn fs(@builtin(position) p: vec4<f32>) -> Out {
    let ndc = vec2<f32>(p.x / scene.size.x * 2.0 - 1.0, 1.0 - p.y / scene.size.y * 2.0);
    let a = scene.world_from_clip * vec4<f32>(ndc, 0.0, 1.0);
    let b = scene.world_from_clip * vec4<f32>(ndc, 0.5, 1.0);
    let o = scene.eye.xyz;
    let d = normalize(b.xyz / b.w - a.xyz / a.w);
    var t = 1e30;
    var n = vec3<f32>(0.0);
    var albedo = vec3<f32>(0.0);
    if (d.y < 0.0) {
        t = -o.y / d.y;
        n = vec3<f32>(0.0, 1.0, 0.0);
        let hit = o + t * d;
        let checker = (i32(floor(hit.x)) + i32(floor(hit.z))) & 1;
        albedo = select(vec3<f32>(0.55), vec3<f32>(0.35), checker == 1);
    }
    for (var k = 0; k < 2; k++) {
        let ts = hit_sphere(o, d, SPHERES[k]);
        if (ts > 0.0 && ts < t) {
            t = ts;
            n = normalize(o + t * d - SPHERES[k].xyz);
            albedo = vec3<f32>(0.7, 0.45, 0.3);
        }
    }
    var out: Out;
    if (t >= 1e30) {
        out.color = vec4<f32>(0.0, 0.0, 0.0, 1.0);
        out.depth = 1.0;
        return out;
    }
    let x = o + t * d;
    let to_light = scene.light.xyz - x;
    let dist = length(to_light);
    let l = to_light / dist;
    var lit = 1.0;
    for (var k = 0; k < 2; k++) {
        let ts = hit_sphere(x + n * 1e-3, l, SPHERES[k]);
        if (ts > 0.0 && ts < dist) { lit = 0.0; }
    }
    let e = scene.intensity.xyz * exp(-scene.sigma_t.xyz * dist) / (dist * dist);
    out.color = vec4<f32>(albedo / 3.14159265 * e * max(dot(n, l), 0.0) * lit + 0.01 * albedo, 1.0);
    let clip = scene.clip_from_world * vec4<f32>(x, 1.0);
    out.depth = clip.z / clip.w;
    return out;
}
"#;
