//! Shadow rays per second of the ray-traced reference on
//! `scenes/spheres.toml` (61,562 triangles) at 256², 16 light samples per
//! pixel: one light pass (sampling, BVH any-hit queries, the shared
//! radiance estimator), on 1 and on 2 threads. The BVH is built once,
//! outside the timed loop; its build is timed separately.
//!
//! A second group times the whole technique (as `render` runs it: every
//! light, the estimator, its buffers) at 64 and 256 light samples on 2
//! threads, the sample counts of the DCS bench (benches/dcs.rs) and of the
//! Embree comparison; 256² keeps the whole bench under about 2 minutes on
//! 2 cores (the reference's time is linear in pixels × samples).
//!
//! A third group times the opaque BVH's build alone over a million
//! triangles (a 160 × 160 UV sphere tessellated 40 times over a grid, as
//! the `spheres81` scaling scenes are, without loading a scene) on 2
//! threads.
//!
//! Run: `cargo bench --bench reference`. Criterion reports the throughput
//! in elements/s = shadow rays (BVH traversals) per second.

// `criterion_main!` defines an undocumented `pub fn main`.
#![allow(missing_docs)]

mod common;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use glam::Vec3;
use penumbra::internal::geom::bvh::Bvh;
use penumbra::internal::geom::SceneGeometry;
use penumbra::internal::shadow::kit::rays::ShadowTracer;
use penumbra::internal::shadow::reference::Reference;
use penumbra::internal::shadow::ShadowTechnique;
use std::time::Duration;

const SAMPLES: u32 = 16;

fn reference(c: &mut Criterion) {
    let prepared = common::Prepared::new("spheres.toml", 256);
    let (scene, geometry) = (&prepared.scene, &prepared.geometry);
    let cache = prepared.cache();
    let ctx = prepared.ctx(&cache);
    let tracer = ShadowTracer::new(scene, geometry);
    let (_, rays) = tracer.trace_light(&ctx, 0, SAMPLES, 1);

    let mut group = c.benchmark_group("reference_spheres_256");
    group.sample_size(20);
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        group.throughput(Throughput::Elements(rays));
        group.bench_function(format!("shadow_rays_{SAMPLES}spp_{threads}t"), |b| {
            b.iter(|| pool.install(|| tracer.trace_light(&ctx, 0, SAMPLES, 1)))
        });
        group.throughput(Throughput::Elements(geometry.triangles.len() as u64));
        group.bench_function(format!("bvh_build_{threads}t"), |b| {
            b.iter(|| pool.install(|| ShadowTracer::new(scene, geometry)))
        });
    }
    group.finish();

    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("thread pool");
    let mut group = c.benchmark_group("reference_technique_spheres_256_2t");
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(8));
    for samples in [64, 256] {
        let technique = Reference::new(samples, 0);
        let (_, rays) = tracer.trace_light(&ctx, 0, samples, 0);
        group.throughput(Throughput::Elements(rays));
        group.bench_function(format!("reference_{samples}spp"), |b| {
            b.iter(|| pool.install(|| technique.compute(&ctx).expect("reference runs")))
        });
    }
    group.finish();
}

/// `count` UV spheres of `seg` × `seg` quads (two triangles each) on a
/// grid, radius 0.35, one unit apart.
fn spheres(count: u32, seg: u32) -> SceneGeometry {
    let mut g = SceneGeometry::default();
    let side = (count as f32).sqrt().ceil() as u32;
    for k in 0..count {
        let centre = Vec3::new((k % side) as f32, 1.5, (k / side) as f32);
        let base = g.positions.len() as u32;
        for r in 0..=seg {
            let theta = std::f32::consts::PI * r as f32 / seg as f32;
            for s in 0..seg {
                let phi = std::f32::consts::TAU * s as f32 / seg as f32;
                let dir = Vec3::new(
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    theta.sin() * phi.sin(),
                );
                g.positions.push(centre + dir * 0.35);
            }
        }
        for r in 0..seg {
            for s in 0..seg {
                let a = base + r * seg + s;
                let b = base + r * seg + (s + 1) % seg;
                g.triangles.push([a, a + seg, b]);
                g.triangles.push([b, a + seg, b + seg]);
            }
        }
    }
    g
}

fn bvh_build_large(c: &mut Criterion) {
    let geometry = spheres(20, 160);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("thread pool");
    let mut group = c.benchmark_group("bvh_build_spheres_1m_2t");
    group.sample_size(10);
    group.throughput(Throughput::Elements(geometry.triangles.len() as u64));
    group.bench_function("bvh_build", |b| {
        b.iter(|| pool.install(|| Bvh::build(&geometry, |_| true)))
    });
    group.finish();
}

criterion_group!(benches, reference, bvh_build_large);
criterion_main!(benches);
