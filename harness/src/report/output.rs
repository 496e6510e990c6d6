//! What the report writes: the printed summary, `report.md`, `report.csv`, `error_table.rs` and
//! `error_vs_time.svg`.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::PathBuf;

use super::measure::Clock;
use super::{
    BoxError, Check, ConfigKey, Curve, Filter, Options, Row, Verdict, ERROR_TABLE_SIZE,
    PASS_COLUMNS,
};

/// The files the report writes into its output folder (besides the reference cache).
pub const FILES: [&str; 4] = [
    "report.csv",
    "report.md",
    "error_vs_time.svg",
    "error_table.rs",
];

/// Today's date (UTC), `YYYY-MM-DD`, from the system clock.
pub fn today() -> String {
    let days = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs() / 86_400) as i64;
    // Howard Hinnant's civil-from-days.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!("{year:04}-{month:02}-{day:02}")
}

/// The cheapest row of `curve`-matching rows of `scene` with p95 ≤ `p95`.
pub fn cheapest<'a>(
    rows: &'a [Row],
    scene: &str,
    p95: f64,
    filter: impl Fn(&Row) -> bool,
) -> Option<&'a Row> {
    rows.iter()
        .filter(|r| r.scene == scene && filter(r) && r.errors.p95 <= p95)
        .min_by(|a, b| a.total_ms.total_cmp(&b.total_ms))
}

/// The per-scene summary and the error-target checks, as printed and written.
pub fn summary(rows: &[Row], checks: &[Check]) -> String {
    let mut out = String::new();
    let mut scenes: Vec<&str> = Vec::new();
    for r in rows {
        if !scenes.contains(&r.scene.as_str()) {
            scenes.push(&r.scene);
        }
    }
    let _ = writeln!(out, "## Summary\n");
    let is_exact = |r: &Row| matches!(r.curve, Curve::Exact(..));
    let _ = writeln!(
        out,
        "| scene | textbook march at p95 ≤ 2% | brute force at p95 ≤ 2% | exact at p95 ≤ 2% | exact vs textbook | exact vs brute force | exact 1/2 3x3 (p95) / analytic floor |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|---|");
    for scene in &scenes {
        let floor = rows
            .iter()
            .find(|r| r.scene == *scene && r.curve == Curve::Analytic);
        let textbook = cheapest(rows, scene, 0.02, |r| r.curve == Curve::Textbook);
        let brute = cheapest(rows, scene, 0.02, |r| r.curve == Curve::Brute);
        let exact = cheapest(rows, scene, 0.02, is_exact);
        let half = rows
            .iter()
            .find(|r| r.scene == *scene && r.curve == Curve::Exact(2, Filter::Box3));
        let describe = |r: Option<&Row>| match r {
            Some(r) if r.curve == Curve::Textbook || r.curve == Curve::Brute => format!(
                "{} steps: {:.1} ms (p95 {:.2}%)",
                r.steps,
                r.total_ms,
                100.0 * r.errors.p95
            ),
            Some(r) => format!(
                "{}: {:.1} ms (p95 {:.2}%)",
                r.curve.name(),
                r.total_ms,
                100.0 * r.errors.p95
            ),
            None => "not reached".into(),
        };
        // A baseline that never reached 2%: a lower bound from its most expensive point.
        let speedup = |baseline: Option<&Row>, curve: Curve| match (baseline, exact) {
            (Some(b), Some(e)) => format!("{:.1}x", b.total_ms / e.total_ms),
            (None, Some(e)) => rows
                .iter()
                .filter(|r| r.scene == *scene && r.curve == curve)
                .max_by(|a, b| a.total_ms.total_cmp(&b.total_ms))
                .map_or("n/a".into(), |b| {
                    format!(
                        "> {:.1}x (at {} steps p95 {:.2}%)",
                        b.total_ms / e.total_ms,
                        b.steps,
                        100.0 * b.errors.p95
                    )
                }),
            _ => "n/a".into(),
        };
        let ratio = match (half, floor) {
            (Some(h), Some(f)) => format!(
                "{:.2}x ({:.1} / {:.1} ms, p95 {:.2}%)",
                h.total_ms / f.total_ms,
                h.total_ms,
                f.total_ms,
                100.0 * h.errors.p95
            ),
            _ => "n/a".into(),
        };
        let _ = writeln!(
            out,
            "| {scene} | {} | {} | {} | {} | {} | {ratio} |",
            describe(textbook),
            describe(brute),
            describe(exact),
            speedup(textbook, Curve::Textbook),
            speedup(brute, Curve::Brute),
        );
    }
    let _ = writeln!(out);
    let _ = writeln!(
        out,
        "| scene | brute force at p95 ≤ 2% | hybrid at p95 ≤ 2% | speedup | 1/4-res pipeline at p95 ≤ 2% | its cost / analytic floor |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|");
    let is_hybrid = |r: &Row| matches!(r.curve, Curve::Hybrid(..));
    for scene in scenes {
        let floor = rows
            .iter()
            .find(|r| r.scene == scene && r.curve == Curve::Analytic);
        let brute = cheapest(rows, scene, 0.02, |r| r.curve == Curve::Brute);
        let hybrid = cheapest(rows, scene, 0.02, is_hybrid);
        let quarter = cheapest(rows, scene, 0.02, |r| is_hybrid(r) && r.scale == 4);
        let describe = |r: Option<&Row>| match r {
            Some(r) => format!(
                "{} {} steps: {:.1} ms (p95 {:.2}%)",
                r.curve.name(),
                r.steps,
                r.total_ms,
                100.0 * r.errors.p95
            ),
            None => "not reached".into(),
        };
        let speedup = match (brute, hybrid) {
            (Some(b), Some(h)) => format!("{:.1}x", b.total_ms / h.total_ms),
            (None, Some(h)) => {
                // Brute force never got there: a lower bound from its most expensive point.
                let best = rows
                    .iter()
                    .filter(|r| r.scene == scene && r.curve == Curve::Brute)
                    .max_by(|a, b| a.total_ms.total_cmp(&b.total_ms));
                best.map_or("n/a".into(), |b| {
                    format!(
                        "> {:.1}x (brute force at {} steps: p95 {:.2}%)",
                        b.total_ms / h.total_ms,
                        b.steps,
                        100.0 * b.errors.p95
                    )
                })
            }
            _ => "n/a".into(),
        };
        let ratio = match (quarter, floor) {
            (Some(q), Some(f)) => {
                let static_light = q.total_ms - q.passes.get("shadow map").copied().unwrap_or(0.0);
                format!(
                    "{:.2}x ({:.1} / {:.1} ms); {:.2}x with the light static (no shadow map)",
                    q.total_ms / f.total_ms,
                    q.total_ms,
                    f.total_ms,
                    static_light / f.total_ms
                )
            }
            _ => "n/a".into(),
        };
        let _ = writeln!(
            out,
            "| {scene} | {} | {} | {speedup} | {} | {ratio} |",
            describe(brute),
            describe(hybrid),
            describe(quarter)
        );
    }
    let soft: Vec<&Row> = rows.iter().filter(|r| r.hard.is_some()).collect();
    if !soft.is_empty() {
        let _ = writeln!(out, "\n## Soft shadows against hard at equal settings\n");
        let _ = writeln!(
            out,
            "Each configuration of a scene whose light has a radius, against the same \
             configuration on the scene with radius 0, timed in the same rounds (a soft frame, \
             then a hard one, each with its own passes; each pass's median over the rounds). Light moving: every pass of a frame, the \
             shadow map and the soft-shadow grid rebuilt. Light static: less the shadow map \
             and the grid, which are then reused.\n"
        );
        let _ = writeln!(
            out,
            "| scene | configuration | soft ms | hard ms | soft / hard, light moving | soft / hard, light static | soft p95 | hard p95 against the soft reference |"
        );
        let _ = writeln!(out, "|---|---|---|---|---|---|---|---|");
        for r in soft {
            let hard = r.hard.expect("filtered");
            let _ = writeln!(
                out,
                "| {} | {} | {:.1} | {:.1} | {:.2}x | {:.2}x | {:.2}% | {:.2}% |",
                r.scene,
                r.curve.name(),
                hard.soft_ms,
                hard.hard_ms,
                hard.moving,
                hard.fixed_light,
                100.0 * r.errors.p95,
                100.0 * hard.p95
            );
        }
    }
    let _ = writeln!(out, "\n## Error-target check\n");
    let _ = writeln!(out, "| scene | tolerance (p95) | achieved p95 | result |");
    let _ = writeln!(out, "|---|---|---|---|");
    for check in checks {
        let Check {
            scene,
            tolerance,
            p95,
            ..
        } = check;
        let tolerance = f64::from(*tolerance);
        let result = if check.verdict() == Verdict::NotJudged {
            format!("not judged (table built at {ERROR_TABLE_SIZE}²)")
        } else if *p95 <= tolerance {
            "pass".to_string()
        } else if p95.is_infinite() {
            "FAIL: no configuration of the error table reaches it with headroom".to_string()
        } else {
            format!(
                "FAIL by {:.2} points ({:.2}x)",
                100.0 * (p95 - tolerance),
                p95 / tolerance
            )
        };
        let _ = writeln!(
            out,
            "| {scene} | {:.0}% | {} | {result} |",
            100.0 * tolerance,
            if p95.is_finite() {
                format!("{:.3}%", 100.0 * p95)
            } else {
                "–".into()
            }
        );
    }
    out
}

/// The run's figures as metric lines ([`crate::metric`]) for `docs/PERFORMANCE.md`: per
/// scene the analytic floor, the default configurations and the cheapest of each method at p95
/// ≤ 2%; and the error-target checks.
pub fn metric_lines(
    options: &Options,
    adapter: &str,
    rows: &[Row],
    checks: &[Check],
) -> Vec<String> {
    use super::metric::{line, Doc};
    let source = format!(
        "cargo run --release -p volshadow_tools --bin report -- {}",
        regenerate(options)
    );
    let mut out = vec![line(Doc::Adapter, &source, adapter, "", "")];
    let mut perf = |check: String, measured: String, bound: &str| {
        out.push(line(Doc::Performance, &source, &check, measured, bound));
    };
    let ms_p95 = |r: &Row| format!("{:.1} ms, p95 {:.2}%", r.total_ms, 100.0 * r.errors.p95);
    let mut scenes: Vec<&str> = Vec::new();
    for r in rows {
        if !scenes.contains(&r.scene.as_str()) {
            scenes.push(&r.scene);
        }
    }
    let size = options.size;
    for scene in scenes {
        let find = |curve: Curve| rows.iter().find(|r| r.scene == scene && r.curve == curve);
        let floor = find(Curve::Analytic);
        if let Some(f) = floor {
            perf(
                format!("{scene}, {size}²: the analytic floor (no shadows)"),
                format!("{:.1} ms", f.total_ms),
                "–",
            );
        }
        for (curve, name) in [
            (
                Curve::Exact(1, Filter::None),
                "exact, full resolution (a GPU's default)",
            ),
            (
                Curve::Exact(2, Filter::Box3),
                "exact, ½ + 3×3 (a CPU adapter's default)",
            ),
        ] {
            if let Some(r) = find(curve) {
                let ratio = floor.map_or(String::new(), |f| {
                    format!(", {:.2}× the floor", r.total_ms / f.total_ms)
                });
                perf(
                    format!("{scene}, {size}²: {name}"),
                    format!("{}{ratio}", ms_p95(r)),
                    "–",
                );
            }
        }
        for (label, is) in [
            (
                "textbook march",
                (|r: &Row| r.curve == Curve::Textbook) as fn(&Row) -> bool,
            ),
            ("brute force", |r: &Row| r.curve == Curve::Brute),
            ("hybrid", |r: &Row| matches!(r.curve, Curve::Hybrid(..))),
            ("exact", |r: &Row| matches!(r.curve, Curve::Exact(..))),
        ] {
            let measured = match cheapest(rows, scene, 0.02, is) {
                Some(r) if r.steps > 0 && !matches!(r.curve, Curve::Exact(..)) => {
                    format!("{} ({} steps): {}", r.curve.name(), r.steps, ms_p95(r))
                }
                Some(r) => format!("{}: {}", r.curve.name(), ms_p95(r)),
                None => "not reached".into(),
            };
            perf(
                format!("{scene}, {size}²: the cheapest {label} at p95 ≤ 2%"),
                measured,
                "–",
            );
        }
        for r in rows.iter().filter(|r| r.scene == scene) {
            if let Some(hard) = r.hard {
                perf(
                    format!(
                        "{scene}, {size}²: {}, soft against hard (light moving; light static)",
                        r.curve.name()
                    ),
                    format!(
                        "{:.1} / {:.1} ms: {:.2}×; {:.2}×",
                        hard.soft_ms, hard.hard_ms, hard.moving, hard.fixed_light
                    ),
                    "–",
                );
            }
        }
    }
    for check in checks {
        let measured = if check.verdict() == Verdict::NotJudged {
            format!(
                "p95 {:.3}% (not judged at {}²)",
                100.0 * check.p95,
                check.size
            )
        } else {
            format!("p95 {:.3}%", 100.0 * check.p95)
        };
        out.push(line(
            Doc::Performance,
            &source,
            &format!(
                "{}, {}²: Settings::for_error_target({}%) achieves",
                check.scene,
                check.size,
                100.0 * check.tolerance
            ),
            measured,
            format!(
                "{}% (judged at {ERROR_TABLE_SIZE}²)",
                100.0 * check.tolerance
            ),
        ));
    }
    out
}

/// The options that reproduce this run.
fn regenerate(options: &Options) -> String {
    let scenes: Vec<String> = options
        .scenes
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    let mut text = format!(
        "--scenes {} --size {} --frames {} --out {}",
        scenes.join(","),
        options.size,
        options.frames,
        options.out.display()
    );
    for (flag, on) in [("--full", options.full), ("--quick", options.quick)] {
        if on {
            text.push(' ');
            text.push_str(flag);
        }
    }
    text
}

pub fn write_outputs(
    options: &Options,
    adapter: &str,
    date: &str,
    clock: Clock,
    rows: &[Row],
    checks: &[Check],
) -> Result<Vec<PathBuf>, BoxError> {
    let write = |name: &str, text: &str| -> Result<PathBuf, BoxError> {
        let path = options.out.join(name);
        std::fs::write(&path, text).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        Ok(path)
    };
    // CSV.
    let mut csv = String::from("scene,method,steps,scale,filter,bisections");
    for c in PASS_COLUMNS {
        let _ = write!(
            csv,
            ",{}_ms",
            c.replace("F' ", "").replace(' ', "_").to_lowercase()
        );
    }
    csv.push_str(",total_ms,rmse_rel,p95,p99\n");
    for r in rows {
        let _ = write!(
            csv,
            "{},{},{},{},{},{}",
            r.scene,
            r.curve.name(),
            r.steps,
            r.scale,
            r.filter.name(),
            r.bisections
        );
        for c in PASS_COLUMNS {
            let _ = write!(csv, ",{:.3}", r.passes.get(c).copied().unwrap_or(0.0));
        }
        let _ = writeln!(
            csv,
            ",{:.3},{:.6},{:.6},{:.6}",
            r.total_ms, r.errors.rmse, r.errors.p95, r.errors.p99
        );
    }
    // Markdown.
    let mut md = format!(
        "# volshadow: error against time\n\n{date}, {adapter}, {}x{} pixels. Timing: {}, median of {} frames after a warm-up frame; F' table, shadow map and soft-shadow grid timed in frames in which the light moves (every pass that depends on it runs; no resource is recreated) and counted in every total. Error against the f64 reference: RMSE relative to the mean in-scatter; p95/p99 of the per-pixel relative error where the reference is above 1% of its 99th percentile (not of its maximum, which a light in view puts in its own glow); the light's own pixels left out. Regenerate: `cargo run --release -p volshadow_tools --bin report -- {}`.\n\n",
        options.size,
        options.size,
        match clock {
            Clock::WallPerPass => "each pass submitted alone and timed by the wall clock (CPU adapter)",
            Clock::Timestamps => "timestamp queries",
        },
        options.frames,
        regenerate(options)
    );
    md.push_str(&summary(rows, checks));
    md.push_str("\n## All configurations\n\n| scene | method | steps | ");
    for c in PASS_COLUMNS {
        let _ = write!(md, "{c} ms | ");
    }
    md.push_str("total ms | RMSE | p95 | p99 |\n|---|---|---|");
    md.push_str(&"---|".repeat(PASS_COLUMNS.len() + 4));
    md.push('\n');
    for r in rows {
        let _ = write!(md, "| {} | {} | {} | ", r.scene, r.curve.name(), r.steps);
        for c in PASS_COLUMNS {
            match r.passes.get(c) {
                Some(ms) => {
                    let _ = write!(md, "{ms:.1} | ");
                }
                None => md.push_str("– | "),
            }
        }
        let _ = writeln!(
            md,
            "{:.1} | {:.3}% | {:.3}% | {:.3}% |",
            r.total_ms,
            100.0 * r.errors.rmse,
            100.0 * r.errors.p95,
            100.0 * r.errors.p99
        );
    }
    let mut files = vec![write(FILES[0], &csv)?, write(FILES[1], &md)?];
    files.push(plot(options, rows, adapter, date)?);
    files.push(write(FILES[3], &error_table(rows, options.size))?);
    Ok(files)
}

/// Hybrid configurations over the scenes with untextured lights without a radius (under an
/// error target a textured spot scatters at full resolution, and a light with a radius marches
/// its penumbra whatever the method): the worst p95 and the mean cost relative to
/// each scene's analytic floor, Pareto-optimal ones only, as rows of `volshadow::plan`'s table.
/// Only configurations measured on every such scene count (a sweep that stopped early on one
/// scene leaves its later step counts out). `size`: the images' width and height, in the
/// header (the planner's table is measured at [`ERROR_TABLE_SIZE`]²).
pub fn error_table(rows: &[Row], size: u32) -> String {
    let rows: Vec<Row> = rows
        .iter()
        .filter(|r| !r.textured && !r.soft)
        .cloned()
        .collect();
    let rows = rows.as_slice();
    let mut groups: BTreeMap<ConfigKey, Vec<&Row>> = BTreeMap::new();
    for r in rows
        .iter()
        .filter(|r| matches!(r.curve, Curve::Hybrid(..) | Curve::Exact(..)))
    {
        let exact = matches!(r.curve, Curve::Exact(..));
        groups
            .entry((exact, r.steps, r.scale, r.filter, r.bisections))
            .or_default()
            .push(r);
    }
    let scenes = rows.iter().filter(|r| r.curve == Curve::Analytic).count();
    let floor = |scene: &str| {
        rows.iter()
            .find(|r| r.scene == scene && r.curve == Curve::Analytic)
            .map_or(1.0, |r| r.total_ms)
    };
    let mut candidates: Vec<(f64, f64, ConfigKey)> = groups
        .into_iter()
        .filter(|(_, v)| v.len() == scenes)
        .map(|(key, v)| {
            let worst = v.iter().map(|r| r.errors.p95).fold(0.0, f64::max);
            let cost = v.iter().map(|r| r.total_ms / floor(&r.scene)).sum::<f64>() / v.len() as f64;
            (worst, cost, key)
        })
        .collect();
    candidates.sort_by(|a, b| a.1.total_cmp(&b.1));
    let mut out = format!(
        "// Measured by `cargo run --release -p volshadow_tools --bin report` at {size}x{size}: exact and hybrid\n\
         // configurations on the Pareto front of worst-scene p95 against mean cost over the\n\
         // analytic floor.{}\n",
        if size == ERROR_TABLE_SIZE {
            String::new()
        } else {
            format!(
                "\n// Not comparable with volshadow::plan::error_table, measured at \
                 {ERROR_TABLE_SIZE}x{ERROR_TABLE_SIZE} (`--scenes all`)."
            )
        }
    );
    let mut best = f64::INFINITY;
    for (worst, cost, (exact, steps, scale, filter, bisections)) in candidates {
        if worst < best {
            best = worst;
            let filter = match filter {
                Filter::None | Filter::Box3 => "UpsampleFilter::DepthAware3x3".to_string(),
                Filter::Bilinear => "UpsampleFilter::Bilinear".to_string(),
                // Written out in full, so the table compiles where it is pasted.
                Filter::Separable => format!("UpsampleFilter::{:?}", super::SEPARABLE),
            };
            let scale = match scale {
                1 => "Scale::Full",
                2 => "Scale::Half",
                _ => "Scale::Quarter",
            };
            let method = if exact { "Exact" } else { "Hybrid" };
            let _ = writeln!(
                out,
                "    measured(MarchMethod::{method}, {worst:.4}, {cost:.3}, {steps}, {scale}, {filter}, {bisections}),"
            );
        }
    }
    out
}

/// A plotted series' marker.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Marker {
    Circle,
    Triangle,
    Square,
    Cross,
}

/// Distinct colours, none of them the analytic floor's grey ([`FLOOR_GREY`]).
pub const PALETTE: [(u8, u8, u8); 15] = [
    (31, 119, 180),
    (214, 39, 40),
    (44, 160, 44),
    (255, 127, 14),
    (148, 103, 189),
    (0, 0, 0),
    (140, 86, 75),
    (227, 119, 194),
    (23, 190, 207),
    (188, 189, 34),
    (0, 0, 128),
    (128, 0, 0),
    (0, 100, 0),
    (204, 153, 0),
    (0, 128, 128),
];

/// The analytic floor's vertical line.
pub const FLOOR_GREY: (u8, u8, u8) = (170, 170, 170);

const MARKERS: [Marker; 4] = [
    Marker::Circle,
    Marker::Triangle,
    Marker::Square,
    Marker::Cross,
];

/// The colour and marker of the `index`-th plotted series: no two of the first 60 share both,
/// no two of the first 15 share a colour.
pub fn series_style(index: usize) -> ((u8, u8, u8), Marker) {
    (
        PALETTE[index % PALETTE.len()],
        MARKERS[index % MARKERS.len()],
    )
}

/// The legend's text height and the width it allows a character (sans-serif at 13 px averages
/// about 7 px a character; 8 leaves room).
const LEGEND_FONT: u32 = 13;
const LEGEND_CHAR: u32 = 8;
/// The legend's line height, and its first line's top (below the title).
const LEGEND_LINE: u32 = 22;
const LEGEND_TOP: u32 = 38;
/// A legend entry's sample (line and marker) and the gap before its text.
const LEGEND_SAMPLE: u32 = 30;

/// Where each legend entry goes in a header `width` wide: its top-left corner, each column
/// as wide as the longest entry, and the header's height below the last line.
pub fn legend_layout(names: &[String], width: u32) -> (Vec<(u32, u32)>, u32) {
    let longest = names.iter().map(|n| n.chars().count()).max().unwrap_or(0) as u32;
    let entry = LEGEND_SAMPLE + LEGEND_CHAR * longest + 20;
    let usable = width.saturating_sub(20);
    let columns = (usable / entry.max(1)).max(1);
    let column_width = usable / columns;
    let places: Vec<(u32, u32)> = (0..names.len() as u32)
        .map(|i| {
            (
                10 + column_width * (i % columns),
                LEGEND_TOP + LEGEND_LINE * (i / columns),
            )
        })
        .collect();
    let lines = (names.len() as u32).div_ceil(columns);
    (places, LEGEND_TOP + LEGEND_LINE * lines + 10)
}

/// The box a legend entry's sample and text take at `place` (left, top, right, bottom).
pub fn legend_box(name: &str, place: (u32, u32)) -> (u32, u32, u32, u32) {
    (
        place.0,
        place.1,
        place.0 + LEGEND_SAMPLE + LEGEND_CHAR * name.chars().count() as u32,
        place.1 + LEGEND_FONT + 4,
    )
}

/// Draws `marker` at `point` on `area` (a chart's plotting area or the header).
fn draw_marker<DB, CT>(
    area: &plotters::drawing::DrawingArea<DB, CT>,
    point: CT::From,
    marker: Marker,
    color: plotters::style::RGBColor,
) -> Result<(), BoxError>
where
    DB: plotters::prelude::DrawingBackend,
    DB::ErrorType: 'static,
    CT: plotters::coord::CoordTranslate,
    CT::From: Clone,
{
    use plotters::prelude::*;
    let result = match marker {
        Marker::Circle => area.draw(&Circle::new(point, 4, color.filled())),
        Marker::Triangle => area.draw(&TriangleMarker::new(point, 5, color.filled())),
        Marker::Square => area
            .draw(&(EmptyElement::at(point) + Rectangle::new([(-4, -4), (4, 4)], color.filled()))),
        Marker::Cross => area.draw(&Cross::new(point, 4, color.stroke_width(2))),
    };
    result.map_err(|e| format!("plot: {e}").into())
}

/// `error_vs_time.svg`: per scene, p95 error (log) against total time (log), one curve per
/// method, each with its own colour and marker ([`series_style`]) and one legend for all.
pub fn plot(
    options: &Options,
    rows: &[Row],
    adapter: &str,
    date: &str,
) -> Result<PathBuf, BoxError> {
    use plotters::prelude::*;
    let path = options.out.join(FILES[2]);
    let mut scenes: Vec<&str> = Vec::new();
    for r in rows {
        if !scenes.contains(&r.scene.as_str()) {
            scenes.push(&r.scene);
        }
    }
    // The plotted curves: brute force, paper 003, the textbook march, the exact method and
    // the hybrid with refinement on.
    let plotted = |c: Curve| match c {
        Curve::Brute | Curve::Paper003 | Curve::Textbook | Curve::Exact(..) => true,
        Curve::Hybrid(_, f, b) => b > 0 && f != Filter::Bilinear,
        _ => false,
    };
    // One style per method across all panels, and one legend for all of them.
    let mut curves: Vec<Curve> = rows
        .iter()
        .map(|r| r.curve)
        .filter(|c| plotted(*c))
        .collect();
    curves.sort();
    curves.dedup();
    let rgb = |(r, g, b): (u8, u8, u8)| RGBColor(r, g, b);
    let style_of = |c: Curve| {
        let (color, marker) = series_style(curves.iter().position(|k| *k == c).unwrap_or(0));
        (rgb(color), marker)
    };
    let floor_grey = rgb(FLOOR_GREY);
    let mut names: Vec<String> = curves.iter().map(|c| c.name()).collect();
    names.push("analytic floor (its time)".into());
    let width = 1200;
    let (places, header) = legend_layout(&names, width);

    let columns = 2usize;
    let panel_rows = scenes.len().div_ceil(columns).max(1);
    let file = path.clone();
    let root =
        SVGBackend::new(&file, (width, header + 420 * panel_rows as u32)).into_drawing_area();
    root.fill(&WHITE)?;
    let (title, body) = root.split_vertically(header);
    title.draw(&Text::new(
        format!(
            "volshadow: p95 relative error against frame time, {}x{} ({date}, {adapter})",
            options.size, options.size
        ),
        (10, 10),
        ("sans-serif", 16).into_font(),
    ))?;
    for (i, (name, &(x, y))) in names.iter().zip(&places).enumerate() {
        let (x, y) = (x as i32, y as i32);
        let middle = y + LEGEND_FONT as i32 / 2;
        if i < curves.len() {
            let (color, marker) = style_of(curves[i]);
            title.draw(&PathElement::new(
                vec![(x, middle), (x + 24, middle)],
                color.stroke_width(2),
            ))?;
            draw_marker(&title, (x + 12, middle), marker, color)?;
        } else {
            title.draw(&PathElement::new(
                vec![(x + 12, y - 2), (x + 12, y + LEGEND_FONT as i32 + 2)],
                floor_grey.stroke_width(2),
            ))?;
        }
        title.draw(&Text::new(
            name.clone(),
            (x + LEGEND_SAMPLE as i32, y),
            ("sans-serif", LEGEND_FONT).into_font(),
        ))?;
    }
    let panels = body.split_evenly((panel_rows, columns));
    for (panel, scene) in panels.iter().zip(&scenes) {
        let scene_rows: Vec<&Row> = rows.iter().filter(|r| r.scene == *scene).collect();
        let (mut t0, mut t1, mut e0, mut e1) = (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64);
        for r in &scene_rows {
            if r.total_ms > 0.0 {
                t0 = t0.min(r.total_ms);
                t1 = t1.max(r.total_ms);
            }
            if r.errors.p95 > 0.0 && r.errors.p95.is_finite() {
                e0 = e0.min(r.errors.p95);
                e1 = e1.max(r.errors.p95);
            }
        }
        if !(t0 < t1 && e0 < e1) {
            continue;
        }
        let mut chart = ChartBuilder::on(panel)
            .caption(*scene, ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(
                (t0 * 0.8..t1 * 1.25).log_scale(),
                (e0 * 0.8..e1 * 1.25).log_scale(),
            )?;
        chart
            .configure_mesh()
            .light_line_style(RGBColor(238, 238, 238))
            .bold_line_style(RGBColor(200, 200, 200))
            .x_labels(8)
            .y_labels(8)
            .x_desc("frame time, ms (sum of pass medians)")
            .y_desc("p95 relative error")
            .x_label_formatter(&|v| format!("{v:.0}"))
            .y_label_formatter(&|v| format!("{:.2}%", 100.0 * v))
            .draw()?;
        for curve in curves
            .iter()
            .filter(|c| scene_rows.iter().any(|r| r.curve == **c))
        {
            let (color, marker) = style_of(*curve);
            let mut points: Vec<(f64, f64)> = scene_rows
                .iter()
                .filter(|r| r.curve == *curve && r.errors.p95 > 0.0)
                .map(|r| (r.total_ms, r.errors.p95))
                .collect();
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            chart.draw_series(LineSeries::new(points.clone(), color.stroke_width(2)))?;
            let area = chart.plotting_area();
            for p in points {
                draw_marker(area, p, marker, color)?;
            }
        }
        if let Some(floor) = scene_rows.iter().find(|r| r.curve == Curve::Analytic) {
            chart.draw_series(LineSeries::new(
                vec![(floor.total_ms, e0 * 0.8), (floor.total_ms, e1 * 1.25)],
                floor_grey.stroke_width(1),
            ))?;
        }
    }
    root.present()?;
    Ok(path)
}
