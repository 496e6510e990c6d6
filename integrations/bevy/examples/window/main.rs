//! The `compare` example's scene (`volshadow_bevy_scene`) in a window: `V` switches the camera
//! between volshadow and Bevy's own `VolumetricFog` (64 steps) on the same scene; the window's
//! title says which.
//!
//! `cargo run --release -p volshadow_bevy --features window --example window --ignore-rust-version`

use bevy::camera::RenderTarget;
use bevy::input::keyboard::KeyCode;
use bevy::input::ButtonInput;
use bevy::light::{VolumetricFog, VolumetricLight};
use bevy::prelude::*;
use bevy::render::view::Msaa;
use bevy::window::{PrimaryWindow, WindowRef};
use volshadow_bevy::{VolshadowLight, VolshadowMedium, VolshadowPlugin};

use volshadow_bevy_scene::{Look, Mode};

const TITLE_VOLSHADOW: &str = "volshadow (V: Bevy's VolumetricFog)";
const TITLE_BEVY: &str = "Bevy's VolumetricFog, 64 steps (V: volshadow)";

fn main() {
    App::new()
        .add_plugins(DefaultPlugins.set(WindowPlugin {
            primary_window: Some(Window {
                title: TITLE_VOLSHADOW.into(),
                resolution: (960, 540).into(),
                ..Default::default()
            }),
            ..Default::default()
        }))
        .add_plugins(VolshadowPlugin)
        .add_systems(Startup, setup)
        .add_systems(Update, switch)
        .run();
}

/// The scene as `compare` builds it for volshadow, plus what Bevy's fog needs to take over:
/// its fog volume and the light's `VolumetricLight` (each ignored while the other is in use).
fn setup(world: &mut World) {
    let target = RenderTarget::Window(WindowRef::Primary);
    volshadow_bevy_scene::spawn(
        world,
        Mode::Volshadow,
        Look::Picture,
        Msaa::default(),
        target,
    );
    world.spawn(volshadow_bevy_scene::fog_volume());
    let lights: Vec<Entity> = world
        .query_filtered::<Entity, With<VolshadowLight>>()
        .iter(world)
        .collect();
    for light in lights {
        world.entity_mut(light).insert(VolumetricLight);
    }
}

/// `V`: the camera's medium goes from one renderer to the other.
fn switch(
    keys: Res<ButtonInput<KeyCode>>,
    mut commands: Commands,
    cameras: Query<(Entity, Has<VolshadowMedium>), With<Camera3d>>,
    mut windows: Query<&mut Window, With<PrimaryWindow>>,
) {
    if !keys.just_pressed(KeyCode::KeyV) {
        return;
    }
    for (camera, volshadow) in &cameras {
        let title = if volshadow {
            commands
                .entity(camera)
                .remove::<VolshadowMedium>()
                .insert(volshadow_bevy_scene::bevy_fog(64));
            TITLE_BEVY
        } else {
            commands
                .entity(camera)
                .remove::<VolumetricFog>()
                .insert(volshadow_bevy_scene::medium());
            TITLE_VOLSHADOW
        };
        for mut window in &mut windows {
            window.title = title.into();
        }
    }
}
