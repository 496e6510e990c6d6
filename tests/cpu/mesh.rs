//! Occluder meshes: validation errors, welded edge adjacency, and the procedural shapes.

use std::collections::HashSet;
use std::time::Instant;

use glam::{Vec2, Vec3};
use volshadow::scene::{shapes, Edge, Mesh};
use volshadow::Error;

fn tetrahedron() -> (Vec<Vec3>, Vec<u32>) {
    let positions = vec![
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(0.0, 0.0, 1.0),
    ];
    // Outward, counter-clockwise seen from outside.
    let indices = vec![0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3];
    (positions, indices)
}

/// A unit cube with 8 shared vertices (bit i of the index = the sign of axis i).
fn cube8() -> (Vec<Vec3>, Vec<u32>) {
    let positions = (0..8)
        .map(|i| Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32))
        .collect();
    #[rustfmt::skip]
    let indices = vec![
        0, 2, 3, 0, 3, 1, // -Z
        4, 5, 7, 4, 7, 6, // +Z
        0, 4, 6, 0, 6, 2, // -X
        1, 3, 7, 1, 7, 5, // +X
        0, 1, 5, 0, 5, 4, // -Y
        2, 6, 7, 2, 7, 3, // +Y
    ];
    (positions, indices)
}

fn tri_positions(mesh: &Mesh, face: u32) -> [Vec3; 3] {
    let i = &mesh.indices()[3 * face as usize..3 * face as usize + 3];
    [0, 1, 2].map(|k| mesh.positions()[i[k] as usize])
}

/// Whether `face` contains the directed edge a → b (by position).
fn has_directed(mesh: &Mesh, face: u32, a: Vec3, b: Vec3) -> bool {
    let t = tri_positions(mesh, face);
    (0..3).any(|k| t[k] == a && t[(k + 1) % 3] == b)
}

/// Checks the orientation rule on every edge: face0 has v0→v1 (by index), face1 has v1→v0
/// (by position).
fn check_orientation(mesh: &Mesh) {
    for e in mesh.edges() {
        let i = &mesh.indices()[3 * e.face0 as usize..3 * e.face0 as usize + 3];
        assert!(
            (0..3).any(|k| i[k] == e.v0 && i[(k + 1) % 3] == e.v1),
            "{e:?}: face0 lacks v0->v1"
        );
        if let Some(f1) = e.face1 {
            assert_ne!(f1, e.face0);
            let (a, b) = (
                mesh.positions()[e.v0 as usize],
                mesh.positions()[e.v1 as usize],
            );
            assert!(has_directed(mesh, f1, b, a), "{e:?}: face1 lacks v1->v0");
        }
    }
}

/// Distinct referenced positions (welded vertex count).
fn welded_vertices(mesh: &Mesh) -> usize {
    mesh.indices()
        .iter()
        .map(|&i| mesh.positions()[i as usize].to_array().map(f32::to_bits))
        .collect::<HashSet<_>>()
        .len()
}

fn euler(mesh: &Mesh) -> i64 {
    let s = mesh.summary();
    welded_vertices(mesh) as i64 - s.edges as i64 + (s.triangles - s.degenerate_triangles) as i64
}

/// Volume enclosed by the mesh via the divergence theorem: positive for outward winding.
fn signed_volume(mesh: &Mesh) -> f64 {
    (0..mesh.triangle_count() as u32)
        .map(|f| {
            let [a, b, c] = tri_positions(mesh, f).map(|p| p.as_dvec3());
            a.dot(b.cross(c)) / 6.0
        })
        .sum()
}

fn assert_closed(name: &str, mesh: &Mesh, euler_char: i64, volume: f64, volume_tol: f64) {
    let s = mesh.summary();
    println!("{name}: {s}; V-E+F = {}", euler(mesh));
    assert!(mesh.is_closed(), "{name}: {s}");
    assert_eq!(s.boundary_edges, 0, "{name}");
    assert_eq!(s.non_manifold_edges, 0, "{name}");
    assert_eq!(s.degenerate_triangles, 0, "{name}");
    assert!(mesh.edges().iter().all(|e| e.face1.is_some()), "{name}");
    assert_eq!(
        2 * s.edges,
        3 * s.triangles,
        "{name}: every edge has two faces"
    );
    assert_eq!(euler(mesh), euler_char, "{name}: Euler characteristic");
    check_orientation(mesh);
    let v = signed_volume(mesh);
    println!("{name}: signed volume {v:.5}, expected ≈ {volume:.5}");
    assert!(v > 0.0, "{name}: winding must be outward, volume {v}");
    assert!(
        ((v - volume) / volume).abs() < volume_tol,
        "{name}: volume {v} vs {volume}"
    );
}

// ---- errors ------------------------------------------------------------------------------

#[test]
fn empty_mesh_is_an_error() {
    let (p, i) = tetrahedron();
    assert_eq!(
        Mesh::new(&[], &i).unwrap_err(),
        Error::EmptyMesh {
            positions: 0,
            indices: 12
        }
    );
    assert_eq!(
        Mesh::new(&p, &[]).unwrap_err(),
        Error::EmptyMesh {
            positions: 4,
            indices: 0
        }
    );
}

#[test]
fn index_count_not_multiple_of_3_is_an_error() {
    let (p, _) = tetrahedron();
    assert_eq!(
        Mesh::new(&p, &[0, 1, 2, 3]).unwrap_err(),
        Error::IndexCountNotMultipleOf3 { count: 4 }
    );
}

#[test]
fn index_out_of_range_is_an_error() {
    let (p, mut i) = tetrahedron();
    i[7] = 4;
    let err = Mesh::new(&p, &i).unwrap_err();
    println!("{err}");
    assert_eq!(
        err,
        Error::IndexOutOfRange {
            position: 7,
            index: 4,
            vertex_count: 4
        }
    );
}

#[test]
fn non_finite_position_is_an_error() {
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        let (mut p, i) = tetrahedron();
        p[2].y = bad;
        let err = Mesh::new(&p, &i).unwrap_err();
        assert!(
            matches!(err, Error::NonFinitePosition { vertex: 2, position } if position.x == 0.0 && !position.y.is_finite()),
            "{err:?}"
        );
    }
}

#[test]
fn all_degenerate_is_an_error() {
    let p = [Vec3::ZERO, Vec3::X, Vec3::splat(2.0) * Vec3::X, Vec3::ZERO];
    // Collinear corners, a repeated index, and two distinct vertices at the same position.
    let i = [0, 1, 2, 1, 1, 2, 0, 3, 1];
    assert_eq!(
        Mesh::new(&p, &i).unwrap_err(),
        Error::DegenerateMesh { triangles: 3 }
    );
}

#[test]
fn too_large_is_an_error() {
    // Zeroed allocations are lazily committed, and the size check comes before any read.
    let indices = vec![0u32; 3 * (Mesh::MAX_TRIANGLES + 1)];
    assert_eq!(
        Mesh::new(&[Vec3::ZERO], &indices).unwrap_err(),
        Error::MeshTooLarge {
            field: "triangles",
            count: Mesh::MAX_TRIANGLES + 1,
            max: Mesh::MAX_TRIANGLES
        }
    );
}

// ---- adjacency ---------------------------------------------------------------------------

#[test]
fn tetrahedron_adjacency() {
    let (p, i) = tetrahedron();
    let (p0, i0) = (p.clone(), i.clone());
    let mesh = Mesh::new(&p, &i).unwrap();
    assert_eq!((p, i), (p0.clone(), i0.clone()), "caller's data unchanged");
    assert_eq!(mesh.positions(), &p0[..]);
    assert_eq!(mesh.indices(), &i0[..]);
    assert_eq!(mesh.triangle_count(), 4);
    assert_eq!(mesh.edges().len(), 6);
    assert_eq!(mesh.bounds(), (Vec3::ZERO, Vec3::ONE));
    assert_closed("tetrahedron", &mesh, 2, 1.0 / 6.0, 1e-6);
    // Faces 0 (0 2 1) and 1 (0 1 3) share 0-1: face 0 has 1→0, face 1 has 0→1.
    let e01 = mesh
        .edges()
        .iter()
        .find(|e| (e.v0.min(e.v1), e.v0.max(e.v1)) == (0, 1))
        .unwrap();
    assert_eq!(
        *e01,
        Edge {
            v0: 1,
            v1: 0,
            face0: 0,
            face1: Some(1)
        }
    );
}

#[test]
fn cube_adjacency_shared_and_welded() {
    let (p, i) = cube8();
    let mesh = Mesh::new(&p, &i).unwrap();
    assert_eq!(mesh.edges().len(), 18);
    assert_closed("cube (8 vertices)", &mesh, 2, 1.0, 1e-6);

    // Fully unindexed (triangle soup, 36 vertices): welding makes it the same closed cube,
    // while the mesh keeps the 36 positions for rendering.
    let soup: Vec<Vec3> = i.iter().map(|&k| p[k as usize]).collect();
    let soup_indices: Vec<u32> = (0..soup.len() as u32).collect();
    let mesh = Mesh::new(&soup, &soup_indices).unwrap();
    assert_eq!(mesh.positions().len(), 36);
    assert_eq!(mesh.edges().len(), 18);
    assert_closed("cube (soup)", &mesh, 2, 1.0, 1e-6);
}

#[test]
fn negative_zero_welds_with_zero() {
    let (mut p, i) = tetrahedron();
    // Duplicate vertex 0 as -0.0 and use it in one face.
    p.push(Vec3::new(-0.0, 0.0, -0.0));
    let mut i2 = i.clone();
    i2[3] = 4;
    let mesh = Mesh::new(&p, &i2).unwrap();
    assert!(mesh.is_closed(), "{}", mesh.summary());
}

#[test]
fn degenerate_triangles_are_dropped_and_counted() {
    let (mut p, mut i) = tetrahedron();
    p.push(Vec3::new(0.5, 0.0, 0.0)); // on edge 0-1
    i.extend_from_slice(&[0, 0, 1, 0, 4, 1, 2, 3, 2]);
    let mesh = Mesh::new(&p, &i).unwrap();
    let s = mesh.summary();
    println!("tetrahedron + 3 degenerate: {s}");
    assert_eq!(s.triangles, 7);
    assert_eq!(s.degenerate_triangles, 3);
    assert_eq!(mesh.triangle_count(), 7);
    assert_eq!(
        mesh.indices().len(),
        21,
        "degenerate triangles kept for rendering"
    );
    assert!(mesh.is_closed());
    assert_eq!(s.edges, 6);
}

#[test]
fn non_manifold_edge_emits_one_edge_per_face() {
    // Three triangles fanned around the edge 0-1 (a "book" with three pages).
    let p = [
        Vec3::ZERO,
        Vec3::Y,
        Vec3::X,
        Vec3::Z,
        Vec3::new(-1.0, 0.0, -1.0),
    ];
    let i = [0, 1, 2, 1, 0, 3, 0, 1, 4];
    let mesh = Mesh::new(&p, &i).unwrap();
    let s = mesh.summary();
    println!("three-page book: {s}");
    assert_eq!(s.non_manifold_edges, 1);
    assert_eq!(s.boundary_edges, 6);
    assert_eq!(s.edges, 9);
    assert!(!mesh.is_closed());
    let spine: Vec<&Edge> = mesh
        .edges()
        .iter()
        .filter(|e| (e.v0.min(e.v1), e.v0.max(e.v1)) == (0, 1))
        .collect();
    assert_eq!(spine.len(), 3);
    assert!(spine.iter().all(|e| e.face1.is_none()));
    let mut faces: Vec<u32> = spine.iter().map(|e| e.face0).collect();
    faces.sort();
    assert_eq!(faces, [0, 1, 2]);
    check_orientation(&mesh);
    assert!(mesh.edges().iter().all(|e| e.face1.is_none()));

    // Two faces with the same orientation of a shared edge are non-manifold too.
    let mesh = Mesh::new(&p, &[0, 1, 2, 0, 1, 3]).unwrap();
    let s = mesh.summary();
    assert_eq!((s.non_manifold_edges, s.boundary_edges, s.edges), (1, 4, 6));
}

#[test]
fn summary_display_is_one_line() {
    let (p, i) = tetrahedron();
    let text = Mesh::new(&p, &i).unwrap().summary().to_string();
    println!("{text}");
    assert_eq!(
        text,
        "4 triangles (0 degenerate), 6 edges (0 boundary, 0 non-manifold)"
    );
}

// ---- shapes ------------------------------------------------------------------------------

#[test]
fn closed_shapes_are_closed_and_outward() {
    use std::f64::consts::PI;
    let c = Vec3::new(1.0, -2.0, 3.0);
    let sphere = shapes::uv_sphere(c, 2.0, 48, 24).unwrap();
    assert_eq!(sphere.triangle_count(), 2 * 48 * 23);
    assert_closed("uv_sphere", &sphere, 2, 4.0 / 3.0 * PI * 8.0, 0.02);
    let (lo, hi) = sphere.bounds();
    assert!(
        (lo - (c - 2.0)).abs().max_element() < 1e-5 && (hi - (c + 2.0)).abs().max_element() < 1e-5
    );

    let cuboid = shapes::cuboid(c, Vec3::new(0.5, 1.0, 2.0)).unwrap();
    assert_eq!(cuboid.positions().len(), 24);
    assert_eq!(cuboid.edges().len(), 18);
    assert_eq!(
        cuboid.bounds(),
        (c - Vec3::new(0.5, 1.0, 2.0), c + Vec3::new(0.5, 1.0, 2.0))
    );
    assert_closed("cuboid", &cuboid, 2, 8.0, 1e-6);

    let torus = shapes::torus(c, 2.0, 0.5, 48, 24).unwrap();
    assert_closed("torus", &torus, 0, 2.0 * PI * PI * 2.0 * 0.25, 0.02);
    let (lo, hi) = torus.bounds();
    assert!((hi.y - lo.y - 1.0).abs() < 1e-5, "torus axis is +Y");

    // Tube volume ≈ π w² × helix length.
    let (r, w, turns, h) = (1.0f64, 0.15, 3.5, 2.0);
    let length = ((2.0 * PI * r * turns).powi(2) + h * h).sqrt();
    let spring =
        shapes::helix_spring(c, r as f32, w as f32, turns as f32, h as f32, 32, 24).unwrap();
    assert_closed("helix_spring", &spring, 2, PI * w * w * length, 0.05);
    let (lo, hi) = spring.bounds();
    assert!((hi.y - lo.y) as f64 > h && ((hi.y - lo.y) as f64) < h + 2.0 * w + 1e-4);
}

#[test]
fn open_shapes_have_boundaries() {
    for segments in [3, 17, 64] {
        let cyl = shapes::cylinder_open(Vec3::ZERO, 1.0, 2.0, segments).unwrap();
        let s = cyl.summary();
        println!("cylinder_open({segments}): {s}");
        assert_eq!(s.boundary_edges, 2 * segments as usize);
        assert_eq!(s.non_manifold_edges, 0);
        assert_eq!(s.edges, 4 * segments as usize);
        assert!(!cyl.is_closed());
        check_orientation(&cyl);
        // Outward: the first face's normal points away from the axis.
        let [a, b, cc] = tri_positions(&cyl, 0);
        let n = (b - a).cross(cc - a);
        let mid = (a + b + cc) / 3.0;
        assert!(n.dot(Vec3::new(mid.x, 0.0, mid.z)) > 0.0);
    }

    let plane = shapes::plane(Vec3::new(0.0, 1.0, 0.0), Vec2::new(2.0, 3.0)).unwrap();
    let s = plane.summary();
    println!("plane: {s}");
    assert_eq!((s.triangles, s.edges, s.boundary_edges), (2, 5, 4));
    check_orientation(&plane);
    for f in 0..2 {
        let [a, b, c] = tri_positions(&plane, f);
        let n = (b - a).cross(c - a);
        assert!(n.normalize().abs_diff_eq(Vec3::Y, 1e-6), "faces +Y: {n}");
    }
    assert_eq!(
        plane.bounds(),
        (Vec3::new(-2.0, 1.0, -3.0), Vec3::new(2.0, 1.0, 3.0))
    );
}

#[test]
fn hundred_thousand_triangles_build_closed_and_welded() {
    let (segments, rings) = (317, 159);
    let start = Instant::now();
    let sphere = shapes::uv_sphere(Vec3::ZERO, 1.0, segments, rings).unwrap();
    let shape_time = start.elapsed();
    // Time Mesh::new alone on a triangle soup (the worst case for welding).
    let soup: Vec<Vec3> = sphere
        .indices()
        .iter()
        .map(|&k| sphere.positions()[k as usize])
        .collect();
    let soup_indices: Vec<u32> = (0..soup.len() as u32).collect();
    let start = Instant::now();
    let mesh = Mesh::new(&soup, &soup_indices).unwrap();
    let new_time = start.elapsed();
    println!(
        "uv_sphere({segments}, {rings}): {} triangles, shape {:.1} ms; Mesh::new on the {}-vertex soup {:.1} ms; {}",
        sphere.triangle_count(),
        shape_time.as_secs_f64() * 1e3,
        soup.len(),
        new_time.as_secs_f64() * 1e3,
        mesh.summary()
    );
    assert!(sphere.triangle_count() >= 100_000);
    assert!(sphere.is_closed() && mesh.is_closed());
    assert_eq!(mesh.edges().len(), sphere.edges().len());
    // No wall-clock bound: the times are printed; quadratic welding would take minutes and
    // show in the suite's run time, not as a flaky assertion on a shared machine.
}
