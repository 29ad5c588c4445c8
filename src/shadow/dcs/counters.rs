//! Per-sample depth-complexity counters of one receiver, and the exact
//! per-sample test of which samples a projected edge covers.
//!
//! A sample `s` (chart coordinates, the light's centre at the origin) is
//! covered by the projected edge `lo → hi` — ordered so that
//! `cross(lo, hi) > 0` — when the segment from the origin to `s` crosses
//! it:
//!
//! ```text
//! cross(lo, s) ≥ 0  and  cross(hi, s) < 0  and  orient(lo, hi, s) < 0
//! ```
//!
//! (inside the sector from `lo` to `hi`, beyond the edge's line). The
//! sector is half-open: a sample exactly on the ray through a vertex
//! shared by two consecutive silhouette edges, where it is `hi` of one and
//! `lo` of the other, is counted by exactly one of them, because both
//! evaluate the same `cross(v, s)` on the same bits. Eight samples at a
//! time with `wide`; only exact IEEE operations (no fused multiply-add),
//! so every SIMD level gives the same counts. [`add_covered_scalar`] is
//! the same test one sample at a time, kept to test the SIMD one.
//!
//! Counters are `i32`: the depth complexity is bounded by the number of
//! caster faces, far below 2³¹ for any scene that fits in memory, so they
//! never wrap.

use crate::simd::level::runs_v3;
use crate::simd::{f32x8, i32x8};

/// Samples per SIMD step.
pub const LANES: usize = 8;

/// One receiver's samples in chart coordinates, structure-of-arrays,
/// padded to a multiple of [`LANES`] with the origin (never covered).
#[derive(Debug, Clone, Default)]
pub struct ChartSamples {
    xs: Vec<f32>,
    ys: Vec<f32>,
    n: usize,
}

impl ChartSamples {
    /// Replaces the samples.
    pub fn set(&mut self, points: impl Iterator<Item = [f64; 2]>) {
        self.clear();
        for p in points {
            self.push(p);
        }
        self.finish();
    }

    /// Starts a new set (then [`ChartSamples::push`] each sample and
    /// [`ChartSamples::finish`]).
    pub fn clear(&mut self) {
        self.xs.clear();
        self.ys.clear();
    }

    /// Appends a sample.
    #[inline]
    pub fn push(&mut self, [x, y]: [f64; 2]) {
        self.xs.push(x as f32);
        self.ys.push(y as f32);
    }

    /// Ends the set: pads it to a multiple of [`LANES`] with the origin.
    pub fn finish(&mut self) {
        self.n = self.xs.len();
        let padded = self.n.div_ceil(LANES) * LANES;
        self.xs.resize(padded, 0.0);
        self.ys.resize(padded, 0.0);
    }

    /// Replaces the samples by at most `n` points, which `f` writes in
    /// order through the [`ChartWriter`] it is given: into the padded
    /// lanes in place, with none of a push's length and capacity
    /// bookkeeping per sample.
    #[inline(always)]
    pub fn fill(&mut self, n: usize, f: impl FnOnce(&mut ChartWriter)) {
        let padded = n.div_ceil(LANES) * LANES;
        self.xs.clear();
        self.ys.clear();
        self.xs.resize(padded, 0.0);
        self.ys.resize(padded, 0.0);
        let mut writer = ChartWriter {
            xs: &mut self.xs[..n],
            ys: &mut self.ys[..n],
            written: 0,
        };
        f(&mut writer);
        let written = writer.written;
        self.n = written;
        self.xs.truncate(written.div_ceil(LANES) * LANES);
        self.ys.truncate(written.div_ceil(LANES) * LANES);
    }

    /// Replaces the samples by `n` points, which `f` writes into the
    /// coordinate slices it is given (`n` long; the padding after them is
    /// the origin).
    #[inline(always)]
    pub fn fill_slices(&mut self, n: usize, f: impl FnOnce(&mut [f32], &mut [f32])) {
        let padded = n.div_ceil(LANES) * LANES;
        self.xs.clear();
        self.ys.clear();
        self.xs.resize(padded, 0.0);
        self.ys.resize(padded, 0.0);
        f(&mut self.xs[..n], &mut self.ys[..n]);
        self.n = n;
    }

    /// Number of (unpadded) samples.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Padded length (the counters' length).
    pub fn padded(&self) -> usize {
        self.xs.len()
    }

    /// Every sample's chart coordinates as tested, `xs` and `ys`,
    /// padded to [`ChartSamples::padded`].
    pub fn padded_points(&self) -> (&[f32], &[f32]) {
        (&self.xs, &self.ys)
    }

    /// Sample `k`'s chart coordinates as tested.
    pub fn get(&self, k: usize) -> [f32; 2] {
        [self.xs[k], self.ys[k]]
    }
}

/// Writes [`ChartSamples::fill`]'s points in order; points past the
/// promised count are dropped.
pub struct ChartWriter<'a> {
    xs: &'a mut [f32],
    ys: &'a mut [f32],
    written: usize,
}

impl ChartWriter<'_> {
    /// Appends a sample.
    #[inline(always)]
    pub fn push(&mut self, [x, y]: [f64; 2]) {
        let k = self.written;
        if let (Some(sx), Some(sy)) = (self.xs.get_mut(k), self.ys.get_mut(k)) {
            (*sx, *sy) = (x as f32, y as f32);
            self.written = k + 1;
        }
    }
}

/// An edge ready for the per-sample test: `cross(lo, hi) > 0`.
#[derive(Debug, Clone, Copy)]
pub struct OrientedEdge {
    lo: [f32; 2],
    hi: [f32; 2],
}

impl OrientedEdge {
    /// Orders the projected edge `a, b`; `None` when it is (in f32) in
    /// line with the centre, where it covers no sample.
    pub fn new(a: [f64; 2], b: [f64; 2]) -> Option<OrientedEdge> {
        let a = [a[0] as f32, a[1] as f32];
        let b = [b[0] as f32, b[1] as f32];
        // The orientation from the same f32 values the test uses.
        let o = f64::from(a[0]) * f64::from(b[1]) - f64::from(a[1]) * f64::from(b[0]);
        if o > 0.0 {
            Some(OrientedEdge { lo: a, hi: b })
        } else if o < 0.0 {
            Some(OrientedEdge { lo: b, hi: a })
        } else {
            None
        }
    }

    /// The end the covered sector starts from (`cross(lo, hi) > 0`), as
    /// the test uses it: other covered-sample tests (the bit-field tables
    /// of `bitfield`) must see the same f32 values.
    #[inline]
    pub fn lo(&self) -> [f32; 2] {
        self.lo
    }

    /// The end the covered sector stops at (excluded), as the test uses it.
    #[inline]
    pub fn hi(&self) -> [f32; 2] {
        self.hi
    }

    /// Whether the sample at chart point `s` is covered.
    #[inline]
    pub fn covers(&self, s: [f32; 2]) -> bool {
        let (lo, hi) = (self.lo, self.hi);
        let c_lo = lo[0] * s[1] - lo[1] * s[0];
        let c_hi = hi[0] * s[1] - hi[1] * s[0];
        let (dx, dy) = (hi[0] - lo[0], hi[1] - lo[1]);
        let beyond = dx * (s[1] - lo[1]) - dy * (s[0] - lo[0]);
        c_lo >= 0.0 && c_hi < 0.0 && beyond < 0.0
    }
}

/// Adds `delta` to the counter of every sample `edge` covers.
pub fn add_covered(counters: &mut [i32], samples: &ChartSamples, edge: &OrientedEdge, delta: i32) {
    add_covered_in(counters, &samples.xs, &samples.ys, edge, delta);
}

/// [`add_covered`] over the samples `xs`, `ys` (a multiple of [`LANES`])
/// and their counters.
#[inline]
pub(super) fn add_covered_in(
    counters: &mut [i32],
    xs: &[f32],
    ys: &[f32],
    edge: &OrientedEdge,
    delta: i32,
) {
    #[cfg(target_arch = "x86_64")]
    if runs_v3() {
        // SAFETY: `runs_v3` checked that the CPU has x86-64-v3's
        // features, AVX and AVX2 among them: the kernel's one requirement.
        return unsafe { add_covered_avx2(counters, xs, ys, edge, delta) };
    }
    add_covered_lanes(counters, xs, ys, edge, delta);
}

/// [`add_covered_in`] on the facade's lanes (the baseline kernel, and
/// the twin the AVX2 one is tested against).
#[inline(always)]
fn add_covered_lanes(
    counters: &mut [i32],
    xs: &[f32],
    ys: &[f32],
    edge: &OrientedEdge,
    delta: i32,
) {
    let (lo, hi) = (edge.lo, edge.hi);
    let (lx, ly) = (f32x8::splat(lo[0]), f32x8::splat(lo[1]));
    let (hx, hy) = (f32x8::splat(hi[0]), f32x8::splat(hi[1]));
    let (dx, dy) = (f32x8::splat(hi[0] - lo[0]), f32x8::splat(hi[1] - lo[1]));
    let zero = f32x8::ZERO;
    let d = i32x8::splat(delta);
    for ((c, xs), ys) in counters
        .chunks_exact_mut(LANES)
        .zip(xs.chunks_exact(LANES))
        .zip(ys.chunks_exact(LANES))
    {
        let sx = f32x8::from(<[f32; LANES]>::try_from(xs).expect("chunks_exact(LANES)"));
        let sy = f32x8::from(<[f32; LANES]>::try_from(ys).expect("chunks_exact(LANES)"));
        let c_lo = lx * sy - ly * sx;
        let c_hi = hx * sy - hy * sx;
        let beyond = dx * (sy - ly) - dy * (sx - lx);
        let m = c_lo.cmp_ge(zero) & c_hi.cmp_lt(zero) & beyond.cmp_lt(zero);
        let m = m.cast_i32();
        let cur = i32x8::from(<[i32; LANES]>::try_from(&*c).expect("chunks_exact(LANES)"));
        let next = cur + (m & d);
        c.copy_from_slice(&next.to_array());
    }
}

/// [`add_covered_in`] in 256-bit registers ([`crate::simd::avx`]): a
/// baseline build runs the facade's `f32x8` as two SSE halves, even in
/// the counter pass's x86-64-v3 copy. The same IEEE operations in the
/// same order per lane, so the same counts.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2")]
#[inline]
fn add_covered_avx2(counters: &mut [i32], xs: &[f32], ys: &[f32], edge: &OrientedEdge, delta: i32) {
    use crate::simd::avx::{F32x8, I32x8};
    let (lo, hi) = (edge.lo, edge.hi);
    let (lx, ly) = (F32x8::splat(lo[0]), F32x8::splat(lo[1]));
    let (hx, hy) = (F32x8::splat(hi[0]), F32x8::splat(hi[1]));
    let (dx, dy) = (F32x8::splat(hi[0] - lo[0]), F32x8::splat(hi[1] - lo[1]));
    let zero = F32x8::splat(0.0);
    let d = I32x8::splat(delta);
    for ((c, xs), ys) in counters
        .chunks_exact_mut(LANES)
        .zip(xs.chunks_exact(LANES))
        .zip(ys.chunks_exact(LANES))
    {
        let sx = F32x8::load(xs.try_into().expect("chunks_exact(LANES)"));
        let sy = F32x8::load(ys.try_into().expect("chunks_exact(LANES)"));
        let c_lo = lx.mul(sy).sub(ly.mul(sx));
        let c_hi = hx.mul(sy).sub(hy.mul(sx));
        let beyond = dx.mul(sy.sub(ly)).sub(dy.mul(sx.sub(lx)));
        let m = c_lo
            .cmp_ge(zero)
            .bitand(c_hi.cmp_lt(zero))
            .bitand(beyond.cmp_lt(zero));
        let c: &mut [i32; LANES] = c.try_into().expect("chunks_exact_mut(LANES)");
        I32x8::load(c).add(d.masked(m)).store(c);
    }
}

/// [`SectorSamples::add_covered_all`]'s tests in 256-bit registers: one
/// call per receiver, with [`add_covered_avx2`] inlined in its loop.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2")]
fn add_runs_avx2(
    counters: &mut [i32],
    xs: &[f32],
    ys: &[f32],
    edges: &[(OrientedEdge, i32)],
    runs: &[[usize; 4]],
) {
    for ((edge, delta), run) in edges.iter().zip(runs) {
        for (from, to) in [(run[0], run[1]), (run[2], run[3])] {
            if from < to {
                add_covered_avx2(
                    &mut counters[from..to],
                    &xs[from..to],
                    &ys[from..to],
                    edge,
                    *delta,
                );
            }
        }
    }
}

/// Sectors of the chart around the centre, by [`pseudo_angles`] (a
/// power of two: keys are masked by `SECTORS − 1`).
const SECTORS: usize = 16;
const _: () = assert!(SECTORS.is_power_of_two());

/// A monotone stand-in for the angles of the points `(x, y)` around the
/// origin, counter-clockwise from the +x axis, in `[0, 4)` (no
/// trigonometry; the origin gives NaN). In f32 it errs by at most a few
/// 1e-7: one rounding each of `|x| + |y|`, the quotient and `1 − p` or
/// `3 + p`. A macro over `$lane` lanes (made by `$splat(v)`), in names
/// the facade's `f32x8` and `simd::avx::F32x8` both have, so the AVX
/// copies of the sector kernels below make the same bits.
macro_rules! pseudo_angles {
    ($lane:ty, $splat:path, $x:expr, $y:expr) => {{
        let (x, y): ($lane, $lane) = ($x, $y);
        let p = x.div(x.abs().add(y.abs()));
        y.cmp_lt($splat(0.0))
            .blend($splat(3.0).add(p), $splat(1.0).sub(p))
    }};
}

/// [`SectorSamples::set`]'s keys of `xs`, `ys` (whole lanes) into `keys`
/// over `$lane` lanes (made by `$splat` and `$load`, truncated to an
/// `[i32; 8]` by the method `$trunc`); `false` at a non-zero sample so
/// close to the centre that its products could underflow.
macro_rules! sector_keys_kernel {
    ($lane:ty, $splat:path, $load:path, $trunc:ident, $xs:expr, $ys:expr, $keys:expr) => {{
        #[allow(unused_imports)]
        use std::ops::{Add, BitAnd, Div, Mul, Sub};
        // The pseudo-angle in f32 errs by a few 1e-7, far inside
        // SECTOR_MARGIN, so every sample still lies in the sectors `plan`
        // gives an edge that can count it. Only which sector a sample
        // near a boundary takes may differ from an f64 key, hence only
        // the counters' order. The origin (0 / 0, NaN) takes the last
        // sector (`min` keeps `last` for a NaN), so every truncated lane
        // lies in `[0, SECTORS)`.
        let (tiny, zero) = ($splat(TINY), $splat(0.0));
        let scale = $splat(SECTORS as f32 / 4.0);
        let last = $splat((SECTORS - 1) as f32);
        let mut near_centre = false;
        for ((xs, ys), out) in $xs
            .chunks_exact(LANES)
            .zip($ys.chunks_exact(LANES))
            .zip($keys.chunks_exact_mut(LANES))
        {
            let xs: &[f32; LANES] = xs.try_into().expect("chunks_exact(LANES)");
            let ys: &[f32; LANES] = ys.try_into().expect("chunks_exact(LANES)");
            let (x, y): ($lane, $lane) = ($load(xs), $load(ys));
            let size = x.abs().max(y.abs());
            // (The padding is the origin, size 0.)
            if size.cmp_lt(tiny).bitand(size.cmp_ne(zero)).any() {
                near_centre = true;
                break;
            }
            let keys = pseudo_angles!($lane, $splat, x, y)
                .mul(scale)
                .min(last)
                .$trunc();
            for (o, &key) in out.iter_mut().zip(&keys) {
                *o = key as u8;
            }
        }
        !near_centre
    }};
}

/// [`SectorSamples::plan`]'s sector ends of eight edges (lanes
/// `[lo.x, lo.y, hi.x, hi.y]`) over `$lane` lanes, as
/// [`sector_keys_kernel!`]: the first and last sector (clamped to
/// `[0, SECTORS)` before truncation, so the same on every lane type),
/// the turn from `lo` to `hi` modulo 4, and the mask of edges with an end
/// at the centre.
macro_rules! sector_ends_kernel {
    ($lane:ty, $splat:path, $load:path, $trunc:ident, $lanes:expr) => {{
        #[allow(unused_imports)]
        use std::ops::{Add, BitOr, Div, Mul, Sub};
        let lanes: &[[f32; LANES]; 4] = $lanes;
        let (zero, four) = ($splat(0.0), $splat(4.0));
        let (margin, tiny) = ($splat(SECTOR_MARGIN as f32), $splat(TINY));
        let scale = $splat(SECTORS as f32 / 4.0);
        let top = $splat((SECTORS - 1) as f32);
        // `t` lies within the margin of `[0, 4)`: one step wraps it.
        macro_rules! wrap {
            ($t:expr) => {{
                let t: $lane = $t;
                let t = t.cmp_lt(zero).blend(t.add(four), t);
                t.cmp_ge(four).blend(t.sub(four), t)
            }};
        }
        let (lx, ly, hx, hy): ($lane, $lane, $lane, $lane) = (
            $load(&lanes[0]),
            $load(&lanes[1]),
            $load(&lanes[2]),
            $load(&lanes[3]),
        );
        let a = pseudo_angles!($lane, $splat, lx, ly).sub(margin);
        let b = pseudo_angles!($lane, $splat, hx, hy).add(margin);
        let first = wrap!(a).mul(scale).max(zero).min(top).$trunc();
        let last = wrap!(b).mul(scale).max(zero).min(top).$trunc();
        // The turn from `a` to `b` modulo 4 (`b − a` lies in
        // `(−4 − 2m, 4 + 2m)`); only compared with 1, far from where one
        // step of wrapping could err.
        let turn = wrap!(b.sub(a)).to_array();
        let small = lx
            .abs()
            .max(ly.abs())
            .cmp_lt(tiny)
            .bitor(hx.abs().max(hy.abs()).cmp_lt(tiny))
            .move_mask();
        SectorEnds {
            first,
            last,
            turn,
            small,
        }
    }};
}

/// Eight edges' sector ends ([`sector_ends_kernel!`]).
struct SectorEnds {
    first: [i32; LANES],
    last: [i32; LANES],
    turn: [f32; LANES],
    small: u32,
}

/// [`sector_keys_kernel!`] on the facade's lanes.
#[inline(always)]
fn sector_keys_lanes(xs: &[f32], ys: &[f32], keys: &mut [u8]) -> bool {
    let load = |a: &[f32; LANES]| f32x8::from(*a);
    sector_keys_kernel!(f32x8, f32x8::splat, load, trunc_int_array, xs, ys, keys)
}

/// [`sector_keys_kernel!`] in 256-bit registers.
///
/// # Safety
///
/// Outside AVX code, call only where the CPU has AVX.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
fn sector_keys_avx(xs: &[f32], ys: &[f32], keys: &mut [u8]) -> bool {
    use crate::simd::avx::F32x8;
    sector_keys_kernel!(
        F32x8,
        F32x8::splat,
        F32x8::load,
        trunc_int_array,
        xs,
        ys,
        keys
    )
}

/// [`sector_ends_kernel!`] on the facade's lanes.
#[inline(always)]
fn sector_ends_lanes(lanes: &[[f32; LANES]; 4]) -> SectorEnds {
    let load = |a: &[f32; LANES]| f32x8::from(*a);
    sector_ends_kernel!(f32x8, f32x8::splat, load, trunc_int_array, lanes)
}

/// [`sector_ends_kernel!`] in 256-bit registers.
///
/// # Safety
///
/// Outside AVX code, call only where the CPU has AVX.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
fn sector_ends_avx(lanes: &[[f32; LANES]; 4]) -> SectorEnds {
    use crate::simd::avx::F32x8;
    sector_ends_kernel!(F32x8, F32x8::splat, F32x8::load, trunc_int_array, lanes)
}

/// One receiver's samples sorted into angular sectors around the centre,
/// so that an edge tests only the samples of the sectors its own sector
/// `lo → hi` overlaps instead of all of them. The per-sample test is
/// [`add_covered`]'s, on the same bits; only which samples it runs on
/// changes, and every sample it can count lies in those sectors (below).
/// Counters follow the sorted order, so only order-independent results
/// (counts, maxima, sums of 0 and 1) may be read from them.
#[derive(Debug, Clone, Default)]
pub struct SectorSamples {
    /// The samples, sector after sector, then padding (the origin).
    xs: Vec<f32>,
    ys: Vec<f32>,
    /// Sector `k` holds samples `start[k]..start[k + 1]`.
    start: [u32; SECTORS + 1],
    keys: Vec<u8>,
    /// Per edge of the last [`SectorSamples::add_covered_all`], its runs
    /// `[from, to, from, to)` in whole lane steps.
    runs: Vec<[usize; 4]>,
}

/// Pseudo-angle margin around an edge's sector. The test's `f32` cross
/// products `cross(v, s)` err by at most ~2⁻²² |v| |s|, an angle of
/// ~2.4e-7 rad, and the pseudo-angle changes by at most one unit per
/// radian: 1e-5 holds every sample the test can count with a margin of
/// 40×.
const SECTOR_MARGIN: f64 = 1e-5;

/// Interleaved histograms and cursors of [`SectorSamples::set`].
const STREAMS: usize = 4;

/// Below this (largest coordinate), a point's products with others may
/// underflow and the angular bound may not hold.
const TINY: f32 = 1e-12;

impl SectorSamples {
    /// Sorts `samples` into sectors; `false` (use [`add_covered`]
    /// instead) when a non-zero sample is so close to the centre that
    /// its products could underflow. (The origin, padding included, is
    /// never counted, so it may sit in any sector.)
    #[inline(always)]
    pub fn set(&mut self, samples: &ChartSamples) -> bool {
        let n = samples.len();
        self.keys.clear();
        self.keys.resize(samples.padded(), 0);
        // One histogram (and below one cursor per sector) per sample
        // index mod STREAMS: consecutive samples mostly share a sector,
        // and a single counter made every increment wait for the last
        // one's store.
        let mut counts = [[0u32; SECTORS]; STREAMS];
        let (xs, ys) = (&samples.xs[..], &samples.ys[..]);
        #[cfg(target_arch = "x86_64")]
        let keyed = if runs_v3() {
            // SAFETY: `runs_v3` checked that the CPU has x86-64-v3's
            // features, AVX among them: the kernel's one requirement.
            unsafe { sector_keys_avx(xs, ys, &mut self.keys) }
        } else {
            sector_keys_lanes(xs, ys, &mut self.keys)
        };
        #[cfg(not(target_arch = "x86_64"))]
        let keyed = sector_keys_lanes(xs, ys, &mut self.keys);
        if !keyed {
            return false;
        }
        // (Keys are below SECTORS, a power of two: the mask only shows
        // the compiler so.)
        let sector = |key: u8| usize::from(key) & (SECTORS - 1);
        for (k, &key) in self.keys[..n].iter().enumerate() {
            counts[k % STREAMS][sector(key)] += 1;
        }
        // Sector by sector, each stream's run of it.
        let mut next = [[0u32; SECTORS]; STREAMS];
        let mut at = 0;
        for sector in 0..SECTORS {
            self.start[sector] = at;
            for (cursor, count) in next.iter_mut().zip(&counts) {
                cursor[sector] = at;
                at += count[sector];
            }
        }
        self.start[SECTORS] = at;
        let padded = samples.padded();
        self.xs.clear();
        self.xs.resize(padded, 0.0);
        self.ys.clear();
        self.ys.resize(padded, 0.0);
        let (xs, ys) = (&samples.xs[..n], &samples.ys[..n]);
        for (k, ((&key, &x), &y)) in self.keys[..n].iter().zip(xs).zip(ys).enumerate() {
            let slot = &mut next[k % STREAMS][sector(key)];
            self.xs[*slot as usize] = x;
            self.ys[*slot as usize] = y;
            *slot += 1;
        }
        true
    }

    /// The lane-aligned runs of sorted samples each edge's sector can
    /// hold (one, or two where it wraps past the +x axis; an empty run is
    /// `from >= to`), into `self.runs`. The ends' pseudo-angles are taken
    /// eight edges at a time in f32, as the samples' keys are: each errs
    /// by at most ~5e-7 (module of [`SectorSamples::set`]), so with the
    /// samples' own error the sector still holds every sample the test
    /// can count with more than 10× to spare of [`SECTOR_MARGIN`]. (Per
    /// edge in f64 with the kernel called once per edge, these bounds had
    /// cost more than the test: 9.5 % against 5.5 % of a bunny profile.)
    #[inline(always)]
    fn plan(&mut self, edges: &[(OrientedEdge, i32)]) {
        self.runs.clear();
        let total = self.start[SECTORS] as usize;
        let all = [0, total.div_ceil(LANES) * LANES, 0, 0];
        let step = |from: u32, to: u32| {
            (
                from as usize / LANES * LANES,
                (to as usize).div_ceil(LANES) * LANES,
            )
        };
        #[cfg(target_arch = "x86_64")]
        let avx = runs_v3();
        for chunk in edges.chunks(LANES) {
            let mut lanes = [[0f32; LANES]; 4];
            for (k, (e, _)) in chunk.iter().enumerate() {
                lanes[0][k] = e.lo[0];
                lanes[1][k] = e.lo[1];
                lanes[2][k] = e.hi[0];
                lanes[3][k] = e.hi[1];
            }
            #[cfg(target_arch = "x86_64")]
            let ends = if avx {
                // SAFETY: `runs_v3` checked that the CPU has x86-64-v3's
                // features, AVX among them: the kernel's one requirement.
                unsafe { sector_ends_avx(&lanes) }
            } else {
                sector_ends_lanes(&lanes)
            };
            #[cfg(not(target_arch = "x86_64"))]
            let ends = sector_ends_lanes(&lanes);
            let SectorEnds {
                first,
                last,
                turn,
                small,
            } = ends;
            for k in 0..chunk.len() {
                // (A NaN angle, at an end at the centre, is such a tiny end.)
                if small & (1 << k) != 0 {
                    self.runs.push(all);
                    continue;
                }
                let (first, last) = (first[k] as usize, last[k] as usize);
                // `lo → hi` turns by less than π (two units); with the
                // margins it wraps past 0 exactly when the sectors come
                // out reversed, or when it starts and ends in one sector
                // but spans nearly all.
                let run = if first < last || (first == last && turn[k] < 1.0) {
                    let (f, t) = step(self.start[first], self.start[last + 1]);
                    [f, t, 0, 0]
                } else if first == last {
                    all
                } else {
                    // The last sectors, then the first: merged where
                    // their lane steps meet, so no sample counts twice.
                    let a = step(self.start[first], self.start[SECTORS]);
                    let b = step(self.start[0], self.start[last + 1]);
                    if a.0 < a.1 && b.0 < b.1 && a.0 < b.1 && b.0 < a.1 {
                        [a.0.min(b.0), a.1.max(b.1), 0, 0]
                    } else {
                        [a.0, a.1, b.0, b.1]
                    }
                };
                self.runs.push(run);
            }
        }
    }

    /// [`add_covered`] on the sorted samples for every `(edge, delta)` of
    /// `edges`: `delta` to the counter (in sorted order) of every sample
    /// the edge covers.
    #[inline(always)]
    pub fn add_covered_all(&mut self, counters: &mut [i32], edges: &[(OrientedEdge, i32)]) {
        self.plan(edges);
        #[cfg(target_arch = "x86_64")]
        if runs_v3() {
            // SAFETY: `runs_v3` checked that the CPU has x86-64-v3's
            // features, AVX and AVX2 among them: the kernel's one requirement.
            return unsafe { add_runs_avx2(counters, &self.xs, &self.ys, edges, &self.runs) };
        }
        for ((edge, delta), run) in edges.iter().zip(&self.runs) {
            for (from, to) in [(run[0], run[1]), (run[2], run[3])] {
                if from < to {
                    add_covered_lanes(
                        &mut counters[from..to],
                        &self.xs[from..to],
                        &self.ys[from..to],
                        edge,
                        *delta,
                    );
                }
            }
        }
    }

    /// The sorted samples as tested, `xs` and `ys`, padded as the
    /// [`ChartSamples`] they came from (the order the counters of
    /// [`SectorSamples::add_covered_all`] follow).
    pub fn points(&self) -> (&[f32], &[f32]) {
        (&self.xs, &self.ys)
    }

    /// The sorted samples as tested (for tests).
    #[cfg(test)]
    fn get(&self, k: usize) -> [f32; 2] {
        [self.xs[k], self.ys[k]]
    }
}

/// [`add_covered`] one sample at a time (the scalar twin).
pub fn add_covered_scalar(
    counters: &mut [i32],
    samples: &ChartSamples,
    edge: &OrientedEdge,
    delta: i32,
) {
    for (k, c) in counters.iter_mut().enumerate().take(samples.padded()) {
        if edge.covers(samples.get(k)) {
            *c += delta;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The tests' random source: uniform in [−1, 1) from a 64-bit LCG.
    fn signed(state: &mut u64) -> f64 {
        *state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }

    fn samples(n: usize, seed: u64) -> ChartSamples {
        let mut s = ChartSamples::default();
        let mut x = seed;
        let pts: Vec<[f64; 2]> = (0..n).map(|_| [signed(&mut x), signed(&mut x)]).collect();
        s.set(pts.into_iter());
        s
    }

    #[test]
    fn simd_matches_scalar() {
        let s = samples(203, 5);
        for (a, b) in [
            ([-0.5, 0.3], [0.7, 0.4]),
            ([0.9, -0.9], [-0.9, -0.1]),
            ([0.1, 0.1], [0.1, 0.8]),
        ] {
            let e = OrientedEdge::new(a, b).unwrap();
            let mut v = vec![0; s.padded()];
            let mut w = vec![0; s.padded()];
            add_covered(&mut v, &s, &e, 3);
            add_covered_scalar(&mut w, &s, &e, 3);
            assert_eq!(v, w);
            assert!(v.contains(&3));
        }
    }

    /// The AVX2 kernel counts what the facade's lanes count, sample for
    /// sample: random edges, edges through samples (ties of every
    /// condition), and ends shared with the samples' own coordinates.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_kernel_matches_the_lanes() {
        if !crate::simd::level::Level::V3.supported() {
            eprintln!("no AVX2 on this CPU: nothing to check");
            return;
        }
        let s = samples(256, 11);
        let mut state = 3u64;
        let mut next = || signed(&mut state);
        let mut covered = 0;
        for round in 0..2000 {
            let (a, b) = match round % 3 {
                0 => ([next(), next()], [next(), next()]),
                // Through a sample, or from one.
                1 => {
                    let [x, y] = s.get(round % s.len()).map(f64::from);
                    ([x, y], [next(), next()])
                }
                _ => {
                    let [x, y] = s.get(round % s.len()).map(f64::from);
                    ([-x, -y], [x * 0.5, y * 0.5])
                }
            };
            let Some(e) = OrientedEdge::new(a, b) else {
                continue;
            };
            let start: Vec<i32> = (0..s.padded() as i32).map(|k| k % 7 - 3).collect();
            let (mut lanes, mut avx2) = (start.clone(), start.clone());
            let delta = round as i32 % 5 - 2;
            add_covered_lanes(&mut lanes, &s.xs, &s.ys, &e, delta);
            // SAFETY: the CPU has AVX2 (checked above).
            unsafe { add_covered_avx2(&mut avx2, &s.xs, &s.ys, &e, delta) };
            assert_eq!(lanes, avx2, "edge {e:?}, delta {delta}");
            covered += lanes.iter().zip(&start).filter(|(a, b)| a != b).count();
        }
        assert!(covered > 10_000, "{covered} samples moved");
    }

    #[test]
    fn consecutive_edges_share_the_ray_once() {
        // Samples exactly on the ray through the shared vertex v.
        let v = [0.25f64, 0.5];
        let mut s = ChartSamples::default();
        s.set((1..=16).map(|k| {
            let t = 1.0 + k as f64 * 0.1;
            [v[0] * t, v[1] * t]
        }));
        let e1 = OrientedEdge::new([0.5, -0.2], v).unwrap();
        let e2 = OrientedEdge::new(v, [-0.4, 0.3]).unwrap();
        let mut c = vec![0; s.padded()];
        add_covered(&mut c, &s, &e1, 1);
        add_covered(&mut c, &s, &e2, 1);
        // Beyond both edges near the vertex: each on-ray sample once.
        assert!(c[..s.len()].iter().all(|&k| k == 1), "{c:?}");
    }

    /// The sector-sorted test counts, per sorted sample, exactly what the
    /// full test counts: random edges, edges with an end on a sample's
    /// ray (ties), edges across the +x axis (the sectors' wrap), nearly
    /// half-turn edges, and samples on the axes and at the centre.
    #[test]
    fn sectors_count_what_the_full_test_counts() {
        let mut x = 17u64;
        let mut next = move || signed(&mut x);
        let mut checked = 0;
        for round in 0..60 {
            let n = [1, 7, 64, 203, 256][round % 5];
            let mut points: Vec<[f64; 2]> = (0..n).map(|_| [next(), next()]).collect();
            if round % 2 == 0 {
                points.extend([
                    [0.5, 0.0],
                    [0.0, 0.5],
                    [-0.5, -0.0],
                    [0.5, -0.0],
                    [0.0, 0.0],
                ]);
            }
            let mut s = ChartSamples::default();
            s.set(points.iter().copied());
            let mut sectors = SectorSamples::default();
            assert!(sectors.set(&s));
            let bits = |p: [f32; 2]| (p[0].to_bits(), p[1].to_bits());
            let mut a: Vec<_> = (0..s.len()).map(|k| bits(s.get(k))).collect();
            let mut b: Vec<_> = (0..s.len()).map(|k| bits(sectors.get(k))).collect();
            a.sort_unstable();
            b.sort_unstable();
            assert_eq!(a, b, "a permutation of the samples");
            let mut batch = Vec::new();
            for j in 0..300 {
                let (a, b) = match j % 5 {
                    0 | 1 => ([next(), next()], [next(), next()]),
                    2 => {
                        // An end on the ray through a sample.
                        let p = points[j % points.len()];
                        let t = 1.5 + 0.5 * next();
                        ([p[0] * t, p[1] * t], [next(), next()])
                    }
                    3 => (
                        [0.5 + 0.3 * next(), -0.2 * next().abs()],
                        [0.5, 0.2 * next().abs()],
                    ),
                    _ => ([1.0, 1e-3 * next()], [-1.0, 1e-3 * next()]),
                };
                let Some(e) = OrientedEdge::new(a, b) else {
                    continue;
                };
                let mut c = vec![0; s.padded()];
                sectors.add_covered_all(&mut c, &[(e, 2)]);
                for (k, &got) in c.iter().enumerate() {
                    let want = if e.covers(sectors.get(k)) { 2 } else { 0 };
                    assert_eq!(got, want, "sample {:?}, edge {e:?}", sectors.get(k));
                    checked += usize::from(want != 0);
                }
                batch.push((e, 1 + (j % 7) as i32 - 3));
            }
            // All the edges at once (their bounds eight at a time): the
            // sum of their single counts.
            let mut c = vec![0; s.padded()];
            sectors.add_covered_all(&mut c, &batch);
            for (k, &got) in c.iter().enumerate() {
                let p = sectors.get(k);
                let want: i32 = batch
                    .iter()
                    .filter(|(e, _)| e.covers(p))
                    .map(|(_, d)| d)
                    .sum();
                assert_eq!(got, want, "sample {p:?}");
            }
        }
        assert!(checked > 10_000, "{checked} covered samples");
    }

    /// A sample near (not at) the centre, where products could
    /// underflow, is refused.
    #[test]
    fn sectors_refuse_samples_at_the_centre() {
        let mut s = ChartSamples::default();
        s.set([[0.5, 0.5], [1e-20, 0.0]].into_iter());
        assert!(!SectorSamples::default().set(&s));
    }

    /// The AVX copies of the sector kernels give the facade's keys and
    /// sector ends, bit for bit: random samples and edges, points on the
    /// axes and diagonals (sector boundaries), at the origin, and near it.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn sector_kernels_in_avx_match_the_lanes() {
        if !crate::simd::avx::available() {
            eprintln!("no AVX on this CPU: nothing to check");
            return;
        }
        let mut state = 17u64;
        let mut next = || signed(&mut state) as f32;
        let special = [0.0, -0.0, 1.0, -1.0, 0.5, -0.5, 1e-13, -3e-12, 1e-30];
        for round in 0..500 {
            let mut point = |k: usize| -> f32 {
                if (round + k).is_multiple_of(3) {
                    special[(round * 7 + k) % special.len()]
                } else {
                    next()
                }
            };
            let xs: Vec<f32> = (0..64).map(&mut point).collect();
            let ys: Vec<f32> = (0..64).map(|k| point(k + 1)).collect();
            let (mut a, mut b) = (vec![0u8; 64], vec![0u8; 64]);
            let lanes_ok = sector_keys_lanes(&xs, &ys, &mut a);
            // SAFETY: the CPU has AVX (checked).
            let avx_ok = unsafe { sector_keys_avx(&xs, &ys, &mut b) };
            assert_eq!(lanes_ok, avx_ok, "round {round}");
            if lanes_ok {
                assert_eq!(a, b, "round {round}");
            }
            let lanes: [[f32; LANES]; 4] = std::array::from_fn(|r| {
                std::array::from_fn(|k| {
                    if r % 2 == 0 {
                        xs[8 * r + k]
                    } else {
                        ys[8 * r + k]
                    }
                })
            });
            let want = sector_ends_lanes(&lanes);
            // SAFETY: the CPU has AVX (checked).
            let got = unsafe { sector_ends_avx(&lanes) };
            assert_eq!(got.first, want.first, "round {round}");
            assert_eq!(got.last, want.last, "round {round}");
            assert_eq!(got.turn.map(f32::to_bits), want.turn.map(f32::to_bits));
            assert_eq!(got.small, want.small, "round {round}");
            assert!(want
                .first
                .iter()
                .chain(&want.last)
                .all(|&k| (0..SECTORS as i32).contains(&k)));
        }
    }

    #[test]
    fn centre_in_line_covers_nothing() {
        assert!(OrientedEdge::new([0.2, 0.2], [0.4, 0.4]).is_none());
    }
}
