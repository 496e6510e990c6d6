//! The examples as tests: each example's code is run small (the render and gltf runs against
//! the f64 reference, their command lines and refusals), so an example that no longer builds or
//! works fails the suite. One test binary. The shared code is `volshadow_harness`; the
//! quickstart's own test sits beside it (`examples/quickstart/quickstart.rs`, run with the
//! crate's tests), the tools' in `tools/tests/`.

mod examples;
