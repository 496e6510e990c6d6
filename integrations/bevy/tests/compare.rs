//! The `compare` example's scene as a test: both renderers draw the scene, and the key that
//! switches them really switches (the two pictures differ). The scene and its headless render
//! are `volshadow_bevy_scene`, which the example and this test share.

use volshadow_bevy_scene::{render, Mode};

const W: u32 = 96;
const H: u32 = 54;

fn spread(pixels: &[u8]) -> f64 {
    let grey: Vec<f64> = pixels.chunks_exact(4).map(|p| f64::from(p[1])).collect();
    let mean = grey.iter().sum::<f64>() / grey.len() as f64;
    (grey.iter().map(|g| (g - mean).powi(2)).sum::<f64>() / grey.len() as f64).sqrt()
}

/// Both modes render a picture with content (a standard deviation of the green channel above
/// 10 of 255: a blank or uniform target reads 0), and they are different pictures (a mean
/// absolute difference above 1 of 255: the same renderer twice reads 0).
#[test]
fn both_modes_render_and_differ() {
    let ours = render(Mode::Volshadow, W, H);
    let bevy = render(Mode::BevyFog, W, H);
    assert_eq!(ours.len(), (W * H * 4) as usize);
    assert_eq!(bevy.len(), ours.len());
    let difference = ours
        .iter()
        .zip(&bevy)
        .map(|(a, b)| f64::from(a.abs_diff(*b)))
        .sum::<f64>()
        / ours.len() as f64;
    println!(
        "compare at {W}x{H}: spread volshadow {:.1}, Bevy fog {:.1}; mean difference {difference:.2} of 255",
        spread(&ours),
        spread(&bevy)
    );
    assert!(spread(&ours) > 10.0 && spread(&bevy) > 10.0);
    assert!(difference > 1.0, "{difference}");
}
