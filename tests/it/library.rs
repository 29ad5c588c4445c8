//! The library through its public interface only (the crate root): no
//! `penumbra::internal` here (the shared test helpers aside), so this file
//! fails to build when the interface loses something a program needs.

use crate::common;
use penumbra::{
    load_scene, render, render_with, scene_from_toml, techniques, Aov, Cancel, Error, Observer,
    RenderOptions, Technique,
};
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

const SCENE: &str = r#"
[camera]
eye = [0.0, 5.0, 6.0]
target = [0.0, 0.0, 0.0]
fov_y = 45
width = 40
height = 30
[[light]]
type = "rect"
center = [0.0, 4.0, 0.0]
u = [0.5, 0.0, 0.0]
v = [0.0, 0.0, 0.5]
radiance = 10
[[object]]
name = "ground"
shape = "quad"
size = [6.0, 6.0]
[[object]]
name = "occluder"
shape = "sphere"
radius = 0.5
translate = [0.0, 1.0, 0.0]
"#;

fn scene() -> penumbra::Scene {
    scene_from_toml(SCENE, Path::new(".")).expect("the scene loads")
}

fn options(technique: &str, threads: Option<usize>) -> RenderOptions {
    RenderOptions {
        technique: Technique::named(technique).expect("a registered technique"),
        samples: 16,
        aovs: vec![Aov::Depth, Aov::Mask, Aov::Vcoef],
        threads,
        ..RenderOptions::default()
    }
}

#[test]
fn a_render_holds_its_layers_lights_timings_and_explain() {
    let image = render(&scene(), &options("dcs", None)).expect("render");
    let pixels = 40 * 30;
    assert_eq!((image.width, image.height), (40, 30));
    assert_eq!(image.radiance.len(), pixels);
    assert!(image.radiance.iter().all(|c| c.is_finite()));
    // The requested layers, in AOV order, one f32 per pixel and channel.
    let names: Vec<&str> = image.layers.iter().map(|l| l.name.as_str()).collect();
    assert_eq!(&names[..3], ["depth", "mask", "vcoef"]);
    let mask = &image.layer("mask").expect("mask").channels[0].1;
    let depth = &image.layer("depth").expect("depth").channels[0].1;
    assert_eq!(mask.len(), pixels);
    assert!(mask.iter().all(|&m| m == 0.0 || m == 1.0));
    assert!(mask
        .iter()
        .zip(depth)
        .all(|(&m, &d)| (m == 1.0) == (d > 0.0)));
    // The vcoef layer is the light's term.
    let vcoef = &image.layer("vcoef").expect("vcoef").channels[0].1;
    let term = image.lights[0].vcoef();
    assert!(vcoef
        .iter()
        .zip(term)
        .zip(mask)
        .all(|((a, b), &m)| m == 0.0 || a == b));
    assert!(term.iter().any(|&v| v < 0.5) && term.contains(&1.0));
    // Every stage is timed; the explain report is data.
    let passes: Vec<&str> = image.passes.iter().map(|p| p.name.as_str()).collect();
    for stage in ["geometry", "gbuffer", "shading"] {
        assert!(passes.contains(&stage), "{passes:?}");
    }
    assert_eq!(image.explain.technique, "dcs");
    assert_eq!(image.explain.samples, 16);
    assert!(image.explain.buffers.iter().any(|b| b.name == "g-buffer"));
}

#[test]
fn the_bits_do_not_depend_on_the_thread_count() {
    let scene = scene();
    for technique in ["dcs", "reference", "penumbra-casting"] {
        let one = render(&scene, &options(technique, Some(1))).expect("render");
        let two = render(&scene, &options(technique, Some(2))).expect("render");
        let all = render(&scene, &options(technique, None)).expect("render");
        assert_eq!(one.explain.threads, 1);
        assert_eq!(two.explain.threads, 2);
        assert!(
            common::render_bits(&one) == common::render_bits(&two)
                && common::render_bits(&one) == common::render_bits(&all),
            "{technique}"
        );
    }
}

#[test]
fn a_file_and_its_text_give_the_same_image() {
    let dir = std::env::temp_dir().join(format!("penumbra-library-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("scene.toml");
    std::fs::write(&path, SCENE).unwrap();
    let from_file = render(&load_scene(&path).expect("load"), &options("dcs", None)).unwrap();
    let from_text = render(&scene(), &options("dcs", None)).unwrap();
    assert!(common::render_bits(&from_file) == common::render_bits(&from_text));
    std::fs::remove_dir_all(&dir).ok();
}

/// Records the stages it hears; cancels once `cancel_after` polls have
/// been made (never when `None`).
struct Recorder {
    stages: Mutex<Vec<String>>,
    steps: AtomicUsize,
    polls: AtomicUsize,
    cancel_after: Option<usize>,
}

impl Recorder {
    fn new(cancel_after: Option<usize>) -> Self {
        Recorder {
            stages: Mutex::new(Vec::new()),
            steps: AtomicUsize::new(0),
            polls: AtomicUsize::new(0),
            cancel_after,
        }
    }
}

impl Observer for Recorder {
    fn stage(&self, name: &str) {
        self.stages.lock().unwrap().push(name.to_string());
    }
    fn step(&self) {
        self.steps.fetch_add(1, Ordering::Relaxed);
    }
    fn cancelled(&self) -> bool {
        let polls = self.polls.fetch_add(1, Ordering::Relaxed) + 1;
        self.cancel_after.is_some_and(|n| polls > n)
    }
}

#[test]
fn an_observer_hears_every_stage_and_changes_no_bit() {
    let scene = scene();
    let recorder = Recorder::new(None);
    let heard = render_with(&scene, &options("dcs", Some(2)), &recorder).expect("render");
    let silent = render(&scene, &options("dcs", Some(2))).expect("render");
    assert!(common::render_bits(&heard) == common::render_bits(&silent));
    let stages = recorder.stages.lock().unwrap().clone();
    assert_eq!(stages, ["geometry", "g-buffer", "shadows", "shading"]);
    assert_eq!(recorder.steps.load(Ordering::Relaxed), 4);
    // Polled between passes and inside the technique's tile loop.
    assert!(recorder.polls.load(Ordering::Relaxed) > 4);
}

#[test]
fn a_cancelled_render_returns_cancelled_and_no_image() {
    let scene = scene();
    for technique in ["dcs", "reference", "penumbra-casting", "shadow-volumes"] {
        // Raised before the start: stopped after the first pass.
        let cancel = Cancel::new();
        cancel.cancel();
        let result = render_with(&scene, &options(technique, None), &cancel);
        assert!(matches!(result, Err(Error::Cancelled)), "{technique}");
        // Raised inside the shadow pass (the third poll is the technique's
        // first): the pass stops early and the render says so.
        let recorder = Recorder::new(Some(2));
        let result = render_with(&scene, &options(technique, Some(2)), &recorder);
        assert!(matches!(result, Err(Error::Cancelled)), "{technique}");
        assert!(!recorder
            .stages
            .lock()
            .unwrap()
            .contains(&"shading".to_string()));
    }
    // A flag raised from another thread while the render runs.
    let cancel = Cancel::new();
    let many = RenderOptions {
        samples: 4096,
        width: Some(400),
        height: Some(300),
        ..options("reference", Some(1))
    };
    let stopped = std::thread::scope(|s| {
        let render = s.spawn(|| render_with(&scene, &many, &cancel));
        std::thread::sleep(std::time::Duration::from_millis(200));
        cancel.cancel();
        let start = std::time::Instant::now();
        let result = render.join().unwrap();
        (result, start.elapsed())
    });
    assert!(matches!(stopped.0, Err(Error::Cancelled)));
    // Loose on purpose (a busy machine): a 400×300 reference at 4096
    // samples on one thread takes minutes; a row takes milliseconds.
    assert!(stopped.1.as_secs_f64() < 10.0, "{:?}", stopped.1);
}

#[test]
fn the_library_refuses_bad_options_by_name() {
    let scene = scene();
    for (options, name) in [
        (
            RenderOptions {
                samples: 0,
                ..RenderOptions::default()
            },
            "--samples",
        ),
        (
            RenderOptions {
                threads: Some(0),
                ..RenderOptions::default()
            },
            "--threads",
        ),
        (
            RenderOptions {
                width: Some(0),
                ..RenderOptions::default()
            },
            "--width",
        ),
    ] {
        match render(&scene, &options) {
            Err(Error::Parameter { name: got, .. }) => assert_eq!(got, name),
            other => panic!("{name}: {other:?}"),
        }
    }
    assert!(Technique::named("no-such-technique").is_err());
}

#[test]
fn a_scene_error_names_the_file_and_line() {
    let text = "[camera]\neye = [0, 1, 2]\nfov_y = \"wide\"\n";
    let message = scene_from_toml(text, Path::new("."))
        .expect_err("refused")
        .to_string();
    assert!(message.contains(":3"), "{message}");
}

#[test]
fn the_techniques_are_data() {
    let all = techniques();
    let names: Vec<&str> = all.iter().map(|t| t.name).collect();
    for name in ["dcs", "reference", "penumbra-casting", "shadow-volumes"] {
        assert!(names.contains(&name), "{names:?}");
    }
    let exact: Vec<&str> = all.iter().filter(|t| t.exact).map(|t| t.name).collect();
    assert!(exact.contains(&"dcs") && exact.contains(&"reference"));
    assert!(!exact.contains(&"shadow-map"));
}

#[test]
fn a_cancelled_compare_returns_cancelled_and_writes_no_tables() {
    let dir = std::env::temp_dir().join(format!("penumbra-library-cmp-{}", std::process::id()));
    let options = penumbra::CompareOptions {
        techniques: vec![Technique::named("dcs").unwrap()],
        samples: vec![4],
        reference_samples: 64,
        repeat: 1,
        width: Some(16),
        height: Some(12),
        cache_dir: dir.join("cache"),
        images: false,
        ..penumbra::CompareOptions::default()
    };
    let out = dir.join("out");
    let cancel = Cancel::new();
    cancel.cancel();
    let result = penumbra::compare_with(&[scene()], &options, Some(&out), &cancel);
    assert!(matches!(result, Err(Error::Cancelled)), "{result:?}");
    assert!(!out.join("results.csv").exists());
    // Not raised: the same call gives its records.
    let records =
        penumbra::compare_with(&[scene()], &options, Some(&out), &Cancel::new()).expect("compare");
    assert!(!records.is_empty() && out.join("results.csv").exists());
    std::fs::remove_dir_all(&dir).ok();
}
