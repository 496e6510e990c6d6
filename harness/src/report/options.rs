//! The report's command line.

use std::path::{Path, PathBuf};

use lexopt::prelude::*;

use super::{BoxError, ERROR_TABLE_SIZE};
use crate::cli::Parsed;

/// The usage line, for error messages (`--help` prints [`help`]).
pub const USAGE: &str = "usage: report [--scenes a,b,...|all] [--size N] [--frames N] [--out DIR] \
[--full] [--quick] [-h | --help]";

/// The scenes of the default run (without `--full` or `--scenes`): a point light behind a
/// sphere and the sun through a window, both hard shadows.
pub const DEFAULT_SCENES: [&str; 2] = ["sphere", "window"];

/// The image size of the default run (without `--full`, `--scenes` or `--size`).
pub const DEFAULT_SIZE: u32 = 256;

/// `report --help`.
pub fn help() -> String {
    format!(
        "{USAGE}

Error against GPU time of every method and setting, against the f64 reference: writes
DIR/report.md, report.csv, error_vs_time.svg and error_table.rs. Progress, with an estimate
of the time left, goes to stderr; the summary to stdout. Exits with status 1 when an
error-target check fails. Checks are judged only at {ERROR_TABLE_SIZE}x{ERROR_TABLE_SIZE}, the size the
planner's error table was measured at; at other sizes they read \"not judged\".

By default a quick set: the scenes {} at {DEFAULT_SIZE}x{DEFAULT_SIZE}, each step sweep stopped once
it reaches p95 0.5% or stops improving by 10% per doubling (a few minutes on two CPU cores
with lavapipe, the f64 references included; they are cached in DIR/cache).

options:
  --full         the whole sweep: every scenes/*.json at {ERROR_TABLE_SIZE}x{ERROR_TABLE_SIZE}, every step count
                 (hours on a CPU adapter); --scenes and --size still apply
  --scenes LIST  scene names (scenes/NAME.json) or paths, comma-separated; `all`: every
                 scenes/*.json
  --size N       image width and height (default {ERROR_TABLE_SIZE}; {DEFAULT_SIZE} for the default quick set)
  --frames N     timed frames per configuration, after a warm-up frame (default 5)
  --out DIR      output folder (default target/volshadow-report; created if missing).
                 A run that would write over an input file is refused.
  --quick        a few configurations per scene only (the test's run)
  -h, --help     this help",
        DEFAULT_SCENES.join(" and ")
    )
}

/// Parsed command line.
#[derive(Debug, Clone)]
pub struct Options {
    /// Scene files.
    pub scenes: Vec<PathBuf>,
    /// Image width and height.
    pub size: u32,
    /// Timed frames per configuration (after one warm-up frame).
    pub frames: usize,
    /// Output directory.
    pub out: PathBuf,
    /// Run every step count of the sweeps.
    pub full: bool,
    /// A few configurations only.
    pub quick: bool,
}

impl Options {
    /// Parses the arguments after the program name: the options, or [`Parsed::Help`] for
    /// `-h` / `--help` (whatever else is given).
    pub fn parse(args: &[String]) -> Result<Parsed<Self>, BoxError> {
        if args.iter().any(|a| a == "-h" || a == "--help") {
            return Ok(Parsed::Help);
        }
        let mut options = Options {
            scenes: Vec::new(),
            size: 0,
            frames: 5,
            out: PathBuf::from("target/volshadow-report"),
            full: false,
            quick: false,
        };
        let (mut scenes, mut size) = (None::<String>, None);
        let number = |parser: &mut lexopt::Parser, flag: &str| -> Result<u32, BoxError> {
            let text = parser.value()?.string()?;
            match text.parse::<u32>() {
                Ok(n) if n > 0 => Ok(n),
                _ => Err(format!("{flag} must be a positive whole number, got {text:?}").into()),
            }
        };
        let mut parser = lexopt::Parser::from_args(args);
        while let Some(arg) = parser.next()? {
            match arg {
                Long("scenes") => scenes = Some(parser.value()?.string()?),
                Long("size") => size = Some(number(&mut parser, "--size")?),
                Long("frames") => options.frames = number(&mut parser, "--frames")? as usize,
                Long("out") => options.out = PathBuf::from(parser.value()?),
                Long("full") => options.full = true,
                Long("quick") => options.quick = true,
                Short('h') | Long("help") => return Ok(Parsed::Help),
                _ => return Err(format!("{}\n{USAGE}", arg.unexpected()).into()),
            }
        }
        // The quick set's size only for the quick set: scenes named on the command line are
        // measured at the error table's size, as before there was a quick set.
        options.size = size.unwrap_or(if options.full || scenes.is_some() {
            ERROR_TABLE_SIZE
        } else {
            DEFAULT_SIZE
        });
        options.scenes = match scenes.as_deref() {
            Some("all") => all_scenes()?,
            Some(list) => list
                .split(',')
                .map(|name| {
                    let path = PathBuf::from(name);
                    if path.extension().is_some() {
                        path
                    } else {
                        Path::new("scenes").join(format!("{name}.json"))
                    }
                })
                .collect(),
            None if options.full => all_scenes()?,
            None => DEFAULT_SCENES
                .iter()
                .map(|name| Path::new("scenes").join(format!("{name}.json")))
                .collect(),
        };
        Ok(Parsed::Run(options))
    }
}

/// Every `scenes/*.json`, sorted.
fn all_scenes() -> Result<Vec<PathBuf>, BoxError> {
    let mut scenes: Vec<PathBuf> = std::fs::read_dir("scenes")
        .map_err(|e| format!("cannot list scenes/: {e} (run from the crate root)"))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .collect();
    scenes.sort();
    Ok(scenes)
}
