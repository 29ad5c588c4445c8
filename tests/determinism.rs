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
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenes")
            .join(name);
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
        assert!(
            one.radiance.iter().all(|c| c.is_finite()),
            "{name}: NaN/inf"
        );
        let reference = bits(&one);
        for threads in [2, 8] {
            assert!(
                bits(&run(threads)) == reference,
                "{name}: {threads} threads differ from 1"
            );
        }
    }
}

/// The SIMD resolve agrees with its scalar twin: same triangles, hit
/// points and normals within a few f64 roundings (stored as f32).
#[test]
fn simd_resolve_matches_scalar_twin() {
    use penumbra::gbuffer::{resolve, resolve_scalar, transform_vertices, visibility_pass};
    use penumbra::geom::SceneGeometry;
    for name in ["spheres.toml", "bunny.toml"] {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenes")
            .join(name);
        let scene = load_scene(&path).expect("scene");
        let options = RenderOptions {
            width: Some(160),
            height: Some(120),
            ..RenderOptions::default()
        };
        let view = penumbra::render::view_for(&scene, &options).expect("view");
        let geometry = SceneGeometry::new(&scene);
        let vertices = transform_vertices(&geometry, &view);
        let (_, ids, _) = visibility_pass(&scene, &geometry, &view, &vertices).expect("draw");
        let simd = resolve(&scene, &geometry, &view, &ids).expect("resolve");
        let scalar = resolve_scalar(&scene, &geometry, &view, &ids).expect("resolve");
        let mut surfaces = 0;
        for (a, b) in simd.samples().zip(scalar.samples()) {
            assert_eq!(a.triangle, b.triangle);
            if !a.is_surface() {
                continue;
            }
            surfaces += 1;
            let scale = a.position.abs().max_element().max(1.0);
            assert!(
                (a.position - b.position).abs().max_element() <= 1e-6 * scale,
                "{a:?} {b:?}"
            );
            assert!((a.normal - b.normal).abs().max_element() <= 1e-6);
            assert!((a.geo_normal - b.geo_normal).abs().max_element() <= 1e-6);
            assert!((a.depth - b.depth).abs() <= 1e-6 * a.depth.max(1.0));
            assert_eq!(a.albedo, b.albedo);
        }
        assert!(surfaces > 1000, "{name}: only {surfaces} surface pixels");
    }
}
