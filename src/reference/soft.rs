//! Soft shadows of a light with a radius: the visible fraction of its disc, and the in-scattered
//! radiance weighted by it.
//!
//! # The model
//!
//! The light is a sphere of radius `R` around its position `P`. Seen from a point `X` at
//! distance `D > R`, it fills the cone of half-angle `α = asin(R/D)` around `P − X`: a spherical
//! cap of solid angle `Ω_L = 2π(1 − cos α)`. The *visible fraction* `f(X)` is the part of that
//! solid angle that no occluder hides; the in-scattered integrand is (1) of the
//! [module docs](super) with `V(x)` replaced by `f(X)` (times a spot light's cone membership of
//! `X`, measured from the centre as for a point light). With `R = 0`, `f` is the point light's
//! visibility and [`inscatter_soft`] is [`inscatter`](super::inscatter). A point inside the
//! light's sphere has `f = 1`.
//!
//! # Spheres: exact
//!
//! A sphere occluder (centre `C`, radius `ρ`) seen from `X` outside it is a cap of half-angle
//! `β = asin(ρ/|C − X|)`, at the angle `γ` from the light's axis. Two caps overlap in
//! `Ω = 2·[φ_L·(1 − cos α) + φ_O·(1 − cos β) − E]` (Gauss–Bonnet on the lens), where `φ_L`,
//! `φ_O` are the angles at the caps' centres of the spherical triangle with sides `α, β, γ` and
//! `E` its spherical excess (L'Huilier's formula), all by half-angle formulas that keep their
//! relative precision for small caps. The occluder hides `Ω/Ω_L` when it is in front of the
//! light, i.e. `X` lies on its side of the plane through `P` perpendicular to `C − P`: exact
//! when the occluder lies wholly between `X` and the light; the whole light when `X` or `P` is
//! inside it (and not both). One sphere partially over the light's cap is exact; when two or
//! more occluders reach it, their union is found by rows, as below.
//!
//! # Boxes, meshes and several occluders: by rows
//!
//! In a frame whose third axis points at the light, the cap is the disc `x² + y² ≤ tan²α` of
//! the plane one unit from `X`. Each row `y = const` of it is a plane through `X`, which meets
//! a triangle (a box's or a mesh's) in a segment and a sphere in a circle: each hides an
//! interval of the row, and the row's visible solid angle is exact, in closed form, over the
//! gaps between them. The rows are integrated across the disc by adaptive Gauss–Kronrod (to
//! 1e-7 of the cap's solid angle), split where a corner or a sphere's outline begins a row's
//! interval. An occluder blocks a line only before the line enters the light's sphere: the
//! cone of lines from `X` touches the sphere along a circle whose disc lies inside it, so an
//! occluder that does not reach into the light's sphere blocks exactly with its part nearer
//! than that circle's plane, and the triangles are clipped there. Measured against the
//! closed forms of a slit between two plates and of two spheres whose caps are apart
//! (`tests/cpu/reference_soft.rs`): within 2e-7. Exact along each row, the rows keep slivers
//! of the light (a door ajar seen from beside its shaft) that no fixed set of directions
//! resolves.
//!
//! # Occluders in the light: sampled
//!
//! Where an occluder reaches into the light's sphere (or a sphere straddles that plane) the
//! cap is sampled instead ([`sampled_fraction`]): it is split into `N × N` strata of equal
//! solid angle (the concentric map of Shirley and Chiu, "A Low Distortion Map Between Disk and
//! Square", 1997, from the square to the disc, then the disc's area to the cap's solid angle),
//! one direction per stratum at a fixed jitter (a hash of the stratum: every call samples the
//! same directions), and a direction is hidden when the segment from `X` to where it meets the
//! light's sphere is blocked ([`Occluder::segment_blocked`]). Only strata that an outline
//! crosses can be wrong, each by at most `1/N²`; the inverse concentric map stretches lengths
//! by at most 1.76, so an outline of length `ℓ` (in units of the disc's radius: `ℓ ≤ 2π` for
//! one convex occluder) crosses at most `4·(0.88·ℓ·N + 1)` strata and the error is at most
//! `(3.6·ℓ + 4/N)/N` (`≤ 23/N` for one convex occluder). That worst case is far from the
//! typical one (a jittered stratum errs as often one way as the other): measured on a 64 × 32
//! mesh sphere across its penumbra (123 points, `tests/cpu/reference_soft.rs`), the sampled
//! fraction stays within 0.24/N (0.015 at [`SAMPLES_PER_SIDE`] = 16) of the band between the
//! closed forms of its inscribed and circumscribed spheres; the stated bound is 0.3/N. On the
//! slits of the rows' test it is up to 0.018 off, which is most of a sliver a few strata
//! wide.
//!
//! # Along a ray
//!
//! [`inscatter_soft`] splits the ray where the kind of `f` can change: the point light's own
//! breakpoints ([`light_intervals`](super::light_intervals)), the ray's crossings of the
//! light's sphere, and per sphere occluder its two cones of lines tangent to both spheres (the
//! umbra's edge `γ = β − α` and the penumbra's edge `γ = α + β`, quadrics in closed form) and
//! the plane above. For a box or mesh the same cones of its bounding sphere bound where it can
//! hide part of the light. Each piece is then wholly dark (skipped), wholly lit (the hard
//! reference's quadrature, [`RELATIVE_TOLERANCE`](super::RELATIVE_TOLERANCE)), fractional
//! and exact (adaptive Gauss–Kronrod with `f` to [`SOFT_TOLERANCE`]), by rows (the same to
//! [`ROWS_TOLERANCE`], at most [`ROWS_BISECTIONS`] bisections) or sampled (to [`SAMPLED_TOLERANCE`], at most [`SAMPLED_BISECTIONS`]
//! bisections: `f` is then a step function in steps of `1/N²`).

use glam::DVec3;

use super::cone::Cone;
use super::quadrature::integrate;
use super::rows::{self, Shape};
use super::texture::Projection;
use super::{Integrand, LightSource, Occluder, RayLight, MAX_BISECTIONS};
use crate::scene::{Camera, Light, Medium};

/// Strata per side of the sampled light disc (`N`; `N²` directions).
pub const SAMPLES_PER_SIDE: u32 = 16;
/// Relative tolerance of the quadrature where `f` is fractional and exact (spheres).
pub const SOFT_TOLERANCE: f64 = 1e-9;
/// Relative tolerance of the quadrature where `f` is found by rows (boxes, meshes, and
/// spheres among them).
pub const ROWS_TOLERANCE: f64 = 1e-4;
/// Most bisections of one such piece's quadrature.
pub const ROWS_BISECTIONS: usize = 100;
/// Relative tolerance of the quadrature where `f` is sampled.
pub const SAMPLED_TOLERANCE: f64 = 1e-4;
/// Most bisections of one sampled piece's quadrature.
pub const SAMPLED_BISECTIONS: usize = 40;

/// An occluder with its bounding sphere (exact for a sphere), and its shape for the rows
/// (`None` where it reaches into the light's sphere).
struct Bound<'a> {
    center: DVec3,
    radius: f64,
    occluder: &'a Occluder,
    shape: Option<Shape>,
}

/// How a visible fraction was found: in closed form, by rows, or sampled.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    Exact,
    Rows,
    Sampled,
}

/// The occluders' bounds for `light` (its centre and radius; none for a directional light).
fn light_bounds(occluders: &[Occluder], light: Light) -> Vec<Bound<'_>> {
    let p = light.position().unwrap_or_default().as_dvec3();
    bounds(occluders, p, f64::from(light.radius()))
}

/// The occluders' bounds for the light `(p, r)`.
fn bounds<'a>(occluders: &'a [Occluder], p: DVec3, r: f64) -> Vec<Bound<'a>> {
    let bound = |occluder: &'a Occluder| {
        let (center, radius) = match occluder {
            Occluder::Sphere(s) => (s.center, s.radius.abs()),
            Occluder::Cuboid(c) => (c.center, c.half_extents.abs().length()),
            Occluder::Mesh(m) => {
                let p = m.positions();
                let lo = p.iter().fold(DVec3::INFINITY, |a, &b| a.min(b));
                let hi = p.iter().fold(DVec3::NEG_INFINITY, |a, &b| a.max(b));
                let c = 0.5 * (lo + hi);
                (c, p.iter().map(|&q| q.distance(c)).fold(0.0, f64::max))
            }
        };
        Bound {
            center,
            radius,
            occluder,
            shape: (r > 0.0).then(|| Shape::of(occluder, p, r)).flatten(),
        }
    };
    occluders.iter().map(bound).collect()
}

/// The cap that a sphere `(center, radius)` fills seen from `x`: unit axis and half-angle;
/// `None` when `x` is inside or on it.
fn cap(x: DVec3, center: DVec3, radius: f64) -> Option<(DVec3, f64)> {
    let to = center - x;
    let d = to.length();
    (d > radius).then(|| (to / d, radius.atan2(((d - radius) * (d + radius)).sqrt())))
}

/// `1 − cos a` without cancellation.
fn versine(a: f64) -> f64 {
    2.0 * (0.5 * a).sin().powi(2)
}

/// Solid angle of the overlap of two caps of half-angles `a`, `b` (≤ π/2) whose axes are `g`
/// apart (see the module docs).
fn overlap(a: f64, b: f64, g: f64) -> f64 {
    if g >= a + b {
        return 0.0;
    }
    if g <= (a - b).abs() {
        return 2.0 * std::f64::consts::PI * versine(a.min(b));
    }
    let s = 0.5 * (a + b + g);
    let (ss, sa, sb, sg) = (s.sin(), (s - a).sin(), (s - b).sin(), (s - g).sin());
    let phi_a = 2.0 * (sa * sg / (ss * sb)).sqrt().atan();
    let phi_b = 2.0 * (sb * sg / (ss * sa)).sqrt().atan();
    let t = |u: f64| (0.5 * u).tan();
    let excess = 4.0 * (t(s) * t(s - a) * t(s - b) * t(s - g)).sqrt().atan();
    (2.0 * (phi_a * versine(a) + phi_b * versine(b) - excess)).max(0.0)
}

/// Angle between two unit vectors.
fn angle(a: DVec3, b: DVec3) -> f64 {
    a.cross(b).length().atan2(a.dot(b))
}

/// The fraction of the light's cap visible from `x` (see the module docs), and how it was
/// found.
fn fraction(x: DVec3, p: DVec3, r: f64, bounds: &[Bound]) -> (f64, Kind) {
    if !(r > 0.0) {
        let blocked = bounds.iter().any(|b| b.occluder.segment_blocked(x, p));
        return (if blocked { 0.0 } else { 1.0 }, Kind::Exact);
    }
    let Some((axis, alpha)) = cap(x, p, r) else {
        return (1.0, Kind::Exact);
    };
    let mut partial: Vec<&Bound> = Vec::new();
    let mut hidden = 0.0;
    for b in bounds {
        let exact = matches!(b.occluder, Occluder::Sphere(_));
        let Some((oaxis, beta)) = cap(x, b.center, b.radius) else {
            if !exact {
                partial.push(b);
            } else if p.distance(b.center) >= b.radius {
                return (0.0, Kind::Exact); // x inside, the light's centre outside
            }
            continue;
        };
        let g = angle(axis, oaxis);
        if exact && p.distance(b.center) <= b.radius {
            return (0.0, Kind::Exact); // the light's centre inside
        }
        if g >= alpha + beta || (exact && (b.center - p).dot(x - p) <= 0.0) {
            continue; // apart, or behind the light
        }
        if exact && g + alpha <= beta {
            return (0.0, Kind::Exact); // umbra
        }
        partial.push(b);
        hidden = overlap(alpha, beta, g);
    }
    match partial[..] {
        [] => (1.0, Kind::Exact),
        [Bound {
            occluder: Occluder::Sphere(_),
            ..
        }] => (
            (1.0 - hidden / (2.0 * std::f64::consts::PI * versine(alpha))).clamp(0.0, 1.0),
            Kind::Exact,
        ),
        _ => {
            let shapes: Option<Vec<&Shape>> = partial.iter().map(|b| b.shape.as_ref()).collect();
            let by_rows =
                shapes.and_then(|shapes| rows::visible(x, axis, x.distance(p), r, alpha, &shapes));
            match by_rows {
                Some(f) => (f, Kind::Rows),
                None => {
                    let occluders: Vec<&Occluder> = partial.iter().map(|b| b.occluder).collect();
                    (sampled(x, p, r, axis, alpha, &occluders), Kind::Sampled)
                }
            }
        }
    }
}

/// A fixed jitter in `[0, 1)²` for stratum `k` (SplitMix64).
fn jitter(k: u64) -> (f64, f64) {
    let mut z = k.wrapping_add(1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    let unit = |bits: u64| (bits >> 11) as f64 / (1u64 << 53) as f64;
    (unit(z & 0xFFFF_FFFF_0000_0000), unit(z << 32))
}

/// The visible fraction of the cap `(axis, alpha)` of the light `(p, r)` from `x` by stratified
/// sampling against `occluders`.
fn sampled(x: DVec3, p: DVec3, r: f64, axis: DVec3, alpha: f64, occluders: &[&Occluder]) -> f64 {
    let n = SAMPLES_PER_SIDE;
    let (e1, e2) = axis.any_orthonormal_pair();
    let (d, cap) = (x.distance(p), versine(alpha));
    let mut hidden = 0u32;
    for k in 0..n * n {
        let (ju, jv) = jitter(u64::from(k));
        let a = 2.0 * ((k % n) as f64 + ju) / n as f64 - 1.0;
        let b = 2.0 * ((k / n) as f64 + jv) / n as f64 - 1.0;
        // Concentric map to the unit disc.
        let (rho, phi) = if a.abs() > b.abs() {
            (a, std::f64::consts::FRAC_PI_4 * b / a)
        } else if b != 0.0 {
            (
                b,
                std::f64::consts::FRAC_PI_2 - std::f64::consts::FRAC_PI_4 * a / b,
            )
        } else {
            (0.0, 0.0)
        };
        let q = rho * rho * cap; // 1 − cos θ: equal areas of the disc, equal solid angles
        let (sin_t, cos_t) = ((q * (2.0 - q)).sqrt(), 1.0 - q);
        let u = axis * cos_t + (e1 * phi.cos() + e2 * phi.sin()) * (sin_t * rho.signum());
        let reach = d * cos_t - (r * r - d * d * sin_t * sin_t).max(0.0).sqrt();
        let end = x + u * reach;
        if occluders.iter().any(|o| o.segment_blocked(x, end)) {
            hidden += 1;
        }
    }
    1.0 - f64::from(hidden) / f64::from(n * n)
}

/// The fraction of the disc of the light of `radius` at `light_center` seen from `x` that no
/// occluder hides, in `[0, 1]` (see the [module docs](self): in closed form for a single
/// sphere partially in front of the light, by rows to 2e-7 otherwise, sampled with the stated
/// bound where an occluder reaches into the light's sphere). `radius ≤ 0` (or
/// NaN) gives the point light's visibility, 0 or 1; `x` inside the light's sphere gives 1.
pub fn visible_fraction(x: DVec3, light_center: DVec3, radius: f64, occluders: &[Occluder]) -> f64 {
    fraction(
        x,
        light_center,
        radius,
        &bounds(occluders, light_center, radius),
    )
    .0
}

/// The visible fraction by `N × N` directions ([`SAMPLES_PER_SIDE`]), whatever the occluders:
/// what [`visible_fraction`] falls back to where the rows cannot be used (see the
/// [module docs](self)), for comparison.
pub fn sampled_fraction(x: DVec3, light_center: DVec3, radius: f64, occluders: &[Occluder]) -> f64 {
    let Some((axis, alpha)) = cap(x, light_center, radius) else {
        return 1.0;
    };
    let all: Vec<&Occluder> = occluders.iter().collect();
    sampled(x, light_center, radius, axis, alpha, &all)
}

/// Appends the real roots of `a·x² + 2·b·x + c` and the vertex `−b/a`.
fn roots(a: f64, b: f64, c: f64, out: &mut Vec<f64>) {
    if a != 0.0 {
        out.push(-b / a);
    }
    let disc = b * b - a * c;
    if disc >= 0.0 {
        let q = -(b + disc.sqrt().copysign(b));
        if a != 0.0 {
            out.push(q / a);
        }
        if q != 0.0 {
            out.push(c / q);
        }
    }
}

/// Ray distances where `f` can change kind because of the sphere `(c, rho)` (an occluder or a
/// bound) and the light `(p, r)`: its crossings by `e + x·v`, the two cones of lines tangent
/// to both spheres and the plane through `p` perpendicular to `c − p`.
fn soft_candidates(e: DVec3, v: DVec3, p: DVec3, r: f64, c: DVec3, rho: f64, out: &mut Vec<f64>) {
    let f = e - c;
    roots(1.0, f.dot(v), f.length_squared() - rho * rho, out);
    let l = p.distance(c);
    if !(l > 0.0) {
        return;
    }
    let axis = (c - p) / l;
    let (w0, av) = (e - p, axis.dot(v));
    let z0 = axis.dot(w0);
    if av != 0.0 {
        out.push(-z0 / av);
    }
    // A line tangent to both, in a meridian plane: n_z·z − √(1 − n_z²)·r_⊥ + R = 0, squared:
    // (1 − n_z²)|w|² − z² − 2R·n_z·z − R² = 0 with w = X − P, z = axis·w.
    for nz in [(rho - r) / l, -(rho + r) / l] {
        if nz.abs() < 1.0 {
            let k = 1.0 - nz * nz;
            let a = k - av * av;
            let b = k * v.dot(w0) - z0 * av - r * nz * av;
            let c0 = k * w0.length_squared() - z0 * z0 - 2.0 * r * nz * z0 - r * r;
            roots(a, b, c0, out);
        }
    }
}

/// ∫ over `[a, b]` (`b` may be `∞`) of the integrand times `f(x)`, adaptively.
fn integrate_weighted(
    g: &Integrand,
    a: f64,
    b: f64,
    f: impl Fn(f64) -> f64,
    tol: f64,
    bisections: usize,
) -> DVec3 {
    let RayLight { distance, t, h, .. } = g.geo;
    let (wa, wb) = (a - t, b - t);
    let mut points = vec![wa, 0.0];
    if h > 0.0 {
        points.extend((0..12).flat_map(|k| [-1.0, 1.0].map(|s| s * h * 4f64.powi(k - 2))));
    }
    points.retain(|&w| w >= wa && w < wb);
    points.sort_by(f64::total_cmp);
    points.dedup();
    let mut segments: Vec<(usize, f64, f64)> = points.windows(2).map(|p| (0, p[0], p[1])).collect();
    let last = *points.last().unwrap_or(&wa);
    let tail = (last - wa)
        .max(distance)
        .max(h)
        .max(f64::MIN_POSITIVE.sqrt());
    segments.push(if b.is_finite() {
        (0, last, wb)
    } else {
        (1, 0.0, 1.0)
    });
    let scale = if h > 0.0 { h } else { 1.0 };
    let value = integrate(
        |map, u| {
            let (w, jac) = if map == 0 {
                (u, 1.0)
            } else {
                (last + tail * u / (1.0 - u), tail / ((1.0 - u) * (1.0 - u)))
            };
            g.at(w, scale) * (f(w + t) * jac)
        },
        &segments,
        tol,
        bisections,
    );
    value / scale
}

/// In-scattered radiance (RGB) along the ray `origin + x·dir`, `0 ≤ x ≤ ds`, from `light` with
/// its [`radius`](crate::scene::Light::radius): [`inscatter`](super::inscatter) with the
/// visibility replaced by [`visible_fraction`] (see the [module docs](self) for the model, the
/// breakpoints and the tolerances). With radius 0 the pieces are exactly the hard reference's
/// lit intervals, integrated the same way. Same conventions for degenerate input as
/// [`inscatter`](super::inscatter).
pub fn inscatter_soft(
    origin: DVec3,
    dir: DVec3,
    ds: f64,
    medium: &Medium,
    light: &impl LightSource,
    occluders: &[Occluder],
) -> DVec3 {
    let light_ = light.light();
    let bounds = light_bounds(occluders, light_);
    soft_light(
        origin,
        dir,
        ds,
        medium,
        light_,
        light.texture(),
        occluders,
        &bounds,
    )
}

#[allow(clippy::too_many_arguments)]
fn soft_light(
    origin: DVec3,
    dir: DVec3,
    ds: f64,
    medium: &Medium,
    light: Light,
    texture: Option<&crate::scene::LightTexture>,
    occluders: &[Occluder],
    bounds: &[Bound],
) -> DVec3 {
    let p = match light {
        // No radius: the hard-shadowed integral.
        Light::Directional(sun) => {
            return super::inscatter_directional(origin, dir, ds, medium, &sun, occluders);
        }
        _ => light.position().unwrap_or_default().as_dvec3(),
    };
    let r = f64::from(light.radius());
    let Some(geo) = RayLight::new(origin, dir, p) else {
        return DVec3::ZERO;
    };
    if !(ds > 0.0) {
        return DVec3::ZERO;
    }
    let (cone, projection) = match (light, texture) {
        (Light::Spot(s), Some(t)) => (Some(Cone::new(&s)), Some(Projection::new(&s, t))),
        (Light::Spot(s), None) => (Some(Cone::new(&s)), None),
        _ => (None, None),
    };
    let g = Integrand::new(geo, medium, light.intensity()).textured(projection);
    // The direction exactly as `light_intervals` normalises it again, so that radius 0 cuts
    // the ray at the same points.
    let v = geo.v / geo.v.length();
    let mut raw = Vec::new();
    for o in occluders {
        o.candidates(origin, v, super::occluder::Source::At(p), &mut raw);
    }
    if let Some(cone) = &cone {
        cone.candidates(origin, v, &mut raw);
    }
    if r > 0.0 {
        let f = origin - p;
        roots(1.0, f.dot(v), f.length_squared() - r * r, &mut raw);
        for b in bounds {
            soft_candidates(origin, v, p, r, b.center, b.radius, &mut raw);
        }
    }
    let mut cuts = vec![0.0];
    cuts.extend(raw.into_iter().filter(|&x| x > 0.0 && x < ds));
    cuts.sort_by(f64::total_cmp);
    cuts.dedup();
    let last = *cuts.last().unwrap_or(&0.0);
    // As in `light_intervals`: beyond the last cut any point decides.
    let end = if ds.is_finite() {
        ds
    } else {
        last + last.max(geo.distance).max(f64::MIN_POSITIVE.sqrt())
    };
    cuts.push(end);
    let f = |x: f64| {
        let point = origin + v * x;
        if cone.as_ref().is_some_and(|c| !c.contains(point)) {
            return (0.0, Kind::Exact);
        }
        fraction(point, p, r, bounds)
    };
    let mut lit: Vec<(f64, f64)> = Vec::new();
    let mut total = DVec3::ZERO;
    let n = cuts.len();
    for i in 0..n - 1 {
        let (a, b) = (cuts[i], if i == n - 2 { ds } else { cuts[i + 1] });
        let test = if b.is_finite() { 0.5 * (a + b) } else { end };
        match f(test) {
            (0.0, Kind::Exact) => {}
            (1.0, Kind::Exact) => match lit.last_mut() {
                Some(prev) if prev.1 == a => prev.1 = b,
                _ => lit.push((a, b)),
            },
            (_, kind) => {
                let (tol, cap) = match kind {
                    Kind::Exact => (SOFT_TOLERANCE, MAX_BISECTIONS),
                    Kind::Rows => (ROWS_TOLERANCE, ROWS_BISECTIONS),
                    Kind::Sampled => (SAMPLED_TOLERANCE, SAMPLED_BISECTIONS),
                };
                total += integrate_weighted(&g, a, b, |x| f(x).0, tol, cap);
            }
        }
    }
    total
        + lit
            .into_iter()
            .map(|(a, b)| g.integrate_x(a, b))
            .sum::<DVec3>()
}

/// [`inscatter_soft`] for every pixel of a `width × height` image seen by `camera`, with the
/// conventions of [`inscatter_image`](super::inscatter_image) (row-major, row 0 at the top,
/// `distance(eye, dir)` the ray's `ds`, rows shared among the available threads).
pub fn inscatter_image_soft(
    camera: &Camera,
    width: u32,
    height: u32,
    distance: impl Fn(DVec3, DVec3) -> f64 + Sync,
    medium: &Medium,
    light: &impl LightSource,
    occluders: &[Occluder],
) -> Vec<DVec3> {
    let (texture, light) = (light.texture(), light.light());
    let bounds = light_bounds(occluders, light);
    super::render(camera, width, height, |eye, dir| {
        let ds = distance(eye, dir);
        soft_light(eye, dir, ds, medium, light, texture, occluders, &bounds)
    })
}
