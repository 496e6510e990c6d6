//! Interactive: the quickstart scene in a window, with volumetric shadows every frame.
//!
//! The application draws its own frame (a ground plane and two spheres, ray-cast in a fragment
//! shader writing colour and depth) into offscreen targets; `VolumetricShadows` adds the light
//! scattered in the fog into an `Rgba16Float` target; a small blit pass tone-maps that to the
//! window (exposure, Reinhard, sRGB).
//!
//! ```text
//! cargo run --release --features window --example interactive
//! ```
//!
//! Controls (printed at start and by `--help`, listed in the window's title; the table is
//! `KEYS` in `volshadow_harness::cli`, which the key handler reads): dragging with the left
//! mouse button moves the light (in a plane behind the spheres; it starts above and between
//! them, where the shafts show, and stays there until dragged); M cycles the march method
//! (exact → hybrid → brute force → textbook → exact); Up / Down double / halve the steps
//! (4 ..= 512); R cycles the scattering resolution (full, 1/2, 1/4); S toggles shadows (no
//! occluders: the planner skips the shadow map and extents); L cycles the light's radius (0: a
//! point, hard shadows; 0.1, 0.25, 0.5: a sphere, soft shadows); V cycles the view: the frame,
//! a split screen (left: the current method; right: the f64 reference), and the difference
//! (per-pixel relative error of the in-scatter against the reference: black 0, blue 2%,
//! yellow 5%, red 10% or more); Escape quits. The reference (`volshadow::reference`, exact
//! sphere visibility) is computed in a background thread at 1/8 of the window's resolution
//! for the current light and shadows, and recomputed when they change; it is sampled
//! bilinearly, so its own resolution shows along shadow edges. The title shows the settings,
//! the view (and whether the reference is current), the plan's passes run / skipped, the GPU
//! time of each of volshadow's passes and the keys: timestamp queries when the device has
//! them; else (a CPU adapter such as lavapipe) each pass is
//! submitted alone and timed by the wall clock. It is printed to stdout once a second too.

use std::error::Error;
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::Arc;
use std::time::{Duration, Instant};

use volshadow::glam::{DVec3, Mat4, Vec3};
use volshadow::gpu::PassTime;
use volshadow::nodes::{MarchMethod, Scale};
use volshadow::reference;
use volshadow::{
    AdapterKind, Cache, Camera, Frame, FrameLight, Light, Medium, Occluder, OccluderMesh,
    PointLight, Settings, VolumetricShadows,
};
use winit::application::ApplicationHandler;
use winit::dpi::{PhysicalPosition, PhysicalSize};
use winit::event::{ElementState, MouseButton, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop, OwnedDisplayHandle};
use winit::keyboard::{Key, NamedKey};
use winit::window::{Window, WindowId};

use volshadow_harness::cli;
use volshadow_harness::fullscreen::texture_desc;
use volshadow_harness::quickstart_scene::{
    self, camera, ScenePass, EYE, LIGHT_INTENSITY, LIGHT_POSITION,
};

/// Offscreen colour format: the app's frame, and volshadow's output.
const HDR: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;
/// How often the title is refreshed, and how often it is printed.
const TITLE_EVERY: Duration = Duration::from_millis(250);
const PRINT_EVERY: Duration = Duration::from_secs(1);
/// The reference is computed at the window's size divided by this.
const REFERENCE_DIVISOR: u32 = 8;

/// What the window shows.
#[derive(Debug, Clone, Copy, PartialEq)]
enum View {
    /// volshadow's output.
    Frame,
    /// Left half: volshadow's output; right half: the app's frame with the reference's
    /// in-scatter.
    Split,
    /// Relative error of volshadow's in-scatter against the reference, as a heat map.
    Difference,
}

impl View {
    fn next(self) -> Self {
        match self {
            View::Frame => View::Split,
            View::Split => View::Difference,
            View::Difference => View::Frame,
        }
    }
    fn name(self) -> &'static str {
        match self {
            View::Frame => "frame",
            View::Split => "split: method | f64 reference",
            View::Difference => "difference to the f64 reference",
        }
    }
    /// The blit shader's mode.
    fn mode(self) -> f32 {
        match self {
            View::Frame => 0.0,
            View::Split => 1.0,
            View::Difference => 2.0,
        }
    }
}

/// What a reference image was computed for: light position and radius, shadows, window size.
type ReferenceKey = ([u32; 4], bool, (u32, u32));

/// A reference computation for the background thread.
struct ReferenceJob {
    key: ReferenceKey,
    camera: Camera,
    light: PointLight,
    medium: Medium,
    shadows: bool,
    size: (u32, u32),
}

/// The f64 reference, computed in a background thread and uploaded when it arrives.
struct ReferenceState {
    jobs: Sender<ReferenceJob>,
    results: Receiver<(ReferenceKey, (u32, u32), Vec<DVec3>)>,
    /// The key of the job in flight, if any.
    in_flight: Option<ReferenceKey>,
    /// The uploaded image (`Rgba32Float`, low resolution), its key and its largest luminance.
    texture: Option<(ReferenceKey, wgpu::Texture, f32)>,
}

impl ReferenceState {
    fn new() -> Self {
        let (jobs, job_receiver) = channel::<ReferenceJob>();
        let (result_sender, results) = channel();
        std::thread::spawn(move || {
            while let Ok(mut job) = job_receiver.recv() {
                // Only the newest request matters.
                while let Ok(newer) = job_receiver.try_recv() {
                    job = newer;
                }
                let image = reference_inscatter(&job);
                if result_sender.send((job.key, job.size, image)).is_err() {
                    break;
                }
            }
        });
        Self {
            jobs,
            results,
            in_flight: None,
            texture: None,
        }
    }

    /// Whether the uploaded reference is for `key`.
    fn is_current(&self, key: ReferenceKey) -> bool {
        self.texture.as_ref().is_some_and(|(k, _, _)| *k == key)
    }
}

/// The reference's in-scatter for `job` (soft shadows for a light with a radius; the same as
/// the hard reference for radius 0): the spheres as exact occluders, the app's ground
/// plane and spheres as the surfaces that end each ray.
fn reference_inscatter(job: &ReferenceJob) -> Vec<DVec3> {
    let occluders = if job.shadows {
        quickstart_scene::reference_occluders()
    } else {
        Vec::new()
    };
    reference::inscatter_image_soft(
        &job.camera,
        job.size.0,
        job.size.1,
        quickstart_scene::surface_distance,
        &job.medium,
        &job.light,
        &occluders,
    )
}

fn main() {
    // Arguments first: `--help` (or a bad argument) opens no window.
    let args: Vec<String> = std::env::args().skip(1).collect();
    match cli::parse_interactive(&args) {
        Ok(cli::Parsed::Help) => {
            println!("{}", cli::interactive_help());
            return;
        }
        Ok(cli::Parsed::Run(())) => {}
        Err(e) => {
            eprintln!("interactive: {e}");
            std::process::exit(1);
        }
    }
    println!("keys:\n{}", cli::keys_help());
    if let Err(e) = run() {
        eprintln!("interactive: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), Box<dyn Error>> {
    let event_loop = EventLoop::new()?;
    // Redraws are requested after every frame; nothing spins while minimised.
    event_loop.set_control_flow(ControlFlow::Wait);
    let mut app = App {
        display: event_loop.owned_display_handle(),
        state: None,
        error: None,
    };
    event_loop.run_app(&mut app)?;
    app.error.map_or(Ok(()), Err)
}

/// The winit application: the window and renderer exist once the event loop has resumed.
struct App {
    display: OwnedDisplayHandle,
    state: Option<State>,
    error: Option<Box<dyn Error>>,
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.state.is_some() {
            return;
        }
        match State::new(event_loop, self.display.clone()) {
            Ok(state) => self.state = Some(state),
            Err(e) => {
                self.error = Some(e);
                event_loop.exit();
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
        let Some(state) = self.state.as_mut() else {
            return;
        };
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::Resized(size) => state.resize(size),
            WindowEvent::CursorMoved { position, .. } => {
                state.cursor = Some(position);
                if state.dragging {
                    state.move_light(position);
                }
            }
            // A release outside the window may never arrive: the drag ends at its edge.
            WindowEvent::CursorLeft { .. } => state.dragging = false,
            WindowEvent::MouseInput {
                state: pressed,
                button: MouseButton::Left,
                ..
            } => {
                state.dragging = pressed == ElementState::Pressed;
                if let (true, Some(position)) = (state.dragging, state.cursor) {
                    state.move_light(position);
                }
            }
            WindowEvent::KeyboardInput { event, .. } if event.state == ElementState::Pressed => {
                let key = match event.logical_key.as_ref() {
                    Key::Named(NamedKey::Escape) => Some(cli::Key::Escape),
                    Key::Named(NamedKey::ArrowUp) => Some(cli::Key::Up),
                    Key::Named(NamedKey::ArrowDown) => Some(cli::Key::Down),
                    // Letters do not repeat while held; the arrows do.
                    Key::Character(c) if !event.repeat => {
                        let mut chars = c.chars().flat_map(char::to_lowercase);
                        match (chars.next(), chars.next()) {
                            (Some(c), None) => Some(cli::Key::Char(c)),
                            _ => None,
                        }
                    }
                    _ => None,
                };
                match key.and_then(cli::action_of) {
                    Some(cli::Action::Quit) => event_loop.exit(),
                    Some(cli::Action::MoreSteps) => state.change_steps(2.0),
                    Some(cli::Action::FewerSteps) => state.change_steps(0.5),
                    Some(cli::Action::CycleMethod) => state.toggle_method(),
                    Some(cli::Action::CycleScale) => state.cycle_scale(),
                    Some(cli::Action::ToggleShadows) => state.shadows = !state.shadows,
                    Some(cli::Action::CycleRadius) => state.cycle_radius(),
                    Some(cli::Action::CycleView) => state.view = state.view.next(),
                    None => {}
                }
            }
            WindowEvent::RedrawRequested => {
                state.render();
                // Keep drawing, unless minimised (a resize to a non-zero size asks again).
                if state.targets.is_some() {
                    state.window.request_redraw();
                }
            }
            _ => {}
        }
    }
}

/// The window, the device and everything drawn every frame.
struct State {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    device: wgpu::Device,
    queue: wgpu::Queue,
    /// Whether volshadow's passes are timed on the GPU.
    timestamps: bool,
    scene: ScenePass,
    blit: Blit,
    view: View,
    reference: ReferenceState,
    /// `None` while minimised.
    targets: Option<Targets>,
    meshes: Vec<OccluderMesh>,
    volumetric: VolumetricShadows,
    medium: Medium,
    light_position: Vec3,
    /// The cursor's last position in the window, and whether the left button is held (the
    /// light follows the cursor only while it is).
    cursor: Option<PhysicalPosition<f64>>,
    dragging: bool,
    /// The light's radius (L cycles it).
    light_radius: f32,
    shadows: bool,
    stats: Stats,
}

/// The per-size part: camera and offscreen targets.
#[derive(Clone)]
struct Targets {
    camera: Camera,
    color: wgpu::Texture,
    depth: wgpu::Texture,
    output: wgpu::Texture,
}

/// What the title shows, and when it was last refreshed / printed.
struct Stats {
    passes_run: usize,
    passes_skipped: usize,
    /// GPU time of each of volshadow's passes in the last frame.
    passes: Vec<PassTime>,
    last_frame: Instant,
    frame_ms: f64,
    last_title: Instant,
    last_print: Instant,
    /// The last error printed, so a persistent one is printed once.
    last_error: Option<String>,
    /// Whether the uploaded reference is for this frame's light, shadows and size.
    reference_current: bool,
}

impl State {
    fn new(
        event_loop: &ActiveEventLoop,
        display: OwnedDisplayHandle,
    ) -> Result<Self, Box<dyn Error>> {
        let window = Arc::new(
            event_loop.create_window(
                Window::default_attributes()
                    .with_title(format!("volshadow interactive | {}", cli::keys_short()))
                    .with_inner_size(PhysicalSize::new(960, 600)),
            )?,
        );
        // WGPU_BACKEND etc. are honoured; the display handle is winit's, as wgpu asks.
        let instance = wgpu::Instance::new(
            wgpu::InstanceDescriptor::new_with_display_handle_from_env(Box::new(display)),
        );
        let surface = instance.create_surface(window.clone())?;
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            compatible_surface: Some(&surface),
            ..Default::default()
        }))?;
        let info = adapter.get_info();
        println!(
            "adapter: {} ({:?}, {:?})",
            info.name, info.backend, info.device_type
        );
        // Timestamp queries are optional: without them the title shows the wall clock.
        let features = adapter.features() & wgpu::Features::TIMESTAMP_QUERY;
        let (device, queue) =
            pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
                label: Some("interactive"),
                required_features: features,
                ..Default::default()
            }))?;
        // wgpu validation errors are printed instead of panicking.
        device.on_uncaptured_error(Arc::new(|e| eprintln!("wgpu error: {e}")));

        // The swapchain: an sRGB format if there is one (the blit encodes otherwise).
        let size = window.inner_size();
        let caps = surface.get_capabilities(&adapter);
        let format = caps
            .formats
            .iter()
            .copied()
            .find(|f| f.is_srgb())
            .or(caps.formats.first().copied())
            .ok_or("the surface is not supported by the adapter")?;
        let config = wgpu::SurfaceConfiguration {
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            format,
            color_space: wgpu::SurfaceColorSpace::Auto,
            width: size.width.max(1),
            height: size.height.max(1),
            desired_maximum_frame_latency: 2,
            present_mode: wgpu::PresentMode::AutoVsync,
            alpha_mode: wgpu::CompositeAlphaMode::Auto,
            view_formats: vec![],
        };
        println!("surface: {format:?}");

        // volshadow: the occluder meshes (uploaded once) and the facade.
        let cache = Cache::new(&device);
        let meshes = quickstart_scene::sphere_meshes(&device);
        let settings = Settings {
            output_format: HDR,
            ..Settings::for_adapter(AdapterKind::of(&device))
        };
        let volumetric = VolumetricShadows::new(&device, &queue, &cache, settings)?;
        let medium = quickstart_scene::medium()?;

        let now = Instant::now();
        let mut state = Self {
            scene: ScenePass::new(&device),
            blit: Blit::new(&device, format),
            view: View::Frame,
            reference: ReferenceState::new(),
            window,
            surface,
            config,
            timestamps: device.features().contains(wgpu::Features::TIMESTAMP_QUERY),
            device,
            queue,
            targets: None,
            meshes,
            volumetric,
            medium,
            light_position: LIGHT_POSITION,
            cursor: None,
            dragging: false,
            light_radius: 0.0,
            shadows: true,
            stats: Stats {
                passes_run: 0,
                passes_skipped: 0,
                passes: Vec::new(),
                last_frame: now,
                frame_ms: 0.0,
                last_title: now,
                last_print: now,
                last_error: None,
                reference_current: false,
            },
        };
        state.resize(size);
        state.window.request_redraw();
        Ok(state)
    }

    /// Reconfigures the swapchain and recreates the offscreen targets; size 0 (minimised)
    /// drops them and stops drawing.
    fn resize(&mut self, size: PhysicalSize<u32>) {
        if size.width == 0 || size.height == 0 {
            self.targets = None;
            return;
        }
        self.config.width = size.width;
        self.config.height = size.height;
        self.surface.configure(&self.device, &self.config);
        let camera = match camera(size.width, size.height) {
            Ok(c) => c,
            Err(e) => return self.report(&e),
        };
        let texture = |label, format| {
            let usage =
                wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING;
            let desc = texture_desc(label, (size.width, size.height), format, usage);
            self.device.create_texture(&desc)
        };
        self.targets = Some(Targets {
            camera,
            color: texture("scene colour", HDR),
            depth: texture("scene depth", wgpu::TextureFormat::Depth32Float),
            output: texture("volshadow output", HDR),
        });
        self.window.request_redraw();
    }

    /// Puts the light where the cursor's ray meets the plane behind the spheres.
    fn move_light(&mut self, cursor: PhysicalPosition<f64>) {
        let Some(targets) = &self.targets else {
            return;
        };
        let ndc_x = (2.0 * cursor.x / f64::from(self.config.width) - 1.0) as f32;
        let ndc_y = (1.0 - 2.0 * cursor.y / f64::from(self.config.height)) as f32;
        let d = targets.camera.ray_direction(ndc_x, ndc_y);
        if d.z < -1e-3 {
            let p = EYE + d * ((LIGHT_POSITION.z - EYE.z) / d.z);
            // Keep it above the ground and not absurdly far to the side.
            self.light_position = Vec3::new(p.x.clamp(-8.0, 8.0), p.y.clamp(0.1, 8.0), p.z);
        }
    }

    fn update_settings(&mut self, change: impl FnOnce(&mut Settings)) {
        let mut settings = self.volumetric.settings();
        change(&mut settings);
        if let Err(e) = self.volumetric.set_settings(settings) {
            self.report(&e);
        }
    }

    /// M: the next march method.
    fn toggle_method(&mut self) {
        self.update_settings(|s| {
            // The methods a user compares: exact → hybrid → brute force → textbook → exact.
            s.march.method = match s.march.method {
                MarchMethod::Exact => MarchMethod::Hybrid,
                MarchMethod::Hybrid => MarchMethod::BruteForce,
                MarchMethod::BruteForce => MarchMethod::Textbook,
                _ => MarchMethod::Exact,
            }
        });
    }

    fn change_steps(&mut self, factor: f32) {
        self.update_settings(|s| {
            s.march.steps = ((s.march.steps as f32 * factor) as u32).clamp(4, 512);
        });
    }

    fn cycle_radius(&mut self) {
        self.light_radius = match self.light_radius {
            r if r < 0.1 => 0.1,
            r if r < 0.25 => 0.25,
            r if r < 0.5 => 0.5,
            _ => 0.0,
        };
    }

    fn cycle_scale(&mut self) {
        self.update_settings(|s| {
            s.march.scale = match s.march.scale {
                Scale::Full => Scale::Half,
                Scale::Half => Scale::Quarter,
                Scale::Quarter => Scale::Full,
            }
        });
    }

    /// Prints an error to stderr (once while it repeats).
    fn report(&mut self, e: &dyn std::fmt::Display) {
        let message = e.to_string();
        if self.stats.last_error.as_ref() != Some(&message) {
            eprintln!("volshadow: {message}");
            self.stats.last_error = Some(message);
        }
    }

    fn render(&mut self) {
        let Some(targets) = self.targets.clone() else {
            return;
        };
        let (surface_texture, suboptimal) = match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t) => (t, false),
            wgpu::CurrentSurfaceTexture::Suboptimal(t) => (t, true),
            wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => return,
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                self.surface.configure(&self.device, &self.config);
                return;
            }
            wgpu::CurrentSurfaceTexture::Validation => {
                eprintln!("surface: validation error acquiring the frame");
                return;
            }
        };
        let light = match PointLight::new(self.light_position, LIGHT_INTENSITY)
            .and_then(|l| l.with_radius(self.light_radius))
        {
            Ok(l) => l,
            Err(e) => return self.report(&e),
        };
        self.update_reference(&targets.camera, light);

        // The application's frame: colour and depth.
        let mut encoder = self.device.create_command_encoder(&Default::default());
        self.scene.encode(
            &self.queue,
            &mut encoder,
            (&targets.color, &targets.depth),
            (&targets.camera, &light, &self.medium),
            self.shadows,
        );

        // volshadow: prepare (validate, upload, plan), then record into our encoder.
        let occluders: Vec<Occluder> = if self.shadows {
            self.meshes
                .iter()
                .map(|mesh| Occluder {
                    mesh,
                    transform: Mat4::IDENTITY,
                })
                .collect()
        } else {
            Vec::new()
        };
        let lights = [FrameLight::from(Light::from(light))];
        let frame = Frame {
            camera: &targets.camera,
            lights: &lights,
            medium: &self.medium,
            occluders: &occluders,
            scene_color: &targets.color,
            scene_depth: &targets.depth,
            surfaces: None,
        };
        let output = &targets.output;
        let counts = match self.volumetric.prepare(&self.device, &self.queue, &frame) {
            Ok(plan) => (plan.steps.len(), plan.skipped.len()),
            Err(e) => return self.report(&e),
        };
        let recorded = if self.timestamps {
            // One submission; the passes are timed by timestamp queries.
            self.volumetric.encode(&mut encoder, output)
        } else {
            // A CPU adapter (lavapipe): each pass submitted alone and timed by the wall clock.
            self.queue.submit([encoder.finish()]);
            encoder = self.device.create_command_encoder(&Default::default());
            self.encode_each_pass_timed(output)
        };
        if let Err(e) = recorded {
            return self.report(&e);
        }
        self.stats.passes_run = counts.0;
        self.stats.passes_skipped = counts.1;
        self.stats.last_error = None;

        // Tone map volshadow's output (or the comparison with the reference) to the window.
        let reference = self
            .reference
            .texture
            .as_ref()
            .map(|(_, texture, max)| (texture, *max));
        let bind_group = self.blit.bind_group(
            &self.device,
            &self.queue,
            &targets,
            self.volumetric.inscatter(0),
            reference,
            self.view,
            &self.medium,
        );
        {
            let view = surface_texture.texture.create_view(&Default::default());
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("blit"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.blit.pipeline);
            pass.set_bind_group(0, &bind_group, &[]);
            pass.draw(0..3, 0..1);
        }
        self.queue.submit([encoder.finish()]);
        self.window.pre_present_notify();
        self.queue.present(surface_texture);
        if suboptimal {
            self.surface.configure(&self.device, &self.config);
        }

        // Timings: volshadow's passes on the GPU (blocks until this frame is done), and the
        // wall-clock time between frames.
        if self.timestamps {
            match self.volumetric.read_timings(&self.device) {
                Ok(t) => self.stats.passes = t,
                Err(e) => self.report(&e),
            }
        }
        let now = Instant::now();
        self.stats.frame_ms = (now - self.stats.last_frame).as_secs_f64() * 1e3;
        self.stats.last_frame = now;
        self.update_title(now);
    }

    /// Records and submits each planned pass alone, timing each submission by the wall clock
    /// (how passes are timed on a CPU adapter, whose timestamps do not bracket compute work).
    fn encode_each_pass_timed(&mut self, output: &wgpu::Texture) -> volshadow::Result<()> {
        let steps = self.volumetric.plan().steps.clone();
        let mut passes = Vec::with_capacity(steps.len());
        for (index, step) in steps.iter().enumerate() {
            let mut encoder = self.device.create_command_encoder(&Default::default());
            self.volumetric.encode_step(&mut encoder, output, index)?;
            let start = Instant::now();
            self.queue.submit([encoder.finish()]);
            self.device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(|e| volshadow::Error::Readback(e.to_string()))?;
            passes.push(PassTime {
                pass: step.pass,
                light: step.light,
                ms: start.elapsed().as_secs_f64() * 1e3,
            });
        }
        self.stats.passes = passes;
        Ok(())
    }

    /// Uploads a reference that arrived, and asks for one for the current light, shadows and
    /// size when a comparison is shown and none is current or being computed.
    fn update_reference(&mut self, camera: &Camera, light: PointLight) {
        while let Ok((key, (width, height), image)) = self.reference.results.try_recv() {
            if self.reference.in_flight == Some(key) {
                self.reference.in_flight = None;
            }
            let texels: Vec<[f32; 4]> = image
                .iter()
                .map(|c| [c.x as f32, c.y as f32, c.z as f32, 1.0])
                .collect();
            let max = image
                .iter()
                .map(|c| c.dot(DVec3::new(0.2126, 0.7152, 0.0722)) as f32)
                .fold(0.0, f32::max);
            let texture = self.device.create_texture(&texture_desc(
                "f64 reference in-scatter",
                (width, height),
                wgpu::TextureFormat::Rgba32Float,
                wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            ));
            self.queue.write_texture(
                texture.as_image_copy(),
                bytemuck::cast_slice(&texels),
                wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(width * 16),
                    rows_per_image: Some(height),
                },
                texture.size(),
            );
            self.reference.texture = Some((key, texture, max));
        }
        let window = (self.config.width, self.config.height);
        let key = (
            self.light_position
                .extend(self.light_radius)
                .to_array()
                .map(f32::to_bits),
            self.shadows,
            window,
        );
        self.stats.reference_current = self.reference.is_current(key);
        if self.view == View::Frame
            || self.stats.reference_current
            || self.reference.in_flight.is_some()
        {
            return;
        }
        let job = ReferenceJob {
            key,
            camera: *camera,
            light,
            medium: self.medium,
            shadows: self.shadows,
            size: (
                (window.0 / REFERENCE_DIVISOR).max(1),
                (window.1 / REFERENCE_DIVISOR).max(1),
            ),
        };
        if self.reference.jobs.send(job).is_ok() {
            self.reference.in_flight = Some(key);
        }
    }

    fn update_title(&mut self, now: Instant) {
        if now - self.stats.last_title < TITLE_EVERY {
            return;
        }
        self.stats.last_title = now;
        let s = self.volumetric.settings();
        let time = if self.stats.passes.is_empty() {
            format!("frame {:.1} ms (wall clock)", self.stats.frame_ms)
        } else {
            let total: f64 = self.stats.passes.iter().map(|p| p.ms).sum();
            let passes: Vec<String> = self
                .stats
                .passes
                .iter()
                .map(|p| format!("{} {:.2}", p.pass, p.ms))
                .collect();
            format!(
                "GPU {total:.2} ms: {} | frame {:.1} ms",
                passes.join(", "),
                self.stats.frame_ms
            )
        };
        let view = match (self.view, self.stats.reference_current) {
            (View::Frame, _) => String::new(),
            (view, true) => format!(" | view: {}", view.name()),
            (view, false) => format!(" | view: {} (reference computing)", view.name()),
        };
        let status = format!(
            "volshadow: {}, {} steps, 1/{} res, shadows {}, light radius {}{view} | {} passes run, {} skipped | {time}",
            s.march.method,
            s.march.steps,
            s.march.scale.divisor(),
            if self.shadows { "on" } else { "off" },
            self.light_radius,
            self.stats.passes_run,
            self.stats.passes_skipped,
        );
        self.window
            .set_title(&format!("{status} | keys: {}", cli::keys_short()));
        if now - self.stats.last_print >= PRINT_EVERY {
            self.stats.last_print = now;
            println!("{status}");
        }
    }
}

/// The tone-mapping blit (exposure and Reinhard; sRGB-encoded in the shader only when the
/// swapchain format does not do it: a non-sRGB 8-bit format; a float format takes linear), and
/// the comparison views against the f64 reference.
struct Blit {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    uniform: wgpu::Buffer,
    /// Bound in place of a missing in-scatter or reference texture.
    dummy: wgpu::Texture,
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct BlitUniform {
    world_from_clip: [f32; 16],
    eye: [f32; 4],
    sigma_t: [f32; 4],
    /// Mode (0 frame, 1 split, 2 difference), split x in pixels, reference present (0 or 1),
    /// the reference's largest luminance.
    params: [f32; 4],
    /// Reference width and height, window width and height.
    sizes: [f32; 4],
}

impl Blit {
    fn new(device: &wgpu::Device, format: wgpu::TextureFormat) -> Self {
        let encode = !format.is_srgb()
            && !matches!(
                format,
                wgpu::TextureFormat::Rgba16Float | wgpu::TextureFormat::Rgba32Float
            );
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("blit"),
            source: wgpu::ShaderSource::Wgsl(include_str!("blit.wgsl").into()),
        });
        let texture = |binding, sample_type| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Texture {
                sample_type,
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled: false,
            },
            count: None,
        };
        // Loaded, never filtered: Rgba32Float needs no optional feature.
        let float = wgpu::TextureSampleType::Float { filterable: false };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("blit"),
            entries: &[
                texture(0, float),
                texture(1, float),
                texture(2, wgpu::TextureSampleType::Depth),
                texture(3, float),
                texture(4, float),
                wgpu::BindGroupLayoutEntry {
                    binding: 5,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("blit"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let constants = [("ENCODE_SRGB", if encode { 1.0 } else { 0.0 })];
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("blit"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: Default::default(),
            depth_stencil: None,
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs"),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants: &constants,
                    ..Default::default()
                },
                targets: &[Some(format.into())],
            }),
            multiview_mask: None,
            cache: None,
        });
        let uniform = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("blit uniform"),
            size: std::mem::size_of::<BlitUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let dummy = device.create_texture(&texture_desc(
            "blit placeholder",
            (1, 1),
            wgpu::TextureFormat::Rgba32Float,
            wgpu::TextureUsages::TEXTURE_BINDING,
        ));
        Self {
            pipeline,
            layout,
            uniform,
            dummy,
        }
    }

    /// This frame's bind group, after writing its uniform: volshadow's output, the app's colour
    /// and depth, volshadow's in-scatter and the reference (with its largest luminance).
    #[allow(clippy::too_many_arguments)]
    fn bind_group(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        targets: &Targets,
        inscatter: Option<&wgpu::Texture>,
        reference: Option<(&wgpu::Texture, f32)>,
        view: View,
        medium: &Medium,
    ) -> wgpu::BindGroup {
        let camera = &targets.camera;
        let (width, height) = (targets.output.width(), targets.output.height());
        let (reference_size, reference_max) =
            reference.map_or(((1, 1), 0.0), |(t, max)| ((t.width(), t.height()), max));
        let uniform = BlitUniform {
            world_from_clip: camera.world_from_clip().to_cols_array(),
            eye: camera.eye().extend(0.0).to_array(),
            sigma_t: medium.sigma_t().extend(0.0).to_array(),
            params: [
                view.mode(),
                (width / 2) as f32,
                if reference.is_some() { 1.0 } else { 0.0 },
                reference_max,
            ],
            sizes: [
                reference_size.0 as f32,
                reference_size.1 as f32,
                width as f32,
                height as f32,
            ],
        };
        queue.write_buffer(&self.uniform, 0, bytemuck::bytes_of(&uniform));
        let view_of = |t: &wgpu::Texture| t.create_view(&Default::default());
        let views = [
            view_of(&targets.output),
            view_of(&targets.color),
            view_of(&targets.depth),
            view_of(inscatter.unwrap_or(&self.dummy)),
            view_of(reference.map_or(&self.dummy, |(t, _)| t)),
        ];
        let mut entries: Vec<wgpu::BindGroupEntry> = views
            .iter()
            .enumerate()
            .map(|(i, v)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: wgpu::BindingResource::TextureView(v),
            })
            .collect();
        entries.push(wgpu::BindGroupEntry {
            binding: 5,
            resource: self.uniform.as_entire_binding(),
        });
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("blit"),
            layout: &self.layout,
            entries: &entries,
        })
    }
}
