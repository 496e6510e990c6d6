//! The indirect single scattering reference (`volshadow::reference::surface_inscatter`): the
//! nested adaptive hemisphere integral against brute force, its reduction to a scale times a
//! function of two numbers, its isotropic `σt → 0` limit, and a table model's interpolation
//! error (the accuracy a GPU table of `G` on the same axes gets).

use std::f64::consts::{FRAC_PI_2, PI};

use glam::{DVec3, Vec3};
use volshadow::reference::{
    inscatter_closed_form, surface_inscatter, surface_inscatter_normalised, surface_inscatter_scale,
};
use volshadow::{Medium, PhaseFunction, PointLight};

const HG: PhaseFunction = PhaseFunction::HenyeyGreenstein { g: 0.8 };

fn medium(sigma_s: Vec3, sigma_a: Vec3, phase: PhaseFunction) -> Medium {
    Medium::new(sigma_s, sigma_a, phase).unwrap()
}

/// A frame with `l` the unit direction from `p` to the light and the normal at angle `alpha`
/// from it.
fn normal_at(l: DVec3, alpha: f64) -> DVec3 {
    let e1 = l.any_orthonormal_vector();
    l * alpha.cos() + e1 * alpha.sin()
}

/// Brute force: midpoint rule in `(γ, φ)` about the direction to the light over the whole
/// sphere, with `γ = π·u²` (cells graded towards the light's integrable 1/γ peak), the
/// closed-form airlight along every direction, and `weight(ω·n)` (the cosine's positive part
/// for the term itself; the broken variants pass other weights).
fn brute(
    p: DVec3,
    n: DVec3,
    medium: &Medium,
    light: &PointLight,
    cells: usize,
    weight: impl Fn(f64) -> f64,
) -> DVec3 {
    let l = (light.position().as_dvec3() - p).normalize();
    let e1 = l.any_orthonormal_vector();
    let e2 = l.cross(e1);
    let (nu, nf) = (cells, 2 * cells);
    let mut sum = DVec3::ZERO;
    for i in 0..nu {
        let u = (i as f64 + 0.5) / nu as f64;
        let g = PI * u * u;
        let jac = 2.0 * PI * u * g.sin() / nu as f64 * (2.0 * PI / nf as f64);
        for j in 0..nf {
            let f = (j as f64 + 0.5) / nf as f64 * 2.0 * PI;
            let w = l * g.cos() + (e1 * f.cos() + e2 * f.sin()) * g.sin();
            let k = weight(w.dot(n));
            if k != 0.0 {
                sum += inscatter_closed_form(p, w, f64::INFINITY, medium, light) * (k * jac);
            }
        }
    }
    sum
}

fn cosine(c: f64) -> f64 {
    c.max(0.0)
}

struct Case {
    name: &'static str,
    medium: Medium,
    distance: f64,
    alpha: f64,
}

fn cases() -> Vec<Case> {
    let m = |s: f32, a: f32, phase| medium(Vec3::splat(s), Vec3::splat(a), phase);
    vec![
        Case {
            name: "HG 0.8, τ = 1, α = 0.7",
            medium: m(0.8, 0.2, HG),
            distance: 1.0,
            alpha: 0.7,
        },
        Case {
            name: "isotropic, τ = 0.1, α = 2",
            medium: m(0.05, 0.05, PhaseFunction::Isotropic),
            distance: 1.0,
            alpha: 2.0,
        },
        Case {
            name: "Rayleigh, τ = 5, α = π/2",
            medium: m(1.0, 0.25, PhaseFunction::Rayleigh),
            distance: 4.0,
            alpha: FRAC_PI_2,
        },
        Case {
            name: "touching the light, D = 1e-6",
            medium: m(0.5, 0.1, HG),
            distance: 1e-6,
            alpha: 0.3,
        },
        Case {
            name: "τ = 100, α = 0.5",
            medium: m(8.0, 2.0, HG),
            distance: 10.0,
            alpha: 0.5,
        },
        Case {
            name: "τ = 100, α = π/2 + 0.01",
            medium: m(8.0, 2.0, PhaseFunction::Isotropic),
            distance: 10.0,
            alpha: FRAC_PI_2 + 0.01,
        },
        Case {
            name: "facing away, α = π, τ = 2",
            medium: m(1.5, 0.5, HG),
            distance: 1.0,
            alpha: PI,
        },
    ]
}

/// (a) and (d): the nested adaptive integral against the brute-force midpoint rule on 400 × 800
/// cells (its own error, measured as the change from 200 × 400, is below 1e-4 relative in every
/// case: the bound 1e-3 leaves a factor of ten); every value finite and non-negative. The same
/// brute force without the cosine, or over the whole sphere with `|ω·n|`, misses by far more.
#[test]
fn a_hemisphere_integral_against_brute_force() {
    let p = DVec3::new(0.3, -1.2, 2.0);
    let dir = DVec3::new(0.2, 0.9, -0.4).normalize();
    let mut failures = Vec::new();
    for c in cases() {
        let light =
            PointLight::new((p + dir * c.distance).as_vec3(), Vec3::new(5.0, 4.0, 3.0)).unwrap();
        // The light's f32 position moves the direction slightly: use the actual one.
        let l = (light.position().as_dvec3() - p).normalize();
        let n = normal_at(l, c.alpha);
        let value = surface_inscatter(p, n, &c.medium, &light);
        let coarse = brute(p, n, &c.medium, &light, 200, cosine);
        let fine = brute(p, n, &c.medium, &light, 400, cosine);
        let rel = ((value - fine) / fine).abs().max_element();
        let own = ((fine - coarse) / fine).abs().max_element();
        let no_cos = brute(p, n, &c.medium, &light, 200, |k| {
            if k > 0.0 {
                1.0
            } else {
                0.0
            }
        });
        let sphere = brute(p, n, &c.medium, &light, 200, f64::abs);
        let miss = |b: DVec3| ((b - value) / value).abs().max_element();
        println!(
            "{}: {value:.6} brute {fine:.6} rel {rel:.1e} (brute's own change {own:.1e}); \
             no cosine misses by {:.1e}, whole sphere by {:.1e}",
            c.name,
            miss(no_cos),
            miss(sphere)
        );
        let ok = value.is_finite() && value.min_element() >= 0.0 && rel <= 1e-3 && own <= 1e-4;
        let broken_caught = miss(no_cos) > 1e-2 && miss(sphere) > 1e-2;
        if !ok || !broken_caught {
            failures.push(c.name);
        }
    }
    assert!(failures.is_empty(), "failed: {failures:?}");
}

/// The seeds run: 12, or the one in `VOLSHADOW_SEED` (to reproduce a failure alone).
fn seeds() -> Vec<u64> {
    match std::env::var("VOLSHADOW_SEED") {
        Ok(s) => vec![s.parse().expect("VOLSHADOW_SEED must be a number")],
        Err(_) => (0..12).collect(),
    }
}

/// (b) `E(P)` (world space, nested quadrature of the closed-form airlight) equals
/// `scale · G(σt·D, α)` per channel (normalised units, closed-form φ integral, its own
/// airlight) within 1e-9 relative: both are computed to 1e-10 (outer) and 1e-12 (inner).
#[test]
fn b_scale_times_g_over_random_scenes() {
    let phases = [
        PhaseFunction::Isotropic,
        HG,
        PhaseFunction::HenyeyGreenstein { g: -0.4 },
        PhaseFunction::Rayleigh,
    ];
    let mut worst = (0.0f64, 0);
    for seed in seeds() {
        let mut rng = fastrand::Rng::with_seed(seed);
        let mut v = |lo: f64, hi: f64| lo + (hi - lo) * rng.f64();
        let p = DVec3::new(v(-5.0, 5.0), v(-5.0, 5.0), v(-5.0, 5.0));
        let light_pos = p + DVec3::new(v(-1.0, 1.0), v(-1.0, 1.0), v(-1.0, 1.0)) * v(0.01, 4.0);
        let n = DVec3::new(v(-1.0, 1.0), v(-1.0, 1.0), v(-1.0, 1.0));
        let sigma_s = Vec3::new(v(0.0, 2.0) as f32, v(0.0, 2.0) as f32, v(0.0, 2.0) as f32);
        let sigma_a = Vec3::new(v(0.0, 1.0) as f32, v(0.0, 1.0) as f32, v(0.0, 1.0) as f32);
        let phase = phases[(v(0.0, 4.0) as usize).min(3)];
        let m = medium(sigma_s, sigma_a, phase);
        let light = PointLight::new(light_pos.as_vec3(), Vec3::new(3.0, 2.0, 1.0)).unwrap();
        let to_light = light.position().as_dvec3() - p;
        let d = to_light.length();
        let alpha = n.normalize().angle_between(to_light / d);
        let scale = surface_inscatter_scale(&m, light.intensity().as_dvec3(), d);
        let taus = m.sigma_t().as_dvec3() * d;
        let factored = DVec3::from_array(std::array::from_fn(|c| {
            scale[c] * surface_inscatter_normalised(taus[c], alpha, &phase)[c]
        }));
        let value = surface_inscatter(p, n, &m, &light);
        let rel = ((value - factored).abs() / factored).max_element();
        println!("seed {seed}: {phase:?} τ {taus:.3} α {alpha:.3}: {value:.6} vs {factored:.6}, rel {rel:.1e}");
        assert!(
            value.is_finite() && rel <= 1e-9,
            "seed {seed} (VOLSHADOW_SEED={seed}): rel {rel:e}"
        );
        if rel > worst.0 {
            worst = (rel, seed);
        }
    }
    println!(
        "worst relative difference {:.1e} (seed {})",
        worst.0, worst.1
    );
}

/// (c) Isotropic, `τ = 0`: `b(0, γ) = (π − γ)/(4π)` integrates to `G(0, 0) = π/4 + 1/2`,
/// `G(0, π) = π/4 − 1/2` and `G(0, α) − G(0, π − α) = cos α`, and a world-space medium with
/// `σt·D = 1e-9` gives `σs·I0/D·(π/4 + 1/2)` (the correction is `O(τ log τ)` ≈ 2e-8; bound 1e-6,
/// the reference's own accuracy).
#[test]
fn c_isotropic_thin_medium_limit() {
    let iso = PhaseFunction::Isotropic;
    let g = |a: f64| surface_inscatter_normalised(0.0, a, &iso).x;
    let mut worst = (g(0.0) - (PI / 4.0 + 0.5))
        .abs()
        .max((g(PI) - (PI / 4.0 - 0.5)).abs());
    for a in [0.1, 0.7, 1.3, FRAC_PI_2, 2.0] {
        worst = worst.max((g(a) - g(PI - a) - a.cos()).abs());
    }
    let m = medium(Vec3::splat(1e-9), Vec3::ZERO, iso);
    let light = PointLight::new(Vec3::new(0.0, 1.0, 0.0), Vec3::splat(2.0)).unwrap();
    let e = surface_inscatter(DVec3::ZERO, DVec3::Y, &m, &light).x;
    let expected = 1e-9f32 as f64 * 2.0 * (PI / 4.0 + 0.5);
    let world = (e / expected - 1.0).abs();
    println!("normalised: max abs error {worst:.1e}; world σt·D = 1e-9: rel {world:.1e}");
    assert!(worst <= 1e-9 && world <= 1e-6, "{worst:e} {world:e}");
}

/// Table coordinates of a candidate parameterisation: `u` linear in `ln τ` over
/// `[1e-3, 50]`; `v` either `α/π` (`warp = None`) or
/// `½ − asinh(s·cos α)/(2·asinh s)` with `s = s0 + s1·τ` (samples gathered about `α = π/2`,
/// where `G` falls over a width `~1/τ`).
#[derive(Debug, Clone, Copy)]
enum Axes {
    Angle,
    Warp(f64, f64),
}

const TAU_RANGE: (f64, f64) = (1e-3, 50.0);

impl Axes {
    fn point(self, u: f64, v: f64) -> (f64, f64) {
        let (lo, hi) = (TAU_RANGE.0.ln(), TAU_RANGE.1.ln());
        let tau = (lo + u * (hi - lo)).exp();
        let alpha = match self {
            Axes::Angle => v * PI,
            Axes::Warp(s0, s1) => {
                let s = s0 + s1 * tau;
                let cos = ((1.0 - 2.0 * v) * s.asinh()).sinh() / s;
                cos.clamp(-1.0, 1.0).acos()
            }
        };
        (tau, alpha)
    }
}

/// Max relative error of an f32 `nu × nv` table of `G` (nodes at `u = i/(nu − 1)`,
/// `v = j/(nv − 1)`), bilinear in f32, at every cell centre and edge midpoint, over the
/// points where `G` is above 1e-6 of its maximum; and the count of non-finite entries.
fn table_error(nu: usize, nv: usize, axes: Axes, phase: &PhaseFunction) -> (f64, usize) {
    let g = |u: f64, v: f64| {
        let (tau, alpha) = axes.point(u, v);
        surface_inscatter_normalised(tau, alpha, phase).x
    };
    let table: Vec<f32> = (0..nu * nv)
        .map(|k| {
            g(
                (k % nu) as f64 / (nu - 1) as f64,
                (k / nu) as f64 / (nv - 1) as f64,
            ) as f32
        })
        .collect();
    let bad = table.iter().filter(|t| !t.is_finite()).count();
    let max = table.iter().fold(0.0f32, |m, &t| m.max(t)) as f64;
    let lookup = |x: f32, y: f32| {
        let (fx, fy) = (x * (nu - 1) as f32, y * (nv - 1) as f32);
        let (i, j) = ((fx as usize).min(nu - 2), (fy as usize).min(nv - 2));
        let (tx, ty) = (fx - i as f32, fy - j as f32);
        let at = |a: usize, b: usize| table[b * nu + a];
        let top = at(i, j) * (1.0 - tx) + at(i + 1, j) * tx;
        let bottom = at(i, j + 1) * (1.0 - tx) + at(i + 1, j + 1) * tx;
        top * (1.0 - ty) + bottom * ty
    };
    let mut worst = 0.0f64;
    for i in 0..2 * nu - 1 {
        for j in 0..2 * nv - 1 {
            if i % 2 == 0 && j % 2 == 0 {
                continue; // a node
            }
            let (u, v) = (
                i as f64 / (2 * nu - 2) as f64,
                j as f64 / (2 * nv - 2) as f64,
            );
            let exact = g(u, v);
            if exact > 1e-6 * max {
                let t = lookup(u as f32, v as f32) as f64;
                worst = worst.max(if t.is_finite() {
                    (t - exact).abs() / exact
                } else {
                    f64::INFINITY
                });
            }
        }
    }
    (worst, bad)
}

/// The table-size study (run with `--ignored --nocapture`): prints the max relative error of
/// each parameterisation and size for isotropic, HG 0.8 and Rayleigh.
#[test]
#[ignore]
fn table_size_study() {
    let phases = [PhaseFunction::Isotropic, HG, PhaseFunction::Rayleigh];
    let configs = [
        (Axes::Angle, 64, 64),
        (Axes::Angle, 128, 128),
        (Axes::Warp(1e-6, 0.0), 64, 64),
        (Axes::Warp(4.0, 1.0), 64, 64),
        (Axes::Warp(8.0, 2.0), 64, 64),
        (Axes::Warp(4.0, 1.0), 128, 64),
        (Axes::Warp(4.0, 1.0), 64, 128),
        (Axes::Warp(4.0, 1.0), 128, 128),
    ];
    for (axes, nu, nv) in configs {
        let t = std::time::Instant::now();
        let errs: Vec<String> = phases
            .iter()
            .map(|p| {
                let (e, bad) = table_error(nu, nv, axes, p);
                format!("{e:.1e}{}", if bad > 0 { " NON-FINITE" } else { "" })
            })
            .collect();
        println!(
            "{axes:?} {nu}×{nv} (τ × α): iso / HG 0.8 / Rayleigh max rel {errs:?} ({:.1?})",
            t.elapsed()
        );
    }
}
