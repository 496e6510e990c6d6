//! Renders a JSON scene file (`scenes/*.json`) headless: linear radiance and in-scatter as
//! OpenEXR, eye distance as OpenEXR, a tone-mapped PNG and a JSON timing report.
//!
//! ```text
//! cargo run --release --example render -- scenes/fence.json [-o out/fence] [--method hybrid:32:2] [--size 256x256]
//! ```
//!
//! The example plays the application: it rasterises the scene's objects into its own colour
//! and depth targets (lit, surfaces shadowed with volshadow's shadow maps through
//! `volshadow::SHADOW_WGSL`), then records volshadow's passes through `VolumetricShadows` into
//! its encoder — or, with `--method reference`, computes the in-scatter with the f64 CPU
//! reference. The options, methods and outputs are documented in
//! `volshadow_harness::render_scene` (`harness/src/render_scene.rs`); `--help` prints them. Outputs go to `out/` unless `-o`
//! says otherwise, and a run that would write over an input is refused. Bad arguments or
//! files print the error and exit with status 1.

use volshadow_harness::cli::Parsed;
use volshadow_harness::render_scene::{help, render, Options};

fn main() {
    volshadow_harness::headless_env::quiet_display_probe();
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = Options::parse(&args).and_then(|parsed| match parsed {
        Parsed::Help => {
            println!("{}", help());
            Ok(())
        }
        Parsed::Run(options) => render(&options).map(|_| ()),
    });
    if let Err(e) = result {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
