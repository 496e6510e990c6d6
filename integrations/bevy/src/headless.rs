//! Headless Bevy apps, for tests, examples and offline rendering: no window, pipelines compiled
//! before the frame that needs them, and the render world readable between frames.

use bevy::app::{App, PluginsState};
use bevy::prelude::PluginGroup;
use bevy::render::pipelined_rendering::PipelinedRenderingPlugin;
use bevy::render::renderer::{RenderAdapter, RenderDevice, RenderInstance, RenderQueue};
use bevy::render::{RenderApp, RenderPlugin};
use bevy::DefaultPlugins;
use volshadow::HeadlessGpu;

use crate::VolshadowPlugin;

/// An app of Bevy's `DefaultPlugins` (and [`VolshadowPlugin`] when `volshadow`), ready for
/// `update`: no primary window, synchronous pipeline compilation (a frame draws everything its
/// pipelines need), no pipelined rendering (the render world can be read between frames), no
/// log plugin (several apps may live in one process). Render into an image target.
pub fn app(volshadow: bool) -> App {
    let mut app = App::new();
    app.add_plugins(
        DefaultPlugins
            .build()
            .disable::<PipelinedRenderingPlugin>()
            .disable::<bevy::log::LogPlugin>()
            .set(RenderPlugin {
                synchronous_pipeline_compilation: true,
                ..Default::default()
            })
            .set(bevy::window::WindowPlugin {
                primary_window: None,
                exit_condition: bevy::window::ExitCondition::DontExit,
                ..Default::default()
            }),
    );
    if volshadow {
        app.add_plugins(VolshadowPlugin);
    }
    // What `App::run` does before its first update: wait for the plugins (the render device
    // is created asynchronously), then finish and clean them up.
    while app.plugins_state() == PluginsState::Adding {
        bevy::tasks::tick_global_task_pools_on_main_thread();
    }
    app.finish();
    app.cleanup();
    app
}

/// volshadow's readback helper on `app`'s own device and queue.
///
/// # Panics
///
/// Before the render device exists (build the app with [`app`]).
pub fn gpu(app: &App) -> HeadlessGpu {
    let world = app.sub_app(RenderApp).world();
    HeadlessGpu {
        instance: (**world.resource::<RenderInstance>()).clone(),
        adapter: (**world.resource::<RenderAdapter>()).clone(),
        device: world.resource::<RenderDevice>().wgpu_device().clone(),
        queue: (**world.resource::<RenderQueue>()).clone(),
    }
}
