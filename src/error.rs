//! The crate's error type: every invalid input names its field and problem.

use thiserror::Error;

/// Everything that can go wrong when building scene types, nodes or frames.
///
/// Each variant names the offending field so a caller can report it without guessing.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum Error {
    /// A value that must be finite was NaN or infinite.
    #[error("`{field}` must be finite, got {value}")]
    NonFinite {
        /// Which input.
        field: &'static str,
        /// The value received.
        value: f32,
    },
    /// A coefficient that must be zero or positive was negative.
    #[error("`{field}` must be >= 0, got {value}")]
    Negative {
        /// Which input.
        field: &'static str,
        /// The value received.
        value: f32,
    },
    /// A Henyey–Greenstein asymmetry parameter outside the open interval (-1, 1).
    #[error("Henyey-Greenstein asymmetry `g` must lie in (-1, 1), got {g}")]
    AsymmetryOutOfRange {
        /// The value received.
        g: f32,
    },
    /// A phase function mixture whose weights are all zero in some colour channel.
    #[error("phase function `{field}` has zero total weight in channel {channel}")]
    ZeroPhaseWeight {
        /// Which phase function.
        field: &'static str,
        /// The RGB channel (0, 1, 2) with no weight.
        channel: usize,
    },
    /// A light whose intensity is zero in every channel: it would contribute nothing.
    #[error("`{field}` is zero in every channel: the light contributes nothing")]
    ZeroIntensity {
        /// Which input.
        field: &'static str,
    },
    /// A direction vector of zero length.
    #[error("`{field}` has zero length")]
    DegenerateDirection {
        /// Which input.
        field: &'static str,
    },
    /// A spot light's apex angle outside (0, `max`], `max` being
    /// [`SpotLight::MAX_CONE_ANGLE`](crate::SpotLight::MAX_CONE_ANGLE) (179°: the widest field
    /// its shadow map covers).
    #[error(
        "spot light cone angle must lie in (0, {max}] radians (SpotLight::MAX_CONE_ANGLE: the \
         widest field its shadow map covers), got {angle}"
    )]
    ConeAngleOutOfRange {
        /// The angle received, radians.
        angle: f32,
        /// The widest angle accepted, radians.
        max: f32,
    },
    /// A matrix that must be invertible is singular (or too close to it for f32).
    #[error(
        "the {matrix} matrix is singular or not invertible in f32 (determinant {determinant})"
    )]
    SingularMatrix {
        /// `"view"` or `"projection"`.
        matrix: &'static str,
        /// Its determinant.
        determinant: f32,
    },
    /// The projection is not a perspective projection (orthographic cameras have no single eye).
    #[error(
        "the projection matrix is not a perspective projection (last row must be (0, 0, ±1, 0))"
    )]
    NotPerspective,
    /// A target or table size with a zero or too large dimension.
    #[error("`{field}` must be between {min} and {max} in each dimension, got {width}x{height}")]
    InvalidSize {
        /// Which size.
        field: &'static str,
        /// Width received.
        width: u32,
        /// Height received.
        height: u32,
        /// Smallest allowed dimension.
        min: u32,
        /// Largest allowed dimension.
        max: u32,
    },
    /// A texture the caller passed has a format, usage, sample count or size the node cannot use.
    #[error("`{field}`: {problem}")]
    InvalidTexture {
        /// Which input texture.
        field: &'static str,
        /// What is wrong with it.
        problem: String,
    },
    /// A buffer the caller passed has a size or usage the node cannot use.
    #[error("`{field}`: {problem}")]
    InvalidBuffer {
        /// Which input buffer.
        field: &'static str,
        /// What is wrong with it.
        problem: String,
    },
    /// A mesh with no positions or no indices.
    #[error("mesh is empty: {positions} positions, {indices} indices")]
    EmptyMesh {
        /// Number of positions received.
        positions: usize,
        /// Number of indices received.
        indices: usize,
    },
    /// A triangle-list index buffer whose length is not a multiple of 3.
    #[error("mesh index count must be a multiple of 3, got {count}")]
    IndexCountNotMultipleOf3 {
        /// Number of indices received.
        count: usize,
    },
    /// A mesh index that does not name a position.
    #[error(
        "mesh index at position {position} is {index}, but the mesh has {vertex_count} vertices"
    )]
    IndexOutOfRange {
        /// Where in the index slice the bad index is.
        position: usize,
        /// The index value.
        index: u32,
        /// Number of positions in the mesh.
        vertex_count: usize,
    },
    /// A mesh vertex position with a NaN or infinite component.
    #[error("mesh vertex {vertex} has a non-finite position {position}")]
    NonFinitePosition {
        /// Which vertex (index into the positions).
        vertex: usize,
        /// Its position.
        position: glam::Vec3,
    },
    /// A mesh whose triangles all have zero area: it cannot occlude anything.
    #[error("all {triangles} triangles of the mesh have zero area")]
    DegenerateMesh {
        /// Number of triangles in the mesh.
        triangles: usize,
    },
    /// A mesh with more triangles or positions than the crate supports.
    #[error("mesh has too many {field}: {count} (at most {max})")]
    MeshTooLarge {
        /// `"triangles"` or `"positions"`.
        field: &'static str,
        /// Number received.
        count: usize,
        /// Largest supported number.
        max: usize,
    },
    /// A node setting outside its documented range.
    #[error("`{field}`: {problem}")]
    InvalidSetting {
        /// Which setting.
        field: &'static str,
        /// What is wrong with it.
        problem: String,
    },
    /// A glTF file that could not be loaded (feature `gltf`).
    #[cfg(feature = "gltf")]
    #[error(transparent)]
    Gltf(#[from] GltfError),
    /// A scene file (see [`crate::scene_file`]) that could not be read, parsed or validated.
    #[error(transparent)]
    SceneFile(#[from] SceneFileError),
    /// [`encode`](crate::VolumetricShadows::encode) without a successful
    /// [`prepare`](crate::VolumetricShadows::prepare) of the current frame: before any
    /// `prepare`, after a `prepare` that failed, or after `invalidate` or `set_settings`.
    #[error("nothing to encode: {reason}; call `prepare` for this frame first")]
    NotPrepared {
        /// Why there is no prepared frame.
        reason: &'static str,
    },
    /// A frame needs a GPU buffer larger than the device's limits allow. Every buffer the crate
    /// sizes from its inputs (shadow volumes, occluder transforms, crossing lists, a soft
    /// light's grid list, a readback) is checked before it is created, and reported so.
    #[error(
        "`{field}` needs {needed} bytes, beyond the device limit `{limit}` = {max}; request a \
         higher limit when creating the device (up to the adapter's), or use fewer or coarser \
         occluders"
    )]
    DeviceLimitExceeded {
        /// What needs the memory.
        field: &'static str,
        /// The name of the `wgpu::Limits` field that is exceeded.
        limit: &'static str,
        /// Bytes needed.
        needed: u64,
        /// The device's limit, bytes.
        max: u64,
    },
    /// A path named inside a scene file or glTF file (a glTF `path`, a light-texture `file`, a
    /// buffer `uri`) leads outside the folder of the file that names it (see
    /// [`crate::load`]). The message is the same whether the target exists or not.
    #[error(
        "{file}: `{field}`: the path {target:?} leads outside the folder of the file that names it \
         (LoadOptions::allow_outside permits it)"
    )]
    PathOutsideFolder {
        /// The file that names the path.
        file: String,
        /// Where in that file, such as `objects[0].shape.path` or `buffers[0].uri`.
        field: String,
        /// The path as written (percent-escapes decoded).
        target: String,
    },
    /// A path that is not a regular file: a directory, device, FIFO or socket. Only regular
    /// files are read.
    #[error("{path}: not a regular file (a directory, device, FIFO or socket); only regular files are read")]
    NotRegularFile {
        /// The path.
        path: String,
    },
    /// A file that could not be opened or read.
    #[error("cannot read {path}: {problem}")]
    FileRead {
        /// The path.
        path: String,
        /// What went wrong.
        problem: String,
    },
    /// A file that could not be written.
    #[error("cannot write {path}: {problem}")]
    FileWrite {
        /// The path.
        path: String,
        /// What went wrong.
        problem: String,
    },
    /// A load went over one of the bounds of [`crate::load::LoadOptions`].
    #[error("{file}: {count} is more than {limit} = {max} (raise it in LoadOptions to load this)")]
    LimitExceeded {
        /// The file being read when the bound was passed.
        file: String,
        /// Which bound.
        limit: Limit,
        /// The total it would have reached (at least).
        count: u64,
        /// The bound.
        max: u64,
    },
    /// A light-texture texel component above the largest `f16` (65504): it would upload as
    /// infinity.
    #[error("light texture texel {texel} has a component {value}, above the f16 maximum 65504")]
    TexelOutOfRange {
        /// Index of the texel (row-major from the top row).
        texel: usize,
        /// The component value.
        value: f32,
    },
    /// An object transform that is not affine (last row other than 0, 0, 0, 1) or mirrors
    /// (negative determinant, which flips the triangles' winding).
    #[error("`{field}`: {problem}")]
    InvalidTransform {
        /// Which transform.
        field: &'static str,
        /// What is wrong with it.
        problem: String,
    },
    /// No GPU adapter could be found (headless helper).
    #[error("no wgpu adapter found: {0}")]
    NoAdapter(String),
    /// Device creation failed (headless helper).
    #[error("could not create a wgpu device: {0}")]
    RequestDevice(String),
    /// Reading a buffer or texture back from the GPU failed (headless helper).
    #[error("GPU readback failed: {0}")]
    Readback(String),
    /// wgpu reported a validation error while `during` (`prepare`, `encode`) made or recorded
    /// work from the caller's resources, which every other check let through: in practice a
    /// texture made on another `wgpu::Device` than the one passed (wgpu's public API cannot
    /// tell which device a texture belongs to, so it is found where wgpu binds it). `message`
    /// is wgpu's.
    #[error("wgpu validation error during {during}: {message}")]
    Validation {
        /// The call that caught it.
        during: &'static str,
        /// wgpu's description.
        message: String,
    },
}

/// A glTF file that could not be loaded (feature `gltf`), as [`Error::Gltf`].
#[cfg(feature = "gltf")]
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum GltfError {
    /// Unreadable, not glTF, truncated, a missing buffer file, an accessor or index out of
    /// range, no triangle meshes, an invalid node transform, ...
    #[error("glTF `{path}`: {problem}")]
    Invalid {
        /// The file as given to `gltf::load`, or `<memory>` for `gltf::load_slice`.
        path: String,
        /// What kind of problem, for callers that handle some differently.
        kind: GltfErrorKind,
        /// What is wrong, naming the glTF object (mesh, primitive, accessor, node, buffer).
        problem: String,
    },
    /// A mesh primitive that [`crate::scene::Mesh::new`] rejected: non-finite positions, all
    /// triangles degenerate, an index count that is not a multiple of 3, too many triangles
    /// or positions.
    #[error("glTF `{path}`: mesh {mesh} primitive {primitive}: {source}")]
    Primitive {
        /// The file as given to `gltf::load`, or `<memory>` for `gltf::load_slice`.
        path: String,
        /// Index of the mesh in the file's `meshes`.
        mesh: usize,
        /// Index of the primitive in the mesh's `primitives`.
        primitive: usize,
        /// The error from [`crate::scene::Mesh::new`].
        source: Box<Error>,
    },
}

#[cfg(feature = "gltf")]
/// What kind of problem a [`GltfError::Invalid`] reports (`volshadow::gltf::ErrorKind`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum GltfErrorKind {
    /// The file itself could not be read.
    Io,
    /// The bytes are not a glTF 2.0 asset: neither binary glTF (`glTF` magic) nor JSON that
    /// parses as a glTF document.
    NotGltf,
    /// The data ends early: a `.glb` shorter than its header or a chunk says, JSON cut off, or
    /// a buffer shorter than its `byteLength`.
    Truncated,
    /// A buffer's external file could not be read, or `load_slice` met a buffer in an
    /// external file (it has no directory to look in).
    MissingBuffer,
    /// An accessor or buffer view reaches past the end of its buffer view or buffer, or a
    /// sparse accessor names an element beyond its count.
    AccessorOutOfRange,
    /// A vertex index is not less than the primitive's number of positions.
    IndexOutOfRange,
    /// The walked scene contains no mesh primitive with triangles.
    NoTriangleMeshes,
    /// A node that places a mesh has a world transform that is not finite or not invertible,
    /// or a rotation that is not a finite non-zero quaternion.
    InvalidTransform,
    /// A feature this loader does not read: a required compression extension, a glTF version
    /// other than 2, a `.glb` version other than 2, or a buffer URI with a scheme other than
    /// `data:`.
    Unsupported,
    /// Any other violation of the glTF specification: a reference to an object that does not
    /// exist, an accessor of the wrong type, invalid base64, a node with two parents or in a
    /// cycle, a malformed `.glb` chunk layout.
    Malformed,
}

/// A scene file (see [`crate::scene_file`]) that could not be read, parsed or validated, as
/// [`Error::SceneFile`].
///
/// `field` is the path of the offending value inside the file, such as
/// `lights[1].cone_angle_degrees`; `(file)` for I/O errors and `(json)` for syntax errors,
/// whose `problem` gives the line and column.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("{path}: {field}: {problem}")]
#[non_exhaustive]
pub struct SceneFileError {
    /// The file as given to [`crate::scene_file::SceneDescription::load`], or `<string>`
    /// for [`crate::scene_file::SceneDescription::from_json`].
    pub path: String,
    /// Where in the file: a path of keys and indices, such as `objects[2].shape.radius`.
    pub field: String,
    /// What is wrong with it.
    pub problem: String,
}

/// Shorthand for `Result<T, volshadow::Error>`.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Checks that every component of `value` is finite.
pub(crate) fn finite(field: &'static str, value: &[f32]) -> Result<()> {
    match value.iter().find(|v| !v.is_finite()) {
        Some(&v) => Err(Error::NonFinite { field, value: v }),
        None => Ok(()),
    }
}

/// Checks that every component of `value` is finite and non-negative.
pub(crate) fn non_negative(field: &'static str, value: &[f32]) -> Result<()> {
    finite(field, value)?;
    match value.iter().find(|v| **v < 0.0) {
        Some(&v) => Err(Error::Negative { field, value: v }),
        None => Ok(()),
    }
}

/// Which bound of [`LoadOptions`](crate::LoadOptions) an [`Error::LimitExceeded`] is about; it
/// displays as the field's name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Limit {
    /// [`LoadOptions::max_file_bytes`](crate::LoadOptions::max_file_bytes).
    FileBytes,
    /// [`LoadOptions::max_total_bytes`](crate::LoadOptions::max_total_bytes).
    TotalBytes,
    /// [`LoadOptions::max_triangles`](crate::LoadOptions::max_triangles).
    Triangles,
    /// [`LoadOptions::max_lights`](crate::LoadOptions::max_lights).
    Lights,
    /// [`LoadOptions::max_texels`](crate::LoadOptions::max_texels).
    Texels,
    /// [`LoadOptions::max_nodes`](crate::LoadOptions::max_nodes).
    Nodes,
    /// [`LoadOptions::max_instances`](crate::LoadOptions::max_instances).
    Instances,
}

impl std::fmt::Display for Limit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Limit::FileBytes => "max_file_bytes",
            Limit::TotalBytes => "max_total_bytes",
            Limit::Triangles => "max_triangles",
            Limit::Lights => "max_lights",
            Limit::Texels => "max_texels",
            Limit::Nodes => "max_nodes",
            Limit::Instances => "max_instances",
        })
    }
}
