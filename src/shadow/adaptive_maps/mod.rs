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
        let options = self.options;
        if options.max_depth > MAX_DEPTH {
            return Err(Error::param(
                "--max-depth",
                format!("{} is outside 0..={MAX_DEPTH}", options.max_depth),
            ));
        }
        if !(options.comparison_scale > 0.0 && options.comparison_scale <= 1.0) {
            return Err(Error::param(
                "--comparison-scale",
                format!("{} is outside (0, 1]", options.comparison_scale),
            ));
        }
        let bias = self.maps.bias();
        bias.validate()?;
        for (name, value) in [
            ("--adaptive-band-low", options.adaptive_band_low),
            ("--adaptive-band-high", options.adaptive_band_high),
        ] {
            if !(0.0..=1e3).contains(&value) {
                return Err(Error::param(name, format!("{value} is outside 0..=1000")));
            }
        }
        let mut out = ShadowOutput::default();
        let mut reports = Vec::new();
        let pixels = ctx.gbuffer.len();
        // Nothing casts or nothing receives: every light fully visible.
        let Some((casters, receivers)) = map_bounds(ctx.scene) else {
            return Ok((fully_lit(ctx), reports));
        };
        let mut cache_bytes = 0u64;
        let points = receiver_points(ctx.gbuffer);
        for (light, _) in ctx.scene.lights.iter().enumerate() {
            let timer = PassTimer::start(format!("adaptive maps light {light}"));
            let setup = MapSetup {
                ctx,
                light,
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
            let LightResult {
                vcoef,
                report,
                peak_map_bytes,
                decision_bytes,
            } = self.light(&setup)?;
            cache_bytes = cache_bytes.max(decision_bytes);
            timer.finish_with(&mut out.passes, format!("{} maps", report.rendered));
            out.buffers
                .push(self.light_note(light, &report, peak_map_bytes));
            reports.push(report);
            out.lights.push(LightTerm::Vcoef(vcoef));
        }
        let max_depth = options.max_depth;
        let grid_side = if max_depth >= 1 {
            (1u64 << (max_depth - 1)) + 1
        } else {
            0
        };
        out.buffers.push(BufferNote {
            name: "decision bits".into(),
            detail: format!(
                "hard test bits of the {grid_side}×{grid_side} decision grid per receiver ({} u64 words), the \
                 per-quad 0–4 counts are their sums; one light at a time",
                (grid_side * grid_side).div_ceil(64)
            ),
            bytes: cache_bytes,
        });
        out.buffers.push(BufferNote {
            name: "receiver points".into(),
            detail: "f32 position and geometric normal per pixel, expanded from the G-buffer \
                     once for every map's look-up"
                .into(),
            bytes: pixels as u64 * 24,
        });
        out.buffers.push(BufferNote {
            name: "map accumulators".into(),
            detail: format!(
                "u64 per receiver: Σ ω · round(visibility · {QSCALE}) with integer weights \
                 (exact, order-free); one light at a time"
            ),
            bytes: pixels as u64 * 8,
        });
        out.buffers.push(BufferNote {
            name: "receiver masks".into(),
            detail: "facing the light, comparison texel, probe failure: one byte per pixel each"
                .into(),
            bytes: pixels as u64 * 3,
        });
        Ok((out, reports))
    }

    /// The `--explain` note of one light's maps.
    fn light_note(&self, light: usize, report: &AdaptiveReport, peak_map_bytes: u64) -> BufferNote {
        let per_depth: Vec<String> = report
            .points_per_depth
            .iter()
            .enumerate()
            .filter(|(_, &count)| count > 0)
            .map(|(depth, count)| format!("{count} at depth {depth}"))
            .collect();
        let levels: Vec<String> = report
            .per_depth
            .iter()
            .enumerate()
            .filter(|(_, stats)| stats.tested > 0)
            .map(|(depth, stats)| {
                format!(
                    "depth {depth}: {} of {} split, {} failing receivers",
                    stats.split, stats.tested, stats.fails
                )
            })
            .collect();
        BufferNote {
            name: "shadow maps".into(),
            detail: format!(
                "{} rendered for light {light}: {} sample points in the estimate ({}); {} for \
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
            bytes: peak_map_bytes,
        }
    }

    /// One light: its Vcoef, report, peak map bytes and decision-cache
    /// bytes.
    fn light(&self, setup: &MapSetup) -> Result<LightResult> {
        let options = self.options;
        let ctx = setup.ctx;
        let light = &ctx.scene.lights[setup.light];
        let n = ctx.gbuffer.len();
        let max_depth = options.max_depth;
        let report = AdaptiveReport {
            points_per_depth: vec![0; max_depth as usize + 1],
            per_depth: vec![DepthStats::default(); max_depth as usize],
            ..AdaptiveReport::default()
        };
        let active = active_receivers(ctx.gbuffer, light);
        if !active.iter().any(|&a| a) {
            // No receiver faces the light: no map work, nothing lit.
            return Ok(LightResult {
                vcoef: vec![0.0; n],
                report,
                peak_map_bytes: 0,
                decision_bytes: 0,
            });
        }
        let target = ComparisonTarget::new(ctx, options.comparison_scale);
        let compared = target.compared(&active);
        let mut pass = LightPass {
            options,
            setup,
            side: 1u32 << max_depth,
            target,
            compared,
            decisions: Decisions::new(setup, &active, options),
            report,
            peak_map_bytes: 0,
            probed: vec![false; (((1u32 << max_depth) + 1).pow(2)) as usize],
            probe_lit: Vec::new(),
        };

        let dump_dir = dump::dir();
        let (leaves, quad_log) = pass.subdivide(dump_dir.is_some())?;
        if let (true, Some(dir)) = (pass.decisions.testing, dump_dir) {
            pass.write_dump(&dir, &quad_log)?;
        }
        let depth = pass.point_depths(&leaves);
        let vcoef = pass.estimate(&depth, self.maps.pcf)?;
        Ok(LightResult {
            vcoef,
            decision_bytes: (pass.decisions.bits.len() * 8) as u64,
            report: pass.report,
            peak_map_bytes: pass.peak_map_bytes,
        })
    }
}

/// One light's result of [`AdaptiveMaps::light`].
struct LightResult {
    /// The light's visibility coefficient per pixel.
    vcoef: Vec<f32>,
    /// What the subdivision did.
    report: AdaptiveReport,
    /// Bytes of the largest map rendered (one is resident at a time).
    peak_map_bytes: u64,
    /// Bytes of the decision bits.
    decision_bytes: u64,
}

/// The comparison target: texel `(ci, cj)` reads the nearest pixel.
#[derive(Debug, Clone, Copy)]
struct ComparisonTarget {
    /// Texels per row.
    cw: usize,
    /// Texel rows.
    ch: usize,
    /// The image's width in pixels.
    width: usize,
    /// Its height.
    height: usize,
}

impl ComparisonTarget {
    /// The target of an image scaled by `scale`.
    fn new(ctx: &ShadowContext, scale: f64) -> ComparisonTarget {
        let (width, height) = (ctx.gbuffer.width as usize, ctx.gbuffer.height as usize);
        let cw = ((width as f64 * scale).round() as usize).clamp(1, width.max(1));
        let ch = ((height as f64 * scale).round() as usize).clamp(1, height.max(1));
        ComparisonTarget {
            cw,
            ch,
            width,
            height,
        }
    }

    /// One quad's view of the target.
    fn view<'a>(
        &self,
        words: usize,
        ambiguous: &'a [u64],
        corners: &'a [usize],
        compared: &'a [bool],
    ) -> Comparison<'a> {
        Comparison {
            words,
            ambiguous,
            corners,
            compared,
            cw: self.cw,
            ch: self.ch,
            width: self.width,
            height: self.height,
        }
    }

    /// Per pixel, whether a texel reads it and it is `active`.
    fn compared(&self, active: &[bool]) -> Vec<bool> {
        let mut compared = vec![false; active.len()];
        let grid = self.view(0, &[], &[], &[]);
        for cj in 0..self.ch {
            for ci in 0..self.cw {
                let i = grid.pixel(ci, cj);
                compared[i] = active[i];
            }
        }
        compared
    }
}

/// The decision grid (every other finest point, level D − 1): per point
/// and receiver the hard test bit, and with the bias band whether that
/// test is bias-ambiguous.
struct Decisions<'s, 'a, 'b> {
    setup: &'s MapSetup<'a, 'b>,
    active: &'s [bool],
    /// Whether the subdivision tests quads at all (depth ≥ 1, not
    /// `--adaptive-split-all`).
    testing: bool,
    /// Points per side (0 when not testing).
    side: u32,
    /// u64 words per receiver.
    words: usize,
    /// Hard-test bits, `words` per receiver.
    bits: Vec<u64>,
    /// Bias-ambiguity bits, same layout (empty: no band).
    ambiguous: Vec<u64>,
    /// Setups at the band's low and high bias.
    band_setups: Option<(MapSetup<'a, 'b>, MapSetup<'a, 'b>)>,
    /// Scratch per receiver for the band's low-bias test.
    lit_low: Vec<u8>,
    /// And for its high-bias test.
    lit_high: Vec<u8>,
    /// Per point, whether its bits are set.
    cached: Vec<bool>,
}

impl<'s, 'a, 'b> Decisions<'s, 'a, 'b> {
    fn new(setup: &'s MapSetup<'a, 'b>, active: &'s [bool], options: AdaptiveMapsOptions) -> Self {
        let n = active.len();
        let side = 1u32 << options.max_depth;
        let testing = options.max_depth >= 1 && !options.adaptive_split_all;
        let grid_side = if testing { side / 2 + 1 } else { 0 };
        let words = ((grid_side * grid_side) as usize).div_ceil(64);
        let bits = vec![0u64; if testing { n * words } else { 0 }];
        // The bias band: per decision point and receiver, whether its hard
        // test differs between the band's ends (bias-ambiguous).
        let band = testing && options.adaptive_band_high > 0.0;
        let ambiguous = vec![0u64; if band { n * words } else { 0 }];
        let bias = setup.bias;
        let low = DepthBias {
            constant: bias.constant,
            slope: 0.0,
            normal_offset: bias.normal_offset.min(options.adaptive_band_low),
        };
        let high = DepthBias {
            constant: bias.constant,
            slope: bias.slope.max(options.adaptive_band_high),
            normal_offset: bias.normal_offset.max(options.adaptive_band_high),
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
        Decisions {
            setup,
            active,
            testing,
            side: grid_side,
            words,
            bits,
            ambiguous,
            band_setups,
            lit_low: vec![0u8; if band { n } else { 0 }],
            lit_high: vec![0u8; if band { n } else { 0 }],
            cached: vec![false; (grid_side * grid_side) as usize],
        }
    }

    /// The decision point of finest point `(i, j)`, if it is one.
    #[inline]
    fn index(&self, i: u32, j: u32) -> Option<usize> {
        (self.testing && i.is_multiple_of(2) && j.is_multiple_of(2))
            .then(|| (i / 2 + (j / 2) * self.side) as usize)
    }

    /// Sets decision point `di`'s hard-test bits from `map`, and its
    /// ambiguity bits.
    fn decide(&mut self, map: Option<&RenderedMap>, di: usize) {
        set_bits(self.setup, map, self.active, &mut self.bits, self.words, di);
        if let Some((low, high)) = &self.band_setups {
            set_ambiguous(
                (low, high),
                map,
                self.active,
                (&mut self.lit_low, &mut self.lit_high),
                &mut self.ambiguous,
                self.words,
                di,
            );
        }
    }
}

/// One light's subdivision and estimate in progress.
struct LightPass<'s, 'a, 'b> {
    options: AdaptiveMapsOptions,
    setup: &'s MapSetup<'a, 'b>,
    /// Finest cells per side (`2^D`).
    side: u32,
    target: ComparisonTarget,
    /// Receivers the comparison target reads.
    compared: Vec<bool>,
    decisions: Decisions<'s, 'a, 'b>,
    report: AdaptiveReport,
    /// Bytes of the largest map rendered so far.
    peak_map_bytes: u64,
    /// Finest-grid points whose centre-probe map was rendered but not
    /// kept (last tested level: they are depth-D points).
    probed: Vec<bool>,
    /// Scratch per receiver: the last-level centre probe's hard test.
    probe_lit: Vec<u8>,
}

impl LightPass<'_, '_, '_> {
    /// Finest points per side (`2^D + 1`).
    #[inline]
    fn points_per_side(&self) -> u32 {
        self.side + 1
    }

    /// Finest point `(i, j)` on the light.
    fn point(&self, i: u32, j: u32) -> Vec3 {
        let per_side = self.points_per_side();
        let light = &self.setup.ctx.scene.lights[self.setup.light];
        let unit = (grid_coordinate(i, per_side), grid_coordinate(j, per_side));
        point_on_light(light, unit, self.setup.casters)
    }

    /// Renders the map at finest point `(i, j)`, tracking the peak bytes.
    fn render(&mut self, i: u32, j: u32) -> Result<Option<RenderedMap>> {
        let map = self.setup.render(self.point(i, j))?;
        if let Some(map) = &map {
            self.peak_map_bytes = self.peak_map_bytes.max(map.map.memory_bytes());
        }
        Ok(map)
    }

    /// The subdivision (§3.3), level by level from the whole light: the
    /// leaves, and with `dumping` each tested quad's line of the dump.
    fn subdivide(&mut self, dumping: bool) -> Result<(Vec<Quad>, Vec<String>)> {
        let mut leaves: Vec<Quad> = Vec::new();
        let mut quad_log: Vec<String> = Vec::new();
        if !self.decisions.testing {
            return Ok((leaves, quad_log));
        }
        let mut level = vec![Quad {
            depth: 0,
            i: 0,
            j: 0,
        }];
        self.probe_lit = vec![0u8; self.compared.len()];
        for depth in 0..self.options.max_depth {
            if level.is_empty() {
                break;
            }
            let quad_side = self.side >> depth;
            self.render_new_corners(&level, quad_side)?;
            let mut next = Vec::new();
            for quad in &level {
                let split = self.test_quad(quad, quad_side, dumping.then_some(&mut quad_log))?;
                if split {
                    self.report.splits += 1;
                    self.report.per_depth[depth as usize].split += 1;
                    let half = quad_side / 2;
                    for (di, dj) in [(0, 0), (half, 0), (0, half), (half, half)] {
                        next.push(Quad {
                            depth: depth + 1,
                            i: quad.i + di,
                            j: quad.j + dj,
                        });
                    }
                } else {
                    leaves.push(*quad);
                }
            }
            level = next;
        }
        leaves.extend(level);
        Ok((leaves, quad_log))
    }

    /// Renders the corner maps of `level`'s quads not rendered yet, in a
    /// fixed order, and sets their decision bits.
    fn render_new_corners(&mut self, level: &[Quad], quad_side: u32) -> Result<()> {
        let mut need = BTreeSet::new();
        for quad in level {
            for (i, j) in corners(quad, quad_side) {
                let di =
                    (self.decisions.index(i, j)).expect("corners above depth D are on the grid");
                if !self.decisions.cached[di] {
                    need.insert((j, i));
                }
            }
        }
        for &(j, i) in &need {
            let di = self.decisions.index(i, j).expect("on the grid");
            let map = self.render(i, j)?;
            self.report.test_maps += 1;
            self.decisions.decide(map.as_ref(), di);
            self.decisions.cached[di] = true;
        }
        Ok(())
    }

    /// Tests one quad (its corners' maps rendered): whether it splits.
    /// Counts it in the report and logs it in `quad_log` when dumping.
    fn test_quad(
        &mut self,
        quad: &Quad,
        quad_side: u32,
        quad_log: Option<&mut Vec<String>>,
    ) -> Result<bool> {
        let depth = quad.depth as usize;
        let corner_points: Vec<usize> = corners(quad, quad_side)
            .iter()
            .map(|&(i, j)| self.decisions.index(i, j).expect("on the grid"))
            .collect();
        let grid = self.target.view(
            self.decisions.words,
            &self.decisions.ambiguous,
            &corner_points,
            &self.compared,
        );
        let penumbra_fails = grid.penumbra_fails(&self.decisions.bits);
        let mut split = penumbra_fails > self.options.adaptive_threshold;
        let stats = &mut self.report.per_depth[depth];
        let fails_before = stats.fails;
        stats.tested += 1;
        stats.fails += penumbra_fails;
        // The centre probe, only where the corners alone keep the quad
        // whole.
        if !split && quad.depth < self.options.adaptive_centre_depth {
            let probe_fails = self.centre_probe_fails(quad, quad_side, &corner_points)?;
            self.report.per_depth[depth].fails += probe_fails;
            if penumbra_fails + probe_fails > self.options.adaptive_threshold {
                split = true;
                self.report.probe_splits += 1;
            }
        }
        if let Some(quad_log) = quad_log {
            quad_log.push(format!(
                "[{},{},{},{penumbra_fails},{},{}]",
                quad.depth,
                quad.i / quad_side,
                quad.j / quad_side,
                self.report.per_depth[depth].fails - fails_before - penumbra_fails,
                u8::from(split)
            ));
        }
        Ok(split)
    }

    /// Renders the centre probe of `quad` (corners `corner_points`) and
    /// counts its failures: on the decision grid the map is kept (a corner
    /// of the children), on the last tested level it is a depth-D point
    /// read once.
    fn centre_probe_fails(
        &mut self,
        quad: &Quad,
        quad_side: u32,
        corner_points: &[usize],
    ) -> Result<u64> {
        let (i, j) = (quad.i + quad_side / 2, quad.j + quad_side / 2);
        let words = self.decisions.words;
        Ok(match self.decisions.index(i, j) {
            Some(di) => {
                if !self.decisions.cached[di] {
                    let map = self.render(i, j)?;
                    self.report.probe_maps += 1;
                    self.decisions.decide(map.as_ref(), di);
                    self.decisions.cached[di] = true;
                }
                let bits = &self.decisions.bits;
                let grid = self.target.view(
                    words,
                    &self.decisions.ambiguous,
                    corner_points,
                    &self.compared,
                );
                grid.probe_fails(bits, |p| grid.bit(bits, p, di) == 1)
            }
            None => {
                let map = self.render(i, j)?;
                self.report.probe_maps += 1;
                let per_side = self.points_per_side();
                self.probed[(i + j * per_side) as usize] = true;
                self.probe_lit.fill(0);
                self.setup.consume(
                    map.as_ref(),
                    Pcf::Nearest,
                    &self.compared,
                    &mut self.probe_lit,
                    1,
                    |v, slot| slot[0] = u8::from(v >= 0.5),
                );
                let grid = self.target.view(
                    words,
                    &self.decisions.ambiguous,
                    corner_points,
                    &self.compared,
                );
                let probe_lit = &self.probe_lit;
                grid.probe_fails(&self.decisions.bits, |p| probe_lit[p] == 1)
            }
        })
    }

    /// Writes the `PENUMBRA_ADAPTIVE_DUMP` files: every decision point's
    /// bits, also those the subdivision did not need (not marked cached:
    /// the estimate is unchanged).
    fn write_dump(&mut self, dir: &std::path::Path, quad_log: &[String]) -> Result<()> {
        let per_side = self.points_per_side();
        let grid_side = self.decisions.side;
        let mut all = vec![Vec3::ZERO; (grid_side * grid_side) as usize];
        for j in (0..per_side).step_by(2) {
            for i in (0..per_side).step_by(2) {
                let di = self.decisions.index(i, j).expect("on the grid");
                all[di] = self.point(i, j);
                if !self.decisions.cached[di] {
                    // Not counted in the peak map bytes.
                    let map = self.setup.render(self.point(i, j))?;
                    self.decisions.decide(map.as_ref(), di);
                }
            }
        }
        let options = self.options;
        dump::write_light(
            dir,
            &dump::LightDump {
                light: self.setup.light,
                gbuffer: self.setup.ctx.gbuffer,
                active: self.decisions.active,
                compared: &self.compared,
                target: (self.target.cw, self.target.ch),
                bits: &self.decisions.bits,
                ambiguous: &self.decisions.ambiguous,
                words: self.decisions.words,
                grid: grid_side,
                points: all,
                note: format!(
                    "{{\"max_depth\":{},\"threshold\":{},\"centre_depth\":{},\"quads\":[{}]}}",
                    options.max_depth,
                    options.adaptive_threshold,
                    options.adaptive_centre_depth,
                    quad_log.join(",")
                ),
            },
        )
    }

    /// Each finest point's depth: the deepest leaf it is a corner of (−1:
    /// not a sample point).
    fn point_depths(&self, leaves: &[Quad]) -> Vec<i32> {
        let per_side = self.points_per_side();
        let mut depth = vec![-1i32; (per_side * per_side) as usize];
        if leaves.is_empty() {
            depth.fill(self.options.max_depth as i32);
        }
        for quad in leaves {
            for (i, j) in corners(quad, self.side >> quad.depth) {
                let point_depth = &mut depth[(i + j * per_side) as usize];
                *point_depth = (*point_depth).max(quad.depth as i32);
            }
        }
        depth
    }

    /// The estimate (§3.4.1) over the sample points (`depth` ≥ 0), with
    /// filter `pcf`: the Vcoef per pixel.
    fn estimate(&mut self, depth: &[i32], pcf: Pcf) -> Result<Vec<f32>> {
        let per_side = self.points_per_side();
        let weights = integer_weights(self.options.max_depth);
        let active = self.decisions.active;
        let mut acc = vec![0u64; active.len()];
        let mut total = 0u64;
        // Points whose hard bits are cached (no PCF: the estimate's test is
        // the decision's).
        let mut from_bits: Vec<(usize, u64)> = Vec::new();
        for j in 0..per_side {
            for i in 0..per_side {
                let point_depth = depth[(i + j * per_side) as usize];
                if point_depth < 0 {
                    continue;
                }
                let weight = weights[point_depth as usize];
                total += weight;
                self.report.points += 1;
                self.report.points_per_depth[point_depth as usize] += 1;
                let cached_bits =
                    (self.decisions.index(i, j)).filter(|&di| self.decisions.cached[di]);
                match cached_bits {
                    Some(di) if pcf == Pcf::Nearest => from_bits.push((di, weight)),
                    _ => {
                        let map = self.render(i, j)?;
                        self.setup
                            .consume(map.as_ref(), pcf, active, &mut acc, 1, |v, a| {
                                a[0] += weight * quantize(v);
                            });
                        self.report.rendered += 1;
                        // A tested map (PCF), or a last-level centre probe
                        // that became a corner: rendered before.
                        if cached_bits.is_some() || self.probed[(i + j * per_side) as usize] {
                            self.report.rerendered += 1;
                        }
                    }
                }
            }
        }
        if !from_bits.is_empty() {
            let (bits, words) = (&self.decisions.bits, self.decisions.words);
            acc.par_iter_mut().enumerate().for_each(|(p, a)| {
                if active[p] {
                    for &(di, weight) in &from_bits {
                        *a += weight * QSCALE * ((bits[p * words + di / 64] >> (di % 64)) & 1);
                    }
                }
            });
        }
        self.report.rendered += self.report.test_maps + self.report.probe_maps;
        Ok(acc.iter().map(|&a| resolve(a, total)).collect())
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
