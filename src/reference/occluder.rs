//! Occluders with exact segment tests, and the exact points along a ray where their shadow can
//! begin or end.
//!
//! Occluders are opaque *surfaces*: a segment is blocked iff it meets the surface. For a closed
//! occluder (sphere, box, closed mesh) this is the same as "meets the solid" unless both ends lie
//! inside it: a light inside a sphere lights the inside of the sphere and nothing outside, as a
//! shadow map rendered from inside would.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use glam::{DMat4, DQuat, DVec3, Vec3};

use super::bvh::{Bvh, Triangle};

/// The fraction of a segment to a point light, at the light's end, that visibility ignores: a
/// surface through the light itself (the light on a vertex, or in a face's plane) touches
/// every segment there (see [`Occluder::hides`]). 1e-9 is far above f64's rounding of the
/// segment (1e-16 relative) and far below anything a render resolves.
pub(crate) const LIGHT_CONTACT: f64 = 1e-9;

/// Where a light is, for visibility: at a point, or infinitely far in the unit direction
/// `Towards(l)` (a directional light, `l` opposite to its direction of travel).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Source {
    At(DVec3),
    Towards(DVec3),
}

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

    /// Whether the half-line `a + s·direction`, `s ≥ 0` (`direction` non-zero, any length),
    /// meets the sphere's surface: always from inside.
    pub fn ray_blocked(&self, a: DVec3, direction: DVec3) -> bool {
        let f = a - self.center;
        let dd = direction.length_squared();
        let s = if dd > 0.0 {
            (-f.dot(direction) / dd).max(0.0)
        } else {
            0.0
        };
        (f + direction * s).length_squared() <= self.radius * self.radius
    }

    /// Ray distances where the visibility of the light from `e + x·v` (`v` unit) can change:
    /// the ray's crossings of the sphere and of the tangent cone from a point light `p`, or of
    /// the shadow cylinder (the sphere's radius, along `l`) for a light towards `l`.
    fn candidates(&self, e: DVec3, v: DVec3, source: Source, out: &mut Vec<f64>) {
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
        let p = match source {
            Source::At(p) => p,
            Source::Towards(l) => {
                // |(f + x v)⊥|² = r², ⊥ removing the component along l.
                let (fp, vp) = (f - l * f.dot(l), v - l * v.dot(l));
                out.extend(quadratic_roots(vp.dot(vp), fp.dot(vp), fp.dot(fp) - r * r));
                return;
            }
        };
        // The tangent cone (apex p, axis towards the centre, sin α = r / L) exists when p is
        // outside the sphere.
        let axis = self.center - p;
        let l = axis.length();
        if !(l > r) {
            // A light on the sphere (or just inside it, where the light's own contact is
            // ignored, see `Occluder::hides`): it lights the side of its tangent plane, so
            // visibility changes where the ray crosses that plane. (An extra candidate for a
            // light deeper inside is harmless.)
            let vw = v.dot(axis);
            if l > 0.0 && vw != 0.0 {
                out.push((p - e).dot(axis) / vw);
            }
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

    /// Distance from `p` to the box's surface (from inside or outside).
    pub(crate) fn surface_distance(&self, p: DVec3) -> f64 {
        let local = self.local_point(p).abs();
        let h = self.half_extents.abs();
        let outside = (local - h).max(DVec3::ZERO);
        if outside != DVec3::ZERO {
            outside.length()
        } else {
            (h - local).min_element()
        }
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
        self.clip(la, lb - la, 1.0)
    }

    /// Whether the half-line `a + s·direction`, `s ≥ 0` (`direction` non-zero, any length),
    /// meets the box's surface: always from inside.
    pub fn ray_blocked(&self, a: DVec3, direction: DVec3) -> bool {
        let d = self.rotation().inverse() * direction;
        self.clip(self.local_point(a), d, f64::INFINITY)
    }

    /// Slab clipping of `la + s·d`, `s ∈ [0, s_max]` (box frame), against the solid box.
    fn clip(&self, la: DVec3, d: DVec3, s_max: f64) -> bool {
        let h = self.half_extents.abs();
        let (mut s0, mut s1) = (0.0f64, s_max);
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

    fn candidates(&self, e: DVec3, v: DVec3, source: Source, out: &mut Vec<f64>) {
        // Work in the box's frame: a rotation keeps distances along the ray.
        let h = self.half_extents.abs();
        let inv = self.rotation().inverse();
        let (o, d) = (self.local_point(e), inv * v);
        let local = match source {
            Source::At(p) => Source::At(self.local_point(p)),
            Source::Towards(l) => Source::Towards(inv * l),
        };
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
        // Planes through each of the 12 edges and the light (or its direction).
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
                    Wedge::new(local, corner(i), corner(j)).candidate(o, d, out);
                }
            }
        }
    }
}

/// The plane through the light `p` and an edge `[vi, vj]` (for a light towards `l`: through
/// the edge and along `l`), with what [`candidate`](Self::candidate) needs of it computed once
/// (for a mesh, once per light and silhouette edge).
#[derive(Debug, Clone, Copy)]
struct Wedge {
    /// The plane's origin: `p`, or `vi` for a light towards `l`.
    o: DVec3,
    /// `vi − p`, or `vj − vi`.
    a: DVec3,
    /// `vj − p`, or `−l·|vj − vi|` (the direction of travel, at the edge's scale).
    b: DVec3,
    /// `a × b`, the plane's normal.
    n: DVec3,
    aa: f64,
    ab: f64,
    bb: f64,
    /// `aa·bb − ab²`.
    det: f64,
    /// Whether the light is towards a direction.
    directional: bool,
}

impl Wedge {
    fn new(source: Source, vi: DVec3, vj: DVec3) -> Self {
        let (o, a, b, directional) = match source {
            Source::At(p) => (p, vi - p, vj - p, false),
            Source::Towards(l) => (vi, vj - vi, -l * (vj - vi).length(), true),
        };
        let (aa, ab, bb) = (a.dot(a), a.dot(b), b.dot(b));
        Self {
            o,
            a,
            b,
            n: a.cross(b),
            aa,
            ab,
            bb,
            det: aa * bb - ab * ab,
            directional,
        }
    }

    /// The ray's crossing of the plane, kept if the segment (half-line) from the crossing point
    /// to the light can touch the edge there.
    fn candidate(&self, e: DVec3, v: DVec3, out: &mut Vec<f64>) {
        let Self {
            o,
            a,
            b,
            n,
            aa,
            ab,
            bb,
            det,
            directional,
        } = *self;
        let nv = n.dot(v);
        if nv == 0.0 {
            return;
        }
        let x = n.dot(o - e) / nv;
        if !x.is_finite() {
            return;
        }
        // y = X − o = α a + β b; the segment p → X meets the edge iff α, β ≥ 0 and α + β ≥ 1;
        // the half-line from X towards l iff 0 ≤ α ≤ 1 and β ≥ 0.
        let y = e + v * x - o;
        if det > 1e-20 * aa * bb {
            let (ay, by) = (a.dot(y), b.dot(y));
            let alpha = (bb * ay - ab * by) / det;
            let beta = (aa * by - ab * ay) / det;
            const SLACK: f64 = 1e-6;
            let far = if directional {
                alpha > 1.0 + SLACK
            } else {
                alpha + beta < 1.0 - SLACK
            };
            if alpha < -SLACK || beta < -SLACK || far {
                return;
            }
        }
        out.push(x);
    }
}

/// An edge of a [`TriangleMesh`] after welding: its end points (in the order of one of its
/// triangles) and, for an edge of exactly two triangles, their third vertices.
#[derive(Debug, Clone, Copy)]
struct Edge {
    vi: DVec3,
    vj: DVec3,
    /// The third vertices of the edge's two triangles; `None` for an edge whose wedge is always
    /// a candidate: a boundary edge, a non-manifold one (three or more triangles) or an edge
    /// of a degenerate triangle.
    sides: Option<[DVec3; 2]>,
}

/// The wedges of a mesh's silhouette edges as seen from one light.
#[derive(Debug)]
struct Silhouette {
    /// The light (an exact match decides a cache hit).
    light: Source,
    wedges: Vec<Wedge>,
}

/// The last [`Silhouette`] computed (a whole image uses one light); shared by the
/// threads of [`inscatter_image`](super::inscatter_image). A clone starts empty.
#[derive(Debug, Default)]
struct SilhouetteCache(Mutex<Option<Arc<Silhouette>>>);

impl Clone for SilhouetteCache {
    fn clone(&self) -> Self {
        Self::default()
    }
}

/// The vertices of triangle `t`, `None` if an index is out of range.
fn vertices(positions: &[DVec3], t: &[u32; 3]) -> Option<[DVec3; 3]> {
    Some([
        *positions.get(t[0] as usize)?,
        *positions.get(t[1] as usize)?,
        *positions.get(t[2] as usize)?,
    ])
}

/// A triangle mesh (an open or closed surface).
///
/// # Acceleration
///
/// The constructors build, once, a bounding volume hierarchy over the triangles and the
/// mesh's edge adjacency (vertices welded where their positions are exactly equal, so that
/// seams with duplicated vertices are no boundaries). With them:
///
/// * [`segment_blocked`](Self::segment_blocked) tests only the triangles whose (padded) boxes
///   the segment meets: `O(log T)`, with the same Möller–Trumbore test on the same values, so
///   the same answer as testing every triangle.
/// * The candidates of a ray are its crossings of the triangles it can reach (the same ray–box
///   culling), where the eye-side point crosses the surface, and the crossings of the wedges
///   (planes through the light and an edge) of the *silhouette* edges only: an edge whose two
///   triangles lie on opposite sides of its wedge cannot change visibility, since the segment
///   to the light just passes from one triangle to the other as it sweeps across the edge.
///   Boundary edges, non-manifold edges and edges of degenerate (zero-area) triangles always
///   count; the side test has a relative margin (`1e-9`) far above its rounding, and a doubtful
///   edge counts. The silhouette is computed per light position (`O(E)`) and cached for the
///   last position.
///
/// The lit intervals are thus those of the brute-force test of every edge and triangle (an
/// interval end is the same floating-point crossing), at a cost per ray of about the
/// silhouette's length plus `O(log T)` per piece, instead of `O(T)` per piece.
#[derive(Clone, Default)]
pub struct TriangleMesh {
    /// Vertex positions, world space.
    positions: Vec<DVec3>,
    /// Triangles as indices into `positions`; triangles with an out-of-range index are ignored.
    triangles: Vec<[u32; 3]>,
    bvh: Bvh,
    edges: Vec<Edge>,
    silhouette: SilhouetteCache,
}

impl std::fmt::Debug for TriangleMesh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TriangleMesh")
            .field("positions", &self.positions)
            .field("triangles", &self.triangles)
            .finish_non_exhaustive()
    }
}

/// Equal geometry: the same positions and triangles (the acceleration follows from them).
impl PartialEq for TriangleMesh {
    fn eq(&self, other: &Self) -> bool {
        self.positions == other.positions && self.triangles == other.triangles
    }
}

impl TriangleMesh {
    /// A mesh from world-space positions and index triples (triangles with an out-of-range
    /// index are ignored).
    pub fn new(positions: Vec<DVec3>, triangles: Vec<[u32; 3]>) -> Self {
        let bvh = Bvh::new(triangles.iter().filter_map(|t| vertices(&positions, t)));
        let edges = mesh_edges(&positions, &triangles);
        Self {
            positions,
            triangles,
            bvh,
            edges,
            silhouette: SilhouetteCache::default(),
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

    /// Vertex positions, world space.
    pub fn positions(&self) -> &[DVec3] {
        &self.positions
    }

    /// Triangles as indices into [`positions`](Self::positions) (triangles with an
    /// out-of-range index are ignored).
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// The triangles' vertices, skipping triangles with an out-of-range index.
    pub fn triangle_vertices(&self) -> impl Iterator<Item = [DVec3; 3]> + '_ {
        self.triangles
            .iter()
            .filter_map(|t| vertices(&self.positions, t))
    }

    /// Whether the closed segment `[a, b]` meets any triangle.
    pub fn segment_blocked(&self, a: DVec3, b: DVec3) -> bool {
        self.bvh
            .any_on_segment(a, b, |t| segment_hits_triangle(a, b, t))
    }

    /// Distance from `o` along the unit direction `d` to the nearest triangle (both sides,
    /// edges included, distance > 0), or `f64::INFINITY` when the ray meets none.
    pub fn ray_distance(&self, o: DVec3, d: DVec3) -> f64 {
        let mut best = f64::INFINITY;
        self.bvh.each_on_ray(o, d, |t| {
            if let Some(s) = ray_hits_triangle(o, d, t).filter(|&s| s > 0.0) {
                best = best.min(s);
            }
        });
        best
    }

    /// Whether the half-line `a + s·direction`, `s ≥ 0` (`direction` non-zero, any length),
    /// meets any triangle.
    pub fn ray_blocked(&self, a: DVec3, direction: DVec3) -> bool {
        self.bvh.any_on_ray(a, direction, |t| {
            ray_hits_triangle(a, direction, t).is_some_and(|s| s >= 0.0)
        })
    }

    /// The wedges of the silhouette edges seen from `light` (cached for the last one).
    fn silhouette(&self, light: Source) -> Arc<Silhouette> {
        let mut cache = self
            .silhouette
            .0
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        if let Some(s) = cache.as_ref().filter(|s| s.light == light) {
            return s.clone();
        }
        let wedges = self
            .edges
            .iter()
            .filter_map(|edge| {
                let w = Wedge::new(light, edge.vi, edge.vj);
                // A zero or non-finite normal never gives a crossing (`Wedge::candidate`).
                if w.n == DVec3::ZERO || !w.n.is_finite() {
                    return None;
                }
                if let Some([c1, c2]) = edge.sides {
                    // orient3d(o, vi, vj, c) by a float determinant: its error is a small
                    // multiple of ε·|a|·|b|·|c − o| (each difference is exact to ε), far below
                    // this margin.
                    let margin = 1e-9 * (w.aa * w.bb).sqrt();
                    let (q1, q2) = (c1 - w.o, c2 - w.o);
                    let (s1, s2) = (w.n.dot(q1), w.n.dot(q2));
                    let (m1, m2) = (margin * q1.length(), margin * q2.length());
                    if (s1 > m1 && s2 < -m2) || (s1 < -m1 && s2 > m2) {
                        return None; // opposite sides: not on the silhouette
                    }
                }
                Some(w)
            })
            .collect();
        let s = Arc::new(Silhouette { light, wedges });
        *cache = Some(s.clone());
        s
    }

    fn candidates(&self, e: DVec3, v: DVec3, light: Source, out: &mut Vec<f64>) {
        for wedge in &self.silhouette(light).wedges {
            wedge.candidate(e, v, out);
        }
        // The triangles' own planes, where the crossing lies in the triangle.
        self.bvh.each_on_ray(e, v, |&Triangle { v0, e1, e2 }| {
            let n = e1.cross(e2);
            let nv = n.dot(v);
            if nv == 0.0 {
                return;
            }
            let x = n.dot(v0 - e) / nv;
            if !x.is_finite() {
                return;
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
                    return;
                }
            }
            out.push(x);
        });
    }
}

/// The welded edges of a mesh (see [`Edge`]).
///
/// Vertices are welded where their positions are exactly equal (`-0.0` as `0.0`). A triangle
/// with two vertices at one position is a segment or a point: it blocks a set of segments of
/// measure zero (the exact Möller–Trumbore test never; the floating-point one at most along
/// the line of its edge, which its neighbours' triangles block too) and takes no part. A
/// triangle with a non-finite vertex is never hit and takes no part either. Any other triangle
/// with a zero normal (three distinct collinear vertices) is degenerate: its edges always
/// count, and it is left out of its neighbours' adjacency, so that their edges there count as
/// boundary edges (conservative: such a sliver can join a T-junction).
fn mesh_edges(positions: &[DVec3], triangles: &[[u32; 3]]) -> Vec<Edge> {
    let mut ids = HashMap::with_capacity(positions.len());
    let welded: Vec<u32> = positions
        .iter()
        .map(|&p| {
            let key = (p + DVec3::ZERO).to_array().map(f64::to_bits);
            let next = ids.len() as u32;
            *ids.entry(key).or_insert(next)
        })
        .collect();
    // (welded ends, low first; the ends in the triangle's order; the third vertex).
    let mut halves: Vec<([u32; 2], [DVec3; 2], DVec3)> = Vec::with_capacity(3 * triangles.len());
    let mut edges = Vec::new();
    for t in triangles {
        let Some(p) = vertices(positions, t) else {
            continue;
        };
        let w = t.map(|i| welded[i as usize]);
        if w[0] == w[1] || w[1] == w[2] || w[2] == w[0] || !p.iter().all(|q| q.is_finite()) {
            continue;
        }
        let degenerate = (p[1] - p[0]).cross(p[2] - p[0]) == DVec3::ZERO;
        for k in 0..3 {
            let (i, j, o) = (k, (k + 1) % 3, (k + 2) % 3);
            if degenerate {
                edges.push(Edge {
                    vi: p[i],
                    vj: p[j],
                    sides: None,
                });
            } else {
                halves.push(([w[i].min(w[j]), w[i].max(w[j])], [p[i], p[j]], p[o]));
            }
        }
    }
    halves.sort_unstable_by_key(|h| h.0);
    for group in halves.chunk_by(|a, b| a.0 == b.0) {
        let [vi, vj] = group[0].1;
        edges.push(Edge {
            vi,
            vj,
            sides: match group {
                [a, b] => Some([a.2, b.2]),
                _ => None,
            },
        });
    }
    edges
}

/// Möller–Trumbore for the closed segment `[a, b]` against a triangle (either side).
fn segment_hits_triangle(a: DVec3, b: DVec3, t: &Triangle) -> bool {
    ray_hits_triangle(a, b - a, t).is_some_and(|s| (0.0..=1.0).contains(&s))
}

/// Möller–Trumbore, both sides, edges included: the parameter `s` of the hit `o + s·d`.
fn ray_hits_triangle(o: DVec3, d: DVec3, &Triangle { v0, e1, e2 }: &Triangle) -> Option<f64> {
    let pv = d.cross(e2);
    let det = e1.dot(pv);
    if det == 0.0 || !det.is_finite() {
        return None; // parallel (or degenerate): measure zero
    }
    let inv = 1.0 / det;
    let tv = o - v0;
    let u = tv.dot(pv) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let qv = tv.cross(e1);
    let w = d.dot(qv) * inv;
    if w < 0.0 || u + w > 1.0 {
        return None;
    }
    Some(e2.dot(qv) * inv)
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

    /// Whether the half-line `a + s·direction`, `s ≥ 0` (`direction` non-zero, any length),
    /// meets the occluder's surface (exact, f64); from inside a closed occluder it always does.
    pub fn ray_blocked(&self, a: DVec3, direction: DVec3) -> bool {
        match self {
            Occluder::Sphere(s) => s.ray_blocked(a, direction),
            Occluder::Cuboid(c) => c.ray_blocked(a, direction),
            Occluder::Mesh(m) => m.ray_blocked(a, direction),
        }
    }

    /// Whether the occluder hides `light` from `x`.
    ///
    /// A point light's own contact with the surface does not hide it: the segment is tested
    /// up to [`LIGHT_CONTACT`] of its length short of the light, so a light on a sphere's top
    /// vertex lights the medium above the sphere's horizon, and one in a ground's plane the
    /// medium on both sides (the whole segment was blocked at the light, and the image black).
    /// A light inside a closed occluder by more than that fraction of the distance is still
    /// inside it.
    pub(crate) fn hides(&self, x: DVec3, light: Source) -> bool {
        match light {
            Source::At(p) => self.segment_blocked(x, p + (x - p) * LIGHT_CONTACT),
            Source::Towards(l) => self.ray_blocked(x, l),
        }
    }

    /// Appends every ray distance `x` at which the visibility of `light` from `e + x·v` (`v`
    /// unit) can change because of this occluder (a superset: extra candidates are harmless).
    pub(crate) fn candidates(&self, e: DVec3, v: DVec3, light: Source, out: &mut Vec<f64>) {
        match self {
            Occluder::Sphere(s) => s.candidates(e, v, light, out),
            Occluder::Cuboid(c) => c.candidates(e, v, light, out),
            Occluder::Mesh(m) => m.candidates(e, v, light, out),
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
