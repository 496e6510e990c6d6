//! The shadow-volume extents node: per pixel, where along the view ray the shadow
//! volumes of the occluders begin and end.
//!
//! A compute pass finds silhouette edges and extrudes them away from the light to infinity,
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
//! With [`ExtentsInputs::crossings`] set (the exact march), one pass replaces the three: every
//! fragment of a volume face in front of the scene surface appends its view depth to a
//! bounded per-pixel list in a storage buffer (an atomic counter per pixel, written from the
//! fragment stage, which core WebGPU allows). Between two consecutive crossings nothing can
//! change visibility, so the march integrates each interval in closed form and samples the
//! shadow map only to learn on which side it is. The rasteriser finds the crossings (one
//! fragment per face and pixel, whatever the mesh), which a compute pass could only do by
//! testing every face against every pixel. The same fragments keep the nearest and farthest
//! crossing with atomics, so a pixel whose list overflowed still knows the range to march.
//!
//! # Output
//! Three `Depth32Float` textures of the pass size
//! (`RENDER_ATTACHMENT | TEXTURE_BINDING | COPY_SRC`); with crossings, the lists instead
//! ([`Crossings`]).

use glam::Mat4;

use crate::error::{Error, Result};
use crate::gpu::uniforms::ViewUniform;
use crate::gpu::{
    check_depth_texture, check_target_size, depth_view, Cache, GpuTimer, Occluder, UniformBuffer,
};
use crate::scene::{Camera, Light};

/// The near plane of the extents' projection, relative to the eye–light distance: small enough
/// that volumes are cut only right at the eye, where the start-at-zero rule covers them.
pub const EXTENTS_NEAR: f32 = 1e-4;

/// Extrude slots are 256 bytes apart (the core minimum dynamic-offset alignment).
const SLOT: u64 = 256;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct ExtrudeUniform {
    world_from_object: [f32; 16],
    light: [f32; 4],
    counts: [u32; 4],
    flags: [f32; 4],
}

#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
struct CrossingUniform {
    size: [u32; 4],
    near: [f32; 4],
}

/// Most crossings a per-pixel list can hold ([`CrossingsRequest::per_pixel`]).
pub const MAX_CROSSINGS_PER_PIXEL: u32 = 32;

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
}

/// Computes per-pixel shadow-volume extents.
pub struct ExtentsNode {
    reset_pipeline: wgpu::ComputePipeline,
    extrude_pipeline: wgpu::ComputePipeline,
    extrude_layout: wgpu::BindGroupLayout,
    front_pipeline: wgpu::RenderPipeline,
    back_near_pipeline: wgpu::RenderPipeline,
    back_far_pipeline: wgpu::RenderPipeline,
    view_buffer: wgpu::Buffer,
    raster_bind_group: wgpu::BindGroup,
    extrude_buffer: Option<wgpu::Buffer>,
    volume: Option<wgpu::Buffer>,
    args: wgpu::Buffer,
    jobs: Vec<Job>,
    targets: Option<[wgpu::Texture; 3]>,
    near: f32,
    crossings_pipeline: wgpu::RenderPipeline,
    crossings_layout: wgpu::BindGroupLayout,
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
    pub fn new(device: &wgpu::Device, cache: &Cache) -> Self {
        let view_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("volshadow extents view"),
            size: 64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let raster_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("volshadow extents raster"),
            layout: &cache.extents_raster_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: view_buffer.as_entire_binding(),
            }],
        });
        Self {
            reset_pipeline: cache.extents_reset_pipeline.clone(),
            extrude_pipeline: cache.extents_extrude_pipeline.clone(),
            extrude_layout: cache.extents_extrude_layout.clone(),
            front_pipeline: cache.extents_front_pipeline.clone(),
            back_near_pipeline: cache.extents_back_near_pipeline.clone(),
            back_far_pipeline: cache.extents_back_far_pipeline.clone(),
            view_buffer,
            raster_bind_group,
            extrude_buffer: None,
            volume: None,
            args: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("volshadow extents draw args"),
                size: 16,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::INDIRECT,
                mapped_at_creation: false,
            }),
            jobs: Vec::new(),
            targets: None,
            near: 0.0,
            crossings_pipeline: cache.extents_crossings_pipeline.clone(),
            crossings_layout: cache.extents_crossings_layout.clone(),
            crossings: None,
            crossings_on: false,
        }
    }

    /// Uploads the occluders' transforms, the light and the camera, and (re)creates the targets
    /// when `width × height` changed.
    ///
    /// # Errors
    ///
    /// [`Error::InvalidSize`](crate::Error::InvalidSize) for a size beyond the device's
    /// limits, and [`Error::NonFinite`](crate::Error::NonFinite) or
    /// [`Error::SingularMatrix`](crate::Error::SingularMatrix) for an occluder's transform.
    pub fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        inputs: &ExtentsInputs<'_>,
    ) -> Result<()> {
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
        }
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

        // The camera's projection with its depth row replaced: depth = near / view depth
        // (reversed Z, infinite), keeping x and y (and any jitter or asymmetry) as they are.
        let eye_light = light.position().distance(camera.eye()).max(1e-20);
        self.near = EXTENTS_NEAR * eye_light;
        let mut proj = camera.projection();
        let w_row = proj.row(3);
        let k = -w_row.z; // clip w = −k z_view
        proj.x_axis.z = 0.0;
        proj.y_axis.z = 0.0;
        proj.z_axis.z = 0.0;
        proj.w_axis.z = self.near * k;
        let clip_from_world: Mat4 = proj * camera.view();
        queue.write_buffer(&self.view_buffer, 0, bytemuck::bytes_of(&clip_from_world));
        self.crossings_on = crossings.is_some();
        if let Some(request) = crossings {
            self.prepare_crossings(device, queue, camera, &request, (width, height))?;
        }

        // Volume vertices: 6 per extruded edge, 3 + 3 per triangle (front and back cap).
        let capacity: u64 = occluders
            .iter()
            .map(|o| 6 * u64::from(o.mesh.edge_count) + 6 * u64::from(o.mesh.triangle_count))
            .sum::<u64>()
            .max(6);
        let vertex_bytes = 32;
        crate::gpu::check_buffer_size(device, "shadow volumes", capacity * vertex_bytes)?;
        if self
            .volume
            .as_ref()
            .is_none_or(|b| b.size() < capacity * vertex_bytes)
        {
            self.volume = Some(device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("volshadow shadow volumes"),
                size: capacity * vertex_bytes,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::VERTEX,
                mapped_at_creation: false,
            }));
        }
        let needed = (occluders.len().max(1) as u64) * SLOT;
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
        let extrude_buffer = self.extrude_buffer.as_ref().expect("created above");
        let volume = self.volume.as_ref().expect("created above");
        self.jobs.clear();
        for (i, o) in occluders.iter().enumerate() {
            let uniform = ExtrudeUniform {
                world_from_object: o.transform.to_cols_array(),
                light: light.position().extend(1.0).to_array(),
                counts: [
                    o.mesh.edge_count,
                    o.mesh.triangle_count,
                    u32::from(o.mesh.is_closed()),
                    capacity as u32,
                ],
                flags: [o.transform.determinant().signum(), 0.0, 0.0, 0.0],
            };
            queue.write_buffer(
                extrude_buffer,
                i as u64 * SLOT,
                bytemuck::bytes_of(&uniform),
            );
            let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("volshadow extrude"),
                layout: &self.extrude_layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                            buffer: extrude_buffer,
                            offset: i as u64 * SLOT,
                            size: wgpu::BufferSize::new(
                                std::mem::size_of::<ExtrudeUniform>() as u64
                            ),
                        }),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: o.mesh.positions.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: o.mesh.indices.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 3,
                        resource: o.mesh.edges.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 4,
                        resource: volume.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 5,
                        resource: self.args.as_entire_binding(),
                    },
                ],
            });
            self.jobs.push(Job {
                bind_group,
                invocations: o.mesh.edge_count + o.mesh.triangle_count,
            });
        }
        Ok(())
    }

    /// Records the extrusion and the three depth passes.
    pub fn encode(&self, encoder: &mut wgpu::CommandEncoder, mut timer: Option<&mut GpuTimer>) {
        let (Some(targets), Some(volume)) = (&self.targets, &self.volume) else {
            return;
        };
        {
            let timestamp_writes = timer.as_deref_mut().and_then(|t| t.compute_pass("extrude"));
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("volshadow extrude reset"),
                timestamp_writes,
            });
            if let Some(first) = self.jobs.first() {
                pass.set_pipeline(&self.reset_pipeline);
                pass.set_bind_group(0, &first.bind_group, &[]);
                pass.dispatch_workgroups(1, 1, 1);
            }
        }
        if !self.jobs.is_empty() {
            let timestamp_writes = timer.as_deref_mut().and_then(|t| t.compute_pass("extrude"));
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("volshadow extrude"),
                timestamp_writes,
            });
            pass.set_pipeline(&self.extrude_pipeline);
            for job in &self.jobs {
                pass.set_bind_group(0, &job.bind_group, &[]);
                pass.dispatch_workgroups(job.invocations.div_ceil(64), 1, 1);
            }
        }
        if self.crossings_on {
            let Some(lists) = &self.crossings else {
                return;
            };
            encoder.clear_buffer(&lists.heads, 0, None);
            // The depth target is only there because a render pass needs an attachment:
            // the pipeline neither tests nor writes it.
            let view = targets[0].create_view(&Default::default());
            let timestamp_writes = timer.as_deref_mut().and_then(|t| t.render_pass("extents"));
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
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
            });
            if !self.jobs.is_empty() {
                pass.set_pipeline(&self.crossings_pipeline);
                pass.set_bind_group(0, &lists.bind_group, &[]);
                pass.set_vertex_buffer(0, volume.slice(..));
                pass.draw_indirect(&self.args, 0);
            }
            return;
        }
        let passes = [
            (&targets[0], &self.front_pipeline, 0.0),
            (&targets[1], &self.back_near_pipeline, 0.0),
            (&targets[2], &self.back_far_pipeline, 1.0),
        ];
        for (target, pipeline, clear) in passes {
            let view = target.create_view(&Default::default());
            let timestamp_writes = timer.as_deref_mut().and_then(|t| t.render_pass("extents"));
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
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
            });
            if !self.jobs.is_empty() {
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, &self.raster_bind_group, &[]);
                pass.set_vertex_buffer(0, volume.slice(..));
                pass.draw_indirect(&self.args, 0);
            }
        }
    }

    /// The extents for the march; `None` before the first `prepare`.
    pub fn extents(&self) -> Option<crate::nodes::Extents<'_>> {
        let crossings = if self.crossings_on {
            let lists = self.crossings.as_ref()?;
            Some(Crossings {
                heads: &lists.heads,
                list: &lists.list,
                per_pixel: lists.per_pixel,
            })
        } else {
            None
        };
        Some(crate::nodes::Extents {
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
        camera: &Camera,
        request: &CrossingsRequest<'_>,
        (width, height): (u32, u32),
    ) -> Result<()> {
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
        // Fewer entries rather than a buffer the device cannot bind: overflowing pixels are
        // still correct, only marched.
        let per_pixel = u64::from(request.per_pixel).min(max_binding / (4 * pixels));
        let heads_size = 16 * pixels;
        if per_pixel == 0 || heads_size > max_binding {
            return Err(Error::InvalidSetting {
                field: "extents size",
                problem: format!(
                    "crossing lists for {width}×{height} pixels need more than the device's \
                     storage buffer binding size ({max_binding} bytes)"
                ),
            });
        }
        let per_pixel = per_pixel as u32;
        let reuse = self
            .crossings
            .as_ref()
            .is_some_and(|c| c.size == (width, height) && c.per_pixel == per_pixel);
        let (mut view, mut params, heads, list, bound) = match self.crossings.take() {
            Some(c) if reuse => {
                let bound = (c.depth == *request.scene_depth).then_some(c.bind_group);
                (c.view, c.params, c.heads, c.list, bound)
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
                let (view, params) = match old {
                    Some(c) => (c.view, c.params),
                    None => (
                        UniformBuffer::new(device, "volshadow crossings view"),
                        UniformBuffer::new(device, "volshadow crossings params"),
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
                )
            }
        };
        view.write(queue, ViewUniform::new(camera, width, height));
        params.write(
            queue,
            CrossingUniform {
                size: [width, height, per_pixel, 0],
                near: [self.near, 0.0, 0.0, 0.0],
            },
        );
        let bind_group = bound.unwrap_or_else(|| {
            let depth_view = depth_view(request.scene_depth);
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("volshadow extents crossings"),
                layout: &self.crossings_layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: self.view_buffer.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: view.binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: params.binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 3,
                        resource: wgpu::BindingResource::TextureView(&depth_view),
                    },
                    wgpu::BindGroupEntry {
                        binding: 4,
                        resource: heads.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 5,
                        resource: list.as_entire_binding(),
                    },
                ],
            })
        });
        self.crossings = Some(CrossingLists {
            view,
            params,
            heads,
            list,
            per_pixel,
            size: (width, height),
            depth: request.scene_depth.clone(),
            bind_group,
        });
        Ok(())
    }
}
