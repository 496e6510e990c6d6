//! The march node: in-scattered radiance `L_sctr` per pixel.
//!
//! Every ray is integrated from the eye to the scene depth (or to infinity for sky pixels)
//! as `I0 · F′(ds)`, read from the [`AirlightTableNode`]'s table with the singular prefactor
//! applied per pixel, clamped by the pixel's footprint when looking into the light (DESIGN §2).
//!
//! # Inputs
//! * `scene_depth`: the caller's depth buffer, any depth format (`Depth16Unorm`, `Depth24Plus`,
//!   `Depth24PlusStencil8`, `Depth32Float`, …), single-sampled, usage `TEXTURE_BINDING`; its
//!   size is the size of the pass. Depth values equal to the camera's far depth
//!   ([`Camera::far_depth`]) are sky.
//! * the table from [`AirlightTableNode`], prepared for the same eye, light and medium.
//!
//! # Output
//! [`MarchNode::output`]: `Rgba32Float`, the size of `scene_depth`, usages
//! `STORAGE_BINDING | TEXTURE_BINDING | COPY_SRC`. rgb = in-scattered radiance, a = eye
//! distance of the pixel's surface (−1 for sky).

use crate::error::Result;
use crate::gpu::uniforms::{AirlightUniform, ViewUniform};
use crate::gpu::{check_depth_texture, check_target_size, depth_view, Cache, UniformBuffer};
use crate::nodes::AirlightTableNode;
use crate::scene::{Camera, Medium, PointLight};

/// What the march reads in a frame.
#[derive(Debug, Clone, Copy)]
pub struct MarchInputs<'a> {
    /// The camera the depth buffer was rendered with.
    pub camera: &'a Camera,
    /// The light.
    pub light: &'a PointLight,
    /// The medium.
    pub medium: &'a Medium,
    /// The caller's depth buffer (see the module docs).
    pub scene_depth: &'a wgpu::Texture,
}

/// Computes in-scattered radiance per pixel into its own `Rgba32Float` texture.
pub struct MarchNode {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    airlight: UniformBuffer<AirlightUniform>,
    view: UniformBuffer<ViewUniform>,
    output: Option<wgpu::Texture>,
    bound: Option<Bound>,
}

/// The bind group and the textures it was made for, so it is rebuilt only when they change.
struct Bound {
    depth: wgpu::Texture,
    table: wgpu::Texture,
    output: wgpu::Texture,
    bind_group: wgpu::BindGroup,
}

impl MarchNode {
    /// Creates the node; textures are allocated by the first [`prepare`](Self::prepare).
    pub fn new(device: &wgpu::Device, cache: &Cache) -> Self {
        Self {
            pipeline: cache.march_pipeline.clone(),
            layout: cache.march_layout.clone(),
            airlight: UniformBuffer::new(device, "volshadow march airlight"),
            view: UniformBuffer::new(device, "volshadow march view"),
            output: None,
            bound: None,
        }
    }

    /// Validates the inputs, (re)creates the output when the size changed, and uploads the
    /// uniforms that changed.
    pub fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        table: &AirlightTableNode,
        inputs: &MarchInputs<'_>,
    ) -> Result<()> {
        check_depth_texture("scene_depth", inputs.scene_depth)?;
        let (width, height) = (inputs.scene_depth.width(), inputs.scene_depth.height());
        check_target_size("scene_depth size", device, width, height)?;

        let output = match &self.output {
            Some(t) if t.width() == width && t.height() == height => t.clone(),
            _ => {
                let t = device.create_texture(&wgpu::TextureDescriptor {
                    label: Some("volshadow in-scatter"),
                    size: wgpu::Extent3d {
                        width,
                        height,
                        depth_or_array_layers: 1,
                    },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D2,
                    format: wgpu::TextureFormat::Rgba32Float,
                    usage: wgpu::TextureUsages::STORAGE_BINDING
                        | wgpu::TextureUsages::TEXTURE_BINDING
                        | wgpu::TextureUsages::COPY_SRC,
                    view_formats: &[],
                });
                self.output = Some(t.clone());
                t
            }
        };

        let same = |b: &Bound| {
            b.depth == *inputs.scene_depth && b.table == *table.texture() && b.output == output
        };
        if !self.bound.as_ref().is_some_and(same) {
            let depth = depth_view(inputs.scene_depth);
            let table_view = table.texture().create_view(&Default::default());
            let output_view = output.create_view(&Default::default());
            let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("volshadow march"),
                layout: &self.layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: self.airlight.binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: self.view.binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: wgpu::BindingResource::TextureView(&table_view),
                    },
                    wgpu::BindGroupEntry {
                        binding: 3,
                        resource: wgpu::BindingResource::TextureView(&depth),
                    },
                    wgpu::BindGroupEntry {
                        binding: 4,
                        resource: wgpu::BindingResource::TextureView(&output_view),
                    },
                ],
            });
            self.bound = Some(Bound {
                depth: inputs.scene_depth.clone(),
                table: table.texture().clone(),
                output,
                bind_group,
            });
        }

        let camera = inputs.camera;
        self.airlight.write(
            queue,
            AirlightUniform::new(
                camera.eye(),
                inputs.light,
                inputs.medium,
                camera.pixel_angular_radius(height),
                table.table_dims(),
            ),
        );
        self.view
            .write(queue, ViewUniform::new(camera, width, height));
        Ok(())
    }

    /// Records the march. Records nothing before the first successful
    /// [`prepare`](Self::prepare).
    pub fn encode(&self, encoder: &mut wgpu::CommandEncoder) {
        let Some(bound) = &self.bound else { return };
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("volshadow march"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &bound.bind_group, &[]);
        pass.dispatch_workgroups(
            bound.output.width().div_ceil(8),
            bound.output.height().div_ceil(8),
            1,
        );
    }

    /// The in-scatter texture (see the module docs); `None` before the first `prepare`.
    pub fn output(&self) -> Option<&wgpu::Texture> {
        self.output.as_ref()
    }
}
