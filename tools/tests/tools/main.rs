//! The tools' tests: each tool's own code run small or on made-up inputs (the report, the soak,
//! the measurements tool) and their command lines. One test binary (one link step); each file
//! beside this one is a tool. `cargo test -p volshadow_tools` runs them.

mod help;
mod measurements;
mod report;
mod soak;

/// The tools run from the repository's root, as `cargo run -p volshadow_tools --bin …` there
/// does (the report lists `scenes/` there); Cargo runs this package's tests in `tools/`. Every
/// test of this binary that reads a relative path calls this first; none writes one.
pub fn at_repo_root() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| std::env::set_current_dir(volshadow_harness::repo_root()).unwrap());
}

/// A command line's arguments.
pub fn args(list: &[&str]) -> Vec<String> {
    list.iter().map(|s| s.to_string()).collect()
}
