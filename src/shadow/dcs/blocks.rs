//! Samples made only where an edge can change them.
//!
//! A receiver's counters start at `D(O)` and move only on the samples its
//! effective edges cover. With stratified samples on a square grid (the
//! default pattern), the cells are fixed squares of the chart, the same
//! for every receiver: grouped in blocks of whole SIMD lanes, each edge
//! rules out by three linear bounds the blocks none of whose samples its
//! test can count ([`BlockGrid::mask`]), and a receiver makes (hashes)
//! and tests only the samples of blocks some edge may cover
//! ([`BlockSamples::count`]); every other sample keeps `D(O)`.
//!
//! Exactness: the per-sample test is `add_covered_in`'s, on the same
//! bits (the samples are made as the sampling module makes them), so a
//! tested sample gets the same count; a block is skipped only when, for
//! one of the test's three conditions, the exact linear function of the
//! sample (on the edge's own f32 ends) is at least [`BLOCK_MARGIN`] on
//! the wrong side over the whole block, enlarged by [`CELL_SLACK`]. The
//! test evaluates each function in f32 on coordinates of magnitude ≤ 2
//! (clipped ends and samples lie in the chart's square `[−1, 1]²`), with
//! at most ~2e-6 of rounding, so it cannot count a sample there.

use super::chart_lanes::chart_rows;
use super::counters::{add_covered_in, OrientedEdge, LANES};
use crate::sampling::Strata;
#[cfg(target_arch = "x86_64")]
use crate::simd::level::runs_v3;
use crate::simd::{f64x4, i32x8};

/// How far past zero (exactly, over a whole block) a condition of the
/// covered test must fail for the block to be skipped: 5× the test's
/// f32 rounding on the chart's square (module doc).
pub const BLOCK_MARGIN: f64 = 1e-5;

/// Enlargement of the cells' chart boxes: the f32 rounding of a sample's
/// coordinates (≤ 6e-8 on the square) with a wide margin.
pub const CELL_SLACK: f64 = 1e-6;

/// Most blocks a grid has (one bit each in a `u64` mask).
const MAX_BLOCKS: usize = 64;

/// A stratified `a × a` grid (`a` a power of two, at least 16) cut into
/// at most 64 blocks of whole SIMD lanes, with each block's chart box.
#[derive(Debug, Clone)]
pub struct BlockGrid {
    /// Strata per side.
    a: u32,
    /// Block width and height, in cells.
    bw: u32,
    bh: u32,
    /// Blocks per row.
    per_row: u32,
    /// Blocks.
    count: usize,
    /// Chart boxes of the blocks (structure of arrays, four blocks per
    /// vector, past the last block empty boxes far out).
    x0: Vec<[f64; 4]>,
    x1: Vec<[f64; 4]>,
    y0: Vec<[f64; 4]>,
    y1: Vec<[f64; 4]>,
}

/// [`BlockGrid::mask`]'s kernel over `$lane` lanes (made by `$splat(v)`
/// and `$new(array)`), in names both the facade's `f64x4` and
/// `simd::avx::F64x4` have, so each gives the same bits.
macro_rules! block_mask_kernel {
    ($lane:ty, $splat:path, $new:path, $grid:ident, $edge:ident) => {{
        #[allow(unused_imports)]
        use std::ops::{Add, BitOr, Mul, Not};
        let (lo, hi) = ($edge.lo(), $edge.hi());
        let f = |v: f32| f64::from(v);
        let (lx, ly, hx, hy) = (f(lo[0]), f(lo[1]), f(hi[0]), f(hi[1]));
        // The test's own f32 differences.
        let (dx, dy) = (f(hi[0] - lo[0]), f(hi[1] - lo[1]));
        // Each condition as `a x + b y + c`: beyond = dx (y − ly) −
        // dy (x − lx) must be < 0, c_lo = lx y − ly x ≥ 0, c_hi =
        // hx y − hy x < 0.
        let beyond = (-dy, dx, dy * lx - dx * ly);
        let c_lo = (-ly, lx, 0.0);
        let c_hi = (-hy, hx, 0.0);
        let (margin, below) = ($splat(BLOCK_MARGIN), $splat(-BLOCK_MARGIN));
        let mut mask = 0u64;
        for (k, (((x0, x1), y0), y1)) in $grid
            .x0
            .iter()
            .zip(&$grid.x1)
            .zip(&$grid.y0)
            .zip(&$grid.y1)
            .enumerate()
        {
            let (x0, x1, y0, y1): ($lane, $lane, $lane, $lane) =
                ($new(*x0), $new(*x1), $new(*y0), $new(*y1));
            // Least and greatest of `a x + b y + c` over the box.
            let range = |(a, b, c): (f64, f64, f64)| {
                let (ax0, ax1) = ($splat(a).mul(x0), $splat(a).mul(x1));
                let (by0, by1) = ($splat(b).mul(y0), $splat(b).mul(y1));
                let c = $splat(c);
                (
                    c.add(ax0.min(ax1)).add(by0.min(by1)),
                    c.add(ax0.max(ax1)).add(by0.max(by1)),
                )
            };
            let (beyond_min, _) = range(beyond);
            let (_, c_lo_max) = range(c_lo);
            let (c_hi_min, _) = range(c_hi);
            let ruled_out = beyond_min
                .cmp_ge(margin)
                .bitor(c_lo_max.cmp_le(below))
                .bitor(c_hi_min.cmp_ge(margin));
            let may = !ruled_out.move_mask() & 0xf;
            mask |= u64::from(may) << (4 * k);
        }
        mask & $grid.all()
    }};
}

impl BlockGrid {
    /// The grid of `strata` for `n` samples, when it is square, a power
    /// of two per side, at least 16, and holds exactly `n` samples. (At
    /// 64 samples, blocks of one lane group cost as much to rule out as
    /// to test: counter pass on `spheres.toml` at 1024², 398 ms without
    /// blocks, 415 ms with.)
    pub fn new(strata: Strata, n: u32) -> Option<BlockGrid> {
        let a = strata.a;
        if a != strata.b || !a.is_power_of_two() || a < 16 || strata.count() != n {
            return None;
        }
        // Square blocks of at least 4 × 4 cells, at most 8 per side.
        let (bw, bh) = ((a / 8).max(4), (a / 8).max(4));
        let (per_row, rows) = (a / bw, a / bh);
        let count = (per_row * rows) as usize;
        debug_assert!(count <= MAX_BLOCKS && ((bw * bh) as usize).is_multiple_of(LANES));
        let far = 1e30;
        let mut boxes = vec![[far, far, far, far]; count.div_ceil(4) * 4];
        let inv = 1.0 / f64::from(a);
        for (b, slot) in boxes.iter_mut().enumerate().take(count) {
            let (bx, by) = (b as u32 % per_row, b as u32 / per_row);
            let (i0, i1) = (f64::from(bx * bw), f64::from((bx + 1) * bw));
            let (j0, j1) = (f64::from(by * bh), f64::from((by + 1) * bh));
            // Chart x = 2 s − 1, y = 1 − 2 t over the cells' [i, i + 1) / a.
            *slot = [
                2.0 * i0 * inv - 1.0 - CELL_SLACK,
                2.0 * i1 * inv - 1.0 + CELL_SLACK,
                1.0 - 2.0 * j1 * inv - CELL_SLACK,
                1.0 - 2.0 * j0 * inv + CELL_SLACK,
            ];
        }
        let lanes = |k: usize| -> Vec<[f64; 4]> {
            boxes
                .chunks_exact(4)
                .map(|c| [c[0][k], c[1][k], c[2][k], c[3][k]])
                .collect()
        };
        Some(BlockGrid {
            a,
            bw,
            bh,
            per_row,
            count,
            x0: lanes(0),
            x1: lanes(1),
            y0: lanes(2),
            y1: lanes(3),
        })
    }

    /// Samples per block.
    fn block_len(&self) -> usize {
        (self.bw * self.bh) as usize
    }

    /// Bit `b`: block `b` may hold a sample `edge`'s test counts
    /// ([`block_mask_kernel!`], in 256-bit registers where the CPU has
    /// AVX).
    #[inline(always)]
    pub fn mask(&self, edge: &OrientedEdge) -> u64 {
        #[cfg(target_arch = "x86_64")]
        if runs_v3() {
            // SAFETY: `runs_v3` checked that the CPU has x86-64-v3's
            // features, AVX among them: the kernel's one requirement.
            return unsafe { self.mask_avx(edge) };
        }
        self.mask_lanes(edge)
    }

    /// [`BlockGrid::mask`] on the facade's lanes.
    #[inline(always)]
    fn mask_lanes(&self, edge: &OrientedEdge) -> u64 {
        block_mask_kernel!(f64x4, f64x4::splat, f64x4::new, self, edge)
    }

    /// [`BlockGrid::mask`] in AVX registers.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where the CPU has AVX.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    fn mask_avx(&self, edge: &OrientedEdge) -> u64 {
        use crate::simd::avx::F64x4;
        block_mask_kernel!(F64x4, F64x4::splat, F64x4::new, self, edge)
    }

    /// Every block's bit.
    fn all(&self) -> u64 {
        if self.count >= 64 {
            u64::MAX
        } else {
            (1 << self.count) - 1
        }
    }
}

/// One receiver's samples of the blocks some edge may cover, and their
/// counters (per worker, reused).
#[derive(Debug, Clone, Default)]
pub struct BlockSamples {
    xs: Vec<f32>,
    ys: Vec<f32>,
    counters: Vec<i32>,
    /// Per edge: its blocks.
    masks: Vec<u64>,
    /// Offset of each made block's samples.
    offsets: Vec<usize>,
}

/// What a receiver's samples give, summed over all of them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BlockCounts {
    /// Samples with `D ≤ 0`.
    pub visible: u64,
    /// Largest `D` (not below 0).
    pub max: i32,
    /// Sum of `max(D, 0)`.
    pub sum: i64,
}

impl BlockCounts {
    /// The counts of `counters` (whole lanes), in one pass eight at a
    /// time: in 256-bit registers where the CPU has AVX2
    /// ([`BlockCounts::of_avx2`]), on the facade's lanes elsewhere.
    #[inline(always)]
    pub fn of(counters: &[i32]) -> BlockCounts {
        #[cfg(target_arch = "x86_64")]
        if runs_v3() {
            // SAFETY: `runs_v3` checked that the CPU has x86-64-v3's
            // features, AVX and AVX2 among them: the kernel's one
            // requirement.
            return unsafe { BlockCounts::of_avx2(counters) };
        }
        BlockCounts::of_lanes(counters)
    }

    /// [`BlockCounts::of`] in 256-bit registers. The sum of positive
    /// counts is kept per lane in `i32`, exact while no lane's sum can
    /// pass `i32::MAX` (the largest count times the lane's length, checked
    /// at the end); otherwise the facade's pass, which widens each count
    /// to `i64`, gives it. Integer sums and maxima do not depend on the
    /// order, so both give the facade's counts.
    ///
    /// # Safety
    ///
    /// Outside AVX2 code, call only where the CPU has AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx,avx2")]
    fn of_avx2(counters: &[i32]) -> BlockCounts {
        use crate::simd::avx::I32x8;
        debug_assert!(counters.len().is_multiple_of(LANES));
        let zero = I32x8::splat(0);
        let (mut hidden, mut top, mut sum) = (0u64, zero, zero);
        for c in counters.chunks_exact(LANES) {
            let d = I32x8::load(c.try_into().expect("whole lanes"));
            let positive = d.cmp_gt(zero);
            hidden += u64::from(positive.move_mask().count_ones());
            top = top.max(d);
            sum = sum.add(d.bitand(positive));
        }
        let max = top.to_array().into_iter().max().unwrap_or(0);
        let per_lane = (counters.len() / LANES) as i64;
        if i64::from(max) * per_lane > i64::from(i32::MAX) {
            return BlockCounts::of_lanes(counters);
        }
        BlockCounts {
            visible: counters.len() as u64 - hidden,
            max,
            sum: sum.to_array().iter().map(|&v| i64::from(v)).sum(),
        }
    }

    /// [`BlockCounts::of`] on the facade's lanes.
    #[inline(always)]
    fn of_lanes(counters: &[i32]) -> BlockCounts {
        debug_assert!(counters.len().is_multiple_of(LANES));
        let zero = i32x8::ZERO;
        let (mut visible, mut top, mut sum) = (0u64, zero, 0i64);
        for c in counters.chunks_exact(LANES) {
            let d = i32x8::from(<[i32; LANES]>::try_from(c).expect("whole lanes"));
            let positive = d.cmp_gt(zero);
            visible += u64::from(LANES as u32 - positive.move_mask().count_ones());
            top = d.cmp_gt(top).blend(d, top);
            // Widened per lane: the sum of many large counts may pass
            // i32's range.
            sum += positive
                .blend(d, zero)
                .to_array()
                .iter()
                .map(|&v| i64::from(v))
                .sum::<i64>();
        }
        BlockCounts {
            visible,
            max: top.to_array().into_iter().max().unwrap_or(0),
            sum,
        }
    }
}

impl BlockSamples {
    /// The counts over all `grid` samples of the pixel with sample key
    /// `key` (the stratified pattern's), start count `d0` and effective
    /// `edges` (each with its signed change of `D`).
    #[inline(always)]
    pub fn count(
        &mut self,
        grid: &BlockGrid,
        key: u64,
        d0: i32,
        edges: &[(OrientedEdge, i32)],
    ) -> BlockCounts {
        self.masks.clear();
        self.masks.extend(edges.iter().map(|(e, _)| grid.mask(e)));
        let union = self.masks.iter().fold(0, |u, m| u | m);
        let len = grid.block_len();
        let made = union.count_ones() as usize * len;
        self.xs.clear();
        self.ys.clear();
        self.xs.resize(made, 0.0);
        self.ys.resize(made, 0.0);
        self.offsets.clear();
        self.offsets.resize(grid.count, usize::MAX);
        let (a, inv) = (grid.a, 1.0 / f64::from(grid.a));
        let mut bits = union;
        let mut at = 0;
        while bits != 0 {
            let b = bits.trailing_zeros();
            bits &= bits - 1;
            self.offsets[b as usize] = at;
            let (i0, j0) = (b % grid.per_row * grid.bw, b / grid.per_row * grid.bh);
            let (xs, ys) = (&mut self.xs[at..at + len], &mut self.ys[at..at + len]);
            // As the sampling module's jittered walk makes samples
            // `j a + i` (`Strata::point`), then the rect chart
            // `(2 s − 1, 1 − 2 t)`, four cells at a time where the CPU
            // can. The tests hold it to that walk's points.
            chart_rows(key, a, (i0, j0, grid.bw as usize), (inv, inv), xs, ys);
            at += len;
        }
        self.counters.clear();
        self.counters.resize(made, d0);
        for ((edge, delta), &mask) in edges.iter().zip(&self.masks) {
            let mut bits = mask;
            while bits != 0 {
                let b = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let at = self.offsets[b];
                add_covered_in(
                    &mut self.counters[at..at + len],
                    &self.xs[at..at + len],
                    &self.ys[at..at + len],
                    edge,
                    *delta,
                );
            }
        }
        let rest = (grid.count * len - made) as u64;
        let mut counts = BlockCounts::of(&self.counters);
        if rest > 0 {
            counts.visible += if d0 <= 0 { rest } else { 0 };
            counts.max = counts.max.max(d0);
            counts.sum += rest as i64 * i64::from(d0.max(0));
        }
        counts
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{PatternSampler, SamplePattern};
    use crate::shadow::dcs::counters::{add_covered, ChartSamples};

    fn rng(state: &mut u64) -> f64 {
        *state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (*state >> 11) as f64 / (1u64 << 53) as f64
    }

    /// The blocks give the counts of every sample tested against every
    /// edge, on random edges (some through or near the centre, some
    /// sharing ends, some at the square's border) and every grid size.
    #[test]
    fn counts_equal_the_full_test() {
        let mut s = 17u64;
        let mut skipped = 0usize;
        assert!(BlockGrid::new(Strata::new(64), 64).is_none());
        assert!(BlockGrid::new(Strata::new(200), 200).is_none());
        for n in [256u32, 1024, 4096] {
            let pattern = PatternSampler::new(SamplePattern::Stratified, n, 3, 0);
            let strata = Strata::new(n);
            let grid = BlockGrid::new(strata, n).expect("square power-of-two grid");
            let mut blocks = BlockSamples::default();
            for pixel in 0..150u32 {
                let points = pattern.pixel_points((pixel, 7));
                let mut chart = ChartSamples::default();
                chart.fill(n as usize, |w| {
                    points.for_each(n, |(s, t)| w.push([2.0 * s - 1.0, 1.0 - 2.0 * t]))
                });
                let mut r = || 2.0 * rng(&mut s) - 1.0;
                let edges: Vec<(OrientedEdge, i32)> = (0..1 + pixel as usize % 12)
                    .filter_map(|k| {
                        let scale = [1.0, 0.3, 0.02][k % 3];
                        let a = [r(), r()];
                        let b = [a[0] + r() * scale, a[1] + r() * scale];
                        let clip = |v: [f64; 2]| [v[0].clamp(-1.0, 1.0), v[1].clamp(-1.0, 1.0)];
                        let delta = if k % 4 == 3 { -1 } else { 1 + k as i32 % 2 };
                        OrientedEdge::new(clip(a), clip(b)).map(|e| (e, delta))
                    })
                    .collect();
                let d0 = pixel as i32 % 3 - 1;
                let mut full = vec![d0; chart.padded()];
                for (e, delta) in &edges {
                    add_covered(&mut full, &chart, e, *delta);
                }
                let full = &full[..chart.len()];
                let expected = BlockCounts {
                    visible: full.iter().filter(|&&c| c <= 0).count() as u64,
                    max: full.iter().copied().max().unwrap_or(0).max(0),
                    sum: full.iter().map(|&c| i64::from(c.max(0))).sum(),
                };
                let (_, key) = pattern
                    .jittered((pixel, 7))
                    .expect("stratified points are jittered");
                let got = blocks.count(&grid, key, d0, &edges);
                assert_eq!(got, expected, "n {n}, pixel {pixel}, edges {edges:?}");
                skipped += grid.count - blocks.offsets.iter().filter(|&&o| o != usize::MAX).count();
            }
        }
        // The culling does skip blocks.
        assert!(skipped > 1000, "{skipped} blocks skipped");
    }

    /// The AVX2 counts equal the facade's: small counts, counts of
    /// every sign, and counts so large that the lanes' `i32` sums would
    /// wrap (the facade's pass then gives them).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn counts_in_avx2_match_the_lanes() {
        if !crate::simd::level::Level::V3.supported() {
            eprintln!("no AVX2 on this CPU: nothing to check");
            return;
        }
        let mut s = 9u64;
        for round in 0..300 {
            let len = LANES * (1 + round % 40);
            let scale = match round % 3 {
                0 => 5.0,
                1 => 1e5,
                _ => 2e9,
            };
            let counters: Vec<i32> = (0..len)
                .map(|_| ((2.0 * rng(&mut s) - 1.0) * scale) as i32)
                .collect();
            // SAFETY: the CPU has AVX2 (checked).
            let got = unsafe { BlockCounts::of_avx2(&counters) };
            assert_eq!(got, BlockCounts::of_lanes(&counters), "round {round}");
        }
        let huge = vec![i32::MAX; 64];
        // SAFETY: the CPU has AVX2 (checked).
        let got = unsafe { BlockCounts::of_avx2(&huge) };
        assert_eq!(got.sum, 64 * i64::from(i32::MAX));
    }

    /// A block is ruled out only when none of its samples can be
    /// counted: every sample of a ruled-out block fails the test, on
    /// edges whose ends are near the blocks' corners.
    #[test]
    fn masks_hold_every_covered_sample() {
        let grid = BlockGrid::new(Strata::new(256), 256).expect("grid");
        let mut s = 5u64;
        for _ in 0..3000 {
            let mut r = || 2.0 * rng(&mut s) - 1.0;
            // Ends on the cells' lines (multiples of 2/16 − 1) or near.
            let snap = |v: f64, r: f64| ((v + 1.0) * 8.0).round() / 8.0 - 1.0 + r * 1e-7;
            let (a, b) = (
                [snap(r(), r()), snap(r(), r())],
                [snap(r(), r()), snap(r(), r())],
            );
            let Some(edge) = OrientedEdge::new(a, b) else {
                continue;
            };
            let mask = grid.mask(&edge);
            assert_eq!(mask, grid.mask_lanes(&edge));
            #[cfg(target_arch = "x86_64")]
            if crate::simd::avx::available() {
                // SAFETY: the CPU has AVX (checked).
                assert_eq!(unsafe { grid.mask_avx(&edge) }, mask, "AVX mask");
            }
            for k in 0..400 {
                let p = [r(), r()];
                let p = if k % 2 == 0 {
                    [snap(p[0], 0.0), p[1]]
                } else {
                    p
                };
                let ps = [p[0] as f32, p[1] as f32];
                if edge.covers(ps) {
                    let (i, j) = (
                        (((f64::from(ps[0]) + 1.0) * 8.0) as u32).min(15),
                        (((1.0 - f64::from(ps[1])) * 8.0) as u32).min(15),
                    );
                    let block = j / grid.bh * grid.per_row + i / grid.bw;
                    // A point on a block's border may belong to either.
                    let near_border =
                        |v: f64| ((v + 1.0) * 2.0 - ((v + 1.0) * 2.0).round()).abs() < 1e-5;
                    if !(near_border(f64::from(ps[0])) || near_border(f64::from(ps[1]))) {
                        assert!(
                            mask >> block & 1 == 1,
                            "{edge:?} covers {ps:?} in block {block}"
                        );
                    }
                }
            }
        }
    }
}
