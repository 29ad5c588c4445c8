//! Shadow rays: the opaque and translucent casters' BVHs, the shadow-ray
//! origin rule and its epsilons (one copy for the reference, STSV and
//! DCS's tie recount), segment transmittance.
//!
//! **Shadow-ray offset** (the oracle's rule): origin
//! `o = p + ε_p n_g` with `n_g` the G-buffer's geometric normal (facing the
//! viewer, also when the sample is behind the surface: `V` is pure
//! visibility), `ε_p = max(1e-6 × D, 1e-5 × max_i |p_i|)`, `D` the diagonal
//! of the bounding box of all triangles and lights. The second term keeps
//! the origin about 80 f32 ulps off the surface far from the world origin.
//! The segment ends at `t_max = |x − o| (1 − 1e-6)`.

mod trace;

use crate::gbuffer::{GBuffer, GSample};
use crate::geom::bvh::{Bvh, Hit, SegmentHull};
use crate::geom::SceneGeometry;
use crate::sampling::Strata;
use crate::scene::{LightShape, Scene};
use crate::shade::LightSample;
#[cfg(target_arch = "x86_64")]
use crate::simd::level::runs_v3;
use glam::{DVec3, Vec2, Vec3};
use rayon::prelude::*;

/// Scene-relative part of the shadow-ray offset: `ε = EPS_SCENE × D`.
pub const EPS_SCENE: f64 = 1e-6;
/// Position-relative part of the offset: `ε_p ≥ EPS_POSITION × max_i |p_i|`.
pub const EPS_POSITION: f64 = 1e-5;
/// A segment ends at `(1 − END_SHORTEN)` of the way to the light sample, so
/// a light lying on a surface does not shadow itself.
pub const END_SHORTEN: f64 = 1e-6;
/// Crossings of non-opaque surfaces closer than `MERGE_SCENE × D` along a
/// segment count once (the oracle's step past each hit); this is what makes
/// a segment through an edge shared by two triangles cross one surface.
pub const MERGE_SCENE: f64 = 1e-6;

/// The reference's shadow-ray origin rule without building its BVHs:
/// `o = p + ε_p n_g`, `ε_p = max(EPS_SCENE × D, EPS_POSITION × max_i |p_i|)`
/// (see the module doc): the one copy of the rule, used by
/// [`ShadowTracer::shadow_origin`], soft textured shadow volumes and DCS.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShadowOrigin {
    eps_scene: f64,
}

impl ShadowOrigin {
    /// The rule for a scene.
    pub fn new(scene: &Scene, geometry: &SceneGeometry) -> Self {
        ShadowOrigin {
            eps_scene: EPS_SCENE * scene_diagonal(scene, geometry),
        }
    }

    /// The origin for receiver `p` with geometric normal `ng` (facing the
    /// viewer).
    #[inline]
    pub fn of(&self, p: Vec3, ng: Vec3) -> Vec3 {
        (p.as_dvec3() + ng.as_dvec3() * self.epsilon(p)).as_vec3()
    }

    /// The offset `ε_p = max(EPS_SCENE × D, EPS_POSITION × max_i |p_i|)`.
    #[inline]
    pub fn epsilon(&self, p: Vec3) -> f64 {
        self.eps_scene
            .max(EPS_POSITION * f64::from(p.abs().max_element()))
    }
}

/// Diagonal of the bounding box of all triangles and lights (rect corners,
/// sphere bounds): the scale of the shadow-ray offset. 0 for an empty
/// scene.
pub fn scene_diagonal(scene: &Scene, geometry: &SceneGeometry) -> f64 {
    let mut lo = DVec3::INFINITY;
    let mut hi = DVec3::NEG_INFINITY;
    let mut grow = |p: DVec3| {
        lo = lo.min(p);
        hi = hi.max(p);
    };
    for p in &geometry.positions {
        grow(p.as_dvec3());
    }
    for light in &scene.lights {
        match light.shape {
            LightShape::Rect { center, u, v, .. } => {
                let (c, u, v) = (center.as_dvec3(), u.as_dvec3(), v.as_dvec3());
                for (a, b) in [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
                    grow(c + u * a + v * b);
                }
            }
            LightShape::Sphere { center, radius } => {
                let r = DVec3::splat(f64::from(radius));
                grow(center.as_dvec3() - r);
                grow(center.as_dvec3() + r);
            }
        }
    }
    if lo.x > hi.x {
        return 0.0;
    }
    (hi - lo).length()
}

/// Shadow rays against a scene: the opaque casters' BVH (any hit) and the
/// non-opaque casters' BVH (transmittance walk), with the offset rule.
/// Build it once per scene; every query is `&self` and thread-safe.
#[derive(Debug, Clone)]
pub struct ShadowTracer<'a> {
    scene: &'a Scene,
    geometry: &'a SceneGeometry,
    opaque: Bvh,
    translucent: Bvh,
    /// The shadow-ray origin rule.
    origin: ShadowOrigin,
    /// `MERGE_SCENE × D`.
    merge: f64,
    /// Most candidate leaves of a receiver's segment hull before its rays
    /// take the whole walk instead (0: always the whole walk).
    hull_limit: usize,
}

/// Default [`ShadowTracer::with_hull_limit`]: past this many candidate
/// leaves the rays' own walks are cheaper than testing every candidate
/// (callgrind on spheres and bunny, 256², 64 samples: 4 is best of 4, 8,
/// 16, 24, 64, 256; see docs/performance.md).
pub const HULL_LIMIT: usize = 4;

/// Reusable per-thread buffers of the tracer's queries (directions,
/// answers, candidate leaves, transmittance walks): one per worker.
#[derive(Debug, Default)]
pub struct Scratch {
    hits: Vec<Hit>,
    /// One receiver's sample directions and their opaque occlusion.
    dirs: Vec<Vec3>,
    occluded: Vec<bool>,
    /// One receiver's candidate leaves ([`Bvh::hull_leaves`]).
    leaves: Vec<(u32, u32)>,
    /// The order samples are traced in ([`PACKET_BLOCK`]), for
    /// `order.len()` samples.
    order: Vec<u32>,
    /// Whether the next receiver skips its segment hull (see
    /// `gsample_bundle`).
    skip_hull: bool,
    /// Whether the next receiver skips the light's hull
    /// ([`ShadowTracer::light_hull`]): set when it kept too many leaves,
    /// cleared by a receiver whose rays find it lit.
    skip_light_hull: bool,
}

/// What [`ShadowTracer::light_hull`] found in the region of a receiver's
/// segments to a whole rect light.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LightHull {
    /// It was not looked at.
    Unknown,
    /// No leaf: every segment is clear.
    Clear,
    /// A few leaves, kept in the scratch space: only they can be hit.
    Few,
    /// More than the hull limit: the rays take their own walks.
    Many,
}

/// A rect light `(center, u, v)` in f64 (exact: the values are f32).
fn rect_f64((c, u, v): (Vec3, Vec3, Vec3)) -> (DVec3, DVec3, DVec3) {
    (c.as_dvec3(), u.as_dvec3(), v.as_dvec3())
}

/// A receiver's rays are traced in blocks of 4 × 2 neighbouring strata
/// ([`Strata::block_order`]), so each packet of eight covers a compact
/// patch of the light rather than a thin row of it (sample order when the
/// grid does not divide). Any order gives the same answers (each ray's
/// result is its own); this only makes packets more coherent (callgrind,
/// 64 samples: spheres −3.4 %, bunny −0.6 %; 256: −3.8 %, −1.7 %).
const PACKET_BLOCK: (u32, u32) = (4, 2);

impl<'a> ShadowTracer<'a> {
    /// Builds both BVHs: casters (`cast_shadows`) whose material is opaque,
    /// and casters whose material is not.
    pub fn new(scene: &'a Scene, geometry: &'a SceneGeometry) -> Self {
        let caster = |t: u32| -> Option<bool> {
            let o = scene
                .objects
                .get(*geometry.triangle_object.get(t as usize)? as usize)?;
            let m = geometry.triangle_material.get(t as usize)?;
            let opaque = scene.materials.get(*m as usize)?.is_opaque();
            o.cast_shadows.then_some(opaque)
        };
        // Each triangle's class once (its object's and material's
        // look-ups), then the builds read one byte a triangle; most scenes
        // have no translucent caster, whose tree is then not built at all.
        const OPAQUE: u8 = 1;
        const TRANSLUCENT: u8 = 2;
        let class: Vec<u8> = (0..geometry.triangles.len() as u32)
            .into_par_iter()
            .map(|t| match caster(t) {
                Some(true) => OPAQUE,
                Some(false) => TRANSLUCENT,
                None => 0,
            })
            .collect();
        let build = |wanted: u8| Bvh::build(geometry, |t| class[t as usize] == wanted);
        let (opaque, translucent) = if class.contains(&TRANSLUCENT) {
            rayon::join(|| build(OPAQUE), || build(TRANSLUCENT))
        } else {
            (build(OPAQUE), Bvh::default())
        };
        let d = scene_diagonal(scene, geometry);
        ShadowTracer {
            scene,
            geometry,
            opaque,
            translucent,
            origin: ShadowOrigin::new(scene, geometry),
            merge: MERGE_SCENE * d,
            hull_limit: HULL_LIMIT,
        }
    }

    /// Sets how many candidate leaves a receiver's segment hull may keep
    /// before its rays take the whole BVH walk ([`Bvh::occluded_hull`]);
    /// 0 turns the hull cull off. Every setting gives the same bits: only
    /// the time changes.
    pub fn with_hull_limit(mut self, limit: usize) -> Self {
        self.hull_limit = limit;
        self
    }

    /// The BVH of opaque casters.
    pub fn opaque_bvh(&self) -> &Bvh {
        &self.opaque
    }

    /// The BVH of non-opaque casters.
    pub fn translucent_bvh(&self) -> &Bvh {
        &self.translucent
    }

    /// The shadow-ray offset at `p`: `max(1e-6 × D, 1e-5 × max_i |p_i|)`.
    pub fn epsilon(&self, p: Vec3) -> f64 {
        self.origin.epsilon(p)
    }

    /// The shadow-ray origin for receiver `p` with geometric normal `ng`
    /// (facing the viewer): `p + ε_p n_g`.
    pub fn shadow_origin(&self, p: Vec3, ng: Vec3) -> Vec3 {
        self.origin.of(p, ng)
    }

    /// Transmittance `Π (1 − opacity)` of the non-opaque casters crossed
    /// at `t ∈ (0, t_max)` on `origin + t · dir`, crossings closer than
    /// `MERGE_SCENE × D` counting once (the first in `(t, triangle)` order).
    /// Opaque casters are ignored. 1 when nothing is crossed.
    pub fn transmittance(&self, origin: Vec3, dir: Vec3, t_max: f32) -> f64 {
        self.walk(origin, dir, t_max, &mut Scratch::default())
    }

    /// `V·T` of the segment from `origin` to `x` (the contract's product
    /// for one light sample, the segment shortened by `END_SHORTEN`), and
    /// the BVH traversals it took.
    pub fn segment(&self, origin: Vec3, x: Vec3) -> (f64, u64) {
        self.segment_with(origin, x, &mut Scratch::default())
    }

    fn segment_with(&self, origin: Vec3, x: Vec3, scratch: &mut Scratch) -> (f64, u64) {
        let dir = (x.as_dvec3() - origin.as_dvec3()).as_vec3();
        // The direction is not normalised, so the segment is t ∈ (0, 1).
        let t_max = (1.0 - END_SHORTEN) as f32;
        if self.opaque.occluded(origin, dir, t_max) {
            return (0.0, 1);
        }
        if self.translucent.triangle_count() == 0 {
            return (1.0, 1);
        }
        (self.walk(origin, dir, t_max, scratch), 2)
    }

    /// The transmittance walk: every crossing, sorted, merged, multiplied.
    fn walk(&self, origin: Vec3, dir: Vec3, t_max: f32, scratch: &mut Scratch) -> f64 {
        let hits = &mut scratch.hits;
        hits.clear();
        self.translucent
            .for_each_hit(origin, dir, t_max, |h| hits.push(h));
        if hits.is_empty() {
            return 1.0;
        }
        // Sorting by (t, triangle) fixes which of several merged crossings
        // gives the opacity, whatever the traversal order.
        hits.sort_unstable_by(|a, b| a.t.total_cmp(&b.t).then(a.triangle.cmp(&b.triangle)));
        let len = f64::from(dir.length());
        let merge_t = if len > 0.0 { self.merge / len } else { 0.0 };
        let mut transmittance = 1.0f64;
        let mut next = f64::NEG_INFINITY;
        for h in hits.iter() {
            let t = f64::from(h.t);
            if t < next {
                continue;
            }
            transmittance *= 1.0 - self.opacity(h);
            if transmittance <= 0.0 {
                return 0.0;
            }
            next = t + merge_t;
        }
        transmittance
    }

    /// Opacity `d × map_d(uv)` at a hit, clamped to `[0, 1]` (public so
    /// that other techniques' look-ups can be checked against it).
    pub fn opacity(&self, h: &Hit) -> f64 {
        let tri = h.triangle as usize;
        let Some(m) = self
            .geometry
            .triangle_material
            .get(tri)
            .and_then(|&m| self.scene.materials.get(m as usize))
        else {
            return 1.0;
        };
        let texture = m.opacity_texture.and_then(|t| self.scene.textures.get(t));
        let tex = texture.map_or(1.0, |t| t.lookup_scalar(self.hit_uv(h)));
        f64::from(m.opacity * tex).clamp(0.0, 1.0)
    }

    /// Texture coordinates at a hit, interpolated (in f64) from the
    /// object's mesh uvs like the G-buffer does; 0 without uvs.
    fn hit_uv(&self, h: &Hit) -> Vec2 {
        let uv = || -> Option<Vec2> {
            let (o, local) = self.geometry.locate(h.triangle);
            let mesh = &self.scene.objects.get(o)?.mesh;
            let uvs = mesh.uvs.as_ref()?;
            let [i, j, k] = mesh.triangles.get(local)?;
            let (i, j, k) = (
                uvs.get(*i as usize)?.as_dvec2(),
                uvs.get(*j as usize)?.as_dvec2(),
                uvs.get(*k as usize)?.as_dvec2(),
            );
            let (b1, b2) = (f64::from(h.b1), f64::from(h.b2));
            Some((i * (1.0 - b1 - b2) + j * b1 + k * b2).as_vec2())
        };
        uv().unwrap_or(Vec2::ZERO)
    }

    /// Whether `g`'s object receives shadows (unknown objects do).
    fn receives(&self, g: &GSample) -> bool {
        self.scene
            .objects
            .get(g.object as usize)
            .is_none_or(|o| o.receive_shadows)
    }

    /// Per-sample `V·T` at shading point `g` for the given light samples,
    /// written to `out` (as many as both slices hold): 0 for a background
    /// pixel, 1 for a receiver with `receive_shadows = false`. The
    /// reference's own per-sample values, for checking other techniques
    /// sample by sample.
    pub fn sample_visibility(&self, g: &GSample, samples: &[LightSample], out: &mut [f32]) {
        let mut scratch = Scratch::default();
        let n = samples.len().min(out.len());
        let mut vt = Vec::with_capacity(n);
        self.gsample_bundle(
            g,
            &samples[..n],
            None,
            &mut vt,
            &mut scratch,
            LightHull::Unknown,
        );
        for (o, v) in out.iter_mut().zip(vt) {
            *o = v as f32;
        }
    }

    /// `V·T` from shading point `g` to each sample (into `out`, cleared
    /// first) and the traversals it took: the values of
    /// [`ShadowTracer::segment`] per sample, the opaque test done for all
    /// samples together by [`Bvh::occluded_bundle`] (same bits as one
    /// ray at a time; the rays share their origin, which makes them
    /// coherent).
    ///
    /// `rect` is the light's parallelogram `(center, u, v)` when the
    /// samples come from a rect light: the segments' pyramid then culls
    /// the tree first ([`Bvh::occluded_hull`], same bits). `known` is what
    /// [`ShadowTracer::light_hull`] found for this receiver and light
    /// (with this `scratch` since), or [`LightHull::Unknown`]: with
    /// [`LightHull::Few`] the rays are tested against the leaves it kept
    /// only, with [`LightHull::Many`] they take their walks without a hull
    /// of their own, with [`LightHull::Clear`] none is traced; the same
    /// answers in each case (the light's hull holds every segment). With
    /// the caller's `scratch`, for callers that trace many receivers.
    pub fn gsample_bundle(
        &self,
        g: &GSample,
        samples: &[LightSample],
        rect: Option<(Vec3, Vec3, Vec3)>,
        out: &mut Vec<f64>,
        scratch: &mut Scratch,
        known: LightHull,
    ) -> u64 {
        #[cfg(target_arch = "x86_64")]
        if runs_v3() {
            // SAFETY: the CPU has every feature the v3 copy enables
            // (`runs_v3` checks them), its one requirement.
            return unsafe { self.gsample_bundle_v3(g, samples, rect, out, scratch, known) };
        }
        self.gsample_bundle_body(g, samples, rect, out, scratch, known)
    }

    /// [`ShadowTracer::gsample_bundle_body`] compiled for `Level::V3`
    /// (`simd::level`): the per-sample directions and the segment hull's
    /// bounds; the walks dispatch on their own.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx,avx2,bmi1,bmi2,lzcnt,popcnt")]
    fn gsample_bundle_v3(
        &self,
        g: &GSample,
        samples: &[LightSample],
        rect: Option<(Vec3, Vec3, Vec3)>,
        out: &mut Vec<f64>,
        scratch: &mut Scratch,
        known: LightHull,
    ) -> u64 {
        self.gsample_bundle_body(g, samples, rect, out, scratch, known)
    }

    /// [`ShadowTracer::gsample_bundle`] itself, inlined into each level's
    /// copy.
    #[inline(always)]
    fn gsample_bundle_body(
        &self,
        g: &GSample,
        samples: &[LightSample],
        rect: Option<(Vec3, Vec3, Vec3)>,
        out: &mut Vec<f64>,
        scratch: &mut Scratch,
        known: LightHull,
    ) -> u64 {
        out.clear();
        if !g.is_surface() || !self.receives(g) {
            let v = if g.is_surface() { 1.0 } else { 0.0 };
            out.resize(samples.len(), v);
            return 0;
        }
        let origin = self.shadow_origin(g.position, g.geo_normal);
        let t_max = (1.0 - END_SHORTEN) as f32;
        let mut dirs = std::mem::take(&mut scratch.dirs);
        let mut occluded = std::mem::take(&mut scratch.occluded);
        let mut order = std::mem::take(&mut scratch.order);
        if order.len() != samples.len() {
            let (w, h) = PACKET_BLOCK;
            Strata::new(samples.len() as u32).block_order(w, h, &mut order);
        }
        dirs.clear();
        dirs.extend(
            order
                .iter()
                .map(|&k| (samples[k as usize].x.as_dvec3() - origin.as_dvec3()).as_vec3()),
        );
        occluded.resize(dirs.len(), false);
        match known {
            LightHull::Clear => occluded.fill(false),
            LightHull::Few => self.opaque.occluded_leaves(
                origin,
                &dirs,
                t_max,
                &mut occluded,
                &mut scratch.leaves,
            ),
            LightHull::Many => self
                .opaque
                .occluded_bundle(origin, &dirs, t_max, &mut occluded),
            LightHull::Unknown => {
                self.receiver_hull_walk(g, origin, rect, &dirs, t_max, &mut occluded, scratch)
            }
        }
        // A receiver its rays find lit has the next one try the light's
        // hull again (`light_hull`).
        if !occluded.iter().any(|&o| o) {
            scratch.skip_light_hull = false;
        }
        out.resize(samples.len(), 0.0);
        let rays = if self.translucent.triangle_count() == 0 {
            // Opaque casters only: `V` is the test's answer, written
            // without a branch (in a penumbra the answers alternate, and
            // the mispredictions cost more than the whole loop).
            for (&blocked, &k) in occluded.iter().zip(&order) {
                out[k as usize] = f64::from(u8::from(!blocked));
            }
            dirs.len() as u64
        } else {
            // A clear segment also walks the non-opaque casters.
            let mut rays = 0;
            for ((&dir, &blocked), &k) in dirs.iter().zip(&occluded).zip(&order) {
                out[k as usize] = if blocked {
                    rays += 1;
                    0.0
                } else {
                    rays += 2;
                    self.walk(origin, dir, t_max, scratch)
                };
            }
            rays
        };
        scratch.dirs = dirs;
        scratch.occluded = occluded;
        scratch.order = order;
        rays
    }

    /// The rays' answers into `occluded` by the receiver's own segment
    /// hull (built from its drawn directions) or their walks, when the
    /// light's hull was not looked at.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn receiver_hull_walk(
        &self,
        g: &GSample,
        origin: Vec3,
        rect: Option<(Vec3, Vec3, Vec3)>,
        dirs: &[Vec3],
        t_max: f32,
        occluded: &mut [bool],
        scratch: &mut Scratch,
    ) {
        // A receiver after one whose hull kept too many leaves, or whose
        // rays (taking the whole walk) found an occluder, skips its hull:
        // receivers in shadow come in runs, and for them building the
        // hull and walking it only to give up is wasted (callgrind, light
        // pass at 256², 64 samples: spheres −7.1 %, bunny −4.4 %). A lit
        // receiver, or one whose hull culled, has the next one try again.
        // Same bits either way: only the time changes.
        let hull = if self.hull_limit > 0 && !scratch.skip_hull {
            // The receiver's own surface is behind its tangent plane: culls
            // its facet and the neighbours curving away (callgrind: −6 %
            // instructions on spheres and bunny).
            SegmentHull::new(origin, dirs, rect.map(rect_f64), Some(g.geo_normal))
        } else {
            None
        };
        match hull {
            Some(hull) => {
                let culled = self.opaque.occluded_hull(
                    &hull,
                    dirs,
                    t_max,
                    occluded,
                    &mut scratch.leaves,
                    self.hull_limit,
                );
                scratch.skip_hull = !culled;
            }
            None => {
                self.opaque.occluded_bundle(origin, dirs, t_max, occluded);
                scratch.skip_hull = occluded.iter().any(|&o| o);
            }
        }
    }

    /// What the tree holds in the region of every shadow segment from
    /// `g` to the rect light `rect` `(center, u, v)`, found before any
    /// sample is drawn ([`SegmentHull::over_light`]: it holds the segments
    /// of any sample set of that light): no leaf ([`LightHull::Clear`]:
    /// [`ShadowTracer::gsample_bundle`] would find every sample visible),
    /// at most the hull limit of them (kept in `scratch`, for
    /// [`ShadowTracer::gsample_bundle`]), or more; then the next receivers
    /// skip this walk ([`LightHull::Unknown`]) until one is found lit: in
    /// a run of shadowed receivers it is wasted.
    /// [`LightHull::Unknown`] when it cannot tell that way: not a surface,
    /// not a receiver, non-opaque casters (whose walk this does not
    /// cover), or no hulls (`with_hull_limit(0)`).
    pub fn light_hull(
        &self,
        g: &GSample,
        rect: (Vec3, Vec3, Vec3),
        scratch: &mut Scratch,
    ) -> LightHull {
        if scratch.skip_light_hull
            || !g.is_surface()
            || !self.receives(g)
            || self.translucent.triangle_count() > 0
            || self.hull_limit == 0
        {
            return LightHull::Unknown;
        }
        let origin = self.shadow_origin(g.position, g.geo_normal);
        let Some(hull) = SegmentHull::over_light(origin, rect_f64(rect), Some(g.geo_normal)) else {
            return LightHull::Unknown;
        };
        #[cfg(target_arch = "x86_64")]
        let few = if runs_v3() {
            // SAFETY: the CPU has every feature the v3 copy enables
            // (`runs_v3` checks them), its one requirement.
            unsafe { self.light_leaves_v3(&hull, scratch) }
        } else {
            self.light_leaves_body(&hull, scratch)
        };
        #[cfg(not(target_arch = "x86_64"))]
        let few = self.light_leaves_body(&hull, scratch);
        match (few, scratch.leaves.is_empty()) {
            (true, true) => LightHull::Clear,
            (true, false) => LightHull::Few,
            (false, _) => {
                scratch.skip_light_hull = true;
                LightHull::Many
            }
        }
    }

    /// [`ShadowTracer::light_leaves_body`] compiled for `Level::V3`.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx,avx2,bmi1,bmi2,lzcnt,popcnt")]
    fn light_leaves_v3(&self, hull: &SegmentHull, scratch: &mut Scratch) -> bool {
        self.light_leaves_body(hull, scratch)
    }

    #[inline(always)]
    fn light_leaves_body(&self, hull: &SegmentHull, scratch: &mut Scratch) -> bool {
        self.opaque
            .hull_leaves(hull, &mut scratch.leaves, self.hull_limit)
    }

    /// Hard-shadow visibility from light `light`'s centre (a sphere light:
    /// its centre) per pixel: 1 or 0 by the opaque casters only (the
    /// contract's binary `V`; non-opaque casters are not counted), 0 for
    /// background, 1 for non-receivers. Empty for a light index out of
    /// range.
    pub fn hard_visibility(&self, gbuffer: &GBuffer, light: usize) -> Vec<f32> {
        let Some(light) = self.scene.lights.get(light) else {
            return Vec::new();
        };
        let centre = match light.shape {
            LightShape::Rect { center, .. } | LightShape::Sphere { center, .. } => center,
        };
        gbuffer
            .par_samples()
            .map(|g| {
                if !g.is_surface() {
                    0.0
                } else if !self.receives(&g) {
                    1.0
                } else {
                    let o = self.shadow_origin(g.position, g.geo_normal);
                    let dir = (centre.as_dvec3() - o.as_dvec3()).as_vec3();
                    let blocked = self.opaque.occluded(o, dir, (1.0 - END_SHORTEN) as f32);
                    if blocked {
                        0.0
                    } else {
                        1.0
                    }
                }
            })
            .collect()
    }
}
