//! Percentage-closer soft shadows: where the estimate is exact (one planar
//! blocker parallel to the light), its limit for a point light, its three
//! known failures measured against the ray-traced reference, and the same
//! bits for any thread count.
//!
//! Test scenes share one layout: a square rect light of half-size 0.5 at
//! y = 4 facing down, a ground quad at y = 0, occluder quads in between,
//! and a camera below the occluders looking at the ground around x = 0.
//! A ground receiver at `x` sees light point `l` (its x offset) through
//! height `y` at `x + (l − x) · y / 4`.

use crate::common;

use common::Frame;
use penumbra::internal::render::{render, with_threads, RenderOptions};
use penumbra::internal::sampling::SamplePattern;
use penumbra::internal::scene::Scene;
use penumbra::internal::shadow::pcss::PcssKernel;
use penumbra::internal::shadow::technique::BuildParams;
use penumbra::internal::shadow::{run_technique, Technique, TechniqueOptions};

/// Light (half-vectors `light_uv`), ground and camera of the test scenes,
/// then `occluders`: `[x0, x1, z0, z1, y]` horizontal quads (a map sees
/// both sides of a quad).
fn scene(name: &str, light_uv: ([f32; 3], [f32; 3]), occluders: &[[f32; 5]]) -> Scene {
    let (u, v) = light_uv;
    let mut toml = format!(
        r#"
[scene]
name = "{name}"
[camera]
eye = [1.2, 0.45, 0.0]
target = [-0.1, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 60.0
width = 64
height = 64
[[light]]
type = "rect"
center = [0.0, 4.0, 0.0]
u = {u:?}
v = {v:?}
radiance = [1.0, 1.0, 1.0]
[[object]]
name = "ground"
shape = "quad"
size = [8.0, 8.0]
"#
    );
    for (i, [x0, x1, z0, z1, y]) in occluders.iter().enumerate() {
        toml.push_str(&format!(
            "[[object]]\nname = \"occluder{i}\"\nshape = \"quad\"\nsize = [{}, {}]\n\
             translate = [{}, {y}, {}]\nreceive_shadows = false\n",
            x1 - x0,
            z1 - z0,
            0.5 * (x0 + x1),
            0.5 * (z0 + z1)
        ));
    }
    common::scene_in_scratch(name, &toml, &[])
}

const SQUARE: ([f32; 3], [f32; 3]) = ([0.5, 0.0, 0.0], [0.0, 0.0, 0.5]);

/// One light's Vcoef of `technique` on `frame`.
fn vcoef(
    scene: &Scene,
    frame: &Frame,
    technique: &str,
    samples: u32,
    set: impl Fn(&mut TechniqueOptions),
) -> Vec<f32> {
    let mut options = TechniqueOptions::default();
    set(&mut options);
    let params = BuildParams {
        samples,
        seed: 3,
        pattern: SamplePattern::Stratified,
        options: &options,
    };
    let out = run_technique(
        Technique::named(technique).unwrap(),
        &params,
        &frame.ctx(scene),
    )
    .expect("technique runs");
    let v = out.lights[0].vcoef().to_vec();
    assert!(v.iter().all(|x| x.is_finite() && (0.0..=1.0).contains(x)));
    v
}

/// Ground pixels (x, z of the receiver, index) with |z| < `z_max`.
fn ground(frame: &Frame, z_max: f32) -> Vec<(f32, usize)> {
    (0..frame.gbuffer.len())
        .filter_map(|i| {
            let g = frame.gbuffer.sample(i);
            (g.is_surface() && g.position.y.abs() < 1e-4 && g.position.z.abs() < z_max)
                .then_some((g.position.x, i))
        })
        .collect()
}

/// Mean of `v` over the ground pixels with x in `[a, b]`, and their count.
fn mean_in(v: &[f32], px: &[(f32, usize)], a: f32, b: f32) -> (f64, usize) {
    let sel: Vec<f64> = px
        .iter()
        .filter(|(x, _)| (a..=b).contains(x))
        .map(|&(_, i)| f64::from(v[i]))
        .collect();
    (sel.iter().sum::<f64>() / sel.len().max(1) as f64, sel.len())
}

/// A straight occluder edge parallel to a light edge, box kernel: the
/// visibility is the fraction of the light's width not blocked, the
/// linear ramp `clamp(x + 0.5, 0, 1)` for the occluder at y = 2 over
/// x < 0. Tolerance: one grid step of the 64 × 64 filter (1/64; the
/// search grid's outer half-step misses blocked fractions below 1/128)
/// plus a few map texels' shift of the edge (2048² map, 0.006).
#[test]
fn a_straight_edge_gives_the_exact_linear_ramp() {
    let scene = scene("pcss-ramp", SQUARE, &[[-4.0, 0.0, -3.0, 3.0, 2.0]]);
    let frame = Frame::new(&scene, 64, 64);
    let v = vcoef(&scene, &frame, "pcss", 1, |o| {
        o.shadow_map.map_size = 2048;
        o.pcss.pcss_kernel = PcssKernel::Box;
        o.pcss.pcss_blocker_samples = 4096;
        o.pcss.pcss_filter_samples = 4096;
    });
    let px = ground(&frame, 1.0);
    let mut worst: f32 = 0.0;
    let mut in_ramp = 0;
    // Receivers far from the occluder's other edges (x = -4, z = ±3).
    for &(x, i) in px.iter().filter(|(x, _)| x.abs() < 1.5) {
        let exact = (x + 0.5).clamp(0.0, 1.0);
        if (-0.5..0.5).contains(&x) {
            in_ramp += 1;
        }
        worst = worst.max((v[i] - exact).abs());
    }
    assert!(in_ramp > 300, "the ramp needs pixels: {in_ramp}");
    eprintln!("ramp: {in_ramp} pixels in the ramp, worst deviation {worst}");
    assert!(worst <= 1.0 / 64.0 + 0.006, "worst deviation {worst}");
}

/// Light size → 0: the search region and the filter shrink below a texel,
/// so PCSS is the hard map's one-tap test. Only receivers whose taps
/// straddle a texel boundary may differ: at most 8 of the 64² pixels
/// (measured: 0).
#[test]
fn a_point_light_gives_the_hard_shadow_map() {
    let tiny = ([5e-4, 0.0, 0.0], [0.0, 0.0, 5e-4]);
    let scene = scene(
        "pcss-tiny",
        tiny,
        &[[-4.0, 0.0, -3.0, 3.0, 2.0], [0.1, 0.4, -0.2, 0.2, 1.0]],
    );
    let frame = Frame::new(&scene, 64, 64);
    let hard = vcoef(&scene, &frame, "shadow-map", 1, |_| {});
    for n in [16, 64] {
        let soft = vcoef(&scene, &frame, "pcss", 1, |o| {
            o.pcss.pcss_blocker_samples = n;
            o.pcss.pcss_filter_samples = n;
        });
        let shadowed = hard.iter().filter(|&&h| h < 0.5).count();
        assert!(shadowed > 500, "the test needs a shadow: {shadowed}");
        let differ = soft
            .iter()
            .zip(&hard)
            .filter(|(a, b)| (**a - **b).abs() > 1e-6)
            .count();
        eprintln!("point light, {n} taps: {differ} pixels differ from shadow-map");
        assert!(differ <= 8, "{n} taps: {differ} pixels differ");
    }
}

/// Failure 1, stacked blockers: a low occluder B (y = 0.5, x > 0) casts a
/// nearly hard shadow, its true umbra starts at x = 0.07; a high occluder
/// A (y = 3, x < −0.2) lies in the same receivers' search region. The
/// blockers' mean depth is pulled toward A's, the filter widens and B's
/// umbra is lit. Theory for a dense box kernel, in map tangents with the
/// receiver's centre `c = x / 4`: search half-width 0.375 (search plane at
/// A's depth 1), B covers `c + 0.375` of it at depth 3.5 and A
/// `max(0, 0.175 − c)` at depth 1; their mean depth `z_b` gives the filter
/// half-width `f = 0.5 (4 − z_b) / (4 z_b)` and `V = (f − c) / 2f`
/// (V ≈ 0.26 at x = 0.1) where the reference gives 0. Without A, PCSS
/// finds B's umbra.
#[test]
fn stacked_blockers_blur_the_low_blockers_edge() {
    let a = [-4.0, -0.2, -3.0, 3.0, 3.0];
    let b = [0.0, 4.0, -3.0, 3.0, 0.5];
    let stacked = scene("pcss-stacked", SQUARE, &[a, b]);
    let alone = scene("pcss-stacked-control", SQUARE, &[b]);
    let (fs, fa) = (Frame::new(&stacked, 64, 64), Frame::new(&alone, 64, 64));
    let (ps, pa) = (ground(&fs, 0.5), ground(&fa, 0.5));
    let dense = |o: &mut TechniqueOptions| {
        o.pcss.pcss_kernel = PcssKernel::Box;
        o.pcss.pcss_blocker_samples = 1024;
        o.pcss.pcss_filter_samples = 1024;
    };
    let reference = vcoef(&stacked, &fs, "reference", 256, |_| {});
    let pcss = vcoef(&stacked, &fs, "pcss", 1, |_| {});
    let boxed = vcoef(&stacked, &fs, "pcss", 1, dense);
    let control = vcoef(&alone, &fa, "pcss", 1, |_| {});
    let theory: Vec<f32> = (0..fs.gbuffer.len())
        .map(|i| {
            let c = f64::from(fs.gbuffer.sample(i).position.x) / 4.0;
            let (lb, la) = (c + 0.375, (0.175 - c).max(0.0));
            let zb = (lb * 3.5 + la) / (lb + la);
            let f = 0.5 * (4.0 - zb) / (4.0 * zb);
            ((f - c) / (2.0 * f)).clamp(0.0, 1.0) as f32
        })
        .collect();
    let region = (0.08, 0.14);
    let mean = |v: &[f32], px: &[(f32, usize)]| mean_in(v, px, region.0, region.1);
    let ((r, n), (p, _), (bx, _)) = (mean(&reference, &ps), mean(&pcss, &ps), mean(&boxed, &ps));
    let ((t, _), (c, _)) = (mean(&theory, &ps), mean(&control, &pa));
    eprintln!(
        "stacked: {n} pixels, reference {r:.4}, pcss 16/16 {p:.4}, box 1024/1024 {bx:.4} \
         (theory {t:.4}), pcss without A {c:.4}"
    );
    assert!(n >= 20, "the region needs pixels: {n}");
    assert!(r < 0.01, "the reference's umbra: {r}");
    assert!(c < 0.03, "one blocker alone: PCSS finds the umbra ({c})");
    assert!((bx - t).abs() < 0.03, "box kernel {bx} against theory {t}");
    assert!(p > 0.05, "stacked, default taps: the umbra is lit ({p})");
}

/// Failure 2, a blocker seen only off-centre: a high occluder A (y = 3,
/// x < 0) hides a low one B (y = 1, −0.6 < x < −0.2) from the light's
/// centre. Around x = −0.5 the reference is umbra (A blocks light points
/// l < 0.17, B all the others); the map holds A alone, and PCSS filters
/// A's shadow: theory gives V = 1/3 at x = −0.5.
#[test]
fn a_blocker_hidden_from_the_centre_is_missed() {
    let a = [-4.0, 0.0, -3.0, 3.0, 3.0];
    let b = [-0.6, -0.2, -3.0, 3.0, 1.0];
    let s = scene("pcss-hidden", SQUARE, &[a, b]);
    let f = Frame::new(&s, 64, 64);
    let px = ground(&f, 0.5);
    let reference = vcoef(&s, &f, "reference", 256, |_| {});
    let pcss = vcoef(&s, &f, "pcss", 1, |o| {
        o.pcss.pcss_kernel = PcssKernel::Box;
        o.pcss.pcss_blocker_samples = 1024;
        o.pcss.pcss_filter_samples = 1024;
    });
    let (r, n) = mean_in(&reference, &px, -0.55, -0.45);
    let (p, _) = mean_in(&pcss, &px, -0.55, -0.45);
    eprintln!("hidden: {n} pixels, reference {r:.4}, pcss {p:.4}");
    assert!(n >= 10, "the region needs pixels: {n}");
    assert!(r < 0.01, "the reference's umbra: {r}");
    assert!((p - 1.0 / 3.0).abs() < 0.05, "pcss sees A alone: {p}");
}

/// Failure 3, the penumbra clipped by the search radius: the light is the
/// square turned 45° (corners at x = ±0.707), the occluder's edge (y = 2,
/// x < 0) runs along a diagonal of it. The disk-shaped search reaches
/// light offsets up to 0.5 only, so receivers at 0.5 < x < 0.707 find no
/// blocker (V = 1) while the light's corner is blocked: `1 − (0.707 − x)²`.
#[test]
fn the_disk_search_clips_the_corners_of_the_penumbra() {
    let h = 0.5f32 * std::f32::consts::FRAC_1_SQRT_2;
    let diamond = ([h, 0.0, h], [-h, 0.0, h]);
    let s = scene("pcss-diamond", diamond, &[[-4.0, 0.0, -3.0, 3.0, 2.0]]);
    let f = Frame::new(&s, 64, 64);
    let px = ground(&f, 1.0);
    let reference = vcoef(&s, &f, "reference", 1024, |_| {});
    let pcss = vcoef(&s, &f, "pcss", 1, |o| {
        o.pcss.pcss_blocker_samples = 64;
        o.pcss.pcss_filter_samples = 64;
    });
    let (lo, hi) = (0.52, 0.62);
    let (r, n) = mean_in(&reference, &px, lo, hi);
    let (p, _) = mean_in(&pcss, &px, lo, hi);
    let theory = {
        let a = std::f64::consts::FRAC_1_SQRT_2;
        let sel: Vec<f64> = px
            .iter()
            .filter(|(x, _)| (lo..=hi).contains(x))
            .map(|&(x, _)| 1.0 - (a - f64::from(x)).powi(2))
            .collect();
        sel.iter().sum::<f64>() / sel.len().max(1) as f64
    };
    eprintln!("clipped: {n} pixels, reference {r:.4} (theory {theory:.4}), pcss {p:.4}");
    assert!(n >= 20, "the region needs pixels: {n}");
    assert_eq!(p, 1.0, "no blocker is found beyond the disk");
    assert!((r - theory).abs() < 0.004, "the reference sees the corner");
    assert!(1.0 - r > 0.01, "a measurable loss: {r}");
}

/// The same bits with one and with two threads.
#[test]
fn the_same_bits_for_any_thread_count() {
    let s = common::shipped("quad.toml");
    let options = RenderOptions {
        width: Some(48),
        height: Some(48),
        technique: Technique::named("pcss").unwrap(),
        ..RenderOptions::default()
    };
    let run = |threads| {
        with_threads(Some(threads), || render(&s, &options).expect("render")).expect("pool")
    };
    let (one, two) = (run(1), run(2));
    assert_eq!(one.lights[0].vcoef(), two.lights[0].vcoef());
    assert_eq!(common::render_bits(&one), common::render_bits(&two));
    let v = one.lights[0].vcoef();
    assert!(v.iter().any(|&x| x > 0.0 && x < 1.0), "a soft penumbra");
}

#[test]
fn sample_counts_are_validated_with_their_name() {
    let s = common::shipped("quad.toml");
    for (name, blocker, filter) in [
        ("--pcss-blocker-samples", 0, 16),
        ("--pcss-filter-samples", 16, 5000),
    ] {
        let mut options = RenderOptions {
            width: Some(16),
            height: Some(16),
            technique: Technique::named("pcss").unwrap(),
            ..RenderOptions::default()
        };
        options.options.pcss.pcss_blocker_samples = blocker;
        options.options.pcss.pcss_filter_samples = filter;
        let e = render(&s, &options).expect_err("refused");
        assert!(e.to_string().contains(name), "{e}");
    }
}
