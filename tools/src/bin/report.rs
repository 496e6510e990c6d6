//! Error against GPU time for every method and setting on the standard scenes: writes
//! `target/volshadow-report/{report.md, report.csv, error_vs_time.svg, error_table.rs}`.
//! See `volshadow_harness::report` (`harness/src/report/`) for what is measured and how;
//! `--help` prints the options.
//!
//! ```text
//! cargo run --release -p volshadow_tools --bin report [-- --scenes sphere,cow --size 512 --frames 5 --full]
//! ```
//!
//! By default a quick set (two scenes, small images: a few minutes on two CPU cores);
//! `--full` is the whole sweep. Progress, with an estimate of the time left, goes to stderr.
//! Exits with status 1 on bad arguments or files, and when an error-target check fails.

use volshadow_harness::cli::Parsed;
use volshadow_harness::report::{help, report, Options};

fn main() {
    volshadow_harness::headless_env::quiet_display_probe();
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = Options::parse(&args).and_then(|parsed| match parsed {
        Parsed::Help => {
            println!("{}", help());
            Ok(())
        }
        Parsed::Run(options) => report(&options)?.verdict(),
    });
    if let Err(e) = result {
        eprintln!("report: {e}");
        std::process::exit(1);
    }
}
