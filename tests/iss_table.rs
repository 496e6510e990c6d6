//! The indirect single scattering table (`nodes::IssTableNode`) read back and compared with the
//! f64 reference `reference::surface_inscatter_normalised` (its own adaptive quadrature, no code
//! shared): entries over σt·D ∈ [1e-3, 50], α ∈ [0, π], isotropic, Henyey–Greenstein 0.8 and
//! Rayleigh phases, and the bilinear interpolation of the default table between entries.

mod common;

use std::time::Instant;

use glam::Vec3;
use volshadow::nodes::{IssTableNode, IssTableSize, ISS_TAU_RANGE};
use volshadow::reference::surface_inscatter_normalised;
use volshadow::{Cache, HeadlessGpu, Medium, PhaseFunction};

const PHASES: [(&str, PhaseFunction); 3] = [
    ("isotropic", PhaseFunction::Isotropic),
    ("HG 0.8", PhaseFunction::HenyeyGreenstein { g: 0.8 }),
    ("Rayleigh", PhaseFunction::Rayleigh),
];

/// The checked range of the optical distance σt·D.
const TAU: [f64; 2] = [1e-3, 50.0];

/// `(τ, α)` of table coordinates `(u, v)`, the axes `nodes::IssTableNode` documents, in f64.
fn point(u: f64, v: f64) -> (f64, f64) {
    let [lo, hi] = ISS_TAU_RANGE.map(f64::from);
    let tau = lo * (u * (hi / lo).ln()).exp();
    let s = 4.0 + tau;
    let cos = (((1.0 - 2.0 * v) * s.asinh()).sinh() / s).clamp(-1.0, 1.0);
    (tau, cos.acos())
}

/// Builds a table of `size` for `phase` and reads it back (ln G per channel).
fn build(
    gpu: &HeadlessGpu,
    cache: &Cache,
    size: IssTableSize,
    phase: PhaseFunction,
) -> Vec<[f32; 4]> {
    let medium = Medium::new(Vec3::splat(0.5), Vec3::splat(0.1), phase).unwrap();
    let mut node = IssTableNode::new(&gpu.device, cache, size).unwrap();
    assert!(
        node.prepare(&gpu.device, &gpu.queue, &medium).unwrap(),
        "a fresh table is built"
    );
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    node.encode(&mut encoder, None).unwrap();
    let t = Instant::now();
    gpu.submit_and_wait(encoder).unwrap();
    eprintln!(
        "  {phase:?}: {}×{} table built in {:.0?}",
        size.tau,
        size.alpha,
        t.elapsed()
    );
    // Unchanged medium: nothing to rebuild.
    assert!(!node.prepare(&gpu.device, &gpu.queue, &medium).unwrap());
    gpu.read_rgba32f(node.texture()).unwrap()
}

/// The table's entries against the reference: within 1e-3 relative wherever G is above 1e-6 of
/// its maximum over the checked nodes (the bar the table must meet), every entry finite. A
/// 33 × 65 table's nodes are checked where σt·D ∈ [1e-3, 50]: every other τ node, and every
/// α node in the sixth of the axis about α = π/2 (where G falls over ~1/τ) and every third
/// elsewhere.
#[test]
fn entries_match_the_reference() {
    let gpu = common::gpu();
    let cache = Cache::new(&gpu.device);
    let size = IssTableSize { tau: 33, alpha: 65 };
    let (nu, nv) = (size.tau as usize, size.alpha as usize);
    let mut failures = Vec::new();
    for (name, phase) in PHASES {
        let table = build(&gpu, &cache, size, phase);
        assert!(
            table.iter().flatten().all(|v| v.is_finite()),
            "{name}: a non-finite entry"
        );
        let t = Instant::now();
        let mut checked = Vec::new();
        for j in 0..nv {
            let v = j as f64 / (nv - 1) as f64;
            if !((v - 0.5).abs() <= 1.0 / 12.0 || j % 3 == 0 || j == nv - 1) {
                continue;
            }
            for i in (0..nu).filter(|i| i % 2 == 0) {
                let (tau, alpha) = point(i as f64 / (nu - 1) as f64, v);
                if !(TAU[0]..=TAU[1]).contains(&tau) {
                    continue;
                }
                let exact = surface_inscatter_normalised(tau, alpha, &phase).x;
                let gpu = f64::from(table[j * nu + i][0]).exp();
                checked.push((exact, gpu, tau, alpha));
            }
        }
        let max = checked.iter().fold(0.0f64, |m, c| m.max(c.0));
        let mut worst = (0.0f64, 0.0, 0.0);
        for &(exact, gpu, tau, alpha) in checked.iter().filter(|c| c.0 > 1e-6 * max) {
            let rel = (gpu - exact).abs() / exact;
            if !(rel <= worst.0) {
                worst = (rel, tau, alpha);
            }
        }
        eprintln!(
            "{name}: {} entries, max relative error {:.2e} (at τ {:.3e}, α {:.4}); reference {:.1?}",
            checked.len(),
            worst.0,
            worst.1,
            worst.2,
            t.elapsed()
        );
        if !(worst.0 <= 1e-3) {
            failures.push(format!("{name}: {:.2e}", worst.0));
        }
    }
    assert!(
        failures.is_empty(),
        "entries off by more than 1e-3: {failures:?}"
    );
}
