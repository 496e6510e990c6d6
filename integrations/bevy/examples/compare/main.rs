//! The quickstart's scene (a point light behind two spheres in hazy air, over a ground) built
//! from Bevy entities and PBR materials, rendered headless to PNGs: once through volshadow, once
//! through Bevy's own `VolumetricFog` with the parameters mapped as closely as the two models
//! allow (see the plugin's README).
//!
//! `cargo run --release -p volshadow_bevy --example compare --ignore-rust-version` writes
//! `out/bevy_volshadow.png` and `out/bevy_fog.png`; `-- --size 480x270` sets the size,
//! `-- --mode volshadow` (or `bevy`) renders one of them. `-- --table --size 160x90` prints the
//! side-by-side table instead: each renderer's in-scatter (black surfaces, no tone mapping)
//! against volshadow's f64 reference, and its time per frame. `-- --first-frames` times the
//! first frames of a new app, with and without volshadow (the cold start).

use bevy::app::App;
use bevy::asset::{Assets, Handle};
use bevy::camera::{
    Camera, Camera3d, ImageRenderTarget, PerspectiveProjection, Projection, RenderTarget,
};
use bevy::color::Color;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::ecs::prelude::*;
use bevy::image::Image;
use bevy::light::{FogVolume, PointLight, VolumetricFog, VolumetricLight};
use bevy::math::{Vec2, Vec3};
use bevy::mesh::{Mesh, Mesh3d, MeshBuilder, Meshable};
use bevy::pbr::{MeshMaterial3d, StandardMaterial};
use bevy::render::render_asset::RenderAssets;
use bevy::render::render_resource::{TextureFormat, TextureUsages};
use bevy::render::texture::GpuImage;
use bevy::render::view::Msaa;
use bevy::render::RenderApp;
use bevy::shape::{Plane3d, Sphere};
use bevy::transform::components::Transform;
use volshadow::{wgpu, HeadlessGpu};
use volshadow_bevy::{VolshadowLight, VolshadowMedium, VolshadowOccluder};

/// Which renderer draws the medium.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// volshadow, through the plugin, at its defaults.
    Volshadow,
    /// Bevy's `VolumetricFog` at its default 64 steps.
    BevyFog,
    /// Bevy's `VolumetricFog` at this many steps.
    BevyFogSteps(u32),
    /// Neither: the scene without a medium (the timing baseline).
    Plain,
}

impl Mode {
    fn bevy_steps(self) -> Option<u32> {
        match self {
            Mode::BevyFog => Some(64),
            Mode::BevyFogSteps(n) => Some(n),
            _ => None,
        }
    }
}

/// How the scene is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Look {
    /// Grey PBR materials, tone-mapped (ACES) into 8-bit sRGB: the picture.
    Picture,
    /// Black surfaces, no tone mapping, a float target: the image is the medium's in-scatter
    /// alone, to measure against the reference.
    Inscatter,
}

/// The medium: σs, σa (per metre, grey) and Henyey–Greenstein g.
pub const SIGMA_S: f32 = 0.06;
/// Absorption.
pub const SIGMA_A: f32 = 0.006;
/// Phase asymmetry.
pub const G: f32 = 0.6;
/// The light's flux (lumens).
pub const LUMENS: f32 = 2.0e6;
/// The camera's place and aim.
pub const EYE: Vec3 = Vec3::new(0.0, 1.6, 7.0);
/// Where it looks.
pub const TARGET: Vec3 = Vec3::new(0.0, 1.3, 0.0);
/// The light, behind the spheres.
pub const LIGHT: Vec3 = Vec3::new(0.1, 2.9, -4.6);
/// The spheres' centres (radius 0.5).
pub const SPHERES: [(f32, f32, f32); 2] = [(-0.55, 1.7, -2.0), (0.65, 2.2, -2.6)];
/// Bevy's fog box: it holds the camera, the light, the spheres and the ground out to 20 m.
pub const FOG_BOX_CENTRE: Vec3 = Vec3::new(0.0, 5.0, -6.0);
/// Its size.
pub const FOG_BOX_SIZE: Vec3 = Vec3::new(40.0, 10.0, 28.0);
/// The camera's vertical field of view.
pub const FOV: f32 = 0.959_931; // 55°
/// Its near plane.
pub const NEAR: f32 = 0.05;

fn app(mode: Mode) -> App {
    volshadow_bevy::headless::app(mode == Mode::Volshadow)
}

/// The medium of [`SIGMA_S`], [`SIGMA_A`] and [`G`] for volshadow.
pub fn medium() -> VolshadowMedium {
    VolshadowMedium {
        scattering: volshadow::glam::Vec3::splat(SIGMA_S),
        absorption: volshadow::glam::Vec3::splat(SIGMA_A),
        phase: volshadow::PhaseFunction::HenyeyGreenstein { g: G },
        ..Default::default()
    }
}

/// Bevy's fog settings for the camera: no ambient light, no jitter, `steps` steps.
pub fn bevy_fog(steps: u32) -> VolumetricFog {
    VolumetricFog {
        ambient_intensity: 0.0,
        jitter: 0.0,
        step_count: steps,
        ..Default::default()
    }
}

/// Bevy's fog volume for the same medium, a box around the scene.
pub fn fog_volume() -> (FogVolume, Transform) {
    // σ = density_factor · coefficient: density 1 and the coefficients themselves.
    (
        FogVolume {
            density_factor: 1.0,
            scattering: SIGMA_S,
            absorption: SIGMA_A,
            scattering_asymmetry: G,
            ..Default::default()
        },
        Transform::from_translation(FOG_BOX_CENTRE).with_scale(FOG_BOX_SIZE),
    )
}

/// Spawns the scene for `mode` into `world`, rendering into `target`.
pub fn spawn(
    world: &mut World,
    mode: Mode,
    look: Look,
    msaa: Msaa,
    target: RenderTarget,
) -> Entity {
    let (sphere, ground) = {
        let mut meshes = world.resource_mut::<Assets<Mesh>>();
        (
            meshes.add(Sphere::new(0.5).mesh().ico(4).unwrap()),
            meshes.add(Plane3d::new(Vec3::Y, Vec2::splat(20.0)).mesh().build()),
        )
    };
    let (grey, white) = {
        let mut materials = world.resource_mut::<Assets<StandardMaterial>>();
        let black = StandardMaterial {
            base_color: Color::BLACK,
            reflectance: 0.0,
            ..Default::default()
        };
        if look == Look::Inscatter {
            (materials.add(black.clone()), materials.add(black))
        } else {
            (
                materials.add(StandardMaterial {
                    base_color: Color::srgb(0.4, 0.4, 0.42),
                    perceptual_roughness: 0.9,
                    ..Default::default()
                }),
                materials.add(StandardMaterial {
                    base_color: Color::srgb(0.8, 0.78, 0.75),
                    perceptual_roughness: 0.6,
                    ..Default::default()
                }),
            )
        }
    };
    let mut camera = world.spawn((
        Camera3d::default(),
        Camera::default(),
        target,
        Projection::Perspective(PerspectiveProjection {
            fov: FOV,
            near: NEAR,
            ..Default::default()
        }),
        match look {
            Look::Picture => Tonemapping::AcesFitted,
            Look::Inscatter => Tonemapping::None,
        },
        bevy::camera::Hdr,
        msaa,
        Transform::from_translation(EYE).looking_at(TARGET, Vec3::Y),
    ));
    match mode {
        Mode::Plain => {}
        Mode::Volshadow => {
            camera.insert(medium());
        }
        Mode::BevyFog | Mode::BevyFogSteps(_) => {
            camera.insert(bevy_fog(mode.bevy_steps().unwrap_or(64)));
        }
    }
    let camera = camera.id();
    let mut light = world.spawn((
        PointLight {
            intensity: LUMENS,
            range: 100.0,
            shadow_maps_enabled: true,
            ..Default::default()
        },
        Transform::from_translation(LIGHT),
    ));
    match mode {
        Mode::Volshadow => {
            light.insert(VolshadowLight::default());
        }
        Mode::BevyFog | Mode::BevyFogSteps(_) => {
            light.insert(VolumetricLight);
        }
        Mode::Plain => {}
    }
    for (x, y, z) in SPHERES {
        let mut s = world.spawn((
            Mesh3d(sphere.clone()),
            MeshMaterial3d(white.clone()),
            Transform::from_xyz(x, y, z),
        ));
        if mode == Mode::Volshadow {
            s.insert(VolshadowOccluder);
        }
    }
    world.spawn((Mesh3d(ground), MeshMaterial3d(grey)));
    if mode.bevy_steps().is_some() {
        // Bevy's fog lives in a box; this one holds the camera, the light and the ground.
        world.spawn(fog_volume());
    }
    camera
}

/// A headless app with the scene of `mode`, rendering into a `width × height` target.
pub struct Rendered {
    app: App,
    target: Handle<Image>,
}

impl Rendered {
    /// Builds the app and renders four frames (pipelines compile synchronously).
    pub fn new(mode: Mode, look: Look, msaa: Msaa, width: u32, height: u32) -> Self {
        let mut rendered = Self::unrendered(mode, look, msaa, width, height);
        for _ in 0..4 {
            rendered.frame();
        }
        rendered
    }

    /// Builds the app and spawns the scene without rendering a frame.
    pub fn unrendered(mode: Mode, look: Look, msaa: Msaa, width: u32, height: u32) -> Self {
        let mut app = app(mode);
        let format = match look {
            Look::Picture => TextureFormat::Rgba8UnormSrgb,
            Look::Inscatter => TextureFormat::Rgba32Float,
        };
        let mut image = Image::new_target_texture(width, height, format, None);
        image.texture_descriptor.usage |= TextureUsages::COPY_SRC;
        let target = app.world_mut().resource_mut::<Assets<Image>>().add(image);
        let image_target = RenderTarget::Image(ImageRenderTarget::from(target.clone()));
        spawn(app.world_mut(), mode, look, msaa, image_target);
        Self { app, target }
    }

    fn gpu(&self) -> HeadlessGpu {
        volshadow_bevy::headless::gpu(&self.app)
    }

    /// One more frame, waited for on the GPU.
    pub fn frame(&mut self) {
        self.app.update();
        let _ = self.gpu().device.poll(wgpu::PollType::wait_indefinitely());
    }

    /// The target's bytes (8-bit sRGB RGBA, or f32 RGBA for [`Look::Inscatter`]).
    pub fn bytes(&self) -> Vec<u8> {
        let world = self.app.sub_app(RenderApp).world();
        let image = world
            .resource::<RenderAssets<GpuImage>>()
            .get(&self.target)
            .expect("the target image on the GPU");
        self.gpu()
            .read_texture_bytes(&image.texture)
            .expect("readback")
    }
}

/// Renders the picture of `mode` at `width × height`: its 8-bit sRGB RGBA pixels.
pub fn render(mode: Mode, width: u32, height: u32) -> Vec<u8> {
    Rendered::new(mode, Look::Picture, Msaa::default(), width, height).bytes()
}

/// The scene's in-scatter in f64 (`volshadow::reference`), for [`Look::Inscatter`] images.
fn reference(width: u32, height: u32) -> (Vec<volshadow::glam::DVec3>, Vec<bool>) {
    use volshadow::glam::{camera::rh, DMat4, DVec3, Vec3 as V3};
    use volshadow::reference::{self, ImageError, Occluder, TriangleMesh};
    let v3 = |v: Vec3| V3::from_array(v.to_array());
    let view = rh::view::look_at_mat4(v3(EYE), v3(TARGET), V3::Y);
    let aspect = width as f32 / height as f32;
    let projection = rh::proj::directx::perspective_infinite_reverse(FOV, aspect, NEAR);
    let camera = volshadow::Camera::new(view, projection).unwrap();
    let mesh = Sphere::new(0.5).mesh().ico(4).unwrap();
    let positions: Vec<V3> = mesh
        .attribute(Mesh::ATTRIBUTE_POSITION)
        .unwrap()
        .as_float3()
        .unwrap()
        .iter()
        .map(|p| V3::from_array(*p))
        .collect();
    let indices: Vec<u32> = mesh.indices().unwrap().iter().map(|i| i as u32).collect();
    let spheres: Vec<TriangleMesh> = SPHERES
        .iter()
        .map(|&(x, y, z)| {
            let at = DMat4::from_translation(DVec3::new(x.into(), y.into(), z.into()));
            TriangleMesh::from_indexed(&positions, &indices, at)
        })
        .collect();
    let occluders: Vec<Occluder> = spheres.iter().cloned().map(Occluder::Mesh).collect();
    let exposure = bevy::camera::Exposure::default().exposure();
    let light = volshadow::PointLight::new(
        v3(LIGHT),
        V3::splat(LUMENS * exposure / (4.0 * std::f32::consts::PI)),
    )
    .unwrap();
    let medium = volshadow::Medium::new(
        V3::splat(SIGMA_S),
        V3::splat(SIGMA_A),
        volshadow::PhaseFunction::HenyeyGreenstein { g: G },
    )
    .unwrap();
    let distance = |eye: DVec3, dir: DVec3| {
        let ground = if dir.y < 0.0 {
            let t = -eye.y / dir.y;
            let p = eye + t * dir;
            if p.x.abs() <= 20.0 && p.z.abs() <= 20.0 {
                t
            } else {
                f64::INFINITY
            }
        } else {
            f64::INFINITY
        };
        spheres
            .iter()
            .map(|s| s.ray_distance(eye, dir))
            .fold(ground, f64::min)
    };
    let image = reference::inscatter_image(
        &camera, width, height, distance, &medium, &light, &occluders,
    );
    let keep = ImageError::keep_away_from_lights(&camera, &[light.into()], width, height);
    (image, keep)
}

/// Prints the side-by-side table: each renderer's error against the f64 reference and its
/// time per frame over `frames` back-to-back frames, at `width × height`.
fn table(width: u32, height: u32, frames: u32) {
    use volshadow::glam::DVec3;
    let (reference, keep) = reference(width, height);
    let adapter = {
        let r = Rendered::new(Mode::Plain, Look::Inscatter, Msaa::Off, 8, 8);
        r.gpu().adapter_summary()
    };
    println!(
        "{width}x{height}, {frames} frames each, {adapter}; Bevy's default 4× MSAA unless noted"
    );
    println!(
        "| renderer | p95 | RMSE | scaled by | p95 so scaled | ms per frame | ms over the plain scene |"
    );
    println!("|---|---|---|---|---|---|---|");
    let mut plain_ms = 0.0;
    for (mode, msaa) in [
        (Mode::Plain, Msaa::default()),
        (Mode::Volshadow, Msaa::default()),
        (Mode::Volshadow, Msaa::Off),
        (Mode::BevyFogSteps(64), Msaa::default()),
        (Mode::BevyFogSteps(256), Msaa::default()),
    ] {
        let mut rendered = Rendered::new(mode, Look::Inscatter, msaa, width, height);
        let pixels: Vec<DVec3> = bytemuck_f32(&rendered.bytes())
            .chunks_exact(4)
            .map(|p| DVec3::new(p[0].into(), p[1].into(), p[2].into()))
            .collect();
        let start = std::time::Instant::now();
        for _ in 0..frames {
            rendered.frame();
        }
        let ms = start.elapsed().as_secs_f64() * 1e3 / f64::from(frames);
        let name = match mode {
            Mode::Plain => {
                plain_ms = ms;
                println!("| the scene without a medium | – | – | – | – | {ms:.1} | – |");
                continue;
            }
            Mode::Volshadow if msaa == Msaa::Off => "volshadow, MSAA off".to_string(),
            Mode::Volshadow => "volshadow (plugin defaults: error target 1%; 4× MSAA)".to_string(),
            _ => format!(
                "Bevy VolumetricFog, {} steps",
                mode.bevy_steps().unwrap_or(64)
            ),
        };
        let error = volshadow::reference::ImageError::measure(&pixels, &reference, &keep);
        // The one brightness factor that brings the image closest to the reference (least
        // squares over the kept pixels): what is left is the shape of the light and shadows.
        let kept = || {
            pixels
                .iter()
                .zip(&reference)
                .zip(&keep)
                .filter(|(_, k)| **k)
                .map(|(pr, _)| pr)
        };
        let scale = kept().map(|(p, r)| p.dot(*r)).sum::<f64>()
            / kept()
                .map(|(p, _)| p.dot(*p))
                .sum::<f64>()
                .max(f64::MIN_POSITIVE);
        let scaled: Vec<DVec3> = pixels.iter().map(|p| *p * scale).collect();
        let shape = volshadow::reference::ImageError::measure(&scaled, &reference, &keep);
        println!(
            "| {name} | {:.2}% | {:.2}% | {scale:.3} | {:.2}% | {ms:.1} | {:.1} |",
            100.0 * error.p95,
            100.0 * error.rmse,
            100.0 * shape.p95,
            ms - plain_ms
        );
    }
}

/// Prints the time of each of the first frames of a new app, with and without volshadow, and
/// the median of later ones: what a cold start costs (pipelines compile synchronously in these
/// headless apps, Bevy's own as well as volshadow's).
fn first_frames(width: u32, height: u32) {
    const FIRST: usize = 4;
    const LATER: usize = 20;
    let adapter = {
        let r = Rendered::unrendered(Mode::Plain, Look::Picture, Msaa::Off, 8, 8);
        r.gpu().adapter_summary()
    };
    println!("{width}x{height}, Bevy's default 4× MSAA, {adapter}");
    println!(
        "| app | frame 1 ms | frame 2 | frame 3 | frame 4 | later frame (median of frames {}–{}) |",
        FIRST + LATER + 1,
        FIRST + 2 * LATER
    );
    println!("|---|---|---|---|---|---|");
    for mode in [Mode::Plain, Mode::Volshadow] {
        let mut rendered =
            Rendered::unrendered(mode, Look::Picture, Msaa::default(), width, height);
        let mut time = || {
            let start = std::time::Instant::now();
            rendered.frame();
            start.elapsed().as_secs_f64() * 1e3
        };
        let first: Vec<f64> = (0..FIRST).map(|_| time()).collect();
        // Frames 5 to 24 unmeasured: what warms in the background has finished by then.
        (0..LATER).for_each(|_| {
            time();
        });
        let mut later: Vec<f64> = (0..LATER).map(|_| time()).collect();
        later.sort_by(f64::total_cmp);
        let name = match mode {
            Mode::Plain => "the scene without a medium",
            _ => "volshadow (plugin defaults)",
        };
        let cells: Vec<String> = first.iter().map(|ms| format!("{ms:.0}")).collect();
        println!(
            "| {name} | {} | {:.1} |",
            cells.join(" | "),
            later[LATER / 2]
        );
    }
}

fn bytemuck_f32(bytes: &[u8]) -> Vec<f32> {
    bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect()
}

#[allow(dead_code)]
fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1))
            .cloned()
    };
    let (width, height) = value("--size")
        .and_then(|s| {
            let (w, h) = s.split_once('x')?;
            Some((w.parse().ok()?, h.parse().ok()?))
        })
        .unwrap_or((960, 540));
    let modes = match value("--mode").as_deref() {
        Some("volshadow") => vec![Mode::Volshadow],
        Some("bevy") => vec![Mode::BevyFog],
        _ => vec![Mode::Volshadow, Mode::BevyFog],
    };
    if args.iter().any(|a| a == "--first-frames") {
        first_frames(width, height);
        return;
    }
    if args.iter().any(|a| a == "--table") {
        let frames = value("--frames").and_then(|f| f.parse().ok()).unwrap_or(20);
        table(width, height, frames);
        return;
    }
    std::fs::create_dir_all("out").expect("create out/");
    for mode in modes {
        let pixels = render(mode, width, height);
        let path = match mode {
            Mode::Volshadow => "out/bevy_volshadow.png",
            _ => "out/bevy_fog.png",
        };
        image::RgbaImage::from_raw(width, height, pixels)
            .expect("pixels of the target's size")
            .save(path)
            .expect("write the PNG");
        println!("{mode:?}: {path} ({width}x{height})");
    }
}
