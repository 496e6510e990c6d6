//! volshadow's own tools, each a binary of this package (never published):
//!
//! ```text
//! cargo run --release -p volshadow_tools --bin report          # error against GPU time
//! cargo run -p volshadow_tools --bin measurements -- LOG...    # docs/ACCURACY.md, PERFORMANCE.md
//! cargo run --release -p volshadow_tools --bin soak            # many frames, everything animated
//! cargo run --release -p volshadow_tools --bin uniform_probe   # a driver's shader variants
//! ```
//!
//! The tools that have tests keep their code here, where the tests (`tests/tools/`) call it:
//! [`measurements`] and [`soak`]; the report's code is `volshadow_harness::report` (the frame
//! bench shares it). Each binary in `src/bin/` calls its tool's `main`.

pub mod measurements;
pub mod soak;
