//! `compare`'s result files: CSV (one row per run, quantity and region),
//! JSON (everything) and a markdown report. The image's error (radiance
//! RMSE, FLIP) comes first everywhere; Vcoef's follows.

use super::model::{NoiseFloor, RegionMetrics, RunResult, SceneComparison};
use crate::error::{Error, Result};
use crate::output::write_atomically;
use crate::report::{ErrorMetrics, FlipMetrics, FlipRegions, FLIP_PPD, VISIBLE_ERROR};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

fn write_bytes(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomically(path, |tmp| {
        std::fs::write(tmp, bytes).map_err(|e| Error::io(tmp, e))
    })
}

/// Passes that are not the shadow technique's own.
fn is_common_pass(name: &str) -> bool {
    matches!(name, "geometry" | "gbuffer" | "shading")
}

/// The columns of `results.csv`.
const CSV_COLUMNS: [&str; 30] = [
    "scene",
    "technique",
    "setting",
    "samples",
    "median_ms",
    "min_ms",
    "max_ms",
    "runs",
    "host",
    "geometry_ms",
    "gbuffer_ms",
    "shadow_ms",
    "shading_ms",
    "quantity",
    "region",
    "count",
    "rmse",
    "mean_abs",
    "max_abs",
    "frac_over",
    "non_finite",
    "p50",
    "p90",
    "p99",
    "pareto_flip",
    "pareto",
    "verify_checked",
    "verify_disagreements",
    "verify_beyond_tie",
    "verify_max_tie",
];

/// `results.csv` being written: quoted only where a cell needs it (a
/// comma, quote or line break), records ended by `\n`.
type CsvTable = csv::Writer<Vec<u8>>;

/// Writes `results.csv`: one row per (scene, run, quantity, region), and
/// rows for each reference's noise floor (technique `reference-floor`)
/// and FLIP between its halves (technique `reference-halves`).
///
/// Quantities, in this order: `radiance` and `flip` (the image's error),
/// then `vcoef.<k>` per light and `vcoef` (all lights). Regions: `all`
/// (every shading point; for `flip` the whole frame), `penumbra` (not for
/// `flip`) and `interior`. A `flip` row's `mean_abs` is the FLIP mean,
/// `max_abs` its maximum and `p50, p90, p99` its percentiles (empty in
/// other rows); its `rmse`, `frac_over` and `non_finite` are empty.
pub fn write_csv(path: &Path, scenes: &[SceneComparison]) -> Result<()> {
    let csv_error = |e: csv::Error| Error::param("results.csv", e.to_string());
    let mut table = csv::WriterBuilder::new()
        .quote_style(csv::QuoteStyle::Necessary)
        .terminator(csv::Terminator::Any(b'\n'))
        .from_writer(Vec::new());
    table.write_record(CSV_COLUMNS).map_err(csv_error)?;
    for sc in scenes {
        for run in &sc.runs {
            write_run_rows(&mut table, sc, run).map_err(csv_error)?;
        }
        write_reference_rows(&mut table, sc).map_err(csv_error)?;
    }
    let bytes = table
        .into_inner()
        .map_err(|e| Error::param("results.csv", e.to_string()))?;
    write_bytes(path, &bytes)
}

/// A run's rows: radiance and FLIP, then Vcoef per light and over all
/// lights, each per region.
fn write_run_rows(
    table: &mut CsvTable,
    scene: &SceneComparison,
    run: &RunResult,
) -> csv::Result<()> {
    let run_cells: [String; 13] = [
        scene.scene.clone(),
        run.technique.clone(),
        run.setting.clone(),
        run.samples.map_or(String::new(), |n| n.to_string()),
        format!("{:.4}", run.median_ms),
        format!("{:.4}", run.min_ms),
        format!("{:.4}", run.max_ms),
        run.runs.to_string(),
        run.host.clone(),
        format!("{:.4}", run.pass_ms(|n| n == "geometry")),
        format!("{:.4}", run.pass_ms(|n| n == "gbuffer")),
        format!("{:.4}", run.pass_ms(|n| !is_common_pass(n))),
        format!("{:.4}", run.pass_ms(|n| n == "shading")),
    ];
    let pareto_cells = [run.pareto_flip.to_string(), run.pareto.to_string()];
    let verify_cells: [String; 4] = run.verify.as_ref().map_or(Default::default(), |verify| {
        [
            verify.checked.to_string(),
            verify.disagreements.to_string(),
            verify.beyond_tie.to_string(),
            format!("{:e}", verify.max_tie_distance),
        ]
    });
    let regions = |quantity: String, metrics: &RegionMetrics| {
        [
            (quantity.clone(), "all", error_cells(&metrics.all)),
            (quantity.clone(), "penumbra", error_cells(&metrics.penumbra)),
            (quantity, "interior", error_cells(&metrics.interior)),
        ]
    };
    let mut rows: Vec<(String, &str, [String; 9])> = Vec::new();
    rows.extend(regions("radiance".into(), &run.radiance));
    rows.push(("flip".into(), "all", flip_cells(&run.flip.all)));
    rows.push(("flip".into(), "interior", flip_cells(&run.flip.interior)));
    for (light, metrics) in run.vcoef.iter().enumerate() {
        if let Some(metrics) = metrics {
            rows.extend(regions(format!("vcoef.{light}"), metrics));
        }
    }
    if let Some(metrics) = &run.vcoef_all_lights {
        rows.extend(regions("vcoef".into(), metrics));
    }
    for (quantity, region, cells) in &rows {
        table.write_record(
            run_cells
                .iter()
                .map(String::as_str)
                .chain([quantity.as_str(), region])
                .chain(cells.iter().map(String::as_str))
                .chain(pareto_cells.iter().map(String::as_str))
                .chain(verify_cells.iter().map(String::as_str)),
        )?;
    }
    Ok(())
}

/// The reference's rows: its noise floors (radiance, Vcoef per light and
/// over all lights, per region), then FLIP between its halves.
fn write_reference_rows(table: &mut CsvTable, scene: &SceneComparison) -> csv::Result<()> {
    let reference = &scene.reference;
    // A reference row: the run columns empty after the setting and
    // samples, no Pareto or verify cells.
    let mut reference_row = |technique: &str,
                             setting: String,
                             samples: u32,
                             quantity: &str,
                             region: &str,
                             cells: [String; 9]| {
        table.write_record(
            [
                scene.scene.as_str(),
                technique,
                &setting,
                &samples.to_string(),
            ]
            .into_iter()
            .chain([""; 9])
            .chain([quantity, region])
            .chain(cells.iter().map(String::as_str))
            .chain([""; 6]),
        )
    };
    let mut floor_rows = |quantity: &str, floor: &NoiseFloor| -> csv::Result<()> {
        for (region, rmse, mae) in [
            ("all", floor.rmse_all, floor.mae_all),
            ("penumbra", floor.rmse_penumbra, floor.mae_penumbra),
            ("interior", floor.rmse_interior, floor.mae_interior),
        ] {
            let cells = [
                String::new(),
                format!("{rmse:e}"),
                format!("{mae:e}"),
                String::new(),
                String::new(),
                String::new(),
                String::new(),
                String::new(),
                String::new(),
            ];
            reference_row(
                "reference-floor",
                format!("{} spp", reference.samples),
                reference.samples,
                quantity,
                region,
                cells,
            )?;
        }
        Ok(())
    };
    floor_rows("radiance", &reference.floor_radiance)?;
    for (light, floor) in reference.floor_vcoef.iter().enumerate() {
        floor_rows(&format!("vcoef.{light}"), floor)?;
    }
    floor_rows("vcoef", &reference.floor_vcoef_all_lights)?;
    let half = reference.samples / 2;
    for (region, metrics) in [
        ("all", &reference.flip_halves.all),
        ("interior", &reference.flip_halves.interior),
    ] {
        reference_row(
            "reference-halves",
            format!("{half} spp vs {half} spp"),
            half,
            "flip",
            region,
            flip_cells(metrics),
        )?;
    }
    Ok(())
}

/// `count,rmse,mean_abs,max_abs,frac_over,non_finite,p50,p90,p99` of a
/// per-value error.
fn error_cells(m: &ErrorMetrics) -> [String; 9] {
    [
        m.count.to_string(),
        format!("{:e}", m.rmse),
        format!("{:e}", m.mean_abs),
        format!("{:e}", m.max_abs),
        format!("{:e}", m.frac_over),
        m.non_finite.to_string(),
        String::new(),
        String::new(),
        String::new(),
    ]
}

/// The same cells of a FLIP error (mean as `mean_abs`, max as `max_abs`).
fn flip_cells(m: &FlipMetrics) -> [String; 9] {
    [
        m.count.to_string(),
        String::new(),
        format!("{:e}", m.mean),
        format!("{:e}", m.max),
        String::new(),
        String::new(),
        format!("{:e}", m.p50),
        format!("{:e}", m.p90),
        format!("{:e}", m.p99),
    ]
}

/// Writes `results.json`: every measurement of every scene.
pub fn write_json(path: &Path, scenes: &[SceneComparison]) -> Result<()> {
    let text = serde_json::to_string_pretty(scenes)
        .map_err(|e| Error::param("results.json", e.to_string()))?;
    write_bytes(path, (text + "\n").as_bytes())
}

/// An error figure, marked with `*` when at or below the reference's noise
/// floor (the reference cannot resolve it).
fn err(x: f64, floor: Option<f64>) -> String {
    let mark = match floor {
        Some(f) if x <= f => "*",
        _ => "",
    };
    let v = if x == 0.0 {
        "0".to_string()
    } else if !x.is_finite() {
        format!("{x}")
    } else if x < 1e-3 {
        format!("{x:.2e}")
    } else {
        format!("{x:.4}")
    };
    v + mark
}

fn percent(x: f64) -> String {
    format!("{:.2} %", x * 100.0)
}

/// Writes the markdown report. `scenes` pairs each comparison with the path
/// of its output directory relative to the report's directory (for image
/// links); `command` is the command line that regenerates the report.
///
/// Per scene, the image's error first (radiance RMSE and FLIP, with the
/// FLIP-vs-time chart), then the visibility (Vcoef) table.
pub fn write_markdown(
    path: &Path,
    scenes: &[(SceneComparison, String)],
    command: &str,
) -> Result<()> {
    let mut s = String::new();
    markdown_intro(&mut s, command);
    for (sc, dir) in scenes {
        scene_summary(&mut s, sc);
        image_section(&mut s, sc, dir);
        visibility_section(&mut s, sc, dir);
    }
    write_bytes(path, s.as_bytes())
}

/// The report's title, how to regenerate it and what its figures mean.
fn markdown_intro(out: &mut String, command: &str) {
    let _ = writeln!(out, "# Error against run time\n");
    let _ = writeln!(
        out,
        "Generated by penumbra {}. Regenerate with:\n\n```sh\n{command}\n```\n",
        env!("CARGO_PKG_VERSION")
    );
    let _ = writeln!(
        out,
        "Each technique renders the scene at the same receiver points (the same \
         G-buffer) as the ray-traced reference. Times are wall-clock medians of \
         whole renders (scene loading excluded) on this machine.\n\n\
         **The image's error** comes first: the RMSE of linear radiance (R, G, B \
         together) over all shading points, over the interior and over the \
         penumbra, and FLIP (NVlabs' perceptual error, 0 to 1) between the image \
         and the reference's, both tone-mapped as the PNG output (clamped to \
         [0, 1], sRGB, 8-bit) and seen at {FLIP_PPD} pixels per degree: its mean, \
         percentiles and maximum over the whole frame and over the interior. The \
         interior is the shading points farther than 2 pixels from the background \
         and from depth and normal discontinuities, where the error is the \
         shading's rather than a silhouette's. Pareto (image): no other run is \
         both faster and lower in FLIP mean.\n\n\
         **Visibility** follows: the shares of the geometry + G-buffer passes, \
         the shadow technique's passes and shading, and RMSE / mean absolute / \
         max absolute error of the visibility coefficient (Vcoef, all lights \
         together) over all shading points, over the penumbra only (pixels whose \
         reference Vcoef is strictly between 0 and 1, as Atty et al. measure) and \
         over the interior; \"> 1/255\" is the share of penumbra values off by \
         more than {VISIBLE_ERROR:.5}. Pareto (Vcoef): no other run is both faster \
         and more accurate in the penumbra.\n\n\
         A `*` marks an error at or below the reference's own noise floor \
         (estimated from two independent half-sample references): the reference \
         cannot tell it from zero.\n"
    );
}

/// `rel` (relative to a scene's directory) as a link from the report:
/// under `dir`, the scene's directory relative to the report's.
fn link(dir: &str, rel: &str) -> String {
    if dir.is_empty() || dir == "." {
        rel.to_string()
    } else {
        format!("{}/{rel}", dir.trim_end_matches('/'))
    }
}

/// A scene's heading and summary: shading points, interior, penumbra per
/// light, and the reference with its noise floor.
fn scene_summary(out: &mut String, scene: &SceneComparison) {
    let _ = writeln!(
        out,
        "## {} (`{}`), {}×{}\n",
        scene.scene, scene.path, scene.width, scene.height
    );
    let penumbra: Vec<String> = scene
        .penumbra_points
        .iter()
        .enumerate()
        .map(|(k, &n)| {
            format!(
                "light {k}: {n} ({})",
                percent(n as f64 / scene.shading_points.max(1) as f64)
            )
        })
        .collect();
    let reference = &scene.reference;
    let floor_vcoef = &reference.floor_vcoef_all_lights;
    let floor_radiance = &reference.floor_radiance;
    let _ = writeln!(
        out,
        "{} shading points; interior: {} ({}); in penumbra: {}.\n\nReference: {} \
         samples per light (two halves of {}), {:.1} s{}. Its noise floor: radiance \
         RMSE {} over all points, {} in the interior, {} in the penumbra; Vcoef \
         RMSE {} / {} / {}. FLIP between its two halves ({} samples each): mean {} \
         (interior {}).\n",
        scene.shading_points,
        scene.interior_points,
        percent(scene.interior_points as f64 / scene.shading_points.max(1) as f64),
        if penumbra.is_empty() {
            "no lights".to_string()
        } else {
            penumbra.join(", ")
        },
        reference.samples,
        reference.samples / 2,
        reference.seconds,
        if reference.from_cache {
            " when computed (read from the cache this time)"
        } else {
            ""
        },
        err(floor_radiance.rmse_all, None),
        err(floor_radiance.rmse_interior, None),
        err(floor_radiance.rmse_penumbra, None),
        err(floor_vcoef.rmse_all, None),
        err(floor_vcoef.rmse_interior, None),
        err(floor_vcoef.rmse_penumbra, None),
        reference.samples / 2,
        err(reference.flip_halves.all.mean, None),
        err(reference.flip_halves.interior.mean, None),
    );
}

/// A scene's image error: the FLIP chart, one row per run, links to the
/// other image charts.
fn image_section(out: &mut String, scene: &SceneComparison, dir: &str) {
    let _ = writeln!(out, "### Image error\n");
    if let Some(chart) = &scene.chart_flip {
        let _ = writeln!(
            out,
            "![FLIP over the whole image against time]({})\n",
            link(dir, chart)
        );
    }
    let _ = writeln!(
        out,
        "| technique | setting | time (ms) | radiance RMSE | RMSE (interior) | RMSE (penumbra) | FLIP mean | FLIP p50 / p90 / p99 | FLIP max | FLIP mean (interior) | FLIP p50 / p90 / p99 (interior) | Pareto |"
    );
    let _ = writeln!(out, "|---|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|:-:|");
    for run in &scene.runs {
        image_row(out, run, scene);
    }
    let _ = writeln!(out);
    let charts: Vec<String> = [
        ("FLIP in the interior", &scene.chart_flip_interior),
        ("radiance RMSE", &scene.chart_radiance),
    ]
    .iter()
    .filter_map(|(what, chart)| {
        chart
            .as_ref()
            .map(|chart| format!("[{what}]({})", link(dir, chart)))
    })
    .collect();
    if !charts.is_empty() {
        let _ = writeln!(out, "Against time, also: {}.\n", charts.join(", "));
    }
}

/// A scene's visibility (Vcoef) error: the chart, one row per run (with
/// `--verify`'s column when something was verified), the hosts that timed
/// the runs when several, and the chart over all shading points.
fn visibility_section(out: &mut String, scene: &SceneComparison, dir: &str) {
    let _ = writeln!(out, "### Visibility (Vcoef)\n");
    if let Some(chart) = &scene.chart {
        let _ = writeln!(
            out,
            "![Vcoef error in the penumbra against time]({})\n",
            link(dir, chart)
        );
    }
    // The `--verify` column only when something was verified.
    let verified = scene.runs.iter().any(|run| run.verify.is_some());
    let _ = writeln!(
        out,
        "| technique | setting | time (ms) | G-buffer | shadows | shading | Vcoef RMSE | Vcoef RMSE (penumbra) | MAE (penumbra) | max abs | > 1/255 (penumbra) | Vcoef RMSE (interior) | Pareto |{}",
        if verified { " verify: disagreeing / checked (beyond tie), max tie |" } else { "" }
    );
    let _ = writeln!(
        out,
        "|---|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|:-:|{}",
        if verified { "--:|" } else { "" }
    );
    for run in &scene.runs {
        vcoef_row(out, run, scene);
        if verified {
            // `vcoef_row` ends the line with `|\n`: append the cell.
            out.pop();
            let cell = run.verify.as_ref().map_or("—".to_string(), |v| v.cell());
            let _ = writeln!(out, " {cell} |");
        }
    }
    let _ = writeln!(out);
    // A sharded sweep's times come from several machines: say which.
    let mut hosts: Vec<&str> = scene.runs.iter().map(|run| run.host.as_str()).collect();
    hosts.sort_unstable();
    hosts.dedup();
    if hosts.len() > 1 {
        let _ = writeln!(
            out,
            "Times measured on {} hosts ({}); results.csv names each run's.\n",
            hosts.len(),
            hosts.join(", ")
        );
    }
    if let Some(chart) = &scene.chart_all {
        let _ = writeln!(
            out,
            "Over all shading points: ![Vcoef error over all shading points against time]({})\n",
            link(dir, chart)
        );
    }
}

/// `p50 / p90 / p99` of a FLIP error.
fn percentiles(m: &FlipMetrics) -> String {
    format!(
        "{} / {} / {}",
        err(m.p50, None),
        err(m.p90, None),
        err(m.p99, None)
    )
}

/// A run's row of the image-error table.
fn image_row(s: &mut String, run: &RunResult, sc: &SceneComparison) {
    let fr = &sc.reference.floor_radiance;
    let FlipRegions { all, interior } = &run.flip;
    let _ = writeln!(
        s,
        "| {} | {} | {:.1} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
        run.technique,
        run.setting,
        run.median_ms,
        err(run.radiance.all.rmse, Some(fr.rmse_all)),
        err(run.radiance.interior.rmse, Some(fr.rmse_interior)),
        err(run.radiance.penumbra.rmse, Some(fr.rmse_penumbra)),
        err(all.mean, None),
        percentiles(all),
        err(all.max, None),
        err(interior.mean, None),
        percentiles(interior),
        if run.pareto_flip { "●" } else { "" }
    );
}

/// A run's row of the visibility table.
fn vcoef_row(s: &mut String, run: &RunResult, sc: &SceneComparison) {
    let f = &sc.reference.floor_vcoef_all_lights;
    let (rmse, rmse_p, mae_p, max, over, rmse_i) = match &run.vcoef_all_lights {
        Some(m) => (
            err(m.all.rmse, Some(f.rmse_all)),
            err(m.penumbra.rmse, Some(f.rmse_penumbra)),
            err(m.penumbra.mean_abs, Some(f.mae_penumbra)),
            err(m.all.max_abs, None),
            percent(m.penumbra.frac_over),
            err(m.interior.rmse, Some(f.rmse_interior)),
        ),
        None => Default::default(),
    };
    let _ = writeln!(
        s,
        "| {} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {rmse} | {rmse_p} | {mae_p} | {max} | {over} | {rmse_i} | {} |",
        run.technique,
        run.setting,
        run.median_ms,
        run.pass_ms(|n| n == "gbuffer" || n == "geometry"),
        run.pass_ms(|n| !is_common_pass(n)),
        run.pass_ms(|n| n == "shading"),
        if run.pareto { "●" } else { "" }
    );
}

/// Writes `results.csv`, `results.json` and `results.md` into `out` and,
/// with `report`, the markdown report there too (links relative to it).
/// `scenes` pairs each comparison with its output directory. The one
/// writer of `compare`'s tables, for a whole run and for merged shards.
pub fn write_results(
    out: &Path,
    scenes: &[(SceneComparison, PathBuf)],
    report: Option<&Path>,
    command: &str,
) -> Result<()> {
    let comparisons: Vec<SceneComparison> = scenes.iter().map(|(r, _)| r.clone()).collect();
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    write_csv(&out.join("results.csv"), &comparisons)?;
    write_json(&out.join("results.json"), &comparisons)?;
    let linked = |base: &Path| -> Vec<(SceneComparison, String)> {
        scenes
            .iter()
            .map(|(r, dir)| (r.clone(), relative_path(base, dir)))
            .collect()
    };
    write_markdown(&out.join("results.md"), &linked(out), command)?;
    if let Some(report) = report {
        let base = match report.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        write_markdown(report, &linked(&base), command)?;
    }
    Ok(())
}

/// `--verify`: an error for the first run that declares itself exact and
/// disagrees beyond the tie distance (inexact settings are expected to
/// disagree).
pub fn check_verified(scenes: &[(SceneComparison, PathBuf)]) -> Result<()> {
    for (r, _) in scenes {
        for run in &r.runs {
            if let Some(v) = run.verify.as_ref().filter(|v| v.declared_exact) {
                v.check().map_err(|e| {
                    Error::param("--verify", format!("{} ({}): {e}", r.scene, run.setting))
                })?;
            }
        }
    }
    Ok(())
}

/// `target` relative to `base` (both relative to the working directory or
/// both absolute), for links in reports.
fn relative_path(base: &Path, target: &Path) -> String {
    let abs = |p: &Path| std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf());
    let (base, target) = (abs(base), abs(target));
    let b: Vec<_> = base.components().collect();
    let t: Vec<_> = target.components().collect();
    let common = b.iter().zip(&t).take_while(|(x, y)| x == y).count();
    let mut rel = PathBuf::new();
    for _ in common..b.len() {
        rel.push("..");
    }
    for c in &t[common..] {
        rel.push(c);
    }
    let s = rel.display().to_string();
    if s.is_empty() {
        ".".into()
    } else {
        s
    }
}
