//! Penumbra casting's translucent pass against the reference's per-sample
//! products, relation by relation, at the reference's own samples
//! (`interleaved:2`, whose four sets the default `--pc-sample-sets 0`
//! picks): semi-opaque casters within 1e-9 relative of the reference's
//! `Π (1 − α)`, S-triangles (the alpha matte) equal to it except at ties —
//! the segment within [`TIE`] (relative to its length) of a caster edge,
//! or its crossing within [`TEXEL_TIE`] texels of a texel boundary.

use crate::common;

use glam::{DVec3, Vec3};
use penumbra::internal::sampling::SamplePattern;
use penumbra::internal::scene::Scene;
use penumbra::internal::shadow::kit::rays::{
    scene_diagonal, ShadowTracer, END_SHORTEN, MERGE_SCENE,
};
use penumbra::internal::shadow::kit::stsv::{Filter, STriangle, STriangles};
use penumbra::internal::shadow::penumbra_casting::samples::SampleKey;
use penumbra::internal::shadow::penumbra_casting::{
    LightMasks, PenumbraCasting, PenumbraCastingOptions,
};
use penumbra::internal::shadow::ShadowTechnique;
use std::collections::HashMap;

/// An edge tie, relative to the segment's length.
const TIE: f64 = 1e-4;
/// A texel tie: the crossing this close (in texels) to a texel boundary.
const TEXEL_TIE: f64 = 1e-3;

fn technique(n: u32, filter: Filter) -> PenumbraCasting {
    PenumbraCasting {
        samples: n,
        seed: 7,
        pattern: SamplePattern::Interleaved { n: 2 },
        options: PenumbraCastingOptions {
            pc_chunk: 32,
            opacity_filter: filter,
            ..PenumbraCastingOptions::default()
        },
    }
}

/// Every shadow-casting triangle's edges.
fn edges(scene: &Scene, frame: &common::Frame) -> Vec<(DVec3, DVec3)> {
    let g = &frame.geometry;
    let mut out = Vec::new();
    for (t, tri) in g.triangles.iter().enumerate() {
        if !scene.objects[g.triangle_object[t] as usize].cast_shadows {
            continue;
        }
        for e in 0..3 {
            out.push((
                g.positions[tri[e] as usize].as_dvec3(),
                g.positions[tri[(e + 1) % 3] as usize].as_dvec3(),
            ));
        }
    }
    out
}

/// The reference's walk (rays.rs `walk`: every crossing, sorted by
/// `(t, triangle)`, crossings closer than `MERGE_SCENE × D` once) with
/// the S-triangles read through `filter`, and the smallest distance in
/// texels of an S-triangle crossing to a texel boundary.
struct Walk<'a> {
    scene: &'a Scene,
    tracer: ShadowTracer<'a>,
    mattes: HashMap<u32, STriangle>,
    merge: f64,
}

impl<'a> Walk<'a> {
    fn new(scene: &'a Scene, frame: &'a common::Frame) -> Walk<'a> {
        let mattes = STriangles::collect(scene, &frame.geometry)
            .list
            .into_iter()
            .map(|s| (s.triangle, s))
            .collect();
        Walk {
            scene,
            tracer: ShadowTracer::new(scene, &frame.geometry),
            mattes,
            merge: MERGE_SCENE * scene_diagonal(scene, &frame.geometry),
        }
    }

    fn vt(&self, o: Vec3, x: Vec3, filter: Filter) -> (f64, f64) {
        let dir = (x.as_dvec3() - o.as_dvec3()).as_vec3();
        let t_max = (1.0 - END_SHORTEN) as f32;
        if self.tracer.opaque_bvh().occluded(o, dir, t_max) {
            return (0.0, f64::INFINITY);
        }
        let mut hits = Vec::new();
        self.tracer
            .translucent_bvh()
            .for_each_hit(o, dir, t_max, |h| hits.push(h));
        hits.sort_unstable_by(|a, b| a.t.total_cmp(&b.t).then(a.triangle.cmp(&b.triangle)));
        let merge_t = self.merge / f64::from(dir.length());
        let (mut t, mut next, mut texel) = (1.0f64, f64::NEG_INFINITY, f64::INFINITY);
        for h in &hits {
            if f64::from(h.t) < next {
                continue;
            }
            let a = match self.mattes.get(&h.triangle) {
                Some(s) => {
                    // Nearest jumps at texel boundaries; bilinear is
                    // continuous (no texel ties).
                    if filter == Filter::Nearest {
                        let uv = s.uv_at(h.b1, h.b2);
                        let tex = &self.scene.textures[s.texture];
                        for c in [
                            f64::from(uv.x) * f64::from(tex.width),
                            (1.0 - f64::from(uv.y)) * f64::from(tex.height),
                        ] {
                            texel = texel.min((c - c.round()).abs());
                        }
                    }
                    f64::from(s.opacity_at(self.scene, h.b1, h.b2, filter))
                }
                None => self.tracer.opacity(h),
            };
            t *= 1.0 - a;
            next = f64::from(h.t) + merge_t;
        }
        (t, texel)
    }
}

#[derive(Debug, Default)]
struct Agreement {
    relations: usize,
    partial: usize,
    zero: usize,
    mismatches: usize,
    worst_tie: f64,
    worst_rel: f64,
}

/// Every relation of `masks` against the reference's walk; a relation
/// agrees when within `rel` relative (0 only with 0).
fn compare(
    scene: &Scene,
    frame: &common::Frame,
    masks: &LightMasks,
    filter: Filter,
    rel: f64,
) -> Agreement {
    let walk = Walk::new(scene, frame);
    let edges = edges(scene, frame);
    let sets = &masks.sets;
    assert!(sets.matches_reference(), "the reference's own samples");
    assert_eq!(masks.transmittance.len(), frame.gbuffer.len() * sets.n);
    let mut a = Agreement::default();
    let w = frame.gbuffer.width;
    let mut samples = Vec::new();
    for (i, set) in masks.set.iter().enumerate() {
        let Some(set) = set else { continue };
        let set = *set as usize;
        let g = frame.gbuffer.sample(i);
        let o = walk.tracer.shadow_origin(g.position, g.geo_normal);
        let key = SampleKey {
            position: g.position,
            pixel: (i as u32 % w, i as u32 / w),
        };
        let samples = sets.samples_for(set, key, &mut samples);
        for (slot, &k) in sets.order[set].iter().enumerate() {
            let x = samples[k as usize].x;
            let ours = masks.transmittance[i * sets.n + slot];
            let (truth, texel) = walk.vt(o, x, filter);
            if filter == Filter::Nearest {
                // The test's walk is the reference's, bit for bit.
                assert_eq!(truth, walk.tracer.segment(o, x).0, "pixel {i} slot {slot}");
            }
            a.relations += 1;
            a.partial += usize::from(truth > 0.0 && truth < 1.0);
            a.zero += usize::from(truth == 0.0);
            let err = (ours - truth).abs();
            if err <= rel * truth || err == 0.0 {
                if truth > 0.0 {
                    a.worst_rel = a.worst_rel.max(err / truth);
                }
                continue;
            }
            a.mismatches += 1;
            if texel < TEXEL_TIE {
                continue;
            }
            let (p0, p1) = (o.as_dvec3(), x.as_dvec3());
            let len = (p1 - p0).length();
            let d = edges
                .iter()
                .map(|&(q0, q1)| common::segment_distance(p0, p1, q0, q1))
                .fold(f64::INFINITY, f64::min)
                / len;
            assert!(
                d <= TIE,
                "pixel {i} slot {slot}: ours {ours} reference {truth}, {d} from an edge, \
                 {texel} texels from a boundary"
            );
            a.worst_tie = a.worst_tie.max(d);
        }
    }
    eprintln!("{a:?}");
    a
}

fn assert_agree(name: &str, a: &Agreement, partial: usize) {
    assert!(a.partial >= partial, "{name}: {a:?}");
    let agree = 1.0 - a.mismatches as f64 / a.relations.max(1) as f64;
    assert!(agree >= 0.9999, "{name}: {a:?}");
}

#[test]
fn tinted_transmittance_is_the_references_product() {
    let scene = common::shipped("tinted.toml");
    let frame = common::Frame::new(&scene, 48, 36);
    let ctx = frame.ctx(&scene);
    let masks = technique(32, Filter::Nearest)
        .light_masks(&ctx, 0)
        .expect("penumbra casting runs");
    let r = &masks.report.translucent;
    assert!(r.layers > 100 && r.mattes == 0, "{r:?}");
    let a = compare(&scene, &frame, &masks, Filter::Nearest, 1e-9);
    assert_agree("tinted", &a, 2000);
    assert!(a.zero > 300, "{a:?}");
}

/// Under a sphere light (each receiver's own samples, made again by the
/// translucent pass): semi-opaque layers and the alpha matte are the
/// reference's products.
#[test]
fn sphere_light_translucent_casters_are_the_references_product() {
    for (name, radius, partial) in [("tinted.toml", 0.5, 2000), ("fence.toml", 0.4, 0)] {
        let scene = common::with_sphere_light(common::shipped(name), radius);
        let frame = common::Frame::new(&scene, 48, 36);
        let ctx = frame.ctx(&scene);
        let masks = technique(48, Filter::Nearest)
            .light_masks(&ctx, 0)
            .expect("penumbra casting runs");
        let r = &masks.report.translucent;
        assert!(r.layers > 100 || r.mattes > 0, "{name}: {r:?}");
        let a = compare(&scene, &frame, &masks, Filter::Nearest, 1e-9);
        assert_agree(name, &a, partial);
        assert!(a.zero > 300, "{name}: {a:?}");
    }
}

/// Stacked layers of 0.5, a layer of 1e-6 and one of 0.999999, an opaque
/// box between.
fn stacked() -> Scene {
    let mut toml = String::from(
        r#"
[scene]
name = "stacked"
[camera]
eye = [0.0, 6.0, 5.0]
target = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 45.0
width = 64
height = 64
[[light]]
type = "rect"
center = [0.0, 4.0, 0.0]
u = [0.6, 0.0, 0.0]
v = [0.0, 0.0, 0.6]
radiance = [6.0, 6.0, 6.0]
[[object]]
shape = "quad"
size = [7.0, 7.0]
[[object]]
shape = "box"
size = [0.4, 0.4, 0.4]
translate = [0.0, 0.2, -1.0]
"#,
    );
    for (x, y, z, a) in [
        (-1.0, 1.0, 0.0, 0.5),
        (-0.9, 1.3, 0.1, 0.5),
        (-0.8, 1.6, 0.2, 0.5),
        (-1.1, 1.9, -0.1, 0.5),
        (1.0, 1.2, 0.0, 1e-6),
        (0.3, 1.5, 1.0, 0.999999),
        (0.5, 0.8, 0.9, 0.5),
    ] {
        toml += &format!(
            "[[object]]\nshape = \"quad\"\nsize = [1.2, 1.2]\ntranslate = [{x}, {y}, {z}]\n\
             material = {{ opacity = {a} }}\n"
        );
    }
    common::scene_in_scratch("pc-stacked", &toml, &[])
}

#[test]
fn stacked_faint_and_dense_layers_are_the_references_product() {
    let scene = stacked();
    let frame = common::Frame::new(&scene, 64, 48);
    let ctx = frame.ctx(&scene);
    for n in [32, 80] {
        let masks = technique(n, Filter::Nearest)
            .light_masks(&ctx, 0)
            .expect("penumbra casting runs");
        let a = compare(&scene, &frame, &masks, Filter::Nearest, 1e-9);
        assert_agree("stacked", &a, 3000);
        // Four 0.5 layers, the faint and the dense layer are all there.
        let has = |v: f64| {
            masks
                .transmittance
                .iter()
                .any(|&t| (t - v).abs() <= 1e-12 * v)
        };
        for v in [
            0.0625,
            1.0 - f64::from(1e-6f32),
            1.0 - f64::from(0.999999f32),
        ] {
            assert!(has(v), "no relation with T = {v}");
        }
    }
}

#[test]
fn vcoef_and_radiance_follow_the_reference_with_translucent_casters() {
    use penumbra::internal::shadow::reference::Reference;
    let scene = common::shipped("tinted.toml");
    let frame = common::Frame::new(&scene, 48, 36);
    let ctx = frame.ctx(&scene);
    let ours = technique(32, Filter::Nearest)
        .compute(&ctx)
        .expect("penumbra casting runs");
    let reference = Reference {
        samples: 32,
        seed: 7,
        pattern: SamplePattern::Interleaved { n: 2 },
    }
    .compute(&ctx)
    .expect("reference runs");
    let (va, vb) = (ours.lights[0].vcoef(), reference.lights[0].vcoef());
    let (ra, rb) = (
        ours.lights[0].radiance().expect("radiance"),
        reference.lights[0].radiance().expect("radiance"),
    );
    let (mut differ, mut partial) = (0, 0);
    for i in 0..va.len() {
        partial += usize::from(vb[i] > 0.0 && vb[i] < 1.0);
        let close = (va[i] - vb[i]).abs() <= 1e-6 && (ra[i] - rb[i]).abs().max_element() <= 1e-5;
        differ += usize::from(!close);
    }
    eprintln!("{differ} of {} pixels differ, {partial} partial", va.len());
    assert!(partial > va.len() / 10, "{partial}");
    assert!(differ * 1000 <= va.len(), "{differ} pixels differ");
}

#[test]
fn fence_alpha_matte_is_the_references_product() {
    let scene = common::shipped("fence.toml");
    let frame = common::Frame::new(&scene, 48, 36);
    let ctx = frame.ctx(&scene);
    let masks = technique(32, Filter::Nearest)
        .light_masks(&ctx, 0)
        .expect("penumbra casting runs");
    assert!(masks.report.translucent.mattes > 0);
    let a = compare(&scene, &frame, &masks, Filter::Nearest, 1e-9);
    // Binary alpha: every relation 0 or 1.
    assert!(a.zero > 1000 && a.relations - a.zero > 1000, "{a:?}");
    assert_agree("fence", &a, 0);
}

/// A quad with a graded 8 × 8 opacity texture (0.1 to 0.9) over the
/// ground, beside an opaque one.
fn graded() -> Scene {
    let texels: Vec<u8> = (0..64)
        .map(|i| (25.0 + 200.0 * ((i % 8) as f64 + (i / 8) as f64) / 14.0) as u8)
        .collect();
    let mut png = Vec::new();
    image::GrayImage::from_raw(8, 8, texels)
        .expect("8×8 image")
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .expect("png encodes");
    let toml = r#"
[scene]
name = "graded"
[camera]
eye = [0.0, 6.0, 5.0]
target = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 45.0
width = 64
height = 64
[[light]]
type = "rect"
center = [0.0, 4.0, 0.0]
u = [0.5, 0.0, 0.0]
v = [0.0, 0.0, 0.5]
radiance = [6.0, 6.0, 6.0]
[[object]]
shape = "quad"
size = [6.0, 6.0]
[[object]]
shape = "quad"
size = [2.0, 2.0]
translate = [-0.3, 1.2, 0.0]
material = { opacity_texture = "graded.png" }
[[object]]
shape = "quad"
size = [0.5, 0.5]
translate = [0.6, 0.8, 0.4]
"#;
    common::scene_in_scratch("pc-graded", toml, &[("graded.png", &png)])
}

#[test]
fn graded_alpha_matte_nearest_and_bilinear_are_the_references_product() {
    let scene = graded();
    let frame = common::Frame::new(&scene, 64, 48);
    let ctx = frame.ctx(&scene);
    for (filter, rel) in [(Filter::Nearest, 1e-9), (Filter::Bilinear, 1e-5)] {
        let masks = technique(32, filter)
            .light_masks(&ctx, 0)
            .expect("penumbra casting runs");
        let a = compare(&scene, &frame, &masks, filter, rel);
        assert_agree(&format!("graded {filter:?}"), &a, 5000);
    }
}

#[test]
fn default_sample_sets_are_the_references_where_the_pattern_allows() {
    let pc = |pattern, sets| PenumbraCasting {
        samples: 64,
        seed: 1,
        pattern,
        options: PenumbraCastingOptions {
            pc_sample_sets: sets,
            ..PenumbraCastingOptions::default()
        },
    };
    assert_eq!(PenumbraCastingOptions::default().pc_sample_sets, 0);
    let interleaved = |n| SamplePattern::Interleaved { n };
    assert_eq!(pc(interleaved(4), 0).sample_sets(), 16);
    assert_eq!(pc(interleaved(2), 0).sample_sets(), 4);
    assert_eq!(pc(SamplePattern::Correlated, 0).sample_sets(), 1);
    assert_eq!(pc(SamplePattern::Grid, 0).sample_sets(), 1);
    assert_eq!(pc(SamplePattern::Stratified, 0).sample_sets(), 8);
    assert_eq!(pc(interleaved(4), 5).sample_sets(), 5);
    // Too many sets × groups for the hard-volume caches: the paper's 8.
    let mut big = pc(interleaved(16), 0);
    big.samples = 1024;
    assert_eq!(big.sample_sets(), 8);
    // The default with interleaved:4 gives every receiver its pixel's
    // reference samples.
    let scene = common::shipped("spheres.toml");
    let frame = common::Frame::new(&scene, 24, 18);
    let ctx = frame.ctx(&scene);
    let masks = pc(interleaved(4), 0)
        .light_masks(&ctx, 0)
        .expect("penumbra casting runs");
    assert!(masks.sets.matches_reference());
    assert_eq!(masks.sets.sets, 16);
    let hashed = pc(interleaved(4), 8)
        .light_masks(&ctx, 0)
        .expect("penumbra casting runs");
    assert!(!hashed.sets.matches_reference());
}
