//! The walk over one glTF document: nodes, meshes, primitives, accessors and buffers.

use std::borrow::Cow;
use std::collections::HashMap;
use std::path::Path;

use glam::{Mat4, Vec3};
use json::accessor::{ComponentType, Type};
use json::mesh::{Mode, Semantic};
use json::validation::Checked;

use super::accessor::{component_f32, component_u32, count, slice_at, Layout};
use super::uri::{decode_data_uri, has_scheme, percent_decode};
use super::{gltf_error, json, local_transform, node_name, ErrorKind, GltfError};
use crate::error::{Error, Result};
use crate::load::{Budget, Limit};
use crate::scene::Mesh;

/// The walk over one document: buffers are loaded when first needed and meshes built once.
pub(super) struct Loader<'a, 'b> {
    pub root: &'a json::Root,
    pub label: &'a str,
    /// The canonical folder of the file, for external buffers (`None` in memory).
    pub base: Option<&'a Path>,
    pub bin: Option<&'a [u8]>,
    pub buffers: Vec<Option<Cow<'a, [u8]>>>,
    /// The triangle primitives of each mesh read so far.
    pub meshes: HashMap<usize, Vec<Mesh>>,
    /// The load's running totals.
    pub budget: &'b mut Budget,
}

impl<'a> Loader<'a, '_> {
    fn fail(&self, kind: ErrorKind, problem: String) -> Error {
        gltf_error(self.label, kind, problem)
    }

    /// Every (mesh, placing node, world transform), in depth-first order. The node is `None`
    /// for meshes of a file without nodes.
    pub fn placements(&self) -> Result<Vec<(usize, Option<usize>, Mat4)>> {
        let root = self.root;
        let nodes = &root.nodes;
        if nodes.is_empty() && root.scenes.is_empty() {
            return Ok((0..root.meshes.len())
                .map(|m| (m, None, Mat4::IDENTITY))
                .collect());
        }

        let parent = self.parents()?;
        let roots = self.roots(&parent)?;

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

    /// Each node's parent; glTF nodes form disjoint strict trees (checked: a child index in
    /// range, one parent, not its own).
    fn parents(&self) -> Result<Vec<Option<usize>>> {
        let root = self.root;
        let nodes = &root.nodes;
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
        Ok(parent)
    }

    /// The nodes the placements start from: the default scene's roots, else every scene's,
    /// else (no scenes) every node without a parent.
    fn roots(&self, parent: &[Option<usize>]) -> Result<Vec<usize>> {
        let root = self.root;
        let nodes = &root.nodes;
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
        Ok(roots)
    }

    /// The triangle primitives of mesh `m`, built on first use.
    pub fn mesh(&mut self, m: usize) -> Result<&[Mesh]> {
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
        let wrap = |source: Error| -> Error {
            GltfError::Primitive {
                path: label.to_owned(),
                mesh: m,
                primitive: p,
                source: Box::new(source),
            }
            .into()
        };

        // Positions.
        let a = position_accessor.value();
        let accessor = self.accessor(a, &what, "POSITION")?;
        let layout = self.position_layout(accessor, a, &what)?;
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
                self.indices(index_accessor.value(), &what, positions.len(), wrap)?
            }
        };

        let triangles = triangle_list(mode, indices);
        if triangles.is_empty() {
            return Ok(None);
        }
        Mesh::new(&positions, &triangles).map(Some).map_err(wrap)
    }

    /// The layout of `what`'s POSITION accessor `a`: a VEC3 of FLOAT (or of 8- or 16-bit
    /// integers).
    fn position_layout(&self, accessor: &json::Accessor, a: usize, what: &str) -> Result<Layout> {
        match (accessor.type_, accessor.component_type) {
            (Checked::Valid(Type::Vec3), Checked::Valid(c)) if c.0 != ComponentType::U32 => {
                Ok(Layout {
                    component: c.0,
                    components: 3,
                })
            }
            _ => Err(self.fail(
                ErrorKind::Malformed,
                format!(
                    "{what}: POSITION accessor {a} must be a VEC3 of FLOAT (or of 8- or \
                     16-bit integers)"
                ),
            )),
        }
    }

    /// The indices of accessor `a` of `what`, a primitive whose POSITION has `vertices`
    /// vertices, each checked against them (`wrap` names the primitive in a size error).
    fn indices(
        &mut self,
        a: usize,
        what: &str,
        vertices: usize,
        wrap: impl Fn(Error) -> Error,
    ) -> Result<Vec<u32>> {
        let max_indices = 3 * Mesh::MAX_TRIANGLES as u64 + 2;
        let accessor = self.accessor(a, what, "indices")?;
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
        let raw = self.read(a, layout, what)?;
        let indices: Vec<u32> = raw
            .chunks_exact(layout.element_size())
            .map(|e| component_u32(layout.component, e))
            .collect();
        if let Some((k, &index)) = indices
            .iter()
            .enumerate()
            .find(|(_, &i)| i as usize >= vertices)
        {
            return Err(self.fail(
                ErrorKind::IndexOutOfRange,
                format!(
                    "{what}: index {k} of accessor {a} is {index}, but POSITION has \
                     {vertices} vertices"
                ),
            ));
        }
        Ok(indices)
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
            self.apply_sparse((a, accessor, sparse), elem, what, &mut out)?;
        }
        Ok(out)
    }

    /// Writes accessor `a`'s `sparse` elements (of `elem` bytes) over `out`, its dense
    /// elements, checking their count, indices and bytes against the accessor and the views.
    fn apply_sparse(
        &mut self,
        (a, accessor, sparse): (usize, &json::Accessor, &json::accessor::sparse::Sparse),
        elem: usize,
        what: &str,
        out: &mut [u8],
    ) -> Result<()> {
        let label = self.label;
        let n = count(accessor);
        let out_of_range = |problem: String| {
            gltf_error(
                label,
                ErrorKind::AccessorOutOfRange,
                format!("{what}: accessor {a} {problem}"),
            )
        };
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
        Ok(())
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

/// The triangles' corners (three indices each) of a primitive drawn in `mode` from `indices`:
/// a strip's odd triangles swap their last two corners to keep the winding.
fn triangle_list(mode: Mode, indices: Vec<u32>) -> Vec<u32> {
    match mode {
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
    }
}
