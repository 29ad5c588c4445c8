//! Covered-sample updates per projected edge in depth complexity
//! sampling: the exact per-sample test (`counters::add_covered`, f32x8)
//! against the thesis's bit-field look-up (`bitfield::CoverageTables`, Fig.
//! 4.9) at the default resolution and at twice it per dimension, for
//! N = 16, 64, 256 and 1024 samples, and the one-off cost of building the
//! default tables.
//!
//! Samples: the `correlated` pattern on a rect light, in its chart
//! (`[2s − 1, 1 − 2t]`). Edges: 4096 projected edges with both ends uniform
//! in the chart's square (in-line ones dropped), applied one after the
//! other to one receiver's counters, so the tables are read at random
//! cells (no coherence between consecutive edges, the unfavourable case
//! for the tables' cache footprint).
//!
//! Run: `cargo bench --bench dcs_bitfield -- --quick`. Criterion's
//! throughput is in edges/s. Before the criterion groups, the bench times
//! exact and bit-field in alternation (41 rounds each) and prints the
//! medians and the median per-round ratio, which is what to quote on a
//! shared machine, where criterion's separate runs see different loads.

// `criterion_main!` defines an undocumented `pub fn main`.
#![allow(missing_docs)]

use criterion::{black_box, criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use penumbra::internal::sampling::{PatternSampler, SamplePattern};
use penumbra::internal::shadow::dcs::bitfield::{CoverageTables, TableResolution};
use penumbra::internal::shadow::dcs::counters::{add_covered, ChartSamples, OrientedEdge};
use std::time::{Duration, Instant};

const EDGES: usize = 4096;

fn samples(n: u32) -> Vec<[f64; 2]> {
    let mut unit = Vec::new();
    PatternSampler::new(SamplePattern::Correlated, n, 7, 0).unit_points((0, 0), &mut unit);
    unit.iter()
        .map(|&(s, t)| [2.0 * s - 1.0, 1.0 - 2.0 * t])
        .collect()
}

fn edges() -> Vec<OrientedEdge> {
    let mut x = 99u64;
    let mut next = || {
        x = x
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((x >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    };
    let mut out = Vec::with_capacity(EDGES);
    while out.len() < EDGES {
        if let Some(e) = OrientedEdge::new([next(), next()], [next(), next()]) {
            out.push(e);
        }
    }
    out
}

/// Median of `v` (sorted in place).
fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Exact and bit-field timed in alternation, round after round, so that
/// both see the same load on a shared machine: prints the median time
/// per edge of each and the median of the per-round ratios (which drift
/// in the load cancels out of).
fn paired(edges: &[OrientedEdge]) {
    const ROUNDS: usize = 41;
    eprintln!("paired rounds ({ROUNDS} × {EDGES} edges, default tables):");
    eprintln!("N | exact ns/edge | bit-field ns/edge | exact / bit-field (median of rounds)");
    for n in [16u32, 64, 256, 1024] {
        let mut chart = ChartSamples::default();
        chart.set(samples(n).into_iter());
        let tables =
            CoverageTables::from_chart(&chart, TableResolution::default()).expect("tables fit");
        let mut counters = vec![0i32; chart.padded()];
        let (mut ex, mut bf, mut ratio) = (Vec::new(), Vec::new(), Vec::new());
        for round in 0..ROUNDS + 1 {
            let t = Instant::now();
            for e in edges {
                add_covered(&mut counters, &chart, e, 1);
            }
            black_box(&mut counters);
            let a = t.elapsed().as_secs_f64();
            let t = Instant::now();
            for e in edges {
                tables.add_covered(&mut counters, e, 1);
            }
            black_box(&mut counters);
            let b = t.elapsed().as_secs_f64();
            // Round 0 warms the caches.
            if round > 0 {
                ex.push(a * 1e9 / edges.len() as f64);
                bf.push(b * 1e9 / edges.len() as f64);
                ratio.push(a / b);
            }
        }
        eprintln!(
            "{n} | {:.1} | {:.1} | {:.2}",
            median(&mut ex),
            median(&mut bf),
            median(&mut ratio)
        );
    }
}

fn per_edge(c: &mut Criterion) {
    let edges = edges();
    paired(&edges);
    let mut group = c.benchmark_group("dcs_covered_per_edge");
    group.throughput(Throughput::Elements(EDGES as u64));
    group.warm_up_time(Duration::from_millis(500));
    group.measurement_time(Duration::from_secs(2));
    for n in [16u32, 64, 256, 1024] {
        let pts = samples(n);
        let mut chart = ChartSamples::default();
        chart.set(pts.iter().copied());
        let mut counters = vec![0i32; chart.padded()];
        group.bench_with_input(BenchmarkId::new("exact", n), &n, |b, _| {
            b.iter(|| {
                for e in &edges {
                    add_covered(&mut counters, &chart, e, 1);
                }
                black_box(&mut counters);
            })
        });
        // The default tables, and twice their resolution per dimension
        // (8 times the memory: 16 MiB at N = 1024, past the L2 cache).
        let fine = TableResolution {
            sector: 128,
            line_directions: 128,
            line_distances: 256,
        };
        for (name, res) in [
            ("bitfield", TableResolution::default()),
            ("bitfield_fine", fine),
        ] {
            let tables = CoverageTables::from_chart(&chart, res).expect("tables fit");
            group.bench_with_input(BenchmarkId::new(name, n), &n, |b, _| {
                b.iter(|| {
                    for e in &edges {
                        tables.add_covered(&mut counters, e, 1);
                    }
                    black_box(&mut counters);
                })
            });
        }
    }
    group.finish();

    let mut build = c.benchmark_group("dcs_bitfield_build");
    build.sample_size(10);
    build.warm_up_time(Duration::from_millis(200));
    build.measurement_time(Duration::from_secs(2));
    for n in [16u32, 64, 256, 1024] {
        let mut chart = ChartSamples::default();
        chart.set(samples(n).into_iter());
        build.bench_with_input(BenchmarkId::new("default", n), &n, |b, _| {
            b.iter(|| CoverageTables::from_chart(&chart, TableResolution::default()))
        });
    }
    build.finish();
}

criterion_group!(benches, per_edge);
criterion_main!(benches);
