//! On a real Slurm cluster (scripts/slurm-local.sh; .ci/run starts one and
//! sets PENUMBRA_SLURM=1): a 4-shard compare over two scenes and a 4-band
//! render submitted with `sweep --slurm --submit`, merged by their
//! dependent jobs, bit-identical to the unsharded runs; a failed shard is
//! named by the merge and re-running it alone completes the sweep.
//!
//! Without PENUMBRA_SLURM=1 each test prints `skipped: ...` and passes.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

fn enabled(test: &str) -> bool {
    if std::env::var("PENUMBRA_SLURM").as_deref() == Ok("1") {
        return true;
    }
    println!(
        "skipped: {test}: PENUMBRA_SLURM is not 1 (run scripts/slurm-local.sh start as root, \
         export its SLURM_CONF and PENUMBRA_SLURM=1; .ci/run does)"
    );
    false
}

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_penumbra")
}

fn run(cmd: &str, args: &[&str]) -> (bool, String) {
    let out = Command::new(cmd)
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap_or_else(|e| panic!("run {cmd}: {e}"));
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr),
    )
}

/// A fresh directory the node can see (this is a one-node cluster; on a
/// real one it would be on the shared filesystem).
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("penumbra-slurm-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The id after `label` in sweep's output (`array job 12 ...`).
fn job_id(out: &str, label: &str) -> String {
    out.lines()
        .find_map(|l| l.strip_prefix(label))
        .and_then(|r| r.split_whitespace().next())
        .unwrap_or_else(|| panic!("no `{label}` in\n{out}"))
        .to_string()
}

/// Job (or every task of an array job) states from scontrol, which keeps
/// finished jobs for MinJobAge (sacct would need accounting).
fn states(id: &str) -> Vec<String> {
    let (_, out) = run("scontrol", &["show", "job", id]);
    out.split_whitespace()
        .filter_map(|w| w.strip_prefix("JobState="))
        .map(str::to_string)
        .collect()
}

/// Waits until every task of `id` has left PENDING/RUNNING; its states.
/// (`sbatch --wait` is not used: it returns 0 for a cancelled job.)
fn wait(id: &str, logs: &Path) -> Vec<String> {
    let start = Instant::now();
    loop {
        let s = states(id);
        if !s.is_empty()
            && s.iter().all(|s| {
                !matches!(
                    s.as_str(),
                    "PENDING" | "RUNNING" | "CONFIGURING" | "COMPLETING"
                )
            })
        {
            return s;
        }
        if start.elapsed() > Duration::from_secs(600) {
            let _ = run("scancel", &[id]);
            panic!(
                "job {id} not done after 600 s: {s:?}; logs in {}",
                logs.display()
            );
        }
        std::thread::sleep(Duration::from_millis(500));
    }
}

fn logs_of(dir: &Path) -> String {
    let mut s = String::new();
    if let Ok(entries) = std::fs::read_dir(dir.join("logs")) {
        for e in entries.flatten() {
            s += &format!(
                "--- {}\n{}",
                e.path().display(),
                std::fs::read_to_string(e.path()).unwrap_or_default()
            );
        }
    }
    s
}

/// results.json without what may differ between runs of the same sweep:
/// times, host, the Pareto flags (decided on times), cache flags and the
/// paths of charts and images (the output directories differ). What is
/// left are the error figures, counts and settings.
fn error_figures(json: &Path) -> serde_json::Value {
    const VARYING: &[&str] = &[
        "host",
        "median_ms",
        "min_ms",
        "max_ms",
        "pareto",
        "pareto_flip",
        "passes",
        "seconds",
        "from_cache",
        "cache_file",
        "chart",
        "chart_all",
        "chart_flip",
        "chart_flip_interior",
        "chart_radiance",
        "heatmaps",
        "image",
        "path",
    ];
    fn strip(v: &mut serde_json::Value) -> usize {
        match v {
            serde_json::Value::Object(m) => {
                m.retain(|k, _| !VARYING.contains(&k.as_str()));
                m.values_mut().map(strip).sum::<usize>() + usize::from(m.contains_key("rmse"))
            }
            serde_json::Value::Array(a) => a.iter_mut().map(strip).sum(),
            _ => 0,
        }
    }
    let text = std::fs::read_to_string(json).unwrap_or_else(|e| panic!("{}: {e}", json.display()));
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let metrics = strip(&mut v);
    assert!(
        metrics > 50,
        "only {metrics} error figures in {}",
        json.display()
    );
    v
}

const COMPARE: &[&str] = &[
    "scenes/quad.toml",
    "scenes/spheres.toml",
    "--techniques",
    "shadow-volumes,dcs,reference",
    "--samples",
    "4,16",
    "--reference-samples",
    "32",
    "--repeat",
    "1",
    "--width",
    "48",
    "--height",
    "40",
    "--no-images",
];

fn sweep(dir: &Path, extra: &[&str], forwarded: &[&str]) -> String {
    let d = dir.to_str().unwrap();
    let args = [
        &[
            "sweep",
            "--slurm",
            "--out",
            d,
            "--submit",
            "--time",
            "10",
            "--job-name",
            "pt",
        ][..],
        extra,
        &["--"],
        forwarded,
    ]
    .concat();
    let (ok, out) = run(bin(), &args);
    assert!(ok, "sweep failed:\n{out}");
    out
}

#[test]
fn sharded_compare_and_banded_render_match_one_machine() {
    if !enabled("sharded_compare_and_banded_render_match_one_machine") {
        return;
    }
    let dir = scratch("sweep");
    let cache = dir.join("cache");
    let cache = cache.to_str().unwrap();
    // The compare: 4 shards, merged by the dependent job.
    let sw = dir.join("compare");
    let out = sweep(
        &sw,
        &["--shards", "4", "--throttle", "4"],
        &[COMPARE, &["--cache-dir", cache]].concat(),
    );
    let (array, merge) = (job_id(&out, "array job "), job_id(&out, "merge job "));
    // The banded render, submitted while the compare runs.
    let rd = dir.join("render");
    let render_args = [
        "--technique",
        "dcs",
        "--samples",
        "8",
        "--width",
        "96",
        "--height",
        "256",
        "--aov",
        "depth,mask,vcoef",
    ];
    let rout = sweep(
        &rd,
        &["--render", "scenes/spheres.toml", "--tiles", "4"],
        &render_args,
    );
    let (rarray, rmerge) = (job_id(&rout, "array job "), job_id(&rout, "merge job "));

    let s = wait(&array, &sw);
    assert!(
        s.len() == 4 && s.iter().all(|s| s == "COMPLETED"),
        "shards {s:?}\n{}",
        logs_of(&sw)
    );
    assert_eq!(wait(&merge, &sw), ["COMPLETED"], "{}", logs_of(&sw));
    let s = wait(&rarray, &rd);
    assert!(
        s.len() == 4 && s.iter().all(|s| s == "COMPLETED"),
        "bands {s:?}\n{}",
        logs_of(&rd)
    );
    assert_eq!(wait(&rmerge, &rd), ["COMPLETED"], "{}", logs_of(&rd));
    // One log per task.
    let logs = std::fs::read_dir(sw.join("logs")).unwrap().count();
    assert_eq!(logs, 5, "{}", logs_of(&sw));

    // The same on one machine.
    let whole = dir.join("whole");
    let (ok, msg) = run(
        bin(),
        &[
            &[
                "compare",
                "--out",
                whole.to_str().unwrap(),
                "--cache-dir",
                cache,
            ][..],
            COMPARE,
        ]
        .concat(),
    );
    assert!(ok, "{msg}");
    assert_eq!(
        error_figures(&sw.join("results.json")),
        error_figures(&whole.join("results.json"))
    );

    let (png, exr) = (dir.join("one.png"), dir.join("one.exr"));
    let (ok, msg) = run(
        bin(),
        &[
            &[
                "render",
                "scenes/spheres.toml",
                "-o",
                png.to_str().unwrap(),
                "--exr",
                exr.to_str().unwrap(),
            ][..],
            &render_args,
        ]
        .concat(),
    );
    assert!(ok, "{msg}");
    assert!(
        std::fs::read(rd.join("render.png")).unwrap() == std::fs::read(&png).unwrap(),
        "PNG differs"
    );
    assert!(
        std::fs::read(rd.join("render.exr")).unwrap() == std::fs::read(&exr).unwrap(),
        "EXR differs"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_failed_shard_is_named_and_rerunning_it_completes_the_sweep() {
    if !enabled("a_failed_shard_is_named_and_rerunning_it_completes_the_sweep") {
        return;
    }
    let dir = scratch("fault");
    let allow = dir.join("allow-3");
    // Shard 3 fails until `allow` exists (a crash, an OOM kill, a node lost).
    let setup = format!(
        "--setup=if [ \"${{SLURM_ARRAY_TASK_ID:-}}\" = 3 ] && [ ! -e {} ]; then echo 'shard 3 dies'; exit 1; fi",
        allow.display()
    );
    let cache = dir.join("cache");
    let out = sweep(
        &dir,
        &["--shards", "4", &setup],
        &[COMPARE, &["--cache-dir", cache.to_str().unwrap()]].concat(),
    );
    let (array, merge) = (job_id(&out, "array job "), job_id(&out, "merge job "));
    let s = wait(&array, &dir);
    assert_eq!(
        s.iter().filter(|s| *s == "FAILED").count(),
        1,
        "{s:?}\n{}",
        logs_of(&dir)
    );
    // kill_invalid_depend: the merge is cancelled, not left pending.
    let m = wait(&merge, &dir);
    assert_eq!(m, ["CANCELLED"], "{}", logs_of(&dir));

    // The merge, run by hand, names the missing shard.
    let shards = dir.join("shards");
    let merge_args = |out: &Path| -> Vec<String> {
        [
            "compare",
            "--no-images",
            "--merge",
            shards.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]
        .map(String::from)
        .to_vec()
    };
    let args = merge_args(&dir.join("merged"));
    let (ok, msg) = run(bin(), &args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(!ok && msg.contains("shard 3/4: no partial result"), "{msg}");

    // Re-run shard 3 alone; the others' partial results stay untouched.
    let stamp = |i: usize| {
        let p = shards.join(format!("shard-{i}-of-4.json"));
        std::fs::metadata(&p)
            .unwrap_or_else(|e| panic!("{}: {e}", p.display()))
            .modified()
            .unwrap()
    };
    let before: Vec<_> = [1, 2, 4].map(stamp).into();
    std::fs::write(&allow, b"").unwrap();
    let script = dir.join("slurm").join("array.sbatch");
    let (ok, id) = run(
        "sbatch",
        &["--parsable", "--array=3", script.to_str().unwrap()],
    );
    assert!(ok, "{id}");
    let id = id.trim().split(';').next().unwrap().to_string();
    assert_eq!(wait(&id, &dir), ["COMPLETED"], "{}", logs_of(&dir));
    let after: Vec<_> = [1, 2, 4].map(stamp).into();
    assert_eq!(before, after, "shards 1, 2, 4 were redone");
    let (ok, msg) = run(bin(), &args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(ok, "{msg}");
    let whole = dir.join("whole");
    let (ok, msg) = run(
        bin(),
        &[
            &[
                "compare",
                "--out",
                whole.to_str().unwrap(),
                "--cache-dir",
                cache.to_str().unwrap(),
            ][..],
            COMPARE,
        ]
        .concat(),
    );
    assert!(ok, "{msg}");
    assert_eq!(
        error_figures(&dir.join("merged").join("results.json")),
        error_figures(&whole.join("results.json"))
    );
    let _ = std::fs::remove_dir_all(&dir);
}
