//! The on-disk cache of reference images, keyed by the scene file, the size and the sources
//! the reference depends on.

use std::path::{Path, PathBuf};
use std::time::Instant;

use volshadow::glam::DVec3;
use volshadow::scene_file::SceneDescription;

use super::measure::Context;
use super::render_scene::reference_inscatter;
use super::{BoxError, Options};

/// The file `path`'s reference at `size` is cached in: `OUT/cache/NAME-WxH-KEY.f64`.
pub fn cache_file(
    options: &Options,
    path: &Path,
    scene: &SceneDescription,
    size: (u32, u32),
) -> Result<PathBuf, BoxError> {
    let text = std::fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    let key = reference_key(&text, size);
    Ok(options.out.join("cache").join(format!(
        "{}-{}x{}-{key:016x}.f64",
        scene.name, size.0, size.1
    )))
}

/// Whether the reference is in the cache (a file of the right length).
pub fn is_cached(
    options: &Options,
    path: &Path,
    scene: &SceneDescription,
    size: (u32, u32),
) -> Result<bool, BoxError> {
    let file = cache_file(options, path, scene, size)?;
    let bytes = u64::from(size.0) * u64::from(size.1) * 24;
    Ok(std::fs::metadata(file).is_ok_and(|m| m.is_file() && m.len() == bytes))
}

/// The reference in-scatter, from the cache or computed and cached.
pub fn cached_reference(
    ctx: &Context,
    options: &Options,
    path: &Path,
    scene: &SceneDescription,
    camera: &volshadow::Camera,
    size: (u32, u32),
) -> Result<Vec<DVec3>, BoxError> {
    let file = cache_file(options, path, scene, size)?;
    let pixels = (size.0 * size.1) as usize;
    if let Ok(bytes) = std::fs::read(&file) {
        if bytes.len() == pixels * 24 {
            ctx.progress(&format!("  reference from the cache ({})", file.display()));
            return Ok(bytes
                .chunks_exact(24)
                .map(|c| {
                    let f = |i: usize| {
                        f64::from_le_bytes(c[i * 8..i * 8 + 8].try_into().expect("8 bytes"))
                    };
                    DVec3::new(f(0), f(1), f(2))
                })
                .collect());
        }
    }
    ctx.progress(&format!(
        "  reference: f64 integrator at {}x{} (not cached yet) …",
        size.0, size.1
    ));
    let start = Instant::now();
    let image = reference_inscatter(scene, camera, size);
    let bytes: Vec<u8> = image
        .iter()
        .flat_map(|v| [v.x, v.y, v.z])
        .flat_map(f64::to_le_bytes)
        .collect();
    std::fs::write(&file, bytes).map_err(|e| format!("cannot write {}: {e}", file.display()))?;
    ctx.progress.reference_done(start.elapsed());
    ctx.progress(&format!(
        "  reference done in {:.1} s, cached as {}",
        start.elapsed().as_secs_f64(),
        file.display()
    ));
    Ok(image)
}

/// The source files the reference images depend on: the integrator, the scene types, the
/// scene-file and glTF loaders and the ray caster that finds each pixel's surface. Whole
/// folders are listed at run time, so a file added to them cannot be forgotten.
pub fn reference_sources() -> Vec<std::path::PathBuf> {
    let root = crate::repo_root();
    let mut files = Vec::new();
    for dir in ["src/reference", "src/scene", "src/scene_file", "src/gltf"] {
        if let Ok(entries) = std::fs::read_dir(root.join(dir)) {
            files.extend(
                entries
                    .filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|p| p.extension().is_some_and(|x| x == "rs")),
            );
        }
    }
    for file in [
        "src/load.rs",
        "src/error.rs",
        "harness/src/render_scene.rs",
        "harness/src/gltf_scene.rs",
    ] {
        files.push(root.join(file));
    }
    files.sort();
    files
}

/// FNV-1a over the scene file, the size and every source the reference depends on
/// ([`reference_sources`]): a change to the integrator or the scene loader invalidates the
/// cache.
pub fn reference_key(scene_file: &[u8], (w, h): (u32, u32)) -> u64 {
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            hash ^= u64::from(b);
            hash = hash.wrapping_mul(0x0100_0000_01b3);
        }
    };
    eat(scene_file);
    eat(&w.to_le_bytes());
    eat(&h.to_le_bytes());
    for source in reference_sources() {
        eat(source.to_string_lossy().as_bytes());
        // A missing file hashes as its name alone, which still differs from its contents.
        eat(&std::fs::read(&source).unwrap_or_default());
    }
    hash
}
