//! Depth complexity sampling against ray casting, relation by relation:
//! with whole-light silhouettes and the reference's own sample positions,
//! every (pixel, light sample) visibility must equal the reference's
//! shadow ray, and on closed occluders the counter must equal half the
//! number of triangles the ray crosses — except at ties, where the ray
//! passes within rounding distance of an edge (see
//! ../shared/notes/exact-depth-complexity.md and docs/algorithms/dcs.md).

mod common;

use glam::DVec3;
use penumbra::sampling::SamplePattern;
use penumbra::scene::Scene;
use penumbra::shade::LightSample;
use penumbra::shadow::dcs::{DcsMode, DepthComplexitySampling, SilhouetteMode, TransmittanceMode};
use penumbra::shadow::reference::{ShadowTracer, END_SHORTEN};
use std::sync::Mutex;

/// What the exactness check measured.
#[derive(Debug, Default)]
struct Exactness {
    relations: usize,
    visibility_mismatches: usize,
    /// Relations on receivers outside every occluder (even crossings),
    /// and how many of their counters differ from crossings / 2.
    counted: usize,
    count_mismatches: usize,
    /// Largest relative distance (distance / ray length) from a
    /// mismatching ray to the nearest caster edge.
    worst_tie: f64,
}

/// One pixel's samples and counters.
type Inspected = (usize, Vec<LightSample>, Vec<i32>);

fn exactness(scene: &Scene, w: u32, h: u32, n: u32, closed: bool) -> Exactness {
    let frame = common::Frame::new(scene, w, h);
    let ctx = frame.ctx(scene);
    let tracer = ShadowTracer::new(scene, &frame.geometry);
    let dcs = DepthComplexitySampling {
        samples: n,
        seed: 11,
        silhouettes: SilhouetteMode::WholeLight,
        mode: DcsMode::Vcoef,
        pattern: SamplePattern::Stratified,
        transmittance: TransmittanceMode::Exact,
    };
    let seen: Mutex<Vec<Inspected>> = Mutex::new(Vec::new());
    dcs.inspect_light(&ctx, 0, &|i, px| {
        seen.lock()
            .unwrap()
            .push((i, px.samples.to_vec(), px.counters.to_vec()));
    })
    .expect("dcs runs");
    let adj = &frame.geometry.adjacency;
    let edges: Vec<(DVec3, DVec3)> = adj
        .edges
        .iter()
        .map(|e| {
            (
                adj.positions[e.v[0] as usize].as_dvec3(),
                adj.positions[e.v[1] as usize].as_dvec3(),
            )
        })
        .collect();
    let bvh = tracer.opaque_bvh();
    let mut out = Exactness::default();
    for (i, samples, counters) in seen.into_inner().unwrap() {
        let g = frame.gbuffer.sample(i);
        let origin = tracer.shadow_origin(g.position, g.geo_normal);
        for (s, &c) in samples.iter().zip(&counters) {
            out.relations += 1;
            let (vt, _) = tracer.segment(origin, s.x);
            let dir = (s.x.as_dvec3() - origin.as_dvec3()).as_vec3();
            let mut crossings = 0;
            bvh.for_each_hit(origin, dir, (1.0 - END_SHORTEN) as f32, |_| crossings += 1);
            let dcs_visible = c <= 0;
            let mut mismatch = dcs_visible != (vt > 0.5);
            if closed && crossings % 2 == 0 {
                out.counted += 1;
                if c != crossings / 2 {
                    out.count_mismatches += 1;
                    mismatch = true;
                }
            }
            if mismatch {
                out.visibility_mismatches += usize::from(dcs_visible != (vt > 0.5));
                let (a, b) = (origin.as_dvec3(), s.x.as_dvec3());
                let len = a.distance(b);
                let d = edges
                    .iter()
                    .map(|&(q0, q1)| common::segment_distance(a, b, q0, q1))
                    .fold(f64::INFINITY, f64::min);
                out.worst_tie = out.worst_tie.max(d / len);
            }
        }
    }
    out
}

/// A tie: the ray passes this close to an edge, relative to its length —
/// a few hundred f32 ulps of the scene, where the rasterizer, the f32
/// chart and the ray tracer may each round differently.
const TIE: f64 = 1e-4;

#[test]
fn dcs_equals_ray_casting_on_the_spheres() {
    let scene = common::shipped("spheres.toml");
    let e = exactness(&scene, 128, 96, 16, true);
    eprintln!("spheres: {e:?}");
    assert!(e.relations > 100_000);
    let agree = 1.0 - e.visibility_mismatches as f64 / e.relations as f64;
    assert!(agree >= 0.9999, "{e:?}");
    assert!(e.counted > e.relations / 2, "{e:?}");
    assert!(e.worst_tie <= TIE, "{e:?}");
}

#[test]
fn dcs_equals_ray_casting_on_the_quad_and_the_bunny() {
    for name in ["quad.toml", "bunny.toml"] {
        let scene = common::shipped(name);
        let e = exactness(&scene, 96, 96, 16, false);
        eprintln!("{name}: {e:?}");
        let agree = 1.0 - e.visibility_mismatches as f64 / e.relations as f64;
        assert!(agree >= 0.9999, "{name}: {e:?}");
        assert!(e.worst_tie <= TIE, "{name}: {e:?}");
    }
}
