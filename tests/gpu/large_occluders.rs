//! Occluders far larger than their distance to the light or the eye: a roof 1e8 wide three
//! units above a point light. The rasteriser clips a triangle to its frustum in f32, and where
//! the triangle's vertices lie beyond about 2^24 times the depth of the clipped points the
//! clipped polygon loses its place: the shadow map lost the roof (light leaked under it), the
//! hybrid's extents and the rasterised crossing lists lost it from the eye. Every method, and
//! both crossing builds, against the f64 reference of the same scene, at half-sizes 1e2 to 1e10.

use glam::{DVec3, Mat4, Vec2, Vec3};
use volshadow::gpu::{Occluder, OccluderMesh};
use volshadow::nodes::{CrossingsBuild, MarchMethod, MarchSettings};
use volshadow::reference::{self, ImageError, TriangleMesh};
use volshadow::scene::{shapes, Mesh};
use volshadow::{Camera, Light, Medium, PhaseFunction, PointLight, SpotLight};

const N: u32 = 32;
/// The exact method's bar (`tests/gpu/exact.rs`: RMSE 0.5% of the mean).
const EXACT_RMSE: f64 = 0.005;
/// The shadow-map methods' bar: the README's target for shadowed scenes, RMSE 2% of the mean
/// (the hybrid at 64 steps, brute force at 512; `tests/gpu/shadows.rs`). Brute force's own
/// error here is its steps', not the scale's: 1.11% on seed 0 of the seeded test at half-size
/// 1e2 and at 6.6e6 alike.
const MAP_RMSE: f64 = 0.02;

/// The configurations compared: each method (steps), and the exact method's two crossing
/// builds.
const CONFIGS: [(&str, MarchMethod, CrossingsBuild, u32, f64); 4] = [
    (
        "exact, compute lists",
        MarchMethod::Exact,
        CrossingsBuild::Compute,
        64,
        EXACT_RMSE,
    ),
    (
        "exact, rasterised lists",
        MarchMethod::Exact,
        CrossingsBuild::Raster,
        64,
        EXACT_RMSE,
    ),
    (
        "hybrid",
        MarchMethod::Hybrid,
        CrossingsBuild::Compute,
        64,
        MAP_RMSE,
    ),
    (
        "brute force",
        MarchMethod::BruteForce,
        CrossingsBuild::Compute,
        512,
        MAP_RMSE,
    ),
];

/// The ground at y = 0 (the depth buffer's surface).
fn ground(o: DVec3, d: DVec3) -> f64 {
    if d.y < 0.0 {
        -o.y / d.y
    } else {
        f64::INFINITY
    }
}

fn medium() -> Medium {
    Medium::new(
        Vec3::splat(0.1),
        Vec3::splat(0.01),
        PhaseFunction::HenyeyGreenstein { g: 0.3 },
    )
    .unwrap()
}

/// A roof of half-size `s` at height `y`: an open plane, a closed slab, or one open triangle.
fn roof(kind: &str, s: f32, y: f32) -> Mesh {
    match kind {
        "plane" => shapes::plane(Vec3::new(0.0, y, 0.0), Vec2::splat(s)).unwrap(),
        "slab" => shapes::cuboid(Vec3::new(0.0, y, 0.0), Vec3::new(s, 0.1, s)).unwrap(),
        _ => Mesh::new(
            &[
                Vec3::new(-s, y, -s),
                Vec3::new(0.0, y, s),
                Vec3::new(s, y, -s),
            ],
            &[0, 1, 2],
        )
        .unwrap(),
    }
}

/// Each configuration's error against the reference of the same scene (the roof `mesh` under
/// `transform`), and how much the roof darkens the reference (the RMSE of the image with the
/// roof against the one without, relative to the latter's mean).
fn errors(
    camera: &Camera,
    light: &Light,
    mesh: &Mesh,
    transform: Mat4,
) -> (Vec<(&'static str, f64, ImageError, usize)>, f64) {
    errors_of(camera, light, &[(mesh, transform)])
}

/// [`errors`] of a scene of several occluders, each a mesh and its transform; the darkening
/// is theirs together.
fn errors_of(
    camera: &Camera,
    light: &Light,
    meshes: &[(&Mesh, Mat4)],
) -> (Vec<(&'static str, f64, ImageError, usize)>, f64) {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let medium = medium();
    let depths = volshadow_harness::depths_at(camera, N, N, ground);
    let depth = volshadow_harness::depth_texture(&gpu, N, N, &depths);
    let occluder: Vec<reference::Occluder> = meshes
        .iter()
        .map(|(mesh, transform)| {
            reference::Occluder::Mesh(TriangleMesh::from_indexed(
                mesh.positions(),
                mesh.indices(),
                transform.as_dmat4(),
            ))
        })
        .collect();
    let expected = reference::inscatter_image(camera, N, N, ground, &medium, light, &occluder);
    let unshadowed = reference::inscatter_image(camera, N, N, ground, &medium, light, &[]);
    let keep = ImageError::keep_away_from_lights(camera, &[*light], N, N);
    let shadow = ImageError::measure(&expected, &unshadowed, &keep).rmse;
    let gpu_meshes: Vec<(OccluderMesh, Mat4)> = meshes
        .iter()
        .map(|(mesh, transform)| (OccluderMesh::new(&gpu.device, mesh), *transform))
        .collect();
    let occluders: Vec<Occluder> = gpu_meshes
        .iter()
        .map(|(mesh, transform)| Occluder {
            mesh,
            transform: *transform,
        })
        .collect();
    let measured = CONFIGS
        .iter()
        .map(|&(name, method, build, steps, bar)| {
            let passes =
                volshadow_harness::ShadowPasses::new(camera, light, &medium, &depth, &occluders)
                    .settings(MarchSettings {
                        method,
                        crossings_build: build,
                        steps,
                        ..MarchSettings::default()
                    });
            let image: Vec<DVec3> = volshadow_harness::shadow_frame(&gpu, &cache, &passes)
                .inscatter
                .iter()
                .map(|p| DVec3::new(p[0].into(), p[1].into(), p[2].into()))
                .collect();
            let non_finite = image.iter().filter(|p| !p.is_finite()).count();
            (
                name,
                bar,
                ImageError::measure(&image, &expected, &keep),
                non_finite,
            )
        })
        .collect();
    (measured, shadow)
}

/// Asserts every configuration within its bar; `what` names the scene.
fn check(what: &str, measured: &[(&str, f64, ImageError, usize)], shadow: f64) {
    // A roof that casts no shadow in view would test nothing.
    assert!(
        shadow > 0.1,
        "{what}: the roof darkens the view by {shadow:.3} only"
    );
    for (name, bar, e, non_finite) in measured {
        println!(
            "{what}, {name}: RMSE {:.5}, p95 {:.5} (shadow {shadow:.3})",
            e.rmse, e.p95
        );
        assert!(
            e.rmse <= *bar && *non_finite == 0,
            "{what}, {name}: RMSE {:.4} over {bar}, {non_finite} non-finite pixels ({e:?})",
            e.rmse
        );
    }
}

/// The census's scenes: a point light three units above the eye, a roof between them 1.4
/// above the eye, as an open plane, a closed slab and one open triangle, at half-sizes 1e2 to
/// 1e10; and the scene file's form, a plane of half-size 100 scaled by 1e6 by its transform.
/// Before the fix, at 1e8: the plane's mean 30% over the reference under the exact method with
/// rasterised lists (the CPU adapter's default), the hybrid 30%, the triangle's 11%.
#[test]
fn a_roof_far_larger_than_its_distance_keeps_its_shadow() {
    let camera = volshadow_harness::look_at(
        Vec3::new(0.0, 1.6, 5.5),
        Vec3::new(0.0, 1.5, 0.0),
        60.0,
        1.0,
    );
    let light: Light = PointLight::new(Vec3::new(0.0, 4.0, 0.0), Vec3::splat(30.0))
        .unwrap()
        .into();
    for kind in ["plane", "slab", "triangle"] {
        for s in [1e2f32, 1e5, 1e8, 1e10] {
            let (measured, shadow) = errors(&camera, &light, &roof(kind, s, 3.0), Mat4::IDENTITY);
            check(&format!("{kind} of half-size {s:e}"), &measured, shadow);
        }
    }
    let scaled = Mat4::from_scale(Vec3::new(1e6, 1.0, 1e6));
    let (measured, shadow) = errors(&camera, &light, &roof("plane", 100.0, 3.0), scaled);
    check("plane of half-size 100 scaled by 1e6", &measured, shadow);
}

/// Seeded scenes: a roof of half-size 10^[2, 10] at a random height and turn about the
/// vertical (its plane stays exactly level: a tilted plane 1e10 wide is only as level as its
/// f32 vertices), a point or spot light 0.3 to 3 above it, the eye 0.5 to 2 below it and three
/// units from under the light, looking away from it and 5° to 25° up. Prints the failing seed.
#[test]
fn seeded_huge_roofs_match_the_reference() {
    for seed in volshadow_harness::rng::seeds(0..10) {
        let mut rng = volshadow_harness::rng::Rng::new(seed);
        let mut next = || rng.next() as f32;
        let s = 10f32.powf(2.0 + 8.0 * next());
        let height = 2.0 + 2.0 * next();
        let kind = ["plane", "slab", "triangle"][(3.0 * next()).min(2.0) as usize];
        let turn = Mat4::from_rotation_y(std::f32::consts::TAU * next());
        let light_at = Vec3::new(
            4.0 * next() - 2.0,
            height + 0.3 + 2.7 * next(),
            4.0 * next() - 2.0,
        );
        // The eye, three units from under the light, looks away from it (the light stays out
        // of view: its glow is not the reference's quantity) and up through the roof, at the
        // lit fog above it and the shadowed fog under it; a spot shines the same way.
        let yaw = std::f32::consts::TAU * next();
        let away = Vec3::new(yaw.cos(), 0.0, yaw.sin());
        let eye = Vec3::new(light_at.x, height - 0.5 - 1.5 * next(), light_at.z) + 3.0 * away;
        let pitch = (5.0 + 20.0 * next()).to_radians();
        let camera = volshadow_harness::look_at(eye, eye + away + Vec3::Y * pitch.tan(), 60.0, 1.0);
        let light: Light = if next() < 0.5 {
            PointLight::new(light_at, Vec3::splat(30.0)).unwrap().into()
        } else {
            SpotLight::new(light_at, away - 0.3 * Vec3::Y, 0.9, Vec3::splat(30.0))
                .unwrap()
                .into()
        };
        let mesh = roof(kind, s, height);
        let (measured, shadow) = errors(&camera, &light, &mesh, turn);
        let what = format!(
            "seed {seed}: {kind} of half-size {s:.3e} at {height:.2}, light at {light_at}, eye at {eye}"
        );
        check(&what, &measured, shadow);
    }
}

/// The sun of the sun tests, high and tilted about 20° from overhead, with the shadow distance
/// the facade's planner gives it over such occluders: the medium's
/// [`shadow_reach`](volshadow::Medium::shadow_reach) (these tests drive the nodes directly).
fn sun() -> Light {
    volshadow::DirectionalLight::new(Vec3::new(0.3, -1.0, 0.2), Vec3::splat(3.0))
        .unwrap()
        .with_shadow_distance(medium().shadow_reach().unwrap())
        .unwrap()
        .into()
}

/// The camera under the roofs of the sun tests, looking up through them.
fn under_the_roof() -> Camera {
    volshadow_harness::look_at(
        Vec3::new(0.0, 1.6, 5.5),
        Vec3::new(0.0, 2.5, 0.0),
        60.0,
        1.0,
    )
}

/// Every method within its bar under [`sun`], from [`under_the_roof`], over each roof of each
/// half-size in `sizes`.
fn sun_over_roofs(sizes: &[f32]) {
    let (camera, light) = (under_the_roof(), sun());
    for kind in ["plane", "slab", "triangle"] {
        for &s in sizes {
            let (measured, shadow) = errors(&camera, &light, &roof(kind, s, 3.0), Mat4::IDENTITY);
            check(
                &format!("sun, {kind} of half-size {s:e}"),
                &measured,
                shadow,
            );
        }
    }
}

/// A sun over the roofs of [`a_roof_far_larger_than_its_distance_keeps_its_shadow`], the eye
/// under them looking up through them, half-sizes 1e2 to 1e5: every method within its bar.
/// Measured (lavapipe, 2026-12-04; before the fixes):
/// - the extents' near plane scaled by the scene's size (1e-4 of it: 14 units for a roof 1e5
///   wide) cut every volume near the eye: from 3e4 the exact method lost the roof, and from 1e5
///   all four configurations drew the unshadowed image (RMSE 116–121%);
/// - without the shadow distance (the map's default is the occluders' farthest corner), the
///   cascades spread over the roof: the hybrid 3.2% at 3e3 and 10.7% at 1e4 (bar 2%), and the
///   open plane and triangle, which the exact method takes from the map between crossings, fail
///   from 1e5 (121%) even with the near plane fixed.
///
/// Now the hybrid is within 1.5% at every size. Larger roofs: the ignored test below.
#[test]
fn a_roof_far_larger_than_its_distance_shadows_a_sun() {
    sun_over_roofs(&[1e2, 1e3, 1e4, 1e5]);
}

/// As [`a_roof_far_larger_than_its_distance_shadows_a_sun`], at half-sizes 1e8 and 1e10.
/// Ignored: it fails (lavapipe, 2026-12-04). The closed slab is exact under the exact method,
/// but the map loses the roof, and with it the shadow-map methods and the exact method over
/// the open plane and triangle (RMSE 44% to 121%); the ground test below stops at 1e5 for the
/// same reason (at 1e7 brute force reads 2.12% against 2%). The cascade's depth runs over the roof's
/// whole extent along the light, so near the cascade the roof and the fog below it are closer
/// in depth than the rasteriser's interpolation resolves; clipping the triangles to the cascade
/// in clip space (tried) did not help, since the clipped vertices' depths carry the same error.
#[test]
#[ignore = "a sun's map loses a roof 1e8 wide (GUIDE, Limits)"]
fn a_roof_vastly_larger_than_its_distance_shadows_a_sun() {
    sun_over_roofs(&[1e8, 1e10]);
}

/// A small cube's sun shadow over a ground slab far larger than the view (0.2 below the depth
/// buffer's ground, so it shadows nothing in view), half-sizes 1e2 to 1e5: every method within
/// its bar (at 1e7 brute force reads 2.12%, the map's limit of the ignored test above; the
/// others pass there). Before the extents' near plane was bounded by the nearest occluder's distance
/// (1e-4 of the scene's size, 14 units at 1e5), the exact method's RMSE was 28% at 1e5 (p95
/// 100%: the fog near the ground black, the cube's shaft lit) and 42% at 1e7 (lavapipe,
/// 2026-12-04); without the shadow distance the hybrid was 2.24% at 1e5 (bar 2%).
#[test]
fn a_ground_far_larger_than_the_view_keeps_a_small_occluders_sun_shadow() {
    let camera = volshadow_harness::look_at(
        Vec3::new(0.0, 1.6, 5.5),
        Vec3::new(0.0, 1.5, 0.0),
        60.0,
        1.0,
    );
    let light = sun();
    let cube = shapes::cuboid(Vec3::new(0.0, 2.2, 0.0), Vec3::splat(0.5)).unwrap();
    for s in [1e2f32, 1e4, 1e5] {
        let floor = roof("slab", s, -0.2);
        let meshes = [(&cube, Mat4::IDENTITY), (&floor, Mat4::IDENTITY)];
        let (measured, _) = errors_of(&camera, &light, &meshes);
        for (name, bar, e, non_finite) in measured {
            println!(
                "ground of half-size {s:e}, {name}: RMSE {:.4}, p95 {:.4}",
                e.rmse, e.p95
            );
            assert!(
                e.rmse <= bar && non_finite == 0,
                "ground of half-size {s:e}, {name}: RMSE {:.4} over {bar}",
                e.rmse
            );
        }
    }
}
