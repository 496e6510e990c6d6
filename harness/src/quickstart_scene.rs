//! The quickstart scene: a camera, a point light behind two spheres, hazy air (the spheres cut
//! dark shafts towards the camera), and the application's pass that draws it
//! (`quickstart_scene.wgsl`). The `quickstart` example takes the app's pass and [`SPHERES`]
//! from here and builds its camera, light, medium and occluders itself, where a reader sees
//! every volshadow call (its test checks that they equal [`scene`]'s); the `interactive`
//! example takes the whole scene, and the quickstart's test the f64 reference's view of it.

use volshadow::glam::{DVec3, Vec3};
use volshadow::reference::{Occluder, Sphere};
use volshadow::scene::shapes;
use volshadow::{Camera, Medium, OccluderMesh, PhaseFunction, PointLight};

use super::fullscreen::FullscreenPass;

/// The spheres of the scene (centre, radius): drawn by the app, and occluders for volshadow.
/// `quickstart_scene.wgsl` repeats them.
pub const SPHERES: [(Vec3, f32); 2] = [
    (Vec3::new(-0.6, 2.2, -2.2), 0.5),
    (Vec3::new(0.8, 1.7, -1.4), 0.4),
];
/// The camera's position.
pub const EYE: Vec3 = Vec3::new(0.0, 1.6, 7.0);
/// The light's position (`interactive` moves it in the plane z = `LIGHT_POSITION.z`): about
/// level with the spheres and behind them, so that both cut dark shafts that open towards the
/// camera and neither throws a shadow across the ground in front of it (issue 36's survey,
/// `examples/quickstart/quickstart.rs::light_positions` at 256x160: 44% of the picture shows the
/// shadows; 30% at the earlier (0.1, 2.9, -4.6), whose spheres threw two black blobs across the
/// ground in front of the camera and whose shafts were faint).
pub const LIGHT_POSITION: Vec3 = Vec3::new(-0.1, 2.1, -5.0);
/// The light's intensity.
pub const LIGHT_INTENSITY: Vec3 = Vec3::new(90.0, 78.0, 60.0);

/// The camera for a frame of this size.
pub fn camera(width: u32, height: u32) -> volshadow::Result<Camera> {
    Camera::new(
        volshadow::glam::camera::rh::view::look_at_mat4(EYE, Vec3::new(0.0, 1.3, 0.0), Vec3::Y),
        volshadow::glam::camera::rh::proj::directx::perspective(
            55f32.to_radians(),
            width as f32 / height as f32,
            0.05,
            200.0,
        ),
    )
}

/// Hazy air.
pub fn medium() -> volshadow::Result<Medium> {
    Medium::new(
        Vec3::new(0.10, 0.11, 0.13),
        Vec3::splat(0.01),
        PhaseFunction::HenyeyGreenstein { g: 0.7 },
    )
}

/// The scene: the camera, the light at [`LIGHT_POSITION`], the medium.
pub fn scene(width: u32, height: u32) -> volshadow::Result<(Camera, PointLight, Medium)> {
    let light = PointLight::new(LIGHT_POSITION, LIGHT_INTENSITY)?;
    Ok((camera(width, height)?, light, medium()?))
}

/// The spheres as volshadow's occluder meshes (48 × 24 segments), uploaded.
pub fn sphere_meshes(device: &wgpu::Device) -> Vec<OccluderMesh> {
    SPHERES
        .iter()
        .map(|&(c, r)| {
            OccluderMesh::new(
                device,
                &shapes::uv_sphere(c, r, 48, 24).expect("valid sphere"),
            )
        })
        .collect()
}

/// The spheres as the f64 reference's exact occluders.
pub fn reference_occluders() -> Vec<Occluder> {
    SPHERES
        .iter()
        .map(|&(c, r)| Occluder::Sphere(Sphere::new(c.as_dvec3(), f64::from(r))))
        .collect()
}

/// Distance along the ray `o + t·d` to the first surface the app draws (the ground plane or a
/// sphere), ∞ for the sky: where the reference's rays end.
pub fn surface_distance(o: DVec3, d: DVec3) -> f64 {
    let mut t = if d.y < 0.0 { -o.y / d.y } else { f64::INFINITY };
    for &(c, r) in &SPHERES {
        let oc = o - c.as_dvec3();
        let b = oc.dot(d);
        let disc = b * b - (oc.length_squared() - f64::from(r * r));
        if disc >= 0.0 && -b - disc.sqrt() > 0.0 {
            t = t.min(-b - disc.sqrt());
        }
    }
    t
}

/// The parameters of `quickstart_scene.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct SceneParams {
    clip_from_world: [f32; 16],
    world_from_clip: [f32; 16],
    eye: [f32; 4],
    light: [f32; 4],
    intensity: [f32; 4],
    sigma_t: [f32; 4],
    /// Width, height, shadows on the surfaces (0 or 1), unused.
    size: [f32; 4],
}

/// The application's own frame of the scene: colour (`Rgba16Float`) and depth.
pub struct ScenePass(FullscreenPass);

impl ScenePass {
    /// Compiles the scene's shader.
    pub fn new(device: &wgpu::Device) -> Self {
        let wgsl = include_str!("quickstart_scene.wgsl");
        Self(FullscreenPass::new(
            device,
            "quickstart scene",
            wgsl,
            std::mem::size_of::<SceneParams>(),
        ))
    }

    /// Records the frame seen by `camera` into `targets` (colour, depth), the spheres
    /// shadowing the surfaces if `shadows`.
    pub fn encode(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        targets: (&wgpu::Texture, &wgpu::Texture),
        (camera, light, medium): (&Camera, &PointLight, &Medium),
        shadows: bool,
    ) {
        let params = SceneParams {
            clip_from_world: (camera.projection() * camera.view()).to_cols_array(),
            world_from_clip: camera.world_from_clip().to_cols_array(),
            eye: camera.eye().extend(0.0).to_array(),
            light: light.position().extend(0.0).to_array(),
            intensity: light.intensity().extend(0.0).to_array(),
            sigma_t: medium.sigma_t().extend(0.0).to_array(),
            size: [
                targets.0.width() as f32,
                targets.0.height() as f32,
                if shadows { 1.0 } else { 0.0 },
                0.0,
            ],
        };
        self.0
            .encode(queue, encoder, &params, targets, camera.far_depth());
    }
}
