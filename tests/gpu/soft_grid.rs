//! The soft-shadow grid (`SoftShadowNode`), which the exact and hybrid methods read for a
//! light with a radius: seeded random sphere scenes against the f64 reference (exact
//! spherical-cap overlap), its rebuild only when the shadow map changes, and its errors.
//!
//! Bars: the issue's, in-scatter RMSE ≤ 2% of the mean and p95 ≤ 3% against the reference.

use volshadow::nodes::{Encode, Node};

use glam::{DVec3, Quat, Vec3};
use volshadow::glam::camera::rh::{proj::directx, view::look_at_mat4};
use volshadow::gpu::{Occluder, OccluderMesh};
use volshadow::nodes::{
    MarchMethod, MarchSettings, ShadowMap, ShadowMapInputs, ShadowMapNode, ShadowMapSettings,
    SoftShadowInputs, SoftShadowNode, SoftShadowSize,
};
use volshadow::reference::{self, Cuboid, Sphere};
use volshadow::scene::shapes;
use volshadow::{
    Camera, DirectionalLight, Error, Light, Medium, PhaseFunction, PointLight, ShaderPrecision,
    SpotLight,
};
use volshadow_harness::scene::errors;

const RMSE_BAR: f64 = 0.02;
const P95_BAR: f64 = 0.03;
const SIZE: u32 = 48;
const SEEDS: u64 = 12;

/// One random scene: a point light of radius R at a position, a sphere at distance L in a
/// random direction, a camera looking across the shadow behind it at a wall, all scaled by a
/// log-uniform unit from 1e-2 to 1e5 (the f32 path must not care; units this large catch a
/// spot's cone cut wrong by a cone test sensitive to rounding: seed 204 of the spot test, at a
/// unit of 8e4, RMSE 5.2%), optical depth σt·L
/// log-uniform over the caller's range (the eye within about 8 optical depths of the shadow).
struct SoftScene {
    camera: Camera,
    medium: Medium,
    light: Light,
    /// The occluders: spheres (centre, radius).
    spheres: Vec<(Vec3, f32)>,
    /// and boxes (centre, half extents, rotation),
    boxes: Vec<(Vec3, Vec3, Quat)>,
    /// and meshes where they stand (the reference takes their triangles).
    meshes: Vec<volshadow::scene::Mesh>,
    /// A point of the wall and its normal (towards the camera).
    wall: (DVec3, DVec3),
    describe: String,
    /// Whether the view shows the shadow (`check_scenes_counted` then requires the image with
    /// the shadow ignored to be beyond twice the p95 bar).
    shows_shadow: bool,
}

impl SoftScene {
    /// The occluders as the reference takes them.
    fn reference_occluders(&self) -> Vec<reference::Occluder> {
        self.occluders_with(|&(c, half, rotation)| {
            Cuboid::new(c.as_dvec3(), half.as_dvec3(), rotation.as_dquat()).into()
        })
    }

    /// The occluders with each box's corners rounded as f32 holds them on their way to the
    /// GPU: `shapes::cuboid`'s vertices carried to the world by the f32 transform that
    /// `placed` hands over (one rounding of the several a GPU may make), then taken exactly.
    /// Spheres and meshes as in `reference_occluders`.
    fn rounded_occluders(&self) -> Vec<reference::Occluder> {
        self.occluders_with(|&(c, half, rotation)| {
            let mesh = shapes::cuboid(Vec3::ZERO, half).unwrap();
            let transform = glam::Mat4::from_rotation_translation(rotation, c);
            let corners: Vec<Vec3> = mesh
                .positions()
                .iter()
                .map(|&p| transform.transform_point3(p))
                .collect();
            reference::Occluder::Mesh(reference::TriangleMesh::from_indexed(
                &corners,
                mesh.indices(),
                glam::DMat4::IDENTITY,
            ))
        })
    }

    /// The reference's image of the scene at `size`², past `occluders`.
    fn reference_image(&self, size: u32, occluders: &[reference::Occluder]) -> Vec<DVec3> {
        let wall = |e: DVec3, d: DVec3| wall_distance(self.wall, e, d);
        reference::soft::inscatter_image_soft(
            &self.camera,
            size,
            size,
            wall,
            &self.medium,
            &self.light,
            occluders,
        )
    }

    /// How far the reference moves when the boxes' corners are rounded to f32
    /// (`rounded_occluders`): its image at `size`² against `reference`, the scene's own.
    fn moved_by_rounding(
        &self,
        size: u32,
        reference: &[DVec3],
    ) -> volshadow_harness::scene::Errors {
        let rounded: Vec<[f32; 4]> = self
            .reference_image(size, &self.rounded_occluders())
            .iter()
            .map(|v| [v.x as f32, v.y as f32, v.z as f32, 1.0])
            .collect();
        errors(&rounded, reference, &self.camera, &self.light, (size, size))
    }

    /// The scene's spheres and meshes as the reference takes them, and its boxes by `boxes`.
    fn occluders_with(
        &self,
        boxes: impl Fn(&(Vec3, Vec3, Quat)) -> reference::Occluder,
    ) -> Vec<reference::Occluder> {
        let spheres = self
            .spheres
            .iter()
            .map(|&(c, rho)| Sphere::new(c.as_dvec3(), f64::from(rho)).into());
        let boxes = self.boxes.iter().map(boxes);
        let meshes = self.meshes.iter().map(|m| {
            reference::Occluder::Mesh(reference::TriangleMesh::from_indexed(
                m.positions(),
                m.indices(),
                glam::DMat4::IDENTITY,
            ))
        });
        spheres.chain(boxes).chain(meshes).collect()
    }
}

/// A grey medium of extinction `sigma_t`, single-scattering `albedo` and Henyey–Greenstein `g`.
fn grey_medium(sigma_t: f32, albedo: f32, g: f32) -> Medium {
    Medium::new(
        Vec3::splat(sigma_t * albedo),
        Vec3::splat(sigma_t * (1.0 - albedo)),
        PhaseFunction::HenyeyGreenstein { g },
    )
    .unwrap()
}

fn random_scene(seed: u64, log_tau: (f32, f32)) -> SoftScene {
    let mut rng = fastrand::Rng::with_seed(seed);
    let mut uniform = |lo: f32, hi: f32| lo + (hi - lo) * rng.f32();
    let unit = 10f32.powf(uniform(-2.0, 5.0));
    let direction = |u: f32, v: f32| {
        let z = 2.0 * u - 1.0;
        let phi = 2.0 * std::f32::consts::PI * v;
        let r = (1.0 - z * z).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    };
    let position = unit * Vec3::new(uniform(-5.0, 5.0), uniform(-5.0, 5.0), uniform(-5.0, 5.0));
    let l = unit * uniform(1.0, 4.0);
    let axis = direction(uniform(0.0, 1.0), uniform(0.0, 1.0));
    let center = position + l * axis;
    let rho = l * uniform(0.1, 0.4);
    // The light's radius: from a fifth of the gap to the sphere up to most of it.
    let radius = (l - rho) * uniform(0.05, 0.6);
    let tau = 10f32.powf(uniform(log_tau.0, log_tau.1));
    let sigma_t = tau / l;
    let albedo = uniform(0.3, 0.95);
    let g = uniform(-0.5, 0.8);
    // The camera: beside the shadow, looking at a point on its axis behind the sphere.
    let target = center + axis * l * uniform(0.5, 2.5);
    let side = direction(uniform(0.0, 1.0), uniform(0.0, 1.0));
    let side = (side - axis * side.dot(axis)).normalize_or(Vec3::X);
    // In thick fog the eye comes closer, within about 8 optical depths of the target: the
    // light's path (up to 3.5 L, 35 optical depths) and the eye's then stay within f32's range.
    // Farther, the reference's in-scatter falls below 1e-38 (1e-75 at σt·L = 25), which no
    // f32 output can hold.
    let reach = (1.6 / tau).min(1.0);
    let eye = target + side * l * reach * uniform(2.0, 5.0) + axis * l * reach * uniform(-1.0, 1.0);
    let up = if axis.cross(eye - target).length_squared() > 1e-6 * l * l {
        axis
    } else {
        Vec3::Y
    };
    let view = look_at_mat4(eye, target, up);
    let fov = uniform(0.6, 1.4);
    let camera = Camera::new(view, directx::perspective(fov, 1.0, 1e-3 * l, 1e4 * l)).unwrap();
    let to_eye = (eye - target).normalize().as_dvec3();
    let wall_point = target.as_dvec3() - to_eye * f64::from(l * uniform(1.0, 3.0));
    let light = PointLight::new(position, Vec3::splat(unit * unit))
        .unwrap()
        .with_radius(radius)
        .unwrap();
    let describe = format!(
        "seed {seed}: unit {unit:.3e}, L {l:.3e}, rho/L {:.2}, R/L {:.3}, sigma_t L {tau:.2e}, g {g:.2}",
        rho / l,
        radius / l
    );
    SoftScene {
        camera,
        medium: grey_medium(sigma_t, albedo, g),
        light: light.into(),
        spheres: vec![(center, rho)],
        boxes: Vec::new(),
        meshes: Vec::new(),
        wall: (wall_point, to_eye),
        describe,
        shows_shadow: true,
    }
}

/// The same light with radius 0 (hard shadows).
fn without_radius(light: Light) -> Light {
    match light {
        Light::Point(l) => l.with_radius(0.0).unwrap().into(),
        Light::Spot(l) => l.with_radius(0.0).unwrap().into(),
        other => other,
    }
}

/// `random_scene` with a spot light (its apex angle log-uniform over `cone`, radians) aimed
/// off the sphere by 0.4 to 1.1 times its half-angle, so that the cone's edge crosses the
/// sphere or passes near it and the penumbra inside the cone reaches parts of the sphere
/// outside it.
fn random_spot_scene(seed: u64, log_tau: (f32, f32), cone: (f32, f32)) -> SoftScene {
    let mut s = random_scene(seed, log_tau);
    let mut rng = fastrand::Rng::with_seed(seed ^ 0x5eed_5907);
    let mut uniform = |lo: f32, hi: f32| lo + (hi - lo) * rng.f32();
    let Light::Point(point) = s.light else {
        unreachable!("random_scene makes point lights")
    };
    let axis = (s.spheres[0].0 - point.position()).normalize();
    let side = Quat::from_axis_angle(axis, uniform(0.0, std::f32::consts::TAU))
        * axis.any_orthonormal_vector();
    let apex = (cone.0.ln() + (cone.1.ln() - cone.0.ln()) * uniform(0.0, 1.0)).exp();
    let off = 0.5 * apex * uniform(0.4, 1.1);
    let aim = Quat::from_axis_angle(axis.cross(side), off) * axis;
    let spot = volshadow::SpotLight::new(point.position(), aim, apex, point.intensity())
        .unwrap()
        .with_radius(point.radius())
        .unwrap();
    s.light = spot.into();
    s.describe = format!(
        "{} (spot {:.0} deg, {:.2} of its half-angle off the sphere)",
        s.describe,
        apex.to_degrees(),
        2.0 * off / apex
    );
    s
}

/// `random_scene` with a box in place of the sphere: half extents of 0.6 to 1 times the
/// sphere's radius over √3 along each axis (so that it fits within the sphere, which the light
/// never reaches), turned at random. Its outline has corners and straight edges, and its
/// shadow-map depths vary across a face: the reference takes the light's disc by rows (exact
/// along each, within 2e-7 of the fraction).
fn random_box_scene(seed: u64, log_tau: (f32, f32)) -> SoftScene {
    let mut s = random_scene(seed, log_tau);
    let mut rng = fastrand::Rng::with_seed(seed ^ 0xb0c5_0b0c);
    let mut uniform = |lo: f32, hi: f32| lo + (hi - lo) * rng.f32();
    let (center, rho) = s.spheres[0];
    let half =
        rho / 3f32.sqrt() * Vec3::new(uniform(0.6, 1.0), uniform(0.6, 1.0), uniform(0.6, 1.0));
    let rotation = Quat::from_euler(
        glam::EulerRot::XYZ,
        uniform(0.0, std::f32::consts::TAU),
        uniform(0.0, std::f32::consts::TAU),
        uniform(0.0, std::f32::consts::TAU),
    );
    s.spheres.clear();
    s.boxes = vec![(center, half, rotation)];
    // Counted by the box test instead (some views show little of a box's shadow).
    s.shows_shadow = false;
    s.describe = format!(
        "{} (a box, half extents {:.2} {:.2} {:.2} of rho)",
        s.describe,
        half.x / rho,
        half.y / rho,
        half.z / rho
    );
    s
}

/// Box scenes: how many seeds, and their image's side (the reference takes the light's disc by
/// rows for a box, far more costly than a sphere's cap overlap).
const BOX_SEEDS: std::ops::Range<u64> = 300..308;
const BOX_SIZE: u32 = 16;
/// Measured limit for every box scene (seed 300, a light of radius 0.33 L close to a box, p95
/// 5.73%, 2026-11-29; against the reference's former 16 × 16 directions 5.87%, and 5.13% when the grid's nearest distance came from the box's world box, looser than
/// its own); the others are held to the issue's bars.
const BOX_P95_LIMIT: f64 = 0.06;

/// Seeded box scenes (`random_box_scene`), otherwise as
/// `random_soft_scenes_against_the_reference`: at least 7 of 8 within the issue's bars, all
/// within RMSE 2% and the measured p95 limit, finite; hard > 10% in one scene at least; the
/// shadow ignored beyond twice the p95 bar in at least 6 (a box is smaller than the sphere it
/// replaces, so some views show little of its shadow).
///
/// Measured: 7 of 8 within, seed 300 p95 5.73% (the others ≤ 1.24%; 5.87% and ≤ 1.32% against
/// the reference's former 16 × 16 directions, as are the figures that follow). Before the
/// grid's nearest distance came from the box's own frame, 5.13%, and then: PCSS's one
/// planar blocker is the limit there, not the grid: the per-step estimate at 256 steps gives
/// 5.24%. Its distance, for that seed and against the reference: the blend of the front surface
/// and the back face the crate uses 5.13%, the chord's midpoint 5.25%, the geometric mean
/// 4.87%, the back face alone 11.3% (beyond the limit: the test tells), the front surface alone
/// 1.83%, which also does best on the other seven box scenes, while on spheres it leaves the
/// deep penumbra 110% too bright (see `grid_cells_against_the_reference_visible_fraction`): a
/// box's penumbra is wider than a planar blocker at its middle predicts.
#[test]
#[cfg_attr(
    not(feature = "sweeps"),
    ignore = "an accuracy sweep: --features sweeps"
)]
fn random_soft_box_scenes_against_the_reference() {
    let scenes: Vec<SoftScene> = BOX_SEEDS
        .map(|seed| random_box_scene(seed, (-4.0, 0.0)))
        .collect();
    let count = scenes.len();
    let Checked {
        worst,
        hard_worst,
        within,
        telling,
        ..
    } = check_scenes_sized(
        &scenes,
        (RMSE_BAR, BOX_P95_LIMIT),
        BOX_SIZE,
        ShaderPrecision::Native,
    );
    eprintln!(
        "boxes: {within} of {count} within, worst p95 {:.2}%, hard worst {:.2}%, {telling} telling",
        100.0 * worst,
        100.0 * hard_worst
    );
    assert!(
        within + 1 >= count,
        "{within} of {count} box scenes within the bars"
    );
    assert!(
        hard_worst > 0.1,
        "hard worst p95 {hard_worst}: the bars cannot tell"
    );
    assert!(
        telling + 2 >= count,
        "only {telling} of {count} box scenes show their shadow"
    );
}

fn wall_distance(wall: (DVec3, DVec3), e: DVec3, d: DVec3) -> f64 {
    let denom = d.dot(wall.1);
    let t = (wall.0 - e).dot(wall.1) / denom;
    if denom < 0.0 && t > 0.0 {
        t
    } else {
        f64::INFINITY
    }
}

/// Seeded scenes from 1e-4 to 1 optical depth σt·L: every one within the bars with the grid
/// (exact method), finite; the same scenes drawn hard are farther than 10% from the soft
/// reference in at least one of them, so the bars can tell a penumbra from none (and each
/// scene with its shadow ignored is beyond twice the p95 bar).
#[test]
fn random_soft_scenes_against_the_reference() {
    let (worst, hard_worst) = random_scenes(0..SEEDS, (-4.0, 0.0), (RMSE_BAR, P95_BAR));
    eprintln!(
        "worst p95 {:.2}%, hard {:.2}%",
        100.0 * worst,
        100.0 * hard_worst
    );
    assert!(
        hard_worst > 0.10,
        "hard shadows within {hard_worst} of every soft reference: the scenes cannot tell"
    );
}

/// The same seeded scenes and bars with every transcendental built-in off by the most WGSL
/// allows.
#[test]
fn random_soft_scenes_against_the_reference_worst_case() {
    let scenes: Vec<SoftScene> = (0..SEEDS)
        .map(|seed| random_scene(seed, (-4.0, 0.0)))
        .collect();
    let worst = check_scenes_sized(
        &scenes,
        (RMSE_BAR, P95_BAR),
        SIZE,
        volshadow_harness::WORST_CASE,
    )
    .worst;
    eprintln!("worst case: worst p95 {:.2}%", 100.0 * worst);
}

/// Seeded scenes with a spot light whose cone's edge crosses the sphere or passes near it
/// (`random_spot_scene`), σt·L from 1e-4 to 1, through the grid (exact method), twice over
/// the same seeds: apex 30° to 90°, and 30° to 115° (a map up to about 146° once widened for
/// the penumbra, coarse at its centre). All finite and beyond twice the p95 bar with the shadow
/// ignored; of each 12, at least 10 within the issue's bars, and every one within p95 10%,
/// RMSE 3%. Those two are measured limits (10 and 11 within, the others up to p95 7.39%; the
/// spiral's pattern moves seed 202 between p95 1.7% and 4.3%, see docs/METHOD.md; with a `sin`
/// hash for the spiral in place of the integer one, 10 and 10 within, the others, p95 3.3%,
/// 7.5% and 3.3%, 7.2%, RMSE up to 2.4%, views in which every counted pixel is in the hard
/// umbra, lit only by the deep penumbra: a known limitation, see the `SoftShadowNode` docs).
/// With the blockers' distance at the chord's midpoint and no extra taps in the deep penumbra:
/// 9 and 10 within, p95 3.5%, 6.2%, 11.4% and 4.6%, 11.3%, RMSE up to 2.7%. Without the spot
/// map widened for the penumbra (`ShadowMapNode::spot_fov`), the parts of the sphere outside
/// the cone are missing from it and light the penumbra they cast inside: 4 of the first 12
/// within the issue's bars, p95 up to 112%, RMSE up to 6.9%.
#[test]
fn random_soft_spot_scenes_against_the_reference() {
    const LIMIT_BARS: (f64, f64) = (0.03, 0.10);
    const WITHIN: usize = 10;
    for cone in [(0.52, 1.57), (0.52, 2.0)] {
        let scenes: Vec<SoftScene> = (200..200 + SEEDS)
            .map(|seed| random_spot_scene(seed, (-4.0, 0.0), cone))
            .collect();
        let (worst, hard_worst, within) = check_scenes_counted(&scenes, LIMIT_BARS);
        eprintln!(
            "apex {:.0}° to {:.0}°: worst p95 {:.2}%, hard {:.2}%, {within} of {} within the issue's bars",
            cone.0.to_degrees(),
            cone.1.to_degrees(),
            100.0 * worst,
            100.0 * hard_worst,
            scenes.len()
        );
        assert!(
            within >= WITHIN,
            "apex up to {:.0}°: {within} of {} scenes within the issue's bars, fewer than {WITHIN}",
            cone.1.to_degrees(),
            scenes.len()
        );
    }
}

/// Two spheres at different distances from a light of radius 0.3: the far one (radius 0.5 at
/// 3.5) in the near one's (radius 0.3 at 1.5) penumbra, their penumbrae overlapping behind it;
/// thin fog, the eye beside the shadows looking across them.
fn overlap_scene() -> SoftScene {
    let mut s = umbra_scene(
        Vec3::new(4.0, 0.3, 5.0),
        Vec3::new(0.2, 0.0, 5.5),
        "two spheres, overlapping penumbrae",
    );
    s.spheres = vec![
        (Vec3::new(0.0, 0.0, 1.5), 0.3),
        (Vec3::new(0.45, 0.0, 3.5), 0.5),
    ];
    s
}

/// Overlapping penumbrae at different distances (`overlap_scene`). Bars: RMSE the issue's 2%;
/// p95 3.25%, a measured limit between the code and plausibly broken variants (measured 2.65%,
/// RMSE 1.28%, where a far layer just below a point does not mark its cell sharp (see
/// `a_ground_that_casts_shadows_under_a_soft_light`); 3.65% when any far layer that hides none
/// of the taps marks it sharp; 2.88% with a grid built uniformly, not adaptively; 3.58% with
/// one blocker distance for both spheres, not the estimate's two layers; 4.13% and 4.63% with
/// 16 taps a search round instead of 8). The far
/// sphere is half hidden behind the near one in the shadow map, which holds one surface a
/// direction: a known limitation (see the `SoftShadowNode` docs).
#[test]
#[cfg_attr(
    not(feature = "sweeps"),
    ignore = "an accuracy sweep: --features sweeps"
)]
fn overlapping_penumbrae_at_different_distances() {
    const OVERLAP_P95_BAR: f64 = 0.0325;
    let (worst, _) = check_scenes(&[overlap_scene()], (RMSE_BAR, OVERLAP_P95_BAR));
    eprintln!("p95 {:.2}%", 100.0 * worst);
}

/// The report's soft scene (a sphere of radius 1 under a light of radius 0.5 at 2.4 from its
/// centre, the camera looking at it over a ground) with the ground casting shadows: a plane
/// 60 × 60 (two triangles), the sphere exact in the reference. The ground is the far layer of the
/// medium just above it.
fn ground_scene() -> SoftScene {
    let light = PointLight::new(Vec3::new(0.6, 4.8, -1.5), Vec3::new(60.0, 58.0, 54.0))
        .unwrap()
        .with_radius(0.5)
        .unwrap();
    let view = look_at_mat4(Vec3::new(0.0, 2.0, 9.0), Vec3::new(0.0, 1.6, 0.0), Vec3::Y);
    let camera = Camera::new(
        view,
        directx::perspective(45f32.to_radians(), 1.0, 0.1, 1e4),
    )
    .unwrap();
    SoftScene {
        camera,
        medium: Medium::new(
            Vec3::splat(0.1),
            Vec3::splat(0.01),
            PhaseFunction::HenyeyGreenstein { g: 0.6 },
        )
        .unwrap(),
        light: light.into(),
        spheres: vec![(Vec3::new(0.0, 3.0, 0.0), 1.0)],
        boxes: Vec::new(),
        meshes: vec![shapes::plane(Vec3::ZERO, glam::Vec2::splat(30.0)).unwrap()],
        wall: (DVec3::ZERO, DVec3::Y),
        describe: "a ground that casts shadows under the report's soft scene".to_string(),
        shows_shadow: true,
    }
}

// One sign (mixed): each costs the scene's reference again (about 30 s).
volshadow_harness::at_each_precision!(
    #[cfg_attr(not(feature = "sweeps"), ignore = "an accuracy sweep: --features sweeps")]
    a_ground_that_casts_shadows_at => a_ground_that_casts_shadows_under_a_soft_light,
    a_ground_that_casts_shadows_under_a_soft_light_worst_case,
    [volshadow_harness::WORST_CASE]
);

/// A ground that casts shadows (`ground_scene`), 32² (the reference takes the light's disc
/// by rows for the plane's triangles everywhere above it). Bars: RMSE the issue's 2%; p95 5%,
/// a measured limit (4.61%, RMSE 1.33%, worst-case precision 4.45%, 2026-11-29; against the
/// reference's former 16 × 16 directions 4.59% and 4.44%, and the figures that follow:
/// at 64² 3.82%; at 128² the report's exact full 3.60% and its defaults 4.02%, and per step at
/// 64 steps 2.67%). The ground and the sphere are two occluders, so `mark_shafts` runs: a cell
/// just behind a surface is neither a shaft's peak nor its side there, without which the
/// penumbra above the ground is marked and refined per point, 5.09% (worst case 5.41%;
/// marks reaching 12 cells). The
/// estimate takes a far layer just in front of a point that hides none of its taps (a receiver
/// the point lies above) as no reason to mark the cell sharp: marking it sharp blends in the
/// shadow map's hard visibility there, in place of the sphere's wide penumbra, 6.35% (fails;
/// the report's exact full at 128² 4.74%). Without the condition that the far layer lies
/// within 0.9 of the point's distance: 3.01% at 128² exact full (3.51% with it, alternated in
/// one process), but two spheres with overlapping penumbrae 3.65%, beyond their bar.
fn a_ground_that_casts_shadows_at(precision: ShaderPrecision) {
    const GROUND_P95_BAR: f64 = 0.05;
    let Checked {
        worst,
        hard_worst: hard,
        ..
    } = check_scenes_sized(&[ground_scene()], (RMSE_BAR, GROUND_P95_BAR), 32, precision);
    eprintln!(
        "{precision:?}: ground: p95 {:.2}%, hard {:.2}%",
        100.0 * worst,
        100.0 * hard
    );
    assert!(
        hard > GROUND_P95_BAR,
        "hard p95 {hard}: the bar cannot tell"
    );
}

/// A sphere of radius 0.6 at distance 2 from a light of radius 0.3 (its umbra widens behind it
/// and never ends), in thin fog (σt·L = 0.2), with the eye placed at `eye` looking at `target`.
fn umbra_scene(eye: Vec3, target: Vec3, describe: &str) -> SoftScene {
    let light = PointLight::new(Vec3::ZERO, Vec3::splat(4.0))
        .unwrap()
        .with_radius(0.3)
        .unwrap();
    let medium = Medium::new(
        Vec3::splat(0.08),
        Vec3::splat(0.02),
        PhaseFunction::HenyeyGreenstein { g: 0.3 },
    )
    .unwrap();
    let up = if (target - eye).normalize().abs().y > 0.9 {
        Vec3::Z
    } else {
        Vec3::Y
    };
    let view = look_at_mat4(eye, target, up);
    let camera = Camera::new(view, directx::perspective(1.2, 1.0, 1e-3, 1e4)).unwrap();
    // A wall 12 units beyond the eye, facing it.
    let to_eye = (eye - target).normalize().as_dvec3();
    SoftScene {
        camera,
        medium,
        light: light.into(),
        spheres: vec![(Vec3::new(0.0, 0.0, 2.0), 0.6)],
        boxes: Vec::new(),
        meshes: Vec::new(),
        wall: (eye.as_dvec3() - to_eye * 12.0, to_eye),
        describe: describe.to_string(),
        shows_shadow: true,
    }
}

/// The eye inside a soft shadow (`umbra_scene`): in the umbra looking back past the sphere at
/// the light, and in the penumbra looking across the shadow. Bars: the issue's; each scene with
/// its shadow ignored (what a march that lit the eye's piece of the ray would come closer to)
/// must be beyond twice the p95 bar.
#[test]
fn eye_inside_a_soft_shadow() {
    let scenes = [
        umbra_scene(
            Vec3::new(0.05, 0.0, 3.2),
            Vec3::new(0.0, 0.0, -1.0),
            "eye in the umbra, looking back at the sphere and the light",
        ),
        umbra_scene(
            Vec3::new(0.95, 0.0, 4.0),
            Vec3::new(-2.0, 0.0, 4.0),
            "eye in the penumbra, looking across the shadow",
        ),
    ];
    let (worst, hard_worst) = check_scenes(&scenes, (RMSE_BAR, P95_BAR));
    eprintln!(
        "worst p95 {:.2}%, hard {:.2}%",
        100.0 * worst,
        100.0 * hard_worst
    );
}

/// The eye in the umbra looking away from the light (`umbra_scene`): most of each ray stays in
/// the umbra and the deep penumbra around it, where the visible fraction is small and the
/// estimate's error is relative to it. The bars: RMSE the issue's 2%; p95 5.5%, above the
/// issue's 3% (measured 4.60%, RMSE 1.31%, a known limitation, see the `SoftShadowNode` docs;
/// without the deep penumbra's extra taps 5.71%, and with the blockers' distance at the
/// chord's midpoint as well, 6.00%; with the grid's neighbours interpolated within an absolute
/// 0.02 instead of a relative 5%, 22.9%). With the blocker's distance taken at the front
/// surface alone (no back-face layer), this scene is at p95 41.1%, RMSE 5.1% (30.7% estimating
/// per step at 256 steps).
#[test]
fn eye_in_the_umbra_looking_away_from_the_light() {
    const DEEP_P95_BAR: f64 = 0.055;
    let (worst, _) = check_scenes(
        &[umbra_scene(
            Vec3::new(0.0, 0.05, 3.2),
            Vec3::new(0.0, 0.0, 10.0),
            "eye in the umbra, looking away from the light",
        )],
        (RMSE_BAR, DEEP_P95_BAR),
    );
    eprintln!("p95 {:.2}%", 100.0 * worst);
}

/// Thick fog, σt·L from 1 to 10 with the eye within about 8 optical depths of the shadow: the
/// light a pixel receives comes from a few mean free paths of the ray, so the error of the
/// visibility at single points shows instead of averaging out along the ray. A known
/// limitation, run by hand: it fails the issue's bars. Measured (exact method, grid 64² × 16,
/// units from 1e-2 to 1e5): of 12 seeds, 8 within the bars; seed 105 (the eye in a deep
/// penumbra, where the visible fraction is small) p95 16.5%, RMSE 11.9%; seed 107 p95 2.47%,
/// RMSE 2.23%; seed 108 (a small light seen close up) 7.8% through the grid (1.1% estimating
/// per step: the grid's cells are coarse for that close a view); seed 110 p95 3.2%, RMSE
/// 3.4%. The hard exact method is within 0.02% of the hard reference in 105 and 108. With the
/// blockers' distance at the chord's midpoint and no extra taps in the deep penumbra: 9
/// within, 105 at 28.2% (18.6% with the scene 0.94 times the size; 37.8% then with the front
/// surface alone), 107 at 1.65%, 110 at 3.4%; that 105 taken apart: 10.5% with 128 filter
/// taps, 8.0% with 64 slices, 14.8% estimating per step; that variant leaves the grid's cells
/// in the deep penumbra of the thinner seeded scenes 10.6% too dark on average
/// (`grid_cells_against_the_reference_visible_fraction`).
#[test]
#[ignore = "known limitation (thick fog, eye close to a deep penumbra): fails the bars; run by hand"]
fn random_soft_scenes_in_thick_fog() {
    random_scenes(100..100 + SEEDS, (0.0, 1.0), (RMSE_BAR, P95_BAR));
}

/// Renders each seed's scene soft through the grid and hard, against the soft reference;
/// fails naming every seed beyond `bars` (RMSE, p95) or not finite. Returns the worst soft and
/// hard p95.
fn random_scenes(seeds: std::ops::Range<u64>, log_tau: (f32, f32), bars: (f64, f64)) -> (f64, f64) {
    let scenes: Vec<SoftScene> = seeds.map(|seed| random_scene(seed, log_tau)).collect();
    check_scenes(&scenes, bars)
}

/// Each scene soft through the grid (exact method), hard, and with its shadow ignored, against
/// the soft reference; fails naming every scene beyond `bars` (RMSE, p95) or not finite, and if
/// a scene's shadow ignored is within twice the issue's p95 bar (it could not tell a lit
/// penumbra).
/// Returns the worst soft and hard p95.
fn check_scenes(scenes: &[SoftScene], bars: (f64, f64)) -> (f64, f64) {
    let (worst, hard_worst, _) = check_scenes_counted(scenes, bars);
    (worst, hard_worst)
}

/// `check_scenes`, also returning how many scenes were within the issue's bars (RMSE_BAR,
/// P95_BAR), which may be tighter than `bars`.
fn check_scenes_counted(scenes: &[SoftScene], bars: (f64, f64)) -> (f64, f64, usize) {
    let checked = check_scenes_sized(scenes, bars, SIZE, ShaderPrecision::Native);
    (checked.worst, checked.hard_worst, checked.within)
}

/// What `check_scenes_sized` measured over the scenes it held to the bars.
struct Checked {
    /// The worst soft p95, and the worst drawn hard.
    worst: f64,
    hard_worst: f64,
    /// How many were within the issue's bars (RMSE_BAR, P95_BAR), which may be tighter than
    /// the bars the scenes were held to.
    within: usize,
    /// How many scenes' images with the shadow ignored are beyond twice the p95 bar (those
    /// that can tell a lit penumbra), of every scene.
    telling: usize,
    /// How many scenes were beyond the bars but not held to them: their image is not
    /// determined by their occluders as f32 holds them (`check_scenes_wired`).
    undetermined: usize,
}

/// `check_scenes_counted` at `size`² pixels.
fn check_scenes_sized(
    scenes: &[SoftScene],
    bars: (f64, f64),
    size: u32,
    precision: ShaderPrecision,
) -> Checked {
    check_scenes_wired(scenes, bars, size, precision, false)
}

/// `check_scenes_sized`, with the nodes wired by hand instead of the facade when `by_hand`
/// (`volshadow_harness::by_hand`: for a light the facade would draw hard).
///
/// A scene beyond the bars, finite, is not held to them when its image is not determined by
/// its occluders as f32 holds them: when the reference of its boxes' corners rounded to f32
/// (`SoftScene::rounded_occluders`) is itself beyond the same bars against its reference. No
/// renderer handed f32 geometry can be within a bar that rounding alone exceeds. It is named,
/// with both figures, and left out of `worst` and `within`. Measured (2026-11-29): the doors
/// ajar behind thick plates nearly closed, 415 and 423 of the gap generator, move by p95
/// 35.2% and 204% (RMSE 60.8% and 343%); the other 46 of seeds 400–447 by at most p95 0.003%,
/// RMSE 0.002% (by hand).
fn check_scenes_wired(
    scenes: &[SoftScene],
    bars: (f64, f64),
    size: u32,
    precision: ShaderPrecision,
    by_hand: bool,
) -> Checked {
    let mut within = 0;
    let mut telling = 0;
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache_with(&gpu, precision);
    let mut hard_worst: f64 = 0.0;
    let mut unshadowed_least = f64::INFINITY;
    let mut worst: f64 = 0.0;
    let mut worst_rmse: f64 = 0.0;
    let mut failures = Vec::new();
    let mut undetermined = 0;
    for s in scenes {
        let wall = |e: DVec3, d: DVec3| wall_distance(s.wall, e, d);
        let reference = s.reference_image(size, &s.reference_occluders());
        let depths = volshadow_harness::depths_at(&s.camera, size, size, wall);
        let depth = volshadow_harness::depth_texture(&gpu, size, size, &depths);
        let meshes = sphere_meshes(&gpu, &s.spheres);
        let box_meshes = box_meshes(&gpu, &s.boxes);
        let other_meshes: Vec<OccluderMesh> = s
            .meshes
            .iter()
            .map(|m| OccluderMesh::new(&gpu.device, m))
            .collect();
        let mut occluders = in_place(&meshes);
        occluders.extend(in_place(&other_meshes));
        occluders.extend(placed(&box_meshes, &s.boxes));
        let settings = MarchSettings {
            method: MarchMethod::Exact,
            ..MarchSettings::default()
        };
        let render_with = |light: &Light, occluders: &[Occluder]| {
            let passes = volshadow_harness::ShadowPasses::new(
                &s.camera, light, &s.medium, &depth, occluders,
            )
            .settings(settings);
            let passes = match by_hand {
                true => passes.by_hand(1.0),
                false => passes,
            };
            volshadow_harness::shadow_frame(&gpu, &cache, &passes)
        };
        let render = |light: &Light| render_with(light, &occluders);
        let soft = s.light;
        let frame = render(&soft);
        let e = errors(&frame.inscatter, &reference, &s.camera, &soft, (size, size));
        let hard = without_radius(s.light);
        let hard_errors = errors(
            &render(&hard).inscatter,
            &reference,
            &s.camera,
            &soft,
            (size, size),
        );
        // The shadow ignored: what a march that lit the penumbra cones would give.
        let unshadowed = errors(
            &render_with(&soft, &[]).inscatter,
            &reference,
            &s.camera,
            &soft,
            (size, size),
        );
        hard_worst = hard_worst.max(hard_errors.p95);
        if unshadowed.p95 > 2.0 * P95_BAR {
            telling += 1;
        }
        if s.shows_shadow {
            unshadowed_least = unshadowed_least.min(unshadowed.p95);
        }
        eprintln!(
            "{}\n  grid: {e}\n  hard: p95 {:.2}%, shadow ignored: p95 {:.2}%",
            s.describe,
            100.0 * hard_errors.p95,
            100.0 * unshadowed.p95
        );
        let beyond = |e: &volshadow_harness::scene::Errors| !(e.rmse <= bars.0 && e.p95 <= bars.1);
        if e.non_finite == 0 && beyond(&e) {
            let moved = s.moved_by_rounding(size, &reference);
            eprintln!("  its reference with the boxes' corners rounded to f32: {moved}");
            if beyond(&moved) {
                eprintln!("  not held to the bars: not determined by its f32 occluders");
                undetermined += 1;
                continue;
            }
        }
        worst = worst.max(e.p95);
        worst_rmse = worst_rmse.max(e.rmse);
        if e.non_finite == 0 && e.rmse <= RMSE_BAR && e.p95 <= P95_BAR {
            within += 1;
        }
        if e.non_finite > 0 || beyond(&e) {
            failures.push(format!("{}: {e}", s.describe));
        }
    }
    let what = match scenes {
        [one] => one.describe.clone(),
        few if few.len() <= 3 => few
            .iter()
            .map(|s| s.describe.as_str())
            .collect::<Vec<_>>()
            .join("; "),
        _ => format!("{} seeded scenes", scenes.len()),
    };
    volshadow_harness::metric::accuracy(
        &format!(
            "{what}, {size}², {precision:?}: exact method through the soft-shadow grid against \
             reference::soft; the same drawn hard; the shadow ignored"
        ),
        format!(
            "worst p95 {:.2}%, worst RMSE {:.2}%, {within} of {} within p95 {}% and RMSE {}%; \
             hard worst p95 {:.1}%; ignored p95 ≥ {}{}",
            100.0 * worst,
            100.0 * worst_rmse,
            scenes.len() - undetermined,
            100.0 * P95_BAR,
            100.0 * RMSE_BAR,
            100.0 * hard_worst,
            if unshadowed_least.is_finite() {
                format!("{:.1}%", 100.0 * unshadowed_least)
            } else {
                "– (no shadow in view)".into()
            },
            match undetermined {
                0 => String::new(),
                n => format!("; {n} not determined by their f32 occluders, not held"),
            }
        ),
        format!(
            "every scene p95 {:.2}%, RMSE {:.2}%; ignored > {}%",
            100.0 * bars.1,
            100.0 * bars.0,
            200.0 * P95_BAR
        ),
    );
    assert!(
        failures.is_empty(),
        "failing seeds:\n{}",
        failures.join("\n")
    );
    // Against the issue's p95 bar: each scene must be able to tell a lit penumbra at it.
    assert!(
        unshadowed_least > 2.0 * P95_BAR,
        "a scene's shadow ignored is within {unshadowed_least} of its reference: it cannot tell"
    );
    Checked {
        worst,
        hard_worst,
        within,
        telling,
        undetermined,
    }
}

/// The meshes of a scene's spheres (centre, radius): 64 segments by 32 rings.
fn sphere_meshes(gpu: &volshadow::HeadlessGpu, spheres: &[(Vec3, f32)]) -> Vec<OccluderMesh> {
    spheres
        .iter()
        .map(|&(c, rho)| {
            OccluderMesh::new(&gpu.device, &shapes::uv_sphere(c, rho, 64, 32).unwrap())
        })
        .collect()
}

/// The meshes of a scene's boxes, each centred at the origin (placed by its occluder's
/// transform, so that the GPU path takes a rotated box as an app would).
fn box_meshes(gpu: &volshadow::HeadlessGpu, boxes: &[(Vec3, Vec3, Quat)]) -> Vec<OccluderMesh> {
    boxes
        .iter()
        .map(|&(_, half, _)| {
            OccluderMesh::new(&gpu.device, &shapes::cuboid(Vec3::ZERO, half).unwrap())
        })
        .collect()
}

/// The occluders of `box_meshes` (`box_meshes` of `boxes`) where `boxes` place them.
fn placed<'a>(meshes: &'a [OccluderMesh], boxes: &[(Vec3, Vec3, Quat)]) -> Vec<Occluder<'a>> {
    meshes
        .iter()
        .zip(boxes)
        .map(|(mesh, &(c, _, rotation))| Occluder {
            mesh,
            transform: glam::Mat4::from_rotation_translation(rotation, c),
        })
        .collect()
}

/// Occluders of `meshes` where they stand (identity transforms).
fn in_place(meshes: &[OccluderMesh]) -> Vec<Occluder<'_>> {
    meshes
        .iter()
        .map(|mesh| Occluder {
            mesh,
            transform: glam::Mat4::IDENTITY,
        })
        .collect()
}

fn sphere_occluder(gpu: &volshadow::HeadlessGpu, at: Vec3) -> OccluderMesh {
    OccluderMesh::new(&gpu.device, &shapes::uv_sphere(at, 0.5, 16, 8).unwrap())
}

/// `prepare` plans a rebuild when the shadow map re-renders (an occluder moved) and not
/// otherwise; a rebuild that were skipped would leave last frame's penumbra in the grid.
#[test]
fn the_grid_is_rebuilt_only_when_the_shadow_map_changes() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let light: Light = PointLight::new(Vec3::ZERO, Vec3::ONE)
        .unwrap()
        .with_radius(0.3)
        .unwrap()
        .into();
    let mut shadow = ShadowMapNode::new(&gpu.device, &cache, ShadowMapSettings::default()).unwrap();
    let mut soft = SoftShadowNode::new(&gpu.device, &cache, SoftShadowSize::default()).unwrap();
    let mesh = sphere_occluder(&gpu, Vec3::new(0.0, 0.0, 2.0));
    let mut frame = |transform: glam::Mat4| -> (bool, bool) {
        let occluders = [Occluder {
            mesh: &mesh,
            transform,
        }];
        let inputs = ShadowMapInputs {
            light: &light,
            occluders: &occluders,
            camera: &volshadow_harness::unread_camera(),
            fallback: None,
        };
        let rendered = shadow.prepare(&gpu.device, &gpu.queue, &inputs).unwrap();
        let rebuilt = soft
            .prepare(
                &gpu.device,
                &gpu.queue,
                &SoftShadowInputs {
                    light: &light,
                    shadow_map: shadow.shadow_map().unwrap(),
                },
            )
            .unwrap();
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        shadow.encode(&mut encoder, None).unwrap();
        soft.encode(&mut encoder, None).unwrap();
        gpu.submit_and_wait(encoder).unwrap();
        (rendered, rebuilt)
    };
    let still = glam::Mat4::IDENTITY;
    let moved = glam::Mat4::from_translation(Vec3::new(0.3, 0.0, 0.0));
    let steps = [frame(still), frame(still), frame(moved), frame(moved)];
    eprintln!("(shadow map rendered, grid rebuilt) per frame: {steps:?}");
    assert_eq!(
        steps,
        [(true, true), (false, false), (true, true), (false, false)]
    );
}

/// A light without a radius, a directional light, a shadow map of the wrong light, sizes out
/// of range and a grid too large to build on the device are typed errors naming the input.
#[test]
fn the_grid_rejects_what_it_cannot_use() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    for size in [
        SoftShadowSize {
            directions: 1,
            slices: 16,
        },
        SoftShadowSize {
            directions: 64,
            slices: SoftShadowSize::MAX_SLICES + 1,
        },
    ] {
        let e = SoftShadowNode::new(&gpu.device, &cache, size).err();
        assert!(
            matches!(e, Some(Error::InvalidSize { .. })),
            "{size:?}: {e:?}"
        );
    }
    let point: Light = PointLight::new(Vec3::ZERO, Vec3::ONE).unwrap().into();
    let mesh = sphere_occluder(&gpu, Vec3::new(0.0, 0.0, 2.0));
    let occluders = [Occluder {
        mesh: &mesh,
        transform: glam::Mat4::IDENTITY,
    }];
    let mut shadow = ShadowMapNode::new(&gpu.device, &cache, ShadowMapSettings::default()).unwrap();
    shadow
        .prepare(
            &gpu.device,
            &gpu.queue,
            &ShadowMapInputs {
                light: &point,
                occluders: &occluders,
                camera: &volshadow_harness::unread_camera(),
                fallback: None,
            },
        )
        .unwrap();
    let mut soft = SoftShadowNode::new(&gpu.device, &cache, SoftShadowSize::default()).unwrap();
    let spot: Light = SpotLight::new(Vec3::ZERO, Vec3::Z, 1.0, Vec3::ONE)
        .unwrap()
        .with_radius(0.2)
        .unwrap()
        .into();
    let sun: Light = DirectionalLight::new(-Vec3::Y, Vec3::ONE).unwrap().into();
    for (light, field) in [
        (point, "light"),
        (sun, "light"),
        (spot, "shadow_map"), // a cube map for a spot light
    ] {
        let e = soft
            .prepare(
                &gpu.device,
                &gpu.queue,
                &SoftShadowInputs {
                    light: &light,
                    shadow_map: shadow.shadow_map().unwrap(),
                },
            )
            .err();
        eprintln!("{e:?}");
        let named = match &e {
            Some(Error::InvalidSetting { field: f, .. })
            | Some(Error::InvalidTexture { field: f, .. }) => *f,
            _ => "",
        };
        assert_eq!(named, field, "{e:?}");
    }
    // A back-face layer that is not the map's size.
    let soft_point: Light = PointLight::new(Vec3::ZERO, Vec3::ONE)
        .unwrap()
        .with_radius(0.2)
        .unwrap()
        .into();
    let small = gpu
        .device
        .create_texture(&volshadow::wgpu::TextureDescriptor {
            label: None,
            size: volshadow::wgpu::Extent3d {
                width: 64,
                height: 64,
                depth_or_array_layers: 6,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: volshadow::wgpu::TextureDimension::D2,
            format: volshadow::wgpu::TextureFormat::Depth32Float,
            usage: volshadow::wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
    // The error of a prepare with `map` for the soft point light.
    fn prepare_error(
        gpu: &volshadow::HeadlessGpu,
        soft: &mut SoftShadowNode,
        light: &Light,
        shadow_map: ShadowMap<'_>,
    ) -> Option<Error> {
        let inputs = SoftShadowInputs { light, shadow_map };
        soft.prepare(&gpu.device, &gpu.queue, &inputs).err()
    }
    let map = ShadowMap {
        back: Some(&small),
        ..shadow.shadow_map().unwrap()
    };
    let e = prepare_error(&gpu, &mut soft, &soft_point, map);
    eprintln!("{e:?}");
    assert!(
        matches!(
            e,
            Some(Error::InvalidTexture {
                field: "shadow_map.back",
                ..
            })
        ),
        "{e:?}"
    );
    // The occluders' triangles: a buffer the shaders cannot bind as whole groups of four, or
    // one of more than MAX_EXACT_TRIANGLES, is named, not a validation error behind `Ok`.
    let buffer = |size, usage| {
        gpu.device
            .create_buffer(&volshadow::wgpu::BufferDescriptor {
                label: None,
                size,
                usage,
                mapped_at_creation: false,
            })
    };
    let storage = volshadow::wgpu::BufferUsages::STORAGE;
    let max_bytes = u64::from(volshadow::nodes::MAX_EXACT_TRIANGLES) / 4 * 256;
    for (bytes, usage, want) in [
        (256, volshadow::wgpu::BufferUsages::UNIFORM, "lacks STORAGE"),
        (200, storage, "not whole groups"),
        (max_bytes + 256, storage, "more than"),
    ] {
        let triangles = buffer(bytes, usage);
        let map = ShadowMap {
            triangles: Some(&triangles),
            ..shadow.shadow_map().unwrap()
        };
        let e = prepare_error(&gpu, &mut soft, &soft_point, map);
        assert!(
            matches!(
                &e,
                Some(Error::InvalidBuffer {
                    field: "shadow_map.triangles",
                    problem,
                }) if problem.contains(want)
            ),
            "{bytes} bytes, {usage:?}: {e:?}"
        );
    }
    // Nothing recorded before a successful prepare.
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    assert!(matches!(
        soft.encode(&mut encoder, None),
        Err(Error::NotPrepared { .. })
    ));
    // The largest grid (2048² directions × 64 slices × 6 layers, 1.6e9 cells): its build's
    // list of cells to estimate is beyond the device's storage buffers, an error at prepare
    // (before anything is allocated) naming the buffer and the limit, as for every buffer
    // beyond a device limit (it was `InvalidSetting` naming `soft shadow size`).
    let mut huge = SoftShadowNode::new(
        &gpu.device,
        &cache,
        SoftShadowSize {
            directions: SoftShadowSize::MAX_DIRECTIONS,
            slices: SoftShadowSize::MAX_SLICES,
        },
    )
    .unwrap();
    let e = huge
        .prepare(
            &gpu.device,
            &gpu.queue,
            &SoftShadowInputs {
                light: &soft_point,
                shadow_map: shadow.shadow_map().unwrap(),
            },
        )
        .err();
    eprintln!("{e:?}");
    assert!(
        matches!(
            e,
            Some(Error::DeviceLimitExceeded {
                field: "soft shadow list",
                limit: "max_storage_buffer_binding_size",
                needed,
                max,
            }) if needed == 4 * (2048 * 2048 - 1024 * 1024) * 64 * 6 && needed > max
        ),
        "{e:?}"
    );
}

/// A ground (an open plane, 60 × 60) under a light of radius 0.3, 3 above it, with a sphere
/// between them: the ground's bounding sphere holds the light, so its penumbra cone is all of
/// space, and every ray would be marched through the grid. Its separating plane
/// (`ShadowMap::planes`) keeps the march to the sphere's cone above the ground: the same
/// pixels are marched with the ground as without it. Measured (exact method, 48²): 428 of
/// 2304 pixels either way; without the planes, 2304 with the ground (170707 steps against
/// 26991).
#[test]
fn a_ground_adds_no_march_above_it() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let light: Light = PointLight::new(Vec3::new(0.0, 3.0, 0.0), Vec3::splat(4.0))
        .unwrap()
        .with_radius(0.3)
        .unwrap()
        .into();
    let medium = Medium::new(
        Vec3::splat(0.08),
        Vec3::splat(0.02),
        PhaseFunction::Isotropic,
    )
    .unwrap();
    let eye = Vec3::new(0.0, 1.0, 6.0);
    let view = look_at_mat4(eye, Vec3::new(0.0, 1.0, 0.0), Vec3::Y);
    let camera = Camera::new(view, directx::perspective(1.2, 1.0, 1e-2, 1e3)).unwrap();
    // Rays end on the ground (y = 0) or on a wall at z = −10.
    let depths = volshadow_harness::depths_at(&camera, SIZE, SIZE, |o, d| {
        let ground = if d.y < 0.0 { -o.y / d.y } else { f64::INFINITY };
        let wall = if d.z < 0.0 {
            (-10.0 - o.z) / d.z
        } else {
            f64::INFINITY
        };
        ground.min(wall)
    });
    let depth = volshadow_harness::depth_texture(&gpu, SIZE, SIZE, &depths);
    let sphere = OccluderMesh::new(
        &gpu.device,
        &shapes::uv_sphere(Vec3::new(0.0, 1.6, 0.0), 0.4, 32, 16).unwrap(),
    );
    let ground = OccluderMesh::new(
        &gpu.device,
        &shapes::plane(Vec3::ZERO, glam::Vec2::splat(30.0)).unwrap(),
    );
    let settings = MarchSettings {
        method: MarchMethod::Exact,
        ..MarchSettings::default()
    };
    // Pixels whose ray is marched (steps > 0), and all the steps.
    let marched = |meshes: &[&OccluderMesh]| -> (usize, u64) {
        let occluders: Vec<Occluder> = meshes
            .iter()
            .map(|&mesh| Occluder {
                mesh,
                transform: glam::Mat4::IDENTITY,
            })
            .collect();
        let passes =
            volshadow_harness::ShadowPasses::new(&camera, &light, &medium, &depth, &occluders)
                .settings(settings);
        let frame = volshadow_harness::shadow_frame(&gpu, &cache, &passes);
        (
            frame.steps.iter().filter(|&&s| s > 0).count(),
            frame.steps.iter().map(|&s| u64::from(s)).sum(),
        )
    };
    let alone = marched(&[&sphere]);
    let with_ground = marched(&[&sphere, &ground]);
    eprintln!(
        "marched pixels (steps): sphere alone {} ({}), with the ground {} ({}), of {}",
        alone.0,
        alone.1,
        with_ground.0,
        with_ground.1,
        SIZE * SIZE
    );
    volshadow_harness::metric::performance(
        "a ground under a soft light and a sphere, 48², exact: pixels whose ray is marched (steps), sphere alone / with the ground",
        format!(
            "{} ({}) / {} ({}) of {}",
            alone.0,
            alone.1,
            with_ground.0,
            with_ground.1,
            SIZE * SIZE
        ),
        "the same pixels with the ground as without",
    );
    assert!(alone.0 > 0, "the sphere's penumbra is in view");
    assert!(
        with_ground.0 == alone.0,
        "the ground added marched pixels above it: {} against {}",
        with_ground.0,
        alone.0
    );
}

/// `umbra_scene` with the light's radius set to `radius` (the sphere's near side is 1.4 from
/// the light's centre).
fn extreme_scene(radius: f32, eye: Vec3, target: Vec3, describe: &str) -> SoftScene {
    let mut s = umbra_scene(eye, target, describe);
    let Light::Point(point) = s.light else {
        unreachable!("umbra_scene makes a point light")
    };
    s.light = point.with_radius(radius).unwrap().into();
    s
}

/// Extreme soft lights, through the grid (exact method): every output finite, each scene
/// within its bar against the soft reference. A light nearly as large as its distance to the
/// occluder is beyond PCSS's one-planar-blocker assumption: bars of 6% (radius 1.39 against a
/// gap of 1.4: measured p95 4.7%, RMSE 4.8%) and 10% (radius 2, the occluder half
/// inside the light's sphere: p95 9.13%, RMSE 9.65%; 8.1% and 8.1% before the soft shadow's
/// nearest distance was floored at the light's radius, which narrows the blocker search
/// there), measured limits, a known limitation (see
/// the `SoftShadowNode` docs). The eye inside the light's sphere: the issue's bars (p95 0.04%;
/// its view is lit mostly near the light, so the shadow barely shows there). The eye between
/// the light and the sphere, 0.1 in front of it, looking through it along the umbra: p95 5%,
/// RMSE 3.5%, measured limits (p95 3.9%, RMSE 2.9%) beyond the issue's bars. Hard shadows
/// are beyond 10% of the soft reference in each of the first two, so the bars can tell. A
/// light of radius 1e-5: the issue's bars, with hard shadows nearer the reference.
#[test]
fn extreme_soft_lights_stay_finite_and_bounded() {
    let across = |radius: f32, eye_x: f32, describe: &str| {
        extreme_scene(
            radius,
            Vec3::new(eye_x, 0.0, 4.0),
            Vec3::new(0.0, 0.0, 4.0),
            describe,
        )
    };
    let (worst, hard) = check_scenes(
        &[across(
            1.39,
            3.0,
            "radius 1.39, nearly touching the occluder",
        )],
        (0.06, 0.06),
    );
    assert!(hard > 0.10, "hard within {hard} of the soft reference");
    eprintln!("nearly touching: p95 {:.2}%", 100.0 * worst);
    let (worst, hard) = check_scenes(
        &[across(
            2.0,
            4.0,
            "radius 2, the occluder half inside the light's sphere",
        )],
        (0.10, 0.10),
    );
    assert!(hard > 0.10, "hard within {hard} of the soft reference");
    eprintln!("half inside: p95 {:.2}%", 100.0 * worst);
    // A tiny light through the grid (the nodes wired by hand, as a caller might use them; the
    // facade draws it hard, see `ShadowMapNode::penumbra_below_texel`): within the issue's
    // bars, and the hard image nearer the soft reference than the grid's (measured 0.21%
    // against 1.81%).
    let tiny = across(1e-5, 2.0, "radius 1e-5, a penumbra far below a texel");
    let bars = (RMSE_BAR, P95_BAR);
    let Checked {
        worst,
        hard_worst: hard,
        ..
    } = check_scenes_wired(&[tiny], bars, SIZE, ShaderPrecision::Native, true);
    eprintln!(
        "radius 1e-5: p95 {:.2}% through the grid, {:.2}% hard",
        100.0 * worst,
        100.0 * hard
    );
    assert!(hard < worst, "hard {hard} not nearer than the grid {worst}");
    let mut inside = extreme_scene(
        0.3,
        Vec3::new(0.1, 0.05, 0.0),
        Vec3::new(0.0, 0.0, 4.0),
        "eye inside the light's sphere",
    );
    inside.shows_shadow = false;
    let (worst, _) = check_scenes(&[inside], (RMSE_BAR, P95_BAR));
    eprintln!("eye inside the light: p95 {:.2}%", 100.0 * worst);
    let (worst, _) = check_scenes(
        &[extreme_scene(
            0.3,
            Vec3::new(0.0, 0.02, 1.3),
            Vec3::new(0.0, 0.0, 4.0),
            "eye 0.1 in front of the occluder, looking through it",
        )],
        (0.035, 0.05),
    );
    eprintln!("eye in front of the occluder: p95 {:.2}%", 100.0 * worst);
}

/// The grid's cells themselves against the reference's exact visible fraction at each cell's
/// point (spherical-cap overlap), on the seeded scenes of `random_soft_scenes_against_the_reference`
/// (the grid does not depend on the medium): the estimate and the adaptive build, apart from
/// the march that reads them, whose integration along a ray averages a cell's error with its
/// neighbours'. In the penumbra (reference fraction 0.02 to 0.98): the mean and 95th
/// percentile of |error|, and the mean signed error (the estimate's bias); outside it (lit or
/// umbra), the share of cells off by more than 0.1.
///
/// Bars: measured limits (mean |error| 0.0198, p95 0.0512, mean error +0.0113;
/// deep penumbra mean relative error −0.026, mean |relative error| 0.175; 0.0087% of the
/// others off), each between the code and a plausibly broken variant measured by hand with the
/// same seeds: the blockers' distance at the chord's midpoint (deep −0.124, the deep penumbra
/// too dark), at the geometric mean of the front and back distances
/// (deep +0.264), at the front surface alone (0.0302, p95 0.0886, deep +1.101, 0.0333% off);
/// no extra taps in the deep penumbra (deep |relative error| 0.249); 16 filter taps instead of
/// 32 (0.0257, p95 0.0666). With 128 filter taps: 0.0156, p95 0.0444, deep −0.012 and 0.153.
#[test]
fn grid_cells_against_the_reference_visible_fraction() {
    const MEAN_BAR: f64 = 0.025;
    const P95_CELL_BAR: f64 = 0.065;
    const DEEP_BIAS_BAR: f64 = 0.06;
    const DEEP_ABS_BAR: f64 = 0.21;
    const OFF_BAR: f64 = 0.0002;
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let size = SoftShadowSize::default();
    let mut shadow = ShadowMapNode::new(
        &gpu.device,
        &cache,
        ShadowMapSettings {
            resolution: 1024,
            ..Default::default()
        },
    )
    .unwrap();
    let mut soft = SoftShadowNode::new(&gpu.device, &cache, size).unwrap();
    let (n, slices) = (size.directions as usize, size.slices as usize);
    let mut penumbra_errors = Vec::new();
    let (mut outside, mut outside_off) = (0usize, 0usize);
    // The deep penumbra (reference fraction 0.02 to 0.2): Σ error / fraction, Σ |…|, count.
    let (mut deep_bias, mut deep_abs, mut deep) = (0.0, 0.0, 0usize);
    let mut all_bias = 0.0;
    for seed in 0..SEEDS {
        let s = random_scene(seed, (-4.0, 0.0));
        let meshes = sphere_meshes(&gpu, &s.spheres);
        let occluders = in_place(&meshes);
        let inputs = ShadowMapInputs {
            light: &s.light,
            occluders: &occluders,
            camera: &volshadow_harness::unread_camera(),
            fallback: None,
        };
        shadow.prepare(&gpu.device, &gpu.queue, &inputs).unwrap();
        let map = shadow.shadow_map().unwrap();
        soft.prepare(
            &gpu.device,
            &gpu.queue,
            &SoftShadowInputs {
                light: &s.light,
                shadow_map: map,
            },
        )
        .unwrap();
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        shadow.encode(&mut encoder, None).unwrap();
        soft.encode(&mut encoder, None).unwrap();
        gpu.submit_and_wait(encoder).unwrap();
        let map = shadow.shadow_map().unwrap();
        let cells: Vec<half::f16> = bytemuck::pod_collect_to_vec(
            &gpu.read_all_layers_bytes(soft.output().unwrap().texture)
                .unwrap(),
        );
        let light = s.light.position().unwrap();
        let radius = s.light.radius();
        // Where the node put its slices.
        let nearest = soft.output().unwrap().near;
        let occ = s.reference_occluders();
        let (mut sum, mut count, mut bias) = (0.0, 0usize, 0.0);
        for (layer, face) in map.faces.iter().enumerate() {
            let world_from_clip = face.inverse();
            for y in 0..n {
                for x in 0..n {
                    // The cell's direction and its slices' points, as the node places them.
                    let uv = (glam::Vec2::new(x as f32, y as f32) + 0.5) / n as f32;
                    let w = world_from_clip
                        * glam::Vec4::new(2.0 * uv.x - 1.0, 1.0 - 2.0 * uv.y, 0.5, 1.0);
                    let dir = (w.truncate() / w.w - light).normalize().as_dvec3();
                    for k in 0..slices {
                        let q = 1.0 - (k as f64 + 0.5) / slices as f64;
                        let point = light.as_dvec3() + dir * (f64::from(nearest) / q);
                        let want = reference::soft::visible_fraction(
                            point,
                            light.as_dvec3(),
                            f64::from(radius),
                            &occ,
                        );
                        let got = f64::from(cells[(((layer * slices + k) * n + y) * n + x) * 4]);
                        let e = got - want;
                        if (0.02..=0.2).contains(&want) {
                            deep_bias += e / want;
                            deep_abs += e.abs() / want;
                            deep += 1;
                        }
                        if (0.02..=0.98).contains(&want) {
                            all_bias += e;
                            penumbra_errors.push(e.abs());
                            sum += e.abs();
                            bias += e;
                            count += 1;
                        } else {
                            outside += 1;
                            outside_off += usize::from(e.abs() > 0.1);
                        }
                    }
                }
            }
        }
        eprintln!(
            "{}\n  {count} penumbra cells: mean |error| {:.4}, mean error {:+.4}",
            s.describe,
            sum / count.max(1) as f64,
            bias / count.max(1) as f64
        );
    }
    penumbra_errors.sort_by(f64::total_cmp);
    let mean = penumbra_errors.iter().sum::<f64>() / penumbra_errors.len() as f64;
    let p95 = penumbra_errors[(penumbra_errors.len() as f64 * 0.95) as usize];
    let off = outside_off as f64 / outside as f64;
    let (deep_bias, deep_abs) = (deep_bias / deep as f64, deep_abs / deep as f64);
    eprintln!(
        "{} penumbra cells: mean |error| {mean:.4}, p95 {p95:.4}, mean error {:+.4}; deep penumbra ({deep} cells, fraction 0.02 to 0.2): mean relative error {deep_bias:+.3}, mean |relative error| {deep_abs:.3}; {outside} others, {:.4}% off by > 0.1",
        penumbra_errors.len(),
        all_bias / penumbra_errors.len() as f64,
        100.0 * off
    );
    volshadow_harness::metric::accuracy(
        "the grid's cells against the reference's visible fraction, 12 seeded scenes: penumbra mean |error|, p95, bias; deep penumbra mean relative error, mean |relative error|; other cells off by > 0.1",
        format!(
            "{mean:.4}, {p95:.4}, {:+.4}; {deep_bias:+.3}, {deep_abs:.3}; {:.4}%",
            all_bias / penumbra_errors.len() as f64,
            100.0 * off
        ),
        format!(
            "{MEAN_BAR}, {P95_CELL_BAR}; ±{DEEP_BIAS_BAR}, {DEEP_ABS_BAR}; {}% (measured limits)",
            100.0 * OFF_BAR
        ),
    );
    assert!(
        mean <= MEAN_BAR && p95 <= P95_CELL_BAR,
        "penumbra cells: mean |error| {mean:.4} (bar {MEAN_BAR}), p95 {p95:.4} (bar {P95_CELL_BAR})"
    );
    assert!(
        deep_bias.abs() <= DEEP_BIAS_BAR && deep_abs <= DEEP_ABS_BAR,
        "deep penumbra: mean relative error {deep_bias:+.3} (bar ±{DEEP_BIAS_BAR}), mean |relative error| {deep_abs:.3} (bar {DEEP_ABS_BAR})"
    );
    assert!(
        off <= OFF_BAR,
        "{:.4}% of the lit and umbra cells off by more than 0.1 (bar {:.4}%)",
        100.0 * off,
        100.0 * OFF_BAR
    );
}

/// The node builds only the directions the penumbra cones reach (and their neighbours), and
/// sets lit those the last build shadowed: its grid must be the whole build's, bit for bit,
/// frame after frame. One node is kept over a run of seeded scenes (point lights, spots,
/// boxes: occluders and lights in other places each frame, so last frame's shadow lies
/// elsewhere), against a node that builds every direction. Without the lit fill, 271 360
/// cells of the first frame differ (a new grid starts at 0). The blocks' bounds themselves
/// are checked direction by direction in the node's unit tests, which a cone without its
/// margin, a cap 10% narrower or blocks without the neighbours' cells fail (this test has
/// room to spare for the last two). Two gap scenes mark shafts (`mark_shafts`, over the cells
/// this build may change), with a sphere between them that does not: the marked copy must be
/// the whole build's too. (The copy's rebuild when marks resume is not told apart here: the
/// plates' blocks reach over the layers, and the copy is the whole build's without it.)
#[test]
fn the_grid_built_where_the_cones_reach_is_the_whole_build() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let size = SoftShadowSize::default();
    let mut shadow = ShadowMapNode::new(&gpu.device, &cache, ShadowMapSettings::default()).unwrap();
    let mut kept = SoftShadowNode::new(&gpu.device, &cache, size).unwrap();
    let mut every = SoftShadowNode::new(&gpu.device, &cache, size).unwrap();
    every.set_every_block(true);
    let scenes = (0..6)
        .map(|seed| random_scene(300 + seed, (-4.0, 0.0)))
        .chain((0..4).map(|seed| random_spot_scene(310 + seed, (-4.0, 0.0), (0.52, 2.0))))
        .chain((0..3).map(|seed| random_box_scene(320 + seed, (-4.0, 0.0))))
        .chain([
            random_gap_scene(402),
            random_scene(306, (-4.0, 0.0)),
            random_gap_scene(403),
        ]);
    let mut marked_frames = 0;
    for (frame, s) in scenes.enumerate() {
        let meshes: Vec<OccluderMesh> = sphere_meshes(&gpu, &s.spheres)
            .into_iter()
            .chain(box_meshes(&gpu, &s.boxes))
            .collect();
        let occluders = in_place(&meshes);
        let inputs = ShadowMapInputs {
            light: &s.light,
            occluders: &occluders,
            camera: &volshadow_harness::unread_camera(),
            fallback: None,
        };
        shadow.prepare(&gpu.device, &gpu.queue, &inputs).unwrap();
        let map = shadow.shadow_map().unwrap();
        let soft_inputs = SoftShadowInputs {
            light: &s.light,
            shadow_map: map,
        };
        assert!(kept.prepare(&gpu.device, &gpu.queue, &soft_inputs).unwrap());
        every
            .prepare(&gpu.device, &gpu.queue, &soft_inputs)
            .unwrap();
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        shadow.encode(&mut encoder, None).unwrap();
        kept.encode(&mut encoder, None).unwrap();
        every.encode(&mut encoder, None).unwrap();
        gpu.submit_and_wait(encoder).unwrap();
        let read = |node: &SoftShadowNode| -> Vec<half::f16> {
            bytemuck::pod_collect_to_vec(
                &gpu.read_all_layers_bytes(node.output().unwrap().texture)
                    .unwrap(),
            )
        };
        let (a, b) = (read(&kept), read(&every));
        let differ = a
            .chunks_exact(4)
            .zip(b.chunks_exact(4))
            .filter(|(x, y)| {
                x.iter()
                    .map(|h| h.to_bits())
                    .ne(y.iter().map(|h| h.to_bits()))
            })
            .count();
        let shadowed = b.chunks_exact(4).filter(|c| c[0].to_f32() < 1.0).count();
        let marked = b.chunks_exact(4).filter(|c| c[3].to_f32() > 0.0).count();
        marked_frames += usize::from(marked > 0);
        eprintln!(
            "frame {frame} ({}): {shadowed} cells not lit, {marked} marked near a shaft, {differ} differ",
            s.describe
        );
        assert!(
            shadowed > 0,
            "frame {frame}: no shadow in the grid, nothing tested"
        );
        assert_eq!(
            differ, 0,
            "frame {frame} ({}): cells differ from the whole build",
            s.describe
        );
    }
    assert!(
        marked_frames > 0,
        "no frame marked a shaft: the marks' pass is not tested"
    );
}

// ---------------------------------------------------------------------------------------------
// Gaps narrower than the light (issue 34): a slit, blinds, a hole in a plate, a door ajar.

/// The kinds of gap `random_gap_scene` draws, in turn by seed.
const GAP_KINDS: [&str; 4] = ["slit", "blinds", "hole", "door ajar"];

/// A seeded gap scene: a light of radius R at distance b from a plate (thin or thick) with a
/// gap narrower or wider than the light (0.2 to 1.5 times its diameter), the kind by seed
/// (`GAP_KINDS`): a slit across the whole plate; blinds, 1 to 8 slats tilted up to 60°
/// across an opening; a square hole; a door ajar, turned on its hinge until its free edge
/// leaves the gap. The plate reaches 8 b from the gap's axis, so that no light passes around
/// it within the view. A point or spot light (aimed through the gap, its cone within the
/// plate); the eye beyond the plate, outside the shaft or inside it, or on the light's side
/// looking through the gap (the depth is a plane behind the shaft: rays cross the plate, as
/// the reference's do). All of it turned and moved at random and scaled by a log-uniform unit
/// from 1e-2 to 1e5, σt·b log-uniform over 1e-3 to 1.
fn random_gap_scene(seed: u64) -> SoftScene {
    let mut rng = fastrand::Rng::with_seed(seed ^ 0x6a95_0001);
    let mut uniform = |lo: f32, hi: f32| lo + (hi - lo) * rng.f32();
    let kind = (seed % GAP_KINDS.len() as u64) as usize;
    let unit = 10f32.powf(uniform(-2.0, 5.0));
    // Local frame: the light at the origin, the plate's near face at z = b, the gap around
    // the z axis; lengths in units of `unit`, placed by `place` at the end.
    let b = uniform(1.0, 4.0);
    let radius = b * uniform(0.05, 0.3);
    let ratio = uniform(0.2, 1.5);
    let gap = ratio * 2.0 * radius;
    let thick = uniform(0.0, 1.0) < 0.5;
    let thickness = if thick {
        gap * uniform(0.3, 1.0)
    } else {
        gap * uniform(0.02, 0.08)
    };
    let zc = b + 0.5 * thickness;
    let t = 0.5 * thickness;
    // Boxes as (centre, half extents, rotation), local.
    let mut boxes: Vec<(Vec3, Vec3, Quat)> = Vec::new();
    // A box over [x0, x1] × [y0, y1] of the plate.
    // The plate reaches 8 b beyond the opening's half extent `open`.
    let reach = |open: f32| 8.0 * b + open;
    let slab = |x0: f32, x1: f32, y0: f32, y1: f32| {
        (
            Vec3::new(0.5 * (x0 + x1), 0.5 * (y0 + y1), zc),
            Vec3::new(0.5 * (x1 - x0), 0.5 * (y1 - y0), t),
            Quat::IDENTITY,
        )
    };
    // The opening's half extents in x and y (where the light reaches through).
    let describe_kind;
    // Where the gap's middle lies across the plate (the door's at its free edge).
    let mut gap_x = 0.0;
    match GAP_KINDS[kind] {
        "slit" => {
            let r = reach(0.5 * gap);
            boxes.push(slab(-r, -0.5 * gap, -r, r));
            boxes.push(slab(0.5 * gap, r, -r, r));
            describe_kind = format!("slit {:.2} of the light's diameter", ratio);
        }
        "blinds" => {
            // n slats of height h with gaps `gap` between them and the opening's edges, each
            // turned by `tilt` about its long axis (x).
            let n = (uniform(1.0, 9.0) as u32).min(8);
            let h = (gap * uniform(0.5, 2.0)).min(0.6 * b);
            let tilt = uniform(0.0, 60f32.to_radians());
            let half_y = 0.5 * (n as f32 * h + (n + 1) as f32 * gap);
            let half_x = half_y.max(2.0 * radius) * uniform(1.0, 2.0);
            let r = reach(half_x.max(half_y));
            boxes.push(slab(-r, -half_x, -r, r));
            boxes.push(slab(half_x, r, -r, r));
            boxes.push(slab(-half_x, half_x, half_y, r));
            boxes.push(slab(-half_x, half_x, -r, -half_y));
            for i in 0..n {
                let y = -half_y + (i + 1) as f32 * gap + (i as f32 + 0.5) * h;
                boxes.push((
                    Vec3::new(0.0, y, zc),
                    Vec3::new(half_x, 0.5 * h, t.min(0.25 * h)),
                    Quat::from_rotation_x(tilt),
                ));
            }
            describe_kind = format!(
                "blinds of {n} slats {:.2} high, gaps {:.2} of the light's diameter, tilt {:.0} deg",
                h / (2.0 * radius),
                ratio,
                tilt.to_degrees()
            );
        }
        "hole" => {
            let a = 0.5 * gap;
            let r = reach(a);
            boxes.push(slab(-r, -a, -r, r));
            boxes.push(slab(a, r, -r, r));
            boxes.push(slab(-a, a, a, r));
            boxes.push(slab(-a, a, -r, -a));
            describe_kind = format!("square hole {:.2} of the light's diameter", ratio);
        }
        _ => {
            // A door of width w and height 2·hh in an opening of the same size, hinged at
            // x = −w/2 on the far face, turned away from the light until its free edge leaves
            // a gap of `gap` (measured across the opening).
            let w = b * uniform(0.3, 0.8);
            let hh = w * uniform(1.0, 2.0);
            let turn = (gap / w).clamp(0.0, 0.9).asin();
            let r = reach(hh.max(0.5 * w));
            boxes.push(slab(-r, -0.5 * w, -r, r));
            boxes.push(slab(0.5 * w, r, -r, r));
            boxes.push(slab(-0.5 * w, 0.5 * w, hh, r));
            boxes.push(slab(-0.5 * w, 0.5 * w, -r, -hh));
            let hinge = Vec3::new(-0.5 * w, 0.0, b + thickness);
            let rotation = Quat::from_rotation_y(-turn);
            let centre = hinge + rotation * Vec3::new(0.5 * w, 0.0, -t);
            boxes.push((centre, Vec3::new(0.5 * w, hh, t), rotation));
            gap_x = 0.5 * w * turn.cos();
            describe_kind = format!(
                "door ajar by {:.1} deg, gap {:.2} of the light's diameter",
                turn.to_degrees(),
                ratio
            );
        }
    }
    // How far the boxes reach along z, towards the light and away from it (tilted slats and
    // the door stand out of the plate): the eye stays out of them.
    let z_extent = |&(c, half, r): &(Vec3, Vec3, Quat)| {
        let m = glam::Mat3::from_quat(r);
        let reach_z = (0..3).map(|i| m.col(i).z.abs() * half[i]).sum::<f32>();
        (c.z - reach_z, c.z + reach_z)
    };
    let near_z = boxes
        .iter()
        .map(|b| z_extent(b).0)
        .fold(f32::INFINITY, f32::min);
    let far_z = boxes
        .iter()
        .map(|b| z_extent(b).1)
        .fold(f32::NEG_INFINITY, f32::max);
    // The eye: beyond the plate outside the shaft looking across it, inside the shaft, or on
    // the light's side looking through the gap.
    let target = Vec3::new(gap_x, 0.0, far_z + b * uniform(0.2, 2.0));
    let side_angle = uniform(0.0, std::f32::consts::TAU);
    let side = Vec3::new(side_angle.cos(), side_angle.sin(), 0.0);
    let place_eye = (uniform(0.0, 3.0) as u32).min(2);
    let (eye, where_eye) = match place_eye {
        0 => (
            target + side * b * uniform(1.0, 3.0) + Vec3::Z * b * uniform(-0.2, 0.5),
            "beyond the plate, beside the shaft",
        ),
        1 => (
            Vec3::new(gap_x, 0.0, far_z + b * uniform(0.05, 0.3)) + side * 0.1 * gap,
            "in the shaft just beyond the gap",
        ),
        _ => {
            let lo = (1.2 * radius).max(0.2 * b);
            let z = lo + (near_z - 0.05 * b - lo) * uniform(0.3, 0.9);
            (
                Vec3::new(gap_x, 0.0, z) + side * b * uniform(0.3, 1.0),
                "on the light's side, looking through the gap",
            )
        }
    };
    let eye = if place_eye == 0 {
        // Beyond every box.
        Vec3::new(eye.x, eye.y, eye.z.max(far_z + 0.05 * b))
    } else {
        eye
    };
    let target = if place_eye == 1 {
        // In the shaft, looking along it with a tilt.
        Vec3::new(gap_x, 0.0, far_z + 3.0 * b) + side * b * uniform(0.0, 1.5)
    } else {
        target
    };
    // Turned, moved and scaled.
    let turn = Quat::from_euler(
        glam::EulerRot::XYZ,
        uniform(0.0, std::f32::consts::TAU),
        uniform(0.0, std::f32::consts::TAU),
        uniform(0.0, std::f32::consts::TAU),
    );
    let shift = Vec3::new(uniform(-5.0, 5.0), uniform(-5.0, 5.0), uniform(-5.0, 5.0));
    let place = |p: Vec3| unit * (turn * p + shift);
    let tau = 10f32.powf(uniform(-3.0, 0.0));
    let sigma_t = tau / (b * unit);
    let albedo = uniform(0.3, 0.95);
    let g = uniform(-0.5, 0.8);
    let position = place(Vec3::ZERO);
    let spot = uniform(0.0, 1.0) < 0.5;
    let light: Light = if spot {
        // Aimed at the gap, wide enough for the gap and its penumbra, its cone within the plate.
        let apex = uniform(40f32.to_radians(), 120f32.to_radians());
        let aim = turn * Vec3::Z;
        SpotLight::new(position, aim, apex, Vec3::splat(unit * unit))
            .unwrap()
            .with_radius(unit * radius)
            .unwrap()
            .into()
    } else {
        PointLight::new(position, Vec3::splat(unit * unit))
            .unwrap()
            .with_radius(unit * radius)
            .unwrap()
            .into()
    };
    let (eye, target) = (place(eye), place(target));
    let up_hint = turn * Vec3::Y;
    let up = if (target - eye).normalize().cross(up_hint).length_squared() > 1e-4 {
        up_hint
    } else {
        turn * Vec3::X
    };
    let view = look_at_mat4(eye, target, up);
    let fov = uniform(0.6, 1.2);
    let camera = Camera::new(
        view,
        directx::perspective(fov, 1.0, 1e-3 * b * unit, 1e4 * b * unit),
    )
    .unwrap();
    let to_eye = (eye - target).normalize().as_dvec3();
    let wall_point = target.as_dvec3() - to_eye * f64::from(b * unit * uniform(1.0, 3.0));
    let boxes = boxes
        .into_iter()
        .map(|(c, half, r)| (place(c), unit * half, turn * r))
        .collect();
    SoftScene {
        camera,
        medium: grey_medium(sigma_t, albedo, g),
        light,
        spheres: Vec::new(),
        boxes,
        meshes: Vec::new(),
        wall: (wall_point, to_eye),
        describe: format!(
            "gap seed {seed}: {describe_kind}, {} plate ({:.2} of the gap), {} light, R/b {:.3}, \
             eye {where_eye}, unit {unit:.3e}, sigma_t b {tau:.2e}, g {g:.2}",
            if thick { "thick" } else { "thin" },
            thickness / gap,
            if spot { "spot" } else { "point" },
            radius / b
        ),
        shows_shadow: true,
    }
}

/// Gap scenes' image side (the reference takes the light's disc by rows against every
/// triangle of the plate's boxes: up to about a minute a scene at 12² in the suite's build, on
/// lavapipe's machine).
const GAP_SIZE: u32 = 12;

/// One seed of each kind of gap (`random_gap_scene`) at the defaults (exact method through
/// the grid, the occluders' triangles given: `soft_exact`) against `reference::soft`: finite,
/// within the issue's bars (p95 3%, RMSE 2%), and with its shadow ignored beyond twice the p95
/// bar. Measured (lavapipe, 12², 2026-11-29): seed 400, a slit 0.66 of the light's diameter
/// seen from beside its shaft, p95 0.44%, RMSE 0.38%; blinds under a spot light (401) 0.41%,
/// 0.25%; a square hole (402) 0.98%, 0.64%; a door ajar (403) 2.03%, 0.56%. Broken variants
/// (against the reference's former 16 × 16 directions, within 0.1% of its rows on 400 and 401):
/// with the shadow map's estimate in place of the triangles (the grid's cells and the
/// per-point refinement near shafts), 400 is at p95 1.78%, 401 at 2.97%, 402 at 2.34%; with
/// that and a ray's first 16 marked steps refined (not all among its first 64) and no shaft
/// marks, seed 400 is at p95 10.24%, RMSE 6.53%; with the triangles' cells but the march
/// refining only the shafts' marks, not every step between lit and umbra, blinds (401) are
/// at 4.33%; with the occluders' distance from the light taken from their world boxes (a
/// turned plate's holds the light) and no floor at the light's radius, seed 400 of this
/// generator's first version (16², its eye placed otherwise) was at p95 1209%, the shadow
/// ignored.
#[test]
#[cfg_attr(
    not(feature = "sweeps"),
    ignore = "an accuracy sweep: --features sweeps"
)]
fn gap_scenes_against_the_reference() {
    let scenes: Vec<SoftScene> = (400..404).map(random_gap_scene).collect();
    let Checked {
        worst,
        hard_worst,
        within,
        ..
    } = check_scenes_sized(
        &scenes,
        (RMSE_BAR, P95_BAR),
        GAP_SIZE,
        ShaderPrecision::Native,
    );
    eprintln!(
        "gaps: {within} of {} within the issue's bars, worst p95 {:.2}%, hard worst {:.2}%",
        scenes.len(),
        100.0 * worst,
        100.0 * hard_worst
    );
}

/// A door ajar by 0.23 of the light's diameter with the eye in its shaft (the generator's seed
/// 411) at the defaults, against `reference::soft`: the pixels beside the shaft, 1% to 9% of
/// the image's brightness, are lit along their whole ray by a sliver of 0.1% to 1.4% of the
/// light, a few of `soft_exact`'s 256 directions at most.
///
/// Bar: p95 2%, tighter than the issue's 3% so that the directions not refined on slivers
/// fail it. Measured (lavapipe, 12², 2026-11-29): p95 1.27%, RMSE 0.78%; before the march's
/// thirds and the exact cells' curvature marks, 1.23% (1.08–1.23% over four shifts of the
/// pixels' seeds, 0, ¼, ½, ¾ of a turn, by hand). Broken variants, measured then, each over
/// the same four shifts: one turn of the directions a call, no more on slivers,
/// 3.04% (2.40–3.06%); the extra turns decided by the call's own first turn (where it saw 1
/// to 31 directions) rather than by the previous step's fraction, 4.77% (3.62–5.60%, darker
/// on average); the turn between calls the golden fraction, 2.62% (1.34–3.13%); the
/// directions turned by the golden fraction a call and never refined (the method before),
/// 6.43% (3.93–9.98%).
#[test]
#[cfg_attr(
    not(feature = "sweeps"),
    ignore = "an accuracy sweep: --features sweeps"
)]
fn a_sliver_of_the_light_past_a_door_ajar() {
    const BAR: f64 = 0.02;
    let scenes = [random_gap_scene(411)];
    let worst =
        check_scenes_sized(&scenes, (RMSE_BAR, BAR), GAP_SIZE, ShaderPrecision::Native).worst;
    eprintln!(
        "door ajar by 0.23: p95 {:.2}% (bar {:.0}%)",
        100.0 * worst,
        100.0 * BAR
    );
}

/// Doors ajar by 31° under a spot light and by 24° under a point light, seen from beside
/// their shafts (the generator's seeds 439 and 443, outside the 16 the method was tuned on).
/// The rays beside a shaft cross it at a slant within one or two of a refined step's pieces
/// (`refined_step` in shaders/passes/march.wgsl), and a midpoint a piece aliases it, the error
/// changing sign from pixel to pixel; the grid's cells near the shaft, exact, are marked where
/// their lookup cannot be trusted (`curved` and `mark_shafts` in shaders/passes/soft_shadow.wgsl).
///
/// Bars: the issue's (p95 3%, RMSE 2%). Measured (lavapipe, 12², 2026-11-29): 439 p95 2.35%,
/// RMSE 1.74%; 443 2.30%, 1.89%. Broken variants: a midpoint a piece, no thirds, 439 at p95
/// 7.34%, RMSE 3.27% (3.15% and 1.91% at 128 steps, 2.21% and 0.91% at 256); the exact cells
/// marked by their curvature alone, none near a shaft, 443 at p95 3.31%.
#[test]
#[cfg_attr(
    not(feature = "sweeps"),
    ignore = "an accuracy sweep: --features sweeps"
)]
fn thin_shafts_crossed_at_a_slant() {
    let scenes = [random_gap_scene(439), random_gap_scene(443)];
    let worst = check_scenes_sized(
        &scenes,
        (RMSE_BAR, P95_BAR),
        GAP_SIZE,
        ShaderPrecision::Native,
    )
    .worst;
    eprintln!(
        "doors ajar by 31° and 24°, beside their shafts: worst p95 {:.2}% (bar {:.0}%)",
        100.0 * worst,
        100.0 * P95_BAR
    );
}

/// What lets `check_scenes_wired` leave a scene out of its bars, checked where rounding does
/// not move the answer: blinds of 7 slats (401) and a door ajar by 9.8° (407) of the gap
/// generator, the reference of their boxes' corners rounded to f32
/// (`SoftScene::rounded_occluders`) against their reference. Bar: p95 and RMSE 0.1%, a
/// thirtieth of the issue's p95 bar; f32 moves a corner by 6e-8 of its coordinates, and the
/// reference integrates to 1e-7 of the light. Measured (2026-11-29): below 0.001% both. A
/// rounding that placed the boxes wrong (each box's rotation inverted, the broken variant, by
/// hand) moves 407 by p95 73.7%, RMSE 40.4%: it would excuse scenes the GPU draws wrong.
#[test]
#[cfg_attr(
    not(feature = "sweeps"),
    ignore = "an accuracy sweep: --features sweeps"
)]
fn rounding_the_corners_to_f32_leaves_a_determined_door() {
    const BAR: f64 = 0.001;
    let size = GAP_SIZE;
    for seed in [401, 407] {
        let s = random_gap_scene(seed);
        let reference = s.reference_image(size, &s.reference_occluders());
        let moved = s.moved_by_rounding(size, &reference);
        eprintln!("seed {seed}, corners rounded to f32: {moved}");
        assert!(
            moved.p95 <= BAR && moved.rmse <= BAR,
            "seed {seed}: rounding its corners to f32 moves its reference by {moved} (bar {}%)",
            100.0 * BAR
        );
    }
}

/// The whole generator, 16 seeds (400 to 407 here, 408 to 415 in the `_second_half` test),
/// held to the issue's bars (p95 3%, RMSE 2%, every scene that
/// its f32 occluders determine: `check_scenes_wired`). `GAP_SEEDS=400..448` runs other seeds,
/// `VOLSHADOW_SEED` one. Measured (lavapipe, 12², 2026-11-29): 15 of 16 within the bars, the
/// 16th not held (below); the worst of them a door ajar by 0.8 of the light's diameter (407, p95 2.15%: its thin shaft
/// crossed at a slant, 2.85% with a midpoint a refined piece and no thirds, see
/// `thin_shafts_crossed_at_a_slant`); the door ajar by 0.23 (411) at 1.27%
/// (`a_sliver_of_the_light_past_a_door_ajar`). Before slivers took more turns of the
/// directions and the turn between calls was the plastic fraction, 14 of 16 (411 at 6.43%).
/// With the shadow map's estimate in place of the occluders' triangles (against the
/// reference's former 16 × 16 directions), 13 of 16 (407 3.31%, blinds tilted 60° 10.40%, and
/// 411 at 66.51%).
///
/// Not held: **a door ajar behind a thick plate, nearly closed, under a spot light** (415),
/// drawn black. Its view is lit only by a strip across the light about 1e-5 of its radius
/// wide, between the door's edge and the frame's (at most 5.9e-6 of the light); 3e-8 of the
/// view with the shadow ignored. Rounding the boxes' corners to f32 moves its reference by p95
/// 35.2%, RMSE 60.8%; moving each corner's coordinates by at most one f32 step (8 random
/// draws, by hand) scales the image's sum by 0.07 to 1.62. Of seeds 400–447 (by hand) the one other such door, 423, moves
/// by p95 204%; the other 46 are within the bars.
#[test]
#[cfg_attr(
    not(feature = "sweeps"),
    ignore = "an accuracy sweep: --features sweeps"
)]
fn random_gap_scenes_against_the_issues_bars() {
    let seeds: Vec<u64> = match std::env::var("GAP_SEEDS") {
        Ok(range) => {
            let (lo, hi) = range
                .split_once("..")
                .expect("GAP_SEEDS is a range, like 400..448");
            (lo.trim().parse().unwrap()..hi.trim().parse().unwrap()).collect()
        }
        Err(_) => volshadow_harness::rng::seeds(400..408),
    };
    gap_sweep(seeds);
}

/// The generator's seeds 408 to 415, the second half of
/// [`random_gap_scenes_against_the_issues_bars`]'s 16 (a test of its own, so that the halves
/// run side by side). Not run when `GAP_SEEDS` or `VOLSHADOW_SEED` names the seeds.
#[test]
#[cfg_attr(
    not(feature = "sweeps"),
    ignore = "an accuracy sweep: --features sweeps"
)]
fn random_gap_scenes_against_the_issues_bars_second_half() {
    if std::env::var("GAP_SEEDS").is_err() && std::env::var("VOLSHADOW_SEED").is_err() {
        gap_sweep(volshadow_harness::rng::seeds(408..416));
    }
}

/// `seeds`' gap scenes held to the issue's bars.
fn gap_sweep(seeds: Vec<u64>) {
    let scenes: Vec<SoftScene> = seeds.into_iter().map(random_gap_scene).collect();
    let checked = check_scenes_sized(
        &scenes,
        (RMSE_BAR, P95_BAR),
        GAP_SIZE,
        ShaderPrecision::Native,
    );
    eprintln!(
        "gaps: {} of {} within ({} not determined by their f32 occluders, not held), worst p95 \
         {:.2}%, hard worst {:.2}%",
        checked.within,
        scenes.len() - checked.undetermined,
        checked.undetermined,
        100.0 * checked.worst,
        100.0 * checked.hard_worst
    );
}

/// The per-point estimate (brute force at 256 steps: `visibility_soft` at every step) on the
/// generator's square hole 1.25 of the light's diameter in a thin plate turned to the light
/// (seed 406), against `reference::soft`, held to the issue's bars (p95 3%, RMSE 2%). PCSS
/// puts the filter's taps where the lines from the point to the light's disc cross a sphere
/// around the light at the blockers' distance; the plate, turned, lies nearer the light on one
/// side and farther on the other, and where the occluders may leave gaps each tap follows its
/// line to its own blocker's distance (`soft_filter`). Measured (lavapipe, 12², 2026-11-29):
/// p95 1.60%, RMSE 0.40%; every tap at the one distance (the broken variant, against the
/// reference's former 16 × 16 directions, 2026-11-28): p95 6.14%, RMSE 0.53%.
#[test]
#[cfg_attr(
    not(feature = "sweeps"),
    ignore = "an accuracy sweep: --features sweeps"
)]
fn a_hole_in_a_turned_plate_per_point() {
    let s = random_gap_scene(406);
    let size = GAP_SIZE;
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache_with(&gpu, ShaderPrecision::Native);
    let wall = |e: DVec3, d: DVec3| wall_distance(s.wall, e, d);
    let reference = s.reference_image(size, &s.reference_occluders());
    let depths = volshadow_harness::depths_at(&s.camera, size, size, wall);
    let depth = volshadow_harness::depth_texture(&gpu, size, size, &depths);
    let box_meshes = box_meshes(&gpu, &s.boxes);
    let occluders = placed(&box_meshes, &s.boxes);
    let settings = MarchSettings {
        method: MarchMethod::BruteForce,
        steps: 256,
        ..MarchSettings::default()
    };
    let passes =
        volshadow_harness::ShadowPasses::new(&s.camera, &s.light, &s.medium, &depth, &occluders)
            .settings(settings);
    let frame = volshadow_harness::shadow_frame(&gpu, &cache, &passes);
    let e = errors(
        &frame.inscatter,
        &reference,
        &s.camera,
        &s.light,
        (size, size),
    );
    eprintln!("{}\n  brute force, 256 steps: {e}", s.describe);
    volshadow_harness::metric::accuracy(
        &format!("{}, {size}²: brute force at 256 steps (the per-point estimate) against reference::soft", s.describe),
        format!("p95 {:.2}%, RMSE {:.2}%", 100.0 * e.p95, 100.0 * e.rmse),
        format!("p95 {}%, RMSE {}% (the issue's bars)", 100.0 * P95_BAR, 100.0 * RMSE_BAR),
    );
    assert_eq!(e.non_finite, 0, "{}: {e}", s.describe);
    assert!(
        e.p95 <= P95_BAR && e.rmse <= RMSE_BAR,
        "{}: {e}",
        s.describe
    );
}

/// The grid's cells of gap scenes against the reference's visible fraction at each cell's
/// point (every second direction and slice, each layer): with the occluders' triangles
/// (`soft_exact`, the default for such frames) and with the shadow map's estimate alone (the
/// map without them), on a slit, blinds under a spot light, a square hole, a door ajar by 0.8
/// and one by 0.23 of the light's diameter, and blinds tilted 60° (seeds 400, 401, 402, 407,
/// 411, 413). In
/// the penumbra (reference fraction 0.02 to 0.98): the 95th percentile and the largest
/// |error|.
///
/// Bars: p95 0.02 and max 0.04, the 256 directions' error (the reference's rows are within
/// 2e-7): a half-plane's table entry is within 0.0178 of its segment's area
/// (`the_exact_directions_and_their_half_planes`), and a slit is two of them. Measured
/// (lavapipe, 2026-11-29): p95 ≤ 0.0132, max ≤ 0.0260 per scene (against the reference's
/// former 16 × 16 directions, 0.0197 and 0.0396). The shadow map's estimate on the same cells
/// is the broken variant, held to fail them: p95 up to 0.2440, max up to 0.5468.
///
/// In the reference's umbra (fraction exactly 0): the mean and the largest cell, bars 1e-5
/// and two directions (2/256: the two sides of an edge two triangles share take opposite
/// half-planes of one line, so no direction falls between them, but an atan2 within WGSL's
/// 4096 ULP may put the two sides' angles one bin apart). Measured: 0 and 0 in every scene.
/// Broken variant (by hand, 2026-11-29): the table's offsets rounded up, not to the nearest,
/// so that the two sides of a shared edge each leave out a strip along it: mean up to
/// 1.22e-3, max 0.0352 (and p95 0.0227, max 0.0428 in the penumbra).
#[test]
fn gap_grid_cells_against_the_reference_visible_fraction() {
    const P95_BAR: f64 = 0.02;
    const MAX_BAR: f64 = 0.04;
    const UMBRA_MEAN_BAR: f64 = 1e-5;
    const UMBRA_MAX_BAR: f64 = 2.0 / 256.0;
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let size = SoftShadowSize::default();
    let (n, slices) = (size.directions as usize, size.slices as usize);
    let mut shadow = ShadowMapNode::new(&gpu.device, &cache, Default::default()).unwrap();
    let mut worst = [(0.0f64, 0.0f64); 2];
    let mut umbra_worst = (0.0f64, 0.0f64);
    for seed in [400, 401, 402, 407, 411, 413] {
        let s = random_gap_scene(seed);
        let meshes = box_meshes(&gpu, &s.boxes);
        let occluders = placed(&meshes, &s.boxes);
        let inputs = ShadowMapInputs {
            light: &s.light,
            occluders: &occluders,
            camera: &volshadow_harness::unread_camera(),
            fallback: None,
        };
        shadow.prepare(&gpu.device, &gpu.queue, &inputs).unwrap();
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        shadow.encode(&mut encoder, None).unwrap();
        gpu.submit_and_wait(encoder).unwrap();
        let own = shadow.shadow_map().unwrap();
        assert!(
            own.triangles.is_some(),
            "{}: no triangles gathered",
            s.describe
        );
        let occ = s.reference_occluders();
        let light = s.light.position().unwrap();
        for (variant, map) in [
            own,
            ShadowMap {
                triangles: None,
                ..own
            },
        ]
        .into_iter()
        .enumerate()
        {
            let mut soft = SoftShadowNode::new(&gpu.device, &cache, size).unwrap();
            let inputs = SoftShadowInputs {
                light: &s.light,
                shadow_map: map,
            };
            soft.prepare(&gpu.device, &gpu.queue, &inputs).unwrap();
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            soft.encode(&mut encoder, None).unwrap();
            gpu.submit_and_wait(encoder).unwrap();
            let cells: Vec<half::f16> = bytemuck::pod_collect_to_vec(
                &gpu.read_all_layers_bytes(soft.output().unwrap().texture)
                    .unwrap(),
            );
            let nearest = soft.output().unwrap().near;
            let mut errors = Vec::new();
            let mut umbra = Vec::new();
            for (layer, face) in map.faces.iter().enumerate() {
                let world_from_clip = face.inverse();
                for y in (0..n).step_by(2) {
                    for x in (0..n).step_by(2) {
                        let uv = (glam::Vec2::new(x as f32, y as f32) + 0.5) / n as f32;
                        let w = world_from_clip
                            * glam::Vec4::new(2.0 * uv.x - 1.0, 1.0 - 2.0 * uv.y, 0.5, 1.0);
                        let dir = (w.truncate() / w.w - light).normalize().as_dvec3();
                        for k in (0..slices).step_by(2) {
                            let q = 1.0 - (k as f64 + 0.5) / slices as f64;
                            let point = light.as_dvec3() + dir * (f64::from(nearest) / q);
                            let want = reference::soft::visible_fraction(
                                point,
                                light.as_dvec3(),
                                f64::from(s.light.radius()),
                                &occ,
                            );
                            let got =
                                f64::from(cells[(((layer * slices + k) * n + y) * n + x) * 4]);
                            if (0.02..=0.98).contains(&want) {
                                errors.push((got - want).abs());
                            } else if want == 0.0 {
                                umbra.push(got);
                            }
                        }
                    }
                }
            }
            assert!(!errors.is_empty(), "{}: no penumbra cell", s.describe);
            errors.sort_by(f64::total_cmp);
            let p95 = errors[errors.len() * 95 / 100];
            let max = errors[errors.len() - 1];
            let name = ["triangles", "shadow map alone"][variant];
            let umbra_max = umbra.iter().copied().fold(0.0, f64::max);
            let umbra_mean = umbra.iter().sum::<f64>() / umbra.len().max(1) as f64;
            eprintln!(
                "{}\n  {name}: {} penumbra cells, p95 |error| {p95:.4}, max {max:.4}; {} umbra cells, mean {umbra_mean:.2e}, max {umbra_max:.4}",
                s.describe,
                errors.len(),
                umbra.len()
            );
            worst[variant] = (worst[variant].0.max(p95), worst[variant].1.max(max));
            if variant == 0 {
                umbra_worst = (umbra_worst.0.max(umbra_mean), umbra_worst.1.max(umbra_max));
            }
        }
    }
    let [(p95, max), (map_p95, map_max)] = worst;
    volshadow_harness::metric::accuracy(
        "the grid's cells of 6 gap scenes against the reference's visible fraction (penumbra): worst p95 |error|, worst max; the shadow map's estimate alone",
        format!("{p95:.4}, {max:.4}; {map_p95:.4}, {map_max:.4}"),
        format!("{P95_BAR}, {MAX_BAR} (the 256 directions' sampling); the map alone beyond them"),
    );
    assert!(
        p95 <= P95_BAR && max <= MAX_BAR,
        "with the triangles: p95 {p95:.4} (bar {P95_BAR}), max {max:.4} (bar {MAX_BAR})"
    );
    assert!(
        map_p95 > P95_BAR || map_max > MAX_BAR,
        "the shadow map alone within the bars: p95 {map_p95:.4}, max {map_max:.4}"
    );
    let (umbra_mean, umbra_max) = umbra_worst;
    volshadow_harness::metric::accuracy(
        "the grid's cells of 6 gap scenes in the reference's umbra (fraction 0): worst mean, worst max",
        format!("{umbra_mean:.2e}, {umbra_max:.4}"),
        format!("{UMBRA_MEAN_BAR:.0e}, {UMBRA_MAX_BAR:.4} (two directions)"),
    );
    assert!(
        umbra_mean <= UMBRA_MEAN_BAR && umbra_max <= UMBRA_MAX_BAR,
        "light in the umbra: mean {umbra_mean:.2e} (bar {UMBRA_MEAN_BAR:.0e}), max {umbra_max:.4} (bar {UMBRA_MAX_BAR:.4})"
    );
}

/// The shadow-map node gathers the occluders' triangles (`ShadowMap::triangles`) only where
/// the soft shadows take them: a point or spot light with a radius, occluders that may leave
/// gaps, at most `MAX_EXACT_TRIANGLES` in all; and it gathers them where the occluders stand.
/// Two boxes (one turned and moved) under a point light of radius 0.2: 6 groups of four, each
/// box's corners those of its mesh through its transform (to 1e-5), each group's sphere
/// holding its corners. Not gathered: one box alone (convex), the light without a radius, a
/// directional light, and 43 boxes (516 triangles). A gather without the transforms (the
/// broken variant) would leave every corner of either box at least 2 off (their translations).
#[test]
fn the_triangles_are_gathered_where_the_soft_shadows_take_them() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let half = Vec3::new(0.5, 0.3, 0.1);
    let cube = shapes::cuboid(Vec3::ZERO, half).unwrap();
    let mesh = OccluderMesh::new(&gpu.device, &cube);
    let turned = glam::Mat4::from_rotation_translation(
        Quat::from_rotation_y(0.7) * Quat::from_rotation_x(0.3),
        Vec3::new(0.4, -0.2, 2.0),
    );
    let occluder = |transform| Occluder {
        mesh: &mesh,
        transform,
    };
    let soft: Light = PointLight::new(Vec3::ZERO, Vec3::ONE)
        .unwrap()
        .with_radius(0.2)
        .unwrap()
        .into();
    let hard: Light = PointLight::new(Vec3::ZERO, Vec3::ONE).unwrap().into();
    let sun: Light = DirectionalLight::new(Vec3::new(0.0, -1.0, 0.2), Vec3::ONE)
        .unwrap()
        .into();
    let gathered = |light: &Light, occluders: &[Occluder]| -> Option<Vec<[f32; 4]>> {
        let mut node = ShadowMapNode::new(&gpu.device, &cache, Default::default()).unwrap();
        let inputs = ShadowMapInputs {
            light,
            occluders,
            camera: &volshadow_harness::unread_camera(),
            fallback: None,
        };
        node.prepare(&gpu.device, &gpu.queue, &inputs).unwrap();
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        node.encode(&mut encoder, None).unwrap();
        gpu.submit_and_wait(encoder).unwrap();
        let map = node.shadow_map().unwrap();
        map.triangles
            .map(|b| bytemuck::pod_collect_to_vec(&gpu.read_buffer_bytes(b).unwrap()))
    };
    let pair = [
        occluder(glam::Mat4::from_translation(Vec3::new(-0.6, 0.0, 2.0))),
        occluder(turned),
    ];
    let groups = gathered(&soft, &pair).expect("two boxes under a soft light");
    let triangles = cube.indices().len() / 3;
    let per_box = triangles.div_ceil(4);
    assert_eq!(groups.len(), 2 * per_box * 16, "6 groups of 16 vec4");
    for (b, o) in pair.iter().enumerate() {
        for t in 0..triangles {
            let (g, k) = (b * per_box + t / 4, t % 4);
            for c in 0..3 {
                let want = o
                    .transform
                    .transform_point3(cube.positions()[cube.indices()[3 * t + c] as usize]);
                let got = groups[16 * g + 3 * k + c];
                let got = Vec3::new(got[0], got[1], got[2]);
                assert!(
                    got.distance(want) <= 1e-5,
                    "box {b} triangle {t} corner {c}: {got} against {want}"
                );
                let sphere = groups[16 * g + 12];
                let centre = Vec3::new(sphere[0], sphere[1], sphere[2]);
                assert!(
                    centre.distance(got) <= sphere[3],
                    "box {b} group {g}: corner outside its sphere"
                );
            }
        }
    }
    assert!(gathered(&soft, &pair[..1]).is_none(), "one convex box");
    assert!(gathered(&hard, &pair).is_none(), "a light without a radius");
    assert!(gathered(&sun, &pair).is_none(), "a directional light");
    let many: Vec<Occluder> = (0..43)
        .map(|i| occluder(glam::Mat4::from_translation(Vec3::new(i as f32, 0.0, 3.0))))
        .collect();
    assert!(
        43 * triangles > volshadow::nodes::MAX_EXACT_TRIANGLES as usize,
        "43 boxes must exceed the cap"
    );
    assert!(gathered(&soft, &many).is_none(), "43 boxes");
}
