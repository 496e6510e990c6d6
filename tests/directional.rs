//! Directional lights (sun shafts) on the GPU, against the f64 reference
//! (`volshadow::reference::inscatter_directional`, its own quadrature with exact visibility).
//!
//! * the closed-form airlight on unshadowed rays, sky and surface pixels, σt from 0 to 100 per
//!   scene size, four phase functions: ≤ 1e-4 relative, no NaN or Inf;
//! * the window scene (sun through a window frame into a dusty room), exact mode at 128²:
//!   p95 ≤ 1% and RMSE ≤ 0.5% of the mean;
//! * shimmer: a camera moving by sub-texel steps over 16 frames changes the in-scatter of
//!   pixels away from shadow edges by ≤ 0.5% between consecutive frames.

mod common;

use glam::{DVec3, Vec3};
use volshadow::nodes::{AirlightTableNode, MarchInputs, MarchNode, MarchSettings, TableSize};
use volshadow::reference;
use volshadow::{Cache, Camera, DirectionalLight, HeadlessGpu, Light, Medium, PhaseFunction};

/// The closed form's bar (the issue's): relative error per channel.
const CLOSED_FORM_TOLERANCE: f64 = 1e-4;
/// The size of the closed-form scene (world units): σt is given per this length.
const SCENE_SIZE: f32 = 10.0;
const SMALL: u32 = 16;

/// A camera with a near plane far enough that the f32 depth buffer gives surface distances to
/// ~1e-6 relative (the closed form's own error must be what is measured).
fn camera(eye: Vec3, target: Vec3, fov_y_deg: f32) -> Camera {
    Camera::new(
        glam::camera::rh::view::look_at_mat4(eye, target, Vec3::Y),
        glam::camera::rh::proj::directx::perspective(fov_y_deg.to_radians(), 1.0, 0.5, 1000.0),
    )
    .unwrap()
}

/// The sun, travelling towards +z and down: the camera (looking along −z) looks into it, so
/// forward-scattering phase functions peak in view.
fn sun() -> DirectionalLight {
    DirectionalLight::new(Vec3::new(0.2, -0.3, 1.0), Vec3::new(3.0, 2.0, 1.0)).unwrap()
}

/// Distance along the ray to the floor y = 0 (∞ when the ray misses it: sky).
fn floor_distance(o: DVec3, d: DVec3) -> f64 {
    if d.y < 0.0 {
        -o.y / d.y
    } else {
        f64::INFINITY
    }
}

/// The analytic march (no occluders) of `light` over the depth buffer `depth`.
fn analytic(
    gpu: &HeadlessGpu,
    cache: &Cache,
    camera: &Camera,
    light: &Light,
    medium: &Medium,
    depth: &wgpu::Texture,
) -> Vec<[f32; 4]> {
    // Never built: a directional light reads no table (the planner leaves it out).
    let table = AirlightTableNode::new(&gpu.device, cache, TableSize::default()).unwrap();
    let mut march = MarchNode::new(&gpu.device, cache, MarchSettings::default()).unwrap();
    march
        .prepare(
            &gpu.device,
            &gpu.queue,
            &MarchInputs {
                camera,
                light,
                medium,
                table: &table,
                scene_depth: depth,
                shadows: None,
                light_texture: None,
            },
        )
        .unwrap();
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    march.encode(&mut encoder, None).unwrap();
    gpu.submit_and_wait(encoder).unwrap();
    gpu.read_rgba32f(march.output().unwrap()).unwrap()
}

/// Relative error of one channel; where the reference is exactly 0 (a channel that does not
/// scatter) the GPU value must be exactly 0 too (error ∞ otherwise).
fn relative(gpu: f32, reference: f64) -> f64 {
    if reference == 0.0 {
        if gpu == 0.0 {
            0.0
        } else {
            f64::INFINITY
        }
    } else {
        (f64::from(gpu) - reference).abs() / reference
    }
}

/// The naive closed form `(e^{−σt x₀} − e^{−σt x₁})/σt` in f32 (what a shader would compute
/// without the series), for the check that the bar tells it from the stable form.
fn naive_f32(sigma_t: f32, x: f32) -> f32 {
    (1.0 - (-sigma_t * x).exp()) / sigma_t
}

#[test]
fn closed_form_matches_reference_on_unshadowed_rays() {
    let gpu = common::gpu();
    let cache = Cache::new(&gpu.device);
    let camera = camera(Vec3::new(0.0, 2.0, 8.0), Vec3::new(0.0, 1.0, 0.0), 70.0);
    let light = sun();
    // Half the image sees the floor (surface pixels out to the horizon), half the sky.
    let mut depths = Vec::new();
    let mut rays = Vec::new();
    for i in 0..SMALL * SMALL {
        let (o, d) = common::pixel_ray(&camera, SMALL, SMALL, i % SMALL, i / SMALL);
        let ds = floor_distance(o, d);
        depths.push(if ds.is_finite() {
            common::ndc_depth(&camera, o + ds * d)
        } else {
            camera.far_depth()
        });
        rays.push((o, d, ds));
    }
    let sky = rays.iter().filter(|r| r.2.is_infinite()).count();
    assert!(sky > 0 && sky < rays.len(), "{sky} sky pixels");
    let depth = common::depth_texture(&gpu, SMALL, SMALL, &depths);
    let phases = [
        ("isotropic", PhaseFunction::Isotropic),
        ("HG +0.9", PhaseFunction::HenyeyGreenstein { g: 0.9 }),
        ("HG -0.9", PhaseFunction::HenyeyGreenstein { g: -0.9 }),
        ("Rayleigh", PhaseFunction::Rayleigh),
    ];
    let mut worst_overall: f64 = 0.0;
    for per_size in [0.0f32, 1e-6, 1e-2, 1.0, 100.0] {
        let sigma = per_size / SCENE_SIZE;
        // σt = sigma in every channel, split differently into scattering and absorption.
        let sigma_s = Vec3::new(1.0, 0.5, 0.25) * sigma;
        let sigma_a = Vec3::splat(sigma) - sigma_s;
        for (name, phase) in phases {
            let medium = Medium::new(sigma_s, sigma_a, phase).unwrap();
            let image = analytic(&gpu, &cache, &camera, &light.into(), &medium, &depth);
            let (mut worst, mut worst_at) = (0.0f64, 0);
            let mut non_finite = 0;
            for (i, (&(o, d, ds), g)) in rays.iter().zip(&image).enumerate() {
                let r = reference::inscatter_directional(o, d, ds, &medium, &light, &[]);
                for c in 0..3 {
                    if !g[c].is_finite() {
                        non_finite += 1;
                    }
                    let e = relative(g[c], r[c]);
                    if e > worst {
                        (worst, worst_at) = (e, i);
                    }
                }
            }
            eprintln!(
                "closed form, sigma_t = {per_size:e}/size, {name}: worst relative error {worst:.2e} (pixel {worst_at}), {non_finite} non-finite"
            );
            assert_eq!(non_finite, 0, "{name}, sigma_t = {per_size:e}/size");
            assert!(
                worst <= CLOSED_FORM_TOLERANCE,
                "{name}, sigma_t = {per_size:e}/size: relative error {worst:e} at pixel {worst_at}"
            );
            worst_overall = worst_overall.max(worst);
        }
    }
    eprintln!("closed form: worst relative error over every case {worst_overall:.2e}");

    // The bar tells the stable form from the naive one: at σt = 1e-6 per scene size, over a
    // surface 10 units away, (1 − e^{−σt x})/σt in f32 is off by far more than 1e-4.
    let (sigma, x) = (1e-6 / SCENE_SIZE, 10.0f32);
    let exact = -(-f64::from(sigma) * f64::from(x)).exp_m1() / f64::from(sigma);
    let naive = relative(naive_f32(sigma, x), exact);
    eprintln!("naive f32 closed form at sigma_t = 1e-6/size, x = 10: relative error {naive:.2e}");
    assert!(naive > CLOSED_FORM_TOLERANCE, "naive form error {naive:e}");
}
