//! Soft shadow maps (Atty et al. 2006): the closed form on an aligned
//! planar occluder, convergence to the hard shadow map, the f16 failure of
//! eq. 4 and its batched fix, degenerate depths, determinism.

use crate::common;

use glam::DVec3;
use penumbra::internal::render::{render, RenderOptions};
use penumbra::internal::scene::Scene;
use penumbra::internal::shadow::soft_shadow_map::SsmLight;
use penumbra::internal::shadow::{Technique, TechniqueOptions};

fn vcoef(scene: &Scene, name: &str, size: u32, f: impl Fn(&mut RenderOptions)) -> Vec<f32> {
    let mut options = RenderOptions {
        width: Some(size),
        height: Some(size),
        technique: Technique::named(name).unwrap(),
        samples: 256,
        ..RenderOptions::default()
    };
    f(&mut options);
    let out = render(scene, &options).expect("render");
    out.lights[0].vcoef().to_vec()
}

/// Builds light 0's soft shadow map of `scene`.
fn build(scene: &Scene, f: impl Fn(&mut TechniqueOptions)) -> SsmLight {
    use penumbra::internal::shadow::kit::light_view::{caster_bounds, receiver_bounds};
    let mut o = TechniqueOptions::default();
    f(&mut o);
    let geometry = penumbra::internal::geom::SceneGeometry::new(scene);
    penumbra::internal::shadow::soft_shadow_map::build_light(
        scene,
        &geometry,
        0,
        &o.ssm,
        &o.shadow_map,
        caster_bounds(scene).unwrap(),
        receiver_bounds(scene).unwrap(),
    )
    .unwrap()
    .unwrap()
}

/// The gather at a texel's centre and receiver depth is the texel's SSM
/// value, bit for bit (same patches, order and arithmetic).
#[test]
fn a_gather_at_a_texel_centre_is_the_texel() {
    let scene = common::shipped("spheres.toml");
    for acc in ["f32", "f16", "f16-batched"] {
        let ssm = build(&scene, |o| {
            o.shadow_map.map_size = 128;
            o.ssm.ssm_accumulate = clap::ValueEnum::from_str(acc, false).unwrap();
        });
        let (w, h) = (ssm.params.width, ssm.params.height);
        let mut checked = 0;
        for y in (0..h).step_by(3) {
            for x in (0..w).step_by(3) {
                let k = y * w + x;
                let z = ssm.receivers[k];
                if !z.is_finite() {
                    continue;
                }
                let test = z - z * ssm.params.bias;
                let g = ssm.gather((x as f64 + 0.5, y as f64 + 0.5), z, test);
                assert_eq!(
                    g.to_bits(),
                    ssm.ssm[k].to_bits(),
                    "{acc} texel ({x}, {y}): gather {g} vs {}",
                    ssm.ssm[k]
                );
                checked += (g > 0.0) as usize;
            }
        }
        assert!(checked > 100, "{checked}");
    }
}

/// The quad scene split as the paper splits it (the ground only receives,
/// the occluder only casts), with the occluder at height `y` and the
/// light's half-size `h`.
fn split_quad(name: &str, y: f32, h: f32) -> Scene {
    common::scene_in_scratch(name, &split_quad_text(y, h), &[])
}

/// The text of [`split_quad`]'s scene.
fn split_quad_text(y: f32, h: f32) -> String {
    std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/quad.toml"))
        .unwrap()
        .replace("u = [0.5, 0.0, 0.0]", &format!("u = [{h}, 0.0, 0.0]"))
        .replace("v = [0.0, 0.0, 0.5]", &format!("v = [0.0, 0.0, {h}]"))
        .replace(
            "size = [6.0, 6.0]",
            "size = [6.0, 6.0]\ncast_shadows = false",
        )
        .replace(
            "translate = [0.0, 1.0, 0.0]",
            &format!("translate = [0.0, {y}, 0.0]\nreceive_shadows = false"),
        )
}

/// World point of SSM texel `(x, y)`'s receiver.
fn receiver_point(ssm: &SsmLight, x: usize, y: usize) -> DVec3 {
    let z = ssm.receivers[y * ssm.params.width + x] as f64;
    let v = &ssm.view;
    v.eye + v.primary_ray_unnormalized(x as u32, y as u32) * z
}

/// The fraction of the light `c ± u ± v` (u ⊥ v) hidden from `r` by the
/// rectangle `corners` (parallel to the light): the corners projected from
/// `r` onto the light's plane, as an axis-aligned box in (u, v), overlapped
/// with the light. Exact in f64.
fn rect_overlap(r: DVec3, corners: &[DVec3; 4], c: DVec3, u: DVec3, v: DVec3) -> f64 {
    let n = u.cross(v).normalize();
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for &q in corners {
        let t = (c - r).dot(n) / (q - r).dot(n);
        let p = r + (q - r) * t - c;
        let st = [p.dot(u) / u.length_squared(), p.dot(v) / v.length_squared()];
        for a in 0..2 {
            lo[a] = lo[a].min(st[a]);
            hi[a] = hi[a].max(st[a]);
        }
    }
    let w = |a: usize| ((hi[a].min(1.0) - lo[a].max(-1.0)) / 2.0).max(0.0);
    w(0) * w(1)
}

/// A planar occluder parallel to the light whose edges are texel edges:
/// the micro-patches tile it exactly (no gap, no overlap: eq. 3 with
/// `dh = 0`), so every SSM texel is the closed-form overlap of the
/// occluder's back-projection with the light.
#[test]
fn an_aligned_planar_occluder_gives_the_closed_form_overlap() {
    let scene = split_quad("ssm-closed-form", 1.0, 0.5);
    let penumbra::internal::scene::LightShape::Rect { center, u, v, .. } = scene.lights[0].shape
    else {
        unreachable!()
    };
    let (c, u, v) = (center.as_dvec3(), u.as_dvec3(), v.as_dvec3());
    for size in [16u32, 40] {
        let ssm = build(&scene, |o| o.shadow_map.map_size = size);
        // The casters' window is the occluder's projection: every texel of
        // the occluder map is a patch, and their union is the window at
        // the occluder's depth (the quad itself up to the window's 1e-6
        // padding).
        assert_eq!(ssm.passes[0].len(), (size * size) as usize);
        let z_o = ssm.passes[0].depth[0] as f64;
        assert!(ssm.passes[0]
            .depth
            .iter()
            .all(|&z| (z as f64 - 3.0).abs() < 1e-6));
        let view = &ssm.view;
        let (ex, ey) = (ssm.margin.0 as f64, ssm.margin.1 as f64);
        let (dx, dy) = (
            (view.window.right - view.window.left) / view.width as f64,
            (view.window.top - view.window.bottom) / view.height as f64,
        );
        let (l, r) = (view.window.left + ex * dx, view.window.right - ex * dx);
        let (b, t) = (view.window.bottom + ey * dy, view.window.top - ey * dy);
        let corner =
            |x: f64, y: f64| view.eye + (view.forward + view.right * x + view.up * y) * z_o;
        let window = [corner(l, b), corner(r, b), corner(r, t), corner(l, t)];
        let quad = [
            DVec3::new(-0.5, 1.0, -0.5),
            DVec3::new(0.5, 1.0, -0.5),
            DVec3::new(0.5, 1.0, 0.5),
            DVec3::new(-0.5, 1.0, 0.5),
        ];
        let (mut worst, mut worst_quad, mut penumbra) = (0.0f64, 0.0f64, 0);
        for y in 0..ssm.params.height {
            for x in 0..ssm.params.width {
                let p = receiver_point(&ssm, x, y);
                assert!((p.y).abs() < 1e-5, "the receiver is the ground: {p}");
                let got = ssm.ssm[y * ssm.params.width + x] as f64;
                let exact = rect_overlap(p, &window, c, u, v);
                worst = worst.max((got - exact).abs());
                worst_quad = worst_quad.max((got - rect_overlap(p, &quad, c, u, v)).abs());
                penumbra += (exact > 0.01 && exact < 0.99) as usize;
            }
        }
        assert!(penumbra > 50, "the test needs a penumbra: {penumbra}");
        assert!(
            worst <= 1e-6,
            "{size}²: |SSM − closed form| up to {worst:e}"
        );
        assert!(
            worst_quad <= 1e-4,
            "{size}²: against the quad itself {worst_quad:e}"
        );
    }
}

/// Eq. 3 (§4.1.2) on a tilted plane: two neighbouring micro-patches at
/// depths `z_O` and `z_O + dh` back-project from a receiver at `z_R` onto
/// intervals of the light that should meet at the image of their shared
/// edge; they overlap on one side of the point `P0` behind that edge and
/// leave a gap on the other, by at most `(L/2) z_R dh / (z_O (z_R − z_O −
/// dh))` (as a fraction of the light's width `L`: that over `L`). Measured
/// on the rasterized patches of a quad tilted about the light's `v` axis,
/// for every x-neighbour pair and every receiver texel of its row; the
/// bound holds, both signs occur, and the bound is nearly reached (the
/// clipped error peaks at `bound / α`, `α = 1 + bound·2 ≈ 1`, where the
/// deeper patch's edge image reaches the light's rim).
#[test]
fn neighbouring_patches_overlap_or_gap_within_eq_3() {
    for deg in [10.0f32, 35.0] {
        let text = split_quad_text(1.5, 0.5).replace(
            "translate = [0.0, 1.5, 0.0]",
            &format!("rotate = [0.0, 0.0, {deg}]\ntranslate = [0.0, 1.5, 0.0]"),
        );
        let scene = common::scene_in_scratch(&format!("ssm-eq3-{deg}"), &text, &[]);
        let ssm = build(&scene, |o| o.shadow_map.map_size = 48);
        let (p, prm) = (&ssm.passes[0], &ssm.params);
        let ax = prm.ax as f64;
        let (mut pairs, mut overlaps, mut gaps, mut best) = (0usize, 0usize, 0usize, 0.0f64);
        for y in 0..prm.height {
            let row = p.row_range(y, 0, prm.width as i64);
            for i in row.start..row.end.saturating_sub(1) {
                if p.x[i + 1] != p.x[i] + 1 {
                    continue;
                }
                let (z1, z2) = (p.depth[i] as f64, p.depth[i + 1] as f64);
                let (z_o, dh) = (z1.min(z2), (z1 - z2).abs());
                if dh == 0.0 {
                    continue;
                }
                pairs += 1;
                for rx in 0..prm.width {
                    let z_r = ssm.receivers[y * prm.width + rx] as f64;
                    if !(z_r.is_finite() && z_r > z_o + dh) {
                        continue;
                    }
                    // Normalised light coordinates of the shared edge's
                    // image through each patch: b of the left patch, a of
                    // the right one (m = receiver − left patch, texels).
                    let m = rx as f64 - p.x[i] as f64;
                    let g = |z: f64| ax * z * z_r / (z_r - z);
                    let b_left = 0.5 - (m - 0.5) * g(z1);
                    let a_right = 0.5 - (m - 0.5) * g(z2);
                    let sat = |v: f64| v.clamp(0.0, 1.0);
                    let signed = sat(b_left) - sat(a_right);
                    let bound = z_r * dh / (2.0 * z_o * (z_r - z_o - dh));
                    assert!(
                        signed.abs() <= bound * (1.0 + 1e-9),
                        "{deg}°: pair {i}, receiver {rx}: |{signed}| > eq. 3 {bound}"
                    );
                    overlaps += (signed > 1e-9) as usize;
                    gaps += (signed < -1e-9) as usize;
                    best = best.max(signed.abs() / bound);
                }
            }
        }
        assert!(pairs > 500, "{deg}°: {pairs} pairs");
        assert!(
            overlaps > 1000 && gaps > 1000,
            "{deg}°: {overlaps} overlaps, {gaps} gaps"
        );
        assert!(best > 0.9, "{deg}°: eq. 3 reached only to {best}");
    }
}

/// With a light of size → 0 every patch's back-projection covers the light
/// or misses it: the SSM is the hard shadow map's test, and the render is
/// `--technique shadow-map`'s up to the outline's pixels.
#[test]
fn a_vanishing_light_converges_to_the_hard_shadow_map() {
    let toml = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/quad.toml"))
        .unwrap()
        .replace("u = [0.5, 0.0, 0.0]", "u = [0.0005, 0.0, 0.0]")
        .replace("v = [0.0, 0.0, 0.5]", "v = [0.0, 0.0, 0.0005]");
    let scene = common::scene_in_scratch("ssm-tiny", &toml, &[]);
    let set = |o: &mut RenderOptions| o.options.shadow_map.map_size = 512;
    let hard = vcoef(&scene, "shadow-map", 96, set);
    for lookup in ["nearest", "bilinear"] {
        let soft = vcoef(&scene, "soft-shadow-map", 96, |o| {
            set(o);
            o.options.ssm.ssm_lookup = clap::ValueEnum::from_str(lookup, false).unwrap();
        });
        let shadowed = hard.iter().filter(|&&v| v < 0.5).count();
        assert!(shadowed > 300, "the test needs a shadow: {shadowed}");
        let differ = soft
            .iter()
            .zip(&hard)
            .filter(|(a, b)| (**a - **b).abs() > 0.5)
            .count();
        assert!(
            differ <= 8,
            "{lookup}: {differ} pixels differ from the hard map"
        );
        let mean: f32 = soft
            .iter()
            .zip(&hard)
            .map(|(a, b)| (a - b).abs())
            .sum::<f32>()
            / soft.len() as f32;
        assert!(mean < 2e-3, "{lookup}: mean |Δ| {mean}");
    }
}

/// Appendix A: fp16 blending stalls once a patch's occlusion is below half
/// an ulp of the running sum. Eq. 4 says this happens when a patch's
/// back-projection is narrower than 1/32 of the light, i.e. when
/// `n = 2h (1/z_O − 1/z_R) / Δ` (patches across the light) exceeds 32; the
/// `⌊√M⌋` batches fix it.
#[test]
fn f16_fails_where_eq_4_says_and_batches_fix_it() {
    // A light three times the occluder's width: n = 0.75 × map size, and
    // the umbra's centre sees the light wholly hidden.
    let scene = split_quad("ssm-f16", 1.0, 1.5);
    let umbra = |size: u32, acc: &str| {
        let ssm = build(&scene, |o| {
            o.shadow_map.map_size = size;
            o.ssm.ssm_accumulate = clap::ValueEnum::from_str(acc, false).unwrap();
        });
        let (w, h) = (ssm.params.width, ssm.params.height);
        let centre = (h / 2) * w + w / 2;
        let (z_r, z_o) = (ssm.receivers[centre] as f64, ssm.passes[0].depth[0] as f64);
        // n = (2h / Δ)(1/z_O − 1/z_R) = (1/ax)(1/z_O − 1/z_R).
        let n = (1.0 / z_o - 1.0 / z_r) / ssm.params.ax as f64;
        (ssm.ssm[centre], n)
    };
    let (f32_small, n_small) = umbra(24, "f32");
    let (f16_small, _) = umbra(24, "f16");
    let (f32_large, n_large) = umbra(171, "f32");
    let (f16_large, _) = umbra(171, "f16");
    let (batched_large, _) = umbra(171, "f16-batched");
    assert!(n_small < 32.0 && n_large > 100.0, "n {n_small} {n_large}");
    // f32: n² terms of 1/n² each, rounding errors of 2^-24 each at most.
    assert!((f32_small - 1.0).abs() < 1e-5 && (f32_large - 1.0).abs() < 1e-4);
    // Below eq. 4's threshold every add moves the sum, each off by at
    // most half an ulp (2^-12 below 1): a few percent, no stall.
    assert!(
        (f16_small - 1.0).abs() < 0.03,
        "f16 at n = {n_small}: {f16_small}"
    );
    assert!(
        f16_large < 0.6,
        "f16 at n = {n_large} should stall: {f16_large}"
    );
    assert!(
        (batched_large - 1.0).abs() < 5e-3,
        "batched: {batched_large}"
    );
}

/// An occluder touching the receiver (eq. 3's overlap bound diverges as
/// `1/(z_R − z_O − dh)`) or touching the light (`1/z_O`): no NaN, values in
/// [0, 1], and the contact is in shadow.
#[test]
fn occluders_touching_the_receiver_or_the_light_give_no_nan() {
    for (name, y) in [
        ("ssm-touch-receiver", 0.0005f32),
        ("ssm-touch-light", 3.9995),
    ] {
        let scene = split_quad(name, y, 0.5);
        for acc in ["f32", "f16", "f16-batched"] {
            for passes in [1u8, 2] {
                let v = vcoef(&scene, "soft-shadow-map", 48, |o| {
                    o.options.shadow_map.map_size = 64;
                    o.options.ssm.ssm_accumulate = clap::ValueEnum::from_str(acc, false).unwrap();
                    o.options.ssm.ssm_passes = passes;
                });
                assert!(
                    v.iter().all(|x| x.is_finite() && (0.0..=1.0).contains(x)),
                    "{name} {acc} {passes}"
                );
                if y < 1.0 {
                    // Under the occluder lying on the ground: dark.
                    assert!(v.iter().filter(|&&x| x < 0.05).count() > 50, "{name} {acc}");
                }
            }
        }
    }
    // Self-shadowing on the shipped scenes touches receivers everywhere
    // (every caster is its own receiver): still finite.
    let bunny = common::shipped("bunny.toml");
    let v = vcoef(&bunny, "soft-shadow-map", 48, |o| {
        o.options.shadow_map.map_size = 128;
        o.options.ssm.ssm_passes = 2;
    });
    assert!(v.iter().all(|x| x.is_finite() && (0.0..=1.0).contains(x)));
}

/// What we do where eq. 3 diverges, against the reference. Touching the
/// receiver (`G` capped): the hard contact shadow, which is the reference
/// there. Near the light (0.05 below it, the quad's edge at tangent 10
/// from the centre): still held to the reference. Touching it (5e-4
/// below): the quad's edges are at tangent 1000 from the light's centre,
/// beyond what one view from the centre holds (`MAX_TAN` = 16), so the
/// occluder map holds only its middle and the margin is capped: the SSM
/// says it is incomplete (`--explain`: INCOMPLETE) and most of the shadow
/// is lost, never a NaN.
#[test]
fn touching_the_receiver_or_the_light_against_the_reference() {
    for (name, y, complete, tolerance) in [
        ("ssm-ref-touch-receiver", 0.0005f32, true, 0.01f32),
        ("ssm-ref-near-light", 3.95, true, 0.02),
        ("ssm-ref-touch-light", 3.9995, false, f32::INFINITY),
    ] {
        let scene = split_quad(name, y, 0.5);
        let ssm = build(&scene, |o| o.shadow_map.map_size = 64);
        assert_eq!(ssm.complete, complete, "{name}");
        let set = |o: &mut RenderOptions| o.options.shadow_map.map_size = 64;
        let soft = vcoef(&scene, "soft-shadow-map", 48, set);
        let reference = vcoef(&scene, "reference", 48, |_| {});
        assert!(soft
            .iter()
            .all(|v| v.is_finite() && (0.0..=1.0).contains(v)));
        let mean = soft
            .iter()
            .zip(&reference)
            .map(|(a, b)| (a - b).abs())
            .sum::<f32>()
            / soft.len() as f32;
        let dark = reference.iter().filter(|&&v| v < 0.05).count();
        assert!(dark > 300, "{name}: the test needs a shadow ({dark})");
        assert!(mean <= tolerance, "{name}: mean |Δ| {mean}");
        if !complete {
            // The failure, stated: the reference is dark everywhere.
            assert!(
                mean > 0.3,
                "{name}: mean |Δ| {mean} (fixed? update the docs)"
            );
        }
    }
}

/// Same bits for 1 and 2 threads, every accumulation, both passes.
#[test]
fn the_same_bits_for_any_thread_count() {
    use penumbra::internal::render::with_threads;
    let scene = common::shipped("spheres.toml");
    for acc in ["f32", "f16-batched"] {
        let run = |threads| {
            with_threads(Some(threads), || {
                vcoef(&scene, "soft-shadow-map", 64, |o| {
                    o.options.shadow_map.map_size = 200;
                    o.options.ssm.ssm_passes = 2;
                    o.options.ssm.ssm_accumulate = clap::ValueEnum::from_str(acc, false).unwrap();
                })
            })
            .expect("pool")
        };
        let one: Vec<u32> = run(1).iter().map(|v| v.to_bits()).collect();
        let two: Vec<u32> = run(2).iter().map(|v| v.to_bits()).collect();
        assert!(
            one.iter().any(|&b| f32::from_bits(b) < 0.5),
            "{acc}: no shadow"
        );
        assert_eq!(one, two, "{acc}");
    }
}

/// Sphere lights are refused with the reason, naming the parameter.
#[test]
fn sphere_lights_are_refused() {
    let toml = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/quad.toml"))
        .unwrap()
        .replace(
            "type = \"rect\"\ncenter = [0.0, 4.0, 0.0]\nu = [0.5, 0.0, 0.0]\nv = [0.0, 0.0, 0.5]",
            "type = \"sphere\"\ncenter = [0.0, 4.0, 0.0]\nradius = 0.3",
        );
    let scene = common::scene_in_scratch("ssm-sphere", &toml, &[]);
    let options = RenderOptions {
        width: Some(16),
        height: Some(16),
        technique: Technique::named("soft-shadow-map").unwrap(),
        ..RenderOptions::default()
    };
    let e = render(&scene, &options).expect_err("refused");
    let msg = e.to_string();
    assert!(
        msg.contains("--technique") && msg.contains("rectangle"),
        "{msg}"
    );
}
