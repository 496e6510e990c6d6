//! The crate's top-level modules form layers that only point down: every `crate::` path in
//! `src/` (unit tests included) names a module of a lower layer, or its own. Paths through the
//! crate root's re-exports (`crate::Settings`) count as the module they come from. Read from the
//! source text, not from rustdoc or the compiler, so the check runs with the suite.
//!
//! `LAYERS` is the order, bottom up, that `docs/GUIDE.md`'s "Layout" describes. A module not in
//! it, an upward edge, or a cycle fails with the file and line of each offending path.
//!
//! Inside `src/nodes/` the modules form no circle either (`modules_inside_nodes_form_no_circle`).
//!
//! Also read from the source: every pass begins through `gpu::passes`, which counts it.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Bottom up. A module may use any module of a lower layer; modules of one layer use neither
/// each other nor anything above.
const LAYERS: &[&[&str]] = &[
    &["error"],
    &["load"],
    &["scene"],
    &["reference", "gltf", "pass", "light"],
    &["gpu"],
    &["nodes"],
    &["settings", "frame", "scene_file"],
    &["plan"],
    &["facade"],
];

/// One use of another top-level module: `from` → `to` at `site` (file:line).
#[derive(Debug, Clone)]
struct Edge {
    from: String,
    to: String,
    site: String,
}

/// The text with `//` comments removed (doc links are not dependencies), keeping line breaks.
fn strip_comments(text: &str) -> String {
    text.lines()
        .map(|line| {
            let mut in_string = false;
            let bytes = line.as_bytes();
            let mut cut = line.len();
            let mut i = 0;
            while i < bytes.len() {
                match bytes[i] {
                    b'\\' if in_string => i += 1,
                    b'"' => in_string = !in_string,
                    b'/' if !in_string && bytes.get(i + 1) == Some(&b'/') => {
                        cut = i;
                        break;
                    }
                    _ => {}
                }
                i += 1;
            }
            &line[..cut]
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// `name → module` for the root's `pub use module::…::{A, B};` lines.
fn root_reexports(lib: &str) -> BTreeMap<String, String> {
    let mut map = BTreeMap::new();
    let text = strip_comments(lib);
    for stmt in text.split(';') {
        // A statement may begin after an item's closing brace (`}` of a trait before the
        // first `pub use`), so the re-export is found where it begins, not at the start.
        let Some(at) = stmt.find("pub use ") else {
            continue;
        };
        let path = &stmt[at + "pub use ".len()..];
        let Some((module, rest)) = path.split_once("::") else {
            continue;
        };
        let names = rest.rsplit("::").next().unwrap_or(rest);
        for name in names.split(|c: char| !(c.is_alphanumeric() || c == '_')) {
            if !name.is_empty() {
                map.insert(name.to_string(), module.to_string());
            }
        }
    }
    map
}

/// Every module a file's text names through `crate::`, with its line: `crate::x` and the
/// first names of a `crate::{x, y::z}` group, re-exports resolved through `reexports`.
fn uses(text: &str, reexports: &BTreeMap<String, String>) -> Vec<(String, usize)> {
    uses_after(text, "crate::", reexports)
}

/// Every name a file's text names after `prefix` (`crate::`, `crate::nodes::`, …), as
/// [`uses`] does; a prefix right after an identifier or `::` is part of a longer path and
/// skipped.
fn uses_after(
    text: &str,
    prefix: &str,
    reexports: &BTreeMap<String, String>,
) -> Vec<(String, usize)> {
    let text = strip_comments(text);
    let ident = |s: &str| -> String {
        s.chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect()
    };
    let resolve = |name: String| reexports.get(&name).cloned().unwrap_or(name);
    let mut found = Vec::new();
    for (at, _) in text.match_indices(prefix) {
        if at > 0 {
            let before = text.as_bytes()[at - 1];
            if before.is_ascii_alphanumeric() || before == b'_' || before == b':' {
                continue; // `volshadow_crate::`, `crate::nodes::` for `nodes::`, or similar
            }
        }
        let line = text[..at].matches('\n').count() + 1;
        let rest = &text[at + prefix.len()..];
        if let Some(group) = rest.strip_prefix('{') {
            let group = &group[..group.find('}').unwrap_or(group.len())];
            // Only the first segment of each comma-separated path.
            let mut depth = 0;
            let mut start = true;
            for (i, c) in group.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' => depth -= 1,
                    ',' if depth == 0 => start = true,
                    c if start && (c.is_alphanumeric() || c == '_') => {
                        found.push((resolve(ident(&group[i..])), line));
                        start = false;
                    }
                    _ => {}
                }
            }
        } else {
            found.push((resolve(ident(rest)), line));
        }
    }
    found
}

/// The top-level modules of a crate's `src/` (files and folders beside `lib.rs`).
fn top_modules(src: &Path) -> BTreeSet<String> {
    let mut modules = BTreeSet::new();
    for entry in std::fs::read_dir(src).expect("read src/") {
        let path = entry.expect("entry").path();
        let name = path.file_stem().unwrap().to_string_lossy().to_string();
        if path.is_dir() || (path.extension().is_some_and(|e| e == "rs") && name != "lib") {
            modules.insert(name);
        }
    }
    modules
}

fn rust_files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("read dir") {
        let path = entry.expect("entry").path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// Every use of one top-level module by another in the crate at `src`, from `(path, text)`
/// pairs relative to `src`.
fn edges(files: &[(String, String)], lib: &str, modules: &BTreeSet<String>) -> Vec<Edge> {
    let reexports = root_reexports(lib);
    let mut out = Vec::new();
    for (path, text) in files {
        let from = path
            .split('/')
            .next()
            .unwrap()
            .trim_end_matches(".rs")
            .to_string();
        if from == "lib" {
            continue;
        }
        for (to, line) in uses(text, &reexports) {
            if to != from && modules.contains(&to) {
                out.push(Edge {
                    from: from.clone(),
                    to,
                    site: format!("{path}:{line}"),
                });
            }
        }
    }
    out
}

/// The edges that break `layers`: into a module of the same or a higher layer, or touching
/// a module no layer names.
fn violations(edges: &[Edge], modules: &BTreeSet<String>, layers: &[&[&str]]) -> Vec<String> {
    let layer_of = |m: &str| layers.iter().position(|l| l.contains(&m));
    let mut out: Vec<String> = modules
        .iter()
        .filter(|m| layer_of(m).is_none())
        .map(|m| format!("module `{m}` is in no layer"))
        .collect();
    for e in edges {
        if let (Some(a), Some(b)) = (layer_of(&e.from), layer_of(&e.to)) {
            if b >= a {
                out.push(format!(
                    "{} -> {} at src/{} (layer {a} uses layer {b})",
                    e.from, e.to, e.site
                ));
            }
        }
    }
    out
}

/// A cycle among the modules, if any (depth-first search), as `a -> b -> … -> a`.
fn cycle(edges: &[Edge]) -> Option<Vec<String>> {
    let mut graph: BTreeMap<&str, BTreeSet<&str>> = BTreeMap::new();
    for e in edges {
        graph.entry(&e.from).or_default().insert(&e.to);
    }
    fn visit<'a>(
        node: &'a str,
        graph: &BTreeMap<&'a str, BTreeSet<&'a str>>,
        state: &mut BTreeMap<&'a str, u8>,
        stack: &mut Vec<&'a str>,
    ) -> Option<Vec<String>> {
        state.insert(node, 1);
        stack.push(node);
        for &next in graph.get(node).into_iter().flatten() {
            match state.get(next).copied().unwrap_or(0) {
                1 => {
                    let from = stack.iter().position(|&n| n == next).unwrap();
                    let mut c: Vec<String> = stack[from..].iter().map(|s| s.to_string()).collect();
                    c.push(next.to_string());
                    return Some(c);
                }
                0 => {
                    if let Some(c) = visit(next, graph, state, stack) {
                        return Some(c);
                    }
                }
                _ => {}
            }
        }
        stack.pop();
        state.insert(node, 2);
        None
    }
    let mut state = BTreeMap::new();
    let nodes: Vec<&str> = graph.keys().copied().collect();
    for n in nodes {
        if state.get(n).copied().unwrap_or(0) == 0 {
            if let Some(c) = visit(n, &graph, &mut state, &mut Vec::new()) {
                return Some(c);
            }
        }
    }
    None
}

#[test]
fn top_level_modules_only_point_down() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let modules = top_modules(&src);
    let mut paths = Vec::new();
    rust_files(&src, &mut paths);
    let files: Vec<(String, String)> = paths
        .iter()
        .map(|p| {
            let rel = p
                .strip_prefix(&src)
                .unwrap()
                .to_string_lossy()
                .replace('\\', "/");
            (rel, std::fs::read_to_string(p).expect("read source"))
        })
        .collect();
    let lib = std::fs::read_to_string(src.join("lib.rs")).expect("read lib.rs");
    let edges = edges(&files, &lib, &modules);
    let mut summary: BTreeMap<(String, String), usize> = BTreeMap::new();
    for e in &edges {
        *summary.entry((e.from.clone(), e.to.clone())).or_default() += 1;
    }
    println!(
        "{} files, {} top-level modules:",
        files.len(),
        modules.len()
    );
    for ((from, to), n) in &summary {
        println!("  {from} -> {to} ({n} paths)");
    }
    // The parser must see the crate's own edges: the facade drives the nodes and the nodes
    // are built on `gpu`. A parser that found nothing would pass every rule below.
    for (from, to) in [("facade", "nodes"), ("nodes", "gpu"), ("facade", "error")] {
        assert!(
            summary.contains_key(&(from.to_string(), to.to_string())),
            "the scan lost the edge {from} -> {to}"
        );
    }
    assert_eq!(cycle(&edges), None, "a cycle between top-level modules");
    let bad = violations(&edges, &modules, LAYERS);
    assert!(bad.is_empty(), "layers broken:\n{}", bad.join("\n"));
}

/// The scan and the two rules on a made-up crate whose edges break the layers: the planner and
/// the nodes naming each other, the GPU helpers reading the facade's settings through a root
/// re-export, and `error` and `load` each using the other.
#[test]
fn the_check_finds_upward_uses_and_cycles() {
    let lib = "pub mod error; pub mod load;\n\
               pub use facade::{Frame, Settings};\n\
               pub use load::{Limit, LoadOptions};\n";
    let files = [
        ("error.rs", "pub enum E { L { limit: crate::load::Limit } }"),
        ("load.rs", "use crate::error::{Error, Result};"),
        ("plan.rs", "use crate::nodes::{MarchMethod, Scale};"),
        ("nodes/march.rs", "use crate::{plan::Pass, gpu::Cache};"),
        (
            "gpu/cache.rs",
            "fn warm(s: &crate::Settings) {}\n// crate::facade in a comment",
        ),
        ("facade.rs", "use crate::nodes::MarchNode;"),
    ];
    let files: Vec<(String, String)> = files
        .iter()
        .map(|(p, t)| (p.to_string(), t.to_string()))
        .collect();
    let modules: BTreeSet<String> = ["error", "load", "plan", "nodes", "gpu", "facade"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    let edges = edges(&files, lib, &modules);
    let pairs: BTreeSet<(String, String)> = edges
        .iter()
        .map(|e| (e.from.clone(), e.to.clone()))
        .collect();
    let has = |a: &str, b: &str| pairs.contains(&(a.to_string(), b.to_string()));
    assert!(has("error", "load") && has("load", "error"));
    assert!(
        has("nodes", "plan") && has("nodes", "gpu"),
        "a `crate::{{…}}` group"
    );
    assert!(
        has("gpu", "facade"),
        "a root re-export resolved to its module"
    );
    assert_eq!(
        edges.iter().filter(|e| e.from == "gpu").count(),
        1,
        "comments skipped"
    );
    assert!(cycle(&edges).is_some());
    let bad = violations(&edges, &modules, LAYERS);
    println!("{}", bad.join("\n"));
    for needle in ["error -> load", "nodes -> plan", "gpu -> facade"] {
        assert!(
            bad.iter().any(|v| v.starts_with(needle)),
            "{needle} not reported"
        );
    }
    // Without the offending files, the same crate passes.
    let clean: Vec<Edge> = edges
        .into_iter()
        .filter(|e| !["error", "nodes", "gpu"].contains(&e.from.as_str()))
        .collect();
    assert_eq!(cycle(&clean), None);
    assert!(violations(&clean, &modules, LAYERS).is_empty());
}

/// Every use of one module inside `src/nodes/` by another, from `(path, text)` pairs relative
/// to `src` (the `nodes/*.rs` files, and a folder module's `nodes/x/*.rs` files counting as
/// module `x`; `nodes/mod.rs` declares and re-exports, as `lib.rs` does above):
/// `crate::nodes::x`, `nodes::x` and `super::x` paths (in a folder module's files
/// `super::super::x`, their `super::` being the folder's own module), a name re-exported by
/// `mod_rs` counting as the module it comes from.
fn node_edges(files: &[(String, String)], mod_rs: &str, modules: &BTreeSet<String>) -> Vec<Edge> {
    let reexports = root_reexports(mod_rs);
    let mut out = Vec::new();
    for (path, text) in files {
        let Some(file) = path
            .strip_prefix("nodes/")
            .and_then(|f| f.strip_suffix(".rs"))
            .filter(|f| *f != "mod")
        else {
            continue;
        };
        let (from, parent) = match file.split_once('/') {
            Some((folder, rest)) if !rest.contains('/') => (folder, "super::super::"),
            Some(_) => continue,
            None => (file, "super::"),
        };
        for prefix in ["crate::nodes::", "nodes::", parent] {
            for (to, line) in uses_after(text, prefix, &reexports) {
                if to != from && modules.contains(&to) {
                    out.push(Edge {
                        from: from.to_string(),
                        to,
                        site: format!("{path}:{line}"),
                    });
                }
            }
        }
    }
    out
}

/// The modules inside `src/nodes/` use each other without a circle (the shared groups,
/// `groups/`, are imported by the nodes and import none of them; the `Cache` finds each node's
/// pipelines by type and names none). Also: a made-up circle through a re-export and a
/// `super::` path is found.
#[test]
fn modules_inside_nodes_form_no_circle() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let dir = src.join("nodes");
    let mut files = Vec::new();
    let mut modules = BTreeSet::new();
    for entry in std::fs::read_dir(&dir).expect("read src/nodes") {
        let path = entry.expect("entry").path();
        let name = path.file_stem().unwrap().to_string_lossy().to_string();
        if path.extension().is_some_and(|e| e == "rs") {
            let text = std::fs::read_to_string(&path).expect("read source");
            files.push((format!("nodes/{name}.rs"), text));
            if name != "mod" {
                modules.insert(name);
            }
        } else if path.is_dir() {
            // A node split into a folder: its files are the module `name`.
            for inner in std::fs::read_dir(&path).expect("read a folder of src/nodes") {
                let inner = inner.expect("entry").path();
                if inner.extension().is_some_and(|e| e == "rs") {
                    let file = inner.file_name().unwrap().to_string_lossy().to_string();
                    let text = std::fs::read_to_string(&inner).expect("read source");
                    files.push((format!("nodes/{name}/{file}"), text));
                }
            }
            modules.insert(name);
        }
    }
    let mod_rs = std::fs::read_to_string(dir.join("mod.rs")).expect("read nodes/mod.rs");
    let edges = node_edges(&files, &mod_rs, &modules);
    let mut summary: BTreeMap<(String, String), usize> = BTreeMap::new();
    for e in &edges {
        *summary.entry((e.from.clone(), e.to.clone())).or_default() += 1;
    }
    println!("{} modules inside nodes/:", modules.len());
    for ((from, to), n) in &summary {
        println!("  {from} -> {to} ({n} paths)");
    }
    // The scan must see the folder's own edges: the march reads the shadow map and the shared
    // shadow group, and every node the cache.
    for (from, to) in [
        ("march", "shadow_map"),
        ("march", "groups"),
        ("shadow_map", "cache"),
    ] {
        assert!(
            summary.contains_key(&(from.to_string(), to.to_string())),
            "the scan lost the edge {from} -> {to}"
        );
    }
    if let Some(c) = cycle(&edges) {
        let sites: Vec<String> = c
            .windows(2)
            .flat_map(|w| {
                edges
                    .iter()
                    .filter(move |e| e.from == w[0] && e.to == w[1])
                    .map(|e| format!("  {} -> {} at src/{}", e.from, e.to, e.site))
            })
            .collect();
        panic!(
            "a circle inside nodes/: {}\n{}",
            c.join(" -> "),
            sites.join("\n")
        );
    }

    // Planted: `a` names `b` through `crate::nodes::`, `b` names `a`'s re-exported type
    // through `super::`; `c` names `a` in a comment only. Then in a folder module `d`: its
    // `super::` paths name its own files (`super::a` is `d/a.rs`, no edge), and
    // `super::super::b` names the node `b`, which names `d` back: a circle.
    let planted = [
        ("nodes/a.rs", "use crate::nodes::b::Helper;"),
        ("nodes/b.rs", "fn f(n: &super::ANode) {}"),
        (
            "nodes/c.rs",
            "// crate::nodes::a::ANode\nuse crate::nodes::{self};",
        ),
        ("nodes/d/mod.rs", "mod a; use crate::nodes::c::C;"),
        (
            "nodes/d/a.rs",
            "use super::a::X; use super::super::b::Helper;",
        ),
    ];
    let planted: Vec<(String, String)> = planted
        .iter()
        .map(|(p, t)| (p.to_string(), t.to_string()))
        .collect();
    let names: BTreeSet<String> = ["a", "b", "c", "d"].iter().map(|s| s.to_string()).collect();
    // The re-export right after an item's closing brace (a trait, as in nodes/mod.rs) counts
    // too: reading only statements that begin with `pub use`, it was lost, and with it the
    // circle airlight_table -> uniforms -> airlight_table through `crate::nodes::TableSize`.
    for mod_rs in [
        "pub use a::{ANode, AInputs};",
        "pub trait T {\n    fn f();\n}\n\npub use a::{ANode, AInputs};",
    ] {
        let found = node_edges(&planted[..3], mod_rs, &names);
        assert_eq!(found.len(), 2, "{mod_rs}: {found:?}");
        assert_eq!(
            cycle(&found),
            Some(vec!["a".to_string(), "b".to_string(), "a".to_string()])
        );
    }
    let mut planted = planted;
    planted[1].1 = "fn f(n: &super::DNode) {}".to_string();
    planted[0].1 = String::new();
    let found = node_edges(&planted, "pub use d::{DNode};", &names);
    let pairs: Vec<(&str, &str, &str)> = found
        .iter()
        .map(|e| (e.from.as_str(), e.to.as_str(), e.site.as_str()))
        .collect();
    assert_eq!(
        pairs,
        [
            ("b", "d", "nodes/b.rs:1"),
            ("d", "c", "nodes/d/mod.rs:1"),
            ("d", "b", "nodes/d/a.rs:1")
        ],
        "{found:?}"
    );
    assert_eq!(
        cycle(&found),
        Some(vec!["b".to_string(), "d".to_string(), "b".to_string()])
    );
}

/// The places in `files` (path, text) that begin a pass on the encoder directly, outside
/// `gpu/passes.rs` and comments.
fn uncounted_passes(files: &[(String, String)]) -> Vec<String> {
    let mut found = Vec::new();
    for (path, text) in files {
        if path.ends_with("gpu/passes.rs") {
            continue;
        }
        for (i, line) in strip_comments(text).lines().enumerate() {
            if line.contains(".begin_render_pass(") || line.contains(".begin_compute_pass(") {
                found.push(format!("{path}:{}", i + 1));
            }
        }
    }
    found
}

/// Every pass the crate records begins through `gpu::passes` (`begin_render`,
/// `begin_compute`), so that `passes_recorded` and the bench's `--work` counts are complete; a
/// direct `encoder.begin_render_pass(…)` is found with its file and line.
#[test]
fn every_pass_begins_through_the_counter() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut paths = Vec::new();
    rust_files(&src, &mut paths);
    let files: Vec<(String, String)> = paths
        .iter()
        .map(|p| (p.display().to_string(), std::fs::read_to_string(p).unwrap()))
        .collect();
    assert!(files.len() > 20, "read {} files of src/", files.len());
    let found = uncounted_passes(&files);
    assert!(
        found.is_empty(),
        "passes begun outside gpu::passes: {found:?}"
    );
    // A direct call is found; one in a comment is not.
    let planted = [(
        "src/nodes/x.rs".to_string(),
        "// encoder.begin_render_pass(&d)\nlet p = encoder.begin_compute_pass(&d);\n".to_string(),
    )];
    assert_eq!(uncounted_passes(&planted), ["src/nodes/x.rs:2"]);
}
