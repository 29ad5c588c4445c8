//! `compare --merge DIR...`: the partial results of a sharded sweep
//! ([`shard`](super::shard)) joined into the results an unsharded run
//! writes, through the same code ([`finish_scene`](super::pipeline::finish_scene)
//! for the Pareto front and charts, [`write_results`](super::write_results)
//! for the tables).
//!
//! Refused, with the reason: partials of another format or crate version,
//! of other options or scene contents, of another shard count or plan, the
//! same shard twice; and a sweep with runs missing, naming each missing
//! shard (or the shard that stopped early) with its runs, so that re-running
//! just those shards completes it.

use super::charts::slug;
use super::model::RunResult;
use super::model::SceneComparison;
use super::pipeline::{finish_scene, scene_dir};
use super::shard::{Partial, PartialRun, PartialScene, PlanEntry, SceneId, PARTIAL_FORMAT};
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

/// A partial read from disk: the partial, its file and the directory it
/// was found in (its shard's `--out`).
type FoundPartial = (Partial, PathBuf, PathBuf);

/// Every finished run of the plan by (scene, index among the scene's
/// runs), with the index of the partial that holds it.
type RunsFound<'a> = BTreeMap<(usize, usize), (&'a PartialRun, usize)>;

/// `shard-I-of-N.json` → (I, N).
fn parse_name(name: &str) -> Option<(u32, u32)> {
    let rest = name.strip_prefix("shard-")?.strip_suffix(".json")?;
    let (i, n) = rest.split_once("-of-")?;
    Some((i.parse().ok()?, n.parse().ok()?))
}

/// Reads every partial in `dirs`, with the directory each came from.
fn read_partials(dirs: &[PathBuf]) -> Result<Vec<FoundPartial>> {
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
fn check_same_sweep(partials: &[FoundPartial]) -> Result<()> {
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
    check_each_shard_once(&partials)?;
    let first = &partials[0].0;
    let (shards, plan, scenes) = (first.shards, first.plan.clone(), first.scenes.clone());
    let done = runs_of_plan(&partials, &plan)?;
    check_complete(&partials, &plan, &scenes, shards, &done)?;
    if images {
        check_images_written(&partials)?;
    }

    // Everything is checked before anything is written, so that a refused
    // merge leaves no half-filled --out: first the runs, images and heat
    // maps of every scene, then the copies, then the charts.
    let mut scenes_done = Vec::new();
    let mut copies: Vec<(PathBuf, PathBuf)> = Vec::new();
    let sweep = MergeSweep {
        partials: &partials,
        plan: &plan,
        done: &done,
        scenes: scenes.len(),
        images,
    };
    for (index, id) in scenes.iter().enumerate() {
        if let Some(scene) = sweep.scene(index, id, out, &mut copies)? {
            scenes_done.push(scene);
        }
    }
    for (src, dst) in &copies {
        copy_file(src, dst)?;
    }
    let mut results = Vec::new();
    for (header, runs, dir) in scenes_done {
        results.push((finish_scene(header, runs, Some(&dir))?, dir));
    }
    Ok(Merged {
        results,
        command: first.command.clone(),
        partials: partials.len(),
    })
}

/// Refuses the same shard twice (`partials` sorted by shard).
fn check_each_shard_once(partials: &[FoundPartial]) -> Result<()> {
    for pair in partials.windows(2) {
        if pair[0].0.shard == pair[1].0.shard {
            return Err(Error::param(
                "--merge",
                format!(
                    "shard {}/{} is there twice: {} and {} (keep one)",
                    pair[0].0.shard,
                    pair[0].0.shards,
                    pair[0].1.display(),
                    pair[1].1.display()
                ),
            ));
        }
    }
    Ok(())
}

/// Every finished run of the plan, by (scene, index), with the index of
/// its partial; an error for a run found twice or in another shard than
/// its own.
fn runs_of_plan<'a>(partials: &'a [FoundPartial], plan: &[PlanEntry]) -> Result<RunsFound<'a>> {
    let mut done = RunsFound::new();
    for (from, (partial, path, _)) in partials.iter().enumerate() {
        for run in &partial.runs {
            let owner = plan
                .iter()
                .find(|entry| (entry.scene, entry.index) == (run.scene, run.index))
                .map(|entry| entry.shard);
            if owner != Some(partial.shard)
                || done.insert((run.scene, run.index), (run, from)).is_some()
            {
                return Err(Error::file(
                    path,
                    None,
                    format!(
                        "holds run {} {} of scene {} that is not shard {}'s own",
                        run.technique, run.setting, run.scene, partial.shard
                    ),
                ));
            }
        }
    }
    Ok(done)
}

/// Refuses a sweep with runs missing, naming each shard that owes runs
/// (absent, or stopped early) with its runs.
fn check_complete(
    partials: &[FoundPartial],
    plan: &[PlanEntry],
    scenes: &[SceneId],
    shards: u32,
    done: &RunsFound,
) -> Result<()> {
    let mut missing = String::new();
    for shard in 1..=shards {
        let owed: Vec<String> = plan
            .iter()
            .filter(|entry| entry.shard == shard && !done.contains_key(&(entry.scene, entry.index)))
            .map(|entry| {
                format!(
                    "{}: {} {}",
                    scenes[entry.scene].name, entry.technique, entry.setting
                )
            })
            .collect();
        if owed.is_empty() {
            continue;
        }
        let total = plan.iter().filter(|entry| entry.shard == shard).count();
        let why = match partials
            .iter()
            .find(|(partial, _, _)| partial.shard == shard)
        {
            None => {
                format!(
                    "no partial result (shard-{shard}-of-{shards}.json in none of the directories)"
                )
            }
            Some((_, path, _)) => format!(
                "{} stopped after {} of its {total} runs",
                path.display(),
                total - owed.len()
            ),
        };
        let _ = writeln!(
            missing,
            "  shard {shard}/{shards}: {why}; missing {} run(s): {}",
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
    Ok(())
}

/// Refuses to merge images that a shard run with `--no-images` did not
/// write.
fn check_images_written(partials: &[FoundPartial]) -> Result<()> {
    if let Some((partial, path, _)) = partials.iter().find(|(partial, _, _)| !partial.images) {
        return Err(Error::param(
            "--merge",
            format!(
                "shard {}/{} ({}) was run with --no-images: merge with --no-images",
                partial.shard,
                partial.shards,
                path.display()
            ),
        ));
    }
    Ok(())
}

/// A checked sweep, read to gather each scene's part.
struct MergeSweep<'a> {
    partials: &'a [FoundPartial],
    plan: &'a [PlanEntry],
    done: &'a RunsFound<'a>,
    /// Scenes in the sweep.
    scenes: usize,
    /// Images and heat maps are merged.
    images: bool,
}

impl MergeSweep<'_> {
    /// Scene `scene_index` (`id`): its header, its runs in order and its directory
    /// under `out`, with the images to copy appended to `copies` after
    /// checking they are there; `None` for a scene without runs.
    fn scene(
        &self,
        scene_index: usize,
        id: &SceneId,
        out: &Path,
        copies: &mut Vec<(PathBuf, PathBuf)>,
    ) -> Result<Option<(SceneComparison, Vec<RunResult>, PathBuf)>> {
        let (partials, images) = (self.partials, self.images);
        let dir = scene_dir(out, &id.name, self.scenes);
        // Derived, like the file names, not read from the partial.
        let rel_dir = scene_dir(Path::new(""), &id.name, self.scenes);
        // The header of the shard that computed the reference (its time is
        // the reference's), else of the first that read it.
        let with_header: Vec<(usize, &PartialScene)> = partials
            .iter()
            .enumerate()
            .filter_map(|(from, (partial, _, _))| {
                partial.headers[scene_index]
                    .as_ref()
                    .map(|partial_header| (from, partial_header))
            })
            .collect();
        let header = with_header
            .iter()
            .find(|(_, partial_header)| !partial_header.from_cache)
            .or(with_header.first())
            .map(|&(from, partial_header)| (from, partial_header.to_header()));
        let Some((header_from, header)) = header else {
            // A scene without runs (no technique had a setting).
            return Ok(None);
        };
        let mut runs = Vec::new();
        for entry in self.plan.iter().filter(|entry| entry.scene == scene_index) {
            let (run, from) = self.done[&(entry.scene, entry.index)];
            let mut result = run.to_result();
            let src = partials[from].2.join(&rel_dir);
            if images {
                let (image, heatmaps) = run_files(run);
                if result.image.as_ref() != Some(&image) || result.heatmaps != heatmaps {
                    return Err(Error::file(
                        &partials[from].1,
                        None,
                        format!(
                            "run {} {} names its image and heat maps {:?} {:?}, not the \
                             {image:?} {heatmaps:?} compare writes: the partial result is \
                             damaged or edited",
                            run.technique, run.setting, result.image, result.heatmaps
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
        Ok(Some((header, runs, dir)))
    }
}
