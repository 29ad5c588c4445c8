//! Adaptive light-source sampling (Schwärzler, Mattausch, Scherzer and
//! Wimmer 2012, §3): hard maps at the four corners of a rect light, then a
//! quadtree on the light refined only where the maps' shadows, compared in
//! screen space, are too far apart.
//!
//! Per light:
//!
//! 1. **Subdivision** (§3.3), level by level from the whole light
//!    (depth 0). Every quad under test has its four corner maps (a corner
//!    shared by neighbouring quads, or kept from the parent, is rendered
//!    once). Per receiver of the comparison target the quad's count is the
//!    number of its corners whose hard test shadows it (0–4). A penumbra
//!    receiver (count 1–3) whose 1-ring neighbourhood in the comparison
//!    target holds no different count *fails*: the corners' shadow borders
//!    are more than a texel apart there (banding). A quad with more failing
//!    receivers than `--adaptive-threshold` splits into four; the new
//!    corners get maps. Quads at `--max-depth` are not tested.
//! 2. **Beyond the paper: the centre probe** (on by default for quads of
//!    depth below `--adaptive-centre-depth`, 2; 0 turns it off). An occluder whose shadows from
//!    all four corners miss every receiver (small, close to the light) or
//!    fall between receivers leaves every count at 0 or 4: nothing fails,
//!    the quad never splits and its shadow is lost. A quad the corners do
//!    not split gets one more map at its centre; a receiver whose four
//!    corners agree but whose centre test differs fails as well. The
//!    centre is a corner of the children, so when the quad splits the map
//!    is kept; the probe is limited to shallow quads (at most 1 + 4 maps
//!    at the default) because a probe that does not split is a map the
//!    estimate does not use.
//!    **Beyond the paper: the bias band** (`--adaptive-band-low` 0.5,
//!    `--adaptive-band-high` 4 texels; 0 turns it off). A receiver whose
//!    hard test from one of the quad's corners flips between those biases
//!    cannot fail (it still counts as a neighbour): each corner map has
//!    its own acne and light-leak pattern at its own texel phase, and
//!    those texel-wide patches failed the test on curved self-shadowing
//!    casters (bunny-paper: 268 maps instead of 25; located with the
//!    `PENUMBRA_ADAPTIVE_DUMP` dump, docs/algorithms/adaptive-light-sampling.md).
//! 3. **Estimate** (§3.4.1): every corner of a leaf quad is a sample point
//!    with weight `ω = 1/(2^d + 1)²` (eq. 3), `d` the depth of the deepest
//!    leaf it is a corner of (all points at depth `d`: the `(2^d + 1)²` grid
//!    with equal weights summing to 1), normalised by their sum. The weights
//!    are integers over the common denominator `lcm_d (2^d + 1)²`, so the
//!    accumulation is exact ([`crate::shadow::kit::many_maps`]).
//!
//! Maps are rendered and consumed one at a time. Per receiver: the hard
//! test bits of the decision grid (the `(2^(D−1) + 1)²` points the tests
//! at depths `< D` can use; 81 bits at the default `D = 4`), one `u64`
//! accumulator. Without PCF the estimate reuses those bits, so every map
//! that is tested is rendered once; with PCF the tested maps are rendered
//! again for the filtered estimate (counted in `--explain`), as are the
//! last level's centre probes that became corners.
//!
//! Rect lights only (the paper's quadtree is on the light's rectangle);
//! sphere lights are refused.

use crate::error::{Error, Result};
use crate::sampling::grid_coordinate;
use crate::shadow::kit::light_view::{fully_lit, map_bounds};
use crate::shadow::kit::many_maps::{
    active_receivers, point_on_light, quantize, receiver_points, resolve, MapSetup, RenderedMap,
    QSCALE,
};
use crate::shadow::kit::shadow_maps::{poisson_disk, Pcf};
use crate::shadow::kit::shadow_maps::{DepthBias, ShadowMapOptions};
use crate::shadow::kit::PassTimer;
use crate::shadow::technique::{
    Bands, Capabilities, QualitySetting, Support, TechniqueInfo, TermKind,
};
use crate::shadow::{BufferNote, LightTerm, ShadowContext, ShadowOutput, ShadowTechnique};
use glam::Vec3;
pub use options::{AdaptiveMapsOptions, MAX_DEPTH};
use rayon::prelude::*;
use std::collections::BTreeSet;

pub mod dump;
pub mod options;

/// The adaptive-maps technique.
#[derive(Debug, Clone, Copy)]
pub struct AdaptiveMaps {
    /// Subdivision options.
    pub options: AdaptiveMapsOptions,
    /// Map size, filter and biases.
    pub maps: ShadowMapOptions,
    /// Seed of the Poisson-PCF rotation.
    pub seed: u64,
}

/// Adaptive maps in the technique registry.
pub static TECHNIQUE: TechniqueInfo = TechniqueInfo {
    name: "adaptive-maps",
    summary: "adaptive light-source sampling: corner maps, quadtree split where the corners' shadows band in screen space, centre probe (Schwärzler et al. 2012)",
    module: "shadow/adaptive_maps/",
    page: Some("adaptive-light-sampling.md"),
    capabilities: |_| Capabilities {
        rect_lights: Support::Yes,
        sphere_lights: Support::Refused {
            param: "--technique",
            why: "adaptive-maps subdivides the rect light's rectangle (Schwärzler et al. \
                  2012); for sphere lights use multi-map (fixed points on the sphere) or dcs",
        },
        textured_lights: Support::Ignored(
            "the weights are the subdivision's (eq. 3): the light's radiance texture does \
             not weight the maps (the unshadowed light still uses it)",
        ),
        enclosed_lights: crate::shadow::technique::MAPS_MISS_ENCLOSURE,
        reached_lights: Support::Yes,
        semi_opaque: crate::shadow::technique::MAPS_OPAQUE_ONLY,
        s_triangles: Support::StsvAddOn,
        output: TermKind::Vcoef,
        exact: false,
        exact_image: false,
    },
    quality_settings: |s| {
        let size = s.base.shadow_map.map_size;
        (1..=4u32)
            .map(|d| {
                let mut options = s.base.clone();
                options.adaptive_maps.max_depth = d;
                let most = ((1u32 << d) + 1).pow(2);
                QualitySetting {
                    curve: "adaptive-maps".into(),
                    label: format!("depth ≤ {d} (≤ {most} maps), {size}²"),
                    samples: None,
                    pattern: s.first_pattern(),
                    options,
                }
            })
            .collect()
    },
    build: |p| {
        Box::new(AdaptiveMaps {
            options: p.options.adaptive_maps,
            maps: p.options.shadow_map,
            seed: p.seed,
        })
    },
    bands: Bands::Refused(
        "its refinement tests each pixel's screen-space 1-ring and refines the \
         maps for every receiver it sees, so a band's result depends on the pixels \
         of the whole frame",
    ),
    reads: {
        use crate::shadow::options::OptionGroup::*;
        &[Seed, ShadowMaps, AdaptiveMaps]
    },
    cost: crate::shadow::technique::CostClass::Raster,
};

/// A quad of the light's quadtree, in units of the finest grid (`2^D`
/// cells per side).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Quad {
    depth: u32,
    i: u32,
    j: u32,
}

/// What one light's subdivision did, for `--explain` and the tests.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct AdaptiveReport {
    /// Maps rendered in all (tests, probes and the estimate).
    pub rendered: u32,
    /// Sample points in the estimate.
    pub points: u32,
    /// Sample points per depth `0..=D` (their weight's depth).
    pub points_per_depth: Vec<u32>,
    /// Maps rendered for the subdivision tests (corners).
    pub test_maps: u32,
    /// Centre-probe maps rendered.
    pub probe_maps: u32,
    /// Maps rendered a second time for the estimate (PCF, or last-level
    /// probes that became corners).
    pub rerendered: u32,
    /// Quads that split.
    pub splits: u32,
    /// Quads that split on the centre probe alone.
    pub probe_splits: u32,
    /// Per depth `0..D`: quads tested, quads split, and the failing
    /// receivers summed over the tested quads (the evidence of why a level
    /// split).
    pub per_depth: Vec<DepthStats>,
}

/// One subdivision level's decisions.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DepthStats {
    /// Quads tested at this depth.
    pub tested: u32,
    /// Of those, quads that split.
    pub split: u32,
    /// Failing receivers (banding, plus the probe's), summed over the tested
    /// quads.
    pub fails: u64,
}

/// The common denominator `lcm_{d ≤ D} (2^d + 1)²` and the integer weight
/// `lcm / (2^d + 1)²` of each depth.
fn integer_weights(max_depth: u32) -> Vec<u64> {
    fn gcd(a: u64, b: u64) -> u64 {
        if b == 0 {
            a
        } else {
            gcd(b, a % b)
        }
    }
    let sq = |d: u32| ((1u64 << d) + 1).pow(2);
    let lcm = (0..=max_depth).fold(1u64, |l, d| l / gcd(l, sq(d)) * sq(d));
    (0..=max_depth).map(|d| lcm / sq(d)).collect()
}

impl AdaptiveMaps {
    /// Runs every light, with each light's subdivision report.
    pub fn compute_with_report(
        &self,
        ctx: &ShadowContext,
    ) -> Result<(ShadowOutput, Vec<AdaptiveReport>)> {
        let o = self.options;
        if o.max_depth > MAX_DEPTH {
            return Err(Error::param(
                "--max-depth",
                format!("{} is outside 0..={MAX_DEPTH}", o.max_depth),
            ));
        }
        if !(o.comparison_scale > 0.0 && o.comparison_scale <= 1.0) {
            return Err(Error::param(
                "--comparison-scale",
                format!("{} is outside (0, 1]", o.comparison_scale),
            ));
        }
        let bias = self.maps.bias();
        bias.validate()?;
        for (name, v) in [
            ("--adaptive-band-low", o.adaptive_band_low),
            ("--adaptive-band-high", o.adaptive_band_high),
        ] {
            if !(0.0..=1e3).contains(&v) {
                return Err(Error::param(name, format!("{v} is outside 0..=1000")));
            }
        }
        let mut out = ShadowOutput::default();
        let mut reports = Vec::new();
        let n = ctx.gbuffer.len();
        // Nothing casts or nothing receives: every light fully visible.
        let Some((casters, receivers)) = map_bounds(ctx.scene) else {
            return Ok((fully_lit(ctx), reports));
        };
        let mut cache_bytes = 0u64;
        let points = receiver_points(ctx.gbuffer);
        for (k, _) in ctx.scene.lights.iter().enumerate() {
            let t = PassTimer::start(format!("adaptive maps light {k}"));
            let setup = MapSetup {
                ctx,
                light: k,
                casters,
                receivers,
                size: self.maps.map_size,
                bias,
                seed: self.seed,
                taps: match self.maps.pcf {
                    Pcf::Poisson(m) => poisson_disk(m, 1.5),
                    _ => Vec::new(),
                },
                points: &points,
            };
            let (vcoef, report, peak, cache) = self.light(&setup)?;
            cache_bytes = cache_bytes.max(cache);
            t.finish_with(&mut out.passes, format!("{} maps", report.rendered));
            let per_depth: Vec<String> = report
                .points_per_depth
                .iter()
                .enumerate()
                .filter(|(_, &c)| c > 0)
                .map(|(d, c)| format!("{c} at depth {d}"))
                .collect();
            let levels: Vec<String> = report
                .per_depth
                .iter()
                .enumerate()
                .filter(|(_, s)| s.tested > 0)
                .map(|(d, s)| {
                    format!(
                        "depth {d}: {} of {} split, {} failing receivers",
                        s.split, s.tested, s.fails
                    )
                })
                .collect();
            out.buffers.push(BufferNote {
                name: "shadow maps".into(),
                detail: format!(
                    "{} rendered for light {k}: {} sample points in the estimate ({}); {} for \
                     the tests, {} centre probes, {} rendered again for the estimate; {} quads \
                     split ({} on the centre probe alone; {}); one map resident at a time ({}² \
                     f32 linear depth)",
                    report.rendered,
                    report.points,
                    per_depth.join(", "),
                    report.test_maps,
                    report.probe_maps,
                    report.rerendered,
                    report.splits,
                    report.probe_splits,
                    if levels.is_empty() {
                        "no test".to_string()
                    } else {
                        levels.join("; ")
                    },
                    self.maps.map_size
                ),
                bytes: peak,
            });
            reports.push(report);
            out.lights.push(LightTerm::Vcoef(vcoef));
        }
        let d = self.options.max_depth;
        let g = if d >= 1 { (1u64 << (d - 1)) + 1 } else { 0 };
        out.buffers.push(BufferNote {
            name: "decision bits".into(),
            detail: format!(
                "hard test bits of the {g}×{g} decision grid per receiver ({} u64 words), the \
                 per-quad 0–4 counts are their sums; one light at a time",
                (g * g).div_ceil(64)
            ),
            bytes: cache_bytes,
        });
        out.buffers.push(BufferNote {
            name: "receiver points".into(),
            detail: "f32 position and geometric normal per pixel, expanded from the G-buffer \
                     once for every map's look-up"
                .into(),
            bytes: n as u64 * 24,
        });
        out.buffers.push(BufferNote {
            name: "map accumulators".into(),
            detail: format!(
                "u64 per receiver: Σ ω · round(visibility · {QSCALE}) with integer weights \
                 (exact, order-free); one light at a time"
            ),
            bytes: n as u64 * 8,
        });
        out.buffers.push(BufferNote {
            name: "receiver masks".into(),
            detail: "facing the light, comparison texel, probe failure: one byte per pixel each"
                .into(),
            bytes: n as u64 * 3,
        });
        Ok((out, reports))
    }

    /// One light: its Vcoef, report, peak map bytes and decision-cache
    /// bytes.
    fn light(&self, setup: &MapSetup) -> Result<(Vec<f32>, AdaptiveReport, u64, u64)> {
        let o = self.options;
        let ctx = setup.ctx;
        let light = &ctx.scene.lights[setup.light];
        let n = ctx.gbuffer.len();
        let (width, height) = (ctx.gbuffer.width as usize, ctx.gbuffer.height as usize);
        let dmax = o.max_depth;
        let side = 1u32 << dmax;
        let g = side + 1;
        let unit = |i: u32, j: u32| (grid_coordinate(i, g), grid_coordinate(j, g));
        let point = |i: u32, j: u32| point_on_light(light, unit(i, j), setup.casters);
        let mut report = AdaptiveReport {
            points_per_depth: vec![0; dmax as usize + 1],
            per_depth: vec![DepthStats::default(); dmax as usize],
            ..AdaptiveReport::default()
        };
        let active = active_receivers(ctx.gbuffer, light);
        if !active.iter().any(|&a| a) {
            // No receiver faces the light: no map work, nothing lit.
            return Ok((vec![0.0; n], report, 0, 0));
        }
        let mut peak = 0u64;
        let mut track = |m: &Option<RenderedMap>| {
            if let Some(m) = m {
                peak = peak.max(m.map.memory_bytes());
            }
        };

        // The comparison target: texel (ci, cj) reads the nearest pixel.
        let cw = ((width as f64 * o.comparison_scale).round() as usize).clamp(1, width.max(1));
        let ch = ((height as f64 * o.comparison_scale).round() as usize).clamp(1, height.max(1));
        let mut compared = vec![false; n];
        {
            let grid = Comparison {
                words: 0,
                ambiguous: &[],
                corners: &[],
                compared: &[],
                cw,
                ch,
                width,
                height,
            };
            for cj in 0..ch {
                for ci in 0..cw {
                    let i = grid.pixel(ci, cj);
                    compared[i] = active[i];
                }
            }
        }

        // Decision grid: every other finest point (level D − 1).
        let testing = dmax >= 1 && !o.adaptive_split_all;
        let gd = if testing { side / 2 + 1 } else { 0 };
        let words = ((gd * gd) as usize).div_ceil(64);
        let dec = |i: u32, j: u32| -> Option<usize> {
            (testing && i.is_multiple_of(2) && j.is_multiple_of(2))
                .then(|| (i / 2 + (j / 2) * gd) as usize)
        };
        let mut bits = vec![0u64; if testing { n * words } else { 0 }];
        // The bias band: per decision point and receiver, whether its hard
        // test differs between the band's ends (bias-ambiguous).
        let band = testing && o.adaptive_band_high > 0.0;
        let mut ambiguous = vec![0u64; if band { n * words } else { 0 }];
        let b = setup.bias;
        let low = DepthBias {
            constant: b.constant,
            slope: 0.0,
            normal_offset: b.normal_offset.min(o.adaptive_band_low),
        };
        let high = DepthBias {
            constant: b.constant,
            slope: b.slope.max(o.adaptive_band_high),
            normal_offset: b.normal_offset.max(o.adaptive_band_high),
        };
        let band_setups = band.then(|| {
            let with = |bias: DepthBias| MapSetup {
                ctx: setup.ctx,
                light: setup.light,
                casters: setup.casters,
                receivers: setup.receivers,
                size: setup.size,
                bias,
                seed: setup.seed,
                taps: Vec::new(),
                points: setup.points,
            };
            (with(low), with(high))
        });
        let mut lit_low = vec![0u8; if band { n } else { 0 }];
        let mut lit_high = vec![0u8; if band { n } else { 0 }];
        // Hard-test bits of a decision point, and its ambiguity bits.
        let mut decide =
            |map: Option<&RenderedMap>, bits: &mut [u64], ambiguous: &mut [u64], di: usize| {
                set_bits(setup, map, &active, bits, words, di);
                if let Some((lo, hi)) = &band_setups {
                    set_ambiguous(
                        (lo, hi),
                        map,
                        &active,
                        (&mut lit_low, &mut lit_high),
                        ambiguous,
                        words,
                        di,
                    );
                }
            };
        let mut cached = vec![false; (gd * gd) as usize];

        let mut leaves: Vec<Quad> = Vec::new();
        let dump_dir = dump::dir();
        let dumping = dump_dir.is_some();
        let mut quad_log: Vec<String> = Vec::new();
        // Finest-grid points whose centre-probe map was rendered but not
        // kept (last tested level: they are depth-D points).
        let mut probed = vec![false; (g * g) as usize];
        if testing {
            let mut level = vec![Quad {
                depth: 0,
                i: 0,
                j: 0,
            }];
            let mut probe_lit = vec![0u8; n];
            for d in 0..dmax {
                if level.is_empty() {
                    break;
                }
                let s = side >> d;
                // Corner maps not rendered yet, in a fixed order.
                let mut need = BTreeSet::new();
                for q in &level {
                    for (i, j) in corners(q, s) {
                        let di = dec(i, j).expect("corners above depth D are on the grid");
                        if !cached[di] {
                            need.insert((j, i));
                        }
                    }
                }
                for &(j, i) in &need {
                    let di = dec(i, j).expect("on the grid");
                    let map = setup.render(point(i, j))?;
                    track(&map);
                    report.test_maps += 1;
                    decide(map.as_ref(), &mut bits, &mut ambiguous, di);
                    cached[di] = true;
                }
                let mut next = Vec::new();
                for q in &level {
                    let c: Vec<usize> = corners(q, s)
                        .iter()
                        .map(|&(i, j)| dec(i, j).expect("on the grid"))
                        .collect();
                    let grid = Comparison {
                        words,
                        ambiguous: &ambiguous,
                        corners: &c,
                        compared: &compared,
                        cw,
                        ch,
                        width,
                        height,
                    };
                    let penumbra_fails = grid.penumbra_fails(&bits);
                    let mut split = penumbra_fails > o.adaptive_threshold;
                    let stats = &mut report.per_depth[d as usize];
                    let fails_before = stats.fails;
                    stats.tested += 1;
                    stats.fails += penumbra_fails;
                    // The centre probe, only where the corners alone keep
                    // the quad whole: on the decision grid it is kept (a
                    // corner of the children), on the last tested level it
                    // is a depth-D point read once.
                    if !split && d < o.adaptive_centre_depth {
                        let (i, j) = (q.i + s / 2, q.j + s / 2);
                        let probe_fails = match dec(i, j) {
                            Some(di) => {
                                if !cached[di] {
                                    let map = setup.render(point(i, j))?;
                                    track(&map);
                                    report.probe_maps += 1;
                                    decide(map.as_ref(), &mut bits, &mut ambiguous, di);
                                    cached[di] = true;
                                }
                                let grid = Comparison {
                                    ambiguous: &ambiguous,
                                    corners: &c,
                                    compared: &compared,
                                    words,
                                    cw,
                                    ch,
                                    width,
                                    height,
                                };
                                grid.probe_fails(&bits, |p| grid.bit(&bits, p, di) == 1)
                            }
                            None => {
                                let map = setup.render(point(i, j))?;
                                track(&map);
                                report.probe_maps += 1;
                                probed[(i + j * g) as usize] = true;
                                probe_lit.fill(0);
                                setup.consume(
                                    map.as_ref(),
                                    Pcf::Nearest,
                                    &compared,
                                    &mut probe_lit,
                                    1,
                                    |v, slot| slot[0] = u8::from(v >= 0.5),
                                );
                                grid.probe_fails(&bits, |p| probe_lit[p] == 1)
                            }
                        };
                        report.per_depth[d as usize].fails += probe_fails;
                        if penumbra_fails + probe_fails > o.adaptive_threshold {
                            split = true;
                            report.probe_splits += 1;
                        }
                    }
                    if dumping {
                        quad_log.push(format!(
                            "[{d},{},{},{penumbra_fails},{},{}]",
                            q.i / s,
                            q.j / s,
                            report.per_depth[d as usize].fails - fails_before - penumbra_fails,
                            u8::from(split)
                        ));
                    }
                    if split {
                        report.splits += 1;
                        report.per_depth[d as usize].split += 1;
                        let h = s / 2;
                        for (di, dj) in [(0, 0), (h, 0), (0, h), (h, h)] {
                            next.push(Quad {
                                depth: d + 1,
                                i: q.i + di,
                                j: q.j + dj,
                            });
                        }
                    } else {
                        leaves.push(*q);
                    }
                }
                level = next;
            }
            leaves.extend(level);
        }
        if let (true, Some(dir)) = (testing, dump_dir) {
            // Every decision point's bits, also those the subdivision did
            // not need (not marked cached: the estimate is unchanged).
            let mut all = vec![Vec3::ZERO; (gd * gd) as usize];
            for j in (0..g).step_by(2) {
                for i in (0..g).step_by(2) {
                    let di = dec(i, j).expect("on the grid");
                    all[di] = point(i, j);
                    if !cached[di] {
                        let map = setup.render(point(i, j))?;
                        decide(map.as_ref(), &mut bits, &mut ambiguous, di);
                    }
                }
            }
            dump::write_light(
                &dir,
                &dump::LightDump {
                    light: setup.light,
                    gbuffer: ctx.gbuffer,
                    active: &active,
                    compared: &compared,
                    target: (cw, ch),
                    bits: &bits,
                    ambiguous: &ambiguous,
                    words,
                    grid: gd,
                    points: all,
                    note: format!(
                        "{{\"max_depth\":{dmax},\"threshold\":{},\"centre_depth\":{},\"quads\":[{}]}}",
                        o.adaptive_threshold,
                        o.adaptive_centre_depth,
                        quad_log.join(",")
                    ),
                },
            )?;
        }

        // Each point's depth: the deepest leaf it is a corner of.
        let mut depth = vec![-1i32; (g * g) as usize];
        if leaves.is_empty() {
            depth.fill(dmax as i32);
        }
        for q in &leaves {
            for (i, j) in corners(q, side >> q.depth) {
                let e = &mut depth[(i + j * g) as usize];
                *e = (*e).max(q.depth as i32);
            }
        }
        let weights = integer_weights(dmax);
        let pcf = self.maps.pcf;
        let mut acc = vec![0u64; n];
        let mut total = 0u64;
        // Points whose hard bits are cached (no PCF: the estimate's test is
        // the decision's).
        let mut from_bits: Vec<(usize, u64)> = Vec::new();
        for j in 0..g {
            for i in 0..g {
                let dp = depth[(i + j * g) as usize];
                if dp < 0 {
                    continue;
                }
                let w = weights[dp as usize];
                total += w;
                report.points += 1;
                report.points_per_depth[dp as usize] += 1;
                let cached_bits = dec(i, j).filter(|&di| cached[di]);
                match cached_bits {
                    Some(di) if pcf == Pcf::Nearest => from_bits.push((di, w)),
                    _ => {
                        let map = setup.render(point(i, j))?;
                        track(&map);
                        setup.consume(map.as_ref(), pcf, &active, &mut acc, 1, |v, a| {
                            a[0] += w * quantize(v);
                        });
                        report.rendered += 1;
                        // A tested map (PCF), or a last-level centre probe
                        // that became a corner: rendered before.
                        if cached_bits.is_some() || probed[(i + j * g) as usize] {
                            report.rerendered += 1;
                        }
                    }
                }
            }
        }
        if !from_bits.is_empty() {
            acc.par_iter_mut().enumerate().for_each(|(p, a)| {
                if active[p] {
                    for &(di, w) in &from_bits {
                        *a += w * QSCALE * ((bits[p * words + di / 64] >> (di % 64)) & 1);
                    }
                }
            });
        }
        report.rendered += report.test_maps + report.probe_maps;
        let vcoef = acc.iter().map(|&a| resolve(a, total)).collect();
        Ok((vcoef, report, peak, (bits.len() * 8) as u64))
    }
}

/// The four corners of `q` (side `s` finest cells).
fn corners(q: &Quad, s: u32) -> [(u32, u32); 4] {
    [
        (q.i, q.j),
        (q.i + s, q.j),
        (q.i, q.j + s),
        (q.i + s, q.j + s),
    ]
}

/// Sets bit `di` of every active receiver the map lights (hard test).
fn set_bits(
    setup: &MapSetup,
    map: Option<&RenderedMap>,
    active: &[bool],
    bits: &mut [u64],
    words: usize,
    di: usize,
) {
    let (w, b) = (di / 64, 1u64 << (di % 64));
    setup.consume(map, Pcf::Nearest, active, bits, words, |v, slot| {
        if v >= 0.5 {
            slot[w] |= b;
        }
    });
}

/// Sets bit `di` of `ambiguous` for every active receiver whose hard test
/// in `map` differs between the bias band's ends (`lo`, `hi`: the setups
/// with those biases; `lit` two byte buffers of scratch).
fn set_ambiguous<'a, 'b>(
    (lo, hi): (&MapSetup<'a, 'b>, &MapSetup<'a, 'b>),
    map: Option<&RenderedMap>,
    active: &[bool],
    (lit_lo, lit_hi): (&mut [u8], &mut [u8]),
    ambiguous: &mut [u64],
    words: usize,
    di: usize,
) {
    for (setup, lit) in [(lo, &mut *lit_lo), (hi, &mut *lit_hi)] {
        lit.fill(0);
        setup.consume(map, Pcf::Nearest, active, lit, 1, |v, slot| {
            slot[0] = u8::from(v >= 0.5)
        });
    }
    let (w, b) = (di / 64, 1u64 << (di % 64));
    ambiguous
        .par_chunks_mut(words)
        .zip(lit_lo.par_iter().zip(lit_hi.par_iter()))
        .for_each(|(slot, (l, h))| {
            if l != h {
                slot[w] |= b;
            }
        });
}

/// One quad's view of the comparison target: per texel the receiver's
/// count of shadowing corners, from the decision bits.
#[derive(Clone, Copy)]
struct Comparison<'a> {
    words: usize,
    /// Bias-ambiguity bits (same layout as the decision bits; empty: no
    /// band).
    ambiguous: &'a [u64],
    corners: &'a [usize],
    compared: &'a [bool],
    cw: usize,
    ch: usize,
    width: usize,
    height: usize,
}

impl Comparison<'_> {
    /// Bit `di` of receiver `p` (1: lit from that point).
    #[inline]
    fn bit(&self, bits: &[u64], p: usize, di: usize) -> u32 {
        ((bits[p * self.words + di / 64] >> (di % 64)) & 1) as u32
    }

    /// Whether receiver `p` can fail this quad's test: read by the
    /// comparison target, and no corner's hard test is bias-ambiguous
    /// (acne or leak). An ambiguous receiver still counts as a neighbour:
    /// leaving it out there would make its penumbra neighbours fail
    /// (measured: spheres-paper 100 → 185 maps).
    #[inline]
    fn tested(&self, p: usize) -> bool {
        self.compared[p]
            && (self.ambiguous.is_empty()
                || self
                    .corners
                    .iter()
                    .all(|&di| (self.ambiguous[p * self.words + di / 64] >> (di % 64)) & 1 == 0))
    }

    /// How many of the quad's corners shadow receiver `p` (0–4).
    #[inline]
    fn count(&self, bits: &[u64], p: usize) -> u32 {
        4 - self
            .corners
            .iter()
            .map(|&di| self.bit(bits, p, di))
            .sum::<u32>()
    }

    /// The pixel comparison texel `(ci, cj)` reads (nearest).
    #[inline]
    fn pixel(&self, ci: usize, cj: usize) -> usize {
        let x =
            (((ci as f64 + 0.5) * self.width as f64 / self.cw as f64) as usize).min(self.width - 1);
        let y = (((cj as f64 + 0.5) * self.height as f64 / self.ch as f64) as usize)
            .min(self.height - 1);
        y * self.width + x
    }

    /// Penumbra texels (count 1–3) whose 1-ring holds no different count
    /// (§3.3.3), bias-ambiguous texels excepted; neighbours that are not
    /// receivers of the light are not looked at.
    fn penumbra_fails(&self, bits: &[u64]) -> u64 {
        (0..self.ch)
            .into_par_iter()
            .map(|cj| {
                let mut fails = 0u64;
                for ci in 0..self.cw {
                    let p = self.pixel(ci, cj);
                    if !self.tested(p) {
                        continue;
                    }
                    let cnt = self.count(bits, p);
                    if cnt == 0 || cnt == 4 {
                        continue;
                    }
                    let mut differs = false;
                    'ring: for dj in -1i64..=1 {
                        for di in -1i64..=1 {
                            let (ni, nj) = (ci as i64 + di, cj as i64 + dj);
                            if (di == 0 && dj == 0)
                                || ni < 0
                                || nj < 0
                                || ni >= self.cw as i64
                                || nj >= self.ch as i64
                            {
                                continue;
                            }
                            let np = self.pixel(ni as usize, nj as usize);
                            if self.compared[np] && self.count(bits, np) != cnt {
                                differs = true;
                                break 'ring;
                            }
                        }
                    }
                    fails += u64::from(!differs);
                }
                fails
            })
            .sum()
    }

    /// Texels whose four corners agree (count 0 or 4) but whose centre
    /// test (`centre_lit`) differs: the centre probe's failures.
    fn probe_fails(&self, bits: &[u64], centre_lit: impl Fn(usize) -> bool + Sync) -> u64 {
        (0..self.ch)
            .into_par_iter()
            .map(|cj| {
                let mut fails = 0u64;
                for ci in 0..self.cw {
                    let p = self.pixel(ci, cj);
                    if !self.tested(p) {
                        continue;
                    }
                    let cnt = self.count(bits, p);
                    if cnt == 0 || cnt == 4 {
                        fails += u64::from((cnt == 0) != centre_lit(p));
                    }
                }
                fails
            })
            .sum()
    }
}

impl ShadowTechnique for AdaptiveMaps {
    fn name(&self) -> &'static str {
        "adaptive-maps"
    }

    fn compute(&self, ctx: &ShadowContext) -> Result<ShadowOutput> {
        Ok(self.compute_with_report(ctx)?.0)
    }
}
