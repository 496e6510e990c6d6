//! The quickstart example as a test: its in-scatter, small, against the f64 reference, and its
//! dark shafts are really there. A module of the example itself (`[[example]] test = true`), so
//! that it runs the example's own [`run`]: `cargo test --example quickstart`, and the crate's
//! `cargo test`. (Named `quickstart`, as its tests' metric lines have always been.)

use volshadow_harness::quickstart_scene::{reference_occluders, surface_distance};
use volshadow_harness::visibility;

use super::{run, run_with, scene, EXPOSURE, LIGHT_POSITION};

use glam::DVec3;
use volshadow::reference;
use volshadow::{HeadlessGpu, Settings};

const W: u32 = 128;
const H: u32 = 80;

#[test]
fn quickstart_matches_the_reference() {
    let gpu = HeadlessGpu::new().expect("GPU tests need a wgpu adapter (lavapipe works)");
    let rendered = run(&gpu, W, H, Settings::PREDICTABLE, 1).unwrap();
    assert!(rendered
        .output
        .iter()
        .all(|p| p.iter().all(|v| v.is_finite())));
    let (camera, light, medium) = scene(W, H).unwrap();
    let spheres = reference_occluders();
    // The app's depth: ground plane and the analytic spheres it ray-casts.
    let distance = surface_distance;
    let shadowed = reference::inscatter_image(&camera, W, H, distance, &medium, &light, &spheres);
    let open = reference::inscatter_image(&camera, W, H, distance, &medium, &light, &[]);
    // The light's own pixels: there the GPU clamps the singular 1/h by the pixel footprint on
    // purpose (DESIGN §2) while the reference integrates the one ray through the centre.
    let keep = reference::ImageError::keep_away_from_lights(&camera, &[light.into()], W, H);
    let near_light = |i: usize| !keep[i];
    let rmse = |a: &dyn Fn(usize) -> DVec3| {
        let (mut sq, mut sum) = (0.0, 0.0);
        for (i, r) in shadowed.iter().enumerate().filter(|(i, _)| !near_light(*i)) {
            let d = a(i) - *r;
            sq += d.length_squared();
            sum += r.x + r.y + r.z;
        }
        let n = 3.0 * (0..shadowed.len()).filter(|&i| !near_light(i)).count() as f64;
        (sq / n).sqrt() / (sum / n)
    };
    let gpu_rmse = rmse(&|i| {
        let p = rendered.inscatter[i];
        DVec3::new(p[0].into(), p[1].into(), p[2].into())
    });
    let no_shadow_rmse = rmse(&|i| open[i]);
    println!("quickstart at {W}x{H}: in-scatter RMSE {gpu_rmse:.4} of mean; without shadows it would be {no_shadow_rmse:.4}");
    volshadow_harness::metric::accuracy(
        &format!("quickstart scene at {W}x{H}; without shadows"),
        format!(
            "RMSE {:.2}%; {:.1}%",
            100.0 * gpu_rmse,
            100.0 * no_shadow_rmse
        ),
        "RMSE 2%; without > 5%",
    );
    // The spheres are tessellated (48×24) on the GPU and exact in the reference: the difference
    // lives on shadow edges. 2% is issue 5's bound for the standard scenes.
    assert!(gpu_rmse <= 0.02, "RMSE {gpu_rmse:.4}");
    assert!(
        no_shadow_rmse > 0.05,
        "the dark shafts should matter: {no_shadow_rmse:.4}"
    );
}

/// The quickstart's picture shows its shafts: at least [`visibility::MIN_VISIBLE_FRACTION`] of
/// the tone-mapped image (the PNG's exposure) differs from the same frame with unshadowed fog,
/// the demo-scene measure of `tests/examples/examples.rs`. A march that dropped the occluders (both
/// images alike) reads 0%.
#[test]
fn quickstart_shafts_are_visible() {
    let gpu = HeadlessGpu::new().expect("GPU tests need a wgpu adapter (lavapipe works)");
    let light = LIGHT_POSITION;
    let picture = |shadows| {
        let rendered = run_with(&gpu, (W, H), Settings::PREDICTABLE, 1, shadows, light).unwrap();
        volshadow::tone_map(&rendered.output, EXPOSURE)
    };
    let visible = visibility::visible_fraction_rgba(&picture(true), &picture(false));
    println!(
        "quickstart at {W}x{H}, light at {light}: {:.1}% of the picture shows the shadows \
         (required {:.0}%)",
        100.0 * visible,
        100.0 * visibility::MIN_VISIBLE_FRACTION
    );
    volshadow_harness::metric::accuracy(
        &format!("quickstart at {W}x{H}: shadows visible in the tone-mapped picture"),
        format!("{:.1}%", 100.0 * visible),
        format!("≥ {:.0}%", 100.0 * visibility::MIN_VISIBLE_FRACTION),
    );
    assert!(visible >= visibility::MIN_VISIBLE_FRACTION, "{visible}");
}

/// The `interactive` example shows this scene from `volshadow_harness::quickstart_scene` (which
/// also holds the app's pass that draws it): the camera, light and medium built here are the
/// same, so the two examples cannot drift apart.
#[test]
fn interactive_shows_the_same_scene() {
    let here = scene(W, H).unwrap();
    let shared = volshadow_harness::quickstart_scene::scene(W, H).unwrap();
    assert_eq!(here, shared);
}

/// Candidate light positions for the quickstart's picture (issue 36): prints each one's
/// visibility. `cargo test --example quickstart light_positions -- --ignored --nocapture`.
#[test]
#[ignore = "a survey, run by hand"]
fn light_positions() {
    let gpu = HeadlessGpu::new().unwrap();
    let candidates = std::env::var("QUICKSTART_LIGHTS").unwrap_or_default();
    for text in candidates.split(';').filter(|t| !t.is_empty()) {
        let v: Vec<f32> = text.split(',').map(|x| x.parse().unwrap()).collect();
        let light = glam::Vec3::new(v[0], v[1], v[2]);
        let picture = |shadows| {
            let rendered = run_with(
                &gpu,
                (W * 2, H * 2),
                Settings::PREDICTABLE,
                1,
                shadows,
                light,
            )
            .unwrap();
            volshadow::tone_map(&rendered.output, EXPOSURE)
        };
        let shadowed = picture(true);
        let visible = visibility::visible_fraction_rgba(&shadowed, &picture(false));
        let path = format!("/tmp/qs_{text}.png");
        image::RgbaImage::from_raw(W * 2, H * 2, shadowed)
            .unwrap()
            .save(&path)
            .unwrap();
        println!("light {light}: visible {:.1}% -> {path}", 100.0 * visible);
    }
}
