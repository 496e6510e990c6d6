//! CPU-side occluder meshes with the edge adjacency that silhouette extrusion needs.

use std::collections::HashMap;
use std::fmt;
use std::hash::{BuildHasherDefault, Hasher};

use glam::{DVec3, Vec3};

use crate::error::{Error, Result};

/// One edge of a [`Mesh`], with the faces on either side.
///
/// `v0` and `v1` are indices into [`Mesh::positions`], exactly as they appear in the indices of
/// face `face0`, in its counter-clockwise winding order: face `face0` contains the directed edge
/// `v0 → v1`. Faces are numbered by triangle (indices `3 * face .. 3 * face + 3`).
///
/// For a manifold interior edge, `face1` is the other face, which contains the same edge in the
/// opposite direction `v1 → v0` (compared by welded position: its own indices may name duplicate
/// vertices at the same positions). `face1` is `None` for a boundary edge (one face) and for each
/// face around a non-manifold edge, so that silhouette extrusion treats them conservatively, as
/// boundary edges, which are always extruded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Edge {
    /// First vertex, in `face0`'s winding order.
    pub v0: u32,
    /// Second vertex, in `face0`'s winding order.
    pub v1: u32,
    /// The face that contains `v0 → v1`.
    pub face0: u32,
    /// The face that contains `v1 → v0`, or `None` for boundary and non-manifold edges.
    pub face1: Option<u32>,
}

/// Counts describing a [`Mesh`]'s topology, from [`Mesh::summary`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct MeshSummary {
    /// Triangles in the index buffer, degenerate ones included.
    pub triangles: usize,
    /// Triangles of zero area (or with two corners at the same position), left out of the
    /// adjacency.
    pub degenerate_triangles: usize,
    /// Entries in [`Mesh::edges`]: one per manifold or boundary edge, and one per incident face
    /// for each non-manifold edge.
    pub edges: usize,
    /// Edges with exactly one incident face.
    pub boundary_edges: usize,
    /// Edges (counted once each, by welded position) with three or more incident faces, or with
    /// two faces that traverse them in the same direction.
    pub non_manifold_edges: usize,
}

impl fmt::Display for MeshSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} triangles ({} degenerate), {} edges ({} boundary, {} non-manifold)",
            self.triangles,
            self.degenerate_triangles,
            self.edges,
            self.boundary_edges,
            self.non_manifold_edges
        )
    }
}

/// A triangle mesh that casts shadows: positions, a triangle-list index buffer with
/// counter-clockwise (outward-facing, right-handed) winding, and the edge adjacency built from
/// them.
///
/// Adjacency is computed after welding vertices at exactly equal positions (`0.0` and `-0.0`
/// count as equal), so meshes that duplicate vertices at UV or normal seams are still closed.
/// The positions and indices are kept as given, for rendering.
#[derive(Clone)]
pub struct Mesh {
    positions: Vec<Vec3>,
    indices: Vec<u32>,
    edges: Vec<Edge>,
    summary: MeshSummary,
    bounds: (Vec3, Vec3),
}

impl fmt::Debug for Mesh {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Mesh")
            .field("vertices", &self.positions.len())
            .field("summary", &self.summary)
            .field("bounds", &self.bounds)
            .finish_non_exhaustive()
    }
}

/// Sentinel for "no half-edge" in the grouping lists.
const NONE: u32 = u32::MAX;

impl Mesh {
    /// The most triangles a mesh may have (2²⁶), so that half-edge numbers (3 per triangle)
    /// and every other `u32` count stay far from overflow.
    pub const MAX_TRIANGLES: usize = 1 << 26;
    /// The most positions a mesh may have (3 × [`Mesh::MAX_TRIANGLES`], enough for a triangle
    /// soup with no shared vertices).
    pub const MAX_POSITIONS: usize = 3 * Self::MAX_TRIANGLES;

    /// A mesh from `positions` and a triangle list `indices` (three per triangle,
    /// counter-clockwise seen from outside). Both are copied; the caller's data is not touched.
    ///
    /// Used in the [crate-level example](crate#example).
    ///
    /// # Errors
    ///
    /// Checked in this order: [`Error::EmptyMesh`] (no positions or no indices),
    /// [`Error::MeshTooLarge`] (more than [`Mesh::MAX_TRIANGLES`] triangles or
    /// [`Mesh::MAX_POSITIONS`] positions), [`Error::IndexCountNotMultipleOf3`],
    /// [`Error::NonFinitePosition`] (the first such vertex, referenced or not),
    /// [`Error::IndexOutOfRange`] (the first such index), and [`Error::DegenerateMesh`] when
    /// every triangle has zero area.
    ///
    /// A triangle is degenerate when two of its corners are at the same position or its three
    /// corners are exactly collinear (cross product of its edges exactly zero, computed in f64).
    /// Degenerate triangles among good ones are kept in [`Mesh::indices`] but left out of the
    /// adjacency, and counted in [`MeshSummary::degenerate_triangles`].
    pub fn new(positions: &[Vec3], indices: &[u32]) -> Result<Self> {
        if positions.is_empty() || indices.is_empty() {
            return Err(Error::EmptyMesh {
                positions: positions.len(),
                indices: indices.len(),
            });
        }
        if indices.len() / 3 > Self::MAX_TRIANGLES {
            return Err(Error::MeshTooLarge {
                field: "triangles",
                count: indices.len() / 3,
                max: Self::MAX_TRIANGLES,
            });
        }
        if positions.len() > Self::MAX_POSITIONS {
            return Err(Error::MeshTooLarge {
                field: "positions",
                count: positions.len(),
                max: Self::MAX_POSITIONS,
            });
        }
        if !indices.len().is_multiple_of(3) {
            return Err(Error::IndexCountNotMultipleOf3 {
                count: indices.len(),
            });
        }
        if let Some((vertex, &position)) =
            positions.iter().enumerate().find(|(_, p)| !p.is_finite())
        {
            return Err(Error::NonFinitePosition { vertex, position });
        }
        if let Some((position, &index)) = indices
            .iter()
            .enumerate()
            .find(|(_, &i)| i as usize >= positions.len())
        {
            return Err(Error::IndexOutOfRange {
                position,
                index,
                vertex_count: positions.len(),
            });
        }

        let weld = weld(positions);
        let (edges, summary) = adjacency(positions, indices, &weld)?;
        let bounds = positions.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        );
        Ok(Self {
            positions: positions.to_vec(),
            indices: indices.to_vec(),
            edges,
            summary,
            bounds,
        })
    }

    /// Vertex positions, as given.
    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }
    /// Triangle-list indices, as given (degenerate triangles included).
    pub fn indices(&self) -> &[u32] {
        &self.indices
    }
    /// The edge adjacency (see [`Edge`]), grouped by welded edge in order of first appearance
    /// in the index buffer.
    pub fn edges(&self) -> &[Edge] {
        &self.edges
    }
    /// Number of triangles in the index buffer, degenerate ones included.
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }
    /// Topology counts: triangles, degenerate triangles, edges, boundary and non-manifold edges.
    pub fn summary(&self) -> MeshSummary {
        self.summary
    }
    /// Whether the mesh is closed (watertight) and manifold after welding: no boundary edges and
    /// no non-manifold edges, so every edge has a `face1`.
    pub fn is_closed(&self) -> bool {
        self.summary.boundary_edges == 0 && self.summary.non_manifold_edges == 0
    }
    /// Axis-aligned bounds `(min, max)` of all positions (referenced by an index or not).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.bounds
    }
}

/// A fast, deterministic hasher for the integer keys used here (not DoS-resistant; keys are
/// positions and vertex pairs, never adversarial in a way that matters to a renderer).
#[derive(Default)]
struct KeyHasher(u64);

impl Hasher for KeyHasher {
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }
    fn write_u32(&mut self, x: u32) {
        self.write_u64(u64::from(x));
    }
    fn write_u64(&mut self, x: u64) {
        self.0 = (self.0.rotate_left(23) ^ x).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    }
    fn finish(&self) -> u64 {
        // Fold the well-mixed high bits into the low ones, which pick the bucket.
        self.0 ^ (self.0 >> 32)
    }
}

type KeyMap<K, V> = HashMap<K, V, BuildHasherDefault<KeyHasher>>;

/// For every vertex, the index of the first vertex at exactly the same position.
fn weld(positions: &[Vec3]) -> Vec<u32> {
    let bits = |x: f32| if x == 0.0 { 0 } else { x.to_bits() };
    let mut first: KeyMap<(u32, u32, u32), u32> =
        KeyMap::with_capacity_and_hasher(positions.len(), Default::default());
    positions
        .iter()
        .enumerate()
        .map(|(i, p)| {
            *first
                .entry((bits(p.x), bits(p.y), bits(p.z)))
                .or_insert(i as u32)
        })
        .collect()
}

/// One directed edge of a non-degenerate triangle.
#[derive(Clone, Copy)]
struct HalfEdge {
    face: u32,
    /// Original indices, in the face's winding order.
    v0: u32,
    v1: u32,
    /// Whether the welded `v0 < v1` (its direction relative to the sorted key).
    forward: bool,
}

/// Builds the edge list and summary from the welded mesh.
fn adjacency(
    positions: &[Vec3],
    indices: &[u32],
    weld: &[u32],
) -> Result<(Vec<Edge>, MeshSummary)> {
    let triangles = indices.len() / 3;
    let mut degenerate = 0;
    let mut half_edges: Vec<HalfEdge> = Vec::with_capacity(indices.len());
    // Grouping by welded undirected edge: `group_last[g]` is the latest half-edge of group `g`,
    // `prev[h]` the half-edge of the same group before `h` (NONE at the first).
    let mut groups: KeyMap<u64, u32> =
        KeyMap::with_capacity_and_hasher(indices.len() / 2 + 16, Default::default());
    let mut group_last: Vec<u32> = Vec::with_capacity(indices.len() / 2 + 16);
    let mut prev: Vec<u32> = Vec::with_capacity(indices.len());

    for (face, tri) in indices.chunks_exact(3).enumerate() {
        let w = [
            weld[tri[0] as usize],
            weld[tri[1] as usize],
            weld[tri[2] as usize],
        ];
        if w[0] == w[1] || w[1] == w[2] || w[0] == w[2] || zero_area(positions, tri) {
            degenerate += 1;
            continue;
        }
        for k in 0..3 {
            let (a, b) = (w[k], w[(k + 1) % 3]);
            let key = (u64::from(a.min(b)) << 32) | u64::from(a.max(b));
            let h = half_edges.len() as u32;
            half_edges.push(HalfEdge {
                face: face as u32,
                v0: tri[k],
                v1: tri[(k + 1) % 3],
                forward: a < b,
            });
            let next_group = group_last.len() as u32;
            let g = *groups.entry(key).or_insert(next_group);
            if g == next_group {
                group_last.push(h);
                prev.push(NONE);
            } else {
                prev.push(group_last[g as usize]);
                group_last[g as usize] = h;
            }
        }
    }
    if degenerate == triangles {
        return Err(Error::DegenerateMesh { triangles });
    }

    let mut edges = Vec::with_capacity(group_last.len() + 16);
    let mut boundary_edges = 0;
    let mut non_manifold_edges = 0;
    let mut group: Vec<HalfEdge> = Vec::new();
    for &last in &group_last {
        group.clear();
        let mut h = last;
        while h != NONE {
            group.push(half_edges[h as usize]);
            h = prev[h as usize];
        }
        group.reverse(); // first appearance (lowest face) first
        match group.as_slice() {
            [only] => {
                boundary_edges += 1;
                edges.push(Edge {
                    v0: only.v0,
                    v1: only.v1,
                    face0: only.face,
                    face1: None,
                });
            }
            [first, second] if first.forward != second.forward => edges.push(Edge {
                v0: first.v0,
                v1: first.v1,
                face0: first.face,
                face1: Some(second.face),
            }),
            all => {
                non_manifold_edges += 1;
                edges.extend(all.iter().map(|he| Edge {
                    v0: he.v0,
                    v1: he.v1,
                    face0: he.face,
                    face1: None,
                }));
            }
        }
    }
    let summary = MeshSummary {
        triangles,
        degenerate_triangles: degenerate,
        edges: edges.len(),
        boundary_edges,
        non_manifold_edges,
    };
    Ok((edges, summary))
}

/// Whether the triangle's corners are exactly collinear (in f64, so huge coordinates cannot
/// overflow to a non-zero infinity).
fn zero_area(positions: &[Vec3], tri: &[u32]) -> bool {
    let p = |k: usize| positions[tri[k] as usize].as_dvec3();
    (p(1) - p(0)).cross(p(2) - p(0)) == DVec3::ZERO
}

/// What is wrong with an object → world transform (see [`check_object_transform`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum TransformProblem {
    /// An entry is NaN or infinite (the first such entry).
    NonFinite(f32),
    /// The last row is not (0, 0, 0, 1).
    NotAffine(glam::Vec4),
    /// The determinant is negative: the transform mirrors, flipping the triangles' winding.
    Mirrored(f64),
    /// The determinant is zero or negligible next to the columns' lengths, or the inverse is
    /// not finite in f32.
    Singular(f64),
    /// The transform is invertible (in f64, and its determinant is not negligible next to its
    /// columns' lengths), but its scale is beyond f32: the determinant, the product of the
    /// three scales, is above `f32::MAX` (a uniform scale above about 7e12) or below
    /// `f32::MIN_POSITIVE` (one below about 2e-13), so the inverse cannot be computed in f32.
    ScaleOutOfRange(f64),
}

impl fmt::Display for TransformProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TransformProblem::NonFinite(_) => write!(f, "the transform is not finite"),
            TransformProblem::NotAffine(row) => write!(
                f,
                "must be affine (column-major; the last row must be 0, 0, 0, 1), got last row {row}"
            ),
            TransformProblem::Mirrored(det) | TransformProblem::Singular(det) => write!(
                f,
                "the transform must be invertible with a positive determinant (no mirroring), \
                 got determinant {det}"
            ),
            TransformProblem::ScaleOutOfRange(det) => {
                let (way, bound) = if *det > 1.0 {
                    (
                        "overflows",
                        format!("above f32's largest value {:e}", f32::MAX),
                    )
                } else {
                    (
                        "underflows",
                        format!("below f32's smallest normal value {:e}", f32::MIN_POSITIVE),
                    )
                };
                write!(
                    f,
                    "the transform's scale {way} f32: its determinant {det:e} (the product of \
                     its three scales, about {:e} each) is {bound}, so it cannot be inverted in \
                     f32; scale the scene's units instead",
                    det.cbrt()
                )
            }
        }
    }
}

/// Checks an object → world transform, as scene files and [`crate::Occluder`] need it: finite,
/// affine (last row 0, 0, 0, 1), a positive determinant above 1e-12 of the product of the
/// columns' lengths (so scale does not matter, only how close to flat it is), and an inverse
/// that is finite in f32 and f64. A transform that passes all but the last because its
/// determinant lies outside f32's normal range is [`TransformProblem::ScaleOutOfRange`], not
/// singular.
pub(crate) fn check_object_transform(m: glam::Mat4) -> std::result::Result<(), TransformProblem> {
    if let Some(&v) = m.to_cols_array().iter().find(|v| !v.is_finite()) {
        return Err(TransformProblem::NonFinite(v));
    }
    if m.row(3) != glam::Vec4::W {
        return Err(TransformProblem::NotAffine(m.row(3)));
    }
    let d = m.as_dmat4();
    let det = d.determinant();
    let scale =
        d.x_axis.truncate().length() * d.y_axis.truncate().length() * d.z_axis.truncate().length();
    if det.is_finite() && det < -1e-12 * scale {
        return Err(TransformProblem::Mirrored(det));
    }
    let invertible = det.is_finite() && det > 1e-12 * scale && d.inverse().is_finite();
    if !invertible {
        return Err(TransformProblem::Singular(det));
    }
    if !(f64::from(f32::MIN_POSITIVE)..=f64::from(f32::MAX)).contains(&det) {
        return Err(TransformProblem::ScaleOutOfRange(det));
    }
    if !m.inverse().is_finite() {
        return Err(TransformProblem::Singular(det));
    }
    Ok(())
}
