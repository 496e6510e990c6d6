//! The examples as tests: `render` on every scene file and `gltf` on a box written here, run
//! through the same code the example binaries call (`volshadow_harness`), at 64×64.
//!
//! The GPU's in-scatter with each scene's own (hybrid) method is compared with the f64
//! reference on the same scene and size: RMSE over all pixels and channels at most 2% of the
//! reference's mean (issue 5). Each scene's shadows must also be visible in its tone-mapped
//! PNG: it differs from the same scene rendered without occluder shadows over at least 5% of
//! the image; and a scene with a light of some radius must show its penumbrae: its PNG differs
//! by the same measure from the scene drawn hard (every radius 0).

use std::path::{Path, PathBuf};
use std::time::Instant;

use volshadow_harness::cli::{self, Parsed};
use volshadow_harness::files::{assert_refused, snapshot};
use volshadow_harness::render_scene::{self, RenderMethod};
use volshadow_harness::visibility::{
    visible_fraction, MIN_LEVELS, MIN_PIXEL_CHANGE, MIN_VISIBLE_FRACTION,
};
use volshadow_harness::{app, metric, scene_files};

/// Test image size: keeps the f64 reference (O(triangles) per ray) fast.
const SIZE: u32 = 64;
/// Issue 5: in-scatter RMSE against the reference, relative to the reference's mean.
const MAX_RMSE: f64 = 0.02;

fn args(list: &[&str]) -> Vec<String> {
    list.iter().map(|s| s.to_string()).collect()
}

/// Reads an EXR's RGB, checking its size and that every value is finite.
fn read_exr(path: &Path) -> Vec<[f32; 3]> {
    let image = image::open(path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()))
        .into_rgb32f();
    assert_eq!(image.dimensions(), (SIZE, SIZE), "{}", path.display());
    let pixels: Vec<[f32; 3]> = image.pixels().map(|p| p.0).collect();
    assert!(
        pixels.iter().flatten().all(|v| v.is_finite()),
        "{} has non-finite values",
        path.display()
    );
    pixels
}

/// Checks the five files of one render and returns its in-scatter.
fn check_outputs(rendered: &render_scene::Rendered) -> Vec<[f32; 3]> {
    let [radiance, png, inscatter, depth, json] = &rendered.files;
    for file in &rendered.files {
        assert!(file.is_file(), "{} was not written", file.display());
    }
    let radiance = read_exr(radiance);
    assert!(
        radiance.iter().flatten().all(|v| *v >= 0.0),
        "negative radiance"
    );
    let png = image::open(png).unwrap();
    assert_eq!((png.width(), png.height()), (SIZE, SIZE));
    let depth = read_exr(depth);
    assert!(depth
        .iter()
        .all(|d| d[0] > 0.0 && d[0] <= app::SKY_DISTANCE));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap();
    // What the example returned is what it wrote (floats may differ in the last digit).
    for key in ["scene", "method", "adapter", "plan", "size", "files"] {
        assert_eq!(report[key], rendered.report[key], "{key}");
    }
    assert_eq!(report["size"], serde_json::json!([SIZE, SIZE]));
    assert!(report["plan"].as_array().is_some_and(|p| !p.is_empty()));
    assert!(report["wall_ms"]
        .as_f64()
        .is_some_and(|t| t.is_finite() && t >= 0.0));
    for key in ["scene", "method", "adapter"] {
        assert!(report[key].is_string(), "report lacks {key}");
    }
    let inscatter = read_exr(inscatter);
    assert!(
        inscatter.iter().flatten().all(|v| *v >= 0.0),
        "negative in-scatter"
    );
    inscatter
}

/// RMSE of `test` against `reference` over all pixels and channels but those in `skip`,
/// relative to the reference's mean over all pixels.
fn relative_rmse(test: &[[f32; 3]], reference: &[[f32; 3]], skip: &[usize]) -> f64 {
    let (mut sq, mut sum) = (0.0, 0.0);
    for (i, (t, r)) in test.iter().zip(reference).enumerate() {
        for c in 0..3 {
            sum += f64::from(r[c]);
            if skip.contains(&i) {
                continue;
            }
            sq += (f64::from(t[c]) - f64::from(r[c])).powi(2);
        }
    }
    let n = 3.0 * reference.len() as f64;
    (sq / n).sqrt() / (sum / n)
}

/// The pixels (at `SIZE`²) that contain a light of the scene.
fn light_pixels(scene: &Path) -> Vec<usize> {
    let description = volshadow::scene_file::SceneDescription::load(scene).unwrap();
    let camera = app::with_aspect(&description.camera, 1.0).unwrap();
    let clip_from_world = camera.projection() * camera.view();
    description
        .lights
        .iter()
        .filter_map(|l| {
            let clip = clip_from_world * l.light.position()?.extend(1.0);
            let (x, y) = (clip.x / clip.w, clip.y / clip.w);
            let px = ((x + 1.0) * 0.5 * SIZE as f32).floor();
            let py = ((1.0 - y) * 0.5 * SIZE as f32).floor();
            let inside = clip.w > 0.0
                && (0.0..SIZE as f32).contains(&px)
                && (0.0..SIZE as f32).contains(&py);
            inside.then(|| py as usize * SIZE as usize + px as usize)
        })
        .collect()
}

/// Prints and records how much of `stem`'s PNG its `what` (shadows, penumbrae) change against
/// `against`, and adds a failure below [`MIN_VISIBLE_FRACTION`].
fn judge_visible(stem: &str, what: &str, against: &str, fraction: f64, failures: &mut Vec<String>) {
    println!(
        "{stem:<14} {what} visible: {:.1}% of the PNG differs from {against} by >= {:.0}% of the \
         pixel value (at least {MIN_LEVELS} levels); required {:.0}%",
        100.0 * fraction,
        100.0 * MIN_PIXEL_CHANGE,
        100.0 * MIN_VISIBLE_FRACTION
    );
    metric::accuracy(
        &format!(
            "{stem}: {what} visible in the tone-mapped PNG (pixels ≥ {:.0}% and {MIN_LEVELS} \
             levels off {against})",
            100.0 * MIN_PIXEL_CHANGE
        ),
        format!("{:.1}%", 100.0 * fraction),
        format!("≥ {:.0}%", 100.0 * MIN_VISIBLE_FRACTION),
    );
    if fraction.is_nan() || fraction < MIN_VISIBLE_FRACTION {
        failures.push(format!(
            "{stem}: {what} visible over {:.1}% of the image < {:.0}%",
            100.0 * fraction,
            100.0 * MIN_VISIBLE_FRACTION
        ));
    }
}

/// One scene of [`render_every_scene_and_match_the_reference`]: its failures.
fn check_scene(scene: &Path, dir: &Path, size: &str) -> Vec<String> {
    let mut failures = Vec::new();
    let size = size.to_owned();
    let stem = scene.file_stem().unwrap().to_string_lossy().into_owned();
    let scene_arg = scene.to_str().unwrap();
    let start = Instant::now();
    let out = dir.join(&stem);
    let gpu = render_scene::run(&args(&[
        scene_arg,
        "-o",
        out.to_str().unwrap(),
        "--size",
        &size,
    ]))
    .unwrap_or_else(|e| panic!("{stem}: {e}"));
    let gpu_time = start.elapsed().as_secs_f64();
    let gpu_inscatter = check_outputs(&gpu);
    let method = gpu.report["method"].as_str().unwrap().to_owned();

    // The same scene without occluder shadows (`--method analytic` passes no occluders;
    // the app's frame is the same), tone-mapped with the shadowed render's exposure.
    let exposure = gpu.report["exposure"].as_f64().unwrap().to_string();
    let out = dir.join(format!("{stem}.unshadowed"));
    let unshadowed = render_scene::run(&args(&[
        scene_arg,
        "-o",
        out.to_str().unwrap(),
        "--size",
        &size,
        "--method",
        "analytic",
        "--exposure",
        &exposure,
    ]))
    .unwrap_or_else(|e| panic!("{stem} unshadowed: {e}"));
    let visible = visible_fraction(&gpu.files[1], &unshadowed.files[1]);
    judge_visible(
        &stem,
        "shadows",
        "the unshadowed render",
        visible,
        &mut failures,
    );

    // A light with a radius: its penumbrae must show too. The same scene with every
    // radius 0 (hard shadows), tone-mapped with the soft render's exposure, must differ by
    // the same measure.
    let mut hard_scene: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(scene).unwrap()).unwrap();
    let mut soft = false;
    for light in hard_scene["lights"].as_array_mut().into_iter().flatten() {
        if light
            .get("radius")
            .and_then(|r| r.as_f64())
            .is_some_and(|r| r > 0.0)
        {
            light["radius"] = serde_json::json!(0.0);
            soft = true;
        }
    }
    if soft {
        let hard_file = dir.join(format!("{stem}.hard-scene.json"));
        std::fs::write(&hard_file, hard_scene.to_string()).unwrap();
        let out = dir.join(format!("{stem}.hard"));
        let hard = render_scene::run(&args(&[
            hard_file.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--size",
            &size,
            "--exposure",
            &exposure,
        ]))
        .unwrap_or_else(|e| panic!("{stem} hard: {e}"));
        let penumbra = visible_fraction(&gpu.files[1], &hard.files[1]);
        judge_visible(
            &stem,
            "penumbrae",
            "the scene drawn hard",
            penumbra,
            &mut failures,
        );
    }

    let start = Instant::now();
    let out = dir.join(format!("{stem}.reference"));
    let reference = render_scene::run(&args(&[
        scene_arg,
        "-o",
        out.to_str().unwrap(),
        "--size",
        &size,
        "--method",
        "reference",
    ]))
    .unwrap_or_else(|e| panic!("{stem} reference: {e}"));
    let reference_time = start.elapsed().as_secs_f64();
    let reference_inscatter = check_outputs(&reference);

    let with_lights = relative_rmse(&gpu_inscatter, &reference_inscatter, &[]);
    // As in every GPU test: without the pixels that hold a light, where the GPU clamps the
    // singular 1/h by the pixel footprint on purpose while the reference integrates the one
    // ray through the pixel centre (README, "Accuracy"). Both are printed.
    let rmse = relative_rmse(&gpu_inscatter, &reference_inscatter, &light_pixels(scene));
    println!(
        "{stem:<14} {method:<36} in-scatter RMSE {:.2}% of the reference mean \
         without the lights' own pixels ({:.2}% with them); GPU run {gpu_time:.1} s, \
         reference run {reference_time:.1} s",
        100.0 * rmse,
        100.0 * with_lights
    );
    metric::accuracy(
        &format!("{stem}: `render` ({method}) against `--method reference`"),
        format!("RMSE {:.2}%", 100.0 * rmse),
        format!("RMSE {}%", 100.0 * MAX_RMSE),
    );
    if rmse.is_nan() || rmse > MAX_RMSE {
        failures.push(format!("{stem}: RMSE {rmse:.4} > {MAX_RMSE}"));
    }
    failures
}

/// Every standard scene through `render`, against its reference. The scenes run on as many
/// threads as the machine has (each render compiles its own pipelines, on one thread).
#[test]
fn render_every_scene_and_match_the_reference() {
    let dir = tempfile::tempdir().unwrap();
    let size = format!("{SIZE}x{SIZE}");
    let scenes = scene_files();
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let next = std::sync::atomic::AtomicUsize::new(0);
    // Named as this test, which the metric lines name (`metric::this_test`).
    let name = std::thread::current().name().map(str::to_owned);
    let failures: Vec<String> = std::thread::scope(|s| {
        let workers: Vec<_> = (0..threads.min(scenes.len()))
            .map(|_| {
                let mut builder = std::thread::Builder::new();
                if let Some(name) = &name {
                    builder = builder.name(name.clone());
                }
                builder
                    .spawn_scoped(s, || {
                        let mut failures = Vec::new();
                        loop {
                            let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                            let Some(scene) = scenes.get(i) else {
                                return failures;
                            };
                            failures.extend(check_scene(scene, dir.path(), &size));
                        }
                    })
                    .unwrap()
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().unwrap())
            .collect()
    });
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn render_parses_every_method() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/sphere.json");
    let dir = tempfile::tempdir().unwrap();
    for method in [
        "analytic",
        "brute:16",
        "hybrid:16:2:separable:2",
        "hybrid:8:4:bilinear",
    ] {
        let out = dir.path().join(method.replace(':', "_"));
        let rendered = render_scene::run(&args(&[
            scene.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--size",
            &format!("{SIZE}x{SIZE}"),
            "--method",
            method,
        ]))
        .unwrap_or_else(|e| panic!("{method}: {e}"));
        check_outputs(&rendered);
        let parsed = RenderMethod::parse(method).unwrap();
        assert_eq!(RenderMethod::parse(&parsed.describe()).unwrap(), parsed);
        assert_eq!(rendered.report["method"], parsed.describe());
    }
}

/// `render --surface-scatter` on the lamp-and-wall scene: `OUT.surface.exr` is finite and
/// non-negative, zero on sky, positive on the surfaces near the lamp, and it is exactly what
/// the term adds: `OUT.exr` minus the same render without the option, within f32 rounding
/// (1e-5 of the largest radiance). Without the surfaces passed (or the term not added) the
/// difference is zero and the test fails on the positive-pixel count.
#[test]
fn render_surface_scatter_writes_the_added_radiance() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/lamp_wall.json");
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, extra: &[&str]| {
        let out = dir.path().join(name);
        let mut list = vec![
            scene.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--size",
            "64x64",
            "--method",
            "analytic",
        ];
        list.extend(extra);
        render_scene::run(&args(&list)).unwrap();
        out
    };
    let with = run("with", &["--surface-scatter"]);
    let without = run("without", &[]);
    let path = |out: &Path, suffix: &str| {
        let mut s = out.as_os_str().to_owned();
        s.push(suffix);
        PathBuf::from(s)
    };
    let surface = read_exr(&path(&with, ".surface.exr"));
    let (a, b) = (
        read_exr(&path(&with, ".exr")),
        read_exr(&path(&without, ".exr")),
    );
    let depth = read_exr(&path(&with, ".depth.exr"));
    let sky = |k: usize| depth[k][0] >= app::SKY_DISTANCE;
    let max = a.iter().flatten().fold(0.0f32, |m, &v| m.max(v));
    let mut worst = 0.0f32;
    let mut positive = 0;
    for k in 0..surface.len() {
        for c in 0..3 {
            assert!(surface[k][c] >= 0.0, "pixel {k}: {:?}", surface[k]);
            if sky(k) {
                assert_eq!(surface[k][c], 0.0, "sky pixel {k}");
            }
            worst = worst.max((a[k][c] - b[k][c] - surface[k][c]).abs());
        }
        positive += usize::from(surface[k][0] > 1e-3 * max);
    }
    println!(
        "surface term above 1e-3 of the max in {positive} pixels; difference off by {worst:e}"
    );
    assert!(worst <= 1e-5 * max, "{worst:e}");
    assert!(
        positive > surface.len() / 4,
        "{positive} pixels gain the term"
    );
}

#[test]
fn render_rejects_bad_arguments_and_files() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/sphere.json");
    let scene = scene.to_str().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let bad_json = dir.path().join("bad.json");
    std::fs::write(&bad_json, "{\"name\": 3}").unwrap();
    for bad in [
        vec![],
        vec!["no/such/scene.json"],
        vec![bad_json.to_str().unwrap()],
        vec![scene, "--method", "fast"],
        vec![scene, "--method", "hybrid:0"],
        vec![scene, "--method", "hybrid:64:3"],
        vec![scene, "--method", "hybrid:64:2:separable,4,1,1"],
        vec![scene, "--size", "0x64"],
        vec![scene, "--size", "64"],
        vec![scene, "--bogus"],
        vec![scene, "-o"],
        vec![scene, "--method", "reference", "--surface-scatter"],
    ] {
        let result = render_scene::run(&args(&bad));
        assert!(result.is_err(), "{bad:?} should be an error");
        println!("{bad:?}: {}", result.err().unwrap());
    }
}

/// `render` never writes over its input: an output path naming the scene file (`-o` with its
/// stem, with its extension, through `.` or `..`, through a symbolic link to the file or to
/// its folder, or a hard link: the same file under another name) is refused before anything
/// is written, and every file in the folder keeps its bytes. Without `-o` the outputs go to `out/STEM`,
/// not beside the input. No GPU: the refusal comes first.
#[test]
fn render_never_overwrites_its_input() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("lamp.json");
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/lamp_wall.json"),
        &scene,
    )
    .unwrap();
    let d = dir.path().to_str().unwrap();
    std::fs::create_dir(dir.path().join("sub")).unwrap();
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(&scene, dir.path().join("alias.json")).unwrap();
        std::os::unix::fs::symlink(dir.path(), dir.path().join("here")).unwrap();
        std::fs::hard_link(&scene, dir.path().join("hard.json")).unwrap();
    }
    let before = snapshot(dir.path());
    let mut cases = vec![
        format!("{d}/lamp"),
        format!("{d}/lamp.json"),
        format!("{d}/./lamp"),
        format!("{d}/sub/../lamp"),
        // Through folders the run would create: `..` goes back from the new folder to the
        // scene's (the check gave up on a missing folder, and the run wrote the report over
        // the scene).
        format!("{d}/newdir/../lamp"),
        format!("{d}/new/er/../../lamp.json"),
    ];
    if cfg!(unix) {
        // A link to the file, a link to its folder, a second name of the same file.
        cases.extend([
            format!("{d}/alias"),
            format!("{d}/here/lamp"),
            format!("{d}/hard"),
        ]);
    }
    for out in &cases {
        let result = render_scene::run(&args(&[
            scene.to_str().unwrap(),
            "-o",
            out,
            "--size",
            "16x16",
        ]));
        assert_refused(result, "lamp.json", dir.path(), &before, out);
    }
    // The outputs' default: `out/STEM`, whatever folder the scene is in.
    let Parsed::Run(options) =
        render_scene::Options::parse(&args(&[scene.to_str().unwrap()])).unwrap()
    else {
        panic!("not a run")
    };
    assert_eq!(options.out, Path::new(cli::OUT_DIR).join("lamp"));
    for output in options.outputs() {
        assert!(output.starts_with(cli::OUT_DIR), "{}", output.display());
    }
}

/// A file the scene names (a spot light's texture `glass.png`) is an input too: `-o glass`
/// would write `glass.png` over it.
#[cfg(feature = "image")]
#[test]
fn render_never_overwrites_a_file_the_scene_names() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/stained_glass.json"),
    )
    .unwrap();
    let text = text.replace(
        r#""texture": { "stained_glass": { "size": 256, "cells": 8, "seed": 2024 } }"#,
        r#""texture": { "file": "glass.png" }"#,
    );
    assert!(text.contains("glass.png"), "the scene's texture line moved");
    let scene = dir.path().join("spot.json");
    std::fs::write(&scene, text).unwrap();
    image::RgbImage::from_fn(8, 8, |x, y| {
        image::Rgb([(x * 30) as u8, (y * 30) as u8, 200])
    })
    .save(dir.path().join("glass.png"))
    .unwrap();
    // A valid scene that reads the texture.
    volshadow::scene_file::SceneDescription::load(&scene).unwrap();
    let before = snapshot(dir.path());
    for out in ["glass", "nd/../glass"] {
        let out = dir.path().join(out);
        let result = render_scene::run(&args(&[
            scene.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--size",
            "16x16",
        ]));
        assert_refused(
            result,
            "glass.png",
            dir.path(),
            &before,
            &out.display().to_string(),
        );
    }
}

/// `-o` naming a folder (`sub/`, `.`, `..`) is an error of the parser, not the hidden files
/// `sub/.png`, `sub/.exr` and `sub/.json` (for `gltf` too); `-o sub` (a folder's name without
/// the separator) is the base `sub`, whose outputs are `sub.png` and so on beside it.
#[test]
fn output_naming_a_folder_is_refused() {
    use volshadow_harness::gltf_scene;
    for out in ["sub/", "out/sub/", ".", "..", "sub/.", "/"] {
        let line = args(&["scenes/sphere.json", "-o", out]);
        let e = render_scene::Options::parse(&line).expect_err(out);
        assert!(e.to_string().contains("names a folder"), "{out}: {e}");
        let line = args(&["model.glb", "-o", out]);
        let e = gltf_scene::Options::parse(&line).expect_err(out);
        assert!(e.to_string().contains("names a folder"), "{out}: {e}");
    }
    let line = args(&["scenes/sphere.json", "-o", "sub"]);
    let Parsed::Run(options) = render_scene::Options::parse(&line).unwrap() else {
        panic!("not a run")
    };
    assert_eq!(options.path(".png"), Path::new("sub.png"));
}

/// A FIFO as the scene or the model is an error at once, not a run blocked forever on
/// opening it (the tools looked for the files it names by opening it first).
#[cfg(unix)]
#[test]
fn fifo_input_is_an_error_not_a_hang() {
    use volshadow_harness::gltf_scene;
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("pipe.json");
    assert!(std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .expect("mkfifo runs")
        .success());
    let out = dir.path().join("o").display().to_string();
    let (send, receive) = std::sync::mpsc::channel();
    let (scene, model) = (fifo.display().to_string(), fifo.display().to_string());
    std::thread::spawn(move || {
        let render = render_scene::run(&args(&[&scene, "-o", &out])).map_err(|e| e.to_string());
        let gltf = gltf_scene::run(&args(&[&model, "-o", &out])).map_err(|e| e.to_string());
        let _ = send.send((render.err(), gltf.err()));
    });
    // Hang guard, not a speed bound: both answer from metadata in milliseconds.
    let (render, gltf) = receive
        .recv_timeout(std::time::Duration::from_secs(120))
        .expect("render or gltf blocked on a FIFO input");
    for (tool, e) in [("render", render), ("gltf", gltf)] {
        let e = e.unwrap_or_else(|| panic!("{tool} ran on a FIFO"));
        assert!(e.contains("not a regular file"), "{tool}: {e}");
    }
}

/// `--help` and `-h` are a request for the usage, not an error, for every example's parser,
/// whatever else is on the line; and `render`'s help lists every method its parser accepts
/// (both come from `METHODS`). The tools' parsers: `tools/tests/tools/help.rs`.
#[test]
fn every_example_answers_help() {
    for flag in ["--help", "-h"] {
        let scene = "scenes/sphere.json";
        for line in [
            vec![flag],
            vec![scene, flag],
            vec![scene, "--method", "bogus", flag],
        ] {
            let line = args(&line);
            assert!(
                render_scene::Options::parse(&line).unwrap().is_help(),
                "render {line:?}"
            );
            #[cfg(feature = "gltf")]
            assert!(
                volshadow_harness::gltf_scene::Options::parse(&line)
                    .unwrap()
                    .is_help(),
                "gltf {line:?}"
            );
        }
        let line = args(&[flag]);
        assert!(cli::parse_quickstart(&line).unwrap().is_help());
        assert!(cli::parse_interactive(&line).unwrap().is_help());
    }
    // Without --help, the same parsers run (or refuse) as before.
    assert!(!render_scene::Options::parse(&args(&["s.json"]))
        .unwrap()
        .is_help());
    assert!(render_scene::Options::parse(&args(&["--bogus"])).is_err());
    assert!(cli::parse_interactive(&args(&["--bogus"])).is_err());
    assert_eq!(cli::parse_interactive(&[]).unwrap(), Parsed::Run(()));

    let help = render_scene::help();
    for m in &render_scene::METHODS {
        assert!(
            help.contains(&m.syntax()),
            "{} missing from:\n{help}",
            m.syntax()
        );
        for name in std::iter::once(&m.name).chain(m.aliases) {
            RenderMethod::parse(name).unwrap_or_else(|e| panic!("{name}: {e}"));
        }
    }
    for method in ["exact", "exact:2:separable:16", "textbook:32:4"] {
        RenderMethod::parse(method).unwrap_or_else(|e| panic!("{method}: {e}"));
    }
    let unknown = RenderMethod::parse("fast").unwrap_err().to_string();
    for m in &render_scene::METHODS {
        assert!(unknown.contains(m.name), "{unknown}");
    }
    assert!(RenderMethod::parse("textbook:32:4:1").is_err());
    // The interactive keys: each listed key does what it says, every action has a key.
    let keys = cli::keys_help();
    for (key, name, action, _) in cli::KEYS {
        assert_eq!(cli::action_of(key), Some(action));
        assert!(keys.contains(name) && cli::interactive_help().contains(name));
    }
    assert!(
        keys.contains("exact -> hybrid -> brute force -> textbook"),
        "{keys}"
    );
}

/// The small examples' options: quickstart writes to `out/quickstart.png` unless told
/// otherwise (one PNG path). uniform_probe's: `tools/tests/tools/help.rs`.
#[test]
fn small_examples_parse_their_options() {
    let run = |list: &[&str]| match cli::parse_quickstart(&args(list)).unwrap() {
        Parsed::Run(o) => o.output,
        Parsed::Help => panic!("help"),
    };
    assert_eq!(run(&[]), Path::new(cli::OUT_DIR).join("quickstart.png"));
    assert_eq!(run(&["a/b.png"]), Path::new("a/b.png"));
    assert_eq!(run(&["-o", "c.PNG"]), Path::new("c.PNG"));
    for bad in [
        &["a.png", "b.png"][..],
        &["-o", "x.jpg"],
        &["--bogus"],
        &["-o"],
    ] {
        assert!(cli::parse_quickstart(&args(bad)).is_err(), "{bad:?}");
    }
}

/// A box of half extents (1, 0.5, 0.75) as a binary glTF, placed 1.5 above the origin.
#[cfg(feature = "gltf")]
fn box_glb() -> Vec<u8> {
    let positions: Vec<[f32; 3]> = (0..8)
        .map(|i| {
            let c = |bit: u32, h: f32| if i & (1 << bit) != 0 { h } else { -h };
            [c(0, 1.0), c(1, 0.5), c(2, 0.75)]
        })
        .collect();
    const INDICES: [u16; 36] = [
        0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6,
        1, 3, 5, 3, 7, 5,
    ];
    let mut bin: Vec<u8> = positions
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    bin.extend(INDICES.iter().flat_map(|i| i.to_le_bytes()));
    let json = r#"{"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "Box", "mesh": 0, "translation": [0, 1.5, 0]}],
        "meshes": [{"name": "Box", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [{"byteLength": 168}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 96},
                        {"buffer": 0, "byteOffset": 96, "byteLength": 72}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3",
                       "min": [-1, -0.5, -0.75], "max": [1, 0.5, 0.75]},
                      {"bufferView": 1, "componentType": 5123, "count": 36, "type": "SCALAR"}]}"#;
    volshadow_harness::files::glb(json, &bin)
}

#[cfg(feature = "gltf")]
#[test]
fn gltf_renders_a_box() {
    use volshadow_harness::gltf_scene;

    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("box.glb");
    std::fs::write(&model, box_glb()).unwrap();
    let png = dir.path().join("box.png");
    let rendered = gltf_scene::run(&args(&[
        model.to_str().unwrap(),
        "-o",
        png.to_str().unwrap(),
        "--size",
        &format!("{SIZE}x{SIZE}"),
    ]))
    .unwrap();
    let image = image::open(&png).unwrap();
    assert_eq!((image.width(), image.height()), (SIZE, SIZE));
    assert_eq!(rendered.png, png);
    assert_eq!(rendered.inscatter.len(), (SIZE * SIZE) as usize);
    // The in-scatter EXR beside the PNG holds what the run returned (f32 of the f64 sums).
    assert_eq!(rendered.inscatter_exr, dir.path().join("box.inscatter.exr"));
    let exr = read_exr(&rendered.inscatter_exr);
    for (e, r) in exr.iter().zip(&rendered.inscatter) {
        assert_eq!(*e, r.as_vec3().to_array());
    }
    // The box is closed: 12 triangles, no boundary or non-manifold edge, tight extents.
    assert_eq!(rendered.summaries.len(), 1);
    let summary = &rendered.summaries[0];
    println!("{summary}");
    assert!(
        summary.contains("\"Box\": 12 triangles, closed, 0 boundary and 0 non-manifold edges")
            && summary.contains("tight"),
        "{summary}"
    );
    assert!(rendered
        .inscatter
        .iter()
        .all(|v| v.is_finite() && v.min_element() >= 0.0));
    assert!(rendered.radiance.iter().all(|v| v.is_finite()));
    assert!(
        rendered.inscatter.iter().any(|v| v.max_element() > 0.0),
        "no in-scatter at all"
    );
    // The box is an occluder: its shadow volume's extents are rasterised every frame.
    let plan = &rendered.stats.plan;
    assert!(
        plan.iter()
            .any(|l| l.contains("run") && l.contains("extents")),
        "{plan:?}"
    );

    assert!(gltf_scene::run(&args(&[dir.path().join("missing.glb").to_str().unwrap()])).is_err());
    assert!(
        gltf_scene::run(&args(&[png.to_str().unwrap()])).is_err(),
        "a PNG is not a glTF"
    );
}

/// `gltf` never writes over its input: a model whose own name an output takes (`-o` naming
/// `box.png` when the model is a GLB called `box.png`) or an image the model names (`tex.png`
/// of a `.gltf`) is refused before anything is written; without `-o` the outputs go to
/// `out/STEM`.
#[cfg(feature = "gltf")]
#[test]
fn gltf_never_overwrites_its_input() {
    use volshadow_harness::gltf_scene;
    let dir = tempfile::tempdir().unwrap();
    // A GLB under a PNG's name: `-o box` would write box.png over it.
    let glb = dir.path().join("box.png");
    std::fs::write(&glb, box_glb()).unwrap();
    // A .gltf whose buffer and image are files beside it: `-o tex` would write tex.png.
    let bytes = box_glb();
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let bin = &bytes[28 + json_len..];
    std::fs::write(dir.path().join("box data.bin"), bin).unwrap();
    std::fs::write(dir.path().join("tex.png"), b"an image").unwrap();
    let json: String = String::from_utf8(bytes[20..20 + json_len].to_vec()).unwrap();
    let json = json.replace(
        r#""buffers": [{"byteLength": 168}]"#,
        r#""buffers": [{"byteLength": 168, "uri": "box%20data.bin"}],
        "images": [{"uri": "tex.png"}]"#,
    );
    assert!(json.contains("tex.png"));
    let gltf = dir.path().join("model.gltf");
    std::fs::write(&gltf, json).unwrap();
    // Both are models the loader reads.
    volshadow::gltf::load(&glb).unwrap();
    volshadow::gltf::load(&gltf).unwrap();
    let before = snapshot(dir.path());
    let d = dir.path().to_str().unwrap();
    for (model, out, input) in [
        (&glb, format!("{d}/box"), "box.png"),
        (&glb, format!("{d}/./box.png"), "box.png"),
        (&gltf, format!("{d}/tex"), "tex.png"),
        (&gltf, format!("{d}/nd/../tex"), "tex.png"),
        (&glb, format!("{d}/nd/../box"), "box.png"),
    ] {
        let result = gltf_scene::run(&args(&[
            model.to_str().unwrap(),
            "-o",
            &out,
            "--size",
            "16x16",
        ]));
        assert_refused(result, input, dir.path(), &before, &out);
    }
    let Parsed::Run(options) = gltf_scene::Options::parse(&args(&[glb.to_str().unwrap()])).unwrap()
    else {
        panic!("not a run")
    };
    assert_eq!(options.out, Path::new(cli::OUT_DIR).join("box"));
}

/// The child of [`headless_runs_print_no_error_lines`]: what `render`'s `main` does, on the
/// sphere scene at 32×32. Ignored in a normal run; the parent runs it in a fresh process.
#[test]
#[ignore = "run in a child process by headless_runs_print_no_error_lines"]
fn headless_child_render() {
    volshadow_harness::headless_env::quiet_display_probe();
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/sphere.json");
    let dir = tempfile::tempdir().unwrap();
    render_scene::run(&args(&[
        scene.to_str().unwrap(),
        "-o",
        dir.path().join("sphere").to_str().unwrap(),
        "--size",
        "32x32",
    ]))
    .unwrap();
}

/// A run on a machine without a desktop session prints no line starting with `error:` unless
/// something failed: Mesa's Vulkan device-selection layer used to make libwayland print
/// `error: XDG_RUNTIME_DIR is invalid or not set in the environment.` twice per run
/// (`volshadow_harness::headless_env`). The render runs in a child process, since the message
/// is written by C code straight to the process's standard error.
#[test]
fn headless_runs_print_no_error_lines() {
    // The child's path in this binary: this file's module, then the test's name.
    let module = module_path!().split_once("::").map_or("", |(_, m)| m);
    let child = format!("{module}::headless_child_render")
        .trim_start_matches("::")
        .to_string();
    let output = std::process::Command::new(std::env::current_exe().unwrap())
        .args([
            child.as_str(),
            "--exact",
            "--ignored",
            "--nocapture",
            "--test-threads=1",
        ])
        // A headless machine: no session, no display, no device choice by the user.
        .env_remove("XDG_RUNTIME_DIR")
        .env_remove("WAYLAND_DISPLAY")
        .env_remove("DISPLAY")
        .env_remove("NODEVICE_SELECT")
        .env_remove("MESA_VK_DEVICE_SELECT")
        .output()
        .unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(output.status.success(), "the child render failed:\n{text}");
    assert!(
        text.contains("1 passed"),
        "the child ran no render:\n{text}"
    );
    let errors: Vec<&str> = text.lines().filter(|l| l.starts_with("error:")).collect();
    println!("lines starting with \"error:\": {errors:?}");
    // Nothing failed, so not one line may read as a failure.
    assert!(errors.is_empty(), "{errors:?}\n{text}");
}

/// An open mesh (a box without its top face) and one with a non-manifold edge are reported
/// as such, with conservative extents.
#[cfg(feature = "gltf")]
#[test]
fn gltf_mesh_report_says_open_and_non_manifold() {
    use volshadow::glam::{Mat4, Vec3};
    use volshadow::scene::Mesh;
    use volshadow_harness::gltf_scene::mesh_report;
    let corners: Vec<Vec3> = (0..8)
        .map(|i| Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32))
        .collect();
    // The closed box of `box_glb` less its +y face (triangles 3 and 4 of 6 faces · 2).
    const BOX: [u32; 36] = [
        0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6,
        1, 3, 5, 3, 7, 5,
    ];
    let open: Vec<u32> = BOX[..18].iter().chain(&BOX[24..]).copied().collect();
    // Three triangles sharing the edge 0-1: non-manifold.
    let fan = [0, 1, 2, 1, 0, 4, 0, 1, 6];
    for (indices, expected) in [
        (
            &open[..],
            "10 triangles, open, 4 boundary and 0 non-manifold edges",
        ),
        (
            &fan[..],
            "3 triangles, open, 6 boundary and 1 non-manifold edges",
        ),
    ] {
        let mesh = volshadow::gltf::GltfMesh {
            name: Some("m".into()),
            mesh: Mesh::new(&corners, indices).unwrap(),
            transform: Mat4::IDENTITY,
        };
        let line = mesh_report(0, &mesh);
        println!("{line}");
        assert!(
            line.contains(expected) && line.contains("conservative"),
            "{line}"
        );
    }
}

/// Census item 9: with the light at the eye, the tools' ambient (3% of what a white surface
/// facing the light reflects at the eye's distance from it) divided by that distance squared,
/// floored at 1e-6: 2e11 times the light's intensity over π. The distance is now at least a
/// tenth of the objects' bounds' half-diagonal. Checked: the light at the eye gives that
/// floor's ambient (a bound the old rule misses by 11 orders of magnitude), and a light
/// farther from the eye than the floor keeps the old rule's value exactly (the standard
/// scenes' surfaces are unchanged).
#[test]
fn a_light_at_the_eye_does_not_flood_the_surfaces_with_ambient() {
    use volshadow::glam::{Mat4, Vec2, Vec3};
    use volshadow::scene::shapes;
    use volshadow_harness::raster::{default_ambient, DrawLight, DrawObject};
    let eye = Vec3::new(0.0, 1.6, 6.0);
    let camera = volshadow::Camera::new(
        volshadow::glam::camera::rh::view::look_at_mat4(eye, Vec3::ZERO, Vec3::Y),
        volshadow::glam::camera::rh::proj::directx::perspective(0.8, 1.0, 0.1, 100.0),
    )
    .unwrap();
    let medium = volshadow::Medium::new(
        Vec3::splat(0.05),
        Vec3::splat(0.005),
        volshadow::PhaseFunction::Isotropic,
    )
    .unwrap();
    let ground = shapes::plane(Vec3::ZERO, Vec2::splat(20.0)).unwrap();
    let objects = [DrawObject {
        mesh: &ground,
        transform: Mat4::IDENTITY,
        albedo: Vec3::splat(0.8),
    }];
    let intensity = 20.0f32;
    let ambient_with_light_at = |p: Vec3| {
        let light = volshadow::PointLight::new(p, Vec3::splat(intensity)).unwrap();
        let lights = [DrawLight {
            light: light.into(),
            texture: None,
            shadow: None,
        }];
        default_ambient(&camera, &lights, &objects, &medium).x
    };
    let sigma_t = 0.055f32;
    let rule = |d: f32| intensity * (-sigma_t * d).exp() / (d * d) * 0.03 / std::f32::consts::PI;
    // The ground's bounds: 40 × 0 × 40, half-diagonal 28.3; a tenth of it is the floor.
    let floor = 0.1 * 0.5 * (2.0f32 * 40.0 * 40.0).sqrt();
    let at_eye = ambient_with_light_at(eye);
    println!(
        "light at the eye: ambient {at_eye:.3e} (floor {floor:.2}: {:.3e}; the old rule {:.3e})",
        rule(floor),
        rule(1e-6)
    );
    assert!(
        (at_eye - rule(floor)).abs() <= 1e-5 * rule(floor),
        "{at_eye} against {}",
        rule(floor)
    );
    let far = eye + Vec3::new(0.0, 2.0, -8.0); // 8.2 from the eye, beyond the floor
    let d = far.distance(eye);
    assert!(d > floor);
    let value = ambient_with_light_at(far);
    assert!(
        (value - rule(d)).abs() <= 1e-5 * rule(d),
        "{value} against {}",
        rule(d)
    );
}
