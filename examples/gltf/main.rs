//! Loads every mesh of a glTF model as an occluder, prints each mesh's topology and what it
//! means for its shadow volume, frames the model over a ground plane with a point light above
//! and behind it in hazy fog, and renders its dark shafts to `OUT.png` and the in-scattered
//! light alone to `OUT.inscatter.exr` (`OUT` defaults to `out/` and the model's stem).
//!
//! ```text
//! cargo run --release --features gltf --example gltf -- MODEL.gltf|MODEL.glb [-o OUT] [--size WxH]
//! ```
//!
//! How the scene is set up around the model is documented in `volshadow_harness::gltf_scene` (`harness/src/gltf_scene.rs`);
//! `--help` prints the options. The plan and per-pass GPU times are printed. A run that would
//! write over an input is refused. Bad arguments or files print the error and exit with
//! status 1.

use volshadow_harness::cli::Parsed;
use volshadow_harness::gltf_scene::{render, Options, HELP};

fn main() {
    volshadow_harness::headless_env::quiet_display_probe();
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = Options::parse(&args).and_then(|parsed| match parsed {
        Parsed::Help => {
            println!("{HELP}");
            Ok(())
        }
        Parsed::Run(options) => render(&options).map(|_| ()),
    });
    if let Err(e) = result {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
