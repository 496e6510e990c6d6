//! The report's command line.

use std::path::{Path, PathBuf};

use lexopt::prelude::*;

use super::BoxError;

/// The command line, for error messages.
pub const USAGE: &str =
    "usage: report [--scenes a,b,...] [--size N] [--frames N] [--out DIR] [--full] [--quick]";

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
    /// Parses the arguments after the program name.
    pub fn parse(args: &[String]) -> Result<Self, BoxError> {
        let mut options = Options {
            scenes: Vec::new(),
            size: 512,
            frames: 5,
            out: PathBuf::from("target/volshadow-report"),
            full: false,
            quick: false,
        };
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
                Long("scenes") => {
                    options.scenes = parser
                        .value()?
                        .string()?
                        .split(',')
                        .map(|name| {
                            let path = PathBuf::from(name);
                            if path.extension().is_some() {
                                path
                            } else {
                                Path::new("scenes").join(format!("{name}.json"))
                            }
                        })
                        .collect()
                }
                Long("size") => options.size = number(&mut parser, "--size")?,
                Long("frames") => options.frames = number(&mut parser, "--frames")? as usize,
                Long("out") => options.out = PathBuf::from(parser.value()?),
                Long("full") => options.full = true,
                Long("quick") => options.quick = true,
                Short('h') | Long("help") => return Err(USAGE.into()),
                _ => return Err(format!("{}\n{USAGE}", arg.unexpected()).into()),
            }
        }
        if options.scenes.is_empty() {
            let mut scenes: Vec<PathBuf> = std::fs::read_dir("scenes")
                .map_err(|e| format!("cannot list scenes/: {e} (run from the crate root)"))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|e| e == "json"))
                .collect();
            scenes.sort();
            options.scenes = scenes;
        }
        Ok(options)
    }
}
