//! The tools' command lines: `--help` is the usage, not an error (the examples' parsers:
//! `tests/examples/examples.rs`); uniform_probe's arguments are checked, not unwrapped. The
//! soak's and the measurements tool's: `soak.rs`, `measurements.rs`.

use volshadow_harness::cli::{self, Parsed};
use volshadow_harness::report;

use crate::args;

/// `--help` and `-h` are a request for the usage, not an error, for the report's and
/// uniform_probe's parsers, whatever else is on the line.
#[test]
fn every_tool_answers_help() {
    for flag in ["--help", "-h"] {
        assert!(report::Options::parse(&args(&["--size", "64", flag]))
            .unwrap()
            .is_help());
        assert!(cli::parse_probe(&args(&["storage", flag]))
            .unwrap()
            .is_help());
    }
}

/// uniform_probe's arguments are checked, not unwrapped.
#[test]
fn uniform_probe_parses_its_options() {
    let probe = |list: &[&str]| cli::parse_probe(&args(list));
    assert_eq!(
        probe(&["storage", "100", "composite"]).unwrap(),
        Parsed::Run(cli::ProbeOptions {
            storage: true,
            frames: 100,
            composite: true
        })
    );
    assert_eq!(
        probe(&[]).unwrap(),
        Parsed::Run(cli::ProbeOptions {
            storage: false,
            frames: 2000,
            composite: false
        })
    );
    for bad in [
        &["bogus"][..],
        &["uniform", "x"],
        &["uniform", "0"],
        &["uniform", "9", "y"],
    ] {
        assert!(probe(bad).is_err(), "{bad:?}");
    }
}
