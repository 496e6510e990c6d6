//! What the examples' and tools' command lines share: `--help`, the default output folder and
//! the rule that no output overwrites an input; and the options of the programs too small for
//! a module of their own (`quickstart`, `interactive`, `uniform_probe`).
//!
//! Only `std` and `lexopt` (and `libc` for a non-blocking open).

use std::fmt;
use std::path::{Path, PathBuf};

use lexopt::prelude::*;

type BoxError = Box<dyn std::error::Error>;

/// A parsed command line: run with these options, or print the full usage and exit 0.
#[derive(Debug, Clone, PartialEq)]
pub enum Parsed<T> {
    /// Run.
    Run(T),
    /// `-h` or `--help` was given: print the usage, run nothing.
    Help,
}

impl<T> Parsed<T> {
    /// Whether `--help` was asked for.
    pub fn is_help(&self) -> bool {
        matches!(self, Parsed::Help)
    }
}

/// The folder outputs go to when no output path is given (relative to the working folder,
/// created if missing): never beside the input.
pub const OUT_DIR: &str = "out";

/// `out/STEM` for an input file `…/STEM.ext` (`out/FALLBACK` for a path without a stem).
pub fn default_output(input: &Path, fallback: &str) -> PathBuf {
    Path::new(OUT_DIR).join(input.file_stem().unwrap_or(fallback.as_ref()))
}

/// The base path of a run's outputs (`-o`, or the default), each output being it with a
/// suffix: an extension among `extensions` dropped. A path naming a folder (`sub/`, `.`,
/// `..`) is an error, not the hidden files `sub/.png` and `sub/.exr`.
pub fn output_base(out: PathBuf, extensions: &[&str]) -> Result<PathBuf, BoxError> {
    let text = out.as_os_str().to_string_lossy();
    let last = text
        .rsplit(std::path::is_separator)
        .next()
        .unwrap_or_default();
    if matches!(last, "" | "." | "..") || out.file_name().is_none() {
        return Err(format!(
            "-o {}: names a folder; give the outputs' path without extension, e.g. {}",
            out.display(),
            out.join("scene").display()
        )
        .into());
    }
    let mut out = out;
    if out
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| extensions.contains(&e))
    {
        out.set_extension("");
    }
    Ok(out)
}

/// A run refused because an output file it would write is one of its input files.
#[derive(Debug, Clone, PartialEq)]
pub struct WouldOverwriteInput {
    /// The output, as the run would write it.
    pub output: PathBuf,
    /// The input, as given (or as the file naming it names it).
    pub input: PathBuf,
    /// The file both name.
    pub resolved: PathBuf,
}

impl fmt::Display for WouldOverwriteInput {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "refusing to write {}: it is the input file {} (both are {}); nothing was written, \
             choose another output path",
            self.output.display(),
            self.input.display(),
            self.resolved.display()
        )
    }
}

impl std::error::Error for WouldOverwriteInput {}

/// What identifies an existing file: its canonical path (`.`, `..` and symbolic links
/// resolved) and, on Unix, its device and inode (a hard link, or a case-insensitive file
/// system's other spelling).
#[derive(Debug, Clone, PartialEq)]
struct FileId {
    path: PathBuf,
    inode: Option<(u64, u64)>,
}

impl FileId {
    fn of_existing(path: &Path) -> Option<Self> {
        let canonical = path.canonicalize().ok()?;
        #[cfg(unix)]
        let inode = {
            use std::os::unix::fs::MetadataExt;
            std::fs::metadata(&canonical)
                .ok()
                .map(|m| (m.dev(), m.ino()))
        };
        #[cfg(not(unix))]
        let inode = None;
        Some(Self {
            path: canonical,
            inode,
        })
    }

    /// The file an output path would write once its missing folders are created
    /// ([`volshadow::load::written_path`]: links followed, `..` applied to the folder actually
    /// reached, so `new/../scene.json` is `scene.json`), with its device and inode where it
    /// exists; `None` when nothing can be written there (no existing file can be written).
    fn of_output(path: &Path) -> Option<Self> {
        let written = volshadow::load::written_path(path)?;
        Some(match Self::of_existing(&written) {
            Some(id) => id,
            None => Self {
                path: written,
                inode: None,
            },
        })
    }

    fn same(&self, other: &Self) -> bool {
        self.path == other.path || (self.inode.is_some() && self.inode == other.inode)
    }
}

/// Refuses (before anything is written) when an output file is one of the input files:
/// compared as canonical paths, so `./x.json`, `x.json`, `dir/../x.json` and a symbolic link
/// to it are the same file.
pub fn refuse_overwrite(
    inputs: &[PathBuf],
    outputs: &[PathBuf],
) -> Result<(), WouldOverwriteInput> {
    let inputs: Vec<(&PathBuf, FileId)> = inputs
        .iter()
        .filter_map(|p| FileId::of_existing(p).map(|id| (p, id)))
        .collect();
    for output in outputs {
        let Some(id) = FileId::of_output(output) else {
            continue;
        };
        if let Some((input, found)) = inputs.iter().find(|(_, i)| i.same(&id)) {
            return Err(WouldOverwriteInput {
                output: output.clone(),
                input: (*input).clone(),
                resolved: found.path.clone(),
            });
        }
    }
    Ok(())
}

/// `file` and every existing file it names, followed through the files they name (a scene
/// file's glTF models and light textures, a glTF file's buffers and images): any string of a
/// JSON file (a scene, a `.gltf`) or of a `.glb`'s JSON chunk that names an existing file
/// relative to the naming file's folder (percent-escapes decoded, `data:` and other URIs with
/// a scheme skipped). Unreadable or non-JSON files name nothing.
pub fn input_files(file: &Path) -> Vec<PathBuf> {
    let mut files = vec![file.to_path_buf()];
    let mut next = 0;
    // Bounded: a scene names glTF files and textures, a glTF file its buffers and images.
    while next < files.len() && next < 64 {
        let named = named_files(&files[next]);
        next += 1;
        for f in named {
            if files.len() < 256 && !files.contains(&f) {
                files.push(f);
            }
        }
    }
    files
}

/// The files one file names (see [`input_files`]).
fn named_files(file: &Path) -> Vec<PathBuf> {
    let Some(json) = json_of(file) else {
        return Vec::new();
    };
    let folder = match file.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let mut strings = Vec::new();
    collect_strings(&json, &mut strings);
    let mut files = Vec::new();
    for s in strings
        .into_iter()
        .filter(|s| !s.is_empty() && !s.contains(':'))
    {
        // As written (a scene file's paths) and percent-decoded (a glTF file's URIs).
        for candidate in [folder.join(s), folder.join(percent_decode(s))] {
            if candidate.is_file() && !files.contains(&candidate) {
                files.push(candidate);
            }
        }
    }
    files
}

/// A JSON file's value, or a `.glb`'s JSON chunk; `None` for anything else (or over 64 MiB).
fn json_of(file: &Path) -> Option<serde_json::Value> {
    use std::io::Read;
    const LIMIT: u64 = 64 << 20;
    // Decided before opening (a FIFO's open blocks until a writer comes), then opened
    // non-blocking and checked again, as the crate's loaders do.
    if !std::fs::metadata(file).ok()?.is_file() {
        return None;
    }
    let mut open = std::fs::OpenOptions::new();
    open.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        open.custom_flags(libc::O_NONBLOCK);
    }
    let mut reader = open.open(file).ok()?;
    if !reader.metadata().ok()?.is_file() {
        return None;
    }
    let mut head = [0u8; 20];
    let n = reader.read(&mut head).ok()?;
    if n == 20 && &head[0..4] == b"glTF" && &head[16..20] == b"JSON" {
        let length = u64::from(u32::from_le_bytes(head[12..16].try_into().ok()?));
        let mut chunk = Vec::new();
        reader
            .take(length.min(LIMIT))
            .read_to_end(&mut chunk)
            .ok()?;
        return serde_json::from_slice(&chunk).ok();
    }
    let mut bytes = head[..n].to_vec();
    reader.take(LIMIT).read_to_end(&mut bytes).ok()?;
    serde_json::from_slice(&bytes).ok()
}

fn collect_strings<'a>(value: &'a serde_json::Value, out: &mut Vec<&'a str>) {
    match value {
        serde_json::Value::String(s) => out.push(s),
        serde_json::Value::Array(items) => items.iter().for_each(|v| collect_strings(v, out)),
        serde_json::Value::Object(map) => map.values().for_each(|v| collect_strings(v, out)),
        _ => {}
    }
}

/// `%XX` escapes decoded (invalid ones kept as they are).
fn percent_decode(s: &str) -> PathBuf {
    PathBuf::from(
        percent_encoding::percent_decode_str(s)
            .decode_utf8_lossy()
            .into_owned(),
    )
}

// ---------------------------------------------------------------------------------------------
// quickstart

/// `quickstart --help`.
pub const QUICKSTART_HELP: &str = "\
usage: quickstart [-o OUT.png | OUT.png] [--size WxH]

Renders the quickstart scene (a point light behind and between two spheres in hazy air)
headless, prints each frame's plan and per-pass GPU times and writes a tone-mapped PNG.

options:
  -o, --output OUT.png  the PNG to write (default: out/quickstart.png; its folder is created)
  --size WxH            image size (default 640x400; the vertical field of view is kept)
  -h, --help            this help";

/// The quickstart's options.
#[derive(Debug, Clone, PartialEq)]
pub struct QuickstartOptions {
    /// The PNG to write.
    pub output: PathBuf,
    /// Image size, default 640×400.
    pub size: (u32, u32),
}

/// Parses `quickstart`'s arguments (after the program name).
pub fn parse_quickstart(args: &[String]) -> Result<Parsed<QuickstartOptions>, BoxError> {
    let mut output: Option<PathBuf> = None;
    let mut size = (640, 400);
    let mut parser = lexopt::Parser::from_args(args);
    while let Some(arg) = parser.next()? {
        match arg {
            Short('h') | Long("help") => return Ok(Parsed::Help),
            Long("size") => {
                let text = parser.value()?.string()?;
                let parsed = text
                    .split_once('x')
                    .and_then(|(w, h)| Some((w.parse().ok()?, h.parse().ok()?)))
                    .filter(|&(w, h): &(u32, u32)| {
                        (1..=8192).contains(&w) && (1..=8192).contains(&h)
                    });
                size = parsed.ok_or_else(|| {
                    format!("--size wants WxH with each in 1..=8192 (e.g. 1920x1080), got {text:?}")
                })?;
            }
            Short('o') | Long("output") if output.is_none() => {
                output = Some(parser.value()?.into())
            }
            Value(path) if output.is_none() => output = Some(path.into()),
            Short('o') | Long("output") | Value(_) => {
                return Err(format!("one output path only\n{}", usage_line(QUICKSTART_HELP)).into())
            }
            _ => {
                return Err(format!("{}\n{}", arg.unexpected(), usage_line(QUICKSTART_HELP)).into())
            }
        }
    }
    let output = output.unwrap_or_else(|| Path::new(OUT_DIR).join("quickstart.png"));
    if !output
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"))
    {
        return Err(format!(
            "quickstart writes a PNG: the output must end in .png, got {}",
            output.display()
        )
        .into());
    }
    Ok(Parsed::Run(QuickstartOptions { output, size }))
}

/// The first line of a help text (the usage line), for error messages.
pub fn usage_line(help: &str) -> &str {
    help.lines().next().unwrap_or(help)
}

// ---------------------------------------------------------------------------------------------
// interactive

/// A key `interactive` reacts to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Key {
    /// A letter (lower case).
    Char(char),
    /// Arrow up.
    Up,
    /// Arrow down.
    Down,
    /// Escape.
    Escape,
}

/// What a key does in `interactive`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Action {
    /// exact → hybrid → brute force → textbook → exact.
    CycleMethod,
    /// Steps × 2.
    MoreSteps,
    /// Steps ÷ 2.
    FewerSteps,
    /// Full → ½ → ¼ resolution.
    CycleScale,
    /// Shadows on / off.
    ToggleShadows,
    /// Light radius 0 → 0.1 → 0.25 → 0.5.
    CycleRadius,
    /// Frame → split → difference.
    CycleView,
    /// Quit.
    Quit,
}

/// `interactive`'s keys: the key, its name, what it does and its help line. The window's
/// handler looks keys up here ([`action_of`]), so what is printed is what the keys do.
pub const KEYS: [(Key, &str, Action, &str); 8] = [
    (
        Key::Char('m'),
        "M",
        Action::CycleMethod,
        "march method: exact -> hybrid -> brute force -> textbook -> exact",
    ),
    (
        Key::Up,
        "Up",
        Action::MoreSteps,
        "double the march steps (at most 512)",
    ),
    (
        Key::Down,
        "Down",
        Action::FewerSteps,
        "halve the march steps (at least 4)",
    ),
    (
        Key::Char('r'),
        "R",
        Action::CycleScale,
        "scattering resolution: full -> 1/2 -> 1/4",
    ),
    (
        Key::Char('s'),
        "S",
        Action::ToggleShadows,
        "shadows on / off (off: no occluders, the planner skips shadow map and extents)",
    ),
    (
        Key::Char('l'),
        "L",
        Action::CycleRadius,
        "light radius: 0 (hard shadows) -> 0.1 -> 0.25 -> 0.5 (soft shadows)",
    ),
    (
        Key::Char('v'),
        "V",
        Action::CycleView,
        "view: frame -> split (method | f64 reference) -> per-pixel error against the reference",
    ),
    (Key::Escape, "Esc", Action::Quit, "quit"),
];

/// What the mouse does, printed with the keys.
pub const MOUSE: &str =
    "move the light, left button held (it starts above and between the spheres)";

/// The action of a key, if it has one.
pub fn action_of(key: Key) -> Option<Action> {
    KEYS.iter().find(|k| k.0 == key).map(|k| k.2)
}

/// The keys, one a line, as printed at start and by `--help`.
pub fn keys_help() -> String {
    let mut text = format!("  {:<6}{MOUSE}\n", "drag");
    for (_, name, _, what) in KEYS {
        text.push_str(&format!("  {name:<6}{what}\n"));
    }
    text
}

/// The keys in a few words, for the window's title.
pub fn keys_short() -> String {
    let words = |a: Action| match a {
        Action::CycleMethod => "method",
        Action::MoreSteps => "steps",
        Action::FewerSteps => "steps",
        Action::CycleScale => "resolution",
        Action::ToggleShadows => "shadows",
        Action::CycleRadius => "radius",
        Action::CycleView => "view",
        Action::Quit => "quit",
    };
    let mut parts = vec!["drag: light".to_string()];
    for (_, name, action, _) in KEYS {
        if action == Action::FewerSteps {
            continue;
        }
        let name = if action == Action::MoreSteps {
            "Up/Down"
        } else {
            name
        };
        parts.push(format!("{name}: {}", words(action)));
    }
    parts.join(", ")
}

/// `interactive --help`.
pub fn interactive_help() -> String {
    format!(
        "usage: interactive [-h | --help]\n\n\
         Opens a window with the quickstart scene (a point light behind two spheres in hazy \
         air) and\nrenders volumetric shadows every frame; the window's title shows the \
         settings and each pass's\nGPU time. Build with `--features window`.\n\nkeys:\n{}",
        keys_help()
    )
}

/// Parses `interactive`'s arguments: none but `--help`.
pub fn parse_interactive(args: &[String]) -> Result<Parsed<()>, BoxError> {
    let mut parser = lexopt::Parser::from_args(args);
    if let Some(arg) = parser.next()? {
        return match arg {
            Short('h') | Long("help") => Ok(Parsed::Help),
            _ => Err(format!("{}\nusage: interactive [-h | --help]", arg.unexpected()).into()),
        };
    }
    Ok(Parsed::Run(()))
}

// ---------------------------------------------------------------------------------------------
// uniform_probe

/// `uniform_probe --help`.
pub const PROBE_HELP: &str = "\
usage: uniform_probe [uniform|storage] [FRAMES] [composite]

Does the driver compile (and keep) a shader variant per uniform-buffer value? Runs FRAMES
frames (default 2000) whose parameters change every frame, from a uniform buffer (default) or
a read-only storage buffer, and prints the resident set size and the time per frame every 250
frames. Without `composite`: a small compute shader whose loop bound and branch read the
buffer; with it: volshadow's composite shader. Writes no file.

environment:
  CYCLE=N    repeat N parameter sets (composite only)
  NOWRITE=1  write the buffers once (composite only)

options:
  -h, --help  this help";

/// `uniform_probe`'s options.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeOptions {
    /// Read-only storage buffers instead of uniform buffers.
    pub storage: bool,
    /// Frames to run.
    pub frames: u32,
    /// Volshadow's composite shader instead of the compute shader.
    pub composite: bool,
}

/// Parses `uniform_probe`'s arguments (after the program name).
pub fn parse_probe(args: &[String]) -> Result<Parsed<ProbeOptions>, BoxError> {
    let mut options = ProbeOptions {
        storage: false,
        frames: 2000,
        composite: false,
    };
    let mut positional = 0;
    let mut parser = lexopt::Parser::from_args(args);
    while let Some(arg) = parser.next()? {
        let bad =
            |what: String| -> BoxError { format!("{what}\n{}", usage_line(PROBE_HELP)).into() };
        match arg {
            Short('h') | Long("help") => return Ok(Parsed::Help),
            Value(value) => {
                let text = value.string()?;
                match (positional, text.as_str()) {
                    (0, "uniform" | "storage") => options.storage = text == "storage",
                    (0, other) => {
                        return Err(bad(format!(
                            "the buffer kind is uniform or storage, got {other:?}"
                        )))
                    }
                    (1, n) => {
                        options.frames = match n.parse::<u32>() {
                            Ok(f) if f > 0 => f,
                            _ => {
                                return Err(bad(format!(
                                    "FRAMES must be a positive whole number, got {n:?}"
                                )))
                            }
                        }
                    }
                    (2, "composite") => options.composite = true,
                    (2, other) => return Err(bad(format!("expected `composite`, got {other:?}"))),
                    _ => return Err(bad(format!("unexpected argument {text:?}"))),
                }
                positional += 1;
            }
            _ => return Err(bad(arg.unexpected().to_string())),
        }
    }
    Ok(Parsed::Run(options))
}
