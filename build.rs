//! The list of shared WGSL files, derived from the folder: every `.wgsl` file under
//! `shaders/shared/` becomes an entry of `gpu::wgsl::FILES` (named by its path inside that
//! folder, as an `#import` line names it), so that adding a shared file is adding the file.

use std::path::{Path, PathBuf};
use std::{env, fs};

fn main() {
    let root = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets it"));
    let shared = root.join("shaders").join("shared");
    // A folder here makes cargo rerun the script when anything under it changes.
    println!("cargo:rerun-if-changed=shaders/shared");
    let mut files = Vec::new();
    collect(&shared, &shared, &mut files);
    files.sort();
    let mut out = String::from("&[\n");
    for name in &files {
        let path = shared.join(name);
        out.push_str(&format!(
            "    Wgsl {{ name: {name:?}, text: include_str!({:?}) }},\n",
            path.to_str().expect("a UTF-8 path")
        ));
    }
    out.push_str("]\n");
    let dest = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets it")).join("shared_wgsl.rs");
    fs::write(&dest, out).expect("OUT_DIR is writable");
}

/// The `.wgsl` files under `dir`, as `/`-separated paths relative to `base`.
fn collect(base: &Path, dir: &Path, files: &mut Vec<String>) {
    let entries = fs::read_dir(dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    for entry in entries {
        let path = entry.expect("a folder entry").path();
        if path.is_dir() {
            collect(base, &path, files);
        } else if path.extension().is_some_and(|e| e == "wgsl") {
            let relative = path.strip_prefix(base).expect("under the base");
            let parts: Vec<&str> = relative
                .components()
                .map(|c| c.as_os_str().to_str().expect("a UTF-8 file name"))
                .collect();
            files.push(parts.join("/"));
        }
    }
}
