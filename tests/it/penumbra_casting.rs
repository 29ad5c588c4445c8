//! Hierarchical penumbra casting against ray casting, relation by
//! relation: with the reference's own samples (`interleaved:2` and four
//! sets, so every receiver gets its pixel's reference samples), every
//! (receiver, light sample) bit must equal the shadow ray through the
//! opaque casters, except at ties — where the ray passes within
//! [`TIE`] (relative to its length) of a caster triangle's edge. The
//! optimised traversal (Fig. 3, SIMD) must give the basic one's (Fig. 2,
//! scalar) masks bit for bit, and the umbra bits the AND of the mask bits.

use crate::common;

use glam::DVec3;
use penumbra::internal::sampling::{LightSampler, PatternSampler, SamplePattern};
use penumbra::internal::scene::LightShape;
use penumbra::internal::scene::Scene;
use penumbra::internal::shadow::kit::rays::{ShadowTracer, END_SHORTEN};
use penumbra::internal::shadow::penumbra_casting::samples::{SampleKey, GROUP};
use penumbra::internal::shadow::penumbra_casting::{
    LightMasks, PenumbraCasting, PenumbraCastingOptions,
};
use penumbra::internal::shadow::ShadowTechnique;

/// A tie: the ray passes this close to a caster edge, relative to its
/// length (the same bound as DCS's exactness test).
const TIE: f64 = 1e-4;

const SHIPPED: [&str; 7] = [
    "bunny.toml",
    "dabrovic.toml",
    "fence.toml",
    "quad.toml",
    "spheres.toml",
    "sponza-plants.toml",
    "tinted.toml",
];

fn technique(n: u32, options: PenumbraCastingOptions) -> PenumbraCasting {
    PenumbraCasting {
        samples: n,
        seed: 7,
        pattern: SamplePattern::Interleaved { n: 2 },
        options: PenumbraCastingOptions {
            pc_sample_sets: 4,
            pc_chunk: 32,
            ..options
        },
    }
}

#[derive(Debug, Default)]
struct Exactness {
    relations: usize,
    blocked: usize,
    mismatches: usize,
    worst_tie: f64,
}

/// Every opaque caster edge, for the tie distance.
fn caster_edges(scene: &Scene, frame: &common::Frame) -> Vec<(DVec3, DVec3)> {
    let g = &frame.geometry;
    let mut out = Vec::new();
    for (t, tri) in g.triangles.iter().enumerate() {
        let obj = &scene.objects[g.triangle_object[t] as usize];
        let opaque = scene.materials[g.triangle_material[t] as usize].is_opaque();
        if !(obj.cast_shadows && opaque) {
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

fn check(scene: &Scene, frame: &common::Frame, masks: &LightMasks) -> Exactness {
    let tracer = ShadowTracer::new(scene, &frame.geometry);
    let edges = caster_edges(scene, frame);
    let sets = &masks.sets;
    assert!(
        sets.matches_reference(),
        "interleaved:2 with 4 sets is the reference's"
    );
    let pattern = PatternSampler::new(SamplePattern::Interleaved { n: 2 }, sets.n as u32, 7, 0);
    let sampler = LightSampler::new(&scene.lights[0]);
    let w = frame.gbuffer.width;
    let mut reference = Vec::new();
    let mut ours = Vec::new();
    let mut e = Exactness::default();
    for (i, set) in masks.set.iter().enumerate() {
        let Some(set) = set else { continue };
        let set = *set as usize;
        let g = frame.gbuffer.sample(i);
        // The set's samples are the reference's at this pixel, bit for bit.
        sampler.samples_with(
            &pattern,
            g.position,
            (i as u32 % w, i as u32 / w),
            &mut reference,
        );
        let key = SampleKey {
            position: g.position,
            pixel: (i as u32 % w, i as u32 / w),
        };
        assert_eq!(
            reference,
            sets.samples_for(set, key, &mut ours),
            "pixel {i}"
        );
        assert!(
            !reference.is_empty(),
            "pixel {i}: a receiver without samples"
        );
        let o = tracer.shadow_origin(g.position, g.geo_normal);
        let words = &masks.words[i * sets.groups..(i + 1) * sets.groups];
        // Umbra bits: exactly the groups whose words are full.
        let (gu, full) = masks.umbra[i];
        for (k, &word) in words.iter().enumerate() {
            assert_eq!(
                (gu >> k) & 1 == 1,
                word == sets.valid[k],
                "pixel {i} group {k}"
            );
        }
        assert_eq!(full, gu == sets.all_groups(), "pixel {i}");
        for (slot, &k) in sets.order[set].iter().enumerate() {
            let ours = (words[slot / GROUP] >> (slot % GROUP)) & 1 == 1;
            let x = reference[k as usize].x;
            let dir = (x.as_dvec3() - o.as_dvec3()).as_vec3();
            let ray = tracer
                .opaque_bvh()
                .occluded(o, dir, (1.0 - END_SHORTEN) as f32);
            e.relations += 1;
            e.blocked += usize::from(ray);
            if ours != ray {
                e.mismatches += 1;
                let (a, b) = (o.as_dvec3(), x.as_dvec3());
                let d = edges
                    .iter()
                    .map(|&(q0, q1)| common::segment_distance(a, b, q0, q1))
                    .fold(f64::INFINITY, f64::min);
                e.worst_tie = e.worst_tie.max(d / a.distance(b));
            }
        }
    }
    e
}

fn assert_exact(name: &str, e: &Exactness) {
    eprintln!("{name}: {e:?}");
    let agree = 1.0 - e.mismatches as f64 / e.relations.max(1) as f64;
    assert!(agree >= 0.9999, "{name}: {e:?}");
    assert!(e.worst_tie <= TIE, "{name}: {e:?}");
}

#[test]
fn penumbra_casting_equals_ray_casting_on_every_shipped_scene() {
    for name in SHIPPED {
        let scene = common::shipped(name);
        let frame = common::Frame::new(&scene, 48, 36);
        let ctx = frame.ctx(&scene);
        let masks = technique(32, PenumbraCastingOptions::default())
            .light_masks(&ctx, 0)
            .expect("penumbra casting runs");
        let e = check(&scene, &frame, &masks);
        assert!(e.relations > 20_000, "{name}: {e:?}");
        assert_exact(name, &e);
    }
}

#[test]
fn several_groups_and_partial_groups_stay_exact() {
    // 80 samples: two full groups and one of 16.
    let scene = common::shipped("spheres.toml");
    let frame = common::Frame::new(&scene, 40, 30);
    let ctx = frame.ctx(&scene);
    let masks = technique(80, PenumbraCastingOptions::default())
        .light_masks(&ctx, 0)
        .expect("penumbra casting runs");
    assert_eq!(masks.sets.groups, 3);
    assert_eq!(masks.sets.valid[2], 0xffff);
    let e = check(&scene, &frame, &masks);
    assert!(e.blocked > e.relations / 20, "{e:?}");
    assert_exact("spheres, 80 samples", &e);
}

#[test]
fn optimised_equals_basic_on_every_shipped_scene() {
    let optimised = PenumbraCastingOptions {
        // Rebuild often, so rebuilt hierarchies are exercised too.
        pc_rebuild_percent: 5,
        ..PenumbraCastingOptions::default()
    };
    for name in SHIPPED {
        let scene = common::shipped(name);
        let frame = common::Frame::new(&scene, 40, 30);
        let ctx = frame.ctx(&scene);
        let a = technique(32, optimised)
            .light_masks(&ctx, 0)
            .expect("optimised runs");
        let b = technique(32, PenumbraCastingOptions::default().basic())
            .light_masks(&ctx, 0)
            .expect("basic runs");
        assert_eq!(a.set, b.set, "{name}");
        let blocked: u32 = a.words.iter().map(|w| w.count_ones()).sum();
        // The fence's only caster is an S-triangle, which is not cast.
        assert!(
            blocked > 0 || name == "fence.toml",
            "{name}: something is shadowed"
        );
        assert!(
            a.words == b.words,
            "{name}: optimised and basic masks differ"
        );
        eprintln!(
            "{name}: {blocked} blocked bits; rebuilds {} (optimised) {} (basic); masked {} vs {}",
            a.report.stats.rebuilds,
            b.report.stats.rebuilds,
            a.report.stats.masked,
            b.report.stats.masked
        );
    }
}

#[test]
fn each_optimisation_alone_gives_the_same_masks() {
    let scene = common::shipped("bunny.toml");
    let frame = common::Frame::new(&scene, 40, 30);
    let ctx = frame.ctx(&scene);
    let basic = PenumbraCastingOptions::default().basic();
    let base = technique(64, basic)
        .light_masks(&ctx, 0)
        .expect("basic runs");
    let variants: [fn(&mut PenumbraCastingOptions); 10] = [
        |o| o.pc_umbra_bits = true,
        |o| o.pc_active_planes = true,
        |o| o.pc_lazy_volumes = true,
        |o| o.pc_on_demand_masks = true,
        |o| o.pc_sort_blockers = true,
        |o| o.pc_simd = true,
        |o| o.pc_cone_prefilter = true,
        // The cone's decisions (they need its prefilter), scalar and SIMD.
        |o| {
            o.pc_cone_prefilter = true;
            o.pc_cone_decides = true;
        },
        |o| {
            o.pc_cone_prefilter = true;
            o.pc_cone_decides = true;
            o.pc_cone_split = true;
        },
        |o| {
            o.pc_cone_prefilter = true;
            o.pc_cone_decides = true;
            o.pc_cone_split = true;
            o.pc_simd = true;
        },
    ];
    for (j, set) in variants.iter().enumerate() {
        let mut o = basic;
        set(&mut o);
        let m = technique(64, o).light_masks(&ctx, 0).expect("variant runs");
        assert!(
            m.words == base.words,
            "optimisation {j} alone changes the masks"
        );
    }
}

/// Splitting heavy chunks by the probe changes no bit: bunny with one
/// 256² chunk split wherever the probe saw any work (down to 64²) against
/// no split, and the split chunks the same in a pool of one thread and of
/// three.
#[test]
fn splitting_heavy_chunks_changes_no_mask() {
    let scene = common::shipped("bunny.toml");
    let frame = common::Frame::new(&scene, 200, 150);
    let ctx = frame.ctx(&scene);
    let with = |split: u64| {
        let mut t = technique(32, PenumbraCastingOptions::default());
        t.options.pc_chunk = 256;
        t.options.pc_split_work = split;
        t
    };
    let whole = with(0).light_masks(&ctx, 0).expect("runs");
    assert_eq!(whole.report.chunks, 1);
    let pool = |n| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .expect("a pool")
    };
    let split = pool(1).install(|| with(1).light_masks(&ctx, 0).expect("runs"));
    let again = pool(3).install(|| with(1).light_masks(&ctx, 0).expect("runs"));
    assert!(
        split.report.chunks > 4 && split.report.chunks_unsplit == 1,
        "{} chunks from {}",
        split.report.chunks,
        split.report.chunks_unsplit
    );
    assert_eq!(split.report.chunks, again.report.chunks);
    let blocked: u32 = whole.words.iter().map(|w| w.count_ones()).sum();
    assert!(blocked > 1000, "{blocked} blocked relations");
    assert!(split.words == whole.words, "split chunks change the masks");
    assert!(again.words == whole.words);
    assert!(split.umbra == whole.umbra);
}

/// Penumbra casting `pc` and the reference with its samples, seed and
/// pattern on `ctx`: at most one pixel in 10³ may differ in any bit of
/// Vcoef or radiance (those with a relation at a tie), and more than a
/// tenth must be shadowed. Gives penumbra casting's output.
fn assert_reference_bits(
    ctx: &penumbra::internal::shadow::ShadowContext,
    pc: &PenumbraCasting,
) -> penumbra::internal::shadow::ShadowOutput {
    use penumbra::internal::shadow::reference::Reference;
    let ours = pc.compute(ctx).expect("penumbra casting runs");
    let reference = Reference {
        samples: pc.samples,
        seed: pc.seed,
        pattern: pc.pattern,
    }
    .compute(ctx)
    .expect("reference runs");
    let (a, b) = (&ours.lights[0], &reference.lights[0]);
    let (va, vb) = (a.vcoef(), b.vcoef());
    let (ra, rb) = (
        a.radiance().expect("radiance"),
        b.radiance().expect("radiance"),
    );
    let differ = (0..va.len())
        .filter(|&i| va[i].to_bits() != vb[i].to_bits() || ra[i] != rb[i])
        .count();
    let shadowed = vb.iter().filter(|&&v| v < 1.0).count();
    eprintln!(
        "{differ} of {} pixels differ ({shadowed} shadowed)",
        va.len()
    );
    assert!(shadowed > va.len() / 10);
    assert!(differ * 1000 <= va.len(), "{differ} pixels differ");
    ours
}

/// With the reference's samples the output is the reference's, bit for
/// bit, at every pixel whose relations are all ray-exact.
#[test]
fn vcoef_and_radiance_are_the_references_bits() {
    let scene = common::shipped("spheres.toml");
    let frame = common::Frame::new(&scene, 48, 36);
    let ctx = frame.ctx(&scene);
    let ours = assert_reference_bits(&ctx, &technique(32, PenumbraCastingOptions::default()));
    let layer = &ours.layers[0];
    assert_eq!(layer.name, "pc_leaf_triangles");
    assert!(layer.channels[0].1.iter().any(|&c| c > 0.0));
}

/// The stiff cases of one scene, shifted by `offset`: a box standing on
/// the ground (contact), a quad lying in the ground's plane (coplanar
/// receiver and blocker), a box whose top touches the light's plane
/// under the light, and a tall box crossing the light's plane beside it.
fn stiff_scene(name: &str, offset: [f64; 3]) -> Scene {
    let at = |x: f64, y: f64, z: f64| {
        format!("[{}, {}, {}]", x + offset[0], y + offset[1], z + offset[2])
    };
    let toml = format!(
        r#"
[scene]
name = "stiff"
[camera]
eye = {eye}
target = {target}
up = [0.0, 1.0, 0.0]
fov_y = 50.0
width = 64
height = 48
[[light]]
type = "rect"
center = {light}
u = [0.6, 0.0, 0.0]
v = [0.0, 0.0, 0.6]
radiance = [8.0, 8.0, 8.0]
[[object]]
name = "ground"
shape = "quad"
size = [8.0, 8.0]
translate = {ground}
[[object]]
name = "contact"
shape = "box"
size = [0.8, 0.8, 0.8]
translate = {contact}
[[object]]
name = "coplanar"
shape = "quad"
size = [1.0, 1.0]
translate = {coplanar}
[[object]]
name = "touching the light"
shape = "box"
size = [0.4, 0.6, 0.4]
translate = {touching}
[[object]]
name = "crossing the light's plane"
shape = "box"
size = [0.3, 2.0, 0.3]
translate = {crossing}
"#,
        eye = at(0.0, 4.5, 6.0),
        target = at(0.0, 0.5, 0.0),
        light = at(0.0, 3.0, 0.0),
        ground = at(0.0, 0.0, 0.0),
        contact = at(-1.0, 0.4, 0.5),
        coplanar = at(1.2, 0.0, 1.0),
        touching = at(0.3, 2.7, 0.2),
        crossing = at(1.2, 3.0, -0.3),
    );
    common::scene_in_scratch(name, &toml, &[])
}

/// Both the optimised and the basic traversal on `scene` (64 × 48, 64
/// samples) against the rays: more than a `1 / blocked` share of the
/// relations blocked, and every disagreement a tie — at most one in 10⁴
/// near the origin; `far` from it, where the `f32` grid (1/64 unit at
/// 2·10⁵) puts light samples exactly on the edges of a box touching the
/// light, at most one in 10³.
fn assert_stiff(name: &str, scene: &Scene, far: bool, blocked: usize) {
    let frame = common::Frame::new(scene, 64, 48);
    let ctx = frame.ctx(scene);
    for options in [
        PenumbraCastingOptions::default(),
        PenumbraCastingOptions::default().basic(),
    ] {
        let masks = technique(64, options)
            .light_masks(&ctx, 0)
            .expect("penumbra casting runs");
        let e = check(scene, &frame, &masks);
        eprintln!("{name}: {e:?}");
        assert!(e.blocked > e.relations / blocked, "{name}: {e:?}");
        let share = if far { 1000 } else { 10_000 };
        assert!(e.mismatches * share <= e.relations, "{name}: {e:?}");
        assert!(e.worst_tie <= TIE, "{name}: {e:?}");
    }
}

#[test]
fn stiff_cases_lose_and_invent_no_shadow_beyond_ties() {
    // Far from the origin 19 of 123,840 relations differ, each at
    // distance 0 from an edge of the box touching the light.
    for (name, offset) in [
        ("pc-stiff", [0.0; 3]),
        ("pc-stiff-far", [1.0e5, -3.0e4, 2.0e5]),
    ] {
        assert_stiff(name, &stiff_scene(name, offset), offset != [0.0; 3], 20);
    }
}

/// Sphere lights: every receiver's samples are the reference's own at its
/// pixel (the cone from its surface point), and every relation is the
/// shadow ray's except at ties, optimised and basic alike.
#[test]
fn sphere_lights_equal_ray_casting() {
    for (name, radius) in [
        ("spheres.toml", 1.2),
        ("bunny.toml", 0.4),
        ("sponza-plants.toml", 0.5),
    ] {
        let scene = common::with_sphere_light(common::shipped(name), radius);
        let frame = common::Frame::new(&scene, 48, 36);
        let ctx = frame.ctx(&scene);
        let optimised = technique(80, PenumbraCastingOptions::default())
            .light_masks(&ctx, 0)
            .expect("penumbra casting runs");
        let e = check(&scene, &frame, &optimised);
        assert!(e.relations > 50_000, "{name}: {e:?}");
        assert!(e.blocked > e.relations / 50, "{name}: {e:?}");
        assert_exact(name, &e);
        let basic = technique(80, PenumbraCastingOptions::default().basic())
            .light_masks(&ctx, 0)
            .expect("penumbra casting runs");
        assert!(basic.words == optimised.words, "{name}: basic differs");
        assert!(basic.umbra == optimised.umbra, "{name}: umbra bits differ");
    }
}

/// With a sphere light every receiver has the reference's samples for any
/// pattern (here the default, stratified one), so the output is the
/// reference's at every pixel whose relations are all ray-exact; a
/// receiver inside the sphere gets Vcoef 1 and no radiance, as there.
#[test]
fn sphere_light_vcoef_and_radiance_are_the_references_bits() {
    // The light's sphere reaches into the ground: receivers inside it.
    let mut scene = common::with_sphere_light(common::shipped("spheres.toml"), 1.0);
    if let LightShape::Sphere { center, .. } = &mut scene.lights[0].shape {
        center.y = 0.6;
        center.x += 2.5;
    }
    let LightShape::Sphere { center, radius } = scene.lights[0].shape else {
        unreachable!()
    };
    let frame = common::Frame::new(&scene, 48, 36);
    let ctx = frame.ctx(&scene);
    let pc = PenumbraCasting {
        samples: 48,
        seed: 3,
        pattern: SamplePattern::Stratified,
        options: PenumbraCastingOptions {
            pc_chunk: 16,
            ..PenumbraCastingOptions::default()
        },
    };
    let ours = assert_reference_bits(&ctx, &pc);
    let (va, ra) = (
        ours.lights[0].vcoef(),
        ours.lights[0].radiance().expect("radiance"),
    );
    let mut inside = 0;
    for i in 0..va.len() {
        assert!(va[i].is_finite() && ra[i].is_finite(), "pixel {i}");
        let g = frame.gbuffer.sample(i);
        if g.is_surface() && g.position.distance(center) <= radius {
            inside += 1;
            assert_eq!((va[i], ra[i]), (1.0, glam::Vec3::ZERO), "pixel {i}");
        }
    }
    assert!(inside > 0, "no receiver inside the light");
}

/// The stiff cases under a sphere light, in two placements: the sphere's
/// lowest point on the top of the box touching the light, and the sphere
/// around the tall box's top (a caster through the light: its surface
/// inside the sphere gets no samples, the rest sees the light on both
/// sides of it); contact and the coplanar quad in both; at the origin and
/// 2·10⁵ from it.
#[test]
fn sphere_light_stiff_cases_lose_and_invent_no_shadow_beyond_ties() {
    for (name, offset) in [
        ("pc-sphere-stiff", [0.0; 3]),
        ("pc-sphere-stiff-far", [1.0e5, -3.0e4, 2.0e5]),
    ] {
        let scene = stiff_scene(name, offset);
        // (centre relative to the rect light's centre, radius)
        for (place, radius) in [([0.3, 0.3, 0.2], 0.3), ([1.2, 0.8, -0.3], 0.4)] {
            let mut scene = common::with_sphere_light(scene.clone(), radius);
            if let LightShape::Sphere { center, .. } = &mut scene.lights[0].shape {
                *center += glam::Vec3::from_array(place);
            }
            let label = format!("{name} {place:?}");
            assert_stiff(&label, &scene, offset != [0.0; 3], 50);
        }
    }
}

/// A unit cube (outward faces), each face an 8 × 8 grid of quads (so its
/// back faces outnumber the triangles closing an opening), with the faces
/// in `missing` left out: `"bottom"`, `"top"`, `"front"`, `"back"`,
/// `"left"`, `"right"`. Grid coordinates are multiples of 1/8, exact, so
/// the faces' shared edges weld.
fn open_cube_obj(missing: &[&str]) -> String {
    const N: usize = 8;
    let mut obj = String::new();
    let mut next = 1;
    // (name, origin, a, b) with a × b the outward normal.
    type Face = (&'static str, [f32; 3], [f32; 3], [f32; 3]);
    let faces: [Face; 6] = [
        (
            "bottom",
            [-0.5, -0.5, -0.5],
            [1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0],
        ),
        ("top", [-0.5, 0.5, -0.5], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]),
        ("front", [-0.5, -0.5, 0.5], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
        ("back", [-0.5, -0.5, -0.5], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]),
        ("left", [-0.5, -0.5, -0.5], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]),
        ("right", [0.5, -0.5, -0.5], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]),
    ];
    for (name, o, a, b) in faces {
        if missing.contains(&name) {
            continue;
        }
        for j in 0..=N {
            for i in 0..=N {
                let (u, v) = (i as f32 / N as f32, j as f32 / N as f32);
                let p: Vec<f32> = (0..3).map(|k| o[k] + a[k] * u + b[k] * v).collect();
                obj += &format!("v {} {} {}\n", p[0], p[1], p[2]);
            }
        }
        let at = |i: usize, j: usize| next + j * (N + 1) + i;
        for j in 0..N {
            for i in 0..N {
                let (p00, p10, p11, p01) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                obj += &format!("f {p00} {p10} {p11}\nf {p00} {p11} {p01}\n");
            }
        }
        next += (N + 1) * (N + 1);
    }
    obj
}

/// Open casters (a cube without one or two faces, opening up, sideways
/// and down onto the ground, and the shipped bunny, whose base has five
/// holes): their back faces are cast only into the receivers not sealed
/// against the holes, and every relation is still the shadow ray's,
/// optimised equal to basic (which casts every face everywhere).
#[test]
fn open_casters_skip_back_faces_only_where_sealed() {
    for (name, missing) in [
        ("up", &["top"][..]),
        ("side", &["right"][..]),
        ("down", &["bottom"][..]),
        ("tunnel", &["front", "back"][..]),
    ] {
        let toml = r#"
[scene]
name = "open"
[camera]
eye = [2.5, 3.5, 3.0]
target = [0.0, 0.3, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 50.0
width = 64
height = 48
[[light]]
type = "rect"
center = [-0.8, 3.0, -0.5]
u = [0.5, 0.0, 0.0]
v = [0.0, 0.0, 0.5]
radiance = [8.0, 8.0, 8.0]
[[object]]
name = "ground"
shape = "quad"
size = [8.0, 8.0]
[[object]]
name = "open cube"
obj = "cube.obj"
translate = [0.0, 0.5, 0.0]
rotate = [0.0, 20.0, 0.0]
"#;
        let obj = open_cube_obj(missing);
        let scene = common::scene_in_scratch(
            &format!("pc-open-{name}"),
            toml,
            &[("cube.obj", obj.as_bytes())],
        );
        let frame = common::Frame::new(&scene, 64, 48);
        let ctx = frame.ctx(&scene);
        let optimised = technique(64, PenumbraCastingOptions::default())
            .light_masks(&ctx, 0)
            .expect("penumbra casting runs");
        let r = &optimised.report;
        eprintln!(
            "{name}: {} open back faces, {} caps, {} of {} receivers sealed",
            r.open_back, r.caps, r.sealed, r.receivers
        );
        assert!(r.open_back > 0 && r.caps > 0, "{name}: {r:?}");
        assert!(r.sealed > 0 && r.sealed < r.receivers, "{name}: {r:?}");
        let e = check(&scene, &frame, &optimised);
        assert!(e.blocked > e.relations / 50, "{name}: {e:?}");
        assert_exact(name, &e);
        let basic = technique(64, PenumbraCastingOptions::default().basic())
            .light_masks(&ctx, 0)
            .expect("penumbra casting runs");
        assert!(basic.words == optimised.words, "{name}: basic differs");
    }
    let scene = common::shipped("bunny.toml");
    let frame = common::Frame::new(&scene, 48, 36);
    let ctx = frame.ctx(&scene);
    let masks = technique(32, PenumbraCastingOptions::default())
        .light_masks(&ctx, 0)
        .expect("penumbra casting runs");
    let r = &masks.report;
    assert!(
        r.open_back > 10_000 && r.sealed > r.receivers / 2,
        "bunny: {r:?}"
    );
    assert_exact("bunny", &check(&scene, &frame, &masks));
}

/// The boundary loops of an open caster close it: a fan per loop, with
/// the object's faces, uses every welded edge as often in one direction
/// as in the other; a closed cube has none.
#[test]
fn boundary_loops_close_open_casters() {
    use std::collections::HashMap;
    for (missing, loops) in [
        (&[][..], 0),
        (&["top"][..], 1),
        (&["front", "back"][..], 2),
        (&["top", "right"][..], 1),
    ] {
        let toml = "[scene]\nname = \"loops\"\n[camera]\neye = [2.0, 2.0, 3.0]\n\
                    target = [0.0, 0.0, 0.0]\nup = [0.0, 1.0, 0.0]\nfov_y = 50.0\n\
                    width = 16\nheight = 16\n[[light]]\ntype = \"rect\"\n\
                    center = [0.0, 3.0, 0.0]\nu = [0.5, 0.0, 0.0]\nv = [0.0, 0.0, 0.5]\n\
                    radiance = [1.0, 1.0, 1.0]\n[[object]]\nobj = \"cube.obj\"\n";
        let obj = open_cube_obj(missing);
        let scene = common::scene_in_scratch("pc-loops", toml, &[("cube.obj", obj.as_bytes())]);
        let g = penumbra::internal::geom::SceneGeometry::new(&scene);
        let adj = g.adjacency();
        let found = adj.boundary_loops(&g, 0);
        assert_eq!(found.len(), loops, "{missing:?}: {found:?}");
        let mut sum: HashMap<(u32, u32), i32> = HashMap::new();
        let mut add = |a: u32, b: u32| {
            let (key, d) = if a < b { ((a, b), 1) } else { ((b, a), -1) };
            *sum.entry(key).or_default() += d;
        };
        for f in &adj.face_vertices {
            for k in 0..3 {
                add(f[k], f[(k + 1) % 3]);
            }
        }
        for l in &found {
            for i in 1..l.len() - 1 {
                let t = [l[0], l[i + 1], l[i]];
                for k in 0..3 {
                    add(t[k], t[(k + 1) % 3]);
                }
            }
        }
        assert!(
            sum.values().all(|&s| s == 0),
            "{missing:?}: not closed by its caps"
        );
    }
}

/// A sphere light's receivers hold their own samples: under a small mask
/// budget the chunks shrink (to a divisor of `--pc-chunk`, so bands stay
/// aligned) and the masks are the same.
#[test]
fn sphere_light_chunks_shrink_to_the_budget_with_the_same_masks() {
    let scene = common::with_sphere_light(common::shipped("spheres.toml"), 1.2);
    let frame = common::Frame::new(&scene, 48, 36);
    let ctx = frame.ctx(&scene);
    let whole = technique(256, PenumbraCastingOptions::default())
        .light_masks(&ctx, 0)
        .expect("penumbra casting runs");
    let small = technique(
        256,
        PenumbraCastingOptions {
            pc_mask_budget_mib: 1,
            ..PenumbraCastingOptions::default()
        },
    )
    .light_masks(&ctx, 0)
    .expect("penumbra casting runs");
    let (a, b) = (&whole.report, &small.report);
    assert_eq!(a.chunk_side, 32, "{a:?}");
    assert!(b.chunk_side < 32 && 32 % b.chunk_side == 0, "{b:?}");
    assert!(b.chunks > a.chunks && b.waves > 1, "{b:?}");
    assert!(small.words == whole.words, "the budget changes the masks");
}
