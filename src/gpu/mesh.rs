//! Occluder meshes uploaded once, and their per-frame instances.

use glam::{Mat4, Vec3};
use wgpu::util::DeviceExt;

use crate::error::{Error, Result};
use crate::scene::{Mesh, MeshSummary};

/// GPU buffers of one occluder mesh: positions, triangle indices and the edge adjacency built
/// by [`Mesh::new`]. Upload once, instance any number of times with [`Occluder`].
///
/// Used in the [crate-level example](crate#example).
pub struct OccluderMesh {
    pub(crate) positions: wgpu::Buffer,
    pub(crate) indices: wgpu::Buffer,
    pub(crate) edges: wgpu::Buffer,
    pub(crate) triangle_count: u32,
    pub(crate) edge_count: u32,
    closed: bool,
    bounds: (Vec3, Vec3),
    /// Object-space bounding sphere: the box's centre and the farthest vertex's distance
    /// from it (a sphere's own radius, where the box's circumsphere is √3 times as large).
    sphere: (Vec3, f32),
    summary: MeshSummary,
    id: u64,
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
            bounds: mesh.bounds(),
            sphere: (centre, reach),
            summary: mesh.summary(),
            id: NEXT_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
        }
    }

    /// Whether the mesh is closed (every edge shared by exactly two consistently wound faces).
    /// Open or non-manifold meshes get conservative (larger) shadow-volume extents.
    pub fn is_closed(&self) -> bool {
        self.closed
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
        let (lo, hi) = self.mesh.bounds;
        let mut min = Vec3::splat(f32::INFINITY);
        let mut max = Vec3::splat(f32::NEG_INFINITY);
        for i in 0..8 {
            let corner = Vec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            );
            let p = self.transform.transform_point3(corner);
            min = min.min(p);
            max = max.max(p);
        }
        (min, max)
    }
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
