//! Procedural occluder meshes for tests and examples.
//!
//! Every shape winds its triangles counter-clockwise seen from outside (right-handed, outward
//! normals), and the closed ones ([`uv_sphere`], [`cuboid`], [`torus`], [`helix_spring`]) are
//! closed under [`Mesh`]'s adjacency: no boundary and no non-manifold edges. [`cylinder_open`]
//! and [`plane`] are open.
//!
//! Invalid parameters are errors, never panics: [`Error::NonFinite`] for a non-finite value,
//! [`Error::InvalidSetting`] for a length that is not positive or a segment count too small,
//! and [`Mesh::new`]'s errors for a mesh beyond [`Mesh::MAX_TRIANGLES`] or one that f32
//! rounding collapses.

use std::f32::consts::TAU;

use glam::{Vec2, Vec3};

use super::Mesh;
use crate::error::{finite, Error, Result};

fn check_positive(field: &'static str, value: f32) -> Result<()> {
    finite(field, &[value])?;
    if value > 0.0 {
        return Ok(());
    }
    Err(Error::InvalidSetting {
        field,
        problem: format!("must be > 0, got {value}"),
    })
}

fn check_segments(field: &'static str, value: u32, min: u32) -> Result<()> {
    if value >= min {
        return Ok(());
    }
    Err(Error::InvalidSetting {
        field,
        problem: format!("must be at least {min}, got {value}"),
    })
}

/// A mesh of at most [`Mesh::MAX_TRIANGLES`] `triangles`, checked before it is built.
fn check_size(triangles: u64) -> Result<()> {
    if triangles <= Mesh::MAX_TRIANGLES as u64 {
        return Ok(());
    }
    Err(Error::MeshTooLarge {
        field: "triangles",
        count: usize::try_from(triangles).unwrap_or(usize::MAX),
        max: Mesh::MAX_TRIANGLES,
    })
}

/// Pushes the two triangles of the quad `a b c d` (counter-clockwise seen from its front).
fn quad(indices: &mut Vec<u32>, a: u32, b: u32, c: u32, d: u32) {
    indices.extend_from_slice(&[a, b, c, a, c, d]);
}

/// A UV sphere of `radius` around `center`: `segments` vertices around each ring of latitude
/// (≥ 3), `rings` bands from pole to pole (≥ 2), and one vertex at each pole. The seam shares
/// its vertices, so the mesh is closed; `2 · segments · (rings − 1)` triangles.
///
/// # Errors
/// If `center` is not finite, `radius` is not finite and positive, `segments < 3` or
/// `rings < 2`, or the mesh would exceed [`Mesh::MAX_TRIANGLES`].
pub fn uv_sphere(center: Vec3, radius: f32, segments: u32, rings: u32) -> Result<Mesh> {
    finite("center", &center.to_array())?;
    check_positive("radius", radius)?;
    check_segments("segments", segments, 3)?;
    check_segments("rings", rings, 2)?;
    check_size(2 * u64::from(segments) * u64::from(rings - 1))?;
    let (s, r) = (segments, rings);
    // Vertex 0: north pole; then rings 1..r of `s` vertices; last: south pole.
    let mut positions = Vec::with_capacity((s * (r - 1) + 2) as usize);
    positions.push(center + Vec3::Y * radius);
    for i in 1..r {
        let theta = std::f32::consts::PI * i as f32 / r as f32;
        let (st, ct) = theta.sin_cos();
        for j in 0..s {
            let (sp, cp) = (TAU * j as f32 / s as f32).sin_cos();
            positions.push(center + radius * Vec3::new(st * cp, ct, st * sp));
        }
    }
    let south = positions.len() as u32;
    positions.push(center - Vec3::Y * radius);
    // Ring `i` (1-based), segment `j` (wrapping).
    let v = |i: u32, j: u32| 1 + (i - 1) * s + j % s;
    let mut indices = Vec::with_capacity(6 * (s * (r - 1)) as usize);
    for j in 0..s {
        indices.extend_from_slice(&[0, v(1, j + 1), v(1, j)]);
        indices.extend_from_slice(&[south, v(r - 1, j), v(r - 1, j + 1)]);
    }
    for i in 1..r - 1 {
        for j in 0..s {
            quad(
                &mut indices,
                v(i, j),
                v(i, j + 1),
                v(i + 1, j + 1),
                v(i + 1, j),
            );
        }
    }
    Mesh::new(&positions, &indices)
}

/// An axis-aligned box around `center` with half-extents `half_extents` (all > 0): 12
/// triangles over 24 vertices (4 per face, as a flat-shaded model would have them); the corners
/// are welded by position, so the mesh is closed.
///
/// # Errors
/// If `center` is not finite or a half-extent is not finite and positive.
pub fn cuboid(center: Vec3, half_extents: Vec3) -> Result<Mesh> {
    finite("center", &center.to_array())?;
    for (name, h) in ["half_extents.x", "half_extents.y", "half_extents.z"]
        .into_iter()
        .zip(half_extents.to_array())
    {
        check_positive(name, h)?;
    }
    // (normal, t1, t2) with t1 × t2 = normal, so (−,−) (+,−) (+,+) (−,+) is counter-clockwise.
    let faces = [
        (Vec3::X, Vec3::Y, Vec3::Z),
        (Vec3::NEG_X, Vec3::Z, Vec3::Y),
        (Vec3::Y, Vec3::Z, Vec3::X),
        (Vec3::NEG_Y, Vec3::X, Vec3::Z),
        (Vec3::Z, Vec3::X, Vec3::Y),
        (Vec3::NEG_Z, Vec3::Y, Vec3::X),
    ];
    let mut positions = Vec::with_capacity(24);
    let mut indices = Vec::with_capacity(36);
    for (n, t1, t2) in faces {
        let base = positions.len() as u32;
        for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            // Signs are exactly ±1 per axis, so a corner shared by three faces gets the same bits.
            positions.push(center + half_extents * (n + a * t1 + b * t2));
        }
        quad(&mut indices, base, base + 1, base + 2, base + 3);
    }
    Mesh::new(&positions, &indices)
}

/// A torus around `center` with its axis along +Y (lying in the XZ plane): the tube's centre
/// circle has radius `major_radius`, the tube radius `minor_radius` (0 < minor < major).
/// `major_segments` around the axis, `minor_segments` around the tube (each ≥ 3); both seams
/// share vertices, so the mesh is closed (genus 1).
///
/// # Errors
/// If `center` is not finite, the radii are not finite and positive with
/// `minor_radius < major_radius`, a segment count is below 3, or the mesh would exceed
/// [`Mesh::MAX_TRIANGLES`].
pub fn torus(
    center: Vec3,
    major_radius: f32,
    minor_radius: f32,
    major_segments: u32,
    minor_segments: u32,
) -> Result<Mesh> {
    finite("center", &center.to_array())?;
    check_positive("major_radius", major_radius)?;
    check_positive("minor_radius", minor_radius)?;
    if minor_radius >= major_radius {
        return Err(Error::InvalidSetting {
            field: "torus.minor_radius",
            problem: format!("must be below major_radius ({major_radius}), got {minor_radius}"),
        });
    }
    check_segments("major_segments", major_segments, 3)?;
    check_segments("minor_segments", minor_segments, 3)?;
    check_size(2 * u64::from(major_segments) * u64::from(minor_segments))?;
    let (m, n) = (major_segments, minor_segments);
    let mut positions = Vec::with_capacity((m * n) as usize);
    for i in 0..m {
        let (su, cu) = (TAU * i as f32 / m as f32).sin_cos();
        for j in 0..n {
            let (sv, cv) = (TAU * j as f32 / n as f32).sin_cos();
            let ring = major_radius + minor_radius * cv;
            positions.push(center + Vec3::new(ring * cu, minor_radius * sv, ring * su));
        }
    }
    let v = |i: u32, j: u32| (i % m) * n + j % n;
    let mut indices = Vec::with_capacity(6 * (m * n) as usize);
    for i in 0..m {
        for j in 0..n {
            quad(
                &mut indices,
                v(i, j),
                v(i, j + 1),
                v(i + 1, j + 1),
                v(i + 1, j),
            );
        }
    }
    Mesh::new(&positions, &indices)
}

/// An open cylinder (a tube without caps) around `center`, axis +Y, from `y = −half_height` to
/// `+half_height`, with `segments` (≥ 3) quads around. Open: two boundary loops of `segments`
/// edges each.
///
/// # Errors
/// If `center` is not finite, `radius` or `half_height` is not finite and positive, or
/// `segments < 3`.
pub fn cylinder_open(center: Vec3, radius: f32, half_height: f32, segments: u32) -> Result<Mesh> {
    finite("center", &center.to_array())?;
    check_positive("radius", radius)?;
    check_positive("half_height", half_height)?;
    check_segments("segments", segments, 3)?;
    check_size(2 * u64::from(segments))?;
    let s = segments;
    // Vertex 2j: bottom, 2j + 1: top.
    let mut positions = Vec::with_capacity(2 * s as usize);
    for j in 0..s {
        let (sp, cp) = (TAU * j as f32 / s as f32).sin_cos();
        let rim = center + radius * Vec3::new(cp, 0.0, sp);
        positions.push(rim - Vec3::Y * half_height);
        positions.push(rim + Vec3::Y * half_height);
    }
    let mut indices = Vec::with_capacity(6 * s as usize);
    for j in 0..s {
        let (b0, t0) = (2 * j, 2 * j + 1);
        let (b1, t1) = (2 * ((j + 1) % s), 2 * ((j + 1) % s) + 1);
        quad(&mut indices, b0, t0, t1, b1);
    }
    Mesh::new(&positions, &indices)
}

/// A coil spring: a tube of radius `wire_radius` (`wire_segments` ≥ 3 around it) swept along a
/// helix of radius `coil_radius` around the +Y axis through `center`, making `turns` (> 0,
/// fractional allowed) counter-clockwise turns seen from +Y while rising from
/// `y = −height/2` to `+height/2`, with `segments_per_turn` (≥ 3) rings per turn.
///
/// Both ends are **closed** with flat caps (a triangle fan around the end point), so the mesh is
/// closed, topologically a sphere. The tube intersects itself when `wire_radius` is not below
/// `coil_radius` or half the pitch `height / turns`; that is not checked.
///
/// # Errors
/// If `center` is not finite, `coil_radius`, `wire_radius`, `turns` or `height` is not finite
/// and positive, a segment count is below 3, or the mesh would exceed [`Mesh::MAX_TRIANGLES`].
pub fn helix_spring(
    center: Vec3,
    coil_radius: f32,
    wire_radius: f32,
    turns: f32,
    height: f32,
    segments_per_turn: u32,
    wire_segments: u32,
) -> Result<Mesh> {
    finite("center", &center.to_array())?;
    check_positive("coil_radius", coil_radius)?;
    check_positive("wire_radius", wire_radius)?;
    check_positive("turns", turns)?;
    check_positive("height", height)?;
    check_segments("segments_per_turn", segments_per_turn, 3)?;
    check_segments("wire_segments", wire_segments, 3)?;
    let steps = ((turns * segments_per_turn as f32).ceil() as u64).max(1);
    check_size(2 * (steps + 1) * u64::from(wire_segments))?;
    let steps = steps as u32;
    let w = wire_segments;
    let end_angle = TAU * turns;
    // Along the helix: p(t) = (R cos t, −h/2 + h t / T, R sin t). The radial direction r(t) is
    // perpendicular to the tangent; the frame (r, b = tangent × r, tangent) is right-handed.
    let frame = |k: u32| {
        let t = end_angle * k as f32 / steps as f32;
        let (st, ct) = t.sin_cos();
        let point = center
            + Vec3::new(
                coil_radius * ct,
                height * (t / end_angle - 0.5),
                coil_radius * st,
            );
        let tangent =
            Vec3::new(-coil_radius * st, height / end_angle, coil_radius * ct).normalize();
        let radial = Vec3::new(ct, 0.0, st);
        (point, radial, tangent.cross(radial), tangent)
    };
    let mut positions = Vec::with_capacity(((steps + 1) * w + 2) as usize);
    for k in 0..=steps {
        let (point, radial, binormal, _) = frame(k);
        for j in 0..w {
            let (sp, cp) = (TAU * j as f32 / w as f32).sin_cos();
            positions.push(point + wire_radius * (cp * radial + sp * binormal));
        }
    }
    let start_cap = positions.len() as u32;
    positions.push(frame(0).0);
    let end_cap = positions.len() as u32;
    positions.push(frame(steps).0);
    let v = |k: u32, j: u32| k * w + j % w;
    let mut indices = Vec::with_capacity((6 * steps * w + 6 * w) as usize);
    for k in 0..steps {
        for j in 0..w {
            // Increasing j turns counter-clockwise about the tangent, so (j, k) order faces out.
            quad(
                &mut indices,
                v(k, j),
                v(k, j + 1),
                v(k + 1, j + 1),
                v(k + 1, j),
            );
        }
    }
    for j in 0..w {
        // The start cap faces −tangent, the end cap +tangent.
        indices.extend_from_slice(&[start_cap, v(0, j + 1), v(0, j)]);
        indices.extend_from_slice(&[end_cap, v(steps, j), v(steps, j + 1)]);
    }
    Mesh::new(&positions, &indices)
}

/// A flat rectangle in the XZ plane through `center`, facing +Y (counter-clockwise seen from
/// above), spanning `±half_size.x` along X and `±half_size.y` along Z: two triangles, open
/// (4 boundary edges).
///
/// # Errors
/// If `center` is not finite or a component of `half_size` is not finite and positive.
pub fn plane(center: Vec3, half_size: Vec2) -> Result<Mesh> {
    finite("center", &center.to_array())?;
    check_positive("half_size.x", half_size.x)?;
    check_positive("half_size.y", half_size.y)?;
    let (x, z) = (half_size.x, half_size.y);
    let positions = [
        center + Vec3::new(-x, 0.0, -z),
        center + Vec3::new(x, 0.0, -z),
        center + Vec3::new(x, 0.0, z),
        center + Vec3::new(-x, 0.0, z),
    ];
    Mesh::new(&positions, &[0, 3, 2, 0, 2, 1])
}

/// A fence: `posts` boxes of half-extents `half` in a row along X, `spacing` apart centre to
/// centre, around `center` (the centre of the row); with `rail`, two horizontal rails at 30% and
/// 75% of the post height, slightly narrower than the posts. All boxes merged into one mesh.
///
/// # Errors
/// As [`cuboid`], and if `posts` is 0 or `spacing` is not finite and positive.
pub fn fence(center: Vec3, posts: u32, spacing: f32, half: Vec3, rail: bool) -> Result<Mesh> {
    check_segments("posts", posts, 1)?;
    check_positive("spacing", spacing)?;
    check_size(12 * (u64::from(posts) + 2))?;
    let mut boxes: Vec<(Vec3, Vec3)> = (0..posts)
        .map(|k| {
            let x = (k as f32 - 0.5 * (posts - 1) as f32) * spacing;
            (center + Vec3::X * x, half)
        })
        .collect();
    if rail && posts > 1 {
        let run = 0.5 * (posts - 1) as f32 * spacing;
        let rail_half = Vec3::new(run + 0.5 * half.x, 0.6 * half.x.min(half.y), 0.5 * half.z);
        for fraction in [0.3, 0.75] {
            let y = center.y - half.y + 2.0 * half.y * fraction;
            boxes.push((Vec3::new(center.x, y, center.z), rail_half));
        }
    }
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for (c, h) in boxes {
        let b = cuboid(Vec3::ZERO, h)?;
        let base = positions.len() as u32;
        positions.extend(b.positions().iter().map(|&p| p + c));
        indices.extend(b.indices().iter().map(|&i| i + base));
    }
    Mesh::new(&positions, &indices)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each call below, with an invalid parameter, returns an error naming that parameter
    /// (not a panic).
    #[test]
    fn invalid_parameters_are_errors() {
        let setting = |r: Result<Mesh>, name: &str| matches!(r, Err(Error::InvalidSetting { field, .. }) if field == name);
        assert!(setting(uv_sphere(Vec3::ZERO, -1.0, 8, 4), "radius"));
        assert!(setting(
            torus(Vec3::ZERO, 1.0, 2.0, 8, 4),
            "torus.minor_radius"
        ));
        assert!(setting(
            fence(Vec3::ZERO, 0, 1.0, Vec3::ONE, false),
            "posts"
        ));
        let center = cuboid(Vec3::NAN, Vec3::ONE);
        assert!(matches!(
            center,
            Err(Error::NonFinite {
                field: "center",
                ..
            })
        ));
        // 2^33 triangles, beyond Mesh::MAX_TRIANGLES: refused before anything is allocated.
        let huge = torus(Vec3::ZERO, 2.0, 1.0, 1 << 16, 1 << 16);
        assert!(matches!(huge, Err(Error::MeshTooLarge { .. })));
    }
}
