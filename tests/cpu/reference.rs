//! Tests of the f64 reference (`volshadow::reference`): the quadrature of (1) against the
//! independent closed form (2), shadowed rays against a brute-force Riemann sum, exact lit
//! intervals against brute-force sampling, degenerate rays, and the per-frame image helper.

use volshadow_harness::metric;
use volshadow_harness::rng::{self, rel_err};

use std::f64::consts::PI;
use std::time::Instant;

use rng::Rng;
use volshadow::glam::camera::rh::proj::directx;
use volshadow::glam::camera::rh::view::look_at_mat4;
use volshadow::glam::{DQuat, DVec3, Vec3};
use volshadow::reference::*;
use volshadow::{Camera, Medium, PhaseFunction, PointLight};

fn unit_perpendicular(a: DVec3) -> DVec3 {
    a.cross(DVec3::new(0.3, -0.8, 0.52)).normalize()
}

#[test]
fn quadrature_matches_closed_form_on_unshadowed_rays() {
    let origin = DVec3::new(0.3, -0.2, 0.5);
    let d_target = 2.0;
    let light_dir = DVec3::new(1.0, 2.0, -0.5).normalize();
    let light = PointLight::new(
        (origin + light_dir * d_target).as_vec3(),
        Vec3::new(1.0, 2.0, 0.5),
    )
    .unwrap();
    // Work with the light where f32 put it.
    let to_light = light.position().as_dvec3() - origin;
    let d = to_light.length();
    let a = to_light / d;
    let b = unit_perpendicular(a);

    let phases: [(&str, Option<PhaseFunction>); 7] = [
        ("isotropic", Some(PhaseFunction::Isotropic)),
        ("HG(0.9)", Some(PhaseFunction::HenyeyGreenstein { g: 0.9 })),
        (
            "HG(-0.9)",
            Some(PhaseFunction::HenyeyGreenstein { g: -0.9 }),
        ),
        ("Rayleigh", Some(PhaseFunction::Rayleigh)),
        ("Hoffman-Preetham", None),
        ("MieHazy", Some(PhaseFunction::MieHazy)),
        ("MieMurky", Some(PhaseFunction::MieMurky)),
    ];
    let optical_depths = [1e-4, 1e-2, 1.0, 10.0, 100.0];
    let gammas = [1e-3, 0.1, 1.0, PI / 2.0, 2.5, PI - 1e-3];
    let ends = [0.01 * d, 0.5 * d, d, 3.0 * d, f64::INFINITY];

    let mut worst = 0.0f64;
    let mut worst_case = String::new();
    let mut rays = 0;
    let start = Instant::now();
    for (name, phase) in phases {
        for &tau in &optical_depths {
            let k = (tau / d) as f32; // σt in channel 0
            let mut media = Vec::new();
            match phase {
                Some(p) => {
                    let ratio = Vec3::new(1.0, 0.7, 1.3);
                    media.push(("σa = 0", Medium::new(ratio * k, Vec3::ZERO, p).unwrap()));
                    // σa = 3σs: extinction in the exponent, scattering only in the prefactor.
                    media.push((
                        "σa = 3σs",
                        Medium::new(ratio * k * 0.25, ratio * k * 0.75, p).unwrap(),
                    ));
                }
                None => {
                    // Distinct Rayleigh / Mie mixes per channel, σt·D = tau in channel 0.
                    let rayleigh = Vec3::new(0.3, 0.6, 0.9) * k;
                    let mie = Vec3::new(0.7, 0.3, 0.05) * k;
                    media.push((
                        "σa = 0",
                        Medium::hoffman_preetham(rayleigh, mie, 0.76, Vec3::ZERO).unwrap(),
                    ));
                }
            }
            for (medium_name, medium) in &media {
                for &gamma in &gammas {
                    let dir = a * gamma.cos() + b * gamma.sin();
                    for &ds in &ends {
                        let q = inscatter(origin, dir, ds, medium, &light, &[]);
                        let c = inscatter_closed_form(origin, dir, ds, medium, &light);
                        assert!(q.is_finite() && c.is_finite(), "{q} {c}");
                        assert!(
                            q.min_element() > 0.0,
                            "{name} τ={tau} γ={gamma} ds={ds}: {q}"
                        );
                        let e = rel_err(q, c);
                        rays += 1;
                        if e > worst {
                            worst = e;
                            worst_case = format!(
                                "{name}, {medium_name}, σt·D = {tau}, γ = {gamma}, ds = {ds}: \
                                 quadrature {q}, closed form {c}"
                            );
                        }
                    }
                }
            }
        }
    }
    println!(
        "{rays} unshadowed rays in {:.2?}: max relative error quadrature vs closed form = {worst:.3e} ({worst_case})",
        start.elapsed()
    );
    // Both integrals are computed to a relative tolerance of 1e-12 (RELATIVE_TOLERANCE) by
    // different substitutions; 1e-9 leaves a factor 1000 for the condition of the exponentials
    // (σt·D up to 100) and the f64 round-off in the geometry.
    metric::accuracy(
        &format!("{rays} unshadowed rays, 7 phase functions: quadrature against the closed form"),
        format!("max {worst:.1e}"),
        "1e-9",
    );
    assert!(worst <= 1e-9, "max relative error {worst:e}: {worst_case}");
}

/// Henyey–Greenstein, written here again so that the Riemann sum shares nothing with the
/// reference's integrand.
fn hg(g: f64, mu: f64) -> f64 {
    (1.0 - g * g) / (4.0 * PI * (1.0 + g * g - 2.0 * g * mu).powf(1.5))
}

/// Midpoint rule of (1) in x with `n` points, visibility from the exact segment test. Returns
/// the sum, the largest integrand value seen (over all channels) and the number of visibility
/// flips between consecutive samples.
#[allow(clippy::too_many_arguments)]
fn riemann(
    e: DVec3,
    v: DVec3,
    ds: f64,
    p: DVec3,
    sigma_s: DVec3,
    sigma_t: DVec3,
    i0: DVec3,
    g: f64,
    sphere: &Sphere,
    n: usize,
) -> (DVec3, f64, usize) {
    let step = ds / n as f64;
    let mut sum = DVec3::ZERO;
    let mut max_f = 0.0f64;
    let mut flips = 0;
    let mut prev_lit = None;
    for i in 0..n {
        let x = (i as f64 + 0.5) * step;
        let xp = e + v * x;
        let dist = (xp - p).length();
        let mu = v.dot(p - xp) / dist;
        let f = sigma_s * hg(g, mu) * i0 * (-sigma_t * (dist + x)).exp() / (dist * dist);
        max_f = max_f.max(f.max_element());
        let lit = !sphere.segment_blocked(xp, p);
        if prev_lit.is_some_and(|l| l != lit) {
            flips += 1;
        }
        prev_lit = Some(lit);
        if lit {
            sum += f;
        }
    }
    (sum * step, max_f, flips)
}

#[test]
fn shadowed_rays_match_a_fine_riemann_sum() {
    let g = 0.6;
    let sigma_s = Vec3::new(0.15, 0.1, 0.05);
    let sigma_a = Vec3::new(0.05, 0.02, 0.3);
    let medium = Medium::new(
        sigma_s,
        sigma_a,
        PhaseFunction::HenyeyGreenstein { g: g as f32 },
    )
    .unwrap();
    let light = PointLight::new(Vec3::new(5.0, 4.0, 0.5), Vec3::new(10.0, 8.0, 6.0)).unwrap();
    let p = light.position().as_dvec3();
    let sphere = Sphere::new(DVec3::new(5.0, 2.0, 0.3), 0.7);
    let occluders = [Occluder::Sphere(sphere)];
    // (eye, direction, ds): a ray under the sphere's shadow, and one that starts inside it.
    let rays = [
        (DVec3::ZERO, DVec3::new(1.0, 0.0, 0.05).normalize(), 10.0),
        (
            DVec3::new(4.8, 0.5, 0.2),
            DVec3::new(-0.3, -0.1, 1.0).normalize(),
            6.0,
        ),
    ];
    let n = 2_000_000;
    let mut worst_ratio = 0.0f64;
    for (e, v, ds) in rays {
        let reference = inscatter(e, v, ds, &medium, &light, &occluders);
        let unshadowed = inscatter(e, v, ds, &medium, &light, &[]);
        let args = (
            medium.sigma_s().as_dvec3(),
            medium.sigma_t().as_dvec3(),
            light.intensity().as_dvec3(),
        );
        let (fine, max_f, flips) = riemann(e, v, ds, p, args.0, args.1, args.2, g, &sphere, n);
        let (coarse, _, _) = riemann(e, v, ds, p, args.0, args.1, args.2, g, &sphere, n / 2);
        // Error of the midpoint sum: each cell holding a visibility jump is off by at most
        // step·max f; the smooth part converges as step², so |R_N − R_{N/2}| (which also holds
        // the coarse sum's jump error) bounds the rest generously.
        let step = ds / n as f64;
        let bound = DVec3::splat(flips as f64 * step * max_f) + (fine - coarse).abs();
        let diff = (reference - fine).abs();
        let ratio = (diff / bound).max_element();
        worst_ratio = worst_ratio.max(ratio);
        println!(
            "shadowed ray: reference {reference}, Riemann {fine} (N = {n}), |diff| {diff}, \
             Riemann error bound {bound} ({flips} visibility flips), \
             relative diff {:.2e}; unshadowed {unshadowed}",
            rel_err(reference, fine)
        );
        assert!(flips >= 1, "the ray must cross a shadow boundary");
        assert!(
            diff.cmple(bound).all(),
            "reference and Riemann sum differ by {diff}, more than the sum's error {bound}"
        );
        // The shadow must matter, or this test could not tell.
        assert!(
            (reference / unshadowed).max_element() < 0.9,
            "shadowed {reference} vs unshadowed {unshadowed}"
        );
    }
    println!("max |reference − Riemann| / Riemann error bound = {worst_ratio:.3}");
}

/// Samples `samples` points uniformly in (0, ds) and checks that `segment_blocked` agrees with
/// `lit_intervals` everywhere except within `margin` of an interval end. Returns (number of lit
/// intervals, number of dark samples, number of samples within the margin that disagreed).
fn check_intervals(
    e: DVec3,
    v: DVec3,
    ds: f64,
    p: DVec3,
    occluders: &[Occluder],
    samples: usize,
) -> (usize, usize, usize) {
    let margin = 1e-9;
    let intervals = lit_intervals(e, v, ds, p, occluders);
    for w in intervals.windows(2) {
        assert!(
            w[0].1 < w[1].0,
            "intervals not sorted and disjoint: {intervals:?}"
        );
    }
    let mut dark = 0;
    let mut excused = 0;
    for i in 0..samples {
        let x = (i as f64 + 0.5) / samples as f64 * ds;
        let lit = !occluders.iter().any(|o| o.segment_blocked(e + v * x, p));
        let inside = intervals.iter().any(|&(a, b)| a <= x && x <= b);
        dark += usize::from(!lit);
        if lit != inside {
            let near_end = intervals
                .iter()
                .any(|&(a, b)| (x - a).abs() <= margin || (x - b).abs() <= margin);
            assert!(
                near_end,
                "x = {x}: sampled lit = {lit}, intervals say {inside}: {intervals:?} \
                 (e = {e}, v = {v}, p = {p})"
            );
            excused += 1;
        }
    }
    (intervals.len(), dark, excused)
}

fn lit_interval_suite(name: &str, occluders: &[Occluder], centre: DVec3, size: f64) {
    let mut rng = Rng::new(0x5eed ^ name.len() as u64);
    let samples = 100_000;
    let mut with_shadow = 0;
    let mut total_excused = 0;
    let mut rays = 0;
    // Lights around the occluder, eyes farther out, rays aimed at points behind the occluder
    // as seen from the light (where its shadow is).
    for _ in 0..6 {
        let p = centre + rng.vec(-1.0, 1.0).normalize() * size * (2.0 + 2.0 * rng.next());
        let behind = centre + (centre - p).normalize() * size * (1.0 + 2.0 * rng.next());
        let target = behind + rng.vec(-0.5, 0.5) * size;
        let e = target + rng.vec(-1.0, 1.0).normalize() * size * 5.0;
        let v = (target - e).normalize();
        let (n, dark, excused) = check_intervals(e, v, 12.0 * size, p, occluders, samples);
        rays += 1;
        total_excused += excused;
        if dark > 0 && n > 0 {
            with_shadow += 1;
        }
    }
    println!(
        "lit_intervals {name}: {rays} rays × {samples} samples agree with segment_blocked \
         ({total_excused} samples within 1e-9 of an interval end disagreed); \
         {with_shadow} rays crossed a shadow"
    );
    assert!(
        with_shadow >= 3,
        "too few rays crossed a shadow to test anything"
    );
}

fn tetrahedron() -> TriangleMesh {
    let positions = [
        DVec3::new(1.0, 1.0, 1.0),
        DVec3::new(1.0, -1.0, -1.0),
        DVec3::new(-1.0, 1.0, -1.0),
        DVec3::new(-1.0, -1.0, 1.0),
    ];
    let triangles = [[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]];
    let transform = volshadow::glam::DMat4::from_scale_rotation_translation(
        DVec3::splat(0.8),
        DQuat::from_euler(volshadow::glam::EulerRot::XYZ, 0.3, -0.7, 1.1),
        DVec3::new(1.0, 2.0, -3.0),
    );
    TriangleMesh::transformed(&positions, &triangles, transform)
}

#[test]
fn lit_intervals_match_brute_force_sampling() {
    let sphere = Sphere::new(DVec3::new(0.5, -1.0, 2.0), 0.8);
    lit_interval_suite("sphere", &[sphere.into()], sphere.center, 0.8);

    let cuboid = Cuboid::new(
        DVec3::new(-2.0, 1.0, 0.5),
        DVec3::new(0.9, 0.4, 0.6),
        DQuat::from_euler(volshadow::glam::EulerRot::YXZ, 0.8, 0.4, -0.3),
    );
    lit_interval_suite("cuboid", &[cuboid.into()], cuboid.center, 0.9);

    let mesh = tetrahedron();
    lit_interval_suite(
        "tetrahedron",
        &[mesh.into()],
        DVec3::new(1.0, 2.0, -3.0),
        0.8,
    );

    // All three at once, plus special configurations.
    let all = [
        Occluder::from(sphere),
        Occluder::from(cuboid),
        Occluder::from(tetrahedron()),
    ];
    let p = DVec3::new(0.0, 0.5, 0.0);
    let (n, dark, _) = check_intervals(
        DVec3::new(3.0, -3.0, 5.0),
        DVec3::new(-1.0, 0.6, -0.9).normalize(),
        15.0,
        p,
        &all,
        100_000,
    );
    println!("all occluders: {n} lit intervals, {dark} dark samples");
    // Light inside the sphere: everything outside is dark, the inside is lit.
    let inside_light = sphere.center + DVec3::new(0.2, 0.1, -0.3);
    let (n, dark, _) = check_intervals(
        DVec3::new(-3.0, -1.2, 2.1),
        DVec3::X,
        8.0,
        inside_light,
        &[sphere.into()],
        100_000,
    );
    assert_eq!(
        n, 1,
        "light inside the sphere: one lit interval (the inside)"
    );
    assert!(dark > 50_000);
    // Eye inside the sphere, light outside; and eye inside the box.
    check_intervals(
        sphere.center,
        DVec3::new(0.3, 1.0, 0.2).normalize(),
        5.0,
        DVec3::new(3.0, 3.0, 3.0),
        &[sphere.into()],
        100_000,
    );
    check_intervals(
        cuboid.center,
        DVec3::new(-0.5, 0.2, 1.0).normalize(),
        5.0,
        DVec3::new(-2.0, 4.0, 0.0),
        &[cuboid.into()],
        100_000,
    );
    // A ray through the light, across the sphere's shadow.
    let light = DVec3::new(0.5, 2.0, 2.0);
    let e = DVec3::new(0.5, 4.0, 2.0);
    let (n, dark, _) = check_intervals(e, -DVec3::Y, 8.0, light, &[sphere.into()], 100_000);
    assert!(n >= 1 && dark > 0);
    // Along the shadow's axis everything beyond the sphere's near surface (x = 4.2) is dark.
    let iv = lit_intervals(e, -DVec3::Y, f64::INFINITY, light, &[sphere.into()]);
    println!("ray through the light along the shadow's axis, ds = ∞: {iv:?}");
    assert!(
        iv.len() == 1 && iv[0].0 == 0.0 && (iv[0].1 - 4.2).abs() < 1e-12,
        "{iv:?}"
    );
    // ds = ∞ across the shadow cone: lit, dark, then lit to infinity. The cone's half angle is
    // asin(0.8/3); at 5 below the light its radius is 5·tan α.
    let radius = 5.0 * (0.8f64 / 3.0).asin().tan();
    let iv = lit_intervals(
        DVec3::new(-5.0, -3.0, 2.0),
        DVec3::X,
        f64::INFINITY,
        light,
        &[sphere.into()],
    );
    println!("across the shadow cone, ds = ∞: {iv:?}");
    assert_eq!(iv.len(), 2, "{iv:?}");
    assert!((iv[0].1 - (5.5 - radius)).abs() < 1e-12 && (iv[1].0 - (5.5 + radius)).abs() < 1e-12);
    assert_eq!(iv[1].1, f64::INFINITY);
}

#[test]
fn degenerate_rays_give_no_nan() {
    let medium = Medium::new(
        Vec3::new(0.1, 0.2, 0.0),
        Vec3::splat(0.05),
        PhaseFunction::HenyeyGreenstein { g: 0.8 },
    )
    .unwrap();
    let light = PointLight::new(Vec3::new(3.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 1.0)).unwrap();
    let e = DVec3::ZERO;
    let sphere = Occluder::Sphere(Sphere::new(DVec3::ZERO, 1.0));
    let box_around_light = Occluder::Cuboid(Cuboid::axis_aligned(
        DVec3::new(3.0, 0.0, 0.0),
        DVec3::splat(0.5),
    ));
    let finite_or_pos_inf = |v: DVec3| v.to_array().iter().all(|x| !x.is_nan() && *x >= 0.0);

    // Through the light (h = 0), light within [0, ds]: +∞ where σs·I0 > 0, 0 elsewhere.
    for f in [
        inscatter(e, DVec3::X, 5.0, &medium, &light, &[]),
        inscatter_closed_form(e, DVec3::X, 5.0, &medium, &light),
        inscatter(e, DVec3::X, f64::INFINITY, &medium, &light, &[]),
    ] {
        assert!(
            f.x == f64::INFINITY && f.y == f64::INFINITY && f.z == 0.0,
            "{f}"
        );
    }
    // h = 0 with the light beyond ds or behind the eye: finite, and both methods agree.
    for (dir, ds) in [
        (DVec3::X, 2.0),
        (-DVec3::X, 4.0),
        (-DVec3::X, f64::INFINITY),
    ] {
        let q = inscatter(e, dir, ds, &medium, &light, &[]);
        let c = inscatter_closed_form(e, dir, ds, &medium, &light);
        assert!(q.is_finite() && c.is_finite() && q.x > 0.0, "{q} {c}");
        assert!(rel_err(q, c) < 1e-12);
    }
    // Eye inside an occluder, light inside another, ds = 0, zero and tiny directions.
    let cases = [
        (DVec3::X, 5.0, vec![sphere.clone()]),
        (
            DVec3::X,
            f64::INFINITY,
            vec![sphere.clone(), box_around_light.clone()],
        ),
        (DVec3::Y, f64::INFINITY, vec![box_around_light.clone()]),
        (DVec3::new(1.0, 1e-300, 0.0), 5.0, vec![sphere.clone()]),
        (DVec3::X, 0.0, vec![sphere.clone()]),
        (DVec3::ZERO, 5.0, vec![]),
        (DVec3::new(0.0, 1e-200, 0.0), 5.0, vec![]),
        (DVec3::new(1e-310, 0.0, 0.0), 5.0, vec![]),
        (DVec3::new(1e300, 1e300, 0.0), 5.0, vec![sphere.clone()]),
        (DVec3::X, -1.0, vec![]),
        (DVec3::X, f64::NAN, vec![sphere.clone()]),
    ];
    for (dir, ds, occ) in cases {
        let f = inscatter(e, dir, ds, &medium, &light, &occ);
        assert!(finite_or_pos_inf(f), "dir {dir} ds {ds}: {f}");
        let c = inscatter_closed_form(e, dir, ds, &medium, &light);
        assert!(finite_or_pos_inf(c), "dir {dir} ds {ds}: {c}");
        if ds.is_nan() || ds <= 0.0 || dir == DVec3::ZERO {
            assert_eq!(f, DVec3::ZERO);
        }
    }
    // A light inside a box lights only the inside of the box: a ray that never enters it is
    // dark, one that does is bright.
    let outside = inscatter(
        e,
        DVec3::Y,
        f64::INFINITY,
        &medium,
        &light,
        std::slice::from_ref(&box_around_light),
    );
    assert_eq!(outside, DVec3::ZERO);
    let through = inscatter(
        DVec3::new(0.0, 0.1, 0.0),
        DVec3::X,
        f64::INFINITY,
        &medium,
        &light,
        std::slice::from_ref(&box_around_light),
    );
    let through_open = inscatter(
        DVec3::new(0.0, 0.1, 0.0),
        DVec3::X,
        f64::INFINITY,
        &medium,
        &light,
        &[],
    );
    println!("light inside a box: ray through the box {through}, without the box {through_open}");
    assert!(through.is_finite() && through.x > 0.0 && through.x < through_open.x);
    // Light a hair off the ray: large but finite.
    let near = inscatter(
        DVec3::new(0.0, 1e-12, 0.0),
        DVec3::X,
        5.0,
        &medium,
        &light,
        &[],
    );
    let near_cf =
        inscatter_closed_form(DVec3::new(0.0, 1e-12, 0.0), DVec3::X, 5.0, &medium, &light);
    println!("light 1e-12 off the ray: quadrature {near}, closed form {near_cf}");
    assert!(near.is_finite() && near.x > 1e9 && rel_err(near, near_cf) < 1e-9);
    let t = transmittance(&medium, f64::INFINITY);
    assert_eq!(t, DVec3::new(0.0, 0.0, 0.0));
    let m0 = Medium::new(Vec3::ZERO, Vec3::ZERO, PhaseFunction::Isotropic).unwrap();
    assert_eq!(transmittance(&m0, f64::INFINITY), DVec3::ONE);
    assert_eq!(transmittance(&medium, 0.0), DVec3::ONE);
}

/// The test's own ray through an NDC point for a `look_at_mat4` camera with vertical field of
/// view `fov`: forward + x·tan(fov/2)·aspect·right + y·tan(fov/2)·up.
fn expected_ray(eye: DVec3, target: DVec3, fov: f64, aspect: f64, x: f64, y: f64) -> DVec3 {
    let f = (target - eye).normalize();
    let r = f.cross(DVec3::Y).normalize();
    let u = r.cross(f);
    let k = (fov / 2.0).tan();
    (f + r * (x * k * aspect) + u * (y * k)).normalize()
}

fn ground_or_sky(e: DVec3, v: DVec3) -> f64 {
    if v.y < 0.0 {
        -e.y / v.y
    } else {
        f64::INFINITY
    }
}

#[test]
fn image_matches_per_pixel_rays_for_standard_and_reversed_z() {
    let (w, h) = (16u32, 12u32);
    let aspect = w as f32 / h as f32;
    let fov = 1.0f32;
    let eye = Vec3::new(0.0, 1.0, 6.0);
    let target = Vec3::new(0.0, 1.0, 0.0);
    let view = look_at_mat4(eye, target, Vec3::Y);
    let medium = Medium::new(
        Vec3::splat(0.1),
        Vec3::splat(0.02),
        PhaseFunction::HenyeyGreenstein { g: 0.5 },
    )
    .unwrap();
    let light = PointLight::new(Vec3::new(0.5, 2.5, -1.0), Vec3::splat(20.0)).unwrap();
    let occluders = [Occluder::Sphere(Sphere::new(
        DVec3::new(0.3, 1.6, -0.4),
        0.4,
    ))];
    let projections = [
        (
            "directx::perspective (standard Z)",
            directx::perspective(fov, aspect, 0.1, 100.0),
        ),
        (
            "directx::perspective_infinite_reverse (reversed Z, infinite far)",
            directx::perspective_infinite_reverse(fov, aspect, 0.1),
        ),
    ];
    let mut images = Vec::new();
    for (name, projection) in projections {
        let camera = Camera::new(view, projection).unwrap();
        let image = inscatter_image(&camera, w, h, ground_or_sky, &medium, &light, &occluders);
        assert_eq!(image.len(), (w * h) as usize);
        assert!(image
            .iter()
            .all(|p| p.is_finite() && p.min_element() >= 0.0));
        let mut worst_dir = 0.0f64;
        let mut worst_val = 0.0f64;
        for (px, py) in [
            (0, 0),
            (w - 1, 0),
            (7, 5),
            (3, h - 1),
            (w - 1, h - 1),
            (10, 2),
        ] {
            let ndc = pixel_ndc(w, h, px, py);
            let (e, v) = camera_ray(&camera, ndc);
            let expected = expected_ray(
                eye.as_dvec3(),
                target.as_dvec3(),
                fov as f64,
                aspect as f64,
                ndc.x,
                ndc.y,
            );
            worst_dir = worst_dir
                .max(v.angle_between(expected))
                .max((e - eye.as_dvec3()).length());
            let value = inscatter(
                eye.as_dvec3(),
                expected,
                ground_or_sky(eye.as_dvec3(), expected),
                &medium,
                &light,
                &occluders,
            );
            worst_val = worst_val.max(rel_err(image[(py * w + px) as usize], value));
        }
        println!(
            "{name}: max ray direction error {worst_dir:.2e} rad, max relative pixel \
             difference {worst_val:.2e}"
        );
        // The camera matrices are f32 (relative rounding ~6e-8), so the unprojected direction
        // is off by ~1e-7 rad; the radiance of these pixels changes by less than 1e-5 for
        // such a change (no pixel here grazes a shadow edge or passes near the light).
        assert!(worst_dir < 1e-6, "direction error {worst_dir}");
        assert!(worst_val < 1e-5, "pixel error {worst_val}");
        images.push(image);
    }
    let diff = images[0]
        .iter()
        .zip(&images[1])
        .map(|(a, b)| rel_err(*a, *b))
        .fold(0.0, f64::max);
    println!("standard vs reversed-Z image: max relative difference {diff:.2e}");
    // Same view, same rays up to f32 rounding of two different matrices (see above).
    assert!(diff < 1e-4, "{diff}");
}

#[test]
fn image_128_with_a_sphere_is_finite() {
    let view = look_at_mat4(Vec3::new(0.0, 1.0, 6.0), Vec3::new(0.0, 1.0, 0.0), Vec3::Y);
    let camera = Camera::new(view, directx::perspective_infinite_reverse(1.0, 1.0, 0.1)).unwrap();
    let medium = Medium::new(
        Vec3::splat(0.1),
        Vec3::splat(0.02),
        PhaseFunction::HenyeyGreenstein { g: 0.7 },
    )
    .unwrap();
    let light = PointLight::new(Vec3::new(0.5, 2.5, -1.0), Vec3::splat(20.0)).unwrap();
    let occluders = [Occluder::Sphere(Sphere::new(
        DVec3::new(0.3, 1.6, -0.4),
        0.4,
    ))];
    let start = Instant::now();
    let image = inscatter_image(
        &camera,
        128,
        128,
        ground_or_sky,
        &medium,
        &light,
        &occluders,
    );
    let elapsed = start.elapsed();
    let max = image.iter().map(|p| p.max_element()).fold(0.0, f64::max);
    println!(
        "128×128 with a sphere: {elapsed:.2?} ({} threads), brightest pixel {max:.3e}",
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    assert!(image.iter().all(|p| p.is_finite()));
    // No wall-clock bound (the time is printed): timings on a shared machine are not test
    // assertions.
}

#[test]
fn random_rays_across_scales_are_finite_and_consistent() {
    // Scene scales 1e-2 … 1e4, optical depths 1e-4 … 1e2, strongly forward and backward
    // phases, random ds (including sky), random occluders near the ray.
    let mut rng = Rng::new(42);
    let phases = [
        PhaseFunction::Isotropic,
        PhaseFunction::HenyeyGreenstein { g: 0.95 },
        PhaseFunction::HenyeyGreenstein { g: -0.95 },
        PhaseFunction::MieMurky,
        PhaseFunction::Rayleigh,
    ];
    let mut worst = 0.0f64;
    let mut worst_excess = 0.0f64;
    let rays = 1000;
    for i in 0..rays {
        let scale = 10f64.powf(-2.0 + 6.0 * rng.next());
        let tau = 10f64.powf(-4.0 + 6.0 * rng.next());
        let e = rng.vec(-1.0, 1.0) * scale;
        let p = rng.vec(-1.0, 1.0) * scale;
        let d = (p - e).length();
        let k = (tau / d) as f32;
        let medium = Medium::new(
            Vec3::new(1.0, 0.5, 0.25) * k * 0.5,
            Vec3::new(0.0, 0.5, 2.0) * k * 0.5,
            phases[i % phases.len()],
        )
        .unwrap();
        let light = PointLight::new(p.as_vec3(), Vec3::splat((scale * scale) as f32)).unwrap();
        let p = light.position().as_dvec3();
        let v = rng.vec(-1.0, 1.0).normalize();
        let ds = match i % 4 {
            0 => f64::INFINITY,
            _ => 10f64.powf(-3.0 + 4.0 * rng.next()) * (p - e).length(),
        };
        let open = inscatter(e, v, ds, &medium, &light, &[]);
        let closed = inscatter_closed_form(e, v, ds, &medium, &light);
        assert!(
            open.is_finite() && closed.is_finite(),
            "ray {i}: {open} {closed}"
        );
        worst = worst.max(rel_err(open, closed));
        // An occluder somewhere between the ray and the light can only darken the ray.
        let x = rng.next() * ds.min(3.0 * (p - e).length());
        let c = (e + v * x).lerp(p, 0.2 + 0.6 * rng.next());
        let occluders = [Occluder::Sphere(Sphere::new(
            c,
            0.3 * rng.next() * (p - c).length(),
        ))];
        let shadowed = inscatter(e, v, ds, &medium, &light, &occluders);
        assert!(shadowed.is_finite() && shadowed.min_element() >= 0.0);
        let excess = ((shadowed - open) / open.max(DVec3::splat(f64::MIN_POSITIVE))).max_element();
        worst_excess = worst_excess.max(excess);
    }
    println!(
        "{rays} random rays: max relative error quadrature vs closed form {worst:.3e}, \
         max relative excess of a shadowed ray over the open one {worst_excess:.3e}"
    );
    metric::accuracy(
        &format!("{rays} random rays: quadrature against the closed form; a shadowed ray's excess over the open one"),
        format!("max {worst:.1e}; {worst_excess:.1e}"),
        "1e-9; 1e-10",
    );
    // Same tolerance budget as the grid test above.
    assert!(worst <= 1e-9, "{worst:e}");
    // Shadowed ≤ open up to the quadrature tolerance (1e-12 each, plus round-off).
    assert!(worst_excess <= 1e-10, "{worst_excess:e}");
}
