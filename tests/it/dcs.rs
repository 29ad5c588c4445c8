//! Depth complexity sampling against ray casting, relation by relation:
//! with whole-light silhouettes and the reference's own sample positions,
//! every (pixel, light sample) visibility must equal the reference's
//! shadow ray, and on closed occluders the counter must equal half the
//! number of triangles the ray crosses — except at ties, where the ray
//! passes within rounding distance of an edge (see
//! ../shared/notes/exact-depth-complexity.md and docs/algorithms/dcs.md).

use crate::common;

use glam::DVec3;
use penumbra::internal::sampling::SamplePattern;
use penumbra::internal::scene::Scene;
use penumbra::internal::shade::LightSample;
use penumbra::internal::shadow::dcs::{
    DcsMode, DepthComplexitySampling, SilhouetteMode, TransmittanceMode,
};
use penumbra::internal::shadow::kit::rays::{ShadowTracer, END_SHORTEN};
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

/// Exact DCS (whole-light silhouettes, exact transmittance) in Vcoef
/// mode with stratified samples: the configuration held to ray casting.
fn exact_dcs(samples: u32, seed: u64) -> DepthComplexitySampling {
    DepthComplexitySampling {
        samples,
        seed,
        silhouettes: SilhouetteMode::WholeLight,
        mode: DcsMode::Vcoef,
        pattern: SamplePattern::Stratified,
        transmittance: TransmittanceMode::Exact,
        coverage: Default::default(),
        opacity_filter: Default::default(),
        rays: penumbra::internal::shadow::dcs::RayChoice::Never,
    }
}

/// One pixel's samples and counters.
type Inspected = (usize, Vec<LightSample>, Vec<i32>);

fn exactness(scene: &Scene, w: u32, h: u32, n: u32, closed: bool) -> Exactness {
    let frame = common::Frame::new(scene, w, h);
    let ctx = frame.ctx(scene);
    let tracer = ShadowTracer::new(scene, &frame.geometry);
    let dcs = exact_dcs(n, 11);
    let seen: Mutex<Vec<Inspected>> = Mutex::new(Vec::new());
    dcs.inspect_light(&ctx, 0, &|i, px| {
        seen.lock()
            .unwrap()
            .push((i, px.samples.to_vec(), px.counters.to_vec()));
    })
    .expect("dcs runs");
    let adj = frame.geometry.adjacency();
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

/// Eq. 4.2: with a textured light in Vcoef mode, each sample's visibility
/// is weighted by its emitted radiance. A light whose left half is white
/// and right half black, half hidden by an occluder: plain Vcoef shading
/// (unshadowed × visible fraction) is far off where the occluder hides
/// the bright half; the luminance-weighted Vcoef follows the reference's
/// radiance (same samples) to the estimator's noise, and fully lit
/// receivers get the unshadowed light exactly.
#[test]
fn textured_light_vcoef_is_luminance_weighted() {
    use penumbra::internal::shade::{surface_point, PreparedLight};
    use penumbra::internal::shadow::reference::Reference;
    use penumbra::internal::shadow::ShadowTechnique;
    let mut png = Vec::new();
    image::RgbImage::from_raw(2, 1, vec![255, 255, 255, 0, 0, 0])
        .expect("2×1 image")
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .expect("png encodes");
    let toml = r#"
[scene]
name = "half-lit"
[camera]
eye = [0.0, 6.0, 5.0]
target = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 45.0
width = 64
height = 64
[[light]]
type = "rect"
center = [0.0, 4.0, 0.0]
u = [1.0, 0.0, 0.0]
v = [0.0, 0.0, 1.0]
radiance = [6.0, 6.0, 6.0]
texture = "half.png"
[[object]]
shape = "quad"
size = [6.0, 6.0]
[[object]]
shape = "quad"
size = [1.0, 1.0]
translate = [0.3, 1.5, 0.0]
"#;
    let scene = common::scene_in_scratch("dcs-textured", toml, &[("half.png", &png)]);
    let frame = common::Frame::new(&scene, 64, 64);
    let ctx = frame.ctx(&scene);
    let n = 256;
    let dcs = exact_dcs(n, 3);
    let ours = dcs.compute(&ctx).expect("dcs runs");
    let reference = Reference::new(n, 3).compute(&ctx).expect("reference runs");
    let term = &ours.lights[0];
    let weighted = term.radiance().expect("textured light: radiance");
    let vcoef = term.vcoef();
    let truth = reference.lights[0].radiance().expect("reference radiance");
    let prepared = PreparedLight::new(&scene.lights[0], &scene.textures);
    let eye = frame.view.eye.as_vec3();
    let (mut err_weighted, mut err_plain, mut penumbra) = (0.0f64, 0.0f64, 0);
    for i in 0..frame.gbuffer.len() {
        let g = frame.gbuffer.sample(i);
        if !g.is_surface() {
            continue;
        }
        let unshadowed = prepared.unshadowed_direct(&surface_point(&scene, &g, eye));
        if vcoef[i] == 1.0 {
            assert_eq!(weighted[i], unshadowed, "fully lit pixel {i}");
        }
        if vcoef[i] > 0.0 && vcoef[i] < 1.0 {
            penumbra += 1;
            err_weighted += f64::from((weighted[i] - truth[i]).abs().max_element());
            err_plain += f64::from((unshadowed * vcoef[i] - truth[i]).abs().max_element());
        }
    }
    let (mae_w, mae_p) = (err_weighted / penumbra as f64, err_plain / penumbra as f64);
    eprintln!("penumbra pixels {penumbra}: MAE weighted {mae_w:.4}, plain {mae_p:.4}");
    assert!(penumbra > 200);
    assert!(mae_w < 0.25 * mae_p, "weighted {mae_w} vs plain {mae_p}");
}

/// The bit-field option (Fig. 4.9) approximates the exact test: on the
/// quad with the correlated set, its Vcoef stays close to the exact one
/// (the tables' cells are ~1/64 of the light; a sample flips only within
/// a cell of an edge), and it is refused for per-pixel patterns.
#[test]
fn bitfield_coverage_is_close_to_exact_and_refused_where_invalid() {
    use penumbra::internal::shadow::dcs::CoverageTest;
    use penumbra::internal::shadow::ShadowTechnique;
    let scene = common::shipped("quad.toml");
    let frame = common::Frame::new(&scene, 128, 128);
    let ctx = frame.ctx(&scene);
    let run = |coverage, pattern| {
        DepthComplexitySampling {
            samples: 64,
            seed: 1,
            silhouettes: SilhouetteMode::Centre,
            mode: DcsMode::Vcoef,
            pattern,
            transmittance: TransmittanceMode::Exact,
            coverage,
            opacity_filter: Default::default(),
            rays: penumbra::internal::shadow::dcs::RayChoice::Never,
        }
        .compute(&ctx)
    };
    let exact = run(CoverageTest::Exact, SamplePattern::Correlated).expect("exact runs");
    let table = run(CoverageTest::BitField, SamplePattern::Correlated).expect("bitfield runs");
    let (a, b) = (exact.lights[0].vcoef(), table.lights[0].vcoef());
    let (mut sum, mut max, mut differ) = (0.0f64, 0.0f32, 0);
    for (x, y) in a.iter().zip(b) {
        let d = (x - y).abs();
        sum += f64::from(d);
        max = max.max(d);
        differ += usize::from(d > 0.0);
    }
    let mae = sum / a.len() as f64;
    eprintln!("bitfield vs exact: MAE {mae:.2e}, max {max}, {differ} pixels differ");
    // Some pixels do differ (the option is not secretly the exact test)...
    assert!(differ > 0);
    // ...by a few samples at most: 4 of 64.
    assert!(max <= 4.0 / 64.0 + 1e-6, "max {max}");
    assert!(mae < 1e-3, "MAE {mae}");
    let refused = run(CoverageTest::BitField, SamplePattern::Stratified);
    let message = refused.expect_err("stratified is refused").to_string();
    assert!(message.contains("--coverage"), "{message}");
}

/// The counter pass's shortcuts for the opaque Vcoef (samples made only
/// in the blocks some edge may cover, the angular sectors, the integer
/// count of visible samples) give, pixel for pixel, the Vcoef and depth
/// complexity AOVs of the full per-sample counters the inspector sees
/// (which run the plain path: every sample tested against every edge),
/// at 256 samples, where the blocks apply.
#[test]
fn shortcuts_equal_the_full_counters() {
    use penumbra::internal::shadow::ShadowTechnique;
    for (name, w, h) in [("spheres.toml", 96, 80), ("bunny.toml", 96, 96)] {
        let scene = common::shipped(name);
        let frame = common::Frame::new(&scene, w, h);
        let ctx = frame.ctx(&scene);
        let n = 256;
        let dcs = exact_dcs(n, 5);
        let out = dcs.compute(&ctx).expect("dcs runs");
        let vcoef = out.lights[0].vcoef();
        let layer = |prefix: &str| -> Vec<f32> {
            let l = out
                .layers
                .iter()
                .find(|l| l.name.starts_with(prefix))
                .unwrap_or_else(|| panic!("layer {prefix}"));
            l.channels[0].1.clone()
        };
        let (dc_max, dc_mean) = (layer("dc_max"), layer("dc_mean"));
        let seen: Mutex<Vec<(usize, Vec<i32>)>> = Mutex::new(Vec::new());
        dcs.inspect_light(&ctx, 0, &|i, px| {
            seen.lock().unwrap().push((i, px.counters.to_vec()));
        })
        .expect("dcs runs");
        let mut partial = 0;
        for (i, counters) in seen.into_inner().unwrap() {
            let visible = counters.iter().filter(|&&c| c <= 0).count();
            let max = counters.iter().copied().max().unwrap_or(0).max(0);
            let sum: i64 = counters.iter().map(|&c| i64::from(c.max(0))).sum();
            assert_eq!(
                vcoef[i],
                visible as f32 / n as f32,
                "{name} pixel {i}: vcoef"
            );
            assert_eq!(dc_max[i], max as f32, "{name} pixel {i}: dc_max");
            assert_eq!(
                dc_mean[i],
                (sum as f64 / f64::from(n)) as f32,
                "{name} pixel {i}"
            );
            partial += usize::from(visible > 0 && visible < n as usize);
        }
        assert!(partial > 100, "{name}: only {partial} penumbra pixels");
    }
}
