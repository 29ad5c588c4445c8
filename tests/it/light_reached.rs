//! Casters that reach into a light: an open quad through a rect light, a
//! quad through a sphere light, a closed box poking into a sphere light
//! (its centre outside the box, so the enclosure rule does not see it).
//! Exact DCS counts from the light's centre and clips its edges at the
//! light, which such casters break (before the refusal: 97 %, 83 % and
//! 21 % of the pixels wrong, exit 0): it must refuse them with the reason,
//! and the techniques that take them (penumbra casting, the reference)
//! must agree with each other bit for bit; so is a quad standing with an
//! edge on a rect light. A caster just short of the light is not refused,
//! and DCS agrees with the reference there.

use crate::common;

use penumbra::internal::render::{render, RenderOptions, Technique};
use penumbra::internal::sampling::SamplePattern;

const GROUND: &str = r#"
[camera]
eye = [0, 5, 6]
target = [0, 0, 0]
fov_y = 45
width = 40
height = 40
[[object]]
name = "ground"
shape = "quad"
size = [6.0, 6.0]
"#;

const RECT: &str = r#"
[[light]]
type = "rect"
center = [0, 4, 0]
u = [0.5, 0, 0]
v = [0, 0, 0.5]
radiance = 10
"#;

const SPHERE: &str = r#"
[[light]]
type = "sphere"
center = [0, 4, 0]
radius = 0.5
radiance = 10
"#;

/// A vertical unit quad centred at height `y`.
fn quad_at(y: f32) -> String {
    format!(
        "[[object]]\nname = \"blade\"\nshape = \"quad\"\nsize = [1, 1]\ntranslate = [0, {y}, 0]\nrotate = [90, 0, 0]\n"
    )
}

/// A unit box centred at `(x, y, 0)`.
fn box_at(x: f32, y: f32) -> String {
    format!("[[object]]\nname = \"block\"\nshape = \"box\"\nsize = [1, 1, 1]\ntranslate = [{x}, {y}, 0]\n")
}

fn options(name: &str) -> RenderOptions {
    RenderOptions {
        technique: Technique::named(name).expect("registered"),
        samples: 16,
        seed: 3,
        pattern: SamplePattern::Correlated,
        ..RenderOptions::default()
    }
}

fn vcoef(scene: &penumbra::internal::scene::Scene, name: &str) -> Vec<f32> {
    let out = render(scene, &options(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
    out.lights[0].vcoef().to_vec()
}

/// DCS refuses, naming the caster and the light; the exact techniques
/// that take the scene agree bit for bit, and the caster does shadow.
fn assert_refused_and_others_agree(case: &str, toml: &str, caster: &str) {
    let scene = common::scene_in_scratch(case, toml, &[]);
    let err = render(&scene, &options("dcs"))
        .err()
        .unwrap_or_else(|| panic!("{case}: dcs rendered a caster reaching into the light"))
        .to_string();
    assert!(err.contains("--technique"), "{case}: {err}");
    assert!(
        err.contains(&format!("`{caster}` reaches into light 0")),
        "{case}: {err}"
    );
    let reference = vcoef(&scene, "reference");
    let pc = vcoef(&scene, "penumbra-casting");
    let differ = reference
        .iter()
        .zip(&pc)
        .filter(|(a, b)| a.to_bits() != b.to_bits())
        .count();
    assert_eq!(
        differ, 0,
        "{case}: penumbra casting differs from the reference"
    );
    assert!(
        reference.iter().filter(|&&v| v < 1.0).count() > reference.len() / 50,
        "{case}: the caster casts no shadow"
    );
}

#[test]
fn quad_standing_on_a_rect_light_is_refused_by_dcs() {
    let toml = format!("{GROUND}{RECT}{}", quad_at(3.5));
    assert_refused_and_others_agree("reach-touch", &toml, "blade");
}

#[test]
fn open_quad_through_a_rect_light_is_refused_by_dcs() {
    let toml = format!("{GROUND}{RECT}{}", quad_at(4.0));
    assert_refused_and_others_agree("reach-rect", &toml, "blade");
}

#[test]
fn open_quad_through_a_sphere_light_is_refused_by_dcs() {
    let toml = format!("{GROUND}{SPHERE}{}", quad_at(4.0));
    assert_refused_and_others_agree("reach-sphere", &toml, "blade");
}

#[test]
fn box_poking_into_a_sphere_light_is_refused_by_dcs() {
    // The box spans y ∈ [2.7, 3.7] and x ∈ [0.1, 1.1]: its top corner
    // region is 0.3 below the centre, inside the ball of radius 0.5, and
    // the centre itself is outside the box.
    let toml = format!("{GROUND}{SPHERE}{}", box_at(0.6, 3.2));
    assert_refused_and_others_agree("reach-box", &toml, "block");
}

/// Just short of the light (the quad's top edge 1e-3 below a rect light,
/// a box 1e-3 below a sphere light's ball) the scene is not refused, and
/// DCS equals the reference at every pixel.
#[test]
fn casters_just_short_of_the_light_render_exactly() {
    let cases = [
        (
            "short-rect",
            format!("{GROUND}{RECT}{}", quad_at(4.0 - 0.501)),
        ),
        (
            "short-sphere",
            format!("{GROUND}{SPHERE}{}", box_at(0.0, 4.0 - 0.501 - 0.5)),
        ),
    ];
    for (case, toml) in cases {
        let scene = common::scene_in_scratch(case, &toml, &[]);
        let dcs = vcoef(&scene, "dcs");
        let reference = vcoef(&scene, "reference");
        let differ = dcs.iter().zip(&reference).filter(|(a, b)| a != b).count();
        assert_eq!(differ, 0, "{case}: {differ} pixels differ");
        assert!(reference.iter().any(|&v| v < 1.0), "{case}: no shadow");
    }
}

/// The test behind the refusal, on its edge cases: an edge lying on a
/// rect light reaches in (DCS was wrong there: a fuzz campaign's quads
/// standing on the light's plane under it), a box tangent to a sphere
/// light's ball does not, nor does a quad crossing the rect's plane
/// beside it.
#[test]
fn touching_a_rect_light_is_reaching_it() {
    use penumbra::internal::geom::SceneGeometry;
    use penumbra::internal::shadow::kit::enclosure::reached_lights;
    let cases = [
        // The quad's top edge exactly in a rect light's plane.
        ("touch-rect", format!("{GROUND}{RECT}{}", quad_at(3.5)), 1),
        // A box whose top face is tangent to the sphere light's ball.
        ("touch-sphere", format!("{GROUND}{SPHERE}{}", box_at(0.0, 3.0)), 0),
        // The quad 0.01 into the rect light.
        ("into-rect", format!("{GROUND}{RECT}{}", quad_at(3.51)), 1),
        // A quad beside the rect light, crossing its plane outside it.
        (
            "beside-rect",
            format!(
                "{GROUND}{RECT}[[object]]\nname = \"side\"\nshape = \"quad\"\nsize = [1, 1]\ntranslate = [2, 4, 0]\nrotate = [90, 0, 0]\n"
            ),
            0,
        ),
    ];
    for (case, toml, expected) in cases {
        let scene = common::scene_in_scratch(case, &toml, &[]);
        let geometry = SceneGeometry::new(&scene);
        assert_eq!(reached_lights(&scene, &geometry).len(), expected, "{case}");
    }
}
