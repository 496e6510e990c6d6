//! Tests of the reference's directional light (`volshadow::reference`): the quadrature against
//! the closed form on unshadowed rays, exact lit intervals against dense sampling of the
//! half-line visibility test, a mesh box against the same box as a cuboid, and random shadowed
//! rays against a brute-force midpoint rule.
//!
//! `cargo test --test cpu reference_directional:: -- --nocapture` prints the measured figures;
//! `VOLSHADOW_SEED=<n>` runs one seed of the random test alone.

use volshadow_harness::metric;
use volshadow_harness::rng::{self, rel_err};

use volshadow::glam::{DQuat, DVec3, Vec3};
use volshadow::reference::*;
use volshadow::{DirectionalLight, Medium, PhaseFunction, PointLight};

const PHASES: [PhaseFunction; 4] = [
    PhaseFunction::Isotropic,
    PhaseFunction::HenyeyGreenstein { g: 0.9 },
    PhaseFunction::HenyeyGreenstein { g: -0.9 },
    PhaseFunction::Rayleigh,
];

fn sun() -> DirectionalLight {
    DirectionalLight::new(Vec3::new(0.3, -1.0, 0.2), Vec3::new(1.0, 0.8, 0.5)).unwrap()
}

/// A medium whose extinction is `sigma_t` in every channel, scattering 40–100% of it.
fn medium(sigma_t: f64, phase: PhaseFunction) -> Medium {
    let t = sigma_t as f32;
    let s = Vec3::new(0.4, 0.7, 1.0) * t;
    Medium::new(s, Vec3::splat(t) - s, phase).unwrap()
}

/// Unit ray directions: towards the light, along it, across it, and a few in between.
fn directions(light: &DirectionalLight) -> Vec<DVec3> {
    let d = light.direction().as_dvec3();
    let across = d.cross(DVec3::X).normalize();
    let mut dirs = vec![
        -d,
        d,
        across,
        (across - d).normalize(),
        (across + d).normalize(),
    ];
    dirs.extend([
        DVec3::Y,
        DVec3::new(-0.6, 0.2, 0.77).normalize(),
        (-d + 1e-3 * across).normalize(),
    ]);
    dirs
}

#[test]
fn light_rejects_bad_input() {
    let e = Vec3::ONE;
    for (dir, irr) in [
        (Vec3::ZERO, e),
        (Vec3::new(f32::NAN, 0.0, 1.0), e),
        (Vec3::X, Vec3::new(1.0, -1.0, 0.0)),
        (Vec3::X, Vec3::ZERO),
        (Vec3::X, Vec3::new(f32::INFINITY, 0.0, 0.0)),
    ] {
        assert!(DirectionalLight::new(dir, irr).is_err(), "{dir} {irr}");
    }
    // Tiny and huge finite directions normalise (to within f32 rounding).
    for dir in [Vec3::new(1e-40, 0.0, 1e-40), Vec3::splat(3e38)] {
        let l = DirectionalLight::new(dir, e).unwrap();
        assert!((l.direction().length() - 1.0).abs() <= 1e-6, "{dir}");
    }
}

/// Closed form against quadrature over σt ∈ {0, 1e-6, 1e-2, 1, 100}/size at scene sizes 1e-2
/// and 1e5, sky and surface rays, four phase functions: ≤ 1e-10 relative (the quadrature's
/// tolerance is 1e-12; the closed form's `expm1` form is exact to a few ulps), no NaN or Inf.
/// Also a far point light (`I = E·D²`, `D` = 1e7 scene sizes) in a thin medium against the
/// directional value, which checks the scattering-angle convention independently: ≤ 1e-4
/// (the point light's angle and distance vary by ~1e-7 relative over the ray, and HG 0.9's
/// slope magnifies angle errors by < 100).
#[test]
fn closed_form_matches_quadrature_on_unshadowed_rays() {
    let light = sun();
    let mut worst = 0.0f64;
    let mut count = 0;
    for size in [1e-2, 1e5] {
        let origins = [DVec3::ZERO, DVec3::new(0.3, -0.7, 0.2) * size];
        for k in [0.0, 1e-6, 1e-2, 1.0, 100.0] {
            for phase in PHASES {
                let m = medium(k / size, phase);
                for &o in &origins {
                    for v in directions(&light) {
                        for ds in [f64::INFINITY, size, 0.37 * size, 1e-4 * size] {
                            let q = inscatter_directional(o, v, ds, &m, &light, &[]);
                            let c = inscatter_directional_closed_form(o, v, ds, &m, &light);
                            assert!(q.is_finite() && c.is_finite(), "{q} {c}");
                            let e = rel_err(q, c);
                            assert!(
                                e <= 1e-10,
                                "size {size} σt {k}/size {phase:?} ds {ds}: {q} vs {c}: {e:e}"
                            );
                            assert!(k == 0.0 || c.max_element() > 0.0, "zero at σt {k}/size");
                            worst = worst.max(e);
                            count += 1;
                        }
                    }
                }
            }
        }
    }
    println!("closed form vs quadrature: {count} rays, worst relative error {worst:e}");
    metric::accuracy(
        &format!("{count} unshadowed rays, scene sizes 1e-2 and 1e5, σt 0…100 per size, 4 phases: closed form against the quadrature"),
        format!("max {worst:.1e}"),
        "1e-10 (the quadrature's tolerance is 1e-12)",
    );

    let mut worst_point = 0.0f64;
    for phase in PHASES {
        let m = medium(1e-12, phase);
        let d = light.direction().as_dvec3();
        let far = 1e7;
        let e = light.irradiance().as_dvec3();
        for v in directions(&light) {
            let p = PointLight::new((-d * far).as_vec3(), (e * far * far).as_vec3()).unwrap();
            // Divide out the point light's own f32 rounding of position and intensity, and
            // its light-path attenuation exp(−σt·D).
            let pos = p.position().as_dvec3();
            let dist = pos.length();
            let scale = (e * dist * dist) / p.intensity().as_dvec3()
                * (m.sigma_t().as_dvec3() * dist).exp();
            let light_dir = DirectionalLight::new((-pos).as_vec3(), light.irradiance()).unwrap();
            let want = inscatter_directional_closed_form(DVec3::ZERO, v, 1.0, &m, &light_dir);
            let got = inscatter(DVec3::ZERO, v, 1.0, &m, &p, &[]) * scale;
            let err = rel_err(want, got);
            assert!(
                err <= 1e-4,
                "{phase:?} {v}: {want} vs far point light {got}: {err:e}"
            );
            worst_point = worst_point.max(err);
        }
    }
    println!("directional vs far point light: worst relative difference {worst_point:e}");
    metric::accuracy(
        "the sun against a point light 1e7 scene sizes away, thin medium, 4 phases",
        format!("max {worst_point:.1e}"),
        "1e-4 (the point light's angle varies by ~1e-7 over the ray, HG 0.9 magnifies it < 100×)",
    );
}

/// The direction of travel of `light` in f64, normalised as the reference does.
fn travel(light: &DirectionalLight) -> DVec3 {
    light.direction().as_dvec3().normalize()
}

/// The distances in `(0, ds)` where `ray_blocked` towards the light changes along the ray,
/// found by dense sampling (`n` samples) and bisection to 1e-14·ds.
fn sampled_transitions(
    o: DVec3,
    v: DVec3,
    ds: f64,
    l: DVec3,
    occ: &[Occluder],
    n: usize,
) -> Vec<f64> {
    let blocked = |x: f64| occ.iter().any(|oc| oc.ray_blocked(o + v * x, l));
    let mut out = Vec::new();
    let h = ds / n as f64;
    let mut prev = blocked(0.0);
    for i in 1..=n {
        let b = blocked(i as f64 * h);
        if b != prev {
            let (mut lo, mut hi) = ((i - 1) as f64 * h, i as f64 * h);
            while hi - lo > 1e-14 * ds {
                let mid = 0.5 * (lo + hi);
                if blocked(mid) == prev {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            out.push(0.5 * (lo + hi));
            prev = b;
        }
    }
    out
}

/// The interval ends strictly inside `(0, ds)`.
fn breakpoints(intervals: &[(f64, f64)], ds: f64) -> Vec<f64> {
    intervals
        .iter()
        .flat_map(|&(a, b)| [a, b])
        .filter(|&x| x > 0.0 && x < ds)
        .collect()
}

/// Random rays through the box `[-2, 2]³`, each checked against sampled transitions: the same
/// number of breakpoints, each within `tol` of its sampled transition. Returns how many
/// breakpoints were checked, how many `on` accepts and the worst distance.
fn check_against_sampling(
    occluders: &[Occluder],
    light: &DirectionalLight,
    seed: u64,
    rays: usize,
    on: impl Fn(DVec3) -> bool,
) -> (usize, usize, f64) {
    let l = -travel(light);
    let mut rng = fastrand::Rng::with_seed(seed);
    let mut r = || rng.f64() * 2.0 - 1.0;
    let (mut checked, mut accepted, mut worst) = (0, 0, 0.0f64);
    for i in 0..rays {
        let o = DVec3::new(r(), r(), r()) * 2.0;
        let v = DVec3::new(r(), r(), r()).normalize();
        let ds = 4.0;
        let exact = breakpoints(&directional_lit_intervals(o, v, ds, light, occluders), ds);
        let sampled = sampled_transitions(o, v, ds, l, occluders, 20_000);
        assert_eq!(
            exact.len(),
            sampled.len(),
            "ray {i} ({o}, {v}): {exact:?} vs sampled {sampled:?}"
        );
        for (x, s) in exact.iter().zip(&sampled) {
            worst = worst.max((x - s).abs());
            // 1e-9 of the scene size (≈1): rounding of the crossings is ~1e-15.
            assert!(
                (x - s).abs() <= 1e-9,
                "ray {i}: breakpoint {x} vs sampled {s}"
            );
            checked += 1;
            accepted += on(o + v * x) as usize;
        }
    }
    println!("{checked} breakpoints, worst distance to the sampled transition {worst:e}");
    (checked, accepted, worst)
}

/// A sphere's shadow: the lit intervals' ends are the sampled transitions of `ray_blocked`,
/// within 1e-9, and some of them lie on the shadow cylinder away from the sphere (so that the
/// cylinder's breakpoints are exercised, not only the sphere's).
#[test]
fn sphere_intervals_match_sampled_visibility() {
    let light = sun();
    let sphere = Sphere::new(DVec3::new(0.1, -0.2, 0.05), 0.6);
    let occ = [Occluder::from(sphere)];
    let off_sphere = |p: DVec3| ((p - sphere.center).length() - sphere.radius).abs() > 1e-6;
    let (checked, on_cylinder, worst) = check_against_sampling(&occ, &light, 7, 300, off_sphere);
    println!("sphere: {on_cylinder} of {checked} breakpoints on the cylinder");
    metric::accuracy(
        "a sphere's shadow, 300 random rays: lit-interval ends against sampled visibility; ends on the shadow cylinder",
        format!("max {worst:.1e} ({checked} ends); {on_cylinder} on the cylinder"),
        "1e-9 of the scene size (rounding is ~1e-15); ≥ 50",
    );
    // Random rays through [-2, 2]³ cross the cylinder (length ~2 beyond the sphere) often.
    assert!(on_cylinder >= 50, "only {on_cylinder} cylinder breakpoints");
}

/// A rotated box as a 12-triangle mesh and as a `Cuboid`: the same lit intervals (ends within
/// 1e-12 of each other: the same planes computed two ways), and both against sampling.
#[test]
fn mesh_box_matches_cuboid() {
    let light = sun();
    let cuboid = Cuboid::new(
        DVec3::new(0.2, 0.1, -0.1),
        DVec3::new(0.7, 0.3, 0.5),
        DQuat::from_euler(volshadow::glam::EulerRot::XYZ, 0.3, -0.5, 0.8),
    );
    let as_box = [Occluder::from(cuboid)];
    let as_mesh = [Occluder::from(cuboid.to_mesh())];
    let mut rng = fastrand::Rng::with_seed(11);
    let mut r = || rng.f64() * 2.0 - 1.0;
    let (mut compared, mut worst) = (0, 0.0f64);
    for i in 0..2000 {
        let o = DVec3::new(r(), r(), r()) * 2.0;
        let v = DVec3::new(r(), r(), r()).normalize();
        let ds = if i % 4 == 0 { f64::INFINITY } else { 4.0 };
        let a = directional_lit_intervals(o, v, ds, &light, &as_box);
        let b = directional_lit_intervals(o, v, ds, &light, &as_mesh);
        assert_eq!(
            a.len(),
            b.len(),
            "ray {i} ({o}, {v}): box {a:?} vs mesh {b:?}"
        );
        for (p, q) in a.iter().zip(&b) {
            let end = if p.1 == q.1 { 0.0 } else { (p.1 - q.1).abs() };
            let e = (p.0 - q.0).abs().max(end);
            assert!(e <= 1e-12, "ray {i}: box {a:?} vs mesh {b:?}");
            worst = worst.max(e);
            compared += 1;
        }
    }
    println!("mesh vs cuboid: {compared} intervals, worst end difference {worst:e}");
    metric::accuracy(
        "a rotated box as a 12-triangle mesh against it as a cuboid, 2000 random rays: lit-interval ends",
        format!("max {worst:.1e} ({compared} intervals)"),
        "1e-12 (the same planes computed two ways); > 1000 intervals",
    );
    assert!(compared > 1000);
    let (mesh_checked, _, mesh_worst) = check_against_sampling(&as_mesh, &light, 5, 150, |_| true);
    let (box_checked, _, box_worst) = check_against_sampling(&as_box, &light, 5, 150, |_| true);
    metric::accuracy(
        "a rotated box, 150 random rays: lit-interval ends against sampled visibility, as a mesh / as a cuboid",
        format!("max {mesh_worst:.1e} ({mesh_checked} ends) / {box_worst:.1e} ({box_checked} ends)"),
        "1e-9 of the scene size",
    );
}

/// Random rays and scenes: a random sun, a medium with `σt·ds ≤ 3`, and 1–4 occluders (sphere,
/// rotated box, closed mesh, open quad) placed so that each shadows the ray somewhere.
/// The quadrature over the exact lit intervals against a midpoint rule of `N = 50 000`
/// samples of `ray_blocked`: the rule's error is at most `h·σs·p·E` per visibility
/// transition (≤ 2 per convex occluder, so ≤ 8) plus `ds·h²·σt²/24` of it for the smooth part,
/// while the unshadowed value `U ≥ σs·p·E·ds·(1 − e⁻³)/3`; so `|error| ≤ 8·(ds/N)/(0.317·ds)·U
/// ≈ 5e-4·U`, asserted as ≤ 1e-3·U. Ignoring the occluders must fail the same bound.
#[test]
fn random_shadowed_rays_match_midpoint_rule() {
    const N: usize = 50_000;
    let (mut worst, mut failed, mut unshadowed_passed) = (0.0f64, Vec::new(), 0);
    for seed in rng::seeds(0..200) {
        let mut rng = fastrand::Rng::with_seed(seed);
        let mut r = || rng.f64() * 2.0 - 1.0;
        let dir = DVec3::new(r(), r() - 1.5, r());
        let light = DirectionalLight::new(dir.as_vec3(), Vec3::new(1.0, 0.7, 0.4)).unwrap();
        let l = -travel(&light);
        let o = DVec3::new(r(), r(), r());
        let v = DVec3::new(r(), r(), r()).normalize();
        let ds = 2.0 + r();
        let sigma_t = (1.0 + r()) * 1.5 / ds;
        let ph = PHASES[(seed % 4) as usize];
        let m = medium(sigma_t, ph);
        let count = 1 + (seed / 4 % 4) as usize;
        let occluders: Vec<Occluder> = (0..count)
            .map(|k| {
                let x = ds * (0.5 + 0.45 * r());
                let size = 0.1 + 0.1 * (1.0 + r());
                let c = o + v * x + l * (0.3 + 0.5 * (1.0 + r()));
                let rot = DQuat::from_scaled_axis(DVec3::new(r(), r(), r()) * 2.0);
                match (seed as usize + k) % 4 {
                    0 => Sphere::new(c, size).into(),
                    1 => Cuboid::new(c, DVec3::new(1.0, 0.5, 0.7) * size, rot).into(),
                    2 => Cuboid::new(c, DVec3::splat(size), rot).to_mesh().into(),
                    _ => {
                        let q = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
                            .map(|(a, b)| c + rot * DVec3::new(a, b, 0.0) * size);
                        TriangleMesh::new(q.to_vec(), vec![[0, 1, 2], [0, 2, 3]]).into()
                    }
                }
            })
            .collect();
        if std::env::var("VOLSHADOW_SEED").is_ok() {
            println!("{occluders:?}\nlight {light:?} o {o} v {v} ds {ds}");
            for oc in &occluders {
                let one = std::slice::from_ref(oc);
                println!(
                    "exact {:?}\nsampled {:?}",
                    directional_lit_intervals(o, v, ds, &light, one),
                    sampled_transitions(o, v, ds, l, one, 20000)
                );
            }
        }
        let got = inscatter_directional(o, v, ds, &m, &light, &occluders);
        let unshadowed = inscatter_directional_closed_form(o, v, ds, &m, &light);
        let h = ds / N as f64;
        // The integrand at x = 0, from the public phase function: σs·p(−v·d)·E.
        let mu = -v.dot(travel(&light));
        let one = m.sigma_s().as_dvec3() * phase(&m.phase(), mu) * light.irradiance().as_dvec3();
        let sigma = m.sigma_t().as_dvec3();
        let midpoint: DVec3 = (0..N)
            .map(|i| (i as f64 + 0.5) * h)
            .filter(|&x| !occluders.iter().any(|oc| oc.ray_blocked(o + v * x, l)))
            .map(|x| one * (-sigma * x).exp() * h)
            .sum();
        let err = ((got - midpoint).abs() / unshadowed).max_element();
        worst = worst.max(err);
        assert!(
            got.is_finite() && (got - unshadowed).max_element() <= 1e-12 * unshadowed.max_element()
        );
        if err.is_nan() || err > 1e-3 {
            failed.push(format!(
                "seed {seed}: {got} vs midpoint {midpoint} (U {unshadowed}): {err:e}"
            ));
        }
        if ((unshadowed - midpoint).abs() / unshadowed).max_element() <= 1e-3 {
            unshadowed_passed += 1;
        }
    }
    println!("random rays: worst |quadrature − midpoint|/U = {worst:e}; ignoring occluders passes {unshadowed_passed}");
    metric::accuracy(
        &format!("{} random shadowed rays, 1–4 occluders: quadrature against a midpoint rule of {N} samples, |error|/unshadowed; occluders ignored (must fail)", rng::seeds(0..200).len()),
        format!("max {worst:.1e}; ignored passes on {unshadowed_passed} seeds"),
        "1e-3 (the rule's own error ≤ 5e-4); 0 seeds",
    );
    assert!(
        failed.is_empty(),
        "rerun one with VOLSHADOW_SEED=<seed>:\n{}",
        failed.join("\n")
    );
    // Discriminative: every scene is shadowed by construction, so ignoring occluders fails.
    assert_eq!(
        unshadowed_passed, 0,
        "ignoring the occluders passed on some seeds"
    );
}
