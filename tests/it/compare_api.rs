//! `compare` as a library call: its records are the rows of the
//! `results.csv` it writes (and the command writes), scenes given in
//! memory work without any output directory, and bad options are errors
//! that name the parameter.

use crate::common;

use penumbra::{
    compare, load_scene, scene_from_toml, CompareOptions, Record, Scene, Technique, CSV_COLUMNS,
};
use std::path::{Path, PathBuf};
use std::process::Command;

fn quad_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/quad.toml")
}

/// The small sweep of the command line
/// `compare scenes/quad.toml --width 32 --height 24 --techniques
/// shadow-volumes,dcs,reference --samples 4,16 --reference-samples 64
/// --no-images --sweep-settings`, with its cache in `cache` (the swept
/// settings too: the option goes through both routes alike).
fn small(cache: &Path) -> CompareOptions {
    CompareOptions {
        techniques: ["shadow-volumes", "dcs", "reference"]
            .map(|name| Technique::named(name).expect("registered"))
            .to_vec(),
        samples: vec![4, 16],
        reference_samples: 64,
        width: Some(32),
        height: Some(24),
        images: false,
        cache_dir: cache.to_path_buf(),
        sweep_settings: true,
        ..CompareOptions::default()
    }
}

/// Its arguments after `compare`.
const SMALL_ARGS: [&str; 14] = [
    "--sweep-settings",
    "--width",
    "32",
    "--height",
    "24",
    "--techniques",
    "shadow-volumes,dcs,reference",
    "--samples",
    "4,16",
    "--reference-samples",
    "64",
    "--no-images",
    "--repeat",
    "3",
];

/// A `results.csv` read back as records: an empty cell is `None`, every
/// other cell parses as its field's type.
fn read_csv(path: &Path) -> (Vec<String>, Vec<Record>) {
    let mut reader = csv::Reader::from_path(path).expect("results.csv reads");
    let header: Vec<String> = reader
        .headers()
        .expect("a header")
        .iter()
        .map(String::from)
        .collect();
    let rows = reader
        .records()
        .map(|row| {
            let row = row.expect("a row");
            assert_eq!(row.len(), CSV_COLUMNS.len(), "{row:?}");
            let cell = |i: usize| Some(row[i].to_string()).filter(|s| !s.is_empty());
            fn parsed<T: std::str::FromStr>(cell: Option<String>) -> Option<T> {
                cell.map(|s| {
                    s.parse()
                        .unwrap_or_else(|_| panic!("{s:?} is not a number or flag"))
                })
            }
            Record {
                scene: row[0].to_string(),
                technique: row[1].to_string(),
                setting: row[2].to_string(),
                samples: parsed(cell(3)),
                median_ms: parsed(cell(4)),
                min_ms: parsed(cell(5)),
                max_ms: parsed(cell(6)),
                runs: parsed(cell(7)),
                host: cell(8),
                geometry_ms: parsed(cell(9)),
                gbuffer_ms: parsed(cell(10)),
                shadow_ms: parsed(cell(11)),
                shading_ms: parsed(cell(12)),
                quantity: row[13].to_string(),
                region: row[14].to_string(),
                count: parsed(cell(15)),
                rmse: parsed(cell(16)),
                mean_abs: parsed(cell(17)).expect("every row has mean_abs"),
                max_abs: parsed(cell(18)),
                frac_over: parsed(cell(19)),
                non_finite: parsed(cell(20)),
                p50: parsed(cell(21)),
                p90: parsed(cell(22)),
                p99: parsed(cell(23)),
                pareto_flip: parsed(cell(24)),
                pareto: parsed(cell(25)),
                verify_checked: parsed(cell(26)),
                verify_disagreements: parsed(cell(27)),
                verify_beyond_tie: parsed(cell(28)),
                verify_max_tie: parsed(cell(29)),
            }
        })
        .collect();
    (header, rows)
}

/// `r` without what differs from one run to the next: times and what
/// depends on them (the Pareto fronts).
fn untimed(r: &Record) -> Record {
    Record {
        median_ms: r.median_ms.map(|_| 0.0),
        min_ms: r.min_ms.map(|_| 0.0),
        max_ms: r.max_ms.map(|_| 0.0),
        geometry_ms: r.geometry_ms.map(|_| 0.0),
        gbuffer_ms: r.gbuffer_ms.map(|_| 0.0),
        shadow_ms: r.shadow_ms.map(|_| 0.0),
        shading_ms: r.shading_ms.map(|_| 0.0),
        pareto_flip: r.pareto_flip.map(|_| false),
        pareto: r.pareto.map(|_| false),
        ..r.clone()
    }
}

/// The records are the rows of the results.csv the call writes, column
/// for column and value for value; their shape is the file's.
#[test]
fn the_records_are_the_rows_of_results_csv() {
    let dir = common::ScratchDir::new("compare-api-rows");
    let scene = load_scene(&quad_path()).expect("quad loads");
    let out = dir.0.join("out");
    let records = compare(
        std::slice::from_ref(&scene),
        &small(&dir.0.join("cache")),
        Some(&out),
    )
    .expect("compare");
    let (header, rows) = read_csv(&out.join("results.csv"));
    assert_eq!(header, CSV_COLUMNS);
    assert_eq!(rows, records);
    for file in ["results.json", "results.md", "flip_vs_time.png"] {
        assert!(out.join(file).is_file(), "{file} written");
    }
    assert!(!out.join("images").exists(), "no images without images");

    // 7 runs (shadow volumes; DCS, DCS with silhouettes from the light's
    // centre (--sweep-settings), and the reference, at 4 and 16 samples), each
    // with 3 radiance, 2 FLIP and 3 + 3 Vcoef rows (one light and all
    // lights); then the reference's 3 + 3 + 3 floor rows and 2 FLIP rows
    // between its halves.
    assert_eq!(records.len(), 7 * 11 + 11);
    let runs: Vec<&Record> = records.iter().filter(|r| r.median_ms.is_some()).collect();
    assert_eq!(runs.len(), 77);
    assert!(runs.iter().all(|r| r.host.is_some() && r.runs == Some(3)));
    assert!(runs.iter().any(|r| r.pareto_flip == Some(true)));
    for r in &records {
        let flip = r.quantity == "flip";
        assert_eq!(r.rmse.is_none(), flip, "{r:?}");
        assert_eq!(r.p50.is_some(), flip, "{r:?}");
        assert!(r.verify_checked.is_none(), "no --verify: {r:?}");
    }
    assert!(records.iter().any(|r| r.technique == "dcs centre"));

    // Without --sweep-settings, each technique's default configuration
    // only: 5 runs (shadow volumes; DCS and the reference at 4 and 16).
    let plain = CompareOptions {
        sweep_settings: false,
        repeat: 1,
        ..small(&dir.0.join("cache"))
    };
    let few = compare(&[scene], &plain, None).expect("compare");
    assert_eq!(few.len(), 5 * 11 + 11);
    assert!(few.iter().all(|r| r.technique != "dcs centre"), "{few:?}");
    let floors: Vec<&Record> = records
        .iter()
        .filter(|r| r.technique == "reference-floor")
        .collect();
    assert_eq!(floors.len(), 9);
    assert!(floors
        .iter()
        .all(|r| r.samples == Some(64) && r.count.is_none() && r.host.is_none()));

    // As dicts (the Python package's), the records have the columns.
    let json = serde_json::to_value(&records[0]).expect("serializes");
    let mut keys: Vec<&str> = json
        .as_object()
        .expect("an object")
        .keys()
        .map(String::as_str)
        .collect();
    let mut columns = CSV_COLUMNS.to_vec();
    keys.sort_unstable();
    columns.sort_unstable();
    assert_eq!(keys, columns);
}

/// `penumbra compare` writes the rows the function returns: the same
/// columns and values but for times (and the Pareto fronts, which
/// depend on them), which differ from run to run.
#[test]
fn the_command_writes_the_records_of_the_function() {
    let dir = common::ScratchDir::new("compare-api-cli");
    let cache = dir.0.join("cache");
    let scene = load_scene(&quad_path()).expect("quad loads");
    let records = compare(&[scene], &small(&cache), None).expect("compare");
    let out = dir.0.join("cli");
    let status = Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .arg("compare")
        .arg(quad_path())
        .args(SMALL_ARGS)
        .arg("--cache-dir")
        .arg(&cache)
        .arg("--out")
        .arg(&out)
        .status()
        .expect("penumbra runs");
    assert!(status.success());
    let (_, rows) = read_csv(&out.join("results.csv"));
    let untimed_rows: Vec<Record> = rows.iter().map(untimed).collect();
    let untimed_records: Vec<Record> = records.iter().map(untimed).collect();
    assert_eq!(untimed_rows, untimed_records);
}

/// A scene given as text (no file) compares without an output
/// directory: nothing is written but the reference cache, and its
/// records are those of the same scene loaded from its file.
#[test]
fn a_scene_in_memory_compares_without_files() {
    let dir = common::ScratchDir::new("compare-api-memory");
    let cache = dir.0.join("cache");
    let text = std::fs::read_to_string(quad_path()).expect("quad reads");
    let in_memory: Scene = scene_from_toml(&text, &dir.0).expect("quad parses");
    let options = CompareOptions {
        repeat: 1,
        ..small(&cache)
    };
    let records = compare(&[in_memory], &options, None).expect("compare");
    let entries: Vec<PathBuf> = std::fs::read_dir(&dir.0)
        .expect("scratch lists")
        .map(|e| e.expect("an entry").path())
        .collect();
    assert_eq!(
        entries,
        std::slice::from_ref(&cache),
        "only the cache is written"
    );
    assert!(std::fs::read_dir(&cache).expect("cache lists").all(|e| e
        .expect("an entry")
        .file_name()
        .to_string_lossy()
        .starts_with("reference-")));
    let from_file = load_scene(&quad_path()).expect("quad loads");
    let again = compare(&[from_file], &options, None).expect("compare");
    let untimed_records: Vec<Record> = records.iter().map(untimed).collect();
    let untimed_again: Vec<Record> = again.iter().map(untimed).collect();
    assert_eq!(untimed_records, untimed_again);
}

/// Options out of range are errors naming the parameter, before any
/// work (nothing is written).
#[test]
fn bad_options_are_errors_naming_the_parameter() {
    let dir = common::ScratchDir::new("compare-api-errors");
    let scene = load_scene(&quad_path()).expect("quad loads");
    let out = dir.0.join("out");
    let cases = [
        (
            "--samples",
            CompareOptions {
                samples: vec![0],
                ..small(&dir.0)
            },
        ),
        (
            "--reference-samples",
            CompareOptions {
                reference_samples: 63,
                ..small(&dir.0)
            },
        ),
        (
            "--repeat",
            CompareOptions {
                repeat: 0,
                ..small(&dir.0)
            },
        ),
        (
            "--techniques",
            CompareOptions {
                techniques: Vec::new(),
                ..small(&dir.0)
            },
        ),
        (
            "--height",
            CompareOptions {
                height: Some(0),
                ..small(&dir.0)
            },
        ),
    ];
    for (param, options) in cases {
        let error = compare(std::slice::from_ref(&scene), &options, Some(&out))
            .expect_err(param)
            .to_string();
        assert!(error.contains(param), "{param}: {error}");
        assert!(!out.exists(), "{param}: nothing written");
    }
}
