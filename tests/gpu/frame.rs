//! Whole frames of unshadowed airlight against the f64 reference (issue 2): a ground plane,
//! sky pixels and the light in view; the light behind the camera; absorption ≫ scattering.

use glam::{DVec3, Vec3};
use volshadow::nodes::TableSize;
use volshadow::reference;
use volshadow::{Cache, Camera, HeadlessGpu, Medium, PhaseFunction, PointLight, ShaderPrecision};

const SIZE: u32 = 128;

/// Eye distance to the ground plane y = 0 (infinite for rays that miss it: sky).
fn ground_distance(origin: DVec3, dir: DVec3) -> f64 {
    if dir.y < 0.0 {
        -origin.y / dir.y
    } else {
        f64::INFINITY
    }
}

struct Comparison {
    /// Largest relative error over the pixels compared.
    max_rel: f64,
    /// How many pixels were compared.
    compared: usize,
    /// GPU in-scatter and reference, per pixel.
    gpu: Vec<[f32; 4]>,
    reference: Vec<DVec3>,
}

/// Renders the ground-plane frame on the GPU and with the reference, and compares pixels whose
/// reference in-scatter is above 1% of the frame's maximum.
fn compare_frame(
    gpu: &HeadlessGpu,
    cache: &Cache,
    camera: &Camera,
    light: &PointLight,
    medium: &Medium,
) -> Comparison {
    let depths: Vec<f32> = (0..SIZE * SIZE)
        .map(|i| {
            let (eye, dir) = volshadow_harness::pixel_ray(camera, SIZE, SIZE, i % SIZE, i / SIZE);
            let ds = ground_distance(eye, dir);
            if ds.is_finite() {
                volshadow_harness::ndc_depth(camera, eye + ds * dir)
            } else {
                camera.far_depth()
            }
        })
        .collect();
    let depth = volshadow_harness::depth_texture(gpu, SIZE, SIZE, &depths);
    let texels = volshadow_harness::march_frame(
        gpu,
        cache,
        TableSize::default(),
        camera,
        light,
        medium,
        &depth,
    );
    assert!(
        texels.iter().all(|t| t[0..3].iter().all(|v| v.is_finite())),
        "NaN or Inf in the in-scatter"
    );
    let reference =
        reference::inscatter_image(camera, SIZE, SIZE, ground_distance, medium, light, &[]);

    // The light's own pixels, where the GPU clamps the singular 1/h by the pixel footprint on
    // purpose while the reference integrates the one ray through the pixel centre.
    let keep = reference::ImageError::keep_away_from_lights(camera, &[light.into()], SIZE, SIZE);
    let near_light = |i: usize| !keep[i];
    let max_ref = (0..reference.len())
        .filter(|&i| !near_light(i))
        .map(|i| reference[i].max_element())
        .fold(0.0, f64::max);
    let mut max_rel: f64 = 0.0;
    let mut compared = 0;
    for (i, r) in reference.iter().enumerate() {
        if near_light(i) {
            continue;
        }
        for c in 0..3 {
            if r[c] > 0.01 * max_ref {
                let got = f64::from(texels[i][c]);
                max_rel = max_rel.max((got - r[c]).abs() / r[c]);
                compared += 1;
            }
        }
    }
    Comparison {
        max_rel,
        compared,
        gpu: texels,
        reference,
    }
}

fn camera() -> Camera {
    volshadow_harness::look_at(
        Vec3::new(0.0, 1.5, 6.0),
        Vec3::new(0.0, 1.0, 0.0),
        60.0,
        1.0,
    )
}

// Issue 2's bound: per-pixel in-scatter within 0.5% of the reference where it is above 1% of
// the frame's maximum.
const FRAME_TOLERANCE: f64 = 5e-3;

volshadow_harness::at_each_precision!(
    ground_plane_with_sky_and_light_in_view_at => ground_plane_with_sky_and_light_in_view,
    ground_plane_with_sky_and_light_in_view_worst_case,
    volshadow_harness::WORST_CASES
);

fn ground_plane_with_sky_and_light_in_view_at(precision: ShaderPrecision) {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache_with(&gpu, precision);
    let camera = camera();
    let light = PointLight::new(Vec3::new(0.6, 2.2, -1.0), Vec3::new(40.0, 36.0, 30.0)).unwrap();
    for phase in [
        PhaseFunction::Isotropic,
        PhaseFunction::HenyeyGreenstein { g: 0.7 },
    ] {
        let medium = Medium::new(Vec3::new(0.10, 0.12, 0.15), Vec3::splat(0.02), phase).unwrap();
        let cmp = compare_frame(&gpu, &cache, &camera, &light, &medium);
        println!(
            "{precision:?}: light in view, {phase:?}: max relative error {:.3e} over {} channel-pixels",
            cmp.max_rel, cmp.compared
        );
        volshadow_harness::metric::accuracy(
            &format!("{precision:?}: 128² ground and sky, light in view, {phase:?}"),
            format!("max {:.1e}", cmp.max_rel),
            format!("{FRAME_TOLERANCE:.0e}"),
        );
        // A quarter of the frame at least, so the comparison is not vacuous.
        assert!(
            cmp.compared > 3 * 4096,
            "too few pixels compared: {}",
            cmp.compared
        );
        assert!(
            cmp.max_rel <= FRAME_TOLERANCE,
            "max relative error {:.3e}",
            cmp.max_rel
        );
        // The light's pixel is the brightest and finite.
        let brightest = cmp.gpu.iter().map(|t| t[0]).fold(0.0, f32::max);
        assert!(
            brightest.is_finite()
                && f64::from(brightest)
                    > cmp.reference.iter().map(|r| r.x).fold(0.0, f64::max) * 0.1
        );
    }
}

volshadow_harness::at_each_precision!(
    light_behind_the_camera_at => light_behind_the_camera,
    light_behind_the_camera_worst_case,
    volshadow_harness::WORST_CASES
);

fn light_behind_the_camera_at(precision: ShaderPrecision) {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache_with(&gpu, precision);
    let camera = camera();
    let light = PointLight::new(Vec3::new(-0.5, 2.5, 9.0), Vec3::splat(50.0)).unwrap();
    let medium = Medium::new(
        Vec3::splat(0.15),
        Vec3::splat(0.05),
        PhaseFunction::Rayleigh,
    )
    .unwrap();
    let cmp = compare_frame(&gpu, &cache, &camera, &light, &medium);
    println!(
        "{precision:?}: light behind the camera: max relative error {:.3e} over {} channel-pixels",
        cmp.max_rel, cmp.compared
    );
    volshadow_harness::metric::accuracy(
        &format!("{precision:?}: light behind the camera, Rayleigh"),
        format!("max {:.1e}", cmp.max_rel),
        format!("{FRAME_TOLERANCE:.0e}"),
    );
    assert!(cmp.compared > 3 * 4096);
    assert!(
        cmp.max_rel <= FRAME_TOLERANCE,
        "max relative error {:.3e}",
        cmp.max_rel
    );
}

volshadow_harness::at_each_precision!(
    absorption_three_times_scattering_at => absorption_three_times_scattering,
    absorption_three_times_scattering_worst_case,
    [volshadow_harness::WORST_CASE]
);

fn absorption_three_times_scattering_at(precision: ShaderPrecision) {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache_with(&gpu, precision);
    let camera = camera();
    let light = PointLight::new(Vec3::new(0.6, 2.2, -1.0), Vec3::splat(40.0)).unwrap();
    let sigma_s = Vec3::splat(0.08);
    let medium = Medium::new(
        sigma_s,
        3.0 * sigma_s,
        PhaseFunction::HenyeyGreenstein { g: 0.4 },
    )
    .unwrap();
    let cmp = compare_frame(&gpu, &cache, &camera, &light, &medium);
    println!(
        "{precision:?}: σa = 3σs: max relative error {:.3e} over {} channel-pixels",
        cmp.max_rel, cmp.compared
    );
    volshadow_harness::metric::accuracy(
        &format!("{precision:?}: σa = 3σs (a wrong σs/σt split is off by 300%)"),
        format!("max {:.1e}", cmp.max_rel),
        format!("{FRAME_TOLERANCE:.0e}"),
    );
    assert!(
        cmp.max_rel <= FRAME_TOLERANCE,
        "max relative error {:.3e}",
        cmp.max_rel
    );

    // The test can tell a wrong split: the same σt all counted as scattering (σs = σt, σa = 0)
    // must be off by far more than the tolerance.
    let wrong = Medium::new(4.0 * sigma_s, Vec3::ZERO, medium.phase()).unwrap();
    let wrong_ref =
        reference::inscatter_image(&camera, SIZE, SIZE, ground_distance, &wrong, &light, &[]);
    let median_rel = {
        let mut rel: Vec<f64> = cmp
            .reference
            .iter()
            .zip(&wrong_ref)
            .filter(|(r, _)| r.x > 0.0)
            .map(|(r, w)| (w.x - r.x).abs() / r.x)
            .collect();
        rel.sort_by(f64::total_cmp);
        rel[rel.len() / 2]
    };
    println!("wrong σs/σt split: median relative difference {median_rel:.3}");
    assert!(
        median_rel > 0.10,
        "a wrong split differs by only {median_rel:.3}"
    );
}

volshadow_harness::at_each_precision!(
    stiff_optical_depths_random_distances_at => stiff_optical_depths_random_distances,
    stiff_optical_depths_random_distances_worst_case,
    volshadow_harness::WORST_CASES
);

/// Random rays with random surface distances (1e-2·D … 1e3·D, and sky) at every optical depth of
/// DESIGN §5, seen through a reversed-Z infinite projection, with the light in view and behind.
fn stiff_optical_depths_random_distances_at(precision: ShaderPrecision) {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache_with(&gpu, precision);
    let eye = Vec3::new(1.0, 2.0, 3.0);
    let camera = Camera::new(
        glam::camera::rh::view::look_to_mat4(eye, Vec3::new(0.2, -0.1, -1.0), Vec3::Y),
        glam::camera::rh::proj::directx::perspective_infinite_reverse(1.6, 1.0, 0.01),
    )
    .unwrap();
    let d = 4.0_f32;
    let mut rng = 0x2545_f491_4f6c_dd1d_u64;
    let mut uniform = move || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        (rng >> 11) as f64 / (1u64 << 53) as f64
    };
    let distances: Vec<f64> = (0..SIZE * SIZE)
        .map(|_| {
            if uniform() < 0.1 {
                f64::INFINITY
            } else {
                // 1e-2·D = 0.04 is beyond the near plane (0.01): nearer surfaces would be clipped.
                f64::from(d) * 10f64.powf(-2.0 + 5.0 * uniform())
            }
        })
        .collect();
    let depths: Vec<f32> = (0..SIZE * SIZE)
        .map(|i| {
            let ds = distances[i as usize];
            if ds.is_finite() {
                let (o, dir) =
                    volshadow_harness::pixel_ray(&camera, SIZE, SIZE, i % SIZE, i / SIZE);
                volshadow_harness::ndc_depth(&camera, o + ds * dir)
            } else {
                camera.far_depth()
            }
        })
        .collect();
    let depth = volshadow_harness::depth_texture(&gpu, SIZE, SIZE, &depths);
    let pixel_of = |o: DVec3, dir: DVec3| -> usize {
        // Recover the pixel index from the ray (the reference hands us rays, not indices).
        let clip =
            camera.projection().as_dmat4() * camera.view().as_dmat4() * (o + dir).extend(1.0);
        let ndc = clip.truncate() / clip.w;
        let px = ((ndc.x + 1.0) * 0.5 * f64::from(SIZE)).floor() as usize;
        let py = ((1.0 - ndc.y) * 0.5 * f64::from(SIZE)).floor() as usize;
        py * SIZE as usize + px
    };
    let mut worst: f64 = 0.0;
    for (label, light_dir) in [
        ("in view", Vec3::new(0.25, -0.1, -1.0)),
        ("behind", Vec3::new(0.3, 0.2, 1.0)),
    ] {
        let light_pos = eye + light_dir.normalize() * d;
        for optical_depth in [1e-4_f32, 1e-2, 1.0, 10.0, 100.0] {
            // Scale I0 so that the image is O(1) where f32 allows it (at σt·D = 100 the result is
            // ~1e-14: it must survive exp(−100) without underflowing to zero).
            let i0 = optical_depth.exp().min(1e30);
            let light = PointLight::new(light_pos, Vec3::splat(i0)).unwrap();
            let sigma_t = optical_depth / d;
            let medium = Medium::new(
                Vec3::splat(0.5 * sigma_t),
                Vec3::splat(0.5 * sigma_t),
                PhaseFunction::HenyeyGreenstein { g: 0.5 },
            )
            .unwrap();
            let texels = volshadow_harness::march_frame(
                &gpu,
                &cache,
                TableSize::default(),
                &camera,
                &light,
                &medium,
                &depth,
            );
            assert!(
                texels.iter().all(|t| t[0..3].iter().all(|v| v.is_finite())),
                "NaN/Inf at σt·D = {optical_depth}"
            );
            let reference = reference::inscatter_image(
                &camera,
                SIZE,
                SIZE,
                |o, dir| distances[pixel_of(o, dir)],
                &medium,
                &light,
                &[],
            );
            let keep =
                reference::ImageError::keep_away_from_lights(&camera, &[light.into()], SIZE, SIZE);
            let near_light = |i: usize| !keep[i];
            let max_ref = (0..reference.len())
                .filter(|&i| !near_light(i))
                .map(|i| reference[i].x)
                .fold(0.0, f64::max);
            let mut max_rel: f64 = 0.0;
            let mut compared = 0;
            for i in (0..reference.len()).filter(|&i| !near_light(i)) {
                let r = reference[i].x;
                if r > 0.01 * max_ref {
                    max_rel = max_rel.max((f64::from(texels[i][0]) - r).abs() / r);
                    compared += 1;
                }
            }
            println!("{precision:?}: light {label}, σt·D = {optical_depth:>6}: max relative error {max_rel:.3e} over {compared} pixels");
            assert!(compared > 200, "too few pixels compared: {compared}");
            worst = worst.max(max_rel);
        }
    }
    volshadow_harness::metric::accuracy(
        &format!(
            "{precision:?}: random rays and distances, σt·D 1e-4…100, light in view and behind"
        ),
        format!("max {worst:.1e}"),
        format!("{FRAME_TOLERANCE:.0e}"),
    );
    // Same bound as the frame tests (issue 2): 0.5% where the reference is above 1% of its max.
    assert!(
        worst <= FRAME_TOLERANCE,
        "{precision:?}: max relative error {worst:.3e}"
    );
}
