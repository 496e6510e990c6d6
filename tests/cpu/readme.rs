//! The README's application `Cargo.toml` against the crate's own (issue 36): the versions it
//! tells an application to use are the ones volshadow is built on, and what it says about
//! backends is true. A wgpu or pollster bump without the README's lines fails here. And the
//! README as a front door (issue 38): its size, CI's exact test command, no dated narrative,
//! and generated measurement documents that match the runs they are generated from.

use volshadow_harness::{docs, metric};

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

/// Whether `line` holds a date `YYYY-MM-DD`.
fn has_date(line: &str) -> bool {
    let b = line.as_bytes();
    b.windows(10).any(|w| {
        w.iter().enumerate().all(|(i, c)| match i {
            4 | 7 => *c == b'-',
            _ => c.is_ascii_digit(),
        })
    })
}

/// Issue 38's front door: at most 12 KiB; the test command CI runs (the last line of
/// `.ci/run`) byte for byte in a shell block; the generated documents and the command that
/// regenerates them named; dates only in the "How good it is" table, where each figure names
/// the run it comes from (the narrative history is in CHANGELOG.md).
#[test]
fn readme_is_a_front_door() {
    let readme = read("README.md");
    const MAX: usize = 12 * 1024;
    println!("README: {} bytes (at most {MAX})", readme.len());
    assert!(
        readme.len() <= MAX,
        "README is {} bytes, over {MAX}",
        readme.len()
    );
    let ci = read(".ci/run");
    let command = ci
        .lines()
        .rev()
        .find(|l| !l.trim().is_empty())
        .expect("an empty .ci/run");
    assert!(
        readme.contains(&format!("```sh\n{command}\n```")),
        "the README does not give CI's test command `{command}` in a shell block of its own"
    );
    for named in [
        "docs/ACCURACY.md",
        "docs/PERFORMANCE.md",
        "docs/METHOD.md",
        ".ci/measure",
        "cargo run -p volshadow_tools --bin measurements",
    ] {
        assert!(readme.contains(named), "the README does not name {named}");
    }
    let dated: Vec<&str> = readme
        .lines()
        .filter(|l| has_date(l) && !l.starts_with('|'))
        .collect();
    assert!(
        dated.is_empty(),
        "dated lines outside the table: {dated:#?}"
    );
    assert!(has_date("on 2026-11-26,") && !has_date("2026-1-26"));
}

/// `docs/ACCURACY.md` and `docs/PERFORMANCE.md` are exactly what `cargo run -p volshadow_tools
/// --bin measurements -- --docs-only` writes from `docs/measurements/*.tsv`: a hand edit, or a run's
/// file committed without its documents, fails here.
#[test]
fn generated_documents_match_their_runs() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let runs = docs::read_runs(&root.join("docs/measurements")).expect("docs/measurements");
    assert!(!runs.is_empty(), "no run in docs/measurements");
    for (doc, file) in [
        (metric::Doc::Accuracy, "docs/ACCURACY.md"),
        (metric::Doc::Performance, "docs/PERFORMANCE.md"),
    ] {
        let expected = docs::document(doc, &runs);
        let committed = read(file);
        assert!(
            committed == expected,
            "{file} is not what `cargo run -p volshadow_tools --bin measurements -- --docs-only` writes from \
             docs/measurements/*.tsv (edited by hand, or not regenerated)"
        );
        let rows = committed.lines().filter(|l| l.starts_with("| ")).count();
        println!("{file}: {rows} table rows from {} runs", runs.len());
    }
}

/// One front door (issue 66, item 6): the crate's rustdoc opens with the README itself,
/// included (`#![doc = include_str!("../README.md")]`), and its own `//!` text repeats no line
/// of the README's prose (code aside), so the two cannot drift apart. Without the include (the rustdoc
/// writing its own introduction, as it did before) this fails, and so does a README paragraph
/// copied into the crate docs.
#[test]
fn the_crate_docs_open_with_the_readme() {
    let lib = read("src/lib.rs");
    let readme = read("README.md");
    let first = lib
        .lines()
        .find(|l| !l.trim().is_empty())
        .expect("an empty src/lib.rs");
    assert_eq!(
        first, "#![doc = include_str!(\"../README.md\")]",
        "src/lib.rs does not open with the README as its crate documentation"
    );
    let docs: String = lib
        .lines()
        .filter_map(|l| l.trim_start().strip_prefix("//!"))
        .map(|l| l.trim())
        .collect::<Vec<_>>()
        .join(" ");
    // The README's prose: its lines outside fenced code blocks (the two examples' code may
    // share a line such as an import list).
    let mut in_code = false;
    let prose = readme.lines().map(str::trim).filter(|l| {
        if l.starts_with("```") {
            in_code = !in_code;
            return false;
        }
        !in_code
    });
    let repeated: Vec<&str> = prose
        .filter(|l| l.len() >= 60 && !l.starts_with('|') && !l.starts_with('<'))
        .filter(|l| docs.contains(*l))
        .collect();
    assert!(
        repeated.is_empty(),
        "README lines repeated in src/lib.rs's own docs: {repeated:#?}"
    );
    println!(
        "crate docs: README included, {} further lines of their own",
        lib.lines().filter(|l| l.starts_with("//!")).count()
    );
}
