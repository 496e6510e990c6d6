//! One machine-readable line per measured check. Tests (and the `report` tool) print them;
//! `cargo run -p volshadow_tools --bin measurements` collects them into `docs/ACCURACY.md` and
//! `docs/PERFORMANCE.md` (`.ci/measure` runs the suite and the report, then that tool).
//!
//! A line is `volshadow-metric`, then tab-separated fields: the document (`accuracy` or
//! `performance`), the source (the test's file and name, or a command), the check, the measured
//! value and its bound. `adapter` lines name the adapter that measured them. The format is
//! defined here once, for the writers and the reader (the `measurements` tool, [`crate::docs`]).

use std::fmt::Display;

/// The first field of every metric line.
pub const PREFIX: &str = "volshadow-metric";

/// Which generated document a line belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Doc {
    /// `docs/ACCURACY.md`.
    Accuracy,
    /// `docs/PERFORMANCE.md`.
    Performance,
    /// The adapter the lines after it were measured on (its `check` field holds the summary).
    Adapter,
}

impl Doc {
    fn name(self) -> &'static str {
        match self {
            Doc::Accuracy => "accuracy",
            Doc::Performance => "performance",
            Doc::Adapter => "adapter",
        }
    }
}

/// One parsed metric line.
#[derive(Clone, Debug, PartialEq)]
pub struct Metric {
    /// The document it goes into.
    pub doc: Doc,
    /// `FILE::TEST` for a test, or the command that printed it.
    pub source: String,
    /// What was measured, in words.
    pub check: String,
    /// The current value, with its unit.
    pub measured: String,
    /// The bound the test asserts, and where it comes from when that is not obvious.
    pub bound: String,
}

/// Fields hold no tab or newline (the line's separators).
fn clean(text: &str) -> String {
    text.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// The line for one metric.
pub fn line(
    doc: Doc,
    source: &str,
    check: &str,
    measured: impl Display,
    bound: impl Display,
) -> String {
    format!(
        "{PREFIX}\t{}\t{}\t{}\t{}\t{}",
        doc.name(),
        clean(source),
        clean(check),
        clean(&measured.to_string()),
        clean(&bound.to_string())
    )
}

/// The metric on `line`, if it is one (anywhere in the line: libtest may prefix output).
pub fn parse(line: &str) -> Option<Metric> {
    let start = line.find(PREFIX)?;
    let mut fields = line[start..].trim_end().split('\t').skip(1);
    let doc = match fields.next()? {
        "accuracy" => Doc::Accuracy,
        "performance" => Doc::Performance,
        "adapter" => Doc::Adapter,
        _ => return None,
    };
    let mut next = || fields.next().map(str::to_string);
    Some(Metric {
        doc,
        source: next()?,
        check: next()?,
        measured: next().unwrap_or_default(),
        bound: next().unwrap_or_default(),
    })
}

/// `FILE::TEST` of the running test: libtest's thread name, which is the test's path in its
/// binary; in the tier binaries (`tests/gpu/main.rs`) it starts with the topic file's module. A
/// test at a binary's root is prefixed with the binary's crate ([`binary_crate`]).
pub fn this_test() -> String {
    let thread = std::thread::current();
    let test = thread.name().unwrap_or("unnamed thread");
    if test.contains("::") {
        test.to_string()
    } else {
        format!("{}::{test}", binary_crate())
    }
}

/// The running binary's crate: Cargo names a test binary `CRATE-HASH` (16 hex digits), the
/// name the test's own `CARGO_CRATE_NAME` holds (which this library cannot read: its own is
/// `volshadow_harness`).
pub fn binary_crate() -> String {
    let exe = std::env::current_exe().unwrap_or_default();
    let stem = exe
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("unknown binary");
    match stem.rsplit_once('-') {
        Some((name, hash)) if hash.len() == 16 && hash.chars().all(|c| c.is_ascii_hexdigit()) => {
            name.to_string()
        }
        _ => stem.to_string(),
    }
}

/// Prints an accuracy check of the running test: its `measured` value and the `bound` it is
/// asserted against.
pub fn accuracy(check: &str, measured: impl Display, bound: impl Display) {
    println!(
        "{}",
        line(Doc::Accuracy, &this_test(), check, measured, bound)
    );
}

/// Prints a cost measured by the running test (a time, a count of steps or passes).
pub fn performance(check: &str, measured: impl Display, bound: impl Display) {
    println!(
        "{}",
        line(Doc::Performance, &this_test(), check, measured, bound)
    );
}

/// Prints the adapter the running test measures on (`HeadlessGpu::adapter_summary`).
pub fn adapter(summary: &str) {
    println!("{}", line(Doc::Adapter, &this_test(), summary, "", ""));
}
