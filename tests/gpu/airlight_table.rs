//! The F′ table read back and compared, entry by entry, with the f64 reference (DESIGN §2,
//! issue 2): σt·D from 1e-4 to 100, γ from 1e-3 to π − 1e-3 (light in front of and behind the
//! eye), isotropic, HG(±0.9) and Rayleigh phases.

use volshadow::nodes::{Encode, Node};

use glam::{DVec3, Vec3};
use volshadow::nodes::{AirlightTableNode, TableSize};
use volshadow::reference;
use volshadow::{Cache, Medium, PhaseFunction, PointLight, ShaderPrecision};

/// One table built on the GPU and checked against `reference::inscatter` on unshadowed rays:
/// each head entry `T(s_j)` against the in-scatter from the eye to the point of `s_j`, and each
/// tail entry `∫_{s_j}^1` against the in-scatter beyond it (the reference's whole ray less the
/// part before, in f64, checked where that difference keeps 1e-9 of the whole, far below what
/// an f32 difference of heads could resolve). Returns the largest relative error over the
/// checked entries.
fn table_error(
    gpu: &volshadow::HeadlessGpu,
    cache: &Cache,
    optical_depth: f32,
    phase: PhaseFunction,
) -> f64 {
    let size = TableSize::default();
    let d = 3.0_f32; // eye–light distance
    let sigma_t = optical_depth / d;
    // σa > 0 on purpose: σt in the exponentials, σs only in the prefactor.
    let medium = Medium::new(
        Vec3::splat(0.6 * sigma_t),
        Vec3::splat(0.4 * sigma_t),
        phase,
    )
    .unwrap();
    let eye = Vec3::new(0.5, 1.0, -2.0);
    let light = PointLight::new(eye + Vec3::new(0.0, 0.0, d), Vec3::ONE).unwrap();

    let mut table = AirlightTableNode::new(&gpu.device, cache, size).unwrap();
    let light = light.into();
    let inputs = volshadow::nodes::TableInputs {
        eye,
        light: &light,
        medium: &medium,
    };
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    assert!(
        table.prepare(&gpu.device, &gpu.queue, &inputs).unwrap(),
        "a fresh table must be built"
    );
    table.encode(&mut encoder, None).unwrap();
    gpu.submit_and_wait(encoder).unwrap();
    let texels = gpu.read_rgba32f(table.texture()).unwrap();
    assert!(
        texels.iter().flatten().all(|v| v.is_finite()),
        "non-finite table entry at σt·D = {optical_depth}, {phase:?}"
    );

    let (n, rows) = (size.along_ray as usize, size.across_rays as usize);
    let eye_d = eye.as_dvec3();
    let dd = f64::from(d);
    let mut worst: f64 = 0.0;
    for i in (1..rows - 1).filter(|i| i % 8 == 1 || *i == rows - 2) {
        // The row's γ and π − γ as the shader defines them, in f64: the shader's f32 rounding
        // moves T by ~1e-7, but x(s) below is sensitive to π − γ near γ = 0, so the geometry
        // must use the exact values.
        let t = i as f64 / (rows - 1) as f64;
        let gamma = std::f64::consts::PI * t * t;
        let w = std::f64::consts::PI * (1.0 - t) * (1.0 + t);
        if !(1e-3..=std::f64::consts::PI - 1e-3).contains(&gamma) {
            continue;
        }
        // A ray from the eye at angle γ to the light (which lies along +z).
        let dir = DVec3::new(gamma.sin(), 0.0, gamma.cos());
        let sigma_s = f64::from(0.6 * sigma_t);
        let prefactor = sigma_s * (-f64::from(sigma_t) * dd).exp() * w / (dd * gamma.sin());
        let whole = reference::inscatter(eye_d, dir, f64::INFINITY, &medium, &light, &[]);
        let entries: Vec<(usize, DVec3)> = (1..n)
            .filter(|j| j % 4 == 0 || *j == 1 || *j == n - 1)
            .map(|j| {
                let s = j as f64 / (n - 1) as f64;
                // The end point whose normalised scattering angle is s (law of sines).
                let x = if j == n - 1 {
                    f64::INFINITY
                } else {
                    dd * (s * w).sin() / ((1.0 - s) * w).sin()
                };
                (j, reference::inscatter(eye_d, dir, x, &medium, &light, &[]))
            })
            .collect();
        let row_max = entries
            .iter()
            .map(|(_, r)| r.max_element())
            .fold(0.0, f64::max);
        for (j, r) in entries {
            // A row holds the heads, then the tails (see `AirlightTableNode`).
            let gpu_t = texels[i * 2 * n + j];
            let gpu_tail = texels[i * 2 * n + n + j];
            let tail = whole - r;
            for c in 0..3 {
                if r[c] > 1e-6 * row_max {
                    let got = prefactor * f64::from(gpu_t[c]);
                    worst = worst.max((got - r[c]).abs() / r[c]);
                }
                if j + 1 < n && tail[c] > 1e-9 * whole[c] && tail[c] > 1e-30 {
                    let got = prefactor * f64::from(gpu_tail[c]);
                    worst = worst.max((got - tail[c]).abs() / tail[c]);
                }
            }
        }
    }
    worst
}

volshadow_harness::at_each_precision!(
    table_matches_reference_at => table_matches_reference_over_optical_depths_angles_and_phases,
    table_matches_reference_worst_case,
    volshadow_harness::WORST_CASES
);

fn table_matches_reference_at(precision: ShaderPrecision) {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache_with(&gpu, precision);
    let phases = [
        PhaseFunction::Isotropic,
        PhaseFunction::HenyeyGreenstein { g: 0.9 },
        PhaseFunction::HenyeyGreenstein { g: -0.9 },
        PhaseFunction::Rayleigh,
    ];
    let mut overall: f64 = 0.0;
    for optical_depth in [1e-4, 1e-2, 1.0, 10.0, 100.0] {
        for phase in phases {
            let err = table_error(&gpu, &cache, optical_depth, phase);
            println!(
                "{precision:?}: σt·D = {optical_depth:>7}: {phase:?}: max relative error {err:.3e}"
            );
            overall = overall.max(err);
        }
    }
    println!(
        "{precision:?}: F' table: max relative error over all entries checked: {overall:.3e} on {}",
        gpu.adapter_summary()
    );
    volshadow_harness::metric::accuracy(
        &format!(
            "{precision:?}: F′ table entries against the f64 reference, σt·D 1e-4…100, every phase"
        ),
        format!("max {overall:.2e}"),
        "1e-3",
    );
    // Issue 2's bound for the table: 1e-3 relative on every entry above 1e-6 of its row's max.
    assert!(
        overall <= 1e-3,
        "{precision:?}: max relative error {overall:.3e} > 1e-3"
    );
}

/// p95 and max relative error of the unshadowed in-scatter of a 64×64 ground-plane frame
/// (light in view, sky pixels) built with a `size` table, against the f64 reference, over
/// pixels whose reference is above 1% of the frame's maximum (the light's own pixels, where
/// the GPU clamps the singular 1/h by the pixel footprint, are left out).
fn frame_error(
    gpu: &volshadow::HeadlessGpu,
    cache: &Cache,
    size: TableSize,
    medium: &Medium,
    reference_image: &[DVec3],
) -> (f64, f64) {
    const N: u32 = 64;
    let (camera, light) = frame_scene();
    let depths: Vec<f32> = (0..N * N)
        .map(|i| {
            let (o, d) = volshadow_harness::pixel_ray(&camera, N, N, i % N, i / N);
            let t = ground(o, d);
            if t.is_finite() {
                volshadow_harness::ndc_depth(&camera, o + t * d)
            } else {
                camera.far_depth()
            }
        })
        .collect();
    let depth = volshadow_harness::depth_texture(gpu, N, N, &depths);
    let texels = volshadow_harness::march_frame(gpu, cache, size, &camera, &light, medium, &depth);
    let keep = reference::ImageError::keep_away_from_lights(&camera, &[light.into()], N, N);
    let near_light = |i: usize| !keep[i];
    let max_ref = reference_image
        .iter()
        .enumerate()
        .filter(|(i, _)| !near_light(*i))
        .map(|(_, r)| r.max_element())
        .fold(0.0, f64::max);
    let mut errors: Vec<f64> = Vec::new();
    for (i, r) in reference_image.iter().enumerate() {
        if near_light(i) {
            continue;
        }
        for c in 0..3 {
            if r[c] > 0.01 * max_ref {
                errors.push((f64::from(texels[i][c]) - r[c]).abs() / r[c]);
            }
        }
    }
    errors.sort_by(f64::total_cmp);
    let p95 = errors[(errors.len() * 95) / 100];
    (p95, *errors.last().unwrap())
}

fn ground(o: DVec3, d: DVec3) -> f64 {
    if d.y < 0.0 {
        -o.y / d.y
    } else {
        f64::INFINITY
    }
}

fn frame_scene() -> (volshadow::Camera, PointLight) {
    let camera = volshadow_harness::look_at(
        Vec3::new(0.0, 1.5, 6.0),
        Vec3::new(0.0, 1.0, 0.0),
        60.0,
        1.0,
    );
    let light = PointLight::new(Vec3::new(0.5, 2.0, -1.0), Vec3::splat(10.0)).unwrap();
    (camera, light)
}

/// The smallest table dimensions accepted ([`TableSize::MIN_ALONG_RAY`],
/// [`TableSize::MIN_ACROSS_RAYS`]) are where the measured p95 error of a whole frame stays
/// within 0.2%, under a third of the tightest configuration of the planner's error table
/// (0.73%); smaller tables are rejected (the 2×2 table that used to be accepted has p95 errors
/// of 57–875%).
#[test]
fn table_size_minimum_is_where_the_frame_error_stays_within_a_fifth_of_a_percent() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let (camera, light) = frame_scene();
    let media = [
        Medium::new(
            Vec3::splat(0.05),
            Vec3::splat(0.01),
            PhaseFunction::Isotropic,
        )
        .unwrap(),
        Medium::new(
            Vec3::splat(0.3),
            Vec3::splat(0.1),
            PhaseFunction::HenyeyGreenstein { g: 0.9 },
        )
        .unwrap(),
        Medium::new(
            Vec3::new(0.5, 0.8, 1.2),
            Vec3::splat(0.05),
            PhaseFunction::HenyeyGreenstein { g: -0.5 },
        )
        .unwrap(),
    ];
    // A third of the tightest configuration the error target offers (p95 0.73%).
    const BOUND: f64 = 2e-3;
    let min = TableSize {
        along_ray: TableSize::MIN_ALONG_RAY,
        across_rays: TableSize::MIN_ACROSS_RAYS,
    };
    let mut worst_at_min: f64 = 0.0;
    for medium in &media {
        let reference_image =
            reference::inscatter_image(&camera, 64, 64, ground, medium, &light, &[]);
        // Sizes from the minimum up (smaller ones are rejected; with the minimum lowered to 2
        // the same sweep measured, worst over these media: along the ray 2: 57%, 4: 0.39%;
        // across rays 2: 875%, 16: 11%, 64: 0.59%).
        for n in [TableSize::MIN_ALONG_RAY, 16, 64, 256] {
            let (p95, max) = frame_error(
                &gpu,
                &cache,
                TableSize {
                    along_ray: n,
                    across_rays: 256,
                },
                medium,
                &reference_image,
            );
            println!(
                "{:?}: {n:>3} along the ray: p95 {p95:.2e} max {max:.2e}",
                medium.phase()
            );
        }
        for n in [TableSize::MIN_ACROSS_RAYS, 256] {
            let (p95, max) = frame_error(
                &gpu,
                &cache,
                TableSize {
                    along_ray: 256,
                    across_rays: n,
                },
                medium,
                &reference_image,
            );
            println!(
                "{:?}: {n:>3} across rays: p95 {p95:.2e} max {max:.2e}",
                medium.phase()
            );
        }
        let (p95, max) = frame_error(&gpu, &cache, min, medium, &reference_image);
        println!(
            "{:?}: minimum table {}x{}: p95 {p95:.2e} max {max:.2e}",
            medium.phase(),
            min.along_ray,
            min.across_rays
        );
        worst_at_min = worst_at_min.max(p95);
    }
    volshadow_harness::metric::accuracy(
        "the smallest F′ table: frame p95 against the reference",
        format!("p95 {:.3}%", 100.0 * worst_at_min),
        format!("p95 {}%", 100.0 * BOUND),
    );
    assert!(worst_at_min <= BOUND, "{worst_at_min:.2e}");
    for small in [
        TableSize {
            along_ray: min.along_ray - 1,
            across_rays: 256,
        },
        TableSize {
            along_ray: 256,
            across_rays: min.across_rays - 1,
        },
        TableSize {
            along_ray: 2,
            across_rays: 2,
        },
    ] {
        let err = AirlightTableNode::new(&gpu.device, &cache, small).err();
        assert!(
            matches!(err, Some(volshadow::Error::InvalidSize { .. })),
            "{small:?}: {err:?}"
        );
    }
}
