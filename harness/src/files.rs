//! Test files: a binary glTF (GLB) container, files written into a `tempfile::TempDir`, and
//! the check that a refused run wrote nothing.

use std::path::{Path, PathBuf};

/// Files written into a test's temporary folder.
pub trait WriteAt {
    /// Writes `bytes` at `relative` (creating folders) and returns the full path.
    fn write(&self, relative: &str, bytes: impl AsRef<[u8]>) -> PathBuf;
}

impl WriteAt for tempfile::TempDir {
    fn write(&self, relative: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
        let path = self.path().join(relative);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, bytes).unwrap();
        path
    }
}

/// The GLB of `json` and `bin`, each chunk padded to 4 bytes (JSON with spaces, BIN with
/// zeros) as the format requires.
pub fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut json = json.as_bytes().to_vec();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut bin = bin.to_vec();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

/// The bytes of every file in `dir` (names and contents), to show a refused run wrote nothing.
pub fn snapshot(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut files: Vec<(PathBuf, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file())
        .map(|p| {
            let bytes = std::fs::read(&p).unwrap();
            (p, bytes)
        })
        .collect();
    files.sort();
    files
}

/// A refused run: the error is [`WouldOverwriteInput`](crate::cli::WouldOverwriteInput) naming the input (its file name) and
/// the output, and nothing in `dir` changed.
pub fn assert_refused<T>(
    result: Result<T, crate::app::BoxError>,
    input: &str,
    dir: &Path,
    before: &[(PathBuf, Vec<u8>)],
    case: &str,
) {
    let error = match result {
        Ok(_) => panic!("{case}: the run was not refused"),
        Err(e) => e,
    };
    let refusal = error
        .downcast_ref::<crate::cli::WouldOverwriteInput>()
        .unwrap_or_else(|| panic!("{case}: another error than the refusal: {error}"));
    let message = error.to_string();
    println!("{case}: {message}");
    assert!(
        refusal.input.ends_with(input) && message.contains(&refusal.output.display().to_string()),
        "{case}: {message}"
    );
    assert_eq!(snapshot(dir), before, "{case}: files changed");
}
