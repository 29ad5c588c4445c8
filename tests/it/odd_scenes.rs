//! Odd but legal scenes (issue 19, point 9): every technique gives the
//! reference's answer or refuses the scene with an error that says why —
//! never a silently different image. The loops run over the registry, so
//! a new technique is held to the same rule.

use crate::common;

use penumbra::internal::render::{render, Render, RenderOptions};
use penumbra::internal::sampling::SamplePattern;
use penumbra::internal::scene::Scene;
use penumbra::internal::shadow::{Technique, TechniqueOptions};

const SIZE: u32 = 48;

fn run(
    scene: &Scene,
    technique: Technique,
    options: TechniqueOptions,
) -> penumbra::internal::error::Result<Render> {
    run_with(scene, technique, options, SamplePattern::default())
}

fn run_with(
    scene: &Scene,
    technique: Technique,
    options: TechniqueOptions,
    pattern: SamplePattern,
) -> penumbra::internal::error::Result<Render> {
    render(
        scene,
        &RenderOptions {
            technique,
            samples: 16,
            width: Some(SIZE),
            height: Some(SIZE),
            options,
            pattern,
            ..RenderOptions::default()
        },
    )
}

fn vcoef(out: &Render) -> Vec<f32> {
    out.lights[0].vcoef().to_vec()
}

/// Mean and largest absolute difference of two Vcoef images.
fn difference(a: &[f32], b: &[f32]) -> (f64, f64) {
    assert_eq!(a.len(), b.len());
    let mut sum = 0.0;
    let mut max: f64 = 0.0;
    for (x, y) in a.iter().zip(b) {
        assert!(x.is_finite(), "non-finite Vcoef");
        let d = f64::from((x - y).abs());
        sum += d;
        max = max.max(d);
    }
    (sum / a.len() as f64, max)
}

const CAMERA_OUTSIDE: &str = r#"
[camera]
eye = [0.0, 5.0, 8.0]
target = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 45.0
width = 48
height = 48
"#;

const GROUND: &str = r#"
[[object]]
name = "ground"
shape = "quad"
size = [8.0, 8.0]
translate = [0.0, -1.5, 0.0]
"#;

fn light_in_box() -> Scene {
    common::scene_in_scratch(
        "odd-light-in-box",
        &format!(
            r#"{CAMERA_OUTSIDE}
[[light]]
type = "rect"
center = [0.0, 0.5, 0.0]
u = [0.3, 0.0, 0.0]
v = [0.0, 0.0, 0.3]
radiance = [10.0, 10.0, 10.0]
{GROUND}
[[object]]
name = "closed-box"
shape = "box"
size = [2.0, 2.0, 2.0]
"#
        ),
        &[],
    )
}

fn light_in_sphere() -> Scene {
    common::scene_in_scratch(
        "odd-light-in-sphere",
        &format!(
            r#"{CAMERA_OUTSIDE}
[[light]]
type = "sphere"
center = [0.0, 0.3, 0.0]
radius = 0.2
radiance = [10.0, 10.0, 10.0]
{GROUND}
[[object]]
name = "closed-sphere"
shape = "sphere"
radius = 1.2
"#
        ),
        &[],
    )
}

/// The enclosed light's shadow covers everything outside the closed
/// caster: the reference is 0 on every visible receiver (the caster's
/// outside faces and the ground), so a technique either refuses, naming
/// the light and the caster, or agrees.
fn enclosed(scene: &Scene, object: &str) {
    let reference = vcoef(
        &run(
            scene,
            Technique::named("reference").unwrap(),
            TechniqueOptions::default(),
        )
        .unwrap(),
    );
    assert!(
        reference.iter().all(|&v| v == 0.0),
        "reference is dark outside the caster"
    );
    for t in Technique::all() {
        if t.name() == "none" {
            continue; // unshadowed by definition
        }
        match run(scene, t, TechniqueOptions::default()) {
            Err(e) => {
                let e = e.to_string();
                let other_refusal = matches!(
                    t.capabilities(&TechniqueOptions::default()).sphere_lights,
                    penumbra::internal::shadow::technique::Support::Refused { .. }
                ) && e.contains("sphere lights");
                assert!(
                    other_refusal
                        || (e.contains("closed caster")
                            && e.contains(object)
                            && e.contains("light 0")),
                    "{}: {e}",
                    t.name()
                );
            }
            Ok(out) => {
                let (mean, max) = difference(&vcoef(&out), &reference);
                // Exact and approximate alike: the whole image is umbra.
                assert!(
                    mean < 1e-3 && max < 0.05,
                    "{}: mean {mean}, max {max}",
                    t.name()
                );
            }
        }
    }
}

#[test]
fn a_rect_light_inside_a_closed_box_is_refused_or_dark_outside_it() {
    enclosed(&light_in_box(), "closed-box");
}

#[test]
fn a_sphere_light_inside_a_closed_sphere_is_refused_or_dark_outside_it() {
    enclosed(&light_in_sphere(), "closed-sphere");
}

/// A light in a closed room seen from inside the room is not refused:
/// every visible receiver is inside the room, where silhouettes are
/// right, and exact techniques agree with the reference.
#[test]
fn a_light_in_a_closed_room_seen_from_inside_renders_and_exact_techniques_agree() {
    let scene = common::scene_in_scratch(
        "odd-room",
        r#"
[camera]
eye = [0.0, 0.5, 2.5]
target = [0.0, -0.5, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 60.0
width = 48
height = 48

[[light]]
type = "rect"
center = [0.0, 1.4, 0.0]
u = [0.3, 0.0, 0.0]
v = [0.0, 0.0, 0.3]
radiance = [10.0, 10.0, 10.0]

[[object]]
name = "room"
shape = "box"
size = [6.0, 3.0, 6.0]

[[object]]
name = "cube"
shape = "box"
size = [0.5, 0.5, 0.5]
translate = [0.0, -1.0, 0.0]
"#,
        &[],
    );
    let reference = vcoef(
        &run(
            &scene,
            Technique::named("reference").unwrap(),
            TechniqueOptions::default(),
        )
        .unwrap(),
    );
    // The cube's shadow is on the floor: not all lit, not all dark.
    let lit = reference.iter().filter(|&&v| v == 1.0).count();
    assert!(lit > reference.len() / 2 && lit < reference.len(), "{lit}");
    for t in Technique::all() {
        let (options, pattern) = common::matched_sampling(t);
        let out = run_with(&scene, t, options.clone(), pattern)
            .unwrap_or_else(|e| panic!("{}: {e}", t.name()));
        let v = vcoef(&out);
        let reference = vcoef(
            &run_with(
                &scene,
                Technique::named("reference").unwrap(),
                options,
                pattern,
            )
            .unwrap(),
        );
        let (mean, _) = difference(&v, &reference);
        if t.capabilities(&TechniqueOptions::default()).exact {
            // Same samples, same receivers: only ties may differ.
            assert!(mean < 1e-3, "{}: mean {mean}", t.name());
        }
    }
}

/// An occluder just behind a one-sided light's plane (it emits away from
/// it) casts nothing; with the eye inside that occluder's volume, z-pass
/// would count every pixel shadowed. It is refused, naming `--zpass`;
/// z-fail (the default) agrees with the reference.
#[test]
fn zpass_with_the_eye_in_a_volume_is_refused_and_zfail_agrees() {
    let scene = common::scene_in_scratch(
        "odd-zpass",
        r#"
[camera]
eye = [0.0, 5.0, 6.0]
target = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 45.0
width = 48
height = 48

[[light]]
type = "rect"
center = [0.0, 4.0, 0.0]
u = [0.5, 0.0, 0.0]
v = [0.0, 0.0, 0.5]
radiance = [10.0, 10.0, 10.0]

[[object]]
name = "ground"
shape = "quad"
size = [6.0, 6.0]

[[object]]
name = "in-the-light-plane"
shape = "quad"
size = [2.0, 2.0]
translate = [0.0, 4.0, 0.0]
"#,
        &[],
    );
    let sv = Technique::named("shadow-volumes").unwrap();
    let mut zpass = TechniqueOptions::default();
    zpass.shadow_volumes.zpass = true;
    let e = run(&scene, sv, zpass)
        .expect_err("z-pass refused")
        .to_string();
    assert!(e.contains("--zpass") && e.contains("z-fail"), "{e}");
    let reference = vcoef(
        &run(
            &scene,
            Technique::named("reference").unwrap(),
            TechniqueOptions::default(),
        )
        .unwrap(),
    );
    let zfail = vcoef(&run(&scene, sv, TechniqueOptions::default()).unwrap());
    // Nothing shadows the ground here: both fully lit where it is seen.
    assert_eq!(difference(&zfail, &reference).1, 0.0);
    assert!(reference.contains(&1.0));
}

/// A tiny sphere light (radius 1e-9 .. 1e-3, which the docs accept) at
/// `[0, 4, 0]`: a point on it rounded to f32 lands off the sphere by more
/// than the radius. The light-view techniques render it, as a point light,
/// with the reference's hard shadow of a box on the ground (fuzz repro
/// `tiny-sphere-light-point-on-light`).
#[test]
fn tiny_sphere_lights_render_with_light_view_techniques() {
    for radius in ["1e-9", "1e-5", "1e-4", "1e-3"] {
        let scene = common::scene_in_scratch(
            &format!("tiny-sphere-{radius}"),
            &format!(
                "[camera]\neye = [0, 5, 6]\ntarget = [0, 0, 0]\nfov_y = 45\n\
                 width = 48\nheight = 48\n\
                 [[light]]\ntype = \"sphere\"\ncenter = [0, 4, 0]\nradius = {radius}\n\
                 radiance = 10\n\
                 [[object]]\nname = \"ground\"\nshape = \"quad\"\nsize = [6.0, 6.0]\n\
                 [[object]]\nshape = \"box\"\ntranslate = [0, 1, 0]\n"
            ),
            &[],
        );
        let reference = run(
            &scene,
            Technique::named("reference").unwrap(),
            TechniqueOptions::default(),
        )
        .expect("reference renders");
        let want = reference.lights[0].vcoef();
        for name in ["shadow-map", "pcss", "multi-map"] {
            let out = run(
                &scene,
                Technique::named(name).unwrap(),
                TechniqueOptions::default(),
            )
            .unwrap_or_else(|e| panic!("radius {radius}, {name}: {e}"));
            let got = out.lights[0].vcoef();
            // A hard shadow: the pixels may differ only along its edge.
            let differ = (got.iter().zip(want))
                .filter(|(g, w)| (*g - *w).abs() > 0.5)
                .count();
            let shadowed = want.iter().filter(|&&w| w < 0.5).count();
            assert!(shadowed > 20, "radius {radius}: the box casts a shadow");
            assert!(
                differ * 10 < shadowed,
                "radius {radius}, {name}: {differ} pixels differ from the reference \
                 ({shadowed} in its shadow)"
            );
        }
    }
}
