//! The nodes wired by hand, as a caller who does not use the facade wires them: for the tests
//! of what the nodes do with inputs the facade never gives them (a caller's own face matrices,
//! a light whose penumbra the facade would draw hard). Every other frame of the tests goes
//! through the facade (`super::shadow_frame`).

use super::{ShadowFrame, ShadowPasses};
use volshadow::nodes::{
    AirlightTableNode, CrossingsRequest, Encode, ExtentsInputs, ExtentsNode, MarchInputs,
    MarchMethod, MarchMode, MarchNode, MarchStats, Node, Scale, ShadowForms, ShadowMap,
    ShadowMapInputs, ShadowMapNode, ShadowMapSettings, Shadows, SoftShadowInputs, SoftShadowNode,
    TableInputs,
};
use volshadow::{Cache, HeadlessGpu};

/// The shadow map, extents, soft-shadow grid (a light with a radius, exact or hybrid method),
/// table and march of `passes` (at full resolution, untextured), with the shadow map's face
/// matrices times `face_scale` handed to the grid and the march: clip coordinates scaled, the
/// same projection, but not the node's own matrices. Untimed; no extents in the result.
pub fn frame(
    gpu: &HeadlessGpu,
    cache: &Cache,
    passes: &ShadowPasses,
    face_scale: f32,
) -> ShadowFrame {
    let ShadowPasses {
        camera,
        light,
        medium,
        depth,
        occluders,
        settings,
        shadow_resolution,
        texture,
        ..
    } = *passes;
    assert!(
        settings.scale == Scale::Full && texture.is_none(),
        "by hand: full resolution, untextured"
    );
    let (device, queue) = (&gpu.device, &gpu.queue);
    let shadow_settings = ShadowMapSettings {
        resolution: shadow_resolution,
        ..ShadowMapSettings::DEFAULT
    };
    let mut shadow = ShadowMapNode::new(device, cache, shadow_settings).unwrap();
    let mut extents = ExtentsNode::new(device, cache).unwrap();
    let mut table = AirlightTableNode::new(device, cache, Default::default()).unwrap();
    let mut march = MarchNode::new(device, cache, settings).unwrap();
    let inputs = ShadowMapInputs {
        light,
        occluders,
        camera,
        fallback: None,
    };
    shadow.prepare(device, queue, &inputs).unwrap();
    let crossings = (settings.method == MarchMethod::Exact).then_some(CrossingsRequest {
        per_pixel: settings.crossings,
        scene_depth: depth,
        build: settings.crossings_build,
    });
    let inputs = ExtentsInputs {
        camera,
        light,
        occluders,
        size: (depth.width(), depth.height()),
        crossings,
    };
    extents.prepare(device, queue, &inputs).unwrap();
    let own = shadow.shadow_map().unwrap();
    let faces: Vec<glam::Mat4> = own.faces.iter().map(|f| *f * face_scale).collect();
    let shadow_map = ShadowMap {
        faces: &faces,
        ..own
    };
    let bounded = matches!(settings.method, MarchMethod::Exact | MarchMethod::Hybrid);
    let mut soft = (light.radius() > 0.0 && bounded).then(|| {
        let mut node = SoftShadowNode::new(device, cache, Default::default()).unwrap();
        let inputs = SoftShadowInputs { light, shadow_map };
        node.prepare(device, queue, &inputs).unwrap();
        node
    });
    let inputs = TableInputs {
        eye: camera.eye(),
        light,
        medium,
    };
    table.prepare(device, queue, &inputs).unwrap();
    let shadows = Shadows {
        shadow_map,
        extents: extents.extents(),
        soft: soft.as_ref().and_then(|n| n.output()),
    };
    let forms = Some(ShadowForms::of(&shadows));
    let mode = MarchMode::choose(settings.method, light.radius() > 0.0, forms);
    let inputs = MarchInputs {
        camera,
        light,
        medium,
        table: &table,
        scene_depth: depth,
        shadows: Some(shadows),
        mode,
        light_texture: None,
    };
    march.prepare(device, queue, &inputs).unwrap();
    let mut encoder = device.create_command_encoder(&Default::default());
    shadow.encode(&mut encoder, None).unwrap();
    extents.encode(&mut encoder, None).unwrap();
    if let Some(node) = soft.as_mut() {
        node.encode(&mut encoder, None).unwrap();
    }
    table.encode(&mut encoder, None).unwrap();
    march.encode(&mut encoder, None).unwrap();
    gpu.submit_and_wait(encoder).unwrap();
    let steps = gpu
        .read_texture_bytes(march.step_counts().unwrap())
        .unwrap();
    let stats = gpu.read_buffer_bytes(march.stats_buffer()).unwrap();
    ShadowFrame {
        inscatter: gpu.read_rgba32f(march.output().unwrap()).unwrap(),
        steps: bytemuck::pod_collect_to_vec(&steps),
        stats: MarchStats::from_bytes(&stats).unwrap(),
        extents: None,
        times: Vec::new(),
    }
}
