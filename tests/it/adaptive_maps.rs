//! Adaptive light-source sampling (adaptive-maps): forced to split
//! everywhere it is the 17 × 17 multi-map to the bit; adaptively, receivers
//! fully lit or in umbra in the 17 × 17 result keep their exact value; the
//! centre probe finds the occluder the corner maps miss; thread counts do
//! not change a bit; sphere lights and absurd parameters are refused.

use crate::common;

use penumbra::internal::render::{render, with_threads, Render, RenderOptions};
use penumbra::internal::sampling::SamplePattern;
use penumbra::internal::scene::Scene;
use penumbra::internal::shadow::Technique;

fn run(scene: &Scene, name: &str, size: u32, f: impl Fn(&mut RenderOptions)) -> Render {
    let mut options = RenderOptions {
        width: Some(size),
        height: Some(size),
        technique: Technique::named(name).unwrap(),
        ..RenderOptions::default()
    };
    f(&mut options);
    render(scene, &options).expect("render")
}

fn grid289(o: &mut RenderOptions) {
    o.samples = 289;
    o.pattern = SamplePattern::Grid;
}

/// Maps rendered, from the `--explain` note (`N rendered ...`).
fn rendered(out: &Render) -> u32 {
    let note = out
        .explain
        .buffers
        .iter()
        .find(|b| b.name == "shadow maps")
        .expect("shadow maps note");
    note.detail
        .split_whitespace()
        .next()
        .and_then(|n| n.parse().ok())
        .expect("a count")
}

/// Split everywhere down to depth 4: the same 289 points, the same maps,
/// weights 1/289 each: bit-identical to multi-map on the 17 × 17 grid,
/// with and without PCF.
#[test]
fn split_everywhere_is_the_17x17_multi_map_bit_for_bit() {
    for (scene, pcf) in [("quad.toml", "1"), ("thin-occluder.toml", "2x2")] {
        let s = common::shipped(scene);
        let set = |o: &mut RenderOptions| {
            o.options.shadow_map.map_size = 256;
            o.options.shadow_map.pcf = pcf.parse().unwrap();
        };
        let adaptive = run(&s, "adaptive-maps", 48, |o| {
            set(o);
            o.options.adaptive_maps.adaptive_split_all = true;
        });
        let multi = run(&s, "multi-map", 48, |o| {
            set(o);
            grid289(o);
        });
        assert_eq!(rendered(&adaptive), 289);
        let (a, m) = (adaptive.lights[0].vcoef(), multi.lights[0].vcoef());
        let soft = m.iter().filter(|v| **v > 0.0 && **v < 1.0).count();
        assert!(soft > 50, "{scene}: the test needs a penumbra ({soft})");
        let same = a.iter().zip(m).all(|(x, y)| x.to_bits() == y.to_bits());
        assert!(same, "{scene} pcf {pcf}: not bit-identical");
        assert!(adaptive.radiance == multi.radiance);
    }
}

/// A receiver lit by all 289 points is lit by every subset, one in the
/// umbra of all is shadowed by every subset: the adaptive result keeps
/// those values exactly, with far fewer maps.
#[test]
fn lit_and_umbra_receivers_of_the_17x17_result_are_kept() {
    for scene in ["quad.toml", "spheres.toml"] {
        let s = common::shipped(scene);
        let adaptive = run(&s, "adaptive-maps", 64, |_| {});
        let multi = run(&s, "multi-map", 64, grid289);
        let (a, m) = (adaptive.lights[0].vcoef(), multi.lights[0].vcoef());
        let mut lit = 0;
        let mut umbra = 0;
        for (x, y) in a.iter().zip(m) {
            if *y == 1.0 || *y == 0.0 {
                assert_eq!(x, y, "{scene}");
                lit += usize::from(*y == 1.0);
                umbra += usize::from(*y == 0.0);
            }
        }
        assert!(
            lit > 500 && umbra > 100,
            "{scene}: {lit} lit, {umbra} umbra"
        );
        let maps = rendered(&adaptive);
        assert!(maps < 289, "{scene}: {maps} maps");
        println!("{scene}: {maps} maps");
    }
}

/// Mean |Vcoef − reference| over the ground receivers of the thin-occluder
/// scene (reference at the same 289 grid points).
fn thin_error(out: &Render, reference: &Render) -> f64 {
    let (a, r) = (out.lights[0].vcoef(), reference.lights[0].vcoef());
    let keep: Vec<usize> = (0..r.len()).filter(|&i| r[i] > 0.0).collect();
    keep.iter()
        .map(|&i| f64::from((a[i] - r[i]).abs()))
        .sum::<f64>()
        / keep.len() as f64
}

/// The plate near the light: every corner's shadow misses the ground, so
/// the paper's corner test (`--adaptive-centre-depth 0`) keeps four maps
/// and loses the shadow (a quarter of the light); the centre probe splits
/// and recovers it.
#[test]
fn the_centre_probe_finds_the_occluder_the_corners_miss() {
    let s = common::shipped("thin-occluder.toml");
    let reference = run(&s, "reference", 48, grid289);
    let shadowed = reference.lights[0]
        .vcoef()
        .iter()
        .filter(|v| **v > 0.0 && **v < 0.85)
        .count();
    assert!(shadowed > 500, "the scene needs its shadow ({shadowed})");
    let paper = run(&s, "adaptive-maps", 48, |o| {
        o.options.adaptive_maps.adaptive_centre_depth = 0;
    });
    let fixed = run(&s, "adaptive-maps", 48, |_| {});
    let (e_paper, e_fixed) = (
        thin_error(&paper, &reference),
        thin_error(&fixed, &reference),
    );
    println!(
        "paper: {} maps, error {e_paper:.4}; probe: {} maps, error {e_fixed:.4}",
        rendered(&paper),
        rendered(&fixed)
    );
    assert_eq!(rendered(&paper), 4);
    // Lost: the ground is fully lit where a quarter of the light is hidden.
    assert!(e_paper > 0.2, "{e_paper}");
    assert!(e_fixed < 0.02, "{e_fixed}");
}

#[test]
fn same_bits_for_any_thread_count() {
    let s = common::shipped("spheres.toml");
    let go = |threads| {
        with_threads(Some(threads), || {
            run(&s, "adaptive-maps", 64, |o| {
                o.options.shadow_map.map_size = 256;
                o.options.adaptive_maps.max_depth = 3;
                o.options.adaptive_maps.comparison_scale = 0.5;
            })
        })
        .expect("pool")
    };
    let one = go(1);
    let two = go(2);
    assert!(one.lights[0].vcoef() == two.lights[0].vcoef());
    assert_eq!(rendered(&one), rendered(&two));
    assert!(one.radiance == go(3).radiance);
}

/// §3.3.2: a smaller comparison target, or a threshold, never needs more
/// maps; depth 0 is the four corners.
#[test]
fn coarser_criteria_use_fewer_maps() {
    let s = common::shipped("quad.toml");
    let full = rendered(&run(&s, "adaptive-maps", 64, |_| {}));
    let half = rendered(&run(&s, "adaptive-maps", 64, |o| {
        o.options.adaptive_maps.comparison_scale = 0.25;
    }));
    let tolerant = rendered(&run(&s, "adaptive-maps", 64, |o| {
        o.options.adaptive_maps.adaptive_threshold = 1000;
    }));
    let corners = rendered(&run(&s, "adaptive-maps", 64, |o| {
        o.options.adaptive_maps.max_depth = 0;
    }));
    println!("full {full}, quarter target {half}, threshold 1000 {tolerant}");
    assert!(half <= full && tolerant <= full);
    assert!(half < full || tolerant < full, "{full} {half} {tolerant}");
    assert_eq!(corners, 4);
}

/// The bias band keeps acne and light leak out of the banding test: on
/// bunny-paper (self-shadowed curved mesh, contact with the ground) the
/// paper's test splits on the corner maps' differing acne, the band does
/// not (docs/algorithms/adaptive-light-sampling.md: 280 → 25 maps at 256²).
#[test]
fn the_bias_band_keeps_acne_out_of_the_test() {
    let s = common::shipped("bunny-paper.toml");
    let maps = |high: f64| {
        rendered(&run(&s, "adaptive-maps", 128, |o| {
            o.options.shadow_map.map_size = 512;
            o.options.adaptive_maps.adaptive_band_high = high;
        }))
    };
    let (band, paper) = (maps(4.0), maps(0.0));
    println!("bunny-paper 128²: band {band} maps, no band {paper}");
    assert!(band < paper, "{band} {paper}");
}

#[test]
fn sphere_lights_and_absurd_parameters_are_refused() {
    let toml = "[scene]\nname = \"s\"\n[camera]\neye = [0.0, 3.0, 5.0]\ntarget = [0.0, 0.0, 0.0]\n\
                up = [0.0, 1.0, 0.0]\nfov_y = 45.0\nwidth = 16\nheight = 16\n\
                [[light]]\ntype = \"sphere\"\ncenter = [0.0, 4.0, 0.0]\nradius = 0.5\n\
                radiance = [1.0, 1.0, 1.0]\n[[object]]\nshape = \"quad\"\nsize = [4.0, 4.0]\n";
    let sphere = common::scene_in_scratch("adaptive-sphere", toml, &[]);
    let options = RenderOptions {
        width: Some(16),
        height: Some(16),
        technique: Technique::named("adaptive-maps").unwrap(),
        ..RenderOptions::default()
    };
    let e = render(&sphere, &options).expect_err("refused");
    assert!(e.to_string().contains("--technique"), "{e}");
    let quad = common::shipped("quad.toml");
    for (name, scale) in [("--comparison-scale", 0.0), ("--comparison-scale", 1.5)] {
        let mut o = options.clone();
        o.options.adaptive_maps.comparison_scale = scale;
        let e = render(&quad, &o).expect_err("refused");
        assert!(e.to_string().contains(name), "{e}");
    }
    let mut o = options.clone();
    o.options.adaptive_maps.max_depth = 9;
    let e = render(&quad, &o).expect_err("refused");
    assert!(e.to_string().contains("--max-depth"), "{e}");
    for (name, low, high) in [
        ("--adaptive-band-low", -1.0, 4.0),
        ("--adaptive-band-high", 0.5, f64::NAN),
    ] {
        let mut o = options.clone();
        o.options.adaptive_maps.adaptive_band_low = low;
        o.options.adaptive_maps.adaptive_band_high = high;
        let e = render(&quad, &o).expect_err("refused");
        assert!(e.to_string().contains(name), "{e}");
    }
}
