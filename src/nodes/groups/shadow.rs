//! The light and its shadow map as the shared shadow-map visibility reads them
//! (`shaders/shared/pcss.wgsl`): bind group 1 of the march's and the soft-shadow grid's pipelines.
//! The WGSL file declares the group; this module builds its layout, its parameters
//! ([`ShadowUniform`]) and its bind group ([`ShadowBinding`]) for both, and a light with a
//! radius as both read it ([`SoftLight`], [`soft_params`], [`cell_angle`]).

use bytemuck::{Pod, Zeroable};

use super::shadow_map::{ShadowMap, GROUP_BYTES};
use crate::gpu::pipeline::{bind_group, layout, Binding};
use crate::gpu::{depth_array_view, texture_2d, UniformBuffer};
use crate::light::LightUniform;
use crate::scene::Light;

/// Group 1's binding table (`shaders/shared/pcss.wgsl`).
const BINDINGS: [Binding; 6] = [
    Binding::Params,      // shadow
    Binding::DepthArray,  // shadow_map
    Binding::DepthArray,  // shadow_back
    Binding::Comparison,  // shadow_sampler
    Binding::Params,      // soft_triangles
    Binding::UintTexture, // soft_masks
];

/// Directions `soft_exact` (`shaders/shared/pcss.wgsl`) tests over the light's disc: 8 rings of 32,
/// one `u32` of bits each.
pub(crate) const EXACT_SAMPLES: usize = 256;
/// The half-plane table's angles (of the line's normal, over a turn) and offsets (over
/// `[−1, 1]`, in units of the disc's radius): `soft_masks` in `shaders/shared/pcss.wgsl`.
pub(crate) const MASK_ANGLES: u32 = 256;
pub(crate) const MASK_OFFSETS: u32 = 128;

/// The directions of `soft_exact` as points of the unit disc: a golden-angle spiral, equal
/// areas (Vogel 1979), so that direction `i` lies in ring `i / 32` of 8 rings of equal area.
pub(crate) fn exact_samples() -> Vec<[f64; 2]> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..EXACT_SAMPLES)
        .map(|i| {
            let r = ((i as f64 + 0.5) / EXACT_SAMPLES as f64).sqrt();
            let phi = golden * i as f64;
            [r * phi.cos(), r * phi.sin()]
        })
        .collect()
}

/// The half-plane table (bitmask soft shadows, Schwarz and Stamminger 2007): for the line
/// with normal angle `β_k = 2π(k + ½)/MASK_ANGLES` and offset `c_j = −1 + 2(j + ½)/MASK_OFFSETS`,
/// bit `i` of word `w` (direction `32w + i` of [`exact_samples`]) set where `n·q ≥ c`. Row
/// `k`, two `Rgba32Uint` texels `2j` (words 0–3) and `2j + 1` (words 4–7).
pub(crate) fn half_plane_masks() -> &'static [u32] {
    static MASKS: std::sync::OnceLock<Vec<u32>> = std::sync::OnceLock::new();
    MASKS.get_or_init(build_half_plane_masks)
}

fn build_half_plane_masks() -> Vec<u32> {
    let samples = exact_samples();
    let mut out = Vec::with_capacity((MASK_ANGLES * MASK_OFFSETS * 8) as usize);
    for k in 0..MASK_ANGLES {
        let beta = std::f64::consts::TAU * (f64::from(k) + 0.5) / f64::from(MASK_ANGLES);
        let (sin, cos) = beta.sin_cos();
        for j in 0..MASK_OFFSETS {
            let c = -1.0 + 2.0 * (f64::from(j) + 0.5) / f64::from(MASK_OFFSETS);
            let mut words = [0u32; 8];
            for (i, q) in samples.iter().enumerate() {
                if cos * q[0] + sin * q[1] >= c {
                    words[i / 32] |= 1 << (i % 32);
                }
            }
            out.extend(words);
        }
    }
    out
}

/// Group 1's layout, for a pipeline layout's second entry.
pub(crate) fn shadow_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    layout(
        device,
        "volshadow light and shadow map",
        wgpu::ShaderStages::COMPUTE,
        &BINDINGS,
    )
}

/// WGSL `LightShadow` (`shaders/shared/pcss.wgsl`), field by field.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub(crate) struct ShadowUniform {
    pub light: LightUniform,
    pub faces: [[f32; 16]; 6],
    pub spheres: [[f32; 4]; MAX_SOFT_SPHERES],
    pub planes: [[f32; 4]; MAX_SOFT_SPHERES],
    pub depth_bias: f32,
    pub cube_near: f32,
    pub soft: SoftLight,
}

impl ShadowUniform {
    /// `light` with no shadow map: its description only.
    pub fn unshadowed(light: &Light) -> Self {
        Self {
            light: LightUniform::new(light),
            ..Self::zeroed()
        }
    }

    /// `light` with its shadow `map`, and with `soft` the soft estimate's constants (a light
    /// with a radius).
    pub fn new(light: &Light, map: &ShadowMap<'_>, soft: bool) -> Self {
        let mut out = Self::unshadowed(light);
        for (slot, face) in out.faces.iter_mut().zip(map.faces) {
            *slot = face.to_cols_array();
        }
        out.depth_bias = map.depth_bias;
        out.cube_near = light.model().cube_near(map.faces);
        if soft {
            (out.soft, out.spheres, out.planes) = soft_params(light, map);
        }
        out
    }
}

/// One node's group 1: the parameters, the comparison sampler, and the bind group with the
/// shadow map it was made for (rebuilt only when the map changes).
pub(crate) struct ShadowBinding {
    layout: wgpu::BindGroupLayout,
    uniform: UniformBuffer<ShadowUniform>,
    sampler: wgpu::Sampler,
    /// Bound in place of a shadow map where there is none.
    dummy: wgpu::Texture,
    /// Bound in place of the occluders' triangles where the map has none (one empty group).
    no_triangles: wgpu::Buffer,
    /// The half-plane table ([`half_plane_masks`]), written at the first [`write`](Self::write).
    masks: wgpu::Texture,
    masks_written: bool,
    bound: Option<(wgpu::Texture, wgpu::Texture, wgpu::Buffer, wgpu::BindGroup)>,
}

impl ShadowBinding {
    /// `layout` is the pipelines' group-1 layout ([`shadow_layout`]).
    pub fn new(device: &wgpu::Device, layout: &wgpu::BindGroupLayout, label: &str) -> Self {
        Self {
            layout: layout.clone(),
            uniform: UniformBuffer::new(device, label),
            sampler: device.create_sampler(&wgpu::SamplerDescriptor {
                label: Some("volshadow shadow compare"),
                mag_filter: wgpu::FilterMode::Linear,
                min_filter: wgpu::FilterMode::Linear,
                compare: Some(wgpu::CompareFunction::GreaterEqual),
                ..Default::default()
            }),
            dummy: texture_2d(
                device,
                "volshadow no shadow map",
                (1, 1, 1),
                wgpu::TextureFormat::Depth32Float,
                wgpu::TextureUsages::TEXTURE_BINDING,
            ),
            no_triangles: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("volshadow no occluder triangles"),
                size: GROUP_BYTES,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            }),
            masks: texture_2d(
                device,
                "volshadow half-plane masks",
                (2 * MASK_OFFSETS, MASK_ANGLES, 1),
                wgpu::TextureFormat::Rgba32Uint,
                wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            ),
            masks_written: false,
            bound: None,
        }
    }

    /// Binds `map` (none: a 1×1 stand-in); returns whether the bind group was rebuilt.
    pub fn bind(&mut self, device: &wgpu::Device, map: Option<&ShadowMap<'_>>) -> bool {
        let front = map.map_or(&self.dummy, |m| m.texture);
        let back = map.and_then(|m| m.back).unwrap_or(front);
        let triangles = map.and_then(|m| m.triangles).unwrap_or(&self.no_triangles);
        if self
            .bound
            .as_ref()
            .is_some_and(|(f, b, t, _)| f == front && b == back && t == triangles)
        {
            return false;
        }
        let group = bind_group(
            device,
            "volshadow light and shadow map",
            &self.layout,
            [
                self.uniform.binding(),
                wgpu::BindingResource::TextureView(&depth_array_view(front)),
                wgpu::BindingResource::TextureView(&depth_array_view(back)),
                wgpu::BindingResource::Sampler(&self.sampler),
                triangles.as_entire_binding(),
                wgpu::BindingResource::TextureView(&self.masks.create_view(&Default::default())),
            ],
        );
        self.bound = Some((front.clone(), back.clone(), triangles.clone(), group));
        true
    }

    /// Writes `value` unless it is the last one written; returns whether it wrote.
    pub fn write(&mut self, queue: &wgpu::Queue, value: ShadowUniform) -> bool {
        if !self.masks_written {
            queue.write_texture(
                self.masks.as_image_copy(),
                bytemuck::cast_slice(half_plane_masks()),
                wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(2 * MASK_OFFSETS * 16),
                    rows_per_image: None,
                },
                self.masks.size(),
            );
            self.masks_written = true;
        }
        self.uniform.write(queue, value)
    }

    /// The last parameters written.
    pub fn last(&self) -> Option<&ShadowUniform> {
        self.uniform.last()
    }

    /// The bind group of the last [`bind`](Self::bind).
    pub fn group(&self) -> Option<&wgpu::BindGroup> {
        self.bound.as_ref().map(|(_, _, _, g)| g)
    }
}

/// Most occluder bounding spheres the soft shadow tests a point against; more are merged into
/// one sphere around them all.
pub(crate) const MAX_SOFT_SPHERES: usize = 8;

/// The soft shadow's constants: `[radius, least distance from the light to an occluder (its
/// bounding box, or sphere; at least the radius), number of spheres, 0]`, the spheres (see [`ShadowMap::bounds`])
/// and their planes ([`ShadowMap::planes`]; zero, none, for spheres merged into one).
pub(crate) fn soft_params(
    light: &Light,
    map: &ShadowMap<'_>,
) -> (
    SoftLight,
    [[f32; 4]; MAX_SOFT_SPHERES],
    [[f32; 4]; MAX_SOFT_SPHERES],
) {
    let bounds = map.bounds;
    let mut spheres = [[0.0; 4]; MAX_SOFT_SPHERES];
    let mut planes = [[0.0; 4]; MAX_SOFT_SPHERES];
    let p = light.position().unwrap_or_default();
    // The grid's slices start at the occluders' bounding boxes (where known), not at their
    // tighter spheres: on the seeded spot scenes of the tests, slices from the spheres left
    // the views lit by a deep penumbra worse (p95 up to 8.1% against 7.5%).
    let nearest = if map.occluder_distance > 0.0 {
        map.occluder_distance
    } else {
        bounds
            .iter()
            .map(|b| (b.truncate().distance(p) - b.w).max(0.0))
            .fold(f32::INFINITY, f32::min)
    };
    let count = if bounds.len() <= MAX_SOFT_SPHERES {
        for (slot, b) in spheres.iter_mut().zip(bounds) {
            *slot = b.to_array();
        }
        for (slot, plane) in planes.iter_mut().zip(map.planes) {
            *slot = plane.to_array();
        }
        bounds.len()
    } else {
        let lo = bounds
            .iter()
            .fold(glam::Vec3::INFINITY, |a, b| a.min(b.truncate() - b.w));
        let hi = bounds
            .iter()
            .fold(glam::Vec3::NEG_INFINITY, |a, b| a.max(b.truncate() + b.w));
        let c = 0.5 * (lo + hi);
        let r = bounds
            .iter()
            .map(|b| b.truncate().distance(c) + b.w)
            .fold(0.0, f32::max);
        spheres[0] = c.extend(r).to_array();
        1
    };
    // At least the light's radius: a point inside the light's sphere sees all of it (the
    // model's convention), and the grid's slices and the blocker search, which reach from
    // `nearest` out, would otherwise spread over a light with an occluder's bounds around it.
    let nearest = if nearest.is_finite() { nearest } else { 0.0 }.max(light.radius());
    (
        SoftLight {
            nearest,
            spheres: count as u32,
            cell_angle: 0.0,
            reproject: u32::from(map.gaps),
            groups: map.triangle_groups(),
        },
        spheres,
        planes,
    )
}

/// WGSL `SoftLight` (`shaders/shared/pcss.wgsl`): a light with a radius as the soft estimate reads
/// it, in the march's and the grid's parameters.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct SoftLight {
    /// The least distance from the light of any occluder's bounds (at least the radius).
    pub nearest: f32,
    /// Bounding spheres (and planes) given beside it.
    pub spheres: u32,
    /// The grid's cells: the angle (radians) one subtends at a layer's centre; 0 in the march.
    pub cell_angle: f32,
    /// 1 where the shadow map's occluders may leave gaps ([`ShadowMap::gaps`]), outside the
    /// grid's build: each of the filter's taps moves to where its line crosses its own
    /// blocker's distance (`soft_filter` in `shaders/shared/pcss.wgsl`); else 0.
    pub reproject: u32,
    /// The groups of four of the occluders' triangles the exact visible fraction reads
    /// ([`ShadowMap::triangles`], `soft_exact` in `shaders/shared/pcss.wgsl`); 0: the estimate from
    /// the shadow map.
    pub groups: u32,
}

impl SoftLight {
    /// The grid's least distance from a light of `radius`, as the shaders take it
    /// (`soft_estimate`).
    pub fn near(&self, radius: f32) -> f32 {
        self.nearest.max(1.0e-3 * radius)
    }
}

/// The angle (radians) a grid cell subtends at the centre of a layer of `directions` cells
/// whose `clip_from_world` is `face`.
pub(crate) fn cell_angle(face: &glam::Mat4, directions: u32) -> f32 {
    let scale = face.row(0).truncate().length();
    2.0 * (1.0 / scale).atan() / directions as f32
}

#[cfg(test)]
#[test]
fn the_shadow_parameters_match_the_wgsl() {
    use crate::nodes::layout::{assert_same, rust_layout};
    let source = "#import pcss.wgsl";
    let rust = rust_layout!(ShadowUniform {
        light,
        faces,
        spheres,
        planes,
        depth_bias,
        cube_near,
        soft,
    });
    assert_same(rust, source, "LightShadow");
    let soft = rust_layout!(SoftLight {
        nearest,
        spheres,
        cell_angle,
        reproject,
        groups,
    });
    assert_same(soft, source, "SoftLight");
}

/// The directions of `soft_exact` and its half-plane table. Each ring of 32 directions lies in
/// its eighth of the disc's area (`soft_exact` weighs the rings by their solid angles), and
/// each table entry holds as many directions as the disc's segment beyond its line holds
/// area, to within the spiral's discrepancy: measured over the whole table (deterministic, in
/// f64), at most 0.0178 of the directions off the segment's area fraction, bar 0.02. Broken
/// variants fail it: the entries' side of the line flipped (`≤ c`: 0.9996 off), each offset
/// taken at its bin's edge rather than its centre (0.0210 off), directions uniform in radius
/// rather than in area (direction 32 out of its ring).
#[cfg(test)]
#[test]
fn the_exact_directions_and_their_half_planes() {
    const BAR: f64 = 0.02;
    let samples = exact_samples();
    for (i, q) in samples.iter().enumerate() {
        let r2 = q[0] * q[0] + q[1] * q[1];
        let ring = (i / 32) as f64;
        assert!(
            (ring / 8.0..(ring + 1.0) / 8.0).contains(&r2),
            "direction {i}: r² {r2} outside ring {ring}"
        );
    }
    let masks = half_plane_masks();
    let mut worst = 0.0f64;
    for k in 0..MASK_ANGLES as usize {
        for j in 0..MASK_OFFSETS as usize {
            let c = -1.0 + 2.0 * (j as f64 + 0.5) / f64::from(MASK_OFFSETS);
            let area = (c.acos() - c * (1.0 - c * c).sqrt()) / std::f64::consts::PI;
            let at = (k * MASK_OFFSETS as usize + j) * 8;
            let count: u32 = masks[at..at + 8].iter().map(|w| w.count_ones()).sum();
            worst = worst.max((f64::from(count) / EXACT_SAMPLES as f64 - area).abs());
        }
    }
    eprintln!("half-plane table: worst |directions − area| {worst:.4} (bar {BAR})");
    assert!(
        worst <= BAR,
        "half-plane table off by {worst:.4} (bar {BAR})"
    );
}

/// `soft_exact`'s loop budget in `shaders/shared/pcss.wgsl` is one turn over the most triangles the
/// shadow-map node gathers, in groups of four: a larger budget would let a sliver's extra
/// turns take a call past what `MAX_EXACT_TRIANGLES` was sized for (llvmpipe's loop limit).
/// And the WGSL's directions and offsets are the table's.
#[cfg(test)]
#[test]
fn the_exact_constants_match_the_wgsl() {
    crate::nodes::layout::assert_constants(
        "#import pcss.wgsl",
        &[
            (
                "EXACT_BUDGET",
                crate::nodes::groups::shadow_map::MAX_EXACT_TRIANGLES / 4,
            ),
            ("EXACT_SAMPLES", EXACT_SAMPLES as u32),
            ("MASK_OFFSETS", MASK_OFFSETS),
        ],
    );
}
