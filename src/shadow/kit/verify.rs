//! `--verify K`: an exactness certificate. `K` (pixel, light, sample)
//! relations, drawn by a generator keyed by the render's seed, are re-cast
//! with the reference's shadow rays ([`ShadowTracer::sample_visibility`]:
//! the same origin rule, through the sample positions the technique itself
//! used) and compared with the technique's own per-sample decision.
//!
//! A technique exposes its decisions through
//! [`ShadowTechnique::sample_decisions`](crate::shadow::ShadowTechnique::sample_decisions)
//! ([`SampleDecisions`]); one without them is refused by name.
//!
//! **Tie distance.** For a disagreement, with `o` the shadow-ray origin
//! and `x` the sample, the tie distance is
//! `min over the edges e of every shadow-casting triangle of
//! dist(segment o→x, segment e) / |x − o|`: the world-space distance
//! between the two segments relative to the ray's length (for a nearby
//! edge, about the angle in radians under which the ray misses the edge,
//! seen from the receiver). A disagreement at most [`TIE_DISTANCE`] from
//! an edge is a tie (the rasterizer, the f32 chart and the ray tracer
//! round differently there); one farther is an error.

use super::rays::ShadowTracer;
use crate::error::{Error, Result};
use crate::sampling::{mix64, SplitMix64, GOLDEN};
use crate::shadow::technique::{SampleDecisions, ShadowContext};
use glam::DVec3;
use rayon::prelude::*;
use serde::Serialize;
use std::fmt;

/// Largest tie distance (relative, see the module docs) a disagreement may
/// have: a few hundred f32 ulps of the ray's length.
pub const TIE_DISTANCE: f64 = 1e-4;

/// Two visibilities (`V·T`, in `[0, 1]`) closer than this agree: the
/// reference stores f32, and products of semi-opaque layers may round in a
/// different order.
pub const VALUE_TOLERANCE: f64 = 1e-5;

/// One disagreement.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Disagreement {
    /// Pixel `(x, y)`.
    pub pixel: (u32, u32),
    /// Light index.
    pub light: usize,
    /// Sample index (the technique's order).
    pub sample: usize,
    /// The technique's visibility.
    pub ours: f64,
    /// The shadow ray's.
    pub reference: f64,
    /// Its tie distance (module docs).
    pub tie_distance: f64,
    /// The ray crosses an opacity-textured caster (an S-triangle).
    pub textured: bool,
}

/// What `--verify` found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct VerifyReport {
    /// The technique.
    pub technique: String,
    /// Whether it declares itself exact with these options.
    pub declared_exact: bool,
    /// Relations asked for (`K`).
    pub requested: u64,
    /// Relations checked (those on pixels without samples are skipped).
    pub checked: u64,
    /// Relations the shadow ray sees (partly) blocked: how much shadow
    /// the check saw.
    pub blocked: u64,
    /// Relations whose visibility differs from the shadow ray's.
    pub disagreements: u64,
    /// Disagreements farther than [`TIE_DISTANCE`] from every edge, on
    /// rays that cross no opacity-textured caster: the errors.
    pub beyond_tie: u64,
    /// Disagreements farther than [`TIE_DISTANCE`] from every edge on rays
    /// that cross an opacity-textured caster: a look-up at a texel border
    /// is a tie the edge distance cannot see, so these are reported, not
    /// certified (and not errors).
    pub textured: u64,
    /// The largest tie distance among the disagreements (0 without any).
    pub max_tie_distance: f64,
    /// The tie distance allowed.
    pub tie_limit: f64,
    /// The disagreement of largest tie distance.
    pub worst: Option<Disagreement>,
}

impl VerifyReport {
    /// Disagreements per relation checked.
    pub fn rate(&self) -> f64 {
        if self.checked == 0 {
            0.0
        } else {
            self.disagreements as f64 / self.checked as f64
        }
    }

    /// No disagreement beyond the tie distance.
    pub fn passed(&self) -> bool {
        self.beyond_tie == 0
    }

    /// Short form for tables: `disagreements/checked, max tie distance`.
    pub fn cell(&self) -> String {
        format!(
            "{}/{} ({}), max tie {}",
            self.disagreements,
            self.checked,
            self.beyond_tie,
            short(self.max_tie_distance)
        )
    }

    /// `Ok` when it passed, else an error naming the worst disagreement.
    pub fn check(&self) -> Result<()> {
        if self.passed() {
            return Ok(());
        }
        let worst = self
            .worst
            .map(|w| {
                format!(
                    "; worst: pixel ({}, {}), light {}, sample {}: {} says {:.3}, the shadow ray {:.3}, \
                     {:.2e} from the nearest edge",
                    w.pixel.0, w.pixel.1, w.light, w.sample, self.technique, w.ours, w.reference,
                    w.tie_distance
                )
            })
            .unwrap_or_default();
        Err(Error::param(
            "--verify",
            format!(
                "`{}` is not exact here: {} of {} relations disagree with the shadow rays farther \
                 than the tie distance {:.0e}{}{worst}",
                self.technique,
                self.beyond_tie,
                self.checked,
                self.tie_limit,
                if self.declared_exact {
                    ""
                } else {
                    " (it declares itself approximate with these options)"
                }
            ),
        ))
    }
}

impl fmt::Display for VerifyReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "verify {}: {} relations checked ({} in shadow), {} disagreements (rate {}), {} beyond the tie \
             distance {:.0e}{}; largest tie distance {}",
            self.technique,
            self.checked,
            self.blocked,
            self.disagreements,
            short(self.rate()),
            self.beyond_tie,
            self.tie_limit,
            if self.textured > 0 {
                format!(
                    " (and {} at opacity-textured casters: texel-border ties, not certified)",
                    self.textured
                )
            } else {
                String::new()
            },
            short(self.max_tie_distance)
        )
    }
}

/// `0`, or three significant digits in scientific notation.
fn short(x: f64) -> String {
    if x == 0.0 {
        "0".into()
    } else {
        format!("{x:.2e}")
    }
}

/// Most relations one `--verify K` draws (they are held in memory).
pub const MAX_RELATIONS: u64 = 10_000_000;

/// `--verify all`: every relation of every receiving pixel, checked in
/// chunks of pixels (so memory stays bounded), instead of `K` drawn ones.
pub const EVERY_RELATION: u64 = u64::MAX;

/// Parses `--verify`'s value: a count `K` or `all` ([`EVERY_RELATION`]).
pub fn parse_amount(s: &str) -> std::result::Result<u64, String> {
    if s.eq_ignore_ascii_case("all") {
        return Ok(EVERY_RELATION);
    }
    s.parse::<u64>()
        .map_err(|_| format!("`{s}` is neither a number of relations nor `all`"))
}

/// One relation to check.
#[derive(Debug, Clone, Copy)]
struct Relation {
    light: usize,
    pixel: usize,
    /// Uniform in `[0, 1)`: the sample is `⌊u · N⌋` of the pixel's `N`.
    u: f64,
}

/// `k` relations keyed by `seed`: uniformly a light, a receiving surface
/// pixel and a sample, with replacement. Deterministic.
fn relations(ctx: &ShadowContext, k: u64, seed: u64) -> Vec<Relation> {
    let pool = receiving_pixels(ctx);
    let lights = ctx.scene.lights.len();
    if pool.is_empty() || lights == 0 {
        return Vec::new();
    }
    let key = mix64(seed ^ 0x7665_7269_6679_2121);
    // Relation j draws output j of the stream whose first output is
    // `mix64(key)`.
    let mut hashes = SplitMix64::new(key.wrapping_sub(GOLDEN));
    (0..k)
        .map(|_| {
            let h = hashes.next_u64();
            let (h1, h2) = (mix64(h ^ 1), mix64(h ^ 2));
            Relation {
                light: (h % lights as u64) as usize,
                pixel: pool[(h1 % pool.len() as u64) as usize],
                u: (h2 >> 11) as f64 * (1.0 / (1u64 << 53) as f64),
            }
        })
        .collect()
}

/// The surface pixels of shadow receivers, in order.
fn receiving_pixels(ctx: &ShadowContext) -> Vec<usize> {
    let receives = |o: u32| {
        ctx.scene
            .objects
            .get(o as usize)
            .is_none_or(|o| o.receive_shadows)
    };
    (0..ctx.gbuffer.len())
        .filter(|&i| ctx.gbuffer.is_surface(i) && receives(ctx.gbuffer.sample(i).object))
        .collect()
}

/// Distance between segments `p0p1` and `q0q1` (closest points, clamped).
pub fn segment_distance(p0: DVec3, p1: DVec3, q0: DVec3, q1: DVec3) -> f64 {
    let (d1, d2, r) = (p1 - p0, q1 - q0, p0 - q0);
    let (a, e, f) = (d1.dot(d1), d2.dot(d2), d2.dot(r));
    let (c, b) = (d1.dot(r), d1.dot(d2));
    let denom = a * e - b * b;
    let mut s = if denom > 1e-300 {
        ((b * f - c * e) / denom).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let mut t = if e > 0.0 { (b * s + f) / e } else { 0.0 };
    if t < 0.0 {
        t = 0.0;
        s = if a > 0.0 {
            (-c / a).clamp(0.0, 1.0)
        } else {
            0.0
        };
    } else if t > 1.0 {
        t = 1.0;
        s = if a > 0.0 {
            ((b - c) / a).clamp(0.0, 1.0)
        } else {
            0.0
        };
    }
    (p0 + d1 * s).distance(q0 + d2 * t)
}

/// Distance from point `q` to segment `p0p1`.
fn point_segment_distance(q: DVec3, p0: DVec3, p1: DVec3) -> f64 {
    let d = p1 - p0;
    let a = d.dot(d);
    let s = if a > 0.0 {
        ((q - p0).dot(d) / a).clamp(0.0, 1.0)
    } else {
        0.0
    };
    q.distance(p0 + d * s)
}

/// The shadow-casting triangles, with a bounding sphere each (for a lower
/// bound on their edges' distance to a ray).
struct Casters {
    tris: Vec<([DVec3; 3], DVec3, f64)>,
}

impl Casters {
    fn new(ctx: &ShadowContext) -> Casters {
        let g = ctx.geometry;
        let tris = g
            .triangles
            .iter()
            .zip(g.triangle_object.iter())
            .filter(|(_, &o)| {
                ctx.scene
                    .objects
                    .get(o as usize)
                    .is_some_and(|o| o.cast_shadows)
            })
            .map(|(t, _)| {
                let v = t.map(|i| g.positions[i as usize].as_dvec3());
                let c = (v[0] + v[1] + v[2]) / 3.0;
                let r = v.iter().map(|p| p.distance(c)).fold(0.0, f64::max);
                (v, c, r)
            })
            .collect();
        Casters { tris }
    }

    /// The ray `a → b`'s tie distance (module docs).
    fn tie_distance(&self, a: DVec3, b: DVec3) -> f64 {
        let len = a.distance(b);
        let mut best = f64::INFINITY;
        for (v, c, r) in &self.tris {
            if point_segment_distance(*c, a, b) - r >= best {
                continue;
            }
            for j in 0..3 {
                best = best.min(segment_distance(a, b, v[j], v[(j + 1) % 3]));
            }
        }
        if len > 0.0 {
            best / len
        } else {
            best
        }
    }
}

/// Relations per chunk of [`verify_all`]: the chunk's samples and
/// decisions are held at once (~56 bytes a relation).
const ALL_CHUNK_RELATIONS: usize = 1 << 22;

/// Every relation of every receiving surface pixel and light (`samples`
/// per pixel, as the technique was built), in chunks of pixels: each
/// chunk runs the technique's light pass again with its inspector on
/// those pixels, and every sample of every pixel is re-cast.
pub(crate) fn verify_all(
    decisions: &dyn SampleDecisions,
    name: &str,
    declared_exact: bool,
    ctx: &ShadowContext,
    samples: u32,
) -> Result<VerifyReport> {
    let pool = receiving_pixels(ctx);
    let tracer: &ShadowTracer = ctx.cache.tracer();
    let width = ctx.gbuffer.width.max(1) as usize;
    let chunk = (ALL_CHUNK_RELATIONS / samples.max(1) as usize).max(1);
    let (mut checked, mut blocked) = (0u64, 0u64);
    let mut found: Vec<(Relation, usize, f64, f64, DVec3, DVec3)> = Vec::new();
    for light in 0..ctx.scene.lights.len() {
        for pixels in pool.chunks(chunk) {
            let mut answers = decisions.sample_visibility(ctx, light, pixels)?;
            answers.sort_by_key(|p| p.pixel);
            let per_pixel: Vec<(u64, u64, Vec<_>)> = answers
                .par_iter()
                .map(|px| {
                    let n = px.samples.len().min(px.visibility.len());
                    let g = ctx.gbuffer.sample(px.pixel);
                    let mut reference = vec![0.0f32; n];
                    tracer.sample_visibility(&g, &px.samples[..n], &mut reference);
                    let o = tracer.shadow_origin(g.position, g.geo_normal).as_dvec3();
                    let mut bad = Vec::new();
                    for (s, &r) in reference.iter().enumerate() {
                        let (ours, r) = (px.visibility[s], f64::from(r));
                        if (ours - r).abs() > VALUE_TOLERANCE {
                            let relation = Relation {
                                light,
                                pixel: px.pixel,
                                u: 0.0,
                            };
                            bad.push((relation, s, ours, r, o, px.samples[s].x.as_dvec3()));
                        }
                    }
                    let shadowed = reference.iter().filter(|&&r| r < 1.0).count() as u64;
                    (n as u64, shadowed, bad)
                })
                .collect();
            for (n, shadowed, bad) in per_pixel {
                checked += n;
                blocked += shadowed;
                found.extend(bad);
            }
        }
    }
    Ok(report(
        ctx,
        tracer,
        width,
        (name, declared_exact, EVERY_RELATION),
        (checked, blocked),
        found,
    ))
}

/// [`verify`](crate::shadow::verify::verify) with any [`SampleDecisions`] (named `name`, declaring itself
/// exact or not), `k` relations keyed by `seed`.
pub fn verify_with(
    decisions: &dyn SampleDecisions,
    name: &str,
    declared_exact: bool,
    ctx: &ShadowContext,
    k: u64,
    seed: u64,
) -> Result<VerifyReport> {
    let chosen = relations(ctx, k, seed);
    let tracer: &ShadowTracer = ctx.cache.tracer();
    let width = ctx.gbuffer.width.max(1) as usize;
    let (mut checked, mut blocked) = (0u64, 0u64);
    // (relation, sample, ours, reference, origin, sample point)
    let mut found: Vec<(Relation, usize, f64, f64, DVec3, DVec3)> = Vec::new();
    for light in 0..ctx.scene.lights.len() {
        let mine: Vec<Relation> = chosen
            .iter()
            .copied()
            .filter(|r| r.light == light)
            .collect();
        if mine.is_empty() {
            continue;
        }
        let mut pixels: Vec<usize> = mine.iter().map(|r| r.pixel).collect();
        pixels.sort_unstable();
        pixels.dedup();
        let mut answers = decisions.sample_visibility(ctx, light, &pixels)?;
        answers.sort_by_key(|p| p.pixel);
        for r in mine {
            let Ok(a) = answers.binary_search_by_key(&r.pixel, |p| p.pixel) else {
                continue;
            };
            let px = &answers[a];
            let n = px.samples.len().min(px.visibility.len());
            if n == 0 {
                continue;
            }
            let s = ((r.u * n as f64) as usize).min(n - 1);
            let g = ctx.gbuffer.sample(r.pixel);
            let mut reference = [0.0f32];
            tracer.sample_visibility(&g, &px.samples[s..=s], &mut reference);
            let (ours, reference) = (px.visibility[s], f64::from(reference[0]));
            checked += 1;
            blocked += u64::from(reference < 1.0);
            if (ours - reference).abs() > VALUE_TOLERANCE {
                let o = tracer.shadow_origin(g.position, g.geo_normal).as_dvec3();
                found.push((r, s, ours, reference, o, px.samples[s].x.as_dvec3()));
            }
        }
    }
    Ok(report(
        ctx,
        tracer,
        width,
        (name, declared_exact, k),
        (checked, blocked),
        found,
    ))
}

/// The report of the disagreements `found` among `checked` relations
/// (`blocked` of them in shadow by the rays), with their tie distances.
fn report(
    ctx: &ShadowContext,
    tracer: &ShadowTracer,
    width: usize,
    (name, declared_exact, k): (&str, bool, u64),
    (checked, blocked): (u64, u64),
    found: Vec<(Relation, usize, f64, f64, DVec3, DVec3)>,
) -> VerifyReport {
    let casters = Casters::new(ctx);
    let textured = |o: DVec3, x: DVec3| {
        let mut any = false;
        let t_max = (1.0 - super::rays::END_SHORTEN) as f32;
        let (o, dir) = (o.as_vec3(), (x - o).as_vec3());
        tracer.translucent_bvh().for_each_hit(o, dir, t_max, |h| {
            let m = ctx.geometry.triangle_material.get(h.triangle as usize);
            any |= m
                .and_then(|&m| ctx.scene.materials.get(m as usize))
                .is_some_and(|m| m.opacity_texture.is_some());
        });
        any
    };
    let found: Vec<Disagreement> = found
        .par_iter()
        .map(|&(r, s, ours, reference, o, x)| Disagreement {
            pixel: ((r.pixel % width) as u32, (r.pixel / width) as u32),
            light: r.light,
            sample: s,
            ours,
            reference,
            tie_distance: casters.tie_distance(o, x),
            textured: textured(o, x),
        })
        .collect();
    // The first of the largest, in relation order (deterministic), those
    // at no textured caster first: the error to show.
    let worst = found.iter().copied().reduce(|a, b| {
        let better = if a.textured == b.textured {
            b.tie_distance > a.tie_distance
        } else {
            a.textured
        };
        if better {
            b
        } else {
            a
        }
    });
    VerifyReport {
        technique: name.to_string(),
        declared_exact,
        requested: k,
        checked,
        blocked,
        disagreements: found.len() as u64,
        beyond_tie: found
            .iter()
            .filter(|d| !(d.tie_distance <= TIE_DISTANCE) && !d.textured)
            .count() as u64,
        textured: found
            .iter()
            .filter(|d| !(d.tie_distance <= TIE_DISTANCE) && d.textured)
            .count() as u64,
        max_tie_distance: found.iter().map(|d| d.tie_distance).fold(0.0, f64::max),
        tie_limit: TIE_DISTANCE,
        worst,
    }
}
