//! The error of an image against the reference, as every test and the report measure it: the
//! RMSE relative to the mean, and percentiles of the per-pixel relative error where the
//! reference is bright enough for a relative error to mean something.

use glam::DVec3;

use super::{camera_ray, pixel_ndc};
use crate::scene::{Camera, Light};

/// The error of an in-scatter image against the reference over the pixels a mask keeps.
///
/// * `rmse`: the root mean square of the difference over the kept pixels and their three
///   channels, relative to the mean reference value (0 for a black reference);
/// * `p95`, `p99`, `max`: percentiles of the per-pixel relative error
///   `max_c |image − reference| / max_c reference`, over the kept pixels whose reference is
///   above 1% of the frame's brightness scale. The scale is the 99th percentile of the kept
///   pixels' brightness, not their maximum: a light in view puts the maximum in its own 1/h
///   glow, and 1% of that would count only the pixels around the light. A pixel whose error
///   is not finite (a NaN or infinite image value) counts as infinitely wrong.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ImageError {
    /// RMSE relative to the mean reference value.
    pub rmse: f64,
    /// 95th percentile of the per-pixel relative error.
    pub p95: f64,
    /// 99th percentile of the per-pixel relative error.
    pub p99: f64,
    /// The largest per-pixel relative error.
    pub max: f64,
    /// The pixel (index into the images) with the largest relative error.
    pub worst: usize,
    /// Pixels counted in the percentiles.
    pub counted: usize,
}

impl ImageError {
    /// The pixels of a `width × height` image of `camera` to measure: all but those whose
    /// centre ray passes within 1.5 pixels of a point or spot light's position. Looking at a
    /// light through the medium the in-scatter is singular (1/h); a renderer clamps it by the
    /// pixel's footprint on purpose while the reference integrates the centre ray, so they are
    /// not the same quantity there. A rectilinear pixel's angular size falls as cos^1.5 of its
    /// angle to the view axis (its solid angle as cos³), and so does the margin: a wide view's
    /// edge pixels are small. A directional light has no glow to leave out.
    pub fn keep_away_from_lights(
        camera: &Camera,
        lights: &[Light],
        width: u32,
        height: u32,
    ) -> Vec<bool> {
        let forward = -camera
            .view()
            .as_dmat4()
            .inverse()
            .z_axis
            .truncate()
            .normalize();
        let pixel = 2.0 * f64::from(camera.pixel_angular_radius(height));
        let positions: Vec<DVec3> = lights
            .iter()
            .filter_map(|l| l.position())
            .map(|p| p.as_dvec3())
            .collect();
        (0..width * height)
            .map(|i| {
                let (eye, dir) = camera_ray(camera, pixel_ndc(width, height, i % width, i / width));
                let cos_axis = dir.dot(forward).clamp(0.0, 1.0);
                let margin = 1.5 * pixel * cos_axis.powf(1.5);
                positions
                    .iter()
                    .all(|p| dir.angle_between(*p - eye) >= margin)
            })
            .collect()
    }

    /// Measures `image` against `reference` (same layout) over the pixels where `keep` is true
    /// (commonly all but the pixels within 1.5 pixels of a light's centre, where a renderer
    /// clamps the singular glow by the pixel's footprint). Slices of different lengths are
    /// measured over their common prefix.
    pub fn measure(image: &[DVec3], reference: &[DVec3], keep: &[bool]) -> Self {
        let kept = || {
            image
                .iter()
                .zip(reference)
                .zip(keep)
                .enumerate()
                .filter(|(_, (_, &k))| k)
                .map(|(i, ((g, r), _))| (i, *g, *r))
        };
        let (mut sum_sq, mut sum_ref, mut count) = (0.0, 0.0, 0usize);
        let mut brightness = Vec::new();
        for (_, g, r) in kept() {
            sum_sq += (g - r).length_squared();
            sum_ref += r.x + r.y + r.z;
            count += 3;
            brightness.push(r.max_element());
        }
        brightness.sort_by(f64::total_cmp);
        let scale = brightness
            .get((brightness.len().saturating_sub(1) as f64 * 0.99) as usize)
            .copied()
            .unwrap_or(0.0);
        let mut relative: Vec<(f64, usize)> = kept()
            .filter(|(_, _, r)| r.max_element() > 0.01 * scale)
            .map(|(i, g, r)| {
                // `max_element` skips a NaN channel: test the pixel itself.
                let e = (g - r).abs().max_element() / r.max_element();
                let finite = g.is_finite() && e.is_finite();
                (if finite { e } else { f64::INFINITY }, i)
            })
            .collect();
        relative.sort_by(|a, b| a.0.total_cmp(&b.0));
        let percentile = |p: f64| {
            if relative.is_empty() {
                0.0
            } else {
                let index = ((p * relative.len() as f64).ceil() as usize).clamp(1, relative.len());
                relative[index - 1].0
            }
        };
        let (max, worst) = relative.last().copied().unwrap_or((0.0, 0));
        let mean = sum_ref / count.max(1) as f64;
        ImageError {
            rmse: if mean > 0.0 {
                (sum_sq / count.max(1) as f64).sqrt() / mean
            } else {
                0.0
            },
            p95: percentile(0.95),
            p99: percentile(0.99),
            max,
            worst,
            counted: relative.len(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::ImageError;
    use glam::DVec3;

    /// The light's own pixels are left out over about 1.5 pixels, in the view's centre and at
    /// the edge of a 170° view, where a pixel subtends 1/30 of a centre pixel's angle radially
    /// (cos² 80°): a margin of 1.5 centre pixels' angle there (without the cos^1.5) would leave
    /// out hundreds of pixels.
    #[test]
    fn the_light_s_own_pixels_are_left_out_by_their_angular_size() {
        use crate::reference::{camera_ray, pixel_ndc};
        use crate::scene::{Camera, Light, PointLight};
        use glam::Vec3;
        let n = 96;
        let left_out = |fov_degrees: f32, (px, py): (u32, u32)| {
            let view = glam::camera::rh::view::look_at_mat4(Vec3::ZERO, Vec3::NEG_Z, Vec3::Y);
            let projection = glam::camera::rh::proj::directx::perspective(
                fov_degrees.to_radians(),
                1.0,
                0.1,
                100.0,
            );
            let camera = Camera::new(view, projection).unwrap();
            // The light on the ray through the pixel's centre.
            let (eye, dir) = camera_ray(&camera, pixel_ndc(n, n, px, py));
            let position = (eye + 10.0 * dir).as_vec3();
            let light = Light::from(PointLight::new(position, Vec3::ONE).unwrap());
            let keep = ImageError::keep_away_from_lights(&camera, &[light], n, n);
            assert!(!keep[(py * n + px) as usize], "its own pixel is kept");
            keep.iter().filter(|k| !**k).count()
        };
        let centre = left_out(60.0, (48, 48));
        // The light 80° off the axis of a 170° view: tan 80° / tan 85° of the half width.
        let off = (48.0 + 48.0 * 80f32.to_radians().tan() / 85f32.to_radians().tan()) as u32;
        let edge = left_out(170.0, (off, 48));
        assert!(
            (5..=13).contains(&centre),
            "centre: {centre} pixels left out"
        );
        assert!(
            (1..=2 * centre).contains(&edge),
            "edge: {edge} pixels left out"
        );
    }

    /// Hand-computed figures on 100 pixels: 90 exact, 10 off by 10%..100%, one masked out and
    /// one below the brightness floor (neither counted), and a NaN that counts as infinite.
    #[test]
    fn figures_match_hand_computation() {
        let reference: Vec<DVec3> = (0..100).map(|_| DVec3::splat(1.0)).collect();
        let mut image = reference.clone();
        for k in 0..10 {
            image[90 + k] = DVec3::splat(1.0 + 0.1 * (k + 1) as f64);
        }
        let keep = vec![true; 100];
        let e = ImageError::measure(&image, &reference, &keep);
        assert_eq!(e.counted, 100);
        // Sorted errors: 90 zeros, then 0.1 … 1.0; the 95th is index 94: 0.5.
        assert!((e.p95 - 0.5).abs() < 1e-12, "{e:?}");
        assert!((e.p99 - 0.9).abs() < 1e-12, "{e:?}");
        assert!((e.max - 1.0).abs() < 1e-12 && e.worst == 99, "{e:?}");
        let sq: f64 = (1..=10).map(|k| 3.0 * (0.1 * k as f64).powi(2)).sum();
        assert!((e.rmse - (sq / 300.0).sqrt()).abs() < 1e-12, "{e:?}");

        // A masked pixel and a dark one leave the percentiles; a NaN is the worst.
        let mut keep = keep;
        keep[99] = false;
        let mut reference = reference;
        reference[98] = DVec3::splat(1e-3);
        image[0] = DVec3::new(f64::NAN, 1.0, 1.0);
        let e = ImageError::measure(&image, &reference, &keep);
        assert_eq!(e.counted, 98);
        assert_eq!((e.max, e.worst), (f64::INFINITY, 0));
    }
}
