//! The soft-shadow node: for a light with a radius, the fraction of the light's disc visible
//! from each cell of a light-space grid, built once per frame from the shadow map (and only
//! when the shadow map changed), which the march then reads with one trilinear lookup per step.
//!
//! # Method
//!
//! Each cell holds the percentage-closer soft shadow estimate (Fernando, "Percentage-Closer
//! Soft Shadows", 2005) that the march would otherwise compute per step from the shadow map:
//! a blocker search (two rounds of 8 taps), then 32 filter taps over the light's disc, 96 more
//! where at most 12 of the 32 are lit (the deep penumbra, where a tap is a large part of a small
//! fraction). The blockers' distance lies between the midpoint `m` of the front surface and the
//! back face ([`ShadowMap::back`]) and their geometric mean `g`, as `m^¾ g^¼`: for a sphere `m`
//! is the centre's distance and `g` the tangent distance, and a planar blocker at either sets
//! the deep penumbra too dark or too bright (see `docs/METHOD.md` §3). Where the blockers found
//! lie at clearly different distances (ratio > 1.5) the estimate takes two layers, each with its
//! own filter width.
//!
//! The grid is the shadow map's layers (cube faces of a point light, the one layer of a spot)
//! at [`SoftShadowSize::directions`]² directions, times [`SoftShadowSize::slices`] distances
//! uniform in `q = d_near / d ∈ (0, 1]` (`d_near` the least distance of an occluder's bounding
//! box from the light): a penumbra's width seen from the light, `radius · (1/d_blocker − 1/d)`,
//! is linear in `q`, so the slices are uniform steps in penumbra width and the last reaches
//! infinity.
//!
//! The build estimates only where interpolation would not do. A first pass estimates the
//! directions at even indices (a quarter) at their even slices and the last, and an odd slice
//! only where its two neighbours differ; a second fills each other direction with the mean of
//! its neighbours where they agree (none marked, fractions within 5% of the larger, or on a
//! penumbra at least 4 cells wide away from its foot), and estimates it where not. Each pass
//! lists the cells it cannot interpolate, and an indirect dispatch estimates each list, one
//! cell a thread, its stages (search, filter, deep-penumbra taps) gathered onto the first
//! threads of the workgroup, so that a SIMD batch does not wait on one lane's long list. The
//! build runs only over the blocks of 2 × 2 directions whose cells, or their neighbours', a
//! penumbra cone may reach; elsewhere the grid is lit, and each build sets lit the last build's
//! blocks outside its own.
//!
//! Cells where the estimate found the penumbra (or the edge between lit and umbra) narrower
//! than two cells, and cells with an occluder's surface between them and a neighbouring
//! slice, are marked: interpolation would smear them, so the march refines its steps there
//! (see [`MarchNode`](crate::nodes::MarchNode)), blending in the shadow map's own visibility
//! where the penumbra is narrow, and at a surface taking the grid's slice on the near side for
//! a point in front of it and the shadow map's visibility behind. A far layer that hides none of
//! a point's filter taps and lies within 0.9 of its distance is a receiver the point lies above
//! (a ground), not a reason to mark the cell.
//!
//! Where the shadow map carries the occluders' triangles ([`ShadowMap::triangles`]: occluders
//! that may leave gaps, at most [`MAX_EXACT_TRIANGLES`](crate::nodes::MAX_EXACT_TRIANGLES) of
//! them), a cell's estimate is the exact visible fraction in place of PCSS: bitmask soft
//! shadows (Schwarz and Stamminger, "Bitmask Soft Shadows", 2007) with the triangles in place
//! of shadow-map texels, 256 directions over the light's cap, each triangle hiding the
//! intersection of three half-planes of it from a precomputed table. A shadow map sees the
//! occluders from the light's centre alone, and through a gap narrower than the light a point
//! sees parts of the light past faces the centre does not (`docs/METHOD.md`). The march then
//! takes the same fraction at the steps the marks below single out, and at those marked for a
//! narrow penumbra or a surface whose grid value lies strictly between 0 and 1.
//!
//! Where the shadow map's occluders may leave gaps ([`ShadowMap::gaps`]: more than one
//! occluder, or one that is not convex), a last pass copies the grid to the output and marks
//! the cells within 20 of a narrow shaft: a peak of visible fraction below 0.95 that rises by
//! more than 0.1 above its lowest on both sides along a layer's rows or columns, as through a
//! gap narrower than the light (a slit, blinds, a door ajar). There the trilinear lookup cuts
//! the corners of the shaft's profile (too bright at its foot) and the shadow map's own
//! visibility is the light's centre alone, so the march takes the per-point estimate at its
//! steps (the grid's value where that estimate takes two layers of blockers). An occluder's
//! own penumbra falls one way only, from lit to umbra, so a scene without gaps has no such
//! mark and pays only for the copy. A cell just behind a surface (the slice before it saw more
//! than 0.1 more of the light) is neither a peak nor a shaft's side: the slices behind a ground
//! under a penumbra are darker, and they are not the side of a gap. Where the cells are exact
//! (the triangles given), the marks reach 6 cells from a shaft, not 20, and also cover a cell
//! whose second difference along a layer's rows or columns or the slices exceeds a tenth of
//! the largest of the three cells' fractions (at most 0.04): there the trilinear lookup
//! between exact cells cannot be trusted. A room lit through a door ajar lies wholly in the
//! gap's penumbra, and far from the gap its shaft is smooth enough for the lookup.
//!
//! # Accuracy and limits
//!
//! Current figures, with their bounds, are in `docs/ACCURACY.md`:
//!
//! * a sphere under a light of radius 0.2 × their distance, against `reference::soft`
//!   (`tests/gpu/soft.rs`); 12 seeded sphere scenes, and the grid's cells against the exact visible
//!   fraction at each cell's point (`tests/gpu/soft_grid.rs`).
//! * PCSS assumes one planar blocker per point. The error is relative to the visible fraction,
//!   so it shows where a pixel's light comes mostly from the deep penumbra: the eye in an umbra
//!   looking away from the light (bar p95 5.5%), spot lights whose view is lit only by the
//!   deep penumbra (2 of 12 seeded scenes beyond p95 3%, all within 10%), and a thick medium
//!   (σt·L 1 to 10) with the eye a few mean free paths from a penumbra, which fails the soft
//!   bars (`random_soft_scenes_in_thick_fog`, ignored, run by hand).
//! * The shadow map holds one surface a direction: an occluder hidden behind a nearer one is
//!   partly missed (two spheres with overlapping penumbrae, bar p95 3.25%).
//! * A light nearly as large as its distance to an occluder is beyond the one-planar-blocker
//!   assumption (radius 1.39 against a gap of 1.4, bar 6%; the occluder half inside the light's
//!   sphere, bar 10%).
//! * Gaps: with the occluders' triangles, 15 of the 16 gap scenes of `tests/gpu/soft_grid.rs`
//!   are within p95 3% (the shadow map's estimate cannot see a shaft the light's centre does
//!   not: blinds tilted across it, a door ajar). The 16th, a door nearly closed behind a thick
//!   plate, is lit only by a strip of the light 1e-5 of its radius wide, narrower than what
//!   rounding the occluders' corners to f32 moves (its reference moves by p95 35%): it comes
//!   out black. A shaft narrower than a refined step's piece, between two of its samples, is
//!   missed (see `docs/METHOD.md`).
//! * The exact fraction cuts a triangle where the cone of lines to the light touches the
//!   light's sphere: an occluder reaching into the sphere is beyond it.
//! * The blockers' distance is fitted to round occluders: a box's penumbra is wider than the
//!   model predicts, most where the light is larger than the box (8 seeded box scenes, bar:
//!   7 within p95 3%, all within 6%).
//! * A light whose penumbrae are all narrower than a shadow-map texel is better drawn hard
//!   ([`ShadowMapNode::penumbra_below_texel`](crate::nodes::ShadowMapNode::penumbra_below_texel),
//!   which the facade applies): through the grid such a penumbra is marched, not integrated
//!   between exact boundaries.
//!
//! # Inputs
//! * the [`ShadowMap`] of the light, with its occluders' [`ShadowMap::bounds`] (which bound
//!   where a penumbra can be; without them every cell is estimated);
//! * the light: a point or spot light with a radius > 0.
//!
//! # Output
//! [`SoftShadowNode::output`]: a 3D `Rgba16Float` texture, `directions × directions ×
//! (layers · slices)` (layer-major along z), usages `STORAGE_BINDING | TEXTURE_BINDING |
//! COPY_SRC`;
//! r = visible fraction in [0, 1], g = 1 where the cell's penumbra is marked sharp, b = 1
//! where an occluder's surface lies between it and a neighbouring slice, a = 1 near a narrow
//! shaft, else 0.
//!
//! # Cost
//! The work moves from pixels × steps to the grid's cells, most of which lie outside every
//! penumbra cone and cost no tap: an estimate is 49 shadow-map taps (145 in the deep
//! penumbra), a cell interpolated from its neighbours none. The build runs once per frame in
//! which the shadow map changed, and its cost grows with the cells inside the penumbra cones,
//! not with the output's pixels; the march reads the grid with about half a step per cell the
//! ray crosses. The report's soft scene (`cargo run --release -p volshadow_tools --bin report -- --scenes
//! scenes/soft.json`) times the build against the hard frame (`docs/PERFORMANCE.md`).
//!
//! # Memory
//! Besides the grid (8 bytes a cell: 3 MiB at the default size for a point light), the build
//! holds the grid before its shaft marks (8 bytes a cell), the cells before their marks (an
//! `Rg32Float` texture of the grid's extent, 8 bytes a cell), the anchors (a quarter of the
//! cells, 8 bytes each), and a list of up to three quarters of the cells (4 bytes each):
//! about 10.9 MiB in all at the default size.

use crate::error::{Error, Result};
use crate::gpu::pipeline::{bind_group, compute_pipeline, layout, module, Binding};
use crate::gpu::wgsl::{wgsl_file, Wgsl};
use crate::gpu::ShaderPrecision;
use crate::gpu::{check_depth_layers, texture_3d, GpuTimer, UniformBuffer};
use crate::light::{light_constant, LightKind, Source};
use crate::nodes::cache::CachedPipelines;
use crate::nodes::groups::shadow::{cell_angle, shadow_layout, ShadowBinding, ShadowUniform};
use crate::nodes::shadow_map::ShadowMap;
use crate::nodes::Cache;
use crate::nodes::{Encode, Node};
use crate::pass::Pass;
use crate::scene::Light;

mod blocks;

use blocks::{every_block, penumbra_blocks, Blocks};

/// The binding tables of the build's entry points in `shaders/passes/soft_shadow.wgsl`
/// (`@binding(i)` of group 0 is entry `i`; group 1, the light and its shadow map, is
/// [`ShadowBinding`]'s): each binds every slot, with the type its entry point declares where
/// it uses the slot. Slots: 0 `mp`, 1 `volume` (the grid), 2 the anchors, 3 the cells before
/// their marks, 4 a list of cells to estimate, 5 its dispatch, 6 the rest's listed columns,
/// 7 the anchors' slice ranges.
const fn bindings(
    anchors: Binding,
    rest: Binding,
    list: Binding,
    columns: Binding,
    ranges: Binding,
) -> [Binding; 8] {
    [
        Binding::Params,
        Binding::StorageVolume(wgpu::TextureFormat::Rgba16Float),
        anchors,
        rest,
        list,
        list,
        columns,
        ranges,
    ]
}
const ANCHORS_WRITTEN: Binding = Binding::StorageVolume(wgpu::TextureFormat::Rgba16Float);
const REST_WRITTEN: Binding = Binding::StorageVolume(REST_FORMAT);
/// `build_anchors`: fills a list and the anchors' ranges.
const ANCHOR_BINDINGS: [Binding; 8] = bindings(
    ANCHORS_WRITTEN,
    REST_WRITTEN,
    Binding::ReadWrite,
    Binding::ReadWrite,
    Binding::ReadWrite,
);
/// `between_anchors` and `store_anchors`: read the estimated cells and the ranges, fill a list
/// or write the anchors.
const BETWEEN_BINDINGS: [Binding; 8] = bindings(
    ANCHORS_WRITTEN,
    Binding::VolumeLoad,
    Binding::ReadWrite,
    Binding::ReadWrite,
    Binding::Params,
);
/// `build_rest`: reads the anchors, writes cells before their marks, fills a list.
const REST_BINDINGS: [Binding; 8] = bindings(
    Binding::Volume,
    REST_WRITTEN,
    Binding::ReadWrite,
    Binding::ReadWrite,
    Binding::Params,
);
/// `estimate_listed`: reads a list and its dispatch (which cannot be bound for writing while
/// it dispatches), writes the cells.
const ESTIMATE_BINDINGS: [Binding; 8] = bindings(
    Binding::Volume,
    REST_WRITTEN,
    Binding::Params,
    Binding::Params,
    Binding::Params,
);
/// `store_rest`: reads the cells back.
const STORE_BINDINGS: [Binding; 8] = bindings(
    Binding::Volume,
    Binding::VolumeLoad,
    Binding::ReadWrite,
    Binding::Params,
    Binding::Params,
);

/// `mark_shafts`: reads the built grid, writes its copy with the shaft marks (the output).
const MARK_BINDINGS: [Binding; 3] = [
    Binding::Params,
    Binding::VolumeLoad,
    Binding::StorageVolume(wgpu::TextureFormat::Rgba16Float),
];

/// Cells before their marks (see `shaders/passes/soft_shadow.wgsl`): exact f32, so that the marks
/// are those of the values the estimates gave.
const REST_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rg32Float;
/// The three lists' dispatches, each in its own slot of the dispatch buffer (a storage
/// binding's offset is a multiple of 256 bytes on every device).
const LIST_SLOT: u64 = 256;

/// The grid's resolution (default 64 directions × 16 slices; see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SoftShadowSize {
    /// Cells across each shadow-map layer, in each direction. At least [`SoftShadowSize::MIN`].
    pub directions: u32,
    /// Cells along the distance from the light. At least [`SoftShadowSize::MIN`].
    pub slices: u32,
}

impl Default for SoftShadowSize {
    fn default() -> Self {
        Self::DEFAULT
    }
}

impl SoftShadowSize {
    /// The default: 64 directions × 16 slices.
    pub const DEFAULT: SoftShadowSize = SoftShadowSize {
        directions: 64,
        slices: 16,
    };
    /// Fewest cells along any axis.
    pub const MIN: u32 = 2;
    /// Most cells across a layer (the core limit for 3D textures' width).
    pub const MAX_DIRECTIONS: u32 = 2048;
    /// Most slices (one thread holds a direction's slices).
    pub const MAX_SLICES: u32 = 64;

    pub(crate) fn validate(&self) -> Result<()> {
        if (Self::MIN..=Self::MAX_DIRECTIONS).contains(&self.directions)
            && (Self::MIN..=Self::MAX_SLICES).contains(&self.slices)
        {
            Ok(())
        } else {
            Err(Error::InvalidSize {
                field: "soft shadow size (directions, slices)",
                width: self.directions,
                height: self.slices,
                min: Self::MIN,
                max: Self::MAX_SLICES.min(Self::MAX_DIRECTIONS),
            })
        }
    }
}

/// What the node reads in a frame.
#[derive(Clone, Copy)]
pub struct SoftShadowInputs<'a> {
    /// A point or spot light with a radius > 0.
    pub light: &'a Light,
    /// Its shadow map, rendered this frame.
    pub shadow_map: ShadowMap<'a>,
}

/// The grid as the march reads it ([`Shadows::soft`](crate::nodes::Shadows::soft)).
#[derive(Clone, Copy)]
pub struct SoftShadow<'a> {
    /// The 3D texture (see the module docs).
    pub texture: &'a wgpu::Texture,
    /// Its resolution.
    pub size: SoftShadowSize,
    /// `d_near` of its slices (see the module docs): slice `k` of `s` lies at the distance
    /// `d_near / (1 − (k + ½) / s)` from the light. For reading the grid; the march derives
    /// the same from the shadow map.
    pub near: f32,
    /// Whether its cells are marked near narrow shafts (a = 1 there; see the module docs):
    /// only where the shadow map's occluders may leave gaps ([`ShadowMap::gaps`]); else a is
    /// 0 everywhere and the march skips the shafts' refinement.
    pub shafts: bool,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
/// WGSL `SoftShadowParams` (`shaders/passes/soft_shadow.wgsl`), field by field.
struct SoftShadowUniform {
    built: Blocks,
    lit: Blocks,
    world_from_clip: [[f32; 16]; 6],
    size: u32,
    slices: u32,
    layers: u32,
}

/// The grid's WGSL: the shared shadow-map visibility, then the grid's passes.
const SOURCE: Wgsl<'static> = wgsl_file!("soft_shadow.wgsl");

/// The passes of a build (see `shaders/passes/soft_shadow.wgsl`) for one kind of light.
#[derive(Clone)]
struct Build {
    fill: wgpu::ComputePipeline,
    anchors: wgpu::ComputePipeline,
    between: wgpu::ComputePipeline,
    store_anchors: wgpu::ComputePipeline,
    rest: wgpu::ComputePipeline,
    estimate: wgpu::ComputePipeline,
    store_rest: wgpu::ComputePipeline,
    mark: wgpu::ComputePipeline,
}

/// The node's layouts and its pipelines (one per kind of light that can have a radius), held
/// by the [`Cache`].
#[derive(Clone)]
pub(crate) struct Pipelines {
    anchor_layout: wgpu::BindGroupLayout,
    between_layout: wgpu::BindGroupLayout,
    rest_layout: wgpu::BindGroupLayout,
    estimate_layout: wgpu::BindGroupLayout,
    store_layout: wgpu::BindGroupLayout,
    /// Group 1, the light and its shadow map ([`ShadowBinding`]).
    shadow_layout: wgpu::BindGroupLayout,
    mark_layout: wgpu::BindGroupLayout,
    /// Per `LIGHT` constant.
    by_kind: Vec<(u32, Build)>,
}

impl CachedPipelines for Pipelines {
    fn build(device: &wgpu::Device, precision: ShaderPrecision) -> Self {
        Self::new(device, precision)
    }
}

impl Pipelines {
    pub(crate) fn new(device: &wgpu::Device, precision: ShaderPrecision) -> Self {
        let label = "volshadow soft shadow";
        let stages = wgpu::ShaderStages::COMPUTE;
        let anchor_layout = layout(device, label, stages, &ANCHOR_BINDINGS);
        let between_layout = layout(device, label, stages, &BETWEEN_BINDINGS);
        let rest_layout = layout(device, label, stages, &REST_BINDINGS);
        let estimate_layout = layout(device, label, stages, &ESTIMATE_BINDINGS);
        let store_layout = layout(device, label, stages, &STORE_BINDINGS);
        let mark_layout = layout(device, label, stages, &MARK_BINDINGS);
        let shadow_layout = shadow_layout(device);
        let module = module(device, &SOURCE, precision);
        let build = |light: u32| {
            let constants = [light_constant(light)];
            let pipeline = |layout, entry| {
                compute_pipeline(
                    device,
                    label,
                    &[layout, &shadow_layout],
                    &module,
                    entry,
                    &constants,
                )
            };
            Build {
                fill: pipeline(&anchor_layout, "fill_lit"),
                anchors: pipeline(&anchor_layout, "build_anchors"),
                between: pipeline(&between_layout, "between_anchors"),
                store_anchors: pipeline(&between_layout, "store_anchors"),
                rest: pipeline(&rest_layout, "build_rest"),
                estimate: pipeline(&estimate_layout, "estimate_listed"),
                store_rest: pipeline(&store_layout, "store_rest"),
                // Group 0 alone: it reads the grid, not the shadow map.
                mark: compute_pipeline(
                    device,
                    label,
                    &[&mark_layout, &shadow_layout],
                    &module,
                    "mark_shafts",
                    &constants,
                ),
            }
        };
        let mut by_kind: Vec<(u32, Build)> = Vec::new();
        for kind in LightKind::ALL
            .into_iter()
            .filter(|k| k.soft())
            .map(LightKind::gpu)
        {
            if by_kind.iter().all(|(k, _)| *k != kind) {
                by_kind.push((kind, build(kind)));
            }
        }
        Self {
            anchor_layout,
            between_layout,
            rest_layout,
            estimate_layout,
            store_layout,
            shadow_layout,
            mark_layout,
            by_kind,
        }
    }
}

/// What the bind groups were made for, and they.
struct Bound {
    grid: wgpu::Texture,
    groups: Groups,
    /// `mark_shafts`: the grid in, its marked copy out.
    mark: wgpu::BindGroup,
}

/// The build's bind groups: one per pass, and the estimates' one per list.
struct Groups {
    anchors: wgpu::BindGroup,
    between: wgpu::BindGroup,
    store_anchors: wgpu::BindGroup,
    rest: wgpu::BindGroup,
    estimates: [wgpu::BindGroup; 3],
    store_rest: wgpu::BindGroup,
}

/// The build's own textures and buffers (see `shaders/passes/soft_shadow.wgsl`), sized with the
/// grid.
struct Scratch {
    /// The anchors' cells with what decides interpolation (`anchor_count()`² per layer).
    anchors: wgpu::Texture,
    /// Cells before their marks, the grid's extent, exact f32.
    rest: wgpu::Texture,
    /// A list of cells to estimate (the lists take turns in it), room for every cell of the
    /// other directions, the longest list.
    work: wgpu::Buffer,
    /// The three lists' indirect dispatches and counts, a slot of `LIST_SLOT` bytes each.
    work_args: wgpu::Buffer,
    /// Per block of 2 × 2 directions: which of its other columns have listed cells.
    listed_columns: wgpu::Buffer,
    /// Per anchor: its slices inside a penumbra cone.
    anchor_ranges: wgpu::Buffer,
}

impl Scratch {
    /// For a grid of `n`² directions by `s` slices in `layers` layers. Errors where the
    /// longest list would not fit the device's storage-buffer limits (a grid of more than
    /// about 44 million cells at the core limits, a third of a gigabyte itself).
    fn new(device: &wgpu::Device, n: u32, layers: u32, s: u32) -> Result<Self> {
        let a = n.div_ceil(2);
        let rest_cells = u64::from(n * n - a * a) * u64::from(layers * s);
        let bytes = 4 * rest_cells.max(1);
        crate::gpu::check_buffer_size(device, "soft shadow list", bytes)?;
        let buffer = |label, size, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::STORAGE | usage,
                mapped_at_creation: false,
            })
        };
        let blocks = 4 * u64::from(a * a * layers);
        Ok(Self {
            anchors: texture_3d(
                device,
                "volshadow soft shadow anchors",
                (a, a, layers * s),
                wgpu::TextureFormat::Rgba16Float,
                wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::TEXTURE_BINDING,
            ),
            rest: texture_3d(
                device,
                "volshadow soft shadow cells",
                (n, n, layers * s),
                REST_FORMAT,
                wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::TEXTURE_BINDING,
            ),
            work: buffer(
                "volshadow soft shadow list",
                bytes,
                wgpu::BufferUsages::empty(),
            ),
            // COPY_DST: cleared before each build (every list starts empty).
            work_args: buffer(
                "volshadow soft shadow list dispatch",
                3 * LIST_SLOT,
                wgpu::BufferUsages::INDIRECT | wgpu::BufferUsages::COPY_DST,
            ),
            listed_columns: buffer(
                "volshadow soft shadow listed columns",
                blocks,
                wgpu::BufferUsages::empty(),
            ),
            anchor_ranges: buffer(
                "volshadow soft shadow anchor ranges",
                blocks,
                wgpu::BufferUsages::empty(),
            ),
        })
    }

    /// The passes' bind groups, with `common` the bindings 0 and 1 (parameters, grid).
    fn bind(
        &self,
        device: &wgpu::Device,
        pipelines: &Pipelines,
        common: [wgpu::BindingResource<'_>; 2],
    ) -> Groups {
        let anchors = self.anchors.create_view(&Default::default());
        let rest = self.rest.create_view(&Default::default());
        let slot = |i: u64| {
            wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                buffer: &self.work_args,
                offset: i * LIST_SLOT,
                size: wgpu::BufferSize::new(16),
            })
        };
        let group = |layout: &wgpu::BindGroupLayout, list: u64| {
            let [c0, c1] = common.clone();
            bind_group(
                device,
                "volshadow soft shadow",
                layout,
                [
                    c0,
                    c1,
                    wgpu::BindingResource::TextureView(&anchors),
                    wgpu::BindingResource::TextureView(&rest),
                    self.work.as_entire_binding(),
                    slot(list),
                    self.listed_columns.as_entire_binding(),
                    self.anchor_ranges.as_entire_binding(),
                ],
            )
        };
        Groups {
            anchors: group(&pipelines.anchor_layout, 0),
            between: group(&pipelines.between_layout, 1),
            store_anchors: group(&pipelines.between_layout, 1),
            rest: group(&pipelines.rest_layout, 2),
            estimates: [0, 1, 2].map(|list| group(&pipelines.estimate_layout, list)),
            store_rest: group(&pipelines.store_layout, 2),
        }
    }
}

/// Builds the soft-shadow grid of one light (see the module docs). `prepare` decides whether
/// it needs rebuilding: only when the shadow map ([`ShadowMap::generation`]), the light or the
/// grid's size changed; `encode` records the build only then.
pub struct SoftShadowNode {
    size: SoftShadowSize,
    pipelines: Pipelines,
    uniform: UniformBuffer<SoftShadowUniform>,
    /// Group 1: the light and its shadow map.
    shadow: ShadowBinding,
    /// The grid as the build writes it.
    texture: Option<wgpu::Texture>,
    /// Its copy with the shaft marks (`mark_shafts`), the output where the shadow map's
    /// occluders may leave gaps ([`ShadowMap::gaps`]); else the output is `texture`.
    marked: Option<wgpu::Texture>,
    /// This frame's shadow map may have gaps: the build marks shafts.
    marks: bool,
    /// `marked` holds the grid of the last build (every cell: the last build marked shafts).
    marked_current: bool,
    /// The build's own textures and buffers, made with `texture`.
    scratch: Option<Scratch>,
    /// The bind groups of the passes, and the shadow map, its back faces and the grid they
    /// were made for.
    bound: Option<Bound>,
    pipeline: Option<Build>,
    layers: u32,
    /// The slices' `d_near` of the last `prepare`.
    near: f32,
    /// The shadow map generation the grid was (or will be, when `pending`) built from.
    generation: Option<u64>,
    pending: bool,
    /// The blocks the next build covers, and those that may hold a shadow (the last build's;
    /// every block of a new grid, which starts at 0).
    built: Blocks,
    stale: Blocks,
    /// Build every block (a test's reference for `penumbra_blocks`).
    every_block: bool,
}

impl SoftShadowNode {
    /// Creates the node; the grid is allocated by the first [`prepare`](Self::prepare).
    ///
    /// # Errors
    ///
    /// [`Error::InvalidSize`] naming the soft shadow size for a resolution out of range.
    pub fn new(device: &wgpu::Device, cache: &Cache, size: SoftShadowSize) -> Result<Self> {
        size.validate()?;
        Ok(Self {
            size,
            pipelines: cache.get::<Pipelines>(),
            uniform: UniformBuffer::new(device, "volshadow soft shadow params"),
            shadow: ShadowBinding::new(
                device,
                &cache.get::<Pipelines>().shadow_layout,
                "volshadow soft shadow light",
            ),
            texture: None,
            marked: None,
            marks: false,
            marked_current: false,
            scratch: None,
            bound: None,
            pipeline: None,
            layers: 0,
            near: 0.0,
            generation: None,
            pending: false,
            built: [[0; 4]; 6],
            stale: [[0; 4]; 6],
            every_block: false,
        })
    }

    /// Builds every direction of the grid, not only those the penumbra cones reach (the
    /// same grid, for a test to compare with).
    #[doc(hidden)]
    pub fn set_every_block(&mut self, every: bool) {
        self.every_block = every;
    }

    /// Changes the resolution (validated); the grid is recreated at the next `prepare` when
    /// it differs.
    ///
    /// # Errors
    ///
    /// As [`SoftShadowNode::new`].
    pub fn set_size(&mut self, size: SoftShadowSize) -> Result<()> {
        size.validate()?;
        self.size = size;
        Ok(())
    }

    /// The grid's resolution.
    pub fn size(&self) -> SoftShadowSize {
        self.size
    }

    /// The grid (see the module docs); `None` before the first `prepare`.
    pub fn output(&self) -> Option<SoftShadow<'_>> {
        let texture = if self.marks {
            &self.marked
        } else {
            &self.texture
        };
        texture.as_ref().map(|texture| SoftShadow {
            texture,
            size: self.size,
            near: self.near,
            shafts: self.marks,
        })
    }
}

impl Node for SoftShadowNode {
    type Inputs<'a> = SoftShadowInputs<'a>;

    /// Validates the inputs, (re)creates the grid when its size changed and uploads the
    /// parameters. Returns whether the next [`encode`](Self::encode) rebuilds the grid: the
    /// shadow map's generation, the light, the occluders' bounds or the size changed now, or
    /// at an earlier `prepare` that no `encode` followed.
    ///
    /// # Errors
    ///
    /// [`Error::InvalidSetting`] naming `light` for a light without a radius or a directional
    /// light; [`Error::DeviceLimitExceeded`] naming `soft shadow list` for a grid whose build
    /// needs a list of cells larger than the device's storage buffers (at the core limit of
    /// 128 MiB, more than about 44 million cells); [`Error::InvalidTexture`] naming `shadow_map` for a shadow map
    /// whose layers or face matrices do not match the light.
    fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        inputs: &SoftShadowInputs<'_>,
    ) -> Result<bool> {
        let layers = validate(inputs)?;
        self.allocate(device, layers)?;
        self.bind(device, inputs.shadow_map);
        self.upload(queue, inputs, layers);
        let kind = inputs.light.model().gpu().kind;
        self.pipeline = self
            .pipelines
            .by_kind
            .iter()
            .find(|(k, _)| *k == kind)
            .map(|(_, build)| build.clone());
        Ok(self.pending)
    }
}

/// Checks the inputs (see [`SoftShadowNode::prepare`]); returns the light's shadow-map layers.
fn validate(inputs: &SoftShadowInputs<'_>) -> Result<u32> {
    let light = inputs.light;
    if !matches!(light.model().source(), Source::At(_)) {
        return Err(Error::InvalidSetting {
            field: "light",
            problem: "soft shadows need a point or spot light".into(),
        });
    }
    let layers = light.model().layers();
    if light.radius() <= 0.0 {
        return Err(Error::InvalidSetting {
            field: "light",
            problem: "soft shadows need a light with a radius > 0".into(),
        });
    }
    let map = inputs.shadow_map;
    check_depth_layers("shadow_map", map.texture, layers)?;
    map.check_back()?;
    map.check_triangles()?;
    if map.faces.len() != layers as usize {
        return Err(Error::InvalidTexture {
            field: "shadow_map",
            problem: format!(
                "has {} face matrices; this light needs {layers}",
                map.faces.len()
            ),
        });
    }
    for (i, m) in map.faces.iter().enumerate() {
        if !m.inverse().is_finite() {
            return Err(Error::InvalidTexture {
                field: "shadow_map",
                problem: format!("face matrix {i} is not invertible"),
            });
        }
    }
    Ok(layers)
}

impl SoftShadowNode {
    /// (Re)creates the grid and its scratch buffers when its size changed.
    fn allocate(&mut self, device: &wgpu::Device, layers: u32) -> Result<()> {
        let (n, s) = (self.size.directions, self.size.slices);
        let extent = (n, n, layers * s);
        if self
            .texture
            .as_ref()
            .is_none_or(|t| (t.width(), t.height(), t.depth_or_array_layers()) != extent)
        {
            let scratch = Scratch::new(device, n, layers, s)?;
            self.pending = true;
            self.stale = every_block(n, layers as usize);
            self.marked_current = false;
            let grid = |label| {
                texture_3d(
                    device,
                    label,
                    extent,
                    wgpu::TextureFormat::Rgba16Float,
                    // COPY_SRC: for reading the grid back (its tests compare each cell with
                    // the reference).
                    wgpu::TextureUsages::STORAGE_BINDING
                        | wgpu::TextureUsages::TEXTURE_BINDING
                        | wgpu::TextureUsages::COPY_SRC,
                )
            };
            self.texture = Some(grid("volshadow soft shadow build"));
            self.marked = Some(grid("volshadow soft shadow"));
            self.scratch = Some(scratch);
        }
        Ok(())
    }

    /// Binds the shadow map and the grid, building the bind groups when one of them changed.
    fn bind(&mut self, device: &wgpu::Device, map: ShadowMap<'_>) {
        let texture = self.texture.as_ref().expect("created above");
        let marked = self.marked.as_ref().expect("created with the grid");
        let scratch = self.scratch.as_ref().expect("created with the grid");
        self.pending |= self.shadow.bind(device, Some(&map));
        if self.bound.as_ref().is_none_or(|b| b.grid != *texture) {
            let groups = scratch.bind(
                device,
                &self.pipelines,
                [
                    self.uniform.binding(),
                    wgpu::BindingResource::TextureView(&texture.create_view(&Default::default())),
                ],
            );
            let mark = bind_group(
                device,
                "volshadow soft shadow marks",
                &self.pipelines.mark_layout,
                [
                    self.uniform.binding(),
                    wgpu::BindingResource::TextureView(&texture.create_view(&Default::default())),
                    wgpu::BindingResource::TextureView(&marked.create_view(&Default::default())),
                ],
            );
            self.bound = Some(Bound {
                grid: texture.clone(),
                groups,
                mark,
            });
            self.pending = true;
        }
    }

    /// Writes the parameters when they changed (or a build is pending), with the blocks the
    /// build covers.
    fn upload(&mut self, queue: &wgpu::Queue, inputs: &SoftShadowInputs<'_>, layers: u32) {
        let (light, map) = (inputs.light, inputs.shadow_map);
        let (n, s) = (self.size.directions, self.size.slices);
        // A build that marks shafts after one that did not copies every cell: the copy's
        // cells outside this build's blocks are the older build's.
        self.marks = map.gaps;
        if self.marks && !self.marked_current {
            self.stale = every_block(n, layers as usize);
            self.pending = true;
        }
        let mut world_from_clip = [[0.0; 16]; 6];
        for (i, m) in map.faces.iter().enumerate() {
            world_from_clip[i] = m.inverse().to_cols_array();
        }
        let mut shadow = ShadowUniform::new(light, &map, true);
        // A cell's angle: a layer's field of view (its projection's x scale is 1 / tan(half
        // the angle)) over its cells.
        shadow.soft.cell_angle = cell_angle(&map.faces[0], n);
        // The grid's cells take the filter's taps where the blockers' distance puts them:
        // with each tap following its line (`soft_filter`) in the cells too, the generator's
        // blinds (seed 401) are at p95 3.03%, not 2.97%, and the ground under the report's
        // soft scene at 4.90%, not 4.59% (tests/gpu/soft_grid.rs).
        shadow.soft.reproject = 0;
        self.near = shadow.soft.near(light.radius());
        let position = light.position().unwrap_or_default();
        let built = if self.every_block {
            every_block(n, layers as usize)
        } else {
            penumbra_blocks(
                map.faces,
                position,
                light.radius(),
                shadow.soft,
                &shadow.spheres,
                n,
            )
        };
        let mut value = SoftShadowUniform {
            world_from_clip,
            size: n,
            slices: s,
            layers,
            built,
            lit: self.uniform.last().map_or([[0; 4]; 6], |u| u.lit),
        };
        // The blocks to set lit follow from the last build, not from the inputs: they change
        // only with a build.
        self.pending |= self.uniform.last() != Some(&value);
        self.pending |= self.shadow.last() != Some(&shadow);
        self.pending |= self.generation != Some(map.generation);
        if self.pending {
            value.lit = self.stale;
            self.uniform.write(queue, value);
            self.shadow.write(queue, shadow);
        }
        self.built = built;
        self.generation = Some(map.generation);
        self.layers = layers;
    }
}

impl Encode for SoftShadowNode {
    /// Records the grid's build if [`prepare`](Self::prepare) found a change since the last
    /// build; otherwise records nothing.
    ///
    /// # Errors
    ///
    /// [`Error::NotPrepared`] before the first successful `prepare`, recording nothing.
    fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        timer: Option<&mut GpuTimer>,
    ) -> Result<()> {
        let (Some(Bound { groups, mark, .. }), Some(build), Some(shadow)) =
            (&self.bound, &self.pipeline, self.shadow.group())
        else {
            return Err(Error::NotPrepared {
                reason: "SoftShadowNode::prepare has not succeeded yet",
            });
        };
        if !std::mem::take(&mut self.pending) {
            return Ok(());
        }
        let scratch = self.scratch.as_ref().expect("created with the grid");
        // Every list starts empty, its dispatch 0 workgroups until a pass lists a cell.
        encoder.clear_buffer(&scratch.work_args, 0, None);
        // Blocks of 2 × 2 directions, 8 × 8 a workgroup, over the largest layer's rectangle
        // (the anchors' passes one block more each way).
        let a = self.size.directions.div_ceil(2);
        let groups_over = |blocks: &Blocks, more: u32| {
            let extent = |axis: usize| {
                blocks
                    .iter()
                    .filter(|r| r[2] > r[0] && r[3] > r[1])
                    .map(|r| (r[axis + 2] + more).min(a) - r[axis])
                    .max()
                    .unwrap_or(0)
                    .div_ceil(8)
            };
            (extent(0), extent(1), self.layers)
        };
        let timestamp_writes = timer.and_then(|t| t.compute_pass(Pass::SoftShadow));
        let mut pass = crate::gpu::passes::begin_compute(
            encoder,
            &wgpu::ComputePassDescriptor {
                label: Some("volshadow soft shadow"),
                timestamp_writes,
            },
        );
        let dispatch = |pass: &mut wgpu::ComputePass<'_>, (x, y, z): (u32, u32, u32)| {
            if x > 0 && y > 0 {
                pass.dispatch_workgroups(x, y, z);
            }
        };
        pass.set_bind_group(1, shadow, &[]);
        pass.set_pipeline(&build.fill);
        pass.set_bind_group(0, &groups.anchors, &[]);
        dispatch(&mut pass, groups_over(&self.stale, 0));
        // Each pass that fills a list is followed by the list's estimates.
        let passes = [
            (&build.anchors, &groups.anchors, Some(0), 1),
            (&build.between, &groups.between, Some(1), 1),
            (&build.store_anchors, &groups.store_anchors, None, 1),
            (&build.rest, &groups.rest, Some(2), 0),
            (&build.store_rest, &groups.store_rest, None, 0),
        ];
        for (pipeline, group, list, more) in passes {
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, group, &[]);
            dispatch(&mut pass, groups_over(&self.built, more));
            if let Some(list) = list {
                pass.set_pipeline(&build.estimate);
                pass.set_bind_group(0, &groups.estimates[list], &[]);
                pass.dispatch_workgroups_indirect(&scratch.work_args, list as u64 * LIST_SLOT);
            }
        }
        // The marked copy, 8 × 8 cells of a slice a workgroup (those outside the cells this
        // build may change return at once).
        if self.marks {
            pass.set_pipeline(&build.mark);
            pass.set_bind_group(0, mark, &[]);
            let n = self.size.directions.div_ceil(8);
            pass.dispatch_workgroups(n, n, self.layers * self.size.slices);
        }
        self.marked_current = self.marks;
        drop(pass);
        self.stale = self.built;
        Ok(())
    }
}

#[cfg(test)]
#[test]
fn params_layout_matches_the_wgsl() {
    use crate::nodes::layout::{assert_same, rust_layout};
    let rust = rust_layout!(SoftShadowUniform {
        built,
        lit,
        world_from_clip,
        size,
        slices,
        layers,
    });
    assert_same(rust, SOURCE.text, "SoftShadowParams");
}
