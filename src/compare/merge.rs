//! `compare --merge DIR...`: the partial results of a sharded sweep
//! ([`shard`](super::shard)) joined into the results an unsharded run
//! writes, through the same code ([`finish_scene`](super::finish_scene)
//! for the Pareto front and charts, [`write_results`](super::write_results)
//! for the tables).
//!
//! Refused, with the reason: partials of another format or crate version,
//! of other options or scene contents, of another shard count or plan, the
//! same shard twice; and a sweep with runs missing, naming each missing
//! shard (or the shard that stopped early) with its runs, so that re-running
//! just those shards completes it.

use super::charts::slug;
use super::shard::{Partial, PartialRun, PARTIAL_FORMAT};
use super::{finish_scene, scene_dir, SceneComparison};
use crate::error::{Error, Result};
use crate::output::write_atomically;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The merged sweep.
#[derive(Debug, Clone)]
pub struct Merged {
    /// Each scene's comparison with its output directory (under `out`).
    pub results: Vec<(SceneComparison, PathBuf)>,
    /// The equivalent unsharded command line.
    pub command: String,
    /// Partials merged.
    pub partials: usize,
}

/// `shard-I-of-N.json` → (I, N).
fn parse_name(name: &str) -> Option<(u32, u32)> {
    let rest = name.strip_prefix("shard-")?.strip_suffix(".json")?;
    let (i, n) = rest.split_once("-of-")?;
    Some((i.parse().ok()?, n.parse().ok()?))
}

/// Reads every partial in `dirs`, with the directory each came from.
fn read_partials(dirs: &[PathBuf]) -> Result<Vec<(Partial, PathBuf, PathBuf)>> {
    let mut found = Vec::new();
    for dir in dirs {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .map_err(|e| Error::io(dir, e))?
            .filter_map(|e| e.ok())
            .filter_map(|e| e.file_name().into_string().ok())
            .filter(|n| parse_name(n).is_some())
            .collect();
        names.sort();
        if names.is_empty() {
            return Err(Error::param(
                "--merge",
                format!(
                    "{} holds no partial results (shard-I-of-N.json, written by compare --shard I/N --out {})",
                    dir.display(),
                    dir.display()
                ),
            ));
        }
        for name in names {
            let path = dir.join(&name);
            let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
            // The format first: a partial of another format is refused as
            // such (re-run its shard), not read with missing figures.
            #[derive(serde::Deserialize)]
            struct Format {
                format: u32,
            }
            if let Ok(Format { format }) = serde_json::from_str::<Format>(&text) {
                if format != PARTIAL_FORMAT {
                    return Err(Error::file(
                        &path,
                        None,
                        format!(
                            "partial format {format} (this penumbra reads {PARTIAL_FORMAT}): \
                             re-run this shard with this penumbra"
                        ),
                    ));
                }
            }
            let partial: Partial = serde_json::from_str(&text).map_err(|e| {
                Error::file(
                    &path,
                    Some(e.line()),
                    format!("not a partial result of compare --shard: {e}"),
                )
            })?;
            if parse_name(&name) != Some((partial.shard, partial.shards)) {
                return Err(Error::file(
                    &path,
                    None,
                    format!(
                        "holds shard {}/{}, not what its name says",
                        partial.shard, partial.shards
                    ),
                ));
            }
            found.push((partial, path, dir.clone()));
        }
    }
    Ok(found)
}

/// Refuses partials that are not of one sweep, with the reason.
fn check_same_sweep(partials: &[(Partial, PathBuf, PathBuf)]) -> Result<()> {
    let (first, first_path, _) = &partials[0];
    let refuse = |path: &Path, what: String| {
        Err(Error::param(
            "--merge",
            format!(
                "{} and {} are not of the same sweep: {what}",
                first_path.display(),
                path.display()
            ),
        ))
    };
    for (p, path, _) in partials {
        if p.format != PARTIAL_FORMAT || first.format != PARTIAL_FORMAT {
            return Err(Error::file(
                path,
                None,
                format!(
                    "partial format {} (this penumbra reads {PARTIAL_FORMAT})",
                    p.format
                ),
            ));
        }
        if p.version != first.version {
            return refuse(
                path,
                format!("written by penumbra {} and {}", first.version, p.version),
            );
        }
        if p.shards != first.shards {
            return refuse(
                path,
                format!(
                    "shards of a sweep in {} and in {} (clear out the older partials)",
                    first.shards, p.shards
                ),
            );
        }
        for ((k, a), (k2, b)) in first.options.iter().zip(&p.options) {
            if k != k2 || a != b {
                return refuse(path, format!("{k} was {a} and {b}"));
            }
        }
        if first.options.len() != p.options.len() {
            return refuse(path, "different option sets".into());
        }
        if first.scenes.len() != p.scenes.len() {
            return refuse(
                path,
                format!("{} and {} scenes", first.scenes.len(), p.scenes.len()),
            );
        }
        for (a, b) in first.scenes.iter().zip(&p.scenes) {
            if a.name != b.name {
                return refuse(path, format!("scene {} and scene {}", a.name, b.name));
            }
            if a.hash != b.hash {
                return refuse(
                    path,
                    format!(
                        "scene {} has different contents (hash {} from {}, {} from {})",
                        a.name, a.hash, a.path, b.hash, b.path
                    ),
                );
            }
        }
        if p.plan != first.plan {
            return refuse(path, "different plans of runs".into());
        }
    }
    Ok(())
}

/// Checks that the image `src` a partial result owes is there, as a
/// regular file.
fn check_source(src: &Path) -> Result<()> {
    match std::fs::metadata(src) {
        Ok(m) if m.is_file() => Ok(()),
        Ok(_) => Err(Error::file(
            src,
            None,
            "a partial result owes this image, but it is not a regular file",
        )),
        Err(e) => Err(Error::io(
            src,
            std::io::Error::new(
                e.kind(),
                format!("a partial result owes this image, but it cannot be read: {e}"),
            ),
        )),
    }
}

/// The image and heat maps a run writes (relative to its scene's
/// directory), derived from the run itself as `compare` names them:
/// a partial's own names are never used as paths, only checked against
/// these (a merge must not follow `../` out of the shard or `--out`).
fn run_files(r: &PartialRun) -> (String, Vec<String>) {
    let result = r.to_result();
    let stem = slug(&format!("{}-{}", result.technique, result.setting));
    let heatmaps = result
        .vcoef
        .iter()
        .enumerate()
        .filter(|(_, v)| v.is_some())
        .map(|(k, _)| format!("heatmaps/{stem}.vcoef{k}.png"))
        .collect();
    (format!("images/{stem}.png"), heatmaps)
}

/// Copies `src` to `dst` (atomically), unless they are the same file.
fn copy_file(src: &Path, dst: &Path) -> Result<()> {
    if let (Ok(a), Ok(b)) = (std::fs::canonicalize(src), std::fs::canonicalize(dst)) {
        if a == b {
            return Ok(());
        }
    }
    if let Some(parent) = dst.parent() {
        std::fs::create_dir_all(parent).map_err(|e| Error::io(parent, e))?;
    }
    write_atomically(dst, |tmp| {
        std::fs::copy(src, tmp)
            .map(|_| ())
            .map_err(|e| Error::io(src, e))
    })
}

/// Merges the partial results in `dirs` into `out`: per scene its images
/// and heat maps (unless `!images`), charts and Pareto front; returns the
/// comparisons for [`write_results`](super::write_results).
pub fn merge_partials(dirs: &[PathBuf], out: &Path, images: bool) -> Result<Merged> {
    if dirs.is_empty() {
        return Err(Error::param("--merge", "name at least one directory"));
    }
    let mut partials = read_partials(dirs)?;
    check_same_sweep(&partials)?;
    partials.sort_by_key(|(p, _, _)| p.shard);
    for w in partials.windows(2) {
        if w[0].0.shard == w[1].0.shard {
            return Err(Error::param(
                "--merge",
                format!(
                    "shard {}/{} is there twice: {} and {} (keep one)",
                    w[0].0.shard,
                    w[0].0.shards,
                    w[0].1.display(),
                    w[1].1.display()
                ),
            ));
        }
    }
    let first = &partials[0].0;
    let (shards, plan, scenes) = (first.shards, first.plan.clone(), first.scenes.clone());

    // Every run of the plan, found exactly once, in its own shard.
    let mut done: BTreeMap<(usize, usize), (&PartialRun, usize)> = BTreeMap::new();
    for (k, (p, path, _)) in partials.iter().enumerate() {
        for r in &p.runs {
            let owner = plan
                .iter()
                .find(|e| (e.scene, e.index) == (r.scene, r.index))
                .map(|e| e.shard);
            if owner != Some(p.shard) || done.insert((r.scene, r.index), (r, k)).is_some() {
                return Err(Error::file(
                    path,
                    None,
                    format!(
                        "holds run {} {} of scene {} that is not shard {}'s own",
                        r.technique, r.setting, r.scene, p.shard
                    ),
                ));
            }
        }
    }
    let mut missing = String::new();
    for i in 1..=shards {
        let owed: Vec<String> = plan
            .iter()
            .filter(|e| e.shard == i && !done.contains_key(&(e.scene, e.index)))
            .map(|e| format!("{}: {} {}", scenes[e.scene].name, e.technique, e.setting))
            .collect();
        if owed.is_empty() {
            continue;
        }
        let total = plan.iter().filter(|e| e.shard == i).count();
        let why = match partials.iter().find(|(p, _, _)| p.shard == i) {
            None => {
                format!("no partial result (shard-{i}-of-{shards}.json in none of the directories)")
            }
            Some((_, path, _)) => format!(
                "{} stopped after {} of its {total} runs",
                path.display(),
                total - owed.len()
            ),
        };
        let _ = writeln!(
            missing,
            "  shard {i}/{shards}: {why}; missing {} run(s): {}",
            owed.len(),
            owed.join("; ")
        );
    }
    if !missing.is_empty() {
        return Err(Error::param(
            "--merge",
            format!(
                "the sweep is incomplete:\n{missing}re-run only these shards \
                 (the same compare command with --shard I/{shards}), then merge again"
            ),
        ));
    }
    if images {
        if let Some((p, path, _)) = partials.iter().find(|(p, _, _)| !p.images) {
            return Err(Error::param(
                "--merge",
                format!(
                    "shard {}/{} ({}) was run with --no-images: merge with --no-images",
                    p.shard,
                    p.shards,
                    path.display()
                ),
            ));
        }
    }

    // Everything is checked before anything is written, so that a refused
    // merge leaves no half-filled --out: first the runs, images and heat
    // maps of every scene, then the copies, then the charts.
    let mut scenes_done = Vec::new();
    let mut copies: Vec<(PathBuf, PathBuf)> = Vec::new();
    for (s, id) in scenes.iter().enumerate() {
        let dir = scene_dir(out, &id.name, scenes.len());
        // Derived, like the file names, not read from the partial.
        let rel_dir = scene_dir(Path::new(""), &id.name, scenes.len());
        // The header of the shard that computed the reference (its time is
        // the reference's), else of the first that read it.
        let with_header: Vec<(usize, &super::shard::PartialScene)> = partials
            .iter()
            .enumerate()
            .filter_map(|(k, (p, _, _))| p.headers[s].as_ref().map(|h| (k, h)))
            .collect();
        let header = with_header
            .iter()
            .find(|(_, h)| !h.from_cache)
            .or(with_header.first())
            .map(|&(k, h)| (k, h.to_header()));
        let Some((header_from, header)) = header else {
            // A scene without runs (no technique had a setting).
            continue;
        };
        let mut runs = Vec::new();
        for e in plan.iter().filter(|e| e.scene == s) {
            let (r, k) = done[&(e.scene, e.index)];
            let mut result = r.to_result();
            let src = partials[k].2.join(&rel_dir);
            if images {
                let (image, heatmaps) = run_files(r);
                if result.image.as_ref() != Some(&image) || result.heatmaps != heatmaps {
                    return Err(Error::file(
                        &partials[k].1,
                        None,
                        format!(
                            "run {} {} names its image and heat maps {:?} {:?}, not the \
                             {image:?} {heatmaps:?} compare writes: the partial result is \
                             damaged or edited",
                            r.technique, r.setting, result.image, result.heatmaps
                        ),
                    ));
                }
                for rel in std::iter::once(&image).chain(&heatmaps) {
                    check_source(&src.join(rel))?;
                    copies.push((src.join(rel), dir.join(rel)));
                }
            } else {
                result.image = None;
                result.heatmaps.clear();
            }
            runs.push(result);
        }
        if images {
            let rel = "images/reference.png";
            let src = partials[header_from].2.join(&rel_dir).join(rel);
            check_source(&src)?;
            copies.push((src, dir.join(rel)));
        }
        scenes_done.push((header, runs, dir));
    }
    for (src, dst) in &copies {
        copy_file(src, dst)?;
    }
    let mut results = Vec::new();
    for (header, runs, dir) in scenes_done {
        results.push((finish_scene(header, runs, &dir)?, dir));
    }
    Ok(Merged {
        results,
        command: first.command.clone(),
        partials: partials.len(),
    })
}
