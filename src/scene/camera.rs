//! The caller's camera, given as view and projection matrices.

use glam::{DMat4, DVec4, Mat4, Vec3};

use crate::error::{finite, Error, Result};

/// The camera the caller renders with: a world → view matrix (right-handed, looking down −z)
/// and a perspective view → clip matrix producing wgpu's depth range [0, 1].
///
/// Any depth convention works — standard or reversed Z, finite or infinite far plane — because
/// eye distances are recovered through the inverse projection. The depth value of the far end
/// (what the caller clears its depth buffer to, `1.0` standard or `0.0` reversed) is detected
/// from the matrix; pixels holding it are sky and integrate to infinity.
///
/// Used in the [crate-level example](crate#example).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    view: Mat4,
    projection: Mat4,
    world_from_clip: Mat4,
    eye: Vec3,
    far_depth: f32,
}

impl Camera {
    /// The largest aspect ratio (width over height of the view, or its inverse) a camera may
    /// have: a target of 8192 × 1 square pixels, WebGPU's default `max_texture_dimension_2d`
    /// along one side. Beyond it no target can show the view, and the ray directions lose
    /// their spread in f32 (an aspect of 1e30 made every pixel the same).
    pub const MAX_ASPECT: f32 = 8192.0;

    /// The farthest near plane (distance from the eye along the view axis, in world units) a
    /// camera may have: 1e9, the far bound of scene files. Nothing nearer than it is drawn, so
    /// a scene within the supported range (coordinates up to 1e6) would be empty.
    pub const MAX_NEAR: f64 = 1e9;

    /// Validates and stores the matrices: `view` maps world to view space (right-handed, e.g.
    /// `glam::camera::rh::view::look_at_mat4`), `projection` view to clip space (any
    /// perspective: standard or reversed Z, finite or infinite far, e.g.
    /// `glam::camera::rh::proj::directx::perspective`). See the
    /// [crate-level example](crate#example).
    ///
    /// # Errors
    ///
    /// [`Error::NonFinite`] for a non-finite entry (or an inverse view-projection that
    /// overflows), [`Error::SingularMatrix`] for a singular view or projection matrix,
    /// [`Error::NotPerspective`] for a projection that is not perspective,
    /// [`Error::InvalidSetting`] naming `camera.projection` for an aspect ratio outside
    /// [1/[`MAX_ASPECT`](Self::MAX_ASPECT), [`MAX_ASPECT`](Self::MAX_ASPECT)] or a near plane
    /// farther than [`MAX_NEAR`](Self::MAX_NEAR).
    pub fn new(view: Mat4, projection: Mat4) -> Result<Self> {
        finite("camera.view", &view.to_cols_array())?;
        finite("camera.projection", &projection.to_cols_array())?;
        let invertible = |m: Mat4, matrix: &'static str| -> Result<Mat4> {
            let determinant = m.determinant();
            let inverse = m.inverse();
            let ok = determinant.is_finite()
                && determinant.abs() > f32::MIN_POSITIVE
                && inverse.to_cols_array().iter().all(|v| v.is_finite());
            if ok {
                Ok(inverse)
            } else {
                Err(Error::SingularMatrix {
                    matrix,
                    determinant,
                })
            }
        };
        let view_inverse = invertible(view, "view")?;
        invertible(projection, "projection")?;
        // Perspective: clip w is a multiple of view z alone.
        let w_row = projection.row(3);
        let scale = w_row.z.abs();
        if scale == 0.0 || w_row.x != 0.0 || w_row.y != 0.0 || w_row.w.abs() > 1e-6 * scale {
            return Err(Error::NotPerspective);
        }
        // The aspect ratio, the x scale against the y scale (cot(fov_y/2) / aspect and
        // cot(fov_y/2) for a symmetric perspective).
        let aspect = (projection.y_axis.y / projection.x_axis.x).abs();
        if !(1.0 / Self::MAX_ASPECT..=Self::MAX_ASPECT).contains(&aspect) {
            return Err(Error::InvalidSetting {
                field: "camera.projection",
                problem: format!(
                    "its aspect ratio {aspect:.3e} is outside [1/{0}, {0}], the widest a \
                     target within WebGPU's texture limits has with square pixels",
                    Self::MAX_ASPECT
                ),
            });
        }
        let far_depth = far_end_depth(projection)?;
        let world_from_clip = (projection * view).inverse();
        finite(
            "camera (inverse view-projection)",
            &world_from_clip.to_cols_array(),
        )?;
        Ok(Self {
            view,
            projection,
            world_from_clip,
            eye: view_inverse.w_axis.truncate(),
            far_depth,
        })
    }

    /// World → view matrix.
    pub fn view(&self) -> Mat4 {
        self.view
    }
    /// View → clip matrix.
    pub fn projection(&self) -> Mat4 {
        self.projection
    }
    /// Clip → world matrix, the inverse of `projection * view`.
    pub fn world_from_clip(&self) -> Mat4 {
        self.world_from_clip
    }
    /// The eye position in world space.
    pub fn eye(&self) -> Vec3 {
        self.eye
    }
    /// The depth value of the far end of the depth range (1.0 standard Z, 0.0 reversed Z):
    /// the value a depth buffer is cleared to, read as sky.
    pub fn far_depth(&self) -> f32 {
        self.far_depth
    }
    /// Angular radius of one pixel at the centre of a `height`-pixel image, in radians.
    pub fn pixel_angular_radius(&self, height: u32) -> f32 {
        // projection[1][1] = cot(fov_y / 2): one pixel spans 2 / (height * cot) in tan units.
        1.0 / (height.max(1) as f32 * self.projection.y_axis.y.abs())
    }
    /// Unit world-space direction of the ray through normalised device coordinates (x, y),
    /// both in [−1, 1], y up.
    pub fn ray_direction(&self, ndc_x: f32, ndc_y: f32) -> Vec3 {
        let near = if self.far_depth == 1.0 { 0.0 } else { 1.0 };
        let p = self.world_from_clip * glam::Vec4::new(ndc_x, ndc_y, near, 1.0);
        (p.truncate() / p.w - self.eye).normalize()
    }
}

/// Which NDC depth (0 or 1) lies at the far end: the one that unprojects farther from the eye
/// (a point at infinity, w = 0, counts as farthest).
fn far_end_depth(projection: Mat4) -> Result<f32> {
    let inverse = projection.as_dmat4().inverse();
    // Each end's unprojected point: its distance from the eye and its |w|.
    let [(l0, w0), (l1, w1)] = [0.0, 1.0].map(|z| {
        let p: DVec4 = DMat4::mul_vec4(&inverse, DVec4::new(0.0, 0.0, z, 1.0));
        (p.truncate().length(), p.w.abs())
    });
    // The near end's distance, measured without the test below for points at infinity: a
    // near plane beyond 1e12 would read as infinitely far, and so as no perspective.
    let near = (l0 / w0).min(l1 / w1);
    if near.is_finite() && near > Camera::MAX_NEAR {
        return Err(Error::InvalidSetting {
            field: "camera.projection",
            problem: format!(
                "its near plane is {near:.3e} from the eye, beyond {:e}",
                Camera::MAX_NEAR
            ),
        });
    }
    let distance = |len: f64, w: f64| {
        if w <= 1e-12 * len {
            f64::INFINITY
        } else {
            len / w
        }
    };
    let (d0, d1) = (distance(l0, w0), distance(l1, w1));
    if d0 == d1 || d0.is_nan() || d1.is_nan() {
        return Err(Error::NotPerspective);
    }
    Ok(if d1 > d0 { 1.0 } else { 0.0 })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::camera::rh::proj::directx;

    fn view() -> Mat4 {
        glam::camera::rh::view::look_at_mat4(Vec3::new(0.0, 1.0, 5.0), Vec3::ZERO, Vec3::Y)
    }

    fn problem(r: Result<Camera>) -> String {
        match r {
            Err(Error::InvalidSetting { field, problem }) => format!("{field}: {problem}"),
            other => panic!("expected InvalidSetting, got {other:?}"),
        }
    }

    /// Census item 9: an aspect of 1e30 was accepted and drew a flat image. Bound
    /// `MAX_ASPECT` (8192, a 8192 × 1 target): at it the camera is accepted, beyond it (either
    /// way round) the error names the projection and the bound.
    #[test]
    fn an_aspect_beyond_any_target_is_an_error() {
        for aspect in [1.0, Camera::MAX_ASPECT, 1.0 / Camera::MAX_ASPECT] {
            let p = directx::perspective(0.8, aspect, 0.1, 100.0);
            assert!(Camera::new(view(), p).is_ok(), "aspect {aspect}");
        }
        for aspect in [
            1e30,
            1.01 * Camera::MAX_ASPECT,
            1e-30,
            0.99 / Camera::MAX_ASPECT,
        ] {
            let p = directx::perspective(0.8, aspect, 0.1, 100.0);
            let text = problem(Camera::new(view(), p));
            assert!(
                text.starts_with("camera.projection: its aspect ratio") && text.contains("8192"),
                "aspect {aspect}: {text}"
            );
        }
    }

    /// Census item 9: a near plane of 1e30 read "not a perspective projection". It is a
    /// perspective, with its near plane beyond `MAX_NEAR`: the error says so, for standard and
    /// reversed, finite and infinite projections; 1e8 is accepted.
    #[test]
    fn a_near_plane_beyond_the_scene_range_is_named() {
        // Finite forms only where near · far fits in f32 (beyond it the matrix itself
        // overflows, a `NonFinite` error).
        let projections = |near: f32| {
            let mut p = vec![
                directx::perspective_infinite(0.8, 1.5, near),
                directx::perspective_infinite_reverse(0.8, 1.5, near),
            ];
            if near < 1e18 {
                p.push(directx::perspective(0.8, 1.5, near, near * 10.0));
                p.push(directx::perspective(0.8, 1.5, near * 10.0, near));
            }
            p
        };
        for p in projections(1e8) {
            assert!(Camera::new(view(), p).is_ok(), "near 1e8: {p}");
        }
        for near in [1e30, 1e13, 2e9] {
            for p in projections(near) {
                let text = problem(Camera::new(view(), p));
                assert!(
                    text.contains("near plane") && text.contains("beyond 1e9"),
                    "near {near}: {text}"
                );
            }
        }
    }
}
