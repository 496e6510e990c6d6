//! Error against GPU time for every method and setting on the standard scenes: writes
//! `target/volshadow-report/{report.md, report.csv, error_vs_time.svg, error_table.rs}`.
//! See `common/report/` for what is measured and how.
//!
//! ```text
//! cargo run --release --example report [-- --scenes sphere,cow --size 512 --frames 5 --full]
//! ```

#[path = "../common/mod.rs"]
mod common;

fn main() {
    common::headless_env::quiet_display_probe();
    let args: Vec<String> = std::env::args().skip(1).collect();
    if let Err(e) = common::report::run(&args) {
        eprintln!("report: {e}");
        std::process::exit(1);
    }
}
