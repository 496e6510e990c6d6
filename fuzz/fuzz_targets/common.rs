//! Shared by the fuzz targets: the bounds each input is loaded with.

use volshadow::LoadOptions;

/// Bounds small enough that every input finishes well within the fuzzer's timeout (the
/// default bounds let one input build millions of triangles, seconds of work that would only
/// slow the search): the code paths that check them are the same.
pub fn options() -> LoadOptions {
    LoadOptions {
        max_triangles: 1 << 16,
        max_texels: 1 << 18,
        max_file_bytes: 1 << 20,
        max_total_bytes: 1 << 22,
        ..LoadOptions::default()
    }
}

#[allow(dead_code)] // not every target resolves paths
/// An empty folder for the scene's relative paths, so no input reads a real file.
pub fn empty_folder() -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("volshadow-fuzz-empty-{}", std::process::id()));
    let _ = std::fs::create_dir_all(&dir);
    dir
}
