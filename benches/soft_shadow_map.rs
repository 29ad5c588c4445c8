//! Soft shadow maps per frame: the shadow technique alone on a prebuilt
//! 512² G-buffer (geometry, G-buffer and shading excluded, as in
//! `benches/dcs.rs`), occluder maps of 256², 512² and 1024², one pass, f32,
//! on `scenes/spheres.toml` and `scenes/bunny.toml`; penumbra wedges on the
//! same G-buffer for scale. Each frame builds the maps, the SSM and does
//! the look-up (nothing is cached between frames). 2 threads.
//!
//! Run: `cargo bench --bench soft_shadow_map`; the time against polygon
//! count is `scripts/ssm-scaling.sh` (docs/performance.md).

// `criterion_main!` defines an undocumented `pub fn main`.
#![allow(missing_docs)]

mod common;

use criterion::{criterion_group, criterion_main, Criterion};
use penumbra::internal::shadow::soft_shadow_map::{SoftShadowMap, SsmOptions};
use penumbra::internal::shadow::wedges::PenumbraWedges;
use penumbra::internal::shadow::{ShadowTechnique, TechniqueOptions};
use std::time::Duration;

const SIZE: u32 = 512;

fn soft_shadow_map(c: &mut Criterion) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("thread pool");
    for name in ["spheres.toml", "bunny.toml"] {
        let prepared = common::Prepared::new(name, SIZE);
        let cache = prepared.cache();
        let ctx = prepared.ctx(&cache);
        let mut group = c.benchmark_group(format!(
            "soft_shadow_map_{}_{SIZE}_2t",
            name.trim_end_matches(".toml")
        ));
        group.sample_size(10);
        group.warm_up_time(Duration::from_secs(1));
        group.measurement_time(Duration::from_secs(10));
        for map_size in [256u32, 512, 1024] {
            let mut map = TechniqueOptions::default().shadow_map;
            map.map_size = map_size;
            let t = SoftShadowMap {
                options: SsmOptions::default(),
                map,
            };
            group.bench_function(format!("map_{map_size}"), |b| {
                b.iter(|| pool.install(|| t.compute(&ctx).expect("soft shadow map runs")))
            });
        }
        group.bench_function("wedges", |b| {
            b.iter(|| pool.install(|| PenumbraWedges.compute(&ctx).expect("wedges run")))
        });
        group.finish();
    }
}

criterion_group!(benches, soft_shadow_map);
criterion_main!(benches);
