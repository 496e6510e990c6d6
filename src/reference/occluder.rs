//! Occluders with exact segment tests, and the exact points along a ray where their shadow can
//! begin or end.
//!
//! Occluders are opaque *surfaces*: a segment is blocked iff it meets the surface. For a closed
//! occluder (sphere, box, closed mesh) this is the same as "meets the solid" unless both ends lie
//! inside it: a light inside a sphere lights the inside of the sphere and nothing outside, as a
//! shadow map rendered from inside would.

use glam::{DMat4, DQuat, DVec3, Vec3};

/// A sphere, `|X − center| = radius` (the radius' sign is ignored).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    /// Centre, world space.
    pub center: DVec3,
    /// Radius, world units.
    pub radius: f64,
}

impl Sphere {
    /// A sphere at `center` with `radius`.
    pub fn new(center: DVec3, radius: f64) -> Self {
        Self { center, radius }
    }

    /// Whether the closed segment `[a, b]` meets the sphere's surface.
    pub fn segment_blocked(&self, a: DVec3, b: DVec3) -> bool {
        let r2 = self.radius * self.radius;
        let fa = a - self.center;
        let fb = b - self.center;
        if fa.length_squared() < r2 && fb.length_squared() < r2 {
            return false; // wholly inside: the surface is never crossed
        }
        let d = b - a;
        let dd = d.length_squared();
        let s = if dd > 0.0 {
            (-fa.dot(d) / dd).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (fa + d * s).length_squared() <= r2
    }

    /// Ray distances where the visibility of `p` from `e + x·v` (`v` unit) can change: the
    /// ray's crossings of the sphere and of the tangent cone from `p`.
    fn candidates(&self, e: DVec3, v: DVec3, p: DVec3, out: &mut Vec<f64>) {
        let r = self.radius.abs();
        // The sphere itself.
        let f = e - self.center;
        let b = f.dot(v);
        let perp = f - v * b;
        let disc = r * r - perp.length_squared();
        if disc >= 0.0 {
            let s = disc.sqrt();
            out.extend([-b - s, -b + s]);
        }
        // The tangent cone (apex p, axis towards the centre, sin α = r / L) exists when p is
        // outside the sphere.
        let axis = self.center - p;
        let l = axis.length();
        if !(l > r) {
            return;
        }
        let w = axis / l;
        let cos2 = (1.0 - (r / l) * (r / l)).max(0.0);
        let q = e - p;
        let (vw, qw) = (v.dot(w), q.dot(w));
        // ((q + x v)·w)² = cos²α |q + x v|²
        let qa = vw * vw - cos2;
        let qb = qw * vw - cos2 * q.dot(v);
        let qc = qw * qw - cos2 * q.length_squared();
        for x in quadratic_roots(qa, qb, qc) {
            // Keep the nappe on the sphere's side (with slack: extra candidates are harmless).
            let y = q + v * x;
            if y.dot(w) >= -1e-9 * y.length() {
                out.push(x);
            }
        }
    }
}

/// Real roots of `a x² + 2 b x + c = 0`, stably; a slightly negative discriminant (rounding, a
/// ray tangent to the cone) gives the double root.
fn quadratic_roots(a: f64, b: f64, c: f64) -> Vec<f64> {
    let mut roots = Vec::with_capacity(2);
    if a == 0.0 {
        if b != 0.0 {
            roots.push(-c / (2.0 * b));
        }
        return roots;
    }
    let disc = b * b - a * c;
    let scale = (b * b).max((a * c).abs());
    if disc < 0.0 {
        if disc >= -1e-12 * scale {
            roots.push(-b / a);
        }
        return roots;
    }
    let q = -(b + disc.sqrt().copysign(b));
    roots.push(q / a);
    if q != 0.0 {
        roots.push(c / q);
    }
    roots.retain(|x| x.is_finite());
    roots
}

/// An oriented box: `center + rotation · (±half_extents)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cuboid {
    /// Centre, world space.
    pub center: DVec3,
    /// Half the edge lengths along the box's local axes (signs ignored).
    pub half_extents: DVec3,
    /// Rotation from the box's local axes to world axes (normalised on use; a zero or
    /// non-finite quaternion reads as the identity).
    pub rotation: DQuat,
}

impl Cuboid {
    /// A box with the given centre, half extents and rotation.
    pub fn new(center: DVec3, half_extents: DVec3, rotation: DQuat) -> Self {
        Self {
            center,
            half_extents,
            rotation,
        }
    }

    /// An axis-aligned box.
    pub fn axis_aligned(center: DVec3, half_extents: DVec3) -> Self {
        Self::new(center, half_extents, DQuat::IDENTITY)
    }

    fn rotation(&self) -> DQuat {
        let len = self.rotation.length();
        if len > 0.0 && len.is_finite() {
            self.rotation / len
        } else {
            DQuat::IDENTITY
        }
    }

    fn local_point(&self, p: DVec3) -> DVec3 {
        self.rotation().inverse() * (p - self.center)
    }

    /// The 8 corners in world space (bit k of the index picks the sign along local axis k).
    pub fn corners(&self) -> [DVec3; 8] {
        let h = self.half_extents.abs();
        let r = self.rotation();
        std::array::from_fn(|i| {
            let s = DVec3::new(
                if i & 1 == 0 { -1.0 } else { 1.0 },
                if i & 2 == 0 { -1.0 } else { 1.0 },
                if i & 4 == 0 { -1.0 } else { 1.0 },
            );
            self.center + r * (s * h)
        })
    }

    /// The box as 12 outward-facing triangles (two per face).
    pub fn to_mesh(&self) -> TriangleMesh {
        const TRIANGLES: [[u32; 3]; 12] = [
            [0, 4, 6],
            [0, 6, 2], // −x
            [1, 3, 7],
            [1, 7, 5], // +x
            [0, 1, 5],
            [0, 5, 4], // −y
            [2, 6, 7],
            [2, 7, 3], // +y
            [0, 2, 3],
            [0, 3, 1], // −z
            [4, 5, 7],
            [4, 7, 6], // +z
        ];
        TriangleMesh::new(self.corners().to_vec(), TRIANGLES.to_vec())
    }

    /// Whether the closed segment `[a, b]` meets the box's surface.
    pub fn segment_blocked(&self, a: DVec3, b: DVec3) -> bool {
        let h = self.half_extents.abs();
        let (la, lb) = (self.local_point(a), self.local_point(b));
        let inside = |p: DVec3| (0..3).all(|k| p[k].abs() < h[k]);
        if inside(la) && inside(lb) {
            return false;
        }
        // Slab clipping of s ∈ [0, 1] against the solid box.
        let d = lb - la;
        let (mut s0, mut s1) = (0.0f64, 1.0f64);
        for k in 0..3 {
            if d[k] == 0.0 {
                if la[k].abs() > h[k] {
                    return false;
                }
                continue;
            }
            let t0 = (-h[k] - la[k]) / d[k];
            let t1 = (h[k] - la[k]) / d[k];
            s0 = s0.max(t0.min(t1));
            s1 = s1.min(t0.max(t1));
            if s0 > s1 {
                return false;
            }
        }
        true
    }

    fn candidates(&self, e: DVec3, v: DVec3, p: DVec3, out: &mut Vec<f64>) {
        // Work in the box's frame: a rotation keeps distances along the ray.
        let h = self.half_extents.abs();
        let (o, d, pl) = (
            self.local_point(e),
            self.rotation().inverse() * v,
            self.local_point(p),
        );
        // Face planes, where the crossing lies on the face.
        for k in 0..3 {
            if d[k] == 0.0 {
                continue;
            }
            for side in [-1.0, 1.0] {
                let x = (side * h[k] - o[k]) / d[k];
                let y = o + d * x;
                let on_face = (0..3)
                    .filter(|&j| j != k)
                    .all(|j| y[j].abs() <= h[j] * (1.0 + 1e-6) + 1e-300);
                if on_face && x.is_finite() {
                    out.push(x);
                }
            }
        }
        // Planes through the light and each of the 12 edges.
        let corner = |i: usize| {
            DVec3::new(
                if i & 1 == 0 { -h.x } else { h.x },
                if i & 2 == 0 { -h.y } else { h.y },
                if i & 4 == 0 { -h.z } else { h.z },
            )
        };
        for i in 0..8 {
            for bit in [1, 2, 4] {
                let j = i ^ bit;
                if i < j {
                    edge_candidate(o, d, pl, corner(i), corner(j), out);
                }
            }
        }
    }
}

/// The ray's crossing of the plane through the light `p` and the edge `[vi, vj]`, kept if the
/// segment from the light to the crossing point can touch the edge there.
fn edge_candidate(e: DVec3, v: DVec3, p: DVec3, vi: DVec3, vj: DVec3, out: &mut Vec<f64>) {
    let (a, b) = (vi - p, vj - p);
    let n = a.cross(b);
    let nv = n.dot(v);
    if nv == 0.0 {
        return;
    }
    let x = n.dot(p - e) / nv;
    if !x.is_finite() {
        return;
    }
    // y = X − p = α a + β b; the segment p → X meets the edge iff α, β ≥ 0 and α + β ≥ 1.
    let y = e + v * x - p;
    let (aa, ab, bb) = (a.dot(a), a.dot(b), b.dot(b));
    let det = aa * bb - ab * ab;
    if det > 1e-20 * aa * bb {
        let (ay, by) = (a.dot(y), b.dot(y));
        let alpha = (bb * ay - ab * by) / det;
        let beta = (aa * by - ab * ay) / det;
        const SLACK: f64 = 1e-6;
        if alpha < -SLACK || beta < -SLACK || alpha + beta < 1.0 - SLACK {
            return;
        }
    }
    out.push(x);
}

/// A triangle mesh (an open or closed surface).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TriangleMesh {
    /// Vertex positions, world space.
    pub positions: Vec<DVec3>,
    /// Triangles as indices into `positions`; triangles with an out-of-range index are ignored.
    pub triangles: Vec<[u32; 3]>,
}

impl TriangleMesh {
    /// A mesh from world-space positions and index triples.
    pub fn new(positions: Vec<DVec3>, triangles: Vec<[u32; 3]>) -> Self {
        Self {
            positions,
            triangles,
        }
    }

    /// A mesh whose positions are `transform` applied to `positions` (as points).
    pub fn transformed(positions: &[DVec3], triangles: &[[u32; 3]], transform: DMat4) -> Self {
        Self::new(
            positions
                .iter()
                .map(|&p| transform.transform_point3(p))
                .collect(),
            triangles.to_vec(),
        )
    }

    /// A mesh from f32 positions and a flat index list (three per triangle, a trailing partial
    /// triangle is ignored), as uploaded to the GPU, placed in the world by `transform`.
    pub fn from_indexed(positions: &[Vec3], indices: &[u32], transform: DMat4) -> Self {
        Self::new(
            positions
                .iter()
                .map(|p| transform.transform_point3(p.as_dvec3()))
                .collect(),
            indices
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect(),
        )
    }

    /// The triangles' vertices, skipping triangles with an out-of-range index.
    pub fn triangle_vertices(&self) -> impl Iterator<Item = [DVec3; 3]> + '_ {
        self.triangles.iter().filter_map(|t| {
            Some([
                *self.positions.get(t[0] as usize)?,
                *self.positions.get(t[1] as usize)?,
                *self.positions.get(t[2] as usize)?,
            ])
        })
    }

    /// Whether the closed segment `[a, b]` meets any triangle.
    pub fn segment_blocked(&self, a: DVec3, b: DVec3) -> bool {
        self.triangle_vertices()
            .any(|t| segment_hits_triangle(a, b, t))
    }

    fn candidates(&self, e: DVec3, v: DVec3, p: DVec3, out: &mut Vec<f64>) {
        for [v0, v1, v2] in self.triangle_vertices() {
            edge_candidate(e, v, p, v0, v1, out);
            edge_candidate(e, v, p, v1, v2, out);
            edge_candidate(e, v, p, v2, v0, out);
            // The triangle's own plane, where the crossing lies in the triangle.
            let (e1, e2) = (v1 - v0, v2 - v0);
            let n = e1.cross(e2);
            let nv = n.dot(v);
            if nv == 0.0 {
                continue;
            }
            let x = n.dot(v0 - e) / nv;
            if !x.is_finite() {
                continue;
            }
            let y = e + v * x - v0;
            let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
            let (y1, y2) = (y.dot(e1), y.dot(e2));
            let det = d11 * d22 - d12 * d12;
            if det > 0.0 {
                let s = (d22 * y1 - d12 * y2) / det;
                let t = (d11 * y2 - d12 * y1) / det;
                const SLACK: f64 = 1e-6;
                if s < -SLACK || t < -SLACK || s + t > 1.0 + SLACK {
                    continue;
                }
            }
            out.push(x);
        }
    }
}

/// Möller–Trumbore for the closed segment `[a, b]` against a triangle (either side).
fn segment_hits_triangle(a: DVec3, b: DVec3, [v0, v1, v2]: [DVec3; 3]) -> bool {
    let d = b - a;
    let (e1, e2) = (v1 - v0, v2 - v0);
    let pv = d.cross(e2);
    let det = e1.dot(pv);
    if det == 0.0 || !det.is_finite() {
        return false; // parallel (or degenerate): measure zero
    }
    let inv = 1.0 / det;
    let tv = a - v0;
    let u = tv.dot(pv) * inv;
    if !(0.0..=1.0).contains(&u) {
        return false;
    }
    let qv = tv.cross(e1);
    let w = d.dot(qv) * inv;
    if w < 0.0 || u + w > 1.0 {
        return false;
    }
    let s = e2.dot(qv) * inv;
    (0.0..=1.0).contains(&s)
}

/// Any occluder the reference knows.
#[derive(Debug, Clone, PartialEq)]
pub enum Occluder {
    /// A sphere.
    Sphere(Sphere),
    /// An oriented box.
    Cuboid(Cuboid),
    /// A triangle mesh.
    Mesh(TriangleMesh),
}

impl Occluder {
    /// Whether the closed segment `[a, b]` meets the occluder's surface (exact, f64).
    pub fn segment_blocked(&self, a: DVec3, b: DVec3) -> bool {
        match self {
            Occluder::Sphere(s) => s.segment_blocked(a, b),
            Occluder::Cuboid(c) => c.segment_blocked(a, b),
            Occluder::Mesh(m) => m.segment_blocked(a, b),
        }
    }

    /// Appends every ray distance `x` at which the visibility of `p` from `e + x·v` (`v` unit)
    /// can change because of this occluder (a superset: extra candidates are harmless).
    pub(crate) fn candidates(&self, e: DVec3, v: DVec3, p: DVec3, out: &mut Vec<f64>) {
        match self {
            Occluder::Sphere(s) => s.candidates(e, v, p, out),
            Occluder::Cuboid(c) => c.candidates(e, v, p, out),
            Occluder::Mesh(m) => m.candidates(e, v, p, out),
        }
    }
}

impl From<Sphere> for Occluder {
    fn from(s: Sphere) -> Self {
        Occluder::Sphere(s)
    }
}
impl From<Cuboid> for Occluder {
    fn from(c: Cuboid) -> Self {
        Occluder::Cuboid(c)
    }
}
impl From<TriangleMesh> for Occluder {
    fn from(m: TriangleMesh) -> Self {
        Occluder::Mesh(m)
    }
}
