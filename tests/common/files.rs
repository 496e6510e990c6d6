//! Test files: a binary glTF (GLB) container, and files written into a `tempfile::TempDir`.
//! Included with `#[path = "common/files.rs"] mod files;` by the tests that write files.
#![allow(dead_code)]

use std::path::PathBuf;

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
