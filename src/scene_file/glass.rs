//! The procedural stained-glass light texture.

use glam::Vec3;

use crate::error::{Error, Result};
use crate::scene::LightTexture;

/// SplitMix64: a tiny deterministic generator, so a seed gives the same window everywhere.
struct SplitMix64(u64);

impl SplitMix64 {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn next_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// HSV (all in [0, 1]) to RGB.
fn hsv(h: f32, s: f32, v: f32) -> Vec3 {
    let h6 = (h.fract() * 6.0).min(5.999_999);
    let sector = h6 as u32;
    let f = h6 - sector as f32;
    let (p, q, t) = (v * (1.0 - s), v * (1.0 - s * f), v * (1.0 - s * (1.0 - f)));
    match sector {
        0 => Vec3::new(v, t, p),
        1 => Vec3::new(q, v, p),
        2 => Vec3::new(p, v, t),
        3 => Vec3::new(p, q, v),
        4 => Vec3::new(t, p, v),
        _ => Vec3::new(v, p, q),
    }
}

/// Colour of the lead between the panes (linear RGB).
const LEAD: Vec3 = Vec3::splat(0.01);

/// A stained-glass window: a `cells × cells` grid of panes of random saturated colours
/// (linear RGB, each channel in [0, 1]), separated by dark lead lines about 6% of a pane wide
/// (at least one texel), `size × size` texels. The colours depend only on `seed`, through a
/// SplitMix64 generator, so a scene file reproduces the same window on every machine.
///
/// # Errors
///
/// [`Error::InvalidSize`] unless `1 <= size <= LightTexture::MAX_SIZE`,
/// [`Error::InvalidSetting`] unless `1 <= cells <= size`.
pub fn stained_glass(size: u32, cells: u32, seed: u64) -> Result<LightTexture> {
    if size == 0 || size > LightTexture::MAX_SIZE {
        return Err(Error::InvalidSize {
            field: "stained_glass.size",
            width: size,
            height: size,
            min: 1,
            max: LightTexture::MAX_SIZE,
        });
    }
    if cells == 0 || cells > size {
        return Err(Error::InvalidSetting {
            field: "stained_glass.cells",
            problem: format!("must be in 1..={size} (the texture size), got {cells}"),
        });
    }
    let mut rng = SplitMix64(seed);
    let colours: Vec<Vec3> = (0..cells * cells)
        .map(|_| {
            let (h, s, v) = (
                rng.next_f32(),
                0.75 + 0.25 * rng.next_f32(),
                0.6 + 0.4 * rng.next_f32(),
            );
            // Squaring keeps the hues saturated once read as linear radiance.
            let c = hsv(h, s, v);
            c * c
        })
        .collect();
    let pane = size as f32 / cells as f32;
    let lead = (0.06 * pane).max(0.5);
    let coordinate = |i: u32| {
        let x = i as f32 + 0.5;
        let cell = ((x / pane) as u32).min(cells - 1);
        let local = x - cell as f32 * pane;
        (cell, local.min(pane - local))
    };
    let texels = (0..size * size)
        .map(|i| {
            let (cx, dx) = coordinate(i % size);
            let (cy, dy) = coordinate(i / size);
            if dx.min(dy) < lead {
                LEAD
            } else {
                colours[(cy * cells + cx) as usize]
            }
        })
        .collect();
    LightTexture::new(size, size, texels)
}
