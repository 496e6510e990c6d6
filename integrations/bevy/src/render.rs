//! The render world: occluder meshes on the GPU, one `VolumetricShadows` per camera, and the
//! `Core3d` system that records it into Bevy's encoder.

use std::collections::HashMap;

use bevy::asset::AssetId;
use bevy::ecs::prelude::*;
use bevy::mesh::Mesh;
use bevy::render::renderer::{RenderContext, RenderDevice, RenderQueue, ViewQuery};
use bevy::render::sync_world::MainEntity;
use bevy::render::view::{ExtractedView, ViewDepthStencilTexture, ViewTarget};
use volshadow::{glam, wgpu, AdapterKind, Cache, OccluderMesh, Settings, VolumetricShadows};

use crate::extract::ExtractedScene;
use crate::resolve::DepthResolve;
use crate::{ViewReport, VolshadowDiagnostics, VolshadowQuality};

/// The render world's volshadow state: the shared pipelines, the occluder meshes on the GPU,
/// and one [`VolumetricShadows`] per camera.
#[derive(Resource, Default)]
pub struct VolshadowViews {
    cache: Option<Cache>,
    meshes: HashMap<AssetId<Mesh>, (u64, OccluderMesh)>,
    views: HashMap<Entity, ViewState>,
    resolve: Option<DepthResolve>,
}

struct ViewState {
    facade: VolumetricShadows,
    /// The resolved depth (with MSAA), kept while the view's size stays.
    depth: Option<wgpu::Texture>,
}

impl VolshadowViews {
    /// The in-scatter that `light` added in `camera`'s last frame (a main-world entity;
    /// full resolution, `Rgba32Float`), for debugging and tests.
    pub fn inscatter(&self, camera: Entity, light: usize) -> Option<&wgpu::Texture> {
        self.views.get(&camera)?.facade.inscatter(light)
    }

    /// The facade of `camera` (a main-world entity), for its plan and debug outputs.
    pub fn facade(&self, camera: Entity) -> Option<&VolumetricShadows> {
        Some(&self.views.get(&camera)?.facade)
    }
}

/// Uploads the occluder meshes that are new or changed, and drops the ones no longer used and
/// the cameras that are gone.
pub(crate) fn prepare_occluder_meshes(
    scene: Res<ExtractedScene>,
    device: Res<RenderDevice>,
    diagnostics: Res<VolshadowDiagnostics>,
    mut state: ResMut<VolshadowViews>,
) {
    let device = device.wgpu_device();
    let state = &mut *state;
    state.meshes.retain(|id, (generation, _)| {
        let source = scene.sources.meshes.get(id);
        source.is_some_and(|(g, _)| g == generation)
    });
    for (id, (generation, mesh)) in &scene.sources.meshes {
        if let (false, Ok(mesh)) = (state.meshes.contains_key(id), mesh) {
            state
                .meshes
                .insert(*id, (*generation, OccluderMesh::new(device, mesh)));
        }
    }
    state.views.retain(|e, _| scene.cameras.contains_key(e));
    diagnostics.retain(|e| scene.cameras.contains_key(&e));
}

fn settings_for(quality: VolshadowQuality, kind: AdapterKind) -> volshadow::Result<Settings> {
    match quality {
        VolshadowQuality::Adapter => Ok(Settings::for_adapter(kind)),
        VolshadowQuality::ErrorTarget(p95) => Settings::for_error_target(p95, kind),
        VolshadowQuality::Custom(settings) => Ok(settings),
    }
}

/// Records one camera's volumetric shadows after Bevy's main pass.
pub(crate) fn volshadow_view(
    view: ViewQuery<(
        &MainEntity,
        &ViewTarget,
        &ViewDepthStencilTexture,
        &ExtractedView,
    )>,
    scene: Res<ExtractedScene>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    diagnostics: Res<VolshadowDiagnostics>,
    mut state: ResMut<VolshadowViews>,
    mut ctx: RenderContext,
) {
    let (main_entity, target, depth, extracted) = view.into_inner();
    let camera_entity = main_entity.id();
    let Some(camera) = scene.cameras.get(&camera_entity) else {
        return; // a camera without VolshadowMedium
    };
    let device = device.wgpu_device().clone();
    let queue: &wgpu::Queue = &queue;
    let report = record(
        &device,
        queue,
        &scene,
        camera_entity,
        camera,
        target,
        depth,
        extracted,
        &mut state,
        &mut ctx,
    );
    diagnostics.set(
        camera_entity,
        match report {
            Ok(plan) => ViewReport::Planned(plan),
            Err(why) => ViewReport::Failed(why),
        },
    );
}

#[allow(clippy::too_many_arguments)]
fn record(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    scene: &ExtractedScene,
    camera_entity: Entity,
    camera: &crate::extract::SourceCamera,
    target: &ViewTarget,
    depth: &ViewDepthStencilTexture,
    extracted: &ExtractedView,
    state: &mut VolshadowViews,
    ctx: &mut RenderContext,
) -> Result<String, String> {
    let text = |e: volshadow::Error| e.to_string();
    if camera.viewport {
        return Err("the camera has a viewport: volshadow_bevy draws whole targets only".into());
    }
    let state = &mut *state;
    let cache = state.cache.get_or_insert_with(|| Cache::new(device));
    let kind = AdapterKind::of(device);
    let medium = &camera.medium;
    let settings = Settings {
        output_format: target.main_texture_format(),
        ..settings_for(medium.quality, kind).map_err(text)?
    };
    let view_state = match state.views.entry(camera_entity) {
        std::collections::hash_map::Entry::Occupied(e) => e.into_mut(),
        std::collections::hash_map::Entry::Vacant(e) => e.insert(ViewState {
            facade: VolumetricShadows::new(device, queue, cache, settings).map_err(text)?,
            depth: None,
        }),
    };
    if view_state.facade.settings() != settings {
        view_state.facade.set_settings(settings).map_err(text)?;
    }

    let world_from_view = extracted.world_from_view.to_matrix().to_cols_array();
    let view_matrix = glam::Mat4::from_cols_array(&world_from_view).inverse();
    let projection = glam::Mat4::from_cols_array(&extracted.clip_from_view.to_cols_array());
    let vs_camera = volshadow::Camera::new(view_matrix, projection).map_err(text)?;
    let vs_medium =
        volshadow::Medium::new(medium.scattering, medium.absorption, medium.phase).map_err(text)?;
    let max = volshadow::nodes::MAX_LIGHTS;
    let lights = scene
        .lights
        .iter()
        .take(max)
        .map(|l| l.to_volshadow(camera.exposure).map(Into::into))
        .collect::<volshadow::Result<Vec<volshadow::FrameLight>>>()
        .map_err(text)?;
    let occluders: Vec<volshadow::Occluder> = scene
        .occluders
        .iter()
        .filter_map(|(id, transform)| {
            Some(volshadow::Occluder {
                mesh: &state.meshes.get(id)?.1,
                transform: *transform,
            })
        })
        .collect();

    // Single-sampled depth: Bevy's own when it has one sample, resolved otherwise.
    let depth_texture: &wgpu::Texture = depth.texture();
    let scene_depth = if depth_texture.sample_count() > 1 {
        let resolve = state
            .resolve
            .get_or_insert_with(|| DepthResolve::new(device));
        let resolved = resolve.target(device, &mut view_state.depth, depth_texture);
        resolve.encode(device, ctx.command_encoder(), depth_texture, &resolved);
        resolved
    } else {
        view_state.depth = None;
        depth_texture.clone()
    };
    let scene_color: &wgpu::Texture = target.main_texture();
    let plan = view_state
        .facade
        .prepare(
            device,
            queue,
            &volshadow::Frame {
                camera: &vs_camera,
                lights: &lights,
                medium: &vs_medium,
                occluders: &occluders,
                scene_color,
                scene_depth: &scene_depth,
                surfaces: None,
            },
        )
        .map_err(text)?;
    let plan = plan.to_string();
    let output: &wgpu::Texture = target.post_process_write().destination_texture;
    view_state
        .facade
        .encode(ctx.command_encoder(), output)
        .map_err(text)?;
    let skipped = scene.lights.len().saturating_sub(max);
    Ok(if skipped > 0 {
        format!("{plan}\n({skipped} lights beyond the first {max} left out)")
    } else {
        plan
    })
}
