//! Volumetric shadows against the f64 reference with exact visibility (issue 3): shadow maps,
//! shadow-volume extents, hybrid and brute-force march.

use glam::{DVec3, Mat4, Vec3};
use volshadow::gpu::{Occluder, OccluderMesh};
use volshadow::nodes::{MarchMethod, MarchSettings, Scale, UpsampleFilter};
use volshadow::reference::{self, TriangleMesh};
use volshadow::scene::{shapes, Mesh};
use volshadow::{Cache, Camera, HeadlessGpu, Light, Medium, PhaseFunction, PointLight, SpotLight};
use volshadow_harness::ShadowPasses;

const SIZE: u32 = 128;
const SHADOW_RES: u32 = 1024;
/// The accuracy target for shadowed scenes: in-scatter RMSE (and the shadow-map sweep's p95)
/// within 2% of the mean against the f64 reference, as the README's table states.
const MAX_RMSE: f64 = 0.02;

/// Geometry seen by the camera (its depth buffer): a ground plane and analytic spheres.
struct Scene {
    spheres: Vec<(DVec3, f64)>,
    occluders: Vec<(Mesh, Mat4)>,
}

impl Scene {
    fn distance(&self, o: DVec3, d: DVec3) -> f64 {
        let mut t = if d.y < 0.0 { -o.y / d.y } else { f64::INFINITY };
        for &(c, r) in &self.spheres {
            let oc = o - c;
            let b = oc.dot(d);
            let disc = b * b - (oc.length_squared() - r * r);
            if disc >= 0.0 {
                let hit = -b - disc.sqrt();
                if hit > 0.0 {
                    t = t.min(hit);
                }
            }
        }
        t
    }

    fn reference_occluders(&self) -> Vec<reference::Occluder> {
        self.occluders
            .iter()
            .map(|(m, t)| {
                reference::Occluder::Mesh(TriangleMesh::from_indexed(
                    m.positions(),
                    m.indices(),
                    t.as_dmat4(),
                ))
            })
            .collect()
    }
}

struct Metrics {
    /// RMSE of the in-scatter over all pixels and channels, relative to its mean.
    rmse_rel: f64,
    /// Largest per-pixel relative error outside a 2-pixel band around shadow boundaries,
    /// where the reference is above 1% of its maximum.
    max_rel_outside_band: f64,
    frame: volshadow_harness::ShadowFrame,
}

fn render(
    gpu: &HeadlessGpu,
    cache: &Cache,
    camera: &Camera,
    light: &Light,
    medium: &Medium,
    scene: &Scene,
    settings: MarchSettings,
) -> Metrics {
    render_upsampled(
        gpu,
        cache,
        camera,
        light,
        medium,
        scene,
        settings,
        UpsampleFilter::DepthAware3x3,
    )
}

#[allow(clippy::too_many_arguments)]
fn render_upsampled(
    gpu: &HeadlessGpu,
    cache: &Cache,
    camera: &Camera,
    light: &Light,
    medium: &Medium,
    scene: &Scene,
    settings: MarchSettings,
    filter: UpsampleFilter,
) -> Metrics {
    let rays: Vec<(DVec3, DVec3)> = (0..SIZE * SIZE)
        .map(|i| volshadow_harness::pixel_ray(camera, SIZE, SIZE, i % SIZE, i / SIZE))
        .collect();
    let depths: Vec<f32> = rays
        .iter()
        .map(|&(o, d)| {
            let ds = scene.distance(o, d);
            if ds.is_finite() {
                volshadow_harness::ndc_depth(camera, o + ds * d)
            } else {
                camera.far_depth()
            }
        })
        .collect();
    let depth = volshadow_harness::depth_texture(gpu, SIZE, SIZE, &depths);
    let meshes: Vec<OccluderMesh> = scene
        .occluders
        .iter()
        .map(|(m, _)| OccluderMesh::new(&gpu.device, m))
        .collect();
    let occluders: Vec<Occluder> = meshes
        .iter()
        .zip(&scene.occluders)
        .map(|(mesh, (_, transform))| Occluder {
            mesh,
            transform: *transform,
        })
        .collect();
    let passes = ShadowPasses::new(camera, light, medium, &depth, &occluders)
        .settings(settings)
        .shadow_resolution(SHADOW_RES)
        .filter(filter);
    let frame = volshadow_harness::shadow_frame(gpu, cache, &passes);
    assert!(
        frame
            .inscatter
            .iter()
            .all(|t| t[0..3].iter().all(|v| v.is_finite() && *v >= 0.0)),
        "NaN, Inf or negative in-scatter"
    );
    let ref_occ = scene.reference_occluders();
    let reference = reference::inscatter_image(
        camera,
        SIZE,
        SIZE,
        |o, d| scene.distance(o, d),
        medium,
        light,
        &ref_occ,
    );

    // Shadow boundaries: pixels whose ray has a different number of lit intervals than a
    // neighbour's; the band is everything within 2 pixels of one.
    let intervals: Vec<usize> = rays
        .iter()
        .map(|&(o, d)| {
            reference::lit_intervals(
                o,
                d,
                scene.distance(o, d),
                light.position().unwrap().as_dvec3(),
                &ref_occ,
            )
            .len()
        })
        .collect();
    let n = SIZE as i64;
    let at = |x: i64, y: i64| intervals[(y.clamp(0, n - 1) * n + x.clamp(0, n - 1)) as usize];
    let boundary: Vec<bool> = (0..n * n)
        .map(|i| {
            let (x, y) = (i % n, i / n);
            [(1, 0), (-1, 0), (0, 1), (0, -1)]
                .iter()
                .any(|(dx, dy)| at(x + dx, y + dy) != at(x, y))
        })
        .collect();
    let in_band = |i: i64| {
        let (x, y) = (i % n, i / n);
        (-2..=2).any(|dy| {
            (-2..=2).any(|dx| {
                let (xx, yy) = (x + dx, y + dy);
                (0..n).contains(&xx) && (0..n).contains(&yy) && boundary[(yy * n + xx) as usize]
            })
        })
    };
    let near = near_light(camera, light);
    let near_light = |i: usize| near[i];
    let max_ref = (0..reference.len())
        .filter(|&i| !near_light(i))
        .map(|i| reference[i].max_element())
        .fold(0.0, f64::max);
    let (mut sq, mut sum, mut count) = (0.0, 0.0, 0.0);
    let mut max_rel: f64 = 0.0;
    for (i, r) in reference.iter().enumerate() {
        if near_light(i) {
            continue;
        }
        for c in 0..3 {
            let g = f64::from(frame.inscatter[i][c]);
            sq += (g - r[c]).powi(2);
            sum += r[c];
            count += 1.0;
            if r[c] > 0.01 * max_ref && !in_band(i as i64) {
                max_rel = max_rel.max((g - r[c]).abs() / r[c]);
            }
        }
    }
    Metrics {
        rmse_rel: (sq / count).sqrt() / (sum / count),
        max_rel_outside_band: max_rel,
        frame,
    }
}

/// Per pixel, whether it looks at the light (`ImageError::keep_away_from_lights`): there the
/// GPU clamps the singular 1/h by the pixel footprint on purpose while the reference
/// integrates one ray.
fn near_light(camera: &Camera, light: &Light) -> Vec<bool> {
    reference::ImageError::keep_away_from_lights(camera, &[*light], SIZE, SIZE)
        .into_iter()
        .map(|keep| !keep)
        .collect()
}

fn look_at(eye: Vec3, target: Vec3) -> Camera {
    volshadow_harness::look_at(eye, target, 60.0, 1.0)
}

fn sphere_scene() -> Scene {
    let center = Vec3::new(0.0, 2.0, 0.0);
    Scene {
        spheres: vec![(center.as_dvec3(), 0.6)],
        occluders: vec![(
            shapes::uv_sphere(center, 0.6, 24, 12).unwrap(),
            Mat4::IDENTITY,
        )],
    }
}

fn medium() -> Medium {
    Medium::new(
        Vec3::new(0.25, 0.27, 0.30),
        Vec3::splat(0.03),
        PhaseFunction::HenyeyGreenstein { g: 0.3 },
    )
    .unwrap()
}

fn point_light(p: Vec3) -> Light {
    PointLight::new(p, Vec3::new(30.0, 28.0, 25.0))
        .unwrap()
        .into()
}

fn hybrid(steps: u32) -> MarchSettings {
    MarchSettings {
        method: MarchMethod::Hybrid,
        steps,
        ..MarchSettings::default()
    }
}
fn brute(steps: u32) -> MarchSettings {
    MarchSettings {
        method: MarchMethod::BruteForce,
        steps,
        ..MarchSettings::default()
    }
}

#[test]
fn sphere_above_plane_hybrid_and_brute_force() {
    let gpu = volshadow_harness::gpu_timed();
    let cache = volshadow_harness::cache(&gpu);
    let camera = look_at(Vec3::new(0.0, 1.2, 5.0), Vec3::new(0.0, 0.9, 0.0));
    let light = point_light(Vec3::new(0.4, 4.2, -0.3));
    let scene = sphere_scene();

    let h = render(&gpu, &cache, &camera, &light, &medium(), &scene, hybrid(64));
    println!(
        "hybrid 64 steps: RMSE {:.4} of mean, max rel outside band {:.4}, march {:.3} ms",
        h.rmse_rel,
        h.max_rel_outside_band,
        h.frame.time_ms("march")
    );
    volshadow_harness::metric::accuracy(
        "sphere shadow, 128², hybrid at 64 steps: RMSE; max outside 2 px of shadow edges",
        format!(
            "RMSE {:.3}%, max {:.2}%",
            100.0 * h.rmse_rel,
            100.0 * h.max_rel_outside_band
        ),
        "RMSE 2%, max 10%",
    );
    // Issue 3: hybrid at 64 steps within 2% RMSE of the image mean, and no pixel off by more
    // than 10% outside a 2-pixel band around shadow boundaries.
    assert!(h.rmse_rel <= MAX_RMSE, "hybrid RMSE {:.4}", h.rmse_rel);
    assert!(
        h.max_rel_outside_band <= 0.10,
        "hybrid max {:.4}",
        h.max_rel_outside_band
    );

    let b = render(&gpu, &cache, &camera, &light, &medium(), &scene, brute(512));
    println!(
        "brute force 512 steps: RMSE {:.4} of mean, march {:.3} ms",
        b.rmse_rel,
        b.frame.time_ms("march")
    );
    volshadow_harness::metric::accuracy(
        "sphere shadow, 128², brute force at 512 steps",
        format!("RMSE {:.3}%", 100.0 * b.rmse_rel),
        "RMSE 1%",
    );
    // Issue 3: brute force at 512 steps within 1% RMSE.
    assert!(b.rmse_rel <= 0.01, "brute-force RMSE {:.4}", b.rmse_rel);

    // The test can tell a missing shadow: the unshadowed reference, scored like the GPU image,
    // fails both bounds by a wide margin.
    let ref_occ = scene.reference_occluders();
    let shadowed = reference::inscatter_image(
        &camera,
        SIZE,
        SIZE,
        |o, d| scene.distance(o, d),
        &medium(),
        &light,
        &ref_occ,
    );
    let unshadowed = reference::inscatter_image(
        &camera,
        SIZE,
        SIZE,
        |o, d| scene.distance(o, d),
        &medium(),
        &light,
        &[],
    );
    let (mut sq, mut sum, mut max_rel) = (0.0, 0.0, 0.0_f64);
    for (u, s) in unshadowed.iter().zip(&shadowed) {
        sq += (u.x - s.x).powi(2);
        sum += s.x;
        max_rel = max_rel.max((u.x - s.x).abs() / s.x);
    }
    let rmse = (sq / shadowed.len() as f64).sqrt() / (sum / shadowed.len() as f64);
    println!("without the occluder: RMSE {rmse:.4} of mean, max relative {max_rel:.3}");
    assert!(
        rmse > 0.02 && max_rel > 0.10,
        "the occluder barely changes the image"
    );
}

#[test]
fn hybrid_is_cheaper_and_at_least_as_accurate_as_brute_force_at_equal_steps() {
    let gpu = volshadow_harness::gpu_timed();
    let cache = volshadow_harness::cache(&gpu);
    let camera = look_at(Vec3::new(0.0, 1.2, 5.0), Vec3::new(0.0, 0.9, 0.0));
    let light = point_light(Vec3::new(0.4, 4.2, -0.3));
    let scene = sphere_scene();
    for steps in [16, 64] {
        let h = render(
            &gpu,
            &cache,
            &camera,
            &light,
            &medium(),
            &scene,
            hybrid(steps),
        );
        let b = render(
            &gpu,
            &cache,
            &camera,
            &light,
            &medium(),
            &scene,
            brute(steps),
        );
        let (hs, bs): (u64, u64) = (
            h.frame.steps.iter().map(|&s| u64::from(s)).sum(),
            b.frame.steps.iter().map(|&s| u64::from(s)).sum(),
        );
        println!(
            "{steps} steps: hybrid RMSE {:.4}, {hs} steps, march {:.3} ms | brute force RMSE {:.4}, {bs} steps, march {:.3} ms",
            h.rmse_rel, h.frame.time_ms("march"), b.rmse_rel, b.frame.time_ms("march")
        );
        volshadow_harness::metric::accuracy(
            &format!("hybrid against brute force at {steps} steps"),
            format!(
                "RMSE {:.3}% against {:.3}%; {hs} against {bs} steps",
                100.0 * h.rmse_rel,
                100.0 * b.rmse_rel
            ),
            "hybrid RMSE ≤ 1.02 × brute force's, fewer steps",
        );
        // Same step count per marched interval, but the hybrid's interval is only the shadow
        // volume: finer steps there, so at least as accurate (2% slack for noise in the metric)…
        assert!(
            h.rmse_rel <= b.rmse_rel * 1.02,
            "hybrid {:.4} vs brute {:.4}",
            h.rmse_rel,
            b.rmse_rel
        );
        // …and it executes fewer steps in total (the deterministic measure of its cost; GPU
        // times are printed above and compared in the error-vs-time report, not asserted).
        assert!(hs < bs, "hybrid {hs} steps vs brute force {bs}");
    }
}

#[test]
fn bisection_locates_shadow_edges_between_steps() {
    // Brute force at 16 steps puts a shadow edge anywhere within a step; 4 bisections place it
    // to 1/16 of a step. The visibility error should shrink accordingly (measured at 128x128
    // on lavapipe: RMSE 0.57% without, 0.14% with): we ask for at least a third less,
    // and for the steps the bisections executed to be counted.
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let camera = look_at(Vec3::new(0.0, 1.2, 5.0), Vec3::new(0.0, 0.9, 0.0));
    let light = point_light(Vec3::new(0.4, 4.2, -0.3));
    let scene = sphere_scene();
    let run = |bisections| {
        render(
            &gpu,
            &cache,
            &camera,
            &light,
            &medium(),
            &scene,
            MarchSettings {
                bisections,
                ..brute(16)
            },
        )
    };
    let (plain, refined) = (run(0), run(4));
    let steps = |m: &Metrics| -> u64 { m.frame.steps.iter().map(|&s| u64::from(s)).sum() };
    println!(
        "brute force 16: RMSE {:.4} ({} steps) without bisection, {:.4} ({} steps) with 4",
        plain.rmse_rel,
        steps(&plain),
        refined.rmse_rel,
        steps(&refined)
    );
    volshadow_harness::metric::accuracy(
        "brute force at 16 steps without / with 4 bisections locating shadow edges",
        format!(
            "RMSE {:.3}% / {:.3}%",
            100.0 * plain.rmse_rel,
            100.0 * refined.rmse_rel
        ),
        "with < 0.67 × without",
    );
    assert!(
        refined.rmse_rel < 0.67 * plain.rmse_rel,
        "bisection: RMSE {:.4} vs {:.4} without",
        refined.rmse_rel,
        plain.rmse_rel
    );
    assert!(steps(&refined) > steps(&plain));
}

#[test]
fn pixels_without_extents_execute_no_steps() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let camera = look_at(Vec3::new(0.0, 1.2, 5.0), Vec3::new(0.0, 0.9, 0.0));
    let light = point_light(Vec3::new(0.4, 4.2, -0.3));
    let m = render(
        &gpu,
        &cache,
        &camera,
        &light,
        &medium(),
        &sphere_scene(),
        hybrid(32),
    );
    let total = (SIZE * SIZE) as usize;
    let without: Vec<usize> = (0..total).filter(|&i| !m.frame.has_extents(i)).collect();
    let stepped_without = without.iter().filter(|&&i| m.frame.steps[i] != 0).count();
    let with_steps = (0..total)
        .filter(|&i| m.frame.has_extents(i) && m.frame.steps[i] > 0)
        .count();
    println!("{} of {total} pixels cross no extents; {stepped_without} of them stepped; {with_steps} pixels marched", without.len());
    assert!(
        without.len() > total / 4,
        "the scene should leave most rays outside the volume"
    );
    assert!(with_steps > 100, "some rays must cross the volume");
    assert_eq!(
        stepped_without, 0,
        "pixels without extents executed march steps"
    );
}

/// Renders `scene` with the hybrid at 64 steps and checks it against the reference with the
/// sphere scene's bounds (issue 3: RMSE ≤ 2% of the mean, ≤ 10% per pixel outside the
/// boundary band), and that the scene's shadow is big enough for the check to notice if it
/// were missing (the unshadowed reference breaks the per-pixel bound).
fn check_no_missing_shadow(name: &str, camera: &Camera, light: &Light, scene: &Scene) {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let m = render(&gpu, &cache, camera, light, &medium(), scene, hybrid(64));
    let ref_occ = scene.reference_occluders();
    let shadowed = reference::inscatter_image(
        camera,
        SIZE,
        SIZE,
        |o, d| scene.distance(o, d),
        &medium(),
        light,
        &ref_occ,
    );
    let unshadowed = reference::inscatter_image(
        camera,
        SIZE,
        SIZE,
        |o, d| scene.distance(o, d),
        &medium(),
        light,
        &[],
    );
    let near = near_light(camera, light);
    let max_ref = (0..shadowed.len())
        .filter(|&i| !near[i])
        .map(|i| shadowed[i].x)
        .fold(0.0, f64::max);
    let missing = (0..shadowed.len())
        .filter(|&i| !near[i] && shadowed[i].x > 0.01 * max_ref)
        .map(|i| (unshadowed[i].x - shadowed[i].x) / shadowed[i].x)
        .fold(0.0, f64::max);
    println!(
        "{name}: RMSE {:.4} of mean, max rel outside band {:.4}; without occluders max rel {missing:.3}",
        m.rmse_rel, m.max_rel_outside_band
    );
    assert!(
        missing > 0.10,
        "{name}: the shadow is too faint to test ({missing:.3})"
    );
    volshadow_harness::metric::accuracy(
        &format!("{name}: hybrid at 64 steps, RMSE; max outside 2 px of shadow edges"),
        format!(
            "RMSE {:.3}%, max {:.2}%",
            100.0 * m.rmse_rel,
            100.0 * m.max_rel_outside_band
        ),
        "RMSE 2%, max 10%",
    );
    assert!(m.rmse_rel <= MAX_RMSE, "{name}: RMSE {:.4}", m.rmse_rel);
    assert!(
        m.max_rel_outside_band <= 0.10,
        "{name}: max {:.4}",
        m.max_rel_outside_band
    );
}

#[test]
fn eye_inside_the_shadow_volume() {
    // The eye sits in the sphere's shadow, below it, looking along the ground.
    let scene = sphere_scene();
    let light = point_light(Vec3::new(0.4, 4.2, -0.3));
    let camera = look_at(Vec3::new(0.05, 0.9, 0.1), Vec3::new(2.0, 0.6, 3.0));
    let eye_in_shadow = scene.reference_occluders()[0].segment_blocked(
        camera.eye().as_dvec3(),
        light.position().unwrap().as_dvec3(),
    );
    assert!(eye_in_shadow, "the eye must be inside the shadow volume");
    check_no_missing_shadow("eye inside", &camera, &light, &scene);
}

#[test]
fn volume_cut_by_the_near_plane() {
    // A camera with a far near plane (1.2) right next to the shadow shaft: the caller's
    // projection clips the volume's front, the extents must still cover it. The occluder is
    // not in the caller's depth (nothing may lie nearer than the near plane there).
    let mut scene = sphere_scene();
    scene.spheres.clear();
    let camera = Camera::new(
        glam::camera::rh::view::look_at_mat4(
            Vec3::new(-0.6, 1.5, 0.5),
            Vec3::new(1.5, 0.8, -1.0),
            Vec3::Y,
        ),
        glam::camera::rh::proj::directx::perspective(70f32.to_radians(), 1.0, 1.2, 100.0),
    )
    .unwrap();
    check_no_missing_shadow(
        "near plane cut",
        &camera,
        &point_light(Vec3::new(0.4, 4.2, -0.3)),
        &scene,
    );
}

#[test]
fn light_behind_the_camera() {
    // The occluder between the camera and the scene, the light behind the camera; the
    // occluder is left out of the caller's depth so the whole shaft is seen through it.
    let center = Vec3::new(0.0, 2.0, 2.0);
    let scene = Scene {
        spheres: vec![],
        occluders: vec![(
            shapes::uv_sphere(center, 0.6, 24, 12).unwrap(),
            Mat4::IDENTITY,
        )],
    };
    let camera = look_at(Vec3::new(0.0, 2.3, 4.0), Vec3::new(0.0, 1.5, 0.0));
    check_no_missing_shadow(
        "light behind",
        &camera,
        &point_light(Vec3::new(0.2, 2.8, 5.2)),
        &scene,
    );
}

#[test]
fn two_overlapping_occluders() {
    let a = Vec3::new(-0.35, 2.0, 0.0);
    let b = Vec3::new(0.35, 2.3, 0.2);
    let scene = Scene {
        spheres: vec![(a.as_dvec3(), 0.5), (b.as_dvec3(), 0.45)],
        occluders: vec![
            (
                shapes::uv_sphere(Vec3::ZERO, 0.5, 20, 10).unwrap(),
                Mat4::from_translation(a),
            ),
            (
                shapes::uv_sphere(Vec3::ZERO, 0.45, 20, 10).unwrap(),
                Mat4::from_translation(b),
            ),
        ],
    };
    let camera = look_at(Vec3::new(0.0, 1.2, 5.0), Vec3::new(0.0, 1.2, 0.0));
    check_no_missing_shadow(
        "overlapping",
        &camera,
        &point_light(Vec3::new(0.1, 4.0, -0.2)),
        &scene,
    );
}

#[test]
fn torus_with_light_through_its_hole() {
    // A horizontal torus under the light: light passes through the hole as a lit column
    // inside a dark tube.
    let center = Vec3::new(0.0, 2.2, 0.0);
    let scene = Scene {
        spheres: vec![],
        occluders: vec![(
            shapes::torus(center, 0.7, 0.25, 24, 12).unwrap(),
            Mat4::IDENTITY,
        )],
    };
    let camera = look_at(Vec3::new(0.0, 1.4, 4.5), Vec3::new(0.0, 1.3, 0.0));
    check_no_missing_shadow(
        "torus",
        &camera,
        &point_light(Vec3::new(0.0, 3.6, 0.0)),
        &scene,
    );
}

#[test]
fn open_mesh_cylinder_without_caps() {
    // An open tube lying on its side: boundary edges are extruded conservatively.
    let scene = Scene {
        spheres: vec![],
        occluders: vec![(
            shapes::cylinder_open(Vec3::ZERO, 0.4, 0.8, 24).unwrap(),
            Mat4::from_translation(Vec3::new(0.0, 2.0, 0.0)) * Mat4::from_rotation_z(1.2),
        )],
    };
    let camera = look_at(Vec3::new(0.0, 1.2, 5.0), Vec3::new(0.0, 1.2, 0.0));
    check_no_missing_shadow(
        "open cylinder",
        &camera,
        &point_light(Vec3::new(0.2, 3.8, -0.3)),
        &scene,
    );
}

#[test]
fn spot_light_with_a_2d_shadow_map() {
    // A spot light pointing down at a sphere, seen from the side: rays that miss the cone get
    // exactly nothing from it; the rest match the reference (cone and shadow both exact there).
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let spot = SpotLight::new(
        Vec3::new(0.2, 4.0, 0.0),
        Vec3::new(-0.1, -1.0, 0.05),
        50f32.to_radians(),
        Vec3::splat(60.0),
    )
    .unwrap();
    let light = Light::from(spot);
    let scene = sphere_scene();
    let camera = look_at(Vec3::new(0.0, 1.6, 5.5), Vec3::new(0.0, 1.5, 0.0));
    let m = render(&gpu, &cache, &camera, &light, &medium(), &scene, hybrid(64));
    let unlit = reference::inscatter_image(
        &camera,
        SIZE,
        SIZE,
        |o, d| scene.distance(o, d),
        &medium(),
        &light,
        &[],
    );
    let outside: Vec<usize> = (0..unlit.len())
        .filter(|&i| unlit[i].max_element() == 0.0)
        .collect();
    let lit_outside = outside
        .iter()
        .filter(|&&i| m.frame.inscatter[i][0..3].iter().any(|&v| v != 0.0))
        .count();
    println!(
        "spot: {} pixels miss the cone, {lit_outside} of them received light; RMSE {:.4}, max rel outside band {:.4}",
        outside.len(), m.rmse_rel, m.max_rel_outside_band
    );
    assert!(
        outside.len() > 1000,
        "the view should include rays that miss the cone"
    );
    volshadow_harness::metric::accuracy(
        "spot light: rays outside the cone that received light; RMSE",
        format!(
            "{lit_outside} of {}; RMSE {:.3}%",
            outside.len(),
            100.0 * m.rmse_rel
        ),
        "0; RMSE 2%",
    );
    assert_eq!(lit_outside, 0, "rays outside the cone received light");
    assert!(m.rmse_rel <= MAX_RMSE, "spot RMSE {:.4}", m.rmse_rel);
}

#[test]
fn sphere_at_quarter_resolution_with_bilateral_upsampling() {
    let gpu = volshadow_harness::gpu_timed();
    let cache = volshadow_harness::cache(&gpu);
    let camera = look_at(Vec3::new(0.0, 1.2, 5.0), Vec3::new(0.0, 0.9, 0.0));
    let light = point_light(Vec3::new(0.4, 4.2, -0.3));
    let scene = sphere_scene();
    let full = render(&gpu, &cache, &camera, &light, &medium(), &scene, hybrid(64));
    let filters = [
        ("3x3 depth-aware", UpsampleFilter::DepthAware3x3),
        (
            "separable 7-tap",
            UpsampleFilter::Separable {
                taps: 7,
                sigma_spatial: 1.0,
                sigma_depth: 0.05,
            },
        ),
    ];
    for (name, filter) in filters {
        let settings = MarchSettings {
            scale: Scale::Quarter,
            ..hybrid(64)
        };
        let q = render_upsampled(
            &gpu,
            &cache,
            &camera,
            &light,
            &medium(),
            &scene,
            settings,
            filter,
        );
        let (full_steps, quarter_steps): (u64, u64) = (
            full.frame.steps.iter().map(|&s| u64::from(s)).sum(),
            q.frame.steps.iter().map(|&s| u64::from(s)).sum(),
        );
        println!(
            "1/4 resolution + {name}: RMSE {:.4} of mean; march {:.3} ms vs full {:.3} ms; {quarter_steps} vs {full_steps} steps",
            q.rmse_rel, q.frame.time_ms("march"), full.frame.time_ms("march")
        );
        volshadow_harness::metric::accuracy(
            &format!("sphere at ¼ resolution + {name} upsample"),
            format!("RMSE {:.3}%", 100.0 * q.rmse_rel),
            "RMSE 3%",
        );
        // Issue 4: RMSE ≤ 3% of the mean against the reference at 1/4 resolution.
        assert!(q.rmse_rel <= 0.03, "{name}: RMSE {:.4}", q.rmse_rel);
        // A sixteenth of the pixels march: the work is at most an eighth of full resolution
        // (GPU times are in the printout and the report, not asserted in a test).
        assert!(
            quarter_steps * 8 <= full_steps,
            "{quarter_steps} steps vs {full_steps}"
        );
    }
}

/// p95 relative error of the sphere scene's in-scatter against the reference, for a shadow
/// map of `resolution`², over pixels whose reference is above 1% of the maximum.
fn p95_with_shadow_resolution(
    gpu: &HeadlessGpu,
    cache: &Cache,
    camera: &Camera,
    light: &Light,
    scene: &Scene,
    reference_image: &[DVec3],
    resolution: u32,
) -> f64 {
    let depths: Vec<f32> = (0..SIZE * SIZE)
        .map(|i| {
            let (o, d) = volshadow_harness::pixel_ray(camera, SIZE, SIZE, i % SIZE, i / SIZE);
            let ds = scene.distance(o, d);
            if ds.is_finite() {
                volshadow_harness::ndc_depth(camera, o + ds * d)
            } else {
                camera.far_depth()
            }
        })
        .collect();
    let depth = volshadow_harness::depth_texture(gpu, SIZE, SIZE, &depths);
    let meshes: Vec<OccluderMesh> = scene
        .occluders
        .iter()
        .map(|(m, _)| OccluderMesh::new(&gpu.device, m))
        .collect();
    let occluders: Vec<Occluder> = meshes
        .iter()
        .zip(&scene.occluders)
        .map(|(mesh, (_, transform))| Occluder {
            mesh,
            transform: *transform,
        })
        .collect();
    let medium = medium();
    let passes = ShadowPasses::new(camera, light, &medium, &depth, &occluders)
        .settings(hybrid(64))
        .shadow_resolution(resolution);
    let frame = volshadow_harness::shadow_frame(gpu, cache, &passes);
    let near = near_light(camera, light);
    let max = reference_image
        .iter()
        .enumerate()
        .filter(|(i, _)| !near[*i])
        .map(|(_, r)| r.max_element())
        .fold(0.0, f64::max);
    let mut errors: Vec<f64> = Vec::new();
    for (i, r) in reference_image.iter().enumerate() {
        if near[i] {
            continue;
        }
        for c in 0..3 {
            if r[c] > 0.01 * max {
                errors.push((f64::from(frame.inscatter[i][c]) - r[c]).abs() / r[c]);
            }
        }
    }
    errors.sort_by(f64::total_cmp);
    errors[errors.len() * 95 / 100]
}

/// The smallest shadow map accepted ([`ShadowMapSettings::MIN_RESOLUTION`]) is where the
/// sphere scene's p95 error stays within 2%, the error the hybrid march at 64 steps is held
/// to elsewhere in this file; smaller maps are rejected.
#[test]
fn shadow_map_minimum_resolution_is_where_the_p95_error_stays_within_two_percent() {
    use volshadow::nodes::{ShadowMapNode, ShadowMapSettings};
    let gpu = volshadow_harness::gpu_timed();
    let cache = volshadow_harness::cache(&gpu);
    let camera = look_at(Vec3::new(0.0, 1.2, 5.0), Vec3::new(0.0, 0.9, 0.0));
    let light = point_light(Vec3::new(0.4, 4.2, -0.3));
    let scene = sphere_scene();
    let reference_image = reference::inscatter_image(
        &camera,
        SIZE,
        SIZE,
        |o, d| scene.distance(o, d),
        &medium(),
        &light,
        &scene.reference_occluders(),
    );
    let min = ShadowMapSettings::MIN_RESOLUTION;
    // Sizes below the minimum are rejected; with the minimum lowered to 2 the same scene
    // measured p95 22% at 2², 7.8% at 8², 3.8% at 16².
    for resolution in [min, 2 * min, 1024] {
        let p95 = p95_with_shadow_resolution(
            &gpu,
            &cache,
            &camera,
            &light,
            &scene,
            &reference_image,
            resolution,
        );
        println!("shadow map {resolution}²: p95 relative error {p95:.4}");
        if resolution == min {
            volshadow_harness::metric::accuracy(
                &format!("the smallest shadow map ({resolution}²), sphere scene"),
                format!("p95 {:.3}%", 100.0 * p95),
                "p95 2%",
            );
            assert!(p95 <= MAX_RMSE, "{resolution}: p95 {p95:.4}");
        }
    }
    for resolution in [1, min - 1] {
        let err = ShadowMapNode::new(
            &gpu.device,
            &cache,
            ShadowMapSettings {
                resolution,
                ..Default::default()
            },
        )
        .err();
        assert!(
            matches!(err, Some(volshadow::Error::InvalidSize { .. })),
            "{resolution}: {err:?}"
        );
    }
}

/// A small sphere right below the light, and a 20 km flat occluder out of sight below the
/// ground: the shadow map's near plane must follow the sphere, not the size of the scene (it
/// was floored at 1e-4 of the largest occluder, 2.8 m here, and the sphere's shadow vanished).
#[test]
fn a_terrain_sized_occluder_does_not_cost_a_small_one_its_shadow() {
    let gpu = volshadow_harness::gpu_timed();
    let cache = volshadow_harness::cache(&gpu);
    let camera = look_at(Vec3::new(0.0, 1.2, 5.0), Vec3::new(0.0, 1.5, 0.0));
    let light_pos = Vec3::new(0.4, 4.2, -0.3);
    let light = point_light(light_pos);
    let small = light_pos - Vec3::new(0.0, 0.35, 0.0);
    let sphere = (
        shapes::uv_sphere(small, 0.08, 24, 12).unwrap(),
        Mat4::IDENTITY,
    );
    let terrain = (
        shapes::plane(Vec3::new(0.0, -0.5, 0.0), glam::Vec2::splat(10_000.0)).unwrap(),
        Mat4::IDENTITY,
    );
    let scene = |occluders: Vec<(Mesh, Mat4)>| Scene {
        spheres: vec![(small.as_dvec3(), 0.08)],
        occluders,
    };
    let alone = render(
        &gpu,
        &cache,
        &camera,
        &light,
        &medium(),
        &scene(vec![sphere.clone()]),
        hybrid(64),
    );
    let with_terrain = render(
        &gpu,
        &cache,
        &camera,
        &light,
        &medium(),
        &scene(vec![sphere, terrain]),
        hybrid(64),
    );
    println!(
        "small sphere near the light: RMSE {:.4} alone, {:.4} with a 20 km occluder below the \
         ground; max outside the band {:.4} / {:.4}",
        alone.rmse_rel,
        with_terrain.rmse_rel,
        alone.max_rel_outside_band,
        with_terrain.max_rel_outside_band
    );
    volshadow_harness::metric::accuracy(
        "small sphere near the light, alone / with a 20 km occluder below the ground: hybrid RMSE",
        format!(
            "{:.3}% / {:.3}%",
            100.0 * alone.rmse_rel,
            100.0 * with_terrain.rmse_rel
        ),
        "RMSE 2%, max outside edges 10%",
    );
    // Issue 3's bounds for the hybrid at 64 steps, with or without the far-away occluder.
    for m in [&alone, &with_terrain] {
        assert!(m.rmse_rel <= MAX_RMSE, "RMSE {:.4}", m.rmse_rel);
        assert!(
            m.max_rel_outside_band <= 0.10,
            "max {:.4}",
            m.max_rel_outside_band
        );
    }
}
