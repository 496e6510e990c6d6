//! The render world: the shared pipelines (made at `RenderStartup`), the occluder meshes on the
//! GPU (like Bevy's render assets), one [`ViewVolshadow`] on each camera's render-world view,
//! prepared in `RenderSystems::Prepare`, and the `Core3d` system that only records.

use std::collections::HashMap;
use std::sync::Arc;

use bevy::asset::AssetId;
use bevy::camera::visibility::RenderLayers;
use bevy::core_pipeline::prepass::ViewPrepassTextures;
use bevy::ecs::prelude::*;
use bevy::mesh::Mesh;
use bevy::render::render_asset::RenderAssets;
use bevy::render::renderer::{RenderContext, RenderDevice, RenderQueue, ViewQuery};
use bevy::render::sync_world::MainEntity;
use bevy::render::texture::GpuImage;
use bevy::render::view::{ExtractedView, ViewDepthStencilTexture, ViewTarget};
use bevy::render::Extract;
use volshadow::nodes::{LightKind, MAX_LIGHTS};
use volshadow::{glam, wgpu, AdapterKind, Cache, OccluderMesh, Settings, VolumetricShadows};

use crate::extract::{
    ExtractedOccluder, ExtractedVolshadowLight, ExtractedVolshadowView, OccluderSources,
};
use crate::resolve::{DepthResolve, ResolvedDepth};
use crate::surfaces::{DecodedSurfaces, SurfaceDecode, SurfaceSources};
use crate::viewport::{Region, RegionTextures, RegionWrite};
use crate::{ViewReport, VolshadowDiagnostics, VolshadowQuality};

/// The pipelines every view shares: volshadow's [`Cache`], the depth resolve, the surfaces'
/// decode and the region write, made at `RenderStartup`, and which settings and light kinds
/// have been warmed.
#[derive(Resource)]
pub(crate) struct VolshadowPipelines {
    cache: Cache,
    resolve: DepthResolve,
    surfaces: SurfaceDecode,
    write: RegionWrite,
    /// The settings and light kinds whose remaining pipelines are being (or have been) built
    /// in the background.
    warmed: Vec<(Settings, LightKind)>,
}

/// Makes [`VolshadowPipelines`] when the render device is created (and again if it is
/// re-created).
pub(crate) fn init_pipelines(mut commands: Commands, device: Res<RenderDevice>) {
    let device = device.wgpu_device();
    commands.insert_resource(VolshadowPipelines {
        cache: Cache::new(device),
        resolve: DepthResolve::new(device),
        surfaces: SurfaceDecode::new(device),
        write: RegionWrite::new(device),
        warmed: Vec::new(),
    });
}

impl VolshadowPipelines {
    /// Builds, on Bevy's async compute pool, every pipeline that frames with `settings` can
    /// use for lights of `kinds` ([`Settings::warm_up`]), unless started already. The frame
    /// that first needs them has built what it uses in `prepare` (a view's first frame
    /// compiles only its own passes, in `Prepare`, never while recording); this builds the
    /// rest (the other methods' and variants' pipelines), so that a later change of plan (an
    /// occluder appearing, a light growing a radius) does not compile on its frame. The
    /// cache is shared and locked, so a frame that needs a pipeline being built waits for it.
    fn warm_up_rest(
        &mut self,
        device: &wgpu::Device,
        settings: Settings,
        kinds: impl Iterator<Item = LightKind>,
    ) {
        let new: Vec<LightKind> = kinds
            .filter(|k| !self.warmed.contains(&(settings, *k)))
            .collect();
        if new.is_empty() {
            return;
        }
        self.warmed.extend(new.iter().map(|k| (settings, *k)));
        let (device, cache) = (device.clone(), self.cache.clone());
        bevy::tasks::AsyncComputeTaskPool::get()
            .spawn(async move {
                if let Err(e) = settings.warm_up(&device, &cache, &new) {
                    bevy::log::error!("volshadow: warming pipelines: {e}");
                }
            })
            .detach();
    }
}

/// The occluder meshes on the GPU, per mesh asset, as Bevy's `RenderAssets` keeps a render
/// asset per asset id: each uploaded once per conversion (its generation) in
/// `RenderSystems::PrepareAssets`.
#[derive(Resource, Default)]
pub(crate) struct OccluderMeshes {
    uploaded: HashMap<AssetId<Mesh>, (u64, OccluderMesh)>,
    /// Converted meshes that the last extraction found new, to upload.
    pending: Vec<(AssetId<Mesh>, u64, Arc<volshadow::scene::Mesh>)>,
}

/// Brings the render world's meshes up to the main world's conversions when those changed:
/// drops the meshes no longer converted (or converted again) and queues the new ones.
pub(crate) fn extract_occluder_meshes(
    sources: Extract<Res<OccluderSources>>,
    mut meshes: ResMut<OccluderMeshes>,
) {
    if !sources.is_changed() {
        return;
    }
    let meshes = &mut *meshes;
    meshes.uploaded.retain(
        |id, (generation, _)| matches!(sources.meshes.get(id), Some((g, _)) if g == generation),
    );
    meshes.pending = sources
        .meshes
        .iter()
        .filter(|(id, (g, _))| meshes.uploaded.get(*id).is_none_or(|(u, _)| u != g))
        .filter_map(|(id, (g, mesh))| Some((*id, *g, mesh.as_ref().ok()?.clone())))
        .collect();
}

/// Uploads the meshes the extraction queued.
pub(crate) fn prepare_occluder_meshes(
    device: Res<RenderDevice>,
    mut meshes: ResMut<OccluderMeshes>,
) {
    let device = device.wgpu_device();
    for (id, generation, mesh) in std::mem::take(&mut meshes.pending) {
        let uploaded = OccluderMesh::new(device, &mesh);
        meshes.uploaded.insert(id, (generation, uploaded));
    }
}

/// One camera's volumetric shadows, on its render-world view: the facade (its GPU resources
/// and this frame's plan), the resolved depth (with MSAA, a viewport or a shared target), the
/// decoded surfaces (with [`VolshadowSurfaces`](crate::VolshadowSurfaces)), the region's own
/// textures (with a viewport or a shared target), and what this frame recorded.
/// Removed with the camera's [`VolshadowMedium`](crate::VolshadowMedium) or its view.
#[derive(Component)]
pub struct ViewVolshadow {
    facade: VolumetricShadows,
    /// The quality the facade's settings were made from (with the output format in them).
    quality: VolshadowQuality,
    depth: Option<ResolvedDepth>,
    surfaces: Option<DecodedSurfaces>,
    region: Option<RegionTextures>,
    /// This frame's preparation, when it succeeded: what the recording needs.
    prepared: Option<Prepared>,
}

/// What a successful `prepare` leaves for the recording.
struct Prepared {
    /// The view's main texture the facade read as the scene's colour: the recording writes
    /// only while it is still the main texture (no pass before it swapped them).
    scene_color: wgpu::Texture,
    /// Whether the depth is resolved (or cut out of a shared one) first.
    resolve: bool,
    /// Whether the surfaces are decoded from the prepass (before the passes read them).
    surfaces: bool,
    /// Whether the facade reads and writes the region's own textures (a viewport, or a target
    /// shared with other cameras): the scene's colour is copied out of the main texture of
    /// the moment it records, and the region write fills the post-process target.
    region: bool,
}

impl ViewVolshadow {
    /// The facade, for its plan and debug outputs.
    pub fn facade(&self) -> &VolumetricShadows {
        &self.facade
    }

    /// The in-scatter that the frame's light `light` added (`Rgba32Float`, of the camera's
    /// viewport, or its target, at the facade's resolution), for debugging and tests.
    pub fn inscatter(&self, light: usize) -> Option<&wgpu::Texture> {
        self.facade.inscatter(light)
    }

    /// The state of `camera` (a main-world entity) in `render_world` (the render sub-app's
    /// world), if it has one.
    pub fn of(render_world: &World, camera: Entity) -> Option<&ViewVolshadow> {
        let mut views = render_world.try_query::<(&MainEntity, &ViewVolshadow)>()?;
        views
            .iter(render_world)
            .find(|(main, _)| main.id() == camera)
            .map(|(_, view)| view)
    }
}

/// The settings of a view of `quality` whose target has `format`, on `device`'s adapter.
fn settings_for(
    quality: VolshadowQuality,
    format: wgpu::TextureFormat,
    device: &wgpu::Device,
) -> Result<Settings, String> {
    let kind = AdapterKind::of(device);
    let settings = match quality {
        VolshadowQuality::Adapter => Ok(Settings::for_adapter(kind)),
        VolshadowQuality::ErrorTarget(p95) => Settings::for_error_target(p95, kind),
        VolshadowQuality::Custom(settings) => Ok(settings),
    }
    .map_err(text)?;
    Ok(Settings {
        output_format: format,
        ..settings
    })
}

/// The views with a medium, and their state once they have one.
type Views<'w, 's> = Query<
    'w,
    's,
    (
        Entity,
        &'static MainEntity,
        &'static ExtractedView,
        &'static ExtractedVolshadowView,
        &'static ViewTarget,
        &'static ViewDepthStencilTexture,
        Option<&'static ViewPrepassTextures>,
        Option<&'static mut ViewVolshadow>,
    ),
>;

/// The render world's lights, with their main-world entities.
type Lights<'w, 's> = Query<'w, 's, (&'static MainEntity, &'static ExtractedVolshadowLight)>;

/// Prepares every camera's volumetric shadows for this frame, after the view's depth texture
/// exists: settings (again only when the camera's quality or target format changed), the
/// lights that matter most to it, the MSAA depth's target, and [`VolumetricShadows::prepare`]
/// (validation, uploads, and the pipelines this frame uses, built on first use), then the
/// rest of its pipelines warmed in the background. The report goes to
/// [`VolshadowDiagnostics`].
#[allow(clippy::too_many_arguments)]
pub(crate) fn prepare_views(
    mut commands: Commands,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    mut pipelines: ResMut<VolshadowPipelines>,
    meshes: Res<OccluderMeshes>,
    lights: Lights,
    occluders: Query<&ExtractedOccluder>,
    images: Res<RenderAssets<GpuImage>>,
    diagnostics: Res<VolshadowDiagnostics>,
    mut views: Views,
) {
    let device = device.wgpu_device();
    let queue: &wgpu::Queue = &queue;
    let occluders: Vec<(volshadow::Occluder, &RenderLayers)> = occluders
        .iter()
        .filter_map(|o| {
            let occluder = volshadow::Occluder {
                mesh: &meshes.uploaded.get(&o.mesh)?.1,
                transform: o.transform,
            };
            Some((occluder, &o.layers))
        })
        .collect();
    // Reports of cameras without a view this frame (despawned, medium removed, inactive) go.
    diagnostics.retain(|camera| views.iter().any(|(_, main, ..)| main.id() == camera));
    // Targets that several of these cameras draw into share their main textures.
    let mains: Vec<wgpu::Texture> = views
        .iter()
        .map(|(.., target, _, _, _)| (**target.main_texture()).clone())
        .collect();
    for (entity, main, extracted, camera, target, depth, prepass, state) in &mut views {
        let shared = mains
            .iter()
            .filter(|t| **t == **target.main_texture())
            .count()
            > 1;
        let mut created = None;
        let state: &mut ViewVolshadow = match state {
            Some(state) => state.into_inner(),
            None => match new_view(device, queue, &mut pipelines, camera, target) {
                Ok(state) => created.insert(state),
                Err(why) => {
                    diagnostics.set(main.id(), ViewReport::Failed(why));
                    continue;
                }
            },
        };
        let report = prepare_view(
            device,
            queue,
            &mut pipelines,
            (&lights, &images),
            &occluders,
            (extracted, camera, target, depth, prepass, shared),
            state,
        );
        if let Some(state) = created {
            commands.entity(entity).insert(state);
        }
        diagnostics.set(
            main.id(),
            match report {
                Ok(plan) => ViewReport::Planned(plan),
                Err(why) => ViewReport::Failed(why),
            },
        );
    }
}

fn text(e: volshadow::Error) -> String {
    e.to_string()
}

/// A new view's state: its settings and facade.
fn new_view(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    pipelines: &mut VolshadowPipelines,
    camera: &ExtractedVolshadowView,
    target: &ViewTarget,
) -> Result<ViewVolshadow, String> {
    let quality = camera.medium.quality;
    let settings = settings_for(quality, target.main_texture_format(), device)?;
    Ok(ViewVolshadow {
        facade: VolumetricShadows::new(device, queue, &pipelines.cache, settings).map_err(text)?,
        quality,
        depth: None,
        surfaces: None,
        region: None,
        prepared: None,
    })
}

/// The rectangle of its target a view fogs in textures of its own: its viewport (clamped to the
/// target, as Bevy draws it) or, for a camera sharing its target with others, the whole target;
/// `None` where the facade reads and writes the view's main textures directly.
fn region_of(
    camera: &ExtractedVolshadowView,
    target: &ViewTarget,
    shared: bool,
) -> Result<Option<Region>, String> {
    let size = target.main_texture().size();
    let whole = Region::whole(size);
    let region = match &camera.viewport {
        Some(v) => {
            if v.depth != (0.0..1.0) {
                return Err(format!(
                    "the camera's viewport has the depth range {:?}: volshadow_bevy reads \
                     depth of the range 0..1 only",
                    v.depth
                ));
            }
            let viewport = (v.physical_position.to_array(), v.physical_size.to_array());
            Region::clamped(viewport, size).ok_or_else(|| {
                format!(
                    "the camera's viewport (at {}, size {}) holds no pixel of its {}x{} target",
                    v.physical_position, v.physical_size, size.width, size.height
                )
            })?
        }
        None => whole,
    };
    Ok((shared || region != whole).then_some(region))
}

/// Prepares one view (`shared`: whether other cameras draw into its target); its plan's text,
/// or why nothing will be drawn.
fn prepare_view(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    pipelines: &mut VolshadowPipelines,
    (lights, images): (&Lights, &RenderAssets<GpuImage>),
    occluders: &[(volshadow::Occluder, &RenderLayers)],
    (extracted, camera, target, depth, prepass, shared): (
        &ExtractedView,
        &ExtractedVolshadowView,
        &ViewTarget,
        &ViewDepthStencilTexture,
        Option<&ViewPrepassTextures>,
        bool,
    ),
    state: &mut ViewVolshadow,
) -> Result<String, String> {
    state.prepared = None;
    let region = region_of(camera, target, shared)?;
    let medium = &camera.medium;
    let format = target.main_texture_format();
    if state.quality != medium.quality || state.facade.settings().output_format != format {
        let settings = settings_for(medium.quality, format, device)?;
        state.facade.set_settings(settings).map_err(text)?;
        state.quality = medium.quality;
    }

    let world_from_view = extracted.world_from_view.to_matrix().to_cols_array();
    let view_matrix = glam::Mat4::from_cols_array(&world_from_view).inverse();
    let projection = glam::Mat4::from_cols_array(&extracted.clip_from_view.to_cols_array());
    let vs_camera = volshadow::Camera::new(view_matrix, projection).map_err(text)?;
    let vs_medium =
        volshadow::Medium::new(medium.scattering, medium.absorption, medium.phase).map_err(text)?;

    // The lights that matter most to this view (see `SourceLight::contribution`), at most
    // volshadow's limit, strongest first; ties keep the entities' order.
    let eye = view_matrix.inverse().w_axis.truncate();
    let sigma_s = medium.scattering.element_sum() / 3.0;
    let sigma_t = sigma_s + medium.absorption.element_sum() / 3.0;
    // Lights on render layers this camera does not see are not its (as Bevy's lights); a
    // spot whose texture is not on the GPU yet waits for it (drawn without its mask, its whole
    // cone would flash lit).
    let seen: Vec<_> = lights
        .iter()
        .filter(|(_, l)| camera.layers.intersects(&l.1))
        .collect();
    let unseen = lights.iter().count() - seen.len();
    let mut ranked: Vec<(f32, Entity, &ExtractedVolshadowLight)> = seen
        .iter()
        .filter(|(_, l)| l.2.is_none_or(|image| images.get(image).is_some()))
        .map(|&(main, l)| (l.0.contribution(eye, sigma_s, sigma_t), main.id(), l))
        .collect();
    let waiting = seen.len() - ranked.len();
    ranked.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    let left_out: Vec<String> = ranked
        .iter()
        .skip(MAX_LIGHTS)
        .map(|(_, e, _)| e.to_string())
        .collect();
    ranked.truncate(MAX_LIGHTS);
    // Each light's shadow casters: the occluders whose layers share one with the light's.
    let casters: Vec<Vec<usize>> = ranked
        .iter()
        .map(|(_, _, l)| {
            (0..occluders.len())
                .filter(|&j| occluders[j].1.intersects(&l.1))
                .collect()
        })
        .collect();
    let frame_lights = ranked
        .iter()
        .zip(&casters)
        .map(|((_, _, l), casters)| {
            let light = l.0.to_volshadow(camera.exposure)?;
            // Bevy reads a spot texture's red channel alone, as a mask.
            let texture = l.2.and_then(|image| images.get(image)).map(|g| &*g.texture);
            Ok(volshadow::FrameLight {
                casters: Some(casters),
                texture,
                texture_channels: volshadow::scene::TextureChannels::Red,
                ..light.into()
            })
        })
        .collect::<volshadow::Result<Vec<volshadow::FrameLight>>>()
        .map_err(text)?;
    let occluders: Vec<volshadow::Occluder> = occluders.iter().map(|(o, _)| *o).collect();

    // Single-sampled depth of the view's region: Bevy's own when it has one sample and is the
    // view's alone, resolved or cut out otherwise.
    let depth_texture: &wgpu::Texture = depth.texture();
    let resolve = depth_texture.sample_count() > 1 || region.is_some();
    let scene_depth = if resolve {
        let whole = Region::whole(depth_texture.size());
        pipelines.resolve.prepare(
            device,
            queue,
            &mut state.depth,
            depth_texture,
            region.unwrap_or(whole),
        )
    } else {
        state.depth = None;
        depth_texture.clone()
    };
    // The surfaces, decoded from the prepass over the same region as the depth.
    let surfaces = match camera.surfaces {
        Some(wanted) => {
            let normal = prepass.and_then(|p| p.normal.as_ref()).ok_or(
                "the camera has VolshadowSurfaces but no normal prepass this frame (add Bevy's \
                 NormalPrepass)",
            )?;
            let sources = SurfaceSources {
                normal: &normal.texture.texture,
                depth: depth_texture,
                gbuffer: prepass
                    .and_then(|p| p.deferred.as_ref())
                    .map(|d| &*d.texture.texture),
            };
            let whole = Region::whole(sources.normal.size());
            let decoded = pipelines.surfaces.prepare(
                device,
                queue,
                &mut state.surfaces,
                &sources,
                region.unwrap_or(whole),
                wanted.albedo,
            );
            Some(volshadow::Surfaces {
                normal: &decoded.normal,
                albedo: &decoded.albedo,
            })
        }
        None => {
            state.surfaces = None;
            None
        }
    };
    let decode = surfaces.is_some();
    // The scene's colour: the main texture, or the region's own copy of it.
    pipelines.write.prepare(device, format);
    let scene_color: &wgpu::Texture = match region {
        Some(region) => {
            &RegionTextures::prepare(device, queue, &mut state.region, region, format).color
        }
        None => {
            state.region = None;
            target.main_texture()
        }
    };
    let plan = state
        .facade
        .prepare(
            device,
            queue,
            &volshadow::Frame {
                camera: &vs_camera,
                lights: &frame_lights,
                medium: &vs_medium,
                occluders: &occluders,
                scene_color,
                scene_depth: &scene_depth,
                surfaces,
            },
        )
        .map_err(text)?
        .to_string();
    pipelines.warm_up_rest(
        device,
        state.facade.settings(),
        frame_lights.iter().map(|l| l.kind()),
    );
    state.prepared = Some(Prepared {
        scene_color: (**target.main_texture()).clone(),
        resolve,
        surfaces: decode,
        region: region.is_some(),
    });
    let mut report = plan;
    if !left_out.is_empty() {
        report += &format!(
            "\n({} lights beyond the {MAX_LIGHTS} that add most to this view left out: {})",
            left_out.len(),
            left_out.join(", ")
        );
    }
    if unseen > 0 {
        report += &format!("\n({unseen} lights on render layers this camera does not see)");
    }
    if waiting > 0 {
        report += &format!("\n({waiting} spot lights waiting for their texture to load)");
    }
    Ok(report)
}

/// Records one camera's volumetric shadows after Bevy's main pass: the depth resolve (MSAA, or
/// the view's region of a viewport or shared target) and [`VolumetricShadows::encode`] into the
/// view's next post-process target, or, for a region, the copy of its colour out of the main
/// texture, the passes into the region's output and the region write. Everything else was
/// decided in `prepare_views`.
pub(crate) fn record_view(
    view: ViewQuery<(&MainEntity, &ViewTarget, &mut ViewVolshadow)>,
    pipelines: Res<VolshadowPipelines>,
    diagnostics: Res<VolshadowDiagnostics>,
    mut ctx: RenderContext,
) {
    let (main, target, mut state) = view.into_inner();
    let state = &mut *state;
    let Some(prepared) = state.prepared.take() else {
        return; // not prepared this frame: its report says why
    };
    let device = ctx.render_device().wgpu_device().clone();
    let write = target.post_process_write();
    let (source, destination): (&wgpu::Texture, &wgpu::Texture) =
        (write.source_texture, write.destination_texture);
    // From here the view's main texture is `destination`, so every way out writes it: the
    // fogged scene, or the scene as it is.
    // A view of its own target reads the main texture it was prepared with; a region copies
    // its colour out of whichever main texture holds the scene now.
    if !prepared.region && *source != prepared.scene_color {
        diagnostics.set(
            main.id(),
            ViewReport::Failed(
                "a pass before volshadow's swapped the view's main texture after it was \
                 prepared; nothing drawn"
                    .into(),
            ),
        );
        pipelines
            .write
            .encode(&device, ctx.command_encoder(), source, None, destination);
        return;
    }
    let encoder = ctx.command_encoder();
    // What the preparation made for the passes to read; without it, the scene as it is.
    if (prepared.resolve && state.depth.is_none())
        || (prepared.surfaces && state.surfaces.is_none())
    {
        pipelines
            .write
            .encode(&device, encoder, source, None, destination);
        return;
    }
    if let Some(resolved) = state.depth.as_ref().filter(|_| prepared.resolve) {
        pipelines.resolve.encode(encoder, resolved);
    }
    if let Some(decoded) = state.surfaces.as_ref().filter(|_| prepared.surfaces) {
        pipelines.surfaces.encode(encoder, decoded);
    }
    let region = state.region.as_ref().filter(|_| prepared.region);
    if let Some(region) = region {
        region.copy_in(encoder, source);
    }
    let output = region.map_or(destination, |r| &r.output);
    match state.facade.encode(encoder, output) {
        Ok(()) => {
            if region.is_some() {
                pipelines
                    .write
                    .encode(&device, encoder, source, region, destination);
            }
        }
        Err(e) => {
            // Recording nothing (encode checks before it records): the next target gets the
            // scene as it is, so the swap Bevy made shows the frame without fog, not a stale
            // one.
            pipelines
                .write
                .encode(&device, encoder, source, None, destination);
            diagnostics.set(main.id(), ViewReport::Failed(e.to_string()));
        }
    }
}
