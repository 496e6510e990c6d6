//! The shadow-volume extents node: per pixel, where along the view ray the shadow
//! volumes of the occluders begin and end.
//!
//! A compute pass finds silhouette edges and extrudes them away from the light to infinity
//! (for a directional light: edges between a face turned towards the light and one turned
//! away, extruded along its direction, so each volume is a prism closed at one point at
//! infinity),
//! writing the volumes and an indirect draw (no CPU readback); three depth-only passes then
//! rasterise them with the camera's view and a reversed-Z infinite projection
//! (depth = [`EXTENTS_NEAR`] / view depth):
//!
//! * `front`: nearest front face of a closed mesh's volume (0 = none);
//! * `back_near`: nearest back face (0 = none at finite distance);
//! * `back_far`: farthest back face (1 = none, 0 = at infinity).
//!
//! Faces of open or non-manifold meshes count as back faces, so their extents are conservative.
//!
//! With [`ExtentsInputs::crossings`] set (the exact march), per-pixel crossing lists replace
//! the three textures: for every pixel, the view depth at which its centre ray crosses each
//! volume face in front of the scene surface (a bounded list), the nearest and farthest of them,
//! and the net number of volumes entered behind the surface. Between two consecutive crossings
//! nothing can change visibility, so the march integrates each interval in closed form, lit
//! where no volume is around it (the net count behind the surface makes that count known; a
//! pixel crossed by an open mesh's face samples the shadow map instead). Depths are where the pixel's ray
//! meets the face's plane, to f32's precision. Two builds write the same lists
//! ([`CrossingsBuild`]):
//!
//! * **Compute** (the default): the faces are binned into 16 × 16 pixel tiles (a screen box
//!   clipped at the near plane, then a test of each tile's corner rays), and each pixel tests
//!   its ray against its tile's faces: the ray is inside a face when it is inside the cone the
//!   face's vertices span from the eye, three signs of `det(P, Q, d)`, computed for each edge
//!   from its canonically ordered vertices so that two faces sharing an edge never both miss
//!   or both take a ray (watertight), whatever the GPU's rounding. Faces through or behind the
//!   eye and faces at infinity need no clipping. Cost: about the faces times the tiles each
//!   covers, then per pixel its tile's faces (256 at a time through workgroup memory).
//! * **Raster**: one render pass whose fragment stage appends each crossing to the pixel's
//!   list with atomics. Its cost follows the volumes' screen coverage and the GPU's raster
//!   units (few on compute GPUs such as NVIDIA's H100 and H200).
//!
//! # Output
//! Three `Depth32Float` textures of the pass size
//! (`RENDER_ATTACHMENT | TEXTURE_BINDING | COPY_SRC`); with crossings, the lists instead
//! ([`Crossings`]).

use glam::Mat4;

use crate::error::{Error, Result};
use crate::gpu::pipeline::{bind_group, compute_pipeline, depth_pipeline, layout, module, Binding};
use crate::gpu::wgsl::wgsl_file;
use crate::gpu::ShaderPrecision;
use crate::gpu::{
    check_depth_texture, check_target_size, depth_view, wgsl_size, GpuTimer, Occluder,
    UniformBuffer,
};
use crate::nodes::cache::CachedPipelines;
use crate::nodes::light::LightUniform;
use crate::nodes::uniforms::ViewUniform;
use crate::nodes::Cache;
use crate::nodes::{Encode, Node};
use crate::pass::Pass;
use crate::scene::{Camera, Light};

/// Bytes of one shadow-volume vertex (`VolumeVertex` in `shaders/extents.wgsl`): position,
/// flags, the face's plane and a point of it.
const VOLUME_VERTEX_BYTES: u64 = 64;

/// The extrusion's binding table (`@binding(i)` of the compute stage of `shaders/extents.wgsl`).
const EXTRUDE_BINDINGS: [Binding; 6] = [
    Binding::Params,    // ex: the occluder's slot of the extrude parameters
    Binding::Params,    // positions
    Binding::Params,    // indices
    Binding::Params,    // edges
    Binding::ReadWrite, // volume
    Binding::ReadWrite, // args: the indirect draw
];
/// The three depth passes' binding table.
const RASTER_BINDINGS: [Binding; 2] = [
    Binding::Params, // vv: clip_from_world (the fragments project their plane's point)
    Binding::Params, // cross_view: the pass's view, for each pixel's ray
];
/// The crossing lists' binding table (the exact method).
const CROSSINGS_BINDINGS: [Binding; 6] = [
    Binding::VertexParams, // vv
    Binding::Params,       // cross_view
    Binding::Params,       // cp
    Binding::Depth,        // cross_scene_depth
    Binding::ReadWrite,    // heads
    Binding::ReadWrite,    // crossings
];

/// The compute build's binding table (`shaders/crossings.wgsl`).
const BIN_BINDINGS: [Binding; 9] = [
    Binding::Params,    // volume
    Binding::Params,    // count_args: the volume's vertex count
    Binding::Params,    // bp
    Binding::Depth,     // scene_depth
    Binding::ReadWrite, // faces
    Binding::ReadWrite, // tiles
    Binding::ReadWrite, // bins
    Binding::ReadWrite, // heads
    Binding::ReadWrite, // crossings
];
/// `vs_volume_clipped`'s group 1: the volume, read as storage.
const CLIP_VOLUME_BINDINGS: [Binding; 1] = [Binding::VertexParams];

/// How far an occluder may reach from the eye, relative to its distance, before its volumes
/// are clipped ([`clips_volumes`]).
const RASTER_SAFE_REACH: f32 = 65536.0;

/// The fan triangles (instances) a clipped volume triangle is drawn as (at most nine vertices
/// after a cube's six planes).
const FAN: u32 = 7;

/// Tiles of the compute build, in pixels across and down (`TILE` in `shaders/crossings.wgsl`).
const TILE: u32 = 16;
/// Workgroups of the compute build's binning passes (`GROUPS` in `shaders/crossings.wgsl`).
const BIN_GROUPS: u32 = 1024;
/// Bytes of one face record of the compute build (5 `vec4<f32>`).
const FACE_BYTES: u64 = 80;

/// The node's layouts and pipelines, held by the [`Cache`].
#[derive(Clone)]
pub(crate) struct Pipelines {
    extrude_layout: wgpu::BindGroupLayout,
    raster_layout: wgpu::BindGroupLayout,
    crossings_layout: wgpu::BindGroupLayout,
    reset: wgpu::ComputePipeline,
    extrude: wgpu::ComputePipeline,
    /// Front, back near and back far.
    depths: [wgpu::RenderPipeline; 3],
    crossings: wgpu::RenderPipeline,
    /// `depths` through `vs_volume_clipped`, with the volume bound as group 1
    /// (`clip_layout`), for frames whose occluders [`clips_volumes`] says may need it (the
    /// exact method's lists are then built by compute passes).
    clip_layout: wgpu::BindGroupLayout,
    depths_clipped: [wgpu::RenderPipeline; 3],
    bin_layout: wgpu::BindGroupLayout,
    /// The compute build: setup, count, scan, fill, build.
    bin: [wgpu::ComputePipeline; 5],
}

impl CachedPipelines for Pipelines {
    fn build(device: &wgpu::Device, precision: ShaderPrecision) -> Self {
        Self::new(device, precision)
    }
}

impl Pipelines {
    pub(crate) fn new(device: &wgpu::Device, precision: ShaderPrecision) -> Self {
        let extrude_layout = layout(
            device,
            "volshadow extrude",
            wgpu::ShaderStages::COMPUTE,
            &EXTRUDE_BINDINGS,
        );
        let raster_layout = layout(
            device,
            "volshadow extents",
            wgpu::ShaderStages::VERTEX_FRAGMENT,
            &RASTER_BINDINGS,
        );
        // Exact mode: every crossing appended to per-pixel lists from the fragment stage
        // (storage buffers and atomics there are core WebGPU).
        let crossings_layout = layout(
            device,
            "volshadow extents crossings",
            wgpu::ShaderStages::FRAGMENT,
            &CROSSINGS_BINDINGS,
        );
        let clip_layout = layout(
            device,
            "volshadow extents clipped volume",
            wgpu::ShaderStages::VERTEX,
            &CLIP_VOLUME_BINDINGS,
        );
        let module = module(device, &wgsl_file!("extents.wgsl"), precision);
        let compute =
            |label, entry| compute_pipeline(device, label, &[&extrude_layout], &module, entry, &[]);
        let volume_vertices = [wgpu::VertexBufferLayout {
            array_stride: VOLUME_VERTEX_BYTES,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &wgpu::vertex_attr_array![
                0 => Float32x4, 1 => Float32x4, 2 => Float32x4, 3 => Float32x4
            ],
        }];
        let raster = |layout, entry, compare| {
            depth_pipeline(
                device,
                "volshadow extents",
                &[layout],
                &module,
                "vs_volume",
                Some(entry),
                &volume_vertices,
                compare,
                None,
            )
        };
        let clipped = |layout, entry, compare| {
            depth_pipeline(
                device,
                "volshadow extents clipped",
                &[layout, &clip_layout],
                &module,
                "vs_volume_clipped",
                Some(entry),
                &[],
                compare,
                None,
            )
        };
        let bin_layout = layout(
            device,
            "volshadow crossings",
            wgpu::ShaderStages::COMPUTE,
            &BIN_BINDINGS,
        );
        let bin_module =
            crate::gpu::pipeline::module(device, &wgsl_file!("crossings.wgsl"), precision);
        let bin = ["setup", "count", "scan", "fill", "build"].map(|entry| {
            compute_pipeline(
                device,
                "volshadow crossings",
                &[&bin_layout],
                &bin_module,
                entry,
                &[],
            )
        });
        // Reversed Z: nearest = greatest depth.
        use wgpu::CompareFunction::{Greater, Less};
        Self {
            bin_layout,
            bin,
            reset: compute("volshadow extrude reset", "reset"),
            extrude: compute("volshadow extrude", "extrude"),
            depths: [
                raster(&raster_layout, "fs_front", Some(Greater)),
                raster(&raster_layout, "fs_back", Some(Greater)),
                raster(&raster_layout, "fs_back", Some(Less)),
            ],
            crossings: raster(&crossings_layout, "fs_crossings", None),
            depths_clipped: [
                clipped(&raster_layout, "fs_front", Some(Greater)),
                clipped(&raster_layout, "fs_back", Some(Greater)),
                clipped(&raster_layout, "fs_back", Some(Less)),
            ],
            extrude_layout,
            clip_layout,
            raster_layout,
            crossings_layout,
        }
    }
}

/// Per-pixel shadow-volume extents, as written by [`ExtentsNode`].
#[derive(Clone, Copy)]
pub struct Extents<'a> {
    /// Front, back-near and back-far depth textures (see the module docs).
    pub textures: &'a [wgpu::Texture; 3],
    /// The extents projection's near plane.
    pub near: f32,
    /// Per-pixel crossing lists (the exact method); `None`: the textures hold the extents.
    pub crossings: Option<Crossings<'a>>,
}

/// The near plane of the extents' projection, relative to the eye–light distance (a directional
/// light: the scene's size seen from the eye): small enough that volumes are cut only right at
/// the eye, where the start-at-zero rule covers them. Never more than 1% of the
/// distance from the eye to the nearest occluder's bounds.
pub const EXTENTS_NEAR: f32 = 1e-4;

/// The most of the distance from the eye to the nearest occluder's bounds (of those outside
/// which the eye is) that the extents' near plane may be.
const NEAREST_SHARE: f32 = 1e-2;

/// Extrude slots are 256 bytes apart (the core minimum dynamic-offset alignment).
const SLOT: u64 = 256;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct ExtrudeUniform {
    world_from_object: [f32; 16],
    light: LightUniform,
    mirror: f32,
    edges: u32,
    triangles: u32,
    closed: u32,
    capacity: u32,
}

/// WGSL `Params` of `shaders/crossings.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
struct BinUniform {
    view_from_clip: [f32; 16],
    world_from_view: [f32; 16],
    clip_from_world: [f32; 16],
    view_size: [f32; 2],
    size: [u32; 2],
    tiles: [u32; 2],
    far_depth: f32,
    entries: u32,
    near: f32,
    bin_capacity: u32,
    face_capacity: u32,
    /// 1: ray directions are affine in pixel coordinates (see `shaders/crossings.wgsl`).
    affine: u32,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
struct CrossingUniform {
    size: [u32; 2],
    entries: u32,
    near: f32,
}

/// Most crossings a per-pixel list can hold ([`CrossingsRequest::per_pixel`]).
pub const MAX_CROSSINGS_PER_PIXEL: u32 = 32;

/// How the crossing lists are built. Both write the same lists (up to the order of entries and
/// rays that pass exactly through a face's edge).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum CrossingsBuild {
    /// Compute passes: the volume's faces are binned into 16 × 16 pixel tiles, then each pixel
    /// tests its ray against its tile's faces (a watertight edge test from the eye, so faces
    /// through or behind the eye need no clipping). Scales with the GPU's compute units.
    #[default]
    Compute,
    /// One render pass whose fragment stage appends each face's crossing, the rasteriser
    /// finding which pixels a face covers. Its cost follows the GPU's raster units and the
    /// volumes' screen coverage.
    Raster,
}

/// Asks the extents node for per-pixel crossing lists (the exact march) instead of the three
/// depth textures.
#[derive(Clone, Copy)]
pub struct CrossingsRequest<'a> {
    /// Entries per pixel (1 ..= [`MAX_CROSSINGS_PER_PIXEL`]); pixels with more crossings
    /// overflow and are marched between their nearest and farthest crossing. Lowered to what
    /// the device's `max_storage_buffer_binding_size` allows at this size (see
    /// [`Crossings::per_pixel`]).
    pub per_pixel: u32,
    /// The caller's depth buffer (any depth format, `TEXTURE_BINDING`, full resolution):
    /// crossings behind the scene surface are not recorded.
    pub scene_depth: &'a wgpu::Texture,
    /// How the lists are built.
    pub build: CrossingsBuild,
}

/// Per-pixel crossing lists, as written by [`ExtentsNode`] for the exact march.
#[derive(Clone, Copy)]
pub struct Crossings<'a> {
    /// Per pixel (row-major at the pass size) four `u32`: the number of crossings in front of
    /// the surface (may exceed `per_pixel`; bit 31 set when a face of an open or non-manifold
    /// mesh crossed the pixel), the bitwise-not of the nearest crossing's view depth bits, the
    /// farthest crossing's view depth bits, and the net number of volumes entered behind the
    /// surface (wrapping `i32`) (`STORAGE | COPY_SRC`).
    pub heads: &'a wgpu::Buffer,
    /// `per_pixel` view depths (`f32`) per pixel, unsorted, negative for a face entering a
    /// volume; valid up to the count (`STORAGE | COPY_SRC`).
    pub list: &'a wgpu::Buffer,
    /// Entries per pixel.
    pub per_pixel: u32,
    /// The lists' width and height in pixels (the pass size).
    pub size: (u32, u32),
}

/// What the extents are computed for.
#[derive(Clone, Copy)]
pub struct ExtentsInputs<'a> {
    /// The camera (its view and projection; the pass uses its own depth range).
    pub camera: &'a Camera,
    /// The light the volumes are extruded from.
    pub light: &'a Light,
    /// The occluders.
    pub occluders: &'a [Occluder<'a>],
    /// The pass size (the march's resolution).
    pub size: (u32, u32),
    /// `Some`: per-pixel crossing lists for the exact march; `None`: the three depth textures.
    pub crossings: Option<CrossingsRequest<'a>>,
}

/// Whether a pixel's ray direction is an affine function of its coordinates: the inverse
/// projection's w row has no x or y term (every perspective projection, off-centre and jittered
/// ones included), so the binning tests a tile with one evaluation per edge.
fn rays_are_affine(camera: &Camera) -> bool {
    let w = camera.projection().inverse().row(3);
    let scale = w.abs().max_element();
    scale > 0.0 && w.x.abs() <= 1e-7 * scale && w.y.abs() <= 1e-7 * scale
}

/// Tiles across and down at a pass size.
fn tiles_of(width: u32, height: u32) -> (u32, u32) {
    (width.div_ceil(TILE), height.div_ceil(TILE))
}

impl Bins {
    fn new(device: &wgpu::Device, (tx, ty): (u32, u32), max_faces: u32) -> Result<Self> {
        let tiles = u64::from(tx) * u64::from(ty);
        let faces = u64::from(max_faces.max(1));
        crate::gpu::check_buffer_size(device, "crossing bins", FACE_BYTES * faces)?;
        let limits = device.limits();
        let max_binding = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        // Room for every face in 16 tiles and 64 faces a tile on average; a tile beyond it
        // tests every face (correct, slower).
        let entries = (16 * faces + 64 * tiles)
            .max(1 << 16)
            .min(max_binding / 4)
            .min(u64::from(u32::MAX));
        let buffer = |label, size| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        crate::gpu::check_buffer_size(device, "crossing bins", 12 * tiles + 16)?;
        Ok(Self {
            params: UniformBuffer::new(device, "volshadow crossings bins params"),
            faces: buffer("volshadow crossing faces", FACE_BYTES * faces),
            tiles: buffer("volshadow crossing tiles", 12 * tiles + 16),
            bins: buffer("volshadow crossing bins", 4 * entries),
            tile_count: (tx, ty),
            face_capacity: max_faces.max(1),
            bound: None,
        })
    }
}

/// The crossing lists' GPU state.
struct CrossingLists {
    view: UniformBuffer<ViewUniform>,
    params: UniformBuffer<CrossingUniform>,
    heads: wgpu::Buffer,
    list: wgpu::Buffer,
    per_pixel: u32,
    size: (u32, u32),
    depth: wgpu::Texture,
    bind_group: wgpu::BindGroup,
    build: CrossingsBuild,
    /// The compute build's state (created on first use).
    bins: Option<Bins>,
}

/// The compute build's buffers and bind group.
struct Bins {
    params: UniformBuffer<BinUniform>,
    faces: wgpu::Buffer,
    tiles: wgpu::Buffer,
    bins: wgpu::Buffer,
    tile_count: (u32, u32),
    face_capacity: u32,
    /// The bind group, and the volume buffer, lists and depth texture it was made for.
    bound: Option<(wgpu::BindGroup, wgpu::Buffer, wgpu::Buffer, wgpu::Texture)>,
}

/// Computes per-pixel shadow-volume extents.
pub struct ExtentsNode {
    pipelines: Pipelines,
    view_buffer: wgpu::Buffer,
    /// The depth passes' view (their size), for the rays `fs_front` and `fs_back` intersect
    /// with each face's plane.
    raster_view: UniformBuffer<ViewUniform>,
    /// This frame's volumes go through `vs_volume_clipped` ([`clips_volumes`]): the volume
    /// bound for it, and its draw's arguments (the volume's vertex count copied from `args`,
    /// [`FAN`] instances).
    clipping: bool,
    clip_group: Option<wgpu::BindGroup>,
    clipped_args: wgpu::Buffer,
    raster_bind_group: wgpu::BindGroup,
    extrude_buffer: Option<wgpu::Buffer>,
    volume: Option<wgpu::Buffer>,
    args: wgpu::Buffer,
    jobs: Vec<Job>,
    targets: Option<[wgpu::Texture; 3]>,
    near: f32,
    /// `Some` when the last `prepare` asked for crossing lists.
    crossings: Option<CrossingLists>,
    crossings_on: bool,
}

struct Job {
    bind_group: wgpu::BindGroup,
    invocations: u32,
}

impl ExtentsNode {
    /// Creates the node; buffers and textures are sized by [`prepare`](Self::prepare).
    pub fn new(device: &wgpu::Device, cache: &Cache) -> Result<Self> {
        let view_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("volshadow extents view"),
            size: 64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let raster_view = UniformBuffer::new(device, "volshadow extents raster view");
        let raster_bind_group = bind_group(
            device,
            "volshadow extents raster",
            &cache.get::<Pipelines>().raster_layout,
            [view_buffer.as_entire_binding(), raster_view.binding()],
        );
        Ok(Self {
            pipelines: cache.get::<Pipelines>(),
            view_buffer,
            raster_view,
            raster_bind_group,
            extrude_buffer: None,
            volume: None,
            args: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("volshadow extents draw args"),
                size: 16,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::INDIRECT
                    | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            clipping: false,
            clip_group: None,
            clipped_args: {
                use wgpu::util::DeviceExt;
                device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("volshadow extents clipped draw args"),
                    contents: bytemuck::cast_slice(&[0u32, FAN, 0, 0]),
                    usage: wgpu::BufferUsages::INDIRECT | wgpu::BufferUsages::COPY_DST,
                })
            },
            jobs: Vec::new(),
            targets: None,
            near: 0.0,
            crossings: None,
            crossings_on: false,
        })
    }

    /// The extents for the march; `None` before the first `prepare`.
    pub fn extents(&self) -> Option<Extents<'_>> {
        let crossings = if self.crossings_on {
            let lists = self.crossings.as_ref()?;
            Some(Crossings {
                heads: &lists.heads,
                list: &lists.list,
                per_pixel: lists.per_pixel,
                size: lists.size,
            })
        } else {
            None
        };
        Some(Extents {
            textures: self.targets.as_ref()?,
            near: self.near,
            crossings,
        })
    }

    /// Sizes the crossing lists (recreated only when the size or entries per pixel change),
    /// uploads the camera, and rebinds when the depth buffer changed.
    fn prepare_crossings(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        (request, per_pixel): (&CrossingsRequest<'_>, u32),
        (camera, clip_from_world, (width, height), max_faces): (&Camera, Mat4, (u32, u32), u32),
    ) -> Result<()> {
        let pixels = u64::from(width) * u64::from(height);
        let heads_size = 16 * pixels;
        let reuse = self
            .crossings
            .as_ref()
            .is_some_and(|c| c.size == (width, height) && c.per_pixel == per_pixel);
        let (mut view, mut params, heads, list, bound, bins) = match self.crossings.take() {
            Some(c) if reuse => {
                let bound = (c.depth == *request.scene_depth).then_some(c.bind_group);
                (c.view, c.params, c.heads, c.list, bound, c.bins)
            }
            old => {
                let buffer = |label, size| {
                    device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some(label),
                        size,
                        usage: wgpu::BufferUsages::STORAGE
                            | wgpu::BufferUsages::COPY_DST
                            | wgpu::BufferUsages::COPY_SRC,
                        mapped_at_creation: false,
                    })
                };
                let (view, params, bins) = match old {
                    Some(c) => (c.view, c.params, c.bins),
                    None => (
                        UniformBuffer::new(device, "volshadow crossings view"),
                        UniformBuffer::new(device, "volshadow crossings params"),
                        None,
                    ),
                };
                (
                    view,
                    params,
                    buffer("volshadow crossing heads", heads_size),
                    buffer(
                        "volshadow crossing lists",
                        4 * pixels * u64::from(per_pixel),
                    ),
                    None,
                    bins.map(|mut b| {
                        b.bound = None;
                        b
                    }),
                )
            }
        };
        let view_uniform = ViewUniform::new(camera, width, height);
        view.write(queue, view_uniform);
        params.write(
            queue,
            CrossingUniform {
                size: [width, height],
                entries: per_pixel,
                near: self.near,
            },
        );
        let bind_group = bound.unwrap_or_else(|| {
            let depth_view = depth_view(request.scene_depth);
            bind_group(
                device,
                "volshadow extents crossings",
                &self.pipelines.crossings_layout,
                [
                    self.view_buffer.as_entire_binding(),
                    view.binding(),
                    params.binding(),
                    wgpu::BindingResource::TextureView(&depth_view),
                    heads.as_entire_binding(),
                    list.as_entire_binding(),
                ],
            )
        });
        let bins = match request.build {
            CrossingsBuild::Raster => bins,
            CrossingsBuild::Compute => {
                let volume = self.volume.as_ref().expect("created before the lists");
                let mut b = match bins {
                    Some(b)
                        if b.tile_count == tiles_of(width, height)
                            && b.face_capacity >= max_faces =>
                    {
                        b
                    }
                    _ => Bins::new(device, tiles_of(width, height), max_faces)?,
                };
                b.params.write(
                    queue,
                    BinUniform {
                        view_from_clip: view_uniform.view_from_clip,
                        world_from_view: view_uniform.world_from_view,
                        view_size: view_uniform.size,
                        far_depth: view_uniform.far_depth,
                        clip_from_world: clip_from_world.to_cols_array(),
                        size: [width, height],
                        entries: per_pixel,
                        near: self.near,
                        tiles: [b.tile_count.0, b.tile_count.1],
                        bin_capacity: (b.bins.size() / 4) as u32,
                        face_capacity: b.face_capacity,
                        affine: u32::from(rays_are_affine(camera)),
                    },
                );
                let stale = b.bound.as_ref().is_none_or(|(_, v, h, d)| {
                    v != volume || *h != heads || d != request.scene_depth
                });
                if stale {
                    let depth_view = depth_view(request.scene_depth);
                    let group = crate::gpu::pipeline::bind_group(
                        device,
                        "volshadow crossings",
                        &self.pipelines.bin_layout,
                        [
                            volume.as_entire_binding(),
                            self.args.as_entire_binding(),
                            b.params.binding(),
                            wgpu::BindingResource::TextureView(&depth_view),
                            b.faces.as_entire_binding(),
                            b.tiles.as_entire_binding(),
                            b.bins.as_entire_binding(),
                            heads.as_entire_binding(),
                            list.as_entire_binding(),
                        ],
                    );
                    b.bound = Some((
                        group,
                        volume.clone(),
                        heads.clone(),
                        request.scene_depth.clone(),
                    ));
                }
                Some(b)
            }
        };
        self.crossings = Some(CrossingLists {
            view,
            params,
            heads,
            list,
            per_pixel,
            size: (width, height),
            depth: request.scene_depth.clone(),
            bind_group,
            build: request.build,
            bins,
        });
        Ok(())
    }
}

impl Node for ExtentsNode {
    type Inputs<'a> = ExtentsInputs<'a>;

    /// Uploads the occluders' transforms, the light and the camera, and (re)creates the targets
    /// when `width × height` changed. Returns `true` (the extents are recorded every frame).
    ///
    /// # Errors
    ///
    /// [`Error::InvalidSize`](crate::Error::InvalidSize) for a size beyond the device's
    /// limits, [`Error::NonFinite`](crate::Error::NonFinite) or
    /// [`Error::SingularMatrix`](crate::Error::SingularMatrix) for an occluder's transform,
    /// and [`Error::DeviceLimitExceeded`](crate::Error::DeviceLimitExceeded) naming the limit
    /// for buffers the device cannot hold: `shadow volumes`, `occluder transforms`,
    /// `crossing lists` (16 bytes a pixel of heads, bound whole: more than 8.4 million
    /// pixels, such as 4096² at full resolution, at the core limit of 128 MiB), or
    /// `crossing bins` (the compute build's 80 bytes a volume face).
    fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        inputs: &ExtentsInputs<'_>,
    ) -> Result<bool> {
        let ExtentsInputs {
            camera,
            light,
            occluders,
            size: (width, height),
            crossings,
        } = *inputs;
        check_target_size("extents size", device, width, height)?;
        for o in occluders {
            o.validate()?;
            o.check_device(device)?;
        }
        let per_pixel = crossings
            .map(|request| crossings_per_pixel(device, &request, (width, height)))
            .transpose()?;
        let capacity = volume_capacity(occluders);
        self.allocate(device, (width, height), capacity, occluders.len())?;
        let clip_from_world = self.upload_view(queue, camera, light, occluders);
        self.clipping = clips_volumes(camera.eye(), self.near, occluders);
        self.crossings_on = crossings.is_some();
        if !self.crossings_on {
            self.raster_view
                .write(queue, ViewUniform::new(camera, width, height));
        }
        if let (Some(mut request), Some(per_pixel)) = (crossings, per_pixel) {
            // The compute build tests each pixel's ray against each face from the eye and
            // clips nothing, so it holds at any scale; the rasterised lists lose the volumes'
            // caps at infinity where an occluder is far larger than its distance to the eye
            // (figures in CHANGELOG.md), which clipping the finite faces does not cure.
            if self.clipping {
                request.build = CrossingsBuild::Compute;
            }
            let faces = u32::try_from(capacity / 3).unwrap_or(u32::MAX);
            let lists = (camera, clip_from_world, (width, height), faces);
            self.prepare_crossings(device, queue, (&request, per_pixel), lists)?;
        }
        self.bind_occluders(device, queue, light, occluders, capacity);
        Ok(true)
    }
}

/// Whether this frame's volumes go through `vs_volume_clipped` (see `shaders/extents.wgsl`),
/// and the exact method's lists are built by compute passes: where an occluder's bounds reach
/// farther from the eye (in some axis) than [`RASTER_SAFE_REACH`] times their distance from it,
/// or than the extents' near plane (the rasteriser clips nothing nearer). Within it every
/// finite volume vertex lies within 65536 times the depth of any point the rasteriser clips,
/// where it holds (rasterised lists without the clip, a roof's half-size over its distance
/// from the eye: 7e5 moves the image's mean by 0.06%, 7e6 by 1.2%, 7e7 by 43%; see
/// CHANGELOG.md). Elsewhere the plain pipelines draw, with a seventh of the vertex work.
fn clips_volumes(eye: glam::Vec3, near: f32, occluders: &[Occluder<'_>]) -> bool {
    occluders.iter().any(|o| {
        let (lo, hi) = o.world_bounds();
        let distance = eye.clamp(lo, hi).distance(eye).max(near);
        let reach = (eye - lo).abs().max((eye - hi).abs()).max_element();
        reach > RASTER_SAFE_REACH * distance || reach.is_nan()
    })
}

/// Volume vertices: 6 per extruded edge, 3 + 3 per triangle (front and back cap).
fn volume_capacity(occluders: &[Occluder<'_>]) -> u64 {
    occluders
        .iter()
        .map(|o| 6 * u64::from(o.mesh.edge_count) + 6 * u64::from(o.mesh.triangle_count))
        .sum::<u64>()
        .max(6)
}

/// Checks a crossing-list request for a `width × height` frame; returns the entries per pixel
/// that fit the device's bindings.
fn crossings_per_pixel(
    device: &wgpu::Device,
    request: &CrossingsRequest<'_>,
    (width, height): (u32, u32),
) -> Result<u32> {
    if !(1..=MAX_CROSSINGS_PER_PIXEL).contains(&request.per_pixel) {
        return Err(Error::InvalidSetting {
            field: "crossings per pixel",
            problem: format!(
                "must be in 1..={MAX_CROSSINGS_PER_PIXEL}, got {}",
                request.per_pixel
            ),
        });
    }
    check_depth_texture("scene_depth", request.scene_depth)?;
    let pixels = u64::from(width) * u64::from(height);
    let limits = device.limits();
    let max_binding = limits
        .max_storage_buffer_binding_size
        .min(limits.max_buffer_size);
    // The heads (16 bytes a pixel) must fit whole, like every buffer beyond a device limit
    // (`DeviceLimitExceeded`); then at least 4 entries of 4 bytes a pixel fit too.
    let heads_size = 16 * pixels;
    crate::gpu::check_buffer_size(device, "crossing lists", heads_size)?;
    // Fewer entries rather than a buffer the device cannot bind: overflowing pixels are
    // still correct, only marched.
    let per_pixel = u64::from(request.per_pixel).min(max_binding / (4 * pixels)) as u32;
    Ok(per_pixel)
}

impl ExtentsNode {
    /// (Re)creates the targets when the size changed and the buffers when they are too small
    /// for `capacity` volume vertices of `occluders` occluders.
    fn allocate(
        &mut self,
        device: &wgpu::Device,
        (width, height): (u32, u32),
        capacity: u64,
        occluders: usize,
    ) -> Result<()> {
        if !self
            .targets
            .as_ref()
            .is_some_and(|t| t[0].width() == width && t[0].height() == height)
        {
            let make = |label| {
                crate::gpu::texture_2d(
                    device,
                    label,
                    (width, height, 1),
                    wgpu::TextureFormat::Depth32Float,
                    // COPY_SRC so tests and debug views can read the extents back.
                    wgpu::TextureUsages::RENDER_ATTACHMENT
                        | wgpu::TextureUsages::TEXTURE_BINDING
                        | wgpu::TextureUsages::COPY_SRC,
                )
            };
            self.targets = Some([
                make("volshadow extents front"),
                make("volshadow extents back near"),
                make("volshadow extents back far"),
            ]);
        }

        let vertex_bytes = VOLUME_VERTEX_BYTES;
        crate::gpu::check_buffer_size(device, "shadow volumes", capacity * vertex_bytes)?;
        if self
            .volume
            .as_ref()
            .is_none_or(|b| b.size() < capacity * vertex_bytes)
        {
            let volume = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("volshadow shadow volumes"),
                size: capacity * vertex_bytes,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::VERTEX,
                mapped_at_creation: false,
            });
            self.clip_group = Some(bind_group(
                device,
                "volshadow extents clipped volume",
                &self.pipelines.clip_layout,
                [volume.as_entire_binding()],
            ));
            self.volume = Some(volume);
        }
        let needed = (occluders.max(1) as u64) * SLOT;
        crate::gpu::check_buffer_allocation(device, "occluder transforms", needed)?;
        if self
            .extrude_buffer
            .as_ref()
            .is_none_or(|b| b.size() < needed)
        {
            self.extrude_buffer = Some(device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("volshadow extrude params"),
                size: needed,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }));
        }
        Ok(())
    }

    /// Writes the extents' view (the camera's, with reversed infinite depth from a near plane
    /// scaled to the scene); returns its clip-from-world matrix.
    fn upload_view(
        &mut self,
        queue: &wgpu::Queue,
        camera: &Camera,
        light: &Light,
        occluders: &[Occluder<'_>],
    ) -> Mat4 {
        // The camera's projection with its depth row replaced: depth = near / view depth
        // (reversed Z, infinite), keeping x and y (and any jitter or asymmetry) as they are.
        let eye_light = match light.position() {
            Some(p) => p.distance(camera.eye()),
            // A directional light: the scene's size seen from the eye instead.
            None => occluders
                .iter()
                .map(|o| {
                    let (lo, hi) = o.world_bounds();
                    (camera.eye() - 0.5 * (lo + hi)).length() + 0.5 * (hi - lo).length()
                })
                .fold(0.0, f32::max),
        }
        .max(1e-20);
        // Never beyond a hundredth of the way to the nearest occluder the eye is outside of:
        // scaled by the light's distance or the scene's size alone, a distant light or a
        // ground 1e5 wide put it metres from the eye, and it cut the volumes of an occluder
        // there (a cube 5 units away over such a ground lost its shadow, and the fog near the
        // ground went black). An occluder whose bounds hold the eye gives no bound.
        let eye = camera.eye();
        let nearest = occluders
            .iter()
            .map(|o| {
                let (lo, hi) = o.world_bounds();
                eye.clamp(lo, hi).distance(eye)
            })
            .filter(|d| *d > 0.0)
            .fold(f32::INFINITY, f32::min);
        self.near = (EXTENTS_NEAR * eye_light).min(NEAREST_SHARE * nearest);
        let mut proj = camera.projection();
        let w_row = proj.row(3);
        let k = -w_row.z; // clip w = −k z_view
        proj.x_axis.z = 0.0;
        proj.y_axis.z = 0.0;
        proj.z_axis.z = 0.0;
        proj.w_axis.z = self.near * k;
        let clip_from_world: Mat4 = proj * camera.view();
        queue.write_buffer(&self.view_buffer, 0, bytemuck::bytes_of(&clip_from_world));
        clip_from_world
    }

    /// Writes each occluder's extrusion parameters and binds its mesh.
    fn bind_occluders(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        light: &Light,
        occluders: &[Occluder<'_>],
        capacity: u64,
    ) {
        let extrude_buffer = self.extrude_buffer.as_ref().expect("created above");
        let volume = self.volume.as_ref().expect("created above");
        self.jobs.clear();
        for (i, o) in occluders.iter().enumerate() {
            let uniform = ExtrudeUniform {
                world_from_object: o.transform.to_cols_array(),
                light: LightUniform::new(light),
                mirror: o.transform.determinant().signum(),
                edges: o.mesh.edge_count,
                triangles: o.mesh.triangle_count,
                closed: u32::from(o.mesh.is_closed()),
                capacity: capacity as u32,
            };
            queue.write_buffer(
                extrude_buffer,
                i as u64 * SLOT,
                bytemuck::bytes_of(&uniform),
            );
            let bind_group = bind_group(
                device,
                "volshadow extrude",
                &self.pipelines.extrude_layout,
                [
                    wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: extrude_buffer,
                        offset: i as u64 * SLOT,
                        size: wgpu::BufferSize::new(wgsl_size::<ExtrudeUniform>()),
                    }),
                    o.mesh.positions.as_entire_binding(),
                    o.mesh.indices.as_entire_binding(),
                    o.mesh.edges.as_entire_binding(),
                    volume.as_entire_binding(),
                    self.args.as_entire_binding(),
                ],
            );
            self.jobs.push(Job {
                bind_group,
                invocations: o.mesh.edge_count + o.mesh.triangle_count,
            });
        }
    }
}

impl Encode for ExtentsNode {
    /// Records the extrusion and the three depth passes (or the crossing lists).
    ///
    /// # Errors
    ///
    /// [`Error::NotPrepared`] before the first successful `prepare`, recording nothing.
    fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        mut timer: Option<&mut GpuTimer>,
    ) -> Result<()> {
        let (Some(targets), Some(volume)) = (&self.targets, &self.volume) else {
            return Err(Error::NotPrepared {
                reason: "ExtentsNode::prepare has not succeeded yet",
            });
        };
        {
            let mut pass = crate::gpu::passes::begin_compute(
                encoder,
                &wgpu::ComputePassDescriptor {
                    label: Some("volshadow extrude reset"),
                    timestamp_writes: timer
                        .as_deref_mut()
                        .and_then(|t| t.compute_pass(Pass::Extents)),
                },
            );
            if let Some(first) = self.jobs.first() {
                pass.set_pipeline(&self.pipelines.reset);
                pass.set_bind_group(0, &first.bind_group, &[]);
                pass.dispatch_workgroups(1, 1, 1);
            }
        }
        if !self.jobs.is_empty() {
            let mut pass = crate::gpu::passes::begin_compute(
                encoder,
                &wgpu::ComputePassDescriptor {
                    label: Some("volshadow extrude"),
                    timestamp_writes: timer
                        .as_deref_mut()
                        .and_then(|t| t.compute_pass(Pass::Extents)),
                },
            );
            pass.set_pipeline(&self.pipelines.extrude);
            for job in &self.jobs {
                pass.set_bind_group(0, &job.bind_group, &[]);
                pass.dispatch_workgroups(job.invocations.div_ceil(64), 1, 1);
            }
        }
        let raster_clipped = self.clipping && !self.jobs.is_empty();
        if raster_clipped && !self.crossings_on {
            encoder.copy_buffer_to_buffer(&self.args, 0, &self.clipped_args, 0, 4);
        }
        if self.crossings_on {
            let Some(lists) = &self.crossings else {
                return Ok(());
            };
            if let (CrossingsBuild::Compute, Some(bins)) = (lists.build, &lists.bins) {
                let Some((group, ..)) = &bins.bound else {
                    return Ok(());
                };
                if self.jobs.is_empty() {
                    // No volume: nothing crosses.
                    encoder.clear_buffer(&lists.heads, 0, None);
                    return Ok(());
                }
                encoder.clear_buffer(&bins.tiles, 0, None);
                let mut pass = crate::gpu::passes::begin_compute(
                    encoder,
                    &wgpu::ComputePassDescriptor {
                        label: Some("volshadow crossings"),
                        timestamp_writes: timer
                            .as_deref_mut()
                            .and_then(|t| t.compute_pass(Pass::Extents)),
                    },
                );
                let [setup, count, scan, fill, build] = &self.pipelines.bin;
                let groups = bins.face_capacity.div_ceil(64);
                let gx = groups.min(65535);
                pass.set_bind_group(0, group, &[]);
                pass.set_pipeline(setup);
                pass.dispatch_workgroups(gx, groups.div_ceil(gx), 1);
                pass.set_pipeline(count);
                pass.dispatch_workgroups(BIN_GROUPS, 1, 1);
                pass.set_pipeline(scan);
                pass.dispatch_workgroups(1, 1, 1);
                pass.set_pipeline(fill);
                pass.dispatch_workgroups(BIN_GROUPS, 1, 1);
                pass.set_pipeline(build);
                pass.dispatch_workgroups(bins.tile_count.0, bins.tile_count.1, 1);
                return Ok(());
            }
            encoder.clear_buffer(&lists.heads, 0, None);
            // The depth target is only there because a render pass needs an attachment:
            // the pipeline neither tests nor writes it.
            let view = targets[0].create_view(&Default::default());
            let timestamp_writes = timer
                .as_deref_mut()
                .and_then(|t| t.render_pass(Pass::Extents));
            let mut pass = crate::gpu::passes::begin_render(
                encoder,
                &wgpu::RenderPassDescriptor {
                    label: Some("volshadow extents crossings"),
                    color_attachments: &[],
                    depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                        view: &view,
                        depth_ops: Some(wgpu::Operations {
                            load: wgpu::LoadOp::Clear(0.0),
                            store: wgpu::StoreOp::Discard,
                        }),
                        stencil_ops: None,
                    }),
                    timestamp_writes,
                    occlusion_query_set: None,
                    multiview_mask: None,
                },
            );
            if !self.jobs.is_empty() {
                pass.set_pipeline(&self.pipelines.crossings);
                pass.set_bind_group(0, &lists.bind_group, &[]);
                pass.set_vertex_buffer(0, volume.slice(..));
                pass.draw_indirect(&self.args, 0);
            }
            return Ok(());
        }
        for (((target, pipeline), clipped), clear) in targets
            .iter()
            .zip(&self.pipelines.depths)
            .zip(&self.pipelines.depths_clipped)
            .zip([0.0, 0.0, 1.0])
        {
            let view = target.create_view(&Default::default());
            let timestamp_writes = timer
                .as_deref_mut()
                .and_then(|t| t.render_pass(Pass::Extents));
            let mut pass = crate::gpu::passes::begin_render(
                encoder,
                &wgpu::RenderPassDescriptor {
                    label: Some("volshadow extents"),
                    color_attachments: &[],
                    depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                        view: &view,
                        depth_ops: Some(wgpu::Operations {
                            load: wgpu::LoadOp::Clear(clear),
                            store: wgpu::StoreOp::Store,
                        }),
                        stencil_ops: None,
                    }),
                    timestamp_writes,
                    occlusion_query_set: None,
                    multiview_mask: None,
                },
            );
            if let (true, Some(clip)) = (raster_clipped, &self.clip_group) {
                pass.set_pipeline(clipped);
                pass.set_bind_group(0, &self.raster_bind_group, &[]);
                pass.set_bind_group(1, clip, &[]);
                pass.draw_indirect(&self.clipped_args, 0);
            } else if !self.jobs.is_empty() {
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, &self.raster_bind_group, &[]);
                pass.set_vertex_buffer(0, volume.slice(..));
                pass.draw_indirect(&self.args, 0);
            }
        }
        Ok(())
    }
}

#[cfg(test)]
#[test]
fn params_layouts_match_the_wgsl() {
    use crate::nodes::layout::{assert_same, rust_layout};
    let extents = include_str!("../../shaders/extents.wgsl");
    let extrude = rust_layout!(ExtrudeUniform {
        world_from_object,
        light,
        mirror,
        edges,
        triangles,
        closed,
        capacity,
    });
    assert_same(extrude, extents, "Extrude");
    assert_same(
        rust_layout!(CrossingUniform {
            size,
            entries,
            near
        }),
        extents,
        "CrossingParams",
    );
    let bin = rust_layout!(BinUniform {
        view_from_clip,
        world_from_view,
        clip_from_world,
        view_size,
        size,
        tiles,
        far_depth,
        entries,
        near,
        bin_capacity,
        face_capacity,
        affine,
    });
    assert_same(bin, include_str!("../../shaders/crossings.wgsl"), "Params");
}
