//! Occluder meshes from glTF 2.0 files (feature `gltf`).
//!
//! [`load`] reads a `.gltf` (with external `.bin` buffers next to it, or `data:` URIs) or a
//! `.glb` file; [`load_slice`] reads a `.glb` or a self-contained `.gltf` already in memory.
//! Both return one [`GltfMesh`] per triangle primitive per node that instances it, in the
//! order of a depth-first walk of the scene: only positions and indices are read, since that
//! is all a shadow caster needs.
//!
//! Which nodes are walked: the roots of the default scene (`"scene"`); without one, the roots
//! of every scene (each node once); without scenes, every node that has no parent; and in a
//! file with no nodes at all, every mesh, with the identity transform.
//!
//! Primitives in `TRIANGLES` mode are used as they are, `TRIANGLE_STRIP` and `TRIANGLE_FAN`
//! are converted to triangle lists (keeping their winding), and points and lines are skipped
//! without an error, as are primitives with no `POSITION`. A primitive without indices uses
//! its vertices in order. `POSITION` may be `FLOAT` or, as `KHR_mesh_quantization` allows,
//! (normalized) 8- or 16-bit integers; sparse accessors are applied. Skins, morph targets and
//! `EXT_mesh_gpu_instancing` are ignored (meshes are in their bind pose and base shape), and
//! files that require `KHR_draco_mesh_compression` or `EXT_meshopt_compression` are rejected
//! as [`ErrorKind::Unsupported`].
//!
//! Nothing in the input can make the loader panic or abort: every problem is an
//! [`GltfError::Invalid`] naming the file, an [`ErrorKind`] and what is wrong, a
//! [`GltfError::Primitive`] wrapping the error [`Mesh::new`] gave for one primitive, or one of
//! the errors of [`crate::load`]: external buffers must lie inside the file's folder
//! ([`Error::PathOutsideFolder`]) and be regular files ([`Error::NotRegularFile`]), and bytes,
//! nodes, placed meshes and triangles are bounded by [`LoadOptions`]
//! ([`Error::LimitExceeded`]), checked before anything is allocated for them.

use std::collections::HashMap;
use std::path::Path;

use glam::{Mat4, Quat, Vec3};
use gltf::json;

use crate::error::{Error, Result};
use crate::load::{Budget, Limit, LoadOptions};
use crate::scene::Mesh;

mod accessor;
mod loader;
mod uri;

use loader::Loader;

/// One triangle primitive of a glTF mesh, placed by one node.
///
/// A mesh instanced by several nodes gives one `GltfMesh` per node (each with its own copy of
/// the [`Mesh`]); a mesh with several triangle primitives gives one per primitive.
#[derive(Debug, Clone)]
pub struct GltfMesh {
    /// The glTF mesh's `name`, if it has one (shared by all its primitives and instances).
    pub name: Option<String>,
    /// The primitive's positions (in the mesh's own object space, not transformed) and its
    /// triangle-list indices.
    pub mesh: Mesh,
    /// The node's world transform (object to world): the product of the local transforms
    /// along its parent chain, root first. Always finite and invertible, with a positive
    /// determinant: where the node mirrors (a negative determinant, which reverses the
    /// triangles' winding), [`mesh`](Self::mesh) is the primitive mirrored in x and wound the
    /// other way, and this the node's transform times that mirror, so the world triangles are
    /// the node's, facing out.
    pub transform: Mat4,
}

pub use crate::error::{GltfError, GltfErrorKind as ErrorKind};

/// Loads every triangle mesh placed by the scene of the `.gltf` or `.glb` file at `path`.
///
/// External buffers are read relative to the file's directory; `data:` URIs and the `.glb`
/// binary chunk are supported. Buffers that no loaded primitive uses are not read. See the
/// [module documentation](self) for which nodes and primitives are used.
///
/// # Errors
///
/// [`GltfError::Invalid`] with the path as given and an [`ErrorKind`], and
/// [`GltfError::Primitive`] when [`Mesh::new`] rejects a primitive (non-finite positions, all
/// triangles degenerate, too large, ...). A file whose scene has no triangle primitive is an
/// error of kind [`ErrorKind::NoTriangleMeshes`].
pub fn load(path: impl AsRef<Path>) -> Result<Vec<GltfMesh>> {
    load_with(path, &LoadOptions::default())
}

/// [`load`] with the bounds and the folder rule of `options` (see [`crate::load`]).
///
/// The file at `path` may be anywhere; external buffers must resolve inside its folder unless
/// [`LoadOptions::allow_outside`] is set.
pub fn load_with(path: impl AsRef<Path>, options: &LoadOptions) -> Result<Vec<GltfMesh>> {
    load_budgeted(path.as_ref(), &mut Budget::new(options))
}

/// [`load_with`], counting into a budget shared with the caller (a scene file).
pub(crate) fn load_budgeted(path: &Path, budget: &mut Budget) -> Result<Vec<GltfMesh>> {
    let label = path.display().to_string();
    let io = |e: Error| match e {
        Error::FileRead { problem, .. } => gltf_error(
            &label,
            ErrorKind::Io,
            format!("cannot read the file: {problem}"),
        ),
        e => e,
    };
    let bytes = budget.read(path).map_err(io)?;
    let folder = crate::load::folder_of(path).map_err(io)?;
    load_bytes(&bytes, &label, Some(&folder), budget)
}

/// Loads every triangle mesh placed by the scene of a `.glb` or a self-contained `.gltf`
/// (all buffers in `data:` URIs or the `.glb` binary chunk) held in memory.
///
/// # Errors
///
/// Those of [`load`], except that errors name the file `<memory>` and a buffer in an external
/// file is an error of kind [`ErrorKind::MissingBuffer`].
pub fn load_slice(bytes: &[u8]) -> Result<Vec<GltfMesh>> {
    load_slice_with(bytes, &LoadOptions::default())
}

/// [`load_slice`] with the bounds of `options` (see [`crate::load`]); `bytes` itself counts
/// against neither [`LoadOptions::max_file_bytes`] nor [`LoadOptions::max_total_bytes`].
pub fn load_slice_with(bytes: &[u8], options: &LoadOptions) -> Result<Vec<GltfMesh>> {
    load_bytes(bytes, MEMORY, None, &mut Budget::new(options))
}

/// The file name errors from [`load_slice`] carry.
const MEMORY: &str = "<memory>";

/// Required extensions whose meshes cannot be read without decoding them.
const UNSUPPORTED_EXTENSIONS: &[&str] = &["KHR_draco_mesh_compression", "EXT_meshopt_compression"];

pub(super) fn gltf_error(path: &str, kind: ErrorKind, problem: String) -> Error {
    Error::Gltf(GltfError::Invalid {
        path: path.to_owned(),
        kind,
        problem,
    })
}

fn load_bytes(
    bytes: &[u8],
    label: &str,
    base: Option<&Path>,
    budget: &mut Budget,
) -> Result<Vec<GltfMesh>> {
    let fail = |kind, problem: String| gltf_error(label, kind, problem);
    let glb = match bytes.starts_with(b"glTF") {
        true => Some(read_glb(bytes).map_err(|(kind, problem)| fail(kind, problem))?),
        false => None,
    };
    let json_bytes = glb.as_ref().map_or(bytes, |g| &g.json[..]);
    let bin = glb.as_ref().and_then(|g| g.bin.as_deref());
    let root = parse_json(json_bytes).map_err(|(kind, problem)| match (&glb, kind) {
        // The binary container was read: what is wrong is its JSON chunk, not the magic.
        (Some(_), ErrorKind::NotGltf) => fail(
            ErrorKind::Malformed,
            "binary glTF whose JSON chunk is not a JSON glTF document (it must start with `{`)"
                .to_owned(),
        ),
        (_, kind) => fail(kind, problem),
    })?;

    check_supported(&root, label)?;
    budget.add(Limit::Nodes, root.nodes.len() as u64, label)?;
    let mut loader = Loader {
        root: &root,
        label,
        base,
        bin,
        buffers: vec![None; root.buffers.len()],
        meshes: HashMap::new(),
        budget,
    };
    let placements = loader.placements()?;
    let mut out = Vec::new();
    for (mesh_index, node, transform) in placements {
        loader.mesh(mesh_index)?;
        let primitives = loader
            .meshes
            .get(&mesh_index)
            .map_or(&[][..], Vec::as_slice);
        if primitives.is_empty() {
            continue;
        }
        // Each placement is a copy: count it before making it.
        for mesh in primitives {
            loader
                .budget
                .add(Limit::Triangles, mesh.triangle_count() as u64, label)?;
            loader.budget.add(Limit::Instances, 1, label)?;
        }
        out.try_reserve(primitives.len()).map_err(|e| {
            fail(
                ErrorKind::Malformed,
                format!("cannot allocate the placed meshes: {e}"),
            )
        })?;
        if let Some(node) = node {
            check_transform(&transform).map_err(|problem| {
                fail(
                    ErrorKind::InvalidTransform,
                    format!(
                        "{} places mesh {mesh_index}, but {problem}",
                        node_name(&root, node)
                    ),
                )
            })?;
        }
        let name = root.meshes.get(mesh_index).and_then(|m| m.name.clone());
        place(&mut out, primitives, name, transform)?;
    }
    if out.is_empty() {
        return Err(fail(
            ErrorKind::NoTriangleMeshes,
            format!(
                "no triangle meshes: the scene places no mesh primitive with triangles \
                 ({} meshes, {} nodes in the file)",
                root.meshes.len(),
                root.nodes.len()
            ),
        ));
    }
    Ok(out)
}

/// Fails on a glTF version other than 2.x and on a required extension this loader cannot
/// decode.
fn check_supported(root: &json::Root, label: &str) -> Result<()> {
    let fail = |kind, problem: String| gltf_error(label, kind, problem);
    let version = root.asset.version.trim();
    if version.split('.').next() != Some("2") {
        return Err(fail(
            ErrorKind::Unsupported,
            format!("glTF version {version:?} is not supported (only 2.x)"),
        ));
    }
    if let Some(ext) = root
        .extensions_required
        .iter()
        .find(|ext| UNSUPPORTED_EXTENSIONS.contains(&ext.as_str()))
    {
        return Err(fail(
            ErrorKind::Unsupported,
            format!("the file requires the extension {ext}, which this loader cannot decode"),
        ));
    }
    Ok(())
}

/// Appends to `out` one placement of a mesh's `primitives` (named `name`) at `transform`.
fn place(
    out: &mut Vec<GltfMesh>,
    primitives: &[Mesh],
    name: Option<String>,
    transform: Mat4,
) -> Result<()> {
    if transform.determinant() < 0.0 {
        // A mirroring node (valid glTF: its triangles' winding reverses). Occluders take
        // no mirroring transform (their shadow volumes would turn inside out), so the
        // mesh is mirrored in its own space and wound the other way, and the transform
        // mirrored back: the same world triangles, facing out.
        let mirror = Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0));
        for mesh in primitives {
            out.push(GltfMesh {
                name: name.clone(),
                mesh: mirrored(mesh)?,
                transform: transform * mirror,
            });
        }
        return Ok(());
    }
    out.extend(primitives.iter().map(|mesh| GltfMesh {
        name: name.clone(),
        mesh: mesh.clone(),
        transform,
    }));
    Ok(())
}

/// `mesh` mirrored in x, each triangle wound the other way (so it still faces out).
fn mirrored(mesh: &Mesh) -> Result<Mesh> {
    let positions: Vec<Vec3> = mesh
        .positions()
        .iter()
        .map(|p| Vec3::new(-p.x, p.y, p.z))
        .collect();
    let indices: Vec<u32> = mesh
        .indices()
        .chunks_exact(3)
        .flat_map(|t| [t[0], t[2], t[1]])
        .collect();
    Mesh::new(&positions, &indices)
}

/// A problem found while parsing, before the file's name is attached.
type Problem = (ErrorKind, String);

/// The JSON and binary chunks of a `.glb`, read by the `gltf` crate. Its header length is
/// checked here first (the crate subtracts the header size from it unchecked), and bytes past
/// it are ignored.
fn read_glb(bytes: &[u8]) -> std::result::Result<gltf::Glb<'_>, Problem> {
    let Some(length) = bytes.get(8..12) else {
        return Err((
            ErrorKind::Truncated,
            format!(
                "binary glTF is {} bytes, shorter than its 12-byte header",
                bytes.len()
            ),
        ));
    };
    let length = u32::from_le_bytes([length[0], length[1], length[2], length[3]]) as usize;
    if length < 12 {
        return Err((
            ErrorKind::Malformed,
            format!("binary glTF header gives a length of {length} bytes, less than itself"),
        ));
    }
    let bytes = bytes.get(..length).unwrap_or(bytes);
    gltf::Glb::from_slice(bytes)
        .or_else(|e| match e {
            // The spec asks readers to ignore chunks of unknown type; the crate rejects one
            // straight after the JSON chunk (where a BIN chunk would be), so read the JSON alone.
            gltf::Error::Binary(gltf::binary::Error::UnknownChunkType(_)) => {
                json_only(bytes).ok_or(e)
            }
            e => Err(e),
        })
        .map_err(|e| {
            use gltf::binary::Error as B;
            let kind = match &e {
                gltf::Error::Binary(B::Version(_)) => ErrorKind::Unsupported,
                gltf::Error::Binary(B::Io(_) | B::Length { .. } | B::ChunkLength { .. }) => {
                    ErrorKind::Truncated
                }
                _ => ErrorKind::Malformed,
            };
            (kind, format!("binary glTF: {e}"))
        })
}

/// A `.glb` whose second chunk has an unknown type, as its JSON chunk alone (no BIN chunk).
fn json_only(bytes: &[u8]) -> Option<gltf::Glb<'_>> {
    let json_length = u32::from_le_bytes(bytes.get(12..16)?.try_into().ok()?) as usize;
    Some(gltf::Glb {
        header: gltf::binary::Header {
            magic: *b"glTF",
            version: 2,
            length: bytes.len() as u32,
        },
        json: bytes.get(20..20usize.checked_add(json_length)?)?.into(),
        bin: None,
    })
}

/// Parses the glTF JSON document.
fn parse_json(bytes: &[u8]) -> std::result::Result<json::Root, Problem> {
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    // Some writers pad the JSON chunk with NULs instead of spaces.
    let end = bytes
        .iter()
        .rposition(|&b| b != 0 && !b.is_ascii_whitespace())
        .map_or(0, |i| i + 1);
    let bytes = &bytes[..end];
    if bytes.iter().find(|b| !b.is_ascii_whitespace()) != Some(&b'{') {
        return Err((
            ErrorKind::NotGltf,
            "neither binary glTF (no `glTF` magic) nor a JSON glTF document".to_owned(),
        ));
    }
    json::deserialize::from_slice::<json::Root>(bytes).map_err(|e| {
        if e.is_eof() {
            (ErrorKind::Truncated, format!("the JSON ends early: {e}"))
        } else {
            (
                ErrorKind::NotGltf,
                format!("not a valid glTF 2.0 JSON document: {e}"),
            )
        }
    })
}

/// `node 3 ("Name")`, for messages.
pub(super) fn node_name(root: &json::Root, node: usize) -> String {
    match root.nodes.get(node).and_then(|n| n.name.as_deref()) {
        Some(name) => format!("node {node} ({name:?})"),
        None => format!("node {node}"),
    }
}

/// `Ok` if `m` is finite and invertible, else what is wrong with it.
fn check_transform(m: &Mat4) -> std::result::Result<(), String> {
    if !m.is_finite() {
        return Err("its world transform has non-finite entries".to_owned());
    }
    let det = m.determinant();
    let wide = m.as_dmat4().determinant();
    if wide != 0.0 && !(f64::from(f32::MIN_POSITIVE)..=f64::from(f32::MAX)).contains(&wide.abs()) {
        return Err(format!(
            "its world transform's scale {} f32: the determinant {wide:e} is beyond f32's \
             range, so it cannot be inverted in f32",
            if wide.abs() > 1.0 {
                "overflows"
            } else {
                "underflows"
            }
        ));
    }
    if !det.is_finite() || det == 0.0 || !m.inverse().is_finite() {
        return Err(format!(
            "its world transform is singular (determinant {det})"
        ));
    }
    Ok(())
}

/// A node's local transform.
pub(super) fn local_transform(node: &json::Node) -> std::result::Result<Mat4, String> {
    if let Some(m) = node.matrix {
        return Ok(Mat4::from_cols_array(&m));
    }
    let t = Vec3::from(node.translation.unwrap_or([0.0; 3]));
    let s = Vec3::from(node.scale.unwrap_or([1.0; 3]));
    let r = node
        .rotation
        .map_or(Quat::IDENTITY, |q| Quat::from_array(q.0));
    let len = r.length();
    if !len.is_finite() || len == 0.0 {
        return Err(format!(
            "its rotation {:?} is not a finite non-zero quaternion",
            r.to_array()
        ));
    }
    Ok(Mat4::from_scale_rotation_translation(s, r / len, t))
}

/// A `.glb` header whose length is less than the header itself is an error (the `gltf`
/// crate's reader would subtract the header size from it and overflow).
#[test]
fn glb_length_below_its_header() {
    let kind = match load_slice(b"glTF\x02\0\0\0\x04\0\0\0") {
        Err(Error::Gltf(GltfError::Invalid { kind, .. })) => kind,
        other => panic!("{other:?}"),
    };
    assert_eq!(kind, ErrorKind::Malformed);
}
