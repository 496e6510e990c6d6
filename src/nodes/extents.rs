//! The shadow-volume extents node (DESIGN §3): per pixel, where along the view ray the shadow
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
//! # Output
//! Three `Depth32Float` textures of the pass size
//! (`RENDER_ATTACHMENT | TEXTURE_BINDING | COPY_SRC`).

use glam::Mat4;

use crate::error::Result;
use crate::gpu::{check_target_size, Cache, GpuTimer, Occluder};
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
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
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

        // Volume vertices: 6 per extruded edge, 3 + 3 per triangle (front and back cap).
        let capacity: u64 = occluders
            .iter()
            .map(|o| 6 * u64::from(o.mesh.edge_count) + 6 * u64::from(o.mesh.triangle_count))
            .sum::<u64>()
            .max(6);
        let vertex_bytes = 32;
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
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
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
        Some(crate::nodes::Extents {
            textures: self.targets.as_ref()?,
            near: self.near,
        })
    }
}
