//! The exact method's per-pixel crossing lists: the request, the lists' GPU state and the
//! compute build's bins, their preparation each frame, and their recording.

use glam::Mat4;

use crate::error::{Error, Result};
use crate::gpu::pipeline::bind_group;
use crate::gpu::{check_depth_texture, depth_view, GpuTimer, UniformBuffer};
use crate::nodes::groups::uniforms::ViewUniform;
use crate::pass::Pass;
use crate::scene::Camera;

use super::pipelines::{BinUniform, CrossingUniform};
use super::ExtentsNode;

const TILE: u32 = 16;
/// Workgroups of the compute build's binning passes (`GROUPS` in `shaders/shared/crossings.wgsl`).
const BIN_GROUPS: u32 = 1024;
/// Bytes of one face record of the compute build (5 `vec4<f32>`).
const FACE_BYTES: u64 = 80;

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

    /// Writes this frame's parameters: the view, its clip-from-world matrix and the lists'
    /// (`lists`: size, entries per pixel, near plane).
    fn write_params(
        &mut self,
        queue: &wgpu::Queue,
        view: &ViewUniform,
        camera: &Camera,
        clip_from_world: Mat4,
        lists: &CrossingUniform,
    ) {
        self.params.write(
            queue,
            BinUniform {
                view_from_clip: view.view_from_clip,
                world_from_view: view.world_from_view,
                view_size: view.size,
                far_depth: view.far_depth,
                clip_from_world: clip_from_world.to_cols_array(),
                size: lists.size,
                entries: lists.entries,
                near: lists.near,
                tiles: [self.tile_count.0, self.tile_count.1],
                bin_capacity: (self.bins.size() / 4) as u32,
                face_capacity: self.face_capacity,
                affine: u32::from(rays_are_affine(camera)),
            },
        );
    }

    /// Rebinds when the volume, the lists' heads or the request's depth buffer changed since
    /// the last bind (`args`: the volume's draw arguments).
    fn bind(
        &mut self,
        device: &wgpu::Device,
        layout: &wgpu::BindGroupLayout,
        (volume, args): (&wgpu::Buffer, &wgpu::Buffer),
        (heads, list): (&wgpu::Buffer, &wgpu::Buffer),
        request: &CrossingsRequest<'_>,
    ) {
        let stale = self
            .bound
            .as_ref()
            .is_none_or(|(_, v, h, d)| v != volume || h != heads || d != request.scene_depth);
        if !stale {
            return;
        }
        let depth_view = depth_view(request.scene_depth);
        let group = bind_group(
            device,
            "volshadow crossings",
            layout,
            [
                volume.as_entire_binding(),
                args.as_entire_binding(),
                self.params.binding(),
                wgpu::BindingResource::TextureView(&depth_view),
                self.faces.as_entire_binding(),
                self.tiles.as_entire_binding(),
                self.bins.as_entire_binding(),
                heads.as_entire_binding(),
                list.as_entire_binding(),
            ],
        );
        self.bound = Some((
            group,
            volume.clone(),
            heads.clone(),
            request.scene_depth.clone(),
        ));
    }
}

/// The crossing lists' GPU state.
pub(super) struct CrossingLists {
    view: UniformBuffer<ViewUniform>,
    params: UniformBuffer<CrossingUniform>,
    pub(super) heads: wgpu::Buffer,
    pub(super) list: wgpu::Buffer,
    pub(super) per_pixel: u32,
    pub(super) size: (u32, u32),
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

impl ExtentsNode {
    /// Sizes the crossing lists (recreated only when the size or entries per pixel change),
    /// uploads the camera, and rebinds when the depth buffer changed.
    pub(super) fn prepare_crossings(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        (request, per_pixel): (&CrossingsRequest<'_>, u32),
        (camera, clip_from_world, (width, height), max_faces): (&Camera, Mat4, (u32, u32), u32),
    ) -> Result<()> {
        let Lists {
            mut view,
            mut params,
            heads,
            list,
            bound,
            bins,
        } = self.take_lists(device, request.scene_depth, per_pixel, (width, height));
        let view_uniform = ViewUniform::new(camera, width, height);
        view.write(queue, view_uniform);
        let lists_uniform = CrossingUniform {
            size: [width, height],
            entries: per_pixel,
            near: self.near,
        };
        params.write(queue, lists_uniform);
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
                b.write_params(
                    queue,
                    &view_uniform,
                    camera,
                    clip_from_world,
                    &lists_uniform,
                );
                let layout = &self.pipelines.bin_layout;
                b.bind(
                    device,
                    layout,
                    (volume, &self.args),
                    (&heads, &list),
                    request,
                );
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

    /// The last frame's lists when they have this size and entries per pixel (with their bind
    /// group where `scene_depth` is the same texture), else new heads and lists, keeping the
    /// uniforms and the compute build's bins (unbound). Leaves `self.crossings` empty.
    fn take_lists(
        &mut self,
        device: &wgpu::Device,
        scene_depth: &wgpu::Texture,
        per_pixel: u32,
        (width, height): (u32, u32),
    ) -> Lists {
        let pixels = u64::from(width) * u64::from(height);
        let heads_size = 16 * pixels;
        let reuse = self
            .crossings
            .as_ref()
            .is_some_and(|c| c.size == (width, height) && c.per_pixel == per_pixel);
        match self.crossings.take() {
            Some(c) if reuse => {
                let bound = (c.depth == *scene_depth).then_some(c.bind_group);
                Lists {
                    view: c.view,
                    params: c.params,
                    heads: c.heads,
                    list: c.list,
                    bound,
                    bins: c.bins,
                }
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
                Lists {
                    view,
                    params,
                    heads: buffer("volshadow crossing heads", heads_size),
                    list: buffer(
                        "volshadow crossing lists",
                        4 * pixels * u64::from(per_pixel),
                    ),
                    bound: None,
                    bins: bins.map(|mut b| {
                        b.bound = None;
                        b
                    }),
                }
            }
        }
    }

    /// Records the lists' build: the compute build's passes over its bins, or the rasterised
    /// lists' render pass (`target`: the attachment the pass needs, neither tested nor
    /// written; `volume`: the shadow volumes).
    pub(super) fn encode_crossings(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        timer: Option<&mut GpuTimer>,
        lists: &CrossingLists,
        target: &wgpu::Texture,
        volume: &wgpu::Buffer,
    ) {
        if let (CrossingsBuild::Compute, Some(bins)) = (lists.build, &lists.bins) {
            self.encode_bins(encoder, timer, lists, bins);
            return;
        }
        encoder.clear_buffer(&lists.heads, 0, None);
        // The depth target is only there because a render pass needs an attachment:
        // the pipeline neither tests nor writes it.
        let view = target.create_view(&Default::default());
        let timestamp_writes = timer.and_then(|t| t.render_pass(Pass::Extents));
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
    }

    /// Records the compute build: the faces binned into tiles, then each tile's lists (or,
    /// without a volume, empty lists).
    fn encode_bins(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        timer: Option<&mut GpuTimer>,
        lists: &CrossingLists,
        bins: &Bins,
    ) {
        let Some((group, ..)) = &bins.bound else {
            return;
        };
        if self.jobs.is_empty() {
            // No volume: nothing crosses.
            encoder.clear_buffer(&lists.heads, 0, None);
            return;
        }
        encoder.clear_buffer(&bins.tiles, 0, None);
        let mut pass = crate::gpu::passes::begin_compute(
            encoder,
            &wgpu::ComputePassDescriptor {
                label: Some("volshadow crossings"),
                timestamp_writes: timer.and_then(|t| t.compute_pass(Pass::Extents)),
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
    }
}

/// The lists' buffers for a frame ([`ExtentsNode::take_lists`]): the uniforms, heads and lists,
/// the bind group where it still holds, and the compute build's bins.
struct Lists {
    view: UniformBuffer<ViewUniform>,
    params: UniformBuffer<CrossingUniform>,
    heads: wgpu::Buffer,
    list: wgpu::Buffer,
    bound: Option<wgpu::BindGroup>,
    bins: Option<Bins>,
}

/// Checks a crossing-list request for a `width × height` frame; returns the entries per pixel
/// that fit the device's bindings.
pub(super) fn crossings_per_pixel(
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
