//! Exact lit intervals along a ray.

use glam::DVec3;

use super::occluder::Occluder;

/// The parts of the ray `origin + x·dir`, `0 ≤ x ≤ ds`, from which `light_pos` is visible (no
/// occluder surface on the segment to the light), as sorted, disjoint `(start, end)` pairs in
/// distance along the ray (`dir` need not be unit length: it is normalised, and `x` is a
/// distance). The last end is `ds`, which may be `f64::INFINITY` (sky).
///
/// Exact from the geometry, with no sampling: every `x` where visibility can change is found
/// in closed form — for each triangle (and each box face) the ray's crossings of the planes
/// through the light and each edge and of the face's own plane; for each sphere the ray's
/// crossings of the sphere and of its tangent cone from the light. Between consecutive
/// candidates visibility is constant, so it is decided by [`Occluder::segment_blocked`] at the
/// midpoint, and adjacent lit pieces are merged.
///
/// Returns no intervals for `ds ≤ 0`, NaN `ds`, a zero or non-finite `dir`, or non-finite
/// positions; `[(0, ds)]` with no occluders.
pub fn lit_intervals(
    origin: DVec3,
    dir: DVec3,
    ds: f64,
    light_pos: DVec3,
    occluders: &[Occluder],
) -> Vec<(f64, f64)> {
    let len = dir.length();
    let valid =
        ds > 0.0 && len > 0.0 && len.is_finite() && origin.is_finite() && light_pos.is_finite();
    if !valid {
        return Vec::new();
    }
    let v = dir / len;
    if occluders.is_empty() {
        return vec![(0.0, ds)];
    }
    let mut raw = Vec::new();
    for occluder in occluders {
        occluder.candidates(origin, v, light_pos, &mut raw);
    }
    let mut cuts = Vec::with_capacity(raw.len() + 2);
    cuts.push(0.0);
    cuts.extend(raw.into_iter().filter(|&x| x > 0.0 && x < ds));
    cuts.sort_by(f64::total_cmp);
    cuts.dedup();
    let last = *cuts.last().unwrap_or(&0.0);
    if ds.is_finite() {
        cuts.push(ds);
    } else {
        // Visibility is constant beyond the last candidate: any point there decides it.
        let scale = last
            .max((light_pos - origin).length())
            .max(f64::MIN_POSITIVE.sqrt());
        cuts.push(last + scale); // a test point only; the interval's end is replaced by ∞
    }
    let lit = |x: f64| {
        let point = origin + v * x;
        !occluders
            .iter()
            .any(|o| o.segment_blocked(point, light_pos))
    };
    let mut intervals: Vec<(f64, f64)> = Vec::new();
    let n = cuts.len();
    for i in 0..n - 1 {
        let (a, b) = (cuts[i], cuts[i + 1]);
        let is_last = i == n - 2;
        let test = if is_last && !ds.is_finite() {
            b
        } else {
            0.5 * (a + b)
        };
        if !lit(test) {
            continue;
        }
        let end = if is_last { ds } else { b };
        match intervals.last_mut() {
            Some(prev) if prev.1 == a => prev.1 = end,
            _ => intervals.push((a, end)),
        }
    }
    intervals
}
