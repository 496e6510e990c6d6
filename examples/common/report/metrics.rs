//! The error of an image against the reference: relative RMSE and percentiles of the per-pixel
//! relative error, away from the lights' own pixels.

use volshadow::glam::DVec3;
use volshadow::reference::{camera_ray, pixel_ndc};
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

/// RMSE relative to the mean, and percentiles of the per-pixel relative error.
pub fn errors(image: &[DVec3], reference: &[DVec3], keep: &[bool]) -> Errors {
    let mut sum_sq = 0.0;
    let mut sum_ref = 0.0;
    let mut count = 0usize;
    let mut brightness = Vec::new();
    for ((g, r), &k) in image.iter().zip(reference).zip(keep) {
        if k {
            sum_sq += (*g - *r).length_squared();
            sum_ref += r.x + r.y + r.z;
            count += 3;
            brightness.push(r.max_element());
        }
    }
    // The frame's brightness scale: its 99th percentile, not its maximum. With a light in view
    // the maximum sits in the light's 1/h glow, and 1% of it would leave only the pixels
    // around the light counted (where no shadow falls).
    brightness.sort_by(f64::total_cmp);
    let peak = brightness
        .get((brightness.len().saturating_sub(1) as f64 * 0.99) as usize)
        .copied()
        .unwrap_or(0.0);
    let mut relative: Vec<f64> = image
        .iter()
        .zip(reference)
        .zip(keep)
        .filter(|((_, r), &k)| k && r.max_element() > 0.01 * peak)
        .map(|((g, r), _)| {
            let e = (*g - *r).abs().max_element() / r.max_element();
            if e.is_finite() {
                e
            } else {
                f64::INFINITY
            }
        })
        .collect();
    relative.sort_by(f64::total_cmp);
    let percentile = |p: f64| {
        if relative.is_empty() {
            0.0
        } else {
            let index = ((p * relative.len() as f64).ceil() as usize).clamp(1, relative.len()) - 1;
            relative[index]
        }
    };
    let mean = sum_ref / count.max(1) as f64;
    Errors {
        rmse: if mean > 0.0 {
            (sum_sq / count.max(1) as f64).sqrt() / mean
        } else {
            0.0
        },
        p95: percentile(0.95),
        p99: percentile(0.99),
    }
}
