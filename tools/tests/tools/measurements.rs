//! The measurements tool refuses to write over its input.

use std::path::Path;

use volshadow_harness::files::snapshot;
use volshadow_harness::metric;
use volshadow_tools::measurements;

/// `measurements` never writes over its input: a log saved where the run's table would go
/// (`docs/measurements/NAME.tsv` under its root) is refused before anything is written, and
/// the same log elsewhere is read and the documents written (so the refusal, not a failing
/// read, kept the files).
#[test]
fn measurements_never_overwrites_its_input() {
    let dir = tempfile::tempdir().unwrap();
    let folder = dir.path().join("docs/measurements");
    std::fs::create_dir_all(&folder).unwrap();
    let log = format!(
        "{}\n",
        metric::line(metric::Doc::Accuracy, "examples::x", "a check", "1%", "2%")
    );
    let in_place = folder.join("x.tsv");
    std::fs::write(&in_place, &log).unwrap();
    let before = snapshot(dir.path());
    let run = |path: &Path| {
        let args = ["--run", "x", "--date", "2026-01-01", path.to_str().unwrap()];
        measurements::run(args.map(String::from).to_vec(), dir.path())
    };
    let message = run(&in_place).expect_err("not refused").to_string();
    println!("{message}");
    assert!(message.contains("refusing to write"), "{message}");
    assert_eq!(snapshot(dir.path()), before, "files changed");
    let elsewhere = dir.path().join("x.log");
    std::fs::write(&elsewhere, &log).unwrap();
    run(&elsewhere).unwrap();
    assert!(dir.path().join("docs/ACCURACY.md").exists());
    assert_ne!(std::fs::read(&in_place).unwrap(), log.as_bytes());
}
