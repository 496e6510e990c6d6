//! Exact lit intervals along a ray.

use glam::DVec3;

use super::cone::Cone;
use super::occluder::{Occluder, Source};
use super::LightSource;
use crate::scene::Light;

/// The parts of the ray `origin + x·dir`, `0 ≤ x ≤ ds`, from which `light_pos` is visible (no
/// occluder surface on the segment to the light), as sorted, disjoint `(start, end)` pairs in
/// distance along the ray (`dir` need not be unit length: it is normalised, and `x` is a
/// distance). The last end is `ds`, which may be `f64::INFINITY` (sky).
///
/// Exact from the geometry, with no sampling: every `x` where visibility can change is found
/// in closed form — for a triangle mesh the ray's crossings of the planes through the light and
/// each edge that can change visibility (silhouette edges seen from the light, boundary and
/// non-manifold edges) and of each triangle's own plane; for each box face the planes through
/// the light and its edges and the face's plane; for each sphere the ray's
/// crossings of the sphere and of its tangent cone from the light. Between consecutive
/// candidates visibility is constant, so it is decided by [`Occluder::segment_blocked`] at the
/// midpoint and at a second interior point (lit only if both see the light, so that a float
/// test slipping between two triangles that share an edge cannot light a piece), and adjacent
/// lit pieces are merged.
///
/// This treats the light as a point light (lit in every direction); [`light_intervals`] also
/// limits the result to a spot light's cone.
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
    intervals(origin, dir, ds, Source::At(light_pos), None, occluders)
}

/// The parts of the ray `origin + x·dir`, `0 ≤ x ≤ ds`, that `light` lights: for a
/// [`Light::Point`] exactly [`lit_intervals`]; for a [`Light::Spot`] the points `X` that are
/// inside its cone, `direction·(X − P) ≥ cos_half_angle·|X − P|` (see
/// [`SpotLight::cos_half_angle`](crate::scene::SpotLight::cos_half_angle); the f32 values
/// converted to f64, the cone's boundary included, the nappe behind the light excluded), *and*
/// see the light past every occluder. Same conventions as [`lit_intervals`].
///
/// The cone is exact too: the ray's entry into and exit from the cone are the roots of a
/// quadratic in `x` (see the [module docs](super) of the reference), taken in closed form and
/// added to the occluders' candidate breakpoints; membership in the cone and visibility are
/// then both decided at the midpoint of each piece. A ray through the apex, a ray tangent to
/// the cone or parallel to one of its generators, an eye inside the cone and `ds = ∞` all give
/// the exact pieces (an isolated touching point is no interval).
pub fn light_intervals(
    origin: DVec3,
    dir: DVec3,
    ds: f64,
    light: &impl LightSource,
    occluders: &[Occluder],
) -> Vec<(f64, f64)> {
    match light.light() {
        Light::Point(point) => {
            let p = point.position().as_dvec3();
            intervals(origin, dir, ds, Source::At(p), None, occluders)
        }
        Light::Spot(spot) => {
            let cone = Cone::new(&spot);
            intervals(
                origin,
                dir,
                ds,
                Source::At(cone.apex()),
                Some(&cone),
                occluders,
            )
        }
        Light::Directional(sun) => {
            super::directional_lit_intervals(origin, dir, ds, &sun, occluders)
        }
    }
}

/// [`light_intervals`] for `light`, limited to `cone` when there is one.
pub(super) fn intervals(
    origin: DVec3,
    dir: DVec3,
    ds: f64,
    light: Source,
    cone: Option<&Cone>,
    occluders: &[Occluder],
) -> Vec<(f64, f64)> {
    let len = dir.length();
    // The distance scale of the light for the sky test point below.
    let (light_pos, reach) = match light {
        Source::At(p) => (p, (p - origin).length()),
        Source::Towards(l) => (l, origin.length()),
    };
    let valid =
        ds > 0.0 && len > 0.0 && len.is_finite() && origin.is_finite() && light_pos.is_finite();
    if !valid {
        return Vec::new();
    }
    let v = dir / len;
    if occluders.is_empty() && cone.is_none() {
        return vec![(0.0, ds)];
    }
    let mut raw = Vec::new();
    for occluder in occluders {
        occluder.candidates(origin, v, light, &mut raw);
    }
    if let Some(cone) = cone {
        cone.candidates(origin, v, &mut raw);
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
        let scale = last.max(reach).max(f64::MIN_POSITIVE.sqrt());
        cuts.push(last + scale); // a test point only; the interval's end is replaced by ∞
    }
    let lit = |x: f64| {
        let point = origin + v * x;
        cone.is_none_or(|c| c.contains(point)) && !occluders.iter().any(|o| o.hides(point, light))
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
        // A second interior point: a float test can slip through the crack between two
        // triangles that share an edge at one point (the midpoint of a ray across a quad's
        // shadow can lie on its diagonal's), not in practice at two.
        if !lit(test) || !lit(a + 0.382 * (b - a)) {
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
