//! glTF loading: every test writes its own small glTF (a temp dir under
//! `std::env::temp_dir()`, or bytes for `load_slice`).
#![cfg(feature = "gltf")]

use volshadow_harness::files;

use std::path::Path;

use files::{glb, WriteAt};
use volshadow::glam::{Mat4, Quat, Vec3};
use volshadow::gltf::{self, ErrorKind, GltfError, GltfMesh};
use volshadow::Error;

// ---------------------------------------------------------------------------------------------
// Building test files
// ---------------------------------------------------------------------------------------------

/// The 8 corners of the cube [-1, 1]³: corner `i` has x, y, z = ±1 from bits 0, 1, 2.
fn cube_positions() -> Vec<[f32; 3]> {
    (0..8)
        .map(|i| {
            let c = |bit: u32| if i & (1 << bit) != 0 { 1.0 } else { -1.0 };
            [c(0), c(1), c(2)]
        })
        .collect()
}

/// 12 counter-clockwise (outward) triangles over [`cube_positions`].
const CUBE_INDICES: [u16; 36] = [
    0, 2, 1, 1, 2, 3, // -z
    4, 5, 6, 5, 7, 6, // +z
    0, 1, 4, 1, 5, 4, // -y
    2, 6, 3, 3, 6, 7, // +y
    0, 4, 2, 2, 4, 6, // -x
    1, 3, 5, 3, 7, 5, // +x
];

/// Positions (96 bytes) then u16 indices (72 bytes): 168 bytes.
fn cube_bin(positions: &[[f32; 3]]) -> Vec<u8> {
    let mut bin = bytemuck::cast_slice::<[f32; 3], u8>(positions).to_vec();
    bin.extend_from_slice(bytemuck::cast_slice(&CUBE_INDICES));
    bin
}

/// A glTF JSON document, built from top-level fields given as raw JSON; later fields replace
/// earlier ones with the same key.
#[derive(Clone)]
struct Doc(Vec<(&'static str, String)>);

impl Doc {
    /// One cube mesh ("Cube") in buffer 0 (`buffer` is the buffer object's JSON), placed by
    /// one node in the default scene.
    fn cube(buffer: &str) -> Self {
        Doc(vec![
            ("scene", "0".into()),
            ("scenes", r#"[{"nodes": [0]}]"#.into()),
            ("nodes", r#"[{"name": "CubeNode", "mesh": 0}]"#.into()),
            (
                "meshes",
                r#"[{"name": "Cube", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}]"#
                    .into(),
            ),
            ("buffers", format!("[{buffer}]")),
            (
                "bufferViews",
                r#"[{"buffer": 0, "byteOffset": 0, "byteLength": 96, "target": 34962},
                    {"buffer": 0, "byteOffset": 96, "byteLength": 72, "target": 34963}]"#
                    .into(),
            ),
            (
                "accessors",
                r#"[{"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3",
                     "min": [-1, -1, -1], "max": [1, 1, 1]},
                    {"bufferView": 1, "componentType": 5123, "count": 36, "type": "SCALAR"}]"#
                    .into(),
            ),
        ])
    }
    fn set(mut self, key: &'static str, value: impl Into<String>) -> Self {
        self.0.retain(|(k, _)| *k != key);
        self.0.push((key, value.into()));
        self
    }
    fn remove(mut self, key: &'static str) -> Self {
        self.0.retain(|(k, _)| *k != key);
        self
    }
    fn json(&self) -> String {
        let mut s = String::from(r#"{"asset": {"version": "2.0", "generator": "volshadow tests"}"#);
        for (k, v) in &self.0 {
            s.push_str(&format!(",\n\"{k}\": {v}"));
        }
        s.push('}');
        s
    }
}

/// Standard base64 with padding.
fn base64(data: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in data.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(char::from(ALPHABET[(n >> (18 - 6 * k)) as usize & 63]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

fn data_uri(bin: &[u8]) -> String {
    format!(
        r#"{{"uri": "data:application/octet-stream;base64,{}", "byteLength": {}}}"#,
        base64(bin),
        bin.len()
    )
}

// ---------------------------------------------------------------------------------------------
// Checks
// ---------------------------------------------------------------------------------------------

fn assert_mat_eq(got: Mat4, want: Mat4) {
    assert!(
        got.abs_diff_eq(want, 1e-6),
        "transform\n{got:?}\nexpected\n{want:?}"
    );
}

fn assert_cube(m: &GltfMesh) {
    assert_eq!(m.name.as_deref(), Some("Cube"));
    assert_eq!(m.mesh.positions().len(), 8);
    assert_eq!(m.mesh.triangle_count(), 12);
    assert!(m.mesh.is_closed(), "{:?}", m.mesh.summary());
    assert_eq!(m.mesh.summary().degenerate_triangles, 0);
    let want: Vec<u32> = CUBE_INDICES.iter().map(|&i| u32::from(i)).collect();
    assert_eq!(m.mesh.indices(), want.as_slice());
    assert_eq!(m.mesh.bounds(), (Vec3::splat(-1.0), Vec3::splat(1.0)));
}

/// The [`ErrorKind`] of an [`Error::Gltf`], checking that its message names `path`.
#[track_caller]
fn gltf_kind(result: volshadow::Result<Vec<GltfMesh>>, path: &str) -> ErrorKind {
    let error = match result {
        Ok(meshes) => panic!("expected Error::Gltf, loaded {} meshes", meshes.len()),
        Err(e) => e,
    };
    let message = error.to_string();
    assert!(message.contains(path), "{message}");
    match error {
        Error::Gltf(GltfError::Invalid {
            path: p,
            kind,
            problem,
            ..
        }) => {
            assert_eq!(p, path);
            assert!(!problem.is_empty());
            kind
        }
        other => panic!("expected Error::Gltf, got {other:?}"),
    }
}

fn path_str(p: &Path) -> String {
    p.display().to_string()
}

// ---------------------------------------------------------------------------------------------
// Loading
// ---------------------------------------------------------------------------------------------

#[test]
fn gltf_with_external_bin_cube() {
    let dir = tempfile::tempdir().unwrap();
    // The URI is percent-encoded: the file name has a space.
    dir.write("cube data.bin", cube_bin(&cube_positions()));
    let doc = Doc::cube(r#"{"uri": "cube%20data.bin", "byteLength": 168}"#);
    let path = dir.write("cube.gltf", doc.json());

    let meshes = gltf::load(&path).unwrap();
    assert_eq!(meshes.len(), 1);
    assert_cube(&meshes[0]);
    assert_mat_eq(meshes[0].transform, Mat4::IDENTITY);
    // Cube's triangles wind counter-clockwise seen from outside.
    let p = meshes[0].mesh.positions();
    for t in meshes[0].mesh.indices().chunks(3) {
        let (a, b, c) = (p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]);
        assert!((b - a).cross(c - a).dot(a + b + c) > 0.0);
    }
}

#[test]
fn glb_two_instances_under_a_parent() {
    let bin = cube_bin(&cube_positions());
    // Parent: translate (1, 2, 3), rotate 180° about z, scale 2. Child A translates (0, 0, 5);
    // child B has a matrix: rotate 90° about x, then translate (-3, 0, 0) (column-major).
    let doc = Doc::cube(r#"{"byteLength": 168}"#).set(
        "nodes",
        r#"[{"name": "Parent", "translation": [1, 2, 3], "rotation": [0, 0, 1, 0],
             "scale": [2, 2, 2], "children": [1, 2]},
            {"name": "A", "mesh": 0, "translation": [0, 0, 5]},
            {"name": "B", "mesh": 0,
             "matrix": [1, 0, 0, 0,  0, 0, 1, 0,  0, -1, 0, 0,  -3, 0, 0, 1]}]"#,
    );
    let bytes = glb(&doc.json(), &bin);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.write("instances.glb", &bytes);

    let meshes = gltf::load(&path).unwrap();
    assert_eq!(meshes.len(), 2);
    for m in &meshes {
        assert_cube(m);
    }
    let parent = Mat4::from_scale_rotation_translation(
        Vec3::splat(2.0),
        Quat::from_rotation_z(std::f32::consts::PI),
        Vec3::new(1.0, 2.0, 3.0),
    );
    let a = parent * Mat4::from_translation(Vec3::new(0.0, 0.0, 5.0));
    let b = parent
        * Mat4::from_translation(Vec3::new(-3.0, 0.0, 0.0))
        * Mat4::from_rotation_x(std::f32::consts::FRAC_PI_2);
    assert_mat_eq(meshes[0].transform, a);
    assert_mat_eq(meshes[1].transform, b);
    // The same, by hand: A's origin lands at (1, 2, 3) + 2 * (0, 0, 5); B maps +y to +z, then
    // the parent maps (-3, 0, 1) to (1 + 6, 2, 3 + 2).
    assert!(meshes[0]
        .transform
        .transform_point3(Vec3::ZERO)
        .abs_diff_eq(Vec3::new(1.0, 2.0, 13.0), 1e-6));
    assert!(meshes[1]
        .transform
        .transform_point3(Vec3::Y)
        .abs_diff_eq(Vec3::new(7.0, 2.0, 5.0), 1e-6));

    // The same bytes from memory.
    let from_memory = gltf::load_slice(&bytes).unwrap();
    assert_eq!(from_memory.len(), 2);
    for (m, n) in meshes.iter().zip(&from_memory) {
        assert_eq!(m.transform, n.transform);
        assert_eq!(m.mesh.positions(), n.mesh.positions());
        assert_eq!(m.mesh.indices(), n.mesh.indices());
    }
}

/// A `.glb` whose JSON chunk is followed by a chunk of unknown type (and no BIN chunk) loads:
/// readers must ignore unknown chunks (glTF 2.0, GLB file format). Was `Malformed`.
#[test]
fn glb_with_an_unknown_chunk_after_the_json_loads() {
    let doc = Doc::cube(&data_uri(&cube_bin(&cube_positions())));
    let mut bytes = glb(&doc.json(), &[0u8; 8]);
    let bin_type = bytes.len() - 8 - 4;
    bytes[bin_type..bin_type + 4].copy_from_slice(b"XTRA");
    let meshes = gltf::load_slice(&bytes).unwrap();
    assert_eq!(meshes.len(), 1);
    assert_cube(&meshes[0]);
}

#[test]
fn data_uri_gltf() {
    let doc = Doc::cube(&data_uri(&cube_bin(&cube_positions())))
        .set("nodes", r#"[{"mesh": 0, "scale": [1, 2, 3]}]"#);
    let meshes = gltf::load_slice(doc.json().as_bytes()).unwrap();
    assert_eq!(meshes.len(), 1);
    assert_cube(&meshes[0]);
    assert_mat_eq(
        meshes[0].transform,
        Mat4::from_scale(Vec3::new(1.0, 2.0, 3.0)),
    );

    // And from a file, with no other file next to it.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.write("embedded.gltf", doc.json());
    let from_file = gltf::load(&path).unwrap();
    assert_eq!(from_file.len(), 1);
    assert_cube(&from_file[0]);
}

/// A node that mirrors (scale -2, 1, 1: valid glTF, its triangles' winding reverses) loads
/// with a positive determinant, which occluders need (the mirrored transform loaded, then
/// `prepare` refused it naming neither node nor mesh): the same world triangles as the node
/// places, wound to face out (positive signed volume, where the node's transform on the
/// file's mesh gives the negative of the cube's).
#[test]
fn a_mirroring_node_loads_as_the_same_triangles_facing_out() {
    let doc = Doc::cube(&data_uri(&cube_bin(&cube_positions()))).set(
        "nodes",
        r#"[{"mesh": 0, "scale": [-2, 1, 1], "translation": [3, 0, 0]}]"#,
    );
    let meshes = gltf::load_slice(doc.json().as_bytes()).unwrap();
    assert_eq!(meshes.len(), 1);
    let m = &meshes[0];
    assert!(m.transform.determinant() > 0.0, "{:?}", m.transform);
    assert!(m.mesh.is_closed());
    let world = |t: Mat4, mesh: &volshadow::scene::Mesh| -> Vec<[Vec3; 3]> {
        mesh.indices()
            .chunks_exact(3)
            .map(|k| {
                k.iter()
                    .map(|&i| t.transform_point3(mesh.positions()[i as usize]))
            })
            .map(|mut v| [v.next().unwrap(), v.next().unwrap(), v.next().unwrap()])
            .collect()
    };
    let volume =
        |tris: &[[Vec3; 3]]| -> f32 { tris.iter().map(|[a, b, c]| a.dot(b.cross(*c)) / 6.0).sum() };
    let node = Mat4::from_scale_rotation_translation(
        Vec3::new(-2.0, 1.0, 1.0),
        volshadow::glam::Quat::IDENTITY,
        Vec3::new(3.0, 0.0, 0.0),
    );
    let placed = world(m.transform, &m.mesh);
    // The file's cube under the node's transform, each triangle as a sorted set of corners.
    let file_mesh = gltf::load_slice(
        Doc::cube(&data_uri(&cube_bin(&cube_positions())))
            .json()
            .as_bytes(),
    )
    .unwrap()
    .remove(0)
    .mesh;
    let as_written = world(node, &file_mesh);
    let key = |t: &[Vec3; 3]| {
        let mut k: Vec<[i32; 3]> = t
            .iter()
            .map(|v| (*v * 1000.0).round().as_ivec3().to_array())
            .collect();
        k.sort();
        k
    };
    let mut a: Vec<_> = placed.iter().map(key).collect();
    let mut b: Vec<_> = as_written.iter().map(key).collect();
    a.sort();
    b.sort();
    assert_eq!(a, b, "not the node's triangles");
    let (out, inverted) = (volume(&placed), volume(&as_written));
    println!("signed volume: loaded {out}, the node's transform on the file's winding {inverted}");
    assert!(
        (out - 16.0).abs() < 1e-3,
        "{out}: a 2·2·2 cube scaled by 2 in x faces out"
    );
    assert!((inverted + 16.0).abs() < 1e-3, "{inverted}");
}

#[test]
fn triangle_strip_and_fan() {
    // A tetrahedron as one indexed strip: 0 1 2 3 0 1 gives (0 1 2) (1 3 2) (2 3 0) (3 1 0).
    let tetra: [[f32; 3]; 4] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, -1.0],
    ];
    let strip: [u8; 6] = [0, 1, 2, 3, 0, 1];
    // A square fan: centre then four corners, not indexed.
    let fan: [[f32; 3]; 5] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, -1.0, 0.0],
    ];
    let mut bin = bytemuck::cast_slice::<[f32; 3], u8>(&tetra).to_vec(); // 0..48
    bin.extend_from_slice(&strip); // 48..54
    bin.extend_from_slice(&[0, 0]); // 54..56
    bin.extend_from_slice(bytemuck::cast_slice(&fan)); // 56..116
    let doc = Doc::cube(&data_uri(&bin))
        .set(
            "meshes",
            r#"[{"name": "Shapes", "primitives": [
                  {"attributes": {"POSITION": 0}, "indices": 1, "mode": 5},
                  {"attributes": {"POSITION": 2}, "mode": 0},
                  {"attributes": {"POSITION": 2}, "mode": 1},
                  {"attributes": {"POSITION": 2}, "mode": 6}]}]"#,
        )
        .set(
            "bufferViews",
            r#"[{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                {"buffer": 0, "byteOffset": 48, "byteLength": 6},
                {"buffer": 0, "byteOffset": 56, "byteLength": 60}]"#,
        )
        .set(
            "accessors",
            r#"[{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                 "min": [0, 0, -1], "max": [1, 1, 0]},
                {"bufferView": 1, "componentType": 5121, "count": 6, "type": "SCALAR"},
                {"bufferView": 2, "componentType": 5126, "count": 5, "type": "VEC3",
                 "min": [-1, -1, 0], "max": [1, 1, 0]}]"#,
        );
    let meshes = gltf::load_slice(doc.json().as_bytes()).unwrap();
    // The points and lines primitives are skipped.
    assert_eq!(meshes.len(), 2);

    let strip = &meshes[0].mesh;
    assert_eq!(meshes[0].name.as_deref(), Some("Shapes"));
    assert_eq!(strip.triangle_count(), 4);
    assert_eq!(strip.indices(), &[0, 1, 2, 1, 3, 2, 2, 3, 0, 3, 1, 0]);
    assert!(strip.is_closed(), "{:?}", strip.summary());

    let fan = &meshes[1].mesh;
    assert_eq!(fan.triangle_count(), 3);
    assert_eq!(fan.indices(), &[1, 2, 0, 2, 3, 0, 3, 4, 0]);
    let p = fan.positions();
    for t in fan.indices().chunks(3) {
        let n = (p[t[1] as usize] - p[t[0] as usize]).cross(p[t[2] as usize] - p[t[0] as usize]);
        assert!(n.z > 0.0, "fan winding flipped: {t:?}");
    }
}

#[test]
fn non_indexed_primitive_uses_vertices_in_order() {
    let positions = cube_positions();
    let soup: Vec<[f32; 3]> = CUBE_INDICES
        .iter()
        .map(|&i| positions[i as usize])
        .collect();
    let bin = bytemuck::cast_slice::<[f32; 3], u8>(&soup).to_vec();
    let doc = Doc::cube(&data_uri(&bin))
        .set(
            "meshes",
            r#"[{"primitives": [{"attributes": {"POSITION": 0}}]}]"#,
        )
        .set("bufferViews", r#"[{"buffer": 0, "byteLength": 432}]"#)
        .set(
            "accessors",
            r#"[{"bufferView": 0, "componentType": 5126, "count": 36, "type": "VEC3",
                 "min": [-1, -1, -1], "max": [1, 1, 1]}]"#,
        );
    let meshes = gltf::load_slice(doc.json().as_bytes()).unwrap();
    assert_eq!(meshes.len(), 1);
    let m = &meshes[0];
    assert_eq!(m.name, None);
    assert_eq!(m.mesh.triangle_count(), 12);
    assert_eq!(m.mesh.indices(), (0..36).collect::<Vec<u32>>().as_slice());
    // Welding by position closes the soup.
    assert!(m.mesh.is_closed());
}

#[test]
fn scene_selection() {
    let bin = data_uri(&cube_bin(&cube_positions()));
    let nodes = r#"[{"mesh": 0, "translation": [1, 0, 0]},
                    {"mesh": 0, "translation": [2, 0, 0], "children": [2]},
                    {"mesh": 0, "translation": [0, 3, 0]}]"#;
    let x = |meshes: &[GltfMesh]| -> Vec<Vec3> {
        meshes
            .iter()
            .map(|m| m.transform.transform_point3(Vec3::ZERO))
            .collect()
    };
    let base = Doc::cube(&bin).set("nodes", nodes).set(
        "scenes",
        r#"[{"nodes": [0]}, {"nodes": [1]}, {"nodes": [0, 1]}]"#,
    );

    // The default scene only.
    let doc = base.clone().set("scene", "1");
    let got = x(&gltf::load_slice(doc.json().as_bytes()).unwrap());
    assert_eq!(got, [Vec3::new(2.0, 0.0, 0.0), Vec3::new(2.0, 3.0, 0.0)]);

    // No default scene: every scene's roots, each node once.
    let doc = base.clone().remove("scene");
    let got = x(&gltf::load_slice(doc.json().as_bytes()).unwrap());
    assert_eq!(
        got,
        [
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(2.0, 3.0, 0.0)
        ]
    );

    // No scenes: every node without a parent.
    let doc = base.clone().remove("scene").remove("scenes");
    let got = x(&gltf::load_slice(doc.json().as_bytes()).unwrap());
    assert_eq!(
        got,
        [
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(2.0, 3.0, 0.0)
        ]
    );

    // No nodes at all: every mesh, untransformed.
    let doc = base.remove("scene").remove("scenes").remove("nodes");
    let meshes = gltf::load_slice(doc.json().as_bytes()).unwrap();
    assert_eq!(meshes.len(), 1);
    assert_eq!(meshes[0].transform, Mat4::IDENTITY);
}

#[test]
fn sparse_and_quantized_positions() {
    // Positions as normalized i8 (KHR_mesh_quantization): ±127 → ±1. Vertex 7 is stored as
    // zero and set to (1, 1, 1) by a sparse substitution.
    let mut quantized: Vec<i8> = cube_positions()
        .iter()
        .flat_map(|p| p.map(|c| (c * 127.0) as i8))
        .collect();
    quantized[21..24].fill(0);
    let mut bin: Vec<u8> = bytemuck::cast_slice(&quantized).to_vec(); // 0..24
    bin.extend_from_slice(bytemuck::cast_slice(&CUBE_INDICES)); // 24..96
    bin.push(7); // 96: sparse index (u8)
    bin.extend_from_slice(bytemuck::cast_slice(&[127i8, 127, 127])); // 97..100
    let doc = Doc::cube(&data_uri(&bin))
        .set("extensionsUsed", r#"["KHR_mesh_quantization"]"#)
        .set("extensionsRequired", r#"["KHR_mesh_quantization"]"#)
        .set(
            "bufferViews",
            r#"[{"buffer": 0, "byteOffset": 0, "byteLength": 24},
                {"buffer": 0, "byteOffset": 24, "byteLength": 72},
                {"buffer": 0, "byteOffset": 96, "byteLength": 1},
                {"buffer": 0, "byteOffset": 97, "byteLength": 3}]"#,
        )
        .set(
            "accessors",
            r#"[{"bufferView": 0, "componentType": 5120, "normalized": true, "count": 8,
                 "type": "VEC3", "min": [-127, -127, -127], "max": [127, 127, 127],
                 "sparse": {"count": 1,
                            "indices": {"bufferView": 2, "componentType": 5121},
                            "values": {"bufferView": 3}}},
                {"bufferView": 1, "componentType": 5123, "count": 36, "type": "SCALAR"}]"#,
        );
    let meshes = gltf::load_slice(doc.json().as_bytes()).unwrap();
    assert_eq!(meshes.len(), 1);
    assert_cube(&meshes[0]);
    let want: Vec<Vec3> = cube_positions().into_iter().map(Vec3::from).collect();
    assert_eq!(meshes[0].mesh.positions(), want.as_slice());

    // The sparse index names vertex 0 instead: vertex 0 moves to (1, 1, 1), vertex 7 stays 0.
    let mut moved = bin.clone();
    moved[96] = 0;
    let doc = doc.set("buffers", format!("[{}]", data_uri(&moved)));
    let meshes = gltf::load_slice(doc.json().as_bytes()).unwrap();
    assert_eq!(meshes[0].mesh.positions()[0], Vec3::ONE);
    assert_eq!(meshes[0].mesh.positions()[7], Vec3::ZERO);
}

// ---------------------------------------------------------------------------------------------
// Errors
// ---------------------------------------------------------------------------------------------

#[test]
fn error_not_a_gltf() {
    assert_eq!(
        gltf_kind(gltf::load_slice(b"PK\x03\x04 not a glTF"), "<memory>"),
        ErrorKind::NotGltf
    );
    assert_eq!(
        gltf_kind(gltf::load_slice(br#"{"name": "package.json"}"#), "<memory>"),
        ErrorKind::NotGltf
    );
    assert_eq!(
        gltf_kind(gltf::load_slice(b""), "<memory>"),
        ErrorKind::NotGltf
    );
    let dir = tempfile::tempdir().unwrap();
    let path = dir.write("notes.gltf", "just some text\n");
    assert_eq!(
        gltf_kind(gltf::load(&path), &path_str(&path)),
        ErrorKind::NotGltf
    );
    // A GLB with a valid magic and header whose JSON chunk is not JSON: malformed, and the
    // message says so (it said "neither binary glTF (no `glTF` magic) nor JSON").
    let bytes = glb("not json at all", &[]);
    match gltf::load_slice(&bytes) {
        Err(Error::Gltf(GltfError::Invalid { kind, problem, .. })) => {
            assert_eq!(kind, ErrorKind::Malformed, "{problem}");
            assert!(
                problem.contains("JSON chunk") && !problem.contains("magic"),
                "{problem}"
            );
        }
        other => panic!("{other:?}"),
    }
    // A file that does not exist at all.
    let path = dir.path().join("absent.gltf");
    assert_eq!(
        gltf_kind(gltf::load(&path), &path_str(&path)),
        ErrorKind::Io
    );
}

#[test]
fn error_truncated_glb() {
    let doc = Doc::cube(r#"{"byteLength": 168}"#);
    let bytes = glb(&doc.json(), &cube_bin(&cube_positions()));
    let dir = tempfile::tempdir().unwrap();
    let path = dir.write("cut.glb", &bytes[..bytes.len() - 40]);
    assert_eq!(
        gltf_kind(gltf::load(&path), &path_str(&path)),
        ErrorKind::Truncated
    );
    // Shorter than the 12-byte header.
    assert_eq!(
        gltf_kind(gltf::load_slice(&bytes[..10]), "<memory>"),
        ErrorKind::Truncated
    );
    // A BIN chunk shorter than the buffer's byteLength.
    let short = glb(&doc.json(), &cube_bin(&cube_positions())[..100]);
    assert_eq!(
        gltf_kind(gltf::load_slice(&short), "<memory>"),
        ErrorKind::Truncated
    );
    // A .gltf whose JSON is cut off.
    let json = Doc::cube(&data_uri(&cube_bin(&cube_positions()))).json();
    assert_eq!(
        gltf_kind(
            gltf::load_slice(&json.as_bytes()[..json.len() / 2]),
            "<memory>"
        ),
        ErrorKind::Truncated
    );
}

#[test]
fn error_missing_buffer_file() {
    let dir = tempfile::tempdir().unwrap();
    let doc = Doc::cube(r#"{"uri": "missing.bin", "byteLength": 168}"#);
    let path = dir.write("cube.gltf", doc.json());
    let err = gltf::load(&path).unwrap_err();
    assert!(err.to_string().contains("missing.bin"), "{err}");
    assert_eq!(
        gltf_kind(Err(err), &path_str(&path)),
        ErrorKind::MissingBuffer
    );
    // From memory there is no directory to look in.
    assert_eq!(
        gltf_kind(gltf::load_slice(doc.json().as_bytes()), "<memory>"),
        ErrorKind::MissingBuffer
    );
    // A .bin file shorter than the buffer's byteLength.
    dir.write("short.bin", &cube_bin(&cube_positions())[..160]);
    let doc = Doc::cube(r#"{"uri": "short.bin", "byteLength": 168}"#);
    let path = dir.write("short.gltf", doc.json());
    assert_eq!(
        gltf_kind(gltf::load(&path), &path_str(&path)),
        ErrorKind::Truncated
    );
}

#[test]
fn error_accessor_out_of_range() {
    let bin = data_uri(&cube_bin(&cube_positions()));
    // Nine positions in a 96-byte view.
    let doc = Doc::cube(&bin).set(
        "accessors",
        r#"[{"bufferView": 0, "componentType": 5126, "count": 9, "type": "VEC3",
             "min": [-1, -1, -1], "max": [1, 1, 1]},
            {"bufferView": 1, "componentType": 5123, "count": 36, "type": "SCALAR"}]"#,
    );
    assert_eq!(
        gltf_kind(gltf::load_slice(doc.json().as_bytes()), "<memory>"),
        ErrorKind::AccessorOutOfRange
    );
    // A byte offset that pushes the indices past their view.
    let doc = Doc::cube(&bin).set(
        "accessors",
        r#"[{"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3",
             "min": [-1, -1, -1], "max": [1, 1, 1]},
            {"bufferView": 1, "byteOffset": 2, "componentType": 5123, "count": 36,
             "type": "SCALAR"}]"#,
    );
    assert_eq!(
        gltf_kind(gltf::load_slice(doc.json().as_bytes()), "<memory>"),
        ErrorKind::AccessorOutOfRange
    );
    // A buffer view past the end of its buffer.
    let doc = Doc::cube(&bin).set(
        "bufferViews",
        r#"[{"buffer": 0, "byteOffset": 0, "byteLength": 96},
            {"buffer": 0, "byteOffset": 100, "byteLength": 72}]"#,
    );
    assert_eq!(
        gltf_kind(gltf::load_slice(doc.json().as_bytes()), "<memory>"),
        ErrorKind::AccessorOutOfRange
    );
    // A huge count must not allocate or overflow.
    let doc = Doc::cube(&bin).set(
        "accessors",
        r#"[{"bufferView": 0, "componentType": 5126, "count": 18446744073709551615,
             "type": "VEC3", "min": [-1, -1, -1], "max": [1, 1, 1]},
            {"bufferView": 1, "componentType": 5123, "count": 36, "type": "SCALAR"}]"#,
    );
    assert!(gltf::load_slice(doc.json().as_bytes()).is_err());
}

#[test]
fn error_index_out_of_range() {
    let mut bin = cube_bin(&cube_positions());
    // The last index (a u16 at the end) becomes 8, one past the last vertex.
    let n = bin.len();
    bin[n - 2..].copy_from_slice(&8u16.to_le_bytes());
    let doc = Doc::cube(&data_uri(&bin));
    assert_eq!(
        gltf_kind(gltf::load_slice(doc.json().as_bytes()), "<memory>"),
        ErrorKind::IndexOutOfRange
    );
}

#[test]
fn error_no_triangle_meshes() {
    let bin = data_uri(&cube_bin(&cube_positions()));
    // Only points and lines.
    let doc = Doc::cube(&bin).set(
        "meshes",
        r#"[{"primitives": [{"attributes": {"POSITION": 0}, "mode": 0},
                            {"attributes": {"POSITION": 0}, "indices": 1, "mode": 1}]}]"#,
    );
    let result = gltf::load_slice(doc.json().as_bytes());
    let message = result.as_ref().unwrap_err().to_string();
    assert!(message.contains("no triangle meshes"), "{message}");
    assert_eq!(gltf_kind(result, "<memory>"), ErrorKind::NoTriangleMeshes);
    // A scene whose nodes place no mesh.
    let doc = Doc::cube(&bin).set("nodes", r#"[{"name": "Empty"}]"#);
    assert_eq!(
        gltf_kind(gltf::load_slice(doc.json().as_bytes()), "<memory>"),
        ErrorKind::NoTriangleMeshes
    );
}

#[test]
fn error_non_finite_positions() {
    let mut positions = cube_positions();
    positions[3][1] = f32::NAN;
    let doc = Doc::cube(&data_uri(&cube_bin(&positions)));
    match gltf::load_slice(doc.json().as_bytes()) {
        Err(Error::Gltf(GltfError::Primitive {
            path,
            mesh: 0,
            primitive: 0,
            source,
            ..
        })) => {
            assert_eq!(path, "<memory>");
            assert!(
                matches!(*source, Error::NonFinitePosition { vertex: 3, .. }),
                "{source:?}"
            );
        }
        other => panic!("expected Error::GltfPrimitive, got {other:?}"),
    }
}

#[test]
fn error_invalid_transform() {
    let bin = data_uri(&cube_bin(&cube_positions()));
    let cases = [
        // Singular: a zero scale.
        r#"[{"mesh": 0, "scale": [1, 0, 1]}]"#,
        // Singular through the parent.
        r#"[{"scale": [0, 0, 0], "children": [1]}, {"mesh": 0}]"#,
        // Non-finite: 1e39 overflows f32.
        r#"[{"mesh": 0, "translation": [1e39, 0, 0]}]"#,
        r#"[{"mesh": 0, "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 1e39, 1]}]"#,
        // A zero quaternion.
        r#"[{"mesh": 0, "rotation": [0, 0, 0, 0]}]"#,
    ];
    for nodes in cases {
        let doc = Doc::cube(&bin).set("nodes", nodes);
        assert_eq!(
            gltf_kind(gltf::load_slice(doc.json().as_bytes()), "<memory>"),
            ErrorKind::InvalidTransform,
            "{nodes}"
        );
    }
    // A scale beyond f32 says so (it was "singular (determinant inf)").
    for (scale, way) in [("1e30", "overflows f32"), ("1e-30", "underflows f32")] {
        let nodes = format!(r#"[{{"mesh": 0, "scale": [{scale}, {scale}, {scale}]}}]"#);
        let doc = Doc::cube(&bin).set("nodes", &nodes);
        let e = gltf::load_slice(doc.json().as_bytes()).unwrap_err();
        match &e {
            Error::Gltf(volshadow::GltfError::Invalid { kind, problem, .. }) => {
                assert_eq!(*kind, ErrorKind::InvalidTransform, "{e}");
                assert!(
                    problem.contains(way) && !problem.contains("singular"),
                    "{e}"
                );
            }
            other => panic!("{scale}: {other:?}"),
        }
    }
    // A zero scale on a node that places nothing is harmless.
    let doc = Doc::cube(&bin)
        .set("nodes", r#"[{"mesh": 0}, {"scale": [0, 0, 0]}]"#)
        .set("scenes", r#"[{"nodes": [0, 1]}]"#);
    assert_eq!(gltf::load_slice(doc.json().as_bytes()).unwrap().len(), 1);
}

#[test]
fn error_malformed_structure() {
    let bin = data_uri(&cube_bin(&cube_positions()));
    let cases = [
        // A scene root that is a child (a cycle 0 → 1 → 0).
        Doc::cube(&bin).set(
            "nodes",
            r#"[{"mesh": 0, "children": [1]}, {"children": [0]}]"#,
        ),
        // A node with two parents.
        Doc::cube(&bin)
            .set(
                "nodes",
                r#"[{"children": [2]}, {"children": [2]}, {"mesh": 0}]"#,
            )
            .set("scenes", r#"[{"nodes": [0, 1]}]"#),
        // A node that is its own child.
        Doc::cube(&bin).set("nodes", r#"[{"mesh": 0, "children": [0]}]"#),
        // References to objects that do not exist.
        Doc::cube(&bin).set("nodes", r#"[{"mesh": 4}]"#),
        Doc::cube(&bin).set("scene", "3"),
        Doc::cube(&bin).set("scenes", r#"[{"nodes": [9]}]"#),
        Doc::cube(&bin).set(
            "meshes",
            r#"[{"primitives": [{"attributes": {"POSITION": 7}}]}]"#,
        ),
        Doc::cube(&bin).set("bufferViews", r#"[{"buffer": 2, "byteLength": 96}]"#),
        // Positions that are not VEC3.
        Doc::cube(&bin).set(
            "accessors",
            r#"[{"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC4",
                 "min": [-1, -1, -1, -1], "max": [1, 1, 1, 1]},
                {"bufferView": 1, "componentType": 5123, "count": 36, "type": "SCALAR"}]"#,
        ),
        // Bad base64.
        Doc::cube(r#"{"uri": "data:application/octet-stream;base64,AA*A", "byteLength": 3}"#),
        // No uri outside a .glb.
        Doc::cube(r#"{"byteLength": 168}"#),
    ];
    for doc in cases {
        assert_eq!(
            gltf_kind(gltf::load_slice(doc.json().as_bytes()), "<memory>"),
            ErrorKind::Malformed,
            "{}",
            doc.json()
        );
    }
}

#[test]
fn error_unsupported() {
    let bin = data_uri(&cube_bin(&cube_positions()));
    let draco = Doc::cube(&bin).set("extensionsRequired", r#"["KHR_draco_mesh_compression"]"#);
    let http = Doc::cube(r#"{"uri": "https://example.com/cube.bin", "byteLength": 168}"#);
    let v1 = Doc::cube(&bin);
    let v1 = v1
        .json()
        .replace(r#""version": "2.0""#, r#""version": "1.0""#);
    for json in [draco.json(), http.json(), v1] {
        assert_eq!(
            gltf_kind(gltf::load_slice(json.as_bytes()), "<memory>"),
            ErrorKind::Unsupported,
            "{json}"
        );
    }
}

/// Every prefix and many corruptions of a valid .glb load or fail, never panic.
#[test]
fn corrupted_glb_never_panics() {
    let doc = Doc::cube(r#"{"byteLength": 168}"#);
    let bytes = glb(&doc.json(), &cube_bin(&cube_positions()));
    assert_eq!(gltf::load_slice(&bytes).unwrap().len(), 1);
    for n in 0..bytes.len() {
        assert!(
            gltf::load_slice(&bytes[..n]).is_err(),
            "prefix of {n} bytes"
        );
    }
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    for _ in 0..3000 {
        let mut corrupt = bytes.clone();
        for _ in 0..1 + next() % 4 {
            let at = (next() % corrupt.len() as u64) as usize;
            corrupt[at] = next() as u8;
        }
        let _ = gltf::load_slice(&corrupt);
    }
}
