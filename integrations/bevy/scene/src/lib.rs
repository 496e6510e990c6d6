//! The scene of the Bevy plugin's `compare` example, its `window` example and its test
//! (`tests/compare.rs`): the quickstart's scene (a point light behind two spheres in hazy air,
//! over a ground) built from Bevy entities and PBR materials, for volshadow or for Bevy's own
//! `VolumetricFog` with the parameters mapped as closely as the two models allow (see the
//! plugin's README), and a headless app that renders it ([`Rendered`], [`render`]).
//!
//! A crate of its own that is never published, a dev-dependency of `volshadow_bevy`: the
//! plugin itself does not depend on it.

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
    /// The steps of Bevy's fog in this mode (`None`: no Bevy fog).
    pub fn bevy_steps(self) -> Option<u32> {
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

    /// The app's device (the plugin's headless device).
    pub fn gpu(&self) -> HeadlessGpu {
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
