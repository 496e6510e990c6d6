//! The tests that need no GPU: the f64 reference against closed forms and brute force, scene
//! files, glTF and the load bounds, meshes, the crate's layering, and the README's front door.
//! One test binary (one link step); each file beside this one is a topic. What the tiers share
//! (the device, metric lines, scenes) is `volshadow_harness`.
//! `cargo test --test cpu` runs them alone, in about a minute.

mod file_limits;
mod gltf;
mod layers;
mod mesh;
mod readme;
mod reference;
mod reference_directional;
mod reference_iss;
mod reference_mesh;
mod reference_soft;
mod reference_spot;
mod reference_texture;
mod scene_file;
