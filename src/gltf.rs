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
//! [`Error::Gltf`] naming the file, an [`ErrorKind`] and what is wrong, an
//! [`Error::GltfPrimitive`] wrapping the error [`Mesh::new`] gave for one primitive, or one of
//! the errors of [`crate::load`]: external buffers must lie inside the file's folder
//! ([`Error::PathOutsideFolder`]) and be regular files ([`Error::NotRegularFile`]), and bytes,
//! nodes, placed meshes and triangles are bounded by [`LoadOptions`]
//! ([`Error::LimitExceeded`]), checked before anything is allocated for them.

use std::borrow::Cow;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{Mat4, Quat, Vec3};
use gltf::json;
use json::accessor::{ComponentType, Type};
use json::mesh::{Mode, Semantic};
use json::validation::Checked;

use crate::error::{Error, Result};
use crate::load::{Budget, Limit, LoadOptions};
use crate::scene::Mesh;

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
    /// along its parent chain, root first. Always finite and invertible.
    pub transform: Mat4,
}

/// What kind of problem an [`Error::Gltf`] reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum ErrorKind {
    /// The file itself could not be read.
    Io,
    /// The bytes are not a glTF 2.0 asset: neither binary glTF (`glTF` magic) nor JSON that
    /// parses as a glTF document.
    NotGltf,
    /// The data ends early: a `.glb` shorter than its header or a chunk says, JSON cut off, or
    /// a buffer shorter than its `byteLength`.
    Truncated,
    /// A buffer's external file could not be read, or [`load_slice`] met a buffer in an
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

/// Loads every triangle mesh placed by the scene of the `.gltf` or `.glb` file at `path`.
///
/// External buffers are read relative to the file's directory; `data:` URIs and the `.glb`
/// binary chunk are supported. Buffers that no loaded primitive uses are not read. See the
/// [module documentation](self) for which nodes and primitives are used.
///
/// # Errors
///
/// [`Error::Gltf`] with the path as given and an [`ErrorKind`], and
/// [`Error::GltfPrimitive`] when [`Mesh::new`] rejects a primitive (non-finite positions, all
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

fn gltf_error(path: &str, kind: ErrorKind, problem: String) -> Error {
    Error::Gltf {
        path: path.to_owned(),
        kind,
        problem,
    }
}

fn load_bytes(
    bytes: &[u8],
    label: &str,
    base: Option<&Path>,
    budget: &mut Budget,
) -> Result<Vec<GltfMesh>> {
    let fail = |kind, problem: String| gltf_error(label, kind, problem);
    let (json_bytes, bin) = if bytes.starts_with(b"glTF") {
        split_glb(bytes).map_err(|(kind, problem)| fail(kind, problem))?
    } else {
        (bytes, None)
    };
    let root = parse_json(json_bytes).map_err(|(kind, problem)| fail(kind, problem))?;

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
        out.extend(primitives.iter().map(|mesh| GltfMesh {
            name: name.clone(),
            mesh: mesh.clone(),
            transform,
        }));
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

/// A problem found while parsing, before the file's name is attached.
type Problem = (ErrorKind, String);

/// Splits a `.glb` into its JSON chunk and its binary chunk, if any.
fn split_glb(bytes: &[u8]) -> std::result::Result<(&[u8], Option<&[u8]>), Problem> {
    let u32_at = |at: usize| -> Option<u32> {
        let b = bytes.get(at..at + 4)?;
        Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    let (Some(version), Some(length)) = (u32_at(4), u32_at(8)) else {
        return Err((
            ErrorKind::Truncated,
            format!(
                "binary glTF is {} bytes, shorter than its 12-byte header",
                bytes.len()
            ),
        ));
    };
    if version != 2 {
        return Err((
            ErrorKind::Unsupported,
            format!("binary glTF version {version} is not supported (only 2)"),
        ));
    }
    let length = length as usize;
    if length > bytes.len() {
        return Err((
            ErrorKind::Truncated,
            format!(
                "binary glTF header gives a length of {length} bytes, but there are only {}",
                bytes.len()
            ),
        ));
    }
    let data = &bytes[..length];
    let mut at = 12;
    let mut chunks: Vec<(&[u8; 4], &[u8])> = Vec::new();
    while at < data.len() {
        let Some(header) = data.get(at..at + 8) else {
            return Err((
                ErrorKind::Truncated,
                format!("binary glTF chunk header at byte {at} is cut off"),
            ));
        };
        let len = u32::from_le_bytes([header[0], header[1], header[2], header[3]]) as usize;
        let kind: &[u8; 4] = header[4..8].try_into().unwrap_or(b"????");
        let start = at + 8;
        let Some(chunk) = start.checked_add(len).and_then(|end| data.get(start..end)) else {
            return Err((
                ErrorKind::Truncated,
                format!(
                    "binary glTF chunk at byte {at} is {len} bytes long, but only {} remain",
                    data.len() - start
                ),
            ));
        };
        chunks.push((kind, chunk));
        at = start + len;
    }
    match chunks.as_slice() {
        [] => Err((
            ErrorKind::Malformed,
            "binary glTF has no JSON chunk".to_owned(),
        )),
        [(kind, _), ..] if *kind != b"JSON" => Err((
            ErrorKind::Malformed,
            format!(
                "binary glTF's first chunk is {:?}, not JSON",
                String::from_utf8_lossy(&kind[..])
            ),
        )),
        [(_, json), rest @ ..] => {
            let bin = match rest.first() {
                Some((kind, bin)) if *kind == b"BIN\0" => Some(*bin),
                _ => None,
            };
            Ok((json, bin))
        }
    }
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
fn node_name(root: &json::Root, node: usize) -> String {
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
    if !det.is_finite() || det == 0.0 || !m.inverse().is_finite() {
        return Err(format!(
            "its world transform is singular (determinant {det})"
        ));
    }
    Ok(())
}

/// A node's local transform.
fn local_transform(node: &json::Node) -> std::result::Result<Mat4, String> {
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

/// How to read the components of an accessor.
#[derive(Debug, Clone, Copy)]
struct Layout {
    component: ComponentType,
    components: usize,
}

impl Layout {
    fn component_size(self) -> usize {
        match self.component {
            ComponentType::I8 | ComponentType::U8 => 1,
            ComponentType::I16 | ComponentType::U16 => 2,
            ComponentType::U32 | ComponentType::F32 => 4,
        }
    }
    fn element_size(self) -> usize {
        self.component_size() * self.components
    }
}

/// Reads a little-endian `u32` from the first four bytes (the caller checks the length).
fn le_u32(b: &[u8]) -> u32 {
    u32::from_le_bytes([b[0], b[1], b[2], b[3]])
}

/// Reads component `b` (of `component`'s size) as a float, normalized if asked.
fn component_f32(component: ComponentType, normalized: bool, b: &[u8]) -> f32 {
    match (component, normalized) {
        (ComponentType::F32, _) => f32::from_bits(le_u32(b)),
        (ComponentType::I8, false) => f32::from(b[0] as i8),
        (ComponentType::I8, true) => (f32::from(b[0] as i8) / 127.0).max(-1.0),
        (ComponentType::U8, false) => f32::from(b[0]),
        (ComponentType::U8, true) => f32::from(b[0]) / 255.0,
        (ComponentType::I16, false) => f32::from(i16::from_le_bytes([b[0], b[1]])),
        (ComponentType::I16, true) => {
            (f32::from(i16::from_le_bytes([b[0], b[1]])) / 32767.0).max(-1.0)
        }
        (ComponentType::U16, false) => f32::from(u16::from_le_bytes([b[0], b[1]])),
        (ComponentType::U16, true) => f32::from(u16::from_le_bytes([b[0], b[1]])) / 65535.0,
        // Not accepted for positions; kept total for safety.
        (ComponentType::U32, false) => le_u32(b) as f32,
        (ComponentType::U32, true) => le_u32(b) as f32 / u32::MAX as f32,
    }
}

/// Reads an unsigned index component.
fn component_u32(component: ComponentType, b: &[u8]) -> u32 {
    match component {
        ComponentType::U8 | ComponentType::I8 => u32::from(b[0]),
        ComponentType::U16 | ComponentType::I16 => u32::from(u16::from_le_bytes([b[0], b[1]])),
        ComponentType::U32 | ComponentType::F32 => le_u32(b),
    }
}

/// The walk over one document: buffers are loaded when first needed and meshes built once.
struct Loader<'a, 'b> {
    root: &'a json::Root,
    label: &'a str,
    /// The canonical folder of the file, for external buffers (`None` in memory).
    base: Option<&'a Path>,
    bin: Option<&'a [u8]>,
    buffers: Vec<Option<Cow<'a, [u8]>>>,
    /// The triangle primitives of each mesh read so far.
    meshes: HashMap<usize, Vec<Mesh>>,
    /// The load's running totals.
    budget: &'b mut Budget,
}

impl<'a> Loader<'a, '_> {
    fn fail(&self, kind: ErrorKind, problem: String) -> Error {
        gltf_error(self.label, kind, problem)
    }

    /// Every (mesh, placing node, world transform), in depth-first order. The node is `None`
    /// for meshes of a file without nodes.
    fn placements(&self) -> Result<Vec<(usize, Option<usize>, Mat4)>> {
        let root = self.root;
        let nodes = &root.nodes;
        if nodes.is_empty() && root.scenes.is_empty() {
            return Ok((0..root.meshes.len())
                .map(|m| (m, None, Mat4::IDENTITY))
                .collect());
        }

        // Each node's parent; glTF nodes form disjoint strict trees.
        let mut parent: Vec<Option<usize>> = vec![None; nodes.len()];
        for (i, node) in nodes.iter().enumerate() {
            for child in node.children.iter().flatten() {
                let c = child.value();
                if c >= nodes.len() {
                    return Err(self.fail(
                        ErrorKind::Malformed,
                        format!(
                            "{} has child {c}, but there are {} nodes",
                            node_name(root, i),
                            nodes.len()
                        ),
                    ));
                }
                if let Some(p) = parent[c] {
                    return Err(self.fail(
                        ErrorKind::Malformed,
                        format!("node {c} has two parents, nodes {p} and {i}"),
                    ));
                }
                if c == i {
                    return Err(self.fail(
                        ErrorKind::Malformed,
                        format!("{} is its own child", node_name(root, i)),
                    ));
                }
                parent[c] = Some(i);
            }
        }

        let scene_roots = |s: usize| -> Result<&'a [json::Index<json::Node>]> {
            match root.scenes.get(s) {
                Some(scene) => Ok(&scene.nodes),
                None => Err(self.fail(
                    ErrorKind::Malformed,
                    format!(
                        "the default scene is {s}, but there are {} scenes",
                        root.scenes.len()
                    ),
                )),
            }
        };
        let roots: Vec<usize> = if let Some(s) = root.scene {
            scene_roots(s.value())?.iter().map(|n| n.value()).collect()
        } else if !root.scenes.is_empty() {
            root.scenes
                .iter()
                .flat_map(|scene| scene.nodes.iter().map(|n| n.value()))
                .collect()
        } else {
            (0..nodes.len()).filter(|&i| parent[i].is_none()).collect()
        };

        let mut visited = vec![false; nodes.len()];
        let mut out = Vec::new();
        let mut stack: Vec<(usize, Mat4)> = Vec::new();
        for r in roots {
            if r >= nodes.len() {
                return Err(self.fail(
                    ErrorKind::Malformed,
                    format!(
                        "a scene lists node {r}, but there are {} nodes",
                        nodes.len()
                    ),
                ));
            }
            if let Some(p) = parent[r] {
                return Err(self.fail(
                    ErrorKind::Malformed,
                    format!("a scene lists node {r} as a root, but it is a child of node {p}"),
                ));
            }
            if visited[r] {
                continue;
            }
            stack.push((r, Mat4::IDENTITY));
            // Every node reached has a single parent and the walk starts at a parentless
            // node, so it never meets a node twice and cannot loop.
            while let Some((i, parent_world)) = stack.pop() {
                visited[i] = true;
                let node = &nodes[i];
                let local = local_transform(node).map_err(|problem| {
                    self.fail(
                        ErrorKind::InvalidTransform,
                        format!("{}: {problem}", node_name(root, i)),
                    )
                })?;
                let world = parent_world * local;
                if let Some(mesh) = node.mesh {
                    if mesh.value() >= root.meshes.len() {
                        return Err(self.fail(
                            ErrorKind::Malformed,
                            format!(
                                "{} places mesh {}, but there are {} meshes",
                                node_name(root, i),
                                mesh.value(),
                                root.meshes.len()
                            ),
                        ));
                    }
                    out.push((mesh.value(), Some(i), world));
                }
                if let Some(children) = &node.children {
                    stack.extend(children.iter().rev().map(|c| (c.value(), world)));
                }
            }
        }
        Ok(out)
    }

    /// The triangle primitives of mesh `m`, built on first use.
    fn mesh(&mut self, m: usize) -> Result<&[Mesh]> {
        if !self.meshes.contains_key(&m) {
            let built = self.build_mesh(m)?;
            self.meshes.insert(m, built);
        }
        Ok(self.meshes.get(&m).map_or(&[], Vec::as_slice))
    }

    fn build_mesh(&mut self, m: usize) -> Result<Vec<Mesh>> {
        let root = self.root;
        let Some(mesh) = root.meshes.get(m) else {
            return Err(self.fail(
                ErrorKind::Malformed,
                format!(
                    "a node places mesh {m}, but there are {} meshes",
                    root.meshes.len()
                ),
            ));
        };
        let mut out = Vec::new();
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            if let Some(built) = self.primitive(m, p, primitive)? {
                out.push(built);
            }
        }
        Ok(out)
    }

    /// One primitive as a [`Mesh`], or `None` if it has no triangles to cast shadows with.
    fn primitive(
        &mut self,
        m: usize,
        p: usize,
        primitive: &json::mesh::Primitive,
    ) -> Result<Option<Mesh>> {
        let what = format!("mesh {m} primitive {p}");
        let mode = match primitive.mode {
            Checked::Valid(mode) => mode,
            Checked::Invalid => {
                return Err(self.fail(ErrorKind::Malformed, format!("{what} has an unknown mode")))
            }
        };
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            return Ok(None);
        }
        let Some(&position_accessor) = primitive
            .attributes
            .get(&Checked::Valid(Semantic::Positions))
        else {
            return Ok(None);
        };
        let label = self.label;
        let wrap = |source: Error| Error::GltfPrimitive {
            path: label.to_owned(),
            mesh: m,
            primitive: p,
            source: Box::new(source),
        };

        // Positions.
        let a = position_accessor.value();
        let accessor = self.accessor(a, &what, "POSITION")?;
        let layout = match (accessor.type_, accessor.component_type) {
            (Checked::Valid(Type::Vec3), Checked::Valid(c)) if c.0 != ComponentType::U32 => {
                Layout {
                    component: c.0,
                    components: 3,
                }
            }
            _ => {
                return Err(self.fail(
                    ErrorKind::Malformed,
                    format!(
                        "{what}: POSITION accessor {a} must be a VEC3 of FLOAT (or of 8- or \
                         16-bit integers)"
                    ),
                ))
            }
        };
        let vertex_count = count(accessor);
        if vertex_count > Mesh::MAX_POSITIONS as u64 {
            return Err(wrap(Error::MeshTooLarge {
                field: "positions",
                count: usize::try_from(vertex_count).unwrap_or(usize::MAX),
                max: Mesh::MAX_POSITIONS,
            }));
        }
        // Before reading anything: the triangles this primitive can have must fit in what is
        // left of the budget (a primitive without indices has a triangle per 3 vertices, and
        // no mesh needs more than 3 positions per triangle).
        let index_count = match primitive.indices {
            None => vertex_count,
            Some(i) => self.root.accessors.get(i.value()).map_or(0, count),
        };
        let triangle_bound = match mode {
            Mode::Triangles => index_count / 3,
            _ => index_count.saturating_sub(2),
        };
        self.budget.check(Limit::Triangles, triangle_bound, label)?;
        self.budget
            .check(Limit::Triangles, vertex_count.div_ceil(3), label)?;
        let raw = self.read(a, layout, &what)?;
        let size = layout.component_size();
        let positions: Vec<Vec3> = raw
            .chunks_exact(layout.element_size())
            .map(|e| {
                let c =
                    |k: usize| component_f32(layout.component, accessor.normalized, &e[k * size..]);
                Vec3::new(c(0), c(1), c(2))
            })
            .collect();

        // Indices, in the primitive's own order.
        let max_indices = 3 * Mesh::MAX_TRIANGLES as u64 + 2;
        let indices: Vec<u32> = match primitive.indices {
            None => {
                if vertex_count > max_indices {
                    return Err(wrap(Error::MeshTooLarge {
                        field: "triangles",
                        count: usize::try_from(vertex_count / 3).unwrap_or(usize::MAX),
                        max: Mesh::MAX_TRIANGLES,
                    }));
                }
                (0..positions.len() as u32).collect()
            }
            Some(index_accessor) => {
                let a = index_accessor.value();
                let accessor = self.accessor(a, &what, "indices")?;
                let layout = match (accessor.type_, accessor.component_type) {
                    (Checked::Valid(Type::Scalar), Checked::Valid(c))
                        if matches!(
                            c.0,
                            ComponentType::U8 | ComponentType::U16 | ComponentType::U32
                        ) =>
                    {
                        Layout {
                            component: c.0,
                            components: 1,
                        }
                    }
                    _ => {
                        return Err(self.fail(
                            ErrorKind::Malformed,
                            format!(
                                "{what}: indices accessor {a} must be a SCALAR of \
                                 UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT"
                            ),
                        ))
                    }
                };
                if count(accessor) > max_indices {
                    return Err(wrap(Error::MeshTooLarge {
                        field: "triangles",
                        count: usize::try_from(count(accessor) / 3).unwrap_or(usize::MAX),
                        max: Mesh::MAX_TRIANGLES,
                    }));
                }
                let raw = self.read(a, layout, &what)?;
                let indices: Vec<u32> = raw
                    .chunks_exact(layout.element_size())
                    .map(|e| component_u32(layout.component, e))
                    .collect();
                if let Some((k, &index)) = indices
                    .iter()
                    .enumerate()
                    .find(|(_, &i)| i as usize >= positions.len())
                {
                    return Err(self.fail(
                        ErrorKind::IndexOutOfRange,
                        format!(
                            "{what}: index {k} of accessor {a} is {index}, but POSITION has \
                             {} vertices",
                            positions.len()
                        ),
                    ));
                }
                indices
            }
        };

        let triangles: Vec<u32> = match mode {
            Mode::TriangleStrip => (0..indices.len().saturating_sub(2))
                .flat_map(|i| {
                    let (a, b, c) = (indices[i], indices[i + 1], indices[i + 2]);
                    // Odd triangles swap their last two corners to keep the winding.
                    if i % 2 == 0 {
                        [a, b, c]
                    } else {
                        [a, c, b]
                    }
                })
                .collect(),
            Mode::TriangleFan => (1..indices.len().saturating_sub(1))
                .flat_map(|i| [indices[i], indices[i + 1], indices[0]])
                .collect(),
            _ => indices,
        };
        if triangles.is_empty() {
            return Ok(None);
        }
        Mesh::new(&positions, &triangles).map(Some).map_err(wrap)
    }

    /// Accessor `a`, referenced as `role` by `what`.
    fn accessor(&self, a: usize, what: &str, role: &str) -> Result<&'a json::Accessor> {
        self.root.accessors.get(a).ok_or_else(|| {
            self.fail(
                ErrorKind::Malformed,
                format!(
                    "{what}: {role} is accessor {a}, but there are {} accessors",
                    self.root.accessors.len()
                ),
            )
        })
    }

    /// The bytes of accessor `a`'s elements, tightly packed (`count × element size`), with its
    /// sparse substitution applied.
    fn read(&mut self, a: usize, layout: Layout, what: &str) -> Result<Vec<u8>> {
        let label = self.label;
        let accessor = self.accessor(a, what, "an attribute")?;
        let elem = layout.element_size();
        let n = count(accessor);
        let out_of_range = |problem: String| {
            gltf_error(
                label,
                ErrorKind::AccessorOutOfRange,
                format!("{what}: accessor {a} {problem}"),
            )
        };

        let mut out = match accessor.buffer_view {
            Some(view) => {
                let view = view.value();
                let stride = self.view_stride(view, what)?.unwrap_or(elem);
                if stride < elem {
                    return Err(self.fail(
                        ErrorKind::Malformed,
                        format!(
                            "{what}: accessor {a} has {elem}-byte elements, but bufferView \
                             {view}'s byteStride is {stride}"
                        ),
                    ));
                }
                let data = self.view(view, what)?;
                let offset = accessor.byte_offset.map_or(0, |o| o.0);
                let needed = if n == 0 {
                    Some(offset)
                } else {
                    (n - 1)
                        .checked_mul(stride as u64)
                        .and_then(|x| x.checked_add(offset))
                        .and_then(|x| x.checked_add(elem as u64))
                };
                match needed {
                    Some(end) if end <= data.len() as u64 => {}
                    _ => {
                        return Err(out_of_range(format!(
                            "reads {n} elements of {elem} bytes (stride {stride}) from byte \
                             {offset} of bufferView {view}, which is only {} bytes long",
                            data.len()
                        )))
                    }
                }
                // `end` fits in the view, so `n`, `offset` and every product fit in usize.
                let (n, offset) = (n as usize, offset as usize);
                let mut out = Vec::with_capacity(n * elem);
                for k in 0..n {
                    let start = offset + k * stride;
                    out.extend_from_slice(&data[start..start + elem]);
                }
                out
            }
            // Without a buffer view the elements start as zeros (the caller bounded `n`).
            None => vec![0; (n as usize).saturating_mul(elem)],
        };

        if let Some(sparse) = &accessor.sparse {
            let m = sparse.count.0;
            if m > n {
                return Err(out_of_range(format!(
                    "has {m} sparse elements but only {n} elements"
                )));
            }
            let index_component = match sparse.indices.component_type {
                Checked::Valid(c) => c.0,
                Checked::Invalid => {
                    return Err(self.fail(
                        ErrorKind::Malformed,
                        format!("{what}: accessor {a} has sparse indices of an invalid type"),
                    ))
                }
            };
            let index_layout = Layout {
                component: index_component,
                components: 1,
            };
            let m = m as usize;
            let isize_ = index_layout.element_size();
            let view = sparse.indices.buffer_view.value();
            let offset = sparse.indices.byte_offset.0;
            let data = self.view(view, what)?;
            let Some(bytes) = slice_at(data, offset, m, isize_) else {
                return Err(out_of_range(format!(
                    "has {m} sparse indices at byte {offset} of bufferView {view}, which is \
                     only {} bytes long",
                    data.len()
                )));
            };
            let targets: Vec<u32> = bytes
                .chunks_exact(isize_)
                .map(|b| component_u32(index_component, b))
                .collect();
            if let Some(&t) = targets.iter().find(|&&t| u64::from(t) >= n) {
                return Err(out_of_range(format!(
                    "has sparse index {t}, but only {n} elements"
                )));
            }
            let view = sparse.values.buffer_view.value();
            let offset = sparse.values.byte_offset.0;
            let data = self.view(view, what)?;
            let Some(values) = slice_at(data, offset, m, elem) else {
                return Err(out_of_range(format!(
                    "has {m} sparse values at byte {offset} of bufferView {view}, which is \
                     only {} bytes long",
                    data.len()
                )));
            };
            for (t, value) in targets.iter().zip(values.chunks_exact(elem)) {
                let t = *t as usize * elem;
                out[t..t + elem].copy_from_slice(value);
            }
        }
        Ok(out)
    }

    /// Buffer view `v`'s byte stride, if it has one.
    fn view_stride(&self, v: usize, what: &str) -> Result<Option<usize>> {
        let view = self.root.buffer_views.get(v).ok_or_else(|| {
            self.fail(
                ErrorKind::Malformed,
                format!(
                    "{what}: bufferView {v} does not exist (there are {})",
                    self.root.buffer_views.len()
                ),
            )
        })?;
        Ok(view.byte_stride.map(|s| s.0).filter(|&s| s != 0))
    }

    /// The bytes of buffer view `v`.
    fn view(&mut self, v: usize, what: &str) -> Result<&[u8]> {
        let root = self.root;
        let Some(view) = root.buffer_views.get(v) else {
            return Err(self.fail(
                ErrorKind::Malformed,
                format!(
                    "{what}: bufferView {v} does not exist (there are {})",
                    root.buffer_views.len()
                ),
            ));
        };
        let b = view.buffer.value();
        let offset = view.byte_offset.map_or(0, |o| o.0);
        let len = view.byte_length.0;
        let label = self.label;
        let data = self.buffer(b, what)?;
        match offset.checked_add(len) {
            Some(end) if end <= data.len() as u64 => Ok(&data[offset as usize..end as usize]),
            _ => Err(gltf_error(
                label,
                ErrorKind::AccessorOutOfRange,
                format!(
                    "{what}: bufferView {v} spans bytes {offset}..{} of buffer {b}, which is \
                     only {} bytes long",
                    offset.saturating_add(len),
                    data.len()
                ),
            )),
        }
    }

    /// The bytes of buffer `b` (exactly its `byteLength`), read on first use.
    fn buffer(&mut self, b: usize, what: &str) -> Result<&[u8]> {
        let root = self.root;
        let Some(buffer) = root.buffers.get(b) else {
            return Err(self.fail(
                ErrorKind::Malformed,
                format!(
                    "{what}: buffer {b} does not exist (there are {})",
                    root.buffers.len()
                ),
            ));
        };
        if self.buffers[b].is_none() {
            let data = self.fetch(b, buffer)?;
            let len = buffer.byte_length.0;
            if (data.len() as u64) < len {
                return Err(self.fail(
                    ErrorKind::Truncated,
                    format!(
                        "buffer {b} has {} bytes, but its byteLength is {len}",
                        data.len()
                    ),
                ));
            }
            let data = match data {
                Cow::Borrowed(d) => Cow::Borrowed(&d[..len as usize]),
                Cow::Owned(mut d) => {
                    d.truncate(len as usize);
                    Cow::Owned(d)
                }
            };
            self.buffers[b] = Some(data);
        }
        Ok(self.buffers[b].as_deref().unwrap_or(&[]))
    }

    /// Reads buffer `b`'s data from the GLB chunk, a data URI or a file.
    fn fetch(&mut self, b: usize, buffer: &json::Buffer) -> Result<Cow<'a, [u8]>> {
        let Some(uri) = buffer.uri.as_deref() else {
            return match (b, self.bin) {
                (0, Some(bin)) => Ok(Cow::Borrowed(bin)),
                _ => Err(self.fail(
                    ErrorKind::Malformed,
                    format!("buffer {b} has no uri and is not the binary chunk of a .glb"),
                )),
            };
        };
        if let Some(data) = uri.strip_prefix("data:") {
            return decode_data_uri(data).map(Cow::Owned).map_err(|problem| {
                self.fail(
                    ErrorKind::Malformed,
                    format!("buffer {b}'s data URI: {problem}"),
                )
            });
        }
        if has_scheme(uri) {
            return Err(self.fail(
                ErrorKind::Unsupported,
                format!("buffer {b}'s uri {uri:?} is neither a relative path nor a data: URI"),
            ));
        }
        let Some(folder) = self.base else {
            return Err(self.fail(
                ErrorKind::MissingBuffer,
                format!(
                    "buffer {b} is in the external file {uri:?}, which a glTF loaded from \
                     memory cannot read (use gltf::load with the file's path)"
                ),
            ));
        };
        let named = percent_decode(uri);
        let field = format!("buffers[{b}].uri");
        let label = self.label;
        match crate::load::read_named(self.budget, folder, &named, label, &field) {
            Ok((_, bytes)) => Ok(Cow::Owned(bytes)),
            Err(Error::FileRead { path, problem }) => Err(gltf_error(
                label,
                ErrorKind::MissingBuffer,
                format!("cannot read buffer {b} from {path}: {problem}"),
            )),
            Err(e) => Err(e),
        }
    }
}

/// An accessor's element count.
fn count(accessor: &json::Accessor) -> u64 {
    accessor.count.0
}

/// `n` tightly packed elements of `size` bytes from byte `offset` of `data`, if they fit.
fn slice_at(data: &[u8], offset: u64, n: usize, size: usize) -> Option<&[u8]> {
    let start = usize::try_from(offset).ok()?;
    let end = n.checked_mul(size)?.checked_add(start)?;
    data.get(start..end)
}

/// Whether `uri` starts with a URL scheme (`http:`, `file:`, ...). One-letter schemes are
/// taken for Windows drive letters.
fn has_scheme(uri: &str) -> bool {
    match uri.split_once(':') {
        Some((scheme, _)) => {
            scheme.len() > 1
                && scheme.starts_with(|c: char| c.is_ascii_alphabetic())
                && scheme
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.'))
        }
        None => false,
    }
}

/// Decodes `%XX` escapes; malformed escapes are kept as they are.
fn percent_decode_bytes(s: &str) -> Vec<u8> {
    percent_encoding::percent_decode_str(s).collect()
}

/// A relative URI as a path (percent-escapes decoded, so `..%2F` is `../`).
fn percent_decode(uri: &str) -> PathBuf {
    PathBuf::from(
        percent_encoding::percent_decode_str(uri)
            .decode_utf8_lossy()
            .into_owned(),
    )
}

/// Decodes the part of a data URI after `data:`.
fn decode_data_uri(data: &str) -> std::result::Result<Vec<u8>, String> {
    let Some((header, payload)) = data.split_once(',') else {
        return Err("no ',' before the data".to_owned());
    };
    if header.ends_with(";base64") {
        decode_base64(payload)
    } else {
        Ok(percent_decode_bytes(payload))
    }
}

/// Decodes standard or URL-safe base64, with or without padding.
fn decode_base64(s: &str) -> std::result::Result<Vec<u8>, String> {
    let s = s.trim_end_matches('=');
    let mut out = Vec::with_capacity(s.len() / 4 * 3 + 3);
    let mut acc: u32 = 0;
    let mut bits = 0;
    for (i, c) in s.bytes().enumerate() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            _ => {
                return Err(format!(
                    "invalid base64 character {:?} at offset {i}",
                    char::from(c)
                ))
            }
        };
        acc = (acc << 6) | u32::from(v);
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    if s.len() % 4 == 1 {
        return Err(format!("base64 data of {} characters is cut off", s.len()));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_round_trips() {
        assert_eq!(decode_base64("").unwrap(), b"");
        assert_eq!(decode_base64("Zg==").unwrap(), b"f");
        assert_eq!(decode_base64("Zm8=").unwrap(), b"fo");
        assert_eq!(decode_base64("Zm9v").unwrap(), b"foo");
        assert_eq!(decode_base64("Zm9vYmFy").unwrap(), b"foobar");
        assert_eq!(decode_base64("AP8A/w").unwrap(), [0, 255, 0, 255]);
        assert!(decode_base64("Zm9v!").is_err());
        assert!(decode_base64("Zm9vY").is_err());
    }

    #[test]
    fn uris() {
        assert!(has_scheme("http://example.com/a.bin"));
        assert!(!has_scheme("C:/models/a.bin"));
        assert!(!has_scheme("models/a.bin"));
        assert_eq!(percent_decode_bytes("a%20b%2"), b"a b%2");
        assert_eq!(decode_data_uri("text/plain,a%41").unwrap(), b"aA");
    }
}
