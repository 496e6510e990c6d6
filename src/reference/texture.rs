//! Textured spot lights in the reference: the projection of a point onto a spot light's
//! [`LightTexture`] and the bilinear lookup, in f64, written from the definition in
//! [`LightTexture`]'s documentation (nothing shared with the GPU path).

use glam::{DVec2, DVec3};

use super::cone::Cone;
use super::unit;
use crate::scene::{LightTexture, SpotLight};

/// A spot light with a projected texture (gobo, stained glass): it emits
/// `spot.intensity() × bilinear(texture, uv(X))` towards a point `X` inside the cone and nothing
/// outside, with `uv` from [`TexturedSpot::uv`] and the lookup of [`bilinear`]. Pass it by
/// reference wherever the reference takes a light ([`inscatter`](super::inscatter),
/// [`inscatter_image`](super::inscatter_image), [`light_intervals`](super::light_intervals)):
/// it implements [`LightSource`](super::LightSource). Its lit intervals are the untextured
/// spot's (texels of 0 are dark but not "unlit").
#[derive(Debug, Clone, Copy)]
pub struct TexturedSpot<'a> {
    /// The spot light: position, cone, intensity (the factor multiplying every texel).
    pub spot: SpotLight,
    /// The projected texture, linear RGB.
    pub texture: &'a LightTexture,
}

impl<'a> TexturedSpot<'a> {
    /// `spot` projecting `texture`.
    pub fn new(spot: SpotLight, texture: &'a LightTexture) -> Self {
        Self { spot, texture }
    }

    /// The texture coordinates of the point `point`, from [`LightTexture`]'s definition,
    /// in f64: `(x, y, z)` is `point` in the spot's texture frame, `t = tan(cone_angle/2)`,
    /// `uv = (0.5 + 0.5·x/(−z·t), 0.5 − 0.5·y/(−z·t))`, so the axis maps to `(0.5, 0.5)`, the
    /// cone's edge to the circle of radius 0.5 around it, the frame's `+x` to `u = 1` and its
    /// `+y` to `v = 0` (the top row).
    ///
    /// The frame is that of [`SpotLight::texture_frame`] rebuilt in f64 (see
    /// [`texture_axes`]), so it agrees with the f32 matrix up to its rounding (~1e-7).
    /// `None` where `−z ≤ 0` (the apex itself and the half-space behind the light, which the
    /// cone never reaches) or for non-finite input; `u`, `v` may lie outside `[0, 1]` (inside the
    /// square but outside the cone, or outside the square) and may be infinite for points
    /// almost in the light's plane: [`bilinear`] clamps them.
    pub fn uv(&self, point: DVec3) -> Option<DVec2> {
        Projection::new(&self.spot, self.texture).uv(point - self.spot.position().as_dvec3())
    }

    /// The radiant intensity (RGB) emitted towards `point`: `spot.intensity() ×
    /// bilinear(texture, uv(point))` inside the cone (the test of
    /// [`SpotLight::cos_half_angle`], boundary included), 0 outside and at the apex itself.
    pub fn emission(&self, point: DVec3) -> DVec3 {
        if !Cone::new(&self.spot).contains(point) {
            return DVec3::ZERO;
        }
        self.uv(point).map_or(DVec3::ZERO, |uv| {
            self.spot.intensity().as_dvec3() * bilinear(self.texture, uv)
        })
    }
}

/// The spot's texture frame in f64: the unit vectors `(right, up, forward)` in world space of
/// the frame's `+x`, `+y` and `−z`, i.e. the rows of the rotation of
/// [`SpotLight::texture_frame`] (glam's right-handed `look_to`), rebuilt from its documented
/// rule: `forward` is the light's direction (renormalised in f64), the up hint is
/// [`SpotLight::texture_up`] when given, else `+Y` unless `|direction.y| ≥ 0.9` (then `+X`),
/// `right = normalize(forward × hint)`, `up = right × forward`.
pub fn texture_axes(spot: &SpotLight) -> (DVec3, DVec3, DVec3) {
    let dir = spot.direction();
    let hint = match spot.texture_up() {
        Some(up) => up.as_dvec3(),
        None if dir.y.abs() < 0.9 => DVec3::Y,
        None => DVec3::X,
    };
    let forward = unit(dir.as_dvec3()).unwrap_or(DVec3::NEG_Z);
    let right = unit(forward.cross(hint)).unwrap_or(DVec3::X);
    let up = right.cross(forward);
    (right, up, forward)
}

/// Bilinear lookup of `texture` at `uv` as the GPU's linear filter with clamp-to-edge does it,
/// in f64: texel `(i, j)` (column `i`, row `j`, row 0 at the top, `v = 0`) has its centre at
/// `((i + 0.5)/W, (j + 0.5)/H)`; with `p = u·W − 0.5` and `q = v·H − 0.5` clamped to
/// `[0, W − 1]` and `[0, H − 1]`, the result interpolates linearly in `p` between columns
/// `⌊p⌋` and `⌊p⌋ + 1` and in `q` between rows `⌊q⌋` and `⌊q⌋ + 1`. Written as `a + f·(b − a)`,
/// so a constant texture gives its colour exactly. `u = ±∞` clamps to the edge; NaN reads as
/// 0.5.
pub fn bilinear(texture: &LightTexture, uv: DVec2) -> DVec3 {
    let (w, h) = (texture.width() as usize, texture.height() as usize);
    let texels = texture.texels();
    let (i, fx) = axis(uv.x, w);
    let (j, fy) = axis(uv.y, h);
    let at = |i: usize, j: usize| texels[j * w + i].as_dvec3();
    let (i1, j1) = ((i + 1).min(w - 1), (j + 1).min(h - 1));
    let top = lerp(at(i, j), at(i1, j), fx);
    let bottom = lerp(at(i, j1), at(i1, j1), fx);
    lerp(top, bottom, fy)
}

/// `a + f·(b − a)`: exact when `a == b`.
fn lerp(a: DVec3, b: DVec3, f: f64) -> DVec3 {
    a + (b - a) * f
}

/// Along one axis of `n ≥ 1` texels: the lower texel index and the fraction towards the next.
fn axis(u: f64, n: usize) -> (usize, f64) {
    let u = if u.is_nan() { 0.5 } else { u };
    let last = (n - 1) as f64;
    let p = (u * n as f64 - 0.5).clamp(0.0, last);
    let i = (p.floor() as usize).min(n.saturating_sub(2));
    (i, p - i as f64)
}

/// The texture projection of a spot light in the form the integrator uses: offsets `w = X − P`
/// from the apex instead of points.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Projection<'a> {
    right: DVec3,
    up: DVec3,
    forward: DVec3,
    /// `tan(cone_angle/2)`, in f64 from the f32 angle.
    tan_half: f64,
    texture: &'a LightTexture,
}

impl<'a> Projection<'a> {
    pub(crate) fn new(spot: &SpotLight, texture: &'a LightTexture) -> Self {
        let (right, up, forward) = texture_axes(spot);
        Self {
            right,
            up,
            forward,
            tan_half: (0.5 * f64::from(spot.cone_angle())).tan(),
            texture,
        }
    }

    /// uv of the offset `w = X − P` (see [`TexturedSpot::uv`]).
    pub(crate) fn uv(&self, w: DVec3) -> Option<DVec2> {
        let depth = self.forward.dot(w);
        if !(depth > 0.0) {
            return None;
        }
        let q = depth * self.tan_half;
        let uv = DVec2::new(
            0.5 + 0.5 * (self.right.dot(w) / q),
            0.5 - 0.5 * (self.up.dot(w) / q),
        );
        (!uv.is_nan()).then_some(uv)
    }

    /// The texel factor (RGB) towards the offset `w = X − P`: [`bilinear`] at its uv, 0 where
    /// there is none.
    pub(crate) fn texel(&self, w: DVec3) -> DVec3 {
        self.uv(w)
            .map_or(DVec3::ZERO, |uv| bilinear(self.texture, uv))
    }

    /// The parameters `s` in `(lo, hi)` (`hi` may be `∞`) where the line `w(s) = w0 + s·v`
    /// (offsets from the apex; `v` unit) crosses a texel-centre line of the texture, appended
    /// to `out` (in no particular order): the places where the bilinear lookup has a kink.
    ///
    /// The line `u = (i + 0.5)/W` is the plane through the apex `x = k·t·(−z)`,
    /// `k = 2u − 1`, i.e. `(right − k·t·forward)·w = 0`, so each crossing is one ray–plane
    /// intersection (likewise `v = (j + 0.5)/H`, with `up` and `k = 1 − 2v`). Inside the cone
    /// (`−z > 0`) `u` and `v` are ratios of affine functions of `s`, hence monotonic, so only
    /// the lines between the values at the two ends can be crossed, each once: the cost is
    /// proportional to the number of crossings (at most `W + H`), not to the texture's size.
    /// Where an end has no uv (the apex, or behind the light) every line is tried.
    pub(crate) fn crossings(&self, w0: DVec3, v: DVec3, lo: f64, hi: f64, out: &mut Vec<f64>) {
        let start = self.uv(w0 + v * lo);
        let end = if hi.is_finite() {
            self.uv(w0 + v * hi)
        } else {
            self.uv(v) // the direction of X − P far along the ray
        };
        let (w, h) = (self.texture.width(), self.texture.height());
        let range = |a: Option<f64>, b: Option<f64>, n: u32| -> (u32, u32) {
            match (a, b) {
                (Some(a), Some(b)) => {
                    let (pa, pb) = (a * n as f64 - 0.5, b * n as f64 - 0.5);
                    let (lo, hi) = (pa.min(pb), pa.max(pb));
                    let first = lo.ceil().max(0.0);
                    let last = hi.floor().min((n - 1) as f64);
                    if first > last {
                        (1, 0)
                    } else {
                        (first as u32, last as u32)
                    }
                }
                _ => (0, n - 1),
            }
        };
        let (i0, i1) = range(start.map(|p| p.x), end.map(|p| p.x), w);
        let (j0, j1) = range(start.map(|p| p.y), end.map(|p| p.y), h);
        let t = self.tan_half;
        let mut cross = |normal: DVec3| {
            let nv = normal.dot(v);
            if nv != 0.0 {
                let s = -normal.dot(w0) / nv;
                if s > lo && s < hi {
                    out.push(s);
                }
            }
        };
        for i in i0..=i1 {
            let k = 2.0 * ((i as f64 + 0.5) / w as f64) - 1.0;
            cross(self.right - self.forward * (k * t));
        }
        for j in j0..=j1 {
            let k = 1.0 - 2.0 * ((j as f64 + 0.5) / h as f64);
            cross(self.up - self.forward * (k * t));
        }
    }
}
