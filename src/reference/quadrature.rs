//! Globally adaptive Gauss–Kronrod (7, 15) quadrature of RGB-valued integrands (QUADPACK's QAG
//! scheme: keep every segment with its error estimate, bisect the worst until the summed error
//! meets the tolerance in every channel).

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use glam::DVec3;

/// Kronrod abscissae on [−1, 1] (positive half, descending; the last is the centre).
#[allow(clippy::excessive_precision)] // QUADPACK's published digits
const XGK: [f64; 8] = [
    0.991_455_371_120_812_639_206_854_697_526_329,
    0.949_107_912_342_758_524_526_189_684_047_851,
    0.864_864_423_359_769_072_789_712_788_640_926,
    0.741_531_185_599_394_439_863_864_773_280_788,
    0.586_087_235_467_691_130_294_144_845_693_013,
    0.405_845_151_377_397_166_906_606_412_076_961,
    0.207_784_955_007_898_467_600_689_403_773_245,
    0.0,
];
/// Kronrod weights, matching `XGK`.
#[allow(clippy::excessive_precision)] // QUADPACK's published digits
const WGK: [f64; 8] = [
    0.022_935_322_010_529_224_963_732_008_058_970,
    0.063_092_092_629_978_553_290_700_663_189_204,
    0.104_790_010_322_250_183_839_876_322_541_518,
    0.140_653_259_715_525_918_745_189_590_510_238,
    0.169_004_726_639_267_902_826_583_426_598_550,
    0.190_350_578_064_785_409_913_256_402_421_014,
    0.204_432_940_075_298_892_414_161_999_234_649,
    0.209_482_141_084_727_828_012_999_174_891_714,
];
/// Gauss weights for the abscissae `XGK[1], XGK[3], XGK[5], XGK[7]`.
#[allow(clippy::excessive_precision)] // QUADPACK's published digits
const WG: [f64; 4] = [
    0.129_484_966_168_869_693_270_611_432_679_082,
    0.279_705_391_489_276_667_901_467_771_423_780,
    0.381_830_050_505_118_944_950_369_775_488_975,
    0.417_959_183_673_469_387_755_102_040_816_327,
];

/// One 15-point Kronrod rule on [a, b], with QUADPACK's error estimate per channel.
fn gk15(g: &impl Fn(usize, f64) -> DVec3, map: usize, a: f64, b: f64) -> (DVec3, DVec3) {
    let centre = 0.5 * (a + b);
    let half = 0.5 * (b - a);
    let fc = g(map, centre);
    let mut kronrod = fc * WGK[7];
    let mut gauss = fc * WG[3];
    let mut f1 = [DVec3::ZERO; 7];
    let mut f2 = [DVec3::ZERO; 7];
    for j in 0..7 {
        let dx = half * XGK[j];
        f1[j] = g(map, centre - dx);
        f2[j] = g(map, centre + dx);
        let pair = f1[j] + f2[j];
        kronrod += pair * WGK[j];
        if j % 2 == 1 {
            gauss += pair * WG[j / 2];
        }
    }
    let mean = kronrod * 0.5;
    let mut resasc = WGK[7] * (fc - mean).abs();
    let mut resabs = WGK[7] * fc.abs();
    for j in 0..7 {
        resasc += WGK[j] * ((f1[j] - mean).abs() + (f2[j] - mean).abs());
        resabs += WGK[j] * (f1[j].abs() + f2[j].abs());
    }
    let h = half.abs();
    let (resasc, resabs) = (resasc * h, resabs * h);
    let raw = ((kronrod - gauss) * half).abs();
    let mut err = DVec3::ZERO;
    for c in 0..3 {
        let mut e = raw[c];
        if resasc[c] != 0.0 && e != 0.0 {
            e = resasc[c] * (200.0 * e / resasc[c]).powf(1.5).min(1.0);
        }
        // Round-off floor of the rule itself.
        e = e.max(50.0 * f64::EPSILON * resabs[c]);
        // A NaN or infinite value must not stall the loop: treat it as huge.
        err[c] = if e.is_finite() { e } else { f64::MAX };
    }
    (kronrod * half, err)
}

struct Segment {
    map: usize,
    a: f64,
    b: f64,
    value: DVec3,
    err: DVec3,
    key: f64,
}

impl PartialEq for Segment {
    fn eq(&self, other: &Self) -> bool {
        self.key.total_cmp(&other.key) == Ordering::Equal
    }
}
impl Eq for Segment {}
impl PartialOrd for Segment {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Segment {
    fn cmp(&self, other: &Self) -> Ordering {
        self.key.total_cmp(&other.key)
    }
}

/// Integrates `g(map, u)` over the `segments` `(map, a, b)` (the `map` index lets the caller use
/// a different change of variables on each segment) until the estimated error of the total is
/// at most `rel_tol` times its absolute value in every channel, or `max_bisections` segments
/// were bisected. Segments with `a >= b` or non-finite ends are skipped.
pub(crate) fn integrate(
    g: impl Fn(usize, f64) -> DVec3,
    segments: &[(usize, f64, f64)],
    rel_tol: f64,
    max_bisections: usize,
) -> DVec3 {
    integrate_to(
        g,
        segments,
        rel_tol,
        DVec3::splat(f64::MIN_POSITIVE),
        max_bisections,
    )
}

/// [`integrate`], content also where the estimated error of a channel is at most `floor` (an
/// absolute tolerance, for a total that may be tiny or zero).
pub(crate) fn integrate_to(
    g: impl Fn(usize, f64) -> DVec3,
    segments: &[(usize, f64, f64)],
    rel_tol: f64,
    floor: DVec3,
    max_bisections: usize,
) -> DVec3 {
    let mut pieces: Vec<(usize, f64, f64, DVec3, DVec3)> = Vec::with_capacity(segments.len());
    for &(map, a, b) in segments {
        if a < b && a.is_finite() && b.is_finite() {
            let (value, err) = gk15(&g, map, a, b);
            pieces.push((map, a, b, value, err));
        }
    }
    let mut total: DVec3 = pieces.iter().map(|p| p.3).sum();
    let mut total_err: DVec3 = pieces.iter().map(|p| p.4).sum();
    // Scale of each channel, for ranking segments (from the first estimate).
    let scale = total.abs().max(DVec3::splat(f64::MIN_POSITIVE));
    let key = |err: DVec3| (err / scale).max_element();
    let mut heap: BinaryHeap<Segment> = pieces
        .into_iter()
        .map(|(map, a, b, value, err)| Segment {
            map,
            a,
            b,
            value,
            err,
            key: key(err),
        })
        .collect();
    let converged = |total: DVec3, err: DVec3| {
        (0..3).all(|c| err[c] <= (rel_tol * total[c].abs()).max(floor[c]))
    };
    let mut bisections = 0;
    while bisections < max_bisections && !converged(total, total_err) {
        let Some(worst) = heap.pop() else { break };
        let mid = 0.5 * (worst.a + worst.b);
        if !(worst.a < mid && mid < worst.b) {
            // Cannot be split further in f64: keep it as it is.
            heap.push(Segment {
                key: f64::NEG_INFINITY,
                ..worst
            });
            if heap.peek().is_some_and(|s| s.key == f64::NEG_INFINITY) {
                break;
            }
            continue;
        }
        bisections += 1;
        let (v1, e1) = gk15(&g, worst.map, worst.a, mid);
        let (v2, e2) = gk15(&g, worst.map, mid, worst.b);
        total += v1 + v2 - worst.value;
        total_err += e1 + e2 - worst.err;
        total_err = total_err.max(DVec3::ZERO);
        for (a, b, value, err) in [(worst.a, mid, v1, e1), (mid, worst.b, v2, e2)] {
            heap.push(Segment {
                map: worst.map,
                a,
                b,
                value,
                err,
                key: key(err),
            });
        }
    }
    // Re-sum from scratch, free of the drift of the running total.
    heap.iter().map(|s| s.value).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polynomials_and_peaks() {
        // K15 integrates polynomials of degree ≤ 22 exactly.
        let v = integrate(
            |_, x| DVec3::splat(x.powi(21) + 1.0),
            &[(0, 0.0, 1.0)],
            1e-13,
            10,
        );
        assert!((v.x - (1.0 / 22.0 + 1.0)).abs() < 1e-15);
        // A Lorentzian of width 1e-6: ∫_{-1}^{1} ε/(x²+ε²) dx = 2 atan(1/ε).
        let eps = 1e-6;
        let v = integrate(
            |_, x| DVec3::splat(eps / (x * x + eps * eps)),
            &[(0, -1.0, 0.3), (0, 0.3, 1.0)],
            1e-12,
            10_000,
        );
        let exact = 2.0 * (1.0f64 / eps).atan();
        assert!((v.x / exact - 1.0).abs() < 1e-11, "{}", v.x / exact - 1.0);
    }
}
