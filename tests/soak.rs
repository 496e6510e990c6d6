//! The soak example, short: 200 frames at 96×64 with everything animated, a resize and a
//! settings switch every 20 frames, on top of one warm-up frame per size and settings.

#[path = "../examples/soak/main.rs"]
#[allow(dead_code)]
mod soak;

#[test]
fn soak_200_frames_keeps_memory_flat_with_no_errors_or_nan() {
    let gpu =
        volshadow::HeadlessGpu::new().expect("GPU tests need a wgpu adapter (lavapipe works)");
    let options = soak::Options {
        frames: 200,
        size: (96, 64),
        report_every: 20,
        resize_every: 20,
        settings_every: 20,
        warmup: 100,
        // About a minute: on lavapipe a frame here takes ~50 ms; a shader compile per frame
        // (what uniform buffers cost there) takes several times the budget.
        max_seconds: Some(60.0),
    };
    let summary = soak::run(&gpu, &options).unwrap();
    // Every configuration (2 sizes × 4 settings) ran, and the last block has a twin after the
    // warm-up to compare its RSS with.
    assert_eq!(summary.blocks.len(), 10);
    // The soak's verdict: no validation error, no NaN/Inf, RSS within 5% after frame 100, in
    // budget (the thresholds are the issue's, see the example's `Summary::failures`).
    assert!(
        summary.failures().is_empty(),
        "{:?}: {:?}",
        summary.failures(),
        summary.blocks
    );
}
