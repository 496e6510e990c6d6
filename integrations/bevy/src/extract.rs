//! From Bevy's main world to the render world: occluder meshes converted once per asset (in
//! the main world, where the asset is), and per entity, by Bevy's component extraction, each
//! camera's medium, each light and each occluder's mesh and transform.

use std::collections::{HashMap, HashSet};
use std::sync::Arc;

use bevy::asset::{AssetEvent, AssetId, Assets};
use bevy::camera::visibility::{InheritedVisibility, RenderLayers};
use bevy::camera::{Camera, Exposure};
use bevy::ecs::message::MessageReader;
use bevy::ecs::prelude::*;
use bevy::ecs::query::QueryItem;
use bevy::image::Image;
use bevy::light::{DirectionalLight, PointLight, SpotLight, SpotLightTexture};
use bevy::mesh::{Mesh, Mesh3d, PrimitiveTopology};
use bevy::render::extract_component::ExtractComponent;
use bevy::render::sync_component::SyncComponent;
use bevy::render::RenderApp;
use bevy::transform::components::GlobalTransform;
use volshadow::glam;

use crate::render::ViewVolshadow;
use crate::{exposure_of, VolshadowLight, VolshadowMedium, VolshadowOccluder, VolshadowSurfaces};

/// A mesh asset as volshadow's mesh, or why it cannot occlude.
type Converted = Result<Arc<volshadow::scene::Mesh>, String>;

/// The occluder meshes in use, converted once per mesh asset (and again when it changes).
#[derive(Resource, Clone, Default)]
pub struct OccluderSources {
    /// Per mesh asset: its generation (new on every conversion) and the mesh, or why it cannot
    /// occlude.
    pub(crate) meshes: HashMap<AssetId<Mesh>, (u64, Converted)>,
    next_generation: u64,
}

impl OccluderSources {
    /// Why the mesh asset `id` cannot be an occluder, if it was converted and failed.
    pub fn error(&self, id: AssetId<Mesh>) -> Option<&str> {
        self.meshes.get(&id)?.1.as_ref().err().map(String::as_str)
    }
}

/// A Bevy mesh as volshadow's triangle mesh.
fn convert(mesh: &Mesh) -> Result<volshadow::scene::Mesh, String> {
    if mesh.primitive_topology() != PrimitiveTopology::TriangleList {
        return Err(format!(
            "an occluder must be a triangle list, this mesh is a {:?}",
            mesh.primitive_topology()
        ));
    }
    let positions = mesh
        .try_attribute(Mesh::ATTRIBUTE_POSITION)
        .map_err(|e| format!("its positions cannot be read: {e}"))?
        .as_float3()
        .ok_or("its positions are not Float32x3")?;
    let positions: Vec<glam::Vec3> = positions.iter().map(|p| glam::Vec3::from(*p)).collect();
    let indices: Vec<u32> = match mesh.try_indices() {
        Ok(indices) => indices
            .iter()
            .map(|i| u32::try_from(i).map_err(|_| format!("index {i} does not fit in u32")))
            .collect::<Result<_, _>>()?,
        Err(_) => (0..u32::try_from(positions.len()).map_err(|_| "too many vertices")?).collect(),
    };
    volshadow::scene::Mesh::new(&positions, &indices).map_err(|e| e.to_string())
}

/// Converts the mesh of every occluder not yet converted, again when its asset changed, and
/// forgets meshes no occluder uses.
pub(crate) fn track_occluder_meshes(
    mut events: MessageReader<AssetEvent<Mesh>>,
    occluders: Query<&Mesh3d, With<VolshadowOccluder>>,
    assets: Res<Assets<Mesh>>,
    mut sources: ResMut<OccluderSources>,
) {
    for event in events.read() {
        if let AssetEvent::Modified { id } | AssetEvent::Removed { id } = event {
            if sources.meshes.contains_key(id) {
                sources.meshes.remove(id);
            }
        }
    }
    let used: HashSet<AssetId<Mesh>> = occluders.iter().map(|m| m.id()).collect();
    if sources.meshes.keys().any(|id| !used.contains(id)) {
        sources.meshes.retain(|id, _| used.contains(id));
    }
    for id in used {
        if sources.meshes.contains_key(&id) {
            continue;
        }
        let Some(mesh) = assets.get(id) else {
            continue; // not loaded yet
        };
        let converted = convert(mesh).map(Arc::new);
        if let Err(why) = &converted {
            bevy::log::error!("volshadow: mesh {id} cannot occlude: {why}");
        }
        sources.next_generation += 1;
        let generation = sources.next_generation;
        sources.meshes.insert(id, (generation, converted));
    }
}

/// A light as Bevy describes it, before the camera's exposure.
#[derive(Clone, Copy, Debug)]
pub(crate) enum SourceLight {
    Point {
        position: glam::Vec3,
        /// Linear colour times lumens.
        flux: glam::Vec3,
        radius: f32,
    },
    Spot {
        position: glam::Vec3,
        direction: glam::Vec3,
        /// The transform's up: a [`SpotLightTexture`]'s frame turns with it, as Bevy's does.
        up: glam::Vec3,
        outer_angle: f32,
        flux: glam::Vec3,
        radius: f32,
    },
    Directional {
        direction: glam::Vec3,
        /// Linear colour times lux.
        illuminance: glam::Vec3,
    },
}

impl SourceLight {
    /// Whether the light emits nothing.
    fn is_dark(&self) -> bool {
        let emitted = match self {
            SourceLight::Point { flux, .. } | SourceLight::Spot { flux, .. } => *flux,
            SourceLight::Directional { illuminance, .. } => *illuminance,
        };
        emitted == glam::Vec3::ZERO
    }

    /// How much this light can add to a view from `eye` through a medium of scattering `σs`
    /// and extinction `σt` (per unit, the channels' means), to rank lights when more light
    /// the medium than volshadow takes: the brightest unshadowed single scattering along a
    /// ray from the eye, phase function and cone left out.
    ///
    /// * Point and spot lights of intensity `I` at distance `d`: a ray passing the light at
    ///   distance `d` gathers `σs·I·∫ds/(d² + s²) = σs·I·π/(2d)`, and the light's extinction
    ///   to the eye, `e^(−σt·d)`, scales it. (The ray straight at the light gathers more, but
    ///   in that one pixel; `π/(2d)` is what the rays around it see.)
    /// * Directional lights of irradiance `E`: an infinite ray gathers `σs·E/σt`.
    ///
    /// The light's colour counts by the sum of its channels.
    pub(crate) fn contribution(&self, eye: glam::Vec3, sigma_s: f32, sigma_t: f32) -> f32 {
        let sum = |v: glam::Vec3| v.element_sum();
        match *self {
            SourceLight::Point { position, flux, .. }
            | SourceLight::Spot { position, flux, .. } => {
                let d = position.distance(eye).max(f32::MIN_POSITIVE);
                let intensity = sum(flux) / (4.0 * std::f32::consts::PI);
                sigma_s * intensity * std::f32::consts::FRAC_PI_2 / d * (-sigma_t * d).exp()
            }
            SourceLight::Directional { illuminance, .. } => {
                sigma_s * sum(illuminance) / sigma_t.max(f32::MIN_POSITIVE)
            }
        }
    }

    /// volshadow's light for a camera whose shading multiplies light by `exposure`.
    pub(crate) fn to_volshadow(self, exposure: f32) -> volshadow::Result<volshadow::Light> {
        let per_steradian = exposure / (4.0 * std::f32::consts::PI);
        Ok(match self {
            SourceLight::Point {
                position,
                flux,
                radius,
            } => volshadow::PointLight::new(position, flux * per_steradian)?
                .with_radius(radius)?
                .into(),
            SourceLight::Spot {
                position,
                direction,
                up,
                outer_angle,
                flux,
                radius,
            } => volshadow::SpotLight::new(
                position,
                direction,
                (2.0 * outer_angle).min(volshadow::SpotLight::MAX_CONE_ANGLE),
                flux * per_steradian,
            )?
            .with_radius(radius)?
            .with_texture_up(up)?
            .into(),
            SourceLight::Directional {
                direction,
                illuminance,
            } => volshadow::DirectionalLight::new(direction, illuminance * exposure)?.into(),
        })
    }
}

/// A camera's medium and exposure on its render-world view.
#[derive(Component, Clone, Debug)]
pub struct ExtractedVolshadowView {
    pub(crate) medium: VolshadowMedium,
    pub(crate) exposure: f32,
    /// The part of its target it renders into, when not all of it: physical origin and size,
    /// and the depth range.
    pub(crate) viewport: Option<bevy::camera::Viewport>,
    /// The camera's render layers (Bevy's default, layer 0, without the component): the view
    /// takes the lights whose layers share one with them.
    pub(crate) layers: RenderLayers,
    /// The camera's [`VolshadowSurfaces`], when the medium's light on its surfaces is drawn.
    pub(crate) surfaces: Option<VolshadowSurfaces>,
}

/// A camera's volshadow state lives on its render-world view: its extracted medium and its
/// [`ViewVolshadow`] (the facade and resolved depth), both dropped with the medium or the view.
impl SyncComponent<RenderApp> for VolshadowMedium {
    type Target = (ExtractedVolshadowView, ViewVolshadow);
}

impl ExtractComponent<RenderApp> for VolshadowMedium {
    type QueryData = (
        &'static VolshadowMedium,
        &'static Camera,
        Option<&'static Exposure>,
        Option<&'static RenderLayers>,
        Option<&'static VolshadowSurfaces>,
    );
    type QueryFilter = ();
    type Out = ExtractedVolshadowView;

    fn extract_component(
        (medium, camera, exposure, layers, surfaces): QueryItem<'_, '_, Self::QueryData>,
    ) -> Option<Self::Out> {
        Some(ExtractedVolshadowView {
            medium: medium.clone(),
            exposure: exposure_of(exposure),
            viewport: camera.viewport.clone(),
            layers: layers.cloned().unwrap_or_default(),
            surfaces: surfaces.copied(),
        })
    }
}

/// A light with [`VolshadowLight`] on its render-world entity, as Bevy describes it, its
/// render layers (as Bevy's lights do, it lights the views whose layers share one with them,
/// and only the occluders whose layers share one with them shadow it) and a spot's
/// [`SpotLightTexture`] image.
#[derive(Component, Clone, Debug)]
pub struct ExtractedVolshadowLight(
    pub(crate) SourceLight,
    pub(crate) RenderLayers,
    pub(crate) Option<AssetId<Image>>,
);

impl SyncComponent<RenderApp> for VolshadowLight {
    type Target = ExtractedVolshadowLight;
}

impl ExtractComponent<RenderApp> for VolshadowLight {
    type QueryData = (
        &'static VolshadowLight,
        &'static GlobalTransform,
        Option<&'static PointLight>,
        Option<&'static SpotLight>,
        Option<&'static DirectionalLight>,
        Option<&'static RenderLayers>,
        Option<&'static SpotLightTexture>,
    );
    type QueryFilter = ();
    type Out = ExtractedVolshadowLight;

    /// `None` (no light in the render world) for an entity that is none of Bevy's three
    /// lights, and for a light that emits nothing (volshadow refuses a zero intensity).
    fn extract_component(
        (marker, transform, point, spot, directional, layers, texture): QueryItem<
            '_,
            '_,
            Self::QueryData,
        >,
    ) -> Option<Self::Out> {
        let position = vec3(transform.translation());
        let direction = vec3(transform.forward().into());
        let light = if let Some(p) = point {
            SourceLight::Point {
                position,
                flux: linear(p.color) * p.intensity,
                radius: marker.radius.unwrap_or(p.radius),
            }
        } else if let Some(s) = spot {
            SourceLight::Spot {
                position,
                direction,
                up: vec3(transform.up().into()),
                outer_angle: s.outer_angle,
                flux: linear(s.color) * s.intensity,
                radius: marker.radius.unwrap_or(s.radius),
            }
        } else if let Some(d) = directional {
            SourceLight::Directional {
                direction,
                illuminance: linear(d.color) * d.illuminance,
            }
        } else {
            return None;
        };
        // Only a spot's texture counts (Bevy's point-light textures are cube maps, which
        // volshadow does not project).
        let texture = spot.and(texture).map(|t| t.image.id());
        (!light.is_dark())
            .then(|| ExtractedVolshadowLight(light, layers.cloned().unwrap_or_default(), texture))
    }
}

/// An occluder on its render-world entity: its mesh asset, its world transform and its render
/// layers (it shadows the lights that share one with them, as Bevy's shadow casters do).
#[derive(Component, Clone, Debug)]
pub struct ExtractedOccluder {
    pub(crate) mesh: AssetId<Mesh>,
    pub(crate) transform: glam::Mat4,
    pub(crate) layers: RenderLayers,
}

impl SyncComponent<RenderApp> for VolshadowOccluder {
    type Target = ExtractedOccluder;
}

impl ExtractComponent<RenderApp> for VolshadowOccluder {
    type QueryData = (
        &'static Mesh3d,
        &'static GlobalTransform,
        Option<&'static InheritedVisibility>,
        Option<&'static RenderLayers>,
    );
    type QueryFilter = ();
    type Out = ExtractedOccluder;

    /// `None` for a hidden occluder: it neither draws nor occludes.
    fn extract_component(
        (mesh, transform, visibility, layers): QueryItem<'_, '_, Self::QueryData>,
    ) -> Option<Self::Out> {
        if visibility.is_some_and(|v| !v.get()) {
            return None;
        }
        let m = transform.to_matrix().to_cols_array();
        Some(ExtractedOccluder {
            mesh: mesh.id(),
            transform: glam::Mat4::from_cols_array(&m),
            layers: layers.cloned().unwrap_or_default(),
        })
    }
}

fn vec3(v: bevy::math::Vec3) -> glam::Vec3 {
    glam::Vec3::from_array(v.to_array())
}

fn linear(color: bevy::color::Color) -> glam::Vec3 {
    let c = color.to_linear();
    glam::Vec3::new(c.red, c.green, c.blue)
}

/// The fraction of a spot light's light, averaged over its cone's solid angle, that Bevy's
/// falloff from `inner_angle` to `outer_angle` keeps: Bevy's surfaces are lit by
/// `saturate((cos θ − cos outer)/(cos inner − cos outer))²` of the light, volshadow's fog by
/// all of it inside `outer_angle`. With `c = cos θ` uniform over the cone's solid angle (dΩ =
/// 2π dc) and `w = max(cᵢ − cₒ, 1e-4)` the width of Bevy's ramp (its shader's floor), the
/// mean is `(w/3 + (1 − cₒ − w)) / (1 − cₒ)`.
#[cfg(test)]
fn bevy_spot_falloff_mean(inner: f64, outer: f64) -> f64 {
    let (ci, co) = (inner.cos(), outer.cos());
    let w = (ci - co).max(1e-4);
    (w / 3.0 + (1.0 - co - w)) / (1.0 - co)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The inner angle is not modelled (the README's "Light units"): this measures what that
    /// leaves out, Bevy's falloff averaged over the cone, by the closed form above and by a
    /// midpoint rule over the solid angle (20 000 rings) that evaluates Bevy's attenuation as
    /// its shader does (its `1e-4` floor on `cos inner − cos outer` included). Bar: the two
    /// agree to 1e-6 (the midpoint rule's error at that step is below 1e-8). A closed form for
    /// a hard cone (1) would fail it wherever inner < outer (0.333 at inner 0), and one
    /// without Bevy's floor fails at inner = outer (0.99977 against 1, seen).
    #[test]
    fn bevy_spot_falloff_against_a_hard_cone() {
        let outer = std::f64::consts::FRAC_PI_4; // Bevy's default outer_angle
        for ratio in [0.0, 0.5, 0.8, 0.9, 1.0] {
            let inner = ratio * outer;
            let (ci, co) = (inner.cos(), outer.cos());
            let scale = 1.0 / (ci - co).max(1e-4);
            let n = 20_000;
            let dc = (1.0 - co) / n as f64;
            let mean = (0..n)
                .map(|k| {
                    let c = co + (k as f64 + 0.5) * dc;
                    let a = ((c - co) * scale).clamp(0.0, 1.0);
                    a * a
                })
                .sum::<f64>()
                * dc
                / (1.0 - co);
            let closed = bevy_spot_falloff_mean(inner, outer);
            println!(
                "outer π/4, inner {ratio:.1} × outer: Bevy keeps {:.1}% of the cone's light \
                 (volshadow's fog: 100%)",
                100.0 * mean
            );
            assert!((mean - closed).abs() <= 1e-6, "{mean} against {closed}");
        }
    }
}
