//! The visible fraction of a light's cap by rows: exact along each row of directions, adaptive
//! Gauss–Kronrod across the rows.
//!
//! Seen from `X`, the light (centre `P`, radius `R`, distance `D`) fills the cone of half-angle
//! `α`. In a frame whose third axis points at `P`, the direction `(x, y, 1)` of the plane one
//! unit from `X` is in the cone when `x² + y² ≤ tan²α`, and the solid angle of `dx dy` there is
//! `dx dy / (1 + x² + y²)^{3/2}`. A *row* is the line `y = const` of that plane: the directions
//! in the plane through `X` that holds it. A triangle meets that plane in a segment, which hides
//! an interval of the row; a sphere meets it in a circle, which hides the interval between its
//! two tangents from `X`. The row's visible solid angle is then exact, in closed form
//! (`∫ dx / (1 + x² + y²)^{3/2} = x / ((1 + y²)·√(1 + x² + y²))`) over the gaps between the
//! merged intervals, and the rows are integrated across `y = tan α · sin θ` by adaptive
//! Gauss–Kronrod ([`integrate_to`]), split where a vertex or a sphere's outline begins or ends a
//! row's interval: the integrand is continuous across the rows and smooth between those
//! breakpoints and the rows where two outlines cross (which the bisection finds).
//!
//! # Where a line has entered the light
//!
//! The cone of lines from `X` touches the light's sphere along a circle in the plane at
//! `D·cos²α = D − R·sin α` along the axis; the disc it bounds lies inside the sphere, so every
//! line of the cone is inside the sphere there. A point of the cone outside the sphere is
//! therefore before the sphere on its line when it is nearer `X` than that plane, and behind
//! it otherwise: an occluder that does not reach into the light's sphere blocks a line exactly
//! where its part nearer than that plane meets it. The triangles are clipped there; a sphere
//! occluder meets the cone on one side of it (its intersection with the cone is convex, and
//! the plane meets the cone inside the light), which its extent along the axis tells unless it
//! straddles the plane.
//!
//! [`Shape::of`] gives `None` for an occluder that reaches into the light's sphere, and
//! [`visible`] gives `None` for a sphere that straddles that plane: the caller samples those.

use glam::DVec3;

use super::occluder::{Occluder, TriangleMesh};
use super::quadrature::integrate_to;

/// Tolerance of the integral across the rows, relative to the cap's solid angle.
pub(crate) const ROW_TOLERANCE: f64 = 1e-7;
/// Most bisections of the integral across the rows.
const ROW_BISECTIONS: usize = 100;
/// Pre-split the rows at most this many breakpoints (more are left to the bisection).
const MAX_BREAKPOINTS: usize = 256;

/// An occluder as the rows see it.
pub(crate) enum Shape {
    /// World-space triangles.
    Triangles(Vec<[DVec3; 3]>),
    /// A sphere: centre and radius.
    Ball(DVec3, f64),
}

impl Shape {
    /// The occluder's shape for the rows, or `None` when it reaches into the light's sphere
    /// `(p, r)` (or touches it).
    pub(crate) fn of(occluder: &Occluder, p: DVec3, r: f64) -> Option<Self> {
        match occluder {
            Occluder::Sphere(s) => {
                let rho = s.radius.abs();
                (p.distance(s.center) - rho > r).then_some(Shape::Ball(s.center, rho))
            }
            Occluder::Cuboid(c) => (c.surface_distance(p) > r).then(|| triangles(&c.to_mesh())),
            Occluder::Mesh(m) => m
                .triangle_vertices()
                .all(|t| triangle_distance(t, p) > r)
                .then(|| triangles(m)),
        }
    }
}

fn triangles(m: &TriangleMesh) -> Shape {
    Shape::Triangles(m.triangle_vertices().collect())
}

/// Distance from `p` to the triangle `[a, b, c]` (the closest point by its Voronoi regions:
/// Ericson, "Real-Time Collision Detection", 2005, §5.1.5).
fn triangle_distance([a, b, c]: [DVec3; 3], p: DVec3) -> f64 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.length();
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return bp.length();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return (ap - ab * (d1 / (d1 - d3))).length();
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return cp.length();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return (ap - ac * (d2 / (d2 - d6))).length();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (p - (b + (c - b) * w)).length();
    }
    let sum = va + vb + vc;
    if !(sum != 0.0) {
        // A degenerate triangle: its edges.
        return [ap.length(), bp.length(), cp.length()]
            .into_iter()
            .fold(f64::INFINITY, f64::min);
    }
    let (v, w) = (vb / sum, vc / sum);
    (p - (a + ab * v + ac * w)).length()
}

/// A triangle clipped to the slab `z_min ≤ z ≤ cut` of the frame: a convex polygon of at most
/// five corners, all with `z > 0`.
struct Polygon {
    corners: [DVec3; 5],
    len: usize,
    /// Least and greatest `y / (z·tan α)` of its corners.
    v: (f64, f64),
}

/// Sutherland–Hodgman against `sign·(z − at) ≤ 0`.
fn clip(input: &[DVec3], at: f64, sign: f64, out: &mut Vec<DVec3>) {
    out.clear();
    for (i, &a) in input.iter().enumerate() {
        let b = input[(i + 1) % input.len()];
        let (fa, fb) = (sign * (a.z - at), sign * (b.z - at));
        if fa <= 0.0 {
            out.push(a);
        }
        if (fa < 0.0 && fb > 0.0) || (fa > 0.0 && fb < 0.0) {
            out.push(a + (b - a) * (fa / (fa - fb)));
        }
    }
}

/// The hidden interval of row `y` (directions `(x, y, 1)`) of a polygon: where the plane
/// `Y = y·Z` meets it.
///
/// The soft reference's hot loop: each corner's height above the plane is computed once, and an
/// edge's crossing only in the two components the interval reads, each as the whole vector's
/// would be (the same operations in the same order, so the same bits).
fn polygon_interval(poly: &Polygon, y: f64) -> Option<(f64, f64)> {
    let c = &poly.corners[..poly.len];
    let mut h = [0.0; 5];
    for (h, q) in h.iter_mut().zip(c) {
        *h = q.y - y * q.z;
    }
    let h = &h[..c.len()];
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    let mut add = |x: f64| {
        lo = lo.min(x);
        hi = hi.max(x);
    };
    for i in 0..c.len() {
        let j = if i + 1 == c.len() { 0 } else { i + 1 };
        let (a, b, ha, hb) = (c[i], c[j], h[i], h[j]);
        if ha == 0.0 {
            add(a.x / a.z);
        }
        if (ha < 0.0 && hb > 0.0) || (ha > 0.0 && hb < 0.0) {
            let t = ha / (ha - hb);
            add((a.x + (b.x - a.x) * t) / (a.z + (b.z - a.z) * t));
        }
    }
    (lo < hi).then_some((lo, hi))
}

/// The hidden interval of row `y` of a sphere (centre `c` in the frame, radius `rho`, `X`
/// outside it): between its two tangents from `X` in the row's plane, in front of `X`.
fn ball_interval(c: DVec3, rho: f64, y: f64) -> Option<(f64, f64)> {
    // The plane's unit normal and its unit vectors: a = (1, 0, 0), b = (0, y, 1)/k.
    let k = (1.0 + y * y).sqrt();
    let n = DVec3::new(0.0, 1.0, -y) / k;
    let delta = n.dot(c);
    if delta.abs() >= rho {
        return None;
    }
    let (ca, cb) = (c.x, (y * c.y + c.z) / k);
    let reach = ((rho - delta) * (rho + delta)).sqrt();
    let l = ca.hypot(cb);
    if !(l > reach) {
        return None;
    }
    let centre = cb.atan2(ca);
    let half = (reach / l).asin();
    // Directions at angle φ from a: x = k·cot φ for 0 < φ < π (in front of X). The arc is
    // shorter than π, so it meets (0, π) in one interval, turned by at most one turn.
    let pi = std::f64::consts::PI;
    let cot = |phi: f64| k * phi.cos() / phi.sin();
    [0.0, 2.0 * pi, -2.0 * pi].into_iter().find_map(|turn| {
        let (from, to) = (
            (centre - half + turn).max(0.0),
            (centre + half + turn).min(pi),
        );
        (from < to).then(|| (cot(to), cot(from)))
    })
}

/// The triangle `a` (corners in the cap's frame) clipped to the slab `z_min ≤ z ≤ cut`
/// (`b`: scratch; `a` ends as the clipped polygon), where it keeps a corner and overlaps the
/// cap's square (`tan_a`: the tangent of the cap's half-angle), with the rows through its
/// corners added to `breaks`.
fn clip_polygon(
    (a, b): (&mut Vec<DVec3>, &mut Vec<DVec3>),
    (z_min, cut): (f64, f64),
    tan_a: f64,
    breaks: &mut Vec<f64>,
) -> Option<Polygon> {
    clip(a, z_min, -1.0, b);
    if b.len() < 3 {
        return None;
    }
    clip(b, cut, 1.0, a);
    if a.len() < 3 {
        return None;
    }
    let proj = |q: &DVec3| (q.x / (q.z * tan_a), q.y / (q.z * tan_a));
    let (mut u0, mut u1, mut v0, mut v1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for q in a.iter() {
        let (u, v) = proj(q);
        (u0, u1, v0, v1) = (u0.min(u), u1.max(u), v0.min(v), v1.max(v));
    }
    if u0 >= 1.0 || u1 <= -1.0 || v0 >= 1.0 || v1 <= -1.0 {
        return None; // wholly outside the cap's square
    }
    let mut corners = [DVec3::ZERO; 5];
    let len = a.len().min(5);
    corners[..len].copy_from_slice(&a[..len]);
    for q in a.iter() {
        let v = proj(q).1;
        if v.abs() < 1.0 {
            breaks.push(v.asin());
        }
    }
    Some(Polygon {
        corners,
        len,
        v: (v0, v1),
    })
}

/// The visible fraction of the cap of half-angle `alpha` around the unit `axis` of the light
/// at distance `d` (radius `r`) from `x`, hidden by `shapes`; `None` where a sphere straddles
/// the plane where the lines have entered the light (see the [module docs](self)).
pub(crate) fn visible(
    x: DVec3,
    axis: DVec3,
    d: f64,
    r: f64,
    alpha: f64,
    shapes: &[&Shape],
) -> Option<f64> {
    let (e1, e2) = axis.any_orthonormal_pair();
    let tan_a = alpha.tan();
    if !(tan_a > 0.0 && tan_a.is_finite()) {
        return None;
    }
    let cut = d - r * alpha.sin();
    let z_min = 1e-12 * d;
    let frame = |q: DVec3| {
        let w = q - x;
        DVec3::new(w.dot(e1), w.dot(e2), w.dot(axis))
    };
    let mut polygons: Vec<Polygon> = Vec::new();
    let mut balls: Vec<(DVec3, f64)> = Vec::new();
    let mut breaks: Vec<f64> = Vec::new();
    let (mut a, mut b) = (Vec::with_capacity(8), Vec::with_capacity(8));
    for shape in shapes {
        match shape {
            Shape::Triangles(triangles) => {
                for t in triangles {
                    a.clear();
                    a.extend(t.iter().map(|&q| frame(q)));
                    let slab = (z_min, cut);
                    if let Some(p) = clip_polygon((&mut a, &mut b), slab, tan_a, &mut breaks) {
                        polygons.push(p);
                    }
                }
            }
            &&Shape::Ball(centre, rho) => {
                let c = frame(centre);
                if c.z - rho >= cut {
                    continue; // behind the light
                }
                if c.z + rho > cut {
                    return None;
                }
                // Rows tangent to its outline: (c.y − y·c.z)² = ρ²(1 + y²).
                let (qa, qb, qc) = (c.z * c.z - rho * rho, -c.y * c.z, c.y * c.y - rho * rho);
                let disc = qb * qb - qa * qc;
                if qa != 0.0 && disc >= 0.0 {
                    for y in [(-qb - disc.sqrt()) / qa, (-qb + disc.sqrt()) / qa] {
                        let v = y / tan_a;
                        if v.abs() < 1.0 {
                            breaks.push(v.asin());
                        }
                    }
                }
                balls.push((c, rho));
            }
        }
    }
    let half_pi = std::f64::consts::FRAC_PI_2;
    let mut points = vec![-half_pi, half_pi];
    if breaks.len() <= MAX_BREAKPOINTS {
        points.extend(breaks);
    } else {
        points.extend((1..16).map(|k| -half_pi + std::f64::consts::PI * f64::from(k) / 16.0));
    }
    points.sort_by(f64::total_cmp);
    points.dedup();
    let segments: Vec<(usize, f64, f64)> = points.windows(2).map(|w| (0, w[0], w[1])).collect();
    // By their least row, so that a row reads only those that begin below it (the order of a
    // row's intervals does not change what it sees: `row_seen` sorts them).
    polygons.sort_by(|p, q| p.v.0.total_cmp(&q.v.0));
    // One list of a row's hidden intervals, reused by every row.
    let hidden = std::cell::RefCell::new(Vec::new());
    let row = |theta: f64| row_seen(theta, tan_a, (&polygons, &balls), &mut hidden.borrow_mut());
    // The tolerance is relative to the cap's solid angle as well as to what is seen, which a
    // sliver of the light makes tiny (and a hidden light zero, exactly: no row sees anything).
    let cap = 2.0 * std::f64::consts::PI * 2.0 * (0.5 * alpha).sin().powi(2);
    let seen = integrate_to(
        |_, theta| DVec3::splat(row(theta)),
        &segments,
        ROW_TOLERANCE,
        DVec3::splat(ROW_TOLERANCE * cap),
        ROW_BISECTIONS,
    )
    .x;
    Some((seen / cap).clamp(0.0, 1.0))
}

/// What the row at angle `theta` sees of the cap of half-angle tangent `tan_a`: the rest of its
/// width where `polygons` (in order of their least row, `v.0`) and `balls` hide none, weighted
/// by the solid angle along it (`hidden`: scratch for the row's hidden intervals).
fn row_seen(
    theta: f64,
    tan_a: f64,
    (polygons, balls): (&[Polygon], &[(DVec3, f64)]),
    hidden: &mut Vec<(f64, f64)>,
) -> f64 {
    let (s, c) = theta.sin_cos();
    let y = tan_a * s;
    let w = tan_a * c;
    let k2 = 1.0 + y * y;
    let f = |x: f64| x / (k2 * (k2 + x * x).sqrt());
    let v = s;
    hidden.clear();
    hidden.extend(
        polygons
            .iter()
            .take_while(|p| p.v.0 < v)
            .filter(|p| v < p.v.1)
            .filter_map(|p| polygon_interval(p, y))
            .chain(
                balls
                    .iter()
                    .filter_map(|&(c, rho)| ball_interval(c, rho, y)),
            )
            .map(|(lo, hi)| (lo.max(-w), hi.min(w)))
            .filter(|(lo, hi)| lo < hi),
    );
    hidden.sort_by(|p, q| p.0.total_cmp(&q.0));
    let mut seen = 0.0;
    let mut from = -w;
    for &(lo, hi) in hidden.iter() {
        if lo > from {
            seen += f(lo) - f(from);
        }
        from = from.max(hi);
    }
    if w > from {
        seen += f(w) - f(from);
    }
    tan_a * c * seen
}
