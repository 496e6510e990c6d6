//! The shadow-map node: occluder depth seen from the light.
//!
//! A point light gets a cube of six faces (+X, −X, +Y, −Y, +Z, −Z, 90° each), a spot light one
//! face covering its cone. Each face uses a reversed-Z infinite perspective projection
//! ([`ShadowMapNode::face_matrices`]): depth = near / (distance along the face's axis), so the
//! nearest occluder has the largest depth and nothing is clipped far away.
//!
//! A directional light gets cascaded orthographic maps (rendered by
//! [`ShadowMapNode::prepare`] (the camera in [`ShadowMapInputs`]); Engel 2006, "Cascaded shadow maps", ShaderX⁵; the
//! splits of Zhang et al. 2006, "Parallel-split shadow maps for large-scale virtual
//! environments"): the view depth from the eye to the light's
//! [shadow distance](crate::DirectionalLight::with_shadow_distance) is split into
//! [`cascades`](crate::DirectionalLight::with_cascades) ranges ([`ShadowMapNode::cascade_splits`]),
//! shorter near the eye, and each range gets one layer ([`ShadowMapNode::directional_matrix`])
//! fitted to the bounding sphere of the view pyramid's slice, so its size does not change as
//! the camera turns, with its centre snapped to whole texels in the light's frame, so that a
//! moving camera does not make the shadows' edges shimmer. Depth is reversed and linear along
//! the light's direction (1 at the side towards the light). A layer holds only the occluders
//! that can shadow its region (those whose box, seen along the direction, overlaps the
//! layer's square and begins before the region's far side), and its depth spans the region and
//! those occluders alone: an occluder beyond the region along the direction (a terrain
//! kilometres below) can shadow none of it and neither is drawn nor widens the range.
//!
//! A point takes the first layer whose square holds it (within a texel of the edge) and whose
//! far plane it is not beyond; it counts as lit where it lies in no layer's square; in a
//! square but beyond every such layer's far plane (beyond the shadow distance) it is compared
//! at the far plane of the last of them: shadowed where that layer holds an occluder. Its
//! depth bias is [`DIRECTIONAL_BIAS_TEXELS`] texels of its layer in world units, so it means
//! the same at every scale and range.
//!
//! # Output
//! [`ShadowMap`]: a `Depth32Float` 2D array texture, `resolution²`, 6 layers (point), 1
//! (spot) or one per cascade (directional), usages `RENDER_ATTACHMENT | TEXTURE_BINDING`,
//! cleared to 0 (nothing); plus the face matrices and the depth bias. A shadow map the caller renders itself can be passed to the
//! march instead, in the same layout and convention (any depth format that can be sampled).
//!
//! For a light with a radius the node also renders [`ShadowMap::back`]: the same faces again
//! with closed occluders' faces turned towards the light culled, which keeps each one's
//! nearest back face (open meshes, which have no inside, draw both sides: their nearest face).
//! The soft shadows take a blocker's distance between the two (between their midpoint and
//! their geometric mean), where a convex occluder's outline lies; the front surface alone is
//! nearer and made the deep penumbra up to
//! 41% too bright (see [`SoftShadowNode`](crate::nodes::SoftShadowNode)). It doubles the
//! pass's draws for such a light, less the cube faces no occluder's bounding sphere reaches:
//! their front layer holds no blocker, so their back layer is never read, and is not drawn.

use glam::{Mat4, Vec4};

use crate::error::{finite, Error, Result};
use crate::gpu::pipeline::bind_group;
use crate::gpu::Occluder;
use crate::light::Source;
use crate::nodes::shadow_gate::{arguments, Gate};
use crate::nodes::{Cache, Crossings, Node};
use crate::scene::{Camera, Light};

mod cascades;
mod draw;
mod pipelines;
mod spot;

pub(crate) use crate::nodes::groups::shadow_map::GROUP_BYTES;
pub use crate::nodes::groups::shadow_map::{ShadowMap, ShadowParams, MAX_EXACT_TRIANGLES};
pub use cascades::{CASCADE_RANGE, DIRECTIONAL_BIAS_TEXELS};
pub(crate) use pipelines::Pipelines;

use draw::{Draw, FAN};
use pipelines::{slot, FACE_BYTES, INSTANCE_BYTES, SLOT};

/// What the shadow map is rendered for.
#[derive(Clone, Copy)]
pub struct ShadowMapInputs<'a> {
    /// The light.
    pub light: &'a Light,
    /// The occluders.
    pub occluders: &'a [Occluder<'a>],
    /// The view: a directional light's map is fitted to what it sees (point and spot lights do
    /// not read it).
    pub camera: &'a Camera,
    /// `Some`: the map is read only where these crossing lists (of this frame, recorded
    /// before the map) cannot be counted: a list that overflowed, or a face of an open or
    /// non-manifold mesh (bit 31 of a pixel's count). The map is then drawn only in a frame
    /// with such a pixel, decided on the GPU, and not again until its inputs change; in any
    /// other frame it is left as it was and its texels are not all valid, so it must not be
    /// read elsewhere (the exact method's march, for a light without a radius, reads it only
    /// there). `None`: drawn whenever its inputs change.
    pub fallback: Option<Crossings<'a>>,
}

/// Shadow-map settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShadowMapSettings {
    /// Width and height of each face, in texels ([`ShadowMapSettings::MIN_RESOLUTION`] ..=
    /// device limit). Default 1024.
    pub resolution: u32,
    /// Relative depth bias: a point counts as lit while its distance from the light is below
    /// `(1 + bias)`-ish times the occluder's (exactly: depth ≥ stored · (1 − bias)). It is
    /// relative so it works at any scene scale. Default 2e-3; must be in [0, 0.5).
    pub depth_bias: f32,
    /// Keep every light's map whole, for shadowing the caller's surfaces with
    /// [`SHADOW_WGSL`](crate::SHADOW_WGSL) ([`VolumetricShadows::shadow_map`](crate::VolumetricShadows::shadow_map)).
    /// Default `false`: under the exact method a light without a radius draws its map only in
    /// a frame where a pixel's crossings cannot be counted (see
    /// [`LightPlan::map_on_demand`](crate::plan::LightPlan::map_on_demand)), usually none.
    pub surfaces: bool,
}

impl ShadowMapSettings {
    /// The smallest resolution accepted. Set by measurement (`tests/gpu/shadows.rs`: a sphere's
    /// shadow in fog under a point light, hybrid march, against the f64 reference): the p95
    /// relative error of the in-scatter is 1.2% at 32², within the 2% the hybrid march is held
    /// to, and 3.8% at 16², 7.8% at 8², 22% at 2² (0.67% at 64², 0.15% at 256², 0.11% at
    /// 1024²). A floor against broken settings, not a recommendation: an occluder that covers
    /// fewer texels needs more.
    pub const MIN_RESOLUTION: u32 = 32;
}

impl Default for ShadowMapSettings {
    fn default() -> Self {
        Self::DEFAULT
    }
}

impl ShadowMapSettings {
    /// The default: 1024² texels a layer, depth bias 2e-3, maps drawn only where the march
    /// reads them.
    pub const DEFAULT: ShadowMapSettings = ShadowMapSettings {
        resolution: 1024,
        depth_bias: 2e-3,
        surfaces: false,
    };
}

/// Renders the occluders' depth from the light. Re-renders only when the light, an occluder or
/// a transform changed since the last render.
pub struct ShadowMapNode {
    settings: ShadowMapSettings,
    pipelines: Pipelines,
    texture: Option<wgpu::Texture>,
    /// See [`ShadowMap::back`]: only for a light with a radius.
    back: Option<wgpu::Texture>,
    faces: Vec<Mat4>,
    bounds: Vec<Vec4>,
    planes: Vec<Vec4>,
    /// Per layer, whether `back` is drawn there: a cube face no occluder's bounding sphere
    /// reaches holds no blocker in the front layer, so its back layer is never read.
    back_layers: Vec<bool>,
    face_buffer: wgpu::Buffer,
    instance_buffer: Option<wgpu::Buffer>,
    bind_group: Option<wgpu::BindGroup>,
    draws: Vec<Draw>,
    key: Vec<u32>,
    pending: bool,
    /// Counts the renders `prepare` has planned (see [`ShadowMap::generation`]).
    generation: u64,
    /// Per layer, the occluders (indices into `draws`) drawn there: a directional light's
    /// cascades, those that can shadow its region; a point light's cube faces, those whose
    /// bounding sphere reaches the face (its light's [`layers_reached`](crate::light::LightModel::layers_reached)). `None`: every occluder in
    /// every layer.
    layer_draws: Option<Vec<Vec<u32>>>,
    /// Per layer of `texture`, whether it holds depth drawn since it was last cleared: a layer
    /// with nothing to draw that is already clear (a new texture reads as cleared: zero, at
    /// infinity) is neither cleared nor drawn again, and its lookups read lit.
    dirty: Vec<bool>,
    /// See [`ShadowMap::occluder_distance`].
    occluder_distance: f32,
    /// Whether the occluders may leave gaps (see [`ShadowMap::gaps`]).
    gaps: bool,
    /// See [`ShadowMap::triangles`], and per occluder its gather's bind group and workgroups.
    triangles: Option<wgpu::Buffer>,
    gathers: Vec<(wgpu::BindGroup, u32)>,
    /// The gate of a map drawn only where the crossings cannot be counted
    /// ([`ShadowMapInputs::fallback`]); `None` while the map is drawn whenever it changes.
    gate: Option<Gate>,
}

impl ShadowMapNode {
    /// Creates the node. Errors on a zero or too large resolution or a bias outside [0, 0.5).
    ///
    /// # Errors
    ///
    /// [`Error::InvalidSize`] for a zero resolution or one beyond the device's limits,
    /// [`Error::NonFinite`] or [`Error::InvalidSetting`] for a depth bias outside [0, 0.5).
    pub fn new(device: &wgpu::Device, cache: &Cache, settings: ShadowMapSettings) -> Result<Self> {
        let max = device.limits().max_texture_dimension_2d;
        let min = ShadowMapSettings::MIN_RESOLUTION;
        if settings.resolution < min || settings.resolution > max {
            return Err(Error::InvalidSize {
                field: "shadow map resolution",
                width: settings.resolution,
                height: settings.resolution,
                min,
                max,
            });
        }
        finite("shadow_map.depth_bias", &[settings.depth_bias])?;
        if !(0.0..0.5).contains(&settings.depth_bias) {
            return Err(Error::InvalidSetting {
                field: "shadow_map.depth_bias",
                problem: format!("must lie in [0, 0.5), got {}", settings.depth_bias),
            });
        }
        Ok(Self {
            settings,
            pipelines: cache.get::<Pipelines>(),
            texture: None,
            back: None,
            faces: Vec::new(),
            bounds: Vec::new(),
            back_layers: Vec::new(),
            planes: Vec::new(),
            face_buffer: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("volshadow shadow faces"),
                size: 6 * SLOT,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            instance_buffer: None,
            bind_group: None,
            draws: Vec::new(),
            key: Vec::new(),
            pending: false,
            generation: 0,
            layer_draws: None,
            dirty: Vec::new(),
            occluder_distance: 0.0,
            gaps: true,
            triangles: None,
            gathers: Vec::new(),
            gate: None,
        })
    }

    /// The face matrices this node uses for `light`, with near plane `near`: reversed-Z
    /// infinite perspective per face (90° cube faces, or the spot cone plus a small margin,
    /// widened for a light with a radius by the penumbra's reach beyond the cone: see
    /// [`spot_fov`](Self::spot_fov), with `occluder_distance` the least distance from the
    /// light to an occluder). None for a directional light, whose face depends on the camera
    /// ([`directional_matrix`](Self::directional_matrix)).
    pub fn face_matrices(light: &Light, near: f32, occluder_distance: f32) -> Vec<Mat4> {
        light.model().faces(near, occluder_distance)
    }

    fn prepare_for(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        inputs: &ShadowMapInputs<'_>,
        camera: Option<&Camera>,
    ) -> Result<bool> {
        let ShadowMapInputs {
            light, occluders, ..
        } = *inputs;
        for occluder in occluders {
            occluder.validate()?;
            occluder.check_device(device)?;
        }
        let needed = (occluders.len().max(1) as u64) * SLOT;
        crate::gpu::check_buffer_allocation(device, "occluder transforms", needed)?;
        let recreate = self.allocate(device, light, needed);
        // Re-render only when something the map depends on changed.
        let directional = match (light, camera) {
            (Light::Directional(l), Some(camera)) => {
                Some(self.directional_faces(l, camera, occluders))
            }
            _ => None,
        };
        let mut key = Self::key(light, occluders, directional.as_ref());
        // Switching between a gated map and one drawn whenever it changes re-renders it.
        key.push(u32::from(inputs.fallback.is_some()));
        let changed = recreate || key != self.key;
        if changed {
            self.key = key;
            self.place(light, occluders, directional);
            self.upload(device, queue, light, occluders);
            self.gather_triangles(device, light, occluders);
            self.pending = true;
            self.generation += 1;
        }
        let Some(crossings) = inputs.fallback else {
            self.gate = None;
            // Still pending when an earlier prepare's render was never encoded.
            return Ok(self.pending);
        };
        let gate = self
            .gate
            .get_or_insert_with(|| Gate::new(device, &self.pipelines.gate));
        if changed {
            // The layers a gated frame records: those with draws, and those that may hold an
            // earlier frame's depth (cleared when the gate opens). Which the GPU drew is not
            // known here, so a layer once drawn stays in the list.
            let mut layers = Vec::new();
            for layer in 0..self.faces.len() {
                let drawn: Vec<(u32, u32, u32)> = match self.layer_draws.as_ref() {
                    Some(l) => l.get(layer).map_or(&[][..], Vec::as_slice).to_vec(),
                    None => (0..self.draws.len() as u32).collect(),
                }
                .into_iter()
                .map(|i| {
                    let draw = &self.draws[i as usize];
                    let instances = if draw.clipped.is_some() { FAN } else { 1 };
                    (i, draw.index_count, instances)
                })
                .collect();
                let dirty = self.dirty.get_mut(layer);
                let was = dirty.as_deref().copied().unwrap_or(true);
                if drawn.is_empty() && !was {
                    continue;
                }
                if let Some(d) = dirty {
                    *d = true;
                }
                layers.push((layer as u32, drawn));
            }
            gate.set_arguments(device, queue, arguments(&layers));
        }
        gate.bind(device, queue, &crossings);
        // The scan runs every frame: only the GPU knows whether this one needs the map.
        Ok(true)
    }

    /// For benches and tests: a gated map's two `u32` (whether it was drawn since its inputs
    /// last changed, and whether the last recorded frame drew it), `None` for a map drawn
    /// whenever it changes ([`ShadowMapInputs::fallback`]).
    pub fn gate_state(&self) -> Option<&wgpu::Buffer> {
        Some(self.gate.as_ref()?.state())
    }

    /// (Re)creates the map (and its back faces' layer for a light with a radius) when its
    /// layers changed, and the occluders' transforms buffer when it is smaller than `needed`
    /// bytes. Returns whether the map was recreated.
    fn allocate(&mut self, device: &wgpu::Device, light: &Light, needed: u64) -> bool {
        let layers = light.model().layers();
        let resolution = self.settings.resolution;
        let map = |label| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width: resolution,
                    height: resolution,
                    depth_or_array_layers: layers,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::Depth32Float,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                    | wgpu::TextureUsages::TEXTURE_BINDING
                    | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            })
        };
        let wants_back = light.radius() > 0.0;
        let recreate = self
            .texture
            .as_ref()
            .is_none_or(|t| t.depth_or_array_layers() != layers)
            || wants_back != self.back.is_some();
        if recreate {
            self.texture = Some(map("volshadow shadow map"));
            self.back = wants_back.then(|| map("volshadow shadow map back faces"));
            // wgpu zero-initialises a texture before its first use: every layer reads clear.
            self.dirty = vec![false; layers as usize];
        }
        if self
            .instance_buffer
            .as_ref()
            .is_none_or(|b| b.size() < needed)
        {
            let buffer = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("volshadow shadow instances"),
                size: needed,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            self.bind_group = Some(bind_group(
                device,
                "volshadow shadow map",
                &self.pipelines.layout,
                [
                    slot(&self.face_buffer, FACE_BYTES),
                    slot(&buffer, INSTANCE_BYTES),
                ],
            ));
            self.instance_buffer = Some(buffer);
        }
        recreate
    }

    /// What the map depends on: the light's placement, the directional cascades' faces, the
    /// occluders' meshes and transforms.
    fn key(
        light: &Light,
        occluders: &[Occluder<'_>],
        directional: Option<&(Vec<Mat4>, Vec<Vec<u32>>)>,
    ) -> Vec<u32> {
        let bits = |v: &[f32]| v.iter().map(|f| f.to_bits()).collect::<Vec<u32>>();
        let mut key = match (light.position(), &directional) {
            (Some(p), _) => bits(&p.to_array()),
            (None, Some((faces, _))) => faces
                .iter()
                .flat_map(|f| bits(&f.to_cols_array()))
                .collect(),
            (None, None) => Vec::new(),
        };
        key.extend(light.model().map_key());
        for o in occluders {
            key.extend([o.mesh.id() as u32, (o.mesh.id() >> 32) as u32]);
            key.extend(bits(&o.transform.to_cols_array()));
        }
        key
    }

    /// The faces' matrices, the occluders' bounds and their separating planes for this light.
    fn place(
        &mut self,
        light: &Light,
        occluders: &[Occluder<'_>],
        directional: Option<(Vec<Mat4>, Vec<Vec<u32>>)>,
    ) {
        // The least distance from the light to an occluder's bounds, each in its own frame as
        // well as the world's (0 without occluders or with the light inside their bounds): a
        // spot map widens by it for a light with a radius (`spot_fov`).
        self.occluder_distance = match light.position() {
            Some(p) => occluders
                .iter()
                .map(|o| o.distance_lower_bound(p))
                .fold(f32::INFINITY, f32::min),
            None => 0.0,
        };
        if !self.occluder_distance.is_finite() {
            self.occluder_distance = 0.0;
        }

        // Near plane: half the distance to the nearest occluder's bounds, or less for a wide
        // spot cone (measured along the axis, an occluder near the frustum's edge is nearer
        // than its distance: a 165° cone clipped a sphere 84° off axis), so every occluder is
        // in front of it. Depth is near / distance in f32 (reversed Z), whose relative
        // precision is the same at every distance, so a tiny near plane costs nothing: no
        // floor relative to the scene's size (a terrain-sized occluder elsewhere would push
        // it past a small occluder next to the light). When the light is inside an occluder's
        // bounds the distance is 0; then a floor of about one f32 step of the light's
        // coordinates (nothing nearer can be placed) keeps the projection finite.
        self.bounds = occluders.iter().map(|o| o.world_sphere()).collect();
        if let Some((faces, drawn)) = directional {
            self.faces = faces;
            self.layer_draws = Some(drawn);
        } else {
            self.layer_draws = light.model().layer_draws(&self.bounds);
            let p = light.position().unwrap_or_default();
            let along_axis = (0.9 * Self::corner_cosine(light, self.occluder_distance)).min(0.5);
            let mut near = f32::INFINITY;
            for o in occluders {
                near = near.min(along_axis * o.distance_lower_bound(p));
            }
            let floor = 1e-7 * p.abs().max_element().max(1e-3);
            let near = if near.is_finite() {
                near.max(floor)
            } else {
                floor
            };
            self.faces = Self::face_matrices(light, near, self.occluder_distance);
        }
        self.gaps = occluders.len() > 1 || occluders.iter().any(|o| !o.mesh.is_convex());
        self.back_layers = match light.model().layers_reached(&self.bounds) {
            Some(reached) => reached.to_vec(),
            None => vec![true; self.faces.len()],
        };
        self.planes = occluders
            .iter()
            .map(|o| {
                light
                    .position()
                    .map_or(Vec4::ZERO, |p| o.separating_plane(p, light.radius()))
            })
            .collect();
    }

    /// Lists the gathers of [`ShadowMap::triangles`] where the soft shadows take them (a point
    /// or spot light with a radius, occluders that may leave gaps, at most
    /// [`MAX_EXACT_TRIANGLES`] in all), each occluder's in groups of four.
    fn gather_triangles(
        &mut self,
        device: &wgpu::Device,
        light: &Light,
        occluders: &[Occluder<'_>],
    ) {
        self.gathers.clear();
        let groups = |o: &Occluder<'_>| o.mesh.triangle_count.div_ceil(4);
        let total: u64 = occluders.iter().map(|o| u64::from(groups(o))).sum();
        let wanted = light.radius() > 0.0
            && light.position().is_some()
            && self.gaps
            && total > 0
            && 4 * total <= u64::from(MAX_EXACT_TRIANGLES);
        if !wanted {
            self.triangles = None;
            return;
        }
        let size = total * GROUP_BYTES;
        if self.triangles.as_ref().is_none_or(|b| b.size() != size) {
            self.triangles = Some(device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("volshadow occluder triangles"),
                size,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }));
        }
        let (Some(triangles), Some(instances)) = (&self.triangles, &self.instance_buffer) else {
            return;
        };
        let mut first = 0u64;
        for (i, o) in occluders.iter().enumerate() {
            let count = groups(o);
            let range = u64::from(count) * GROUP_BYTES;
            let group = bind_group(
                device,
                "volshadow occluder triangles",
                &self.pipelines.gather_layout,
                [
                    wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: instances,
                        offset: i as u64 * SLOT,
                        size: wgpu::BufferSize::new(64),
                    }),
                    o.mesh.positions.as_entire_binding(),
                    o.mesh.indices.as_entire_binding(),
                    wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: triangles,
                        offset: first,
                        size: wgpu::BufferSize::new(range),
                    }),
                ],
            );
            self.gathers.push((group, count.div_ceil(64)));
            first += range;
        }
    }
    /// The shadow map for the march (`None` before the first `prepare`).
    pub fn shadow_map(&self) -> Option<ShadowMap<'_>> {
        Some(ShadowMap {
            texture: self.texture.as_ref()?,
            back: self.back.as_ref(),
            faces: &self.faces,
            depth_bias: self.settings.depth_bias,
            bounds: &self.bounds,
            planes: &self.planes,
            occluder_distance: self.occluder_distance,
            gaps: self.gaps,
            triangles: self.triangles.as_ref(),
            generation: self.generation,
        })
    }
}

impl Node for ShadowMapNode {
    type Inputs<'a> = ShadowMapInputs<'a>;

    /// Validates the occluders and decides whether the map must be re-rendered. Returns
    /// whether the next [`encode`](crate::nodes::Encode::encode) will render. A directional light's
    /// orthographic map is fitted to what `inputs.camera` sees up to the light's
    /// [shadow distance](crate::DirectionalLight::with_shadow_distance), or, without one, up to the
    /// farthest corner of the occluders' bounds (see [`directional_matrix`](Self::directional_matrix)),
    /// and re-renders only when the fitted map moved by a texel, the light or an occluder
    /// changed; point and spot lights do not read the camera.
    ///
    /// # Errors
    ///
    /// [`Error::NonFinite`] or [`Error::SingularMatrix`] for an occluder's transform.
    fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        inputs: &ShadowMapInputs<'_>,
    ) -> Result<bool> {
        // Only a direction-like light's faces are fitted to the camera.
        let camera =
            matches!(inputs.light.model().source(), Source::Along(_)).then_some(inputs.camera);
        self.prepare_for(device, queue, inputs, camera)
    }
}
#[cfg(test)]
pub(crate) mod tests {
    /// Seeded numbers uniform in [−1, 1) (xorshift64).
    pub(crate) fn uniform(mut seed: u64) -> impl FnMut() -> f32 {
        move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f32 / (1u64 << 53) as f32 * 2.0 - 1.0
        }
    }
}
