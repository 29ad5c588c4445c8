//! `compare --shard I/N` and `compare --merge`: a sharded sweep gives the
//! unsharded run's error figures bit for bit, every run exactly once;
//! missing shards and mismatched sweeps are named; bad specs refused; the
//! reference is computed once under the cache's lock.

use crate::common;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_penumbra"));
    c.current_dir(env!("CARGO_MANIFEST_DIR"));
    c
}

fn run(args: &[String]) -> (Option<i32>, String) {
    let out = bin().args(args).output().expect("run penumbra");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned() + &String::from_utf8_lossy(&out.stdout),
    )
}

fn spawn(args: &[String]) -> Child {
    bin()
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn penumbra")
}

fn strings(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

/// A small sweep: the given scenes at 32×24, two techniques, three runs
/// per scene, a 16-sample reference.
fn sweep(scenes: &[&str], cache: &Path, extra: &[&str]) -> Vec<String> {
    let mut a = strings(&["compare"]);
    a.extend(strings(scenes));
    a.extend(strings(&[
        "--techniques",
        "shadow-volumes,reference",
        "--samples",
        "4,16",
        "--reference-samples",
        "16",
        "--repeat",
        "1",
        "--width",
        "32",
        "--height",
        "24",
        "--threads",
        "1",
        "--cache-dir",
        cache.to_str().unwrap(),
    ]));
    a.extend(strings(extra));
    a
}

fn ok(args: &[String]) -> String {
    let (code, msg) = run(args);
    assert_eq!(code, Some(0), "{args:?}\n{msg}");
    msg
}

/// A results.csv row's key and its cells by column.
type Rows = BTreeMap<(String, String, String, String, String), BTreeMap<String, String>>;

/// results.csv as rows keyed by (scene, technique, setting, quantity,
/// region), each a map from column to value.
fn csv(path: &Path) -> Rows {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let mut rows = BTreeMap::new();
    for line in lines {
        // No quoted fields in these scenes' names and labels.
        let cells: Vec<&str> = line.split(',').collect();
        assert_eq!(cells.len(), header.len(), "{line}");
        let row: BTreeMap<String, String> = header
            .iter()
            .cloned()
            .zip(cells.iter().map(|c| c.to_string()))
            .collect();
        let key = (
            row["scene"].clone(),
            row["technique"].clone(),
            row["setting"].clone(),
            row["quantity"].clone(),
            row["region"].clone(),
        );
        assert!(rows.insert(key, row).is_none(), "duplicate row {line}");
    }
    rows
}

fn partial(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

const ERROR_COLUMNS: [&str; 9] = [
    "count",
    "rmse",
    "mean_abs",
    "max_abs",
    "frac_over",
    "non_finite",
    "p50",
    "p90",
    "p99",
];

#[test]
fn three_shards_merge_to_the_unsharded_numbers() {
    let dir = common::scratch_dir("shard-main");
    let scenes = ["scenes/quad.toml", "scenes/thin-occluder.toml"];
    let whole = dir.join("whole");
    ok(&sweep(
        &scenes,
        &dir.join("cache-a"),
        &["--out", whole.to_str().unwrap()],
    ));

    // Three shards at once on a fresh cache: the lock lets one compute
    // each reference while the others wait and read it.
    let shards = dir.join("shards");
    let cache = dir.join("cache-b");
    let children: Vec<Child> = (1..=3)
        .map(|i| {
            spawn(&sweep(
                &scenes,
                &cache,
                &[
                    "--shard",
                    &format!("{i}/3"),
                    "--out",
                    shards.to_str().unwrap(),
                ],
            ))
        })
        .collect();
    for c in children {
        let out = c.wait_with_output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }

    // Every run of the plan exactly once, in the shard the plan names.
    let mut seen = BTreeSet::new();
    let mut computed = [0; 2];
    let mut plan_len = 0;
    for i in 1..=3 {
        let p = partial(&shards.join(format!("shard-{i}-of-3.json")));
        assert_eq!(p["complete"], true);
        let plan = p["plan"].as_array().unwrap();
        plan_len = plan.len();
        for r in p["runs"].as_array().unwrap() {
            let key = (r["scene"].as_u64().unwrap(), r["index"].as_u64().unwrap());
            let owner = plan
                .iter()
                .find(|e| (e["scene"].as_u64().unwrap(), e["index"].as_u64().unwrap()) == key)
                .unwrap();
            assert_eq!(owner["shard"], i, "{r}");
            assert!(seen.insert(key), "run {key:?} twice");
            assert!(!r["host"].as_str().unwrap().is_empty());
        }
        for (s, h) in p["headers"].as_array().unwrap().iter().enumerate() {
            if h["from_cache"] == false {
                computed[s] += 1;
            }
        }
    }
    assert_eq!(plan_len, 6, "two scenes × (hard + 4 and 16 spp)");
    assert_eq!(seen.len(), plan_len, "the shards' runs are all runs");
    assert_eq!(computed, [1, 1], "each reference computed once");

    let merged = dir.join("merged");
    let report = dir.join("report.md");
    let msg = ok(&strings(&[
        "compare",
        "--merge",
        shards.to_str().unwrap(),
        "--out",
        merged.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]));
    assert!(msg.contains("6 runs"), "{msg}");

    let (a, b) = (
        csv(&whole.join("results.csv")),
        csv(&merged.join("results.csv")),
    );
    assert_eq!(
        a.keys().collect::<Vec<_>>(),
        b.keys().collect::<Vec<_>>(),
        "the same rows"
    );
    let mut compared = 0;
    for (key, ra) in &a {
        let rb = &b[key];
        for col in ERROR_COLUMNS {
            // Parsed exactly: the same value, not merely close.
            let (x, y) = (&ra[col], &rb[col]);
            if x.is_empty() {
                assert!(y.is_empty());
                continue;
            }
            let (px, py): (f64, f64) = (x.parse().unwrap(), y.parse().unwrap());
            assert_eq!(px.to_bits(), py.to_bits(), "{key:?} {col}: {x} vs {y}");
            compared += 1;
        }
        assert_eq!(ra["samples"], rb["samples"]);
        if key.1 != "reference-floor" && key.1 != "reference-halves" {
            assert!(!rb["host"].is_empty(), "{key:?}");
            assert!(rb["median_ms"].parse::<f64>().unwrap() > 0.0);
        }
    }
    assert!(compared > 100, "{compared} error values compared");
    assert!(b.keys().any(|k| k.3 == "vcoef" && k.4 == "penumbra"));
    // FLIP too (whole frame and interior), from the partials exactly.
    for region in ["all", "interior"] {
        assert!(
            b.iter().any(|(k, r)| k.1 == "reference"
                && k.3 == "flip"
                && k.4 == region
                && !r["p99"].is_empty()),
            "{region}"
        );
    }

    // The same images, heat maps and charts, in the same places; the
    // markdown report regenerates the sweep without --shard.
    for scene in ["quad", "thin-occluder"] {
        for rel in [
            "flip_vs_time.png",
            "flip_vs_time_interior.png",
            "radiance_vs_time.png",
            "error_vs_time.png",
            "error_vs_time_all.png",
            "images/reference.png",
        ] {
            assert!(merged.join(scene).join(rel).exists(), "{scene}/{rel}");
        }
        let names = |d: &Path| -> BTreeSet<String> {
            std::fs::read_dir(d.join(scene).join("heatmaps"))
                .unwrap()
                .map(|e| e.unwrap().file_name().into_string().unwrap())
                .collect()
        };
        assert_eq!(names(&whole), names(&merged));
        // Heat maps depend on errors only: byte-identical.
        for n in names(&whole) {
            let rel = PathBuf::from(scene).join("heatmaps").join(&n);
            assert_eq!(
                std::fs::read(whole.join(&rel)).unwrap(),
                std::fs::read(merged.join(&rel)).unwrap(),
                "{}",
                rel.display()
            );
        }
    }
    let md = std::fs::read_to_string(&report).unwrap();
    assert!(md.contains("penumbra compare scenes/quad.toml"), "{md}");
    assert!(!md.contains("--shard"), "{md}");
    assert!(md.contains("](merged/quad/error_vs_time.png)"), "{md}");
}

#[test]
fn a_missing_or_stopped_shard_is_named_and_rerunning_it_completes_the_sweep() {
    let dir = common::scratch_dir("shard-missing");
    let cache = dir.join("cache");
    let shards = dir.join("shards");
    let shard = |i: u32| {
        ok(&sweep(
            &["scenes/quad.toml"],
            &cache,
            &[
                "--shard",
                &format!("{i}/3"),
                "--out",
                shards.to_str().unwrap(),
                "--no-images",
            ],
        ))
    };
    shard(1);
    shard(3);
    let merge = strings(&[
        "compare",
        "--merge",
        shards.to_str().unwrap(),
        "--out",
        dir.join("merged").to_str().unwrap(),
        "--no-images",
    ]);
    let (code, msg) = run(&merge);
    assert_eq!(code, Some(2), "{msg}");
    assert!(msg.contains("shard 2/3: no partial result"), "{msg}");
    // The runs it owes, by name, from the plan.
    let plan = partial(&shards.join("shard-1-of-3.json"))["plan"].clone();
    let owed: Vec<String> = plan
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e["shard"] == 2)
        .map(|e| {
            format!(
                "quad: {} {}",
                e["technique"].as_str().unwrap(),
                e["setting"].as_str().unwrap()
            )
        })
        .collect();
    assert!(!owed.is_empty());
    for o in &owed {
        assert!(msg.contains(o.as_str()), "{o} in {msg}");
    }
    assert!(!dir.join("merged/results.csv").exists(), "nothing written");

    // A shard killed after its first run: its partial says so.
    let s3 = shards.join("shard-3-of-3.json");
    let mut p = partial(&s3);
    let all_runs = p["runs"].as_array().unwrap().clone();
    p["runs"] = serde_json::Value::Array(Vec::new());
    p["complete"] = false.into();
    std::fs::write(&s3, serde_json::to_string(&p).unwrap()).unwrap();
    shard(2);
    let (code, msg) = run(&merge);
    assert_eq!(code, Some(2), "{msg}");
    assert!(
        msg.contains("shard 3/3") && msg.contains("stopped after 0 of its"),
        "{msg}"
    );
    assert!(!msg.contains("shard 2/3"), "{msg}");
    assert_eq!(all_runs.len(), 1);

    // Re-running that shard alone completes it.
    shard(3);
    let msg = ok(&merge);
    assert!(msg.contains("3 runs"), "{msg}");
    let rows = csv(&dir.join("merged/results.csv"));
    assert!(rows.keys().any(|k| k.1 == "reference" && k.2 == "16 spp"));
}

#[test]
fn partials_of_different_sweeps_are_refused_with_the_reason() {
    let dir = common::scratch_dir("shard-mismatch");
    let cache = dir.join("cache");
    let shards = dir.join("shards");
    let out = shards.to_str().unwrap();
    ok(&sweep(
        &["scenes/quad.toml"],
        &cache,
        &["--shard", "1/2", "--out", out, "--no-images", "--seed", "1"],
    ));
    ok(&sweep(
        &["scenes/quad.toml"],
        &cache,
        &["--shard", "2/2", "--out", out, "--no-images", "--seed", "2"],
    ));
    let merge = strings(&[
        "compare",
        "--merge",
        out,
        "--out",
        dir.join("merged").to_str().unwrap(),
        "--no-images",
    ]);
    let (code, msg) = run(&merge);
    assert_eq!(code, Some(2), "{msg}");
    assert!(
        msg.contains("not of the same sweep") && msg.contains("--seed was 1 and 2"),
        "{msg}"
    );

    // Another crate version.
    ok(&sweep(
        &["scenes/quad.toml"],
        &cache,
        &["--shard", "2/2", "--out", out, "--no-images", "--seed", "1"],
    ));
    assert_eq!(run(&merge).0, Some(0));
    let s2 = shards.join("shard-2-of-2.json");
    let mut p = partial(&s2);
    p["version"] = "0.0.0-other".into();
    std::fs::write(&s2, serde_json::to_string(&p).unwrap()).unwrap();
    let (code, msg) = run(&merge);
    assert_eq!(code, Some(2), "{msg}");
    assert!(msg.contains("0.0.0-other"), "{msg}");

    // Other scene contents under the same name.
    p["version"] = partial(&shards.join("shard-1-of-2.json"))["version"].clone();
    p["scenes"][0]["hash"] = "0123456789abcdef".into();
    std::fs::write(&s2, serde_json::to_string(&p).unwrap()).unwrap();
    let (code, msg) = run(&merge);
    assert_eq!(code, Some(2), "{msg}");
    assert!(msg.contains("scene quad has different contents"), "{msg}");

    // A partial of the format before FLIP (no FLIP, no interior): refused
    // as such, never merged with missing figures.
    let mut old = partial(&shards.join("shard-1-of-2.json"));
    old["format"] = 1.into();
    for r in old["runs"].as_array_mut().unwrap() {
        r.as_object_mut().unwrap().remove("flip");
    }
    std::fs::write(&s2, serde_json::to_string(&old).unwrap()).unwrap();
    let (code, msg) = run(&merge);
    assert_eq!(code, Some(2), "{msg}");
    assert!(
        msg.contains("partial format 1 (this penumbra reads 2)"),
        "{msg}"
    );
    std::fs::write(&s2, serde_json::to_string(&p).unwrap()).unwrap();

    // Partials of another shard count in the same directory.
    ok(&sweep(
        &["scenes/quad.toml"],
        &cache,
        &["--shard", "1/3", "--out", out, "--no-images", "--seed", "1"],
    ));
    let (code, msg) = run(&merge);
    assert_eq!(code, Some(2), "{msg}");
    assert!(msg.contains("shards of a sweep in"), "{msg}");
}

#[test]
fn bad_shard_specs_are_parameter_errors() {
    let dir = common::scratch_dir("shard-specs");
    for spec in ["0/3", "4/3", "1/0", "2", "x/3"] {
        let (code, msg) = run(&sweep(
            &["scenes/quad.toml"],
            &dir.join("cache"),
            &["--shard", spec, "--out", dir.join("out").to_str().unwrap()],
        ));
        assert_eq!(code, Some(2), "{spec}: {msg}");
        assert!(
            msg.contains("--shard") && msg.contains(spec),
            "{spec}: {msg}"
        );
        assert!(!dir.join("out").exists(), "{spec}: refused before any work");
    }
    let (code, msg) = run(&strings(&[
        "compare",
        "--merge",
        dir.to_str().unwrap(),
        "scenes/quad.toml",
    ]));
    assert_eq!(code, Some(2), "{msg}");
    assert!(msg.contains("--merge"), "{msg}");
}

#[test]
fn a_dead_holders_lock_is_taken_over_and_references_only_fills_the_cache() {
    use penumbra::internal::compare::cache::{
        hash_scene, ReferenceKey, StableHasher, REFERENCE_VERSION,
    };
    let dir = common::scratch_dir("shard-lock");
    let cache = dir.join("cache");
    std::fs::create_dir_all(&cache).unwrap();
    let scene = common::shipped("quad.toml");
    let mut h = StableHasher::default();
    hash_scene(&mut h, &scene);
    let options = penumbra::internal::compare::CompareOptions {
        techniques: Vec::new(),
        technique_options: Default::default(),
        samples: vec![4],
        reference_samples: 16,
        repeat: 1,
        width: Some(32),
        height: Some(24),
        seed: 0,
        cache_dir: cache.clone(),
        images: false,
        patterns: Vec::new(),
        verify: None,
        threads: None,
        sweep_settings: false,
        target_error: None,
    };
    let key = ReferenceKey {
        scene_hash: h.finish(),
        width: 32,
        height: 24,
        samples: 16,
        seeds: options.reference_seeds(),
        version: REFERENCE_VERSION,
    };
    // A holder on this host whose process is gone.
    let mut gone = Command::new("true").spawn().unwrap();
    let pid = gone.id();
    gone.wait().unwrap();
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap();
    let lock = cache.join(format!("{}.lock", key.stem()));
    std::fs::write(
        &lock,
        format!(
            r#"{{"host":"{}","pid":{pid},"token":"x","beat":0}}"#,
            host.trim()
        ),
    )
    .unwrap();
    let start = std::time::Instant::now();
    let msg = ok(&sweep(
        &["scenes/quad.toml"],
        &cache,
        &["--references-only"],
    ));
    assert!(
        start.elapsed() < penumbra::internal::compare::cache::STALE_AFTER,
        "the dead pid is seen at once, not after the heartbeat timeout"
    );
    assert!(msg.contains("stale reference lock"), "{msg}");
    assert!(msg.contains("computed into"), "{msg}");
    assert!(!lock.exists(), "the lock is released");
    assert!(cache.join(format!("{}.exr", key.stem())).exists(), "{msg}");
    let msg = ok(&sweep(
        &["scenes/quad.toml"],
        &cache,
        &["--references-only"],
    ));
    assert!(msg.contains("already in"), "{msg}");
}
