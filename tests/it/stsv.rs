//! Soft textured shadow volumes (`penumbra::internal::shadow::kit::stsv`) against the
//! ray-traced reference, relation by relation: per (receiver, light
//! sample, S-triangle) the per-sample opacity look-up must equal the
//! reference's opacity of that triangle on the shadow ray, except at
//! ties (the ray within rounding distance of a triangle edge or the look-up
//! within rounding distance of a texel border); membership must hold every
//! receiver whose rays hit the triangle.

use crate::common;

use glam::{DVec3, Vec3};
use penumbra::internal::sampling::{LightSampler, PatternSampler, SamplePattern};
use penumbra::internal::scene::{LightShape, Scene};
use penumbra::internal::shade::LightSample;
use penumbra::internal::shadow::kit::membership::light_bound;
use penumbra::internal::shadow::kit::rays::{ShadowTracer, END_SHORTEN};
use penumbra::internal::shadow::kit::stsv::{
    build_volumes, membership, Filter, STriangle, STriangles, SamplePositions, SampleProjector,
    ShadowOrigin, StsvMembership, VolumeParams,
};
use rayon::prelude::*;

/// The fence's opacity texture: a diamond wire mesh, 256 × 256 RGBA,
/// wires along both diagonals every 64 texels, 12 texels wide along the
/// diagonal coordinate, alpha 255 on the wires and 0 in the holes.
/// `scenes/fence-opacity.png` is this image; rewrite it with
/// `PENUMBRA_WRITE_FENCE_TEXTURE=1 cargo test --release --test it stsv:: fence_texture`.
fn fence_texture() -> image::RgbaImage {
    image::RgbaImage::from_fn(256, 256, |i, j| {
        let (i, j) = (i64::from(i), i64::from(j));
        let wire = (i + j).rem_euclid(64) < 12 || (i - j).rem_euclid(64) < 12;
        if wire {
            image::Rgba([150, 150, 160, 255])
        } else {
            image::Rgba([0, 0, 0, 0])
        }
    })
}

fn scenes_dir() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes")
}

#[test]
fn fence_texture_matches_generator() {
    let path = scenes_dir().join("fence-opacity.png");
    if std::env::var_os("PENUMBRA_WRITE_FENCE_TEXTURE").is_some() {
        fence_texture()
            .save(&path)
            .expect("write the fence texture");
    }
    let shipped = image::open(&path).expect("fence texture").to_rgba8();
    assert!(
        shipped == fence_texture(),
        "{} differs from its generator",
        path.display()
    );
}

/// The fence texture as PNG bytes, for scenes written to scratch dirs.
fn fence_png() -> Vec<u8> {
    let mut png = Vec::new();
    fence_texture()
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .expect("encode");
    png
}

/// Disagreements are accepted only at ties: the segment passes within
/// `EDGE_TIE` × its length of a border of the S-triangle, or within
/// `TEXEL_TIE` × its length of a texel border line on the triangle. (3-D
/// distances, as in tests/it/dcs.rs: a segment grazing the triangle's plane
/// has its crossing's position in the plane ill-conditioned — for the
/// reference as for the look-up — while its distance to the border
/// stays small.) Measured worst cases are printed and quoted in
/// docs/algorithms/stsv.md.
const EDGE_TIE: f64 = 1e-6;
const TEXEL_TIE: f64 = 1e-6;

/// Where disagreeing relations lie.
#[derive(Debug, Default, Clone, Copy)]
struct Ties {
    /// Disagreements.
    count: usize,
    /// Of those, nearer a triangle border than a texel border (relative
    /// to the bounds), and their largest distance (÷ segment length).
    at_edges: usize,
    worst_edge: f64,
    /// The others, and their largest distance to a texel border line
    /// (÷ segment length).
    at_texels: usize,
    worst_texel: f64,
}

impl Ties {
    fn record(&mut self, (edge, texel): (f64, f64)) {
        self.count += 1;
        if edge / EDGE_TIE <= texel / TEXEL_TIE {
            self.at_edges += 1;
            self.worst_edge = self.worst_edge.max(edge);
        } else {
            self.at_texels += 1;
            self.worst_texel = self.worst_texel.max(texel);
        }
    }

    fn merge(mut self, o: Ties) -> Ties {
        self.count += o.count;
        self.at_edges += o.at_edges;
        self.worst_edge = self.worst_edge.max(o.worst_edge);
        self.at_texels += o.at_texels;
        self.worst_texel = self.worst_texel.max(o.worst_texel);
        self
    }

    fn check(&self, what: &str) {
        assert!(
            self.worst_edge <= EDGE_TIE && self.worst_texel <= TEXEL_TIE,
            "{what}: a disagreement away from every tie: {self:?}"
        );
    }
}

/// Distance between the lines `p + t d` and `q + s l` (f64).
fn line_distance(p: DVec3, d: DVec3, q: DVec3, l: DVec3) -> f64 {
    let m = d.cross(l);
    if m.length_squared() > 0.0 {
        ((p - q).dot(m)).abs() / m.length()
    } else {
        (p - q).cross(d).length() / d.length()
    }
}

/// How far segment `o → x` passes from a tie of `tri`, each ÷ the
/// segment's length: from the triangle's border (segment to edge
/// segments), and from the nearest texel border line through its
/// crossing with the triangle's plane (infinite without a crossing).
fn tie_distances(scene: &Scene, tri: &STriangle, o: Vec3, x: Vec3) -> (f64, f64) {
    let (o, x) = (o.as_dvec3(), x.as_dvec3());
    let dir = x - o;
    let len = dir.length();
    let edge = (0..3)
        .map(|k| common::segment_distance(o, x, tri.corners[k], tri.corners[(k + 1) % 3]))
        .fold(f64::INFINITY, f64::min)
        / len;
    let Some((l, b1, b2)) = tri.frame.hit(o, dir) else {
        return (edge, f64::INFINITY);
    };
    let c = o + dir * l;
    let [i, j, k] = tri.uvs.unwrap_or([glam::DVec2::ZERO; 3]);
    let uv = i * (1.0 - b1 - b2) + j * b1 + k * b2;
    let t = &scene.textures[tri.texture];
    let f = &tri.frame;
    let n = f.normal.normalize();
    // Texel coordinates (column, row) and their world gradients in the
    // plane; the border line through the nearest integer is
    // perpendicular to the gradient.
    let (w, h) = (f64::from(t.width), f64::from(t.height));
    let coords = [
        (uv.x * w, (f.dual1 * (j - i).x + f.dual2 * (k - i).x) * w),
        (
            (1.0 - uv.y) * h,
            -(f.dual1 * (j - i).y + f.dual2 * (k - i).y) * h,
        ),
    ];
    let texel = coords
        .iter()
        .map(|&(v, grad)| {
            let g2 = grad.length_squared();
            if !g2.is_normal() {
                return f64::INFINITY;
            }
            let foot = c + grad * ((v.round() - v) / g2);
            line_distance(c, dir, foot, n.cross(grad))
        })
        .fold(f64::INFINITY, f64::min)
        / len;
    (edge, texel)
}

/// The reference's opacity of geometry triangle `t` on the segment
/// `origin → x` (its own shadow ray: direction rounded to f32, shortened
/// end), and whether the ray hits it at all.
fn reference_opacity(tracer: &ShadowTracer, t: u32, origin: Vec3, x: Vec3) -> (bool, f64) {
    let dir = (x.as_dvec3() - origin.as_dvec3()).as_vec3();
    let mut out = (false, 0.0);
    tracer
        .translucent_bvh()
        .for_each_hit(origin, dir, (1.0 - END_SHORTEN) as f32, |h| {
            if h.triangle == t {
                out = (true, tracer.opacity(&h));
            }
        });
    out
}

/// What the relation-by-relation comparison measured.
#[derive(Debug, Default, Clone)]
struct Agreement {
    /// (receiver, sample, S-triangle) relations compared.
    relations: usize,
    /// Relations whose reference ray hits the S-triangle.
    reference_hits: usize,
    /// Nearest look-ups that differ from the reference's opacity.
    ties: Ties,
    /// (receiver, sample) relations compared as a whole.
    segments: usize,
    /// Segments whose product `Π (1 − opacity)` over the S-triangles
    /// differs from the reference's `V·T` (the quad's shared diagonal
    /// counts once there, once per triangle here).
    product_ties: Ties,
    /// SIMD and scalar look-ups that differ in any bit (must be 0).
    simd_scalar_differences: usize,
    /// Non-finite or out-of-range opacities, nearest or bilinear (must be 0).
    bad_values: usize,
    /// Bilinear look-ups that are not 0 where the ray misses (must be 0).
    bilinear_off_triangle: usize,
}

impl Agreement {
    fn merge(mut self, o: Agreement) -> Agreement {
        self.relations += o.relations;
        self.reference_hits += o.reference_hits;
        self.ties = self.ties.merge(o.ties);
        self.segments += o.segments;
        self.product_ties = self.product_ties.merge(o.product_ties);
        self.simd_scalar_differences += o.simd_scalar_differences;
        self.bad_values += o.bad_values;
        self.bilinear_off_triangle += o.bilinear_off_triangle;
        self
    }

    fn check(&self, name: &str, min_hits: usize) {
        eprintln!("{name}: {self:#?}");
        assert!(
            self.reference_hits >= min_hits,
            "{name}: too few hits to test"
        );
        assert_eq!(self.simd_scalar_differences, 0, "{name}");
        assert_eq!(self.bad_values, 0, "{name}");
        assert_eq!(self.bilinear_off_triangle, 0, "{name}");
        assert!(
            self.ties.count as f64 <= 1e-3 * self.relations as f64,
            "{name}: {} of {} relations disagree",
            self.ties.count,
            self.relations
        );
        self.ties.check(name);
        assert!(
            self.product_ties.count as f64 <= 1e-3 * self.segments as f64,
            "{name}: {} of {} segments disagree",
            self.product_ties.count,
            self.segments
        );
        self.product_ties.check(name);
    }
}

/// Per-sample look-ups against the reference: every surface pixel of
/// `frame`, every light, `n` of the reference's own samples per pixel
/// (stratified, as `PatternSampler` gives them to DCS and the reference).
fn agreement(scene: &Scene, frame: &common::Frame, n: u32, seed: u64) -> Agreement {
    let tracer = ShadowTracer::new(scene, &frame.geometry);
    let stris = STriangles::collect(scene, &frame.geometry);
    let rule = ShadowOrigin::new(scene, &frame.geometry);
    let width = frame.gbuffer.width as usize;
    let mut total = Agreement::default();
    for (k, light) in scene.lights.iter().enumerate() {
        let pattern = PatternSampler::new(SamplePattern::Stratified, n, seed, k);
        let sampler = LightSampler::new(light);
        let part = (0..frame.gbuffer.len())
            .into_par_iter()
            .filter(|&i| frame.gbuffer.is_surface(i))
            .map(|i| {
                let mut a = Agreement::default();
                let g = frame.gbuffer.sample(i);
                let mut samples: Vec<LightSample> = Vec::new();
                let pixel = ((i % width) as u32, (i / width) as u32);
                sampler.samples_with(&pattern, g.position, pixel, &mut samples);
                let origin = tracer.shadow_origin(g.position, g.geo_normal);
                assert_eq!(origin, rule.of(g.position, g.geo_normal));
                let m = samples.len();
                let mut product = vec![1.0f64; m];
                let (mut near, mut twin, mut bilinear) = (vec![0.0; m], vec![0.0; m], vec![0.0; m]);
                for (s, tri) in stris.list.iter().enumerate() {
                    stris.sample_opacities(scene, s, origin, &samples, Filter::Nearest, &mut near);
                    stris.sample_opacities_scalar(
                        scene,
                        s,
                        origin,
                        &samples,
                        Filter::Nearest,
                        &mut twin,
                    );
                    stris.sample_opacities(
                        scene,
                        s,
                        origin,
                        &samples,
                        Filter::Bilinear,
                        &mut bilinear,
                    );
                    a.simd_scalar_differences += near
                        .iter()
                        .zip(&twin)
                        .filter(|(x, y)| x.to_bits() != y.to_bits())
                        .count();
                    a.bad_values += near
                        .iter()
                        .chain(&bilinear)
                        .filter(|x| !(0.0..=1.0).contains(*x))
                        .count();
                    for (j, smp) in samples.iter().enumerate() {
                        a.relations += 1;
                        product[j] *= 1.0 - f64::from(near[j]);
                        let (hit, op) = reference_opacity(&tracer, tri.triangle, origin, smp.x);
                        a.reference_hits += usize::from(hit);
                        if !hit && bilinear[j] != 0.0 && !hits(&stris, s, origin, smp) {
                            a.bilinear_off_triangle += 1;
                        }
                        if near[j] != op as f32 {
                            a.ties.record(tie_distances(scene, tri, origin, smp.x));
                        }
                    }
                }
                for (j, smp) in samples.iter().enumerate() {
                    a.segments += 1;
                    let (vt, _) = tracer.segment(origin, smp.x);
                    if (vt - product[j]).abs() > 1e-6 {
                        // The tie nearest to any of the S-triangles.
                        let nearest = stris
                            .list
                            .iter()
                            .map(|t| tie_distances(scene, t, origin, smp.x))
                            .min_by(|x, y| {
                                (x.0 / EDGE_TIE)
                                    .min(x.1 / TEXEL_TIE)
                                    .total_cmp(&(y.0 / EDGE_TIE).min(y.1 / TEXEL_TIE))
                            })
                            .unwrap_or((f64::INFINITY, f64::INFINITY));
                        a.product_ties.record(nearest);
                    }
                }
                a
            })
            .reduce(Agreement::default, Agreement::merge);
        total = total.merge(part);
    }
    total
}

/// Whether the look-up reports a hit for one sample (opacity aside).
fn hits(stris: &STriangles, s: usize, origin: Vec3, smp: &LightSample) -> bool {
    let Some(p) = SampleProjector::new(&stris.list[s], origin) else {
        return false;
    };
    let mut hit = false;
    p.for_each_hit(std::slice::from_ref(smp), |_, _, _| hit = true);
    hit
}

/// What the membership checks measured.
#[derive(Debug, Default)]
struct Conservative {
    /// (receiver, S-triangle) relations checked.
    relations: usize,
    /// Relations with at least one sample ray hitting the S-triangle.
    with_hits: usize,
    /// Membership pairs.
    pairs: usize,
    /// Pairs the rasterizer found before the exact plane test.
    raster_pairs: usize,
    /// Relations with a hit but no membership (must be 0).
    missed: usize,
    /// Relations where membership and the exact plane test on the
    /// shadow-ray origin disagree (must be 0: the rasterized volume holds
    /// the exact one).
    exact_differences: usize,
}

/// Membership of every light against ray casting with `n` samples per
/// receiver and against the exact point-in-STSV test.
fn conservative(scene: &Scene, frame: &common::Frame, n: u32, seed: u64) -> Conservative {
    let ctx = frame.ctx(scene);
    let tracer = ShadowTracer::new(scene, &frame.geometry);
    let stris = STriangles::collect(scene, &frame.geometry);
    let params = VolumeParams::new(scene, &frame.geometry, &frame.view);
    let width = frame.gbuffer.width as usize;
    let mut out = Conservative::default();
    for (k, light) in scene.lights.iter().enumerate() {
        let m: StsvMembership = membership(&ctx, k, &stris).expect("membership");
        out.pairs += m.len();
        out.raster_pairs += m.raster_pairs;
        assert_eq!(m.pairs().count(), m.len());
        let volumes = build_volumes(&stris, &light_bound(&light.shape), &params);
        let pattern = PatternSampler::new(SamplePattern::Stratified, n, seed, k);
        let sampler = LightSampler::new(light);
        let counts = (0..frame.gbuffer.len())
            .into_par_iter()
            .filter(|&i| frame.gbuffer.is_surface(i))
            .map(|i| {
                let g = frame.gbuffer.sample(i);
                let (x, y) = ((i % width) as u32, (i / width) as u32);
                let mut samples = Vec::new();
                sampler.samples_with(&pattern, g.position, (x, y), &mut samples);
                let origin = tracer.shadow_origin(g.position, g.geo_normal);
                let mut c = [0usize; 4];
                for (s, tri) in stris.list.iter().enumerate() {
                    c[0] += 1;
                    let inside = m.contains(x, y, s as u32);
                    let hit = samples
                        .iter()
                        .any(|smp| reference_opacity(&tracer, tri.triangle, origin, smp.x).0);
                    c[1] += usize::from(hit);
                    c[2] += usize::from(hit && !inside);
                    let exact = volumes
                        .iter()
                        .filter(|v| v.s_triangle == s as u32)
                        .any(|v| v.contains(origin.as_dvec3(), params.tolerance));
                    c[3] += usize::from(exact != inside);
                }
                c
            })
            .reduce(|| [0; 4], |a, b| std::array::from_fn(|j| a[j] + b[j]));
        out.relations += counts[0];
        out.with_hits += counts[1];
        out.missed += counts[2];
        out.exact_differences += counts[3];
    }
    out
}

impl Conservative {
    fn check(&self, name: &str) {
        eprintln!("{name}: {self:#?}");
        assert!(self.with_hits > 0, "{name}: nothing to test");
        assert_eq!(
            self.missed, 0,
            "{name}: receivers hit through a triangle left out"
        );
        assert_eq!(
            self.exact_differences, 0,
            "{name}: raster and exact test differ"
        );
        assert!(self.raster_pairs >= self.pairs, "{name}");
    }
}

#[test]
fn fence_lookups_match_the_reference() {
    let scene = common::shipped("fence.toml");
    let frame = common::Frame::new(&scene, 96, 96);
    agreement(&scene, &frame, 16, 3).check("fence", 5000);
}

#[test]
fn fence_membership_is_conservative() {
    let scene = common::shipped("fence.toml");
    let frame = common::Frame::new(&scene, 96, 96);
    conservative(&scene, &frame, 64, 5).check("fence");
}

/// The measurement quoted in docs/algorithms/stsv.md (full size, 64
/// samples; about 6 s on two cores, so it runs with the others):
/// `cargo test --release --test it stsv:: fence_full_size -- --nocapture`.
#[test]
fn fence_full_size() {
    let scene = common::shipped("fence.toml");
    let frame = common::Frame::new(&scene, 512, 512);
    agreement(&scene, &frame, 64, 3).check("fence 512² × 64", 100_000);
    conservative(&scene, &frame, 64, 5).check("fence 512² × 64");
    // Timings (this machine, whatever else runs on it): the membership
    // pass, and the look-ups of every member pixel's 64 samples.
    let ctx = frame.ctx(&scene);
    let stris = STriangles::collect(&scene, &frame.geometry);
    let t = std::time::Instant::now();
    let m = membership(&ctx, 0, &stris).expect("membership");
    let pass = t.elapsed();
    let pattern = PatternSampler::new(SamplePattern::Stratified, 64, 3, 0);
    let sampler = LightSampler::new(&scene.lights[0]);
    let rule = ShadowOrigin::new(&scene, &frame.geometry);
    let width = frame.gbuffer.width as usize;
    let jobs: Vec<(Vec3, u32, Vec<LightSample>, SamplePositions)> = m
        .pairs()
        .map(|(i, s)| {
            let g = frame.gbuffer.sample(i);
            let mut samples = Vec::new();
            let pixel = ((i % width) as u32, (i / width) as u32);
            sampler.samples_with(&pattern, g.position, pixel, &mut samples);
            let mut positions = SamplePositions::default();
            positions.set(&samples);
            (rule.of(g.position, g.geo_normal), s, samples, positions)
        })
        .collect();
    // Best of three, alternating: the barycentric test alone (counting
    // hits), then with the opacity look-ups.
    let mut out = vec![0.0; 64];
    let projectors: Vec<(SampleProjector, &[LightSample], &SamplePositions)> = jobs
        .iter()
        .filter_map(|(o, s, samples, positions)| {
            SampleProjector::new(&stris.list[*s as usize], *o)
                .map(|p| (p, samples.as_slice(), positions))
        })
        .collect();
    let mut best = [f64::INFINITY; 4];
    let mut counts = [0usize; 4];
    for _ in 0..3 {
        for (slot, scalar) in [(0, false), (1, true)] {
            let t = std::time::Instant::now();
            let mut hits = 0usize;
            for (p, samples, positions) in &projectors {
                if scalar {
                    p.for_each_hit_scalar(samples, |_, _, _| hits += 1);
                } else {
                    p.for_each_hit_in(positions, |_, _, _| hits += 1);
                }
            }
            best[slot] = best[slot].min(t.elapsed().as_secs_f64());
            counts[slot] = hits;
        }
        for (slot, scalar) in [(2, false), (3, true)] {
            let t = std::time::Instant::now();
            let mut opaque = 0usize;
            for (origin, s, samples, positions) in &jobs {
                let s = *s as usize;
                if scalar {
                    stris.sample_opacities_scalar(
                        &scene,
                        s,
                        *origin,
                        samples,
                        Filter::Nearest,
                        &mut out,
                    );
                } else {
                    stris.sample_opacities_in(
                        &scene,
                        s,
                        *origin,
                        positions,
                        Filter::Nearest,
                        &mut out,
                    );
                }
                opaque += out.iter().filter(|&&o| o > 0.0).count();
            }
            best[slot] = best[slot].min(t.elapsed().as_secs_f64());
            counts[slot] = opaque;
        }
    }
    assert_eq!(counts[0], counts[1]);
    assert_eq!(counts[2], counts[3]);
    let rate = |secs: f64| jobs.len() as f64 * 64.0 / secs / 1e6;
    eprintln!(
        "{} pairs × 64 samples, {} hits, {} opaque: test alone f32x8 {:.0} / scalar {:.0} M samples/s; \
         with nearest look-ups f32x8 {:.0} / scalar {:.0} M samples/s",
        jobs.len(),
        counts[0],
        counts[2],
        rate(best[0]),
        rate(best[1]),
        rate(best[2]),
        rate(best[3])
    );
    eprintln!(
        "membership: {} volumes, {} triangles, {} raster pairs, {} pairs, {:.1} ms",
        m.volumes,
        m.triangles,
        m.raster_pairs,
        m.len(),
        pass.as_secs_f64() * 1e3
    );
}

/// Rays aimed at the triangles' edges and at texel borders, at offsets
/// from 1e-2 down to 1e-10 (of the edge's length, or in texels) on both
/// sides: the look-up and the reference may disagree only at ties, and,
/// for rays not grazing the triangle's plane, only at offsets ≤ 1e-5.
#[test]
fn aimed_rays_disagree_only_at_ties() {
    let scene = common::shipped("fence.toml");
    let frame = common::Frame::new(&scene, 48, 48);
    let tracer = ShadowTracer::new(&scene, &frame.geometry);
    let stris = STriangles::collect(&scene, &frame.geometry);
    let LightShape::Rect { center, u, v, .. } = scene.lights[0].shape else {
        panic!("rect light")
    };
    let (lc, ln) = (center.as_dvec3(), u.cross(v).as_dvec3());
    let offsets: Vec<f64> = (2..=10)
        .flat_map(|e| [10f64.powi(-e), -(10f64.powi(-e))])
        .chain([0.0])
        .collect();
    let receivers: Vec<Vec3> = (0..frame.gbuffer.len())
        .step_by(7)
        .filter(|&i| frame.gbuffer.is_surface(i))
        .map(|i| {
            let g = frame.gbuffer.sample(i);
            tracer.shadow_origin(g.position, g.geo_normal)
        })
        .collect();
    // Largest disagreeing offset over all rays, and over rays at least
    // 0.1 rad off the triangle's plane.
    let (mut tested, mut ties) = (0usize, Ties::default());
    let (mut worst_offset, mut worst_steep_offset) = (0.0f64, 0.0f64);
    let mut out = [0.0f32];
    for &origin in &receivers {
        let o = origin.as_dvec3();
        for (s, tri) in stris.list.iter().enumerate() {
            let [a, b, c] = tri.corners;
            let n = tri.frame.normal.normalize();
            let [uv0, uv1, uv2] = tri.uvs.expect("the quad has uvs");
            let tex = &scene.textures[tri.texture];
            // Aimed-at points with their offset: near edges (along the
            // in-plane inward normal, × edge length; 0.23 and 0.81 of the
            // way along, away from texel borders), then near texel column
            // borders (along u, in texels).
            let mut targets: Vec<(DVec3, f64)> = Vec::new();
            for (p, q, r) in [(a, b, c), (b, c, a), (c, a, b)] {
                let len = (q - p).length();
                let mut w = n.cross(q - p).normalize();
                if w.dot(r - p) < 0.0 {
                    w = -w;
                }
                for t in [0.23, 0.81] {
                    for &d in &offsets {
                        targets.push((p + (q - p) * t + w * (d * len), d.abs()));
                    }
                }
            }
            let (du1, du2) = (uv1 - uv0, uv2 - uv0);
            let det = du1.x * du2.y - du1.y * du2.x;
            for col in [70.0, 128.0, 173.0] {
                for row in [40.3, 121.5, 200.25] {
                    for &d in &offsets {
                        let uv = glam::DVec2::new(
                            (col + d) / f64::from(tex.width),
                            1.0 - row / f64::from(tex.height),
                        );
                        let r = uv - uv0;
                        let b1 = (r.x * du2.y - r.y * du2.x) / det;
                        let b2 = (du1.x * r.y - du1.y * r.x) / det;
                        if b1 < 0.01 || b2 < 0.01 || b1 + b2 > 0.99 {
                            continue;
                        }
                        targets.push((a + (b - a) * b1 + (c - a) * b2, d.abs()));
                    }
                }
            }
            for (y, offset) in targets {
                // The ray o → y continued to the light's plane.
                let k = ln.dot(lc - o) / ln.dot(y - o);
                if !(k > 1.0 && k.is_finite()) {
                    continue;
                }
                let x = (o + (y - o) * k).as_vec3();
                let smp = LightSample {
                    x,
                    st: glam::Vec2::ZERO,
                    inv_pdf_area: 1.0,
                };
                tested += 1;
                let one = std::slice::from_ref(&smp);
                stris.sample_opacities(&scene, s, origin, one, Filter::Nearest, &mut out);
                let (_, op) = reference_opacity(&tracer, tri.triangle, origin, x);
                if out[0] != op as f32 {
                    ties.record(tie_distances(&scene, tri, origin, x));
                    worst_offset = worst_offset.max(offset);
                    let sin = n.dot((x.as_dvec3() - o).normalize()).abs();
                    if sin > 0.1 {
                        worst_steep_offset = worst_steep_offset.max(offset);
                    }
                }
            }
        }
    }
    eprintln!(
        "aimed rays: {tested}; largest disagreeing offset {worst_offset:e} \
         ({worst_steep_offset:e} for rays over 0.1 rad off the plane); {ties:#?}"
    );
    assert!(tested > 10_000, "{tested}");
    assert!(ties.count > 0, "offsets down to 1e-10 must reach some ties");
    ties.check("aimed rays");
    assert!(worst_steep_offset <= 1e-5, "{worst_steep_offset}");
}

/// A vertical fence (plane x = 0, normal −X) under a rect light that
/// straddles its plane: each side of the fence casts the shadow of the
/// light part on the other side (two volumes per S-triangle). Seen from
/// both sides, so receivers on the fence see it from the front and the
/// back.
fn two_sided_scene(name: &str, light: &str) -> Scene {
    let toml = format!(
        r#"
[camera]
eye = [-3.0, 3.0, 4.0]
target = [0.0, 0.8, 0.0]
fov_y = 50.0
width = 64
height = 64

{light}

[[object]]
shape = "quad"
size = [6.0, 6.0]

[[object]]
shape = "quad"
size = [2.0, 2.0]
rotate = [0.0, 0.0, 90.0]
translate = [0.0, 1.2, 0.0]
material = {{ opacity_texture = "fence.png" }}
"#
    );
    common::scene_in_scratch(name, &toml, &[("fence.png", &fence_png())])
}

const STRADDLING_RECT: &str = r#"
[[light]]
type = "rect"
center = [0.3, 3.2, 0.0]
u = [0.8, 0.0, 0.0]
v = [0.0, 0.0, 0.4]
radiance = 10.0
"#;

#[test]
fn two_sided_light() {
    let mut scene = two_sided_scene("stsv-two-sided-rect", STRADDLING_RECT);
    let frame = common::Frame::new(&scene, 80, 80);
    let stris = STriangles::collect(&scene, &frame.geometry);
    assert_eq!(stris.len(), 2);
    let params = VolumeParams::new(&scene, &frame.geometry, &frame.view);
    let volumes = build_volumes(&stris, &light_bound(&scene.lights[0].shape), &params);
    assert_eq!(volumes.len(), 4, "two volumes per S-triangle");
    agreement(&scene, &frame, 32, 7).check("two-sided, seen from −x", 2000);
    conservative(&scene, &frame, 32, 7).check("two-sided, seen from −x");
    // The other side of the fence.
    scene.camera.eye = Vec3::new(3.0, 2.5, -4.0);
    let frame = common::Frame::new(&scene, 80, 80);
    agreement(&scene, &frame, 32, 8).check("two-sided, seen from +x", 2000);
    conservative(&scene, &frame, 32, 8).check("two-sided, seen from +x");
}

#[test]
fn sphere_lights() {
    // Above the tilted fence (one side), then straddling the vertical one.
    let mut scene = common::shipped("fence.toml");
    scene.lights[0].shape = LightShape::Sphere {
        center: Vec3::new(0.2, 3.5, -0.3),
        radius: 0.4,
    };
    let frame = common::Frame::new(&scene, 80, 80);
    agreement(&scene, &frame, 32, 9).check("sphere above", 2000);
    conservative(&scene, &frame, 32, 9).check("sphere above");
    let scene = two_sided_scene(
        "stsv-two-sided-sphere",
        r#"
[[light]]
type = "sphere"
center = [0.1, 3.0, 0.0]
radius = 0.5
radiance = 10.0
"#,
    );
    let frame = common::Frame::new(&scene, 80, 80);
    let stris = STriangles::collect(&scene, &frame.geometry);
    let params = VolumeParams::new(&scene, &frame.geometry, &frame.view);
    let volumes = build_volumes(&stris, &light_bound(&scene.lights[0].shape), &params);
    assert_eq!(volumes.len(), 4, "two volumes per S-triangle");
    agreement(&scene, &frame, 32, 10).check("sphere straddling", 2000);
    conservative(&scene, &frame, 32, 10).check("sphere straddling");
}

/// A horizontal fence at y = 0.75 (exact in binary, so lights can touch
/// its plane exactly) with `light`.
fn flat_fence(name: &str, light: &str) -> Scene {
    let toml = format!(
        r#"
[camera]
eye = [0.0, 4.0, 5.0]
target = [0.0, 0.3, 0.0]
fov_y = 45.0
width = 64
height = 64

{light}

[[object]]
shape = "quad"
size = [6.0, 6.0]

[[object]]
shape = "quad"
size = [2.0, 2.0]
translate = [0.0, 0.75, 0.0]
material = {{ opacity_texture = "fence.png" }}
"#
    );
    common::scene_in_scratch(name, &toml, &[("fence.png", &fence_png())])
}

/// Look-ups and membership run on `scene` without panicking, with finite
/// opacities in [0, 1] everywhere (bilinear too).
fn all_finite(scene: &Scene, frame: &common::Frame) {
    let ctx = frame.ctx(scene);
    let stris = STriangles::collect(scene, &frame.geometry);
    let rule = ShadowOrigin::new(scene, &frame.geometry);
    for (k, light) in scene.lights.iter().enumerate() {
        let m = membership(&ctx, k, &stris).expect("membership");
        assert!(m.len() <= m.raster_pairs);
        let pattern = PatternSampler::new(SamplePattern::Stratified, 16, 1, k);
        let sampler = LightSampler::new(light);
        let mut samples = Vec::new();
        let mut out = vec![0.0; 16];
        for (i, g) in frame
            .gbuffer
            .samples()
            .enumerate()
            .filter(|(_, g)| g.is_surface())
        {
            let w = frame.gbuffer.width as usize;
            sampler.samples_with(
                &pattern,
                g.position,
                ((i % w) as u32, (i / w) as u32),
                &mut samples,
            );
            let origin = rule.of(g.position, g.geo_normal);
            for s in 0..stris.len() {
                for filter in [Filter::Nearest, Filter::Bilinear] {
                    stris.sample_opacities(scene, s, origin, &samples, filter, &mut out);
                    assert!(out.iter().all(|o| (0.0..=1.0).contains(o)), "{out:?}");
                }
            }
        }
    }
}

#[test]
fn degenerate_s_triangles() {
    // The fence plus a zero-area S-triangle (three distinct collinear
    // corners: the loader would have dropped it, so it is added by hand)
    // and a sliver 1e-7 wide, both in the fence's material.
    let mut scene = common::shipped("fence.toml");
    let fence = scene
        .objects
        .iter_mut()
        .find(|o| o.name == "fence")
        .expect("fence");
    let mesh = &mut fence.mesh;
    let base = mesh.positions.len() as u32;
    // Binary-exact coordinates: the three corners are exactly collinear.
    let (p, e) = (Vec3::new(-0.25, 1.25, 0.125), Vec3::new(0.5, 0.0625, -0.25));
    mesh.positions
        .extend([p, p + e, p + e * 2.0, p + Vec3::new(0.0, 1e-7, 0.0)]);
    mesh.uvs
        .as_mut()
        .expect("uvs")
        .extend([glam::Vec2::new(0.3, 0.3); 4]);
    let material = mesh.material_ids[0];
    mesh.triangles
        .extend([[base, base + 1, base + 2], [base, base + 1, base + 3]]);
    mesh.material_ids.extend([material, material]);
    if let Some(n) = mesh.normals.as_mut() {
        n.extend([Vec3::Y; 4]);
    }
    let frame = common::Frame::new(&scene, 64, 64);
    let stris = STriangles::collect(&scene, &frame.geometry);
    assert_eq!(stris.len(), 4);
    let params = VolumeParams::new(&scene, &frame.geometry, &frame.view);
    let volumes = build_volumes(&stris, &light_bound(&scene.lights[0].shape), &params);
    assert_eq!(stris.list[2].frame.normal, DVec3::ZERO);
    assert!(
        volumes.iter().all(|v| v.s_triangle != 2),
        "no volume for zero area"
    );
    assert!(
        volumes.iter().any(|v| v.s_triangle == 3),
        "the sliver has one"
    );
    // No look-up on the zero-area triangle ever hits.
    assert!(SampleProjector::new(&stris.list[2], Vec3::new(0.0, 0.5, 0.0)).is_none());
    all_finite(&scene, &frame);
    agreement(&scene, &frame, 16, 2).check("with degenerate S-triangles", 1000);
    conservative(&scene, &frame, 16, 2).check("with degenerate S-triangles");
}

#[test]
fn lights_touching_the_plane() {
    // A rect light standing on the fence's plane (its lower edge in it),
    // a sphere light tangent to the fence inside the quad, and a rect
    // light lying in the plane (every sample on it: nothing is crossed).
    let standing = r#"
[[light]]
type = "rect"
center = [1.5, 1.25, 0.0]
u = [0.0, 0.5, 0.0]
v = [0.0, 0.0, 0.5]
radiance = 10.0
"#;
    let tangent = r#"
[[light]]
type = "sphere"
center = [0.25, 1.75, 0.5]
radius = 1.0
radiance = 10.0
"#;
    let lying = r#"
[[light]]
type = "rect"
center = [0.0, 0.75, -2.5]
u = [0.5, 0.0, 0.0]
v = [0.0, 0.0, 0.5]
radiance = 10.0
two_sided = true
"#;
    for (name, light, hits) in [
        ("stsv-standing", standing, 200),
        ("stsv-tangent", tangent, 200),
        ("stsv-lying", lying, 0),
    ] {
        let scene = flat_fence(name, light);
        let frame = common::Frame::new(&scene, 64, 64);
        all_finite(&scene, &frame);
        let a = agreement(&scene, &frame, 16, 4);
        a.check(name, hits);
        if hits == 0 {
            assert_eq!(a.reference_hits, 0, "{name}");
            let stris = STriangles::collect(&scene, &frame.geometry);
            let m = membership(&frame.ctx(&scene), 0, &stris).expect("membership");
            assert!(m.is_empty() && m.volumes == 0, "{name}");
        } else {
            conservative(&scene, &frame, 16, 4).check(name);
        }
    }
}
