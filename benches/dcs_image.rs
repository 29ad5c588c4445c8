//! The exact image's cost: depth complexity sampling in its default
//! `direct` mode (the light integrated per sample with its binary
//! visibility, the exact image) against its `vcoef` mode (the unshadowed
//! light times the visibility coefficient, thesis eq. 4.1, an
//! approximation of the image), on `scenes/spheres.toml` and
//! `scenes/bunny.toml` at 1024², 64 and 256 stratified light samples, 2
//! threads. What is timed is what differs between the two: the technique
//! on a prebuilt G-buffer plus the shading pass that turns its terms into
//! radiance (`vcoef` shades every pixel with the closed-form unshadowed
//! light there; `direct` has done its radiance already, and shading only
//! adds the ambient term). Geometry and G-buffer are the same for both and
//! excluded.
//!
//! The target is `direct` at most 1.2× `vcoef` at each setting
//! (docs/performance.md has the figures and the command).
//!
//! Run: `cargo bench --bench dcs_image`.

// `criterion_main!` defines an undocumented `pub fn main`.
#![allow(missing_docs)]

mod common;

use criterion::{criterion_group, criterion_main, Criterion};
use penumbra::internal::render::shade;
use penumbra::internal::sampling::SamplePattern;
use penumbra::internal::shadow::dcs::{DcsMode, DepthComplexitySampling, SilhouetteMode};
use penumbra::internal::shadow::ShadowTechnique;
use std::time::Duration;

const SIZE: u32 = 1024;

fn dcs_image(c: &mut Criterion) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("thread pool");
    for scene in ["spheres", "bunny"] {
        let prepared = common::Prepared::new(&format!("{scene}.toml"), SIZE);
        let cache = prepared.cache();
        let ctx = prepared.ctx(&cache);
        let mut group = c.benchmark_group(format!("dcs_image_{scene}_{SIZE}_2t"));
        group.sample_size(10);
        group.warm_up_time(Duration::from_secs(1));
        group.measurement_time(Duration::from_secs(10));
        for samples in [64, 256] {
            for mode in [DcsMode::Vcoef, DcsMode::Direct] {
                let technique = DepthComplexitySampling {
                    samples,
                    seed: 0,
                    silhouettes: SilhouetteMode::WholeLight,
                    mode,
                    pattern: SamplePattern::Stratified,
                    transmittance: Default::default(),
                    coverage: Default::default(),
                    opacity_filter: Default::default(),
                    rays: penumbra::internal::shadow::dcs::RayChoice::Never,
                };
                group.bench_function(format!("{}_{samples}spp", mode.name()), |b| {
                    b.iter(|| {
                        pool.install(|| {
                            let out = technique.compute(&ctx).expect("dcs runs");
                            shade(
                                &prepared.scene,
                                &prepared.view,
                                &prepared.gbuffer,
                                &out.lights,
                            )
                        })
                    })
                });
            }
        }
        group.finish();
    }
}

criterion_group!(benches, dcs_image);
criterion_main!(benches);
