//! Loads every mesh of a glTF model as an occluder, prints each mesh's topology and what it
//! means for its shadow volume, frames the model over a ground plane with a point light above
//! and behind it in hazy fog, and renders its dark shafts to `OUT.png` and the in-scattered
//! light alone to `OUT.inscatter.exr`.
//!
//! ```text
//! cargo run --release --features gltf --example gltf -- MODEL.gltf|MODEL.glb [-o OUT] [--size WxH]
//! ```
//!
//! How the scene is set up around the model is documented in `examples/common/gltf_scene.rs`.
//! The plan and per-pass GPU times are printed. Bad arguments or files print the error and
//! exit with status 1.

#[path = "../common/mod.rs"]
mod common;

fn main() {
    common::headless_env::quiet_display_probe();
    let args: Vec<String> = std::env::args().skip(1).collect();
    if let Err(e) = common::gltf_scene::run(&args) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
