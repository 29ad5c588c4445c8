//! Geometry preparation of the largest scaling scene, step by step, on 2
//! threads: the 81 spheres of `scenes/spheres.toml` tessellated at 160
//! segments × 160 rings (4,121,282 triangles, `spheres81-s160` of
//! `scripts/scaling.py`), as `render --timings` splits it:
//!
//! - `load`: the scene text parsed, validated and tessellated;
//! - `geometry`: the meshes concatenated, each object's closedness, the
//!   unit normals (`SceneGeometry::new`; the edge adjacency is built on
//!   first use, by edge-walking techniques only, and is not part of it);
//! - `bvh`: the shadow rays' BVH over every triangle (`ShadowTracer::new`,
//!   what the reference and DCS's traced lights build).
//!
//! The target (≤ 1.5 s for the three) is in `docs/performance.md`, with
//! the figures this bench gave. Run: `cargo bench --bench geometry`
//! (about 2 minutes; 10 samples of each step).

// `criterion_main!` defines an undocumented `pub fn main`.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use penumbra::internal::geom::SceneGeometry;
use penumbra::internal::shadow::kit::rays::ShadowTracer;
use std::path::Path;
use std::time::Duration;

/// `scenes/spheres.toml` with every sphere at `segments` × `segments`.
fn spheres_text(segments: u32) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/spheres.toml");
    let text = std::fs::read_to_string(&path).expect("read scenes/spheres.toml");
    let text = text
        .replace("segments = 20", &format!("segments = {segments}"))
        .replace("rings = 20", &format!("rings = {segments}"));
    assert_eq!(
        text.matches(&format!("segments = {segments}")).count(),
        81,
        "every sphere retessellated"
    );
    text
}

fn preparation(c: &mut Criterion) {
    let text = spheres_text(160);
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("thread pool");
    let scene = pool
        .install(|| penumbra::scene_from_toml(&text, &dir))
        .expect("the scene loads");
    let geometry = pool.install(|| SceneGeometry::new(&scene));
    let triangles = geometry.triangles.len() as u64;
    assert_eq!(triangles, 4_121_282);

    let mut group = c.benchmark_group("geometry_spheres81_s160_2t");
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(10));
    group.throughput(Throughput::Elements(triangles));
    group.bench_function("load", |b| {
        b.iter(|| pool.install(|| penumbra::scene_from_toml(&text, &dir)))
    });
    group.bench_function("geometry", |b| {
        b.iter(|| pool.install(|| SceneGeometry::new(&scene)))
    });
    group.bench_function("bvh", |b| {
        b.iter(|| pool.install(|| ShadowTracer::new(&scene, &geometry)))
    });
    group.finish();
}

criterion_group!(benches, preparation);
criterion_main!(benches);
