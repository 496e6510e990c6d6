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
use crate::gpu::pipeline::bind_group;
use crate::gpu::{check_target_size, wgsl_size, GpuTimer, Occluder, UniformBuffer};
use crate::light::LightUniform;
use crate::nodes::groups::uniforms::ViewUniform;
use crate::nodes::Cache;
use crate::nodes::{Encode, Node};
use crate::pass::Pass;
use crate::scene::{Camera, Light};

mod crossings;
mod pipelines;

pub use crossings::{Crossings, CrossingsBuild, CrossingsRequest, MAX_CROSSINGS_PER_PIXEL};
pub(crate) use pipelines::Pipelines;

use crossings::{crossings_per_pixel, CrossingLists};
use pipelines::{ExtrudeUniform, FAN, VOLUME_VERTEX_BYTES};

/// are clipped ([`clips_volumes`]).
const RASTER_SAFE_REACH: f32 = 65536.0;

/// The fan triangles (instances) a clipped volume triangle is drawn as (at most nine vertices
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

/// Whether this frame's volumes go through `vs_volume_clipped` (see `shaders/passes/extents.wgsl`),
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
        self.encode_extrusion(encoder, timer.as_deref_mut());
        let raster_clipped = self.clipping && !self.jobs.is_empty();
        if raster_clipped && !self.crossings_on {
            encoder.copy_buffer_to_buffer(&self.args, 0, &self.clipped_args, 0, 4);
        }
        if self.crossings_on {
            if let Some(lists) = &self.crossings {
                self.encode_crossings(encoder, timer, lists, &targets[0], volume);
            }
            return Ok(());
        }
        self.encode_depths(encoder, timer, targets, volume, raster_clipped);
        Ok(())
    }
}

impl ExtentsNode {
    /// Records the extrusion: the volume's draw arguments reset, then each occluder's
    /// silhouette extruded into the volume.
    fn encode_extrusion(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        mut timer: Option<&mut GpuTimer>,
    ) {
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
                    timestamp_writes: timer.and_then(|t| t.compute_pass(Pass::Extents)),
                },
            );
            pass.set_pipeline(&self.pipelines.extrude);
            for job in &self.jobs {
                pass.set_bind_group(0, &job.bind_group, &[]);
                pass.dispatch_workgroups(job.invocations.div_ceil(64), 1, 1);
            }
        }
    }

    /// Records the three depth passes over `volume` into `targets` (front, back near, back
    /// far), through `vs_volume_clipped` where `raster_clipped`.
    fn encode_depths(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        mut timer: Option<&mut GpuTimer>,
        targets: &[wgpu::Texture; 3],
        volume: &wgpu::Buffer,
        raster_clipped: bool,
    ) {
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
    }
}
