//! Depth complexity sampling with semi-opaque casters against the
//! reference's per-sample products, relation by relation: with
//! whole-light silhouettes and the reference's own samples, every
//! (pixel, sample) `V·T` must equal the shadow ray's `V · Π (1 − α)` to
//! `REL` (relative; both below `TINY` count as equal), except at ties
//! where the ray passes within `TIE` (relative) of a caster edge.
//! Opacities 1, 0.999999, 0.5 and 1e-7, closed and open casters, several
//! opacities at once, and a hundred overlapping layers.

use crate::common;

use glam::DVec3;
use penumbra::internal::sampling::SamplePattern;
use penumbra::internal::scene::Scene;
use penumbra::internal::shadow::dcs::{
    DcsMode, DepthComplexitySampling, SilhouetteMode, TransmittanceMode,
};
use penumbra::internal::shadow::kit::rays::{ShadowTracer, END_SHORTEN};
use std::sync::Mutex;

/// Relative agreement of `V·T` (the two sides form the same product in
/// different orders: a few f64 ulps per layer).
const REL: f64 = 1e-9;
/// Below this both are "zero" (f64 subnormals round differently).
const TINY: f64 = 1e-290;
/// A tie: the ray passes this close to an edge, relative to its length.
const TIE: f64 = 1e-4;

#[derive(Debug, Default)]
struct Agreement {
    relations: usize,
    mismatches: usize,
    worst_tie: f64,
    /// Largest relative error of T among relations where it is
    /// positive on both sides.
    worst_rel: f64,
    /// Smallest positive transmittance seen (how deep the test went).
    min_t: f64,
    /// Relations the reference sees blocked (`V·T = 0`).
    blocked: usize,
}

fn header(extra: &str) -> String {
    format!(
        r#"
[scene]
name = "transmittance"
[camera]
eye = [0.0, 5.0, 5.0]
target = [0.0, 0.5, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 50.0
width = 64
height = 48
[[light]]
type = "rect"
center = [0.0, 4.0, 0.0]
u = [0.6, 0.0, 0.0]
v = [0.0, 0.0, 0.6]
radiance = [10.0, 10.0, 10.0]
[[object]]
name = "ground"
shape = "quad"
size = [8.0, 8.0]
{extra}
"#
    )
}

/// A semi-opaque quad, a semi-opaque (closed) sphere and an opaque box.
fn mixed(opacity: f64) -> String {
    header(&format!(
        r#"
[[object]]
shape = "quad"
size = [1.2, 1.0]
translate = [-0.6, 1.2, 0.0]
rotate = [10.0, 20.0, 0.0]
material = {{ opacity = {opacity} }}
[[object]]
shape = "sphere"
radius = 0.45
segments = 12
rings = 8
translate = [0.9, 1.0, 0.3]
material = {{ opacity = {opacity} }}
[[object]]
shape = "box"
size = [0.4, 0.4, 0.4]
translate = [0.2, 0.6, -0.9]
"#
    ))
}

/// `n` overlapping quads of `opacity`, each turned and sized a little
/// differently so their edges (and penumbrae) never coincide.
fn stack(n: usize, opacity: f64) -> String {
    let mut s = String::new();
    for k in 0..n {
        s.push_str(&format!(
            "[[object]]\nshape = \"quad\"\nsize = [{}, {}]\ntranslate = [0.0, {}, 0.0]\n\
             rotate = [0.0, {}, 0.0]\nmaterial = {{ opacity = {opacity} }}\n",
            1.0 + 0.004 * k as f64,
            0.9 + 0.005 * k as f64,
            1.0 + 0.012 * k as f64,
            3.7 * k as f64,
        ));
    }
    header(&s)
}

fn scene(name: &str, toml: &str) -> Scene {
    common::scene_in_scratch(name, toml, &[])
}

type Inspected = (usize, Vec<glam::Vec3>, Vec<i32>, Vec<f64>);

/// Runs DCS on light 0 and checks every relation against the reference.
/// `summed`: compare against `max(0, 1 − crossings · α)` instead.
fn agreement(scene: &Scene, n: u32, mode: TransmittanceMode, summed_alpha: f64) -> Agreement {
    let frame = common::Frame::new(scene, 64, 48);
    let ctx = frame.ctx(scene);
    let tracer = ShadowTracer::new(scene, &frame.geometry);
    let dcs = DepthComplexitySampling {
        samples: n,
        seed: 5,
        silhouettes: SilhouetteMode::WholeLight,
        mode: DcsMode::Vcoef,
        pattern: SamplePattern::Stratified,
        transmittance: mode,
        coverage: Default::default(),
        opacity_filter: Default::default(),
        rays: penumbra::internal::shadow::dcs::RayChoice::Never,
    };
    let seen: Mutex<Vec<Inspected>> = Mutex::new(Vec::new());
    dcs.inspect_light(&ctx, 0, &|i, px| {
        let xs = px.samples.iter().map(|s| s.x).collect();
        seen.lock()
            .unwrap()
            .push((i, xs, px.counters.to_vec(), px.transmittance.to_vec()));
    })
    .expect("dcs runs");
    let adj = penumbra::internal::geom::EdgeAdjacency::build(&frame.geometry, |_| true);
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
    let mut out = Agreement {
        min_t: 1.0,
        ..Agreement::default()
    };
    for (i, xs, counters, ts) in seen.into_inner().unwrap() {
        let g = frame.gbuffer.sample(i);
        let origin = tracer.shadow_origin(g.position, g.geo_normal);
        for (k, (&x, &c)) in xs.iter().zip(&counters).enumerate() {
            out.relations += 1;
            let t_dcs = ts.get(k).copied().unwrap_or(1.0);
            let ours = if c <= 0 { t_dcs } else { 0.0 };
            let expected = if mode == TransmittanceMode::Summed {
                let dir = (x.as_dvec3() - origin.as_dvec3()).as_vec3();
                let mut crossings = 0;
                tracer.translucent_bvh().for_each_hit(
                    origin,
                    dir,
                    (1.0 - END_SHORTEN) as f32,
                    |_| crossings += 1,
                );
                let blocked = tracer
                    .opaque_bvh()
                    .occluded(origin, dir, (1.0 - END_SHORTEN) as f32);
                if blocked {
                    0.0
                } else {
                    (1.0 - crossings as f64 * summed_alpha).max(0.0)
                }
            } else {
                tracer.segment(origin, x).0
            };
            out.blocked += usize::from(expected == 0.0);
            let agree = if ours <= TINY && expected <= TINY {
                true
            } else if ours > TINY && expected > TINY {
                let rel = (ours - expected).abs() / expected;
                if rel <= REL {
                    out.worst_rel = out.worst_rel.max(rel);
                    out.min_t = out.min_t.min(ours);
                }
                rel <= REL
            } else {
                false
            };
            if !agree {
                out.mismatches += 1;
                let (a, b) = (origin.as_dvec3(), x.as_dvec3());
                let d = edges
                    .iter()
                    .map(|&(q0, q1)| common::segment_distance(a, b, q0, q1))
                    .fold(f64::INFINITY, f64::min);
                out.worst_tie = out.worst_tie.max(d / a.distance(b));
            }
        }
    }
    out
}

fn check(name: &str, a: &Agreement) {
    eprintln!("{name}: {a:?}");
    assert!(a.relations > 20_000, "{name}: {a:?}");
    let agree = 1.0 - a.mismatches as f64 / a.relations as f64;
    assert!(agree >= 0.9999, "{name}: {a:?}");
    assert!(a.worst_tie <= TIE, "{name}: {a:?}");
}

#[test]
fn semi_opaque_casters_match_the_reference_products() {
    for opacity in [1.0, 0.999999, 0.5, 1e-7] {
        let s = scene("mixed", &mixed(opacity));
        let a = agreement(&s, 16, TransmittanceMode::Exact, 0.0);
        check(&format!("mixed opacity {opacity}"), &a);
        if opacity < 1.0 {
            // The layers were really crossed: some sample saw T < 1.
            assert!(a.min_t < 1.0 - 0.5 * opacity, "opacity {opacity}: {a:?}");
        }
    }
}

#[test]
fn several_opacities_at_once() {
    let toml = header(
        r#"
[[object]]
shape = "quad"
size = [1.0, 1.0]
translate = [-0.3, 1.0, 0.0]
material = { opacity = 0.3 }
[[object]]
shape = "quad"
size = [1.0, 1.0]
translate = [0.3, 1.3, 0.2]
rotate = [0.0, 30.0, 0.0]
material = { opacity = 0.6 }
[[object]]
shape = "sphere"
radius = 0.3
segments = 10
rings = 6
translate = [0.0, 1.7, 0.0]
material = { opacity = 0.9 }
"#,
    );
    let s = scene("several", &toml);
    let a = agreement(&s, 16, TransmittanceMode::Exact, 0.0);
    check("several opacities", &a);
    assert!(a.min_t < 0.7 * 0.4, "{a:?}");
}

#[test]
fn a_hundred_overlapping_layers() {
    for opacity in [0.5, 0.999999, 1e-7] {
        let s = scene("hundred", &stack(100, opacity));
        let a = agreement(&s, 16, TransmittanceMode::Exact, 0.0);
        check(&format!("100 layers of {opacity}"), &a);
        if opacity == 0.5 {
            // Deep: at least 90 layers crossed somewhere, 2^-90 ≈ 8e-28.
            assert!(a.min_t < 1e-27, "{a:?}");
        }
        if opacity == 1e-7 {
            assert!(a.min_t < 1.0 - 90.0 * 1e-7 && a.min_t > 1.0 - 101.0 * 1e-7);
        }
    }
}

#[test]
fn summed_opacity_is_the_thesis_approximation() {
    // Per sample, summed mode gives max(0, 1 − crossings · α) exactly
    // (what the thesis's packed counters compute), which is the product
    // only under a single layer.
    for (opacity, layers) in [(0.5, 1), (0.3, 3)] {
        let s = scene("summed", &stack(layers, opacity));
        let a = agreement(&s, 16, TransmittanceMode::Summed, f64::from(opacity as f32));
        check(&format!("summed {layers} × {opacity}"), &a);
    }
}

/// Soft textured shadow volumes inside DCS (§5.2): on the shipped fence
/// (a perforated quad, binary opacity texture), nearest look-ups and the
/// reference's own samples, every (pixel, sample) `V·T` equals the
/// reference's shadow ray but for ties at texel borders and edges; the
/// issue asks ≥ 99.9 %.
#[test]
fn fence_s_triangles_match_the_reference() {
    let s = common::shipped("fence.toml");
    let a = agreement(&s, 16, TransmittanceMode::Exact, 0.0);
    eprintln!("fence: {a:?}");
    assert!(a.relations > 20_000, "{a:?}");
    let agree = 1.0 - a.mismatches as f64 / a.relations as f64;
    assert!(agree >= 0.999, "{a:?}");
    // The fence really shadows: some relations are blocked by texels.
    assert!(a.blocked > a.relations / 50, "{a:?}");
}
