//! Hard shadow maps against the exact hard shadow: with a point-sized
//! light, the reference's one-sample visibility is the hard shadow of the
//! light's centre; a map of enough resolution agrees with it except within
//! a few texels of shadow edges.

use crate::common;

use penumbra::internal::render::{render, RenderOptions};
use penumbra::internal::shadow::Technique;

fn vcoef(
    scene: &penumbra::internal::scene::Scene,
    name: &str,
    f: impl Fn(&mut RenderOptions),
) -> Vec<f32> {
    let mut options = RenderOptions {
        width: Some(96),
        height: Some(96),
        technique: Technique::named(name).unwrap(),
        samples: 1,
        ..RenderOptions::default()
    };
    f(&mut options);
    let out = render(scene, &options).expect("render");
    out.lights[0].vcoef().to_vec()
}

/// The quad scene with its light shrunk to a near-point: the shadow is
/// (almost) hard, and the hard map must find it.
#[test]
fn a_tiny_light_gives_the_reference_hard_shadow() {
    let toml = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/quad.toml"))
        .unwrap()
        .replace("u = [0.5, 0.0, 0.0]", "u = [0.0005, 0.0, 0.0]")
        .replace("v = [0.0, 0.0, 0.5]", "v = [0.0, 0.0, 0.0005]");
    let scene = common::scene_in_scratch("shadow-map-tiny", &toml, &[]);
    let reference = vcoef(&scene, "reference", |_| {});
    for pcf in ["1", "2x2", "3x3", "poisson:8"] {
        let map = vcoef(&scene, "shadow-map", |o| {
            o.options.shadow_map.pcf = pcf.parse().unwrap();
            o.options.shadow_map.map_size = 2048;
        });
        let shadowed = reference.iter().filter(|&&v| v < 0.5).count();
        assert!(shadowed > 300, "the test needs a shadow: {shadowed}");
        let differ = map
            .iter()
            .zip(&reference)
            .filter(|(a, b)| (**a - **b).abs() > 0.5)
            .count();
        // Only pixels straddling the shadow's outline may differ: its
        // perimeter is about 4 × 20 pixels at 96².
        assert!(differ <= 40, "pcf {pcf}: {differ} pixels differ");
        assert!(map.iter().all(|v| v.is_finite() && (0.0..=1.0).contains(v)));
    }
}

#[test]
fn absurd_parameters_are_refused_with_their_name() {
    let scene = common::shipped("quad.toml");
    let options = RenderOptions {
        width: Some(16),
        height: Some(16),
        technique: Technique::named("shadow-map").unwrap(),
        ..RenderOptions::default()
    };
    for (name, set) in [
        (
            "--depth-bias",
            (|o: &mut RenderOptions| o.options.shadow_map.depth_bias = f64::NAN)
                as fn(&mut RenderOptions),
        ),
        ("--slope-bias", |o: &mut RenderOptions| {
            o.options.shadow_map.slope_bias = -1.0
        }),
        ("--normal-offset", |o: &mut RenderOptions| {
            o.options.shadow_map.normal_offset = 1e9
        }),
    ] {
        let mut o = options.clone();
        set(&mut o);
        let e = render(&scene, &o).expect_err("refused");
        assert!(e.to_string().contains(name), "{e}");
    }
    let e = "poisson:0"
        .parse::<penumbra::internal::shadow::shadow_map::Pcf>()
        .expect_err("refused");
    assert!(e.contains("poisson"), "{e}");
}
