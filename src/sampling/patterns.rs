//! Selectable sample patterns on the unit square `[0, 1)²` (`[0, 1]²` for
//! [`SamplePattern::Grid`], whose points include the square's edges).
//!
//! A [`SamplePattern`] says how the `N` unit points of one light at one
//! pixel are laid out and how they change from pixel to pixel; a
//! [`PatternSampler`] precomputes, once per `(pattern, N, seed, light)`,
//! whatever the pattern shares between pixels (the Poisson-disk base set,
//! the Sobol' points, the keys of the correlated sets) and then gives any
//! pixel's points ([`PatternSampler::unit_points`]). The mapping of a unit
//! point to a light (rect or sphere) is the sampling module's
//! ([`super::LightSampler::samples_with`]), the same for every pattern.
//!
//! Everything is a pure function of `(pattern, N, seed, light, pixel,
//! k)`: no generator state, no dependence on threads or visiting order.
//! See `docs/algorithms/sample-patterns.md` for the patterns and the
//! Poisson distance rule.

use super::{mix64, pixel_key, uniform_pair, Strata, GOLDEN};
use std::fmt;
use std::str::FromStr;

/// How the `N` light samples of a pixel are laid out on `[0, 1)²` and how
/// they are decorrelated between pixels (Forest 2008, §4.2 and §5.3.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum SamplePattern {
    /// A stratified jittered `a × b` grid ([`Strata`]) with fresh jitter
    /// per pixel (key [`pixel_key`]`(seed, light, pixel)`). Exactly the
    /// layout the sampling module always had; the default.
    #[default]
    Stratified,
    /// One stratified jittered set shared by every pixel (key from seed and
    /// light only): no noise, but the pattern shows as banding.
    Correlated,
    /// The [`Correlated`](SamplePattern::Correlated) set moved per pixel by
    /// a Cranley–Patterson rotation: a toroidal shift by a per-pixel
    /// uniform offset `(δs, δt)`, `(s, t) ↦ ((s + δs) mod 1, (t + δt) mod
    /// 1)`. This is our reading of the thesis's per-pixel "random
    /// rotation" of a precomputed set on a square domain (a true rotation
    /// would move points out of the square).
    Rotated,
    /// A Poisson-disk set made once by dart throwing on the torus
    /// (toroidal distance), minimum distance [`poisson_target_distance`]
    /// (the thesis's 0.2456139 for 16 and 0.1076681 for 64 samples),
    /// decorrelated per pixel by a Cranley–Patterson rotation, which keeps
    /// every toroidal distance and so the minimum-distance property.
    Poisson,
    /// The first `N` points of the 2-D Sobol' (0,2)-sequence (van der
    /// Corput in base 2 and the Sobol' second dimension), decorrelated per
    /// pixel by a random digital shift: each coordinate's 32-bit integer is
    /// XORed with a per-pixel 32-bit key (one key per coordinate). The
    /// shift maps elementary intervals onto elementary intervals, so for
    /// `N = 2^m` every pixel's set is a (0, m, 2)-net.
    Sobol02,
    /// An `n × n` tile of correlated sets (interleaved sampling, Keller and
    /// Heidrich 2001): pixel `(x, y)` uses set number
    /// `(x mod n) + n (y mod n)`, each a stratified jittered set keyed by
    /// seed, light and set number (not by the pixel); set 0 is the
    /// [`Correlated`](SamplePattern::Correlated) set. Any `n × n` block of
    /// pixels covers the `n²` sets once; [`crate::shade::gather`] filters
    /// them back together. `n = 0` counts as 1.
    Interleaved {
        /// Tile side (2 ≤ n ≤ 16 when parsed).
        n: u32,
    },
    /// The regular `a × b` grid ([`Strata`]'s shape) including the light's
    /// edges, shared by every pixel: point `k` in column `i = k mod a`,
    /// row `j = k div a` is `(i / (a − 1), j / (b − 1))`, `0.5` along an
    /// axis with a single point. For `N = (2^d + 1)²` this is the ground
    /// truth of Schwärzler et al. 2012 (289 = 17 × 17, `d = 4`), the grid
    /// their adaptive subdivision reaches at depth `d`. No jitter, no
    /// decorrelation: the points are exactly representable (`i / 2^d`).
    Grid,
}

/// The tile side of `interleaved` without a number.
pub const DEFAULT_INTERLEAVE: u32 = 4;

impl SamplePattern {
    /// The names [`SamplePattern::parse`] accepts (`interleaved` also as
    /// `interleavedN` and `interleaved:N`, `sobol` also as `02`).
    pub const NAMES: &'static [&'static str] = &[
        "stratified",
        "correlated",
        "rotated",
        "poisson",
        "sobol",
        "interleaved",
        "grid",
    ];

    /// Parses a pattern name: `stratified`, `correlated`, `rotated`,
    /// `poisson`, `sobol` (or `02`, `sobol02`), `grid`, `interleaved` (4 × 4),
    /// `interleavedN` or `interleaved:N` with `2 ≤ N ≤ 16`. Case and
    /// surrounding blanks are ignored. The error lists the valid names.
    pub fn parse(name: &str) -> Result<SamplePattern, String> {
        let lower = name.trim().to_ascii_lowercase();
        let err = || {
            format!(
                "unknown sample pattern `{}`: expected one of stratified, correlated, \
                 rotated, poisson, sobol (or 02), grid, interleaved (4×4), interleavedN \
                 or interleaved:N with N in 2..=16",
                name.trim()
            )
        };
        Ok(match lower.as_str() {
            "stratified" => SamplePattern::Stratified,
            "correlated" => SamplePattern::Correlated,
            "rotated" => SamplePattern::Rotated,
            "poisson" => SamplePattern::Poisson,
            "sobol" | "02" | "sobol02" => SamplePattern::Sobol02,
            "grid" => SamplePattern::Grid,
            "interleaved" => SamplePattern::Interleaved {
                n: DEFAULT_INTERLEAVE,
            },
            other => {
                let rest = other.strip_prefix("interleaved").ok_or_else(err)?;
                let digits = rest.strip_prefix(':').unwrap_or(rest);
                if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
                    return Err(err());
                }
                match digits.parse::<u32>() {
                    Ok(n) if (2..=16).contains(&n) => SamplePattern::Interleaved { n },
                    _ => return Err(err()),
                }
            }
        })
    }

    /// The canonical name, which [`SamplePattern::parse`] maps back to
    /// `self`: `stratified`, `correlated`, `rotated`, `poisson`, `sobol`,
    /// `interleaved:N`, `grid`.
    pub fn name(&self) -> String {
        match self {
            SamplePattern::Stratified => "stratified".into(),
            SamplePattern::Correlated => "correlated".into(),
            SamplePattern::Rotated => "rotated".into(),
            SamplePattern::Poisson => "poisson".into(),
            SamplePattern::Sobol02 => "sobol".into(),
            SamplePattern::Interleaved { n } => format!("interleaved:{n}"),
            SamplePattern::Grid => "grid".into(),
        }
    }

    /// Whether neighbouring pixels get different point sets (every pattern
    /// but [`Correlated`](SamplePattern::Correlated) and
    /// [`Grid`](SamplePattern::Grid); interleaved sets repeat every `n`
    /// pixels).
    pub fn is_decorrelated(&self) -> bool {
        !matches!(self, SamplePattern::Correlated | SamplePattern::Grid)
    }
}

impl fmt::Display for SamplePattern {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.name())
    }
}

impl FromStr for SamplePattern {
    type Err = String;

    fn from_str(s: &str) -> Result<SamplePattern, String> {
        SamplePattern::parse(s)
    }
}

// ------------------------------------------------------------ keys

/// Stream tags, so the keys of different uses never coincide by design.
const TAG_SET: u64 = 1;
const TAG_ROTATION: u64 = 2;
const TAG_POISSON: u64 = 3;
const TAG_POISSON_SHIFT: u64 = 4;
const TAG_DIGITAL_SHIFT: u64 = 5;

/// A key that depends on `(seed, light, tag, index)` but not on any pixel,
/// hashed like [`pixel_key`] with other constants.
#[inline]
fn stream_key(seed: u64, light_index: usize, tag: u64, index: u64) -> u64 {
    let mut h = mix64(seed ^ 0x510e_527f_ade6_82d1);
    h = mix64(h ^ (light_index as u64).wrapping_mul(0x9b05_688c_2b3e_6c1f));
    h = mix64(h ^ tag.wrapping_mul(0x1f83_d9ab_fb41_bd6b));
    mix64(h ^ index.wrapping_mul(0x5be0_cd19_137e_2179))
}

/// The key of jittered set number `set` (correlated and interleaved sets).
#[inline]
fn set_key(seed: u64, light_index: usize, set: u64) -> u64 {
    stream_key(seed, light_index, TAG_SET, set)
}

/// A per-pixel key for one decorrelation, independent of the
/// [`Stratified`](SamplePattern::Stratified) jitter of the same pixel.
#[inline]
fn pixel_tag_key(seed: u64, light_index: usize, pixel: (u32, u32), tag: u64) -> u64 {
    mix64(pixel_key(seed, light_index, pixel) ^ tag.wrapping_mul(0xcbbb_9d5d_c105_9ed9))
}

/// `(a + b) mod 1` for `a, b ∈ [0, 1)`, in `[0, 1)`: `a + b < 2` and its
/// rounding stays below 2, and `r − 1` is exact for `r ∈ [1, 2)`.
#[inline]
fn wrap_add(a: f64, b: f64) -> f64 {
    let r = a + b;
    if r >= 1.0 {
        r - 1.0
    } else {
        r
    }
}

/// `2^-32`: the spacing of 32-bit fixed-point coordinates.
const INV_2_32: f64 = 1.0 / 4_294_967_296.0;

// ------------------------------------------------------------ Sobol'

/// Point `k` of the 2-D Sobol' (0,2)-sequence as 32-bit fixed-point
/// integers: `x` is the base-2 radical inverse of `k` (bit reversal) and
/// `y` the Sobol' second dimension, `y = ⊕_{bit j of k set} V_j` with
/// `V_0 = 2^31`, `V_j = V_{j−1} ⊕ (V_{j−1} >> 1)` (direction numbers
/// 1, 3, 5, 15, 17, 51, …: the upper-triangular Pascal matrix mod 2).
pub fn sobol02(k: u32) -> (u32, u32) {
    let x = k.reverse_bits();
    let mut y = 0u32;
    let mut v = 1u32 << 31;
    let mut bits = k;
    while bits != 0 {
        if bits & 1 == 1 {
            y ^= v;
        }
        bits >>= 1;
        v ^= v >> 1;
    }
    (x, y)
}

// ------------------------------------------------------------ Poisson

/// The thesis's Poisson-disk minimum distances (§5.3.1): `(N, d)`.
pub const POISSON_THESIS_DISTANCES: [(u32, f64); 2] = [(16, 0.245_613_9), (64, 0.107_668_1)];

/// Lower bound of the relative radius [`poisson_relative_radius`] (only
/// reached beyond `N ≈ 2.4 × 10⁵`).
pub const POISSON_MIN_RELATIVE_RADIUS: f64 = 0.2;

/// Restarts of dart throwing at one distance before it is shrunk.
pub const POISSON_RESTARTS: u32 = 32;

/// Factor the distance is multiplied by after [`POISSON_RESTARTS`] failed
/// restarts.
pub const POISSON_SHRINK: f64 = 0.98;

/// Distances tried (the target and 99 shrinks, down to `0.98^99 ≈ 0.135`
/// of it); after them the distance is 0, where every dart is accepted, so
/// dart throwing always ends.
pub const POISSON_MAX_LEVELS: u32 = 100;

/// Darts one restart may throw for `n` points: `32 n + 1024`.
pub fn poisson_dart_budget(n: u32) -> u64 {
    32 * u64::from(n) + 1024
}

/// The largest minimum distance `N` points can have on the unit torus if
/// they could be packed hexagonally: `d_max(N) = √(2 / (√3 N))` (the disks
/// of diameter `d_max` fill the area at the hexagonal density `π / √12`).
/// Infinite for `N = 0`.
pub fn max_packing_distance(n: u32) -> f64 {
    (2.0 / (3f64.sqrt() * f64::from(n))).sqrt()
}

/// The relative radius `ρ(N) = d(N) / d_max(N)` of the Poisson-disk target
/// distance: linear in `log N` through the thesis's two values,
/// `ρ16 = 0.2456139 / d_max(16) ≈ 0.91428` and
/// `ρ64 = 0.1076681 / d_max(64) ≈ 0.80157`:
///
/// ```text
/// ρ(N) = ρ16 + (ρ64 − ρ16) · log(N / 16) / log 4,
/// ```
///
/// clamped to `[POISSON_MIN_RELATIVE_RADIUS, ρ16]`: below 16 samples the
/// line would exceed hexagonal packing (`ρ > 1` for `N ≤ 4`), so it is
/// held at `ρ16`; above 64 it falls by `0.1127` per factor 4 (`ρ ≈ 0.689`
/// at 256, `0.576` at 1024, `0.240` at 65536).
pub fn poisson_relative_radius(n: u32) -> f64 {
    let [(n16, d16), (n64, d64)] = POISSON_THESIS_DISTANCES;
    let r16 = d16 / max_packing_distance(n16);
    let r64 = d64 / max_packing_distance(n64);
    let x = (f64::from(n.max(1)) / f64::from(n16)).ln() / (f64::from(n64) / f64::from(n16)).ln();
    (r16 + (r64 - r16) * x).clamp(POISSON_MIN_RELATIVE_RADIUS, r16)
}

/// The target minimum toroidal distance of `n` Poisson-disk points,
/// `ρ(n) · d_max(n)` ([`poisson_relative_radius`],
/// [`max_packing_distance`]): 0.2456139 for 16 and 0.1076681 for 64
/// (to rounding). 0 for `n = 0`.
pub fn poisson_target_distance(n: u32) -> f64 {
    if n == 0 {
        return 0.0;
    }
    poisson_relative_radius(n) * max_packing_distance(n)
}

/// Squared distance on the unit torus.
#[inline]
pub fn toroidal_distance2(a: (f64, f64), b: (f64, f64)) -> f64 {
    let dx = (a.0 - b.0).abs();
    let dy = (a.1 - b.1).abs();
    let dx = dx.min(1.0 - dx);
    let dy = dy.min(1.0 - dy);
    dx * dx + dy * dy
}

/// A Poisson-disk set made by [`poisson_dart_throwing`], with how it was
/// made.
#[derive(Debug, Clone, PartialEq)]
pub struct PoissonSet {
    /// The points, in the order they were accepted.
    pub points: Vec<(f64, f64)>,
    /// The target distance [`poisson_target_distance`].
    pub target: f64,
    /// The distance the set was made with: `target · 0.98^level`, or 0
    /// after [`POISSON_MAX_LEVELS`] levels. Every two points are at least
    /// this far apart on the torus.
    pub distance: f64,
    /// How many times the distance was shrunk.
    pub level: u32,
    /// Restarts at the final level before success (0 = first try).
    pub restart: u32,
    /// Darts thrown in all, failed restarts included.
    pub darts: u64,
}

/// The points accepted so far, bucketed in a `g × g` toroidal grid of cells
/// of side `1/g ≥ d`, so a dart only meets the 3 × 3 cells around it.
struct DartGrid {
    g: usize,
    /// First point of each cell (`u32::MAX`: none), then a linked list.
    head: Vec<u32>,
    next: Vec<u32>,
    points: Vec<(f64, f64)>,
}

impl DartGrid {
    fn new(n: u32, d: f64) -> DartGrid {
        // Side ≥ d; no more cells than about N; fewer than 3 cells per
        // axis would visit cells twice, so then one cell (brute force).
        let by_distance = if d > 0.0 { (1.0 / d).floor() } else { f64::MAX };
        let by_count = f64::from(n).sqrt().ceil().max(1.0);
        let mut g = by_distance.min(by_count).min(4096.0) as usize;
        if g < 3 {
            g = 1;
        }
        DartGrid {
            g,
            head: vec![u32::MAX; g * g],
            next: Vec::with_capacity(n as usize),
            points: Vec::with_capacity(n as usize),
        }
    }

    fn clear(&mut self) {
        self.head.fill(u32::MAX);
        self.next.clear();
        self.points.clear();
    }

    #[inline]
    fn cell(&self, p: (f64, f64)) -> (usize, usize) {
        let c = |v: f64| ((v * self.g as f64) as usize).min(self.g - 1);
        (c(p.0), c(p.1))
    }

    /// Whether `p` is at least `sqrt(d2)` from every point (toroidally).
    fn free(&self, p: (f64, f64), d2: f64) -> bool {
        let g = self.g;
        let (cx, cy) = self.cell(p);
        let span: &[usize] = if g == 1 { &[0] } else { &[g - 1, 0, 1] };
        for &oy in span {
            for &ox in span {
                let cell = ((cy + oy) % g) * g + (cx + ox) % g;
                let mut i = self.head[cell];
                while i != u32::MAX {
                    if toroidal_distance2(p, self.points[i as usize]) < d2 {
                        return false;
                    }
                    i = self.next[i as usize];
                }
            }
        }
        true
    }

    fn push(&mut self, p: (f64, f64)) {
        let (cx, cy) = self.cell(p);
        let cell = cy * self.g + cx;
        self.next.push(self.head[cell]);
        self.head[cell] = self.points.len() as u32;
        self.points.push(p);
    }
}

/// Dart `k` of the stream `key`: two 32-bit uniforms in `[0, 1)`, outputs
/// `2k` and `2k + 1` of SplitMix64 from `key` (as [`uniform_pair`], with a
/// 64-bit counter).
#[inline]
fn dart(key: u64, k: u64) -> (f64, f64) {
    let c = k.wrapping_mul(2);
    let to_unit = |h: u64| (h >> 32) as f64 * INV_2_32;
    (
        to_unit(mix64(
            key.wrapping_add(c.wrapping_add(1).wrapping_mul(GOLDEN)),
        )),
        to_unit(mix64(
            key.wrapping_add(c.wrapping_add(2).wrapping_mul(GOLDEN)),
        )),
    )
}

/// `n` points on the unit torus with toroidal minimum distance
/// [`poisson_target_distance`]`(n)`, by dart throwing, deterministic in
/// `(n, seed, light_index)`.
///
/// Darts are uniform (32-bit) points from a counter-based stream keyed by
/// `(seed, light, n, level, restart)`; a dart closer than `d` to an
/// accepted point is rejected. A restart that has not accepted `n` points
/// after [`poisson_dart_budget`]`(n)` darts is abandoned; after
/// [`POISSON_RESTARTS`] abandoned restarts `d` is multiplied by
/// [`POISSON_SHRINK`]; after [`POISSON_MAX_LEVELS`] levels `d = 0`, which
/// accepts every dart. So at most `(POISSON_MAX_LEVELS · POISSON_RESTARTS
/// + 1) · poisson_dart_budget(n)` darts are thrown.
pub fn poisson_dart_throwing(n: u32, seed: u64, light_index: usize) -> PoissonSet {
    let target = poisson_target_distance(n);
    let base = stream_key(seed, light_index, TAG_POISSON, u64::from(n));
    let budget = poisson_dart_budget(n);
    let mut darts = 0u64;
    let mut d = target;
    for level in 0..=POISSON_MAX_LEVELS {
        if level == POISSON_MAX_LEVELS {
            d = 0.0;
        }
        let d2 = d * d;
        let mut grid = DartGrid::new(n, d);
        for restart in 0..POISSON_RESTARTS {
            grid.clear();
            let key =
                mix64(base ^ (u64::from(level) << 32 | u64::from(restart)).wrapping_mul(GOLDEN));
            let mut k = 0u64;
            while grid.points.len() < n as usize && k < budget {
                let p = dart(key, k);
                k += 1;
                if grid.free(p, d2) {
                    grid.push(p);
                }
            }
            darts += k;
            if grid.points.len() == n as usize {
                return PoissonSet {
                    points: std::mem::take(&mut grid.points),
                    target,
                    distance: d,
                    level,
                    restart,
                    darts,
                };
            }
        }
        d *= POISSON_SHRINK;
    }
    unreachable!("at distance 0 every dart is accepted within the budget")
}

// ------------------------------------------------------------ grid

/// Coordinate `i` of `m` grid points on `[0, 1]` including both ends:
/// `i / (m − 1)`, or `0.5` when `m ≤ 1`. One IEEE division of two small
/// integers: `i / 2^d` exactly when `m = 2^d + 1`.
#[inline]
pub fn grid_coordinate(i: u32, m: u32) -> f64 {
    if m <= 1 {
        0.5
    } else {
        f64::from(i) / f64::from(m - 1)
    }
}

// ------------------------------------------------------------ sampler

/// One pixel's view of a [`PatternSampler`]: what point `k` needs.
#[derive(Debug, Clone, Copy)]
pub(crate) enum PixelPoints<'a> {
    /// `strata.point(key, k)` (stratified, correlated, interleaved).
    Jittered { strata: Strata, key: u64 },
    /// `strata.point(key, k)` shifted toroidally (rotated).
    JitteredShifted {
        strata: Strata,
        key: u64,
        shift: (f64, f64),
    },
    /// `base[k]` shifted toroidally (Poisson).
    Shifted {
        base: &'a [(f64, f64)],
        shift: (f64, f64),
    },
    /// `base[k]` XORed with `shift` (Sobol').
    Digital {
        base: &'a [(u32, u32)],
        shift: (u32, u32),
    },
    /// The regular grid including the edges (grid).
    Grid { strata: Strata },
}

impl PixelPoints<'_> {
    /// Calls `f` with points `0..n` in order, the same values as
    /// [`PixelPoints::point`] gives, walking the strata row by row instead
    /// of dividing `k` for each (the hot path of per-pixel sampling).
    #[inline]
    pub(crate) fn for_each(&self, n: u32, mut f: impl FnMut((f64, f64))) {
        match *self {
            PixelPoints::Jittered { strata, key } if strata.count() == n && n > 0 => {
                // Dividing by a power of two is multiplying by its exact
                // inverse (the quotients here are far from subnormal): the
                // same bits without two divisions per sample (4, 16, 64,
                // 256, 1024 samples have power-of-two grids). The choice is
                // made once per pixel, as a type parameter: a run-time flag
                // in the loop had the compiler compute the division anyway
                // and select.
                match (strata.a.is_power_of_two(), strata.b.is_power_of_two()) {
                    (true, true) => jittered::<true, true>(strata, key, f),
                    (true, false) => jittered::<true, false>(strata, key, f),
                    (false, true) => jittered::<false, true>(strata, key, f),
                    (false, false) => jittered::<false, false>(strata, key, f),
                }
            }
            _ => (0..n).for_each(|k| f(self.point(k))),
        }
    }

    /// Unit point `k` of this pixel.
    #[inline]
    pub(crate) fn point(&self, k: u32) -> (f64, f64) {
        match *self {
            PixelPoints::Jittered { strata, key } => strata.point(key, k),
            PixelPoints::JitteredShifted { strata, key, shift } => {
                let (s, t) = strata.point(key, k);
                (wrap_add(s, shift.0), wrap_add(t, shift.1))
            }
            PixelPoints::Shifted { base, shift } => {
                let (s, t) = base[k as usize];
                (wrap_add(s, shift.0), wrap_add(t, shift.1))
            }
            PixelPoints::Digital { base, shift } => {
                let (x, y) = base[k as usize];
                (
                    f64::from(x ^ shift.0) * INV_2_32,
                    f64::from(y ^ shift.1) * INV_2_32,
                )
            }
            PixelPoints::Grid { strata } => {
                let (i, j) = strata.cell(k);
                (grid_coordinate(i, strata.a), grid_coordinate(j, strata.b))
            }
        }
    }
}

/// The jittered points of `strata` under `key` in sample order, row by row
/// (no division of `k`); `EXACT_A` / `EXACT_B`: the column / row count is
/// a power of two, so dividing by it is multiplying by its inverse.
#[inline(always)]
fn jittered<const EXACT_A: bool, const EXACT_B: bool>(
    strata: Strata,
    key: u64,
    mut f: impl FnMut((f64, f64)),
) {
    let (a, b) = (f64::from(strata.a), f64::from(strata.b));
    let (inv_a, inv_b) = (1.0 / a, 1.0 / b);
    let mut k = 0;
    for j in 0..strata.b {
        let t_row = f64::from(j);
        for i in 0..strata.a {
            let (xi, xi2) = super::uniform_pair(key, k);
            let (s, t) = (f64::from(i) + xi, t_row + xi2);
            f((
                if EXACT_A { s * inv_a } else { s / a },
                if EXACT_B { t * inv_b } else { t / b },
            ));
            k += 1;
        }
    }
}

/// The per-`(pattern, N, seed, light)` part of a sample pattern,
/// precomputed once (the Poisson-disk set, the Sobol' points, the
/// correlated set's key); [`PatternSampler::unit_points`] then gives any
/// pixel's `N` points in `[0, 1)²`. Cheap to share between threads (`&self`
/// everywhere).
#[derive(Debug, Clone)]
pub struct PatternSampler {
    pattern: SamplePattern,
    n: u32,
    seed: u64,
    light_index: usize,
    strata: Strata,
    /// Key of the correlated set (set 0).
    correlated_key: u64,
    /// The Poisson-disk set, when the pattern is Poisson.
    poisson: Option<PoissonSet>,
    /// The Sobol' points, when the pattern is Sobol02.
    sobol: Vec<(u32, u32)>,
}

impl PatternSampler {
    /// Precomputes `pattern` for `n` samples of light `light_index` under
    /// `seed`. `n = 0` gives no points. Poisson costs one dart throwing
    /// ([`poisson_dart_throwing`]), Sobol' `n` point evaluations; the
    /// other patterns nothing.
    pub fn new(pattern: SamplePattern, n: u32, seed: u64, light_index: usize) -> PatternSampler {
        let poisson = (pattern == SamplePattern::Poisson && n > 0)
            .then(|| poisson_dart_throwing(n, seed, light_index));
        let sobol = if pattern == SamplePattern::Sobol02 {
            (0..n).map(sobol02).collect()
        } else {
            Vec::new()
        };
        PatternSampler {
            pattern,
            n,
            seed,
            light_index,
            strata: Strata::new(n),
            correlated_key: set_key(seed, light_index, 0),
            poisson,
            sobol,
        }
    }

    /// The pattern.
    pub fn pattern(&self) -> SamplePattern {
        self.pattern
    }

    /// When `pixel`'s points are jittered strata (stratified, correlated,
    /// interleaved): the strata and the key, so that point `k = j a + i`
    /// is `((i + ξ) / a, (j + ξ') / b)` with `(ξ, ξ') =
    /// uniform_pair(key, k)`, made one by one in any order.
    pub fn jittered(&self, pixel: (u32, u32)) -> Option<(Strata, u64)> {
        match self.pixel_points(pixel) {
            PixelPoints::Jittered { strata, key } => Some((strata, key)),
            _ => None,
        }
    }

    /// Points per pixel, `N`.
    pub fn len(&self) -> u32 {
        self.n
    }

    /// Whether there are no points (`N = 0`).
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// The seed.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// The light index.
    pub fn light_index(&self) -> usize {
        self.light_index
    }

    /// The Poisson-disk base set and how it was made (Poisson only).
    pub fn poisson_set(&self) -> Option<&PoissonSet> {
        self.poisson.as_ref()
    }

    /// The minimum toroidal distance every pixel's set keeps (Poisson
    /// only): [`PoissonSet::distance`].
    pub fn poisson_distance(&self) -> Option<f64> {
        self.poisson.as_ref().map(|p| p.distance)
    }

    /// The interleaved set number of `pixel`, `(x mod n) + n (y mod n)`
    /// (Interleaved only).
    pub fn interleaved_set(&self, pixel: (u32, u32)) -> Option<u64> {
        match self.pattern {
            SamplePattern::Interleaved { n } => {
                let n = u64::from(n.max(1));
                Some(u64::from(pixel.0) % n + n * (u64::from(pixel.1) % n))
            }
            _ => None,
        }
    }

    /// What `pixel` needs to produce its points.
    #[inline]
    pub(crate) fn pixel_points(&self, pixel: (u32, u32)) -> PixelPoints<'_> {
        let (seed, light) = (self.seed, self.light_index);
        let strata = self.strata;
        let shift = |tag| uniform_pair(pixel_tag_key(seed, light, pixel, tag), 0);
        match self.pattern {
            SamplePattern::Stratified => PixelPoints::Jittered {
                strata,
                key: pixel_key(seed, light, pixel),
            },
            SamplePattern::Correlated => PixelPoints::Jittered {
                strata,
                key: self.correlated_key,
            },
            SamplePattern::Rotated => PixelPoints::JitteredShifted {
                strata,
                key: self.correlated_key,
                shift: shift(TAG_ROTATION),
            },
            SamplePattern::Interleaved { .. } => PixelPoints::Jittered {
                strata,
                key: set_key(seed, light, self.interleaved_set(pixel).unwrap_or(0)),
            },
            SamplePattern::Poisson => PixelPoints::Shifted {
                base: self.poisson.as_ref().map_or(&[], |p| &p.points),
                shift: shift(TAG_POISSON_SHIFT),
            },
            SamplePattern::Grid => PixelPoints::Grid { strata },
            SamplePattern::Sobol02 => {
                let key = pixel_tag_key(seed, light, pixel, TAG_DIGITAL_SHIFT);
                PixelPoints::Digital {
                    base: &self.sobol,
                    shift: (
                        (mix64(key.wrapping_add(GOLDEN)) >> 32) as u32,
                        (mix64(key.wrapping_add(GOLDEN.wrapping_mul(2))) >> 32) as u32,
                    ),
                }
            }
        }
    }

    /// Unit point `k < N` of `pixel`.
    pub fn point(&self, pixel: (u32, u32), k: u32) -> (f64, f64) {
        self.pixel_points(pixel).point(k)
    }

    /// The `N` points of `pixel` in `[0, 1)²`, written to `out` (cleared
    /// first; no allocation once `out` has room for `N`).
    pub fn unit_points(&self, pixel: (u32, u32), out: &mut Vec<(f64, f64)>) {
        out.clear();
        let pts = self.pixel_points(pixel);
        out.reserve(self.n as usize);
        pts.for_each(self.n, |p| out.push(p));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn poisson_formula_reproduces_the_thesis() {
        assert!((poisson_target_distance(16) - 0.245_613_9).abs() < 1e-6);
        assert!((poisson_target_distance(64) - 0.107_668_1).abs() < 1e-6);
        let r16 = poisson_relative_radius(16);
        let r64 = poisson_relative_radius(64);
        assert!((r16 - 0.914_28).abs() < 1e-5, "{r16}");
        assert!((r64 - 0.801_57).abs() < 1e-5, "{r64}");
        // Held below 16, linear in log N above.
        assert_eq!(poisson_relative_radius(1), r16);
        assert_eq!(poisson_relative_radius(4), r16);
        let r256 = poisson_relative_radius(256);
        assert!((r256 - (2.0 * r64 - r16)).abs() < 1e-12, "{r256}");
        assert!(poisson_relative_radius(65536) > POISSON_MIN_RELATIVE_RADIUS);
        assert_eq!(poisson_target_distance(0), 0.0);
    }

    #[test]
    fn dart_throwing_reaches_n_points_within_the_bound() {
        for n in [1u32, 4, 16, 64, 256, 1024] {
            let set = poisson_dart_throwing(n, 7, 0);
            assert_eq!(set.points.len(), n as usize);
            let bound = (u64::from(POISSON_MAX_LEVELS) * u64::from(POISSON_RESTARTS) + 1)
                * poisson_dart_budget(n);
            assert!(set.darts <= bound);
            // Never shrunk to nothing: at least 0.75 of the target.
            assert!(
                set.distance >= 0.75 * set.target,
                "n {n}: {} of {}",
                set.distance,
                set.target
            );
            let mut min = f64::INFINITY;
            for i in 0..set.points.len() {
                for j in 0..i {
                    min = min.min(toroidal_distance2(set.points[i], set.points[j]));
                }
            }
            assert!(min.sqrt() >= set.distance, "n {n}");
            println!(
                "n {n}: target {:.7} distance {:.7} (rho {:.4}) level {} restart {} darts {}",
                set.target,
                set.distance,
                set.distance / max_packing_distance(n),
                set.level,
                set.restart,
                set.darts
            );
            // Deterministic.
            assert_eq!(set, poisson_dart_throwing(n, 7, 0));
        }
    }

    #[test]
    fn sobol_first_points() {
        let pts: Vec<(u32, u32)> = (0..4).map(sobol02).collect();
        let h = 1u32 << 31;
        assert_eq!(pts[0], (0, 0));
        assert_eq!(pts[1], (h, h));
        assert_eq!(pts[2], (h >> 1, 3 << 30));
        assert_eq!(pts[3], (3 << 30, h >> 1));
    }

    /// 289 grid points are the 17 × 17 grid `i / 16` with both edges, the
    /// same for every pixel; one point is the centre.
    #[test]
    fn grid_includes_the_edges() {
        let g = PatternSampler::new(SamplePattern::Grid, 289, 3, 0);
        let mut a = Vec::new();
        let mut b = Vec::new();
        g.unit_points((0, 0), &mut a);
        g.unit_points((91, 7), &mut b);
        assert_eq!(a, b);
        assert_eq!(a[0], (0.0, 0.0));
        assert_eq!(a[16], (1.0, 0.0));
        assert_eq!(a[288], (1.0, 1.0));
        assert_eq!(a[17 * 3 + 5], (5.0 / 16.0, 3.0 / 16.0));
        let one = PatternSampler::new(SamplePattern::Grid, 1, 3, 0);
        assert_eq!(one.point((0, 0), 0), (0.5, 0.5));
        assert_eq!(SamplePattern::parse("grid"), Ok(SamplePattern::Grid));
        assert!(!SamplePattern::Grid.is_decorrelated());
    }

    #[test]
    fn wrap_add_stays_in_the_unit_interval() {
        let below_one = 1.0 - f64::EPSILON / 2.0;
        assert!(wrap_add(below_one, below_one) < 1.0);
        assert!(wrap_add(0.5, 0.5) == 0.0);
        assert!(wrap_add(below_one, 1e-300) < 1.0);
    }
}

#[cfg(test)]
mod for_each_tests {
    use super::*;

    /// The row-by-row walk gives exactly `point(k)` for every pattern.
    #[test]
    fn for_each_equals_point() {
        for pattern in [
            "stratified",
            "correlated",
            "rotated",
            "poisson",
            "sobol",
            "interleaved:3",
            "grid",
        ] {
            let pattern = SamplePattern::parse(pattern).unwrap();
            for n in [1, 7, 12, 16, 32, 64, 100, 256] {
                let sampler = PatternSampler::new(pattern, n, 9, 1);
                for pixel in [(0, 0), (5, 3), (1000, 77)] {
                    let pts = sampler.pixel_points(pixel);
                    let mut walked = Vec::new();
                    pts.for_each(n, |p| walked.push(p));
                    let direct: Vec<_> = (0..n).map(|k| pts.point(k)).collect();
                    assert_eq!(walked, direct, "{pattern} n={n} {pixel:?}");
                }
            }
        }
    }
}
