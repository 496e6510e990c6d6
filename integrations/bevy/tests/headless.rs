//! The plugin inside a headless Bevy app (lavapipe works): the in-scatter it writes against
//! volshadow's f64 reference, and cameras, lights, occluders and target sizes changing at run
//! time without a wgpu error.

use std::sync::atomic::{AtomicUsize, Ordering};

use bevy::app::App;
use bevy::asset::{Assets, Handle, RenderAssetUsages};
use bevy::camera::{
    Camera, Camera3d, ClearColorConfig, Exposure, ImageRenderTarget, PerspectiveProjection,
    Projection, RenderTarget, Viewport,
};
use bevy::ecs::prelude::*;
use bevy::image::Image;
use bevy::light::PointLight;
use bevy::math::{UVec2, Vec2, Vec3};
use bevy::mesh::{Mesh, Mesh3d, MeshBuilder, Meshable};
use bevy::pbr::{MeshMaterial3d, StandardMaterial};
use bevy::render::error_handler::{RenderErrorHandler, RenderErrorPolicy};
use bevy::render::render_asset::RenderAssets;
use bevy::render::render_resource::{PipelineCache, TextureFormat, TextureUsages};
use bevy::render::texture::GpuImage;
use bevy::render::view::{DebandDither, Msaa, Tonemapping};
use bevy::render::RenderApp;
use bevy::shape::{Plane3d, Sphere};
use bevy::transform::components::Transform;
use volshadow::glam::camera::rh;
use volshadow::glam::{DMat4, DVec3};
use volshadow::reference::{self, ImageError, TriangleMesh};
use volshadow_bevy::{
    ViewReport, ViewVolshadow, VolshadowDiagnostics, VolshadowLight, VolshadowMedium,
    VolshadowOccluder, VolshadowQuality,
};

const W: u32 = 96;
const H: u32 = 64;
const FOV: f32 = std::f32::consts::FRAC_PI_4;
const NEAR: f32 = 0.1;
const EYE: Vec3 = Vec3::new(0.0, 1.6, 6.0);
const TARGET: Vec3 = Vec3::new(0.0, 1.2, 0.0);
const LIGHT: Vec3 = Vec3::new(0.4, 3.5, -2.5);
const LUMENS: f32 = 400_000.0;
const SPHERE_AT: Vec3 = Vec3::new(0.0, 1.7, -0.9);
const SPHERE_RADIUS: f32 = 0.6;
const GROUND_HALF: f32 = 20.0;

/// wgpu errors Bevy reported (validation, out of memory): the handler counts them.
static RENDER_ERRORS: AtomicUsize = AtomicUsize::new(0);

fn count_errors(
    error: &bevy::render::error_handler::RenderError,
    _: &mut World,
    _: &mut World,
) -> RenderErrorPolicy {
    eprintln!("render error: {error:?}");
    RENDER_ERRORS.fetch_add(1, Ordering::SeqCst);
    RenderErrorPolicy::Ignore
}

fn medium() -> VolshadowMedium {
    VolshadowMedium {
        scattering: volshadow::glam::Vec3::new(0.08, 0.08, 0.09),
        absorption: volshadow::glam::Vec3::splat(0.01),
        phase: volshadow::PhaseFunction::HenyeyGreenstein { g: 0.4 },
        quality: VolshadowQuality::default(),
    }
}

fn sphere_mesh() -> Mesh {
    Sphere::new(SPHERE_RADIUS).mesh().ico(4).unwrap()
}

/// A headless app with the plugin, its wgpu errors counted.
fn headless_app() -> App {
    let mut app = volshadow_bevy::headless::app(true);
    app.insert_resource(RenderErrorHandler(count_errors));
    app
}

fn target_image(app: &mut App, w: u32, h: u32) -> Handle<Image> {
    let mut image = Image::new_target_texture(w, h, TextureFormat::Rgba8UnormSrgb, None);
    image.asset_usage = RenderAssetUsages::RENDER_WORLD;
    image.texture_descriptor.usage |= TextureUsages::COPY_SRC; // read back by `target_bytes`
    app.world_mut().resource_mut::<Assets<Image>>().add(image)
}

#[allow(dead_code)]
struct Scene {
    camera: Entity,
    light: Entity,
    occluder: Entity,
    image: Handle<Image>,
}

fn spawn_scene(app: &mut App, msaa: Msaa) -> Scene {
    let image = target_image(app, W, H);
    let camera = spawn_camera(app, &image, msaa, None, medium());
    let (light, occluder) = spawn_world(app);
    Scene {
        camera,
        light,
        occluder,
        image,
    }
}

/// A camera of the scene drawing into `image`, into the rectangle `viewport` (physical origin
/// and size) when given, with `medium` when given. Without deband dithering, whose noise
/// follows the target's pixels, so that a viewport draws what a target of its size does.
fn spawn_camera(
    app: &mut App,
    image: &Handle<Image>,
    msaa: Msaa,
    viewport: Option<(UVec2, UVec2)>,
    medium: impl Into<Option<VolshadowMedium>>,
) -> Entity {
    let mut camera = app.world_mut().spawn((
        Camera3d::default(),
        Camera {
            viewport: viewport.map(|(physical_position, physical_size)| Viewport {
                physical_position,
                physical_size,
                ..Default::default()
            }),
            ..Default::default()
        },
        RenderTarget::Image(ImageRenderTarget::from(image.clone())),
        Projection::Perspective(PerspectiveProjection {
            fov: FOV,
            near: NEAR,
            ..Default::default()
        }),
        Transform::from_translation(EYE).looking_at(TARGET, Vec3::Y),
        msaa,
        DebandDither::Disabled,
        // Without tonemapping, whose default (TonyMcMapface) needs a table that these headless
        // apps leave out and draws a flat error colour without it.
        Tonemapping::None,
    ));
    if let Some(medium) = medium.into() {
        camera.insert(medium);
    }
    camera.id()
}

/// The scene's point light, lighting the medium.
fn spawn_light(world: &mut World) -> Entity {
    world
        .spawn((
            PointLight {
                intensity: LUMENS,
                ..Default::default()
            },
            Transform::from_translation(LIGHT),
            VolshadowLight::default(),
        ))
        .id()
}

/// The scene's ground plane, as a mesh asset.
fn ground_mesh(world: &mut World) -> Handle<Mesh> {
    world.resource_mut::<Assets<Mesh>>().add(
        Plane3d::new(Vec3::Y, Vec2::splat(GROUND_HALF))
            .mesh()
            .build(),
    )
}

/// The scene's light, its sphere (an occluder) and the ground.
fn spawn_world(app: &mut App) -> (Entity, Entity) {
    let world = app.world_mut();
    let sphere = world.resource_mut::<Assets<Mesh>>().add(sphere_mesh());
    let ground = ground_mesh(world);
    let material = world
        .resource_mut::<Assets<StandardMaterial>>()
        .add(StandardMaterial::default());
    let light = spawn_light(world);
    let occluder = world
        .spawn((
            Mesh3d(sphere),
            MeshMaterial3d(material.clone()),
            Transform::from_translation(SPHERE_AT),
            VolshadowOccluder,
        ))
        .id();
    world.spawn((Mesh3d(ground), MeshMaterial3d(material)));
    (light, occluder)
}

/// The target `image` as Bevy left it: 8-bit sRGB RGBA, row-major from the top row.
fn target_bytes(app: &App, image: &Handle<Image>) -> Vec<u8> {
    let world = app.sub_app(RenderApp).world();
    let images = world.resource::<RenderAssets<GpuImage>>();
    let texture = &images.get(image).expect("the target on the GPU").texture;
    volshadow_bevy::headless::gpu(app)
        .read_texture_bytes(texture)
        .unwrap()
}

/// Updates until no pipeline is waiting, then `extra` frames more.
fn settle(app: &mut App, extra: usize) {
    for _ in 0..50 {
        app.update();
        let waiting = app
            .sub_app(RenderApp)
            .world()
            .get_resource::<PipelineCache>()
            .map_or(0, |c| c.waiting_pipelines().count());
        if waiting == 0 {
            break;
        }
    }
    for _ in 0..extra {
        app.update();
    }
}

fn inscatter(app: &App, camera: Entity) -> Vec<[f32; 4]> {
    let gpu = volshadow_bevy::headless::gpu(app);
    let texture = ViewVolshadow::of(app.sub_app(RenderApp).world(), camera)
        .and_then(|view| view.inscatter(0))
        .expect("the camera's in-scatter after a frame");
    gpu.read_rgba(texture).unwrap()
}

fn report(app: &App, camera: Entity) -> Option<ViewReport> {
    app.world()
        .resource::<VolshadowDiagnostics>()
        .report(camera)
}

/// The same scene in f64: the reference camera from Bevy's projection (infinite, reversed Z),
/// the ico sphere's own triangles as the occluder, the ground plane and the sphere as the
/// surfaces a pixel's ray ends on.
fn reference_image(w: u32, h: u32, shadowed: bool) -> (Vec<DVec3>, Vec<bool>) {
    reference_image_in(w, h, &medium(), shadowed)
}

/// [`reference_image`] in `m`.
fn reference_image_in(
    w: u32,
    h: u32,
    m: &VolshadowMedium,
    shadowed: bool,
) -> (Vec<DVec3>, Vec<bool>) {
    let exposure = Exposure::default().exposure();
    let light = volshadow::PointLight::new(
        volshadow::glam::Vec3::from_array(LIGHT.to_array()),
        volshadow::glam::Vec3::splat(LUMENS * exposure / (4.0 * std::f32::consts::PI)),
    )
    .unwrap();
    reference_of(w, h, m, shadowed, &light)
}

/// What Bevy's camera of a `w × h` target builds: a right-handed view, an infinite reversed-Z
/// projection.
fn reference_camera(w: u32, h: u32) -> volshadow::Camera {
    let v3 = |v: Vec3| volshadow::glam::Vec3::from_array(v.to_array());
    let view = rh::view::look_at_mat4(v3(EYE), v3(TARGET), volshadow::glam::Vec3::Y);
    let projection =
        rh::proj::directx::perspective_infinite_reverse(FOV, w as f32 / h as f32, NEAR);
    volshadow::Camera::new(view, projection).unwrap()
}

/// The ico sphere's own triangles, placed where the scene has it.
fn placed_sphere() -> TriangleMesh {
    let mesh = sphere_mesh();
    let positions: Vec<volshadow::glam::Vec3> = mesh
        .attribute(Mesh::ATTRIBUTE_POSITION)
        .unwrap()
        .as_float3()
        .unwrap()
        .iter()
        .map(|p| volshadow::glam::Vec3::from_array(*p))
        .collect();
    let indices: Vec<u32> = mesh.indices().unwrap().iter().map(|i| i as u32).collect();
    TriangleMesh::from_indexed(
        &positions,
        &indices,
        DMat4::from_translation(DVec3::from_array(SPHERE_AT.to_array().map(f64::from))),
    )
}

/// [`reference_image_in`] lit by `light`.
fn reference_of(
    w: u32,
    h: u32,
    m: &VolshadowMedium,
    shadowed: bool,
    light: &impl reference::LightSource,
) -> (Vec<DVec3>, Vec<bool>) {
    let camera = reference_camera(w, h);
    let placed = placed_sphere();
    let vs_medium = volshadow::Medium::new(m.scattering, m.absorption, m.phase).unwrap();
    let ground = |eye: DVec3, dir: DVec3| {
        if dir.y >= 0.0 {
            return f64::INFINITY;
        }
        let t = -eye.y / dir.y;
        let p = eye + t * dir;
        let half = f64::from(GROUND_HALF);
        if p.x.abs() <= half && p.z.abs() <= half {
            t
        } else {
            f64::INFINITY
        }
    };
    let occluders = [reference::Occluder::Mesh(placed.clone())];
    let image = reference::inscatter_image(
        &camera,
        w,
        h,
        |eye, dir| ground(eye, dir).min(placed.ray_distance(eye, dir)),
        &vs_medium,
        light,
        if shadowed { &occluders } else { &[] },
    );
    let keep = ImageError::keep_away_from_lights(&camera, &[light.light()], w, h);
    (image, keep)
}

fn as_dvec3(pixels: &[[f32; 4]]) -> Vec<DVec3> {
    pixels
        .iter()
        .map(|p| DVec3::new(p[0].into(), p[1].into(), p[2].into()))
        .collect()
}

/// Renders the scene (with `msaa`) and measures the plugin's in-scatter against the
/// reference; also returns the unshadowed reference's error, which shows what leaving the
/// occluder out would read.
fn measure(msaa: Msaa, label: &str) -> (ImageError, ImageError) {
    let mut app = headless_app();
    let scene = spawn_scene(&mut app, msaa);
    settle(&mut app, 2);
    let plan = report(&app, scene.camera);
    assert!(
        matches!(plan, Some(ViewReport::Planned(_))),
        "the plugin's report: {plan:?}"
    );
    let image = as_dvec3(&inscatter(&app, scene.camera));
    assert_eq!(image.len(), (W * H) as usize);
    assert!(image.iter().all(|p| p.is_finite()));
    let (reference_pixels, keep) = reference_image(W, H, true);
    let error = ImageError::measure(&image, &reference_pixels, &keep);
    let (unshadowed, _) = reference_image(W, H, false);
    let without_shadows = ImageError::measure(&unshadowed, &reference_pixels, &keep);
    println!(
        "volshadow_bevy headless {W}x{H}, {label}: p95 {:.3}%, RMSE {:.3}%, max {:.2}% over {} \
         pixels; without the shadows p95 {:.2}%",
        100.0 * error.p95,
        100.0 * error.rmse,
        100.0 * error.max,
        error.counted,
        100.0 * without_shadows.p95
    );
    assert!(
        error.counted > (W * H / 2) as usize,
        "{} counted",
        error.counted
    );
    assert_eq!(RENDER_ERRORS.load(Ordering::SeqCst), 0);
    (error, without_shadows)
}

/// The in-scatter the plugin writes inside Bevy at its defaults (Bevy's 4× MSAA, its depth
/// resolved by the plugin; the plugin's 1% error target; the light converted from lumens)
/// against the f64 reference of the same scene. Bar: p95 1% (issue 39, the plugin's error
/// target). Leaving the sphere out of the occluders reads p95 36% (checked: above 5%);
/// resolving the depth to sample 0 instead of the median read 1.49%, and the plugin's
/// `Adapter` quality on lavapipe (half resolution) 2.27%.
#[test]
fn inscatter_inside_bevy_matches_the_reference() {
    let (error, without_shadows) = measure(Msaa::Sample4, "4x MSAA");
    assert!(error.p95 <= 0.01, "p95 {:.4}", error.p95);
    assert!(
        without_shadows.p95 > 0.05,
        "the shadow should matter: {without_shadows:?}"
    );
}

/// Without MSAA the depth is Bevy's own and the pixel's ray ends where the reference's does:
/// the exact method is exact. Bar: p95 0.1% (the exact method at full resolution is within
/// 0.03% on the crate's standard scenes); measured 0.002%.
#[test]
fn without_msaa_the_inscatter_is_exact() {
    let (error, _) = measure(Msaa::Off, "no MSAA");
    assert!(error.p95 <= 0.001, "p95 {:.5}", error.p95);
}

/// One frame, then the camera's report must be a plan and its in-scatter finite, `w × h`, and
/// Bevy must have seen no wgpu error.
fn frame_is_valid(app: &mut App, camera: Entity, (w, h): (u32, u32), what: &str) -> String {
    app.update();
    let plan = match report(app, camera) {
        Some(ViewReport::Planned(plan)) => plan,
        other => panic!("{what}: the plugin's report is {other:?}"),
    };
    let pixels = inscatter(app, camera);
    assert_eq!(pixels.len(), (w * h) as usize, "{what}: in-scatter size");
    assert!(
        pixels.iter().all(|p| p.iter().all(|v| v.is_finite())),
        "{what}: a pixel is not finite"
    );
    assert_eq!(
        RENDER_ERRORS.load(Ordering::SeqCst),
        0,
        "{what}: a wgpu error"
    );
    plan
}

/// Occluders, lights and cameras added and removed at run time, a mesh asset changed, a mesh
/// that cannot occlude, more lights than volshadow takes, and a target resized: every frame
/// valid (a plan, finite in-scatter of the target's size, no wgpu error). Each step also
/// checks what it should change: the plan's light count, the occluder's shadow, the error
/// named for the bad mesh.
#[test]
fn cameras_lights_occluders_and_sizes_change_at_run_time() {
    let mut app = headless_app();
    let scene = spawn_scene(&mut app, Msaa::Sample4);
    settle(&mut app, 1);
    let camera = scene.camera;
    let shadowed = inscatter(&app, camera);
    frame_is_valid(&mut app, camera, (W, H), "the scene");

    // The occluder goes: the shadow goes with it.
    app.world_mut().despawn(scene.occluder);
    frame_is_valid(&mut app, camera, (W, H), "occluder removed");
    let open = inscatter(&app, camera);
    let brighter = shadowed
        .iter()
        .zip(&open)
        .filter(|(s, o)| o[0] > 1.05 * s[0])
        .count();
    assert!(
        brighter > 100,
        "removing the occluder brightened {brighter} pixels"
    );

    // A new occluder whose mesh asset then changes (a bigger sphere).
    let mesh = app
        .world_mut()
        .resource_mut::<Assets<Mesh>>()
        .add(sphere_mesh());
    let occluder = app
        .world_mut()
        .spawn((
            Mesh3d(mesh.clone()),
            Transform::from_translation(SPHERE_AT),
            VolshadowOccluder,
        ))
        .id();
    frame_is_valid(&mut app, camera, (W, H), "occluder added");
    let small = inscatter(&app, camera);
    let bigger = Sphere::new(2.0 * SPHERE_RADIUS).mesh().ico(3).unwrap();
    app.world_mut()
        .resource_mut::<Assets<Mesh>>()
        .insert(mesh.id(), bigger)
        .unwrap();
    frame_is_valid(&mut app, camera, (W, H), "mesh asset changed");
    let big = inscatter(&app, camera);
    let darker = small
        .iter()
        .zip(&big)
        .filter(|(s, b)| b[0] < 0.95 * s[0])
        .count();
    assert!(darker > 50, "the bigger sphere darkened {darker} pixels");

    // A mesh that cannot occlude (a line list): named, left out, the frame still drawn.
    let lines = app.world_mut().resource_mut::<Assets<Mesh>>().add(
        Mesh::new(
            bevy::mesh::PrimitiveTopology::LineList,
            RenderAssetUsages::default(),
        )
        .with_inserted_attribute(
            Mesh::ATTRIBUTE_POSITION,
            vec![[0.0f32, 0.0, 0.0], [1.0, 1.0, 1.0]],
        ),
    );
    app.world_mut().spawn((
        Mesh3d(lines.clone()),
        Transform::default(),
        VolshadowOccluder,
    ));
    frame_is_valid(&mut app, camera, (W, H), "a line mesh as occluder");
    let why = app
        .world()
        .resource::<volshadow_bevy::OccluderSources>()
        .error(lines.id())
        .map(str::to_owned);
    assert!(
        why.as_deref().is_some_and(|w| w.contains("triangle list")),
        "the line mesh's error: {why:?}"
    );

    // Lights: a spot and a sun join, then five more point lights than volshadow takes.
    app.world_mut().spawn((
        bevy::light::SpotLight {
            intensity: LUMENS,
            outer_angle: 0.5,
            ..Default::default()
        },
        Transform::from_xyz(-1.0, 4.0, -1.0).looking_at(Vec3::ZERO, Vec3::Y),
        VolshadowLight { radius: Some(0.1) },
    ));
    app.world_mut().spawn((
        bevy::light::DirectionalLight::default(),
        Transform::default().looking_to(Vec3::new(0.3, -1.0, -0.2), Vec3::Y),
        VolshadowLight::default(),
    ));
    // A light turned off (zero lumens) is skipped, not an error.
    app.world_mut().spawn((
        PointLight {
            intensity: 0.0,
            ..Default::default()
        },
        Transform::from_xyz(2.0, 3.0, 0.0),
        VolshadowLight::default(),
    ));
    let plan = frame_is_valid(&mut app, camera, (W, H), "spot, sun and a dark light added");
    assert!(!plan.contains("left out)"), "{plan}");
    let extra: Vec<Entity> = (0..3)
        .map(|i| {
            app.world_mut()
                .spawn((
                    PointLight::default(),
                    Transform::from_xyz(i as f32, 5.0, 0.0),
                    VolshadowLight::default(),
                ))
                .id()
        })
        .collect();
    let plan = frame_is_valid(&mut app, camera, (W, H), "six lights");
    assert!(
        plan.contains("2 lights beyond the 4 that add most to this view left out"),
        "{plan}"
    );
    for e in extra {
        app.world_mut().despawn(e);
    }
    app.world_mut().despawn(scene.light);
    frame_is_valid(&mut app, camera, (W, H), "lights removed");

    // A second camera comes and goes; the first one's target is resized.
    let second_target = target_image(&mut app, 40, 30);
    let second = app
        .world_mut()
        .spawn((
            Camera3d::default(),
            Camera {
                order: 1,
                ..Default::default()
            },
            RenderTarget::Image(ImageRenderTarget::from(second_target)),
            Transform::from_xyz(3.0, 2.0, 4.0).looking_at(Vec3::ZERO, Vec3::Y),
            medium(),
        ))
        .id();
    frame_is_valid(&mut app, second, (40, 30), "second camera");
    app.world_mut().despawn(second);
    app.update();
    assert_eq!(
        report(&app, second),
        None,
        "the removed camera's report is dropped"
    );
    let resized = target_image(&mut app, 64, 48);
    app.world_mut()
        .entity_mut(camera)
        .insert(RenderTarget::Image(ImageRenderTarget::from(resized)));
    // A new image reaches the render world a frame after it is added (Bevy's asset pipeline);
    // that frame must be valid too, at whichever size it draws.
    app.update();
    assert!(matches!(report(&app, camera), Some(ViewReport::Planned(_))));
    assert_eq!(RENDER_ERRORS.load(Ordering::SeqCst), 0);
    frame_is_valid(&mut app, camera, (64, 48), "target resized");
    app.world_mut().despawn(occluder);
    frame_is_valid(&mut app, camera, (64, 48), "last occluder removed");
}

/// The part of a plan that names the lights left out (after "left out: "), if any.
fn left_out(plan: &str) -> Option<&str> {
    Some(plan.split_once("left out: ")?.1.trim_end_matches(')'))
}

/// Five equal point lights, two beside each of two cameras 40 m apart and one between them:
/// each camera keeps the four that add most to its own view and leaves out the farthest from
/// it, so the two views leave out different lights, and each plan names its own. Broken
/// variant, checked: one choice for every view in entity order leaves out the same light in
/// both views (camera A left out the A side's first light, 8.7 m away, and failed).
#[test]
fn each_view_takes_the_lights_that_add_most_to_it() {
    let mut app = headless_app();
    let target_a = target_image(&mut app, 48, 32);
    let target_b = target_image(&mut app, 48, 32);
    let world = app.world_mut();
    let camera = |world: &mut World, x: f32, order: isize, target: Handle<Image>| {
        world
            .spawn((
                Camera3d::default(),
                Camera {
                    order,
                    ..Default::default()
                },
                RenderTarget::Image(ImageRenderTarget::from(target)),
                Transform::from_xyz(x, 1.6, 6.0).looking_at(Vec3::new(x, 1.2, 0.0), Vec3::Y),
                medium(),
            ))
            .id()
    };
    let a = camera(world, 0.0, 0, target_a);
    let b = camera(world, 40.0, 1, target_b);
    let lights: Vec<Entity> = [
        (0.0, -2.5),  // A1: 8.7 m from camera A, 40.9 from B
        (1.0, -2.0),  // A2: 8.3 and 39.8
        (20.0, -2.0), // between them: 21.6 from both
        (40.0, -2.5), // B1: 40.9 and 8.7
        (41.0, -2.0), // B2: 41.8 and 8.3
    ]
    .iter()
    .map(|&(x, z)| {
        world
            .spawn((
                PointLight {
                    intensity: LUMENS,
                    ..Default::default()
                },
                Transform::from_xyz(x, 3.5, z),
                VolshadowLight::default(),
            ))
            .id()
    })
    .collect();
    settle(&mut app, 1);
    for (camera, expected, what) in [(a, lights[4], "camera A"), (b, lights[0], "camera B")] {
        let plan = match report(&app, camera) {
            Some(ViewReport::Planned(plan)) => plan,
            other => panic!("{what}: {other:?}"),
        };
        println!("{what}: left out {:?}", left_out(&plan));
        assert_eq!(
            left_out(&plan),
            Some(expected.to_string().as_str()),
            "{what} should leave out only the light farthest from it ({expected}): {plan}"
        );
    }
    assert_eq!(RENDER_ERRORS.load(Ordering::SeqCst), 0);
}

/// The RMSE of two in-scatter images, relative to the mean of `b`.
fn relative_rmse(a: &[[f32; 4]], b: &[[f32; 4]]) -> f64 {
    let (mut sq, mut sum) = (0.0f64, 0.0f64);
    for (p, q) in a.iter().zip(b) {
        for c in 0..3 {
            sq += (f64::from(p[c]) - f64::from(q[c])).powi(2);
            sum += f64::from(q[c]);
        }
    }
    let n = 3.0 * b.len() as f64;
    (sq / n).sqrt() / (sum / n)
}

/// Render layers as Bevy's lights and shadow casters use them: a light lights the views whose
/// layers share one with its own, and an occluder shadows the lights whose layers share one
/// with its own. The camera sees layers 0 and 1, the light is on 0. The sphere on layer 1
/// (drawn, but not the light's caster) casts no shadow: the in-scatter is the one with the
/// sphere not an occluder at all (RMSE below 1e-6 of the mean), where on layer 0 its shadow
/// changes it by more than 1% of the mean (5.3% measured). The light on layer 2 is not the
/// camera's: its plan has no light and says why. Broken variants, checked: an occluder
/// shadowing every light keeps the shadow on layer 1 (difference 0.15; fails), and a light
/// lighting every view leaves the report without the light it does not see (fails).
#[test]
fn render_layers_choose_a_views_lights_and_a_lights_occluders() {
    use bevy::camera::visibility::RenderLayers;
    let mut app = headless_app();
    let scene = spawn_scene(&mut app, Msaa::Off);
    app.world_mut()
        .entity_mut(scene.camera)
        .insert(RenderLayers::from_layers(&[0, 1]));
    settle(&mut app, 1);
    let shadowed = inscatter(&app, scene.camera);

    app.world_mut()
        .entity_mut(scene.occluder)
        .insert(RenderLayers::layer(1));
    settle(&mut app, 1);
    let other_layer = inscatter(&app, scene.camera);

    app.world_mut()
        .entity_mut(scene.occluder)
        .remove::<VolshadowOccluder>();
    settle(&mut app, 1);
    let no_occluder = inscatter(&app, scene.camera);

    let (same, shadow) = (
        relative_rmse(&other_layer, &no_occluder),
        relative_rmse(&shadowed, &no_occluder),
    );
    println!(
        "sphere on layer 1 against no occluder: {same:.2e}; on layer 0 (its shadow): {shadow:.3}"
    );
    assert!(
        shadow > 0.01,
        "the sphere on the light's layer shadows: {shadow}"
    );
    assert!(
        same < 1e-6,
        "the sphere on another layer than the light's: {same}"
    );

    app.world_mut()
        .entity_mut(scene.light)
        .insert(RenderLayers::layer(2));
    settle(&mut app, 1);
    let plan = match report(&app, scene.camera) {
        Some(ViewReport::Planned(plan)) => plan,
        other => panic!("the light on layer 2: {other:?}"),
    };
    println!("{plan}");
    assert!(
        plan.contains("1 lights on render layers this camera does not see"),
        "{plan}"
    );
    assert_eq!(RENDER_ERRORS.load(Ordering::SeqCst), 0);
}

/// A medium unlike [`medium`]: over twice as dense, scattering more forward.
fn thick_medium() -> VolshadowMedium {
    VolshadowMedium {
        scattering: volshadow::glam::Vec3::new(0.2, 0.21, 0.23),
        absorption: volshadow::glam::Vec3::splat(0.02),
        phase: volshadow::PhaseFunction::HenyeyGreenstein { g: 0.7 },
        quality: VolshadowQuality::default(),
    }
}

/// The in-scatter of `camera` against the reference of a `w × h` view in `m`: its p95.
fn inscatter_p95(app: &App, camera: Entity, (w, h): (u32, u32), m: &VolshadowMedium) -> f64 {
    let image = as_dvec3(&inscatter(app, camera));
    assert_eq!(image.len(), (w * h) as usize, "the in-scatter's size");
    let (expected, keep) = reference_image_in(w, h, m, true);
    ImageError::measure(&image, &expected, &keep).p95
}

/// The largest difference, in 8-bit levels, between the `w × h` rectangle at `origin` of the
/// `row`-pixel-wide RGBA image `a` and the whole of `b` (`w` wide).
fn largest_difference(a: &[u8], row: u32, origin: (u32, u32), b: &[u8], w: u32) -> u8 {
    let h = b.len() as u32 / (4 * w);
    let mut largest = 0;
    for y in 0..h {
        for x in 0..4 * w {
            let p = a[(4 * ((origin.1 + y) * row + origin.0) + x) as usize];
            let q = b[(4 * y * w + x) as usize];
            largest = largest.max(p.abs_diff(q));
        }
    }
    largest
}

/// The plan of `camera`, or a panic naming `what` and its report.
fn planned(app: &App, camera: Entity, what: &str) -> String {
    match report(app, camera) {
        Some(ViewReport::Planned(plan)) => plan,
        other => panic!("{what}: the plugin's report is {other:?}"),
    }
}

/// A camera with a viewport (a `W × H` rectangle at (20, 10) of a 128 × 80 target, Bevy's
/// default 4× MSAA, so its depth is resolved and cut out to the rectangle) fogs that rectangle
/// as a camera of a `W × H` target of its own does: its in-scatter is the `W × H` view's
/// against the reference (p95 ≤ 1%, the bar of `inscatter_inside_bevy_matches_the_reference`
/// with MSAA), and the final image's rectangle is the other camera's image to within one 8-bit
/// level (the same values, rounded once; measured 0). Broken variants, checked: the
/// depth read from the target's corner instead of the viewport's (p95 51%), and the fogged
/// rectangle written at the target's corner (179 levels), each fail. The rectangle is
/// also far from the scene without fog (more than 16 levels; measured 212), so that the
/// comparison sees the fog.
#[test]
fn a_camera_with_a_viewport_fogs_its_rectangle_as_a_target_of_its_size() {
    let origin = UVec2::new(20, 10);
    let mut app = headless_app();
    let image = target_image(&mut app, W + 32, H + 16);
    let camera = spawn_camera(
        &mut app,
        &image,
        Msaa::Sample4,
        Some((origin, UVec2::new(W, H))),
        medium(),
    );
    spawn_world(&mut app);
    settle(&mut app, 2);
    println!("{}", planned(&app, camera, "the camera with a viewport"));
    let p95 = inscatter_p95(&app, camera, (W, H), &medium());
    let in_viewport = target_bytes(&app, &image);

    let own_target = own_target_image(medium(), Msaa::Sample4);

    let mut plain = volshadow_bevy::headless::app(false);
    let image_plain = target_image(&mut plain, W, H);
    spawn_camera(&mut plain, &image_plain, Msaa::Sample4, None, None);
    spawn_world(&mut plain);
    settle(&mut plain, 2);
    let no_fog = target_bytes(&plain, &image_plain);
    let largest = largest_difference(&in_viewport, W + 32, (20, 10), &own_target, W);
    let fog = largest_difference(&in_viewport, W + 32, (20, 10), &no_fog, W);
    println!(
        "viewport: in-scatter p95 {:.4}%, image {largest} levels from its own target's, {fog} \
         from the scene without fog",
        100.0 * p95
    );
    assert!(p95 <= 0.01, "in-scatter p95 {p95:.5}");
    assert!(
        largest <= 1,
        "{largest} levels from the image of a target of its own"
    );
    // The image comparison must see the fog: without it the rectangle is far from the image.
    assert!(
        fog > 16,
        "the fog changes the rectangle by {fog} levels only"
    );
    assert_eq!(RENDER_ERRORS.load(Ordering::SeqCst), 0);
}

/// The final image of a camera of the scene alone on a `W × H` target, in `m`.
fn own_target_image(m: VolshadowMedium, msaa: Msaa) -> Vec<u8> {
    let mut app = headless_app();
    let image = target_image(&mut app, W, H);
    spawn_camera(&mut app, &image, msaa, None, m);
    spawn_world(&mut app);
    settle(&mut app, 2);
    target_bytes(&app, &image)
}

/// Two cameras side by side on one target, each with its own medium, `W × H` rectangles at
/// (0, 10) and (W, 10) of a `2W × (H + 16)` target: each is fogged in its own medium
/// (in-scatter against its reference, p95 ≤ 0.1%), and each rectangle of the final image is
/// the image of a camera alone on a `W × H` target in that medium (to within one level;
/// measured 0). Broken variants, checked: the cameras sharing Bevy's main textures (each
/// camera's post-process passes swap them), the plugin's former check that the main texture
/// is the one prepared left the second camera without fog; the depth read from the target's
/// corner reads p95 14% on the right camera; the fogged rectangle written at the target's
/// corner leaves the rectangles 181 and 212 levels from their own targets' images. (Bevy's
/// upscaling copies each camera's rectangle only, so what the region write leaves outside it
/// is not seen in the final image.)
#[test]
fn two_cameras_on_one_target_fog_each_its_viewport_in_its_medium() {
    let mut app = headless_app();
    let image = target_image(&mut app, 2 * W, H + 16);
    let size = UVec2::new(W, H);
    let left = spawn_camera(
        &mut app,
        &image,
        Msaa::Off,
        Some((UVec2::new(0, 10), size)),
        medium(),
    );
    let right = spawn_camera(
        &mut app,
        &image,
        Msaa::Off,
        Some((UVec2::new(W, 10), size)),
        thick_medium(),
    );
    {
        let mut camera = app.world_mut().get_mut::<Camera>(right).unwrap();
        camera.order = 1;
        camera.clear_color = ClearColorConfig::None;
    }
    spawn_world(&mut app);
    settle(&mut app, 2);
    planned(&app, left, "the left camera");
    planned(&app, right, "the right camera");
    let p95_left = inscatter_p95(&app, left, (W, H), &medium());
    let p95_right = inscatter_p95(&app, right, (W, H), &thick_medium());
    let both = target_bytes(&app, &image);
    let left_off = largest_difference(
        &both,
        2 * W,
        (0, 10),
        &own_target_image(medium(), Msaa::Off),
        W,
    );
    let right_off = largest_difference(
        &both,
        2 * W,
        (W, 10),
        &own_target_image(thick_medium(), Msaa::Off),
        W,
    );
    println!(
        "two cameras: p95 {:.4}% (left), {:.4}% (right); rectangles {left_off} and {right_off} \
         levels from their own targets' images",
        100.0 * p95_left,
        100.0 * p95_right
    );
    assert!(p95_left <= 0.001, "left in-scatter p95 {p95_left:.5}");
    assert!(p95_right <= 0.001, "right in-scatter p95 {p95_right:.5}");
    assert!(left_off <= 1, "the left rectangle is {left_off} levels off");
    assert!(
        right_off <= 1,
        "the right rectangle is {right_off} levels off"
    );
    assert_eq!(RENDER_ERRORS.load(Ordering::SeqCst), 0);
}

/// Two cameras on two targets, each with its own medium: each is fogged in its own (in-scatter
/// against its reference, p95 ≤ 0.1%). The same view in the first camera's medium, what one
/// medium for every view would draw for the second, is far from the second's reference (p95
/// above 5%: checked here).
#[test]
fn cameras_on_two_targets_fog_each_in_its_medium() {
    let mut app = headless_app();
    let first = target_image(&mut app, W, H);
    let second = target_image(&mut app, W, H);
    let a = spawn_camera(&mut app, &first, Msaa::Off, None, medium());
    let b = spawn_camera(&mut app, &second, Msaa::Off, None, thick_medium());
    spawn_world(&mut app);
    settle(&mut app, 2);
    planned(&app, a, "the first camera");
    planned(&app, b, "the second camera");
    let p95_a = inscatter_p95(&app, a, (W, H), &medium());
    let p95_b = inscatter_p95(&app, b, (W, H), &thick_medium());
    let one_medium = inscatter_p95(&app, a, (W, H), &thick_medium());
    println!(
        "two targets: p95 {:.4}%, {:.4}%; the first's image against the second's reference \
         {:.1}%",
        100.0 * p95_a,
        100.0 * p95_b,
        100.0 * one_medium
    );
    assert!(one_medium > 0.05, "the media should differ: {one_medium}");
    assert!(p95_a <= 0.001, "first in-scatter p95 {p95_a:.5}");
    assert!(p95_b <= 0.001, "second in-scatter p95 {p95_b:.5}");
    assert_eq!(RENDER_ERRORS.load(Ordering::SeqCst), 0);
}

/// RMSE of `a` against `b` (RGB) over the pixels `keep` marks, relative to `b`'s mean there.
fn masked_relative_rmse(a: &[DVec3], b: &[DVec3], keep: &[bool]) -> f64 {
    let (mut sq, mut sum, mut n) = (0.0, 0.0, 0.0);
    for ((a, b), _) in a.iter().zip(b).zip(keep).filter(|(_, &k)| k) {
        sq += (*a - *b).length_squared();
        sum += b.element_sum();
        n += 3.0;
    }
    (sq / n).sqrt() / (sum / n)
}

/// The decoded value of an sRGB byte (the sRGB transfer function, as the GPU's sRGB formats
/// read it).
fn srgb_to_linear(byte: u8) -> f32 {
    let c = f32::from(byte) / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Bevy's `SpotLightTexture` on a `VolshadowLight` spot is volshadow's textured spot: the
/// image's red channel as a grey mask (all Bevy reads), projected in the frame of the light's
/// transform (its up turns the image about the axis; `bevy_pbr` takes the uv from the
/// transform's inverse). A 16² `Rgba8UnormSrgb` image whose red, green and blue are three
/// unrelated random patterns of 4×4-texel blocks, on a spot whose transform's up is about 90°
/// from the frame volshadow would pick for that axis, over the scene's sphere, without MSAA:
/// the plugin's in-scatter against the reference's textured spot (red texels, decoded from
/// sRGB, as grey; the transform's up as the frame's hint). Bar: volshadow's textured-spot
/// bar, RMSE 3% of the mean (`tests/gpu/textured_spot.rs`); measured 1.61% (lavapipe,
/// 2026-12-04). The same reference with volshadow's own frame, with the image's RGB, and with
/// no texture are each more than 20% from it (measured 380.8%, 380.4%, 1745%), so a plugin
/// that dropped the up, read every channel or ignored the texture fails the bar by far; run:
/// the plugin without the transform's up, 380.9%.
#[test]
fn a_spot_lights_texture_masks_the_fog_by_its_red_channel_in_the_lights_frame() {
    use bevy::light::{SpotLight, SpotLightTexture};
    use bevy::render::render_resource::{Extent3d, TextureDimension};
    use volshadow::reference::TexturedSpot;
    use volshadow::scene::LightTexture;

    let size = 16u32;
    // Three patterns of 4×4 blocks from a fixed LCG: red, green, blue.
    let mut state = 0x9e37_79b9_u32;
    let mut blocks = || -> Vec<u8> {
        (0..16)
            .map(|_| {
                state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                40 + (state >> 24) as u8 % 216
            })
            .collect()
    };
    let (red, green, blue) = (blocks(), blocks(), blocks());
    let block = |b: &[u8], i: u32| b[((i / size / 4) * 4 + (i % size) / 4) as usize];
    let bytes: Vec<u8> = (0..size * size)
        .flat_map(|i| [block(&red, i), block(&green, i), block(&blue, i), 255])
        .collect();
    let texels = |f: &dyn Fn(u32) -> volshadow::glam::Vec3| -> LightTexture {
        LightTexture::new(size, size, (0..size * size).map(f).collect()).unwrap()
    };
    let grey = texels(&|i| volshadow::glam::Vec3::splat(srgb_to_linear(block(&red, i))));
    let colour = texels(&|i| {
        volshadow::glam::Vec3::new(
            srgb_to_linear(block(&red, i)),
            srgb_to_linear(block(&green, i)),
            srgb_to_linear(block(&blue, i)),
        )
    });

    let mut app = headless_app();
    let image = target_image(&mut app, W, H);
    let camera = spawn_camera(&mut app, &image, Msaa::Off, None, medium());
    let (light, _) = spawn_world(&mut app);
    let outer = 0.45f32;
    let aim = Vec3::new(0.0, 0.6, -0.4);
    // Up about +X across the axis, where volshadow's own frame would take +Y.
    let transform = Transform::from_translation(LIGHT).looking_at(aim, Vec3::new(1.0, 0.0, 0.2));
    let mask = Image::new(
        Extent3d {
            width: size,
            height: size,
            depth_or_array_layers: 1,
        },
        TextureDimension::D2,
        bytes,
        TextureFormat::Rgba8UnormSrgb,
        RenderAssetUsages::RENDER_WORLD,
    );
    let mask = app.world_mut().resource_mut::<Assets<Image>>().add(mask);
    let world = app.world_mut();
    world.entity_mut(light).remove::<PointLight>().insert((
        SpotLight {
            intensity: LUMENS,
            outer_angle: outer,
            // A hard cone, as volshadow's (the plugin does not model the falloff).
            inner_angle: outer,
            ..Default::default()
        },
        SpotLightTexture { image: mask },
        transform,
    ));
    settle(&mut app, 2);
    planned(&app, camera, "the textured spot");
    let gpu = as_dvec3(&inscatter(&app, camera));
    assert!(gpu.iter().all(|p| p.is_finite()));
    assert_eq!(RENDER_ERRORS.load(Ordering::SeqCst), 0);

    let v3 = |v: Vec3| volshadow::glam::Vec3::from_array(v.to_array());
    let exposure = Exposure::default().exposure();
    let spot = volshadow::SpotLight::new(
        v3(LIGHT),
        v3(aim - LIGHT),
        2.0 * outer,
        volshadow::glam::Vec3::splat(LUMENS * exposure / (4.0 * std::f32::consts::PI)),
    )
    .unwrap();
    let turned = spot.with_texture_up(v3(transform.up().into())).unwrap();
    let reference_with = |spot: volshadow::SpotLight, texture: &LightTexture| {
        reference_of(W, H, &medium(), true, &TexturedSpot::new(spot, texture))
    };
    let (truth, keep) = reference_with(turned, &grey);
    let rmse = masked_relative_rmse(&gpu, &truth, &keep);
    let unturned = masked_relative_rmse(&reference_with(spot, &grey).0, &truth, &keep);
    let coloured = masked_relative_rmse(&reference_with(turned, &colour).0, &truth, &keep);
    let plain = masked_relative_rmse(
        &reference_of(W, H, &medium(), true, &turned).0,
        &truth,
        &keep,
    );
    println!(
        "volshadow_bevy headless {W}x{H}, SpotLightTexture: RMSE {:.2}% of the mean; the \
         reference with volshadow's own frame {:.1}%, with the image's RGB {:.1}%, untextured \
         {:.1}%",
        100.0 * rmse,
        100.0 * unturned,
        100.0 * coloured,
        100.0 * plain
    );
    assert!(
        unturned > 0.2 && coloured > 0.2 && plain > 0.2,
        "the frame, the channel and the texture must each change the image: {unturned:.3}, \
         {coloured:.3}, {plain:.3}"
    );
    assert!(rmse <= 0.03, "RMSE {rmse:.4}");
}

/// Which of the scene's surfaces a ray ends on.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Surface {
    Sky,
    Ground,
    Sphere,
}

/// The scene's surfaces for [`VolshadowSurfaces`](volshadow_bevy::VolshadowSurfaces) tests:
/// the light, the sphere (not an occluder: the surface term is unshadowed, and without a
/// shadow the in-scatter does not hide it) and the ground, each with its own material.
fn spawn_surfaces_world(
    app: &mut App,
    ground: StandardMaterial,
    sphere: StandardMaterial,
) -> Entity {
    let world = app.world_mut();
    let sphere_mesh = world.resource_mut::<Assets<Mesh>>().add(sphere_mesh());
    let ground_mesh = ground_mesh(world);
    let mut materials = world.resource_mut::<Assets<StandardMaterial>>();
    let (ground, sphere) = (materials.add(ground), materials.add(sphere));
    world.spawn((
        Mesh3d(sphere_mesh),
        MeshMaterial3d(sphere),
        Transform::from_translation(SPHERE_AT),
    ));
    world.spawn((Mesh3d(ground_mesh), MeshMaterial3d(ground)));
    spawn_light(world)
}

/// A float target (`Rgba16Float`, the HDR main texture's format), read back as f32.
fn float_target_image(app: &mut App, w: u32, h: u32) -> Handle<Image> {
    let mut image = Image::new_target_texture(w, h, TextureFormat::Rgba16Float, None);
    image.asset_usage = RenderAssetUsages::RENDER_WORLD;
    image.texture_descriptor.usage |= TextureUsages::COPY_SRC;
    app.world_mut().resource_mut::<Assets<Image>>().add(image)
}

fn float_target(app: &App, image: &Handle<Image>) -> Vec<[f32; 4]> {
    let world = app.sub_app(RenderApp).world();
    let images = world.resource::<RenderAssets<GpuImage>>();
    let texture = &images.get(image).expect("the target on the GPU").texture;
    volshadow_bevy::headless::gpu(app)
        .read_rgba(texture)
        .unwrap()
}

/// The final image with the camera's [`VolshadowSurfaces`](volshadow_bevy::VolshadowSurfaces)
/// minus the same frame without them: what the surface term adds (the composite adds it under
/// the medium's transmittance); and, per pixel, how far the two images' rounding to the HDR
/// target's half floats can move that difference (2⁻¹¹ of each, per channel).
fn surface_term_of(
    app: &mut App,
    camera: Entity,
    image: &Handle<Image>,
) -> (Vec<DVec3>, Vec<DVec3>) {
    settle(app, 2);
    let plan = planned(app, camera, "with surfaces");
    let with = as_dvec3(&float_target(app, image));
    app.world_mut()
        .entity_mut(camera)
        .remove::<volshadow_bevy::VolshadowSurfaces>();
    settle(app, 2);
    planned(app, camera, "without surfaces");
    let without = as_dvec3(&float_target(app, image));
    assert_eq!(RENDER_ERRORS.load(Ordering::SeqCst), 0, "{plan}");
    let half = 2f64.powi(-11);
    with.iter()
        .zip(&without)
        .map(|(a, b)| (*a - *b, half * (a.abs() + b.abs())))
        .unzip()
}

/// The reference's surface irradiance of the scene of [`spawn_surfaces_world`], seen through the
/// medium, at every `step`-th pixel in each direction and every other pixel of the sphere,
/// where the pixel's 3×3 neighbourhood ends on one surface (no silhouette, no sky): the pixel, its surface and `E(P) · e^(−σt·|P − eye|)`, `E`
/// from `reference::surface_inscatter` (its own quadrature over the hemisphere), at the f64
/// ray's hit on the ico sphere's triangles or the ground, the sphere's normal its analytic one.
/// The surface term is this times `ρ/π`. Computed once (about half a minute), for both
/// surface tests.
fn surface_irradiance_reference() -> &'static [(usize, Surface, DVec3)] {
    static IRRADIANCE: std::sync::OnceLock<Vec<(usize, Surface, DVec3)>> =
        std::sync::OnceLock::new();
    IRRADIANCE.get_or_init(|| surface_irradiance_of(&medium(), 4))
}

fn surface_irradiance_of(m: &VolshadowMedium, step: u32) -> Vec<(usize, Surface, DVec3)> {
    let v3 = |v: Vec3| volshadow::glam::Vec3::from_array(v.to_array());
    let camera = reference_camera(W, H);
    let centre = DVec3::from_array(SPHERE_AT.to_array().map(f64::from));
    let placed = placed_sphere();
    let hit = |px: u32, py: u32| -> (Surface, DVec3, f64) {
        let (eye, dir) = reference::camera_ray(&camera, reference::pixel_ndc(W, H, px, py));
        let sphere = placed.ray_distance(eye, dir);
        let mut ground = f64::INFINITY;
        if dir.y < 0.0 {
            let t = -eye.y / dir.y;
            let p = eye + t * dir;
            let half = f64::from(GROUND_HALF);
            if p.x.abs() <= half && p.z.abs() <= half {
                ground = t;
            }
        }
        let (surface, t) = if sphere < ground {
            (Surface::Sphere, sphere)
        } else if ground.is_finite() {
            (Surface::Ground, ground)
        } else {
            (Surface::Sky, f64::INFINITY)
        };
        (surface, eye + t * dir, t)
    };
    let exposure = Exposure::default().exposure();
    let light = volshadow::PointLight::new(
        v3(LIGHT),
        volshadow::glam::Vec3::splat(LUMENS * exposure / (4.0 * std::f32::consts::PI)),
    )
    .unwrap();
    let vs_medium = volshadow::Medium::new(m.scattering, m.absorption, m.phase).unwrap();
    let sigma_t = (m.scattering + m.absorption).as_dvec3();
    let mut out = Vec::new();
    for py in 1..H - 1 {
        for px in 1..W - 1 {
            let on_grid = px % step == 1 && py % step == 1;
            let (surface, p, t) = hit(px, py);
            // The sphere is small in the view: every other pixel of it (a checkerboard).
            let sampled = on_grid || (surface == Surface::Sphere && px % 2 == py % 2);
            if !sampled || surface == Surface::Sky {
                continue;
            }
            let alone = (0..9).all(|k| hit(px + k % 3 - 1, py + k / 3 - 1).0 == surface);
            if !alone {
                continue;
            }
            let n = match surface {
                Surface::Sphere => (p - centre).normalize(),
                _ => DVec3::Y,
            };
            let e = reference::surface_inscatter(p, n, &vs_medium, &light);
            out.push(((py * W + px) as usize, surface, e * (-sigma_t * t).exp()));
        }
    }
    out
}

/// The surface term `ρ/π · E` of `irradiance` with `albedo` giving each surface's ρ, as an
/// image of `len` pixels (zero where not sampled) and as the sampled pixels' terms.
fn surface_term(
    irradiance: &[(usize, Surface, DVec3)],
    albedo: impl Fn(Surface) -> DVec3,
) -> Vec<(usize, DVec3)> {
    irradiance
        .iter()
        .map(|(k, s, e)| (*k, albedo(*s) / std::f64::consts::PI * *e))
        .collect()
}

fn term_image(terms: &[(usize, DVec3)]) -> Vec<DVec3> {
    let mut image = vec![DVec3::ZERO; (W * H) as usize];
    for (k, t) in terms {
        image[*k] = *t;
    }
    image
}

/// The largest relative error of `gpu` at the reference's pixels whose term is above 1% of the
/// largest (the library's surface-term test counts the same pixels), per channel, less the
/// half-float rounding `rounding` allows there; and how many pixels were counted.
fn surface_term_error(
    gpu: &[DVec3],
    rounding: &[DVec3],
    reference: &[(usize, DVec3)],
) -> (f64, usize) {
    let largest = reference
        .iter()
        .map(|(_, t)| t.max_element())
        .fold(0.0, f64::max);
    let mut worst: f64 = 0.0;
    let mut counted = 0;
    for (k, t) in reference {
        if t.max_element() < 0.01 * largest {
            continue;
        }
        counted += 1;
        for c in 0..3 {
            let off = ((gpu[*k][c] - t[c]).abs() - rounding[*k][c]).max(0.0);
            worst = worst.max(off / t[c]);
        }
    }
    (worst, counted)
}

/// The 95th percentile of the same relative errors as [`surface_term_error`].
fn surface_term_p95(gpu: &[DVec3], rounding: &[DVec3], reference: &[(usize, DVec3)]) -> f64 {
    let largest = reference
        .iter()
        .map(|(_, t)| t.max_element())
        .fold(0.0, f64::max);
    let mut errors: Vec<f64> = reference
        .iter()
        .filter(|(_, t)| t.max_element() >= 0.01 * largest)
        .flat_map(|(k, t)| {
            (0..3).map(move |c| ((gpu[*k][c] - t[c]).abs() - rounding[*k][c]).max(0.0) / t[c])
        })
        .collect();
    errors.sort_by(f64::total_cmp);
    errors[(errors.len() * 95 / 100).min(errors.len() - 1)]
}

/// A forward camera's surface term with `msaa` and the surfaces' albedo `albedo`: the final
/// image's gain from [`VolshadowSurfaces`](volshadow_bevy::VolshadowSurfaces), and its rounding.
fn forward_surface_term(msaa: Msaa, albedo: volshadow::glam::Vec3) -> (Vec<DVec3>, Vec<DVec3>) {
    let mut app = headless_app();
    let image = float_target_image(&mut app, W, H);
    let camera = spawn_camera(&mut app, &image, msaa, None, medium());
    app.world_mut()
        .entity_mut(camera)
        .insert(volshadow_bevy::VolshadowSurfaces { albedo });
    // Black, without specular: Bevy's own lighting adds nothing to round.
    let black = StandardMaterial {
        base_color: bevy::color::Color::BLACK,
        reflectance: 0.0,
        ..Default::default()
    };
    spawn_surfaces_world(&mut app, black.clone(), black);
    let (gpu, rounding) = surface_term_of(&mut app, camera, &image);
    assert!(gpu.iter().all(|p| p.is_finite()));
    (gpu, rounding)
}

/// [`VolshadowSurfaces`](volshadow_bevy::VolshadowSurfaces) on a forward camera: the light the
/// medium scatters onto the ground and the sphere, from Bevy's normal prepass (decoded) and
/// the component's albedo (one per channel), is what the final image gains over the same frame
/// without the component, against the reference's surface term (every 4th pixel away from
/// silhouettes, those above 1% of the largest, less the HDR target's half-float rounding of
/// the two images). Bar: at most 1% everywhere, the library's surface-term bar
/// (`iss_table::frame_of_ground_and_wall_matches_the_reference`), without MSAA, and with
/// Bevy's default 4× MSAA (each pixel the normal of the sample whose depth the resolve
/// picks) on the sphere. With MSAA the ground is characterised, not held to the bar: the
/// resolved depth is one sample's, up to ⅜ of a pixel from the centre the composite casts its
/// ray through, and on ground seen at a few degrees 96 pixels across that moves the surface
/// point by metres (measured p95 5.38%, worst 10.3%, at 96×64, shrinking with the pixels'
/// angle; the plugin's README names it). The reference with the channels' albedos swapped is
/// far beyond the bar (checked: above 10%), so a plugin that mixed them fails. Broken
/// variants, run (lavapipe, 2026-12-04; measured 0.19% and, with MSAA on the sphere, 0.45%):
/// the stored `n·½ + ½` taken as the normal, 123.3%, fails. Reading the multisampled normal at
/// sample 0 instead of the resolve's sample gave 0.90% on the sphere and passes: away from
/// silhouettes a pixel's samples see one surface, so this test does not tell them apart.
#[test]
fn a_forward_cameras_surfaces_take_the_mediums_light_from_the_normal_prepass() {
    let albedo = volshadow::glam::Vec3::new(0.8, 0.5, 0.25);
    let rho = albedo.as_dvec3();
    let irradiance = surface_irradiance_reference();
    let reference = surface_term(irradiance, |_| rho);
    let (gpu, rounding) = forward_surface_term(Msaa::Off, albedo);
    let (worst, counted) = surface_term_error(&gpu, &rounding, &reference);
    let (gpu_ms, rounding_ms) = forward_surface_term(Msaa::Sample4, albedo);
    let (worst_ms, _) = surface_term_error(&gpu_ms, &rounding_ms, &reference);
    let p95_ms = surface_term_p95(&gpu_ms, &rounding_ms, &reference);
    let on_sphere: Vec<(usize, DVec3)> = irradiance
        .iter()
        .zip(&reference)
        .filter(|((_, s, _), _)| *s == Surface::Sphere)
        .map(|(_, r)| *r)
        .collect();
    let (sphere_ms, sphere_counted) = surface_term_error(&gpu_ms, &rounding_ms, &on_sphere);
    let swapped = surface_term(irradiance, |_| DVec3::new(rho.z, rho.y, rho.x));
    let exact = vec![DVec3::ZERO; gpu.len()];
    let (channels, _) = surface_term_error(&term_image(&swapped), &exact, &reference);
    println!(
        "volshadow_bevy headless {W}x{H}, forward surfaces: worst relative error {:.2}% over \
         {counted} pixels; with 4x MSAA worst {:.2}% on the sphere ({sphere_counted} pixels), \
         p95 {:.2}% and worst {:.2}% on all; the channels' albedos swapped {:.1}%",
        100.0 * worst,
        100.0 * sphere_ms,
        100.0 * p95_ms,
        100.0 * worst_ms,
        100.0 * channels
    );
    assert!(counted > 100, "{counted} pixels counted");
    assert!(channels > 0.1, "{channels}");
    assert!(worst <= 0.01, "worst relative error {worst:.4}");
    assert!(
        sphere_counted > 30,
        "{sphere_counted} sphere pixels counted"
    );
    assert!(sphere_ms <= 0.01, "with MSAA, on the sphere {sphere_ms:.4}");
}

/// [`VolshadowSurfaces`](volshadow_bevy::VolshadowSurfaces) on a deferred camera: each
/// material's diffuse colour from Bevy's G-buffer (the ground's base colour; the sphere's base
/// colour times `1 − metallic` at metallic 0.4), not the component's albedo. As the forward
/// test: the final image's gain against the reference's surface term, bar 1% (the library's
/// surface-term bar; the G-buffer's 8-bit colour adds at most 0.3% here). The reference with
/// the G-buffer's stored `pow(base, 1/2.2)` as the albedo, and with the metallic ignored, are
/// each beyond it (checked: above 10%), so a plugin that skipped the decode or read the base
/// colour as diffuse fails. Measured 0.56% (lavapipe, 2026-12-04); broken variants, run: the
/// base colour not raised to 2.2, 179.3%; the metallic ignored, 66.0%; the normal not
/// decoded, 123.0%.
#[test]
fn a_deferred_cameras_surfaces_take_each_materials_colour_from_the_g_buffer() {
    use bevy::core_pipeline::prepass::{DeferredPrepass, DepthPrepass};
    use bevy::material::OpaqueRendererMethod;
    use volshadow_bevy::VolshadowSurfaces;
    let mut app = headless_app();
    let image = float_target_image(&mut app, W, H);
    let camera = spawn_camera(&mut app, &image, Msaa::Off, None, medium());
    app.world_mut().entity_mut(camera).insert((
        DepthPrepass,
        DeferredPrepass,
        VolshadowSurfaces {
            albedo: volshadow::glam::Vec3::splat(0.05),
        },
    ));
    let (ground, sphere) = ([0.8f32, 0.45, 0.2], [0.15f32, 0.5, 0.9]);
    let metallic = 0.4f32;
    let material = |rgb: [f32; 3], metallic: f32| StandardMaterial {
        base_color: bevy::color::Color::linear_rgb(rgb[0], rgb[1], rgb[2]),
        metallic,
        opaque_render_method: OpaqueRendererMethod::Deferred,
        ..Default::default()
    };
    spawn_surfaces_world(&mut app, material(ground, 0.0), material(sphere, metallic));
    let (gpu, rounding) = surface_term_of(&mut app, camera, &image);
    let exact = vec![DVec3::ZERO; gpu.len()];
    assert!(gpu.iter().all(|p| p.is_finite()));
    let d = |rgb: [f32; 3]| DVec3::from_array(rgb.map(f64::from));
    let diffuse = move |s: Surface, metallic: f64| match s {
        Surface::Sphere => d(sphere) * (1.0 - metallic),
        _ => d(ground),
    };
    let irradiance = surface_irradiance_reference();
    let reference = surface_term(irradiance, |s| diffuse(s, metallic.into()));
    let (worst, counted) = surface_term_error(&gpu, &rounding, &reference);
    let encoded = surface_term(irradiance, |s| diffuse(s, metallic.into()).powf(1.0 / 2.2));
    let (undecoded, _) = surface_term_error(&term_image(&encoded), &exact, &reference);
    let base = surface_term(irradiance, |s| diffuse(s, 0.0));
    let (no_metallic, _) = surface_term_error(&term_image(&base), &exact, &reference);
    println!(
        "volshadow_bevy headless {W}x{H}, deferred surfaces: worst relative error {:.2}% over \
         {counted} pixels; the stored pow(rgb, 1/2.2) as albedo {:.1}%, the metallic ignored \
         {:.1}%",
        100.0 * worst,
        100.0 * undecoded,
        100.0 * no_metallic
    );
    assert!(counted > 100, "{counted} pixels counted");
    assert!(
        undecoded > 0.1 && no_metallic > 0.1,
        "{undecoded} {no_metallic}"
    );
    assert!(worst <= 0.01, "worst relative error {worst:.4}");
}
