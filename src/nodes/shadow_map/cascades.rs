//! A directional light's cascades: the splits of the view depth, each cascade's square fitted
//! to its slice of the view, and the occluders each one draws.

use glam::{Mat4, Vec3, Vec4};

use crate::gpu::Occluder;
use crate::scene::{Camera, DirectionalLight};

use super::ShadowMapNode;

/// A directional map's depth bias in texels of the cascade a point falls in (world units:
/// this times the cascade's texel). A point of the medium counts as lit while it lies less
/// than this far beyond the stored occluder surface along the light: a surface sloped at up
/// to atan(2) ≈ 63° to the light within a texel's width stays on its own side. Tied to the
/// texel, not to the depth range, which an occluder far along the direction may stretch to
/// kilometres.
pub const DIRECTIONAL_BIAS_TEXELS: f32 = 2.0;

/// The widest ratio of a directional light's shadow distance to the start of its logarithmic
/// cascade splits ([`ShadowMapNode::cascade_splits`]).
pub const CASCADE_RANGE: f32 = 1000.0;

/// One cascade's square in the light's frame: centre (`cx`, `cy`, snapped to texels; `ct`
/// along the direction), half width `radius`.
#[derive(Debug, Clone, Copy)]
struct CascadeFit {
    right: Vec3,
    up: Vec3,
    cx: f32,
    cy: f32,
    ct: f32,
    radius: f32,
}

impl CascadeFit {
    fn new(light: &DirectionalLight, camera: &Camera, slice: (f32, f32), resolution: u32) -> Self {
        let d = light.direction();
        let (right, up) = d.any_orthonormal_pair();
        // The view pyramid's corners at view depths `slice.0` and `slice.1`: two rings around
        // the axis.
        let eye = camera.eye();
        let view = camera.view();
        let ring = |depth: f32| {
            let mut corners = [Vec3::ZERO; 4];
            for (k, corner) in corners.iter_mut().enumerate() {
                let x = if k & 1 == 0 { -1.0 } else { 1.0 };
                let y = if k & 2 == 0 { -1.0 } else { 1.0 };
                let dir = camera.ray_direction(x, y);
                let depth_per_unit = (-view.transform_vector3(dir).z).max(1e-6);
                *corner = eye + dir * (depth / depth_per_unit);
            }
            let mid = 0.25 * corners.iter().copied().sum::<Vec3>();
            let half = corners.iter().map(|c| c.distance(mid)).fold(0.0, f32::max);
            (mid, half)
        };
        let (near_mid, near_half) = ring(slice.0.max(0.0));
        let (far_mid, far_half) = ring(slice.1.max(slice.0.max(0.0)));
        let (a, b) = (near_mid.distance(eye), far_mid.distance(eye));
        // The smallest sphere around both rings with its centre on the axis: where the
        // distances to the two rings are equal, clamped between them.
        let axis = (far_mid - eye).normalize_or(Vec3::NEG_Z);
        let (centre, radius) = if b > a {
            let t = ((b * b + far_half * far_half - a * a - near_half * near_half)
                / (2.0 * (b - a)))
                .clamp(a, b);
            let r = ((t - a).hypot(near_half)).max((b - t).hypot(far_half));
            (eye + axis * t, r)
        } else {
            (far_mid, far_half.max(near_half))
        };
        let texels = resolution.max(1) as f32;
        let radius = radius.max(1e-6) * (1.0 + 6.0 / texels);
        let radius = ((radius.log2() * 16.0).ceil() / 16.0).exp2();
        let texel = 2.0 * radius / texels;
        let snap = |v: f32| (v / texel).round() * texel;
        Self {
            right,
            up,
            cx: snap(centre.dot(right)),
            cy: snap(centre.dot(up)),
            ct: centre.dot(d),
            radius,
        }
    }

    /// The far side of the region along the direction.
    fn t_far(&self) -> f32 {
        self.ct + self.radius
    }

    /// Whether a box with corners projected to `[lo, hi]` (right, up, along) can shadow a point
    /// of the cascade's square prism up to its far side.
    fn reaches(&self, lo: Vec3, hi: Vec3) -> bool {
        let r = self.radius;
        // Non-finite bounds reach everything (they cannot be ruled out).
        !(lo.is_finite() && hi.is_finite())
            || (lo.x <= self.cx + r
                && hi.x >= self.cx - r
                && lo.y <= self.cy + r
                && hi.y >= self.cy - r
                && lo.z < self.t_far())
    }

    fn matrix(&self, d: Vec3, nearest: f32) -> Mat4 {
        let r = self.radius;
        let t_far = self.t_far();
        let t_near = if nearest.is_finite() {
            (self.ct - r).min(nearest)
        } else {
            self.ct - r
        };
        let depth = 1.0 / (t_far - t_near).max(1e-20);
        Mat4::from_cols(
            (self.right / r).extend(-self.cx / r),
            (self.up / r).extend(-self.cy / r),
            (-d * depth).extend(t_far * depth),
            Vec4::W,
        )
        .transpose()
    }
}

/// An occluder's world box seen in a light frame: the least and greatest (right, up, along)
/// coordinates of its corners.
fn light_frame_bounds(lo: Vec3, hi: Vec3, right: Vec3, up: Vec3, d: Vec3) -> (Vec3, Vec3) {
    let (mut a, mut b) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for i in 0..8 {
        let corner = Vec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        );
        let p = Vec3::new(corner.dot(right), corner.dot(up), corner.dot(d));
        a = a.min(p);
        b = b.max(p);
    }
    (a, b)
}

impl ShadowMapNode {
    /// The view depths bounding a directional light's cascades: `cascades + 1` increasing
    /// values from 0 (the eye) to `distance`. The splits are logarithmic (Zhang et al. 2006:
    /// the split that spreads perspective aliasing evenly), `n · (distance / n)^(i / cascades)`
    /// from `n` the camera's near plane or `distance / CASCADE_RANGE`, whichever is farther: a
    /// cascade's texels grow with its distance from the eye, as the pixels they are seen
    /// through do, and a near plane far closer than the distance does not leave the first
    /// cascades covering nothing.
    pub fn cascade_splits(camera: &Camera, distance: f32, cascades: u32) -> Vec<f32> {
        let n = cascades.max(1);
        let distance = if distance.is_finite() && distance > 0.0 {
            distance
        } else {
            1.0
        };
        // The near plane's view depth (an infinite or reversed projection's near plane
        // unprojects like any other).
        let near_ndc = if camera.far_depth() == 1.0 { 0.0 } else { 1.0 };
        let p = camera.projection().inverse() * Vec4::new(0.0, 0.0, near_ndc, 1.0);
        let near = (-p.z / p.w).abs();
        let floor = distance / CASCADE_RANGE;
        let near = if near.is_finite() {
            near.clamp(floor, distance)
        } else {
            floor
        };
        let mut splits = vec![0.0];
        for i in 1..n {
            let split = near * (distance / near).powf(i as f32 / n as f32);
            splits.push(split.clamp(*splits.last().unwrap_or(&0.0), distance));
        }
        splits.push(distance);
        splits
    }

    /// A directional light's `clip_from_world` for a square map of `resolution²` texels:
    /// orthographic, in a basis built from the light's direction alone, covering the bounding
    /// sphere (centred on the view axis) of the camera's view pyramid between view depths
    /// `slice.0` and `slice.1`, its radius widened by 3 texels (a point within a texel of the
    /// square's edge takes the next cascade) and rounded up to 1/16 of an octave so that
    /// rounding noise cannot change it, with the centre snapped to whole texels. Depth is
    /// `(t_far − t)/(t_far − t_near)` for `t` the coordinate along the direction, `t_far` the
    /// sphere's far side and `t_near` its near side or `nearest`, whichever is less (the
    /// nearest occluder that can shadow the sphere: see [`ShadowMapNode`]'s module docs).
    pub fn directional_matrix(
        light: &DirectionalLight,
        camera: &Camera,
        slice: (f32, f32),
        resolution: u32,
        nearest: f32,
    ) -> Mat4 {
        let fit = CascadeFit::new(light, camera, slice, resolution);
        fit.matrix(light.direction(), nearest)
    }

    /// The directional map's cascades for this camera and these occluders: each one's face,
    /// and which occluders can shadow its region (the only ones drawn into it).
    pub(super) fn directional_faces(
        &self,
        light: &DirectionalLight,
        camera: &Camera,
        occluders: &[Occluder<'_>],
    ) -> (Vec<Mat4>, Vec<Vec<u32>>) {
        let d = light.direction();
        let (right, up) = d.any_orthonormal_pair();
        let eye = camera.eye();
        let mut farthest = 0.0f32;
        let boxes: Vec<(Vec3, Vec3)> = occluders
            .iter()
            .map(|o| {
                let (lo, hi) = o.world_bounds();
                // The farthest corner.
                farthest = farthest.max((eye - lo).abs().max((eye - hi).abs()).length());
                light_frame_bounds(lo, hi, right, up, d)
            })
            .collect();
        let distance =
            light
                .shadow_distance()
                .unwrap_or(if farthest > 0.0 && farthest.is_finite() {
                    farthest
                } else {
                    1.0
                });
        let splits = Self::cascade_splits(camera, distance, light.cascades());
        let resolution = self.settings.resolution;
        let mut faces = Vec::new();
        let mut drawn = Vec::new();
        for slice in splits.windows(2) {
            let fit = CascadeFit::new(light, camera, (slice[0], slice[1]), resolution);
            let mut nearest = f32::INFINITY;
            let mut layer = Vec::new();
            for (i, &(lo, hi)) in boxes.iter().enumerate() {
                if fit.reaches(lo, hi) {
                    nearest = nearest.min(lo.z);
                    layer.push(i as u32);
                }
            }
            faces.push(fit.matrix(d, nearest));
            drawn.push(layer);
        }
        (faces, drawn)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nodes::shadow_map::tests::uniform;

    /// Every point of the view pyramid's slice of each cascade lies in that cascade's square,
    /// at least a texel inside its edge (where the shaders take it), and within its depth
    /// range: seeded views, sun directions, distances from 1e-2 to 1e5 and 1 to 6 cascades,
    /// 500 points per slice. (A square of the fitted sphere's own radius, without the 3 texels'
    /// widening, was tried as the broken variant: it too holds every point, so this test does
    /// not show that the widening is needed.)
    #[test]
    fn every_point_of_a_slice_lies_in_its_cascade() {
        let mut next = uniform(0x0dd_ba11_cafe_f00d);
        for case in 0..60 {
            let scale = [1.0e-2_f32, 1.0, 1.0e3, 1.0e5][case % 4];
            let eye = Vec3::new(next(), next(), next()) * scale;
            let target =
                eye + Vec3::new(next(), next() * 0.5, next()).normalize_or(Vec3::X) * scale;
            let fov = 0.4 + 1.2 * next().abs();
            let camera = Camera::new(
                glam::camera::rh::view::look_at_mat4(eye, target, Vec3::Y),
                glam::camera::rh::proj::directx::perspective(fov, 1.3, 0.01 * scale, 1e4 * scale),
            )
            .unwrap();
            let dir = Vec3::new(next(), -next().abs() - 0.05, next());
            let light = DirectionalLight::new(dir, Vec3::ONE).unwrap();
            let cascades = 1 + (case % 6) as u32;
            let distance = scale * (1.0 + 100.0 * next().abs());
            let resolution = 1024;
            let splits = ShadowMapNode::cascade_splits(&camera, distance, cascades);
            assert_eq!(splits.len(), cascades as usize + 1);
            assert!(splits.windows(2).all(|w| w[0] <= w[1]), "{splits:?}");
            for (k, slice) in splits.windows(2).enumerate() {
                let fit = CascadeFit::new(&light, &camera, (slice[0], slice[1]), resolution);
                let face = fit.matrix(light.direction(), f32::INFINITY);
                let edge = 1.0 - 2.0 / resolution as f32;
                for _ in 0..500 {
                    let (x, y) = (next(), next());
                    let depth = slice[0] + (slice[1] - slice[0]) * (0.5 + 0.5 * next());
                    let ray = camera.ray_direction(x, y);
                    let per_unit = -camera.view().transform_vector3(ray).z;
                    let p = eye + ray * (depth / per_unit);
                    let c = face * p.extend(1.0);
                    let tol = 1e-4;
                    assert!(
                        c.x.abs() <= edge + tol && c.y.abs() <= edge + tol,
                        "case {case}, cascade {k}: {p} at {c}"
                    );
                    assert!(
                        c.z >= -tol && c.z <= 1.0 + tol,
                        "case {case}, cascade {k}: depth {}",
                        c.z
                    );
                }
            }
        }
    }
}
