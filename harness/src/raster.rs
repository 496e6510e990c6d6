//! The application's own frame: a plain forward rasteriser of triangle meshes.
//!
//! This is the "app" side of the examples, not part of volshadow: it writes what any renderer
//! would hand to [`volshadow::VolumetricShadows`] — linear radiance in an `Rgba32Float` colour
//! texture and a `Depth32Float` depth buffer, both the output's size.
//!
//! Shading, per surface point `x` with flat normal `n` (two-sided) and albedo `ρ`:
//!
//! ```text
//! Ls = ρ/π · Σ_lights I0(ω) · max(n·l, 0) / d² · exp(−σt·d)  +  ρ · ambient
//! ```
//!
//! with `d` the distance to the light, `exp(−σt·d)` the fog between light and surface (the
//! fog between surface and eye is volshadow's composite's job), `I0(ω)` zero outside a spot
//! light's cone and multiplied by its projected texture when it has one, and by the surface's
//! visibility from the light where the light has a shadow map ([`surface_shadow_maps`]:
//! volshadow's shadow-map node, sampled with `volshadow::SHADOW_WGSL`).

use volshadow::glam::{Mat4, Vec3};
use volshadow::nodes::{Encode, Node};
use volshadow::nodes::{ShadowMap, ShadowMapInputs, ShadowMapNode, ShadowMapSettings};
use volshadow::scene::Mesh;
use volshadow::{Cache, Camera, HeadlessGpu, Light, Medium, Occluder};

pub use super::fullscreen::texture_desc;

/// The most lights the raster shades (the facade's limit too).
pub const MAX_LIGHTS: usize = 4;

/// One mesh to draw: object-space triangles placed by `transform`.
pub struct DrawObject<'a> {
    /// The triangles, in object space.
    pub mesh: &'a Mesh,
    /// Object → world.
    pub transform: Mat4,
    /// Diffuse reflectance, linear RGB.
    pub albedo: Vec3,
}

/// One light to shade with, and its projected texture (as uploaded for volshadow, e.g. by
/// `LightTexture::upload`; only used for spot lights).
#[derive(Clone, Copy)]
pub struct DrawLight<'a> {
    /// The light.
    pub light: Light,
    /// A filterable float texture, or `None` for white.
    pub texture: Option<&'a wgpu::Texture>,
    /// The light's shadow map (from [`surface_shadow_maps`]), or `None` for unshadowed.
    pub shadow: Option<ShadowMap<'a>>,
}

/// Renders one shadow map per light with volshadow's shadow-map node (default settings: 1024²,
/// the depth bias the volumetric shadows use) for the app's surfaces; `None` for a light
/// without occluders. A directional light's map is fitted to what `camera` sees.
pub fn surface_shadow_maps(
    gpu: &HeadlessGpu,
    lights: &[Light],
    occluders: &[Occluder],
    camera: &Camera,
) -> Result<Vec<Option<ShadowMapNode>>, Box<dyn std::error::Error>> {
    let cache = Cache::new(&gpu.device);
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    let mut nodes = Vec::new();
    for light in lights {
        if occluders.is_empty() {
            nodes.push(None);
            continue;
        }
        let mut node = ShadowMapNode::new(&gpu.device, &cache, ShadowMapSettings::default())?;
        let inputs = ShadowMapInputs {
            light,
            occluders,
            camera,
            fallback: None,
        };
        node.prepare(&gpu.device, &gpu.queue, &inputs)?;
        node.encode(&mut encoder, None)?;
        nodes.push(Some(node));
    }
    gpu.submit_and_wait(encoder)?;
    Ok(nodes)
}

/// The app's frame: colour (`Rgba32Float`, linear radiance, alpha 1), depth
/// (`Depth32Float`, cleared to `camera.far_depth()` where nothing was drawn), and the surfaces'
/// world-space normals (facing the eye) and albedo (`Rgba16Float`, zero where nothing was
/// drawn: what `volshadow::Surfaces` takes). All have usage
/// `RENDER_ATTACHMENT | TEXTURE_BINDING | COPY_SRC`.
pub struct AppFrame {
    /// Shaded colour.
    pub color: wgpu::Texture,
    /// Depth buffer.
    pub depth: wgpu::Texture,
    /// Unit normals, facing the eye.
    pub normal: wgpu::Texture,
    /// Diffuse albedo ρ.
    pub albedo: wgpu::Texture,
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Vertex {
    position: [f32; 3],
    normal: [f32; 3],
    albedo: [f32; 3],
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct LightUniform {
    /// xyz position, w: 0 point, 1 spot.
    position: [f32; 4],
    /// rgb intensity, w: 1 when textured.
    intensity: [f32; 4],
    /// xyz cone axis, w: cos(half angle).
    direction: [f32; 4],
    /// World → the spot's texture frame.
    frame: [f32; 16],
    /// x: tan(half angle).
    params: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct SceneUniform {
    clip_from_world: [f32; 16],
    eye: [f32; 4],
    sigma_t: [f32; 4],
    ambient: [f32; 4],
    light_count: [u32; 4],
    lights: [LightUniform; MAX_LIGHTS],
}

/// `VolshadowShadow` of each light slot.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct ShadowUniform {
    lights: [volshadow::nodes::ShadowParams; MAX_LIGHTS],
}

/// A small ambient radiance per unit albedo for a scene: 3% of what a white surface facing
/// each light at the eye's distance from it would reflect, so it scales with the scene. The
/// distance is at least a tenth of the half-diagonal of the objects' bounds: a light at (or
/// next to) the eye would otherwise light the surfaces by its 1/d² there (2e11 with the light
/// at the eye).
pub fn default_ambient(
    camera: &Camera,
    lights: &[DrawLight],
    objects: &[DrawObject],
    medium: &Medium,
) -> Vec3 {
    let (lo, hi) = objects
        .iter()
        .flat_map(|o| {
            let (a, b) = o.mesh.bounds();
            (0..8).map(move |k| {
                let corner = Vec3::new(
                    if k & 1 == 0 { a.x } else { b.x },
                    if k & 2 == 0 { a.y } else { b.y },
                    if k & 4 == 0 { a.z } else { b.z },
                );
                o.transform.transform_point3(corner)
            })
        })
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p), hi.max(p))
        });
    let floor = if objects.is_empty() {
        0.0
    } else {
        0.1 * 0.5 * (hi - lo).length()
    };
    lights
        .iter()
        .map(|l| {
            let Some(p) = l.light.position() else {
                return l.light.intensity(); // a directional light's irradiance
            };
            let d = p.distance(camera.eye()).max(floor).max(1e-6);
            l.light.intensity() * (-medium.sigma_t() * d).exp() / (d * d)
        })
        .sum::<Vec3>()
        * (0.03 / std::f32::consts::PI)
}

/// Draws `objects` seen by `camera` into a new `width × height` colour and depth texture (see
/// the [module docs](self) for the shading). Standard and reversed Z both work: depth is
/// cleared to `camera.far_depth()` and compared towards the near end.
pub fn draw_app_frame(
    gpu: &HeadlessGpu,
    camera: &Camera,
    (width, height): (u32, u32),
    objects: &[DrawObject],
    lights: &[DrawLight],
    medium: &Medium,
    ambient: Vec3,
) -> Result<AppFrame, Box<dyn std::error::Error>> {
    if lights.len() > MAX_LIGHTS {
        return Err(format!(
            "{} lights, the example draws at most {MAX_LIGHTS}",
            lights.len()
        )
        .into());
    }
    let device = &gpu.device;
    let usage = wgpu::TextureUsages::RENDER_ATTACHMENT
        | wgpu::TextureUsages::TEXTURE_BINDING
        | wgpu::TextureUsages::COPY_SRC;
    let color = device.create_texture(&texture_desc(
        "app colour",
        (width, height),
        wgpu::TextureFormat::Rgba32Float,
        usage,
    ));
    let depth = device.create_texture(&texture_desc(
        "app depth",
        (width, height),
        wgpu::TextureFormat::Depth32Float,
        usage,
    ));
    let [normal, albedo] = ["app normal", "app albedo"].map(|label| {
        device.create_texture(&texture_desc(
            label,
            (width, height),
            wgpu::TextureFormat::Rgba16Float,
            usage,
        ))
    });

    // World-space triangles with flat normals, one vertex buffer for the whole scene.
    let mut vertices: Vec<Vertex> = Vec::new();
    for object in objects {
        let positions = object.mesh.positions();
        for tri in object.mesh.indices().chunks_exact(3) {
            let p = [tri[0], tri[1], tri[2]]
                .map(|i| object.transform.transform_point3(positions[i as usize]));
            let normal = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
            for q in p {
                vertices.push(Vertex {
                    position: q.to_array(),
                    normal: normal.to_array(),
                    albedo: object.albedo.to_array(),
                });
            }
        }
    }
    let vertex_buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("app vertices"),
        size: (std::mem::size_of_val(vertices.as_slice()) as u64).max(64),
        usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    gpu.queue
        .write_buffer(&vertex_buffer, 0, bytemuck::cast_slice(&vertices));

    let mut uniform = SceneUniform {
        clip_from_world: (camera.projection() * camera.view()).to_cols_array(),
        eye: camera.eye().extend(1.0).to_array(),
        sigma_t: medium.sigma_t().extend(0.0).to_array(),
        ambient: ambient.extend(0.0).to_array(),
        light_count: [lights.len() as u32, 0, 0, 0],
        lights: [bytemuck::Zeroable::zeroed(); MAX_LIGHTS],
    };
    for (slot, l) in uniform.lights.iter_mut().zip(lights) {
        let textured = if l.texture.is_some() { 1.0 } else { 0.0 };
        let shadowed = if l.shadow.is_some() { 1.0 } else { 0.0 };
        *slot = match l.light {
            Light::Spot(spot) => LightUniform {
                position: spot.position().extend(1.0).to_array(),
                intensity: spot.intensity().extend(textured).to_array(),
                direction: spot.direction().extend(spot.cos_half_angle()).to_array(),
                frame: spot.texture_frame().to_cols_array(),
                params: [(0.5 * spot.cone_angle()).tan(), shadowed, 0.0, 0.0],
            },
            Light::Directional(sun) => LightUniform {
                position: (-sun.direction()).extend(2.0).to_array(),
                intensity: sun.irradiance().extend(0.0).to_array(),
                direction: [0.0, -1.0, 0.0, -1.0],
                frame: Mat4::IDENTITY.to_cols_array(),
                params: [1.0, shadowed, 0.0, 0.0],
            },
            other => LightUniform {
                position: other.position().unwrap_or_default().extend(0.0).to_array(),
                intensity: other.intensity().extend(0.0).to_array(),
                direction: [0.0, -1.0, 0.0, -1.0],
                frame: Mat4::IDENTITY.to_cols_array(),
                params: [1.0, shadowed, 0.0, 0.0],
            },
        };
    }
    let uniform_buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("app scene"),
        size: std::mem::size_of::<SceneUniform>() as u64,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    gpu.queue
        .write_buffer(&uniform_buffer, 0, bytemuck::bytes_of(&uniform));

    // Untextured slots read a 1×1 white texture.
    let white = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("app white"),
        size: wgpu::Extent3d {
            width: 1,
            height: 1,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba16Float,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    let one = half::f16::from_f32(1.0);
    gpu.queue.write_texture(
        white.as_image_copy(),
        bytemuck::cast_slice(&[one; 4]),
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(8),
            rows_per_image: Some(1),
        },
        wgpu::Extent3d {
            width: 1,
            height: 1,
            depth_or_array_layers: 1,
        },
    );
    let views: Vec<wgpu::TextureView> = (0..MAX_LIGHTS)
        .map(|i| {
            lights
                .get(i)
                .and_then(|l| l.texture)
                .unwrap_or(&white)
                .create_view(&Default::default())
        })
        .collect();
    let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
        label: Some("app light texture"),
        mag_filter: wgpu::FilterMode::Linear,
        min_filter: wgpu::FilterMode::Linear,
        ..Default::default()
    });

    // Surface shadows: each light's shadow map (a 1-layer placeholder where it has none) and
    // its parameters, sampled by volshadow's helper.
    let placeholder = device.create_texture(&texture_desc(
        "app no shadow map",
        (1, 1),
        wgpu::TextureFormat::Depth32Float,
        wgpu::TextureUsages::TEXTURE_BINDING,
    ));
    let mut shadow_uniform: ShadowUniform = bytemuck::Zeroable::zeroed();
    let shadow_views: Vec<wgpu::TextureView> = (0..MAX_LIGHTS)
        .map(|i| {
            let shadow = lights.get(i).and_then(|l| l.shadow.as_ref());
            if let (Some(s), Some(l)) = (shadow, lights.get(i)) {
                shadow_uniform.lights[i] = s.params(&l.light, None);
            }
            shadow
                .map_or(&placeholder, |s| s.texture)
                .create_view(&wgpu::TextureViewDescriptor {
                    dimension: Some(wgpu::TextureViewDimension::D2Array),
                    ..Default::default()
                })
        })
        .collect();
    let shadow_buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("app shadows"),
        size: std::mem::size_of::<ShadowUniform>() as u64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    gpu.queue
        .write_buffer(&shadow_buffer, 0, bytemuck::bytes_of(&shadow_uniform));
    let shadow_sampler = device.create_sampler(&wgpu::SamplerDescriptor {
        label: Some("app shadow compare"),
        mag_filter: wgpu::FilterMode::Linear,
        min_filter: wgpu::FilterMode::Linear,
        compare: Some(wgpu::CompareFunction::GreaterEqual),
        ..Default::default()
    });

    let source = format!(
        "{}\n{}",
        volshadow::SHADOW_WGSL,
        include_str!("raster.wgsl")
    );
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("app raster"),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    // Nearer is smaller with standard Z, larger with reversed Z.
    let compare = if camera.far_depth() == 1.0 {
        wgpu::CompareFunction::Less
    } else {
        wgpu::CompareFunction::Greater
    };
    let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("app raster"),
        layout: None,
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs"),
            compilation_options: Default::default(),
            buffers: &[Some(wgpu::VertexBufferLayout {
                array_stride: std::mem::size_of::<Vertex>() as u64,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x3],
            })],
        },
        primitive: wgpu::PrimitiveState { cull_mode: None, ..Default::default() },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: wgpu::TextureFormat::Depth32Float,
            depth_write_enabled: Some(true),
            depth_compare: Some(compare),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("fs"),
            compilation_options: Default::default(),
            targets: &[
                Some(wgpu::TextureFormat::Rgba32Float.into()),
                Some(wgpu::TextureFormat::Rgba16Float.into()),
                Some(wgpu::TextureFormat::Rgba16Float.into()),
            ],
        }),
        multiview_mask: None,
        cache: None,
    });
    let mut entries = vec![wgpu::BindGroupEntry {
        binding: 0,
        resource: uniform_buffer.as_entire_binding(),
    }];
    for (i, view) in views.iter().enumerate() {
        entries.push(wgpu::BindGroupEntry {
            binding: 1 + i as u32,
            resource: wgpu::BindingResource::TextureView(view),
        });
    }
    entries.push(wgpu::BindGroupEntry {
        binding: 1 + MAX_LIGHTS as u32,
        resource: wgpu::BindingResource::Sampler(&sampler),
    });
    for (i, view) in shadow_views.iter().enumerate() {
        entries.push(wgpu::BindGroupEntry {
            binding: 6 + i as u32,
            resource: wgpu::BindingResource::TextureView(view),
        });
    }
    entries.push(wgpu::BindGroupEntry {
        binding: 10,
        resource: wgpu::BindingResource::Sampler(&shadow_sampler),
    });
    entries.push(wgpu::BindGroupEntry {
        binding: 11,
        resource: shadow_buffer.as_entire_binding(),
    });
    let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("app raster"),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &entries,
    });

    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let color_view = color.create_view(&Default::default());
        let depth_view = depth.create_view(&Default::default());
        let normal_view = normal.create_view(&Default::default());
        let albedo_view = albedo.create_view(&Default::default());
        let attachment = |view, a| {
            Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color {
                        r: 0.0,
                        g: 0.0,
                        b: 0.0,
                        a,
                    }),
                    store: wgpu::StoreOp::Store,
                },
            })
        };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("app raster"),
            color_attachments: &[
                attachment(&color_view, 1.0),
                attachment(&normal_view, 0.0),
                attachment(&albedo_view, 0.0),
            ],
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
        if !vertices.is_empty() {
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &bind_group, &[]);
            pass.set_vertex_buffer(0, vertex_buffer.slice(..));
            pass.draw(0..vertices.len() as u32, 0..1);
        }
    }
    gpu.submit_and_wait(encoder)?;
    Ok(AppFrame {
        color,
        depth,
        normal,
        albedo,
    })
}
