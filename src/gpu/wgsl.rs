//! The crate's WGSL files and the include step that joins them. A file names the files it uses
//! in `#import NAME.wgsl` lines; [`compose`] puts each imported file once before the first file
//! that imports it, after the precision wrappers, and keeps where each line came from, so that
//! an error names the file and the line it is in ([`Composed::locate`]).

use crate::gpu::precision;
use crate::gpu::ShaderPrecision;

/// One WGSL source: a file of `shaders/`, or a node's generated variant of one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Wgsl<'a> {
    /// The file's name (a generated source: what it is, for error messages).
    pub name: &'a str,
    /// Its text.
    pub text: &'a str,
}

/// A WGSL file of `shaders/`: `wgsl_file!("NAME.wgsl")` a pass's own, in `shaders/passes/`;
/// `wgsl_file!(shared "NAME.wgsl")` a shared one (also in [`FILES`]), in `shaders/shared/`.
/// Named as in the folder (from the crate's root, so that a node in a folder of `src/nodes/`
/// names it as one in a file does).
macro_rules! wgsl_file {
    ($name:literal) => {
        $crate::gpu::wgsl::Wgsl {
            name: $name,
            text: include_str!(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/shaders/passes/",
                $name
            )),
        }
    };
    (shared $name:literal) => {
        $crate::gpu::wgsl::Wgsl {
            name: $name,
            text: include_str!(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/shaders/shared/",
                $name
            )),
        }
    };
}
pub(crate) use wgsl_file;

/// Every file an `#import` can name: each `.wgsl` file under `shaders/shared/`, named by its
/// path there (`light/point.wgsl`), listed by the build script from the folder itself.
pub(crate) const FILES: &[Wgsl<'static>] = include!(concat!(env!("OUT_DIR"), "/shared_wgsl.rs"));

/// In tests, also a shared file with an error, for the check that errors name their file.
#[cfg(test)]
static BROKEN: Wgsl<'static> = Wgsl {
    name: "broken.wgsl",
    text:
        "// a shared file with an error on line 3\n\nfn broken() -> f32 { return no_such_name; }\n",
};

/// The shared file an `#import` line names.
fn shared(name: &str) -> Option<&'static Wgsl<'static>> {
    #[cfg(test)]
    if name == BROKEN.name {
        return Some(&BROKEN);
    }
    FILES.iter().find(|f| f.name == name)
}

/// The import directive: `#import NAME.wgsl` alone on a line.
const IMPORT: &str = "#import ";

/// Lines `first ..= first + lines − 1` of the composed text are lines `1 ..= lines` of `file`.
#[derive(Debug, Clone, PartialEq)]
struct Span {
    file: String,
    first: usize,
    lines: usize,
}

/// A composed WGSL module and where each of its lines came from.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Composed {
    /// The text that is compiled.
    pub text: String,
    spans: Vec<Span>,
}

impl Composed {
    /// The file and line (both 1-based) that line `line` of the composed text is; `("?", line)`
    /// past the end. (The sources are the crate's own: `every_shader_compiles` parses each
    /// module with naga and names an error's file and line with this.)
    #[cfg(test)]
    pub(crate) fn locate(&self, line: usize) -> (&str, usize) {
        self.spans
            .iter()
            .find(|s| (s.first..s.first + s.lines).contains(&line))
            .map_or(("?", line), |s| (s.file.as_str(), line - s.first + 1))
    }
}

/// The files `source` imports, in order.
fn imports<'s>(source: &'s Wgsl<'_>) -> impl Iterator<Item = &'static Wgsl<'static>> + 's {
    source
        .text
        .lines()
        .filter_map(|l| l.trim_end().strip_prefix(IMPORT))
        .map(|name| match shared(name.trim()) {
            Some(f) => f,
            // The sources are the crate's own: every_shader_composes fails on an unknown name.
            None => panic!("{}: #import of unknown file `{name}`", source.name),
        })
}

/// `source` with its imports (each file once, before the first file that imports it) after the
/// precision wrappers at `precision`. Import lines become blank lines, so each file keeps its
/// line numbers.
pub(crate) fn compose(source: &Wgsl<'_>, precision: ShaderPrecision) -> Composed {
    let mut order: Vec<Wgsl<'_>> = Vec::new();
    visit(*source, &mut order, &mut Vec::new());
    let mut composed = Composed {
        text: String::new(),
        spans: Vec::new(),
    };
    let wrappers = precision::wgsl(precision);
    push(&mut composed, "precision.wgsl", &wrappers);
    for file in order {
        let text: String = file
            .text
            .lines()
            .map(|l| match l.starts_with(IMPORT) {
                true => "\n".to_string(),
                false => format!("{l}\n"),
            })
            .collect();
        push(&mut composed, file.name, &text);
    }
    composed
}

/// Appends `file` (its own line numbers from 1) to `composed`.
fn push(composed: &mut Composed, file: &str, text: &str) {
    let first = composed.text.lines().count() + 1;
    composed.text.push_str(text);
    if !text.ends_with('\n') {
        composed.text.push('\n');
    }
    composed.spans.push(Span {
        file: file.to_string(),
        first,
        lines: text.lines().count(),
    });
}

/// Depth first: `file`'s imports, then `file`, each once; a cycle panics (the sources are the
/// crate's own: `every_shader_composes` fails on one).
fn visit<'a>(file: Wgsl<'a>, order: &mut Vec<Wgsl<'a>>, path: &mut Vec<&'a str>) {
    if order.iter().any(|f| f.name == file.name) {
        return;
    }
    assert!(
        !path.contains(&file.name),
        "an #import cycle: {} -> {}",
        path.join(" -> "),
        file.name
    );
    path.push(file.name);
    for import in imports(&file) {
        visit(*import, order, path);
    }
    path.pop();
    order.push(file);
}

#[cfg(test)]
mod tests {
    use super::{compose, Wgsl};
    use crate::gpu::ShaderPrecision;

    /// An import is placed once, before its first importer, and every line of the composed text
    /// locates to the line of the file it came from: a line of the node after a 500-line import
    /// is still the node's own line.
    #[test]
    fn composed_lines_locate_to_their_files() {
        let node = Wgsl {
            name: "node.wgsl",
            text: "#import pcss.wgsl\n#import prelude.wgsl\n// line 3\nfn line4() {}\n",
        };
        let composed = compose(&node, ShaderPrecision::Native);
        let lines: Vec<&str> = composed.text.lines().collect();
        let at = |needle: &str| lines.iter().position(|l| l.contains(needle)).unwrap() + 1;
        assert_eq!(composed.locate(at("fn line4()")), ("node.wgsl", 4));
        let prelude = at("fn vs_fullscreen");
        let pcss = at("fn shadow_face(");
        assert!(
            prelude < pcss,
            "the prelude, which pcss imports, comes first"
        );
        let (file, line) = composed.locate(pcss);
        let expected = 1 + super::shared("pcss.wgsl")
            .expect("a shared file")
            .text
            .lines()
            .position(|l| l.contains("fn shadow_face("))
            .unwrap();
        assert_eq!((file, line), ("pcss.wgsl", expected));
        assert_eq!(
            composed.text.matches("fn vs_fullscreen").count(),
            1,
            "imported once"
        );
        assert!(composed.text.lines().all(|l| !l.starts_with("#import")));
    }
}
