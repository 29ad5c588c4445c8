//! Same scene and options, same bits, whatever the thread count.
//! (The SIMD-level half of the promise is checked by `.ci/run`, which
//! builds for several `target-cpu` levels and compares the images.)

use crate::common;

use penumbra::internal::render::{render, with_threads, Aov, RenderOptions};
use penumbra::internal::scene::{load_scene, Scene};
use std::path::Path;

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
            with_threads(Some(threads), || render(&scene, &options).expect("render")).expect("pool")
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
        let reference = common::render_bits(&one);
        for threads in [2, 8] {
            assert!(
                common::render_bits(&run(threads)) == reference,
                "{name}: {threads} threads differ from 1"
            );
        }
    }
}

/// A scene with an albedo texture (the G-buffer then keeps per-pixel
/// albedo): a textured ground quad (flat), a textured sphere (smooth) and
/// an untextured box, seen from above at an angle.
fn textured_scene() -> Scene {
    let mut png = Vec::new();
    // 2×1: red | blue (sRGB 255 decodes to linear 1).
    image::RgbImage::from_raw(2, 1, vec![255, 0, 0, 0, 0, 255])
        .expect("2×1 image")
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .expect("encode png");
    common::scene_in_scratch(
        "determinism-textured",
        r#"
[camera]
eye = [0.5, 4.0, 3.0]
target = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 50.0

[[light]]
type = "rect"
center = [0.0, 3.0, 0.0]
u = [0.5, 0.0, 0.0]
v = [0.0, 0.0, 0.5]
radiance = [4.0, 4.0, 4.0]

[[object]]
shape = "quad"
size = [4.0, 4.0]
material = { albedo = [0.5, 0.5, 0.5], albedo_texture = "rb.png" }

[[object]]
shape = "sphere"
radius = 0.6
translate = [-0.8, 0.6, 0.2]
material = { albedo = [0.9, 0.9, 0.9], albedo_texture = "rb.png" }

[[object]]
shape = "box"
size = [0.6, 0.6, 0.6]
translate = [0.9, 0.3, -0.4]
material = { albedo = [0.2, 0.7, 0.3] }
"#,
        &[("rb.png", &png[..])],
    )
}

/// The SIMD resolve agrees with its scalar twin: same triangles, hit
/// points and normals within a few f64 roundings (stored as f32), the
/// same albedo (textured or not).
#[test]
fn simd_resolve_matches_scalar_twin() {
    use penumbra::internal::gbuffer::{
        resolve, resolve_scalar, transform_vertices, visibility_pass,
    };
    use penumbra::internal::geom::SceneGeometry;
    let scenes = [
        ("spheres", common::shipped("spheres.toml")),
        ("bunny", common::shipped("bunny.toml")),
        ("textured", textured_scene()),
    ];
    for (name, scene) in &scenes {
        let options = RenderOptions {
            width: Some(160),
            height: Some(120),
            ..RenderOptions::default()
        };
        let view = penumbra::internal::render::view_for(scene, &options).expect("view");
        let geometry = SceneGeometry::new(scene);
        let vertices = transform_vertices(&geometry, &view);
        let (_, ids, _) = visibility_pass(scene, &geometry, &view, &vertices).expect("draw");
        let simd = resolve(scene, &geometry, &view, &ids).expect("resolve");
        let scalar = resolve_scalar(scene, &geometry, &view, &ids).expect("resolve");
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

/// Albedo textures reach the G-buffer: the textured objects show both
/// texels (times their material albedo), the untextured box its albedo,
/// and a render is the same for 1 and 2 threads.
#[test]
fn textured_albedo_in_gbuffer() {
    use penumbra::internal::gbuffer::gbuffer_pass;
    use penumbra::internal::geom::SceneGeometry;
    let scene = textured_scene();
    let options = RenderOptions {
        width: Some(97),
        height: Some(83),
        aovs: Aov::ALL.to_vec(),
        ..RenderOptions::default()
    };
    let view = penumbra::internal::render::view_for(&scene, &options).expect("view");
    let geometry = SceneGeometry::new(&scene);
    let (gbuffer, _, _) = gbuffer_pass(&scene, &geometry, &view).expect("g-buffer");
    let seen = |object: u32, albedo: [f32; 3]| {
        gbuffer
            .samples()
            .any(|g| g.is_surface() && g.object == object && g.albedo.to_array() == albedo)
    };
    for (object, grey) in [(0, 0.5), (1, 0.9)] {
        assert!(
            seen(object, [grey, 0.0, 0.0]),
            "object {object}: no red texel"
        );
        assert!(
            seen(object, [0.0, 0.0, grey]),
            "object {object}: no blue texel"
        );
    }
    assert!(gbuffer
        .samples()
        .filter(|g| g.is_surface() && g.object == 2)
        .all(|g| g.albedo.to_array() == [0.2, 0.7, 0.3]));
    assert!(seen(2, [0.2, 0.7, 0.3]), "box not seen");
    let run = |threads| {
        with_threads(Some(threads), || render(&scene, &options).expect("render")).expect("pool")
    };
    assert!(common::render_bits(&run(1)) == common::render_bits(&run(2)));
}

/// The sampling techniques with semi-opaque casters and S-triangles:
/// per-sample transmittance, STSV look-ups and the interleaved gather give
/// the same bits for any thread count.
#[test]
fn shadow_techniques_bit_identical_across_threads() {
    use penumbra::internal::render::Technique;
    use penumbra::internal::sampling::SamplePattern;
    for (name, technique, pattern) in [
        (
            "tinted.toml",
            Technique::named("dcs").unwrap(),
            SamplePattern::Stratified,
        ),
        (
            "fence.toml",
            Technique::named("dcs").unwrap(),
            SamplePattern::Interleaved { n: 3 },
        ),
        (
            "fence.toml",
            Technique::named("wedges").unwrap(),
            SamplePattern::Stratified,
        ),
    ] {
        let scene = common::shipped(name);
        let options = RenderOptions {
            width: Some(131),
            height: Some(97),
            aovs: Aov::ALL.to_vec(),
            technique,
            samples: 16,
            pattern,
            ..RenderOptions::default()
        };
        let run = |threads| {
            with_threads(Some(threads), || render(&scene, &options).expect("render")).expect("pool")
        };
        let one = common::render_bits(&run(1));
        for threads in [2, 8] {
            assert!(
                common::render_bits(&run(threads)) == one,
                "{name} {technique:?}: {threads} threads differ from 1"
            );
        }
    }
}
