//! The examples as tests: each example's code is included and run small (the quickstart against
//! the f64 reference, the render and gltf runs, the report, the soak, the measurements tool),
//! so an example that no longer builds or works fails the suite. One test binary.
// Each example is a complete program that includes the shared files it needs
// (`examples/common/`); this binary includes several examples, so some files load twice.
#![allow(clippy::duplicate_mod)]

#[macro_use]
#[path = "../common/mod.rs"]
mod common;

mod examples;
mod quickstart;
mod soak;
