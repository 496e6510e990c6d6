//! The demo-scene visibility measure (issue 13): how much of a picture its shadows change.
//! Used by the tests that judge a picture.

use std::path::Path;

/// Shadows must be visible in the picture, not only in the in-scatter: at least this fraction
/// of a standard scene's tone-mapped PNG must differ from the same scene without occluder
/// shadows (issue 13: "≥ 10% of the pixel value over ≥ 5% of the image").
pub const MIN_VISIBLE_FRACTION: f64 = 0.05;
/// A pixel differs when its mean 8-bit sRGB value moves by at least this fraction of the
/// unshadowed value ...
pub const MIN_PIXEL_CHANGE: f64 = 0.10;
/// ... and by at least this many levels, so that rounding in near-black pixels does not count.
pub const MIN_LEVELS: f64 = 3.0;

/// The fraction of pixels whose mean sRGB value differs between `shadowed` and `unshadowed`
/// (8-bit RGBA, the same size) by at least [`MIN_PIXEL_CHANGE`] of the unshadowed value and
/// [`MIN_LEVELS`] levels.
pub fn visible_fraction_rgba(shadowed: &[u8], unshadowed: &[u8]) -> f64 {
    assert_eq!(shadowed.len(), unshadowed.len());
    let mean = |p: &[u8]| p[..3].iter().map(|&v| f64::from(v)).sum::<f64>() / 3.0;
    let pixels = shadowed.len() / 4;
    let differ = shadowed
        .chunks_exact(4)
        .zip(unshadowed.chunks_exact(4))
        .filter(|(s, u)| {
            let (s, u) = (mean(s), mean(u));
            (s - u).abs() >= (MIN_PIXEL_CHANGE * u).max(MIN_LEVELS)
        })
        .count();
    differ as f64 / pixels as f64
}

/// [`visible_fraction_rgba`] of two image files.
pub fn visible_fraction(shadowed: &Path, unshadowed: &Path) -> f64 {
    let read = |p: &Path| image::open(p).unwrap().into_rgba8();
    let (a, b) = (read(shadowed), read(unshadowed));
    assert_eq!(a.dimensions(), b.dimensions());
    visible_fraction_rgba(a.as_raw(), b.as_raw())
}
