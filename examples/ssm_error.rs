//! Soft shadow maps against the ray-traced reference: the measurements of
//! docs/algorithms/soft-shadow-maps.md (`cargo run --release --example
//! ssm_error [quick]`). Prints markdown tables: RMSE over all pixels, MAE
//! in the reference's penumbra, the paper's metric (Σ|Δ| over pixels in
//! umbra or penumbra of the reference / their number) and render time.

use penumbra::render::{render, Aov, RenderOptions};
use penumbra::report::Progress;
use penumbra::scene::{load_scene, Scene};
use penumbra::shadow::soft_shadow_map::Accumulate;
use penumbra::shadow::Technique;
use std::time::Instant;

const SIZE: u32 = 160;

fn scene_from(name: &str, edit: impl Fn(String) -> String) -> Scene {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let text = std::fs::read_to_string(dir.join(name)).unwrap();
    let text = text.replace(
        "obj = \"models/",
        &format!("obj = \"{}/models/", dir.display()),
    );
    let path = std::env::temp_dir().join(format!("ssm-error-{}", name));
    std::fs::write(&path, edit(text)).unwrap();
    load_scene(&path).unwrap()
}

struct Run {
    vcoef: Vec<f32>,
    ground: Vec<bool>,
    seconds: f64,
}

fn run(scene: &Scene, technique: &str, f: impl Fn(&mut RenderOptions)) -> Run {
    let mut o = RenderOptions {
        width: Some(SIZE),
        height: Some(SIZE),
        technique: Technique::named(technique).unwrap(),
        samples: 1024,
        aovs: vec![Aov::Position],
        ..RenderOptions::default()
    };
    f(&mut o);
    let t = Instant::now();
    let out = render(scene, &o, &Progress::hidden()).unwrap();
    let seconds = t.elapsed().as_secs_f64();
    let y = &out
        .layers
        .iter()
        .find(|l| l.name == "position")
        .unwrap()
        .channels[1]
        .1;
    Run {
        vcoef: out.lights[0].vcoef().to_vec(),
        ground: y.iter().map(|y| y.abs() < 1e-3).collect(),
        seconds,
    }
}

/// (RMSE, MAE in penumbra, paper's metric) over pixels `keep`.
fn metrics(a: &[f32], r: &[f32], keep: &[bool]) -> (f64, f64, f64) {
    let (mut se, mut n) = (0.0, 0usize);
    let (mut pen, mut np) = (0.0, 0usize);
    let (mut paper, mut nq) = (0.0, 0usize);
    for ((&a, &r), &k) in a.iter().zip(r).zip(keep) {
        if !k {
            continue;
        }
        let d = (a - r).abs() as f64;
        se += d * d;
        n += 1;
        if r > 0.01 && r < 0.99 {
            pen += d;
            np += 1;
        }
        if r < 0.99 {
            paper += d;
            nq += 1;
        }
    }
    (
        (se / n.max(1) as f64).sqrt(),
        pen / np.max(1) as f64,
        paper / nq.max(1) as f64,
    )
}

fn main() {
    let quick = std::env::args().any(|a| a == "quick");
    if std::env::args().any(|a| a == "height") {
        return height();
    }
    let scenes: Vec<(&str, Scene)> = ["quad.toml", "spheres.toml", "bunny.toml"]
        .iter()
        .map(|n| (*n, scene_from(n, |s| s)))
        .collect();
    let sizes: &[u32] = if quick {
        &[128, 512]
    } else {
        &[64, 128, 256, 512, 1024, 2048]
    };
    let all = |r: &Run| vec![true; r.vcoef.len()];
    println!("## Map size and passes (f32, bilinear), {SIZE}² pixels, reference 1024 spp\n");
    println!("| scene | map | passes | RMSE | MAE penumbra | paper metric | RMSE ground | paper metric ground | time (s) |");
    println!("|---|---|---|---|---|---|---|---|---|");
    let mut refs = Vec::new();
    for (name, scene) in &scenes {
        let reference = run(scene, "reference", |_| {});
        for &size in sizes {
            for passes in [1u8, 2] {
                let r = run(scene, "soft-shadow-map", |o| {
                    o.options.shadow_map.map_size = size;
                    o.options.ssm.ssm_passes = passes;
                });
                let (rmse, mae, paper) = metrics(&r.vcoef, &reference.vcoef, &all(&r));
                let (rg, _, pg) = metrics(&r.vcoef, &reference.vcoef, &r.ground);
                println!(
                    "| {name} | {size} | {passes} | {rmse:.4} | {mae:.4} | {paper:.4} | {rg:.4} | {pg:.4} | {:.3} |",
                    r.seconds
                );
            }
        }
        let hard = run(scene, "shadow-map", |o| {
            o.options.shadow_map.map_size = 1024
        });
        let (rmse, mae, paper) = metrics(&hard.vcoef, &reference.vcoef, &all(&hard));
        let (rg, _, pg) = metrics(&hard.vcoef, &reference.vcoef, &hard.ground);
        println!(
            "| {name} | shadow-map 1024 | — | {rmse:.4} | {mae:.4} | {paper:.4} | {rg:.4} | {pg:.4} | {:.3} |",
            hard.seconds
        );
        refs.push(reference);
    }
    println!("\n## Accumulation and look-up (1 pass)\n");
    println!("| scene | map | variant | RMSE | MAE penumbra | paper metric | time (s) |");
    println!("|---|---|---|---|---|---|---|");
    for ((name, scene), reference) in scenes.iter().zip(&refs) {
        for &size in if quick {
            &[512u32][..]
        } else {
            &[128u32, 512, 2048][..]
        } {
            for (label, acc, nearest, bottom) in [
                ("f16", Accumulate::F16, false, false),
                ("f16-batched", Accumulate::F16Batched, false, false),
                ("nearest", Accumulate::F32, true, false),
                ("bottom patches", Accumulate::F32, false, true),
            ] {
                let r = run(scene, "soft-shadow-map", |o| {
                    o.options.shadow_map.map_size = size;
                    o.options.ssm.ssm_accumulate = acc;
                    o.options.ssm.ssm_bottom_patches = bottom;
                    if nearest {
                        o.options.ssm.ssm_lookup =
                            penumbra::shadow::soft_shadow_map::Lookup::Nearest;
                    }
                });
                let (rmse, mae, paper) = metrics(&r.vcoef, &reference.vcoef, &all(&r));
                println!(
                    "| {name} | {size} | {label} | {rmse:.4} | {mae:.4} | {paper:.4} | {:.3} |",
                    r.seconds
                );
            }
        }
    }
    println!("\n## Self-shadowing: error on the ground only (512² map, 1 pass)\n");
    println!("| scene | split | RMSE ground | MAE penumbra ground | paper metric ground |");
    println!("|---|---|---|---|---|");
    for (i, (name, scene)) in scenes.iter().enumerate() {
        if *name == "spheres.toml" {
            continue;
        }
        let split = scene_from(name, |s| split_flags(&s));
        for (label, sc) in [
            ("every caster receives (default)", scene),
            ("paper's split", &split),
        ] {
            let r = run(sc, "soft-shadow-map", |o| {
                o.options.shadow_map.map_size = 512
            });
            let (rmse, mae, paper) = metrics(&r.vcoef, &refs[i].vcoef, &r.ground);
            println!("| {name} | {label} | {rmse:.4} | {mae:.4} | {paper:.4} |");
        }
    }
    if quick {
        return;
    }
    println!("\n## Light size (quad and bunny, 256² map, 1 and 2 passes)\n");
    println!(
        "| scene | light half-size | passes | RMSE | MAE penumbra | paper metric | time (s) |"
    );
    println!("|---|---|---|---|---|---|---|");
    for (name, from) in [("quad.toml", "0.5"), ("bunny.toml", "0.6")] {
        for h in ["0.02", "0.1", "0.25", "0.5", "1.0"] {
            let sc = scene_from(name, |s| {
                s.replace(
                    &format!("u = [{from}, 0.0, 0.0]"),
                    &format!("u = [{h}, 0.0, 0.0]"),
                )
                .replace(
                    &format!("v = [0.0, 0.0, {from}]"),
                    &format!("v = [0.0, 0.0, {h}]"),
                )
            });
            let reference = run(&sc, "reference", |_| {});
            for passes in [1u8, 2] {
                let r = run(&sc, "soft-shadow-map", |o| {
                    o.options.shadow_map.map_size = 256;
                    o.options.ssm.ssm_passes = passes;
                });
                let (rmse, mae, paper) = metrics(&r.vcoef, &reference.vcoef, &all(&r));
                println!(
                    "| {name} | {h} | {passes} | {rmse:.4} | {mae:.4} | {paper:.4} | {:.3} |",
                    r.seconds
                );
            }
        }
    }
    height();
}

fn height() {
    println!("\n## Occluder height (quad, split flags, 256² map; light at 4)\n");
    println!("| occluder height | RMSE | MAE penumbra | paper metric | time (s) |");
    println!("|---|---|---|---|---|");
    for y in ["0.05", "0.25", "1.0", "2.0", "3.0", "3.75", "3.95"] {
        let sc = scene_from("quad.toml", |s| {
            split_flags(&s).replace(
                "translate = [0.0, 1.0, 0.0]",
                &format!("translate = [0.0, {y}, 0.0]"),
            )
        });
        let reference = run(&sc, "reference", |_| {});
        let r = run(&sc, "soft-shadow-map", |o| {
            o.options.shadow_map.map_size = 256
        });
        let (rmse, mae, paper) = metrics(&r.vcoef, &reference.vcoef, &r.ground);
        println!(
            "| {y} | {rmse:.4} | {mae:.4} | {paper:.4} | {:.3} |",
            r.seconds
        );
    }
}

/// The paper's split: the ground only receives, every other object only
/// casts (the ground is each shipped scene's first object).
fn split_flags(s: &str) -> String {
    let mut out = String::new();
    let mut first = true;
    for (i, block) in s.split("[[object]]").enumerate() {
        if i == 0 {
            out.push_str(block);
            continue;
        }
        out.push_str("[[object]]");
        out.push_str(block.trim_end());
        out.push_str(if first {
            "\ncast_shadows = false\n\n"
        } else {
            "\nreceive_shadows = false\n\n"
        });
        first = false;
    }
    out
}
