//! Bounds on what loading a scene file or a glTF file may read and build.
//!
//! [`LoadOptions`] holds the bounds; [`crate::scene_file::SceneDescription::load_with`],
//! [`crate::gltf::load_with`] and [`crate::scene::LightTexture::from_image_file_with`] take
//! them, and the plain entry points use [`LoadOptions::default`].
//!
//! # Files
//!
//! * The file passed to a loader may be anywhere. Every path *inside* it (a scene file's glTF
//!   `path` and light-texture `file`, a glTF buffer `uri`) must resolve inside the folder of
//!   the file that names it, after `.`/`..`, percent-escapes (glTF URIs) and symbolic links are
//!   resolved. A path that leads outside is an [`Error::PathOutsideFolder`] whose message is
//!   the same whether the target exists or not; the resolution never looks at anything
//!   outside the folder. [`LoadOptions::allow_outside`] lifts the rule. A loop of symbolic
//!   links inside the folder (more than 40), or a component before the last that is missing or
//!   a file, is an [`Error::FileRead`], as opening it would be. [`resolve_inside`] is the rule,
//!   public; [`written_path`] is the same walk for a file a tool will write.
//! * Only regular files are read: a directory, device (`/dev/zero`), FIFO or socket is an
//!   [`Error::NotRegularFile`], decided from the file's metadata before it is opened (and, on
//!   Unix, opened non-blocking and checked again, so a FIFO swapped in meanwhile cannot block).
//! * A file larger than [`LoadOptions::max_file_bytes`] is an [`Error::LimitExceeded`]; reads
//!   stop one byte past the limit, so a file growing while it is read cannot exceed it either.
//!
//! # Totals
//!
//! One load (a scene file with everything it names, or one glTF file with its buffers) counts
//! bytes read, triangles, lights, light-texture texels, glTF nodes and placed meshes, and
//! stops with an [`Error::LimitExceeded`] naming the [`Limit`] as soon as one would pass its
//! bound. The counts are checked *before* the memory is allocated, so no input can make the
//! process abort on a failed allocation. A scene file's procedural shapes are totalled from
//! their declared sizes before any of them is built.
// Paths named inside files are only followed by the loaders behind the `gltf` and `image`
// features.
#![cfg_attr(not(any(feature = "gltf", feature = "image")), allow(dead_code))]

use std::io::Read;
use std::path::{Component, Path, PathBuf};

pub use crate::error::Limit;
use crate::error::{Error, Result};

/// Bounds on a load. The defaults suit interactive scenes; raise them for larger assets.
///
/// ```
/// use volshadow::load::LoadOptions;
/// let options = LoadOptions {
///     allow_outside: true,
///     max_triangles: 16 << 20,
///     ..LoadOptions::default()
/// };
/// # let _ = options;
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LoadOptions {
    /// Let paths named inside a file lead outside its folder (default `false`).
    pub allow_outside: bool,
    /// Largest single file, in bytes (default 256 MiB).
    pub max_file_bytes: u64,
    /// Most bytes read from all files of one load together (default 512 MiB).
    pub max_total_bytes: u64,
    /// Most triangles over all meshes of one load, each placement counted (default 4 Mi). A
    /// glTF primitive is checked from its accessor counts before it is read, and may have at
    /// most 3 positions per triangle still allowed; a scene file's procedural shapes are
    /// totalled from their declared sizes before any is built.
    pub max_triangles: u64,
    /// Most lights in a scene file (default 16).
    pub max_lights: u64,
    /// Most light-texture texels over all lights of a scene file (default 16 Mi: one 4096²
    /// texture).
    pub max_texels: u64,
    /// Most nodes in one glTF file (default 65,536).
    pub max_nodes: u64,
    /// Most placed meshes: scene-file objects plus glTF mesh placements (each primitive of each
    /// node that places a mesh) (default 16,384).
    pub max_instances: u64,
}

impl Default for LoadOptions {
    fn default() -> Self {
        Self {
            allow_outside: false,
            max_file_bytes: 256 << 20,
            max_total_bytes: 512 << 20,
            max_triangles: 4 << 20,
            max_lights: 16,
            max_texels: 16 << 20,
            max_nodes: 1 << 16,
            max_instances: 1 << 14,
        }
    }
}

/// The running totals of one load.
#[derive(Debug, Clone)]
pub(crate) struct Budget {
    pub(crate) options: LoadOptions,
    /// Indexed by `Limit as usize`.
    used: [u64; 7],
}

impl Budget {
    pub(crate) fn new(options: &LoadOptions) -> Self {
        Self {
            options: *options,
            used: [0; 7],
        }
    }

    /// The bound of `limit`.
    pub(crate) fn max(&self, limit: Limit) -> u64 {
        let o = &self.options;
        match limit {
            Limit::FileBytes => o.max_file_bytes,
            Limit::TotalBytes => o.max_total_bytes,
            Limit::Triangles => o.max_triangles,
            Limit::Lights => o.max_lights,
            Limit::Texels => o.max_texels,
            Limit::Nodes => o.max_nodes,
            Limit::Instances => o.max_instances,
        }
    }

    /// Checks that `n` more of `limit` fit, without counting them.
    pub(crate) fn check(&self, limit: Limit, n: u64, file: &str) -> Result<()> {
        let total = self.used[limit as usize].saturating_add(n);
        let max = self.max(limit);
        if total > max {
            return Err(Error::LimitExceeded {
                file: file.to_owned(),
                limit,
                count: total,
                max,
            });
        }
        Ok(())
    }

    /// Counts `n` more of `limit`, or fails if the total would pass its bound.
    pub(crate) fn add(&mut self, limit: Limit, n: u64, file: &str) -> Result<()> {
        self.check(limit, n, file)?;
        let slot = limit as usize;
        self.used[slot] = self.used[slot].saturating_add(n);
        Ok(())
    }

    /// Reads the regular file at `path` (see [`read_regular_file`]) and counts its bytes.
    pub(crate) fn read(&mut self, path: &Path) -> Result<Vec<u8>> {
        let remaining = self
            .max(Limit::TotalBytes)
            .saturating_sub(self.used[Limit::TotalBytes as usize]);
        let limit = self.options.max_file_bytes.min(remaining);
        let which = if limit < self.options.max_file_bytes {
            Limit::TotalBytes
        } else {
            Limit::FileBytes
        };
        let bytes = read_regular_file(path, limit).map_err(|e| match e {
            Error::LimitExceeded { file, count, .. } if which == Limit::TotalBytes => {
                Error::LimitExceeded {
                    file,
                    limit: which,
                    count: self.used[Limit::TotalBytes as usize].saturating_add(count),
                    max: self.max(Limit::TotalBytes),
                }
            }
            e => e,
        })?;
        self.add(
            Limit::TotalBytes,
            bytes.len() as u64,
            &path.display().to_string(),
        )?;
        Ok(bytes)
    }
}

/// Why a file could not be read (other than a limit).
fn io_error(path: &Path, e: &std::io::Error) -> Error {
    Error::FileRead {
        path: path.display().to_string(),
        problem: e.to_string(),
    }
}

/// Reads the regular file at `path`, at most `max_bytes` of it.
///
/// A path that is not a regular file (directory, device, FIFO, socket; symbolic links are
/// followed) is an [`Error::NotRegularFile`], decided before opening it. A file longer than
/// `max_bytes` is an [`Error::LimitExceeded`] for [`Limit::FileBytes`]: the read takes at most
/// `max_bytes + 1` bytes, so a file that grows meanwhile cannot make it read more.
pub(crate) fn read_regular_file(path: &Path, max_bytes: u64) -> Result<Vec<u8>> {
    let shown = || path.display().to_string();
    let not_regular = || Error::NotRegularFile { path: shown() };
    let too_large = |count: u64| Error::LimitExceeded {
        file: shown(),
        limit: Limit::FileBytes,
        count,
        max: max_bytes,
    };
    let metadata = std::fs::metadata(path).map_err(|e| io_error(path, &e))?;
    if !metadata.is_file() {
        return Err(not_regular());
    }
    if metadata.len() > max_bytes {
        return Err(too_large(metadata.len()));
    }
    let mut open = std::fs::OpenOptions::new();
    open.read(true);
    #[cfg(unix)]
    {
        // Non-blocking, so that a FIFO put in the file's place after the check above cannot
        // block the open; reads from a regular file are unaffected.
        use std::os::unix::fs::OpenOptionsExt;
        open.custom_flags(libc::O_NONBLOCK);
    }
    let file = open.open(path).map_err(|e| io_error(path, &e))?;
    let metadata = file.metadata().map_err(|e| io_error(path, &e))?;
    if !metadata.is_file() {
        return Err(not_regular());
    }
    let mut bytes = Vec::new();
    // The size is bounded by `max_bytes` above; a failed reservation is an error, not an abort.
    bytes
        .try_reserve_exact(metadata.len() as usize)
        .map_err(|e| Error::FileRead {
            path: shown(),
            problem: format!("cannot allocate {} bytes: {e}", metadata.len()),
        })?;
    file.take(max_bytes.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| io_error(path, &e))?;
    if bytes.len() as u64 > max_bytes {
        return Err(too_large(bytes.len() as u64));
    }
    Ok(bytes)
}

/// The canonical folder of the file at `file` (its parent, or `.`).
pub(crate) fn folder_of(file: &Path) -> Result<PathBuf> {
    let dir = match file.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    };
    dir.canonicalize().map_err(|e| io_error(dir, &e))
}

/// Where `named` (a path written at `field` of the file `file`) leads from `folder` (the
/// canonical folder of `file`): confined to it unless `allow_outside` (see [`resolve`]).
///
/// A path that leads outside is [`Error::PathOutsideFolder`]; one that runs into a loop of
/// symbolic links inside the folder, or through a component inside it that is missing or not
/// a folder, is a read error, [`Error::FileRead`], as opening it would be: all of these are
/// inside the folder, so saying so tells nothing about what lies outside.
pub(crate) fn confine(
    folder: &Path,
    named: &Path,
    allow_outside: bool,
    file: &str,
    field: &str,
) -> Result<PathBuf> {
    let read_error = |problem: String| Error::FileRead {
        path: folder.join(named).display().to_string(),
        problem,
    };
    match resolve(folder, named, allow_outside) {
        Resolved::Inside(path) => Ok(path),
        Resolved::Outside => Err(Error::PathOutsideFolder {
            file: file.to_owned(),
            field: field.to_owned(),
            target: named.display().to_string(),
        }),
        Resolved::LinkLoop => Err(read_error(format!(
            "too many levels of symbolic links (more than {MAX_LINKS}: a loop of links)"
        ))),
        Resolved::Missing(at) => Err(read_error(format!(
            "no such file or directory: {} does not exist",
            at.display()
        ))),
        Resolved::NotAFolder(at) => Err(read_error(format!(
            "not a directory: {} is a file, and the path goes on below it",
            at.display()
        ))),
    }
}

/// Where `named`, a path written in a file whose folder is `folder`, leads under the rule
/// every loader of this crate applies to the paths inside the files it reads (a scene file's
/// glTF `path` and light-texture `file`, a glTF buffer's `uri`): resolved one component at a
/// time as the operating system resolves it (symbolic links followed, `..` leaving the folder
/// actually reached), and refused as soon as it leaves `folder`.
///
/// `named` is read as [`Path::components`] reads it: `.` components and a trailing separator
/// are dropped (so `tex.png/.` is `tex.png`, where the system would say "not a directory").
/// The path returned holds no symbolic link and no `..`, and every component but the last
/// exists: opening it opens the file the walk checked.
///
/// # Errors
///
/// [`Error::PathOutsideFolder`] for a path that leads outside `folder` (the same whether its
/// target exists or not: nothing outside `folder` is looked at); [`Error::FileRead`] for a
/// loop of links, or a component before the last that is missing or not a folder;
/// [`Error::FileRead`] when `folder` itself cannot be resolved.
///
/// ```no_run
/// use std::path::Path;
/// let texture = volshadow::load::resolve_inside(Path::new("scenes"), Path::new("tex/a.png"))?;
/// # Ok::<(), volshadow::Error>(())
/// ```
pub fn resolve_inside(folder: &Path, named: &Path) -> Result<PathBuf> {
    let canonical = folder.canonicalize().map_err(|e| io_error(folder, &e))?;
    let shown = folder.display().to_string();
    confine(&canonical, named, false, &shown, "path")
}

/// The file that writing `path` reaches once its missing folders are created (as a tool that
/// creates an output's folder and then writes it does): the same walk as
/// [`resolve_inside`], unconfined, from the working folder (or the root, for an absolute
/// path), with each missing component taken as the new folder it will be. So
/// `new/../scene.json` is `./scene.json`, and `new/../link` is where the link `./link`
/// points.
///
/// `None` where nothing can be written at `path`: a component before the last is a file, a
/// loop of links, or the working folder cannot be resolved.
pub fn written_path(path: &Path) -> Option<PathBuf> {
    let root = PathBuf::from(std::path::MAIN_SEPARATOR_STR);
    let start = if path.has_root() {
        root.clone()
    } else {
        std::env::current_dir().ok()?.canonicalize().ok()?
    };
    let steps = parts(path.strip_prefix(&root).unwrap_or(path), &root)?;
    match walk(&root, start, steps, Missing::Created) {
        Walk::Found(path) => Some(path),
        _ => None,
    }
}

/// Reads the file that `named` names (see [`confine`]) and counts its bytes. Returns the path
/// read and its bytes.
pub(crate) fn read_named(
    budget: &mut Budget,
    folder: &Path,
    named: &Path,
    file: &str,
    field: &str,
) -> Result<(PathBuf, Vec<u8>)> {
    let path = confine(folder, named, budget.options.allow_outside, file, field)?;
    let bytes = budget.read(&path)?;
    Ok((path, bytes))
}

/// One step of a path being resolved.
#[derive(Debug, Clone)]
enum Part {
    Parent,
    Name(std::ffi::OsString),
}

/// `path`'s steps, or `None` if it is absolute and not under `folder` (or has a prefix).
fn parts(path: &Path, folder: &Path) -> Option<Vec<Part>> {
    let relative = if path.has_root() {
        path.strip_prefix(folder).ok()?
    } else {
        path
    };
    let mut out = Vec::new();
    for c in relative.components() {
        match c {
            Component::Prefix(_) | Component::RootDir => return None,
            Component::CurDir => {}
            Component::ParentDir => out.push(Part::Parent),
            Component::Normal(name) => out.push(Part::Name(name.to_owned())),
        }
    }
    Some(out)
}

/// The most symbolic links followed in resolving one path (Linux's own bound): more is a loop.
const MAX_LINKS: u32 = 40;

/// Where [`resolve`] found that a path leads.
#[derive(Debug, PartialEq)]
pub(crate) enum Resolved {
    /// Inside the folder (or anywhere, where going outside is allowed): this path, every
    /// component of which but the last exists.
    Inside(PathBuf),
    /// Outside the folder.
    Outside,
    /// More than [`MAX_LINKS`] symbolic links, every one of them inside the folder: a loop.
    LinkLoop,
    /// This component, inside the folder, does not exist, and the path goes on below it (so
    /// nothing the path names can exist either).
    Missing(PathBuf),
    /// This component, inside the folder, is not a folder, and the path goes on below it.
    NotAFolder(PathBuf),
}

/// What a walk does with a component that does not exist and is not the last.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Missing {
    /// Stops: a path read through it names nothing.
    Stops,
    /// Takes it as a new, empty folder (an output whose folders will be created): the names
    /// below it do not exist either, and `..` goes back to where it was made.
    Created,
}

/// Where [`walk`] ended.
#[derive(Debug, PartialEq)]
enum Walk {
    /// The path reached: no link and no `..` in it; every component exists but the last, and
    /// with [`Missing::Created`] the new folders it would make.
    Found(PathBuf),
    /// Left the root (confined walks only).
    Outside,
    /// Too many links.
    LinkLoop,
    /// A missing component with more after it ([`Missing::Stops`]).
    Missing(PathBuf),
    /// A component that exists and is not a folder, with more after it.
    NotAFolder(PathBuf),
}

/// Walks `steps` from `start` (a canonical path under `root`) one component at a time, as the
/// operating system resolves a path: a symbolic link is replaced by its target's steps (from
/// `root` for an absolute target, which must lie under it, else from the link's folder), and
/// `..` leaves the folder reached so far, not the one written. Only paths under `root` are
/// looked at on disk, so the outcome cannot depend on what lies outside it. `..` at `root` is
/// [`Walk::Outside`] unless `root` is the file system's root, where it stays (as the system
/// does).
fn walk(root: &Path, start: PathBuf, steps: Vec<Part>, missing: Missing) -> Walk {
    let top = root.parent().is_none();
    let mut pending = steps;
    pending.reverse();
    let mut current = start;
    // How many trailing components of `current` do not exist (folders yet to be created).
    let mut created = 0usize;
    let mut hops = 0;
    while let Some(part) = pending.pop() {
        let name = match part {
            Part::Parent => {
                if current == root {
                    if top {
                        continue;
                    }
                    return Walk::Outside;
                }
                current.pop();
                created = created.saturating_sub(1);
                continue;
            }
            Part::Name(name) => name,
        };
        current.push(name);
        if created > 0 {
            created += 1;
            continue;
        }
        let last = pending.is_empty();
        match std::fs::symlink_metadata(&current) {
            Ok(m) if m.file_type().is_symlink() => {
                hops += 1;
                if hops > MAX_LINKS {
                    return Walk::LinkLoop;
                }
                let Ok(target) = std::fs::read_link(&current) else {
                    return Walk::Outside;
                };
                current.pop();
                if target.has_root() {
                    current = root.to_path_buf();
                }
                let Some(steps) = parts(&target, root) else {
                    return Walk::Outside;
                };
                pending.extend(steps.into_iter().rev());
            }
            Ok(m) if !m.is_dir() && !last => return Walk::NotAFolder(current),
            Ok(_) => {}
            Err(_) if last => {}
            Err(_) => match missing {
                Missing::Stops => return Walk::Missing(current),
                Missing::Created => created = 1,
            },
        }
    }
    if current.starts_with(root) {
        Walk::Found(current)
    } else {
        Walk::Outside
    }
}

/// Resolves `named` (a path written inside a file) against `folder` (that file's canonical
/// folder).
///
/// With `allow_outside` it is `folder.join(named)`. Otherwise it is [`walk`]ed from `folder`
/// and confined to it: `Outside` as soon as it leaves the folder (an absolute path, or a link
/// to one, counts as inside only when it starts with `folder`), whether the target exists or
/// not. A component before the last that is missing, or is not a folder, ends it: the
/// operating system would not reach a file through it (and applying the `..` that follow as
/// written would reach one it does not: a link beside the missing component, say).
pub(crate) fn resolve(folder: &Path, named: &Path, allow_outside: bool) -> Resolved {
    if allow_outside {
        return Resolved::Inside(folder.join(named));
    }
    let Some(steps) = parts(named, folder) else {
        return Resolved::Outside;
    };
    match walk(folder, folder.to_path_buf(), steps, Missing::Stops) {
        Walk::Found(path) => Resolved::Inside(path),
        Walk::Outside => Resolved::Outside,
        Walk::LinkLoop => Resolved::LinkLoop,
        Walk::Missing(at) => Resolved::Missing(at),
        Walk::NotAFolder(at) => Resolved::NotAFolder(at),
    }
}
