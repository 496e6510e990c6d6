//! Writes `docs/ACCURACY.md` and `docs/PERFORMANCE.md` from the metric lines of a run's logs
//! ([`volshadow_tools::measurements`]).
//!
//! ```text
//! cargo run -p volshadow_tools --bin measurements -- [--run NAME] [--date YYYY-MM-DD] LOG...
//! cargo run -p volshadow_tools --bin measurements -- --docs-only
//! ```

fn main() {
    volshadow_tools::measurements::main();
}
