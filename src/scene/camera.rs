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
    /// [`Error::NotPerspective`] for a projection that is not perspective.
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
    let distance = |z: f64| -> f64 {
        let p: DVec4 = DMat4::mul_vec4(&inverse, DVec4::new(0.0, 0.0, z, 1.0));
        let len = p.truncate().length();
        if p.w.abs() <= 1e-12 * len {
            f64::INFINITY
        } else {
            len / p.w.abs()
        }
    };
    let (d0, d1) = (distance(0.0), distance(1.0));
    if d0 == d1 || d0.is_nan() || d1.is_nan() {
        return Err(Error::NotPerspective);
    }
    Ok(if d1 > d0 { 1.0 } else { 0.0 })
}
