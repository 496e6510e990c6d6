//! The report tool's own code (`volshadow_harness::report`) run small, its metrics, verdicts,
//! plot and cache key, and its refusal to write over an input.

use std::path::Path;

use volshadow_harness::cli::Parsed;
use volshadow_harness::files::{assert_refused, snapshot};
use volshadow_harness::{repo_root, report, scene_files};

use crate::{args, at_repo_root};

#[test]
fn report_metrics_measure_what_they_say() {
    use report::errors;
    use volshadow::glam::DVec3;
    // A ramp of in-scatter (2..=101: every pixel above 1% of the maximum, so all count).
    let reference: Vec<DVec3> = (2..=101).map(|i| DVec3::splat(f64::from(i))).collect();
    let keep = vec![true; 100];
    let exact = errors(&reference, &reference, &keep);
    assert_eq!((exact.rmse, exact.p95, exact.p99), (0.0, 0.0, 0.0));
    let mut image: Vec<DVec3> = reference.iter().map(|r| *r * 1.1).collect();
    let scaled = errors(&image, &reference, &keep);
    assert!((scaled.p95 - 0.1).abs() < 1e-12 && (scaled.p99 - 0.1).abs() < 1e-12);
    // RMSE relative to the mean: 0.1·sqrt(mean r²)/mean r for r = 2..=101.
    let mean_sq = (2..=101).map(|i| f64::from(i * i)).sum::<f64>() / 100.0;
    assert!((scaled.rmse - 0.1 * mean_sq.sqrt() / 51.5).abs() < 1e-12);
    // One pixel 5x off moves p99 (the 99th of 100 values) but not p95; a pixel left out of
    // the mask (a light's own) moves nothing.
    image[99] = reference[99] * 6.0;
    let outlier = errors(&image, &reference, &keep);
    assert!((outlier.p95 - 0.1).abs() < 1e-12 && (outlier.p99 - 0.1).abs() < 1e-12);
    let mut masked = keep.clone();
    masked[99] = false;
    image[50] = reference[50] * 6.0;
    let two = errors(&image, &reference, &masked);
    assert!((two.p99 - 5.0).abs() < 1e-12, "{}", two.p99);
    // A light's glow in view: one pixel a million times brighter does not set the scale (1% of
    // the maximum would count that pixel alone and see none of the errors on the ramp).
    let mut glow = reference.clone();
    glow[0] = DVec3::splat(1e6);
    let mut off = glow.clone();
    for r in &mut off[10..20] {
        *r *= 1.5;
    }
    let lit = errors(&off, &glow, &keep);
    assert!((lit.p95 - 0.5).abs() < 1e-12, "{}", lit.p95);
}

#[test]
fn report_runs_every_kind_of_configuration_and_writes_its_files() {
    // The report's own code path at a small size: two scenes (one with a textured spot), a
    // few configurations each, one timed frame. Checks the outputs exist and agree, and that
    // the measured errors order as the methods should.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_string_lossy().into_owned();
    let report = report::run(&args(&[
        "--quick",
        "--size",
        "48",
        "--frames",
        "1",
        "--scenes",
        &format!(
            "{}/scenes/sphere.json,{}/scenes/stained_glass.json",
            repo_root().display(),
            repo_root().display()
        ),
        "--out",
        &out,
    ]))
    .unwrap();
    for f in &report.files {
        let len = std::fs::metadata(f).unwrap().len();
        assert!(len > 100, "{} has {len} bytes", f.display());
    }
    let csv = std::fs::read_to_string(dir.path().join("report.csv")).unwrap();
    assert_eq!(csv.lines().count(), report.rows.len() + 1);
    let svg = std::fs::read_to_string(dir.path().join("error_vs_time.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.contains("brute force") && svg.contains("hybrid"));
    for r in &report.rows {
        assert!(r.total_ms.is_finite() && r.total_ms > 0.0, "{r:?}");
        assert!(
            r.errors.rmse.is_finite() && r.errors.p95.is_finite(),
            "{r:?}"
        );
    }
    // Three tolerances per scene were checked, none judged at 48x48 (the error table was
    // built at 512x512): the run's verdict (the binary's exit status) is a success whatever
    // the p95, and the report says why.
    assert_eq!(report.checks.len(), 6);
    use report::Verdict;
    assert!(report
        .checks
        .iter()
        .all(|c| c.size == 48 && c.verdict() == Verdict::NotJudged));
    assert!(report.verdict().is_ok());
    let md = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    assert_eq!(
        md.matches("not judged (table built at 512²)").count(),
        6,
        "{md}"
    );
    assert!(!md.contains("FAIL"), "{md}");
    assert!(std::fs::read_to_string(dir.path().join("error_table.rs"))
        .unwrap()
        .contains("at 48x48"));
    // On the sphere the hybrid at full resolution beats brute force at 16 steps (measured at
    // 48x48: p95 0.2% vs 16%), and the unshadowed floor is far off (89%).
    use report::Curve;
    let p95 = |curve: Curve, steps: u32| {
        report
            .rows
            .iter()
            .find(|r| r.scene == "sphere" && r.curve == curve && r.steps == steps)
            .map(|r| r.errors.p95)
            .unwrap()
    };
    let hybrid = p95(Curve::Hybrid(1, report::Filter::None, 0), 8);
    let brute = p95(Curve::Brute, 16);
    let floor = p95(Curve::Analytic, 0);
    println!("sphere 48x48 p95: hybrid 8 {hybrid:.4}, brute force 16 {brute:.4}, floor {floor:.4}");
    // The 2% accuracy target, met by the hybrid at 8 steps; brute force at 16 does worse.
    const TARGET_P95: f64 = 0.02;
    assert!(hybrid < TARGET_P95 && hybrid < brute && brute < floor);
}

/// The error-target checks are judged only at the size the planner's table was built for
/// (512²): there a p95 over the tolerance is a FAIL, the summary says so and the run's verdict
/// (the binary's exit status 1) is an error; at another size the same p95 is "not judged"
/// and the verdict a success.
#[test]
fn report_judges_error_targets_at_the_table_size_only() {
    use report::{summary, Check, Report, Verdict, ERROR_TABLE_SIZE};
    assert_eq!(ERROR_TABLE_SIZE, 512);
    let check = |size: u32, p95: f64| Check {
        scene: "window".into(),
        tolerance: 0.05,
        p95,
        size,
    };
    let report = |checks: Vec<Check>| Report {
        rows: Vec::new(),
        checks,
        files: Vec::new(),
    };
    assert_eq!(check(512, 0.071).verdict(), Verdict::Fail);
    assert_eq!(check(512, f64::INFINITY).verdict(), Verdict::Fail);
    assert_eq!(check(512, 0.049).verdict(), Verdict::Pass);
    assert_eq!(check(256, 0.071).verdict(), Verdict::NotJudged);
    assert_eq!(check(256, 0.001).verdict(), Verdict::NotJudged);

    let judged = report(vec![check(512, 0.049), check(512, 0.071)]);
    let error = judged.verdict().unwrap_err().to_string();
    println!("{error}");
    assert!(error.contains("1 error-target check(s) FAIL") && error.contains("window"));
    let text = summary(&[], &judged.checks);
    assert!(
        text.contains("| window | 5% | 0.049% | pass |")
            || text.contains("| window | 5% | 4.900% | pass |"),
        "{text}"
    );
    assert!(text.contains("FAIL by 2.10 points"), "{text}");

    let elsewhere = report(vec![check(256, 0.071), check(256, 0.001)]);
    assert!(elsewhere.verdict().is_ok());
    let text = summary(&[], &elsewhere.checks);
    assert_eq!(
        text.matches("not judged (table built at 512²)").count(),
        2,
        "{text}"
    );
    assert!(!text.contains("FAIL") && !text.contains("pass"), "{text}");
}

/// The report never writes over its input: a scene file where an output would go (here a
/// scene saved as `report.md` in the output folder) is refused before anything is written
/// (no cache folder, no other file). Its default output folder is `target/volshadow-report`,
/// and its default run the quick set.
#[test]
fn report_never_overwrites_its_input() {
    at_repo_root();
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("report.md");
    std::fs::copy(repo_root().join("scenes/sphere.json"), &scene).unwrap();
    let before = snapshot(dir.path());
    let d = dir.path().to_str().unwrap();
    for out in [d.to_string(), format!("{d}/.")] {
        let result = report::run(&args(&[
            "--quick",
            "--size",
            "8",
            "--frames",
            "1",
            "--scenes",
            scene.to_str().unwrap(),
            "--out",
            &out,
        ]));
        assert_refused(result, "report.md", dir.path(), &before, &out);
        assert!(
            !dir.path().join("cache").exists(),
            "{out}: the cache folder was made"
        );
    }
    use report::Options;
    let Parsed::Run(defaults) = Options::parse(&[]).unwrap() else {
        panic!("not a run")
    };
    assert_eq!(defaults.out, Path::new("target/volshadow-report"));
    assert_eq!(defaults.size, report::DEFAULT_SIZE);
    assert_eq!(
        defaults.scenes,
        report::DEFAULT_SCENES.map(|n| Path::new("scenes").join(format!("{n}.json")))
    );
    assert!(!defaults.full);
    // `--full`: every scene file at the table's size; `--size` still applies.
    let Parsed::Run(full) = Options::parse(&args(&["--full"])).unwrap() else {
        panic!("not a run")
    };
    assert_eq!(full.size, 512);
    assert_eq!(full.scenes.len(), scene_files().len());
    let Parsed::Run(full) = Options::parse(&args(&["--full", "--size", "64"])).unwrap() else {
        panic!("not a run")
    };
    assert!(full.full && full.size == 64);
    // Scenes named on the command line: at the table's size, as before the quick set.
    let Parsed::Run(named) = Options::parse(&args(&["--scenes", "soft"])).unwrap() else {
        panic!("not a run")
    };
    assert_eq!(named.size, 512);
    assert_eq!(named.scenes, [Path::new("scenes/soft.json")]);
}

/// `error_vs_time.svg`: every series the report can plot (13 in a full run) has its own
/// colour, and its own colour and marker together; none is the analytic floor's grey; and
/// the legend's entries, at the widths their names need, neither overlap nor leave the header.
#[test]
fn report_plot_series_and_legend_are_distinct() {
    use report::FLOOR_GREY;
    use report::{legend_box, legend_layout, series_style, Curve, Filter};
    let mut curves = vec![Curve::Brute, Curve::Paper003, Curve::Textbook];
    for (d, f) in [(1, Filter::None), (2, Filter::Box3), (2, Filter::Separable)] {
        curves.push(Curve::Exact(d, f));
        curves.push(Curve::Hybrid(d, f, 2));
    }
    for f in [Filter::Box3, Filter::Separable] {
        curves.push(Curve::Exact(4, f));
        curves.push(Curve::Hybrid(4, f, 2));
    }
    assert_eq!(curves.len(), 13);
    let styles: Vec<_> = (0..curves.len()).map(series_style).collect();
    for (i, a) in styles.iter().enumerate() {
        assert_ne!(a.0, FLOOR_GREY);
        for (j, b) in styles.iter().enumerate().skip(i + 1) {
            assert_ne!(a.0, b.0, "series {i} and {j} share a colour");
        }
    }
    let pairs: Vec<_> = (0..60).map(series_style).collect();
    for (i, a) in pairs.iter().enumerate() {
        assert!(!pairs[i + 1..].contains(a), "style {i} repeats");
    }
    let mut names: Vec<String> = curves.iter().map(|c| c.name()).collect();
    names.push("analytic floor (its time)".into());
    for width in [1200, 800] {
        let (places, header) = legend_layout(&names, width);
        let boxes: Vec<_> = names
            .iter()
            .zip(&places)
            .map(|(n, &p)| legend_box(n, p))
            .collect();
        for (i, a) in boxes.iter().enumerate() {
            assert!(
                a.2 <= width && a.3 <= header,
                "{:?} leaves the header",
                names[i]
            );
            for (j, b) in boxes.iter().enumerate().skip(i + 1) {
                let apart = a.2 <= b.0 || b.2 <= a.0 || a.3 <= b.1 || b.3 <= a.1;
                assert!(apart, "{:?} and {:?} overlap", names[i], names[j]);
            }
        }
    }
}

/// The report's reference cache is keyed by every source the reference depends on: the files
/// the old hand-written list missed (the BVH, the JSON layer, the scene types) are in it, and
/// every listed file exists (a renamed file would otherwise silently drop out of the key).
#[test]
fn report_cache_key_covers_the_reference_sources() {
    let sources = report::reference_sources();
    let names: Vec<String> = sources
        .iter()
        .map(|p| p.to_string_lossy().replace('\\', "/"))
        .collect();
    for needed in [
        "src/reference/bvh.rs",
        "src/scene_file/spec.rs",
        "src/scene/shapes.rs",
        "src/scene/medium.rs",
        "src/scene/light.rs",
        "src/scene/camera.rs",
        "src/scene/mesh.rs",
        "harness/src/render_scene.rs",
    ] {
        assert!(
            names.iter().any(|n| n.ends_with(needed)),
            "{needed} is not in the reference cache key: {names:?}"
        );
    }
    for p in &sources {
        assert!(p.is_file(), "{} does not exist", p.display());
    }
}
