//! The ray-traced reference: its estimators against closed forms, its
//! convergence, hand-checkable shadows, the BVH against brute force, the
//! watertight triangle test, transmittance, the sampling module's keying
//! and stratification, and thread-count independence.

use crate::common;

use common::{shipped, Rng};
use glam::{Vec2, Vec3};
use penumbra::internal::gbuffer::GSample;
use penumbra::internal::geom::bvh::{intersect_triangle, Bvh};
use penumbra::internal::geom::SceneGeometry;
use penumbra::internal::render::with_threads;
use penumbra::internal::sampling::{light_samples, pixel_key, LightSampler, Strata};
use penumbra::internal::scene::{Light, LightShape, Scene};
use penumbra::internal::shade::{LightSample, PreparedLight, SurfacePoint};
use penumbra::internal::shadow::kit::rays::ShadowTracer;
use penumbra::internal::shadow::reference::Reference;
use penumbra::internal::shadow::{ShadowOutput, ShadowTechnique};
use penumbra::internal::simd::level::Level;
use penumbra::internal::view::View;
use rayon::prelude::*;

// ---------------------------------------------------------------- set-up

/// Loads a scene written to a scratch directory (extra files: name, bytes).
fn scene_from_toml(name: &str, toml: &str, files: &[(&str, &[u8])]) -> Scene {
    common::scene_in_scratch(&format!("reference-{name}"), toml, files)
}

use common::Frame;

fn run(scene: &Scene, frame: &Frame, samples: u32, seed: u64) -> ShadowOutput {
    Reference::new(samples, seed)
        .compute(&frame.ctx(scene))
        .expect("reference runs")
}

fn vcoef(out: &ShadowOutput, light: usize) -> &[f32] {
    out.lights[light].vcoef()
}

fn radiance(out: &ShadowOutput, light: usize) -> &[Vec3] {
    out.lights[light]
        .radiance()
        .expect("reference gives radiance")
}

fn surface_point(scene: &Scene, view: &View, g: &GSample) -> SurfacePoint {
    let m = &scene.materials[g.material as usize];
    SurfacePoint {
        p: g.position,
        n: g.normal,
        ng: g.geo_normal,
        wo: (view.eye.as_vec3() - g.position).normalize_or_zero(),
        albedo: g.albedo,
        specular: m.specular,
        shininess: m.shininess,
    }
}

/// A shading point on the ground (`y = 0`, normal +Y), object `object`.
fn ground_point(p: Vec3, object: u32) -> GSample {
    GSample {
        position: p,
        normal: Vec3::Y,
        geo_normal: Vec3::Y,
        albedo: Vec3::splat(0.8),
        object,
        triangle: 0,
        ..GSample::BACKGROUND
    }
}

const CAMERA_DOWN: &str = r#"
[camera]
eye = [0.0, 6.0, 0.5]
target = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 50.0
width = 32
height = 32
"#;

// ------------------------------------------------------------- sampling

#[test]
fn strata_follow_the_oracle_layout() {
    for (n, a, b) in [
        (1, 1, 1),
        (7, 1, 7),
        (16, 4, 4),
        (60, 6, 10),
        (64, 8, 8),
        (256, 16, 16),
        (4096, 64, 64),
    ] {
        assert_eq!(Strata::new(n), Strata { a, b }, "N = {n}");
    }
    // Every stratum holds exactly one jittered point.
    for n in [1u32, 7, 16, 60, 256, 1000] {
        let strata = Strata::new(n);
        let key = pixel_key(3, 1, (17, 5));
        let mut seen = vec![0u32; n as usize];
        for k in 0..n {
            let (s, t) = strata.point(key, k);
            assert!((0.0..1.0).contains(&s) && (0.0..1.0).contains(&t));
            let i = (s * f64::from(strata.a)).floor() as u32;
            let j = (t * f64::from(strata.b)).floor() as u32;
            assert_eq!((i, j), strata.cell(k), "N = {n}, k = {k}");
            seen[(j * strata.a + i) as usize] += 1;
        }
        assert!(seen.iter().all(|&c| c == 1), "N = {n}: {seen:?}");
    }
}

fn rect_light(center: Vec3, u: Vec3, v: Vec3) -> Light {
    Light {
        shape: LightShape::Rect {
            center,
            u,
            v,
            two_sided: false,
        },
        radiance: Vec3::ONE,
        texture: None,
    }
}

fn sphere_light(center: Vec3, radius: f32) -> Light {
    Light {
        shape: LightShape::Sphere { center, radius },
        radiance: Vec3::ONE,
        texture: None,
    }
}

#[test]
fn samples_are_keyed() {
    let rect = rect_light(Vec3::new(0.0, 4.0, 0.0), Vec3::X * 0.5, Vec3::Z * 0.5);
    let sphere = sphere_light(Vec3::new(0.0, 4.0, 0.0), 0.5);
    for light in [&rect, &sphere] {
        let p = Vec3::new(0.3, 0.0, -0.2);
        let base = light_samples(light, 0, p, (10, 20), 64, 7);
        assert_eq!(base.len(), 64);
        assert_eq!(
            base,
            light_samples(light, 0, p, (10, 20), 64, 7),
            "same key"
        );
        for (what, other) in [
            ("pixel x", light_samples(light, 0, p, (11, 20), 64, 7)),
            ("pixel y", light_samples(light, 0, p, (10, 21), 64, 7)),
            ("swapped pixel", light_samples(light, 0, p, (20, 10), 64, 7)),
            ("light", light_samples(light, 1, p, (10, 20), 64, 7)),
            ("seed", light_samples(light, 0, p, (10, 20), 64, 8)),
        ] {
            let same = base.iter().zip(&other).filter(|(a, b)| a.x == b.x).count();
            assert_eq!(same, 0, "{what}: samples must differ");
        }
        // Sample k does not depend on how many are drawn after it (the
        // stratum layout does, through a × b, but 64 and 64 agree).
        let mut buf = Vec::new();
        LightSampler::new(light).samples_into(0, p, (10, 20), 64, 7, &mut buf);
        assert_eq!(buf, base, "buffer version");
    }
}

#[test]
fn rect_samples_map_st_to_the_light_and_stratify() {
    let (c, u, v) = (
        Vec3::new(1.0, 3.0, -2.0),
        Vec3::new(0.8, 0.0, 0.3),
        Vec3::new(0.0, 0.2, 0.6),
    );
    let light = rect_light(c, u, v);
    let n = 60;
    let strata = Strata::new(n);
    let samples = light_samples(&light, 2, Vec3::ZERO, (3, 4), n, 11);
    let area = 4.0 * u.cross(v).length();
    let mut seen = vec![0; n as usize];
    for s in &samples {
        let (ss, tt) = (s.st.x, s.st.y);
        let x = c + u * (2.0 * ss - 1.0) + v * (1.0 - 2.0 * tt);
        assert!(x.distance(s.x) < 1e-5, "{x} vs {}", s.x);
        assert!((s.inv_pdf_area - area).abs() < 1e-6 * area);
        let i = ((ss * strata.a as f32) as u32).min(strata.a - 1);
        let j = ((tt * strata.b as f32) as u32).min(strata.b - 1);
        seen[(j * strata.a + i) as usize] += 1;
    }
    assert!(seen.iter().all(|&k| k == 1), "{seen:?}");
}

#[test]
fn sphere_samples_lie_on_the_near_cap_inside_the_cone() {
    let (c, r) = (Vec3::new(0.5, 3.0, -1.0), 0.7f32);
    let light = sphere_light(c, r);
    let p = Vec3::new(-0.3, 0.2, 0.4);
    let d = c.distance(p);
    let cos_max = (1.0 - (r / d).powi(2)).sqrt();
    let axis = (c - p) / d;
    for s in light_samples(&light, 0, p, (1, 2), 256, 5) {
        assert!((s.x.distance(c) - r).abs() < 1e-5, "on the sphere");
        let w = (s.x - p).normalize();
        assert!(w.dot(axis) >= cos_max - 1e-5, "inside the cone");
        assert!((s.x - c).dot(p - c) >= -1e-4, "on the near side");
        assert!(s.inv_pdf_area.is_finite() && s.inv_pdf_area >= 0.0);
    }
    // A receiver inside the light has no samples.
    assert!(light_samples(&light, 0, c + Vec3::X * 0.1, (1, 2), 16, 5).is_empty());
}

// ------------------------------------------- (a) estimators vs closed form

/// (a) Unoccluded rect light: the reference radiance against Lambert's
/// closed form, per pixel, in units of the estimator's own standard
/// deviation. With one jittered sample per stratum the estimator's
/// variance is `σ² = (1/N²) Σ_cells Var_cell(f)`, `f` one sample's
/// contribution; each cell's variance is evaluated on an 8 × 8 midpoint
/// grid. Then `z = (est − exact)/σ` must look standard: `mean z²` near 1,
/// no `|z|` beyond 6 (the bound is loose only for cells where `f` is
/// poorly resolved by 8 × 8 points; this integrand is smooth).
#[test]
fn unoccluded_rect_radiance_matches_closed_form() {
    let scene = scene_from_toml(
        "unoccluded",
        &format!(
            r#"{CAMERA_DOWN}
[[light]]
type = "rect"
center = [0.3, 1.5, -0.2]
u = [0.6, 0.0, 0.0]
v = [0.0, 0.0, 0.4]
radiance = [5.0, 4.0, 3.0]

[[object]]
shape = "quad"
size = [4.0, 4.0]
material = {{ albedo = [0.7, 0.6, 0.5] }}
"#
        ),
        &[],
    );
    let frame = Frame::new(&scene, 32, 32);
    let n = 64u32;
    let out = run(&scene, &frame, n, 99);
    let light = &scene.lights[0];
    let prepared = PreparedLight::new(light, &scene.textures);
    let LightShape::Rect { center, u, v, .. } = light.shape else {
        unreachable!()
    };
    let area = 4.0 * u.cross(v).length();
    let strata = Strata::new(n);
    let sub = 8u32;
    let (mut z2, mut zmax, mut count) = (0.0f64, 0.0f64, 0usize);
    for (i, g) in frame.gbuffer.samples().enumerate() {
        if !g.is_surface() {
            continue;
        }
        assert_eq!(vcoef(&out, 0)[i], 1.0, "nothing occludes");
        let sp = surface_point(&scene, &frame.view, &g);
        let exact = prepared.unshadowed_direct(&sp).as_dvec3();
        let est = radiance(&out, 0)[i].as_dvec3();
        // σ² per channel from the within-cell variance of f.
        let mut var = glam::DVec3::ZERO;
        for cell in 0..n {
            let (ci, cj) = strata.cell(cell);
            let (mut s1, mut s2) = (glam::DVec3::ZERO, glam::DVec3::ZERO);
            for q in 0..sub * sub {
                let s = (f64::from(ci) + (f64::from(q % sub) + 0.5) / f64::from(sub))
                    / f64::from(strata.a);
                let t = (f64::from(cj) + (f64::from(q / sub) + 0.5) / f64::from(sub))
                    / f64::from(strata.b);
                let x = center + u * (2.0 * s as f32 - 1.0) + v * (1.0 - 2.0 * t as f32);
                let one = LightSample {
                    x,
                    st: Vec2::new(s as f32, t as f32),
                    inv_pdf_area: area,
                };
                let f = prepared.direct_from_samples(&sp, &[one], &[1.0]).as_dvec3();
                s1 += f;
                s2 += f * f;
            }
            let m = f64::from(sub * sub);
            var += (s2 / m - (s1 / m) * (s1 / m)).max(glam::DVec3::ZERO);
        }
        let sigma = (var / f64::from(n * n)).powf(0.5);
        for c in 0..3 {
            // A floor for pixels where f is (numerically) constant.
            let z = (est[c] - exact[c]) / sigma[c].max(1e-7 * exact[c]).max(1e-12);
            z2 += z * z;
            zmax = zmax.max(z.abs());
            count += 1;
        }
    }
    let mean_z2 = z2 / count as f64;
    eprintln!(
        "unoccluded rect: {count} pixel-channels, mean z² = {mean_z2:.3}, max |z| = {zmax:.2}"
    );
    assert!(count > 1000);
    assert!(mean_z2 < 2.0 && mean_z2 > 0.25, "mean z² = {mean_z2}");
    assert!(zmax < 6.0, "max |z| = {zmax}");
}

/// The sphere light's area pdf (`inv_pdf_area = Ω r² / cos_x`) makes the
/// shared estimator unbiased: against the closed form at N = 1024, per
/// pixel (the per-pixel error falls about as N^-1.2 here: 3 % at 16, 0.5 %
/// at 64, 0.03 % at 1024 for a far pixel) and on average over the image
/// (a wrong pdf factor would show as an O(1) bias).
#[test]
fn unoccluded_sphere_radiance_matches_closed_form() {
    let scene = scene_from_toml(
        "sphere-unoccluded",
        &format!(
            r#"{CAMERA_DOWN}
[[light]]
type = "sphere"
center = [0.4, 1.2, 0.1]
radius = 0.5
radiance = [3.0, 3.0, 3.0]

[[object]]
shape = "quad"
size = [4.0, 4.0]
"#
        ),
        &[],
    );
    let frame = Frame::new(&scene, 32, 32);
    let out = run(&scene, &frame, 1024, 4);
    let prepared = PreparedLight::new(&scene.lights[0], &scene.textures);
    let (mut worst, mut signed, mut count) = (0.0f64, 0.0f64, 0usize);
    for (i, g) in frame.gbuffer.samples().enumerate() {
        if !g.is_surface() {
            continue;
        }
        let exact = f64::from(
            prepared
                .unshadowed_direct(&surface_point(&scene, &frame.view, &g))
                .x,
        );
        let est = f64::from(radiance(&out, 0)[i].x);
        let rel = (est - exact) / exact;
        worst = worst.max(rel.abs());
        signed += rel;
        count += 1;
    }
    let mean = signed / count as f64;
    eprintln!("unoccluded sphere: {count} pixels, max |rel| = {worst:.2e}, mean rel = {mean:.2e}");
    assert!(worst < 2e-3, "max relative error {worst}");
    assert!(mean.abs() < 1e-4, "mean relative error {mean}");
}

// ------------------------------------------------------- (b) convergence

/// (b) Vcoef RMSE against a 16384-sample run on scenes/quad.toml at 64²:
/// the log-log slope over N = 16 … 1024 must be at most −0.45 (1/√N would
/// be −0.5; stratified sampling of a 2D step gives about −0.75).
#[test]
fn vcoef_converges_at_least_as_one_over_sqrt_n() {
    let scene = shipped("quad.toml");
    let frame = Frame::new(&scene, 64, 64);
    let truth = run(&scene, &frame, 16384, 1_000_001);
    let truth = vcoef(&truth, 0);
    let mut points = Vec::new();
    for n in [16u32, 64, 256, 1024] {
        let out = run(&scene, &frame, n, 7);
        let v = vcoef(&out, 0);
        let (mut se, mut count) = (0.0f64, 0usize);
        for (i, g) in frame.gbuffer.samples().enumerate() {
            if g.is_surface() {
                se += (f64::from(v[i]) - f64::from(truth[i])).powi(2);
                count += 1;
            }
        }
        let rmse = (se / count as f64).sqrt();
        eprintln!("quad.toml 64²: N = {n:5}  Vcoef RMSE = {rmse:.5}");
        points.push((f64::from(n).ln(), rmse.ln()));
    }
    let m = points.len() as f64;
    let (sx, sy) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x, b + y));
    let (mx, my) = (sx / m, sy / m);
    let slope = points.iter().map(|(x, y)| (x - mx) * (y - my)).sum::<f64>()
        / points.iter().map(|(x, _)| (x - mx).powi(2)).sum::<f64>();
    for w in points.windows(2) {
        eprintln!(
            "  RMSE ratio per 4× samples: {:.2}",
            (w[0].1 - w[1].1).exp()
        );
    }
    eprintln!("  log-log slope: {slope:.3}");
    assert!(slope <= -0.45, "slope {slope}");
}

// ------------------------------------------------------ (c) hard shadow

/// (c) A 1 × 1 occluder at y = 1 directly below a 0.2 × 0.2 light at
/// y = 4: the ground under the occluder's centre sees none of the light
/// (the rays to the light's corners cross y = 1 within 0.025 of the axis),
/// a point far outside sees all of it, and at x = 2/3 the occluder's edge
/// projects onto the light's centre line, so exactly the half `s < 1/2`
/// is hidden: with an even number of columns that is exactly half the
/// samples.
#[test]
fn hand_checkable_hard_shadow() {
    let scene = scene_from_toml(
        "hard",
        &format!(
            r#"{CAMERA_DOWN}
[[light]]
type = "rect"
center = [0.0, 4.0, 0.0]
u = [0.1, 0.0, 0.0]
v = [0.0, 0.0, 0.1]
radiance = [10.0, 10.0, 10.0]

[[object]]
name = "ground"
shape = "quad"
size = [6.0, 6.0]

[[object]]
name = "occluder"
shape = "quad"
size = [1.0, 1.0]
translate = [0.0, 1.0, 0.0]
"#
        ),
        &[],
    );
    let frame = Frame::new(&scene, 64, 64);
    let out = run(&scene, &frame, 64, 1);
    let ctx = frame.ctx(&scene);
    let hard = penumbra::internal::shadow::reference::hard_visibility(&ctx, 0);
    // The camera sees the occluder's top at the centre: look just beside
    // it, under its edge region, and far away.
    let lit = frame.pixel_near(Vec3::new(2.5, 0.0, 2.5));
    assert_eq!(frame.gbuffer.sample(lit).object, 0);
    assert_eq!(vcoef(&out, 0)[lit], 1.0);
    assert_eq!(hard[lit], 1.0);

    let tracer = ShadowTracer::new(&scene, &frame.geometry);
    let light = &scene.lights[0];
    let mut vis = vec![0.0f32; 64];
    let under = ground_point(Vec3::ZERO, 0);
    let samples = light_samples(light, 0, under.position, (0, 0), 64, 3);
    tracer.sample_visibility(&under, &samples, &mut vis);
    assert!(vis.iter().all(|&v| v == 0.0), "umbra");
    let half = ground_point(Vec3::new(2.0 / 3.0, 0.0, 0.0), 0);
    let samples = light_samples(light, 0, half.position, (0, 0), 64, 3);
    tracer.sample_visibility(&half, &samples, &mut vis);
    for (s, v) in samples.iter().zip(&vis) {
        assert_eq!(*v, if s.st.x < 0.5 { 0.0 } else { 1.0 }, "{s:?}");
    }
    assert_eq!(vis.iter().sum::<f32>(), 32.0);

    // Non-receivers: Vcoef 1, per-sample 1.
    let mut other = under;
    other.object = 1;
    let scene_nr = {
        let mut s = scene.clone();
        s.objects[1].receive_shadows = false;
        s
    };
    let tracer_nr = ShadowTracer::new(&scene_nr, &frame.geometry);
    tracer_nr.sample_visibility(&other, &samples, &mut vis);
    assert!(vis.iter().all(|&v| v == 1.0));
}

// ------------------------------------------------ (d') ray bundles

/// The bunny scene's geometry, a BVH over all of it, and its bounding
/// box's low corner and size (where the bundle tests place rays).
fn bunny_bvh() -> (SceneGeometry, Bvh, Vec3, Vec3) {
    let scene = shipped("bunny.toml");
    let geometry = SceneGeometry::new(&scene);
    let bvh = Bvh::build(&geometry, |_| true);
    let (lo, hi) = geometry
        .positions
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(l, h), p| {
            (l.min(*p), h.max(*p))
        });
    (geometry, bvh, lo, hi - lo)
}

/// Both copies of the dispatched walks (`simd::level`): the baseline and,
/// where this CPU has it, the x86-64-v3 one (on a CPU without it the v3
/// request runs the baseline copy, so the test still passes, testing less:
/// it says so).
const LEVELS: [Level; 2] = [Level::Baseline, Level::V3];

/// No bundle answer differs from its single ray's, and the rays were a
/// useful mix: more than `1/mix` of them occluded and more than `1/mix`
/// clear.
fn assert_bundle_agreement(rays: usize, hits: usize, mix: usize, mismatches: &[String]) {
    if !Level::V3.supported() {
        eprintln!("this CPU lacks x86-64-v3: only the baseline copy was tested");
    }
    eprintln!(
        "{rays} rays, {hits} occluded, {} mismatches",
        mismatches.len()
    );
    assert!(
        hits > rays / mix && hits < rays - rays / mix,
        "a useful mix: {hits} of {rays}"
    );
    assert!(
        mismatches.is_empty(),
        "{}",
        mismatches[..mismatches.len().min(10)].join("\n")
    );
}

/// (d') `occluded_bundle` gives, ray by ray, exactly `occluded`'s answer:
/// bundles of 1–37 rays (partial packets) from random origins toward
/// random points of a rectangle (coherent, like a light's samples), toward
/// the bunny's vertices and edge midpoints (ties: rays through shared
/// edges and vertices), and in random directions; with axis-parallel,
/// zero and NaN directions mixed in and several `t_max`.
#[test]
fn ray_bundles_agree_with_single_rays_bit_for_bit() {
    let (geometry, bvh, lo, size) = bunny_bvh();
    let verts = &geometry.positions;
    let mut rng = Rng(777);
    let (mut rays, mut hits, mut mismatches) = (0usize, 0usize, Vec::new());
    for bundle in 0..3000 {
        let o = lo + Vec3::new(rng.f64() as f32, rng.f64() as f32, rng.f64() as f32) * size * 1.4
            - size * 0.2;
        let n = 1 + (rng.next_u64() % 37) as usize;
        let centre = lo + Vec3::new(rng.f64() as f32, 1.5, rng.f64() as f32) * size;
        let dirs: Vec<Vec3> = (0..n)
            .map(|i| {
                let d = match bundle % 3 {
                    0 => {
                        centre
                            + Vec3::new(rng.f64() as f32 - 0.5, 0.0, rng.f64() as f32 - 0.5)
                                * size.x
                            - o
                    }
                    1 => {
                        let t = &geometry.triangles
                            [(rng.next_u64() % geometry.triangles.len() as u64) as usize];
                        let (a, b) = (verts[t[0] as usize], verts[t[1] as usize]);
                        if i % 2 == 0 {
                            a - o
                        } else {
                            a.lerp(b, 0.5) - o
                        }
                    }
                    _ => Vec3::new(rng.f64() as f32, rng.f64() as f32, rng.f64() as f32) - 0.5,
                };
                match rng.next_u64() % 16 {
                    0 => Vec3::new(0.0, d.y, 0.0),
                    1 => Vec3::new(d.x, 0.0, d.z),
                    2 => Vec3::ZERO,
                    3 => Vec3::new(f32::NAN, d.y, d.z),
                    _ => d,
                }
            })
            .collect();
        let t_max = [1.0 - 1e-6, 2.0, 0.5, 0.0][bundle % 4];
        for level in LEVELS {
            let mut out = vec![true; n];
            bvh.occluded_bundle_at(level, o, &dirs, t_max, &mut out);
            for (i, (&d, &b)) in dirs.iter().zip(&out).enumerate() {
                let single = bvh.occluded(o, d, t_max);
                if level == Level::Baseline {
                    rays += 1;
                    hits += single as usize;
                }
                if single != b {
                    mismatches.push(format!("bundle {bundle} ray {i} at {level:?}: o {o:?} d {d:?} t_max {t_max}: single {single}, bundle {b}"));
                }
            }
        }
    }
    assert_bundle_agreement(rays, hits, 10, &mismatches);
}

/// A shadow-ray origin and a rect light `(center, u, v)` above the bunny
/// (`lo`, `size`: its box): on `surface`, a point of a random triangle
/// offset along its normal by the reference's rule, with that normal as
/// its tangent plane; else a random point around the box.
fn origin_and_light(
    rng: &mut Rng,
    geometry: &SceneGeometry,
    lo: Vec3,
    size: Vec3,
    surface: bool,
) -> (Vec3, Option<Vec3>, Vec3, Vec3, Vec3) {
    let verts = &geometry.positions;
    let mut tangent = None;
    let o = if surface {
        let t = &geometry.triangles[(rng.next_u64() % geometry.triangles.len() as u64) as usize];
        let (p, n) = point_on(rng, t.map(|i| verts[i as usize]));
        tangent = Some(n);
        p + n * shadow_offset(p, size)
    } else {
        lo + Vec3::new(rng.f64() as f32, rng.f64() as f32, rng.f64() as f32) * size * 1.4
            - size * 0.2
    };
    let center = lo + Vec3::new(rng.f64() as f32, 1.2 + rng.f64() as f32, rng.f64() as f32) * size;
    let u = Vec3::new(rng.f64() as f32, 0.0, rng.f64() as f32 * 0.2) * size.x * 0.5;
    let v = Vec3::new(rng.f64() as f32 * 0.2, 0.0, rng.f64() as f32) * size.z * 0.5;
    (o, tangent, center, u, v)
}

/// A uniform random point of triangle `[a, b, c]` and the triangle's unit
/// normal (by its winding).
fn point_on(rng: &mut Rng, [a, b, c]: [Vec3; 3]) -> (Vec3, Vec3) {
    let (u, v) = (rng.f64() as f32, rng.f64() as f32);
    let (u, v) = if u + v > 1.0 {
        (1.0 - u, 1.0 - v)
    } else {
        (u, v)
    };
    let p = a + (b - a) * u + (c - a) * v;
    (p, (b - a).cross(c - a).normalize_or_zero())
}

/// The reference's shadow-ray offset at `p` in a scene of extent `size`.
fn shadow_offset(p: Vec3, size: Vec3) -> f32 {
    (1e-5 * p.abs().max_element()).max(1e-6 * size.length())
}

/// The traced direction from `o` to the point `(s, t)` of the rect light
/// `(center, u, v)`, rounded as the sampler and the reference round it.
fn segment_dir(o: Vec3, (center, u, v): (Vec3, Vec3, Vec3), (s, t): (f64, f64)) -> Vec3 {
    let x = (center.as_dvec3() + u.as_dvec3() * (2.0 * s - 1.0) + v.as_dvec3() * (1.0 - 2.0 * t))
        .as_vec3();
    (x.as_dvec3() - o.as_dvec3()).as_vec3()
}

/// (d'') The per-receiver segment hull ([`Bvh::occluded_hull`]) gives,
/// ray by ray, exactly `occluded`'s answer, for every candidate limit
/// (1: nearly always the rays' own walks; 4: the default; 10⁶: always the
/// candidate leaves): bundles of 1–70 rays from random origins (a third on
/// the bunny's surface or the ground, offset by the reference's rule,
/// where the hull's margins and its exact "behind" rule are tight)
/// toward random points of a random rect light.
#[test]
fn hull_bundles_agree_with_single_rays_bit_for_bit() {
    use penumbra::internal::geom::bvh::SegmentHull;
    let (geometry, bvh, lo, size) = bunny_bvh();
    let mut rng = Rng(4242);
    let mut leaves = Vec::new();
    let (mut rays, mut hits, mut mismatches) = (0usize, 0usize, Vec::new());
    for bundle in 0..3000 {
        let (o, tangent, center, u, v) =
            origin_and_light(&mut rng, &geometry, lo, size, bundle % 3 == 0);
        let n = 1 + (rng.next_u64() % 70) as usize;
        let dirs: Vec<Vec3> = (0..n)
            .map(|_| segment_dir(o, (center, u, v), (rng.f64(), rng.f64())))
            .collect();
        let t_max = (1.0 - 1e-6) as f32;
        // On-surface bundles also get the receiver's tangent plane, as the
        // reference gives it.
        let hull = SegmentHull::new(
            o,
            &dirs,
            Some((center.as_dvec3(), u.as_dvec3(), v.as_dvec3())),
            tangent,
        )
        .expect("usable bundle");
        for limit in [1, 4, 1_000_000] {
            for level in LEVELS {
                let mut out = vec![true; n];
                bvh.occluded_hull_at(level, &hull, &dirs, t_max, &mut out, &mut leaves, limit);
                for (i, (&d, &b)) in dirs.iter().zip(&out).enumerate() {
                    let single = bvh.occluded(o, d, t_max);
                    if limit == 4 && level == Level::Baseline {
                        rays += 1;
                        hits += single as usize;
                    }
                    if single != b {
                        mismatches.push(format!(
                            "bundle {bundle} ray {i} limit {limit} at {level:?}: o {o:?} d {d:?}: single {single}, hull {b}"
                        ));
                    }
                }
            }
        }
    }
    assert_bundle_agreement(rays, hits, 20, &mismatches);
}

/// (d''′) A receiver's hull over the whole light
/// ([`SegmentHull::over_light`]) holds every segment any sampling of that
/// light traces: where it meets no leaf, no ray from the origin to any
/// point of the light is occluded, and where it meets a few, the rays
/// tested against those only ([`Bvh::occluded_leaves`]) get the single
/// rays' answers — corners, edges and random points, computed as the
/// sampler and the reference compute them. Origins as in the test above
/// (a third on the bunny's surface, offset by the reference's rule, with
/// its tangent plane: the receiver's own triangle then lies just behind
/// that plane). All three verdicts (none, a few, too many) must occur.
#[test]
fn light_hull_holds_every_segment() {
    use penumbra::internal::geom::bvh::SegmentHull;
    let (geometry, bvh, lo, size) = bunny_bvh();
    let mut rng = Rng(777);
    let mut leaves = Vec::new();
    let (mut clear, mut few, mut many, mut rays, mut hits) = (0usize, 0usize, 0usize, 0, 0);
    let mut wrong = Vec::new();
    for trial in 0..4000 {
        let (o, tangent, center, u, v) =
            origin_and_light(&mut rng, &geometry, lo, size, trial % 3 == 0);
        let rect = (center.as_dvec3(), u.as_dvec3(), v.as_dvec3());
        let Some(hull) = SegmentHull::over_light(o, rect, tangent) else {
            continue;
        };
        if !bvh.hull_leaves(&hull, &mut leaves, 4) {
            many += 1;
            continue;
        }
        if leaves.is_empty() {
            clear += 1;
        } else {
            few += 1;
        }
        let mut points: Vec<(f64, f64)> = (0..64).map(|_| (rng.f64(), rng.f64())).collect();
        points.extend(
            [0.0, 0.5, 1.0]
                .iter()
                .flat_map(|&s| [0.0, 0.5, 1.0].map(|t| (s, t))),
        );
        let dirs: Vec<Vec3> = points
            .iter()
            .map(|&st| segment_dir(o, (center, u, v), st))
            .collect();
        let t_max = (1.0 - 1e-6) as f32;
        let mut out = vec![true; dirs.len()];
        bvh.occluded_leaves(o, &dirs, t_max, &mut out, &mut leaves);
        for (i, (&d, &b)) in dirs.iter().zip(&out).enumerate() {
            let single = bvh.occluded(o, d, t_max);
            rays += 1;
            hits += usize::from(single);
            if single != b {
                wrong.push(format!(
                    "trial {trial} ray {i}: o {o:?} light {rect:?}: single {single}, leaves {b}"
                ));
            }
        }
    }
    assert!(wrong.is_empty(), "the light's hull lost a hit: {wrong:#?}");
    assert!(
        clear >= 200 && few >= 100 && many >= 200,
        "every verdict must occur: {clear} clear, {few} few, {many} too many"
    );
    assert!(rays > 10_000 && hits > 500, "{rays} rays, {hits} hit");
}

/// (d''') The reference's images do not depend on the segment hull: the
/// same bits with it off, at the default limit and always on, on shipped
/// scenes with rect lights and non-opaque casters, and on spheres.toml
/// with its light made a sphere (the hull is then the segments' box).
#[test]
fn hull_limit_changes_no_bit_of_the_reference() {
    let mut sphere_lit = shipped("spheres.toml");
    if let LightShape::Rect { center, .. } = sphere_lit.lights[0].shape {
        sphere_lit.lights[0].shape = LightShape::Sphere {
            center,
            radius: 1.0,
        };
    }
    let scenes = ["spheres.toml", "bunny.toml", "fence.toml", "tinted.toml"]
        .map(shipped)
        .into_iter()
        .chain([sphere_lit]);
    for scene in scenes {
        let frame = Frame::new(&scene, 61, 47);
        let ctx = frame.ctx(&scene);
        let image = |limit: usize| {
            let tracer = ShadowTracer::new(&scene, &frame.geometry).with_hull_limit(limit);
            (0..scene.lights.len())
                .flat_map(|k| {
                    let (term, _) = tracer.trace_light(&ctx, k, 32, 9);
                    let v: Vec<u32> = term.vcoef().iter().map(|x| x.to_bits()).collect();
                    v
                })
                .collect::<Vec<_>>()
        };
        let off = image(0);
        let name = &scene.name;
        assert!(off.iter().any(|&b| b != 0), "{name}: empty image");
        assert!(
            off.iter().any(|&b| b != 0 && b != 1f32.to_bits()),
            "{name}: no penumbra"
        );
        for limit in [4, 1_000_000] {
            assert!(
                image(limit) == off,
                "{name}: limit {limit} changes the image"
            );
        }
    }
}

// ------------------------------------------------ (d) BVH vs brute force

/// (d) `occluded` and `for_each_hit` agree with a brute-force loop over all
/// triangles (same watertight test) on 100k random segments against the
/// bunny, 10 % of them axis-parallel.
#[test]
fn bvh_agrees_with_brute_force_on_the_bunny() {
    let scene = shipped("bunny.toml");
    let geometry = SceneGeometry::new(&scene);
    let bunny = 1u32;
    let keep = |t: u32| geometry.triangle_object[t as usize] == bunny;
    let bvh = Bvh::build(&geometry, keep);
    let tris: Vec<(u32, [Vec3; 3])> = (0..geometry.triangles.len() as u32)
        .filter(|&t| keep(t))
        .map(|t| {
            (
                t,
                geometry.triangles[t as usize].map(|i| geometry.positions[i as usize]),
            )
        })
        .collect();
    assert_eq!(bvh.triangle_count(), tris.len());
    // Triangle boxes, to skip most of the brute-force tests cheaply (a hit
    // point lies in both the triangle's and the segment's box).
    let boxes: Vec<(Vec3, Vec3)> = tris
        .iter()
        .map(|(_, [a, b, c])| (a.min(*b).min(*c), a.max(*b).max(*c)))
        .collect();
    let (lo, hi) = boxes
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(l, h), (a, b)| {
            (l.min(*a), h.max(*b))
        });
    let size = hi - lo;
    let mut rng = Rng(12345);
    let point = |rng: &mut Rng, grow: f32| {
        let c = (lo + hi) * 0.5;
        c + (Vec3::new(rng.f64() as f32, rng.f64() as f32, rng.f64() as f32) - 0.5) * size * grow
    };
    let rays: Vec<(Vec3, Vec3, f32)> = (0..100_000)
        .map(|i| {
            let o = point(&mut rng, 1.6);
            let mut d = point(&mut rng, 0.9) - o;
            if i % 10 == 0 {
                let axis = (rng.next_u64() % 3) as usize;
                let len = d[axis];
                d = Vec3::ZERO;
                d[axis] = if len == 0.0 { 1.0 } else { len };
            }
            let t_max = (0.2 + 1.3 * rng.f64()) as f32;
            (o, d, t_max)
        })
        .collect();
    let mismatches: Vec<String> = rays
        .par_iter()
        .enumerate()
        .filter_map(|(i, &(o, d, t_max))| {
            let end = o + d * t_max;
            let (slo, shi) = (o.min(end) - 1e-4, o.max(end) + 1e-4);
            let mut brute: Vec<u32> = tris
                .iter()
                .zip(&boxes)
                .filter(|(_, (bl, bh))| bl.cmple(shi).all() && bh.cmpge(slo).all())
                .filter(|((_, tri), _)| intersect_triangle(o, d, t_max, tri).is_some())
                .map(|((t, _), _)| *t)
                .collect();
            let mut walked = Vec::new();
            bvh.for_each_hit(o, d, t_max, |h| walked.push(h.triangle));
            brute.sort_unstable();
            walked.sort_unstable();
            let occluded = bvh.occluded(o, d, t_max);
            (occluded == brute.is_empty() || walked != brute)
                .then(|| format!("ray {i}: occluded {occluded}, brute {brute:?}, bvh {walked:?}"))
        })
        .collect();
    let hits = rays
        .iter()
        .filter(|(o, d, t)| bvh.occluded(*o, *d, *t))
        .count();
    eprintln!(
        "bunny: {} triangles, 100000 rays, {hits} hit, {} mismatches",
        tris.len(),
        mismatches.len()
    );
    assert!(
        hits > 10_000 && hits < 90_000,
        "a useful mix of hits and misses: {hits}"
    );
    assert!(
        mismatches.is_empty(),
        "{:?}",
        &mismatches[..mismatches.len().min(5)]
    );
}

/// The watertight test against an independent f64 Möller–Trumbore on
/// random rays and triangles: they must agree wherever the hit is not
/// within rounding of an edge or of the segment's ends (the f64 test
/// reports nothing behind the origin; those cases must miss too).
#[test]
fn watertight_test_agrees_with_f64_moller_trumbore() {
    let mut rng = Rng(77);
    let v =
        |rng: &mut Rng| Vec3::new(rng.f64() as f32, rng.f64() as f32, rng.f64() as f32) * 4.0 - 2.0;
    let (mut checked, mut hits) = (0, 0);
    for _ in 0..200_000 {
        let tri = [v(&mut rng), v(&mut rng), v(&mut rng)];
        let o = v(&mut rng) * 2.0;
        let d = v(&mut rng) - o;
        let t_max = 1.0f32;
        let ours = intersect_triangle(o, d, t_max, &tri);
        let reference = penumbra::internal::geom::TriangleFrame::new(tri.map(|p| p.as_dvec3()))
            .hit(o.as_dvec3(), d.as_dvec3());
        let Some((t, b1, b2)) = reference else {
            // Parallel in f64 or behind the origin: ours must miss too.
            assert!(ours.is_none());
            continue;
        };
        let b0 = 1.0 - b1 - b2;
        let margin = 1e-5;
        let clearly_in =
            b0 > margin && b1 > margin && b2 > margin && t > margin && t < 1.0 - margin;
        let clearly_out =
            b0 < -margin || b1 < -margin || b2 < -margin || t < -margin || t > 1.0 + margin;
        if clearly_in {
            let (ot, ob1, ob2) = ours.expect("hit");
            assert!(
                (f64::from(ot) - t).abs() < 1e-4
                    && (f64::from(ob1) - b1).abs() < 1e-4
                    && (f64::from(ob2) - b2).abs() < 1e-4
            );
            hits += 1;
        } else if clearly_out {
            assert!(ours.is_none());
        } else {
            continue;
        }
        checked += 1;
    }
    assert!(
        checked > 150_000 && hits > 1000,
        "{checked} checked, {hits} hits"
    );
}

// ------------------------------------------------------ (e) watertight

/// (e) Rays from outside aimed at the vertices and at points on the shared
/// edges of closed UV spheres (the built-in sphere, welded) always hit. A target is used from an origin
/// only where every triangle around it faces that origin clearly (same
/// side, |cos| > 0.05): at a silhouette the ray only grazes the mesh, and
/// a target rounded a hair outside it may rightly miss. Axis-parallel rays
/// through the vertices themselves are exact (only one coordinate of the
/// direction is non-zero and the ray passes exactly through the vertex, so
/// the edge functions there are exactly 0 and the tie rule decides); they
/// are used at every vertex, silhouettes included.
#[test]
fn rays_through_shared_edges_and_vertices_always_hit() {
    let scene = scene_from_toml(
        "watertight",
        &format!(
            r#"{CAMERA_DOWN}
[[light]]
type = "rect"
center = [0.0, 6.0, 0.0]
u = [0.5, 0.0, 0.0]
v = [0.0, 0.0, 0.5]
radiance = [1.0, 1.0, 1.0]

[[object]]
shape = "sphere"
radius = 1.0
segments = 20
rings = 20

[[object]]
shape = "sphere"
radius = 0.37
segments = 48
rings = 31
translate = [3.3, 1.7, -0.2]
rotate = [10.0, 20.0, 30.0]
"#
        ),
        &[],
    );
    // Positions welded to 1e-5: the UV sphere repeats its seam column and
    // pole vertices under new indices, and the seam copies are not exact
    // (sin 2π ≠ 0 in floating point leaves a crack about 1e-16 wide that a
    // ray can slip through). Welding makes the meshes exactly closed, which
    // is what watertightness is about.
    let key = |p: Vec3| (p * 1e5).round().to_array().map(|x| x as i64);
    let mut geometry = SceneGeometry::new(&scene);
    let mut canonical: std::collections::HashMap<[i64; 3], Vec3> = Default::default();
    for p in &mut geometry.positions {
        *p = *canonical.entry(key(*p)).or_insert(*p);
    }
    let geometry = geometry;
    let pos = |i: u32| geometry.positions[i as usize];
    let mut rng = Rng(2024);
    let (mut rays, mut exact, mut misses) = (0usize, 0usize, Vec::new());
    for object in 0..2u32 {
        let bvh = Bvh::build(&geometry, |t| {
            geometry.triangle_object[t as usize] == object
        });
        let tris: Vec<[Vec3; 3]> = (0..geometry.triangles.len())
            .filter(|&t| geometry.triangle_object[t] == object)
            .map(|t| geometry.triangles[t].map(pos))
            .collect();
        // Triangles around each vertex position (the seam and the poles
        // repeat positions under different indices).
        let mut around: std::collections::HashMap<[i64; 3], Vec<usize>> = Default::default();
        for (t, tri) in tris.iter().enumerate() {
            for p in tri {
                around.entry(key(*p)).or_default().push(t);
            }
        }
        let centre =
            tris.iter().flatten().fold(Vec3::ZERO, |a, p| a + *p) / (3 * tris.len()) as f32;
        let radius = tris[0][0].distance(centre);
        // Targets with the triangles around them.
        let mut targets: Vec<(Vec3, Vec<usize>, bool)> = Vec::new();
        for tri in &tris {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                targets.push((a, around[&key(a)].clone(), true));
                let shared: Vec<usize> = around[&key(a)]
                    .iter()
                    .copied()
                    .filter(|t| around[&key(b)].contains(t))
                    .collect();
                assert_eq!(shared.len(), 2, "closed mesh: two triangles per edge");
                targets.push((a.lerp(b, 0.5), shared.clone(), false));
                targets.push((a.lerp(b, rng.f64() as f32), shared, false));
            }
        }
        let transversal = |o: Vec3, ts: &[usize]| {
            let cos: Vec<f32> = ts
                .iter()
                .map(|&t| {
                    let [a, b, c] = tris[t];
                    (b - a).cross(c - a).normalize().dot((o - a).normalize())
                })
                .collect();
            cos.iter().all(|&c| c > 0.05) || cos.iter().all(|&c| c < -0.05)
        };
        let mut aim = |o: Vec3, target: Vec3| {
            rays += 1;
            // t_max 2: well beyond the target on the segment.
            if !bvh.occluded(o, target - o, 2.0) {
                misses.push((object, o, target));
            }
        };
        for (target, ts, is_vertex) in &targets {
            for _ in 0..2 {
                let dir = Vec3::new(
                    rng.f64() as f32 - 0.5,
                    rng.f64() as f32 - 0.5,
                    rng.f64() as f32 - 0.5,
                )
                .normalize_or(Vec3::X);
                let o = centre + dir * radius * 3.0;
                if transversal(o, ts) {
                    aim(o, *target);
                }
            }
            // Axis-parallel rays from outside through the target: only the
            // axis coordinate of the origin differs from the target's.
            for k in 0..3 {
                let side = if target[k] >= centre[k] { 1.0 } else { -1.0 };
                let mut o = *target;
                o[k] += side * radius * 3.0;
                if *is_vertex {
                    exact += 1;
                    aim(o, *target);
                } else if transversal(o, ts) {
                    aim(o, *target);
                }
            }
        }
    }
    eprintln!(
        "watertight: {rays} rays ({exact} exact axis-parallel through vertices), {} misses",
        misses.len()
    );
    assert!(rays > 20_000);
    assert!(misses.is_empty(), "{:?}", &misses[..misses.len().min(5)]);
}

// ---------------------------------------------------- (f) transmittance

fn stack_scene(name: &str, opacity: f32) -> Scene {
    let mut toml = format!(
        r#"{CAMERA_DOWN}
[[light]]
type = "rect"
center = [0.0, 3.0, 0.0]
u = [0.5, 0.0, 0.0]
v = [0.0, 0.0, 0.5]
radiance = [1.0, 1.0, 1.0]

[[object]]
shape = "quad"
size = [4.0, 4.0]
"#
    );
    for k in 0..100 {
        toml += &format!(
            "\n[[object]]\nshape = \"quad\"\nsize = [1.0, 1.0]\ntranslate = [0.0, {}, 0.0]\nmaterial = {{ opacity = {opacity:e} }}\n",
            1.0 + 0.01 * k as f32
        );
    }
    scene_from_toml(name, &toml, &[])
}

/// (f) A stack of 100 quads: opacity 0.5 gives `T = 2⁻¹⁰⁰` and opacity
/// 1e-7 gives `1 − T = 1 − (1 − 1e-7)¹⁰⁰`, both to relative 1e-4, through
/// the quads' interiors and exactly through their shared diagonal (where
/// both triangles report the crossing and it must count once).
#[test]
fn transmittance_of_a_stack_of_quads() {
    for (opacity, name) in [(0.5f32, "stack-half"), (1e-7, "stack-faint")] {
        let scene = stack_scene(name, opacity);
        let geometry = SceneGeometry::new(&scene);
        let tracer = ShadowTracer::new(&scene, &geometry);
        assert_eq!(tracer.translucent_bvh().triangle_count(), 200);
        let per_layer = 1.0 - f64::from(opacity);
        let expected = per_layer.powi(100);
        for (x, z) in [(0.2f32, -0.1f32), (0.0, 0.0), (0.25, 0.25), (-0.3, -0.3)] {
            let o = Vec3::new(x, 0.5, z);
            let t = tracer.transmittance(o, Vec3::new(0.0, 2.0, 0.0), 1.0);
            let (got, want) = if opacity < 0.1 {
                (1.0 - t, 1.0 - expected)
            } else {
                (t, expected)
            };
            assert!(
                ((got - want) / want).abs() < 1e-4,
                "opacity {opacity} at ({x}, {z}): {got:e} vs {want:e}"
            );
            // One layer.
            let one = tracer.transmittance(o, Vec3::new(0.0, 0.505, 0.0), 1.0);
            let (got, want) = if opacity < 0.1 {
                (1.0 - one, f64::from(opacity))
            } else {
                (one, per_layer)
            };
            assert!(
                ((got - want) / want).abs() < 1e-4,
                "one layer: {got:e} vs {want:e}"
            );
        }
        // Through the reference: a ground point under the stack.
        let g = ground_point(Vec3::new(0.1, 0.0, 0.1), 0);
        let samples = [LightSample {
            x: Vec3::new(0.1, 3.0, 0.1),
            st: Vec2::splat(0.5),
            inv_pdf_area: 1.0,
        }];
        let mut vis = [0.0f32];
        tracer.sample_visibility(&g, &samples, &mut vis);
        // f32 cannot hold 1 − 1e-5 to 1e-4 relative of its deficit; the
        // f64 walk above checks that.
        let tolerance = if opacity < 0.1 { 1e-6 } else { 1e-4 * expected };
        assert!(
            (f64::from(vis[0]) - expected).abs() < tolerance,
            "{} vs {expected:e}",
            vis[0]
        );
    }
}

/// An opacity texture: a 2 × 1 RGBA texture whose left texel is clear and
/// right texel opaque, on a quad (u runs along +x): segments through
/// x < 0 pass, through x > 0 are blocked.
#[test]
fn opacity_texture_is_looked_up_at_the_hit() {
    let mut png = Vec::new();
    let img = image::RgbaImage::from_raw(2, 1, vec![255, 255, 255, 0, 255, 255, 255, 255])
        .expect("2×1 image");
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .expect("encode png");
    let scene = scene_from_toml(
        "alpha",
        &format!(
            r#"{CAMERA_DOWN}
[[light]]
type = "rect"
center = [0.0, 3.0, 0.0]
u = [0.5, 0.0, 0.0]
v = [0.0, 0.0, 0.5]
radiance = [1.0, 1.0, 1.0]

[[object]]
shape = "quad"
size = [2.0, 2.0]
translate = [0.0, 1.0, 0.0]
material = {{ opacity_texture = "alpha.png" }}
"#
        ),
        &[("alpha.png", &png[..])],
    );
    let geometry = SceneGeometry::new(&scene);
    let tracer = ShadowTracer::new(&scene, &geometry);
    let up = Vec3::new(0.0, 2.0, 0.0);
    for z in [-0.7f32, -0.2, 0.0, 0.3, 0.8] {
        assert_eq!(tracer.transmittance(Vec3::new(-0.5, 0.0, z), up, 1.0), 1.0);
        assert_eq!(tracer.transmittance(Vec3::new(0.5, 0.0, z), up, 1.0), 0.0);
    }
}

// ------------------------------------------------- (g) sphere light

/// (g) A sphere light and nothing between it and the ground: Vcoef is
/// exactly 1 on every surface pixel.
#[test]
fn sphere_light_vcoef_without_occluder_is_exactly_one() {
    let scene = scene_from_toml(
        "sphere-free",
        &format!(
            r#"{CAMERA_DOWN}
[[light]]
type = "sphere"
center = [0.5, 2.0, -0.5]
radius = 0.6
radiance = [2.0, 2.0, 2.0]

[[object]]
shape = "quad"
size = [4.0, 4.0]
"#
        ),
        &[],
    );
    let frame = Frame::new(&scene, 48, 48);
    let out = run(&scene, &frame, 64, 3);
    let mut surface = 0;
    for (i, g) in frame.gbuffer.samples().enumerate() {
        if g.is_surface() {
            surface += 1;
            assert_eq!(vcoef(&out, 0)[i], 1.0, "pixel {i}");
            assert!(radiance(&out, 0)[i].x > 0.0);
        }
    }
    assert!(surface > 1000);
}

// -------------------------------------------------- (h) determinism

fn bits(out: &ShadowOutput) -> Vec<u32> {
    out.lights
        .iter()
        .flat_map(|l| {
            let v = l.vcoef().iter().map(|x| x.to_bits());
            let r = l
                .radiance()
                .into_iter()
                .flatten()
                .flat_map(|c| c.to_array().map(f32::to_bits));
            v.chain(r).collect::<Vec<_>>()
        })
        .collect()
}

/// (h) Same output, bit for bit, for 1 and 2 threads: the image (spheres
/// and a non-opaque stack) and the BVH itself (bunny: large enough for the
/// parallel build to split).
#[test]
fn same_bits_for_one_and_two_threads() {
    for scene in [shipped("spheres.toml"), stack_scene("det-stack", 0.3)] {
        let frame = Frame::new(&scene, 67, 53);
        let go = |threads| {
            with_threads(Some(threads), || bits(&run(&scene, &frame, 16, 42))).expect("pool")
        };
        let one = go(1);
        assert!(one.iter().any(|&b| b != 0));
        assert!(go(2) == one, "{}: 2 threads differ from 1", scene.name);
    }
    let bunny = shipped("bunny.toml");
    let geometry = SceneGeometry::new(&bunny);
    let build =
        |threads| with_threads(Some(threads), || Bvh::build(&geometry, |_| true)).expect("pool");
    let one = build(1);
    assert!(one.node_count() > 1000);
    assert!(build(2) == one, "BVH differs between 1 and 2 threads");
}

/// The technique plugs into the renderer by name, and rejects N = 0.
#[test]
fn technique_is_wired_into_the_renderer() {
    use penumbra::internal::render::Technique;
    assert_eq!(
        "reference".parse::<Technique>().ok(),
        Some(Technique::named("reference").unwrap())
    );
    assert!(penumbra::internal::shadow::registry::names().contains(&"reference"));
    let scene = shipped("quad.toml");
    let frame = Frame::new(&scene, 8, 8);
    let none = Reference::new(0, 0).compute(&frame.ctx(&scene));
    assert!(none.is_err());
    let out = run(&scene, &frame, 4, 0);
    let names: Vec<&str> = out.passes.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names[0], "reference bvh");
    assert!(names[1].starts_with("reference light 0 ("), "{names:?}");
}

/// The reference traces a receiver's samples in packets of 4 × 2
/// neighbouring strata, not in sample order: each sample's value in the
/// bundle is still that sample's own, traced alone, on penumbra pixels of
/// spheres.toml at 64 and 256 samples (and 48, which keeps sample order).
#[test]
fn bundle_order_keeps_each_sample_its_own_value() {
    let scene = shipped("spheres.toml");
    let frame = Frame::new(&scene, 40, 30);
    let tracer = ShadowTracer::new(&scene, &frame.geometry);
    let light = &scene.lights[0];
    let (mut lit, mut dark, mut checked) = (0usize, 0usize, 0usize);
    for n in [64u32, 256, 48] {
        for (i, g) in frame.gbuffer.samples().enumerate().step_by(5) {
            if !g.is_surface() {
                continue;
            }
            let pixel = ((i % 40) as u32, (i / 40) as u32);
            let samples = light_samples(light, 0, g.position, pixel, n, 11);
            let mut bundle = vec![0.0f32; samples.len()];
            tracer.sample_visibility(&g, &samples, &mut bundle);
            let (l, d) = (
                bundle.iter().filter(|&&v| v == 1.0).count(),
                bundle.iter().filter(|&&v| v == 0.0).count(),
            );
            if l == 0 || d == 0 {
                continue; // not in a penumbra: the order cannot show
            }
            for (k, s) in samples.iter().enumerate() {
                let mut alone = [0.0f32];
                tracer.sample_visibility(&g, std::slice::from_ref(s), &mut alone);
                assert_eq!(bundle[k], alone[0], "n {n} pixel {pixel:?} sample {k}");
            }
            lit += l;
            dark += d;
            checked += 1;
        }
    }
    assert!(
        checked >= 10 && lit > 100 && dark > 100,
        "{checked} receivers, {lit} lit, {dark} dark"
    );
}

/// `Strata::block_order` is a permutation of the samples whose runs of
/// `w h` are `w × h` blocks of neighbouring strata, and sample order when
/// the block does not divide the grid.
#[test]
fn strata_block_order_is_a_permutation_of_compact_blocks() {
    let mut order = Vec::new();
    for (n, w, h) in [
        (64u32, 4u32, 2u32),
        (256, 4, 2),
        (256, 2, 4),
        (48, 4, 2),
        (7, 4, 2),
    ] {
        let strata = Strata::new(n);
        strata.block_order(w, h, &mut order);
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..n).collect::<Vec<_>>(), "n {n}");
        if !strata.a.is_multiple_of(w) || !strata.b.is_multiple_of(h) {
            assert_eq!(order, sorted, "n {n}: sample order");
            continue;
        }
        for block in order.chunks(w as usize * h as usize) {
            let cells: Vec<_> = block.iter().map(|&k| strata.cell(k)).collect();
            let (i0, j0) = cells[0];
            assert!(
                cells.iter().all(|&(i, j)| i - i0 < w && j - j0 < h),
                "n {n}: {cells:?}"
            );
        }
    }
}

/// (d'''') The receiver's tangent plane culls the ground it lies on even
/// where its rays run more along the ground than away from it (the light
/// low and far to the side, so the rays' dominant axis is not the
/// ground's normal and the exact "behind" rule cannot drop it): the
/// ground is bigger than the general margin allows for, but its corners
/// lie behind the plane by the shadow-ray offset, far beyond the
/// watertight test's rounding (`TANGENT_MARGIN`). Receivers on
/// `bunny.toml`'s ground, offset by the reference's rule, in a tree of
/// the ground alone: the light's hull finds no leaf, and no ray from such
/// a receiver to the light hits the ground.
#[test]
fn tangent_plane_culls_the_receivers_ground() {
    use penumbra::internal::geom::bvh::SegmentHull;
    let (geometry, _, lo, size) = bunny_bvh();
    let ground: Vec<u32> = (0..geometry.triangles.len() as u32)
        .filter(|&t| geometry.triangle_object[t as usize] == 0)
        .collect();
    assert_eq!(ground.len(), 2, "bunny.toml's ground is one quad");
    let bvh = Bvh::build(&geometry, |t| geometry.triangle_object[t as usize] == 0);
    let verts = &geometry.positions;
    let mut rng = Rng(31337);
    let mut leaves = Vec::new();
    let mut sideways = 0usize;
    for trial in 0..2000 {
        let t = &geometry.triangles[ground[trial % 2] as usize];
        let (p, n) = point_on(&mut rng, t.map(|i| verts[i as usize]));
        let n = if n.y < 0.0 { -n } else { n };
        let o = p + n * shadow_offset(p, size);
        // Low and far to the side: rays closer to the ground than to its
        // normal for most receivers.
        let side = if trial % 2 == 0 { 1.0 } else { -1.0 };
        let center = Vec3::new(
            side * (0.6 + 0.3 * rng.f64() as f32) * size.x,
            lo.y + (0.05 + 0.3 * rng.f64() as f32) * size.y,
            lo.z + rng.f64() as f32 * size.z,
        );
        let (lu, lv) = (
            Vec3::new(0.0, 0.05, 0.0) * size.y,
            Vec3::new(0.0, 0.0, 0.1) * size.z,
        );
        let rect = (center.as_dvec3(), lu.as_dvec3(), lv.as_dvec3());
        let hull = SegmentHull::over_light(o, rect, Some(n)).expect("usable hull");
        assert!(bvh.hull_leaves(&hull, &mut leaves, 1_000_000));
        let dirs: Vec<Vec3> = (0..16)
            .map(|_| segment_dir(o, (center, lu, lv), (rng.f64(), rng.f64())))
            .collect();
        sideways += usize::from(dirs.iter().all(|d| d.x.abs() > d.y.abs().max(d.z.abs())));
        for d in &dirs {
            assert!(
                !bvh.occluded(o, *d, (1.0 - 1e-6) as f32),
                "trial {trial}: a ray hit the ground"
            );
        }
        assert!(
            leaves.is_empty(),
            "trial {trial}: the hull kept the receiver's own ground (o {o:?}, light {rect:?})"
        );
    }
    assert!(
        sideways > 1000,
        "most bundles must run along the ground: {sideways} of 2000"
    );
}
