//! Depth complexity sampling against the reference's shadow rays with the
//! same samples, on `scenes/spheres.toml`: the shadow technique alone on a
//! prebuilt G-buffer (geometry, G-buffer and shading are the same for both
//! and excluded), stratified samples, 2 threads. DCS runs with
//! whole-light silhouettes (the default, exact) and centre silhouettes
//! (`--silhouettes centre`, the fast approximation), each at 64 and 256
//! light samples; the reference at 64 beside them.
//!
//! 512² rather than the 1024², so that the whole bench stays under
//! about 2 minutes on 2 cores (each configuration takes 10 samples in at
//! least 8 s); per-pixel costs scale with the pixel count, so the ratios
//! carry over. The 1024² side-by-side with native Embree is
//! `scripts/embree-peer.py` (docs/performance.md).
//!
//! Run: `cargo bench --bench dcs`. The llvmpipe peer (64 accumulated
//! hard-shadow passes, `../shared/peers/glsv`) is measured in the same
//! session by the command in docs/performance.md.

// `criterion_main!` defines an undocumented `pub fn main`.
#![allow(missing_docs)]

mod common;

use criterion::{criterion_group, criterion_main, Criterion};
use penumbra::internal::sampling::SamplePattern;
use penumbra::internal::shadow::dcs::{DcsMode, DepthComplexitySampling, SilhouetteMode};
use penumbra::internal::shadow::reference::Reference;
use penumbra::internal::shadow::ShadowTechnique;
use std::time::Duration;

const SIZE: u32 = 512;

fn dcs(c: &mut Criterion) {
    let prepared = common::Prepared::new("spheres.toml", SIZE);
    let (_scene, _geometry) = (&prepared.scene, &prepared.geometry);
    let cache = prepared.cache();
    let ctx = prepared.ctx(&cache);
    let technique = |silhouettes, samples| DepthComplexitySampling {
        samples,
        seed: 0,
        silhouettes,
        mode: DcsMode::Vcoef,
        pattern: SamplePattern::Stratified,
        transmittance: Default::default(),
        coverage: Default::default(),
        opacity_filter: Default::default(),
        rays: penumbra::internal::shadow::dcs::RayChoice::Never,
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("thread pool");
    let mut group = c.benchmark_group(format!("shadows_spheres_{SIZE}_2t"));
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(8));
    for samples in [64, 256] {
        for (name, sil) in [
            ("dcs_light", SilhouetteMode::WholeLight),
            ("dcs_centre", SilhouetteMode::Centre),
        ] {
            let t = technique(sil, samples);
            group.bench_function(format!("{name}_{samples}spp"), |b| {
                b.iter(|| pool.install(|| t.compute(&ctx).expect("dcs runs")))
            });
        }
    }
    let reference = Reference::new(64, 0);
    group.bench_function("reference_64spp", |b| {
        b.iter(|| pool.install(|| reference.compute(&ctx).expect("reference runs")))
    });
    group.finish();
}

criterion_group!(benches, dcs);
criterion_main!(benches);
