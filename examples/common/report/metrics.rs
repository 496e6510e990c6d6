//! The error of an image against the reference (the crate's `reference::ImageError`), away from
//! the lights' own pixels.

use volshadow::glam::DVec3;
use volshadow::reference::{camera_ray, pixel_ndc, ImageError};
use volshadow::scene_file::SceneDescription;

use super::Errors;

/// Pixels the error is measured on: all but those within 1.5 pixels of a light's centre.
pub fn keep_mask(
    scene: &SceneDescription,
    camera: &volshadow::Camera,
    (w, h): (u32, u32),
) -> Vec<bool> {
    let pixel_angle = 2.0 * f64::from(camera.pixel_angular_radius(h));
    (0..w * h)
        .map(|i| {
            let (eye, dir) = camera_ray(camera, pixel_ndc(w, h, i % w, i / w));
            scene.lights.iter().all(|l| {
                // A directional light has no glow to leave out.
                let Some(p) = l.light.position() else {
                    return true;
                };
                let to_light = p.as_dvec3() - eye;
                dir.angle_between(to_light) >= 1.5 * pixel_angle
            })
        })
        .collect()
}

/// RMSE relative to the mean, and percentiles of the per-pixel relative error: the crate's
/// metric ([`ImageError`]), as the tests measure.
pub fn errors(image: &[DVec3], reference: &[DVec3], keep: &[bool]) -> Errors {
    let e = ImageError::measure(image, reference, keep);
    Errors {
        rmse: e.rmse,
        p95: e.p95,
        p99: e.p99,
    }
}
