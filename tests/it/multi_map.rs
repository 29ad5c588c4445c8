//! Many hard maps per light (multi-map): the mean of N hard tests at N
//! points converges to the reference traced at the same N points, up to
//! the maps' depth and resolution error; a point-sized light gives the one
//! hard map; the result does not depend on the thread count; memory does
//! not grow with the number of maps; receivers that face away get nothing.

use crate::common;

use penumbra::internal::render::{render, with_threads, Aov, Render, RenderOptions};
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

/// Receivers that face the light (the others get Vcoef 0 by design, the
/// reference their pure visibility): the scene's light is above, so a
/// receiver faces it when its normal points up-ish; found as those where
/// the unshadowed technique `none` gives light. Compared as the mean
/// absolute Vcoef difference and the share of receivers off by > 0.1.
fn errors(a: &[f32], b: &[f32], keep: &[bool]) -> (f64, f64, usize) {
    let mut sum = 0.0;
    let mut far = 0usize;
    let mut count = 0usize;
    for ((x, y), k) in a.iter().zip(b).zip(keep) {
        if !k {
            continue;
        }
        let d = f64::from((x - y).abs());
        sum += d;
        far += usize::from(d > 0.1);
        count += 1;
    }
    (
        sum / count.max(1) as f64,
        far as f64 / count.max(1) as f64,
        count,
    )
}

/// Lit receivers facing up (normal.y > 0.5): the ground and the tops of
/// curved casters, away from the terminators of tessellated spheres, where
/// the reference's ray offset and the maps' bias disagree about
/// self-shadowing (the scene contract lets error figures leave those out).
fn lit_receivers(scene: &Scene, size: u32) -> Vec<bool> {
    let out = run(scene, "none", size, |o| o.aovs = vec![Aov::Normal]);
    let normal = out
        .layers
        .iter()
        .find(|l| l.name == "normal")
        .expect("normal layer");
    let ny = &normal
        .channels
        .iter()
        .find(|c| c.0 == "Y")
        .expect("normal.Y")
        .1;
    out.radiance
        .iter()
        .zip(ny)
        .map(|(r, y)| r.max_element() > 0.05 && *y > 0.5)
        .collect()
}

/// multi-map with N maps at the grid / correlated points against the
/// reference traced at exactly those points: the difference is the maps'
/// depth and resolution error only. Tolerance (at 96², 1024² maps):
/// mean |ΔVcoef| < 0.02 and fewer than 3 % of the receivers off by more
/// than 0.1. Measured: quad 0.0003 / 0.25 %, spheres 0.012 / 1.3 % (light
/// leaks between the densely packed spheres: 0.033 → 0.025 → 0.018 over
/// all pixels at 1024², 2048², 4096² maps), quad correlated 16 below 0.001.
#[test]
fn converges_to_the_reference_at_the_same_points() {
    for (scene, n, pattern) in [
        ("quad.toml", 81, SamplePattern::Grid),
        ("spheres.toml", 25, SamplePattern::Grid),
        ("quad.toml", 16, SamplePattern::Correlated),
    ] {
        let s = common::shipped(scene);
        let keep = lit_receivers(&s, 96);
        let set = |o: &mut RenderOptions| {
            o.samples = n;
            o.pattern = pattern;
        };
        let maps = run(&s, "multi-map", 96, set);
        let reference = run(&s, "reference", 96, set);
        let (mean, far, count) = errors(maps.lights[0].vcoef(), reference.lights[0].vcoef(), &keep);
        println!("{scene} {n} {pattern}: mean {mean:.5}, > 0.1: {far:.4} of {count}");
        assert!(count > 1000, "{scene}: {count} receivers");
        assert!(mean < 0.02, "{scene} {n} {pattern}: mean {mean}");
        assert!(far < 0.03, "{scene} {n} {pattern}: {far} off by > 0.1");
        // Not trivially equal: the scene has soft shadow to get right.
        let soft = reference.lights[0]
            .vcoef()
            .iter()
            .zip(&keep)
            .filter(|(v, k)| **k && **v > 0.05 && **v < 0.95)
            .count();
        assert!(soft > 100, "{scene}: only {soft} penumbra receivers");
    }
}

/// A point-sized light: every map is the light centre's, so multi-map is
/// the hard shadow map up to the points' spread of 1e-3 of the light.
#[test]
fn a_tiny_light_gives_the_hard_shadow_map() {
    let toml = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/quad.toml"))
        .unwrap()
        .replace("u = [0.5, 0.0, 0.0]", "u = [0.0005, 0.0, 0.0]")
        .replace("v = [0.0, 0.0, 0.5]", "v = [0.0, 0.0, 0.0005]");
    let scene = common::scene_in_scratch("multi-map-tiny", &toml, &[]);
    let hard = run(&scene, "shadow-map", 96, |_| {});
    let many = run(&scene, "multi-map", 96, |o| o.samples = 16);
    let (a, b) = (many.lights[0].vcoef(), hard.lights[0].vcoef());
    let shadowed = b.iter().filter(|&&v| v < 0.5).count();
    assert!(shadowed > 300, "the test needs a shadow: {shadowed}");
    let differ = a
        .iter()
        .zip(b)
        .filter(|(x, y)| (**x - **y).abs() > 0.5)
        .count();
    // Only receivers on the outline may flip (perimeter ~80 pixels).
    assert!(differ <= 20, "{differ} receivers differ");
    let soft = a.iter().filter(|v| **v > 0.01 && **v < 0.99).count();
    assert!(
        soft <= 80,
        "{soft} receivers in a penumbra of a point light"
    );
}

#[test]
fn same_bits_for_any_thread_count() {
    let scene = common::shipped("spheres.toml");
    let go = |threads| {
        with_threads(Some(threads), || {
            run(&scene, "multi-map", 64, |o| {
                o.samples = 9;
                o.options.shadow_map.map_size = 256;
                o.options.shadow_map.pcf = "poisson:4".parse().unwrap();
            })
        })
        .expect("pool")
    };
    let one = go(1);
    assert!(one.lights[0].vcoef() == go(2).lights[0].vcoef());
    assert!(one.radiance == go(3).radiance);
}

fn note<'a>(out: &'a Render, name: &str) -> &'a penumbra::internal::shadow::BufferNote {
    out.explain
        .buffers
        .iter()
        .find(|b| b.name == name)
        .unwrap_or_else(|| panic!("no buffer note {name}"))
}

/// Maps are consumed one at a time: the buffers do not grow with N, and
/// `--explain` says how many maps were rendered.
#[test]
fn memory_does_not_grow_with_the_number_of_maps() {
    let scene = common::shipped("quad.toml");
    let few = run(&scene, "multi-map", 48, |o| {
        o.samples = 4;
        o.options.shadow_map.map_size = 128;
    });
    let many = run(&scene, "multi-map", 48, |o| {
        o.samples = 64;
        o.options.shadow_map.map_size = 128;
    });
    for name in ["shadow maps", "map accumulators"] {
        assert_eq!(note(&few, name).bytes, note(&many, name).bytes, "{name}");
        assert!(note(&few, name).bytes > 0);
    }
    assert!(note(&few, "shadow maps").detail.starts_with("4 rendered"));
    assert!(note(&many, "shadow maps").detail.starts_with("64 rendered"));
}

/// A light facing away from every receiver: no map is rendered, nothing
/// is lit.
#[test]
fn a_light_no_receiver_faces_gets_no_maps() {
    let toml = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/quad.toml"))
        .unwrap()
        .replace("center = [0.0, 4.0, 0.0]", "center = [0.0, -4.0, 0.0]");
    let scene = common::scene_in_scratch("multi-map-away", &toml, &[]);
    let out = run(&scene, "multi-map", 48, |o| o.samples = 16);
    assert!(
        note(&out, "shadow maps").detail.starts_with("0 rendered"),
        "{}",
        note(&out, "shadow maps").detail
    );
    assert!(out.lights[0].vcoef().iter().all(|&v| v == 0.0));
}

#[test]
fn absurd_map_counts_are_refused() {
    let scene = common::shipped("quad.toml");
    let options = RenderOptions {
        width: Some(16),
        height: Some(16),
        technique: Technique::named("multi-map").unwrap(),
        samples: 0,
        ..RenderOptions::default()
    };
    let e = render(&scene, &options).expect_err("refused");
    assert!(e.to_string().contains("--samples"), "{e}");
}

/// The four-lane hard look-up (`HardLanes`, the default path) gives the
/// scalar `project_receiver` + hard test's value for every receiver, on the
/// spheres' G-buffer points and on points jittered off them (shadow edges,
/// behind the view, outside the window), from a corner of the light.
#[test]
fn lane_look_up_equals_the_scalar_one() {
    use penumbra::internal::gbuffer::{gbuffer_pass, GSample};
    use penumbra::internal::geom::SceneGeometry;
    use penumbra::internal::render::view_for;
    use penumbra::internal::shadow::kit::light_view::{caster_bounds, receiver_bounds};
    use penumbra::internal::shadow::kit::many_maps::{point_on_light, HardLanes};
    use penumbra::internal::shadow::kit::shadow_maps::{
        light_view_at, opaque_depth_map, pcf_visibility, project_receiver, DepthBias, Pcf,
    };
    let scene = common::shipped("spheres.toml");
    let options = RenderOptions {
        width: Some(96),
        height: Some(96),
        ..RenderOptions::default()
    };
    let view = view_for(&scene, &options).unwrap();
    let geometry = SceneGeometry::new(&scene);
    let (gbuffer, _, _) = gbuffer_pass(&scene, &geometry, &view).unwrap();
    let (casters, receivers) = (
        caster_bounds(&scene).unwrap(),
        receiver_bounds(&scene).unwrap(),
    );
    let light = &scene.lights[0];
    let lv = light_view_at(
        light,
        point_on_light(light, (0.0, 1.0), casters),
        casters,
        receivers,
        (256, 256),
    )
    .unwrap()
    .unwrap();
    let map = opaque_depth_map(&scene, &geometry, &lv.view).unwrap();
    let mut points: Vec<(glam::Vec3, glam::Vec3)> = (0..gbuffer.len())
        .map(|i| gbuffer.sample(i))
        .filter(|g| g.is_surface())
        .map(|g| (g.position, g.geo_normal))
        .collect();
    let n = points.len();
    let mut state = 0x1234_5678u64;
    for k in 0..n {
        state = penumbra::internal::sampling::mix64(state);
        let j = |s: u64| ((s & 0xffff) as f32 / 65535.0 - 0.5) * 0.05;
        let (p, nm) = points[k];
        points.push((
            p + glam::Vec3::new(j(state), j(state >> 16), j(state >> 32)),
            nm,
        ));
    }
    // Behind the view's eye and far outside its window.
    points.push((lv.view.eye.as_vec3() + glam::Vec3::Y, glam::Vec3::Y));
    points.push((glam::Vec3::new(1e4, 0.0, 0.0), glam::Vec3::Y));
    for bias in [
        DepthBias {
            constant: 1e-4,
            slope: 0.0,
            normal_offset: 0.5,
        },
        DepthBias {
            constant: 0.0,
            slope: 0.0,
            normal_offset: 0.0,
        },
    ] {
        let lanes = HardLanes::new(&lv.view, &bias);
        let (mut lit, mut shadowed) = (0, 0);
        for quad in points.chunks_exact(4) {
            let quad: [(glam::Vec3, glam::Vec3); 4] = quad.try_into().unwrap();
            let got = lanes.visibility(&map, &quad);
            for (l, &(position, geo_normal)) in quad.iter().enumerate() {
                let g = GSample {
                    position,
                    geo_normal,
                    ..GSample::BACKGROUND
                };
                let want = project_receiver(&g, &lv.view, &bias)
                    .map_or(0.0, |r| pcf_visibility(&map, &r, Pcf::Nearest, &[], 0.0));
                assert_eq!(got[l].to_bits(), want.to_bits(), "receiver {position:?}");
                if want == 1.0 {
                    lit += 1;
                } else {
                    shadowed += 1;
                }
            }
        }
        // Both outcomes occur: the comparison is not vacuous.
        assert!(
            lit > 100 && shadowed > 100,
            "{lit} lit, {shadowed} shadowed"
        );
    }
}
