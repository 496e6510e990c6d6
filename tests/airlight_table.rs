//! The F′ table read back and compared, entry by entry, with the f64 reference (DESIGN §2,
//! issue 2): σt·D from 1e-4 to 100, γ from 1e-3 to π − 1e-3 (light in front of and behind the
//! eye), isotropic, HG(±0.9) and Rayleigh phases.

mod common;

use glam::{DVec3, Vec3};
use volshadow::nodes::{AirlightTableNode, TableSize};
use volshadow::reference;
use volshadow::{Cache, Medium, PhaseFunction, PointLight};

/// One table built on the GPU and checked against `reference::inscatter` on unshadowed rays.
/// Returns the largest relative error over the checked entries.
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
    table.prepare(&gpu.queue, eye, &light.into(), &medium);
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    assert!(
        table.encode(&mut encoder, None),
        "a fresh table must be built"
    );
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
            let gpu_t = texels[i * n + j];
            for c in 0..3 {
                if r[c] > 1e-6 * row_max {
                    let got = prefactor * f64::from(gpu_t[c]);
                    worst = worst.max((got - r[c]).abs() / r[c]);
                }
            }
        }
    }
    worst
}

#[test]
fn table_matches_reference_over_optical_depths_angles_and_phases() {
    let gpu = common::gpu();
    let cache = Cache::new(&gpu.device);
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
            println!("σt·D = {optical_depth:>7}: {phase:?}: max relative error {err:.3e}");
            overall = overall.max(err);
        }
    }
    println!(
        "F' table: max relative error over all entries checked: {overall:.3e} on {}",
        gpu.adapter_summary()
    );
    // Issue 2's bound for the table: 1e-3 relative on every entry above 1e-6 of its row's max.
    assert!(overall <= 1e-3, "max relative error {overall:.3e} > 1e-3");
}
