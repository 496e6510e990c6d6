#![doc = include_str!("../README.md")]
//!
//! # Beyond the README
//!
//! The text above is the repository's `README.md`, included as it is: the crate has one front
//! door, not two copies of it (its images and relative links point into the repository). What
//! follows is in the rustdoc only.
//!
//! ## A complete program
//!
//! A complete frame: a device, the application's colour and depth textures (cleared here,
//! where an application draws its scene), a camera from glam 0.34's `camera::rh` functions, a
//! box as the occluder, a point light in hazy air, and the output written by the composite.
//!
//! ```no_run
//! use volshadow::glam::{camera::rh, Mat4, Vec3};
//! use volshadow::scene::Mesh;
//! use volshadow::{
//!     AdapterKind, Cache, Camera, Frame, Light, Medium, Occluder, OccluderMesh, PhaseFunction,
//!     PointLight, Settings, VolumetricShadows,
//! };
//!
//! fn main() -> Result<(), Box<dyn std::error::Error>> {
//!     // Any adapter of any backend: volshadow records into the device you already have.
//!     let instance = wgpu::Instance::default();
//!     let adapter = pollster::block_on(instance.request_adapter(&Default::default()))?;
//!     let (device, queue) = pollster::block_on(adapter.request_device(&Default::default()))?;
//!
//!     // The application's own targets. volshadow samples colour and depth
//!     // (`TEXTURE_BINDING`) and writes the composite into `output` (of
//!     // `Settings::output_format`), all the same size. With `STORAGE_BINDING` the composite
//!     // is a compute pass, far cheaper where the graphics units are a small part of the GPU.
//!     let (width, height) = (640, 400);
//!     let target = |label, format, usage| {
//!         device.create_texture(&wgpu::TextureDescriptor {
//!             label: Some(label),
//!             size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
//!             mip_level_count: 1,
//!             sample_count: 1,
//!             dimension: wgpu::TextureDimension::D2,
//!             format,
//!             usage,
//!             view_formats: &[],
//!         })
//!     };
//!     let draw_and_sample =
//!         wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING;
//!     let color = target("scene colour", wgpu::TextureFormat::Rgba16Float, draw_and_sample);
//!     let depth = target("scene depth", wgpu::TextureFormat::Depth32Float, draw_and_sample);
//!     let output = target(
//!         "volshadow output",
//!         wgpu::TextureFormat::Rgba16Float,
//!         wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::STORAGE_BINDING,
//!     );
//!
//!     // Right-handed view; wgpu's depth range 0..1 is DirectX's (reversed Z and an infinite
//!     // far plane work too: `Camera` reads the convention from the matrix).
//!     let camera = Camera::new(
//!         rh::view::look_at_mat4(Vec3::new(0.0, 1.6, 7.0), Vec3::new(0.0, 1.3, 0.0), Vec3::Y),
//!         rh::proj::directx::perspective(
//!             55f32.to_radians(),
//!             width as f32 / height as f32,
//!             0.05,
//!             200.0,
//!         ),
//!     )?;
//!
//!     // Once: the shared pipelines, the occluder's mesh (validated, adjacency built, uploaded)
//!     // and the facade.
//!     let cache = Cache::new(&device);
//!     let positions: Vec<Vec3> = (0..8)
//!         .map(|i| Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32))
//!         .map(|p| p - 0.5)
//!         .collect();
//!     let indices = [
//!         0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4,
//!         6, 1, 3, 5, 3, 7, 5,
//!     ];
//!     let cube = OccluderMesh::new(&device, &Mesh::new(&positions, &indices)?);
//!     let mut volumetric = VolumetricShadows::new(
//!         &device,
//!         &queue,
//!         &cache,
//!         Settings {
//!             output_format: wgpu::TextureFormat::Rgba16Float,
//!             // The exact method, at full resolution on a GPU and half on a CPU adapter.
//!             ..Settings::for_adapter(AdapterKind::of(&device))
//!         },
//!     )?;
//!
//!     // Every frame: draw your scene into `color` and `depth`. Here a ground plane and the
//!     // cube, lit by a fixed direction, from one vertex buffer (position, normal) and the
//!     // camera's matrix baked into the shader: your renderer does this its own way.
//!     let cube_at = Mat4::from_translation(Vec3::new(0.0, 2.0, -2.0));
//!     let mut vertices: Vec<[f32; 6]> = Vec::new();
//!     for tri in indices.chunks_exact(3) {
//!         let p = [tri[0], tri[1], tri[2]].map(|i| cube_at.transform_point3(positions[i as usize]));
//!         let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
//!         vertices.extend(p.map(|q| [q.x, q.y, q.z, n.x, n.y, n.z]));
//!     }
//!     for [x, z] in [[-1.0, -1.0], [1.0, 1.0], [1.0, -1.0], [-1.0, -1.0], [-1.0, 1.0], [1.0, 1.0]] {
//!         vertices.push([20.0 * x, 0.0, 20.0 * z, 0.0, 1.0, 0.0]);
//!     }
//!     let vertex_buffer = wgpu::util::DeviceExt::create_buffer_init(
//!         &device,
//!         &wgpu::util::BufferInitDescriptor {
//!             label: Some("the application's geometry"),
//!             contents: bytemuck::cast_slice(&vertices),
//!             usage: wgpu::BufferUsages::VERTEX,
//!         },
//!     );
//!     let view_proj = camera.projection() * camera.view();
//!     let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
//!         label: Some("the application's shading"),
//!         source: wgpu::ShaderSource::Wgsl(format!(
//!             "const VIEW_PROJ = mat4x4<f32>({:?});
//!              struct V {{ @builtin(position) clip: vec4<f32>, @location(0) n: vec3<f32> }}
//!              @vertex fn vs(@location(0) p: vec3<f32>, @location(1) n: vec3<f32>) -> V {{
//!                  return V(VIEW_PROJ * vec4<f32>(p, 1.0), n);
//!              }}
//!              @fragment fn fs(v: V) -> @location(0) vec4<f32> {{
//!                  let lit = max(dot(normalize(v.n), normalize(vec3<f32>(0.3, 1.0, 0.5))), 0.0);
//!                  return vec4<f32>(vec3<f32>(0.05 + 0.4 * lit), 1.0);
//!              }}",
//!             view_proj.to_cols_array()
//!         ).replace(['[', ']'], "").into()),
//!     });
//!     let raster = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
//!         label: Some("the application's raster"),
//!         layout: None,
//!         vertex: wgpu::VertexState {
//!             module: &shader,
//!             entry_point: Some("vs"),
//!             compilation_options: Default::default(),
//!             buffers: &[Some(wgpu::VertexBufferLayout {
//!                 array_stride: 24,
//!                 step_mode: wgpu::VertexStepMode::Vertex,
//!                 attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3],
//!             })],
//!         },
//!         primitive: Default::default(),
//!         depth_stencil: Some(wgpu::DepthStencilState {
//!             format: wgpu::TextureFormat::Depth32Float,
//!             depth_write_enabled: Some(true),
//!             depth_compare: Some(wgpu::CompareFunction::Less),
//!             stencil: Default::default(),
//!             bias: Default::default(),
//!         }),
//!         multisample: Default::default(),
//!         fragment: Some(wgpu::FragmentState {
//!             module: &shader,
//!             entry_point: Some("fs"),
//!             compilation_options: Default::default(),
//!             targets: &[Some(wgpu::TextureFormat::Rgba16Float.into())],
//!         }),
//!         multiview_mask: None,
//!         cache: None,
//!     });
//!     let mut encoder = device.create_command_encoder(&Default::default());
//!     {
//!         let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
//!             label: Some("the application's scene"),
//!             color_attachments: &[Some(wgpu::RenderPassColorAttachment {
//!                 view: &color.create_view(&Default::default()),
//!                 depth_slice: None,
//!                 resolve_target: None,
//!                 ops: wgpu::Operations {
//!                     load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
//!                     store: wgpu::StoreOp::Store,
//!                 },
//!             })],
//!             depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
//!                 view: &depth.create_view(&Default::default()),
//!                 depth_ops: Some(wgpu::Operations {
//!                     load: wgpu::LoadOp::Clear(camera.far_depth()),
//!                     store: wgpu::StoreOp::Store,
//!                 }),
//!                 stencil_ops: None,
//!             }),
//!             timestamp_writes: None,
//!             occlusion_query_set: None,
//!             multiview_mask: None,
//!         });
//!         pass.set_pipeline(&raster);
//!         pass.set_vertex_buffer(0, vertex_buffer.slice(..));
//!         pass.draw(0..vertices.len() as u32, 0..1);
//!     }
//!
//!     // ... then describe it, prepare (validate, upload, plan) and record volshadow's passes.
//!     let lights = [Light::from(PointLight::new(
//!         Vec3::new(0.1, 2.9, -4.6),
//!         Vec3::new(90.0, 78.0, 60.0),
//!     )?)
//!     .into()];
//!     let medium = Medium::new(
//!         Vec3::new(0.10, 0.11, 0.13),
//!         Vec3::splat(0.01),
//!         PhaseFunction::HenyeyGreenstein { g: 0.7 },
//!     )?;
//!     let occluders = [Occluder {
//!         mesh: &cube,
//!         transform: cube_at,
//!     }];
//!     let plan = volumetric.prepare(
//!         &device,
//!         &queue,
//!         &Frame {
//!             camera: &camera,
//!             lights: &lights,
//!             medium: &medium,
//!             occluders: &occluders,
//!             scene_color: &color,
//!             scene_depth: &depth,
//!             surfaces: None,
//!         },
//!     )?;
//!     println!("{plan}"); // what runs, and why the rest does not
//!     volumetric.encode(&mut encoder, &output)?;
//!     queue.submit([encoder.finish()]); // volshadow never submits: you do
//!     Ok(())
//! }
//! ```
//!
//! `cargo run --release --example quickstart` renders the same kind of scene headless to a PNG
//! (with [`HeadlessGpu`], which also reads textures back); the repository's `examples/` hold a
//! scene-file renderer, a glTF viewer and an interactive window.
//!
//! ## Where the method comes from
//!
//! The closed-form airlight is a numerically stable form of the analytic single-scattering
//! model of Sun, Ramamoorthi, Narasimhan and Nayar ("A Practical Analytic Single Scattering
//! Model for Real Time Rendering", 2005), tabulated per frame on the GPU. The exact method
//! integrates between shadow-volume crossings after Biri, Arquès and Michelin's exact
//! integration between shadow planes; the hybrid method is Wyman and Ramsey's ("Interactive
//! Volumetric Shadows in Participating Media with Single-Scattering", 2008: march only between
//! the shadow volumes' extents). A light with a radius gets soft shadows from a light-space grid
//! of fractional visibility; the light the medium scatters onto surfaces comes from a
//! per-medium table ([`nodes::IssTableNode`]).
//!
//! ## How the crate is built
//!
//! Objects are split by lifetime: a shared [`Cache`] of pipelines and layouts, and
//! per-view nodes ([`nodes`]) that own their textures. Each node has `new`, `prepare`
//! (validates, resizes, uploads what changed) and `encode` (records into a
//! `&mut wgpu::CommandEncoder`; nodes never submit); [`VolumetricShadows`] owns one set per
//! light and follows the [`plan`].
//!
//! [`reference`](mod@reference) is an independent f64 integrator of the same model, the ground
//! truth the tests compare every GPU image with.
//!
//! ## Documents
//!
//! * [`method`]: the maths, the papers it comes from, and design notes (`docs/METHOD.md`).
//! * [`accuracy`]: every accuracy check of the test suite, its current value and its bound
//!   (`docs/ACCURACY.md`, generated from the tests' output).
//! * [`performance`]: the cost of each method on the standard scenes (`docs/PERFORMANCE.md`,
//!   generated from the `report` example's and the tests' output).
#![warn(missing_docs)]

pub mod error;
mod facade;
mod frame;
#[cfg(feature = "gltf")]
pub mod gltf;
pub mod gpu;
mod light;
pub mod load;
/// The method's maths: the model, the stable airlight form, the F′ table, shadows along the ray.
#[doc = include_str!("../docs/METHOD.md")]
pub mod method {}
pub mod nodes;
mod pass;
/// Measured accuracy: every check, its current value and bound, and the test that printed it.
#[doc = include_str!("../docs/ACCURACY.md")]
pub mod accuracy {}
/// Measured cost: the `report` example's and the benchmark's figures on the standard scenes.
#[doc = include_str!("../docs/PERFORMANCE.md")]
pub mod performance {}
pub mod plan;
pub mod reference;
pub mod scene;
pub mod scene_file;
mod settings;

#[cfg(feature = "gltf")]
pub use error::GltfError;
pub use error::{Error, Result, SceneFileError};
pub use facade::VolumetricShadows;
pub use frame::{Frame, FrameLight, Surfaces};
pub use gpu::headless::{tone_map, HeadlessGpu};
pub use gpu::{passes_recorded, PassCount};
pub use gpu::{ErrorSign, ShaderPrecision};
pub use gpu::{Occluder, OccluderMesh};
pub use load::{Limit, LoadOptions};
pub use nodes::{Cache, LightKind};
pub use plan::{AdapterKind, FrameReport, Plan};
pub use scene::{Camera, DirectionalLight, Light, Medium, PhaseFunction, PointLight, SpotLight};
pub use settings::Settings;

pub use glam;
pub use wgpu;

/// A self-contained WGSL module for a caller's surface shader: `volshadow_iss(table, p, n,
/// light_pos, intensity, sigma_s, sigma_t) -> vec3<f32>` returns the irradiance `E(P)` the
/// medium scatters onto a Lambertian surface point (unshadowed, the medium extending to
/// infinity around it) from a point light; multiply by the surface's `kd` (`ρ/π` for an albedo
/// `ρ`) for the radiance it adds. `table` is [`nodes::IssTableNode::view`] (a
/// `texture_2d<f32>`, non-filterable: read with `textureLoad`, no sampler). Its names start
/// with `volshadow_iss` / `VOLSHADOW_ISS`, and with `vs_` / `VS_` / `VOLSHADOW_PRECISION` for
/// the precision wrappers it calls its built-ins through (at [`ShaderPrecision::Native`]: the
/// built-ins themselves). See [`nodes::IssTableNode`] for the maths and the table's measured
/// accuracy.
///
/// For a spot light, `volshadow_iss_spot(phase, p, n, light_pos, axis, cos_half, intensity,
/// sigma_s, sigma_t) -> vec3<f32>` returns the same irradiance from the medium inside the cone
/// only (apex `light_pos`, `axis` the cone's direction, `cos_half` the cosine of half its apex
/// angle, [`SpotLight::cos_half_angle`]); `phase` is a `VolshadowIssPhase`, the bytes of
/// [`nodes::IssPhase`] in a buffer. It reads no table: a fixed quadrature over the hemisphere
/// (about 16 × 12 × 3 phase evaluations a point), within 2% of the f64 reference at the 95th
/// percentile for σt·D ≤ 5 (`tests/gpu/iss_spot.rs`; the method is in `docs/METHOD.md`). It is
/// smooth across a surface: evaluate it on a lattice of pixels and interpolate, as the
/// composite does ([`nodes::CompositeNode::set_spot_lattice`]).
pub const ISS_WGSL: &str = concat!(
    include_str!("../shaders/precision.wgsl"),
    include_str!("../shaders/shared/iss.wgsl")
);

/// A self-contained WGSL module for shadowing a caller's surfaces with the shadow maps volshadow
/// renders for its volumetric shadows: `volshadow_shadow(map, cmp, params, p, n) -> f32`, the
/// visibility in `[0, 1]` of a surface point (2×2 percentage-closer filtered; soft for a light
/// with a radius, below), with a normal
/// offset and the maps' relative depth bias. `map` is a shadow map's texture
/// ([`nodes::ShadowMap`], from [`VolumetricShadows::shadow_map`]) as a
/// `texture_depth_2d_array`, `cmp` a comparison sampler (`GreaterEqual`, linear filtering),
/// `params` [`nodes::ShadowMap::params`] uploaded as a buffer. The module's comments document
/// the layout and the bias.
///
/// For a point or spot light with a radius (the params' `radius` above 0) the same function is
/// soft: the visible fraction of the light's disc by percentage-closer soft shadows in the
/// map's front layer (16 blocker-search taps, 32 filter taps), times the part of the light
/// above the surface's own tangent plane, `n` then being the outward normal of the side being
/// lit. Radius 0 (or [`nodes::ShadowParams::radius`] set to 0) and directional lights take the
/// hard lookup. Against the exact visible fraction (`tests/gpu/surface_shadow.rs`, a sphere above a
/// ground, light radius 0.4 at 1.52 from the sphere's centre, lavapipe): on the ground, mean
/// 4.5% and p95 12.5% (point light; spot 5.9%, 16.2%), the hard lookup 18.7% and 46%; on the
/// sphere itself mean 0.2%, p95 0.5%.
pub const SHADOW_WGSL: &str = include_str!("../shaders/public/shadow.wgsl");
