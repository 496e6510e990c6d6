//! # volshadow_bevy
//!
//! [`volshadow`]'s volumetric shadows in a Bevy app: light shafts, and the dark shafts that
//! occluders cut through a homogeneous fog, computed with the exact method (closed form between
//! the shadow volumes' faces) and composited into the camera's HDR target after the main pass.
//!
//! ```no_run
//! use bevy::prelude::*;
//! use volshadow_bevy::{VolshadowLight, VolshadowMedium, VolshadowOccluder, VolshadowPlugin};
//!
//! fn setup(
//!     mut commands: Commands,
//!     mut meshes: ResMut<Assets<Mesh>>,
//!     mut materials: ResMut<Assets<StandardMaterial>>,
//! ) {
//!     // The camera sees the medium: σs and σa per metre, and a phase function.
//!     commands.spawn((
//!         Camera3d::default(),
//!         Transform::from_xyz(0.0, 1.5, 6.0).looking_at(Vec3::new(0.0, 1.0, 0.0), Vec3::Y),
//!         VolshadowMedium::default(),
//!     ));
//!     // A light that casts volumetric shadows, here with a radius of 5 cm (soft shadows).
//!     commands.spawn((
//!         PointLight { intensity: 200_000.0, ..default() },
//!         Transform::from_xyz(0.0, 4.0, -2.0),
//!         VolshadowLight { radius: Some(0.05) },
//!     ));
//!     // A mesh that occludes it: closed, triangle-list.
//!     commands.spawn((
//!         Mesh3d(meshes.add(Sphere::new(0.5).mesh().ico(4).unwrap())),
//!         MeshMaterial3d(materials.add(Color::WHITE)),
//!         Transform::from_xyz(0.0, 2.0, -1.0),
//!         VolshadowOccluder,
//!     ));
//! }
//!
//! App::new()
//!     .add_plugins((DefaultPlugins, VolshadowPlugin))
//!     .add_systems(Startup, setup)
//!     .run();
//! ```
//!
//! # What the plugin does
//!
//! * **Meshes** of [`VolshadowOccluder`] entities become [`volshadow::OccluderMesh`]es once per
//!   mesh asset (welded, their edge adjacency built, uploaded), and again when the asset
//!   changes; their transforms are read every frame, and a hidden one (its inherited
//!   visibility off) does not occlude. A mesh that cannot be an occluder (not a triangle list,
//!   no positions) is left out with a logged error naming it.
//! * **Lights** with [`VolshadowLight`] (a `PointLight`, `SpotLight` or `DirectionalLight`) are
//!   converted to volshadow's radiometric lights (see [Light units](#light-units)). A light
//!   that emits nothing (zero intensity) is skipped. When more than
//!   [`volshadow::nodes::MAX_LIGHTS`] light the medium, each camera takes the ones that add
//!   most to its view: ranked by the brightest unshadowed single scattering a ray from the
//!   camera gathers from each, `σs·I·π/(2d)·e^(−σt·d)` for a point or spot light of intensity
//!   `I` at distance `d`, `σs·E/σt` for a directional light of irradiance `E`. Its plan names
//!   the lights left out.
//! * **Render layers** ([`RenderLayers`](bevy::camera::visibility::RenderLayers), layer 0
//!   when absent) are kept as Bevy keeps them for its own lights and shadows: a camera's medium
//!   is lit only by the lights on a layer the camera sees, and a light is shadowed only by the
//!   occluders that share a layer with it. The plan counts the lights a camera's layers leave
//!   out.
//! * **Cameras** with [`VolshadowMedium`] get one [`volshadow::VolumetricShadows`] each, held
//!   with its resolved depth in a [`ViewVolshadow`] on the camera's render-world view and
//!   dropped with it. Bevy's component extraction brings the camera's medium, each light and
//!   each occluder into the render world. In `RenderSystems::Prepare`, after the view's depth
//!   texture exists, the plugin builds the view's settings (again only when its quality or
//!   target format changes), picks its lights, builds the pipelines they need and prepares the
//!   frame (validation and uploads). A system in Bevy's `Core3d` schedule, after the main pass
//!   and before the post-processing, then only records: the depth resolve and the passes,
//!   reading the view's HDR colour and depth and writing the next HDR target
//!   ([`ViewTarget::post_process_write`](bevy::render::view::ViewTarget::post_process_write)).
//!   A camera with a viewport, or one sharing its target with other cameras (whose
//!   post-process passes swap the target's main textures), is fogged in textures of its own:
//!   it copies its rectangle's colour out of the main texture of the moment it records, its
//!   depth is cut out (and resolved) to the rectangle, and a pass writes the next target, the
//!   fogged rectangle in the rest of the scene. [`VolshadowSystems`] names these steps, to
//!   order other systems around them.
//! * **Surfaces** of a camera with [`VolshadowSurfaces`] get the light the medium scatters onto
//!   them (volshadow's surface term), added by the composite: normals from Bevy's normal
//!   prepass, albedo from the deferred G-buffer (a deferred camera) or the component (a
//!   forward one), decoded in a small pass of the plugin's own before volshadow's.
//! * **Pipelines** are shared by every camera in one volshadow [`volshadow::Cache`], made
//!   when Bevy creates the render device (`RenderStartup`). A view's first frame builds the
//!   pipelines it uses in `Prepare`, so recording never compiles; the rest of what its
//!   settings and its lights' kinds can use (other methods and variants) is then built on
//!   Bevy's async compute pool, so a later change of plan does not compile on its frame.
//!
//! # Depth and MSAA
//!
//! The passes read single-sampled depth. The plugin adds `TEXTURE_BINDING` to the depth
//! texture's usages of cameras with [`VolshadowMedium`]. With MSAA (Bevy's default 4×), it
//! resolves the depth to one value per pixel in a small pass of its own: the median of the
//! pixel's samples, so that where two surfaces share a pixel, the one covering most of it
//! (most likely the one at its centre, where the pixel's ray is cast) gives the depth.
//!
//! # Light units
//!
//! Bevy's lights are photometric (lumens, lux) and its shading multiplies them by the
//! camera's exposure; volshadow's are radiometric and unitless beyond the medium's
//! coefficients. The plugin hands volshadow what Bevy's own shading uses, so that the fog and
//! the surfaces share one scale:
//!
//! * point and spot lights: radiant intensity `I = colour · lumens / (4π) · exposure` (Bevy's
//!   point and spot lights alike: a spot's cone masks, it does not concentrate);
//! * directional lights: irradiance `E = colour · lux · exposure`;
//! * `colour` is the light's linear RGB, `exposure` the camera's [`Exposure::exposure`]
//!   (Bevy's default when the camera has none).
//!
//! A spot's cone is its `outer_angle` (volshadow's spots have a hard edge: the soft falloff
//! from `inner_angle` is not modelled). A light's `range` is not a cut-off for volshadow. A
//! spot's [`SpotLightTexture`](bevy::light::SpotLightTexture) becomes volshadow's textured spot:
//! the image's red channel as a grey mask (what Bevy reads), turned with the light's transform
//! (its up is the texture frame's); the light is left out of the fog until its image is on the
//! GPU (its plan says it waits).
//!
//! # Debugging
//!
//! [`VolshadowDiagnostics`] (a resource of the main app) holds, per camera, the last frame's
//! plan (which passes ran and why the others did not) or the error that stopped it.

#![warn(missing_docs)]

mod extract;
pub mod headless;
mod render;
mod resolve;
mod surfaces;
mod viewport;

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use bevy::app::{App, Plugin, PostUpdate};
use bevy::asset::AssetEventSystems;
use bevy::camera::{Camera3d, Exposure, Hdr};
use bevy::core_pipeline::core_3d::{prepare_core_3d_depth_textures, prepare_prepass_textures};
#[cfg(doc)]
use bevy::core_pipeline::prepass::DeferredPrepass;
use bevy::core_pipeline::prepass::NormalPrepass;
use bevy::core_pipeline::schedule::{Core3d, Core3dSystems};
use bevy::ecs::prelude::*;
use bevy::render::extract_component::ExtractComponentPlugin;
use bevy::render::render_resource::TextureUsages;
use bevy::render::{ExtractSchedule, Render, RenderApp, RenderStartup, RenderSystems};
use bevy::transform::TransformSystems;

pub use extract::{
    ExtractedOccluder, ExtractedVolshadowLight, ExtractedVolshadowView, OccluderSources,
};
pub use render::ViewVolshadow;
pub use volshadow;

/// The medium a camera sees, and how volshadow renders it. Put it on a `Camera3d` entity; it
/// requires [`Hdr`] (the passes read and write float colour).
#[derive(Component, Clone, Debug)]
#[require(Hdr)]
pub struct VolshadowMedium {
    /// Scattering coefficient σs per channel (per world unit).
    pub scattering: volshadow::glam::Vec3,
    /// Absorption coefficient σa per channel (per world unit).
    pub absorption: volshadow::glam::Vec3,
    /// The phase function.
    pub phase: volshadow::PhaseFunction,
    /// The method and resolution.
    pub quality: VolshadowQuality,
}

impl Default for VolshadowMedium {
    /// Light haze: σs 0.05, σa 0.005 per unit in every channel, Henyey–Greenstein g 0.5, and
    /// [`VolshadowQuality::default`].
    fn default() -> Self {
        Self {
            scattering: volshadow::glam::Vec3::splat(0.05),
            absorption: volshadow::glam::Vec3::splat(0.005),
            phase: volshadow::PhaseFunction::HenyeyGreenstein { g: 0.5 },
            quality: VolshadowQuality::default(),
        }
    }
}

/// How a camera's volumetric shadows are rendered. The default is an error target of 1% (p95),
/// the same on every adapter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum VolshadowQuality {
    /// [`volshadow::Settings::for_adapter`]: the exact method, at full resolution on a GPU and
    /// half on a CPU adapter (cheaper there, and less accurate: about 3% at p95).
    Adapter,
    /// [`volshadow::Settings::for_error_target`]: the cheapest measured configuration within
    /// this relative error (p95, e.g. `0.01`).
    ErrorTarget(f32),
    /// These settings as they are (their output format is replaced by the view's).
    Custom(volshadow::Settings),
}

impl Default for VolshadowQuality {
    fn default() -> Self {
        Self::ErrorTarget(0.01)
    }
}

/// Draws, on a camera with [`VolshadowMedium`], the light the medium scatters onto the scene's
/// surfaces (volshadow's surface term: the in-scattered light each point and spot light
/// gives a Lambertian surface through the fog, unshadowed), added by the composite to what
/// Bevy drew. It requires Bevy's [`NormalPrepass`], whose normals it reads; with MSAA, each
/// pixel takes the sample whose depth the resolved depth holds.
///
/// The albedo: a camera with Bevy's [`DeferredPrepass`] reads each material's diffuse colour
/// from the G-buffer (the base colour times `1 − metallic`, as Bevy's deferred lighting
/// decodes it; unlit materials reflect nothing); a forward camera has no such buffer (Bevy's
/// forward prepass writes no colour), so every surface it sees has [`albedo`](Self::albedo).
#[derive(Component, Clone, Copy, Debug, PartialEq)]
#[require(NormalPrepass)]
pub struct VolshadowSurfaces {
    /// The diffuse albedo (linear RGB, each in 0..=1) of the surfaces of a camera without a
    /// deferred G-buffer.
    pub albedo: volshadow::glam::Vec3,
}

impl Default for VolshadowSurfaces {
    /// An albedo of 0.5 in every channel.
    fn default() -> Self {
        Self {
            albedo: volshadow::glam::Vec3::splat(0.5),
        }
    }
}

/// Makes a `PointLight`, `SpotLight` or `DirectionalLight` cast volumetric shadows (and light
/// the medium: a light without it adds no in-scatter).
#[derive(Component, Clone, Copy, Debug, Default, PartialEq)]
pub struct VolshadowLight {
    /// The light's radius for soft shadows (point and spot lights): `None` takes Bevy's
    /// `radius` of the light, `Some(0.0)` draws hard shadows. Ignored for directional lights.
    pub radius: Option<f32>,
}

/// Makes a mesh entity (`Mesh3d`, a closed triangle list) an occluder of the lights with
/// [`VolshadowLight`].
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct VolshadowOccluder;

/// Per camera, the last frame's plan or error, shared by the main and render apps. A map
/// shared between the two worlds, as Bevy's own render diagnostics are: the render world
/// cannot write a main-world component. The render world drops the report of a camera that
/// no longer has a view.
#[derive(Resource, Clone, Default)]
pub struct VolshadowDiagnostics(Arc<Mutex<HashMap<Entity, ViewReport>>>);

/// What happened to one camera's volumetric shadows in the last frame it rendered.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ViewReport {
    /// The plan's description: which passes ran, and why the others were left out.
    Planned(String),
    /// Why nothing was drawn (a typed volshadow error, or the view's textures).
    Failed(String),
}

impl VolshadowDiagnostics {
    /// The last report of `camera` (a main-world entity), if it has rendered.
    pub fn report(&self, camera: Entity) -> Option<ViewReport> {
        self.0.lock().ok()?.get(&camera).cloned()
    }

    pub(crate) fn set(&self, camera: Entity, report: ViewReport) {
        if let Ok(mut map) = self.0.lock() {
            if map.get(&camera) != Some(&report) {
                match &report {
                    ViewReport::Planned(plan) => bevy::log::debug!("volshadow {camera}: {plan}"),
                    ViewReport::Failed(why) => bevy::log::error!("volshadow {camera}: {why}"),
                }
                map.insert(camera, report);
            }
        }
    }

    pub(crate) fn retain(&self, keep: impl Fn(Entity) -> bool) {
        if let Ok(mut map) = self.0.lock() {
            map.retain(|e, _| keep(*e));
        }
    }
}

/// The plugin's systems, to order other systems around them.
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum VolshadowSystems {
    /// Main world, `PostUpdate`, after the asset events: occluder meshes converted (welded,
    /// their edges found) when new or changed.
    TrackMeshes,
    /// Render world, `Render`, in `RenderSystems::PrepareAssets`: the converted meshes
    /// uploaded.
    PrepareMeshes,
    /// Render world, `Render`, in `RenderSystems::Prepare` after the views' depth textures:
    /// each camera's settings, lights, pipelines and frame prepared.
    PrepareViews,
    /// Render world, `Core3d`, after the main pass and before the post-processing: each
    /// camera's passes recorded.
    Record,
}

/// Adds volshadow's volumetric shadows to cameras with [`VolshadowMedium`].
pub struct VolshadowPlugin;

impl Plugin for VolshadowPlugin {
    fn build(&self, app: &mut App) {
        let diagnostics = VolshadowDiagnostics::default();
        app.insert_resource(diagnostics.clone())
            .init_resource::<OccluderSources>()
            .add_plugins((
                ExtractComponentPlugin::<VolshadowMedium>::default(),
                ExtractComponentPlugin::<VolshadowLight>::default(),
                ExtractComponentPlugin::<VolshadowOccluder>::default(),
            ))
            .add_systems(
                PostUpdate,
                (
                    // After the asset events, so that a changed mesh is used the same frame.
                    extract::track_occluder_meshes
                        .after(AssetEventSystems)
                        .in_set(VolshadowSystems::TrackMeshes),
                    configure_cameras.after(TransformSystems::Propagate),
                ),
            );
        let Some(render_app) = app.get_sub_app_mut(RenderApp) else {
            return;
        };
        render_app
            .insert_resource(diagnostics)
            .init_resource::<render::OccluderMeshes>()
            .add_systems(RenderStartup, render::init_pipelines)
            .add_systems(ExtractSchedule, render::extract_occluder_meshes)
            .add_systems(
                Render,
                (
                    render::prepare_occluder_meshes
                        .in_set(RenderSystems::PrepareAssets)
                        .in_set(VolshadowSystems::PrepareMeshes),
                    render::prepare_views
                        .in_set(RenderSystems::Prepare)
                        .after(prepare_core_3d_depth_textures)
                        .after(prepare_prepass_textures)
                        .after(VolshadowSystems::PrepareMeshes)
                        .in_set(VolshadowSystems::PrepareViews),
                ),
            )
            .add_systems(
                Core3d,
                render::record_view
                    .after(Core3dSystems::MainPass)
                    .before(Core3dSystems::EarlyPostProcess)
                    .in_set(VolshadowSystems::Record),
            );
    }
}

/// Cameras with [`VolshadowMedium`] need their depth texture readable.
fn configure_cameras(mut cameras: Query<&mut Camera3d, Changed<VolshadowMedium>>) {
    for mut camera in &mut cameras {
        let usages = TextureUsages::from_bits_truncate(camera.depth_texture_usages.0);
        if !usages.contains(TextureUsages::TEXTURE_BINDING) {
            camera.depth_texture_usages = (usages | TextureUsages::TEXTURE_BINDING).into();
        }
    }
}

/// The multiplier Bevy's shading applies to light for this camera.
pub(crate) fn exposure_of(exposure: Option<&Exposure>) -> f32 {
    exposure.copied().unwrap_or_default().exposure()
}
