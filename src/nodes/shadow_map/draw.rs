//! The occluders' draws: each one's buffers (and clipping around the light), listed by
//! [`ShadowMapNode::upload`], and recording them into each layer's render pass.

use crate::error::Result;
use crate::gpu::pipeline::{bind_group, dispatch};
use crate::gpu::{GpuTimer, Occluder};
use crate::nodes::Encode;
use crate::pass::Pass;
use crate::scene::Light;

use super::pipelines::{slot, slot_words, Pipelines, FACE_BYTES, INSTANCE_BYTES, SLOT};
use super::ShadowMapNode;

/// An occluder reaching farther from the light than this times its distance is clipped to a
/// cube of that half-side around the light before it is drawn ([`clip_reach`]).
const CLIP_REACH: f32 = 4096.0;

/// The fan triangles (instances) a clipped triangle is drawn as: a triangle clipped by a
/// cube's six planes keeps at most nine vertices.
pub(super) const FAN: u32 = 7;

pub(super) struct Draw {
    positions: wgpu::Buffer,
    indices: wgpu::Buffer,
    pub(super) index_count: u32,
    closed: bool,
    /// For an occluder with a [`clip_reach`]: its bind group of `CLIPPED_BINDINGS`, drawn by
    /// `vs_shadow_clipped` (`index_count` vertices, [`FAN`] instances).
    pub(super) clipped: Option<wgpu::BindGroup>,
}

impl Draw {
    /// Records the draw with `pipelines`' `depth` or `back` pipeline (`back`: faces turned away
    /// from the light, an open mesh's nearest face), with the face and instance slots
    /// `offsets`.
    fn record(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        pipelines: &Pipelines,
        group: &wgpu::BindGroup,
        offsets: [u32; 2],
        back: bool,
    ) {
        let back = back && self.closed;
        if let Some(clipped) = &self.clipped {
            pass.set_pipeline(if back {
                &pipelines.back_clipped
            } else {
                &pipelines.depth_clipped
            });
            pass.set_bind_group(0, clipped, &offsets);
            pass.draw(0..self.index_count, 0..FAN);
            return;
        }
        pass.set_pipeline(if back {
            &pipelines.back
        } else {
            &pipelines.depth
        });
        pass.set_bind_group(0, group, &offsets);
        pass.set_vertex_buffer(0, self.positions.slice(..));
        pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed(0..self.index_count, 0, 0..1);
    }
}

/// The half-side of the cube around the light that `occluder`'s triangles are clipped to
/// before the rasteriser clips them (`vs_shadow_clipped`), where they need it: [`CLIP_REACH`]
/// times the distance from a point or spot light to the occluder's bounds, where the bounds
/// reach farther than that from the light (in some axis). One value for all its triangles, so
/// that two triangles sharing an edge cut it at the same points, bit for bit: each triangle's
/// own distance would give neighbours different cubes, and the points each computes on a
/// shared edge 1e7 long are off the edge by f32 steps of its far end, which opened a wedge
/// beside the light that the light leaked through. `None` for a directional light, an occluder
/// within its cube, and a light inside the bounds (its distance to them is 0; see the
/// crate's Limits).
fn clip_reach(light: &Light, occluder: &Occluder<'_>) -> Option<f32> {
    let p = light.position()?;
    let (lo, hi) = occluder.world_bounds();
    let reach = CLIP_REACH * p.clamp(lo, hi).distance(p);
    let farthest = (p - lo).abs().max((p - hi).abs()).max_element();
    (reach > 0.0 && farthest > reach).then_some(reach)
}

impl ShadowMapNode {
    /// Writes the faces' matrices and the occluders' transforms, and lists the draws.
    pub(super) fn upload(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        light: &Light,
        occluders: &[Occluder<'_>],
    ) {
        let centre = light.position().unwrap_or_default().extend(1.0);
        for (i, face) in self.faces.iter().enumerate() {
            let words = slot_words((*face, centre));
            queue.write_buffer(
                &self.face_buffer,
                i as u64 * SLOT,
                bytemuck::cast_slice(&words),
            );
        }
        let instances = self.instance_buffer.as_ref().expect("just created");
        self.draws.clear();
        for (i, o) in occluders.iter().enumerate() {
            let mut words = [0f32; 20];
            words[..16].copy_from_slice(&o.transform.to_cols_array());
            let reach = clip_reach(light, o);
            words[16] = reach.unwrap_or(0.0);
            queue.write_buffer(instances, i as u64 * SLOT, bytemuck::cast_slice(&words));
            let clipped = reach.map(|_| {
                bind_group(
                    device,
                    "volshadow shadow map clipped",
                    &self.pipelines.clipped_layout,
                    [
                        slot(&self.face_buffer, FACE_BYTES),
                        slot(instances, INSTANCE_BYTES),
                        o.mesh.positions.as_entire_binding(),
                        o.mesh.indices.as_entire_binding(),
                    ],
                )
            });
            self.draws.push(Draw {
                positions: o.mesh.positions.clone(),
                indices: o.mesh.indices.clone(),
                index_count: o.mesh.triangle_count * 3,
                closed: o.mesh.is_closed(),
                clipped,
            });
        }
    }
}

/// A depth-only render pass over one layer of `target`, loading it as `load` says.
fn layer_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    target: &wgpu::Texture,
    layer: u32,
    load: wgpu::LoadOp<f32>,
    timer: Option<&mut GpuTimer>,
) -> wgpu::RenderPass<'e> {
    let view = target.create_view(&wgpu::TextureViewDescriptor {
        label: Some("volshadow shadow face"),
        dimension: Some(wgpu::TextureViewDimension::D2),
        base_array_layer: layer,
        array_layer_count: Some(1),
        ..Default::default()
    });
    crate::gpu::passes::begin_render(
        encoder,
        &wgpu::RenderPassDescriptor {
            label: Some("volshadow shadow map"),
            color_attachments: &[],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &view,
                depth_ops: Some(wgpu::Operations {
                    load,
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: timer.and_then(|t| t.render_pass(Pass::ShadowMap)),
            occlusion_query_set: None,
            multiview_mask: None,
        },
    )
}

impl ShadowMapNode {
    /// Records a gated map ([`ShadowMapInputs::fallback`](super::ShadowMapInputs::fallback)): the
    /// gate's scan, then each listed layer's render pass, which loads the layer and draws its clear
    /// and its occluders from the gate's arguments (zero, drawing nothing, unless the gate opened).
    fn encode_gated(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        mut timer: Option<&mut GpuTimer>,
    ) -> Result<()> {
        let (Some(texture), Some(bind_group), Some(gate)) =
            (&self.texture, &self.bind_group, self.gate.as_mut())
        else {
            return Ok(());
        };
        gate.encode(encoder, timer.as_deref_mut());
        let Some(live) = gate.live() else {
            return Ok(());
        };
        for layer in &gate.layers {
            let timer = timer.as_deref_mut();
            let mut pass = layer_pass(encoder, texture, layer.layer, wgpu::LoadOp::Load, timer);
            let face = layer.layer * SLOT as u32;
            pass.set_pipeline(&self.pipelines.clear);
            pass.set_bind_group(0, bind_group, &[face, 0]);
            pass.draw_indirect(live, layer.clear);
            for &(i, at) in &layer.draws {
                let draw = &self.draws[i as usize];
                let offsets = [face, i * SLOT as u32];
                if let Some(clipped) = &draw.clipped {
                    pass.set_pipeline(&self.pipelines.depth_clipped);
                    pass.set_bind_group(0, clipped, &offsets);
                    pass.draw_indirect(live, at);
                    continue;
                }
                pass.set_pipeline(&self.pipelines.depth);
                pass.set_bind_group(0, bind_group, &offsets);
                pass.set_vertex_buffer(0, draw.positions.slice(..));
                pass.set_index_buffer(draw.indices.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed_indirect(live, at);
            }
        }
        Ok(())
    }
}

impl Encode for ShadowMapNode {
    /// Records the render of every face, if [`prepare`](crate::nodes::Node::prepare) found a
    /// change.
    fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        mut timer: Option<&mut GpuTimer>,
    ) -> Result<()> {
        let pending = std::mem::take(&mut self.pending);
        if self.gate.is_some() {
            return self.encode_gated(encoder, timer);
        }
        if !pending {
            return Ok(());
        }
        let (Some(texture), Some(bind_group)) = (&self.texture, &self.bind_group) else {
            return Ok(());
        };
        // The front surfaces, then (a light with a radius) the back faces.
        let targets = std::iter::once((texture, false)).chain(self.back.iter().map(|b| (b, true)));
        for (target, back) in targets {
            for layer in 0..target.depth_or_array_layers() {
                if back
                    && !self
                        .back_layers
                        .get(layer as usize)
                        .copied()
                        .unwrap_or(true)
                {
                    continue;
                }
                let drawn = self
                    .layer_draws
                    .as_ref()
                    .and_then(|l| l.get(layer as usize));
                let draws = drawn.map_or(self.draws.len(), Vec::len);
                if !back {
                    // A layer with nothing to draw that is already clear stays as it is.
                    let dirty = self.dirty.get_mut(layer as usize);
                    if draws == 0 && dirty.as_deref() == Some(&false) {
                        continue;
                    }
                    if let Some(d) = dirty {
                        *d = draws > 0;
                    }
                }
                let timer = timer.as_deref_mut();
                let mut pass = layer_pass(encoder, target, layer, wgpu::LoadOp::Clear(0.0), timer);
                let mut all = 0..self.draws.len() as u32;
                let mut listed = drawn.map(|l| l.iter().copied());
                let indices: &mut dyn Iterator<Item = u32> = match listed.as_mut() {
                    Some(l) => l,
                    None => &mut all,
                };
                for i in indices {
                    // An open mesh has no inside: its back layer is its nearest face.
                    self.draws[i as usize].record(
                        &mut pass,
                        &self.pipelines,
                        bind_group,
                        [layer * SLOT as u32, i * SLOT as u32],
                        back,
                    );
                }
            }
        }
        if !self.gathers.is_empty() {
            let groups: Vec<[&wgpu::BindGroup; 1]> =
                self.gathers.iter().map(|(g, _)| [g]).collect();
            let dispatches: Vec<_> = self
                .gathers
                .iter()
                .zip(&groups)
                .map(|((_, n), g)| (&self.pipelines.gather, &g[..], (*n, 1, 1)))
                .collect();
            dispatch(
                encoder,
                timer,
                Pass::ShadowMap,
                "volshadow occluder triangles",
                &dispatches,
            );
        }
        Ok(())
    }
}
