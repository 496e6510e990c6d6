//! A point light's cube faces: their matrices, which occluders reach each, and how the
//! shaders recognise the faces this module makes.

use glam::{Mat4, Vec3, Vec4};

/// A point light's six cube faces (+X, −X, +Y, −Y, +Z, −Z) around `position`: 90°
/// reversed-Z infinite perspectives with near plane `near`, looking along each axis.
pub(super) fn cube_faces(position: Vec3, near: f32) -> [Mat4; 6] {
    use glam::camera::rh::{proj::directx::perspective_infinite_reverse, view::look_to_mat4};
    let proj = perspective_infinite_reverse(std::f32::consts::FRAC_PI_2, 1.0, near);
    [
        (Vec3::X, Vec3::Y),
        (Vec3::NEG_X, Vec3::Y),
        (Vec3::Y, Vec3::Z),
        (Vec3::NEG_Y, Vec3::Z),
        (Vec3::Z, Vec3::Y),
        (Vec3::NEG_Z, Vec3::Y),
    ]
    .map(|(dir, up)| proj * look_to_mat4(position, dir, up))
}

/// Per cube face of a point light at `position`, the spheres (indices) that reach it
/// ([`cube_faces_touched`] of each): what its layer draws.
pub(crate) fn cube_face_draws(position: Vec3, spheres: &[Vec4]) -> Vec<Vec<u32>> {
    let mut faces = vec![Vec::new(); 6];
    for (i, sphere) in (0u32..).zip(spheres) {
        for (face, reached) in cube_faces_touched(position, std::slice::from_ref(sphere))
            .into_iter()
            .enumerate()
        {
            if reached {
                faces[face].push(i);
            }
        }
    }
    faces
}

/// Which of a point light's cube faces (+X, −X, +Y, −Y, +Z, −Z) at `position` the spheres
/// `(centre, radius)` may reach, conservatively: a face's pyramid is four half-spaces through
/// the light (`±x_a ≥ |x_b|` for the face's axis `a` and each other axis `b`), and a sphere
/// inside it reaches into each of them. The back layer of a face none reaches is not drawn.
pub(crate) fn cube_faces_touched(position: Vec3, spheres: &[Vec4]) -> [bool; 6] {
    let mut touched = [false; 6];
    for sphere in spheres {
        let c = sphere.truncate() - position;
        let r = sphere.w * std::f32::consts::SQRT_2;
        for (face, reached) in touched.iter_mut().enumerate() {
            let a = face / 2;
            let along = if face % 2 == 0 { c[a] } else { -c[a] };
            let (b, d) = ((a + 1) % 3, (a + 2) % 3);
            // n·c ≥ −r for n = (±e_a ∓ e_b)/√2, times √2; a non-finite sphere reaches all.
            let inside = along - c[b].abs() >= -r && along - c[d].abs() >= -r;
            *reached |= inside || !(along.is_finite() && r.is_finite());
        }
    }
    touched
}

/// The near plane of `faces` where they are the cube faces this node draws for a point light at
/// `position` ([`cube_faces`]), entry by
/// entry to within 1e-5 of each entry's size, else 0. The shaders then project a point into a face
/// with a few selects on its offset from the light (`cube_clip` in `shaders/shared/pcss.wgsl`) in
/// place of the face's matrix, which each SIMD lane reads for its own face: on the report's soft
/// scene on llvmpipe the march at ½ resolution took about 0.9 of its time, and so did the
/// soft-shadow grid's build. A caller's map with other faces keeps the matrices.
pub(crate) fn standard_cube_near(faces: &[Mat4], position: Vec3) -> f32 {
    // Reversed-Z infinite perspective: clip z = near (the matrix's column w, row z).
    let near = faces.first().map_or(0.0, |f| f.w_axis.z);
    let standard = faces.len() == 6
        && near.is_finite()
        && near > 0.0
        && position.is_finite()
        && faces.iter().zip(cube_faces(position, near)).all(|(a, b)| {
            a.to_cols_array()
                .iter()
                .zip(b.to_cols_array())
                .all(|(x, y)| (x - y).abs() <= 1.0e-5 * y.abs().max(1.0))
        });
    if standard {
        near
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Seeded numbers uniform in [−1, 1) (xorshift64).
    fn uniform(mut seed: u64) -> impl FnMut() -> f32 {
        move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f32 / (1u64 << 53) as f32 * 2.0 - 1.0
        }
    }

    /// `cube_clip` of shaders/shared/pcss.wgsl, line for line: a face's clip coordinates as a
    /// signed permutation of the offset from the light.
    fn cube_clip(face: usize, rel: Vec3, near: f32) -> Vec4 {
        let sign = if face & 1 == 1 { -1.0 } else { 1.0 };
        match face {
            0 | 1 => Vec4::new(sign * rel.z, rel.y, near, sign * rel.x),
            2 | 3 => Vec4::new(sign * rel.x, rel.z, near, sign * rel.y),
            _ => Vec4::new(-sign * rel.x, rel.y, near, sign * rel.z),
        }
    }

    /// The node's own cube faces are recognised, with their near plane, at light positions and
    /// near planes from 1e-3 to 1e5, and there the shaders' permutation gives the faces'
    /// projection (ndc within 1e-5 over seeded points of each face); a caller's faces that
    /// differ (another up vector, another order, a spot's one face, a uniform scale that
    /// projects the same but is not the node's) are not, and keep their matrices. A
    /// permutation with one sign wrong fails the projection check, so it can tell.
    #[test]
    fn the_node_s_cube_faces_project_by_permutation() {
        let mut next = uniform(0x2545_f491_4f6c_dd1d);
        let mut wrong_sign_failed = 0;
        for &scale in &[1.0e-3_f32, 1.0, 37.0, 1.0e5] {
            let position = Vec3::new(next(), next(), next()) * scale;
            let near = 1.0e-3 * scale.max(1.0);
            let faces = cube_faces(position, near);
            assert_eq!(standard_cube_near(&faces, position), near, "scale {scale}");
            for _ in 0..2000 {
                let rel = Vec3::new(next(), next(), next()) * scale;
                let face = {
                    let m = rel.abs();
                    let axis = if m.x >= m.y && m.x >= m.z {
                        0
                    } else if m.y >= m.z {
                        1
                    } else {
                        2
                    };
                    2 * axis + usize::from(rel[axis] <= 0.0)
                };
                let ndc = |c: Vec4| c.truncate() / c.w;
                let by_matrix = ndc(faces[face] * (position + rel).extend(1.0));
                let by_permutation = ndc(cube_clip(face, rel, near));
                let err = (by_matrix - by_permutation).abs();
                assert!(
                    err.x <= 1.0e-5 && err.y <= 1.0e-5 && err.z <= 1.0e-5 * by_matrix.z.abs(),
                    "face {face}, rel {rel}: matrix {by_matrix}, permutation {by_permutation}"
                );
                let mut flipped = cube_clip(face, rel, near);
                flipped.x = -flipped.x;
                if (ndc(flipped) - by_matrix).abs().max_element() > 1.0e-3 {
                    wrong_sign_failed += 1;
                }
            }
            let mut other_up = faces;
            other_up[0] = {
                use glam::camera::rh::{
                    proj::directx::perspective_infinite_reverse, view::look_to_mat4,
                };
                perspective_infinite_reverse(std::f32::consts::FRAC_PI_2, 1.0, near)
                    * look_to_mat4(position, Vec3::X, Vec3::NEG_Y)
            };
            assert_eq!(standard_cube_near(&other_up, position), 0.0);
            let mut reordered = faces;
            reordered.swap(2, 3);
            assert_eq!(standard_cube_near(&reordered, position), 0.0);
            assert_eq!(standard_cube_near(&faces[..1], position), 0.0);
            let scaled = faces.map(|f| f * 1.001);
            assert_eq!(standard_cube_near(&scaled, position), 0.0);
            assert_eq!(standard_cube_near(&faces, position + Vec3::X * scale), 0.0);
        }
        assert!(wrong_sign_failed > 7000, "{wrong_sign_failed}");
    }

    /// Every point of a sphere lies in a face `cube_faces_touched` marks (2000 seeded spheres
    /// around lights at scales 1e-3 to 1e5, 200 points each, on and inside the surface), and a
    /// small sphere on an axis marks its face alone, so the test can skip faces. Marking only
    /// the face of the sphere's centre leaves points out, so the test can tell.
    #[test]
    fn every_point_of_a_sphere_lies_in_a_touched_face() {
        let mut next = uniform(0x9e37_79b9_7f4a_7c15);
        let face_of = |p: Vec3| {
            let m = p.abs();
            let a = if m.x >= m.y && m.x >= m.z {
                0
            } else if m.y >= m.z {
                1
            } else {
                2
            };
            2 * a + usize::from(p[a] < 0.0)
        };
        let mut centre_only_missed = 0;
        for i in 0..2000 {
            let scale = [1.0e-3_f32, 1.0, 1.0e5][i % 3];
            let light = Vec3::new(next(), next(), next()) * scale;
            let centre = light + Vec3::new(next(), next(), next()) * 2.0 * scale;
            let radius = (0.5 * next() + 0.55) * scale;
            let touched = cube_faces_touched(light, &[centre.extend(radius)]);
            for _ in 0..200 {
                let dir = Vec3::new(next(), next(), next()).normalize_or(Vec3::X);
                let depth = if next() > 0.0 { 1.0 } else { next().abs() };
                let p = centre + dir * radius * depth - light;
                assert!(
                    touched[face_of(p)],
                    "sphere {centre} r {radius}, light {light}: point {p} in face {}, marked {touched:?}",
                    face_of(p)
                );
                if face_of(p) != face_of(centre - light) {
                    centre_only_missed += 1;
                }
            }
        }
        assert!(centre_only_missed > 1000, "{centre_only_missed}");
        let small = cube_faces_touched(Vec3::ZERO, &[Vec4::new(0.0, 0.0, -5.0, 1.0)]);
        assert_eq!(small, [false, false, false, false, false, true]);
    }
}
