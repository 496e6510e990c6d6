//! `Settings::warm_up` (issue 36, item 5): after it, no frame builds a pipeline or a shader
//! module, for every method, resolution and light kind, with and without occluders, with a light whose
//! penumbra is below a texel (drawn hard), with and without the surface term. Measured by the
//! wgpu instance's own count of live pipelines and shader modules, not by the crate's
//! bookkeeping. The same frames on a cold cache build some, which shows the count sees them.
//! `VolumetricShadows::is_first_frame` marks exactly the frames that bring a new form.

use glam::{Mat4, Vec3};
use volshadow::nodes::{MarchMethod, Scale};
use volshadow::scene::shapes;
use volshadow::{
    Cache, Camera, DirectionalLight, Frame, FrameLight, HeadlessGpu, Light, LightKind, Medium,
    Occluder, OccluderMesh, PhaseFunction, PointLight, Settings, SpotLight, Surfaces,
    VolumetricShadows,
};

/// Small: the frames are prepared, never run; only pipeline creation matters.
const SIZE: u32 = 32;

/// Live compute and render pipelines and shader modules of the instance.
fn built(gpu: &HeadlessGpu) -> usize {
    let report = gpu
        .instance
        .generate_report()
        .expect("a wgpu-core backend reports its resources");
    let hub = report.hub_report();
    hub.compute_pipelines.num_allocated
        + hub.render_pipelines.num_allocated
        + hub.shader_modules.num_allocated
}

struct Rig {
    gpu: HeadlessGpu,
    camera: Camera,
    color: wgpu::Texture,
    depth: wgpu::Texture,
    normal: wgpu::Texture,
    albedo: wgpu::Texture,
    light_texture: wgpu::Texture,
    sphere: OccluderMesh,
}

/// A rig on a device of its own: the counts are the instance's, so a test that counts must not
/// share its instance with tests that build pipelines at the same time.
fn rig() -> Rig {
    let gpu = HeadlessGpu::new().expect("GPU tests need a wgpu adapter (lavapipe works)");
    let camera = volshadow_harness::look_at(
        Vec3::new(0.0, 1.5, 6.0),
        Vec3::new(0.0, 1.0, 0.0),
        60.0,
        1.0,
    );
    let depth =
        volshadow_harness::depth_texture(&gpu, SIZE, SIZE, &vec![0.99; (SIZE * SIZE) as usize]);
    let sampled = wgpu::TextureUsages::TEXTURE_BINDING;
    let tex = |format| volshadow_harness::texture(&gpu, format, sampled, (SIZE, SIZE, 1), 1);
    let color = tex(wgpu::TextureFormat::Rgba32Float);
    let normal = tex(wgpu::TextureFormat::Rgba16Float);
    let albedo = tex(wgpu::TextureFormat::Rgba16Float);
    let light_texture = volshadow_harness::texture(
        &gpu,
        wgpu::TextureFormat::Rgba16Float,
        sampled,
        (16, 16, 1),
        1,
    );
    let sphere = OccluderMesh::new(
        &gpu.device,
        &shapes::uv_sphere(Vec3::new(0.0, 1.5, 0.0), 0.5, 24, 12).unwrap(),
    );
    Rig {
        gpu,
        camera,
        color,
        depth,
        normal,
        albedo,
        light_texture,
        sphere,
    }
}

/// Lights of `kind`: for a soft kind a radius whose penumbra the shadow map resolves and one
/// far below a texel (the facade draws that one hard).
fn lights(kind: LightKind) -> Vec<Light> {
    let position = Vec3::new(0.3, 4.0, -0.5);
    let intensity = Vec3::splat(20.0);
    let radii: &[f32] = match kind {
        LightKind::Point { soft: true } | LightKind::Spot { soft: true, .. } => &[0.3, 1e-6],
        _ => &[0.0],
    };
    radii
        .iter()
        .map(|&r| match kind {
            LightKind::Point { .. } => PointLight::new(position, intensity)
                .unwrap()
                .with_radius(r)
                .unwrap()
                .into(),
            LightKind::Spot { .. } => SpotLight::new(position, -Vec3::Y, 1.2, intensity)
                .unwrap()
                .with_radius(r)
                .unwrap()
                .into(),
            LightKind::Directional => DirectionalLight::new(Vec3::new(0.2, -1.0, -0.3), Vec3::ONE)
                .unwrap()
                .into(),
        })
        .collect()
}

/// Prepares (never runs) every frame a light of `kind` can bring under `settings`: with and
/// without the occluder, each radius, with and without surfaces. Returns how many pipelines
/// and modules the frames built, and which frames `is_first_frame` marked.
fn prepare_frames(
    rig: &Rig,
    cache: &Cache,
    settings: Settings,
    kind: LightKind,
) -> (usize, Vec<bool>) {
    let gpu = &rig.gpu;
    let medium = Medium::new(
        Vec3::splat(0.1),
        Vec3::splat(0.01),
        PhaseFunction::HenyeyGreenstein { g: 0.5 },
    )
    .unwrap();
    let occluder = [Occluder {
        mesh: &rig.sphere,
        transform: Mat4::IDENTITY,
    }];
    let textured = matches!(kind, LightKind::Spot { textured: true, .. });
    let mut volumetric = VolumetricShadows::new(&gpu.device, &gpu.queue, cache, settings).unwrap();
    let before = built(gpu);
    let mut marks = Vec::new();
    // Twice over: the second round brings no new form, so no frame of it may be marked.
    for _round in 0..2 {
        for light in lights(kind) {
            let frame_light = [FrameLight {
                light,
                texture: textured.then_some(&rig.light_texture),
                casters: None,
                texture_channels: Default::default(),
            }];
            assert_eq!(frame_light[0].kind(), kind);
            for occluders in [&occluder[..], &[]] {
                for surfaces in [false, true] {
                    let frame = Frame {
                        camera: &rig.camera,
                        lights: &frame_light,
                        medium: &medium,
                        occluders,
                        scene_color: &rig.color,
                        scene_depth: &rig.depth,
                        surfaces: surfaces.then_some(Surfaces {
                            normal: &rig.normal,
                            albedo: &rig.albedo,
                        }),
                    };
                    volumetric
                        .prepare(&gpu.device, &gpu.queue, &frame)
                        .unwrap_or_else(|e| panic!("{kind:?}, {settings:?}: {e}"));
                    marks.push(volumetric.is_first_frame());
                }
            }
        }
    }
    (built(gpu) - before, marks)
}

/// `method` at half resolution, on the output format the facade's defaults use. Half
/// resolution uses every pipeline full resolution does (the march's variants do not depend on
/// the scale) and the upsample's too; each frame here plans the upsample's light-kind variant.
fn half_resolution(method: MarchMethod) -> Settings {
    let mut settings = Settings::default();
    settings.march.method = method;
    settings.march.scale = Scale::Half;
    settings
}

/// After `warm_up` of `method`'s settings for every light kind on a new cache, no frame of
/// those settings builds a pipeline or a module (and a second warm-up builds nothing); the
/// first frame of each kind is marked first, no repeated frame is. One test per method, each on
/// a device of its own, so that they run side by side.
fn no_frame_builds_after_warm_up(method: MarchMethod) {
    let rig = rig();
    let settings = half_resolution(method);
    let warm = Cache::new(&rig.gpu.device);
    let before = built(&rig.gpu);
    settings
        .warm_up(&rig.gpu.device, &warm, &LightKind::ALL)
        .unwrap();
    let by_warm_up = built(&rig.gpu) - before;
    // Warming twice builds nothing more.
    let before = built(&rig.gpu);
    settings
        .warm_up(&rig.gpu.device, &warm, &LightKind::ALL)
        .unwrap();
    assert_eq!(built(&rig.gpu), before, "a second warm-up built pipelines");
    let mut failures = Vec::new();
    for kind in LightKind::ALL {
        let (n, marks) = prepare_frames(&rig, &warm, settings, kind);
        if n != 0 {
            failures.push(format!("{kind:?}: {n}"));
        }
        let (first_round, second_round) = marks.split_at(marks.len() / 2);
        assert!(
            first_round[0],
            "{kind:?}: the very first frame is not marked"
        );
        assert!(
            second_round.iter().all(|m| !m),
            "{kind:?}: a repeated frame is marked first: {marks:?}"
        );
    }
    println!(
        "{method:?} at {:?}: warm-up built {by_warm_up}; frames after it built {}",
        settings.march.scale,
        if failures.is_empty() {
            "none".to_string()
        } else {
            failures.join(", ")
        }
    );
    assert!(
        failures.is_empty(),
        "{method:?} at {:?}: frames after warm_up built pipelines or modules: {}",
        settings.march.scale,
        failures.join(", ")
    );
}

#[test]
fn after_warm_up_no_exact_frame_builds_a_pipeline() {
    no_frame_builds_after_warm_up(MarchMethod::Exact);
}

#[test]
fn after_warm_up_no_hybrid_frame_builds_a_pipeline() {
    no_frame_builds_after_warm_up(MarchMethod::Hybrid);
}

#[test]
fn after_warm_up_no_brute_force_frame_builds_a_pipeline() {
    no_frame_builds_after_warm_up(MarchMethod::BruteForce);
}

#[test]
fn after_warm_up_no_textbook_frame_builds_a_pipeline() {
    no_frame_builds_after_warm_up(MarchMethod::Textbook);
}

/// The measure sees what frames build: the same frames on a cold cache (the exact method's;
/// building pipelines on lavapipe is slow) build pipelines, for every light kind.
#[test]
fn cold_frames_build_pipelines_and_the_count_sees_them() {
    let rig = rig();
    let cold = Cache::new(&rig.gpu.device);
    for kind in LightKind::ALL {
        let built = prepare_frames(&rig, &cold, half_resolution(MarchMethod::Exact), kind).0;
        println!("{kind:?}: cold frames built {built} pipelines and modules");
        assert!(
            built > 0,
            "{kind:?}: the cold frames built nothing: the count is blind"
        );
    }
}

#[test]
fn warm_up_refuses_bad_settings_and_builds_nothing() {
    let gpu = HeadlessGpu::new().expect("GPU tests need a wgpu adapter (lavapipe works)");
    let cache = Cache::new(&gpu.device);
    let before = built(&gpu);
    let mut bad = Settings::default();
    bad.march.bisections = 99;
    let depth_format = Settings {
        output_format: wgpu::TextureFormat::Depth32Float,
        ..Settings::default()
    };
    for (settings, field) in [(bad, "bisections"), (depth_format, "output")] {
        let error = settings
            .warm_up(&gpu.device, &cache, &LightKind::ALL)
            .unwrap_err()
            .to_string();
        println!("{error}");
        assert!(error.contains(field), "{error}");
    }
    assert_eq!(built(&gpu), before);
}
