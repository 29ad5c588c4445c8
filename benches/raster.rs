//! Raster benchmarks on `scenes/spheres.toml` at 1024²: the depth-only
//! pre-pass, the G-buffer pass (visibility raster + exact resolve) and the
//! hard-shadow stencil pass (volume build + z-fail counts).
//!
//! Run: `cargo bench --bench raster` (set `RAYON_NUM_THREADS=2` to compare
//! with llvmpipe's two-thread figures, see docs/performance.md).

// `criterion_main!` defines an undocumented `pub fn main`.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use penumbra::internal::gbuffer::{depth_pass, gbuffer_pass, transform_vertices, GBufferPass};
use penumbra::internal::geom::SceneGeometry;
use penumbra::internal::render::{view_for, RenderOptions};
use penumbra::internal::scene::load_scene;
use penumbra::internal::shadow::kit::volumes::{
    build_volume, caster_adjacency, light_point, stencil_counts,
};
use std::path::Path;

fn raster(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/spheres.toml");
    let scene = load_scene(&path).expect("shipped scene loads");
    let options = RenderOptions {
        width: Some(1024),
        height: Some(1024),
        ..RenderOptions::default()
    };
    let view = view_for(&scene, &options).expect("view");
    let geometry = SceneGeometry::new(&scene);
    let triangles = geometry.triangles.len() as u64;

    let mut group = c.benchmark_group("spheres_1024");
    group.sample_size(30);
    group.throughput(Throughput::Elements(triangles));
    group.bench_function("depth_prepass", |b| {
        b.iter(|| {
            let vertices = transform_vertices(&geometry, &view);
            depth_pass(&scene, &geometry, &view, &vertices).expect("draw")
        })
    });
    // A frame loop, as glsv times llvmpipe: the pass's buffers are made
    // once and reused, every frame clears and fills them.
    let mut pass = GBufferPass::new(&view).expect("buffers");
    group.bench_function("gbuffer", |b| {
        b.iter(|| pass.run(&scene, &geometry, &view).expect("draw"))
    });
    let (_, depth, _) = gbuffer_pass(&scene, &geometry, &view).expect("gbuffer");
    let adjacency = caster_adjacency(&scene, &geometry);
    let light = light_point(&scene.lights[0].shape);
    let mut framebuffer = depth.clone();
    group.bench_function("stencil_pass", |b| {
        b.iter(|| {
            // Volume build (CPU) + stencil clear + z-fail pass, as glsv's
            // "volume build" + "stencil pass" columns.
            let volume = build_volume(&adjacency, &view, light);
            stencil_counts(&mut framebuffer, &volume, false).expect("stencil")
        })
    });
    group.finish();
}

criterion_group!(benches, raster);
criterion_main!(benches);
