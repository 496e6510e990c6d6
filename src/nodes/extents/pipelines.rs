//! The extents node's binding tables, the parameter structs its shaders read
//! (`shaders/passes/extents.wgsl`, `shaders/shared/crossings.wgsl`), and its pipelines.

use crate::gpu::pipeline::{compute_pipeline, depth_pipeline, layout, module, Binding};
use crate::gpu::wgsl::wgsl_file;
use crate::gpu::ShaderPrecision;
use crate::light::LightUniform;
use crate::nodes::cache::CachedPipelines;

/// Bytes of one shadow-volume vertex (`VolumeVertex` in `shaders/passes/extents.wgsl`): position,
/// flags, the face's plane and a point of it.
pub(super) const VOLUME_VERTEX_BYTES: u64 = 64;

/// The extrusion's binding table (`@binding(i)` of the compute stage of
/// `shaders/passes/extents.wgsl`).
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

/// The compute build's binding table (`shaders/shared/crossings.wgsl`).
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
/// after a cube's six planes).
pub(super) const FAN: u32 = 7;

/// Tiles of the compute build, in pixels across and down (`TILE` in
/// `shaders/shared/crossings.wgsl`). The node's layouts and pipelines, held by the
/// [`Cache`](crate::nodes::Cache).
#[derive(Clone)]
pub(crate) struct Pipelines {
    pub(super) extrude_layout: wgpu::BindGroupLayout,
    pub(super) raster_layout: wgpu::BindGroupLayout,
    pub(super) crossings_layout: wgpu::BindGroupLayout,
    pub(super) reset: wgpu::ComputePipeline,
    pub(super) extrude: wgpu::ComputePipeline,
    /// Front, back near and back far.
    pub(super) depths: [wgpu::RenderPipeline; 3],
    pub(super) crossings: wgpu::RenderPipeline,
    /// `depths` through `vs_volume_clipped`, with the volume bound as group 1 (`clip_layout`), for
    /// frames whose occluders [`clips_volumes`](super::clips_volumes) says may need it (the exact
    /// method's lists are then built by compute passes).
    pub(super) clip_layout: wgpu::BindGroupLayout,
    pub(super) depths_clipped: [wgpu::RenderPipeline; 3],
    pub(super) bin_layout: wgpu::BindGroupLayout,
    /// The compute build: setup, count, scan, fill, build.
    pub(super) bin: [wgpu::ComputePipeline; 5],
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
        let (bin_layout, bin) = Self::bins(device, precision);
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

    /// The compute build's layout and its five passes (`shaders/shared/crossings.wgsl`): setup,
    /// count, scan, fill, build.
    fn bins(
        device: &wgpu::Device,
        precision: ShaderPrecision,
    ) -> (wgpu::BindGroupLayout, [wgpu::ComputePipeline; 5]) {
        let bin_layout = layout(
            device,
            "volshadow crossings",
            wgpu::ShaderStages::COMPUTE,
            &BIN_BINDINGS,
        );
        let bin_module =
            crate::gpu::pipeline::module(device, &wgsl_file!(shared "crossings.wgsl"), precision);
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
        (bin_layout, bin)
    }
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct ExtrudeUniform {
    pub(super) world_from_object: [f32; 16],
    pub(super) light: LightUniform,
    pub(super) mirror: f32,
    pub(super) edges: u32,
    pub(super) triangles: u32,
    pub(super) closed: u32,
    pub(super) capacity: u32,
}

/// WGSL `Params` of `shaders/shared/crossings.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct BinUniform {
    pub(super) view_from_clip: [f32; 16],
    pub(super) world_from_view: [f32; 16],
    pub(super) clip_from_world: [f32; 16],
    pub(super) view_size: [f32; 2],
    pub(super) size: [u32; 2],
    pub(super) tiles: [u32; 2],
    pub(super) far_depth: f32,
    pub(super) entries: u32,
    pub(super) near: f32,
    pub(super) bin_capacity: u32,
    pub(super) face_capacity: u32,
    /// 1: ray directions are affine in pixel coordinates (see `shaders/shared/crossings.wgsl`).
    pub(super) affine: u32,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct CrossingUniform {
    pub(super) size: [u32; 2],
    pub(super) entries: u32,
    pub(super) near: f32,
}

#[cfg(test)]
#[test]
fn params_layouts_match_the_wgsl() {
    use crate::nodes::layout::{assert_same, rust_layout};
    let extents = include_str!("../../../shaders/passes/extents.wgsl");
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
    assert_same(
        bin,
        include_str!("../../../shaders/shared/crossings.wgsl"),
        "Params",
    );
}
