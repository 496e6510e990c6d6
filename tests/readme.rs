//! The README's application `Cargo.toml` against the crate's own (issue 36): the versions it
//! tells an application to use are the ones volshadow is built on, and what it says about
//! backends is true. A wgpu or pollster bump without the README's lines fails here.

use std::path::Path;

fn read(name: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(name);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The first fenced block of `lang` in `markdown`.
fn first_block(markdown: &str, lang: &str) -> String {
    let fence = format!("```{lang}\n");
    let start = markdown
        .find(&fence)
        .unwrap_or_else(|| panic!("no {lang} block"))
        + fence.len();
    let len = markdown[start..].find("```").expect("unterminated block");
    markdown[start..start + len].to_string()
}

/// The value of `name = ...` in the lines of `section` (the whole text when `None`).
fn entry(text: &str, section: Option<&str>, name: &str) -> String {
    let mut current: Option<&str> = None;
    for line in text.lines() {
        let line = line.trim();
        if line.starts_with('[') {
            current = Some(line);
            continue;
        }
        if section.is_some() && current != section {
            continue;
        }
        if let Some(rest) = line.strip_prefix(name) {
            if let Some(value) = rest.trim_start().strip_prefix('=') {
                return value.trim().to_string();
            }
        }
    }
    panic!("no `{name} =` in {section:?}")
}

/// `"30"` → `30`; `{ version = "30", ... }` → `30`.
fn version(value: &str) -> String {
    let v = match value.find("version") {
        Some(i) => &value[i..],
        None => value,
    };
    v.split('"').nth(1).expect("a quoted version").to_string()
}

#[test]
fn readme_app_manifest_matches_the_crate() {
    let readme = read("README.md");
    let manifest = read("Cargo.toml");
    let app = first_block(&readme, "toml");
    let deps = Some("[dependencies]");

    // volshadow: a requirement the crate's own version satisfies (`0.1` for 0.1.x).
    let wanted = version(&entry(&app, deps, "volshadow"));
    let own = env!("CARGO_PKG_VERSION");
    assert!(
        own == wanted || own.starts_with(&format!("{wanted}.")),
        "README asks for volshadow {wanted}, the crate is {own}"
    );
    // wgpu: the same major version as the crate's dependency.
    let ours = entry(&manifest, deps, "wgpu");
    assert_eq!(
        version(&entry(&app, deps, "wgpu")),
        version(&ours),
        "README's wgpu against Cargo.toml's"
    );
    // "volshadow itself enables none" of the backends.
    for backend in ["vulkan", "metal", "dx12", "gles", "webgpu"] {
        assert!(
            !ours.contains(&format!("\"{backend}\"")),
            "Cargo.toml's wgpu enables {backend}, the README says volshadow enables no backend"
        );
    }
    assert!(ours.contains("default-features = false"), "{ours}");
    // pollster: the version the crate (and its HeadlessGpu) uses.
    assert_eq!(
        version(&entry(&app, deps, "pollster")),
        version(&entry(&manifest, deps, "pollster"))
    );
    println!(
        "README app manifest: volshadow {wanted}, wgpu {}, pollster matches",
        version(&ours)
    );
}
