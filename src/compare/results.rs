//! `compare`'s result files: CSV (one row per run, quantity and region),
//! JSON (everything) and a markdown report. The image's error (radiance
//! RMSE, FLIP) comes first everywhere; Vcoef's follows.

use super::{NoiseFloor, RegionMetrics, RunResult, SceneComparison};
use crate::error::{Error, Result};
use crate::output::write_atomically;
use crate::report::{ErrorMetrics, FlipMetrics, FlipRegions, FLIP_PPD, VISIBLE_ERROR};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

fn write_text(path: &Path, text: &str) -> Result<()> {
    write_atomically(path, |tmp| {
        std::fs::write(tmp, text.as_bytes()).map_err(|e| Error::io(tmp, e))
    })
}

/// Passes that are not the shadow technique's own.
fn is_common_pass(name: &str) -> bool {
    matches!(name, "geometry" | "gbuffer" | "shading")
}

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
    let mut s = String::from(
        "scene,technique,setting,samples,median_ms,min_ms,max_ms,runs,host,geometry_ms,gbuffer_ms,shadow_ms,shading_ms,quantity,region,count,rmse,mean_abs,max_abs,frac_over,non_finite,p50,p90,p99,pareto_flip,pareto,verify_checked,verify_disagreements,verify_beyond_tie,verify_max_tie\n",
    );
    for sc in scenes {
        for r in &sc.runs {
            let verify = r.verify.as_ref().map_or(",,,".to_string(), |v| {
                format!(
                    "{},{},{},{:e}",
                    v.checked, v.disagreements, v.beyond_tie, v.max_tie_distance
                )
            });
            let mut row = |quantity: &str, region: &str, cells: String| {
                let _ = writeln!(
                    s,
                    "{},{},{},{},{:.4},{:.4},{:.4},{},{},{:.4},{:.4},{:.4},{:.4},{},{},{cells},{},{},{verify}",
                    csv_field(&sc.scene),
                    csv_field(&r.technique),
                    csv_field(&r.setting),
                    r.samples.map_or(String::new(), |n| n.to_string()),
                    r.median_ms,
                    r.min_ms,
                    r.max_ms,
                    r.runs,
                    csv_field(&r.host),
                    r.pass_ms(|n| n == "geometry"),
                    r.pass_ms(|n| n == "gbuffer"),
                    r.pass_ms(|n| !is_common_pass(n)),
                    r.pass_ms(|n| n == "shading"),
                    quantity,
                    region,
                    r.pareto_flip,
                    r.pareto
                );
            };
            let regions = |quantity: String, m: &RegionMetrics| {
                [
                    (quantity.clone(), "all", error_cells(&m.all)),
                    (quantity.clone(), "penumbra", error_cells(&m.penumbra)),
                    (quantity, "interior", error_cells(&m.interior)),
                ]
            };
            let mut rows: Vec<(String, &str, String)> = Vec::new();
            rows.extend(regions("radiance".into(), &r.radiance));
            rows.push(("flip".into(), "all", flip_cells(&r.flip.all)));
            rows.push(("flip".into(), "interior", flip_cells(&r.flip.interior)));
            for (k, m) in r.vcoef.iter().enumerate() {
                if let Some(m) = m {
                    rows.extend(regions(format!("vcoef.{k}"), m));
                }
            }
            if let Some(m) = &r.vcoef_all_lights {
                rows.extend(regions("vcoef".into(), m));
            }
            for (quantity, region, cells) in rows {
                row(&quantity, region, cells);
            }
        }
        let floor = &sc.reference;
        let mut floor_row = |quantity: &str, f: &NoiseFloor| {
            for (region, rmse, mae) in [
                ("all", f.rmse_all, f.mae_all),
                ("penumbra", f.rmse_penumbra, f.mae_penumbra),
                ("interior", f.rmse_interior, f.mae_interior),
            ] {
                let _ = writeln!(
                    s,
                    "{},reference-floor,{} spp,{},,,,,,,,,,{},{},,{:e},{:e},,,,,,,,,,,,",
                    csv_field(&sc.scene),
                    floor.samples,
                    floor.samples,
                    quantity,
                    region,
                    rmse,
                    mae
                );
            }
        };
        floor_row("radiance", &floor.floor_radiance);
        for (k, f) in floor.floor_vcoef.iter().enumerate() {
            floor_row(&format!("vcoef.{k}"), f);
        }
        floor_row("vcoef", &floor.floor_vcoef_all_lights);
        for (region, m) in [
            ("all", &floor.flip_halves.all),
            ("interior", &floor.flip_halves.interior),
        ] {
            let _ = writeln!(
                s,
                "{},reference-halves,{} spp vs {} spp,{},,,,,,,,,,flip,{region},{},,,,,,",
                csv_field(&sc.scene),
                floor.samples / 2,
                floor.samples / 2,
                floor.samples / 2,
                flip_cells(m)
            );
        }
    }
    write_text(path, &s)
}

/// `count,rmse,mean_abs,max_abs,frac_over,non_finite,p50,p90,p99` of a
/// per-value error.
fn error_cells(m: &ErrorMetrics) -> String {
    format!(
        "{},{:e},{:e},{:e},{:e},{},,,",
        m.count, m.rmse, m.mean_abs, m.max_abs, m.frac_over, m.non_finite
    )
}

/// The same cells of a FLIP error (mean as `mean_abs`, max as `max_abs`).
fn flip_cells(m: &FlipMetrics) -> String {
    format!(
        "{},,{:e},{:e},,,{:e},{:e},{:e}",
        m.count, m.mean, m.max, m.p50, m.p90, m.p99
    )
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// Writes `results.json`: every measurement of every scene.
pub fn write_json(path: &Path, scenes: &[SceneComparison]) -> Result<()> {
    let text = serde_json::to_string_pretty(scenes)
        .map_err(|e| Error::param("results.json", e.to_string()))?;
    write_text(path, &(text + "\n"))
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
    let _ = writeln!(s, "# Error against run time\n");
    let _ = writeln!(
        s,
        "Generated by penumbra {}. Regenerate with:\n\n```sh\n{command}\n```\n",
        env!("CARGO_PKG_VERSION")
    );
    let _ = writeln!(
        s,
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
    for (sc, dir) in scenes {
        let link = |rel: &str| {
            if dir.is_empty() || dir == "." {
                rel.to_string()
            } else {
                format!("{}/{rel}", dir.trim_end_matches('/'))
            }
        };
        let _ = writeln!(
            s,
            "## {} (`{}`), {}×{}\n",
            sc.scene, sc.path, sc.width, sc.height
        );
        let pen: Vec<String> = sc
            .penumbra_points
            .iter()
            .enumerate()
            .map(|(k, &n)| {
                format!(
                    "light {k}: {n} ({})",
                    percent(n as f64 / sc.shading_points.max(1) as f64)
                )
            })
            .collect();
        let r = &sc.reference;
        let f = &r.floor_vcoef_all_lights;
        let fr = &r.floor_radiance;
        let _ = writeln!(
            s,
            "{} shading points; interior: {} ({}); in penumbra: {}.\n\nReference: {} \
             samples per light (two halves of {}), {:.1} s{}. Its noise floor: radiance \
             RMSE {} over all points, {} in the interior, {} in the penumbra; Vcoef \
             RMSE {} / {} / {}. FLIP between its two halves ({} samples each): mean {} \
             (interior {}).\n",
            sc.shading_points,
            sc.interior_points,
            percent(sc.interior_points as f64 / sc.shading_points.max(1) as f64),
            if pen.is_empty() {
                "no lights".to_string()
            } else {
                pen.join(", ")
            },
            r.samples,
            r.samples / 2,
            r.seconds,
            if r.from_cache {
                " when computed (read from the cache this time)"
            } else {
                ""
            },
            err(fr.rmse_all, None),
            err(fr.rmse_interior, None),
            err(fr.rmse_penumbra, None),
            err(f.rmse_all, None),
            err(f.rmse_interior, None),
            err(f.rmse_penumbra, None),
            r.samples / 2,
            err(r.flip_halves.all.mean, None),
            err(r.flip_halves.interior.mean, None),
        );

        // The image's error.
        let _ = writeln!(s, "### Image error\n");
        if let Some(c) = &sc.chart_flip {
            let _ = writeln!(
                s,
                "![FLIP over the whole image against time]({})\n",
                link(c)
            );
        }
        let _ = writeln!(
            s,
            "| technique | setting | time (ms) | radiance RMSE | RMSE (interior) | RMSE (penumbra) | FLIP mean | FLIP p50 / p90 / p99 | FLIP max | FLIP mean (interior) | FLIP p50 / p90 / p99 (interior) | Pareto |"
        );
        let _ = writeln!(s, "|---|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|:-:|");
        for run in &sc.runs {
            image_row(&mut s, run, sc);
        }
        let _ = writeln!(s);
        let charts: Vec<String> = [
            ("FLIP in the interior", &sc.chart_flip_interior),
            ("radiance RMSE", &sc.chart_radiance),
        ]
        .iter()
        .filter_map(|(what, c)| c.as_ref().map(|c| format!("[{what}]({})", link(c))))
        .collect();
        if !charts.is_empty() {
            let _ = writeln!(s, "Against time, also: {}.\n", charts.join(", "));
        }

        // Visibility.
        let _ = writeln!(s, "### Visibility (Vcoef)\n");
        if let Some(c) = &sc.chart {
            let _ = writeln!(
                s,
                "![Vcoef error in the penumbra against time]({})\n",
                link(c)
            );
        }
        // The `--verify` column only when something was verified.
        let verified = sc.runs.iter().any(|r| r.verify.is_some());
        let _ = writeln!(
            s,
            "| technique | setting | time (ms) | G-buffer | shadows | shading | Vcoef RMSE | Vcoef RMSE (penumbra) | MAE (penumbra) | max abs | > 1/255 (penumbra) | Vcoef RMSE (interior) | Pareto |{}",
            if verified { " verify: disagreeing / checked (beyond tie), max tie |" } else { "" }
        );
        let _ = writeln!(
            s,
            "|---|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|:-:|{}",
            if verified { "--:|" } else { "" }
        );
        for run in &sc.runs {
            vcoef_row(&mut s, run, sc);
            if verified {
                // `vcoef_row` ends the line with `|\n`: append the cell.
                s.pop();
                let cell = run.verify.as_ref().map_or("—".to_string(), |v| v.cell());
                let _ = writeln!(s, " {cell} |");
            }
        }
        let _ = writeln!(s);
        // A sharded sweep's times come from several machines: say which.
        let mut hosts: Vec<&str> = sc.runs.iter().map(|r| r.host.as_str()).collect();
        hosts.sort_unstable();
        hosts.dedup();
        if hosts.len() > 1 {
            let _ = writeln!(
                s,
                "Times measured on {} hosts ({}); results.csv names each run's.\n",
                hosts.len(),
                hosts.join(", ")
            );
        }
        if let Some(c) = &sc.chart_all {
            let _ = writeln!(
                s,
                "Over all shading points: ![Vcoef error over all shading points against time]({})\n",
                link(c)
            );
        }
    }
    write_text(path, &s)
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
