//! The exact method (closed form between the sorted shadow-volume crossings of each ray) and
//! the fix it grew from: a piece of a ray that crosses no shadow-volume face is never assumed
//! lit. Every case is measured against the f64 reference with exact visibility.
//!
//! Thresholds: exact mode p95 ≤ 0.5% and RMSE ≤ 0.5% of the mean (its boundaries come from
//! geometry, so what is left is the F′ table's and f32's error, measured at ≤ 0.1%); the hybrid
//! at its defaults RMSE ≤ 2% (it still takes shadow edges from the shadow map). Each scene is
//! checked to be one where ignoring the shadow the eye stands in fails the same bars.

use volshadow_harness::rng;

use glam::{Mat4, Vec3};
use volshadow::nodes::{MarchMethod, MarchSettings};
use volshadow::reference::TexturedSpot;
use volshadow::scene::{shapes, LightTexture};
use volshadow::{
    Cache, Camera, HeadlessGpu, Light, Medium, PhaseFunction, PointLight, ShaderPrecision,
    SpotLight,
};
use volshadow_harness::scene::{Errors, MeshScene, SceneMesh, Shot};

const SIZE: u32 = 64;
/// Exact mode: p95 and RMSE bounds of the issue (0.5%).
const EXACT_P95: f64 = 0.005;
const EXACT_RMSE: f64 = 0.005;
/// The hybrid at its defaults.
const HYBRID_RMSE: f64 = 0.02;
/// Scene (c) is stiff fog: its optical depth σt·D from the eye to the light is at least this.
const STIFF_OPTICAL_DEPTH: f64 = 30.0;

fn exact() -> MarchSettings {
    MarchSettings {
        method: MarchMethod::Exact,
        ..MarchSettings::default()
    }
}

fn hybrid() -> MarchSettings {
    MarchSettings {
        method: MarchMethod::Hybrid,
        ..MarchSettings::default()
    }
}

fn haze() -> Medium {
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

fn look_at(eye: Vec3, target: Vec3, fov: f32) -> Camera {
    volshadow_harness::look_at(eye, target, fov, 1.0)
}

fn eye_in_shadow(scene: &MeshScene, camera: &Camera, light: &Light) -> bool {
    scene.reference_occluders().iter().any(|o| {
        o.segment_blocked(
            camera.eye().as_dvec3(),
            light.position().unwrap().as_dvec3(),
        )
    })
}

/// Renders `shot` with the exact method, the hybrid and without occluders, prints the three
/// errors, and checks the bars. Returns the exact method's measurement.
fn check(
    name: &str,
    gpu: &HeadlessGpu,
    cache: &Cache,
    shot: &Shot<'_>,
) -> volshadow_harness::scene::Measured {
    check_with(name, gpu, cache, shot, Some(HYBRID_RMSE))
}

/// [`check`] with the hybrid's RMSE bound (`None`: only printed).
fn check_with(
    name: &str,
    gpu: &HeadlessGpu,
    cache: &Cache,
    shot: &Shot<'_>,
    hybrid_rmse: Option<f64>,
) -> volshadow_harness::scene::Measured {
    let reference = shot.reference();
    let m = shot.measure(gpu, cache, exact(), &reference);
    let hybrid = shot.measure(gpu, cache, hybrid(), &reference);
    let unshadowed_scene = MeshScene {
        occluders: Vec::new(),
        ..shot.scene.clone()
    };
    // The occluders stay in the depth buffer; only their shadows are left out: what a march
    // that assumes the eye's piece of every ray lit gives on rays that never leave the shadow.
    let lit = Shot {
        scene: &unshadowed_scene,
        ..*shot
    };
    let lit = lit.measure(gpu, cache, exact(), &reference);
    println!(
        "{name}: exact {}\n  hybrid {}\n  shadows ignored {}\n  crossings: {:?}",
        m.errors, hybrid.errors, lit.errors, m.frame.stats
    );
    volshadow_harness::metric::accuracy(
        &format!("{name}: exact method against the reference, {SIZE}²"),
        m.errors.short(),
        "p95 0.5%, RMSE 0.5%",
    );
    volshadow_harness::metric::accuracy(
        &format!("{name}: hybrid at its defaults"),
        format!("RMSE {:.3}%", 100.0 * hybrid.errors.rmse),
        hybrid_rmse.map_or("none (characterised)".into(), |b| {
            format!("RMSE {}%", 100.0 * b)
        }),
    );
    volshadow_harness::metric::accuracy(
        &format!("{name}: shadows ignored (must fail)"),
        lit.errors.short(),
        "p95 > 0.5% and RMSE > 2%",
    );
    assert_bars(name, &m.errors, &hybrid.errors, hybrid_rmse);
    assert!(
        lit.errors.p95 > EXACT_P95 && lit.errors.rmse > HYBRID_RMSE,
        "{name}: the scene does not test shadows: ignoring them gives {}",
        lit.errors
    );
    m
}

fn assert_bars(name: &str, exact: &Errors, hybrid: &Errors, hybrid_rmse: Option<f64>) {
    assert_eq!(
        exact.non_finite, 0,
        "{name}: NaN, Inf or negative in-scatter"
    );
    assert_eq!(
        hybrid.non_finite, 0,
        "{name}: NaN, Inf or negative (hybrid)"
    );
    assert!(
        exact.counted > 100,
        "{name}: too few bright pixels to measure"
    );
    assert!(exact.p95 <= EXACT_P95, "{name}: exact p95 {exact}");
    assert!(exact.rmse <= EXACT_RMSE, "{name}: exact RMSE {exact}");
    if let Some(bound) = hybrid_rmse {
        assert!(hybrid.rmse <= bound, "{name}: hybrid RMSE {hybrid}");
    }
}

#[test]
fn a_camera_in_the_shade_of_a_wide_roof() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    // A porch: a wide roof on two pillars. The pillars' shadow volumes lie inside the roof's,
    // so rays from the eye enter a pillar's volume (a front face) before they leave the roof's:
    // the piece before that face is in the roof's shadow, not lit.
    let mut scene = MeshScene {
        ground: Some(0.0),
        ..Default::default()
    };
    scene
        .add(shapes::cuboid(Vec3::new(0.0, 3.0, 0.0), Vec3::new(3.0, 0.05, 3.0)).unwrap())
        .add(shapes::cuboid(Vec3::new(2.2, 1.45, -0.6), Vec3::new(0.12, 1.45, 0.12)).unwrap())
        .add(shapes::cuboid(Vec3::new(2.2, 1.45, 1.6), Vec3::new(0.12, 1.45, 0.12)).unwrap());
    let light = point_light(Vec3::new(1.0, 7.0, 0.5));
    // Under the roof, looking along its shadow and out of it.
    let camera = look_at(Vec3::new(0.5, 1.2, 0.8), Vec3::new(6.0, 0.9, -1.0), 70.0);
    assert!(eye_in_shadow(&scene, &camera, &light));
    check(
        "roof",
        &gpu,
        &cache,
        &Shot::new(&scene, &camera, &light, &haze(), SIZE),
    );
}

#[test]
fn b_eye_inside_two_overlapping_volumes() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    // The eye is in the shadows of two stacked boards; most rays leave one and stay in the
    // other. A third board's volume starts beside the eye, so many rays enter it (a front
    // face) before leaving the first two.
    let mut scene = MeshScene {
        ground: Some(0.0),
        ..Default::default()
    };
    scene
        .add(shapes::cuboid(Vec3::new(-0.3, 2.5, 0.0), Vec3::new(0.9, 0.1, 1.0)).unwrap())
        .add(shapes::cuboid(Vec3::new(0.2, 3.2, 0.3), Vec3::new(0.8, 0.1, 0.9)).unwrap())
        .add(shapes::cuboid(Vec3::new(1.4, 2.5, 0.6), Vec3::new(0.6, 0.1, 0.6)).unwrap());
    let light = point_light(Vec3::new(0.1, 6.0, 0.0));
    let camera = look_at(Vec3::new(0.1, 1.0, 0.0), Vec3::new(3.0, 0.7, 2.0), 70.0);
    let occ = scene.reference_occluders();
    let (e, l) = (
        camera.eye().as_dvec3(),
        light.position().unwrap().as_dvec3(),
    );
    assert!(
        occ[0].segment_blocked(e, l)
            && occ[1].segment_blocked(e, l)
            && !occ[2].segment_blocked(e, l),
        "the eye must be in the first two shadows only"
    );
    check(
        "two volumes",
        &gpu,
        &cache,
        &Shot::new(&scene, &camera, &light, &haze(), SIZE),
    );
}

#[test]
fn c_thick_fog_light_behind_eye_in_shadow_near_the_edge() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let mut scene = MeshScene {
        ground: Some(0.0),
        ..Default::default()
    };
    // The box's edge x = 0 and the light (x = 0) put the shadow's side on the plane x = 0;
    // the eye stands 0.05 inside it.
    scene.add(shapes::cuboid(Vec3::new(-0.5, 1.0, 5.0), Vec3::new(0.5, 0.5, 0.1)).unwrap());
    let light = point_light(Vec3::new(0.0, 1.0, 10.0));
    let medium = Medium::new(
        Vec3::new(1.0, 1.1, 1.2),
        Vec3::splat(2.2),
        PhaseFunction::HenyeyGreenstein { g: 0.7 },
    )
    .unwrap();
    let camera = look_at(Vec3::new(-0.05, 1.0, 0.0), Vec3::new(0.6, 0.8, -5.0), 60.0);
    let optical_depth = f64::from(medium.sigma_t().min_element())
        * f64::from(light.position().unwrap().distance(camera.eye()));
    assert!(
        optical_depth >= STIFF_OPTICAL_DEPTH,
        "σt·D = {optical_depth}"
    );
    assert!(eye_in_shadow(&scene, &camera, &light));
    let shot = Shot::new(&scene, &camera, &light, &medium, SIZE);
    // The hybrid and brute force take the shadow's edge from the 1024² shadow map; here the
    // in-scatter comes from within 1/σt of the eye, where a texel's shift along these grazing
    // rays is a large error whatever the step count. That is what the exact method fixes, so
    // the two are only required to be clearly worse than it.
    let m = check_with("thick fog", &gpu, &cache, &shot, None);
    let brute = shot.measure(
        &gpu,
        &cache,
        MarchSettings {
            method: MarchMethod::BruteForce,
            steps: 512,
            ..MarchSettings::default()
        },
        &m.reference,
    );
    println!("  brute force 512 steps {}", brute.errors);
    volshadow_harness::metric::accuracy(
        "thick fog: brute force at 512 steps (shadow map's edges)",
        brute.errors.short(),
        "p95 > 10 × the exact method's",
    );
    assert!(
        brute.errors.p95 > 10.0 * m.errors.p95,
        "the shadow map's edge should limit brute force here: {}",
        brute.errors
    );
}

/// A blind of `slats` thin slats between the light and the camera.
fn blind(slats: u32) -> MeshScene {
    let mut scene = MeshScene {
        ground: Some(0.0),
        ..Default::default()
    };
    for i in 0..slats {
        scene.add(
            shapes::cuboid(
                Vec3::new(0.0, 0.9 + 0.22 * i as f32, 0.0),
                Vec3::new(1.4, 0.015, 0.1),
            )
            .unwrap(),
        );
    }
    scene
}

#[test]
fn d_blind_of_slats_exact_and_overflowing() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let scene = blind(12);
    let light = point_light(Vec3::new(0.2, 4.5, -3.0));
    let camera = look_at(Vec3::new(0.4, 1.3, 3.5), Vec3::new(0.0, 1.9, -1.0), 60.0);
    let medium = haze();
    let shot = Shot::new(&scene, &camera, &light, &medium, SIZE);
    let m = check("blind", &gpu, &cache, &shot);
    assert_eq!(
        m.frame.stats.overflowed, 0,
        "the default list must hold the blind's crossings"
    );
    assert!(
        m.frame.stats.max_crossings >= 8,
        "the blind should give many crossings per ray: {:?}",
        m.frame.stats
    );
    // Lists of 4 overflow; those pixels are marched as the hybrid does.
    let small = shot.measure(
        &gpu,
        &cache,
        MarchSettings {
            crossings: 4,
            ..exact()
        },
        &m.reference,
    );
    println!("  4 per pixel: {} {:?}", small.errors, small.frame.stats);
    volshadow_harness::metric::accuracy(
        "blind, lists of 4 crossings: overflowing pixels marched",
        format!(
            "{} pixels overflowed, RMSE {:.3}%",
            small.frame.stats.overflowed,
            100.0 * small.errors.rmse
        ),
        "over 100 pixels overflow; RMSE 2%",
    );
    assert!(
        small.frame.stats.overflowed > 100,
        "lists of 4 must overflow: {:?}",
        small.frame.stats
    );
    assert_eq!(small.errors.non_finite, 0);
    assert!(
        small.errors.rmse <= HYBRID_RMSE,
        "overflow: {}",
        small.errors
    );
}

#[test]
fn e_volume_cut_by_the_near_plane() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    // A camera with a far near plane (1.2) right next to the shaft: the caller's projection
    // clips the volume's front. The occluder is not in the caller's depth.
    let mut scene = MeshScene {
        ground: Some(0.0),
        ..Default::default()
    };
    scene.occluders.push(SceneMesh {
        mesh: shapes::uv_sphere(Vec3::new(0.0, 2.0, 0.0), 0.6, 24, 12).unwrap(),
        transform: Mat4::IDENTITY,
        visible: false,
    });
    let camera = Camera::new(
        glam::camera::rh::view::look_at_mat4(
            Vec3::new(-0.6, 1.5, 0.5),
            Vec3::new(1.5, 0.8, -1.0),
            Vec3::Y,
        ),
        glam::camera::rh::proj::directx::perspective(70f32.to_radians(), 1.0, 1.2, 100.0),
    )
    .unwrap();
    let light = point_light(Vec3::new(0.4, 4.2, -0.3));
    check(
        "near plane",
        &gpu,
        &cache,
        &Shot::new(&scene, &camera, &light, &haze(), SIZE),
    );
}

/// The eye on a shadow-volume face: a box lit from straight above casts a volume whose side
/// faces are the planes through the light and the top face's edges; the eye stands on one of
/// them (`2x + y/2 = 2.25`, inside the face's extent), half in the shaft it looks across. The
/// volumes around the eye are counted from the far end, so a face through the eye is counted
/// for every pixel alike, whichever side f32 puts the eye. Counting from the eye instead (the
/// eye in no volume) fails: p95 1617% (lavapipe, 2026-12-02).
#[test]
fn h_eye_on_a_shadow_volume_face() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let mut scene = MeshScene {
        ground: Some(0.0),
        ..Default::default()
    };
    scene.occluders.push(SceneMesh {
        mesh: shapes::cuboid(Vec3::new(0.0, 2.0, 0.0), Vec3::splat(0.5)).unwrap(),
        transform: Mat4::IDENTITY,
        visible: true,
    });
    // The face through the light (0, 4.5, 0) and the edge x = 0.5, y = 2.5: at y = 1 it spans
    // |z| ≤ 0.875, at x = 0.875.
    let eye = Vec3::new(0.875, 1.0, 0.3);
    let camera = look_at(eye, Vec3::new(-1.5, 0.7, -0.4), 70.0);
    let light = point_light(Vec3::new(0.0, 4.5, 0.0));
    check(
        "eye on a face",
        &gpu,
        &cache,
        &Shot::new(&scene, &camera, &light, &haze(), SIZE),
    );
}

/// An octahedron of radius 1.5 centred on (0, 2, 0) under a light at (0, 5.5, 0), both in the
/// plane x = 0, seen from (0, 3.5, 4) straight along −z in an image of odd width: the middle
/// column's rays lie exactly in x = 0 (f32 gives exact zeros there), so each meets, exactly on
/// an edge, the front cap's two faces that share the edge from the top vertex to (0, 2, 1.5),
/// and the two side faces extruded from the silhouette edges that share the vertex
/// (0, 2, 1.5); the centre pixel's ray meets the top vertex, shared by four faces. Exactly one
/// face of each pair should count such a crossing (the crossing build's tie rule): counting
/// neither puts every interval behind the edge in too few volumes. The octahedron is left
/// out of the depth buffer so that the rays go on through its shadow to the ground. Checked
/// over the whole image against the exact method's bars (the shadow is in it: ignored, it
/// fails them; its RMSE over the whole image stays below the other scenes' 2% bar, so this
/// scene is not held to that one), and over the middle column alone (the pixels the
/// image metric keeps, away from the light): its largest error within the exact method's p95
/// bar (0.5%). A tie rule under which neither face of a pair owns its edge fails there: 24.6%
/// (lavapipe, 2026-12-02); one under which both own it counts the entry and the exit twice
/// here, which leaves every count's sign as it is, and passes.
#[test]
fn i_rays_through_shared_edges_and_a_vertex() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let r = 1.5;
    let c = Vec3::new(0.0, 2.0, 0.0);
    let positions: Vec<Vec3> = [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z]
        .iter()
        .map(|&d| c + r * d)
        .collect();
    // Wound counter-clockwise seen from outside.
    let indices = [
        4, 0, 2, 0, 5, 2, 5, 1, 2, 1, 4, 2, 0, 4, 3, 5, 0, 3, 1, 5, 3, 4, 1, 3,
    ];
    let mut scene = MeshScene {
        ground: Some(0.0),
        ..Default::default()
    };
    scene.occluders.push(SceneMesh {
        mesh: volshadow::scene::Mesh::new(&positions, &indices).unwrap(),
        transform: Mat4::IDENTITY,
        visible: false,
    });
    let size = SIZE - 1;
    let camera = look_at(Vec3::new(0.0, 3.5, 4.0), Vec3::new(0.0, 3.5, 0.0), 50.0);
    let light = point_light(Vec3::new(0.0, 5.5, 0.0));
    let medium = haze();
    let shot = Shot::new(&scene, &camera, &light, &medium, size);
    let reference = shot.reference();
    let m = shot.measure(&gpu, &cache, exact(), &reference);
    let unshadowed_scene = MeshScene {
        occluders: Vec::new(),
        ..scene.clone()
    };
    let lit = Shot {
        scene: &unshadowed_scene,
        ..shot
    };
    let lit = lit.measure(&gpu, &cache, exact(), &reference);
    println!(
        "rays through edges and a vertex: exact {}\n  shadows ignored {}",
        m.errors, lit.errors
    );
    volshadow_harness::metric::accuracy(
        &format!("rays through edges and a vertex: exact method against the reference, {size}²"),
        m.errors.short(),
        "p95 0.5%, RMSE 0.5%",
    );
    assert!(
        m.errors.p95 <= EXACT_P95 && m.errors.rmse <= EXACT_RMSE && m.errors.non_finite == 0,
        "rays through edges and a vertex: {}",
        m.errors
    );
    // The octahedron's shadow is in the image: without it the same bar fails.
    assert!(
        lit.errors.p95 > EXACT_P95,
        "no shadow to test: {}",
        lit.errors
    );
    let middle = size / 2;
    // The pixels the image metric keeps (not those right around the light).
    let keep =
        volshadow::reference::ImageError::keep_away_from_lights(&camera, &[light], size, size);
    let column: Vec<(u32, f64, f64)> = (0..size)
        .filter(|y| keep[(y * size + middle) as usize])
        .map(|y| {
            let i = (y * size + middle) as usize;
            let g = m.frame.inscatter[i];
            let gpu = glam::DVec3::new(g[0].into(), g[1].into(), g[2].into());
            let reference = m.reference[i];
            (
                y,
                (gpu - reference).abs().max_element(),
                reference.max_element(),
            )
        })
        .collect();
    let brightest = column.iter().map(|c| c.2).fold(0.0, f64::max);
    let (row, worst) = column
        .iter()
        .filter(|c| c.2 > 0.01 * brightest)
        .map(|c| (c.0, c.1 / c.2))
        .fold((0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
    volshadow_harness::metric::accuracy(
        "rays through edges and a vertex: the middle column's largest error",
        format!("{:.3}% (row {row})", 100.0 * worst),
        "0.5%",
    );
    assert!(
        worst <= EXACT_P95,
        "the middle column, whose rays meet the volume's edges exactly: {:.2}% at row {row}",
        100.0 * worst
    );
}

#[test]
fn f_textured_spot_eye_in_its_occluders_shadow() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let spot = SpotLight::new(
        Vec3::new(0.3, 4.0, -0.2),
        Vec3::new(-0.1, -1.0, 0.05),
        70f32.to_radians(),
        Vec3::splat(60.0),
    )
    .unwrap();
    // A smooth texture: this case is about visibility, not the texture's detail.
    let n = 16;
    let texels = (0..n * n)
        .map(|i| {
            let (u, v) = ((i % n) as f32 / n as f32, (i / n) as f32 / n as f32);
            Vec3::new(0.4 + 0.6 * u, 0.5 + 0.5 * v, 1.0 - 0.5 * u * v)
        })
        .collect();
    let texture = LightTexture::new(n, n, texels).unwrap();
    let uploaded = texture.upload(&gpu.device, &gpu.queue);
    let textured = TexturedSpot {
        spot,
        texture: &texture,
    };
    let mut scene = MeshScene {
        ground: Some(0.0),
        ..Default::default()
    };
    scene.add(shapes::uv_sphere(Vec3::new(0.0, 2.6, 0.0), 0.7, 24, 12).unwrap());
    let light = Light::from(spot);
    let camera = look_at(Vec3::new(-0.1, 1.0, 0.1), Vec3::new(2.5, 0.6, 2.5), 70.0);
    assert!(eye_in_shadow(&scene, &camera, &light));
    let medium = haze();
    let shot = Shot {
        texture: Some((&uploaded, &textured)),
        ..Shot::new(&scene, &camera, &light, &medium, SIZE)
    };
    check("textured spot", &gpu, &cache, &shot);
}

/// One scene chosen by the seed: 1–4 occluders (boxes turned any way, spheres, a torus) over
/// an optional ground, a point or spot light, an eye that is often inside a shadow or looking
/// at the light, a camera whose near plane may cut the volumes (standard or reversed infinite
/// depth), optical depth σt·D from 1e-3 to 50, any phase, and the whole scene scaled by
/// 1e-2 … 1e5 (up to 1e5: at that scale a cone test sensitive to rounding cuts a spot's cone
/// wrong for rays nearly parallel to its surface, as seed 204 of `tests/gpu/soft_grid.rs` shows).
struct SeededMeshScene {
    scene: MeshScene,
    camera: Camera,
    light: Light,
    medium: Medium,
    size: u32,
    summary: String,
}

/// What a seeded scene may be held to: the optical depth σt·D's range (log10), whether the
/// light must be a spot, and a factor on its intensity.
#[derive(Clone, Copy)]
struct Regime {
    log_tau: (f32, f32),
    spot: bool,
    brighter: f32,
}

/// The regime of `g_random_scenes_against_the_reference`.
fn any_regime() -> Regime {
    Regime {
        log_tau: (-3.0, 50f32.log10()),
        spot: false,
        brighter: 1.0,
    }
}

fn random_scene(seed: u64) -> SeededMeshScene {
    random_scene_in(seed, any_regime())
}

fn random_scene_in(seed: u64, regime: Regime) -> SeededMeshScene {
    let mut rng = fastrand::Rng::with_seed(seed);
    let mut uniform = |a: f32, b: f32| a + (b - a) * rng.f32();
    let scale = 10f32.powf(uniform(-2.0, 5.0));
    let ground = uniform(0.0, 1.0) < 0.7;
    let mut scene = MeshScene {
        ground: ground.then_some(0.0),
        ..Default::default()
    };
    let count = 1 + (uniform(0.0, 4.0) as usize).min(3);
    let mut centers = Vec::new();
    for k in 0..count {
        let c = Vec3::new(uniform(-2.0, 2.0), uniform(0.6, 3.0), uniform(-2.0, 2.0));
        let kind = (uniform(0.0, 3.0) as u32).min(2);
        let (mesh, radius) = match kind {
            0 => {
                let h = Vec3::new(uniform(0.05, 1.0), uniform(0.03, 0.6), uniform(0.05, 1.0));
                (shapes::cuboid(Vec3::ZERO, h).unwrap(), h.length())
            }
            1 => {
                let r = uniform(0.15, 0.8);
                (shapes::uv_sphere(Vec3::ZERO, r, 16, 8).unwrap(), r)
            }
            _ => {
                let major = uniform(0.3, 0.8);
                (
                    shapes::torus(Vec3::ZERO, major, major * uniform(0.2, 0.5), 16, 8).unwrap(),
                    major * 1.5,
                )
            }
        };
        let axis = Vec3::new(uniform(-1.0, 1.0), uniform(-1.0, 1.0), uniform(-1.0, 1.0))
            .try_normalize()
            .unwrap_or(Vec3::Y);
        let rotation = glam::Quat::from_axis_angle(axis, uniform(0.0, std::f32::consts::TAU));
        scene.occluders.push(SceneMesh {
            mesh,
            transform: Mat4::from_scale_rotation_translation(
                Vec3::splat(scale),
                rotation,
                c * scale,
            ),
            // Now and then an occluder the camera does not see (its shadow only).
            visible: k > 0 || uniform(0.0, 1.0) < 0.85,
        });
        centers.push((c, radius));
    }
    let clear = |p: Vec3, margin: f32| centers.iter().all(|&(c, r)| p.distance(c) > r + margin);
    let mut light_pos;
    loop {
        light_pos = Vec3::new(uniform(-3.5, 3.5), uniform(1.5, 6.0), uniform(-3.5, 3.5));
        if clear(light_pos, 0.3) {
            break;
        }
    }
    // The eye: behind an occluder as seen from the light (in its shadow) half the time.
    let mut eye;
    loop {
        eye = if uniform(0.0, 1.0) < 0.5 {
            let (c, _) = centers[(uniform(0.0, count as f32) as usize).min(count - 1)];
            light_pos
                + (c - light_pos) * uniform(1.2, 2.5)
                + Vec3::new(uniform(-0.3, 0.3), uniform(-0.3, 0.3), uniform(-0.3, 0.3))
        } else {
            Vec3::new(uniform(-4.0, 4.0), uniform(0.2, 3.5), uniform(-4.0, 4.0))
        };
        if (!ground || eye.y > 0.05) && clear(eye, 0.05) && eye.distance(light_pos) > 0.3 {
            break;
        }
    }
    let target = match (uniform(0.0, 3.0) as u32).min(2) {
        0 => light_pos,
        1 => centers[0].0,
        _ => eye + Vec3::new(uniform(-1.0, 1.0), uniform(-0.7, 0.5), uniform(-1.0, 1.0)),
    };
    let target = if target.distance(eye) < 1e-3 {
        eye + Vec3::X
    } else {
        target
    };
    let up = if (target - eye).normalize().y.abs() > 0.99 {
        Vec3::X
    } else {
        Vec3::Y
    };
    let fov = uniform(40.0, 90.0).to_radians();
    // The near plane may cut the volumes: up to a quarter of the way to the light.
    let near = eye.distance(light_pos) * 10f32.powf(uniform(-3.0, -0.6)) * scale;
    let view = glam::camera::rh::view::look_at_mat4(eye * scale, target * scale, up);
    let reversed = uniform(0.0, 1.0) < 0.3;
    let proj = if reversed {
        glam::camera::rh::proj::directx::perspective_infinite_reverse(fov, 1.0, near)
    } else {
        glam::camera::rh::proj::directx::perspective(fov, 1.0, near, 1e3 * scale)
    };
    let camera = Camera::new(view, proj).unwrap();
    let spot = uniform(0.0, 1.0) < 0.2 || regime.spot;
    let intensity = Vec3::new(uniform(5.0, 40.0), uniform(5.0, 40.0), uniform(5.0, 40.0))
        * scale
        * scale
        * regime.brighter;
    let light: Light = if spot {
        let dir = (centers[0].0 - light_pos).normalize();
        SpotLight::new(
            light_pos * scale,
            dir,
            uniform(30.0, 120.0).to_radians(),
            intensity,
        )
        .unwrap()
        .into()
    } else {
        PointLight::new(light_pos * scale, intensity)
            .unwrap()
            .into()
    };
    let tau = 10f32.powf(uniform(regime.log_tau.0, regime.log_tau.1));
    let sigma_t = tau / (eye.distance(light_pos) * scale);
    let albedo = uniform(0.2, 1.0);
    let phase = match (uniform(0.0, 3.0) as u32).min(2) {
        0 => PhaseFunction::Isotropic,
        1 => PhaseFunction::HenyeyGreenstein {
            g: uniform(-0.9, 0.9),
        },
        _ => PhaseFunction::Rayleigh,
    };
    let medium = Medium::new(
        Vec3::new(1.0, 0.9, 0.8) * albedo * sigma_t,
        Vec3::new(0.0, 0.1, 0.2) * albedo * sigma_t + Vec3::splat((1.0 - albedo) * sigma_t),
        phase,
    )
    .unwrap();
    let size = 24 + 8 * (uniform(0.0, 2.0) as u32).min(1);
    SeededMeshScene {
        summary: format!(
            "{count} occluder(s), scale {scale:.1e}, σt·D {tau:.1e}, {phase:?}, {}, near {near:.1e}{}, {size}²",
            if spot { "spot" } else { "point" },
            if reversed { " (reversed, infinite)" } else { "" }
        ),
        scene,
        camera,
        light,
        medium,
        size,
    }
}

volshadow_harness::at_each_precision!(
    random_scenes_at => g_random_scenes_against_the_reference,
    g_random_scenes_against_the_reference_worst_case,
    [volshadow_harness::WORST_CASE]
);

/// Random scenes nobody chose, exact mode against the reference: every scene p95 ≤ 1% (the
/// issue's bar for this test: half the hand-picked cases' margin, for scenes at 24² whose
/// percentile rests on few pixels), and nothing non-finite. The depth buffer and the
/// reference come from the same ray cast, so no pixel's first surface differs between them.
/// The `_worst_case` test: the same with every transcendental built-in off by the most WGSL
/// allows.
fn random_scenes_at(precision: ShaderPrecision) {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache_with(&gpu, precision);
    let mut results = Vec::new();
    for seed in rng::seeds(0..200) {
        let s = random_scene(seed);
        let shot = Shot::new(&s.scene, &s.camera, &s.light, &s.medium, s.size);
        let reference = shot.reference();
        let m = shot.measure(&gpu, &cache, exact(), &reference);
        if std::env::var("VOLSHADOW_SEED").is_ok() {
            println!(
                "seed {seed}: {}\n  {}\n  {:?}",
                s.summary, m.errors, m.frame.stats
            );
            let h = shot.measure(&gpu, &cache, hybrid(), &reference);
            println!("  hybrid: {}", h.errors);
            let bare = MeshScene {
                occluders: Vec::new(),
                ..s.scene.clone()
            };
            let lit = Shot::new(&bare, &s.camera, &s.light, &s.medium, s.size);
            let lit_ref = lit.reference();
            println!(
                "  no occluders: {}",
                lit.measure(&gpu, &cache, exact(), &lit_ref).errors
            );
            let w = m.errors.worst;
            println!(
                "  worst pixel {w}: gpu {:?} reference {:?}",
                m.frame.inscatter[w], reference[w]
            );
        }
        results.push((seed, m.errors, s.summary, m.frame.stats));
    }
    let mut p95: Vec<f64> = results.iter().map(|r| r.1.p95).collect();
    p95.sort_by(f64::total_cmp);
    let worst = results
        .iter()
        .max_by(|a, b| a.1.p95.total_cmp(&b.1.p95))
        .unwrap();
    let overflowed = results.iter().filter(|r| r.3.overflowed > 0).count();
    println!(
        "{precision:?}: {} random scenes: median p95 {:.4}%, worst p95 {:.4}% at seed {} ({}: {}); {} scenes had overflowing pixels",
        results.len(),
        100.0 * p95[p95.len() / 2],
        100.0 * worst.1.p95,
        worst.0,
        worst.2,
        worst.1,
        overflowed
    );
    volshadow_harness::metric::accuracy(
        &format!(
            "{precision:?}: {} seeded random exact scenes, 24²–32²",
            results.len()
        ),
        format!(
            "median p95 {:.4}%, worst p95 {:.3}% (seed {}); {overflowed} with overflowing pixels",
            100.0 * p95[p95.len() / 2],
            100.0 * worst.1.p95,
            worst.0
        ),
        "every scene p95 1%",
    );
    let failed: Vec<String> = results
        .iter()
        .filter(|r| r.1.p95 > 0.01 || r.1.non_finite > 0)
        .map(|r| format!("seed {} ({}): {}", r.0, r.2, r.1))
        .collect();
    assert!(
        failed.is_empty(),
        "{precision:?}: {} scene(s) over p95 1% or non-finite; rerun one with VOLSHADOW_SEED=<seed>:\n{}",
        failed.len(),
        failed.join("\n")
    );
}

/// Exact mode at ½ and ¼ resolution with the existing upsample filters, eye in a shadow:
/// the bound is the reduced-resolution one of the hybrid's tests (RMSE ≤ 3% of the mean),
/// and at ½ the 3×3 filter must stay within 1% (measured 0.1–0.3%).
#[test]
fn reduced_resolution_with_the_upsample_filters() {
    use volshadow::nodes::{Scale, UpsampleFilter};
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let mut scene = MeshScene {
        ground: Some(0.0),
        ..Default::default()
    };
    scene.add(shapes::uv_sphere(Vec3::new(0.0, 2.0, 0.0), 0.6, 24, 12).unwrap());
    let light = point_light(Vec3::new(0.4, 4.2, -0.3));
    let camera = look_at(Vec3::new(0.05, 0.9, 0.1), Vec3::new(2.0, 0.6, 3.0), 60.0);
    assert!(eye_in_shadow(&scene, &camera, &light));
    let medium = haze();
    let base = Shot::new(&scene, &camera, &light, &medium, 128);
    let reference = base.reference();
    let separable = UpsampleFilter::Separable {
        taps: 7,
        sigma_spatial: 1.5,
        sigma_depth: 0.05,
    };
    for (scale, filter, bound) in [
        (Scale::Half, UpsampleFilter::DepthAware3x3, 0.01),
        (Scale::Half, separable, 0.03),
        (Scale::Quarter, UpsampleFilter::DepthAware3x3, 0.03),
        (Scale::Quarter, separable, 0.03),
    ] {
        let shot = Shot {
            filter,
            ..Shot::new(&scene, &camera, &light, &medium, 128)
        };
        let m = shot.measure(&gpu, &cache, MarchSettings { scale, ..exact() }, &reference);
        println!(
            "exact at 1/{} with {filter:?}: {}",
            scale.divisor(),
            m.errors
        );
        volshadow_harness::metric::accuracy(
            &format!("exact at 1/{} with {filter:?}, 128²", scale.divisor()),
            format!("RMSE {:.3}%", 100.0 * m.errors.rmse),
            format!("RMSE {}%", 100.0 * bound),
        );
        assert_eq!(m.errors.non_finite, 0);
        assert!(
            m.errors.rmse <= bound,
            "1/{}: {}",
            scale.divisor(),
            m.errors
        );
    }
}

/// Intersecting occluders with a low light (a cow's leg pushed into its body, the light just
/// behind it): rays start in one shadow volume and enter the other before leaving the first.
/// The hybrid lit the piece before the nearest front face there (10% of the pixels wrong in a
/// render of the cow scene before the fix).
#[test]
fn intersecting_occluders_with_a_low_light() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let mut scene = MeshScene {
        ground: Some(0.0),
        ..Default::default()
    };
    scene.occluders.push(SceneMesh {
        mesh: shapes::uv_sphere(Vec3::ZERO, 1.0, 48, 24).unwrap(),
        transform: Mat4::from_scale_rotation_translation(
            Vec3::new(1.4, 0.75, 0.7),
            glam::Quat::IDENTITY,
            Vec3::new(0.0, 1.5, 0.0),
        ),
        visible: true,
    });
    scene.add(shapes::cuboid(Vec3::new(0.85, 0.5, 0.38), Vec3::new(0.14, 0.5, 0.14)).unwrap());
    let light = point_light(Vec3::new(0.5, 1.9, -2.8));
    let camera = look_at(Vec3::new(-1.0, 2.2, 9.0), Vec3::new(0.3, 1.2, 0.0), 45.0);
    let medium = Medium::new(
        Vec3::splat(0.1),
        Vec3::splat(0.005),
        PhaseFunction::HenyeyGreenstein { g: 0.6 },
    )
    .unwrap();
    check(
        "intersecting occluders",
        &gpu,
        &cache,
        &Shot::new(&scene, &camera, &light, &medium, SIZE),
    );
}

volshadow_harness::at_each_precision!(
    thick_fog_spot_scenes_at => thick_fog_spot_scenes_against_the_reference,
    thick_fog_spot_scenes_against_the_reference_worst_case,
    [volshadow_harness::WORST_CASE]
);

/// The reference's brightest value.
fn brightest(reference: &[glam::DVec3]) -> f64 {
    reference
        .iter()
        .map(|r| r.max_element())
        .fold(0.0, f64::max)
}

/// Seeded spot-light scenes in thick fog, σt·D from 10 to 100 (the generator of
/// `g_random_scenes_against_the_reference` otherwise, the light 1e15 times as bright so that
/// the in-scatter, which falls as e^{−σt·D}, stays within f32's normal range, and brighter
/// still where it would not: at 1e15, seed 146's brightest in-scatter is 9e-39, subnormal,
/// which an NVIDIA H200 flushed to 0, p95 100%, as WGSL allows), exact method
/// against the reference: all finite, at least 198 of 200 within p95 1% (the random scenes'
/// bar) and every one within p95 2%. Those two are measured limits (199 within, the other p95
/// 1.04%). With the table's rows in γ mixed linearly (see `table_row_mix`), 198 are within and
/// the others at 2.4% and 11.8%, views with 11 and 15 pixels lit above 1% of their brightest,
/// whose light comes from far beyond the integrand's peak, where T is nearly exponential in γ.
/// The integrand along a ray peaks sharply there, and a spot's cone can leave the peak outside:
/// the table keeps the tails (`AirlightTableNode`) because an interval beyond the peak taken as
/// the difference of two heads T(s) that both hold it puts 13 of these 200 over 1%, the worst
/// at p95 100% (seed 95 of the random scenes, at σt·D 81 brightened, off by up to 106%).
/// The `_worst_case` test: the same with every transcendental built-in off by the most WGSL
/// allows.
fn thick_fog_spot_scenes_at(precision: ShaderPrecision) {
    const BRIGHTER: f32 = 1e15;
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache_with(&gpu, precision);
    let regime = |brighter| Regime {
        log_tau: (1.0, 2.0),
        spot: true,
        brighter,
    };
    let (mut within, mut worst) = (0, 0.0_f64);
    let mut failed = Vec::new();
    for seed in 0..200 {
        let mut s = random_scene_in(seed, regime(BRIGHTER));
        let mut reference = Shot::new(&s.scene, &s.camera, &s.light, &s.medium, s.size).reference();
        // The same scene (brightness draws no random number) with the light brighter still,
        // where its whole answer would lie below f32's normal range: a GPU may flush that to
        // zero (WGSL allows it; NVIDIA's do), so no f32 renderer could show it.
        let scale = brightest(&reference);
        if scale > 0.0 && scale < 1e-30 {
            let more = (1e-20 / scale).min(1e37 / s.light.intensity().max_element() as f64) as f32;
            s = random_scene_in(seed, regime(BRIGHTER * more));
            reference = Shot::new(&s.scene, &s.camera, &s.light, &s.medium, s.size).reference();
            println!(
                "seed {seed}: brightest in-scatter {scale:.1e} at 1e15, the light {more:.1e} times brighter still: {:.1e}",
                brightest(&reference)
            );
        }
        let shot = Shot::new(&s.scene, &s.camera, &s.light, &s.medium, s.size);
        let e = shot.measure(&gpu, &cache, exact(), &reference).errors;
        worst = worst.max(e.p95);
        if e.p95 <= 0.01 {
            within += 1;
        } else {
            println!("{precision:?}: seed {seed} ({}): {e}", s.summary);
        }
        if e.non_finite > 0 || e.p95 > 0.02 {
            failed.push(format!("seed {seed} ({}): {e}", s.summary));
        }
    }
    println!(
        "{precision:?}: 200 thick-fog spot scenes: {within} within p95 1%, worst p95 {:.3}%",
        100.0 * worst
    );
    volshadow_harness::metric::accuracy(
        &format!("{precision:?}: 200 seeded spot lights in thick fog (σt·D 10–100)"),
        format!("{within} within p95 1%, worst p95 {:.3}%", 100.0 * worst),
        "at least 198 within p95 1%, all within 2% (measured limits)",
    );
    assert!(
        failed.is_empty(),
        "over p95 2% or non-finite:\n{}",
        failed.join("\n")
    );
    assert!(
        within >= 198,
        "{within} of 200 within p95 1%, fewer than 198"
    );
}
