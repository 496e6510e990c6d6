//! Textured spot lights in the f64 reference (`volshadow::reference::TexturedSpot`): a uniform
//! texture against the untextured spot, rays inside the cone against a fine midpoint sum of the
//! integrand with the texture lookup, the uv mapping, and degenerate rays and textures.
//!
//! The midpoint sums evaluate the texture here again from `LightTexture`'s documentation (the
//! view matrix from glam's own f64 `look_to`, the bilinear filter written out), so they share
//! nothing with the reference's projection, lookup or kink breakpoints.

use volshadow_harness::rng::{self, rel_err};

use std::f64::consts::PI;
use std::time::Instant;

use rng::Rng;
use volshadow::glam::camera::rh::proj::directx;
use volshadow::glam::camera::rh::view::look_at_mat4;
use volshadow::glam::dcamera::rh::view::look_to_mat4;
use volshadow::glam::{DMat4, DVec2, DVec3, Vec3};
use volshadow::reference::*;
use volshadow::scene::LightTexture;
use volshadow::{Camera, Medium, PhaseFunction, SpotLight};

/// A vector in short scientific notation.
fn sci(v: DVec3) -> String {
    format!("[{:.1e}, {:.1e}, {:.1e}]", v.x, v.y, v.z)
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

/// The Henyey–Greenstein `g` of the test medium (f32, as the medium stores it).
const G: f32 = 0.6;

fn medium() -> Medium {
    Medium::new(
        Vec3::new(0.15, 0.1, 0.05),
        Vec3::new(0.05, 0.02, 0.3),
        PhaseFunction::HenyeyGreenstein { g: G },
    )
    .unwrap()
}

/// Henyey–Greenstein, written here again.
fn hg(g: f64, mu: f64) -> f64 {
    (1.0 - g * g) / (4.0 * PI * (1.0 + g * g - 2.0 * g * mu).powf(1.5))
}

/// The cone test from `SpotLight::cos_half_angle`'s documentation.
fn in_cone(s: &SpotLight, x: DVec3) -> bool {
    let w = x - s.position().as_dvec3();
    s.direction().as_dvec3().dot(w) >= f64::from(s.cos_half_angle()) * w.length()
}

/// The spot's texture frame in f64 from glam's `look_to` (up = +Y unless |dir.y| ≥ 0.9).
fn frame(s: &SpotLight) -> DMat4 {
    let dir = s.direction();
    let up = match s.texture_up() {
        Some(up) => up.as_dvec3(),
        None if dir.y.abs() < 0.9 => DVec3::Y,
        None => DVec3::X,
    };
    look_to_mat4(s.position().as_dvec3(), dir.as_dvec3().normalize(), up)
}

/// `LightTexture`'s uv formula with the view matrix `view`.
fn doc_uv(view: &DMat4, tan_half: f64, x: DVec3) -> DVec2 {
    let q = view.transform_point3(x);
    DVec2::new(
        0.5 + 0.5 * q.x / (-q.z * tan_half),
        0.5 - 0.5 * q.y / (-q.z * tan_half),
    )
}

/// Bilinear between texel centres, clamp to edge, written out: the texel value at the
/// continuous texel coordinate `(p, q)` = `(u·W − 0.5, v·H − 0.5)`.
fn doc_bilinear(tex: &LightTexture, uv: DVec2) -> DVec3 {
    let (w, h) = (tex.width() as i64, tex.height() as i64);
    let texel = |i: i64, j: i64| {
        let (i, j) = (i.clamp(0, w - 1), j.clamp(0, h - 1));
        tex.texels()[(j * w + i) as usize].as_dvec3()
    };
    let p = uv.x * w as f64 - 0.5;
    let q = uv.y * h as f64 - 0.5;
    let (i, j) = (p.floor(), q.floor());
    let (fx, fy) = (p - i, q - j);
    let (i, j) = (i as i64, j as i64);
    texel(i, j) * ((1.0 - fx) * (1.0 - fy))
        + texel(i + 1, j) * (fx * (1.0 - fy))
        + texel(i, j + 1) * ((1.0 - fx) * fy)
        + texel(i + 1, j + 1) * (fx * fy)
}

/// The bilinear cell `(⌊p⌋, ⌊q⌋)` of `doc_bilinear` at `uv`, clamped to `[−1, W − 1]` ×
/// `[−1, H − 1]`: it changes exactly where the lookup has a kink (a texel-centre line).
fn doc_cell(tex: &LightTexture, uv: DVec2) -> (i64, i64) {
    let (w, h) = (tex.width() as i64, tex.height() as i64);
    let p = (uv.x * w as f64 - 0.5).floor().clamp(-1.0, (w - 1) as f64) as i64;
    let q = (uv.y * h as f64 - 0.5).floor().clamp(-1.0, (h - 1) as f64) as i64;
    (p, q)
}

/// Midpoint rule of (1) in x with `n` points, the texture looked up with `doc_uv` and
/// `doc_bilinear`, for a ray that stays inside the cone on `[0, ds]`, unoccluded.
///
/// Returns the sum and a bound on the error its kinks add: a change of slope `J` inside one
/// cell of width `h` puts the midpoint rule off by at most `J·h²/8`, and where the bilinear
/// cell changes between samples `i` and `i + 1`, the second differences at `i` and `i + 1`
/// add up to about `J·h`; the bound is `Σ (|Δ²f_i| + |Δ²f_{i+1}|)·h/4` (a factor 2 spare).
fn midpoint_sum(
    e: DVec3,
    v: DVec3,
    ds: f64,
    s: &SpotLight,
    tex: &LightTexture,
    medium: &Medium,
    n: usize,
) -> (DVec3, DVec3) {
    let p = s.position().as_dvec3();
    let view = frame(s);
    let tan_half = (0.5 * f64::from(s.cone_angle())).tan();
    let (sigma_s, sigma_t) = (medium.sigma_s().as_dvec3(), medium.sigma_t().as_dvec3());
    let i0 = s.intensity().as_dvec3();
    let step = ds / n as f64;
    // Neumaier-compensated, so that the rounding of 2·10⁶ additions stays at a few ulps.
    let (mut sum, mut carry) = (DVec3::ZERO, DVec3::ZERO);
    let mut values = Vec::with_capacity(n);
    let mut cells = Vec::with_capacity(n);
    for i in 0..n {
        let x = (i as f64 + 0.5) * step;
        let xp = e + v * x;
        let dist = (xp - p).length();
        let mu = v.dot(p - xp) / dist;
        let uv = doc_uv(&view, tan_half, xp);
        let texel = doc_bilinear(tex, uv);
        cells.push(doc_cell(tex, uv));
        let f = sigma_s * hg(f64::from(G), mu) * i0 * texel * (-sigma_t * (dist + x)).exp()
            / (dist * dist);
        values.push(f);
        for c in 0..3 {
            let t = sum[c] + f[c];
            carry[c] += if sum[c].abs() >= f[c].abs() {
                (sum[c] - t) + f[c]
            } else {
                (f[c] - t) + sum[c]
            };
            sum[c] = t;
        }
    }
    let second = |i: usize| (values[i + 1] - values[i] * 2.0 + values[i - 1]).abs();
    let mut kinks = DVec3::ZERO;
    for i in 1..n.saturating_sub(2) {
        if cells[i] != cells[i + 1] {
            kinks += second(i) + second(i + 1);
        }
    }
    ((sum + carry) * step, kinks * (step / 4.0))
}

fn checkerboard() -> LightTexture {
    LightTexture::checkerboard(8, 8, Vec3::new(1.0, 0.2, 0.05), Vec3::new(0.1, 0.5, 0.9)).unwrap()
}

/// A smooth (trigonometric) gradient sampled on `n × n` texels.
fn gradient(n: u32) -> LightTexture {
    let texels = (0..n * n)
        .map(|k| {
            let (x, y) = ((k % n) as f32 / n as f32, (k / n) as f32 / n as f32);
            Vec3::new(
                0.5 + 0.5 * (3.0 * x + 1.0).sin(),
                y * y,
                0.3 + 0.7 * (2.0 * x * y).cos().abs(),
            )
        })
        .collect();
    LightTexture::new(n, n, texels).unwrap()
}

/// Pseudo-random texels in [0, 1): a kink at every texel-centre line, none of them aligned.
fn noise(n: u32) -> LightTexture {
    let mut rng = Rng::new(0x2545_f491_4f6c_dd1d);
    let mut next = || rng.next() as f32;
    let texels = (0..n * n)
        .map(|_| Vec3::new(next(), next(), next()))
        .collect();
    LightTexture::new(n, n, texels).unwrap()
}

/// The test spot: 50° cone, pointing down and a little sideways.
fn test_spot() -> SpotLight {
    spot(
        DVec3::new(1.0, 4.0, -0.5),
        DVec3::new(0.15, -1.0, 0.1),
        50.0,
        Vec3::new(10.0, 8.0, 6.0),
    )
}

#[test]
fn uniform_texture_is_the_untextured_spot_times_its_colour() {
    let medium = medium();
    let s = test_spot();
    let p = s.position().as_dvec3();
    let a = s.direction().as_dvec3();
    let c = Vec3::new(0.3, 0.7, 1.9);
    let textures = [
        LightTexture::new(1, 1, vec![c]).unwrap(),
        LightTexture::new(16, 16, vec![c; 256]).unwrap(),
        LightTexture::new(64, 3, vec![c; 192]).unwrap(),
    ];
    let sphere = Occluder::Sphere(Sphere::new(p + a * 1.5 + DVec3::new(0.2, 0.0, 0.1), 0.3));
    // (eye, direction, ds, occluders): across the cone, from inside it to the sky, close past
    // the light, through a sphere's shadow, and from outside towards the light.
    let rays = [
        (DVec3::new(-3.0, 1.0, 0.0), DVec3::X, 8.0, vec![]),
        (
            p + a * 2.0,
            DVec3::new(0.3, 0.2, 1.0),
            f64::INFINITY,
            vec![],
        ),
        (
            p + a * 3.0 + DVec3::new(0.0, 0.0, 1.0),
            p + DVec3::new(0.0, 0.0, 1e-3) - (p + a * 3.0 + DVec3::new(0.0, 0.0, 1.0)),
            f64::INFINITY,
            vec![],
        ),
        (DVec3::new(-3.0, 2.5, -0.4), DVec3::X, 9.0, vec![sphere]),
        (
            p + a * 5.0 + DVec3::new(0.5, 0.0, 0.0),
            -(a * 5.0 + DVec3::new(0.5, 0.0, 0.0)),
            4.5,
            vec![],
        ),
    ];
    let mut worst = 0.0f64;
    for tex in &textures {
        let textured = TexturedSpot::new(s, tex);
        for (e, v, ds, occluders) in &rays {
            let plain = inscatter(*e, *v, *ds, &medium, &s, occluders);
            let value = inscatter(*e, *v, *ds, &medium, &textured, occluders);
            let expected = plain * c.as_dvec3();
            let err = rel_err(value, expected);
            worst = worst.max(err);
            assert!(
                plain.min_element() > 0.0,
                "every test ray is lit: {plain} for e = {e}, v = {v}"
            );
            assert_eq!(
                light_intervals(*e, *v, *ds, &textured, occluders),
                light_intervals(*e, *v, *ds, &s, occluders)
            );
            println!(
                "uniform {}x{}: textured {value}, c x untextured {expected}, rel. diff {err:.1e}",
                tex.width(),
                tex.height()
            );
        }
    }
    println!("uniform texture: max relative difference from c x untextured spot {worst:.2e}");
    // The brief's 1e-12: the lookup of a constant texture is exactly c (a + f·(b − a)), the
    // intervals are the same; only the kink breakpoints differ, and both quadratures are
    // converged far below 1e-12.
    assert!(worst <= 1e-12, "{worst:e}");
}

#[test]
fn rays_inside_the_cone_match_a_fine_midpoint_sum() {
    let medium = medium();
    let s = test_spot();
    let p = s.position().as_dvec3();
    let a = s.direction().as_dvec3();
    let n = 2_000_000;
    let textures = [
        ("checkerboard 8x8", checkerboard()),
        ("gradient 32x32", gradient(32)),
        ("noise 48x48", noise(48)),
        ("noise 256x256", noise(256)),
    ];
    // Eyes inside the cone: across it (stopping short of the far side), and towards a point
    // 0.25 from the light (the integrand peaks there).
    let e1 = p + a * 3.5 + DVec3::new(-1.2, 0.0, 0.3);
    let e2 = p + a * 4.0 + DVec3::new(0.5, 0.0, -0.6);
    let rays = [
        (e1, DVec3::new(1.0, 0.05, -0.2).normalize()),
        (
            e2,
            (p + a * 0.6 + DVec3::new(0.25, 0.0, 0.0) - e2).normalize(),
        ),
    ];
    let mut worst_ratio = 0.0f64;
    for (name, tex) in &textures {
        let textured = TexturedSpot::new(s, tex);
        for &(e, v) in &rays {
            // ds: 95% of the way to the cone's far side, so the whole ray is inside the cone.
            let exit = light_intervals(e, v, f64::INFINITY, &s, &[])[0].1;
            let ds = 0.95 * exit;
            assert_eq!(light_intervals(e, v, ds, &textured, &[]), vec![(0.0, ds)]);
            assert!(in_cone(&s, e) && in_cone(&s, e + v * ds));
            let start = Instant::now();
            let reference = inscatter(e, v, ds, &medium, &textured, &[]);
            let time = start.elapsed();
            let (fine, kinks) = midpoint_sum(e, v, ds, &s, tex, &medium, n);
            let (coarse, _) = midpoint_sum(e, v, ds, &s, tex, &medium, n / 2);
            // The midpoint sum's error: on the smooth pieces it converges as step², so it is
            // about |M_N − M_{N/2}|/3 there (|M_N − M_{N/2}| is used); the kinks add errors of
            // order step² too, but of erratic sign (the kink's place in its cell), which the
            // difference does not capture: their bound from `midpoint_sum` is added, and 1e-14
            // relative for the rounding of the integrand and the compensated sum.
            let bound = (fine - coarse).abs() + kinks + fine.abs() * 1e-14;
            let diff = (reference - fine).abs();
            let ratio = (diff / bound).max_element();
            worst_ratio = worst_ratio.max(ratio);
            println!(
                "{name}, ds = {ds:.3}: reference {reference} ({time:?}), midpoint sum {fine}; \
                 relative to the sum: |diff| {}, error estimate {} (of which kinks {}); \
                 max ratio {ratio:.3}",
                sci(diff / fine),
                sci(bound / fine),
                sci(kinks / fine)
            );
            assert!(
                diff.cmple(bound).all(),
                "{name}: reference and midpoint sum differ by {diff}, more than the sum's \
                 error estimate {bound}"
            );
        }
    }
    println!("max |reference - midpoint sum| / sum's error estimate = {worst_ratio:.3}");
}

#[test]
fn uv_mapping_follows_the_documented_frame() {
    let tex = checkerboard();
    let spots = [
        test_spot(),
        spot(
            DVec3::new(0.0, 2.0, 0.0),
            DVec3::new(0.0, -1.0, 0.0),
            30.0,
            Vec3::ONE,
        ),
        spot(
            DVec3::new(-3.0, 1.0, 2.0),
            DVec3::new(1.0, 0.2, -0.4),
            100.0,
            Vec3::ONE,
        ),
        spot(
            DVec3::new(5.0, 0.0, 0.0),
            DVec3::new(0.3, 0.95, 0.0),
            10.0,
            Vec3::ONE,
        ),
        // Up hints of the caller's (`with_texture_up`): oblique, nearly along the axis (2°
        // off it), and a vertical one for a vertical axis's neighbour.
        test_spot()
            .with_texture_up(Vec3::new(0.7, -0.2, 1.3))
            .unwrap(),
        spot(
            DVec3::new(0.0, 2.0, 0.0),
            DVec3::new(0.0, -1.0, 0.0),
            30.0,
            Vec3::ONE,
        )
        .with_texture_up(Vec3::new(
            2f32.to_radians().sin(),
            -2f32.to_radians().cos(),
            0.0,
        ))
        .unwrap(),
        spot(
            DVec3::new(-3.0, 1.0, 2.0),
            DVec3::new(1.0, 0.2, -0.4),
            100.0,
            Vec3::ONE,
        )
        .with_texture_up(Vec3::Y)
        .unwrap(),
    ];
    let (mut axis_err, mut edge_err, mut f32_err) = (0.0f64, 0.0f64, 0.0f64);
    for s in &spots {
        let textured = TexturedSpot::new(*s, &tex);
        let p = s.position().as_dvec3();
        let a = s.direction().as_dvec3().normalize();
        let half = 0.5 * f64::from(s.cone_angle());
        // The frame's +x and +y in world space, from the f32 matrix of `texture_frame`.
        let inv = s.texture_frame().inverse();
        let x_dir = inv.transform_vector3(Vec3::X).as_dvec3();
        let y_dir = inv.transform_vector3(Vec3::Y).as_dvec3();
        let (right, up, forward) = texture_axes(s);
        f32_err = f32_err
            .max((right - x_dir).length())
            .max((up - y_dir).length())
            .max((forward - a).length());
        for r in [0.01, 1.0, 300.0] {
            let uv = textured.uv(p + a * r).unwrap();
            axis_err = axis_err.max((uv - DVec2::splat(0.5)).abs().max_element());
            // On the cone's edge (the f64 half angle) in the frame's +x and +y directions.
            let edge_x = p + (forward * half.cos() + right * half.sin()) * r;
            let edge_y = p + (forward * half.cos() + up * half.sin()) * r;
            let (ux, uy) = (textured.uv(edge_x).unwrap(), textured.uv(edge_y).unwrap());
            edge_err = edge_err
                .max((ux - DVec2::new(1.0, 0.5)).abs().max_element())
                .max((uy - DVec2::new(0.5, 0.0)).abs().max_element());
            // The same with the f32 frame's +x and +y (orthogonal to the axis to ~1e-7).
            let edge_x32 = p + (a * half.cos() + x_dir * half.sin()) * r;
            let edge_y32 = p + (a * half.cos() + y_dir * half.sin()) * r;
            let (ux, uy) = (
                textured.uv(edge_x32).unwrap(),
                textured.uv(edge_y32).unwrap(),
            );
            f32_err = f32_err
                .max((ux - DVec2::new(1.0, 0.5)).abs().max_element())
                .max((uy - DVec2::new(0.5, 0.0)).abs().max_element());
        }
    }
    println!(
        "uv: axis max |uv - (0.5, 0.5)| {axis_err:.1e}; cone edge in the f64 frame's +x/+y: \
         max |uv - (1, 0.5)|, |uv - (0.5, 0)| {edge_err:.1e}; f64 frame vs the f32 \
         texture_frame() (axes and edge points) {f32_err:.1e}"
    );
    // f64 rounding of a few operations.
    assert!(axis_err <= 1e-12, "{axis_err:e}");
    assert!(edge_err <= 1e-12, "{edge_err:e}");
    // The f32 matrix of `texture_frame` rounds its axes at ~6e-8; 1e-6 leaves room.
    assert!(f32_err <= 1e-6, "{f32_err:e}");

    // Random points inside the cones against the formula evaluated with glam's f64 look_to,
    // and `emission` against intensity × the written-out bilinear lookup.
    let mut rng = Rng::new(7);
    let mut next = || rng.next();
    let (mut uv_err, mut emission_err, mut outside) = (0.0f64, 0.0f64, 0);
    for s in &spots {
        let textured = TexturedSpot::new(*s, &tex);
        let view = frame(s);
        let tan_half = (0.5 * f64::from(s.cone_angle())).tan();
        let p = s.position().as_dvec3();
        for _ in 0..2000 {
            let x = p + DVec3::new(next(), next(), next()) * 8.0 - DVec3::splat(4.0);
            let e = textured.emission(x);
            if !in_cone(s, x) {
                assert_eq!(e, DVec3::ZERO);
                outside += 1;
                continue;
            }
            let uv = textured.uv(x).unwrap();
            let expected = doc_uv(&view, tan_half, x);
            uv_err = uv_err.max((uv - expected).abs().max_element());
            let want = s.intensity().as_dvec3() * doc_bilinear(&tex, expected);
            emission_err = emission_err.max((e - want).abs().max_element() / want.max_element());
        }
    }
    println!(
        "random points: max |uv - documented formula| {uv_err:.1e}, emission rel. error \
         {emission_err:.1e}, {outside} points outside the cones gave exactly 0"
    );
    assert!(uv_err <= 1e-12, "{uv_err:e}");
    assert!(emission_err <= 1e-12, "{emission_err:e}");
    assert!(outside > 100);

    // The lookup itself: texel centres give the texel, midway between two centres the mean,
    // beyond the edge the edge texel.
    let g = gradient(5);
    let texel = |i: usize, j: usize| g.texels()[j * 5 + i].as_dvec3();
    let centre = |i: usize, j: usize| DVec2::new((i as f64 + 0.5) / 5.0, (j as f64 + 0.5) / 5.0);
    let mut lookup_err = 0.0f64;
    for j in 0..5 {
        for i in 0..5 {
            lookup_err = lookup_err.max(
                (bilinear(&g, centre(i, j)) - texel(i, j))
                    .abs()
                    .max_element(),
            );
            if i < 4 {
                let mid = (centre(i, j) + centre(i + 1, j)) * 0.5;
                let mean = (texel(i, j) + texel(i + 1, j)) * 0.5;
                lookup_err = lookup_err.max((bilinear(&g, mid) - mean).abs().max_element());
            }
        }
    }
    for (uv, (i, j)) in [
        (DVec2::new(-3.0, 0.02), (0, 0)),
        (DVec2::new(1.0, 1.0), (4, 4)),
        (DVec2::new(f64::INFINITY, -f64::INFINITY), (4, 0)),
        (DVec2::new(0.05, 7.0), (0, 4)),
    ] {
        lookup_err = lookup_err.max((bilinear(&g, uv) - texel(i, j)).abs().max_element());
    }
    println!(
        "bilinear lookup at centres, midpoints and beyond the edges: max error {lookup_err:.1e}"
    );
    assert!(lookup_err <= 1e-15, "{lookup_err:e}");
}

#[test]
fn degenerate_rays_and_textures_give_no_nan() {
    let medium = medium();
    let s = test_spot();
    let p = s.position().as_dvec3();
    let a = s.direction().as_dvec3();
    let side = a.any_orthonormal_vector();
    let one = LightTexture::new(1, 1, vec![Vec3::new(0.5, 0.0, 2.0)]).unwrap();
    let black_centre =
        LightTexture::new(2, 2, vec![Vec3::ZERO, Vec3::ONE, Vec3::ONE, Vec3::ONE]).unwrap();
    let textures = [checkerboard(), one, gradient(1), noise(3), black_centre];
    // Through the apex: along the axis (eye behind and in front of the light), and at an angle
    // inside the cone entering it at the apex; within 1e-12 of the apex (finite, huge);
    // outside the cone; in the light's plane; zero-length ray.
    let inside_generator = (a * 0.95 + side * 0.2).normalize();
    let rays: [(DVec3, DVec3, f64, bool); 9] = [
        (p - a * 3.0, a, 10.0, true),
        (p + a * 3.0, -a, f64::INFINITY, true),
        (p - inside_generator * 2.0, inside_generator, 5.0, true),
        (p - a * 3.0 + side * 1e-12, a, 10.0, false),
        (p + side * 5.0 + a * 2.0, -a, f64::INFINITY, false),
        (p + side * 5.0 - a, -side, 10.0, false),
        (p - a * 2.0, side, f64::INFINITY, false),
        (p + a * 2.0, DVec3::ZERO, 1.0, false),
        (p + a * 2.0, side, 0.0, false),
    ];
    let mut checked = 0;
    let mut infinite = 0;
    for tex in &textures {
        let textured = TexturedSpot::new(s, tex);
        for &(e, v, ds, through_apex) in &rays {
            let value = inscatter(e, v, ds, &medium, &textured, &[]);
            assert!(
                !value.is_nan() && value.min_element() >= 0.0,
                "{value} for e = {e}, v = {v}, ds = {ds}, {}x{} texture",
                tex.width(),
                tex.height()
            );
            if through_apex {
                infinite += (!value.is_finite()) as usize;
            } else {
                assert!(value.is_finite(), "{value}");
            }
            checked += 1;
        }
        // A ray exactly along the axis sees only the centre of the texture: where that is
        // black (all channels), the ray through the apex carries nothing, not ∞.
        let along = inscatter(p - a * 3.0, a, 10.0, &medium, &textured, &[]);
        let centre = bilinear(tex, DVec2::splat(0.5));
        for c in 0..3 {
            assert_eq!(
                along[c] == f64::INFINITY,
                centre[c] > 0.0,
                "{along} vs centre {centre}"
            );
        }
    }
    println!("{checked} degenerate rays, no NaN; {infinite} through the apex were +inf");
    assert!(infinite > 0);

    // A whole image with a textured spot and a 1×1 texture: finite everywhere.
    let (w, h) = (24u32, 16u32);
    let view = look_at_mat4(Vec3::new(0.0, 1.5, 8.0), Vec3::new(0.0, 1.5, 0.0), Vec3::Y);
    let camera = Camera::new(
        view,
        directx::perspective_infinite_reverse(1.0, w as f32 / h as f32, 0.1),
    )
    .unwrap();
    let down = SpotLight::new(
        Vec3::new(0.0, 3.0, 0.0),
        Vec3::new(0.0, -1.0, 0.0),
        1.6,
        Vec3::splat(20.0),
    )
    .unwrap();
    let ground = |e: DVec3, v: DVec3| if v.y < 0.0 { -e.y / v.y } else { f64::INFINITY };
    for tex in [
        checkerboard(),
        LightTexture::new(1, 1, vec![Vec3::splat(0.5)]).unwrap(),
    ] {
        let textured = TexturedSpot::new(down, &tex);
        let image = inscatter_image(&camera, w, h, ground, &medium, &textured, &[]);
        let plain = inscatter_image(&camera, w, h, ground, &medium, &down, &[]);
        assert!(image
            .iter()
            .all(|p| p.is_finite() && p.min_element() >= 0.0));
        // Never brighter than the untextured spot times the largest texel.
        let max_texel = tex
            .texels()
            .iter()
            .map(|t| t.max_element())
            .fold(0.0f32, f32::max) as f64;
        let excess = image
            .iter()
            .zip(&plain)
            .map(|(t, u)| (*t - *u * max_texel).max_element() / u.max_element().max(1e-300))
            .fold(0.0, f64::max);
        println!(
            "image {w}x{h}, {}x{} texture: finite; max (textured - max texel x plain)/plain \
             {excess:.1e}",
            tex.width(),
            tex.height()
        );
        assert!(excess <= 1e-12, "{excess:e}");
    }
}

/// The cost of the kink breakpoints and the quadrature's accuracy with large textures: one
/// ray across the cone (eye outside it) under pseudo-random textures from 8² to 4096² texels,
/// whose every texel-centre line is a kink. The ray crosses about `W + H` of those lines,
/// each one Gauss–Kronrod panel. Accuracy: the integral over `[0, ds]` against the sum of
/// the integrals over `[0, c]` and `[c, ds]` (the second from `E + c·v`, attenuated by
/// `exp(−σt·c)`), which are computed with different panels (1e-9, the brief's target).
/// Timing: printed, not judged.
#[test]
fn kink_breakpoints_keep_large_textures_accurate() {
    let medium = medium();
    let s = test_spot();
    let p = s.position().as_dvec3();
    let a = s.direction().as_dvec3();
    let e = p + a * 3.5 + DVec3::new(-3.0, 0.0, 0.3);
    let v = DVec3::new(1.0, 0.05, -0.2).normalize();
    let ds = 6.0;
    let plain_start = Instant::now();
    let plain = inscatter(e, v, ds, &medium, &s, &[]);
    let plain_time = plain_start.elapsed();
    println!("untextured: {plain} in {plain_time:?}");
    let mut slowest = 0.0f64;
    for n in [8u32, 64, 256, 1024, 4096] {
        let tex = noise(n);
        let textured = TexturedSpot::new(s, &tex);
        let start = Instant::now();
        let value = inscatter(e, v, ds, &medium, &textured, &[]);
        let time = start.elapsed();
        // The same integral split into two rays at an arbitrary point: the two halves use
        // different breakpoints and panels, so their sum checks the quadrature's accuracy.
        let cut = 2.7;
        let first = inscatter(e, v, cut, &medium, &textured, &[]);
        let second = transmittance(&medium, cut)
            * inscatter(e + v * cut, v, ds - cut, &medium, &textured, &[]);
        let err = rel_err(value, first + second);
        slowest = slowest.max(time.as_secs_f64());
        println!("noise {n}x{n}: {value} in {time:?}; split at {cut}: rel. diff {err:.1e}");
        assert!(value.is_finite() && value.min_element() > 0.0);
        assert!(err <= 1e-9, "{err:e}");
    }
    // No wall-clock bound (the times are printed; the 4096² texture's ray, thousands of
    // panels, takes tens of ms): timings on a shared machine are not test assertions. The
    // split above judges the quadrature on every texture size.
    println!("slowest textured ray: {slowest:.3} s");
}

/// An up hint turns the frame: its +y is the hint made perpendicular to the axis (in the f64
/// frame and the f32 matrix alike), and a hint with no part across the axis, zero or not
/// finite is `DegenerateDirection` or `NonFinite`, named `spot_light.texture_up`.
#[test]
fn the_texture_frame_follows_the_up_hint() {
    let s = test_spot();
    let a = s.direction().as_dvec3();
    let mut rng = Rng::new(11);
    let mut worst = 0.0f64;
    for _ in 0..200 {
        let hint = DVec3::new(rng.next() - 0.5, rng.next() - 0.5, rng.next() - 0.5);
        let Ok(turned) = s.with_texture_up(hint.as_vec3()) else {
            continue;
        };
        let across = (hint - a * a.dot(hint)).normalize();
        let (_, up, _) = texture_axes(&turned);
        let y32 = turned
            .texture_frame()
            .inverse()
            .transform_vector3(Vec3::Y)
            .as_dvec3();
        worst = worst
            .max((up - across).length())
            .max((y32 - across).length());
    }
    println!("frame +y against the hint across the axis: {worst:.1e}");
    // f32 rounding of the hint and the matrix (~6e-8 an axis); 1e-6 leaves room.
    assert!(worst <= 1e-6, "{worst:e}");
    let axis = s.direction();
    for (bad, kind) in [
        (Vec3::ZERO, "degenerate"),
        (axis * 3.0, "degenerate"),
        (-axis, "degenerate"),
        (Vec3::new(f32::NAN, 0.0, 1.0), "non-finite"),
        (Vec3::new(f32::INFINITY, 0.0, 1.0), "non-finite"),
    ] {
        match (s.with_texture_up(bad), kind) {
            (Err(volshadow::Error::DegenerateDirection { field }), "degenerate")
            | (Err(volshadow::Error::NonFinite { field, .. }), "non-finite") => {
                assert_eq!(field, "spot_light.texture_up")
            }
            (other, _) => panic!("{bad}: {other:?}"),
        }
    }
    // Huge and tiny finite hints normalise.
    for scale in [1e-30f32, 1e30] {
        let up = s.with_texture_up(Vec3::new(1.0, 0.0, 0.3) * scale).unwrap();
        assert!((up.texture_up().unwrap().length() - 1.0).abs() < 1e-6);
    }
}
