//! `load::resolve_inside`, the rule every loader applies to the paths named inside files, on
//! arbitrary paths in a fixed tree of folders, files and symbolic links (relative, absolute,
//! into the folder, out of it, dangling, looping, to files and folders) beside a folder
//! outside. Each input is a path: its bytes as UTF-8 (lossy), or, where its first byte is
//! below 128, a sequence of the tree's names, `..`, `.` and missing names picked by the
//! remaining bytes. Properties, checked with the system's own resolution
//! (`std::fs::canonicalize` of the path as `Path::components` reads it) as the oracle:
//!
//! * a path it returns lies inside the folder: it is the folder, or its parent canonicalises
//!   inside, and so does the path where it exists;
//! * where it exists, it is the file the system reaches by the path as written; where it does
//!   not, the system reaches none;
//! * a path without `..` that the system leads to a file inside is resolved (the tree's links
//!   hold no `..`, so the system's walk of such a path never leaves the folder).
#![no_main]

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;

/// The names a generated path is made of.
const NAMES: [&str; 20] = [
    "d", "e", "f", "g.bin", "up", "out", "abs_in", "abs_out", "dangling", "loop", "fdir", "deep",
    "missing", "secret", "odir", "in", ".", "..", "", "x",
];

/// `(top, folder)`: a fresh temporary tree, made once per process.
fn tree() -> &'static (PathBuf, PathBuf) {
    static TREE: OnceLock<(PathBuf, PathBuf)> = OnceLock::new();
    TREE.get_or_init(|| {
        use std::os::unix::fs::symlink;
        let top = std::env::temp_dir().join(format!("volshadow-fuzz-paths-{}", std::process::id()));
        std::fs::create_dir_all(&top).unwrap();
        let top = top.canonicalize().unwrap();
        let folder = top.join("in");
        let _ = std::fs::remove_dir_all(&folder);
        std::fs::create_dir_all(folder.join("d/e")).unwrap();
        std::fs::create_dir_all(top.join("odir")).unwrap();
        std::fs::write(top.join("secret"), "s").unwrap();
        std::fs::write(top.join("odir/secret"), "s").unwrap();
        std::fs::write(folder.join("f"), "f").unwrap();
        std::fs::write(folder.join("d/g.bin"), "g").unwrap();
        std::fs::write(folder.join("d/e/g.bin"), "g").unwrap();
        let links: [(&str, PathBuf); 9] = [
            ("up", PathBuf::from("../secret")),
            ("d/out", top.join("odir")),
            ("abs_in", folder.join("d/e")),
            ("abs_out", top.join("secret")),
            ("dangling", PathBuf::from("missing/g.bin")),
            ("loop", PathBuf::from("loop")),
            ("fdir", PathBuf::from("f/x")),
            ("deep", PathBuf::from("d/e")),
            ("d/e/x", PathBuf::from("g.bin")),
        ];
        for (at, target) in links {
            let _ = std::fs::remove_file(folder.join(at));
            symlink(target, folder.join(at)).unwrap();
        }
        (top, folder)
    })
}

fuzz_target!(|data: &[u8]| {
    let (_, folder) = tree();
    let named: String = match data.split_first() {
        Some((&first, rest)) if first < 128 => rest
            .iter()
            .take(24)
            .map(|&b| NAMES[usize::from(b) % NAMES.len()])
            .collect::<Vec<_>>()
            .join("/"),
        _ => String::from_utf8_lossy(data).into_owned(),
    };
    if named.contains('\0') {
        return;
    }
    let inside = |p: &Path| p.starts_with(folder);
    // The system's walk of the path as `Path` reads it (`.` and a trailing separator dropped).
    let os = std::fs::canonicalize(folder.join(Path::new(&named).components().collect::<PathBuf>()));
    match volshadow::load::resolve_inside(folder, Path::new(&named)) {
        Ok(q) => {
            let parent = q.parent().and_then(|p| p.canonicalize().ok());
            assert!(
                q == *folder || parent.as_deref().is_some_and(inside),
                "{named:?} -> {q:?}: folder outside"
            );
            match (q.canonicalize(), &os) {
                (Ok(c), _) if !inside(&c) => panic!("{named:?} -> {c:?}: outside"),
                (Ok(c), Ok(o)) if c == *o => {}
                (Err(_), Err(_)) => {}
                (c, o) => panic!("{named:?} -> {q:?}: {c:?}, the system reaches {o:?}"),
            }
        }
        Err(_) => {
            let parent_free = !Path::new(&named)
                .components()
                .any(|c| c == std::path::Component::ParentDir);
            if let Ok(c) = &os {
                // The tree's links that leave the folder are `up`, `d/out` and `abs_out`;
                // a path through none of them and without `..` stays inside.
                let through_out = ["up", "out", "abs_out"]
                    .iter()
                    .any(|l| named.split('/').any(|w| w == *l));
                assert!(
                    !(parent_free && !through_out && inside(c) && !Path::new(&named).has_root()),
                    "{named:?} leads to {c:?} inside, refused"
                );
            }
        }
    }
});
