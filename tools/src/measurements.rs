//! Writes `docs/ACCURACY.md` and `docs/PERFORMANCE.md` from the metric lines that the tests and
//! the `report` tool print (`volshadow_harness::metric`).
//!
//! ```text
//! cargo run -p volshadow_tools --bin measurements -- [--run NAME] [--date YYYY-MM-DD] LOG...
//! cargo run -p volshadow_tools --bin measurements -- --docs-only
//! ```
//!
//! Each run's logs (`cargo test --features gltf,image,sweeps -- --nocapture` and the report's output,
//! as `.ci/measure` writes them) become `docs/measurements/NAME.tsv`: the run's date, adapter,
//! failed tests and metric lines, NAME taken from the adapter (`llvmpipe`, `nvidia-h200`) unless
//! `--run` names it. The documents are then rewritten from every `.tsv` there, one column of
//! values per run: a run on another adapter adds its column without losing the others.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use volshadow_harness::docs::{document, read_runs, Run};
use volshadow_harness::metric::{self, Doc};
use volshadow_harness::{cli, repo_root};

const HELP: &str = "\
Writes docs/ACCURACY.md and docs/PERFORMANCE.md from metric lines.

usage: cargo run -p volshadow_tools --bin measurements -- [--run NAME] [--date YYYY-MM-DD] LOG...
       cargo run -p volshadow_tools --bin measurements -- --docs-only

LOG...       logs of one run: `cargo test --features gltf,image,sweeps -- --nocapture` and the
             report's output (.ci/measure writes both); saved as docs/measurements/NAME.tsv
--run NAME   the run's name (default: from the adapter, e.g. llvmpipe)
--date DATE  the run's date (default: today, UTC)
--docs-only  rewrite the documents from docs/measurements/*.tsv alone

A run whose output (NAME.tsv or a document) is one of its logs is refused before anything is
written.
";

type BoxError = Box<dyn std::error::Error>;

/// The `measurements` binary: [`run`] on the command line, under the repository's root.
pub fn main() {
    let args = std::env::args().skip(1).collect();
    if let Err(e) = run(args, repo_root()) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}

/// Runs the tool with `args` (the command line after the program's name), reading and writing
/// under `root` (the crate's folder).
pub fn run(args: Vec<String>, root: &Path) -> Result<(), BoxError> {
    let folder = root.join("docs/measurements");
    let mut logs: Vec<PathBuf> = Vec::new();
    let (mut name, mut date, mut docs_only) = (None, None, false);
    let mut args = args.into_iter();
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--help" | "-h" => {
                print!("{HELP}");
                return Ok(());
            }
            "--run" => name = Some(args.next().ok_or("--run needs a name")?),
            "--date" => date = Some(args.next().ok_or("--date needs a date")?),
            "--docs-only" => docs_only = true,
            a if a.starts_with('-') => return Err(format!("unknown option {a}\n\n{HELP}").into()),
            _ => logs.push(PathBuf::from(arg)),
        }
    }
    if !docs_only {
        if logs.is_empty() {
            return Err(format!("no log given\n\n{HELP}").into());
        }
        let mut run = Run {
            date: date.unwrap_or_else(today),
            ..Run::default()
        };
        for log in &logs {
            let text = std::fs::read_to_string(log)
                .map_err(|e| format!("cannot read {}: {e}", log.display()))?;
            read_log(&text, &mut run);
        }
        if run.metrics.is_empty() {
            return Err("no metric lines in the logs (did the tests run with --nocapture?)".into());
        }
        run.name = name.unwrap_or_else(|| slug(run.adapters.iter().next().map_or("run", |a| a)));
        let path = folder.join(format!("{}.tsv", run.name));
        let outputs = [
            path.clone(),
            root.join("docs/ACCURACY.md"),
            root.join("docs/PERFORMANCE.md"),
        ];
        cli::refuse_overwrite(&logs, &outputs)?;
        std::fs::create_dir_all(&folder)?;
        std::fs::write(&path, write_run(&run))?;
        println!(
            "{}: {} metric lines, {} failed tests",
            path.display(),
            run.metrics.len(),
            run.failed.len()
        );
    }
    let runs = read_runs(&folder).map_err(|e| format!("cannot read {}: {e}", folder.display()))?;
    for (doc, file) in [
        (Doc::Accuracy, "docs/ACCURACY.md"),
        (Doc::Performance, "docs/PERFORMANCE.md"),
    ] {
        let path = root.join(file);
        std::fs::write(&path, document(doc, &runs))?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// The metric lines of a log, its adapters and its failed tests (from libtest's `Running`
/// headers and `test NAME ... FAILED` lines).
fn read_log(text: &str, run: &mut Run) {
    let mut binary = String::from("?");
    for line in text.lines() {
        let trimmed = line.trim();
        if let Some(rest) = trimmed.strip_prefix("Running ") {
            // `Running tests/gpu/main.rs (target/debug/deps/gpu-…)`
            let file = rest.split_whitespace().next().unwrap_or(rest);
            binary = Path::new(file)
                .file_stem()
                .map_or(file.to_string(), |s| s.to_string_lossy().into_owned());
        } else if let Some(test) = trimmed
            .strip_prefix("test ")
            .and_then(|t| t.strip_suffix(" ... FAILED"))
        {
            // In a tier binary (`tests/gpu/main.rs`) the name starts with its file's module,
            // as the metric lines' sources do (`metric::this_test`).
            if test.contains("::") {
                run.failed.insert(test.to_string());
            } else {
                run.failed.insert(format!("{binary}::{test}"));
            }
        }
        let Some(m) = metric::parse(line) else {
            continue;
        };
        match m.doc {
            Doc::Adapter => {
                run.adapters.insert(m.check.clone());
                if !m.source.contains("::") && !run.commands.contains(&m.source) {
                    run.commands.push(m.source);
                }
            }
            _ => run.metrics.push(m),
        }
    }
}

/// `docs/measurements/NAME.tsv`: the run's header lines, then its metric lines.
fn write_run(run: &Run) -> String {
    let mut out = String::from(
        "# Written by `cargo run -p volshadow_tools --bin measurements` from a run's logs; read back to write \
         docs/ACCURACY.md and docs/PERFORMANCE.md.\n",
    );
    let _ = writeln!(out, "date\t{}", run.date);
    for a in &run.adapters {
        let _ = writeln!(out, "adapter\t{a}");
    }
    for c in &run.commands {
        let _ = writeln!(out, "command\t{c}");
    }
    for f in &run.failed {
        let _ = writeln!(out, "failed\t{f}");
    }
    // One line per check, the last printed winning (a test may print again after a retry);
    // sorted by source so that a rerun's file differs only where a value changed.
    let mut last: BTreeMap<(Doc, &str, &str), usize> = BTreeMap::new();
    for (i, m) in run.metrics.iter().enumerate() {
        last.insert((m.doc, &m.source, &m.check), i);
    }
    let mut order: Vec<usize> = last.into_values().collect();
    order.sort_by(|&a, &b| {
        let (x, y) = (&run.metrics[a], &run.metrics[b]);
        (x.doc, &x.source, a).cmp(&(y.doc, &y.source, b))
    });
    for i in order {
        let m = &run.metrics[i];
        let _ = writeln!(
            out,
            "{}",
            metric::line(m.doc, &m.source, &m.check, &m.measured, &m.bound)
        );
    }
    out
}

/// `llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan, …)` → `llvmpipe`; `NVIDIA H200 (…)` → `nvidia-h200`.
fn slug(adapter: &str) -> String {
    let name = adapter.split(" (").next().unwrap_or(adapter);
    let s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() {
                c.to_ascii_lowercase()
            } else {
                '-'
            }
        })
        .collect();
    let s = s.trim_matches('-').to_string();
    if s.is_empty() {
        "run".into()
    } else {
        s
    }
}

/// Today's date (UTC), `YYYY-MM-DD` (Howard Hinnant's civil-from-days).
fn today() -> String {
    let days = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs() / 86_400) as i64;
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!("{year:04}-{month:02}-{day:02}")
}
