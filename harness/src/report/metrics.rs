//! The error of an image against the reference (the crate's `reference::ImageError`), away from
//! the lights' own pixels.

use volshadow::glam::DVec3;
use volshadow::reference::ImageError;
use volshadow::scene_file::SceneDescription;

use super::Errors;

/// Pixels the error is measured on: all but those looking at a light
/// (`ImageError::keep_away_from_lights`, as the tests measure).
pub fn keep_mask(
    scene: &SceneDescription,
    camera: &volshadow::Camera,
    (w, h): (u32, u32),
) -> Vec<bool> {
    let lights: Vec<volshadow::Light> = scene.lights.iter().map(|l| l.light).collect();
    ImageError::keep_away_from_lights(camera, &lights, w, h)
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
