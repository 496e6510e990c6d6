//! The composite node: `Ls · exp(−σt · ds) + L_sctr` into the caller's target.
//!
//! # Inputs (all the same size, single-sampled, usage `TEXTURE_BINDING`)
//! * `scene_color`: the caller's shaded colour Ls, linear radiance, any format with a float
//!   sample type (`Rgba16Float`, `Rgba32Float`, `Rgba8Unorm`, …). Alpha is passed through.
//! * `scene_depth`: the caller's depth buffer, any depth format; far depth is sky (see
//!   [`Camera::far_depth`]), which an attenuating medium hides completely.
//! * `inscatter`: [`MarchNode::output`](crate::nodes::MarchNode::output).
//!
//! # Output
//! A view of a texture with usage `RENDER_ATTACHMENT`, of the format given to
//! [`CompositeNode::new`] (or its sRGB twin), the same size, and not one of the inputs. Every
//! pixel is written (linear radiance; tone mapping is the caller's).

use crate::error::{Error, Result};
use crate::gpu::uniforms::{CompositeUniform, ViewUniform};
use crate::gpu::{
    check_depth_texture, check_float_texture, check_size, depth_view, Cache, UniformBuffer,
};
use crate::scene::{Camera, Medium};

/// What the composite reads in a frame.
#[derive(Debug, Clone, Copy)]
pub struct CompositeInputs<'a> {
    /// The camera the frame was rendered with.
    pub camera: &'a Camera,
    /// The medium (its σt attenuates the scene colour).
    pub medium: &'a Medium,
    /// The caller's shaded colour.
    pub scene_color: &'a wgpu::Texture,
    /// The caller's depth buffer.
    pub scene_depth: &'a wgpu::Texture,
    /// The in-scattered radiance from the march.
    pub inscatter: &'a wgpu::Texture,
}

/// Writes the attenuated scene plus in-scattered light into the caller's target.
pub struct CompositeNode {
    format: wgpu::TextureFormat,
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    uniform: UniformBuffer<CompositeUniform>,
    view: UniformBuffer<ViewUniform>,
    bound: Option<Bound>,
}

struct Bound {
    color: wgpu::Texture,
    depth: wgpu::Texture,
    inscatter: wgpu::Texture,
    bind_group: wgpu::BindGroup,
}

impl CompositeNode {
    /// A composite writing `output_format`, which must be a colour format usable as a render
    /// attachment on every device (e.g. `Rgba16Float`, `Rgba8UnormSrgb`).
    pub fn new(
        device: &wgpu::Device,
        cache: &Cache,
        output_format: wgpu::TextureFormat,
    ) -> Result<Self> {
        let features = output_format.guaranteed_format_features(device.features());
        let renderable = features
            .allowed_usages
            .contains(wgpu::TextureUsages::RENDER_ATTACHMENT);
        if output_format.is_depth_stencil_format() || !renderable {
            return Err(Error::InvalidTexture {
                field: "output_format",
                problem: format!("{output_format:?} is not a renderable colour format"),
            });
        }
        Ok(Self {
            format: output_format,
            pipeline: cache.composite_pipeline(device, output_format),
            layout: cache.composite_layout.clone(),
            uniform: UniformBuffer::new(device, "volshadow composite"),
            view: UniformBuffer::new(device, "volshadow composite view"),
            bound: None,
        })
    }

    /// Validates the inputs and uploads what changed.
    pub fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        inputs: &CompositeInputs<'_>,
    ) -> Result<()> {
        check_float_texture("scene_color", inputs.scene_color)?;
        check_depth_texture("scene_depth", inputs.scene_depth)?;
        check_float_texture("inscatter", inputs.inscatter)?;
        let (width, height) = (inputs.scene_color.width(), inputs.scene_color.height());
        check_size("scene_depth", inputs.scene_depth, width, height)?;
        check_size("inscatter", inputs.inscatter, width, height)?;

        let same = |b: &Bound| {
            b.color == *inputs.scene_color
                && b.depth == *inputs.scene_depth
                && b.inscatter == *inputs.inscatter
        };
        if !self.bound.as_ref().is_some_and(same) {
            let color = inputs.scene_color.create_view(&Default::default());
            let depth = depth_view(inputs.scene_depth);
            let inscatter = inputs.inscatter.create_view(&Default::default());
            let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("volshadow composite"),
                layout: &self.layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: self.uniform.binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: self.view.binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: wgpu::BindingResource::TextureView(&color),
                    },
                    wgpu::BindGroupEntry {
                        binding: 3,
                        resource: wgpu::BindingResource::TextureView(&depth),
                    },
                    wgpu::BindGroupEntry {
                        binding: 4,
                        resource: wgpu::BindingResource::TextureView(&inscatter),
                    },
                ],
            });
            self.bound = Some(Bound {
                color: inputs.scene_color.clone(),
                depth: inputs.scene_depth.clone(),
                inscatter: inputs.inscatter.clone(),
                bind_group,
            });
        }
        self.uniform.write(
            queue,
            CompositeUniform {
                sigma_t: inputs.medium.sigma_t().extend(0.0).to_array(),
            },
        );
        self.view
            .write(queue, ViewUniform::new(inputs.camera, width, height));
        Ok(())
    }

    /// Records the composite into `output` (see the module docs for what it must be).
    /// Errors, recording nothing, if `output` does not fit or `prepare` has not succeeded.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        output: &wgpu::TextureView,
        timer: Option<&mut crate::gpu::GpuTimer>,
    ) -> Result<()> {
        let problem = |p: String| Error::InvalidTexture {
            field: "output",
            problem: p,
        };
        let Some(bound) = &self.bound else {
            return Err(problem(
                "CompositeNode::prepare has not succeeded yet".into(),
            ));
        };
        let target = output.texture();
        if target.format().remove_srgb_suffix() != self.format.remove_srgb_suffix() {
            return Err(problem(format!(
                "format {:?}, the node was made for {:?}",
                target.format(),
                self.format
            )));
        }
        if !target
            .usage()
            .contains(wgpu::TextureUsages::RENDER_ATTACHMENT)
        {
            return Err(problem("needs TextureUsages::RENDER_ATTACHMENT".into()));
        }
        check_size("output", target, bound.color.width(), bound.color.height())?;
        if *target == bound.color || *target == bound.inscatter {
            return Err(problem("must not be one of the composite's inputs".into()));
        }
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("volshadow composite"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: output,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: timer.and_then(|t| t.render_pass("composite")),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &bound.bind_group, &[]);
        pass.draw(0..3, 0..1);
        Ok(())
    }
}
