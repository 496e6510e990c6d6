//! The scene-file parser on arbitrary bytes (UTF-8 text only: `from_json` takes a `&str`).
#![no_main]

mod common;

use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use volshadow::scene_file::SceneDescription;

static FOLDER: OnceLock<std::path::PathBuf> = OnceLock::new();

fuzz_target!(|data: &[u8]| {
    let folder = FOLDER.get_or_init(common::empty_folder);
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = SceneDescription::from_json_with(text, folder, &common::options());
    }
});
