//! Occluder meshes uploaded once, and their per-frame instances.

use glam::{Mat4, Vec3};
use wgpu::util::DeviceExt;

use crate::error::{Error, Result};
use crate::scene::{Mesh, MeshSummary};

/// GPU buffers of one occluder mesh: positions, triangle indices and the edge adjacency built
/// by [`Mesh::new`]. Upload once, instance any number of times with [`Occluder`].
///
/// The mesh keeps its device: a frame on another device of the same `wgpu::Instance` refuses
/// it ([`Error::InvalidBuffer`] naming `occluder.mesh`), as it refuses textures of another
/// device ([`Error::Validation`]). Devices of two separate instances number their resources
/// alike and wgpu's public API cannot tell them apart (a resource of one resolves to another
/// resource of the other, or wgpu panics), so no resource may be passed to another instance's
/// device.
///
/// Used in the [crate-level example](crate#example).
pub struct OccluderMesh {
    pub(crate) positions: wgpu::Buffer,
    pub(crate) indices: wgpu::Buffer,
    pub(crate) edges: wgpu::Buffer,
    pub(crate) triangle_count: u32,
    pub(crate) edge_count: u32,
    closed: bool,
    /// Closed and convex (see [`OccluderMesh::is_convex`]).
    convex: bool,
    bounds: (Vec3, Vec3),
    /// Object-space bounding sphere: the box's centre and the farthest vertex's distance
    /// from it (a sphere's own radius, where the box's circumsphere is √3 times as large).
    sphere: (Vec3, f32),
    summary: MeshSummary,
    id: u64,
    /// The device its buffers live on: an occluder is refused on any other.
    device: wgpu::Device,
}

/// GPU edge record: the edge v0→v1 in face0's winding, face1 = u32::MAX when none (boundary or
/// non-manifold: always extruded).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct GpuEdge {
    v0: u32,
    v1: u32,
    face0: u32,
    face1: u32,
}

impl OccluderMesh {
    /// Uploads `mesh` (validated and with adjacency already built by [`Mesh::new`]).
    ///
    /// Used in the [crate-level example](crate#example).
    pub fn new(device: &wgpu::Device, mesh: &Mesh) -> Self {
        static NEXT_ID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);
        let positions: Vec<[f32; 4]> = mesh
            .positions()
            .iter()
            .map(|p| p.extend(1.0).to_array())
            .collect();
        let edges: Vec<GpuEdge> = mesh
            .edges()
            .iter()
            .map(|e| GpuEdge {
                v0: e.v0,
                v1: e.v1,
                face0: e.face0,
                face1: e.face1.unwrap_or(u32::MAX),
            })
            .collect();
        let buffer = |label, contents: &[u8], usage| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage,
            })
        };
        // A zero-size storage binding is invalid; a mesh always has triangles, but may have no
        // edge record only if degenerate, which Mesh::new rejects. Pad anyway.
        let edge_bytes: &[u8] = if edges.is_empty() {
            &[0; 16]
        } else {
            bytemuck::cast_slice(&edges)
        };
        let (lo, hi) = mesh.bounds();
        let centre = 0.5 * (lo + hi);
        let reach = mesh
            .positions()
            .iter()
            .map(|p| p.distance(centre))
            .fold(0.0, f32::max);
        Self {
            positions: buffer(
                "volshadow occluder positions",
                bytemuck::cast_slice(&positions),
                wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::STORAGE,
            ),
            indices: buffer(
                "volshadow occluder indices",
                bytemuck::cast_slice(mesh.indices()),
                wgpu::BufferUsages::INDEX | wgpu::BufferUsages::STORAGE,
            ),
            edges: buffer(
                "volshadow occluder edges",
                edge_bytes,
                wgpu::BufferUsages::STORAGE,
            ),
            triangle_count: (mesh.indices().len() / 3) as u32,
            edge_count: edges.len() as u32,
            closed: mesh.is_closed(),
            convex: mesh.is_closed() && is_convex(mesh),
            bounds: mesh.bounds(),
            sphere: (centre, reach),
            summary: mesh.summary(),
            id: NEXT_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            device: device.clone(),
        }
    }

    /// Whether the mesh is closed (every edge shared by exactly two consistently wound faces).
    /// Open or non-manifold meshes get conservative (larger) shadow-volume extents.
    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// Whether the mesh is closed and convex: every vertex on or behind every triangle's
    /// plane (within 1e-4 of the box's diagonal), checked for meshes of up to 4096 triangles
    /// (larger ones count as not convex). A light shines through no gap of one convex
    /// occluder, so a frame whose only occluder is convex needs no search for narrow shafts
    /// (see [`SoftShadowNode`](crate::nodes::SoftShadowNode)).
    pub fn is_convex(&self) -> bool {
        self.convex
    }

    /// Triangles, boundary and non-manifold edges.
    pub fn summary(&self) -> MeshSummary {
        self.summary
    }

    /// Object-space bounding box (min, max).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.bounds
    }

    /// A process-unique id, so nodes can tell whether the occluder set changed.
    pub(crate) fn id(&self) -> u64 {
        self.id
    }
}

/// Most triangles [`OccluderMesh::is_convex`] checks (the check is triangles × vertices).
pub(crate) const CONVEX_CHECK_TRIANGLES: usize = 4096;

/// Every vertex of `mesh` on or behind the plane of every triangle (its winding's normal
/// pointing out), within 1e-4 of the box's diagonal; false beyond [`CONVEX_CHECK_TRIANGLES`].
fn is_convex(mesh: &Mesh) -> bool {
    let (p, idx) = (mesh.positions(), mesh.indices());
    if idx.len() / 3 > CONVEX_CHECK_TRIANGLES {
        return false;
    }
    let (lo, hi) = mesh.bounds();
    let tolerance = 1e-4 * (hi - lo).length();
    idx.chunks_exact(3).all(|t| {
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| p[i as usize]);
        let n = (b - a).cross(c - a);
        let len = n.length();
        if len.is_nan() || len <= 0.0 {
            return true; // a degenerate triangle has no plane
        }
        let n = n / len;
        p.iter().all(|v| n.dot(*v - a) <= tolerance)
    })
}

/// One occluder in a frame: a mesh and its object → world transform.
///
/// Used in the [crate-level example](crate#example).
#[derive(Clone, Copy)]
pub struct Occluder<'a> {
    /// The uploaded mesh.
    pub mesh: &'a OccluderMesh,
    /// Object → world transform (finite and invertible).
    pub transform: Mat4,
}

impl Occluder<'_> {
    /// Checks that the mesh was made on `device`: wgpu resources of another device resolve,
    /// on this one, to unrelated resources (or panic inside wgpu), so they are refused, with
    /// [`Error::InvalidBuffer`] naming `occluder.mesh`, before any is bound.
    pub(crate) fn check_device(&self, device: &wgpu::Device) -> Result<()> {
        if self.mesh.device == *device {
            return Ok(());
        }
        Err(Error::InvalidBuffer {
            field: "occluder.mesh",
            problem: "made on another wgpu::Device than the one passed to prepare \
                      (OccluderMesh::new with this device)"
                .into(),
        })
    }

    /// Checks the transform as scene files do: finite, affine (last row 0, 0, 0, 1),
    /// invertible, not mirroring (a negative determinant flips the triangles' winding,
    /// which turns the shadow volumes inside out), and with a determinant within f32's range
    /// ([`Error::InvalidTransform`] saying the scale overflows or underflows f32, not
    /// [`Error::SingularMatrix`]).
    pub(crate) fn validate(&self) -> Result<()> {
        use crate::scene::TransformProblem;
        const FIELD: &str = "occluder.transform";
        match crate::scene::check_object_transform(self.transform) {
            Ok(()) => Ok(()),
            Err(TransformProblem::NonFinite(value)) => Err(Error::NonFinite {
                field: FIELD,
                value,
            }),
            Err(TransformProblem::Singular(determinant)) => Err(Error::SingularMatrix {
                matrix: "occluder transform",
                determinant: determinant as f32,
            }),
            Err(
                p @ (TransformProblem::NotAffine(_)
                | TransformProblem::Mirrored(_)
                | TransformProblem::ScaleOutOfRange(_)),
            ) => Err(Error::InvalidTransform {
                field: FIELD,
                problem: p.to_string(),
            }),
        }
    }

    /// A world-space bounding sphere (centre, radius) of the transformed mesh: the object-space
    /// sphere transformed, its radius scaled by a bound on the transform's largest stretch
    /// (Gershgorin's on the eigenvalues of `MᵀM`, exact for a rotation times a scale), or
    /// the world box's circumsphere where that is smaller.
    pub(crate) fn world_sphere(&self) -> glam::Vec4 {
        let (lo, hi) = self.world_bounds();
        let boxed = (0.5 * (lo + hi)).extend(0.5 * (hi - lo).length());
        let (centre, reach) = self.mesh.sphere;
        let sphere = transformed_sphere(centre, reach, self.transform);
        if sphere.w < boxed.w {
            sphere
        } else {
            boxed
        }
    }

    /// World-space bounding box of the transformed mesh.
    pub(crate) fn world_bounds(&self) -> (Vec3, Vec3) {
        transformed_bounds(self.mesh.bounds, self.transform)
    }

    /// A lower bound on the distance from `p` to the transformed mesh
    /// ([`box_distance_lower_bound`] of its box).
    pub(crate) fn distance_lower_bound(&self, p: Vec3) -> f32 {
        box_distance_lower_bound(self.mesh.bounds, self.transform, p)
    }

    /// A plane with the transformed mesh on one side and the sphere (`centre`, `radius`)
    /// wholly beyond it ([`oriented_separating_plane`] of its box).
    pub(crate) fn separating_plane(&self, centre: Vec3, radius: f32) -> glam::Vec4 {
        oriented_separating_plane(self.mesh.bounds, self.transform, centre, radius)
    }
}

/// The world box of the object-space box `(lo, hi)` under `transform`.
fn transformed_bounds((lo, hi): (Vec3, Vec3), transform: Mat4) -> (Vec3, Vec3) {
    let mut min = Vec3::splat(f32::INFINITY);
    let mut max = Vec3::splat(f32::NEG_INFINITY);
    for corner in box_corners(lo, hi) {
        let p = transform.transform_point3(corner);
        min = min.min(p);
        max = max.max(p);
    }
    (min, max)
}

/// The eight corners of the box `[lo, hi]`.
fn box_corners(lo: Vec3, hi: Vec3) -> [Vec3; 8] {
    std::array::from_fn(|i| {
        Vec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        )
    })
}

/// A lower bound on the distance from `p` to the object-space box `bounds` under the affine
/// `transform`: the larger of the distance to its world box and the distance to the box
/// measured in object space times a lower bound on the transform's least stretch (the square
/// root of Gershgorin's lower bound on the eigenvalues of `MᵀM`, `M` its linear part; exact
/// for a rotation times a scale, 0 where Gershgorin cannot bound it). A turned occluder, a
/// wall turned about the light, is bounded by its own box: its world box may hold the light.
pub(crate) fn box_distance_lower_bound(bounds: (Vec3, Vec3), transform: Mat4, p: Vec3) -> f32 {
    let (lo, hi) = transformed_bounds(bounds, transform);
    let world = p.clamp(lo, hi).distance(p);
    let local = transform.inverse().transform_point3(p);
    let m = glam::Mat3::from_mat4(transform);
    let a = m.transpose() * m;
    let least = (0..3)
        .map(|i| {
            let col = a.col(i);
            2.0 * col[i] - col.abs().element_sum()
        })
        .fold(f32::INFINITY, f32::min)
        .max(0.0)
        .sqrt();
    // Rounding: the object-space point carries about an ULP of the world coordinates.
    let own = local.clamp(bounds.0, bounds.1).distance(local) * least * (1.0 - 1.0e-5)
        - 1.0e-6 * p.abs().max_element();
    let bound = world.max(own);
    if bound.is_finite() {
        bound.max(0.0)
    } else {
        world
    }
}

/// A plane `(n, d)` with the object-space box `bounds` under the affine `transform` in
/// `n·x ≤ d` and the sphere (`centre`, `radius`) wholly beyond it, the farthest beyond among
/// the faces' planes of the world box and of the box itself (transformed); zero when the
/// sphere reaches every one of them.
pub(crate) fn oriented_separating_plane(
    bounds: (Vec3, Vec3),
    transform: Mat4,
    centre: Vec3,
    radius: f32,
) -> glam::Vec4 {
    let (lo, hi) = transformed_bounds(bounds, transform);
    let mut best = box_separating_plane(lo, hi, centre, radius);
    let mut gap = if best == glam::Vec4::ZERO {
        0.0
    } else {
        best.truncate().dot(centre) - best.w - radius
    };
    let (olo, ohi) = bounds;
    let normal_matrix = glam::Mat3::from_mat4(transform).inverse().transpose();
    for axis in 0..3 {
        for (sign, face) in [(1.0, ohi[axis]), (-1.0, olo[axis])] {
            let n = (normal_matrix * (sign * Vec3::AXES[axis])).normalize_or_zero();
            if n == Vec3::ZERO {
                continue;
            }
            // A point of the face's plane, in the world.
            let mut q = 0.5 * (olo + ohi);
            q[axis] = face;
            let on_face = transform.transform_point3(q);
            let d = n.dot(on_face);
            // A margin for the rounding of coordinates as large as the scene's.
            let slack = 1.0e-5 * (on_face.abs().max_element() + centre.abs().max_element());
            let beyond = n.dot(centre) - d - radius - slack;
            if beyond.is_finite() && beyond > gap {
                gap = beyond;
                best = n.extend(d + slack);
            }
        }
    }
    best
}

/// The face plane of the box `[lo, hi]` farthest from the sphere (`centre`, `radius`) among
/// those with the sphere wholly beyond them, as `(n, d)` with the box in `n·x ≤ d` (see
/// [`ShadowMap::planes`](crate::nodes::ShadowMap::planes)); zero when the sphere reaches every face's plane.
pub(crate) fn box_separating_plane(lo: Vec3, hi: Vec3, centre: Vec3, radius: f32) -> glam::Vec4 {
    let mut best = glam::Vec4::ZERO;
    let mut gap = 0.0;
    for axis in 0..3 {
        let n = Vec3::AXES[axis];
        for (sign, face) in [(1.0, hi[axis]), (-1.0, lo[axis])] {
            let beyond = sign * (centre[axis] - face) - radius;
            if beyond > gap {
                gap = beyond;
                best = (sign * n).extend(sign * face);
            }
        }
    }
    best
}

/// A sphere (centre, radius) holding the image of the sphere (`centre`, `radius`) under the
/// affine `transform`: its radius scaled by a bound on the transform's largest stretch, the
/// square root of Gershgorin's bound on the largest eigenvalue of `MᵀM` (`M` its linear
/// part; exact for a rotation times a scale, larger with a shear), with a margin for the
/// rounding of points as large as the centre's coordinates.
fn transformed_sphere(centre: Vec3, radius: f32, transform: Mat4) -> glam::Vec4 {
    let m = glam::Mat3::from_mat4(transform);
    let a = m.transpose() * m;
    let stretch = (0..3)
        .map(|i| a.col(i).abs().element_sum())
        .fold(0.0, f32::max)
        .sqrt();
    let world = transform.transform_point3(centre);
    let reach = radius * stretch;
    world.extend(reach + 1.0e-5 * (reach + world.abs().max_element()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    /// Convex shapes are found convex and the others not, so that a frame whose one occluder
    /// is a sphere skips the soft shadow's search for shafts and one with a torus (a light
    /// shines through its hole) does not: a sphere and a box at scales 1e-2 to 1e4; a torus; a
    /// sphere with one vertex pushed a hundredth of its radius inwards (a dent); a fence (many
    /// posts, open). Checking every vertex against the triangles' planes the wrong way round
    /// (normals taken inwards) finds the sphere not convex and fails the first assertion.
    #[test]
    fn convex_meshes_are_told_from_the_others() {
        use crate::scene::shapes;
        for scale in [1e-2, 1.0, 1e4] {
            let centre = Vec3::new(3.0, -1.0, 2.0) * scale;
            let sphere = shapes::uv_sphere(centre, scale, 48, 24).unwrap();
            assert!(is_convex(&sphere), "sphere at scale {scale}");
            let cuboid = shapes::cuboid(centre, Vec3::new(1.0, 0.1, 2.0) * scale).unwrap();
            assert!(is_convex(&cuboid), "box at scale {scale}");
        }
        let torus = shapes::torus(Vec3::ZERO, 1.0, 0.3, 32, 16).unwrap();
        assert!(!is_convex(&torus), "torus");
        let sphere = shapes::uv_sphere(Vec3::ZERO, 1.0, 48, 24).unwrap();
        let mut positions = sphere.positions().to_vec();
        let dent = positions.len() / 2;
        positions[dent] *= 0.99;
        let dented = Mesh::new(&positions, sphere.indices()).unwrap();
        assert!(!is_convex(&dented), "dented sphere");
        let fence = shapes::fence(Vec3::ZERO, 5, 1.0, Vec3::new(0.1, 1.0, 0.1), true).unwrap();
        assert!(!is_convex(&fence), "fence");
    }

    /// A thin slab 16 × 16 turned about the origin with its plane 2 from it: its world box
    /// holds the origin (distance 0, no separating face), its own box gives the distance 2
    /// and its own face the plane. With the world box alone a soft light there would take its
    /// nearest occluder at distance 0 and search the whole map for blockers.
    #[test]
    fn a_turned_box_is_bounded_in_its_own_frame() {
        let bounds = (Vec3::new(-8.0, -8.0, -0.05), Vec3::new(8.0, 8.0, 0.05));
        let turn = glam::Quat::from_axis_angle(Vec3::new(1.0, 1.0, 0.3).normalize(), 0.7);
        let transform = Mat4::from_rotation_translation(turn, turn * Vec3::new(0.0, 0.0, 2.05));
        let (lo, hi) = transformed_bounds(bounds, transform);
        assert_eq!(
            Vec3::ZERO.clamp(lo, hi),
            Vec3::ZERO,
            "the world box holds the light"
        );
        let d = box_distance_lower_bound(bounds, transform, Vec3::ZERO);
        assert!((d - 2.0).abs() < 1e-4, "distance {d}, 2 expected");
        let plane = oriented_separating_plane(bounds, transform, Vec3::ZERO, 0.3);
        let n = plane.truncate();
        assert!((n - turn * Vec3::NEG_Z).length() < 1e-4, "plane {plane}");
        assert!((-plane.w - 2.0).abs() < 1e-3, "plane {plane}");
    }

    /// Over seeded affine transforms (rotation, scale from 1e-2 to 1e3 per axis, shear) and
    /// points: the distance bound never exceeds the distance to any point of the box's
    /// surface, and a separating plane, where one is found, holds every corner on its side
    /// and the sphere beyond it. A bound taken as the object-space distance times the
    /// largest stretch, not the least, fails the first.
    #[test]
    fn oriented_bounds_are_bounds() {
        let mut rng = fastrand::Rng::with_seed(7);
        let mut u = |lo: f32, hi: f32| lo + (hi - lo) * rng.f32();
        let mut found = 0;
        for _ in 0..300 {
            let lo = Vec3::new(u(-2.0, 0.0), u(-2.0, 0.0), u(-2.0, 0.0));
            let hi = lo + Vec3::new(u(0.01, 3.0), u(0.01, 3.0), u(0.01, 3.0));
            let scale = Vec3::new(
                10f32.powf(u(-2.0, 3.0)),
                10f32.powf(u(-2.0, 3.0)),
                10f32.powf(u(-2.0, 3.0)),
            );
            let turn =
                glam::Quat::from_euler(glam::EulerRot::XYZ, u(0.0, 6.3), u(0.0, 6.3), u(0.0, 6.3));
            let shear = Mat4::from_cols_array(&[
                1.0,
                u(-0.5, 0.5),
                0.0,
                0.0,
                0.0,
                1.0,
                u(-0.5, 0.5),
                0.0,
                0.0,
                0.0,
                1.0,
                0.0,
                0.0,
                0.0,
                0.0,
                1.0,
            ]);
            let size = scale.max_element();
            let transform = Mat4::from_scale_rotation_translation(
                scale,
                turn,
                Vec3::new(u(-3.0, 3.0), u(-3.0, 3.0), u(-3.0, 3.0)) * size,
            ) * shear;
            let p = Vec3::new(u(-4.0, 4.0), u(-4.0, 4.0), u(-4.0, 4.0)) * size;
            // The least distance to points of the box's surface, 24 a side a face.
            let mut surface = f32::INFINITY;
            for axis in 0..3 {
                for face in [lo[axis], hi[axis]] {
                    for i in 0..=24 {
                        for j in 0..=24 {
                            let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
                            let mut q = Vec3::ZERO;
                            q[axis] = face;
                            q[a] = lo[a] + (hi[a] - lo[a]) * i as f32 / 24.0;
                            q[b] = lo[b] + (hi[b] - lo[b]) * j as f32 / 24.0;
                            surface = surface.min(transform.transform_point3(q).distance(p));
                        }
                    }
                }
            }
            let bound = box_distance_lower_bound((lo, hi), transform, p);
            assert!(
                bound <= surface * (1.0 + 1e-5),
                "bound {bound} beyond the surface's {surface}"
            );
            let radius = u(0.0, 0.5) * size;
            let plane = oriented_separating_plane((lo, hi), transform, p, radius);
            if plane != glam::Vec4::ZERO {
                found += 1;
                let n = plane.truncate();
                assert!(n.dot(p) - plane.w >= radius, "the sphere reaches {plane}");
                for c in box_corners(lo, hi) {
                    let w = transform.transform_point3(c);
                    assert!(
                        n.dot(w) <= plane.w + 1e-5 * w.abs().max_element(),
                        "corner {w} beyond {plane}"
                    );
                }
            }
        }
        assert!(
            found > 100,
            "only {found} planes found: the check says little"
        );
    }

    /// The plane is the face the light's sphere lies farthest beyond; none when the sphere
    /// reaches every face's plane. A plane that cut the sphere would let a penumbra through.
    #[test]
    fn separating_plane_keeps_the_light_beyond_it() {
        let (lo, hi) = (Vec3::new(-30.0, 0.0, -30.0), Vec3::new(30.0, 0.0, 30.0));
        // A light 3 above a ground: the top face, n·x ≤ 0 with n = +Y.
        assert_eq!(
            box_separating_plane(lo, hi, Vec3::new(0.0, 3.0, 0.0), 0.3),
            glam::Vec4::new(0.0, 1.0, 0.0, 0.0)
        );
        // Below it: the bottom face, −y ≤ 0.
        assert_eq!(
            box_separating_plane(lo, hi, Vec3::new(1.0, -2.0, 0.0), 0.3),
            glam::Vec4::new(0.0, -1.0, 0.0, 0.0)
        );
        // The light's sphere reaching the plane: none.
        assert_eq!(
            box_separating_plane(lo, hi, Vec3::new(0.0, 0.2, 0.0), 0.3),
            glam::Vec4::ZERO
        );
        // Inside a box: none.
        let (a, b) = (Vec3::splat(-1.0), Vec3::splat(1.0));
        assert_eq!(
            box_separating_plane(a, b, Vec3::ZERO, 0.1),
            glam::Vec4::ZERO
        );
        // Beside a box, farther along x than along y: the +X face.
        assert_eq!(
            box_separating_plane(a, b, Vec3::new(5.0, 2.0, 0.0), 0.5),
            glam::Vec4::new(1.0, 0.0, 0.0, 1.0)
        );
    }

    /// Points on a sphere, transformed, stay within `transformed_sphere`'s, over seeded
    /// transforms (rotation, scale from 1e-2 to 1e2 per axis, shear, translation); for a
    /// rotation times a scale its radius is the largest scale's. The largest column length,
    /// a plausible stretch that shear breaks, lets points out: the test can tell.
    #[test]
    fn a_transformed_sphere_holds_the_transformed_points() {
        let mut rng = fastrand::Rng::with_seed(7);
        let mut escaped_by_columns = 0;
        for case in 0..500 {
            let rotation = Quat::from_euler(
                glam::EulerRot::XYZ,
                rng.f32() * 6.3,
                rng.f32() * 6.3,
                rng.f32() * 6.3,
            );
            let scale = Vec3::new(
                10f32.powf(4.0 * rng.f32() - 2.0),
                10f32.powf(4.0 * rng.f32() - 2.0),
                10f32.powf(4.0 * rng.f32() - 2.0),
            );
            let shear = if case % 2 == 0 {
                Mat4::IDENTITY
            } else {
                Mat4::from_mat3(glam::Mat3::from_cols(
                    Vec3::new(1.0, rng.f32() - 0.5, rng.f32() - 0.5),
                    Vec3::new(rng.f32() - 0.5, 1.0, rng.f32() - 0.5),
                    Vec3::Z,
                ))
            };
            let transform = Mat4::from_translation(Vec3::splat(100.0 * rng.f32() - 50.0))
                * Mat4::from_quat(rotation)
                * shear
                * Mat4::from_scale(scale);
            let (centre, radius) = (Vec3::new(rng.f32(), rng.f32(), rng.f32()), 0.5 + rng.f32());
            let sphere = transformed_sphere(centre, radius, transform);
            let columns = (0..3)
                .map(|i| glam::Mat3::from_mat4(transform).col(i).length())
                .fold(0.0, f32::max)
                * radius;
            if case % 2 == 0 {
                let largest = scale.max_element() * radius;
                let rounding = 2.0e-5 * sphere.truncate().abs().max_element();
                assert!(
                    (sphere.w - largest).abs() <= 1e-4 * largest + rounding,
                    "case {case}: radius {} for a largest scale of {largest}",
                    sphere.w
                );
            }
            let mut escaped = false;
            for k in 0..2000 {
                let d = Vec3::new(rng.f32() - 0.5, rng.f32() - 0.5, rng.f32() - 0.5);
                let d = if k < 6 {
                    Vec3::AXES[k % 3] * if k < 3 { 1.0 } else { -1.0 }
                } else {
                    d.normalize_or(Vec3::X)
                };
                let p = transform.transform_point3(centre + radius * d);
                let r = p.distance(sphere.truncate());
                assert!(
                    r <= sphere.w,
                    "case {case}: a point {r} from the centre, radius {}",
                    sphere.w
                );
                escaped |= r > columns * (1.0 + 1.0e-5);
            }
            escaped_by_columns += usize::from(escaped);
        }
        assert!(
            escaped_by_columns > 10,
            "the column bound let points out in only {escaped_by_columns} of 500 cases"
        );
    }
}
