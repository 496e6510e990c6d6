//! The indirect single scattering reference (`volshadow::reference::surface_inscatter`): the
//! nested adaptive hemisphere integral against brute force, its reduction to a scale times a
//! function of two numbers, its isotropic `σt → 0` limit, and a table model's interpolation
//! error (the accuracy a GPU table of `G` on the same axes gets).

use volshadow_harness::metric;
use volshadow_harness::rng;

use std::f64::consts::{FRAC_PI_2, PI};

use glam::{DVec3, Vec3};
use volshadow::reference::{
    inscatter_closed_form, iss_table_point, surface_inscatter, surface_inscatter_normalised,
    surface_inscatter_scale,
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
/// sphere, `cells × 2·cells`, with `γ = π·u²` (cells graded towards the light's integrable 1/γ
/// peak) and the closed-form airlight along every direction. Returns the sums weighted by
/// `(ω·n)₊` (the term itself) and by two broken variants' weights: `[ω·n > 0]` (the cosine
/// dropped) and `|ω·n|` (the whole sphere).
fn brute(p: DVec3, n: DVec3, medium: &Medium, light: &PointLight, cells: usize) -> [DVec3; 3] {
    let l = (light.position().as_dvec3() - p).normalize();
    let e1 = l.any_orthonormal_vector();
    let e2 = l.cross(e1);
    let (nu, nf) = (cells, 2 * cells);
    let mut sums = [DVec3::ZERO; 3];
    for i in 0..nu {
        let u = (i as f64 + 0.5) / nu as f64;
        let g = PI * u * u;
        let jac = 2.0 * PI * u * g.sin() / nu as f64 * (2.0 * PI / nf as f64);
        for j in 0..nf {
            let f = (j as f64 + 0.5) / nf as f64 * 2.0 * PI;
            let w = l * g.cos() + (e1 * f.cos() + e2 * f.sin()) * g.sin();
            let c = w.dot(n);
            let value = inscatter_closed_form(p, w, f64::INFINITY, medium, light) * jac;
            let weights = [c.max(0.0), if c > 0.0 { 1.0 } else { 0.0 }, c.abs()];
            for (sum, k) in sums.iter_mut().zip(weights) {
                *sum += value * k;
            }
        }
    }
    sums
}

/// The brute force's finer grid (its coarser one is half of it).
const CELLS: usize = 240;

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

/// (a) and (d): the nested adaptive integral against the brute-force midpoint rule on 240 × 480
/// cells (its error is about a third of its change from 120 × 240, which must stay ≤ 5e-4
/// relative: the bound 1e-3 leaves a factor of six); every value finite and non-negative.
/// The same brute force without the cosine, or over the whole sphere with `|ω·n|`, must miss
/// by more than that bound in at least one case each (they miss by 0.1–2 where the back
/// hemisphere matters).
#[test]
fn a_hemisphere_integral_against_brute_force() {
    let p = DVec3::new(0.3, -1.2, 2.0);
    let dir = DVec3::new(0.2, 0.9, -0.4).normalize();
    let mut failures = Vec::new();
    let mut caught = [false; 2];
    let (mut worst, mut worst_own, mut misses) = (0.0f64, 0.0f64, [0.0f64; 2]);
    let cases = cases();
    for c in &cases {
        let light =
            PointLight::new((p + dir * c.distance).as_vec3(), Vec3::new(5.0, 4.0, 3.0)).unwrap();
        // The light's f32 position moves the direction slightly: use the actual one.
        let l = (light.position().as_dvec3() - p).normalize();
        let n = normal_at(l, c.alpha);
        let value = surface_inscatter(p, n, &c.medium, &light);
        let [coarse, no_cos, sphere] = brute(p, n, &c.medium, &light, CELLS / 2);
        let [fine, ..] = brute(p, n, &c.medium, &light, CELLS);
        let rel = ((value - fine) / fine).abs().max_element();
        let own = ((fine - coarse) / fine).abs().max_element();
        let miss = |b: DVec3| ((b - value) / value).abs().max_element();
        println!(
            "{}: {value:.6} brute {fine:.6} rel {rel:.1e} (brute's own change {own:.1e}); \
             no cosine misses by {:.1e}, whole sphere by {:.1e}",
            c.name,
            miss(no_cos),
            miss(sphere)
        );
        if !(value.is_finite() && value.min_element() >= 0.0 && rel <= 1e-3 && own <= 5e-4) {
            failures.push(c.name);
        }
        caught[0] |= miss(no_cos) > 1e-3;
        caught[1] |= miss(sphere) > 1e-3;
        // NaN propagates (`f64::max` would drop it).
        worst = if rel > worst || rel.is_nan() {
            rel
        } else {
            worst
        };
        worst_own = worst_own.max(own);
        misses = [misses[0].max(miss(no_cos)), misses[1].max(miss(sphere))];
    }
    metric::accuracy(
        &format!("{} cases: the nested adaptive hemisphere integral against a brute-force midpoint rule (240 × 480 cells); the rule's change from 120 × 240", cases.len()),
        format!("max {worst:.1e}; {worst_own:.1e}"),
        "1e-3; 5e-4",
    );
    metric::accuracy(
        "broken variants (must fail): the brute force without the cosine / over the whole sphere, largest miss",
        format!("{:.1e} / {:.1e}", misses[0], misses[1]),
        "> 1e-3 in some case each",
    );
    assert!(
        caught == [true, true],
        "a broken variant passes every case: {caught:?}"
    );
    assert!(failures.is_empty(), "failed: {failures:?}");
}

/// (b) `E(P)` (world space, nested quadrature of the closed-form airlight) equals
/// `scale · G(σt·D, α)` per channel (normalised units, closed-form φ integral, its own
/// airlight) within 1e-9 relative: both are computed to 1e-10 (outer) and 1e-12 (inner).
#[test]
#[cfg_attr(
    not(feature = "sweeps"),
    ignore = "an accuracy sweep: --features sweeps"
)]
fn b_scale_times_g_over_random_scenes() {
    let phases = [
        PhaseFunction::Isotropic,
        HG,
        PhaseFunction::HenyeyGreenstein { g: -0.4 },
        PhaseFunction::Rayleigh,
    ];
    let mut worst = (0.0f64, 0);
    for seed in rng::seeds(0..12) {
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
    metric::accuracy(
        &format!(
            "{} random scenes: E(P) in world space against scale · G(σt·D, α)",
            rng::seeds(0..12).len()
        ),
        format!("max {:.1e}", worst.0),
        "1e-9 (both computed to 1e-10 and 1e-12)",
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
    metric::accuracy(
        "isotropic, τ = 0: G against its closed-form values (absolute); a world medium at σt·D = 1e-9 against σs·I0/D·(π/4 + 1/2) (relative)",
        format!("{worst:.1e}; {world:.1e}"),
        "1e-9; 1e-6 (the correction is ~2e-8)",
    );
    assert!(worst <= 1e-9 && world <= 1e-6, "{worst:e} {world:e}");
}

/// The table-size study (run with `--ignored --nocapture`; minutes). `G` is evaluated on a fine
/// 65 × 65 grid of [`iss_table_coords`]; each coarser table (every `su`-th node in `τ`, every
/// `sv`-th in `α`, stored in f32, bilinear in f32) is checked at every fine node it does not
/// hold (cell centres and edge midpoints), over the values above 1e-6 of the maximum, storing
/// `G` or `ln G`.
#[test]
#[ignore]
fn table_size_study() {
    const N: usize = 65;
    for (name, phase) in [
        ("isotropic", PhaseFunction::Isotropic),
        ("HG 0.8", HG),
        ("Rayleigh", PhaseFunction::Rayleigh),
    ] {
        let t = std::time::Instant::now();
        let fine: Vec<f64> = (0..N * N)
            .map(|k| {
                let (tau, alpha) = iss_table_point(
                    (k % N) as f64 / (N - 1) as f64,
                    (k / N) as f64 / (N - 1) as f64,
                );
                surface_inscatter_normalised(tau, alpha, &phase).x
            })
            .collect();
        let bad = fine.iter().filter(|g| !g.is_finite() || **g < 0.0).count();
        let max = fine.iter().fold(0.0f64, |m, &g| m.max(g));
        let mut line = format!("{name}: {bad} non-finite or negative; max G {max:.4}");
        let mut where_ = (0, 0);
        for log in [false, true] {
            line += if log {
                "\n  ln G stored:"
            } else {
                "\n  G stored:"
            };
            let stored = |g: f64| if log { g.ln() as f32 } else { g as f32 };
            for (su, sv) in [(4, 4), (2, 4), (4, 2), (2, 2), (1, 2), (2, 1)] {
                let (nu, nv) = ((N - 1) / su + 1, (N - 1) / sv + 1);
                let table: Vec<f32> = (0..nu * nv)
                    .map(|k| stored(fine[(k / nu) * sv * N + (k % nu) * su]))
                    .collect();
                let mut worst = 0.0f64;
                for (k, &exact) in fine.iter().enumerate() {
                    let (i, j) = (k % N, k / N);
                    if (i % su == 0 && j % sv == 0) || exact <= 1e-6 * max {
                        continue;
                    }
                    let (fx, fy) = ((i as f32) / su as f32, (j as f32) / sv as f32);
                    let (a, b) = ((fx as usize).min(nu - 2), (fy as usize).min(nv - 2));
                    let (tx, ty) = (fx - a as f32, fy - b as f32);
                    let at = |x: usize, y: usize| table[y * nu + x];
                    let top = at(a, b) * (1.0 - tx) + at(a + 1, b) * tx;
                    let bottom = at(a, b + 1) * (1.0 - tx) + at(a + 1, b + 1) * tx;
                    let mixed = top * (1.0 - ty) + bottom * ty;
                    let value = if log { mixed.exp() } else { mixed } as f64;
                    if (value - exact).abs() / exact > worst {
                        worst = (value - exact).abs() / exact;
                        where_ = (i, j);
                    }
                }
                line += &format!(" {nu}×{nv}: {worst:.1e} at {where_:?};");
            }
        }
        println!("{line} ({:.0?})", t.elapsed());
    }
}
