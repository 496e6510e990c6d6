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
    /// invertible, and not mirroring (a negative determinant flips the triangles' winding,
    /// which turns the shadow volumes inside out).
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
            Err(p @ (TransformProblem::NotAffine(_) | TransformProblem::Mirrored(_))) => {
                Err(Error::InvalidTransform {
                    field: FIELD,
                    problem: p.to_string(),
                })
            }
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
