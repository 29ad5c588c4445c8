//! DCS's cost choice (`--dcs-rays`): a light whose counting path would
//! cost more than every receiver's shadow rays is traced instead. Both
//! are exact, so the image must stay the exact one, and the choice comes
//! from counts alone, so the bits must not depend on the thread count.

use crate::common;
use crate::common::{
    dcs_rays_options as options, first_light_traced as traced, first_light_vcoef as vcoef,
};
use penumbra::internal::render::{render, with_threads, Render};
use penumbra::internal::shadow::dcs::RayChoice;

/// One finely tessellated sphere (400 × 400: 319,200 triangles) over a
/// ground quad under a rect light: at 40² counting's setup alone would
/// cost far more than 1,600 receivers' rays.
fn dense_sphere() -> penumbra::internal::scene::Scene {
    common::scene_in_scratch(
        "dcs-rays-dense",
        r#"
[scene]
name = "dense-sphere"
[camera]
eye = [0.0, 3.0, 4.0]
target = [0.0, 0.5, 0.0]
fov_y = 45.0
width = 40
height = 40
[[light]]
type = "rect"
center = [0.0, 4.0, 0.0]
u = [0.8, 0.0, 0.0]
v = [0.0, 0.0, 0.8]
radiance = [8.0, 8.0, 8.0]
[[object]]
shape = "sphere"
radius = 0.6
segments = 400
rings = 400
translate = [0.0, 1.0, 0.0]
[[object]]
shape = "quad"
size = [6.0, 6.0]
"#,
        &[],
    )
}

/// `--explain`'s buffer note `name`: its detail and bytes.
fn buffer(r: &Render, name: &str) -> Option<(String, u64)> {
    r.explain
        .buffers
        .iter()
        .find(|b| b.name == name)
        .map(|b| (b.detail.clone(), b.bytes))
}

/// The number written just before `tail` in an `--explain` note.
fn number_before(text: &str, tail: &str) -> f64 {
    let end = text
        .find(tail)
        .unwrap_or_else(|| panic!("{tail:?} in {text}"));
    text[..end]
        .split_whitespace()
        .last()
        .and_then(|w| w.parse().ok())
        .unwrap_or_else(|| panic!("a number before {tail:?} in {text}"))
}

/// What `--explain` says of light 0's cost choice.
fn note(r: &Render) -> String {
    buffer(r, "cost choice light 0")
        .expect("a cost-choice note")
        .0
}

/// The dense sphere at 40² is traced; the flowers (7.8k triangles) at 40²
/// would save less than the least saving that replaces counting, so they
/// are counted. The explanation says which, with both estimates.
#[test]
fn the_plan_follows_the_estimated_costs() {
    let small = render(&dense_sphere(), &options("dcs", 40, RayChoice::Auto)).unwrap();
    assert!(traced(&small));
    assert!(
        note(&small).starts_with("every receiver traced"),
        "{}",
        note(&small)
    );
    assert!(!small.passes.iter().any(|p| p.name.starts_with("counters")));
    let flowers = common::shipped("flowers.toml");
    let counted = render(&flowers, &options("dcs", 40, RayChoice::Auto)).unwrap();
    assert!(!traced(&counted));
    assert!(
        note(&counted).starts_with("counted: estimated"),
        "{}",
        note(&counted)
    );
    let never = render(&dense_sphere(), &options("dcs", 40, RayChoice::Never)).unwrap();
    assert!(!traced(&never));
    assert!(note(&never).starts_with("counted (rays not an option"));
    // `always` traces the flowers, to the counted bits.
    let always = render(&flowers, &options("dcs", 40, RayChoice::Always)).unwrap();
    assert!(traced(&always));
    assert!(
        note(&always).contains("--dcs-rays always"),
        "{}",
        note(&always)
    );
    // Both exact: they differ only at ties.
    let differing = vcoef(&always)
        .iter()
        .zip(vcoef(&counted))
        .filter(|(a, c)| a != c)
        .count();
    assert!(
        differing <= vcoef(&always).len() / 100,
        "{differing} pixels differ"
    );
}

/// `--explain` itemises the counting path's largest per-light structures
/// (the unbounded edges' regions, the tie recount's table) only where the
/// light is counted, with their bytes: at least the regions' fixed part per
/// edge and the table's four bytes per triangle.
#[test]
fn explain_itemises_the_counted_paths_regions_and_ties() {
    let flowers = common::shipped("flowers.toml");
    let counted = render(&flowers, &options("dcs", 40, RayChoice::Never)).unwrap();
    let (detail, bytes) = buffer(&counted, "edge regions light 0").expect("a regions note");
    let edges = number_before(&detail, " edges without a bounded wedge") as u64;
    assert!(edges > 0, "{detail}");
    assert!(bytes >= edges * 256, "{bytes} bytes for {edges} edges");
    let (_, tie_bytes) = buffer(&counted, "start-count ties light 0").expect("a ties note");
    let triangles = penumbra::internal::geom::SceneGeometry::new(&flowers)
        .triangles
        .len() as u64;
    assert!(
        tie_bytes >= 4 * triangles,
        "{tie_bytes} bytes, {triangles} triangles"
    );
    let traced = render(&dense_sphere(), &options("dcs", 40, RayChoice::Always)).unwrap();
    assert!(buffer(&traced, "edge regions light 0").is_none());
    assert!(buffer(&traced, "start-count ties light 0").is_none());
}

/// An open grid of 20,000 triangles (100 × 100 quads, its vertices
/// shared) over a ground quad: its only edges that change a count are its
/// boundary's, which have one face. The probe counts them as silhouettes
/// from everywhere, as the counting path does, so its pairs are of the
/// order of the counting path's own; dropping them (as a closed object's
/// unmatched edges, its seams, are dropped) left it near none.
#[test]
fn the_probe_counts_an_open_objects_boundary() {
    let n = 100;
    let mut obj = String::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, z) = (i as f32 / n as f32 - 0.5, j as f32 / n as f32 - 0.5);
            obj += &format!("v {x} 0 {z}\n");
        }
    }
    let at = |i: usize, j: usize| j * (n + 1) + i + 1;
    for j in 0..n {
        for i in 0..n {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            obj += &format!("f {a} {d} {c}\nf {a} {c} {b}\n");
        }
    }
    let scene = common::scene_in_scratch(
        "dcs-rays-open-grid",
        r#"
[scene]
name = "open-grid"
[camera]
eye = [0.0, 3.0, 3.0]
target = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 50.0
width = 256
height = 256
[[light]]
type = "rect"
center = [0.3, 4.0, 0.0]
u = [1.0, 0.0, 0.0]
v = [0.0, 0.0, 1.0]
radiance = [8.0, 8.0, 8.0]
[[object]]
obj = "grid.obj"
scale = 1.5
translate = [0.0, 1.2, 0.0]
[[object]]
shape = "quad"
size = [6.0, 6.0]
"#,
        &[("grid.obj", obj.as_bytes())],
    );
    let auto = render(&scene, &options("dcs", 256, RayChoice::Auto)).unwrap();
    let probed = number_before(&note(&auto), " (receiver, edge) pairs");
    let counted = render(&scene, &options("dcs", 256, RayChoice::Never)).unwrap();
    let (detail, bytes) = buffer(&counted, "wedge membership light 0").expect("a membership note");
    let pairs = number_before(&detail, " (pixel, unbounded edge) pairs") + (bytes / 8) as f64;
    assert!(pairs > 1000.0, "{detail}");
    assert!(
        probed > 0.3 * pairs && probed < 3.0 * pairs,
        "probe {probed} against the counting path's {pairs} pairs"
    );
}

/// The cost probe runs where its bounds leave the choice open (the bunny,
/// 69k triangles, at 160²: estimated rays at most 50 ms, counting at least
/// 88 ms but possibly far more), and what it finds, hence the plan and the
/// image, is the same on 1 and 3 threads.
#[test]
fn the_probe_is_the_same_on_any_thread_count() {
    let bunny = common::shipped("bunny.toml");
    let o = options("dcs", 160, RayChoice::Auto);
    let run = |threads| with_threads(Some(threads), || render(&bunny, &o).unwrap()).unwrap();
    let (one, three) = (run(1), run(3));
    assert!(note(&one).contains("probe of"), "{}", note(&one));
    assert!(one.passes.iter().any(|p| p.name.starts_with("cost probe")));
    assert_eq!(note(&one), note(&three));
    assert_eq!(common::render_bits(&one), common::render_bits(&three));
}

/// A traced light's Vcoef is the reference's bit for bit (the same keyed
/// samples, origins and rays, and a count of 0/1 visibilities is exact
/// in f32), and the counted light's agrees with it but at ties: both are
/// the exact answer.
#[test]
fn a_traced_light_is_the_reference_and_agrees_with_counting() {
    let scene = dense_sphere();
    let auto = render(&scene, &options("dcs", 40, RayChoice::Auto)).unwrap();
    let reference = render(&scene, &options("reference", 40, RayChoice::Auto)).unwrap();
    let never = render(&scene, &options("dcs", 40, RayChoice::Never)).unwrap();
    assert!(traced(&auto));
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(vcoef(&auto)), bits(vcoef(&reference)));
    // Counting against rays: a sample differs only at a tie (an edge
    // through the sample's ray within rounding), at most one sample of
    // 16 per differing pixel, and few pixels.
    let (a, n) = (vcoef(&auto), vcoef(&never));
    let differing: Vec<f32> = a
        .iter()
        .zip(n)
        .map(|(x, y)| (x - y).abs())
        .filter(|&d| d > 0.0)
        .collect();
    assert!(
        differing.len() <= a.len() / 100,
        "{} pixels differ",
        differing.len()
    );
    assert!(
        differing.iter().all(|&d| d <= 1.0 / 16.0 + 1e-6),
        "{differing:?}"
    );
    // The radiance: the same estimator on the same visibilities (the
    // counted path evaluates it in f32 lanes), so close everywhere.
    for (i, (x, y)) in auto.radiance.iter().zip(&never.radiance).enumerate() {
        if (vcoef(&auto)[i] - vcoef(&never)[i]).abs() > 0.0 {
            continue;
        }
        let tolerance = 1e-5 * x.max_element().max(1e-3);
        assert!(
            (*x - *y).abs().max_element() <= tolerance,
            "pixel {i}: {x} against {y}"
        );
        assert!(x.is_finite());
    }
}

/// The plan and the traced image are the same bits on 1 and 3 threads.
#[test]
fn the_choice_is_the_same_bits_on_any_thread_count() {
    let scene = dense_sphere();
    let o = options("dcs", 40, RayChoice::Auto);
    let run = |threads| with_threads(Some(threads), || render(&scene, &o).unwrap()).unwrap();
    let (one, three) = (run(1), run(3));
    assert!(traced(&one) && traced(&three));
    assert_eq!(common::render_bits(&one), common::render_bits(&three));
}
