//! Shadow maps rendered per second (the depth pass of the opaque casters
//! through a light view, `kit::shadow_maps::opaque_depth_map`) at 512² and
//! 1024² on `scenes/spheres.toml` (61,562 triangles) and
//! `scenes/bunny.toml`, from the light's centre; and the whole multi-map
//! technique with 64 maps on spheres at 512² (image and maps), the
//! configuration of `../shared/peers/glsv`'s 64-pass accumulation
//! (docs/performance.md).
//!
//! Run: `cargo bench --bench shadow_maps`. Criterion reports elements/s =
//! maps per second (maps per second × 64 for the multi-map group).
//!
//! The `penumbra` binary sets glibc's allocator to keep freed memory
//! (`src/main.rs`); a bench binary does not run that `main`, so run it with
//! the same setting for figures comparable with the command line:
//! `GLIBC_TUNABLES=glibc.malloc.mmap_threshold=33554432:glibc.malloc.trim_threshold=2147483647`.
//! The multi-map group renders 4 maps per receiver pass (`multi_map::BATCH`).

// `criterion_main!` defines an undocumented `pub fn main`.
#![allow(missing_docs)]

mod common;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use penumbra::internal::geom::SceneGeometry;
use penumbra::internal::scene::{load_scene, Scene};
use penumbra::internal::shadow::kit::light_view::{caster_bounds, receiver_bounds};
use penumbra::internal::shadow::kit::shadow_maps::{centre_point, light_view_at, opaque_depth_map};
use penumbra::internal::shadow::multi_map::MultiMap;
use penumbra::internal::shadow::{ShadowTechnique, TechniqueOptions};
use std::path::Path;

fn scene(name: &str) -> Scene {
    load_scene(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenes")
            .join(name),
    )
    .expect("shipped scene loads")
}

fn maps_per_second(c: &mut Criterion) {
    let mut group = c.benchmark_group("shadow_maps");
    group.sample_size(20);
    for name in ["spheres.toml", "bunny.toml"] {
        let scene = scene(name);
        let geometry = SceneGeometry::new(&scene);
        let casters = caster_bounds(&scene).expect("casters");
        let receivers = receiver_bounds(&scene).expect("receivers");
        let light = &scene.lights[0];
        for size in [512u32, 1024] {
            let lv = light_view_at(
                light,
                centre_point(light, casters),
                casters,
                receivers,
                (size, size),
            )
            .expect("view")
            .expect("casters in front");
            group.throughput(Throughput::Elements(1));
            group.bench_function(format!("{name}_{size}"), |b| {
                b.iter(|| opaque_depth_map(&scene, &geometry, &lv.view).expect("map"))
            });
        }
    }
    group.finish();
}

fn multi_map_64(c: &mut Criterion) {
    let prepared = common::Prepared::new("spheres.toml", 512);
    let cache = prepared.cache();
    let ctx = prepared.ctx(&cache);
    let mut maps = TechniqueOptions::default().shadow_map;
    maps.map_size = 512;
    let technique = MultiMap {
        maps: 64,
        pattern: penumbra::internal::sampling::SamplePattern::Stratified,
        seed: 0,
        options: maps,
    };
    let mut group = c.benchmark_group("multi_map_spheres_512");
    group.sample_size(10);
    group.throughput(Throughput::Elements(64));
    group.bench_function("64_maps", |b| {
        b.iter(|| technique.compute(&ctx).expect("multi-map"))
    });
    group.finish();
}

criterion_group!(benches, maps_per_second, multi_map_64);
criterion_main!(benches);
