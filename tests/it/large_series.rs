//! Exactness on the scaling benchmark's large scenes, downsized to CI's
//! budget: the shipped spheres scene with every sphere tessellated as the
//! benchmark's 1M-triangle point (`scripts/scaling.py`, 80 segments × 80
//! rings: 1,023,842 triangles), rendered at 48² with 16 samples. Both of
//! DCS's paths are held to the shadow rays: counting (`--dcs-rays never`)
//! by the exactness certificate over every (pixel, sample) relation, the
//! default (which traces this light) by the reference's Vcoef bit for bit,
//! and the two against each other but at ties.

use crate::common;
use crate::common::{first_light_traced as traced, first_light_vcoef as vcoef};
use penumbra::internal::render::{render, verify_render};
use penumbra::internal::shadow::dcs::RayChoice;
use penumbra::internal::shadow::kit::verify::{EVERY_RELATION, TIE_DISTANCE};

const SIDE: u32 = 48;
/// The samples of `common::dcs_rays_options` (held to it in the test).
const SAMPLES: u32 = 16;

/// The benchmark's tessellation-series scene at `segments` (segments =
/// rings), made as the script makes it: the shipped scene's `segments`
/// and `rings` lines rewritten.
fn tessellated(segments: u32) -> penumbra::internal::scene::Scene {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/spheres.toml");
    let text = std::fs::read_to_string(path).expect("shipped spheres scene");
    let mut spheres = 0;
    let out: Vec<String> = text
        .lines()
        .map(|line| {
            if line.starts_with("segments = ") {
                spheres += 1;
                format!("segments = {segments}")
            } else if line.starts_with("rings = ") {
                format!("rings = {segments}")
            } else {
                line.to_string()
            }
        })
        .collect();
    assert_eq!(spheres, 81, "the shipped scene's 9 × 9 spheres");
    common::scene_in_scratch(&format!("large-series-{segments}"), &out.join("\n"), &[])
}

#[test]
fn the_million_triangle_point_is_exact_by_both_paths() {
    let scene = tessellated(80);
    let triangles: usize = scene.objects.iter().map(|o| o.mesh.triangles.len()).sum();
    assert_eq!(triangles, 1_023_842, "the benchmark's count");

    // Counting, certified over every relation.
    let never = common::dcs_rays_options("dcs", SIDE, RayChoice::Never);
    assert_eq!(never.samples, SAMPLES);
    let report = verify_render(&scene, &never, EVERY_RELATION).expect("verify runs");
    eprintln!("{report}");
    assert!(report.declared_exact, "{report:?}");
    assert!(
        report.blocked > report.checked / 20 && report.blocked < report.checked * 19 / 20,
        "real shadow in view: {report:?}"
    );
    assert_eq!(report.beyond_tie, 0, "{report:?}");
    assert!(report.max_tie_distance <= TIE_DISTANCE, "{report:?}");

    // The default traces this light (1M triangles at 48²): the
    // reference's Vcoef, bit for bit.
    let auto = render(
        &scene,
        &common::dcs_rays_options("dcs", SIDE, RayChoice::Auto),
    )
    .unwrap();
    let reference = render(
        &scene,
        &common::dcs_rays_options("reference", SIDE, RayChoice::Auto),
    )
    .unwrap();
    assert!(traced(&auto), "{:?}", auto.passes);
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(vcoef(&auto)), bits(vcoef(&reference)));
    assert!(auto.radiance.iter().all(|c| c.is_finite()));

    // Counting against the rays: a pixel differs only by tied samples
    // (certified above), at most one of 16, on few pixels.
    let counted = render(&scene, &never).unwrap();
    assert!(!traced(&counted));
    let differing: Vec<f32> = vcoef(&auto)
        .iter()
        .zip(vcoef(&counted))
        .map(|(x, y)| (x - y).abs())
        .filter(|&d| d > 0.0)
        .collect();
    assert!(
        differing.len() <= vcoef(&auto).len() / 100,
        "{} pixels differ",
        differing.len()
    );
    assert!(
        differing.iter().all(|&d| d <= 1.0 / SAMPLES as f32 + 1e-6),
        "{differing:?}"
    );
}
