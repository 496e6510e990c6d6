//! File loading is confined and bounded: paths named inside scene files and glTF files stay in
//! the folder of the file that names them, only regular files are read, and totals (bytes,
//! triangles, lights, texels, nodes, placed meshes) are bounded, each with a typed error.
//!
//! Every test builds its own files under a fresh temporary folder.
#![cfg(feature = "gltf")]

use volshadow_harness::files;

use std::path::Path;
use std::time::Duration;

use files::{glb, WriteAt};
use volshadow::scene_file::SceneDescription;
use volshadow::{gltf, Error, Limit, LoadOptions};

/// Hang guard: every rejection below is decided from metadata and counts and returns in
/// milliseconds, even on a loaded machine; a loader that opens a FIFO blocks forever. Two
/// minutes is far beyond any healthy run, so the guard only turns a hang into a failure
/// (instead of a suite that never ends); it judges no speed. (A loader reading `/dev/zero`
/// would run out of memory, which fails the test binary by itself.)
const HANG: Duration = Duration::from_secs(120);

/// A valid scene with `objects` and, if given, `lights` (raw JSON arrays).
fn scene(objects: &str, lights: Option<&str>) -> String {
    let lights = lights.unwrap_or(r#"[{"type": "point", "position": [0, 6, 0], "intensity": 10}]"#);
    format!(
        r#"{{"name": "t",
            "camera": {{"eye": [0, 2, 8], "target": [0, 1, 0], "fov_y_degrees": 45, "near": 0.1}},
            "lights": {lights}, "medium": {{"sigma_s": 0.05}}, "objects": {objects}}}"#
    )
}

/// A scene whose one object is the glTF file `path`.
fn gltf_scene(path: &str) -> String {
    scene(
        &format!(r#"[{{"name": "m", "shape": {{"type": "gltf", "path": {path:?}}}}}]"#),
        None,
    )
}

/// A scene whose one spot light has the texture file `file`.
fn texture_scene(file: &str) -> String {
    scene(
        "[]",
        Some(&format!(
            r#"[{{"type": "spot", "position": [0, 5, 0], "direction": [0, -1, 0],
                 "cone_angle_degrees": 40, "intensity": 1, "texture": {{"file": {file:?}}}}}]"#
        )),
    )
}

/// A one-triangle glTF whose buffer is at `uri` (36 bytes).
fn gltf_with_buffer(uri: &str) -> String {
    format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}],
            "nodes": [{{"mesh": 0}}],
            "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}}}]}}],
            "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                            "min": [0, 0, 0], "max": [1, 0, 1]}}],
            "bufferViews": [{{"buffer": 0, "byteLength": 36}}],
            "buffers": [{{"byteLength": 36, "uri": {uri:?}}}]}}"#
    )
}

/// The 36 bytes of one triangle.
fn triangle_bin() -> Vec<u8> {
    [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]
        .iter()
        .flat_map(|p| p.to_le_bytes())
        .collect()
}

/// Runs `f` on its own thread and returns what it returns; fails if it has not returned
/// after [`HANG`] (the thread is left blocked: the test fails, the suite goes on).
fn quick<T: Send + 'static>(what: &str, f: impl FnOnce() -> T + Send + 'static) -> T {
    let (send, receive) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = send.send(f());
    });
    receive
        .recv_timeout(HANG)
        .unwrap_or_else(|e| panic!("{what} did not return within {HANG:?} ({e}): a hang"))
}

/// Loads the scene text from `dir` with the default options; must fail.
fn scene_err(dir: &Path, text: &str) -> Error {
    let what = format!("scene in {}", dir.display());
    let (dir, text) = (dir.to_path_buf(), text.to_owned());
    quick(&what, move || SceneDescription::from_json(&text, &dir)).expect_err("must be rejected")
}

fn is_outside(e: &Error) -> bool {
    matches!(e, Error::PathOutsideFolder { .. })
}

fn is_not_regular(e: &Error) -> bool {
    matches!(e, Error::NotRegularFile { .. })
}

fn limit_of(e: &Error) -> Option<Limit> {
    match e {
        Error::LimitExceeded { limit, .. } => Some(*limit),
        _ => None,
    }
}

/// Fails the same way with the target present and absent: loads `text` from `dir` once with
/// `create` done and once after `remove`, and compares the messages.
fn same_either_way(dir: &Path, text: &str, create: impl Fn(), remove: impl Fn()) -> Error {
    create();
    let present = scene_err(dir, text);
    remove();
    let absent = scene_err(dir, text);
    assert_eq!(
        present.to_string(),
        absent.to_string(),
        "the error must not tell whether the target exists"
    );
    assert_eq!(present, absent);
    present
}

// -------------------------------------------------------------------------------------------
// Paths outside the folder
// -------------------------------------------------------------------------------------------

#[test]
fn parent_path_is_outside_whether_or_not_it_exists() {
    let t = tempfile::tempdir().unwrap();
    let scene_dir = t.path().join("scene");
    std::fs::create_dir_all(&scene_dir).unwrap();
    let secret = t.path().join("secret.gltf");
    let text = gltf_scene("../secret.gltf");
    let e = same_either_way(
        &scene_dir,
        &text,
        || std::fs::write(&secret, gltf_with_buffer("data:,")).unwrap(),
        || std::fs::remove_file(&secret).unwrap(),
    );
    assert!(is_outside(&e), "{e}");
    assert!(e.to_string().contains("objects[0].shape.path"), "{e}");
}

#[cfg(feature = "image")]
#[test]
fn texture_file_outside_whether_or_not_it_exists() {
    let t = tempfile::tempdir().unwrap();
    let scene_dir = t.path().join("scene");
    std::fs::create_dir_all(&scene_dir).unwrap();
    // The same through a light texture's "file" (the message names that field).
    let text = texture_scene("../secret.png");
    let png = t.path().join("secret.png");
    let e = same_either_way(
        &scene_dir,
        &text,
        || std::fs::write(&png, b"not read").unwrap(),
        || std::fs::remove_file(&png).unwrap(),
    );
    assert!(is_outside(&e), "{e}");
    assert!(e.to_string().contains("lights[0].texture.file"), "{e}");
}

#[test]
fn absolute_path_is_outside_whether_or_not_it_exists() {
    let t = tempfile::tempdir().unwrap();
    let scene_dir = t.path().join("scene");
    std::fs::create_dir_all(&scene_dir).unwrap();
    let secret = t.path().join("secret.gltf");
    let text = gltf_scene(secret.to_str().unwrap());
    let e = same_either_way(
        &scene_dir,
        &text,
        || std::fs::write(&secret, gltf_with_buffer("data:,")).unwrap(),
        || std::fs::remove_file(&secret).unwrap(),
    );
    assert!(is_outside(&e), "{e}");
}

/// A glTF's buffer URI, plain, percent-encoded and absolute, pointing at `../secret.bin`.
#[test]
fn gltf_buffer_uri_outside_whether_or_not_it_exists() {
    let t = tempfile::tempdir().unwrap();
    let secret = t.path().join("secret.bin");
    for uri in [
        "../secret.bin".to_owned(),
        "..%2Fsecret.bin".to_owned(),
        "%2E%2E/secret.bin".to_owned(),
        secret.to_str().unwrap().replace('/', "%2F"),
    ] {
        t.write("scene/models/m.gltf", gltf_with_buffer(&uri));
        let text = gltf_scene("models/m.gltf");
        // The glTF's folder is scene/models: the relative URIs name scene/secret.bin, the
        // absolute one the secret beside scene/.
        let target = if uri.starts_with("%2F") {
            secret.clone()
        } else {
            t.path().join("scene/secret.bin")
        };
        let e = same_either_way(
            &t.path().join("scene"),
            &text,
            || std::fs::write(&target, triangle_bin()).unwrap(),
            || std::fs::remove_file(&target).unwrap(),
        );
        assert!(is_outside(&e), "{uri}: {e}");
        assert!(e.to_string().contains("buffers[0].uri"), "{e}");
    }
}

/// A symbolic link inside the folder that points out of it: refused whether its target exists
/// or not (a dangling link reads the same as one to an existing file).
#[cfg(unix)]
#[test]
fn symlink_out_of_the_folder_is_outside() {
    let t = tempfile::tempdir().unwrap();
    let scene_dir = t.path().join("scene");
    std::fs::create_dir_all(&scene_dir).unwrap();
    let secret = t.path().join("secret.gltf");
    std::os::unix::fs::symlink(&secret, scene_dir.join("link.gltf")).unwrap();
    let text = gltf_scene("link.gltf");
    let e = same_either_way(
        &scene_dir,
        &text,
        || std::fs::write(&secret, gltf_with_buffer("data:,")).unwrap(),
        || std::fs::remove_file(&secret).unwrap(),
    );
    assert!(is_outside(&e), "{e}");

    // A relative link climbing out through a subfolder, and a link to a folder outside.
    std::fs::create_dir_all(scene_dir.join("sub")).unwrap();
    std::os::unix::fs::symlink("../../secret.gltf", scene_dir.join("sub/up.gltf")).unwrap();
    std::os::unix::fs::symlink(t.path(), scene_dir.join("parent_dir")).unwrap();
    for path in ["sub/up.gltf", "parent_dir/secret.gltf"] {
        let e = same_either_way(
            &scene_dir,
            &gltf_scene(path),
            || std::fs::write(&secret, gltf_with_buffer("data:,")).unwrap(),
            || std::fs::remove_file(&secret).unwrap(),
        );
        assert!(is_outside(&e), "{path}: {e}");
    }
}

/// A loop of symbolic links inside the folder is a read error ("too many levels of symbolic
/// links"), as opening it would be, not a path outside the folder (it was
/// `PathOutsideFolder`): as a scene's glTF path (a link to itself, and two links to each
/// other), a glTF buffer URI and a light-texture file.
#[cfg(unix)]
#[test]
fn symlink_loop_inside_the_folder_is_a_read_error() {
    use std::os::unix::fs::symlink;
    let t = tempfile::tempdir().unwrap();
    let dir = t.path();
    symlink("self.gltf", dir.join("self.gltf")).unwrap();
    symlink("b.gltf", dir.join("a.gltf")).unwrap();
    symlink("a.gltf", dir.join("b.gltf")).unwrap();
    for name in ["self.gltf", "a.gltf"] {
        let e = scene_err(dir, &gltf_scene(name));
        assert!(!is_outside(&e), "{name}: {e}");
        match &e {
            Error::SceneFile(f) => {
                assert_eq!(f.field, "objects[0].shape.path", "{e}");
                assert!(f.problem.contains("cannot read"), "{e}");
                assert!(f.problem.contains("symbolic links"), "{e}");
            }
            other => panic!("{name}: expected a read error, got {other:?}"),
        }
    }
    // The same link loop straight through the public read error of the folder rules.
    symlink("loop.bin", dir.join("loop.bin")).unwrap();
    let gltf_path = t.write("m.gltf", gltf_with_buffer("loop.bin"));
    let e = quick("buffer loop", move || gltf::load(gltf_path)).unwrap_err();
    assert!(!is_outside(&e), "{e}");
    match &e {
        Error::Gltf(volshadow::GltfError::Invalid { kind, problem, .. }) => {
            assert_eq!(*kind, gltf::ErrorKind::MissingBuffer, "{e}");
            assert!(problem.contains("cannot read buffer 0"), "{e}");
            assert!(problem.contains("symbolic links"), "{e}");
        }
        other => panic!("expected a read error, got {other:?}"),
    }
    #[cfg(feature = "image")]
    {
        symlink("loop.png", dir.join("loop.png")).unwrap();
        let e = scene_err(dir, &texture_scene("loop.png"));
        assert!(!is_outside(&e), "{e}");
        match &e {
            Error::SceneFile(f) => {
                assert_eq!(f.field, "lights[0].texture.file", "{e}");
                assert!(f.problem.contains("cannot read"), "{e}");
                assert!(f.problem.contains("symbolic links"), "{e}");
            }
            other => panic!("expected a read error, got {other:?}"),
        }
    }
}

/// A link out of the folder reached through a component that does not exist
/// (`nonexistent/../link.gltf`) or through a regular file (`scene.json/x/../../link.gltf`):
/// the system reaches no file through either, and neither may the loader (both read the
/// link's outside target, applying the `..` after the missing component as written). Refused
/// with a read error that names the component, the same whether the outside target exists or
/// not.
#[cfg(unix)]
#[test]
fn link_reached_through_a_missing_component_or_a_file_is_not_read() {
    let t = tempfile::tempdir().unwrap();
    let scene_dir = t.path().join("scene");
    std::fs::create_dir_all(&scene_dir).unwrap();
    std::fs::write(scene_dir.join("scene.json"), "{}").unwrap();
    let secret = t.path().join("secret.gltf");
    std::os::unix::fs::symlink(&secret, scene_dir.join("link.gltf")).unwrap();
    for (path, problem) in [
        ("nonexistent/../link.gltf", "does not exist"),
        ("a/b/../../link.gltf", "does not exist"),
        ("scene.json/x/../../link.gltf", "not a directory"),
        ("scene.json/../link.gltf", "not a directory"),
    ] {
        let e = same_either_way(
            &scene_dir,
            &gltf_scene(path),
            || std::fs::write(&secret, gltf_with_buffer("data:,")).unwrap(),
            || std::fs::remove_file(&secret).unwrap(),
        );
        match &e {
            Error::SceneFile(f) => {
                assert_eq!(f.field, "objects[0].shape.path", "{path}: {e}");
                assert!(f.problem.contains(problem), "{path}: {e}");
            }
            other => panic!("{path}: expected a read error, got {other:?}"),
        }
    }
    // The same paths through the public rule every loader applies.
    for path in ["nonexistent/../link.gltf", "scene.json/x/../../link.gltf"] {
        let e = volshadow::load::resolve_inside(&scene_dir, Path::new(path)).unwrap_err();
        assert!(matches!(e, Error::FileRead { .. }), "{path}: {e}");
    }
}

/// A glTF buffer through a missing component to a link out of the folder: its bytes were read
/// (an index buffer so placed echoed the outside file's first bytes in its error). Here the
/// outside file is a valid buffer, so reading it would load: the load must fail, and fail the
/// same whether the outside file exists or not.
#[cfg(unix)]
#[test]
fn gltf_buffer_through_a_missing_component_is_not_read() {
    let t = tempfile::tempdir().unwrap();
    let model_dir = t.path().join("model");
    std::fs::create_dir_all(&model_dir).unwrap();
    let secret = t.path().join("secret.bin");
    std::os::unix::fs::symlink(&secret, model_dir.join("k.bin")).unwrap();
    let gltf_path = model_dir.join("m.gltf");
    let mut errors = Vec::new();
    for present in [true, false] {
        if present {
            std::fs::write(&secret, triangle_bin()).unwrap();
        } else {
            std::fs::remove_file(&secret).unwrap();
        }
        for uri in [
            "nonexistent/../k.bin",
            "nonexistent%2F..%2Fk.bin",
            "m.gltf/../k.bin",
        ] {
            std::fs::write(&gltf_path, gltf_with_buffer(uri)).unwrap();
            let path = gltf_path.clone();
            let e = quick(uri, move || gltf::load(path)).expect_err("must not read the link");
            assert!(!is_outside(&e), "{uri}: {e}");
            errors.push(e.to_string());
        }
    }
    assert_eq!(
        errors[..3],
        errors[3..],
        "the errors must not tell whether it exists"
    );
}

/// `..` after a link leaves the folder the link leads to, as the system does: `deep/..`, with
/// `deep` a link to `a/b`, is `a` (not the folder holding `deep`). So `deep/../m.gltf` loads
/// `a/m.gltf`, and `deep/../out.gltf` is outside when `a/out.gltf` links out, though
/// `out.gltf` beside `deep` is a plain model.
#[cfg(unix)]
#[test]
fn parent_after_a_link_leaves_the_links_target() {
    let t = tempfile::tempdir().unwrap();
    t.write("scene/a/b/keep", "");
    t.write("scene/a/real.bin", triangle_bin());
    t.write("scene/a/m.gltf", gltf_with_buffer("real.bin"));
    t.write("scene/out.gltf", gltf_with_buffer("data:,"));
    t.write("secret.gltf", gltf_with_buffer("data:,"));
    let scene_dir = t.path().join("scene");
    std::os::unix::fs::symlink("a/b", scene_dir.join("deep")).unwrap();
    std::os::unix::fs::symlink("../../secret.gltf", scene_dir.join("a/out.gltf")).unwrap();
    let scene = SceneDescription::from_json(&gltf_scene("deep/../m.gltf"), &scene_dir).unwrap();
    assert_eq!(scene.objects[0].mesh.triangle_count(), 1);
    let e = scene_err(&scene_dir, &gltf_scene("deep/../out.gltf"));
    assert!(is_outside(&e), "{e}");
    let e = scene_err(&scene_dir, &gltf_scene("deep/../../../secret.gltf"));
    assert!(is_outside(&e), "{e}");
}

/// Randomized (seeded; `VOLSHADOW_SEED=N` runs one): a temporary tree of folders, files and
/// symbolic links (relative and absolute, inside, outside, dangling, looping, through missing
/// components and files) beside an outside folder, and random paths over the tree's names,
/// `..`, `.` and missing names, resolved by `load::resolve_inside`. Every path it returns
/// stays inside (it is the folder, or its folder and, where it exists, it canonicalise inside); where it
/// exists it is the file the system reaches by the path as written, and where it does not the
/// system reaches none; and every file and folder of the tree is reached by its own relative
/// path, and, in trees whose links hold no `..`, every path the system leads to a file inside
/// the folder is resolved to that file. Broken variant: the resolution before this test (`..`
/// applied as written after a missing component) fails the first rule on seed 0.
#[cfg(unix)]
#[test]
fn random_paths_in_a_tree_of_links_stay_inside_and_reach_every_inside_file() {
    use std::os::unix::fs::symlink;
    use volshadow_harness::rng::{seeds, Rng};
    let mut checked = 0usize;
    for seed in seeds(0..48) {
        let mut rng = Rng::new(seed);
        let t = tempfile::tempdir().unwrap();
        let top = t.path().canonicalize().unwrap();
        let folder = top.join("in");
        std::fs::create_dir_all(top.join("out/odir")).unwrap();
        std::fs::write(top.join("out/secret"), "s").unwrap();
        std::fs::write(top.join("out/odir/ofile"), "o").unwrap();
        std::fs::create_dir_all(&folder).unwrap();
        let pick = |rng: &mut Rng, n: usize| (rng.next() * n as f64) as usize % n;
        // Folders d0..d3, each in an earlier one (or the folder); files f0..f3 in any.
        let mut dirs = vec![String::new()];
        for k in 0..4 {
            let parent = dirs[pick(&mut rng, dirs.len())].clone();
            let d = format!("{parent}d{k}/");
            std::fs::create_dir_all(folder.join(&d)).unwrap();
            dirs.push(d);
        }
        let mut entries: Vec<String> = dirs[1..]
            .iter()
            .map(|d| d.trim_end_matches('/').to_owned())
            .collect();
        for k in 0..4 {
            let f = format!("{}f{k}", dirs[pick(&mut rng, dirs.len())]);
            std::fs::write(folder.join(&f), "f").unwrap();
            entries.push(f);
        }
        let plain = rng.next() < 0.5; // links without `..`
        let names = [
            "d0", "d1", "d2", "d3", "f0", "f1", "f2", "f3", "l0", "l1", "l2", "l3", "l4", "l5",
            "missing", "secret", "odir", "ofile", "in", "out", ".", "..",
        ];
        let word = |rng: &mut Rng, plain: bool| loop {
            let w = names[pick(rng, names.len())];
            if !(plain && w == "..") {
                return w;
            }
        };
        let steps = |rng: &mut Rng, plain: bool, most: usize| {
            let n = 1 + pick(rng, most);
            (0..n)
                .map(|_| word(rng, plain))
                .collect::<Vec<_>>()
                .join("/")
        };
        for k in 0..6 {
            let at = format!("{}l{k}", dirs[pick(&mut rng, dirs.len())]);
            let target = match pick(&mut rng, 4) {
                0 => folder.join(steps(&mut rng, plain, 3)).display().to_string(),
                1 if !plain => top
                    .join("out")
                    .join(steps(&mut rng, plain, 2))
                    .display()
                    .to_string(),
                _ => steps(&mut rng, plain, 3),
            };
            symlink(&target, folder.join(&at)).unwrap();
        }
        let inside = |p: &Path| p.starts_with(&folder);
        macro_rules! fail {
            ($($what:tt)*) => { panic!("seed {seed}: {}", format_args!($($what)*)) };
        }
        for e in &entries {
            match volshadow::load::resolve_inside(&folder, Path::new(e)) {
                Ok(q) if q == folder.join(e) => {}
                other => fail!("{e} (in the tree) resolved to {other:?}"),
            }
        }
        for _ in 0..300 {
            let named = steps(&mut rng, false, 6);
            // The system's walk of the path as `Path` reads it (`.` components and a trailing
            // separator dropped, which the system would apply to a file as "not a directory").
            let os = std::fs::canonicalize(
                folder.join(
                    Path::new(&named)
                        .components()
                        .collect::<std::path::PathBuf>(),
                ),
            );
            let Ok(q) = volshadow::load::resolve_inside(&folder, Path::new(&named)) else {
                if plain && !named.split('/').any(|w| w == "..") {
                    if let Ok(c) = &os {
                        if inside(c) {
                            fail!("{named} leads to {} inside, refused", c.display());
                        }
                    }
                }
                continue;
            };
            checked += 1;
            let parent = q.parent().and_then(|p| p.canonicalize().ok());
            if q != folder && !parent.as_deref().is_some_and(inside) {
                fail!("{named} -> {}: its folder is not inside", q.display());
            }
            match (q.canonicalize(), &os) {
                (Ok(c), _) if !inside(&c) => fail!("{named} -> {} is outside", c.display()),
                (Ok(c), Ok(o)) if c == *o => {}
                (Err(_), Err(_)) => {}
                (c, o) => fail!(
                    "{named} -> {}: {c:?}, the system reaches {o:?}",
                    q.display()
                ),
            }
        }
    }
    println!("{checked} resolved random paths checked");
    assert!(
        checked > 1000,
        "only {checked} paths resolved: the trees test too little"
    );
}

/// A link that stays inside the folder, and `..` that comes back in, are fine.
#[cfg(unix)]
#[test]
fn paths_inside_the_folder_load() {
    let t = tempfile::tempdir().unwrap();
    t.write("scene/models/real.bin", triangle_bin());
    t.write("scene/models/m.gltf", gltf_with_buffer("link%20name.bin"));
    std::os::unix::fs::symlink("real.bin", t.path().join("scene/models/link name.bin")).unwrap();
    let text = gltf_scene("models/../models/./m.gltf");
    let scene = SceneDescription::from_json(&text, &t.path().join("scene")).unwrap();
    // One triangle from the 36-byte buffer read through the link.
    assert_eq!(scene.objects.len(), 1);
    assert_eq!(scene.objects[0].mesh.triangle_count(), 1);
}

/// `LoadOptions::allow_outside` lifts the rule.
#[test]
fn allow_outside_loads_an_outside_file() {
    let t = tempfile::tempdir().unwrap();
    t.write("secret.bin", triangle_bin());
    t.write("models/m.gltf", gltf_with_buffer("../secret.bin"));
    let text = gltf_scene("../models/m.gltf");
    let scene_dir = t.path().join("scene");
    std::fs::create_dir_all(&scene_dir).unwrap();
    assert!(is_outside(&scene_err(&scene_dir, &text)));
    let options = LoadOptions {
        allow_outside: true,
        ..LoadOptions::default()
    };
    let scene = SceneDescription::from_json_with(&text, &scene_dir, &options).unwrap();
    assert_eq!(scene.objects[0].mesh.triangle_count(), 1);
    // The glTF loader on its own, too.
    let path = t.path().join("models/m.gltf");
    assert!(is_outside(&gltf::load(&path).unwrap_err()));
    assert_eq!(gltf::load_with(&path, &options).unwrap().len(), 1);
}

// -------------------------------------------------------------------------------------------
// Only regular files
// -------------------------------------------------------------------------------------------

#[cfg(target_os = "linux")]
#[test]
fn dev_zero_is_not_read() {
    let options = LoadOptions {
        allow_outside: true,
        ..LoadOptions::default()
    };
    let e = quick("scene /dev/zero", || SceneDescription::load("/dev/zero")).unwrap_err();
    assert!(is_not_regular(&e), "{e}");
    let e = quick("glTF /dev/zero", || gltf::load("/dev/zero")).unwrap_err();
    assert!(is_not_regular(&e), "{e}");
    // As a buffer URI and a scene path, once going outside is allowed.
    let t = tempfile::tempdir().unwrap();
    let gltf_path = t.write("m.gltf", gltf_with_buffer("/dev/zero"));
    let e = quick("buffer /dev/zero", move || {
        gltf::load_with(gltf_path, &options)
    })
    .unwrap_err();
    assert!(is_not_regular(&e), "{e}");
    let folder = t.path().to_path_buf();
    let e = quick("scene path /dev/zero", move || {
        SceneDescription::from_json_with(&gltf_scene("/dev/zero"), &folder, &options)
    })
    .unwrap_err();
    assert!(is_not_regular(&e), "{e}");
}

/// A FIFO is never opened: nothing writes to it, so opening it would block forever.
#[cfg(unix)]
#[test]
fn fifo_is_not_opened() {
    let t = tempfile::tempdir().unwrap();
    let fifo = t.path().join("pipe");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .expect("mkfifo runs");
    assert!(made.success());
    let path = fifo.clone();
    let e = quick("scene FIFO", move || SceneDescription::load(path)).unwrap_err();
    assert!(is_not_regular(&e), "{e}");
    let path = fifo.clone();
    let e = quick("glTF FIFO", move || gltf::load(path)).unwrap_err();
    assert!(is_not_regular(&e), "{e}");
    let e = scene_err(t.path(), &gltf_scene("pipe"));
    assert!(is_not_regular(&e), "{e}");
    let gltf_path = t.write("m.gltf", gltf_with_buffer("pipe"));
    let e = quick("buffer FIFO", move || gltf::load(gltf_path)).unwrap_err();
    assert!(is_not_regular(&e), "{e}");
}

#[test]
fn directory_is_not_read() {
    let t = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(t.path().join("models")).unwrap();
    let e = scene_err(t.path(), &gltf_scene("models"));
    assert!(is_not_regular(&e), "{e}");
}

// -------------------------------------------------------------------------------------------
// Totals
// -------------------------------------------------------------------------------------------

#[test]
fn file_bytes_limit() {
    let t = tempfile::tempdir().unwrap();
    t.write("secret.bin", triangle_bin());
    let path = t.write("m.gltf", gltf_with_buffer("secret.bin"));
    let size = std::fs::metadata(&path).unwrap().len();
    // The glTF itself over the per-file bound.
    let small = LoadOptions {
        max_file_bytes: size - 1,
        ..LoadOptions::default()
    };
    let e = gltf::load_with(&path, &small).unwrap_err();
    assert_eq!(limit_of(&e), Some(Limit::FileBytes), "{e}");
    assert!(e.to_string().contains("max_file_bytes"), "{e}");
    // The glTF fits, the glTF plus its 36-byte buffer does not.
    let total = LoadOptions {
        max_total_bytes: size + 35,
        ..LoadOptions::default()
    };
    let e = gltf::load_with(&path, &total).unwrap_err();
    assert_eq!(limit_of(&e), Some(Limit::TotalBytes), "{e}");
    let exact = LoadOptions {
        max_total_bytes: size + 36,
        ..LoadOptions::default()
    };
    assert!(gltf::load_with(&path, &exact).is_ok());
}

/// The 2.1 KB scene of 20 spheres of 1024 × 1024 segments: 42M triangles (2.4 GB and 32 s
/// before any bound; then refused at the third sphere, after two were built: 12.5 s and
/// 409 MB). The declared total is checked before any shape is built: refused at once, naming
/// the whole total.
#[test]
fn triangle_limit_stops_a_small_scene_asking_for_42m_triangles_before_building_any() {
    let sphere = r#"{"shape": {"type": "sphere", "center": [0, 1, 0], "radius": 1, "segments": 1024, "rings": 1024}}"#;
    let text = scene(&format!("[{}]", vec![sphere; 20].join(",")), None);
    assert!(text.len() < 2600, "{} bytes", text.len());
    // Refused before any sphere is built: the error names the whole declared total (checked
    // below), where a bound met while building would name the running total at the third.
    let e = SceneDescription::from_json(&text, Path::new(".")).unwrap_err();
    match &e {
        Error::LimitExceeded {
            limit: Limit::Triangles,
            count,
            max,
            ..
        } => {
            assert_eq!(*max, LoadOptions::default().max_triangles);
            // The whole declared total: 20 spheres of 2 · 1024 · 1023 triangles.
            assert_eq!(*count, 20 * 2 * 1024 * 1023);
            assert!(e.to_string().contains("41902080"), "{e}");
        }
        e => panic!("expected the triangle limit, got {e}"),
    }
    // Out-of-range counts are the shape's own error, not a triangle total.
    let huge =
        r#"{"shape": {"type": "sphere", "center": [0, 1, 0], "radius": 1, "segments": 100000}}"#;
    let e = scene_err(Path::new("."), &scene(&format!("[{huge}]"), None));
    assert!(e.to_string().contains("objects[0].shape.segments"), "{e}");
}

#[test]
fn light_limit() {
    let light = r#"{"type": "point", "position": [0, 6, 0], "intensity": 10}"#;
    let text = scene("[]", Some(&format!("[{}]", vec![light; 17].join(","))));
    let e = SceneDescription::from_json(&text, Path::new(".")).unwrap_err();
    assert_eq!(limit_of(&e), Some(Limit::Lights), "{e}");
    assert!(e.to_string().contains("max_lights = 16"), "{e}");
    let text = scene("[]", Some(&format!("[{}]", vec![light; 16].join(","))));
    assert!(SceneDescription::from_json(&text, Path::new(".")).is_ok());
}

/// 20 stained-glass spot lights of 4096² (4 GB of texels; the process aborted before). The
/// default texel bound is one 4096² texture, so the second is refused before it is built.
#[test]
fn texel_limit_stops_twenty_4096_textures() {
    let light = r#"{"type": "spot", "position": [0, 6, 0], "direction": [0, -1, 0],
        "cone_angle_degrees": 50, "intensity": 40,
        "texture": {"stained_glass": {"size": 4096, "cells": 8, "seed": 7}}}"#;
    let text = scene("[]", Some(&format!("[{}]", vec![light; 20].join(","))));
    let options = LoadOptions {
        max_lights: 20,
        ..LoadOptions::default()
    };
    let e = SceneDescription::from_json_with(&text, Path::new("."), &options).unwrap_err();
    match e {
        Error::LimitExceeded {
            limit: Limit::Texels,
            count,
            max,
            ..
        } => {
            assert_eq!(max, 4096 * 4096);
            assert_eq!(count, 2 * 4096 * 4096);
        }
        e => panic!("expected the texel limit, got {e}"),
    }
}

/// A glb with one `n × n`-quad grid mesh (2n² triangles) placed by `nodes` nodes.
fn grid_glb(n: u32, nodes: usize) -> Vec<u8> {
    let mut bin = Vec::new();
    for z in 0..=n {
        for x in 0..=n {
            for c in [x as f32, 0.0, z as f32] {
                bin.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    let positions = bin.len();
    let v = |x: u32, z: u32| z * (n + 1) + x;
    for z in 0..n {
        for x in 0..n {
            for i in [
                v(x, z),
                v(x, z + 1),
                v(x + 1, z),
                v(x + 1, z),
                v(x, z + 1),
                v(x + 1, z + 1),
            ] {
                bin.extend_from_slice(&i.to_le_bytes());
            }
        }
    }
    let indices = bin.len() - positions;
    let node_list: Vec<String> = (0..nodes)
        .map(|i| format!(r#"{{"mesh": 0, "translation": [0, {i}, 0]}}"#))
        .collect();
    let json = format!(
        r#"{{"asset": {{"version": "2.0"}}, "nodes": [{}],
            "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1}}]}}],
            "accessors": [{{"bufferView": 0, "componentType": 5126, "count": {}, "type": "VEC3",
                            "min": [0, 0, 0], "max": [{n}, 0, {n}]}},
                          {{"bufferView": 1, "componentType": 5125, "count": {}, "type": "SCALAR"}}],
            "bufferViews": [{{"buffer": 0, "byteLength": {positions}}},
                            {{"buffer": 0, "byteOffset": {positions}, "byteLength": {indices}}}],
            "buffers": [{{"byteLength": {}}}]}}"#,
        node_list.join(","),
        (n + 1) * (n + 1),
        6 * n * n,
        bin.len()
    );
    glb(&json, &bin)
}

/// A 2.4 MB glb placing a 131k-triangle mesh through 1,000 nodes (131M triangles; the process
/// aborted before): refused after 32 placements, before the 33rd copy is made.
#[test]
fn triangle_limit_stops_a_mesh_placed_by_1000_nodes() {
    let bytes = grid_glb(256, 1000);
    assert!(bytes.len() > 2_000_000 && bytes.len() < 2_600_000);
    let e = gltf::load_slice(&bytes).unwrap_err();
    match e {
        Error::LimitExceeded {
            limit: Limit::Triangles,
            count,
            max,
            ..
        } => {
            let per_mesh = 2 * 256 * 256;
            assert_eq!(max, 4 << 20);
            // 4Mi / 131,072 = 32 placements fit exactly; the 33rd passes the bound.
            assert_eq!(count, 33 * per_mesh);
        }
        e => panic!("expected the triangle limit, got {e}"),
    }
}

#[test]
fn node_and_instance_limits() {
    let bytes = grid_glb(1, 100);
    let nodes = LoadOptions {
        max_nodes: 99,
        ..LoadOptions::default()
    };
    let e = gltf::load_slice_with(&bytes, &nodes).unwrap_err();
    assert_eq!(limit_of(&e), Some(Limit::Nodes), "{e}");
    let instances = LoadOptions {
        max_instances: 99,
        ..LoadOptions::default()
    };
    let e = gltf::load_slice_with(&bytes, &instances).unwrap_err();
    assert_eq!(limit_of(&e), Some(Limit::Instances), "{e}");
    assert_eq!(gltf::load_slice(&bytes).unwrap().len(), 100);
}
