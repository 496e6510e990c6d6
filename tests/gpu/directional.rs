//! Directional lights (sun shafts) on the GPU, against the f64 reference
//! (`volshadow::reference::inscatter_directional`, its own quadrature with exact visibility).
//!
//! * the closed-form airlight on unshadowed rays, sky and surface pixels, σt from 0 to 100 per
//!   scene size, four phase functions: ≤ 1e-4 relative, no NaN or Inf;
//! * the window scene (sun through a window frame into a dusty room), exact mode at 128²:
//!   p95 ≤ 1% and RMSE ≤ 0.5% of the mean;
//! * shimmer: a camera moving by sub-texel steps over 16 frames changes the in-scatter of
//!   pixels away from shadow edges by ≤ 0.5% between consecutive frames.

use volshadow::nodes::{Encode, Node};

use glam::{DVec3, Vec3};
use volshadow::nodes::{
    AirlightTableNode, MarchInputs, MarchMethod, MarchNode, MarchSettings, ShadowMapNode, TableSize,
};
use volshadow::reference;
use volshadow::scene::shapes;
use volshadow::{Cache, Camera, DirectionalLight, HeadlessGpu, Light, Medium, PhaseFunction};
use volshadow_harness::scene::{MeshScene, Shot};

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
                mode: volshadow::nodes::MarchMode::Analytic,
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
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let camera = camera(Vec3::new(0.0, 2.0, 8.0), Vec3::new(0.0, 1.0, 0.0), 70.0);
    let light = sun();
    // Half the image sees the floor (surface pixels out to the horizon), half the sky.
    let mut depths = Vec::new();
    let mut rays = Vec::new();
    for i in 0..SMALL * SMALL {
        let (o, d) = volshadow_harness::pixel_ray(&camera, SMALL, SMALL, i % SMALL, i / SMALL);
        let ds = floor_distance(o, d);
        depths.push(if ds.is_finite() {
            volshadow_harness::ndc_depth(&camera, o + ds * d)
        } else {
            camera.far_depth()
        });
        rays.push((o, d, ds));
    }
    let sky = rays.iter().filter(|r| r.2.is_infinite()).count();
    assert!(sky > 0 && sky < rays.len(), "{sky} sky pixels");
    let depth = volshadow_harness::depth_texture(&gpu, SMALL, SMALL, &depths);
    let phases = [
        ("isotropic", PhaseFunction::Isotropic),
        ("HG +0.9", PhaseFunction::HenyeyGreenstein { g: 0.9 }),
        ("HG -0.9", PhaseFunction::HenyeyGreenstein { g: -0.9 }),
        ("Rayleigh", PhaseFunction::Rayleigh),
    ];
    let (mut worst_overall, mut non_finite_overall) = (0.0f64, 0);
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
            non_finite_overall += non_finite;
            assert_eq!(non_finite, 0, "{name}, sigma_t = {per_size:e}/size");
            assert!(
                worst <= CLOSED_FORM_TOLERANCE,
                "{name}, sigma_t = {per_size:e}/size: relative error {worst:e} at pixel {worst_at}"
            );
            worst_overall = worst_overall.max(worst);
        }
    }
    eprintln!("closed form: worst relative error over every case {worst_overall:.2e}");
    volshadow_harness::metric::accuracy(
        &format!("closed-form airlight, unshadowed sky and floor rays, {SMALL}², σt 0…100 per scene size, 4 phases: worst channel"),
        format!("max {worst_overall:.1e}; {non_finite_overall} non-finite"),
        format!("{CLOSED_FORM_TOLERANCE:.0e} (the issue's); 0"),
    );

    // The bar tells the stable form from the naive one: at σt = 1e-6 per scene size, over a
    // surface 10 units away, (1 − e^{−σt x})/σt in f32 is off by far more than 1e-4.
    let (sigma, x) = (1e-6 / SCENE_SIZE, 10.0f32);
    let exact = -(-f64::from(sigma) * f64::from(x)).exp_m1() / f64::from(sigma);
    let naive = relative(naive_f32(sigma, x), exact);
    eprintln!("naive f32 closed form at sigma_t = 1e-6/size, x = 10: relative error {naive:.2e}");
    volshadow_harness::metric::accuracy(
        "the naive f32 closed form (1 − e^(−σt·x))/σt at σt = 1e-6 per scene size, x = 10 (must fail)",
        format!("{naive:.1e}"),
        format!("> {CLOSED_FORM_TOLERANCE:.0e}"),
    );
    assert!(naive > CLOSED_FORM_TOLERANCE, "naive form error {naive:e}");
}

/// The window scene's bars (the issue's): exact mode at 128².
const WINDOW_SIZE: u32 = 128;
const WINDOW_P95: f64 = 0.01;
const WINDOW_RMSE: f64 = 0.005;
/// The shimmer bar: largest change between consecutive frames, pixels away from edges.
const SHIMMER: f64 = 0.005;
/// Map-based marching (brute force at 1024 steps with 4 bisections) on the same frames: the
/// change beyond the reference's. Measured 1.6% with texel snapping (the residual is the
/// fixed staircase of texels the moving rays cross) and 4.0% without it (the staircase moves
/// with the camera): the bound lies between, so removing the snapping fails it.
const SHIMMER_MAP: f64 = 0.025;
/// The shimmer test's shadow distance (the room in view is about 12 units deep).
const SHIMMER_DISTANCE: f32 = 14.0;

/// A dusty room lit by the sun through a window with a cross-shaped frame: a wall at z = 0
/// (40 × 20, 0.3 thick) with a 3 × 3 opening from y = 2 to 5, cut into four panes by two
/// bars; the floor y = 0 receives but casts no shadow. The sun shines in from z < 0.
fn window_room() -> (MeshScene, DirectionalLight, Medium) {
    let mut scene = MeshScene {
        ground: Some(0.0),
        ..Default::default()
    };
    let wall = |lo: Vec3, hi: Vec3| shapes::cuboid(0.5 * (lo + hi), 0.5 * (hi - lo)).unwrap();
    let (t0, t1) = (-0.15, 0.15);
    scene
        .add(wall(Vec3::new(-20.0, 0.0, t0), Vec3::new(-1.5, 20.0, t1)))
        .add(wall(Vec3::new(1.5, 0.0, t0), Vec3::new(20.0, 20.0, t1)))
        .add(wall(Vec3::new(-1.5, 0.0, t0), Vec3::new(1.5, 2.0, t1)))
        .add(wall(Vec3::new(-1.5, 5.0, t0), Vec3::new(1.5, 20.0, t1)))
        .add(wall(Vec3::new(-0.08, 2.0, t0), Vec3::new(0.08, 5.0, t1)))
        .add(wall(Vec3::new(-1.5, 3.42, t0), Vec3::new(1.5, 3.58, t1)));
    let sun = DirectionalLight::new(Vec3::new(0.35, -0.55, 1.0), Vec3::new(4.0, 3.6, 3.0)).unwrap();
    let dust = Medium::new(
        Vec3::splat(0.12),
        Vec3::splat(0.02),
        PhaseFunction::HenyeyGreenstein { g: 0.5 },
    )
    .unwrap();
    (scene, sun, dust)
}

/// Inside the room, looking across the shafts towards the window.
fn window_camera(offset: Vec3) -> Camera {
    let eye = Vec3::new(-3.5, 1.7, 8.0) + offset;
    camera(eye, Vec3::new(0.8, 1.6, 2.0) + offset, 60.0)
}

fn exact() -> MarchSettings {
    MarchSettings {
        method: MarchMethod::Exact,
        ..MarchSettings::default()
    }
}

#[test]
fn window_scene_exact_mode_matches_reference() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let (scene, sun, dust) = window_room();
    let camera = window_camera(Vec3::ZERO);
    let light = Light::from(sun);
    let shot = Shot::new(&scene, &camera, &light, &dust, WINDOW_SIZE);
    let started = std::time::Instant::now();
    let reference = shot.reference();
    let reference_s = started.elapsed().as_secs_f64();
    let m = shot.measure(&gpu, &cache, exact(), &reference);
    let hybrid = shot.measure(
        &gpu,
        &cache,
        MarchSettings {
            method: MarchMethod::Hybrid,
            ..MarchSettings::default()
        },
        &reference,
    );
    // The shadows matter: without occluders (the sun everywhere) the error is large.
    let open = MeshScene {
        occluders: Vec::new(),
        ..scene.clone()
    };
    let lit = Shot {
        scene: &open,
        ..shot
    }
    .measure(&gpu, &cache, exact(), &reference);
    eprintln!(
        "window {WINDOW_SIZE}²: exact {}\n  hybrid {}\n  shadows ignored {}\n  crossings {:?}; reference {reference_s:.1} s",
        m.errors, hybrid.errors, lit.errors, m.frame.stats
    );
    volshadow_harness::metric::accuracy(
        &format!(
            "window scene (sun through a window frame), exact, {WINDOW_SIZE}²; occluders ignored (the sun everywhere)"
        ),
        format!(
            "{}, {} pixels counted; ignored {}",
            m.errors.short(),
            m.errors.counted,
            lit.errors.short()
        ),
        format!(
            "p95 {}%, RMSE {}% (the issue's), > 1000 pixels; ignored beyond both",
            100.0 * WINDOW_P95,
            100.0 * WINDOW_RMSE
        ),
    );
    assert_eq!(m.errors.non_finite, 0, "NaN, Inf or negative in-scatter");
    assert!(
        m.errors.counted > 1000,
        "too few bright pixels: {}",
        m.errors
    );
    assert!(m.errors.p95 <= WINDOW_P95, "exact p95: {}", m.errors);
    assert!(m.errors.rmse <= WINDOW_RMSE, "exact RMSE: {}", m.errors);
    assert!(
        lit.errors.p95 > WINDOW_P95 && lit.errors.rmse > WINDOW_RMSE,
        "the scene does not test shadows: {}",
        lit.errors
    );
}

/// Pixels whose in-scatter is within 5% of each of its eight neighbours' and above 1% of the
/// image's 99th percentile: away from the shafts' edges in the image.
fn away_from_edges(image: &[[f32; 4]], size: u32) -> Vec<usize> {
    let value = |i: usize| f64::from(image[i][0].max(image[i][1]).max(image[i][2]));
    let mut sorted: Vec<f64> = (0..image.len()).map(value).collect();
    sorted.sort_by(f64::total_cmp);
    let p99 = sorted[(sorted.len() - 1) * 99 / 100];
    let n = size as i64;
    (0..image.len())
        .filter(|&i| {
            let (x, y) = (i as i64 % n, i as i64 / n);
            let v = value(i);
            v > 0.01 * p99
                && (x > 0 && x < n - 1 && y > 0 && y < n - 1)
                && (-1..=1).all(|dy| {
                    (-1..=1).all(|dx| {
                        let j = ((y + dy) * n + x + dx) as usize;
                        (value(j) - v).abs() <= 0.05 * v
                    })
                })
        })
        .collect()
}

#[test]
fn moving_camera_does_not_make_shafts_shimmer() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let (scene, sun, dust) = window_room();
    // A shadow distance that covers the room in view: texels of about 2 cm.
    let sun = sun.with_shadow_distance(SHIMMER_DISTANCE).unwrap();
    let light = Light::from(sun);
    let size = 96;
    const RESOLUTION: u32 = 1024;
    // The first (finest) cascade's texel for this view (the sphere's size does not change as
    // the camera moves), so that every cascade sees sub-texel steps.
    let splits =
        ShadowMapNode::cascade_splits(&window_camera(Vec3::ZERO), SHIMMER_DISTANCE, sun.cascades());
    let face = ShadowMapNode::directional_matrix(
        &sun,
        &window_camera(Vec3::ZERO),
        (splits[0], splits[1]),
        RESOLUTION,
        f32::INFINITY,
    );
    let texel = 2.0 / face.row(0).truncate().length() / RESOLUTION as f32;
    // 0.37 of a texel per frame, sideways and a little up: every sub-texel phase occurs.
    let step = Vec3::new(0.8, 0.2, -0.3).normalize() * (0.37 * texel);
    // The true change of each frame, from the reference.
    let references: Vec<Vec<DVec3>> = (0..16)
        .map(|k| {
            let camera = window_camera(step * k as f32);
            Shot::new(&scene, &camera, &light, &dust, size).reference()
        })
        .collect();
    // The exact method takes shadow boundaries from geometry (held to the bar); the others
    // take them from the shadow map (printed): brute force at 1024 steps with 4 bisections
    // finely enough that its step error is small, so what changes beyond the reference's
    // change there is the map's staircase of texels that the moving rays cross.
    for (name, method, steps, bisections) in [
        ("exact", MarchMethod::Exact, 64, 0),
        ("hybrid", MarchMethod::Hybrid, 64, 0),
        ("brute force", MarchMethod::BruteForce, 64, 0),
        (
            "brute force 1024 + 4 bisections",
            MarchMethod::BruteForce,
            1024,
            4,
        ),
    ] {
        let settings = MarchSettings {
            method,
            steps,
            bisections,
            ..MarchSettings::default()
        };
        let mut frames = Vec::new();
        for k in 0..16 {
            let camera = window_camera(step * k as f32);
            let shot = Shot {
                shadow_resolution: RESOLUTION,
                ..Shot::new(&scene, &camera, &light, &dust, size)
            };
            frames.push(shot.measure(&gpu, &cache, settings, &[]).frame.inscatter);
        }
        // Per pair of frames: pixels away from edges in both (the image moves by several
        // pixels over the 16 frames).
        let (mut worst, mut true_change, mut spurious) = (0.0f64, 0.0f64, 0.0f64);
        let mut kept = usize::MAX;
        for (k, pair) in frames.windows(2).enumerate() {
            let next = away_from_edges(&pair[1], size);
            let both: Vec<usize> = away_from_edges(&pair[0], size)
                .into_iter()
                .filter(|i| next.contains(i))
                .collect();
            kept = kept.min(both.len());
            for &i in &both {
                for c in 0..3 {
                    let (a, b) = (f64::from(pair[0][i][c]), f64::from(pair[1][i][c]));
                    worst = worst.max((b - a).abs() / a.max(1e-30));
                    let (ra, rb) = (references[k][i][c], references[k + 1][i][c]);
                    true_change = true_change.max((rb - ra).abs() / ra.max(1e-30));
                    spurious = spurious.max(((b - a) - (rb - ra)).abs() / ra.max(1e-30));
                }
            }
        }
        eprintln!(
            "shimmer, {name}: texel {texel:.4}, step {:.4}, {} pixels away from edges, largest change between frames {:.3}% (the reference's {:.3}%; GPU change less the reference's {:.3}%)",
            step.length(),
            kept,
            100.0 * worst,
            100.0 * true_change,
            100.0 * spurious
        );
        if method == MarchMethod::Exact {
            volshadow_harness::metric::accuracy(
                &format!("shimmer: camera moving 0.37 shadow-map texel a frame, {size}², 16 frames, {name}: largest change between frames, pixels away from shadow edges"),
                format!("{:.3}% ({kept} pixels)", 100.0 * worst),
                format!("{}%; > 200 pixels", 100.0 * SHIMMER),
            );
        }
        if steps == 1024 {
            volshadow_harness::metric::accuracy(
                &format!("shimmer, {name}: change between frames beyond the reference's"),
                format!("{:.3}% ({kept} pixels)", 100.0 * spurious),
                format!(
                    "{}% (4.0% without texel snapping); > 200 pixels",
                    100.0 * SHIMMER_MAP
                ),
            );
        }
        assert!(kept > 200, "{name}: too few pixels away from edges");
        if method == MarchMethod::Exact {
            assert!(worst <= SHIMMER, "{name}: in-scatter changes by {worst}");
        }
        if steps == 1024 {
            assert!(
                spurious <= SHIMMER_MAP,
                "{name}: spurious change {spurious}"
            );
        }
    }
}

/// The facade mixes a point light and the sun: the planner builds no F′ table for the sun
/// (and says why), and the sun's in-scatter matches the reference.
#[test]
fn facade_mixes_point_and_directional_lights() {
    use volshadow::plan::{Pass, Reason};
    use volshadow::{Frame, FrameLight, Occluder, OccluderMesh, PointLight, Settings};
    const SIZE: u32 = 48;
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let camera = camera(Vec3::new(0.0, 1.5, 6.0), Vec3::new(0.0, 1.0, 0.0), 60.0);
    let mut rays = Vec::new();
    let depths: Vec<f32> = (0..SIZE * SIZE)
        .map(|i| {
            let (o, d) = volshadow_harness::pixel_ray(&camera, SIZE, SIZE, i % SIZE, i / SIZE);
            let ds = floor_distance(o, d);
            rays.push((o, d, ds));
            if ds.is_finite() {
                volshadow_harness::ndc_depth(&camera, o + ds * d)
            } else {
                camera.far_depth()
            }
        })
        .collect();
    let depth = volshadow_harness::depth_texture(&gpu, SIZE, SIZE, &depths);
    let tex = |format, usage| volshadow_harness::texture(&gpu, format, usage, (SIZE, SIZE, 1), 1);
    let color = tex(
        wgpu::TextureFormat::Rgba32Float,
        wgpu::TextureUsages::TEXTURE_BINDING,
    );
    let output = tex(
        wgpu::TextureFormat::Rgba16Float,
        wgpu::TextureUsages::RENDER_ATTACHMENT,
    );
    // A board above the floor: the sun casts its shadow through the fog.
    let board = shapes::cuboid(Vec3::new(0.0, 2.0, 0.0), Vec3::new(1.0, 0.05, 1.0)).unwrap();
    let mesh = OccluderMesh::new(&gpu.device, &board);
    let occluders = [Occluder {
        mesh: &mesh,
        transform: glam::Mat4::IDENTITY,
    }];
    let sun = DirectionalLight::new(Vec3::new(0.3, -1.0, -0.4), Vec3::new(2.0, 1.8, 1.5)).unwrap();
    let point = PointLight::new(Vec3::new(2.0, 3.0, -2.0), Vec3::splat(20.0)).unwrap();
    let medium = Medium::new(
        Vec3::splat(0.1),
        Vec3::splat(0.02),
        PhaseFunction::HenyeyGreenstein { g: 0.4 },
    )
    .unwrap();
    let lights = [
        FrameLight::from(Light::from(point)),
        FrameLight::from(Light::from(sun)),
    ];
    let frame = Frame {
        camera: &camera,
        lights: &lights,
        medium: &medium,
        occluders: &occluders,
        scene_color: &color,
        scene_depth: &depth,
        surfaces: None,
    };
    for (name, settings) in [
        ("predictable", Settings::PREDICTABLE),
        (
            "CPU adapter's defaults",
            Settings::for_adapter(volshadow::AdapterKind::Cpu),
        ),
    ] {
        let mut vs =
            volshadow::VolumetricShadows::new(&gpu.device, &gpu.queue, &cache, settings).unwrap();
        let plan = vs.prepare(&gpu.device, &gpu.queue, &frame).unwrap().clone();
        eprintln!("{name}:\n{plan}");
        assert!(plan.runs(Pass::AirlightTable, Some(0)));
        assert!(!plan.runs(Pass::AirlightTable, Some(1)));
        assert_eq!(
            plan.skip_reason(Pass::AirlightTable, Some(1)),
            Some(&Reason::ClosedFormAirlight)
        );
        assert!(plan.runs(Pass::ShadowMap, Some(1)));
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        vs.encode(&mut encoder, &output).unwrap();
        gpu.submit_and_wait(encoder).unwrap();
        let image = gpu.read_rgba32f(vs.inscatter(1).unwrap()).unwrap();
        let occ = [reference::Occluder::Mesh(
            reference::TriangleMesh::from_indexed(
                board.positions(),
                board.indices(),
                glam::DMat4::IDENTITY,
            ),
        )];
        let reference: Vec<DVec3> = rays
            .iter()
            .map(|&(o, d, ds)| reference::inscatter_directional(o, d, ds, &medium, &sun, &occ))
            .collect();
        let errors = volshadow_harness::scene::errors(
            &image,
            &reference,
            &camera,
            &Light::from(sun),
            (SIZE, SIZE),
        );
        eprintln!("facade, {name}, the sun's in-scatter: {errors}");
        volshadow_harness::metric::accuracy(
            &format!("facade, a point light and the sun, {SIZE}², {name}: the sun's in-scatter"),
            errors.short(),
            if settings.march.scale == volshadow::nodes::Scale::Full {
                format!("p95 {}% (the window scene's)", 100.0 * WINDOW_P95)
            } else {
                "RMSE 3% (reduced resolution)".to_string()
            },
        );
        assert_eq!(errors.non_finite, 0);
        // Exact at full resolution: the window scene's bar; half resolution (a 24² march)
        // with the 3×3 upsample: the 3% RMSE bound of the reduced-resolution tests.
        if settings.march.scale == volshadow::nodes::Scale::Full {
            assert!(errors.p95 <= WINDOW_P95, "{name}: {errors}");
        } else {
            assert!(errors.rmse <= 0.03, "{name}: {errors}");
        }
    }
    // The board's shadow is in view: the unshadowed in-scatter fails the bar.
    let open: Vec<[f32; 4]> = rays
        .iter()
        .map(|&(o, d, ds)| {
            let v = reference::inscatter_directional(o, d, ds, &medium, &sun, &[]);
            [v.x as f32, v.y as f32, v.z as f32, 0.0]
        })
        .collect();
    let occ = [reference::Occluder::Mesh(
        reference::TriangleMesh::from_indexed(
            board.positions(),
            board.indices(),
            glam::DMat4::IDENTITY,
        ),
    )];
    let shadowed: Vec<DVec3> = rays
        .iter()
        .map(|&(o, d, ds)| reference::inscatter_directional(o, d, ds, &medium, &sun, &occ))
        .collect();
    let ignored = volshadow_harness::scene::errors(
        &open,
        &shadowed,
        &camera,
        &Light::from(sun),
        (SIZE, SIZE),
    );
    eprintln!("facade, the board's shadow ignored: {ignored}");
    volshadow_harness::metric::accuracy(
        &format!("facade, {SIZE}²: the board's shadow ignored (must fail)"),
        ignored.short(),
        format!("p95 > {}%", 100.0 * WINDOW_P95),
    );
    assert!(
        ignored.p95 > WINDOW_P95,
        "the shadow is not in view: {ignored}"
    );
}

/// Scene files: a directional light is read with its fields' names, and bad values name them.
#[test]
fn scene_file_directional_light() {
    use volshadow::scene_file::SceneDescription;
    let window = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/window.json");
    let scene = SceneDescription::load(&window).unwrap();
    match scene.lights[0].light {
        Light::Directional(sun) => {
            assert!((sun.direction().length() - 1.0).abs() < 1e-6);
            assert_eq!(sun.irradiance(), Vec3::new(4.0, 3.6, 3.0));
            assert_eq!(sun.shadow_distance(), None);
        }
        other => panic!("expected a directional light, got {other:?}"),
    }
    let text = std::fs::read_to_string(&window).unwrap();
    let light = r#"{ "type": "directional", "direction": [0.35, -0.55, 1.0], "irradiance": [4.0, 3.6, 3.0] }"#;
    assert!(text.contains(light));
    for (bad, field) in [
        (
            r#""direction": [0.0, 0.0, 0.0], "irradiance": 1.0"#,
            "direction",
        ),
        (
            r#""direction": [0.0, -1.0, 0.0], "irradiance": [0.0, 0.0, 0.0]"#,
            "irradiance",
        ),
        (
            r#""direction": [0.0, -1.0, 0.0], "irradiance": -1.0"#,
            "irradiance",
        ),
        (
            r#""direction": [0.0, -1.0, 0.0], "irradiance": 1.0, "shadow_distance": -2.0"#,
            "shadow_distance",
        ),
    ] {
        let broken = text.replace(light, &format!(r#"{{ "type": "directional", {bad} }}"#));
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("window.json");
        std::fs::write(&path, broken).unwrap();
        let err = SceneDescription::load(&path).unwrap_err().to_string();
        assert!(err.contains(field), "{bad}: {err}");
    }
    let set = DirectionalLight::new(Vec3::NEG_Y, Vec3::ONE)
        .unwrap()
        .with_shadow_distance(12.0)
        .unwrap();
    assert_eq!(set.shadow_distance(), Some(12.0));
    for bad in [0.0, -1.0, f32::NAN, f32::INFINITY] {
        assert!(DirectionalLight::new(Vec3::NEG_Y, Vec3::ONE)
            .unwrap()
            .with_shadow_distance(bad)
            .is_err());
    }
}
