//! Same scene and options, same bits, whatever the thread count.
//! (The SIMD-level half of the promise is checked by `.ci/run`, which
//! builds for several `target-cpu` levels and compares the images.)

use penumbra::render::{render, with_threads, Aov, RenderOptions};
use penumbra::report::Progress;
use penumbra::scene::load_scene;
use std::path::Path;

fn bits(out: &penumbra::render::RenderOutput) -> Vec<u32> {
    let mut v: Vec<u32> = out
        .radiance
        .iter()
        .flat_map(|c| c.to_array().map(f32::to_bits))
        .collect();
    for layer in &out.layers {
        for (_, ch) in &layer.channels {
            v.extend(ch.iter().map(|x| x.to_bits()));
        }
    }
    v
}

#[test]
fn bit_identical_for_1_2_and_8_threads() {
    for name in ["spheres.toml", "quad.toml"] {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes").join(name);
        let scene = load_scene(&path).expect("shipped scene loads");
        let options = RenderOptions {
            width: Some(203), // odd sizes: partial tiles and blocks
            height: Some(157),
            aovs: Aov::ALL.to_vec(),
            ..RenderOptions::default()
        };
        let run = |threads| {
            with_threads(Some(threads), || {
                render(&scene, &options, &Progress::hidden()).expect("render")
            })
            .expect("pool")
        };
        let one = run(1);
        assert!(
            one.radiance.iter().any(|c| c.x > 0.0),
            "{name}: image is black"
        );
        assert!(one.radiance.iter().all(|c| c.is_finite()), "{name}: NaN/inf");
        let reference = bits(&one);
        for threads in [2, 8] {
            assert!(bits(&run(threads)) == reference, "{name}: {threads} threads differ from 1");
        }
    }
}
