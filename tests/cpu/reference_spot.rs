//! Spot lights in the f64 reference (`volshadow::reference`): the cone's exact intervals against
//! brute-force sampling of the cone test, rays wholly outside and wholly inside the cone, a ray
//! across the cone's edge against a fine midpoint sum, and extreme cone angles.
//!
//! The cone test used here is written again from its definition
//! (`direction·(X − P) ≥ cos_half_angle·|X − P|`, the light's f32 values converted to f64), so
//! the sampling shares nothing with the reference's ray–cone quadratic.

use volshadow_harness::rng::{self, rel_err};

use std::f64::consts::PI;

use rng::Rng;
use volshadow::glam::camera::rh::proj::directx;
use volshadow::glam::camera::rh::view::look_at_mat4;
use volshadow::glam::{DVec3, Vec3};
use volshadow::reference::*;
use volshadow::{Camera, Light, Medium, PhaseFunction, PointLight, SpotLight};

/// The cone test from `SpotLight::cos_half_angle`'s documentation.
fn in_cone(spot: &SpotLight, x: DVec3) -> bool {
    let w = x - spot.position().as_dvec3();
    spot.direction().as_dvec3().dot(w) >= f64::from(spot.cos_half_angle()) * w.length()
}

/// Lit by `spot` at `x`: inside the cone and no occluder on the segment to the light.
fn lit(spot: &SpotLight, occluders: &[Occluder], x: DVec3) -> bool {
    let p = spot.position().as_dvec3();
    in_cone(spot, x) && !occluders.iter().any(|o| o.segment_blocked(x, p))
}

/// Two unit vectors perpendicular to `a` and to each other.
fn basis(a: DVec3) -> (DVec3, DVec3) {
    let u = a.any_orthonormal_vector();
    (u, a.cross(u).normalize())
}

/// Outcome of sampling one ray against its intervals.
struct Sampled {
    intervals: Vec<(f64, f64)>,
    /// Changes of the sampled test between consecutive samples.
    flips: usize,
    /// Samples that disagreed with the intervals (each within `MARGIN` of an end, or the
    /// check fails).
    excused: usize,
    /// Largest distance of a disagreeing sample from its nearest interval end.
    worst: f64,
    /// Largest distance of an interval end inside `(0, ds)` from the edge that bisection on
    /// the sampled test finds within ±1e-7 of it.
    end_error: f64,
}

/// How close to an interval end a sample may disagree with it: the brief's 1e-9. The roots
/// are computed to a few ulps of the ray's scale (≤ 20 here), ~1e-14, far inside it.
const MARGIN: f64 = 1e-9;

/// Samples `samples` points uniformly in `(0, span)` (`span = ds`, or a finite stretch past
/// every end when `ds = ∞`) and checks `light_intervals` against the sampled `lit` test.
fn check(
    e: DVec3,
    v: DVec3,
    ds: f64,
    spot: &SpotLight,
    occluders: &[Occluder],
    samples: usize,
) -> Sampled {
    let intervals = light_intervals(e, v, ds, spot, occluders);
    // Distances along the ray are in units of the normalised direction.
    let v = v.normalize();
    for w in intervals.windows(2) {
        assert!(
            w[0].1 < w[1].0,
            "intervals not sorted and disjoint: {intervals:?}"
        );
    }
    for &(a, b) in &intervals {
        assert!(0.0 <= a && a < b && b <= ds, "{intervals:?}");
    }
    let span = if ds.is_finite() {
        ds
    } else {
        // Past every finite end and the light, far enough that the tail is tested.
        let last = intervals
            .iter()
            .flat_map(|&(a, b)| [a, b])
            .filter(|x| x.is_finite())
            .fold(0.0, f64::max);
        4.0 * last.max((spot.position().as_dvec3() - e).length())
    };
    let ends: Vec<f64> = intervals
        .iter()
        .flat_map(|&(a, b)| [a, b])
        .filter(|x| x.is_finite())
        .collect();
    let mut out = Sampled {
        intervals: intervals.clone(),
        flips: 0,
        excused: 0,
        worst: 0.0,
        end_error: 0.0,
    };
    for &end in ends.iter().filter(|&&x| x > 0.0 && x < ds) {
        let at = |x: f64| lit(spot, occluders, e + v * x);
        let (mut lo, mut hi) = (end - 1e-7, end + 1e-7);
        let lit_lo = at(lo);
        assert_ne!(
            lit_lo,
            at(hi),
            "no edge within 1e-7 of the end {end}: {intervals:?} (e = {e}, v = {v})"
        );
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if mid == lo || mid == hi {
                break;
            }
            if at(mid) == lit_lo {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        out.end_error = out.end_error.max((end - 0.5 * (lo + hi)).abs());
    }
    let mut prev = None;
    for i in 0..samples {
        let x = (i as f64 + 0.5) / samples as f64 * span;
        let sampled = lit(spot, occluders, e + v * x);
        if prev.is_some_and(|p| p != sampled) {
            out.flips += 1;
        }
        prev = Some(sampled);
        let inside = intervals.iter().any(|&(a, b)| a <= x && x <= b);
        if sampled != inside {
            let gap = ends
                .iter()
                .map(|&end| (x - end).abs())
                .fold(f64::INFINITY, f64::min);
            assert!(
                gap <= MARGIN,
                "x = {x}: sampled lit = {sampled}, intervals say {inside} ({gap:e} from an \
                 end): {intervals:?} (e = {e}, v = {v}, ds = {ds}, spot = {spot:?})"
            );
            out.excused += 1;
            out.worst = out.worst.max(gap);
        }
    }
    if !ds.is_finite() {
        // The tail: the last interval reaches ∞ iff a point far out is lit.
        let far = lit(spot, occluders, e + v * (16.0 * span));
        let to_infinity = intervals.last().is_some_and(|iv| iv.1 == f64::INFINITY);
        assert_eq!(far, to_infinity, "tail of {intervals:?}");
    }
    out
}

fn spot(p: DVec3, axis: DVec3, cone_deg: f64, i0: Vec3) -> SpotLight {
    SpotLight::new(
        p.as_vec3(),
        axis.as_vec3(),
        cone_deg.to_radians() as f32,
        i0,
    )
    .unwrap()
}

/// The cone's half angle as the cone test sees it: `acos(c/|a|)` with the f32 values in f64
/// (the f32 `cos_half_angle` and the f32-unit axis each round it by ~1e-8 rad, enough to turn
/// an exactly tangent ray into a 1e-4-long chord).
fn half_angle(spot: &SpotLight) -> f64 {
    (f64::from(spot.cos_half_angle()) / spot.direction().as_dvec3().length()).acos()
}

/// A generator of the cone at polar angle `beta` from the axis and azimuth `phi`, built from
/// the light's own f64 axis.
fn generator(spot: &SpotLight, beta: f64, phi: f64) -> DVec3 {
    let a = spot.direction().as_dvec3().normalize();
    let (u, w) = basis(a);
    a * beta.cos() + (u * phi.cos() + w * phi.sin()) * beta.sin()
}

#[test]
fn cone_intervals_match_brute_force_sampling() {
    let mut rng = Rng::new(0xc0ffee);
    let samples = 100_000;
    let mut rays = 0;
    let mut crossing = 0;
    let mut excused = 0;
    let mut worst = 0.0f64;
    let mut end_error = 0.0f64;
    let mut record = |name: &str, s: &Sampled, must_cross: bool| {
        rays += 1;
        end_error = end_error.max(s.end_error);
        crossing += usize::from(s.flips > 0);
        excused += s.excused;
        worst = worst.max(s.worst);
        if must_cross {
            assert!(s.flips > 0, "{name}: the ray must cross the cone's edge");
        }
    };
    // Random spots and random rays aimed at points near the cone's surface (either side of it,
    // either nappe), from eyes inside and outside the cone; every fourth ray is sky.
    for i in 0..40 {
        let p = rng.vec(-3.0, 3.0);
        let axis = rng.vec(-1.0, 1.0);
        let cone_deg = 10.0 + 160.0 * rng.next();
        let s = spot(p, axis, cone_deg, Vec3::ONE);
        let half = half_angle(&s);
        let beta = half + (rng.next() - 0.5) * 0.3;
        let sign = if i % 5 == 4 { -1.0 } else { 1.0 }; // the nappe behind the light, too
        let target =
            p + generator(&s, beta, 2.0 * PI * rng.next()) * sign * (0.5 + 3.0 * rng.next());
        let e = target + rng.vec(-1.0, 1.0).normalize() * (1.0 + 5.0 * rng.next());
        let v = (target - e).normalize();
        let ds = if i % 4 == 3 {
            f64::INFINITY
        } else {
            (target - e).length() * (1.2 + 2.0 * rng.next())
        };
        let sampled = check(e, v, ds, &s, &[], samples);
        record("random", &sampled, false);
    }
    let s = spot(
        DVec3::new(0.5, 2.0, -1.0),
        DVec3::new(0.2, -1.0, 0.1),
        50.0,
        Vec3::ONE,
    );
    let p = s.position().as_dvec3();
    let a = s.direction().as_dvec3();
    let half = half_angle(&s);
    // Through the apex, from behind the light along the axis: dark, then lit from the apex on.
    // (The f32 axis is unit only to ~6e-8, so the apex is at |p − e|, not exactly 3.)
    let e = p - a * 3.0;
    let r = check(e, a, 8.0, &s, &[], samples);
    println!("through the apex along the axis: {:?}", r.intervals);
    let apex = (p - e).length();
    // The apex is found as the closest approach, exact to a few ulps of 3: 1e-12 is generous.
    assert!(r.intervals.len() == 1 && (r.intervals[0].0 - apex).abs() < 1e-12);
    record("apex on axis", &r, true);
    // Through the apex at an angle inside the cone, and at one outside it (touches only the apex).
    let g_in = generator(&s, 0.5 * half, 1.0);
    let r = check(p - g_in * 2.5, g_in, 6.0, &s, &[], samples);
    // Same: the apex at 2.5 to a few ulps.
    assert!(r.intervals.len() == 1 && (r.intervals[0].0 - 2.5).abs() < 1e-12);
    record("apex inside", &r, true);
    let g_out = generator(&s, half + 0.3, 1.0);
    let r = check(p - g_out * 2.5, g_out, 6.0, &s, &[], samples);
    println!("through the apex outside the cone: {:?}", r.intervals);
    assert!(r.intervals.is_empty(), "{:?}", r.intervals);
    record("apex outside", &r, false);
    // Tangent to the cone: in the tangent plane along a generator, perpendicular to it; touches
    // at one point, so no interval (or one narrower than the rounding of the tangency).
    let g = generator(&s, half, 0.7);
    let t = a.normalize().cross(g).normalize();
    let touch = p + g * 2.0;
    let r = check(touch - t * 3.0001, t, 7.0, &s, &[], samples);
    println!("tangent ray: {:?}", r.intervals);
    // A line a distance δ inside the tangency cuts a chord ~2·√(2ρδ) (ρ ~ 1, the curvature
    // radius here); δ ~ 1e-15 from rounding the construction gives ~1e-7: allow 1e-6.
    assert!(r.intervals.iter().all(|&(a, b)| b - a < 1e-6));
    record("tangent", &r, false);
    // Parallel to a generator (A = 0): one root, lit from there to ∞ when inside-bound.
    let g = generator(&s, half, 2.1);
    let (u, _) = basis(g);
    let e = p + u * 0.3 - g * 2.0;
    let r = check(e, g, f64::INFINITY, &s, &[], samples);
    println!("parallel to a generator, ds = ∞: {:?}", r.intervals);
    record("parallel", &r, false);
    // Eye inside the cone, leaving it; eye inside, staying inside to ∞.
    let e = p + a * 2.0;
    let out = generator(&s, half + 0.6, 0.3);
    let r = check(e, out, 10.0, &s, &[], samples);
    assert!(r.intervals.len() == 1 && r.intervals[0].0 == 0.0 && r.intervals[0].1 < 10.0);
    record("eye inside, leaving", &r, true);
    let r = check(
        e,
        generator(&s, 0.5 * half, 0.3),
        f64::INFINITY,
        &s,
        &[],
        samples,
    );
    assert_eq!(r.intervals, vec![(0.0, f64::INFINITY)]);
    record("eye inside, staying", &r, false);
    // The cone and a sphere's shadow together: the two sets of breakpoints combined.
    let sphere = Occluder::Sphere(Sphere::new(p + a * 2.0, 0.4));
    let e = p + a * 3.5 + a.any_orthonormal_vector() * 4.0;
    let v = (p + a * 3.5 - a.any_orthonormal_vector() * 4.0 - e).normalize();
    let r = check(e, v, 8.0, &s, std::slice::from_ref(&sphere), samples);
    println!("across the cone and a sphere's shadow: {:?}", r.intervals);
    assert!(
        r.intervals.len() >= 2,
        "the shadow must split the cone's interval"
    );
    record("cone + sphere", &r, true);

    println!(
        "cone intervals: {rays} rays × {samples} samples agree with the sampled cone test \
         ({crossing} rays cross an edge; {excused} samples disagreed, the farthest {worst:.2e} \
         from an interval end); interval ends vs the edge bisected on the sampled test: \
         max |difference| {end_error:.2e}"
    );
    // The brief's tolerance: an end may be off by 1e-9 (the rays here are ≤ ~20 long, so
    // that is ~5e-11 relative; the quadratic's roots are good to a few ulps away from
    // tangency).
    assert!(end_error <= MARGIN, "{end_error:e}");
    // The random rays aim within ±0.15 rad of the cone's surface, so most cross it; 30 of the
    // 48 rays is what makes this a test of the edges (measured: see the line above).
    assert!(
        crossing >= 30,
        "too few rays crossed the cone's edge: {crossing}"
    );
}

fn medium() -> Medium {
    Medium::new(
        Vec3::new(0.15, 0.1, 0.05),
        Vec3::new(0.05, 0.02, 0.3),
        PhaseFunction::HenyeyGreenstein { g: 0.6 },
    )
    .unwrap()
}

#[test]
fn rays_wholly_outside_are_zero_and_wholly_inside_equal_the_point_light() {
    let medium = medium();
    let i0 = Vec3::new(10.0, 8.0, 6.0);
    let s = spot(
        DVec3::new(1.0, 3.0, 0.0),
        DVec3::new(0.0, -1.0, 0.2),
        60.0,
        i0,
    );
    let point = PointLight::new(s.position(), i0).unwrap();
    let p = s.position().as_dvec3();
    let a = s.direction().as_dvec3();
    let half = half_angle(&s);

    // Outside: beside the cone, in the nappe behind the light, through the apex at an angle
    // outside the cone, and sky rays that never enter.
    let beside = p + a * 2.0 + a.any_orthonormal_vector() * 5.0;
    let outside = [
        (beside, -a, 10.0),
        (beside, -a, f64::INFINITY),
        (
            p - a * 2.0 + a.any_orthonormal_vector() * 0.3,
            -a,
            f64::INFINITY,
        ),
        (
            p - a * 3.0 - a.any_orthonormal_vector() * 2.0,
            a.any_orthonormal_vector(),
            6.0,
        ),
        (
            p - generator(&s, half + 0.2, 0.0) * 2.0,
            generator(&s, half + 0.2, 0.0),
            f64::INFINITY,
        ),
    ];
    for (e, v, ds) in outside {
        let spot_value = inscatter(e, v, ds, &medium, &s, &[]);
        let point_value = inscatter(e, v, ds, &medium, &point, &[]);
        println!("outside the cone: spot {spot_value}, point light {point_value}");
        // Exactly 0: no lit interval, nothing is integrated.
        assert_eq!(spot_value, DVec3::ZERO);
        assert!(point_value.min_element() > 0.0);
    }

    // Inside: eye in the cone, looking across it and towards the light, finite and sky.
    let mut worst = 0.0f64;
    let inside = [
        (p + a * 3.0, generator(&s, 0.3 * half, 1.0), 4.0),
        (p + a * 3.0, generator(&s, 0.3 * half, 1.0), f64::INFINITY),
        (
            p + generator(&s, 0.5 * half, 2.0) * 6.0,
            generator(&s, 0.5 * half, 2.0),
            f64::INFINITY,
        ),
        (
            p + a * 5.0,
            (p + a * 0.5 + generator(&s, 0.3, 0.0) * 0.1 - (p + a * 5.0)).normalize(),
            4.0,
        ),
    ];
    for (e, v, ds) in inside {
        let spot_value = inscatter(e, v, ds, &medium, &s, &[]);
        let point_value = inscatter(e, v, ds, &medium, &point, &[]);
        assert_eq!(light_intervals(e, v, ds, &s, &[]), vec![(0.0, ds)]);
        let err = rel_err(spot_value, point_value);
        worst = worst.max(err);
        println!(
            "inside the cone: spot {spot_value}, point light {point_value}, rel. diff {err:.1e}"
        );
    }
    println!("wholly inside the cone: max relative difference spot vs point light {worst:.1e}");
    // The brief's 1e-12: the same single interval [0, ds] goes through the same quadrature, so
    // the two are in fact identical.
    assert!(worst <= 1e-12, "{worst:e}");

    // Light::Spot and &Light are accepted the same way.
    let (e, v, ds) = inside[0];
    let as_enum = Light::Spot(s);
    assert_eq!(
        inscatter(e, v, ds, &medium, &as_enum, &[]),
        inscatter(e, v, ds, &medium, &s, &[])
    );
}

/// Henyey–Greenstein, written here again so that the midpoint sum shares nothing with the
/// reference's integrand.
fn hg(g: f64, mu: f64) -> f64 {
    (1.0 - g * g) / (4.0 * PI * (1.0 + g * g - 2.0 * g * mu).powf(1.5))
}

/// Midpoint rule of (1) in x with `n` points and visibility from `lit` (cone test and exact
/// segment test). Returns the sum, the largest integrand value seen and the number of
/// visibility flips between consecutive samples.
#[allow(clippy::too_many_arguments)]
fn midpoint_sum(
    e: DVec3,
    v: DVec3,
    ds: f64,
    s: &SpotLight,
    medium: &Medium,
    g: f64,
    occluders: &[Occluder],
    n: usize,
) -> (DVec3, f64, usize) {
    let p = s.position().as_dvec3();
    let (sigma_s, sigma_t) = (medium.sigma_s().as_dvec3(), medium.sigma_t().as_dvec3());
    let i0 = s.intensity().as_dvec3();
    let step = ds / n as f64;
    let mut sum = DVec3::ZERO;
    let mut max_f = 0.0f64;
    let mut flips = 0;
    let mut prev = None;
    for i in 0..n {
        let x = (i as f64 + 0.5) * step;
        let xp = e + v * x;
        let dist = (xp - p).length();
        let mu = v.dot(p - xp) / dist;
        let f = sigma_s * hg(g, mu) * i0 * (-sigma_t * (dist + x)).exp() / (dist * dist);
        max_f = max_f.max(f.max_element());
        let is_lit = lit(s, occluders, xp);
        if prev.is_some_and(|l| l != is_lit) {
            flips += 1;
        }
        prev = Some(is_lit);
        if is_lit {
            sum += f;
        }
    }
    (sum * step, max_f, flips)
}

/// The cone's edge between `inside` and `outside` (ray distances), by bisection on the sampled
/// test: independent of the reference's quadratic.
fn edge(s: &SpotLight, e: DVec3, v: DVec3, mut inside: f64, mut outside: f64) -> f64 {
    for _ in 0..200 {
        let mid = 0.5 * (inside + outside);
        if mid == inside || mid == outside {
            break;
        }
        if in_cone(s, e + v * mid) {
            inside = mid;
        } else {
            outside = mid;
        }
    }
    0.5 * (inside + outside)
}

#[test]
fn ray_across_the_cone_matches_a_fine_midpoint_sum() {
    let g = 0.6;
    let medium = medium();
    let i0 = Vec3::new(10.0, 8.0, 6.0);
    let s = spot(
        DVec3::new(5.0, 4.0, 0.5),
        DVec3::new(0.1, -1.0, -0.05),
        40.0,
        i0,
    );
    let point = PointLight::new(s.position(), i0).unwrap();
    let p = s.position().as_dvec3();
    let a = s.direction().as_dvec3();
    // (eye, direction, ds, occluders): across the cone below the light; from inside the cone
    // out through its side; across the cone and a sphere's shadow inside it.
    let sphere = Occluder::Sphere(Sphere::new(p + a * 1.5 + DVec3::new(0.3, 0.0, 0.0), 0.35));
    let rays = [
        (
            DVec3::new(0.0, 0.5, 0.0),
            DVec3::new(1.0, 0.0, 0.05).normalize(),
            10.0,
            vec![],
        ),
        (
            p + a * 2.5,
            DVec3::new(-0.4, 0.3, 1.0).normalize(),
            6.0,
            vec![],
        ),
        (
            DVec3::new(0.0, 0.5, 0.0),
            DVec3::new(1.0, 0.0, 0.05).normalize(),
            10.0,
            vec![sphere],
        ),
    ];
    let n = 2_000_000;
    let mut worst_ratio = 0.0f64;
    for (e, v, ds, occluders) in rays {
        let reference = inscatter(e, v, ds, &medium, &s, &occluders);
        let unlimited = inscatter(e, v, ds, &medium, &point, &occluders);
        let (fine, max_f, flips) = midpoint_sum(e, v, ds, &s, &medium, g, &occluders, n);
        let (coarse, _, _) = midpoint_sum(e, v, ds, &s, &medium, g, &occluders, n / 2);
        // Error of the midpoint sum: each cell holding a jump (cone edge or shadow edge) is off
        // by at most step·max f; the smooth part converges as step², so |R_N − R_{N/2}| (which
        // also holds the coarse sum's jump error) bounds the rest generously.
        let step = ds / n as f64;
        let bound = DVec3::splat(flips as f64 * step * max_f) + (fine - coarse).abs();
        let diff = (reference - fine).abs();
        let ratio = (diff / bound).max_element();
        worst_ratio = worst_ratio.max(ratio);
        println!(
            "ray across the cone ({} occluders): reference {reference}, midpoint sum {fine} \
             (N = {n}), |diff| {diff}, sum's error bound {bound} ({flips} edges), relative diff \
             {:.2e}; point light {unlimited}",
            occluders.len(),
            rel_err(reference, fine)
        );
        assert!(flips >= 1, "the ray must cross the cone's edge");
        assert!(
            diff.cmple(bound).all(),
            "reference and midpoint sum differ by {diff}, more than the sum's error {bound}"
        );
        assert!(
            (reference / unlimited).max_element() < 0.9,
            "the cone must matter: {reference} vs {unlimited}"
        );
    }
    println!("max |reference − midpoint sum| / sum's error bound = {worst_ratio:.3}");

    // The same as the point light's integral restricted to the cone's interval [x0, x1], found
    // here by bisection on the cone test: ∫_{x0}^{x1} = exp(−σt·x0) · (the point light's ray
    // from E + x0·v, of length x1 − x0), since the path length d + x shifts by x0.
    let (e, v) = (
        DVec3::new(0.0, 0.5, 0.0),
        DVec3::new(1.0, 0.0, 0.05).normalize(),
    );
    let xs: Vec<f64> = (0..10_000).map(|i| (i as f64 + 0.5) * 1e-3).collect();
    let first = xs.iter().position(|&x| in_cone(&s, e + v * x)).unwrap();
    let last = xs.iter().rposition(|&x| in_cone(&s, e + v * x)).unwrap();
    let x0 = edge(&s, e, v, xs[first], xs[first - 1]);
    let x1 = edge(&s, e, v, xs[last], xs[last + 1]);
    let mut worst = 0.0f64;
    for ds in [10.0, f64::INFINITY] {
        let spot_value = inscatter(e, v, ds, &medium, &s, &[]);
        let restricted =
            transmittance(&medium, x0) * inscatter(e + v * x0, v, x1 - x0, &medium, &point, &[]);
        let err = rel_err(spot_value, restricted);
        worst = worst.max(err);
        println!(
            "cone interval [{x0}, {x1}], ds = {ds}: spot {spot_value}, point light restricted \
             {restricted}, rel. diff {err:.2e}"
        );
    }
    // Both are quadratures to 1e-12 relative with different breakpoints; the ends agree to a
    // few ulps (bisection vs quadratic), and E + x0·v rounds at 1e-16: 1e-10 leaves room.
    assert!(worst <= 1e-10, "{worst:e}");
}

#[test]
fn extreme_cone_angles_give_no_nan() {
    let medium = medium();
    let i0 = Vec3::new(10.0, 8.0, 6.0);
    let p = DVec3::new(0.3, 2.0, -0.5);
    let axis = DVec3::new(0.2, -1.0, 0.3).normalize();
    let point = PointLight::new(p.as_vec3(), i0).unwrap();
    let mut rng = Rng::new(7);
    let mut lit_rays = 0;
    let mut checked = 0;
    let mut max_value = 0.0f64;
    // 0.01° is below what the f32 `cos_half_angle` resolves (it rounds to 1.0): the cone the
    // test `a·w ≥ c·|w|` then describes is set by how far the f32 axis is from unit length. It
    // must still give no NaN.
    // 179° is the widest cone `SpotLight::new` accepts (`SpotLight::MAX_CONE_ANGLE`; 179.99°
    // was checked here before it was refused).
    for cone_deg in [179.0, 0.5, 0.01] {
        let s = spot(p, axis, cone_deg, i0);
        let a = s.direction().as_dvec3();
        let (u, _) = basis(a);
        let mut rays = vec![
            (p - a * 2.0, a, 5.0),                       // through the apex along the axis
            (p - a * 2.0 + u * 1e-3, a, f64::INFINITY),  // just off the axis
            (p + a * 3.0 + u * 1e-3, -a, 10.0),          // towards the light, just off the axis
            (p, a, 4.0),                                 // from the apex
            (p, -a, 4.0),                                // from the apex, backwards
            (p + u * 2.0, -u, f64::INFINITY),            // across the apex's plane
            (p + u * 2.0 + a * 1e-6, -u, f64::INFINITY), // just in front of it
            (p + a * 4.0 + u * 3.0, -u, 10.0),           // across the cone's axis
        ];
        for _ in 0..200 {
            let e = p + rng.vec(-4.0, 4.0);
            let v = rng.vec(-1.0, 1.0).normalize();
            let ds = if rng.next() < 0.3 {
                f64::INFINITY
            } else {
                8.0 * rng.next()
            };
            rays.push((e, v, ds));
        }
        for (e, v, ds) in rays {
            let value = inscatter(e, v, ds, &medium, &s, &[]);
            let open = inscatter(e, v, ds, &medium, &point, &[]);
            // Never NaN or negative; +∞ only on the axis rays through the lit apex, where the
            // point light diverges as well.
            assert!(
                value.to_array().iter().all(|c| !c.is_nan() && *c >= 0.0),
                "cone {cone_deg}°: e {e} v {v} ds {ds}: {value}"
            );
            if !value.is_finite() {
                assert!(!open.is_finite(), "cone {cone_deg}°: {value} vs {open}");
                continue;
            }
            // A cone never lights more than the point light: the same quadrature over a subset
            // of [0, ds], each to 1e-12 relative; 1e-10 leaves room for the split points.
            assert!(
                value.cmple(open * (1.0 + 1e-10)).all(),
                "cone {cone_deg}°: {value} > {open}"
            );
            checked += 1;
            lit_rays += usize::from(value.max_element() > 0.0);
            max_value = max_value.max(value.max_element());
        }
        let r = check(p - a * 2.0 + u * 1e-3, a, 10.0, &s, &[], 100_000);
        println!(
            "cone {cone_deg}°: ray along the axis, 1e-3 off it: intervals {:?} ({} samples \
             disagreed)",
            r.intervals, r.excused
        );
    }
    println!(
        "extreme cones: {checked} finite rays, {lit_rays} of them lit, largest value {max_value:.3e}"
    );
    // Not a tolerance, a coverage check: the 832 rays must include plenty that the cones
    // light (about a third do), or the no-NaN check would only see zeros.
    assert!(lit_rays > 50, "{lit_rays}");
}

#[test]
fn spot_image_is_finite_with_a_dark_outside() {
    let (w, h) = (32u32, 24u32);
    let view = look_at_mat4(Vec3::new(0.0, 1.5, 8.0), Vec3::new(0.0, 1.5, 0.0), Vec3::Y);
    let camera = Camera::new(
        view,
        directx::perspective_infinite_reverse(1.0, w as f32 / h as f32, 0.1),
    )
    .unwrap();
    let s = SpotLight::new(
        Vec3::new(0.0, 3.0, 0.0),
        Vec3::new(0.0, -1.0, 0.0),
        1.6,
        Vec3::splat(20.0),
    )
    .unwrap();
    let ground = |e: DVec3, v: DVec3| if v.y < 0.0 { -e.y / v.y } else { f64::INFINITY };
    let image = inscatter_image(&camera, w, h, ground, &medium(), &s, &[]);
    let dark = image.iter().filter(|p| **p == DVec3::ZERO).count();
    let max = image.iter().map(|p| p.max_element()).fold(0.0, f64::max);
    println!(
        "spot image {w}×{h}: {dark} pixels exactly 0 (never in the cone), brightest {max:.3e}"
    );
    assert!(image
        .iter()
        .all(|p| p.is_finite() && p.min_element() >= 0.0));
    // The cone (half angle 0.8 rad, apex 3 above the ground, radius 3.1 there) fills the
    // middle of the view: the pixels above the light and the ground outside the cone's foot
    // miss it (well over 50 of the 768), the middle crosses it (well over 50 too).
    assert!(dark > 50 && dark < (w * h) as usize - 50, "{dark}");
}
